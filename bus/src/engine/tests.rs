use super::*;
use crate::candump::parse_frame;
use crate::fault::ErrorState;

const BIT: u64 = 4000; // 250 kbit/s

fn bus() -> Bus {
    Bus::new(BusConfig::default()).unwrap()
}

fn f(text: &str) -> Frame {
    parse_frame(text).unwrap()
}

fn run(bus: &mut Bus, until_ns: u64) -> Vec<Event> {
    bus.run_until(BusTime::from_nanos(until_ns));
    bus.take_events().collect()
}

fn frames(events: &[Event]) -> Vec<(u64, u64, NodeId, u32)> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Frame {
                start,
                end,
                node,
                frame,
                ..
            } => Some((start.as_nanos(), end.as_nanos(), *node, frame.raw_id())),
            _ => None,
        })
        .collect()
}

#[test]
fn arbitration_under_contention() {
    let mut b = bus();
    let n: Vec<NodeId> = (0..3)
        .map(|i| b.attach(ControllerConfig::named(format!("n{i}"))))
        .collect();
    // Frame lengths (docs/CAN.md, test vectors): 151, 142 and 74 bits, intermission included.
    b.submit(n[0], f("1FFFFFFF#0000000000000000"), BusTime::from_nanos(0))
        .unwrap();
    b.submit(n[1], f("0300A0F5#0102030405060708"), BusTime::from_nanos(0))
        .unwrap();
    b.submit(n[2], f("00000000#"), BusTime::from_nanos(0)).unwrap();
    let got = frames(&run(&mut b, 1_000_000_000));
    let (s1, s2) = (74 * BIT, (74 + 142) * BIT);
    assert_eq!(
        got,
        [
            (0, (74 - 3) * BIT, n[2], 0x00000000),
            (s1, s1 + (142 - 3) * BIT, n[1], 0x0300A0F5),
            (s2, s2 + (151 - 3) * BIT, n[0], 0x1FFFFFFF),
        ]
    );
    let lost: Vec<u64> = b
        .controllers()
        .iter()
        .map(|c| c.counters().arbitration_lost)
        .collect();
    assert_eq!(lost, [2, 1, 0]);
}

#[test]
fn a_late_starter_waits_for_the_bus() {
    let mut b = bus();
    let a = b.attach(ControllerConfig::named("a"));
    let c = b.attach(ControllerConfig::named("c"));
    // c has the higher priority but asks one bit after a started: it waits for the next idle.
    b.submit(a, f("123#DEADBEEF"), BusTime::from_nanos(0)).unwrap();
    b.submit(c, f("000#"), BusTime::from_nanos(BIT)).unwrap();
    let got = frames(&run(&mut b, 1_000_000));
    assert_eq!(
        got,
        [(0, 78 * BIT, a, 0x123), (81 * BIT, 81 * BIT + 50 * BIT, c, 0)]
    );
    // Within the same bit time, both contend and the lower identifier wins.
    let mut b = bus();
    let a = b.attach(ControllerConfig::named("a"));
    let c = b.attach(ControllerConfig::named("c"));
    b.submit(a, f("123#DEADBEEF"), BusTime::from_nanos(0)).unwrap();
    b.submit(c, f("000#"), BusTime::from_nanos(BIT - 1)).unwrap();
    assert_eq!(frames(&run(&mut b, 1_000_000))[0].2, c);
}

#[test]
fn bus_load_is_the_sum_of_exact_lengths() {
    let mut b = bus();
    let a = b.attach(ControllerConfig {
        tx_queue_len: 100,
        ..ControllerConfig::named("a")
    });
    let _rx = b.attach(ControllerConfig::named("rx"));
    let texts = [
        "123#DEADBEEF",
        "000#",
        "7FF#R",
        "0300A0F5#0102030405060708",
        "1FFFFFFF#0000000000000000",
    ];
    let lengths = [81u64, 53, 50, 142, 151];
    let mut expected_bits = 0;
    for k in 0..100u64 {
        let i = (k % 5) as usize;
        b.submit(a, f(texts[i]), BusTime::from_nanos(k * 1_000_000))
            .unwrap();
        expected_bits += lengths[i];
    }
    run(&mut b, 100_000_000);
    b.advance_stats(BusTime::from_nanos(100_000_000));
    assert_eq!(b.stats().busy_bits, expected_bits);
    let load = expected_bits as f64 * BIT as f64 / 100_000_000.0;
    assert!((b.stats().total_load() - load).abs() < 1e-12);
    assert!((b.stats().window_load(BusDuration::from_millis(100)) - load).abs() < 1e-12);
    assert_eq!(b.stats().frames, 100);
    // Nobody drains the receiver: frames go in while they fit 64 bytes at 3 (base) or 5
    // (extended) bytes plus data each (SJA1000 data sheet, receive FIFO), the rest overrun.
    let sizes = [3 + 4, 3, 3, 5 + 8, 5 + 8];
    let (mut used, mut fit) = (0, 0);
    for k in 0..100 {
        if used + sizes[k % 5] <= 64 {
            used += sizes[k % 5];
            fit += 1;
        }
    }
    assert_eq!((b.stats().deliveries, b.stats().overruns), (fit, 100 - fit));
    let per = b.stats().per_id[&0x123]; // a base identifier: no EFF flag
    assert_eq!(per.count, 20);
    assert_eq!(per.mean_period_ns(), Some(5_000_000.0));
    assert_eq!(per.last_payload(), [0xDE, 0xAD, 0xBE, 0xEF]);
    // A remote frame carries no data.
    assert_eq!(
        b.stats().per_id[&(0x7FF | crate::filter::CAN_RTR_FLAG)].last_payload(),
        [] as [u8; 0]
    );
}

#[test]
fn overrun_when_a_node_stops_draining() {
    let mut b = bus();
    let a = b.attach(ControllerConfig::named("a"));
    let rx = b.attach(ControllerConfig::named("rx"));
    for k in 0..10u64 {
        b.submit(
            a,
            f("0601F5D0#0101341EEA2BEF2C"),
            BusTime::from_nanos(k * 1_000_000),
        )
        .unwrap();
    }
    let events = run(&mut b, 20_000_000);
    // 13 bytes per extended 8-byte frame: four fit in 64 bytes, the rest overrun.
    let delivered = events
        .iter()
        .filter(|e| matches!(e, Event::Delivered { .. }))
        .count();
    let overruns = events
        .iter()
        .filter(|e| matches!(e, Event::Overrun { .. }))
        .count();
    assert_eq!((delivered, overruns), (4, 6));
    assert_eq!(b.controller(rx).unwrap().counters().rx_overruns, 6);
    assert!(b.controller(rx).unwrap().overrun_flag());
    let (got, overrun) = b.drain_rx(rx, BusTime::NEVER).unwrap();
    assert_eq!((got.len(), overrun), (4, true));
    assert_eq!(
        got[0].at,
        BusTime::from_nanos(137 * BIT),
        "stamped with the end of frame"
    );
    // Drained: there is room again, and the flag is clear.
    assert!(!b.controller(rx).unwrap().overrun_flag());
    b.submit(a, f("0601F5D0#01"), BusTime::from_nanos(30_000_000))
        .unwrap();
    run(&mut b, 40_000_000);
    assert_eq!(b.controller(rx).unwrap().rx_len(), 1);
}

#[test]
fn bus_off_and_recovery_after_128_times_11_recessive_bits() {
    let mut b = bus();
    let bad = b.attach(ControllerConfig::named("bad"));
    let good = b.attach(ControllerConfig::named("good"));
    b.injector_mut().add(Rule::bit_errors(
        Target::Node(bad),
        Schedule::Always,
        BitPosition::At(40),
    ));
    b.submit(bad, f("0601F5D0#0101341EEA2BEF2C"), BusTime::from_nanos(0))
        .unwrap();
    let events = run(&mut b, 1_000_000_000);
    let errors: Vec<&Event> = events
        .iter()
        .filter(|e| matches!(e, Event::ErrorFrame { .. }))
        .collect();
    // TEC +8 per error: passive at the 16th (128), bus off at the 32nd (256).
    assert_eq!(errors.len(), 32);
    let states: Vec<(ErrorState, ErrorState, u16)> = events
        .iter()
        .filter_map(|e| match e {
            Event::State {
                node, from, to, tec, ..
            } if *node == bad => Some((*from, *to, *tec)),
            _ => None,
        })
        .collect();
    assert_eq!(
        states,
        [
            (ErrorState::Active, ErrorState::Passive, 128),
            (ErrorState::Passive, ErrorState::BusOff, 256),
            (ErrorState::BusOff, ErrorState::Active, 0),
        ]
    );
    assert_eq!(b.controller(good).unwrap().fault().rec(), 32);
    // The last error takes TEC to 256: the node is bus off at once and sends no flag. The
    // receiver samples the flipped bit 40 and then a recessive bus, and finds a stuff error at
    // the sixth equal bit; its active flag (6 dominant bits) breaks the bus-off node's count,
    // which starts again from the flag's end.
    let Event::ErrorFrame { flag, start, .. } = errors[31] else {
        unreachable!()
    };
    assert_eq!(
        flag.as_nanos() - start.as_nanos(),
        41 * BIT,
        "bus off at the first bit after the error"
    );
    let stuffed = crate::bits::encode(&f("0601F5D0#0101341EEA2BEF2C")).stuffed;
    let level = |i: usize| match i {
        40 => !stuffed.get(40).unwrap(),
        i if i > 40 => true,
        i => stuffed.get(i).unwrap(),
    };
    let sixth_equal = (41..)
        .find(|&p| (p - 5..p).all(|q| level(q) == level(p)))
        .unwrap() as u64;
    let recovered = events
        .iter()
        .find_map(|e| match e {
            Event::State {
                node,
                to: ErrorState::Active,
                at,
                ..
            } if *node == bad => Some(*at),
            _ => None,
        })
        .unwrap();
    assert_eq!(
        recovered.as_nanos(),
        start.as_nanos() + (sixth_equal + 1 + 6) * BIT + 128 * 11 * BIT
    );
    // The frame it was sending when it went bus off was dropped.
    assert_eq!(
        events
            .iter()
            .filter(|e| matches!(e, Event::TxAborted { .. }))
            .count(),
        1
    );
    assert_eq!(b.controller(bad).unwrap().tx_len(), 0);
}

#[test]
fn recovery_counts_recessive_runs_between_frames() {
    // While bad is bus off, good keeps sending: each frame breaks the recessive run, so recovery
    // takes longer than 1408 bit times of wall-clock bus time but happens all the same.
    let mut b = bus();
    let bad = b.attach(ControllerConfig::named("bad"));
    let good = b.attach(ControllerConfig::named("good"));
    let _third = b.attach(ControllerConfig::named("third"));
    b.injector_mut().add(Rule::bit_errors(
        Target::Node(bad),
        Schedule::Always,
        BitPosition::At(40),
    ));
    b.submit(bad, f("0601F5D0#01"), BusTime::from_nanos(0)).unwrap();
    for k in 0..200u64 {
        b.submit(good, f("0601F5D1#01"), BusTime::from_nanos(k * 2_000_000))
            .unwrap();
    }
    let events = run(&mut b, 400_000_000);
    let off = events.iter().find_map(|e| match e {
        Event::State {
            node,
            to: ErrorState::BusOff,
            at,
            ..
        } if *node == bad => Some(*at),
        _ => None,
    });
    let back = events.iter().find_map(|e| match e {
        Event::State {
            node,
            to: ErrorState::Active,
            from: ErrorState::BusOff,
            at,
            ..
        } if *node == bad => Some(*at),
        _ => None,
    });
    let (off, back) = (off.unwrap(), back.unwrap());
    let (back, off) = (back.as_nanos(), off.as_nanos());
    assert!(back - off > 1408 * BIT, "frames in between break the runs");
    // Each 2 ms gap holds 500 bits, so 45 sequences per gap: three gaps' worth at least.
    assert!(back - off < 4 * 2_000_000 + 1408 * BIT);
}

#[test]
fn a_lone_transmitter_goes_error_passive_and_never_bus_off() {
    let mut b = bus();
    let lone = b.attach(ControllerConfig::named("lone"));
    b.submit(lone, f("0300A0F5#01"), BusTime::from_nanos(0)).unwrap();
    let events = run(&mut b, 2_000_000_000);
    let acks = events
        .iter()
        .filter(|e| {
            matches!(
                e,
                Event::ErrorFrame {
                    error: BusError::Ack,
                    ..
                }
            )
        })
        .count();
    assert!(acks > 1000, "it keeps retrying: {acks}");
    let c = b.controller(lone).unwrap();
    assert_eq!((c.fault().tec(), c.fault().state()), (128, ErrorState::Passive));
    assert!(!events.iter().any(|e| matches!(
        e,
        Event::State {
            to: ErrorState::BusOff,
            ..
        }
    )));
    assert_eq!(c.counters().tx_frames, 0);
}

#[test]
fn a_node_that_does_not_ack() {
    let mut b = bus();
    let a = b.attach(ControllerConfig::named("a"));
    let mute = b.attach(ControllerConfig::named("mute"));
    b.set_ack(mute, false).unwrap();
    b.submit(a, f("0300A0F5#01"), BusTime::from_nanos(0)).unwrap();
    let events = run(&mut b, 1_000_000);
    let Some(Event::ErrorFrame {
        error,
        bit,
        flag,
        start,
        ..
    }) = events
        .iter()
        .find(|e| matches!(e, Event::ErrorFrame { .. }))
        .copied()
    else {
        panic!()
    };
    assert_eq!(error, BusError::Ack);
    // The flag starts at the ACK delimiter: after the stuffed SOF..CRC, the CRC delimiter and
    // the ACK slot.
    let stuffed = crate::bits::encode(&f("0300A0F5#01")).stuffed.len() as u64;
    assert_eq!(u64::from(bit), stuffed + 1);
    assert_eq!(flag.as_nanos() - start.as_nanos(), (stuffed + 2) * BIT);
    assert_eq!(
        b.controller(mute).unwrap().fault().rec(),
        events
            .iter()
            .filter(|e| matches!(e, Event::ErrorFrame { .. }))
            .count() as u16
    );
    // With the ACK back, the retransmission goes through.
    b.set_ack(mute, true).unwrap();
    let later = run(&mut b, 10_000_000);
    assert_eq!(frames(&later).len(), 1);
}

#[test]
fn disconnected_nodes_neither_send_nor_receive() {
    let mut b = bus();
    let a = b.attach(ControllerConfig::named("a"));
    let rx = b.attach(ControllerConfig::named("rx"));
    let gone = b.attach(ControllerConfig::named("gone"));
    b.set_connected(gone, false, BusTime::from_nanos(0)).unwrap();
    b.submit(gone, f("001#"), BusTime::from_nanos(0)).unwrap();
    b.submit(a, f("002#"), BusTime::from_nanos(0)).unwrap();
    let events = run(&mut b, 10_000_000);
    assert_eq!(frames(&events).iter().map(|f| f.2).collect::<Vec<_>>(), [a]);
    assert_eq!(b.controller(gone).unwrap().rx_len(), 0);
    assert_eq!(b.controller(rx).unwrap().rx_len(), 1);
    b.set_connected(gone, true, BusTime::from_nanos(10_000_000))
        .unwrap();
    let events = run(&mut b, 20_000_000);
    // Back on an idle bus, it integrates first: 11 recessive bits of 4 µs.
    assert_eq!(
        frames(&events).iter().map(|f| (f.0, f.2)).collect::<Vec<_>>(),
        [(10_000_000 + 11 * 4_000, gone)]
    );
}

#[test]
fn filters_decide_what_reaches_the_fifo() {
    let mut b = bus();
    let a = b.attach(ControllerConfig::named("a"));
    let monitor_only = crate::filter::SocketCanFilterSet(vec![crate::filter::SocketCanFilter::new(
        crate::filter::CAN_EFF_FLAG | 0xF500,
        crate::filter::CAN_EFF_FLAG | 0xFF00,
    )]);
    let m = b.attach(ControllerConfig::named("m").with_filter(Filter::SocketCan(monitor_only)));
    b.submit(a, f("0601F5D0#01"), BusTime::from_nanos(0)).unwrap();
    b.submit(a, f("0300A0F5#01"), BusTime::from_nanos(0)).unwrap();
    run(&mut b, 10_000_000);
    let c = b.controller(m).unwrap();
    assert_eq!((c.rx_len(), c.counters().rx_filtered), (1, 1));
    // Filtering does not stop a node from acknowledging and counting the frame as received.
    assert_eq!(b.stats().frames, 2);
}

#[test]
fn identical_frames_go_out_together_different_ones_collide() {
    let mut b = bus();
    let x = b.attach(ControllerConfig::named("x"));
    let y = b.attach(ControllerConfig::named("y"));
    let _z = b.attach(ControllerConfig::named("z"));
    b.submit(x, f("100#01"), BusTime::from_nanos(0)).unwrap();
    b.submit(y, f("100#01"), BusTime::from_nanos(0)).unwrap();
    let events = run(&mut b, 1_000_000);
    assert_eq!(frames(&events).len(), 1);
    assert_eq!(
        events
            .iter()
            .filter(|e| matches!(e, Event::TxDone { .. }))
            .count(),
        2
    );
    b.submit(x, f("100#01"), BusTime::from_nanos(2_000_000)).unwrap();
    b.submit(y, f("100#02"), BusTime::from_nanos(2_000_000)).unwrap();
    assert!(b.step());
    let events: Vec<Event> = b.take_events().collect();
    let lost = |node| {
        events.iter().find_map(|e| match *e {
            Event::ErrorFrame {
                node: n,
                error: BusError::Bit,
                bit,
                ..
            } if n == node => Some(usize::from(bit)),
            _ => None,
        })
    };
    // 100#01 and 100#02 first differ in the last data bits: the node that sends recessive there
    // (y) reads dominant, a bit error; x reads its own bits until y's error flag (dominant from
    // the next bit) meets a recessive bit of x's.
    let (one, two) = (
        crate::bits::encode(&f("100#01")).stuffed,
        crate::bits::encode(&f("100#02")).stuffed,
    );
    let first_difference = (0..one.len()).find(|&i| one.get(i) != two.get(i)).unwrap();
    assert_eq!(two.get(first_difference), Some(true), "y sends recessive there");
    assert_eq!(lost(y), Some(first_difference), "{events:?}");
    let x_sees = (first_difference + 1..)
        .find(|&i| one.get(i) == Some(true))
        .unwrap();
    assert!(x_sees <= first_difference + 6);
    assert_eq!(lost(x), Some(x_sees), "{events:?}");
    assert_eq!(b.controller(x).unwrap().fault().tec(), 8);
    assert_eq!(b.controller(y).unwrap().fault().tec(), 8);
}

#[test]
fn late_submissions_are_moved_to_the_present_and_counted() {
    let mut b = bus();
    let a = b.attach(ControllerConfig::named("a"));
    let _rx = b.attach(ControllerConfig::named("rx"));
    b.submit(a, f("001#"), BusTime::from_nanos(5_000_000)).unwrap();
    run(&mut b, 10_000_000);
    b.submit(a, f("002#"), BusTime::from_nanos(1_000_000)).unwrap();
    assert_eq!(b.late_submissions(), 1);
    let got = frames(&run(&mut b, 20_000_000));
    assert_eq!(
        got[0].0,
        5_000_000 + 50 * BIT,
        "at the present: after the last committed frame"
    );
}

#[test]
fn transmit_queue_is_bounded() {
    let mut b = bus();
    let a = b.attach(ControllerConfig {
        tx_queue_len: 2,
        ..ControllerConfig::named("a")
    });
    assert!(b.submit(a, f("001#"), BusTime::from_nanos(0)).unwrap().is_some());
    assert!(b.submit(a, f("001#"), BusTime::from_nanos(0)).unwrap().is_some());
    assert!(b.submit(a, f("001#"), BusTime::from_nanos(0)).unwrap().is_none());
    assert_eq!(b.controller(a).unwrap().counters().tx_refused, 1);
}

#[test]
fn random_injection_is_deterministic_under_a_seed() {
    let trace = |seed| {
        let mut b = Bus::new(BusConfig {
            seed,
            ..BusConfig::default()
        })
        .unwrap();
        let a = b.attach(ControllerConfig {
            tx_queue_len: 500,
            ..ControllerConfig::named("a")
        });
        let _r = b.attach(ControllerConfig::named("r"));
        b.injector_mut().add(Rule::bit_errors(
            Target::Any,
            Schedule::BitErrorRate(1e-3),
            BitPosition::Random,
        ));
        for k in 0..500u64 {
            b.submit(
                a,
                f("0601F5D0#0101341EEA2BEF2C"),
                BusTime::from_nanos(k * 1_000_000),
            )
            .unwrap();
        }
        run(&mut b, 600_000_000)
    };
    let (one, two, other) = (trace(42), trace(42), trace(43));
    assert_eq!(one, two);
    assert_ne!(one, other);
    let errors = one
        .iter()
        .filter(|e| matches!(e, Event::ErrorFrame { .. }))
        .count();
    // 500 frames of about 140 bits at 1e-3: about 65 hit.
    assert!((30..=110).contains(&errors), "{errors}");
}

#[test]
fn rejects_inexact_bit_rates() {
    let err = Bus::new(BusConfig {
        bitrate: crate::bits::BitRate::new(33_300).unwrap(),
        ..BusConfig::default()
    })
    .unwrap_err();
    assert!(err.to_string().contains("33300"), "{err}");
}

#[test]
fn error_counters_are_kept_over_time() {
    let mut b = bus();
    let a = b.attach(ControllerConfig::named("a"));
    let _rx = b.attach(ControllerConfig::named("rx"));
    let rule = b.injector_mut().add(Rule::bit_errors(
        Target::Node(a),
        Schedule::Always,
        BitPosition::At(40),
    ));
    b.submit(a, f("123#01"), BusTime::from_nanos(0)).unwrap();
    // Four errors, then the rule goes and the frame and four more go through.
    for _ in 0..4 {
        b.step();
    }
    b.injector_mut().remove(rule);
    for k in 0..5u64 {
        b.submit(a, f("123#01"), BusTime::from_nanos(1_000_000 * (k + 1)))
            .unwrap();
    }
    run(&mut b, 100_000_000);
    let tec: Vec<u16> = b.stats().nodes[0]
        .counters
        .points
        .iter()
        .map(|(_, (tec, _, _))| *tec)
        .collect();
    // +8 per error, then -1 per successful frame, every change recorded once.
    assert_eq!(tec, [8, 16, 24, 32, 31, 30, 29, 28, 27, 26]);
    let rec: Vec<u16> = b.stats().nodes[1]
        .counters
        .points
        .iter()
        .map(|(_, (_, rec, _))| *rec)
        .collect();
    assert_eq!(rec, [1, 2, 3, 4, 3, 2, 1, 0]);
}

/// Every frame that completes is, for each other controller, in exactly one of: missed (off the
/// bus), filtered, stored, overrun; and what is stored is read, cleared by a reset or still there.
#[test]
fn receive_books_place_every_frame() {
    let mut b = bus();
    let tx = b.attach(ControllerConfig::named("tx"));
    let filter = Filter::SocketCan(crate::filter::SocketCanFilterSet(vec![
        crate::filter::SocketCanFilter::new(
            crate::filter::CAN_EFF_FLAG | 0xF500,
            crate::filter::CAN_EFF_FLAG | 0xFF00,
        ),
    ]));
    let rx = b.attach(ControllerConfig::named("rx").with_filter(filter.clone()));
    // A third node that acknowledges while `rx` is away, so that frames still complete.
    b.attach(ControllerConfig::named("ack").with_filter(Filter::Nothing));
    let to_rx = f("0500F5B1#01");
    let other = f("0500A0B1#02");
    let mut t = 0;
    let send = |b: &mut Bus, t: &mut u64, frame: Frame, n: usize| {
        for _ in 0..n {
            b.submit(tx, frame, BusTime::from_nanos(*t)).unwrap();
            *t += 1_000_000;
            b.run_until(BusTime::from_nanos(*t));
        }
    };
    send(&mut b, &mut t, to_rx, 3); // stored
    send(&mut b, &mut t, other, 2); // filtered
    b.set_connected(rx, false, BusTime::from_nanos(t)).unwrap();
    send(&mut b, &mut t, to_rx, 4); // missed
    send(&mut b, &mut t, other, 1); // not addressed to it: not missed either
    b.set_connected(rx, true, BusTime::from_nanos(t)).unwrap();
    // It takes part once it has seen 11 recessive bits (44 µs): give it 100 µs.
    t += 100_000;
    send(&mut b, &mut t, to_rx, 2); // stored
    let (read, _) = b.drain_rx(rx, BusTime::from_nanos(t)).unwrap();
    assert_eq!(read.len(), 5);
    send(&mut b, &mut t, to_rx, 1); // stored, then cleared by the reset
    b.reset_node(rx, BusTime::from_nanos(t)).unwrap();
    t += 100_000;
    send(&mut b, &mut t, to_rx, 1); // stored, still there
    // The sender's own frames are not received, but its filter (All) accepts them.
    let c = *b.controller(rx).unwrap().counters();
    assert_eq!(
        (
            c.rx_frames,
            c.rx_filtered,
            c.rx_missed,
            c.rx_read,
            c.rx_cleared,
            c.rx_overruns
        ),
        (7, 2, 4, 5, 1, 0)
    );
    assert_eq!(b.controller(rx).unwrap().rx_len(), 1);
    let own = b.controller(tx).unwrap().counters();
    assert_eq!((own.tx_frames, own.rx_own), (14, 14));
    assert_eq!(b.stats().frames, 14);
}

/// The receive counters of a node whose filter accepts every frame below, summed as the books
/// sum them: each accepted frame that completed on the bus is in exactly one.
fn placed(b: &Bus, node: NodeId) -> (u64, u64, u64) {
    let c = b.controller(node).unwrap().counters();
    let all = c.rx_own + c.rx_missed + c.rx_overruns + c.rx_errored + c.rx_frames;
    (all, c.rx_errored, c.rx_missed)
}

/// An error-passive receiver that alone detects an error in a frame sends a recessive flag: the
/// frame completes for the others and is lost to it. It is booked as errored, not left out.
#[test]
fn a_frame_an_error_passive_receiver_alone_flagged_is_booked() {
    let mut b = bus();
    let rx = b.attach(ControllerConfig::named("rx"));
    let tx = b.attach(ControllerConfig::named("tx").with_filter(Filter::Nothing));
    // A third node acknowledges while `rx` is busy with its error flag.
    b.attach(ControllerConfig::named("ack").with_filter(Filter::Nothing));
    // `rx` alone samples a dominant bus for a while during a frame of its own: it loses
    // arbitration, detects an error as a receiver, and the dominant bits after its flag raise
    // its REC past 127. Its retransmission then succeeds, which leaves its REC alone: it stays
    // error passive.
    b.disturb(Disturbance {
        at: BusTime::from_nanos(20 * BIT),
        bits: 160,
        level: Some(false),
        nodes: Some(vec![rx]),
    });
    b.submit(rx, f("1F00A0F5#01"), BusTime::from_nanos(0)).unwrap();
    run(&mut b, 100_000_000);
    let c = b.controller(rx).unwrap();
    assert_eq!((c.fault().state(), c.tx_len()), (ErrorState::Passive, 0));
    let before = placed(&b, rx);
    // A disturbance only `rx` samples, in the identifier of the next frame.
    let at = BusTime::from_nanos(300_000_000);
    b.disturb(Disturbance {
        at: at + BusDuration::from_nanos(10 * BIT),
        bits: 1,
        level: None,
        nodes: Some(vec![rx]),
    });
    b.submit(tx, f("0500F5B1#02"), at).unwrap();
    let events = run(&mut b, 400_000_000);
    assert_eq!(frames(&events).len(), 1, "{events:?}");
    assert!(events.iter().any(|e| matches!(
        e,
        Event::BusError { node, transmitting: false, .. } if *node == rx
    )));
    assert_eq!(b.controller(rx).unwrap().fault().state(), ErrorState::Passive);
    let after = placed(&b, rx);
    assert_eq!(after, (before.0 + 1, before.1 + 1, before.2));
}

/// A frame that completes bit by bit (a disturbance reaches the attempt) while a node is
/// disconnected is booked as missed, as a clean frame is.
#[test]
fn a_frame_completed_bit_by_bit_is_missed_by_a_disconnected_node() {
    let mut b = bus();
    let rx = b.attach(ControllerConfig::named("rx"));
    let tx = b.attach(ControllerConfig::named("tx").with_filter(Filter::Nothing));
    b.attach(ControllerConfig::named("ack").with_filter(Filter::Nothing));
    b.set_connected(rx, false, BusTime::from_nanos(0)).unwrap();
    // A disturbance that reaches nobody sends the attempt down the bit-level path.
    b.disturb(Disturbance {
        at: BusTime::from_nanos(0),
        bits: 1,
        level: None,
        nodes: Some(Vec::new()),
    });
    b.submit(tx, f("0500F5B1#02"), BusTime::from_nanos(0)).unwrap();
    let events = run(&mut b, 100_000_000);
    assert_eq!(frames(&events).len(), 1, "{events:?}");
    assert_eq!(placed(&b, rx), (1, 0, 1));
}

/// A clean attempt committed in closed form and the same attempt run bit by bit give the same
/// frames, deliveries and confirmations at the same times (a disturbance that reaches nobody
/// sends the second run down the bit-level path without changing anything on the wire).
#[test]
fn bit_by_bit_and_closed_form_agree_on_clean_frames() {
    let texts = [
        "0300A0F5#0101",
        "123#R",
        "1FFFFFFF#FFFFFFFFFFFFFFFF",
        "000#",
        "7FF#00000000",
        "0601F5D0#0101341EEA2BEF2C",
        "0500F5B1#",
    ];
    let run_all = |bit_level: bool| {
        let mut b = bus();
        // Lost arbitration is among the events that must agree.
        b.report_arbitration(true);
        let tx = b.attach(ControllerConfig::named("tx"));
        let rx: Vec<NodeId> = (0..3)
            .map(|i| b.attach(ControllerConfig::named(format!("rx{i}"))))
            .collect();
        let mut events = Vec::new();
        for (k, text) in texts.iter().enumerate() {
            let at = BusTime::from_nanos(k as u64 * 2_000_000);
            if bit_level {
                b.disturb(Disturbance {
                    at,
                    bits: 1,
                    level: None,
                    nodes: Some(Vec::new()),
                });
            }
            b.submit(tx, f(text), at).unwrap();
            // A receiver answers at once: two frames contend with the next one.
            b.submit(rx[k % 3], f("0100F5B2#AA"), at).unwrap();
            events.extend(run(&mut b, at.as_nanos() + 1_900_000));
        }
        events.retain(|e| !matches!(e, Event::State { .. } | Event::Warning { .. }));
        (events, b.stats().busy_bits, b.stats().frames)
    };
    let (closed, busy_closed, frames_closed) = run_all(false);
    let (bitwise, busy_bitwise, frames_bitwise) = run_all(true);
    assert_eq!(frames_closed, 2 * texts.len() as u64);
    assert_eq!(closed, bitwise);
    assert_eq!((busy_closed, frames_closed), (busy_bitwise, frames_bitwise));
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]

    /// Under any mix of injected faults the engine's events never go back in time, every node's
    /// state agrees with its counters, and a transmitter's frames leave its queue only as sent or
    /// aborted at bus off.
    #[test]
    fn random_faults_keep_time_and_books(
        seed in 0u64..1000,
        kinds in proptest::collection::vec(0u8..6, 1..4),
        rate in 1u32..6,
    ) {
        let mut b = Bus::new(BusConfig { seed, ..BusConfig::default() }).unwrap();
        let nodes: Vec<NodeId> = (0..5)
            .map(|i| b.attach(ControllerConfig::named(format!("n{i}"))))
            .collect();
        for (k, kind) in kinds.iter().enumerate() {
            let effect = match kind {
                0 => Effect::Bit,
                1 => Effect::Stuff,
                2 => Effect::Crc,
                3 => Effect::Form,
                4 => Effect::Overload(2),
                _ => Effect::Overload(1),
            };
            let seen_by = if k % 2 == 0 {
                SeenBy::All
            } else {
                SeenBy::Nodes(vec![nodes[k % 5], nodes[(k + 2) % 5]])
            };
            b.injector_mut().add(Rule {
                target: Target::Any,
                schedule: Schedule::EveryNth(rate),
                bit: BitPosition::Random,
                effect,
                seen_by,
            });
        }
        let mut submitted = 0u64;
        let mut last = BusTime::ZERO;
        let mut done = 0u64;
        let mut aborted = 0u64;
        for step in 0..60u64 {
            let at = BusTime::from_nanos(step * 300_000);
            for (i, &n) in nodes.iter().enumerate() {
                if (step + i as u64).is_multiple_of(3) {
                    let frame = Frame::extended(0x0600_0000 | (i as u32) << 8 | step as u32 & 0xFF, &[step as u8, i as u8]).unwrap();
                    if b.submit(n, frame, at).unwrap().is_some() {
                        submitted += 1;
                    }
                }
            }
            b.run_until(BusTime::from_nanos(at.as_nanos() + 300_000));
            for e in b.take_events() {
                match e {
                    Event::TxDone { .. } => done += 1,
                    Event::TxAborted { .. } => aborted += 1,
                    _ => {}
                }
                let t = e.at();
                proptest::prop_assert!(t >= last, "{e:?} before {last}");
                last = t;
            }
        }
        let queued: u64 = nodes.iter().map(|&n| b.controller(n).unwrap().tx_len() as u64).sum();
        proptest::prop_assert_eq!(submitted, done + aborted + queued);
        for &n in &nodes {
            let fc = b.controller(n).unwrap().fault();
            let expected = if fc.tec() >= 256 {
                ErrorState::BusOff
            } else if fc.tec() >= 128 || fc.rec() >= 128 {
                ErrorState::Passive
            } else {
                ErrorState::Active
            };
            proptest::prop_assert_eq!(fc.state(), expected);
        }
    }
}

/// docs/CAN.md, section 6, worked example: `0300A0F5#0101`, a wire flip at stuffed bit 51 (the
/// transmitter sends 1 there), all nodes error active. Bits 47..=50 read 1000 and the flipped bit
/// makes r = 4 dominant bits: the transmitter flags from 52, the receivers see their sixth
/// dominant bit at 53 and flag from 54 to 59, the delimiter is 60..=67, intermission 68..=70,
/// and the retransmission starts at bit 71 (284 µs).
#[test]
fn the_worked_error_frame_of_can_md() {
    let frame = f("0300A0F5#0101");
    let stuffed = crate::bits::encode(&frame).stuffed;
    let bits: String = (47..=51)
        .map(|i| if stuffed.get(i) == Some(true) { '1' } else { '0' })
        .collect();
    assert_eq!(bits, "10001");
    let mut b = bus();
    let tx = b.attach(ControllerConfig::named("tx"));
    let rx: Vec<NodeId> = (0..3)
        .map(|i| b.attach(ControllerConfig::named(format!("rx{i}"))))
        .collect();
    b.injector_mut().add(Rule::bit_errors(
        Target::Node(tx),
        Schedule::Once,
        BitPosition::At(51),
    ));
    b.submit(tx, frame, BusTime::from_nanos(0)).unwrap();
    let events = run(&mut b, 2_000_000);
    let seen: Vec<(NodeId, u64, BusError)> = events
        .iter()
        .filter_map(|e| match *e {
            Event::BusError { node, at, error, .. } => Some((node, at.as_nanos() / BIT, error)),
            _ => None,
        })
        .collect();
    let mut expected = vec![(tx, 52, BusError::Bit)];
    expected.extend(rx.iter().map(|&r| (r, 54, BusError::Stuff)));
    assert_eq!(seen, expected);
    let retransmitted = frames(&events);
    assert_eq!(retransmitted.len(), 1);
    assert_eq!(retransmitted[0].0, 71 * BIT, "284 µs");
    assert_eq!(
        b.controller(tx).unwrap().fault().tec(),
        8 - 1,
        "+8, then -1 for the success"
    );
    for r in rx {
        assert_eq!(
            b.controller(r).unwrap().fault().rec(),
            0,
            "+1, then -1 for the success"
        );
    }
}
