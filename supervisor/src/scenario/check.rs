//! Verdicts: each expectation against what the run produced.

use super::Expect;
use super::books::Books;
use super::plan::Check;
use super::states::{Seen, Timeline};
use crate::harvester::{Happened, Running};
use bus::engine::NodeId;
use bus::fault::ErrorState;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::Snapshot;
use serde::Serialize;

/// The outcome of one expectation.
#[derive(Clone, Debug, Serialize)]
pub struct Verdict {
    /// The expectation, as written.
    pub expectation: String,
    /// Pass or fail.
    pub passed: bool,
    /// When it was decided (the time of the observation that settled it), if there is one.
    pub at: Option<BusTime>,
    /// What was observed.
    pub observed: String,
}

fn verdict(e: &Expect, passed: bool, at: Option<BusTime>, observed: String) -> Verdict {
    Verdict {
        expectation: format!("{e:?}"),
        passed,
        at,
        observed,
    }
}

/// Checks every expectation, resolved ([`Check`]: its node's id known); `kinds` holds the
/// errors the `ErrorKinds` expectations asked the trace to count.
pub fn all(
    checks: &[Check],
    r: &Running,
    snap: &Snapshot,
    books: &Books,
    kinds: &[(super::kinds::Query, u64)],
) -> Vec<Verdict> {
    checks
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let counted = kinds.iter().find(|(q, _)| q.check == i).map(|(_, n)| *n);
            one(&c.expect, c.node, r, snap, books, counted)
        })
        .collect()
}

fn one(
    e: &Expect,
    id: Option<NodeId>,
    r: &Running,
    snap: &Snapshot,
    books: &Books,
    counted: Option<u64>,
) -> Verdict {
    let display = r.display.as_ref().map(|d| d.borrow().clone()).unwrap_or_default();
    match e {
        Expect::Counters { node, at_s, tec, rec } => {
            let t = timeline(snap, id);
            let at = BusTime::from_secs_f64(*at_s);
            let (p, since) = t.at(at);
            let since = since.map_or("since the start".to_string(), |s| format!("since {s} s"));
            let observed = format!("{node}: TEC {}, REC {} at {at} s ({since})", p.tec, p.rec);
            if !t.counters_exact(at, at) {
                return verdict(
                    e,
                    false,
                    Some(at),
                    format!("cannot tell: {node}'s history merged its spans there; {observed}"),
                );
            }
            verdict(e, p.tec == *tec && p.rec == *rec, Some(at), observed)
        }
        Expect::ErrorKinds {
            node,
            kind,
            min,
            max,
            from_s,
            to_s,
        } => {
            let from = BusTime::from_secs_f64(*from_s);
            let to = to_s.map_or(snap.now, BusTime::from_secs_f64);
            match counted {
                Some(n) => verdict(
                    e,
                    (*min..=*max).contains(&n),
                    Some(to),
                    format!(
                        "{node} detected {} from {from} s to {to} s",
                        n_of(n, &format!("{kind:?} error"))
                    ),
                ),
                None => verdict(e, false, None, "the errors were not counted".into()),
            }
        }
        Expect::AlarmRaised {
            node,
            alarm,
            after_s,
            within_ms,
        }
        | Expect::AlarmCleared {
            node,
            alarm,
            after_s,
            within_ms,
        } => {
            let raised = matches!(e, Expect::AlarmRaised { .. });
            let from = BusTime::from_secs_f64(*after_s);
            let to = from + BusDuration::from_millis(*within_ms);
            let times: Vec<BusTime> = display
                .alarms
                .iter()
                .filter(|a| &a.node == node && &a.name == alarm)
                .filter_map(|a| if raised { Some(a.raised) } else { a.cleared })
                .filter(|t| *t >= from)
                .collect();
            match times.first() {
                Some(&t) => {
                    let delay = (t - from).as_nanos() as f64 / 1e6;
                    verdict(
                        e,
                        t <= to,
                        Some(t),
                        format!(
                            "{} after {delay:.1} ms",
                            if raised { "raised" } else { "cleared" }
                        ),
                    )
                }
                None => verdict(
                    e,
                    false,
                    None,
                    format!(
                        "not {} after {after_s} s",
                        if raised { "raised" } else { "cleared" }
                    ),
                ),
            }
        }
        Expect::NoAlarms => {
            let first = display.alarms.first();
            verdict(
                e,
                first.is_none(),
                first.map(|a| a.raised),
                match first {
                    Some(a) => format!(
                        "{} alarm{}, first {} {} at {}",
                        display.alarms.len(),
                        if display.alarms.len() == 1 { "" } else { "s" },
                        a.node,
                        a.name,
                        a.raised
                    ),
                    None => "none".into(),
                },
            )
        }
        Expect::BusLoadBelow(limit) => {
            let load = snap.stats.total_load() * 100.0;
            verdict(e, load < *limit, Some(snap.now), format!("{load:.1} %"))
        }
        Expect::NoFrameLost => {
            let (overruns, lost, broken) = (snap.stats.overruns, display.lost, display.broken_groups);
            verdict(
                e,
                overruns == 0 && lost == 0 && broken == 0,
                Some(snap.now),
                format!(
                    "{}, {lost} lost by the monitor, {}",
                    n_of(overruns, "overrun"),
                    n_of(broken, "broken group")
                ),
            )
        }
        Expect::NodeState {
            state,
            after_s,
            within_ms,
            ..
        } => {
            let from = BusTime::from_secs_f64(*after_s);
            let to = from + BusDuration::from_millis(*within_ms);
            let history = id.and_then(|id| snap.stats.nodes.get(id.index()));
            let hit = history.and_then(|h| {
                h.counters
                    .points
                    .iter()
                    .find(|(t, (_, _, s))| *t >= from && s == state)
                    .map(|(t, _)| *t)
            });
            // A node that never left the state has no history point: its current state counts.
            let now_state = id.and_then(|id| snap.nodes.get(id.index())).map(|n| n.state);
            match hit {
                Some(t) => verdict(
                    e,
                    t <= to,
                    Some(t),
                    format!("{state:?} after {:.3} ms", (t - from).as_nanos() as f64 / 1e6),
                ),
                None if now_state == Some(*state)
                    && *state == ErrorState::Active
                    && history.is_none_or(|h| h.counters.points.is_empty()) =>
                {
                    verdict(e, true, Some(snap.now), "error active throughout".into())
                }
                None => verdict(
                    e,
                    false,
                    None,
                    format!("not {state:?} after {after_s} s (now {now_state:?})"),
                ),
            }
        }
        Expect::ErrorFrames { min, max } => {
            let n = snap.stats.error_frames;
            verdict(
                e,
                (*min..=*max).contains(&n),
                Some(snap.now),
                n_of(n, "error frame"),
            )
        }
        Expect::OverloadFrames { min, max } => {
            let n = snap.stats.overloads;
            verdict(
                e,
                (*min..=*max).contains(&n),
                Some(snap.now),
                n_of(n, "overload flag"),
            )
        }
        Expect::YieldWithin(percent) => {
            let truth = r.plant.borrow().signal("harvested.total").unwrap_or(0.0);
            let err = if truth > 0.0 {
                (display.total_kg - truth) / truth * 100.0
            } else {
                f64::INFINITY
            };
            verdict(
                e,
                err.abs() <= *percent,
                Some(snap.now),
                format!(
                    "monitor {:.1} kg, plant {truth:.1} kg ({err:+.2} %)",
                    display.total_kg
                ),
            )
        }
        Expect::Display { field, min, max } => {
            let value = serde_json::to_value(&display)
                .ok()
                .and_then(|v| v.get(field).and_then(|x| x.as_f64()));
            match value {
                Some(v) => verdict(
                    e,
                    (*min..=*max).contains(&v),
                    Some(snap.now),
                    format!("{field} = {v}"),
                ),
                None => verdict(e, false, Some(snap.now), format!("{field} has no value")),
            }
        }
        Expect::Plant { signal, min, max } => {
            let v = r.plant.borrow().signal(signal).unwrap_or(f64::NAN);
            verdict(
                e,
                (*min..=*max).contains(&v),
                Some(snap.now),
                format!("{signal} = {v}"),
            )
        }
        Expect::Restarts { node, count } => {
            let n = r
                .events
                .iter()
                .filter(|ev| &ev.node == node && ev.what == Happened::Restarted)
                .count();
            let at = r.events.iter().rev().find(|ev| &ev.node == node).map(|ev| ev.at);
            verdict(e, n == *count, at, n_of(n as u64, "restart"))
        }
        Expect::FramesAccounted => match &books.monitor {
            Some(m) => {
                let failed: Vec<&str> = m.checks().iter().filter(|c| !c.holds()).map(|c| c.what).collect();
                let lost = m.on_bus - m.tally.processed.min(m.on_bus);
                let observed = if failed.is_empty() {
                    format!(
                        "{} to F5: {} processed, {lost} accounted as lost or pending",
                        n_of(m.on_bus, "frame"),
                        m.tally.processed
                    )
                } else {
                    format!(
                        "{} to F5, {} accounted; off: {}",
                        n_of(m.on_bus, "frame"),
                        m.accounted(),
                        failed.join("; ")
                    )
                };
                verdict(e, failed.is_empty(), Some(snap.now), observed)
            }
            None => verdict(e, false, None, "no emulated monitor".into()),
        },
        Expect::NodeStateNever {
            node,
            state,
            from_s,
            to_s,
        } => {
            let t = timeline(snap, id);
            let (from, to) = window(*from_s, *to_s);
            match t.first(from, to, |p| p.state == *state) {
                Some(seen) => verdict(e, false, Some(seen.at), was(node, &seen, &state.to_string())),
                None => judged(
                    e,
                    &t,
                    node,
                    Some(to),
                    format!("{node} never {state} from {from} s to {to} s"),
                ),
            }
        }
        Expect::NodeStateHolds {
            node,
            state,
            from_s,
            to_s,
        } => {
            let t = timeline(snap, id);
            let (from, to) = window(*from_s, *to_s);
            match t.first(from, to, |p| p.state != *state) {
                Some(seen) => verdict(
                    e,
                    false,
                    Some(seen.at),
                    was(node, &seen, &seen.point.state.to_string()),
                ),
                None => judged(
                    e,
                    &t,
                    node,
                    Some(to),
                    format!("{node} {state} throughout, {from} s to {to} s"),
                ),
            }
        }
        Expect::BusOffCount { node, min, max } => {
            let t = timeline(snap, id);
            let times = t.entries(ErrorState::BusOff);
            let n = times.len();
            let listed: Vec<String> = times.iter().take(5).map(|t| format!("{t} s")).collect();
            let more = if n > 5 { ", ..." } else { "" };
            let observed = match n {
                0 => format!("{node} never went bus off"),
                _ => format!(
                    "{node} went bus off {}, at {}{more}",
                    n_of(n as u64, "time"),
                    listed.join(", ")
                ),
            };
            let passed = (u64::from(*min)..=u64::from(*max)).contains(&(n as u64));
            if passed {
                judged(e, &t, node, times.last().copied(), observed)
            } else {
                verdict(e, false, times.last().copied(), observed)
            }
        }
        Expect::BusOffLongest { node, max_ms } => {
            let t = timeline(snap, id);
            let stays = t.stays(ErrorState::BusOff);
            let longest = stays
                .iter()
                .map(|&(from, to)| (from, to.map(|to| to.since(from).as_secs_f64() * 1e3)))
                .max_by(|a, b| {
                    a.1.unwrap_or(f64::INFINITY)
                        .total_cmp(&b.1.unwrap_or(f64::INFINITY))
                });
            let (observed, passed, at) = match longest {
                None => (format!("{node} never went bus off"), false, None),
                Some((from, None)) => (
                    format!("{node} went bus off at {from} s and stayed"),
                    false,
                    Some(from),
                ),
                Some((from, Some(ms))) => (
                    format!(
                        "{node} went bus off {}; the longest, from {from} s, lasted {ms:.3} ms",
                        n_of(stays.len() as u64, "time")
                    ),
                    ms <= *max_ms,
                    Some(from),
                ),
            };
            if passed {
                judged(e, &t, node, at, observed)
            } else {
                verdict(e, false, at, observed)
            }
        }
        Expect::RecMax {
            node,
            max,
            from_s,
            to_s,
        }
        | Expect::TecMax {
            node,
            max,
            from_s,
            to_s,
        } => {
            let t = timeline(snap, id);
            let rec = matches!(e, Expect::RecMax { .. });
            let name = if rec { "REC" } else { "TEC" };
            let counter = |p: super::states::Point| if rec { p.rec } else { p.tec };
            let (from, to) = window(*from_s, *to_s);
            match t.first(from, to, |p| counter(p) > *max) {
                // Merged spans keep their highest counters: a pass is certain, a span above the
                // limit proves a failure only where the counters are exact.
                Some(seen) if t.counters_exact(from, to) => verdict(
                    e,
                    false,
                    Some(seen.at),
                    format!("{node}'s {name} was {} at {} s", counter(seen.point), seen.at),
                ),
                Some(seen) => judged(
                    e,
                    &t,
                    node,
                    Some(seen.at),
                    format!("{node}'s {name} up to {} near {} s", counter(seen.point), seen.at),
                ),
                None => {
                    let (highest, at) = t.highest(from, to, counter);
                    verdict(
                        e,
                        true,
                        Some(at),
                        format!("{node}'s {name} at most {highest} (first at {at} s)"),
                    )
                }
            }
        }
        Expect::NoCrashes => {
            let own: Vec<&crate::harvester::SupervisorEvent> =
                r.events.iter().filter(|ev| ev.what.is_own_crash()).collect();
            match own.first() {
                None => verdict(e, true, None, "no crash but the timeline's".into()),
                Some(first) => verdict(
                    e,
                    false,
                    Some(first.at),
                    format!(
                        "{} by itself; first: {} {}",
                        bus::text::count(own.len() as u64, "crash", "crashes"),
                        first.node,
                        first.what
                    ),
                ),
            }
        }
        Expect::TraceComplete => match (books.trace, books.trace_complete()) {
            (Some(t), Some(ok)) => verdict(
                e,
                ok,
                Some(snap.now),
                format!(
                    "{} on the bus, {} in the trace ({})",
                    n_of(books.frames, "frame"),
                    n_of(t.frames, "frame"),
                    n_of(t.error_frames, "error frame")
                ),
            ),
            _ => verdict(e, false, None, "the trace was not counted".into()),
        },
    }
}

/// A node's error history, by its id (none: no history, as for a node that never erred).
fn timeline(snap: &Snapshot, id: Option<NodeId>) -> Timeline<'_> {
    Timeline::new(
        id.and_then(|id| snap.stats.nodes.get(id.index()))
            .map(|h| &h.spans),
    )
}

/// A window in bus time, both ends included.
fn window(from_s: f64, to_s: f64) -> (BusTime, BusTime) {
    (BusTime::from_secs_f64(from_s), BusTime::from_secs_f64(to_s))
}

/// "E0 was bus off at 7.204 s" (or, when it already was on entering the window, since when).
fn was(node: &str, seen: &Seen, what: &str) -> String {
    match (seen.entering, seen.since) {
        (false, _) => format!("{node} was {what} at {} s", seen.at),
        (true, Some(since)) => format!("{node} was {what} at {} s (since {since} s)", seen.at),
        (true, None) => format!("{node} was {what} at {} s (since the start)", seen.at),
    }
}

/// A pass that rests on nothing having happened: it stands only if the history kept every change
/// of state (state checks) or every counter in the window (counter checks).
fn judged(e: &Expect, t: &Timeline, node: &str, at: Option<BusTime>, observed: String) -> Verdict {
    let exact = match e {
        Expect::RecMax { from_s, to_s, .. } | Expect::TecMax { from_s, to_s, .. } => {
            let (from, to) = window(*from_s, *to_s);
            t.counters_exact(from, to)
        }
        _ => t.states_exact(),
    };
    if exact {
        verdict(e, true, at, observed)
    } else {
        verdict(
            e,
            false,
            at,
            format!(
                "cannot tell: {node}'s history merged its {} spans there; {observed} among them",
                t.len()
            ),
        )
    }
}

/// `n` and a noun that takes an `s` for more than one: `1 error frame`, `3 error frames`.
fn n_of(n: u64, noun: &str) -> String {
    bus::text::count(n, noun, &format!("{noun}s"))
}
