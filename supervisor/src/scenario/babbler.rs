//! The babbling idiot of a `Babble` step: an extra controller that floods the bus with one frame.
//!
//! Contract: at most one flood runs at a time (a newer one takes over, and the first end stops
//! it); a stopped babbler is parked, disconnected and hung, and the next flood reuses it, so that
//! a long run with many floods does not grow the bus by a controller each time.

use crate::harvester::Running;
use actix::prelude::*;
use bus::Frame;
use bus::engine::{ControllerConfig, Filter, NodeId};
use bus::node::NodeLogic;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::{Attach, Control, Replace};
use bus_runtime::node::NodeActor;

/// A babbling idiot: tops up its transmit queue every millisecond, so that it always has a
/// frame pending.
struct Babbler {
    frame: Frame,
    next: BusTime,
    owed: usize,
}

const BABBLER_QUEUE: usize = 4;

impl NodeLogic for Babbler {
    fn handle_frame(&mut self, _: BusTime, _: &Frame) {}
    fn handle_timeout(&mut self, now: BusTime) {
        self.owed = BABBLER_QUEUE;
        self.next = now + BusDuration::from_millis(1);
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        // Frames beyond the queue are refused by the controller: no harm, it tries again.
        self.owed = self.owed.checked_sub(1)?;
        Some(self.frame)
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        Some(self.next)
    }
}

/// Babbling idiots: the one flooding now, and those parked for the next flood.
#[derive(Default)]
pub(super) struct Babblers {
    active: Option<NodeId>,
    parked: Vec<NodeId>,
}

impl Babblers {
    /// Starts flooding the bus with `frame` from now on.
    pub(super) async fn start(&mut self, running: &Running, frame: Frame) -> crate::Result<()> {
        let logic = Babbler {
            frame,
            next: running.now(),
            owed: 0,
        };
        let actor = NodeActor::new("babbler", Box::new(logic)).start();
        let node = if let Some(node) = self.parked.pop() {
            // A new logic behind a parked controller (reset), back on the bus.
            running
                .hub
                .send(Replace {
                    node,
                    actor: actor.recipient(),
                })
                .await??;
            running.hub.send(Control::SetConnected(node, true)).await??;
            node
        } else {
            let controller = ControllerConfig {
                tx_queue_len: BABBLER_QUEUE,
                ..ControllerConfig::named("babbler")
            }
            .with_filter(Filter::Nothing);
            running
                .hub
                .send(Attach {
                    controller,
                    node: Some(actor.recipient()),
                    reaction: std::time::Duration::from_micros(50),
                })
                .await?
        };
        if let Some(old) = self.active.replace(node) {
            park(running, old, &mut self.parked).await?;
        }
        Ok(())
    }

    /// Stops the flood, if one runs.
    pub(super) async fn stop(&mut self, running: &Running) -> crate::Result<()> {
        if let Some(node) = self.active.take() {
            park(running, node, &mut self.parked).await?;
        }
        Ok(())
    }
}

/// Takes a babbler off the bus, to wait for the next flood.
async fn park(running: &Running, node: NodeId, parked: &mut Vec<NodeId>) -> crate::Result<()> {
    running.hub.send(Control::SetConnected(node, false)).await??;
    running.hub.send(Control::SetHung(node, true)).await??;
    parked.push(node);
    Ok(())
}
