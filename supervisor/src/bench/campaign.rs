//! The campaign workload: runs of the built-in campaign `harvest` (the default harvester for
//! 60 s with random faults) on every core, as `harvemu campaign` plays them.

use crate::campaign::{self, Campaign};
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
    let c = Campaign::open(Path::new("configs/campaigns/harvest.ron"), None, runs)?;
    let numbers: Vec<u64> = (0..runs).collect();
    let faults = numbers.iter().map(|&i| c.history(i).1.faults.len() as u64).sum();
    let started = Instant::now();
    let results = campaign::play(&c, &numbers, jobs, 400, |_| {});
    let wall = started.elapsed().as_secs_f64();
    Ok(Throughput {
        scenario: "campaign",
        runs: results.len() as u64,
        jobs,
        virtual_seconds: c.base.scenario.duration_s,
        faults,
        failed: results.values().filter(|r| r.failure.is_some()).count() as u64,
        wall_seconds: wall,
        runs_per_hour: results.len() as f64 * 3600.0 / wall.max(1e-9),
    })
}
