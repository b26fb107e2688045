//! Where a signal's bits are in a payload, and raw and physical values in and out.
//!
//! Bit numbering is the DBC's: payload bit `n` is bit `n % 8` of byte `n / 8`, bit 0 the least
//! significant. An Intel (`@1`) signal's start bit is its least significant bit and the rest
//! follow upward through the bytes; a Motorola (`@0`) signal's start bit is its most significant
//! bit and the rest follow downward within a byte, then on from bit 7 of the next byte (the
//! "sawtooth" of Vector's DBC format and of cantools).

use super::{ByteOrder, Signal};

/// The highest payload bit a CAN 2.0 frame has (8 bytes).
pub const PAYLOAD_BITS: u16 = 64;

impl Signal {
    /// The payload bit of each of the signal's bits, least significant first; `None` when one
    /// falls outside an 8-byte payload (a Motorola signal walking past byte 7).
    pub fn positions(&self) -> Option<Vec<u16>> {
        let n = u16::from(self.bits);
        let mut out = Vec::with_capacity(usize::from(n));
        match self.byte_order {
            ByteOrder::Intel => {
                for i in 0..n {
                    let p = self.start_bit.checked_add(i)?;
                    (p < PAYLOAD_BITS).then_some(())?;
                    out.push(p);
                }
            }
            ByteOrder::Motorola => {
                let mut p = self.start_bit;
                for i in 0..n {
                    (p < PAYLOAD_BITS).then_some(())?;
                    out.push(p);
                    if i + 1 < n {
                        p = if p.is_multiple_of(8) { p + 15 } else { p - 1 };
                    }
                }
                out.reverse();
            }
        }
        Some(out)
    }

    /// The bytes the signal needs: one past its highest byte.
    pub fn bytes_needed(&self) -> Option<u8> {
        let highest = self.positions()?.into_iter().max()?;
        u8::try_from(highest / 8 + 1).ok()
    }

    /// The raw value in `data` (sign-extended for a signed signal); `None` if the payload is
    /// too short for it.
    pub fn extract(&self, data: &[u8]) -> Option<i128> {
        let positions = self.positions()?;
        let mut raw: u64 = 0;
        for (i, p) in positions.iter().enumerate() {
            let byte = data.get(usize::from(p / 8))?;
            raw |= u64::from((byte >> (p % 8)) & 1) << i;
        }
        let bits = u32::from(self.bits);
        Some(if self.signed && bits > 0 && (raw >> (bits - 1)) & 1 == 1 {
            i128::from(raw) - (1i128 << bits)
        } else {
            i128::from(raw)
        })
    }

    /// Writes `raw` (already in range: see [`Signal::to_raw`]) into `data`; bits past the end of
    /// `data` are left out.
    pub fn insert(&self, data: &mut [u8], raw: i128) {
        let Some(positions) = self.positions() else {
            return;
        };
        // Two's complement of the signal's width: the low bits of raw as an i128.
        for (i, p) in positions.iter().enumerate() {
            let bit = ((raw >> i) & 1) as u8;
            if let Some(byte) = data.get_mut(usize::from(p / 8)) {
                let mask = 1u8 << (p % 8);
                *byte = (*byte & !mask) | (bit << (p % 8));
            }
        }
    }

    /// The smallest and largest raw values the signal's bits hold.
    pub fn raw_range(&self) -> (i128, i128) {
        let bits = u32::from(self.bits);
        if self.signed {
            (-(1i128 << (bits.max(1) - 1)), (1i128 << (bits.max(1) - 1)) - 1)
        } else {
            (0, (1i128 << bits) - 1)
        }
    }

    /// The physical value of a raw one.
    pub fn physical(&self, raw: i128) -> f64 {
        raw as f64 * self.factor + self.offset
    }

    /// The raw value for a physical one: limited to the signal's range `[min, max]` when it has
    /// one (min < max), rounded to the nearest step of the factor, then limited to what the bits
    /// hold, as a saturating sensor would (an infinity too). `None` for a value that is not a
    /// number. A factor of 0 (or one that is not a finite number) maps every raw value to the
    /// offset: raw 0 is sent.
    pub fn to_raw(&self, physical: f64) -> Option<i128> {
        if physical.is_nan() {
            return None;
        }
        if self.factor == 0.0 || !self.factor.is_finite() {
            let (lo, hi) = self.raw_range();
            return Some(0i128.clamp(lo, hi));
        }
        let v = if self.min < self.max {
            physical.clamp(self.min, self.max)
        } else {
            physical
        };
        let (lo, hi) = self.raw_range();
        // f64 -> i128 saturates; the range limits it to the signal's bits.
        let mut raw = (((v - self.offset) / self.factor).round() as i128).clamp(lo, hi);
        if self.min < self.max {
            // Rounding may land half a step outside the range: one step back in, if the bits
            // allow it.
            let step = if self.factor > 0.0 { 1 } else { -1 };
            if self.physical(raw) < self.min && (lo..=hi).contains(&(raw + step)) {
                raw += step;
            } else if self.physical(raw) > self.max && (lo..=hi).contains(&(raw - step)) {
                raw -= step;
            }
        }
        Some(raw)
    }
}
