//! Behaviour of the plant, with expectations computed independently of the model where possible.

use bus::time::BusTime;
use proptest::prelude::*;

use super::*;

const SEED: u64 = 0x4D5A_0006;

/// Bus time of `s` seconds.
fn at(s: f64) -> BusTime {
    BusTime::from_nanos((s * 1e9).round() as u64)
}

fn get(p: &Plant, name: &str) -> f64 {
    p.signal(name).unwrap_or_else(|| panic!("no signal {name}"))
}

fn set(p: &mut Plant, name: &str, value: f64) {
    p.set_input(name, value).unwrap_or_else(|e| panic!("{e}"));
}

/// Advances by `s` seconds from the plant's time.
fn run(p: &mut Plant, s: f64) {
    let t = p.now().as_secs_f64() + s;
    p.advance_to(at(t));
}

/// A field with no variation at all, so yields can be computed by hand.
fn flat() -> PlantConfig {
    PlantConfig {
        density_variation: 0.0,
        row_variation: 0.0,
        ..PlantConfig::default()
    }
}

fn rows() -> impl Iterator<Item = usize> {
    1..=ROWS
}

/// A scripted sequence of input changes at bus times, to drive two plants alike.
fn script() -> Vec<(f64, &'static str, f64)> {
    vec![
        (0.5, "speed.mode_request", 1.0),
        (0.5, "speed.setpoint", 6.5),
        (3.0, "row.correction", 20.0),
        (4.2, "fault.door2_open", 1.0),
        (5.0, "fault.row4_clutch_slip", 0.5),
        (6.01, "speed.unload", 1.0),
        (7.333, "speed.unload", 0.0),
        (8.0, "fault.door2_open", 0.0),
    ]
}

/// Every signal at time `t` after driving `p` with the script, advancing through `times`.
fn drive(p: &mut Plant, times: &[f64], mut on_sample: impl FnMut(&Plant)) {
    let mut changes = script().into_iter().peekable();
    for &t in times {
        while let Some((tc, name, value)) = changes.next_if(|c| c.0 <= t) {
            p.set_input_at(at(tc), name, value)
                .unwrap_or_else(|e| panic!("{e}"));
        }
        p.advance_to(at(t));
        on_sample(p);
    }
}

fn snapshot(p: &Plant) -> Vec<(String, u64)> {
    Plant::signal_names()
        .into_iter()
        .map(|n| (n.clone(), get(p, &n).to_bits()))
        .collect()
}

#[test]
fn determinism_does_not_depend_on_the_sampling_pattern() {
    let common: Vec<f64> = (1..=10).map(f64::from).collect();
    // A: every grid time. B: irregular times off the grid, plus the common ones.
    let dense: Vec<f64> = (1..=1000).map(|k| f64::from(k) * 0.01).collect();
    let mut sparse: Vec<f64> = (1..=70).map(|k| f64::from(k) * 0.1437).collect();
    sparse.extend(&common);
    sparse.sort_by(f64::total_cmp);
    let mut a = Plant::new(PlantConfig::default(), SEED);
    let mut b = Plant::new(PlantConfig::default(), SEED);
    let mut snaps_a = Vec::new();
    let mut snaps_b = Vec::new();
    drive(&mut a, &dense, |p| {
        if common.iter().any(|&c| at(c) == p.now()) {
            snaps_a.push((p.now(), snapshot(p)));
        }
    });
    drive(&mut b, &sparse, |p| {
        if common.iter().any(|&c| at(c) == p.now()) {
            snaps_b.push((p.now(), snapshot(p)));
        }
    });
    // Several sample times may fall in one grid interval: keep one snapshot per grid time.
    snaps_b.dedup_by_key(|(t, _)| *t);
    assert_eq!(snaps_a.len(), common.len());
    assert_eq!(snaps_a, snaps_b);
}

#[test]
fn different_seeds_give_different_plants() {
    let mut a = Plant::new(PlantConfig::default(), 1);
    let mut b = Plant::new(PlantConfig::default(), 2);
    a.advance_to(at(20.0));
    b.advance_to(at(20.0));
    for name in ["row1.density", "row.offset", "row3.ref2", "row5.unit4"] {
        assert_ne!(get(&a, name), get(&b, name), "{name}");
    }
    // But the deterministic parts agree.
    assert_eq!(get(&a, "speed.actual"), get(&b, "speed.actual"));
}

#[test]
fn time_moves_on_the_grid_only_and_never_back() {
    let mut p = Plant::new(PlantConfig::default(), SEED);
    p.advance_to(BusTime::from_micros(29_999));
    assert_eq!(p.now(), BusTime::from_millis(20));
    p.advance_to(BusTime::from_millis(5));
    assert_eq!(p.now(), BusTime::from_millis(20));
    p.advance_to(BusTime::NEVER);
    assert_eq!(p.now(), BusTime::from_millis(20));
}

#[test]
fn an_input_acts_from_the_next_step() {
    let mut p = Plant::new(flat(), SEED);
    run(&mut p, 10.0);
    let before = get(&p, "row1.flow");
    assert!(before > 0.0);
    set(&mut p, "fault.door1_open", 1.0);
    assert_eq!(get(&p, "fault.door1_open"), 1.0, "the input reads back at once");
    assert_eq!(
        get(&p, "row1.flow"),
        before,
        "outputs change only at the next grid step"
    );
    assert_eq!(get(&p, "door1.open"), 0.0);
    run(&mut p, 0.01);
    assert_eq!(get(&p, "row1.flow"), 0.0);
    assert_eq!(get(&p, "door1.open"), 1.0);
}

#[test]
fn manual_speed_follows_the_operator_with_the_configured_lag() {
    let mut p = Plant::new(PlantConfig::default(), SEED);
    assert_eq!(get(&p, "speed.mode"), 0.0);
    assert_eq!(get(&p, "speed.setpoint_in_force"), 5.0);
    run(&mut p, 2.0);
    // One time constant: 1 − 1/e of the step.
    let expected = 5.0 * (1.0 - (-1.0f64).exp());
    assert!(
        (get(&p, "speed.actual") - expected).abs() < 1e-9,
        "{}",
        get(&p, "speed.actual")
    );
    set(&mut p, "operator.speed", 3.0);
    run(&mut p, 30.0);
    assert!((get(&p, "speed.actual") - 3.0).abs() < 1e-3);
    assert!((get(&p, "wheel.pulses") - 3.0 / 3.6 * 100.0).abs() < 0.1);
}

#[test]
fn cruise_converges_to_the_setpoint_and_unloading_to_zero() {
    let mut p = Plant::new(PlantConfig::default(), SEED);
    set(&mut p, "speed.mode_request", 1.0);
    set(&mut p, "speed.setpoint", 8.0);
    run(&mut p, 30.0);
    assert_eq!(get(&p, "speed.mode"), 1.0);
    assert!((get(&p, "speed.actual") - 8.0).abs() < 1e-3);
    set(&mut p, "speed.unload", 1.0);
    run(&mut p, 30.0);
    assert_eq!(get(&p, "speed.mode"), 2.0);
    assert_eq!(get(&p, "speed.setpoint_in_force"), 0.0);
    assert_eq!(get(&p, "basket.raised"), 1.0);
    assert!(get(&p, "speed.actual") < 1e-3);
    set(&mut p, "speed.unload", 0.0);
    run(&mut p, 30.0);
    assert_eq!(get(&p, "basket.raised"), 0.0);
    assert!(
        (get(&p, "speed.actual") - 8.0).abs() < 1e-3,
        "cruise resumes after unloading"
    );
}

#[test]
fn distance_is_the_integral_of_speed() {
    let mut p = Plant::new(PlantConfig::default(), SEED);
    let mut integral = 0.0;
    for k in 1..=3000u64 {
        if k == 1000 {
            set(&mut p, "operator.speed", 9.0);
        }
        p.advance_to(BusTime::from_millis(10 * k));
        integral += get(&p, "speed.actual") / 3.6 * 0.01;
    }
    let distance = get(&p, "field.distance");
    assert!(distance > 30.0);
    assert!((distance - integral).abs() < 1e-9 * distance);
}

#[test]
fn harvest_on_a_flat_field_is_density_times_distance_times_efficiency() {
    let mut p = Plant::new(flat(), SEED);
    run(&mut p, 120.0);
    let distance = get(&p, "field.distance");
    let per_row = 0.38 * distance * 0.95;
    let sum: f64 = rows().map(|n| get(&p, &format!("row{n}.harvested"))).sum();
    let total = get(&p, "harvested.total");
    assert!((total - sum).abs() < 1e-9);
    assert!(
        (total - 6.0 * per_row).abs() < 0.01 * total,
        "{total} vs {}",
        6.0 * per_row
    );
    for n in rows() {
        assert!((get(&p, &format!("row{n}.density")) - 0.38).abs() < 1e-12);
        let flow = 0.38 * get(&p, "speed.actual") / 3.6 * 0.95 * 1000.0;
        assert!((get(&p, &format!("row{n}.flow")) - flow).abs() < 1e-9);
    }
    assert_eq!(get(&p, "harvested.lost"), 0.0);
    assert!((get(&p, "basket.mass") - total).abs() < 1e-9);
}

#[test]
fn seeded_variation_stays_within_its_bounds() {
    let mut p = Plant::new(PlantConfig::default(), SEED);
    set(&mut p, "operator.speed", 12.0);
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for _ in 0..300 {
        run(&mut p, 1.0);
        let mean = get(&p, "field.density");
        let rows_mean: f64 = rows().map(|n| get(&p, &format!("row{n}.density"))).sum::<f64>() / 6.0;
        assert!((mean - rows_mean).abs() < 1e-12);
        // ±20 % along the path times ±5 % between rows.
        let bounds = 0.38 * 0.8 * 0.95 - 1e-12..=0.38 * 1.2 * 1.05 + 1e-12;
        for n in rows() {
            let d = get(&p, &format!("row{n}.density"));
            assert!(bounds.contains(&d), "{d}");
        }
        lo = lo.min(mean);
        hi = hi.max(mean);
    }
    assert!(hi - lo > 0.38 * 0.1, "the density varies along ~1 km: {lo}..{hi}");
}

#[test]
fn density_steps_apply_from_their_distance() {
    let config = PlantConfig {
        density_steps: vec![(200.0, 1.5), (50.0, 0.5)],
        ..flat()
    };
    let mut p = Plant::new(config, SEED);
    set(&mut p, "operator.speed", 10.0);
    let mut seen = Vec::new();
    while get(&p, "field.distance") < 260.0 {
        run(&mut p, 0.5);
        seen.push((get(&p, "field.distance"), get(&p, "field.density")));
    }
    for (x, d) in seen {
        let expected = if x < 50.0 {
            0.38
        } else if x < 200.0 {
            0.19
        } else {
            0.57
        };
        assert!((d - expected).abs() < 1e-12, "at {x} m: {d}");
    }
}

#[test]
fn an_open_door_loses_that_rows_cotton() {
    let mut p = Plant::new(flat(), SEED);
    run(&mut p, 20.0);
    set(&mut p, "fault.door3_open", 1.0);
    run(&mut p, 0.01);
    let h3 = get(&p, "row3.harvested");
    let h1 = get(&p, "row1.harvested");
    let lost0 = get(&p, "harvested.lost");
    run(&mut p, 10.0);
    assert_eq!(get(&p, "door3.open"), 1.0);
    assert_eq!(get(&p, "row3.flow"), 0.0);
    assert_eq!(get(&p, "row3.unit1"), 0.0);
    assert_eq!(get(&p, "row3.harvested"), h3);
    let gained = get(&p, "row1.harvested") - h1;
    assert!(gained > 0.0);
    // Row 3 would have harvested what row 1 did; it lost it instead.
    assert!((get(&p, "harvested.lost") - lost0 - gained).abs() < 1e-9);
    for n in [1, 2, 4, 5, 6] {
        assert_eq!(get(&p, &format!("door{n}.open")), 0.0);
    }
}

#[test]
fn a_slipping_row_clutch_slows_its_drum_and_picks_less() {
    let mut p = Plant::new(flat(), SEED);
    run(&mut p, 20.0);
    let drums = get(&p, "drum.front_rpm");
    assert!(
        (drums - (300.0 + 55.0 * get(&p, "speed.actual"))).abs() < 1.0,
        "{drums}"
    );
    set(&mut p, "fault.row2_clutch_slip", 1.0);
    run(&mut p, 5.0);
    assert_eq!(get(&p, "row2.clutch_slip"), 1.0);
    assert!((get(&p, "row2.flow") / get(&p, "row1.flow") - 0.6).abs() < 1e-9);
    let expected = drums * (5.0 + 0.6) / 6.0;
    assert!((get(&p, "drum.front_rpm") - expected).abs() < 1.0);
    assert!(get(&p, "clutch.pressure") < 3400.0);
}

#[test]
fn an_open_main_clutch_stops_picking() {
    let mut p = Plant::new(flat(), SEED);
    run(&mut p, 20.0);
    let loaded = get(&p, "engine.rpm");
    assert!((2100.0..2200.0).contains(&loaded), "{loaded}");
    assert!((3300.0..3450.0).contains(&get(&p, "fan.rpm")));
    set(&mut p, "fault.main_clutch_open", 1.0);
    run(&mut p, 20.0);
    assert_eq!(get(&p, "main_clutch.open"), 1.0);
    assert!(rows().all(|n| get(&p, &format!("row{n}.flow")) == 0.0));
    assert!(get(&p, "drum.front_rpm") < 1.0);
    assert!(get(&p, "fan.rpm") < 50.0);
    assert!(get(&p, "engine.rpm") > 2390.0);
    assert!(get(&p, "clutch.pressure") < 600.0);
    assert!(get(&p, "duct.vacuum") < 600.0);
    assert!(get(&p, "speed.actual") > 4.9, "the machine still drives");
}

/// Seconds until `flag` reads 1, checking every 100 ms up to `limit`.
fn time_to_flag(p: &mut Plant, flag: &str, limit: f64) -> f64 {
    let start = p.now().as_secs_f64();
    while get(p, flag) == 0.0 {
        assert!(
            p.now().as_secs_f64() - start < limit,
            "{flag} not raised within {limit} s"
        );
        run(p, 0.1);
    }
    p.now().as_secs_f64() - start
}

#[test]
fn faults_raise_their_flags_within_bounded_times() {
    let cases: [(&str, &str, f64); 6] = [
        ("fault.belt_stop", "belt.stopped", 2.0),
        ("fault.low_water", "water.low_pressure", 10.0),
        ("fault.oil_overheat", "oil.overheat", 300.0),
        ("fault.engine_overheat", "engine.overheat", 300.0),
        ("fault.lubricant_low", "lubricant.low", 60.0),
        ("fault.duct_blocked", "duct.blocked", 0.2),
    ];
    for (fault, flag, limit) in cases {
        let mut p = Plant::new(PlantConfig::default(), SEED);
        run(&mut p, 5.0);
        assert_eq!(get(&p, flag), 0.0, "{flag} before the fault");
        set(&mut p, fault, 1.0);
        let took = time_to_flag(&mut p, flag, limit);
        assert!(took > 0.0, "{flag} needs at least one step");
    }
}

#[test]
fn healthy_machine_stays_in_its_normal_ranges() {
    let mut p = Plant::new(PlantConfig::default(), SEED);
    run(&mut p, 600.0);
    let oil = get(&p, "oil.temperature");
    assert!((65.0..=70.0).contains(&oil), "oil warms to ~70 in minutes: {oil}");
    assert!((get(&p, "water.pressure") - 350.0).abs() < 1e-6);
    let water = 100.0 - 10.0 * 600.0 / 3600.0;
    assert!(
        (get(&p, "water.level") - water).abs() < 1e-9,
        "{}",
        get(&p, "water.level")
    );
    assert!((27000.0..28000.0).contains(&get(&p, "supply.voltage")));
    assert!((1.49..=1.5).contains(&get(&p, "belt.speed")));
    let rate = get(&p, "lubricant.rate");
    assert!((rate - 0.1 * get(&p, "drum.front_rpm")).abs() < 1e-9 && rate > 50.0);
    assert!(get(&p, "lubricant.level") < 100.0);
    for flag in [
        "belt.stopped",
        "basket.raised",
        "duct.blocked",
        "water.low_pressure",
        "oil.overheat",
        "engine.overheat",
        "lubricant.low",
        "main_clutch.open",
    ] {
        assert_eq!(get(&p, flag), 0.0, "{flag}");
    }
}

#[test]
fn a_blocked_duct_holds_cotton_back_until_it_clears() {
    let mut p = Plant::new(flat(), SEED);
    run(&mut p, 20.0);
    let vacuum = get(&p, "duct.vacuum");
    set(&mut p, "fault.duct_blocked", 1.0);
    run(&mut p, 0.01);
    let harvested = get(&p, "harvested.total");
    run(&mut p, 10.0);
    assert!(get(&p, "duct.vacuum") < vacuum * 0.5);
    assert_eq!(get(&p, "harvested.total"), harvested);
    assert!(get(&p, "duct.holdup") > 0.0);
    assert!(get(&p, "row1.flow") > 0.0, "the sensors still see the cotton");
    set(&mut p, "fault.duct_blocked", 0.0);
    run(&mut p, 0.01);
    assert_eq!(get(&p, "duct.holdup"), 0.0);
    let expected = 6.0 * 0.38 * get(&p, "field.distance") * 0.95;
    assert!((get(&p, "harvested.total") - expected).abs() < 1e-6 * expected);
}

#[test]
fn the_basket_fills_with_the_harvest_and_empties_on_unload() {
    let config = PlantConfig {
        basket_initial_kg: 2300.0,
        ..flat()
    };
    let mut p = Plant::new(config, SEED);
    set(&mut p, "operator.speed", 12.0);
    assert_eq!(get(&p, "basket.full"), 0.0);
    let mut last = get(&p, "basket.fill");
    while get(&p, "basket.full") == 0.0 {
        run(&mut p, 1.0);
        let fill = get(&p, "basket.fill");
        assert!(fill > last || p.now() < at(2.0));
        last = fill;
        assert!(p.now() < at(300.0));
    }
    assert!(get(&p, "basket.fill") >= 95.0);
    assert!((get(&p, "basket.mass") - 2300.0 - get(&p, "harvested.total")).abs() < 1e-6);
    let level = get(&p, "basket.level");
    assert!((level - (500.0 + 40.0 * get(&p, "basket.fill"))).abs() < 1e-9);
    set(&mut p, "speed.unload", 1.0);
    run(&mut p, 0.01);
    let harvested = get(&p, "harvested.total");
    run(&mut p, 60.0);
    assert_eq!(get(&p, "basket.mass"), 0.0);
    assert_eq!(get(&p, "basket.full"), 0.0);
    assert_eq!(get(&p, "basket.level"), 500.0);
    assert_eq!(
        get(&p, "harvested.total"),
        harvested,
        "no picking while unloading"
    );
    assert!(rows().all(|n| get(&p, &format!("row{n}.flow")) == 0.0));
}

#[test]
fn a_stopped_belt_stops_unloading() {
    let config = PlantConfig {
        basket_initial_kg: 1000.0,
        ..flat()
    };
    let mut p = Plant::new(config, SEED);
    set(&mut p, "fault.belt_stop", 1.0);
    set(&mut p, "speed.unload", 1.0);
    run(&mut p, 5.0);
    let mass = get(&p, "basket.mass");
    assert!(mass > 1000.0 - 50.0, "{mass}");
    run(&mut p, 20.0);
    assert!(mass - get(&p, "basket.mass") < 1e-3);
}

#[test]
fn overrides_force_an_output_and_release_it() {
    let mut p = Plant::new(PlantConfig::default(), SEED);
    run(&mut p, 5.0);
    p.set_override("engine.rpm", Some(1234.0))
        .unwrap_or_else(|e| panic!("{e}"));
    p.set_override("door4.open", Some(1.0))
        .unwrap_or_else(|e| panic!("{e}"));
    run(&mut p, 1.0);
    assert_eq!(get(&p, "engine.rpm"), 1234.0);
    assert_eq!(get(&p, "door4.open"), 1.0);
    assert!(
        get(&p, "row4.flow") > 0.0,
        "a forced switch reading does not open the door"
    );
    p.set_override("engine.rpm", None)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!((get(&p, "engine.rpm") - 2200.0).abs() < 100.0);
    assert_eq!(get(&p, "door4.open"), 1.0);
    assert_eq!(
        p.set_override("speed.setpoint", Some(1.0)),
        Err(PlantError::NotAnOutput("speed.setpoint".into()))
    );
    assert!(matches!(
        p.set_override("engine.rpm", Some(f64::NAN)),
        Err(PlantError::BadValue { .. })
    ));
    assert_eq!(
        p.set_override("nope", None),
        Err(PlantError::UnknownSignal("nope".into()))
    );
}

#[test]
fn names_are_checked() {
    let mut p = Plant::new(PlantConfig::default(), SEED);
    assert_eq!(p.signal("engine.rpms"), None);
    assert_eq!(
        p.set_input("row7.flow", 1.0),
        Err(PlantError::UnknownSignal("row7.flow".into()))
    );
    assert_eq!(
        p.set_input("engine.rpm", 1.0),
        Err(PlantError::NotAnInput("engine.rpm".into()))
    );
    for (name, value) in [
        ("speed.setpoint", 12.5),
        ("speed.setpoint", -1.0),
        ("speed.mode_request", 0.5),
        ("speed.unload", 2.0),
        ("row.correction", 101.0),
        ("fault.low_water", 1.5),
        ("sensor.target_reference", 0.0),
    ] {
        assert_eq!(
            p.set_input(name, value),
            Err(PlantError::BadValue {
                name: name.into(),
                value
            })
        );
    }
    assert!(matches!(
        p.set_input("operator.speed", f64::NAN),
        Err(PlantError::BadValue { .. })
    ));
    let names = Plant::signal_names();
    assert_eq!(
        names.len(),
        names.iter().collect::<std::collections::BTreeSet<_>>().len()
    );
    // 6 + 2×6 + 7 inputs; 37 machine outputs + 5 per row + 10 per row's sensor.
    assert_eq!(names.iter().filter(|n| Plant::is_input(n)).count(), 25);
    assert_eq!(names.len(), 25 + 37 + 6 * 15);
    for n in &names {
        assert!(p.signal(n).is_some_and(f64::is_finite), "{n}");
    }
    for n in [
        "row6.unit5",
        "row1.ref1",
        "fault.door6_open",
        "door1.open",
        "rowN.flow",
    ] {
        assert_eq!(names.contains(&n.to_string()), n != "rowN.flow", "{n}");
    }
    assert!(Plant::is_input("fault.row6_clutch_slip"));
    assert!(!Plant::is_input("row6.clutch_slip"));
    assert!(!Plant::is_input("nope"));
    let e = PlantError::BadValue {
        name: "speed.setpoint".into(),
        value: 13.0,
    };
    assert_eq!(
        e.to_string(),
        "value 13 is out of range for plant input `speed.setpoint`"
    );
}

#[test]
fn a_monitor_recovers_the_flow_from_the_units() {
    let config = PlantConfig::default();
    let coefficient = config.attenuation_per_g_s;
    let mut p = Plant::new(config, SEED);
    run(&mut p, 20.0);
    let mut truth = [0.0; ROWS];
    let mut recovered = [0.0; ROWS];
    for _ in 0..600 {
        run(&mut p, 0.1);
        for r in 0..ROWS {
            let n = r + 1;
            let ratio: f64 = (1..=UNITS)
                .map(|k| get(&p, &format!("row{n}.unit{k}")) / get(&p, &format!("row{n}.ref{k}")))
                .sum::<f64>()
                / UNITS as f64;
            recovered[r] += ratio / coefficient;
            truth[r] += get(&p, &format!("row{n}.flow"));
        }
    }
    for r in 0..ROWS {
        assert!(truth[r] > 0.0);
        let error = (recovered[r] - truth[r]).abs() / truth[r];
        assert!(error < 0.01, "row {}: {error}", r + 1);
    }
}

#[test]
fn sensor_constants_follow_their_documented_ranges() {
    let mut p = Plant::new(PlantConfig::default(), SEED);
    set(&mut p, "sensor.target_reference", 12000.0);
    run(&mut p, 0.01);
    for r in 0..ROWS {
        let w = p.model.sensors().weights(r);
        assert!((w.iter().sum::<f64>() / 5.0 - 1.0).abs() < 1e-12);
        assert!(w.iter().all(|x| (0.9..=1.1).contains(x)), "{w:?}");
        for k in 1..=UNITS {
            let reference = get(&p, &format!("row{}.ref{k}", r + 1));
            assert!(
                (0.75 * 12000.0 - 1.0..=1.15 * 12000.0 + 1.0).contains(&reference),
                "{reference}"
            );
            assert_eq!(reference, reference.round());
        }
    }
    // An empty duct reads exactly 0.
    let mut still = Plant::new(
        PlantConfig {
            operator_speed_kmh: 0.0,
            ..PlantConfig::default()
        },
        SEED,
    );
    run(&mut still, 5.0);
    assert!((1..=UNITS).all(|k| get(&still, &format!("row1.unit{k}")) == 0.0));
}

#[test]
fn dust_lowers_the_references_slowly() {
    let config = PlantConfig {
        step_ms: 1000,
        ..PlantConfig::default()
    };
    let mut p = Plant::new(config, SEED);
    run(&mut p, 1.0);
    let start = get(&p, "row2.ref3");
    run(&mut p, 7200.0);
    let expected = start * (1.0 - 0.005 * 2.0);
    assert!(
        (get(&p, "row2.ref3") - expected).abs() <= 1.0,
        "{} vs {expected}",
        get(&p, "row2.ref3")
    );
}

/// Runs the row alignment module's P law, correction = −gain × offset, every 50 ms.
fn align(p: &mut Plant, gain: f64, seconds: f64) -> Vec<f64> {
    let mut offsets = Vec::new();
    for _ in 0..(seconds / 0.05).round() as usize {
        let offset = get(p, "row.offset");
        offsets.push(offset);
        set(p, "row.correction", (-gain * offset).clamp(-100.0, 100.0));
        run(p, 0.05);
    }
    offsets
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

#[test]
fn row_offset_drifts_and_a_p_controller_holds_it() {
    let mut free = Plant::new(PlantConfig::default(), SEED);
    let open_loop = align(&mut free, 0.0, 600.0);
    assert!(open_loop.iter().all(|x| x.abs() <= 500.0));
    let drift_rms = rms(&open_loop);
    assert!(drift_rms > 20.0, "the rows drift: {drift_rms}");

    let mut held = Plant::new(PlantConfig::default(), SEED);
    let closed_loop = align(&mut held, 0.4, 600.0);
    assert!(
        rms(&closed_loop) < drift_rms / 5.0,
        "{} vs {drift_rms}",
        rms(&closed_loop)
    );

    // From a large offset, the controller brings the heads back.
    let mut p = Plant::new(PlantConfig::default(), SEED);
    set(&mut p, "row.correction", 100.0);
    run(&mut p, 20.0);
    assert!(
        get(&p, "row.offset") > 300.0,
        "a positive correction steers toward positive offset"
    );
    let back = align(&mut p, 0.4, 30.0);
    assert!(back.last().is_some_and(|x| x.abs() < 30.0), "{:?}", back.last());
}

#[test]
fn the_offset_holds_still_at_a_standstill() {
    let mut p = Plant::new(
        PlantConfig {
            operator_speed_kmh: 0.0,
            ..PlantConfig::default()
        },
        SEED,
    );
    set(&mut p, "row.correction", 50.0);
    run(&mut p, 30.0);
    assert_eq!(get(&p, "row.offset"), 0.0);
}

#[test]
fn config_round_trips_through_ron() {
    let parsed: PlantConfig = ron::from_str("()").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(parsed, PlantConfig::default());
    assert!(ron::from_str::<PlantConfig>("(step_ms: 10, no_such_field: 1)").is_err());
    let config = PlantConfig {
        density_steps: vec![(200.0, 1.5)],
        step_ms: 5,
        ..PlantConfig::default()
    };
    let text = ron::to_string(&config).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(ron::from_str::<PlantConfig>(&text).ok(), Some(config));
    let partial: PlantConfig = ron::from_str("(density_steps: [(200.0, 1.5)], basket_capacity_kg: 3000.0)")
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(partial.density_steps, vec![(200.0, 1.5)]);
    assert_eq!(partial.basket_capacity_kg, 3000.0);
    assert_eq!(partial.pick_efficiency, 0.95);
}

#[test]
fn invalid_config_is_reported_and_repaired() {
    assert_eq!(validate(&PlantConfig::default()), vec![]);
    let bad = PlantConfig {
        step_ms: 0,
        pick_efficiency: 1.5,
        basket_capacity_kg: 0.0,
        speed_time_constant_s: f64::NAN,
        density_steps: vec![(f64::INFINITY, 1.0), (100.0, 2.0)],
        ..PlantConfig::default()
    };
    let problems = validate(&bad);
    let fields: Vec<&str> = problems.iter().map(|(f, _)| f.as_str()).collect();
    assert_eq!(
        fields,
        [
            "step_ms",
            "speed_time_constant_s",
            "pick_efficiency",
            "basket_capacity_kg",
            "density_steps"
        ],
        "{problems:?}"
    );
    assert_eq!(problems[2].1, "1.5 is not in 0..=1");
    assert_eq!(problems[3].1, "0 is not positive");
    let mut p = Plant::new(bad, SEED);
    assert_eq!(p.config().step_ms, 10);
    assert_eq!(p.config().density_steps, vec![(100.0, 2.0)]);
    run(&mut p, 10.0);
    assert!(Plant::signal_names().iter().all(|n| get(&p, n).is_finite()));
}

#[test]
fn the_shared_handle_is_one_plant() {
    let handle = Plant::shared(PlantConfig::default(), SEED);
    let other = PlantHandle::clone(&handle);
    handle.borrow_mut().advance_to(at(1.0));
    assert_eq!(other.borrow().now(), at(1.0));
    assert_eq!(other.borrow().seed(), SEED);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Any increasing sampling pattern sees the same values at grid times as stepping every
    /// grid time.
    #[test]
    fn sampling_never_changes_the_plant(gaps in prop::collection::vec(1u64..400_000_000, 1..40), seed: u64) {
        let mut reference = Plant::new(PlantConfig::default(), seed);
        let mut sampled = Plant::new(PlantConfig::default(), seed);
        reference.set_input("operator.speed", 7.0).unwrap_or_else(|e| panic!("{e}"));
        sampled.set_input("operator.speed", 7.0).unwrap_or_else(|e| panic!("{e}"));
        let mut t = 0u64;
        for gap in gaps {
            t += gap;
            sampled.advance_to(BusTime::from_nanos(t));
            while reference.now() < sampled.now() {
                reference.advance_to(reference.now() + bus::time::BusDuration::from_millis(10));
            }
            prop_assert_eq!(reference.now(), sampled.now());
            prop_assert_eq!(snapshot(&reference), snapshot(&sampled));
        }
    }

    /// Whatever the correction does, the offset stays within its bound.
    #[test]
    fn the_offset_stays_bounded(corrections in prop::collection::vec(-100.0f64..=100.0, 1..30), seed: u64) {
        let mut p = Plant::new(PlantConfig { row_drift_mm_per_s: 50.0, ..PlantConfig::default() }, seed);
        p.set_input("operator.speed", 12.0).unwrap_or_else(|e| panic!("{e}"));
        for c in corrections {
            p.set_input("row.correction", c).unwrap_or_else(|e| panic!("{e}"));
            run(&mut p, 5.0);
            let offset = get(&p, "row.offset");
            prop_assert!(offset.abs() <= 500.0, "{}", offset);
        }
    }
}
