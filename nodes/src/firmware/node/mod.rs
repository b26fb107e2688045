//! [`FirmwareNode`]: a firmware image as a node's logic, in oscillator clocks.
//!
//! Time: oscillator clock `c` after power-on is bus time `power_on + c · period`, exactly (the
//! clock's period is a whole number of bus-clock ticks); a machine cycle is 12 clocks, or 6 in
//! the AT89C51CC03's X2 mode. The CPU runs ahead of the bus optimistically: after every input
//! it runs on from the present, keeping a copy of its state every [`CHUNK`] clocks or more
//! (about sixteen copies a run), until a chip asks the bus for something (a transmit request, a
//! mode change), until a horizon, or until it is found in a loop whose whole state repeats. It asks
//! to be woken when it stopped. An input that arrives before that moment (a frame, a
//! confirmation) sends it back to the last copy before the input, from where it runs to the
//! input's moment again: so it never acts on what it could not yet have read, and a run is the
//! same every time. A frame that the on-chip controller would not take, while the run ahead
//! writes none of its registers, changes nothing and sends nothing back.
//!
//! A loop whose whole state (CPU, internal RAM, SFRs, the chips) comes back after `P` clocks
//! changes nothing until an input arrives or the on-chip controller's CAN timer overflows
//! (OVRTIM): such a node asks to be woken at that overflow only (no wake at all without one),
//! and an input at clock `n` finds it where `n − c₀` mod `P` clocks into the loop puts it
//! (whole turns are skipped up to the overflow, the rest is run).
//!
//! Several chips: each is a controller of its own on the bus, controller `k` being chip `k` of
//! the node file. An input of controller `k` reaches chip `k` at its moment, and each chip's
//! requests become commands for its own controller; the CPU, its run ahead and its deadline are
//! the node's, one for all the chips.
//!
//! Plant wiring: a node whose ADC channels or port pins are wired to the plant reads them when
//! an input arrives and at least every [`SAMPLE_MS`] ms (it asks to be woken for it), and
//! between those moments sees them unchanged; its output pins reach the plant at the same
//! moments.

mod trace;

pub use trace::CpuTrace;

use super::machine::{Machine, Request};
use super::spec::FirmwareSpec;
use super::wiring::Wiring;
use crate::script::SharedEnv;
use bus::Frame;
use bus::fault::ErrorState;
use bus::node::{ControllerCommand, ControllerEvent, HardwareState, NodeLogic};
use bus::sja1000::{Action, BusSide, ecc_segment};
use bus::time::{BusDuration, BusTime};
use std::collections::VecDeque;
use std::sync::Arc;

/// Fewest oscillator clocks between kept copies of a run ahead (100 machine cycles): an input
/// that sends the run back costs at most that much again. A long run ahead keeps about
/// sixteen.
pub const CHUNK: u64 = 1_200;
/// Longest stretch of bus time a node wired to the plant goes without reading it, ms.
pub const SAMPLE_MS: u64 = 1;
/// Copies kept of a run ahead at its longest horizon.
const COPIES: u64 = 16;
/// Most chunks between two looks for a loop whose state repeats, when looks keep finding none.
const LOOK_BACKOFF: u32 = 64;
/// The shortest and longest horizon of a run ahead, oscillator clocks (1000 and 64 000 machine
/// cycles): it doubles while runs ahead are not cut short by an input and halves when they
/// are, so a node that hears frames often wastes little and a quiet one is seldom woken.
const HORIZON: (u64, u64) = (12_000, 768_000);
/// Instructions watched at the start of every chunk for a loop whose state repeats.
const LOOP_WATCH: usize = 64;
/// Longest piece of a serial line the log takes at once: a longer line goes out in pieces.
const SERIAL_LINE: usize = 256;

/// How a run ahead ended.
#[derive(Clone, Debug, PartialEq)]
enum Stop {
    /// A chip asked the bus for something.
    Actions,
    /// The horizon.
    Horizon,
    /// In a loop of this many clocks that changes nothing.
    Parked(u64),
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

/// The machine at some clock, and how it got there.
struct Projection {
    machine: Machine,
    actions: Vec<Request>,
    failed: Option<String>,
    path: Path,
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
    /// Chunks to run before the next look for a repeating loop, and how many to wait after a
    /// look that finds none: a node that is busy (delay loops count their registers down) pays
    /// for a look seldom, one that idles is found at once.
    look_in: u32,
    look_backoff: u32,
    /// The plant, when its signals are wired to the node, and the next time to read them.
    wiring: Option<Wiring>,
    next_sample: BusTime,
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
            look_in: 0,
            look_backoff: 1,
            wiring: None,
            next_sample: power_on,
        };
        node.run_ahead();
        node
    }

    /// Wires the node's ADC channels and port pins to the plant (when its file wires any): it
    /// reads them now and then at least every [`SAMPLE_MS`] ms of bus time.
    pub fn with_plant(mut self, env: SharedEnv) -> FirmwareNode {
        if self.spec.analog.is_empty() && self.spec.pins.is_empty() {
            return self;
        }
        self.wiring = Some(Wiring::new(env, &self.spec));
        let at = self.power_on;
        self.sample(at);
        self.run_ahead();
        self
    }

    /// Reads the plant into `now` when it is time.
    fn sample(&mut self, at: BusTime) {
        let Some(w) = self.wiring.as_mut() else {
            return;
        };
        if at < self.next_sample {
            return;
        }
        w.sample(&self.spec, &mut self.now, at);
        self.next_sample = at.saturating_add(BusDuration::from_millis(SAMPLE_MS));
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
        if self.failed.is_some() {
            self.ahead = self.now.clone();
            self.stop = Stop::Parked(0);
            return;
        }
        let mut m = self.now.clone();
        let limit = m.clocks().saturating_add(self.horizon);
        let chunk = (self.horizon / COPIES).max(CHUNK);
        // An input may have moved the firmware on to a loop that waits: look at once.
        self.look_in = 0;
        self.stop = loop {
            self.checkpoints.push(m.clone());
            if self.look_in == 0 && self.spec.skip_idle_loops {
                match find_loop(&mut m) {
                    Err(e) => break Stop::Failed(e.to_string()),
                    Ok(Some(period)) => {
                        self.look_backoff = 1;
                        break Stop::Parked(period);
                    }
                    Ok(None) if !m.board.actions.is_empty() => break Stop::Actions,
                    Ok(None) => {
                        self.look_backoff = (self.look_backoff * 2).min(LOOK_BACKOFF);
                        self.look_in = self.look_backoff;
                    }
                }
            }
            self.look_in = self.look_in.saturating_sub(1);
            let target = m.clocks().saturating_add(chunk).min(limit);
            if let Err(e) = m.run(target) {
                break Stop::Failed(e.to_string());
            }
            if !m.board.actions.is_empty() {
                break Stop::Actions;
            }
            if m.clocks() >= limit {
                break Stop::Horizon;
            }
        };
        self.ahead = m;
    }

    /// The machine at clock `n` (not before `now`), found from the run ahead where it holds,
    /// without changing anything: what it asked of the bus on the way, and a fault if it hit
    /// one.
    fn project(&self, n: u64) -> Projection {
        let reached = self.ahead.clocks();
        let (mut machine, path) = match self.stop {
            _ if n <= self.now.clocks() => (self.now.clone(), Path::Here),
            Stop::Parked(period) if n >= reached && period > 0 => {
                // Whole turns up to the CAN timer's overflow at most: from there it runs.
                let skip_to = self.ahead.timer_due().map_or(n, |due| due.min(n));
                let loops = skip_to.saturating_sub(reached) / period;
                let mut m = self.ahead.clone();
                m.skip_clocks(loops * period);
                (m, Path::Skipped)
            }
            _ if n >= reached => (self.ahead.clone(), Path::Ahead),
            _ => {
                // An input came first: back to the last copy before it.
                let i = self
                    .checkpoints
                    .partition_point(|c| c.clocks() <= n)
                    .saturating_sub(1);
                (self.checkpoints.get(i).unwrap_or(&self.now).clone(), Path::Back)
            }
        };
        let mut failed = match &self.stop {
            Stop::Failed(message) if path == Path::Ahead => Some(message.clone()),
            _ => None,
        };
        let mut actions = machine.take_actions();
        while machine.clocks() < n && failed.is_none() {
            if let Err(e) = machine.run(n) {
                failed = Some(e.to_string());
            }
            actions.extend(machine.take_actions());
        }
        Projection {
            machine,
            actions,
            failed,
            path,
        }
    }

    /// Brings `now` to clock `n`.
    fn advance_to(&mut self, n: u64) {
        if self.failed.is_some() {
            return;
        }
        if let Some(last) = self.traced_until(n) {
            self.step_traced(last);
        }
        let p = self.project(n);
        match p.path {
            Path::Here | Path::Skipped => {}
            Path::Ahead => self.horizon = (self.horizon * 2).min(HORIZON.1),
            Path::Back => self.horizon = (self.horizon / 2).max(HORIZON.0),
        }
        if let Some(message) = p.failed {
            self.failed = Some(format!("{}: {message}", self.spec.name));
        }
        self.command(p.actions);
        self.now = p.machine;
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
        let n = self.clock_at(at);
        self.advance_to(n);
        self.sample(at);
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
    /// the run ahead got past `at` (or idles in a loop) without writing a controller register,
    /// and no controller takes such a frame now. Such a frame changes nothing, so the run ahead
    /// stands; the hub hears about every frame on the bus, and the chip keeps few.
    fn changes_nothing(&self, at: BusTime, frame: &Frame) -> bool {
        let n = self.clock_at(at);
        let covered = n <= self.ahead.clocks() || matches!(self.stop, Stop::Parked(_));
        covered
            && self.spec.skip_idle_loops
            && self.failed.is_none()
            && self.trace.is_none()
            && self.ahead.board.can_writes == self.now.board.can_writes
            && self.now.ignores(frame)
    }
}

impl FirmwareNode {
    /// A loop that changes nothing does change when the on-chip controller's CAN timer
    /// overflows (OVRTIM, the CAN timer interrupt): the node is woken then.
    fn timer_wake(&self) -> Option<BusTime> {
        if self.failed.is_some() {
            return None;
        }
        self.ahead.timer_due().map(|clock| self.time_of(clock))
    }
}

/// Watches the first instructions of a chunk for a loop whose whole state repeats: the loop's
/// length in clocks, with `m` one loop further on; `None` (with `m` moved on as far as it ran)
/// if none was seen or a chip asked for the bus.
fn find_loop(m: &mut Machine) -> Result<Option<u64>, mcs51::Error> {
    let head = m.clone();
    for _ in 0..LOOP_WATCH {
        m.step()?;
        if !m.board.actions.is_empty() {
            return Ok(None);
        }
        if m.cpu.pc() == head.cpu.pc() && m.same_state(&head) {
            return Ok(Some(m.clocks() - head.clocks()));
        }
    }
    Ok(None)
}

/// A line the firmware had begun on its serial port when the node goes (the run ends, or the
/// supervisor replaces it) is not lost: it goes to the log as it is.
impl Drop for FirmwareNode {
    fn drop(&mut self) {
        if !self.serial.is_empty() {
            self.log_serial(" [no end of line: the node stopped]");
        }
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
        let ahead = match self.stop {
            // A traced node is woken now and then even in a loop that changes nothing, so that
            // its trace keeps up with the run.
            Stop::Parked(_) if self.trace_open() => {
                let traced = self.time_of(self.now.clocks().saturating_add(self.horizon));
                Some(self.timer_wake().map_or(traced, |t| t.min(traced)))
            }
            Stop::Parked(_) => self.timer_wake(),
            _ => Some(self.time_of(self.ahead.clocks())),
        };
        let sample = self.wiring.as_ref().map(|_| self.next_sample);
        match (ahead, sample) {
            (Some(a), Some(s)) => Some(a.min(s)),
            (a, s) => a.or(s),
        }
    }

    fn wants_every_event(&self) -> bool {
        true
    }

    fn failed(&self) -> Option<String> {
        self.failed.clone()
    }

    /// A traced node brings its trace to the end of the run: the instructions since its last
    /// wake. An untraced node has nothing to write, and stays as its last input left it.
    fn run_ends(&mut self, at: BusTime) {
        if self.trace.is_some() {
            self.advance_to(self.clock_at(at));
        }
    }

    fn hardware(&self, at: BusTime) -> Option<HardwareState> {
        Some(super::dump::state(&self.project(self.clock_at(at)).machine))
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
