//! The bus engine: a sans-IO, deterministic model of one CAN bus and the controllers on it.
//!
//! Contract: the caller submits frames with the bus time at which their node hands them to its
//! controller, asks [`Bus::next_event_time`] when the bus would next act if nothing else were
//! submitted, and calls [`Bus::step`] to commit that one event (an arbitration round and the frame
//! or error frame that follows it, or a bus-off recovery). Committing is final: the caller must
//! not submit a frame stamped earlier than an event it has already committed (the engine moves
//! such late submissions to the present and counts them). Results come out as [`Event`]s, in
//! time order, from [`Bus::take_events`]; received frames wait in each controller's receive FIFO
//! until the node drains it with [`Bus::drain_rx`].
//!
//! What is modelled, bit-exactly at the configured bit rate: arbitration (lowest
//! [`ArbitrationKey`](crate::ArbitrationKey) wins; nodes that start within the same bit time
//! contend; losers retry when the bus is next idle), the stuffed length of every frame, ACK (a
//! frame that no other connected, acknowledging, not-bus-off controller acknowledges is an ACK
//! error), error frames (flag, superposition, delimiter, intermission, and the 8-bit suspend of an
//! error-passive transmitter), fault confinement through [`FaultConfinement`], automatic
//! retransmission, bus off and recovery after 128 × 11 recessive bits, acceptance filters, and the
//! SJA1000's 64-byte receive FIFO with counted overruns.
//!
//! Simplifications, chosen so that runs stay deterministic and documented in `docs/DESIGN.md`:
//! an error flag that more than one error-active node sends is taken to be superposed to the full
//! 12 bits, one sent by a single active node to 6; a node that loses bus-off does not keep the
//! frame it was sending; a disconnected node neither sends nor receives, and keeps its queue.

mod controller;
pub mod inject;
pub mod stats;

pub use controller::{
    Controller, ControllerConfig, ControllerCounters, Filter, NodeId, Received, SJA1000_FIFO_BYTES,
    fifo_bytes,
};
pub use inject::{BitPosition, Injector, Rule, RuleId, Schedule, Target};
pub use stats::Stats;

use crate::bits::{self, BitRate};
use crate::fault::{Changes, ErrorState, TransmitError, TxErrorKind};
use crate::filter::{AcceptanceFilter, kernel_can_id};
use crate::time::BusTime;
use crate::{Error, Frame};
use controller::Pending;

/// Bits of an error flag sent by one node.
const FLAG_BITS: u64 = 6;
/// Error delimiter.
const DELIMITER_BITS: u64 = 8;
/// Intermission.
const INTERMISSION_BITS: u64 = 3;
/// Suspend transmission of an error-passive transmitter.
const SUSPEND_BITS: u64 = 8;

/// How a bus is built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusConfig {
    /// Nominal bit rate; must have a whole-nanosecond bit time.
    pub bitrate: BitRate,
    /// Seed of the injection generator.
    pub seed: u64,
}

impl Default for BusConfig {
    fn default() -> Self {
        BusConfig {
            bitrate: BitRate::K250,
            seed: 0,
        }
    }
}

/// The kind of bus error behind an error frame.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, serde::Serialize)]
pub enum BusError {
    /// The transmitter read back another level than it sent (injected corruption, collision).
    Bit,
    /// Nobody acknowledged.
    Ack,
}

impl BusError {
    /// Short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            BusError::Bit => "bit",
            BusError::Ack => "ack",
        }
    }
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
    /// An error frame destroyed a transmission attempt.
    ErrorFrame {
        /// Start of the destroyed frame.
        start: BusTime,
        /// First bit of the error flag.
        flag: BusTime,
        /// End of the error delimiter.
        end: BusTime,
        /// Transmitter of the destroyed frame.
        node: NodeId,
        /// The destroyed frame.
        frame: Frame,
        /// What went wrong.
        error: BusError,
        /// Stuffed bit at which the error was detected.
        bit: u16,
        /// TEC and REC of the transmitter after the error.
        tec: u16,
        /// REC of the transmitter after the error.
        rec: u16,
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
    bitrate: BitRate,
    bit_ns: u64,
    /// When the bus is next idle (end of the last intermission).
    idle_at: BusTime,
    /// Start of the last committed event: nothing may be submitted before it.
    committed: BusTime,
    controllers: Vec<Controller>,
    injector: Injector,
    stats: Stats,
    events: Vec<Event>,
    next_token: u64,
    late_submissions: u64,
    transmitters: Vec<usize>,
}

impl Bus {
    /// An empty bus. Fails for a bit rate whose bit time is not a whole number of nanoseconds.
    pub fn new(config: BusConfig) -> Result<Bus, Error> {
        let bit_ns = config.bitrate.exact_bit_time_ns().ok_or_else(|| {
            Error::Syntax(format!(
                "bit rate {} bit/s has no whole-nanosecond bit time; use 125000, 250000, 500000 or 1000000",
                config.bitrate.bits_per_second()
            ))
        })?;
        Ok(Bus {
            bitrate: config.bitrate,
            bit_ns,
            idle_at: BusTime::ZERO,
            committed: BusTime::ZERO,
            controllers: Vec::new(),
            injector: Injector::new(config.seed),
            stats: Stats::new(bit_ns),
            events: Vec::new(),
            next_token: 1,
            late_submissions: 0,
            transmitters: Vec::new(),
        })
    }

    /// The bit rate.
    pub fn bitrate(&self) -> BitRate {
        self.bitrate
    }
    /// One bit time in nanoseconds.
    pub fn bit_ns(&self) -> u64 {
        self.bit_ns
    }
    /// Adds a controller.
    pub fn attach(&mut self, config: ControllerConfig) -> NodeId {
        let id = NodeId(self.controllers.len() as u16);
        let mut c = Controller::new(config);
        c.recessive_since = self.idle_at;
        self.controllers.push(c);
        id
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
    pub fn injector_mut(&mut self) -> &mut Injector {
        &mut self.injector
    }
    /// Start of the last committed event.
    pub fn committed(&self) -> BusTime {
        self.committed
    }

    fn get_mut(&mut self, node: NodeId) -> Result<&mut Controller, Error> {
        self.controllers
            .get_mut(node.index())
            .ok_or_else(|| Error::Syntax(format!("no node {}", node.0)))
    }

    /// Queues a frame that `node` hands to its controller at `at`. Returns a token that the
    /// matching [`Event::TxDone`] or [`Event::TxAborted`] carries; `Ok(None)` when the transmit
    /// queue is full (counted as refused).
    pub fn submit(&mut self, node: NodeId, frame: Frame, at: BusTime) -> Result<Option<u64>, Error> {
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

    /// End of the oldest frame waiting in a node's receive FIFO.
    pub fn rx_front(&self, node: NodeId) -> Option<BusTime> {
        self.controllers.get(node.index()).and_then(Controller::rx_front)
    }

    /// Makes a node acknowledge frames or not.
    pub fn set_ack(&mut self, node: NodeId, acks: bool) -> Result<(), Error> {
        self.get_mut(node)?.acks = acks;
        Ok(())
    }

    /// Disconnects a node from the bus or connects it again at `at`.
    pub fn set_connected(&mut self, node: NodeId, connected: bool, at: BusTime) -> Result<(), Error> {
        let c = self.get_mut(node)?;
        if connected && !c.connected {
            // It sees an idle bus from here on, and sends nothing before it is back.
            c.recessive_since = c.recessive_since.max(at);
            c.suspended_until = c.suspended_until.max(at);
        }
        c.connected = connected;
        Ok(())
    }

    /// Resets a node's controller (power cycle): counters zero, error active, queues emptied.
    pub fn reset_node(&mut self, node: NodeId, at: BusTime) -> Result<(), Error> {
        let c = self.get_mut(node)?;
        c.fault.reset();
        c.tx.clear();
        c.clear_rx();
        c.recessive_since = at;
        c.suspended_until = c.suspended_until.max(at);
        self.events.push(Event::Restarted { node, at });
        self.sample(node, at);
        Ok(())
    }

    /// Takes the events committed so far.
    pub fn take_events(&mut self) -> std::vec::Drain<'_, Event> {
        self.events.drain(..)
    }

    /// When a frame would next start, if nothing else were submitted.
    fn next_sof(&self) -> Option<BusTime> {
        self.controllers
            .iter()
            .filter(|c| c.on_bus())
            .filter_map(|c| {
                c.tx.front()
                    .map(|p| p.submitted.max(self.idle_at).max(c.suspended_until))
            })
            .min()
    }

    /// When the next bus-off node would recover, if no frame came first.
    fn next_recovery(&self) -> Option<(BusTime, usize)> {
        self.controllers
            .iter()
            .enumerate()
            .filter(|(_, c)| c.fault.state() == ErrorState::BusOff)
            .map(|(i, c)| {
                let at = c.recessive_since + u64::from(c.fault.recovery_bits_remaining()) * self.bit_ns;
                (at, i)
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
        let changes = c.fault.recessive_bits(bits);
        c.recessive_since = at;
        self.note(node, at, changes);
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
        let bit_ns = self.bit_ns;
        for c in &mut self.controllers {
            if c.connected && c.fault.state() == ErrorState::BusOff {
                let bits = (sof - c.recessive_since) / bit_ns;
                c.fault.recessive_bits(bits as u32);
                c.fault.dominant_bit();
                c.recessive_since = resume;
            }
        }
    }

    fn attempt(&mut self, sof: BusTime) {
        self.committed = self.committed.max(sof);
        let bit = self.bit_ns;
        // Contenders: nodes ready to start within the same bit time.
        let mut winner: Option<(crate::ArbitrationKey, usize)> = None;
        let mut contenders = 0;
        for (i, c) in self.controllers.iter().enumerate() {
            if !c.on_bus() {
                continue;
            }
            let Some(p) = c.tx.front() else { continue };
            let ready = p.submitted.max(self.idle_at).max(c.suspended_until);
            if ready >= sof + bit {
                continue;
            }
            contenders += 1;
            let key = p.frame.arbitration();
            if winner.is_none_or(|(k, _)| key < k) {
                winner = Some((key, i));
            }
        }
        let Some((key, w)) = winner else { return };
        let mut collision: Vec<usize> = Vec::new();
        if contenders > 1 {
            for (i, c) in self.controllers.iter_mut().enumerate() {
                if i == w || !c.on_bus() {
                    continue;
                }
                let Some(p) = c.tx.front() else { continue };
                let ready = p.submitted.max(self.idle_at).max(c.suspended_until);
                if ready >= sof + bit {
                    continue;
                }
                if p.frame.arbitration() == key {
                    collision.push(i);
                } else {
                    c.counters.arbitration_lost += 1;
                }
            }
        }
        let pending = self.controllers[w].tx[0];
        let frame = pending.frame;
        // The full bitstream is only needed when two different frames collide.
        let stuffed_len = u64::from(bits::stuffed_len(&frame));

        // Two nodes sending the same identifier with different contents collide at the first
        // bit where their streams differ; identical frames simply go out together.
        let mut error_bit: Option<(u16, BusError)> = None;
        let mut same_frame_partners: Vec<usize> = Vec::new();
        for &i in &collision {
            let other = self.controllers[i].tx[0].frame;
            if other == frame {
                same_frame_partners.push(i);
            } else {
                let ours = bits::encode(&frame).stuffed;
                let theirs = bits::encode(&other).stuffed;
                let differ = (0..ours.len().max(theirs.len()))
                    .find(|&b| ours.get(b) != theirs.get(b))
                    .unwrap_or(0);
                error_bit = Some((differ as u16, BusError::Bit));
            }
        }
        if error_bit.is_none() && !self.injector.is_empty() {
            let arb_bits: u16 = if frame.is_extended() { 33 } else { 13 };
            let last = (stuffed_len - 1) as u16;
            let first = (arb_bits + arb_bits / 4).min(last);
            if let Some(b) = self
                .injector
                .decide(NodeId(w as u16), frame.raw_id(), first, last)
            {
                error_bit = Some((b, BusError::Bit));
            }
        }
        // A buffer kept across frames: one frame each is too often to allocate for.
        let mut transmitters = std::mem::take(&mut self.transmitters);
        transmitters.clear();
        transmitters.push(w);
        transmitters.extend_from_slice(if error_bit.is_some() {
            &collision
        } else {
            &same_frame_partners
        });
        let is_tx = |i: usize| transmitters.contains(&i);
        let ackers = self
            .controllers
            .iter()
            .enumerate()
            .filter(|(i, c)| !is_tx(*i) && c.on_bus() && c.acks)
            .count();
        if error_bit.is_none() && ackers == 0 {
            error_bit = Some(((stuffed_len + 1) as u16, BusError::Ack));
        }
        match error_bit {
            None => self.succeed(sof, w, &transmitters, frame, stuffed_len as u32 + bits::TAIL_BITS),
            Some((b, error)) => self.fail(sof, w, &transmitters, frame, b, error),
        }
        self.transmitters = transmitters;
    }

    fn succeed(&mut self, sof: BusTime, w: usize, transmitters: &[usize], frame: Frame, total_bits: u32) {
        let bit = self.bit_ns;
        let end = sof + (u64::from(total_bits) - INTERMISSION_BITS) * bit;
        let idle = sof + u64::from(total_bits) * bit;
        // After the ACK slot (dominant) everything up to the next SOF is recessive.
        let ack_slot_end = BusTime(end.0 - (7 + 1) * bit);
        self.break_recessive_runs(sof, ack_slot_end);
        self.stats.advance_to(end);
        self.stats.busy(sof, idle, total_bits);
        let latency = end - self.controllers[w].tx[0].submitted;
        let priority = if frame.is_extended() {
            (frame.raw_id() >> 24) as usize
        } else {
            32
        };
        self.stats
            .frame(kernel_can_id(&frame), frame.data(), priority, end, latency);
        self.events.push(Event::Frame {
            start: sof,
            end,
            node: NodeId(w as u16),
            frame,
            bits: total_bits,
        });
        for &t in transmitters {
            let c = &mut self.controllers[t];
            let Some(p) = c.tx.pop_front() else { continue };
            c.counters.tx_frames += 1;
            if c.config.filter.accepts(&frame) {
                c.counters.rx_own += 1;
            }
            let recovering = c.fault.tec() > 0;
            let changes = c.fault.transmit_success();
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
            if !c.on_bus() {
                // Counted for the books: a frame addressed to it that it never saw.
                if c.config.filter.accepts(&frame) {
                    c.counters.rx_missed += 1;
                }
                continue;
            }
            let recovering = c.fault.rec() > 0;
            let changes = c.fault.receive_success();
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

    fn fail(
        &mut self,
        sof: BusTime,
        w: usize,
        transmitters: &[usize],
        frame: Frame,
        at_bit: u16,
        error: BusError,
    ) {
        let bit = self.bit_ns;
        // The flag starts at the bit after the error: for an ACK error, at the ACK delimiter.
        let flag_start = sof + (u64::from(at_bit) + 1) * bit;
        let receivers: Vec<usize> = (0..self.controllers.len())
            .filter(|&i| !transmitters.contains(&i) && self.controllers[i].on_bus())
            .collect();
        let active_flaggers = transmitters
            .iter()
            .chain(&receivers)
            .filter(|&&i| self.controllers[i].fault.state() == ErrorState::Active)
            .count();
        let flag_bits = if active_flaggers >= 2 {
            2 * FLAG_BITS
        } else {
            FLAG_BITS
        };
        let flag_end = flag_start + flag_bits * bit;
        let end = flag_end + DELIMITER_BITS * bit;
        let idle = end + INTERMISSION_BITS * bit;
        // A receiver's active flag is the dominant level a passive transmitter looks for (3a).
        let dominant_seen = receivers
            .iter()
            .any(|&i| self.controllers[i].fault.state() == ErrorState::Active);
        let resume = if active_flaggers > 0 { flag_end } else { flag_start };
        self.break_recessive_runs(sof, resume);
        let total = (at_bit as u64 + 1 + flag_bits + DELIMITER_BITS + INTERMISSION_BITS) as u32;
        self.stats.advance_to(end);
        self.stats.busy(sof, idle, total);
        self.stats.error(error.name());
        for &t in transmitters {
            let c = &mut self.controllers[t];
            c.counters.tx_errors += 1;
            let mut report = TransmitError::new(match error {
                BusError::Bit => TxErrorKind::Bit,
                BusError::Ack => TxErrorKind::Ack,
            });
            report.dominant_during_passive_flag = dominant_seen;
            let changes = c.fault.transmit_error(report);
            if c.fault.state() == ErrorState::Passive {
                c.suspended_until = idle + SUSPEND_BITS * bit;
            }
            if c.fault.state() == ErrorState::BusOff {
                c.recessive_since = flag_end;
                if let Some(p) = c.tx.pop_front() {
                    c.counters.tx_aborted += 1;
                    self.events.push(Event::TxAborted {
                        node: NodeId(t as u16),
                        at: flag_start,
                        token: p.token,
                        frame: p.frame,
                    });
                }
            }
            self.note_events(NodeId(t as u16), flag_start, changes);
            self.sample(NodeId(t as u16), flag_start);
        }
        for &r in &receivers {
            let c = &mut self.controllers[r];
            c.counters.rx_errors += 1;
            let changes = c.fault.receive_error();
            self.note_events(NodeId(r as u16), flag_start, changes);
            self.sample(NodeId(r as u16), flag_start);
        }
        let tx = &self.controllers[w].fault;
        let (tec, rec) = (tx.tec(), tx.rec());
        self.events.push(Event::ErrorFrame {
            start: sof,
            flag: flag_start,
            end,
            node: NodeId(w as u16),
            frame,
            error,
            bit: at_bit,
            tec,
            rec,
        });
        // With at most 12 flag bits, rules 2 and 6 (dominant bits after a flag) never apply.
        self.idle_at = idle;
    }
}

#[cfg(test)]
mod tests;
