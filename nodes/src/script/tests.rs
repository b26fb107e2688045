use super::*;
use bus::Frame;
use bus::candump::parse_frame;
use bus::node::NodeLogic;
use bus::time::BusTime;
use protocol::catalogue;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;

/// A plant stand-in: named values, some of them inputs, a log of writes.
#[derive(Default)]
struct Fake {
    values: BTreeMap<String, f64>,
    writes: Vec<(String, f64)>,
    now: BusTime,
}

/// The fake plant's signals; a port is the index of its name here.
const FAKE_SIGNALS: [&str; 5] = [
    "row3.unit1",
    "engine.rpm",
    "speed.actual",
    "speed.mode_request",
    "speed.setpoint",
];

impl Environment for Fake {
    fn advance_to(&mut self, t: BusTime) {
        self.now = self.now.max(t);
    }
    fn port(&self, name: &str) -> Option<Port> {
        FAKE_SIGNALS
            .iter()
            .position(|n| *n == name)
            .map(|i| Port(i as u32))
    }
    fn read(&self, port: Port) -> Option<f64> {
        self.values.get(FAKE_SIGNALS[port.0 as usize]).copied()
    }
    fn write(&mut self, port: Port, value: f64) -> bool {
        let name = FAKE_SIGNALS[port.0 as usize];
        self.writes.push((name.to_string(), value));
        self.values.insert(name.to_string(), value);
        true
    }
}

struct FakeSignals;
impl Signals for FakeSignals {
    fn is_signal(&self, name: &str) -> bool {
        FAKE_SIGNALS.contains(&name)
    }
    fn is_input(&self, name: &str) -> bool {
        name.starts_with("speed.")
    }
}

const B1: &str = r#"
NodeScript(
    address: 0xB1, name: "B1", kind: Parameter, boot_delay_ms: 10,
    filter: Atmel(canidt: "28 05 8F A8", canidm: "FF FF FF FD", ide: true),
    states: [(name: "boot", code: 0), (name: "running", code: 1)],
    initial: "running",
    messages: [(name: "p", frames: [(message: "param.engine", fields: {"engine_rpm": Signal("engine.rpm")})],
                when: Periodic(period_ms: 100, phase_ms: 5))],
)"#;

fn node(text: &str, values: &[(&str, f64)]) -> (ScriptedNode, Rc<RefCell<Fake>>) {
    let script = parse("test.ron", text).unwrap();
    let problems = validate("test.ron", &script, &FakeSignals);
    assert!(problems.is_empty(), "{problems:?}");
    let fake = Rc::new(RefCell::new(Fake::default()));
    for (k, v) in values {
        fake.borrow_mut().values.insert(k.to_string(), *v);
    }
    let env: SharedEnv = fake.clone();
    (ScriptedNode::new(script, env, BusTime::from_millis(500), 1), fake)
}

/// Drives a logic alone until `until`, feeding it `inbox` frames at their times; returns what it
/// sent with the time it was polled.
fn drive(n: &mut ScriptedNode, until: BusTime, inbox: &[(BusTime, Frame)]) -> Vec<(BusTime, Frame)> {
    let mut out = Vec::new();
    let mut inbox = inbox.iter().peekable();
    loop {
        let t = n.poll_timeout().unwrap_or(BusTime::NEVER);
        let f = inbox.peek().map_or(BusTime::NEVER, |(t, _)| *t);
        let now = t.min(f);
        if now > until {
            break;
        }
        if f <= t {
            let (at, frame) = inbox.next().unwrap();
            n.handle_frame(*at, frame);
        } else {
            n.handle_timeout(now);
        }
        while let Some(frame) = n.poll_transmit() {
            out.push((now, frame));
        }
    }
    out
}

#[test]
fn periodic_messages_follow_boot_phase_and_period() {
    let (mut n, _) = node(B1, &[("engine.rpm", 2150.0)]);
    let sent = drive(&mut n, BusTime::from_millis(800), &[]);
    // Power on at 500 ms, boot 10 ms, phase 5 ms: 515, 615, 715 ms.
    let times: Vec<u64> = sent.iter().map(|(t, _)| t.as_nanos() / 1_000_000).collect();
    assert_eq!(times, [515, 615, 715]);
    let d = catalogue::decode(&sent[0].1).unwrap().unwrap();
    assert_eq!((d.message.name, d.node.0), ("param.engine", 0xB1));
    assert_eq!(d.get("engine_rpm").unwrap().physical, 2150.0);
}

#[test]
fn values_out_of_range_saturate() {
    let (mut n, _) = node(B1, &[("engine.rpm", 99_999.0)]);
    let sent = drive(&mut n, BusTime::from_millis(520), &[]);
    let d = catalogue::decode(&sent[0].1).unwrap().unwrap();
    assert_eq!(
        d.get("engine_rpm").unwrap().physical,
        3000.0,
        "the catalogue's maximum"
    );
}

#[test]
fn fault_hooks_change_what_the_node_reads() {
    let (mut n, _) = node(B1, &[("engine.rpm", 2000.0)]);
    n.set_fault("engine.rpm", Some(FaultKind::Offset(150.0)), BusTime::ZERO);
    let sent = drive(&mut n, BusTime::from_millis(520), &[]);
    let rpm = |f: &Frame| {
        catalogue::decode(f)
            .unwrap()
            .unwrap()
            .get("engine_rpm")
            .unwrap()
            .physical
    };
    assert_eq!(rpm(&sent[0].1), 2150.0);
    n.set_fault(
        "engine.rpm",
        Some(FaultKind::Stuck(1234.0)),
        BusTime::from_millis(520),
    );
    let sent = drive(&mut n, BusTime::from_millis(620), &[]);
    assert_eq!(rpm(&sent[0].1), 1234.0);
    n.set_fault(
        "engine.rpm",
        Some(FaultKind::Drift(10.0)),
        BusTime::from_millis(615),
    );
    let sent = drive(&mut n, BusTime::from_millis(2615), &[]);
    // 2 s after the fault began (615 -> 2615 ms): +20 rpm.
    assert_eq!(rpm(&sent.last().unwrap().1), 2020.0);
    n.set_fault("engine.rpm", Some(FaultKind::Dropout), BusTime::from_millis(2615));
    assert!(drive(&mut n, BusTime::from_millis(3000), &[]).is_empty());
    assert!(n.counts().1 >= 3, "dropped sends are counted");
    n.set_fault("engine.rpm", None, BusTime::from_millis(3000));
    assert_eq!(rpm(&drive(&mut n, BusTime::from_millis(3100), &[])[0].1), 2000.0);
}

/// A scenario reaches a script's fault hooks through the node interface alone, with no
/// knowledge of the logic behind it: each kind arrives as the same kind.
#[test]
fn injected_sensor_faults_reach_the_fault_hooks() {
    use bus::node::{NodeFault, SensorFault};
    let (mut n, _) = node(B1, &[("engine.rpm", 2000.0)]);
    let rpm = |sent: &[(BusTime, Frame)]| {
        catalogue::decode(&sent.last().unwrap().1)
            .unwrap()
            .unwrap()
            .get("engine_rpm")
            .unwrap()
            .physical
    };
    let inject = |n: &mut ScriptedNode, reads: Option<SensorFault>, ms: u64| {
        let signal = "engine.rpm".to_string();
        let fault = match reads {
            Some(reads) => NodeFault::Sensor { signal, reads },
            None => NodeFault::SensorRepaired { signal },
        };
        let logic: &mut dyn NodeLogic = n;
        logic.inject(&fault, BusTime::from_millis(ms)).unwrap();
    };
    inject(&mut n, Some(SensorFault::Offset(150.0)), 0);
    assert_eq!(rpm(&drive(&mut n, BusTime::from_millis(520), &[])), 2150.0);
    inject(&mut n, Some(SensorFault::Stuck(1234.0)), 520);
    assert_eq!(rpm(&drive(&mut n, BusTime::from_millis(620), &[])), 1234.0);
    inject(&mut n, Some(SensorFault::Drift(10.0)), 615);
    // 2 s after the fault began: +20 rpm.
    assert_eq!(rpm(&drive(&mut n, BusTime::from_millis(2615), &[])), 2020.0);
    inject(&mut n, Some(SensorFault::Dropout), 2615);
    assert!(drive(&mut n, BusTime::from_millis(3000), &[]).is_empty());
    inject(&mut n, None, 3000);
    assert_eq!(rpm(&drive(&mut n, BusTime::from_millis(3100), &[])), 2000.0);
}

const E0: &str = r#"
NodeScript(
    address: 0xE0, name: "E0", kind: SpeedControl,
    filter: Sja1000(mode: Single, acr: "10 07 07 A8", amr: "00 00 00 03"),
    states: [(name: "boot", code: 0), (name: "manual", code: 0), (name: "cruise", code: 1)],
    initial: "manual",
    vars: {"timeout": 0},
    messages: [(name: "status", frames: [(message: "speed.status", fields: {
        "actual": Signal("speed.actual"), "setpoint": Var("timeout"), "mode": StateCode,
        "operator_override": Const(0), "setpoint_timeout": Var("timeout")})],
        when: Periodic(period_ms: 50))],
    reactions: [
        (message: "speed.mode", when: {"mode": 1}, actions: [SetState("cruise"), Write("speed.mode_request", Const(1))]),
        (message: "speed.setpoint", actions: [Write("speed.setpoint", Field("setpoint")), Restart("watchdog")]),
    ],
    timers: [(name: "watchdog", after_ms: 1000, states: ["cruise"], actions: [Set("timeout", Const(1)), SetState("manual")])],
)"#;

#[test]
fn reactions_write_inputs_and_watchdogs_fire() {
    let (mut n, fake) = node(E0, &[("speed.actual", 5.0)]);
    let at = |ms| BusTime::from_millis(ms);
    let inbox = [
        (at(600), parse_frame("0200E0F5#0101").unwrap()), // speed.mode cruise
        (at(700), parse_frame("0200E0F5#02F401").unwrap()), // speed.setpoint 5.00 km/h
        (at(1200), parse_frame("0200E0F5#025802").unwrap()), // 6.00 km/h
    ];
    let sent = drive(&mut n, at(3000), &inbox);
    assert_eq!(
        fake.borrow().writes,
        [
            ("speed.mode_request".to_string(), 1.0),
            ("speed.setpoint".to_string(), 5.0),
            ("speed.setpoint".to_string(), 6.0)
        ]
    );
    let mode_at = |ms: u64| {
        let f = sent
            .iter()
            .rev()
            .find(|(t, _)| t.as_nanos() <= ms * 1_000_000)
            .unwrap()
            .1;
        catalogue::decode(&f).unwrap().unwrap().get("mode").unwrap().raw
    };
    assert_eq!(
        (mode_at(650), mode_at(2150)),
        (1, 1),
        "cruise while set-points keep coming"
    );
    // The last set-point came at 1200 ms: the watchdog fires at 2200 ms.
    assert_eq!(mode_at(2250), 0);
    assert_eq!(n.var("timeout"), Some(1.0));
    assert_eq!(n.state(), "manual");
}

const FLOW: &str = r#"
NodeScript(
    address: 0xD2, name: "D2", kind: FlowSensor, boot_delay_ms: 0,
    filter: SocketCan([(can_id: "0x8601D2F5", can_mask: "0xDFFFFFFF")]),
    states: [(name: "boot", code: 0), (name: "running", code: 3), (name: "no acknowledgement", code: 4)],
    initial: "running",
    vars: {"missed": 0},
    messages: [(name: "flow", frames: [
        (message: "flow.marker_flow"),
        (message: "flow.part1", fields: {"status": Const(1), "unit1": Signal("row3.unit1"), "unit2": Const(2), "unit3": Const(3)}),
        (message: "flow.part2", fields: {"unit4": Const(4), "unit5": Const(5), "aux": Const(0)})],
        when: Periodic(period_ms: 100), states: ["running"],
        ack: Some((limit: 3, timeout_ms: 50, state: "no acknowledgement", count_var: Some("missed"))))],
    reactions: [
        (message: "flow.ack", actions: [Acknowledged]),
        (message: "flow.calibrate", when: {"command": 2}, actions: [Acknowledged, SetState("running")]),
    ],
)"#;

#[test]
fn unacknowledged_groups_stop_the_stream() {
    let (mut n, _) = node(FLOW, &[("row3.unit1", 77.0)]);
    let at = |ms| BusTime::from_millis(ms);
    let ack = parse_frame("0601D2F5#210D01").unwrap();
    // Acks for the first two groups only.
    let sent = drive(&mut n, at(1500), &[(at(501), ack), (at(601), ack)]);
    let groups: Vec<u64> = sent.chunks(3).map(|c| c[0].0.as_nanos() / 1_000_000).collect();
    // Groups at 500, 600 (acked), then 700, 800, 900 unacknowledged: the third stops it.
    assert_eq!(groups, [500, 600, 700, 800, 900]);
    assert_eq!(n.state(), "no acknowledgement");
    assert_eq!(n.var("missed"), Some(3.0));
    let d = catalogue::decode(&sent[1].1).unwrap().unwrap();
    assert_eq!(d.get("unit1").unwrap().raw, 77);
    // Accepting again resumes it.
    let resume = parse_frame("0601D2F5#1002102705").unwrap();
    let sent = drive(&mut n, at(1750), &[(at(1550), resume)]);
    assert_eq!(sent.len(), 6, "groups at 1600 and 1700");
}

/// With `resume`, a plain acknowledgement brings a sensor that gave up back to streaming (the
/// connection-oriented exchange picks up again); without it, only the accept command does.
#[test]
fn an_acknowledgement_resumes_a_sensor_that_gave_up_when_the_script_says_so() {
    let at = |ms| BusTime::from_millis(ms);
    let ack = parse_frame("0601D2F5#210D07").unwrap();
    for resume in [false, true] {
        let script = FLOW.replace(
            "count_var: Some(\"missed\"))",
            &format!("count_var: Some(\"missed\"), resume: {resume})"),
        );
        let (mut n, _) = node(&script, &[("row3.unit1", 77.0)]);
        // Groups at 500, 600, 700 go unanswered; the third is overdue at 750 ms.
        let sent = drive(&mut n, at(1000), &[]);
        assert_eq!(sent.len(), 9, "resume: {resume}");
        assert_eq!(n.state(), "no acknowledgement", "resume: {resume}");
        // An acknowledgement at 1010 ms; groups keep their 100 ms grid: 1100, 1200.
        let sent = drive(&mut n, at(1250), &[(at(1010), ack)]);
        let groups: Vec<u64> = sent.chunks(3).map(|c| c[0].0.as_nanos() / 1_000_000).collect();
        if resume {
            assert_eq!(n.state(), "running");
            assert_eq!(groups, [1100, 1200]);
            // Counting starts again from 0: the groups at 1100 and 1200 ms fell due unanswered
            // at 1150 and 1250 ms, two of the three it takes to give up again.
            assert_eq!(n.var("missed"), Some(2.0));
        } else {
            assert_eq!(n.state(), "no acknowledgement");
            assert!(groups.is_empty(), "{groups:?}");
        }
    }
}

/// A node resumes in the state it gave up in, not in some fixed one: one that gave up while
/// calibrating goes back to calibrating.
#[test]
fn a_node_resumes_in_the_state_it_gave_up_in() {
    let script = FLOW
        .replace(
            r#"(name: "running", code: 3),"#,
            r#"(name: "calibrating", code: 2), (name: "running", code: 3),"#,
        )
        .replace(r#"initial: "running""#, r#"initial: "calibrating""#)
        .replace(r#"states: ["running"]"#, r#"states: ["calibrating", "running"]"#)
        .replace(
            "count_var: Some(\"missed\"))",
            "count_var: Some(\"missed\"), resume: true)",
        );
    let (mut n, _) = node(&script, &[("row3.unit1", 77.0)]);
    let at = |ms| BusTime::from_millis(ms);
    drive(&mut n, at(1000), &[]);
    assert_eq!(n.state(), "no acknowledgement");
    let ack = parse_frame("0601D2F5#210D07").unwrap();
    drive(&mut n, at(1050), &[(at(1010), ack)]);
    assert_eq!(n.state(), "calibrating");
}

/// Each group acknowledged 5 ms after it went out, well within the 50 ms timeout: at no moment
/// does the node count a missed acknowledgement.
#[test]
fn acknowledgements_on_their_way_are_not_missed() {
    let (mut n, _) = node(FLOW, &[("row3.unit1", 77.0)]);
    let ack = parse_frame("0601D2F5#210D01").unwrap();
    let mut inbox: Vec<(BusTime, Frame)> = (0..10)
        .map(|g| (BusTime::from_millis(505 + 100 * g), ack))
        .collect();
    let mut groups = 0;
    for ms in 500..1500 {
        let due: Vec<_> = inbox
            .iter()
            .filter(|(t, _)| t.as_nanos() <= ms * 1_000_000)
            .copied()
            .collect();
        inbox.retain(|(t, _)| t.as_nanos() > ms * 1_000_000);
        groups += drive(&mut n, BusTime::from_millis(ms), &due).len() / 3;
        assert_eq!(n.var("missed"), Some(0.0), "at {ms} ms");
    }
    assert_eq!(groups, 10, "groups at 500, 600, ... 1400 ms");
    assert_eq!(n.state(), "running");
}

/// A group's acknowledgement is due 50 ms after it: it counts as missed at that moment, not
/// before, and an acknowledgement clears the count.
#[test]
fn a_group_is_missed_once_its_acknowledgement_is_overdue() {
    let (mut n, _) = node(FLOW, &[("row3.unit1", 77.0)]);
    let at = BusTime::from_millis;
    assert_eq!(drive(&mut n, at(549), &[]).len(), 3, "the group at 500 ms");
    assert_eq!(n.var("missed"), Some(0.0), "due at 550 ms");
    drive(&mut n, at(550), &[]);
    assert_eq!(n.var("missed"), Some(1.0));
    // The group at 600 ms is acknowledged late but within its time: the count starts again.
    let ack = parse_frame("0601D2F5#210D02").unwrap();
    drive(&mut n, at(640), &[(at(640), ack)]);
    assert_eq!(n.var("missed"), Some(0.0));
    drive(&mut n, at(749), &[]);
    assert_eq!(n.var("missed"), Some(0.0), "the group at 700 ms is due at 750 ms");
    drive(&mut n, at(750), &[]);
    assert_eq!(n.var("missed"), Some(1.0));
    assert_eq!(n.state(), "running");
}

#[test]
fn every_problem_is_reported_at_once() {
    let bad = r#"
NodeScript(
    address: 0xB1, name: "B1", kind: Alarm,
    filter: Atmel(canidt: "18 05 07", canidm: "FF FF FF FG", ide: true),
    states: [(name: "boot", code: 0), (name: "boot", code: 1)],
    initial: "runing",
    messages: [
        (name: "p", frames: [(message: "param.engine", fields: {"engine_rpm": Signal("engine.rmp"), "torque": Const(1)})],
         when: Periodic(period_ms: 0)),
        (name: "q", frames: [(message: "param.engine", fields: {})], when: OnChange(heartbeat_ms: 0)),
        (name: "r", frames: [(message: "no.such")], when: OnRequest),
        (name: "s", frames: [(message: "flow.ack")], when: OnRequest),
    ],
    reactions: [(message: "row.command", actions: [SetState("nowhere"), Write("engine.rpm", Field("x")), Start("zz")])],
    timers: [(name: "t", after_ms: 0, actions: [Restart("u")])],
)"#;
    let script = parse("bad.ron", bad).unwrap();
    let problems = validate("bad.ron", &script, &FakeSignals);
    let text: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
    let expect = [
        "kind: address B1 belongs to the kind 'parameter module', not 'alarm module'",
        "states: 'boot' is defined twice",
        "initial: unknown state 'runing'",
        "fields.engine_rpm: unknown plant signal 'engine.rmp'",
        "fields.torque: param.engine has no field 'torque'",
        "(p).when: period 0",
        "(q).when: heartbeat 0",
        "no value for field 'engine_rpm' of param.engine",
        "duplicate message param.engine: both send it in the same states",
        "'no.such' is not in the message catalogue",
        "flow.ack is not a message of node B1",
        "row.command is not a message of node B1",
        "actions[0]: unknown state 'nowhere'",
        "'engine.rpm' is not a plant input",
        "unknown message 'zz'",
        "(t).after_ms: delay 0",
        "unknown timer 'u'",
        "filter.canidt: '18 05 07' has 3 bytes: the filter has four registers",
        "filter.canidm: 'FF FF FF FG': 'FG' is not a hex byte",
    ];
    for e in expect {
        assert!(
            text.iter().any(|t| t.contains(e)),
            "missing '{e}' in:\n{}",
            text.join("\n")
        );
    }
    assert!(
        text.iter().all(|t| t.starts_with("bad.ron: node B1: ")),
        "{text:?}"
    );
}

/// E0's test script with another filter line.
fn e0_with_filter(filter: &str) -> NodeScript {
    let text = E0.replace(
        r#"filter: Sja1000(mode: Single, acr: "10 07 07 A8", amr: "00 00 00 03"),"#,
        &format!("filter: {filter},"),
    );
    assert!(text.contains(&format!("filter: {filter},")));
    parse("test.ron", &text).unwrap()
}

fn problems_of(script: &NodeScript) -> Vec<String> {
    validate("test.ron", script, &FakeSignals)
        .iter()
        .map(|p| p.to_string())
        .collect()
}

#[test]
fn declared_filters_become_the_chips_registers() {
    use bus::engine::Filter;
    use bus::filter::{AtmelFilter, Sja1000Filter, Sja1000Mode, SocketCanFilter, SocketCanFilterSet};
    let filter = |text: &str| e0_with_filter(text).filter.to_filter().unwrap();
    // The seed's A0 registers, in three spellings.
    let seed = Filter::Atmel(AtmelFilter {
        idt: [0x18, 0x05, 0x07, 0xA8],
        idm: [0xFF, 0xFF, 0xFF, 0xFD],
        ide: true,
        ide_mask: true,
    });
    for idt in ["18 05 07 A8", "0x18 0x05 0x07 0xA8", "180507a8", "0x180507A8"] {
        let text = format!(r#"Atmel(canidt: "{idt}", canidm: "FF FF FF FD", ide: true)"#);
        assert_eq!(filter(&text), seed, "{idt}");
    }
    // IDEMSK is CANIDM4 bit 0: clear, the message object takes either format.
    let Filter::Atmel(open) = filter(r#"Atmel(canidt: "18 05 07 A8", canidm: "FF FF FF FC", ide: true)"#)
    else {
        panic!("an Atmel filter");
    };
    assert!(!open.ide_mask);
    assert_eq!(
        filter(r#"Sja1000(mode: Dual, acr: "10 07 10 07", amr: "00 00 00 00")"#),
        Filter::Sja1000(Sja1000Filter {
            mode: Sja1000Mode::Dual,
            acr: [0x10, 0x07, 0x10, 0x07],
            amr: [0; 4],
        })
    );
    assert_eq!(
        filter(
            r#"SocketCan([(can_id: "0x8200E0F5", can_mask: "DFFFFFFF"), (can_id: "0", can_mask: "0x0")])"#
        ),
        Filter::SocketCan(SocketCanFilterSet(vec![
            SocketCanFilter::new(0x8200_E0F5, 0xDFFF_FFFF),
            SocketCanFilter::new(0, 0),
        ]))
    );
}

#[test]
fn bad_filter_registers_are_reported_with_file_node_and_field() {
    let cases = [
        (
            r#"Atmel(canidt: "18 05 07 A8 00", canidm: "FF FF FF FD", ide: true)"#,
            vec![
                "test.ron: node E0: filter.canidt: '18 05 07 A8 00' has 5 bytes: the filter has four registers",
            ],
        ),
        (
            r#"Atmel(canidt: "180507A", canidm: "FF FF FF FD", ide: true)"#,
            vec![
                r#"test.ron: node E0: filter.canidt: '180507A' is not four register bytes: write them as "18 05 07 A8""#,
            ],
        ),
        (
            r#"Sja1000(mode: Single, acr: "10 07 07 A8", amr: "00 00 0 003")"#,
            vec!["test.ron: node E0: filter.amr: '00 00 0 003': '0' is not a hex byte"],
        ),
        (
            r#"Sja1000(mode: Single, acr: "1O 07 07 A8", amr: "")"#,
            vec![
                "test.ron: node E0: filter.acr: '1O 07 07 A8': '1O' is not a hex byte",
                "test.ron: node E0: filter.amr: '' has 0 bytes: the filter has four registers",
            ],
        ),
        (
            r#"SocketCan([(can_id: "0x8200E0F5", can_mask: "0x1DFFFFFFF"), (can_id: "E0F5h", can_mask: "0x")])"#,
            vec![
                "test.ron: node E0: filter[0].can_mask: '0x1DFFFFFFF' is wider than the 32 bits of a can_id",
                "test.ron: node E0: filter[1].can_id: 'E0F5h' is not a hex number",
                "test.ron: node E0: filter[1].can_mask: '0x' is not a hex number",
            ],
        ),
        (
            "SocketCan([])",
            vec![
                "test.ron: node E0: filter: an empty filter list receives nothing: list at least one filter",
            ],
        ),
    ];
    for (filter, expected) in cases {
        assert_eq!(problems_of(&e0_with_filter(filter)), expected, "{filter}");
    }
}

/// E0 reacts to `speed.mode` and `speed.setpoint`, both on identifier 0200E0F5: a filter that
/// drops that identifier is a problem, reported once for it.
#[test]
fn a_filter_that_rejects_the_scripts_own_frames_is_reported() {
    let rejected =
        "test.ron: node E0: filter: rejects speed.mode (identifier 0200E0F5), which reactions[0] answers";
    let cases = [
        // A0's registers from the seed.
        r#"Atmel(canidt: "18 05 07 A8", canidm: "FF FF FF FD", ide: true)"#,
        // E0's identifier, but a base-frame message object that compares IDE.
        r#"Atmel(canidt: "10 07 07 A8", canidm: "FF FF FF FD", ide: false)"#,
        // E0's identifier, remote frames only (RTRTAG set, RTRMSK set).
        r#"Atmel(canidt: "10 07 07 AC", canidm: "FF FF FF FD", ide: true)"#,
        // ACR off by the lowest source bit, compared.
        r#"Sja1000(mode: Single, acr: "10 07 07 B0", amr: "00 00 00 03")"#,
        // Dual mode compares ID28..13: 0200E0F5 >> 13 = 0x1007; 0x1008 in both halves.
        r#"Sja1000(mode: Dual, acr: "10 08 10 08", amr: "00 00 00 00")"#,
        // The kernel's exact filter, for a base frame.
        r#"SocketCan([(can_id: "0x0F5", can_mask: "0xC00007FF")])"#,
        // The exact filter, inverted.
        r#"SocketCan([(can_id: "0xA200E0F5", can_mask: "0xDFFFFFFF")])"#,
    ];
    for filter in cases {
        assert_eq!(problems_of(&e0_with_filter(filter)), [rejected], "{filter}");
    }
    let accepted = [
        r#"Atmel(canidt: "10 07 07 A8", canidm: "FF FF FF FD", ide: true)"#,
        // Only the destination byte compared (ID15..8 = CANIDT2 bits 2:0, CANIDT3 bits 7:3).
        r#"Atmel(canidt: "00 07 07 00", canidm: "00 07 F8 00", ide: true)"#,
        r#"Sja1000(mode: Single, acr: "10 07 07 A8", amr: "00 00 00 03")"#,
        r#"Sja1000(mode: Dual, acr: "FF FF 10 07", amr: "00 00 00 00")"#,
        r#"SocketCan([(can_id: "0x8601D0F5", can_mask: "0xDFFFFFFF"), (can_id: "0x8000E000", can_mask: "0x8000FF00")])"#,
    ];
    for filter in accepted {
        assert_eq!(
            problems_of(&e0_with_filter(filter)),
            Vec::<String>::new(),
            "{filter}"
        );
    }
}

#[test]
fn syntax_errors_have_a_position() {
    let err = parse("x.ron", "NodeScript(\n  address: 0xB1,\n  nmae: \"B1\",\n)").unwrap_err();
    let text = err.to_string();
    assert!(text.contains("x.ron:3:"), "{text}");
}

const C1: &str = r#"
NodeScript(
    address: 0xC1, name: "C1", kind: Alarm,
    filter: Atmel(canidt: "20 06 0F A8", canidm: "FF FF FF FD", ide: true),
    states: [(name: "boot", code: 0), (name: "running", code: 1)],
    initial: "running",
    messages: [(name: "a", frames: [(message: "alarm.clutches", fields: {
        "row1_clutch_slip": Signal("row3.unit1"), "row2_clutch_slip": Const(0), "row3_clutch_slip": Const(0),
        "row4_clutch_slip": Const(0), "row5_clutch_slip": Const(0), "row6_clutch_slip": Const(0),
        "main_clutch_open": Const(0), "clutch_pressure": Quantize(Signal("engine.rpm"), 100.0)})],
        when: OnChange(heartbeat_ms: 1000, check_ms: 10))],
)"#;

#[test]
fn on_change_sends_changes_within_a_check_and_keeps_an_exact_heartbeat() {
    let (mut n, fake) = node(C1, &[("row3.unit1", 0.0), ("engine.rpm", 3500.0)]);
    let at = BusTime::from_millis;
    let mut sent = drive(&mut n, at(2600), &[]);
    // Boot at 500 ms: first send then, heartbeats at exactly 1500 and 2500 ms.
    let times = |s: &[(BusTime, Frame)]| {
        s.iter()
            .map(|(t, _)| t.as_nanos() / 1_000_000)
            .collect::<Vec<_>>()
    };
    assert_eq!(times(&sent), [500, 1500, 2500]);
    // A switch closes at 2603 ms: seen at the 2610 check. Noise below the quantum is not a change.
    fake.borrow_mut().values.insert("engine.rpm".into(), 3520.0);
    drive(&mut n, at(2603), &[]);
    fake.borrow_mut().values.insert("row3.unit1".into(), 1.0);
    sent = drive(&mut n, at(4000), &[]);
    assert_eq!(times(&sent), [2610, 3610]);
    let d = catalogue::decode(&sent[0].1).unwrap().unwrap();
    assert_eq!(d.get("row1_clutch_slip").unwrap().raw, 1);
    assert_eq!(d.get("clutch_pressure").unwrap().physical, 3500.0);
}

const STATUS: &str = r#"
NodeScript(
    address: 0xD1, name: "D1", kind: FlowSensor, boot_delay_ms: 10,
    filter: Atmel(canidt: "30 0E 8F A8", canidm: "FF FF FF FD", ide: true),
    states: [(name: "waiting", code: 0), (name: "running", code: 1)],
    initial: "waiting",
    vars: {"missed": 0},
    messages: [(name: "status", frames: [(message: "flow.status", fields: {
        "state": StateCode, "firmware": Const(3), "missed_acks": Var("missed")})],
        when: OnChange(heartbeat_ms: 250, check_ms: 20))],
    reactions: [(message: "flow.calibrate", when: {"command": 2}, actions: [SetState("running")])],
)"#;

/// An on-change entry that reads only the node's own state is not polled while nothing of the
/// node changes, yet goes out at the same check-grid point as if it had been.
#[test]
fn internal_on_change_entries_sleep_until_the_node_changes() {
    let (mut n, _) = node(STATUS, &[]);
    let ms = BusTime::from_millis;
    let accept = parse_frame("0601D1F5#1002000001").unwrap(); // flow.calibrate "accept and run"
    let mut sent = Vec::new();
    let mut timeouts_before_accept = 0;
    let mut inbox = vec![(ms(1013), accept)].into_iter().peekable();
    loop {
        let t = n.poll_timeout().unwrap_or(BusTime::NEVER);
        let f = inbox.peek().map_or(BusTime::NEVER, |(t, _)| *t);
        let now = t.min(f);
        if now > ms(1600) {
            break;
        }
        if f <= t {
            let (at, frame) = inbox.next().unwrap();
            n.handle_frame(at, &frame);
        } else {
            n.handle_timeout(now);
            if now < ms(1013) {
                timeouts_before_accept += 1;
            }
        }
        while let Some(frame) = n.poll_transmit() {
            let d = catalogue::decode(&frame).unwrap().unwrap();
            sent.push((now.as_nanos() / 1_000_000, d.get("state").unwrap().raw));
        }
    }
    // Power on at 500 ms, boot at 510: the check grid is 510 + 20 k ms. The state changes at
    // 1013 ms; the first grid point after it is 510 + 20 × ceil(503 / 20) = 1030 ms.
    let change = 510 + 20 * (1013u64 - 510).div_ceil(20);
    assert_eq!(change, 1030);
    let expected = [
        (510, 0),
        (760, 0),
        (1010, 0),
        (change, 1),
        (change + 250, 1),
        (change + 500, 1),
    ];
    assert_eq!(sent, expected);
    // Boot at 510, the check at 530 that finds nothing new, the heartbeats at 760 and 1010: not
    // the 26 checks of the grid in between.
    assert_eq!(timeouts_before_accept, 4);
}

/// Times in scripts are `u64` milliseconds; huge ones mean "not within the run" instead of
/// overflowing the nanosecond clock (the node script fuzz target found this).
#[test]
fn huge_times_never_come_instead_of_overflowing() {
    let huge = B1.replace(
        "period_ms: 100, phase_ms: 5",
        "period_ms: 18446744073709551615, phase_ms: 5",
    );
    let (mut n, _) = node(&huge, &[("engine.rpm", 2150.0)]);
    let sent = drive(&mut n, BusTime::from_millis(800), &[]);
    // The first frame at 515 ms; the next one would be after the end of time.
    assert_eq!(sent.len(), 1);
    assert_eq!(sent[0].0, BusTime::from_millis(515));
    assert_eq!(n.poll_timeout(), None, "nothing is due any more");

    let late = B1.replace("boot_delay_ms: 10", "boot_delay_ms: 18446744073709551615");
    let (mut n, _) = node(&late, &[("engine.rpm", 2150.0)]);
    assert!(drive(&mut n, BusTime::from_millis(800), &[]).is_empty());
}

mod database;
mod numbers;
