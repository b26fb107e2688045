//! Bus off and recovery as the SJA1000 data sheet has it, seen by firmware through the chip's
//! registers: at bus off the chip enters reset mode with TXERR 127 and RXERR 0, and stays there
//! until the firmware clears MOD.RM; then TXERR counts down with each of the 128 sequences of 11
//! recessive bits, and the chip is error active again with TXERR 0.
//!
//! The firmware is the lab's sender, changed to poll its own chip (D300h) instead of the
//! receiver's: its receive routine's bus-off path reads IR and writes MOD = 08h, which clears
//! reset mode. Frames end 4.003 ms into the run and then every 99.916 ms, one loop of the program
//! apart; its poll comes about 99.8 ms after each request, at the end of the loop.

use bus::time::BusTime;
use harvemu_e2e::{BitErrorsOf, assemble, bench_file, root, run_firmware_with};

/// The sender polling its own chip, and the lab's receiver.
fn benches() -> Vec<(String, String)> {
    let source = std::fs::read_to_string(root().join("configs/firmware/can_seed.asm")).expect("asm");
    // Before `LCALL RECV`, the program points DPH at the receiver's chip (D4H).
    let own = source.replacen("MOV     DPH, #0D4H", "MOV     DPH, #0D3H", 2);
    assert_ne!(own, source);
    let shipped = std::fs::read_to_string(root().join("configs/firmware/can_seed.hex")).expect("HEX");
    vec![
        (
            bench_file("SENDER", 0x4000, 0xD300, 6_000_000, "None"),
            assemble(&own),
        ),
        (bench_file("RECEIVER", 0x4000, 0xD400, 6_000_000, "None"), shipped),
    ]
}

/// The sender's chip at `t` (ms): TXERR, RXERR, its state, and MOD.
fn sender_at(t_ms: u64) -> (u16, u16, String, u8) {
    // Every frame of the sender is corrupted from 0.55 s to 0.7 s: the frame requested at
    // about 0.5996 s fails 32 times in a row (each attempt a few dozen bits at 30 kbit/s).
    let fault = BitErrorsOf {
        node: 0,
        from: BusTime::from_millis(550),
        to: BusTime::from_millis(700),
    };
    let run = run_firmware_with(&benches(), BusTime::from_millis(t_ms), Some(fault));
    let chip = run.states[0].as_ref().expect("the sender's state").controllers[0].clone();
    let registers = u8::from_str_radix(&chip.registers[0..2], 16).expect("hex");
    (chip.tec, chip.rec, chip.state, registers)
}

#[test]
fn the_firmware_restarts_its_chip_and_txerr_counts_the_recovery_down() {
    // From 0.6 s every frame of the sender fails; error passive, it waits out suspend
    // transmission after each, and goes bus off shortly before its poll at about 0.6994 s.
    // Sampled every millisecond from 0.69 s to 0.76 s:
    let samples: Vec<(u64, u16, String, u8)> = (690..=760)
        .map(|t| {
            let (tec, _, state, mode) = sender_at(t);
            (t, tec, state, mode)
        })
        .collect();
    let rm = |mode: u8| mode & 0x01 == 0x01;
    // Bus off, the chip waits in reset mode with TXERR 127 until the firmware's poll.
    let waiting: Vec<_> = samples
        .iter()
        .filter(|(_, _, state, mode)| state == "bus-off" && rm(*mode))
        .collect();
    assert!(!waiting.is_empty(), "{samples:?}");
    assert!(waiting.iter().all(|(_, tec, _, _)| *tec == 127), "{samples:?}");
    // Then, with MOD.RM cleared, TXERR counts the sequences down: a sequence is 11 bits of
    // 33.3 µs, so a millisecond takes 2 or 3 of them.
    let recovering: Vec<u16> = samples
        .iter()
        .filter(|(_, _, state, mode)| state == "bus-off" && !rm(*mode))
        .map(|(_, tec, _, _)| *tec)
        .collect();
    assert!(recovering.len() >= 40, "{samples:?}");
    assert!(recovering.iter().all(|&tec| tec < 127), "{recovering:?}");
    for pair in recovering.windows(2) {
        assert!((2..=3).contains(&(pair[0] - pair[1])), "{recovering:?}");
    }
    // 1408 bits (46.9 ms) after the poll it is error active with TXERR 0, in operating mode.
    let (_, tec, state, mode) = samples.last().cloned().expect("samples");
    assert_eq!((tec, state.as_str(), rm(mode)), (0, "active", false));
}
