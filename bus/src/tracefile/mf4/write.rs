//! [`Mf4Writer`]: items out as MF4, each group's records a DZ block at a time.

use super::head::*;
use super::*;
use crate::filter::CAN_ERR_FLAG;
use crate::time::Stamp;
use crate::tracefile::{Entry, Item, ItemWriter};
use flate2::Compression;
use flate2::write::ZlibEncoder;
use std::io::{self, Seek, SeekFrom, Write};

/// One group being written.
struct Group {
    /// Bytes per record.
    size: usize,
    /// Records not yet written, at most `block` bytes.
    records: Vec<u8>,
    /// A full buffer: [`BLOCK_SIZE`] rounded down to whole records.
    block: usize,
    /// Where its data blocks are: the one thing that grows.
    blocks: Vec<u64>,
    /// Records in the data blocks written.
    cycles: u64,
    /// Where its DG's data link and its CG's cycle count are, to fill in at the end.
    data_link_at: u64,
    cycles_at: u64,
}

/// Writes items as an MF4 file (see the [module docs](super) for the layout).
pub struct Mf4Writer<W: Write + Seek> {
    inner: W,
    /// Where the file begins in `inner`: links count from there.
    base: u64,
    /// The file's length so far (a multiple of 8).
    end: u64,
    start: Stamp,
    groups: [Group; 3],
    /// The interfaces seen, bus channel 1 first.
    names: Vec<String>,
    deflated: Vec<u8>,
    /// A write failed part way: `inner` is not at the end.
    astray: bool,
    /// Set by `finish`: items are refused from then on.
    closing: bool,
    finished: bool,
}

/// `at - start` in seconds.
fn seconds(at: Stamp, start: Stamp) -> f64 {
    // Exact up to 2^53 ns (104 days); the division is then correctly rounded.
    (i128::from(at.0) - i128::from(start.0)) as f64 / 1e9
}

impl<W: Write + Seek> Mf4Writer<W> {
    /// Starts a file at `inner`'s position whose times count from `start` and writes everything
    /// but the data: ID, header, file history, the three groups' channels.
    pub fn new(mut inner: W, start: Stamp) -> io::Result<Mf4Writer<W>> {
        let base = inner.stream_position()?;
        let (out, places) = head(start);
        inner.write_all(&out)?;
        let groups = Kind::ALL.map(|kind| {
            let size = record_size(kind);
            let block = BLOCK_SIZE / size * size;
            let (data_link_at, cycles_at) = places[kind as usize];
            Group {
                size,
                records: Vec::new(),
                block,
                blocks: Vec::new(),
                cycles: 0,
                data_link_at,
                cycles_at,
            }
        });
        Ok(Mf4Writer {
            inner,
            base,
            end: out.len() as u64,
            start,
            groups,
            names: Vec::new(),
            deflated: Vec::new(),
            astray: false,
            closing: false,
            finished: false,
        })
    }

    /// The output, once the file is done with.
    pub fn into_inner(self) -> W {
        self.inner
    }

    /// The bus channel of interface `name`, numbering it when new.
    fn bus_channel(&mut self, name: &str) -> io::Result<u8> {
        let i = match self.names.iter().position(|n| n == name) {
            Some(i) => i,
            None if self.names.len() < 255 => {
                self.names.push(name.to_string());
                self.names.len() - 1
            }
            None => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!(
                        "a 256th interface, {}: an MF4 bus channel is one byte (1 to 255)",
                        crate::text::quote(name)
                    ),
                ));
            }
        };
        Ok(i as u8 + 1)
    }

    /// Writes group `g`'s buffered records as a DZ block.
    fn write_block(&mut self, g: usize) -> io::Result<()> {
        let group = &self.groups[g];
        let mut z = ZlibEncoder::new(std::mem::take(&mut self.deflated), Compression::default());
        z.write_all(&group.records)?;
        let deflated = z.finish()?;
        // Original block type DT, deflate, no parameter, original and deflated lengths.
        let mut head = Vec::with_capacity(48);
        let mut dz = b"DT".to_vec();
        dz.extend_from_slice(&[DEFLATE, 0, 0, 0, 0, 0]);
        dz.extend_from_slice(&(group.records.len() as u64).to_le_bytes());
        dz.extend_from_slice(&(deflated.len() as u64).to_le_bytes());
        put(&mut head, 0, b"DZ", &[], &dz);
        let length = HEADER + 24 + deflated.len() as u64;
        head[8..16].copy_from_slice(&length.to_le_bytes());
        let padding = length.next_multiple_of(8) - length;
        if self.astray {
            self.inner.seek(SeekFrom::Start(self.base + self.end))?;
            self.astray = false;
        }
        let written = self
            .inner
            .write_all(&head)
            .and_then(|()| self.inner.write_all(&deflated))
            .and_then(|()| self.inner.write_all(&[0; 8][..padding as usize]));
        self.deflated = deflated;
        self.deflated.clear();
        if written.is_err() {
            // Part of the block may be out: the next one starts over at the end.
            self.astray = true;
        }
        written?;
        let group = &mut self.groups[g];
        group.blocks.push(self.end);
        group.cycles += (group.records.len() / group.size) as u64;
        group.records.clear();
        self.end += length + padding;
        Ok(())
    }

    /// Writes group `g`'s DL block (its data blocks, equal length) and an HL block over it;
    /// the HL block's offset.
    fn write_list(&mut self, g: usize) -> io::Result<u64> {
        let group = &self.groups[g];
        let count = group.blocks.len() as u64;
        let dl = self.end;
        let links = 1 + count;
        let length = HEADER + 8 * links + 16;
        let mut out = Vec::with_capacity(64 << 10);
        out.extend_from_slice(b"##DL\0\0\0\0");
        out.extend_from_slice(&length.to_le_bytes());
        out.extend_from_slice(&links.to_le_bytes());
        out.extend_from_slice(&0u64.to_le_bytes());
        for &block in &group.blocks {
            if out.len() >= 64 << 10 {
                self.inner.write_all(&out)?;
                out.clear();
            }
            out.extend_from_slice(&block.to_le_bytes());
        }
        out.extend_from_slice(&[EQUAL_LENGTH, 0, 0, 0]);
        out.extend_from_slice(&u32::try_from(count).unwrap_or(u32::MAX).to_le_bytes());
        out.extend_from_slice(&(group.block as u64).to_le_bytes());
        let hl = dl + length;
        put(
            &mut out,
            0,
            b"HL",
            &[dl],
            &[EQUAL_LENGTH, 0, DEFLATE, 0, 0, 0, 0, 0],
        );
        self.inner.write_all(&out)?;
        self.end = hl + HEADER + 16;
        Ok(hl)
    }

    /// Writes `value` at `at` (from the file's start).
    fn patch(&mut self, at: u64, value: &[u8]) -> io::Result<()> {
        self.inner.seek(SeekFrom::Start(self.base + at))?;
        self.inner.write_all(value)
    }
}

impl<W: Write + Seek> ItemWriter for Mf4Writer<W> {
    fn write(&mut self, item: &Item) -> io::Result<()> {
        if self.closing {
            return Err(io::Error::other("the MF4 file has been finished"));
        }
        let bus = self.bus_channel(&item.interface)?;
        let mut r = [0u8; RECORD];
        r[..8].copy_from_slice(&seconds(item.at, self.start).to_le_bytes());
        r[8] = bus;
        let kind = match &item.entry {
            Entry::Frame(f) => {
                r[9..13].copy_from_slice(&f.raw_id().to_le_bytes());
                r[13] = u8::from(f.is_extended());
                r[14] = f.dlc();
                if f.is_remote() {
                    Kind::Remote
                } else {
                    r[15] = f.dlc();
                    r[16..16 + f.data().len()].copy_from_slice(f.data());
                    Kind::Data
                }
            }
            Entry::Error(e) => {
                if let Some(e) = e {
                    let classes = e.can_id & !CAN_ERR_FLAG & 0x1FFF_FFFF;
                    r[9..13].copy_from_slice(&classes.to_le_bytes());
                    r[13] = u8::from(classes > 0x7FF);
                    r[14] = 8;
                    r[15] = 8;
                    r[16..24].copy_from_slice(&e.data);
                }
                Kind::Error
            }
        };
        let g = kind as usize;
        let group = &self.groups[g];
        if group.records.len() + group.size > group.block {
            self.write_block(g)?;
        }
        // The buffer grows by doubling to at most 1 MiB: a full block.
        let group = &mut self.groups[g];
        group.records.extend_from_slice(&r[..group.size]);
        Ok(())
    }

    /// Passes on what is written; buffered records wait for a full block or the end (a short
    /// block can only be the last of a list of equal-length blocks).
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }

    /// Writes what is buffered and the lists, fills in the links, counts and names and makes
    /// the file finished. After an I/O error it can be called again: it starts over from the
    /// last block written whole.
    fn finish(&mut self) -> io::Result<()> {
        if self.finished {
            return Ok(());
        }
        self.closing = true;
        self.inner.seek(SeekFrom::Start(self.base + self.end))?;
        self.astray = false;
        let mut lists = [0u64; 3];
        for g in 0..3 {
            if !self.groups[g].records.is_empty() {
                self.write_block(g)?;
            }
        }
        for (g, list) in lists.iter_mut().enumerate() {
            if !self.groups[g].blocks.is_empty() {
                *list = self.write_list(g)?;
            }
        }
        let names = self.end;
        let mut out = Vec::new();
        put(&mut out, names, b"MD", &[], &text(&comment(&self.names)));
        self.inner.write_all(&out)?;
        self.end += out.len() as u64;
        for (g, list) in lists.iter().enumerate() {
            let (data_link_at, cycles_at, cycles) = {
                let group = &self.groups[g];
                (group.data_link_at, group.cycles_at, group.cycles)
            };
            self.patch(data_link_at, &list.to_le_bytes())?;
            self.patch(cycles_at, &cycles.to_le_bytes())?;
        }
        self.patch(COMMENT_AT, &names.to_le_bytes())?;
        self.patch(0, b"MDF     ")?;
        self.patch(60, &[0; 4])?;
        self.inner.seek(SeekFrom::Start(self.base + self.end))?;
        self.inner.flush()?;
        self.finished = true;
        Ok(())
    }
}
