//! The AT89C51CC03's 10-bit analog-to-digital converter: ADCON, ADCF, ADCLK, ADDH/ADDL.
//!
//! ADCON (AT89C51CC03 data sheet, "Analog-to-Digital Converter"): PSIDLE (bit 6), ADEN (5,
//! converter on), ADEOC (4, end of conversion: set by hardware, cleared by software, the ADC
//! interrupt request), ADSST (3, written 1 to start, cleared by hardware at the end), SCH (2–0,
//! the channel, input P1.SCH). The 10-bit result is ADDH (bits 9–2) and ADDL bits 1–0.
//!
//! Timing: the ADC clock is the peripheral clock (fosc/2, or fosc in X2) divided by 4 × PRS
//! (ADCLK bits 4–0; PRS = 0 counts as 32) and a conversion takes [`CONVERSION_ADC_CLOCKS`] ADC
//! clocks. A machine cycle is 6 peripheral clocks in both modes, so a conversion takes
//! 44 × PRS / 6 machine cycles, rounded up to a whole machine cycle: the end is seen at the
//! first machine cycle boundary at or after it.
//!
//! The analog inputs are codes 0..=1023 the caller sets ([`Cpu::set_analog`], or
//! [`Cpu::set_analog_millivolts`] with VREF). A conversion samples its channel when it ends.
//! A channel may have an analog multiplexer in front of it ([`Cpu::set_analog_mux`]): a port
//! pin's latch then selects which of two inputs the conversion samples, as it ends.
//! A start with ADEN clear converts nothing (ADSST reads 0). ADCF (which P1 pins are analog) is
//! stored; a channel converts whatever ADCF says. PSIDLE (pseudo-idle during the conversion for
//! best precision) is stored: the CPU is not stopped, results and timing are the same.

use super::Cpu;

pub(crate) const ADCLK: u8 = 0xF2;
pub(crate) const ADCON: u8 = 0xF3;
pub(crate) const ADDL: u8 = 0xF4;
pub(crate) const ADDH: u8 = 0xF5;
pub(crate) const ADCF: u8 = 0xF6;

const ADEN: u8 = 0x20;
const ADEOC: u8 = 0x10;
const ADSST: u8 = 0x08;

/// ADC clocks of one conversion.
pub const CONVERSION_ADC_CLOCKS: u64 = 11;

impl Cpu {
    /// Sets analog input `channel` (0–7, pin P1.channel) to the 10-bit code `code`
    /// (clamped to 1023). Other channels are ignored.
    pub fn set_analog(&mut self, channel: u8, code: u16) {
        if let Some(a) = self.analog.get_mut(channel as usize) {
            *a = code.min(1023);
        }
    }

    /// Sets analog input `channel` to `millivolts` against a reference of `vref_millivolts`:
    /// the code is ⌊1024 × mV / VREF⌋, clamped to 0..=1023 (an ideal converter).
    pub fn set_analog_millivolts(&mut self, channel: u8, millivolts: u32, vref_millivolts: u32) {
        self.set_analog(channel, Cpu::code_of(millivolts, vref_millivolts));
    }

    /// The ideal converter's code for `millivolts` against `vref_millivolts`:
    /// ⌊1024 × mV / VREF⌋, clamped to 0..=1023 (1023 with no reference).
    pub fn code_of(millivolts: u32, vref_millivolts: u32) -> u16 {
        (1024 * millivolts as u64)
            .checked_div(vref_millivolts as u64)
            .unwrap_or(1023)
            .min(1023) as u16
    }

    /// The analog input codes of channels 0–7.
    pub fn analog(&self) -> [u16; 8] {
        self.analog
    }

    /// Machine cycles of one conversion with the current ADCLK.
    pub fn adc_conversion_cycles(&self) -> u64 {
        let prs = match self.sfr[(ADCLK - 0x80) as usize] & 0x1F {
            0 => 32,
            p => p as u64,
        };
        (CONVERSION_ADC_CLOCKS * 4 * prs).div_ceil(6)
    }

    pub(crate) fn write_adcon(&mut self, v: u8) {
        let i = (ADCON - 0x80) as usize;
        let busy = self.adc_end != u64::MAX;
        let mut new = v & !ADSST;
        if busy {
            // A conversion under way finishes; ADSST stays set until it does.
            new |= ADSST;
        } else if v & ADSST != 0 && v & ADEN != 0 {
            new |= ADSST;
            self.adc_end = self.effect_at + self.adc_conversion_cycles();
        }
        self.sfr[i] = new;
    }

    /// Ends the conversion if its time has come (timers are up to `synced`).
    pub(crate) fn adc_tick(&mut self) {
        if self.synced < self.adc_end {
            return;
        }
        self.adc_end = u64::MAX;
        let con = self.sfr[(ADCON - 0x80) as usize];
        let channel = (con & 7) as usize;
        let code = match self.mux[channel] {
            Some((port, bit)) if self.sfr[usize::from(port) * 0x10] >> bit & 1 != 0 => {
                self.analog_high[channel]
            }
            _ => self.analog[channel],
        };
        if self.watched.channels & (1 << channel) != 0 {
            self.input_reads += 1;
        }
        self.sfr[(ADDH - 0x80) as usize] = (code >> 2) as u8;
        self.sfr[(ADDL - 0x80) as usize] = (code & 3) as u8;
        self.sfr[(ADCON - 0x80) as usize] = (con & !ADSST) | ADEOC;
        self.irq_quiet = false;
    }
}
