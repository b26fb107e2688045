//! Bus integration (ISO 11898-1): a controller that joins the bus (plugged back in, reset, out of
//! listen-only mode) takes part only after 11 consecutive recessive bits, and does not receive
//! the frame in progress when it joins. The sweeps plug a node in at every bit time of a data
//! frame and of an error frame and check that transmissions never overlap, that events come in
//! time order, and that errors come only where the standard gives them.
//!
//! The bench and the frame `F` (012#80) are those of `conformance.rs`: stuffed part 0..45 (its
//! last two bits, CRC 1..0, dominant), CRC delimiter 46, ACK slot 47, ACK delimiter 48, EOF
//! 49..55, intermission 56..58. The joining node `j` has `G` = 7FF#01 waiting.

mod net;
use net::*;

fn g() -> Frame {
    Frame::base(0x7FF, &[0x01]).unwrap()
}

/// A bench with `receivers` receivers and the joining node `j`, unplugged, with `G` queued.
fn bench(receivers: usize) -> (Net, NodeId) {
    let mut n = net(receivers);
    let j = n.b.attach(ControllerConfig::named("j"));
    n.b.set_connected(j, false, BusTime::ZERO).unwrap();
    n.b.submit(j, g(), BusTime::ZERO).unwrap();
    (n, j)
}

/// Events in time order, and frames and error frames that never overlap: each attempt starts
/// after the one before has ended.
fn check_order(ev: &[Event], k: u64) {
    for pair in ev.windows(2) {
        assert!(pair[0].at() <= pair[1].at(), "k = {k}: {pair:?}");
    }
    let mut attempts: Vec<(u64, u64)> = ev
        .iter()
        .filter_map(|e| match *e {
            Event::Frame { start, end, .. } => Some((bits_at(start), bits_at(end))),
            Event::ErrorFrame { start, end, .. } => Some((bits_at(start), bits_at(end))),
            _ => None,
        })
        .collect();
    attempts.sort();
    attempts.dedup();
    for pair in attempts.windows(2) {
        assert!(pair[1].0 >= pair[0].1, "k = {k}: overlapping {attempts:?}");
    }
}

fn starts_of(ev: &[Event], node: NodeId) -> Vec<u64> {
    ev.iter()
        .filter_map(|e| match *e {
            Event::Frame { start, node: n, .. } if n == node => Some(bits_at(start)),
            _ => None,
        })
        .collect()
}

/// A data frame: F goes out at 0, acknowledged by r0; `j` is plugged in at bit k. F's last
/// dominant bit is the ACK slot (47), so `j` counts its 11 recessive bits from max(k, 48): G
/// starts at max(k, 48) + 11, which for k up to 48 is 59, the first bit after F's intermission.
/// `j` never receives F, and nothing on the bus is an error.
#[test]
fn a_node_plugged_in_during_a_data_frame_waits_for_11_recessive_bits() {
    for k in 0..=F_BITS + 6 {
        let (mut n, j) = bench(1);
        let mut ev = Vec::new();
        if k == 0 {
            n.b.set_connected(j, true, at(0)).unwrap();
        } else {
            ev.extend(n.step());
            n.b.set_connected(j, true, at(k)).unwrap();
        }
        ev.extend(n.run_for(400));
        check_order(&ev, k);
        assert_eq!(bus_errors(&ev), [], "k = {k}");
        assert_eq!(starts_of(&ev, n.tx), [0], "k = {k}");
        assert_eq!(starts_of(&ev, j), [k.max(48) + 11], "k = {k}");
        let to_j: Vec<u64> = delivered(&ev)
            .into_iter()
            .filter(|(node, _)| *node == j)
            .map(|(_, t)| t)
            .collect();
        assert_eq!(
            to_j,
            [],
            "k = {k}: F is not received by a node that joined during it"
        );
    }
}

/// An error frame: nobody acknowledges F (r0 does not). Each attempt is an ACK error: tx's flag
/// 48..53, r0's (a form error in the ACK delimiter) 49..54, so the last dominant bit is 54; tx's
/// delimiter 55..62, intermission 63..65, the next attempt at 66 (`conformance.rs`,
/// `passive_error_flag_is_not_seen_by_others`). Plugged in at bit k ≤ 55, `j` has its 11 bits at
/// max(k, 55) + 11 = 66 and takes part in the second attempt: it acknowledges it, and F goes out
/// at 66. Plugged in later, the second attempt (last dominant bit 66 + 54) breaks its count, and
/// the third, at 132, is the one it acknowledges. G follows F. The only errors are tx's ACK
/// errors and r0's form errors, one pair per failed attempt; `j` detects none.
#[test]
fn a_node_plugged_in_during_an_error_frame_waits_for_11_recessive_bits() {
    for k in 1..66 {
        let (mut n, j) = bench(1);
        n.b.set_ack(n.rx[0], false).unwrap();
        let mut ev = n.step();
        n.b.set_connected(j, true, at(k)).unwrap();
        ev.extend(n.run_for(600));
        check_order(&ev, k);
        let failed: u64 = if k <= 55 { 1 } else { 2 };
        let expected: Vec<(NodeId, u64, BusError)> = (0..failed)
            .flat_map(|a| {
                [
                    (n.tx, a * 66 + 48, BusError::Ack),
                    (n.rx[0], a * 66 + 49, BusError::Form),
                ]
            })
            .collect();
        assert_eq!(bus_errors(&ev), expected, "k = {k}");
        assert_eq!(starts_of(&ev, n.tx), [failed * 66], "k = {k}");
        let g_start = starts_of(&ev, j);
        assert_eq!(g_start.len(), 1, "k = {k}");
        assert!(g_start[0] >= failed * 66 + F_BITS, "k = {k}: {g_start:?}");
    }
}

/// Joining while a lone error-passive transmitter retries: its passive flag is recessive, so the
/// joining node may complete its 11 bits inside the transmitter's error delimiter and start a
/// frame there, which the transmitter reads as a form error (a dominant delimiter bit).
///
/// tx is error passive alone (TEC 128; its 17th attempt at s = 1048). That attempt's last
/// dominant bit is the CRC's last (s + 45), nobody acknowledging; tx's passive flag s + 48..53,
/// delimiter s + 54..61. `j`, plugged in at s + 10, has its 11 recessive bits at s + 46 + 11 =
/// s + 57 and starts G there, the fourth bit of tx's delimiter: tx flags a form error from
/// s + 58 (as a receiver of G: REC + 1), passive again, so G is not destroyed; nobody
/// acknowledges G, so `j` has an ACK error.
#[test]
fn a_node_joining_beside_a_passive_transmitter_may_start_in_its_error_delimiter() {
    let (mut n, j) = bench(0);
    lone_passive(&mut n);
    let s = LONE_17TH_SOF;
    let mut ev = n.step();
    n.b.set_connected(j, true, at(s + 10)).unwrap();
    ev.extend(n.run_for(60));
    check_order(&ev, 10);
    let errors = bus_errors(&ev);
    assert_eq!(errors[0], (n.tx, s + 48, BusError::Ack));
    assert_eq!(errors[1], (n.tx, s + 58, BusError::Form));
    assert_eq!(errors[2].0, j);
    assert_eq!(errors[2].2, BusError::Ack);
    let g_attempt = ev
        .iter()
        .find_map(|e| match *e {
            Event::ErrorFrame { start, node, .. } if node == j => Some(bits_at(start)),
            _ => None,
        })
        .expect("G's attempt");
    assert_eq!(g_attempt, s + 57);
    assert_eq!((n.tec(n.tx), n.rec(n.tx)), (128, 1));
}

/// A reset (power cycle) and leaving listen-only mode are joins too. tx sends F four times, at 0,
/// 59, 118 and 177. r0 is reset at bit 10 of the first (which it took when the engine committed
/// it, at its start; the reset empties its FIFO): counting from the ACK slot's end (48) it has
/// its 11 bits at 59 and takes the second F. It enters listen-only mode at 70 and leaves it at
/// 109, after the second F's ACK slot (59 + 47): its 11 bits end at 120, so it misses the third
/// F (118) and takes the fourth.
#[test]
fn a_reset_and_leaving_listen_only_are_joins() {
    let (mut n, _) = bench(2);
    let r0 = n.rx[0];
    for _ in 0..3 {
        n.b.submit(n.tx, f(), at(0)).unwrap();
    }
    // Each batch is in time order; a reset at 10 comes after the first F was committed whole.
    let mut ev = n.step();
    n.b.reset_node(r0, at(10)).unwrap();
    let second = n.step();
    check_order(&second, 10);
    ev.extend(second);
    n.b.set_listen_only(r0, true, at(70)).unwrap();
    n.b.set_listen_only(r0, false, at(109)).unwrap();
    let rest = n.run_for(400);
    check_order(&rest, 109);
    ev.extend(rest);
    assert_eq!(starts_of(&ev, n.tx), [0, F_BITS, 2 * F_BITS, 3 * F_BITS]);
    let to_r0: Vec<u64> = delivered(&ev)
        .into_iter()
        .filter(|(node, _)| *node == r0)
        .map(|(_, t)| t)
        .collect();
    assert_eq!(to_r0, [56, F_BITS + 56, 3 * F_BITS + 56]);
    assert_eq!(n.b.controller(r0).unwrap().rx_len(), 2);
}
