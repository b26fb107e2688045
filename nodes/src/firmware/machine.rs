//! One firmware node's hardware: the CPU and the CAN controllers in its external data space,
//! wired together (MOVX windows, interrupt pins). Deterministic: the same inputs at the same
//! cycles give the same state.

use super::spec::{CHIP_WINDOW, ChipSpec, FirmwareSpec};
use bus::sja1000::{Action, BitTiming, BusSide, Sja1000};
use mcs51::{Cpu, RunEnd, Xdata};

/// An SJA1000 where the CPU reaches it.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Chip {
    pub spec: ChipSpec,
    pub sja: Sja1000,
}

/// A chip's request, with its bit timing when it made it (which decides whether it can read the
/// bus when it joins it).
pub(crate) type Request = (Action, BitTiming);

/// The CPU's external data space: the chips, and what they asked of the bus since the CPU last
/// stopped.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Board {
    pub chips: Vec<Chip>,
    pub actions: Vec<Request>,
    /// Something the CPU must see before it goes on: a chip asked for the bus or moved its
    /// interrupt output.
    stop: bool,
}

impl Board {
    /// The chip whose window holds `addr`, and the register address it sees there.
    fn decode(&self, addr: u16) -> Option<(usize, u8)> {
        self.chips.iter().enumerate().find_map(|(i, c)| {
            let offset = u32::from(addr).checked_sub(u32::from(c.spec.base))?;
            (offset < CHIP_WINDOW).then_some((i, offset as u8))
        })
    }

    /// Collects chip `i`'s actions and notes a change of its interrupt output.
    fn after(&mut self, i: usize, int_before: bool) {
        let chip = &mut self.chips[i];
        let before = self.actions.len();
        let timing = chip.sja.bit_timing();
        self.actions.extend(chip.sja.take_actions().map(|a| (a, timing)));
        self.stop |= self.actions.len() > before || chip.sja.int_active() != int_before;
    }
}

impl Xdata for Board {
    /// An address no chip decodes reads FFh (the bus floats high).
    fn read(&mut self, addr: u16) -> u8 {
        let Some((i, offset)) = self.decode(addr) else {
            return 0xFF;
        };
        let int = self.chips[i].sja.int_active();
        let value = self.chips[i].sja.read(offset);
        self.after(i, int);
        value
    }

    /// A write no chip decodes does nothing.
    fn write(&mut self, addr: u16, value: u8) {
        if let Some((i, offset)) = self.decode(addr) {
            let int = self.chips[i].sja.int_active();
            self.chips[i].sja.write(offset, value);
            self.after(i, int);
        }
    }

    fn wants_stop(&self) -> bool {
        self.stop
    }
}

/// A write of the CPU to a chip's register: the cycle after the instruction, the chip's base,
/// the register and the value.
pub(crate) type Write = (u64, u16, u8, u8);

/// The CPU and its board.
#[derive(Clone, Debug)]
pub(crate) struct Machine {
    pub cpu: Cpu,
    pub board: Board,
    /// The CPU's writes to chip registers since the log was last taken, when they are logged.
    pub writes: Option<Vec<Write>>,
}

impl Machine {
    /// The hardware at power-on: the CPU at reset with the image, at its entry point; the chips
    /// at hardware reset.
    pub fn new(spec: &FirmwareSpec) -> Machine {
        let mut cpu = Cpu::new(spec.variant, &spec.image);
        cpu.set_pc(spec.entry);
        let chips = spec
            .chips
            .iter()
            .map(|&c| Chip {
                spec: c,
                sja: Sja1000::new(c.xtal_hz),
            })
            .collect();
        let mut m = Machine {
            cpu,
            board: Board {
                chips,
                actions: Vec::new(),
                stop: false,
            },
            writes: None,
        };
        m.sync_pins();
        m
    }

    /// The same state, the cycle count aside: a loop that comes back to it repeats for ever
    /// until an input changes something.
    pub fn same_state(&self, other: &Machine) -> bool {
        self.cpu.same_state(&other.cpu) && self.board == other.board
    }

    /// Drives the interrupt pins from the chips' INT outputs (active low).
    fn sync_pins(&mut self) {
        for c in &self.board.chips {
            if let Some(pin) = c.spec.irq {
                let (port, bit) = pin.port_bit();
                self.cpu.set_pin(port, bit, !c.sja.int_active());
            }
        }
        self.board.stop = false;
    }

    /// Runs until the cycle count reaches `until` or a chip asks the bus for something (then
    /// [`Machine::take_actions`] has it). Interrupt pins follow the chips as the CPU goes.
    pub fn run(&mut self, until: u64) -> Result<(), mcs51::Error> {
        while self.cpu.cycles() < until {
            let end = self.cpu.run(&mut self.board, until)?;
            if let (RunEnd::XdataWrite { addr, value }, Some(log)) = (end, &mut self.writes)
                && let Some((i, register)) = self.board.decode(addr)
            {
                log.push((self.cpu.cycles(), self.board.chips[i].spec.base, register, value));
            }
            if self.board.stop {
                self.sync_pins();
            }
            if !self.board.actions.is_empty() {
                return Ok(());
            }
            if end == RunEnd::Reached {
                break;
            }
        }
        Ok(())
    }

    /// Executes one instruction (or enters an interrupt), as [`Machine::run`] would.
    pub fn step(&mut self) -> Result<mcs51::Step, mcs51::Error> {
        let step = self.cpu.step(&mut self.board)?;
        if let (Some(mcs51::XAccess::Write { addr, value }), Some(log)) = (step.xdata, &mut self.writes)
            && let Some((i, register)) = self.board.decode(addr)
        {
            log.push((self.cpu.cycles(), self.board.chips[i].spec.base, register, value));
        }
        if self.board.stop {
            self.sync_pins();
        }
        Ok(step)
    }

    /// What the bus did for chip `i`.
    pub fn input(&mut self, i: usize, event: BusSide) {
        if let Some(chip) = self.board.chips.get_mut(i) {
            chip.sja.on_event(event);
            let timing = chip.sja.bit_timing();
            self.board
                .actions
                .extend(chip.sja.take_actions().map(|a| (a, timing)));
        }
        self.sync_pins();
    }

    /// The chips' requests since the last call, in order.
    pub fn take_actions(&mut self) -> Vec<Request> {
        std::mem::take(&mut self.board.actions)
    }
}
