//! Actuator inputs and plant faults, with their accepted ranges.

use super::signals::{Fault, Input};
use super::{MAX_OPERATOR_SPEED_KMH, MAX_SETPOINT_KMH, ROWS};

/// Fault magnitudes, each in 0..=1 (0 = healthy, 1 = the full fault).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Faults {
    pub door_open: [f64; ROWS],
    pub clutch_slip: [f64; ROWS],
    pub main_clutch_open: f64,
    pub belt_stop: f64,
    pub duct_blocked: f64,
    pub low_water: f64,
    pub oil_overheat: f64,
    pub engine_overheat: f64,
    pub lubricant_low: f64,
}

/// Every input's value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Inputs {
    /// 0 manual, 1 cruise.
    pub mode_request: f64,
    /// Cruise set-point [km/h].
    pub setpoint: f64,
    /// 1 while the unload command holds.
    pub unload: f64,
    /// Operator's lever [km/h].
    pub operator_speed: f64,
    /// Steering correction [%].
    pub correction: f64,
    /// Flow sensors' emitter target [counts].
    pub target_reference: f64,
    pub faults: Faults,
}

impl Inputs {
    /// The inputs at start: manual drive at the configured lever position, nothing faulted.
    pub(crate) fn initial(operator_speed: f64, target_reference: f64) -> Inputs {
        Inputs {
            mode_request: 0.0,
            setpoint: 0.0,
            unload: 0.0,
            operator_speed,
            correction: 0.0,
            target_reference,
            faults: Faults::default(),
        }
    }

    /// The value slot of `input`; `None` for a row index out of range (never from the table).
    fn slot(&mut self, input: Input) -> Option<&mut f64> {
        let f = &mut self.faults;
        Some(match input {
            Input::ModeRequest => &mut self.mode_request,
            Input::Setpoint => &mut self.setpoint,
            Input::Unload => &mut self.unload,
            Input::OperatorSpeed => &mut self.operator_speed,
            Input::RowCorrection => &mut self.correction,
            Input::TargetReference => &mut self.target_reference,
            Input::Fault(Fault::DoorOpen(r)) => f.door_open.get_mut(r)?,
            Input::Fault(Fault::ClutchSlip(r)) => f.clutch_slip.get_mut(r)?,
            Input::Fault(Fault::MainClutchOpen) => &mut f.main_clutch_open,
            Input::Fault(Fault::BeltStop) => &mut f.belt_stop,
            Input::Fault(Fault::DuctBlocked) => &mut f.duct_blocked,
            Input::Fault(Fault::LowWater) => &mut f.low_water,
            Input::Fault(Fault::OilOverheat) => &mut f.oil_overheat,
            Input::Fault(Fault::EngineOverheat) => &mut f.engine_overheat,
            Input::Fault(Fault::LubricantLow) => &mut f.lubricant_low,
        })
    }

    /// Current value of `input`.
    pub(crate) fn get(&self, input: Input) -> Option<f64> {
        let mut copy = *self;
        copy.slot(input).map(|v| *v)
    }

    /// Sets `input` if `value` is accepted for it; `false` if it is not.
    pub(crate) fn set(&mut self, input: Input, value: f64) -> bool {
        if !accepts(input, value) {
            return false;
        }
        match self.slot(input) {
            Some(slot) => {
                *slot = value;
                true
            }
            None => false,
        }
    }
}

/// The values a plant input takes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InputRange {
    /// Exactly 0 or 1.
    Switch,
    /// Any finite number in `min..=max`.
    Span(f64, f64),
}

impl InputRange {
    /// The range of `input`.
    pub(crate) fn of(input: Input) -> InputRange {
        match input {
            Input::ModeRequest | Input::Unload => InputRange::Switch,
            Input::Setpoint => InputRange::Span(0.0, MAX_SETPOINT_KMH),
            Input::OperatorSpeed => InputRange::Span(0.0, MAX_OPERATOR_SPEED_KMH),
            Input::RowCorrection => InputRange::Span(-100.0, 100.0),
            Input::TargetReference => InputRange::Span(1.0, 65535.0),
            Input::Fault(_) => InputRange::Span(0.0, 1.0),
        }
    }

    /// True when `value` is one of the range's values.
    pub fn contains(self, value: f64) -> bool {
        match self {
            InputRange::Switch => value == 0.0 || value == 1.0,
            InputRange::Span(lo, hi) => value.is_finite() && (lo..=hi).contains(&value),
        }
    }
}

impl core::fmt::Display for InputRange {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            InputRange::Switch => write!(f, "0 or 1"),
            InputRange::Span(lo, hi) => write!(f, "{lo}..={hi}"),
        }
    }
}

/// Whether `value` is in the range of `input`: switches take exactly 0 or 1, the rest a range.
fn accepts(input: Input, value: f64) -> bool {
    InputRange::of(input).contains(value)
}
