//! Validation of a scenario against its harvester, before anything runs, and the resolution of
//! its timeline into what the run carries out.
//!
//! Contract: [`resolve`] lists every problem it finds, each named by file and field: nodes the
//! harvester does not have, times outside the run, values the harvester or the plant would
//! refuse, sensor faults on the monitor (which has none), and expectations whose numbers mean
//! they could never fail or never pass; with none, it gives the timeline resolved ([`Plan`]):
//! the one interpretation of every step, which the run carries out without checking again. It
//! starts nothing; a scenario it passes can still be stopped while it runs, by a fault a node's
//! logic refuses. [`action`] resolves one action the same way, against a running harvester's
//! nodes (the Python session's `act`).

mod expect;
mod timeline;

use super::model::{Expect, Scenario, Step};
use super::plan::{Check, Plan, Resolved};
use super::{junit, random};
use crate::harvester::Harvester;
use bus::engine::NodeId;
use bus::text::{LIST_CHARS, cut, quote};
use nodes::Problem;
use nodes::plant::Plant;

/// The longest scenario or soak, s: 30 days of virtual time, about two days of wall time at the
/// emulator's pace, and far beyond any soak run so far; longer is a typing error.
pub const MAX_DURATION_S: f64 = 30.0 * 24.0 * 3600.0;

/// Overload frames a receiver may send in a row: the CAN 2.0 specification allows at most two to
/// delay the next data or remote frame.
pub const MAX_OVERLOAD_FRAMES: u8 = 2;

/// What is wrong with a run's length of `duration_s`, if anything.
pub(super) fn duration_problem(duration_s: f64) -> Option<String> {
    if !(duration_s.is_finite() && duration_s > 0.0) {
        Some("must be a positive number of seconds".into())
    } else if duration_s > MAX_DURATION_S {
        Some(format!(
            "{duration_s} s is longer than the longest run, {MAX_DURATION_S} s (30 days of virtual time)"
        ))
    } else {
        None
    }
}

/// Checks names, times and values of a scenario against its harvester: every problem, none when
/// it is good.
pub fn validate(file: &str, s: &Scenario, h: &Harvester) -> Vec<Problem> {
    resolve(file, s, h).err().unwrap_or_default()
}

/// Checks a scenario against its harvester and resolves its timeline, with the node ids the
/// harvester's nodes take on its bus ([`Harvester::node_ids`]); or every problem.
pub fn resolve(file: &str, s: &Scenario, h: &Harvester) -> Result<Plan, Vec<Problem>> {
    let mut c = Checks {
        file,
        nodes: h.node_ids(),
        duration_s: s.duration_s,
        signals: Plant::signal_names(),
        found: Vec::new(),
        sent: sent_frames(s, h),
    };
    // Both reach JUnit XML and the HTML report, which cannot carry control characters.
    for (field, text) in [("name", &s.name), ("description", &s.description)] {
        if let Some(ch) = text.chars().find(|&ch| !junit::xml_char(ch)) {
            c.push(
                field,
                format!(
                    "holds the character U+{:04X}, which JUnit XML and the HTML report cannot carry (control characters other than tab and line breaks are refused)",
                    u32::from(ch)
                ),
            );
        }
    }
    if let Some(r) = &s.random_faults {
        let names: Vec<String> = c.nodes.iter().map(|(n, _)| n.clone()).collect();
        for (field, message) in random::problems(r, s.duration_s, &names) {
            c.push(field, message);
        }
    }
    if let Some(problem) = duration_problem(s.duration_s) {
        c.push("duration_s", problem);
    }
    if s.expect.is_empty() {
        c.push("expect", "a scenario needs at least one expectation");
    }
    let steps: Vec<Resolved> = s
        .timeline
        .iter()
        .enumerate()
        .filter_map(|(i, step)| timeline::step(&mut c, &format!("timeline[{i}]"), i, step))
        .collect();
    let checks: Vec<Check> = s
        .expect
        .iter()
        .enumerate()
        .map(|(i, e)| Check {
            expect: e.clone(),
            node: expect::expectation(&mut c, &format!("expect[{i}]"), e, h),
        })
        .collect();
    if c.found.is_empty() {
        Ok(Plan::new(steps, checks))
    } else {
        Err(c.found)
    }
}

/// Resolves step `index` of a harvester already running, whose nodes are `nodes` (names and
/// ids on its bus) and which has reached `now_s`; `file` names where the step came from. The
/// same checks as a scenario's step, in a run without end.
pub fn action(
    file: &str,
    nodes: Vec<(String, NodeId)>,
    index: usize,
    step: &Step,
) -> Result<Plan, Vec<Problem>> {
    let mut c = Checks::running(file, nodes);
    let resolved = timeline::step(&mut c, "action", index, step);
    match resolved {
        Some(r) if c.found.is_empty() => Ok(Plan::new(vec![r], Vec::new())),
        _ => Err(c.found),
    }
}

/// Resolves expectations against a harvester already running (`h`, whose nodes are `nodes`,
/// names and ids on its bus), as a scenario's are; `file` names where they came from. Those that
/// need the trace counted from the start (`ErrorKinds`, `TraceComplete`) are refused: a running
/// harvester did not count it.
pub fn expectations(
    file: &str,
    h: &Harvester,
    nodes: Vec<(String, NodeId)>,
    expect: &[Expect],
) -> Result<Vec<Check>, Vec<Problem>> {
    let mut c = Checks::running(file, nodes);
    let checks: Vec<Check> = expect
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let at = format!("expect[{i}]");
            if matches!(e, Expect::ErrorKinds { .. } | Expect::TraceComplete) {
                c.push(
                    &at,
                    "counts the trace from the start of the run, which a running harvester did not \
                     count: check it in a scenario (ErrorFrames and the state expectations tell \
                     errors apart here)",
                );
            }
            Check {
                expect: e.clone(),
                node: expect::expectation(&mut c, &at, e, h),
            }
        })
        .collect();
    if expect.is_empty() {
        c.push("expect", "no expectation to check");
    }
    if c.found.is_empty() {
        Ok(checks)
    } else {
        Err(c.found)
    }
}

/// The problems found so far, and what the checks of single fields need to know.
struct Checks<'a> {
    file: &'a str,
    /// The harvester's nodes, with their ids on its bus.
    nodes: Vec<(String, NodeId)>,
    /// The run's length, s.
    duration_s: f64,
    /// The plant's signals.
    signals: Vec<String>,
    found: Vec<Problem>,
    /// The frames of the nodes whose frames are all known (scripted nodes: their messages, with
    /// the timeline's `SendFrame`s of them), in the shape that tells their fields apart.
    sent: Vec<(String, Vec<bus::Frame>)>,
}

/// The frames each scripted node sends: a frame of each catalogue message its script sends (an
/// extended data frame of the message's length), and the timeline's `SendFrame`s of it. Nodes
/// whose frames cannot be known (firmware, the monitor) are not listed.
fn sent_frames(s: &Scenario, h: &Harvester) -> Vec<(String, Vec<bus::Frame>)> {
    h.scripts
        .iter()
        .map(|script| {
            let mut frames: Vec<bus::Frame> = script
                .messages
                .iter()
                .flat_map(|m| &m.frames)
                .filter_map(|f| protocol::catalogue::by_name(&f.message))
                .filter_map(|m| bus::Frame::extended(0, &vec![0; usize::from(m.dlc.min(8))]).ok())
                .collect();
            for step in &s.timeline {
                if let super::model::Action::SendFrame { node, frame } = &step.action
                    && node == &script.name
                    && let Ok(f) = bus::candump::parse_frame(frame)
                {
                    frames.push(f);
                }
            }
            (script.name.clone(), frames)
        })
        .collect()
}

impl<'a> Checks<'a> {
    /// The checks for a harvester already running, whose nodes are `nodes`: a run without end,
    /// whose frames are not known ahead.
    fn running(file: &'a str, nodes: Vec<(String, NodeId)>) -> Checks<'a> {
        Checks {
            file,
            nodes,
            duration_s: f64::INFINITY,
            signals: Plant::signal_names(),
            found: Vec::new(),
            sent: Vec::new(),
        }
    }

    fn push(&mut self, field: impl Into<String>, message: impl Into<String>) {
        self.found.push(Problem::at(self.file, field, message));
    }

    /// A node of the harvester, and its id.
    fn node(&mut self, field: String, n: &str) -> Option<NodeId> {
        let found = self.nodes.iter().find(|(x, _)| x == n).map(|(_, id)| *id);
        if found.is_none() {
            let names: Vec<&str> = self.nodes.iter().map(|(x, _)| x.as_str()).collect();
            let message = format!(
                "unknown node {} (nodes: {})",
                quote(n),
                cut(&names.join(", "), LIST_CHARS)
            );
            self.push(field, message);
        }
        found
    }

    /// The frames `node` sends, when they are all known.
    fn frames_of(&self, node: &str) -> Option<Vec<bus::Frame>> {
        self.sent.iter().find(|(n, _)| n == node).map(|(_, f)| f.clone())
    }

    /// A signal of the plant: true when it is one.
    fn signal(&mut self, field: String, signal: &str) -> bool {
        let known = self.signals.iter().any(|s| s == signal);
        if !known {
            self.push(field, format!("unknown plant signal {}", quote(signal)));
        }
        known
    }

    /// A time in the run.
    fn time(&mut self, field: String, t: f64) {
        if !(t.is_finite() && t >= 0.0) {
            self.push(field, format!("time {t} s is negative or not a number"));
        } else if t > self.duration_s {
            let message = format!("time {t} s is after the end of the run ({} s)", self.duration_s);
            self.push(field, message);
        }
    }

    /// The end of a fault: a time in the run, after its start.
    fn end(&mut self, field: String, start: f64, end: f64) {
        self.time(field.clone(), end);
        if end.is_finite() && start.is_finite() && end <= start {
            self.push(
                field,
                format!("the fault ends at {end} s, not after it starts ({start} s)"),
            );
        }
    }

    /// A window of an expectation: two times in the run, the first before the second.
    fn window(&mut self, at: &str, from: f64, to: f64) {
        self.time(format!("{at}.from_s"), from);
        self.time(format!("{at}.to_s"), to);
        if from.is_finite() && to.is_finite() && from >= to {
            self.push(
                format!("{at}.to_s"),
                format!("the window {from} s to {to} s is empty: to_s must be after from_s"),
            );
        }
    }
}

#[cfg(test)]
mod tests;
