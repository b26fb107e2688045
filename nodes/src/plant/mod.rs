//! The harvester plant: one deterministic, seeded model of the 4MZ-6A and its field that the 20
//! emulated nodes sample.
//!
//! # Contract
//!
//! - **Time.** The plant integrates on a fixed grid of `PlantConfig::step_ms` (10 ms by
//!   default). `advance_to(t)` takes every grid step up to the last grid time not after `t`;
//!   state changes only at grid times, so what `signal` returns at a time does not depend on who
//!   sampled before. Times earlier than `now()` are no-ops.
//! - **Inputs** (`set_input`) act from the first grid step after `now()`. To make that the step
//!   after the bus time of the command, advance to the bus time first (`set_input_at` does both).
//! - **Overrides** (`set_override`) force what `signal` returns for an output, for sensor and
//!   plant faults on the readings; the physics go on from the plant's own state, and flags derived
//!   from an overridden quantity keep following the plant (they come from separate switches).
//! - **Randomness** comes only from the seed: every random stream is derived from (seed,
//!   purpose), so the same seed and the same inputs at the same grid times give identical
//!   signals.
//! - No I/O, no clock reads; all floating-point work is plain `f64` arithmetic.
//!
//! # Signals
//!
//! Names are listed by [`Plant::signal_names`]; N is a row 1..=6 and K a sensor unit 1..=5.
//! Inputs: `speed.mode_request` (0 manual, 1 cruise), `speed.setpoint` [km/h, 0..=12],
//! `speed.unload` (0/1), `operator.speed` [km/h, 0..=12], `row.correction` [%, −100..=100],
//! `sensor.target_reference` [counts, 1..=65535], and the plant faults `fault.doorN_open`,
//! `fault.rowN_clutch_slip`, `fault.main_clutch_open`, `fault.belt_stop`, `fault.duct_blocked`,
//! `fault.low_water`, `fault.oil_overheat`, `fault.engine_overheat`, `fault.lubricant_low`, each a
//! magnitude in 0..=1 (0 healthy, 1 the full fault; any value above 0 closes the matching
//! switch where there is one).
//!
//! Outputs and their models (v = `speed.actual`):
//! - `speed.actual` [km/h]: lag (`speed_time_constant_s`) toward `speed.setpoint_in_force`, which is
//!   `operator.speed` in manual, `speed.setpoint` in cruise, 0 while unloading; `speed.mode`
//!   0 manual, 1 cruise, 2 unloading. `wheel.pulses` (Hz) = v / 3.6 × `pulses_per_metre`.
//! - `engine.rpm`: lag toward `engine_load_rpm` − `engine_droop_rpm_per_kg_s` × total flow [kg/s]
//!   while picking, `engine_idle_rpm` otherwise. `engine.temperature` (degC) (coolant): lag from
//!   ambient toward `engine_working_temperature_c` + fault × `engine_overheat_rise_c`.
//! - `fan.rpm`: lag toward `fan_rpm` × engine rpm / `engine_load_rpm`, 0 with the main clutch open.
//! - `drum.front_rpm`: mean over rows of each row's drum speed, which lags toward
//!   (`drum_base_rpm` + `drum_rpm_per_kmh` × v) × (1 − slip) while picking, 0 otherwise;
//!   `drum.rear_rpm` = front × `rear_drum_ratio`. slip = fault × `clutch_slip_fraction`.
//! - `water.pressure` (kPa): lag toward `water_pressure_kpa` − failure × (that −
//!   `water_failed_pressure_kpa`), failure = `fault.low_water` (1 once the tank is empty);
//!   `water.level` [%] falls by `water_use_percent_per_hour` while picking.
//! - `oil.temperature` (degC): lag from ambient toward `oil_working_temperature_c` + fault ×
//!   `oil_overheat_rise_c`.
//! - `lubricant.rate` [mL/min] = `lubricant_ml_per_min_per_rpm` × `drum.front_rpm`;
//!   `lubricant.level` [%] falls with what is injected (tank `lubricant_tank_l`) and with the
//!   leak `lubricant_leak_percent_per_s` × `fault.lubricant_low`. Levels never refill.
//! - `belt.speed` [m/s]: lag toward `belt_speed_m_s` × (1 − `fault.belt_stop`).
//! - `basket.mass` (kg): grows with the cotton reaching it; while unloading it falls at
//!   `unload_rate_kg_per_s` × belt speed / `belt_speed_m_s`. `basket.fill` [%] = mass /
//!   `basket_capacity_kg` (at most 100); `basket.level` (mV) = 500 + 40 × fill.
//! - `duct.vacuum` (mV) = 500 + 3000 × (fan / `fan_rpm`)² × (1 − 0.8 × `fault.duct_blocked`);
//!   `duct.holdup` (kg): cotton held by a blocked duct (it reaches the basket when the duct
//!   clears). `clutch.pressure` (mV): lag toward 3500 − 150 per slipping row, 500 with the main
//!   clutch open. `supply.voltage` (mV): 27600 with the engine above 500 rpm.
//! - Switches (0/1): `doorN.open`, `rowN.clutch_slip`, `main_clutch.open`, `duct.blocked` follow
//!   their faults; `belt.stopped` below 20 % of the belt speed; `basket.full` at fill ≥ 95 %;
//!   `basket.raised` while unloading; `water.low_pressure` below 150 kPa; `oil.overheat` above
//!   95 degC; `engine.overheat` above 105 degC; `lubricant.low` below 10 %.
//! - `row.offset` [mm]: d(offset)/dt = v / `row_reference_speed_kmh` × (drift +
//!   `row_correction_mm_per_s_per_percent` × `row.correction`), clamped to ±500; `row.drift`
//!   [mm/s] is a seeded Ornstein–Uhlenbeck process (σ `row_drift_mm_per_s`, correlation time
//!   `row_drift_time_constant_s`). The correction is a steering command in the offset's own
//!   direction (positive moves the heads toward positive offset), so the stabilising P law is
//!   correction = −k × offset, as the row alignment script `a0.ron` has it (k = 0.4 %/mm).
//! - Field (see `field.rs`): `field.distance` [m] = Σ v × dt; `rowN.density` [kg/m];
//!   `field.density` = mean over rows.
//! - Cotton: picked = density × v [m/s] × `pick_efficiency` × (1 − slip), 0 unless picking
//!   (main clutch closed and basket down). `rowN.flow` [g/s] = picked, 0 with the row's door open
//!   (then it counts into `harvested.lost` (kg)). `rowN.harvested` (kg) = ∫ of what reached the
//!   basket; `harvested.total` = their sum.
//! - Flow sensors (see `sensor.rs`): `rowN.refK`, `rowN.unitK` [counts]; a monitor recovers
//!   `rowN.flow` as mean_K(unitK / refK) / `attenuation_per_g_s`.

mod config;
mod field;
mod inputs;
mod model;
mod rng;
mod sensor;
mod signals;
#[cfg(test)]
mod tests;

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;

use bus::time::{BusDuration, BusTime};

pub use config::PlantConfig;
pub use inputs::InputRange;
use inputs::Inputs;
use model::Model;
use signals::{Output, Signal};

/// Number of crop rows, picking units and flow sensors.
pub const ROWS: usize = 6;
/// Detection units per flow sensor.
pub const UNITS: usize = 5;
/// Largest cruise set-point, `speed.setpoint` [km/h].
pub const MAX_SETPOINT_KMH: f64 = 12.0;
/// Largest operator lever position, `operator.speed` [km/h]; the same as the cruise limit so
/// that drum speeds stay within `param.drums`'s range.
pub const MAX_OPERATOR_SPEED_KMH: f64 = 12.0;

/// The plant shared by the nodes of one emulation, all on one thread.
pub type PlantHandle = Rc<RefCell<Plant>>;

/// Problems with a plant config as (field, message), every one of them; empty when it is valid.
pub fn validate(config: &PlantConfig) -> Vec<(String, String)> {
    config.validate()
}

/// Why the plant refused a request.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlantError {
    /// No signal has this name.
    #[error("unknown plant signal `{0}`")]
    UnknownSignal(String),
    /// The signal exists but is an output: only inputs can be set.
    #[error("plant signal `{0}` is an output, not an input")]
    NotAnInput(String),
    /// The signal exists but is an input: only outputs can be overridden (set inputs instead).
    #[error("plant signal `{0}` is an input and cannot be overridden")]
    NotAnOutput(String),
    /// The value is not a number or out of the input's range.
    #[error("value {value} is out of range for plant input `{name}`")]
    BadValue {
        /// Signal name.
        name: String,
        /// The refused value.
        value: f64,
    },
}

/// The harvester plant. See the module documentation for the contract and the models.
#[derive(Debug, Clone)]
pub struct Plant {
    model: Model,
    seed: u64,
    /// Grid step.
    step: BusDuration,
    /// Inputs as last set; copied into the model at each step.
    pending: Inputs,
    overrides: BTreeMap<Output, f64>,
}

impl Plant {
    /// The plant at time zero under `seed`. Invalid config values are replaced by their
    /// defaults (see [`PlantConfig::sanitized`]); validate the config first to report them.
    pub fn new(config: PlantConfig, seed: u64) -> Plant {
        let config = config.sanitized();
        let step = BusDuration::from_millis(config.step_ms);
        let model = Model::new(config, seed);
        Plant {
            pending: model.state.applied,
            model,
            seed,
            step,
            overrides: BTreeMap::new(),
        }
    }

    /// A new plant behind a shared handle.
    pub fn shared(config: PlantConfig, seed: u64) -> PlantHandle {
        Rc::new(RefCell::new(Plant::new(config, seed)))
    }

    /// The config in force (after sanitizing).
    pub fn config(&self) -> &PlantConfig {
        &self.model.config
    }

    /// The seed the plant was built with.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Integrates up to the last grid time not after `t`. Earlier times are no-ops, and so is
    /// `BusTime::NEVER`, which is not a time. Each grid interval costs one step, so callers
    /// should advance as bus time passes rather than jump far ahead.
    pub fn advance_to(&mut self, t: BusTime) {
        if t == BusTime::NEVER {
            return;
        }
        let target = t.elapsed() / self.step;
        while self.model.state.steps < target {
            self.model.step(&self.pending);
        }
    }

    /// The first grid time after `t`: when the outputs next change.
    pub fn next_step(&self, t: BusTime) -> BusTime {
        if t == BusTime::NEVER {
            return BusTime::NEVER;
        }
        let next = (t.elapsed() / self.step).saturating_add(1);
        self.step.checked_mul(next).map_or(BusTime::NEVER, BusTime::at)
    }

    /// The last grid time reached.
    pub fn now(&self) -> BusTime {
        BusTime::at(self.step * self.model.state.steps)
    }

    /// Current value of a named output (its override if one is set) or of an input (as last
    /// set); `None` for an unknown name.
    pub fn signal(&self, name: &str) -> Option<f64> {
        self.value_of(signals::lookup(name)?)
    }

    /// The port of a named signal, for reads and writes without the name
    /// ([`Plant::read_port`]); `None` for an unknown name.
    pub fn port(name: &str) -> Option<crate::script::Port> {
        signals::port(name).map(crate::script::Port)
    }

    /// [`Plant::signal`] by port; `None` for a port that is not the plant's.
    pub fn read_port(&self, port: crate::script::Port) -> Option<f64> {
        self.value_of(signals::signal(port.0)?)
    }

    /// [`Plant::set_input`] by port: false for an output, a port that is not the plant's, or a
    /// value the input does not take.
    pub fn write_port(&mut self, port: crate::script::Port, value: f64) -> bool {
        match signals::signal(port.0) {
            Some(Signal::In(input)) => self.pending.set(input, value),
            _ => false,
        }
    }

    fn value_of(&self, signal: Signal) -> Option<f64> {
        match signal {
            Signal::In(input) => self.pending.get(input),
            Signal::Out(output) => Some(
                self.overrides
                    .get(&output)
                    .copied()
                    .unwrap_or_else(|| self.model.value(output)),
            ),
        }
    }

    /// Sets an actuator input or plant fault; it acts from the first grid step after `now()`.
    pub fn set_input(&mut self, name: &str, value: f64) -> Result<(), PlantError> {
        match signals::lookup(name) {
            None => Err(PlantError::UnknownSignal(name.to_owned())),
            Some(Signal::Out(_)) => Err(PlantError::NotAnInput(name.to_owned())),
            Some(Signal::In(input)) => {
                if self.pending.set(input, value) {
                    Ok(())
                } else {
                    Err(PlantError::BadValue {
                        name: name.to_owned(),
                        value,
                    })
                }
            }
        }
    }

    /// Advances to `t`, then sets the input: it acts from the first grid step after `t`.
    pub fn set_input_at(&mut self, t: BusTime, name: &str, value: f64) -> Result<(), PlantError> {
        self.advance_to(t);
        self.set_input(name, value)
    }

    /// Forces an output to `Some(value)` (any finite number: a faulty sensor may read anything)
    /// or releases it with `None`. The plant's physics are unaffected.
    pub fn set_override(&mut self, name: &str, value: Option<f64>) -> Result<(), PlantError> {
        let output = match signals::lookup(name) {
            None => return Err(PlantError::UnknownSignal(name.to_owned())),
            Some(Signal::In(_)) => return Err(PlantError::NotAnOutput(name.to_owned())),
            Some(Signal::Out(output)) => output,
        };
        match value {
            Some(v) if !v.is_finite() => Err(PlantError::BadValue {
                name: name.to_owned(),
                value: v,
            }),
            Some(v) => {
                self.overrides.insert(output, v);
                Ok(())
            }
            None => {
                self.overrides.remove(&output);
                Ok(())
            }
        }
    }

    /// Every valid signal name, inputs first.
    pub fn signal_names() -> Vec<String> {
        signals::names()
    }

    /// Whether `name` is a signal of the plant, input or output.
    pub fn is_signal(name: &str) -> bool {
        signals::lookup(name).is_some()
    }

    /// Whether `name` is a writable input (false for outputs and unknown names).
    pub fn is_input(name: &str) -> bool {
        matches!(signals::lookup(name), Some(Signal::In(_)))
    }

    /// The values the input `name` takes (`None` for outputs and unknown names): what
    /// [`Plant::set_input`] accepts, so that a value can be checked before a run.
    pub fn input_range(name: &str) -> Option<InputRange> {
        match signals::lookup(name)? {
            Signal::In(input) => Some(InputRange::of(input)),
            Signal::Out(_) => None,
        }
    }
}
