//! A bench for register-level tests of the AT89C51CC03's CAN controller driven by real 8051
//! code: the `mcs51` core ([`mcs51::Variant::At89c51cc03`]) and a
//! [`bus::at89c51cc::CanController`] joined through the core's hooks. CAN SFR reads and writes
//! go to the controller; its CAN request ([`CanController::interrupt`]) reaches the core as
//! [`mcs51::irq::CAN`] (vector 003Bh, IEN1.ECAN) and its timer overflow
//! ([`CanController::timer_interrupt`]) as [`mcs51::irq::CAN_TIMER`] (004Bh, IEN1.ETIM).
//!
//! No bus stands behind it: the test plays the bus, handing the controller what happened with
//! [`Cc03::deliver`] and reading what it asked for with [`Cc03::take_actions`].
//!
//! Time: the core runs one instruction at a time, and before each one the controller is told
//! the time in CAN clock periods, `F_CAN = F_OSC / 2` (X1 mode, as in the T89C51CC01 data
//! sheet's bit timing example; the bench does not follow a switch to X2 mode). A register access
//! inside an instruction therefore sees the CAN timer as it stood when that instruction began,
//! and a write that enables the controller starts the timer from that instant too.

use bus::at89c51cc::{Action, BusSide, CanController};
use mcs51::{Cpu, Variant, Xdata, irq};

/// The crystal of the bench: 12 MHz, so one machine cycle is 1 µs in X1 mode.
pub const F_OSC: u64 = 12_000_000;

/// The CAN clock of the bench: F_OSC / 2 in X1 mode.
pub const F_CAN: u64 = F_OSC / 2;

/// The core's hooks: every SFR the core does not implement is offered to the CAN controller.
struct Hooks {
    can: CanController,
}

impl Xdata for Hooks {
    /// Nothing is wired to the external bus: an undriven read.
    fn read(&mut self, _addr: u16) -> u8 {
        0xFF
    }

    fn write(&mut self, _addr: u16, _value: u8) {}

    fn sfr_read(&mut self, addr: u8) -> Option<u8> {
        self.can.sfr_read(addr)
    }

    fn sfr_write(&mut self, addr: u8, value: u8) -> bool {
        self.can.sfr_write(addr, value)
    }

    fn irq(&self) -> u8 {
        let mut bits = 0;
        if self.can.interrupt() {
            bits |= irq::CAN;
        }
        if self.can.timer_interrupt() {
            bits |= irq::CAN_TIMER;
        }
        bits
    }
}

/// An AT89C51CC03 at [`F_OSC`] running one firmware image, its CAN controller on no bus.
pub struct Cc03 {
    cpu: Cpu,
    hooks: Hooks,
}

impl Cc03 {
    /// The chip after reset running the Intel HEX image `hex`.
    pub fn new(hex: &str) -> Result<Cc03, mcs51::Error> {
        let image = mcs51::hex::parse(hex, 0x10000)?;
        Ok(Cc03 {
            cpu: Cpu::new(Variant::At89c51cc03, &image),
            hooks: Hooks {
                can: CanController::new(F_CAN),
            },
        })
    }

    /// Runs the core for at least `cycles` more machine cycles (it stops at the first
    /// instruction boundary at or past them). A core fault is returned as the error.
    pub fn run(&mut self, cycles: u64) -> Result<(), mcs51::Error> {
        let until = self.cpu.cycles() + cycles;
        while self.cpu.cycles() < until {
            self.hooks.can.set_time(self.can_time());
            self.cpu.step(&mut self.hooks)?;
        }
        Ok(())
    }

    /// Hands the controller what the bus did, at the present instant.
    pub fn deliver(&mut self, event: BusSide) {
        self.hooks.can.set_time(self.can_time());
        self.hooks.can.on_event(event);
    }

    /// What the controller asked of the bus since the last call, in order.
    pub fn take_actions(&mut self) -> Vec<Action> {
        self.hooks.can.take_actions().collect()
    }

    /// Internal RAM byte `addr`.
    pub fn iram(&self, addr: u8) -> u8 {
        self.cpu.iram()[usize::from(addr)]
    }

    /// Sets an input pin: port `port` (0–3), bit `bit`, high when `level`.
    pub fn set_pin(&mut self, port: u8, bit: u8, level: bool) {
        self.cpu.set_pin(port, bit, level);
    }

    /// Machine cycles since reset.
    pub fn cycles(&self) -> u64 {
        self.cpu.cycles()
    }

    /// The CAN controller, to read what the registers set up (e.g. its bit timing).
    pub fn can(&self) -> &CanController {
        &self.hooks.can
    }

    /// The time in CAN clock periods: two oscillator periods each.
    fn can_time(&self) -> u64 {
        self.cpu.clocks() / 2
    }
}
