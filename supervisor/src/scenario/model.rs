//! The scenario format (RON): a timeline of stimuli and faults, and expectations.

use bus::fault::ErrorState;
use nodes::script::FaultKind;
use serde::{Deserialize, Serialize};

/// A scenario file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename = "Scenario")]
pub struct Scenario {
    /// Short name (in the JUnit test case's name and the report).
    pub name: String,
    /// What it shows.
    #[serde(default)]
    pub description: String,
    /// Harvester config, relative to the scenario file.
    #[serde(default = "default_config")]
    pub config: String,
    /// Seed; the config's when absent.
    #[serde(default)]
    pub seed: Option<u64>,
    /// Virtual seconds to run: more than 0, at most [`super::MAX_DURATION_S`] (30 days).
    pub duration_s: f64,
    /// Cruise control start, s (overrides the config; `None` keeps it).
    #[serde(default)]
    pub cruise_start_s: Option<f64>,
    /// What happens when.
    #[serde(default)]
    pub timeline: Vec<Step>,
    /// Faults drawn from a seed, added to the timeline when the scenario is loaded.
    #[serde(default)]
    pub random_faults: Option<super::random::RandomFaults>,
    /// What must be true.
    pub expect: Vec<Expect>,
}

fn one_overload_frame() -> u8 {
    1
}

fn default_config() -> String {
    "../harvester.ron".to_string()
}

/// One stimulus at one time.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Step {
    /// Bus time, s.
    pub at_s: f64,
    /// What to do.
    pub action: Action,
}

/// Which frames bit errors hit.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub enum Target {
    /// Every frame.
    Any,
    /// Frames sent by this node.
    Node(String),
    /// Frames with this identifier (8 hex digits).
    Id(String),
    /// Frames of this priority (0–31).
    Priority(u8),
}

/// Which of the targeted frames are hit.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub enum Hits {
    /// The first one.
    Once,
    /// Every n-th.
    EveryNth(u32),
    /// All.
    Always,
    /// Each bit flips with this probability.
    BitErrorRate(f64),
}

/// What kind of error a hit frame meets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ErrorKind {
    /// A bit flipped on the wire: the transmitter reads back what it did not send, and every
    /// node sees the same wrong bit.
    #[default]
    Bit,
    /// Six equal bits in a row where stuffing applies.
    Stuff,
    /// The frame's CRC does not match.
    Crc,
    /// A fixed-form field holds an illegal bit.
    Form,
}

/// An error a controller detects, as SocketCAN reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum DetectedError {
    /// It read back another level than it sent.
    Bit,
    /// Six equal bits where stuffing applies.
    Stuff,
    /// The CRC sequence did not match.
    Crc,
    /// A fixed-form bit was dominant.
    Form,
    /// Nobody acknowledged its frame.
    Ack,
}

/// Which nodes detect the error a hit frame meets.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SeenBy {
    /// Every node on the bus.
    #[default]
    All,
    /// Only these receivers (a local disturbance at their transceivers); the others see the
    /// frame as it was sent until the error flag destroys it.
    Nodes(Vec<String>),
}

/// The level a disturbance makes nodes read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Level {
    /// Logical 0, the level that wins on the bus.
    Dominant,
    /// Logical 1.
    Recessive,
}

/// Which nodes read a disturbance.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ReadBy {
    /// Every controller on the bus, the frame's transmitter included.
    #[default]
    All,
    /// These nodes only (a transmitter among them included).
    Nodes(Vec<String>),
}

fn one_bit() -> u16 {
    1
}

/// Stimuli and faults.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Action {
    /// Corrupt frames on the wire (until `until_s`, if given).
    BitErrors {
        /// Which frames.
        target: Target,
        /// Which of them.
        hits: Hits,
        /// End of the fault, s.
        #[serde(default)]
        until_s: Option<f64>,
        /// The kind of error.
        #[serde(default)]
        kind: ErrorKind,
        /// Who detects it (only `All` for a bit error).
        #[serde(default)]
        seen_by: SeenBy,
    },
    /// In the frames `target` and `hits` select (until `until_s`, if given), the `seen_by`
    /// nodes read `level` for `bits` bit times from bit `bit` (0-based, in the field's bits as
    /// sent) of `field`, each node finding the place as it is in the frame itself.
    Disturb {
        /// Which frames.
        target: Target,
        /// Which of them.
        hits: Hits,
        /// End of the fault, s.
        #[serde(default)]
        until_s: Option<f64>,
        /// The field it starts in.
        field: bus::engine::Field,
        /// The bit of the field it starts at, from 0.
        bit: u16,
        /// The level read.
        level: Level,
        /// How many bit times it lasts.
        #[serde(default = "one_bit")]
        bits: u16,
        /// Who reads it.
        #[serde(default)]
        seen_by: ReadBy,
    },
    /// Receivers that are not ready send overload frames after the frames `target` and `hits`
    /// select (until `until_s`, if given).
    Overload {
        /// Which frames.
        target: Target,
        /// Which of them.
        hits: Hits,
        /// End of the fault, s.
        #[serde(default)]
        until_s: Option<f64>,
        /// The nodes that raise the overload frames; empty: every receiver of the frame.
        #[serde(default)]
        by: Vec<String>,
        /// Overload frames in a row after each hit frame (the CAN rules allow at most 2).
        #[serde(default = "one_overload_frame")]
        frames: u8,
    },
    /// A node stops acknowledging frames.
    AckFailure(String),
    /// It acknowledges again.
    AckRestored(String),
    /// A node is disconnected from the bus.
    Disconnect(String),
    /// It is connected again.
    Reconnect(String),
    /// A node's logic crashes (the supervisor restarts it).
    Crash(String),
    /// A node hangs: alive, silent, not draining its receive FIFO.
    Hang(String),
    /// It runs again.
    Resume(String),
    /// A babbling idiot floods the bus with this frame (`ID#DATA`) until `until_s`.
    Babble {
        /// The frame, in candump notation.
        frame: String,
        /// End of the flood, s.
        until_s: f64,
    },
    /// A node sends one frame of its own making (a wrong DLC or payload), in candump notation.
    SendFrame {
        /// The node whose controller sends it.
        node: String,
        /// The frame.
        frame: String,
    },
    /// A node's sensor reading goes wrong.
    SensorFault {
        /// The node.
        node: String,
        /// The plant signal it reads.
        signal: String,
        /// How.
        fault: FaultKind,
    },
    /// The sensor is repaired.
    SensorRepaired {
        /// The node.
        node: String,
        /// The plant signal.
        signal: String,
    },
    /// Set a plant input (`fault.door3_open`, `operator.speed`, ...).
    Plant {
        /// The input.
        input: String,
        /// Its value.
        value: f64,
    },
    /// Switch the whole machine off and on.
    PowerCycle,
}

impl Action {
    /// The variant's name, as written in scenarios ("Crash", "BitErrors", ...).
    pub fn name(&self) -> &'static str {
        match self {
            Action::BitErrors { .. } => "BitErrors",
            Action::Disturb { .. } => "Disturb",
            Action::Overload { .. } => "Overload",
            Action::AckFailure(_) => "AckFailure",
            Action::AckRestored(_) => "AckRestored",
            Action::Disconnect(_) => "Disconnect",
            Action::Reconnect(_) => "Reconnect",
            Action::Crash(_) => "Crash",
            Action::Hang(_) => "Hang",
            Action::Resume(_) => "Resume",
            Action::Babble { .. } => "Babble",
            Action::SendFrame { .. } => "SendFrame",
            Action::SensorFault { .. } => "SensorFault",
            Action::SensorRepaired { .. } => "SensorRepaired",
            Action::Plant { .. } => "Plant",
            Action::PowerCycle => "PowerCycle",
        }
    }
}

/// What must be true.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Expect {
    /// The monitor shows this alarm, raised within `within_ms` after `after_s`.
    AlarmRaised {
        /// Node that reports it ("C0"), or that it is about.
        node: String,
        /// Alarm name (the catalogue field, or `silent`, `flow sensor stopped`, `setpoint_timeout`).
        alarm: String,
        /// From, s.
        after_s: f64,
        /// Deadline, ms.
        within_ms: u64,
    },
    /// The alarm is cleared within `within_ms` after `after_s`.
    AlarmCleared {
        /// Node.
        node: String,
        /// Alarm name.
        alarm: String,
        /// From, s.
        after_s: f64,
        /// Deadline, ms.
        within_ms: u64,
    },
    /// No alarm was raised at all during the run.
    NoAlarms,
    /// Bus load over the whole run below this, %.
    BusLoadBelow(f64),
    /// No frame lost: no receive overrun anywhere, nothing lost or broken in the monitor.
    NoFrameLost,
    /// A node is in `state` within `within_ms` after `after_s`.
    NodeState {
        /// Node.
        node: String,
        /// Error state.
        state: ErrorState,
        /// From, s.
        after_s: f64,
        /// Deadline, ms.
        within_ms: u64,
    },
    /// Error frames on the bus, between these counts.
    ErrorFrames {
        /// At least.
        min: u64,
        /// At most.
        max: u64,
    },
    /// Overload flags on the bus (counted per controller that sent one), between these counts.
    OverloadFrames {
        /// At least.
        min: u64,
        /// At most.
        max: u64,
    },
    /// The monitor's total yield is within this percentage of the plant's truth.
    YieldWithin(f64),
    /// A field of the monitor's display at the end is within `min..=max`.
    Display {
        /// Field name (as in `nodes::monitor::Display`).
        field: String,
        /// Lowest.
        min: f64,
        /// Highest.
        max: f64,
    },
    /// A plant signal at the end is within `min..=max`.
    Plant {
        /// Signal.
        signal: String,
        /// Lowest.
        min: f64,
        /// Highest.
        max: f64,
    },
    /// A node was restarted this many times.
    Restarts {
        /// Node.
        node: String,
        /// Count.
        count: usize,
    },
    /// Every frame addressed to the monitor that completed on the bus was processed by its main
    /// loop or lost for a counted reason, and the counts add up exactly.
    FramesAccounted,
    /// Every frame that completed on the bus is a frame record of the trace.
    TraceComplete,
    /// No node's logic crashed by itself: the only crashes are the timeline's `Crash` steps.
    NoCrashes,
    /// A node is never in `state` from `from_s` to `to_s` (both included), not even for a moment.
    NodeStateNever {
        /// Node.
        node: String,
        /// Error state.
        state: ErrorState,
        /// From, s.
        from_s: f64,
        /// To, s.
        to_s: f64,
    },
    /// A node is in `state` from `from_s` to `to_s` (both included), without a moment elsewhere.
    NodeStateHolds {
        /// Node.
        node: String,
        /// Error state.
        state: ErrorState,
        /// From, s.
        from_s: f64,
        /// To, s.
        to_s: f64,
    },
    /// A node went bus off between `min` and `max` times over the whole run.
    BusOffCount {
        /// Node.
        node: String,
        /// At least.
        min: u32,
        /// At most.
        max: u32,
    },
    /// A node went bus off at least once, and each time was back within `max_ms` (firmware that
    /// restarts its controller beats the 128 × 11 recessive bits of a recovery).
    BusOffLongest {
        /// Node.
        node: String,
        /// Longest stay in bus off allowed, ms.
        max_ms: f64,
    },
    /// A node's receive error counter stays at or below `max` from `from_s` to `to_s`.
    RecMax {
        /// Node.
        node: String,
        /// Highest REC allowed.
        max: u16,
        /// From, s.
        from_s: f64,
        /// To, s.
        to_s: f64,
    },
    /// A node's error counters are exactly these at the instant `at_s` (inside a frame: as
    /// the last change before it left them).
    Counters {
        /// Node.
        node: String,
        /// The instant, s.
        at_s: f64,
        /// Transmit error counter.
        tec: u16,
        /// Receive error counter.
        rec: u16,
    },
    /// A node's controller detected errors of `kind` between `min` and `max` times from
    /// `from_s` to `to_s` (both included; at the first bit of its error flag, as its trace lines
    /// show them).
    ErrorKinds {
        /// Node.
        node: String,
        /// The kind of error.
        kind: DetectedError,
        /// At least.
        min: u64,
        /// At most.
        max: u64,
        /// From, s.
        #[serde(default)]
        from_s: f64,
        /// To, s (the end of the run when absent).
        #[serde(default)]
        to_s: Option<f64>,
    },
    /// A node's transmit error counter stays at or below `max` from `from_s` to `to_s`.
    TecMax {
        /// Node.
        node: String,
        /// Highest TEC allowed.
        max: u16,
        /// From, s.
        from_s: f64,
        /// To, s.
        to_s: f64,
    },
}
