//! The engine's events on their way out: to the trace (in time order), to observers, and to the
//! nodes' pending inputs; and the wakes those inputs make.

use super::{Heard, Inputs, Notice, Observed, ObservedError, Scheduler, Wake, kept};
use crate::engine::{Event, NodeId};
use crate::node::ControllerEvent;
use crate::time::BusTime;
use crate::trace::{Kind, Record, Source};

impl Scheduler {
    /// Routes the engine's events to traces, observers and the nodes' pending inputs. Returns
    /// the earliest due time among the nodes that got inputs.
    pub(super) fn dispatch(&mut self) -> Option<BusTime> {
        let mut due: Option<BusTime> = None;
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.extend(self.bus.take_events());
        for event in scratch.drain(..) {
            if !self.sinks.is_empty() {
                self.record_event(&event);
            }
            if let Event::Frame { end, node, frame, .. } = event
                && !self.observers.is_empty()
            {
                let seen = Observed { at: end, node, frame };
                self.observers.retain_mut(|o| o(&seen));
            }
            if !self.error_observers.is_empty() {
                self.tell_error(&event);
            }
            if self.register_level > 0
                && let Some(d) = self.counters_of(&event)
            {
                due = Some(due.map_or(d, |x| x.min(d)));
            }
            // No register-level node (the usual case): no slot lookup on the per-frame path.
            let every = |n: NodeId| {
                self.register_level > 0 && self.slots.get(n.index()).is_some_and(|s| s.every_event)
            };
            let (node, at, input, wakes) = match event {
                Event::Delivered { node, at } => (node, at, None, true),
                Event::Overrun { node, at } => (node, at, Some(ControllerEvent::Overrun), true),
                Event::Woken { node, at } => (node, at, Some(ControllerEvent::Woken), true),
                Event::State { node, at, to, .. } => (node, at, Some(ControllerEvent::State(to)), true),
                Event::TxDone { node, at, frame, .. } => {
                    (node, at, Some(ControllerEvent::Sent(frame)), every(node))
                }
                Event::TxAborted { node, at, frame, .. } => {
                    (node, at, Some(ControllerEvent::Aborted(frame)), every(node))
                }
                Event::BusError {
                    node,
                    at,
                    error,
                    transmitting,
                    location,
                    ..
                } if every(node) => {
                    let e = ControllerEvent::BusError {
                        error,
                        transmitting,
                        location,
                    };
                    (node, at, Some(e), true)
                }
                Event::ArbitrationLost { node, at, bit } if every(node) => {
                    (node, at, Some(ControllerEvent::ArbitrationLost(bit)), true)
                }
                Event::RecoveryProgress { node, at, sequences } if every(node) => {
                    (node, at, Some(ControllerEvent::RecoveryProgress(sequences)), true)
                }
                _ => continue,
            };
            if let Some(slot) = self.slots.get_mut(node.index()) {
                let before = slot.due();
                slot.input(at, input, wakes);
                let after = slot.due();
                // Unchanged (a node already waiting for an input), its due time stands.
                if let Some(d) = after {
                    if after != before {
                        self.dues[node.index()] = d;
                    }
                    due = Some(due.map_or(d, |x| x.min(d)));
                }
            }
        }
        self.scratch = scratch;
        self.hand_over(false);
        due
    }

    /// Tells the error observers of an event's error frame, if it raises one.
    #[inline(never)]
    fn tell_error(&mut self, event: &Event) {
        let Some(Record {
            at,
            source: Source::Controller { node, .. },
            kind: Kind::Error(frame),
            ..
        }) = Record::of_event(&self.iface, |_| "", event)
        else {
            return;
        };
        let name = self
            .bus
            .controllers()
            .get(node.index())
            .map_or_else(|| "?".to_string(), |c| c.config().name.clone());
        let seen = ObservedError {
            at,
            node,
            name,
            frame,
        };
        let mut stop = false;
        self.error_observers.retain_mut(|o| match o(&seen) {
            Heard::Gone => false,
            Heard::Noted => true,
            Heard::StopThere => {
                stop = true;
                true
            }
        });
        // Only a run in progress stops; never before the present.
        if stop && let Some(s) = self.stop_at {
            self.stop_at = Some(s.min(at.max(self.now)));
        }
    }

    /// Puts an event's record into the reorder window; names are looked up as records go out
    /// (`hand_over`). Out of line: a run without a trace does not carry the code in its path.
    #[inline(never)]
    fn record_event(&mut self, event: &Event) {
        let Some(record) = Record::of_event(&self.iface, |_| "", event) else {
            return;
        };
        let node = match record.source {
            Source::Bus => None,
            Source::Controller { node, .. } => Some(node),
        };
        if let Err(e) = self.order.push(record.at, (node, record.kind)) {
            if self.order_error.is_none() {
                self.notices.push_back(Notice::TraceOrder(e.clone()));
            }
            self.order_error.get_or_insert(e);
        }
    }

    /// Hands the trace's records that are due to the sinks, in time order: those a reorder
    /// window older than the newest, or every one when `all` (the end of the trace).
    pub(super) fn hand_over(&mut self, all: bool) {
        if self.sinks.is_empty() {
            return;
        }
        let controllers = self.bus.controllers();
        let name = |n: NodeId| {
            controllers
                .get(n.index())
                .map_or("?", |c| c.config().name.as_str())
        };
        loop {
            let next = if all {
                self.order.pop_any()
            } else {
                self.order.pop()
            };
            let Some((at, (node, kind))) = next else {
                return;
            };
            let source = match node {
                None => Source::Bus,
                Some(node) => Source::Controller {
                    node,
                    name: name(node),
                },
            };
            let record = Record {
                at,
                bus: &self.iface,
                source,
                kind,
            };
            let error = &mut self.trace_error;
            self.sinks.retain_mut(|s| kept(s.record(&record), error));
        }
    }

    /// Wakes every node due at `at`, once each with the inputs of its controllers that are due;
    /// the bus waits until all of them have answered. Returns false when no node needed its
    /// logic woken (frames that can wait were only taken from their FIFOs): the bus goes on at
    /// once.
    pub(super) fn wake(&mut self, at: BusTime) -> bool {
        self.now = at;
        self.round += 1;
        self.crashed_in_round = false;
        self.stop_in_round = false;
        // The slots due by `at` as last set (the earliest due time: none is earlier), in slot
        // order; those a later change made stale are read again below.
        let mut due_now = std::mem::take(&mut self.due_now);
        due_now.extend((self.dues.iter().enumerate()).filter_map(|(i, &t)| (t <= at).then_some(i)));
        debug_assert_eq!(
            due_now
                .iter()
                .copied()
                .filter(|&i| self.slots[i].due() == Some(at))
                .collect::<Vec<_>>(),
            (0..self.slots.len())
                .filter(|&i| self.slots[i].due() == Some(at))
                .collect::<Vec<_>>(),
            "the due times lost a slot due at {at}"
        );
        for &i in &due_now {
            if self.slots[i].due() != Some(at) {
                self.queue_due(i);
                continue;
            }
            let slot = &self.slots[i];
            let timeout_due = slot.next_timeout.is_some_and(|t| t <= at);
            // What the node's receive interrupt does: the frames leave the FIFO now (so it does
            // not overrun), and the logic gets them, in order, at its next deadline.
            let buffering = slot.frames_can_wait && !timeout_due && !slot.event_wake;
            // The frames held so far, then those the FIFO has now.
            let mut frames = std::mem::take(&mut self.slots[i].buffered);
            // Every slot has its controller (attached together): an error here is a bug, told.
            if let Err(error) = self.bus.drain_rx_into(NodeId(i as u16), at, &mut frames) {
                self.command_failed(i, error);
            }
            let still_arriving = self.bus.rx_front(NodeId(i as u16));
            let slot = &mut self.slots[i];
            // Frames its logic would take no notice of are handled here, as it would handle
            // them: left out.
            if let Some(u) = &slot.unheeded {
                let before = frames.len();
                frames.retain(|r| !u.covers(r.at, &r.frame));
                slot.handover.handled += (before - frames.len()) as u64;
            }
            // A frame still on the wire is the next input, from its end.
            slot.pending_since = still_arriving;
            if buffering {
                slot.buffered = frames;
                self.queue_due(i);
                continue;
            }
            if frames.is_empty() && slot.events.is_empty() && !timeout_due {
                // Nothing for the logic (a frame it was due for went with a reset): no round
                // trip; its deadline stands.
                slot.buffered = frames;
                slot.event_wake = false;
                self.queue_due(i);
                continue;
            }
            slot.next_timeout = None;
            slot.event_wake = false;
            slot.handover.in_flight += frames.len() as u64;
            let inputs = Inputs {
                slot: i,
                controller: slot.controller,
                frames,
                events: std::mem::take(&mut slot.events),
            };
            let first = slot.first;
            // Due again for a frame still arriving; its deadline comes with its answer.
            self.queue_due(i);
            // A node's controllers are neighbours: a further one joins its node's wake.
            match self.woken.back_mut() {
                Some(wake) if wake.node == first && wake.round == self.round => wake.inputs.push(inputs),
                _ => {
                    self.waiting += 1;
                    self.wakes += 1;
                    self.woken.push_back(Wake {
                        node: first,
                        round: self.round,
                        now: at,
                        inputs: smallvec::smallvec![inputs],
                    });
                }
            }
        }
        due_now.clear();
        self.due_now = due_now;
        self.waiting > 0
    }

    /// Tells register-level nodes of the counters an event changed: the values the event
    /// carries where it has them, else the controller's as the event leaves them (a frame
    /// that went through, a reset). Answers with the earliest due time among the nodes it told
    /// (the others' stand, and the caller knows them). Out of line: a bus without
    /// register-level nodes does not carry it in its per-event path.
    #[inline(never)]
    fn counters_of(&mut self, event: &Event) -> Option<BusTime> {
        match *event {
            Event::BusError {
                node, at, tec, rec, ..
            }
            | Event::State {
                node, at, tec, rec, ..
            }
            | Event::Warning {
                node, at, tec, rec, ..
            } => self.counters_to(node.index(), at, tec, rec),
            Event::TxDone { node, at, .. } | Event::Restarted { node, at } => {
                self.counters_now(node.index(), at)
            }
            Event::Frame { end, .. } => {
                let mut due: Option<BusTime> = None;
                for i in 0..self.slots.len() {
                    if self.slots[i].every_event
                        && let Some(d) = self.counters_now(i, end)
                    {
                        due = Some(due.map_or(d, |x| x.min(d)));
                    }
                }
                due
            }
            _ => None,
        }
    }
}
