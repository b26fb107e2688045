//! `harvemu-vmcheck`: checks, inside a Linux VM with the `can`, `can-raw`, `can-dev` and `vcan`
//! modules loaded, the SocketCAN plumbing that harvemu's real-interface backend relies on.
//!
//! It creates a vcan interface through netlink and brings it up, opens two raw CAN sockets on it,
//! sends extended, base and remote frames from one and reads them on the other, checks
//! `CAN_RAW_RECV_OWN_MSGS`, the socket-layer receive timestamp (`SO_TIMESTAMPNS`) and a kernel
//! id/mask filter, and deletes the interface again. Every check prints one `PASS <check>` or
//! `FAIL <check>: <why>` line; a closing `vmcheck: N passed, N failed` line sums them up.
//!
//! Usage: `harvemu-vmcheck [INTERFACE]` (default `vcan0`; it must not exist yet). Needs root
//! (`CAP_NET_ADMIN`). Exit code 0 only if every check passed, 1 otherwise, 2 on bad arguments.
//! `scripts/vm/run` boots a VM that runs it; see `scripts/vm/README.md`.
//!
//! `harvemu-vmcheck harvester HARVEMU CONFIG` is the end-to-end check of `harvemu run --iface
//! vcan0 --without F5` with an outside monitor ([`monitor`]), freezes of harvemu ([`outside`]) and
//! `harvemu replay --iface` ([`replay`]) instead (see [`harvester`]), reads captures of the
//! interface by tcpdump and dumpcap back with harvemu ([`captures`]), and runs a network imported
//! from a DBC file on the interface ([`imported`]).
#![warn(missing_docs)]

mod captures;
mod harvester;
mod imported;
mod monitor;
mod outside;
mod replay;

use socketcan::{
    CanFilter, CanFrame, CanInterface, CanSocket, EmbeddedFrame, ExtendedId, Id, Socket, SocketOptions,
    StandardId,
};
use std::io;
use std::path::Path;
use std::process::ExitCode;
use std::time::{Duration, SystemTime};

/// `CAN_EFF_FLAG` of `struct can_frame`: the identifier is a 29-bit one.
const CAN_EFF_FLAG: u32 = 0x8000_0000;

/// How long a read waits for a frame that should arrive.
const READ_TIMEOUT: Duration = Duration::from_secs(1);

/// How long a read waits to show that a frame does not arrive.
const SILENCE: Duration = Duration::from_millis(200);

/// Largest accepted age of a receive timestamp when the read returns.
const TIMESTAMP_SLACK: Duration = Duration::from_secs(5);

/// The frames sent from one socket and read back on the other, each with its check's name.
const ROUND_TRIPS: [(&str, &str); 5] = [
    ("extended data frame", "0601F5D0#200D0002FFBFFF00"),
    ("base data frame", "123#DEADBEEF"),
    ("empty data frame", "7FF#"),
    ("remote frame", "123#R"),
    ("extended remote frame", "0300A0F5#R"),
];

/// The outcome of one check: a detail to print after PASS, or why it failed.
type Outcome = Result<String, String>;

/// Counts the outcomes of the checks and prints one line for each.
#[derive(Default)]
struct Report {
    /// Checks that passed.
    passed: usize,
    /// Checks that failed.
    failed: usize,
}

impl Report {
    /// Prints `PASS name (detail)` or `FAIL name: why`, counts it, and says whether it passed.
    fn check(&mut self, name: &str, outcome: Outcome) -> bool {
        match outcome {
            Ok(detail) => {
                if detail.is_empty() {
                    println!("PASS {name}");
                } else {
                    println!("PASS {name} ({detail})");
                }
                self.passed += 1;
                true
            }
            Err(why) => {
                println!("FAIL {name}: {why}");
                self.failed += 1;
                false
            }
        }
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut report = Report::default();
    match args.as_slice() {
        [] => run("vcan0", &mut report),
        [mode, harvemu, config] if mode == "harvester" => {
            harvester::run(Path::new(harvemu), Path::new(config), &mut report)
        }
        [name] if !name.starts_with('-') && name != "harvester" => run(name, &mut report),
        _ => {
            eprintln!(
                "usage: harvemu-vmcheck [INTERFACE]                   plumbing checks (default vcan0)\n       \
                 harvemu-vmcheck harvester HARVEMU CONFIG   harvemu run on vcan0, end to end\n\
                 (needs root)"
            );
            return ExitCode::from(2);
        }
    }
    println!("vmcheck: {} passed, {} failed", report.passed, report.failed);
    if report.failed == 0 && report.passed > 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// Runs every check on the vcan interface `name`, stopping early when one leaves nothing to test.
fn run(name: &str, report: &mut Report) {
    let iface = match create_vcan(name) {
        Ok(iface) => iface,
        Err(why) => {
            report.check(&format!("create and bring up {name}"), Err(why));
            return;
        }
    };
    report.check(&format!("create and bring up {name}"), Ok("netlink".to_owned()));

    match open_pair(name) {
        Ok((tx, rx)) => {
            report.check("open two raw CAN sockets", Ok(String::new()));
            for (check, text) in ROUND_TRIPS {
                report.check(check, round_trip(&tx, &rx, text));
            }
            report.check("own messages", own_messages(&tx, &rx));
            report.check("receive timestamp", receive_timestamp(&tx, &rx));
            report.check("kernel id/mask filter", kernel_filter(&tx, &rx));
        }
        Err(why) => {
            report.check("open two raw CAN sockets", Err(why));
        }
    }

    report.check(&format!("delete {name}"), delete_vcan(iface, name));
}

/// Creates the vcan interface `name` through netlink and brings it up.
fn create_vcan(name: &str) -> Result<CanInterface, String> {
    let iface =
        CanInterface::create_vcan(name, None).map_err(|e| format!("netlink create of vcan {name}: {e}"))?;
    iface
        .bring_up()
        .map_err(|e| format!("netlink bring-up of {name}: {e}"))?;
    let details = iface
        .details()
        .map_err(|e| format!("netlink query of {name}: {e}"))?;
    if !details.is_up {
        return Err(format!("{name} is not up after bring_up"));
    }
    Ok(iface)
}

/// Deletes the interface and checks that its name is gone.
fn delete_vcan(iface: CanInterface, name: &str) -> Outcome {
    iface.delete().map_err(|(_, e)| format!("netlink delete: {e}"))?;
    match CanInterface::open(name) {
        Ok(_) => Err(format!("{name} still resolves after delete")),
        Err(_) => Ok(String::new()),
    }
}

/// Opens a raw CAN socket on `name` with the read timeout set.
fn open_socket(name: &str) -> Result<CanSocket, String> {
    let socket = CanSocket::open(name).map_err(|e| format!("open a raw CAN socket on {name}: {e}"))?;
    socket
        .set_read_timeout(READ_TIMEOUT)
        .map_err(|e| format!("SO_RCVTIMEO: {e}"))?;
    Ok(socket)
}

/// Opens the sending and the receiving socket.
fn open_pair(name: &str) -> Result<(CanSocket, CanSocket), String> {
    Ok((open_socket(name)?, open_socket(name)?))
}

/// Sends the frame `text` on `tx` and checks that `rx` reads exactly it.
fn round_trip(tx: &CanSocket, rx: &CanSocket, text: &str) -> Outcome {
    send(tx, text)?;
    expect(rx, text, "receiver")?;
    Ok(text.to_owned())
}

/// Checks that a socket does not read its own frames by default, and does with
/// `CAN_RAW_RECV_OWN_MSGS`; the other socket reads the frame either way.
fn own_messages(tx: &CanSocket, rx: &CanSocket) -> Outcome {
    let text = "0601F5D0#0102";
    send(tx, text)?;
    expect(rx, text, "receiver")?;
    expect_silence(tx, "sender without CAN_RAW_RECV_OWN_MSGS")?;
    tx.set_recv_own_msgs(true)
        .map_err(|e| format!("set CAN_RAW_RECV_OWN_MSGS: {e}"))?;
    send(tx, text)?;
    let own = expect(tx, text, "sender with CAN_RAW_RECV_OWN_MSGS");
    let restored = tx
        .set_recv_own_msgs(false)
        .map_err(|e| format!("clear CAN_RAW_RECV_OWN_MSGS: {e}"));
    expect(rx, text, "receiver")?;
    own?;
    restored?;
    Ok(String::new())
}

/// Checks that `SO_TIMESTAMPNS` gives each received frame its arrival time.
fn receive_timestamp(tx: &CanSocket, rx: &CanSocket) -> Outcome {
    let text = "0601F5D0#0304";
    rx.set_recv_timestamp(true)
        .map_err(|e| format!("set SO_TIMESTAMPNS: {e}"))?;
    let sent_at = SystemTime::now();
    let read = send(tx, text).and_then(|()| {
        rx.read_frame_with_timestamp()
            .map_err(|e| read_error(&e, READ_TIMEOUT, "receiver"))
    });
    let read_at = SystemTime::now();
    rx.set_recv_timestamp(false)
        .map_err(|e| format!("clear SO_TIMESTAMPNS: {e}"))?;
    let (frame, stamp) = read?;
    let got = format_frame(&frame);
    if got != text {
        return Err(format!("sent {text}, received {got}"));
    }
    let age = read_at
        .duration_since(stamp)
        .map_err(|_| format!("timestamp {stamp:?} is later than the read's return {read_at:?}"))?;
    if age > TIMESTAMP_SLACK {
        return Err(format!("timestamp is {age:?} old when the read returns"));
    }
    if stamp < sent_at {
        return Err(format!(
            "timestamp {stamp:?} is earlier than the send {sent_at:?}"
        ));
    }
    Ok(format!("{} µs before the read returned", age.as_micros()))
}

/// Checks a kernel id/mask filter for destination F5 (`CAN_EFF_FLAG|0xF500`, mask
/// `CAN_EFF_FLAG|0xFF00`): only matching extended frames reach the socket.
fn kernel_filter(tx: &CanSocket, rx: &CanSocket) -> Outcome {
    let filter = CanFilter::new(CAN_EFF_FLAG | 0x0000_F500, CAN_EFF_FLAG | 0x0000_FF00);
    rx.set_filters(&[filter])
        .map_err(|e| format!("set CAN_RAW_FILTER: {e}"))?;
    let outcome = filtered(tx, rx);
    let restored = rx
        .set_filter_accept_all()
        .map_err(|e| format!("reset CAN_RAW_FILTER: {e}"));
    let detail = outcome?;
    restored?;
    Ok(detail)
}

/// Sends two frames the filter rejects and one it passes, and checks that only the latter arrives.
fn filtered(tx: &CanSocket, rx: &CanSocket) -> Outcome {
    let rejected = ["0300A0F5#01", "7F5#01"];
    let passed = "0601F5D0#01";
    for text in rejected {
        send(tx, text)?;
    }
    send(tx, passed)?;
    let frame = read(rx, READ_TIMEOUT, "filtered receiver")?;
    let got = format_frame(&frame);
    if rejected.contains(&got.as_str()) {
        return Err(format!("{got} passed the filter"));
    }
    if got != passed {
        return Err(format!("expected {passed}, received {got}"));
    }
    expect_silence(rx, "filtered receiver")?;
    Ok(format!("{} rejected, {passed} passed", rejected.join(" and ")))
}

/// Sends the frame `text` on `socket`.
fn send(socket: &CanSocket, text: &str) -> Result<(), String> {
    let frame = parse_frame(text)?;
    socket
        .write_frame(&frame)
        .map_err(|e| format!("send {text}: {e}"))
}

/// Reads one frame from `socket` within `timeout`; `who` names the socket in errors.
fn read(socket: &CanSocket, timeout: Duration, who: &str) -> Result<CanFrame, String> {
    socket
        .read_frame_timeout(timeout)
        .map_err(|e| read_error(&e, timeout, who))
}

/// Says why a read on the socket `who` failed.
fn read_error(error: &io::Error, timeout: Duration, who: &str) -> String {
    match error.kind() {
        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock => {
            format!("{who} read no frame within {timeout:?}")
        }
        _ => format!("{who} read: {error}"),
    }
}

/// Reads one frame from `socket` and checks that it is `text`.
fn expect(socket: &CanSocket, text: &str, who: &str) -> Result<(), String> {
    let got = format_frame(&read(socket, READ_TIMEOUT, who)?);
    if got == text {
        Ok(())
    } else {
        Err(format!("{who} expected {text}, read {got}"))
    }
}

/// Checks that `socket` reads nothing for a while.
fn expect_silence(socket: &CanSocket, who: &str) -> Result<(), String> {
    match socket.read_frame_timeout(SILENCE) {
        Ok(frame) => Err(format!("{who} read {} unexpectedly", format_frame(&frame))),
        Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => Ok(()),
        Err(e) => Err(format!("{who} read: {e}")),
    }
}

/// Parses a frame in can-utils notation: `ID#DATA` or `ID#R[DLC]`, with a 3-digit (base) or
/// 8-digit (extended) hexadecimal identifier.
fn parse_frame(text: &str) -> Result<CanFrame, String> {
    let bad = |why: &str| format!("bad frame {text:?}: {why}");
    let (id_text, rest) = text.split_once('#').ok_or_else(|| bad("no '#'"))?;
    let raw = u32::from_str_radix(id_text, 16).map_err(|_| bad("identifier is not hexadecimal"))?;
    let id: Id = match id_text.len() {
        3 => u16::try_from(raw)
            .ok()
            .and_then(StandardId::new)
            .ok_or_else(|| bad("base identifier above 7FF"))?
            .into(),
        8 => ExtendedId::new(raw)
            .ok_or_else(|| bad("extended identifier above 1FFFFFFF"))?
            .into(),
        _ => return Err(bad("identifier needs 3 or 8 hex digits")),
    };
    let frame = if let Some(dlc) = rest.strip_prefix('R') {
        let dlc = if dlc.is_empty() {
            0
        } else {
            dlc.parse().map_err(|_| bad("remote DLC is not a digit"))?
        };
        CanFrame::new_remote(id, dlc)
    } else {
        if rest.len() % 2 != 0 {
            return Err(bad("odd number of data digits"));
        }
        let data = (0..rest.len())
            .step_by(2)
            .map(|at| u8::from_str_radix(&rest[at..at + 2], 16))
            .collect::<Result<Vec<u8>, _>>()
            .map_err(|_| bad("data is not hexadecimal"))?;
        CanFrame::new(id, &data)
    };
    frame.ok_or_else(|| bad("more than 8 data bytes or a DLC above 8"))
}

/// Writes a frame in can-utils notation (see [`parse_frame`]); error frames get a suffix.
fn format_frame(frame: &CanFrame) -> String {
    let mut text = match frame.id() {
        Id::Standard(id) => format!("{:03X}#", id.as_raw()),
        Id::Extended(id) => format!("{:08X}#", id.as_raw()),
    };
    if frame.is_remote_frame() {
        text.push('R');
        if frame.dlc() != 0 {
            text.push_str(&frame.dlc().to_string());
        }
    } else {
        for byte in frame.data() {
            text.push_str(&format!("{byte:02X}"));
        }
    }
    if matches!(frame, CanFrame::Error(_)) {
        text.push_str(" (error frame)");
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_survive_parse_and_format() {
        for text in [
            "0601F5D0#200D0002FFBFFF00",
            "123#DEADBEEF",
            "7FF#",
            "123#R",
            "0300A0F5#R2",
        ] {
            let frame = parse_frame(text).expect("valid frame");
            assert_eq!(format_frame(&frame), text);
        }
        let frame = parse_frame("0601F5D0#01").expect("valid frame");
        assert!(frame.is_extended());
        assert!(!parse_frame("123#R").expect("valid frame").is_extended());
    }

    #[test]
    fn bad_frames_are_refused() {
        for text in [
            "123",
            "800#01",
            "12#01",
            "20000000#01",
            "123#0",
            "123#zz",
            "123#000000000000000000",
        ] {
            assert!(parse_frame(text).is_err(), "{text} was accepted");
        }
    }
}
