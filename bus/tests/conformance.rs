//! Conformance of the bus engine with the Bosch CAN 2.0 specification (part B, sections 6 to 9:
//! error detection, error and overload frames, fault confinement, suspend transmission), laid
//! out by clause in the manner of ISO 16845-1. `docs/CAN.md` states the rules in the project's
//! words; its section 11 lists these cases.
//!
//! Every expected bit time, counter and state below is worked out from the rules, in the
//! comments next to it, never read back from the engine. Bit times count from the start of
//! frame (bit 0 = SOF) at 250 kbit/s, 4 µs a bit. "Flags a..b" means the error or overload
//! flag occupies bits a to b inclusive; "next SOF n" is the first bit of bus idle, where a
//! waiting transmitter starts.
//!
//! Most cases use one frame, `F` = base identifier 0x012, one data byte 0x80, whose stuffed
//! bitstream is written out by hand in [`F_STUFFED`] (and checked against the encoder):
//!
//! ```text
//! bit   0      SOF                     0
//! bits  1..4   ID10..ID7 = 0000        0000   five dominant bits with SOF:
//! bit   5      stuff bit               1      (recessive, in the arbitration field)
//! bits  6..12  ID6..ID0 = 0010010      0010010
//! bit   13     RTR                     0
//! bit   14     IDE                     0
//! bit   15     r0                      0
//! bit   16     DLC3                    0      bits 12..16 are five dominant bits:
//! bit   17     stuff bit               1
//! bits 18..20  DLC2..DLC0              001    (DLC = 1)
//! bits 21..26  data 7..2 = 100000      100000 bits 22..26 five dominant bits:
//! bit   27     stuff bit               1
//! bits 28..29  data 1..0               00
//! bits 30..42  CRC 14..2               1000101011111   (CRC-15 = 0x457C)
//! bit   43     stuff bit               0      after the five recessive bits 38..42
//! bits 44..45  CRC 1..0                00
//! ```
//!
//! So S = 46 (the stuffed part is bits 0..45), and the tail is: CRC delimiter 46, ACK slot
//! 47, ACK delimiter 48, EOF 49..55 (EOF n is bit S + 2 + n), intermission 56..58. A clean
//! frame lasts S + 13 = 59 bits, intermission included.
//!
//! Engine conventions the tests rely on (documented in `bus/src/engine/episode.rs` and
//! `wire.rs`): counters move at the first bit of the error flag (exception 3a is decided when the
//! passive flag is complete); a node whose TEC reaches 256 is bus off at once and sends no flag;
//! a flag is active or passive by the state before the error is counted; rule 8 above 127 sets
//! REC to 119; receivers get a frame at the end of EOF (the `Delivered` time). Disturbances
//! change only what the named controllers sample, never what the others see on the wire.

mod net;
use net::*;

// ---------------------------------------------------------------------------------------------
// The test frame.
// ---------------------------------------------------------------------------------------------

/// The hand layout of `F` used by every case agrees with the encoder.
#[test]
fn test_frame_layout() {
    let e = bits::encode(&f());
    assert_eq!(e.stuffed.to_string(), F_STUFFED);
    assert_eq!(e.stuffed.len() as u64, S);
    assert_eq!(e.stuff_bits, 4, "stuff bits at 5, 17, 27 and 43");
    assert_eq!(u64::from(bits::frame_bits(&f())), F_BITS);
}

// ---------------------------------------------------------------------------------------------
// Error detection, bit error (Bosch 2.0B §7.1; ISO 16845-1 bit error per field).
//
// All nodes error active. The transmitter detects a bit error at stuffed bit k and flags
// k + 1..k + 6. Let r be the number of consecutive dominant bits the receivers read ending at
// bit k. They detect a stuff error at their 6th dominant bit, k + 6 − r, and flag
// k + 7 − r..k + 12 − r. The delimiter takes the 8 bits after the last dominant bit
// (k + 13 − r..k + 20 − r), intermission 3 more, so the retransmission starts at k + 24 − r.
// Counters: TEC + 8 (rule 3), REC + 1 (rule 1); then the retransmission succeeds: TEC 7,
// REC 0 (rules 7 and 8).
// ---------------------------------------------------------------------------------------------

/// Runs a wire bit inversion at bit `k` that every node sees, with two receivers, and checks
/// the standard outcome for `r` with the transmitter's error located at `loc`.
fn bit_error_case(k: u64, r: u64, loc: Location) {
    let mut n = net(2);
    n.disturb(k, 1, INVERT, None);
    let ev = n.step();
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    let rx_flag = k + 7 - r;
    let mut want = vec![
        (tx, k + 1, BusError::Bit),
        (r0, rx_flag, BusError::Stuff),
        (r1, rx_flag, BusError::Stuff),
    ];
    want.sort_by_key(|&(n, t, _)| (t, n));
    assert_eq!(bus_errors(&ev), want, "k = {k}");
    assert!(locations(&ev).contains(&(tx, loc)), "{:?}", locations(&ev));
    // The bus is dominant from k + 1 to k + 12 − r: the last flag ends at k + 13 − r.
    assert_eq!(error_frame(&ev), (k, k + 1, k + 13 - r, BusError::Bit));
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 1, 1));
    let ev = n.run_for(1000);
    assert_eq!(frames(&ev), [(tx, k + 24 - r)], "retransmission at k + 24 - r");
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (7, 0, 0));
}

/// Bit error in SOF (k = 0). The receivers read a recessive bit 0 and take the transmitter's
/// first flag bit (1) as their SOF; bits 1..6 are six dominant bits, a stuff error at 6
/// (= k + 6, r = 0). Flags 7..12; next SOF 24.
#[test]
fn bit_error_in_sof() {
    bit_error_case(0, 0, Location::Sof);
}

/// Bit error in the arbitration field: a dominant bit (ID10 at bit 1) read recessive is a bit
/// error there too. r = 0: receivers flag 8..13; next SOF 25.
#[test]
fn bit_error_in_arbitration_field_dominant_read_recessive() {
    bit_error_case(1, 0, Location::Id28To21);
}

/// Bit error in the control field: DLC3 (bit 16, dominant) read recessive. r = 0: the
/// receivers' six dominant bits are the flag bits 17..22, stuff error at 22, flags 23..28; next
/// SOF 40.
#[test]
fn bit_error_in_control_field() {
    bit_error_case(16, 0, Location::Dlc);
}

/// Bit error in the data field: data bit 7 (bit 21, recessive) read dominant. Bit 20 is
/// recessive, so r = 1: the receivers' dominant run is 21..26, stuff error at 26, flags 27..32
/// (11 dominant bits in all); next SOF 21 + 23 = 44.
#[test]
fn bit_error_in_data_field() {
    bit_error_case(21, 1, Location::Data);
}

/// Bit error on a stuff bit: the recessive stuff bit 27 after the five dominant bits 22..26,
/// read dominant. The transmitter sees a bit error (outside arbitration); the receivers see a
/// sixth dominant bit, a stuff error at the same bit (r = 6). Both flag 28..33, 6 dominant bits
/// in all; next SOF 27 + 18 = 45.
#[test]
fn bit_error_on_a_stuff_bit_in_data_field() {
    let mut n = net(2);
    n.disturb(27, 1, INVERT, None);
    let ev = n.step();
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, 28, BusError::Bit),
            (r0, 28, BusError::Stuff),
            (r1, 28, BusError::Stuff)
        ]
    );
    assert_eq!(error_frame(&ev), (27, 28, 34, BusError::Bit));
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 1, 1));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 45)]);
}

/// Bit error in the CRC sequence: CRC bit 14 (bit 30, recessive) read dominant. Bits 28 and 29
/// are dominant, so r = 3: the receivers' dominant run is 28..33, stuff error at 33, flags
/// 34..39 (9 dominant bits); next SOF 30 + 21 = 51.
#[test]
fn bit_error_in_crc_sequence() {
    bit_error_case(30, 3, Location::CrcSeq);
}

/// A disturbance at tail bit `p` that every node sees (the transmitter's bit error, the
/// receivers' form error), with flags p + 1..p + 6 superposed exactly; next SOF p + 18.
fn tail_error_case(p: u64, tx_loc: Location) {
    let mut n = net(2);
    n.disturb(p, 1, DOMINANT, None);
    let ev = n.step();
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, p + 1, BusError::Bit),
            (r0, p + 1, BusError::Form),
            (r1, p + 1, BusError::Form)
        ],
        "p = {p}"
    );
    assert!(locations(&ev).contains(&(tx, tx_loc)), "{:?}", locations(&ev));
    assert_eq!(error_frame(&ev), (p, p + 1, p + 7, BusError::Bit));
    assert!(
        delivered(&ev).is_empty(),
        "an error up to EOF 6 loses the frame for the receivers"
    );
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 1, 1));
    // Flags p + 1..p + 6, delimiter p + 7..p + 14, intermission p + 15..p + 17.
    assert_eq!(frames(&n.run_for(1000)), [(tx, p + 18)], "p = {p}");
}

/// Bit error in the CRC delimiter (bit S = 46), dominant on the wire: a bit error for the
/// transmitter, a form error for the receivers, all flag 47..52; next SOF S + 18 = 64.
#[test]
fn bit_error_in_crc_delimiter() {
    tail_error_case(S, Location::CrcDel);
}

/// Bit error in the ACK delimiter (bit S + 2 = 48): flags 49..54; next SOF S + 20 = 66.
#[test]
fn bit_error_in_ack_delimiter() {
    tail_error_case(S + 2, Location::AckDel);
}

/// Bit error in EOF bits 1 to 6 (bit S + 2 + n): flags from S + 3 + n; next SOF S + 20 + n.
#[test]
fn bit_error_in_eof_bits_1_to_6() {
    for eof in 1..=6 {
        tail_error_case(S + 2 + eof, Location::Eof);
    }
}

/// Bit error in the last EOF bit (S + 9 = 55), dominant on the wire. The frame is valid for the
/// receivers after EOF 6 (S + 8), so to them the dominant EOF 7 is an overload condition, not an
/// error: overload flags 56..61. The transmitter needs the frame clean to the end of EOF: bit
/// error, active flag 56..61, TEC 8, and it sends the frame again. Flags and overload flags
/// coincide; delimiters 62..69, intermission 70..72; retransmission at S + 27 = 73. The
/// receivers get the frame twice (at the end of EOF: S + 10 = 56 and 73 + 56 = 129).
#[test]
fn bit_error_in_last_eof_bit_gives_retransmission_and_receiver_overload() {
    let mut n = net(2);
    n.disturb(S + 9, 1, DOMINANT, None);
    let ev = n.step();
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    assert_eq!(bus_errors(&ev), [(tx, 56, BusError::Bit)]);
    assert_eq!(overloads(&ev), [(r0, 56), (r1, 56)]);
    assert_eq!(delivered(&ev), [(r0, 56), (r1, 56)]);
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 0, 0));
    let ev = n.run_for(1000);
    assert_eq!(frames(&ev), [(tx, 73)]);
    assert_eq!(
        delivered(&ev),
        [(r0, 73 + 56), (r1, 73 + 56)],
        "received a second time"
    );
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (7, 0, 0));
}

/// Bit error in the ACK slot for a receiver: r0 sends its dominant ACK (bit 47) and reads it
/// recessive: bit error, flag 48..53. The transmitter reads the ACK dominant (r1 acknowledges),
/// then a dominant ACK delimiter at 48: bit error, flag 49..54; r1: form error in the ACK
/// delimiter, flag 49..54. r0 reads 54 dominant right after its own flag: rule 2, REC 1 + 8 = 9.
/// Delimiter 55..62, intermission 63..65, next SOF S + 20 = 66.
#[test]
fn bit_error_in_ack_slot_for_a_receiver() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.disturb(S + 1, 1, RECESSIVE, Some(vec![r0]));
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (r0, 48, BusError::Bit),
            (tx, 49, BusError::Bit),
            (r1, 49, BusError::Form)
        ]
    );
    assert!(locations(&ev).contains(&(r0, Location::Ack)));
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 9, 1));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 66)]);
}

/// Exception: the transmitter sends a recessive ACK slot and reads it dominant; that is the
/// acknowledgement, not a bit error. Here nobody else acknowledges (the receiver's ACK is off),
/// only the transmitter reads the ACK slot (47) dominant: the frame is sent, TEC stays 0, and the
/// receiver (which checks no ACK) has it at the end of EOF, S + 10 = 56.
#[test]
fn transmitter_reading_dominant_ack_slot_is_no_error() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.b.set_ack(r0, false).unwrap();
    n.disturb(S + 1, 1, DOMINANT, Some(vec![tx]));
    let ev = n.step();
    assert_eq!(bus_errors(&ev), []);
    assert_eq!(frames(&ev), [(tx, 0)]);
    assert_eq!(delivered(&ev), [(r0, 56)]);
    assert_eq!((n.tec(tx), n.rec(r0)), (0, 0));
}

/// Exception: a recessive bit of the arbitration field read dominant is lost arbitration, not a
/// bit error. ID4 (bit 8, recessive) is read dominant by everyone: the transmitter becomes a
/// receiver and nobody drives the bus any more. Everyone reads dominant 6..8 and then recessive
/// from 9: five recessive bits 9..13, a stuff bit due at 14 reads recessive: stuff error at 14
/// for all three, the former transmitter included. Flags 15..20, delimiter 21..28,
/// intermission 29..31; the frame, still queued, goes again at 32. REC + 1 for all three
/// (rule 1; the former transmitter was a receiver), TEC 0.
#[test]
fn recessive_arbitration_bit_read_dominant_is_lost_arbitration() {
    let mut n = net(2);
    n.disturb(8, 1, INVERT, None);
    let ev = n.step();
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, 15, BusError::Stuff),
            (r0, 15, BusError::Stuff),
            (r1, 15, BusError::Stuff)
        ]
    );
    assert!(
        ev.iter().all(|e| !matches!(
            e,
            Event::BusError {
                transmitting: true,
                ..
            }
        )),
        "no error as a transmitter"
    );
    assert_eq!((n.tec(tx), n.rec(tx), n.rec(r0), n.rec(r1)), (0, 1, 1, 1));
    assert_eq!(n.b.controller(tx).unwrap().counters().arbitration_lost, 1);
    let ev = n.run_for(1000);
    assert_eq!(frames(&ev), [(tx, 32)]);
    // The retransmission: the transmitter has REC 1 and TEC 0 (rule 7 keeps TEC at 0).
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (0, 0, 0));
}

// ---------------------------------------------------------------------------------------------
// Error detection, stuff, CRC, form and ACK errors (Bosch 2.0B §7.1).
// ---------------------------------------------------------------------------------------------

/// Stuff error: the receivers alone read the recessive stuff bit 17 dominant, a sixth dominant
/// bit after 12..16: stuff error, flags 18..23. The transmitter reads its own bits, 0 at 18 and
/// 19 (DLC2, DLC1), then sends 1 at 20 and reads dominant: bit error, flag 21..26. The receivers
/// read 24 dominant right after their flags: rule 2, REC 1 + 8 = 9. TEC 8. Dominant 18..26,
/// delimiter 27..34, intermission 35..37, next SOF 38.
#[test]
fn stuff_error() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.b.injector_mut().add(Rule {
        target: Target::Node(tx),
        schedule: Schedule::Once,
        bit: BitPosition::At(17),
        effect: Effect::Stuff,
        seen_by: SeenBy::All,
    });
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (r0, 18, BusError::Stuff),
            (r1, 18, BusError::Stuff),
            (tx, 21, BusError::Bit)
        ]
    );
    assert!(locations(&ev).contains(&(r0, Location::Dlc)));
    assert_eq!(error_frame(&ev), (20, 21, 27, BusError::Bit));
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 9, 9));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 38)]);
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (7, 8, 8));
}

/// CRC error, flagged after the ACK delimiter: one receiver (r0) alone reads data bit 1 (bit 28)
/// flipped, so its CRC does not match. It does not acknowledge; r1 does, so the ACK delimiter
/// (48) is recessive, and r0's flag starts at the next bit, EOF 1 = S + 3 = 49: flag 49..54.
/// The transmitter (bit error) and r1 (form error in EOF) read 49 dominant and flag 50..55. r0
/// reads 55 dominant right after its flag: rule 2, REC 1 + 8 = 9 (the brief's example). r1
/// REC 1, TEC 8. Delimiter 56..63, intermission 64..66, next SOF S + 21 = 67.
#[test]
fn crc_error_flag_starts_after_ack_delimiter() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.b.injector_mut().add(Rule {
        target: Target::Node(tx),
        schedule: Schedule::Once,
        bit: BitPosition::At(28),
        effect: Effect::Crc,
        seen_by: SeenBy::Nodes(vec![r0]),
    });
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (r0, 49, BusError::Crc),
            (tx, 50, BusError::Bit),
            (r1, 50, BusError::Form)
        ]
    );
    assert!(locations(&ev).contains(&(r1, Location::Eof)));
    assert_eq!(error_frame(&ev), (49, 50, 56, BusError::Bit));
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 9, 1));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 67)]);
}

/// CRC error at every receiver: nobody acknowledges, so the transmitter finds an ACK error in
/// the ACK slot (47) and flags 48..53. Its flag makes the ACK delimiter (48) dominant: a form
/// error for the receivers, which flag 49..54 before their CRC flag was due. TEC 8, REC 1 each
/// (the first bit after their flags, 55, is recessive). Delimiter 55..62, next SOF 66.
#[test]
fn crc_error_at_every_receiver_is_overtaken_by_ack_error() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.b.injector_mut().add(Rule {
        target: Target::Node(tx),
        schedule: Schedule::Once,
        bit: BitPosition::At(28),
        effect: Effect::Crc,
        seen_by: SeenBy::All,
    });
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, 48, BusError::Ack),
            (r0, 49, BusError::Form),
            (r1, 49, BusError::Form)
        ]
    );
    assert!(locations(&ev).contains(&(r0, Location::AckDel)));
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 1, 1));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 66)]);
}

/// A form error that the receivers alone see at tail bit `p`. They flag p + 1..p + 6; the
/// transmitter reads the first of those bits where it sends recessive and is not in the ACK slot
/// (`tx_sees`) as a bit error and flags tx_sees + 1..tx_sees + 6; the receivers then read a
/// dominant bit right after their flags (rule 2): REC 9. Next SOF tx_sees + 18.
fn form_error_case(p: u64, tx_sees: u64) {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.b.injector_mut().add(Rule {
        target: Target::Node(tx),
        schedule: Schedule::Once,
        bit: BitPosition::At(p as u16),
        effect: Effect::Form,
        seen_by: SeenBy::All,
    });
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (r0, p + 1, BusError::Form),
            (r1, p + 1, BusError::Form),
            (tx, tx_sees + 1, BusError::Bit)
        ],
        "p = {p}"
    );
    assert!(delivered(&ev).is_empty());
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 9, 9), "p = {p}");
    assert_eq!(frames(&n.run_for(1000)), [(tx, tx_sees + 18)], "p = {p}");
}

/// Form error in the CRC delimiter (S = 46): receivers flag 47..52. The transmitter reads 47
/// dominant in the ACK slot, which is an acknowledgement, and 48 (ACK delimiter) dominant: bit
/// error, flag 49..54. Next SOF 48 + 18 = 66.
#[test]
fn form_error_in_crc_delimiter() {
    form_error_case(S, S + 2);
}

/// Form error in the ACK delimiter (S + 2 = 48): receivers flag 49..54; the transmitter reads
/// EOF 1 (49) dominant: bit error, flag 50..55. Next SOF 67.
#[test]
fn form_error_in_ack_delimiter() {
    form_error_case(S + 2, S + 3);
}

/// Form error in EOF bits 1 to 6 (S + 2 + n): receivers flag from S + 3 + n, the transmitter
/// reads that bit (EOF n + 1, at most EOF 7) dominant: bit error. Next SOF S + 21 + n.
#[test]
fn form_error_in_eof_bits_1_to_6() {
    for eof in 1..=6 {
        form_error_case(S + 2 + eof, S + 3 + eof);
    }
}

/// A receiver that reads the last EOF bit (S + 9 = 55) dominant has already taken the frame
/// (at EOF 6): no form error, an overload frame. r0 alone reads it so: overload flag 56..61.
/// The transmitter has sent the frame (TxDone at the end of EOF, 56), reads r0's first flag bit
/// in its first intermission bit (56) and sends an overload flag 57..62; r1 likewise. r0 reads
/// 62 dominant after its flag, then 63 recessive: delimiters 63..70, intermission 71..73; the
/// transmitter's next frame starts at S + 28 = 74. No counter moves.
#[test]
fn dominant_last_eof_bit_is_overload_for_a_receiver() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.b.submit(tx, f(), BusTime::ZERO).unwrap();
    n.disturb(S + 9, 1, DOMINANT, Some(vec![r0]));
    let ev = n.step();
    assert_eq!(bus_errors(&ev), []);
    assert_eq!(frames(&ev), [(tx, 0)]);
    assert_eq!(delivered(&ev), [(r0, 56), (r1, 56)]);
    assert_eq!(overloads(&ev), [(r0, 56), (tx, 57), (r1, 57)]);
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (0, 0, 0));
    let ev = n.run_for(1000);
    assert_eq!(frames(&ev), [(tx, 74)]);
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (0, 0, 0));
}

/// ACK error: a lone transmitter reads the ACK slot (S + 1 = 47) recessive and flags from the
/// ACK delimiter, 48..53 (TEC 8). Delimiter 54..61, intermission 62..64, next attempt at
/// S + 19 = 65.
#[test]
fn ack_error() {
    let mut n = net(0);
    let ev = n.step();
    assert_eq!(bus_errors(&ev), [(n.tx, 48, BusError::Ack)]);
    assert!(locations(&ev).contains(&(n.tx, Location::Ack)));
    assert_eq!(error_frame(&ev), (47, 48, 54, BusError::Ack));
    assert_eq!(n.tec(n.tx), 8);
    let ev = n.step();
    assert_eq!(destroyed(&ev), [65]);
}

// ---------------------------------------------------------------------------------------------
// Error frames (Bosch 2.0B §3.1.3 and §6): flags, superposition, delimiter, intermission.
// ---------------------------------------------------------------------------------------------

/// A single active error flag is 6 dominant bits, the error delimiter 8 recessive bits and
/// intermission 3: a lone transmitter's ACK error at S + 1 gives flag 48..53 (the error frame's
/// last flag ends at 54), delimiter 54..61, intermission 62..64, and the next attempt at 65;
/// every attempt while it is error active lasts S + 19 = 65 bits.
#[test]
fn active_error_flag_delimiter_and_intermission() {
    let mut n = net(0);
    for attempt in 0..5u64 {
        let ev = n.step();
        assert_eq!(destroyed(&ev), [attempt * 65]);
        assert_eq!(error_frame(&ev), (47, 48, 54, BusError::Ack));
    }
}

/// Superposition of error flags as it really falls: with the transmitter's flag at k + 1 and
/// the receivers' at k + 7 − r, the bus is dominant for 12 − r bits (6 to 12), and the next
/// SOF is at k + 24 − r. Cases from the data, control and CRC fields of F (see the bit error
/// cases for the arithmetic of each r).
#[test]
fn superposition_of_error_flags_lasts_6_to_12_bits() {
    // (k, r): DLC3 r = 0, data bit 7 r = 1, CRC bit 14 r = 3, stuff bit 27 r = 6.
    for (k, r) in [(16u64, 0u64), (21, 1), (30, 3), (27, 6)] {
        let mut n = net(2);
        n.disturb(k, 1, INVERT, None);
        let ev = n.step();
        let (_, flag, end, _) = error_frame(&ev);
        assert_eq!(flag, k + 1);
        assert_eq!(end - flag, 12 - r, "dominant bits for r = {r}");
        assert_eq!(frames(&n.run_for(1000)), [(n.tx, k + 24 - r)], "r = {r}");
    }
}

/// A passive error flag is not seen by the other nodes. tx sends with one receiver, r0, that
/// does not acknowledge. While tx is error active, each ACK error (at 47) gives an active flag
/// 48..53, which r0 reads as a form error in the ACK delimiter (flag 49..54, REC + 1); tx reads
/// 54 dominant after its flag (1 bit, tolerated), so delimiter 55..62, intermission 63..65, next
/// attempt 66 bits later. The 16th error takes TEC to 128, still signalled with an active flag
/// (rule 9), and tx then suspends 8 bits: the 17th attempt starts at 15·66 + 74 = 1064. Its
/// passive flag 48..53 is recessive: r0 sees a correct frame and takes it (Delivered at the end
/// of EOF, 1064 + 56), but keeps REC 16: rule 8 decrements REC only after a reception with the
/// ACK bit sent, and r0 sends none. tx keeps TEC 128 (exception 3a). Passive flag,
/// delimiter 54..61, intermission 62..64 and suspend 65..72: the 18th attempt at 1064 + 73.
#[test]
fn passive_error_flag_is_not_seen_by_others() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.b.set_ack(r0, false).unwrap();
    for attempt in 0..16u64 {
        let ev = n.step();
        let s = attempt * 66;
        assert_eq!(
            bus_errors(&ev),
            [(tx, s + 48, BusError::Ack), (r0, s + 49, BusError::Form)],
            "attempt {}",
            attempt + 1
        );
    }
    assert_eq!(
        (n.tec(tx), n.rec(r0), n.state(tx)),
        (128, 16, ErrorState::Passive)
    );
    let ev = n.step();
    assert_eq!(bus_errors(&ev), [(tx, 1064 + 48, BusError::Ack)]);
    assert_eq!(delivered(&ev), [(r0, 1064 + 56)]);
    assert_eq!((n.tec(tx), n.rec(r0)), (128, 16));
    let ev = n.step();
    assert_eq!(destroyed(&ev), [1064 + 73]);
}

/// A passive receiver's error flag is not seen by the others either. r0 is made error passive
/// as in `rule_8_rec_above_127_becomes_119` (bit error at 16, then 120 dominant bits that r0
/// alone reads after its flag: REC 1 + 8 + 15 × 8 = 129; r1 has REC 1). On the retransmission
/// r0 alone reads EOF 1 (49) dominant: a form error, REC 130, and a passive flag from 50 that
/// leaves the bus recessive. The transmitter sends the frame (TEC 8 − 1 = 7) and r1 takes it
/// (REC 0); r0 does not get it.
#[test]
fn passive_receiver_flag_is_not_seen_by_others() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.disturb(16, 1, INVERT, None);
    n.disturb(29, 120, DOMINANT, Some(vec![r0]));
    n.disturb(149, 12, RECESSIVE, Some(vec![r0]));
    n.step();
    assert_eq!(
        (n.rec(r0), n.state(r0), n.rec(r1)),
        (129, ErrorState::Passive, 1),
        "setup"
    );
    n.b.injector_mut().add(Rule {
        target: Target::Node(tx),
        schedule: Schedule::Once,
        bit: BitPosition::At((S + 3) as u16),
        effect: Effect::Form,
        seen_by: SeenBy::Nodes(vec![r0]),
    });
    let ev = n.step();
    let sof = match frames(&ev)[..] {
        [(node, sof)] if node == tx => sof,
        _ => panic!("the frame goes through: {ev:?}"),
    };
    assert_eq!(bus_errors(&ev), [(r0, sof + 50, BusError::Form)]);
    assert_eq!(delivered(&ev), [(r1, sof + 56)]);
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (7, 130, 0));
}

/// A passive error flag is complete after 6 consecutive equal bits, however long that takes,
/// and (exception 3a not applying) a dominant bit during it costs TEC + 8. A lone node at TEC
/// 128 (17th attempt, at 1048) reads its ACK slot recessive and sends its passive flag from 48.
/// It reads a dominant bit at 50: bits 48, 49 recessive, 50 dominant, 51..56 recessive: six
/// equal bits at 56, a 9-bit flag. TEC 128 + 8 = 136. Delimiter 57..64, intermission 65..67,
/// suspend 68..75: next attempt at 1048 + 76.
#[test]
fn passive_flag_completes_after_six_equal_bits() {
    let mut n = net(0);
    let tx = n.tx;
    lone_passive(&mut n);
    let s = LONE_17TH_SOF;
    n.disturb(s + 50, 1, DOMINANT, Some(vec![tx]));
    let ev = n.step();
    assert_eq!(destroyed(&ev), [s]);
    assert_eq!(error_frame(&ev), (47, 48, 57, BusError::Ack));
    assert_eq!(n.tec(tx), 136);
    assert_eq!(destroyed(&n.step()), [s + 76]);
}

/// The 8th bit of an error delimiter read dominant is an overload condition, not an error.
/// Bit error at DLC3 (16, r = 0): flags 17..28, delimiter 29..36; everyone reads 36 dominant and
/// sends an overload flag 37..42; overload delimiter 43..50, intermission 51..53; next SOF 54.
/// Counters as after the error alone: TEC 8, REC 1.
#[test]
fn dominant_last_error_delimiter_bit_is_overload() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.disturb(16, 1, INVERT, None);
    n.disturb(36, 1, DOMINANT, None);
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, 17, BusError::Bit),
            (r0, 23, BusError::Stuff),
            (r1, 23, BusError::Stuff)
        ]
    );
    assert_eq!(overloads(&ev), [(tx, 37), (r0, 37), (r1, 37)]);
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 1, 1));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 54)]);
}

/// A dominant bit in the error delimiter before its last bit is a form error. As above but
/// bit 35 (the 7th delimiter bit) is read dominant by all: form error, flags 36..41; rule 3
/// again for the transmitter (TEC 16), rule 1 for the receivers (REC 2). Delimiter 42..49,
/// intermission 50..52, next SOF 53.
#[test]
fn dominant_error_delimiter_bit_is_form_error() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.disturb(16, 1, INVERT, None);
    n.disturb(35, 1, DOMINANT, None);
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, 17, BusError::Bit),
            (r0, 23, BusError::Stuff),
            (r1, 23, BusError::Stuff),
            (tx, 36, BusError::Form),
            (r0, 36, BusError::Form),
            (r1, 36, BusError::Form)
        ]
    );
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (16, 2, 2));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 53)]);
}

// ---------------------------------------------------------------------------------------------
// Fault confinement (Bosch 2.0B §8), rules 1 to 12 and the exceptions of rule 3.
// ---------------------------------------------------------------------------------------------

/// Rule 1: a receiver that detects an error adds 1 to REC. Bit error at 16 (r = 0): both
/// receivers find a stuff error at 22 and count REC 1 at the first bit of their flags (23); the
/// first bit after their flags (29) is recessive, so rule 2 does not apply.
#[test]
fn rule_1_receiver_error_adds_one() {
    let mut n = net(2);
    n.disturb(16, 1, INVERT, None);
    let ev = n.step();
    let recs: Vec<(NodeId, u64, u16)> = ev
        .iter()
        .filter_map(|e| match *e {
            Event::BusError {
                node,
                at,
                rec,
                transmitting: false,
                ..
            } => Some((node, bits_at(at), rec)),
            _ => None,
        })
        .collect();
    assert_eq!(recs, [(n.rx[0], 23, 1), (n.rx[1], 23, 1)]);
    assert_eq!((n.rec(n.rx[0]), n.rec(n.rx[1])), (1, 1));
}

/// Rule 2: a receiver that reads dominant as the first bit after its own error flag adds 8.
/// Bit error at 16 (r = 0): receivers flag 23..28; r0 alone reads 29 dominant: REC 1 + 8 = 9,
/// r1 stays at 1. r0's delimiter is one bit later (30..37, intermission 38..40), so the
/// retransmission at 40 falls in r0's third intermission bit, which is a SOF: r0 receives it
/// (REC 8). The transmitter, which also read dominant right after its own flag (23), is not a
/// receiver: TEC 8, no more.
#[test]
fn rule_2_dominant_bit_after_receiver_error_flag() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.disturb(16, 1, INVERT, None);
    n.disturb(29, 1, DOMINANT, Some(vec![r0]));
    n.step();
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (8, 9, 1));
    let ev = n.run_for(1000);
    assert_eq!(frames(&ev), [(tx, 40)]);
    assert_eq!(delivered(&ev), [(r0, 40 + 56), (r1, 40 + 56)]);
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (7, 8, 0));
}

/// Rule 3: a transmitter that sends an error flag adds 8 to TEC, counted at the first bit of
/// the flag. Bit error at 16: BusError at 17 with TEC 8.
#[test]
fn rule_3_transmitter_error_adds_eight() {
    let mut n = net(1);
    n.disturb(16, 1, INVERT, None);
    let ev = n.step();
    let tx_errors: Vec<(u64, u16)> = ev
        .iter()
        .filter_map(|e| match *e {
            Event::BusError {
                at,
                tec,
                transmitting: true,
                ..
            } => Some((bits_at(at), tec)),
            _ => None,
        })
        .collect();
    assert_eq!(tx_errors, [(17, 8)]);
    assert_eq!(n.tec(n.tx), 8);
}

/// Rule 3, exception 1 (3a): an error-passive transmitter that detects an ACK error and reads no
/// dominant bit while sending its passive flag keeps its TEC. A lone node stays at 128 for
/// ever; each passive attempt lasts S + 27 = 73 bits (flag 48..53, delimiter 54..61,
/// intermission 62..64, suspend 65..72), from 1048.
#[test]
fn rule_3_exception_passive_ack_error_without_dominant_bit() {
    let mut n = net(0);
    lone_passive(&mut n);
    for attempt in 0..10u64 {
        let ev = n.step();
        assert_eq!(destroyed(&ev), [LONE_17TH_SOF + attempt * 73]);
        assert_eq!(n.tec(n.tx), 128);
    }
    assert_eq!(n.state(n.tx), ErrorState::Passive);
}

/// Rule 3, exception 2 (3b): a stuff error during arbitration on a stuff bit the transmitter
/// sent recessive and read dominant leaves TEC unchanged. Bit 5 is the recessive stuff bit
/// after SOF and ID10..ID7 (all dominant); everyone reads it dominant: for the transmitter a
/// stuff error (not lost arbitration, not a bit error), for the receivers the 6th dominant bit,
/// a stuff error too. All flag 6..11; delimiter 12..19, intermission 20..22, next SOF 23.
/// TEC 0, REC 1 (rule 1 applies to the receivers).
#[test]
fn rule_3_exception_stuff_error_on_recessive_arbitration_stuff_bit() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.disturb(5, 1, INVERT, None);
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, 6, BusError::Stuff),
            (r0, 6, BusError::Stuff),
            (r1, 6, BusError::Stuff)
        ]
    );
    assert!(ev.iter().any(|e| matches!(
        e,
        Event::BusError {
            transmitting: true,
            error: BusError::Stuff,
            ..
        }
    )));
    assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (0, 1, 1));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 23)]);
}

/// Rule 4: a transmitter that detects a bit error while sending an active error flag adds 8.
/// Bit error at 16 (flag from 17); the transmitter alone reads 17 recessive: TEC 8 + 8 = 16, and
/// it starts a new flag 18..23. The bus is dominant from 17 all the same, so the receivers find
/// the stuff error at 22 (flags 23..28) as with r = 0; the transmitter reads 24..28 dominant
/// after its flag (5 bits, tolerated); next SOF 40.
#[test]
fn rule_4_transmitter_bit_error_in_active_flag() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.disturb(16, 1, INVERT, None);
    n.disturb(17, 1, RECESSIVE, Some(vec![tx]));
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, 17, BusError::Bit),
            (tx, 18, BusError::Bit),
            (r0, 23, BusError::Stuff)
        ]
    );
    assert!(locations(&ev).contains(&(tx, Location::Flag)));
    assert_eq!((n.tec(tx), n.rec(r0)), (16, 1));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 40)]);
}

/// Rule 5: a receiver that detects a bit error while sending an active error flag adds 8 (and
/// rule 1 does not apply to that error). Bit error at 16: r0 flags from 23 (REC 1) and reads 23
/// recessive: REC 1 + 8 = 9, and a new flag from the next bit (as ISO 16845-1 expects),
/// 24..29. The transmitter reads 23..29 dominant after its flag (17..22): 7 bits, still
/// tolerated by rule 6: TEC 8. Delimiter 30..37, intermission 38..40, next SOF 41.
#[test]
fn rule_5_receiver_bit_error_in_active_flag() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.disturb(16, 1, INVERT, None);
    n.disturb(23, 1, RECESSIVE, Some(vec![r0]));
    let ev = n.step();
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, 17, BusError::Bit),
            (r0, 23, BusError::Stuff),
            (r0, 24, BusError::Bit)
        ]
    );
    assert_eq!((n.tec(tx), n.rec(r0)), (8, 9));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 41)]);
}

/// Rule 5 for an overload flag: r0 reads the last EOF bit (55) dominant, has the frame, and
/// sends an overload flag 56..61; the transmitter answers with 57..62. r0 reads its third flag
/// bit (58) recessive: a bit error, REC 0 + 8 = 8, and an error flag 59..64. The transmitter
/// reads 63, 64 dominant after its overload flag (2 bits). Delimiter 65..72, intermission
/// 73..75; the transmitter's next frame at S + 30 = 76. TEC 0 (the frame was sent).
#[test]
fn rule_5_receiver_bit_error_in_overload_flag() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.b.submit(tx, f(), BusTime::ZERO).unwrap();
    n.disturb(S + 9, 1, DOMINANT, Some(vec![r0]));
    n.disturb(58, 1, RECESSIVE, Some(vec![r0]));
    let ev = n.step();
    assert_eq!(overloads(&ev), [(r0, 56), (tx, 57)]);
    assert_eq!(bus_errors(&ev), [(r0, 59, BusError::Bit)]);
    assert_eq!(delivered(&ev), [(r0, 56)]);
    assert_eq!((n.tec(tx), n.rec(r0)), (0, 8));
    assert_eq!(frames(&n.run_for(1000)), [(tx, 76)]);
}

/// Rule 6 after an active error flag: up to 7 consecutive dominant bits after the flag are
/// tolerated; the 8th (the 14th counting the flag's own 6) and each further 8th add 8. A lone
/// transmitter flags 48..53 after its ACK error (TEC 8) and then reads N dominant bits 54..53+N:
/// N = 7 → 8, N = 8 → 16, N = 15 → 16, N = 16 → 24, N = 24 → 32. Its delimiter starts at
/// 54 + N, so the next attempt is at 65 + N.
#[test]
fn rule_6_dominant_bits_after_active_error_flag() {
    for (dominant, tec) in [(7u32, 8u16), (8, 16), (15, 16), (16, 24), (24, 32)] {
        let mut n = net(0);
        let tx = n.tx;
        n.disturb(54, dominant, DOMINANT, Some(vec![tx]));
        n.step();
        assert_eq!(n.tec(tx), tec, "{dominant} dominant bits");
        assert_eq!(
            destroyed(&n.step()),
            [65 + u64::from(dominant)],
            "{dominant} dominant bits"
        );
    }
}

/// Rule 6 after a passive error flag: the 8th consecutive dominant bit adds 8. A lone passive
/// node (TEC 128, attempt at 1048) completes its passive flag at 53 without a dominant bit
/// (exception 3a: TEC unchanged) and then reads N dominant bits from 54: N = 7 → 128, N = 8 →
/// 136. Next attempt after delimiter, intermission and suspend: 1048 + 73 + N.
#[test]
fn rule_6_dominant_bits_after_passive_error_flag() {
    for (dominant, tec) in [(7u32, 128u16), (8, 136)] {
        let mut n = net(0);
        let tx = n.tx;
        lone_passive(&mut n);
        let s = LONE_17TH_SOF;
        n.disturb(s + 54, dominant, DOMINANT, Some(vec![tx]));
        n.step();
        assert_eq!(n.tec(tx), tec, "{dominant} dominant bits");
        assert_eq!(
            destroyed(&n.step()),
            [s + 73 + u64::from(dominant)],
            "{dominant} dominant bits"
        );
    }
}

/// Rule 6 after an overload flag, counted as after an active error flag: r0 reads the last EOF
/// bit dominant and sends an overload flag 56..61; it then reads N dominant bits from 62 (the
/// transmitter's overload flag covers 62 anyway): N = 7 → REC 0, N = 8 → REC 8 (a receiver).
#[test]
fn rule_6_dominant_bits_after_overload_flag() {
    for (dominant, rec) in [(7u32, 0u16), (8, 8)] {
        let mut n = net(1);
        let r0 = n.rx[0];
        n.disturb(S + 9, 1, DOMINANT, Some(vec![r0]));
        n.disturb(62, dominant, DOMINANT, Some(vec![r0]));
        let ev = n.step();
        assert_eq!(overloads(&ev), [(r0, 56), (n.tx, 57)]);
        assert_eq!((n.rec(r0), n.tec(n.tx)), (rec, 0), "{dominant} dominant bits");
    }
}

/// Rule 7: a successful transmission takes 1 from TEC, not below 0. After one bit error
/// (TEC 8) and two more frames queued, three successes leave TEC 5; a fresh node's success
/// leaves 0.
#[test]
fn rule_7_successful_transmission_decrements_tec() {
    let mut n = net(1);
    n.b.submit(n.tx, f(), BusTime::ZERO).unwrap();
    n.b.submit(n.tx, f(), BusTime::ZERO).unwrap();
    n.disturb(16, 1, INVERT, None);
    n.step();
    assert_eq!(n.tec(n.tx), 8);
    // Retransmission at 40, then the other two back to back.
    assert_eq!(frames(&n.run_for(1000)), [(n.tx, 40), (n.tx, 99), (n.tx, 158)]);
    assert_eq!(n.tec(n.tx), 5);
    let mut fresh = net(1);
    fresh.run_for(1000);
    assert_eq!(fresh.tec(fresh.tx), 0);
}

/// Rule 8: a successful reception takes 1 from REC when it is 1..127, and leaves 0 at 0. After
/// one error (REC 1) the retransmission gives 0, and a further frame leaves 0.
#[test]
fn rule_8_successful_reception_decrements_rec() {
    let mut n = net(1);
    n.b.submit(n.tx, f(), BusTime::ZERO).unwrap();
    n.disturb(16, 1, INVERT, None);
    n.step();
    assert_eq!(n.rec(n.rx[0]), 1);
    n.step();
    assert_eq!(n.rec(n.rx[0]), 0);
    n.step();
    assert_eq!(n.rec(n.rx[0]), 0);
}

/// Rule 8 above 127, with rules 9 and 11 on REC: a receiver whose REC is above 127 gets a value
/// from 119 to 127 on a successful reception (harvemu: 119). Bit error at 16: r0 flags 23..28
/// (REC 1); r0 alone then reads 120 dominant bits 29..148: rule 2 at 29 (REC 9), rule 6 at the
/// 8th, 16th, ..., 120th (bits 36, 44, ..., 148): 15 × 8, REC 129, error passive (rule 9). r0
/// reads 149..160 recessive: delimiter, intermission, idle. The retransmission then reaches it
/// cleanly: REC 119, error active again (rule 11).
#[test]
fn rule_8_rec_above_127_becomes_119() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.disturb(16, 1, INVERT, None);
    n.disturb(29, 120, DOMINANT, Some(vec![r0]));
    n.disturb(149, 12, RECESSIVE, Some(vec![r0]));
    let ev = n.step();
    assert_eq!((n.rec(r0), n.state(r0)), (129, ErrorState::Passive));
    assert_eq!(
        states(&ev),
        [(r0, 149, ErrorState::Active, ErrorState::Passive, 0, 129)],
        "passive at the 15th rule-6 penalty, counted at bit 148"
    );
    let ev = n.run_for(1000);
    assert_eq!(frames(&ev).len(), 1);
    assert_eq!((n.rec(r0), n.state(r0), n.tec(tx)), (119, ErrorState::Active, 7));
    assert!(
        states(&ev)
            .iter()
            .any(|s| s.0 == r0 && s.2 == ErrorState::Passive && s.3 == ErrorState::Active && s.5 == 119)
    );
}

/// Rules 9, 10 and 12, and the suspend after an error frame, over one timeline. A transmitter
/// has a bit error at DLC3 (16) on every attempt; one receiver.
/// - Error active (attempts 1 to 16): r = 0, receivers flag 23..28, next SOF 40 bits later.
///   The 12th error takes TEC to 96 (warning); the 16th to 128: error passive (rule 9), still
///   signalled with an active flag (so the receiver again detects at 22, flags from 23), and
///   the suspend follows its intermission: attempt 17 at 15·40 + 48 = 648.
/// - Error passive (attempts 17 to 31): the passive flag leaves the bus recessive from 16, so
///   the receiver reads five recessive bits 16..20 and a recessive bit where a stuff bit is due
///   (21): stuff error, flag 22..27. The transmitter's passive flag (17..27) completes with six
///   equal dominant bits 22..27; delimiter 28..35, intermission 36..38, suspend 39..46: 47 bits
///   an attempt. Attempt 32 at 648 + 15·47 = 1353.
/// - Attempt 32 takes TEC from 248 to 256: bus off at once (rule 10), no flag, the frame is
///   dropped. The receiver's flag is 22..27 again; from 28 the bus is recessive, and after 128
///   sequences of 11 recessive bits (1408 bits) the node is error active with TEC = REC = 0
///   (rule 12): at 1353 + 28 + 1408 = 2789.
///
/// The receiver counts REC + 1 per attempt: 32.
#[test]
fn rules_9_10_12_error_passive_bus_off_and_recovery() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.b.injector_mut().add(Rule::bit_errors(
        Target::Node(tx),
        Schedule::Always,
        BitPosition::At(16),
    ));
    let ev = n.run_for(100_000);
    let mut sof = Vec::new();
    let mut s = 0;
    for attempt in 1..=32u64 {
        sof.push(s);
        s += match attempt {
            1..=15 => 40,
            16 => 48,
            _ => 47,
        };
    }
    assert_eq!(sof[16], 648);
    assert_eq!(sof[31], 1353);
    assert_eq!(destroyed(&ev), sof);
    // Where the receiver detects: at 22 while the transmitter's flag is active, 21 when passive.
    let rx_flags: Vec<u64> = bus_errors(&ev)
        .iter()
        .filter(|e| e.0 == r0)
        .map(|e| e.1)
        .collect();
    let want: Vec<u64> = sof
        .iter()
        .enumerate()
        .map(|(i, s)| s + if i < 16 { 23 } else { 22 })
        .collect();
    assert_eq!(rx_flags, want);
    let tx_states: Vec<_> = states(&ev)
        .into_iter()
        .filter(|s| s.0 == tx)
        .map(|s| (s.1, s.2, s.3, s.4))
        .collect();
    assert_eq!(
        tx_states,
        [
            (sof[15] + 17, ErrorState::Active, ErrorState::Passive, 128),
            (sof[31] + 17, ErrorState::Passive, ErrorState::BusOff, 256),
            (2789, ErrorState::BusOff, ErrorState::Active, 0),
        ]
    );
    let warning = ev.iter().find_map(|e| match *e {
        Event::Warning {
            node,
            at,
            entered: true,
            tec,
            ..
        } if node == tx => Some((bits_at(at), tec)),
        _ => None,
    });
    assert_eq!(warning, Some((sof[11] + 17, 96)));
    assert!(
        ev.iter()
            .any(|e| matches!(e, Event::TxAborted { node, .. } if *node == tx))
    );
    assert_eq!((n.tec(tx), n.rec(tx), n.state(tx)), (0, 0, ErrorState::Active));
    assert_eq!(n.rec(r0), 32);
}

/// Rule 11: an error-passive node whose counters are both at or below 127 is error active
/// again. 16 bit errors (as in the timeline above) leave TEC 128; the 17th attempt (at 648,
/// after the suspend) succeeds: TEC 127, error active, at the end of EOF (648 + 56).
#[test]
fn rule_11_back_to_error_active() {
    let mut n = net(1);
    let tx = n.tx;
    let rule = n.b.injector_mut().add(Rule::bit_errors(
        Target::Node(tx),
        Schedule::Always,
        BitPosition::At(16),
    ));
    for _ in 0..16 {
        n.step();
    }
    assert_eq!((n.tec(tx), n.state(tx)), (128, ErrorState::Passive));
    n.b.injector_mut().remove(rule);
    let ev = n.step();
    assert_eq!(frames(&ev), [(tx, 648)]);
    assert_eq!((n.tec(tx), n.state(tx)), (127, ErrorState::Active));
    assert_eq!(
        states(&ev),
        [(tx, 648 + 56, ErrorState::Passive, ErrorState::Active, 127, 0)]
    );
}

// ---------------------------------------------------------------------------------------------
// Overload frames (Bosch 2.0B §3.1.4).
// ---------------------------------------------------------------------------------------------

/// (node, bit) pairs: overload flags, frame starts.
type At = Vec<(NodeId, u64)>;

/// Overload frames of receivers that are not ready, `k` requested: returns the overload flags,
/// the start of the transmitter's next frame and the nodes.
fn not_ready(k: u8) -> (At, At, [NodeId; 3]) {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.b.submit(tx, f(), BusTime::ZERO).unwrap();
    n.b.injector_mut().add(Rule {
        target: Target::Node(tx),
        schedule: Schedule::Once,
        bit: BitPosition::At(0),
        effect: Effect::Overload(k),
        seen_by: SeenBy::Nodes(vec![r0]),
    });
    let ev = n.step();
    assert_eq!(bus_errors(&ev), []);
    let next = frames(&n.run_for(1000));
    assert_eq!(
        (n.tec(tx), n.rec(r0), n.rec(r1)),
        (0, 0, 0),
        "overload changes no counter"
    );
    (overloads(&ev), next, [tx, r0, r1])
}

/// Overload frame of a receiver that is not ready: it may start only at the first bit of
/// intermission (56): flag 56..61; the others read it in their first intermission bit and
/// answer with 57..62; delimiter 63..70, intermission 71..73; next frame at S + 28 = 74. No
/// counter moves.
#[test]
fn overload_frame_of_a_receiver_not_ready() {
    let (ov, next, [tx, r0, r1]) = not_ready(1);
    assert_eq!(ov, [(r0, 56), (tx, 57), (r1, 57)]);
    assert_eq!(next, [(tx, 74)]);
}

/// At most two overload frames delay the next frame. With two: the second flag starts at the
/// first intermission bit after the first overload delimiter (71): 71..76, answered 72..77,
/// delimiter 78..85, intermission 86..88, next frame at S + 43 = 89. Asking for three gives the
/// same.
#[test]
fn at_most_two_overload_frames_of_a_receiver_not_ready() {
    for k in [2u8, 3] {
        let (ov, next, [tx, r0, r1]) = not_ready(k);
        assert_eq!(
            ov,
            [(r0, 56), (tx, 57), (r1, 57), (r0, 71), (tx, 72), (r1, 72)],
            "{k} requested"
        );
        assert_eq!(next, [(tx, 89)], "{k} requested");
    }
}

/// A dominant bit in the 1st or 2nd intermission bit (56 or 57) is an overload condition: every
/// node sends an overload flag from the next bit (57..62 or 58..63); delimiter and intermission
/// follow, next frame at 74 or 75. No counter moves.
#[test]
fn dominant_first_or_second_intermission_bit_is_overload() {
    for i in [0u64, 1] {
        let mut n = net(2);
        let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
        n.b.submit(tx, f(), BusTime::ZERO).unwrap();
        n.disturb(S + 10 + i, 1, DOMINANT, None);
        let ev = n.step();
        assert_eq!(bus_errors(&ev), []);
        let o = S + 11 + i;
        assert_eq!(overloads(&ev), [(tx, o), (r0, o), (r1, o)]);
        assert_eq!(frames(&n.run_for(1000)), [(tx, 74 + i)]);
        assert_eq!((n.tec(tx), n.rec(r0), n.rec(r1)), (0, 0, 0));
    }
}

/// A dominant 3rd intermission bit (58) is a start of frame, not an overload condition. Nobody
/// has a frame waiting, so every node is a receiver of a frame nobody sends: SOF 58, then five
/// recessive bits 59..63 and a recessive bit where a stuff bit is due (64): stuff error, flags
/// 65..70. REC 1 for all three (the previous transmitter is a receiver here).
#[test]
fn dominant_third_intermission_bit_is_start_of_frame() {
    let mut n = net(2);
    let (tx, r0, r1) = (n.tx, n.rx[0], n.rx[1]);
    n.disturb(S + 12, 1, DOMINANT, None);
    let ev = n.step();
    assert_eq!(overloads(&ev), []);
    assert_eq!(
        bus_errors(&ev),
        [
            (tx, 65, BusError::Stuff),
            (r0, 65, BusError::Stuff),
            (r1, 65, BusError::Stuff)
        ]
    );
    assert_eq!((n.tec(tx), n.rec(tx), n.rec(r0), n.rec(r1)), (0, 1, 1, 1));
}

// ---------------------------------------------------------------------------------------------
// Suspend transmission (Bosch 2.0B §3.2.3 and §8).
// ---------------------------------------------------------------------------------------------

/// Suspend after a failed transmission, and another node starting meanwhile. tx is error
/// passive after 17 bit errors at DLC3 (see `passive_by_bit_errors`); its 18th attempt, at 695,
/// has the same bit error: passive flag from 17, r0's stuff error at 21 and flag 22..27, which
/// completes tx's passive flag; both read 28 recessive: delimiter 28..35, intermission 36..38.
/// r0 has a frame waiting (submitted at 700) and is not suspended: it starts at 695 + 39 = 734,
/// during tx's 8 suspend bits (39..46), and tx becomes its receiver. After r0's frame (59 bits,
/// to 793) tx, which was a receiver, tries again at once: 793.
#[test]
fn suspend_after_failed_transmission_lets_another_node_start() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.b.injector_mut().add(Rule::bit_errors(
        Target::Node(tx),
        Schedule::Always,
        BitPosition::At(16),
    ));
    for _ in 0..17 {
        n.step();
    }
    assert_eq!((n.tec(tx), n.state(tx)), (136, ErrorState::Passive), "setup");
    n.b.submit(r0, f(), at(700)).unwrap();
    let ev = n.step();
    assert_eq!(destroyed(&ev), [695]);
    assert_eq!(n.tec(tx), 144);
    let ev = n.step();
    assert_eq!(frames(&ev), [(r0, 734)]);
    assert_eq!(delivered(&ev), [(tx, 734 + 56)]);
    let ev = n.step();
    assert_eq!(destroyed(&ev), [734 + F_BITS]);
}

/// Brings tx to TEC 136 (error passive) with 17 bit errors at DLC3 (16 active attempts of 40
/// bits, the 16th followed by the suspend, then one passive attempt of 47 bits, see
/// `rules_9_10_12_error_passive_bus_off_and_recovery`); its frame then goes at 648 + 47 = 695.
fn passive_by_bit_errors(n: &mut Net) {
    let rule = n.b.injector_mut().add(Rule::bit_errors(
        Target::Node(n.tx),
        Schedule::Always,
        BitPosition::At(16),
    ));
    for _ in 0..17 {
        n.step();
    }
    n.b.injector_mut().remove(rule);
    assert_eq!((n.tec(n.tx), n.state(n.tx)), (136, ErrorState::Passive), "setup");
}

/// Suspend after a successful transmission: an error-passive node (TEC 136) sends its frame at
/// 695 (TEC 135, still passive) and waits 8 bits after the intermission before its next frame:
/// 695 + 59 + 8 = 762.
#[test]
fn suspend_after_successful_transmission() {
    let mut n = net(1);
    n.b.submit(n.tx, f(), BusTime::ZERO).unwrap();
    passive_by_bit_errors(&mut n);
    let ev = n.run_for(1000);
    assert_eq!(frames(&ev), [(n.tx, 695), (n.tx, 762)]);
    assert_eq!(n.tec(n.tx), 134);
}

/// During that suspend another node may start, and the suspended node becomes its receiver:
/// r0's frame (submitted at 700) starts at the end of the intermission, 695 + 59 = 754; the
/// passive node's next frame follows r0's at once (it was a receiver): 754 + 59 = 813.
#[test]
fn suspend_lets_another_node_start_meanwhile() {
    let mut n = net(1);
    let (tx, r0) = (n.tx, n.rx[0]);
    n.b.submit(tx, f(), BusTime::ZERO).unwrap();
    passive_by_bit_errors(&mut n);
    n.b.submit(r0, f(), at(700)).unwrap();
    let ev = n.run_for(1000);
    assert_eq!(frames(&ev), [(tx, 695), (r0, 754), (tx, 813)]);
    assert_eq!(delivered(&ev).iter().filter(|d| d.0 == tx).count(), 1);
}

/// No suspend once the successful transmission has made the node error active: a lone node at
/// TEC 128 (error passive) gets a receiver that acknowledges; its frame goes at 1048 and takes
/// TEC to 127, error active (rule 11), so at the end of the intermission it is no longer an
/// error-passive node and its next frame starts at once: 1048 + 59 = 1107.
#[test]
fn no_suspend_after_success_that_makes_the_node_error_active() {
    let mut n = net(0);
    let tx = n.tx;
    n.b.submit(tx, f(), BusTime::ZERO).unwrap();
    lone_passive(&mut n);
    n.b.attach(ControllerConfig::named("r0"));
    let ev = n.run_for(1000);
    assert_eq!(frames(&ev), [(tx, LONE_17TH_SOF), (tx, LONE_17TH_SOF + F_BITS)]);
    assert_eq!((n.tec(tx), n.state(tx)), (126, ErrorState::Active));
}

// ---------------------------------------------------------------------------------------------
// Bus time.
// ---------------------------------------------------------------------------------------------

/// Bus time never goes backwards: on a busy bus with every kind of injected error, overload
/// frames and disturbances, events come out in time order, each attempt starts after the
/// previous one has ended, and within an error frame start ≤ flag ≤ end.
#[test]
fn bus_time_never_goes_backwards() {
    let mut b = Bus::new(BusConfig {
        seed: 7,
        ..BusConfig::default()
    })
    .unwrap();
    let nodes: Vec<NodeId> = (0..4)
        .map(|i| {
            b.attach(ControllerConfig {
                tx_queue_len: 1000,
                ..ControllerConfig::named(format!("n{i}"))
            })
        })
        .collect();
    let rules = [
        Rule::bit_errors(Target::Any, Schedule::BitErrorRate(2e-3), BitPosition::Random),
        Rule {
            target: Target::Any,
            schedule: Schedule::EveryNth(7),
            bit: BitPosition::Random,
            effect: Effect::Overload(2),
            seen_by: SeenBy::All,
        },
        Rule {
            target: Target::Any,
            schedule: Schedule::EveryNth(11),
            bit: BitPosition::Random,
            effect: Effect::Stuff,
            seen_by: SeenBy::Nodes(vec![nodes[1]]),
        },
        Rule {
            target: Target::Any,
            schedule: Schedule::EveryNth(13),
            bit: BitPosition::Random,
            effect: Effect::Form,
            seen_by: SeenBy::All,
        },
        Rule {
            target: Target::Any,
            schedule: Schedule::EveryNth(17),
            bit: BitPosition::Random,
            effect: Effect::Crc,
            seen_by: SeenBy::Nodes(vec![nodes[2]]),
        },
    ];
    for r in rules {
        b.injector_mut().add(r);
    }
    for k in 0..200u64 {
        b.disturb(Disturbance {
            at: at(k * 997 + 13),
            bits: (k % 23) as u32 + 1,
            level: [DOMINANT, RECESSIVE, INVERT][(k % 3) as usize],
            nodes: (k % 2 == 0).then(|| vec![nodes[(k % 4) as usize]]),
        });
    }
    for k in 0..600u64 {
        let node = nodes[(k % 4) as usize];
        let frame = Frame::base((0x100 + (k % 37)) as u16, &[(k % 256) as u8, 0x55]).unwrap();
        b.submit(node, frame, at(k * 300)).unwrap();
    }
    let mut last = BusTime::ZERO;
    // The attempt seen last: its start, and the latest end of a frame or error frame in it.
    let (mut attempt_start, mut attempt_end) = (None, BusTime::ZERO);
    let mut count = 0;
    let mut until = 0;
    while until < 400_000 {
        until += 5_000;
        b.run_until(at(until));
        for e in b.take_events() {
            let t = e.at();
            assert!(t >= last, "{e:?} at {t:?} before {last:?}");
            last = t;
            count += 1;
            let (start, end) = match e {
                Event::Frame { start, end, .. } => (start, end),
                Event::ErrorFrame { start, flag, end, .. } => {
                    assert!(start < flag && flag < end, "{e:?}");
                    (start, end)
                }
                _ => continue,
            };
            assert!(start < end, "{e:?}");
            if attempt_start != Some(start) {
                // Several transmitters of one attempt share its start; a new attempt starts
                // after the previous one has ended.
                assert!(start >= attempt_end, "{e:?} starts before {attempt_end:?}");
                attempt_start = Some(start);
            }
            attempt_end = attempt_end.max(end);
        }
    }
    assert!(count > 1000, "{count} events");
}
