//! The near-infrared flow sensors: five detection units per row.
//!
//! For row r and unit k (all in counts, rounded to whole counts as a 16-bit ADC gives them):
//!
//!   refK  = target_reference × factor[r][k] × max(0, 1 + dust × hours)
//!   unitK = clamp(flow [g/s] × refK × attenuation × weight[r][k] + noise, 0, 65535),
//!           and exactly 0 when the flow is 0 (an empty duct attenuates nothing)
//!
//! with `factor` seeded in 0.75..1.15 (the source's example references 7732..11503 at a
//! 10000 target), `weight` seeded within ±10 % and averaging exactly 1 over the five units (how
//! the cotton spreads across the duct), and `noise` Gaussian with the configured sigma, drawn
//! afresh at every plant step. A monitor therefore recovers the flow as
//!
//!   flow [g/s] ≈ mean_k(unitK / refK) / attenuation
//!
//! exactly up to noise, rounding and saturation at 65535.

use rand_chacha::ChaCha8Rng;

use super::config::PlantConfig;
use super::rng;
use super::{ROWS, UNITS};

/// Lowest and highest seeded reference factor.
const FACTOR_RANGE: (f64, f64) = (0.75, 1.15);
/// Largest deviation of a distribution weight from 1.
const WEIGHT_SPREAD: f64 = 0.10;
/// Full scale of a unit's 16-bit value [counts].
const FULL_SCALE: f64 = 65535.0;

/// The seeded constants of the six sensors and their noise streams.
#[derive(Debug, Clone)]
pub(crate) struct FlowSensors {
    factor: [[f64; UNITS]; ROWS],
    weight: [[f64; UNITS]; ROWS],
    noise_rng: Vec<ChaCha8Rng>,
    /// This step's noise [counts].
    noise: [[f64; UNITS]; ROWS],
    sigma: f64,
    attenuation: f64,
    dust_per_hour: f64,
}

impl FlowSensors {
    /// The sensors of `config` under the run seed.
    pub(crate) fn new(config: &PlantConfig, seed: u64) -> FlowSensors {
        let mut factor = [[0.0; UNITS]; ROWS];
        let mut weight = [[0.0; UNITS]; ROWS];
        for r in 0..ROWS {
            let mut g = rng::stream(seed, &format!("sensor{}.constants", r + 1));
            for f in &mut factor[r] {
                let u = (rng::symmetric(&mut g) + 1.0) / 2.0;
                *f = FACTOR_RANGE.0 + u * (FACTOR_RANGE.1 - FACTOR_RANGE.0);
            }
            // Half-width draws re-centred on their mean: the mean is 1 and each stays within
            // ±WEIGHT_SPREAD.
            let mut d = [0.0; UNITS];
            for x in &mut d {
                *x = rng::symmetric(&mut g) * WEIGHT_SPREAD / 2.0;
            }
            let mean = d.iter().sum::<f64>() / UNITS as f64;
            weight[r] = d.map(|x| 1.0 + x - mean);
        }
        let noise_rng = (0..ROWS)
            .map(|r| rng::stream(seed, &format!("sensor{}.noise", r + 1)))
            .collect();
        FlowSensors {
            factor,
            weight,
            noise_rng,
            noise: [[0.0; UNITS]; ROWS],
            sigma: config.sensor_noise_counts,
            attenuation: config.attenuation_per_g_s,
            dust_per_hour: config.reference_drift_percent_per_hour / 100.0,
        }
    }

    /// Draws this step's noise for every unit. Called once per step whatever the flow, so the
    /// streams do not depend on what the machine did.
    pub(crate) fn draw_noise(&mut self) {
        for (row, g) in self.noise.iter_mut().zip(&mut self.noise_rng) {
            for n in row {
                *n = self.sigma * rng::gaussian(g);
            }
        }
    }

    /// Reference level of unit `k` of `row` [counts] with the emitter target `target` [counts],
    /// after `hours` of plant time; 0 for indices out of range.
    pub(crate) fn reference(&self, row: usize, k: usize, target: f64, hours: f64) -> f64 {
        let Some(f) = self.factor.get(row).and_then(|u| u.get(k)) else {
            return 0.0;
        };
        (target * f * (1.0 + self.dust_per_hour * hours).max(0.0))
            .round()
            .clamp(0.0, FULL_SCALE)
    }

    /// Value of unit `k` of `row` [counts] for a flow `flow_g_s` [g/s] and that unit's reference.
    pub(crate) fn unit(&self, row: usize, k: usize, flow_g_s: f64, reference: f64) -> f64 {
        let (Some(w), Some(n)) = (
            self.weight.get(row).and_then(|u| u.get(k)),
            self.noise.get(row).and_then(|u| u.get(k)),
        ) else {
            return 0.0;
        };
        if flow_g_s <= 0.0 {
            return 0.0;
        }
        (flow_g_s * reference * self.attenuation * w + n)
            .round()
            .clamp(0.0, FULL_SCALE)
    }

    /// The distribution weights of `row`, for tests.
    #[cfg(test)]
    pub(crate) fn weights(&self, row: usize) -> [f64; UNITS] {
        self.weight[row]
    }
}
