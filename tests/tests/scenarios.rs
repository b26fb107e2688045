//! Every shipped scenario passes with many seeds, and fails without its fault: its expectations
//! hold whatever the seed, and they are about the fault, not about any run.
//!
//! The seeds cost time: in an optimised build (`cargo test --release -p harvemu-e2e --test
//! scenarios`) every scenario runs with its own seed and seeds 1 to 20; a debug build runs seeds 1
//! and 2 (scenarios longer than a minute, `plant_faults.ron`, seed 1 only): a debug run of a
//! scenario takes 1.5 to 3 s of wall time per 20 s of bus time (22 s for `plant_faults.ron`), so
//! 20 seeds would take a quarter of an hour. Set
//! `HARVEMU_SCENARIO_SEEDS=n` to run seeds 1 to n in any build.

use harvemu_e2e::root;
use std::collections::BTreeSet;
use std::path::PathBuf;
use std::sync::Mutex;
use supervisor::scenario;

/// Every shipped scenario and the timeline actions that are its fault. A scenario file that is
/// not here fails both tests.
const SHIPPED: &[(&str, &[&str])] = &[
    (
        "ack_failure.ron",
        &["AckFailure", "AckRestored", "Hang", "Resume"],
    ),
    ("babbling_idiot.ron", &["Babble"]),
    ("bit_error_every_nth.ron", &["BitErrors"]),
    ("bit_error_once.ron", &["BitErrors"]),
    ("bit_error_rate.ron", &["BitErrors"]),
    ("bus_off.ron", &["BitErrors"]),
    ("crash.ron", &["Crash"]),
    ("disconnect.ron", &["Disconnect", "Reconnect"]),
    ("hang.ron", &["Hang", "Resume"]),
    ("plant_faults.ron", &["Plant"]),
    ("power_cycle.ron", &["PowerCycle"]),
    ("sensor_faults.ron", &["SensorFault", "SensorRepaired"]),
    ("suction_door.ron", &["Plant"]),
    ("wrong_frames.ron", &["SendFrame"]),
    ("local_crc_errors.ron", &["BitErrors"]),
    ("overload.ron", &["Overload"]),
    ("lab_bus_off.ron", &["BitErrors"]),
    ("lab_disconnect.ron", &["Disconnect", "Reconnect"]),
    ("lab_ack_failure.ron", &["AckFailure", "AckRestored"]),
    ("c0_bus_off.ron", &["BitErrors"]),
    ("dead_from_power_on.ron", &["Disconnect"]),
    ("flood_from_power_on.ron", &["Babble"]),
];

/// The shipped scenarios C0 takes part in, which its C firmware must pass as its script does.
const C0_FIRMWARE: [&str; 3] = ["suction_door.ron", "plant_faults.ron", "power_cycle.ron"];

/// Longest run the scenario glob may hold: a day of virtual time lives in `configs/soak/`, for
/// `harvemu soak` and `tests/tests/soak.rs`.
const GLOB_MAX_S: f64 = 3600.0;

/// Scenarios whose virtual run is this long get one seed in a debug build.
const LONG_S: f64 = 60.0;

fn dir() -> PathBuf {
    root().join("configs/scenarios")
}

#[test]
fn every_scenario_file_is_in_the_tables() {
    let files: BTreeSet<String> = std::fs::read_dir(dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ron"))
        .collect();
    let listed: BTreeSet<String> = SHIPPED.iter().map(|(f, _)| f.to_string()).collect();
    assert_eq!(
        files, listed,
        "add new scenarios to SHIPPED (with their fault) in tests/tests/scenarios.rs"
    );
    // What `harvemu scenario configs/scenarios/*.ron` runs must not hold a long run.
    for f in &files {
        let loaded = scenario::load(&dir().join(f), None).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert!(
            loaded.scenario.duration_s <= GLOB_MAX_S,
            "{f}: {} s of virtual time in the scenario glob",
            loaded.scenario.duration_s
        );
    }
}

/// Runs `jobs` on two threads (every run has its own actix system), collecting what they say.
fn on_two_threads<J: Sync, R: Send>(jobs: &[J], run: impl Fn(&J) -> R + Sync) -> Vec<R> {
    let next = Mutex::new(0usize);
    let results = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                loop {
                    let i = {
                        let mut n = next.lock().unwrap();
                        *n += 1;
                        *n - 1
                    };
                    let Some(job) = jobs.get(i) else { break };
                    let r = run(job);
                    results.lock().unwrap().push((i, r));
                }
            });
        }
    });
    let mut results = results.into_inner().unwrap();
    results.sort_by_key(|(i, _)| *i);
    results.into_iter().map(|(_, r)| r).collect()
}

/// The failed verdicts of one run, as lines.
fn failures(file: &str, seed: Option<u64>, drop: &[&str]) -> Vec<String> {
    let path = dir().join(file);
    let mut loaded = scenario::load(&path, seed).unwrap_or_else(|e| panic!("{file}: {e}"));
    if !drop.is_empty() {
        let before = loaded.scenario.timeline.len();
        loaded
            .scenario
            .timeline
            .retain(|s| !drop.contains(&s.action.name()));
        assert!(loaded.scenario.timeline.len() < before, "{file} has no {drop:?}");
        // The run carries out the resolved timeline: resolve the changed one.
        loaded = loaded.resolved().unwrap_or_else(|e| panic!("{file}: {e}"));
    }
    failed_verdicts(file, &loaded)
}

/// Runs a loaded scenario: its failed verdicts, each with the file and the seed.
fn failed_verdicts(file: &str, loaded: &scenario::Loaded) -> Vec<String> {
    let outcome = scenario::run(loaded, None, |_| {}).unwrap();
    outcome
        .verdicts
        .iter()
        .filter(|v| !v.passed)
        .map(|v| {
            format!(
                "{file} seed {}: {} -> {}",
                outcome.seed, v.expectation, v.observed
            )
        })
        .collect()
}

#[test]
fn every_shipped_scenario_passes_with_many_seeds() {
    let override_seeds = std::env::var("HARVEMU_SCENARIO_SEEDS")
        .ok()
        .map(|n| n.parse::<u64>().expect("HARVEMU_SCENARIO_SEEDS is a number"));
    let mut jobs = Vec::new();
    for (file, _) in SHIPPED {
        let duration = scenario::load(&dir().join(file), None)
            .unwrap_or_else(|e| panic!("{file}: {e}"))
            .scenario
            .duration_s;
        let seeds = match override_seeds {
            Some(n) => n,
            None if !cfg!(debug_assertions) => 20,
            None if duration > LONG_S => 1,
            None => 2,
        };
        // The scenario's own seed (the config's when it names none), then 1 to n.
        jobs.push((*file, None));
        jobs.extend((1..=seeds).map(|seed| (*file, Some(seed))));
    }
    let started = std::time::Instant::now();
    let failed: Vec<String> = on_two_threads(&jobs, |(file, seed)| failures(file, *seed, &[])).concat();
    println!(
        "{} run(s) of {} scenario(s) in {:.1} s",
        jobs.len(),
        SHIPPED.len(),
        started.elapsed().as_secs_f64()
    );
    assert!(failed.is_empty(), "{failed:#?}");
}

/// `harvemu scenario FILE --config configs/harvester-firmware-c0.ron`: the harvester with C0 as
/// C firmware passes the scenarios C0 takes part in, with the scenario's seed and more.
#[test]
fn c0_as_firmware_passes_the_scenarios_c0_takes_part_in() {
    let config = root().join("configs/harvester-firmware-c0.ron");
    // A debug build runs each with its own seed only: C0's CPU is slow there.
    let seeds = if cfg!(debug_assertions) { 0 } else { 5 };
    let mut jobs = Vec::new();
    for file in C0_FIRMWARE {
        jobs.push((file, None));
        jobs.extend((1..=seeds).map(|seed| (file, Some(seed))));
    }
    let failed: Vec<String> = on_two_threads(&jobs, |(file, seed)| {
        let loaded = scenario::load_with(&dir().join(file), *seed, None, Some(&config))
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(
            loaded.harvester.firmware.iter().any(|f| f.name == "C0"),
            "{file}: C0 is firmware"
        );
        failed_verdicts(file, &loaded)
    })
    .concat();
    assert!(failed.is_empty(), "{failed:#?}");
}

#[test]
fn every_shipped_scenario_fails_without_its_fault() {
    let passed: Vec<&str> = on_two_threads(SHIPPED, |(file, fault)| {
        failures(file, None, fault).is_empty().then_some(*file)
    })
    .into_iter()
    .flatten()
    .collect();
    assert!(
        passed.is_empty(),
        "these pass without their fault, so their expectations do not show it: {passed:?}"
    );
}

#[test]
fn the_same_seed_gives_the_same_verdicts_and_another_seed_runs_too() {
    let f = root().join("configs/scenarios/bit_error_rate.ron");
    let observed = |seed| {
        let l = scenario::load(&f, Some(seed)).unwrap();
        let o = scenario::run(&l, None, |_| {}).unwrap();
        (
            o.seed,
            o.verdicts.iter().map(|v| v.observed.clone()).collect::<Vec<_>>(),
        )
    };
    let (a, b, c) = (observed(5), observed(5), observed(6));
    assert_eq!(a, b);
    assert_eq!(a.0, 5);
    assert_ne!(a.1, c.1, "the error frames come from the seed");
}
