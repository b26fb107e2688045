//! Trace readers (candump log and Vector ASC): whole-text and line-by-line reading agree, error
//! frames are the only difference between keeping and skipping them, bad lines are named by
//! number, and every record written back in its own format reads back the same.
#![no_main]

use bus::Error;
use bus::time::BusTime;
use bus::tracefile::{self, Entry, ErrorFrames, Format, Reader, Record};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
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
            assert!(
                matches!(a, Error::TraceLine { line, .. } if (1..=lines).contains(line)),
                "{a}"
            );
        }
        (a, b) => panic!("keeping error frames gives {a:?}, skipping them {b:?}"),
    }
});

/// Writes the records in their format and reads them back: same entries, times to the
/// microsecond (both formats write microseconds).
fn write_back(format: Format, records: &[Record]) {
    let mut out = String::new();
    for r in records {
        match (format, &r.entry) {
            (Format::Candump, Entry::Frame(f)) => bus::trace::frame_line(&mut out, r.at, "can0", f),
            (Format::Candump, Entry::Error(Some(e))) => bus::trace::error_line(&mut out, r.at, "can0", e),
            (Format::Asc, Entry::Frame(f)) => tracefile::asc::frame_line(&mut out, r.at, 1, f),
            (Format::Asc, Entry::Error(None)) => tracefile::asc::error_line(&mut out, r.at, 1),
            (format, entry) => panic!("{format:?} gave {entry:?}"),
        }
    }
    let back = tracefile::read_str(&out, ErrorFrames::Keep).unwrap_or_else(|e| panic!("{e}\n{out}"));
    assert_eq!(back.len(), records.len(), "{out}");
    for (a, b) in records.iter().zip(&back) {
        assert_eq!(a.entry, b.entry, "{out}");
        assert_eq!(BusTime(a.at.0 / 1000 * 1000), b.at, "{out}");
    }
}
