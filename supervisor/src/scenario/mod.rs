//! Scenarios: a harvester run in virtual time with a timeline of stimuli and faults, and
//! expectations checked against the monitor's display, the bus statistics and node states, each
//! with a verdict.

pub mod books;
mod check;
pub mod junit;
mod model;
pub mod random;
pub mod series;
mod states;
pub mod trace_count;

pub use check::Verdict;
pub use model::*;
pub use random::{RandomFault, RandomFaults};
pub use series::Series;

use crate::BadInput;
use crate::harvester::{self, Harvester, Running};
use actix::prelude::*;
use bus::candump::parse_frame;
use bus::engine::{BitPosition, ControllerConfig, Effect, Filter, Rule, Schedule};
use bus::hub::{Attach, Control, GetErrorCounters, GetSnapshot, Replace, Submit, runtime};
use bus::node::{Apply, NodeActor, NodeFault, NodeLogic};
use bus::text::{LIST_CHARS, cut, quote};
use bus::time::BusTime;
use nodes::plant::Plant;
use nodes::{Error, Problem};
use std::io::Write;
use std::path::{Path, PathBuf};

/// A scenario read and checked, with the harvester it runs on.
pub struct Loaded {
    /// Its file.
    pub path: PathBuf,
    /// The scenario.
    pub scenario: Scenario,
    /// The harvester, with the scenario's seed applied.
    pub harvester: Harvester,
}

/// Reads and checks a scenario and its harvester; every problem is listed. Files are read with
/// [`nodes::file::read_text`]: at most [`nodes::file::MAX_FILE`] bytes each.
pub fn load(path: &Path, seed: Option<u64>) -> Result<Loaded, Error> {
    load_with(path, seed, None)
}

/// [`load`], with the run's length replaced by `duration_s` when given (before the random
/// faults are drawn, so that they cover the new length).
pub fn load_with(path: &Path, seed: Option<u64>, duration_s: Option<f64>) -> Result<Loaded, Error> {
    let text = nodes::file::read_text(path)?;
    parse(path, &text, seed, duration_s, Harvester::load)
}

/// As [`load`] with the scenario's text already read: `path` is where it came from (problems
/// name it; its config is relative to its directory) and `harvester` loads the harvester config
/// at a path, as [`Harvester::load`] does.
pub fn from_text(
    path: &Path,
    text: &str,
    seed: Option<u64>,
    harvester: impl FnOnce(&Path) -> Result<Harvester, Error>,
) -> Result<Loaded, Error> {
    parse(path, text, seed, None, harvester)
}

fn parse(
    path: &Path,
    text: &str,
    seed: Option<u64>,
    duration_s: Option<f64>,
    harvester: impl FnOnce(&Path) -> Result<Harvester, Error>,
) -> Result<Loaded, Error> {
    let file = path.display().to_string();
    let mut scenario: Scenario = nodes::parse_ron(&file, text)?;
    if let Some(d) = duration_s {
        scenario.duration_s = d;
    }
    let config = path.parent().unwrap_or(Path::new(".")).join(&scenario.config);
    let mut harvester = harvester(&config)?;
    let problems = validate(&file, &scenario, &harvester);
    if !problems.is_empty() {
        return Err(Error::Invalid(problems));
    }
    if let Some(s) = seed.or(scenario.seed) {
        harvester.config.seed = s;
    }
    if let Some(r) = &scenario.random_faults {
        // Ordinary steps from here on: the runner, the report and the checks see no difference.
        let seed = r.seed.unwrap_or(harvester.config.seed);
        let steps = random::expand(r, seed, scenario.duration_s, &node_names(&harvester));
        scenario.timeline.extend(steps);
    }
    if let Some(s) = scenario.cruise_start_s {
        harvester.config.monitor.cruise.start_s = Some(s);
    }
    Ok(Loaded {
        path: path.to_path_buf(),
        scenario,
        harvester,
    })
}

/// The names of a harvester's nodes, the monitor's ("F5") first when it is emulated.
fn node_names(h: &Harvester) -> Vec<String> {
    let monitor = h.config.monitor.enabled.then(|| "F5".to_string());
    monitor
        .into_iter()
        .chain(h.scripts.iter().map(|s| s.name.clone()))
        .collect()
}

/// The longest scenario or soak, s: 30 days of virtual time, about two days of wall time at the
/// emulator's pace, and far beyond any soak run so far; longer is a typing error.
pub const MAX_DURATION_S: f64 = 30.0 * 24.0 * 3600.0;

/// Overload frames a receiver may send in a row: the CAN 2.0 specification allows at most two to
/// delay the next data or remote frame.
pub const MAX_OVERLOAD_FRAMES: u8 = 2;

/// Bits a bus-off node must see recessive before it is error active again (128 sequences of 11):
/// no node can go bus off more often than once per this many bit times.
const RECOVERY_BITS: u64 = bus::fault::RECOVERY_SEQUENCES as u64 * bus::fault::RECOVERY_SEQUENCE_BITS as u64;

/// TEC stops counting at bus off, at most one penalty (8) past the limit: no TEC is ever higher.
const TEC_CEILING: u16 = bus::fault::BUS_OFF_LIMIT + 7;

/// Checks names, times and values of a scenario against its harvester.
pub fn validate(file: &str, s: &Scenario, h: &Harvester) -> Vec<Problem> {
    let mut p = Vec::new();
    // Both reach JUnit XML and the HTML report, which cannot carry control characters.
    for (field, text) in [("name", &s.name), ("description", &s.description)] {
        if let Some(c) = text.chars().find(|&c| !junit::xml_char(c)) {
            p.push(Problem::at(
                file,
                field.to_string(),
                format!(
                    "holds the character U+{:04X}, which JUnit XML and the HTML report cannot carry (control characters other than tab and line breaks are refused)",
                    u32::from(c)
                ),
            ));
        }
    }
    let names = node_names(h);
    if let Some(r) = &s.random_faults {
        for (field, message) in random::problems(r, s.duration_s, &names) {
            p.push(Problem::at(file, field, message));
        }
    }
    let node_ok = |p: &mut Vec<Problem>, field: String, n: &str| {
        if !names.iter().any(|x| x == n) {
            p.push(Problem::at(
                file,
                field,
                format!(
                    "unknown node {} (nodes: {})",
                    quote(n),
                    cut(&names.join(", "), LIST_CHARS)
                ),
            ));
        }
    };
    let time_ok = |p: &mut Vec<Problem>, field: String, t: f64| {
        if !(t.is_finite() && t >= 0.0) {
            p.push(Problem::at(
                file,
                field,
                format!("time {t} s is negative or not a number"),
            ));
        } else if t > s.duration_s {
            p.push(Problem::at(
                file,
                field,
                format!("time {t} s is after the end of the run ({} s)", s.duration_s),
            ));
        }
    };
    // The end of a fault: a time in the run, after its start.
    let end_ok = |p: &mut Vec<Problem>, field: String, start: f64, end: f64| {
        time_ok(p, field.clone(), end);
        if end.is_finite() && start.is_finite() && end <= start {
            p.push(Problem::at(
                file,
                field,
                format!("the fault ends at {end} s, not after it starts ({start} s)"),
            ));
        }
    };
    // A window of an expectation: two times in the run, the first before the second.
    let window_ok = |p: &mut Vec<Problem>, at: &str, from: f64, to: f64| {
        time_ok(p, format!("{at}.from_s"), from);
        time_ok(p, format!("{at}.to_s"), to);
        if from.is_finite() && to.is_finite() && from >= to {
            p.push(Problem::at(
                file,
                format!("{at}.to_s"),
                format!("the window {from} s to {to} s is empty: to_s must be after from_s"),
            ));
        }
    };
    // Which frames a fault selects.
    let frames_ok = |p: &mut Vec<Problem>, at: &str, target: &Target, hits: &Hits| {
        match target {
            Target::Node(n) => node_ok(p, format!("{at}.action.target"), n),
            Target::Id(id)
                if id.len() != 8 || u32::from_str_radix(id, 16).map_or(true, |v| v > 0x1FFF_FFFF) =>
            {
                p.push(Problem::at(
                    file,
                    format!("{at}.action.target"),
                    format!("{} is not an 8-digit 29-bit identifier", quote(id)),
                ))
            }
            Target::Priority(pr) if *pr > 31 => p.push(Problem::at(
                file,
                format!("{at}.action.target"),
                format!("priority {pr} is over 31"),
            )),
            _ => {}
        }
        match hits {
            Hits::EveryNth(0) => p.push(Problem::at(file, format!("{at}.action.hits"), "EveryNth(0)")),
            Hits::BitErrorRate(r) if !(0.0..=1.0).contains(r) => p.push(Problem::at(
                file,
                format!("{at}.action.hits"),
                format!("bit-error rate {r} is outside 0..1"),
            )),
            _ => {}
        }
    };
    if !(s.duration_s.is_finite() && s.duration_s > 0.0) {
        p.push(Problem::at(
            file,
            "duration_s",
            "must be a positive number of seconds",
        ));
    } else if s.duration_s > MAX_DURATION_S {
        p.push(Problem::at(
            file,
            "duration_s",
            format!(
                "{} s is longer than the longest run, {MAX_DURATION_S} s (30 days of virtual time)",
                s.duration_s
            ),
        ));
    }
    if s.expect.is_empty() {
        p.push(Problem::at(
            file,
            "expect",
            "a scenario needs at least one expectation",
        ));
    }
    let signals = Plant::signal_names();
    let display_fields = serde_json::to_value(nodes::monitor::Display::default()).unwrap_or_default();
    for (i, step) in s.timeline.iter().enumerate() {
        let at = format!("timeline[{i}]");
        time_ok(&mut p, format!("{at}.at_s"), step.at_s);
        if let Action::SensorFault { fault, .. } = &step.action
            && let Some(m) = fault.problem()
        {
            p.push(Problem::at(file, format!("{at}.action.fault"), m));
        }
        match &step.action {
            Action::BitErrors {
                target,
                hits,
                until_s,
                kind,
                seen_by,
            } => {
                frames_ok(&mut p, &at, target, hits);
                if let Some(u) = until_s {
                    end_ok(&mut p, format!("{at}.action.until_s"), step.at_s, *u);
                }
                if let SeenBy::Nodes(nodes) = seen_by {
                    if nodes.is_empty() {
                        p.push(Problem::at(
                            file,
                            format!("{at}.action.seen_by"),
                            "Nodes([]): name at least one node, or leave seen_by out for All",
                        ));
                    }
                    for (k, n) in nodes.iter().enumerate() {
                        node_ok(&mut p, format!("{at}.action.seen_by[{k}]"), n);
                    }
                    if *kind == ErrorKind::Bit {
                        p.push(Problem::at(
                            file,
                            format!("{at}.action.seen_by"),
                            "a bit error is a bit flipped on the wire, which every node sees: \
                             seen_by: Nodes(..) needs kind Stuff, Crc or Form",
                        ));
                    }
                }
            }
            Action::Overload {
                target,
                hits,
                until_s,
                by,
                frames,
            } => {
                frames_ok(&mut p, &at, target, hits);
                if let Some(u) = until_s {
                    end_ok(&mut p, format!("{at}.action.until_s"), step.at_s, *u);
                }
                for (k, n) in by.iter().enumerate() {
                    node_ok(&mut p, format!("{at}.action.by[{k}]"), n);
                }
                if !(1..=MAX_OVERLOAD_FRAMES).contains(frames) {
                    p.push(Problem::at(
                        file,
                        format!("{at}.action.frames"),
                        format!(
                            "{frames} overload frames in a row: a receiver may send 1 or \
                             {MAX_OVERLOAD_FRAMES} (CAN 2.0, overload frame)"
                        ),
                    ));
                }
            }
            Action::AckFailure(n)
            | Action::AckRestored(n)
            | Action::Disconnect(n)
            | Action::Reconnect(n)
            | Action::Crash(n)
            | Action::Hang(n)
            | Action::Resume(n) => node_ok(&mut p, format!("{at}.action"), n),
            Action::Babble { frame, until_s } => {
                if let Err(e) = parse_frame(frame) {
                    p.push(Problem::at(file, format!("{at}.action.frame"), e.to_string()));
                }
                end_ok(&mut p, format!("{at}.action.until_s"), step.at_s, *until_s);
            }
            Action::SendFrame { node, frame } => {
                node_ok(&mut p, format!("{at}.action.node"), node);
                if let Err(e) = parse_frame(frame) {
                    p.push(Problem::at(file, format!("{at}.action.frame"), e.to_string()));
                }
            }
            Action::SensorFault { node, signal, .. } | Action::SensorRepaired { node, signal } => {
                node_ok(&mut p, format!("{at}.action.node"), node);
                if node == "F5" {
                    p.push(Problem::at(
                        file,
                        format!("{at}.action.node"),
                        "the monitor has no sensors",
                    ));
                }
                if !signals.iter().any(|s| s == signal) {
                    p.push(Problem::at(
                        file,
                        format!("{at}.action.signal"),
                        format!("unknown plant signal {}", quote(signal)),
                    ));
                }
            }
            Action::Plant { input, value } => match Plant::input_range(input) {
                None => p.push(Problem::at(
                    file,
                    format!("{at}.action.input"),
                    format!("{} is not a plant input", quote(input)),
                )),
                // The plant refuses it when the step runs, which would end the run there.
                Some(range) if !range.contains(*value) => p.push(Problem::at(
                    file,
                    format!("{at}.action.value"),
                    format!("{value} is not {range}, the range of plant input {input}"),
                )),
                Some(_) => {}
            },
            Action::PowerCycle => {}
        }
    }
    for (i, e) in s.expect.iter().enumerate() {
        let at = format!("expect[{i}]");
        let bounds_ok = |p: &mut Vec<Problem>, min: f64, max: f64| {
            for (name, v) in [("min", min), ("max", max)] {
                if !v.is_finite() {
                    p.push(Problem::at(
                        file,
                        format!("{at}.{name}"),
                        format!("{v} is not a number"),
                    ));
                }
            }
            if min > max {
                p.push(Problem::at(
                    file,
                    format!("{at}.min"),
                    format!("min {min} is above max {max}"),
                ));
            }
        };
        match e {
            Expect::AlarmRaised { node, after_s, .. } | Expect::AlarmCleared { node, after_s, .. } => {
                node_ok(&mut p, format!("{at}.node"), node);
                time_ok(&mut p, format!("{at}.after_s"), *after_s);
            }
            Expect::NodeState { node, after_s, .. } => {
                node_ok(&mut p, format!("{at}.node"), node);
                time_ok(&mut p, format!("{at}.after_s"), *after_s);
            }
            Expect::NodeStateNever {
                node, from_s, to_s, ..
            }
            | Expect::NodeStateHolds {
                node, from_s, to_s, ..
            } => {
                node_ok(&mut p, format!("{at}.node"), node);
                window_ok(&mut p, &at, *from_s, *to_s);
            }
            Expect::RecMax {
                node,
                max,
                from_s,
                to_s,
            }
            | Expect::TecMax {
                node,
                max,
                from_s,
                to_s,
            } => {
                node_ok(&mut p, format!("{at}.node"), node);
                window_ok(&mut p, &at, *from_s, *to_s);
                let (name, ceiling) = if matches!(e, Expect::RecMax { .. }) {
                    ("REC", bus::fault::REC_MAX)
                } else {
                    ("TEC", TEC_CEILING)
                };
                if *max >= ceiling {
                    p.push(Problem::at(
                        file,
                        format!("{at}.max"),
                        format!("{name} never exceeds {ceiling}: a maximum of {max} cannot fail"),
                    ));
                }
            }
            Expect::BusOffCount { node, min, max } => {
                node_ok(&mut p, format!("{at}.node"), node);
                if min > max {
                    p.push(Problem::at(
                        file,
                        format!("{at}.min"),
                        format!("min {min} is above max {max}"),
                    ));
                }
                // Each bus-off but the last is followed by a recovery of RECOVERY_BITS.
                if s.duration_s.is_finite() && h.config.bitrate > 0 {
                    let bits = s.duration_s * f64::from(h.config.bitrate);
                    let most = (bits / RECOVERY_BITS as f64).floor() + 1.0;
                    if f64::from(*min) > most {
                        p.push(Problem::at(
                            file,
                            format!("{at}.min"),
                            format!(
                                "{min} bus-offs cannot fit in {} s: each recovery takes \
                                 {RECOVERY_BITS} bit times, at most {most} in the run",
                                s.duration_s
                            ),
                        ));
                    }
                }
            }
            Expect::Restarts { node, .. } => node_ok(&mut p, format!("{at}.node"), node),
            Expect::Display { field, min, max } => {
                if display_fields.get(field).is_none() {
                    p.push(Problem::at(
                        file,
                        format!("{at}.field"),
                        format!("the display has no field {}", quote(field)),
                    ));
                }
                bounds_ok(&mut p, *min, *max);
            }
            Expect::Plant { signal, min, max } => {
                if !signals.iter().any(|s| s == signal) {
                    p.push(Problem::at(
                        file,
                        format!("{at}.signal"),
                        format!("unknown plant signal {}", quote(signal)),
                    ));
                }
                bounds_ok(&mut p, *min, *max);
            }
            Expect::ErrorFrames { min, max } | Expect::OverloadFrames { min, max } if min > max => p.push(
                Problem::at(file, format!("{at}.min"), format!("min {min} is above max {max}")),
            ),
            Expect::BusLoadBelow(limit) if !(*limit > 0.0 && *limit <= 100.0) => p.push(Problem::at(
                file,
                at.clone(),
                format!("a load limit of {limit} % is outside (0, 100]: it would always pass or never"),
            )),
            Expect::YieldWithin(percent) if !(*percent >= 0.0 && *percent <= 100.0) => p.push(Problem::at(
                file,
                at.clone(),
                format!("{percent} % is not a tolerance in 0..=100"),
            )),
            _ => {}
        }
        let needs_monitor = matches!(
            e,
            Expect::AlarmRaised { .. }
                | Expect::AlarmCleared { .. }
                | Expect::NoAlarms
                | Expect::YieldWithin(_)
                | Expect::Display { .. }
                | Expect::FramesAccounted
        );
        if needs_monitor && !h.config.monitor.enabled {
            p.push(Problem::at(
                file,
                format!("expect[{i}]"),
                "needs the emulated monitor, which the config switches off",
            ));
        }
    }
    p
}

/// A babbling idiot: tops up its transmit queue every millisecond, so that it always has a
/// frame pending.
struct Babbler {
    frame: bus::Frame,
    next: BusTime,
    owed: usize,
}

const BABBLER_QUEUE: usize = 4;

impl NodeLogic for Babbler {
    fn handle_frame(&mut self, _: BusTime, _: &bus::Frame) {}
    fn handle_timeout(&mut self, now: BusTime) {
        self.owed = BABBLER_QUEUE;
        self.next = now + 1_000_000;
    }
    fn poll_transmit(&mut self) -> Option<bus::Frame> {
        // Frames beyond the queue are refused by the controller: no harm, it tries again.
        self.owed = self.owed.checked_sub(1)?;
        Some(self.frame)
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        Some(self.next)
    }
}

/// What a scenario run produced.
pub struct Outcome {
    /// Verdicts, one per expectation.
    pub verdicts: Vec<Verdict>,
    /// The seed used.
    pub seed: u64,
    /// Crashes, restarts, power cycles.
    pub events: Vec<harvester::SupervisorEvent>,
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
    pub books: books::Books,
    /// Timeline actions carried out, by [`Action::name`].
    pub applied: std::collections::BTreeMap<&'static str, u64>,
    /// The hub at the end.
    pub snapshot: Option<bus::hub::Snapshot>,
}

/// What the run leaves besides verdicts.
struct End {
    books: books::Books,
    applied: std::collections::BTreeMap<&'static str, u64>,
    snapshot: bus::hub::Snapshot,
}

impl Outcome {
    /// True when every expectation passed.
    pub fn passed(&self) -> bool {
        self.verdicts.iter().all(|v| v.passed)
    }
}

enum Todo {
    Act(usize, Action),
    EndBitErrors(usize),
    EndBabble,
}

/// Runs a loaded scenario in virtual time. `progress` is called with bus seconds reached.
pub fn run(
    l: &Loaded,
    trace: Option<Box<dyn Write>>,
    mut progress: impl FnMut(f64),
) -> anyhow::Result<Outcome> {
    let started = std::time::Instant::now();
    let s = l.scenario.clone();
    let h = l.harvester.clone();
    let seed = h.config.seed;
    let mut todo: Vec<(BusTime, usize, Todo)> = Vec::new();
    for (i, step) in s.timeline.iter().enumerate() {
        todo.push((
            BusTime::from_secs_f64(step.at_s),
            i,
            Todo::Act(i, step.action.clone()),
        ));
        match &step.action {
            Action::BitErrors { until_s: Some(u), .. } | Action::Overload { until_s: Some(u), .. } => {
                todo.push((BusTime::from_secs_f64(*u), i, Todo::EndBitErrors(i)))
            }
            Action::Babble { until_s, .. } => {
                todo.push((BusTime::from_secs_f64(*until_s), i, Todo::EndBabble))
            }
            _ => {}
        }
    }
    todo.sort_by_key(|(t, i, _)| (*t, *i));
    // Counting the trace costs a line per frame: only when it is written anyway or checked.
    let count_trace = trace.is_some() || s.expect.iter().any(|e| matches!(e, Expect::TraceComplete));
    let (trace, trace_tally) = if count_trace {
        let (w, tally) = trace_count::CountingWriter::new(trace);
        (Some(Box::new(w) as Box<dyn Write>), Some(tally))
    } else {
        (trace, None)
    };
    let system = System::with_tokio_rt(|| runtime(true).expect("a tokio runtime"));
    let result = system.block_on(async move {
        let mut stop = crate::stop::Stop::new()?;
        let mut running = harvester::begin(&h, trace).await?;
        let mut rules = std::collections::BTreeMap::new();
        let mut babbler = Babblers::default();
        let mut applied = std::collections::BTreeMap::new();
        // A stop signal stops the run where it is; verdicts, trace and report are still written.
        let mut interrupted = None;
        let mut series = Series::default();
        // Runs to a time, stopping at each whole second on the way to sample the series.
        macro_rules! run_to {
            ($t:expr) => {
                let target = $t;
                loop {
                    let until = series.next_stop(running.now(), target);
                    tokio::select! {
                        r = running.run_until(until) => r?,
                        sig = stop.wait() => interrupted = Some(sig),
                    }
                    if interrupted.is_some() {
                        break;
                    }
                    if series.is_due(running.now()) {
                        let sample = sample(&running).await?;
                        series.record(running.now(), sample);
                    }
                    if running.now() >= target {
                        break;
                    }
                }
            };
        }
        let end = BusTime::from_secs_f64(s.duration_s);
        // Start-up: the timeline and the series begin once the field nodes are there (at the
        // time relay).
        tokio::select! {
            r = running.run_until(h.relay().min(end)) => r?,
            sig = stop.wait() => interrupted = Some(sig),
        }
        for (at, _, what) in todo {
            if interrupted.is_some() {
                break;
            }
            run_to!(at.max(running.now()));
            if interrupted.is_some() {
                break;
            }
            progress(running.now().as_secs_f64());
            match what {
                Todo::Act(i, action) => {
                    let name = action.name();
                    act(&mut running, i, action, &mut rules, &mut babbler).await?;
                    *applied.entry(name).or_insert(0) += 1;
                }
                Todo::EndBitErrors(i) => {
                    if let Some(id) = rules.remove(&i) {
                        running.hub.send(Control::RemoveRule(id)).await??;
                    }
                }
                Todo::EndBabble => {
                    if let Some(id) = babbler.active.take() {
                        running.hub.send(Control::SetConnected(id, false)).await??;
                        running.hub.send(Control::SetHung(id, true)).await??;
                        babbler.parked.push(id);
                    }
                }
            }
        }
        while running.now() < end && interrupted.is_none() {
            let next = (running.now() + 1_000_000_000).min(end);
            run_to!(next);
            progress(running.now().as_secs_f64());
        }
        // Pausing the hub at the present flushes the trace.
        let now = running.hub.send(GetSnapshot).await?.now;
        running.hub.send(bus::hub::RunUntil(now)).await??;
        let snap = running.hub.send(GetSnapshot).await?;
        let monitor = running
            .node("F5")
            .zip(running.display.as_ref().map(|d| d.borrow().tally));
        let trace = trace_tally.map(|t| *t.borrow());
        let books = books::Books::gather(&snap, monitor, trace);
        let mut verdicts = check::all(&s, &running, &snap, &books);
        if let Some(signal) = interrupted {
            verdicts.push(Verdict {
                expectation: "the run completes".into(),
                passed: false,
                at: Some(snap.now),
                observed: format!("interrupted by {}", signal.describe()),
            });
        }
        let down = running.down_by_themselves();
        series.finish(&snap);
        let end = End {
            books,
            applied,
            snapshot: snap,
        };
        anyhow::Ok((
            verdicts,
            running.events.clone(),
            interrupted.is_some(),
            series,
            end,
            down,
        ))
    })?;
    Ok(Outcome {
        verdicts: result.0,
        seed,
        events: result.1,
        wall_seconds: started.elapsed().as_secs_f64(),
        interrupted: result.2,
        down: result.5,
        series: result.3,
        books: result.4.books,
        applied: result.4.applied,
        snapshot: Some(result.4.snapshot),
    })
}

/// Reads the plant, the monitor's display and the error counters, without moving anything on.
async fn sample(running: &Running) -> anyhow::Result<series::Sample> {
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

/// Babbling idiots: the one flooding now, and those parked (disconnected, hung) for the next
/// flood, so that a long run with many floods does not grow the bus by a controller each time.
#[derive(Default)]
struct Babblers {
    active: Option<bus::engine::NodeId>,
    parked: Vec<bus::engine::NodeId>,
}

/// The engine's form of the frames a fault targets.
fn engine_target(
    target: &Target,
    id: &dyn Fn(&str) -> anyhow::Result<bus::engine::NodeId>,
) -> anyhow::Result<bus::engine::Target> {
    Ok(match target {
        Target::Any => bus::engine::Target::Any,
        Target::Node(n) => bus::engine::Target::Node(id(n)?),
        Target::Id(text) => bus::engine::Target::Id {
            id: u32::from_str_radix(text, 16)?,
            mask: 0x1FFF_FFFF,
        },
        Target::Priority(p) => bus::engine::Target::Id {
            id: u32::from(*p) << 24,
            mask: 0x1F00_0000,
        },
    })
}

/// The engine's form of which targeted frames are hit.
fn engine_schedule(hits: Hits) -> Schedule {
    match hits {
        Hits::Once => Schedule::Once,
        Hits::EveryNth(n) => Schedule::EveryNth(n),
        Hits::Always => Schedule::Always,
        Hits::BitErrorRate(r) => Schedule::BitErrorRate(r),
    }
}

async fn act(
    running: &mut Running,
    index: usize,
    action: Action,
    rules: &mut std::collections::BTreeMap<usize, bus::engine::RuleId>,
    babbler: &mut Babblers,
) -> anyhow::Result<()> {
    let id = |n: &str| running.node(n).ok_or_else(|| anyhow::anyhow!("no node {n}"));
    match action {
        Action::BitErrors {
            target,
            hits,
            kind,
            seen_by,
            ..
        } => {
            let effect = match kind {
                ErrorKind::Bit => Effect::Bit,
                ErrorKind::Stuff => Effect::Stuff,
                ErrorKind::Crc => Effect::Crc,
                ErrorKind::Form => Effect::Form,
            };
            let seen_by = match seen_by {
                SeenBy::All => bus::engine::SeenBy::All,
                SeenBy::Nodes(names) => {
                    bus::engine::SeenBy::Nodes(names.iter().map(|n| id(n)).collect::<Result<_, _>>()?)
                }
            };
            let rule = Rule {
                target: engine_target(&target, &id)?,
                schedule: engine_schedule(hits),
                bit: BitPosition::Random,
                effect,
                seen_by,
            };
            if let Some(r) = running.hub.send(Control::AddRule(rule)).await?? {
                // Keyed by timeline entry, so that its `until_s` removes this rule.
                rules.insert(index, r);
            }
        }
        Action::Overload {
            target,
            hits,
            by,
            frames,
            ..
        } => {
            let seen_by = if by.is_empty() {
                bus::engine::SeenBy::All
            } else {
                bus::engine::SeenBy::Nodes(by.iter().map(|n| id(n)).collect::<Result<_, _>>()?)
            };
            let rule = Rule {
                target: engine_target(&target, &id)?,
                schedule: engine_schedule(hits),
                bit: BitPosition::Random,
                effect: Effect::Overload(frames),
                seen_by,
            };
            if let Some(r) = running.hub.send(Control::AddRule(rule)).await?? {
                rules.insert(index, r);
            }
        }
        Action::AckFailure(n) => drop(running.hub.send(Control::SetAck(id(&n)?, false)).await??),
        Action::AckRestored(n) => drop(running.hub.send(Control::SetAck(id(&n)?, true)).await??),
        Action::Disconnect(n) => drop(running.hub.send(Control::SetConnected(id(&n)?, false)).await??),
        Action::Reconnect(n) => drop(running.hub.send(Control::SetConnected(id(&n)?, true)).await??),
        Action::Hang(n) => drop(running.hub.send(Control::SetHung(id(&n)?, true)).await??),
        Action::Resume(n) => drop(running.hub.send(Control::SetHung(id(&n)?, false)).await??),
        Action::Crash(n) => running.crash(&n).await?,
        Action::Babble { frame, .. } => {
            let frame = parse_frame(&frame)?;
            let babbler_logic = Babbler {
                frame,
                next: running.now(),
                owed: 0,
            };
            let actor = NodeActor::new("babbler", Box::new(babbler_logic)).start();
            let node = if let Some(node) = babbler.parked.pop() {
                // A new logic behind a parked controller (reset), back on the bus.
                running
                    .hub
                    .send(Replace {
                        node,
                        actor: actor.recipient(),
                    })
                    .await??;
                running.hub.send(Control::SetConnected(node, true)).await??;
                node
            } else {
                let controller = ControllerConfig {
                    tx_queue_len: BABBLER_QUEUE,
                    ..ControllerConfig::named("babbler")
                }
                .with_filter(Filter::Nothing);
                running
                    .hub
                    .send(Attach {
                        controller,
                        node: Some(actor.recipient()),
                        reaction: std::time::Duration::from_micros(50),
                    })
                    .await?
            };
            // Overlapping floods: the newer one takes over, and the first end stops it.
            if let Some(old) = babbler.active.replace(node) {
                running.hub.send(Control::SetConnected(old, false)).await??;
                running.hub.send(Control::SetHung(old, true)).await??;
                babbler.parked.push(old);
            }
        }
        Action::SendFrame { node, frame } => {
            let frame = parse_frame(&frame)?;
            running
                .hub
                .send(Submit {
                    node: id(&node)?,
                    frame,
                })
                .await??;
        }
        Action::SensorFault { node, signal, fault } => sensor(running, &node, signal, Some(fault)).await?,
        Action::SensorRepaired { node, signal } => sensor(running, &node, signal, None).await?,
        Action::Plant { input, value } => {
            let now = running.now();
            running
                .plant
                .borrow_mut()
                .set_input_at(now, &input, value)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }
        Action::PowerCycle => running.power_cycle().await?,
    }
    Ok(())
}

async fn sensor(
    running: &Running,
    node: &str,
    signal: String,
    fault: Option<nodes::script::FaultKind>,
) -> anyhow::Result<()> {
    let actor = running
        .actor(node)
        .ok_or_else(|| BadInput(format!("no node {node}")))?;
    let now = running.now();
    let fault = match fault {
        Some(f) => NodeFault::Sensor {
            signal,
            reads: f.into(),
        },
        None => NodeFault::SensorRepaired { signal },
    };
    let (answer, taken) = std::sync::mpsc::channel();
    let described = format!("{fault:?}");
    actor
        .send(Apply(Box::new(move |logic| {
            let _ = answer.send(logic.inject(&fault, now));
        })))
        .await?;
    match taken.try_recv() {
        Ok(Ok(())) => Ok(()),
        Ok(Err(refused)) => Err(BadInput(format!("node {node} refused {described}: {refused}")).into()),
        Err(e) => Err(anyhow::anyhow!("node {node} did not answer {described}: {e}")),
    }
}

#[cfg(test)]
mod tests;
