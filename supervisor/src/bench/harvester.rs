//! The harvester workload: whole harvesters, each on its own hub, in virtual time.

use super::Totals;
use crate::harvester::{self, Harvester};
use actix::prelude::*;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::runtime;

/// Bus time each harvester runs before the next one's turn.
const SLICE: BusDuration = BusDuration::from_secs(1);

/// Runs `count` harvesters on this thread for `seconds` of virtual time each; harvester `i` gets
/// the config's seed plus `first + i`, so that no two buses run the same traffic in lockstep.
pub fn run_on_this_thread(h: &Harvester, count: usize, first: u64, seconds: f64) -> Result<Totals, String> {
    let system = System::with_tokio_rt(|| runtime(true).expect("a tokio runtime"));
    let h = h.clone();
    system.block_on(async move {
        let mut running = Vec::new();
        for i in 0..count as u64 {
            let mut h = h.clone();
            h.config.network.seed = h.config.network.seed.wrapping_add(first + i);
            running.push(
                harvester::start(&h, false, Vec::new())
                    .await
                    .map_err(|e| e.report().to_string())?,
            );
        }
        // Round robin in slices of bus time, one harvester at a time: each one's working set
        // (plant, scripts, queues) stays in the core's cache for a whole slice instead of being
        // evicted at every wake by the next harvester's.
        let until = BusTime::from_secs_f64(seconds);
        let mut reached = BusTime::ZERO;
        while reached < until {
            reached = (reached + SLICE).min(until);
            for r in &mut running {
                r.run_until(reached).await.map_err(|e| e.report().to_string())?;
            }
        }
        let hubs: Vec<_> = running.iter().map(|r| r.hub.clone()).collect();
        super::totals(&hubs).await
    })
}
