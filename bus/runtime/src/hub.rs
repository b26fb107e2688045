//! The virtual CAN hub: an actor that owns a [`Bus`] engine, wakes node actors when they have
//! input or a deadline, and keeps bus time in step with the runtime's clock.
//!
//! # Time
//!
//! The bus clock is exact (nanoseconds, whole bit times); tokio's timers resolve milliseconds.
//! The hub never sleeps per frame. It commits bus events in time order up to the next moment a
//! node could change the outcome — the earliest node deadline, or a delivery plus that node's
//! reaction time — then wakes the nodes due at that moment, waits for their answers (which may
//! submit frames), and goes on.
//!
//! Paced (real time, [`HubConfig::paced`]): before committing anything at bus time `t` the hub
//! waits until the wall clock has reached `t` (less an optional slack), on a timer thread of its
//! own that wakes within tens of microseconds where tokio's timers would round to milliseconds
//! (`wall_timer`). When the process was not scheduled for a while and bus time is more than
//! [`HubConfig::overrun_threshold`] behind that schedule, bus time slips: it goes on from where
//! it stopped, the overrun is counted ([`Snapshot::overruns`]) and logged (at most once a
//! second), and frames from outside ([`Submit`]) are stamped on the slipped clock
//! ([`bus::pacing`]). Unpaced (virtual time): nothing but the nodes holds the bus back, and bus time runs as
//! fast as they answer; the runtime's clock is not consulted at all, so a run costs no timers and
//! is deterministic. Runtimes made by [`runtime`] tell hubs made on their thread which to be.
//!
//! # Trace
//!
//! The engine's events become trace records ([`bus::trace::Record`]) for the sinks, through a
//! reorder window first ([`bus::trace::Reorder`], [`bus::trace::WINDOW_BITS`] bit times): the
//! engine commits a frame or error frame whole at its start, so its records can lie ahead of
//! what a node's command (a controller reset, counters written) or a fault injection makes the
//! bus say at the hub's present. Sinks get records in time order, equal times as they came, a
//! window behind the newest, and the rest when the trace ends ([`FlushTrace`], or the hub
//! stopping). A record later than the window allows is not written: it is
//! [`bus::Error::TraceOrder`], which every [`RunUntil`] answers with from then on.
//!
//! # Wakes
//!
//! A node is woken at its deadline (`poll_timeout`), and a reaction time after a frame reaches its
//! receive FIFO, after a receive overrun or after an error-state change. Transmit confirmations
//! (sent, aborted, refused) do not wake a node by themselves: they ride along with its next wake.
//! A node whose logic models its controller's registers (a firmware node,
//! [`bus::node::NodeLogic::wants_every_event`]) is woken by every event of its controller as it
//! happens instead (confirmations, counters, bus errors, lost arbitration, bus-off recovery), and
//! its commands (join or leave the bus, abort, counters, recovery, tuning) act at its wake's
//! time (`hub/commands.rs`).
//! Such a node may have several controllers on the bus ([`AttachControllers`]), each a slot of its
//! own (arbitration, acknowledgement, error counters, bus off) that wakes the node's one actor
//! with its inputs tagged by its index; the node's deadline, crashes, hangs and replacements are
//! the node's, shared by all its controllers.
//! A hung node (fault injection) is never woken, so its FIFO fills and overruns as a real one
//! would.

mod commands;

use crate::Error;
use crate::node::{Answer, Reply, Wake};
use actix::prelude::*;
use bus::Frame;
use bus::engine::{Bus, BusConfig, ControllerConfig, ControllerCounters, Event, NodeId, Rule, RuleId, Stats};
use bus::fault::ErrorState;
use bus::node::{ControllerEvent, CrashCause, Report};
use bus::pacing::{Overruns, Pace, Pacer};
use bus::time::{BusDuration, BusTime, Epoch};
use bus::trace::{Kind, Record, Reorder, Sink, Source};
use std::time::Duration;
use tokio::sync::oneshot;

/// How a hub is set up.
#[derive(Clone, Debug)]
pub struct HubConfig {
    /// The bus.
    pub bus: BusConfig,
    /// Interface name in traces.
    pub iface: String,
    /// How far bus time may run ahead of the wall clock when paced (a frame goes out this much
    /// before its time at most; none by default).
    pub slack: Duration,
    /// Keep bus time in step with the wall clock (real time); when false, run as fast as the
    /// nodes answer (virtual time). Chosen by the caller ([`HubConfig::new`]); either works on
    /// either kind of [`runtime`], see there.
    pub paced: bool,
    /// When paced: how far bus time may fall behind its schedule before it slips instead of
    /// catching up ([`bus::pacing`]; [`bus::pacing::OVERRUN_THRESHOLD`] by default).
    pub overrun_threshold: Duration,
    /// Where bus time zero lies on the wall clock for the gateway's frames ([`GetEpoch`]; a
    /// trace sink is given its epoch by whoever makes it, the same one in harvemu) ([`Epoch`]): by default the wall clock when the config is made if paced, else
    /// [`Epoch::FIXED`]. Bus time itself starts at zero either way.
    pub epoch: Epoch,
}

impl HubConfig {
    /// A 250 kbit/s bus named `harv0`, paced (real time) or not (virtual time), with the epoch
    /// that goes with that ([`default_epoch`]).
    pub fn new(paced: bool) -> Self {
        HubConfig {
            bus: BusConfig::default(),
            iface: "harv0".to_string(),
            slack: Duration::ZERO,
            paced,
            overrun_threshold: bus::pacing::OVERRUN_THRESHOLD,
            epoch: default_epoch(paced),
        }
    }
}

/// The epoch a hub takes when not given one: the wall clock now for a paced (real-time) hub, as
/// `candump -l` stamps with the wall clock; [`Epoch::FIXED`] in virtual time, so that traces are
/// reproducible.
pub fn default_epoch(paced: bool) -> Epoch {
    if paced {
        // The runtime reads the wall clock; the core only converts it.
        Epoch::from_system_time(std::time::SystemTime::now())
    } else {
        Epoch::FIXED
    }
}

struct Slot {
    name: String,
    node: Option<Recipient<Wake>>,
    /// The slot of the node's first controller: its own, but for a further controller of a
    /// node with several ([`AttachControllers`]). The node's deadline is kept there.
    first: usize,
    /// Which of the node's controllers this is.
    controller: usize,
    reaction: BusDuration,
    next_timeout: Option<BusTime>,
    pending_since: Option<BusTime>,
    events: Vec<(BusTime, ControllerEvent)>,
    /// An input that needs the logic itself (an error-state change, an overrun) is pending.
    event_wake: bool,
    /// The logic said its frames can wait for its next deadline ([`Report::frames_can_wait`]).
    frames_can_wait: bool,
    /// Frames taken from the FIFO at the reaction time, for the next wake.
    buffered: Vec<bus::engine::Received>,
    /// What became of the frames taken from the FIFO (plain counters: no cost per frame).
    handover: Handover,
    hung: bool,
    crashed: Option<CrashCause>,
    /// The logic hears of every controller event as it happens ([`Report::every_event`]).
    every_event: bool,
    /// What its logic set on its controller (register-level nodes).
    switches: commands::Switches,
}

impl Slot {
    fn due(&self) -> Option<BusTime> {
        if self.hung || self.crashed.is_some() || self.node.is_none() {
            return None;
        }
        let reaction = self.pending_since.map(|t| t + self.reaction);
        match (self.next_timeout, reaction) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }
    fn input(&mut self, at: BusTime, event: Option<ControllerEvent>, wakes: bool) {
        if let Some(e) = event {
            self.events.push((at, e));
        }
        if wakes && self.pending_since.is_none() {
            self.pending_since = Some(at);
        }
        self.event_wake |= wakes && event.is_some();
    }

    /// Forgets what the old logic left unread (a new logic starts with an empty FIFO too).
    fn clear(&mut self) {
        self.events.clear();
        self.handover.dropped_at_replace += self.buffered.len() as u64;
        self.buffered.clear();
        self.event_wake = false;
        self.frames_can_wait = false;
        self.pending_since = None;
    }
}

/// What became of the frames the hub took out of one node's receive FIFO. Every frame taken
/// (the controller's `rx_read`) is in exactly one of these:
/// `rx_read = handled + crashed + dropped_at_replace + held + in_flight`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Handover {
    /// Handed to the logic's `handle_frame`.
    pub handled: u64,
    /// In wakes whose logic crashed (or whose actor was gone) before handling them.
    pub crashed: u64,
    /// Held for the logic's next deadline, and dropped when a new logic took over (restart,
    /// power cycle).
    pub dropped_at_replace: u64,
    /// Held for the logic's next deadline now.
    pub held: u64,
    /// In a wake not answered yet (none while the hub is paused).
    pub in_flight: u64,
}

/// The hub actor.
pub struct Hub {
    bus: Bus,
    iface: String,
    epoch: Epoch,
    /// When bus time may be committed, and the overruns (paced hubs only).
    pacer: Pacer,
    paced: bool,
    slots: Vec<Slot>,
    start: Option<tokio::time::Instant>,
    now: BusTime,
    /// Answers still awaited from the present wake round.
    waiting: usize,
    round: u64,
    me: Option<std::sync::Arc<Recipient<Answer>>>,
    crashed_in_round: bool,
    /// A node asked in this round for the run to stop here ([`bus::node::NodeLogic::stop_here`]).
    stop_in_round: bool,
    paused: bool,
    timer: Option<SpawnHandle>,
    /// Paced hubs wait on a wall-clock timer thread (`wall_timer`), with the wall-clock start.
    wall: Option<(crate::wall_timer::WallTimer, std::time::Instant)>,
    /// The id of the deadline the wall timer is armed for; others are stale.
    armed: u64,
    stop_at: Option<BusTime>,
    on_stop: Vec<oneshot::Sender<Result<BusTime, bus::Error>>>,
    /// Where the trace goes; a sink that failed is dropped.
    sinks: Vec<Box<dyn Sink>>,
    /// The trace's records on their way to the sinks, put in time order: the bus commits whole
    /// frames ahead of time, and what nodes' commands make it say comes at their present, which
    /// may be earlier ([`Reorder`]). Each record is its source (the bus, or a controller) and
    /// what it holds; names are looked up as it goes out.
    order: Reorder<(Option<NodeId>, Kind)>,
    /// A record came too late to be put in order: every run answers with this from then on.
    order_error: Option<bus::Error>,
    /// [`FlushTrace`] asked for the end of the trace: the next stop hands every record on.
    trace_ends: bool,
    /// The first error of a sink.
    trace_error: Option<String>,
    scratch: Vec<Event>,
    wakes: u64,
    observers: Vec<Observer>,
    /// How many slots hear of every event (register-level nodes): none, usually, and then
    /// nothing is spent on them.
    register_level: usize,
}

/// False when a sink failed: it is given nothing more, and the first error is kept.
fn kept(result: std::io::Result<()>, error: &mut Option<String>) -> bool {
    match result {
        Ok(()) => true,
        Err(e) => {
            error.get_or_insert_with(|| e.to_string());
            false
        }
    }
}

/// A frame as an observer of the bus sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Observed {
    /// End of frame.
    pub at: BusTime,
    /// Transmitter.
    pub node: NodeId,
    /// The frame.
    pub frame: Frame,
}

struct Observer {
    tx: tokio::sync::mpsc::Sender<Observed>,
    dropped: u64,
}

impl Hub {
    /// A hub with no nodes; each of `sinks` receives the trace's records ([`bus::trace`]).
    pub fn new(config: HubConfig, sinks: Vec<Box<dyn Sink>>) -> Result<Hub, Error> {
        let bus = Bus::new(config.bus)?;
        Ok(Hub {
            order: Reorder::for_bit_time(bus.bit_time()),
            order_error: None,
            trace_ends: false,
            bus,
            iface: config.iface,
            epoch: config.epoch,
            pacer: Pacer::new(config.slack, config.overrun_threshold),
            paced: config.paced,
            slots: Vec::new(),
            start: None,
            now: BusTime::ZERO,
            waiting: 0,
            round: 0,
            me: None,
            crashed_in_round: false,
            stop_in_round: false,
            paused: true,
            timer: None,
            wall: None,
            armed: 0,
            stop_at: None,
            on_stop: Vec::new(),
            sinks,
            trace_error: None,
            scratch: Vec::with_capacity(64),
            wakes: 0,
            observers: Vec::new(),
            register_level: 0,
        })
    }

    /// Nanoseconds since the hub started: on the wall clock when it has its wall timer (so a
    /// paced hub keeps to real time even on a paused-clock runtime), else on the runtime's clock.
    fn clock(&self) -> u64 {
        let elapsed = match &self.wall {
            Some((_, start)) => start.elapsed(),
            None => self.start.map_or(Duration::ZERO, |s| s.elapsed()),
        };
        u64::try_from(elapsed.as_nanos()).unwrap_or(u64::MAX)
    }

    /// True when the runtime's clock allows committing at `t`. A paced hub that finds `t`
    /// overdue by more than the overrun threshold lets bus time slip ([`bus::pacing`]).
    fn reached(&mut self, t: BusTime) -> bool {
        if !self.paced {
            return true;
        }
        let wall = self.clock();
        match self.pacer.check(wall, t) {
            Pace::Wait(_) => false,
            Pace::Go { slipped: None } => true,
            Pace::Go { slipped: Some(late) } => {
                if let Some(n) = self.pacer.log_due(wall) {
                    let o = self.pacer.overruns();
                    tracing::warn!(
                        late_ms = late / 1_000_000,
                        overruns = n,
                        behind_ms = o.slipped_ns / 1_000_000,
                        "real-time overrun: harvemu was not scheduled in time; bus time slips instead of bursting"
                    );
                }
                true
            }
        }
    }

    /// The bus time of the present, for a frame from outside: the wall clock less the slips. A
    /// stall not yet noticed by the hub is noticed first, so the frame does not land in the
    /// future of bus time it stalled at.
    fn present(&mut self) -> BusTime {
        if !self.paced {
            return BusTime::from_nanos(self.clock());
        }
        let frontier = if self.waiting > 0 {
            Some(self.now)
        } else {
            let stop = self.stop_at.unwrap_or(BusTime::NEVER);
            let next = self.bus.next_event().map_or(stop, |(t, _)| t.min(stop));
            Some(self.next_due().map_or(next, |d| d.min(next))).filter(|&t| t < BusTime::NEVER)
        };
        if let Some(t) = frontier.filter(|_| !self.paused) {
            self.reached(t);
        }
        self.pacer.bus_time(self.clock())
    }

    fn arm(&mut self, t: BusTime, ctx: &mut Context<Self>) {
        if let Some((timer, start)) = &self.wall {
            self.armed += 1;
            let at = *start + Duration::from_nanos(self.pacer.due(t));
            if timer.set(self.armed, at) {
                return;
            }
        }
        let wait = self.pacer.due(t).saturating_sub(self.clock());
        self.timer = Some(ctx.run_later(Duration::from_nanos(wait.max(1)), |hub, ctx| {
            hub.timer = None;
            hub.pump(ctx);
        }));
    }

    fn next_due(&self) -> Option<BusTime> {
        self.slots.iter().filter_map(Slot::due).min()
    }

    /// Runs the bus as far as it can without hearing from a node.
    fn pump(&mut self, ctx: &mut Context<Self>) {
        if self.waiting > 0 || self.paused {
            return;
        }
        if let Some(h) = self.timer.take() {
            ctx.cancel_future(h);
        }
        // A wall-timer deadline set before is stale from here on.
        self.armed += 1;
        // What the nodes' commands made the bus say (an abort's answer, counters written) goes
        // out before the bus moves on: nothing else would carry it to its node.
        if self.bus.has_events() {
            self.dispatch();
        }
        // Nodes become due only by being woken (recomputed then) or by new inputs (which
        // `dispatch` reports), so the earliest due time is kept up to date, not rescanned.
        let mut due = self.next_due();
        loop {
            let stop = self.stop_at.unwrap_or(BusTime::NEVER);
            let limit = due.map_or(stop, |d| d.min(stop));
            if let Some((t, next)) = self.bus.next_event().filter(|&(t, _)| t < limit) {
                if !self.reached(t) {
                    return self.arm(t, ctx);
                }
                self.bus.commit(next);
                if let Some(d) = self.dispatch() {
                    due = Some(due.map_or(d, |x| x.min(d)));
                }
                continue;
            }
            match due {
                Some(d) if d < stop => {
                    if !self.reached(d) {
                        return self.arm(d, ctx);
                    }
                    if self.wake(d, ctx) {
                        return;
                    }
                    due = self.next_due();
                }
                _ if stop < BusTime::NEVER => {
                    if !self.reached(stop) {
                        return self.arm(stop, ctx);
                    }
                    return self.finish(stop);
                }
                _ => return,
            }
        }
    }

    /// Routes the engine's events to traces and to the nodes' pending inputs. Returns the
    /// earliest due time among the nodes that got inputs.
    fn dispatch(&mut self) -> Option<BusTime> {
        let mut due: Option<BusTime> = None;
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.extend(self.bus.take_events());
        for event in scratch.drain(..) {
            // Into the reorder window; names are looked up as records go out (`hand_over`).
            if !self.sinks.is_empty()
                && let Some(record) = Record::of_event(&self.iface, |_| "", &event)
            {
                let node = match record.source {
                    Source::Bus => None,
                    Source::Controller { node, .. } => Some(node),
                };
                if let Err(e) = self.order.push(record.at, (node, record.kind)) {
                    tracing::error!(error = %e, "a trace record out of order");
                    self.order_error.get_or_insert(e);
                }
            }
            if let Event::Frame { end, node, frame, .. } = event {
                // A slow observer loses frames (counted); it never holds up the bus.
                self.observers
                    .retain_mut(|o| match o.tx.try_send(Observed { at: end, node, frame }) {
                        Ok(()) => true,
                        Err(tokio::sync::mpsc::error::TrySendError::Full(_)) => {
                            o.dropped += 1;
                            true
                        }
                        Err(tokio::sync::mpsc::error::TrySendError::Closed(_)) => false,
                    });
            }
            if self.register_level > 0 {
                self.counters_of(&event);
                // Counters wake register-level nodes (at most a handful): keep `due` whole.
                if let Some(d) = self
                    .slots
                    .iter()
                    .filter(|s| s.every_event)
                    .filter_map(Slot::due)
                    .min()
                {
                    due = Some(due.map_or(d, |x| x.min(d)));
                }
            }
            // No register-level node (the usual case): no slot lookup on the per-frame path.
            let every = |n: NodeId| {
                self.register_level > 0 && self.slots.get(n.index()).is_some_and(|s| s.every_event)
            };
            let (node, at, input, wakes) = match event {
                Event::Delivered { node, at } => (node, at, None, true),
                Event::Overrun { node, at } => (node, at, Some(ControllerEvent::Overrun), true),
                Event::Woken { node, at } => (node, at, Some(ControllerEvent::Woken), true),
                Event::State { node, at, to, .. } => (node, at, Some(ControllerEvent::State(to)), true),
                Event::TxDone { node, at, frame, .. } => {
                    (node, at, Some(ControllerEvent::Sent(frame)), every(node))
                }
                Event::TxAborted { node, at, frame, .. } => {
                    (node, at, Some(ControllerEvent::Aborted(frame)), every(node))
                }
                Event::BusError {
                    node,
                    at,
                    error,
                    transmitting,
                    location,
                    ..
                } if every(node) => {
                    let e = ControllerEvent::BusError {
                        error,
                        transmitting,
                        location,
                    };
                    (node, at, Some(e), true)
                }
                Event::ArbitrationLost { node, at, bit } if every(node) => {
                    (node, at, Some(ControllerEvent::ArbitrationLost(bit)), true)
                }
                Event::RecoveryProgress { node, at, sequences } if every(node) => {
                    (node, at, Some(ControllerEvent::RecoveryProgress(sequences)), true)
                }
                _ => continue,
            };
            if let Some(slot) = self.slots.get_mut(node.index()) {
                slot.input(at, input, wakes);
                if let Some(d) = slot.due() {
                    due = Some(due.map_or(d, |x| x.min(d)));
                }
            }
        }
        self.scratch = scratch;
        self.hand_over(false);
        due
    }

    /// Hands the trace's records that are due to the sinks, in time order: those a reorder
    /// window older than the newest, or every one when `all` (the end of the trace).
    fn hand_over(&mut self, all: bool) {
        if self.sinks.is_empty() {
            return;
        }
        let controllers = self.bus.controllers();
        let name = |n: NodeId| {
            controllers
                .get(n.index())
                .map_or("?", |c| c.config().name.as_str())
        };
        loop {
            let next = if all {
                self.order.pop_any()
            } else {
                self.order.pop()
            };
            let Some((at, (node, kind))) = next else {
                return;
            };
            let source = match node {
                None => Source::Bus,
                Some(node) => Source::Controller {
                    node,
                    name: name(node),
                },
            };
            let record = Record {
                at,
                bus: &self.iface,
                source,
                kind,
            };
            let error = &mut self.trace_error;
            self.sinks.retain_mut(|s| kept(s.record(&record), error));
        }
    }

    /// Wakes every node due at `at`; the bus waits until all of them have answered. Returns false
    /// when no node needed its logic woken (frames that can wait were only taken from their
    /// FIFOs): the bus goes on at once.
    fn wake(&mut self, at: BusTime, ctx: &mut Context<Self>) -> bool {
        self.now = at;
        self.round += 1;
        self.crashed_in_round = false;
        self.stop_in_round = false;
        let me = self
            .me
            .get_or_insert_with(|| std::sync::Arc::new(ctx.address().recipient()))
            .clone();
        for i in 0..self.slots.len() {
            if self.slots[i].due() != Some(at) {
                continue;
            }
            // Every slot has its controller (attached together): an error here is a bug, told.
            let drained = match self.bus.drain_rx(NodeId(i as u16), at) {
                Ok((frames, _overrun)) => frames,
                Err(e) => {
                    tracing::error!(node = %self.slots[i].name, error = %e, "receive FIFO not read");
                    Vec::new()
                }
            };
            let still_arriving = self.bus.rx_front(NodeId(i as u16));
            let slot = &mut self.slots[i];
            // A frame still on the wire is the next input, from its end.
            slot.pending_since = still_arriving;
            let timeout_due = slot.next_timeout.is_some_and(|t| t <= at);
            if slot.frames_can_wait && !timeout_due && !slot.event_wake {
                // What the node's receive interrupt does: the frames leave the FIFO now (so it
                // does not overrun), and the logic gets them, in order, at its next deadline.
                slot.buffered.extend(drained);
                continue;
            }
            let frames = if slot.buffered.is_empty() {
                drained
            } else {
                let mut frames = std::mem::take(&mut slot.buffered);
                frames.extend(drained);
                frames
            };
            slot.next_timeout = None;
            slot.event_wake = false;
            let events = std::mem::take(&mut slot.events);
            if let Some(node) = &slot.node {
                self.waiting += 1;
                self.wakes += 1;
                slot.handover.in_flight += frames.len() as u64;
                // A node whose actor is gone answers at once: its reply is dropped with the wake.
                node.do_send(Wake {
                    now: at,
                    controller: slot.controller,
                    frames,
                    events,
                    reply: Reply::new(me.clone(), i, self.round),
                });
            }
        }
        self.waiting > 0
    }

    /// The slots of the node slot `i` belongs to: its controllers, first to last.
    fn group(&self, i: usize) -> Vec<usize> {
        let first = self.slots[i].first;
        (first..self.slots.len())
            .filter(|&j| self.slots[j].first == first)
            .collect()
    }

    /// Takes a node's answer; true when the node crashed.
    fn answer(&mut self, i: usize, report: Report) -> bool {
        let now = self.now;
        let h = &mut self.slots[i].handover;
        let sent = std::mem::take(&mut h.in_flight);
        let handled = report.frames_handled.min(sent);
        h.handled += handled;
        h.crashed += sent - handled;
        let first = self.slots[i].first;
        if let Some(message) = report.crashed {
            if self.slots[i].crashed.is_none() {
                if message == CrashCause::Injected {
                    // Asked for by a scenario: expected, so not a warning on the operator's screen.
                    tracing::info!(node = %self.slots[i].name, %message, "node crashed");
                } else {
                    tracing::warn!(node = %self.slots[i].name, %message, "node crashed");
                }
            }
            // One logic behind all of a node's controllers: they go down together.
            for j in self.group(i) {
                self.slots[j].crashed = Some(message.clone());
            }
            return true;
        }
        if report.every_event != self.slots[i].every_event {
            for j in self.group(i) {
                self.slots[j].every_event = report.every_event;
            }
            self.register_level = self.slots.iter().filter(|s| s.every_event).count();
            self.bus.report_arbitration(self.register_level > 0);
        }
        for (k, command) in report.commands {
            let target = if k == self.slots[i].controller {
                Some(i)
            } else {
                self.group(i).into_iter().find(|&j| self.slots[j].controller == k)
            };
            match target {
                Some(j) => self.apply(j, command, now),
                None => tracing::error!(
                    node = %self.slots[i].name,
                    controller = k,
                    "a command for a controller the node does not have"
                ),
            }
        }
        for frame in report.transmit {
            self.submit_for(first, frame, now, false);
        }
        // A deadline the logic left in the past would wake it at the same instant for ever.
        self.slots[first].next_timeout = report.next_timeout.map(|t| {
            if t <= now {
                now + BusDuration::from_millis(1)
            } else {
                t
            }
        });
        if report.frames_can_wait != self.slots[i].frames_can_wait {
            for j in self.group(i) {
                self.slots[j].frames_can_wait = report.frames_can_wait;
            }
        }
        false
    }

    /// Queues a frame of slot `i`'s logic; a full queue is told back as refused.
    fn submit_for(&mut self, i: usize, frame: Frame, now: BusTime, single_shot: bool) {
        match self.bus.submit_with(NodeId(i as u16), frame, now, single_shot) {
            Ok(Some(_)) => {}
            Ok(None) => self.slots[i].input(now, Some(ControllerEvent::Refused(frame)), false),
            Err(e) => tracing::error!(error = %e, "submit failed"),
        }
    }

    /// Tells register-level nodes of the counters an event changed: the values the event
    /// carries where it has them, else the controller's as the event leaves them (a frame
    /// that went through, a reset).
    fn counters_of(&mut self, event: &Event) {
        match *event {
            Event::BusError {
                node, at, tec, rec, ..
            }
            | Event::State {
                node, at, tec, rec, ..
            }
            | Event::Warning {
                node, at, tec, rec, ..
            } => self.counters_to(node.index(), at, tec, rec),
            Event::TxDone { node, at, .. } | Event::Restarted { node, at } => {
                self.counters_now(node.index(), at)
            }
            Event::Frame { end, .. } => {
                for i in 0..self.slots.len() {
                    if self.slots[i].every_event {
                        self.counters_now(i, end);
                    }
                }
            }
            _ => {}
        }
    }

    fn flush_sinks(&mut self) {
        let error = &mut self.trace_error;
        self.sinks.retain_mut(|s| kept(s.flush(), error));
    }

    fn finish(&mut self, at: BusTime) {
        self.now = self.now.max(at);
        self.bus.advance_stats(at);
        // The end of the trace; or a run about to fail for a record out of order, which should
        // leave everything else in its trace.
        if std::mem::take(&mut self.trace_ends) || self.order_error.is_some() {
            self.hand_over(true);
        }
        self.flush_sinks();
        self.paused = true;
        self.stop_at = None;
        for tx in self.on_stop.drain(..) {
            let _ = tx.send(self.order_error.clone().map_or(Ok(at), Err));
        }
    }
}

impl Handler<Answer> for Hub {
    type Result = ();
    fn handle(&mut self, msg: Answer, ctx: &mut Context<Self>) {
        if msg.round != self.round || self.waiting == 0 || msg.slot >= self.slots.len() {
            return;
        }
        self.stop_in_round |= msg.report.stop;
        self.crashed_in_round |= self.answer(msg.slot, msg.report);
        self.waiting -= 1;
        if self.waiting > 0 {
            return;
        }
        if (self.crashed_in_round || self.stop_in_round) && self.stop_at.is_some() {
            // The run stops here so that whoever supervises (or waits for a frame) hears of it
            // at once.
            self.finish(self.now);
        } else {
            self.pump(ctx);
        }
    }
}

impl Actor for Hub {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        self.start = Some(tokio::time::Instant::now());
        if self.paced {
            let hub = ctx.address();
            // Without the thread (it could not be started), tokio's timers pace the bus.
            self.wall = crate::wall_timer::WallTimer::start(move |id| hub.do_send(WallTick(id)))
                .ok()
                .map(|timer| (timer, std::time::Instant::now()));
        }
    }

    fn stopped(&mut self, _ctx: &mut Context<Self>) {
        self.hand_over(true);
        self.flush_sinks();
    }
}

impl Drop for Hub {
    /// A hub dropped without being stopped (its system went away first) still hands on the
    /// records it held.
    fn drop(&mut self) {
        if !self.order.is_empty() {
            self.hand_over(true);
            self.flush_sinks();
        }
    }
}

/// The wall timer's deadline `0` has passed.
#[derive(Message)]
#[rtype(result = "()")]
struct WallTick(u64);

impl Handler<WallTick> for Hub {
    type Result = ();
    fn handle(&mut self, WallTick(id): WallTick, ctx: &mut Context<Self>) {
        if id == self.armed {
            self.pump(ctx);
        }
    }
}

/// Attaches a node: a controller on the bus, and the actor that runs its logic (none for a
/// node driven from outside, e.g. a gateway that only submits).
#[derive(Message)]
#[rtype(result = "NodeId")]
pub struct Attach {
    /// The controller.
    pub controller: ControllerConfig,
    /// The node's actor.
    pub node: Option<Recipient<Wake>>,
    /// How long after an input the node acts on it.
    pub reaction: Duration,
}

impl Handler<Attach> for Hub {
    type Result = MessageResult<Attach>;
    fn handle(&mut self, msg: Attach, ctx: &mut Context<Self>) -> Self::Result {
        let id = self.attach(vec![msg.controller], msg.node, msg.reaction)[0];
        self.pump(ctx);
        MessageResult(id)
    }
}

/// Attaches a node with several controllers on the bus (a firmware node with several CAN
/// chips), as [`Attach`] attaches a node with one: each controller has a place of its own on the
/// bus (arbitration, acknowledgement, error counters, bus off) and wakes the node's actor with
/// its inputs tagged by its index in `controllers`, the index the node's commands for it carry.
/// The node's deadline, crash, hang and replacement are shared by all its controllers. Answers
/// with their ids, in order; the first is the node's.
#[derive(Message)]
#[rtype(result = "Result<Vec<NodeId>, Error>")]
pub struct AttachControllers {
    /// The controllers, at least one.
    pub controllers: Vec<ControllerConfig>,
    /// The node's actor.
    pub node: Option<Recipient<Wake>>,
    /// How long after an input the node acts on it.
    pub reaction: Duration,
}

impl Handler<AttachControllers> for Hub {
    type Result = Result<Vec<NodeId>, Error>;
    fn handle(&mut self, msg: AttachControllers, ctx: &mut Context<Self>) -> Self::Result {
        if msg.controllers.is_empty() {
            return Err(Error::NoControllers);
        }
        let ids = self.attach(msg.controllers, msg.node, msg.reaction);
        self.pump(ctx);
        Ok(ids)
    }
}

impl Hub {
    /// Attaches the controllers of one node, all at once so that no wake comes between them.
    fn attach(
        &mut self,
        controllers: Vec<ControllerConfig>,
        node: Option<Recipient<Wake>>,
        reaction: Duration,
    ) -> Vec<NodeId> {
        let now = self.now.max(self.bus.committed());
        let first = self.slots.len();
        let mut ids = Vec::with_capacity(controllers.len());
        for (k, controller) in controllers.into_iter().enumerate() {
            ids.push(self.bus.attach(controller.clone()));
            self.slots.push(Slot {
                name: controller.name,
                node: node.clone(),
                first,
                controller: k,
                reaction: BusDuration::from_std(reaction),
                // A first wake tells the node the time and collects its first deadline (which
                // the first controller's slot keeps).
                next_timeout: (k == 0).then_some(now),
                pending_since: None,
                events: Vec::new(),
                event_wake: false,
                frames_can_wait: false,
                buffered: Vec::new(),
                handover: Handover::default(),
                hung: false,
                crashed: None,
                every_event: false,
                switches: commands::Switches::default(),
            });
        }
        ids
    }
}

/// Runs the bus until bus time `0` and answers with the time reached: that time, or the moment a
/// node crashed or asked to stop ([`bus::node::NodeLogic::stop_here`]), if one did on the way
/// (so that a supervisor, or a program waiting for a frame, can act at once). Once a trace
/// record has come too late to be written in time order ([`bus::Error::TraceOrder`], a bug),
/// every run answers with that error.
#[derive(Message)]
#[rtype(result = "Result<BusTime, Error>")]
pub struct RunUntil(pub BusTime);

impl Handler<RunUntil> for Hub {
    type Result = ResponseFuture<Result<BusTime, Error>>;
    fn handle(&mut self, msg: RunUntil, ctx: &mut Context<Self>) -> Self::Result {
        let (tx, rx) = oneshot::channel();
        self.on_stop.push(tx);
        self.stop_at = Some(self.stop_at.map_or(msg.0, |s| s.min(msg.0)));
        self.paused = false;
        self.pump(ctx);
        Box::pin(async move { rx.await.map_err(|_| Error::HubStopped)?.map_err(Error::from) })
    }
}

/// Ends the trace: the bus stops at the present bus time (a run in progress ends there, and its
/// [`RunUntil`] answers with it), every record still held for time order goes to the sinks,
/// and every sink is flushed. Answers with that time. A caller sends it before it reads the end
/// of the trace: a file to finish, a count, a snapshot's `trace_error`. A bus run on after it
/// must not give a record older than those (the reorder window is empty then): that is the
/// error of [`RunUntil`].
#[derive(Message)]
#[rtype(result = "Result<BusTime, Error>")]
pub struct FlushTrace;

impl Handler<FlushTrace> for Hub {
    type Result = ResponseFuture<Result<BusTime, Error>>;
    fn handle(&mut self, _: FlushTrace, ctx: &mut Context<Self>) -> Self::Result {
        // Stopping at the present hands on and flushes (`finish`), once the nodes woken, if any,
        // have answered.
        self.trace_ends = true;
        let present = self.now.max(self.bus.committed());
        self.handle(RunUntil(present), ctx)
    }
}

/// Fault-injection and test hooks.
#[derive(Message, Clone, Debug)]
#[rtype(result = "Result<Option<RuleId>, Error>")]
pub enum Control {
    /// Make a node acknowledge frames or not.
    SetAck(NodeId, bool),
    /// Disconnect or reconnect a node.
    SetConnected(NodeId, bool),
    /// Stop waking a node (it hangs: alive, silent, not draining its FIFO), or wake it again.
    SetHung(NodeId, bool),
    /// Reset a node's controller.
    Reset(NodeId),
    /// Install a corruption rule.
    AddRule(Rule),
    /// Remove one.
    RemoveRule(RuleId),
    /// Wake a node now, so that it reports its next deadline: a logic driven from outside
    /// ([`bus::node::NodeLogic`] state changed between wakes) says when it is next due.
    Poke(NodeId),
}

impl Handler<Control> for Hub {
    type Result = Result<Option<RuleId>, Error>;
    fn handle(&mut self, msg: Control, ctx: &mut Context<Self>) -> Self::Result {
        let now = self.now.max(self.bus.committed());
        let result = match msg {
            Control::SetAck(n, on) => self.bus.set_ack(n, on).map(|_| None).map_err(Error::from),
            Control::SetConnected(n, on) => self
                .bus
                .set_connected(n, on, now)
                .map(|_| None)
                .map_err(Error::from),
            // A node hangs as a whole, all its controllers.
            Control::SetHung(n, on) if n.index() < self.slots.len() => {
                for j in self.group(n.index()) {
                    let slot = &mut self.slots[j];
                    slot.hung = on;
                    if !on && slot.first == j {
                        slot.next_timeout = Some(now);
                    }
                }
                Ok(None)
            }
            Control::SetHung(n, _) => Err(Error::NoNode(n.0)),
            Control::Reset(n) => {
                let r = self.bus.reset_node(n, now).map(|_| None).map_err(Error::from);
                self.dispatch();
                r
            }
            Control::AddRule(rule) => Ok(Some(self.bus.injector_mut().add(rule))),
            Control::RemoveRule(id) => {
                self.bus.injector_mut().remove(id);
                Ok(None)
            }
            Control::Poke(n) => match self.slots.get_mut(n.index()) {
                Some(slot) => {
                    slot.next_timeout = Some(slot.next_timeout.map_or(now, |t| t.min(now)));
                    Ok(None)
                }
                None => Err(Error::NoNode(n.0)),
            },
        };
        self.pump(ctx);
        result
    }
}

/// Puts a new actor behind a node whose logic crashed (or is being restarted): its controllers
/// (all of them, for a node with several) are reset, and the new logic is woken at once.
#[derive(Message)]
#[rtype(result = "Result<(), Error>")]
pub struct Replace {
    /// The node (any of its controllers).
    pub node: NodeId,
    /// Its new actor.
    pub actor: Recipient<Wake>,
}

impl Handler<Replace> for Hub {
    type Result = Result<(), Error>;
    fn handle(&mut self, msg: Replace, ctx: &mut Context<Self>) -> Self::Result {
        let now = self.now.max(self.bus.committed());
        if msg.node.index() >= self.slots.len() {
            return Err(Error::NoNode(msg.node.0));
        }
        for j in self.group(msg.node.index()) {
            self.bus.reset_node(NodeId(j as u16), now)?;
            let slot = &mut self.slots[j];
            slot.node = Some(msg.actor.clone());
            slot.crashed = None;
            slot.hung = false;
            slot.clear();
            slot.next_timeout = (slot.first == j).then_some(now);
        }
        self.dispatch();
        self.pump(ctx);
        Ok(())
    }
}

/// Hands a frame to a node's controller from outside (a gateway, a replay), at the present.
#[derive(Message)]
#[rtype(result = "Result<bool, Error>")]
pub struct Submit {
    /// The node whose controller sends it.
    pub node: NodeId,
    /// The frame.
    pub frame: Frame,
}

impl Handler<Submit> for Hub {
    type Result = Result<bool, Error>;
    fn handle(&mut self, msg: Submit, ctx: &mut Context<Self>) -> Self::Result {
        // Not before the hub's present: what the nodes' commands did there is in the trace.
        let at = self.present().max(self.bus.committed()).max(self.now);
        let queued = self.bus.submit(msg.node, msg.frame, at)?.is_some();
        self.pump(ctx);
        Ok(queued)
    }
}

/// Hands a frame to a node's controller from outside at a given bus time (a replayed trace): the
/// sender runs the hub to `at` first, so the frame keeps its place in time whatever the clock; a
/// time already committed becomes the present and counts as a late submission.
#[derive(Message)]
#[rtype(result = "Result<bool, Error>")]
pub struct SubmitAt {
    /// The node whose controller sends it.
    pub node: NodeId,
    /// The frame.
    pub frame: Frame,
    /// When the node hands it over.
    pub at: BusTime,
}

impl Handler<SubmitAt> for Hub {
    type Result = Result<bool, Error>;
    fn handle(&mut self, msg: SubmitAt, ctx: &mut Context<Self>) -> Self::Result {
        let queued = self.bus.submit(msg.node, msg.frame, msg.at)?.is_some();
        self.pump(ctx);
        Ok(queued)
    }
}

/// One node as the hub sees it.
#[derive(Clone, Debug, serde::Serialize)]
pub struct NodeSnapshot {
    /// Name.
    pub name: String,
    /// Transmit error counter.
    pub tec: u16,
    /// Receive error counter.
    pub rec: u16,
    /// Error state.
    pub state: ErrorState,
    /// Controller counters.
    pub counters: ControllerCounters,
    /// What became of the frames taken from its receive FIFO.
    pub handover: Handover,
    /// Frames in its receive FIFO now.
    pub rx_queued: u64,
    /// Hung by fault injection.
    pub hung: bool,
    /// Why it crashed, if it did.
    pub crashed: Option<CrashCause>,
}

/// The hub's state for reports and tests.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Snapshot {
    /// Bus time of the last committed event or wake.
    pub now: BusTime,
    /// Statistics.
    pub stats: Stats,
    /// Nodes in `NodeId` order.
    pub nodes: Vec<NodeSnapshot>,
    /// Node wakes so far.
    pub wakes: u64,
    /// Submissions that arrived after bus time had moved past them.
    pub late_submissions: u64,
    /// Real-time overruns: how often, and how far, bus time slipped behind the wall clock
    /// (always zero in virtual time).
    pub overruns: Overruns,
    /// Why the trace stopped, if writing it failed.
    pub trace_error: Option<String>,
}

/// Registers an observer of every frame on the bus (gateways, displays). The channel is
/// bounded: frames that do not fit are dropped for that observer and counted.
#[derive(Message)]
#[rtype(result = "()")]
pub struct Subscribe(pub tokio::sync::mpsc::Sender<Observed>);

impl Handler<Subscribe> for Hub {
    type Result = ();
    fn handle(&mut self, Subscribe(tx): Subscribe, _: &mut Context<Self>) {
        self.observers.push(Observer { tx, dropped: 0 });
    }
}

/// Asks for the hub's [`Epoch`]: what a bus time is written as ([`Epoch::stamp`]).
#[derive(Message)]
#[rtype(result = "Epoch")]
pub struct GetEpoch;

impl Handler<GetEpoch> for Hub {
    type Result = MessageResult<GetEpoch>;
    fn handle(&mut self, _: GetEpoch, _: &mut Context<Self>) -> Self::Result {
        MessageResult(self.epoch)
    }
}

/// Asks which nodes have crashed, and why: cheap enough to ask often (a [`Snapshot`] copies the
/// statistics).
#[derive(Message)]
#[rtype(result = "Vec<(NodeId, CrashCause)>")]
pub struct GetCrashed;

impl Handler<GetCrashed> for Hub {
    type Result = MessageResult<GetCrashed>;
    fn handle(&mut self, _: GetCrashed, _: &mut Context<Self>) -> Self::Result {
        MessageResult(
            self.slots
                .iter()
                .enumerate()
                .filter_map(|(i, s)| s.crashed.clone().map(|why| (NodeId(i as u16), why)))
                .collect(),
        )
    }
}

/// Asks for every node's (TEC, REC), by node index: cheap enough to ask once per bus second
/// (the statistics keep counters only at errors, so a sampler sees them decay with this).
#[derive(Message)]
#[rtype(result = "Vec<(u16, u16)>")]
pub struct GetErrorCounters;

impl Handler<GetErrorCounters> for Hub {
    type Result = MessageResult<GetErrorCounters>;
    fn handle(&mut self, _: GetErrorCounters, _: &mut Context<Self>) -> Self::Result {
        MessageResult(
            self.bus
                .controllers()
                .iter()
                .map(|c| (c.fault().tec(), c.fault().rec()))
                .collect(),
        )
    }
}

/// Asks for a [`Snapshot`].
#[derive(Message)]
#[rtype(result = "Snapshot")]
pub struct GetSnapshot;

impl Handler<GetSnapshot> for Hub {
    type Result = MessageResult<GetSnapshot>;
    fn handle(&mut self, _: GetSnapshot, _: &mut Context<Self>) -> Self::Result {
        let nodes = self
            .slots
            .iter()
            .zip(self.bus.controllers())
            .map(|(s, c)| NodeSnapshot {
                name: s.name.clone(),
                tec: c.fault().tec(),
                rec: c.fault().rec(),
                state: c.fault().state(),
                counters: *c.counters(),
                handover: Handover {
                    held: s.buffered.len() as u64,
                    ..s.handover
                },
                rx_queued: c.rx_len() as u64,
                hung: s.hung,
                crashed: s.crashed.clone(),
            })
            .collect();
        MessageResult(Snapshot {
            now: self.now.max(self.bus.committed()),
            stats: self.bus.stats().clone(),
            nodes,
            wakes: self.wakes,
            late_submissions: self.bus.late_submissions(),
            overruns: self.pacer.overruns(),
            trace_error: self.trace_error.clone(),
        })
    }
}

/// A tokio runtime for the hub: with paused time (`virtual_time`: deterministic, as fast as the
/// CPU allows) or the normal clock (real time). It only builds the runtime: whether a hub is
/// paced is its [`HubConfig::paced`], which the caller sets to match. Wrap it with
/// `actix::System::with_tokio_rt(|| runtime(true).expect(...))`.
///
/// The other combinations work too. An unpaced hub on a normal-clock runtime runs as fast as the
/// nodes answer, as on a paused one. A paced hub on a paused-clock runtime keeps to the wall
/// clock all the same, because it waits on its own wall-timer thread, never on tokio's timers;
/// only the bus time it gives frames from outside (a gateway, a SocketCAN interface) follows the
/// paused clock, so such a hub must not take frames from outside.
pub fn runtime(virtual_time: bool) -> std::io::Result<tokio::runtime::Runtime> {
    let mut builder = tokio::runtime::Builder::new_current_thread();
    builder.enable_all();
    if virtual_time {
        builder.start_paused(true);
    }
    builder.build()
}
