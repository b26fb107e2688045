//! A data group's data as a stream of bytes: its DT and DZ blocks, alone or listed by DL blocks
//! (under an HL block or not), one block at a time.

use super::blocks::{Block, Input};
use super::*;
use crate::Error;
use flate2::read::ZlibDecoder;
use std::io::{Read, Seek};

/// The smallest DL block (header, next link, one data link, flags and count), which bounds how
/// many the file can hold.
const MIN_DL: u64 = HEADER + 16 + 8;

/// Where the bytes come from, and what of them is read.
pub(super) struct Data {
    /// The data group's data link, until it is opened, and the DG block's offset.
    first: u64,
    dg: u64,
    /// The data blocks of the DL block being read, and the next one to take.
    links: Vec<u64>,
    next: usize,
    /// The DL block after that one, and the one before it.
    next_list: u64,
    list_at: u64,
    /// DL blocks read, to end a loop.
    lists: u64,
    /// The last data block opened: the next must come after it in the file.
    last: u64,
    /// Bytes of the block being read (a DZ block's all, a DT block's next window), and how many
    /// of them are taken.
    buf: Vec<u8>,
    pos: usize,
    /// A DT block's unread data: from, to.
    window: Option<(u64, u64)>,
    /// A transposed block's bytes before they are put back in order.
    scratch: Vec<u8>,
    /// The data block being read (its offset), for messages.
    pub(super) block: u64,
}

impl Data {
    /// The data a data group's data link leads to.
    pub(super) fn new(link: u64, dg: u64) -> Data {
        Data {
            first: link,
            dg,
            list_at: dg,
            links: Vec::new(),
            next: 0,
            next_list: 0,
            lists: 0,
            last: 0,
            buf: Vec::new(),
            pos: 0,
            window: None,
            scratch: Vec::new(),
            block: link,
        }
    }

    /// Appends the next `n` bytes to `out`, fewer where the data ends: how many.
    pub(super) fn take<R: Read + Seek>(
        &mut self,
        input: &mut Input<R>,
        out: &mut Vec<u8>,
        n: usize,
    ) -> Result<usize, Error> {
        let mut got = 0;
        while got < n {
            let rest = self.buf.get(self.pos..).unwrap_or(&[]);
            if rest.is_empty() {
                if !self.refill(input)? {
                    break;
                }
                continue;
            }
            let k = rest.len().min(n - got);
            out.extend_from_slice(&rest[..k]);
            self.pos += k;
            got += k;
        }
        Ok(got)
    }

    /// Passes over the next `n` bytes, fewer where the data ends: how many.
    pub(super) fn skip<R: Read + Seek>(&mut self, input: &mut Input<R>, n: u64) -> Result<u64, Error> {
        let mut got = 0u64;
        while got < n {
            let rest = self.buf.len().saturating_sub(self.pos) as u64;
            if rest == 0 {
                if !self.refill(input)? {
                    break;
                }
                continue;
            }
            let k = rest.min(n - got);
            self.pos += k as usize;
            got += k;
        }
        Ok(got)
    }

    /// Puts the next bytes in `buf`: false at the end of the data.
    fn refill<R: Read + Seek>(&mut self, input: &mut Input<R>) -> Result<bool, Error> {
        self.buf.clear();
        self.pos = 0;
        if let Some((from, to)) = self.window.filter(|(from, to)| from < to) {
            let n = (to - from).min(WINDOW as u64);
            self.buf = input.bytes_at(from, n as usize, self.block)?;
            self.window = Some((from + n, to));
            return Ok(true);
        }
        self.window = None;
        let Some(block) = self.next_block(input)? else {
            return Ok(false);
        };
        self.block = block.offset;
        if block.id == *b"DT" {
            self.window = Some((block.data_at(), block.data_at() + block.data_len()));
        } else {
            self.inflate(input, &block)?;
        }
        Ok(true)
    }

    /// The next DT or DZ block's header.
    fn next_block<R: Read + Seek>(&mut self, input: &mut Input<R>) -> Result<Option<Block>, Error> {
        let what = "the data group's data";
        loop {
            if self.first != 0 {
                let link = std::mem::take(&mut self.first);
                let block = input.block(link, self.dg, &[b"DT", b"DZ", b"DL", b"HL"], 24, what)?;
                match &block.id {
                    b"DL" => self.list(input, block)?,
                    b"HL" => (self.next_list, self.list_at) = (block.link(0), block.offset),
                    _ => return self.data_block(input, block).map(Some),
                }
            } else if let Some(&link) = self.links.get(self.next) {
                self.next += 1;
                if link != 0 {
                    let block = input.block(
                        link,
                        self.list_at,
                        &[b"DT", b"DZ"],
                        24,
                        "a data block of a DL block's",
                    )?;
                    return self.data_block(input, block).map(Some);
                }
            } else if self.next_list != 0 {
                let link = std::mem::take(&mut self.next_list);
                let block = input.block(link, self.list_at, &[b"DL"], 0, "the next DL block")?;
                self.list(input, block)?;
            } else {
                return Ok(None);
            }
        }
    }

    /// Takes the data blocks a DL block lists.
    fn list<R: Read + Seek>(&mut self, input: &mut Input<R>, mut block: Block) -> Result<(), Error> {
        self.lists += 1;
        if self.lists > input.len / MIN_DL + 1 {
            return Err(input.error(
                block.offset,
                "more DL blocks in a list than the file can hold (a loop)",
            ));
        }
        self.next_list = block.link(0);
        self.list_at = block.offset;
        block.links.drain(..block.links.len().min(1));
        self.links = block.links;
        self.next = 0;
        Ok(())
    }

    /// Checks that a data block comes after the one before it: no block is read twice.
    fn data_block<R: Read + Seek>(&mut self, input: &mut Input<R>, block: Block) -> Result<Block, Error> {
        if block.offset <= self.last {
            return Err(input.error(
                block.offset,
                format!(
                    "data block listed after the one at byte {}: data blocks must come in file order",
                    self.last
                ),
            ));
        }
        self.last = block.offset;
        Ok(block)
    }

    /// Inflates a DZ block into `buf`.
    fn inflate<R: Read + Seek>(&mut self, input: &mut Input<R>, block: &Block) -> Result<(), Error> {
        let d = &block.data;
        if d.len() < 24 {
            return Err(input.error(block.offset, "DZ block shorter than its header"));
        }
        let (original, zip, param) = (&d[..2], d[2], u32_at(d, 4));
        let (size, deflated) = (u64_at(d, 8), u64_at(d, 16));
        if original != b"DT" {
            return Err(input.error(
                block.offset,
                format!(
                    "DZ block of a {} block: only DT blocks are read",
                    blocks::shown(original)
                ),
            ));
        }
        if zip != DEFLATE && zip != TRANSPOSED_DEFLATE {
            return Err(input.error(
                block.offset,
                format!("DZ block of zip type {zip}: only deflate (0, 1) is read"),
            ));
        }
        if size > MAX_BLOCK {
            return Err(input.error(
                block.offset,
                format!("DZ block inflates to {size} bytes, more than the {MAX_BLOCK}-byte limit"),
            ));
        }
        if deflated > block.data_len() - 24 {
            return Err(input.error(
                block.offset,
                format!(
                    "DZ block holds {deflated} deflated bytes in {} bytes",
                    block.data_len() - 24
                ),
            ));
        }
        let at = block.data_at() + 24;
        input
            .inner
            .seek(std::io::SeekFrom::Start(at))
            .map_err(|e| input.io_error(block.offset, e))?;
        let mut z = ZlibDecoder::new((&mut input.inner).take(deflated)).take(size + 1);
        let out = if zip == TRANSPOSED_DEFLATE {
            &mut self.scratch
        } else {
            &mut self.buf
        };
        out.clear();
        if let Err(e) = z.read_to_end(out) {
            return Err(input.error(block.offset, format!("DZ block cannot be inflated: {e}")));
        }
        if out.len() as u64 != size {
            let got = out.len();
            return Err(input.error(
                block.offset,
                format!("DZ block inflates to {got} bytes, not {size}"),
            ));
        }
        if zip == TRANSPOSED_DEFLATE {
            // Stored column by column: `param` columns (bytes per record) of `rows` rows, then
            // what is left over as it is (asammdf's layout).
            let cols = param as usize;
            if cols == 0 {
                return Err(input.error(block.offset, "transposed DZ block of 0 columns"));
            }
            let rows = self.scratch.len() / cols;
            self.buf.clear();
            self.buf.reserve(self.scratch.len());
            for r in 0..rows {
                self.buf.extend((0..cols).map(|c| self.scratch[c * rows + r]));
            }
            self.buf.extend_from_slice(&self.scratch[rows * cols..]);
        }
        Ok(())
    }
}
