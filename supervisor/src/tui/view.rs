//! The view model: what the screen shows, as plain values.
//!
//! Contract: [`View::build`] reads its [`Sources`] and nothing else (no clock, no I/O), so the
//! same inputs always give the same view. Numbers stay numbers here; [`super::draw`] formats
//! them. Only decoded payload fields are text already, because how to show one (a named state,
//! or a value with the decimals its scaling allows) comes from the catalogue, or from the DBC of
//! a network imported from one.

use super::RateMeter;
use crate::harvester::SupervisorEvent;
use bus::Frame;
use bus::fault::ErrorState;
use bus::filter::{CAN_EFF_FLAG, CAN_EFF_MASK, CAN_RTR_FLAG, CAN_SFF_MASK};
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::Snapshot;
use nodes::monitor::Display;
use nodes::plant::{Plant, ROWS};
use protocol::catalogue::{self, Value};
use protocol::database::Database;
use protocol::ident::AppId;

/// How the emulation's clock runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Clock {
    /// Virtual time, as fast as the machine allows (`--fast`).
    Virtual,
    /// Bus time follows the wall clock.
    RealTime,
}

/// Everything a view is built from.
pub struct Sources<'a> {
    /// The machine's name (from the harvester config).
    pub machine: &'a str,
    /// How time runs.
    pub clock: Clock,
    /// True once the run has reached its end (`--for`).
    pub finished: bool,
    /// The hub's state.
    pub snapshot: &'a Snapshot,
    /// What the monitor shows; `None` when the monitor is not emulated (`--without F5`).
    pub display: Option<&'a Display>,
    /// The plant, for the true values beside the monitor's.
    pub plant: &'a Plant,
    /// Per-identifier rates, already updated with `snapshot`.
    pub rates: &'a RateMeter,
    /// Crashes, restarts and power cycles so far.
    pub events: &'a [SupervisorEvent],
    /// The DBC database of a network imported from one: its messages name and decode the
    /// frames instead of the harvester catalogue.
    pub database: Option<&'a Database>,
}

/// The whole screen.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// The machine's name.
    pub machine: String,
    /// How time runs.
    pub clock: Clock,
    /// Bus time.
    pub now: BusTime,
    /// The run has reached its end.
    pub finished: bool,
    /// The cab monitor panel.
    pub monitor: MonitorView,
    /// The bus panel.
    pub bus: BusView,
}

/// One quantity: what the monitor shows beside the plant's true value.
#[derive(Clone, Debug, PartialEq)]
pub struct Reading {
    /// What it is.
    pub label: String,
    /// Unit.
    pub unit: &'static str,
    /// Decimals to show.
    pub decimals: usize,
    /// On the monitor (`None`: not received yet, or no monitor).
    pub shown: Option<f64>,
    /// In the plant (`None`: the plant has no such signal).
    pub truth: Option<f64>,
    /// A remark (a flow sensor's state and flow).
    pub note: String,
}

/// An active alarm.
#[derive(Clone, Debug, PartialEq)]
pub struct AlarmView {
    /// What (the catalogue field or the monitor's check).
    pub name: String,
    /// The node it concerns.
    pub node: String,
    /// When it was raised.
    pub raised: BusTime,
}

/// The cab monitor panel.
#[derive(Clone, Debug, PartialEq)]
pub struct MonitorView {
    /// False when the monitor is not emulated: only the plant's values are shown.
    pub present: bool,
    /// "power-up", "calibrating", "running".
    pub phase: String,
    /// Manual, cruise, unloading.
    pub drive_mode: Option<String>,
    /// Yield: total, kg/ha, area, feed, then one reading per row.
    pub yields: Vec<Reading>,
    /// Speeds, rpm, pressures, temperatures, levels, basket.
    pub machine: Vec<Reading>,
    /// Active alarms, oldest first.
    pub alarms: Vec<AlarmView>,
    /// Frames the monitor lost (its receive queue was full).
    pub frames_lost: u64,
}

/// One node on the bus.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeView {
    /// Name (its address, "F5" for the monitor).
    pub name: String,
    /// Error state.
    pub state: ErrorState,
    /// Transmit error counter.
    pub tec: u16,
    /// Receive error counter.
    pub rec: u16,
    /// Its logic crashed (and is not restarted yet).
    pub crashed: bool,
    /// Hung by fault injection.
    pub hung: bool,
}

/// A decoded payload field.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldView {
    /// Field name.
    pub name: String,
    /// Value with unit, or the name of the value.
    pub text: String,
}

/// One identifier seen on the bus.
#[derive(Clone, Debug, PartialEq)]
pub struct IdView {
    /// The identifier (11 or 29 bits).
    pub id: u32,
    /// A 29-bit identifier.
    pub extended: bool,
    /// Remote frames.
    pub remote: bool,
    /// The catalogue (or DBC) message of the last payload.
    pub message: Option<String>,
    /// Where it goes: a harvester identifier's source and destination (`D0>F5`), or a DBC
    /// message's transmitter.
    pub route: Option<String>,
    /// Frames per second, recently.
    pub rate: f64,
    /// Frames so far.
    pub count: u64,
    /// The last payload.
    pub payload: Vec<u8>,
    /// The last payload, decoded through the catalogue (or the DBC).
    pub fields: Vec<FieldView>,
    /// Why the last payload does not fit its message's layout.
    pub problem: Option<String>,
}

/// The bus panel.
#[derive(Clone, Debug, PartialEq)]
pub struct BusView {
    /// Load over the whole run, 0..=1.
    pub load: f64,
    /// Load over the last second, 0..=1.
    pub load_1s: f64,
    /// Frames.
    pub frames: u64,
    /// Error frames.
    pub error_frames: u64,
    /// Receive overruns, all nodes.
    pub overruns: u64,
    /// Nodes in attach order.
    pub nodes: Vec<NodeView>,
    /// Identifiers in arbitration order.
    pub ids: Vec<IdView>,
    /// The most recent supervisor events, as lines, oldest first.
    pub events: Vec<String>,
}

/// Supervisor events the bus panel lists.
const EVENTS_SHOWN: usize = 4;

impl View {
    /// Builds the view.
    pub fn build(s: &Sources) -> View {
        View {
            machine: s.machine.to_string(),
            clock: s.clock,
            now: s.snapshot.now,
            finished: s.finished,
            monitor: monitor(s.display, s.plant),
            bus: bus(s.snapshot, s.rates, s.events, s.database),
        }
    }
}

fn monitor(display: Option<&Display>, plant: &Plant) -> MonitorView {
    let truth = |name: &str| plant.signal(name);
    let d = display;
    let reading = |label: &str, unit, decimals, shown: Option<f64>, truth: Option<f64>| Reading {
        label: label.to_string(),
        unit,
        decimals,
        shown,
        truth,
        note: String::new(),
    };
    let mut yields = vec![
        reading(
            "harvested",
            "kg",
            1,
            d.map(|d| d.total_kg),
            truth("harvested.total"),
        ),
        reading("yield", "kg/ha", 0, d.and_then(|d| d.kg_per_ha), None),
        reading("area", "ha", 3, d.map(|d| d.area_ha), None),
        reading("feed", "kg/s", 2, d.map(|d| d.feed_kg_s), None),
    ];
    let rows = d.map_or(0, |d| d.rows.len()).max(ROWS);
    for r in 0..rows {
        let row = d.and_then(|d| d.rows.get(r));
        let mut y = reading(
            &format!("row {}", r + 1),
            "kg",
            1,
            row.map(|row| row.kg),
            truth(&format!("row{}.harvested", r + 1)),
        );
        if let Some(row) = row {
            let calibration = if row.calibrated { "" } else { ", uncalibrated" };
            y.note = format!("{:.0} g/s {}{calibration}", row.flow_g_s, row.sensor_state)
                .trim_end()
                .to_string();
        }
        yields.push(y);
    }
    let machine = vec![
        reading(
            "travel speed",
            "km/h",
            1,
            d.and_then(|d| d.speed_kmh),
            truth("speed.actual"),
        ),
        reading("wheel speed", "km/h", 1, d.and_then(|d| d.ground_speed_kmh), None),
        reading(
            "set-point",
            "km/h",
            1,
            d.and_then(|d| d.setpoint_kmh),
            truth("speed.setpoint_in_force"),
        ),
        reading(
            "engine",
            "rpm",
            0,
            d.and_then(|d| d.engine_rpm),
            truth("engine.rpm"),
        ),
        reading("fan", "rpm", 0, d.and_then(|d| d.fan_rpm), truth("fan.rpm")),
        reading(
            "front drums",
            "rpm",
            0,
            d.and_then(|d| d.front_drum_rpm),
            truth("drum.front_rpm"),
        ),
        reading(
            "rear drums",
            "rpm",
            0,
            d.and_then(|d| d.rear_drum_rpm),
            truth("drum.rear_rpm"),
        ),
        reading(
            "water pressure",
            "kPa",
            0,
            d.and_then(|d| d.water_pressure_kpa),
            truth("water.pressure"),
        ),
        reading(
            "water tank",
            "%",
            1,
            d.and_then(|d| d.water_level_pct),
            truth("water.level"),
        ),
        reading(
            "hydraulic oil",
            "°C",
            1,
            d.and_then(|d| d.oil_temperature_c),
            truth("oil.temperature"),
        ),
        reading(
            "grease rate",
            "mL/min",
            1,
            d.and_then(|d| d.lubricant_rate_ml_min),
            truth("lubricant.rate"),
        ),
        reading(
            "grease tank",
            "%",
            1,
            d.and_then(|d| d.lubricant_level_pct),
            truth("lubricant.level"),
        ),
        reading(
            "conveyor belt",
            "m/s",
            2,
            d.and_then(|d| d.belt_speed_m_s),
            truth("belt.speed"),
        ),
        reading(
            "basket",
            "%",
            1,
            d.and_then(|d| d.basket_fill_pct),
            truth("basket.fill"),
        ),
        reading(
            "row offset",
            "mm",
            0,
            d.and_then(|d| d.row_offset_mm),
            truth("row.offset"),
        ),
    ];
    let alarms = d.map_or(Vec::new(), |d| {
        d.active_alarms()
            .map(|a| AlarmView {
                name: a.name.clone(),
                node: a.node.clone(),
                raised: a.raised,
            })
            .collect()
    });
    MonitorView {
        present: d.is_some(),
        phase: d.map_or_else(|| "not emulated".to_string(), |d| d.phase.clone()),
        drive_mode: d.and_then(|d| d.drive_mode.clone()),
        yields,
        machine,
        alarms,
        frames_lost: d.map_or(0, |d| d.lost),
    }
}

fn bus(
    snapshot: &Snapshot,
    rates: &RateMeter,
    events: &[SupervisorEvent],
    database: Option<&Database>,
) -> BusView {
    let st = &snapshot.stats;
    let nodes = snapshot
        .nodes
        .iter()
        .map(|n| NodeView {
            name: n.name.clone(),
            state: n.state,
            tec: n.tec,
            rec: n.rec,
            crashed: n.crashed.is_some(),
            hung: n.hung,
        })
        .collect();
    let mut ids: Vec<(Option<Frame>, IdView)> = st
        .per_id
        .iter()
        .map(|(&kernel, stats)| {
            let frame = frame_of(kernel, stats.last_payload());
            (
                frame,
                match database {
                    Some(db) => dbc_identifier(db, kernel, frame, rates.rate(kernel, stats), stats.count),
                    None => identifier(kernel, frame, rates.rate(kernel, stats), stats.count),
                },
            )
        })
        .collect();
    // Arbitration order: the order in which the bus would let them through.
    ids.sort_by_key(|(f, v)| (f.map(|f| f.arbitration()), v.id));
    let events = events[events.len().saturating_sub(EVENTS_SHOWN)..]
        .iter()
        .map(|e| format!("{:.1} s {} {}", e.at.as_secs_f64(), e.node, e.what))
        .collect();
    BusView {
        load: st.total_load(),
        load_1s: st.window_load(BusDuration::from_secs(1)),
        frames: st.frames,
        error_frames: st.error_frames,
        overruns: st.overruns,
        nodes,
        ids: ids.into_iter().map(|(_, v)| v).collect(),
        events,
    }
}

/// The frame a kernel-form identifier and a payload stand for (a remote frame as a data frame
/// without data: only its identifier matters here).
fn frame_of(kernel: u32, payload: &[u8]) -> Option<Frame> {
    if kernel & CAN_EFF_FLAG != 0 {
        Frame::extended(kernel & CAN_EFF_MASK, payload).ok()
    } else {
        Frame::base((kernel & CAN_SFF_MASK) as u16, payload).ok()
    }
}

fn identifier(kernel: u32, frame: Option<Frame>, rate: f64, count: u64) -> IdView {
    let extended = kernel & CAN_EFF_FLAG != 0;
    let id = kernel & if extended { CAN_EFF_MASK } else { CAN_SFF_MASK };
    let mut view = IdView {
        id,
        extended,
        remote: kernel & CAN_RTR_FLAG != 0,
        message: None,
        route: None,
        rate,
        count,
        payload: frame.map(|f| f.data().to_vec()).unwrap_or_default(),
        fields: Vec::new(),
        problem: None,
    };
    if extended && let Ok(app) = AppId::from_raw(id) {
        view.route = Some(format!("{}>{}", app.source, app.destination));
    }
    let Some(frame) = frame else {
        return view;
    };
    match catalogue::decode(&frame) {
        Ok(Some(d)) => {
            view.message = Some(d.message.name.to_string());
            view.fields = d
                .values
                .iter()
                .filter(|v| v.field.constant.is_none())
                .map(|v| FieldView {
                    name: v.field.name.to_string(),
                    text: value_text(v),
                })
                .collect();
        }
        Ok(None) => {}
        Err(e) => {
            // The identifier and Data0 name the message even when the payload breaks it.
            if let Ok(app) = AppId::from_id(frame.id()) {
                view.message = catalogue::lookup(&app, frame.data()).map(|(m, _)| m.name.to_string());
            }
            view.problem = Some(e.to_string());
        }
    }
    view
}

/// An identifier of a DBC network: its message, transmitter and signals (those of the
/// multiplexor's page in a multiplexed message), each by its value name or physical value.
fn dbc_identifier(db: &Database, kernel: u32, frame: Option<Frame>, rate: f64, count: u64) -> IdView {
    let extended = kernel & CAN_EFF_FLAG != 0;
    let id = kernel & if extended { CAN_EFF_MASK } else { CAN_SFF_MASK };
    let message = db.messages.iter().find(|m| m.extended == extended && m.id == id);
    let mut view = IdView {
        id,
        extended,
        remote: kernel & CAN_RTR_FLAG != 0,
        message: message.map(|m| m.name.clone()),
        route: message.and_then(|m| m.transmitter.clone()),
        rate,
        count,
        payload: frame.map(|f| f.data().to_vec()).unwrap_or_default(),
        fields: Vec::new(),
        problem: None,
    };
    let (Some(m), Some(frame)) = (message, frame) else {
        return view;
    };
    let data = frame.data();
    for (s, raw) in m.decode(data) {
        let Some(raw) = raw else {
            view.problem = Some(format!("{} bytes: too short for {}", data.len(), s.name));
            break;
        };
        let text = match s.values.iter().find(|(v, _)| i128::from(*v) == raw) {
            Some((_, name)) => name.clone(),
            None if s.unit.is_empty() => format!("{:.*}", decimals(s.factor), s.physical(raw)),
            None => format!("{:.*} {}", decimals(s.factor), s.physical(raw), s.unit),
        };
        view.fields.push(FieldView {
            name: s.name.clone(),
            text,
        });
    }
    view
}

/// A field's value as the monitor would show it: its name if it has one, else the physical
/// value with as many decimals as its scaling gives, and its unit.
fn value_text(v: &Value) -> String {
    if let Some(label) = v.label() {
        return label.to_string();
    }
    let decimals = decimals(v.field.scale);
    let unit = v.field.unit;
    if unit.is_empty() {
        format!("{:.*}", decimals, v.physical)
    } else {
        format!("{:.*} {unit}", decimals, v.physical)
    }
}

/// Decimals needed to show multiples of `scale` exactly (at most 4).
pub(super) fn decimals(scale: f64) -> usize {
    (0..4)
        .find(|&d| {
            let x = scale.abs() * 10f64.powi(d as i32);
            (x - x.round()).abs() < 1e-9
        })
        .unwrap_or(4)
}
