//! Skipping what a chip does while nothing can change (loops that wait on a timer, a flag, the
//! bus or the ADC, passed in closed form) changes nothing anyone can see: the firmware harvester
//! (every field node an AT89C51CC03 image) over 5 s of bus time, with skipping and without, gives
//! the same trace, frame for frame and to the nanosecond, and the same state dumps (CPU, internal
//! RAM, SFRs, CAN controller) of every node at the end.
//!
//! The 5 s cover each image's boot, the flow sensors' calibration (the monitor starts it at once
//! and accepts it after five reference groups) and a bus off of one node of each kind: every
//! frame its controller sends is corrupted for a while, so that it fails 32 times in a row and
//! its firmware restarts the controller.

use bus::trace::Sink;
use harvemu_e2e::{Shared, root};
use std::sync::Arc;
use supervisor::harvester::Harvester;

const SCENARIO: &str = r#"Scenario(
    name: "bus off of one node of each kind",
    description: "test",
    config: "../harvester-firmware.ron",
    duration_s: 5.0,
    timeline: [
        (at_s: 1.0, action: BitErrors(target: Node("A0"), hits: Always, until_s: Some(1.25))),
        (at_s: 1.5, action: BitErrors(target: Node("B0"), hits: Always, until_s: Some(1.65))),
        (at_s: 1.8, action: Plant(input: "fault.door4_open", value: 1.0)),
        (at_s: 1.8, action: BitErrors(target: Node("C0"), hits: Always, until_s: Some(1.9))),
        (at_s: 2.5, action: BitErrors(target: Node("D2"), hits: Always, until_s: Some(2.65))),
        (at_s: 3.0, action: BitErrors(target: Node("E0"), hits: Always, until_s: Some(3.1))),
    ],
    expect: [
        BusOffCount(node: "A0", min: 1, max: 100),
        BusOffCount(node: "B0", min: 1, max: 100),
        BusOffCount(node: "C0", min: 1, max: 100),
        BusOffCount(node: "D2", min: 1, max: 100),
        BusOffCount(node: "E0", min: 1, max: 100),
    ],
)"#;

/// The trace and the end's state dumps of one run, with skipping on or off.
fn run(skip: bool) -> (String, String) {
    let path = root().join("configs/scenarios/_skipping.ron");
    let mut loaded = supervisor::scenario::from_text(&path, SCENARIO, None, Harvester::load)
        .unwrap_or_else(|e| panic!("the scenario: {e}"));
    for f in &mut loaded.harvester.firmware {
        Arc::make_mut(f).skip_idle_loops = skip;
    }
    assert_eq!(loaded.harvester.firmware.len(), 20, "twenty firmware nodes");
    let trace = Shared::default();
    let sink: Box<dyn Sink> = harvemu_e2e::candump(trace.clone(), &loaded.harvester);
    let outcome = supervisor::scenario::run(&loaded, Some(sink), |_| {}).expect("the run");
    for v in &outcome.verdicts {
        assert!(v.passed, "skip {skip}: {} ({})", v.expectation, v.observed);
    }
    let dumps = outcome
        .hardware
        .iter()
        .map(|(name, hw)| format!("{name} {hw:?}\n"))
        .collect::<String>();
    assert_eq!(outcome.hardware.len(), 20, "a dump of every node");
    (String::from_utf8(trace.0.take()).expect("utf-8"), dumps)
}

#[test]
fn skipping_changes_no_frame_and_no_state_of_any_image() {
    let (skipping, skipped_state) = run(true);
    let (working, worked_state) = run(false);
    assert!(
        skipping.lines().count() > 2500,
        "{} frames",
        skipping.lines().count()
    );
    if skipping != working {
        let first = skipping
            .lines()
            .zip(working.lines())
            .find(|(a, b)| a != b)
            .map(|(a, b)| format!("skipping: {a}\nworking:  {b}"));
        panic!("the traces differ: {first:?}");
    }
    for (a, b) in skipped_state.lines().zip(worked_state.lines()) {
        assert_eq!(a, b, "the state dumps differ");
    }
}
