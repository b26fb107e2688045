//! One firmware node's hardware: the CPU and its CAN controllers (SJA1000s in its external data
//! space, or the AT89C51CC03's own behind its SFRs), wired together (MOVX windows, SFRs,
//! interrupt pins and sources). Deterministic: the same inputs at the same oscillator clocks
//! give the same state.

use super::spec::{CHIP_WINDOW, ChipSpec, FirmwareSpec};
use bus::at89c51cc::{CanController, sfr};
use bus::sja1000::{Action, BusSide, Sja1000};
use mcs51::{Cover, Cpu, RunEnd, Xdata};
use smallvec::SmallVec;

/// A CAN controller where the CPU reaches it.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Chip {
    /// An SJA1000 at `base` in external data space.
    Sja {
        base: u16,
        irq: Option<super::Pin>,
        sja: Sja1000,
    },
    /// The AT89C51CC03's controller, behind SFRs.
    OnChip(CanController),
}

impl Chip {
    fn new(spec: &ChipSpec, clock_hz: u64) -> Chip {
        match *spec {
            ChipSpec::Sja1000 { base, xtal_hz, irq } => Chip::Sja {
                base,
                irq,
                sja: Sja1000::new(xtal_hz),
            },
            // F_CAN is the peripheral clock, F_OSC / 2 (X1 mode, as after reset).
            ChipSpec::OnChip => Chip::OnChip(CanController::new(clock_hz / 2)),
        }
    }

    /// Whether its timing samples a bus of `bitrate_hz` correctly.
    fn tuned(&self, bitrate_hz: f64) -> bool {
        match self {
            Chip::Sja { sja, .. } => sja.bit_timing().samples_correctly(bitrate_hz),
            Chip::OnChip(can) => can.bit_timing().samples_correctly(bitrate_hz),
        }
    }

    /// Moves its requests into `into`, as chip `chip`'s.
    fn take_actions(&mut self, chip: usize, bitrate_hz: f64, into: &mut Vec<Request>) {
        let from = into.len();
        let request = |action| Request {
            chip,
            action,
            tuned: false,
        };
        match self {
            Chip::Sja { sja, .. } => into.extend(sja.take_actions().map(request)),
            Chip::OnChip(can) => into.extend(can.take_actions().map(request)),
        }
        // Worked out only when there is a request: most register accesses make none.
        if into.len() > from {
            let tuned = self.tuned(bitrate_hz);
            for r in &mut into[from..] {
                r.tuned = tuned;
            }
        }
    }

    /// Its interrupt outputs as [`mcs51::irq`] bits: the SJA1000's INT (active) as
    /// [`mcs51::irq::CAN`], the on-chip controller's CAN and CAN timer requests.
    fn requests(&self) -> u8 {
        match self {
            Chip::Sja { sja, .. } => {
                if sja.int_active() {
                    mcs51::irq::CAN
                } else {
                    0
                }
            }
            Chip::OnChip(can) => {
                (if can.interrupt() { mcs51::irq::CAN } else { 0 })
                    | if can.timer_interrupt() {
                        mcs51::irq::CAN_TIMER
                    } else {
                        0
                    }
            }
        }
    }

    fn on_event(&mut self, event: BusSide) {
        match self {
            Chip::Sja { sja, .. } => sja.on_event(event),
            Chip::OnChip(can) => can.on_event(event),
        }
    }
}

/// A chip's request of the bus.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Request {
    /// Which chip (its index in the node file's controllers).
    pub chip: usize,
    pub action: Action,
    /// Whether its bit timing read the bus correctly when it made it (which decides whether it
    /// can read the bus when it joins it).
    pub tuned: bool,
}

/// The CPU's surroundings: the chips, and what they asked of the bus since the CPU last
/// stopped.
#[derive(Debug)]
pub(crate) struct Board {
    /// Inline: a machine is copied at every look and checkpoint, and most have one chip.
    pub chips: SmallVec<[Chip; 1]>,
    pub actions: Vec<Request>,
    /// Each chip's interrupt outputs ([`Chip::requests`]) as of its last change: the core asks
    /// for them after every hooked access, and working them out takes a look at every channel.
    requests: SmallVec<[u8; 2]>,
    /// The bus's bit rate, to tell whether a controller's timing reads it.
    bitrate_hz: f64,
    /// Something the CPU must see before it goes on: a chip asked for the bus or moved its
    /// interrupt output.
    stop: bool,
    /// Writes to the on-chip controller's registers since power-on: where two states show the
    /// same count, the firmware configured nothing in between.
    pub can_writes: u64,
    /// Writes to the registers that decide which frames the on-chip controller takes (CANGCON,
    /// and a channel's CANCONCH, CANIDT, CANIDM) since power-on: where two states show the same
    /// count, a frame is taken or not alike in both.
    pub filter_writes: u64,
    /// Reads of the on-chip controller's timers (CANTIM, CANTTC) since power-on: a loop that
    /// reads one does not turn the same way twice.
    pub time_reads: u64,
}

/// A board with one chip (most have one) is copied without the generic path of a `SmallVec`,
/// which costs several times the copy itself.
impl Clone for Board {
    fn clone(&self) -> Board {
        Board {
            chips: match self.chips.as_slice() {
                [one] => SmallVec::from_buf([one.clone()]),
                _ => self.chips.clone(),
            },
            actions: self.actions.clone(),
            requests: SmallVec::from_slice(&self.requests),
            bitrate_hz: self.bitrate_hz,
            stop: self.stop,
            can_writes: self.can_writes,
            filter_writes: self.filter_writes,
            time_reads: self.time_reads,
        }
    }
}

/// The state, the write count aside (a loop that writes the same values repeats all the same).
impl PartialEq for Board {
    fn eq(&self, other: &Board) -> bool {
        self.chips == other.chips
            && self.actions == other.actions
            && self.requests == other.requests
            && self.bitrate_hz == other.bitrate_hz
            && self.stop == other.stop
    }
}

impl Board {
    /// The SJA1000 whose window holds `addr`, and the register address it sees there.
    fn decode(&self, addr: u16) -> Option<(usize, u8)> {
        self.chips.iter().enumerate().find_map(|(i, c)| {
            let Chip::Sja { base, .. } = c else {
                return None;
            };
            let offset = u32::from(addr).checked_sub(u32::from(*base))?;
            (offset < CHIP_WINDOW).then_some((i, offset as u8))
        })
    }

    fn on_chip(&mut self) -> Option<(usize, &mut CanController)> {
        self.chips.iter_mut().enumerate().find_map(|(i, c)| match c {
            Chip::OnChip(can) => Some((i, can)),
            Chip::Sja { .. } => None,
        })
    }

    /// Brings chip `i`'s interrupt outputs up to date; true when they changed.
    fn refresh(&mut self, i: usize) -> bool {
        let now = self.chips[i].requests();
        std::mem::replace(&mut self.requests[i], now) != now
    }

    /// Collects chip `i`'s actions and notes a change of its interrupt output.
    fn after(&mut self, i: usize) {
        let before = self.actions.len();
        self.chips[i].take_actions(i, self.bitrate_hz, &mut self.actions);
        let changed = self.refresh(i);
        self.stop |= self.actions.len() > before || changed;
    }
}

impl Xdata for Board {
    /// An address no chip decodes reads FFh (the bus floats high).
    fn read(&mut self, addr: u16) -> u8 {
        let Some((i, offset)) = self.decode(addr) else {
            return 0xFF;
        };
        let value = match &mut self.chips[i] {
            Chip::Sja { sja, .. } => sja.read(offset),
            Chip::OnChip(_) => 0xFF,
        };
        self.after(i);
        value
    }

    /// A write no chip decodes does nothing.
    fn write(&mut self, addr: u16, value: u8) {
        if let Some((i, offset)) = self.decode(addr) {
            if let Chip::Sja { sja, .. } = &mut self.chips[i] {
                sja.write(offset, value);
            }
            self.after(i);
        }
    }

    fn wants_stop(&self) -> bool {
        self.stop
    }

    /// A read asks nothing of the bus and moves no interrupt output (only CANMSG's index
    /// moves on): nothing to collect after it.
    fn sfr_read(&mut self, addr: u8) -> Option<u8> {
        let (_, can) = self.on_chip()?;
        let value = can.sfr_read(addr)?;
        if matches!(addr, sfr::CANTIML | sfr::CANTIMH | sfr::CANTTCL | sfr::CANTTCH) {
            self.time_reads += 1;
        }
        Some(value)
    }

    fn sfr_write(&mut self, addr: u8, value: u8) -> bool {
        let Some((i, can)) = self.on_chip() else {
            return false;
        };
        if !can.sfr_write(addr, value) {
            return false;
        }
        self.can_writes += 1;
        if matches!(addr, sfr::CANGCON | sfr::CANCONCH | 0xBC..=0xBF | 0xC4..=0xC7) {
            self.filter_writes += 1;
        }
        self.after(i);
        true
    }

    /// F_CAN = F_OSC / 2: the CAN timer and time stamps follow the CPU's clock. Time moves
    /// only the timer's overflow request.
    fn sfr_clock(&mut self, clocks: u64) {
        if let Some((i, can)) = self.on_chip() {
            let before = can.timer_interrupt();
            can.set_time(clocks / 2);
            if can.timer_interrupt() != before {
                self.refresh(i);
            }
        }
    }

    /// The on-chip controller's requests (an SJA1000 interrupts through a pin instead).
    fn irq(&self) -> u8 {
        self.chips
            .iter()
            .zip(&self.requests)
            .filter(|(c, _)| matches!(c, Chip::OnChip(_)))
            .fold(0, |bits, (_, r)| bits | r)
    }
}

/// A write of the CPU to a chip's register: the oscillator clock after the instruction, the
/// chip's base (0 for SFRs), the register and the value.
pub(crate) type Write = (u64, u16, u8, u8);

/// The CPU and its board. Its time is the CPU's oscillator clocks ([`Cpu::clocks`]): a machine
/// cycle is 12 of them, or 6 in the AT89C51CC03's X2 mode.
#[derive(Clone, Debug)]
pub(crate) struct Machine {
    pub cpu: Cpu,
    pub board: Board,
    /// The CPU's writes to chip registers since the log was last taken, when they are logged.
    pub writes: Option<Vec<Write>>,
    /// The CPU stopped for its wires to the plant: the next instruction reads inputs whose
    /// levels no longer hold, or the last one changed an output ([`mcs51::Watched`]).
    pub plant_stop: bool,
    /// Where this machine is in the node's coverage journal, when it ran with one
    /// ([`super::coverage::Journal`]): the entries before it are its instructions since the
    /// run ahead began.
    pub journaled: usize,
}

/// One turn of a loop that turns the same way until something happens
/// ([`Machine::repeats`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Turn {
    /// Its length, oscillator clocks.
    pub clocks: u64,
    /// Its length, machine cycles.
    pub cycles: u64,
    /// It reads wired inputs: it turns the same way only while their levels hold.
    pub reads_inputs: bool,
    /// Its instructions in the coverage journal: from the head's position to the end's.
    pub journal: (usize, usize),
}

impl Machine {
    /// The hardware at power-on: the CPU at reset with the image, at its entry point; the chips
    /// at hardware reset.
    pub fn new(spec: &FirmwareSpec, bitrate_hz: f64) -> Machine {
        let mut cpu = Cpu::new(spec.variant, &spec.image);
        cpu.set_pc(spec.entry);
        let chips: SmallVec<[Chip; 1]> = spec.chips.iter().map(|c| Chip::new(c, spec.clock_hz)).collect();
        let mut m = Machine {
            cpu,
            board: Board {
                requests: chips.iter().map(Chip::requests).collect(),
                chips,
                actions: Vec::new(),
                bitrate_hz,
                stop: false,
                can_writes: 0,
                filter_writes: 0,
                time_reads: 0,
            },
            writes: None,
            plant_stop: false,
            journaled: 0,
        };
        m.sync_pins();
        m
    }

    /// Oscillator clocks since power-on.
    pub fn clocks(&self) -> u64 {
        self.cpu.clocks()
    }

    /// `self` being `head` one turn of a loop later: the turn, when every later turn will do
    /// the same as this one up to the next event ([`Machine::next_change`]). That holds when
    /// the turn read no timer count (the CPU's or the CAN controller's), no event fell due
    /// during it, and the state is the head's with the turn's time passed on it, nothing
    /// executed (the timers counted; both told the on-chip controller the time).
    pub fn repeats(&mut self, head: std::borrow::Cow<'_, Machine>) -> Option<Turn> {
        if self.cpu.time_reads() != head.cpu.time_reads()
            || self.board.time_reads != head.board.time_reads
            || self.board.can_writes != head.board.can_writes
            || head.next_change() <= self.clocks()
            || self.plant_stop
        {
            return None;
        }
        let turn = Turn {
            clocks: self.clocks() - head.clocks(),
            cycles: self.cpu.cycles() - head.cpu.cycles(),
            reads_inputs: self.cpu.input_reads() != head.cpu.input_reads(),
            journal: (head.journaled, self.journaled),
        };
        let mut passed = head.into_owned();
        passed.pass(turn, 1);
        self.sync_chip_time();
        (passed.cpu.same_but_time(&self.cpu) && passed.board == self.board).then_some(turn)
    }

    /// Passes `turns` turns of a loop found by [`Machine::repeats`] without executing them:
    /// only for a machine at the loop's head, and not up to [`Machine::next_change`].
    pub fn pass(&mut self, turn: Turn, turns: u64) {
        self.cpu.idle(turn.cycles.saturating_mul(turns));
        self.sync_chip_time();
    }

    /// Tells the on-chip controller the time. Its time moves lazily, when the CPU reaches it,
    /// and nothing it shows depends on when it was told: two machines at one clock compare
    /// alike once both were told.
    pub fn sync_chip_time(&mut self) {
        let clocks = self.cpu.clocks();
        if let Some((i, can)) = self.board.on_chip() {
            // F_CAN = F_OSC / 2.
            can.set_time(clocks / 2);
            self.board.refresh(i);
        }
    }

    /// The first oscillator clock at which something may change what a loop does: the CPU's
    /// next timer, serial, ADC or watchdog event, or the CAN timer's overflow
    /// ([`Machine::timer_due`]); `u64::MAX` when none is coming.
    pub fn next_change(&self) -> u64 {
        let cpu = match self.cpu.next_event() {
            u64::MAX => u64::MAX,
            cycle => self.cpu.clocks().saturating_add(
                cycle
                    .saturating_sub(self.cpu.cycles())
                    .saturating_mul(self.cpu.clocks_per_cycle()),
            ),
        };
        cpu.min(self.timer_due().unwrap_or(u64::MAX))
    }

    /// The oscillator clock at which the on-chip controller's CAN timer next overflows while
    /// that would raise its timer request (OVRTIM clear): from that clock on the CPU must see
    /// OVRTIM. F_CAN = F_OSC / 2: CAN clock period `p` begins at oscillator clock `2p`. `None`
    /// with no on-chip controller, while it is disabled, or while OVRTIM is already set (an
    /// overflow then changes nothing the CPU sees without reading a CAN register, and a read
    /// brings the timer up to date itself).
    pub fn timer_due(&self) -> Option<u64> {
        self.board.chips.iter().find_map(|c| match c {
            Chip::OnChip(can) if !can.timer_interrupt() => {
                can.next_timer_overflow().map(|p| p.saturating_mul(2))
            }
            _ => None,
        })
    }

    /// Tells the on-chip controller the time when its CAN timer overflow is due, so that its
    /// request is up before the next instruction starts.
    fn catch_up_timer(&mut self) {
        let clocks = self.cpu.clocks();
        if self.timer_due().is_some_and(|due| clocks >= due)
            && let Some((i, can)) = self.board.on_chip()
        {
            can.set_time(clocks / 2);
            self.board.refresh(i);
        }
    }

    /// Drives the interrupt pins from the SJA1000s' INT outputs, and tells the on-chip
    /// controller the time. INT is active low and open drain: several chips wired to one pin
    /// pull it low together, so the pin is low while any of them holds its INT active.
    fn sync_pins(&mut self) {
        let clocks = self.cpu.clocks();
        let mut pins: [(super::Pin, Option<bool>); 2] = [(super::Pin::Int0, None), (super::Pin::Int1, None)];
        for i in 0..self.board.chips.len() {
            match &mut self.board.chips[i] {
                Chip::Sja {
                    irq: Some(pin), sja, ..
                } => {
                    for (p, low) in &mut pins {
                        if p == pin {
                            *low = Some(low.unwrap_or(false) || sja.int_active());
                        }
                    }
                }
                Chip::Sja { irq: None, .. } => {}
                // F_CAN = F_OSC / 2.
                Chip::OnChip(can) => can.set_time(clocks / 2),
            }
            self.board.refresh(i);
        }
        // A pin no chip is wired to is left alone.
        for (pin, low) in pins {
            if let Some(low) = low {
                let (port, bit) = pin.port_bit();
                self.cpu.set_pin(port, bit, !low);
            }
        }
        self.board.stop = false;
    }

    /// Logs a register write of the last instruction, when writes are logged.
    fn log(&mut self, access: Option<(u16, u8)>) {
        if let (Some((addr, value)), Some(log)) = (access, &mut self.writes)
            && let Some((i, register)) = self.board.decode(addr)
            && let Chip::Sja { base, .. } = &self.board.chips[i]
        {
            log.push((self.cpu.clocks(), *base, register, value));
        }
    }

    /// Runs until the clock count reaches `until` or a chip asks the bus for something (then
    /// [`Machine::take_actions`] has it). Interrupt pins follow the chips as the CPU goes, and
    /// the CPU sees the CAN timer overflow from the first instruction boundary at or after it
    /// ([`Machine::timer_due`]), as when the controller is told the time before every
    /// instruction.
    pub fn run(&mut self, until: u64) -> Result<(), mcs51::Error> {
        self.run_covered(until, &mut ())
    }

    /// [`Machine::run`], telling `cover` of every instruction executed.
    pub fn run_covered<C: Cover>(&mut self, until: u64, cover: &mut C) -> Result<(), mcs51::Error> {
        self.catch_up_timer();
        while self.cpu.clocks() < until {
            let due = self.timer_due().filter(|&d| d > self.cpu.clocks() && d < until);
            let to = due.unwrap_or(until);
            let per = self.cpu.clocks_per_cycle();
            let target = self.cpu.cycles() + (to - self.cpu.clocks()).div_ceil(per);
            let end = self.cpu.run_covered(&mut self.board, target, cover)?;
            if let RunEnd::XdataWrite { addr, value } = end {
                self.log(Some((addr, value)));
            }
            if end == RunEnd::AtPc {
                self.catch_up_timer();
                if self.board.stop {
                    self.sync_pins();
                }
                return Ok(());
            }
            if matches!(end, RunEnd::InputsDue | RunEnd::OutputChanged) {
                self.plant_stop = true;
                self.catch_up_timer();
                if self.board.stop {
                    self.sync_pins();
                }
                return Ok(());
            }
            self.catch_up_timer();
            if self.board.stop {
                self.sync_pins();
            }
            if !self.board.actions.is_empty() {
                return Ok(());
            }
            if end == RunEnd::Reached && due.is_none() {
                break;
            }
        }
        Ok(())
    }

    /// [`Machine::run_covered`], stopping also after an instruction that leaves the PC at `pc`.
    pub fn run_to_pc<C: Cover>(&mut self, until: u64, pc: u16, cover: &mut C) -> Result<(), mcs51::Error> {
        self.cpu.stop_at_pc(Some(pc));
        let r = self.run_covered(until, cover);
        self.cpu.stop_at_pc(None);
        r
    }

    /// Executes one instruction (or enters an interrupt), as [`Machine::run`] would, telling
    /// `cover` of it.
    pub fn step<C: Cover>(&mut self, cover: &mut C) -> Result<mcs51::Step, mcs51::Error> {
        self.catch_up_timer();
        let step = self.cpu.step_covered(&mut self.board, cover)?;
        self.catch_up_timer();
        if self.cpu.take_output_changed() {
            self.plant_stop = true;
        }
        if let Some(mcs51::XAccess::Write { addr, value }) = step.xdata {
            self.log(Some((addr, value)));
        }
        if self.board.stop {
            self.sync_pins();
        }
        Ok(step)
    }

    /// What the bus did for chip `i`.
    pub fn input(&mut self, i: usize, event: BusSide) {
        self.sync_pins();
        if let Some(chip) = self.board.chips.get_mut(i) {
            chip.on_event(event);
            chip.take_actions(i, self.board.bitrate_hz, &mut self.board.actions);
            self.board.refresh(i);
        }
        self.sync_pins();
    }

    /// Whether `frame` would change nothing here: every chip is an on-chip controller that
    /// takes no such frame as it stands.
    pub fn ignores(&self, frame: &bus::Frame) -> bool {
        self.board.chips.iter().all(|c| match c {
            Chip::OnChip(can) => !can.takes(frame),
            Chip::Sja { .. } => false,
        })
    }

    /// The filters of the on-chip controller's channels that would take a frame now, when its
    /// only chip is that controller: a frame none of them accepts is one [`Machine::ignores`].
    pub fn heeded(&self) -> Option<smallvec::SmallVec<[bus::filter::AtmelFilter; 4]>> {
        match self.board.chips.as_slice() {
            [Chip::OnChip(can)] => Some(can.heeded().collect()),
            _ => None,
        }
    }

    /// The chips' requests since the last call, in order.
    pub fn take_actions(&mut self) -> Vec<Request> {
        std::mem::take(&mut self.board.actions)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::firmware::Pin;
    use bus::time::BusDuration;
    use std::sync::Arc;

    /// `MOV A, P3` at 0000h, then `SJMP 0000h`: each pass reads the port's pins into A.
    const READ_P3: [u8; 4] = [0xE5, 0xB0, 0x80, 0xFC];

    /// An 80C51 at 12 MHz with SJA1000s at `bases`, every INT output wired to INT0.
    fn two_chips(bases: &[u16]) -> Machine {
        let mut code = vec![0xFF; 0x10000];
        code[..READ_P3.len()].copy_from_slice(&READ_P3);
        let spec = FirmwareSpec {
            name: "BENCH".into(),
            address: None,
            start_up_ms: 0,
            file: "bench.ron".into(),
            image: Arc::new(mcs51::Image {
                code,
                written: std::iter::once(0..READ_P3.len() as u32).collect(),
            }),
            image_file: "bench.hex".into(),
            image_sha256: String::new(),
            debug: None,
            debug_problems: Vec::new(),
            entry: 0,
            variant: mcs51::Variant::I8051,
            clock_hz: 12_000_000,
            clock: BusDuration::period_of(12_000_000).unwrap(),
            chips: bases
                .iter()
                .map(|&base| ChipSpec::Sja1000 {
                    base,
                    xtal_hz: 6_000_000,
                    irq: Some(Pin::Int0),
                })
                .collect(),
            vref_mv: 0,
            analog: Vec::new(),
            pins: Vec::new(),
            dacs: Vec::new(),
            skip_idle_loops: false,
        };
        let mut m = Machine::new(&spec, 30_000.0);
        // PeliCAN, receive interrupt enabled, every identifier accepted, operating mode.
        for &base in bases {
            for (register, value) in [(0, 0x01), (31, 0x88), (4, 0x01), (20, 0xFF), (21, 0xFF)] {
                m.board.write(base + register, value);
            }
            for register in [22, 23] {
                m.board.write(base + register, 0xFF);
            }
            m.board.write(base, 0x00);
        }
        m.sync_pins();
        m.take_actions();
        m
    }

    /// P3.2 (INT0) as the CPU reads it.
    fn int0_high(m: &mut Machine) -> bool {
        m.cpu.set_pc(0);
        m.step(&mut ()).unwrap();
        m.cpu.sfr()[0x60] & 0x04 != 0
    }

    fn receive(m: &mut Machine, chip: usize) {
        let frame = bus::candump::parse_frame("123#0102").unwrap();
        m.input(chip, BusSide::Received(frame));
    }

    /// CMR.RRB: the chip at `base` releases its receive buffer, which clears RI (and INT).
    fn release(m: &mut Machine, base: u16) {
        m.board.write(base + 1, 0x04);
        m.sync_pins();
    }

    #[test]
    fn int_outputs_on_one_pin_pull_it_low_together() {
        for first_released in [0, 1] {
            let bases = [0xD300, 0xD400];
            let mut m = two_chips(&bases);
            assert!(int0_high(&mut m), "no interrupt pending: INT0 high");
            receive(&mut m, 0);
            receive(&mut m, 1);
            assert!(!int0_high(&mut m), "both pending: INT0 low");
            release(&mut m, bases[first_released]);
            assert!(
                !int0_high(&mut m),
                "chip {} released, the other still pending: INT0 low",
                first_released
            );
            release(&mut m, bases[1 - first_released]);
            assert!(int0_high(&mut m), "both released: INT0 high");
        }
    }

    #[test]
    fn one_chip_pending_pulls_the_shared_pin_low() {
        for pending in [0, 1] {
            let mut m = two_chips(&[0xD300, 0xD400]);
            receive(&mut m, pending);
            assert!(!int0_high(&mut m), "chip {pending} pending: INT0 low");
        }
    }
}
