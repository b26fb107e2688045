//! Interrupt sources, priorities and entry (Intel MCS-51 User's Manual, "Interrupts").
//!
//! Sources in polling order within a level: IE0 (vector 03h), TF0 (0Bh), IE1 (13h), TF1 (1Bh),
//! RI or TI (23h). Each source is low or high priority by its IP bit; a high-priority request
//! interrupts a low-priority handler, nothing interrupts a high-priority one, and a request is
//! not taken while a handler of its own level runs. No interrupt is taken right after RETI or a
//! write to IE or IP (the next instruction runs first). The hardware call takes 2 machine cycles
//! (settable: s51 takes 1, see [`Cpu::set_interrupt_entry_cycles`]) and clears IE0/IE1 (edge
//! mode only) and TF0/TF1, never RI/TI.
//!
//! The AT89C51CC03 (data sheet, "Interrupt System") has eleven sources with four priority
//! levels each, IPHx:IPLx = 00 (lowest) to 11 (highest). A request interrupts a handler of a
//! lower level only. In polling order within a level: INT0 (03h), TF0 (0Bh), INT1 (13h),
//! TF1 (1Bh), PCA (33h), serial (23h), timer 2 TF2|EXF2 (2Bh), CAN (3Bh), ADC ADEOC (43h), CAN
//! timer overrun (4Bh), SPI (53h). IEN0 = IE (EA 7, EC 6, ET2 5, ES 4, ET1 3, EX1 2, ET0 1,
//! EX0 0) with IPL0 = IP and IPH0 using the same bit positions; IEN1 (ESPI 3, ETIM 2, EADC 1,
//! ECAN 0) with IPL1/IPH1 likewise. Vectoring clears only what the 80C51 clears; TF2, EXF2
//! and ADEOC stay for the handler to clear, and the outside sources ([`crate::irq`]) are
//! levels the caller's peripheral drops.

use super::cc03::{IEN1, IPH0, IPH1, IPL1};
use super::{Cpu, IE, IP, SCON, TCON, adc::ADCON, timer2::T2CON};
use crate::{Error, irq};

/// Vectors by IE bit: IE0, TF0, IE1, TF1, RI|TI.
const VECTORS: [u16; 5] = [0x03, 0x0B, 0x13, 0x1B, 0x23];

/// AT89C51CC03 sources in polling order: (vector, register set 0 = IEN0/IPL0/IPH0 or
/// 1 = IEN1/IPL1/IPH1, bit).
const CC03_SOURCES: [(u16, usize, u8); 11] = [
    (0x03, 0, 0),
    (0x0B, 0, 1),
    (0x13, 0, 2),
    (0x1B, 0, 3),
    (0x33, 0, 6),
    (0x23, 0, 4),
    (0x2B, 0, 5),
    (0x3B, 1, 0),
    (0x43, 1, 1),
    (0x4B, 1, 2),
    (0x53, 1, 3),
];

impl Cpu {
    /// The requests that are pending and enabled, as IE bits (EA ignored).
    #[inline(always)]
    fn requests(&self) -> u8 {
        let tcon = self.sfr[(TCON - 0x80) as usize];
        let scon = self.sfr[(SCON - 0x80) as usize];
        // TCON: IE0 bit 1, IE1 bit 3, TF0 bit 5, TF1 bit 7 -> IE bits 0, 2, 1, 3.
        let r = (tcon >> 1 & 0x01)
            | (tcon >> 1 & 0x04)
            | (tcon >> 4 & 0x02)
            | (tcon >> 4 & 0x08)
            | if scon & 0x03 != 0 { 0x10 } else { 0 };
        r & self.sfr[(IE - 0x80) as usize]
    }

    /// Whether interrupts are enabled at all (EA), so that a timer event may start one.
    pub(crate) fn interrupt_possible(&self) -> bool {
        self.sfr[(IE - 0x80) as usize] & 0x80 != 0
    }

    /// Whether a pending, enabled request is not held off by a handler in service (the
    /// one-instruction delay after RETI or an IE/IP write aside).
    pub(crate) fn request_takeable(&self) -> bool {
        if self.cc03() {
            return self.cc03_choice().is_some();
        }
        let req = self.requests();
        let ip = self.sfr[(IP - 0x80) as usize];
        (req & ip != 0 && self.in_service & 2 == 0) || (req & !ip != 0 && self.in_service == 0)
    }

    /// The AT89C51CC03 request to take now, as (polling index, level), if any: the highest
    /// level pending and enabled, first in polling order, if no handler of that level or
    /// above runs.
    fn cc03_choice(&self) -> Option<(usize, u8)> {
        let r = |a: u8| self.sfr[(a - 0x80) as usize];
        let (ie, ien1) = (r(IE), r(IEN1));
        let bit = |on: bool, n: u8| u8::from(on) << n;
        // Requests at their enable bits' positions in IEN0 and IEN1, of enabled sources only:
        // most instructions find none, and pay only for this.
        let mut wanted = [0, 0];
        let e0 = ie & 0x7F;
        if e0 != 0 {
            // Each enabled source's flag, and only those: most programs enable one or two.
            let mut w = 0;
            if e0 & 0x0F != 0 {
                let tcon = r(TCON);
                w |= bit(tcon & 0x02 != 0, 0)
                    | bit(tcon & 0x20 != 0, 1)
                    | bit(tcon & 0x08 != 0, 2)
                    | bit(tcon & 0x80 != 0, 3);
            }
            if e0 & 0x10 != 0 && r(SCON) & 0x03 != 0 {
                w |= 0x10;
            }
            if e0 & 0x20 != 0 && r(T2CON) & 0xC0 != 0 {
                w |= 0x20;
            }
            if e0 & 0x40 != 0 && self.ext_irq & irq::PCA != 0 {
                w |= 0x40;
            }
            wanted[0] = w & ie;
        }
        if ien1 & 0x0F != 0 {
            let ext = self.ext_irq;
            wanted[1] = ien1
                & (bit(ext & irq::CAN != 0, 0)
                    | bit(r(ADCON) & 0x10 != 0, 1)
                    | bit(ext & irq::CAN_TIMER != 0, 2)
                    | bit(ext & irq::SPI != 0, 3));
        }
        if wanted == [0, 0] {
            return None;
        }
        let ipl = [r(IP), r(IPL1)];
        let iph = [r(IPH0), r(IPH1)];
        let mut best: Option<(usize, u8)> = None;
        for (k, &(_, set, bit)) in CC03_SOURCES.iter().enumerate() {
            if wanted[set] >> bit & 1 == 0 {
                continue;
            }
            let level = (iph[set] >> bit & 1) << 1 | (ipl[set] >> bit & 1);
            if best.is_none_or(|(_, l)| level > l) {
                best = Some((k, level));
            }
        }
        best.filter(|&(_, level)| self.in_service >> level == 0)
    }

    /// Whether any AT89C51CC03 request flag is up, outside requests counted only when enabled
    /// (a CAN timer overrun nobody enabled stays up for ever): most instructions find none.
    #[inline(always)]
    fn cc03_flag_up(&self, ie: u8) -> bool {
        let r = |a: u8| self.sfr[(a - 0x80) as usize];
        let ien1 = r(IEN1);
        let outside = (if ie & 0x40 != 0 { irq::PCA } else { 0 }) | (ien1 & 0x01) << 1 | (ien1 & 0x0C);
        (r(TCON) & 0xAA) | (r(SCON) & 0x03) | (r(T2CON) & 0xC0) | (r(ADCON) & 0x10) | (self.ext_irq & outside)
            != 0
    }

    /// The poll found nothing to take: so will the next ones until something they read changes
    /// ([`Cpu::irq_quiet`]).
    fn quiet(&mut self) -> Option<u16> {
        self.irq_quiet = true;
        None
    }

    /// Sets `bits` of the flag register `reg`; a flag that goes up may start an interrupt.
    #[inline(always)]
    pub(crate) fn raise(&mut self, reg: u8, bits: u8) {
        let r = &mut self.sfr[(reg - 0x80) as usize];
        if *r & bits != bits {
            *r |= bits;
            self.irq_quiet = false;
        }
    }

    /// The outside requests as the peripheral shows them now ([`crate::Xdata::irq`]).
    #[inline(always)]
    pub(crate) fn set_ext_irq(&mut self, v: u8) {
        if v != self.ext_irq {
            self.ext_irq = v;
            self.irq_quiet = false;
        }
    }

    /// Enters the highest-priority pending interrupt, if one may be taken now.
    #[inline(always)]
    pub(crate) fn poll_interrupt(&mut self) -> Result<Option<u16>, Error> {
        if self.irq_quiet {
            debug_assert!(
                !(self.interrupt_possible() && self.request_takeable()),
                "a request became takeable at {:04X}h without clearing irq_quiet",
                self.pc
            );
            self.inhibit = false;
            return Ok(None);
        }
        let ie = self.sfr[(IE - 0x80) as usize];
        if self.inhibit {
            self.inhibit = false;
            return Ok(None);
        }
        // From here on, a poll that takes nothing finds the same until something it reads
        // changes.
        if ie & 0x80 == 0 {
            return Ok(self.quiet());
        }
        let (index, level, vector) = if self.cc03() {
            if !self.cc03_flag_up(ie) {
                return Ok(self.quiet());
            }
            match self.cc03_choice() {
                Some((k, level)) => (k, 1 << level, CC03_SOURCES[k].0),
                None => return Ok(self.quiet()),
            }
        } else {
            let req = self.requests();
            if req == 0 {
                return Ok(self.quiet());
            }
            let ip = self.sfr[(IP - 0x80) as usize];
            let (level, chosen) = if req & ip != 0 && self.in_service & 2 == 0 {
                (2, req & ip)
            } else if req & !ip != 0 && self.in_service == 0 {
                (1, req & !ip)
            } else {
                return Ok(self.quiet());
            };
            let index = chosen.trailing_zeros() as usize;
            (index, level, VECTORS[index])
        };
        self.op_pc = self.pc;
        let [lo, hi] = self.pc.to_le_bytes();
        self.push(lo)?;
        self.push(hi)?;
        let tcon = &mut self.sfr[(TCON - 0x80) as usize];
        match index {
            0 if *tcon & 0x01 != 0 => *tcon &= !0x02,
            2 if *tcon & 0x04 != 0 => *tcon &= !0x08,
            1 => *tcon &= !0x20,
            3 => *tcon &= !0x80,
            _ => {}
        }
        self.in_service |= level;
        self.irq_quiet = false;
        self.pc = vector;
        self.cycles += self.entry_cycles as u64;
        if self.cycles >= self.next_event {
            self.sync(self.cycles);
        }
        Ok(Some(vector))
    }

    /// RETI: the highest level in service ends.
    pub(crate) fn end_of_interrupt(&mut self) {
        if self.in_service != 0 {
            self.in_service &= !(0x80 >> self.in_service.leading_zeros());
        }
        self.inhibit = true;
        self.irq_quiet = false;
    }

    /// Level mode (ITx = 0): IEx follows the inverted INTx pin, it is not latched.
    pub(crate) fn sync_ext_ints(&mut self) {
        self.irq_quiet = false;
        let pins = self.pins(3);
        let tcon = &mut self.sfr[(TCON - 0x80) as usize];
        for (it, ie, pin) in [(0x01, 0x02, 0x04), (0x04, 0x08, 0x08)] {
            if *tcon & it == 0 {
                if pins & pin == 0 {
                    *tcon |= ie;
                } else {
                    *tcon &= !ie;
                }
            }
        }
    }

    /// P3 pins changed (latch write or external level): INT edges and counter edges.
    pub(crate) fn p3_changed(&mut self, before: u8) {
        self.irq_quiet = false;
        let after = self.pins(3);
        let falling = before & !after;
        let tcon = &mut self.sfr[(TCON - 0x80) as usize];
        if falling & 0x04 != 0 && *tcon & 0x01 != 0 {
            *tcon |= 0x02;
        }
        if falling & 0x08 != 0 && *tcon & 0x04 != 0 {
            *tcon |= 0x08;
        }
        if falling & 0x10 != 0 {
            self.count_edge(0);
        }
        if falling & 0x20 != 0 {
            self.count_edge(1);
        }
        self.sync_ext_ints();
    }
}
