//! Bus time: nanoseconds since the bus started.
//!
//! The bus keeps its own clock in whole nanoseconds because a frame lasts a few hundred
//! microseconds and tokio's timers only resolve milliseconds. The bus runs only at rates whose
//! bit time is a whole number of nanoseconds (125, 250, 500 and 1000 kbit/s among them: every
//! rate that divides 10^9), so this clock is exact.

use core::fmt;
use core::ops::{Add, Sub};
use core::time::Duration;
use serde::{Deserialize, Serialize};

/// A point on the bus clock, in nanoseconds since the bus started.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct BusTime(pub u64);

impl BusTime {
    /// The start of the bus.
    pub const ZERO: BusTime = BusTime(0);
    /// Later than anything.
    pub const NEVER: BusTime = BusTime(u64::MAX);

    /// From whole seconds, saturating at [`BusTime::NEVER`] (about 584 years).
    pub const fn from_secs(s: u64) -> BusTime {
        BusTime(s.saturating_mul(1_000_000_000))
    }
    /// From seconds, rounded to the nanosecond (negative and non-numbers give zero).
    pub fn from_secs_f64(s: f64) -> BusTime {
        BusTime(if s.is_finite() && s > 0.0 {
            (s * 1e9).round() as u64
        } else {
            0
        })
    }
    /// From whole milliseconds, saturating at [`BusTime::NEVER`]: config and script times are
    /// read as `u64`, and a huge one must mean "never", not overflow.
    pub const fn from_millis(ms: u64) -> BusTime {
        BusTime(ms.saturating_mul(1_000_000))
    }
    /// From whole microseconds, saturating at [`BusTime::NEVER`].
    pub const fn from_micros(us: u64) -> BusTime {
        BusTime(us.saturating_mul(1_000))
    }
    /// From a duration since the start.
    pub fn from_duration(d: Duration) -> BusTime {
        BusTime(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
    }
    /// Nanoseconds since the start.
    pub const fn as_nanos(self) -> u64 {
        self.0
    }
    /// The time since the start as a duration.
    pub const fn as_duration(self) -> Duration {
        Duration::from_nanos(self.0)
    }
    /// Seconds since the start, for display.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 / 1e9
    }
    /// `self + d`, saturating.
    pub fn after(self, d: Duration) -> BusTime {
        BusTime(
            self.0
                .saturating_add(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)),
        )
    }
    /// The time elapsed from `earlier` to `self` (zero if `earlier` is later).
    pub fn since(self, earlier: BusTime) -> Duration {
        Duration::from_nanos(self.0.saturating_sub(earlier.0))
    }
}

impl Add<u64> for BusTime {
    type Output = BusTime;
    /// Adds nanoseconds, saturating.
    fn add(self, ns: u64) -> BusTime {
        BusTime(self.0.saturating_add(ns))
    }
}

impl Sub for BusTime {
    type Output = u64;
    /// Nanoseconds between two times, saturating at zero.
    fn sub(self, other: BusTime) -> u64 {
        self.0.saturating_sub(other.0)
    }
}

impl fmt::Display for BusTime {
    /// `seconds.microseconds`, as candump writes timestamps.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}.{:06}",
            self.0 / 1_000_000_000,
            self.0 % 1_000_000_000 / 1_000
        )
    }
}

impl fmt::Debug for BusTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:09}s", self.0 / 1_000_000_000, self.0 % 1_000_000_000)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_units_convert_exactly_and_saturate() {
        assert_eq!(BusTime::from_secs(3), BusTime(3_000_000_000));
        assert_eq!(BusTime::from_millis(500), BusTime(500_000_000));
        assert_eq!(BusTime::from_micros(200), BusTime(200_000));
        // The largest values that still fit, then one more.
        assert_eq!(
            BusTime::from_millis(u64::MAX / 1_000_000),
            BusTime(u64::MAX / 1_000_000 * 1_000_000)
        );
        assert_eq!(BusTime::from_millis(u64::MAX / 1_000_000 + 1), BusTime::NEVER);
        // A harvester config with `time_relay_ms: 18446744073709551615` overflowed here.
        assert_eq!(BusTime::from_millis(u64::MAX), BusTime::NEVER);
        assert_eq!(BusTime::from_micros(u64::MAX), BusTime::NEVER);
        assert_eq!(BusTime::from_secs(u64::MAX / 1_000_000_000 + 1), BusTime::NEVER);
    }
}
