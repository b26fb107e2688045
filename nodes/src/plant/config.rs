//! The plant's parameters, read from the run's RON config.

use serde::{Deserialize, Serialize};

/// Every parameter of the plant model. `Default` is the 4MZ-6A as harvemu models it; a RON file
/// only names what it changes (`()` is the default machine) and an unknown field is an error, so a
/// typo cannot silently leave a default in force.
///
/// Times are seconds unless the name says otherwise; a time constant is that of a first-order lag
/// (63 % of a step after one time constant).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlantConfig {
    /// Integration step [ms]: the plant's state changes only at whole multiples of it.
    pub step_ms: u64,

    /// Time constant of the ground speed's lag toward its target [s].
    pub speed_time_constant_s: f64,
    /// Initial position of the operator's speed lever, `operator.speed` [km/h].
    pub operator_speed_kmh: f64,
    /// Ground-speed wheel sensor pulses per metre travelled [1/m].
    pub pulses_per_metre: f64,

    /// Mean seed-cotton density along a row [kg/m] (0.38 = 5 t/ha at 0.76 m row spacing).
    pub base_density_kg_per_m: f64,
    /// Amplitude of the smooth seeded variation along the path, as a fraction of the density
    /// (0.2 = ±20 %); 0 makes a flat field.
    pub density_variation: f64,
    /// Wavelengths of the sinusoids that make up the variation along the path [m].
    pub variation_wavelengths_m: Vec<f64>,
    /// Largest seeded difference of one row from the mean, as a fraction (0.05 = ±5 %).
    pub row_variation: f64,
    /// Density steps `(from_distance_m, factor)`: from that distance travelled [m] on, the
    /// density is multiplied by `factor` (the step with the largest distance not beyond the
    /// position applies; before the first step the factor is 1).
    pub density_steps: Vec<(f64, f64)>,
    /// Fraction of the cotton on the plants that the spindles pick.
    pub pick_efficiency: f64,
    /// Fraction of drum speed, and so of picked cotton, that a row loses at
    /// `fault.rowN_clutch_slip` = 1 (the fault's value scales it).
    pub clutch_slip_fraction: f64,

    /// Basket capacity (kg); `basket.fill` is the mass in percent of it.
    pub basket_capacity_kg: f64,
    /// Rate at which unloading empties the basket with the conveyor belt at full speed [kg/s].
    pub unload_rate_kg_per_s: f64,
    /// Cotton in the basket at start (kg).
    pub basket_initial_kg: f64,

    /// Engine speed with the picking units disengaged [rpm].
    pub engine_idle_rpm: f64,
    /// Engine speed while picking with no cotton flow [rpm].
    pub engine_load_rpm: f64,
    /// Engine speed lost per kg/s of total cotton flow [rpm per kg/s].
    pub engine_droop_rpm_per_kg_s: f64,
    /// Time constant of the engine speed [s].
    pub engine_time_constant_s: f64,
    /// Fan speed at the loaded engine speed [rpm]; the fan is belt-driven, so it scales with the
    /// engine, and it stops with the main clutch open.
    pub fan_rpm: f64,
    /// Time constant of the fan speed [s].
    pub fan_time_constant_s: f64,
    /// Picking drum speed at standstill with the picking units engaged [rpm].
    pub drum_base_rpm: f64,
    /// Drum speed added per km/h of ground speed [rpm per km/h] (55 keeps 12 km/h inside the
    /// 0–1000 rpm range of `param.drums`).
    pub drum_rpm_per_kmh: f64,
    /// Rear drum speed as a fraction of the front drum's.
    pub rear_drum_ratio: f64,
    /// Time constant of the drum speeds [s].
    pub drum_time_constant_s: f64,

    /// Ambient temperature, where oil and coolant start (degC).
    pub ambient_temperature_c: f64,
    /// Hydraulic oil working temperature (degC).
    pub oil_working_temperature_c: f64,
    /// Rise of the oil's target temperature at `fault.oil_overheat` = 1 [K].
    pub oil_overheat_rise_c: f64,
    /// Time constant of the oil temperature [s].
    pub oil_time_constant_s: f64,
    /// Engine coolant working temperature (degC).
    pub engine_working_temperature_c: f64,
    /// Rise of the coolant's target temperature at `fault.engine_overheat` = 1 [K].
    pub engine_overheat_rise_c: f64,
    /// Time constant of the coolant temperature [s].
    pub engine_temperature_time_constant_s: f64,

    /// Spindle-moistener water pressure with a healthy supply (kPa).
    pub water_pressure_kpa: f64,
    /// Water pressure with the supply failed (`fault.low_water` = 1 or an empty tank) (kPa).
    pub water_failed_pressure_kpa: f64,
    /// Time constant of the water pressure [s].
    pub water_pressure_time_constant_s: f64,
    /// Water used while the picking units run [% of the tank per hour].
    pub water_use_percent_per_hour: f64,
    /// Water tank level at start [%].
    pub water_level_initial_percent: f64,

    /// Lubricant injected per drum rpm [mL/min per rpm].
    pub lubricant_ml_per_min_per_rpm: f64,
    /// Lubricant tank volume [L].
    pub lubricant_tank_l: f64,
    /// Leak at `fault.lubricant_low` = 1 [% of the tank per second].
    pub lubricant_leak_percent_per_s: f64,
    /// Lubricant tank level at start [%].
    pub lubricant_level_initial_percent: f64,

    /// Conveyor belt speed while running [m/s].
    pub belt_speed_m_s: f64,
    /// Time constant of the belt speed [s].
    pub belt_time_constant_s: f64,

    /// Standard deviation of the seeded lateral drift rate of the rows relative to the heads at
    /// the reference speed [mm/s].
    pub row_drift_mm_per_s: f64,
    /// Correlation time of the drift rate [s].
    pub row_drift_time_constant_s: f64,
    /// Lateral speed that 1 % of `row.correction` gives at the reference speed [mm/s per %].
    pub row_correction_mm_per_s_per_percent: f64,
    /// Ground speed at which drift and correction have their nominal rates; both scale with
    /// ground speed, so the offset does not change at a standstill [km/h].
    pub row_reference_speed_kmh: f64,

    /// Initial `sensor.target_reference`: the emitter level the flow sensors calibrate to [counts].
    pub target_reference: f64,
    /// Light attenuation per unit of reference level per g/s of cotton flow [1 per g/s].
    pub attenuation_per_g_s: f64,
    /// Standard deviation of a flow sensor unit's noise [counts].
    pub sensor_noise_counts: f64,
    /// Change of the units' reference levels as dust settles on them [% per hour of plant time].
    pub reference_drift_percent_per_hour: f64,
}

impl Default for PlantConfig {
    fn default() -> PlantConfig {
        PlantConfig {
            step_ms: 10,
            speed_time_constant_s: 2.0,
            operator_speed_kmh: 5.0,
            pulses_per_metre: 100.0,
            base_density_kg_per_m: 0.38,
            density_variation: 0.2,
            variation_wavelengths_m: vec![37.0, 91.0, 263.0],
            row_variation: 0.05,
            density_steps: Vec::new(),
            pick_efficiency: 0.95,
            clutch_slip_fraction: 0.4,
            basket_capacity_kg: 2500.0,
            unload_rate_kg_per_s: 50.0,
            basket_initial_kg: 0.0,
            engine_idle_rpm: 2400.0,
            engine_load_rpm: 2200.0,
            engine_droop_rpm_per_kg_s: 15.0,
            engine_time_constant_s: 1.5,
            fan_rpm: 3400.0,
            fan_time_constant_s: 3.0,
            drum_base_rpm: 300.0,
            drum_rpm_per_kmh: 55.0,
            rear_drum_ratio: 1.0,
            drum_time_constant_s: 0.5,
            ambient_temperature_c: 25.0,
            oil_working_temperature_c: 70.0,
            oil_overheat_rise_c: 50.0,
            oil_time_constant_s: 180.0,
            engine_working_temperature_c: 88.0,
            engine_overheat_rise_c: 35.0,
            engine_temperature_time_constant_s: 120.0,
            water_pressure_kpa: 350.0,
            water_failed_pressure_kpa: 80.0,
            water_pressure_time_constant_s: 2.0,
            water_use_percent_per_hour: 10.0,
            water_level_initial_percent: 100.0,
            lubricant_ml_per_min_per_rpm: 0.1,
            lubricant_tank_l: 60.0,
            lubricant_leak_percent_per_s: 2.0,
            lubricant_level_initial_percent: 100.0,
            belt_speed_m_s: 1.5,
            belt_time_constant_s: 0.3,
            row_drift_mm_per_s: 3.0,
            row_drift_time_constant_s: 10.0,
            row_correction_mm_per_s_per_percent: 0.5,
            row_reference_speed_kmh: 5.0,
            target_reference: 10000.0,
            attenuation_per_g_s: 0.004,
            sensor_noise_counts: 20.0,
            reference_drift_percent_per_hour: -0.5,
        }
    }
}

/// An accepted range of a parameter, inclusive.
#[derive(Clone, Copy)]
struct Range(f64, f64);

impl Range {
    fn contains(self, x: f64) -> bool {
        x.is_finite() && x >= self.0 && x <= self.1
    }
}

impl core::fmt::Display for Range {
    /// How a problem report describes the range.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match (self.0, self.1) {
            (f64::MIN, f64::MAX) => write!(f, "a finite number"),
            (f64::MIN_POSITIVE, f64::MAX) => write!(f, "positive"),
            (0.0, f64::MAX) => write!(f, "a number >= 0"),
            (lo, hi) => write!(f, "in {lo}..={hi}"),
        }
    }
}

/// Largest accepted step: beyond a second the lags and the flow integral stop being smooth.
const MAX_STEP_MS: u64 = 1000;

impl PlantConfig {
    /// Every problem with this config as (field, message); empty when there is none.
    pub fn validate(&self) -> Vec<(String, String)> {
        self.clone().repair()
    }

    /// The config with every invalid value replaced by its default (invalid density steps and
    /// wavelengths are dropped). `Plant::new` uses this so that a bad config cannot make the
    /// model panic or produce NaN; call `validate` first to report the problems.
    pub fn sanitized(&self) -> PlantConfig {
        let mut copy = self.clone();
        copy.repair();
        copy
    }

    /// Replaces invalid values, returning (field, message) for each.
    fn repair(&mut self) -> Vec<(String, String)> {
        let defaults = PlantConfig::default();
        let mut problems = Vec::new();
        if self.step_ms == 0 || self.step_ms > MAX_STEP_MS {
            problems.push((
                "step_ms".to_owned(),
                format!("{} is not in 1..={MAX_STEP_MS}", self.step_ms),
            ));
            self.step_ms = defaults.step_ms;
        }
        let unit = Range(0.0, 1.0);
        let positive = Range(f64::MIN_POSITIVE, f64::MAX);
        let non_negative = Range(0.0, f64::MAX);
        let percent = Range(0.0, 100.0);
        let any = Range(f64::MIN, f64::MAX);
        #[rustfmt::skip]
        let scalars = [
            ("speed_time_constant_s", &mut self.speed_time_constant_s, defaults.speed_time_constant_s, non_negative),
            ("operator_speed_kmh", &mut self.operator_speed_kmh, defaults.operator_speed_kmh, Range(0.0, super::MAX_OPERATOR_SPEED_KMH)),
            ("pulses_per_metre", &mut self.pulses_per_metre, defaults.pulses_per_metre, positive),
            ("base_density_kg_per_m", &mut self.base_density_kg_per_m, defaults.base_density_kg_per_m, non_negative),
            ("density_variation", &mut self.density_variation, defaults.density_variation, unit),
            ("row_variation", &mut self.row_variation, defaults.row_variation, unit),
            ("pick_efficiency", &mut self.pick_efficiency, defaults.pick_efficiency, unit),
            ("clutch_slip_fraction", &mut self.clutch_slip_fraction, defaults.clutch_slip_fraction, unit),
            ("basket_capacity_kg", &mut self.basket_capacity_kg, defaults.basket_capacity_kg, positive),
            ("unload_rate_kg_per_s", &mut self.unload_rate_kg_per_s, defaults.unload_rate_kg_per_s, non_negative),
            ("basket_initial_kg", &mut self.basket_initial_kg, defaults.basket_initial_kg, non_negative),
            ("engine_idle_rpm", &mut self.engine_idle_rpm, defaults.engine_idle_rpm, non_negative),
            ("engine_load_rpm", &mut self.engine_load_rpm, defaults.engine_load_rpm, positive),
            ("engine_droop_rpm_per_kg_s", &mut self.engine_droop_rpm_per_kg_s, defaults.engine_droop_rpm_per_kg_s, non_negative),
            ("engine_time_constant_s", &mut self.engine_time_constant_s, defaults.engine_time_constant_s, non_negative),
            ("fan_rpm", &mut self.fan_rpm, defaults.fan_rpm, positive),
            ("fan_time_constant_s", &mut self.fan_time_constant_s, defaults.fan_time_constant_s, non_negative),
            ("drum_base_rpm", &mut self.drum_base_rpm, defaults.drum_base_rpm, non_negative),
            ("drum_rpm_per_kmh", &mut self.drum_rpm_per_kmh, defaults.drum_rpm_per_kmh, non_negative),
            ("rear_drum_ratio", &mut self.rear_drum_ratio, defaults.rear_drum_ratio, non_negative),
            ("drum_time_constant_s", &mut self.drum_time_constant_s, defaults.drum_time_constant_s, non_negative),
            ("ambient_temperature_c", &mut self.ambient_temperature_c, defaults.ambient_temperature_c, Range(-40.0, 60.0)),
            ("oil_working_temperature_c", &mut self.oil_working_temperature_c, defaults.oil_working_temperature_c, Range(-40.0, 150.0)),
            ("oil_overheat_rise_c", &mut self.oil_overheat_rise_c, defaults.oil_overheat_rise_c, non_negative),
            ("oil_time_constant_s", &mut self.oil_time_constant_s, defaults.oil_time_constant_s, non_negative),
            ("engine_working_temperature_c", &mut self.engine_working_temperature_c, defaults.engine_working_temperature_c, Range(-40.0, 150.0)),
            ("engine_overheat_rise_c", &mut self.engine_overheat_rise_c, defaults.engine_overheat_rise_c, non_negative),
            ("engine_temperature_time_constant_s", &mut self.engine_temperature_time_constant_s, defaults.engine_temperature_time_constant_s, non_negative),
            ("water_pressure_kpa", &mut self.water_pressure_kpa, defaults.water_pressure_kpa, non_negative),
            ("water_failed_pressure_kpa", &mut self.water_failed_pressure_kpa, defaults.water_failed_pressure_kpa, non_negative),
            ("water_pressure_time_constant_s", &mut self.water_pressure_time_constant_s, defaults.water_pressure_time_constant_s, non_negative),
            ("water_use_percent_per_hour", &mut self.water_use_percent_per_hour, defaults.water_use_percent_per_hour, non_negative),
            ("water_level_initial_percent", &mut self.water_level_initial_percent, defaults.water_level_initial_percent, percent),
            ("lubricant_ml_per_min_per_rpm", &mut self.lubricant_ml_per_min_per_rpm, defaults.lubricant_ml_per_min_per_rpm, non_negative),
            ("lubricant_tank_l", &mut self.lubricant_tank_l, defaults.lubricant_tank_l, positive),
            ("lubricant_leak_percent_per_s", &mut self.lubricant_leak_percent_per_s, defaults.lubricant_leak_percent_per_s, non_negative),
            ("lubricant_level_initial_percent", &mut self.lubricant_level_initial_percent, defaults.lubricant_level_initial_percent, percent),
            ("belt_speed_m_s", &mut self.belt_speed_m_s, defaults.belt_speed_m_s, positive),
            ("belt_time_constant_s", &mut self.belt_time_constant_s, defaults.belt_time_constant_s, non_negative),
            ("row_drift_mm_per_s", &mut self.row_drift_mm_per_s, defaults.row_drift_mm_per_s, non_negative),
            ("row_drift_time_constant_s", &mut self.row_drift_time_constant_s, defaults.row_drift_time_constant_s, positive),
            ("row_correction_mm_per_s_per_percent", &mut self.row_correction_mm_per_s_per_percent, defaults.row_correction_mm_per_s_per_percent, non_negative),
            ("row_reference_speed_kmh", &mut self.row_reference_speed_kmh, defaults.row_reference_speed_kmh, positive),
            ("target_reference", &mut self.target_reference, defaults.target_reference, Range(1.0, 65535.0)),
            ("attenuation_per_g_s", &mut self.attenuation_per_g_s, defaults.attenuation_per_g_s, positive),
            ("sensor_noise_counts", &mut self.sensor_noise_counts, defaults.sensor_noise_counts, non_negative),
            ("reference_drift_percent_per_hour", &mut self.reference_drift_percent_per_hour, defaults.reference_drift_percent_per_hour, any),
        ];
        for (name, value, default, range) in scalars {
            if !range.contains(*value) {
                problems.push((name.to_owned(), format!("{value} is not {range}")));
                *value = default;
            }
        }
        let before = self.variation_wavelengths_m.len();
        self.variation_wavelengths_m.retain(|w| w.is_finite() && *w > 0.0);
        if self.variation_wavelengths_m.len() != before {
            problems.push((
                "variation_wavelengths_m".to_owned(),
                "every wavelength must be a positive number".to_owned(),
            ));
        }
        let before = self.density_steps.len();
        self.density_steps
            .retain(|(from, factor)| from.is_finite() && factor.is_finite() && *factor >= 0.0);
        if self.density_steps.len() != before {
            problems.push((
                "density_steps".to_owned(),
                "every step needs a finite distance and a non-negative factor".to_owned(),
            ));
        }
        problems
    }
}
