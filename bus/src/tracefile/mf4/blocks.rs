//! Reading blocks: every link followed and every block read passes the checks here.

use super::*;
use crate::Error;
use std::io::{self, Read, Seek, SeekFrom};

/// The longest text read from a TX or MD block; the rest of a longer one is left unread.
pub(super) const MAX_TEXT: u64 = 4 << 20;

/// A bad input: `record` and `offset` as the module docs say.
pub(super) fn bad(record: u64, offset: u64, reason: impl Into<String>) -> Error {
    Error::TraceRecord {
        format: "MF4",
        record,
        offset,
        reason: reason.into(),
    }
}

/// The file being read, its length and how many blocks have been read from it.
pub(super) struct Input<R> {
    pub(super) inner: R,
    pub(super) len: u64,
    pub(super) blocks: u64,
}

/// One block as read: its header, its links and (up to a limit) its data.
pub(super) struct Block {
    pub(super) offset: u64,
    pub(super) id: [u8; 2],
    pub(super) length: u64,
    pub(super) links: Vec<u64>,
    /// The data section's first bytes, as many as asked for.
    pub(super) data: Vec<u8>,
}

impl Block {
    /// Link `i`, 0 when the block has no such link.
    pub(super) fn link(&self, i: usize) -> u64 {
        self.links.get(i).copied().unwrap_or(0)
    }

    /// Where the data section begins in the file.
    pub(super) fn data_at(&self) -> u64 {
        self.offset + HEADER + 8 * self.links.len() as u64
    }

    /// The data section's length.
    pub(super) fn data_len(&self) -> u64 {
        self.length - HEADER - 8 * self.links.len() as u64
    }
}

/// `id` as text for a message: `DZ`, or the bytes when they are not letters.
pub(super) fn shown(id: &[u8]) -> String {
    if id.iter().all(u8::is_ascii_alphanumeric) {
        String::from_utf8_lossy(id).into_owned()
    } else {
        format!("{id:02X?}")
    }
}

impl<R: Read + Seek> Input<R> {
    /// An error about the block read last, at `offset`.
    pub(super) fn error(&self, offset: u64, reason: impl std::fmt::Display) -> Error {
        bad(
            self.blocks,
            offset,
            format!("block {} read: {reason}", self.blocks),
        )
    }

    /// Reads `n` bytes at `offset` (checked to be inside the file by the caller).
    pub(super) fn bytes_at(&mut self, offset: u64, n: usize, at_block: u64) -> Result<Vec<u8>, Error> {
        let mut buf = vec![0u8; n];
        self.inner
            .seek(SeekFrom::Start(offset))
            .and_then(|_| self.inner.read_exact(&mut buf))
            .map_err(|e| self.io_error(at_block, e))?;
        Ok(buf)
    }

    pub(super) fn io_error(&self, offset: u64, e: io::Error) -> Error {
        if e.kind() == io::ErrorKind::UnexpectedEof {
            self.error(offset, "the file ends inside it (cut off?)")
        } else {
            self.error(offset, format!("cannot read: {e}"))
        }
    }

    /// Reads the block `link` (a link of the block at `from`) points to, which must be one of
    /// `ids`, with at most `data` bytes of its data section; `what` names it in messages (`a
    /// channel group`). A link outside the file is reported at `from`.
    pub(super) fn block(
        &mut self,
        link: u64,
        from: u64,
        ids: &[&[u8; 2]],
        data: u64,
        what: &str,
    ) -> Result<Block, Error> {
        self.blocks += 1;
        let want = || {
            ids.iter()
                .map(|id| shown(&id[..]))
                .collect::<Vec<_>>()
                .join(" or ")
        };
        if link < ID_SIZE || link.checked_add(HEADER).is_none_or(|end| end > self.len) {
            return Err(self.error(
                from,
                format!(
                    "{what} ({} block) is linked at byte {link}, outside the file's {} bytes (cut off?)",
                    want(),
                    self.len
                ),
            ));
        }
        let head = self.bytes_at(link, HEADER as usize, link)?;
        let id = [byte(&head, 2), byte(&head, 3)];
        if !head.starts_with(b"##") || !ids.contains(&&id) {
            return Err(self.error(
                link,
                format!(
                    "{what} should be a {} block, not {}",
                    want(),
                    shown(head.get(..4).unwrap_or(&[]))
                ),
            ));
        }
        let length = u64_at(&head, 8);
        let count = u64_at(&head, 16);
        let links_end = count.checked_mul(8).and_then(|n| n.checked_add(HEADER));
        let Some(links_end) = links_end.filter(|&end| end <= length && end <= MAX_BLOCK) else {
            return Err(self.error(
                link,
                format!(
                    "{} block: {count} links do not fit in its length of {length} bytes",
                    shown(&id)
                ),
            ));
        };
        if link.checked_add(length).is_none_or(|end| end > self.len) {
            return Err(self.error(
                link,
                format!(
                    "{} block of {length} bytes runs past the end of the file ({} bytes; cut off?)",
                    shown(&id),
                    self.len
                ),
            ));
        }
        let links = self.bytes_at(link + HEADER, (links_end - HEADER) as usize, link)?;
        let links = links.chunks_exact(8).map(|c| u64_at(c, 0)).collect();
        let n = (length - links_end).min(data);
        let data = self.bytes_at(link + links_end, n as usize, link)?;
        Ok(Block {
            offset: link,
            id,
            length,
            links,
            data,
        })
    }

    /// The text of the TX or MD block at `link` (up to [`MAX_TEXT`] bytes, up to its first
    /// zero byte, bad UTF-8 replaced); empty for no link.
    pub(super) fn text(&mut self, link: u64, from: u64, what: &str) -> Result<String, Error> {
        if link == 0 {
            return Ok(String::new());
        }
        let block = self.block(link, from, &[b"TX", b"MD"], MAX_TEXT, what)?;
        let end = block
            .data
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(block.data.len());
        Ok(String::from_utf8_lossy(block.data.get(..end).unwrap_or(&[])).into_owned())
    }

    /// Reads the list of blocks that begins at `first` (a link of the block at `from`; each
    /// links the next with its first link), calling `each` on every one: at most [`MAX_LIST`]
    /// blocks, so a loop ends.
    pub(super) fn list(
        &mut self,
        first: u64,
        from: u64,
        id: &[u8; 2],
        data: u64,
        what: &str,
        mut each: impl FnMut(&mut Self, Block) -> Result<(), Error>,
    ) -> Result<(), Error> {
        let (mut next, mut from) = (first, from);
        let mut count = 0u64;
        while next != 0 {
            count += 1;
            if count > MAX_LIST {
                return Err(self.error(
                    from,
                    format!(
                        "{what}: more than {MAX_LIST} {} blocks in a list (a loop?)",
                        shown(id)
                    ),
                ));
            }
            let block = self.block(next, from, &[id], data, what)?;
            (next, from) = (block.link(0), block.offset);
            each(self, block)?;
        }
        Ok(())
    }
}
