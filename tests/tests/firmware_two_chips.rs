//! A firmware node with two SJA1000s on one bus, their INT outputs both wired to INT0 (open
//! drain, so the pin is low while either chip holds its INT active), taking the lab sender's
//! frames in one interrupt handler; and the lab program on one board with both its chips.
//!
//! The receiver is written here and assembled with as31: an 80C51 at 12 MHz with chips at D300h
//! and D400h (6 MHz crystals, 30 kbit/s, PeliCAN, acceptance code BBh on ID10..3, receive
//! interrupt only), INT0 level-triggered. Each entry of the handler services one chip only, the
//! D400h chip first when both have a frame, and returns: the other chip, still holding INT0 low,
//! brings the CPU straight back. It counts entries at 40H, frames taken from the D300h chip at
//! 41H and from the D400h chip at 42H, entries that found neither at 43H, and copies each chip's
//! last data bytes to 50H–57H (D300h) and 58H–5FH (D400h).
//!
//! Expectations come from the lab sender (`configs/firmware/can_seed.asm`, see
//! `firmware_seed_lab.rs`): it sends ID 5DFh (ID10..3 = BBh) with the data below, the first
//! frame ending 8.093 ms into the run (its first attempt, at 0.4597 ms, comes before any other
//! chip has integrated into the bus, so nobody acknowledges it), the later ones 4.003 ms +
//! k × 99.916 ms, so ten by 1 s (and an eleventh that started before 1 s, which the bus completes
//! after it), each retransmitted until it is acknowledged. This receiver's chips leave reset
//! mode at 204 µs and 277 µs (cycles from the listing below: `LJMP` 2, `MOV SP` 2, `MOV R0` 1,
//! `CLEAR` 32 × 4, `MOV DPH`, `MOV R7`, `LCALL` 5, then INIT's writes 66 up to its last `MOVX`;
//! the second chip 2 + 5 + 66 later), so they take part from 570.7 µs and 643.7 µs on: after
//! the first attempt started, in time for the second.
//! Both chips accept every one of them: by 1 s each has taken ten, so the handler was entered
//! twenty times. A chip in listen-only mode (MOD.LOM) receives but never acknowledges (SJA1000
//! data sheet, MOD register). A frame nobody acknowledges is an acknowledgement error for its
//! transmitter (ISO 11898-1): while error active it adds 8 to its transmit error counter and
//! destroys the frame for the receivers with an active error flag; after 16 attempts (TEC 128)
//! it is error passive, its ACK errors leave TEC at 128 (fault confinement, exception to rule 3)
//! and its passive error flag is recessive, so the receivers take each further attempt as a good
//! frame, again and again.

use bus::fault::ErrorState;
use harvemu_e2e::{FirmwareRun, assemble, bench_file, parse_trace, root, run_firmware};

const DATA: [u8; 8] = [0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18];
/// MOD for operating mode with the single acceptance filter, and the same listening only.
const NORMAL: u8 = 0x08;
const LISTEN_ONLY: u8 = 0x0A;

/// The two-chip receiver, its D300h chip in mode `mod1`, its D400h chip in `mod2`.
fn receiver(mod1: u8, mod2: u8) -> String {
    format!(
        "
        .org    0000H
        LJMP    START
        .org    0003H
        LJMP    ISR0
        .org    0030H
START:  MOV     SP, #60H
        MOV     R0, #40H
CLEAR:  MOV     @R0, #00H
        INC     R0
        CJNE    R0, #60H, CLEAR
        MOV     DPH, #0D3H
        MOV     R7, #{mod1}
        LCALL   INIT
        MOV     DPH, #0D4H
        MOV     R7, #{mod2}
        LCALL   INIT
        CLR     88H             ; IT0 = 0: INT0 level-triggered
        SETB    0A8H            ; EX0
        SETB    0AFH            ; EA
IDLE:   SJMP    IDLE

; Sets up the chip whose page DPH holds; R7 is its operating MOD value.
INIT:   MOV     DPL, #00H       ; MOD: reset mode
        MOV     A, #09H
        MOVX    @DPTR, A
        MOV     DPL, #1FH       ; CDR: PeliCAN
        MOV     A, #88H
        MOVX    @DPTR, A
        MOV     DPL, #04H       ; IER: receive interrupt only
        MOV     A, #01H
        MOVX    @DPTR, A
        MOV     DPL, #06H       ; BTR0, BTR1: 30 kbit/s at 6 MHz
        MOV     A, #03H
        MOVX    @DPTR, A
        INC     DPTR
        MOV     A, #0FFH
        MOVX    @DPTR, A
        MOV     DPL, #10H       ; ACR0 BBh, ACR1-3 FFh, AMR0 00h, AMR1-3 FFh
        MOV     A, #0BBH
        MOVX    @DPTR, A
        MOV     A, #0FFH
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        CLR     A
        MOVX    @DPTR, A
        MOV     A, #0FFH
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        MOV     DPL, #00H       ; MOD: out of reset mode
        MOV     A, R7
        MOVX    @DPTR, A
        RET

ISR0:   PUSH    ACC
        PUSH    DPL
        PUSH    DPH
        INC     40H
        MOV     DPTR, #0D403H   ; IR of the D400h chip: RI?
        MOVX    A, @DPTR
        JB      0E0H, CHIP2
        MOV     DPTR, #0D303H   ; IR of the D300h chip: RI?
        MOVX    A, @DPTR
        JB      0E0H, CHIP1
        INC     43H
        SJMP    DONE
CHIP2:  MOV     R0, #58H
        LCALL   TAKE
        INC     42H
        SJMP    DONE
CHIP1:  MOV     R0, #50H
        LCALL   TAKE
        INC     41H
DONE:   POP     DPH
        POP     DPL
        POP     ACC
        RETI

; Copies the data of the frame in the receive buffer of the chip whose page DPH holds to @R0,
; and releases the buffer.
TAKE:   MOV     DPL, #13H       ; first data byte of a standard frame
        MOV     R2, #08H
COPY:   MOVX    A, @DPTR
        MOV     @R0, A
        INC     R0
        INC     DPTR
        DJNZ    R2, COPY
        MOV     DPL, #01H       ; CMR: release the receive buffer
        MOV     A, #04H
        MOVX    @DPTR, A
        RET
"
    )
}

/// The two-chip node: both INT outputs on INT0.
fn receiver_file() -> String {
    "Firmware(name: \"TWIN\", image: \"lab.hex\", entry: Some(0), \
     cpu: I80C51(clock_hz: 12000000), \
     controllers: [\
        Sja1000(base: 0xD300, xtal_hz: 6000000, irq: Some(Int0)), \
        Sja1000(base: 0xD400, xtal_hz: 6000000, irq: Some(Int0))])"
        .to_string()
}

/// The lab sender and the two-chip receiver with its chips in modes `mod1` and `mod2`, for 1 s.
fn lab(mod1: u8, mod2: u8) -> FirmwareRun {
    let sender = std::fs::read_to_string(root().join("configs/firmware/can_seed.hex")).expect("HEX");
    let run = run_firmware(
        &[
            (bench_file("SENDER", 0x4000, 0xD300, 6_000_000, "None"), sender),
            (receiver_file(), assemble(&receiver(mod1, mod2))),
        ],
        1,
    );
    assert!(run.crashed.is_empty(), "{:?}", run.crashed);
    run
}

#[test]
fn both_chips_take_every_frame_through_one_shared_int0() {
    let run = lab(NORMAL, NORMAL);
    assert_eq!(run.iram(1, 0x41, 2), [10, 10], "frames taken from D300h, D400h");
    assert_eq!(run.iram(1, 0x40, 1), [20], "handler entries: one a chip a frame");
    assert_eq!(
        run.iram(1, 0x43, 1),
        [0],
        "entries that found no chip with a frame"
    );
    assert_eq!(run.iram(1, 0x50, 8), DATA, "D300h's data");
    assert_eq!(run.iram(1, 0x58, 8), DATA, "D400h's data");
    // The hub sees two controllers of the node, each with every frame, the eleventh too.
    let twin = &run.controllers[1];
    let names: Vec<&str> = twin.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["TWIN", "TWIN.1"]);
    for c in twin {
        assert_eq!(
            (c.counters.rx_frames, c.counters.tx_frames),
            (11, 0),
            "{}",
            c.name
        );
    }
    let frames = parse_trace(&run.trace);
    assert_eq!(frames.len(), 11, "{}", run.trace);
    for f in &frames {
        assert_eq!((f.frame.raw_id(), f.frame.data()), (0x5DF, &DATA[..]));
    }
    // The dump lists both chips, each at its base.
    let state = run.states[1].as_ref().expect("the node's hardware");
    let bases: Vec<u16> = state.controllers.iter().map(|c| c.base).collect();
    assert_eq!(bases, [0xD300, 0xD400]);
}

#[test]
fn each_chip_acknowledges_by_itself() {
    // Either chip alone acknowledging is enough: every frame but the very first goes through at
    // its first attempt (the first has one ACK error, TEC 8, which the eleven frames bring back
    // to 0), and both chips take it.
    for (mod1, mod2) in [(NORMAL, LISTEN_ONLY), (LISTEN_ONLY, NORMAL)] {
        let run = lab(mod1, mod2);
        let sender = &run.controllers[0][0];
        assert_eq!(
            (sender.tec, sender.counters.tx_frames),
            (0, 11),
            "MOD {mod1:02X}h, {mod2:02X}h"
        );
        assert_eq!(run.iram(1, 0x41, 2), [10, 10], "MOD {mod1:02X}h, {mod2:02X}h");
    }
    // Neither acknowledging: no attempt succeeds for the sender, which ends error passive at
    // 128; both chips saw attempts 2 to 16 destroyed (15; the first came before they had
    // integrated), and take the later ones alike.
    let run = lab(LISTEN_ONLY, LISTEN_ONLY);
    let sender = &run.controllers[0][0];
    assert_eq!(sender.counters.tx_frames, 0);
    assert_eq!((sender.tec, sender.state), (128, ErrorState::Passive));
    let twin = &run.controllers[1];
    for c in twin {
        assert_eq!(c.counters.rx_errors, 15, "{}", c.name);
        assert!(c.counters.rx_frames > 0, "{}", c.name);
    }
    assert_eq!(twin[0].counters.rx_frames, twin[1].counters.rx_frames);
    let counts = run.iram(1, 0x40, 4);
    let (entries, d300, d400, idle) = (counts[0], counts[1], counts[2], counts[3]);
    assert!(d300 > 0 && d300 == d400, "{counts:?}");
    // The counters are bytes: the entries may have wrapped past FFh.
    assert_eq!((entries, idle), (d300.wrapping_add(d400), 0), "{counts:?}");
}

/// The lab program as CAN.ASM was written, for one board with both chips: CAN1 at D300h sends,
/// CAN2 at D400h (acceptance code BBh) receives, and nothing else is on the bus. CAN2
/// acknowledges CAN1's frames and takes every one, as a chip of another node would; CAN1 never
/// receives its own frames, even with its acceptance code made BBh so that its filter passes
/// them (SJA1000 data sheet: only a self reception request, CMR.SRR, stores a chip's own frame).
#[test]
fn one_board_with_both_lab_chips_talks_to_itself() {
    let source = std::fs::read_to_string(root().join("configs/firmware/can_seed.asm")).expect("source");
    let own_code = source.replacen("#0AAH", "#0BBH", 1);
    assert_ne!(own_code, source, "CAN1's acceptance code AAh is in the source");
    let shipped = std::fs::read_to_string(root().join("configs/firmware/can_seed.hex")).expect("HEX");
    let board = "Firmware(name: \"BOARD\", image: \"lab.hex\", entry: Some(0x4000), \
                 cpu: I80C51(clock_hz: 12000000), \
                 controllers: [\
                    Sja1000(base: 0xD300, xtal_hz: 6000000, irq: None), \
                    Sja1000(base: 0xD400, xtal_hz: 6000000, irq: None)])";
    for (hex, what) in [(shipped, "AAh"), (assemble(&own_code), "BBh")] {
        let run = run_firmware(&[(board.to_string(), hex)], 1);
        assert!(run.crashed.is_empty(), "{:?}", run.crashed);
        assert_eq!(run.iram(0, 0x30, 8), DATA, "CAN1 code {what}: 30H-37H");
        let frames = parse_trace(&run.trace);
        assert!(!frames.is_empty(), "CAN1 code {what}: {}", run.trace);
        for f in &frames {
            assert_eq!((f.frame.raw_id(), f.frame.data()), (0x5DF, &DATA[..]));
        }
        let n = frames.len() as u64;
        let (can1, can2) = (&run.controllers[0][0], &run.controllers[0][1]);
        assert_eq!(
            (can1.counters.tx_frames, can1.counters.rx_frames),
            (n, 0),
            "CAN1 code {what}"
        );
        assert_eq!(
            (can2.counters.tx_frames, can2.counters.rx_frames),
            (0, n),
            "CAN1 code {what}"
        );
        // RMC (register 29) counts the messages in CAN1's receive FIFO: none.
        let state = run.states[0].as_ref().expect("the board's hardware");
        let registers = &state.controllers[0].registers;
        assert_eq!(&registers[58..60], "00", "CAN1 code {what}: RMC");
    }
}
