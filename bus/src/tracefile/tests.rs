use super::*;
use crate::candump::parse_frame;
use crate::time::BusTime;
use crate::trace::err;
use proptest::prelude::*;
use std::time::{Duration, UNIX_EPOCH};

fn frame(text: &str) -> Frame {
    parse_frame(text).unwrap()
}

fn frames(records: &[Record]) -> Vec<(u64, Frame)> {
    records
        .iter()
        .filter_map(|r| match r.entry {
            Entry::Frame(f) => Some((r.at.as_nanos(), f)),
            Entry::Error(_) => None,
        })
        .collect()
}

#[test]
fn candump_logs_are_read_with_error_frames_kept_or_skipped() {
    let log = "(1708620903.978650) can0 0601F5D0#200D0002FFBFFF00\n\
               \n\
               (1708620903.978900) can0 123#R4 R\n\
               (1708620903.979000) harv0 200002A8#0000801900000800\n\
               (1708620903.980000) vcan0 7FF# T\n";
    let kept = read_str(log, ErrorFrames::Keep).unwrap();
    assert_eq!(
        kept.iter().map(|r| (r.line, r.at.as_nanos())).collect::<Vec<_>>(),
        [
            (1, 1_708_620_903_978_650_000),
            (3, 1_708_620_903_978_900_000),
            (4, 1_708_620_903_979_000_000),
            (5, 1_708_620_903_980_000_000)
        ]
    );
    assert_eq!(kept[0].entry, Entry::Frame(frame("0601F5D0#200D0002FFBFFF00")));
    assert_eq!(kept[1].entry, Entry::Frame(frame("123#R4")));
    let Entry::Error(Some(e)) = kept[2].entry else {
        panic!("{:?}", kept[2]);
    };
    assert_eq!(
        e.can_id,
        0x2000_0000 | err::PROT | err::ACK | err::BUSERROR | err::CNT
    );
    assert_eq!(e.data, [0, 0, 0x80, 0x19, 0, 0, 0x08, 0]);
    let skipped = read_str(log, ErrorFrames::Skip).unwrap();
    assert_eq!(frames(&skipped), frames(&kept));
    assert_eq!(skipped.len(), 3);
}

/// An ASC file as CANalyzer writes one: header, comment, trigger block, events interleaved with
/// frames, trailing bit-timing fields, a CAN FD-free classic log.
const CANALYZER: &str = "date Wed Jun 12 02:47:38.610 pm 2024\r
base hex  timestamps absolute\r
internal events logged\r
// version 13.0.0\r
// Measurement UUID: 9c2b4f5e-1d3a-4e8b-9a77-0c1d2e3f4a5b\r
Begin Triggerblock Wed Jun 12 02:47:38.610 pm 2024\r
   0.000000 Start of measurement\r
   0.001372 1  Statistic: D 0 R 0 XD 0 XR 0 E 0 O 0 B 0.00%\r
   0.015991 CAN 1 Status:chip status error active\r
   1.015991 1  300A0F5x        Rx   d 2 01 01  Length = 238000 BitCount = 123 ID = 50372853x\r
   1.016456 2  C8              Tx   d 8 09 08 07 06 05 04 03 02\r
   1.017000 1  5x              Rx   r\r
   1.018000 1  7FF             Rx   r 8\r
   1.019000 1  123             Rx   d 0\r
   1.020000 1  ErrorFrame\r
   1.021000 1  SV: 5 0 1 ::System::Engine = 1\r
   1.022000 J1939TP FEE3p 6 0 0 - Rx d 23 A0 0F A6 60 3B D1 40 1F\r
End TriggerBlock\r
";

#[test]
fn asc_as_canalyzer_writes_it() {
    let mut reader = Reader::new(ErrorFrames::Keep);
    let mut records = Vec::new();
    for line in CANALYZER.lines() {
        records.extend(reader.line(line).unwrap());
    }
    assert_eq!(reader.format(), Some(Format::Asc));
    let got: Vec<(usize, u64, String)> = records
        .iter()
        .map(|r| {
            let what = match r.entry {
                Entry::Frame(f) => crate::candump::format_frame(&f),
                Entry::Error(e) => format!("error {e:?}"),
            };
            (r.line, r.at.as_nanos() / 1000, what)
        })
        .collect();
    let want = [
        (10, 1_015_991, "0300A0F5#0101"),
        (11, 1_016_456, "0C8#0908070605040302"),
        (12, 1_017_000, "00000005#R"),
        (13, 1_018_000, "7FF#R8"),
        (14, 1_019_000, "123#"),
        (15, 1_020_000, "error None"),
    ];
    assert_eq!(
        got,
        want.map(|(l, t, f)| (l, t, f.to_string())).to_vec(),
        "frames and the error frame, nothing else"
    );
}

#[test]
fn asc_in_decimal_base() {
    let text = "date Wed Jun 12 02:47:38.610 pm 2024\nbase dec  timestamps absolute\n\
                0.5 1 200 Rx d 3 1 2 255\n0.6 1 50000000x Tx d 1 16\n";
    let got = read_str(text, ErrorFrames::Keep).unwrap();
    assert_eq!(
        frames(&got),
        [
            (500_000_000, Frame::base(200, &[1, 2, 255]).unwrap()),
            (600_000_000, Frame::extended(50_000_000, &[16]).unwrap())
        ]
    );
}

#[test]
fn bad_lines_are_named_by_number() {
    let asc =
        |body: &str| format!("date Wed Jun 12 02:47:38.610 pm 2024\nbase hex  timestamps absolute\n\n{body}");
    for (body, line, words) in [
        ("hello world\n", 4, "not an ASC line"),
        ("1.0 1 12G Rx d 1 00\n", 4, "identifier '12G'"),
        ("1.0 1 800 Rx d 1 00\n", 4, "11 bits"),
        ("1.0 1 20000000x Rx d 1 00\n", 4, "29 bits"),
        ("1.0 1 123 Rx d 9 00 01 02 03 04 05 06 07 08\n", 4, "above 8"),
        ("1.0 1 123 Rx d 3 01 02\n", 4, "DLC 3 but 2 data bytes"),
        ("1.0 1 123 Rx d 1 01 02\n", 4, "more data bytes"),
        ("1.0 1 123 Rx q 1 01\n", 4, "frame type 'q'"),
        ("1.0 1 123 Rx\n", 4, "no frame type"),
        ("1.0 1 123 Rx d 2 01 1FF\n", 4, "data byte '1FF'"),
        (
            "0.5 1 123 Rx d 0\n1.0 CANFD 1 Rx 123 1 0 8 8 00 00 00 00 00 00 00 00\n",
            5,
            "CAN FD",
        ),
        ("1.0.0 1 123 Rx d 0\n", 4, "not an ASC line"),
        ("base oct\n", 4, "hex or dec"),
    ] {
        let e = read_str(&asc(body), ErrorFrames::Keep).unwrap_err();
        let Error::TraceLine { line: l, reason } = &e else {
            panic!("{e:?}");
        };
        assert_eq!(*l, line, "{body}: {e}");
        assert!(reason.contains(words), "{body}: {e}");
        assert!(e.to_string().starts_with(&format!("line {line}: ")), "{e}");
    }
    for (log, line, words) in [
        ("(1.000000) can0 123#00\n(1.5) can0 123#0G\n", 2, "non-hex"),
        (
            "(1.000000) can0 123#00\n1.5 1 123 Rx d 0\n",
            2,
            "not a candump log line",
        ),
        ("(1.000000)\n", 1, "lacks"),
        ("(x) can0 123#00\n", 1, "not a time"),
        ("(1.0) can0 123#00 extra words\n", 1, "text after"),
        ("(1.0) can0 123##100\n", 1, "CAN FD"),
        ("(1.0) can0 E0000000#00\n", 1, "flags other than CAN_ERR_FLAG"),
        ("(1.0) can0 12345#00\n", 1, "5 hex digits"),
    ] {
        let e = read_str(log, ErrorFrames::Keep).unwrap_err();
        assert!(
            matches!(e, Error::TraceLine { line: l, .. } if l == line),
            "{log}: {e}"
        );
        assert!(e.to_string().contains(words), "{log}: {e}");
    }
}

#[test]
fn times_that_go_backwards_are_bad_lines() {
    // Error frames count, kept or skipped; equal times are fine.
    let log = "(1.000000) can0 123#00\n\
               (1.000000) harv0.D2 20000288#0000010A00000800\n\
               (2.000000) harv0.D2 20000288#0000010A00000800\n\
               (1.999999) can0 123#01\n";
    for errors in [ErrorFrames::Keep, ErrorFrames::Skip] {
        let e = read_str(log, errors).unwrap_err();
        let Error::TraceLine { line, reason } = &e else {
            panic!("{e:?}");
        };
        assert_eq!(*line, 4, "{e}");
        assert!(
            reason.contains("1.999999 goes backwards: line 3 is at 2.000000"),
            "{e}"
        );
    }
    let asc = "base hex  timestamps absolute\n\
               Begin Triggerblock\n\
               0.500000 1  123  Rx   d 1 00\n\
               0.500000 1  ErrorFrame\n\
               0.400000 1  123  Rx   d 1 00\n";
    let e = read_str(asc, ErrorFrames::Skip).unwrap_err();
    assert!(matches!(e, Error::TraceLine { line: 5, .. }), "{e}");
    assert!(e.to_string().contains("goes backwards"), "{e}");
    let equal = "(1.0) can0 123#00\n(1.0) can0 123#01\n(1.0) harv0.E0 20000004#0000000000000000\n";
    assert_eq!(read_str(equal, ErrorFrames::Keep).unwrap().len(), 3);
}

#[test]
fn relative_asc_times_accumulate() {
    // Every timestamped line, events included, is relative to the one before it.
    let asc = "date Wed Jun 12 02:47:38.610 pm 2024\n\
               base hex  timestamps relative\n\
               internal events logged\n\
               Begin Triggerblock Wed Jun 12 02:47:38.610 pm 2024\n\
               0.000000 Start of measurement\n\
               0.250000 1  123  Rx   d 1 00\n\
               0.100000 1  Statistic: D 1 R 0 XD 0 XR 0 E 0 O 0 B 0.12%\n\
               0.000500 1  0300A0F5x  Rx   d 2 01 01\n\
               0.000000 1  ErrorFrame\n\
               1.5 1  7FF  Tx   r 0\n\
               End TriggerBlock\n";
    let records = read_str(asc, ErrorFrames::Keep).unwrap();
    // 0.25; 0.25 + 0.1 + 0.0005 = 0.3505; the same; 0.3505 + 1.5 = 1.8505.
    assert_eq!(
        records
            .iter()
            .map(|r| (r.line, r.at.as_nanos()))
            .collect::<Vec<_>>(),
        [
            (6, 250_000_000),
            (8, 350_500_000),
            (9, 350_500_000),
            (10, 1_850_500_000)
        ]
    );
    let absolute = asc.replace("timestamps relative", "timestamps absolute");
    let e = read_str(&absolute, ErrorFrames::Keep).unwrap_err();
    assert!(matches!(e, Error::TraceLine { line: 8, .. }), "{e}");
    let bare = asc.replace("  timestamps relative", "");
    assert!(
        read_str(&bare, ErrorFrames::Keep).is_err(),
        "absolute is the default"
    );
    let e = read_str("base hex timestamps sideways\n", ErrorFrames::Keep).unwrap_err();
    assert!(e.to_string().contains("absolute or relative"), "{e}");
}

#[test]
fn reading_stops_at_the_first_bad_line() {
    let text = "(1.0) can0 123#00\n(2.0) can0 bad\n(3.0) can0 123#00\n";
    let all: Vec<_> = read(text.as_bytes(), ErrorFrames::Keep).collect();
    assert_eq!(all.len(), 2);
    assert!(all[0].is_ok() && all[1].is_err());
    let invalid_utf8: &[u8] = b"(1.0) can0 123#00\n(2.0) \xFF\n";
    let all: Vec<_> = read(invalid_utf8, ErrorFrames::Keep).collect();
    assert!(
        matches!(&all[1], Err(Error::TraceLine { line: 2, .. })),
        "{all:?}"
    );
}

#[test]
fn times_are_exact() {
    assert_eq!(
        parse_time("1708620903.978650"),
        Ok(Stamp(1_708_620_903_978_650_000))
    );
    assert_eq!(parse_time("0.000001"), Ok(Stamp(1_000)));
    assert_eq!(parse_time("2"), Ok(Stamp(2_000_000_000)));
    assert_eq!(parse_time("1.1234567891"), Ok(Stamp(1_123_456_789)));
    assert!(parse_time("-1.0").is_err());
    assert!(parse_time("99999999999.0").is_err());
}

#[test]
fn asc_header_and_lines() {
    let start = UNIX_EPOCH + Duration::from_micros(1_708_620_903_978_650);
    assert_eq!(asc::date(start), "Thu Feb 22 04:55:03.978 pm 2024");
    assert_eq!(asc::date(UNIX_EPOCH), "Thu Jan 01 12:00:00.000 am 1970");
    let mut out = String::new();
    asc::header(&mut out, start);
    assert_eq!(
        out,
        "date Thu Feb 22 04:55:03.978 pm 2024\nbase hex  timestamps absolute\n\
         internal events logged\n// version 9.0.0\n\
         Begin Triggerblock Thu Feb 22 04:55:03.978 pm 2024\n   0.000000 Start of measurement\n"
    );
    out.clear();
    asc::frame_line(
        &mut out,
        BusTime::from_nanos(1_234_567_000),
        1,
        &frame("0300A0F5#0101"),
    );
    asc::frame_line(&mut out, BusTime::from_nanos(1_300_000_000), 1, &frame("123#R4"));
    asc::error_line(&mut out, BusTime::from_nanos(1_400_000_000), 1);
    asc::footer(&mut out);
    assert_eq!(
        out,
        "   1.234567 1  0300A0F5x       Rx   d 2 01 01\n\
         \x20  1.300000 1  123             Rx   r 4\n\
         \x20  1.400000 1  ErrorFrame\n\
         End TriggerBlock\n"
    );
}

#[test]
fn the_asc_writer_writes_the_lines_of_the_format_and_ends_the_file_when_dropped() {
    // docs/TRACES.md's example: 2024-01-01T00:00:00Z was a Monday; ASC times count from it.
    let mut file = Vec::new();
    {
        let mut w = AscWriter::new(&mut file, crate::time::Epoch::from_secs(1_704_067_200)).unwrap();
        for r in crate::trace::tests::example() {
            w.record(&r).unwrap();
        }
    }
    assert_eq!(
        String::from_utf8(file).unwrap(),
        "date Mon Jan 01 12:00:00.000 am 2024\n\
         base hex  timestamps absolute\n\
         internal events logged\n\
         // version 9.0.0\n\
         Begin Triggerblock Mon Jan 01 12:00:00.000 am 2024\n\
         \x20  0.000000 Start of measurement\n\
         \x20  0.551520 1  0200F5E0x       Rx   d 7 10 78 00 F4 01 00 00\n\
         \x20  0.600000 1  123             Rx   r 4\n\
         \x20  0.700000 1  ErrorFrame\n\
         End TriggerBlock\n"
    );
}

#[test]
fn the_asc_writer_refuses_records_once_finished() {
    let mut file = Vec::new();
    let mut w = AscWriter::new(&mut file, crate::time::Epoch::UNIX).unwrap();
    w.finish().unwrap();
    let r = crate::trace::tests::example()[0];
    assert!(w.record(&r).is_err());
    drop(w);
    assert_eq!(
        String::from_utf8(file)
            .unwrap()
            .matches("End TriggerBlock")
            .count(),
        1
    );
}

use crate::trace::{CandumpWriter, Kind, Sink, Source};

/// The candump log line of a frame, written here independently of `bus::trace`.
fn reference_line(at_us: u64, id: u32, extended: bool, remote: Option<u8>, data: &[u8]) -> String {
    let id = if extended {
        format!("{id:08X}")
    } else {
        format!("{id:03X}")
    };
    let body = match remote {
        Some(0) => "R".to_string(),
        Some(dlc) => format!("R{dlc}"),
        None => data.iter().map(|b| format!("{b:02X}")).collect(),
    };
    format!(
        "({}.{:06}) harv0 {id}#{body}\n",
        at_us / 1_000_000,
        at_us % 1_000_000
    )
}

type Spec = (u64, u32, bool, Option<u8>, Vec<u8>);

fn spec() -> impl Strategy<Value = Spec> {
    (
        0u64..10_000_000_000,
        any::<bool>(),
        prop::option::weighted(0.2, 0u8..=8),
        prop::collection::vec(any::<u8>(), 0..=8),
        any::<u32>(),
    )
        .prop_map(|(gap, extended, remote, data, id)| {
            let id = if extended { id & 0x1FFF_FFFF } else { id & 0x7FF };
            (gap, id, extended, remote, data)
        })
}

fn spec_frame(id: u32, extended: bool, remote: Option<u8>, data: &[u8]) -> Frame {
    let id: crate::Id = if extended {
        crate::extended_id(id).unwrap().into()
    } else {
        crate::standard_id(id as u16).unwrap().into()
    };
    match remote {
        Some(dlc) => Frame::new_remote(id, dlc.into()).unwrap(),
        None => Frame::new_data(id, data).unwrap(),
    }
}

proptest! {
    /// The same records written as a candump log and as ASC: the log is the text the format
    /// prescribes, and reading both back gives the same frames at the same times.
    #[test]
    fn candump_and_asc_from_the_same_records_agree(specs in prop::collection::vec(spec(), 0..40)) {
        let mut at = 0u64;
        let mut want = String::new();
        let (mut log, mut asc) = (Vec::new(), Vec::new());
        {
            let mut c = CandumpWriter::new(&mut log, crate::time::Epoch::UNIX);
            let mut a = AscWriter::new(&mut asc, crate::time::Epoch::UNIX).unwrap();
            for (gap, id, extended, remote, data) in &specs {
                // Records are exact to the nanosecond; both formats keep microseconds.
                at += gap;
                want.push_str(&reference_line(at / 1_000, *id, *extended, *remote, data));
                let r = crate::trace::Record {
                    at: BusTime::from_nanos(at),
                    bus: "harv0",
                    source: Source::Bus,
                    kind: Kind::Frame(spec_frame(*id, *extended, *remote, data)),
                };
                c.record(&r).unwrap();
                a.record(&r).unwrap();
            }
            a.finish().unwrap();
        }
        let log = String::from_utf8(log).unwrap();
        prop_assert_eq!(&log, &want);
        let from_asc = read_str(&String::from_utf8(asc).unwrap(), ErrorFrames::Keep).unwrap();
        let from_log = read_str(&log, ErrorFrames::Keep).unwrap();
        prop_assert_eq!(frames(&from_asc), frames(&from_log));
        prop_assert_eq!(from_asc.len(), specs.len());
    }
}
