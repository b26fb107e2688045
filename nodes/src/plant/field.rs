//! The cotton field: seed-cotton density along each of the six rows.
//!
//! density of row r at distance x [kg/m] =
//!   base × row_factor[r] × (1 + variation × mean_i sin(2π x / λ_i + φ_i)) × step_factor(x)
//!
//! The sinusoids' phases φ_i and the row factors are seeded; the mean of sines stays within ±1,
//! so `variation` is the largest relative swing. Row factors are centred so that their mean is
//! exactly 1: `field.density` (the mean over rows) then carries no seeded bias.

use super::ROWS;
use super::config::PlantConfig;
use super::rng;

/// The density model, fixed at construction.
#[derive(Debug, Clone)]
pub(crate) struct Field {
    base: f64,
    variation: f64,
    /// (angular wavenumber 2π/λ [rad/m], phase [rad]) of each sinusoid.
    waves: Vec<(f64, f64)>,
    row_factor: [f64; ROWS],
    /// Density steps sorted by distance.
    steps: Vec<(f64, f64)>,
}

impl Field {
    /// The field of `config` under the run seed.
    pub(crate) fn new(config: &PlantConfig, seed: u64) -> Field {
        let mut phases = rng::stream(seed, "field.variation_phases");
        let waves = config
            .variation_wavelengths_m
            .iter()
            .map(|&wavelength| {
                let phase = (rng::symmetric(&mut phases) + 1.0) * core::f64::consts::PI;
                (core::f64::consts::TAU / wavelength, phase)
            })
            .collect();
        // Half-width draws re-centred on their mean stay within ±row_variation.
        let mut rows = rng::stream(seed, "field.row_factors");
        let mut deviation = [0.0; ROWS];
        for d in &mut deviation {
            *d = rng::symmetric(&mut rows) * config.row_variation / 2.0;
        }
        let mean = deviation.iter().sum::<f64>() / ROWS as f64;
        let row_factor = deviation.map(|d| 1.0 + d - mean);
        let mut steps = config.density_steps.clone();
        steps.sort_by(|a, b| a.0.total_cmp(&b.0));
        Field {
            base: config.base_density_kg_per_m,
            variation: config.density_variation,
            waves,
            row_factor,
            steps,
        }
    }

    /// The factor of the density step in force at `distance` [m].
    fn step_factor(&self, distance: f64) -> f64 {
        self.steps
            .iter()
            .take_while(|(from, _)| *from <= distance)
            .last()
            .map_or(1.0, |(_, f)| *f)
    }

    /// Density common to all rows at `distance` [m], in kg/m before the row factor.
    fn path_density(&self, distance: f64) -> f64 {
        let swing = if self.waves.is_empty() {
            0.0
        } else {
            self.waves
                .iter()
                .map(|(k, phase)| (k * distance + phase).sin())
                .sum::<f64>()
                / self.waves.len() as f64
        };
        self.base * (1.0 + self.variation * swing) * self.step_factor(distance)
    }

    /// Density of `row` (0-based) at `distance` [kg/m]; 0 for a row that does not exist.
    pub(crate) fn row_density(&self, row: usize, distance: f64) -> f64 {
        self.row_factor
            .get(row)
            .map_or(0.0, |f| f * self.path_density(distance))
    }

    /// Densities of every row at `distance` [kg/m].
    pub(crate) fn densities(&self, distance: f64) -> [f64; ROWS] {
        let path = self.path_density(distance);
        self.row_factor.map(|f| f * path)
    }
}
