//! A node that crashes by itself more often than the restart policy allows stays down, and the
//! run ends with exit code 4; a crash a scenario injects on purpose does not count.
//!
//! No valid config or script makes a node's logic fail at run time (they are checked on
//! loading, and the node logics do not panic on any input), so the crash comes from a logic
//! put in a node's place here, in-process: exactly what the supervisor sees of a logic that
//! panics.

use actix::prelude::*;
use bus::Frame;
use bus::node::NodeLogic;
use bus::time::BusTime;
use bus_runtime::hub::{Replace, runtime};
use bus_runtime::node::NodeActor;
use std::path::Path;
use supervisor::exit::{self, Ended};
use supervisor::harvester::{self, Harvester};

/// Panics the first time it is woken.
struct Faulty;

impl NodeLogic for Faulty {
    fn handle_frame(&mut self, _: BusTime, _: &Frame) {
        panic!("a fault in the logic");
    }
    fn handle_timeout(&mut self, _: BusTime) {
        panic!("a fault in the logic");
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        None
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        Some(BusTime::ZERO)
    }
}

#[test]
fn a_node_down_by_itself_is_exit_4_and_an_injected_crash_is_not() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/harvester.ron");
    let mut h = Harvester::load(&path).unwrap();
    // One crash is one too many: the first puts the node down.
    h.config.network.restart.max_restarts = 0;
    let system = System::with_tokio_rt(|| runtime(true).expect("a tokio runtime"));
    let (down, events) = system.block_on(async move {
        let mut running = harvester::start(&h, false, Vec::new()).await.unwrap();
        let d3 = running.node("D3").unwrap();
        let faulty = NodeActor::new("D3", Box::new(Faulty)).start();
        running
            .hub
            .send(Replace {
                node: d3,
                actor: faulty.recipient(),
            })
            .await
            .unwrap()
            .unwrap();
        running.crash("D4").await.unwrap();
        let until = running.now() + bus::time::BusDuration::from_secs(2);
        running.run_until(until).await.unwrap();
        (running.down_by_themselves(), running.events.clone())
    });
    let gave_up: Vec<&str> = events
        .iter()
        .filter(|e| matches!(e.what, harvester::Happened::GaveUp { .. }))
        .map(|e| e.node.as_str())
        .collect();
    assert_eq!(gave_up, ["D3", "D4"], "both stay down: {events:?}");
    assert_eq!(down, ["D3"], "only D3 crashed by itself: {events:?}");
    let ended = Ended {
        expectations_failed: false,
        node_down: !down.is_empty(),
    };
    assert_eq!(exit::code(&Ok(ended), None), 4);
}
