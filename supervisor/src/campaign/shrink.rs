//! Shrinking a failing history: the smallest set of faults, shortest, earliest and mildest,
//! and the shortest run, that still fails.
//!
//! Contract (sans-IO: the caller's `fails` runs a candidate and says whether it fails the same
//! expectation): [`shrink`] only ever keeps a candidate that `fails` accepted, so its result
//! fails whenever its start did. It tries, in rounds until a round changes nothing or the trial
//! budget is spent:
//! 1. dropping faults: first all of them, then delta debugging (Zeller and Hildebrandt, 2002:
//!    drop each of n chunks, halving the chunks when none can go);
//! 2. all faults earlier together (what they do together stays as it was), then for each fault
//!    left, in turn: a shorter duration, an earlier start (its duration kept), and a lower rate
//!    (half the bit error rate, a node's frames hit half as often);
//! 3. a shorter run.
//!
//! Within the campaign's rules ([`Bounds`]): no fault starts before `earliest_s`, and the run
//! goes on at least `settle_s` after the last start (after `earliest_s` without faults) and
//! never ends before a fault does, so that what the expectations check still follows a settled
//! machine rather than a run cut short.
//!
//! Durations, starts and the run's length are searched by bisection down to a resolution of
//! [`resolution_ms`] of the value, times stay whole milliseconds, and the same start and
//! answers give the same result.

use crate::scenario::{Fault, Hit};

/// A campaign run's random part: its faults and its length.
#[derive(Clone, Debug, PartialEq)]
pub struct History {
    /// The faults, in the order they were drawn.
    pub faults: Vec<Fault>,
    /// The run's length, s.
    pub duration_s: f64,
}

impl History {
    /// When the last fault ends, s (0 without faults).
    pub fn last_end_s(&self) -> f64 {
        self.faults.iter().map(|f| f.until_s).fold(0.0, f64::max)
    }
}

/// What shrinking left.
#[derive(Clone, Debug, PartialEq)]
pub struct Shrunk {
    /// The smallest failing history found.
    pub history: History,
    /// Candidates run.
    pub trials: u32,
    /// False when the budget ran out before a round changed nothing.
    pub complete: bool,
}

/// What a shrunk history must keep to (the random faults' `from_s` and `quiet_end_s`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Bounds {
    /// No fault starts earlier, s.
    pub earliest_s: f64,
    /// The run lasts this long after the last fault starts, s.
    pub settle_s: f64,
}

/// Bisection stops when the interval is this narrow, ms: a sixteenth of the value, at least
/// 10 ms.
pub fn resolution_ms(value_ms: i64) -> i64 {
    (value_ms / 16).max(10)
}

/// The lowest bit error rate tried.
const MIN_RATE: f64 = 1e-7;
/// The rarest hits on a node's frames tried: every 64th frame.
const MAX_EVERY: u32 = 64;

fn ms(s: f64) -> i64 {
    (s * 1000.0).round() as i64
}

fn s(ms: i64) -> f64 {
    ms as f64 / 1000.0
}

/// Shrinks `start` (which failed) with at most `budget` calls of `fails`.
pub fn shrink(start: History, bounds: Bounds, budget: u32, fails: impl FnMut(&History) -> bool) -> Shrunk {
    let mut s = Shrinker {
        best: start,
        trials: 0,
        budget,
        fails,
        earliest: ms(bounds.earliest_s),
        settle: ms(bounds.settle_s),
    };
    let complete = loop {
        let before = s.best.clone();
        s.drop_faults();
        s.all_earlier();
        for i in 0..s.best.faults.len() {
            s.shorten(i);
            s.earlier(i);
            s.milder(i);
        }
        s.shorten_run();
        if s.trials >= s.budget {
            break s.best == before;
        }
        if s.best == before {
            break true;
        }
    };
    Shrunk {
        history: s.best,
        trials: s.trials,
        complete,
    }
}

struct Shrinker<F> {
    best: History,
    trials: u32,
    budget: u32,
    fails: F,
    /// [`Bounds`], ms.
    earliest: i64,
    settle: i64,
}

impl<F: FnMut(&History) -> bool> Shrinker<F> {
    /// Runs a candidate; keeps it when it fails.
    fn attempt(&mut self, candidate: History) -> bool {
        if self.trials >= self.budget || candidate == self.best {
            return false;
        }
        self.trials += 1;
        let failed = (self.fails)(&candidate);
        if failed {
            self.best = candidate;
        }
        failed
    }

    fn without(&self, from: usize, to: usize) -> History {
        let mut h = self.best.clone();
        h.faults.drain(from..to);
        h
    }

    fn drop_faults(&mut self) {
        if self.best.faults.is_empty() || self.attempt(self.without(0, self.best.faults.len())) {
            return;
        }
        let mut n = 2;
        while self.best.faults.len() >= 2 && self.trials < self.budget {
            let len = self.best.faults.len();
            let chunk = len.div_ceil(n);
            let dropped = (0..len)
                .step_by(chunk)
                .any(|from| self.attempt(self.without(from, (from + chunk).min(len))));
            if dropped {
                n = (n - 1).max(2);
            } else if n >= len {
                break;
            } else {
                n = (n * 2).min(len);
            }
        }
    }

    /// Bisects an integer in `lo..=hi` (`hi` fails as things stand) for the smallest value that
    /// `make` turns into a failing candidate, trying `lo` first.
    fn bisect(&mut self, lo: i64, hi: i64, make: impl Fn(&History, i64) -> History) {
        if lo >= hi || self.attempt(make(&self.best, lo)) {
            return;
        }
        let (mut lo, mut hi) = (lo, hi);
        while hi - lo > resolution_ms(hi) && self.trials < self.budget {
            let mid = lo + (hi - lo) / 2;
            if self.attempt(make(&self.best, mid)) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
    }

    fn shorten(&mut self, i: usize) {
        let f = &self.best.faults[i];
        if !f.lasts() {
            return;
        }
        let length = ms(f.until_s) - ms(f.at_s);
        self.bisect(1, length, |h, length| {
            let mut h = h.clone();
            let f = &mut h.faults[i];
            f.until_s = s(ms(f.at_s) + length);
            h
        });
    }

    /// Every fault earlier by the same time: what they do together stays as it was.
    fn all_earlier(&mut self) {
        let Some(first) = self.best.faults.iter().map(|f| ms(f.at_s)).min() else {
            return;
        };
        self.bisect(self.earliest.min(first), first, |h, to| {
            let mut h = h.clone();
            for f in &mut h.faults {
                f.at_s = s(ms(f.at_s) - first + to);
                f.until_s = s(ms(f.until_s) - first + to);
            }
            h
        });
    }

    fn earlier(&mut self, i: usize) {
        let at = ms(self.best.faults[i].at_s);
        self.bisect(self.earliest.min(at), at, |h, at| {
            let mut h = h.clone();
            let f = &mut h.faults[i];
            let length = ms(f.until_s) - ms(f.at_s);
            f.at_s = s(at);
            f.until_s = s(at + length);
            h
        });
    }

    fn milder(&mut self, i: usize) {
        loop {
            let mut h = self.best.clone();
            match &mut h.faults[i].hit {
                Hit::BitErrors(rate) if *rate / 2.0 >= MIN_RATE => *rate /= 2.0,
                Hit::ErrorPassive { every, .. } if *every * 2 <= MAX_EVERY => *every *= 2,
                _ => return,
            }
            if !self.attempt(h) {
                return;
            }
        }
    }

    fn shorten_run(&mut self) {
        let last_start = self
            .best
            .faults
            .iter()
            .map(|f| ms(f.at_s))
            .fold(self.earliest, i64::max);
        let lo = (last_start + self.settle).max(ms(self.best.last_end_s())).max(1);
        self.bisect(lo, ms(self.best.duration_s), |h, d| {
            let mut h = h.clone();
            h.duration_s = s(d);
            h
        });
    }
}

#[cfg(test)]
mod tests;
