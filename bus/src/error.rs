use thiserror::Error;

/// Every way input to this crate can be wrong.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum Error {
    /// A data frame was given more than 8 bytes.
    #[error("a classic CAN frame carries at most 8 data bytes, got {0}")]
    TooMuchData(usize),
    /// A DLC above 8 (classic CAN only).
    #[error("DLC {0} is out of range 0..=8")]
    BadDlc(usize),
    /// An identifier that does not fit its format.
    #[error("identifier 0x{raw:X} does not fit in {bits} bits")]
    IdOutOfRange {
        /// The identifier as given.
        raw: u32,
        /// 11 for a base frame, 29 for an extended frame.
        bits: u8,
    },
    /// A bit rate whose bit time is not a whole number of bus-clock ticks, which the engine
    /// cannot keep exactly.
    #[error(
        "bit rate {0} bit/s has no exact bit time on the bus clock: it does not divide 3456000000000 (2^16 * 3^3 * 5^9 ticks per second)"
    )]
    InexactBitRate(u32),
    /// A request names a node the bus does not have.
    #[error("no node {0}")]
    NoNode(u16),
    /// A node was to be attached with no controller at all.
    #[error("a node needs a controller")]
    NoControllers,
    /// Text in the `ID#DATA` notation could not be read.
    #[error("{0}")]
    Syntax(String),
    /// A line of a trace file (candump log, Vector ASC) that could not be read.
    #[error("line {line}: {reason}")]
    TraceLine {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A record of a binary trace file (BLF, pcapng, MF4) that could not be read.
    #[error("{format} record {record} at byte {offset}: {reason}")]
    TraceRecord {
        /// The format's name (`BLF`, `pcapng`, `MF4`).
        format: &'static str,
        /// 1-based number of the record (block, object) in the file.
        record: u64,
        /// Where the record starts, bytes from the start of the file.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// A record of a binary trace stamped earlier than the one before it.
    #[error(
        "{format} record {record}: time {at} goes backwards: record {before_record} is at {before} (a trace must be in time order)"
    )]
    TraceTime {
        /// The format, in words.
        format: &'static str,
        /// The record's number.
        record: u64,
        /// Its time.
        at: crate::time::Stamp,
        /// The number of the record before it.
        before_record: u64,
        /// That record's time.
        before: crate::time::Stamp,
    },
    /// A trace record came after one stamped later had already been handed to the sinks, by
    /// more than the reorder window ([`crate::trace::Reorder`]): it cannot be written in time
    /// order. Not the input's fault: the hub produced it later than the engine's contract
    /// allows, a bug of harvemu's own.
    #[error(
        "internal error: a trace record at {at} s came after one at {released} s was written, later than the trace's reorder window of {window} allows"
    )]
    TraceOrder {
        /// Bus time of the record that came too late.
        at: crate::time::BusTime,
        /// Bus time of the last record already handed on.
        released: crate::time::BusTime,
        /// The reorder window.
        window: crate::time::BusDuration,
    },
}
