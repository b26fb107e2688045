//! The script format (deserialized with serde from RON; unknown fields are errors).

use bus::filter::Sja1000Mode;
use protocol::ident::NodeKind;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One node's behaviour.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeScript {
    /// Bus address (e.g. `0xD0`); a harvester node's. A node of a network imported from a DBC
    /// file (one with `database`) has none: leave it out.
    #[serde(default)]
    pub address: u8,
    /// Name in traces and reports ("D0").
    pub name: String,
    /// Node kind; must agree with the address. Left out with `database`.
    #[serde(default = "no_kind")]
    pub kind: NodeKind,
    /// A DBC file, relative to the script, whose messages the script sends and answers instead
    /// of the harvester catalogue's (`harvemu import` writes such scripts).
    #[serde(default)]
    pub database: Option<String>,
    /// The database read from `database` when the script is loaded: never in a file.
    #[serde(skip)]
    pub db: Option<std::sync::Arc<protocol::database::Database>>,
    /// The acceptance filter of the node's CAN controller, as its firmware sets it up.
    pub filter: FilterDef,
    /// Time from power-on to the end of boot, ms.
    #[serde(default)]
    pub boot_delay_ms: u64,
    /// States with the codes that `StateCode` sends. The node is in the first state while it
    /// boots.
    pub states: Vec<StateDef>,
    /// The state entered when boot is over.
    pub initial: String,
    /// Variables and their initial values.
    #[serde(default)]
    pub vars: BTreeMap<String, f64>,
    /// What it sends.
    #[serde(default)]
    pub messages: Vec<SendDef>,
    /// How it reacts to frames addressed to it.
    #[serde(default)]
    pub reactions: Vec<Reaction>,
    /// Timers that fire when nothing restarts them in time (watchdogs).
    #[serde(default)]
    pub timers: Vec<TimerDef>,
    /// Sensor faults active from the start (scenarios add more at run time).
    #[serde(default)]
    pub faults: Vec<SignalFault>,
}

/// What `kind` is when a script leaves it out: no field node's kind, so that a harvester script
/// without it is told its address belongs to another.
fn no_kind() -> NodeKind {
    NodeKind::Monitor
}

/// A CAN controller's acceptance filter, in the registers of the chip the node is built on
/// (the semantics are `bus::filter`'s; register values are hex text, see `FilterDef::to_filter`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum FilterDef {
    /// One receive message object of an Atmel AT89C51CC01/CC03 on-chip CAN controller.
    Atmel {
        /// CANIDT1..4: the identifier, left-aligned (ID28..0 in bits 31..3 of the four bytes),
        /// RTRTAG in CANIDT4 bit 2, RB1TAG and RB0TAG in bits 1 and 0.
        canidt: String,
        /// CANIDM1..4: 1 = compare the bit; RTRMSK is CANIDM4 bit 2, IDEMSK CANIDM4 bit 0.
        canidm: String,
        /// IDE of CANCDMOB: the message object takes extended (true) or base frames.
        ide: bool,
    },
    /// A Philips SJA1000 in PeliCAN mode.
    Sja1000 {
        /// AFM of the MOD register: `Single` or `Dual` filter.
        mode: Sja1000Mode,
        /// ACR0..3, acceptance code.
        acr: String,
        /// AMR0..3, acceptance mask: 1 = don't care.
        amr: String,
    },
    /// A Linux raw CAN socket's filter list (`CAN_RAW_FILTER`): a frame passes if any matches.
    SocketCan(Vec<SocketCanDef>),
}

/// One `struct can_filter`: `can_id` and `can_mask` as 32-bit hex words, with the kernel's flag
/// bits (`0x80000000` EFF, `0x40000000` RTR, `0x20000000` inverted filter).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SocketCanDef {
    /// The identifier to match, with flags.
    pub can_id: String,
    /// Which bits of a received `can_id` are compared.
    pub can_mask: String,
}

/// A state and its code.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateDef {
    /// Name.
    pub name: String,
    /// The value `StateCode` evaluates to in this state.
    pub code: u8,
}

/// A message, or a group of messages sent back to back.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SendDef {
    /// Name that actions use to start, stop or send it.
    pub name: String,
    /// The frames, in order.
    pub frames: Vec<FrameSpec>,
    /// When it is sent.
    pub when: When,
    /// States in which it is sent; empty means every state after boot.
    #[serde(default)]
    pub states: Vec<String>,
    /// Whether it starts enabled (`Start`/`Stop` actions change it).
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Acknowledgement tracking for connection-oriented traffic.
    #[serde(default)]
    pub ack: Option<AckDef>,
}

fn yes() -> bool {
    true
}

/// One frame of a message: the catalogue message and what each field is bound to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameSpec {
    /// Catalogue name (`flow.part1`).
    pub message: String,
    /// Field name -> value. Constant fields of the catalogue need none.
    #[serde(default)]
    pub fields: BTreeMap<String, Expr>,
}

/// When a message is sent.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum When {
    /// Every `period_ms`, the first time `phase_ms` after boot.
    Periodic {
        /// Period, ms.
        period_ms: u64,
        /// Offset from the end of boot, ms.
        #[serde(default)]
        phase_ms: u64,
    },
    /// When the encoded payload changes (checked every `check_ms`), and at least every
    /// `heartbeat_ms`.
    OnChange {
        /// Longest silence, ms.
        heartbeat_ms: u64,
        /// How often the value is looked at, ms.
        #[serde(default = "default_check")]
        check_ms: u64,
    },
    /// Only when an action sends it.
    OnRequest,
}

fn default_check() -> u64 {
    20
}

/// Acknowledgement tracking: every send of every entry with an `ack` awaits an acknowledgement
/// (an `Acknowledged` action, which answers every send before it). A send whose acknowledgement
/// has not come `timeout_ms` after it counts as missed; when `limit` sends in a row are missed
/// the node enters `state`. A send whose acknowledgement is merely on its way is not missed.
/// With `resume`, the next acknowledgement takes a node that gave up back to the state it gave
/// up in: a connection-oriented exchange picks up where it stopped once the peer answers again.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AckDef {
    /// Missed acknowledgements in a row that make the node give up.
    pub limit: u32,
    /// How long after a send its acknowledgement is due, ms.
    pub timeout_ms: u64,
    /// State entered when the limit is reached.
    pub state: String,
    /// Variable that holds the count of missed acknowledgements (for status messages).
    #[serde(default)]
    pub count_var: Option<String>,
    /// An acknowledgement received in `state` returns the node to the state it gave up in.
    #[serde(default)]
    pub resume: bool,
}

/// A value for a field, a plant input or a variable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Expr {
    /// A number.
    Const(f64),
    /// A plant signal, through this node's fault hooks.
    Signal(String),
    /// A plant signal resolved to its port when the node starts ([`crate::script::Port`]):
    /// never in a file.
    #[serde(skip)]
    Port(crate::script::Port),
    /// A variable of the node.
    Var(String),
    /// A field of the frame being reacted to (only in reactions).
    Field(String),
    /// The current state's code.
    StateCode,
    /// `value × gain + offset`.
    Scaled(Box<Expr>, f64, f64),
    /// `value` limited to `min..=max`.
    Clamp(Box<Expr>, f64, f64),
    /// `value` rounded to a multiple of `step`, so that an analog input sent on change does not
    /// change with every bit of noise.
    Quantize(Box<Expr>, f64),
    /// A sawtooth: `from` at boot, rising (or falling) evenly to `to` over `period_s` seconds,
    /// then again from `from`.
    Ramp {
        /// Value at the start of each period.
        from: f64,
        /// Value approached at its end.
        to: f64,
        /// Length of a period, s.
        period_s: f64,
    },
    /// `mean + amplitude × sin(2π t / period_s)`, t seconds since boot.
    Sine {
        /// Middle value.
        mean: f64,
        /// Half the swing.
        amplitude: f64,
        /// Period, s.
        period_s: f64,
    },
    /// Starts at `start`; each time it is read it moves by a uniform random amount in
    /// `-step..=step` (from the run's seed), kept within `min..=max`.
    RandomWalk {
        /// First value.
        start: f64,
        /// Largest move per reading.
        step: f64,
        /// Lowest value.
        min: f64,
        /// Highest value.
        max: f64,
    },
    /// `from`, then `from + step`, ... each time it is read, back to `from` after passing `to`
    /// (a message counter).
    Counter {
        /// First value.
        from: f64,
        /// Last value before it wraps.
        to: f64,
        /// Increment.
        step: f64,
    },
    /// Each reading the next of these values, round and round: a multiplexor's pages, or an
    /// enumeration's named values.
    Cycle(Vec<f64>),
}

impl Expr {
    /// True when the value depends only on the node itself (its state and variables): no plant
    /// signal, no received frame.
    pub fn is_internal(&self) -> bool {
        match self {
            Expr::Const(_) | Expr::Var(_) | Expr::StateCode => true,
            // They change with time or with every reading, not with the node.
            Expr::Ramp { .. }
            | Expr::Sine { .. }
            | Expr::RandomWalk { .. }
            | Expr::Counter { .. }
            | Expr::Cycle(_) => false,
            Expr::Signal(_) | Expr::Port(_) | Expr::Field(_) => false,
            Expr::Scaled(e, ..) | Expr::Clamp(e, ..) | Expr::Quantize(e, _) => e.is_internal(),
        }
    }
}

/// What a node does when a frame for it arrives.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reaction {
    /// Catalogue name of the message.
    pub message: String,
    /// Field values that must match (raw values, as the catalogue's value tables name them).
    #[serde(default)]
    pub when: BTreeMap<String, f64>,
    /// States in which it applies; empty means every state after boot.
    #[serde(default)]
    pub states: Vec<String>,
    /// What to do.
    pub actions: Vec<Action>,
}

/// One step of a reaction or timer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Action {
    /// Enter a state.
    SetState(String),
    /// Enable a message.
    Start(String),
    /// Disable a message.
    Stop(String),
    /// Send a message now (a reply).
    Send(String),
    /// Write a plant input.
    Write(String, Expr),
    /// A plant input resolved to its port when the node starts: never in a file.
    #[serde(skip)]
    WritePort(crate::script::Port, Expr),
    /// Set a variable.
    Set(String, Expr),
    /// An acknowledgement arrived: every send so far is answered, and the count of missed
    /// acknowledgements starts again from 0.
    Acknowledged,
    /// Restart a timer.
    Restart(String),
}

/// A timer: fires `after_ms` after it was last (re)started, while the node is in one of its
/// states; it restarts on entering them, on `Restart` actions and when it fires.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimerDef {
    /// Name for `Restart`.
    pub name: String,
    /// Delay, ms.
    pub after_ms: u64,
    /// States in which it runs; empty means every state after boot.
    #[serde(default)]
    pub states: Vec<String>,
    /// What to do when it fires.
    pub actions: Vec<Action>,
}

/// A sensor fault on one plant signal as this node reads it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SignalFault {
    /// The plant signal.
    pub signal: String,
    /// What goes wrong.
    pub fault: FaultKind,
}

/// Sensor fault kinds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum FaultKind {
    /// Reads this value whatever the plant does.
    Stuck(f64),
    /// Reads the true value plus this.
    Offset(f64),
    /// Reads the true value plus `rate` per second since the fault began.
    Drift(f64),
    /// Reads the true value plus Gaussian noise of this standard deviation.
    Noise(f64),
    /// The sensor is gone: messages that read this signal are not sent.
    Dropout,
}

// The node interface's form of a sensor fault, which cannot name this crate's file model.
impl From<FaultKind> for bus::node::SensorFault {
    fn from(k: FaultKind) -> Self {
        use bus::node::SensorFault as S;
        match k {
            FaultKind::Stuck(v) => S::Stuck(v),
            FaultKind::Offset(v) => S::Offset(v),
            FaultKind::Drift(v) => S::Drift(v),
            FaultKind::Noise(v) => S::Noise(v),
            FaultKind::Dropout => S::Dropout,
        }
    }
}

impl From<bus::node::SensorFault> for FaultKind {
    fn from(k: bus::node::SensorFault) -> Self {
        use bus::node::SensorFault as S;
        match k {
            S::Stuck(v) => FaultKind::Stuck(v),
            S::Offset(v) => FaultKind::Offset(v),
            S::Drift(v) => FaultKind::Drift(v),
            S::Noise(v) => FaultKind::Noise(v),
            S::Dropout => FaultKind::Dropout,
        }
    }
}

impl FaultKind {
    /// What is wrong with the fault's number, if anything: every one must be finite, and a
    /// noise's standard deviation not negative.
    pub fn problem(self) -> Option<String> {
        let (what, v) = match self {
            FaultKind::Stuck(v) => ("Stuck", v),
            FaultKind::Offset(v) => ("Offset", v),
            FaultKind::Drift(v) => ("Drift", v),
            FaultKind::Noise(v) => ("Noise", v),
            FaultKind::Dropout => return None,
        };
        if !v.is_finite() {
            Some(format!("{what}({v}): not a finite number"))
        } else if matches!(self, FaultKind::Noise(_)) && v < 0.0 {
            Some(format!("Noise({v}): a standard deviation is not negative"))
        } else {
            None
        }
    }
}
