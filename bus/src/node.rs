//! The sans-IO [`NodeLogic`] every emulated node implements, and [`drive`], which feeds it one
//! wake's inputs. Runtimes (the actor in `bus-runtime`, a test, a firmware runner) are drivers.
//!
//! Calling contract (quinn-proto style): the driver feeds inputs in time order —
//! [`NodeLogic::handle_frame`] for each received frame, [`NodeLogic::handle_event`] for
//! controller notifications, [`NodeLogic::handle_timeout`] when the time from
//! [`NodeLogic::poll_timeout`] has come — then drains [`NodeLogic::poll_command`] and
//! [`NodeLogic::poll_transmit`] until they return `None`, and asks `poll_timeout` for the next
//! deadline. Logic never reads a clock: `now` is bus time, passed in.
//!
//! A logic that models its controller's registers (a firmware node) also gives its controller
//! commands (join or leave the bus, abort, counters, bus-off recovery, whether its bit timing
//! can read the bus), hears of every controller event as it happens
//! ([`NodeLogic::wants_every_event`]), may stop for good ([`NodeLogic::failed`]) and shows its
//! hardware for state dumps ([`NodeLogic::hardware`]). Such a node may have several controllers
//! on the bus (a board with several CAN chips): each has its own place on the bus, its inputs
//! come tagged with its index ([`NodeLogic::handle_frame_on`], [`NodeLogic::handle_event_on`])
//! and so do the commands for it. Every other node has one controller, controller 0.
//!
//! A logic may also say which frames it would take no notice of for a while
//! ([`NodeLogic::unheeded`]): a driver may then leave such frames out of a wake (and not wake
//! the node for them), since handing them over would change nothing.

use crate::Frame;
use crate::engine::{BusError, Location, Received};
use crate::fault::ErrorState;
use crate::filter::{AcceptanceFilter, AtmelFilter};
use crate::time::BusTime;

/// What a node's controller tells it besides received frames.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum ControllerEvent {
    /// A frame it submitted went out.
    Sent(Frame),
    /// A frame it submitted was dropped when the controller went bus off.
    Aborted(Frame),
    /// Its transmit queue was full: this frame was not queued.
    Refused(Frame),
    /// Frames were lost because its receive FIFO was full.
    Overrun,
    /// Its error state changed.
    State(ErrorState),
    /// Its error counters changed (only to a logic that asks for every event:
    /// [`NodeLogic::wants_every_event`]).
    Counters {
        /// Transmit error counter (256 and above while bus off).
        tec: u16,
        /// Receive error counter.
        rec: u16,
    },
    /// It detected a bus error (only to a logic that asks for every event).
    BusError {
        /// What it detected.
        error: BusError,
        /// It was transmitting.
        transmitting: bool,
        /// Where in the frame.
        location: Location,
    },
    /// It lost arbitration at this bit of the arbitration field, 0 being the first identifier
    /// bit (only to a logic that asks for every event).
    ArbitrationLost(u16),
    /// Bus off and recovering on its host's request, it has counted this many of the 128
    /// sequences of 11 recessive bits (only to a logic that asks for every event).
    RecoveryProgress(u8),
    /// Asleep ([`ControllerCommand::Sleep`]), it saw bus activity and woke; it does not receive
    /// the frame that woke it.
    Woken,
}

/// What a node asks of its controller, for a logic that models its controller's registers
/// (firmware): [`NodeLogic::poll_command`]. Commands act at the wake's time, in order.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum ControllerCommand {
    /// Queue this frame, as [`NodeLogic::poll_transmit`] does.
    Transmit(Frame),
    /// Queue this frame for one attempt only (single shot): an attempt that fails or loses
    /// arbitration drops it, answered with [`ControllerEvent::Aborted`]. A frame the chip also
    /// receives itself (self reception) is the chip's to store when [`ControllerEvent::Sent`]
    /// comes: the bus does not deliver a controller's own frame to it.
    TransmitOnce(Frame),
    /// Join the bus (a controller leaving reset mode).
    Online {
        /// Listen-only mode: it drives nothing dominant (no frame, no acknowledgement, no error
        /// or overload flag) and its error counters stay as they are; it still receives.
        listen_only: bool,
        /// Self-test mode: its own frames need no acknowledge.
        self_test: bool,
    },
    /// Leave the bus (reset mode): it neither sends nor receives, and frames not yet started
    /// are dropped.
    Offline,
    /// Drop the frames not yet started.
    Abort,
    /// Set the error counters (the host writes them in reset mode).
    SetCounters {
        /// Transmit error counter; 256 and above is bus off.
        tec: u16,
        /// Receive error counter.
        rec: u16,
    },
    /// Start counting the recessive bits that end bus off (the host cleared reset mode).
    Recover,
    /// Sleep mode on (off the bus until bus activity wakes it: [`ControllerEvent::Woken`]) or
    /// off (the host woke it: it joins the bus again).
    Sleep(bool),
    /// Whether its bit timing lets it sample the bus's frames: a controller that cannot
    /// destroys what it cannot read with error flags and acknowledges nothing.
    Tuned(bool),
}

/// Frames a logic takes no notice of for a while ([`NodeLogic::unheeded`]): those that end
/// before `before` and that no filter of `heeded` accepts. Handed to the logic, such a frame
/// would change nothing in it, and it would answer the same.
#[derive(Clone, Debug, PartialEq)]
pub struct Unheeded {
    /// The end of the while: frames that end at or after it may matter.
    pub before: BusTime,
    /// The filters of what the logic would take (an on-chip CAN controller's receiving
    /// channels).
    pub heeded: smallvec::SmallVec<[AtmelFilter; 4]>,
}

impl Unheeded {
    /// Whether a frame that ends at `at` is one of them.
    pub fn covers(&self, at: BusTime, frame: &Frame) -> bool {
        at < self.before && !self.heeded.iter().any(|f| f.accepts(frame))
    }
}

/// The behaviour of one node, without I/O.
pub trait NodeLogic {
    /// A frame passed this node's acceptance filter; `now` is its end-of-frame time.
    fn handle_frame(&mut self, now: BusTime, frame: &Frame);
    /// The deadline from `poll_timeout` has come.
    fn handle_timeout(&mut self, now: BusTime);
    /// A controller notification.
    fn handle_event(&mut self, now: BusTime, event: ControllerEvent) {
        let _ = (now, event);
    }
    /// The next frame to hand to the controller, if any.
    fn poll_transmit(&mut self) -> Option<Frame>;
    /// A frame that passed the acceptance filter of controller `controller` (0 for a node with
    /// one); `now` is its end-of-frame time. By default, [`NodeLogic::handle_frame`].
    fn handle_frame_on(&mut self, controller: usize, now: BusTime, frame: &Frame) {
        let _ = controller;
        self.handle_frame(now, frame);
    }
    /// A notification of controller `controller` (0 for a node with one). By default,
    /// [`NodeLogic::handle_event`].
    fn handle_event_on(&mut self, controller: usize, now: BusTime, event: ControllerEvent) {
        let _ = controller;
        self.handle_event(now, event);
    }
    /// The next command, with the controller it is for (0 for a node with one), if any; drained
    /// before `poll_transmit`.
    fn poll_command(&mut self) -> Option<(usize, ControllerCommand)> {
        None
    }
    /// True when the logic models its controller's registers and must hear of every change as
    /// it happens: counters, bus errors, lost arbitration, and sent or aborted frames wake it at
    /// their time (others hear of them with their next wake).
    fn wants_every_event(&self) -> bool {
        false
    }
    /// When `handle_timeout` is next due.
    fn poll_timeout(&self) -> Option<BusTime>;
    /// The frames this logic, as it stands after its inputs so far, takes no notice of (a node
    /// with one controller only): until its next input they change nothing in it, so a driver
    /// need not hand them over. By default, none.
    fn unheeded(&self) -> Option<Unheeded> {
        None
    }
    /// Set once the logic has stopped for good, with why (a firmware's CPU fault): the driver
    /// reports it as a crash, as it reports a panic.
    fn failed(&self) -> Option<String> {
        None
    }
    /// A register-level node's hardware as it is at `at` (not before its last input), for a
    /// state dump; `None` for a logic without such hardware.
    fn hardware(&self, at: BusTime) -> Option<HardwareState> {
        let _ = at;
        None
    }
    /// True when `handle_frame` only stores frames for `handle_timeout` to work through (a
    /// receive interrupt feeding a main loop): it transmits nothing and moves no deadline. The
    /// hub then takes such a node's frames from its FIFO a reaction time after they arrive, as the
    /// interrupt would, and hands them over at the next deadline instead of waking the logic for
    /// each: the logic sees the same calls in the same order, for a fraction of the wakes.
    fn frames_can_wait(&self) -> bool {
        false
    }
    /// True when the run should stop at this wake: a program outside the bus that waits for a
    /// frame has one now (a python-can `recv`). The driver stops the bus at the wake's time, as
    /// it stops at a crash, and runs on when asked again. Read once after every wake.
    fn stop_here(&mut self) -> bool {
        false
    }
    /// The run ends at `at` (not before the logic's last input): nothing reaches it after
    /// that. A logic that writes something out as it goes brings it up to `at` (a firmware
    /// node's instruction trace, which only its wakes move on). By default, nothing.
    fn run_ends(&mut self, at: BusTime) {
        let _ = at;
    }
    /// Takes a fault injected from outside (a scenario's timeline), from `now` on. A logic that
    /// cannot take this fault refuses it, and says why: by default every fault is refused.
    fn inject(&mut self, fault: &NodeFault, now: BusTime) -> Result<(), Refused> {
        let _ = (fault, now);
        Err(Refused("its logic takes no injected faults".to_string()))
    }
}

/// A firmware node's hardware, as `harvemu run --dump-state` writes it ([`NodeLogic::hardware`]).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct HardwareState {
    /// The CPU.
    pub cpu: CpuState,
    /// Its CAN controllers.
    pub controllers: Vec<ChipState>,
}

/// A CPU's state.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct CpuState {
    /// Program counter.
    pub pc: u16,
    /// Machine cycles since reset.
    pub cycles: u64,
    /// Internal RAM, 256 bytes as hex (what a part without the upper half lacks reads 00).
    pub iram: String,
    /// The SFRs 80h–FFh as hex, 128 bytes.
    pub sfr: String,
}

/// A CAN controller's state.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ChipState {
    /// The part ("SJA1000", or "AT89C51CC03" for that chip's own controller).
    pub kind: String,
    /// Where the CPU reaches it (an SJA1000's window; 0 for SFRs).
    pub base: u16,
    /// Its register set ("BasicCAN" or "PeliCAN"; "on chip").
    pub mode: String,
    /// Registers as the CPU would read them, as hex: an SJA1000's 0–31, or the SFRs 80h–FFh
    /// (00 where the controller has none).
    pub registers: String,
    /// Transmit error counter.
    pub tec: u16,
    /// Receive error counter.
    pub rec: u16,
    /// "active", "passive" or "bus-off".
    pub state: String,
}

/// A fault injected into a node's logic: see [`NodeLogic::inject`].
#[derive(Clone, Debug, PartialEq)]
pub enum NodeFault {
    /// The node's sensor of a plant signal reads wrong.
    Sensor {
        /// The plant signal.
        signal: String,
        /// How it reads.
        reads: SensorFault,
    },
    /// The node's sensor of a plant signal reads true again.
    SensorRepaired {
        /// The plant signal.
        signal: String,
    },
}

/// How a faulty sensor reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SensorFault {
    /// This value, whatever the plant does.
    Stuck(f64),
    /// The true value plus this.
    Offset(f64),
    /// The true value plus this rate per second since the fault began.
    Drift(f64),
    /// The true value plus Gaussian noise of this standard deviation.
    Noise(f64),
    /// Nothing: the sensor is gone.
    Dropout,
}

/// Why a logic refused an injected fault.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Refused(pub String);

/// Why a node's logic stopped taking part.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CrashCause {
    /// Fault injection asked for it (a scenario's `Crash`).
    Injected,
    /// The logic panicked; the panic's message.
    Panic(String),
    /// The logic stopped for good ([`NodeLogic::failed`]: a firmware's CPU fault), with why.
    Failed(String),
    /// The node's actor was gone before it answered a wake.
    ActorGone,
}

impl std::fmt::Display for CrashCause {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CrashCause::Injected => f.write_str("injected crash"),
            CrashCause::Panic(message) | CrashCause::Failed(message) => f.write_str(message),
            CrashCause::ActorGone => f.write_str("node actor gone"),
        }
    }
}

/// Written as its text, as reports and JSON outputs show it.
impl serde::Serialize for CrashCause {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// A node's answer to a wake.
#[derive(Debug, Default, PartialEq)]
pub struct Report {
    /// Commands for its controllers, each with the controller's index, at the wake's time,
    /// before `transmit`.
    pub commands: Vec<(usize, ControllerCommand)>,
    /// Frames to submit by its first controller, at the wake's time.
    pub transmit: Vec<Frame>,
    /// Next deadline.
    pub next_timeout: Option<BusTime>,
    /// Set when the logic crashed: why; the node takes no further part.
    pub crashed: Option<CrashCause>,
    /// [`NodeLogic::frames_can_wait`], as of this wake.
    pub frames_can_wait: bool,
    /// [`NodeLogic::wants_every_event`], as of this wake.
    pub every_event: bool,
    /// How many of the wake's frames reached [`NodeLogic::handle_frame`]: all of them, unless
    /// the logic crashed first (the hub counts the rest as lost).
    pub frames_handled: u64,
    /// [`NodeLogic::stop_here`], as of this wake.
    pub stop: bool,
    /// [`NodeLogic::unheeded`], as of this wake.
    pub unheeded: Option<Unheeded>,
}

/// Most timeouts handled in one wake, so a logic whose deadline never moves cannot hang the bus.
const MAX_TIMEOUTS_PER_WAKE: usize = 100_000;
/// Most frames taken from one wake's `poll_transmit`.
const MAX_TRANSMIT_PER_WAKE: usize = 1024;

/// Feeds one wake to a logic and collects its answer. This is all a driver does; it is a free
/// function so that tests and other drivers can use it without actix.
pub fn drive(
    logic: &mut dyn NodeLogic,
    now: BusTime,
    frames: Vec<Received>,
    events: Vec<(BusTime, ControllerEvent)>,
) -> Report {
    drive_counted(logic, 0, now, frames, events, &mut 0)
}

/// [`drive`] with the inputs of controller `controller` (0 for a node with one), counting in
/// `handled` the frames handed to the logic as it goes, so that the count survives a panic in
/// the logic.
pub fn drive_counted(
    logic: &mut dyn NodeLogic,
    controller: usize,
    now: BusTime,
    frames: Vec<Received>,
    events: Vec<(BusTime, ControllerEvent)>,
    handled: &mut u64,
) -> Report {
    let mut frames = frames.into_iter().peekable();
    let mut events = events.into_iter().peekable();
    let mut timeouts = 0;
    loop {
        // The earliest of: next frame, next event, next due timeout.
        let tf = frames.peek().map(|r| r.at);
        let te = events.peek().map(|(t, _)| *t);
        let tt = logic
            .poll_timeout()
            .filter(|&t| t <= now && timeouts < MAX_TIMEOUTS_PER_WAKE);
        let Some(next) = [tf, te, tt].into_iter().flatten().min() else {
            break;
        };
        if tt == Some(next) {
            timeouts += 1;
            logic.handle_timeout(next);
        } else if tf == Some(next) {
            if let Some(r) = frames.next() {
                *handled += 1;
                logic.handle_frame_on(controller, r.at, &r.frame);
            }
        } else if let Some((t, e)) = events.next() {
            logic.handle_event_on(controller, t, e);
        }
    }
    let mut commands = Vec::new();
    while commands.len() < MAX_TRANSMIT_PER_WAKE {
        match logic.poll_command() {
            Some(c) => commands.push(c),
            None => break,
        }
    }
    let mut transmit = Vec::new();
    while transmit.len() < MAX_TRANSMIT_PER_WAKE {
        match logic.poll_transmit() {
            Some(f) => transmit.push(f),
            None => break,
        }
    }
    Report {
        commands,
        transmit,
        next_timeout: logic.poll_timeout(),
        crashed: logic.failed().map(CrashCause::Failed),
        frames_can_wait: logic.frames_can_wait(),
        every_event: logic.wants_every_event(),
        frames_handled: *handled,
        stop: logic.stop_here(),
        unheeded: logic.unheeded(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::candump::parse_frame;

    /// Records what it is fed, in order; sends one frame per received frame; ticks every 10 ms.
    #[derive(Default)]
    struct Echo {
        log: Vec<String>,
        out: Vec<Frame>,
        next: Option<BusTime>,
    }

    impl NodeLogic for Echo {
        fn handle_frame(&mut self, now: BusTime, frame: &Frame) {
            self.log.push(format!("frame {now:?}"));
            self.out.push(*frame);
        }
        fn handle_timeout(&mut self, now: BusTime) {
            self.log.push(format!("timeout {now:?}"));
            self.next = Some(now + crate::time::BusDuration::from_millis(10));
        }
        fn handle_event(&mut self, now: BusTime, _: ControllerEvent) {
            self.log.push(format!("event {now:?}"));
        }
        fn poll_transmit(&mut self) -> Option<Frame> {
            self.out.pop()
        }
        fn poll_timeout(&self) -> Option<BusTime> {
            self.next
        }
    }

    #[test]
    fn inputs_are_fed_in_time_order() {
        let f = parse_frame("123#01").unwrap();
        let mut logic = Echo {
            next: Some(BusTime::from_millis(5)),
            ..Echo::default()
        };
        let report = drive(
            &mut logic,
            BusTime::from_millis(25),
            vec![
                Received {
                    at: BusTime::from_millis(1),
                    frame: f,
                },
                Received {
                    at: BusTime::from_millis(17),
                    frame: f,
                },
            ],
            vec![(BusTime::from_millis(6), ControllerEvent::Overrun)],
        );
        let expected: Vec<String> = [
            ("frame", 1),
            ("timeout", 5),
            ("event", 6),
            ("timeout", 15),
            ("frame", 17),
            ("timeout", 25),
        ]
        .iter()
        .map(|(k, ms)| format!("{k} {:?}", BusTime::from_millis(*ms)))
        .collect();
        assert_eq!(logic.log, expected);
        assert_eq!(report.transmit.len(), 2);
        // A deadline at exactly `now` is due: the hub wakes a node at its deadline.
        assert_eq!(report.next_timeout, Some(BusTime::from_millis(35)));
    }

    struct Stuck;
    impl NodeLogic for Stuck {
        fn handle_frame(&mut self, _: BusTime, _: &Frame) {}
        fn handle_timeout(&mut self, _: BusTime) {}
        fn poll_transmit(&mut self) -> Option<Frame> {
            None
        }
        fn poll_timeout(&self) -> Option<BusTime> {
            Some(BusTime::ZERO)
        }
    }

    #[test]
    fn a_deadline_that_never_moves_cannot_hang_the_driver() {
        let report = drive(&mut Stuck, BusTime::from_millis(1), vec![], vec![]);
        assert_eq!(report.next_timeout, Some(BusTime::ZERO));
    }
}
