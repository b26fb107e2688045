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
//! One opcode table decodes every opcode to its operation and operands, with its length and
//! machine cycles; execution, cycle counting and [`disasm()`] (Intel/as31 syntax) all read it.
//!
//! We write our own core rather than use the `i8051` crate because its recent versions count no
//! cycles, ignore IP and treat INT0/INT1 as level-triggered only.
//!
//! Facts follow the Intel MCS-51 Microcontroller Family User's Manual (instruction set, cycle
//! counts, SFR reset values, interrupt polling and latency, timers, serial port). Choices where
//! the manual leaves freedom, kept consistent with the `s51` simulator (uCsim) where it has one:
//!
//! - SFR addresses the core does not implement go to [`Xdata::sfr_read`]/[`Xdata::sfr_write`];
//!   by default they read 00h and ignore writes (s51 shows them as 00h). Timer 2 and
//!   its SFRs are not implemented on [`Variant::I8052`] (they are on the AT89C51CC03), which differs from the 80C51 only by its
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
//! The AT89C51CC03 ([`Variant::At89c51cc03`]) adds timer 2, X2 mode, the on-chip XRAM, the
//! 10-bit ADC, the watchdog and its interrupt system (four levels, eleven sources); the
//! repository's `docs/FIRMWARE.md` ("The AT89C51CC03") lists the facts and what is not
//! modelled. SFRs the core does not implement reach the caller through [`Xdata::sfr_read`]
//! and [`Xdata::sfr_write`], outside interrupt requests through [`Xdata::irq`].
//!
//! Idle skipping: [`Cpu::run`] executes a `DJNZ Rn,$` or `DJNZ direct,$` delay loop in closed
//! form, never past `until` and, when interrupts are enabled, never past the next timer overflow
//! or serial event nor while a request waits out the instruction after RETI or an IE/IP write,
//! so the result is exactly that of stepping (pins change only between calls). For other idle loops
//! (polling a flag that only an interrupt, a timer or a pin changes) a caller compares the core
//! after one turn with a copy taken at the loop head and let the same cycles pass
//! ([`Cpu::idle`], [`Cpu::same_but_time`]): when they agree, no timer count was read
//! ([`Cpu::time_reads`]) and no event fell due on the way ([`Cpu::next_event`]), every later
//! turn does the same until the next event, and [`Cpu::idle`] passes as many whole turns as come
//! before it.
//!
//! Coverage: [`Cpu::run_covered`] and [`Cpu::step_covered`] tell a [`Cover`] of each instruction
//! they execute (address, and for a conditional jump whether it jumped), a delay loop passed in
//! closed form as its iterations; [`Cpu::run`] and [`Cpu::step`] tell `()`, which costs nothing.
//!
//! Watched inputs and outputs: a caller that drives pins and analog inputs from a world it
//! brings up to date only now and then names them ([`Cpu::watch`]); [`Cpu::run`] then stops
//! before an instruction would read them once their levels no longer hold, and after an
//! instruction changes a watched latch ([`RunEnd::InputsDue`], [`RunEnd::OutputChanged`]).

#![warn(missing_docs)]

mod cpu;
mod decode;
mod disasm;
mod error;
pub mod hex;

pub use cpu::cc03::XRAM_BYTES;
pub use cpu::{ADC_LEAD, Cpu, RunEnd, Snapshot, Step, Watched, XAccess};
pub use disasm::disasm;
pub use error::Error;
pub use hex::Image;

/// Which part: the 80C51 (128 bytes of internal RAM), the 8052 (256 bytes) or the Atmel
/// AT89C51CC03.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// 80C51/8051: internal RAM 00h–7Fh.
    I8051,
    /// 8052: internal RAM 00h–FFh, the upper half reached only indirectly (@Ri, stack).
    I8052,
    /// Atmel AT89C51CC03: 256 bytes of internal RAM, 2048 bytes of on-chip XRAM (AUXR),
    /// timer 2, X2 mode (CKCON), the 10-bit ADC, the watchdog, four interrupt priority levels
    /// and eleven interrupt sources. Its CAN controller, PCA, SPI, ports P4 and the flash
    /// registers are the caller's, reached through [`Xdata::sfr_read`]/[`Xdata::sfr_write`]
    /// and requesting interrupts through [`Xdata::irq`] (see [`irq`]).
    At89c51cc03,
}

/// Interrupt request bits returned by [`Xdata::irq`] for sources that live outside the core
/// (AT89C51CC03 only; the other variants ignore them). Level-sensitive: a source requests
/// while its bit is 1, and the core never clears it (the handler must make the peripheral
/// drop it, as on the chip).
pub mod irq {
    /// PCA (CF or CCFn), vector 0033h, enabled by IEN0.EC.
    pub const PCA: u8 = 0x01;
    /// CAN controller (CANGIT.CANIT), vector 003Bh, enabled by IEN1.ECAN.
    pub const CAN: u8 = 0x02;
    /// CAN timer overrun (CANGIT.OVRTIM), vector 004Bh, enabled by IEN1.ETIM.
    pub const CAN_TIMER: u8 = 0x04;
    /// SPI, vector 0053h, enabled by IEN1.ESPI.
    pub const SPI: u8 = 0x08;
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
    /// Reads an SFR the core does not implement for its variant. `None` keeps the core's own
    /// behaviour (the address reads 00h). Reached by direct addressing, by bit instructions
    /// on bit-addressable SFRs (a read of the whole byte, then for a write a write of it) and
    /// by PUSH. The value read is not the port-pin/latch distinction: the hook sees one read.
    fn sfr_read(&mut self, _addr: u8) -> Option<u8> {
        None
    }
    /// Writes an SFR the core does not implement for its variant (direct addressing, bit
    /// instructions, POP). Returns false when nothing there takes it (the write is ignored,
    /// the core's own behaviour). After a hooked access [`Cpu::run`] returns
    /// [`RunEnd::Peripheral`] if [`Xdata::wants_stop`] says so, as after a MOVX read.
    fn sfr_write(&mut self, _addr: u8, _value: u8) -> bool {
        false
    }
    /// The oscillator clocks ([`Cpu::clocks`]) at the moment of the hooked SFR access that
    /// follows, told before every [`Xdata::sfr_read`] and [`Xdata::sfr_write`]: a peripheral
    /// with a timer of its own brings it up to date.
    fn sfr_clock(&mut self, _clocks: u64) {}
    /// Interrupt requests of outside sources, as [`irq`] bits (level-sensitive). The core
    /// reads it when [`Cpu::step`] or [`Cpu::run`] starts and after every MOVX or hooked SFR
    /// access, so a peripheral's request may change only then (or between calls).
    fn irq(&self) -> u8 {
        0
    }
}

/// Told of every instruction [`Cpu::run_covered`] and [`Cpu::step_covered`] execute, for code
/// coverage. An interrupt's entry is not an instruction and is not told; an instruction that
/// faults did not complete and is not told either.
pub trait Cover {
    /// The instruction at `pc` ran once (not a conditional jump).
    fn ran(&mut self, pc: u16);
    /// The conditional jump at `pc` (JB, JNB, JBC, JC, JNC, JZ, JNZ, CJNE, DJNZ) ran once and
    /// jumped or not. A jump whose target is the next instruction counts as not taken.
    fn jumped(&mut self, pc: u16, taken: bool);
    /// A `DJNZ` delay loop onto itself at `pc` ran `times` times in closed form; every time
    /// jumped back but, when `ended`, the last.
    fn looped(&mut self, pc: u16, times: u32, ended: bool);
}

/// Coverage off: every call is empty and folds away.
impl Cover for () {
    #[inline(always)]
    fn ran(&mut self, _pc: u16) {}
    #[inline(always)]
    fn jumped(&mut self, _pc: u16, _taken: bool) {}
    #[inline(always)]
    fn looped(&mut self, _pc: u16, _times: u32, _ended: bool) {}
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
