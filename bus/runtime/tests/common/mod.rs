//! Node logics, and a small bus, that the hub's integration tests share.

use actix::prelude::*;
use bus::Frame;
use bus::candump::parse_frame;
use bus::engine::ControllerConfig;
use bus::node::NodeLogic;
use bus::time::BusTime;
use bus_runtime::hub::{Attach, Hub, HubConfig};
use bus_runtime::node::NodeActor;
use std::time::Duration;

/// A hub with a node `ticker` that sends `frame` every `period_us` from time 0, and a silent
/// `listener` that acknowledges every frame, paced (real time). Must run inside an actor system.
#[allow(dead_code)] // not every test file builds a bus
pub async fn hub_with_ticker(frame: &str, period_us: u64) -> Addr<Hub> {
    hub_with_ticker_at(HubConfig::new(true), frame, period_us).await
}

/// The same bus, built from `config` (its epoch, say).
#[allow(dead_code)] // not every test file builds a bus
pub async fn hub_with_ticker_at(config: HubConfig, frame: &str, period_us: u64) -> Addr<Hub> {
    let hub = Hub::new(config, Vec::new()).unwrap().start();
    let ticker = NodeActor::new("ticker", Box::new(Periodic::every_us(frame, period_us, 0))).start();
    for (name, node) in [("ticker", Some(ticker.recipient())), ("listener", None)] {
        hub.send(Attach {
            controller: ControllerConfig::named(name),
            node,
            reaction: Duration::ZERO,
        })
        .await
        .unwrap();
    }
    hub
}

/// Sends `frame` every `period` nanoseconds, the first time at `next`.
pub struct Periodic {
    pub frame: Frame,
    pub period: bus::time::BusDuration,
    pub next: BusTime,
    pub due: bool,
}

impl Periodic {
    /// Every `period_ms`, starting at `phase_us`.
    #[allow(dead_code)] // not every test file uses every constructor
    pub fn new(text: &str, period_ms: u64, phase_us: u64) -> Periodic {
        Periodic::every_us(text, period_ms * 1000, phase_us)
    }

    /// Every `period_us`, starting at `phase_us`.
    pub fn every_us(text: &str, period_us: u64, phase_us: u64) -> Periodic {
        Periodic {
            frame: parse_frame(text).unwrap(),
            period: bus::time::BusDuration::from_micros(period_us),
            next: BusTime::from_micros(phase_us),
            due: false,
        }
    }
}

impl NodeLogic for Periodic {
    fn handle_frame(&mut self, _: BusTime, _: &Frame) {}
    fn handle_timeout(&mut self, now: BusTime) {
        self.due = true;
        self.next = now + self.period;
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        std::mem::take(&mut self.due).then_some(self.frame)
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        Some(self.next)
    }
}
