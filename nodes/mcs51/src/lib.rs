//! An 80C51/8052 core that runs Intel HEX images: sans-IO, deterministic, cycle-counting.
//!
//! The core counts machine cycles (12 oscillator clocks each) and never reads a clock: the
//! caller advances it with [`Cpu::step`] or [`Cpu::run`] to a cycle count of its own (virtual
//! time). External data memory (MOVX) goes through the caller's [`Xdata`], so peripherals live
//! outside the core; [`Cpu::run`] stops right after every MOVX write so a caller can react to
//! it (a write may be a CAN transmit request), and after a MOVX read when the external data
//! space asks to ([`Xdata::wants_stop`]: a peripheral moved its interrupt output). Port pins are inputs the caller sets with
//! [`Cpu::set_pin`]; serial output is collected for [`Cpu::take_serial`].
//!
//! We write our own core rather than use the `i8051` crate because its recent versions count no
//! cycles, ignore IP and treat INT0/INT1 as level-triggered only.
//!
//! Facts follow the Intel MCS-51 Microcontroller Family User's Manual (instruction set, cycle
//! counts, SFR reset values, interrupt polling and latency, timers, serial port). Choices where
//! the manual leaves freedom, kept consistent with the `s51` simulator (uCsim) where it has one:
//!
//! - Unimplemented SFR addresses read 00h and ignore writes (s51 shows them as 00h). Timer 2 and
//!   its SFRs are not implemented on [`Variant::I8052`], which differs from the 80C51 only by its
//!   256 bytes of internal RAM.
//! - On [`Variant::I8051`] the upper 128 bytes of internal RAM do not exist: indirect reads at
//!   80h–FFh return 00h and indirect writes there do nothing (the dump shows zeros).
//! - A push past the top of internal RAM (7Fh, or FFh on the 8052) and the reserved opcode A5h
//!   are faults ([`Error::StackOverflow`], [`Error::ReservedOpcode`]); the core then stays
//!   stopped and every later step returns [`Error::Stopped`].
//! - Serial port: transmit only. A write to SBUF queues the byte at once and sets TI when the
//!   whole character, stop bit included, has gone out (as s51 does): mode 0 after 8 cycles;
//!   mode 2 after 11 bits at fosc/64 (fosc/32 with SMOD); modes 1 and 3 after 10 or 11 bits of
//!   32 timer 1 overflows each (16 with SMOD). If timer 1 does not run when a mode 1 or 3 byte
//!   is written, TI is set at once. Nothing is ever received (RI stays as written).
//! - Counter inputs (T0, T1) and INT0/INT1 edges are seen when the caller changes a pin between
//!   steps, i.e. at most one edge per pin per call of [`Cpu::set_pin`].
//! - Within an instruction, timers count the first machine cycle before the instruction's reads
//!   and writes and the others after them; conditional jumps test after all their cycles. A flag
//!   set during an instruction is polled at its end (the manual samples flags one cycle before
//!   the poll, so hardware may answer one instruction later). s51 does the same as this core.
//! - The hardware call into an interrupt takes 2 machine cycles as the manual says; s51 takes 1
//!   ([`Cpu::set_interrupt_entry_cycles`] selects, the s51 comparisons use 1). s51 also sends
//!   in serial mode 2 at twice the manual's rate; we follow the manual.
//!
//! Idle skipping: [`Cpu::run`] executes a `DJNZ Rn,$` or `DJNZ direct,$` delay loop in closed
//! form, never past `until` and, when interrupts are enabled, never past the next timer overflow
//! or serial event nor while a request waits out the instruction after RETI or an IE/IP write,
//! so the result is exactly that of stepping (pins change only between calls). For other idle loops (polling a
//! flag that only an interrupt or a pin changes) a caller can compare the core with a copy taken
//! at the loop head ([`Cpu::same_state`]: equal snapshots, pins, no timer or serial event under
//! way): then the loop repeats unchanged until an input changes something, and
//! [`Cpu::skip_cycles`] moves the cycle count over as many turns as it likes.

#![warn(missing_docs)]

mod cpu;
mod disasm;
mod error;
pub mod hex;

pub use cpu::{Cpu, RunEnd, Snapshot, Step, XAccess};
pub use disasm::disasm;
pub use error::Error;
pub use hex::Image;

/// Which part: the 80C51 (128 bytes of internal RAM) or the 8052 (256 bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// 80C51/8051: internal RAM 00h–7Fh.
    I8051,
    /// 8052: internal RAM 00h–FFh, the upper half reached only indirectly (@Ri, stack).
    I8052,
}

/// External data memory and memory-mapped peripherals, reached by MOVX.
pub trait Xdata {
    /// Reads the byte at `addr`.
    fn read(&mut self, addr: u16) -> u8;
    /// Writes `value` at `addr`.
    fn write(&mut self, addr: u16, value: u8);
    /// True when the last access changed something the caller must act on before the CPU goes
    /// on (a peripheral moved its interrupt output): [`Cpu::run`] then returns after a MOVX
    /// read too, as it always does after a MOVX write.
    fn wants_stop(&self) -> bool {
        false
    }
}

/// No external memory: every address reads FFh (an undriven bus) and writes do nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoXdata;

impl Xdata for NoXdata {
    fn read(&mut self, _addr: u16) -> u8 {
        0xFF
    }
    fn write(&mut self, _addr: u16, _value: u8) {}
}
