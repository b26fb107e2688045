//! The scheduler: the bus engine and the nodes' wakes in one sans-IO state machine, which an
//! actor (the hub of `bus-runtime`), a test or any other driver runs.
//!
//! A driver calls [`Scheduler::advance`] with the wall clock, then takes what the scheduler
//! asks for: [`Scheduler::poll_wake`] (nodes to wake; each answers with
//! [`Scheduler::handle_answer`]), [`Scheduler::poll_notice`] (a run stopped, a node crashed,
//! something failed that the driver should log) and [`Scheduler::poll_timeout`] (the wall time
//! to call `advance` again at, when paced). Nothing here reads a clock, sleeps or does I/O but
//! through the trace [`Sink`]s and observers it was given; like the rest of the crate it depends
//! on no runtime or actor crate (`tests/pure.rs`), and its unit tests step it by hand.
//!
//! # Time
//!
//! The bus clock is exact (nanoseconds, whole bit times). The scheduler never steps per frame.
//! It commits bus events in time order up to the next moment a node could change the outcome —
//! the earliest node deadline, or a delivery plus that node's reaction time — then wakes the
//! nodes due at that moment, waits for their answers (which may submit frames), and goes on.
//!
//! Paced (real time): before committing anything at bus time `t` the scheduler waits until the
//! wall clock has reached `t` (less an optional slack): it asks to be advanced again then
//! ([`Scheduler::poll_timeout`]). When bus time is more than the overrun threshold behind that
//! schedule (the process was not scheduled for a while), bus time slips: it goes on from where it
//! stopped, the overrun is counted ([`Snapshot::overruns`]) and told ([`Notice::Overrun`], at
//! most once a second), and frames from outside ([`Scheduler::submit_now`]) are stamped on the
//! slipped clock ([`crate::pacing`]). Unpaced (virtual time): nothing but the nodes holds the bus
//! back, and bus time runs as fast as they answer; the wall clock given is not consulted.
//!
//! # Trace
//!
//! The engine's events become trace records ([`crate::trace::Record`]) for the sinks, through a
//! reorder window first ([`Reorder`], [`crate::trace::WINDOW_BITS`] bit times): the engine
//! commits a frame or error frame whole at its start, so its records can lie ahead of what a
//! node's command (a controller reset, counters written) or a fault injection makes the bus say
//! at the scheduler's present. Sinks get records in time order, equal times as they came, a
//! window behind the newest, and the rest when the trace ends ([`Scheduler::end_trace`], or the
//! scheduler dropped). A record later than the window allows is not written: it is
//! [`Error::TraceOrder`], which every stop answers with from then on.
//!
//! # Wakes
//!
//! A node is woken at its deadline (`poll_timeout`), and a reaction time after a frame reaches its
//! receive FIFO, after a receive overrun or after an error-state change. Transmit confirmations
//! (sent, aborted, refused) do not wake a node by themselves: they ride along with its next wake.
//! A node whose logic said its frames can wait ([`crate::node::NodeLogic::frames_can_wait`]) is
//! not woken for frames alone: they leave its FIFO a reaction time after they arrive and reach the
//! logic with its next wake, so such a wake asks for no answer. A node whose logic models its
//! controller's registers (a firmware node, [`crate::node::NodeLogic::wants_every_event`]) is
//! woken by every event of its controller as it happens instead (confirmations, counters, bus
//! errors, lost arbitration, bus-off recovery), and its commands (join or leave the bus, abort,
//! counters, recovery, tuning) act at its wake's time (`commands.rs`). A logic that said at its
//! last answer which frames it takes no notice of for a while ([`crate::node::Unheeded`]) is not
//! woken for those: they leave its FIFO at their wake and count as handled.
//! Such a node may have several controllers on the bus ([`Scheduler::attach`]), each a slot of its
//! own (arbitration, acknowledgement, error counters, bus off); a node is woken once per moment,
//! with the inputs of each of its controllers that is due ([`Wake::inputs`]), and reports on
//! each in turn ([`Scheduler::handle_answer`]). A node due with nothing for its logic (the frame
//! it was due for went with a reset) is not woken at all.
//! The node's deadline, crashes, hangs and replacements are the node's, shared by all its
//! controllers. A hung node (fault injection) is never woken, so its FIFO fills and overruns as a
//! real one would.

mod commands;
mod dispatch;
mod slot;
#[cfg(test)]
mod tests;

pub use slot::Handover;

use crate::Error;
use crate::Frame;
use crate::engine::{
    Bus, BusConfig, ControllerConfig, ControllerCounters, Event, NodeId, Received, Rule, RuleId, Stats,
};
use crate::fault::ErrorState;
use crate::node::{ControllerEvent, CrashCause, Report};
use crate::pacing::{Overruns, Pace, Pacer};
use crate::time::{BusDuration, BusTime};
use crate::trace::{Kind, Reorder, Sink};
use slot::Slot;
use smallvec::SmallVec;
use std::collections::VecDeque;

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

/// An observer of every frame: false when it is gone and wants no more.
pub type Observer = Box<dyn FnMut(&Observed) -> bool>;

/// A controller's error frame as an observer sees it, when the engine commits it (possibly
/// ahead of the bus time a run has reached: [`crate::engine`] commits whole events at their
/// start).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ObservedError {
    /// Its time: the first bit of the error or overload flag, or the moment of the state change
    /// or overrun ([`crate::trace::Record::at`]).
    pub at: BusTime,
    /// The controller that reports it.
    pub node: NodeId,
    /// That controller's name.
    pub name: String,
    /// It, in SocketCAN's encoding, as the trace writes it.
    pub frame: crate::trace::ErrorFrame,
}

/// What an observer of error frames says to each.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Heard {
    /// It is gone and wants no more.
    Gone,
    /// Noted; the run goes on.
    Noted,
    /// The run in progress is to stop at the error frame's time (a program outside the bus
    /// waits for one), as it stops for a node that asks ([`crate::node::NodeLogic::stop_here`]).
    StopThere,
}

/// An observer of every controller's error frames.
pub type ErrorObserver = Box<dyn FnMut(&ObservedError) -> Heard>;

/// A node to wake: its inputs since its last wake, all at or before `now`.
#[derive(Debug)]
pub struct Wake {
    /// The node: the slot of its first controller.
    pub node: usize,
    /// The wake round; the answer names it.
    pub round: u64,
    /// Bus time of the wake.
    pub now: BusTime,
    /// The inputs of each of the node's controllers that is due, in controller order (one but
    /// for a node with several: kept inline, so a wake allocates nothing of its own).
    pub inputs: SmallVec<[Inputs; 1]>,
}

/// One controller's inputs in a [`Wake`].
#[derive(Debug)]
pub struct Inputs {
    /// The controller's slot (its [`NodeId`]'s index); the answer's report for it names it.
    pub slot: usize,
    /// Which of the node's controllers it is (0 for a node with one).
    pub controller: usize,
    /// Frames from its receive FIFO, oldest first.
    pub frames: Vec<Received>,
    /// Its notifications, oldest first.
    pub events: Vec<(BusTime, ControllerEvent)>,
}

/// What the scheduler tells its driver.
#[derive(Debug)]
pub enum Notice {
    /// A run stopped ([`Scheduler::run_until`]): at this time, or with the trace's error.
    Stopped(Result<BusTime, Error>),
    /// A node's logic crashed (told once per crash).
    Crashed {
        /// The node.
        node: String,
        /// Why.
        cause: CrashCause,
    },
    /// Paced: bus time slipped behind the wall clock (told at most once a second).
    Overrun {
        /// How late the bus was this time, ns.
        late_ns: u64,
        /// Overruns since the last notice.
        overruns: u64,
        /// How far bus time is behind the wall clock in all, ns.
        behind_ns: u64,
    },
    /// A command of a node's logic, or a frame it gave, was refused by the bus.
    CommandFailed {
        /// The node.
        node: String,
        /// Why.
        error: Error,
    },
    /// A node's logic gave a command for a controller it does not have.
    NoController {
        /// The node.
        node: String,
        /// The controller it named.
        controller: usize,
    },
    /// A trace record came too late to be written in order (a bug): the trace stops there.
    TraceOrder(Error),
}

/// The scheduler: see the module's documentation.
pub struct Scheduler {
    bus: Bus,
    iface: String,
    /// When bus time may be committed, and the overruns (paced only).
    pacer: Pacer,
    paced: bool,
    slots: Vec<Slot>,
    now: BusTime,
    /// Nodes woken in the present round that have not answered yet.
    waiting: usize,
    round: u64,
    crashed_in_round: bool,
    /// A node asked in this round for the run to stop here ([`crate::node::NodeLogic::stop_here`]).
    stop_in_round: bool,
    paused: bool,
    stop_at: Option<BusTime>,
    /// Wall time to be advanced again at (paced, waiting for the clock).
    timeout: Option<u64>,
    /// Where the trace goes; a sink that failed is dropped.
    sinks: Vec<Box<dyn Sink>>,
    /// The trace's records on their way to the sinks, put in time order: the bus commits whole
    /// frames ahead of time, and what nodes' commands make it say comes at their present, which
    /// may be earlier ([`Reorder`]). Each record is its source (the bus, or a controller) and
    /// what it holds; names are looked up as it goes out.
    order: Reorder<(Option<NodeId>, Kind)>,
    /// A record came too late to be put in order: every stop answers with this from then on.
    order_error: Option<Error>,
    /// [`Scheduler::end_trace`] asked for the end of the trace: the next stop hands every
    /// record on.
    trace_ends: bool,
    /// The first error of a sink.
    trace_error: Option<String>,
    scratch: Vec<Event>,
    wakes: u64,
    observers: Vec<Observer>,
    error_observers: Vec<ErrorObserver>,
    /// How many slots hear of every event (register-level nodes): none, usually, and then
    /// nothing is spent on them.
    register_level: usize,
    woken: VecDeque<Wake>,
    notices: VecDeque<Notice>,
    /// Each slot's due time as last set (`BusTime::NEVER`: none), no later than the slot's own:
    /// it is set whenever a slot's due time may have changed, and checked against the slot when
    /// it comes up (a later change leaves it early, and it is read again then). The earliest
    /// is found by one pass over a few words per slot, which costs less than a heap's pushes
    /// and pops for the node counts of a CAN bus, and never reads the slots themselves.
    dues: Vec<BusTime>,
    /// The slots due at a wake's moment (kept to reuse its allocation).
    due_now: Vec<usize>,
}

/// How a scheduler is set up.
#[derive(Clone, Debug)]
pub struct Setup {
    /// The bus.
    pub bus: BusConfig,
    /// Interface name in traces.
    pub iface: String,
    /// Keep bus time in step with the wall clock given to [`Scheduler::advance`] (real time).
    pub paced: bool,
    /// When paced: how far bus time runs ahead of the wall clock, and how far it may fall
    /// behind before it slips ([`crate::pacing`]).
    pub pacer: Pacer,
}

impl Scheduler {
    /// A scheduler with no nodes, paused at bus time zero; each of `sinks` receives the trace's
    /// records ([`crate::trace`]).
    pub fn new(setup: Setup, sinks: Vec<Box<dyn Sink>>) -> Result<Scheduler, Error> {
        let bus = Bus::new(setup.bus)?;
        Ok(Scheduler {
            order: Reorder::for_bit_time(bus.bit_time()),
            order_error: None,
            trace_ends: false,
            bus,
            iface: setup.iface,
            pacer: setup.pacer,
            paced: setup.paced,
            slots: Vec::new(),
            now: BusTime::ZERO,
            waiting: 0,
            round: 0,
            crashed_in_round: false,
            stop_in_round: false,
            paused: true,
            stop_at: None,
            timeout: None,
            sinks,
            trace_error: None,
            scratch: Vec::with_capacity(64),
            wakes: 0,
            observers: Vec::new(),
            error_observers: Vec::new(),
            register_level: 0,
            woken: VecDeque::new(),
            notices: VecDeque::new(),
            dues: Vec::new(),
            due_now: Vec::new(),
        })
    }

    /// The present: the last committed event or wake.
    pub fn present(&self) -> BusTime {
        self.now.max(self.bus.committed())
    }

    /// Attaches the controllers of one node, all at once so that no wake comes between them,
    /// with a logic to wake or without one (a node driven from outside); answers with their
    /// ids, in order, the first being the node's. A node with a logic is woken at once (the
    /// present), to say when it is next due.
    pub fn attach(
        &mut self,
        controllers: Vec<ControllerConfig>,
        reaction: BusDuration,
        logic: bool,
    ) -> Result<Vec<NodeId>, Error> {
        if controllers.is_empty() {
            return Err(Error::NoControllers);
        }
        let first = self.slots.len();
        Ok(controllers
            .into_iter()
            .enumerate()
            .map(|(k, controller)| self.add_slot(controller, reaction, logic, first, k))
            .collect())
    }

    /// [`Scheduler::attach`] for a node with one controller.
    pub fn attach_one(&mut self, controller: ControllerConfig, reaction: BusDuration, logic: bool) -> NodeId {
        let first = self.slots.len();
        self.add_slot(controller, reaction, logic, first, 0)
    }

    /// Puts controller `k` of the node whose first slot is `first` on the bus.
    fn add_slot(
        &mut self,
        controller: ControllerConfig,
        reaction: BusDuration,
        logic: bool,
        first: usize,
        k: usize,
    ) -> NodeId {
        let mut slot = Slot::new(controller.name.clone(), logic, first, k, reaction);
        // A first wake tells the node the time and collects its first deadline (which the
        // first controller's slot keeps).
        slot.next_timeout = (k == 0).then(|| self.present());
        self.slots.push(slot);
        self.dues.push(BusTime::NEVER);
        self.queue_due(self.slots.len() - 1);
        self.bus.attach(controller)
    }

    /// Runs until bus time `t` (or an earlier stop asked for before): the stop is told as
    /// [`Notice::Stopped`], with that time, or with the moment a node crashed or asked to stop
    /// ([`crate::node::NodeLogic::stop_here`]) if one did on the way. Once a trace record came
    /// too late to be written in time order ([`Error::TraceOrder`]), every stop tells that.
    pub fn run_until(&mut self, t: BusTime) {
        self.stop_at = Some(self.stop_at.map_or(t, |s| s.min(t)));
        self.paused = false;
    }

    /// Ends the trace: the run stops at the present (told as [`Notice::Stopped`]), every record
    /// still held for time order goes to the sinks, and every sink is flushed, once the nodes
    /// woken, if any, have answered. A bus run on after it must not give a record older than
    /// those (the reorder window is empty then): that is the stop's error.
    pub fn end_trace(&mut self) {
        self.trace_ends = true;
        self.run_until(self.present());
    }

    /// The next node to wake, if any: the driver hands the wake to the node's logic and gives
    /// its answer to [`Scheduler::handle_answer`]. The bus waits for every answer of a round.
    pub fn poll_wake(&mut self) -> Option<Wake> {
        self.woken.pop_front()
    }

    /// The next notice, if any.
    pub fn poll_notice(&mut self) -> Option<Notice> {
        self.notices.pop_front()
    }

    /// When paced and waiting for the wall clock: the wall time (ns, on the clock given to
    /// [`Scheduler::advance`]) to advance again at.
    pub fn poll_timeout(&self) -> Option<u64> {
        self.timeout
    }

    /// Runs the bus as far as it can without hearing from a node, at wall time `wall_ns` (ns
    /// since the driver started; only a paced scheduler reads it).
    pub fn advance(&mut self, wall_ns: u64) {
        if self.waiting > 0 || self.paused {
            return;
        }
        self.timeout = None;
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
                if !self.reached(t, wall_ns) {
                    self.timeout = Some(self.pacer.due(t));
                    return;
                }
                self.bus.commit(next);
                if let Some(d) = self.dispatch() {
                    due = Some(due.map_or(d, |x| x.min(d)));
                }
                continue;
            }
            match due {
                Some(d) if d < stop => {
                    if !self.reached(d, wall_ns) {
                        self.timeout = Some(self.pacer.due(d));
                        return;
                    }
                    if self.wake(d) {
                        return;
                    }
                    due = self.next_due();
                }
                _ if stop < BusTime::NEVER => {
                    if !self.reached(stop, wall_ns) {
                        self.timeout = Some(self.pacer.due(stop));
                        return;
                    }
                    return self.finish(stop);
                }
                _ => return,
            }
        }
    }

    /// Takes a node's report to wake `round` on the inputs of the controller in `slot`; `last`
    /// when it is the wake's last (its controllers report in order, and a crash is the last
    /// report: the slots after it count their frames as lost). After the last report of the
    /// round, runs on as [`Scheduler::advance`] does.
    pub fn handle_answer(&mut self, round: u64, slot: usize, report: Report, last: bool, wall_ns: u64) {
        if round != self.round || self.waiting == 0 || slot >= self.slots.len() {
            return;
        }
        self.stop_in_round |= report.stop;
        self.crashed_in_round |= self.answer(slot, report);
        if !last {
            return;
        }
        // A slot whose report never came (its logic crashed on an earlier controller's inputs)
        // lost the frames of its wake.
        for j in self.group(slot) {
            let h = &mut self.slots[j].handover;
            h.crashed += std::mem::take(&mut h.in_flight);
        }
        self.waiting -= 1;
        if self.waiting > 0 {
            return;
        }
        if (self.crashed_in_round || self.stop_in_round) && self.stop_at.is_some() {
            // The run stops here so that whoever supervises (or waits for a frame) hears of it
            // at once.
            self.finish(self.now);
        } else {
            self.advance(wall_ns);
        }
    }

    /// True when the wall clock allows committing at `t`. A paced scheduler that finds `t`
    /// overdue by more than the overrun threshold lets bus time slip ([`crate::pacing`]).
    fn reached(&mut self, t: BusTime, wall_ns: u64) -> bool {
        if !self.paced {
            return true;
        }
        match self.pacer.check(wall_ns, t) {
            Pace::Wait(_) => false,
            Pace::Go { slipped: None } => true,
            Pace::Go { slipped: Some(late) } => {
                if let Some(overruns) = self.pacer.log_due(wall_ns) {
                    self.notices.push_back(Notice::Overrun {
                        late_ns: late,
                        overruns,
                        behind_ns: self.pacer.overruns().slipped_ns,
                    });
                }
                true
            }
        }
    }

    /// The bus time of wall time `wall_ns`, for a frame from outside: the wall clock less the
    /// slips. A stall not yet noticed is noticed first, so the frame does not land in the future
    /// of bus time it stalled at.
    fn outside_time(&mut self, wall_ns: u64) -> BusTime {
        if !self.paced {
            return BusTime::from_nanos(wall_ns);
        }
        let frontier = if self.waiting > 0 {
            Some(self.now)
        } else {
            let stop = self.stop_at.unwrap_or(BusTime::NEVER);
            let next = self.bus.next_event().map_or(stop, |(t, _)| t.min(stop));
            Some(self.next_due().map_or(next, |d| d.min(next))).filter(|&t| t < BusTime::NEVER)
        };
        if let Some(t) = frontier.filter(|_| !self.paused) {
            self.reached(t, wall_ns);
        }
        self.pacer.bus_time(wall_ns)
    }

    /// The earliest time a node is due (reading again the slots whose time went stale).
    fn next_due(&mut self) -> Option<BusTime> {
        let next = loop {
            let Some((i, &t)) = self.dues.iter().enumerate().min_by_key(|&(_, t)| *t) else {
                break None;
            };
            if t == BusTime::NEVER {
                break None;
            }
            match self.slots[i].due() {
                Some(d) if d == t => break Some(t),
                d => self.dues[i] = d.unwrap_or(BusTime::NEVER),
            }
        };
        debug_assert_eq!(
            next,
            self.slots.iter().filter_map(Slot::due).min(),
            "the due times lost a slot"
        );
        next
    }

    /// Sets slot `i`'s due time after a change that may have moved it; answers with that
    /// time.
    fn queue_due(&mut self, i: usize) -> Option<BusTime> {
        let due = self.slots[i].due();
        self.dues[i] = due.unwrap_or(BusTime::NEVER);
        due
    }

    /// The slots of the node slot `i` belongs to: its controllers, first to last.
    fn group(&self, i: usize) -> std::ops::Range<usize> {
        let first = self.slots[i].first;
        let end = (first..self.slots.len())
            .find(|&j| self.slots[j].first != first)
            .unwrap_or(self.slots.len());
        first..end
    }

    /// Takes a node's report for slot `i`; true when the node crashed.
    fn answer(&mut self, i: usize, report: Report) -> bool {
        let now = self.now;
        let h = &mut self.slots[i].handover;
        let sent = std::mem::take(&mut h.in_flight);
        let handled = report.frames_handled.min(sent);
        h.handled += handled;
        h.crashed += sent - handled;
        let first = self.slots[i].first;
        if let Some(cause) = report.crashed {
            self.crash(i, cause);
            return true;
        }
        if report.every_event != self.slots[i].every_event {
            self.set_every_event(i, report.every_event);
        }
        for (k, command) in report.commands {
            let target = if k == self.slots[i].controller {
                Some(i)
            } else {
                self.group(i).find(|&j| self.slots[j].controller == k)
            };
            match target {
                Some(j) => self.apply(j, command, now),
                None => self.notices.push_back(Notice::NoController {
                    node: self.slots[i].name.clone(),
                    controller: k,
                }),
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
        self.queue_due(first);
        self.slots[i].unheeded = report.unheeded;
        if report.frames_can_wait != self.slots[i].frames_can_wait {
            for j in self.group(i) {
                self.slots[j].frames_can_wait = report.frames_can_wait;
            }
        }
        false
    }

    /// Slot `i`'s logic crashed: all of its node's controllers go down with it (one logic
    /// behind them), told once. Out of line, as the other rare turns of a wake's path are, so
    /// that the path itself stays small.
    #[cold]
    #[inline(never)]
    fn crash(&mut self, i: usize, cause: CrashCause) {
        if self.slots[i].crashed.is_some() {
            return;
        }
        let node = self.slots[i].name.clone();
        self.notices.push_back(Notice::Crashed {
            node,
            cause: cause.clone(),
        });
        for j in self.group(i) {
            self.slots[j].crashed = Some(cause.clone());
        }
    }

    /// Slot `i`'s node starts or stops hearing of every event (register level).
    #[cold]
    #[inline(never)]
    fn set_every_event(&mut self, i: usize, on: bool) {
        for j in self.group(i) {
            self.slots[j].every_event = on;
        }
        self.register_level = self.slots.iter().filter(|s| s.every_event).count();
        self.bus.report_arbitration(self.register_level > 0);
    }

    /// Queues a frame of slot `i`'s logic; a full queue is told back as refused.
    fn submit_for(&mut self, i: usize, frame: Frame, now: BusTime, single_shot: bool) {
        match self.bus.submit_with(NodeId(i as u16), frame, now, single_shot) {
            Ok(Some(_)) => {}
            Ok(None) => self.slots[i].input(now, Some(ControllerEvent::Refused(frame)), false),
            Err(error) => self.command_failed(i, error),
        }
    }

    /// Tells that a command of slot `i`'s logic failed.
    #[cold]
    #[inline(never)]
    fn command_failed(&mut self, i: usize, error: Error) {
        let node = self.slots[i].name.clone();
        self.notices.push_back(Notice::CommandFailed { node, error });
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
        let result = self.order_error.clone().map_or(Ok(at), Err);
        self.notices.push_back(Notice::Stopped(result));
    }

    /// Hands every record still held to the sinks and flushes them (the driver is stopping).
    pub fn close_trace(&mut self) {
        self.hand_over(true);
        self.flush_sinks();
    }
}

/// A scheduler dropped without its trace closed still hands on the records it held.
impl Drop for Scheduler {
    fn drop(&mut self) {
        if !self.order.is_empty() {
            self.close_trace();
        }
    }
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

/// Fault injection, frames from outside, and what a driver reads.
impl Scheduler {
    /// Makes a node acknowledge frames or not.
    pub fn set_ack(&mut self, node: NodeId, on: bool) -> Result<(), Error> {
        self.bus.set_ack(node, on)
    }

    /// Disconnects or reconnects a node (its cable), at the present. Reconnected, a controller
    /// its logic holds off the bus (a chip in reset) stays off until the logic puts it back.
    pub fn set_connected(&mut self, node: NodeId, on: bool) -> Result<(), Error> {
        let now = self.present();
        let Some(slot) = self.slots.get_mut(node.index()) else {
            return Err(Error::NoNode(node.0));
        };
        slot.switches.unplugged = !on;
        // Plugged in, a controller its logic holds off the bus stays off it.
        let on = on && !slot.switches.offline;
        self.bus.set_connected(node, on, now)
    }

    /// Stops waking a node, all its controllers (it hangs: alive, silent, not draining its
    /// FIFO), or wakes it again at once.
    pub fn set_hung(&mut self, node: NodeId, on: bool) -> Result<(), Error> {
        if node.index() >= self.slots.len() {
            return Err(Error::NoNode(node.0));
        }
        let now = self.present();
        for j in self.group(node.index()) {
            let slot = &mut self.slots[j];
            slot.hung = on;
            if !on {
                // What arrived while it hung is handled from now on, not in the past.
                slot.pending_since = slot.pending_since.map(|t| t.max(now));
                if slot.first == j {
                    slot.next_timeout = Some(now);
                }
                self.queue_due(j);
            }
        }
        Ok(())
    }

    /// Resets a node's controller, at the present.
    pub fn reset(&mut self, node: NodeId) -> Result<(), Error> {
        let now = self.present();
        let result = self.bus.reset_node(node, now);
        self.dispatch();
        result
    }

    /// Installs a corruption rule.
    pub fn add_rule(&mut self, rule: Rule) -> RuleId {
        self.bus.injector_mut().add(rule)
    }

    /// Removes one.
    pub fn remove_rule(&mut self, id: RuleId) {
        self.bus.injector_mut().remove(id);
    }

    /// Hits and misses of a disturbance rule, removed or not ([`crate::engine::Effect::Disturb`]).
    pub fn disturb_counts(&self, id: RuleId) -> Option<crate::engine::DisturbCounts> {
        self.bus.injector().disturb_counts(id)
    }

    /// Wakes a node at the present, so that it reports its next deadline: a logic driven from
    /// outside ([`crate::node::NodeLogic`] state changed between wakes) says when it is next due.
    pub fn poke(&mut self, node: NodeId) -> Result<(), Error> {
        let now = self.present();
        let slot = self.slots.get_mut(node.index()).ok_or(Error::NoNode(node.0))?;
        slot.next_timeout = Some(slot.next_timeout.map_or(now, |t| t.min(now)));
        self.queue_due(node.index());
        Ok(())
    }

    /// A new logic takes over a node (after a crash, or a restart): its controllers (all of
    /// them) are reset, what the old logic left unread is dropped, and the new one is woken at
    /// once. Answers with the node's first controller, whose wakes the new logic gets.
    pub fn replace(&mut self, node: NodeId) -> Result<NodeId, Error> {
        if node.index() >= self.slots.len() {
            return Err(Error::NoNode(node.0));
        }
        let now = self.present();
        let group = self.group(node.index());
        let first = NodeId(group.start as u16);
        for j in group {
            self.bus.reset_node(NodeId(j as u16), now)?;
            let slot = &mut self.slots[j];
            slot.logic = true;
            slot.crashed = None;
            slot.hung = false;
            slot.clear();
            slot.next_timeout = (slot.first == j).then_some(now);
            self.queue_due(j);
        }
        self.dispatch();
        Ok(first)
    }

    /// Hands a frame to a node's controller from outside (a gateway), at wall time `wall_ns`
    /// (not before the present: what the nodes' commands did there is in the trace). True when
    /// it was queued, false when the queue was full.
    pub fn submit_now(&mut self, node: NodeId, frame: Frame, wall_ns: u64) -> Result<bool, Error> {
        let at = self.outside_time(wall_ns).max(self.present());
        Ok(self.bus.submit(node, frame, at)?.is_some())
    }

    /// Hands a frame to a node's controller from outside at bus time `at` (a replayed trace); a
    /// time already committed becomes the present and counts as a late submission.
    pub fn submit_at(&mut self, node: NodeId, frame: Frame, at: BusTime) -> Result<bool, Error> {
        Ok(self.bus.submit(node, frame, at)?.is_some())
    }

    /// Registers an observer of every frame on the bus, told at the frame's end.
    pub fn observe(&mut self, observer: Observer) {
        self.observers.push(observer);
    }

    /// Registers an observer of every controller's error frames, told as the engine commits
    /// them, in the order it does; one that answers [`Heard::StopThere`] stops the run in
    /// progress at that error frame's time (told as [`Notice::Stopped`]).
    pub fn observe_errors(&mut self, observer: ErrorObserver) {
        self.error_observers.push(observer);
    }

    /// The nodes that crashed, and why.
    pub fn crashed(&self) -> Vec<(NodeId, CrashCause)> {
        self.slots
            .iter()
            .enumerate()
            .filter_map(|(i, s)| s.crashed.clone().map(|why| (NodeId(i as u16), why)))
            .collect()
    }

    /// Every node's (TEC, REC), by node index.
    pub fn error_counters(&self) -> Vec<(u16, u16)> {
        self.bus
            .controllers()
            .iter()
            .map(|c| (c.fault().tec(), c.fault().rec()))
            .collect()
    }

    /// The scheduler's state for reports and tests.
    pub fn snapshot(&self) -> Snapshot {
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
        Snapshot {
            now: self.present(),
            stats: self.bus.stats().clone(),
            nodes,
            wakes: self.wakes,
            late_submissions: self.bus.late_submissions(),
            overruns: self.pacer.overruns(),
            trace_error: self.trace_error.clone(),
        }
    }
}

/// One node as the scheduler sees it.
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

/// The scheduler's state for reports and tests.
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
