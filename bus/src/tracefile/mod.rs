//! Trace files: one reader for candump logs and Vector ASC traces, and an ASC writer.
//!
//! Contract:
//! - [`Reader`] takes a trace one line at a time and gives back timestamped [`Record`]s with
//!   their line numbers. The format is decided by the first line that is not blank: a candump
//!   log line starts with `(`, anything else is read as ASC. Lines of the other format later on
//!   are errors, never guesses.
//! - Error frames are kept or skipped as the caller says ([`ErrorFrames`]); nothing is dropped
//!   silently except what the format defines as not being a frame (ASC header, comment and event
//!   lines such as `Start of measurement`, statistics or chip status).
//! - Every bad line gives [`Error::TraceLine`] with its 1-based line number; nothing panics.
//!   Text from the line is quoted in the reason cut to a few dozen characters
//!   ([`crate::text::quote`]), so an error is one short line whatever the input.
//! - [`read`] reads at most [`MAX_LINE`] (64 KiB) of a line: a longer line is a bad line as soon
//!   as that much of it has been read, so input without line breaks (`/dev/zero`) ends at once
//!   and memory stays bounded ([`Lines`]).
//! - Times never go backwards: a frame or error frame (kept or skipped) stamped earlier than the
//!   one before it is a bad line. Equal times are fine. Nothing is sorted or held back, so memory
//!   does not grow with the trace.
//! - Timestamps are kept exactly to the nanosecond as written (`1708620903.978650` in a candump
//!   log is seconds since 1970, an ASC time is seconds since the start of the measurement); no
//!   floating point is involved. An ASC file whose header says `timestamps relative` has each
//!   time relative to the previous timestamped line's; the reader gives the accumulated times.
//! - [`asc`] formats ASC lines; [`AscWriter`] is a trace sink ([`crate::trace::Sink`]) that
//!   writes the hub's records as an ASC file.

mod any;
pub mod asc;
pub mod blf;
mod candump_log;
mod convert;
mod format;
mod item;
mod le;
#[cfg(test)]
mod limit_tests;
mod lines;
pub mod mf4;
pub mod pcapng;
mod pcapng_read;
#[cfg(test)]
mod pcapng_tests;
#[cfg(test)]
mod test_items;
#[cfg(test)]
mod tests;

pub use any::{Items, items};
pub use convert::{AscWriter, LogWriter};
pub use format::{FileFormat, Sniffed};
pub use item::{Item, ItemWriter, Stamped, fill};
pub use lines::{LineError, Lines, MAX_LINE};
pub use pcapng::PcapngWriter;
pub use pcapng_read::PcapngReader;

use crate::text::quote;
use crate::time::Stamp;
use crate::trace::ErrorFrame;
use crate::{Error, Frame};
use std::fmt::Write as _;
use std::io::BufRead;

/// The two formats a [`Reader`] understands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// `(1708620903.978650) can0 0601F5D0#200D0002FFBFFF00` (`candump -L`).
    Candump,
    /// Vector ASC (CANalyzer, CANoe, python-can's `ASCWriter`).
    Asc,
}

/// What to do with error frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorFrames {
    /// Give them back as [`Entry::Error`].
    Keep,
    /// Leave them out.
    Skip,
}

/// What one line of a trace holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entry {
    /// A data or remote frame.
    Frame(Frame),
    /// An error frame: with SocketCAN's class bits and data when the format carries them
    /// (candump), without when it does not (ASC's `ErrorFrame`).
    Error(Option<ErrorFrame>),
}

/// One timestamped entry of a trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Record {
    /// The time written on the line, in nanoseconds.
    pub at: Stamp,
    /// 1-based line number.
    pub line: usize,
    /// The frame or error frame.
    pub entry: Entry,
}

/// Reads a trace line by line.
#[derive(Debug)]
pub struct Reader {
    errors: ErrorFrames,
    format: Option<Format>,
    asc: asc::ReadState,
    line: usize,
    /// The time of the last frame or error frame, with its line.
    last: Option<(Stamp, usize)>,
    /// The interface of the last record: a candump log's, or `canN` for ASC channel N+1.
    interface: String,
}

impl Reader {
    /// A reader that has seen no line yet.
    pub fn new(errors: ErrorFrames) -> Reader {
        Reader {
            errors,
            format: None,
            asc: asc::ReadState::default(),
            line: 0,
            last: None,
            interface: String::new(),
        }
    }

    /// The format, once a line that is not blank has been seen.
    pub fn format(&self) -> Option<Format> {
        self.format
    }

    /// Lines taken so far.
    pub fn lines(&self) -> usize {
        self.line
    }

    /// The interface of the last record given: a candump log's own, `canN` for ASC channel
    /// N + 1 (ASC numbers channels from 1, SocketCAN and python-can from 0).
    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// The time of a record since 1970: a candump log's as it is; an ASC time added to the
    /// measurement's start (its `date` line, to the millisecond; 1970 when there is none that
    /// reads as a date).
    pub fn since_1970(&self, at: Stamp) -> Stamp {
        match self.format {
            Some(Format::Asc) => Stamp(at.0.saturating_add(self.asc.start.unwrap_or_default().0)),
            _ => at,
        }
    }

    /// Takes the next line (without its line break); gives the record it holds, if any.
    pub fn line(&mut self, text: &str) -> Result<Option<Record>, Error> {
        self.line += 1;
        let line = self.line;
        let trimmed = text.trim();
        if trimmed.is_empty() {
            return Ok(None);
        }
        let format = *self.format.get_or_insert(if trimmed.starts_with('(') {
            Format::Candump
        } else {
            Format::Asc
        });
        let parsed = match format {
            Format::Candump => candump_log::parse_line(trimmed).map(|(at, iface, entry)| {
                self.interface.clear();
                self.interface.push_str(iface);
                Some((at, entry))
            }),
            Format::Asc => self.asc.parse_line(trimmed).inspect(|entry| {
                if entry.is_some() {
                    self.interface.clear();
                    let _ = write!(self.interface, "can{}", self.asc.channel.saturating_sub(1));
                }
            }),
        };
        let entry = parsed.map_err(|reason| Error::TraceLine { line, reason })?;
        if let Some((at, _)) = entry {
            if let Some((before, before_line)) = self.last
                && at < before
            {
                return Err(Error::TraceLine {
                    line,
                    reason: format!(
                        "time {at} goes backwards: line {before_line} is at {before} (a trace must be in time order)"
                    ),
                });
            }
            self.last = Some((at, line));
        }
        Ok(entry.and_then(|(at, entry)| match (entry, self.errors) {
            (Entry::Error(_), ErrorFrames::Skip) => None,
            _ => Some(Record { at, line, entry }),
        }))
    }
}

/// Reads every record of a trace from `input`, one line at a time: memory does not grow with the
/// trace. A line that cannot be read (longer than [`MAX_LINE`], bad text, not UTF-8, an I/O
/// error) ends it with an error naming the line.
pub fn read(input: impl BufRead, errors: ErrorFrames) -> impl Iterator<Item = Result<Record, Error>> {
    read_numbered(input, errors).map(|r| r.map(|(_, record)| record))
}

/// [`read`], each record with the number of its line (from 1).
pub fn read_numbered(
    input: impl BufRead,
    errors: ErrorFrames,
) -> impl Iterator<Item = Result<(u64, Record), Error>> {
    read_lines(input, errors, |_, record| record)
}

/// Every record of a text trace as an [`Item`], numbered by its line: times since 1970 (ASC's
/// from its `date` line), interfaces as [`Reader::interface`] gives them.
pub fn text_items(
    input: impl BufRead,
    errors: ErrorFrames,
) -> impl Iterator<Item = Result<(u64, Item), Error>> {
    read_lines(input, errors, |reader, record| Item {
        at: reader.since_1970(record.at),
        interface: reader.interface().to_string(),
        entry: record.entry,
    })
}

fn read_lines<T>(
    input: impl BufRead,
    errors: ErrorFrames,
    mut make: impl FnMut(&Reader, Record) -> T,
) -> impl Iterator<Item = Result<(u64, T), Error>> {
    let mut reader = Reader::new(errors);
    let mut lines = Lines::new(input, MAX_LINE);
    let mut failed = false;
    std::iter::from_fn(move || {
        while !failed {
            // Every line given or refused counts one.
            let line = lines.number() + 1;
            let result = match lines.next_line()? {
                Ok(bytes) => match std::str::from_utf8(bytes) {
                    Ok(text) => reader.line(text),
                    Err(e) => Err(Error::TraceLine {
                        line,
                        reason: format!(
                            "not UTF-8 text (byte {} is not): {}",
                            e.valid_up_to() + 1,
                            quote(&String::from_utf8_lossy(bytes))
                        ),
                    }),
                },
                Err(LineError::TooLong { start }) => Err(Error::TraceLine {
                    line,
                    reason: format!(
                        "longer than {MAX_LINE} bytes, the limit for a trace line: {}",
                        quote(&start)
                    ),
                }),
                Err(LineError::Io(e)) => Err(Error::TraceLine {
                    line,
                    reason: format!("cannot read: {e}"),
                }),
            };
            match result {
                Ok(Some(record)) => return Some(Ok((line as u64, make(&reader, record)))),
                Ok(None) => {}
                Err(e) => {
                    failed = true;
                    return Some(Err(e));
                }
            }
        }
        None
    })
}

/// Reads every record of a trace held in memory.
pub fn read_str(text: &str, errors: ErrorFrames) -> Result<Vec<Record>, Error> {
    read(text.as_bytes(), errors).collect()
}

/// Reads `secs.fraction` exactly (up to 9 fraction digits; more are cut off).
fn parse_time(text: &str) -> Result<Stamp, String> {
    let bad = || format!("{} is not a time in seconds (e.g. 1.234567)", quote(text));
    let (secs, fraction) = text.split_once('.').unwrap_or((text, ""));
    if secs.is_empty()
        || !secs.bytes().all(|b| b.is_ascii_digit())
        || !fraction.bytes().all(|b| b.is_ascii_digit())
    {
        return Err(bad());
    }
    let secs: u64 = secs.parse().map_err(|_| bad())?;
    let mut nanos = 0u64;
    for i in 0..9 {
        let digit = fraction.as_bytes().get(i).map_or(0, |b| u64::from(b - b'0'));
        nanos = nanos * 10 + digit;
    }
    secs.checked_mul(1_000_000_000)
        .and_then(|s| s.checked_add(nanos))
        .map(Stamp)
        .ok_or_else(|| format!("time {} is too large", quote(text)))
}
