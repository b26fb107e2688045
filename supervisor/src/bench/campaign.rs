//! The campaign workload: runs of the built-in campaign `harvest` (the default harvester for
//! 60 s with random faults) on every core, as `harvemu campaign` plays them.

use crate::campaign::{self, Campaign, Shard};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Campaign throughput.
#[derive(Serialize, Debug, Clone)]
pub struct Throughput {
    /// Always "campaign".
    pub scenario: &'static str,
    /// Runs played.
    pub runs: u64,
    /// Runs played at once.
    pub jobs: usize,
    /// Virtual seconds per run.
    pub virtual_seconds: f64,
    /// Faults drawn, all runs.
    pub faults: u64,
    /// Runs that failed (and were shrunk).
    pub failed: u64,
    /// Wall-clock seconds.
    pub wall_seconds: f64,
    /// Runs per wall-clock hour.
    pub runs_per_hour: f64,
}

/// Plays `runs` runs of the built-in campaign on `jobs` threads.
pub fn measure(runs: u64, jobs: usize) -> crate::Result<Throughput> {
    let c = Campaign::open(Path::new("configs/campaigns/harvest.ron"), None, None)?;
    let faults = (0..runs).map(|i| c.history(i).1.faults.len() as u64).sum();
    let started = Instant::now();
    let mut failed = 0;
    let done = campaign::play(&c, Shard::ALL, runs, jobs, 400, |r| {
        failed += u64::from(r.failure.is_some());
        true
    })
    .map_err(crate::Error::Internal)?;
    let wall = started.elapsed().as_secs_f64();
    Ok(Throughput {
        scenario: "campaign",
        runs: done,
        jobs,
        virtual_seconds: c.base.scenario.duration_s,
        faults,
        failed,
        wall_seconds: wall,
        runs_per_hour: done as f64 * 3600.0 / wall.max(1e-9),
    })
}
