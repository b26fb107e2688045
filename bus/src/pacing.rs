//! The pacing of a real-time hub, sans-IO: when bus time may be committed, given the wall clock,
//! and what happens when the process was not scheduled for a while (an overrun).
//!
//! Contract: the wall clock is given as nanoseconds since the hub started. Bus time `t` is due at
//! wall time `slip + t`, and may be committed from `slack` before that. When the hub is about to
//! commit `t` and finds the wall clock more than the threshold past `t`'s due time, the process
//! was stalled (not scheduled, frozen, swapped out): instead of sending every overdue frame back to
//! back, bus time **slips**. `slip` grows by the lateness, so `t` is due now and everything after
//! it keeps its spacing; the overrun is counted, and bus time stays behind the wall clock by the
//! slips added up. Lateness up to the threshold is caught up as before (a frame goes out a little
//! late). [`Pacer::log_due`] rate-limits the log lines about overruns.
//!
//! Nothing here allocates: it runs on every step of a paced hub.

use crate::time::BusTime;
use std::time::Duration;

/// How late bus time may fall behind its schedule before it slips, by default. A stall shorter
/// than this is caught up (frames go out up to this late, back to back); a longer one slips.
/// 50 ms is the flow sensors' acknowledgement deadline: a caught-up delay costs a sensor at most
/// one acknowledgement, never the three in a row that make it give up. It is well above the
/// wake-up lateness of a loaded machine: in the emulated (TCG) test VM timer wakes often come
/// 20–30 ms late, and a 20 ms threshold there slipped at nearly every wake, which slowed bus time
/// to a tenth of real time.
pub const OVERRUN_THRESHOLD: Duration = Duration::from_millis(50);

/// How often, at most, an overrun is logged (wall time); the count in between is summed up.
pub const LOG_EVERY: Duration = Duration::from_secs(1);

/// What the overruns came to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Overruns {
    /// Overruns: times the hub found bus time more than the threshold behind its schedule.
    pub count: u64,
    /// How far bus time slipped in all, in nanoseconds: how far it is behind the wall clock.
    pub slipped_ns: u64,
    /// The longest single slip, in nanoseconds.
    pub longest_ns: u64,
}

/// What the hub is to do about bus time `t`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pace {
    /// Not yet: wait until this wall time (nanoseconds since the start).
    Wait(u64),
    /// Commit it now; with the lateness that was slipped when it was an overrun.
    Go {
        /// Nanoseconds slipped by this decision, if it was an overrun.
        slipped: Option<u64>,
    },
}

/// The pacing state of one hub.
#[derive(Clone, Debug)]
pub struct Pacer {
    slack_ns: u64,
    threshold_ns: u64,
    slip_ns: u64,
    overruns: Overruns,
    /// Wall time of the last overrun log line, and the overruns counted then.
    logged: Option<(u64, u64)>,
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

impl Pacer {
    /// A pacer that lets bus time run `slack` ahead and slips beyond `threshold` of lateness.
    pub fn new(slack: Duration, threshold: Duration) -> Pacer {
        Pacer {
            slack_ns: nanos(slack),
            threshold_ns: nanos(threshold),
            slip_ns: 0,
            overruns: Overruns::default(),
            logged: None,
        }
    }

    /// The wall time (nanoseconds since the start) from which bus time `t` may be committed.
    pub fn due(&self, t: BusTime) -> u64 {
        self.slip_ns
            .saturating_add(t.as_nanos())
            .saturating_sub(self.slack_ns)
    }

    /// The bus time that wall time `wall_ns` stands for (where a frame from outside belongs).
    pub fn bus_time(&self, wall_ns: u64) -> BusTime {
        BusTime::from_nanos(wall_ns.saturating_sub(self.slip_ns))
    }

    /// Decides about committing bus time `t` at wall time `wall_ns`; slips when `t` is overdue
    /// by more than the threshold.
    pub fn check(&mut self, wall_ns: u64, t: BusTime) -> Pace {
        let due = self.due(t);
        if wall_ns < due {
            return Pace::Wait(due);
        }
        let late = wall_ns.saturating_sub(self.slip_ns.saturating_add(t.as_nanos()));
        if late <= self.threshold_ns {
            return Pace::Go { slipped: None };
        }
        self.slip_ns = self.slip_ns.saturating_add(late);
        let o = &mut self.overruns;
        o.count += 1;
        o.slipped_ns = o.slipped_ns.saturating_add(late);
        o.longest_ns = o.longest_ns.max(late);
        Pace::Go { slipped: Some(late) }
    }

    /// The overruns so far.
    pub fn overruns(&self) -> Overruns {
        self.overruns
    }

    /// Whether an overrun at wall time `wall_ns` is to be logged: the first one is, and then one
    /// per [`LOG_EVERY`] at most. Returns how many overruns the line covers (those since the
    /// last line).
    pub fn log_due(&mut self, wall_ns: u64) -> Option<u64> {
        let count = self.overruns.count;
        match self.logged {
            Some((at, _)) if wall_ns.saturating_sub(at) < nanos(LOG_EVERY) => None,
            last => {
                self.logged = Some((wall_ns, count));
                Some(count - last.map_or(0, |(_, n)| n))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    fn pacer() -> Pacer {
        Pacer::new(Duration::ZERO, Duration::from_millis(20))
    }

    #[test]
    fn bus_time_waits_for_the_wall_clock() {
        let mut p = pacer();
        assert_eq!(p.check(5 * MS, BusTime::from_nanos(10 * MS)), Pace::Wait(10 * MS));
        assert_eq!(
            p.check(10 * MS, BusTime::from_nanos(10 * MS)),
            Pace::Go { slipped: None }
        );
        // With slack, a little ahead of time.
        let mut p = Pacer::new(Duration::from_millis(2), Duration::from_millis(20));
        assert_eq!(
            p.check(8 * MS, BusTime::from_nanos(10 * MS)),
            Pace::Go { slipped: None }
        );
        assert_eq!(p.check(7 * MS, BusTime::from_nanos(10 * MS)), Pace::Wait(8 * MS));
    }

    #[test]
    fn lateness_up_to_the_threshold_is_caught_up_without_slipping() {
        let mut p = pacer();
        // 20 ms late: the frames go out back to back, bus time keeps its schedule.
        assert_eq!(
            p.check(120 * MS, BusTime::from_nanos(100 * MS)),
            Pace::Go { slipped: None }
        );
        assert_eq!(
            p.check(120 * MS, BusTime::from_nanos(110 * MS)),
            Pace::Go { slipped: None }
        );
        assert_eq!(p.overruns(), Overruns::default());
        assert_eq!(p.bus_time(120 * MS), BusTime::from_nanos(120 * MS));
    }

    #[test]
    fn a_stall_slips_bus_time_instead_of_bursting() {
        let mut p = pacer();
        // The process was frozen: at wall 500 ms, bus time 100 ms is 400 ms overdue.
        assert_eq!(
            p.check(500 * MS, BusTime::from_nanos(100 * MS)),
            Pace::Go {
                slipped: Some(400 * MS)
            }
        );
        // The rest keeps its spacing from there: 200 ms is due at wall 600 ms, not at once.
        assert_eq!(
            p.check(500 * MS, BusTime::from_nanos(200 * MS)),
            Pace::Wait(600 * MS)
        );
        assert_eq!(
            p.check(600 * MS, BusTime::from_nanos(200 * MS)),
            Pace::Go { slipped: None }
        );
        // A frame arriving from outside at wall 550 ms belongs at bus time 150 ms.
        assert_eq!(p.bus_time(550 * MS), BusTime::from_nanos(150 * MS));
        // A second stall adds up.
        assert_eq!(
            p.check(1_000 * MS, BusTime::from_nanos(250 * MS)),
            Pace::Go {
                slipped: Some(350 * MS)
            }
        );
        assert_eq!(
            p.overruns(),
            Overruns {
                count: 2,
                slipped_ns: 750 * MS,
                longest_ns: 400 * MS
            }
        );
        assert_eq!(p.bus_time(1_000 * MS), BusTime::from_nanos(250 * MS));
    }

    #[test]
    fn overrun_lines_are_rate_limited() {
        let mut p = pacer();
        let mut overrun = |wall: u64| {
            let t = p.bus_time(wall).as_nanos().saturating_sub(30 * MS);
            assert!(matches!(
                p.check(wall, BusTime::from_nanos(t)),
                Pace::Go { slipped: Some(_) }
            ));
            p.log_due(wall)
        };
        assert_eq!(overrun(100 * MS), Some(1), "the first is logged");
        assert_eq!(overrun(200 * MS), None);
        assert_eq!(overrun(900 * MS), None);
        assert_eq!(
            overrun(1_100 * MS),
            Some(3),
            "a second later, with the two in between"
        );
        assert_eq!(overrun(1_200 * MS), None);
    }
}
