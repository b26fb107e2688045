//! A trace sink that counts the errors `ErrorKinds` expectations ask about, read from the
//! controllers' error frames as SocketCAN encodes them (`linux/can/error.h`), as a trace line
//! shows them: an ACK error by its class, the others by the protocol-error type in data[2], a
//! CRC error as Linux drivers report it (no type, at the CRC sequence).
//!
//! Contract: each query is counted over its window, both ends included, once per error frame of
//! its node; nothing but the counts is kept, so memory does not grow with the run.

use super::model::DetectedError;
use bus::engine::NodeId;
use bus::time::BusTime;
use bus::trace::{Kind, Record, Sink, Source, err};
use std::cell::RefCell;
use std::io;
use std::rc::Rc;

/// One question: errors of `kind` detected by `node` from `from` to `to`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Query {
    /// The expectation it answers (its index among the scenario's).
    pub check: usize,
    /// The node's controller.
    pub node: NodeId,
    /// The kind.
    pub kind: DetectedError,
    /// From.
    pub from: BusTime,
    /// To.
    pub to: BusTime,
}

/// The queries with their counts so far.
pub type Counts = Rc<RefCell<Vec<(Query, u64)>>>;

/// Counts the errors of each query.
pub struct Counting(Counts);

impl Counting {
    /// A sink for `queries`, and the counts it keeps.
    pub fn new(queries: Vec<Query>) -> (Counting, Counts) {
        let counts = Rc::new(RefCell::new(queries.into_iter().map(|q| (q, 0)).collect()));
        (Counting(Rc::clone(&counts)), counts)
    }
}

/// The error a controller's error frame reports, if it reports one.
pub fn detected(can_id: u32, data: &[u8; 8]) -> Option<DetectedError> {
    if can_id & err::ACK != 0 {
        return Some(DetectedError::Ack);
    }
    if can_id & err::PROT == 0 || can_id & err::BUSERROR == 0 {
        return None;
    }
    let kind = data[2] & !err::PROT_TX;
    if kind & err::PROT_BIT != 0 {
        Some(DetectedError::Bit)
    } else if kind & err::PROT_STUFF != 0 {
        Some(DetectedError::Stuff)
    } else if kind & err::PROT_FORM != 0 {
        Some(DetectedError::Form)
    } else if kind == 0 && data[3] == CAN_ERR_PROT_LOC_CRC_SEQ {
        Some(DetectedError::Crc)
    } else {
        None
    }
}

/// `CAN_ERR_PROT_LOC_CRC_SEQ` of `linux/can/error.h`: the CRC sequence.
const CAN_ERR_PROT_LOC_CRC_SEQ: u8 = 0x08;

impl Sink for Counting {
    fn record(&mut self, r: &Record<'_>) -> io::Result<()> {
        let (Source::Controller { node, .. }, Kind::Error(e)) = (r.source, r.kind) else {
            return Ok(());
        };
        let Some(kind) = detected(e.can_id, &e.data) else {
            return Ok(());
        };
        for (q, n) in self.0.borrow_mut().iter_mut() {
            if q.node == node && q.kind == kind && (q.from..=q.to).contains(&r.at) {
                *n += 1;
            }
        }
        Ok(())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Error frames as a SocketCAN driver writes them (values from `linux/can/error.h`:
    /// CAN_ERR_FLAG 0x20000000, PROT 0x08, ACK 0x20, BUSERROR 0x80, CNT 0x200; data[2] BIT 0x01,
    /// FORM 0x02, STUFF 0x04, OVERLOAD 0x20, TX 0x80; data[3] ACK 0x19, CRC_SEQ 0x08).
    #[test]
    fn kinds_from_socketcan_error_frames() {
        let id = |class: u32| 0x2000_0000 | class;
        let d = |b2: u8, b3: u8| [0, 0, b2, b3, 0, 0, 8, 0];
        let cases = [
            (id(0x288), d(0x81, 0x0A), Some(DetectedError::Bit)),
            (id(0x288), d(0x04, 0x0A), Some(DetectedError::Stuff)),
            (id(0x288), d(0x02, 0x1A), Some(DetectedError::Form)),
            (id(0x288), d(0x00, 0x08), Some(DetectedError::Crc)),
            (id(0x2A8), d(0x80, 0x19), Some(DetectedError::Ack)),
            // An overload flag, a state change: no error detected.
            (id(0x008), d(0x20, 0x00), None),
            (id(0x204), d(0x00, 0x00), None),
        ];
        for (can_id, data, want) in cases {
            assert_eq!(detected(can_id, &data), want, "{can_id:08X} {data:02X?}");
        }
    }
}
