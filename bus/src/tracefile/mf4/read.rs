//! [`Mf4Reader`]: MF4 in, the bus-logging groups merged by time.

use super::blocks::{Input, bad};
use super::data::Data;
use super::groups::{Field, Layout, Length, find, names};
use super::*;
use crate::filter::CAN_ERR_FLAG;
use crate::time::Stamp;
use crate::trace::ErrorFrame;
use crate::tracefile::{Entry, Item};
use crate::{Error, Frame, Id, extended_id, standard_id};
use std::io::{Read, Seek, SeekFrom};

/// One channel group's records, one at a time.
struct Stream {
    layout: Layout,
    data: Data,
    /// The record being read.
    record: Vec<u8>,
    /// Records taken so far.
    taken: u64,
    /// The next item, once read.
    head: Option<Item>,
    done: bool,
}

/// Reads an MF4 file's CAN bus logging (see the [module docs](super)), giving each frame and
/// error frame as an [`Item`] with its number in time order.
pub struct Mf4Reader<R: Read + Seek> {
    input: Input<R>,
    start: Stamp,
    streams: Vec<Stream>,
    /// Interface names by bus channel.
    names: Vec<Option<String>>,
    number: u64,
    done: bool,
}

impl<R: Read + Seek> Mf4Reader<R> {
    /// Reads the ID and header blocks and finds the CAN bus-logging groups.
    pub fn new(mut input: R) -> Result<Mf4Reader<R>, Error> {
        let id = |reason: String| bad(0, 0, reason);
        let len = input
            .seek(SeekFrom::End(0))
            .and_then(|len| input.seek(SeekFrom::Start(0)).map(|_| len))
            .map_err(|e| id(format!("cannot read: {e}")))?;
        let mut head = vec![0u8; len.min(ID_SIZE) as usize];
        input
            .read_exact(&mut head)
            .map_err(|e| id(format!("cannot read: {e}")))?;
        if len == 0 {
            return Err(id("the file is empty: no MDF ID block".into()));
        }
        let unfinished = b"UnFinMF ".starts_with(&head[..head.len().min(8)]);
        if !b"MDF     ".starts_with(&head[..head.len().min(8)]) && !unfinished {
            return Err(id(format!(
                "not an MDF file: it starts with {}, not \"MDF     \"",
                crate::text::quote(&String::from_utf8_lossy(&head[..head.len().min(8)]))
            )));
        }
        if len < ID_SIZE {
            return Err(id(format!(
                "the file ends {len} bytes into its {ID_SIZE}-byte ID block"
            )));
        }
        if unfinished {
            return Err(id(
                "the file is not finalised (ID \"UnFinMF \"): the program writing it did not finish it"
                    .into(),
            ));
        }
        if !head[8..].starts_with(b"4.") {
            return Err(id(format!(
                "MDF version {}: only MDF 4 is read",
                crate::text::quote(String::from_utf8_lossy(&head[8..16]).trim())
            )));
        }
        let mut input = Input {
            inner: input,
            len,
            blocks: 0,
        };
        let hd = input.block(ID_SIZE, 0, &[b"HD"], 8, "the header block")?;
        let start = Stamp(u64_at(&hd.data, 0));
        let names = names(&input.text(hd.link(5), hd.offset, "the header's comment")?);
        let layouts = find(&mut input, &hd)?;
        if layouts.is_empty() {
            return Err(bad(
                input.blocks,
                0,
                "no CAN bus logging in the file: no channel group of CAN_DataFrame, CAN_ErrorFrame or CAN_RemoteFrame",
            ));
        }
        let streams = layouts
            .into_iter()
            .map(|layout| Stream {
                data: Data::new(layout.data, layout.dg),
                record: Vec::with_capacity(layout.size as usize),
                layout,
                taken: 0,
                head: None,
                done: false,
            })
            .collect();
        Ok(Mf4Reader {
            input,
            start,
            streams,
            names,
            number: 0,
            done: false,
        })
    }

    /// The header's start time, which record times count from.
    pub fn start(&self) -> Stamp {
        self.start
    }

    /// The next item of all the groups: the earliest of their next ones.
    fn step(&mut self) -> Result<Option<Item>, Error> {
        for s in &mut self.streams {
            if s.head.is_none() && !s.done {
                s.head = s.next(&mut self.input, self.start, &self.names)?;
                s.done = s.head.is_none();
            }
        }
        let first = self
            .streams
            .iter_mut()
            .filter(|s| s.head.is_some())
            .min_by_key(|s| (s.head.as_ref().map(|h| h.at), s.layout.kind));
        Ok(first.and_then(|s| s.head.take()))
    }
}

impl Stream {
    /// The next record of this group as an item, `None` after the last.
    fn next<R: Read + Seek>(
        &mut self,
        input: &mut Input<R>,
        start: Stamp,
        names: &[Option<String>],
    ) -> Result<Option<Item>, Error> {
        let l = &self.layout;
        if self.taken == l.cycles {
            return Ok(None);
        }
        self.taken += 1;
        let n = self.taken;
        if l.id_size != 0 {
            self.skip_others(input)?;
        }
        let l = &self.layout;
        self.record.clear();
        let got = self.data.take(input, &mut self.record, l.size as usize)?;
        if (got as u64) < l.size {
            return Err(self.ends(got));
        }
        let wrong = |reason: String| bad(n, self.data.block, format!("record {n} of {}: {reason}", l.what));
        let item = decode(l, &self.record, n - 1, start, names).map_err(wrong)?;
        Ok(Some(item))
    }

    /// The error for data that ends `got` bytes into the record being read.
    fn ends(&self, got: usize) -> Error {
        let (l, n) = (&self.layout, self.taken);
        let reason = if got == 0 {
            format!(
                "{}: the data ends after {} of its {} records",
                l.what,
                n - 1,
                l.cycles
            )
        } else {
            format!(
                "{}: the data ends {got} bytes into record {n} of {}",
                l.what, l.cycles
            )
        };
        bad(n, self.data.block, reason)
    }

    /// In an unsorted data group: passes over other groups' records up to and including the
    /// next record id of this group.
    fn skip_others<R: Read + Seek>(&mut self, input: &mut Input<R>) -> Result<(), Error> {
        let size = usize::from(self.layout.id_size);
        loop {
            self.record.clear();
            let got = self.data.take(input, &mut self.record, size)?;
            if got < size {
                return Err(self.ends(got));
            }
            let id = u64_at(&self.record, 0);
            if id == self.layout.record_id {
                return Ok(());
            }
            let length = match self.layout.others.iter().find(|(other, _)| *other == id) {
                Some((_, Length::Fixed(n))) => *n,
                Some((_, Length::Vlsd)) => {
                    self.record.clear();
                    let got = self.data.take(input, &mut self.record, 4)?;
                    if got < 4 {
                        return Err(self.ends(got));
                    }
                    u64::from(u32_at(&self.record, 0))
                }
                None => {
                    let what = &self.layout.what;
                    let reason = format!("{what}: record id {id} is no channel group's of its data group");
                    return Err(bad(self.taken, self.data.block, reason));
                }
            };
            if self.data.skip(input, length)? < length {
                let what = &self.layout.what;
                let reason = format!("{what}: the data ends inside a record of record id {id}");
                return Err(bad(self.taken, self.data.block, reason));
            }
        }
    }
}

/// The unsigned value of an integer field, 0 for a field the record does not have.
fn uint(record: &[u8], f: &Option<Field>) -> u64 {
    let Some(f) = f else { return 0 };
    let n = (u32::from(f.bit) + f.bits).div_ceil(8) as usize;
    let bytes = record.get(f.byte..).and_then(|r| r.get(..n)).unwrap_or(&[]);
    let raw = if matches!(f.data_type, UINT_BE | INT_BE) {
        bytes.iter().fold(0u128, |v, &b| (v << 8) | u128::from(b))
    } else {
        bytes.iter().rev().fold(0u128, |v, &b| (v << 8) | u128::from(b))
    };
    let mask = if f.bits >= 64 {
        u64::MAX
    } else {
        (1u64 << f.bits) - 1
    };
    (raw >> f.bit) as u64 & mask
}

/// The record's time as seconds since the header's start.
fn seconds(l: &Layout, record: &[u8], index: u64) -> f64 {
    let m = &l.master;
    let raw = match &m.field {
        None => index as f64,
        Some(f) => {
            let bytes = record
                .get(f.byte..)
                .and_then(|r| r.get(..f.bits as usize / 8))
                .unwrap_or(&[]);
            match (f.data_type, bytes.len()) {
                (FLOAT_LE, 8) => f64::from_le_bytes(bytes.try_into().unwrap_or_default()),
                (FLOAT_BE, 8) => f64::from_be_bytes(bytes.try_into().unwrap_or_default()),
                (FLOAT_LE, 4) => f64::from(f32::from_le_bytes(bytes.try_into().unwrap_or_default())),
                (FLOAT_BE, 4) => f64::from(f32::from_be_bytes(bytes.try_into().unwrap_or_default())),
                _ => uint(record, &Some(*f)) as f64,
            }
        }
    };
    if m.offset == 0.0 && m.factor == 1.0 {
        raw
    } else {
        m.offset + m.factor * raw
    }
}

/// `t` seconds in nanoseconds, rounded to the nearest (halves away from zero), computed
/// exactly from the float's bits; `None` if not finite or beyond ±2^64 ns.
pub(super) fn nanos(t: f64) -> Option<i128> {
    if !t.is_finite() {
        return None;
    }
    let bits = t.to_bits();
    let exponent = ((bits >> 52) & 0x7FF) as i32;
    let fraction = bits & ((1 << 52) - 1);
    let (mantissa, shift) = if exponent == 0 {
        (fraction, -1074)
    } else {
        (fraction | 1 << 52, exponent - 1075)
    };
    // |t| = mantissa * 2^shift seconds; mantissa * 1e9 < 2^83.
    let scaled = u128::from(mantissa) * 1_000_000_000;
    let ns = if shift >= 0 {
        if shift > 44 {
            return None;
        }
        scaled << shift
    } else if shift < -100 {
        0
    } else {
        let s = shift.unsigned_abs();
        (scaled + (1 << (s - 1))) >> s
    };
    let ns = i128::try_from(ns).ok().filter(|&n| n <= i128::from(u64::MAX))?;
    Some(if t < 0.0 { -ns } else { ns })
}

/// The item a record holds.
pub(super) fn decode(
    l: &Layout,
    r: &[u8],
    index: u64,
    start: Stamp,
    names: &[Option<String>],
) -> Result<Item, String> {
    let t = seconds(l, r, index);
    let at = nanos(t)
        .map(|ns| ns + i128::from(start.0))
        .and_then(|ns| u64::try_from(ns).ok())
        .ok_or_else(|| {
            // Far out, in scientific notation: not hundreds of digits.
            let t = if t.abs() < 1e12 {
                t.to_string()
            } else {
                format!("{t:e}")
            };
            format!("time {t} s after the start {start} is not between 1970 and 2554")
        })?;
    let f = &l.fields;
    let id = uint(r, &f.id);
    let dlc = uint(r, &f.dlc);
    let length = if f.length.is_some() {
        uint(r, &f.length)
    } else {
        dlc.min(8)
    };
    if uint(r, &f.edl) != 0 || (l.kind != Kind::Remote && length > 8) {
        return Err(format!("a CAN FD frame ({length} bytes); harvemu is CAN 2.0"));
    }
    let mut data = [0u8; 8];
    // A remote frame has no data, whatever its DataLength says (which may pass 8).
    if let Some(b) = f.bytes.as_ref().filter(|_| l.kind != Kind::Remote) {
        let stored = (b.bits / 8) as usize;
        // At most 8: a longer length was refused above.
        let n = if l.kind == Kind::Error {
            (length as usize).min(stored)
        } else {
            length as usize
        };
        if n > stored {
            return Err(format!("DataLength {length} but DataBytes holds {stored} bytes"));
        }
        let bytes = r.get(b.byte..).and_then(|r| r.get(..n)).unwrap_or(&[]);
        data[..bytes.len()].copy_from_slice(bytes);
    }
    let extended = uint(r, &f.ide) != 0 || id & 0x8000_0000 != 0;
    let raw = (id & 0x1FFF_FFFF) as u32;
    let ident = || -> Result<Id, String> {
        Ok(if extended {
            extended_id(raw).map_err(|e| e.to_string())?.into()
        } else {
            let raw = u16::try_from(raw)
                .map_err(|_| format!("base identifier 0x{raw:X} does not fit in 11 bits"))?;
            standard_id(raw).map_err(|e| e.to_string())?.into()
        })
    };
    let entry = match l.kind {
        Kind::Data => {
            Entry::Frame(Frame::new_data(ident()?, &data[..length as usize]).map_err(|e| e.to_string())?)
        }
        Kind::Remote => {
            let dlc = if f.dlc.is_some() { dlc } else { length };
            let dlc = usize::try_from(dlc).unwrap_or(usize::MAX);
            Entry::Frame(Frame::new_remote(ident()?, dlc).map_err(|e| format!("remote frame: {e}"))?)
        }
        Kind::Error if raw == 0 && dlc == 0 => Entry::Error(None),
        Kind::Error => Entry::Error(Some(ErrorFrame {
            can_id: CAN_ERR_FLAG | raw,
            data,
        })),
    };
    let bus = uint(r, &f.bus);
    let interface = match usize::try_from(bus).ok().and_then(|b| names.get(b)) {
        Some(Some(name)) => name.clone(),
        _ => format!("can{bus}"),
    };
    Ok(Item {
        at: Stamp(at),
        interface,
        entry,
    })
}

impl<R: Read + Seek> Iterator for Mf4Reader<R> {
    type Item = Result<(u64, Item), Error>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        match self.step() {
            Ok(Some(item)) => {
                self.number += 1;
                Some(Ok((self.number, item)))
            }
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
