//! Time series of a scenario run, for the run report: what the hub's statistics do not keep.
//!
//! Contract: the scenario loop stops the bus at [`Series::next_stop`] on its way to any target;
//! whenever [`Series::is_due`] says so it reads a [`Sample`] and hands it to [`Series::record`].
//! That gives one sample at each whole bus second from the end of start-up to the end of the run,
//! up to [`MAX_SAMPLES`]: past that, every other sample is dropped and the period doubles (as the
//! hub's histories do), so a day-long soak keeps its memory flat.
//! At the end, [`Series::finish`] copies the hub's own histories (load per second, latency per
//! priority, error counters at each error) from the final snapshot. Sampling only reads, and the
//! bus already stops at every 10 ms for supervision, so a run gives the same verdicts whether
//! anyone looks at its series or not.

use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::Snapshot;

/// Sampling period.
pub const SAMPLE: BusDuration = BusDuration::from_secs(1);
/// Most samples kept before the resolution halves.
pub const MAX_SAMPLES: usize = 4096;

/// What was read at one whole second.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sample {
    /// Bus time, s.
    pub t_s: f64,
    /// The plant's true travel speed, km/h.
    pub speed_kmh: f64,
    /// The plant's true harvested mass, kg.
    pub harvested_kg: f64,
    /// Travel speed on the monitor's display, km/h (no monitor, or nothing shown yet: `None`).
    pub monitor_speed_kmh: Option<f64>,
    /// Yield on the monitor's display, kg (no monitor: `None`).
    pub monitor_kg: Option<f64>,
    /// (TEC, REC) of every node, by node index.
    pub counters: Vec<(u16, u16)>,
}

/// Queueing latency of one priority class over the whole run.
#[derive(Clone, Debug, PartialEq)]
pub struct ClassLatency {
    /// "P0" to "P31" for extended identifiers by their priority field, "base" for base frames.
    pub class: String,
    /// Frames.
    pub frames: u64,
    /// Mean, µs.
    pub mean_us: f64,
    /// 99th percentile (an upper bound within 19 %), µs.
    pub p99_us: f64,
    /// Largest, µs.
    pub max_us: f64,
}

/// One node's error counters over time.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeCounters {
    /// Node name.
    pub node: String,
    /// (time s, TEC, REC), in time order: the hub's points at each error merged with the
    /// per-second samples, which show the counters decaying between errors.
    pub points: Vec<(f64, u16, u16)>,
}

/// The series of one run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// One per whole bus second, in time order.
    pub samples: Vec<Sample>,
    /// Bus load per 1 s window (end of window s, load 0..=1) over the whole run, from the hub.
    /// Past 4096 s the hub halves its resolution, so this may then have fewer points.
    pub load: Vec<(f64, f64)>,
    /// Latency per priority class that carried frames.
    pub latency: Vec<ClassLatency>,
    /// Every node whose counters were ever above zero.
    pub counters: Vec<NodeCounters>,
    /// Bus time the run reached, s.
    pub end_s: f64,
    next: Option<BusTime>,
    /// Sampling period: [`SAMPLE`] times a power of two (zero before the first halving).
    period: BusDuration,
}

fn ceil_to_sample(t: BusTime) -> BusTime {
    t.ceil_to(SAMPLE)
}

impl Series {
    /// The present sampling period.
    pub fn period(&self) -> BusDuration {
        self.period.max(SAMPLE)
    }

    /// The next sampling time, given that the bus is at `now`.
    fn due(&self, now: BusTime) -> BusTime {
        self.next.unwrap_or_else(|| ceil_to_sample(now))
    }

    /// Where the bus should stop next on its way from `now` to `target`.
    pub fn next_stop(&self, now: BusTime, target: BusTime) -> BusTime {
        self.due(now).min(target).max(now)
    }

    /// Whether a sample is due at `now`.
    pub fn is_due(&self, now: BusTime) -> bool {
        now >= self.due(now)
    }

    /// Keeps a sample read at `now`; the next one is due at the following whole second.
    pub fn record(&mut self, now: BusTime, mut sample: Sample) {
        sample.t_s = now.as_secs_f64();
        self.samples.push(sample);
        if self.samples.len() > MAX_SAMPLES {
            // Halve the resolution: keep every other sample, sample half as often from now on.
            let mut i = 0;
            self.samples.retain(|_| {
                i += 1;
                i % 2 == 1
            });
            self.period = self.period() * 2;
        }
        self.next = Some(now.next_multiple_of(self.period()));
    }

    /// Takes the hub's histories from the final snapshot.
    pub fn finish(&mut self, snap: &Snapshot) {
        self.end_s = snap.now.as_secs_f64();
        let stats = &snap.stats;
        self.load = stats
            .load_history
            .points
            .iter()
            .map(|(t, l)| (t.as_secs_f64(), f64::from(*l)))
            .collect();
        self.latency = stats
            .latency
            .iter()
            .enumerate()
            .filter(|(_, l)| l.count > 0)
            .map(|(p, l)| ClassLatency {
                class: if p < 32 { format!("P{p}") } else { "base".into() },
                frames: l.count,
                mean_us: l.mean_ns().unwrap_or(0.0) / 1e3,
                p99_us: l.quantile_ns(0.99).unwrap_or(0.0) / 1e3,
                max_us: l.max_ns as f64 / 1e3,
            })
            .collect();
        self.counters = snap
            .nodes
            .iter()
            .enumerate()
            .filter_map(|(i, node)| {
                let errors = stats.nodes.get(i).map_or(&[][..], |h| &h.counters.points[..]);
                let mut points: Vec<(f64, u16, u16)> = errors
                    .iter()
                    .map(|(t, (tec, rec, _))| (t.as_secs_f64(), *tec, *rec))
                    .collect();
                for s in &self.samples {
                    let (tec, rec) = s.counters.get(i).copied().unwrap_or((0, 0));
                    points.push((s.t_s, tec, rec));
                }
                // Stable: at equal times a sample (the state after everything at that time)
                // comes after the errors.
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                points.push((self.end_s, node.tec, node.rec));
                points.iter().any(|p| p.1 > 0 || p.2 > 0).then(|| NodeCounters {
                    node: node.name.clone(),
                    points,
                })
            })
            .collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Drives the sampling contract as the scenario loop does, with a bus that stops exactly
    /// where it is asked to (or `overshoot` ns later); returns the sample times in ns.
    fn drive(start: BusTime, targets: &[u64], overshoot: u64) -> Vec<u64> {
        let mut series = Series::default();
        let mut now = start;
        for &target in targets {
            let target = BusTime::from_nanos(target).max(now);
            loop {
                let stop = series.next_stop(now, target);
                if stop > now {
                    now = stop + bus::time::BusDuration::from_nanos(overshoot);
                }
                if series.is_due(now) {
                    series.record(now, Sample::default());
                }
                if now >= target {
                    break;
                }
            }
        }
        series
            .samples
            .iter()
            .map(|s| (s.t_s * 1e9).round() as u64)
            .collect()
    }

    const S: u64 = 1_000_000_000; // one sample period, ns

    #[test]
    fn one_sample_per_whole_second_after_start_up() {
        // Start-up ends at 0.5 s; a timeline entry at 5 s (twice) and at 7.25 s; the run ends at
        // 10 s, which the loop reaches in 1 s steps.
        let mut targets = vec![5 * S, 5 * S, 7 * S + S / 4];
        targets.extend((8..=10).map(|k| k * S));
        let times = drive(BusTime::from_nanos(S / 2), &targets, 0);
        let expected: Vec<u64> = (1..=10).map(|k| k * S).collect();
        assert_eq!(times, expected, "10 s run: 10 samples");
    }

    #[test]
    fn a_run_that_ends_between_seconds_and_a_start_on_a_second() {
        // Start-up ends exactly at 2 s: that second is sampled too; the end at 4.5 s is not.
        let times = drive(BusTime::from_nanos(2 * S), &[4 * S + S / 2], 0);
        assert_eq!(times, vec![2 * S, 3 * S, 4 * S]);
    }

    #[test]
    fn a_long_run_halves_its_resolution_and_keeps_its_memory_bounded() {
        let run = 3 * MAX_SAMPLES as u64 + 5;
        let times = drive(BusTime::from_nanos(0), &[run * S], 0);
        assert!(times.len() <= MAX_SAMPLES, "{} samples", times.len());
        assert!(times.len() > MAX_SAMPLES / 2, "{} samples", times.len());
        // Still in time order, from the start to near the end, on whole seconds.
        assert!(times.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(times[0], 0);
        assert!(*times.last().unwrap() > (run - 4) * S);
        assert!(times.iter().all(|t| t % S == 0));
        // After two halvings, samples are 4 s apart.
        assert_eq!(times[times.len() - 1] - times[times.len() - 2], 4 * S);
    }

    #[test]
    fn a_bus_that_stops_late_still_gives_one_sample_per_second() {
        let times = drive(BusTime::from_nanos(0), &[3 * S + 1000], 10);
        assert_eq!(times, vec![0, S + 10, 2 * S + 10, 3 * S + 10]);
    }
}
