//! Validation: every problem of a scenario is found, named by its field, and nothing else is.

use crate::harvester::Harvester;
use crate::scenario::{Action, ErrorKind, SeenBy, from_text};
use nodes::Error;
use std::path::Path;

fn harvester(_: &Path) -> Result<Harvester, Error> {
    Harvester::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/harvester.ron"))
}

/// The problems of a scenario with this timeline and these expectations, as "field: message".
fn problems(duration_s: f64, timeline: &str, expect: &str) -> Vec<String> {
    let text = format!(
        "Scenario(name: \"t\", duration_s: {duration_s:?}, timeline: [{timeline}], expect: [{expect}])"
    );
    match from_text(Path::new("t.ron"), &text, None, harvester) {
        Ok(_) => Vec::new(),
        Err(Error::Invalid(p)) => p
            .iter()
            .map(|p| {
                assert_eq!(p.file, "t.ron");
                format!("{}: {}", p.field.as_deref().unwrap_or("-"), p.message)
            })
            .collect(),
        Err(e) => panic!("{e}"),
    }
}

/// Asserts that the problems are exactly these, each given by the start of its text.
#[track_caller]
fn assert_problems(found: &[String], expected: &[&str]) {
    for e in expected {
        assert!(
            found.iter().any(|f| f.starts_with(e)),
            "missing '{e}' in {found:#?}"
        );
    }
    assert_eq!(found.len(), expected.len(), "{found:#?}");
}

const OK: &str = "NoFrameLost";

#[test]
fn a_sound_scenario_with_every_new_expectation_passes_validation() {
    let found = problems(
        20.0,
        r#"(at_s: 5.0, action: BitErrors(target: Node("D2"), hits: Always, until_s: Some(5.2),
               kind: Crc, seen_by: Nodes(["F5", "D0"]))),
           (at_s: 6.0, action: Overload(target: Any, hits: EveryNth(3), until_s: Some(7.0),
               by: ["F5"], frames: 2)),
           (at_s: 8.0, action: Overload(target: Id("0601F5D0"), hits: Once))"#,
        r#"NodeStateNever(node: "E0", state: BusOff, from_s: 5.0, to_s: 20.0),
           NodeStateHolds(node: "E0", state: Active, from_s: 10.1, to_s: 20.0),
           BusOffCount(node: "D2", min: 1, max: 1),
           RecMax(node: "F5", max: 16, from_s: 0.0, to_s: 20.0),
           TecMax(node: "E0", max: 128, from_s: 0.0, to_s: 20.0),
           BusLoadBelow(100.0), YieldWithin(0.0)"#,
    );
    assert_problems(&found, &[]);
}

#[test]
fn windows_must_be_in_the_run_and_not_empty() {
    let found = problems(
        20.0,
        "",
        r#"NodeStateNever(node: "E0", state: BusOff, from_s: 10.0, to_s: 10.0),
           NodeStateHolds(node: "E0", state: Active, from_s: -1.0, to_s: 30.0),
           RecMax(node: "F5", max: 16, from_s: NaN, to_s: 5.0),
           TecMax(node: "E0", max: 16, from_s: 8.0, to_s: 2.0),
           NodeStateNever(node: "E9", state: Passive, from_s: 0.0, to_s: inf)"#,
    );
    assert_problems(
        &found,
        &[
            "expect[0].to_s: the window 10 s to 10 s is empty",
            "expect[1].from_s: time -1 s is negative",
            "expect[1].to_s: time 30 s is after the end of the run (20 s)",
            "expect[2].from_s: time NaN s is negative or not a number",
            "expect[3].to_s: the window 8 s to 2 s is empty",
            "expect[4].node: unknown node 'E9'",
            "expect[4].to_s: time inf s is negative or not a number",
        ],
    );
}

#[test]
fn thresholds_that_cannot_fail_or_cannot_pass_are_refused() {
    let found = problems(
        10.0,
        "",
        r#"BusLoadBelow(1000.0), BusLoadBelow(0.0), BusLoadBelow(-5.0), BusLoadBelow(NaN),
           YieldWithin(NaN), YieldWithin(-1.0),
           Display(field: "engine_rpm", min: NaN, max: 1.0),
           Display(field: "engine_rpm", min: 3.0, max: 1.0),
           Plant(signal: "engine.rpm", min: 0.0, max: inf),
           ErrorFrames(min: 5, max: 1),
           RecMax(node: "F5", max: 255, from_s: 0.0, to_s: 1.0),
           TecMax(node: "F5", max: 263, from_s: 0.0, to_s: 1.0),
           TecMax(node: "F5", max: 262, from_s: 0.0, to_s: 1.0),
           BusOffCount(node: "D2", min: 2, max: 1),
           BusOffCount(node: "D2", min: 5000, max: 5000)"#,
    );
    assert_problems(
        &found,
        &[
            "expect[0]: a load limit of 1000 % is outside (0, 100]",
            "expect[1]: a load limit of 0 % is outside (0, 100]",
            "expect[2]: a load limit of -5 % is outside (0, 100]",
            "expect[3]: a load limit of NaN % is outside (0, 100]",
            "expect[4]: NaN % is not a tolerance in 0..=100",
            "expect[5]: -1 % is not a tolerance in 0..=100",
            "expect[6].min: NaN is not a number",
            "expect[7].min: min 3 is above max 1",
            "expect[8].max: inf is not a number",
            "expect[9].min: min 5 is above max 1",
            "expect[10].max: REC never exceeds 255",
            "expect[11].max: TEC never exceeds 263",
            "expect[13].min: min 2 is above max 1",
            // 10 s at 250 kbit/s is 2,500,000 bit times, 1408 per recovery: 1775 recoveries.
            "expect[14].min: 5000 bus-offs cannot fit in 10 s: each recovery takes 1408 bit times, at most 1776",
        ],
    );
}

#[test]
fn seen_by_names_receivers_of_errors_other_than_bit_errors() {
    let found = problems(
        10.0,
        r#"(at_s: 1.0, action: BitErrors(target: Any, hits: Once, seen_by: Nodes(["F5"]))),
           (at_s: 1.0, action: BitErrors(target: Any, hits: Once, kind: Bit, seen_by: Nodes(["F5"]))),
           (at_s: 1.0, action: BitErrors(target: Any, hits: Once, kind: Stuff, seen_by: Nodes([]))),
           (at_s: 1.0, action: BitErrors(target: Any, hits: Once, kind: Form, seen_by: Nodes(["F5", "X1"]))),
           (at_s: 1.0, action: BitErrors(target: Any, hits: Once, kind: Crc)),
           (at_s: 1.0, action: BitErrors(target: Any, hits: Once, kind: Crc, seen_by: All))"#,
        OK,
    );
    assert_problems(
        &found,
        &[
            "timeline[0].action.seen_by: a bit error is a bit flipped on the wire, which every node sees",
            "timeline[1].action.seen_by: a bit error is a bit flipped on the wire, which every node sees",
            "timeline[2].action.seen_by: Nodes([]): name at least one node",
            "timeline[3].action.seen_by[1]: unknown node 'X1'",
        ],
    );
}

#[test]
fn overload_frames_come_one_or_two_at_a_time_from_known_nodes() {
    let found = problems(
        10.0,
        r#"(at_s: 1.0, action: Overload(target: Node("Q1"), hits: EveryNth(0), frames: 0)),
           (at_s: 1.0, action: Overload(target: Priority(32), hits: BitErrorRate(2.0), frames: 3)),
           (at_s: 2.0, action: Overload(target: Any, hits: Always, until_s: Some(1.0), by: ["F5", "F6"])),
           (at_s: 2.0, action: Overload(target: Any, hits: Always, until_s: Some(11.0)))"#,
        OK,
    );
    assert_problems(
        &found,
        &[
            "timeline[0].action.target: unknown node 'Q1'",
            "timeline[0].action.hits: EveryNth(0)",
            "timeline[0].action.frames: 0 overload frames in a row",
            "timeline[1].action.target: priority 32 is over 31",
            "timeline[1].action.hits: bit-error rate 2 is outside 0..1",
            "timeline[1].action.frames: 3 overload frames in a row",
            "timeline[2].action.until_s: the fault ends at 1 s, not after it starts (2 s)",
            "timeline[2].action.by[1]: unknown node 'F6'",
            "timeline[3].action.until_s: time 11 s is after the end of the run",
        ],
    );
}

#[test]
fn faults_end_after_they_start() {
    let found = problems(
        10.0,
        r#"(at_s: 3.0, action: BitErrors(target: Any, hits: Always, until_s: Some(3.0))),
           (at_s: 3.0, action: Babble(frame: "00000000#00", until_s: 2.0)),
           (at_s: 3.0, action: BitErrors(target: Any, hits: Always, until_s: Some(NaN)))"#,
        OK,
    );
    assert_problems(
        &found,
        &[
            "timeline[0].action.until_s: the fault ends at 3 s, not after it starts (3 s)",
            "timeline[1].action.until_s: the fault ends at 2 s, not after it starts (3 s)",
            "timeline[2].action.until_s: time NaN s is negative or not a number",
        ],
    );
}

/// A plant value out of its input's range passed validation, and the plant refused it in the
/// middle of the run, which ended it there.
#[test]
fn plant_values_and_sensor_faults_are_checked_before_the_run() {
    let found = problems(
        10.0,
        r#"(at_s: 1.0, action: Plant(input: "speed.setpoint", value: 50.0)),
           (at_s: 1.0, action: Plant(input: "speed.unload", value: 0.5)),
           (at_s: 1.0, action: Plant(input: "fault.door3_open", value: NaN)),
           (at_s: 1.0, action: Plant(input: "engine.rpm", value: 1.0)),
           (at_s: 1.0, action: Plant(input: "operator.speed", value: 12.0)),
           (at_s: 1.0, action: SensorFault(node: "D2", signal: "row3.unit1", fault: Stuck(inf)))"#,
        OK,
    );
    assert_problems(
        &found,
        &[
            "timeline[0].action.value: 50 is not 0..=12, the range of plant input speed.setpoint",
            "timeline[1].action.value: 0.5 is not 0 or 1, the range of plant input speed.unload",
            "timeline[2].action.value: NaN is not 0..=1, the range of plant input fault.door3_open",
            "timeline[3].action.input: 'engine.rpm' is not a plant input",
            "timeline[5].action.fault: Stuck(inf): not a finite number",
        ],
    );
}

/// A sensor fault names a node with sensors (not the monitor), a plant signal and a usable value;
/// past this, a node's logic could still refuse it while the run goes on.
#[test]
fn sensor_faults_name_a_node_with_sensors_and_a_plant_signal() {
    let found = problems(
        10.0,
        r#"(at_s: 1.0, action: SensorFault(node: "F5", signal: "engine.rpm", fault: Stuck(0.0))),
           (at_s: 1.0, action: SensorRepaired(node: "X9", signal: "engine.rpm")),
           (at_s: 1.0, action: SensorFault(node: "B1", signal: "engine.rmp", fault: Offset(1.0))),
           (at_s: 1.0, action: SensorFault(node: "B1", signal: "engine.rpm", fault: Noise(-1.0))),
           (at_s: 2.0, action: SensorRepaired(node: "B1", signal: "engine.rpm"))"#,
        OK,
    );
    assert_problems(
        &found,
        &[
            "timeline[0].action.node: the monitor has no sensors",
            "timeline[1].action.node: unknown node 'X9'",
            "timeline[2].action.signal: unknown plant signal 'engine.rmp'",
            "timeline[3].action.fault: Noise(-1): a standard deviation is not negative",
        ],
    );
}

#[test]
fn the_new_fields_have_their_defaults() {
    let text = r#"Scenario(name: "t", duration_s: 10.0, expect: [NoFrameLost], timeline: [
        (at_s: 1.0, action: BitErrors(target: Any, hits: Once)),
        (at_s: 1.0, action: Overload(target: Any, hits: Once)),
    ])"#;
    let loaded = from_text(Path::new("t.ron"), text, None, harvester).unwrap();
    match &loaded.scenario.timeline[0].action {
        Action::BitErrors { kind, seen_by, .. } => {
            assert_eq!((*kind, seen_by), (ErrorKind::Bit, &SeenBy::All))
        }
        other => panic!("{other:?}"),
    }
    match &loaded.scenario.timeline[1].action {
        Action::Overload {
            by, frames, until_s, ..
        } => assert_eq!((by.len(), *frames, *until_s), (0, 1, None)),
        other => panic!("{other:?}"),
    }
}

/// B2 sends `param.fan` (DLC 3: data bits 0 to 23) and nothing else; every field of `Disturb`,
/// `Counters` and `ErrorKinds` is checked.
#[test]
fn disturbances_counters_and_error_kinds_are_checked_field_by_field() {
    let sound = problems(
        10.0,
        r#"(at_s: 1.0, action: Disturb(target: Node("B2"), hits: Once, field: Data, bit: 23, level: Recessive)),
           (at_s: 1.0, action: Disturb(target: Node("B2"), hits: Once, field: ErrorFlag, bit: 5, level: Recessive,
               bits: 2, seen_by: Nodes(["F5", "B2"]))),
           (at_s: 2.0, action: Disturb(target: Any, hits: Always, until_s: Some(3.0), field: StuffBit, bit: 28,
               level: Dominant, bits: 4096))"#,
        r#"Counters(node: "B2", at_s: 1.5, tec: 263, rec: 255),
           ErrorKinds(node: "F5", kind: Crc, min: 0, max: 3, from_s: 1.0, to_s: Some(2.0)),
           ErrorKinds(node: "F5", kind: Ack, min: 1, max: 1)"#,
    );
    assert_problems(&sound, &[]);
    let found = problems(
        10.0,
        r#"(at_s: 1.0, action: Disturb(target: Node("B2"), hits: Once, field: Data, bit: 24, level: Recessive)),
           (at_s: 1.0, action: Disturb(target: Node("B2"), hits: Once, field: Eof, bit: 7, level: Dominant, bits: 0)),
           (at_s: 1.0, action: Disturb(target: Node("X1"), hits: EveryNth(0), until_s: Some(0.5), field: Sof, bit: 0,
               level: Dominant, bits: 4097, seen_by: Nodes([]))),
           (at_s: 1.0, action: Disturb(target: Any, hits: Once, field: Identifier, bit: 29, level: Dominant,
               seen_by: Nodes(["F5", "Q"])))"#,
        r#"Counters(node: "Z", at_s: 11.0, tec: 264, rec: 256),
           ErrorKinds(node: "F5", kind: Bit, min: 2, max: 1, from_s: 3.0, to_s: Some(2.0))"#,
    );
    assert_problems(
        &found,
        &[
            "timeline[0].action.bit: bit 24 of Data is in no frame B2 sends: its frames have at most 24 bit(s)",
            "timeline[1].action.bit: bit 7 is past the field Eof, which has at most 7 bit(s)",
            "timeline[1].action.bits: 0 bit times",
            "timeline[2].action.target: unknown node 'X1'",
            "timeline[2].action.hits: EveryNth(0)",
            "timeline[2].action.until_s: the fault ends at 0.5 s, not after it starts",
            "timeline[2].action.bits: 4097 bit times",
            "timeline[2].action.seen_by: Nodes([])",
            "timeline[3].action.bit: bit 29 is past the field Identifier",
            "timeline[3].action.seen_by[1]: unknown node 'Q'",
            "expect[0].node: unknown node 'Z'",
            "expect[0].at_s: time 11 s is after the end of the run",
            "expect[0].tec: TEC never exceeds 263",
            "expect[0].rec: REC never exceeds 255",
            "expect[1].to_s: the window 3 s to 2 s is empty",
            "expect[1].min: min 2 is above max 1",
        ],
    );
}

/// Unknown fields, levels and kinds are named with the ones accepted, at their line and column.
#[test]
fn unknown_names_in_the_new_steps_list_the_accepted_ones() {
    for (timeline, expect, needle) in [
        (
            r#"(at_s: 1.0, action: Disturb(target: Any, hits: Once, field: Ack, bit: 0, level: Dominant))"#,
            OK,
            "`Sof`, `Identifier`",
        ),
        (
            r#"(at_s: 1.0, action: Disturb(target: Any, hits: Once, field: Sof, bit: 0, level: High))"#,
            OK,
            "`Dominant` or `Recessive`",
        ),
        (
            "",
            r#"ErrorKinds(node: "F5", kind: Overload, min: 0, max: 1)"#,
            "`Form`, or `Ack`",
        ),
        (
            "",
            r#"Counters(node: "F5", at_s: 1.0, tec: 0, rec: 0, state: Active)"#,
            "`tec`, or `rec`",
        ),
        (
            r#"(at_s: 1.0, action: Disturb(target: Any, hits: Once, field: Sof, bit: 0, level: Dominant, length: 3))"#,
            OK,
            "`bits`, or `seen_by`",
        ),
    ] {
        let text =
            format!("Scenario(name: \"t\", duration_s: 5.0, timeline: [{timeline}], expect: [{expect}])");
        match from_text(Path::new("t.ron"), &text, None, harvester) {
            Err(Error::Invalid(p)) => {
                assert_eq!(p.len(), 1);
                assert!(p[0].position.is_some(), "{p:?}");
                assert!(p[0].message.contains(needle), "{needle} in {}", p[0].message);
            }
            other => panic!("{text}: {:?}", other.err()),
        }
    }
}

/// A problem found after parsing points at its field's line and column.
#[test]
fn problems_after_parsing_have_a_line_and_column() {
    let text = "Scenario(name: \"t\", duration_s: 5.0,\n  timeline: [\n    (at_s: 1.0, action: Disturb(target: Any, hits: Once,\n      field: Crc, bit: 15, level: Dominant)),\n  ],\n  expect: [NoFrameLost])";
    match from_text(Path::new("t.ron"), text, None, harvester) {
        Err(Error::Invalid(p)) => {
            assert_eq!(p.len(), 1, "{p:?}");
            assert_eq!(p[0].field.as_deref(), Some("timeline[0].action.bit"));
            assert_eq!(p[0].position, Some((4, 19)));
        }
        other => panic!("{:?}", other.err()),
    }
}
