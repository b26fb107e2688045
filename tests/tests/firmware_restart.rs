//! A firmware node that crashes by itself is restarted by the supervisor under the restart
//! policy, as a scripted node is, and runs again from reset: the seed lab with a sender whose
//! program meets a reserved opcode (A5h) after its first pass of the loop.
//!
//! Expectations from the listing's cycle counts (Intel MCS-51 User's Manual; worked out in
//! `firmware_seed_lab.rs`), the frame's bit count at 30 kbit/s and the restart policy (3 restarts
//! within 60 s, 100 ms after each crash).

use bus::time::{BusDuration, BusTime};
use harvemu_e2e::{assemble, drive, firmware_spec, parse_trace, root};
use supervisor::harvester::{Happened, Harvester, SupervisorEvent};

/// Reset to the end of the write that takes the sender's chip out of reset mode, machine cycles
/// of 1 µs (`firmware_seed_lab.rs` counts them from the listing).
const SENDER_JOINS: u64 = 93;
/// The lab frame from start of frame to the end of end of frame.
const FRAME_BITS: u64 = 110;
/// Reset to the reserved opcode put in place of the loop's `NOP`: the write of TR ends at 337;
/// `RET` 2, `LCALL DELAY` 2, DELAY 99 803 (its comment in the listing), `MOV DPH,#` 2,
/// `MOV R0,#` 1, `LCALL RECV` 2; RECV on the sending bench (SR reads FFh, the bus-off path):
/// `MOV DPL,#` 2, `MOVX` 2, `ANL A,#` 1, `JNZ` 2, `JNB` 2, `MOV DPL,#` 2, `MOVX` 2,
/// `MOV DPL,#` 2, `MOV A,#` 1, `MOVX` 2, `RET` 2 = 20. 337 + 2 + 2 + 99 803 + 5 + 20 = 100 169.
/// The core spends the machine cycle that fetches A5h and stops at its end (`mcs51`'s choice:
/// the part's behaviour is undefined): the crash is at 100 170.
const CYCLES_TO_CRASH: u64 = 100_169 + 1;
const BACKOFF_MS: u64 = 100;

/// The seed lab whose sender runs `hex`, with the default restart policy spelt out.
fn lab(hex: &str) -> Harvester {
    let mut h = Harvester::load(&root().join("configs/firmware/seed_lab.ron")).expect("the lab");
    let text = "Firmware(name: \"SENDER\", image: \"crash.hex\", entry: Some(0x4000), \
                cpu: I80C51(clock_hz: 12000000), \
                controllers: [Sja1000(base: 0xD300, xtal_hz: 6000000, irq: None)])";
    let at = h
        .firmware
        .iter()
        .position(|f| f.name == "SENDER")
        .expect("SENDER");
    h.firmware[at] = firmware_spec("sender.ron", text, "crash.hex", hex);
    h.config.network.restart.max_restarts = 3;
    h.config.network.restart.window_s = 60.0;
    h.config.network.restart.backoff_ms = BACKOFF_MS;
    h
}

/// The lab with the sender's loop `NOP` replaced by `instead`, run for 2 s: the supervisor's
/// events about the sender, every frame's end (µs), and the hardware at the end.
fn crash_loop(
    instead: &str,
) -> (
    Vec<SupervisorEvent>,
    Vec<u64>,
    Vec<(String, bus::node::HardwareState)>,
) {
    let source = std::fs::read_to_string(root().join("configs/firmware/can_seed.asm")).expect("asm");
    let patched = source.replacen("        NOP                     ; breakpoint here", instead, 1);
    assert_ne!(patched, source, "the NOP is in the source");
    let end = BusTime::from_secs(2);
    let (trace, (events, hw)) = drive(lab(&assemble(&patched)), async move |running| {
        running.run_until(end).await.expect("run");
        let hw = running.hardware(end).await;
        (running.events.clone(), hw)
    });
    let frames = parse_trace(&trace);
    let ends = frames.iter().map(|f| f.at.as_micros()).collect();
    let of_sender = events.into_iter().filter(|e| e.node == "SENDER").collect();
    (of_sender, ends, hw)
}

/// Three restarts within the window, then the fourth crash is one too many.
fn assert_restarted_three_times(events: &[SupervisorEvent]) {
    let texts: Vec<String> = events.iter().map(|e| e.what.to_string()).collect();
    let kinds: Vec<&str> = texts
        .iter()
        .map(|t| t.split(':').next().unwrap_or_default())
        .collect();
    assert_eq!(
        kinds,
        [
            "crashed",
            "restarted",
            "crashed",
            "restarted",
            "crashed",
            "restarted",
            "crashed",
            "gave up after 3 restarts in 60 s"
        ],
        "{events:#?}"
    );
}

#[test]
fn a_crashing_firmware_node_is_restarted_from_reset_until_the_policy_gives_up() {
    let (of_sender, ends, hw) = crash_loop("        .byte   0A5H            ; a reserved opcode");
    assert_restarted_three_times(&of_sender);
    assert!(
        of_sender[0].what.to_string().contains("A5"),
        "the crash names the opcode: {}",
        of_sender[0].what
    );
    // Each life: power on (at 0, then at each restart), the crash 100 170 µs later, the restart
    // 100 ms after that; each life sends its frame. The sender's chip leaves reset mode 93 µs
    // after power on and takes part 11 bits later (bus integration), after its TR (337 µs): in
    // the first life the receiver, which joined at 186 µs, is still integrating then, so the
    // first attempt has an ACK error and the frame ends 93 µs + (11 + 119 + 110) bits after power
    // on (`firmware_seed_lab.rs`); in the later lives the receiver is on the bus, and the frame
    // ends 93 µs + (11 + 110) bits after power on.
    let life = BusDuration::from_micros(CYCLES_TO_CRASH) + BusDuration::from_millis(BACKOFF_MS);
    let bit = BusDuration::from_ticks(3_456_000_000_000 / 30_000);
    for (k, pair) in of_sender.chunks(2).enumerate() {
        let power_on = BusTime::ZERO + life * k as u64;
        assert_eq!(
            pair[0].at,
            power_on + BusDuration::from_micros(CYCLES_TO_CRASH),
            "crash {k}"
        );
        if pair[1].what == Happened::Restarted {
            assert_eq!(pair[1].at, power_on + life, "restart {k}");
        }
    }
    let expected: Vec<u64> = (0..4u64)
        .map(|k| {
            let bits = if k == 0 {
                11 + 119 + FRAME_BITS
            } else {
                11 + FRAME_BITS
            };
            (BusTime::ZERO + life * k + BusDuration::from_micros(SENDER_JOINS) + bit * bits).as_micros()
        })
        .collect();
    assert_eq!(ends, expected, "one frame a life, four lives");
    // The sender's last life ran from reset to its crash and stopped there; the receiver runs
    // on and stored the frame.
    let names: Vec<&str> = hw.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["SENDER", "RECEIVER"]);
    assert_eq!(hw[0].1.cpu.cycles, CYCLES_TO_CRASH);
    assert_eq!(&hw[1].1.cpu.iram[0x60..0x70], "AABBCCD4E5F69718");
}

/// A subroutine that calls itself runs the stack past internal RAM (7Fh on the 80C51): a crash
/// too, restarted in the same way; each life sends its frame before it.
#[test]
fn a_stack_overflow_is_a_crash_the_supervisor_restarts() {
    let (of_sender, ends, _) = crash_loop("DEEP:   LCALL   DEEP            ; calls itself for ever");
    assert_restarted_three_times(&of_sender);
    assert!(
        of_sender[0].what.to_string().contains("stack"),
        "the crash says what: {}",
        of_sender[0].what
    );
    // The program reaches the NOP's place at cycle 100 169 (as in the test above), with SP =
    // 07h: 60 calls of 2 cycles and 2 bytes fill 08h-7Fh, and the 61st pushes past it, 120 to
    // 122 cycles later as the core counts the failing LCALL's cycles.
    let crash = of_sender[0].at.as_micros();
    assert!((100_169 + 120..=100_169 + 122).contains(&crash), "{crash} µs");
    assert_eq!(ends.len(), 4, "{ends:?}");
}
