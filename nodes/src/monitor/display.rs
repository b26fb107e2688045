//! What the cab screen shows: one value that tests, reports and a terminal display read.

use bus::time::BusTime;
use serde::Serialize;

/// One row's yield meter.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RowYield {
    /// Seed cotton counted so far, kg.
    pub kg: f64,
    /// Latest flow, g/s.
    pub flow_g_s: f64,
    /// The sensor's state as it last reported it.
    pub sensor_state: String,
    /// Calibration accepted.
    pub calibrated: bool,
}

/// An alarm: raised, and cleared when the cause went away.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alarm {
    /// What (the catalogue field, or a monitor check such as "silent").
    pub name: String,
    /// The node that reported it (or that it is about).
    pub node: String,
    /// When it was raised (bus time of the frame that showed it).
    pub raised: BusTime,
    /// When it was cleared.
    pub cleared: Option<BusTime>,
}

/// The monitor's display. Values are `None` until their message has been received.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Display {
    /// Bus time of the last update.
    pub now: BusTime,
    /// Monitor phase: "power-up", "calibrating", "running".
    pub phase: String,
    /// Travel speed from the speed controller, km/h.
    pub speed_kmh: Option<f64>,
    /// Ground speed from the wheel (B0), km/h.
    pub ground_speed_kmh: Option<f64>,
    /// Set-point in force, km/h.
    pub setpoint_kmh: Option<f64>,
    /// Drive mode: manual, cruise, unloading.
    pub drive_mode: Option<String>,
    /// Engine speed, rpm.
    pub engine_rpm: Option<f64>,
    /// Fan speed, rpm.
    pub fan_rpm: Option<f64>,
    /// Front picking drums, rpm.
    pub front_drum_rpm: Option<f64>,
    /// Rear picking drums, rpm.
    pub rear_drum_rpm: Option<f64>,
    /// Spindle water pressure, kPa.
    pub water_pressure_kpa: Option<f64>,
    /// Water tank, %.
    pub water_level_pct: Option<f64>,
    /// Hydraulic oil, °C.
    pub oil_temperature_c: Option<f64>,
    /// Grease injection, mL/min.
    pub lubricant_rate_ml_min: Option<f64>,
    /// Grease tank, %.
    pub lubricant_level_pct: Option<f64>,
    /// Conveyor belt, m/s.
    pub belt_speed_m_s: Option<f64>,
    /// Basket, %.
    pub basket_fill_pct: Option<f64>,
    /// Row alignment state.
    pub row_alignment: Option<String>,
    /// Offset from the rows, mm.
    pub row_offset_mm: Option<f64>,
    /// Yield per row.
    pub rows: Vec<RowYield>,
    /// Yield, all rows, kg.
    pub total_kg: f64,
    /// Distance travelled while picking, m.
    pub distance_m: f64,
    /// Area harvested, ha.
    pub area_ha: f64,
    /// Yield per area, kg/ha.
    pub kg_per_ha: Option<f64>,
    /// Feed rate (all rows, filtered), kg/s.
    pub feed_kg_s: f64,
    /// Cruise control on.
    pub cruise: bool,
    /// Set-point cruise control sends, km/h.
    pub cruise_setpoint_kmh: Option<f64>,
    /// Alarms, active and past (the most recent 256).
    pub alarms: Vec<Alarm>,
    /// Frames received.
    pub frames: u64,
    /// Frames lost because the receive queue was full.
    pub lost: u64,
    /// Flow groups broken (a frame missing or out of order).
    pub broken_groups: u64,
    /// What became of every frame the receive interrupt got, since the first power-up (kept
    /// across restarts, unlike the rest of the screen).
    pub tally: FrameTally,
}

/// The monitor's books on the frames its receive interrupt got. Every frame is in exactly one
/// place: `received = queue_full + processed + queued + dropped_at_restart`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct FrameTally {
    /// Frames handed to the receive interrupt.
    pub received: u64,
    /// Lost because the queue was full.
    pub queue_full: u64,
    /// Taken from the queue by the main loop.
    pub processed: u64,
    /// In the queue now (or when the last logic stopped for good).
    pub queued: u64,
    /// In the queue of a logic that a restart or power cycle replaced.
    pub dropped_at_restart: u64,
}

impl FrameTally {
    /// True when every received frame is accounted for.
    pub fn balances(&self) -> bool {
        self.queue_full + self.processed + self.queued + self.dropped_at_restart == self.received
    }
}

impl Display {
    /// Alarms not cleared yet.
    pub fn active_alarms(&self) -> impl Iterator<Item = &Alarm> {
        self.alarms.iter().filter(|a| a.cleared.is_none())
    }
}
