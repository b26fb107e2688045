//! The bit timing of CANBT1–3 with the CAN clock (T89C51CC01 data sheet, "Bit Timing and Baud
//! Rate"; AT89C51CC03 data sheet, the same section and the CANBT1–3 tables).

use crate::sja1000::{iso_tolerance, within_tolerance};
use crate::time::{BusDuration, TICKS_PER_SEC};

/// The bit timing programmed in CANBT1–3, with the CAN clock.
///
/// Fields hold the raw register fields; each length is one more than its field: a time quantum
/// is `(BRP + 1) / F_CAN`, and a bit is the synchronisation segment (1 quantum) plus PRS + 1,
/// PHS1 + 1 and PHS2 + 1 quanta. SJW is SJW + 1 quanta.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct BitTiming {
    /// Baud rate prescaler, CANBT1 bits 6:1.
    pub brp: u8,
    /// Synchronisation jump width field, CANBT2 bits 6:5.
    pub sjw: u8,
    /// Propagation segment field, CANBT2 bits 3:1.
    pub prs: u8,
    /// Phase segment 2 field, CANBT3 bits 6:4.
    pub phs2: u8,
    /// Phase segment 1 field, CANBT3 bits 3:1.
    pub phs1: u8,
    /// CANBT3 bit 0: the bus is sampled three times.
    pub smp: bool,
    /// The CAN clock F_CAN in Hz.
    pub clock_hz: u64,
}

impl BitTiming {
    /// The timing of CANBT1, CANBT2, CANBT3 = `bt` with a CAN clock of `clock_hz`.
    pub fn from_registers(bt: [u8; 3], clock_hz: u64) -> BitTiming {
        BitTiming {
            brp: (bt[0] >> 1) & 0x3F,
            sjw: (bt[1] >> 5) & 0x03,
            prs: (bt[1] >> 1) & 0x07,
            phs2: (bt[2] >> 4) & 0x07,
            phs1: (bt[2] >> 1) & 0x07,
            smp: bt[2] & 0x01 != 0,
            clock_hz,
        }
    }

    /// Time quanta in one bit: 1 + (PRS + 1) + (PHS1 + 1) + (PHS2 + 1), from 4 to 25 (the data
    /// sheet asks for 8 to 25).
    pub fn quanta_per_bit(&self) -> u32 {
        4 + u32::from(self.prs) + u32::from(self.phs1) + u32::from(self.phs2)
    }

    /// CAN clock periods in one bit: (BRP + 1) · quanta per bit.
    pub fn clocks_per_bit(&self) -> u64 {
        (u64::from(self.brp) + 1) * u64::from(self.quanta_per_bit())
    }

    /// The bit rate in bit/s (0 for a clock of 0 Hz).
    pub fn bit_rate_hz(&self) -> f64 {
        self.clock_hz as f64 / self.clocks_per_bit() as f64
    }

    /// The bit time on the bus clock when it is a whole number of ticks; `None` otherwise (and
    /// for a clock of 0 Hz).
    pub fn bit_time(&self) -> Option<BusDuration> {
        if self.clock_hz == 0 {
            return None;
        }
        let num = u128::from(TICKS_PER_SEC) * u128::from(self.clocks_per_bit());
        let clock = u128::from(self.clock_hz);
        if num % clock != 0 {
            return None;
        }
        u64::try_from(num / clock).ok().map(BusDuration::from_ticks)
    }

    /// The largest relative oscillator deviation this timing tolerates, by the same ISO 11898-1
    /// formula as [`crate::sja1000::BitTiming::tolerance`]. Here the propagation segment has a
    /// field of its own, so PS1 is PHS1 + 1 exactly.
    pub fn tolerance(&self) -> f64 {
        iso_tolerance(
            u32::from(self.sjw) + 1,
            u32::from(self.phs1) + 1,
            u32::from(self.phs2) + 1,
            self.quanta_per_bit(),
        )
    }

    /// True when this bit rate is within [`tolerance`](BitTiming::tolerance) of
    /// `nominal_bit_rate_hz`.
    pub fn samples_correctly(&self, nominal_bit_rate_hz: f64) -> bool {
        within_tolerance(self.bit_rate_hz(), nominal_bit_rate_hz, self.tolerance())
    }
}
