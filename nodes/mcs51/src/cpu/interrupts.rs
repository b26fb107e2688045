//! Interrupt sources, priorities and entry (Intel MCS-51 User's Manual, "Interrupts").
//!
//! Sources in polling order within a level: IE0 (vector 03h), TF0 (0Bh), IE1 (13h), TF1 (1Bh),
//! RI or TI (23h). Each source is low or high priority by its IP bit; a high-priority request
//! interrupts a low-priority handler, nothing interrupts a high-priority one, and a request is
//! not taken while a handler of its own level runs. No interrupt is taken right after RETI or a
//! write to IE or IP (the next instruction runs first). The hardware call takes 2 machine cycles
//! (settable: s51 takes 1, see [`Cpu::set_interrupt_entry_cycles`]) and clears IE0/IE1 (edge
//! mode only) and TF0/TF1, never RI/TI.

use super::{Cpu, IE, IP, SCON, TCON};
use crate::Error;

/// Vectors by IE bit: IE0, TF0, IE1, TF1, RI|TI.
const VECTORS: [u16; 5] = [0x03, 0x0B, 0x13, 0x1B, 0x23];

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
        let req = self.requests();
        let ip = self.sfr[(IP - 0x80) as usize];
        (req & ip != 0 && self.in_service & 2 == 0) || (req & !ip != 0 && self.in_service == 0)
    }

    /// Enters the highest-priority pending interrupt, if one may be taken now.
    #[inline(always)]
    pub(crate) fn poll_interrupt(&mut self) -> Result<Option<u16>, Error> {
        let ie = self.sfr[(IE - 0x80) as usize];
        if ie & 0x80 == 0 || self.inhibit {
            self.inhibit = false;
            return Ok(None);
        }
        let req = self.requests();
        if req == 0 {
            return Ok(None);
        }
        let ip = self.sfr[(IP - 0x80) as usize];
        let (level, chosen) = if req & ip != 0 && self.in_service & 2 == 0 {
            (2, req & ip)
        } else if req & !ip != 0 && self.in_service == 0 {
            (1, req & !ip)
        } else {
            return Ok(None);
        };
        let index = chosen.trailing_zeros() as usize;
        let vector = VECTORS[index];
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
        self.pc = vector;
        self.cycles += self.entry_cycles as u64;
        if self.cycles >= self.next_event {
            self.sync(self.cycles);
        }
        Ok(Some(vector))
    }

    /// RETI: the highest level in service ends.
    pub(crate) fn end_of_interrupt(&mut self) {
        if self.in_service & 2 != 0 {
            self.in_service &= !2;
        } else {
            self.in_service = 0;
        }
        self.inhibit = true;
    }

    /// Level mode (ITx = 0): IEx follows the inverted INTx pin, it is not latched.
    pub(crate) fn sync_ext_ints(&mut self) {
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
