//! Puts trace records in time order before they reach a sink: a bounded reorder window.
//!
//! Contract: [`Reorder::push`] takes records as they come, each with its bus time;
//! [`Reorder::pop`] gives them back in time order, records with equal times in the order they
//! came (stable), once the newest time pushed is at least a window past them;
//! [`Reorder::pop_any`] gives back the rest, at the end of a run. A record stamped earlier than
//! one already given back cannot be put in order: `push` refuses it with
//! [`Error::TraceOrder`] and keeps nothing of it. No clock, no I/O: the caller says when.
//!
//! Why records come out of order at all, and why a window of [`WINDOW_BITS`] bit times is
//! enough: the engine commits each event whole, at its start (`bus::engine`'s contract: an
//! arbitration round and the frame or error frame that follows it, or a bus-off recovery), and
//! its events from that one step reach to the end of that frame or error frame. Whatever a host
//! makes the bus say afterwards (a controller reset, counters written, a frame submitted) is
//! stamped no earlier than the start of that last committed event
//! ([`crate::engine::Bus::committed`]: the engine moves earlier submissions, aborts, counters
//! and recovery requests there; the hub stamps resets and commands at its present, never before
//! it), so a record can come at most one committed event's length after a later one. A frame
//! lasts at most 160 bit times (an extended frame with 8 data bytes and every stuff bit,
//! intermission included); an error frame (the attempt up to the error, superposed flags,
//! delimiter, overload frames) a few hundred; and the engine cuts any episode, however long a
//! disturbance holds the bus, at 20,000 bit times. The window is that longest one: 80 ms at
//! 250 kbit/s. What is held is at most a window's worth of records: with the shipped scenarios,
//! at most about 2,800 (the error storms of `c0_bus_off`), a few tens of bytes each.

use crate::Error;
use crate::time::{BusDuration, BusTime};
use std::collections::VecDeque;

/// The reorder window, in bit times: the longest event the engine commits at once, an error
/// episode cut at 20,000 bit times (a frame is at most 160).
pub const WINDOW_BITS: u64 = 20_000;

/// Records in time order, held until a window past them (see the [module](self)).
#[derive(Debug)]
pub struct Reorder<T> {
    window: BusDuration,
    /// In time order, equal times in arrival order.
    held: VecDeque<(BusTime, T)>,
    /// The newest time pushed.
    newest: BusTime,
    /// The time of the last record given back, once one was.
    released: Option<BusTime>,
}

impl<T> Reorder<T> {
    /// Holds each record until the newest time pushed is `window` past it.
    pub fn new(window: BusDuration) -> Self {
        Reorder {
            window,
            held: VecDeque::new(),
            newest: BusTime::ZERO,
            released: None,
        }
    }

    /// The window for a bus whose bit time is `bit`: [`WINDOW_BITS`] of them.
    pub fn for_bit_time(bit: BusDuration) -> Self {
        Reorder::new(bit.saturating_mul(WINDOW_BITS))
    }

    /// The window.
    pub fn window(&self) -> BusDuration {
        self.window
    }

    /// Records held now.
    pub fn len(&self) -> usize {
        self.held.len()
    }

    /// True when nothing is held.
    pub fn is_empty(&self) -> bool {
        self.held.is_empty()
    }

    /// Takes a record stamped `at`: after every held record stamped at or before `at`. A record
    /// stamped before the last one given back is refused ([`Error::TraceOrder`]), and nothing
    /// of it is kept.
    pub fn push(&mut self, at: BusTime, item: T) -> Result<(), Error> {
        if let Some(released) = self.released
            && at < released
        {
            return Err(Error::TraceOrder {
                at,
                released,
                window: self.window,
            });
        }
        self.newest = self.newest.max(at);
        // Nearly every record is the newest: it goes at the back, with no search.
        if self.held.back().is_none_or(|(t, _)| *t <= at) {
            self.held.push_back((at, item));
        } else {
            let i = self.held.partition_point(|(t, _)| *t <= at);
            self.held.insert(i, (at, item));
        }
        Ok(())
    }

    /// The oldest record held, once the newest time pushed is a window past it.
    pub fn pop(&mut self) -> Option<(BusTime, T)> {
        let due = self.newest.saturating_sub(self.window);
        if self.held.front().is_some_and(|(t, _)| *t <= due) {
            self.pop_any()
        } else {
            None
        }
    }

    /// The oldest record held, whatever its time: at the end of a run, every one.
    pub fn pop_any(&mut self) -> Option<(BusTime, T)> {
        let (at, item) = self.held.pop_front()?;
        self.released = Some(at);
        Some((at, item))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::{Bus, BusConfig, ControllerConfig, Disturbance, Event};
    use crate::time::BusDuration;

    fn us(n: u64) -> BusTime {
        BusTime::from_micros(n)
    }

    /// Pushes `(µs, tag)` and gives back what `pop` releases after each push, as `(µs, tag)`.
    fn run(
        window_us: u64,
        input: &[(u64, &'static str)],
    ) -> (Reorder<&'static str>, Vec<(u64, &'static str)>) {
        let mut r = Reorder::new(BusDuration::from_micros(window_us));
        let mut out = Vec::new();
        for &(t, tag) in input {
            r.push(us(t), tag).unwrap();
            while let Some((at, tag)) = r.pop() {
                out.push((at.as_micros(), tag));
            }
        }
        (r, out)
    }

    fn rest(r: &mut Reorder<&'static str>) -> Vec<(u64, &'static str)> {
        std::iter::from_fn(|| r.pop_any())
            .map(|(at, tag)| (at.as_micros(), tag))
            .collect()
    }

    #[test]
    fn records_in_order_wait_one_window_and_come_out_as_they_came() {
        let (mut r, out) = run(100, &[(10, "a"), (50, "b"), (109, "c"), (110, "d"), (300, "e")]);
        // "a" goes at 110 (10 + 100), "b", "c" and "d" at 300; "e" waits for the end.
        assert_eq!(out, [(10, "a"), (50, "b"), (109, "c"), (110, "d")]);
        assert_eq!(r.len(), 1);
        assert_eq!(rest(&mut r), [(300, "e")]);
        assert!(r.is_empty());
    }

    #[test]
    fn a_record_late_within_the_window_is_put_in_its_place() {
        // The engine's shape: a frame committed ahead (ends at 200), then a reset stamped at
        // the node's present (150), then the bus goes on.
        let (mut r, out) = run(
            100,
            &[(120, "bus error"), (200, "frame"), (150, "reset"), (400, "next")],
        );
        assert_eq!(out, [(120, "bus error"), (150, "reset"), (200, "frame")]);
        assert_eq!(rest(&mut r), [(400, "next")]);
    }

    #[test]
    fn equal_times_keep_the_order_they_came_in_also_when_late() {
        let input = [
            (100, "a1"),
            (100, "a2"),
            (300, "c"),
            (200, "b1"),
            (100, "a3"),
            (200, "b2"),
            (300, "c2"),
            (200, "b3"),
        ];
        let (mut r, out) = run(1_000, &input);
        assert!(out.is_empty(), "{out:?}");
        assert_eq!(
            rest(&mut r),
            [
                (100, "a1"),
                (100, "a2"),
                (100, "a3"),
                (200, "b1"),
                (200, "b2"),
                (200, "b3"),
                (300, "c"),
                (300, "c2")
            ]
        );
    }

    #[test]
    fn a_record_older_than_one_given_back_is_refused_and_not_kept() {
        let (mut r, out) = run(100, &[(10, "a"), (50, "b"), (200, "c")]);
        assert_eq!(out, [(10, "a"), (50, "b")]);
        let e = r.push(us(49), "too late").unwrap_err();
        assert_eq!(
            e,
            Error::TraceOrder {
                at: us(49),
                released: us(50),
                window: BusDuration::from_micros(100),
            }
        );
        let text = e.to_string();
        assert!(text.contains("0.000049") && text.contains("0.000050"), "{text}");
        // The time of the last one given back is still fine: it comes after it.
        r.push(us(50), "b2").unwrap();
        assert_eq!(rest(&mut r), [(50, "b2"), (200, "c")]);
        // After the end too: everything given back, nothing older may come.
        assert!(r.push(us(199), "after the end").is_err());
        r.push(us(200), "at the end").unwrap();
        assert_eq!(rest(&mut r), [(200, "at the end")]);
    }

    #[test]
    fn what_is_held_stays_within_one_window() {
        // A record every 10 µs with a window of 1000 µs, each tenth 500 µs late: never more
        // than a window's worth (101 records) held.
        let mut r = Reorder::new(BusDuration::from_micros(1_000));
        let mut out = Vec::new();
        let mut most = 0;
        for k in 0..10_000u64 {
            let t = k * 10 + 1_000;
            let t = if k % 10 == 9 { t - 500 } else { t };
            r.push(us(t), k).unwrap();
            while let Some((at, _)) = r.pop() {
                out.push(at);
            }
            most = most.max(r.len());
        }
        out.extend(std::iter::from_fn(|| r.pop_any()).map(|(at, _)| at));
        assert!(most <= 101, "{most} held");
        assert_eq!(out.len(), 10_000);
        assert!(out.windows(2).all(|w| w[0] <= w[1]));
    }

    #[test]
    fn the_window_is_in_bit_times() {
        let bit = crate::bits::BitRate::K250.bit_time().unwrap();
        let r: Reorder<()> = Reorder::for_bit_time(bit);
        assert_eq!(r.window(), BusDuration::from_millis(80));
    }

    /// The window holds the longest event the engine commits at once: a disturbance that holds
    /// the bus dominant far longer makes one episode, which the engine cuts at the window's
    /// length; every event of that one step lies within it.
    #[test]
    fn the_longest_episode_the_engine_commits_fits_in_the_window() {
        let mut bus = Bus::new(BusConfig::default()).unwrap();
        let a = bus.attach(ControllerConfig::named("a"));
        bus.attach(ControllerConfig::named("b"));
        let frame = crate::candump::parse_frame("0601F5D0#0102030405060708").unwrap();
        bus.submit(a, frame, BusTime::ZERO).unwrap();
        let bit = bus.bit_time();
        bus.disturb(Disturbance {
            at: BusTime::ZERO + bit * 40,
            bits: 1_000_000,
            level: Some(false),
            nodes: None,
        });
        let start = bus.next_event_time().unwrap();
        assert!(bus.step());
        let events: Vec<Event> = bus.take_events().collect();
        let end = events
            .iter()
            .find_map(|e| match e {
                Event::ErrorFrame { end, .. } => Some(*end),
                _ => None,
            })
            .expect("an error frame");
        assert_eq!(end - start, bit * WINDOW_BITS, "cut at the window");
        assert!(
            events.iter().all(|e| e.at() >= start && e.at() <= end),
            "{events:?}"
        );
    }
}
