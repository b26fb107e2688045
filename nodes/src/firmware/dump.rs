//! A machine's state as `harvemu run --dump-state` writes it.

use super::machine::{Chip, Machine};
use bus::fault::ErrorState;
use bus::node::{ChipState, CpuState, HardwareState};
use bus::sja1000::Mode;

/// Bytes as upper-case hex, two digits each, nothing between.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect()
}

/// The dump of `m`.
pub(crate) fn state(m: &Machine) -> HardwareState {
    let controllers = m.board.chips.iter().map(chip).collect();
    HardwareState {
        cpu: CpuState {
            pc: m.cpu.pc(),
            cycles: m.cpu.cycles(),
            iram: hex(&m.cpu.iram()),
            sfr: hex(&m.cpu.sfr()),
        },
        controllers,
    }
}

fn chip(c: &Chip) -> ChipState {
    let (kind, base, mode, registers, (tec, rec, state)) = match c {
        Chip::Sja { base, sja, .. } => {
            let registers: Vec<u8> = (0..32).map(|r| sja.peek(r)).collect();
            let mode = match sja.mode() {
                Mode::BasicCan => "BasicCAN",
                Mode::PeliCan => "PeliCAN",
            };
            ("SJA1000", *base, mode, registers, sja.error_counters())
        }
        // The SFRs 80h–FFh as the CPU would read them (00 where the controller has none).
        Chip::OnChip(can) => {
            let registers: Vec<u8> = (0x80..=0xFF).map(|a| can.sfr_peek(a).unwrap_or(0)).collect();
            ("AT89C51CC03", 0, "on chip", registers, can.error_counters())
        }
    };
    ChipState {
        kind: kind.into(),
        base,
        mode: mode.into(),
        registers: hex(&registers),
        tec,
        rec,
        state: match state {
            ErrorState::Active => "active",
            ErrorState::Passive => "passive",
            ErrorState::BusOff => "bus-off",
        }
        .into(),
    }
}
