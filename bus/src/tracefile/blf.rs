//! Vector BLF (binary logging) in and out.
//!
//! Contract:
//! - The layout is the one python-can's `can/io/blf.py` reads and writes (Vector publishes no
//!   specification; python-can and Tobias Lorenz's `vector_blf` describe the format): a 144-byte
//!   `LOGG` file header (application, versions, file size, uncompressed size, object count, start
//!   and stop time as a Windows SYSTEMTIME, in UTC as python-can has it), then `LOBJ` objects,
//!   each followed by `size % 4` padding bytes (not an alignment: python-can and `vector_blf`
//!   both pad so). Logged objects sit in LOG_CONTAINER objects (type 10) whose payload is
//!   zlib-compressed (the reader also takes stored ones, method 0, and objects outside any
//!   container); an object may begin in one container and end in the next.
//! - [`BlfWriter`] writes frames as CAN_MESSAGE (type 1: channel, flags with bit 7 for a remote
//!   frame and direction Rx, DLC, id with bit 31 for an extended id, 8 data bytes) and error
//!   frames as CAN_ERROR_EXT (type 73) the way python-can does: the SocketCAN error classes
//!   (`can_id` without `CAN_ERR_FLAG`) as the id, DLC 8 and the 8 detail bytes; an error frame
//!   without details has id 0 and DLC 0. Object times are nanoseconds (flag TIME_ONE_NANS) after
//!   the header's start time, which is the writer's start truncated to the millisecond (all a
//!   SYSTEMTIME holds), so every time is kept to the nanosecond. A container is written each time
//!   [`CONTAINER_SIZE`] bytes (python-can's 128 KiB) of objects are buffered, and on `finish`
//!   (not on [`ItemWriter::flush`](super::ItemWriter::flush), which the hub calls at every stop
//!   of a run); only that buffer is held.
//!   The header has the start time from the first; `finish` goes back to fill in its sizes,
//!   object count and stop time (the last item's). Until then they are zero, which readers
//!   (python-can's, this one) do not mind, so a file whose writer was killed (never finished)
//!   still reads up to the last whole object of its last container; the object that goes on in
//!   the container never written is reported as cut off.
//! - Interface names: BLF numbers CAN channels from 1 and has no place for a name in a frame.
//!   Each interface gets the next channel number when first seen, and its name goes in an
//!   APP_TEXT object (type 65) written just before its first frame, as a "database channel
//!   info" text (source 1; bits 8 to 15 of its reserved word the channel, bits 16 to 23 the bus
//!   type, 1 for CAN; `vector_blf` documents the fields) with an empty database path and the
//!   name where the cluster name goes: `;harv0`. Readers that do not know APP_TEXT skip it
//!   (python-can reads every frame as before); one that reads channel info sees a channel
//!   without a database on the cluster `harv0`. Only channels 1 to 255 and names of at most
//!   [`MAX_NAME`] bytes fit; other names are not stored (they read back as `can{N-1}`).
//! - [`BlfReader`] streams: one file object at a time, one container inflated at a time, plus
//!   the part of an object that continues in the next container. No object, and no container's
//!   uncompressed data, may be larger than [`MAX_OBJECT`] (16 MiB), so the reader never holds
//!   more than about twice that. It gives CAN_MESSAGE and CAN_MESSAGE2 as frames (a DLC above 8
//!   carries 8 bytes, as in CAN 2.0; a remote frame keeps its DLC up to 8), CAN_ERROR as an error
//!   frame without details, CAN_ERROR_EXT as one with the id's 29 bits as error classes and the
//!   8 data bytes as details (id 0 and DLC 0: without details), CAN FD objects (types 100 and
//!   101) that carry a classic frame as that frame; a real CAN FD frame is an error (harvemu is
//!   CAN 2.0). Channel names are read back from APP_TEXT objects in harvemu's form (an empty
//!   database path); a channel without one is `can{N-1}` for BLF channel N, as python-can
//!   numbers channels from 0. Every other object is skipped, but counted. Inside a container the
//!   next object is looked for up to 4 bytes past the end of the last, as python-can does, so
//!   that other paddings read too.
//! - Times: object time in 10 µs units when its flags are exactly TIME_TEN_MICS (1), else in
//!   nanoseconds (as python-can decides), added to the header's start time (UTC; a SYSTEMTIME of
//!   all zeros is 1970). Objects are given as stored: BLF does not promise time order.
//! - Objects are numbered from 1 in file order, counting what the header's object count counts
//!   (every logged object, containers not); each item comes with its number. Every bad or cut-off
//!   object is an [`Error::TraceRecord`](crate::Error::TraceRecord) with that number and the byte
//!   offset of the object, or for one inside a container the offset of the container it begins
//!   in; a container that cannot be inflated is reported as the next object, at the container's
//!   offset; a bad file header is record 0 at byte 0. A file that ends inside an object says so
//!   ("ends N bytes into a M-byte object"); one that ends between objects has been read whole.
//!   The first error ends the items. Nothing panics on any input.

mod read;
mod write;

#[cfg(test)]
mod tests;

pub use read::BlfReader;
pub use write::BlfWriter;

use super::le::{byte, u16_at, u32_at, u64_at};
use crate::time::Stamp;

/// The file header's size, as python-can and Vector write it.
const HEADER_SIZE: usize = 144;
/// The header's fields: signature to stop time; the rest is reserved.
const HEADER_FIELDS: usize = 72;
/// The longest file header accepted.
const MAX_HEADER: usize = 1 << 16;
/// An object's base header: signature, header size, header version, object size, type.
const BASE_HEADER: usize = 16;
/// A version 1 object header: the base, flags, client index, object version, timestamp.
const HEADER_V1: usize = 32;
/// A version 2 object header: also a timestamp status and the original timestamp.
const HEADER_V2: usize = 40;
/// A container's header: the base, compression method, uncompressed size, reserved fields.
const CONTAINER_HEADER: usize = 32;

/// Objects buffered before they are written as a container: python-can's container size.
pub const CONTAINER_SIZE: usize = 128 * 1024;
/// The largest object, and the largest uncompressed container, the reader takes: far above
/// anything a CAN log holds (a container is 128 KiB), so that a corrupt size cannot make it
/// allocate gigabytes.
pub const MAX_OBJECT: usize = 16 << 20;
/// The longest channel name stored or read back, bytes.
pub const MAX_NAME: usize = 1024;

const CAN_MESSAGE: u32 = 1;
const CAN_ERROR: u32 = 2;
const LOG_CONTAINER: u32 = 10;
const APP_TEXT: u32 = 65;
const CAN_ERROR_EXT: u32 = 73;
const CAN_MESSAGE2: u32 = 86;
const CAN_FD_MESSAGE: u32 = 100;
const CAN_FD_MESSAGE_64: u32 = 101;

/// In a CAN object's id: the id is extended.
const CAN_MSG_EXT: u32 = 0x8000_0000;
/// In a CAN_MESSAGE's flags: a remote frame.
const REMOTE_FLAG: u8 = 0x80;
/// Object header flags: the timestamp counts 10 µs or 1 ns.
const TIME_TEN_MICS: u32 = 1;
const TIME_ONE_NANS: u32 = 2;
/// Container compression methods.
const NO_COMPRESSION: u16 = 0;
const ZLIB_DEFLATE: u16 = 2;
/// APP_TEXT source: database channel info.
const DB_CHANNEL_INFO: u32 = 1;
/// Bus type in a channel info: CAN.
const BUS_TYPE_CAN: u32 = 1;

const NS_PER_MS: u64 = 1_000_000;

/// `at` as a SYSTEMTIME in UTC: year, month, day of the week (Sunday 0), day, hour, minute,
/// second, millisecond.
fn system_time(at: Stamp) -> [u16; 8] {
    let Ok(t) = time::OffsetDateTime::from_unix_timestamp_nanos(i128::from(at.0)) else {
        // Out of reach of a u64 of nanoseconds (year 2554 at most); zero means "no time".
        return [0; 8];
    };
    [
        u16::try_from(t.year()).unwrap_or(0),
        u16::from(u8::from(t.month())),
        u16::from(t.weekday().number_days_from_sunday()),
        u16::from(t.day()),
        u16::from(t.hour()),
        u16::from(t.minute()),
        u16::from(t.second()),
        t.millisecond(),
    ]
}

/// The time a SYSTEMTIME (UTC) names; all zeros is 1970.
fn stamp_of(st: [u16; 8]) -> Result<Stamp, String> {
    if st == [0; 8] {
        return Ok(Stamp(0));
    }
    let [year, month, _, day, hour, minute, second, milli] = st;
    let shown = format!("{year:04}-{month:02}-{day:02} {hour:02}:{minute:02}:{second:02}.{milli:03}");
    let bad = || format!("{shown} is not a date and time");
    let small = |v: u16| u8::try_from(v).map_err(|_| bad());
    let month = time::Month::try_from(small(month)?).map_err(|_| bad())?;
    let date = time::Date::from_calendar_date(i32::from(year), month, small(day)?).map_err(|_| bad())?;
    let clock =
        time::Time::from_hms_milli(small(hour)?, small(minute)?, small(second)?, milli).map_err(|_| bad())?;
    let ns = date.with_time(clock).assume_utc().unix_timestamp_nanos();
    u64::try_from(ns)
        .map(Stamp)
        .map_err(|_| format!("{shown} is outside 1970 to 2554, the times harvemu keeps"))
}
