//! The bus engine: a sans-IO, deterministic model of one CAN bus and the controllers on it.
//!
//! Contract: the caller submits frames with the bus time at which their node hands them to its
//! controller, asks [`Bus::next_event_time`] when the bus would next act if nothing else were
//! submitted, and calls [`Bus::step`] to commit that one event (an arbitration round and the frame
//! or error frame that follows it, or a bus-off recovery). Committing is final: the caller must
//! not submit a frame stamped earlier than an event it has already committed (the engine moves
//! such late submissions to the present and counts them). Results come out as [`Event`]s, in
//! time order (host calls aside, see below), from [`Bus::take_events`]; received frames wait in each controller's receive FIFO
//! until the node drains it with [`Bus::drain_rx`].
//!
//! What is modelled, bit-exactly at the configured bit rate, following the Bosch CAN 2.0
//! specification and ISO 11898-1 (docs/CAN.md): arbitration (lowest
//! [`ArbitrationKey`](crate::ArbitrationKey) wins; nodes that start within the same bit time
//! contend; losers retry when the bus is next idle), the stuffed length of every frame, ACK (a
//! frame that no other connected, acknowledging, not-bus-off controller acknowledges is an ACK
//! error), automatic retransmission, suspend transmission after anything an error-passive node
//! sent, bus off and recovery after 128 × 11 recessive bits, acceptance filters, receive FIFOs
//! with counted overruns (the SJA1000's 64 bytes by default; no limit for a controller that
//! hands frames over to a chip model, [`ControllerConfig::handing_over`]), the controller modes
//! drivers use (listen-only, self test, single shot, abort, sleep: off the bus until the next
//! start of frame wakes it) and bus integration: a controller that joins the bus takes part only
//! after 11 consecutive recessive bits.
//!
//! An attempt that goes through cleanly (one frame or identical ones, acknowledged, nothing
//! injected, every controller idle) is committed in closed form. Any other attempt runs bit by
//! bit (`episode`): every controller's protocol state machine (`wire`) drives the bus, which is
//! the wired AND of their levels; injected faults, [`Disturbance`]s and disturbances at places
//! ([`Effect::Disturb`], which each controller finds by its own state: an episode goes on until a
//! delimiter or intermission place it still waits for is past) change what chosen controllers
//! sample; and every controller detects what it would detect: bit, stuff, CRC, form
//! and ACK errors at their detection points, active and passive error flags (a passive flag is
//! recessive, so others do not see it), superposed flags of 6 to 12 bits as they fall, overload
//! frames, delimiters, and every fault-confinement rule and exception of [`crate::fault`]. What is
//! left of a delimiter or an intermission when the next frame starts is carried into that
//! attempt, so a controller still in its error delimiter sees that start of frame as a form
//! error, as on a real bus.
//!
//! Choices where the specification leaves room, all documented in `docs/CAN.md`: counters move
//! at the first bit of the error flag, except exception 3a, decided when the passive flag is
//! complete; the flag's kind (active or passive) follows the state before the error is counted; a
//! controller whose TEC reaches 256 is bus off at once and sends no flag (a bus-off node has no
//! influence on the bus), dropping the frame it was sending; a disconnected node neither sends
//! nor receives, and keeps its queue. The events of each committed event come out in time order.
//! What a host call makes the engine say (a reset, counters written, an abort's answer) is
//! stamped at that call's time (an abort's answer for a frame whose attempt is on the bus: when
//! that attempt is over), which is never before the start of the last committed event but may be
//! before that event's end: a consumer that needs one order across both puts them in
//! order within one committed event's length (`bus::trace::Reorder` does so for traces).

mod controller;
mod episode;
pub mod inject;
pub mod stats;
mod wire;

pub use controller::{
    Controller, ControllerConfig, ControllerCounters, Filter, NodeId, Received, Recovery, SJA1000_FIFO_BYTES,
    fifo_bytes,
};
pub use inject::{
    BitPosition, Decision, Disturb, DisturbCounts, Effect, Field, Injector, Place, Rule, RuleId, Schedule,
    SeenBy, Target,
};
pub use stats::Stats;
pub use wire::Location;

use crate::bits::{self, BitRate};
use crate::fault::{Changes, ErrorState};
use crate::filter::{AcceptanceFilter, kernel_can_id};
use crate::time::{BusDuration, BusTime};
use crate::{Error, Frame};
use controller::Pending;
use episode::{Anchored, Flip, Plan, Who};
use smallvec::SmallVec;

/// Intermission.
const INTERMISSION_BITS: u64 = wire::INTERMISSION_BITS as u64;
/// Suspend transmission of an error-passive transmitter.
const SUSPEND_BITS: u64 = wire::SUSPEND_BITS as u64;
/// Bus integration: consecutive recessive bits a joining controller waits for (ISO 11898-1).
pub const INTEGRATION_BITS: u64 = 11;

/// How a bus is built.
#[derive(Clone, Copy, Debug)]
pub struct BusConfig {
    /// Nominal bit rate; its bit time must be a whole number of bus-clock ticks
    /// ([`BitRate::bit_time`]).
    pub bitrate: BitRate,
    /// Seed of the injection generator.
    pub seed: u64,
    /// The class a frame's queueing latency is counted in ([`stats::BusStats::latency`]):
    /// a protocol's notion of priority, which the generic engine does not know.
    pub latency_class: LatencyClass,
}

/// Sorts a frame into a latency class, below [`stats::LATENCY_CLASSES`]; a larger number
/// counts in the last class.
pub type LatencyClass = fn(&Frame) -> usize;

/// The default [`LatencyClass`]: every frame in class 0.
pub fn one_latency_class(_: &Frame) -> usize {
    0
}

impl Default for BusConfig {
    fn default() -> Self {
        BusConfig {
            bitrate: BitRate::K250,
            seed: 0,
            latency_class: one_latency_class,
        }
    }
}

/// The kind of bus error a controller detected.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, serde::Serialize)]
pub enum BusError {
    /// A controller read back another level than it sent.
    Bit,
    /// Six equal bits where stuffing applies.
    Stuff,
    /// The CRC sequence did not match (receivers only).
    Crc,
    /// A fixed-form bit was dominant.
    Form,
    /// Nobody acknowledged (the transmitter only).
    Ack,
}

impl BusError {
    /// Short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            BusError::Bit => "bit",
            BusError::Stuff => "stuff",
            BusError::Crc => "crc",
            BusError::Form => "form",
            BusError::Ack => "ack",
        }
    }
}

/// A change to what controllers sample while something is on the bus, for tests and for
/// disturbances that injection rules cannot express: from `at` for `bits` bit times, the
/// controllers named (all when `nodes` is `None`) sample `level` (`Some(true)` recessive,
/// `Some(false)` dominant) or the inverse of the bus level (`None`). It acts only during
/// attempts (an idle bus is not disturbed), and an attempt it reaches lasts until it is over: no
/// frame starts while it lasts, even where a node would have been ready to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Disturbance {
    /// First bit time it covers (bits that start at or after it).
    pub at: BusTime,
    /// How many bit times.
    pub bits: u32,
    /// The level sampled, or `None` to invert.
    pub level: Option<bool>,
    /// Who samples it; `None` for every controller.
    pub nodes: Option<Vec<NodeId>>,
}

/// What happened on the bus.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Event {
    /// A frame went through.
    Frame {
        /// Start of frame.
        start: BusTime,
        /// End of frame (last EOF bit); receivers have it from here.
        end: BusTime,
        /// Transmitter.
        node: NodeId,
        /// The frame.
        frame: Frame,
        /// Bits on the bus, intermission included.
        bits: u32,
    },
    /// An error frame destroyed a transmission attempt (one event per transmitter that lost
    /// its attempt; each controller's own view is a [`Event::BusError`]).
    ErrorFrame {
        /// Start of the destroyed frame.
        start: BusTime,
        /// First bit of the transmitter's error flag.
        flag: BusTime,
        /// When the last flag of the episode was over (the bus quiet again).
        end: BusTime,
        /// Transmitter of the destroyed frame.
        node: NodeId,
        /// The destroyed frame.
        frame: Frame,
        /// What the transmitter detected.
        error: BusError,
        /// Bit of the frame (from SOF, tail bits after the stuffed part) at which it did.
        bit: u16,
        /// TEC and REC of the transmitter after the error.
        tec: u16,
        /// REC of the transmitter after the error.
        rec: u16,
    },
    /// A controller detected a bus error and signals it with an error flag from `at` (one
    /// event per controller, as its SocketCAN interface reports it).
    BusError {
        /// The controller.
        node: NodeId,
        /// First bit of its error flag.
        at: BusTime,
        /// What it detected.
        error: BusError,
        /// It was the transmitter of the frame.
        transmitting: bool,
        /// Where.
        location: Location,
        /// TEC after counting the error.
        tec: u16,
        /// REC after counting the error.
        rec: u16,
    },
    /// A controller lost arbitration (one event per loser and attempt).
    ArbitrationLost {
        /// The controller.
        node: NodeId,
        /// The bit time after the one it lost at.
        at: BusTime,
        /// The bit of the arbitration field it lost at: 0 is the first identifier bit, as the
        /// SJA1000's arbitration lost capture (ALC) numbers them; SRR, IDE and RTR count too.
        bit: u16,
    },
    /// A controller sends an overload flag from `at`.
    Overload {
        /// The controller.
        node: NodeId,
        /// First bit of its overload flag.
        at: BusTime,
    },
    /// A frame entered a node's receive FIFO.
    Delivered {
        /// Receiver.
        node: NodeId,
        /// End of frame.
        at: BusTime,
    },
    /// A frame passed a node's filter but its FIFO was full.
    Overrun {
        /// Receiver.
        node: NodeId,
        /// End of frame.
        at: BusTime,
    },
    /// A node's frame was sent.
    TxDone {
        /// Transmitter.
        node: NodeId,
        /// End of frame.
        at: BusTime,
        /// The token `submit` returned.
        token: u64,
        /// The frame.
        frame: Frame,
    },
    /// A node's frame was dropped from its queue because the node went bus off.
    TxAborted {
        /// Transmitter.
        node: NodeId,
        /// When.
        at: BusTime,
        /// The token `submit` returned.
        token: u64,
        /// The frame.
        frame: Frame,
    },
    /// A node's error state changed.
    State {
        /// The node.
        node: NodeId,
        /// When.
        at: BusTime,
        /// Old state.
        from: ErrorState,
        /// New state.
        to: ErrorState,
        /// TEC after the change.
        tec: u16,
        /// REC after the change.
        rec: u16,
    },
    /// A bus-off controller set to recover on request ([`Recovery::OnRequest`]) has counted
    /// this many of the 128 sequences of 11 recessive bits (the SJA1000 counts its TXERR down
    /// with them). The last one is an [`Event::State`] instead.
    RecoveryProgress {
        /// The node.
        node: NodeId,
        /// When the sequence was complete.
        at: BusTime,
        /// Sequences counted, 1 to 127.
        sequences: u8,
    },
    /// A sleeping controller saw bus activity (the start of a frame) and left sleep mode: it
    /// integrates before it takes part, so it does not receive the frame that woke it.
    Woken {
        /// The node.
        node: NodeId,
        /// The end of the first dominant bit it saw.
        at: BusTime,
    },
    /// A node's controller was reset (a node restart or a power cycle).
    Restarted {
        /// The node.
        node: NodeId,
        /// When.
        at: BusTime,
    },
    /// A node's counters crossed the warning limit.
    Warning {
        /// The node.
        node: NodeId,
        /// When.
        at: BusTime,
        /// True when it entered the warning level, false when it left.
        entered: bool,
        /// TEC.
        tec: u16,
        /// REC.
        rec: u16,
    },
}

impl Event {
    /// When it happened: the end of a frame, the first flag bit of a destroyed attempt, the
    /// `at` of the others. The engine gives events in this order.
    pub fn at(&self) -> BusTime {
        match *self {
            Event::Frame { end, .. } => end,
            Event::ErrorFrame { flag, .. } => flag,
            Event::Delivered { at, .. }
            | Event::Overrun { at, .. }
            | Event::TxDone { at, .. }
            | Event::TxAborted { at, .. }
            | Event::State { at, .. }
            | Event::Restarted { at, .. }
            | Event::Woken { at, .. }
            | Event::Warning { at, .. }
            | Event::BusError { at, .. }
            | Event::ArbitrationLost { at, .. }
            | Event::RecoveryProgress { at, .. }
            | Event::Overload { at, .. } => at,
        }
    }
}

/// What the bus does next (from [`Bus::next_event`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NextEvent {
    /// The controller at this index recovers from bus off at this time.
    Recovery(usize, BusTime),
    /// Frames pending at this start of frame are arbitrated.
    Frame(BusTime),
}

/// One CAN bus.
#[derive(Debug)]
pub struct Bus {
    latency_class: LatencyClass,
    bitrate: BitRate,
    bit: BusDuration,
    /// When the last committed activity on the bus ended.
    idle_at: BusTime,
    /// Disturbances still to come, in the order given.
    disturbances: Vec<Disturbance>,
    /// Some controller may be in a state other than idle (left by an episode, a reset or a
    /// reconnection): the next attempt settles them first.
    carried: bool,
    /// Start of the last committed event: nothing may be submitted before it.
    committed: BusTime,
    /// End of the last dominant bit committed on the bus: a controller joining later counts its
    /// recessive run from here.
    last_dominant: BusTime,
    /// Some controller may still be integrating (false lets a clean frame skip looking).
    joining: bool,
    /// Some controller may be asleep (false lets a frame skip looking for one to wake).
    sleeping: bool,
    controllers: Vec<Controller>,
    injector: Injector,
    stats: Stats,
    events: Vec<Event>,
    next_token: u64,
    late_submissions: u64,
    transmitters: Vec<usize>,
    /// Give [`Event::ArbitrationLost`] events (off unless asked: they cost time on a busy bus
    /// and only a register-level controller reads them).
    arbitration_events: bool,
}

impl Bus {
    /// An empty bus. Fails for a bit rate whose bit time the bus clock cannot hold exactly
    /// ([`BitRate::bit_time`]).
    pub fn new(config: BusConfig) -> Result<Bus, Error> {
        let bit = config
            .bitrate
            .bit_time()
            .ok_or(Error::InexactBitRate(config.bitrate.bits_per_second()))?;
        Ok(Bus {
            bitrate: config.bitrate,
            bit,
            idle_at: BusTime::ZERO,
            disturbances: Vec::new(),
            carried: false,
            committed: BusTime::ZERO,
            last_dominant: BusTime::ZERO,
            joining: false,
            sleeping: false,
            controllers: Vec::new(),
            injector: Injector::new(config.seed),
            latency_class: config.latency_class,
            stats: Stats::new(bit),
            events: Vec::new(),
            next_token: 1,
            late_submissions: 0,
            transmitters: Vec::new(),
            arbitration_events: false,
        })
    }

    /// The bit rate.
    pub fn bitrate(&self) -> BitRate {
        self.bitrate
    }
    /// One bit time.
    pub fn bit_time(&self) -> BusDuration {
        self.bit
    }
    /// Adds a controller. It takes part at once, as on a bus that has been idle before: a
    /// controller joining later integrates first ([`Bus::set_connected`]).
    pub fn attach(&mut self, config: ControllerConfig) -> NodeId {
        let id = NodeId(self.controllers.len() as u16);
        let mut c = Controller::new(config);
        c.recessive_since = self.idle_at;
        c.mac_at = self.idle_at;
        c.ready_at = self.idle_at;
        self.controllers.push(c);
        id
    }
    /// Gives [`Event::ArbitrationLost`] events from now on (or no longer).
    pub fn report_arbitration(&mut self, on: bool) {
        self.arbitration_events = on;
    }

    /// A controller.
    pub fn controller(&self, node: NodeId) -> Option<&Controller> {
        self.controllers.get(node.index())
    }
    /// All controllers, by `NodeId` order.
    pub fn controllers(&self) -> &[Controller] {
        &self.controllers
    }
    /// The statistics so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }
    /// Brings the statistics' clock to `now` (closing load windows up to it).
    pub fn advance_stats(&mut self, now: BusTime) {
        self.stats.advance_to(now);
    }
    /// Submissions that arrived stamped before an already committed event.
    pub fn late_submissions(&self) -> u64 {
        self.late_submissions
    }
    /// The injection rules.
    pub fn injector(&self) -> &Injector {
        &self.injector
    }

    /// The injection rules, to change them.
    pub fn injector_mut(&mut self) -> &mut Injector {
        &mut self.injector
    }
    /// Start of the last committed event.
    pub fn committed(&self) -> BusTime {
        self.committed
    }
    /// Adds a disturbance (see [`Disturbance`]).
    pub fn disturb(&mut self, d: Disturbance) {
        self.disturbances.push(d);
    }

    fn get_mut(&mut self, node: NodeId) -> Result<&mut Controller, Error> {
        self.controllers
            .get_mut(node.index())
            .ok_or(Error::NoNode(node.0))
    }

    /// Queues a frame that `node` hands to its controller at `at`. Returns a token that the
    /// matching [`Event::TxDone`] or [`Event::TxAborted`] carries; `Ok(None)` when the transmit
    /// queue is full (counted as refused).
    pub fn submit(&mut self, node: NodeId, frame: Frame, at: BusTime) -> Result<Option<u64>, Error> {
        self.submit_with(node, frame, at, false)
    }

    /// [`Bus::submit`], for one attempt only when `single_shot` (the SJA1000's TR with AT, Linux's
    /// ONE_SHOT): an attempt that fails or loses arbitration drops the frame, answered with an
    /// [`Event::TxAborted`] when that attempt is over; there is no retransmission.
    pub fn submit_with(
        &mut self,
        node: NodeId,
        frame: Frame,
        at: BusTime,
        single_shot: bool,
    ) -> Result<Option<u64>, Error> {
        let at = if at < self.committed {
            self.late_submissions += 1;
            self.committed
        } else {
            at
        };
        let token = self.next_token;
        let c = self.get_mut(node)?;
        if c.tx.len() >= c.config.tx_queue_len {
            c.counters.tx_refused += 1;
            return Ok(None);
        }
        c.tx.push_back(Pending {
            frame,
            submitted: at,
            token,
            single_shot,
        });
        self.next_token += 1;
        Ok(Some(token))
    }

    /// Takes from a node's receive FIFO the frames that had ended by `until`: the frames, and
    /// whether an overrun happened since the last drain. Frames committed ahead of `until`
    /// (the engine commits a whole frame at its start) stay until they have ended.
    pub fn drain_rx(&mut self, node: NodeId, until: BusTime) -> Result<(Vec<Received>, bool), Error> {
        Ok(self.get_mut(node)?.drain(until))
    }

    /// [`Bus::drain_rx`] onto the end of `out`: whether an overrun happened since the last
    /// drain.
    pub fn drain_rx_into(
        &mut self,
        node: NodeId,
        until: BusTime,
        out: &mut Vec<Received>,
    ) -> Result<bool, Error> {
        Ok(self.get_mut(node)?.drain_into(until, out))
    }

    /// End of the oldest frame waiting in a node's receive FIFO.
    pub fn rx_front(&self, node: NodeId) -> Option<BusTime> {
        self.controllers.get(node.index()).and_then(Controller::rx_front)
    }

    /// Makes a node acknowledge frames or not.
    pub fn set_ack(&mut self, node: NodeId, acks: bool) -> Result<(), Error> {
        self.get_mut(node)?.acks = acks;
        Ok(())
    }

    /// Puts a node's controller in listen-only mode or takes it out: while in it, the node
    /// drives nothing dominant (it neither acknowledges nor sends frames, error or overload
    /// flags; its frames wait in its queue) and its error counters stay as they are, but it
    /// still receives (SJA1000 data sheet 6.4.3, MOD.LOM; ISO 11898-1, bus monitoring mode).
    /// Leaving the mode, at `at`, it joins the bus again: it integrates first.
    pub fn set_listen_only(&mut self, node: NodeId, on: bool, at: BusTime) -> Result<(), Error> {
        let c = self.get_mut(node)?;
        let leaving = c.listen_only && !on;
        c.listen_only = on;
        c.fault.set_frozen(on);
        if leaving {
            self.join(node.index(), at);
        }
        Ok(())
    }

    /// Controller `i` joins the bus at `at`: before it takes part (sends, receives,
    /// acknowledges, flags) it waits for 11 consecutive recessive bits, counted from `at` or from
    /// the end of the last dominant bit of what was on the bus then (ISO 11898-1, bus
    /// integration). The frame in progress when it joins is not received by it.
    fn join(&mut self, i: usize, at: BusTime) {
        let from = at.max(self.last_dominant);
        self.joining = true;
        let c = &mut self.controllers[i];
        c.integrating = Some(from);
        c.mac = wire::Mac::default();
        c.mac_at = at;
    }

    /// Puts a node's controller in self-test mode or takes it out: its own frames then need no
    /// acknowledge (SJA1000 data sheet 6.4.3, MOD.STM; Linux's CAN_CTRLMODE_PRESUME_ACK).
    pub fn set_presume_ack(&mut self, node: NodeId, on: bool) -> Result<(), Error> {
        self.get_mut(node)?.presume_ack = on;
        Ok(())
    }

    /// Disconnects a node from the bus or connects it again at `at`. Connected again, it
    /// integrates before it takes part ([`INTEGRATION_BITS`] recessive bits).
    pub fn set_connected(&mut self, node: NodeId, connected: bool, at: BusTime) -> Result<(), Error> {
        self.get_mut(node)?;
        self.connect(node.index(), connected, at);
        Ok(())
    }

    /// [`Bus::set_connected`] for controller `i`, which exists.
    fn connect(&mut self, i: usize, connected: bool, at: BusTime) {
        let c = &mut self.controllers[i];
        c.asleep = false;
        let joins = connected && !c.connected;
        if joins {
            // A bus-off node counts its recovery from here on, and sends nothing before.
            c.recessive_since = c.recessive_since.max(at);
            c.ready_at = c.ready_at.max(at);
        }
        c.connected = connected;
        if joins {
            self.join(i, at);
        }
    }

    /// Puts a node's controller to sleep or wakes it, at `at`. Asleep it is off the bus: it
    /// drives nothing, receives nothing, its counters stay and its queued frames wait. The next
    /// start of frame on the bus wakes it ([`Event::Woken`] at the end of that first dominant
    /// bit); woken so or by its host, it integrates before it takes part (SJA1000 data sheet
    /// 6.4.3, MOD.SM: the frame that wakes the chip is not received). A controller that is not
    /// connected does not go to sleep.
    pub fn set_asleep(&mut self, node: NodeId, asleep: bool, at: BusTime) -> Result<(), Error> {
        let c = self.get_mut(node)?;
        if asleep && c.connected {
            c.connected = false;
            c.asleep = true;
            self.sleeping = true;
        } else if !asleep && c.asleep {
            self.connect(node.index(), true, at);
        }
        Ok(())
    }

    /// Bus activity from `sof` on wakes the sleeping controllers: each says so now, and joins
    /// the bus once the attempt starting at `sof` is committed (`wake_up`).
    fn woken_by(&mut self, sof: BusTime) -> Vec<usize> {
        if !self.sleeping {
            return Vec::new();
        }
        self.sleeping = false;
        let at = sof + self.bit;
        let woken: Vec<usize> = (0..self.controllers.len())
            .filter(|&i| self.controllers[i].asleep)
            .collect();
        for &i in &woken {
            self.events.push(Event::Woken {
                node: NodeId(i as u16),
                at,
            });
        }
        woken
    }

    /// The controllers woken at `sof` join the bus, counting recessive bits from the last
    /// dominant bit of what was committed from `sof` on.
    fn wake_up(&mut self, woken: Vec<usize>, sof: BusTime) {
        for i in woken {
            self.connect(i, true, sof + self.bit);
        }
    }

    /// Resets a node's controller (power cycle): counters zero, error active, queues emptied.
    pub fn reset_node(&mut self, node: NodeId, at: BusTime) -> Result<(), Error> {
        let c = self.get_mut(node)?;
        c.fault.reset();
        c.asleep = false;
        c.listen_only = false;
        c.presume_ack = false;
        c.tx.clear();
        c.clear_rx();
        c.recessive_since = at;
        c.ready_at = c.ready_at.max(at);
        if c.connected {
            self.join(node.index(), at);
        }
        self.events.push(Event::Restarted { node, at });
        self.sample(node, at);
        Ok(())
    }

    /// The host of a bus-off controller set to [`Recovery::OnRequest`] asks it to recover: it
    /// counts recessive bits from `at`. Nothing happens for a controller that is not bus off or
    /// already counting.
    pub fn request_recovery(&mut self, node: NodeId, at: BusTime) -> Result<(), Error> {
        let at = at.max(self.committed);
        let c = self.get_mut(node)?;
        if c.fault.state() == ErrorState::BusOff && !c.counts_recovery() {
            c.recovery_requested = true;
            c.fault.dominant_bit();
            c.recessive_since = c.recessive_since.max(at);
        }
        Ok(())
    }

    /// Drops every frame in a node's queue: each becomes an [`Event::TxAborted`] at `at`. An
    /// attempt already on the bus at `at` runs to its end (the engine commits attempts whole):
    /// if it succeeded, its frame has left the queue and is answered with its
    /// [`Event::TxDone`]; if it failed or lost arbitration, its frame is not retried, and the
    /// answer comes when that attempt was over for the node.
    pub fn abort(&mut self, node: NodeId, at: BusTime) -> Result<(), Error> {
        let at = at.max(self.committed);
        let c = self.get_mut(node)?;
        let (token, end) = c.attempt;
        let mut dropped: Vec<(BusTime, Pending)> =
            c.tx.drain(..)
                .map(|p| (if p.token == token { at.max(end) } else { at }, p))
                .collect();
        c.counters.tx_aborted += dropped.len() as u64;
        dropped.sort_by_key(|(t, _)| *t);
        for (at, p) in dropped {
            self.events.push(Event::TxAborted {
                node,
                at,
                token: p.token,
                frame: p.frame,
            });
        }
        Ok(())
    }

    /// The host writes a controller's error counters ([`crate::fault::FaultConfinement::set_counters`]),
    /// e.g. the SJA1000's TXERR and RXERR in reset mode.
    pub fn set_counters(&mut self, node: NodeId, tec: u16, rec: u16, at: BusTime) -> Result<(), Error> {
        let at = at.max(self.committed);
        let c = self.get_mut(node)?;
        let changes = c.fault.set_counters(tec, rec);
        c.recovery_requested = false;
        c.recessive_since = at;
        self.note(node, at, changes);
        Ok(())
    }

    /// True when events wait for [`Bus::take_events`].
    pub fn has_events(&self) -> bool {
        !self.events.is_empty()
    }

    /// Takes the events committed so far.
    pub fn take_events(&mut self) -> std::vec::Drain<'_, Event> {
        self.events.drain(..)
    }

    /// When a frame would next start, if nothing else were submitted. A controller still
    /// integrating starts no earlier than its 11th recessive bit is over.
    fn next_sof(&self) -> Option<BusTime> {
        if !self.joining {
            // Nobody integrating (nearly always): the frames waiting in controllers that may send.
            return self
                .controllers
                .iter()
                .filter(|c| c.may_send())
                .filter_map(|c| c.tx.front().map(|p| p.submitted.max(c.ready_at)))
                .min();
        }
        let integration = self.bit * INTEGRATION_BITS;
        self.controllers
            .iter()
            .filter(|c| c.connected && !c.listen_only && c.fault.state() != ErrorState::BusOff)
            .filter_map(|c| {
                let integrated = c.integrating.map_or(BusTime::ZERO, |t| t + integration);
                c.tx.front().map(|p| p.submitted.max(c.ready_at).max(integrated))
            })
            .min()
    }

    /// Controllers whose 11 recessive bits are over by `sof` take part from here.
    fn integrate_by(&mut self, sof: BusTime) {
        if !self.joining {
            return;
        }
        let integration = self.bit * INTEGRATION_BITS;
        let mut still = false;
        for c in &mut self.controllers {
            if let Some(t) = c.integrating {
                if t + integration <= sof {
                    c.integrating = None;
                    c.mac = wire::Mac::default();
                    c.mac_at = sof;
                    c.ready_at = c.ready_at.max(t + integration);
                } else {
                    still = true;
                }
            }
        }
        self.joining = still;
    }

    /// When the next bus-off node would recover, if no frame came first.
    fn next_recovery(&self) -> Option<(BusTime, usize)> {
        self.controllers
            .iter()
            .enumerate()
            .filter(|(_, c)| c.counts_recovery())
            .map(|(i, c)| {
                // A controller that reports its progress stops at every sequence.
                let bits = if c.config.recovery == Recovery::OnRequest {
                    c.fault
                        .recovery_bits_remaining()
                        .min(crate::fault::RECOVERY_SEQUENCE_BITS - c.fault.recovery_run())
                } else {
                    c.fault.recovery_bits_remaining()
                };
                (c.recessive_since + u64::from(bits) * self.bit, i)
            })
            .min()
    }

    /// When the bus next acts on its own: a frame starting or a node recovering from bus off.
    pub fn next_event_time(&self) -> Option<BusTime> {
        self.next_event().map(|(t, _)| t)
    }

    /// The next event the bus would commit, and when: pass it to [`Bus::commit`] (before
    /// anything else changes the bus) to commit it without looking for it again.
    pub fn next_event(&self) -> Option<(BusTime, NextEvent)> {
        match (self.next_sof(), self.next_recovery()) {
            (sof, Some((r, i))) if sof.is_none_or(|s| r <= s) => Some((r, NextEvent::Recovery(i, r))),
            (Some(s), _) => Some((s, NextEvent::Frame(s))),
            _ => None,
        }
    }

    /// Commits an event found by [`Bus::next_event`].
    pub fn commit(&mut self, event: NextEvent) {
        match event {
            NextEvent::Recovery(i, at) => self.recover(i, at),
            NextEvent::Frame(sof) => self.attempt(sof),
        }
    }

    /// Commits the next event. Returns false when there is nothing to do.
    pub fn step(&mut self) -> bool {
        match self.next_event() {
            Some((_, event)) => {
                self.commit(event);
                true
            }
            None => false,
        }
    }

    /// Commits every event that starts before `until`.
    pub fn run_until(&mut self, until: BusTime) {
        while self.next_event_time().is_some_and(|t| t < until) {
            self.step();
        }
    }

    fn recover(&mut self, i: usize, at: BusTime) {
        self.committed = self.committed.max(at);
        let node = NodeId(i as u16);
        let c = &mut self.controllers[i];
        let bits = c.fault.recovery_bits_remaining();
        let bits = if c.config.recovery == Recovery::OnRequest {
            bits.min(crate::fault::RECOVERY_SEQUENCE_BITS - c.fault.recovery_run())
        } else {
            bits
        };
        let before = c.fault.recovery_progress();
        let changes = c.fault.recessive_bits(bits);
        c.recessive_since = at;
        if c.fault.state() == ErrorState::BusOff {
            self.progress(i, at, before);
            return;
        }
        c.recovery_requested = false;
        // Back on the bus from here: an idle bus, and nothing sent before the recovery. The
        // 128 × 11 recessive bits integrate it as well.
        c.integrating = None;
        c.ready_at = c.ready_at.max(at);
        c.mac = wire::Mac::default();
        c.mac_at = at;
        self.note(node, at, changes);
    }

    /// After an attempt of controller `i` that did not send its frame: a single-shot frame is
    /// dropped, answered with [`Event::TxAborted`] at `at`.
    pub(crate) fn drop_single_shot(&mut self, i: usize, at: BusTime, token: u64) {
        let c = &mut self.controllers[i];
        if !c.tx.front().is_some_and(|p| p.single_shot && p.token == token) {
            return;
        }
        let Some(p) = c.tx.pop_front() else { return };
        c.counters.tx_aborted += 1;
        self.events.push(Event::TxAborted {
            node: NodeId(i as u16),
            at,
            token: p.token,
            frame: p.frame,
        });
    }

    /// Tells of a controller's recovery progress since `before` sequences, when it reports it.
    pub(crate) fn progress(&mut self, i: usize, at: BusTime, before: u8) {
        let c = &self.controllers[i];
        let sequences = c.fault.recovery_progress();
        if c.config.recovery == Recovery::OnRequest
            && c.fault.state() == ErrorState::BusOff
            && sequences != before
        {
            self.events.push(Event::RecoveryProgress {
                node: NodeId(i as u16),
                at,
                sequences,
            });
        }
    }

    /// Records fault-confinement changes as events and, when there are any, in the history.
    fn note(&mut self, node: NodeId, at: BusTime, changes: Changes) {
        self.note_events(node, at, changes);
        if !changes.is_empty() {
            self.sample(node, at);
        }
    }

    fn note_events(&mut self, node: NodeId, at: BusTime, changes: Changes) {
        if changes.is_empty() {
            return;
        }
        let c = &self.controllers[node.index()];
        let (tec, rec) = (c.fault.tec(), c.fault.rec());
        if let Some(t) = changes.transition {
            self.events.push(Event::State {
                node,
                at,
                from: t.from,
                to: t.to,
                tec,
                rec,
            });
        }
        if let Some(w) = changes.warning {
            let entered = matches!(w, crate::fault::WarningChange::Entered);
            self.events.push(Event::Warning {
                node,
                at,
                entered,
                tec,
                rec,
            });
        }
    }

    /// Puts a node's counters in the history. Every error is recorded; successful frames only
    /// when they change the state, so a long quiet run does not fill the history.
    fn sample(&mut self, node: NodeId, at: BusTime) {
        let c = &self.controllers[node.index()];
        let (tec, rec, state) = (c.fault.tec(), c.fault.rec(), c.fault.state());
        self.stats.node_counters(node, at, tec, rec, state);
    }

    /// Bus-off nodes see a dominant bit at `sof`: the recessive run they were counting ends.
    fn break_recessive_runs(&mut self, sof: BusTime, resume: BusTime) {
        let bit_ns = self.bit;
        for i in 0..self.controllers.len() {
            let c = &mut self.controllers[i];
            if c.connected && c.counts_recovery() {
                let bits = (sof - c.recessive_since) / bit_ns;
                let before = c.fault.recovery_progress();
                c.fault.recessive_bits(bits as u32);
                c.fault.dominant_bit();
                c.recessive_since = resume;
                self.progress(i, sof, before);
            }
        }
    }

    fn attempt(&mut self, sof: BusTime) {
        self.committed = self.committed.max(sof);
        self.integrate_by(sof);
        let bit = self.bit;
        // Contenders: nodes ready to start within the same bit time.
        let mut winner: Option<(crate::ArbitrationKey, usize)> = None;
        let mut starters = std::mem::take(&mut self.transmitters);
        starters.clear();
        for (i, c) in self.controllers.iter().enumerate() {
            if !c.may_send() {
                continue;
            }
            let Some(p) = c.tx.front() else { continue };
            if p.submitted.max(c.ready_at) >= sof + bit {
                continue;
            }
            starters.push(i);
            let key = p.frame.arbitration();
            if winner.is_none_or(|(k, _)| key < k) {
                winner = Some((key, i));
            }
        }
        let Some((key, w)) = winner else {
            self.transmitters = starters;
            return;
        };
        let woken = self.woken_by(sof);
        let frame = self.controllers[w].tx[0].frame;
        // After a clean frame every controller is idle: only an episode leaves states to carry.
        let mut all_idle = true;
        if self.carried {
            for i in 0..self.controllers.len() {
                if self.controllers[i].on_bus() {
                    self.settle(i, sof);
                    all_idle &= self.controllers[i].mac.idle_for_sof();
                }
            }
        }
        let stuffed_len = bits::stuffed_len(&frame);
        let total_bits = stuffed_len + bits::TAIL_BITS;
        let horizon = sof + u64::from(total_bits) * bit;
        self.disturbances.retain(|d| d.at + u64::from(d.bits) * bit > sof);
        let disturbed = self.disturbances.iter().any(|d| d.at < horizon);
        let decision = if self.injector.is_empty() {
            inject::Decision::default()
        } else {
            let arb_bits: u16 = if frame.is_extended() { 33 } else { 13 };
            let last = (stuffed_len - 1) as u16;
            let first = (arb_bits + arb_bits / 4).min(last);
            self.injector
                .decide(NodeId(w as u16), &frame, first, last, &mut |effect| {
                    positions(&frame, effect, first)
                })
        };
        // Identical frames go out together; the same identifier with other contents collides.
        let clash = starters.iter().any(|&i| {
            let other = self.controllers[i].tx[0].frame;
            other.arbitration() == key && other != frame
        });
        let sends_it = |c: &Controller| c.tx.front().is_some_and(|p| p.frame == frame);
        let ackers = self
            .controllers
            .iter()
            .enumerate()
            .any(|(i, c)| c.acks() && c.on_bus() && !(starters.contains(&i) && sends_it(c)));
        let acked = ackers
            || starters
                .iter()
                .map(|&i| &self.controllers[i])
                .filter(|c| sends_it(c))
                .all(|c| c.presume_ack);
        if decision.is_none() && !disturbed && !clash && acked && all_idle {
            // Starters sending another frame lose arbitration; the rest go out together.
            let mut lost_at = Vec::new();
            // Each loser with the token of the frame it tried.
            let mut losers: SmallVec<[(usize, u64); 8]> = SmallVec::new();
            let mut k = 0;
            while k < starters.len() {
                let c = &mut self.controllers[starters[k]];
                if c.tx.front().is_some_and(|p| p.frame == frame) {
                    k += 1;
                } else if !self.arbitration_events {
                    c.counters.arbitration_lost += 1;
                    losers.push((starters.swap_remove(k), c.tx.front().map_or(0, |p| p.token)));
                } else {
                    c.counters.arbitration_lost += 1;
                    let own = c.tx.front().map(|p| p.frame);
                    let token = c.tx.front().map_or(0, |p| p.token);
                    let lost = own
                        .and_then(|f| bits::arbitration_lost_at(&f, &frame))
                        .unwrap_or(0);
                    // Both sent the same bits up to there, stuff bits included.
                    let wire = bits::stuffed_position(&frame, u32::from(lost) + 1);
                    lost_at.push(Event::ArbitrationLost {
                        node: NodeId(starters[k] as u16),
                        at: sof + u64::from(wire + 1) * bit,
                        bit: lost,
                    });
                    losers.push((starters.swap_remove(k), token));
                }
            }
            lost_at.sort_by_key(Event::at);
            self.events.extend(lost_at);
            if self.carried {
                // Whatever was left (a suspend, the last intermission bit) ends with this frame.
                for c in &mut self.controllers {
                    c.mac = wire::Mac::default();
                }
                self.carried = false;
            }
            self.succeed(sof, w, &starters, frame, total_bits, ackers);
            let end = sof + (u64::from(total_bits) - INTERMISSION_BITS) * bit;
            for (i, token) in losers {
                self.controllers[i].attempt = (token, end);
                self.drop_single_shot(i, end, token);
            }
        } else {
            let n = self.controllers.len();
            let anchored = decision
                .disturb
                .into_iter()
                .map(|(rule, d, seen_by)| Anchored {
                    rule,
                    place: d.place,
                    level: d.level,
                    bits: u32::from(d.bits.max(1)),
                    who: match seen_by {
                        SeenBy::All => Who::All,
                        SeenBy::Nodes(list) => Who::Nodes(list),
                    },
                    from: vec![None; n],
                })
                .collect();
            let mut plan = Plan {
                flips: Vec::new(),
                anchored,
                extended: frame.is_extended(),
                overload: decision.overload,
            };
            if let Some((effect, at, seen_by)) = decision.corrupt {
                let who = match (effect, seen_by) {
                    (Effect::Bit, _) => Who::All,
                    (_, SeenBy::All) => Who::Receivers,
                    (_, SeenBy::Nodes(list)) => Who::ReceiversIn(list),
                };
                plan.flips.push(Flip {
                    from: u32::from(at),
                    bits: 1,
                    level: (effect == Effect::Form).then_some(wire::DOM),
                    who,
                });
            }
            for d in &self.disturbances {
                let end = d.at + u64::from(d.bits) * bit;
                let from = if d.at <= sof {
                    0
                } else {
                    (d.at - sof).div_ceil(bit)
                };
                let to = (end - sof).div_ceil(bit);
                if to > from {
                    plan.flips.push(Flip {
                        from: from.min(u64::from(u32::MAX)) as u32,
                        bits: (to - from).min(u64::from(u32::MAX)) as u32,
                        level: d.level,
                        who: d.nodes.clone().map_or(Who::All, Who::Nodes),
                    });
                }
            }
            self.episode(sof, &starters, plan);
            self.carried = true;
        }
        self.wake_up(woken, sof);
        self.transmitters = starters;
    }

    fn succeed(
        &mut self,
        sof: BusTime,
        w: usize,
        transmitters: &[usize],
        frame: Frame,
        total_bits: u32,
        acked: bool,
    ) {
        let bit = self.bit;
        let end = sof + (u64::from(total_bits) - INTERMISSION_BITS) * bit;
        let idle = sof + u64::from(total_bits) * bit;
        // After the ACK slot (dominant) everything up to the next SOF is recessive.
        let ack_slot_end = end - (7 + 1) * bit;
        self.break_recessive_runs(sof, ack_slot_end);
        // The last dominant bit: the ACK slot, or without an acknowledge (a self-test
        // transmitter alone) the last dominant bit of the stuffed part.
        let last_dominant = if acked {
            ack_slot_end
        } else {
            let stuffed = bits::encode(&frame).stuffed;
            let last = (0..stuffed.len())
                .rev()
                .find(|&k| stuffed.get(k) == Some(wire::DOM));
            sof + (last.map_or(0, |k| k as u64) + 1) * bit
        };
        self.last_dominant = self.last_dominant.max(last_dominant);
        if self.joining {
            for c in &mut self.controllers {
                if let Some(t) = c.integrating.as_mut() {
                    *t = (*t).max(last_dominant);
                }
            }
        }
        let suspend_end = idle + SUSPEND_BITS * bit;
        self.stats.advance_to(end);
        self.stats.busy(sof, idle, total_bits);
        let latency = end - self.controllers[w].tx[0].submitted;
        let class = (self.latency_class)(&frame);
        self.stats
            .frame(kernel_can_id(&frame), frame.data(), class, end, latency);
        self.events.push(Event::Frame {
            start: sof,
            end,
            node: NodeId(w as u16),
            frame,
            bits: total_bits,
        });
        for &t in transmitters {
            let c = &mut self.controllers[t];
            c.mac_at = idle;
            c.ready_at = c.ready_at.max(idle);
            let Some(p) = c.tx.pop_front() else { continue };
            c.attempt = (p.token, end);
            c.counters.tx_frames += 1;

            if c.config.filter.accepts(&frame) {
                c.counters.rx_own += 1;
            }
            let recovering = c.fault.tec() > 0;
            let changes = c.fault.transmit_success();
            // Suspend transmission: a node still error passive after what it sent waits 8 more
            // bits, unless somebody else starts first.
            if c.fault.state() == ErrorState::Passive {
                c.ready_at = c.ready_at.max(suspend_end);
            }
            self.events.push(Event::TxDone {
                node: NodeId(t as u16),
                at: end,
                token: p.token,
                frame: p.frame,
            });
            self.note_events(NodeId(t as u16), end, changes);
            if recovering {
                // Counters coming down after errors are part of the history too.
                self.sample(NodeId(t as u16), end);
            }
        }
        for i in 0..self.controllers.len() {
            if transmitters.contains(&i) {
                continue;
            }
            let c = &mut self.controllers[i];
            c.mac_at = idle;
            c.ready_at = c.ready_at.max(idle);
            if !c.on_bus() {
                // Counted for the books: a frame addressed to it that it never saw.
                if c.config.filter.accepts(&frame) {
                    c.counters.rx_missed += 1;
                }
                continue;
            }
            // Rule 8 counts a reception only with the node's ACK sent.
            let recovering = c.fault.rec() > 0 && c.acks();
            let changes = if c.acks() {
                c.fault.receive_success()
            } else {
                Changes::NONE
            };
            if c.config.filter.accepts(&frame) {
                if c.store(end, frame) {
                    self.stats.deliveries += 1;
                    self.events.push(Event::Delivered {
                        node: NodeId(i as u16),
                        at: end,
                    });
                } else {
                    self.stats.overruns += 1;
                    self.events.push(Event::Overrun {
                        node: NodeId(i as u16),
                        at: end,
                    });
                }
            } else {
                c.counters.rx_filtered += 1;
            }
            self.note_events(NodeId(i as u16), end, changes);
            if recovering {
                self.sample(NodeId(i as u16), end);
            }
        }
        self.idle_at = idle;
    }
}

/// Bits of `frame` where an injected `effect` can fall: stuff bits for a stuff error, data and
/// CRC bits whose flip is a CRC error (and nothing else) to a receiver, fixed-form tail bits for
/// a form error. Empty for a wire flip and an overload, which need no search.
fn positions(frame: &Frame, effect: Effect, first: u16) -> Vec<u16> {
    let stuffed = bits::encode(frame).stuffed;
    let len = stuffed.len() as u16;
    match effect {
        Effect::Stuff => wire::stuff_bits(&stuffed)
            .into_iter()
            .filter(|&b| b >= 1)
            .collect(),
        Effect::Crc => (first..len)
            .filter(|&b| wire::receiver_outcome(&stuffed, u32::from(b)) == wire::Outcome::Crc)
            .collect(),
        Effect::Form => {
            let t = |x: u8| len + u16::from(x);
            let mut v = vec![t(wire::tail::CRC_DEL), t(wire::tail::ACK_DEL)];
            v.extend((wire::tail::EOF..=wire::tail::EOF6).map(t));
            v
        }
        Effect::Bit | Effect::Overload(_) | Effect::Disturb(_) => Vec::new(),
    }
}

#[cfg(test)]
mod host_tests;
#[cfg(test)]
mod tests;
