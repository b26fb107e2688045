//! Disturbances at a place ([`Effect::Disturb`]): a field and a bit of it, found by each node as
//! it is in the frame, give exactly what a disturbance at the same bit times gives.
//!
//! The bit times of every place of the test frame `F` (012#80) are written out by hand below
//! from its layout in `conformance.rs` (stuff bits at 5, 17, 27 and 43; S = 46); a disturbance
//! at the bit time ([`Disturbance`], which the conformance cases check against the rules) is the
//! reference. For the fields after an error, the bit times follow from the rules, worked out in
//! the comments.

mod net;
use bus::engine::{Disturb, DisturbCounts, Field, Place, RuleId};
use net::*;

/// The stuffed bit of `F` at which each place of the frame lies, by hand from the layout.
fn frame_places() -> Vec<(Field, u16, u64)> {
    let mut v = vec![(Field::Sof, 0, 0)];
    // ID10..ID7 at 1..4, stuff bit 5, ID6..ID0 at 6..12.
    v.extend((0..4).map(|b| (Field::Identifier, b, 1 + u64::from(b))));
    v.extend((4..11).map(|b| (Field::Identifier, b, 2 + u64::from(b))));
    v.extend([(Field::Rtr, 0, 13), (Field::Ide, 0, 14), (Field::Reserved, 0, 15)]);
    // DLC3 at 16, stuff bit 17, DLC2..0 at 18..20.
    v.push((Field::Dlc, 0, 16));
    v.extend((1..4).map(|b| (Field::Dlc, b, 17 + u64::from(b))));
    // Data 7..2 at 21..26, stuff bit 27, data 1..0 at 28..29.
    v.extend((0..6).map(|b| (Field::Data, b, 21 + u64::from(b))));
    v.extend((6..8).map(|b| (Field::Data, b, 22 + u64::from(b))));
    // CRC 14..2 at 30..42, stuff bit 43, CRC 1..0 at 44..45.
    v.extend((0..13).map(|b| (Field::Crc, b, 30 + u64::from(b))));
    v.extend((13..15).map(|b| (Field::Crc, b, 31 + u64::from(b))));
    v.extend(
        [5, 17, 27, 43]
            .iter()
            .enumerate()
            .map(|(i, &k)| (Field::StuffBit, i as u16, k)),
    );
    v.extend([
        (Field::CrcDelimiter, 0, S),
        (Field::AckSlot, 0, S + 1),
        (Field::AckDelimiter, 0, S + 2),
    ]);
    v.extend((0..7).map(|b| (Field::Eof, b, S + 3 + u64::from(b))));
    v.extend((0..3).map(|b| (Field::Intermission, b, S + 10 + u64::from(b))));
    v
}

fn rule(tx: NodeId, place: Place, level: bool, bits: u16, seen_by: SeenBy) -> Rule {
    Rule {
        target: Target::Node(tx),
        schedule: Schedule::Once,
        bit: BitPosition::Random,
        effect: Effect::Disturb(Disturb { place, level, bits }),
        seen_by,
    }
}

/// Events and counters of one attempt and what follows, on a bus set up by `setup`.
fn outcome(setup: impl FnOnce(&mut Net)) -> (Vec<Event>, Vec<(u16, u16)>) {
    let mut n = net(2);
    setup(&mut n);
    let mut ev = n.step();
    ev.extend(n.run_for(400));
    let all = [n.tx, n.rx[0], n.rx[1]];
    (ev, all.iter().map(|&i| (n.tec(i), n.rec(i))).collect())
}

#[test]
fn every_place_of_the_frame_is_its_bit_time() {
    for (field, b, k) in frame_places() {
        for level in [true, false] {
            for nodes in [None, Some(1usize)] {
                let by_place = outcome(|n| {
                    let seen_by = nodes.map_or(SeenBy::All, |i| SeenBy::Nodes(vec![n.rx[i - 1]]));
                    let tx = n.tx;
                    n.b.injector_mut()
                        .add(rule(tx, Place { field, bit: b }, level, 2, seen_by));
                });
                let by_time = outcome(|n| {
                    let who = nodes.map(|i| vec![n.rx[i - 1]]);
                    n.disturb(k, 2, Some(level), who);
                });
                assert_eq!(
                    by_place, by_time,
                    "{field:?} bit {b} (bit time {k}), level {level}, {nodes:?}"
                );
            }
        }
    }
}

/// A data bit read recessive at 22 (data bit 1, sent dominant) by everyone: the transmitter's
/// bit error, flag 23..28; the receivers read six dominant bits 23..28, a stuff error, and flag
/// 29..34 (r = 0). Each node's own flag and delimiter then lie at:
/// - the receivers' error flag bit n at 29 + n; the transmitter's at 23 + n;
/// - error delimiter bit 0, the first bit after a node's flag: 35 for the receivers, 29 for the
///   transmitter; bits 1..7 follow the first recessive bit, 35, so they are 36..42 for all;
/// - intermission 43..45.
#[test]
fn places_after_an_error_are_each_nodes_own() {
    let data1 = Place {
        field: Field::Data,
        bit: 1,
    };
    let cases: Vec<(Field, u16, Option<usize>, bool, u64)> = vec![
        (Field::ErrorFlag, 2, Some(0), true, 31),
        (Field::ErrorFlag, 5, Some(1), true, 34),
        (Field::ErrorFlag, 0, None, true, 23),
        (Field::ErrorDelimiter, 0, Some(0), false, 35),
        (Field::ErrorDelimiter, 7, None, false, 42),
        (Field::ErrorDelimiter, 3, Some(1), false, 38),
        (Field::Intermission, 0, None, false, 43),
        (Field::Intermission, 2, Some(0), false, 45),
    ];
    for (field, b, who, level, k) in cases {
        let by_place = outcome(|n| {
            let tx = n.tx;
            n.b.injector_mut().add(rule(tx, data1, true, 1, SeenBy::All));
            let seen_by = who.map_or(SeenBy::All, |i| SeenBy::Nodes(vec![n.rx[i]]));
            n.b.injector_mut()
                .add(rule(tx, Place { field, bit: b }, level, 1, seen_by));
        });
        let by_time = outcome(|n| {
            n.disturb(22, 1, RECESSIVE, None);
            if who.is_none() && field == Field::ErrorFlag {
                // Every node's own first flag bit: the transmitter's at 23, the receivers' at 29.
                n.disturb(23, 1, Some(level), Some(vec![n.tx]));
                n.disturb(29, 1, Some(level), Some(n.rx.clone()));
            } else {
                n.disturb(k, 1, Some(level), who.map(|i| vec![n.rx[i]]));
            }
        });
        assert_eq!(by_place, by_time, "{field:?} bit {b}, {who:?}");
    }
}

/// A dominant first intermission bit (56) of a clean `F`: overload flags 57..62 for all (they
/// read it at once), so each node's overload flag bit n is 57 + n and its overload delimiter
/// bit 0 is 63, bits 1..7 64..70.
#[test]
fn places_after_an_overload() {
    let i0 = Place {
        field: Field::Intermission,
        bit: 0,
    };
    for (field, b, level, k) in [
        (Field::OverloadFlag, 1, true, 58),
        (Field::OverloadDelimiter, 0, false, 63),
        (Field::OverloadDelimiter, 7, false, 70),
    ] {
        let by_place = outcome(|n| {
            let tx = n.tx;
            n.b.injector_mut().add(rule(tx, i0, false, 1, SeenBy::All));
            let r0 = n.rx[0];
            n.b.injector_mut().add(rule(
                tx,
                Place { field, bit: b },
                level,
                1,
                SeenBy::Nodes(vec![r0]),
            ));
        });
        let by_time = outcome(|n| {
            n.disturb(S + 10, 1, DOMINANT, None);
            n.disturb(k, 1, Some(level), Some(vec![n.rx[0]]));
        });
        assert_eq!(by_place, by_time, "{field:?} bit {b}");
    }
}

/// Hits and misses: a data bit past `F`'s one byte is not in the frame; an error flag in a
/// clean attempt is reached by nobody; a data bit that is there is a hit.
#[test]
fn hits_and_misses_are_counted() {
    let mut n = net(2);
    let tx = n.tx;
    let place = |field, bit| Place { field, bit };
    let always = |r: Rule| Rule {
        schedule: Schedule::Always,
        ..r
    };
    let past =
        n.b.injector_mut()
            .add(always(rule(tx, place(Field::Data, 8), false, 1, SeenBy::All)));
    let flag =
        n.b.injector_mut()
            .add(always(rule(tx, place(Field::ErrorFlag, 0), true, 1, SeenBy::All)));
    let ev = n.step();
    assert_eq!(bus_errors(&ev), [], "neither place was reached");
    let counts = |n: &Net, id: RuleId| n.b.injector().disturb_counts(id).unwrap();
    assert_eq!(counts(&n, past), DisturbCounts { hits: 0, misses: 1 });
    assert_eq!(counts(&n, flag), DisturbCounts { hits: 0, misses: 1 });
    let data =
        n.b.injector_mut()
            .add(rule(tx, place(Field::Data, 1), true, 1, SeenBy::All));
    n.b.submit(tx, f(), n.b.committed() + BIT * 100).unwrap();
    n.step();
    assert_eq!(counts(&n, data), DisturbCounts { hits: 1, misses: 0 });
    // The error flag rule reached the transmitter's flag and the receivers' this time.
    assert_eq!(counts(&n, flag), DisturbCounts { hits: 1, misses: 1 });
    assert!(n.b.injector_mut().remove(past));
    assert_eq!(counts(&n, past).misses, 2, "kept after removal");
    assert_eq!(n.b.injector().disturb_counts(RuleId(999)), None);
}

/// The places of an extended frame, `0300A0F5#0101`, by their unstuffed index (from CAN.md's
/// field table: SOF 0, ID28..ID18 1..11, SRR 12, IDE 13, ID17..ID0 14..31, RTR 32, r1 33, r0 34,
/// DLC 35..38, data from 39), put on the wire by `bits::stuffed_position`.
#[test]
fn the_places_of_an_extended_frame() {
    let frame = Frame::extended(0x0300_A0F5, &[0x01, 0x01]).unwrap();
    let mut places: Vec<(Field, u16, u32)> = vec![(Field::Sof, 0, 0)];
    places.extend((0..11).map(|b| (Field::Identifier, b, 1 + u32::from(b))));
    places.extend([(Field::Srr, 0, 12), (Field::Ide, 0, 13)]);
    places.extend((11..29).map(|b| (Field::Identifier, b, 3 + u32::from(b))));
    places.extend([
        (Field::Rtr, 0, 32),
        (Field::Reserved, 0, 33),
        (Field::Reserved, 1, 34),
    ]);
    places.extend((0..4).map(|b| (Field::Dlc, b, 35 + u32::from(b))));
    places.extend((0..16).map(|b| (Field::Data, b, 39 + u32::from(b))));
    let run = |setup: &dyn Fn(&mut Bus, [NodeId; 3])| {
        let mut b = Bus::new(BusConfig::default()).unwrap();
        let ids = [0, 1, 2].map(|i| b.attach(ControllerConfig::named(format!("n{i}"))));
        b.submit(ids[0], frame, BusTime::ZERO).unwrap();
        setup(&mut b, ids);
        b.run_until(BusTime::ZERO + BIT * 400);
        let ev: Vec<Event> = b.take_events().collect();
        let counters: Vec<(u16, u16)> = ids
            .iter()
            .map(|&i| {
                let f = b.controller(i).unwrap().fault();
                (f.tec(), f.rec())
            })
            .collect();
        (ev, counters)
    };
    for (field, bit, index) in places {
        let k = u64::from(bits::stuffed_position(&frame, index));
        for level in [true, false] {
            let by_place = run(&|b, ids| {
                b.injector_mut()
                    .add(rule(ids[0], Place { field, bit }, level, 1, SeenBy::All));
            });
            let by_time = run(&|b, _| {
                b.disturb(Disturbance {
                    at: at(k),
                    bits: 1,
                    level: Some(level),
                    nodes: None,
                });
            });
            assert_eq!(
                by_place, by_time,
                "{field:?} bit {bit} (unstuffed {index}, wire {k}), level {level}"
            );
        }
    }
}
