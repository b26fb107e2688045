//! A harvester driven from outside, one call at a time: what the python-can interface (the
//! `harvemu` Python package) stands on.
//!
//! Contract: [`Session::start`] loads a harvester config (the built-in default without a path),
//! leaves out the nodes named, and puts a program in their place: a node of its own on the bus,
//! with a controller like any other (it arbitrates, is acknowledged, retransmits). The harvester
//! runs on a thread of its own, behind a channel, so a session can be used from any thread.
//!
//! In virtual time (the default) bus time moves only inside the session's calls:
//! [`Session::recv`], [`Session::run_for`], [`Session::wait_ready`], and a [`Session::send`]
//! that waits for the nodes' boot (the first) or for room in the transmit queue. The same seed and
//! the same calls give the same frames at the same times, run after run. Paced
//! ([`Options::paced`]), the bus keeps to the wall clock and runs between calls too, and a call
//! from one thread is not held up by another's `recv` or `run_for`.
//!
//! Frames that reach the program pass its filters when they arrive (the others are dropped, as a
//! kernel filter drops them); with the error frames asked for ([`Options::error_frames`]), they
//! wait in time order in a queue of at most [`QUEUE`] of each, the oldest dropped beyond it, as
//! in a socket's buffer: also while the program does not wait for one ([`Session::run_for`]).
//! A program that changes nothing on the bus may take it a slice at a time instead
//! ([`Session::slice`]): the harvester computes each slice while the program works through the
//! last, and other calls are carried out at the end of the slice being computed.
//! Periodic tasks are sent by the program's node in bus time; actions are a scenario timeline's,
//! carried out at the present bus time, their faults ended at their `until_s` as the bus runs;
//! expectations are checked as a scenario's ([`Session::check`]).

mod driver;
mod program;

use crate::harvester::Harvester;
use crate::{Error, Result};
use bus::Frame;
use bus::time::{BusDuration, BusTime, Epoch};
use bus_runtime::hub::default_epoch;
pub use program::{Filter, Inbox, QUEUE};
use std::path::PathBuf;
use std::thread::JoinHandle;
use tokio::sync::{mpsc, oneshot};

/// How long a thread looks for an answer (the session's caller) or the next command (the
/// harvester's thread) before it sleeps on it. Both usually come within tens of microseconds, and
/// a sleep costs a wake-up through the kernel each way.
const LOOK: std::time::Duration = std::time::Duration::from_micros(200);

/// Whether to look once more, since `started`. The thread yields in between rather than spinning:
/// on a busy machine, or on one core, the thread it waits for may need this core to answer.
pub(crate) fn look_again(started: std::time::Instant) -> bool {
    if started.elapsed() >= LOOK {
        return false;
    }
    std::thread::yield_now();
    true
}

/// Bus time a [`Session::slice`] covers, s.
pub const SLICE_S: f64 = 0.1;

/// Longest a `recv` without a timeout waits, in bus time: the longest run a scenario may have.
pub const FOREVER_S: f64 = crate::scenario::MAX_DURATION_S;

/// What a session is made of.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// The harvester config; the built-in default when `None`.
    pub config: Option<PathBuf>,
    /// Nodes left out ("F5" for the monitor), whose place the program takes.
    pub without: Vec<String>,
    /// The run's seed; the config's when `None`.
    pub seed: Option<u64>,
    /// The program's name on the bus (in traces and reports).
    pub name: String,
    /// Bus time paced by the wall clock, the bus running between calls too; virtual time when
    /// false.
    pub paced: bool,
    /// Where bus time zero lies on the wall clock; `None` for harvemu's default (as
    /// `--start-time`: 2024-01-01T00:00:00Z in virtual time, the wall clock at the start when
    /// paced).
    pub start_time: Option<Epoch>,
    /// The program receives the frames its own controller sent, at their end of frame (as
    /// SocketCAN's `CAN_RAW_RECV_OWN_MSGS`).
    pub own_frames: bool,
    /// Whose error frames reach the program.
    pub error_frames: ErrorFrames,
}

/// Whose error frames reach the program, as a SocketCAN socket's error mask would let them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ErrorFrames {
    /// None.
    None,
    /// Its own controller's, as a SocketCAN interface delivers its controller's (python-can's
    /// socketcan interface asks for them all).
    #[default]
    Own,
    /// Every controller's on the bus.
    All,
}

/// A frame the program received, with its end-of-frame time.
#[derive(Clone, Debug, PartialEq)]
pub struct Received {
    /// Bus time, s.
    pub at_s: f64,
    /// The frame.
    pub frame: Frame,
    /// Sent by the program's own controller ([`Options::own_frames`]).
    pub own: bool,
}

/// A controller's error frame as it reaches the program.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorReceived {
    /// Bus time, s: the first bit of the error or overload flag, or the moment of the state
    /// change or overrun.
    pub at_s: f64,
    /// The controller that reports it.
    pub controller: String,
    /// SocketCAN's `can_id`: `CAN_ERR_FLAG` with the error classes.
    pub can_id: u32,
    /// The details, as linux/can/error.h lays them out.
    pub data: [u8; 8],
}

/// What reaches the program: a frame or an error frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Delivered {
    /// A data or remote frame.
    Frame(Received),
    /// A controller's error frame.
    Error(ErrorReceived),
}

impl Delivered {
    /// Bus time, s.
    pub fn at_s(&self) -> f64 {
        match self {
            Delivered::Frame(r) => r.at_s,
            Delivered::Error(e) => e.at_s,
        }
    }

    /// The frame, when it is one.
    pub fn frame(self) -> Option<Received> {
        match self {
            Delivered::Frame(r) => Some(r),
            Delivered::Error(_) => None,
        }
    }
}

/// The program's controller, as it stands.
#[derive(Clone, Debug, PartialEq)]
pub struct Own {
    /// Its part on the bus, with its counters.
    pub state: NodeState,
    /// In listen-only mode ([`Session::set_listen_only`]).
    pub listen_only: bool,
}

pub(crate) enum Command {
    Filters(Vec<Filter>, oneshot::Sender<Result<()>>),
    Recv(f64, oneshot::Sender<Result<Option<Delivered>>>),
    Slice(oneshot::Sender<Result<(f64, Vec<Delivered>)>>),
    Send(Frame, f64, oneshot::Sender<Result<bool>>),
    ListenOnly(bool, oneshot::Sender<Result<()>>),
    Own(oneshot::Sender<Result<Own>>),
    RunFor(f64, oneshot::Sender<Result<f64>>),
    Periodic(Vec<Frame>, f64, Option<f64>, oneshot::Sender<Result<u64>>),
    StopPeriodic(u64, oneshot::Sender<Result<bool>>),
    Sent(oneshot::Sender<Result<u64>>),
    States(oneshot::Sender<Result<Vec<NodeState>>>),
    Display(oneshot::Sender<Result<Option<String>>>),
    Input(String, f64, oneshot::Sender<Result<()>>),
    Act(String, oneshot::Sender<Result<()>>),
    Check(String, oneshot::Sender<Result<Vec<crate::scenario::Verdict>>>),
    ModifyPeriodic(u64, Vec<Frame>, oneshot::Sender<Result<bool>>),
}

/// A node's part on the bus, as its controller stands.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeState {
    /// Its name.
    pub name: String,
    /// "error active", "error passive" or "bus off".
    pub state: String,
    /// Transmit error counter.
    pub tec: u16,
    /// Receive error counter.
    pub rec: u16,
}

impl NodeState {
    /// A node's state as the hub's snapshot has it.
    pub(crate) fn of(n: &bus::schedule::NodeSnapshot) -> NodeState {
        NodeState {
            name: n.name.clone(),
            state: n.state.to_string(),
            tec: n.tec,
            rec: n.rec,
        }
    }
}

/// A running harvester with a program on its bus.
pub struct Session {
    commands: Option<mpsc::UnboundedSender<Command>>,
    thread: Option<JoinHandle<()>>,
    epoch: Epoch,
    bitrate: u32,
    ready: BusTime,
}

/// When every node on the bus has booted: the time relay that powers the field nodes, plus the
/// longest start-up of those present (zero when there are none).
fn ready_at(h: &Harvester) -> BusTime {
    let present = |n: &str| h.scripts.iter().any(|s| s.name == n) || h.firmware.iter().any(|f| f.name == n);
    let longest = h
        .expected
        .iter()
        .filter(|(n, _, _)| present(n))
        .map(|(_, _, ms)| *ms)
        .max();
    longest.map_or(BusTime::ZERO, |ms| h.relay() + BusDuration::from_millis(ms))
}

impl Session {
    /// Loads the harvester and starts it, paused at bus time zero. A bad config is an error
    /// naming its file and line.
    pub fn start(o: &Options) -> Result<Session> {
        let path = o.config.clone().unwrap_or_else(|| "configs/harvester.ron".into());
        let mut h = Harvester::load(&path)?;
        h.without(&o.without)?;
        let epoch = o.start_time.or(h.epoch).unwrap_or_else(|| default_epoch(o.paced));
        h.epoch = Some(epoch);
        let bitrate = h.config.network.bitrate;
        let ready = ready_at(&h);
        if let Some(seed) = o.seed {
            h.config.network.seed = seed;
        }
        let name = if o.name.is_empty() {
            "program".to_string()
        } else {
            o.name.clone()
        };
        let (tx, rx) = mpsc::unbounded_channel();
        let (started_tx, started) = oneshot::channel();
        let setup = driver::Setup {
            name,
            paced: o.paced,
            own_frames: o.own_frames,
            error_frames: o.error_frames,
            ready,
        };
        let thread = std::thread::Builder::new()
            .name("harvemu-session".into())
            .spawn(move || driver::drive(h, setup, rx, started_tx))
            .map_err(|e| Error::Internal(format!("cannot start the harvester's thread: {e}")))?;
        let session = Session {
            commands: Some(tx),
            thread: Some(thread),
            epoch,
            bitrate,
            ready,
        };
        started
            .blocking_recv()
            .map_err(|_| Error::Internal("the harvester's thread ended at start".into()))??;
        Ok(session)
    }

    fn ask<T>(&self, make: impl FnOnce(oneshot::Sender<Result<T>>) -> Command) -> Result<T> {
        let (tx, rx) = oneshot::channel();
        let gone = || Error::Internal("the harvester's thread has ended".into());
        self.commands
            .as_ref()
            .ok_or_else(gone)?
            .send(make(tx))
            .map_err(|_| gone())?;
        let mut rx = rx;
        let started = std::time::Instant::now();
        loop {
            match rx.try_recv() {
                Ok(answer) => return answer,
                Err(oneshot::error::TryRecvError::Empty) => {
                    if !look_again(started) {
                        break;
                    }
                }
                Err(oneshot::error::TryRecvError::Closed) => return Err(gone()),
            }
        }
        rx.blocking_recv().map_err(|_| gone())?
    }

    /// When bus time zero is, in seconds since 1970: the wall clock at the start when paced,
    /// 2024-01-01T00:00:00Z in virtual time (harvemu's traces are stamped from it).
    pub fn epoch_s(&self) -> f64 {
        self.epoch.as_micros() as f64 / 1e6
    }

    /// Sets the program's filters: from now on a frame reaches it when any of them passes it
    /// (every frame when the list is empty, as at the start). Frames waiting that none passes
    /// are dropped.
    pub fn set_filters(&self, filters: &[Filter]) -> Result<()> {
        self.ask(|tx| Command::Filters(filters.to_vec(), tx))
    }

    /// The oldest frame or error frame waiting for the program; when none is, runs the harvester
    /// (paced: waits for it) until one comes or `timeout_s` of bus time have passed (`None`:
    /// [`FOREVER_S`]). In virtual time a timeout of zero runs the bus for up to the longest
    /// frame's time, so that a loop of them moves bus time. Frames and error frames come in
    /// time order, and the bus stops at each while the session waits.
    pub fn recv(&self, timeout_s: Option<f64>) -> Result<Option<Delivered>> {
        let t = timeout_s.unwrap_or(FOREVER_S);
        if !(t.is_finite() && t >= 0.0) {
            return Err(Error::BadInput(format!("timeout {t} s is not a time")));
        }
        self.ask(|tx| Command::Recv(t.min(FOREVER_S), tx))
    }

    /// In virtual time, the next slice of the bus: every frame and error frame for the program
    /// up to the end of the next [`SLICE_S`] of bus time, with that end, s. The harvester
    /// computes each slice ahead, while the caller works through the last, so the bus stands one
    /// slice ahead of what has been handed over: any other call is carried out at the end of
    /// the slice being computed. Which slices there are depends on the calls alone, so this too
    /// is deterministic. Meant for a program that changes nothing on the bus (listen-only): one
    /// that answers what it receives wants [`Session::recv`], which stops the bus at each frame.
    pub fn slice(&self) -> Result<(f64, Vec<Delivered>)> {
        self.ask(Command::Slice)
    }

    /// Hands a frame to the program's controller, which sends it when the bus next runs. In
    /// virtual time the first frame waits until every node has booted ([`Session::ready_s`]),
    /// and when the controller's transmit queue is full the bus runs until there is room, for at
    /// most `timeout_s` of bus time; false when there was none by then. Paced, the queue is
    /// looked at once.
    pub fn send(&self, frame: Frame, timeout_s: f64) -> Result<bool> {
        if !(timeout_s.is_finite() && timeout_s >= 0.0) {
            return Err(Error::BadInput(format!("timeout {timeout_s} s is not a time")));
        }
        self.ask(|tx| Command::Send(frame, timeout_s.min(FOREVER_S), tx))
    }

    /// The bus's bit rate, bit/s.
    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }

    /// Bus time by which every node on the bus has booted, s: the time relay that powers the
    /// field nodes plus the longest of their start-up times. Before it, nodes may not yet
    /// acknowledge frames.
    pub fn ready_s(&self) -> f64 {
        self.ready.as_secs_f64()
    }

    /// Runs the harvester (paced: waits) until every node has booted ([`Session::ready_s`]);
    /// answers with the bus time then, s.
    pub fn wait_ready(&self) -> Result<f64> {
        let now = self.now()?;
        let left = self.ready.as_secs_f64() - now;
        if left > 0.0 { self.run_for(left) } else { Ok(now) }
    }

    /// Puts the program's controller in listen-only mode, or takes it out (it joins the bus
    /// again as a controller does, after 11 recessive bits). In listen-only mode it acknowledges
    /// nothing, sends nothing (its frames wait), and its error counters stay as they are.
    pub fn set_listen_only(&self, on: bool) -> Result<()> {
        self.ask(|tx| Command::ListenOnly(on, tx))
    }

    /// The program's controller as it stands.
    pub fn own(&self) -> Result<Own> {
        self.ask(Command::Own)
    }

    /// Runs the harvester (paced: waits for it) for `seconds` of bus time; answers with the bus
    /// time reached, s.
    pub fn run_for(&self, seconds: f64) -> Result<f64> {
        if !(0.0..=FOREVER_S).contains(&seconds) {
            return Err(Error::BadInput(format!(
                "{seconds} s is not a time from 0 to {FOREVER_S} s"
            )));
        }
        self.ask(|tx| Command::RunFor(seconds, tx))
    }

    /// Bus time now, s.
    pub fn now(&self) -> Result<f64> {
        self.run_for(0.0)
    }

    /// Sends `frames` in turn, the first now, then one every `period_s` of bus time, for
    /// `duration_s` if given (as python-can's `send_periodic`, in bus time); answers with the
    /// task's number.
    pub fn start_periodic(&self, frames: Vec<Frame>, period_s: f64, duration_s: Option<f64>) -> Result<u64> {
        if frames.is_empty() {
            return Err(Error::BadInput("a periodic task needs at least one frame".into()));
        }
        if !(1e-6..=FOREVER_S).contains(&period_s) {
            return Err(Error::BadInput(format!(
                "period {period_s} s is not from 1 µs to {FOREVER_S} s"
            )));
        }
        if let Some(d) = duration_s.filter(|d| !(0.0..=FOREVER_S).contains(d)) {
            return Err(Error::BadInput(format!("duration {d} s is not a time")));
        }
        self.ask(|tx| Command::Periodic(frames, period_s, duration_s, tx))
    }

    /// Frames the program's controller has sent so far (acknowledged on the bus).
    pub fn sent(&self) -> Result<u64> {
        self.ask(Command::Sent)
    }

    /// Every node's controller (the program's too), in the order they joined the bus.
    pub fn states(&self) -> Result<Vec<NodeState>> {
        self.ask(Command::States)
    }

    /// What the reference monitor shows, as JSON, when it runs (it is not left out).
    pub fn display(&self) -> Result<Option<String>> {
        self.ask(Command::Display)
    }

    /// Sets a plant input (`operator.speed`, `fault.door3_open`, ...) from now on.
    pub fn set_input(&self, input: &str, value: f64) -> Result<()> {
        let input = input.to_string();
        self.ask(move |tx| Command::Input(input, value, tx))
    }

    /// Carries out a scenario action, written as in a scenario's timeline (docs/SCENARIOS.md):
    /// `Disconnect("D3")`, `BitErrors(target: Node("D2"), hits: Always, until_s: Some(12.5))`,
    /// `Crash("B1")`, ... An `until_s` is bus time, as in a scenario: the fault ends there.
    pub fn act(&self, action: &str) -> Result<()> {
        let action = action.to_string();
        self.ask(move |tx| Command::Act(action, tx))
    }

    /// Checks expectations written as in a scenario's `expect` (docs/SCENARIOS.md), one or a
    /// list of them, against the run so far: `[AlarmRaised(node: "C0", alarm: "bus_off",
    /// after_s: 1.0, within_ms: 3000), NodeState(node: "D2", state: BusOff, after_s: 1.0)]`.
    /// Answers with a verdict for each, as a scenario's report gives them. Bad text, a node that
    /// is not on the bus, or an expectation that needs the trace counted from the start
    /// (`ErrorKinds`, `TraceComplete`) is an error naming it.
    pub fn check(&self, expectations: &str) -> Result<Vec<crate::scenario::Verdict>> {
        let text = expectations.to_string();
        self.ask(move |tx| Command::Check(text, tx))
    }

    /// Stops a periodic task; false when it had stopped already.
    pub fn stop_periodic(&self, id: u64) -> Result<bool> {
        self.ask(|tx| Command::StopPeriodic(id, tx))
    }

    /// Gives a periodic task new frames from its next sending on; false when it has stopped.
    pub fn modify_periodic(&self, id: u64, frames: Vec<Frame>) -> Result<bool> {
        if frames.is_empty() {
            return Err(Error::BadInput("a periodic task needs at least one frame".into()));
        }
        self.ask(|tx| Command::ModifyPeriodic(id, frames, tx))
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        // Closing the channel ends the thread's loop.
        self.commands.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests;
