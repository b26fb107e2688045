//! Bus statistics, kept as the bus runs, in memory that does not grow with the run's length.

use super::NodeId;
use crate::fault::ErrorState;
use crate::time::{BusDuration, BusTime, TICKS_PER_NS};
use serde::Serialize;
use std::collections::HashMap;

/// Width of one load bucket.
pub const BUCKET: BusDuration = BusDuration::from_millis(10);
/// Buckets kept for sliding windows (10 s).
const BUCKETS: usize = 1000;
/// Most points a history keeps before it halves its resolution.
const HISTORY_POINTS: usize = 4096;
/// Most identifiers tracked one by one; the rest are counted together.
const MAX_IDS: usize = 4096;
/// How many latency classes are counted (a protocol maps its priorities onto them).
pub const LATENCY_CLASSES: usize = 33;

/// Period statistics of one identifier.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct IdStats {
    /// Frames seen.
    pub count: u64,
    /// End of the first frame.
    pub first: BusTime,
    /// End of the last frame.
    pub last: BusTime,
    /// Shortest interval between consecutive frames, ns.
    pub min_period_ns: u64,
    /// Longest interval, ns.
    pub max_period_ns: u64,
    mean: f64,
    m2: f64,
    /// Payload of the last frame (live views show it decoded); `last_len` bytes are valid.
    last_data: [u8; 8],
    last_len: u8,
}

impl IdStats {
    fn record(&mut self, at: BusTime, payload: &[u8]) {
        // A classic frame carries at most 8 bytes; anything past that cannot reach here.
        let n = payload.len().min(8);
        self.last_data = [0; 8];
        self.last_data[..n].copy_from_slice(&payload[..n]);
        self.last_len = n as u8;
        if self.count == 0 {
            self.first = at;
            self.min_period_ns = u64::MAX;
        } else {
            let interval = (at - self.last).as_nanos();
            self.min_period_ns = self.min_period_ns.min(interval);
            self.max_period_ns = self.max_period_ns.max(interval);
            // Welford's running mean and variance of the intervals.
            let n = self.count as f64;
            let x = interval as f64;
            let delta = x - self.mean;
            self.mean += delta / n;
            self.m2 += delta * (x - self.mean);
        }
        self.last = at;
        self.count += 1;
    }
    /// The payload of the last frame (empty for a remote frame or before the first frame).
    pub fn last_payload(&self) -> &[u8] {
        &self.last_data[..usize::from(self.last_len)]
    }
    /// Mean interval between frames, ns (None with fewer than two frames).
    pub fn mean_period_ns(&self) -> Option<f64> {
        (self.count >= 2).then_some(self.mean)
    }
    /// Sample standard deviation of the interval (the period jitter), ns; zero with a single
    /// interval.
    pub fn jitter_ns(&self) -> Option<f64> {
        let intervals = self.count.checked_sub(1)?;
        match intervals {
            0 => None,
            1 => Some(0.0),
            n => Some((self.m2 / (n - 1) as f64).sqrt()),
        }
    }
}

/// A latency distribution: count, mean, maximum and a log-scale histogram for percentiles.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Latency {
    /// Samples.
    pub count: u64,
    /// Sum of samples, ns.
    pub sum_ns: u128,
    /// Largest sample, ns.
    pub max_ns: u64,
    /// Bucket k counts samples below 2^((k+1)/4) µs and at or above the previous bound.
    buckets: Vec<u64>,
}

impl Default for Latency {
    fn default() -> Self {
        Latency {
            count: 0,
            sum_ns: 0,
            max_ns: 0,
            buckets: vec![0; 128],
        }
    }
}

impl Latency {
    fn bucket(ns: u64) -> usize {
        let us = ns as f64 / 1000.0;
        if us < 1.0 {
            0
        } else {
            ((us.log2() * 4.0).floor() as usize + 1).min(127)
        }
    }
    fn upper_bound_ns(bucket: usize) -> f64 {
        2f64.powf(bucket as f64 / 4.0) * 1000.0
    }
    /// Adds a sample.
    pub fn record(&mut self, ns: u64) {
        self.count += 1;
        self.sum_ns += u128::from(ns);
        self.max_ns = self.max_ns.max(ns);
        self.buckets[Self::bucket(ns)] += 1;
    }
    /// Mean, ns.
    pub fn mean_ns(&self) -> Option<f64> {
        (self.count > 0).then(|| self.sum_ns as f64 / self.count as f64)
    }
    /// An upper bound of the `q` quantile (0..=1), within a factor 2^(1/4) of the true value.
    pub fn quantile_ns(&self, q: f64) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let rank = (q.clamp(0.0, 1.0) * self.count as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for (k, n) in self.buckets.iter().enumerate() {
            seen += n;
            if seen >= rank {
                return Some(Self::upper_bound_ns(k).min(self.max_ns as f64));
            }
        }
        Some(self.max_ns as f64)
    }
}

/// Points (time, value) that halve their resolution when full, so a day-long run stays small.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct History<T> {
    /// The kept points, oldest first.
    pub points: Vec<(BusTime, T)>,
    stride: u64,
    seen: u64,
}

impl<T> Default for History<T> {
    fn default() -> Self {
        History {
            points: Vec::new(),
            stride: 1,
            seen: 0,
        }
    }
}

impl<T: Copy> History<T> {
    /// Adds a point; when full, every other point is dropped and only every second new point
    /// is kept from then on.
    pub fn push(&mut self, at: BusTime, value: T) {
        self.seen += 1;
        if !self.seen.is_multiple_of(self.stride) {
            return;
        }
        if self.points.len() >= HISTORY_POINTS {
            let mut i = 0;
            self.points.retain(|_| {
                i += 1;
                i % 2 == 0
            });
            self.stride *= 2;
        }
        self.points.push((at, value));
    }
}

/// Per-node error history.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct NodeHistory {
    /// (time, TEC, REC, state) at each change, thinned past 4096 points (for plots).
    pub counters: History<(u16, u16, ErrorState)>,
    /// The same points for judging: never thinned across a change of state.
    pub spans: Spans,
}

/// Most spans a node keeps before it merges neighbours in the same state.
const SPANS: usize = 8192;

/// One or more consecutive history points in one error state: from `from` to `to` (the times
/// of its first and last point), with the highest TEC and REC among them.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
pub struct Span {
    /// First point.
    pub from: BusTime,
    /// Last point (`from` for a single point).
    pub to: BusTime,
    /// Highest TEC.
    pub tec: u16,
    /// Highest REC.
    pub rec: u16,
    /// The state throughout.
    pub state: ErrorState,
}

/// A node's history for judging, in memory that does not grow with the run: every point until
/// there are [`SPANS`] of them, then neighbours in the same state merge, keeping the highest
/// counters. A change of state is never merged away, so when and how long a node was in each
/// state stays exact; counters stay exact where no merged span is.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Spans {
    /// Oldest first.
    pub list: Vec<Span>,
    /// Some spans hold more than one point.
    pub merged: bool,
    /// Changes of state were so many that some were lost (past 4 × [`SPANS`] spans that could
    /// not merge); state judgements are then no longer exact.
    pub lost: bool,
}

impl Spans {
    /// Adds a point.
    pub fn push(&mut self, at: BusTime, tec: u16, rec: u16, state: ErrorState) {
        if self.list.len() >= SPANS {
            self.merge();
        }
        if self.list.len() >= 4 * SPANS {
            // Only alternating states can get here; keep the newest.
            self.list.remove(0);
            self.lost = true;
        }
        self.list.push(Span {
            from: at,
            to: at,
            tec,
            rec,
            state,
        });
    }

    /// Merges pairs of neighbours in the same state.
    fn merge(&mut self) {
        let mut out: Vec<Span> = Vec::with_capacity(self.list.len());
        let mut i = 0;
        while i < self.list.len() {
            let a = self.list[i];
            match self.list.get(i + 1) {
                Some(b) if b.state == a.state => {
                    out.push(Span {
                        from: a.from,
                        to: b.to,
                        tec: a.tec.max(b.tec),
                        rec: a.rec.max(b.rec),
                        state: a.state,
                    });
                    self.merged = true;
                    i += 2;
                }
                _ => {
                    out.push(a);
                    i += 1;
                }
            }
        }
        self.list = out;
    }
}

/// Everything the bus measures.
#[derive(Clone, Debug, Serialize)]
pub struct Stats {
    /// Bus time covered.
    pub elapsed: BusTime,
    /// Bits the bus was busy (frames, error frames, intermission).
    pub busy_bits: u64,
    /// End of the last busy stretch (a frame committed before a stop may end after it).
    pub busy_until: BusTime,
    #[serde(rename = "bit_ns")]
    bit: BusDuration,
    /// Successful frames.
    pub frames: u64,
    /// Frames placed in receive FIFOs.
    pub deliveries: u64,
    /// Error frames, all kinds.
    pub error_frames: u64,
    /// Error frames by kind name ("bit", "ack", ...).
    pub errors_by_kind: HashMap<&'static str, u64>,
    /// Receive overruns over all nodes.
    pub overruns: u64,
    /// Overload flags sent, counted per controller.
    pub overloads: u64,
    /// Per identifier (kernel form: EFF flag set for extended).
    pub per_id: rustc_hash::FxHashMap<u32, IdStats>,
    /// Frames of identifiers beyond the tracked maximum.
    pub untracked_frames: u64,
    /// Queueing latency (submit to end of frame) per class, as the bus's
    /// [`crate::engine::LatencyClass`] sorts frames.
    pub latency: Vec<Latency>,
    /// Busy ns per 10 ms bucket over the last 10 s (ring).
    #[serde(skip)]
    buckets: Vec<BusDuration>,
    #[serde(skip)]
    bucket_index: u64,
    /// Load per second over the whole run.
    pub load_history: History<f32>,
    /// Per node error counters over time.
    pub nodes: Vec<NodeHistory>,
}

impl Stats {
    pub(crate) fn new(bit: BusDuration) -> Stats {
        Stats {
            elapsed: BusTime::ZERO,
            busy_bits: 0,
            busy_until: BusTime::ZERO,
            bit,
            frames: 0,
            overloads: 0,
            deliveries: 0,
            error_frames: 0,
            errors_by_kind: HashMap::new(),
            overruns: 0,
            per_id: Default::default(),
            untracked_frames: 0,
            latency: vec![Latency::default(); LATENCY_CLASSES],
            buckets: vec![BusDuration::ZERO; BUCKETS],
            bucket_index: 0,
            load_history: History::default(),
            nodes: Vec::new(),
        }
    }

    /// Moves the covered time forward, closing buckets and seconds on the way.
    pub(crate) fn advance_to(&mut self, now: BusTime) {
        if now <= self.elapsed {
            return;
        }
        let target = now.elapsed() / BUCKET;
        while self.bucket_index < target {
            // Closing bucket `bucket_index`; at each whole second, record the second's load.
            let closing = self.bucket_index;
            self.bucket_index += 1;
            let next = (self.bucket_index as usize) % BUCKETS;
            if (closing + 1).is_multiple_of(100) {
                let second = (0..100)
                    .map(|k| self.buckets[((closing - k) as usize) % BUCKETS])
                    .fold(BusDuration::ZERO, |a, b| a + b);
                self.load_history.push(
                    BusTime::at(BUCKET * (closing + 1)),
                    second.as_nanos() as f32 / 1e9,
                );
            }
            self.buckets[next] = BusDuration::ZERO;
        }
        self.elapsed = now;
    }

    /// Adds busy time [start, end) to the load buckets.
    pub(crate) fn busy(&mut self, start: BusTime, end: BusTime, bits: u32) {
        self.busy_bits += u64::from(bits);
        self.busy_until = self.busy_until.max(end);
        let mut t = start;
        while t < end {
            let bucket = t.elapsed() / BUCKET;
            let bucket_end = BusTime::at(BUCKET * (bucket + 1)).min(end);
            if bucket + (BUCKETS as u64) > self.bucket_index {
                self.buckets[(bucket as usize) % BUCKETS] += bucket_end - t;
            }
            t = bucket_end;
        }
    }

    pub(crate) fn frame(
        &mut self,
        kernel_id: u32,
        payload: &[u8],
        class: usize,
        end: BusTime,
        latency: BusDuration,
    ) {
        self.frames += 1;
        self.latency[class.min(LATENCY_CLASSES - 1)].record(latency.as_nanos());
        let tracked = self.per_id.len();
        match self.per_id.get_mut(&kernel_id) {
            Some(s) => s.record(end, payload),
            None if tracked < MAX_IDS => self.per_id.entry(kernel_id).or_default().record(end, payload),
            None => self.untracked_frames += 1,
        }
    }

    pub(crate) fn error(&mut self, kind: &'static str) {
        self.error_frames += 1;
        *self.errors_by_kind.entry(kind).or_default() += 1;
    }

    pub(crate) fn node_counters(&mut self, node: NodeId, at: BusTime, tec: u16, rec: u16, state: ErrorState) {
        if self.nodes.len() <= node.index() {
            self.nodes.resize_with(node.index() + 1, NodeHistory::default);
        }
        let h = &mut self.nodes[node.index()];
        h.counters.push(at, (tec, rec, state));
        h.spans.push(at, tec, rec, state);
    }

    /// Load over the whole run, 0..=1.
    pub fn total_load(&self) -> f64 {
        // In nanoseconds, as reports have always computed it (a bit time is exact in f64).
        let bit_ns = self.bit.as_ticks() as f64 / TICKS_PER_NS as f64;
        let elapsed_bits = self.elapsed.max(self.busy_until).as_nanos() as f64 / bit_ns;
        if elapsed_bits > 0.0 {
            self.busy_bits as f64 / elapsed_bits
        } else {
            0.0
        }
    }

    /// Load over the last `window` (at most 10 s) of closed 10 ms buckets, 0..=1.
    pub fn window_load(&self, window: BusDuration) -> f64 {
        let n = (window / BUCKET)
            .clamp(1, BUCKETS as u64 - 1)
            .min(self.bucket_index);
        if n == 0 {
            return 0.0;
        }
        let busy = (1..=n)
            .map(|k| self.buckets[((self.bucket_index - k) as usize) % BUCKETS])
            .fold(BusDuration::ZERO, |a, b| a + b);
        busy.as_ticks() as f64 / (BUCKET * n).as_ticks() as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn id_stats_period_and_jitter() {
        let mut s = IdStats::default();
        for t in [0u64, 100, 210, 300, 400] {
            s.record(BusTime::from_nanos(t), &[]);
        }
        // Intervals 100, 110, 90, 100: mean 100, sample std dev sqrt(200/3).
        assert_eq!(s.mean_period_ns(), Some(100.0));
        assert!((s.jitter_ns().unwrap() - (200.0f64 / 3.0).sqrt()).abs() < 1e-9);
        assert_eq!((s.min_period_ns, s.max_period_ns), (90, 110));
    }

    #[test]
    fn id_stats_keep_the_last_payload_only() {
        let mut s = IdStats::default();
        assert_eq!(s.last_payload(), &[] as &[u8]);
        s.record(BusTime::from_nanos(0), &[1, 2, 3, 4, 5, 6, 7, 8]);
        assert_eq!(s.last_payload(), &[1, 2, 3, 4, 5, 6, 7, 8]);
        // A shorter payload leaves nothing of the longer one behind.
        s.record(BusTime::from_nanos(10), &[0xAA, 0xBB]);
        assert_eq!(s.last_payload(), &[0xAA, 0xBB]);
        s.record(BusTime::from_nanos(20), &[]);
        assert_eq!(s.last_payload(), &[] as &[u8]);
        assert_eq!(s.count, 3);
    }

    #[test]
    fn latency_quantiles_bound_the_truth() {
        let mut l = Latency::default();
        for us in 1..=1000u64 {
            l.record(us * 1000);
        }
        let p99 = l.quantile_ns(0.99).unwrap();
        assert!(p99 >= 990_000.0 && p99 <= 990_000.0 * 2f64.powf(0.25), "{p99}");
        assert_eq!(l.mean_ns(), Some(500_500.0));
        assert_eq!(l.max_ns, 1_000_000);
    }

    #[test]
    fn history_stays_bounded() {
        let mut h = History::default();
        for i in 0..100_000u64 {
            h.push(BusTime::from_nanos(i), i);
        }
        assert!(h.points.len() <= HISTORY_POINTS);
        assert!(h.points.windows(2).all(|w| w[0].0 < w[1].0));
        assert!(h.points.last().unwrap().1 > 99_000);
    }

    #[test]
    fn window_and_total_load() {
        let mut s = Stats::new(BusDuration::from_micros(4));
        // Busy for the first 5 ms of every 10 ms bucket, for 2 s.
        let half = BusDuration::from_millis(5);
        for k in 0..200u64 {
            let start = BusTime::from_millis(10 * k);
            s.advance_to(start + half);
            s.busy(start, start + half, 1250);
        }
        s.advance_to(BusTime::from_nanos(2_000_000_000));
        assert!((s.total_load() - 0.5).abs() < 1e-12);
        assert!((s.window_load(BusDuration::from_secs(1)) - 0.5).abs() < 1e-12);
        assert_eq!(s.load_history.points.len(), 2);
        assert!((s.load_history.points[0].1 - 0.5).abs() < 1e-6);
        // A long idle stretch.
        s.advance_to(BusTime::from_nanos(60_000_000_000));
        assert_eq!(s.window_load(BusDuration::from_secs(1)), 0.0);
        assert_eq!(s.load_history.points.len(), 60);
    }
}
