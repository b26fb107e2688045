//! What the accept loop does when `accept` fails: how long to wait before trying again, and
//! when to log. Sans-IO: the caller passes the time in.
//!
//! An accept error usually means the process is out of file descriptors (or the system out of
//! memory or buffers). The pending connection stays in the listen queue, so the listener stays
//! ready and an immediate retry fails again: without a pause the loop spins and logs as fast as
//! it can. So each failure waits, starting at [`MIN_DELAY`] and doubling up to [`MAX_DELAY`];
//! a successful accept starts again from the shortest wait. Logging is rate-limited to one
//! message per [`REPORT_INTERVAL`], which counts the failures since the previous message.

use std::time::{Duration, Instant};

/// The first wait after a failed accept.
pub const MIN_DELAY: Duration = Duration::from_millis(10);
/// The longest wait between attempts.
pub const MAX_DELAY: Duration = Duration::from_secs(1);
/// At most one log message per this interval.
pub const REPORT_INTERVAL: Duration = Duration::from_secs(10);

/// The accept loop's backoff and log rate limit.
#[derive(Debug)]
pub struct AcceptBackoff {
    delay: Duration,
    /// When the last message was logged.
    last_report: Option<Instant>,
    /// Failures not yet counted in a message.
    unreported: u64,
}

impl Default for AcceptBackoff {
    fn default() -> Self {
        AcceptBackoff {
            delay: MIN_DELAY,
            last_report: None,
            unreported: 0,
        }
    }
}

impl AcceptBackoff {
    /// An accept failed at `now`: how long to wait before the next attempt, and, if a message
    /// is due, the number of failures it reports (this one included).
    pub fn failed(&mut self, now: Instant) -> (Duration, Option<u64>) {
        let wait = self.delay;
        self.delay = (self.delay * 2).min(MAX_DELAY);
        self.unreported += 1;
        (wait, self.report(now))
    }

    /// An accept succeeded at `now`: the next failure waits the shortest time again. If
    /// failures went unreported and a message is due, their number.
    pub fn succeeded(&mut self, now: Instant) -> Option<u64> {
        self.delay = MIN_DELAY;
        if self.unreported == 0 {
            return None;
        }
        self.report(now)
    }

    fn report(&mut self, now: Instant) -> Option<u64> {
        let due = self
            .last_report
            .is_none_or(|t| now.saturating_duration_since(t) >= REPORT_INTERVAL);
        if !due {
            return None;
        }
        self.last_report = Some(now);
        Some(std::mem::take(&mut self.unreported))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn waits_double_up_to_a_second_and_start_over_after_a_success() {
        let t0 = Instant::now();
        let mut b = AcceptBackoff::default();
        let waits: Vec<u64> = (0..10).map(|_| b.failed(t0).0.as_millis() as u64).collect();
        assert_eq!(waits, [10, 20, 40, 80, 160, 320, 640, 1000, 1000, 1000]);
        b.succeeded(t0);
        assert_eq!(b.failed(t0).0, ms(10));
        assert_eq!(b.failed(t0).0, ms(20));
    }

    #[test]
    fn the_first_failure_is_logged_then_one_summary_per_interval() {
        let t0 = Instant::now();
        let mut b = AcceptBackoff::default();
        assert_eq!(b.failed(t0).1, Some(1));
        // A failure every second (the longest wait): silent for ten seconds...
        let mut t = t0;
        for _ in 1..10 {
            t += ms(1000);
            assert_eq!(b.failed(t).1, None);
        }
        // ...then one message counting the ten failures since the first.
        t += ms(1000);
        assert_eq!(b.failed(t).1, Some(10));
        t += ms(1000);
        assert_eq!(b.failed(t).1, None);
    }

    #[test]
    fn at_most_one_message_per_interval_however_fast_failures_come() {
        let t0 = Instant::now();
        let mut b = AcceptBackoff::default();
        let mut messages = 0;
        let mut total = 0;
        // Failures and successes alternating every millisecond for 30 s.
        for i in 0..30_000u64 {
            let t = t0 + ms(i);
            let report = if i % 2 == 0 { b.failed(t).1 } else { b.succeeded(t) };
            if let Some(n) = report {
                messages += 1;
                total += n;
            }
        }
        assert_eq!(messages, 3, "at 0, 10 and 20 s");
        assert!(total > 0 && total < 15_000, "{total}");
    }

    #[test]
    fn failures_left_unreported_are_counted_on_the_next_success_once_due() {
        let t0 = Instant::now();
        let mut b = AcceptBackoff::default();
        assert_eq!(b.failed(t0).1, Some(1));
        assert_eq!(b.failed(t0 + ms(10)).1, None);
        assert_eq!(b.failed(t0 + ms(30)).1, None);
        assert_eq!(b.succeeded(t0 + ms(70)), None, "not due yet");
        assert_eq!(b.succeeded(t0 + ms(10_070)), Some(2));
        assert_eq!(b.succeeded(t0 + ms(30_000)), None, "nothing left to report");
        // After a quiet spell, the next failure is logged at once.
        assert_eq!(b.failed(t0 + ms(40_000)).1, Some(1));
    }
}
