//! The controller modes real drivers use, at the engine: single shot (the SJA1000's TR with AT,
//! Linux's CAN_CTRLMODE_ONE_SHOT), self test (MOD.STM, PRESUME_ACK), listen only (MOD.LOM,
//! LISTENONLY), abort, sleep (MOD.SM), rule 8's ACK condition, what counts as an error frame,
//! the counters an error line carries and the frame a receiver takes although its transmitter
//! flags an error.
//!
//! The bench and the frame `F` (012#80) are those of `conformance.rs`, whose module docs lay `F`
//! out bit by bit: stuffed part 0..45, CRC delimiter 46, ACK slot 47, ACK delimiter 48, EOF
//! 49..55, intermission 56..58. Every expectation is worked out from the rules in the comments.

mod net;
use net::*;

fn aborted(ev: &[Event]) -> Vec<(NodeId, u64)> {
    ev.iter()
        .filter_map(|e| match *e {
            Event::TxAborted { node, at, .. } => Some((node, bits_at(at))),
            _ => None,
        })
        .collect()
}

fn done(ev: &[Event]) -> Vec<(NodeId, u64)> {
    ev.iter()
        .filter_map(|e| match *e {
            Event::TxDone { node, at, .. } => Some((node, bits_at(at))),
            _ => None,
        })
        .collect()
}

/// Self test: alone on the bus, F completes without an acknowledge. Nobody drives the ACK slot
/// (47), which is no error to a transmitter that presumes it; EOF ends at 56 and TEC stays 0.
/// The same node without self test has an ACK error with its flag at 48.
#[test]
fn self_test_needs_no_acknowledge() {
    let mut n = net(0);
    n.b.set_presume_ack(n.tx, true).unwrap();
    let ev = n.step();
    assert_eq!(bus_errors(&ev), []);
    assert_eq!(frames(&ev), [(n.tx, 0)]);
    assert_eq!(done(&ev), [(n.tx, 56)]);
    assert_eq!(n.tec(n.tx), 0);

    let mut n = net(0);
    let ev = n.step();
    assert_eq!(bus_errors(&ev), [(n.tx, 48, BusError::Ack)]);
}

/// Self test with a receiver that acknowledges, and in a disturbed attempt (run bit by bit):
/// still no error; the disturbance (a recessive ACK slot that only tx reads) would be an ACK
/// error without self test.
#[test]
fn self_test_holds_bit_by_bit() {
    let mut n = net(1);
    n.b.set_presume_ack(n.tx, true).unwrap();
    n.disturb(47, 1, RECESSIVE, Some(vec![n.tx]));
    let ev = n.step();
    assert_eq!(bus_errors(&ev), []);
    assert_eq!(done(&ev), [(n.tx, 56)]);
    assert_eq!(delivered(&ev), [(n.rx[0], 56)]);

    let mut n = net(1);
    n.disturb(47, 1, RECESSIVE, Some(vec![n.tx]));
    let ev = n.step();
    assert_eq!(bus_errors(&ev)[0], (n.tx, 48, BusError::Ack));
}

/// Single shot, alone: one attempt. Its ACK error at 47 is flagged 48..53 (TEC 8); the bus is
/// quiet from 54, when the attempt is over and the frame dropped. Nothing is retried.
#[test]
fn single_shot_makes_one_attempt() {
    let mut b = Bus::new(BusConfig::default()).unwrap();
    let tx = b.attach(ControllerConfig::named("tx"));
    b.submit_with(tx, f(), BusTime::ZERO, true).unwrap();
    assert!(b.step());
    let ev: Vec<Event> = b.take_events().collect();
    assert_eq!(bus_errors(&ev), [(tx, 48, BusError::Ack)]);
    assert_eq!(aborted(&ev), [(tx, 54)]);
    assert!(!b.step(), "a single-shot frame is not retried");
    let c = b.controller(tx).unwrap();
    assert_eq!((c.fault().tec(), c.tx_len(), c.counters().tx_aborted), (8, 0, 1));
}

/// Single shot losing arbitration (closed form): w sends 011#80 and tx sends 012#80 from the
/// same instant. ID10..ID0 are 000 0001 0001 against 000 0001 0010: they part at ID1, the 10th
/// identifier bit (ALC 9), where tx sends recessive and reads dominant. tx's attempt is over
/// with w's frame, and its frame is dropped then, never sent.
#[test]
fn single_shot_that_loses_arbitration_is_dropped() {
    let mut n = net(0);
    let tx = n.tx;
    n.b.abort(tx, BusTime::ZERO).unwrap();
    n.b.take_events().for_each(drop);
    let w = n.b.attach(ControllerConfig::named("w"));
    n.b.report_arbitration(true);
    n.b.submit_with(tx, f(), BusTime::ZERO, true).unwrap();
    n.b.submit(w, Frame::base(0x011, &[0x80]).unwrap(), BusTime::ZERO)
        .unwrap();
    let ev = n.run_for(1000);
    let lost: Vec<(NodeId, u16)> = ev
        .iter()
        .filter_map(|e| match *e {
            Event::ArbitrationLost { node, bit, .. } => Some((node, bit)),
            _ => None,
        })
        .collect();
    assert_eq!(lost, [(tx, 9)]);
    let end = ev
        .iter()
        .find_map(|e| match *e {
            Event::Frame { node, end, .. } if node == w => Some(bits_at(end)),
            _ => None,
        })
        .expect("w's frame");
    assert_eq!(aborted(&ev), [(tx, end)]);
    assert_eq!(frames(&ev), [(w, 0)], "tx never sends");
}

/// Listen only: r0 drives nothing dominant. Alone with tx, it does not acknowledge: tx has an
/// ACK error (flag 48..53). Its active flag makes the ACK delimiter (48) dominant, which r0
/// detects as a form error; but r0 sends no flag and its counters stay where they were (REC 5,
/// written before), where an ordinary receiver would count REC + 1.
#[test]
fn listen_only_neither_acknowledges_nor_flags_nor_counts() {
    let mut n = net(1);
    let r0 = n.rx[0];
    n.b.set_counters(r0, 0, 5, BusTime::ZERO).unwrap();
    n.b.set_listen_only(r0, true, BusTime::ZERO).unwrap();
    n.b.take_events().for_each(drop);
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [(n.tx, 48, BusError::Ack), (r0, 49, BusError::Form)]
    );
    assert_eq!((n.tec(n.tx), n.rec(r0)), (8, 5));
    // Only tx's flag is on the bus (48..53); its delimiter 54..61 and intermission 62..64 put
    // its next attempt at 65, as if r0 were not there: ACK error again, flag at 65 + 48. r0's
    // own (passive, unsent) flag took six equal bits from 49: 49..53 are dominant, 54..59
    // recessive, so its delimiter runs 60..67 and tx's SOF at 65 is a form error to it, flagged
    // from 66, as for any error-passive receiver.
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [(r0, 66, BusError::Form), (n.tx, 65 + 48, BusError::Ack)]
    );
    assert_eq!((n.tec(n.tx), n.rec(r0)), (16, 5));
}

/// Listen only, receiving: with r1 acknowledging, F goes through and r0 takes it too (at the end
/// of EOF, 56), but REC stays 5 (counters stopped, and no ACK sent). An error only r0 reads (data
/// bit 21 read dominant: stuff error at 26, see the bit error cases) destroys nothing: its flag
/// would have been active at 27..32, but it sends none, so tx and r1 finish the frame.
#[test]
fn listen_only_receives_and_destroys_nothing() {
    let mut n = net(2);
    let (r0, r1) = (n.rx[0], n.rx[1]);
    n.b.set_counters(r0, 0, 5, BusTime::ZERO).unwrap();
    n.b.set_listen_only(r0, true, BusTime::ZERO).unwrap();
    let ev = n.step();
    assert_eq!(delivered(&ev), [(r0, 56), (r1, 56)]);
    assert_eq!(n.rec(r0), 5);

    n.b.submit(n.tx, f(), n.b.committed()).unwrap();
    let sof = bits_at(n.b.committed()) + F_BITS;
    n.disturb(sof + 21, 1, DOMINANT, Some(vec![r0]));
    let ev = n.run_for(200);
    assert_eq!(bus_errors(&ev), [(r0, sof + 27, BusError::Stuff)]);
    assert_eq!(frames(&ev), [(n.tx, sof)]);
    assert_eq!(delivered(&ev), [(r1, sof + 56)]);
    assert_eq!((n.rec(r0), n.b.stats().error_frames), (5, 0));
}

/// Rule 8: REC − 1 needs the ACK bit sent. r0 does not acknowledge, r1 does; both start at
/// REC 5; after one clean F r0 keeps 5 and r1 has 4.
#[test]
fn rule_8_counts_a_reception_only_with_the_ack_sent() {
    let mut n = net(2);
    let (r0, r1) = (n.rx[0], n.rx[1]);
    n.b.set_counters(r0, 0, 5, BusTime::ZERO).unwrap();
    n.b.set_counters(r1, 0, 5, BusTime::ZERO).unwrap();
    n.b.set_ack(r0, false).unwrap();
    let ev = n.step();
    assert_eq!(delivered(&ev), [(r0, 56), (r1, 56)]);
    assert_eq!((n.rec(r0), n.rec(r1)), (5, 4));
}

/// Abort while an attempt that fails is on the bus: tx alone, its ACK error flagged 48..53 and
/// the bus quiet from 54. The abort comes at bit 10; the attempt runs to its end, and the frame
/// is answered as aborted at 54 and never retried.
#[test]
fn abort_ends_a_failing_attempt_without_retry() {
    let mut n = net(0);
    let ev = n.step();
    assert_eq!(bus_errors(&ev), [(n.tx, 48, BusError::Ack)]);
    n.b.abort(n.tx, at(10)).unwrap();
    let ev: Vec<Event> = n.b.take_events().collect();
    assert_eq!(aborted(&ev), [(n.tx, 54)]);
    assert!(!n.b.step());
}

/// Abort while an attempt that succeeds is on the bus: the frame is done at 56 and nothing is
/// aborted.
#[test]
fn abort_lets_a_succeeding_attempt_finish() {
    let mut n = net(1);
    let ev = n.step();
    n.b.abort(n.tx, at(10)).unwrap();
    let later: Vec<Event> = n.b.take_events().collect();
    assert_eq!(done(&ev), [(n.tx, 56)]);
    assert_eq!(aborted(&later), []);
}

/// An error flagged during arbitration is an error frame. Only r0 reads the recessive stuff bit
/// 5 dominant: six dominant bits 0..5, a stuff error, its active flag 6..11. tx sends ID4 (bit
/// 8) recessive and reads r0's flag: in the arbitration field that is lost arbitration, not an
/// error, so tx becomes a receiver and with r1 reads the dominant bits 6..11 as a stuff error
/// at 11: flags 12..17. The bus is dominant 6..17 without a break: one error frame, though no
/// transmitter lost a frame to an error (no `ErrorFrame` event), and F is sent again.
#[test]
fn an_error_flagged_during_arbitration_is_an_error_frame() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.disturb(5, 1, DOMINANT, Some(vec![r0]));
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (r0, 6, BusError::Stuff),
            (tx, 12, BusError::Stuff),
            (r1, 12, BusError::Stuff)
        ]
    );
    assert_eq!(destroyed(&ev), []);
    assert_eq!(n.b.stats().error_frames, 1);
    let ev = n.run_for(200);
    assert_eq!(frames(&ev).len(), 1, "F is sent again");
}

/// The counters an error line carries are those after counting, exception 3a included. tx is
/// made error passive alone (TEC 128, 17th attempt at 1048). Its ACK error at 1048 + 47 starts a
/// passive flag at 48; one dominant bit that tx alone reads at 50 restarts the flag's run of six
/// equal bits (51..56), and having seen a dominant bit, exception 3a does not apply: TEC 136,
/// which the bus error stamped at 48 carries.
#[test]
fn a_bus_error_carries_the_counters_after_exception_3a_is_decided() {
    let mut n = net(0);
    lone_passive(&mut n);
    let s = LONE_17TH_SOF;
    n.disturb(s + 50, 1, DOMINANT, Some(vec![n.tx]));
    let ev = n.step();
    let carried: Vec<(u64, u16)> = ev
        .iter()
        .filter_map(|e| match *e {
            Event::BusError { at, tec, .. } => Some((bits_at(at), tec)),
            _ => None,
        })
        .collect();
    assert_eq!(carried, [(s + 48, 136)]);
    assert_eq!(n.tec(n.tx), 136);
}

/// A frame its receivers took is on the bus although its transmitter flags an error: tx error
/// passive, r0 not acknowledging (the 17th attempt of `passive_error_flag_is_not_seen_by_others`,
/// at 1064): tx's ACK error gives a passive flag that nobody sees, r0 takes F at the end of EOF
/// (1064 + 56), and the bus shows F there, as a listen-only analyser would.
#[test]
fn a_frame_taken_by_its_receivers_is_on_the_bus() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.b.set_ack(r0, false).unwrap();
    for _ in 0..16 {
        n.step();
    }
    let ev = n.step();
    assert_eq!(delivered(&ev), [(r0, 1064 + 56)]);
    assert_eq!(frames(&ev), [(tx, 1064)]);
    assert_eq!(done(&ev), []);
}

fn woken(ev: &[Event]) -> Vec<(NodeId, u64)> {
    ev.iter()
        .filter_map(|e| match *e {
            Event::Woken { node, at } => Some((node, bits_at(at))),
            _ => None,
        })
        .collect()
}

/// Sleep: the only receiver is asleep, so nobody acknowledges F: tx's ACK error is flagged at
/// 48..53. F's start of frame (bit 0) wakes the sleeper at the end of that bit (1); it does not
/// receive F, and counts 11 recessive bits from the end of the last dominant bit, tx's flag
/// (54): error delimiter 54..61 and intermission 62..64 make 11, so it takes part in tx's retry
/// at 65, acknowledges it and receives it at its end (65 + 56 = 121); tx's TEC goes 8 then 7.
#[test]
fn bus_activity_wakes_a_sleeping_controller_which_misses_that_frame() {
    let mut n = net(1);
    let r = n.rx[0];
    n.b.set_asleep(r, true, BusTime::ZERO).unwrap();
    assert!(n.b.controller(r).unwrap().is_asleep());
    let ev = n.step();
    assert_eq!(bus_errors(&ev), [(n.tx, 48, BusError::Ack)]);
    assert_eq!(woken(&ev), [(r, 1)]);
    assert_eq!(delivered(&ev), []);
    assert!(!n.b.controller(r).unwrap().is_asleep());
    let ev = n.step();
    assert_eq!(frames(&ev), [(n.tx, 65)]);
    assert_eq!(delivered(&ev), [(r, 121)]);
    assert_eq!((n.tec(n.tx), n.rec(r)), (7, 0));
}

/// A sleeping controller sends nothing, even with a frame queued; woken by its host at bit 100,
/// it integrates first (11 recessive bits on an idle bus) and starts its frame at 111.
#[test]
fn a_sleeping_controller_sends_after_its_host_wakes_it() {
    let mut b = Bus::new(BusConfig::default()).unwrap();
    let s = b.attach(ControllerConfig::named("s"));
    let _other = b.attach(ControllerConfig::named("o"));
    b.set_asleep(s, true, BusTime::ZERO).unwrap();
    b.submit(s, f(), BusTime::ZERO).unwrap();
    assert!(!b.step(), "asleep, it does not send");
    b.set_asleep(s, false, at(100)).unwrap();
    assert!(b.step());
    let ev: Vec<Event> = b.take_events().collect();
    assert_eq!(frames(&ev), [(s, 111)]);
    assert_eq!(woken(&ev), [], "a host wake is no bus wake");
}
