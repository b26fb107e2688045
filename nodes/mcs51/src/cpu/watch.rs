//! What a caller that wires the core to an outside world needs to see: reads of inputs it brings
//! up to date only now and then, writes of latches that drive that world, and what makes a
//! loop's turns differ or not.
//!
//! - **Inputs.** The caller names the port pins and ADC channels it drives
//!   ([`Cpu::watch`]) and says up to which machine cycle their levels hold
//!   ([`Cpu::inputs_hold_until`]). From that cycle on, [`Cpu::run`] stops before an instruction
//!   that addresses a watched pin or its port (a read-modify-write of the port too: the check is
//!   by operand, before execution), at the first instruction boundary within [`ADC_LEAD`]
//!   cycles of the end of a conversion of a watched channel, and at its first boundary when a
//!   timer, serial, ADC or watchdog event (what wakes a program to read its inputs) took effect
//!   since the inputs were set, so that the caller can set the levels of that moment first
//!   ([`RunEnd::InputsDue`]).
//! - **Outputs.** [`Cpu::run`] stops after an instruction that changes a watched latch bit
//!   ([`RunEnd::OutputChanged`]), so that the caller drives the world from that moment.
//! - **Idle turns.** [`Cpu::same_but_time`] compares two states but for what counting time
//!   changes (timer counts, a serial character's progress); [`Cpu::idle`] lets cycles pass with
//!   nothing executed, the timers counting. A loop that reads no timer count
//!   ([`Cpu::time_reads`]), comes back to its state but for time, and meets no event on the way,
//!   turns the same way until the next event: its turns can be passed with [`Cpu::idle`].

use super::adc::ADCON;
use super::{Cpu, RunEnd};
use crate::decode::{OPS, Opnd};
use std::sync::Arc;

/// Cycles before a conversion's end at which the core stops for fresh analog levels: the
/// longest instruction (MUL, DIV), so that no instruction started earlier ends past it.
pub const ADC_LEAD: u64 = 4;

/// The pins and channels a caller drives, and the latch bits that drive it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Watched {
    /// Port 0–3 input pins, by bit.
    pub pins: [u8; 4],
    /// ADC channels 0–7, by bit.
    pub channels: u8,
    /// Port 0–3 latch bits that drive the outside.
    pub outputs: [u8; 4],
}

impl Cpu {
    /// Watches `w` from now on; its inputs hold until [`Cpu::inputs_hold_until`] says (not at
    /// all until then).
    pub fn watch(&mut self, w: Watched) {
        self.watched = w;
        self.stale_from = 0;
    }

    /// The watched inputs were set now, and their levels hold for machine cycles before
    /// `cycle`.
    pub fn inputs_hold_until(&mut self, cycle: u64) {
        self.stale_from = cycle;
        self.served_at = self.cycles;
    }

    /// The first machine cycle at which the watched inputs no longer hold.
    pub fn stale_from(&self) -> u64 {
        self.stale_from
    }

    /// Whether the next instruction must wait for fresh input levels (see the module docs).
    pub fn inputs_due(&self) -> bool {
        if self.cycles < self.stale_from {
            return false;
        }
        if self.last_event >= self.served_at {
            return true;
        }
        let con = self.sfr[(ADCON - 0x80) as usize];
        if self.adc_end != u64::MAX
            && self.cycles + ADC_LEAD >= self.adc_end
            && self.watched.channels & (1 << (con & 7)) != 0
        {
            return true;
        }
        self.addresses_watched_pin()
    }

    /// Whether the instruction at PC names a watched pin, or the port of one, as an operand.
    fn addresses_watched_pin(&self) -> bool {
        let pins = self.watched.pins;
        if pins == [0; 4] {
            return false;
        }
        let d = &OPS[self.code[self.pc as usize] as usize];
        let mut at = self.pc.wrapping_add(1);
        for o in d.opnds {
            let byte = self.code[at as usize];
            match o {
                Opnd::Direct if byte & 0xCF == 0x80 && pins[usize::from(byte >> 4 & 3)] != 0 => {
                    return true;
                }
                Opnd::Bit | Opnd::NotBit
                    if byte >= 0x80
                        && byte & 0xC8 == 0x80
                        && pins[usize::from(byte >> 4 & 3)] & (1 << (byte & 7)) != 0 =>
                {
                    return true;
                }
                _ => {}
            }
            at = at.wrapping_add(u16::from(o.bytes()));
        }
        false
    }

    /// Notes a write of `v` to port `port`'s latch, which held `old`.
    pub(crate) fn port_written(&mut self, port: usize, old: u8, v: u8) {
        if self.watched.outputs[port] & (old ^ v) != 0 {
            self.output_changed = true;
            self.attention = true;
        }
    }

    /// Reads of watched inputs so far: instructions that read a watched pin's port, and
    /// conversions of a watched channel.
    pub fn input_reads(&self) -> u64 {
        self.input_reads
    }

    /// Reads of timer counts (TLx, THx) so far: what a loop whose turns repeat must not do.
    pub fn time_reads(&self) -> u64 {
        self.time_reads
    }

    /// Lets `cycles` machine cycles pass with nothing executed: timers, the serial port and the
    /// ADC count, events falling due on the way take effect. For a caller that found the core in
    /// a loop whose turns repeat (see the module docs). Counted in [`Cpu::skipped_cycles`].
    pub fn idle(&mut self, cycles: u64) {
        self.sync(self.cycles);
        self.cycles = self.cycles.saturating_add(cycles);
        self.skipped = self.skipped.saturating_add(cycles);
        self.sync(self.cycles);
    }

    /// The machine cycle of the next timer, serial, ADC or watchdog event (`u64::MAX`: none is
    /// coming).
    pub fn next_event(&self) -> u64 {
        self.next_event
    }

    /// True when `other` is in the same state as `self` but for the cycle count and what counting
    /// time changes: timer counts and a serial character's progress (compare both after the
    /// same number of cycles have passed on one of them with [`Cpu::idle`]).
    pub fn same_but_time(&self, other: &Cpu) -> bool {
        self.pc == other.pc
            && self.iram == other.iram
            && self.sfr == other.sfr
            && self.tx == other.tx
            && self.fault == other.fault
            && self.ext == other.ext
            && self.inhibit == other.inhibit
            && self.ext_irq == other.ext_irq
            && self.in_service == other.in_service
            && self.adc_end == other.adc_end
            && self.analog == other.analog
            && self.analog_high == other.analog_high
            && self.mux == other.mux
            && self.wdt_deadline == other.wdt_deadline
            && self.wdt_armed == other.wdt_armed
            && self.clock_base == other.clock_base
            && (Arc::ptr_eq(&self.xram, &other.xram) || self.xram == other.xram)
    }

    /// Sets the level of analog input `channel` while port `port` bit `bit`'s latch is high,
    /// through a multiplexer in front of the channel ([`Cpu::set_analog`] sets the other): a
    /// conversion takes the input the latch selects when it ends.
    pub fn set_analog_mux(&mut self, channel: u8, port: u8, bit: u8, code: u16) {
        if let (Some(m), Some(a)) = (
            self.mux.get_mut(channel as usize),
            self.analog_high.get_mut(channel as usize),
        ) {
            *m = Some((port & 3, bit & 7));
            *a = code.min(1023);
        }
    }

    /// Makes [`Cpu::run`] stop after an instruction that leaves the PC at `pc` (`None`: never),
    /// as when a loop comes back to its head.
    pub fn stop_at_pc(&mut self, pc: Option<u16>) {
        self.stop_pc = pc.map_or(u32::MAX, u32::from);
    }

    /// How far a DJNZ delay loop may be passed in closed form before `until`: not into the
    /// stretch before the end of a conversion of a watched channel, where the core may have to
    /// stop for fresh levels.
    pub(crate) fn djnz_bound(&self, until: u64) -> u64 {
        let con = self.sfr[(ADCON - 0x80) as usize];
        if self.adc_end != u64::MAX && self.watched.channels & (1 << (con & 7)) != 0 {
            until.min(self.adc_end.saturating_sub(ADC_LEAD))
        } else {
            until
        }
    }

    /// Whether an instruction changed a watched latch bit since the last call ([`Cpu::run`]
    /// stops after it; after [`Cpu::step`] the caller asks).
    pub fn take_output_changed(&mut self) -> bool {
        std::mem::take(&mut self.output_changed)
    }

    /// The stop [`Cpu::run`] makes for the watched outputs, if one is due.
    pub(crate) fn watch_stop(&mut self) -> Option<RunEnd> {
        self.take_output_changed().then_some(RunEnd::OutputChanged)
    }
}
