//! The crate's one error type: Intel HEX input errors and the faults that stop the core.

use thiserror::Error;

/// Everything that can go wrong: a bad HEX file (with its 1-based line) or a CPU fault (with the
/// program counter of the instruction that caused it).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum Error {
    /// A HEX line is not `:` followed by an even number of hex digits of the length it declares.
    #[error("HEX line {line}: malformed record: {what}")]
    Malformed {
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        what: &'static str,
    },
    /// The record's checksum does not make its bytes sum to zero.
    #[error("HEX line {line}: bad checksum (record sums to {sum:02X}h, expected 00h)")]
    Checksum {
        /// 1-based line number.
        line: usize,
        /// The low byte of the sum of all the record's bytes.
        sum: u8,
    },
    /// A record writes an address an earlier record already wrote.
    #[error("HEX line {line}: address {addr:05X}h was already written by line {first}")]
    Overlap {
        /// 1-based line number of the second writer.
        line: usize,
        /// 1-based line number of the first writer.
        first: usize,
        /// The address written twice.
        addr: u32,
    },
    /// A record writes beyond the code memory.
    #[error("HEX line {line}: address {addr:05X}h is beyond the {size}-byte code memory")]
    OutOfRange {
        /// 1-based line number.
        line: usize,
        /// The first address outside the memory.
        addr: u32,
        /// The code memory's size in bytes.
        size: usize,
    },
    /// A record type other than 00 to 05.
    #[error("HEX line {line}: unknown record type {kind:02X}h")]
    RecordType {
        /// 1-based line number.
        line: usize,
        /// The record type.
        kind: u8,
    },
    /// Something other than blank lines follows the end-of-file record: records there would be
    /// silently left out of the image.
    #[error(
        "HEX line {line}: text after the end-of-file record of line {eof} (only blank lines may follow it)"
    )]
    AfterEof {
        /// 1-based line number of the first such text.
        line: usize,
        /// 1-based line number of the end-of-file record.
        eof: usize,
    },
    /// The file ends without an end-of-file (01) record.
    #[error("HEX file has no end-of-file record")]
    MissingEof,
    /// The code memory size asked for is 0 or above 64 KB.
    #[error("code memory size {0} is not in 1..=65536")]
    CodeSize(usize),
    /// The core fetched the reserved opcode A5h.
    #[error("reserved opcode A5h at PC {pc:04X}h")]
    ReservedOpcode {
        /// Address of the opcode.
        pc: u16,
    },
    /// A push (PUSH, CALL or interrupt entry) would move SP past the top of internal RAM.
    #[error("stack overflow at PC {pc:04X}h: SP {sp:02X}h is the top of internal RAM")]
    StackOverflow {
        /// Address of the instruction (or of the interrupted instruction).
        pc: u16,
        /// The stack pointer before the push.
        sp: u8,
    },
    /// The core faulted before and stays stopped.
    #[error("CPU is stopped after a fault at PC {pc:04X}h")]
    Stopped {
        /// The PC of the fault.
        pc: u16,
    },
}
