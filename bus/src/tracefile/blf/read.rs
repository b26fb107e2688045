//! [`BlfReader`]: BLF in, one object at a time.

use super::*;
use crate::filter::CAN_ERR_FLAG;
use crate::trace::ErrorFrame;
use crate::tracefile::{Entry, Item};
use crate::{Error, Frame, Id, extended_id, standard_id};
use flate2::read::ZlibDecoder;
use std::io::{self, Read};

/// CAN_FD_MESSAGE's FD flags: EDL, BRS, ESI.
const FD_FLAGS: u8 = 0x07;
/// CAN_FD_MESSAGE_64's flags: EDL, BRS, ESI; and its remote frame flag.
const FD64_FLAGS: u32 = 0x7000;
const FD64_REMOTE: u32 = 0x0010;

fn bad(record: u64, offset: u64, reason: impl Into<String>) -> Error {
    Error::TraceRecord {
        format: "BLF",
        record,
        offset,
        reason: reason.into(),
    }
}

/// Reads until `buf` is full or the input ends; how many bytes were read.
fn fill(input: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while let Some(rest) = buf.get_mut(got..).filter(|r| !r.is_empty()) {
        match input.read(rest) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// The input, counting the bytes read from it: the offset of what comes next.
struct Counted<R> {
    inner: R,
    offset: u64,
}

impl<R: Read> Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.offset = self.offset.saturating_add(n as u64);
        Ok(n)
    }
}

/// Where bytes of the inflated data come from: a container, or an object outside any.
#[derive(Clone, Copy, Debug)]
struct Origin {
    offset: u64,
    container: bool,
}

/// Reads a BLF file (see the [module docs](super)), giving each frame and error frame as an
/// [`Item`] with its object number.
pub struct BlfReader<R: Read> {
    input: Counted<R>,
    start: Stamp,
    /// Objects taken so far.
    number: u64,
    /// Inflated objects: what is left of earlier containers, then the latest one's.
    data: Vec<u8>,
    /// Where the next object is looked for in `data`.
    pos: usize,
    /// Where the latest container's bytes begin in `data`, and where it is in the file.
    base: usize,
    latest: Origin,
    /// Where the bytes before `base` came from (the container an unfinished object began in).
    earlier: Origin,
    /// Channel names, by channel number (0 to 255).
    names: Vec<Option<String>>,
    done: bool,
}

/// What an object holds, as far as harvemu reads it.
enum Parsed {
    Skip,
    Name(u8, String),
    Entry { channel: u16, time: u64, entry: Entry },
}

impl<R: Read> BlfReader<R> {
    /// Reads and checks the file header.
    pub fn new(input: R) -> Result<BlfReader<R>, Error> {
        let mut input = Counted {
            inner: input,
            offset: 0,
        };
        let header = |reason: String| bad(0, 0, reason);
        let mut head = [0u8; HEADER_FIELDS];
        let got = fill(&mut input, &mut head).map_err(|e| header(format!("cannot read: {e}")))?;
        let signature = head.get(..got.min(4)).unwrap_or(&[]);
        if got == 0 {
            return Err(header("the file is empty: no BLF file header".into()));
        }
        if !b"LOGG".starts_with(signature) {
            return Err(header(format!(
                "not a BLF file: it starts with {signature:02X?}, not the signature LOGG"
            )));
        }
        if got < HEADER_FIELDS {
            return Err(header(format!(
                "the file ends {got} bytes into its {HEADER_SIZE}-byte header"
            )));
        }
        let size = u32_at(&head, 4);
        let size_ok = usize::try_from(size).is_ok_and(|s| (HEADER_FIELDS..=MAX_HEADER).contains(&s));
        if !size_ok {
            return Err(header(format!(
                "header size {size} is not between {HEADER_FIELDS} and {MAX_HEADER} (BLF's is {HEADER_SIZE})"
            )));
        }
        let rest = u64::from(size) - HEADER_FIELDS as u64;
        let skipped = io::copy(&mut (&mut input).take(rest), &mut io::sink())
            .map_err(|e| header(format!("cannot read: {e}")))?;
        if skipped < rest {
            return Err(header(format!(
                "the file ends {} bytes into its {size}-byte header",
                HEADER_FIELDS as u64 + skipped
            )));
        }
        let mut start = [0u16; 8];
        for (i, word) in start.iter_mut().enumerate() {
            *word = u16_at(&head, 40 + 2 * i);
        }
        let start = stamp_of(start).map_err(|reason| header(format!("start time: {reason}")))?;
        let origin = Origin {
            offset: u64::from(size),
            container: false,
        };
        Ok(BlfReader {
            input,
            start,
            number: 0,
            data: Vec::new(),
            pos: 0,
            base: 0,
            latest: origin,
            earlier: origin,
            names: vec![None; 256],
            done: false,
        })
    }

    /// The header's start time, which object times count from.
    pub fn start(&self) -> Stamp {
        self.start
    }

    /// The next frame or error frame, `None` at the end of the file.
    fn step(&mut self) -> Result<Option<(u64, Item)>, Error> {
        loop {
            while let Some((start, end)) = self.next_in_data()? {
                self.number += 1;
                let parsed = self.data.get(start..end).map_or(Ok(Parsed::Skip), parse);
                match parsed {
                    Err(reason) => return Err(self.error_at(self.number, start, reason)),
                    Ok(Parsed::Skip) => {}
                    Ok(Parsed::Name(channel, name)) => {
                        if let Some(slot) = self.names.get_mut(usize::from(channel)) {
                            *slot = Some(name);
                        }
                    }
                    Ok(Parsed::Entry { channel, time, entry }) => {
                        let Some(at) = self.start.0.checked_add(time) else {
                            return Err(self.error_at(
                                self.number,
                                start,
                                format!("time {time} ns after the start is past 2554"),
                            ));
                        };
                        let item = Item {
                            at: Stamp(at),
                            interface: self.interface(channel),
                            entry,
                        };
                        return Ok(Some((self.number, item)));
                    }
                }
            }
            if !self.next_in_file()? {
                return self.end();
            }
        }
    }

    /// The name of BLF channel `channel`: the one stored, else python-can's number.
    fn interface(&self, channel: u16) -> String {
        match self.names.get(usize::from(channel)) {
            Some(Some(name)) => name.clone(),
            _ => format!("can{}", i32::from(channel) - 1),
        }
    }

    /// Where the byte at `p` of the inflated data came from.
    fn origin(&self, p: usize) -> Origin {
        if p >= self.base { self.latest } else { self.earlier }
    }

    /// The error of object `record`, which begins at `p` of the inflated data.
    fn error_at(&self, record: u64, p: usize, reason: String) -> Error {
        let origin = self.origin(p);
        if origin.container {
            bad(
                record,
                origin.offset,
                format!("{reason} (the object is inside the log container that starts there)"),
            )
        } else {
            bad(record, origin.offset, reason)
        }
    }

    /// The next whole object in the inflated data, as its range; `None` when it needs more.
    fn next_in_data(&mut self) -> Result<Option<(usize, usize)>, Error> {
        let rest = self.data.get(self.pos..).unwrap_or(&[]);
        // Padding before the next signature: python-can looks for it within 4 bytes too,
        // which also reads writers that pad to a multiple of 4 instead of BLF's size % 4.
        let mut skip = 0;
        loop {
            match rest.get(skip..skip + 4) {
                None => return Ok(None),
                Some(s) if s == b"LOBJ" => break,
                Some(_) if skip < 4 => skip += 1,
                Some(s) => {
                    let reason =
                        format!("no object where one should begin: {s:02X?} is not the signature LOBJ");
                    return Err(self.error_at(self.number + 1, self.pos, reason));
                }
            }
        }
        let start = self.pos + skip;
        self.pos = start;
        let Some(head) = self.data.get(start..start + BASE_HEADER) else {
            return Ok(None);
        };
        let size = u32_at(head, 8);
        let Some(size) = object_size(size) else {
            let reason = size_error(size);
            return Err(self.error_at(self.number + 1, start, reason));
        };
        let end = start + size;
        if end > self.data.len() {
            return Ok(None);
        }
        self.pos = end;
        Ok(Some((start, end)))
    }

    /// Drops the inflated data already taken, before more is added.
    fn compact(&mut self) {
        if self.pos >= self.base {
            self.earlier = self.latest;
        }
        let taken = self.pos.min(self.data.len());
        self.data.drain(..taken);
        self.pos = 0;
        self.base = self.data.len();
    }

    /// Reads the file's next object into the inflated data: a container's content, or an
    /// object outside containers as it is. False at the end of the file.
    fn next_in_file(&mut self) -> Result<bool, Error> {
        let offset = self.input.offset;
        let record = self.number + 1;
        let cannot = |e: io::Error| bad(record, offset, format!("cannot read: {e}"));
        let mut head = [0u8; BASE_HEADER];
        let got = fill(&mut self.input, &mut head).map_err(cannot)?;
        if got == 0 {
            return Ok(false);
        }
        if got < BASE_HEADER {
            return Err(bad(
                record,
                offset,
                format!("the file ends {got} bytes into an object's {BASE_HEADER}-byte header"),
            ));
        }
        if head[..4] != *b"LOBJ" {
            return Err(bad(
                record,
                offset,
                format!("no object here: {:02X?} is not the signature LOBJ", &head[..4]),
            ));
        }
        let size32 = u32_at(&head, 8);
        let Some(size) = object_size(size32) else {
            return Err(bad(record, offset, size_error(size32)));
        };
        let kind = u32_at(&head, 12);
        self.compact();
        if kind == LOG_CONTAINER {
            self.container(record, offset, size)?;
        } else {
            // An object outside the containers (python-can skips these; they are read here).
            if self.data.iter().any(|&b| b != 0) {
                return Err(bad(
                    record,
                    offset,
                    "an object outside the log containers while one begun in a container is unfinished",
                ));
            }
            self.data.clear();
            self.base = 0;
            self.data.extend_from_slice(&head);
            let want = (size - BASE_HEADER) as u64;
            let got = (&mut self.input)
                .take(want)
                .read_to_end(&mut self.data)
                .map_err(cannot)?;
            if (got as u64) < want {
                return Err(bad(
                    record,
                    offset,
                    format!(
                        "the file ends {} bytes into a {size}-byte object",
                        BASE_HEADER + got
                    ),
                ));
            }
        }
        self.latest = Origin {
            offset,
            container: kind == LOG_CONTAINER,
        };
        // A file cut inside the padding has ended between objects.
        let padding = u64::from(size32 % 4);
        io::copy(&mut (&mut self.input).take(padding), &mut io::sink()).map_err(cannot)?;
        Ok(true)
    }

    /// Appends the content of the container at `offset` (`size` bytes; its base header read).
    fn container(&mut self, record: u64, offset: u64, size: usize) -> Result<(), Error> {
        let cut = |read: u64| {
            bad(
                record,
                offset,
                format!("the file ends {read} bytes into a {size}-byte object (a log container)"),
            )
        };
        let cannot = |e: io::Error| bad(record, offset, format!("cannot read: {e}"));
        if size < CONTAINER_HEADER {
            return Err(bad(
                record,
                offset,
                format!("a log container of {size} bytes, less than its {CONTAINER_HEADER}-byte header"),
            ));
        }
        let mut head = [0u8; CONTAINER_HEADER - BASE_HEADER];
        let got = fill(&mut self.input, &mut head).map_err(cannot)?;
        if got < head.len() {
            return Err(cut((BASE_HEADER + got) as u64));
        }
        let method = u16_at(&head, 0);
        let stated = u32_at(&head, 8);
        let len = (size - CONTAINER_HEADER) as u64;
        let before = self.data.len();
        let from = self.input.offset;
        match method {
            NO_COMPRESSION => {
                let got = (&mut self.input)
                    .take(len)
                    .read_to_end(&mut self.data)
                    .map_err(cannot)?;
                if (got as u64) < len {
                    return Err(cut((CONTAINER_HEADER + got) as u64));
                }
            }
            ZLIB_DEFLATE => {
                if usize::try_from(stated).map_or(true, |s| s > MAX_OBJECT) {
                    return Err(bad(
                        record,
                        offset,
                        format!(
                            "a log container of {stated} bytes uncompressed, above {MAX_OBJECT}, the largest read"
                        ),
                    ));
                }
                // Inflate straight from the file, at most one byte more than stated; then
                // read past whatever compressed bytes the stream left.
                let (inflated, drained) = {
                    let mut z = ZlibDecoder::new((&mut self.input).take(len));
                    let inflated = (&mut z).take(u64::from(stated) + 1).read_to_end(&mut self.data);
                    let mut rest = z.into_inner();
                    (inflated, io::copy(&mut rest, &mut io::sink()))
                };
                let read = self.input.offset.saturating_sub(from);
                if read < len {
                    return Err(cut(CONTAINER_HEADER as u64 + read));
                }
                drained.map_err(cannot)?;
                inflated.map_err(|e| {
                    bad(
                        record,
                        offset,
                        format!("the log container's data does not inflate (zlib): {e}"),
                    )
                })?;
                if self.data.len() - before > stated as usize {
                    return Err(bad(
                        record,
                        offset,
                        format!("the log container inflates to more than the {stated} bytes it states"),
                    ));
                }
            }
            m => {
                return Err(bad(
                    record,
                    offset,
                    format!("the log container's compression method {m} is unknown (0 is none, 2 zlib)"),
                ));
            }
        }
        Ok(())
    }

    /// At the end of the file: fine when nothing but padding is left of the containers.
    fn end(&mut self) -> Result<Option<(u64, Item)>, Error> {
        let rest = self.data.get(self.pos..).unwrap_or(&[]);
        if rest.iter().all(|&b| b == 0) {
            return Ok(None);
        }
        let reason = if rest.starts_with(b"LOBJ") && rest.len() >= BASE_HEADER {
            format!(
                "the file ends {} bytes into a {}-byte object",
                rest.len(),
                u32_at(rest, 8)
            )
        } else {
            format!(
                "the file ends {} bytes into an object, inside its {BASE_HEADER}-byte header",
                rest.len()
            )
        };
        Err(self.error_at(self.number + 1, self.pos, reason))
    }
}

impl<R: Read> Iterator for BlfReader<R> {
    type Item = Result<(u64, Item), Error>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        match self.step() {
            Ok(Some(item)) => Some(Ok(item)),
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

/// An object's size, if it is one the reader takes.
fn object_size(size: u32) -> Option<usize> {
    usize::try_from(size)
        .ok()
        .filter(|s| (BASE_HEADER..=MAX_OBJECT).contains(s))
}

fn size_error(size: u32) -> String {
    if (size as usize) < BASE_HEADER {
        format!("object size {size} is less than its {BASE_HEADER}-byte header")
    } else {
        format!("object size {size} is above {MAX_OBJECT}, the largest object read")
    }
}

/// What a whole object (`obj`, its header included) holds.
fn parse(obj: &[u8]) -> Result<Parsed, String> {
    let kind = u32_at(obj, 12);
    let name = match kind {
        CAN_MESSAGE => "CAN_MESSAGE",
        CAN_MESSAGE2 => "CAN_MESSAGE2",
        CAN_ERROR => "CAN_ERROR",
        CAN_ERROR_EXT => "CAN_ERROR_EXT",
        CAN_FD_MESSAGE => "CAN_FD_MESSAGE",
        CAN_FD_MESSAGE_64 => "CAN_FD_MESSAGE_64",
        APP_TEXT => "APP_TEXT",
        _ => return Ok(Parsed::Skip),
    };
    let header = match u16_at(obj, 6) {
        1 => HEADER_V1,
        2 => HEADER_V2,
        v => {
            return Err(format!(
                "{name}: object header version {v} is unknown (1 and 2 are)"
            ));
        }
    };
    let Some(body) = obj.get(header..) else {
        return Err(format!(
            "{name}: an object of {} bytes, less than its {header}-byte header",
            obj.len()
        ));
    };
    let need = |n: usize| {
        if body.len() < n {
            Err(format!(
                "{name}: {} bytes after the object header, {n} needed",
                body.len()
            ))
        } else {
            Ok(())
        }
    };
    let stamp = u64_at(obj, 24);
    // python-can's rule: 10 µs units when the flags say exactly that, else nanoseconds.
    let time = if u32_at(obj, 16) == TIME_TEN_MICS {
        stamp
            .checked_mul(10_000)
            .ok_or_else(|| format!("{name}: time {stamp} × 10 µs is past 2554"))?
    } else {
        stamp
    };
    let fd = || format!("{name}: a CAN FD frame; harvemu is CAN 2.0");
    let (channel, entry) = match kind {
        CAN_MESSAGE | CAN_MESSAGE2 => {
            // Channel, flags, DLC, id, 8 data bytes.
            need(16)?;
            let remote = byte(body, 2) & REMOTE_FLAG != 0;
            let frame = frame(u32_at(body, 4), remote, byte(body, 3), body.get(8..16))
                .map_err(|e| format!("{name}: {e}"))?;
            (u16_at(body, 0), Entry::Frame(frame))
        }
        CAN_ERROR => {
            // Channel, length.
            need(4)?;
            (u16_at(body, 0), Entry::Error(None))
        }
        CAN_ERROR_EXT => {
            // Channel, length, flags, ECC, position, DLC, reserved, frame length, id, extended
            // flags, reserved, 8 data bytes.
            need(32)?;
            let id = u32_at(body, 16) & 0x1FFF_FFFF;
            let dlc = byte(body, 10);
            let details = (id != 0 || dlc != 0).then(|| {
                let mut data = [0u8; 8];
                for (i, d) in data.iter_mut().enumerate() {
                    *d = byte(body, 24 + i);
                }
                ErrorFrame {
                    can_id: CAN_ERR_FLAG | id,
                    data,
                }
            });
            (u16_at(body, 0), Entry::Error(details))
        }
        CAN_FD_MESSAGE => {
            // Channel, flags, DLC, id, frame length, bit count, FD flags, valid bytes,
            // reserved, data.
            need(20)?;
            if byte(body, 13) & FD_FLAGS != 0 || byte(body, 14) > 8 {
                return Err(fd());
            }
            let remote = byte(body, 2) & REMOTE_FLAG != 0;
            let frame = frame(u32_at(body, 4), remote, byte(body, 3), body.get(20..))
                .map_err(|e| format!("{name}: {e}"))?;
            (u16_at(body, 0), Entry::Frame(frame))
        }
        CAN_FD_MESSAGE_64 => {
            // Channel (one byte), DLC, valid bytes, tx count, id, frame length, flags, bit
            // rates and timing, bit count, direction, extended data offset, CRC, data.
            need(40)?;
            let flags = u32_at(body, 12);
            if flags & FD64_FLAGS != 0 || byte(body, 2) > 8 {
                return Err(fd());
            }
            let frame = frame(
                u32_at(body, 4),
                flags & FD64_REMOTE != 0,
                byte(body, 1),
                body.get(40..),
            )
            .map_err(|e| format!("{name}: {e}"))?;
            (u16::from(byte(body, 0)), Entry::Frame(frame))
        }
        _ => return Ok(channel_name(body)),
    };
    Ok(Parsed::Entry { channel, time, entry })
}

/// An APP_TEXT's channel name, when it holds one as harvemu writes it: database channel info
/// for a CAN channel with an empty database path, the name where the cluster name goes. Other
/// channel infos name databases, not channels.
fn channel_name(body: &[u8]) -> Parsed {
    let (source, info) = (u32_at(body, 0), u32_at(body, 4));
    if body.len() < 16 || source != DB_CHANNEL_INFO || (info >> 16) & 0xFF != BUS_TYPE_CAN {
        return Parsed::Skip;
    }
    let text = body.get(16..).unwrap_or(&[]);
    let len = usize::try_from(u32_at(body, 8)).unwrap_or(usize::MAX);
    let text = text.get(..len).unwrap_or(text);
    let Some(name) = text.strip_prefix(b";").filter(|n| n.len() <= MAX_NAME) else {
        return Parsed::Skip;
    };
    // Kept as it is, so that a name read and written again reads back the same.
    let name = String::from_utf8_lossy(name).into_owned();
    if name.is_empty() || name.len() > MAX_NAME {
        return Parsed::Skip;
    }
    Parsed::Name(((info >> 8) & 0xFF) as u8, name)
}

/// A classic frame from a CAN object's id (bit 31 extended), remote flag, DLC and data (missing
/// bytes are zeros). A DLC above 8 means 8 bytes, as in CAN 2.0.
fn frame(raw: u32, remote: bool, dlc: u8, data: Option<&[u8]>) -> Result<Frame, String> {
    let number = raw & 0x1FFF_FFFF;
    let id: Id = if raw & CAN_MSG_EXT != 0 {
        extended_id(number).map_err(|e| e.to_string())?.into()
    } else {
        u16::try_from(number)
            .ok()
            .and_then(|n| standard_id(n).ok())
            .ok_or_else(|| {
                format!("id 0x{number:X} has no extended flag (bit 31) but does not fit in 11 bits")
            })?
            .into()
    };
    let n = usize::from(dlc.min(8));
    let frame = if remote {
        Frame::new_remote(id, n)
    } else {
        let mut bytes = [0u8; 8];
        for (b, d) in bytes.iter_mut().zip(data.unwrap_or(&[])) {
            *b = *d;
        }
        Frame::new_data(id, bytes.get(..n).unwrap_or(&[]))
    };
    frame.map_err(|e| e.to_string())
}
