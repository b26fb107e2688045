//! The sans-IO part of `harvemu replay`: which frames of a trace go out, and when.
//!
//! Contract:
//! - A trace is never held in memory. A [`Survey`] reads it once, record by record, and keeps
//!   only counts and times. A [`Schedule`] is built from the survey, the source addresses to
//!   leave out, the number of passes and a source that gives the trace's records from the start
//!   again for each pass (in `harvemu replay`, the file opened again); it then yields every frame
//!   to send as a [`Due`], in time order, with its offset from the start of the replay, reading
//!   one record ahead of the frame it gives. It reads no clock and does no I/O of its own.
//! - An error from the source (a line that has become bad since the survey, a file that cannot
//!   be opened again) is given once and ends the schedule; so is a pass that finds no frame to
//!   send although the survey found some (the trace was emptied since), which would otherwise
//!   make `--loop` open the file again and again without end.
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

use crate::Error;
use bus::Frame;
use bus::time::Stamp;
use bus::tracefile::{Entry, Record};
use protocol::ident::{Address, AppId};
use std::collections::BTreeSet;
use std::convert::Infallible;

/// How many times the trace is played.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Passes {
    /// This many times (at least once).
    Times(u32),
    /// Until stopped.
    Forever,
}

/// What the schedule does with the trace's records, per pass.
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

/// The source address of a harvester frame; `None` for a base frame.
pub fn source(frame: &Frame) -> Option<Address> {
    AppId::from_id(frame.id()).ok().map(|id| id.source)
}

/// True for a frame the skip set leaves out.
fn skipped(frame: &Frame, skip: &BTreeSet<Address>) -> bool {
    source(frame).is_some_and(|a| skip.contains(&a))
}

/// A pause between two records of a trace longer than the limit a survey was given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Gap {
    /// The line (or record number) of the record after it.
    pub line: u64,
    /// Its length, ns.
    pub nanos: u64,
}

/// What one reading of a whole trace found: enough to plan every pass without its records.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Survey {
    counts: Counts,
    /// The time of the first record.
    first: Stamp,
    /// The offset of the last record (never decreasing: the largest offset so far).
    last: u64,
    /// The offset of the last frame sent in a pass.
    last_frame: Option<u64>,
    /// The first pause longer than the limit given.
    long_gap: Option<Gap>,
}

impl Survey {
    /// Reads `records` to the end, or to the first error, which it gives back.
    pub fn new<E>(
        records: impl IntoIterator<Item = Result<Record, E>>,
        skip: &BTreeSet<Address>,
    ) -> Result<Survey, E> {
        let numbered = records.into_iter().zip(1..).map(|(r, n)| r.map(|r| (n, r)));
        Survey::numbered(numbered, skip, u64::MAX)
    }

    /// [`Survey::new`] of records with their line numbers, noting the first pause between two
    /// records longer than `gap_limit` ns ([`Survey::long_gap`]).
    pub fn numbered<E>(
        records: impl IntoIterator<Item = Result<(u64, Record), E>>,
        skip: &BTreeSet<Address>,
        gap_limit: u64,
    ) -> Result<Survey, E> {
        let mut s = Survey::default();
        let mut previous = None;
        for r in records {
            let (line, r) = r?;
            if s.counts.read == 0 {
                s.first = r.at;
            }
            if let Some(before) = previous {
                let nanos = r.at.since(before).as_nanos();
                if nanos > gap_limit && s.long_gap.is_none() {
                    s.long_gap = Some(Gap { line, nanos });
                }
            }
            previous = Some(r.at);
            s.counts.read += 1;
            s.last = s.last.max(r.at.since(s.first).as_nanos());
            match r.entry {
                Entry::Error(_) => s.counts.error_frames += 1,
                Entry::Frame(f) if skipped(&f, skip) => s.counts.skipped += 1,
                Entry::Frame(_) => {
                    s.counts.per_pass += 1;
                    s.last_frame = Some(s.last);
                }
            }
        }
        Ok(s)
    }

    /// The first pause between two records longer than the limit given, if any.
    pub fn long_gap(&self) -> Option<Gap> {
        self.long_gap
    }

    /// What was read, skipped and is sent per pass.
    pub fn counts(&self) -> Counts {
        self.counts
    }

    /// The shift between two passes, ns.
    pub fn period(&self) -> u64 {
        let intervals = self.counts.read.saturating_sub(1);
        let mean = if intervals > 0 && self.last > 0 {
            (self.last / intervals).max(1)
        } else {
            1_000_000
        };
        self.last + mean
    }
}

/// Gives a trace's records from its start, once per pass.
pub type Source = Box<dyn FnMut() -> Box<dyn Iterator<Item = crate::Result<Record>>>>;

/// The frames of a trace, in the order and at the offsets they are to be sent.
pub struct Schedule {
    survey: Survey,
    skip: BTreeSet<Address>,
    passes: Passes,
    period: u64,
    source: Source,
    /// The pass being read, once opened.
    reading: Option<Box<dyn Iterator<Item = crate::Result<Record>>>>,
    /// The current pass, from 0.
    pass: u32,
    /// Passes whose first frame has been taken.
    begun: u32,
    /// The largest offset of this pass so far.
    last: u64,
    done: bool,
}

impl Schedule {
    /// Plans the replay of the trace `survey` was made of, which `source` gives again for each
    /// pass, leaving out frames sent from `skip`.
    pub fn new(survey: Survey, skip: BTreeSet<Address>, passes: Passes, source: Source) -> Schedule {
        Schedule {
            period: survey.period(),
            survey,
            skip,
            passes,
            source,
            reading: None,
            pass: 0,
            begun: 0,
            last: 0,
            done: survey.counts.per_pass == 0,
        }
    }

    /// Plans the replay of records held in memory (tests, and traces built by a program).
    pub fn from_records(records: Vec<Record>, skip: &BTreeSet<Address>, passes: Passes) -> Schedule {
        let Ok(survey) = Survey::new(records.iter().map(|r| Ok::<_, Infallible>(*r)), skip);
        let source: Source = Box::new(move || Box::new(records.clone().into_iter().map(Ok)));
        Schedule::new(survey, skip.clone(), passes, source)
    }

    /// What was read, skipped and is sent per pass.
    pub fn counts(&self) -> Counts {
        self.survey.counts
    }

    /// The shift between two passes, ns.
    pub fn period(&self) -> u64 {
        self.period
    }

    /// Passes begun so far (a pass begins when its first frame is taken).
    pub fn passes_begun(&self) -> u32 {
        self.begun
    }

    /// The offset of the last frame of the last pass; `None` when that is never.
    pub fn end(&self) -> Option<u64> {
        let last = self.survey.last_frame?;
        match self.passes {
            Passes::Times(n) => {
                Some(last.saturating_add(u64::from(n.max(1) - 1).saturating_mul(self.period)))
            }
            Passes::Forever => None,
        }
    }

    /// True when a pass after the current one is to be played.
    fn another_pass(&self) -> bool {
        match self.passes {
            Passes::Times(n) => self.pass + 1 < n,
            Passes::Forever => true,
        }
    }
}

impl Iterator for Schedule {
    type Item = crate::Result<Due>;

    fn next(&mut self) -> Option<crate::Result<Due>> {
        while !self.done {
            let Some(reading) = &mut self.reading else {
                self.reading = Some((self.source)());
                self.last = 0;
                continue;
            };
            let record = match reading.next() {
                Some(Ok(r)) => r,
                Some(Err(e)) => {
                    self.done = true;
                    return Some(Err(e));
                }
                None => {
                    self.reading = None;
                    if self.begun == self.pass {
                        // The survey found frames to send, this reading none: the trace changed.
                        self.done = true;
                        let e = Error::BadInput(format!(
                            "the trace changed while it was replayed: pass {} found no frame to send",
                            self.pass + 1
                        ));
                        return Some(Err(e));
                    }
                    if self.another_pass() {
                        self.pass += 1;
                    } else {
                        self.done = true;
                    }
                    continue;
                }
            };
            // Never backwards: a record out of order goes out right after the one before it.
            self.last = self.last.max(record.at.since(self.survey.first).as_nanos());
            let Entry::Frame(frame) = record.entry else {
                continue;
            };
            if skipped(&frame, &self.skip) {
                continue;
            }
            if self.begun == self.pass {
                self.begun += 1;
            }
            let shift = u64::from(self.pass).saturating_mul(self.period);
            return Some(Ok(Due {
                offset: self.last.saturating_add(shift),
                frame,
                pass: self.pass,
            }));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bus::candump::parse_frame;
    use std::cell::Cell;
    use std::rc::Rc;

    fn record(at_us: u64, text: &str) -> Record {
        let entry = if text == "error" {
            Entry::Error(None)
        } else {
            Entry::Frame(parse_frame(text).unwrap())
        };
        Record {
            at: Stamp(at_us * 1_000),
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
        let got: Vec<(u64, String)> = Schedule::from_records(trace(), &BTreeSet::new(), Passes::Times(1))
            .map(|d| d.unwrap())
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
        let s = Schedule::from_records(trace(), &skip, Passes::Times(1));
        let c = s.counts();
        assert_eq!((c.read, c.error_frames, c.skipped, c.per_pass), (5, 1, 2, 2));
        let sources: Vec<Option<u8>> = s.map(|d| source(&d.unwrap().frame).map(|a| a.0)).collect();
        assert_eq!(sources, [None, Some(0xD3)]);
    }

    #[test]
    fn passes_are_shifted_by_span_plus_mean_interval() {
        let mut s = Schedule::from_records(trace(), &BTreeSet::new(), Passes::Times(3));
        // Span 3 ms over 4 intervals: the period is 3.75 ms.
        assert_eq!(s.period(), 3_750_000);
        assert_eq!(s.end(), Some(3_000_000 + 2 * 3_750_000));
        assert_eq!(s.passes_begun(), 0);
        let all: Vec<Due> = s.by_ref().map(|d| d.unwrap()).collect();
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
        let s = Schedule::from_records(trace(), &BTreeSet::new(), Passes::Forever);
        assert_eq!(s.end(), None);
        assert_eq!(s.take(1000).count(), 1000);
        let everything = BTreeSet::from([Address(0xF5), Address(0xD0), Address(0xD3)]);
        let only_emulated = vec![record(5, "0300A0F5#01")];
        assert_eq!(
            Schedule::from_records(only_emulated, &everything, Passes::Forever).count(),
            0
        );
        // One instant: passes 1 ms apart.
        let one = vec![record(5, "123#00")];
        let s = Schedule::from_records(one, &BTreeSet::new(), Passes::Times(2));
        assert_eq!(s.map(|d| d.unwrap().offset).collect::<Vec<_>>(), [0, 1_000_000]);
    }

    /// A source over `trace()` that counts the records taken from it and the passes opened.
    fn counting(taken: Rc<Cell<usize>>, opened: Rc<Cell<usize>>) -> Source {
        Box::new(move || {
            opened.set(opened.get() + 1);
            let taken = taken.clone();
            Box::new(trace().into_iter().map(move |r| {
                taken.set(taken.get() + 1);
                Ok(r)
            }))
        })
    }

    #[test]
    fn records_are_read_one_ahead_and_again_for_each_pass() {
        let survey = Survey::new(trace().into_iter().map(Ok::<_, ()>), &BTreeSet::new()).unwrap();
        let (taken, opened) = (Rc::new(Cell::new(0)), Rc::new(Cell::new(0)));
        let source = counting(taken.clone(), opened.clone());
        let mut s = Schedule::new(survey, BTreeSet::new(), Passes::Times(2), source);
        assert_eq!(
            opened.get(),
            0,
            "nothing is read before the first frame is asked for"
        );
        let offsets: Vec<u64> = s.by_ref().take(3).map(|d| d.unwrap().offset / 1000).collect();
        // The third frame is the fourth record (the base frame, out of order, at 400 µs).
        assert_eq!(offsets, [0, 400, 400]);
        assert_eq!(taken.get(), 3);
        let rest: Vec<u64> = s.map(|d| d.unwrap().offset / 1000).collect();
        assert_eq!(rest, [3000, 3750, 4150, 4150, 6750]);
        assert_eq!(opened.get(), 2);
        assert_eq!(taken.get(), 10);
    }

    #[test]
    fn an_error_from_the_source_is_given_once_and_ends_the_schedule() {
        let survey = Survey::new(trace().into_iter().map(Ok::<_, ()>), &BTreeSet::new()).unwrap();
        let source: Source = Box::new(|| {
            let good = trace().into_iter().take(2).map(Ok);
            Box::new(good.chain(std::iter::once(Err(crate::Error::BadInput(
                "t.log:3: bad".into(),
            )))))
        });
        let got: Vec<Result<u64, String>> = Schedule::new(survey, BTreeSet::new(), Passes::Forever, source)
            .map(|d| d.map(|d| d.offset / 1000).map_err(|e| e.to_string()))
            .collect();
        assert_eq!(got, [Ok(0), Ok(400), Err("t.log:3: bad".to_string())]);
        // A trace emptied after the survey ends a looping schedule with an error.
        let survey = Survey::new(trace().into_iter().map(Ok::<_, ()>), &BTreeSet::new()).unwrap();
        let mut opened = 0;
        let source: Source = Box::new(move || {
            opened += 1;
            let records = if opened == 1 { trace() } else { Vec::new() };
            Box::new(records.into_iter().map(Ok))
        });
        let got: Vec<Result<u64, String>> = Schedule::new(survey, BTreeSet::new(), Passes::Forever, source)
            .map(|d| d.map(|d| d.offset / 1000).map_err(|e| e.to_string()))
            .collect();
        assert_eq!(got.len(), 5, "{got:?}");
        assert_eq!(
            got[4],
            Err("the trace changed while it was replayed: pass 2 found no frame to send".to_string())
        );
        // The survey stops at the first error too.
        let bad = trace().into_iter().map(Ok).take(2).chain([Err("line 3")]);
        assert_eq!(Survey::new(bad, &BTreeSet::new()), Err("line 3"));
    }
}
