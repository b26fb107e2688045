//! What a register-level node (firmware) asks of its controller, and the events it hears of
//! as they happen ([`crate::node::NodeLogic::wants_every_event`]).

use super::Scheduler;
use crate::engine::{BitPosition, Effect, NodeId, Rule, RuleId, Schedule, SeenBy, Target};
use crate::node::{ControllerCommand, ControllerEvent};
use crate::time::BusTime;

/// A controller's switches as its logic set them.
#[derive(Clone, Debug, Default)]
pub(super) struct Switches {
    /// Listen-only mode: no acknowledgements.
    pub listen_only: bool,
    /// The rules that make a mistuned controller misread the bus and be misread.
    pub mistuned: Option<[RuleId; 2]>,
    /// The counters it last heard of.
    pub counters: (u16, u16),
    /// Its logic took it off the bus (a chip in reset): it stays off until the logic puts it
    /// back.
    pub offline: bool,
    /// Its cable is out ([`Scheduler::set_connected`]): it stays off the bus whatever its logic
    /// does, until plugged in again. Kept apart from `offline`, so that firmware starting its
    /// controller on an unplugged node does not plug it in.
    pub unplugged: bool,
}

impl Scheduler {
    /// Applies one command of slot `i`'s logic at `now`.
    pub(super) fn apply(&mut self, i: usize, command: ControllerCommand, now: BusTime) {
        let node = NodeId(i as u16);
        let result = match command {
            ControllerCommand::Transmit(frame) => {
                self.submit_for(i, frame, now, false);
                Ok(())
            }
            ControllerCommand::TransmitOnce(frame) => {
                self.submit_for(i, frame, now, true);
                Ok(())
            }
            ControllerCommand::Online {
                listen_only,
                self_test,
            } => {
                let switches = &mut self.slots[i].switches;
                switches.listen_only = listen_only;
                switches.offline = false;
                let (tuned, plugged) = (switches.mistuned.is_none(), !switches.unplugged);
                self.bus
                    .set_connected(node, plugged, now)
                    .and_then(|()| self.bus.set_listen_only(node, listen_only, now))
                    .and_then(|()| self.bus.set_presume_ack(node, self_test))
                    .and_then(|()| self.bus.set_ack(node, tuned && !listen_only))
            }
            ControllerCommand::Offline => {
                self.slots[i].switches.offline = true;
                self.bus
                    .abort(node, now)
                    .and_then(|()| self.bus.set_connected(node, false, now))
            }
            ControllerCommand::Abort => self.bus.abort(node, now),
            ControllerCommand::SetCounters { tec, rec } => {
                let r = self.bus.set_counters(node, tec, rec, now);
                let _ = self.counters_now(i, now);
                r
            }
            ControllerCommand::Recover => self.bus.request_recovery(node, now),
            ControllerCommand::Sleep(on) => self.bus.set_asleep(node, on, now),
            ControllerCommand::Tuned(tuned) => {
                self.tune(i, tuned);
                let listen_only = self.slots[i].switches.listen_only;
                self.bus.set_ack(node, tuned && !listen_only)
            }
        };
        if let Err(error) = result {
            self.command_failed(i, error);
        }
    }

    /// A mistuned controller samples every other node's frame wrongly (a stuff error where the
    /// first one can fall after arbitration), and every other node samples its frames wrongly:
    /// so it destroys frames with error flags while error active and acknowledges nothing.
    fn tune(&mut self, i: usize, tuned: bool) {
        let node = NodeId(i as u16);
        match (tuned, self.slots[i].switches.mistuned.take()) {
            (true, Some(ids)) => {
                for id in ids {
                    self.bus.injector_mut().remove(id);
                }
            }
            (false, None) => {
                let misread = |target, seen_by| Rule {
                    target,
                    schedule: Schedule::Always,
                    bit: BitPosition::At(0),
                    effect: Effect::Stuff,
                    seen_by,
                };
                // Its own frames first: the first rule that corrupts an attempt wins.
                let own = self
                    .bus
                    .injector_mut()
                    .add(misread(Target::Node(node), SeenBy::All));
                let others = self
                    .bus
                    .injector_mut()
                    .add(misread(Target::Any, SeenBy::Nodes(vec![node])));
                self.slots[i].switches.mistuned = Some([own, others]);
            }
            (_, kept) => self.slots[i].switches.mistuned = kept,
        }
    }

    /// Tells slot `i` its counters at `at` if they changed since it last heard; then its due
    /// time.
    pub(super) fn counters_to(&mut self, i: usize, at: BusTime, tec: u16, rec: u16) -> Option<BusTime> {
        let slot = &mut self.slots[i];
        if !slot.every_event || slot.switches.counters == (tec, rec) {
            return None;
        }
        slot.switches.counters = (tec, rec);
        slot.input(at, Some(ControllerEvent::Counters { tec, rec }), true);
        self.queue_due(i);
        self.slots[i].due()
    }

    /// [`Scheduler::counters_to`] with the controller's present counters.
    pub(super) fn counters_now(&mut self, i: usize, at: BusTime) -> Option<BusTime> {
        let c = self.bus.controller(NodeId(i as u16))?;
        let (tec, rec) = (c.fault().tec(), c.fault().rec());
        self.counters_to(i, at, tec, rec)
    }
}
