//! The 64-byte receive FIFO RAM (data sheet 6.4.14, 6.4.16, 6.4.17).
//!
//! Messages are stored back to back, wrapping at 64, in the receive-buffer layout: one frame
//! information byte, 2 (base) or 4 (extended) identifier bytes, then the data bytes (none for a
//! remote frame). RBSA is the RAM address of the first byte of the message the receive window
//! shows; RRB moves it past that message.

use crate::Frame;
use std::collections::VecDeque;

/// Size of the receive FIFO RAM.
pub const FIFO_BYTES: usize = 64;

/// The receive FIFO: the RAM, the start address and the stored messages' lengths.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct RxFifo {
    pub ram: [u8; FIFO_BYTES],
    /// RBSA: where the front message starts.
    pub start: u8,
    /// Length in bytes of each stored message, front first (RMC is its length).
    lengths: VecDeque<u8>,
}

/// Bytes a received frame takes in the FIFO RAM: frame information and identifier (3 bytes base,
/// 5 extended) plus the data; a remote frame stores no data. The one place this rule lives: the
/// engine's controllers that stand for an SJA1000 count with it too
/// ([`crate::engine::fifo_bytes`]).
pub fn message_bytes(frame: &Frame) -> usize {
    let header = if frame.is_extended() { 5 } else { 3 };
    header + frame.data().len()
}

/// The receive-buffer bytes of a frame (frame information, identifier, data).
pub(crate) fn encode(frame: &Frame) -> Vec<u8> {
    let mut out = Vec::with_capacity(13);
    let rtr = u8::from(frame.is_remote());
    let info = (u8::from(frame.is_extended()) << 7) | (rtr << 6) | frame.dlc();
    out.push(info);
    let id = frame.raw_id();
    if frame.is_extended() {
        out.extend_from_slice(&[(id >> 21) as u8, (id >> 13) as u8, (id >> 5) as u8]);
        out.push(((id << 3) as u8) | (rtr << 2));
    } else {
        out.push((id >> 3) as u8);
        out.push(((id << 5) as u8) | (rtr << 4));
    }
    out.extend_from_slice(frame.data());
    out
}

impl RxFifo {
    pub fn new() -> RxFifo {
        RxFifo {
            ram: [0; FIFO_BYTES],
            start: 0,
            lengths: VecDeque::new(),
        }
    }

    /// Messages stored (RMC).
    pub fn count(&self) -> usize {
        self.lengths.len()
    }

    /// Bytes in use.
    fn used(&self) -> usize {
        self.lengths.iter().map(|&n| usize::from(n)).sum()
    }

    /// Empties the FIFO; RAM and RBSA keep their contents (data sheet 6.4.17: on a software
    /// reset the next message is written where RBSA points).
    pub fn clear(&mut self) {
        self.lengths.clear();
    }

    /// The byte `offset` bytes after RBSA, wrapping.
    pub fn at(&self, offset: usize) -> u8 {
        self.ram[(usize::from(self.start) + offset) % FIFO_BYTES]
    }

    /// Stores `frame`; false (and nothing stored) when it does not fit.
    pub fn push(&mut self, frame: &Frame) -> bool {
        let used = self.used();
        if used + message_bytes(frame) > FIFO_BYTES {
            return false;
        }
        let bytes = encode(frame);
        for (i, b) in bytes.iter().enumerate() {
            self.ram[(usize::from(self.start) + used + i) % FIFO_BYTES] = *b;
        }
        self.lengths.push_back(bytes.len() as u8);
        true
    }

    /// Releases the front message (RRB); nothing when empty.
    pub fn release(&mut self) {
        if let Some(n) = self.lengths.pop_front() {
            self.start = ((usize::from(self.start) + usize::from(n)) % FIFO_BYTES) as u8;
        }
    }
}
