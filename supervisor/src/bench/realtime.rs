//! The realtime workload: the harvester paced by the wall clock, watched from outside the hub.
//!
//! An observer takes every frame as the hub commits it (where a SocketCAN bridge or a socketcand
//! client would) and notes the wall-clock time. For every identifier that is periodic on the bus
//! (all its bus-time periods within 10 % of their median), each wall-clock period is compared with
//! that median: the differences are the period jitter. Losses are everything a frame can fall
//! into on the way: receive overruns, refused or aborted transmissions, error frames, and frames
//! the observer itself missed.

use super::Measurement;
use crate::harvester::{self, Harvester};
use actix::prelude::*;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::{GetSnapshot, Observed, Subscribe, runtime};
use serde::Serialize;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;
use std::time::Instant;

/// Period jitter against the wall clock, and losses.
#[derive(Serialize, Debug, Clone, Default, PartialEq)]
pub struct Jitter {
    /// Identifiers found periodic.
    pub periodic_ids: usize,
    /// Periods measured.
    pub periods: usize,
    /// Median of |wall period - nominal period|, ms.
    pub p50_ms: f64,
    /// 99th percentile, ms.
    pub p99_ms: f64,
    /// Largest, ms.
    pub max_ms: f64,
    /// Frames the observer missed (its queue was full).
    pub observer_missed: u64,
    /// Frames lost to full receive FIFOs, all controllers.
    pub rx_overruns: u64,
    /// Frames refused by full transmit queues.
    pub tx_refused: u64,
    /// Frames dropped at bus off.
    pub tx_aborted: u64,
    /// Error frames on the bus.
    pub error_frames: u64,
}

impl Jitter {
    /// Frames lost, all causes.
    pub fn lost(&self) -> u64 {
        self.observer_missed + self.rx_overruns + self.tx_refused + self.tx_aborted
    }

    /// One line for the table.
    pub fn summary(&self) -> String {
        format!(
            "  period jitter over {} periods of {} periodic ids: p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms; \
             lost {} (observer {}, overruns {}, refused {}, aborted {}), error frames {}",
            self.periods,
            self.periodic_ids,
            self.p50_ms,
            self.p99_ms,
            self.max_ms,
            self.lost(),
            self.observer_missed,
            self.rx_overruns,
            self.tx_refused,
            self.tx_aborted,
            self.error_frames
        )
    }
}

/// Frames seen, per identifier: (bus time, wall time in ns since the start).
#[derive(Default)]
pub struct Sightings {
    by_id: BTreeMap<u32, Vec<(BusTime, u64)>>,
}

impl Sightings {
    /// Notes one frame.
    pub fn add(&mut self, id: u32, bus: BusTime, wall_ns: u64) {
        self.by_id.entry(id).or_default().push((bus, wall_ns));
    }

    /// Frames noted.
    pub fn count(&self) -> u64 {
        self.by_id.values().map(|v| v.len() as u64).sum()
    }

    /// Period jitter of the periodic identifiers (losses left at zero).
    pub fn jitter(&self) -> Jitter {
        let mut deviations = Vec::new();
        let mut periodic_ids = 0;
        for seen in self.by_id.values().filter(|v| v.len() >= 3) {
            let bus: Vec<u64> = seen
                .windows(2)
                .map(|w| w[1].0.as_nanos() - w[0].0.as_nanos())
                .collect();
            let nominal = median(&bus);
            // Event-driven identifiers have no period to keep.
            if nominal == 0 || bus.iter().any(|&p| p.abs_diff(nominal) * 10 > nominal) {
                continue;
            }
            periodic_ids += 1;
            deviations.extend(
                seen.windows(2)
                    .map(|w| w[1].1.saturating_sub(w[0].1).abs_diff(nominal)),
            );
        }
        deviations.sort_unstable();
        let ms = |ns: u64| ns as f64 / 1e6;
        Jitter {
            periodic_ids,
            periods: deviations.len(),
            p50_ms: ms(percentile(&deviations, 50)),
            p99_ms: ms(percentile(&deviations, 99)),
            max_ms: ms(deviations.last().copied().unwrap_or(0)),
            ..Jitter::default()
        }
    }
}

fn median(values: &[u64]) -> u64 {
    let mut v = values.to_vec();
    v.sort_unstable();
    v.get(v.len() / 2).copied().unwrap_or(0)
}

/// The nearest-rank percentile of sorted values.
fn percentile(sorted: &[u64], p: usize) -> u64 {
    if sorted.is_empty() {
        return 0;
    }
    let rank = (p * sorted.len()).div_ceil(100).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// Runs the harvester in real time for `seconds` and measures it.
pub fn measure(h: &Harvester, seconds: f64) -> Result<Measurement, String> {
    super::reset_peak_rss();
    let system = System::with_tokio_rt(|| runtime(false).expect("a tokio runtime"));
    let h = h.clone();
    let started = Instant::now();
    let (jitter, snap) = system.block_on(async move {
        let mut running = harvester::start(&h, true, Vec::new())
            .await
            .map_err(|e| e.report().to_string())?;
        // Large enough for minutes of traffic: the observer must not be the one losing frames.
        let (tx, mut rx) = tokio::sync::mpsc::channel::<Observed>(65_536);
        running.hub.send(Subscribe(tx)).await.map_err(|e| e.to_string())?;
        // Frames of the start-up, before the observer came, are not the observer's to miss.
        let before = running
            .hub
            .send(GetSnapshot)
            .await
            .map_err(|e| e.to_string())?
            .stats
            .frames;
        let sightings = Rc::new(RefCell::new(Sightings::default()));
        let watch = sightings.clone();
        let origin = Instant::now();
        actix::spawn(async move {
            while let Some(o) = rx.recv().await {
                let wall = u64::try_from(origin.elapsed().as_nanos()).unwrap_or(u64::MAX);
                watch.borrow_mut().add(o.frame.raw_id(), o.at, wall);
            }
        });
        let from = running.now();
        running
            .run_until(from + BusDuration::from_secs_f64(seconds))
            .await
            .map_err(|e| e.report().to_string())?;
        // Let the observer take what is still queued.
        tokio::task::yield_now().await;
        let snap = running.hub.send(GetSnapshot).await.map_err(|e| e.to_string())?;
        let s = sightings.borrow();
        let mut jitter = s.jitter();
        let during = snap.stats.frames.saturating_sub(before);
        jitter.observer_missed = during.saturating_sub(s.count());
        Ok::<_, String>((jitter, snap))
    })?;
    let wall = started.elapsed().as_secs_f64();
    let mut jitter = jitter;
    for n in &snap.nodes {
        jitter.rx_overruns += n.counters.rx_overruns;
        jitter.tx_refused += n.counters.tx_refused;
        jitter.tx_aborted += n.counters.tx_aborted;
    }
    jitter.error_frames = snap.stats.error_frames;
    Ok(Measurement {
        scenario: "realtime".into(),
        buses: 1,
        threads: 1,
        virtual_seconds: seconds,
        wall_seconds: wall,
        frames: snap.stats.frames,
        frames_per_second: snap.stats.frames as f64 / wall,
        deliveries: snap.stats.deliveries,
        deliveries_per_second: snap.stats.deliveries as f64 / wall,
        wakes: snap.wakes,
        bus_load: snap.stats.total_load(),
        peak_rss_bytes: super::peak_rss_bytes(),
        speedup: seconds / wall,
        jitter: Some(jitter),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    #[test]
    fn jitter_is_measured_on_periodic_identifiers_against_their_bus_period() {
        let mut s = Sightings::default();
        // A 100 ms identifier whose wall-clock periods deviate by 0, 2, 0 and 1 ms.
        let walls = [0, 100, 202, 302, 403];
        for (i, w) in walls.iter().enumerate() {
            s.add(0x100, BusTime::from_nanos(i as u64 * 100 * MS), w * MS);
        }
        // An event-driven identifier (bus gaps 10, 500, 30 ms) is not periodic: left out.
        for (bus, wall) in [(0, 0), (10, 10), (510, 900), (540, 950)] {
            s.add(0x200, BusTime::from_nanos(bus * MS), wall * MS);
        }
        let j = s.jitter();
        assert_eq!(j.periodic_ids, 1);
        assert_eq!(j.periods, 4);
        // |100-100|, |102-100|, |100-100|, |101-100| sorted: 0, 0, 1, 2 ms.
        assert_eq!(j.max_ms, 2.0);
        assert_eq!(j.p50_ms, 0.0);
        assert_eq!(j.p99_ms, 2.0);
        assert_eq!(s.count(), 9);
    }

    #[test]
    fn nearest_rank_percentiles() {
        let v: Vec<u64> = (1..=200).collect();
        assert_eq!(percentile(&v, 50), 100);
        assert_eq!(percentile(&v, 99), 198);
        assert_eq!(percentile(&[], 99), 0);
        assert_eq!(percentile(&[7], 1), 7);
    }
}
