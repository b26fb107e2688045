//! The cab monitor (F5). For now the part that keeps the network alive: it calibrates and
//! acknowledges the flow sensors and keeps the latest decoded value of every field of every
//! message. (The full reference monitor — yield, alarms, cruise control, display — builds on
//! this.)

pub mod flow;

use bus::Frame;
use bus::catalogue::{self, Direction};
use bus::ident::{Address, NodeKind};
use bus::node::NodeLogic;
use bus::time::BusTime;
use flow::{Calibration, FlowSession};
use std::collections::{BTreeMap, VecDeque};

/// The monitor's logic.
pub struct Monitor {
    sessions: BTreeMap<Address, FlowSession>,
    calibration: Calibration,
    out: VecDeque<Frame>,
    /// Latest value per `message.field` and node, with its time.
    pub latest: BTreeMap<(Address, String), (BusTime, f64)>,
    /// Frames received that the catalogue does not know, or that break its layout.
    pub unknown: u64,
}

impl Monitor {
    /// A monitor with the given calibration settings.
    pub fn new(calibration: Calibration) -> Monitor {
        let sessions = Address::all()
            .filter(|a| a.kind() == Some(NodeKind::FlowSensor))
            .map(|a| (a, FlowSession::new(a)))
            .collect();
        Monitor {
            sessions,
            calibration,
            out: VecDeque::new(),
            latest: BTreeMap::new(),
            unknown: 0,
        }
    }

    /// The session with flow sensor `a`.
    pub fn session(&self, a: Address) -> Option<&FlowSession> {
        self.sessions.get(&a)
    }
}

impl NodeLogic for Monitor {
    fn handle_frame(&mut self, now: BusTime, frame: &Frame) {
        let d = match catalogue::decode(frame) {
            Ok(Some(d)) if d.message.direction == Direction::ToMonitor => d,
            _ => {
                self.unknown += 1;
                return;
            }
        };
        for v in &d.values {
            self.latest.insert(
                (d.node, format!("{}.{}", d.message.name, v.field.name)),
                (now, v.physical),
            );
        }
        if let Some(session) = self.sessions.get_mut(&d.node) {
            let mut out = Vec::new();
            session.handle(&d, self.calibration, &mut out);
            self.out.extend(out);
        }
    }
    fn handle_timeout(&mut self, _: BusTime) {}
    fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        None
    }
}
