//! One controller's place in the scheduler: its node's deadline, its pending inputs, what it
//! buffers, and how its node is doing.

use super::commands::Switches;
use crate::engine::Received;
use crate::node::{ControllerEvent, CrashCause, Unheeded};
use crate::time::{BusDuration, BusTime};

pub(super) struct Slot {
    pub name: String,
    /// The node has a logic to wake (a gateway that only submits has none).
    pub logic: bool,
    /// The slot of the node's first controller: its own, but for a further controller of a
    /// node with several. The node's deadline is kept there.
    pub first: usize,
    /// Which of the node's controllers this is.
    pub controller: usize,
    pub reaction: BusDuration,
    pub next_timeout: Option<BusTime>,
    pub pending_since: Option<BusTime>,
    pub events: Vec<(BusTime, ControllerEvent)>,
    /// An input that needs the logic itself (an error-state change, an overrun) is pending.
    pub event_wake: bool,
    /// The logic said its frames can wait for its next deadline ([`crate::node::Report::frames_can_wait`]).
    pub frames_can_wait: bool,
    /// Frames taken from the FIFO at the reaction time, for the next wake.
    pub buffered: Vec<Received>,
    /// What became of the frames taken from the FIFO (plain counters: no cost per frame).
    pub handover: Handover,
    pub hung: bool,
    pub crashed: Option<CrashCause>,
    /// The logic hears of every controller event as it happens ([`crate::node::Report::every_event`]).
    pub every_event: bool,
    /// What its logic set on its controller (register-level nodes).
    pub switches: Switches,
    /// The frames its logic said at its last answer it takes no notice of
    /// ([`crate::node::Report::unheeded`]): they leave the FIFO at their wake without one.
    pub unheeded: Option<Unheeded>,
}

impl Slot {
    pub fn new(name: String, logic: bool, first: usize, controller: usize, reaction: BusDuration) -> Slot {
        Slot {
            name,
            logic,
            first,
            controller,
            reaction,
            next_timeout: None,
            pending_since: None,
            events: Vec::new(),
            event_wake: false,
            frames_can_wait: false,
            buffered: Vec::new(),
            handover: Handover::default(),
            hung: false,
            crashed: None,
            every_event: false,
            switches: Switches::default(),
            unheeded: None,
        }
    }

    /// When the slot's node is next to be woken for it: its deadline, or a reaction time after
    /// its first pending input; never while it is hung, crashed or without a logic.
    pub fn due(&self) -> Option<BusTime> {
        if self.hung || self.crashed.is_some() || !self.logic {
            return None;
        }
        let reaction = self.pending_since.map(|t| t + self.reaction);
        match (self.next_timeout, reaction) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// An input at `at`: an event for the logic, if any, and whether it wakes the node. A node
    /// without a logic (a replay, a gateway client, a bridge) keeps no events: nobody would
    /// read them, and its confirmations would pile up for as long as it sends.
    pub fn input(&mut self, at: BusTime, event: Option<ControllerEvent>, wakes: bool) {
        if let Some(e) = event
            && self.logic
        {
            self.events.push((at, e));
        }
        if wakes && self.pending_since.is_none() {
            self.pending_since = Some(at);
        }
        self.event_wake |= wakes && event.is_some();
    }

    /// Forgets what the old logic left unread (a new logic starts with an empty FIFO too).
    pub fn clear(&mut self) {
        self.events.clear();
        self.handover.dropped_at_replace += self.buffered.len() as u64;
        self.buffered.clear();
        self.event_wake = false;
        self.frames_can_wait = false;
        self.pending_since = None;
        self.unheeded = None;
    }
}

/// What became of the frames the scheduler took out of one node's receive FIFO. Every frame
/// taken (the controller's `rx_read`) is in exactly one of these:
/// `rx_read = handled + crashed + dropped_at_replace + held + in_flight`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Handover {
    /// Handed to the logic's `handle_frame`.
    pub handled: u64,
    /// In wakes whose logic crashed (or whose actor was gone) before handling them.
    pub crashed: u64,
    /// Held for the logic's next deadline, and dropped when a new logic took over (restart,
    /// power cycle).
    pub dropped_at_replace: u64,
    /// Held for the logic's next deadline now.
    pub held: u64,
    /// In a wake not answered yet (none while the scheduler is paused).
    pub in_flight: u64,
}
