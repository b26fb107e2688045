//! The `ID#DATA` notation: `parse_frame`, `parse_id` and `parse_hex_bytes` against a reference
//! reading written here, and formatting back.
#![no_main]

use bus::candump::{format_frame, parse_frame, parse_hex_bytes, parse_id};
use bus::{Frame, Id};
use harvemu_fuzz::{reference_hex_bytes, reference_id};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    let Ok(text) = std::str::from_utf8(input) else {
        return;
    };
    frame(text);
    if let Some((id, data)) = text.split_once('#') {
        identifier(id);
        bytes(data);
    }
    identifier(text);
    bytes(text);
});

fn frame(text: &str) {
    let parsed = parse_frame(text);
    if let Ok(f) = &parsed {
        // The canonical text reads back to the same frame and is a fixed point.
        let canonical = format_frame(f);
        assert_eq!(parse_frame(&canonical).as_ref(), Ok(f), "{text:?} -> {canonical}");
        assert_eq!(format_frame(&parse_frame(&canonical).unwrap()), canonical);
    }
    // Data frames are checked against the reference; a remote frame's DLC is a plain number.
    let Some((id, data)) = text.trim().split_once('#') else {
        assert!(parsed.is_err());
        return;
    };
    if data.starts_with(['R', 'r']) {
        return;
    }
    let expected = reference_id(id).zip(reference_hex_bytes(data));
    match (&parsed, expected) {
        (Ok(f), Some(((raw, extended), bytes))) => {
            assert_eq!((f.raw_id(), f.is_extended()), (raw, extended), "{text:?}");
            assert_eq!(f.data(), &bytes[..], "{text:?}");
            assert!(!f.is_remote());
        }
        (Err(_), None) => {}
        (got, want) => panic!("{text:?}: parsed {got:?}, reference {want:?}"),
    }
}

fn identifier(text: &str) {
    let got = parse_id(text).ok().map(|id| match id {
        Id::Standard(id) => (u32::from(id.as_raw()), false),
        Id::Extended(id) => (id.as_raw(), true),
    });
    assert_eq!(got, reference_id(text), "{text:?}");
}

fn bytes(text: &str) {
    let got = parse_hex_bytes(text);
    assert_eq!(got.as_ref().ok(), reference_hex_bytes(text).as_ref(), "{text:?}");
    if let Ok(b) = got {
        let f = Frame::base(0x123, &b).expect("at most 8 bytes");
        let hex: String = text.chars().filter(|&c| c != '.').collect();
        assert_eq!(format_frame(&f)[4..], hex.to_ascii_uppercase());
    }
}
