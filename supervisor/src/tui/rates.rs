//! Frames per second per identifier, over the last second (or more) of bus time.
//!
//! Contract: [`RateMeter::update`] is given each snapshot the display shows, in time order;
//! [`RateMeter::rate`] then divides the frames counted since the oldest kept snapshot (the
//! newest one at least [`WINDOW`] old) by the bus time between them. Until two snapshots
//! span some time, it falls back to the mean period over the whole run. No clock is read: the
//! window is bus time, so a fast run and a real-time one show the same rates.

use bus::engine::stats::IdStats;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::Snapshot;
use std::collections::{HashMap, VecDeque};

/// The span of bus time rates are measured over, at least.
pub const WINDOW: BusDuration = BusDuration::from_secs(1);
/// Most snapshots kept: refreshes far more often than the window would otherwise pile up.
const MAX_SAMPLES: usize = 64;

/// Per-identifier frame counts at a few recent bus times.
#[derive(Clone, Debug, Default)]
pub struct RateMeter {
    samples: VecDeque<(BusTime, HashMap<u32, u64>)>,
}

impl RateMeter {
    /// Takes the counts of a new snapshot and forgets those no longer needed.
    pub fn update(&mut self, snapshot: &Snapshot) {
        let now = snapshot.now;
        // A snapshot from before the newest one (a new run) starts the window afresh.
        if self.samples.back().is_some_and(|(t, _)| *t > now) {
            self.samples.clear();
        }
        let counts = snapshot
            .stats
            .per_id
            .iter()
            .map(|(id, s)| (*id, s.count))
            .collect();
        self.samples.push_back((now, counts));
        // Keep the newest sample that is at least a window old, and everything after it.
        while self.samples.len() >= 2 && now - self.samples[1].0 >= WINDOW {
            self.samples.pop_front();
        }
        while self.samples.len() > MAX_SAMPLES {
            self.samples.pop_front();
        }
    }

    /// Frames per second of identifier `id` (kernel form), whose statistics are `stats` now.
    pub fn rate(&self, id: u32, stats: &IdStats) -> f64 {
        if let (Some((t0, old)), Some((t1, new))) = (self.samples.front(), self.samples.back())
            && t1 > t0
        {
            // An identifier missing from the older counts had sent nothing yet.
            let before = old.get(&id).copied().unwrap_or(0);
            let after = new.get(&id).copied().unwrap_or(stats.count);
            return after.saturating_sub(before) as f64 / (*t1 - *t0).as_secs_f64();
        }
        stats.mean_period_ns().map_or(0.0, |p| 1e9 / p)
    }
}
