//! pcapng out: the trace as Wireshark, tshark and tcpdump capture a SocketCAN interface.
//!
//! Contract: [`PcapngWriter`] writes one section (a Section Header Block), then for every record
//! an Enhanced Packet Block on the interface that reports it: the bus's (`harv0`) for frames,
//! `harv0.D2` for controller D2's error frames, as harvemu's candump logs name them. Each
//! interface gets its Interface Description Block (link type `LINKTYPE_CAN_SOCKETCAN`, 227; its
//! name; nanosecond timestamps) just before its first packet, which pcapng allows anywhere in
//! the section. Records stream out as they come; nothing is held.
//!
//! The format (pcapng: IETF draft-ietf-opsawg-pcapng; the link type: tcpdump.org's
//! LINKTYPE_CAN_SOCKETCAN): blocks are little-endian here (the Section Header's byte-order magic
//! says so), but the packet is Linux's `struct can_frame` with its 32-bit `can_id` in network
//! byte order (big-endian), unlike the kernel's own, then the length, three reserved bytes and
//! eight data bytes (zeros past the length). Flags ride in the id as SocketCAN has them:
//! `CAN_EFF_FLAG` for an extended id, `CAN_RTR_FLAG` for a remote frame, `CAN_ERR_FLAG` with the
//! error classes for an error frame (linux/can/error.h, the details in its data).

use super::{Entry, Item, ItemWriter, fill};
use crate::Frame;
use crate::filter::CAN_ERR_FLAG;
use crate::time::Epoch;
use crate::trace::{Record, Sink};
use std::io::{self, Write};

/// The link type of a SocketCAN capture.
pub const LINKTYPE_CAN_SOCKETCAN: u16 = 227;
/// `CAN_EFF_FLAG`: the id is extended (29 bits).
const CAN_EFF_FLAG: u32 = 0x8000_0000;
/// `CAN_RTR_FLAG`: a remote frame.
const CAN_RTR_FLAG: u32 = 0x4000_0000;

/// Writes pcapng to `W` from trace records.
pub struct PcapngWriter<W: Write> {
    inner: W,
    epoch: Epoch,
    /// The interfaces described so far, by name, in the order of their ids.
    interfaces: Vec<String>,
    block: Vec<u8>,
    /// The item a hub record becomes, reused.
    item: Item,
    finished: bool,
}

impl<W: Write> PcapngWriter<W> {
    /// Starts a capture whose bus time zero is `epoch` and writes its section header.
    pub fn new(mut inner: W, epoch: Epoch) -> io::Result<PcapngWriter<W>> {
        let mut block = Vec::with_capacity(64);
        // Section Header Block: byte-order magic, version 1.0, section length unknown (-1),
        // an shb_userappl option naming the writer.
        let mut body = Vec::new();
        body.extend_from_slice(&0x1A2B_3C4Du32.to_le_bytes());
        body.extend_from_slice(&1u16.to_le_bytes());
        body.extend_from_slice(&0u16.to_le_bytes());
        body.extend_from_slice(&u64::MAX.to_le_bytes());
        option(&mut body, 4, b"harvemu");
        end_of_options(&mut body);
        wrap(&mut block, 0x0A0D_0D0A, &body);
        inner.write_all(&block)?;
        Ok(PcapngWriter {
            inner,
            epoch,
            interfaces: Vec::new(),
            block,
            item: Item {
                at: crate::time::Stamp(0),
                interface: String::new(),
                entry: Entry::Error(None),
            },
            finished: false,
        })
    }

    /// The output, once the capture is done with.
    pub fn into_inner(self) -> W {
        self.inner
    }

    /// The id of the interface called `name`, describing it first when it is new.
    fn interface(&mut self, name: &str) -> io::Result<u32> {
        if let Some(i) = self.interfaces.iter().position(|n| n == name) {
            return Ok(i as u32);
        }
        // Interface Description Block: link type, reserved, snap length (none), its name,
        // if_tsresol 9 (nanoseconds).
        let mut body = Vec::new();
        body.extend_from_slice(&LINKTYPE_CAN_SOCKETCAN.to_le_bytes());
        body.extend_from_slice(&0u16.to_le_bytes());
        body.extend_from_slice(&0u32.to_le_bytes());
        option(&mut body, 2, name.as_bytes());
        option(&mut body, 9, &[9]);
        end_of_options(&mut body);
        self.block.clear();
        wrap(&mut self.block, 1, &body);
        self.inner.write_all(&self.block)?;
        self.interfaces.push(name.to_string());
        Ok((self.interfaces.len() - 1) as u32)
    }
}

/// The 16 bytes of `struct can_frame` as LINKTYPE_CAN_SOCKETCAN stores them.
fn can_frame(can_id: u32, data: &[u8], len: u8) -> [u8; 16] {
    let mut packet = [0u8; 16];
    packet[..4].copy_from_slice(&can_id.to_be_bytes());
    packet[4] = len;
    let n = data.len().min(8);
    packet[8..8 + n].copy_from_slice(&data[..n]);
    packet
}

/// A data or remote frame's packet.
pub fn frame_packet(frame: &Frame) -> [u8; 16] {
    let mut id = frame.raw_id();
    if frame.is_extended() {
        id |= CAN_EFF_FLAG;
    }
    if frame.is_remote() {
        id |= CAN_RTR_FLAG;
        return can_frame(id, &[], frame.dlc());
    }
    can_frame(id, frame.data(), frame.dlc())
}

impl<W: Write> ItemWriter for PcapngWriter<W> {
    fn write(&mut self, item: &Item) -> io::Result<()> {
        if self.finished {
            return Err(io::Error::other("the capture has ended"));
        }
        let interface = self.interface(&item.interface)?;
        let packet = match &item.entry {
            Entry::Frame(frame) => frame_packet(frame),
            Entry::Error(Some(e)) => can_frame(CAN_ERR_FLAG | e.can_id, &e.data, 8),
            // An error frame without details (from ASC or BLF): the flag, no class.
            Entry::Error(None) => can_frame(CAN_ERR_FLAG, &[0; 8], 8),
        };
        // Enhanced Packet Block: interface, timestamp (ns since 1970, high word first), captured
        // and original length, the packet.
        let ns = item.at.as_nanos();
        let mut body = Vec::with_capacity(36);
        body.extend_from_slice(&interface.to_le_bytes());
        body.extend_from_slice(&((ns >> 32) as u32).to_le_bytes());
        body.extend_from_slice(&(ns as u32).to_le_bytes());
        body.extend_from_slice(&16u32.to_le_bytes());
        body.extend_from_slice(&16u32.to_le_bytes());
        body.extend_from_slice(&packet);
        self.block.clear();
        wrap(&mut self.block, 6, &body);
        self.inner.write_all(&self.block)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }

    fn finish(&mut self) -> io::Result<()> {
        self.finished = true;
        self.inner.flush()
    }
}

impl<W: Write> Sink for PcapngWriter<W> {
    fn record(&mut self, r: &Record<'_>) -> io::Result<()> {
        let mut item = std::mem::replace(
            &mut self.item,
            Item {
                at: crate::time::Stamp(0),
                interface: String::new(),
                entry: Entry::Error(None),
            },
        );
        fill(&mut item, self.epoch, r);
        let written = ItemWriter::write(self, &item);
        self.item = item;
        written
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// An option: code, length, value padded to 32 bits.
fn option(body: &mut Vec<u8>, code: u16, value: &[u8]) {
    body.extend_from_slice(&code.to_le_bytes());
    body.extend_from_slice(&(value.len() as u16).to_le_bytes());
    body.extend_from_slice(value);
    body.resize(body.len().next_multiple_of(4), 0);
}

fn end_of_options(body: &mut Vec<u8>) {
    body.extend_from_slice(&[0, 0, 0, 0]);
}

/// A block: type, total length, body (padded to 32 bits), total length again.
fn wrap(out: &mut Vec<u8>, kind: u32, body: &[u8]) {
    let padded = body.len().next_multiple_of(4);
    let total = (12 + padded) as u32;
    out.extend_from_slice(&kind.to_le_bytes());
    out.extend_from_slice(&total.to_le_bytes());
    out.extend_from_slice(body);
    out.resize(out.len() + padded - body.len(), 0);
    out.extend_from_slice(&total.to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::BusTime;
    use crate::trace::{Kind, Source};

    fn u32_at(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
    }

    #[test]
    fn blocks_are_laid_out_as_pcapng_and_the_id_is_big_endian() {
        let mut w = PcapngWriter::new(Vec::new(), Epoch::from_secs(1_704_067_200)).unwrap();
        let frame = crate::candump::parse_frame("0200F5E0#107800F4010000").unwrap();
        let record = Record {
            at: BusTime::from_micros(551_520),
            bus: "harv0",
            source: Source::Bus,
            kind: Kind::Frame(frame),
        };
        w.record(&record).unwrap();
        w.record(&record).unwrap();
        let b = w.inner;
        // Section Header Block: its type, its length at both ends, the byte-order magic.
        let shb = u32_at(&b, 4) as usize;
        assert_eq!((u32_at(&b, 0), u32_at(&b, 8)), (0x0A0D_0D0A, 0x1A2B_3C4D));
        assert_eq!(u32_at(&b, shb - 4) as usize, shb);
        // One Interface Description Block, for harv0: link type 227.
        let idb = shb;
        let idb_len = u32_at(&b, idb + 4) as usize;
        assert_eq!(u32_at(&b, idb), 1);
        assert_eq!(u16::from_le_bytes([b[idb + 8], b[idb + 9]]), 227);
        // Two Enhanced Packet Blocks on interface 0, 32 + 16 bytes each.
        let epb = idb + idb_len;
        assert_eq!(b.len(), epb + 2 * 48);
        assert_eq!(
            (u32_at(&b, epb), u32_at(&b, epb + 4), u32_at(&b, epb + 8)),
            (6, 48, 0)
        );
        let ns = (u64::from(u32_at(&b, epb + 12)) << 32) | u64::from(u32_at(&b, epb + 16));
        assert_eq!(ns, 1_704_067_200_551_520_000);
        // struct can_frame: CAN_EFF_FLAG | id, big-endian; length 7; the data, zero-padded.
        let packet = &b[epb + 28..epb + 44];
        assert_eq!(&packet[..8], &[0x82, 0x00, 0xF5, 0xE0, 7, 0, 0, 0]);
        assert_eq!(&packet[8..], &[0x10, 0x78, 0x00, 0xF4, 0x01, 0x00, 0x00, 0x00]);
    }
}
