//! Sessions on the built-in harvester without its monitor: the program stands in F5's place.
//! Frames are written as docs/PROTOCOL.md gives them.

use super::*;
use bus::candump::parse_frame;

fn without_monitor(seed: u64) -> Session {
    start_without_monitor(seed, false)
}

fn paced_without_monitor(seed: u64) -> Session {
    start_without_monitor(seed, true)
}

fn start_without_monitor(seed: u64, paced: bool) -> Session {
    Session::start(&Options {
        without: vec!["F5".into()],
        seed: Some(seed),
        name: "F5".into(),
        paced,
        ..Options::default()
    })
    .unwrap_or_else(|e| panic!("{e}"))
}

/// The next frame within `timeout_s`, error frames skipped (none come on a bus without faults;
/// the tests of faults look at them).
fn next(s: &Session, timeout_s: f64) -> Option<Received> {
    let end = s.now().unwrap() + timeout_s;
    loop {
        let left = (end - s.now().unwrap()).max(0.0);
        match s.recv(Some(left)).unwrap() {
            Some(Delivered::Frame(r)) => return Some(r),
            Some(Delivered::Error(_)) if left > 0.0 => continue,
            _ => return None,
        }
    }
}

/// Frames from D0 to F5: priority 6, type 1, destination F5, source D0.
fn from_d0() -> Filter {
    Filter {
        id: 0x0601_F5D0,
        mask: 0x1FFF_FFFF,
        extended: Some(true),
    }
}

const REFERENCE_MARKER: [u8; 8] = [0x20, 0x0E, 0x00, 0x02, 0xFF, 0xBE, 0xFF, 0x00];

#[test]
fn the_same_seed_and_calls_give_the_same_frames_at_the_same_times() {
    let record = |seed| {
        let s = without_monitor(seed);
        (0..300)
            .map(|_| next(&s, 1.0).unwrap())
            .map(|r| format!("{:.9} {}", r.at_s, bus::candump::format_frame(&r.frame)))
            .collect::<Vec<_>>()
    };
    let a = record(7);
    assert_eq!(a, record(7));
    // Bus time only goes forward, frame after frame.
    let times: Vec<f64> = a
        .iter()
        .map(|l| l.split(' ').next().unwrap().parse().unwrap())
        .collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]), "{a:?}");
}

#[test]
fn recv_waits_in_bus_time_for_a_frame_that_passes_the_filters() {
    let s = without_monitor(1);
    // Nothing passes: the whole timeout passes, exactly.
    let none = Filter {
        id: 0x1FFF_FFFF,
        mask: 0x1FFF_FFFF,
        extended: Some(true),
    };
    s.set_filters(&[none]).unwrap();
    assert_eq!(s.recv(Some(2.5)).unwrap(), None);
    assert_eq!(s.now().unwrap(), 2.5);
    // D0 is waiting for its calibration and says so every 250 ms (flow.status, Data0 = 0x30).
    s.set_filters(&[from_d0()]).unwrap();
    let r = next(&s, 1.0).unwrap();
    assert_eq!(r.frame.raw_id(), 0x0601_F5D0);
    assert_eq!(r.frame.data()[0], 0x30, "{:?}", r.frame);
    // The run stopped where the frame ended.
    assert_eq!(s.now().unwrap(), r.at_s);
    let next = next(&s, 1.0).unwrap();
    assert!(
        (next.at_s - r.at_s - 0.25).abs() < 0.001,
        "{} then {}",
        r.at_s,
        next.at_s
    );
    assert!(s.recv(Some(-1.0)).is_err());
    assert!(s.recv(Some(f64::NAN)).is_err());
}

#[test]
fn what_the_program_sends_reaches_the_nodes() {
    let s = without_monitor(1);
    s.set_filters(&[from_d0()]).unwrap();
    s.run_for(3.0).unwrap();
    // Before: D0 awaits calibration and sends no reference group.
    let before = (0..8).filter_map(|_| next(&s, 1.0));
    assert!(before.into_iter().all(|r| r.frame.data() != REFERENCE_MARKER));
    // flow.calibrate (Data0 0x10): "start calibration" (1), target 10000 (0x2710, low byte
    // first), 5 samples.
    assert!(s.send(parse_frame("0601D0F5#1001102705").unwrap(), 0.0).unwrap());
    let answered = (0..8)
        .filter_map(|_| next(&s, 0.5))
        .any(|r| r.frame.data() == REFERENCE_MARKER);
    assert!(
        answered,
        "D0 sent no reference group after the calibration command"
    );
}

#[test]
fn periodic_tasks_send_in_bus_time() {
    let s = without_monitor(1);
    s.run_for(3.0).unwrap();
    // flow.ack to D0, every 100 ms for 1 s: at 3.0, 3.1, ... 3.9 s, ten frames.
    let ack = parse_frame("0601D0F5#210E01").unwrap();
    let task = s.start_periodic(vec![ack], 0.1, Some(1.0)).unwrap();
    s.run_for(2.0).unwrap();
    assert_eq!(s.sent().unwrap(), 10);
    // Ended by its duration.
    assert!(!s.stop_periodic(task).unwrap());
    // Without a duration, until stopped: at 5.0, 5.1, ... 5.5 s, six more, then no more.
    let task = s.start_periodic(vec![ack, ack], 0.1, None).unwrap();
    s.run_for(0.55).unwrap();
    assert!(s.modify_periodic(task, vec![ack]).unwrap());
    assert!(s.stop_periodic(task).unwrap());
    s.run_for(1.0).unwrap();
    assert_eq!(s.sent().unwrap(), 16);
    assert!(s.start_periodic(vec![ack], 0.0, None).is_err());
    assert!(s.start_periodic(Vec::new(), 0.1, None).is_err());
    assert!(s.start_periodic(vec![ack], 0.1, Some(f64::NAN)).is_err());
}

#[test]
fn node_states_the_display_and_plant_inputs() {
    let s = without_monitor(1);
    s.run_for(2.0).unwrap();
    let states = s.states().unwrap();
    // The 20 field nodes and the program; every controller error active, counters at zero on a
    // bus without faults.
    assert_eq!(states.len(), 21, "{states:?}");
    assert!(states.iter().any(|n| n.name == "F5"));
    assert!(
        states.iter().all(|n| n.state == "error active" && n.tec == 0),
        "{states:?}"
    );
    // No monitor, no display; with the monitor kept, its display.
    assert_eq!(s.display().unwrap(), None);
    let with_monitor = Session::start(&Options {
        name: "tester".into(),
        ..Options::default()
    })
    .unwrap();
    with_monitor.run_for(1.0).unwrap();
    let shown = with_monitor.display().unwrap().unwrap();
    let v: serde_json::Value = serde_json::from_str(&shown).unwrap();
    assert!(v.get("phase").is_some(), "{shown}");
    // A plant input: a known one is taken, an unknown one refused with its name.
    s.set_input("operator.speed", 5.0).unwrap();
    let e = s.set_input("operator.warp", 1.0).unwrap_err().to_string();
    assert!(e.contains("operator.warp"), "{e}");
}

#[test]
fn scenario_actions_reach_the_bus_and_their_faults_end_in_time() {
    let s = without_monitor(1);
    s.set_filters(&[from_d0()]).unwrap();
    s.run_for(2.0).unwrap();
    while s.recv(Some(0.0)).unwrap().is_some() {}
    // Disconnected, D0 is silent (it says "awaiting calibration" every 250 ms otherwise).
    s.act(r#"Disconnect("D0")"#).unwrap();
    assert_eq!(s.recv(Some(1.0)).unwrap(), None);
    s.act(r#"Reconnect("D0")"#).unwrap();
    assert!(s.recv(Some(1.0)).unwrap().is_some());
    // Every D0 frame corrupted for a second: none reaches the program whole (an error flag
    // destroys each, ISO 11898-1), then the fault ends by itself and D0 is heard again.
    let until = (s.now().unwrap() + 1.0).round();
    s.act(&format!(
        "BitErrors(target: Node(\"D0\"), hits: Always, until_s: Some({until:.1}))"
    ))
    .unwrap();
    // The program's controller detects each error too and reports it (SocketCAN's encoding,
    // linux/can/error.h): error frames only, its own, as a receiver's.
    let mut errors = Vec::new();
    while let Some(d) = s.recv(Some((until - s.now().unwrap() - 0.001).max(0.0))).unwrap() {
        match d {
            Delivered::Error(e) => errors.push(e),
            Delivered::Frame(r) => panic!("{r:?} got through the fault"),
        }
        if s.now().unwrap() >= until - 0.001 {
            break;
        }
    }
    // Bus errors (CAN_ERR_PROT | CAN_ERR_BUSERROR), and the state changes their count makes
    // (CAN_ERR_CRTL: REC past 96, the warning level).
    let bus_errors = errors
        .iter()
        .filter(|e| e.can_id == bus::filter::CAN_ERR_FLAG | 0x288);
    assert!(bus_errors.count() >= 3, "{errors:?}");
    for e in &errors {
        assert_eq!(e.controller, "F5");
        assert!(e.can_id & 0x8C != 0, "a bus error or a state change: {e:?}");
        assert_eq!(e.data[2] & 0x80, 0, "not transmitting: {e:?}");
    }
    // In time order, and each handed over where the bus stopped for it.
    assert!(errors.windows(2).all(|w| w[0].at_s <= w[1].at_s));
    let after = next(&s, 1.0).expect("D0 is heard again once the fault ended");
    assert!(after.at_s > until, "{after:?}");
    // Bad text is named with its position; an unknown node is refused.
    let e = s.act("Disconnect(").unwrap_err().to_string();
    assert!(e.contains("the action:1:"), "{e}");
    assert!(s.act(r#"Crash("ZZ")"#).is_err());
}

#[test]
fn paced_bus_time_keeps_behind_the_wall_clock_and_runs_between_calls() {
    let started = std::time::Instant::now();
    let s = paced_without_monitor(3);
    let since_1970 = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64();
    // Stamped from the wall clock at the start, as candump -l stamps.
    assert!((s.epoch_s() - since_1970).abs() < 60.0, "{}", s.epoch_s());
    // D0 asks for its calibration every 250 ms once the field nodes are up.
    s.set_filters(&[from_d0()]).unwrap();
    let first = next(&s, 30.0).expect("D0 speaks within 30 s");
    assert_eq!(first.frame.data()[0], 0x30, "{first:?}");
    // The hub may let a frame out a little before its time on the wall clock, never more.
    let wall = started.elapsed().as_secs_f64();
    assert!(
        first.at_s <= wall + 0.01,
        "bus time {} ahead of the wall clock {wall}",
        first.at_s
    );
    // No recv, no run_for, and yet the bus goes on.
    let before = s.now().unwrap();
    let mut after = before;
    for _ in 0..3000 {
        std::thread::sleep(std::time::Duration::from_millis(10));
        after = s.now().unwrap();
        if after > before + 0.1 {
            break;
        }
    }
    assert!(
        after > before + 0.1,
        "bus time stood at {before} s, then {after} s"
    );
    assert!(after <= started.elapsed().as_secs_f64() + 0.01);
}

#[test]
fn paced_a_recv_waiting_in_one_thread_does_not_hold_up_another() {
    let s = paced_without_monitor(4);
    // Sent before the field nodes are up, the frame would go unacknowledged, and its error
    // frames would end the wait.
    s.wait_ready().unwrap();
    let nothing = Filter {
        id: 0x1FFF_FFFF,
        mask: 0x1FFF_FFFF,
        extended: Some(true),
    };
    s.set_filters(&[nothing]).unwrap();
    let done = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|scope| {
        let waiting = scope.spawn(|| {
            let got = s.recv(Some(600.0));
            done.store(true, std::sync::atomic::Ordering::SeqCst);
            got
        });
        // Sent and acknowledged (by every field node) while the other thread waits.
        let frame = parse_frame("18FF00F5#0102").unwrap();
        assert!(s.send(frame, 0.0).unwrap());
        let mut sent = 0;
        for _ in 0..3000 {
            sent = s.sent().unwrap();
            if sent > 0 {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert_eq!(sent, 1);
        assert!(!done.load(std::sync::atomic::Ordering::SeqCst));
        // Letting D0's frames through ends the wait.
        s.set_filters(&[from_d0()]).unwrap();
        let got = waiting.join().unwrap().unwrap().and_then(Delivered::frame);
        assert_eq!(got.expect("a frame from D0").frame.raw_id(), 0x0601_F5D0);
    });
}

fn with(options: Options) -> Session {
    Session::start(&Options {
        without: vec!["F5".into()],
        name: "F5".into(),
        seed: Some(1),
        ..options
    })
    .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_first_frame_waits_for_the_boot_and_a_full_queue_runs_the_bus() {
    let s = without_monitor(1);
    // The default harvester: the time relay closes at 500 ms and D5 boots longest, 155 ms.
    assert_eq!(s.ready_s(), 0.655);
    let frame = parse_frame("18FF00F5#0102030405060708").unwrap();
    assert!(s.send(frame, 0.0).unwrap());
    assert_eq!(s.now().unwrap(), 0.655);
    // 1,000 frames sent without a recv: the 16-frame queue fills, and each send then runs the
    // bus until a frame has gone out.
    for _ in 1..1000 {
        assert!(s.send(frame, 1.0).unwrap());
    }
    s.run_for(1.0).unwrap();
    assert_eq!(s.sent().unwrap(), 1000);
    // No room within no time: not queued, and the bus stood still.
    for _ in 0..16 {
        s.send(frame, 0.0).unwrap();
    }
    let now = s.now().unwrap();
    assert!(!s.send(frame, 0.0).unwrap());
    assert_eq!(s.now().unwrap(), now);
    assert!(s.send(frame, f64::NAN).is_err());
    // A controller that never gets its frames out (nobody acknowledges): the whole timeout.
    for n in s.states().unwrap().iter().filter(|n| n.name != "F5") {
        s.act(&format!("Disconnect({:?})", n.name)).unwrap();
    }
    s.run_for(0.1).unwrap();
    let now = s.now().unwrap();
    assert!(!s.send(frame, 0.25).unwrap());
    assert!((s.now().unwrap() - now - 0.25).abs() < 1e-9);
}

#[test]
fn recv_zero_runs_the_bus_up_to_one_frame_time() {
    let s = without_monitor(1);
    s.run_for(2.0).unwrap();
    // Only D0's frames from now on, every 250 ms (the frames waiting are dropped).
    s.set_filters(&[Filter {
        mask: 0x1FFF_FFFF,
        id: 0,
        extended: None,
    }])
    .unwrap();
    s.set_filters(&[from_d0()]).unwrap();
    let mut polls = 0u32;
    let got = loop {
        polls += 1;
        let before = s.now().unwrap();
        if let Some(r) = s.recv(Some(0.0)).unwrap().and_then(Delivered::frame) {
            break r;
        }
        // 160 bit times at 250 kbit/s.
        assert!((s.now().unwrap() - before - 0.00064).abs() < 1e-9);
    };
    // The poll stopped where D0's frame ended, within the 250 ms D0 takes.
    assert_eq!(s.now().unwrap(), got.at_s);
    assert!(
        got.at_s > 2.0 && got.at_s < 2.26 && polls > 1,
        "{polls} polls to {}",
        got.at_s
    );
}

#[test]
fn own_frames_come_back_marked_at_their_end_of_frame() {
    let s = with(Options {
        own_frames: true,
        ..Options::default()
    });
    let own = Filter {
        id: 0x18FF_00F5,
        mask: 0x1FFF_FFFF,
        extended: Some(true),
    };
    s.set_filters(&[own]).unwrap();
    let frame = parse_frame("18FF00F5#01").unwrap();
    assert!(s.send(frame, 0.0).unwrap());
    let r = next(&s, 1.0).expect("its own frame");
    assert!(r.own && r.frame == frame, "{r:?}");
    // Handed over at 0.655 s: it ends at least its length later (an extended frame with one
    // data byte is 75 bits before stuffing, ISO 11898-1: 300 µs at 250 kbit/s), and the recv
    // stopped there.
    assert!(r.at_s > 0.655 + 0.000_3 && r.at_s < 0.66, "{r:?}");
    assert_eq!(s.now().unwrap(), r.at_s);
    // Without asking: never.
    let s = without_monitor(1);
    s.set_filters(&[own]).unwrap();
    assert!(s.send(frame, 0.0).unwrap());
    assert_eq!(s.recv(Some(1.0)).unwrap(), None);
    assert_eq!(s.sent().unwrap(), 1);
}

#[test]
fn listen_only_sends_nothing_acknowledges_nothing_and_still_receives() {
    let s = without_monitor(1);
    s.set_filters(&[from_d0()]).unwrap();
    s.run_for(1.0).unwrap();
    s.set_listen_only(true).unwrap();
    assert!(s.own().unwrap().listen_only);
    let e = s
        .send(parse_frame("18FF00F5#01").unwrap(), 0.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("listen-only"), "{e}");
    assert!(next(&s, 1.0).is_some());
    let tx_before = s.own().unwrap().state.tec;
    s.set_listen_only(false).unwrap();
    assert!(!s.own().unwrap().listen_only);
    assert!(s.send(parse_frame("18FF00F5#01").unwrap(), 0.0).unwrap());
    s.run_for(0.1).unwrap();
    assert_eq!(s.sent().unwrap(), 1);
    assert_eq!(
        (tx_before, s.own().unwrap().state.state.as_str()),
        (0, "error active")
    );
}

#[test]
fn a_start_time_stamps_bus_time_zero() {
    let s = with(Options {
        start_time: Some(Epoch::parse("2025-06-01T12:00:00Z").unwrap()),
        ..Options::default()
    });
    assert_eq!(s.epoch_s(), 1_748_779_200.0);
    assert_eq!(without_monitor(1).epoch_s(), 1_704_067_200.0);
    assert_eq!(s.bitrate(), 250_000);
}

#[test]
fn error_frames_are_the_programs_own_every_controllers_or_none_as_asked() {
    let errors_of = |error_frames| {
        let s = with(Options {
            error_frames,
            ..Options::default()
        });
        s.set_filters(&[from_d0()]).unwrap();
        s.run_for(2.0).unwrap();
        s.act(r#"BitErrors(target: Node("D0"), hits: Always, until_s: Some(2.5))"#)
            .unwrap();
        let mut seen = Vec::new();
        while let Some(d) = s.recv(Some((2.5 - s.now().unwrap()).max(0.0))).unwrap() {
            if let Delivered::Error(e) = d {
                seen.push(e.controller);
            }
            if s.now().unwrap() >= 2.5 {
                break;
            }
        }
        seen
    };
    let own = errors_of(ErrorFrames::Own);
    assert!(!own.is_empty() && own.iter().all(|c| c == "F5"), "{own:?}");
    let all = errors_of(ErrorFrames::All);
    // D0 itself (transmitting), and every receiver, each of its own.
    for c in ["D0", "D1", "E0", "F5"] {
        assert!(all.iter().any(|x| x == c), "no error frame of {c}: {all:?}");
    }
    assert!(errors_of(ErrorFrames::None).is_empty());
}

#[test]
fn expectations_are_checked_as_a_scenario_checks_them() {
    // The whole harvester, the monitor too, with the program beside it.
    let s = Session::start(&Options {
        seed: Some(1),
        name: "tester".into(),
        ..Options::default()
    })
    .unwrap();
    s.run_for(10.0).unwrap();
    // The timeline of configs/scenarios/bus_off.ron, from Python's side.
    s.act(r#"BitErrors(target: Node("D2"), hits: Always, until_s: Some(10.15))"#)
        .unwrap();
    s.run_for(5.0).unwrap();
    let verdicts = s
        .check(
            r#"[
                NodeState(node: "D2", state: BusOff, after_s: 10.0, within_ms: 120),
                BusOffCount(node: "D2", min: 1, max: 6),
                NodeStateHolds(node: "D2", state: Active, from_s: 12.5, to_s: 15.0),
            ]"#,
        )
        .unwrap();
    assert_eq!(verdicts.len(), 3);
    assert!(verdicts.iter().all(|v| v.passed), "{verdicts:?}");
    // One alone, and one that does not hold: D0 was never bus off.
    let v = s
        .check(r#"NodeState(node: "D0", state: BusOff, after_s: 10.0, within_ms: 120)"#)
        .unwrap();
    assert!(!v[0].passed, "{v:?}");
    // Refused, naming what and where.
    let e = s
        .check("[NoCrashes, ErrorKinds(node: \"D2\", kind: Bit, min: 1, max: 9)]")
        .unwrap_err()
        .to_string();
    assert!(e.contains("expect[1]") && e.contains("trace"), "{e}");
    let e = s
        .check(r#"NodeState(node: "Q9", state: BusOff, after_s: 1.0, within_ms: 10)"#)
        .unwrap_err()
        .to_string();
    assert!(e.contains("Q9"), "{e}");
    let e = s.check("NodeState(").unwrap_err().to_string();
    assert!(e.contains("the expectations:1:"), "{e}");
}

#[test]
fn slices_hand_over_the_same_frames_as_recv_one_slice_ahead() {
    let by_recv = {
        let s = with(Options::default());
        let mut got = Vec::new();
        while let Some(d) = s.recv(Some((3.0 - s.now().unwrap()).max(0.0))).unwrap() {
            got.push(d);
            if s.now().unwrap() >= 3.0 {
                break;
            }
        }
        got
    };
    let s = with(Options::default());
    let mut got = Vec::new();
    let mut ends = Vec::new();
    while ends.last().is_none_or(|&e| e < 3.0 - 1e-9) {
        let (end, items) = s.slice().unwrap();
        ends.push(end);
        got.extend(items);
    }
    // Slices of 0.1 s, one after another.
    for (i, end) in ends.iter().enumerate() {
        assert!((end - 0.1 * (i + 1) as f64).abs() < 1e-9, "{ends:?}");
    }
    assert!(!got.is_empty());
    assert_eq!(got, by_recv);
    // The next slice was computed ahead: another call finds the bus at its end.
    assert!((s.now().unwrap() - 3.1).abs() < 1e-9);
    // After it, slices start again from where the bus stands.
    let (end, _) = s.slice().unwrap();
    assert!((end - 3.2).abs() < 1e-9, "{end}");
}
