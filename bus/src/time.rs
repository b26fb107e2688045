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
use std::time::{SystemTime, UNIX_EPOCH};

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
    /// The wall clock now.
    pub fn now() -> Epoch {
        Epoch::from_system_time(SystemTime::now())
    }
    /// Whole seconds since 1970.
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
    /// 2500-01-01T00:00:00Z: later epochs would leave too little room for bus time in a u64 of
    /// nanoseconds.
    const LATEST: Epoch = Epoch(16_725_225_600_000_000);

    /// Microseconds since 1970.
    pub const fn as_micros(self) -> u64 {
        self.0
    }
    /// The epoch as a wall-clock time.
    pub fn system_time(self) -> SystemTime {
        UNIX_EPOCH + Duration::from_micros(self.0)
    }
    /// Bus time `at` as written out: nanoseconds since 1970 (saturating).
    pub const fn stamp(self, at: BusTime) -> BusTime {
        BusTime(at.0.saturating_add(self.0.saturating_mul(1_000)))
    }
    /// A written-out time back to bus time (zero for one before the epoch).
    pub const fn unstamp(self, at: BusTime) -> BusTime {
        BusTime(at.0.saturating_sub(self.0.saturating_mul(1_000)))
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
            e.stamp(BusTime(1_500)).to_string(),
            format!("{new_year_2024}.000001")
        );
        assert_eq!(e.unstamp(e.stamp(BusTime(7_000))), BusTime(7_000));
        assert_eq!(Epoch::from_system_time(e.system_time()), e);
    }
}
