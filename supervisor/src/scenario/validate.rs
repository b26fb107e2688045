//! Validation of a scenario against its harvester, before anything runs.
//!
//! Contract: [`validate`] lists every problem it finds, each named by file and field: nodes the
//! harvester does not have, times outside the run, values the harvester or the plant would
//! refuse, sensor faults on the monitor (which has none), and expectations whose numbers mean
//! they could never fail or never pass. It starts nothing; a scenario it passes can still be
//! stopped while it runs, by a fault a node's logic refuses.

mod expect;
mod timeline;

use super::model::{Hits, Scenario, Target};
use super::{junit, random};
use crate::harvester::Harvester;
use bus::text::{LIST_CHARS, cut, quote};
use nodes::Problem;
use nodes::plant::Plant;

/// The longest scenario or soak, s: 30 days of virtual time, about two days of wall time at the
/// emulator's pace, and far beyond any soak run so far; longer is a typing error.
pub const MAX_DURATION_S: f64 = 30.0 * 24.0 * 3600.0;

/// Overload frames a receiver may send in a row: the CAN 2.0 specification allows at most two to
/// delay the next data or remote frame.
pub const MAX_OVERLOAD_FRAMES: u8 = 2;

/// Checks names, times and values of a scenario against its harvester.
pub fn validate(file: &str, s: &Scenario, h: &Harvester) -> Vec<Problem> {
    let mut c = Checks {
        file,
        names: h.node_names(),
        duration_s: s.duration_s,
        signals: Plant::signal_names(),
        found: Vec::new(),
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
        for (field, message) in random::problems(r, s.duration_s, &c.names) {
            c.push(field, message);
        }
    }
    if !(s.duration_s.is_finite() && s.duration_s > 0.0) {
        c.push("duration_s", "must be a positive number of seconds");
    } else if s.duration_s > MAX_DURATION_S {
        c.push(
            "duration_s",
            format!(
                "{} s is longer than the longest run, {MAX_DURATION_S} s (30 days of virtual time)",
                s.duration_s
            ),
        );
    }
    if s.expect.is_empty() {
        c.push("expect", "a scenario needs at least one expectation");
    }
    for (i, step) in s.timeline.iter().enumerate() {
        timeline::step(&mut c, &format!("timeline[{i}]"), step);
    }
    for (i, e) in s.expect.iter().enumerate() {
        expect::expectation(&mut c, &format!("expect[{i}]"), e, h);
    }
    c.found
}

/// The problems found so far, and what the checks of single fields need to know.
struct Checks<'a> {
    file: &'a str,
    /// The harvester's nodes.
    names: Vec<String>,
    /// The run's length, s.
    duration_s: f64,
    /// The plant's signals.
    signals: Vec<String>,
    found: Vec<Problem>,
}

impl Checks<'_> {
    fn push(&mut self, field: impl Into<String>, message: impl Into<String>) {
        self.found.push(Problem::at(self.file, field, message));
    }

    /// A node of the harvester.
    fn node(&mut self, field: String, n: &str) {
        if !self.names.iter().any(|x| x == n) {
            let message = format!(
                "unknown node {} (nodes: {})",
                quote(n),
                cut(&self.names.join(", "), LIST_CHARS)
            );
            self.push(field, message);
        }
    }

    /// A signal of the plant.
    fn signal(&mut self, field: String, signal: &str) {
        if !self.signals.iter().any(|s| s == signal) {
            self.push(field, format!("unknown plant signal {}", quote(signal)));
        }
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

    /// Which frames a fault selects.
    fn frames(&mut self, at: &str, target: &Target, hits: &Hits) {
        match target {
            Target::Node(n) => self.node(format!("{at}.action.target"), n),
            Target::Id(id)
                if id.len() != 8 || u32::from_str_radix(id, 16).map_or(true, |v| v > 0x1FFF_FFFF) =>
            {
                self.push(
                    format!("{at}.action.target"),
                    format!("{} is not an 8-digit 29-bit identifier", quote(id)),
                )
            }
            Target::Priority(pr) if *pr > 31 => {
                self.push(format!("{at}.action.target"), format!("priority {pr} is over 31"))
            }
            _ => {}
        }
        match hits {
            Hits::EveryNth(0) => self.push(format!("{at}.action.hits"), "EveryNth(0)"),
            Hits::BitErrorRate(r) if !(0.0..=1.0).contains(r) => self.push(
                format!("{at}.action.hits"),
                format!("bit-error rate {r} is outside 0..1"),
            ),
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests;
