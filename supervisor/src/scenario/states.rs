//! A node's error state and counters over a run, read from the hub's history of them.
//!
//! The hub records a node's (TEC, REC, state) at every error it takes part in, at every state
//! change (bus-off recovery, a reset) and at every good frame while a counter is above zero. The
//! counters only rise at errors and the state only changes at recorded points, so between two
//! points nothing happens that the checks care about: a window's highest counter and every
//! visit to a state, however brief, are at points. Before its first point a node is error active
//! with both counters at zero, as every controller starts.
//!
//! The history a timeline reads is the hub's [`Spans`]: every point until a node has thousands,
//! then neighbouring points in the same state merge into spans that keep the highest counters.
//! A change of state is never merged away, so the state checks stay exact on any run; a counter
//! check is exact wherever no merged span is, and otherwise says that it cannot tell when the
//! merged spans leave the answer open.

use bus::engine::stats::{Span, Spans};
use bus::fault::ErrorState;
use bus::time::BusTime;

/// (TEC, REC, state) at one moment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Point {
    /// Transmit error counter.
    pub tec: u16,
    /// Receive error counter.
    pub rec: u16,
    /// Error state.
    pub state: ErrorState,
}

/// What every controller is at power-up.
const START: Point = Point {
    tec: 0,
    rec: 0,
    state: ErrorState::Active,
};

/// One node's recorded points (spans), oldest first.
#[derive(Clone, Copy, Debug)]
pub struct Timeline<'a> {
    points: &'a [Span],
    whole: bool,
    lost: bool,
}

/// Where a condition was first seen in a window.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Seen {
    /// When: the window's start if the condition already held on entering it.
    pub at: BusTime,
    /// It already held on entering the window.
    pub entering: bool,
    /// If it held on entering, since when (`None`: since the run's start).
    pub since: Option<BusTime>,
    /// The node's counters and state then.
    pub point: Point,
}

impl<'a> Timeline<'a> {
    /// The timeline of a node with this history (`None`: no point was ever recorded).
    pub fn new(history: Option<&'a Spans>) -> Timeline<'a> {
        match history {
            Some(h) => Timeline {
                points: &h.list,
                whole: !h.merged,
                lost: h.lost,
            },
            None => Timeline {
                points: &[],
                whole: true,
                lost: false,
            },
        }
    }

    /// Spans recorded.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether every recorded point is there on its own.
    #[cfg(test)]
    pub fn is_whole(&self) -> bool {
        self.whole
    }

    /// Whether every change of state is there (state checks need it).
    pub fn states_exact(&self) -> bool {
        !self.lost
    }

    /// Whether the counters are exact between `from` and `to`: no merged span touches them.
    pub fn counters_exact(&self, from: BusTime, to: BusTime) -> bool {
        self.whole
            || self
                .points
                .iter()
                .filter(|s| s.from != s.to)
                .all(|s| s.to < from || s.from > to)
    }

    fn point(&self, i: usize) -> (BusTime, Point) {
        let s = self.points[i];
        (
            s.from,
            Point {
                tec: s.tec,
                rec: s.rec,
                state: s.state,
            },
        )
    }

    /// What the node was on entering a window that starts at `t`, if no point is at `t` itself
    /// (points at `t` are the window's first word on it), and the index of the window's first
    /// point.
    fn entering(&self, t: BusTime) -> (Option<Point>, usize) {
        let n = self.points.partition_point(|s| s.from < t);
        if self.points.get(n).is_some_and(|s| s.from == t) {
            return (None, n);
        }
        (Some(n.checked_sub(1).map_or(START, |i| self.point(i).1)), n)
    }

    /// The node's counters and state at the instant `t`: as the last point at or before `t`
    /// left them, and when that point was (`None`: no point yet, the start).
    pub fn at(&self, t: BusTime) -> (Point, Option<BusTime>) {
        let n = self.points.partition_point(|s| s.from <= t);
        match n.checked_sub(1) {
            Some(i) => {
                let (at, p) = self.point(i);
                (p, Some(at))
            }
            None => (START, None),
        }
    }

    /// The first moment in `[from, to]` at which `cond` holds: `from` itself if it held on
    /// entering the window. Points at `from` belong to the window: a state that ends exactly at
    /// `from` is not in it.
    pub fn first(&self, from: BusTime, to: BusTime, cond: impl Fn(Point) -> bool) -> Option<Seen> {
        let (entering, n) = self.entering(from);
        if let Some(entering) = entering.filter(|p| cond(*p)) {
            // Since when: back over the points where it held, to the start if it always did.
            let mut i = n;
            let mut since = None;
            while let Some(j) = i.checked_sub(1) {
                let (at, p) = self.point(j);
                if !cond(p) {
                    break;
                }
                since = Some(at);
                i = j;
            }
            if i == 0 && cond(START) {
                since = None;
            }
            return Some(Seen {
                at: from,
                entering: true,
                since,
                point: entering,
            });
        }
        (n..self.points.len())
            .map(|i| self.point(i))
            .take_while(|(at, _)| *at <= to)
            .find(|(_, p)| cond(*p))
            .map(|(at, point)| Seen {
                at,
                entering: false,
                since: None,
                point,
            })
    }

    /// The highest value of `counter` in `[from, to]` and the first moment it had it.
    pub fn highest(&self, from: BusTime, to: BusTime, counter: impl Fn(Point) -> u16) -> (u16, BusTime) {
        let (entering, start) = self.entering(from);
        let mut best = (entering.map_or(0, &counter), from);
        for (at, p) in (start..self.points.len())
            .map(|i| self.point(i))
            .take_while(|(at, _)| *at <= to)
        {
            if counter(p) > best.0 {
                best = (counter(p), at);
            }
        }
        best
    }

    /// Each stay in `state` over the whole run: when it began, and when it ended (`None`: it
    /// lasted to the last point).
    pub fn stays(&self, state: ErrorState) -> Vec<(BusTime, Option<BusTime>)> {
        let mut stays: Vec<(BusTime, Option<BusTime>)> = Vec::new();
        let mut previous = START.state;
        for i in 0..self.points.len() {
            let (at, p) = self.point(i);
            if p.state == state && previous != state {
                stays.push((at, None));
            } else if p.state != state
                && previous == state
                && let Some(last) = stays.last_mut()
            {
                last.1 = Some(at);
            }
            previous = p.state;
        }
        stays
    }

    /// The moments the node entered `state` over the whole run.
    pub fn entries(&self, state: ErrorState) -> Vec<BusTime> {
        let mut previous = START.state;
        let mut times = Vec::new();
        for i in 0..self.points.len() {
            let (at, p) = self.point(i);
            if p.state == state && previous != state {
                times.push(at);
            }
            previous = p.state;
        }
        times
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ErrorState::*;

    fn history(points: &[(u64, u16, u16, ErrorState)]) -> Spans {
        let mut h = Spans::default();
        for &(ms, tec, rec, s) in points {
            h.push(BusTime::from_millis(ms), tec, rec, s);
        }
        h
    }

    fn ms(ms: u64) -> BusTime {
        BusTime::from_millis(ms)
    }

    /// E0 error passive at 5.1 s, bus off for 6 ms at 7.2 s, active again at 12 s.
    fn sample() -> Spans {
        history(&[
            (5000, 8, 0, Active),
            (5100, 128, 0, Passive),
            (7200, 256, 0, BusOff),
            (7206, 0, 0, Active),
            (7300, 8, 0, Active),
            (7310, 128, 0, Passive),
            (12000, 127, 0, Active),
            (12001, 126, 0, Active),
        ])
    }

    #[test]
    fn a_brief_visit_inside_a_window_is_found() {
        let h = sample();
        let t = Timeline::new(Some(&h));
        assert!(t.is_whole());
        let seen = t.first(ms(5000), ms(20000), |p| p.state == BusOff).unwrap();
        assert_eq!((seen.at, seen.entering, seen.point.tec), (ms(7200), false, 256));
        // Not before it, and not after it.
        assert_eq!(t.first(ms(0), ms(7199), |p| p.state == BusOff), None);
        assert_eq!(t.first(ms(7206), ms(20000), |p| p.state == BusOff), None);
    }

    #[test]
    fn a_state_held_on_entering_the_window_counts_from_the_window_start() {
        let h = sample();
        let t = Timeline::new(Some(&h));
        let seen = t.first(ms(6000), ms(7000), |p| p.state == Passive).unwrap();
        assert_eq!(
            (seen.at, seen.entering, seen.since),
            (ms(6000), true, Some(ms(5100)))
        );
        // Active since the start of the run: no point before the window, or only active ones.
        let seen = t.first(ms(1000), ms(2000), |p| p.state == Active).unwrap();
        assert_eq!((seen.entering, seen.since), (true, None));
        let seen = t.first(ms(5050), ms(5060), |p| p.state == Active).unwrap();
        assert_eq!((seen.entering, seen.since), (true, None));
        let seen = t.first(ms(5050), ms(5060), |p| p.tec > 0).unwrap();
        assert_eq!((seen.entering, seen.since), (true, Some(ms(5000))));
        // Held: active from 12 s on, but 7.3 s is no proof of it.
        assert_eq!(t.first(ms(12000), ms(20000), |p| p.state != Active), None);
        let off = t.first(ms(7300), ms(20000), |p| p.state != Active).unwrap();
        assert_eq!((off.at, off.point.state), (ms(7310), Passive));
    }

    #[test]
    fn a_node_without_history_was_active_with_clear_counters() {
        let t = Timeline::new(None);
        assert!(t.is_whole());
        assert_eq!(t.first(ms(0), ms(10), |p| p.state != Active), None);
        assert_eq!(t.highest(ms(0), ms(10), |p| p.rec), (0, ms(0)));
        assert!(t.entries(BusOff).is_empty());
    }

    #[test]
    fn stays_begin_at_entries_and_end_at_the_next_state() {
        let h = sample();
        let t = Timeline::new(Some(&h));
        // Bus off from 7200 ms until error active at 7206 ms (the sample's points).
        assert_eq!(t.stays(BusOff), vec![(ms(7200), Some(ms(7206)))]);
        // Never left: the stay is open.
        let stuck = history(&[(1000, 256, 0, BusOff)]);
        assert_eq!(Timeline::new(Some(&stuck)).stays(BusOff), vec![(ms(1000), None)]);
        assert!(Timeline::new(Some(&stuck)).stays(Passive).is_empty());
    }

    #[test]
    fn entries_and_highest_counters() {
        let h = sample();
        let t = Timeline::new(Some(&h));
        assert_eq!(t.entries(BusOff), vec![ms(7200)]);
        assert_eq!(t.entries(Passive), vec![ms(5100), ms(7310)]);
        assert_eq!(t.entries(Active), vec![ms(7206), ms(12000)]);
        assert_eq!(t.highest(ms(5000), ms(20000), |p| p.tec), (256, ms(7200)));
        // Entering the window with a counter counts.
        assert_eq!(t.highest(ms(11000), ms(20000), |p| p.tec), (128, ms(11000)));
        assert_eq!(t.highest(ms(12000), ms(20000), |p| p.tec), (127, ms(12000)));
    }

    #[test]
    fn a_long_history_merges_counters_but_keeps_every_change_of_state() {
        // 20,000 points: REC climbing by one per ms, passive from 128 to 10,000 ms, then bus
        // off for 1 ms and active again.
        let mut points = Vec::new();
        for ms in 0..20_000u64 {
            let rec = (ms % 200) as u16;
            let state = match ms {
                10_000 => BusOff,
                _ if rec >= 128 => Passive,
                _ => Active,
            };
            points.push((ms, 0, rec, state));
        }
        let h = history(&points);
        let t = Timeline::new(Some(&h));
        assert!(!t.is_whole() && t.states_exact());
        assert!(h.list.len() <= 2 * 8192, "{}", h.list.len());
        assert_eq!(t.entries(BusOff), vec![ms(10_000)]);
        // One visit per 200 ms (REC 128..=199); the bus off at 10 s falls on REC 0.
        assert_eq!(t.entries(Passive).len(), 100);
        let seen = t.first(ms(0), ms(20_000), |p| p.state == BusOff).unwrap();
        assert_eq!(seen.at, ms(10_000));
        assert_eq!(t.first(ms(10_001), ms(20_000), |p| p.state == BusOff), None);
        // The highest REC survives merging.
        assert_eq!(t.highest(ms(0), ms(20_000), |p| p.rec).0, 199);
        assert!(!t.counters_exact(ms(0), ms(20_000)));
    }
}
