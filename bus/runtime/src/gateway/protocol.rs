//! The socketcand protocol, sans IO: splitting a byte stream into `< ... >` messages, reading
//! commands as socketcand reads them, writing frames as socketcand writes them.
//!
//! The server greets with `< hi >`; the client opens the bus (`< open harv0 >`, answered
//! `< ok >`) and is then in BCM mode, where it sends frames (`< send ID LEN B0 ... >`), runs
//! cyclic sends (`add`, `update`, `delete`) and receives the identifiers it subscribes to
//! (`subscribe`, `filter`, `unsubscribe`) as `< frame ID SECS.USECS B0 B1 ... >`. `< rawmode >`
//! switches to raw mode, where every frame on the bus comes as `< frame ID SECS.USECS DATA >`
//! (DATA contiguous hex) and `send` works as in BCM mode; `< bcmmode >` switches back.
//!
//! Commands are recognised and read exactly as socketcand's `state_*.c` do: by the message's
//! first characters (`"< send "`, so one space on each side of the word) or, for `< echo >` and
//! the mode switches, the whole message; numbers as its `sscanf` formats read them
//! ([`super::scan`]). An identifier is extended when written with 8 characters (socketcand's
//! rule) and, unlike socketcand, also when its value does not fit 11 bits (python-can before 4.2
//! wrote `0300A0F5` as `300A0F5`; socketcand would send a base frame with the high bits
//! cut off). What socketcand would reject or the kernel would refuse is [`Malformed`]: the server
//! answers nothing to it, as socketcand answers nothing to a bad `send`.

use super::scan::{Conv, element_length, scan};
use bus::time::{BusDuration, Stamp};
use bus::{ExtendedId, Frame, Id, StandardId};
use core::fmt::Write;

/// Longest message accepted, brackets included.
pub const MAX_MESSAGE: usize = 256;

/// The longest cyclic or throttle interval the kernel's broadcast manager accepts (400 days,
/// `BCM_TIMER_SEC_MAX`), seconds.
pub const MAX_INTERVAL_SECS: u64 = 400 * 24 * 60 * 60;

/// Which frames a client receives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Those it subscribed to, BCM style.
    Bcm,
    /// Every frame on the bus.
    Raw,
}

/// A client's command.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    /// `< open BUS >`.
    Open(String),
    /// `< rawmode >` or `< bcmmode >`.
    Mode(Mode),
    /// `< echo >`: answered with `< echo >`.
    Echo,
    /// `< send ID LEN B0 ... >`.
    Send(Frame),
    /// `< add SECS USECS ID LEN B0 ... >`: send now and every interval (0 sends once).
    Add {
        /// The interval.
        interval: BusDuration,
        /// The frame.
        frame: Frame,
    },
    /// `< update ID LEN B0 ... >`: new content for a cyclic send, its timing untouched.
    Update(Frame),
    /// `< delete ID >`.
    Delete(Id),
    /// `< subscribe SECS USECS ID >`: every frame of `id`, at most one per `throttle` (0: all).
    Subscribe {
        /// The throttle interval.
        throttle: BusDuration,
        /// The identifier.
        id: Id,
    },
    /// `< filter SECS USECS ID LEN M0 ... >`: frames of `id` whose bits under the mask changed.
    Filter {
        /// The throttle interval.
        throttle: BusDuration,
        /// The identifier.
        id: Id,
        /// The mask, zeros past LEN.
        mask: [u8; 8],
    },
    /// `< unsubscribe ID >`.
    Unsubscribe(Id),
}

/// Why a message was ignored, for the log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Malformed(pub String);

impl core::fmt::Display for Malformed {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(&self.0)
    }
}

fn bad(text: impl Into<String>) -> Malformed {
    Malformed(text.into())
}

/// Splits a byte stream into messages as socketcand's `receive_command` does: a message runs from
/// a `<` to the next `>`, both included; what lies outside is dropped. Garbage outside messages
/// (one error per run of it), messages over [`MAX_MESSAGE`] and messages that are not UTF-8 are
/// errors; the stream goes on after them.
#[derive(Default, Debug)]
pub struct Splitter {
    buf: Vec<u8>,
    inside: bool,
    skipping: bool,
}

impl Splitter {
    /// Feeds bytes; returns complete messages (brackets included, nothing trimmed) and errors,
    /// in order.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Result<String, Malformed>> {
        let mut out = Vec::new();
        for &b in bytes {
            match (self.inside, b) {
                (false, b'<') => {
                    self.inside = true;
                    self.skipping = false;
                    self.buf.clear();
                    self.buf.push(b);
                }
                (false, b) if b.is_ascii_whitespace() => {}
                (false, _) => {
                    if !self.skipping {
                        out.push(Err(bad("bytes outside '< >'")));
                        self.skipping = true;
                    }
                }
                (true, b'>') => {
                    self.inside = false;
                    if self.buf.len() + 1 > MAX_MESSAGE {
                        out.push(Err(bad(format!("message longer than {MAX_MESSAGE} bytes"))));
                    } else {
                        self.buf.push(b);
                        out.push(
                            String::from_utf8(std::mem::take(&mut self.buf))
                                .map_err(|_| bad("message is not UTF-8")),
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

/// Reads one message, brackets included.
pub fn parse(message: &str) -> Result<Command, Malformed> {
    match message {
        "< rawmode >" => return Ok(Command::Mode(Mode::Raw)),
        "< bcmmode >" => return Ok(Command::Mode(Mode::Bcm)),
        "< echo >" => return Ok(Command::Echo),
        _ => {}
    }
    let Some(word) = message
        .strip_prefix("< ")
        .and_then(|rest| rest.split_once(' '))
        .map(|(w, _)| w)
    else {
        return Err(bad("unknown command"));
    };
    use Conv::{Dec, Hex};
    // The conversions of socketcand's formats: "%x %hhu %hhx x8" for a frame, with "%llu %llu"
    // before it for a timed one.
    const FRAME: [Conv; 10] = [Hex, Dec, Hex, Hex, Hex, Hex, Hex, Hex, Hex, Hex];
    const TIMED: [Conv; 12] = [Dec, Dec, Hex, Dec, Hex, Hex, Hex, Hex, Hex, Hex, Hex, Hex];
    match word {
        "open" => match message["< open ".len()..]
            .split(|c: char| c.is_ascii() && super::scan::is_space(c as u8))
            .find(|w| !w.is_empty())
        {
            // sscanf "< open %s>": the first word, whatever it holds.
            Some(bus) => Ok(Command::Open(bus.to_string())),
            None => Err(bad("open: no bus name")),
        },
        "send" | "update" => {
            let v = scan(message, &FRAME);
            let (id, data) = frame_fields(message, &v, 2)?;
            let frame = Frame::new_data(id, &data).map_err(|e| bad(e.to_string()))?;
            Ok(if word == "send" {
                Command::Send(frame)
            } else {
                Command::Update(frame)
            })
        }
        "add" => {
            let v = scan(message, &TIMED);
            let interval = interval(&v)?;
            let (id, data) = frame_fields(message, &v[2.min(v.len())..], 4)?;
            let frame = Frame::new_data(id, &data).map_err(|e| bad(e.to_string()))?;
            Ok(Command::Add { interval, frame })
        }
        "filter" => {
            let v = scan(message, &TIMED);
            let throttle = interval(&v)?;
            let (id, data) = frame_fields(message, &v[2.min(v.len())..], 4)?;
            let mut mask = [0u8; 8];
            mask[..data.len()].copy_from_slice(&data);
            Ok(Command::Filter { throttle, id, mask })
        }
        "subscribe" => {
            let v = scan(message, &[Dec, Dec, Hex]);
            if v.len() != 3 {
                return Err(bad("subscribe: usage SECS USECS ID"));
            }
            let throttle = interval(&v)?;
            let id = ident(v[2], element_length(message, 4))?;
            Ok(Command::Subscribe { throttle, id })
        }
        "delete" | "unsubscribe" => {
            let v = scan(message, &[Hex]);
            if v.len() != 1 {
                return Err(bad(format!("{word}: usage ID")));
            }
            let id = ident(v[0], element_length(message, 2))?;
            Ok(if word == "delete" {
                Command::Delete(id)
            } else {
                Command::Unsubscribe(id)
            })
        }
        other => Err(bad(format!("unknown command '{other}'"))),
    }
}

/// `ID LEN B0 ...` from the values `v` scanned from them, the identifier being word `id_word` of
/// the message: socketcand's checks (at least ID and LEN, LEN at most 8, exactly LEN bytes read).
fn frame_fields(message: &str, v: &[u64], id_word: usize) -> Result<(Id, Vec<u8>), Malformed> {
    if v.len() < 2 {
        return Err(bad("usage ID LEN B0 ..."));
    }
    // %hhu and %hhx: the low byte of what was read.
    let len = usize::from(v[1] as u8);
    if len > 8 || v.len() != 2 + len {
        return Err(bad(format!(
            "LEN is {len} but {} data bytes were read",
            v.len() - 2
        )));
    }
    let id = ident(v[0], element_length(message, id_word))?;
    Ok((id, v[2..].iter().map(|&b| b as u8).collect()))
}

/// An identifier read by `%x` (so the low 32 bits) and written with `chars` characters.
fn ident(raw: u64, chars: usize) -> Result<Id, Malformed> {
    let raw = raw as u32;
    if chars != 8 && raw <= 0x7FF {
        return StandardId::new(raw as u16)
            .map(Id::Standard)
            .ok_or_else(|| bad("identifier out of range"));
    }
    ExtendedId::new(raw)
        .map(Id::Extended)
        .ok_or_else(|| bad(format!("identifier {raw:X} does not fit 29 bits")))
}

/// `SECS USECS` as the kernel's broadcast manager takes them: microseconds below a second,
/// seconds up to [`MAX_INTERVAL_SECS`]. One longer than the bus clock spans (about 61 days)
/// saturates at [`BusDuration::MAX`]: it never comes round in a run.
fn interval(v: &[u64]) -> Result<BusDuration, Malformed> {
    match v {
        [secs, usecs, ..] if *secs <= MAX_INTERVAL_SECS && *usecs < 1_000_000 => {
            Ok(BusDuration::from_secs(*secs) + BusDuration::from_micros(*usecs))
        }
        [_, _, ..] => Err(bad("interval out of range")),
        _ => Err(bad("usage SECS USECS ...")),
    }
}

/// What the server does about one message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Action {
    /// Answers this.
    Reply(&'static str),
    /// Switched to this mode: the client's BCM jobs end (socketcand closes its BCM socket);
    /// answered `< ok >`.
    Switch(Mode),
    /// Puts the frame on the bus.
    Send(Frame),
    /// A BCM command for the client's jobs and subscriptions.
    Bcm(Command),
    /// Closes the connection (the client asked for a bus this server does not have).
    Close,
    /// Nothing: the message is malformed, unknown, or not valid in this mode.
    Ignore(Malformed),
}

/// A client's place in the protocol: before `open` (`mode` is `None`), then in BCM or raw mode.
#[derive(Clone, Debug, Default)]
pub struct Session {
    /// The mode, once the bus is open.
    pub mode: Option<Mode>,
}

impl Session {
    /// Handles one message from the [`Splitter`] for a server of bus `bus`.
    pub fn handle(&mut self, bus: &str, message: Result<String, Malformed>) -> Action {
        let command = match message.and_then(|m| parse(&m)) {
            Ok(command) => command,
            Err(e) => return Action::Ignore(e),
        };
        let ignore = |why: &str| Action::Ignore(bad(why));
        match (self.mode, command) {
            (None, Command::Open(name)) if name == bus => {
                self.mode = Some(Mode::Bcm);
                Action::Reply("< ok >")
            }
            // socketcand answers `< error could not open bus >` and closes; that message would
            // read as an error frame, so the connection is only closed.
            (None, Command::Open(_)) => Action::Close,
            (None, _) => ignore("open the bus first"),
            (Some(_), Command::Open(_)) => ignore("the bus is open already"),
            (Some(_), Command::Echo) => Action::Reply("< echo >"),
            (Some(_), Command::Send(frame)) => Action::Send(frame),
            (Some(old), Command::Mode(new)) if old != new => {
                self.mode = Some(new);
                Action::Switch(new)
            }
            // socketcand treats these as unknown commands.
            (Some(_), Command::Mode(_)) => ignore("in that mode already"),
            (Some(Mode::Raw), _) => ignore("a BCM command in raw mode"),
            (Some(Mode::Bcm), command) => Action::Bcm(command),
        }
    }
}

fn id_text(s: &mut String, id: Id) {
    let _ = match id {
        Id::Standard(id) => write!(s, "{:03X}", id.as_raw()),
        Id::Extended(id) => write!(s, "{:08X}", id.as_raw()),
    };
}

/// `< frame ID SECS.USECS DATA >` for a frame that ended at `at` (bus time already stamped with
/// the hub's [`bus::time::Epoch`], as socketcand gives the kernel's wall-clock time), as
/// socketcand writes it in raw mode: DATA contiguous upper-case hex.
pub fn frame_message(at: Stamp, frame: &Frame) -> String {
    let mut s = String::with_capacity(48);
    s.push_str("< frame ");
    id_text(&mut s, frame.id());
    let _ = write!(s, " {at} ");
    for b in frame.data() {
        let _ = write!(s, "{b:02X}");
    }
    s.push_str(" >");
    s
}

/// `< frame ID SECS.USECS B0 B1 ...  >` as socketcand writes it in BCM mode: each byte followed
/// by a space, then ` >`.
pub fn bcm_frame_message(at: Stamp, frame: &Frame) -> String {
    let mut s = String::with_capacity(56);
    s.push_str("< frame ");
    id_text(&mut s, frame.id());
    let _ = write!(s, " {at} ");
    for b in frame.data() {
        let _ = write!(s, "{b:02X} ");
    }
    s.push_str(" >");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use bus::candump::parse_frame;

    fn frame(text: &str) -> Frame {
        parse_frame(text).unwrap()
    }

    #[test]
    fn splits_messages_across_reads_as_they_came() {
        let mut s = Splitter::default();
        assert_eq!(s.push(b"< open har"), vec![]);
        assert_eq!(
            s.push(b"v0 >< rawmode >\n<send 123 1 AB>"),
            vec![
                Ok("< open harv0 >".to_string()),
                Ok("< rawmode >".to_string()),
                Ok("<send 123 1 AB>".to_string()),
            ]
        );
    }

    #[test]
    fn garbage_and_oversized_messages_are_errors_and_the_stream_goes_on() {
        let mut s = Splitter::default();
        let out = s.push(b"hello world < echo >");
        assert_eq!(out.len(), 2);
        assert!(out[0].is_err());
        assert_eq!(out[1], Ok("< echo >".to_string()));
        let long = [b"<".as_slice(), &[b'a'; 10_000], b">< echo >"].concat();
        let out = s.push(&long);
        assert!(out[0].as_ref().unwrap_err().0.contains("longer than"));
        assert_eq!(out[1], Ok("< echo >".to_string()));
        assert!(s.buf.capacity() <= 2 * MAX_MESSAGE);
        // The longest message accepted is MAX_MESSAGE bytes, brackets included.
        let most = format!("<{}>", "a".repeat(MAX_MESSAGE - 2));
        assert_eq!(s.push(most.as_bytes()), vec![Ok(most.clone())]);
        let over = format!("<{}>", "a".repeat(MAX_MESSAGE - 1));
        assert!(s.push(over.as_bytes())[0].is_err());
    }

    /// What socketcand does with each `send`: the frame it would put on the bus (its sscanf
    /// count check, `%hhx` keeping the low byte, 8 characters making an identifier extended),
    /// or `None` where it prints "Syntax error" and sends nothing. Worked out by hand from the
    /// C rules, not from this parser.
    #[test]
    fn send_is_read_as_socketcand_reads_it() {
        let table: &[(&str, Option<&str>)] = &[
            // python-can 4.2 and later: padded identifiers, bytes in as few digits as needed.
            ("< send 0300A0F5 2 1 1 >", Some("0300A0F5#0101")),
            ("< send 123 0  >", Some("123#")),
            (
                "< send 7FF 8 0 1 a ff 10 7f 80 fe >",
                Some("7FF#00010AFF107F80FE"),
            ),
            ("< send 1FFFFFFF 3 f8 f9 fa >", Some("1FFFFFFF#F8F9FA")),
            // socketcand's own examples.
            ("< send 123 0 >", Some("123#")),
            ("< send 1AAAAAAA 2 1 f1 >", Some("1AAAAAAA#01F1")),
            // 8 characters: extended, whatever the value.
            ("< send 00000123 1 AB >", Some("00000123#AB")),
            // Over 0x7FF in fewer characters (python-can before 4.2): extended too.
            ("< send 300A0F5 2 1 1 >", Some("0300A0F5#0101")),
            ("< send 800 0 >", Some("00000800#")),
            // %hhx: any number of digits, the low byte kept; sign and 0x prefix allowed.
            ("< send 123 2 1FF 100 >", Some("123#FF00")),
            ("< send 123 2 -1 0x0a >", Some("123#FF0A")),
            ("< send 123 1 0000000000000000000042 >", Some("123#42")),
            // %hhu truncates LEN too: 264 is 8.
            ("< send 123 264 1 2 3 4 5 6 7 8 >", Some("123#0102030405060708")),
            // The count is all socketcand checks: a 9th byte or trailing words go unread.
            ("< send 123 8 1 2 3 4 5 6 7 8 9 >", Some("123#0102030405060708")),
            ("< send 123 1 AB zz >", Some("123#AB")),
            // Numbers need no space between them.
            ("< send 123 2 1-2 >", Some("123#01FE")),
            // Rejected: too few or too many bytes, LEN over 8, no LEN, no identifier.
            ("< send 123 2 AB >", None),
            ("< send 123 1 AB CD >", None),
            ("< send 123 9 0 0 0 0 0 0 0 0 0 >", None),
            ("< send 123 >", None),
            ("< send >", None),
            ("< send XYZ 0 >", None),
            ("< send 123 1 zz >", None),
            // An identifier over 29 bits (socketcand would hand the kernel flag bits).
            ("< send FFFFFFFF 0 >", None),
            // %x keeps 32 bits: 0x100000000 is 0, written in 9 characters, so a base frame.
            ("< send 100000000 0 >", Some("000#")),
            // Not a send as socketcand matches it: "< send " exactly.
            ("<send 123 0>", None),
            ("<  send 123 0 >", None),
            ("< send\t123 0 >", None),
            ("< SEND 123 0 >", None),
        ];
        for (text, want) in table {
            let got = match parse(text) {
                Ok(Command::Send(f)) => Some(f),
                Ok(other) => panic!("{text}: {other:?}"),
                Err(_) => None,
            };
            assert_eq!(got, want.map(frame), "{text}");
        }
    }

    #[test]
    fn bcm_commands() {
        let id = |t: &str| frame(&format!("{t}#")).id();
        let table: &[(&str, Option<Command>)] = &[
            (
                "< add 1 0 123 8 11 22 33 44 55 66 77 88 >",
                Some(Command::Add {
                    interval: BusDuration::from_secs(1),
                    frame: frame("123#1122334455667788"),
                }),
            ),
            (
                "< add 0 20000 123 4 42 42 42 42 >",
                Some(Command::Add {
                    interval: BusDuration::from_millis(20),
                    frame: frame("123#42424242"),
                }),
            ),
            ("< add 0 1000000 123 0 >", None),
            ("< add 34560001 0 123 0 >", None),
            (
                "< add 34560000 999999 12345678 0 >",
                Some(Command::Add {
                    interval: BusDuration::MAX, // 400 days: beyond the bus clock
                    frame: frame("12345678#"),
                }),
            ),
            ("< add 0 0 123 2 1 >", None),
            (
                "< update 123 3 11 22 33 >",
                Some(Command::Update(frame("123#112233"))),
            ),
            ("< delete 123 >", Some(Command::Delete(id("123")))),
            ("< delete 00000123 >", Some(Command::Delete(id("00000123")))),
            ("< delete >", None),
            (
                "< subscribe 0 0 123 >",
                Some(Command::Subscribe {
                    throttle: BusDuration::ZERO,
                    id: id("123"),
                }),
            ),
            (
                "< subscribe 1 500000 1ABCDEF0 >",
                Some(Command::Subscribe {
                    throttle: BusDuration::from_millis(1500),
                    id: id("1ABCDEF0"),
                }),
            ),
            ("< subscribe 0 123 >", None),
            (
                "< filter 1 500000 123 8 FF 00 F8 00 00 00 00 00 >",
                Some(Command::Filter {
                    throttle: BusDuration::from_millis(1500),
                    id: id("123"),
                    mask: [0xFF, 0, 0xF8, 0, 0, 0, 0, 0],
                }),
            ),
            (
                "< filter 0 0 123 1 FF >",
                Some(Command::Filter {
                    throttle: BusDuration::ZERO,
                    id: id("123"),
                    mask: [0xFF, 0, 0, 0, 0, 0, 0, 0],
                }),
            ),
            ("< unsubscribe 123 >", Some(Command::Unsubscribe(id("123")))),
            ("< open harv0 >", Some(Command::Open("harv0".into()))),
            ("< open harv0>", Some(Command::Open("harv0>".into()))),
            ("< rawmode >", Some(Command::Mode(Mode::Raw))),
            ("< bcmmode >", Some(Command::Mode(Mode::Bcm))),
            ("< echo >", Some(Command::Echo)),
            ("<echo>", None),
            ("< echo  >", None),
            (
                "< muxfilter 0 0 123 2 FF 00 00 00 00 00 00 00 33 FF FF FF FF FF FF FF >",
                None,
            ),
            ("< isotpmode >", None),
            ("< controlmode >", None),
            ("< >", None),
            ("<>", None),
        ];
        for (text, want) in table {
            assert_eq!(parse(text).ok(), *want, "{text}");
        }
    }

    #[test]
    fn a_session_opens_switches_and_ignores_what_its_mode_does_not_take() {
        let mut s = Session::default();
        let mut say = |m: &str| s.handle("harv0", Ok(m.to_string()));
        assert!(matches!(say("< rawmode >"), Action::Ignore(_)), "not open yet");
        assert!(matches!(say("< send 123 0 >"), Action::Ignore(_)));
        assert_eq!(say("< open harv0 >"), Action::Reply("< ok >"));
        assert!(matches!(say("< open harv0 >"), Action::Ignore(_)));
        assert!(matches!(say("< bcmmode >"), Action::Ignore(_)), "BCM already");
        assert_eq!(
            say("< subscribe 0 0 123 >"),
            Action::Bcm(parse("< subscribe 0 0 123 >").unwrap())
        );
        assert_eq!(say("< rawmode >"), Action::Switch(Mode::Raw));
        assert!(
            matches!(say("< subscribe 0 0 123 >"), Action::Ignore(_)),
            "raw mode"
        );
        assert_eq!(say("< send 123 0 >"), Action::Send(frame("123#")));
        assert_eq!(say("< echo >"), Action::Reply("< echo >"));
        assert_eq!(say("< bcmmode >"), Action::Switch(Mode::Bcm));
        assert_eq!(
            Session::default().handle("harv0", Ok("< open can0 >".into())),
            Action::Close
        );
    }

    proptest::proptest! {
        /// Whatever comes in, the only answers are `< ok >` and `< echo >`.
        #[test]
        fn any_bytes_get_only_socketcand_answers(
            bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..400),
            prefix in proptest::sample::select(vec!["", "< open harv0 >", "< open harv0 >< rawmode >"]),
        ) {
            let mut s = Session::default();
            let stream = [prefix.as_bytes(), &bytes].concat();
            for message in Splitter::default().push(&stream) {
                match s.handle("harv0", message) {
                    Action::Reply(text) => proptest::prop_assert!(text == "< ok >" || text == "< echo >"),
                    Action::Send(f) => proptest::prop_assert!(f.dlc() <= 8 && !f.is_remote()),
                    _ => {}
                }
            }
        }
    }

    #[test]
    fn frames_are_written_as_socketcand_does() {
        let f = frame("0601F5D0#200D0002FFBFFF00");
        assert_eq!(
            frame_message(Stamp(1_500_000_000), &f),
            "< frame 0601F5D0 1.500000 200D0002FFBFFF00 >"
        );
        assert_eq!(frame_message(Stamp(0), &frame("123#")), "< frame 123 0.000000  >");
        assert_eq!(
            bcm_frame_message(Stamp(23_424_242_000), &frame("123#1A220344")),
            "< frame 123 23.424242 1A 22 03 44  >"
        );
        assert_eq!(
            bcm_frame_message(Stamp(0), &frame("00000005#")),
            "< frame 00000005 0.000000  >"
        );
    }
}
