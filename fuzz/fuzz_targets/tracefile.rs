//! Trace readers (candump log and Vector ASC): whole-text and line-by-line reading agree, error
//! frames are the only difference between keeping and skipping them, bad lines are named by
//! number, errors are one short line, and every record written back in its own format reads back
//! the same. The bounded line reader under them, with a small limit, gives no line over it and
//! every other line as a plain split does.
#![no_main]

use bus::Error;
use bus::time::{BusTime, Stamp};
use bus::tracefile::{self, Entry, ErrorFrames, Format, LineError, Lines, Reader, Record};
use libfuzzer_sys::fuzz_target;
use std::io::BufReader;

/// The longest an error about a line may be, characters.
const SHORT: usize = 200;

fuzz_target!(|input: &[u8]| {
    bounded_lines(input);
    let Ok(text) = std::str::from_utf8(input) else {
        // Not UTF-8: the streaming reader stops at the bad line with an error naming it.
        for r in tracefile::read(input, ErrorFrames::Keep) {
            if let Err(e) = r {
                assert!(matches!(e, Error::TraceLine { line, .. } if line >= 1), "{e}");
            }
        }
        return;
    };
    let lines = text.lines().count();
    let keep = tracefile::read_str(text, ErrorFrames::Keep);
    let skip = tracefile::read_str(text, ErrorFrames::Skip);

    // Line by line, as `replay` reads a file.
    let mut reader = Reader::new(ErrorFrames::Keep);
    let mut by_line = Vec::new();
    let mut failed = None;
    for l in text.lines() {
        match reader.line(l) {
            Ok(Some(r)) => by_line.push(r),
            Ok(None) => {}
            Err(e) => {
                failed = Some(e);
                break;
            }
        }
    }
    match (&keep, failed) {
        (Ok(records), None) => assert_eq!(records, &by_line),
        (Err(a), Some(b)) => assert_eq!(a, &b),
        (a, b) => panic!("read_str {a:?} but line by line {b:?}"),
    }

    match (&keep, &skip) {
        (Ok(k), Ok(s)) => {
            let frames: Vec<&Record> = k.iter().filter(|r| matches!(r.entry, Entry::Frame(_))).collect();
            assert_eq!(frames, s.iter().collect::<Vec<_>>());
            assert!(k.windows(2).all(|w| w[0].line < w[1].line));
            assert!(k.iter().all(|r| (1..=lines).contains(&r.line)));
            if let Some(format) = reader.format() {
                write_back(format, k);
            }
        }
        (Err(a), Err(b)) => {
            assert_eq!(a, b);
            let shown = a.to_string();
            assert!(shown.chars().count() < SHORT && !shown.contains('\n'), "{shown}");
            assert!(
                matches!(a, Error::TraceLine { line, .. } if (1..=lines).contains(line)),
                "{a}"
            );
        }
        (a, b) => panic!("keeping error frames gives {a:?}, skipping them {b:?}"),
    }
});

/// Writes the records in their format and reads them back: same entries, times to the
/// microsecond (both formats write microseconds). The ASC writer takes bus time, which ends at
/// [`BusTime::NEVER`] (about 61.8 days), so later times come back as that end.
fn write_back(format: Format, records: &[Record]) {
    let mut out = String::new();
    for r in records {
        match (format, &r.entry) {
            (Format::Candump, Entry::Frame(f)) => bus::trace::frame_line(&mut out, r.at, "can0", f),
            (Format::Candump, Entry::Error(Some(e))) => bus::trace::error_line(&mut out, r.at, "can0", e),
            (Format::Asc, Entry::Frame(f)) => {
                tracefile::asc::frame_line(&mut out, BusTime::from_nanos(r.at.0), 1, f)
            }
            (Format::Asc, Entry::Error(None)) => {
                tracefile::asc::error_line(&mut out, BusTime::from_nanos(r.at.0), 1)
            }
            (format, entry) => panic!("{format:?} gave {entry:?}"),
        }
    }
    let back = tracefile::read_str(&out, ErrorFrames::Keep).unwrap_or_else(|e| panic!("{e}\n{out}"));
    assert_eq!(back.len(), records.len(), "{out}");
    let end = match format {
        Format::Asc => BusTime::NEVER.as_nanos(),
        Format::Candump => u64::MAX,
    };
    for (a, b) in records.iter().zip(&back) {
        assert_eq!(a.entry, b.entry, "{out}");
        assert_eq!(Stamp(a.at.0.min(end) / 1000 * 1000), b.at, "{out}");
    }
}

/// The first byte is a limit (0–63) and the rest is read with it, 7 bytes at a time: every line
/// given is at most the limit and is the line a plain split on `\n` gives (without a `\r` before
/// the `\n`); every longer line is refused, and nothing else.
fn bounded_lines(input: &[u8]) {
    let Some((&limit, rest)) = input.split_first() else {
        return;
    };
    let limit = usize::from(limit % 64);
    let mut want: Vec<&[u8]> = rest.split(|&b| b == b'\n').collect();
    if rest.is_empty() || rest.ends_with(b"\n") {
        want.pop();
    }
    let last = want.len().saturating_sub(1);
    let mut lines = Lines::new(BufReader::with_capacity(7, rest), limit);
    for (i, w) in want.iter().enumerate() {
        let ends_in_newline = i < last || rest.ends_with(b"\n");
        let w = if ends_in_newline {
            w.strip_suffix(b"\r").unwrap_or(w)
        } else {
            w
        };
        match lines.next_line() {
            Some(Ok(got)) => {
                assert!(got.len() <= limit, "{} bytes, limit {limit}", got.len());
                assert_eq!(got, w);
            }
            Some(Err(LineError::TooLong { start })) => {
                assert!(w.len() > limit, "{} bytes refused, limit {limit}", w.len());
                assert!(start.len() <= 3 * limit, "{start:?}");
            }
            Some(Err(LineError::Io(e))) => panic!("{e}"),
            None => panic!("line {} of {} missing", i + 1, want.len()),
        }
        assert_eq!(lines.number(), i + 1);
    }
    assert!(lines.next_line().is_none());
}
