//! Timers 0 and 1, the serial transmitter's timing, and idle skipping.
//!
//! Timers are brought up to date lazily, in closed form: only when the program touches a timer,
//! serial or P3 register, when the caller changes a pin, at the end of `step`/`run`, and when the
//! cycle count reaches the next event (a timer overflow or the end of a serial character), which
//! is computed ahead. The result is exactly that of counting every machine cycle.
//!
//! Modes (Intel MCS-51 User's Manual, "Timer/Counters"): 0 = 13 bits (TH and the low 5 bits of
//! TL; the manual calls TL's upper 3 bits indeterminate, they read 0 here as in s51), 1 = 16
//! bits, 2 = TL with auto-reload from TH, 3 = timer 0 as two 8-bit timers (TL0 with TR0/TF0, TH0
//! counting cycles with TR1/TF1) while timer 1 in mode 3 stops. While timer 0 is in mode 3,
//! timer 1 runs whenever it is not in mode 3 and sets no flag (it can still clock the serial
//! port). In counter mode (C/T = 1) a timer counts falling edges of its pin (T0 = P3.4,
//! T1 = P3.5) as the caller drives them.

use super::{Cpu, PCON, SCON, TCON, TH0, TH1, TL0, TL1, TMOD, Tx};
use crate::Cover;
use crate::decode::{Ins, OPS, Opnd};

/// Adds `inc` to an up-counter of `bits` bits; returns the new value and the overflow count.
fn count(value: u32, inc: u64, bits: u32) -> (u32, u64) {
    let total = value as u64 + inc;
    ((total & ((1 << bits) - 1)) as u32, total >> bits)
}

impl Cpu {
    fn r(&self, a: u8) -> u8 {
        self.sfr[(a - 0x80) as usize]
    }
    fn w(&mut self, a: u8, v: u8) {
        self.sfr[(a - 0x80) as usize] = v;
    }

    /// Whether timer `t` (0/1) counts: TRx, and GATE clear or INTx high.
    #[inline(always)]
    fn gated_on(&self, t: usize, tr: bool) -> bool {
        tr && (self.r(TMOD) >> (4 * t) & 0x08 == 0 || self.pins(3) & (0x04 << t) != 0)
    }

    /// Brings timers and the serial transmitter up to cycle `to`.
    /// The next event's cycle stands until it has passed: counting towards it moves it no
    /// nearer in time (what changes the counting, a write to a timer, serial, ADC or port
    /// register or a pin, plans again itself).
    pub(crate) fn sync(&mut self, to: u64) {
        let passed = to >= self.next_event;
        if passed {
            self.last_event = self.next_event;
        }
        if to > self.synced {
            let n = to - self.synced;
            self.synced = to;
            self.advance_timers(n, false);
        }
        if passed {
            self.plan();
        }
    }

    /// Computes the cycle of the next timer or serial event.
    pub(crate) fn plan(&mut self) {
        self.next_event = match self.cycles_to_event() {
            Some(d) => self.synced + d,
            None => u64::MAX,
        };
    }

    /// A falling edge on T0 (`t` = 0) or T1 (`t` = 1): one count if that timer is a counter.
    pub(crate) fn count_edge(&mut self, t: usize) {
        if self.r(TMOD) >> (4 * t) & 0x04 != 0 {
            self.advance_timers(1, true);
            self.plan();
        }
    }

    /// Advances by `n` machine cycles (`edge`: by one edge on the counter inputs instead).
    fn advance_timers(&mut self, n: u64, edge: bool) {
        let tcon = self.r(TCON);
        let tmod = self.r(TMOD);
        // Cycles for timers, edges for counters.
        let inc = |t: usize| {
            if (tmod >> (4 * t) & 0x04 != 0) == edge {
                n
            } else {
                0
            }
        };
        let cycles = if edge { 0 } else { n };
        let m0 = tmod & 3;
        let m1 = tmod >> 4 & 3;
        if self.gated_on(0, tcon & 0x10 != 0) && self.advance(TL0, TH0, m0, inc(0)) > 0 {
            self.raise(TCON, 0x20);
        }
        if m0 == 3 && tcon & 0x40 != 0 {
            let (th, ov) = count(self.r(TH0) as u32, cycles, 8);
            self.w(TH0, th as u8);
            if ov > 0 {
                self.raise(TCON, 0x80);
            }
        }
        let mut ov1 = 0;
        if m1 != 3 && self.gated_on(1, m0 == 3 || tcon & 0x40 != 0) {
            ov1 = self.advance(TL1, TH1, m1, inc(1));
            if ov1 > 0 && m0 != 3 {
                self.raise(TCON, 0x80);
            }
        }
        if self.cc03() {
            let ov2 = self.advance_timer2(cycles, false);
            self.adc_tick();
            if self.tx_on_timer2() {
                self.serial_tick(cycles, ov2);
                return;
            }
        }
        self.serial_tick(cycles, ov1);
    }

    /// Counts `inc` on the timer (TL, TH) in `mode` (0–3, mode 3 counting TL only); returns the
    /// number of overflows.
    fn advance(&mut self, tl: u8, th: u8, mode: u8, inc: u64) -> u64 {
        if inc == 0 {
            return 0;
        }
        let (l, h) = (self.r(tl) as u32, self.r(th) as u32);
        match mode {
            0 => {
                let (v, ov) = count(h << 5 | (l & 0x1F), inc, 13);
                self.w(tl, v as u8 & 0x1F);
                self.w(th, (v >> 5) as u8);
                ov
            }
            1 => {
                let (v, ov) = count(h << 8 | l, inc, 16);
                self.w(tl, v as u8);
                self.w(th, (v >> 8) as u8);
                ov
            }
            2 => {
                let total = l as u64 + inc;
                if total < 256 {
                    self.w(tl, total as u8);
                    return 0;
                }
                let over = total - 256;
                let period = 256 - h as u64;
                self.w(tl, (h as u64 + over % period) as u8);
                1 + over / period
            }
            _ => {
                let (v, ov) = count(l, inc, 8);
                self.w(tl, v as u8);
                ov
            }
        }
    }

    /// A byte written to SBUF: emitted now, TI set after its character time.
    pub(crate) fn transmit(&mut self, v: u8) {
        self.serial_out.push(v);
        let scon = self.r(SCON);
        let smod = self.r(PCON) & 0x80 != 0;
        let tmod = self.r(TMOD);
        let t1_runs = tmod >> 4 & 3 != 3 && (tmod & 3 == 3 || self.r(TCON) & 0x40 != 0);
        // Timer 2 as baud-rate generator (TCLK): 16 overflows per bit, SMOD does not apply.
        let (runs, per_bit) = if self.tx_on_timer2() {
            (self.timer2_runs(), 16)
        } else {
            (t1_runs, if smod { 16 } else { 32 })
        };
        self.tx = match scon >> 6 {
            0 => Tx::Cycles(8),
            2 => Tx::Cycles(if smod { 30 } else { 59 }), // 11 bits × 32 or 64 clocks / 12
            mode if runs => {
                let bits = if mode == 1 { 10 } else { 11 };
                Tx::Overflows(bits * per_bit)
            }
            _ => {
                self.w(SCON, scon | 0x02);
                Tx::Idle
            }
        };
        self.plan();
    }

    /// `n` machine cycles and `ov1` overflows of the transmitter's clock (timer 1, or timer 2
    /// with TCLK) passed.
    pub(crate) fn serial_tick(&mut self, n: u64, ov1: u64) {
        let left = match self.tx {
            Tx::Idle => return,
            Tx::Cycles(c) => (c as u64).saturating_sub(n),
            Tx::Overflows(o) => (o as u64).saturating_sub(ov1),
        };
        self.tx = match (self.tx, left) {
            (_, 0) => {
                self.raise(SCON, 0x02);
                Tx::Idle
            }
            (Tx::Cycles(_), l) => Tx::Cycles(l as u32),
            (_, l) => Tx::Overflows(l as u32),
        };
    }

    /// Cycles from `synced` to the next timer overflow or serial event, if any is coming.
    fn cycles_to_event(&self) -> Option<u64> {
        let tcon = self.r(TCON);
        let tmod = self.r(TMOD);
        let (m0, m1) = (tmod & 3, tmod >> 4 & 3);
        let mut d = u64::MAX;
        let to = |tl: u8, th: u8, mode: u8| -> u64 {
            let (l, h) = (self.r(tl) as u64, self.r(th) as u64);
            match mode {
                0 => 0x2000 - (h << 5 | (l & 0x1F)),
                1 => 0x1_0000 - (h << 8 | l),
                _ => 256 - l,
            }
        };
        if tmod & 0x04 == 0 && self.gated_on(0, tcon & 0x10 != 0) {
            d = d.min(to(TL0, TH0, m0));
        }
        if m0 == 3 && tcon & 0x40 != 0 {
            d = d.min(256 - self.r(TH0) as u64);
        }
        if tmod & 0x40 == 0 && m1 != 3 && self.gated_on(1, m0 == 3 || tcon & 0x40 != 0) {
            d = d.min(to(TL1, TH1, m1));
        }
        if let Tx::Cycles(c) = self.tx {
            d = d.min(c as u64);
        }
        if self.cc03() {
            let tx_waits = matches!(self.tx, Tx::Overflows(_)) && self.tx_on_timer2();
            if let Some(t2) = self.timer2_cycles_to_event(tx_waits) {
                d = d.min(t2);
            }
            // The ADC's end and the watchdog's time-out are absolute cycles.
            for at in [self.adc_end, self.wdt_deadline] {
                if at != u64::MAX {
                    d = d.min(at.saturating_sub(self.synced).max(1));
                }
            }
        }
        (d != u64::MAX).then_some(d)
    }

    /// At a `DJNZ Rn,$` or `DJNZ direct,$` (direct in internal RAM), runs as many iterations as
    /// stepping would before `until` or before any interrupt could be taken, in closed form.
    /// Returns false if the instruction is not such a loop or nothing may be skipped; else
    /// tells `cover` of the iterations passed ([`Cover::looped`]).
    pub(crate) fn skip_delay_loop<C: Cover>(&mut self, until: u64, cover: &mut C) -> bool {
        let pc = self.pc;
        let d = OPS[self.code[pc as usize] as usize];
        let byte = |k: u8| self.code[pc.wrapping_add(k as u16) as usize];
        // A loop onto itself: the relative offset, the last byte, is minus the length.
        if d.ins != Ins::Djnz || byte(d.len - 1) as i8 != -(d.len as i8) {
            return false;
        }
        let (len, per) = (d.len as u16, d.cycles as u64);
        let addr = match d.opnds[0] {
            Opnd::Rn(n) => (self.psw() & 0x18) | n,
            Opnd::Direct if byte(1) < 0x80 => byte(1),
            _ => return false,
        };
        let value = self.iram[addr as usize];
        let mut k = if value == 0 { 256 } else { value as u64 };
        // Iteration i starts at cycles + per * i and runs only while that is below `until`.
        k = k.min(until.saturating_sub(self.cycles).div_ceil(per));
        if self.interrupt_possible() {
            if self.request_takeable() {
                // Held off for one instruction only (after RETI or an IE/IP write).
                return false;
            }
            // The iteration whose cycles reach the event is the last one that runs unpolled.
            k = k.min(self.next_event.saturating_sub(self.cycles).div_ceil(per));
        }
        // The watchdog resets the core whether or not interrupts are enabled.
        k = k.min(self.wdt_deadline.saturating_sub(self.cycles).div_ceil(per));
        if k < 2 {
            return false;
        }
        self.iram[addr as usize] = value.wrapping_sub(k as u8);
        let ended = self.iram[addr as usize] == 0;
        if ended {
            self.pc = self.pc.wrapping_add(len);
        }
        self.cycles += per * k;
        self.skipped += per * k;
        if self.cycles >= self.next_event {
            self.sync(self.cycles);
        }
        self.inhibit = false;
        cover.looped(pc, k as u32, ended);
        true
    }
}
