//! The run loop: a loaded scenario played in virtual time, to its verdicts.
//!
//! Contract: the timeline starts once the field nodes are on the bus (the time relay); its steps
//! and the ends of their faults are carried out in time order, and what falls due at the same
//! time in the order of the steps. The series is sampled at every whole second. A stop
//! signal ends the run where it is: the verdicts, the trace and the report are still produced,
//! with a failed verdict "the run completes". A seed gives the same run, frame for frame.

use super::actions::Actions;
use super::books::{Books, TraceTally};
use super::check::{self, Verdict};
use super::model::Expect;
use super::plan::Todo;
use super::series::{self, Series};
use super::{Loaded, kinds, trace_count};
use crate::harvester::{self, Running, SupervisorEvent};
use crate::stop::{Signal, Stop};
use actix::prelude::*;
use bus::time::{BusDuration, BusTime};
use bus::trace::Sink;
use bus_runtime::hub::{FlushTrace, GetErrorCounters, GetSnapshot, Snapshot, runtime};
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;

/// What a scenario run produced.
pub struct Outcome {
    /// Verdicts, one per expectation.
    pub verdicts: Vec<Verdict>,
    /// The seed used.
    pub seed: u64,
    /// Crashes, restarts, power cycles.
    pub events: Vec<SupervisorEvent>,
    /// Wall-clock seconds.
    pub wall_seconds: f64,
    /// Stopped by a stop signal (Ctrl-C, SIGTERM, SIGHUP) before the end.
    pub interrupted: bool,
    /// Nodes that crashed beyond the restart policy by themselves (not by the timeline's
    /// `Crash`) and stayed down.
    pub down: Vec<String>,
    /// What the run looked like over time (for the report).
    pub series: Series,
    /// Where the frames went (the monitor's books, the trace's count).
    pub books: Books,
    /// Timeline actions carried out, by [`Action::name`].
    pub applied: BTreeMap<&'static str, u64>,
    /// The hub at the end.
    pub snapshot: Option<Snapshot>,
    /// Each firmware node's hardware (CPU, controllers) at the end.
    pub hardware: Vec<(String, bus::node::HardwareState)>,
    /// The firmware images' code coverage, when the harvester counts it
    /// ([`crate::harvester::Harvester::coverage`]).
    pub coverage: Option<crate::coverage::Coverage>,
    /// Hits and misses of each `Disturb` step, by timeline entry.
    pub disturbed: Vec<(usize, bus::engine::DisturbCounts)>,
    /// The reference monitor's alarms at the end, in the order raised (none without a monitor).
    pub alarms: Vec<nodes::monitor::Alarm>,
}

impl Outcome {
    /// Each `Disturb` step's hits and misses, in words: `timeline[2] Disturb: 1 hit, 0 misses`.
    pub fn disturbances(&self) -> Vec<String> {
        self.disturbed
            .iter()
            .map(|(i, c)| {
                let plural =
                    |n: u64, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
                format!(
                    "timeline[{i}] Disturb: {}, {}",
                    plural(c.hits, "hit", "hits"),
                    plural(c.misses, "miss", "misses")
                )
            })
            .collect()
    }

    /// True when every expectation passed.
    pub fn passed(&self) -> bool {
        self.verdicts.iter().all(|v| v.passed)
    }
}

/// Runs a loaded scenario in virtual time. `progress` is called with bus seconds reached.
pub fn run(l: &Loaded, trace: Option<Box<dyn Sink>>, progress: impl FnMut(f64)) -> crate::Result<Outcome> {
    let started = std::time::Instant::now();
    // Counting the trace costs a record per frame: only when it is written anyway or checked.
    let count_trace = trace.is_some()
        || l.scenario
            .expect
            .iter()
            .any(|e| matches!(e, Expect::TraceComplete));
    let mut sinks: Vec<Box<dyn Sink>> = trace.into_iter().collect();
    let tally = count_trace.then(|| {
        let (counting, tally) = trace_count::Counting::new();
        sinks.push(Box::new(counting));
        tally
    });
    let queries = kind_queries(l);
    let kinds = (!queries.is_empty()).then(|| {
        let (counting, counts) = kinds::Counting::new(queries);
        sinks.push(Box::new(counting));
        counts
    });
    let system = System::with_tokio_rt(|| runtime(true).expect("a tokio runtime"));
    let mut outcome = system.block_on(play(l, sinks, tally, kinds, progress))?;
    outcome.wall_seconds = started.elapsed().as_secs_f64();
    Ok(outcome)
}

/// The run itself, inside the actix system; the outcome's wall time is left at zero.
async fn play(
    l: &Loaded,
    sinks: Vec<Box<dyn Sink>>,
    tally: Option<Rc<RefCell<TraceTally>>>,
    kinds: Option<kinds::Counts>,
    mut progress: impl FnMut(f64),
) -> crate::Result<Outcome> {
    let (s, h) = (&l.scenario, &l.harvester);
    let mut p = Playing {
        stop: Stop::new().map_err(crate::Error::System)?,
        running: harvester::begin(h, false, sinks).await?,
        series: Series::default(),
        interrupted: None,
    };
    let mut actions = Actions::new(l.source.to_string());
    let mut applied = BTreeMap::new();
    let end = BusTime::from_secs_f64(s.duration_s);
    // Start-up: the timeline and the series begin once the field nodes are there (at the time
    // relay).
    tokio::select! {
        r = p.running.run_until(h.relay().min(end)) => r?,
        sig = p.stop.wait() => p.interrupted = Some(sig),
    }
    for (at, what) in l.plan.todo.iter().cloned() {
        if p.interrupted.is_some() {
            break;
        }
        p.run_to(at.max(p.running.now())).await?;
        if p.interrupted.is_some() {
            break;
        }
        progress(p.running.now().as_secs_f64());
        match what {
            Todo::Act { index, name, act } => {
                actions.act(&mut p.running, index, act).await?;
                *applied.entry(name).or_insert(0) += 1;
            }
            Todo::EndRule(i) => actions.end_rule(&p.running, i).await?,
            Todo::EndBabble => actions.end_babble(&p.running).await?,
        }
    }
    while p.running.now() < end && p.interrupted.is_none() {
        let next = (p.running.now() + BusDuration::from_secs(1)).min(end);
        p.run_to(next).await?;
        progress(p.running.now().as_secs_f64());
    }
    let Playing {
        running,
        mut series,
        interrupted,
        ..
    } = p;
    running.hub.send(FlushTrace).await??;
    let snap = running.hub.send(GetSnapshot).await?;
    let disturbed = actions.disturbed(&running).await?;
    let kinds = kinds.map(|k| k.borrow().clone()).unwrap_or_default();
    let monitor = running
        .node("F5")
        .zip(running.display.as_ref().map(|d| d.borrow().tally));
    let books = Books::gather(&snap, monitor, tally.map(|t| *t.borrow()));
    let mut verdicts = check::all(&l.plan.checks, &running, &snap, &books, &kinds);
    let hardware = running.hardware(snap.now).await;
    let coverage = running.end_coverage(snap.now).await;
    if let Some(signal) = interrupted {
        verdicts.push(Verdict {
            expectation: "the run completes".into(),
            passed: false,
            at: Some(snap.now),
            observed: format!("interrupted by {}", signal.describe()),
        });
    }
    series.finish(&snap);
    Ok(Outcome {
        verdicts,
        seed: h.config.network.seed,
        events: running.events.clone(),
        wall_seconds: 0.0,
        interrupted: interrupted.is_some(),
        down: running.down_by_themselves(),
        series,
        books,
        applied,
        snapshot: Some(snap),
        hardware,
        coverage,
        disturbed,
        alarms: running
            .display
            .as_ref()
            .map_or_else(Vec::new, |d| d.borrow().alarms.clone()),
    })
}

/// The questions of the `ErrorKinds` expectations, for the sink that counts their answers.
fn kind_queries(l: &Loaded) -> Vec<kinds::Query> {
    let end = l.scenario.duration_s;
    l.plan
        .checks
        .iter()
        .enumerate()
        .filter_map(|(check, c)| match (&c.expect, c.node) {
            (
                Expect::ErrorKinds {
                    kind, from_s, to_s, ..
                },
                Some(node),
            ) => Some(kinds::Query {
                check,
                node,
                kind: *kind,
                from: BusTime::from_secs_f64(*from_s),
                to: BusTime::from_secs_f64(to_s.unwrap_or(end)),
            }),
            _ => None,
        })
        .collect()
}

/// The harvester on its way through the run, with what stops it and what it has shown so far.
struct Playing {
    running: Running,
    stop: Stop,
    series: Series,
    /// The stop signal that ended the run early, if one did.
    interrupted: Option<Signal>,
}

impl Playing {
    /// Runs to `target`, stopping at each whole second on the way to sample the series, or
    /// until a stop signal comes.
    async fn run_to(&mut self, target: BusTime) -> crate::Result<()> {
        loop {
            let until = self.series.next_stop(self.running.now(), target);
            tokio::select! {
                r = self.running.run_until(until) => r?,
                sig = self.stop.wait() => self.interrupted = Some(sig),
            }
            if self.interrupted.is_some() {
                return Ok(());
            }
            if self.series.is_due(self.running.now()) {
                let sample = sample(&self.running).await?;
                self.series.record(self.running.now(), sample);
            }
            if self.running.now() >= target {
                return Ok(());
            }
        }
    }
}

/// Reads the plant, the monitor's display and the error counters, without moving anything on.
async fn sample(running: &Running) -> crate::Result<series::Sample> {
    let counters = running.hub.send(GetErrorCounters).await?;
    // The plant is read as of its last step (nodes advance it as they run): advancing it here
    // could change when a node's input takes effect.
    let plant = running.plant.borrow();
    let display = running.display.as_ref().map(|d| d.borrow());
    Ok(series::Sample {
        t_s: 0.0,
        speed_kmh: plant.signal("speed.actual").unwrap_or(f64::NAN),
        harvested_kg: plant.signal("harvested.total").unwrap_or(f64::NAN),
        monitor_speed_kmh: display.as_ref().and_then(|d| d.speed_kmh),
        monitor_kg: display.as_ref().map(|d| d.total_kg),
        counters,
    })
}
