//! Checking the monitor's settings before a run: every number it sends must fit the catalogue
//! field that carries it, and the plant input that field drives at the other end.

use super::MonitorConfig;
use crate::plant::Plant;
use protocol::catalogue::by_name;

/// The range of field `field` of message `message` in the catalogue, narrowed to what plant
/// input `input` (written from it by the receiving node) accepts.
fn carried(message: &str, field: &str, input: Option<&str>) -> Option<(f64, f64)> {
    let f = by_name(message)?.field(field)?;
    let (mut lo, mut hi) = (f.min, f.max);
    if let Some(crate::plant::InputRange::Span(a, b)) = input.and_then(Plant::input_range) {
        lo = lo.max(a);
        hi = hi.min(b);
    }
    Some((lo, hi))
}

impl MonitorConfig {
    /// Every problem with these settings as (field, message); empty when there is none.
    pub fn validate(&self) -> Vec<(String, String)> {
        let mut p = Vec::new();
        let mut sent = |name: &str, v: f64, message: &str, field: &str, input: Option<&str>| {
            if let Some((lo, hi)) = carried(message, field, input)
                && !(v.is_finite() && v >= lo && v <= hi)
            {
                let via = input.map_or(String::new(), |i| format!(" and plant input {i}"));
                p.push((
                    name.to_string(),
                    format!("{v} is outside {lo}..={hi}, what {message}.{field}{via} can carry"),
                ));
            }
        };
        let target = Some("sensor.target_reference");
        sent(
            "target_reference",
            self.target_reference,
            "flow.calibrate",
            "target_reference",
            target,
        );
        let samples = f64::from(self.calibration_samples);
        sent("calibration_samples", samples, "flow.calibrate", "samples", None);
        let c = &self.cruise;
        let setpoint = Some("speed.setpoint");
        sent(
            "cruise.min_kmh",
            c.min_kmh,
            "speed.setpoint",
            "setpoint",
            setpoint,
        );
        sent(
            "cruise.max_kmh",
            c.max_kmh,
            "speed.setpoint",
            "setpoint",
            setpoint,
        );
        if c.min_kmh > c.max_kmh {
            p.push((
                "cruise.min_kmh".to_string(),
                format!("{} is above cruise.max_kmh {}", c.min_kmh, c.max_kmh),
            ));
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let non_negative = |v: f64| v.is_finite() && v >= 0.0;
        for (name, v, ok, what) in [
            (
                "attenuation_per_g_s",
                self.attenuation_per_g_s,
                positive(self.attenuation_per_g_s),
                "positive",
            ),
            (
                "row_spacing_m",
                self.row_spacing_m,
                positive(self.row_spacing_m),
                "positive",
            ),
            (
                "cruise.target_feed_kg_s",
                c.target_feed_kg_s,
                positive(c.target_feed_kg_s),
                "positive",
            ),
            (
                "cruise.step_kmh",
                c.step_kmh,
                non_negative(c.step_kmh),
                "a number >= 0",
            ),
            (
                "cruise.filter_s",
                c.filter_s,
                non_negative(c.filter_s),
                "a number >= 0",
            ),
            (
                "cruise.start_s",
                c.start_s.unwrap_or(0.0),
                non_negative(c.start_s.unwrap_or(0.0)),
                "a number >= 0",
            ),
        ] {
            if !ok {
                p.push((name.to_string(), format!("{v} is not {what}")));
            }
        }
        p
    }
}
