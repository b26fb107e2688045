//! Signal names: the one table that maps the names scripts use to what the plant holds.

use rustc_hash::FxHashMap;
use std::sync::LazyLock;

use super::{ROWS, UNITS};

/// An actuator input or plant fault, writable through `Plant::set_input`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Input {
    ModeRequest,
    Setpoint,
    Unload,
    OperatorSpeed,
    RowCorrection,
    TargetReference,
    Fault(Fault),
}

/// A plant fault; the value is its magnitude in 0..=1 (0 = healthy).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Fault {
    DoorOpen(usize),
    ClutchSlip(usize),
    MainClutchOpen,
    BeltStop,
    DuctBlocked,
    LowWater,
    OilOverheat,
    EngineOverheat,
    LubricantLow,
}

/// An output of the plant, readable (and overridable) but not writable. Row and unit indices
/// are 0-based here and 1-based in names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Output {
    SpeedActual,
    SpeedMode,
    SetpointInForce,
    WheelPulses,
    EngineRpm,
    EngineTemperature,
    FanRpm,
    DrumFrontRpm,
    DrumRearRpm,
    WaterPressure,
    WaterLevel,
    OilTemperature,
    LubricantRate,
    LubricantLevel,
    BeltSpeed,
    BasketMass,
    BasketFill,
    BasketLevel,
    DuctVacuum,
    DuctHoldup,
    ClutchPressure,
    SupplyVoltage,
    DoorOpen(usize),
    RowClutchSlip(usize),
    MainClutchOpen,
    BeltStopped,
    BasketFull,
    BasketRaised,
    DuctBlocked,
    WaterLowPressure,
    OilOverheat,
    EngineOverheat,
    LubricantLow,
    RowOffset,
    RowDrift,
    FieldDistance,
    FieldDensity,
    RowDensity(usize),
    RowFlow(usize),
    RowHarvested(usize),
    HarvestedTotal,
    HarvestedLost,
    RowReference(usize, usize),
    RowUnit(usize, usize),
}

/// Any named signal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Signal {
    In(Input),
    Out(Output),
}

/// Every signal with its name, inputs first, in a fixed order.
fn table() -> Vec<(String, Signal)> {
    use Fault as F;
    use Input as I;
    use Output as O;
    let mut t: Vec<(String, Signal)> = Vec::new();
    let mut input = |name: String, i: Input| t.push((name, Signal::In(i)));
    input("speed.mode_request".into(), I::ModeRequest);
    input("speed.setpoint".into(), I::Setpoint);
    input("speed.unload".into(), I::Unload);
    input("operator.speed".into(), I::OperatorSpeed);
    input("row.correction".into(), I::RowCorrection);
    input("sensor.target_reference".into(), I::TargetReference);
    for r in 0..ROWS {
        input(format!("fault.door{}_open", r + 1), I::Fault(F::DoorOpen(r)));
    }
    for r in 0..ROWS {
        input(
            format!("fault.row{}_clutch_slip", r + 1),
            I::Fault(F::ClutchSlip(r)),
        );
    }
    input("fault.main_clutch_open".into(), I::Fault(F::MainClutchOpen));
    input("fault.belt_stop".into(), I::Fault(F::BeltStop));
    input("fault.duct_blocked".into(), I::Fault(F::DuctBlocked));
    input("fault.low_water".into(), I::Fault(F::LowWater));
    input("fault.oil_overheat".into(), I::Fault(F::OilOverheat));
    input("fault.engine_overheat".into(), I::Fault(F::EngineOverheat));
    input("fault.lubricant_low".into(), I::Fault(F::LubricantLow));

    let mut output = |name: String, o: Output| t.push((name, Signal::Out(o)));
    for (name, o) in [
        ("speed.actual", O::SpeedActual),
        ("speed.mode", O::SpeedMode),
        ("speed.setpoint_in_force", O::SetpointInForce),
        ("wheel.pulses", O::WheelPulses),
        ("engine.rpm", O::EngineRpm),
        ("engine.temperature", O::EngineTemperature),
        ("fan.rpm", O::FanRpm),
        ("drum.front_rpm", O::DrumFrontRpm),
        ("drum.rear_rpm", O::DrumRearRpm),
        ("water.pressure", O::WaterPressure),
        ("water.level", O::WaterLevel),
        ("oil.temperature", O::OilTemperature),
        ("lubricant.rate", O::LubricantRate),
        ("lubricant.level", O::LubricantLevel),
        ("belt.speed", O::BeltSpeed),
        ("basket.mass", O::BasketMass),
        ("basket.fill", O::BasketFill),
        ("basket.level", O::BasketLevel),
        ("duct.vacuum", O::DuctVacuum),
        ("duct.holdup", O::DuctHoldup),
        ("clutch.pressure", O::ClutchPressure),
        ("supply.voltage", O::SupplyVoltage),
        ("main_clutch.open", O::MainClutchOpen),
        ("belt.stopped", O::BeltStopped),
        ("basket.full", O::BasketFull),
        ("basket.raised", O::BasketRaised),
        ("duct.blocked", O::DuctBlocked),
        ("water.low_pressure", O::WaterLowPressure),
        ("oil.overheat", O::OilOverheat),
        ("engine.overheat", O::EngineOverheat),
        ("lubricant.low", O::LubricantLow),
        ("row.offset", O::RowOffset),
        ("row.drift", O::RowDrift),
        ("field.distance", O::FieldDistance),
        ("field.density", O::FieldDensity),
        ("harvested.total", O::HarvestedTotal),
        ("harvested.lost", O::HarvestedLost),
    ] {
        output(name.into(), o);
    }
    for r in 0..ROWS {
        let n = r + 1;
        output(format!("door{n}.open"), O::DoorOpen(r));
        output(format!("row{n}.clutch_slip"), O::RowClutchSlip(r));
        output(format!("row{n}.density"), O::RowDensity(r));
        output(format!("row{n}.flow"), O::RowFlow(r));
        output(format!("row{n}.harvested"), O::RowHarvested(r));
        for k in 0..UNITS {
            output(format!("row{n}.ref{}", k + 1), O::RowReference(r, k));
        }
        for k in 0..UNITS {
            output(format!("row{n}.unit{}", k + 1), O::RowUnit(r, k));
        }
    }
    t
}

/// Names in order, each's signal, the index of each name.
type Table = (Vec<String>, Vec<Signal>, FxHashMap<String, u32>);

/// The table, built once: the names in order, each's signal, and the index of each name (a
/// fast hash: the names are ours, not an attacker's). Names are looked up when a reader loads;
/// reads then go by index ([`crate::script::Port`]).
static TABLE: LazyLock<Table> = LazyLock::new(|| {
    let t = table();
    let names = t.iter().map(|(n, _)| n.clone()).collect();
    let signals = t.iter().map(|(_, s)| *s).collect();
    let index = t
        .into_iter()
        .enumerate()
        .map(|(i, (n, _))| (n, i as u32))
        .collect();
    (names, signals, index)
});

/// The signal a name stands for.
pub(crate) fn lookup(name: &str) -> Option<Signal> {
    port(name).and_then(signal)
}

/// The index of a name in the table: what a [`crate::script::Port`] of the plant holds.
pub(crate) fn port(name: &str) -> Option<u32> {
    TABLE.2.get(name).copied()
}

/// The signal at index `port`.
pub(crate) fn signal(port: u32) -> Option<Signal> {
    TABLE.1.get(port as usize).copied()
}

/// Every name, inputs first.
pub(crate) fn names() -> Vec<String> {
    TABLE.0.clone()
}
