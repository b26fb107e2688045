//! The lab program of `configs/firmware/` on two emulated benches, each an 80C51 at 12 MHz with
//! one SJA1000 (6 MHz crystal, 30 kbit/s): the sender's chip at D300h, the receiver's at D400h.
//! Driven through the hub as harvemu drives every node, in virtual time.
//!
//! Expectations come from the program listing and the data sheets, worked by hand (and with s51
//! for the loop's length): the receiver stores the frame's eight data bytes at 30H–37H; the
//! sender sends one frame per pass of its loop, 99 916 machine cycles (µs at 12 MHz); a receiver
//! whose acceptance code is AAh instead of BBh never stores it.

use bus::time::BusDuration;
use harvemu_e2e::{FirmwareRun, assemble, bench_file, parse_trace, root, run_firmware};

const LOOP_CYCLES: u64 = 99_916;
const DATA: [u8; 8] = [0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18];

fn shipped_hex() -> String {
    std::fs::read_to_string(root().join("configs/firmware/can_seed.hex")).expect("the shipped HEX")
}

fn source() -> String {
    std::fs::read_to_string(root().join("configs/firmware/can_seed.asm")).expect("the source")
}

/// The lab for a second: the sender running `sender_hex` on a 6 MHz crystal, the receiver
/// `receiver_hex` on one of `receiver_xtal_hz`.
fn lab(sender_hex: &str, receiver_hex: &str, receiver_xtal_hz: u32) -> FirmwareRun {
    run_firmware(
        &[
            (
                bench_file("SENDER", 0x4000, 0xD300, 6_000_000, "None"),
                sender_hex.to_string(),
            ),
            (
                bench_file("RECEIVER", 0x4000, 0xD400, receiver_xtal_hz, "None"),
                receiver_hex.to_string(),
            ),
        ],
        1,
    )
}

#[test]
fn the_receiver_stores_the_senders_frame_at_30h() {
    let hex = shipped_hex();
    let run = lab(&hex, &hex, 6_000_000);
    assert!(run.crashed.is_empty(), "{:?}", run.crashed);
    assert_eq!(run.iram(1, 0x30, 8), DATA, "receiver 30H-37H");
    // The program's own copy of the data, made at start-up, is at 20H-27H on both benches.
    assert_eq!(run.iram(0, 0x20, 8), DATA, "sender 20H-27H");
    let frames = parse_trace(&run.trace);
    // Frames end 4.003 ms in and then every 99.916 ms: ten by 1 s, and the eleventh, which
    // started before 1 s, is in the trace too.
    assert_eq!(frames.len(), 11, "{}", run.trace);
    for f in &frames {
        assert_eq!(f.frame.raw_id(), 0x5DF);
        assert!(!f.frame.is_extended() && !f.frame.is_remote());
        assert_eq!(f.frame.data(), DATA);
    }
    // One frame per pass of the loop: the bus is idle when each request comes, so the frames
    // end exactly one loop apart.
    let period = BusDuration::from_micros(LOOP_CYCLES);
    for pair in frames.windows(2) {
        assert_eq!(pair[1].at.since(pair[0].at), period, "{}", run.trace);
    }
    // Both chips ended error active with clean counters, in PeliCAN mode.
    for s in &run.states {
        let c = &s.as_ref().expect("state").controllers[0];
        assert_eq!(
            (c.mode.as_str(), c.tec, c.rec, c.state.as_str()),
            ("PeliCAN", 0, 0, "active")
        );
    }
}

#[test]
fn a_receiver_with_acceptance_code_aah_keeps_30h_untouched() {
    let source = source();
    let patched = source.replacen("#0BBH", "#0AAH", 1);
    assert_ne!(
        patched, source,
        "the receiver's acceptance code BBh is in the source"
    );
    let run = lab(&shipped_hex(), &assemble(&patched), 6_000_000);
    assert!(!parse_trace(&run.trace).is_empty(), "the sender still sends");
    assert_eq!(run.iram(1, 0x30, 8), [0; 8], "receiver 30H-37H");
}

/// The lab notes' first cause of failed communication: bus timing registers set wrong, or a
/// crystal that drifted. A receiver off the bus's bit rate by more than its bit timing
/// tolerates cannot sample the sender's frames: while error active it destroys each with an
/// active error flag, which the sender reads as a bit error (TEC + 8) one bit before its own flag
/// begins, so the receiver sees a dominant bit after its flag (REC + 1 + 8). After 15 attempts
/// its REC (135) makes it error passive and its flags no longer destroy anything, but it
/// acknowledges nothing it could not read: the 16th attempt is an ACK error (TEC 120 + 8 = 128,
/// error passive), and from then on an error-passive sender's ACK errors leave TEC at 128
/// (ISO 11898-1, fault confinement, exception to rule 3). No frame ever gets through.
fn assert_communication_fails(run: &FirmwareRun) {
    assert!(
        parse_trace(&run.trace).is_empty(),
        "no frame completes: {}",
        run.trace
    );
    assert_eq!(run.iram(1, 0x30, 8), [0; 8], "receiver 30H-37H");
    let chip = |i: usize| run.states[i].as_ref().expect("state").controllers[0].clone();
    let sender = chip(0);
    assert_eq!((sender.tec, sender.state.as_str()), (128, "passive"), "sender");
    let receiver = chip(1);
    assert_eq!(receiver.state, "passive", "receiver REC {}", receiver.rec);
}

#[test]
fn wrong_bus_timing_registers_stop_communication() {
    let source = source();
    // BTR0 = 01h: BRP 1 instead of 3, twice the bit rate (60 kbit/s).
    let patched = source.replacen("MOV     A, #03H", "MOV     A, #01H", 1);
    assert_ne!(patched, source, "BTR0's value is in the source");
    assert_communication_fails(&lab(&shipped_hex(), &assemble(&patched), 6_000_000));
}

#[test]
fn a_drifted_crystal_stops_communication_and_a_good_one_does_not() {
    let hex = shipped_hex();
    // 1 % off: the bit timing of BTR0 03h, BTR1 FFh tolerates 0.2 % (SJW 1 of 25 quanta:
    // 1 / (20 * 25)).
    assert_communication_fails(&lab(&hex, &hex, 6_060_000));
    // 0.1 % off is within the tolerance.
    assert_eq!(
        lab(&hex, &hex, 6_006_000).iram(1, 0x30, 8),
        DATA,
        "receiver 30H-37H"
    );
}
