//! The default harvester, end to end in virtual time: every node kind's traffic decoded back
//! through the catalogue, periods, payloads against the plant, start-up, load.

use bus::time::BusTime;
use harvemu_e2e::{Line, default_harvester, run_virtual};
use protocol::catalogue::{self, MESSAGES, Trigger};
use protocol::ident::Address;
use std::collections::BTreeMap;

const SECONDS: u64 = 30;

fn decoded(lines: &[Line]) -> Vec<(BusTime, catalogue::Decoded)> {
    lines
        .iter()
        .filter_map(|l| catalogue::decode(&l.frame).ok().flatten().map(|d| (l.at, d)))
        .collect()
}

#[test]
fn every_node_kind_sends_its_catalogue_traffic_at_its_period() {
    let h = default_harvester();
    let relay = h.relay();
    let (lines, snap) = run_virtual(h, BusTime::from_secs(SECONDS), |_| {}, |_, snap| snap.clone());
    assert!(!lines.is_empty());
    // Nothing is on the bus before the time relay starts the field nodes.
    assert!(lines[0].at > relay, "first frame at {:?}", lines[0].at);
    let all = decoded(&lines);
    assert_eq!(
        all.len(),
        lines.len(),
        "every frame on the bus is a catalogue message"
    );
    let mut times: BTreeMap<(&str, Address), Vec<BusTime>> = BTreeMap::new();
    for (at, d) in &all {
        times.entry((d.message.name, d.node)).or_default().push(*at);
    }
    for m in MESSAGES {
        let Trigger::Periodic { period_ms } = m.trigger else {
            continue;
        };
        for node in Address::all().filter(|a| m.nodes.contains(*a)) {
            let t = times
                .get(&(m.name, node))
                .unwrap_or_else(|| panic!("no {} from {node}", m.name));
            // Skip the first second (boot); then the mean period is the catalogue's within 1 %.
            let t: Vec<&BusTime> = t.iter().filter(|x| x.as_nanos() > 1_500_000_000).collect();
            let mean = (t[t.len() - 1].as_nanos() - t[0].as_nanos()) as f64 / (t.len() - 1) as f64 / 1e6;
            assert!(
                (mean - f64::from(period_ms)).abs() <= 0.01 * f64::from(period_ms),
                "{} from {node}: {mean} ms",
                m.name
            );
        }
    }
    // Alarm modules speak on change and at least once a second.
    for c in 0..4u8 {
        let name = [
            "alarm.suction_doors",
            "alarm.clutches",
            "alarm.conveyor",
            "alarm.hydraulics",
        ][usize::from(c)];
        let t = &times[&(name, Address::alarm(c))];
        let longest = t
            .windows(2)
            .map(|w| w[1].as_nanos() - w[0].as_nanos())
            .max()
            .unwrap();
        assert!(longest <= 1_001_000_000, "{name}: silent for {longest} ns");
    }
    // Bus load of the whole harvester at 250 kbit/s, reported and under half.
    let load = snap.stats.total_load();
    println!("default harvester bus load at 250 kbit/s: {:.1} %", load * 100.0);
    assert!(load > 0.05 && load < 0.5, "{load}");
    assert_eq!(snap.stats.error_frames, 0);
    assert_eq!(snap.stats.overruns, 0);
}

#[test]
fn flow_sensors_are_calibrated_then_stream_acknowledged_groups() {
    let (lines, _) = run_virtual(default_harvester(), BusTime::from_secs(10), |_| {}, |_, _| ());
    let all = decoded(&lines);
    for n in 0..6u8 {
        let d = Address::flow_sensor(n);
        let of = |name: &str| {
            all.iter()
                .filter(|(_, x)| x.node == d && x.message.name == name)
                .count()
        };
        // Calibration: one start, one accept.
        let cal: Vec<i64> = all
            .iter()
            .filter(|(_, x)| x.node == d && x.message.name == "flow.calibrate")
            .map(|(_, x)| x.get("command").unwrap().raw)
            .collect();
        assert_eq!(cal, [1, 2], "{d}");
        let groups = of("flow.marker_flow") + of("flow.marker_reference");
        assert!(
            of("flow.marker_flow") > 80,
            "{d} streams: {}",
            of("flow.marker_flow")
        );
        // Every group is acknowledged, but the last cycle's two may still be in flight.
        assert!(
            groups.abs_diff(of("flow.ack")) <= 2,
            "{d}: {groups} groups, {} acks",
            of("flow.ack")
        );
        assert_eq!(of("flow.part1"), groups);
        // Running at the end.
        let last_state = all
            .iter()
            .rev()
            .find(|(_, x)| x.node == d && x.message.name == "flow.status")
            .unwrap();
        assert_eq!(last_state.1.get("state").unwrap().label(), Some("running"));
    }
}

#[test]
fn payloads_follow_the_plant() {
    // Sample the plant at the end and compare with the last frames of each parameter.
    let (lines, truth) = run_virtual(
        default_harvester(),
        BusTime::from_secs(SECONDS),
        |_| {},
        |running, _| {
            let p = running.plant.borrow();
            [
                "speed.actual",
                "engine.rpm",
                "fan.rpm",
                "water.pressure",
                "oil.temperature",
                "basket.fill",
                "row1.flow",
            ]
            .iter()
            .map(|s| (s.to_string(), p.signal(s).unwrap()))
            .collect::<BTreeMap<String, f64>>()
        },
    );
    let all = decoded(&lines);
    let last = |msg: &str, field: &str| {
        all.iter()
            .rev()
            .find(|(_, d)| d.message.name == msg)
            .and_then(|(_, d)| d.get(field))
            .unwrap()
            .physical
    };
    let close = |a: f64, b: f64, tol: f64| (a - b).abs() <= tol;
    assert!(truth["speed.actual"] > 3.0, "the machine is moving: {truth:?}");
    assert!(close(
        last("param.ground_speed", "ground_speed"),
        truth["speed.actual"],
        0.1
    ));
    assert!(close(last("speed.status", "actual"), truth["speed.actual"], 0.1));
    assert!(close(
        last("param.engine", "engine_rpm"),
        truth["engine.rpm"],
        20.0
    ));
    assert!(close(last("param.fan", "fan_rpm"), truth["fan.rpm"], 20.0));
    assert!(close(
        last("param.water", "water_pressure"),
        truth["water.pressure"],
        5.0
    ));
    assert!(close(
        last("param.oil", "oil_temperature"),
        truth["oil.temperature"],
        0.5
    ));
    assert!(close(
        last("param.conveyor", "basket_fill"),
        truth["basket.fill"],
        1.0
    ));
    // The flow units of D0 against the row's true flow: mean(unit/ref)/0.004 recovers g/s.
    let (_, p1) = all
        .iter()
        .rev()
        .find(|(_, d)| d.node == Address::flow_sensor(0) && d.message.name == "flow.part1")
        .unwrap();
    assert!(p1.get("unit1").unwrap().raw > 0, "cotton is flowing");
    assert!(truth["row1.flow"] > 100.0, "{truth:?}");
}

#[test]
fn seed_frames_of_d0_byte_for_byte() {
    // Hold the plant at the source's unit values: an empty duct and its five references.
    let refs = [0x1E34, 0x2BEA, 0x2CEF, 0x2189, 0x2C98];
    let (lines, _) = run_virtual(
        default_harvester(),
        BusTime::from_secs(3),
        move |running| {
            let mut p = running.plant.borrow_mut();
            for k in 1..=5 {
                p.set_override(&format!("row1.unit{k}"), Some(0.0)).unwrap();
                p.set_override(&format!("row1.ref{k}"), Some(f64::from(refs[k - 1])))
                    .unwrap();
            }
        },
        |_, _| (),
    );
    let d0: Vec<String> = lines
        .iter()
        .filter(|l| l.frame.raw_id() == 0x0601F5D0)
        .map(|l| bus::candump::format_frame(&l.frame))
        .collect();
    let seed = [
        "0601F5D0#200D0002FFBFFF00",
        "0601F5D0#0101000000000000",
        "0601F5D0#0200000000906EFF",
        "0601F5D0#200E0002FFBEFF00",
        "0601F5D0#0101341EEA2BEF2C",
        "0601F5D0#028921982C44D46E",
    ];
    let start = d0
        .iter()
        .position(|f| f == seed[0])
        .expect("D0 streams flow groups");
    assert_eq!(&d0[start..start + 6], seed);
}

#[test]
fn with_the_monitor_switched_off_the_field_waits_for_an_external_one() {
    let mut h = default_harvester();
    h.config.monitor.enabled = false;
    let (lines, display) = run_virtual(
        h,
        BusTime::from_secs(5),
        |_| {},
        |running, _| running.display.is_some(),
    );
    assert!(!display, "no emulated monitor");
    let all = decoded(&lines);
    assert!(
        all.iter()
            .all(|(_, d)| d.message.direction == catalogue::Direction::ToMonitor),
        "nothing from F5"
    );
    // The sensors keep asking to be calibrated, and nothing streams.
    let d0: Vec<&catalogue::Decoded> = all
        .iter()
        .map(|(_, d)| d)
        .filter(|d| d.node == Address::flow_sensor(0))
        .collect();
    assert!(d0.iter().all(|d| d.message.name == "flow.status"));
    assert!(d0.len() >= 17, "every 250 ms for 4.4 s: {}", d0.len());
    assert!(
        d0.iter()
            .all(|d| d.get("state").unwrap().label() == Some("awaiting calibration"))
    );
}
