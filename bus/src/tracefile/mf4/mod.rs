//! MF4 (ASAM MDF 4.1) with the bus-logging groups, in and out.
//!
//! Sources: the block layouts of ASAM MDF 4.1 as asammdf implements them
//! (`asammdf/blocks/v4_constants.py`, `v4_blocks.py`, and `mdf_v4.py` for how data blocks are
//! listed and inflated), the ASAM MDF bus-logging association standard as asammdf's
//! `MDF.extract_bus_logging` reads it (`mdf_v4.py` `_extract_can_logging`,
//! `bus_logging_utils.py`), and python-can's `can/io/mf4.py` (`MF4Writer`, `MF4Reader`).
//!
//! Contract:
//! - [`Mf4Writer`] writes an MDF 4.10 file: the ID block (`MDF     4.10    `, program
//!   `harvemu`), the header block with the start given (`hd_start_time_ns`, UTC), one file
//!   history block, and three data groups in this order, one channel group each:
//!   `CAN_DataFrame`, `CAN_ErrorFrame`, `CAN_RemoteFrame`. Each channel group is flagged a (plain)
//!   bus event group with a CAN bus source (SI: type BUS, bus CAN; acquisition name `CAN`), as
//!   python-can's `MF4Reader` and asammdf's `extract_bus_logging` look for. Its records: the
//!   master channel `t` (float64 seconds since the header's start, unit `s`), then the composed
//!   channel named after the group, whose members are (byte offset, unsigned little-endian
//!   unless said): `.BusChannel` (8, u8), `.ID` (9, u32), `.IDE` (13, u8), `.DLC` (14, u8),
//!   `.DataLength` (15, u8), `.DataBytes` (16, 8-byte array; not in the remote group) and
//!   `.Dir` (24, or 16 in the remote group; 0 = Rx): 25-byte records, 17 for remote frames.
//!   A remote frame has DataLength 0. An error frame has as ID SocketCAN's error classes
//!   (`can_id` without `CAN_ERR_FLAG`), IDE 1 only when they need more than 11 bits, DLC and
//!   DataLength 8 and the 8 details as DataBytes; one without details has ID 0, DLC 0 and
//!   DataLength 0.
//! - Interfaces: every interface gets the next bus channel (1, 2, ...) when first seen, as
//!   bus-logging files number them. Their names are kept in the header's comment, as common
//!   properties that asammdf shows (`mdf.header._common_properties`): `<tree name="bus
//!   channels"><e name="1">harv0</e>...`. At most 255 interfaces (BusChannel is one byte); names
//!   longer than [`MAX_NAME`] bytes are not stored (they read back as `can{N}`).
//! - Streaming and bounded: each group's records are buffered up to [`BLOCK_SIZE`] bytes (a
//!   whole number of records) and then written as a DZ block (zlib deflate of a DT block). At
//!   [`ItemWriter::finish`](super::ItemWriter::finish) the buffers are written out, each group
//!   gets an HL block and one DL block listing its data blocks (equal length: every block but
//!   the last holds [`BLOCK_SIZE`] rounded down to whole records), as asammdf writes them; then
//!   the writer goes back to fill in the data links, the cycle counts, the header's comment and
//!   the ID (`UnFinMF ` until then, custom unfinalised flag 1: "data lists not written"). What
//!   grows while writing is one 8-byte link per data block and the interface names. A file
//!   whose writer never finished opens in asammdf as empty groups and is refused here.
//! - Times: `t = (at - start)` in seconds as f64, `at = start + round(t * 1e9)` reading back,
//!   computed exactly from the float's bits: exact to the nanosecond while `|at - start| <
//!   2^23 s` (97 days), where consecutive f64 values are less than 1 ns apart; within 1 ns up to
//!   2^24 s.
//! - [`Mf4Reader`] reads files of this writer, of python-can's `MF4Writer` and of asammdf's
//!   `MDF.append` of bus-logging signals, without assuming a layout: it walks the data groups,
//!   finds channel groups by their composed channel's name (`CAN_DataFrame`, `CAN_ErrorFrame`,
//!   `CAN_RemoteFrame`), the members by name (`CAN_DataFrame.ID` or `ID`), each with its byte
//!   offset, bit offset, bit count and data type from its CN block, and the time master channel
//!   (float, or integer with a linear conversion; or virtual). Data may be a DT or DZ block
//!   (deflate or transposed deflate) or lists of them (DL blocks, possibly under an HL block);
//!   sorted data groups and unsorted ones (record ids) alike. Each group is read as a stream,
//!   one data block at a time (a DT block in windows of [`WINDOW`] bytes, a DZ block inflated
//!   whole, at most [`MAX_BLOCK`]), and the groups are merged by time: memory is a block per
//!   group, and there may be at most [`MAX_GROUPS`] groups. Equal times come in the order data
//!   frames, error frames, remote frames, then in file order.
//! - Items: a data frame from DataLength bytes of DataBytes (DLC when there is no DataLength),
//!   extended when IDE is set or the ID has bit 31; a remote frame with its DLC; an error frame
//!   with `CAN_ERR_FLAG | ID` and the first 8 DataBytes (zeros past DataLength) when ID or DLC
//!   is not zero, else one without details. A CAN FD frame (EDL set, or more than 8 bytes) is
//!   an error: harvemu is CAN 2.0. The interface is the name stored for the bus channel, else
//!   `can{N}` for bus channel N, as python-can writes `can0` as 0.
//! - Items are numbered from 1 in the order given. Every bad input is an
//!   [`Error::TraceRecord`](crate::Error::TraceRecord) (format `MF4`): for a bad block, the
//!   number of blocks read so far and the block's offset; for a bad record, its number in its
//!   group and the offset of the data block it starts in. Links past the end of the file,
//!   blocks longer than [`MAX_BLOCK`] (or data inflating to more), lists longer than
//!   [`MAX_LIST`] (a loop), data blocks listed out of file order (read twice), and field data
//!   types that cannot hold the value are refused; the first error ends the items. Nothing
//!   panics on any input. A header start flagged local time is taken as UTC (the file does not
//!   say which zone).

use super::le::{byte, u16_at, u32_at, u64_at};

mod blocks;
mod data;
mod groups;
mod head;
mod read;
mod write;

#[cfg(test)]
mod tests;

pub use read::Mf4Reader;
pub use write::Mf4Writer;

/// Records buffered per group before they are written as one DZ block.
pub const BLOCK_SIZE: usize = 1 << 20;
/// The largest block, and the largest inflated data block, the reader takes: far above what a
/// CAN log needs (asammdf writes data blocks of a few MiB), so that a corrupt length cannot make
/// it allocate gigabytes.
pub const MAX_BLOCK: u64 = 64 << 20;
/// A DT block is read this much at a time.
pub const WINDOW: usize = 1 << 20;
/// The most entries a list of blocks (data groups, channel groups, channels) may have.
pub const MAX_LIST: u64 = 1 << 16;
/// The most CAN bus-logging channel groups read from one file.
pub const MAX_GROUPS: usize = 16;
/// The longest interface name stored or read back, bytes.
pub const MAX_NAME: usize = 1024;

/// The size of a block's header: id, reserved, length, link count.
const HEADER: u64 = 24;
/// The ID block's size; the header block follows it.
const ID_SIZE: u64 = 64;

/// The three bus-logging groups, in the order the writer writes them and equal times are given.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Kind {
    Data,
    Error,
    Remote,
}

impl Kind {
    const ALL: [Kind; 3] = [Kind::Data, Kind::Error, Kind::Remote];

    /// The composed channel's name, which the members' names begin with.
    fn name(self) -> &'static str {
        match self {
            Kind::Data => "CAN_DataFrame",
            Kind::Error => "CAN_ErrorFrame",
            Kind::Remote => "CAN_RemoteFrame",
        }
    }
}

/// SI: source type BUS, bus type CAN.
const SOURCE_BUS: u8 = 2;
const BUS_TYPE_CAN: u8 = 2;
/// CG flags: a bus event group, and a plain one (no other channels).
const CG_BUS_EVENT: u16 = 1 << 1;
const CG_PLAIN_BUS_EVENT: u16 = 1 << 2;
/// CG flags: a group of variable-length signal data (no records of its own).
const CG_VLSD: u16 = 1;
/// CN flags: a channel of a bus event.
const CN_BUS_EVENT: u32 = 1 << 10;
/// CN types: a master channel, a virtual master (its value is the record's index).
const CN_MASTER: u8 = 2;
const CN_VIRTUAL_MASTER: u8 = 3;
/// CN sync type: time.
const SYNC_TIME: u8 = 1;
/// CN data types.
const UINT_LE: u8 = 0;
const UINT_BE: u8 = 1;
const INT_LE: u8 = 2;
const INT_BE: u8 = 3;
const FLOAT_LE: u8 = 4;
const FLOAT_BE: u8 = 5;
const BYTE_ARRAY: u8 = 10;
/// DZ zip types.
const DEFLATE: u8 = 0;
const TRANSPOSED_DEFLATE: u8 = 1;
/// DL and HL flags: every data block but the last has the same length.
const EQUAL_LENGTH: u8 = 1;
/// The header comment's tree of interface names.
const NAMES_TREE: &str = "bus channels";
