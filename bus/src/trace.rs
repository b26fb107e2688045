//! The bus as a candump log: `(secs.usecs) harv0 0601F5D0#200D0002FFBFFF00`.
//!
//! Times are bus time stamped with an [`Epoch`] (seconds since 1970, as `candump -l` writes
//! them); the line writers take the time to write, [`event_line`] stamps it itself.
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
use crate::time::{Epoch, Stamp};
use core::fmt::Write;

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

/// Appends the log line an engine event gives, if any, its time stamped with `epoch`: frames at
/// their end-of-frame time on `iface`; a controller's error frames (bus errors at the first bit of its flag, overload flags,
/// state changes, overruns) on `iface.NAME`, with `name` giving each controller's name.
pub fn event_line<'a>(
    out: &mut String,
    epoch: Epoch,
    iface: &str,
    name: impl Fn(NodeId) -> &'a str,
    event: &Event,
) {
    match event {
        Event::Frame { end, frame, .. } => frame_line(out, epoch.stamp(*end), iface, frame),
        Event::BusError { node, at, .. }
        | Event::Overload { node, at }
        | Event::State { node, at, .. }
        | Event::Warning { node, at, .. }
        | Event::Restarted { node, at }
        | Event::Overrun { node, at } => {
            if let Some(e) = error_frame(event) {
                let _ = write!(out, "({}) {iface}.", epoch.stamp(*at));
                // A name is one word on the line, as an interface name would be.
                out.extend(
                    name(*node)
                        .chars()
                        .map(|c| if c.is_ascii_graphic() { c } else { '_' }),
                );
                out.push(' ');
                error_frame_text(out, &e);
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
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
        let mut out = String::new();
        event_line(&mut out, Epoch::UNIX, "harv0", |_| "E0", &ack);
        // CAN_ERR_FLAG | PROT 0x8 | ACK 0x20 | BUSERROR 0x80 | CNT 0x200; data[2] TX, data[3] ACK
        // slot, data[6] TEC.
        assert_eq!(out, "(0.001000) harv0.E0 200002A8#0000801900000800\n");
        out.clear();
        // The same event a day after 1970 began: only the time moves.
        event_line(&mut out, Epoch::from_secs(86_400), "harv0", |_| "E0", &ack);
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
}
