//! A campaign's runs: run `i` drawn from the campaign's seed, played, judged, and shrunk when it
//! fails.

use super::shard::{Shard, run_seed};
use super::shrink::{self, History};
use crate::configs::Source;
use crate::coverage::Coverage;
use crate::scenario::{self, Expect, Fault, Loaded, RandomFaults, Scenario};
use nodes::{Error, Problem};
use std::collections::BTreeSet;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;

/// What a run that panicked fails (harvemu itself, not a node's logic).
pub const NO_PANIC: &str = "harvemu does not panic";
/// The expectation a run fails when its drawn faults do not resolve (a bug: they come from a
/// section the campaign checked).
pub const RESOLVES: &str = "the run's faults make a valid scenario";
/// What a run that ended with an error fails.
pub const NO_ERROR: &str = "the run ends without an error";

/// A campaign read and checked: the scenario without its random faults, and the section they
/// are drawn from.
pub struct Campaign {
    /// The scenario as loaded, its timeline only the file's own steps, its expectations the
    /// file's and the invariants ([`Expect::TraceComplete`], [`Expect::NoCrashes`]).
    pub base: Loaded,
    /// The faults' section.
    pub section: RandomFaults,
    /// The campaign's seed.
    pub seed: u64,
    /// What tells this campaign from another with the same name: a hash of the scenario's text.
    pub id: String,
    nodes: Vec<String>,
    /// Count the firmware images' code coverage of each run (not of the candidates tried while
    /// shrinking): [`RunResult::coverage`].
    pub coverage: bool,
}

/// The expectations a run failed, each with what was observed.
type Failures = Vec<(String, String)>;

/// A failing run, shrunk.
#[derive(Clone, Debug)]
pub struct Failure {
    /// The first expectation it failed.
    pub expectation: String,
    /// What was observed in the run.
    pub observed: String,
    /// What was observed in the shrunk run.
    pub shrunk_observed: String,
    /// Faults drawn.
    pub faults_before: usize,
    /// Faults left after shrinking.
    pub faults_after: usize,
    /// Candidates run while shrinking.
    pub trials: u32,
    /// False when shrinking stopped at its budget.
    pub complete: bool,
    /// The shrunk run, as a scenario with a plain timeline.
    pub scenario: Scenario,
}

/// One run's result.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Its number.
    pub run: u64,
    /// Its seed.
    pub seed: u64,
    /// What it failed, if anything.
    pub failure: Option<Failure>,
    /// Its firmware images' code coverage, when the campaign counts it.
    pub coverage: Option<Coverage>,
}

impl Campaign {
    /// Reads a campaign's scenario (a file, or a built-in one's path): it must have a
    /// `random_faults` section. `seed` defaults to the scenario's, else its config's. `config`
    /// is a harvester config to run it against instead of the one it names.
    pub fn open(path: &Path, seed: Option<u64>, config: Option<&Path>) -> Result<Campaign, Error> {
        let (_, mut text) = Source::file(path).read()?;
        let mut base = scenario::load_with(path, None, None, config)?;
        // Shards of one campaign against another harvester are another campaign.
        if let Some(c) = config {
            text.push_str(&format!("\n// config {}", c.display()));
        }
        let Some(section) = base.scenario.random_faults.take() else {
            return Err(Error::Invalid(vec![Problem::at(
                &base.source.to_string(),
                "random_faults",
                "a campaign draws its faults at random: this scenario has no random_faults section",
            )]));
        };
        let seed = seed.unwrap_or(base.harvester.config.network.seed);
        base.scenario.timeline.truncate(base.fixed);
        for invariant in [Expect::TraceComplete, Expect::NoCrashes] {
            let key = format!("{invariant:?}");
            if !base.scenario.expect.iter().any(|e| format!("{e:?}") == key) {
                base.scenario.expect.push(invariant);
            }
        }
        let nodes = base.harvester.node_names();
        Ok(Campaign {
            id: fnv1a(text.as_bytes()),
            base,
            section,
            seed,
            nodes,
            coverage: false,
        })
    }

    /// The scenario's name.
    pub fn name(&self) -> &str {
        &self.base.scenario.name
    }

    /// Run `i`'s seed and faults.
    pub fn history(&self, i: u64) -> (u64, History) {
        let seed = run_seed(self.seed, i);
        let duration_s = self.base.scenario.duration_s;
        let faults = scenario::random::draw(&self.section, seed, duration_s, &self.nodes);
        (seed, History { faults, duration_s })
    }

    /// The scenario of a run, resolved: see [`Campaign::unresolved`]; the problems when its faults
    /// do not make a scenario `harvemu scenario` would take.
    pub fn loaded(&self, seed: u64, h: &History) -> Result<Loaded, nodes::Error> {
        self.unresolved(seed, h).resolved()
    }

    /// The scenario of a run: the file's own steps and the faults' steps, in time order, with
    /// the run's seed and length and no random faults.
    fn unresolved(&self, seed: u64, h: &History) -> Loaded {
        let mut l = self.base.clone();
        l.harvester.config.network.seed = seed;
        let s = &mut l.scenario;
        s.seed = Some(seed);
        s.duration_s = h.duration_s;
        s.timeline.extend(h.faults.iter().flat_map(Fault::steps));
        // Stable: the file's steps first, then the faults as drawn, at equal times.
        s.timeline.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
        l.fixed = s.timeline.len();
        l
    }

    /// Plays a run: the expectations it failed with what was observed, in the order of the
    /// expectations; `None` when a stop signal interrupted it.
    pub fn failures(&self, l: &Loaded) -> Option<Vec<(String, String)>> {
        self.played(l).map(|(failed, _)| failed)
    }

    /// [`Campaign::failures`], with the run's coverage when its harvester counts it.
    fn played(&self, l: &Loaded) -> Option<(Failures, Option<Coverage>)> {
        let played = catch_unwind(AssertUnwindSafe(|| scenario::run(l, None, |_| {})));
        let failed = match played {
            Err(panic) => {
                let why =
                    bus_runtime::node::panic_message(panic.as_ref()).unwrap_or_else(|| "a panic".into());
                Some(vec![(NO_PANIC.into(), why)])
            }
            Ok(Err(e)) => Some(vec![(NO_ERROR.into(), e.report().to_string())]),
            Ok(Ok(o)) if o.interrupted => None,
            Ok(Ok(o)) => {
                let failed = o
                    .verdicts
                    .into_iter()
                    .filter(|v| !v.passed)
                    .map(|v| (v.expectation, v.observed))
                    .collect();
                return Some((failed, o.coverage));
            }
        };
        failed.map(|f| (f, None))
    }

    /// Plays run `i`, and shrinks it with at most `budget` candidates when it fails; `None`
    /// when a stop signal interrupted it.
    pub fn run(&self, i: u64, budget: u32) -> Option<RunResult> {
        let (seed, start) = self.history(i);
        let (failed, coverage) = match self.loaded(seed, &start) {
            Ok(mut l) => {
                l.harvester.coverage = self.coverage;
                self.played(&l)?
            }
            // Drawn from a section the campaign checked: a bug, told as the run's failure.
            Err(e) => (vec![(RESOLVES.into(), e.to_string())], None),
        };
        let Some((expectation, observed)) = failed.into_iter().next() else {
            return Some(RunResult {
                run: i,
                seed,
                failure: None,
                coverage,
            });
        };
        let bounds = shrink::Bounds {
            earliest_s: self.section.from_s,
            settle_s: self.section.quiet_end_s,
        };
        let before = start.faults.len();
        // What the candidate kept last showed: the shrunk run's observation.
        let mut shrunk_observed = observed.clone();
        let shrunk = shrink::shrink(start, bounds, budget, |h| {
            // A candidate is kept only if `harvemu scenario` would take it.
            let Ok(l) = self.loaded(seed, h) else {
                return false;
            };
            let Some(failed) = self.failures(&l) else {
                return false;
            };
            match failed.into_iter().find(|(e, _)| *e == expectation) {
                Some((_, seen)) => {
                    shrunk_observed = seen;
                    true
                }
                None => false,
            }
        });
        // A stop signal during shrinking leaves the run undone: it is not in the results.
        if crate::stop::received().is_some() {
            return None;
        }
        let mut scenario = self.unresolved(seed, &shrunk.history).scenario;
        scenario.random_faults = None;
        scenario.name = format!("{} run {i}", self.name());
        scenario.description = format!(
            "Run {i} of the campaign {:?} (seed {}), its {} shrunk to {}: it fails {expectation}.",
            self.name(),
            self.seed,
            bus::text::count(before as u64, "random fault", "random faults"),
            shrunk.history.faults.len()
        );
        Some(RunResult {
            run: i,
            seed,
            coverage,
            failure: Some(Failure {
                expectation,
                observed,
                shrunk_observed,
                faults_before: before,
                faults_after: shrunk.history.faults.len(),
                trials: shrunk.trials,
                complete: shrunk.complete,
                scenario,
            }),
        })
    }
}

/// Plays shard `shard` of the runs `0..runs` in order on `jobs` threads, each with its own
/// actor system, shrinking failures with at most `budget` candidates each. `each` sees every
/// result as it comes, and stops the campaign by answering false. The answer is how many of
/// the shard's runs were done without a gap from its first one: all of them, unless a stop
/// signal or `each` ended it (the runs under way are then dropped). Memory holds the runs
/// under way and those finished ahead of the slowest, never one entry per run.
pub fn play(
    c: &Campaign,
    shard: Shard,
    runs: u64,
    jobs: usize,
    budget: u32,
    mut each: impl FnMut(&RunResult) -> bool,
) -> Result<u64, String> {
    // The j-th run of the shard is run k - 1 + j·m.
    let count = shard.count(runs);
    let nth = |j: u64| (shard.k - 1) + j * shard.m;
    let next = AtomicU64::new(0);
    let halt = AtomicBool::new(false);
    let (tx, rx) = mpsc::channel();
    let mut done = 0;
    // Runs finished ahead of the first one still under way, by their place in the shard.
    let mut ahead = BTreeSet::new();
    std::thread::scope(|scope| {
        let mut started = 0;
        for t in 0..jobs.min(count as usize).max(1) {
            let tx = tx.clone();
            let (next, halt) = (&next, &halt);
            let job = move || {
                while crate::stop::received().is_none() && !halt.load(Ordering::Relaxed) {
                    let j = next.fetch_add(1, Ordering::Relaxed);
                    if j >= count {
                        break;
                    }
                    let Some(r) = c.run(nth(j), budget) else { break };
                    if tx.send((j, r)).is_err() {
                        break;
                    }
                }
            };
            match std::thread::Builder::new()
                .name(format!("campaign-{t}"))
                .spawn_scoped(scope, job)
            {
                Ok(_) => started += 1,
                // Fewer threads than asked is slower, not wrong; none at all is an error.
                Err(e) if started == 0 => return Err(format!("cannot start a thread: {e}")),
                Err(_) => break,
            }
        }
        drop(tx);
        for (j, r) in rx {
            if halt.load(Ordering::Relaxed) {
                continue;
            }
            if !each(&r) {
                halt.store(true, Ordering::Relaxed);
                continue;
            }
            ahead.insert(j);
            while ahead.remove(&done) {
                done += 1;
            }
        }
        Ok(())
    })?;
    Ok(done)
}

/// FNV-1a, 64 bits, in hex: a fingerprint of a file's text that is the same on every machine.
pub fn fnv1a(bytes: &[u8]) -> String {
    let mut h: u64 = 0xCBF2_9CE4_8422_2325;
    for b in bytes {
        h = (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01B3);
    }
    format!("{h:016x}")
}
