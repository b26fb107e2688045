//! The SJA1000's bit timing: BTR0 and BTR1 with the crystal frequency (data sheet 6.5.1, 6.5.2).

use crate::time::{BusDuration, TICKS_PER_SEC};

/// The bit timing programmed in BTR0/BTR1, with the crystal that clocks the chip.
///
/// Fields hold the raw register fields; the durations they stand for are one more than the field
/// (data sheet 6.5.1, 6.5.2): a time quantum is `t_scl = 2 · t_clk · (brp + 1)` with `t_clk` the
/// crystal period, SJW is `sjw + 1` quanta, TSEG1 `tseg1 + 1`, TSEG2 `tseg2 + 1`, and a bit is
/// one synchronisation quantum plus TSEG1 plus TSEG2.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct BitTiming {
    /// Baud rate prescaler, BTR0 bits 5:0.
    pub brp: u8,
    /// Synchronisation jump width field, BTR0 bits 7:6.
    pub sjw: u8,
    /// Time segment 1 field, BTR1 bits 3:0 (propagation and phase segment 1 together).
    pub tseg1: u8,
    /// Time segment 2 field, BTR1 bits 6:4.
    pub tseg2: u8,
    /// BTR1 bit 7: the bus is sampled three times instead of once.
    pub sam: bool,
    /// Crystal frequency in Hz (the chip divides it by 2 for its system clock).
    pub xtal_hz: u32,
}

impl BitTiming {
    /// The timing of register values `btr0`, `btr1` with a crystal of `xtal_hz`.
    pub fn from_registers(btr0: u8, btr1: u8, xtal_hz: u32) -> BitTiming {
        BitTiming {
            brp: btr0 & 0x3F,
            sjw: btr0 >> 6,
            tseg1: btr1 & 0x0F,
            tseg2: (btr1 >> 4) & 0x07,
            sam: btr1 & 0x80 != 0,
            xtal_hz,
        }
    }

    /// Time quanta in one bit (NBT): 1 + (TSEG1 + 1) + (TSEG2 + 1), from 4 to 25.
    pub fn quanta_per_bit(&self) -> u32 {
        3 + u32::from(self.tseg1) + u32::from(self.tseg2)
    }

    /// Crystal periods in one bit: 2 · (BRP + 1) · NBT.
    pub fn clocks_per_bit(&self) -> u64 {
        2 * (u64::from(self.brp) + 1) * u64::from(self.quanta_per_bit())
    }

    /// The bit rate in bit/s (0 for a crystal of 0 Hz).
    pub fn bit_rate_hz(&self) -> f64 {
        f64::from(self.xtal_hz) / self.clocks_per_bit() as f64
    }

    /// The bit time on the bus clock, when it is a whole number of ticks; `None` otherwise (and
    /// for a crystal of 0 Hz).
    pub fn bit_time(&self) -> Option<BusDuration> {
        let xtal = u64::from(self.xtal_hz);
        if xtal == 0 {
            return None;
        }
        let num = u128::from(TICKS_PER_SEC) * u128::from(self.clocks_per_bit());
        if num % u128::from(xtal) != 0 {
            return None;
        }
        u64::try_from(num / u128::from(xtal))
            .ok()
            .map(BusDuration::from_ticks)
    }

    /// The largest relative oscillator deviation this timing tolerates (Bosch CAN 2.0 / ISO
    /// 11898-1): the smaller of `SJW / (20 · NBT)` and
    /// `min(PS1, PS2) / (2 · (13 · NBT − PS2))`, all in time quanta.
    ///
    /// The SJA1000 has no separate propagation segment: its TSEG1 holds propagation and phase
    /// segment 1 together. This takes PS1 as the whole of TSEG1 (the chip may lengthen all of it
    /// on resynchronisation), so the result is an upper bound for a bus whose propagation delay
    /// takes part of TSEG1. With TSEG1 ≥ TSEG2, as usual, the minimum is PS2 and the choice does
    /// not matter.
    pub fn tolerance(&self) -> f64 {
        iso_tolerance(
            u32::from(self.sjw) + 1,
            u32::from(self.tseg1) + 1,
            u32::from(self.tseg2) + 1,
            self.quanta_per_bit(),
        )
    }

    /// True when this node's bit rate is within [`tolerance`](BitTiming::tolerance) of
    /// `nominal_bit_rate_hz`: `|f_node − f_nominal| / f_nominal ≤ df_max`.
    pub fn samples_correctly(&self, nominal_bit_rate_hz: f64) -> bool {
        within_tolerance(self.bit_rate_hz(), nominal_bit_rate_hz, self.tolerance())
    }
}

/// The ISO 11898-1 / Bosch CAN 2.0 oscillator tolerance of a bit timing, all lengths in time
/// quanta: the smaller of `SJW / (20 · NBT)` and `min(PS1, PS2) / (2 · (13 · NBT − PS2))`.
pub(crate) fn iso_tolerance(sjw: u32, ps1: u32, ps2: u32, nbt: u32) -> f64 {
    let (sjw, ps1, ps2, nbt) = (f64::from(sjw), f64::from(ps1), f64::from(ps2), f64::from(nbt));
    let jump = sjw / (20.0 * nbt);
    let phase = ps1.min(ps2) / (2.0 * (13.0 * nbt - ps2));
    jump.min(phase)
}

/// True when a node's bit rate `rate_hz` is within `tolerance` (relative) of the bus's
/// `nominal_hz`: `|f_node − f_nominal| / f_nominal ≤ df_max`. A nominal rate that is not a
/// positive number is never met.
pub(crate) fn within_tolerance(rate_hz: f64, nominal_hz: f64, tolerance: f64) -> bool {
    if nominal_hz <= 0.0 || !nominal_hz.is_finite() {
        return false;
    }
    (rate_hz - nominal_hz).abs() / nominal_hz <= tolerance
}
