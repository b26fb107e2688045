//! The sans-IO part of `harvemu replay`: which frames of a trace go out, and when.
//!
//! Contract:
//! - A [`Schedule`] is built from the records of a trace, the source addresses to leave out and
//!   the number of passes; it then yields every frame to send as a [`Due`], in time order, with
//!   its offset from the start of the replay. It reads no clock and does no I/O.
//! - Offsets are measured from the first record of the trace, whatever its kind, so frames keep
//!   their place relative to the whole recording. The trace reader refuses times that go
//!   backwards; records built otherwise that do are sent right after the one before them: offsets
//!   never decrease.
//! - Error frames are counted and never sent: a controller cannot be told to send one.
//! - A frame with an extended identifier whose source byte (the low 8 bits of the harvester's
//!   identifier) is in the skip set is counted and left out. Base frames have no source address
//!   and are always sent.
//! - Each pass after the first is shifted by the period: the trace's span (first to last record)
//!   plus its mean interval between records (1 ms when all records share one instant), so the
//!   times of a looped trace keep increasing by the trace's own rhythm.

use bus::Frame;
use bus::ident::{Address, AppId};
use bus::time::BusTime;
use bus::tracefile::{Entry, Record};
use std::collections::BTreeSet;

/// How many times the trace is played.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Passes {
    /// This many times (at least once).
    Times(u32),
    /// Until stopped.
    Forever,
}

/// What the schedule did with the trace's records.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Records read (frames and error frames).
    pub read: u64,
    /// Error frames among them (not replayable).
    pub error_frames: u64,
    /// Frames left out because an emulated node sends them.
    pub skipped: u64,
    /// Frames sent per pass.
    pub per_pass: u64,
}

/// One frame to send.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Due {
    /// Nanoseconds after the start of the replay.
    pub offset: u64,
    /// The frame.
    pub frame: Frame,
    /// Pass number, from 0.
    pub pass: u32,
}

/// The frames of a trace, in the order and at the offsets they are to be sent.
#[derive(Clone, Debug)]
pub struct Schedule {
    frames: Vec<(u64, Frame)>,
    period: u64,
    passes: Passes,
    counts: Counts,
    pass: u32,
    index: usize,
}

/// The source address of a harvester frame; `None` for a base frame.
pub fn source(frame: &Frame) -> Option<Address> {
    AppId::from_id(frame.id()).ok().map(|id| id.source)
}

impl Schedule {
    /// Plans the replay of `records`, leaving out frames sent from `skip`.
    pub fn new(records: &[Record], skip: &BTreeSet<Address>, passes: Passes) -> Schedule {
        let first = records.first().map_or(BusTime::ZERO, |r| r.at);
        let mut counts = Counts::default();
        let mut frames = Vec::new();
        let mut last = 0u64;
        for r in records {
            counts.read += 1;
            // Never backwards: a record out of order goes out right after the one before it.
            last = last.max(r.at - first);
            match r.entry {
                Entry::Error(_) => counts.error_frames += 1,
                Entry::Frame(f) if source(&f).is_some_and(|a| skip.contains(&a)) => counts.skipped += 1,
                Entry::Frame(f) => frames.push((last, f)),
            }
        }
        counts.per_pass = frames.len() as u64;
        let intervals = records.len().saturating_sub(1) as u64;
        let mean = if intervals > 0 && last > 0 {
            (last / intervals).max(1)
        } else {
            1_000_000
        };
        Schedule {
            frames,
            period: last + mean,
            passes,
            counts,
            pass: 0,
            index: 0,
        }
    }

    /// What was read, skipped and is sent per pass.
    pub fn counts(&self) -> Counts {
        self.counts
    }

    /// The shift between two passes, ns.
    pub fn period(&self) -> u64 {
        self.period
    }

    /// Passes begun so far (a pass begins when its first frame is taken).
    pub fn passes_begun(&self) -> u32 {
        if self.index > 0 { self.pass + 1 } else { self.pass }
    }

    /// The offset of the last frame of the last pass; `None` when that is never.
    pub fn end(&self) -> Option<u64> {
        let (last, _) = self.frames.last()?;
        match self.passes {
            Passes::Times(n) => Some(last + u64::from(n.max(1) - 1) * self.period),
            Passes::Forever => None,
        }
    }
}

impl Iterator for Schedule {
    type Item = Due;

    fn next(&mut self) -> Option<Due> {
        if self.index == self.frames.len() {
            let more = match self.passes {
                Passes::Times(n) => self.pass + 1 < n,
                Passes::Forever => true,
            };
            if self.frames.is_empty() || !more {
                return None;
            }
            self.pass += 1;
            self.index = 0;
        }
        let (offset, frame) = self.frames[self.index];
        self.index += 1;
        Some(Due {
            offset: offset.saturating_add(u64::from(self.pass).saturating_mul(self.period)),
            frame,
            pass: self.pass,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bus::candump::parse_frame;

    fn record(at_us: u64, text: &str) -> Record {
        let entry = if text == "error" {
            Entry::Error(None)
        } else {
            Entry::Frame(parse_frame(text).unwrap())
        };
        Record {
            at: BusTime::from_micros(at_us),
            line: 0,
            entry,
        }
    }

    fn trace() -> Vec<Record> {
        vec![
            record(1_000_000, "0300A0F5#01"), // from the monitor F5
            record(1_000_400, "0601F5D0#20"), // from D0
            record(1_000_300, "123#R"),       // base frame, out of order
            record(1_002_000, "error"),
            record(1_003_000, "0601F5D3#21"), // from D3
        ]
    }

    #[test]
    fn frames_keep_their_offsets_and_never_go_back() {
        let got: Vec<(u64, String)> = Schedule::new(&trace(), &BTreeSet::new(), Passes::Times(1))
            .map(|d| (d.offset / 1000, bus::candump::format_frame(&d.frame)))
            .collect();
        let want = [
            (0, "0300A0F5#01"),
            (400, "0601F5D0#20"),
            (400, "123#R"),
            (3000, "0601F5D3#21"),
        ];
        assert_eq!(got, want.map(|(t, f)| (t, f.to_string())));
    }

    #[test]
    fn the_skip_set_drops_exactly_its_sources() {
        let skip = BTreeSet::from([Address(0xF5), Address(0xD0)]);
        let s = Schedule::new(&trace(), &skip, Passes::Times(1));
        let c = s.counts();
        assert_eq!((c.read, c.error_frames, c.skipped, c.per_pass), (5, 1, 2, 2));
        let sources: Vec<Option<u8>> = s.map(|d| source(&d.frame).map(|a| a.0)).collect();
        assert_eq!(sources, [None, Some(0xD3)]);
    }

    #[test]
    fn passes_are_shifted_by_span_plus_mean_interval() {
        let mut s = Schedule::new(&trace(), &BTreeSet::new(), Passes::Times(3));
        // Span 3 ms over 4 intervals: the period is 3.75 ms.
        assert_eq!(s.period(), 3_750_000);
        assert_eq!(s.end(), Some(3_000_000 + 2 * 3_750_000));
        assert_eq!(s.passes_begun(), 0);
        let all: Vec<Due> = s.by_ref().collect();
        assert_eq!(all.len(), 12, "4 frames, 3 passes");
        assert_eq!(s.passes_begun(), 3);
        assert!(all.windows(2).all(|w| w[0].offset <= w[1].offset), "{all:?}");
        for (i, d) in all.iter().enumerate() {
            let first = &all[i % 4];
            assert_eq!(d.frame, first.frame);
            assert_eq!(d.pass, (i / 4) as u32);
            assert_eq!(d.offset, first.offset + u64::from(d.pass) * 3_750_000);
        }
    }

    #[test]
    fn for_ever_stops_only_when_there_is_nothing_to_send() {
        let s = Schedule::new(&trace(), &BTreeSet::new(), Passes::Forever);
        assert_eq!(s.end(), None);
        assert_eq!(s.take(1000).count(), 1000);
        let everything = BTreeSet::from([Address(0xF5), Address(0xD0), Address(0xD3)]);
        let only_emulated = vec![record(5, "0300A0F5#01")];
        assert_eq!(
            Schedule::new(&only_emulated, &everything, Passes::Forever).count(),
            0
        );
        // One instant: passes 1 ms apart.
        let one = vec![record(5, "123#00")];
        let s = Schedule::new(&one, &BTreeSet::new(), Passes::Times(2));
        assert_eq!(s.map(|d| d.offset).collect::<Vec<_>>(), [0, 1_000_000]);
    }
}
