//! Scripts of a network from a DBC file: messages and signals from the database, generators,
//! reactions to the database's frames. Expected payloads are worked out by hand from the DBC
//! text below (bit numbering as docs/DBC.md gives it).

use super::*;
use protocol::database::Database;
use std::sync::Arc;

const DBC: &str = r#"VERSION ""
NS_ :
BS_:
BU_: ENGINE BRAKE
BO_ 2566844926 EEC1: 8 ENGINE
 SG_ EngineSpeed : 24|16@1+ (0.125,0) [0|8031.875] "rpm" BRAKE
 SG_ Torque : 16|8@1- (1,-125) [-125|125] "%" BRAKE
BO_ 256 Brake: 4 BRAKE
 SG_ Mode M : 7|8@0+ (1,0) [0|2] "" ENGINE
 SG_ Pressure m1 : 15|16@0+ (0.1,0) [0|250] "bar" ENGINE
 SG_ Temp m2 : 15|8@0- (1,0) [-40|125] "C" ENGINE
"#;

fn dbc_node(text: &str) -> ScriptedNode {
    let mut script = parse("dbc.ron", text).unwrap();
    script.db = Some(Arc::new(Database::parse("t.dbc", DBC).unwrap()));
    let problems = validate("dbc.ron", &script, &FakeSignals);
    assert!(problems.is_empty(), "{problems:?}");
    let env: SharedEnv = Rc::new(RefCell::new(Fake::default()));
    ScriptedNode::new(script, env, BusTime::ZERO, 7)
}

const ENGINE: &str = r#"NodeScript(
    name: "ENGINE", database: Some("t.dbc"),
    filter: SocketCan([(can_id: "0x100", can_mask: "0x7FF")]),
    states: [(name: "running", code: 1)], initial: "running",
    messages: [(name: "EEC1", frames: [(message: "EEC1", fields: {
        "EngineSpeed": Ramp(from: 1000.0, to: 2000.0, period_s: 0.1),
        "Torque": Counter(from: -2.0, to: 1.0, step: 1.0),
    })], when: Periodic(period_ms: 20, phase_ms: 0))],
)"#;

#[test]
fn a_dbc_node_sends_its_messages_with_generated_signals() {
    let mut n = dbc_node(ENGINE);
    let sent = drive(&mut n, BusTime::from_millis(119), &[]);
    let got: Vec<(u64, u32, Vec<u8>)> = sent
        .iter()
        .map(|(t, f)| (t.as_nanos() / 1_000_000, f.raw_id(), f.data().to_vec()))
        .collect();
    // EngineSpeed rises 1000 -> 2000 rpm over 100 ms (raw 8000 + 1600 per 20 ms, at bytes
    // 3..4 low byte first); Torque counts -2, -1, 0, 1, -2, ... (raw +125: 123, 124, ...).
    let frame = |speed: u16, torque: u8| {
        let [lo, hi] = speed.to_le_bytes();
        vec![0, 0, torque, lo, hi, 0, 0, 0]
    };
    assert_eq!(
        got,
        vec![
            (0, 0x18FE_F1FE, frame(8000, 123)),
            (20, 0x18FE_F1FE, frame(9600, 124)),
            (40, 0x18FE_F1FE, frame(11200, 125)),
            (60, 0x18FE_F1FE, frame(12800, 126)),
            (80, 0x18FE_F1FE, frame(14400, 123)),
            (100, 0x18FE_F1FE, frame(8000, 124)),
        ]
    );
    assert!(sent.iter().all(|(_, f)| f.is_extended()));
}

#[test]
fn a_dbc_node_answers_frames_of_the_database_by_their_signals() {
    let text = r#"NodeScript(
        name: "BRAKE", database: Some("t.dbc"),
        filter: SocketCan([(can_id: "0x98FEF1FE", can_mask: "0xDFFFFFFF")]),
        states: [(name: "running", code: 1)], initial: "running",
        vars: {"torque": 0.0},
        messages: [(name: "Brake", frames: [(message: "Brake", fields: {"Mode": Const(2.0), "Temp": Var("torque")})],
                    when: OnRequest)],
        reactions: [(message: "EEC1", when: {"Torque": 120.0}, actions: [Set("torque", Field("Torque")), Send("Brake")])],
    )"#;
    let mut n = dbc_node(text);
    let eec1 = |torque_raw: u8| Frame::extended(0x18FE_F1FE, &[0, 0, torque_raw, 0, 0, 0, 0, 0]).unwrap();
    let inbox = [
        (BusTime::from_millis(5), eec1(100)),
        (BusTime::from_millis(10), eec1(120)),
    ];
    let sent = drive(&mut n, BusTime::from_millis(50), &inbox);
    // Only the second matches raw 120; Torque = 120 - 125 = -5 C goes out as Temp, big-endian
    // byte 1, with Mode 2 in byte 0.
    let got: Vec<(u64, u32, Vec<u8>)> = sent
        .iter()
        .map(|(t, f)| (t.as_nanos() / 1_000_000, f.raw_id(), f.data().to_vec()))
        .collect();
    assert_eq!(got, vec![(10, 0x100, vec![2, 0xFB, 0, 0])]);
    assert!(!sent[0].1.is_extended());
}

#[test]
fn names_the_database_lacks_are_problems() {
    let mut script = parse("dbc.ron", ENGINE).unwrap();
    script.db = Some(Arc::new(Database::parse("t.dbc", DBC).unwrap()));
    script.messages[0].frames[0].message = "EEC2".into();
    script.address = 0xB1;
    script.reactions.push(Reaction {
        message: "Brake".into(),
        when: [("Nope".to_string(), 1.0)].into(),
        states: vec![],
        actions: vec![Action::Set("x".into(), Expr::Field("Pressure".into()))],
    });
    let said: Vec<String> = validate("dbc.ron", &script, &FakeSignals)
        .iter()
        .map(|p| format!("{}: {}", p.field.as_deref().unwrap_or(""), p.message))
        .collect();
    assert_eq!(
        said,
        [
            "address: a node of a network from a DBC file has no harvester address: leave `address` and `kind` out",
            "messages[0] (EEC1).frames[0].message: 'EEC2' is not a message of the database",
            "reactions[0] (Brake).when.Nope: Brake has no field 'Nope'",
            "reactions[0] (Brake).actions[0]: unknown variable 'x'",
        ]
    );
    // Read without its file, the database cannot be had.
    let script = parse("dbc.ron", ENGINE).unwrap();
    let said = validate("dbc.ron", &script, &FakeSignals);
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(
        said[0]
            .message
            .contains("the database is read when the script is loaded from its file")
    );
}

#[test]
fn generators_with_numbers_that_mean_nothing_are_problems() {
    let mut script = parse("dbc.ron", ENGINE).unwrap();
    script.db = Some(Arc::new(Database::parse("t.dbc", DBC).unwrap()));
    let fields = &mut script.messages[0].frames[0].fields;
    fields.insert(
        "EngineSpeed".into(),
        Expr::Sine {
            mean: 1.0,
            amplitude: f64::NAN,
            period_s: 0.0,
        },
    );
    fields.insert(
        "Torque".into(),
        Expr::Counter {
            from: 5.0,
            to: 1.0,
            step: 1.0,
        },
    );
    let said: Vec<String> = validate("dbc.ron", &script, &FakeSignals)
        .iter()
        .map(|p| p.message.clone())
        .collect();
    assert_eq!(
        said,
        [
            "Sine amplitude is NaN, not a finite number",
            "Sine period_s is 0, not a positive finite number",
            "Counter step 1 never takes 5 to 1",
        ]
    );
}

#[test]
fn a_random_walk_as_wide_as_f64_goes_never_panics() {
    let text = ENGINE.replace(
        "Ramp(from: 1000.0, to: 2000.0, period_s: 0.1)",
        "RandomWalk(start: 0.0, step: 1e308, min: -1e308, max: 1e308)",
    );
    assert_ne!(text, ENGINE);
    let mut n = dbc_node(&text);
    let sent = drive(&mut n, BusTime::from_millis(199), &[]);
    // Every 20 ms, EngineSpeed within its range: raw 0 to 8031.875 rpm / 0.125 = 64255.
    assert_eq!(sent.len(), 10);
    for (_, f) in &sent {
        let speed = u16::from_le_bytes([f.data()[3], f.data()[4]]);
        assert!(speed <= 64255, "{speed}");
    }
}
