//! pcapng in: SocketCAN captures as Wireshark's dumpcap, tshark, tcpdump and harvemu write them,
//! and classic pcap files (`tcpdump -w`).
//!
//! Contract: [`PcapngReader`] reads one block at a time and gives each CAN packet as an
//! [`Item`] with its block's number (from 1) — never more than one block in memory, and no
//! block longer than [`MAX_BLOCK`].
//! - pcapng (IETF draft-ietf-opsawg-pcapng): sections of either byte order, each starting with
//!   a Section Header Block that forgets the interfaces before it; Interface Description Blocks
//!   with their name (`if_name`, else `canN` for interface N of the section), time resolution
//!   (`if_tsresol`, powers of 10 or of 2) and offset (`if_tsoffset`); packets from Enhanced
//!   Packet Blocks and the obsolete Packet Blocks. Simple Packet Blocks carry no time and are
//!   refused; every other block (name resolution, statistics, custom) is skipped.
//! - classic pcap: the file header's magic gives the byte order and micro- or nanosecond times;
//!   every packet is on `can0`.
//! - Packets: LINKTYPE_CAN_SOCKETCAN (227), Linux's `struct can_frame` with the id in network
//!   byte order (tcpdump.org's link-type list): `CAN_EFF_FLAG` an extended id, `CAN_RTR_FLAG` a
//!   remote frame, `CAN_ERR_FLAG` an error frame with its classes in the id and details in the
//!   data. A packet on an interface of another link type, a CAN FD or CAN XL packet, or a packet
//!   shorter than its 8-byte header plus its length is refused.
//! - Every malformed or cut-off block is an [`Error::TraceRecord`] with its number and byte
//!   offset; a file that ends cleanly between blocks has been read whole.

use super::{Entry, Item};
use crate::Error;
use crate::Frame;
use crate::filter::CAN_ERR_FLAG;
use crate::time::Stamp;
use crate::trace::ErrorFrame;
use std::io::{self, Read};

/// The longest block read, bytes: far above a CAN packet's block (48 bytes), so that a corrupt
/// length cannot make the reader allocate gigabytes.
pub const MAX_BLOCK: usize = 1 << 20;
const LINKTYPE_CAN_SOCKETCAN: u16 = 227;
const CAN_EFF_FLAG: u32 = 0x8000_0000;
const CAN_RTR_FLAG: u32 = 0x4000_0000;
/// `canfd_frame`'s `flags` byte: `CANFD_FDF` says this 16-byte-headed packet is CAN FD.
const CANFD_FDF: u8 = 0x04;
/// `canxl_frame`'s `flags` byte: `CANXL_XLF`.
const CANXL_XLF: u8 = 0x80;

/// One interface of the current section.
#[derive(Clone, Debug)]
struct Interface {
    name: String,
    link: u16,
    /// Nanoseconds per timestamp unit as a fraction (numerator, denominator).
    unit: (u128, u128),
    /// `if_tsoffset`, seconds.
    offset: i64,
}

enum Kind {
    Pcapng { little: bool },
    Pcap { little: bool },
}

/// Reads a pcapng or pcap capture, one block at a time.
pub struct PcapngReader<R> {
    input: R,
    kind: Kind,
    interfaces: Vec<Interface>,
    /// Blocks (pcapng) or packets (pcap) read, the file header counting as the first.
    number: u64,
    offset: u64,
    buf: Vec<u8>,
    done: bool,
}

fn bad(record: u64, offset: u64, reason: impl Into<String>) -> Error {
    Error::TraceRecord {
        format: "pcapng",
        record,
        offset,
        reason: reason.into(),
    }
}

/// Reads exactly `buf.len()` bytes: `Ok(false)` at a clean end (nothing read), an error naming
/// how far in the file ends otherwise.
fn fill(input: &mut impl Read, buf: &mut [u8]) -> io::Result<Result<bool, usize>> {
    let mut got = 0;
    while got < buf.len() {
        match input.read(&mut buf[got..]) {
            Ok(0) => return Ok(if got == 0 { Ok(false) } else { Err(got) }),
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(Ok(true))
}

fn u16_of(b: &[u8], at: usize, little: bool) -> u16 {
    let v = [
        b.get(at).copied().unwrap_or(0),
        b.get(at + 1).copied().unwrap_or(0),
    ];
    if little {
        u16::from_le_bytes(v)
    } else {
        u16::from_be_bytes(v)
    }
}

fn u32_of(b: &[u8], at: usize, little: bool) -> u32 {
    let mut v = [0u8; 4];
    for (i, x) in v.iter_mut().enumerate() {
        *x = b.get(at + i).copied().unwrap_or(0);
    }
    if little {
        u32::from_le_bytes(v)
    } else {
        u32::from_be_bytes(v)
    }
}

impl<R: Read> PcapngReader<R> {
    /// Reads the file header: a pcapng Section Header Block or a pcap file header.
    pub fn new(mut input: R) -> Result<PcapngReader<R>, Error> {
        let mut head = [0u8; 4];
        match fill(&mut input, &mut head) {
            Ok(Ok(true)) => {}
            Ok(_) => return Err(bad(1, 0, "the file is empty or shorter than a file header")),
            Err(e) => return Err(bad(1, 0, format!("cannot read: {e}"))),
        }
        let mut reader = PcapngReader {
            input,
            kind: Kind::Pcapng { little: true },
            interfaces: Vec::new(),
            number: 0,
            offset: 0,
            buf: Vec::new(),
            done: false,
        };
        if head == [0x0A, 0x0D, 0x0D, 0x0A] {
            let mut first = [0u8; 8];
            first[..4].copy_from_slice(&head);
            match fill(&mut reader.input, &mut first[4..]) {
                Ok(Ok(true)) => {}
                Ok(_) => return Err(bad(1, 0, "the file ends inside a Section Header Block")),
                Err(e) => return Err(bad(1, 0, format!("cannot read: {e}"))),
            }
            reader.section(first)?;
            return Ok(reader);
        }
        let le = u32::from_le_bytes(head);
        let be = u32::from_be_bytes(head);
        let (little, nanos) = match (le, be) {
            (0xA1B2_C3D4, _) => (true, false),
            (0xA1B2_3C4D, _) => (true, true),
            (_, 0xA1B2_C3D4) => (false, false),
            (_, 0xA1B2_3C4D) => (false, true),
            _ => {
                return Err(bad(
                    1,
                    0,
                    format!("{head:02X?} is neither a pcapng Section Header Block nor a pcap magic number"),
                ));
            }
        };
        let mut rest = [0u8; 20];
        match fill(&mut reader.input, &mut rest) {
            Ok(Ok(true)) => {}
            Ok(_) => return Err(bad(1, 0, "the file ends inside the 24-byte pcap file header")),
            Err(e) => return Err(bad(1, 0, format!("cannot read: {e}"))),
        }
        // The link type is the low 16 bits of the last field (the upper ones say FCS lengths).
        let link = u16_of(&rest, 16, little);
        reader.kind = Kind::Pcap { little };
        reader.number = 1;
        reader.offset = 24;
        reader.interfaces.push(Interface {
            name: "can0".to_string(),
            link,
            unit: if nanos { (1, 1) } else { (1000, 1) },
            offset: 0,
        });
        Ok(reader)
    }

    /// Reads the rest of a block of `total` bytes whose first `block.len()` are read; checks its
    /// length at both ends; moves past it.
    fn rest_of_block(&mut self, block: &mut Vec<u8>, total: usize, little: bool) -> Result<(), Error> {
        let (number, offset) = (self.number + 1, self.offset);
        if total < 12 || !total.is_multiple_of(4) || total < block.len() {
            return Err(bad(
                number,
                offset,
                format!("block length {total} is not a multiple of 4 of at least 12"),
            ));
        }
        if total > MAX_BLOCK {
            return Err(bad(
                number,
                offset,
                format!("block length {total} is above {MAX_BLOCK}, the longest block read"),
            ));
        }
        let start = block.len();
        block.resize(total, 0);
        match fill(&mut self.input, &mut block[start..]) {
            Ok(Ok(true)) => {}
            Ok(Ok(false)) | Ok(Err(_)) => {
                return Err(bad(
                    number,
                    offset,
                    format!("the file ends inside this {total}-byte block"),
                ));
            }
            Err(e) => return Err(bad(number, offset, format!("cannot read: {e}"))),
        }
        let trailer = u32_of(block, total - 4, little) as usize;
        if trailer != total {
            return Err(bad(
                number,
                offset,
                format!("block length {total} at its start but {trailer} at its end"),
            ));
        }
        self.number = number;
        self.offset += total as u64;
        Ok(())
    }

    /// The next `N` bytes, the header of the next record (`what`): `None` at a clean end (no
    /// byte left), an error naming the record when the file ends inside it.
    fn header<const N: usize>(&mut self, what: &str) -> Result<Option<[u8; N]>, Error> {
        let (number, offset) = (self.number + 1, self.offset);
        let mut head = [0u8; N];
        match fill(&mut self.input, &mut head) {
            Ok(Ok(true)) => Ok(Some(head)),
            Ok(Ok(false)) => Ok(None),
            Ok(Err(got)) => Err(bad(
                number,
                offset,
                format!("the file ends {got} bytes into {what}"),
            )),
            Err(e) => Err(bad(number, offset, format!("cannot read: {e}"))),
        }
    }

    /// The next pcapng block: `None` at a clean end.
    fn next_block(&mut self) -> Result<Option<Item>, Error> {
        loop {
            let Kind::Pcapng { little } = self.kind else {
                return self.next_pcap();
            };
            let (number, offset) = (self.number + 1, self.offset);
            let Some(head) = self.header::<8>("a block header")? else {
                return Ok(None);
            };
            if head[..4] == [0x0A, 0x0D, 0x0D, 0x0A] {
                // A new section: its byte order may differ.
                self.section(head)?;
                continue;
            }
            let kind = u32_of(&head, 0, little);
            let total = u32_of(&head, 4, little) as usize;
            let mut block = std::mem::take(&mut self.buf);
            block.clear();
            block.extend_from_slice(&head);
            let read = self.rest_of_block(&mut block, total, little);
            let item = read.and_then(|()| self.block(kind, &block, number, offset, little));
            self.buf = block;
            if let Some(item) = item? {
                return Ok(Some(item));
            }
        }
    }

    /// A Section Header Block whose first 8 bytes are read: its byte order and length. The
    /// section's interfaces start anew.
    fn section(&mut self, head: [u8; 8]) -> Result<(), Error> {
        let (number, offset) = (self.number + 1, self.offset);
        let mut magic = [0u8; 4];
        match fill(&mut self.input, &mut magic) {
            Ok(Ok(true)) => {}
            Ok(_) => return Err(bad(number, offset, "the file ends inside a Section Header Block")),
            Err(e) => return Err(bad(number, offset, format!("cannot read: {e}"))),
        }
        let little = match u32::from_le_bytes(magic) {
            0x1A2B_3C4D => true,
            0x4D3C_2B1A => false,
            other => {
                return Err(bad(
                    number,
                    offset,
                    format!("byte-order magic {other:#010X} is not pcapng's 0x1A2B3C4D"),
                ));
            }
        };
        let total = u32_of(&head, 4, little) as usize;
        let mut block = Vec::with_capacity(32);
        block.extend_from_slice(&head);
        block.extend_from_slice(&magic);
        self.rest_of_block(&mut block, total, little)?;
        let major = u16_of(&block, 12, little);
        if major != 1 {
            return Err(bad(number, offset, format!("pcapng version {major}, not 1")));
        }
        self.kind = Kind::Pcapng { little };
        self.interfaces.clear();
        Ok(())
    }

    /// What one whole block gives.
    fn block(
        &mut self,
        kind: u32,
        b: &[u8],
        number: u64,
        offset: u64,
        little: bool,
    ) -> Result<Option<Item>, Error> {
        let body = &b[8..b.len() - 4];
        match kind {
            // Interface Description Block.
            1 => {
                if body.len() < 8 {
                    return Err(bad(
                        number,
                        offset,
                        "an Interface Description Block shorter than 20 bytes",
                    ));
                }
                let id = self.interfaces.len();
                let mut interface = Interface {
                    name: format!("can{id}"),
                    link: u16_of(body, 0, little),
                    unit: (1000, 1),
                    offset: 0,
                };
                for (code, value) in options(&body[8..], little).map_err(|r| bad(number, offset, r))? {
                    match code {
                        2 => {
                            let name = String::from_utf8_lossy(value);
                            let name = name.trim_end_matches('\0');
                            if !name.is_empty() {
                                interface.name = name
                                    .chars()
                                    .map(|c| if c.is_ascii_graphic() { c } else { '_' })
                                    .collect();
                            }
                        }
                        9 => {
                            let v = value.first().copied().unwrap_or(6);
                            interface.unit = resolution(v).ok_or_else(|| {
                                bad(
                                    number,
                                    offset,
                                    format!("if_tsresol {v:#04X} is finer than harvemu can count"),
                                )
                            })?;
                        }
                        14 if value.len() == 8 => {
                            let mut v = [0u8; 8];
                            v.copy_from_slice(value);
                            interface.offset = if little {
                                i64::from_le_bytes(v)
                            } else {
                                i64::from_be_bytes(v)
                            };
                        }
                        _ => {}
                    }
                }
                self.interfaces.push(interface);
                Ok(None)
            }
            // Enhanced Packet Block; the obsolete Packet Block has a 16-bit interface id and
            // drop count where the EPB has its 32-bit id.
            6 | 2 => {
                if body.len() < 20 {
                    return Err(bad(
                        number,
                        offset,
                        "a packet block shorter than its 20-byte header",
                    ));
                }
                let interface = if kind == 6 {
                    u32_of(body, 0, little) as usize
                } else {
                    usize::from(u16_of(body, 0, little))
                };
                let time = (u64::from(u32_of(body, 4, little)) << 32) | u64::from(u32_of(body, 8, little));
                let captured = u32_of(body, 12, little) as usize;
                let packet = body.get(20..20usize.saturating_add(captured)).ok_or_else(|| {
                    bad(
                        number,
                        offset,
                        format!("captured length {captured} runs past the block"),
                    )
                })?;
                self.packet(interface, time, packet, number, offset).map(Some)
            }
            3 => Err(bad(
                number,
                offset,
                "a Simple Packet Block carries no time: harvemu needs one per frame",
            )),
            _ => Ok(None),
        }
    }

    fn next_pcap(&mut self) -> Result<Option<Item>, Error> {
        let Kind::Pcap { little } = self.kind else {
            return Ok(None);
        };
        let (number, offset) = (self.number + 1, self.offset);
        let Some(head) = self.header::<16>("a packet header")? else {
            return Ok(None);
        };
        let captured = u32_of(&head, 8, little) as usize;
        if captured > MAX_BLOCK {
            return Err(bad(
                number,
                offset,
                format!("captured length {captured} is above {MAX_BLOCK}"),
            ));
        }
        let mut packet = std::mem::take(&mut self.buf);
        packet.clear();
        packet.resize(captured, 0);
        let read = match fill(&mut self.input, &mut packet) {
            Ok(Ok(_)) if captured == 0 => Ok(()),
            Ok(Ok(true)) => Ok(()),
            Ok(_) => Err(bad(
                number,
                offset,
                format!("the file ends inside this {captured}-byte packet"),
            )),
            Err(e) => Err(bad(number, offset, format!("cannot read: {e}"))),
        };
        self.number = number;
        self.offset += 16 + captured as u64;
        // The time as a count of the interface's units: seconds, then micro- or nanoseconds.
        let secs = u64::from(u32_of(&head, 0, little));
        let frac = u64::from(u32_of(&head, 4, little));
        let per_second = if self.interfaces.first().is_some_and(|i| i.unit == (1, 1)) {
            1_000_000_000
        } else {
            1_000_000
        };
        let item = read.and_then(|()| self.packet(0, secs * per_second + frac, &packet, number, offset));
        self.buf = packet;
        item.map(Some)
    }

    /// The item of a packet on `interface` at `time` of its units.
    fn packet(&self, interface: usize, time: u64, p: &[u8], number: u64, offset: u64) -> Result<Item, Error> {
        let i = self.interfaces.get(interface).ok_or_else(|| {
            bad(
                number,
                offset,
                format!("a packet on interface {interface}, which no Interface Description Block describes"),
            )
        })?;
        if i.link != LINKTYPE_CAN_SOCKETCAN {
            return Err(bad(
                number,
                offset,
                format!(
                    "a packet on {} of link type {}: harvemu reads SocketCAN CAN (LINKTYPE_CAN_SOCKETCAN, 227)",
                    i.name, i.link
                ),
            ));
        }
        let (num, den) = i.unit;
        let ns = u128::from(time) * num / den;
        let ns = i128::try_from(ns).unwrap_or(i128::MAX) + i128::from(i.offset) * 1_000_000_000;
        let at = u64::try_from(ns)
            .map(Stamp)
            .map_err(|_| bad(number, offset, "the time is before 1970 or too far in the future"))?;
        if p.len() < 8 {
            return Err(bad(
                number,
                offset,
                format!(
                    "a {}-byte packet: a SocketCAN frame has an 8-byte header",
                    p.len()
                ),
            ));
        }
        let can_id = u32::from_be_bytes([p[0], p[1], p[2], p[3]]);
        let len = usize::from(p[4]);
        let flags = p[5];
        if flags & CANXL_XLF != 0 {
            return Err(bad(number, offset, "a CAN XL frame: harvemu is CAN 2.0"));
        }
        if flags & CANFD_FDF != 0 || len > 8 || p.len() > 16 {
            return Err(bad(number, offset, "a CAN FD frame: harvemu is CAN 2.0"));
        }
        let entry = if can_id & CAN_ERR_FLAG != 0 {
            let mut data = [0u8; 8];
            let got = p.get(8..).unwrap_or_default();
            data[..got.len().min(8)].copy_from_slice(&got[..got.len().min(8)]);
            Entry::Error(Some(ErrorFrame {
                can_id: can_id & (CAN_ERR_FLAG | 0x1FFF_FFFF),
                data,
            }))
        } else if can_id & CAN_RTR_FLAG != 0 {
            let frame = if can_id & CAN_EFF_FLAG != 0 {
                crate::frame::extended_id(can_id & 0x1FFF_FFFF).map(crate::Id::Extended)
            } else {
                crate::frame::standard_id((can_id & 0x7FF) as u16).map(crate::Id::Standard)
            }
            .and_then(|id| Frame::new_remote(id, len));
            Entry::Frame(frame.map_err(|e| bad(number, offset, e.to_string()))?)
        } else {
            let data = p.get(8..8 + len).ok_or_else(|| {
                bad(
                    number,
                    offset,
                    format!("length {len} but {} data bytes captured", p.len() - 8),
                )
            })?;
            let frame = if can_id & CAN_EFF_FLAG != 0 {
                Frame::extended(can_id & 0x1FFF_FFFF, data)
            } else {
                Frame::base((can_id & 0x7FF) as u16, data)
            };
            Entry::Frame(frame.map_err(|e| bad(number, offset, e.to_string()))?)
        };
        Ok(Item {
            at,
            interface: i.name.clone(),
            entry,
        })
    }
}

/// Nanoseconds per unit for an `if_tsresol` value: 10^-v or 2^-v seconds; `None` when a unit
/// is finer than 2^-64 s or 10^-19 s (the count could not be kept).
fn resolution(v: u8) -> Option<(u128, u128)> {
    let exp = u32::from(v & 0x7F);
    if v & 0x80 == 0 {
        if exp <= 9 {
            Some((10u128.pow(9 - exp), 1))
        } else if exp <= 19 {
            Some((1, 10u128.pow(exp - 9)))
        } else {
            None
        }
    } else if exp <= 64 {
        Some((1_000_000_000, 1u128 << exp))
    } else {
        None
    }
}

/// A block's options: (code, value) until `opt_endofopt` or the end.
fn options(mut b: &[u8], little: bool) -> Result<Vec<(u16, &[u8])>, String> {
    let mut out = Vec::new();
    while b.len() >= 4 {
        let code = u16_of(b, 0, little);
        let len = usize::from(u16_of(b, 2, little));
        if code == 0 {
            break;
        }
        let value = b
            .get(4..4 + len)
            .ok_or_else(|| format!("option {code} of {len} bytes runs past its block"))?;
        out.push((code, value));
        b = b.get(4 + len.next_multiple_of(4)..).unwrap_or_default();
    }
    Ok(out)
}

impl<R: Read> Iterator for PcapngReader<R> {
    type Item = Result<(u64, Item), Error>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        match self.next_block() {
            Ok(Some(item)) => Some(Ok((self.number, item))),
            Ok(None) => {
                self.done = true;
                None
            }
            Err(e) => {
                self.done = true;
                Some(Err(e))
            }
        }
    }
}
