//! Firmware that takes frames in its INT0 interrupt, and firmware that faults: the SJA1000's
//! INT output reaches the CPU only where the node file wires it, and a CPU fault is a crash the
//! hub reports.
//!
//! The receiver is `configs/firmware/irq_receiver.asm`; the faulty programs are written here and
//! assembled with as31. The sender is the lab program of
//! `configs/firmware/`: frames end 4.003 ms into the run and then every 99.916 ms (see
//! `firmware_seed_lab.rs`), so ten have ended by 1 s.

use harvemu_e2e::{assemble, bench_file, root, run_firmware};

/// The shipped interrupt-driven receiver (`configs/firmware/irq_receiver.asm`): its main loop
/// does nothing; an INT0 handler copies each frame's data to 30H–37H, releases the receive
/// buffer and counts frames in R5. `it0` is 0 for a level-triggered INT0 (as shipped), 1 for a
/// falling edge.
fn interrupt_receiver(it0: u8) -> String {
    let source = std::fs::read_to_string(root().join("configs/firmware/irq_receiver.asm")).expect("source");
    if it0 == 0 {
        return std::fs::read_to_string(root().join("configs/firmware/irq_receiver.hex")).expect("HEX");
    }
    let edge = source.replacen("CLR     88H", "SETB    88H", 1);
    assert_ne!(edge, source, "the IT0 line is in the source");
    assemble(&edge)
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
            interrupt_receiver(it0),
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
        interrupt_receiver(0),
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
