//! The checks of the outside monitor's run: calibration, acknowledgements, the freezes of harvemu
//! and what harvemu said about them on stderr.
//!
//! The freezes: harvemu is stopped for [`STALL`] three times. A real-time emulator that bursts
//! out every overdue frame after a freeze puts the monitor's acknowledgements late in bus time
//! and the sensors give up; harvemu's overrun policy lets bus time slip instead. So after each
//! freeze every sensor must stream again within [`RESTART`], without a burst (at most
//! [`BURST_LIMIT`] flow groups in the first [`BURST_WINDOW`]), none may report "no
//! acknowledgement", the stream after the last freeze must keep its rate, and harvemu must count
//! the freezes as overruns. The margins are wide: the VM emulates its CPU (TCG) and is slow.

use crate::harvester::{Recording, STALL, STALLS, times};
use crate::{Outcome, Report};

/// Every sensor sends a flow group this soon after harvemu is resumed (a group every 100 ms,
/// plus scheduling under TCG).
const RESTART: f64 = 1.0;

/// Right after a freeze, this long holds at most [`BURST_LIMIT`] flow groups of one sensor: a
/// burst of the groups that fell due during the freeze would put 3 or 4 there.
const BURST_WINDOW: f64 = 0.15;

/// See [`BURST_WINDOW`].
const BURST_LIMIT: usize = 2;

/// After the last freeze, from this long after it, each sensor sends at least this share of the
/// nominal 10 groups per second.
const SETTLE: f64 = 0.3;
const RATE_SHARE: f64 = 0.6;

/// Runs the checks.
pub fn check(recording: &Recording, stderr: &[String], report: &mut Report) {
    report.check("the outside monitor calibrates D0–D5", calibrated(recording));
    report.check("no flow sensor reports no acknowledgement", no_give_up(recording));
    for (i, stall) in recording.stalls.iter().enumerate() {
        let name = format!("freeze {}: harvemu stopped for {} ms", i + 1, STALL.as_millis());
        let outcome = match (&stall.error, stall.resumed) {
            (Some(e), _) => Err(e.clone()),
            (None, None) => Err("never resumed".to_owned()),
            (None, Some(resumed)) => Ok(format!(
                "SIGSTOP at {:.3} s, SIGCONT at {resumed:.3} s",
                stall.stopped
            )),
        };
        report.check(&name, outcome);
    }
    if recording.stalls.len() < STALLS.len() {
        report.check(
            "every freeze made",
            Err(format!("{} of {}", recording.stalls.len(), STALLS.len())),
        );
    }
    report.check(
        "the flow sensors stream on after each freeze, without a burst",
        streaming(recording),
    );
    report.check("harvemu counts the freezes as overruns", overruns(stderr));
    report.check(
        "the bridge reads every frame with a kernel timestamp",
        kernel_stamps(stderr),
    );
}

/// Every sensor was accepted after calibration.
fn calibrated(recording: &Recording) -> Outcome {
    let tally = &recording.monitor.tally;
    let detail: Vec<String> = tally
        .iter()
        .enumerate()
        .map(|(x, t)| match t.accepted_at {
            Some(at) => format!(
                "D{x} accepted at {at:.2} s, {} groups acknowledged",
                t.acknowledged
            ),
            None => format!("D{x} never calibrated ({} statuses)", t.statuses),
        })
        .collect();
    if tally.iter().all(|t| t.accepted_at.is_some()) {
        Ok(detail.join("; "))
    } else {
        Err(detail.join("; "))
    }
}

/// No sensor reported "no acknowledgement".
fn no_give_up(recording: &Recording) -> Outcome {
    let tally = &recording.monitor.tally;
    let gave_up: Vec<String> = tally
        .iter()
        .enumerate()
        .filter(|(_, t)| !t.gave_up.is_empty())
        .map(|(x, t)| {
            let at: Vec<String> = t.gave_up.iter().map(|a| format!("{a:.2}")).collect();
            format!("D{x} at {} s", at.join(", "))
        })
        .collect();
    let statuses: u64 = tally.iter().map(|t| t.statuses).sum();
    let lost: u64 = tally.iter().map(|t| t.lost).sum();
    if gave_up.is_empty() {
        Ok(format!("{statuses} flow.status frames, {lost} groups broken off"))
    } else {
        Err(format!("gave up: {}", gave_up.join("; ")))
    }
}

/// After each freeze every sensor streams again soon, without a burst; after the last one each
/// keeps its rate to the end of the recording.
fn streaming(recording: &Recording) -> Outcome {
    let resumed: Vec<f64> = recording.stalls.iter().filter_map(|s| s.resumed).collect();
    let Some(&last) = resumed.last() else {
        return Err("no freeze was made".to_owned());
    };
    let mut problems = Vec::new();
    let mut rates = Vec::new();
    for x in 0..6u32 {
        let groups = times(&recording.frames, 0x0601_F5D0 | x, &[0x20, 0x0D]);
        for &r in &resumed {
            let after: Vec<f64> = groups.iter().map(|&g| g - r).filter(|&d| d >= 0.0).collect();
            match after.first() {
                Some(&d) if d <= RESTART => {}
                Some(&d) => problems.push(format!("D{x}: first group {d:.2} s after the freeze at {r:.2} s")),
                None => problems.push(format!("D{x}: no group after the freeze at {r:.2} s")),
            }
            let burst = after.iter().filter(|&&d| d < BURST_WINDOW).count();
            if burst > BURST_LIMIT {
                problems.push(format!(
                    "D{x}: {burst} groups within {BURST_WINDOW} s of the freeze at {r:.2} s"
                ));
            }
        }
        let from = last + SETTLE;
        let span = recording.end - from;
        let n = groups.iter().filter(|&&g| g >= from).count();
        rates.push(format!("D{x} {:.1}/s", n as f64 / span));
        if (n as f64) < span * 10.0 * RATE_SHARE {
            problems.push(format!(
                "D{x}: {n} groups in the {span:.2} s after the last freeze"
            ));
        }
    }
    let detail = format!("after the last freeze: {}", rates.join(", "));
    if problems.is_empty() {
        Ok(detail)
    } else {
        Err(format!("{}; {detail}", problems.join("; ")))
    }
}

/// The numbers in `line`, in order (digits with an optional decimal point).
fn numbers(line: &str) -> Vec<f64> {
    line.split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter_map(|w| w.trim_matches('.').parse().ok())
        .collect()
}

/// harvemu's closing line `real time: N overruns, bus time S s behind the wall clock (longest
/// M ms)` counts at least one overrun per freeze, the longest nearly a whole freeze.
fn overruns(stderr: &[String]) -> Outcome {
    let Some(line) = stderr
        .iter()
        .find(|l| l.contains("real time: ") && l.contains(" overruns"))
    else {
        return Err("no `real time: N overruns` line on harvemu's stderr".to_owned());
    };
    let tail = line.split("real time: ").nth(1).unwrap_or_default();
    match numbers(tail)[..] {
        [n, _behind, longest_ms, ..]
            if n >= STALLS.len() as f64 && longest_ms >= STALL.as_millis() as f64 * 0.75 =>
        {
            Ok(tail.to_owned())
        }
        _ => Err(format!(
            "expected at least {} overruns, the longest near {} ms: {tail}",
            STALLS.len(),
            STALL.as_millis()
        )),
    }
}

/// The bridge's line `N frames in (M with kernel timestamps, ...)` has M = N > 0.
fn kernel_stamps(stderr: &[String]) -> Outcome {
    let Some(line) = stderr.iter().find(|l| l.contains(" frames in (")) else {
        return Err("no `N frames in (...)` line on harvemu's stderr".to_owned());
    };
    let tail = line.split("interface: ").nth(1).unwrap_or(line);
    match numbers(tail)[..] {
        [n, m, ..] if n > 0.0 && m == n => Ok(tail.to_owned()),
        _ => Err(tail.to_owned()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lines_are_read() {
        let ok = [
            "harvemu: interface: 312 frames in (312 with kernel timestamps, longest wait 80 us), 4000 out"
                .to_owned(),
        ];
        assert!(kernel_stamps(&ok).is_ok());
        let none =
            ["harvemu: interface: 312 frames in (0 with kernel timestamps, longest wait 0 us)".to_owned()];
        assert!(kernel_stamps(&none).is_err());
        let slipped = [
            "harvemu: real time: 4 overruns, bus time 1.235 s behind the wall clock (longest 407 ms)"
                .to_owned(),
        ];
        assert!(overruns(&slipped).is_ok(), "{:?}", overruns(&slipped));
        let short = [
            "harvemu: real time: 4 overruns, bus time 0.100 s behind the wall clock (longest 25 ms)"
                .to_owned(),
        ];
        assert!(overruns(&short).is_err());
        assert!(overruns(&[]).is_err());
    }
}
