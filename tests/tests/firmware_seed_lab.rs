//! The lab program of `configs/firmware/` on two emulated benches, each an 80C51 at 12 MHz with
//! one SJA1000 (6 MHz crystal, 30 kbit/s): the sender's chip at D300h, the receiver's at D400h.
//! Driven through the hub as harvemu drives every node, in virtual time.
//!
//! Expectations come from the program listing and the data sheets, worked by hand (and with s51
//! for the loop's length): the receiver stores the frame's eight data bytes at 30H–37H; the
//! sender sends one frame per pass of its loop, 99 916 machine cycles (µs at 12 MHz); a receiver
//! whose acceptance code is AAh instead of BBh never stores it.

use bus::time::{BusDuration, BusTime};
use harvemu_e2e::{
    FirmwareRun, assemble, bench_file, bench_specs, parse_trace, root, run_firmware, run_firmware_specs,
};

const LOOP_CYCLES: u64 = 99_916;
const DATA: [u8; 8] = [0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18];

fn shipped_hex() -> String {
    std::fs::read_to_string(root().join("configs/firmware/can_seed.hex")).expect("the shipped HEX")
}

fn source() -> String {
    std::fs::read_to_string(root().join("configs/firmware/can_seed.asm")).expect("the source")
}

/// The two benches: the sender running `sender_hex` on a 6 MHz crystal, the receiver
/// `receiver_hex` on one of `receiver_xtal_hz`.
fn benches(sender_hex: &str, receiver_hex: &str, receiver_xtal_hz: u32) -> Vec<(String, String)> {
    vec![
        (
            bench_file("SENDER", 0x4000, 0xD300, 6_000_000, "None"),
            sender_hex.to_string(),
        ),
        (
            bench_file("RECEIVER", 0x4000, 0xD400, receiver_xtal_hz, "None"),
            receiver_hex.to_string(),
        ),
    ]
}

/// The lab for a second.
fn lab(sender_hex: &str, receiver_hex: &str, receiver_xtal_hz: u32) -> FirmwareRun {
    run_firmware(&benches(sender_hex, receiver_hex, receiver_xtal_hz), 1)
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
    // The first frame ends 8.093 ms in, after one failed attempt (see
    // `the_first_frame_ends_at_the_senders_start_up_plus_its_length_on_the_bus`); the next ones
    // 4.003 ms + k × 99.916 ms: ten by 1 s, and the eleventh, which started before 1 s, is in
    // the trace too.
    assert_eq!(frames.len(), 11, "{}", run.trace);
    for f in &frames {
        assert_eq!(f.frame.raw_id(), 0x5DF);
        assert!(!f.frame.is_extended() && !f.frame.is_remote());
        assert_eq!(f.frame.data(), DATA);
    }
    // One frame per pass of the loop: the bus is idle when each request comes, so from the
    // second on the frames end exactly one loop apart.
    let period = BusDuration::from_micros(LOOP_CYCLES);
    for pair in frames[1..].windows(2) {
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

/// Machine cycles (µs at 12 MHz) from reset to the end of the sender's first `MOVX @DPTR,A` to
/// CMR (TR), counted from the listing with the Intel MCS-51 User's Manual's cycle counts
/// (LJMP, LCALL, RET, MOV direct,#data, MOV DPTR,#data16, MOVX, MOVC, INC DPTR, CJNE, DJNZ: 2;
/// MOV A,#data, MOV Rn,#data, MOV A,Rn, MOV A,@Ri, MOV @Ri,A, INC Rn, INC direct: 1). A
/// register write takes effect at the end of its instruction.
///
/// - `LJMP START`: 2.
/// - `MOV DPH,#0D3H` 2, `MOV R0,#0AAH` 1, `LCALL INITCAN` 2: 5.
/// - INITCAN: MOD, CDR, IER, BTR0, BTR1 (`MOV DPL,#` 2 + `MOV A,#` 1 + `MOVX` 2) 5 × 5 = 25; the
///   read back of BTR1 2; OCR 5; ACR0 (`MOV A,R0`) 5; ACR1 (`INC DPTR` 2 + `MOV A,#` 1 +
///   `MOVX` 2) 5; ACR2, ACR3 (`INC DPTR` + `MOVX`) 4 + 4; AMR0 5, AMR1 5, AMR2 4, AMR3 4; RBSA 5;
///   TXERR, ECC (`MOV DPL,#` + `MOVX`) 4 + 4; MOD 5; `RET` 2: 88.
/// - `MOV DPH,#0D4H` 2, `MOV R0,#0BBH` 1, `LCALL` 2, INITCAN again (into nothing) 88: 93.
/// - `MOV R0,#20H` 1, `MOV R1,#00H` 1, `MOV DPTR,#TXDATA` 2: 4; SS1 eight times (`MOV A,R1` 1,
///   `MOVC` 2, `MOV @R0,A` 1, `INC R0` 1, `INC R1` 1, `CJNE` 2 = 8): 64.
/// - LOOP: `MOV DPH,#0D3H` 2, `MOV R0,#20H` 1, `LCALL SEND` 2: 5.
/// - SEND: FIN 5; ID1, ID2 (`INC DPL` 1 + `MOV A,#` 1 + `MOVX` 2) 4 + 4; `INC DPL` 1;
///   `MOV R2,#08H` 1; SEND1 eight times (`MOV A,@R0` 1, `MOVX` 2, `INC R0` 1, `INC DPL` 1,
///   `DJNZ` 2 = 7) 56; CMR (`MOV DPL,#` 2, `MOV A,#` 1, `MOVX` 2) 5: 76.
///
/// 2 + 5 + 88 + 93 + 4 + 64 + 5 + 76 = 337.
const CYCLES_TO_TR: u64 = 337;

/// The frame's bits from start of frame to the end of end of frame. Unstuffed, SOF 1, the
/// identifier 5DFh 11, RTR, IDE, r0 3, DLC 4, data 64 and the CRC 15 are 98 bits:
///
/// ```text
/// 0 10111011111 000 1000 10101010 10111011 11001100 11010100 11100101 11110110 10010111 00011000
///   110001101100110
/// ```
///
/// (the CRC-15, polynomial 4599h, of the 83 bits before it is 6366h). Five equal bits in a row
/// get a stuff bit: the identifier's last five ones (a 0 after them), and E5h's last one with
/// F6h's first four (a 0 after them); no other run reaches five, the stuff bits included (the
/// first makes four zeros with RTR, IDE and r0). 98 + 2 = 100, and the CRC delimiter, ACK slot,
/// ACK delimiter and 7 bits of end of frame make 110.
const FRAME_BITS: u64 = 110;

/// Machine cycles from reset to the end of the `MOVX` that clears reset mode (MOD = 08h) in the
/// first INITCAN, the sender's chip joining the bus: 2 + 5 + 88 − 2 (INITCAN's `RET` comes
/// after it) = 93. The receiver's chip joins at the same place in the second INITCAN: the first
/// ends at 95, and 95 + 5 + 88 − 2 = 186.
const SENDER_JOINS: u64 = 93;
const RECEIVER_JOINS: u64 = 186;

/// The sender's first frame, with bus integration (ISO 11898-1, docs/CAN.md section 4): a chip
/// leaving reset mode takes part only after 11 recessive bits.
///
/// - The sender's chip joins at 93 µs and has its 11 bits (366.7 µs) at 459.7 µs, after its TR
///   (337 µs): the first attempt starts at 93 µs + 11 bits.
/// - The receiver's chip joins at 186 µs and would have its 11 bits at 552.7 µs: the first
///   attempt's start of frame breaks its count, so it neither receives nor acknowledges that
///   attempt. The sender has an ACK error: the stuffed part is 100 bits, the ACK slot bit 101,
///   its active flag bits 102 to 107, its delimiter 108 to 115, intermission 116 to 118.
/// - The receiver's count starts again after the flag's last dominant bit (108) and ends at 119,
///   the second attempt's start of frame, which it takes part in: acknowledged, the frame ends
///   110 bits later. So the first frame ends at 93 µs + (11 + 119 + 110) bits = 8.093 ms.
/// - The later requests (337 µs + k × 99.916 ms) find the bus idle and both chips on it: those
///   frames end 110 bits after their TR.
#[test]
fn the_first_frame_ends_at_the_senders_start_up_plus_its_length_on_the_bus() {
    let hex = shipped_hex();
    let run = run_firmware(&benches(&hex, &hex, 6_000_000), 1);
    // A bit at 30 kbit/s is 1/30 000 s, 115 200 000 bus-clock ticks (3.456e12 / 30 000).
    let bit = BusDuration::from_ticks(3_456_000_000_000 / 30_000);
    // The receiver is still integrating when the first attempt starts.
    let start = BusDuration::from_micros(SENDER_JOINS) + bit * 11;
    assert!(BusDuration::from_micros(RECEIVER_JOINS) + bit * 11 > start);
    let first = BusTime::ZERO + BusDuration::from_micros(SENDER_JOINS) + bit * (11 + 119 + FRAME_BITS);
    assert_eq!(run.ends.first(), Some(&first), "{}", run.trace);
    // The sender's error line, at its flag's first bit: 93 µs + 113 bits = 3859.7 µs.
    assert!(
        run.trace
            .starts_with("(1704067200.003859) harv0.SENDER 200002A8#"),
        "{}",
        run.trace
    );
    // Every later frame is as long: each ends one loop after the one before.
    let second = BusTime::ZERO + BusDuration::from_micros(CYCLES_TO_TR) + bit * FRAME_BITS;
    let period = BusDuration::from_micros(LOOP_CYCLES);
    for (k, end) in run.ends.iter().enumerate().skip(1) {
        assert_eq!(*end, second + period * k as u64, "frame {k}");
    }
}

/// The optimistic run ahead is deterministic: two runs give the same trace, to the nanosecond,
/// and the same hardware at the end.
#[test]
fn the_lab_runs_the_same_twice() {
    let hex = shipped_hex();
    let b = benches(&hex, &hex, 6_000_000);
    let end = BusTime::from_millis(500);
    let one = run_firmware_specs(bench_specs(&b), end, None);
    let two = run_firmware_specs(bench_specs(&b), end, None);
    assert!(one.ends.len() >= 5, "{}", one.trace);
    assert_eq!(one.ends, two.ends);
    assert_eq!(one.trace, two.trace);
    assert_eq!(one.states, two.states);
}

/// Skipping idle loops and frames the chip would not take changes nothing: the same trace and
/// the same hardware as when the nodes work through every instruction and every frame.
#[test]
fn the_lab_runs_the_same_without_skipping_idle_loops() {
    let hex = shipped_hex();
    let b = benches(&hex, &hex, 6_000_000);
    let end = BusTime::from_millis(500);
    let skipping = run_firmware_specs(bench_specs(&b), end, None);
    let mut specs = bench_specs(&b);
    for s in &mut specs {
        std::sync::Arc::make_mut(s).skip_idle_loops = false;
    }
    let working = run_firmware_specs(specs, end, None);
    assert!(skipping.ends.len() >= 5, "{}", skipping.trace);
    assert_eq!(skipping.ends, working.ends);
    assert_eq!(skipping.trace, working.trace);
    assert_eq!(skipping.states, working.states);
}
