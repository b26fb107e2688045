//! The bus as a candump log: `(secs.usecs) harv0 0601F5D0#200D0002FFBFFF00`.
//!
//! The hub hands the trace to its [`Sink`]s as typed [`Record`]s ([`Record::of_event`]): a frame
//! from the bus, or an error frame from one controller. Sinks format them ([`CandumpWriter`],
//! `tracefile::AscWriter`) or count them; nothing parses trace text back.
//!
//! Times are bus time stamped with an [`Epoch`] (seconds since 1970, as `candump -l` writes
//! them); the line writers take the time to write, [`CandumpWriter`] stamps it itself.
//!
//! Error frames are written in SocketCAN's error-frame encoding (`include/uapi/linux/can/error.h`):
//! the identifier is `CAN_ERR_FLAG` with class bits, the 8 data bytes carry the details. Frames
//! are written on the bus's interface (`harv0`); everything one controller reports is written on
//! an interface of its own, the bus's name, a dot and the controller's name (`harv0.D2`), as a
//! SocketCAN interface per controller would deliver it: each bus error it detected (protocol
//! error type in data[2], `CAN_ERR_PROT_TX` when it was transmitting, the location in data[3],
//! TEC and REC in data[6] and data[7]), each overload flag it sent, its state changes (warning,
//! passive, bus off, restarted) and its receive overruns.

use crate::Frame;
use crate::candump::write_frame;
use crate::engine::{BusError, Event, NodeId};
use crate::fault::ErrorState;
use crate::filter::CAN_ERR_FLAG;
use crate::time::{BusTime, Epoch, Stamp};
use core::fmt::Write;
use std::io;

mod order;
pub use order::{Reorder, WINDOW_BITS};

/// Error classes (can_id bits) and data bytes of linux/can/error.h.
pub mod err {
    /// Lost arbitration.
    pub const LOSTARB: u32 = 0x0000_0002;
    /// Controller problems: data[1].
    pub const CRTL: u32 = 0x0000_0004;
    /// Protocol violations: data[2], data[3].
    pub const PROT: u32 = 0x0000_0008;
    /// Received no ACK on transmission.
    pub const ACK: u32 = 0x0000_0020;
    /// Bus off.
    pub const BUSOFF: u32 = 0x0000_0040;
    /// Bus error.
    pub const BUSERROR: u32 = 0x0000_0080;
    /// Controller restarted.
    pub const RESTARTED: u32 = 0x0000_0100;
    /// TEC in data[6], REC in data[7].
    pub const CNT: u32 = 0x0000_0200;
    /// data[1]: receive overflow.
    pub const CRTL_RX_OVERFLOW: u8 = 0x01;
    /// data[1]: receive warning level.
    pub const CRTL_RX_WARNING: u8 = 0x04;
    /// data[1]: transmit warning level.
    pub const CRTL_TX_WARNING: u8 = 0x08;
    /// data[1]: receive error passive.
    pub const CRTL_RX_PASSIVE: u8 = 0x10;
    /// data[1]: transmit error passive.
    pub const CRTL_TX_PASSIVE: u8 = 0x20;
    /// data[1]: back to error active.
    pub const CRTL_ACTIVE: u8 = 0x40;
    /// data[2]: single bit error.
    pub const PROT_BIT: u8 = 0x01;
    /// data[2]: frame format error.
    pub const PROT_FORM: u8 = 0x02;
    /// data[2]: bit stuffing error.
    pub const PROT_STUFF: u8 = 0x04;
    /// data[2]: bus overload.
    pub const PROT_OVERLOAD: u8 = 0x20;
    /// data[2]: error occurred on transmission.
    pub const PROT_TX: u8 = 0x80;
    /// data[3]: ACK slot.
    pub const PROT_LOC_ACK: u8 = 0x19;
}

/// A SocketCAN error frame: `can_id` with `CAN_ERR_FLAG`, 8 data bytes.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct ErrorFrame {
    /// Identifier including `CAN_ERR_FLAG` and class bits.
    pub can_id: u32,
    /// Details.
    pub data: [u8; 8],
}

fn counters(data: &mut [u8; 8], tec: u16, rec: u16) {
    data[6] = tec.min(255) as u8;
    data[7] = rec.min(255) as u8;
}

/// The error frame an event would raise, if it raises one.
pub fn error_frame(event: &Event) -> Option<ErrorFrame> {
    let mut data = [0u8; 8];
    let class = match *event {
        Event::BusError {
            error,
            transmitting,
            location,
            tec,
            rec,
            ..
        } => {
            counters(&mut data, tec, rec);
            data[2] = if transmitting { err::PROT_TX } else { 0 };
            data[3] = location.socketcan();
            data[2] |= match error {
                BusError::Bit => err::PROT_BIT,
                BusError::Form => err::PROT_FORM,
                BusError::Stuff => err::PROT_STUFF,
                // Linux drivers report a CRC error as no type at the CRC sequence.
                BusError::Crc | BusError::Ack => 0,
            };
            match error {
                BusError::Ack => {
                    data[3] = err::PROT_LOC_ACK;
                    err::PROT | err::ACK | err::BUSERROR | err::CNT
                }
                _ => err::PROT | err::BUSERROR | err::CNT,
            }
        }
        Event::Overload { .. } => {
            data[2] = err::PROT_OVERLOAD;
            err::PROT
        }
        Event::State {
            to, tec, rec, from, ..
        } => {
            counters(&mut data, tec, rec);
            match to {
                ErrorState::BusOff => err::BUSOFF | err::CNT,
                ErrorState::Active if from == ErrorState::BusOff => {
                    data[1] = err::CRTL_ACTIVE;
                    err::RESTARTED | err::CRTL | err::CNT
                }
                ErrorState::Active => {
                    data[1] = err::CRTL_ACTIVE;
                    err::CRTL | err::CNT
                }
                ErrorState::Passive => {
                    data[1] = if tec >= 128 { err::CRTL_TX_PASSIVE } else { 0 }
                        | if rec >= 128 { err::CRTL_RX_PASSIVE } else { 0 };
                    err::CRTL | err::CNT
                }
            }
        }
        Event::Warning {
            entered: true,
            tec,
            rec,
            ..
        } => {
            counters(&mut data, tec, rec);
            data[1] = if tec >= 96 { err::CRTL_TX_WARNING } else { 0 }
                | if rec >= 96 { err::CRTL_RX_WARNING } else { 0 };
            err::CRTL | err::CNT
        }
        Event::Overrun { .. } => {
            data[1] = err::CRTL_RX_OVERFLOW;
            err::CRTL
        }
        Event::Restarted { .. } => {
            data[1] = err::CRTL_ACTIVE;
            err::RESTARTED | err::CRTL | err::CNT
        }
        _ => return None,
    };
    Some(ErrorFrame {
        can_id: CAN_ERR_FLAG | class,
        data,
    })
}

/// Appends the timestamp and interface of a log line.
fn prefix(out: &mut String, at: Stamp, iface: &str) {
    let _ = write!(out, "({at}) {iface} ");
}

/// Appends one candump log line for a frame.
pub fn frame_line(out: &mut String, at: Stamp, iface: &str, frame: &Frame) {
    prefix(out, at, iface);
    write_frame(out, frame);
    out.push('\n');
}

/// Appends one candump log line for an error frame.
pub fn error_line(out: &mut String, at: Stamp, iface: &str, e: &ErrorFrame) {
    prefix(out, at, iface);
    error_frame_text(out, e);
}

/// Appends `ID#DATA` of an error frame and the end of the line.
fn error_frame_text(out: &mut String, e: &ErrorFrame) {
    let _ = write!(out, "{:08X}#", e.can_id);
    for b in e.data {
        let _ = write!(out, "{b:02X}");
    }
    out.push('\n');
}

/// Who reports a [`Record`]: the bus (a frame, on the bus's interface) or one controller (what it
/// detected, on its own interface).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Source<'a> {
    /// The bus itself: a frame that completed.
    Bus,
    /// A controller, with its name as the trace writes it (`D2` in `harv0.D2`).
    Controller {
        /// Its place on the bus.
        node: NodeId,
        /// Its name.
        name: &'a str,
    },
}

/// What a [`Record`] holds.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Kind {
    /// A data or remote frame.
    Frame(Frame),
    /// A controller's error frame in SocketCAN's encoding.
    Error(ErrorFrame),
}

/// One entry of the trace, typed: what a candump log line carries, before it is formatted. The
/// hub hands these to its [`Sink`]s; nothing parses trace text back.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Record<'a> {
    /// Bus time (not stamped with an epoch): a frame's end of frame, the first bit of a
    /// controller's error or overload flag, or the moment of its state change or overrun.
    pub at: BusTime,
    /// The bus's interface name (`harv0`).
    pub bus: &'a str,
    /// The bus or the controller that reports it.
    pub source: Source<'a>,
    /// The frame or error frame.
    pub kind: Kind,
}

impl<'a> Record<'a> {
    /// The record an engine event gives, if any: frames at their end-of-frame time from the bus;
    /// a controller's error frames (bus errors at the first bit of its flag, overload flags,
    /// state changes, overruns) from that controller, with `name` giving each controller's name.
    pub fn of_event(bus: &'a str, name: impl Fn(NodeId) -> &'a str, event: &Event) -> Option<Record<'a>> {
        match event {
            Event::Frame { end, frame, .. } => Some(Record {
                at: *end,
                bus,
                source: Source::Bus,
                kind: Kind::Frame(*frame),
            }),
            Event::BusError { node, at, .. }
            | Event::Overload { node, at }
            | Event::State { node, at, .. }
            | Event::Warning { node, at, .. }
            | Event::Restarted { node, at }
            | Event::Overrun { node, at } => error_frame(event).map(|e| Record {
                at: *at,
                bus,
                source: Source::Controller {
                    node: *node,
                    name: name(*node),
                },
                kind: Kind::Error(e),
            }),
            _ => None,
        }
    }
}

/// Where the hub's trace goes: a file format, a count, a view. Records arrive in time order, equal
/// times in the order the bus gave them: the hub passes them through a [`Reorder`] first.
///
/// A sink whose `record` or `flush` fails is given nothing more; the hub keeps the first error
/// to report it (`Snapshot::trace_error` in `bus-runtime`).
pub trait Sink {
    /// Takes one record.
    fn record(&mut self, r: &Record<'_>) -> io::Result<()>;
    /// Passes on what is buffered.
    fn flush(&mut self) -> io::Result<()>;
}

/// Writes records as candump log lines, times stamped with an [`Epoch`].
pub struct CandumpWriter<W: io::Write> {
    inner: W,
    epoch: Epoch,
    line: String,
}

impl<W: io::Write> CandumpWriter<W> {
    /// Writes to `inner`, each time stamped with `epoch`.
    pub fn new(inner: W, epoch: Epoch) -> CandumpWriter<W> {
        CandumpWriter {
            inner,
            epoch,
            line: String::with_capacity(128),
        }
    }
}

impl<W: io::Write> Sink for CandumpWriter<W> {
    fn record(&mut self, r: &Record<'_>) -> io::Result<()> {
        self.line.clear();
        record_line(&mut self.line, self.epoch, r);
        self.inner.write_all(self.line.as_bytes())
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// Appends the candump log line of a record, its time stamped with `epoch`: a frame on the
/// bus's interface, a controller's error frame on `bus.NAME`.
pub fn record_line(out: &mut String, epoch: Epoch, r: &Record<'_>) {
    let _ = write!(out, "({}) {}", epoch.stamp(r.at), r.bus);
    if let Source::Controller { name, .. } = r.source {
        out.push('.');
        // A name is one word on the line, as an interface name would be.
        out.extend(name.chars().map(|c| if c.is_ascii_graphic() { c } else { '_' }));
    }
    out.push(' ');
    match &r.kind {
        Kind::Frame(frame) => {
            write_frame(out, frame);
            out.push('\n');
        }
        Kind::Error(e) => error_frame_text(out, e),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::candump::parse_frame;
    use crate::engine::Location;
    use crate::time::BusTime;

    #[test]
    fn frame_lines_look_like_candump() {
        let mut out = String::new();
        let f = parse_frame("0601F5D0#200D0002FFBFFF00").unwrap();
        frame_line(&mut out, Stamp(1_708_620_903_978_650_123), "harv0", &f);
        assert_eq!(out, "(1708620903.978650) harv0 0601F5D0#200D0002FFBFFF00\n");
        out.clear();
        frame_line(&mut out, Stamp(5_000), "harv0", &parse_frame("123#R").unwrap());
        assert_eq!(out, "(0.000005) harv0 123#R\n");
    }

    #[test]
    fn error_frames_use_socketcan_encoding() {
        let ack = Event::BusError {
            node: NodeId(0),
            at: BusTime::from_nanos(1_000_000),
            error: BusError::Ack,
            transmitting: true,
            location: Location::Ack,
            tec: 8,
            rec: 0,
        };
        let line = |epoch, event: &Event| {
            let mut out = String::new();
            let r = Record::of_event("harv0", |_| "E0", event).unwrap();
            record_line(&mut out, epoch, &r);
            out
        };
        let out = line(Epoch::UNIX, &ack);
        // CAN_ERR_FLAG | PROT 0x8 | ACK 0x20 | BUSERROR 0x80 | CNT 0x200; data[2] TX, data[3] ACK
        // slot, data[6] TEC.
        assert_eq!(out, "(0.001000) harv0.E0 200002A8#0000801900000800\n");
        // The same event a day after 1970 began: only the time moves.
        let out = line(Epoch::from_secs(86_400), &ack);
        assert_eq!(out, "(86400.001000) harv0.E0 200002A8#0000801900000800\n");
        // A receiver's stuff error in the data field, a CRC error, a form error in EOF.
        let seen = |error, location| {
            error_frame(&Event::BusError {
                node: NodeId(1),
                at: BusTime::ZERO,
                error,
                transmitting: false,
                location,
                tec: 0,
                rec: 1,
            })
            .unwrap()
        };
        let stuff = seen(BusError::Stuff, Location::Data);
        assert_eq!(stuff.can_id, CAN_ERR_FLAG | 0x8 | 0x80 | 0x200);
        assert_eq!(stuff.data, [0, 0, 0x04, 0x0A, 0, 0, 0, 1]);
        assert_eq!(seen(BusError::Crc, Location::CrcSeq).data[2..4], [0x00, 0x08]);
        assert_eq!(seen(BusError::Form, Location::Eof).data[2..4], [0x02, 0x1A]);
        let over = error_frame(&Event::Overload {
            node: NodeId(2),
            at: BusTime::ZERO,
        })
        .unwrap();
        assert_eq!((over.can_id, over.data[2]), (CAN_ERR_FLAG | 0x8, 0x20));
        let off = Event::State {
            node: NodeId(1),
            at: BusTime::from_nanos(2_000_000),
            from: ErrorState::Passive,
            to: ErrorState::BusOff,
            tec: 256,
            rec: 3,
        };
        let e = error_frame(&off).unwrap();
        assert_eq!(e.can_id, CAN_ERR_FLAG | 0x40 | 0x200);
        assert_eq!((e.data[6], e.data[7]), (255, 3), "TEC saturates in its byte");
        let back = Event::State {
            node: NodeId(1),
            at: BusTime::ZERO,
            from: ErrorState::BusOff,
            to: ErrorState::Active,
            tec: 0,
            rec: 0,
        };
        assert_eq!(error_frame(&back).unwrap().can_id & 0x100, 0x100, "restarted");
        let passive = Event::State {
            node: NodeId(1),
            at: BusTime::ZERO,
            from: ErrorState::Active,
            to: ErrorState::Passive,
            tec: 128,
            rec: 5,
        };
        assert_eq!(error_frame(&passive).unwrap().data[1], 0x20);
        assert!(
            error_frame(&Event::Delivered {
                node: NodeId(0),
                at: BusTime::ZERO
            })
            .is_none()
        );
    }

    /// The records of docs/TRACES.md's example, 2024-01-01T00:00:00Z being the epoch.
    pub(crate) fn example() -> Vec<Record<'static>> {
        let at = |us: u64| BusTime::from_micros(us);
        let ext = crate::extended_id(0x0200_F5E0).unwrap();
        let data = [0x10, 0x78, 0x00, 0xF4, 0x01, 0x00, 0x00];
        let ack = ErrorFrame {
            can_id: CAN_ERR_FLAG | 0x2A8,
            data: [0, 0, 0x80, 0x19, 0, 0, 0x08, 0],
        };
        vec![
            Record {
                at: at(551_520),
                bus: "harv0",
                source: Source::Bus,
                kind: Kind::Frame(Frame::new_data(ext, &data).unwrap()),
            },
            Record {
                at: at(600_000),
                bus: "harv0",
                source: Source::Bus,
                kind: Kind::Frame(Frame::new_remote(crate::standard_id(0x123).unwrap(), 4).unwrap()),
            },
            Record {
                at: at(700_000),
                bus: "harv0",
                source: Source::Controller {
                    node: NodeId(3),
                    name: "E0",
                },
                kind: Kind::Error(ack),
            },
        ]
    }

    #[test]
    fn the_candump_writer_writes_the_lines_of_the_format() {
        let mut file = Vec::new();
        let mut w = CandumpWriter::new(&mut file, Epoch::from_secs(1_704_067_200));
        for r in example() {
            w.record(&r).unwrap();
        }
        // A controller whose name has a space in it still makes one word of an interface.
        let mut odd = example()[2];
        odd.source = Source::Controller {
            node: NodeId(4),
            name: "left door",
        };
        odd.at = BusTime::from_nanos(1_000_000_001_999);
        w.record(&odd).unwrap();
        w.flush().unwrap();
        assert_eq!(
            String::from_utf8(file).unwrap(),
            "(1704067200.551520) harv0 0200F5E0#107800F4010000\n\
             (1704067200.600000) harv0 123#R4\n\
             (1704067200.700000) harv0.E0 200002A8#0000801900000800\n\
             (1704068200.000001) harv0.left_door 200002A8#0000801900000800\n"
        );
    }

    #[test]
    fn events_become_records_from_the_bus_or_from_their_controller() {
        let frame = Frame::new_data(crate::standard_id(0x7FF).unwrap(), &[1]).unwrap();
        let done = Event::Frame {
            node: NodeId(2),
            start: BusTime::from_nanos(10),
            end: BusTime::from_nanos(99),
            frame,
            bits: 50,
        };
        let r = Record::of_event("can0", |_| "X", &done).unwrap();
        assert_eq!(
            (r.at, r.bus, r.source, r.kind),
            (BusTime::from_nanos(99), "can0", Source::Bus, Kind::Frame(frame))
        );
        let names = ["A", "B", "C"];
        let over = Event::Overload {
            node: NodeId(1),
            at: BusTime::from_nanos(7),
        };
        let r = Record::of_event("can0", |n| names[n.index()], &over).unwrap();
        assert_eq!(
            r.source,
            Source::Controller {
                node: NodeId(1),
                name: "B"
            }
        );
        assert_eq!(r.at, BusTime::from_nanos(7));
        let delivered = Event::Delivered {
            node: NodeId(0),
            at: BusTime::from_nanos(0),
        };
        assert!(Record::of_event("can0", |_| "X", &delivered).is_none());
    }
}
