//! The socketcand line parser and session: the splitter gives the same messages however the
//! stream is cut, each one `<...>` and never longer than the limit; a session fed any bytes
//! answers only `< ok >` and `< echo >` (never `< error ... >`, which clients read as an error
//! frame), closes only before the bus is open, and a `send` it reads, written back as python-can
//! writes it, reads back to the same frame, whose `< frame >` messages are well formed.
#![no_main]

use bus::time::Stamp;
use bus::{Frame, Id};
use bus_runtime::gateway::protocol::{
    Action, Command, MAX_MESSAGE, Session, Splitter, bcm_frame_message, frame_message, parse,
};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    let Some((&cut, stream)) = input.split_first() else {
        return;
    };
    let whole = Splitter::default().push(stream);
    let mut parts = Splitter::default();
    let at = usize::from(cut).min(stream.len());
    let mut pieces = parts.push(&stream[..at]);
    pieces.extend(parts.push(&stream[at..]));
    assert_eq!(whole, pieces, "cut at {at}");

    for message in whole.iter().flatten() {
        assert!(message.len() <= MAX_MESSAGE);
        assert!(message.starts_with('<') && message.ends_with('>'));
        assert_eq!(message.matches('>').count(), 1);
    }
    let mut session = Session::default();
    for message in whole {
        let was_open = session.mode.is_some();
        match session.handle("harv0", message) {
            Action::Reply(text) => assert!(text == "< ok >" || text == "< echo >", "{text}"),
            Action::Close => assert!(!was_open),
            Action::Send(frame) | Action::Bcm(Command::Add { frame, .. } | Command::Update(frame)) => {
                round_trip(&frame)
            }
            Action::Switch(_) | Action::Bcm(_) | Action::Ignore(_) => {}
        }
    }
    // Commands also come one by one from other callers.
    if let Ok(Command::Send(frame)) = parse(&String::from_utf8_lossy(stream)) {
        round_trip(&frame);
    }
});

fn round_trip(frame: &Frame) {
    assert!(!frame.is_remote());
    let again = send_text(frame);
    assert_eq!(parse(&again), Ok(Command::Send(*frame)), "{again:?}");
    for m in [
        frame_message(Stamp(u64::MAX), frame),
        bcm_frame_message(Stamp(u64::MAX), frame),
    ] {
        assert!(frame_shape(&m, frame), "{m:?}");
        let out = Splitter::default().push(m.as_bytes());
        assert_eq!(out, [Ok(m.clone())]);
    }
}

/// A `< frame ID SECS.USECS DATA >` as python-can reads it: 3 hex digits for a base
/// identifier, 8 for an extended one; a number; the data in hex, spaces allowed.
fn frame_shape(m: &str, frame: &Frame) -> bool {
    let Some(body) = m.strip_prefix("< frame ").and_then(|b| b.strip_suffix(" >")) else {
        return false;
    };
    let mut parts = body.splitn(3, ' ');
    let (Some(id), Some(time), Some(data)) = (parts.next(), parts.next(), parts.next()) else {
        return false;
    };
    let id_ok = match frame.id() {
        Id::Standard(_) => id.len() == 3,
        Id::Extended(_) => id.len() == 8,
    };
    let hex: String = data.chars().filter(|c| *c != ' ').collect();
    id_ok
        && u32::from_str_radix(id, 16) == Ok(frame.raw_id())
        && time.parse::<f64>().is_ok()
        && hex.len() == 2 * frame.data().len()
        && hex.chars().all(|c| c.is_ascii_hexdigit())
}

/// `< send ... >` as python-can 4.2 and later writes it: padded identifier, LEN in hex, each
/// byte in as few lower-case hex digits as it needs.
fn send_text(frame: &Frame) -> String {
    let id = match frame.id() {
        Id::Standard(id) => format!("{:03X}", id.as_raw()),
        Id::Extended(id) => format!("{:08X}", id.as_raw()),
    };
    let bytes: Vec<String> = frame.data().iter().map(|b| format!("{b:x}")).collect();
    format!("< send {id} {:X} {} >", frame.dlc(), bytes.join(" "))
}
