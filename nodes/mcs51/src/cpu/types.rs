//! What stepping and running report, and the comparable state.

/// One MOVX access, as reported by [`Step`] and [`RunEnd`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum XAccess {
    /// MOVX A,@DPTR or MOVX A,@Ri read `addr`.
    Read {
        /// External address.
        addr: u16,
    },
    /// MOVX @DPTR,A or MOVX @Ri,A wrote `value` at `addr`.
    Write {
        /// External address.
        addr: u16,
        /// The byte written.
        value: u8,
    },
}

/// What one [`Cpu::step`](crate::Cpu::step) did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Step {
    /// Machine cycles taken (1, 2 or 4; 2 for an interrupt entry unless set otherwise).
    pub cycles: u8,
    /// The MOVX access of the instruction, if it was one.
    pub xdata: Option<XAccess>,
    /// The vector called, if this step was an interrupt entry rather than an instruction.
    pub interrupt: Option<u16>,
}

/// Why [`Cpu::run`](crate::Cpu::run) returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunEnd {
    /// The cycle count reached `until`.
    Reached,
    /// The instruction just executed was a MOVX read after which the external data space
    /// asked to stop ([`Xdata::wants_stop`](crate::Xdata::wants_stop)).
    Peripheral,
    /// The instruction just executed was a MOVX write.
    XdataWrite {
        /// External address.
        addr: u16,
        /// The byte written.
        value: u8,
    },
    /// The watchdog ran out: the core was reset at the end of the instruction during which
    /// the time-out fell (AT89C51CC03).
    WatchdogReset,
    /// The instruction just executed switched X2 mode: [`Cpu::clocks_per_cycle`](crate::Cpu::clocks_per_cycle) changed, so
    /// a caller that maps cycles to time recomputes its target (AT89C51CC03).
    ClockChanged,
    /// The next instruction would read watched inputs whose levels no longer hold
    /// ([`crate::Cpu::inputs_due`]): the caller sets them, then runs on.
    InputsDue,
    /// The instruction just executed changed a watched latch bit ([`crate::Watched`]).
    OutputChanged,
    /// The instruction just executed left the PC where [`crate::Cpu::stop_at_pc`] asked.
    AtPc,
}

/// The state that decides what the core does next (everything but the cycle count and the
/// serial output), comparable for equality to detect a loop whose state repeats.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Snapshot {
    /// Program counter.
    pub pc: u16,
    /// Internal RAM.
    pub iram: [u8; 256],
    /// SFRs 80h–FFh as [`Cpu::sfr`](crate::Cpu::sfr) shows them.
    pub sfr: [u8; 128],
    /// Interrupt levels in service (bit n: level n; the 80C51 has levels 0 low and 1 high,
    /// the AT89C51CC03 levels 0 to 3).
    pub in_service: u8,
    /// The on-chip XRAM (empty on variants without one).
    pub xram: Vec<u8>,
    /// The analog inputs (AT89C51CC03; zeros elsewhere).
    pub analog: [u16; 8],
}
