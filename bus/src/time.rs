//! Bus time: a point on the bus clock ([`BusTime`]) and a span of it ([`BusDuration`]), both
//! counted in ticks of 1/3 456 000 000 000 s.
//!
//! The bus keeps its own clock because a frame lasts a few hundred microseconds and tokio's
//! timers only resolve milliseconds. The clock must be exact for every bit rate and every
//! controller or CPU clock harvemu runs: a frame's end is its start plus a whole number of bit
//! times, and a rounded bit time would drift further with every frame. Nanoseconds are not fine
//! enough (30 kbit/s has a bit time of 33 333.3 ns, a 6 MHz SJA1000's time quantum is 333.3 ns,
//! an 11.0592 MHz 8051's machine cycle 1085.07 ns). A tick is 1/(2^16 · 3^3 · 5^9) s, 3456 per
//! nanosecond, so every rate or clock of the form 2^a · 3^b · 5^c Hz with a ≤ 16, b ≤ 3, c ≤ 9
//! has a period of a whole number of ticks: all the standard CAN bit rates, 30 kbit/s, the
//! SJA1000's 6, 8, 16 and 24 MHz and the 8051's 11.0592, 12, 14.7456, 22.1184 and 24 MHz crystals
//! (the last divided by 12 for a machine cycle, too). A `u64` of ticks spans about 61 days,
//! more than the longest run harvemu accepts.
//!
//! Arithmetic is exact and saturates at [`BusTime::NEVER`] / [`BusDuration::MAX`] (and at zero
//! below); times are rounded only where they are written out: [`BusTime::as_nanos`] and the
//! `Display`s truncate, and serialized times are whole nanoseconds, as they always were.
//!
//! Times written in trace files are [`Stamp`]s: whole nanoseconds, counted from 1970 or from the
//! start of a measurement, far beyond the bus clock's range; [`Epoch`] turns one into the other.

use core::fmt;
use core::ops::{Add, AddAssign, Div, Mul, Sub};
use core::time::Duration;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::time::{SystemTime, UNIX_EPOCH};

/// Ticks of the bus clock per second: 2^16 · 3^3 · 5^9.
pub const TICKS_PER_SEC: u64 = 3_456_000_000_000;
const TICKS_PER_MS: u64 = TICKS_PER_SEC / 1_000;
const TICKS_PER_US: u64 = TICKS_PER_SEC / 1_000_000;
/// Ticks of the bus clock per nanosecond.
pub const TICKS_PER_NS: u64 = TICKS_PER_SEC / 1_000_000_000;

/// A span of bus time, in ticks ([`TICKS_PER_SEC`]). Arithmetic saturates at
/// [`BusDuration::MAX`] and at zero.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct BusDuration(u64);

impl BusDuration {
    /// No time.
    pub const ZERO: BusDuration = BusDuration(0);
    /// The longest span (about 61 days); "for ever".
    pub const MAX: BusDuration = BusDuration(u64::MAX);

    /// From ticks of 1/[`TICKS_PER_SEC`] s.
    pub const fn from_ticks(ticks: u64) -> BusDuration {
        BusDuration(ticks)
    }
    /// From whole seconds, saturating at [`BusDuration::MAX`].
    pub const fn from_secs(s: u64) -> BusDuration {
        BusDuration(s.saturating_mul(TICKS_PER_SEC))
    }
    /// From whole milliseconds, saturating: config and script times are read as `u64`, and a
    /// huge one must mean "never", not overflow.
    pub const fn from_millis(ms: u64) -> BusDuration {
        BusDuration(ms.saturating_mul(TICKS_PER_MS))
    }
    /// From whole microseconds, saturating.
    pub const fn from_micros(us: u64) -> BusDuration {
        BusDuration(us.saturating_mul(TICKS_PER_US))
    }
    /// From whole nanoseconds, saturating.
    pub const fn from_nanos(ns: u64) -> BusDuration {
        BusDuration(ns.saturating_mul(TICKS_PER_NS))
    }
    /// From seconds, rounded to the nearest nanosecond (negative and non-numbers give zero,
    /// huge ones [`BusDuration::MAX`]).
    pub fn from_secs_f64(s: f64) -> BusDuration {
        BusDuration::from_nanos(if s.is_finite() && s > 0.0 {
            (s * 1e9).round() as u64
        } else {
            0
        })
    }
    /// The period of `hz` cycles per second, when it is a whole number of ticks (see the
    /// module docs for which are); `None` otherwise and for 0.
    pub const fn period_of(hz: u64) -> Option<BusDuration> {
        if hz != 0 && TICKS_PER_SEC.is_multiple_of(hz) {
            Some(BusDuration(TICKS_PER_SEC / hz))
        } else {
            None
        }
    }
    /// Ticks.
    pub const fn as_ticks(self) -> u64 {
        self.0
    }
    /// Whole nanoseconds (truncated).
    pub const fn as_nanos(self) -> u64 {
        self.0 / TICKS_PER_NS
    }
    /// Whole microseconds (truncated).
    pub const fn as_micros(self) -> u64 {
        self.0 / TICKS_PER_US
    }
    /// Whole milliseconds (truncated).
    pub const fn as_millis(self) -> u64 {
        self.0 / TICKS_PER_MS
    }
    /// Whole seconds (truncated).
    pub const fn as_secs(self) -> u64 {
        self.0 / TICKS_PER_SEC
    }
    /// Seconds, for display and statistics.
    pub fn as_secs_f64(self) -> f64 {
        // Whole nanoseconds first, so that a time of whole nanoseconds gives the very f64 it
        // gave when the clock counted nanoseconds (reports stay byte-identical).
        self.as_nanos() as f64 / 1e9 + (self.0 % TICKS_PER_NS) as f64 / TICKS_PER_SEC as f64
    }
    /// As a std duration, truncated to the nanosecond.
    pub const fn as_std(self) -> Duration {
        Duration::from_nanos(self.as_nanos())
    }
    /// From a std duration (exact: a nanosecond is a whole number of ticks), saturating.
    pub fn from_std(d: Duration) -> BusDuration {
        BusDuration(u64::try_from(d.as_nanos().saturating_mul(u128::from(TICKS_PER_NS))).unwrap_or(u64::MAX))
    }
    /// `self + other`, or `None` past [`BusDuration::MAX`].
    pub const fn checked_add(self, other: BusDuration) -> Option<BusDuration> {
        match self.0.checked_add(other.0) {
            Some(t) => Some(BusDuration(t)),
            None => None,
        }
    }
    /// `self + other`, saturating at [`BusDuration::MAX`].
    pub const fn saturating_add(self, other: BusDuration) -> BusDuration {
        BusDuration(self.0.saturating_add(other.0))
    }
    /// `self - other`, or `None` below zero.
    pub const fn checked_sub(self, other: BusDuration) -> Option<BusDuration> {
        match self.0.checked_sub(other.0) {
            Some(t) => Some(BusDuration(t)),
            None => None,
        }
    }
    /// `self - other`, saturating at zero.
    pub const fn saturating_sub(self, other: BusDuration) -> BusDuration {
        BusDuration(self.0.saturating_sub(other.0))
    }
    /// `self · n`, or `None` past [`BusDuration::MAX`].
    pub const fn checked_mul(self, n: u64) -> Option<BusDuration> {
        match self.0.checked_mul(n) {
            Some(t) => Some(BusDuration(t)),
            None => None,
        }
    }
    /// `self · n`, saturating at [`BusDuration::MAX`].
    pub const fn saturating_mul(self, n: u64) -> BusDuration {
        BusDuration(self.0.saturating_mul(n))
    }
    /// How many `unit`s it takes to cover `self`, rounded up (`u64::MAX` for a zero unit).
    pub const fn div_ceil(self, unit: BusDuration) -> u64 {
        if unit.0 == 0 {
            u64::MAX
        } else {
            self.0.div_ceil(unit.0)
        }
    }
}

impl Add for BusDuration {
    type Output = BusDuration;
    /// Saturates at [`BusDuration::MAX`].
    fn add(self, other: BusDuration) -> BusDuration {
        self.saturating_add(other)
    }
}

impl AddAssign for BusDuration {
    fn add_assign(&mut self, other: BusDuration) {
        *self = *self + other;
    }
}

impl Sub for BusDuration {
    type Output = BusDuration;
    /// Saturates at zero.
    fn sub(self, other: BusDuration) -> BusDuration {
        self.saturating_sub(other)
    }
}

impl Mul<u64> for BusDuration {
    type Output = BusDuration;
    /// Saturates at [`BusDuration::MAX`].
    fn mul(self, n: u64) -> BusDuration {
        self.saturating_mul(n)
    }
}

impl Mul<BusDuration> for u64 {
    type Output = BusDuration;
    /// Saturates at [`BusDuration::MAX`].
    fn mul(self, d: BusDuration) -> BusDuration {
        d.saturating_mul(self)
    }
}

impl Div for BusDuration {
    type Output = u64;
    /// How many whole `other`s fit in `self` (`u64::MAX` for a zero `other`).
    fn div(self, other: BusDuration) -> u64 {
        self.0.checked_div(other.0).unwrap_or(u64::MAX)
    }
}

impl fmt::Display for BusDuration {
    /// Seconds with nine decimals (`0.000333333s`), truncated to the nanosecond.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:09}s", self.as_secs(), self.as_nanos() % 1_000_000_000)
    }
}

impl fmt::Debug for BusDuration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

impl Serialize for BusDuration {
    /// Whole nanoseconds (truncated), the unit reports have always used.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(self.as_nanos())
    }
}

impl<'de> Deserialize<'de> for BusDuration {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<BusDuration, D::Error> {
        u64::deserialize(d).map(BusDuration::from_nanos)
    }
}

/// A point on the bus clock, in ticks ([`TICKS_PER_SEC`]) since the bus started. Arithmetic
/// saturates at [`BusTime::NEVER`] and at [`BusTime::ZERO`]. Serialized as whole nanoseconds.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct BusTime(u64);

impl BusTime {
    /// The start of the bus.
    pub const ZERO: BusTime = BusTime(0);
    /// Later than anything.
    pub const NEVER: BusTime = BusTime(u64::MAX);

    /// At `d` after the start.
    pub const fn at(d: BusDuration) -> BusTime {
        BusTime(d.0)
    }
    /// From ticks since the start.
    pub const fn from_ticks(ticks: u64) -> BusTime {
        BusTime(ticks)
    }
    /// From whole seconds, saturating at [`BusTime::NEVER`].
    pub const fn from_secs(s: u64) -> BusTime {
        BusTime::at(BusDuration::from_secs(s))
    }
    /// From whole milliseconds, saturating at [`BusTime::NEVER`].
    pub const fn from_millis(ms: u64) -> BusTime {
        BusTime::at(BusDuration::from_millis(ms))
    }
    /// From whole microseconds, saturating at [`BusTime::NEVER`].
    pub const fn from_micros(us: u64) -> BusTime {
        BusTime::at(BusDuration::from_micros(us))
    }
    /// From whole nanoseconds, saturating at [`BusTime::NEVER`].
    pub const fn from_nanos(ns: u64) -> BusTime {
        BusTime::at(BusDuration::from_nanos(ns))
    }
    /// From seconds, rounded to the nanosecond (negative and non-numbers give zero).
    pub fn from_secs_f64(s: f64) -> BusTime {
        BusTime::at(BusDuration::from_secs_f64(s))
    }
    /// From a std duration since the start, saturating.
    pub fn from_duration(d: Duration) -> BusTime {
        BusTime::at(BusDuration::from_std(d))
    }
    /// The time since the start.
    pub const fn elapsed(self) -> BusDuration {
        BusDuration(self.0)
    }
    /// Ticks since the start.
    pub const fn as_ticks(self) -> u64 {
        self.0
    }
    /// Whole nanoseconds since the start (truncated).
    pub const fn as_nanos(self) -> u64 {
        self.elapsed().as_nanos()
    }
    /// Whole microseconds since the start (truncated).
    pub const fn as_micros(self) -> u64 {
        self.elapsed().as_micros()
    }
    /// Whole seconds since the start (truncated).
    pub const fn as_secs(self) -> u64 {
        self.elapsed().as_secs()
    }
    /// The time since the start as a std duration (truncated to the nanosecond).
    pub const fn as_duration(self) -> Duration {
        self.elapsed().as_std()
    }
    /// Seconds since the start, for display.
    pub fn as_secs_f64(self) -> f64 {
        self.elapsed().as_secs_f64()
    }
    /// `self + d` for a std duration, saturating.
    pub fn after(self, d: Duration) -> BusTime {
        self + BusDuration::from_std(d)
    }
    /// The time elapsed from `earlier` to `self` (zero if `earlier` is later).
    pub const fn since(self, earlier: BusTime) -> BusDuration {
        BusDuration(self.0.saturating_sub(earlier.0))
    }
    /// `self + d`, or `None` past [`BusTime::NEVER`].
    pub const fn checked_add(self, d: BusDuration) -> Option<BusTime> {
        match self.0.checked_add(d.0) {
            Some(t) => Some(BusTime(t)),
            None => None,
        }
    }
    /// `self + d`, saturating at [`BusTime::NEVER`].
    pub const fn saturating_add(self, d: BusDuration) -> BusTime {
        BusTime(self.0.saturating_add(d.0))
    }
    /// `self - d`, or `None` before the start.
    pub const fn checked_sub(self, d: BusDuration) -> Option<BusTime> {
        match self.0.checked_sub(d.0) {
            Some(t) => Some(BusTime(t)),
            None => None,
        }
    }
    /// `self - d`, saturating at [`BusTime::ZERO`].
    pub const fn saturating_sub(self, d: BusDuration) -> BusTime {
        BusTime(self.0.saturating_sub(d.0))
    }
    /// The first multiple of `step` after `self` (strictly later), saturating; `self` for a zero
    /// step. Sampling and drawing grids use it.
    pub const fn next_multiple_of(self, step: BusDuration) -> BusTime {
        match self.0.checked_div(step.0) {
            Some(n) => BusTime((n + 1).saturating_mul(step.0)),
            None => self,
        }
    }
    /// The first multiple of `step` at or after `self`, saturating; `self` for a zero step.
    pub const fn ceil_to(self, step: BusDuration) -> BusTime {
        if step.0 == 0 {
            self
        } else {
            BusTime(self.0.div_ceil(step.0).saturating_mul(step.0))
        }
    }
}

impl Add<BusDuration> for BusTime {
    type Output = BusTime;
    /// Saturates at [`BusTime::NEVER`].
    fn add(self, d: BusDuration) -> BusTime {
        self.saturating_add(d)
    }
}

impl AddAssign<BusDuration> for BusTime {
    fn add_assign(&mut self, d: BusDuration) {
        *self = *self + d;
    }
}

impl Sub<BusDuration> for BusTime {
    type Output = BusTime;
    /// Saturates at [`BusTime::ZERO`].
    fn sub(self, d: BusDuration) -> BusTime {
        self.saturating_sub(d)
    }
}

impl Sub for BusTime {
    type Output = BusDuration;
    /// The span between two times, saturating at zero.
    fn sub(self, other: BusTime) -> BusDuration {
        self.since(other)
    }
}

impl fmt::Display for BusTime {
    /// `seconds.microseconds`, as candump writes timestamps (truncated to the microsecond).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:06}", self.as_secs(), self.as_micros() % 1_000_000)
    }
}

impl fmt::Debug for BusTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.elapsed(), f)
    }
}

impl Serialize for BusTime {
    /// Whole nanoseconds since the start (truncated), as reports have always written it.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(self.as_nanos())
    }
}

impl<'de> Deserialize<'de> for BusTime {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<BusTime, D::Error> {
        u64::deserialize(d).map(BusTime::from_nanos)
    }
}

/// A time as a trace file writes it: whole nanoseconds, since 1970 (candump logs, socketcand)
/// or since the start of a measurement (ASC). Bus time becomes one through an [`Epoch`].
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Stamp(pub u64);

impl Stamp {
    /// Nanoseconds.
    pub const fn as_nanos(self) -> u64 {
        self.0
    }
    /// The span from `earlier` to `self` (zero if `earlier` is later), as bus time.
    pub const fn since(self, earlier: Stamp) -> BusDuration {
        BusDuration::from_nanos(self.0.saturating_sub(earlier.0))
    }
}

impl fmt::Display for Stamp {
    /// `seconds.microseconds`, as candump writes timestamps (truncated to the microsecond).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}.{:06}",
            self.0 / 1_000_000_000,
            self.0 % 1_000_000_000 / 1_000
        )
    }
}

impl fmt::Debug for Stamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:09}s", self.0 / 1_000_000_000, self.0 % 1_000_000_000)
    }
}

/// Where bus time zero lies on the wall clock, as traces write it: whole microseconds since
/// 1970-01-01T00:00:00Z.
///
/// Bus time itself always starts at zero; an epoch is an offset applied only where a time is
/// written out (candump log lines, the ASC `date` header, socketcand frames), so that tools which
/// read those (can-utils, python-can, Wireshark) see dates rather than the first seconds of 1970.
/// A real-time run takes the wall clock at its start, as `candump -l` would; a virtual-time run
/// takes [`Epoch::FIXED`] (or a chosen one), so its traces stay byte-identical for a seed.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug, Default)]
pub struct Epoch(u64);

impl Epoch {
    /// Bus time written as it is: zero is 1970-01-01T00:00:00Z.
    pub const UNIX: Epoch = Epoch(0);
    /// 2024-01-01T00:00:00Z, the start of every virtual-time run not given another: a fixed
    /// date keeps traces reproducible, a recent whole year keeps them plausible to tools that
    /// show dates, and midnight UTC makes a trace's times easy to read back as bus time.
    pub const FIXED: Epoch = Epoch(1_704_067_200_000_000);

    /// A wall-clock time (truncated to the microsecond; before 1970 gives 1970).
    pub fn from_system_time(t: SystemTime) -> Epoch {
        let us = t.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_micros());
        Epoch(u64::try_from(us).unwrap_or(u64::MAX / 1_000))
    }
    /// `us` microseconds after 1970.
    pub const fn from_micros(us: u64) -> Epoch {
        Epoch(us)
    }
    /// `s` seconds after 1970.
    pub const fn from_secs(s: u64) -> Epoch {
        Epoch(s.saturating_mul(1_000_000))
    }
    /// Reads `2024-01-01T00:00:00Z` (RFC 3339, any offset, fractions of a second to the
    /// microsecond) or whole seconds since 1970 (`1704067200`). A time before 1970, or too far
    /// ahead for bus time to be added to it (after 2500), is refused.
    pub fn parse(text: &str) -> Result<Epoch, String> {
        let text = text.trim();
        let us = if !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit()) {
            let s: u64 = text
                .parse()
                .map_err(|_| format!("'{text}' is too large for seconds since 1970"))?;
            u128::from(s) * 1_000_000
        } else {
            let t = time::OffsetDateTime::parse(text, &time::format_description::well_known::Rfc3339)
                .map_err(|e| {
                    format!("'{text}' is neither an RFC 3339 time (2024-01-01T00:00:00Z) nor seconds since 1970: {e}")
                })?;
            let ns = t.unix_timestamp_nanos();
            if ns < 0 {
                return Err(format!("'{text}' is before 1970"));
            }
            ns.unsigned_abs() / 1_000
        };
        if us > Epoch::LATEST.0.into() {
            return Err(format!("'{text}' is after 2500"));
        }
        Ok(Epoch(us as u64))
    }
    /// 2500-01-01T00:00:00Z: later epochs would leave too little room for bus time in a
    /// [`Stamp`]'s u64 of nanoseconds since 1970.
    const LATEST: Epoch = Epoch(16_725_225_600_000_000);

    /// Microseconds since 1970.
    pub const fn as_micros(self) -> u64 {
        self.0
    }
    /// The epoch as a wall-clock time.
    pub fn system_time(self) -> SystemTime {
        UNIX_EPOCH + Duration::from_micros(self.0)
    }
    /// Bus time `at` as written out: nanoseconds since 1970 (truncated, saturating).
    pub const fn stamp(self, at: BusTime) -> Stamp {
        Stamp(at.as_nanos().saturating_add(self.0.saturating_mul(1_000)))
    }
    /// A written-out time back to bus time (zero for one before the epoch).
    pub const fn unstamp(self, at: Stamp) -> BusTime {
        BusTime::from_nanos(at.0.saturating_sub(self.0.saturating_mul(1_000)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_units_convert_exactly_and_saturate() {
        assert_eq!(BusTime::from_secs(3).as_nanos(), 3_000_000_000);
        assert_eq!(BusTime::from_millis(500).as_nanos(), 500_000_000);
        assert_eq!(BusTime::from_micros(200).as_nanos(), 200_000);
        assert_eq!(BusTime::from_nanos(7).as_ticks(), 7 * 3456);
        assert_eq!(BusTime::from_secs(1), BusTime::from_millis(1000));
        // The largest values that still fit, then one more.
        let max_ms = u64::MAX / 3_456_000_000;
        assert_eq!(BusTime::from_millis(max_ms).as_ticks(), max_ms * 3_456_000_000);
        assert_eq!(BusTime::from_millis(max_ms + 1), BusTime::NEVER);
        // A harvester config with `time_relay_ms: 18446744073709551615` overflowed here.
        assert_eq!(BusTime::from_millis(u64::MAX), BusTime::NEVER);
        assert_eq!(BusTime::from_micros(u64::MAX), BusTime::NEVER);
        assert_eq!(BusTime::from_nanos(u64::MAX), BusTime::NEVER);
        assert_eq!(
            BusTime::from_secs(u64::MAX / 3_456_000_000_000 + 1),
            BusTime::NEVER
        );
        // The clock spans more than the 30 days a run may last.
        assert!(BusTime::from_secs(30 * 86_400) < BusTime::NEVER);
    }

    #[test]
    fn arithmetic_saturates_at_never_and_zero() {
        let d = BusDuration::from_secs(1);
        assert_eq!(BusTime::NEVER + d, BusTime::NEVER);
        assert_eq!(BusTime::NEVER.checked_add(d), None);
        assert_eq!(
            BusTime::NEVER.checked_add(BusDuration::ZERO),
            Some(BusTime::NEVER)
        );
        assert_eq!(BusTime::ZERO - d, BusTime::ZERO);
        assert_eq!(BusTime::ZERO.checked_sub(d), None);
        assert_eq!(BusTime::ZERO - BusTime::from_secs(5), BusDuration::ZERO);
        assert_eq!(
            BusTime::from_secs(5) - BusTime::from_secs(3),
            BusDuration::from_secs(2)
        );
        assert_eq!(d * u64::MAX, BusDuration::MAX);
        assert_eq!(d.checked_mul(u64::MAX), None);
        assert_eq!(BusDuration::MAX + d, BusDuration::MAX);
        assert_eq!(d - BusDuration::MAX, BusDuration::ZERO);
        assert_eq!(
            BusTime::from_secs(2) + BusDuration::from_millis(500),
            BusTime::from_millis(2500)
        );
        assert_eq!(BusTime::NEVER.next_multiple_of(d), BusTime::NEVER);
        assert_eq!(
            BusTime::from_millis(1500).next_multiple_of(d),
            BusTime::from_secs(2)
        );
        assert_eq!(BusTime::from_secs(2).next_multiple_of(d), BusTime::from_secs(3));
        assert_eq!(BusTime::from_secs(2).ceil_to(d), BusTime::from_secs(2));
        assert_eq!(BusTime::from_millis(2001).ceil_to(d), BusTime::from_secs(3));
    }

    /// `n` periods of `hz`, added one by one.
    fn summed(period: BusDuration, n: u64) -> BusDuration {
        (0..n).fold(BusDuration::ZERO, |acc, _| acc + period)
    }

    #[test]
    fn sja1000_and_8051_periods_are_exact() {
        // A 6 MHz SJA1000 with BRP 0: a time quantum is 2 clocks, 1/3 µs.
        let tq = BusDuration::period_of(3_000_000).expect("1/3 µs is a whole number of ticks");
        assert_eq!(tq.as_ticks() * 3, TICKS_PER_SEC / 1_000_000);
        let n = 3_000_000_000; // 1000 s of quanta
        assert_eq!(tq * n, BusDuration::from_secs(1000));
        assert_eq!(summed(tq, 300_000), BusDuration::from_millis(100));
        // An 11.0592 MHz 80C51: a machine cycle is 12 oscillator clocks, 12/11 059 200 s.
        let cycle = BusDuration::period_of(11_059_200 / 12).expect("a machine cycle is exact");
        assert_eq!(cycle.as_ticks() * 921_600, TICKS_PER_SEC);
        assert_eq!(summed(cycle, 921_600), BusDuration::from_secs(1));
        assert_eq!(cycle * (921_600 * 3600), BusDuration::from_secs(3600));
        // Every clock the next boards use, and every standard CAN bit rate.
        for hz in [
            6_000_000, 8_000_000, 16_000_000, 24_000_000, 11_059_200, 12_000_000, 14_745_600, 22_118_400,
            30_000, 10_000, 20_000, 50_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
        ] {
            let p = BusDuration::period_of(hz).unwrap_or_else(|| panic!("{hz} Hz"));
            assert_eq!(p * hz, BusDuration::from_secs(1), "{hz} Hz");
        }
        // 7 kHz and 33.3 kHz have a 7 and a 37 in them: no whole number of ticks.
        assert_eq!(BusDuration::period_of(7_000), None);
        assert_eq!(BusDuration::period_of(33_300), None);
        assert_eq!(BusDuration::period_of(0), None);
    }

    #[test]
    fn rounding_happens_only_in_printing() {
        // 30 kbit/s: 33 333.3 ns a bit. Nanoseconds would lose a third per bit.
        let bit = BusDuration::period_of(30_000).expect("30 kbit/s is exact");
        let t = BusTime::ZERO + bit * 3;
        assert_eq!(t, BusTime::from_micros(100));
        assert_eq!(bit.as_nanos(), 33_333);
        assert_eq!(bit.to_string(), "0.000033333s");
        assert_eq!((BusTime::ZERO + bit).to_string(), "0.000033");
        assert_eq!((BusTime::ZERO + bit * 2).as_nanos(), 66_666);
        assert_eq!((BusTime::from_secs(1) + bit * 29_999).to_string(), "1.999966");
        // Serialized as whole nanoseconds, as before.
        let json = serde_json::to_string(&(BusTime::ZERO + bit)).expect("serializes");
        assert_eq!(json, "33333");
        let back: BusTime = serde_json::from_str("1500").expect("deserializes");
        assert_eq!(back, BusTime::from_nanos(1500));
    }

    #[test]
    fn epochs_read_rfc3339_and_seconds_and_refuse_the_rest() {
        // 2024-01-01T00:00:00Z: 54 years of 365 days, 13 leap days (1972..=2020), in seconds.
        let new_year_2024 = (54 * 365 + 13) * 86_400;
        assert_eq!(Epoch::FIXED, Epoch::from_secs(new_year_2024));
        assert_eq!(Epoch::parse("2024-01-01T00:00:00Z"), Ok(Epoch::FIXED));
        assert_eq!(Epoch::parse("2024-01-01T01:00:00+01:00"), Ok(Epoch::FIXED));
        assert_eq!(Epoch::parse(&new_year_2024.to_string()), Ok(Epoch::FIXED));
        assert_eq!(
            Epoch::parse("2024-01-01T00:00:01.5Z").map(Epoch::as_micros),
            Ok((new_year_2024 + 1) * 1_000_000 + 500_000)
        );
        assert_eq!(Epoch::parse("0"), Ok(Epoch::UNIX));
        for bad in [
            "",
            "yesterday",
            "-5",
            "1.5",
            "2024-01-01",
            "1969-12-31T23:59:59Z",
            "2600-01-01T00:00:00Z",
            "99999999999999999999",
        ] {
            assert!(Epoch::parse(bad).is_err(), "{bad}");
        }
        let e = Epoch::FIXED;
        assert_eq!(
            e.stamp(BusTime::from_nanos(1_500)).to_string(),
            format!("{new_year_2024}.000001")
        );
        assert_eq!(
            e.unstamp(e.stamp(BusTime::from_nanos(7_000))),
            BusTime::from_nanos(7_000)
        );
        assert_eq!(Epoch::from_system_time(e.system_time()), e);
    }
}
