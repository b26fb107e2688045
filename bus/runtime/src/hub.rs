//! The virtual CAN hub: an actor that drives a [`Scheduler`] (the engine and the nodes' wakes,
//! sans-IO, in `bus::schedule`), carries its wakes to the node actors and their answers back, and
//! keeps bus time in step with the runtime's clock.
//!
//! Everything about when what happens is the scheduler's, documented there: how bus time is
//! committed between wakes, reaction times, buffering, register-level nodes' wakes, crashes,
//! hangs and the trace's time order. The hub adds what needs a runtime:
//!
//! - Paced (real time, [`HubConfig::paced`]): when the scheduler waits for the wall clock, the hub
//!   sleeps on a timer thread of its own that wakes within tens of microseconds where tokio's
//!   timers would round to milliseconds (`wall_timer`), and logs the overruns the scheduler
//!   tells of (at most once a second). Unpaced (virtual time): the runtime's clock is not
//!   consulted at all, so a run costs no timers and is deterministic. Runtimes made by
//!   [`runtime`] tell hubs made on their thread which to be.
//! - A wake is one message to the node's actor with the inputs of each of its controllers that
//!   is due, and an answer back for each of them; a node whose actor is gone answers as a crash
//!   ([`crate::node::Reply`]).
//! - The trace ends ([`FlushTrace`]) or the hub stops: every record still held goes to the sinks.
//! - Observers ([`Subscribe`]) get every frame through a bounded channel; a slow one loses
//!   frames, it never holds up the bus.

use crate::Error;
use crate::node::{Answer, Reply, Wake};
use actix::prelude::*;
use bus::Frame;
use bus::engine::{BusConfig, ControllerConfig, DisturbCounts, NodeId, Rule, RuleId};
use bus::node::CrashCause;
use bus::pacing::Pacer;
pub use bus::schedule::{Handover, NodeSnapshot, Observed, Snapshot};
use bus::schedule::{Notice, Scheduler, Setup};
use bus::time::{BusDuration, BusTime, Epoch};
use bus::trace::Sink;
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

/// The hub actor.
pub struct Hub {
    sched: Scheduler,
    epoch: Epoch,
    paced: bool,
    /// Each slot's node actor, by slot (a node's is at its first controller's slot).
    actors: Vec<Option<Recipient<Wake>>>,
    start: Option<tokio::time::Instant>,
    me: Option<std::sync::Arc<Recipient<Answer>>>,
    timer: Option<SpawnHandle>,
    /// Paced hubs wait on a wall-clock timer thread (`wall_timer`), with the wall-clock start.
    wall: Option<(crate::wall_timer::WallTimer, std::time::Instant)>,
    /// The id of the deadline the wall timer is armed for; others are stale.
    armed: u64,
    on_stop: Vec<oneshot::Sender<Result<BusTime, bus::Error>>>,
    /// Crashes told of so far.
    crashes: std::sync::Arc<std::sync::atomic::AtomicU64>,
}

impl Hub {
    /// A hub with no nodes; each of `sinks` receives the trace's records ([`bus::trace`]).
    pub fn new(config: HubConfig, sinks: Vec<Box<dyn Sink>>) -> Result<Hub, Error> {
        let setup = Setup {
            bus: config.bus,
            iface: config.iface,
            paced: config.paced,
            pacer: Pacer::new(config.slack, config.overrun_threshold),
        };
        Ok(Hub {
            sched: Scheduler::new(setup, sinks)?,
            epoch: config.epoch,
            paced: config.paced,
            actors: Vec::new(),
            start: None,
            me: None,
            timer: None,
            wall: None,
            armed: 0,
            on_stop: Vec::new(),
            crashes: Default::default(),
        })
    }

    /// How many node crashes the hub has told of, counted before the stop they end a run at
    /// is answered: a supervisor that finds the count unchanged after a run need not ask which
    /// nodes crashed ([`GetCrashed`]).
    pub fn crashes(&self) -> std::sync::Arc<std::sync::atomic::AtomicU64> {
        self.crashes.clone()
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

    /// Runs one step of the scheduler at the present wall time, then carries out what it asks.
    fn step(&mut self, ctx: &mut Context<Self>, step: impl FnOnce(&mut Scheduler, u64)) {
        if let Some(h) = self.timer.take() {
            ctx.cancel_future(h);
        }
        // A wall-timer deadline set before is stale from here on.
        self.armed += 1;
        // Unpaced, the scheduler reads no clock: none is read for it.
        let wall = if self.paced { self.clock() } else { 0 };
        step(&mut self.sched, wall);
        self.carry_out(ctx);
    }

    /// Runs the bus as far as it can without hearing from a node.
    fn pump(&mut self, ctx: &mut Context<Self>) {
        self.step(ctx, Scheduler::advance);
    }

    /// Sends the scheduler's wakes, tells its notices, and arms the timer it asks for.
    fn carry_out(&mut self, ctx: &mut Context<Self>) {
        while let Some(wake) = self.sched.poll_wake() {
            let me = self
                .me
                .get_or_insert_with(|| std::sync::Arc::new(ctx.address().recipient()));
            let message = Wake {
                now: wake.now,
                inputs: wake.inputs,
                reply: Reply::new(me.clone(), wake.node, wake.round),
            };
            // A node whose actor is gone answers at once: its reply is dropped with the wake.
            if let Some(Some(actor)) = self.actors.get(wake.node) {
                actor.do_send(message);
            }
        }
        while let Some(notice) = self.sched.poll_notice() {
            self.tell(notice);
        }
        if let Some(due) = self.sched.poll_timeout() {
            self.arm(due, ctx);
        }
    }

    /// Carries out or logs one notice of the scheduler.
    fn tell(&mut self, notice: Notice) {
        if matches!(notice, Notice::Crashed { .. }) {
            self.crashes.fetch_add(1, std::sync::atomic::Ordering::Release);
        }
        match notice {
            Notice::Stopped(result) => {
                for tx in self.on_stop.drain(..) {
                    let _ = tx.send(result.clone());
                }
            }
            // Asked for by a scenario: expected, so not a warning on the operator's screen.
            Notice::Crashed { node, cause } if cause == CrashCause::Injected => {
                tracing::info!(%node, message = %cause, "node crashed")
            }
            Notice::Crashed { node, cause } => tracing::warn!(%node, message = %cause, "node crashed"),
            Notice::Overrun {
                late_ns,
                overruns,
                behind_ns,
            } => tracing::warn!(
                late_ms = late_ns / 1_000_000,
                overruns,
                behind_ms = behind_ns / 1_000_000,
                "real-time overrun: harvemu was not scheduled in time; bus time slips instead of bursting"
            ),
            Notice::CommandFailed { node, error } => {
                tracing::error!(%node, %error, "controller command failed")
            }
            Notice::NoController { node, controller } => tracing::error!(
                %node,
                controller,
                "a command for a controller the node does not have"
            ),
            Notice::TraceOrder(error) => tracing::error!(%error, "a trace record out of order"),
        }
    }

    /// Wakes the hub at wall time `due` (ns since its start).
    fn arm(&mut self, due: u64, ctx: &mut Context<Self>) {
        if let Some((timer, start)) = &self.wall {
            self.armed += 1;
            if timer.set(self.armed, *start + Duration::from_nanos(due)) {
                return;
            }
        }
        let wait = due.saturating_sub(self.clock());
        self.timer = Some(ctx.run_later(Duration::from_nanos(wait.max(1)), |hub, ctx| {
            hub.timer = None;
            hub.pump(ctx);
        }));
    }
}

impl Handler<Answer> for Hub {
    type Result = ();
    fn handle(&mut self, msg: Answer, ctx: &mut Context<Self>) {
        self.step(ctx, |sched, wall| {
            sched.handle_answer(msg.round, msg.slot, msg.report, msg.last, wall)
        });
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
        self.sched.close_trace();
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
        let reaction = BusDuration::from_std(msg.reaction);
        let id = self
            .sched
            .attach_one(msg.controller, reaction, msg.node.is_some());
        self.place(id, 1, msg.node);
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
        let ids = self.attach(msg.controllers, msg.node, msg.reaction)?;
        self.pump(ctx);
        Ok(ids)
    }
}

impl Hub {
    /// Attaches the controllers of one node, and its actor at the first one's slot.
    fn attach(
        &mut self,
        controllers: Vec<ControllerConfig>,
        node: Option<Recipient<Wake>>,
        reaction: Duration,
    ) -> Result<Vec<NodeId>, Error> {
        let reaction = BusDuration::from_std(reaction);
        let ids = self.sched.attach(controllers, reaction, node.is_some())?;
        if let Some(&first) = ids.first() {
            self.place(first, ids.len(), node);
        }
        Ok(ids)
    }

    /// Keeps the actor of the node just attached with `count` controllers from `first` on, at
    /// its first slot (where its wakes go).
    fn place(&mut self, first: NodeId, count: usize, node: Option<Recipient<Wake>>) {
        self.actors.resize(first.index() + count, None);
        self.actors[first.index()] = node;
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
        self.step(ctx, |sched, wall| {
            sched.run_until(msg.0);
            sched.advance(wall);
        });
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
        let (tx, rx) = oneshot::channel();
        self.on_stop.push(tx);
        self.step(ctx, |sched, wall| {
            sched.end_trace();
            sched.advance(wall);
        });
        Box::pin(async move { rx.await.map_err(|_| Error::HubStopped)?.map_err(Error::from) })
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
        let sched = &mut self.sched;
        let result = match msg {
            Control::SetAck(n, on) => sched.set_ack(n, on).map(|()| None),
            Control::SetConnected(n, on) => sched.set_connected(n, on).map(|()| None),
            Control::SetHung(n, on) => sched.set_hung(n, on).map(|()| None),
            Control::Reset(n) => sched.reset(n).map(|()| None),
            Control::AddRule(rule) => Ok(Some(sched.add_rule(rule))),
            Control::RemoveRule(id) => {
                sched.remove_rule(id);
                Ok(None)
            }
            Control::Poke(n) => sched.poke(n).map(|()| None),
        };
        self.pump(ctx);
        Ok(result?)
    }
}

/// Hits and misses of disturbance rules, in the order asked (`None` for a rule that is not one).
#[derive(Message, Clone, Debug)]
#[rtype(result = "Vec<Option<DisturbCounts>>")]
pub struct GetDisturbCounts(pub Vec<RuleId>);

impl Handler<GetDisturbCounts> for Hub {
    type Result = Vec<Option<DisturbCounts>>;
    fn handle(&mut self, msg: GetDisturbCounts, _: &mut Context<Self>) -> Self::Result {
        msg.0.iter().map(|&id| self.sched.disturb_counts(id)).collect()
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
        let first = self.sched.replace(msg.node)?;
        if let Some(slot) = self.actors.get_mut(first.index()) {
            *slot = Some(msg.actor);
        }
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
        let wall = self.clock();
        let queued = self.sched.submit_now(msg.node, msg.frame, wall)?;
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
        let queued = self.sched.submit_at(msg.node, msg.frame, msg.at)?;
        self.pump(ctx);
        Ok(queued)
    }
}

/// Registers an observer of every frame on the bus (gateways, displays). The channel is
/// bounded: frames that do not fit are dropped for that observer and counted.
#[derive(Message)]
#[rtype(result = "()")]
pub struct Subscribe(pub tokio::sync::mpsc::Sender<Observed>);

impl Handler<Subscribe> for Hub {
    type Result = ();
    fn handle(&mut self, Subscribe(tx): Subscribe, _: &mut Context<Self>) {
        // A slow observer loses frames; it never holds up the bus.
        self.sched.observe(Box::new(move |seen| {
            !matches!(
                tx.try_send(*seen),
                Err(tokio::sync::mpsc::error::TrySendError::Closed(_))
            )
        }));
    }
}

/// Registers an observer of every controller's error frames, told as the engine commits them
/// (possibly ahead of the bus time a run has reached: see [`bus::schedule::ObservedError`]).
#[derive(Message)]
#[rtype(result = "()")]
pub struct ObserveErrors(pub Box<dyn FnMut(&bus::schedule::ObservedError) -> bus::schedule::Heard + Send>);

impl Handler<ObserveErrors> for Hub {
    type Result = ();
    fn handle(&mut self, ObserveErrors(mut observer): ObserveErrors, _: &mut Context<Self>) {
        self.sched.observe_errors(Box::new(move |seen| observer(seen)));
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
        MessageResult(self.sched.crashed())
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
        MessageResult(self.sched.error_counters())
    }
}

/// Asks for a [`Snapshot`].
#[derive(Message)]
#[rtype(result = "Snapshot")]
pub struct GetSnapshot;

impl Handler<GetSnapshot> for Hub {
    type Result = MessageResult<GetSnapshot>;
    fn handle(&mut self, _: GetSnapshot, _: &mut Context<Self>) -> Self::Result {
        MessageResult(self.sched.snapshot())
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
