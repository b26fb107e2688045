//! The AT89C51CC03's own SFRs besides timer 2 and the ADC: AUXR and the on-chip XRAM, CKCON
//! (X2 mode), the watchdog (WDTRST, WDTPRG) and the extra interrupt registers.
//!
//! Addresses and bits follow the AT89C51CC03 data sheet (SFR mapping table; sections "Expanded
//! RAM (XRAM)", "X2 Feature", "Hardware Watchdog Timer", "Interrupt System").

use std::sync::Arc;

use super::{Cpu, IE, IP, P1, P3, SBUF, SCON, TCON, TH0, TH1, TL0, TL1, TMOD, XAccess};
use super::{adc, timer2};
use crate::Xdata;

pub(crate) const AUXR: u8 = 0x8E;
pub(crate) const CKCON: u8 = 0x8F;
pub(crate) const WDTRST: u8 = 0xA6;
pub(crate) const WDTPRG: u8 = 0xA7;
pub(crate) const IPH0: u8 = 0xB7;
pub(crate) const IEN1: u8 = 0xE8;
pub(crate) const IPH1: u8 = 0xF7;
pub(crate) const IPL1: u8 = 0xF8;

/// Bytes of on-chip expanded RAM (XRAM) on the AT89C51CC03.
pub const XRAM_BYTES: usize = 2048;

/// XRAM sizes selected by AUXR.XRS2:0 (values 6 and 7 are reserved; they select 2048 here).
const XRAM_SIZES: [u16; 8] = [256, 512, 768, 1024, 1792, 2048, 2048, 2048];

/// AUXR at reset: XRS2:0 = 101b (the whole 2048 bytes), EXTRAM = 0 (MOVX reaches the XRAM).
pub(crate) const AUXR_RESET: u8 = 0x14;

const OWN: [u8; 19] = [
    AUXR,
    CKCON,
    WDTRST,
    WDTPRG,
    IPH0,
    timer2::T2CON,
    timer2::T2MOD,
    timer2::RCAP2L,
    timer2::RCAP2H,
    timer2::TL2,
    timer2::TH2,
    IEN1,
    adc::ADCLK,
    adc::ADCON,
    adc::ADDL,
    adc::ADDH,
    adc::ADCF,
    IPH1,
    IPL1,
];

/// SFRs the core implements on the AT89C51CC03 (the 80C51's and [`OWN`]).
pub(crate) const CC03_OWN: [bool; 128] = {
    let mut t = super::WRITABLE;
    let mut i = 0;
    while i < OWN.len() {
        t[(OWN[i] - 0x80) as usize] = true;
        i += 1;
    }
    t
};

/// SFRs brought up to date before an access on the AT89C51CC03: the 80C51's timed SFRs, P1
/// (T2 and T2EX pins), timer 2, the ADC, the watchdog and CKCON.
pub(crate) const CC03_TIMED: [bool; 128] = {
    let mut t = [false; 128];
    let timed = [
        TCON,
        TMOD,
        TL0,
        TL1,
        TH0,
        TH1,
        SCON,
        SBUF,
        P3,
        P1,
        CKCON,
        WDTRST,
        WDTPRG,
        timer2::T2CON,
        timer2::T2MOD,
        timer2::RCAP2L,
        timer2::RCAP2H,
        timer2::TL2,
        timer2::TH2,
        adc::ADCON,
        adc::ADDL,
        adc::ADDH,
        adc::ADCLK,
    ];
    let mut i = 0;
    while i < timed.len() {
        t[(timed[i] - 0x80) as usize] = true;
        i += 1;
    }
    t
};

/// Registers whose write holds off interrupts for one instruction, as IE and IP do.
pub(crate) fn is_interrupt_register(addr: u8) -> bool {
    matches!(addr, IE | IP | IPH0 | IEN1 | IPL1 | IPH1)
}

impl Cpu {
    /// Oscillator clocks per machine cycle: 12, or 6 in X2 mode (AT89C51CC03 CKCON.X2).
    pub fn clocks_per_cycle(&self) -> u64 {
        if self.cc03() && self.sfr[(CKCON - 0x80) as usize] & 1 != 0 {
            6
        } else {
            12
        }
    }

    /// Oscillator clocks since the core was made, machine cycles weighted by the
    /// [`Cpu::clocks_per_cycle`] in force while they ran.
    pub fn clocks(&self) -> u64 {
        let (cycles, clocks) = self.clock_base;
        clocks + (self.cycles - cycles) * self.clocks_per_cycle()
    }

    /// Oscillator clocks at machine cycle `cycle` (not before the last X2 switch).
    pub(crate) fn clocks_at(&self, cycle: u64) -> u64 {
        let (cycles, clocks) = self.clock_base;
        clocks + cycle.saturating_sub(cycles) * self.clocks_per_cycle()
    }

    /// Oscillator clocks at machine cycle `cycle` at the present X2 setting (`u64::MAX` past
    /// the end of the count).
    pub fn clocks_at_cycle(&self, cycle: u64) -> u64 {
        let (cycles, clocks) = self.clock_base;
        cycle
            .saturating_sub(cycles)
            .saturating_mul(self.clocks_per_cycle())
            .saturating_add(clocks)
    }

    /// How many times the watchdog has reset the core.
    pub fn watchdog_resets(&self) -> u64 {
        self.wdt_resets
    }

    /// The on-chip XRAM (empty on variants without one).
    pub fn xram(&self) -> &[u8] {
        &self.xram
    }

    pub(crate) fn cc03(&self) -> bool {
        !self.xram.is_empty()
    }

    /// Whether MOVX at `addr` reaches the on-chip XRAM (AUXR.EXTRAM clear, below its size).
    fn in_xram(&self, addr: u16) -> bool {
        let auxr = self.sfr[(AUXR - 0x80) as usize];
        self.cc03() && auxr & 0x02 == 0 && addr < XRAM_SIZES[(auxr >> 2 & 7) as usize]
    }

    pub(crate) fn movx_read(&mut self, x: &mut dyn Xdata, addr: u16) -> u8 {
        if self.in_xram(addr) {
            return self.xram[addr as usize];
        }
        let v = x.read(addr);
        self.xaccess = Some(XAccess::Read { addr });
        self.attention = true;
        self.set_ext_irq(x.irq());
        v
    }

    pub(crate) fn movx_write(&mut self, x: &mut dyn Xdata, addr: u16, value: u8) {
        if self.in_xram(addr) {
            if self.xram[addr as usize] != value {
                Arc::make_mut(&mut self.xram)[addr as usize] = value;
            }
            return;
        }
        x.write(addr, value);
        self.xaccess = Some(XAccess::Write { addr, value });
        self.attention = true;
        self.set_ext_irq(x.irq());
    }

    /// A write to one of the AT89C51CC03's timed SFRs (timers are up to date).
    pub(crate) fn write_cc03(&mut self, addr: u8, v: u8) {
        let i = (addr - 0x80) as usize;
        match addr {
            CKCON => {
                if (self.sfr[i] ^ v) & 1 != 0 {
                    self.clock_base = (self.cycles, self.clocks());
                    self.clock_changed = true;
                    self.attention = true;
                }
                self.sfr[i] = v;
            }
            WDTRST => {
                // 1Eh then E1h starts the watchdog, or restarts its count when it runs.
                if v == 0xE1 && self.wdt_armed {
                    let wto = self.sfr[(WDTPRG - 0x80) as usize] & 7;
                    self.wdt_deadline = self.effect_at + (1u64 << (14 + wto)) - 1;
                }
                self.wdt_armed = v == 0x1E;
            }
            adc::ADCON => self.write_adcon(v),
            adc::ADDH | adc::ADDL => {}
            P1 => {
                let before = self.pins(1);
                self.sfr[i] = v;
                self.p1_changed(before);
            }
            _ => self.sfr[i] = v,
        }
    }

    /// Reset values of the AT89C51CC03's own SFRs (all 00h but AUXR) and its peripherals'
    /// state; the XRAM keeps its contents.
    pub(crate) fn reset_cc03(&mut self) {
        self.sfr[(AUXR - 0x80) as usize] = AUXR_RESET;
        self.adc_end = u64::MAX;
        self.wdt_deadline = u64::MAX;
        self.wdt_armed = false;
    }

    /// The watchdog ran out during the last instruction: reset, counted and reported.
    pub(crate) fn watchdog_due(&self) -> bool {
        self.synced >= self.wdt_deadline
    }

    pub(crate) fn watchdog_reset(&mut self) {
        self.wdt_resets += 1;
        self.reset();
    }
}
