//! A recorded flow sensor replayed in place of the emulated one: its frames reach the bus as
//! recorded, and the monitor calibrates it, acknowledges it and counts its cotton as it did with
//! the real node; without the replay the monitor never hears from it.

use actix::prelude::*;
use bus::time::BusTime;
use bus::tracefile::{self, ErrorFrames};
use bus_runtime::hub::{RunUntil, runtime};
use harvemu_e2e::{Line, Shared, candump, default_harvester, parse_trace};
use nodes::monitor::Display;
use protocol::ident::Address;
use supervisor::harvester::{self, Harvester};
use supervisor::replay::schedule::{Passes, Schedule};
use supervisor::replay::{self, Played};

const D3: Address = Address(0xD3);

/// Runs `h` in virtual time to `until`, replaying `trace` (when given) from the moment the field
/// nodes are up, leaving out frames of emulated nodes. Gives the new trace and the display.
fn run(h: Harvester, trace: Option<&str>, until: BusTime) -> (Vec<Line>, Display, Played) {
    let out = Shared::default();
    let o = out.clone();
    let skip = replay::emulated(&h);
    let schedule = trace.map(|t| {
        let records = tracefile::read_str(t, ErrorFrames::Keep).expect("the trace reads");
        Schedule::from_records(records, &skip, Passes::Times(1))
    });
    let (display, played) = System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
        let mut running = harvester::start(&h, false, vec![candump(o, &h)])
            .await
            .expect("starts");
        let mut played = Played::default();
        if let Some(mut schedule) = schedule {
            let node = replay::attach(&running).await.expect("attach");
            let start = running.now();
            replay::play(&mut running, node, &mut schedule, start, Some(until), &mut played)
                .await
                .expect("replay");
        }
        running.run_until(until).await.expect("run");
        let display = running
            .display
            .as_ref()
            .expect("the monitor is on")
            .borrow()
            .clone();
        (display, played)
    });
    let text = String::from_utf8(out.0.take()).expect("utf-8");
    (parse_trace(&text), display, played)
}

/// (source, destination) of a harvester frame.
fn ends(l: &Line) -> Option<(u8, u8)> {
    l.frame
        .is_extended()
        .then(|| (l.frame.raw_id() as u8, (l.frame.raw_id() >> 8) as u8))
}

fn from(lines: &[Line], source: u8) -> Vec<bus::Frame> {
    lines
        .iter()
        .filter(|l| ends(l).is_some_and(|(s, _)| s == source))
        .map(|l| l.frame)
        .collect()
}

fn monitor_to(lines: &[Line], dest: u8) -> Vec<bus::Frame> {
    lines
        .iter()
        .filter(|l| ends(l) == Some((0xF5, dest)))
        .map(|l| l.frame)
        .collect()
}

#[test]
fn a_replayed_flow_sensor_drives_the_monitor_as_the_real_one_did() {
    let until = BusTime::from_secs(12);
    // The whole machine, recorded.
    let out = Shared::default();
    let o = out.clone();
    let h = default_harvester();
    let original_display = System::with_tokio_rt(|| runtime(true).unwrap()).block_on(async move {
        let running = harvester::start(&h, false, vec![candump(o, &h)]).await.unwrap();
        running.hub.send(RunUntil(until)).await.unwrap().unwrap();
        running.display.as_ref().unwrap().borrow().clone()
    });
    let recorded = String::from_utf8(out.0.take()).unwrap();
    let original = parse_trace(&recorded);

    let mut without = default_harvester();
    without.without(&["D3".to_string()]).unwrap();
    // A margin past the original's end: the replay starts when the field nodes are up.
    let later = until + bus::time::BusDuration::from_secs(1);
    let (replayed, display, played) = run(without.clone(), Some(&recorded), later);
    let (silent, alone, _) = run(without, None, later);

    // D3's frames, and only those, came from the replay, all of them, as recorded.
    let d3 = from(&original, D3.0);
    assert!(d3.len() > 500, "{} frames of D3", d3.len());
    assert_eq!(played.replayed, d3.len() as u64);
    assert_eq!(played.refused, 0);
    assert_eq!(from(&replayed, D3.0), d3);
    assert!(from(&silent, D3.0).is_empty());

    // The monitor answered them as it answered the real node: calibration and acknowledgements,
    // the same frames in the same order.
    let answers = monitor_to(&original, D3.0);
    let now = monitor_to(&replayed, D3.0);
    assert!(answers.len() > 100, "{} answers", answers.len());
    assert!(now.len() >= answers.len(), "{} < {}", now.len(), answers.len());
    assert_eq!(now[..answers.len()], answers[..]);
    assert!(
        monitor_to(&silent, D3.0).is_empty(),
        "no one to answer without the replay"
    );

    // And the display shows row 4 as it did.
    let row = |d: &Display| d.rows[3].clone();
    assert!(row(&display).calibrated && row(&original_display).calibrated);
    assert!(!row(&alone).calibrated && row(&alone).kg == 0.0);
    let (kg, was) = (row(&display).kg, row(&original_display).kg);
    assert!(
        was > 1.0 && (kg - was).abs() / was < 0.1,
        "row 4: {kg} kg, was {was} kg"
    );
    assert!(
        !display.active_alarms().any(|a| a.node == D3.to_string()),
        "{:?}",
        display.alarms
    );
}
