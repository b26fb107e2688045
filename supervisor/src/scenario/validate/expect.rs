//! The checks of one expectation: its node, window and bounds, and that it can both pass and
//! fail on this harvester.

use super::Checks;
use crate::harvester::Harvester;
use crate::scenario::model::Expect;
use bus::engine::NodeId;
use bus::text::quote;

/// Bits a bus-off node must see recessive before it is error active again (128 sequences of 11):
/// no node can go bus off more often than once per this many bit times.
const RECOVERY_BITS: u64 = bus::fault::RECOVERY_SEQUENCES as u64 * bus::fault::RECOVERY_SEQUENCE_BITS as u64;

/// TEC stops counting at bus off, at most one penalty (8) past the limit: no TEC is ever higher.
const TEC_CEILING: u16 = bus::fault::BUS_OFF_LIMIT + 7;

/// Checks expectation `at` (its field path, `expect[i]`) of a run on `h`; the id of the node it
/// names, if it names one that is there.
pub(super) fn expectation(c: &mut Checks, at: &str, e: &Expect, h: &Harvester) -> Option<NodeId> {
    let mut id = None;
    match e {
        Expect::AlarmRaised { node, after_s, .. } | Expect::AlarmCleared { node, after_s, .. } => {
            id = c.node(format!("{at}.node"), node);
            c.time(format!("{at}.after_s"), *after_s);
        }
        Expect::NodeState { node, after_s, .. } => {
            id = c.node(format!("{at}.node"), node);
            c.time(format!("{at}.after_s"), *after_s);
        }
        Expect::NodeStateNever {
            node, from_s, to_s, ..
        }
        | Expect::NodeStateHolds {
            node, from_s, to_s, ..
        } => {
            id = c.node(format!("{at}.node"), node);
            c.window(at, *from_s, *to_s);
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
            id = c.node(format!("{at}.node"), node);
            c.window(at, *from_s, *to_s);
            let (name, ceiling) = if matches!(e, Expect::RecMax { .. }) {
                ("REC", bus::fault::REC_MAX)
            } else {
                ("TEC", TEC_CEILING)
            };
            if *max >= ceiling {
                c.push(
                    format!("{at}.max"),
                    format!("{name} never exceeds {ceiling}: a maximum of {max} cannot fail"),
                );
            }
        }
        Expect::Counters {
            node, at_s, tec, rec, ..
        } => {
            id = c.node(format!("{at}.node"), node);
            c.time(format!("{at}.at_s"), *at_s);
            for (name, value, ceiling) in [("tec", *tec, TEC_CEILING), ("rec", *rec, bus::fault::REC_MAX)] {
                if value > ceiling {
                    c.push(
                        format!("{at}.{name}"),
                        format!(
                            "{} never exceeds {ceiling}: {value} cannot be",
                            name.to_uppercase()
                        ),
                    );
                }
            }
        }
        Expect::ErrorKinds {
            node,
            min,
            max,
            from_s,
            to_s,
            ..
        } => {
            id = c.node(format!("{at}.node"), node);
            match to_s {
                Some(to) => c.window(at, *from_s, *to),
                None => c.time(format!("{at}.from_s"), *from_s),
            }
            if min > max {
                c.push(format!("{at}.min"), format!("min {min} is above max {max}"));
            }
        }
        Expect::BusOffCount { node, min, max } => {
            id = c.node(format!("{at}.node"), node);
            if min > max {
                c.push(format!("{at}.min"), format!("min {min} is above max {max}"));
            }
            bus_offs_fit(c, at, *min, h.config.network.bitrate);
        }
        Expect::BusOffLongest { node, max_ms } => {
            id = c.node(format!("{at}.node"), node);
            if !(max_ms.is_finite() && *max_ms > 0.0) {
                c.push(
                    format!("{at}.max_ms"),
                    format!("{max_ms}: a duration is a positive number of ms"),
                );
            }
        }
        Expect::Restarts { node, .. } => {
            id = c.node(format!("{at}.node"), node);
        }
        Expect::Display { field, min, max } => {
            let fields = serde_json::to_value(nodes::monitor::Display::default()).unwrap_or_default();
            if fields.get(field).is_none() {
                c.push(
                    format!("{at}.field"),
                    format!("the display has no field {}", quote(field)),
                );
            }
            bounds(c, at, *min, *max);
        }
        Expect::Plant { signal, min, max } => {
            c.signal(format!("{at}.signal"), signal);
            bounds(c, at, *min, *max);
        }
        Expect::ErrorFrames { min, max } | Expect::OverloadFrames { min, max } if min > max => {
            c.push(format!("{at}.min"), format!("min {min} is above max {max}"))
        }
        Expect::BusLoadBelow(limit) if !(*limit > 0.0 && *limit <= 100.0) => c.push(
            at,
            format!("a load limit of {limit} % is outside (0, 100]: it would always pass or never"),
        ),
        Expect::YieldWithin(percent) if !(*percent >= 0.0 && *percent <= 100.0) => {
            c.push(at, format!("{percent} % is not a tolerance in 0..=100"))
        }
        _ => {}
    }
    let needs_monitor = matches!(
        e,
        Expect::AlarmRaised { .. }
            | Expect::AlarmCleared { .. }
            | Expect::NoAlarms
            | Expect::YieldWithin(_)
            | Expect::Display { .. }
            | Expect::FramesAccounted
    );
    if needs_monitor && !h.config.monitor.enabled {
        c.push(at, "needs the emulated monitor, which the config switches off");
    }
    id
}

/// Bounds of a value: numbers, the lower not above the upper.
fn bounds(c: &mut Checks, at: &str, min: f64, max: f64) {
    for (name, v) in [("min", min), ("max", max)] {
        if !v.is_finite() {
            c.push(format!("{at}.{name}"), format!("{v} is not a number"));
        }
    }
    if min > max {
        c.push(format!("{at}.min"), format!("min {min} is above max {max}"));
    }
}

/// At least `min` bus-offs fit in the run: each but the last is followed by a recovery of
/// [`RECOVERY_BITS`].
fn bus_offs_fit(c: &mut Checks, at: &str, min: u32, bitrate: u32) {
    if c.duration_s.is_finite() && bitrate > 0 {
        let bits = c.duration_s * f64::from(bitrate);
        let most = (bits / RECOVERY_BITS as f64).floor() + 1.0;
        if f64::from(min) > most {
            let message = format!(
                "{min} bus-offs cannot fit in {} s: each recovery takes \
                 {RECOVERY_BITS} bit times, at most {most} in the run",
                c.duration_s
            );
            c.push(format!("{at}.min"), message);
        }
    }
}
