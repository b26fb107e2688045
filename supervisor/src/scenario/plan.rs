//! The resolved scenario: what a run carries out, in the order it falls due, with every name,
//! frame and number already checked and turned into what the bus and the nodes take; and the
//! expectations with their nodes' ids.
//!
//! Contract: a [`Plan`] comes from the validation (`validate::resolve` for a scenario,
//! `validate::action` for one action), which refuses what it cannot resolve; the run carries out
//! what it is given, checking no more of the input, only the running harvester's state (a node
//! that is down).

use super::model::Expect;
use bus::Frame;
use bus::engine::{NodeId, Rule};
use bus::node::NodeFault;
use bus::time::BusTime;

/// One timeline action, resolved.
#[derive(Clone, Debug)]
pub enum Act {
    /// Install a fault rule (bit errors, overload frames), with its nodes' ids.
    Rule(Rule),
    /// A node acknowledges frames, or stops.
    Ack(NodeId, bool),
    /// A node is connected to the bus, or not.
    Connect(NodeId, bool),
    /// A node hangs, or runs again.
    Hang(NodeId, bool),
    /// A node's logic crashes (by the node's name, as the supervision keeps it).
    Crash(String),
    /// A babbling idiot floods the bus with this frame.
    Babble(Frame),
    /// A node sends a frame.
    Send(NodeId, Frame),
    /// A fault handed to a node's logic.
    Inject {
        /// The node.
        node: String,
        /// The fault.
        fault: NodeFault,
    },
    /// A plant input set.
    Plant {
        /// The input.
        input: String,
        /// Its value, in its range.
        value: f64,
    },
    /// The machine switched off and on.
    PowerCycle,
}

/// What falls due on the timeline.
#[derive(Clone, Debug)]
pub enum Todo {
    /// Step `index`'s action, with its name ([`super::Action::name`]).
    Act {
        /// The step.
        index: usize,
        /// The action's name.
        name: &'static str,
        /// What to do.
        act: Act,
    },
    /// The end of step `index`'s fault rule.
    EndRule(usize),
    /// The end of a babbling idiot's flood.
    EndBabble,
}

/// An expectation, with the node it names (if it names one) resolved to its id on the bus.
#[derive(Clone, Debug)]
pub struct Check {
    /// The expectation, as written.
    pub expect: Expect,
    /// The id of the node it names.
    pub node: Option<NodeId>,
}

/// A resolved scenario: its timeline and its expectations.
#[derive(Clone, Debug)]
pub struct Plan {
    /// What falls due and when, by time, then by step (a step's start before its end).
    pub todo: Vec<(BusTime, Todo)>,
    /// The expectations, in the scenario's order.
    pub checks: Vec<Check>,
}

/// A resolved step, before it is put in order.
pub(crate) struct Resolved {
    pub index: usize,
    pub at: BusTime,
    pub name: &'static str,
    pub act: Act,
    /// When its fault ends, if it has an end.
    pub ends: Option<(BusTime, Todo)>,
}

impl Plan {
    /// The steps in the order they fall due, and the checks.
    pub(crate) fn new(steps: Vec<Resolved>, checks: Vec<Check>) -> Plan {
        let mut todo = Vec::new();
        for s in steps {
            todo.push((
                s.at,
                s.index,
                Todo::Act {
                    index: s.index,
                    name: s.name,
                    act: s.act,
                },
            ));
            if let Some((t, end)) = s.ends {
                todo.push((t, s.index, end));
            }
        }
        // Stable: one step's entries at the same time keep their order, its start before its end.
        todo.sort_by_key(|(t, i, _)| (*t, *i));
        Plan {
            todo: todo.into_iter().map(|(t, _, what)| (t, what)).collect(),
            checks,
        }
    }
}
