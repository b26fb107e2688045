//! The plant's state and its fixed-step integration.
//!
//! Each step of `dt` first takes a snapshot of the inputs (so a value set between grid times
//! acts from the next step on, whoever sampled in between), then advances, in this order:
//! speed, distance, cotton flow and its destinations, basket, engine, fan, drums, water, oil,
//! coolant, lubricant, belt, clutch pressure, row offset and sensor noise. Lags use the exact
//! discretisation of a first-order lag, `x += (target − x)(1 − e^(−dt/τ))`, so they are stable
//! for any step. Quantities that follow from the state alone (flags, sensor voltages, unit
//! counts) are computed when read.

use rand_chacha::ChaCha8Rng;

use super::config::PlantConfig;
use super::field::Field;
use super::inputs::Inputs;
use super::rng;
use super::sensor::FlowSensors;
use super::signals::Output;
use super::{ROWS, UNITS};

/// Water pressure below which the low-pressure switch closes (kPa).
pub(crate) const LOW_WATER_PRESSURE_KPA: f64 = 150.0;
/// Oil temperature above which the overheat switch closes (degC).
pub(crate) const OIL_OVERHEAT_C: f64 = 95.0;
/// Coolant temperature above which the engine overheat switch closes (degC).
pub(crate) const ENGINE_OVERHEAT_C: f64 = 105.0;
/// Lubricant level below which the low-level switch closes [%].
pub(crate) const LUBRICANT_LOW_PERCENT: f64 = 10.0;
/// Basket fill at and above which the full switch closes [%].
pub(crate) const BASKET_FULL_PERCENT: f64 = 95.0;
/// The belt motion switch reports "stopped" below this fraction of the running speed.
const BELT_STOPPED_FRACTION: f64 = 0.2;
/// Hydraulic clutch pressure sensor with the main clutch engaged and released (mV).
const CLUTCH_ENGAGED_MV: f64 = 3500.0;
const CLUTCH_RELEASED_MV: f64 = 500.0;
/// Clutch pressure lost per fully slipping row clutch (a slipping clutch bleeds the circuit) (mV).
const CLUTCH_SLIP_LOSS_MV: f64 = 150.0;
/// Time constant of the clutch pressure [s].
const CLUTCH_TIME_CONSTANT_S: f64 = 0.3;
/// Duct vacuum sensor: offset, span at the nominal fan speed, and the share of the span a
/// blocked duct takes away (the sensor sits upstream of the blockage, on the heads' side) (mV).
const VACUUM_OFFSET_MV: f64 = 500.0;
const VACUUM_SPAN_MV: f64 = 3000.0;
const VACUUM_BLOCKED_LOSS: f64 = 0.8;
/// Basket level sensor: 0.5 V empty to 4.5 V full (mV).
const BASKET_LEVEL_EMPTY_MV: f64 = 500.0;
const BASKET_LEVEL_FULL_MV: f64 = 4500.0;
/// Supply voltage with the alternator charging, and of the battery alone (mV).
const SUPPLY_CHARGING_MV: f64 = 27600.0;
const SUPPLY_BATTERY_MV: f64 = 24000.0;
/// Engine speed from which the alternator charges [rpm].
const ALTERNATOR_CUT_IN_RPM: f64 = 500.0;
/// Bound of the row offset [mm]: the heads' mechanical travel, and `row.status`'s range.
pub(crate) const ROW_OFFSET_LIMIT_MM: f64 = 500.0;

/// The integrated state at the last grid time.
#[derive(Debug, Clone)]
pub(crate) struct State {
    /// Grid steps taken.
    pub steps: u64,
    /// Inputs in force during the last step.
    pub applied: Inputs,
    pub speed_kmh: f64,
    pub distance_m: f64,
    pub engine_rpm: f64,
    pub engine_temperature_c: f64,
    pub fan_rpm: f64,
    pub drum_rpm: [f64; ROWS],
    pub water_pressure_kpa: f64,
    pub water_level_percent: f64,
    pub oil_temperature_c: f64,
    pub lubricant_level_percent: f64,
    pub belt_speed_m_s: f64,
    pub clutch_pressure_mv: f64,
    pub basket_kg: f64,
    /// Cotton held in the blocked duct, per row (kg).
    pub holdup_kg: [f64; ROWS],
    pub harvested_kg: [f64; ROWS],
    pub lost_kg: f64,
    pub row_offset_mm: f64,
    pub row_drift_mm_s: f64,
    /// Flow reaching each row's duct during the last step [g/s].
    pub flow_g_s: [f64; ROWS],
}

/// First-order lag factor for a step `dt` and time constant `tau` [s].
fn alpha(dt: f64, tau: f64) -> f64 {
    if tau > 0.0 { 1.0 - (-dt / tau).exp() } else { 1.0 }
}

/// Moves `x` toward `target` by the lag factor `a`.
fn lag(x: &mut f64, target: f64, a: f64) {
    *x += (target - *x) * a;
}

/// Whether a fault magnitude is active.
fn on(fault: f64) -> bool {
    fault > 0.0
}

/// Everything the plant is: parameters, seeded constants, random streams and state.
#[derive(Debug, Clone)]
pub(crate) struct Model {
    pub config: PlantConfig,
    /// Step [s].
    dt: f64,
    field: Field,
    sensors: FlowSensors,
    drift_rng: ChaCha8Rng,
    pub state: State,
}

impl Model {
    /// The plant at time zero: engine running at the loaded speed with the picking units
    /// engaged, machine at rest, oil and coolant at ambient temperature.
    pub(crate) fn new(config: PlantConfig, seed: u64) -> Model {
        let c = &config;
        let mut drift_rng = rng::stream(seed, "row.drift");
        // Start the drift rate from its stationary distribution.
        let row_drift_mm_s = c.row_drift_mm_per_s * rng::gaussian(&mut drift_rng);
        let state = State {
            steps: 0,
            applied: Inputs::initial(c.operator_speed_kmh, c.target_reference),
            speed_kmh: 0.0,
            distance_m: 0.0,
            engine_rpm: c.engine_load_rpm,
            engine_temperature_c: c.ambient_temperature_c,
            fan_rpm: c.fan_rpm,
            drum_rpm: [c.drum_base_rpm; ROWS],
            water_pressure_kpa: c.water_pressure_kpa,
            water_level_percent: c.water_level_initial_percent,
            oil_temperature_c: c.ambient_temperature_c,
            lubricant_level_percent: c.lubricant_level_initial_percent,
            belt_speed_m_s: c.belt_speed_m_s,
            clutch_pressure_mv: CLUTCH_ENGAGED_MV,
            basket_kg: c.basket_initial_kg,
            holdup_kg: [0.0; ROWS],
            harvested_kg: [0.0; ROWS],
            lost_kg: 0.0,
            row_offset_mm: 0.0,
            row_drift_mm_s,
            flow_g_s: [0.0; ROWS],
        };
        Model {
            dt: c.step_ms as f64 / 1000.0,
            field: Field::new(c, seed),
            sensors: FlowSensors::new(c, seed),
            drift_rng,
            state,
            config,
        }
    }

    /// Speed mode of the applied inputs: 0 manual, 1 cruise, 2 unloading.
    fn mode(&self) -> f64 {
        let i = &self.state.applied;
        if i.unload >= 0.5 { 2.0 } else { i.mode_request }
    }

    /// Ground speed the controller drives toward [km/h].
    fn target_speed(&self) -> f64 {
        let i = &self.state.applied;
        match self.mode() {
            m if m >= 2.0 => 0.0,
            m if m >= 1.0 => i.setpoint,
            _ => i.operator_speed,
        }
    }

    /// Whether the picking units run: main clutch closed and basket down.
    fn picking(&self) -> bool {
        let i = &self.state.applied;
        !on(i.faults.main_clutch_open) && i.unload < 0.5
    }

    /// Fraction of drum speed row `r` loses to its slipping clutch.
    fn slip(&self, r: usize) -> f64 {
        let f = self
            .state
            .applied
            .faults
            .clutch_slip
            .get(r)
            .copied()
            .unwrap_or(0.0);
        f.clamp(0.0, 1.0) * self.config.clutch_slip_fraction
    }

    /// Plant time of the last step [h].
    fn hours(&self) -> f64 {
        self.state.steps as f64 * self.dt / 3600.0
    }

    /// Advances one grid step with `inputs` in force.
    pub(crate) fn step(&mut self, inputs: &Inputs) {
        let dt = self.dt;
        let c = &self.config;
        let a_speed = alpha(dt, c.speed_time_constant_s);
        let a_engine = alpha(dt, c.engine_time_constant_s);
        let a_fan = alpha(dt, c.fan_time_constant_s);
        let a_drum = alpha(dt, c.drum_time_constant_s);
        let a_water = alpha(dt, c.water_pressure_time_constant_s);
        let a_oil = alpha(dt, c.oil_time_constant_s);
        let a_coolant = alpha(dt, c.engine_temperature_time_constant_s);
        let a_belt = alpha(dt, c.belt_time_constant_s);
        let a_clutch = alpha(dt, CLUTCH_TIME_CONSTANT_S);

        self.state.applied = *inputs;
        self.state.steps += 1;
        let target_speed = self.target_speed();
        let picking = self.picking();
        let slip: [f64; ROWS] = core::array::from_fn(|r| self.slip(r));
        let c = &self.config;
        let f = inputs.faults;
        let s = &mut self.state;

        // Ground speed, then distance with the new speed (so distance = Σ speed × dt exactly).
        lag(&mut s.speed_kmh, target_speed, a_speed);
        let v = s.speed_kmh / 3.6;
        s.distance_m += v * dt;

        // Cotton: picked at the heads, lost through an open door, else into the duct; a
        // blocked duct holds it back until it clears, then it all reaches the basket.
        let density = self.field.densities(s.distance_m);
        let blocked = on(f.duct_blocked);
        let mut total_kg_s = 0.0;
        for r in 0..ROWS {
            let picked = if picking {
                density[r] * v * c.pick_efficiency * (1.0 - slip[r])
            } else {
                0.0
            };
            let reaching = if on(f.door_open[r]) {
                s.lost_kg += picked * dt;
                0.0
            } else {
                picked
            };
            s.flow_g_s[r] = reaching * 1000.0;
            total_kg_s += reaching;
            let arrived = if blocked {
                s.holdup_kg[r] += reaching * dt;
                0.0
            } else {
                reaching * dt + core::mem::take(&mut s.holdup_kg[r])
            };
            s.harvested_kg[r] += arrived;
            s.basket_kg += arrived;
        }

        // Unloading: the basket floor conveyor pushes the cotton out, at the belt's pace.
        if inputs.unload >= 0.5 {
            let out = c.unload_rate_kg_per_s * (s.belt_speed_m_s / c.belt_speed_m_s) * dt;
            s.basket_kg = (s.basket_kg - out).max(0.0);
        }

        let engine_target = if picking {
            (c.engine_load_rpm - c.engine_droop_rpm_per_kg_s * total_kg_s).max(0.0)
        } else {
            c.engine_idle_rpm
        };
        lag(&mut s.engine_rpm, engine_target, a_engine);
        let fan_target = if on(f.main_clutch_open) {
            0.0
        } else {
            c.fan_rpm * s.engine_rpm / c.engine_load_rpm
        };
        lag(&mut s.fan_rpm, fan_target, a_fan);
        let synchronous = c.drum_base_rpm + c.drum_rpm_per_kmh * s.speed_kmh;
        for (drum, slip) in s.drum_rpm.iter_mut().zip(slip) {
            let target = if picking { synchronous * (1.0 - slip) } else { 0.0 };
            lag(drum, target, a_drum);
        }

        if picking {
            s.water_level_percent =
                (s.water_level_percent - c.water_use_percent_per_hour / 3600.0 * dt).max(0.0);
        }
        let supply_failure = if s.water_level_percent <= 0.0 {
            1.0
        } else {
            f.low_water.clamp(0.0, 1.0)
        };
        let pressure_target =
            c.water_pressure_kpa - supply_failure * (c.water_pressure_kpa - c.water_failed_pressure_kpa);
        lag(&mut s.water_pressure_kpa, pressure_target, a_water);

        let oil_target = c.oil_working_temperature_c + f.oil_overheat.clamp(0.0, 1.0) * c.oil_overheat_rise_c;
        lag(&mut s.oil_temperature_c, oil_target, a_oil);
        let coolant_target =
            c.engine_working_temperature_c + f.engine_overheat.clamp(0.0, 1.0) * c.engine_overheat_rise_c;
        lag(&mut s.engine_temperature_c, coolant_target, a_coolant);

        // Lubricant: injection drawn from the tank, plus the leak of the fault.
        let rate_ml_min = c.lubricant_ml_per_min_per_rpm * mean(&s.drum_rpm);
        let used_percent = rate_ml_min / 60.0 * dt / (c.lubricant_tank_l * 1000.0) * 100.0;
        let leak_percent = c.lubricant_leak_percent_per_s * f.lubricant_low.clamp(0.0, 1.0) * dt;
        s.lubricant_level_percent = (s.lubricant_level_percent - used_percent - leak_percent).max(0.0);

        let belt_target = c.belt_speed_m_s * (1.0 - f.belt_stop.clamp(0.0, 1.0));
        lag(&mut s.belt_speed_m_s, belt_target, a_belt);

        let clutch_target = if on(f.main_clutch_open) {
            CLUTCH_RELEASED_MV
        } else {
            CLUTCH_ENGAGED_MV
                - CLUTCH_SLIP_LOSS_MV * f.clutch_slip.iter().map(|x| x.clamp(0.0, 1.0)).sum::<f64>()
        };
        lag(&mut s.clutch_pressure_mv, clutch_target, a_clutch);

        // Row offset: the drift rate is an Ornstein–Uhlenbeck process (exact discretisation);
        // drift and steering both act in proportion to ground speed.
        let tau = c.row_drift_time_constant_s;
        let decay = (-dt / tau).exp();
        let kick = c.row_drift_mm_per_s * (1.0 - decay * decay).sqrt() * rng::gaussian(&mut self.drift_rng);
        s.row_drift_mm_s = s.row_drift_mm_s * decay + kick;
        let lateral =
            s.row_drift_mm_s + c.row_correction_mm_per_s_per_percent * inputs.correction.clamp(-100.0, 100.0);
        s.row_offset_mm = (s.row_offset_mm + s.speed_kmh / c.row_reference_speed_kmh * lateral * dt)
            .clamp(-ROW_OFFSET_LIMIT_MM, ROW_OFFSET_LIMIT_MM);

        self.sensors.draw_noise();
    }

    /// Current value of an output, from the state at the last grid time.
    pub(crate) fn value(&self, output: Output) -> f64 {
        let s = &self.state;
        let c = &self.config;
        let f = &s.applied.faults;
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        let row = |a: &[f64; ROWS], r: usize| a.get(r).copied().unwrap_or(0.0);
        let fill = (s.basket_kg / c.basket_capacity_kg * 100.0).min(100.0);
        match output {
            Output::SpeedActual => s.speed_kmh,
            Output::SpeedMode => self.mode(),
            Output::SetpointInForce => self.target_speed(),
            Output::WheelPulses => s.speed_kmh / 3.6 * c.pulses_per_metre,
            Output::EngineRpm => s.engine_rpm,
            Output::EngineTemperature => s.engine_temperature_c,
            Output::FanRpm => s.fan_rpm,
            Output::DrumFrontRpm => mean(&s.drum_rpm),
            Output::DrumRearRpm => mean(&s.drum_rpm) * c.rear_drum_ratio,
            Output::WaterPressure => s.water_pressure_kpa,
            Output::WaterLevel => s.water_level_percent,
            Output::OilTemperature => s.oil_temperature_c,
            Output::LubricantRate => c.lubricant_ml_per_min_per_rpm * mean(&s.drum_rpm),
            Output::LubricantLevel => s.lubricant_level_percent,
            Output::BeltSpeed => s.belt_speed_m_s,
            Output::BasketMass => s.basket_kg,
            Output::BasketFill => fill,
            Output::BasketLevel => {
                BASKET_LEVEL_EMPTY_MV + (BASKET_LEVEL_FULL_MV - BASKET_LEVEL_EMPTY_MV) * fill / 100.0
            }
            Output::DuctVacuum => {
                let fan = s.fan_rpm / c.fan_rpm;
                let open = 1.0 - VACUUM_BLOCKED_LOSS * f.duct_blocked.clamp(0.0, 1.0);
                (VACUUM_OFFSET_MV + VACUUM_SPAN_MV * fan * fan * open).clamp(0.0, 5000.0)
            }
            Output::DuctHoldup => s.holdup_kg.iter().sum(),
            Output::ClutchPressure => s.clutch_pressure_mv,
            Output::SupplyVoltage => {
                if s.engine_rpm >= ALTERNATOR_CUT_IN_RPM {
                    SUPPLY_CHARGING_MV
                } else {
                    SUPPLY_BATTERY_MV
                }
            }
            Output::DoorOpen(r) => flag(on(row(&f.door_open, r))),
            Output::RowClutchSlip(r) => flag(on(row(&f.clutch_slip, r))),
            Output::MainClutchOpen => flag(on(f.main_clutch_open)),
            Output::BeltStopped => flag(s.belt_speed_m_s < BELT_STOPPED_FRACTION * c.belt_speed_m_s),
            Output::BasketFull => flag(fill >= BASKET_FULL_PERCENT),
            Output::BasketRaised => flag(s.applied.unload >= 0.5),
            Output::DuctBlocked => flag(on(f.duct_blocked)),
            Output::WaterLowPressure => flag(s.water_pressure_kpa < LOW_WATER_PRESSURE_KPA),
            Output::OilOverheat => flag(s.oil_temperature_c > OIL_OVERHEAT_C),
            Output::EngineOverheat => flag(s.engine_temperature_c > ENGINE_OVERHEAT_C),
            Output::LubricantLow => flag(s.lubricant_level_percent < LUBRICANT_LOW_PERCENT),
            Output::RowOffset => s.row_offset_mm,
            Output::RowDrift => s.row_drift_mm_s,
            Output::FieldDistance => s.distance_m,
            Output::FieldDensity => mean(&self.field.densities(s.distance_m)),
            Output::RowDensity(r) => self.field.row_density(r, s.distance_m),
            Output::RowFlow(r) => row(&s.flow_g_s, r),
            Output::RowHarvested(r) => row(&s.harvested_kg, r),
            Output::HarvestedTotal => s.harvested_kg.iter().sum(),
            Output::HarvestedLost => s.lost_kg,
            Output::RowReference(r, k) => self.reference(r, k),
            Output::RowUnit(r, k) => self.sensors.unit(r, k, row(&s.flow_g_s, r), self.reference(r, k)),
        }
    }

    /// Reference level of unit `k` of row `r` [counts].
    fn reference(&self, r: usize, k: usize) -> f64 {
        if k >= UNITS {
            return 0.0;
        }
        self.sensors
            .reference(r, k, self.state.applied.target_reference, self.hours())
    }

    /// The flow sensors, for tests.
    #[cfg(test)]
    pub(crate) fn sensors(&self) -> &FlowSensors {
        &self.sensors
    }
}

/// Mean of the six rows' values.
fn mean(a: &[f64; ROWS]) -> f64 {
    a.iter().sum::<f64>() / ROWS as f64
}
