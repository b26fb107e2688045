//! The firmware CPU alone: how many 80C51 machine cycles one core emulates per second while the
//! CPU is busy (no idle loop to skip, no bus).

use serde::Serialize;
use std::time::Instant;

/// A busy loop, hand-assembled (Intel MCS-51 User's Manual, instruction set):
///
/// ```text
/// 0000  74 00     MOV  A,#00H        1 cycle
/// 0002  24 03     ADD  A,#03H        1
/// 0004  F8        MOV  R0,A          1
/// 0005  A3        INC  DPTR          2
/// 0006  93        MOVC A,@A+DPTR     2
/// 0007  B4 05 F8  CJNE A,#05H,0002H  2
/// 000A  80 F6     SJMP 0002H         2
/// ```
///
/// Code beyond the loop reads FFh, so MOVC never gives 05h: CJNE jumps back to ADD every time
/// (SJMP is never reached) and the loop is 1 + 1 + 2 + 2 + 2 = 8 cycles a turn, with nothing for
/// idle skipping to find.
const BUSY: [u8; 12] = [
    0x74, 0x00, 0x24, 0x03, 0xF8, 0xA3, 0x93, 0xB4, 0x05, 0xF8, 0x80, 0xF6,
];

/// One measurement of the CPU alone.
#[derive(Serialize, Debug, Clone)]
pub struct CpuMeasurement {
    /// "firmware-cpu".
    pub scenario: String,
    /// Machine cycles emulated.
    pub cycles: u64,
    /// Wall-clock seconds.
    pub wall_seconds: f64,
    /// Machine cycles per wall second.
    pub cycles_per_second: f64,
    /// How many 12 MHz 80C51s (a million machine cycles a second each) one core keeps up with.
    pub chips_at_12_mhz: f64,
}

/// The busy loop as a 64 KB code memory.
fn image() -> mcs51::Image {
    let mut code = BUSY.to_vec();
    code.resize(0x10000, 0xFF);
    let written = std::iter::once(0..BUSY.len() as u32).collect();
    mcs51::Image { code, written }
}

/// Runs the busy loop for `cycles` machine cycles on this thread.
pub fn measure(cycles: u64) -> Result<CpuMeasurement, String> {
    let mut cpu = mcs51::Cpu::new(mcs51::Variant::I8051, &image());
    let started = Instant::now();
    while cpu.cycles() < cycles {
        cpu.run(&mut mcs51::NoXdata, cycles).map_err(|e| e.to_string())?;
    }
    let wall = started.elapsed().as_secs_f64();
    let rate = cpu.cycles() as f64 / wall;
    Ok(CpuMeasurement {
        scenario: "firmware-cpu".into(),
        cycles: cpu.cycles(),
        wall_seconds: wall,
        cycles_per_second: rate,
        chips_at_12_mhz: rate / 1e6,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_busy_loop_takes_eight_cycles_a_turn_and_skips_nothing() {
        // MOV A,#00H (1 cycle), then turns of 8 cycles: 1 + 8 * 1000 after 1000 turns.
        let m = measure(1 + 8 * 1000).unwrap();
        assert_eq!(m.cycles, 8001);
        let mut cpu = mcs51::Cpu::new(mcs51::Variant::I8051, &image());
        cpu.run(&mut mcs51::NoXdata, 8001).unwrap();
        assert_eq!(cpu.skipped_cycles(), 0);
        // One INC DPTR a turn, and back at ADD (0002h): DPL is SFR 82h, DPH 83h.
        let sfr = cpu.sfr();
        assert_eq!(u16::from(sfr[3]) << 8 | u16::from(sfr[2]), 1000);
        assert_eq!(cpu.pc(), 0x0002);
        // MOVC replaces A each turn; from the 11th turn on, A + DPTR points past the loop, where
        // code reads FFh, so each turn begins with A = FFh and leaves R0 = FFh + 3 = 02h.
        assert_eq!(cpu.iram()[0], 0x02);
    }
}
