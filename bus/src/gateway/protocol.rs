//! The socketcand protocol, sans IO: splitting a byte stream into `< ... >` messages, reading
//! commands, writing frames.
//!
//! Raw mode as socketcand speaks it: the server greets with `< hi >`; the client opens a bus
//! (`< open harv0 >`, answered `< ok >`) and switches to raw mode (`< rawmode >`, `< ok >`); from
//! then on every frame on the bus comes as `< frame ID SECS.USECS DATA >` (ID in hex, 3 digits
//! for a base and 8 for an extended identifier; DATA contiguous hex), and the client sends with
//! `< send ID LEN B0 B1 ... >`.

use crate::candump::{parse_hex_bytes, parse_id};
use crate::time::BusTime;
use crate::{Frame, Id};
use core::fmt::Write;

/// Longest message accepted, brackets included.
pub const MAX_MESSAGE: usize = 256;

/// A client's command.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    /// `< open BUS >`.
    Open(String),
    /// `< rawmode >`.
    RawMode,
    /// `< send ID LEN B0 ... >`.
    Send(Frame),
    /// `< echo >`: answered with `< echo >`.
    Echo,
}

/// Splits a byte stream into messages. Bytes outside `< >` and messages over [`MAX_MESSAGE`]
/// are errors; the stream goes on after them.
#[derive(Default, Debug)]
pub struct Splitter {
    buf: Vec<u8>,
    inside: bool,
    skipping: bool,
}

impl Splitter {
    /// Feeds bytes; returns complete messages (the text between the brackets, trimmed) and
    /// errors, in order.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Result<String, String>> {
        let mut out = Vec::new();
        for &b in bytes {
            match (self.inside, b) {
                (false, b'<') => {
                    self.inside = true;
                    self.skipping = false;
                    self.buf.clear();
                }
                (false, b) if b.is_ascii_whitespace() => {}
                (false, _) => {
                    // Garbage between messages: one error per run of it.
                    if !self.skipping {
                        out.push(Err("expected '<'".to_string()));
                        self.skipping = true;
                    }
                }
                (true, b'>') => {
                    self.inside = false;
                    if self.buf.len() + 2 > MAX_MESSAGE {
                        out.push(Err(format!("message longer than {MAX_MESSAGE} bytes")));
                    } else {
                        out.push(
                            String::from_utf8(std::mem::take(&mut self.buf))
                                .map(|s| s.trim().to_string())
                                .map_err(|_| "message is not UTF-8".to_string()),
                        );
                    }
                    self.buf.clear();
                }
                (true, b) => {
                    // Keep at most MAX_MESSAGE bytes: an endless message cannot grow memory.
                    if self.buf.len() < MAX_MESSAGE {
                        self.buf.push(b);
                    }
                }
            }
        }
        out
    }
}

/// Reads one message (the text between the brackets).
pub fn parse(message: &str) -> Result<Command, String> {
    let mut words = message.split_ascii_whitespace();
    match words.next() {
        Some("open") => match (words.next(), words.next()) {
            (Some(bus), None) => Ok(Command::Open(bus.to_string())),
            _ => Err("usage: open BUS".into()),
        },
        Some("rawmode") => Ok(Command::RawMode),
        Some("echo") => Ok(Command::Echo),
        Some("send") => {
            let id_text = words.next().ok_or("usage: send ID LEN DATA...")?;
            let id = parse_id(id_text).map_err(|e| e.to_string())?;
            let len: usize = words
                .next()
                .and_then(|l| l.parse().ok())
                .ok_or("send: LEN is not a number")?;
            let bytes: Vec<&str> = words.collect();
            if bytes.len() != len {
                return Err(format!(
                    "send: LEN is {len} but {} data bytes follow",
                    bytes.len()
                ));
            }
            let mut data = Vec::with_capacity(len);
            for b in bytes {
                let v = parse_hex_bytes(b).map_err(|e| e.to_string())?;
                if v.len() != 1 {
                    return Err(format!("send: '{b}' is not one hex byte"));
                }
                data.push(v[0]);
            }
            Frame::new_data(id, &data)
                .map_err(|e| e.to_string())
                .map(Command::Send)
        }
        Some(other) => Err(format!("unknown command '{other}' (this server speaks raw mode)")),
        None => Err("empty message".into()),
    }
}

/// `< frame ID SECS.USECS DATA >` for a frame that ended at `at`.
pub fn frame_message(at: BusTime, frame: &Frame) -> String {
    let mut s = String::with_capacity(48);
    let _ = match frame.id() {
        Id::Standard(id) => write!(s, "< frame {:03X} {at} ", id.as_raw()),
        Id::Extended(id) => write!(s, "< frame {:08X} {at} ", id.as_raw()),
    };
    for b in frame.data() {
        let _ = write!(s, "{b:02X}");
    }
    s.push_str(" >");
    s
}

/// `< error TEXT >`.
pub fn error_message(text: &str) -> String {
    // Brackets in the text would end the message early on the client's side.
    format!("< error {} >", text.replace(['<', '>'], "'"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::candump::parse_frame;

    #[test]
    fn splits_messages_across_reads() {
        let mut s = Splitter::default();
        assert_eq!(s.push(b"< open har"), vec![]);
        assert_eq!(
            s.push(b"v0 >< rawmode >\n< send 123 1 AB >"),
            vec![
                Ok("open harv0".to_string()),
                Ok("rawmode".to_string()),
                Ok("send 123 1 AB".to_string()),
            ]
        );
    }

    #[test]
    fn garbage_and_oversized_messages_are_errors_and_the_stream_goes_on() {
        let mut s = Splitter::default();
        let out = s.push(b"hello world < echo >");
        assert_eq!(out.len(), 2);
        assert!(out[0].is_err());
        assert_eq!(out[1], Ok("echo".to_string()));
        let long = [b"<".as_slice(), &[b'a'; 10_000], b">< echo >"].concat();
        let out = s.push(&long);
        assert!(out[0].as_ref().unwrap_err().contains("longer than"));
        assert_eq!(out[1], Ok("echo".to_string()));
        assert!(s.buf.capacity() <= 2 * MAX_MESSAGE);
    }

    #[test]
    fn commands() {
        assert_eq!(parse("open harv0"), Ok(Command::Open("harv0".into())));
        assert_eq!(parse("rawmode"), Ok(Command::RawMode));
        assert_eq!(
            parse("send 0601F5D0 3 20 0D 00"),
            Ok(Command::Send(parse_frame("0601F5D0#200D00").unwrap()))
        );
        assert_eq!(
            parse("send 123 0"),
            Ok(Command::Send(parse_frame("123#").unwrap()))
        );
        for bad in [
            "send",
            "send 123",
            "send 123 2 AB",
            "send 123 1 ABC",
            "send 1234 0",
            "send 123 9 0 0 0 0 0 0 0 0 0",
            "bcmmode",
            "",
            "open",
        ] {
            assert!(parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn frames_are_written_as_socketcand_does() {
        let f = parse_frame("0601F5D0#200D0002FFBFFF00").unwrap();
        assert_eq!(
            frame_message(BusTime(1_500_000_000), &f),
            "< frame 0601F5D0 1.500000 200D0002FFBFFF00 >"
        );
        assert_eq!(
            frame_message(BusTime(0), &parse_frame("123#").unwrap()),
            "< frame 123 0.000000  >"
        );
        assert_eq!(error_message("bad <x>"), "< error bad 'x' >");
    }
}
