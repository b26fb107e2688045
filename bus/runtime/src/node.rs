//! The node actor: drives one sans-IO [`NodeLogic`] on behalf of the hub, catching its panics.
//!
//! The hub sends a [`Wake`] with the inputs since the last one, for each of the node's
//! controllers that is due; the actor feeds them to the logic with [`drive_counted`], one
//! controller after the other, and answers with a [`Report`] for each through the wake's
//! [`Reply`]: one message out per wake, one back per controller (one, but for a node with
//! several).

use actix::prelude::*;
use bus::node::{CrashCause, HardwareState, NodeFault, NodeLogic, Refused, Report, drive_counted};
use bus::schedule::Inputs;
use bus::time::BusTime;
use smallvec::SmallVec;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;

/// The hub wakes a node: inputs since the last wake, all at or before `now`. The node answers
/// through `reply`.
#[derive(Message, Debug)]
#[rtype(result = "()")]
pub struct Wake {
    /// Bus time of the wake.
    pub now: BusTime,
    /// The inputs of each of the node's controllers that is due, in controller order: one, but
    /// for a node with several ([`crate::hub::AttachControllers`]).
    pub inputs: SmallVec<[Inputs; 1]>,
    /// Where the [`Report`]s go.
    pub reply: Reply,
}

/// A node's answer on its way back to the hub.
#[derive(Message, Debug)]
#[rtype(result = "()")]
pub struct Answer {
    /// The hub's wake round it answers.
    pub round: u64,
    /// The controller's slot on the hub whose inputs the report answers.
    pub slot: usize,
    /// What the node did with them.
    pub report: Report,
    /// The wake's last answer (a wake with inputs of several controllers answers each, in
    /// order; a crash ends them).
    pub last: bool,
}

/// The way back for one wake's [`Report`]. One-way messages both ways are the cheapest round
/// trip actix offers (no response channel, no future per wake). A wake that is never answered,
/// because the node's actor is gone, still answers when it is dropped: as a crash, so the hub
/// never waits for ever.
#[derive(Debug)]
pub struct Reply {
    // Shared: cloning an actix address allocates, an `Arc` does not.
    to: Option<Arc<Recipient<Answer>>>,
    node: usize,
    round: u64,
}

impl Reply {
    /// A reply to `to` for the node whose first controller is in `node`, wake round `round`.
    pub fn new(to: Arc<Recipient<Answer>>, node: usize, round: u64) -> Reply {
        Reply {
            to: Some(to),
            node,
            round,
        }
    }

    /// Sends the report on the inputs of the controller in `slot`, not the wake's last.
    pub fn send(&self, slot: usize, report: Report) {
        if let Some(to) = &self.to {
            to.do_send(Answer {
                round: self.round,
                slot,
                report,
                last: false,
            });
        }
    }

    /// Sends the wake's last report.
    pub fn finish(mut self, slot: usize, report: Report) {
        if let Some(to) = self.to.take() {
            to.do_send(Answer {
                round: self.round,
                slot,
                report,
                last: true,
            });
        }
    }
}

impl Drop for Reply {
    fn drop(&mut self) {
        if let Some(to) = self.to.take() {
            let gone = Report {
                crashed: Some(CrashCause::ActorGone),
                ..Report::default()
            };
            to.do_send(Answer {
                round: self.round,
                slot: self.node,
                report: gone,
                last: true,
            });
        }
    }
}

/// A node as an actor: owns its logic, answers wakes. A panic in the logic is caught and
/// reported; the actor then stops.
pub struct NodeActor {
    name: String,
    logic: Box<dyn NodeLogic>,
    crash_next: bool,
}

impl NodeActor {
    /// An actor around `logic`.
    pub fn new(name: impl Into<String>, logic: Box<dyn NodeLogic>) -> NodeActor {
        NodeActor {
            name: name.into(),
            logic,
            crash_next: false,
        }
    }
}

impl Actor for NodeActor {
    type Context = Context<Self>;
}

impl Handler<Wake> for NodeActor {
    type Result = ();

    fn handle(&mut self, wake: Wake, ctx: &mut Context<Self>) {
        let Wake { now, inputs, reply } = wake;
        let _span = tracing::trace_span!("node", node = %self.name).entered();
        let count = inputs.len();
        for (k, input) in inputs.into_iter().enumerate() {
            let slot = input.slot;
            let report = self.drive(now, input, ctx);
            if report.crashed.is_some() || k + 1 == count {
                return reply.finish(slot, report);
            }
            reply.send(slot, report);
        }
    }
}

impl NodeActor {
    /// Feeds one controller's inputs to the logic; a crash stops the actor.
    fn drive(&mut self, now: BusTime, input: Inputs, ctx: &mut Context<Self>) -> Report {
        if std::mem::take(&mut self.crash_next) {
            // An injected crash behaves as a panic would, without the noise of one.
            tracing::info!(node = %self.name, "injected crash");
            // What the logic did up to this moment stands: a traced or counted firmware node
            // brings its trace and its coverage here.
            self.logic.run_ends(now);
            ctx.stop();
            return Report {
                crashed: Some(CrashCause::Injected),
                ..Report::default()
            };
        }
        let Inputs {
            controller,
            frames,
            events,
            ..
        } = input;
        let mut handled = 0;
        match catch_unwind(AssertUnwindSafe(|| {
            drive_counted(self.logic.as_mut(), controller, now, frames, events, &mut handled)
        })) {
            Ok(report) => report,
            Err(panic) => {
                let message = panic_message(panic.as_ref()).unwrap_or_else(|| "panic".to_string());
                tracing::error!(node = %self.name, %message, "node logic panicked");
                ctx.stop();
                Report {
                    crashed: Some(CrashCause::Panic(message)),
                    frames_handled: handled,
                    ..Report::default()
                }
            }
        }
    }
}

/// The message a panic carried, when it carried text (`panic!("...")` does).
pub fn panic_message(panic: &(dyn std::any::Any + Send)) -> Option<String> {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
}

/// Makes the node's logic crash at its next wake (fault injection).
#[derive(Message)]
#[rtype(result = "()")]
pub struct Crash;

impl Handler<Crash> for NodeActor {
    type Result = ();
    fn handle(&mut self, _: Crash, _: &mut Context<Self>) {
        self.crash_next = true;
    }
}

/// Hands a fault to the node's logic from `now` on ([`NodeLogic::inject`]: a scenario's sensor
/// faults); answers with the logic's refusal, if it refused.
#[derive(Message)]
#[rtype(result = "Result<(), Refused>")]
pub struct Inject {
    /// The fault.
    pub fault: NodeFault,
    /// From when.
    pub now: BusTime,
}

impl Handler<Inject> for NodeActor {
    type Result = Result<(), Refused>;
    fn handle(&mut self, msg: Inject, _: &mut Context<Self>) -> Self::Result {
        self.logic.inject(&msg.fault, msg.now)
    }
}

/// Asks for the node's hardware at bus time `0` ([`NodeLogic::hardware`]: a firmware node's CPU
/// and chips, for a state dump); `None` for a logic without such hardware.
#[derive(Message)]
#[rtype(result = "Option<HardwareState>")]
pub struct ReadHardware(pub BusTime);

impl Handler<ReadHardware> for NodeActor {
    type Result = Option<HardwareState>;
    fn handle(&mut self, ReadHardware(at): ReadHardware, _: &mut Context<Self>) -> Self::Result {
        self.logic.hardware(at)
    }
}

/// Tells the node's logic that the run ends at bus time `0` ([`NodeLogic::run_ends`]: a traced
/// firmware node brings its instruction trace up to there).
#[derive(Message)]
#[rtype(result = "()")]
pub struct RunEnds(pub BusTime);

impl Handler<RunEnds> for NodeActor {
    type Result = ();
    fn handle(&mut self, RunEnds(at): RunEnds, _: &mut Context<Self>) {
        self.logic.run_ends(at);
    }
}
