//! Firmware that takes frames in its INT0 interrupt, and firmware that faults: the SJA1000's
//! INT output reaches the CPU only where the node file wires it, and a CPU fault is a crash the
//! hub reports.
//!
//! The programs are written here and assembled with as31. The sender is the lab program of
//! `configs/firmware/`: frames end 4.003 ms into the run and then every 99.916 ms (see
//! `firmware_seed_lab.rs`), so ten have ended by 1 s.

use harvemu_e2e::{assemble, bench_file, root, run_firmware};

/// A receiver at 0000h whose main loop does nothing: an INT0 handler copies each frame's data
/// to 30H–37H, releases the receive buffer and counts frames in R5. `it0` is 0 for a
/// level-triggered INT0, 1 for a falling edge.
fn interrupt_receiver(it0: u8) -> String {
    let trigger = if it0 == 1 { "SETB    88H" } else { "CLR     88H" };
    format!(
        "
        .org    0000H
        LJMP    START
        .org    0003H
        LJMP    ISR0
        .org    0030H
START:  MOV     SP, #60H
        MOV     DPTR, #0D400H
        MOV     A, #09H         ; MOD: reset mode (BasicCAN CR first, as in the lab)
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
        MOV     DPL, #00H       ; MOD: operating mode, single filter
        MOV     A, #08H
        MOVX    @DPTR, A
        MOV     R5, #00H
        {trigger}               ; IT0
        SETB    0A8H            ; EX0
        SETB    0AFH            ; EA
IDLE:   SJMP    IDLE
ISR0:   PUSH    ACC
        PUSH    DPL
        PUSH    DPH
        MOV     DPTR, #0D403H   ; IR: reading it clears all but RI
        MOVX    A, @DPTR
        MOV     DPTR, #0D413H   ; first data byte of a standard frame
        MOV     R0, #30H
        MOV     R2, #08H
COPY:   MOVX    A, @DPTR
        MOV     @R0, A
        INC     R0
        INC     DPTR
        DJNZ    R2, COPY
        MOV     DPTR, #0D401H   ; CMR: release the receive buffer
        MOV     A, #04H
        MOVX    @DPTR, A
        INC     R5
        POP     DPH
        POP     DPL
        POP     ACC
        RETI
"
    )
}

fn lab_sender() -> (String, String) {
    let hex = std::fs::read_to_string(root().join("configs/firmware/can_seed.hex")).expect("HEX");
    (bench_file("SENDER", 0x4000, 0xD300, 6_000_000, "None"), hex)
}

const DATA: [u8; 8] = [0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18];

#[test]
fn frames_reach_an_int0_handler_level_or_edge_triggered() {
    for it0 in [0, 1] {
        let receiver = (
            bench_file("RECEIVER", 0, 0xD400, 6_000_000, "Some(Int0)"),
            assemble(&interrupt_receiver(it0)),
        );
        let run = run_firmware(&[lab_sender(), receiver], 1);
        assert!(run.crashed.is_empty(), "{:?}", run.crashed);
        assert_eq!(run.iram(1, 0x30, 8), DATA, "IT0 = {it0}: 30H-37H");
        assert_eq!(run.iram(1, 0x05, 1), [10], "IT0 = {it0}: frames counted in R5");
    }
}

#[test]
fn an_unwired_int_output_interrupts_nothing() {
    let receiver = (
        bench_file("RECEIVER", 0, 0xD400, 6_000_000, "None"),
        assemble(&interrupt_receiver(0)),
    );
    let run = run_firmware(&[lab_sender(), receiver], 1);
    assert_eq!(run.iram(1, 0x05, 1), [0], "frames counted in R5");
    assert_eq!(run.iram(1, 0x30, 8), [0; 8], "30H-37H");
}

#[test]
fn a_reserved_opcode_and_a_runaway_stack_are_crashes() {
    let reserved = "
        .org    0000H
        MOV     A, #12H
        NOP
        .byte   0A5H
        SJMP    0000H
";
    // Calls itself for ever: SP climbs from 07h by 2 a call until a push would pass 7Fh.
    let runaway = "
        .org    0000H
AGAIN:  LCALL   AGAIN
";
    for (program, what) in [
        (reserved, "reserved opcode A5h at PC 0003h"),
        (runaway, "stack overflow"),
    ] {
        let node = (bench_file("BAD", 0, 0xD400, 6_000_000, "None"), assemble(program));
        let run = run_firmware(&[lab_sender(), node], 1);
        assert_eq!(run.crashed.len(), 1, "{:?}", run.crashed);
        let (index, why) = &run.crashed[0];
        assert_eq!(*index, 1);
        assert!(why.contains("BAD") && why.contains(what), "{why}");
    }
}
