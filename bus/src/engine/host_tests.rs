//! What a host (firmware behind a register-level controller) can ask of the engine: abort,
//! counters written in reset mode, bus-off recovery on request; and the arbitration-lost
//! events it reads back. Expectations are worked out by hand from the frames' bits.

use super::*;
use crate::candump::parse_frame;

const BIT: u64 = 4000; // 250 kbit/s

fn f(text: &str) -> Frame {
    parse_frame(text).unwrap()
}

fn at(ns: u64) -> BusTime {
    BusTime::from_nanos(ns)
}

fn run(bus: &mut Bus, until_ns: u64) -> Vec<Event> {
    bus.run_until(at(until_ns));
    bus.take_events().collect()
}

#[test]
fn lost_arbitration_bits_are_numbered_as_the_sja1000_alc() {
    let lost = |own: &str, winner: &str| crate::bits::arbitration_lost_at(&f(own), &f(winner));
    // 0x123 = 001 0010 0011 against 0x122: the last identifier bit, number 10.
    assert_eq!(lost("123#", "122#"), Some(10));
    assert_eq!(lost("122#", "123#"), None);
    // Same identifier: the remote frame's recessive RTR (bit 11) loses.
    assert_eq!(lost("100#R", "100#"), Some(11));
    // Extended with ID28..18 = 0x100 against base 0x100: SRR (recessive) meets RTR (dominant).
    assert_eq!(lost("04000000#", "100#"), Some(11));
    // Against a base remote frame, SRR and RTR are both recessive: IDE decides, bit 12.
    assert_eq!(lost("04000000#", "100#R"), Some(12));
    // Extended: ID0 is bit 30, RTR bit 31.
    assert_eq!(lost("1FFFFFFF#", "1FFFFFFE#"), Some(30));
    assert_eq!(lost("1FFFFFFF#R", "1FFFFFFF#"), Some(31));
    // Identical frames do not lose.
    assert_eq!(lost("123#01", "123#01"), None);
}

#[test]
fn stuff_bits_move_later_bits_on_the_wire() {
    // SOF and ID10..7 are five dominant bits: a stuff bit follows unstuffed index 4.
    let frame = f("000#");
    assert_eq!(crate::bits::stuffed_position(&frame, 4), 4);
    assert_eq!(crate::bits::stuffed_position(&frame, 5), 6);
    // 0x7FF: SOF dominant, then eleven recessive bits: a stuff bit after index 5 and index 10.
    let frame = f("7FF#");
    assert_eq!(crate::bits::stuffed_position(&frame, 5), 5);
    assert_eq!(crate::bits::stuffed_position(&frame, 6), 7);
    assert_eq!(crate::bits::stuffed_position(&frame, 11), 13);
}

#[test]
fn losers_hear_where_they_lost() {
    let mut b = Bus::new(BusConfig::default()).unwrap();
    b.report_arbitration(true);
    let n: Vec<NodeId> = (0..3)
        .map(|i| b.attach(ControllerConfig::named(format!("n{i}"))))
        .collect();
    b.submit(n[0], f("1FFFFFFF#00"), at(0)).unwrap();
    b.submit(n[1], f("0300A0F5#01"), at(0)).unwrap();
    b.submit(n[2], f("00000000#"), at(0)).unwrap();
    let lost: Vec<(NodeId, u64, u16)> = run(&mut b, 10_000_000)
        .into_iter()
        .filter_map(|e| match e {
            Event::ArbitrationLost { node, at, bit } => Some((node, at.as_nanos(), bit)),
            _ => None,
        })
        .collect();
    // Round 1, all zeros wins: 0x1FFFFFFF loses at ID28 (bit 0, on the wire the bit after
    // SOF, so the event is 2 bit times in); 0x0300A0F5 has ID28..18 = 000 1100 0000 and loses
    // at bit 3, the fifth dominant bit after SOF, before any stuff bit: 5 bit times in.
    // Round 2 (the 74-bit frame is over): 0x1FFFFFFF loses to 0x0300A0F5 at bit 0 again.
    let s1 = 74 * BIT;
    assert_eq!(
        lost,
        [(n[0], 2 * BIT, 0), (n[1], 5 * BIT, 3), (n[0], s1 + 2 * BIT, 0)]
    );
}

#[test]
fn abort_drops_what_has_not_started_and_not_what_has() {
    let mut b = Bus::new(BusConfig::default()).unwrap();
    let a = b.attach(ControllerConfig::named("a"));
    let _r = b.attach(ControllerConfig::named("r"));
    b.submit(a, f("100#01"), at(0)).unwrap();
    b.submit(a, f("101#02"), at(0)).unwrap();
    // The first frame starts at 0 and is committed whole; the abort at 10 µs drops the second.
    b.step();
    b.abort(a, at(10_000)).unwrap();
    let events = run(&mut b, 10_000_000);
    let sent: Vec<u32> = events
        .iter()
        .filter_map(|e| match e {
            Event::TxDone { frame, .. } => Some(frame.raw_id()),
            _ => None,
        })
        .collect();
    let aborted: Vec<(u32, u64)> = events
        .iter()
        .filter_map(|e| match e {
            Event::TxAborted { frame, at, .. } => Some((frame.raw_id(), at.as_nanos())),
            _ => None,
        })
        .collect();
    assert_eq!(sent, [0x100]);
    assert_eq!(aborted, [(0x101, 10_000)]);
    assert_eq!(b.controller(a).unwrap().counters().tx_aborted, 1);
}

fn state_changes(events: &[Event]) -> Vec<(u64, ErrorState)> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::State { at, to, .. } => Some((at.as_nanos(), *to)),
            _ => None,
        })
        .collect()
}

#[test]
fn counters_written_by_the_host_move_the_state() {
    let mut b = Bus::new(BusConfig::default()).unwrap();
    let a = b.attach(ControllerConfig::named("a"));
    b.set_counters(a, 130, 5, at(1_000)).unwrap();
    b.set_counters(a, 255, 0, at(2_000)).unwrap();
    b.set_counters(a, 300, 0, at(3_000)).unwrap();
    let c = b.controller(a).unwrap();
    assert_eq!((c.fault().tec(), c.fault().rec()), (256, 0));
    let events: Vec<Event> = b.take_events().collect();
    assert_eq!(
        state_changes(&events),
        [(1_000, ErrorState::Passive), (3_000, ErrorState::BusOff)]
    );
}

#[test]
fn an_sja1000_recovers_only_when_its_host_asks() {
    let recovery_bits = 128 * 11;
    // Automatic: 1408 recessive bits after going bus off at 0.
    let mut b = Bus::new(BusConfig::default()).unwrap();
    let a = b.attach(ControllerConfig::named("a"));
    b.set_counters(a, 256, 0, at(0)).unwrap();
    let events = run(&mut b, 1_000_000_000);
    assert_eq!(
        state_changes(&events),
        [(0, ErrorState::BusOff), (recovery_bits * BIT, ErrorState::Active)]
    );

    // On request: nothing for a second; then 1408 bits after the request.
    let mut b = Bus::new(BusConfig::default()).unwrap();
    let config = ControllerConfig {
        recovery: Recovery::OnRequest,
        ..ControllerConfig::named("sja")
    };
    let a = b.attach(config);
    b.set_counters(a, 256, 0, at(0)).unwrap();
    let events = run(&mut b, 1_000_000_000);
    assert_eq!(state_changes(&events), [(0, ErrorState::BusOff)]);
    b.request_recovery(a, at(1_000_000_000)).unwrap();
    let events = run(&mut b, 2_000_000_000);
    assert_eq!(
        state_changes(&events),
        [(1_000_000_000 + recovery_bits * BIT, ErrorState::Active)]
    );
    // It tells of every sequence of 11 recessive bits on the way: the k-th at 11 k bits.
    let progress: Vec<(u64, u8)> = events
        .iter()
        .filter_map(|e| match e {
            Event::RecoveryProgress { at, sequences, .. } => Some((at.as_nanos(), *sequences)),
            _ => None,
        })
        .collect();
    let expected: Vec<(u64, u8)> = (1..128u8)
        .map(|k| (1_000_000_000 + 11 * u64::from(k) * BIT, k))
        .collect();
    assert_eq!(progress, expected);
    // Once recovered, it asks again for the next bus off.
    b.set_counters(a, 256, 0, at(2_000_000_000)).unwrap();
    let events = run(&mut b, 3_000_000_000);
    assert_eq!(state_changes(&events), [(2_000_000_000, ErrorState::BusOff)]);
}
