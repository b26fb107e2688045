//! Frame and identifier decoder: a frame built from raw bytes, its `ID#DATA` text, its
//! application identifier and its decoding through the message catalogue.
//!
//! Input: byte 0 is flags (bit 0 extended, bit 1 remote, bit 2 "take the identifier of a
//! catalogue message"), bytes 1–4 the identifier (little-endian), byte 5 the DLC of a remote
//! frame, the rest the payload. In catalogue mode byte 1 picks the message and byte 2 the node.
#![no_main]

use bus::{Error, Frame, Id};
use harvemu_fuzz::{covered_bits, word};
use libfuzzer_sys::fuzz_target;
use protocol::catalogue::{self, MESSAGES};
use protocol::ident::{Address, AppId};

fuzz_target!(|input: &[u8]| {
    let Some((&flags, rest)) = input.split_first() else {
        return;
    };
    let Some(frame) = build(flags, rest) else {
        return;
    };
    text_round_trip(&frame);
    identifier(&frame);
    decode(&frame);
});

fn build(flags: u8, rest: &[u8]) -> Option<Frame> {
    let byte = |i: usize| rest.get(i).copied().unwrap_or(0);
    let raw = u32::from_le_bytes([byte(0), byte(1), byte(2), byte(3)]);
    let data = rest.get(5..).unwrap_or_default();
    if flags & 4 != 0 {
        let m = &MESSAGES[usize::from(byte(0)) % MESSAGES.len()];
        let nodes: Vec<Address> = Address::all().filter(|a| m.nodes.contains(*a)).collect();
        let node = nodes[usize::from(byte(1)) % nodes.len()];
        let mut payload = data.to_vec();
        payload.resize(usize::from(m.dlc), 0);
        if let Some(first) = payload.first_mut() {
            *first = m.number;
        }
        if let Some((at, value)) = m.selector
            && let Some(b) = payload.get_mut(usize::from(at))
        {
            *b = value;
        }
        return Some(Frame::new_data(m.app_id(node).emit(), &payload).expect("DLC <= 8"));
    }
    let extended = flags & 1 != 0;
    let id = if extended {
        let id = bus::ExtendedId::new(raw);
        assert_eq!(id.is_some(), raw <= 0x1FFF_FFFF);
        Id::Extended(id?)
    } else {
        let raw = raw as u16;
        let id = bus::StandardId::new(raw);
        assert_eq!(id.is_some(), raw <= 0x7FF);
        Id::Standard(id?)
    };
    if flags & 2 != 0 {
        let dlc = usize::from(byte(4));
        let frame = Frame::new_remote(id, dlc);
        assert_eq!(frame.is_ok(), dlc <= 8, "remote DLC {dlc}");
        let frame = frame.ok()?;
        assert!(frame.is_remote() && frame.data().is_empty() && usize::from(frame.dlc()) == dlc);
        Some(frame)
    } else {
        let frame = Frame::new_data(id, data);
        match &frame {
            Ok(f) => assert_eq!(f.data(), data),
            Err(e) => assert_eq!(*e, Error::TooMuchData(data.len())),
        }
        frame.ok()
    }
}

/// The `ID#DATA` text of a frame reads back as the same frame.
fn text_round_trip(frame: &Frame) {
    let text = bus::candump::format_frame(frame);
    let back = bus::candump::parse_frame(&text).expect("formatted frames parse");
    assert_eq!(back, *frame, "{text}");
}

/// The application identifier's fields are the identifier's bytes, and it emits the same id.
fn identifier(frame: &Frame) {
    let app = AppId::from_id(frame.id());
    let Id::Extended(id) = frame.id() else {
        assert!(app.is_err());
        return;
    };
    let app = app.expect("every extended identifier is an AppId");
    let raw = id.as_raw();
    assert_eq!(u32::from(app.priority.value()), raw >> 24);
    assert_eq!(u32::from(u8::from(app.frame_type)), (raw >> 16) & 0xFF);
    assert_eq!(u32::from(app.destination.0), (raw >> 8) & 0xFF);
    assert_eq!(u32::from(app.source.0), raw & 0xFF);
    assert_eq!(app.raw(), raw);
    assert_eq!(app.emit(), id);
    assert!(app.to_string().starts_with(&format!("{raw:08X} ")));
}

/// A decoded message holds its layout; one whose values are all valid encodes back to a frame
/// with the same identifier and the same bits wherever the layout has them (and zeros elsewhere).
fn decode(frame: &Frame) {
    let decoded = match catalogue::decode(frame) {
        Ok(Some(d)) => d,
        Ok(None) => return,
        Err(e) => {
            assert!(matches!(e, protocol::Error::Payload { .. }), "{e}");
            return;
        }
    };
    let m = decoded.message;
    assert_eq!(frame.data().first(), Some(&m.number));
    assert_eq!(frame.data().len(), usize::from(m.dlc));
    assert_eq!(decoded.values.len(), m.fields.len());
    for (v, f) in decoded.values.iter().zip(m.fields) {
        assert_eq!(v.field.name, f.name);
        let (lo, hi) = if f.signed {
            (-(1i64 << (f.bits - 1)), (1i64 << (f.bits - 1)) - 1)
        } else {
            (0, (1i64 << f.bits) - 1)
        };
        assert!((lo..=hi).contains(&v.raw), "{} = {}", f.name, v.raw);
    }
    if !decoded.values.iter().all(|v| v.in_range()) {
        return;
    }
    let encoded = m
        .encode(decoded.node, |name| decoded.get(name).map(|v| v.physical))
        .unwrap_or_else(|e| panic!("valid values of {} do not encode: {e}", m.name));
    assert_eq!(encoded.id(), frame.id());
    assert_eq!(encoded.dlc(), frame.dlc());
    let mask = covered_bits(m);
    assert_eq!(word(&encoded) & mask, word(frame) & mask, "{}", m.name);
    assert_eq!(word(&encoded) & !mask, 0, "{}", m.name);
}
