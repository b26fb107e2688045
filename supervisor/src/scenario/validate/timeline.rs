//! The checks of one timeline step: the nodes, frames, times and values its action names.

use super::{Checks, MAX_OVERLOAD_FRAMES};
use crate::scenario::model::{Action, ErrorKind, SeenBy, Step};
use bus::candump::parse_frame;
use bus::text::quote;
use nodes::plant::Plant;

/// Checks step `at` (its field path, `timeline[i]`).
pub(super) fn step(c: &mut Checks, at: &str, step: &Step) {
    c.time(format!("{at}.at_s"), step.at_s);
    if let Action::SensorFault { fault, .. } = &step.action
        && let Some(m) = fault.problem()
    {
        c.push(format!("{at}.action.fault"), m);
    }
    match &step.action {
        Action::BitErrors {
            target,
            hits,
            until_s,
            kind,
            seen_by,
        } => {
            c.frames(at, target, hits);
            if let Some(u) = until_s {
                c.end(format!("{at}.action.until_s"), step.at_s, *u);
            }
            if let SeenBy::Nodes(nodes) = seen_by {
                if nodes.is_empty() {
                    c.push(
                        format!("{at}.action.seen_by"),
                        "Nodes([]): name at least one node, or leave seen_by out for All",
                    );
                }
                for (k, n) in nodes.iter().enumerate() {
                    c.node(format!("{at}.action.seen_by[{k}]"), n);
                }
                if *kind == ErrorKind::Bit {
                    c.push(
                        format!("{at}.action.seen_by"),
                        "a bit error is a bit flipped on the wire, which every node sees: \
                         seen_by: Nodes(..) needs kind Stuff, Crc or Form",
                    );
                }
            }
        }
        Action::Overload {
            target,
            hits,
            until_s,
            by,
            frames,
        } => {
            c.frames(at, target, hits);
            if let Some(u) = until_s {
                c.end(format!("{at}.action.until_s"), step.at_s, *u);
            }
            for (k, n) in by.iter().enumerate() {
                c.node(format!("{at}.action.by[{k}]"), n);
            }
            if !(1..=MAX_OVERLOAD_FRAMES).contains(frames) {
                c.push(
                    format!("{at}.action.frames"),
                    format!(
                        "{frames} overload frames in a row: a receiver may send 1 or \
                         {MAX_OVERLOAD_FRAMES} (CAN 2.0, overload frame)"
                    ),
                );
            }
        }
        Action::AckFailure(n)
        | Action::AckRestored(n)
        | Action::Disconnect(n)
        | Action::Reconnect(n)
        | Action::Crash(n)
        | Action::Hang(n)
        | Action::Resume(n) => c.node(format!("{at}.action"), n),
        Action::Babble { frame, until_s } => {
            if let Err(e) = parse_frame(frame) {
                c.push(format!("{at}.action.frame"), e.to_string());
            }
            c.end(format!("{at}.action.until_s"), step.at_s, *until_s);
        }
        Action::SendFrame { node, frame } => {
            c.node(format!("{at}.action.node"), node);
            if let Err(e) = parse_frame(frame) {
                c.push(format!("{at}.action.frame"), e.to_string());
            }
        }
        Action::SensorFault { node, signal, .. } | Action::SensorRepaired { node, signal } => {
            c.node(format!("{at}.action.node"), node);
            if node == "F5" {
                c.push(format!("{at}.action.node"), "the monitor has no sensors");
            }
            c.signal(format!("{at}.action.signal"), signal);
        }
        Action::Plant { input, value } => match Plant::input_range(input) {
            None => c.push(
                format!("{at}.action.input"),
                format!("{} is not a plant input", quote(input)),
            ),
            // The plant refuses it when the step runs, which would end the run there.
            Some(range) if !range.contains(*value) => c.push(
                format!("{at}.action.value"),
                format!("{value} is not {range}, the range of plant input {input}"),
            ),
            Some(_) => {}
        },
        Action::PowerCycle => {}
    }
}
