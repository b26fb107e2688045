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

    /// Sets ADC input `channel` (0–7) to the 10-bit `code` the next conversion yields
    /// (clamped to 1023).
    pub fn set_analog(&mut self, channel: u8, code: u16) {
        self.cpu.set_analog(channel, code);
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

/// Test firmware for the bench: the CC03's CAN SFR names, the vectors, and helpers.
pub mod firmware {
    use super::Cc03;
    use crate::assemble;
    use bus::at89c51cc::Action;
    use bus::{ExtendedId, Frame, Id, StandardId};

    /// SFR names (AT89C51CC03 data sheet, SFR map), the vectors and a stack above the results.
    /// Every vector but CAN (003Bh) and CAN timer (004Bh) leads to a trap that marks 7Fh.
    pub const PRELUDE: &str = "
    .equ CANGIT, 09Bh
    .equ CANTEC, 09Ch
    .equ CANREC, 09Dh
    .equ CANTCON, 0A1h
    .equ CANMSG, 0A3h
    .equ CANGSTA, 0AAh
    .equ CANGCON, 0ABh
    .equ CANTIML, 0ACh
    .equ CANTIMH, 0ADh
    .equ CANSTMPL, 0AEh
    .equ CANSTMPH, 0AFh
    .equ CANPAGE, 0B1h
    .equ CANSTCH, 0B2h
    .equ CANCONCH, 0B3h
    .equ CANBT1, 0B4h
    .equ CANBT2, 0B5h
    .equ CANBT3, 0B6h
    .equ CANSIT1, 0BAh
    .equ CANSIT2, 0BBh
    .equ CANIDT1, 0BCh
    .equ CANIDT2, 0BDh
    .equ CANIDT3, 0BEh
    .equ CANIDT4, 0BFh
    .equ CANGIE, 0C1h
    .equ CANIE1, 0C2h
    .equ CANIE2, 0C3h
    .equ CANIDM1, 0C4h
    .equ CANIDM2, 0C5h
    .equ CANIDM3, 0C6h
    .equ CANIDM4, 0C7h
    .equ CANEN1, 0CEh
    .equ CANEN2, 0CFh
    .equ ECAN, 0E8h
    .equ ETIM, 0EAh
    .org 0000h
    	ljmp main
    .org 0003h
    	ljmp trap
    .org 000Bh
    	ljmp trap
    .org 0013h
    	ljmp trap
    .org 001Bh
    	ljmp trap
    .org 0023h
    	ljmp trap
    .org 002Bh
    	ljmp trap
    .org 0033h
    	ljmp trap
    .org 003Bh
    	ljmp can_isr
    .org 0043h
    	ljmp trap
    .org 004Bh
    	ljmp tim_isr
    .org 0053h
    	ljmp trap
    .org 0060h
    trap:	mov 7Fh,#0EEh
    	reti
    .org 0100h
    main:	mov SP,#0C0h
    ";

    /// Accepts everything: every mask bit 0 (CANIDM tables: 0 = don't care).
    pub const ANY: &str = "
    	mov CANIDM1,#00h
    	mov CANIDM2,#00h
    	mov CANIDM3,#00h
    	mov CANIDM4,#00h
    ";

    /// The chip after reset running `main` (which ends in a loop of its own) with the CAN and CAN
    /// timer handlers `can_isr` and `tim_isr`.
    pub fn chip(main: &str, can_isr: &str, tim_isr: &str) -> Cc03 {
        let source = format!("{PRELUDE}{main}\ncan_isr:\n{can_isr}\ntim_isr:\n{tim_isr}\n");
        Cc03::new(&assemble(&source)).expect("the image loads")
    }

    /// Runs `n` machine cycles.
    pub fn run(c: &mut Cc03, n: u64) {
        c.run(n).expect("the core runs");
    }

    /// Pulls P1.`bit` low (the firmware's signal to go on) and runs 400 cycles.
    pub fn go(c: &mut Cc03, bit: u8) {
        c.set_pin(1, bit, false);
        run(c, 400);
    }

    /// Internal RAM `from..from + n`, after checking that no stray vector was taken.
    pub fn ram(c: &Cc03, from: u8, n: u8) -> Vec<u8> {
        assert_ne!(c.iram(0x7F), 0xEE, "an unexpected interrupt vector was taken");
        (from..from + n).map(|a| c.iram(a)).collect()
    }

    /// An extended identifier.
    pub fn eid(id: u32) -> Id {
        ExtendedId::new(id).expect("a 29-bit identifier").into()
    }

    /// A standard identifier.
    pub fn sid(id: u16) -> Id {
        StandardId::new(id).expect("an 11-bit identifier").into()
    }

    /// A data frame.
    pub fn data(id: Id, bytes: &[u8]) -> Frame {
        Frame::new_data(id, bytes).expect("a frame")
    }

    /// A remote frame.
    pub fn remote(id: Id, dlc: usize) -> Frame {
        Frame::new_remote(id, dlc).expect("a frame")
    }

    /// The request to transmit `frame`, as the controller makes it.
    pub fn transmit(frame: Frame) -> Action {
        Action::Transmit {
            frame,
            self_reception: false,
            single_shot: false,
        }
    }

    /// The request to join the bus, as the controller makes it (each channel filters for itself).
    pub const ONLINE: Action = Action::Online {
        listen_only: false,
        self_test: false,
        filter: None,
    };
}
