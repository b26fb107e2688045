//! Fault campaigns: many runs of one scenario, each with its own random faults, every failing
//! run shrunk to a small scenario that fails the same way.
//!
//! Contract: run `i` of a campaign with seed `S` is the scenario with its `random_faults` drawn
//! from the seed [`shard::run_seed`]`(S, i)`, which is also the run's bus seed; its properties
//! are the scenario's expectations with `TraceComplete` and `NoCrashes` added, and it fails
//! when any of them fails, when harvemu panics or when the run ends with an error. A failing
//! run is shrunk ([`shrink`]) with candidates that fail the same (first) expectation and pass
//! validation, and written as an ordinary scenario with a plain timeline, so that `harvemu
//! scenario` reruns it to the same failure. Everything a campaign writes ([`summary`]) follows
//! from the scenario, the seed, the run count and the shard: not from the number of jobs, the
//! machine or the wall clock. A stop signal ends the campaign after the runs under way; the
//! summary then covers the shard's runs before the first one left undone and says so.

mod claim;
pub mod cli;
mod merge;
mod outputs;
mod paths;
mod runs;
pub mod shard;
pub mod shrink;
pub mod summary;

pub use runs::{Campaign, Failure, NO_ERROR, NO_PANIC, RunResult, fnv1a, play};
pub use shard::Shard;
