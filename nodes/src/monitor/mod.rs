//! The reference cab monitor (F5), written the way its firmware would be.
//!
//! - **Producer/consumer**, as the source's monitor: the receive interrupt (`handle_frame`) only
//!   copies frames into a bounded queue, and counts what does not fit as lost; the main loop
//!   (`handle_timeout`, every `tick_ms`) takes up to `consume_per_tick` frames, unpacks each
//!   identifier and payload through the catalogue, and acts.
//! - **Power-up**: it waits for the field nodes, calibrates each flow sensor (start, average the
//!   reference groups, accept), then reads flow continuously, acknowledging every group.
//! - **Machine state, alarms, yield**: every catalogue message updates the [`Display`]; alarm
//!   switches raise and clear timestamped alarms; silent nodes raise an alarm too; each row's
//!   flow, from the five units and their references, is integrated into kg and kg/ha.
//! - **Cruise**: from its start time on, it switches the speed controller to cruise, starts row
//!   alignment, and sets the travel speed from the feed rate with fuzzy rules ([`cruise`]).
//!
//! The display is shared (`Rc<RefCell<Display>>`) so that tests and a terminal view can read it
//! while the monitor runs.

mod check;
pub mod cruise;
pub mod display;
pub mod flow;

use bus::Frame;
use bus::node::NodeLogic;
use bus::time::{BusDuration, BusTime};
use cruise::{Cruise, CruiseConfig};
pub use display::{Alarm, Display, FrameTally, RowYield};
use flow::{Calibration, FlowSession, Group};
use protocol::catalogue::{self, Decoded, Direction, by_name};
use protocol::ident::{Address, NodeKind};
use serde::{Deserialize, Serialize};
use std::cell::RefCell;
use std::collections::{BTreeMap, VecDeque};
use std::rc::Rc;

/// The monitor's settings (the `monitor` section of the harvester config).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MonitorConfig {
    /// False when an external monitor takes its place.
    pub enabled: bool,
    /// Reaction time of its receive interrupt, µs.
    pub reaction_us: u64,
    /// Reference level the flow sensors are calibrated to, counts.
    pub target_reference: f64,
    /// Reference groups averaged during calibration.
    pub calibration_samples: u8,
    /// Sensor constant: attenuation per unit of reference per g/s.
    pub attenuation_per_g_s: f64,
    /// Row spacing, m (for kg/ha).
    pub row_spacing_m: f64,
    /// Receive queue between producer and consumer, frames.
    pub queue_capacity: usize,
    /// Frames the consumer takes per tick.
    pub consume_per_tick: usize,
    /// Main-loop period, ms.
    pub tick_ms: u64,
    /// A node silent this long raises an alarm, ms.
    pub silence_ms: u64,
    /// Cruise control.
    pub cruise: CruiseConfig,
}

impl Default for MonitorConfig {
    fn default() -> Self {
        MonitorConfig {
            enabled: true,
            reaction_us: 100,
            target_reference: 10_000.0,
            calibration_samples: 5,
            attenuation_per_g_s: 0.004,
            row_spacing_m: 0.76,
            queue_capacity: 256,
            consume_per_tick: 64,
            tick_ms: 10,
            silence_ms: 3000,
            cruise: CruiseConfig::default(),
        }
    }
}

/// A shared view of the display.
pub type DisplayHandle = Rc<RefCell<Display>>;

/// The monitor.
pub struct Monitor {
    config: MonitorConfig,
    sessions: BTreeMap<Address, FlowSession>,
    queue: VecDeque<(BusTime, Frame)>,
    out: VecDeque<Frame>,
    display: DisplayHandle,
    next_tick: BusTime,
    /// Last frame time per node, for the silence check.
    heard: BTreeMap<Address, BusTime>,
    /// Nodes not heard yet, with the time by which they should have been: past it, a
    /// "missing" alarm ([`Monitor::expecting`]). Empty once each was heard or missed.
    expected: Vec<(Address, BusTime)>,
    /// Active alarms by (node, name): index into `display.alarms`.
    /// Raised alarms by node and name (names are the catalogue's or the monitor's own).
    active: BTreeMap<(Address, &'static str), BusTime>,
    last_flow: BTreeMap<Address, BusTime>,
    last_ground: Option<(BusTime, f64)>,
    last_feed: Option<BusTime>,
    cruise: Option<Cruise>,
    next_setpoint: BusTime,
    next_control: BusTime,
}

impl Monitor {
    /// A monitor powered up at time 0.
    pub fn new(config: MonitorConfig) -> Monitor {
        Monitor::with_display(config, Rc::new(RefCell::new(Display::default())), BusTime::ZERO)
    }

    /// A monitor powered up at `power_on` that draws on an existing display (after a restart the
    /// screen is the same screen, blanked).
    pub fn with_display(config: MonitorConfig, display: DisplayHandle, power_on: BusTime) -> Monitor {
        let sessions: BTreeMap<Address, FlowSession> = Address::all()
            .filter(|a| a.kind() == Some(NodeKind::FlowSensor))
            .map(|a| (a, FlowSession::new(a)))
            .collect();
        // The books carry on: whatever the previous logic still had queued is gone with it.
        let mut tally = display.borrow().tally;
        tally.dropped_at_restart += std::mem::take(&mut tally.queued);
        *display.borrow_mut() = Display {
            phase: "power-up".to_string(),
            rows: vec![RowYield::default(); sessions.len()],
            now: power_on,
            tally,
            ..Display::default()
        };
        Monitor {
            config,
            sessions,
            queue: VecDeque::new(),
            out: VecDeque::new(),
            display,
            next_tick: power_on,
            heard: BTreeMap::new(),
            expected: Vec::new(),
            active: BTreeMap::new(),
            last_flow: BTreeMap::new(),
            last_ground: None,
            last_feed: None,
            cruise: None,
            next_setpoint: BusTime::NEVER,
            next_control: BusTime::NEVER,
        }
    }

    /// The monitor expects these nodes, each with the time its start-up ends (the time relay's
    /// start plus its boot): one not heard `silence_ms` after that (or after the monitor's own
    /// power-up, when that is later) raises a "missing" alarm, which its first frame clears. A
    /// cab monitor raises a missing-module alarm the same way; the silence alarm covers only
    /// nodes heard at least once.
    pub fn expecting(mut self, nodes: impl IntoIterator<Item = (Address, BusTime)>) -> Monitor {
        let grace = BusDuration::from_millis(self.config.silence_ms);
        let power_on = self.next_tick;
        self.expected = nodes
            .into_iter()
            .map(|(a, start)| (a, start.max(power_on).saturating_add(grace)))
            .collect();
        self
    }

    /// The display, shared.
    pub fn display(&self) -> DisplayHandle {
        self.display.clone()
    }

    /// The session with flow sensor `a`.
    pub fn session(&self, a: Address) -> Option<&FlowSession> {
        self.sessions.get(&a)
    }

    fn calibration(&self) -> Calibration {
        Calibration {
            target_reference: self.config.target_reference,
            samples: self.config.calibration_samples,
        }
    }

    fn send(&mut self, name: &str, node: Address, values: &[(&str, f64)]) {
        if let Some(f) = by_name(name).and_then(|m| {
            m.encode(node, |n| values.iter().find(|(k, _)| *k == n).map(|(_, v)| *v))
                .ok()
        }) {
            self.out.push_back(f);
        }
    }

    fn raise(&mut self, node: Address, name: &'static str, at: BusTime) {
        let key = (node, name);
        if self.active.contains_key(&key) {
            return;
        }
        self.active.insert(key, at);
        let mut d = self.display.borrow_mut();
        d.alarms.push(Alarm {
            name: name.to_string(),
            node: node.to_string(),
            raised: at,
            cleared: None,
        });
        if d.alarms.len() > 256 {
            // Forget the oldest cleared alarm; active ones stay on the screen.
            if let Some(i) = d.alarms.iter().position(|a| a.cleared.is_some()) {
                d.alarms.remove(i);
            }
        }
    }

    fn clear(&mut self, node: Address, name: &'static str, at: BusTime) {
        if self.active.remove(&(node, name)).is_none() {
            return;
        }
        let mut d = self.display.borrow_mut();
        if let Some(a) = d
            .alarms
            .iter_mut()
            .rev()
            .find(|a| a.name == name && a.node == node.to_string() && a.cleared.is_none())
        {
            a.cleared = Some(at);
        }
    }

    /// The consumer: one frame, unpacked and acted on.
    fn consume(&mut self, at: BusTime, frame: Frame) {
        let d = match catalogue::decode(&frame) {
            Ok(Some(d)) if d.message.direction == Direction::ToMonitor => d,
            _ => return,
        };
        if self.heard.insert(d.node, at).is_none() {
            self.clear(d.node, "missing", at);
        }
        self.clear(d.node, "silent", at);
        self.display.borrow_mut().frames += 1;
        if d.message.name.starts_with("alarm.") {
            for v in &d.values {
                if v.field.bits == 1 {
                    if v.raw == 1 {
                        self.raise(d.node, v.field.name, at)
                    } else {
                        self.clear(d.node, v.field.name, at)
                    }
                }
            }
        }
        let cal = self.calibration();
        if let Some(session) = self.sessions.get_mut(&d.node) {
            let mut out = Vec::new();
            let group = session.handle(&d, cal, &mut out);
            self.out.extend(out);
            self.flow_sensor(&d, at, group);
            return;
        }
        self.machine(&d, at);
    }

    fn flow_sensor(&mut self, d: &Decoded, at: BusTime, group: Option<Group>) {
        let row = usize::from(d.node.0 - 0xD0);
        if d.message.name == "flow.status" {
            let state = d.get("state").and_then(|v| v.label()).unwrap_or("?");
            if state == "no acknowledgement" || state == "fault" {
                self.raise(d.node, "flow sensor stopped", at);
            } else {
                self.clear(d.node, "flow sensor stopped", at);
            }
            let shown = &mut self.display.borrow_mut().rows[row].sensor_state;
            if shown != state {
                *shown = state.to_string();
            }
        }
        let calibrated = self.sessions.get(&d.node).is_some_and(|s| s.calibrated);
        let phase_running = self.sessions.values().all(|s| s.calibrated);
        {
            let mut disp = self.display.borrow_mut();
            disp.rows[row].calibrated = calibrated;
            disp.broken_groups = self.sessions.values().map(|s| s.broken).sum();
            let phase = if phase_running { "running" } else { "calibrating" };
            // Set only when it changes: every flow frame passes here.
            if disp.phase != phase {
                disp.phase = phase.to_string();
            }
        }
        let Some(g) = group.filter(|g| g.code == flow::FLOW_GROUP) else {
            return;
        };
        let Some(refs) = self.sessions.get(&d.node).and_then(|s| s.references) else {
            return;
        };
        // flow [g/s] = mean over units of (unit / reference) / attenuation coefficient.
        let ratio: f64 = g
            .units
            .iter()
            .zip(refs)
            .map(|(&u, r)| f64::from(u) / f64::from(r.max(1)))
            .sum::<f64>()
            / g.units.len() as f64;
        let flow = ratio / self.config.attenuation_per_g_s;
        // Each group stands for the time since the previous one (a missed group is covered by the
        // next, up to a second).
        let dt = self
            .last_flow
            .get(&d.node)
            .map_or(0.1, |&t| (at - t).as_nanos() as f64 / 1e9)
            .min(1.0);
        self.last_flow.insert(d.node, at);
        let mut disp = self.display.borrow_mut();
        disp.rows[row].flow_g_s = flow;
        disp.rows[row].kg += flow * dt / 1000.0;
        disp.total_kg = disp.rows.iter().map(|r| r.kg).sum();
        // Feed rate: the rows' latest flows, low-pass filtered in time.
        let feed: f64 = disp.rows.iter().map(|r| r.flow_g_s).sum::<f64>() / 1000.0;
        let since = self.last_feed.map_or(0.0, |t| (at - t).as_nanos() as f64 / 1e9);
        self.last_feed = Some(at);
        disp.feed_kg_s += (feed - disp.feed_kg_s) * (since / self.config.cruise.filter_s.max(1e-3)).min(1.0);
        if disp.area_ha > 0.0 {
            disp.kg_per_ha = Some(disp.total_kg / disp.area_ha);
        }
    }

    fn machine(&mut self, d: &Decoded, at: BusTime) {
        let v = |name: &str| d.get(name).map(|v| v.physical);
        let label = |name: &str| d.get(name).and_then(|v| v.label()).map(str::to_string);
        if d.message.name == "speed.status" {
            {
                let mut disp = self.display.borrow_mut();
                disp.speed_kmh = v("actual");
                disp.setpoint_kmh = v("setpoint");
                disp.drive_mode = label("mode");
            }
            if d.get("setpoint_timeout").is_some_and(|x| x.raw == 1) {
                // The speed controller gave up on us: cruise is off until the operator says.
                self.raise(d.node, "setpoint_timeout", at);
                self.cruise = None;
                self.display.borrow_mut().cruise = false;
            } else {
                self.clear(d.node, "setpoint_timeout", at);
            }
            return;
        }
        let mut disp = self.display.borrow_mut();
        match d.message.name {
            "param.ground_speed" => {
                disp.ground_speed_kmh = v("ground_speed");
                let speed = v("ground_speed").unwrap_or(0.0);
                if let Some((t0, s0)) = self.last_ground {
                    let metres = s0 / 3.6 * ((at - t0).as_nanos() as f64 / 1e9).min(1.0);
                    disp.distance_m += metres;
                    disp.area_ha =
                        disp.distance_m * self.config.row_spacing_m * disp.rows.len() as f64 / 10_000.0;
                }
                self.last_ground = Some((at, speed));
            }
            "param.engine" => disp.engine_rpm = v("engine_rpm"),
            "param.fan" => disp.fan_rpm = v("fan_rpm"),
            "param.drums" => {
                disp.front_drum_rpm = v("front_drum_rpm");
                disp.rear_drum_rpm = v("rear_drum_rpm");
            }
            "param.water" => {
                disp.water_pressure_kpa = v("water_pressure");
                disp.water_level_pct = v("water_level");
            }
            "param.oil" => disp.oil_temperature_c = v("oil_temperature"),
            "param.lubricant" => {
                disp.lubricant_rate_ml_min = v("lubricant_rate");
                disp.lubricant_level_pct = v("lubricant_level");
            }
            "param.conveyor" => {
                disp.belt_speed_m_s = v("belt_speed");
                disp.basket_fill_pct = v("basket_fill");
            }
            "row.status" => {
                disp.row_alignment = label("state");
                disp.row_offset_mm = v("offset");
            }
            _ => {}
        }
    }

    /// Nodes not heard for `silence_ms` raise an alarm; so do expected nodes never heard by
    /// their time.
    fn watch(&mut self, now: BusTime) {
        if !self.expected.is_empty() {
            let mut missing = Vec::new();
            let heard = &self.heard;
            self.expected.retain(|&(a, by)| {
                if heard.contains_key(&a) {
                    return false;
                }
                if now > by {
                    missing.push(a);
                    return false;
                }
                true
            });
            for a in missing {
                self.raise(a, "missing", now);
            }
        }
        let limit = BusDuration::from_millis(self.config.silence_ms);
        let silent: Vec<Address> = self
            .heard
            .iter()
            .filter(|(_, t)| now - **t > limit)
            .map(|(a, _)| *a)
            .collect();
        for a in silent {
            self.raise(a, "silent", now);
        }
    }

    fn drive(&mut self, now: BusTime) {
        let start = self
            .config
            .cruise
            .start_s
            .map(|s| BusTime::from_nanos((s * 1e9) as u64));
        if self.cruise.is_none() && start.is_some_and(|s| now >= s) && self.next_control == BusTime::NEVER {
            let speed = self
                .display
                .borrow()
                .speed_kmh
                .unwrap_or(self.config.cruise.min_kmh);
            self.cruise = Some(Cruise::new(self.config.cruise.clone(), speed));
            self.send("speed.mode", Address::SPEED_CONTROL, &[("mode", 1.0)]);
            self.send("row.command", Address::ROW_ALIGNMENT, &[("command", 1.0)]);
            self.next_setpoint = now;
            self.next_control = now + BusDuration::from_millis(self.config.cruise.period_ms);
            self.display.borrow_mut().cruise = true;
        }
        let Some(cruise) = self.cruise.as_mut() else {
            return;
        };
        if now >= self.next_control {
            let feed = self.display.borrow().feed_kg_s;
            cruise.step(feed);
            self.next_control += BusDuration::from_millis(self.config.cruise.period_ms);
        }
        let setpoint = cruise.setpoint;
        self.display.borrow_mut().cruise_setpoint_kmh = Some(setpoint);
        if now >= self.next_setpoint {
            // The speed controller falls back to manual after 1 s without a set-point.
            self.send(
                "speed.setpoint",
                Address::SPEED_CONTROL,
                &[("setpoint", setpoint)],
            );
            self.next_setpoint += BusDuration::from_millis(200);
        }
    }
}

impl NodeLogic for Monitor {
    /// The producer: the receive interrupt only queues.
    fn handle_frame(&mut self, now: BusTime, frame: &Frame) {
        let mut d = self.display.borrow_mut();
        d.tally.received += 1;
        if self.queue.len() < self.config.queue_capacity {
            self.queue.push_back((now, *frame));
            d.tally.queued += 1;
        } else {
            d.lost += 1;
            d.tally.queue_full += 1;
        }
    }

    /// The main loop.
    fn handle_timeout(&mut self, now: BusTime) {
        for _ in 0..self.config.consume_per_tick {
            let Some((at, frame)) = self.queue.pop_front() else {
                break;
            };
            {
                let mut d = self.display.borrow_mut();
                d.tally.processed += 1;
                d.tally.queued -= 1;
            }
            self.consume(at, frame);
        }
        self.watch(now);
        self.drive(now);
        self.display.borrow_mut().now = now;
        self.next_tick = now + BusDuration::from_millis(self.config.tick_ms.max(1));
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }

    fn poll_timeout(&self) -> Option<BusTime> {
        Some(self.next_tick)
    }

    /// `handle_frame` is the receive interrupt: it only queues (or counts a loss).
    fn frames_can_wait(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests;
