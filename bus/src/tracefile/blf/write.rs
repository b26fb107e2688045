//! [`BlfWriter`]: items out as BLF, one compressed container at a time.

use super::*;
use crate::tracefile::{Entry, Item, ItemWriter};
use flate2::Compression;
use flate2::write::ZlibEncoder;
use std::io::{self, Seek, SeekFrom, Write};

/// Writes items as a BLF file (see the [module docs](super) for the layout).
pub struct BlfWriter<W: Write + Seek> {
    inner: W,
    /// Where the file header is in `inner`.
    base: u64,
    /// The header's start time: the writer's start truncated to the millisecond.
    start: Stamp,
    /// The last item's time (the start until there is one).
    stop: Stamp,
    /// The interfaces seen, channel 1 first.
    channels: Vec<String>,
    /// Objects not yet written in a container.
    buffer: Vec<u8>,
    /// A container's compressed data, reused.
    deflated: Vec<u8>,
    /// Objects written so far (containers not counted, as the header counts them).
    objects: u64,
    /// The file's size were nothing compressed: python-can's "uncompressed size".
    uncompressed: u64,
    finished: bool,
}

impl<W: Write + Seek> BlfWriter<W> {
    /// Starts a file at `inner`'s position whose times count from `start` (kept to the
    /// millisecond in the header; item times stay exact) and writes its header, with counts
    /// of zero until [`ItemWriter::finish`]. Items stamped before `start`'s millisecond are
    /// refused: BLF times count forwards from the header's.
    pub fn new(mut inner: W, start: Stamp) -> io::Result<BlfWriter<W>> {
        let base = inner.stream_position()?;
        let start = Stamp(start.0 - start.0 % NS_PER_MS);
        let mut writer = BlfWriter {
            inner,
            base,
            start,
            stop: start,
            channels: Vec::new(),
            buffer: Vec::with_capacity(CONTAINER_SIZE + 1024),
            deflated: Vec::new(),
            objects: 0,
            uncompressed: HEADER_SIZE as u64,
            finished: false,
        };
        let header = writer.header(None);
        writer.inner.write_all(&header)?;
        Ok(writer)
    }

    /// The output, once the file is done with.
    pub fn into_inner(self) -> W {
        self.inner
    }

    /// The file header: of a finished file of `size` bytes, or with sizes and count zero for
    /// one being written.
    fn header(&self, size: Option<u64>) -> [u8; HEADER_SIZE] {
        let mut h = [0u8; HEADER_SIZE];
        h[..4].copy_from_slice(b"LOGG");
        h[4..8].copy_from_slice(&(HEADER_SIZE as u32).to_le_bytes());
        // Application 5 and BL version 2.6.8.1, what python-can writes: files that Vector's
        // tools are known to open.
        h[8] = 5;
        h[12..16].copy_from_slice(&[2, 6, 8, 1]);
        let (size, uncompressed, objects) = match size {
            None => (0, 0, 0),
            Some(size) => (
                size,
                self.uncompressed,
                u32::try_from(self.objects).unwrap_or(u32::MAX),
            ),
        };
        h[16..24].copy_from_slice(&size.to_le_bytes());
        h[24..32].copy_from_slice(&uncompressed.to_le_bytes());
        h[32..36].copy_from_slice(&objects.to_le_bytes());
        // 36..40: "objects read", whose meaning nobody knows; python-can writes 0.
        for (i, (start, stop)) in system_time(self.start)
            .into_iter()
            .zip(system_time(self.stop))
            .enumerate()
        {
            h[40 + 2 * i..42 + 2 * i].copy_from_slice(&start.to_le_bytes());
            h[56 + 2 * i..58 + 2 * i].copy_from_slice(&stop.to_le_bytes());
        }
        h
    }

    /// The channel of interface `name`, numbering it (and storing its name) when new.
    fn channel(&mut self, name: &str, time: u64) -> io::Result<u16> {
        if let Some(i) = self.channels.iter().position(|n| n == name) {
            // At most u16::MAX channels are ever numbered.
            return Ok(i as u16 + 1);
        }
        let number = u16::try_from(self.channels.len() + 1).map_err(|_| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                "BLF numbers at most 65535 channels: too many interfaces",
            )
        })?;
        self.channels.push(name.to_string());
        if number <= 255 && !name.is_empty() && name.len() <= MAX_NAME {
            // APP_TEXT: source, reserved word (version 1, channel, bus type), text length,
            // reserved, the text: an empty database path, then the name as the cluster.
            let text_len = (name.len() + 1) as u32;
            let info = 1 | (u32::from(number) << 8) | (BUS_TYPE_CAN << 16);
            let mut body = Vec::with_capacity(17 + name.len());
            body.extend_from_slice(&DB_CHANNEL_INFO.to_le_bytes());
            body.extend_from_slice(&info.to_le_bytes());
            body.extend_from_slice(&text_len.to_le_bytes());
            body.extend_from_slice(&0u32.to_le_bytes());
            body.push(b';');
            body.extend_from_slice(name.as_bytes());
            self.object(APP_TEXT, time, &body)?;
        }
        Ok(number)
    }

    /// Buffers one object with a version 1 header and nanosecond time; writes full containers.
    fn object(&mut self, kind: u32, time: u64, body: &[u8]) -> io::Result<()> {
        let size = HEADER_V1 + body.len();
        let b = &mut self.buffer;
        b.extend_from_slice(b"LOBJ");
        b.extend_from_slice(&(HEADER_V1 as u16).to_le_bytes());
        b.extend_from_slice(&1u16.to_le_bytes());
        b.extend_from_slice(&(size as u32).to_le_bytes());
        b.extend_from_slice(&kind.to_le_bytes());
        b.extend_from_slice(&TIME_ONE_NANS.to_le_bytes());
        // Client index and object version.
        b.extend_from_slice(&[0, 0, 0, 0]);
        b.extend_from_slice(&time.to_le_bytes());
        b.extend_from_slice(body);
        // BLF's padding: as many bytes as the size is past a multiple of 4 (python-can,
        // vector_blf); not an alignment.
        b.resize(b.len() + size % 4, 0);
        self.objects += 1;
        // Like python-can, cut containers at exactly CONTAINER_SIZE bytes: the rest of an
        // object goes on in the next one.
        while self.buffer.len() >= CONTAINER_SIZE {
            self.container(CONTAINER_SIZE)?;
        }
        Ok(())
    }

    /// Writes the first `len` buffered bytes as a zlib-compressed container.
    fn container(&mut self, len: usize) -> io::Result<()> {
        let Some(data) = self.buffer.get(..len) else {
            return Ok(());
        };
        let mut deflated = std::mem::take(&mut self.deflated);
        deflated.clear();
        let mut z = ZlibEncoder::new(deflated, Compression::default());
        z.write_all(data)?;
        self.deflated = z.finish()?;
        let size = CONTAINER_HEADER + self.deflated.len();
        let size32 =
            u32::try_from(size).map_err(|_| io::Error::other("a BLF container larger than 4 GiB"))?;
        let mut head = [0u8; CONTAINER_HEADER];
        head[..4].copy_from_slice(b"LOBJ");
        head[4..6].copy_from_slice(&(BASE_HEADER as u16).to_le_bytes());
        head[6..8].copy_from_slice(&1u16.to_le_bytes());
        head[8..12].copy_from_slice(&size32.to_le_bytes());
        head[12..16].copy_from_slice(&LOG_CONTAINER.to_le_bytes());
        head[16..18].copy_from_slice(&ZLIB_DEFLATE.to_le_bytes());
        head[24..28].copy_from_slice(&(len as u32).to_le_bytes());
        self.inner.write_all(&head)?;
        self.inner.write_all(&self.deflated)?;
        self.inner.write_all(&[0u8; 3][..size % 4])?;
        self.buffer.drain(..len);
        self.uncompressed += (CONTAINER_HEADER + len) as u64;
        Ok(())
    }

    /// Writes everything buffered, in containers of at most [`CONTAINER_SIZE`] bytes.
    fn write_buffer(&mut self) -> io::Result<()> {
        while !self.buffer.is_empty() {
            self.container(self.buffer.len().min(CONTAINER_SIZE))?;
        }
        Ok(())
    }
}

impl<W: Write + Seek> ItemWriter for BlfWriter<W> {
    fn write(&mut self, item: &Item) -> io::Result<()> {
        if self.finished {
            return Err(io::Error::other("the BLF file has been finished"));
        }
        let time = item.at.0.checked_sub(self.start.0).ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "an item at {} is before the BLF file's start, {}",
                    item.at, self.start
                ),
            )
        })?;
        let channel = self.channel(&item.interface, time)?;
        match &item.entry {
            Entry::Frame(frame) => {
                // Channel, flags (direction Rx, bit 7 remote), DLC, id, 8 data bytes.
                let mut body = [0u8; 16];
                body[..2].copy_from_slice(&channel.to_le_bytes());
                body[2] = if frame.is_remote() { REMOTE_FLAG } else { 0 };
                body[3] = frame.dlc();
                let ext = if frame.is_extended() { CAN_MSG_EXT } else { 0 };
                body[4..8].copy_from_slice(&(frame.raw_id() | ext).to_le_bytes());
                let data = frame.data();
                body[8..8 + data.len()].copy_from_slice(data);
                self.object(CAN_MESSAGE, time, &body)?;
            }
            Entry::Error(details) => {
                // Channel, length, flags, ECC, position, DLC, reserved, frame length, id,
                // extended flags, reserved, data: python-can's error frame.
                let mut body = [0u8; 32];
                body[..2].copy_from_slice(&channel.to_le_bytes());
                if let Some(e) = details {
                    body[10] = 8;
                    body[16..20].copy_from_slice(&(e.can_id & 0x1FFF_FFFF).to_le_bytes());
                    body[24..32].copy_from_slice(&e.data);
                }
                self.object(CAN_ERROR_EXT, time, &body)?;
            }
        }
        self.stop = self.stop.max(item.at);
        Ok(())
    }

    /// Flushes the file, but not the container being filled: the hub flushes its sinks at
    /// every stop of a run, which would make a container of a few frames each time (python-can
    /// does not write one on flush either). `finish` writes it.
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }

    fn finish(&mut self) -> io::Result<()> {
        if self.finished {
            return Ok(());
        }
        self.finished = true;
        self.write_buffer()?;
        let end = self.inner.stream_position()?;
        let header = self.header(Some(end.saturating_sub(self.base)));
        self.inner.seek(SeekFrom::Start(self.base))?;
        self.inner.write_all(&header)?;
        self.inner.seek(SeekFrom::Start(end))?;
        self.inner.flush()
    }
}
