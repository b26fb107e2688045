//! The saturated bus: 21 nodes that always have a frame pending.

use actix::prelude::*;
use bus::engine::{ControllerConfig, Filter, NodeId};
use bus::filter::SocketCanFilterSet;
use bus::node::{ControllerEvent, NodeLogic};
use bus::time::BusTime;
use bus::{Frame, engine::BusConfig};
use bus_runtime::hub::{Attach, Hub, HubConfig, RunUntil, runtime};
use bus_runtime::node::NodeActor;
use futures_util::future::join_all;
use protocol::ident::{Address, AppId, FrameType, Priority};
use std::time::Duration;

use super::Totals;

/// Keeps `DEPTH` frames in its controller's queue: it refills whenever it is woken.
struct Saturator {
    me: Address,
    to: Address,
    priority: Priority,
    in_flight: usize,
    sequence: u64,
    owed: usize,
}

const DEPTH: usize = 8;

impl NodeLogic for Saturator {
    fn handle_frame(&mut self, _: BusTime, _: &Frame) {}
    fn handle_timeout(&mut self, _: BusTime) {}
    fn handle_event(&mut self, _: BusTime, event: ControllerEvent) {
        if let ControllerEvent::Sent(_) | ControllerEvent::Aborted(_) | ControllerEvent::Refused(_) = event {
            self.in_flight = self.in_flight.saturating_sub(1);
        }
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        if self.owed == 0 {
            self.owed = DEPTH - self.in_flight;
        }
        if self.owed == 0 || self.in_flight >= DEPTH {
            self.owed = 0;
            return None;
        }
        self.owed -= 1;
        self.in_flight += 1;
        self.sequence += 1;
        let id = AppId::new(self.priority, FrameType::PointToPoint, self.to, self.me);
        Frame::new_data(id.emit(), &self.sequence.to_le_bytes()).ok()
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        None
    }
}

/// Builds one saturated bus and returns its hub.
async fn saturated_bus(seed: u64) -> crate::Result<Addr<Hub>> {
    let config = HubConfig {
        bus: BusConfig {
            seed,
            latency_class: protocol::ident::latency_class,
            ..BusConfig::default()
        },
        ..HubConfig::new(false)
    };
    let hub = Hub::new(config, Vec::new())?.start();
    let addresses: Vec<Address> = Address::all().collect();
    for (i, &me) in addresses.iter().enumerate() {
        let to = addresses[(i + 1) % addresses.len()];
        let logic = Saturator {
            me,
            to,
            priority: Priority::new(2 + (i % 5) as u8)?,
            in_flight: 0,
            sequence: 0,
            owed: 0,
        };
        // Take only frames addressed to this node: ID15..8 = own address.
        let filter = SocketCanFilterSet(vec![protocol::ident::to_node_filter(me)]);
        let node = NodeActor::new(me.to_string(), Box::new(logic)).start();
        let controller = ControllerConfig {
            tx_queue_len: DEPTH,
            ..ControllerConfig::named(me.to_string())
        }
        .with_filter(Filter::SocketCan(filter));
        let _: NodeId = hub
            .send(Attach {
                controller,
                node: Some(node.recipient()),
                reaction: Duration::from_micros(50),
            })
            .await
            .map_err(|e| bus::Error::Syntax(e.to_string()))?;
    }
    Ok(hub)
}

/// Runs `buses` saturated buses on this thread for `seconds` of virtual time.
pub fn run_on_this_thread(buses: usize, first_seed: u64, seconds: f64) -> Result<Totals, String> {
    let system = System::with_tokio_rt(|| runtime(true).expect("a tokio runtime"));
    system.block_on(async move {
        let mut hubs = Vec::new();
        for b in 0..buses {
            hubs.push(
                saturated_bus(first_seed + b as u64)
                    .await
                    .map_err(|e| e.to_string())?,
            );
        }
        let until = BusTime::from_nanos((seconds * 1e9) as u64);
        for r in join_all(hubs.iter().map(|h| h.send(RunUntil(until)))).await {
            r.map_err(|e| e.to_string())?.map_err(|e| e.to_string())?;
        }
        super::totals(&hubs).await
    })
}
