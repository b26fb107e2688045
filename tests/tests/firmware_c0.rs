//! The alarm module C0 as C firmware (configs/harvester-firmware-c0.ron) against its script
//! (configs/harvester.ron), end to end in the harvester, with the same seed and the same doors
//! opening and closing: the same identifier and message number, payloads that decode to the same
//! values, heartbeat periods within 2 % of the script's, and each door's change on the bus within
//! 20 ms of the script's.

use actix::prelude::*;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::{GetSnapshot, RunUntil, runtime};
use harvemu_e2e::{Shared, candump, parse_trace, root};
use supervisor::harvester::{self, Harvester};

/// C0's frame: priority 4, broadcast, C0 to the monitor F5 (docs/PROTOCOL.md).
const C0_ID: u32 = 0x0400_F5C0;

/// (when, plant input, value): doors open and close.
const DOORS: [(u64, &str, f64); 4] = [
    (6_000, "fault.door2_open", 1.0),
    (9_500, "fault.door5_open", 1.0),
    (12_250, "fault.door2_open", 0.0),
    (15_000, "fault.door5_open", 0.0),
];

/// C0's frames, (end of frame, data), and the error frames of the run.
fn c0_frames(config: &str, end: BusTime) -> (Vec<(BusTime, Vec<u8>)>, u64) {
    let h = Harvester::load(&root().join(config)).expect("the config loads");
    let (trace, errors) = run(h, end);
    let frames = parse_trace(&trace)
        .into_iter()
        .filter(|l| l.frame.raw_id() == C0_ID)
        .map(|l| (l.at, l.frame.data().to_vec()))
        .collect();
    (frames, errors)
}

/// The whole trace of `h` to `end` with the doors of [`DOORS`], and its error frames.
fn run(h: Harvester, end: BusTime) -> (String, u64) {
    let trace = Shared::default();
    let t = trace.clone();
    let errors = System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
        let running = harvester::start(&h, false, vec![candump(t, &h)])
            .await
            .expect("start");
        for (ms, input, value) in DOORS {
            let at = BusTime::from_millis(ms);
            running.hub.send(RunUntil(at)).await.expect("hub").expect("run");
            running
                .plant
                .borrow_mut()
                .set_input(input, value)
                .expect("a plant input");
        }
        running.hub.send(RunUntil(end)).await.expect("hub").expect("run");
        running
            .hub
            .send(GetSnapshot)
            .await
            .expect("snapshot")
            .stats
            .error_frames
    });
    (String::from_utf8(trace.0.take()).expect("utf-8"), errors)
}

/// The doors byte and the duct vacuum in mV.
fn decode(data: &[u8]) -> (u8, u16) {
    assert_eq!((data.len(), data[0]), (4, 0x30), "{data:02X?}");
    (data[1], u16::from_le_bytes([data[2], data[3]]))
}

/// When the doors byte changed, and to what.
fn changes(frames: &[(BusTime, Vec<u8>)]) -> Vec<(BusTime, u8)> {
    let mut last = None;
    let mut out = Vec::new();
    for (at, data) in frames {
        let (doors, _) = decode(data);
        if last != Some(doors) {
            out.push((*at, doors));
            last = Some(doors);
        }
    }
    out
}

#[test]
fn c0_as_firmware_sends_what_its_script_sends() {
    let end = BusTime::from_secs(20);
    let (script, script_errors) = c0_frames("configs/harvester.ron", end);
    let (firmware, firmware_errors) = c0_frames("configs/harvester-firmware-c0.ron", end);
    assert_eq!((script_errors, firmware_errors), (0, 0));
    assert!(script.len() > 15, "{} script frames", script.len());

    // The doors: both start closed, and each change reaches the bus within 20 ms of the
    // script's. The script's own changes follow the plant within its 10 ms check.
    let (a, b) = (changes(&script), changes(&firmware));
    let doors: Vec<u8> = a.iter().map(|c| c.1).collect();
    assert_eq!(doors, [0, 0b10, 0b1_0010, 0b1_0000, 0]);
    assert_eq!(doors, b.iter().map(|c| c.1).collect::<Vec<_>>());
    for ((ta, _), (tb, _)) in a.iter().zip(&b).skip(1) {
        let apart = if ta > tb { ta.since(*tb) } else { tb.since(*ta) };
        assert!(
            apart <= BusDuration::from_millis(20),
            "script at {ta}, firmware at {tb}"
        );
    }

    // Heartbeats: between two frames with no change in between, the script waits 1000 ms; the
    // firmware's gaps are within 2 % of that.
    let beats = |frames: &[(BusTime, Vec<u8>)]| -> Vec<f64> {
        frames
            .windows(2)
            .filter(|w| w[0].1 == w[1].1)
            .map(|w| w[1].0.since(w[0].0).as_secs_f64())
            .collect()
    };
    let (mut sa, sb) = (beats(&script), beats(&firmware));
    assert!(
        sa.len() >= 5 && sb.len() >= 5,
        "{} and {} heartbeats",
        sa.len(),
        sb.len()
    );
    sa.sort_by(f64::total_cmp);
    let script_period = sa[sa.len() / 2];
    for gap in &sb {
        assert!(
            (gap / script_period - 1.0).abs() <= 0.02,
            "a heartbeat of {gap} s against the script's {script_period} s"
        );
    }

    // The duct vacuum, quantized to 100 mV by both: the values seen at the same moments agree
    // (one quantum apart at most, where the vacuum sits at a rounding edge).
    for (at, data) in firmware.iter().skip(1) {
        let (_, mv) = decode(data);
        assert_eq!(mv % 100, 0, "{mv} mV at {at}");
        let (_, near) = script
            .iter()
            .min_by_key(|(t, _)| if t > at { t.since(*at) } else { at.since(*t) })
            .expect("script frames");
        let (_, script_mv) = decode(near);
        assert!(
            mv.abs_diff(script_mv) <= 100,
            "{mv} mV at {at}, the script {script_mv} mV"
        );
    }
}

/// The node skips what changes nothing (frames its controller does not take, while the firmware
/// writes none of its registers): the same trace, frame for frame and to the nanosecond, as
/// when it works through every frame.
#[test]
fn skipping_frames_c0_does_not_take_changes_nothing() {
    let h = Harvester::load(&root().join("configs/harvester-firmware-c0.ron")).expect("loads");
    let mut worked = h.clone();
    for f in &mut worked.firmware {
        std::sync::Arc::make_mut(f).skip_idle_loops = false;
    }
    let end = BusTime::from_secs(16);
    let (skipping, _) = run(h, end);
    let (working, _) = run(worked, end);
    assert!(
        skipping.lines().count() > 8000,
        "{} lines",
        skipping.lines().count()
    );
    assert!(skipping == working, "the traces differ");
}
