//! [`FirmwareNode`]: a firmware image as a node's logic, in oscillator clocks.
//!
//! Time: oscillator clock `c` after power-on is bus time `power_on + c · period`, exactly (the
//! clock's period is a whole number of bus-clock ticks); a machine cycle is 12 clocks, or 6 in
//! the AT89C51CC03's X2 mode. The CPU runs ahead of the bus optimistically: after every input
//! it runs on from the present, keeping a copy of its state every [`CHUNK`] clocks or more
//! (about sixteen copies a run), until a chip asks the bus for something (a transmit request, a
//! mode change), until the CPU stops for the plant (below), until a horizon, or until it is found
//! in a loop whose turns repeat. It asks to be woken when it stopped. An input that arrives
//! before that moment (a frame, a confirmation) sends it back to the last copy before the
//! input, from where it runs to the input's moment again: so it never acts on what it could not
//! yet have read, and a run is the same every time. A frame that the on-chip controller would
//! not take, while the run ahead writes none of the registers that decide which frames it takes,
//! changes nothing and sends nothing back; the node tells the hub which frames those are, and
//! until when ([`bus::node::Unheeded`]), so that the hub need not wake it for them.
//!
//! Loops that wait: after an input, and then at growing gaps, the node looks for a loop whose
//! turns repeat ([`Machine::repeats`]): it runs until the PC comes back, and compares the state
//! with the one it left with the turn's time passed on it, timers counting. Such a loop does the
//! same turn after turn until its next change: the CPU's next timer, serial, ADC or watchdog
//! event, the CAN timer's overflow, or, for a loop that reads the plant, the plant's next step.
//! The node asks to be woken at the first instruction boundary at or after that change, and an
//! input or a wake at clock `n` finds it after the whole turns that end before the change (passed
//! in closed form: timers, the CAN timer and every register exactly as if each cycle had run),
//! and the rest run. So skipping changes no output, no trace and no state dump.
//!
//! Several chips: each is a controller of its own on the bus, controller `k` being chip `k` of
//! the node file. An input of controller `k` reaches chip `k` at its moment, and each chip's
//! requests become commands for its own controller; the CPU, its run ahead and its deadline are
//! the node's, one for all the chips.
//!
//! Plant wiring: the node serves its wires to the plant when the CPU stops for them
//! ([`mcs51::Watched`]): before an instruction that may read a wired input pin (one that names
//! the pin or its port), and at the first instruction boundary within [`mcs51::ADC_LEAD`]
//! machine cycles of the end of a conversion of a wired ADC channel, once the levels it last
//! read no longer hold (the plant has stepped since: [`crate::script::Environment::next_change`]);
//! and after an instruction that changed a wired output latch (an output pin, a DAC's port). It
//! then drives the plant inputs from its output latches and reads every wired input, at the bus
//! time of that instruction boundary. So the firmware reads the plant as it stands at that
//! moment and drives it from the moment its latch changes, whatever its run ahead or its
//! skipping did; a value a scenario forces between two plant steps reaches it at its first read
//! after the next step.

mod trace;

pub use trace::CpuTrace;

use super::coverage::{Journal, SharedCounts};
use super::machine::{Machine, Request, Turn};
use super::spec::FirmwareSpec;
use super::wiring::Wiring;
use crate::script::SharedEnv;
use bus::Frame;
use bus::fault::ErrorState;
use bus::node::{ControllerCommand, ControllerEvent, HardwareState, NodeFault, NodeLogic, Refused, Unheeded};
use bus::sja1000::{Action, BusSide, ecc_segment};
use bus::time::BusTime;
use std::borrow::Cow;
use std::collections::VecDeque;
use std::sync::Arc;

/// Fewest oscillator clocks between kept copies of a run ahead (100 machine cycles): an input
/// that sends the run back costs at most that much again. A long run ahead keeps about
/// sixteen.
pub const CHUNK: u64 = 1_200;
/// Copies kept of a run ahead at its longest horizon.
const COPIES: u64 = 16;
/// The first and the longest gap between two looks for a loop whose turns repeat, oscillator
/// clocks (100 and 6 400 machine cycles): after an input the node looks at once, then after
/// gaps that double while looks find none, so that a busy node pays for few looks and one that
/// goes idle soon after an input is found soon.
const LOOK_GAP: (u64, u64) = (1_200, 76_800);
/// The shortest and longest horizon of a run ahead, oscillator clocks (1000 and 64 000 machine
/// cycles): it doubles while runs ahead are not cut short by an input and halves when they
/// are, so a node that hears frames often wastes little and a quiet one is seldom woken.
const HORIZON: (u64, u64) = (12_000, 768_000);
/// The shortest wait a node parks for, oscillator clocks (1000 machine cycles): a loop that
/// waits less is run, which costs less than being woken.
const PARK_MIN: u64 = 12_000;
/// Turns a look follows, each from where the last came back, before it gives up.
const LOOK_TURNS: usize = 4;
/// Longest turn a look waits for, oscillator clocks (300 machine cycles): a PC that has not come
/// back by then is looked at again from where the CPU got to.
const LOOK_SPAN: u64 = 3_600;
/// Longest piece of a serial line the log takes at once: a longer line goes out in pieces.
const SERIAL_LINE: usize = 256;

/// How a run ahead ended.
#[derive(Clone, Debug, PartialEq)]
enum Stop {
    /// A chip asked the bus for something.
    Actions,
    /// The horizon.
    Horizon,
    /// In a loop whose turns do the same until the clock `until` (`u64::MAX`: until an input);
    /// the node asks to be woken at `wake`, the first instruction boundary at or after it.
    Parked { turn: Turn, until: u64, wake: u64 },
    /// The CPU waits for the plant: it would read wired inputs whose levels no longer hold, or
    /// it changed an output.
    Plant,
    /// The CPU stopped with this fault.
    Failed(String),
}

/// How [`FirmwareNode::project`] reached a clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Path {
    /// It was there already.
    Here,
    /// From the run ahead, which had got that far.
    Ahead,
    /// From the run ahead parked in a loop, skipping whole turns of it.
    Skipped,
    /// From a copy before the run ahead went past it.
    Back,
}

/// Machine cycles a machine has executed since power-on (those passed in closed form left out).
fn executed(m: &Machine) -> u64 {
    m.cpu.cycles().saturating_sub(m.cpu.skipped_cycles())
}

/// Where [`FirmwareNode::project`] finds the machine it runs on from.
#[derive(Clone, Copy, Debug)]
enum Source {
    Now,
    /// The machine at the wake the run ahead parked for.
    AtWake,
    /// The run ahead, with whole turns of the loop it parked in passed on it.
    Ahead(Option<(Turn, u64)>),
    /// The copy of the run ahead at this index.
    Copy(usize),
}

/// Runs `machine` on to clock `n`, unless `failed` already: what it asked of the bus on the
/// way (from where it was), the fault it stopped with, and the machine cycles it executed. It
/// adds what it executes to `counts`, when given: only for the path the node takes.
fn run_on(
    machine: &mut Machine,
    n: u64,
    mut failed: Option<String>,
    counts: Option<&SharedCounts>,
) -> (Vec<Request>, Option<String>, u64) {
    let start = executed(machine);
    let mut actions = machine.take_actions();
    while machine.clocks() < n && failed.is_none() && !machine.plant_stop {
        let run = match counts {
            Some(c) => machine.run_covered(n, &mut *c.borrow_mut()),
            None => machine.run(n),
        };
        if let Err(e) = run {
            failed = Some(e.to_string());
        }
        actions.extend(machine.take_actions());
    }
    (actions, failed, executed(machine).saturating_sub(start))
}

/// Runs `m` to clock `until` ([`Machine::run`]), or until the PC comes to `pc` when given
/// ([`Machine::run_to_pc`]), writing what it executes to `journal` when coverage is on.
fn run_journaled(
    m: &mut Machine,
    until: u64,
    pc: Option<u16>,
    journal: &mut Option<Journal>,
) -> Result<(), mcs51::Error> {
    let r = match (journal.as_mut(), pc) {
        (Some(j), Some(pc)) => m.run_to_pc(until, pc, j),
        (Some(j), None) => m.run_covered(until, j),
        (None, Some(pc)) => m.run_to_pc(until, pc, &mut ()),
        (None, None) => m.run(until),
    };
    if let Some(j) = journal {
        m.journaled = j.len();
    }
    r
}

/// What a node cost the host, logged when it ends (target `firmware_stats`, level info).
#[derive(Clone, Copy, Debug, Default)]
struct Cost {
    /// Machine cycles executed, runs ahead that an input sent back included.
    executed: u64,
    /// Wakes at its deadline; inputs (frames, controller events) it took.
    wakes: u64,
    inputs: u64,
    /// Inputs that sent its run ahead back to a copy.
    backs: u64,
    /// Host time spent in its inputs and wakes.
    host: std::time::Duration,
}

/// A firmware node.
pub struct FirmwareNode {
    spec: Arc<FirmwareSpec>,
    power_on: BusTime,
    /// The hardware as of the last input.
    now: Machine,
    /// Copies of the run ahead from `now` on, oldest first; the run ahead; how it ended.
    checkpoints: Vec<Machine>,
    ahead: Machine,
    stop: Stop,
    horizon: u64,
    /// Commands for the controllers on the bus, each with its chip's index.
    commands: VecDeque<(usize, ControllerCommand)>,
    failed: Option<String>,
    /// Each chip's error state as last heard, to tell the end of a bus-off recovery.
    states: Vec<ErrorState>,
    serial: Vec<u8>,
    trace: Option<CpuTrace>,
    /// The plant, when its signals are wired to the node.
    wiring: Option<Wiring>,
    /// The run ahead parked: the machine at its wake, as the look for the wake found it, and
    /// the whole turns of the loop it passed on the way.
    at_wake: Option<Machine>,
    wake_turns: u64,
    cost: Cost,
    /// Coverage, when on: the counts the path it takes adds to, and what the run ahead
    /// executed ([`super::coverage`]).
    counts: Option<SharedCounts>,
    journal: Option<Journal>,
}

impl FirmwareNode {
    /// The node powered on at `power_on` on a bus of `bitrate_hz`: CPU and chips at reset.
    pub fn new(spec: Arc<FirmwareSpec>, power_on: BusTime, bitrate_hz: f64) -> FirmwareNode {
        let mut now = Machine::new(&spec, bitrate_hz);
        if tracing::enabled!(tracing::Level::DEBUG) {
            now.writes = Some(Vec::new());
        }
        let chips = spec.chips.len();
        let mut node = FirmwareNode {
            ahead: now.clone(),
            now,
            spec,
            power_on,
            checkpoints: Vec::new(),
            stop: Stop::Horizon,
            horizon: HORIZON.0,
            // Its controllers are in reset mode, off the bus, until the firmware sets them up (a
            // node without a chip still has one on the bus, always off).
            commands: (0..chips.max(1))
                .map(|chip| (chip, ControllerCommand::Offline))
                .collect(),
            failed: None,
            states: vec![ErrorState::Active; chips],
            serial: Vec::new(),
            trace: None,
            wiring: None,
            at_wake: None,
            wake_turns: 0,
            cost: Cost::default(),
            counts: None,
            journal: None,
        };
        node.run_ahead();
        node
    }

    /// Wires the node's ADC channels, port pins and DACs to the plant (when its file wires
    /// any): the CPU stops for them as the module docs say. `seed` drives the noise of an
    /// injected sensor fault.
    pub fn with_plant(mut self, env: SharedEnv, seed: u64) -> FirmwareNode {
        let watched = Wiring::watched(&self.spec);
        if watched == mcs51::Watched::default() {
            return self;
        }
        self.wiring = Some(Wiring::new(env, &self.spec, seed));
        self.now.cpu.watch(watched);
        self.run_ahead();
        self
    }

    /// Counts the instructions it executes from power-on into `counts` ([`super::coverage`]):
    /// exactly those of the path it takes. Before any input.
    pub fn with_coverage(mut self, counts: SharedCounts) -> FirmwareNode {
        self.counts = Some(counts);
        self.journal = Some(Journal::default());
        self.run_ahead();
        self
    }

    /// Serves the plant where the CPU stopped for it, at the bus time of that clock.
    fn serve_plant(&mut self) {
        self.now.plant_stop = false;
        let at = self.time_of(self.now.clocks());
        let Some(w) = self.wiring.as_mut() else {
            return;
        };
        let next = w.serve(&self.spec, &mut self.now, at);
        // The first machine cycle whose time is at or after the plant's next step.
        let cycle = if next == BusTime::NEVER {
            u64::MAX
        } else {
            let clock = next
                .since(self.power_on)
                .as_ticks()
                .div_ceil(self.spec.clock.as_ticks().max(1));
            let per = self.now.cpu.clocks_per_cycle();
            self.now.cpu.cycles() + clock.saturating_sub(self.now.clocks()).div_ceil(per)
        };
        self.now.cpu.inputs_hold_until(cycle);
    }

    /// Its spec.
    pub fn spec(&self) -> &FirmwareSpec {
        &self.spec
    }

    fn time_of(&self, clock: u64) -> BusTime {
        self.power_on
            .checked_add(self.spec.clock.saturating_mul(clock))
            .unwrap_or(BusTime::NEVER)
    }

    fn clock_at(&self, t: BusTime) -> u64 {
        t.since(self.power_on).as_ticks() / self.spec.clock.as_ticks().max(1)
    }

    /// Runs ahead from `now` (see the module docs).
    fn run_ahead(&mut self) {
        self.checkpoints.clear();
        self.at_wake = None;
        // What the last run ahead executed is counted or dropped by now.
        self.now.journaled = 0;
        if let Some(j) = &mut self.journal {
            j.clear();
        }
        if self.failed.is_some() {
            self.ahead = self.now.clone();
            self.stop = Stop::Failed(String::new());
            return;
        }
        let mut m = self.now.clone();
        let start = executed(&m);
        let limit = m.clocks().saturating_add(self.horizon);
        let chunk = (self.horizon / COPIES).max(CHUNK);
        // An input may have moved the firmware on to a loop that waits: look at once, then
        // after gaps that double while looks find none.
        let mut gap = LOOK_GAP.0;
        let mut look_at = m.clocks();
        // Whether `m` has left `now`.
        let mut moved = false;
        self.stop = loop {
            // `now` is the first copy; a look may have kept one lately.
            if m.clocks() > self.now.clocks()
                && self
                    .checkpoints
                    .last()
                    .is_none_or(|c| m.clocks() >= c.clocks().saturating_add(CHUNK))
            {
                self.checkpoints.push(m.clone());
            }
            let target = m.clocks().saturating_add(chunk).min(limit);
            if self.spec.skip_idle_loops && m.clocks() >= look_at {
                let at_now = m.clocks() == self.now.clocks() && !moved;
                moved = true;
                match find_loop(
                    &mut m,
                    target,
                    &mut self.checkpoints,
                    &self.now,
                    at_now,
                    &mut self.journal,
                ) {
                    Err(e) => break Stop::Failed(e.to_string()),
                    Ok(Some(turn)) => {
                        let fresh = if turn.reads_inputs {
                            m.cpu.clocks_at_cycle(m.cpu.stale_from())
                        } else {
                            u64::MAX
                        };
                        let until = m.next_change().min(fresh);
                        if until.saturating_sub(m.clocks()) < PARK_MIN {
                            // A short wait (an ADC conversion) costs less run than a wake.
                            look_at = m.clocks().saturating_add(gap);
                            continue;
                        }
                        (self.at_wake, self.wake_turns) = match wake_of(&m, turn, until, &mut self.journal) {
                            Some((w, turns)) => (Some(w), turns),
                            None => (None, 0),
                        };
                        if let Some(w) = &self.at_wake {
                            self.cost.executed += executed(w).saturating_sub(executed(&m));
                        }
                        let wake = self.at_wake.as_ref().map_or(until, Machine::clocks);
                        break Stop::Parked { turn, until, wake };
                    }
                    Ok(None) => {
                        look_at = m.clocks().saturating_add(gap);
                        gap = (gap * 2).min(LOOK_GAP.1);
                    }
                }
            } else {
                let target = if self.spec.skip_idle_loops {
                    target.min(look_at.max(m.clocks() + 1))
                } else {
                    target
                };
                moved = true;
                if let Err(e) = run_journaled(&mut m, target, None, &mut self.journal) {
                    break Stop::Failed(e.to_string());
                }
            }
            if !m.board.actions.is_empty() {
                break Stop::Actions;
            }
            if m.plant_stop {
                break Stop::Plant;
            }
            if m.clocks() >= limit {
                break Stop::Horizon;
            }
        };
        self.cost.executed += executed(&m).saturating_sub(start);
        self.ahead = m;
    }

    /// Where the machine at clock `n` (not before `now`) is found, and how.
    fn source(&self, n: u64) -> (Source, Path) {
        let reached = self.ahead.clocks();
        match self.stop {
            _ if n <= self.now.clocks() => (Source::Now, Path::Here),
            // Found when it parked: the whole turns, then the rest to the wake.
            Stop::Parked { wake, .. } if n == wake && self.at_wake.is_some() => {
                (Source::AtWake, Path::Skipped)
            }
            Stop::Parked { turn, until, .. } if n >= reached => {
                // Whole turns that end before the next change: from there it runs.
                let skip_to = n.min(until.saturating_sub(1));
                let turns = skip_to.saturating_sub(reached) / turn.clocks.max(1);
                (Source::Ahead(Some((turn, turns))), Path::Skipped)
            }
            _ if n >= reached => (Source::Ahead(None), Path::Ahead),
            _ => {
                // An input came first: back to the last copy before it (`now` is the first).
                let k = self.checkpoints.partition_point(|c| c.clocks() <= n);
                (k.checked_sub(1).map_or(Source::Now, Source::Copy), Path::Back)
            }
        }
    }

    /// The machine at clock `n` (not before `now`), found from the run ahead where it holds,
    /// without changing anything.
    fn project(&self, n: u64) -> Machine {
        let (source, path) = self.source(n);
        let mut machine = match source {
            Source::Now => self.now.clone(),
            Source::AtWake => self.at_wake.as_ref().unwrap_or(&self.ahead).clone(),
            Source::Ahead(skip) => {
                let mut m = self.ahead.clone();
                if let Some((turn, turns)) = skip {
                    m.pass(turn, turns);
                }
                m
            }
            Source::Copy(i) => self.checkpoints.get(i).unwrap_or(&self.now).clone(),
        };
        run_on(&mut machine, n, self.fault_ahead(path), None);
        machine
    }

    /// Adds to the counts, when coverage is on, what the run ahead executed from `now` to the
    /// machine `source` names: the path the node now takes.
    fn commit(&self, source: Source) {
        let (Some(counts), Some(journal)) = (&self.counts, &self.journal) else {
            return;
        };
        let counts = &mut *counts.borrow_mut();
        let ahead = self.ahead.journaled;
        let pass = |turns: u64, counts: &mut _| {
            if let Stop::Parked { turn, .. } = self.stop {
                journal.apply(turn.journal.0..turn.journal.1, turns, counts);
            }
        };
        match source {
            Source::Now => {}
            Source::Copy(i) => {
                let end = self.checkpoints.get(i).map_or(0, |c| c.journaled);
                journal.apply(0..end, 1, counts);
            }
            Source::Ahead(skip) => {
                journal.apply(0..ahead, 1, counts);
                if let Some((_, turns)) = skip {
                    pass(turns, counts);
                }
            }
            Source::AtWake => {
                journal.apply(0..ahead, 1, counts);
                pass(self.wake_turns, counts);
                let end = self.at_wake.as_ref().map_or(ahead, |w| w.journaled);
                journal.apply(ahead..end, 1, counts);
            }
        }
    }

    /// The fault the run ahead stopped with, when the machine is found where it stopped.
    fn fault_ahead(&self, path: Path) -> Option<String> {
        match &self.stop {
            Stop::Failed(message) if path == Path::Ahead => Some(message.clone()),
            _ => None,
        }
    }

    /// Brings `now` to clock `n`. The machine it starts from is moved rather than copied, so
    /// the run ahead is spent: [`FirmwareNode::run_ahead`] must follow before it is read.
    fn advance_to(&mut self, n: u64) {
        if self.failed.is_some() {
            return;
        }
        if let Some(last) = self.traced_until(n) {
            self.step_traced(last);
        }
        let (source, path) = self.source(n);
        self.commit(source);
        match source {
            Source::Now => {}
            Source::AtWake => {
                if let Some(m) = self.at_wake.take() {
                    self.now = m;
                }
            }
            Source::Ahead(skip) => {
                std::mem::swap(&mut self.now, &mut self.ahead);
                if let Some((turn, turns)) = skip {
                    self.now.pass(turn, turns);
                }
            }
            Source::Copy(i) => {
                if let Some(copy) = self.checkpoints.get_mut(i) {
                    std::mem::swap(&mut self.now, copy);
                }
            }
        }
        let fault = self.fault_ahead(path);
        let (actions, failed, executed) = run_on(&mut self.now, n, fault, self.counts.as_ref());
        self.cost.executed += executed;
        match path {
            Path::Here | Path::Skipped => {}
            Path::Ahead => self.horizon = (self.horizon * 2).min(HORIZON.1),
            Path::Back => {
                self.cost.backs += 1;
                self.horizon = (self.horizon / 2).max(HORIZON.0);
            }
        }
        if let Some(message) = failed {
            self.failed = Some(format!("{}: {message}", self.spec.name));
        }
        self.command(actions);
        self.serial();
        self.log_writes();
    }

    /// The firmware's writes to its controllers' registers, at debug level, once each: only
    /// the path the node took, never a run ahead that an input sent back.
    fn log_writes(&mut self) {
        let Some(log) = self.now.writes.as_mut() else {
            return;
        };
        for (clock, base, register, value) in std::mem::take(log) {
            let at = self.time_of(clock);
            tracing::debug!(
                node = %self.spec.name,
                at = %at,
                "SJA1000 at {base:04X}h: register {register} <- {value:02X}h"
            );
        }
    }

    /// Turns chip requests into commands for their controllers.
    fn command(&mut self, actions: Vec<Request>) {
        for Request { chip, action, tuned } in actions {
            let mut push = |c| self.commands.push_back((chip, c));
            match action {
                Action::Online {
                    listen_only,
                    self_test,
                    ..
                } => {
                    push(ControllerCommand::Tuned(tuned));
                    push(ControllerCommand::Online {
                        listen_only,
                        self_test,
                    });
                }
                Action::StartRecovery {
                    listen_only,
                    self_test,
                } => {
                    push(ControllerCommand::Tuned(tuned));
                    push(ControllerCommand::Online {
                        listen_only,
                        self_test,
                    });
                    push(ControllerCommand::Recover);
                }
                Action::Offline => push(ControllerCommand::Offline),
                // Self reception is the chip's: it stores its own frame when told it was sent.
                Action::Transmit {
                    frame, single_shot, ..
                } => push(if single_shot {
                    ControllerCommand::TransmitOnce(frame)
                } else {
                    ControllerCommand::Transmit(frame)
                }),
                Action::Abort => push(ControllerCommand::Abort),
                Action::Sleep(on) => push(ControllerCommand::Sleep(on)),
                Action::SetCounters { tec, rec } => push(ControllerCommand::SetCounters { tec, rec }),
            }
        }
    }

    /// Lines the firmware wrote to its serial port go to the log; a line longer than
    /// [`SERIAL_LINE`] bytes in pieces of that length, each but the last marked as cut.
    fn serial(&mut self) {
        let bytes = self.now.cpu.take_serial();
        for b in bytes {
            if b == b'\n' {
                self.log_serial("");
            } else {
                self.serial.push(b);
                if self.serial.len() >= SERIAL_LINE {
                    self.log_serial(" [cut: the line goes on]");
                }
            }
        }
    }

    /// Logs the serial line so far, with `note` after it, and starts a new one.
    fn log_serial(&mut self, note: &str) {
        let line = String::from_utf8_lossy(&self.serial);
        let line = line.trim_end_matches(['\r', ' ']);
        tracing::info!(node = %self.spec.name, "serial: {line}{note}");
        self.serial.clear();
    }

    /// An input for chip `chip` at `at`.
    fn input(&mut self, at: BusTime, chip: usize, events: &[BusSide]) {
        let started = std::time::Instant::now();
        if !events.is_empty() {
            self.cost.inputs += 1;
        }
        self.take_input(at, chip, events);
        self.cost.host += started.elapsed();
    }

    fn take_input(&mut self, at: BusTime, chip: usize, events: &[BusSide]) {
        let n = self.clock_at(at);
        self.advance_to(n);
        // Stopped for the plant on the way (normally at `n` itself, the wake it asked for), or
        // woken where the CPU would stop for it.
        if self.wiring.is_some() && self.now.cpu.inputs_due() {
            self.now.plant_stop = true;
        }
        while self.now.plant_stop && self.failed.is_none() {
            self.serve_plant();
            if self.now.clocks() >= n {
                break;
            }
            self.run_ahead();
            self.advance_to(n);
        }
        for &e in events {
            self.now.input(chip, e);
        }
        let actions = self.now.take_actions();
        self.command(actions);
        self.run_ahead();
    }
}

impl FirmwareNode {
    /// Whether a frame at `at` would find the controllers as they are now, and not be taken:
    /// the run ahead got past `at` (or waits in a loop that does the same until then) without
    /// writing a register that decides which frames the controller takes, and no controller
    /// takes such a frame now. Such a frame changes nothing, so the run ahead stands; the hub
    /// hears about every frame on the bus, and the chip keeps few.
    fn changes_nothing(&self, at: BusTime, frame: &Frame) -> bool {
        self.quiet_before().is_some_and(|end| self.clock_at(at) < end) && self.now.ignores(frame)
    }

    /// The first clock from which frames the controllers do not take now may change something:
    /// up to it, the run ahead (or the loop it waits in) writes none of the registers that
    /// decide which frames they take. `None` when that cannot be relied on (skipping off, a
    /// trace, a fault).
    fn quiet_before(&self) -> Option<u64> {
        let usable = self.spec.skip_idle_loops
            && self.failed.is_none()
            && self.trace.is_none()
            && self.ahead.board.filter_writes == self.now.board.filter_writes;
        usable.then(|| match &self.stop {
            // The loop does the same until its change; from there to the wake, the look for
            // the wake ran it and saw what it wrote.
            Stop::Parked { until, .. } => {
                let looked = self
                    .at_wake
                    .as_ref()
                    .filter(|w| w.board.filter_writes == self.now.board.filter_writes)
                    .map_or(0, |w| w.clocks().saturating_add(1));
                (*until).max(looked)
            }
            _ => self.ahead.clocks().saturating_add(1),
        })
    }
}

impl FirmwareNode {
    /// A loop whose turns do the same changes when its next change comes (a timer, the ADC,
    /// the CAN timer, the plant's next step for a loop that reads it): the node is woken at the
    /// instruction boundary where the CPU first sees it.
    fn parked_wake(&self, wake: u64) -> Option<BusTime> {
        (self.failed.is_none() && wake != u64::MAX).then(|| self.time_of(wake))
    }
}

/// `m` parked in a loop of `turn`, at the first instruction boundary at or after `until`: where
/// [`FirmwareNode::project`] finds it when woken then (or where it stops first for the bus or
/// the plant); `None` when nothing is coming, or the CPU fails on the way.
///
/// When the change is an event shortly before the wired inputs go stale, the wake is the first
/// boundary after they do instead (or where the CPU first asks the bus for something): the
/// node then reads the plant at that wake, where it would stop to read it soon after, and is
/// woken once rather than twice.
fn wake_of(m: &Machine, turn: Turn, until: u64, journal: &mut Option<Journal>) -> Option<(Machine, u64)> {
    if until == u64::MAX {
        return None;
    }
    let mut trial = m.clone();
    let turns = until.saturating_sub(1).saturating_sub(m.clocks()) / turn.clocks.max(1);
    trial.pass(turn, turns);
    // An error here is met again, and reported, when the node runs there.
    if run_journaled(&mut trial, until, None, journal).is_err() {
        return None;
    }
    let stale = trial.cpu.clocks_at_cycle(trial.cpu.stale_from());
    let quiet = trial.board.actions.is_empty() && !trial.plant_stop;
    if quiet
        && stale > trial.clocks()
        && stale - trial.clocks() <= LOOK_SPAN
        && run_journaled(&mut trial, stale, None, journal).is_err()
    {
        return None;
    }
    Some((trial, turns))
}

/// Looks for a loop whose turns do the same until something changes ([`Machine::repeats`]):
/// runs `m` until its PC comes back to where it is (for [`LOOK_SPAN`] clocks at most, not past
/// `until`) and compares; while the PC comes back to a state that differs, or does not come
/// back in time, looks again from where it got, [`LOOK_TURNS`] times at most (an interrupt, or
/// the work before an idle loop, ends a turn that differs). The turn,
/// with `m` one turn further on; `None` (with `m` moved on as far as it ran) if none was seen,
/// a chip asked for the bus or the CPU stopped for the plant.
///
/// A turn's head that is not compared (its PC did not come back) is kept in `copies`, as a copy
/// of the run ahead from `now`, when it lies after `now` and [`CHUNK`] clocks or more after the
/// last one there: an input that sends the run back finds a copy near it. `at_now` says that
/// `m` has not left `now`: its first head is `now` itself.
fn find_loop(
    m: &mut Machine,
    until: u64,
    copies: &mut Vec<Machine>,
    now: &Machine,
    mut at_now: bool,
    journal: &mut Option<Journal>,
) -> Result<Option<Turn>, mcs51::Error> {
    for _ in 0..LOOK_TURNS {
        if m.cpu.inputs_due() {
            m.plant_stop = true;
            return Ok(None);
        }
        // `m` unchanged from `now` needs no copy of its own (a copy is a kilobyte or more).
        let head = if std::mem::take(&mut at_now) {
            Cow::Borrowed(now)
        } else {
            Cow::Owned(m.clone())
        };
        run_journaled(
            m,
            until.min(head.clocks().saturating_add(LOOK_SPAN)),
            Some(head.cpu.pc()),
            journal,
        )?;
        let stopped = !m.board.actions.is_empty() || m.plant_stop || m.clocks() >= until;
        if !stopped && m.cpu.pc() == head.cpu.pc() && m.clocks() > head.clocks() {
            if let Some(turn) = m.repeats(head) {
                return Ok(Some(turn));
            }
        } else if copies
            .last()
            .map_or(now.clocks(), |c| c.clocks().saturating_add(CHUNK))
            <= head.clocks()
            && head.clocks() > now.clocks()
        {
            copies.push(head.into_owned());
        }
        if stopped {
            return Ok(None);
        }
    }
    Ok(None)
}

/// A line the firmware had begun on its serial port when the node goes (the run ends, or the
/// supervisor replaces it) is not lost: it goes to the log as it is.
///
/// And what it cost the host goes to the log (target `firmware_stats`, level info): machine
/// cycles of bus time, how many of them it executed and passed in closed form, how many it
/// executed in all (runs ahead that inputs sent back included), its wakes, inputs and
/// inputs that sent it back, and the host time they took.
impl Drop for FirmwareNode {
    fn drop(&mut self) {
        if !self.serial.is_empty() {
            self.log_serial(" [no end of line: the node stopped]");
        }
        let c = self.cost;
        let (cycles, skipped) = (self.now.cpu.cycles(), self.now.cpu.skipped_cycles());
        tracing::info!(
            target: "firmware_stats",
            node = %self.spec.name,
            "{cycles} machine cycles: {} executed, {skipped} passed in closed form; {} executed in all; \
             {} wakes, {} inputs, {} sent back; {:.3} s host time",
            cycles.saturating_sub(skipped),
            c.executed,
            c.wakes,
            c.inputs,
            c.backs,
            c.host.as_secs_f64()
        );
    }
}

/// Its controllers on the bus are its chips, in the node file's order: controller `k` is chip `k`.
impl NodeLogic for FirmwareNode {
    fn handle_frame(&mut self, now: BusTime, frame: &Frame) {
        self.handle_frame_on(0, now, frame);
    }

    fn handle_frame_on(&mut self, chip: usize, now: BusTime, frame: &Frame) {
        if self.changes_nothing(now, frame) {
            return;
        }
        self.input(now, chip, &[BusSide::Received(*frame)]);
    }

    fn handle_timeout(&mut self, now: BusTime) {
        self.cost.wakes += 1;
        self.input(now, 0, &[]);
    }

    fn handle_event(&mut self, now: BusTime, event: ControllerEvent) {
        self.handle_event_on(0, now, event);
    }

    fn handle_event_on(&mut self, chip: usize, now: BusTime, event: ControllerEvent) {
        let mut side = Vec::new();
        match event {
            ControllerEvent::Sent(_) => side.push(BusSide::Transmitted),
            ControllerEvent::Aborted(_) | ControllerEvent::Refused(_) => side.push(BusSide::Aborted),
            ControllerEvent::Counters { tec, rec } => side.push(BusSide::Counters {
                tec,
                rec,
                state: state_of(tec, rec),
            }),
            ControllerEvent::State(s) => {
                if let Some(state) = self.states.get_mut(chip) {
                    if *state == ErrorState::BusOff && s == ErrorState::Active {
                        side.push(BusSide::RecoveryDone);
                    }
                    *state = s;
                }
            }
            ControllerEvent::BusError {
                error,
                transmitting,
                location,
            } => side.push(BusSide::BusError {
                error,
                transmitting,
                segment: ecc_segment(location),
            }),
            ControllerEvent::ArbitrationLost(bit) => side.push(BusSide::ArbitrationLost {
                bit: u8::try_from(bit).unwrap_or(u8::MAX),
            }),
            // The SJA1000 counts TXERR down from 127 with the sequences of recovery.
            ControllerEvent::RecoveryProgress(sequences) => side.push(BusSide::Counters {
                tec: 127u16.saturating_sub(u16::from(sequences)),
                rec: 0,
                state: ErrorState::BusOff,
            }),
            // The chip keeps its own receive FIFO and counts its own overruns.
            ControllerEvent::Overrun => {}
            ControllerEvent::Woken => side.push(BusSide::Woken),
        }
        self.input(now, chip, &side);
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        None
    }

    fn poll_command(&mut self) -> Option<(usize, ControllerCommand)> {
        self.commands.pop_front()
    }

    fn poll_timeout(&self) -> Option<BusTime> {
        match self.stop {
            // A traced node is woken now and then even in a loop that changes nothing, so that
            // its trace keeps up with the run.
            Stop::Parked { wake, .. } if self.trace_open() => {
                let traced = self.time_of(self.now.clocks().saturating_add(self.horizon));
                Some(self.parked_wake(wake).map_or(traced, |t| t.min(traced)))
            }
            Stop::Parked { wake, .. } => self.parked_wake(wake),
            Stop::Failed(_) if self.failed.is_some() => None,
            _ => Some(self.time_of(self.ahead.clocks())),
        }
    }

    fn wants_every_event(&self) -> bool {
        true
    }

    /// The frames [`FirmwareNode::changes_nothing`] would tell apart, for the hub to leave out.
    fn unheeded(&self) -> Option<Unheeded> {
        let end = self.quiet_before()?;
        Some(Unheeded {
            before: self.time_of(end),
            heeded: self.now.heeded()?,
        })
    }

    fn failed(&self) -> Option<String> {
        self.failed.clone()
    }

    /// A sensor fault acts on the wire that reads the signal ([`super::wiring`]); a node with no
    /// input wired to it refuses it.
    fn inject(&mut self, fault: &NodeFault, now: BusTime) -> Result<(), Refused> {
        let (signal, reads) = match fault {
            NodeFault::Sensor { signal, reads } => (signal, Some(*reads)),
            NodeFault::SensorRepaired { signal } => (signal, None),
        };
        let port = self
            .wiring
            .as_ref()
            .and_then(|w| w.input_port(&self.spec, signal))
            .ok_or_else(|| Refused(format!("no input of {} is wired to {signal}", self.spec.name)))?;
        if let Some(w) = self.wiring.as_mut() {
            w.set_fault(port, reads, now);
        }
        Ok(())
    }

    /// A traced node brings its trace to the end of the run: the instructions since its last
    /// wake. An untraced node has nothing to write, and stays as its last input left it.
    fn run_ends(&mut self, at: BusTime) {
        if self.trace.is_some() || self.counts.is_some() {
            self.advance_to(self.clock_at(at));
            self.run_ahead();
        }
    }

    /// The machine at `at`, the on-chip controller told the time: its CAN timer shows that
    /// moment, however lately the firmware last reached it.
    fn hardware(&self, at: BusTime) -> Option<HardwareState> {
        let mut machine = self.project(self.clock_at(at));
        machine.sync_chip_time();
        Some(super::dump::state(&machine))
    }
}

/// The error state counters imply (ISO 11898-1 fault confinement).
fn state_of(tec: u16, rec: u16) -> ErrorState {
    if tec >= 256 {
        ErrorState::BusOff
    } else if tec >= 128 || rec >= 128 {
        ErrorState::Passive
    } else {
        ErrorState::Active
    }
}
