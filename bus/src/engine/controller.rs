//! One node's CAN controller as the bus sees it: acceptance filter, receive FIFO, transmit
//! queue, error counters, and the switches fault injection turns.

use crate::Frame;
use crate::fault::FaultConfinement;
use crate::filter::{AcceptanceFilter, AtmelFilter, Sja1000Filter, SocketCanFilterSet};
use crate::time::BusTime;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// Index of a controller on one bus.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug, Serialize, Deserialize)]
pub struct NodeId(pub u16);

impl NodeId {
    /// As an index into per-node tables.
    pub fn index(self) -> usize {
        usize::from(self.0)
    }
}

/// The acceptance filter of a controller, in any of the forms harvemu models.
#[derive(Clone, PartialEq, Eq, Debug, Serialize, Deserialize)]
pub enum Filter {
    /// Keep every frame.
    All,
    /// Keep nothing (a transmit-only node).
    Nothing,
    /// SJA1000 ACR/AMR.
    Sja1000(Sja1000Filter),
    /// A raw socket's filter list.
    SocketCan(SocketCanFilterSet),
    /// An Atmel message object.
    Atmel(AtmelFilter),
}

impl AcceptanceFilter for Filter {
    fn accepts(&self, frame: &Frame) -> bool {
        match self {
            Filter::All => true,
            Filter::Nothing => false,
            Filter::Sja1000(f) => f.accepts(frame),
            Filter::SocketCan(f) => f.accepts(frame),
            Filter::Atmel(f) => f.accepts(frame),
        }
    }
}

/// How a controller is built.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    /// Name used in traces and reports ("D3", "monitor").
    pub name: String,
    /// Acceptance filter.
    pub filter: Filter,
    /// Receive FIFO size in bytes: the SJA1000's 64 for a controller the engine stands for (a
    /// scripted node's). A register-level node's chip model keeps its own FIFO
    /// ([`crate::sja1000`], [`crate::at89c51cc`]), so its controller here only hands frames
    /// over, with no limit: [`ControllerConfig::handing_over`].
    pub rx_fifo_bytes: usize,
    /// Frames the transmit queue holds before submissions are refused.
    pub tx_queue_len: usize,
    /// Error warning limit (SJA1000 EWLR), 96 by default.
    pub warning_limit: u8,
    /// How it leaves bus off.
    pub recovery: Recovery,
}

/// How a controller leaves bus off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Recovery {
    /// It starts counting the 128 sequences of 11 recessive bits at once (the default of CAN
    /// controllers set to restart by themselves, and of SocketCAN's `restart-ms`).
    #[default]
    Automatic,
    /// It waits for its host to ask ([`crate::engine::Bus::request_recovery`]), as the SJA1000
    /// does: it enters reset mode at bus off and counts only after the host clears it.
    OnRequest,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        ControllerConfig {
            name: String::new(),
            filter: Filter::All,
            rx_fifo_bytes: SJA1000_FIFO_BYTES,
            tx_queue_len: 16,
            warning_limit: crate::fault::DEFAULT_WARNING_LIMIT,
            recovery: Recovery::Automatic,
        }
    }
}

impl ControllerConfig {
    /// A controller named `name` with the other settings at their defaults.
    pub fn named(name: impl Into<String>) -> ControllerConfig {
        ControllerConfig {
            name: name.into(),
            ..ControllerConfig::default()
        }
    }
    /// The same with another filter.
    pub fn with_filter(mut self, filter: Filter) -> ControllerConfig {
        self.filter = filter;
        self
    }
    /// The controller of a register-level node (firmware with a chip model): it takes every
    /// frame (the chip filters) and hands frames over to the chip without a FIFO limit of its
    /// own (the chip's FIFO is the one that overruns).
    pub fn handing_over(name: impl Into<String>) -> ControllerConfig {
        ControllerConfig {
            rx_fifo_bytes: usize::MAX,
            ..ControllerConfig::named(name).with_filter(Filter::All)
        }
    }
}

/// The SJA1000's receive FIFO, in bytes ([`crate::sja1000::FIFO_BYTES`]).
pub const SJA1000_FIFO_BYTES: usize = crate::sja1000::FIFO_BYTES;

/// Bytes a received frame takes in an SJA1000 receive FIFO ([`crate::sja1000::message_bytes`],
/// where the rule lives).
pub fn fifo_bytes(frame: &Frame) -> usize {
    crate::sja1000::message_bytes(frame)
}

/// A frame in a receive FIFO, stamped with its end-of-frame time.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Received {
    /// End of frame on the bus.
    pub at: BusTime,
    /// The frame.
    pub frame: Frame,
}

/// A frame waiting in a transmit queue.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) struct Pending {
    pub frame: Frame,
    pub submitted: BusTime,
    pub token: u64,
    /// One attempt only: dropped (as aborted) when that attempt fails or loses arbitration.
    pub single_shot: bool,
}

/// Counters a controller keeps for reports.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Serialize, Deserialize)]
pub struct ControllerCounters {
    /// Frames transmitted successfully.
    pub tx_frames: u64,
    /// Frames stored in the receive FIFO.
    pub rx_frames: u64,
    /// Frames received correctly but rejected by the acceptance filter.
    pub rx_filtered: u64,
    /// Frames its filter accepts that ended while it was off the bus (disconnected or bus off).
    pub rx_missed: u64,
    /// Frames it sent itself that its own filter accepts (a controller does not receive them).
    pub rx_own: u64,
    /// Frames its filter accepts that completed on the bus while it was on the bus but had
    /// detected an error in them: its error flag did not destroy them for the others (an error
    /// passive node's flag is recessive), so the frame is valid for everyone else and lost to it.
    #[serde(default)]
    pub rx_errored: u64,
    /// Frames the node took out of the receive FIFO.
    pub rx_read: u64,
    /// Frames dropped from the receive FIFO by a reset (restart, power cycle).
    pub rx_cleared: u64,
    /// Frames lost because the receive FIFO was full (data overrun).
    pub rx_overruns: u64,
    /// Submissions refused because the transmit queue was full.
    pub tx_refused: u64,
    /// Frames dropped from the transmit queue when the controller went bus off.
    pub tx_aborted: u64,
    /// Arbitration rounds lost.
    pub arbitration_lost: u64,
    /// Error frames this controller took part in as transmitter.
    pub tx_errors: u64,
    /// Error frames this controller took part in as receiver.
    pub rx_errors: u64,
}

/// One controller on the bus.
#[derive(Clone, Debug)]
pub struct Controller {
    pub(crate) config: ControllerConfig,
    pub(crate) fault: FaultConfinement,
    pub(crate) rx: VecDeque<Received>,
    pub(crate) rx_bytes: usize,
    /// SJA1000 DOS: set on overrun, cleared when the node clears it.
    pub(crate) overrun_flag: bool,
    pub(crate) tx: VecDeque<Pending>,
    pub(crate) connected: bool,
    /// Sleep mode: off the bus (`connected` false) until the next bus activity wakes it.
    pub(crate) asleep: bool,
    pub(crate) acks: bool,
    /// Listen-only (bus monitoring) mode: it drives nothing dominant (no frame, no ACK, no
    /// error or overload flag) and its counters do not move.
    pub(crate) listen_only: bool,
    /// Self-test mode (the SJA1000's MOD.STM, Linux's PRESUME_ACK): its own frames need no
    /// acknowledge.
    pub(crate) presume_ack: bool,
    /// Bus integration: it has joined the bus and waits for 11 consecutive recessive bits before
    /// it takes part; the run of recessive bits it has seen began here.
    pub(crate) integrating: Option<BusTime>,
    /// The token of the frame of the last attempt it took part in as a transmitter, and when
    /// that attempt was over for it: that frame, aborted while its attempt ran, is answered
    /// from then (it ends its attempt first).
    pub(crate) attempt: (u64, BusTime),
    /// The earliest time it may start a frame of its own: the end of its intermission, and of
    /// suspend transmission after it sent as an error-passive node.
    pub(crate) ready_at: BusTime,
    /// Its protocol state, carried between attempts, as of `mac_at`.
    pub(crate) mac: super::wire::Mac,
    /// The next bit time `mac` has not seen.
    pub(crate) mac_at: BusTime,
    /// Start of the recessive run this (bus-off) controller is counting towards recovery.
    pub(crate) recessive_since: BusTime,
    /// Its host asked it to recover from bus off ([`Recovery::OnRequest`]).
    pub(crate) recovery_requested: bool,
    pub(crate) counters: ControllerCounters,
}

impl Controller {
    pub(crate) fn new(config: ControllerConfig) -> Controller {
        let fault = FaultConfinement::with_warning_limit(config.warning_limit);
        Controller {
            rx: VecDeque::with_capacity(8),
            tx: VecDeque::with_capacity(config.tx_queue_len.min(64)),
            config,
            fault,
            rx_bytes: 0,
            overrun_flag: false,
            connected: true,
            asleep: false,
            acks: true,
            listen_only: false,
            presume_ack: false,
            integrating: None,
            attempt: (0, BusTime::ZERO),
            ready_at: BusTime::ZERO,
            mac: super::wire::Mac::default(),
            mac_at: BusTime::ZERO,
            recessive_since: BusTime::ZERO,
            recovery_requested: false,
            counters: ControllerCounters::default(),
        }
    }

    /// Its configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }
    /// Its error counters and state.
    pub fn fault(&self) -> &FaultConfinement {
        &self.fault
    }
    /// Its counters.
    pub fn counters(&self) -> &ControllerCounters {
        &self.counters
    }
    /// Frames waiting in the receive FIFO.
    pub fn rx_len(&self) -> usize {
        self.rx.len()
    }
    /// Bytes used in the receive FIFO.
    pub fn rx_bytes(&self) -> usize {
        self.rx_bytes
    }
    /// The data-overrun flag (SJA1000 DOS).
    pub fn overrun_flag(&self) -> bool {
        self.overrun_flag
    }
    /// Frames waiting to be sent.
    pub fn tx_len(&self) -> usize {
        self.tx.len()
    }
    /// True while connected to the bus (it may still be integrating: [`Controller::is_integrating`]).
    pub fn is_connected(&self) -> bool {
        self.connected
    }
    /// True in sleep mode: off the bus until bus activity or its host wakes it.
    pub fn is_asleep(&self) -> bool {
        self.asleep
    }
    /// True while it acknowledges frames: it is set to, and not listen-only.
    pub fn acks(&self) -> bool {
        self.acks && !self.listen_only
    }
    /// True in listen-only mode.
    pub fn is_listen_only(&self) -> bool {
        self.listen_only
    }
    /// True in self-test mode (its frames need no acknowledge).
    pub fn presumes_ack(&self) -> bool {
        self.presume_ack
    }

    /// Takes part in bus traffic: connected and not bus off.
    pub(crate) fn on_bus(&self) -> bool {
        self.connected && self.fault.state() != crate::fault::ErrorState::BusOff && self.integrating.is_none()
    }

    /// True while it waits to integrate into the bus: it has joined and not yet seen 11
    /// consecutive recessive bits.
    pub fn is_integrating(&self) -> bool {
        self.integrating.is_some()
    }

    /// Its protocol state machine at rest (the bus idle to it), with its modes.
    pub(crate) fn idle_mac(&self) -> super::wire::Mac {
        super::wire::Mac {
            acks: self.acks(),
            silent: self.listen_only,
            presume_ack: self.presume_ack,
            ..super::wire::Mac::default()
        }
    }

    /// Its error flags are passive (recessive): it is error passive, or listen-only.
    pub(crate) fn flags_passive(&self) -> bool {
        self.listen_only || self.fault.state() == crate::fault::ErrorState::Passive
    }

    /// It may start a frame: on the bus, and not listen-only.
    pub(crate) fn may_send(&self) -> bool {
        self.on_bus() && !self.listen_only
    }

    /// Bus off and counting recessive bits towards recovery.
    pub(crate) fn counts_recovery(&self) -> bool {
        self.fault.state() == crate::fault::ErrorState::BusOff
            && (self.config.recovery == Recovery::Automatic || self.recovery_requested)
    }

    /// Stores a received frame; false (and the overrun recorded) when it does not fit.
    pub(crate) fn store(&mut self, at: BusTime, frame: Frame) -> bool {
        let need = fifo_bytes(&frame);
        if self.rx_bytes.saturating_add(need) > self.config.rx_fifo_bytes {
            self.overrun_flag = true;
            self.counters.rx_overruns += 1;
            return false;
        }
        self.rx_bytes += need;
        self.rx.push_back(Received { at, frame });
        self.counters.rx_frames += 1;
        true
    }

    /// Releases the frames in the receive FIFO that had ended by `until` (RRB while there is
    /// one) and clears the overrun flag (CDO). A frame the engine committed ahead, still on the
    /// wire at `until`, stays.
    pub(crate) fn drain(&mut self, until: BusTime) -> (Vec<Received>, bool) {
        let mut frames = Vec::new();
        let overrun = self.drain_into(until, &mut frames);
        (frames, overrun)
    }

    /// [`Controller::drain`] onto the end of `out` (a buffer of the caller's, so that taking
    /// frames allocates nothing of its own); whether an overrun happened since the last drain.
    pub(crate) fn drain_into(&mut self, until: BusTime, out: &mut Vec<Received>) -> bool {
        let overrun = std::mem::take(&mut self.overrun_flag);
        let n = self.rx.iter().take_while(|r| r.at <= until).count();
        let mut released = 0;
        out.extend(self.rx.drain(..n).inspect(|r| released += fifo_bytes(&r.frame)));
        self.rx_bytes = self.rx_bytes.saturating_sub(released);
        self.counters.rx_read += n as u64;
        overrun
    }

    /// Empties the receive FIFO at a reset: the frames in it are lost, and counted.
    pub(crate) fn clear_rx(&mut self) {
        self.overrun_flag = false;
        self.counters.rx_cleared += self.rx.len() as u64;
        self.rx.clear();
        self.rx_bytes = 0;
    }

    /// End of the oldest frame still in the receive FIFO.
    pub(crate) fn rx_front(&self) -> Option<BusTime> {
        self.rx.front().map(|r| r.at)
    }
}
