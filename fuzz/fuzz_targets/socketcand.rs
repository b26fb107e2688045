//! The socketcand line parser: the splitter gives the same messages however the stream is cut,
//! never a message longer than the limit, and a `send` it reads writes back to the same frame.
#![no_main]

use bus::gateway::protocol::{Command, MAX_MESSAGE, Splitter, frame_message, parse};
use bus::time::BusTime;
use bus::{Frame, Id};
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
        assert!(message.len() + 2 <= MAX_MESSAGE);
        assert!(!message.contains('>'));
        assert_eq!(message.trim(), message);
        command(message);
    }
    // Commands also come one by one from other callers.
    command(&String::from_utf8_lossy(stream));
});

fn command(message: &str) {
    match parse(message) {
        Ok(Command::Send(frame)) => {
            assert!(!frame.is_remote());
            let again = send_text(&frame);
            assert_eq!(
                parse(&again),
                Ok(Command::Send(frame)),
                "{message:?} -> {again:?}"
            );
            // The frame as the server would write it is one message.
            let out = Splitter::default().push(frame_message(BusTime(u64::MAX), &frame).as_bytes());
            assert_eq!(out.len(), 1);
            assert!(out[0].as_ref().is_ok_and(|m| m.starts_with("frame ")));
        }
        Ok(Command::Open(bus)) => {
            assert!(!bus.is_empty() && !bus.contains(|c: char| c.is_ascii_whitespace()));
        }
        Ok(Command::RawMode | Command::Echo) | Err(_) => {}
    }
}

fn send_text(frame: &Frame) -> String {
    let id = match frame.id() {
        Id::Standard(id) => format!("{:03X}", id.as_raw()),
        Id::Extended(id) => format!("{:08X}", id.as_raw()),
    };
    let bytes: Vec<String> = frame.data().iter().map(|b| format!("{b:02x}")).collect();
    format!("send {id} {} {}", frame.dlc(), bytes.join(" "))
}
