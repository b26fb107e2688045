//! External data memory of a firmware node: an address nothing decodes reads FFh and takes no
//! write (an open bus with pull-ups, as on the seed's board); an SJA1000 decodes exactly its
//! page: the 256 addresses its 8-bit multiplexed address bus takes from its base. Expectations from the SJA1000 data sheet: after a hardware reset the chip is
//! in BasicCAN mode with the control register's reset request set (bit 0) and its bit 5, reserved,
//! reading 1: 21h.

use harvemu_e2e::{assemble, bench_file, run_firmware};

const PROGRAM: &str = "
        .org    0000H
        MOV     DPTR, #1234H     ; nothing decodes 1234H
        MOVX    A, @DPTR
        MOV     30H, A
        MOV     A, #5AH          ; a write there goes nowhere
        MOVX    @DPTR, A
        CLR     A
        MOVX    A, @DPTR
        MOV     31H, A
        MOV     DPTR, #0D3FFH    ; the byte below the chip's window
        MOVX    A, @DPTR
        MOV     32H, A
        MOV     DPTR, #0D500H    ; the byte above it
        MOVX    A, @DPTR
        MOV     33H, A
        MOV     DPTR, #0D400H    ; the chip's control register
        MOVX    A, @DPTR
        MOV     34H, A
IDLE:   SJMP    IDLE
";

#[test]
fn movx_reads_ffh_where_nothing_decodes_and_the_chip_answers_in_its_window() {
    let benches = [(
        bench_file("PROBE", 0, 0xD400, 6_000_000, "None"),
        assemble(PROGRAM),
    )];
    let run = run_firmware(&benches, 1);
    assert!(run.crashed.is_empty(), "{:?}", run.crashed);
    assert_eq!(run.iram(0, 0x30, 5), [0xFF, 0xFF, 0xFF, 0xFF, 0x21]);
}
