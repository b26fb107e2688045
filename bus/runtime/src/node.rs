//! The node actor: drives one sans-IO [`NodeLogic`] on behalf of the hub, catching its panics.
//!
//! The hub sends a [`Wake`] with the inputs since the last one; the actor feeds them to the logic
//! with [`drive_counted`] and answers with a [`Report`] through the wake's [`Reply`].

use actix::prelude::*;
use bus::engine::Received;
use bus::node::{ControllerEvent, CrashCause, NodeLogic, Report, drive_counted};
use bus::time::BusTime;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;

/// The hub wakes a node: inputs since the last wake, all at or before `now`. The node answers
/// through `reply`.
#[derive(Message, Debug)]
#[rtype(result = "()")]
pub struct Wake {
    /// Bus time of the wake.
    pub now: BusTime,
    /// Which of the node's controllers the inputs are from: 0, but for a node with several
    /// ([`crate::hub::AttachControllers`]).
    pub controller: usize,
    /// Frames from the receive FIFO, oldest first.
    pub frames: Vec<Received>,
    /// Controller notifications, oldest first.
    pub events: Vec<(BusTime, ControllerEvent)>,
    /// Where the [`Report`] goes.
    pub reply: Reply,
}

/// A node's answer on its way back to the hub.
#[derive(Message, Debug)]
#[rtype(result = "()")]
pub struct Answer {
    /// The node's slot on the hub.
    pub slot: usize,
    /// The hub's wake round it answers.
    pub round: u64,
    /// What the node did.
    pub report: Report,
}

/// The way back for one wake's [`Report`]. One-way messages both ways are the cheapest round
/// trip actix offers (no response channel, no future per wake). A wake that is never answered,
/// because the node's actor is gone, still answers when it is dropped: as a crash, so the hub
/// never waits for ever.
#[derive(Debug)]
pub struct Reply {
    // Shared: cloning an actix address allocates, an `Arc` does not.
    to: Option<Arc<Recipient<Answer>>>,
    slot: usize,
    round: u64,
}

impl Reply {
    /// A reply to `to` for the node in `slot`, wake round `round`.
    pub fn new(to: Arc<Recipient<Answer>>, slot: usize, round: u64) -> Reply {
        Reply {
            to: Some(to),
            slot,
            round,
        }
    }

    /// Sends the report.
    pub fn send(mut self, report: Report) {
        if let Some(to) = self.to.take() {
            to.do_send(Answer {
                slot: self.slot,
                round: self.round,
                report,
            });
        }
    }
}

impl Drop for Reply {
    fn drop(&mut self) {
        if let Some(to) = self.to.take() {
            to.do_send(Answer {
                slot: self.slot,
                round: self.round,
                report: Report {
                    crashed: Some(CrashCause::ActorGone),
                    ..Report::default()
                },
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
        let Wake {
            now,
            controller,
            frames,
            events,
            reply,
        } = wake;
        let _span = tracing::trace_span!("node", node = %self.name).entered();
        if std::mem::take(&mut self.crash_next) {
            // An injected crash behaves as a panic would, without the noise of one.
            tracing::info!(node = %self.name, "injected crash");
            ctx.stop();
            return reply.send(Report {
                crashed: Some(CrashCause::Injected),
                ..Report::default()
            });
        }
        let mut handled = 0;
        let report = match catch_unwind(AssertUnwindSafe(|| {
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
        };
        reply.send(report);
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

/// A change made to a node's logic from outside.
pub type LogicChange = Box<dyn FnOnce(&mut dyn NodeLogic) + Send>;

/// Runs a function on the node's logic, on the node's actor (a scenario's faults reach the logic
/// this way, through [`NodeLogic::inject`]).
#[derive(Message)]
#[rtype(result = "()")]
pub struct Apply(pub LogicChange);

impl Handler<Apply> for NodeActor {
    type Result = ();
    fn handle(&mut self, Apply(f): Apply, _: &mut Context<Self>) {
        f(self.logic.as_mut());
    }
}
