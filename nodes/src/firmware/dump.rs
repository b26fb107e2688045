//! A machine's state as `harvemu run --dump-state` writes it.

use super::machine::Machine;
use bus::fault::ErrorState;
use bus::node::{ChipState, CpuState, HardwareState};
use bus::sja1000::Mode;

/// Bytes as upper-case hex, two digits each, nothing between.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect()
}

/// The dump of `m`.
pub(crate) fn state(m: &Machine) -> HardwareState {
    let controllers = m
        .board
        .chips
        .iter()
        .map(|c| {
            let registers: Vec<u8> = (0..32).map(|r| c.sja.peek(r)).collect();
            let (tec, rec, state) = c.sja.error_counters();
            ChipState {
                kind: "SJA1000".into(),
                base: c.spec.base,
                mode: match c.sja.mode() {
                    Mode::BasicCan => "BasicCAN",
                    Mode::PeliCan => "PeliCAN",
                }
                .into(),
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
        })
        .collect();
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
