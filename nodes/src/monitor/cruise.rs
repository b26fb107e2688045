//! Cruise control: travel speed from online yield, with fuzzy rules.
//!
//! Every control period the monitor compares the measured feed rate (seed cotton entering the
//! machine, kg/s, from the flow sensors) with the target. Inputs, normalized:
//!
//! - error `e = (target − feed) / target`, clamped to −1..1 (positive: too little cotton, go faster);
//! - change of error `de = e − e_previous`, clamped to −1..1.
//!
//! Each has five triangular membership functions NB, NS, ZE, PS, PB centred on −1, −0.5, 0, 0.5,
//! 1 (half-width 0.5; NB and PB stay at 1 beyond their centres). The rule table gives the speed
//! change as a singleton (in units of `step_kmh`):
//!
//! | e \ de | NB | NS | ZE | PS | PB |
//! |---|---|---|---|---|---|
//! | NB | −2 | −2 | −2 | −1 | 0 |
//! | NS | −2 | −1 | −1 | 0 | 1 |
//! | ZE | −1 | −1 | 0 | 1 | 1 |
//! | PS | −1 | 0 | 1 | 1 | 2 |
//! | PB | 0 | 1 | 2 | 2 | 2 |
//!
//! The output is the weighted mean of the singletons (min for AND, centroid of singletons), times
//! `step_kmh`, added to the set-point, which stays within `min_kmh..=max_kmh`.

use serde::{Deserialize, Serialize};

/// Cruise settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CruiseConfig {
    /// Bus time at which the operator switches cruise on, s (None: never).
    pub start_s: Option<f64>,
    /// Feed rate to hold, kg/s of seed cotton.
    pub target_feed_kg_s: f64,
    /// Lowest set-point, km/h.
    pub min_kmh: f64,
    /// Highest set-point, km/h.
    pub max_kmh: f64,
    /// Largest speed change per control period, km/h.
    pub step_kmh: f64,
    /// Control period, ms.
    pub period_ms: u64,
    /// Time constant of the feed-rate filter, s.
    pub filter_s: f64,
}

impl Default for CruiseConfig {
    fn default() -> Self {
        CruiseConfig {
            start_s: None,
            target_feed_kg_s: 3.0,
            min_kmh: 1.0,
            max_kmh: 8.0,
            step_kmh: 0.3,
            period_ms: 500,
            filter_s: 1.0,
        }
    }
}

const RULES: [[f64; 5]; 5] = [
    [-2.0, -2.0, -2.0, -1.0, 0.0],
    [-2.0, -1.0, -1.0, 0.0, 1.0],
    [-1.0, -1.0, 0.0, 1.0, 1.0],
    [-1.0, 0.0, 1.0, 1.0, 2.0],
    [0.0, 1.0, 2.0, 2.0, 2.0],
];

/// Degrees of membership of `x` in NB, NS, ZE, PS, PB.
pub fn memberships(x: f64) -> [f64; 5] {
    let x = x.clamp(-1.0, 1.0);
    let centres = [-1.0, -0.5, 0.0, 0.5, 1.0];
    let mut m = [0.0; 5];
    for (i, c) in centres.iter().enumerate() {
        m[i] = (1.0 - (x - c).abs() / 0.5).max(0.0);
    }
    m
}

/// The rule table's output for error `e` and change `de`, in steps (−2..2).
pub fn infer(e: f64, de: f64) -> f64 {
    let (me, mde) = (memberships(e), memberships(de));
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..5 {
        for j in 0..5 {
            let w = me[i].min(mde[j]);
            num += w * RULES[i][j];
            den += w;
        }
    }
    if den > 0.0 { num / den } else { 0.0 }
}

/// The cruise controller's state.
#[derive(Clone, Debug, PartialEq)]
pub struct Cruise {
    config: CruiseConfig,
    previous_error: f64,
    /// Set-point being sent, km/h.
    pub setpoint: f64,
}

impl Cruise {
    /// A controller starting from `speed_kmh`.
    pub fn new(config: CruiseConfig, speed_kmh: f64) -> Cruise {
        let setpoint = within(speed_kmh, &config);
        Cruise {
            config,
            previous_error: 0.0,
            setpoint,
        }
    }
    /// One control period with the filtered feed rate; returns the new set-point.
    pub fn step(&mut self, feed_kg_s: f64) -> f64 {
        let target = self.config.target_feed_kg_s.max(1e-6);
        let e = ((target - feed_kg_s) / target).clamp(-1.0, 1.0);
        let de = (e - self.previous_error).clamp(-1.0, 1.0);
        self.previous_error = e;
        self.setpoint = within(self.setpoint + infer(e, de) * self.config.step_kmh, &self.config);
        self.setpoint
    }
}

/// `v` limited to `min_kmh..=max_kmh`. Validation refuses a config whose range is empty or not
/// a number; one built in code gets a deterministic answer, not f64::clamp's panic.
fn within(v: f64, c: &CruiseConfig) -> f64 {
    v.max(c.min_kmh).min(c.max_kmh)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f64::clamp panicked on these; a config built in code skips validation.
    #[test]
    fn an_empty_or_nan_speed_range_does_not_panic() {
        for (min_kmh, max_kmh) in [(6.0, 2.0), (f64::NAN, 8.0), (1.0, f64::NAN)] {
            let config = CruiseConfig {
                min_kmh,
                max_kmh,
                ..CruiseConfig::default()
            };
            let mut c = Cruise::new(config, 5.0);
            let v = c.step(1.0);
            assert!(!v.is_nan(), "({min_kmh}, {max_kmh}) gave {v}");
        }
    }

    #[test]
    fn memberships_partition_unity() {
        for k in -20..=20 {
            let x = f64::from(k) / 20.0;
            let m = memberships(x);
            assert!((m.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{x}: {m:?}");
        }
        assert_eq!(memberships(0.25), [0.0, 0.0, 0.5, 0.5, 0.0]);
    }

    #[test]
    fn rules_push_the_right_way() {
        assert_eq!(infer(0.0, 0.0), 0.0);
        assert_eq!(infer(1.0, 0.0), 2.0, "far too little cotton: speed up fast");
        assert_eq!(infer(-1.0, 0.0), -2.0);
        // Half way between ZE and PS on both inputs: the four rules ZE/ZE 0, ZE/PS 1, PS/ZE 1,
        // PS/PS 1 fire at 0.5 each.
        assert!((infer(0.25, 0.25) - 0.75).abs() < 1e-12);
    }

    #[test]
    fn holds_a_feed_rate_on_a_simple_plant() {
        // Feed proportional to speed: 0.6 kg/s per km/h, then a 1.5x density step.
        let mut c = Cruise::new(CruiseConfig::default(), 5.0);
        let mut speed = 5.0;
        let mut density = 1.0;
        for k in 0..120 {
            if k == 60 {
                density = 1.5;
            }
            let feed = 0.6 * speed * density;
            speed += (c.step(feed) - speed) * 0.4; // the machine lags its set-point
        }
        let feed = 0.6 * speed * density;
        assert!((feed - 3.0).abs() < 0.15, "{feed}");
        assert!((speed - 3.0 / 0.9).abs() < 0.3, "{speed}");
    }
}
