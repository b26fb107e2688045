//! Random faults from a seed: a scenario's `random_faults` section, expanded into ordinary
//! timeline steps before the run.
//!
//! Contract of [`expand`] (sans-IO, no clock, no global RNG):
//! - the same section, seed, run length and node list give the same steps, on every platform;
//! - fault starts form a Poisson process (exponential gaps of mean `mean_interval_s`) between
//!   `from_s` and the run's end less `quiet_end_s`;
//! - kinds are drawn in shuffled rounds (each round deals every kind once), so every kind appears
//!   as soon as there are as many faults as kinds, and none is starved;
//! - every fault that can be undone is undone (reconnect, resume, end of bit errors or babbling)
//!   after `min_fault_s..=max_fault_s`, and before the end of the run, so the machine keeps working;
//! - a node has one fault at a time and then rests `node_rest_s` (so that crashes never exhaust
//!   the restart policy); babbling idiots never overlap. A fault with no node free is skipped.

use super::{Action, ErrorKind, Hits, SeenBy, Step, Target};
use bus::text::{LIST_CHARS, cut, quote};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The `random_faults` section of a scenario.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomFaults {
    /// Seed of the schedule; the run's seed when absent.
    #[serde(default)]
    pub seed: Option<u64>,
    /// Mean time between fault starts, s.
    pub mean_interval_s: f64,
    /// Which faults to draw from.
    pub kinds: Vec<RandomFault>,
    /// Nodes the faults hit; every node (and the monitor) when empty.
    #[serde(default)]
    pub nodes: Vec<String>,
    /// No fault before this time, s (start-up and calibration).
    #[serde(default = "default_from")]
    pub from_s: f64,
    /// No fault starts in this last stretch of the run, s (the machine settles before the checks).
    #[serde(default = "default_quiet_end")]
    pub quiet_end_s: f64,
    /// Shortest fault, s.
    #[serde(default = "default_min_fault")]
    pub min_fault_s: f64,
    /// Longest fault, s.
    #[serde(default = "default_max_fault")]
    pub max_fault_s: f64,
    /// A node's rest after its fault ends, s.
    #[serde(default = "default_node_rest")]
    pub node_rest_s: f64,
}

fn default_from() -> f64 {
    10.0
}
fn default_quiet_end() -> f64 {
    30.0
}
fn default_min_fault() -> f64 {
    0.5
}
fn default_max_fault() -> f64 {
    5.0
}
fn default_node_rest() -> f64 {
    60.0
}

/// A kind of random fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub enum RandomFault {
    /// Every frame on the bus risks bit errors (a rate of 1e-5 to 1e-4 per bit) for a while.
    BitErrors,
    /// Every second frame of one node is hit for a while: its TEC climbs to error passive,
    /// often to bus off, and it recovers.
    ErrorPassive,
    /// A node's logic crashes; the supervisor restarts it.
    Crash,
    /// A node hangs for a while, then runs again.
    Hang,
    /// A babbling idiot floods the bus with top-priority frames for a while.
    Babble,
    /// A node is disconnected for a while, then reconnected.
    Disconnect,
}

impl RandomFault {
    /// Every kind.
    pub const ALL: [RandomFault; 6] = [
        RandomFault::BitErrors,
        RandomFault::ErrorPassive,
        RandomFault::Crash,
        RandomFault::Hang,
        RandomFault::Babble,
        RandomFault::Disconnect,
    ];

    fn needs_node(self) -> bool {
        !matches!(self, RandomFault::BitErrors | RandomFault::Babble)
    }
}

/// The random kind a timeline action starts, if it starts one (undo steps start none).
pub fn kind_of(action: &Action) -> Option<RandomFault> {
    match action {
        Action::BitErrors {
            target: Target::Any, ..
        } => Some(RandomFault::BitErrors),
        Action::BitErrors { .. } => Some(RandomFault::ErrorPassive),
        Action::Crash(_) => Some(RandomFault::Crash),
        Action::Hang(_) => Some(RandomFault::Hang),
        Action::Babble { .. } => Some(RandomFault::Babble),
        Action::Disconnect(_) => Some(RandomFault::Disconnect),
        _ => None,
    }
}

/// Most faults one section may produce: more is a typo in `mean_interval_s`, not a soak.
pub const MAX_FAULTS: f64 = 100_000.0;

/// What is wrong with a section, as (field, message) pairs; `names` are the run's nodes.
pub fn problems(r: &RandomFaults, duration_s: f64, names: &[String]) -> Vec<(String, String)> {
    let mut p = Vec::new();
    let mut bad = |field: &str, m: String| p.push((format!("random_faults.{field}"), m));
    if !(r.mean_interval_s.is_finite() && r.mean_interval_s > 0.0) {
        bad("mean_interval_s", "must be a positive number of seconds".into());
    } else if duration_s / r.mean_interval_s > MAX_FAULTS {
        bad(
            "mean_interval_s",
            format!(
                "{} s over {duration_s} s is more than {MAX_FAULTS} faults",
                r.mean_interval_s
            ),
        );
    }
    if r.kinds.is_empty() {
        bad("kinds", "name at least one kind of fault".into());
    }
    for n in &r.nodes {
        if !names.contains(n) {
            bad(
                "nodes",
                format!(
                    "unknown node {} (nodes: {})",
                    quote(n),
                    cut(&names.join(", "), LIST_CHARS)
                ),
            );
        }
    }
    for (field, v) in [
        ("from_s", r.from_s),
        ("quiet_end_s", r.quiet_end_s),
        ("node_rest_s", r.node_rest_s),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            bad(field, format!("{v} is negative or not a number"));
        }
    }
    if !(r.min_fault_s.is_finite() && r.min_fault_s > 0.0) {
        bad("min_fault_s", "must be a positive number of seconds".into());
    }
    if !(r.max_fault_s.is_finite() && r.max_fault_s >= r.min_fault_s) {
        bad(
            "max_fault_s",
            format!("must be at least min_fault_s ({} s)", r.min_fault_s),
        );
    }
    p
}

/// The babbling idiot's identifier: priority 0, so it wins every arbitration, addressed to the
/// monitor from an address no node has (its flood reaches the monitor's books too).
pub const BABBLE_ID: u32 = 0x0000_F5EE;

/// Rounds a time to the millisecond, for steps that read well.
fn ms(t: f64) -> f64 {
    (t * 1000.0).round() / 1000.0
}

/// One drawn fault: when it starts, when it is undone, and what it is.
#[derive(Clone, Debug, PartialEq)]
pub struct Fault {
    /// Start, s (whole milliseconds).
    pub at_s: f64,
    /// End, s (whole milliseconds); the start for a crash, which is never undone.
    pub until_s: f64,
    /// What it does.
    pub hit: Hit,
}

/// What a drawn fault does.
#[derive(Clone, Debug, PartialEq)]
pub enum Hit {
    /// Each bit of every frame flips with this probability.
    BitErrors(f64),
    /// Every `every`-th frame of the node is hit.
    ErrorPassive {
        /// The node.
        node: String,
        /// Which of its frames.
        every: u32,
    },
    /// The node's logic crashes.
    Crash(String),
    /// The node hangs.
    Hang(String),
    /// A babbling idiot floods the bus with this frame (candump notation).
    Babble(String),
    /// The node is disconnected.
    Disconnect(String),
}

impl Fault {
    /// The timeline steps that carry it out: its start, and its undoing where that is a step of
    /// its own.
    pub fn steps(&self) -> Vec<Step> {
        let step = |action| Step {
            at_s: self.at_s,
            action,
        };
        let undo = |action| Step {
            at_s: self.until_s,
            action,
        };
        let until_s = Some(self.until_s);
        match &self.hit {
            Hit::BitErrors(rate) => vec![step(Action::BitErrors {
                target: Target::Any,
                hits: Hits::BitErrorRate(*rate),
                until_s,
                kind: ErrorKind::Bit,
                seen_by: SeenBy::All,
            })],
            Hit::ErrorPassive { node, every } => vec![step(Action::BitErrors {
                target: Target::Node(node.clone()),
                hits: Hits::EveryNth(*every),
                until_s,
                kind: ErrorKind::Bit,
                seen_by: SeenBy::All,
            })],
            Hit::Crash(node) => vec![step(Action::Crash(node.clone()))],
            Hit::Hang(node) => vec![
                step(Action::Hang(node.clone())),
                undo(Action::Resume(node.clone())),
            ],
            Hit::Disconnect(node) => vec![
                step(Action::Disconnect(node.clone())),
                undo(Action::Reconnect(node.clone())),
            ],
            Hit::Babble(frame) => vec![step(Action::Babble {
                frame: frame.clone(),
                until_s: self.until_s,
            })],
        }
    }

    /// Whether it can be undone (a crash cannot: the supervisor restarts the node).
    pub fn lasts(&self) -> bool {
        !matches!(self.hit, Hit::Crash(_))
    }
}

/// The steps of a section (see the module contract): [`draw`]'s faults, one after the other.
pub fn expand(r: &RandomFaults, seed: u64, duration_s: f64, nodes: &[String]) -> Vec<Step> {
    draw(r, seed, duration_s, nodes)
        .iter()
        .flat_map(Fault::steps)
        .collect()
}

/// The faults of a section, in the order they start (see the module contract). `nodes` are
/// every node of the run; the section's own list, when given, narrows them. Call [`problems`]
/// first: a section with problems gives no faults.
pub fn draw(r: &RandomFaults, seed: u64, duration_s: f64, nodes: &[String]) -> Vec<Fault> {
    if !problems(r, duration_s, nodes).is_empty() {
        return Vec::new();
    }
    let pool: Vec<&String> = if r.nodes.is_empty() {
        nodes.iter().collect()
    } else {
        r.nodes.iter().collect()
    };
    // A stream of its own: drawing more here never changes the bus's or the plant's randomness.
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_FA17_0000_0000);
    let last_start = duration_s - r.quiet_end_s;
    let mut free_at: BTreeMap<&String, f64> = BTreeMap::new();
    let mut babble_free_at = 0.0;
    let mut bag: Vec<RandomFault> = Vec::new();
    let mut faults = Vec::new();
    let mut t = r.from_s;
    loop {
        // Exponential gap: -mean * ln(1 - u), u in [0, 1).
        t += -r.mean_interval_s * (1.0 - rng.random::<f64>()).ln();
        if t >= last_start {
            break;
        }
        if bag.is_empty() {
            bag = r.kinds.clone();
            bag.shuffle(&mut rng);
        }
        let Some(kind) = bag.pop() else { break };
        let at = ms(t);
        let until = ms((t + rng.random_range(r.min_fault_s..=r.max_fault_s)).min(duration_s));
        let node = if kind.needs_node() {
            let free: Vec<&String> = pool
                .iter()
                .copied()
                .filter(|n| free_at.get(n).is_none_or(|&f| f <= at))
                .collect();
            if free.is_empty() {
                continue;
            }
            let n = free[rng.random_range(0..free.len())];
            free_at.insert(n, until + r.node_rest_s);
            n.clone()
        } else {
            String::new()
        };
        let hit = match kind {
            RandomFault::BitErrors => Hit::BitErrors(f64::from(rng.random_range(10u32..=100)) * 1e-6),
            RandomFault::ErrorPassive => Hit::ErrorPassive { node, every: 2 },
            RandomFault::Crash => Hit::Crash(node),
            RandomFault::Hang => Hit::Hang(node),
            RandomFault::Disconnect => Hit::Disconnect(node),
            RandomFault::Babble => {
                if babble_free_at > at {
                    continue;
                }
                babble_free_at = until;
                let data: [u8; 8] = rng.random();
                let hex: String = data.iter().map(|b| format!("{b:02X}")).collect();
                Hit::Babble(format!("{BABBLE_ID:08X}#{hex}"))
            }
        };
        let until_s = if matches!(hit, Hit::Crash(_)) { at } else { until };
        faults.push(Fault {
            at_s: at,
            until_s,
            hit,
        });
    }
    faults
}

#[cfg(test)]
mod tests;
