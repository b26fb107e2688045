//! The whole machine as firmware (configs/harvester-firmware.ron: every field node an
//! AT89C51CC03 image) against the script harvester (configs/harvester.ron), ten minutes each
//! with the same seed, message by message: every catalogue message either sends, in the same
//! number to within the start's shifts, at the same mean period to within 2 %, with field values
//! in the same ranges to within what the ADC's steps explain; and the monitor ends with the
//! same yield to within 1 % and raised the same alarms, each within 20 ms of the other run's (the
//! alarm modules look every 10 ms, on grids of their own).
//!
//! Runs in the optimised phase of `scripts/test` only (ten minutes of twenty firmware nodes take
//! seconds there, minutes in a debug build).

use actix::prelude::*;
use bus::time::BusTime;
use bus_runtime::hub::{RunUntil, runtime};
use harvemu_e2e::{Shared, candump, parse_trace, root};
use std::collections::BTreeMap;
use supervisor::harvester::{self, Harvester};

/// What one message did over a run: its frames' end times, and each field's raw range.
#[derive(Default, Debug)]
struct Seen {
    at: Vec<BusTime>,
    ranges: BTreeMap<&'static str, (i64, i64)>,
}

/// One run: its messages by (catalogue name, field node address), the monitor's yield and its
/// alarms as (node, name, raised, cleared).
struct Run {
    messages: BTreeMap<(&'static str, u8), Seen>,
    yield_kg: f64,
    alarms: Vec<(String, String, BusTime, Option<BusTime>)>,
}

/// (when, s; plant input; value): faults that raise and clear alarms of three alarm modules.
const FAULTS: [(u64, &str, f64); 6] = [
    (100, "fault.door2_open", 1.0),
    (150, "fault.door2_open", 0.0),
    (200, "fault.belt_stop", 1.0),
    (260, "fault.belt_stop", 0.0),
    (300, "fault.low_water", 1.0),
    (400, "fault.low_water", 0.0),
];

fn run(config: &str, end: BusTime) -> Run {
    let h = Harvester::load(&root().join(config)).expect("the config loads");
    let trace = Shared::default();
    let t = trace.clone();
    let (yield_kg, alarms) = System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
        let running = harvester::start(&h, false, vec![candump(t, &h)])
            .await
            .expect("start");
        for (s, input, value) in FAULTS {
            let at = BusTime::from_secs(s);
            running.hub.send(RunUntil(at)).await.expect("hub").expect("run");
            running
                .plant
                .borrow_mut()
                .set_input(input, value)
                .expect("a plant input");
        }
        running.hub.send(RunUntil(end)).await.expect("hub").expect("run");
        let d = running.display.as_ref().expect("the monitor's display").borrow();
        let alarms = d
            .alarms
            .iter()
            .map(|a| (a.node.clone(), a.name.clone(), a.raised, a.cleared))
            .collect();
        (d.total_kg, alarms)
    });
    let mut messages: BTreeMap<(&'static str, u8), Seen> = BTreeMap::new();
    for l in parse_trace(&String::from_utf8(trace.0.take()).expect("utf-8")) {
        let Ok(Some(d)) = protocol::catalogue::decode(&l.frame) else {
            continue;
        };
        let seen = messages.entry((d.message.name, d.node.0)).or_default();
        seen.at.push(l.at);
        for v in &d.values {
            let r = seen.ranges.entry(v.field.name).or_insert((v.raw, v.raw));
            *r = (r.0.min(v.raw), r.1.max(v.raw));
        }
    }
    Run {
        messages,
        yield_kg,
        alarms,
    }
}

fn mean_period_ms(at: &[BusTime]) -> f64 {
    let (first, last) = (at[0], at[at.len() - 1]);
    last.since(first).as_secs_f64() * 1000.0 / (at.len() - 1) as f64
}

#[test]
fn the_firmware_harvester_is_the_same_harvester_on_the_bus() {
    let end = BusTime::from_secs(600);
    let scripts = run("configs/harvester.ron", end);
    let firmware = run("configs/harvester-firmware.ron", end);
    let names: Vec<_> = scripts.messages.keys().collect();
    assert_eq!(
        names,
        firmware.messages.keys().collect::<Vec<_>>(),
        "the same messages from the same nodes"
    );
    assert!(names.len() >= 25, "{} messages", names.len());
    for (key, s) in &scripts.messages {
        let f = &firmware.messages[key];
        let (n, m) = (s.at.len() as f64, f.at.len() as f64);
        // Counts: the start and a heartbeat restarted by a change shift a few frames.
        assert!(
            (n - m).abs() <= 3.0_f64.max(0.01 * n),
            "{key:?}: {n} frames from the scripts, {m} from the firmware"
        );
        if s.at.len() > 10 {
            let (p, q) = (mean_period_ms(&s.at), mean_period_ms(&f.at));
            assert!(
                (p - q).abs() <= 0.02 * p,
                "{key:?}: mean period {p:.3} ms (scripts), {q:.3} ms (firmware)"
            );
        }
        for (field, &(lo, hi)) in &s.ranges {
            let (flo, fhi) = f.ranges[field];
            // A range may end an ADC step further either way: 1 % of the field's span (a flow
            // unit's step of 64 counts is under 1 % of its range, a reference's of 16 too).
            let slack = (2_i64).max((hi - lo) / 100);
            assert!(
                (flo - lo).abs() <= slack && (fhi - hi).abs() <= slack,
                "{key:?} {field}: {lo}..{hi} from the scripts, {flo}..{fhi} from the firmware"
            );
        }
    }
    let (a, b) = (scripts.yield_kg, firmware.yield_kg);
    assert!(a > 1000.0, "ten minutes of harvest: {a} kg");
    assert!(
        (a - b).abs() <= 0.01 * a,
        "yield {a:.1} kg (scripts), {b:.1} kg (firmware)"
    );
    let (sa, fa) = (&scripts.alarms, &firmware.alarms);
    let names = |v: &[(String, String, BusTime, Option<BusTime>)]| {
        let mut n: Vec<(String, String)> = v.iter().map(|a| (a.0.clone(), a.1.clone())).collect();
        n.sort();
        n
    };
    assert_eq!(names(sa), names(fa), "the same alarms");
    assert!(sa.len() >= 3, "the faults raise alarms: {sa:?}");
    let close = |a: BusTime, b: BusTime| a.max(b).since(a.min(b)).as_secs_f64() <= 0.020;
    for (node, name, raised, cleared) in sa {
        let f = fa
            .iter()
            .find(|f| (&f.0, &f.1) == (node, name) && close(f.2, *raised))
            .unwrap_or_else(|| {
                panic!("{node} {name} raised at {raised} (scripts): not within 20 ms in {fa:?}")
            });
        match (cleared, f.3) {
            (Some(a), Some(b)) => assert!(close(*a, b), "{node} {name} cleared at {a} and {b}"),
            (None, None) => {}
            (a, b) => panic!("{node} {name}: cleared {a:?} (scripts), {b:?} (firmware)"),
        }
    }
}
