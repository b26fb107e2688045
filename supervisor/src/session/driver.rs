//! The harvester's thread: it starts the harvester with the program on its bus, then carries out
//! the session's commands one at a time, until the session is dropped.
//!
//! In virtual time the bus runs only inside a `recv` or a `run_for`, which the thread carries out
//! before it takes the next command. Paced by the wall clock, the bus runs all the time, in short
//! slices with the commands carried out between them; a `recv` or a `run_for` waits for the bus
//! as it runs, so that a call from another thread is not held up behind one.

use super::program::{self, Inbox, Program};
use super::{Command, Delivered, ErrorFrames, ErrorReceived, NodeState, Own};
use crate::harvester::{self, Harvester, Running};
use crate::scenario::books::Books;
use crate::scenario::{self, Action, Actions, Expect, Step, Todo, Verdict};
use crate::{Error, Result};
use actix::prelude::*;
use bus::Frame;
use bus::engine::{ControllerConfig, NodeId};
use bus::node::ControllerCommand;
use bus::schedule::{Heard, ObservedError};
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::{Attach, Control, GetSnapshot, ObserveErrors, Submit, runtime};
use bus_runtime::node::NodeActor;
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use tokio::sync::{mpsc, oneshot};

/// Bus time a paced bus runs between looks at the commands: how long a call waits at most before
/// the thread hears of it.
const SLICE: BusDuration = BusDuration::from_micros(2000);

/// A `recv` or a `run_for` waiting for a paced bus.
enum Wait {
    /// A frame, or none by the time given.
    Recv(BusTime, oneshot::Sender<Result<Option<Delivered>>>),
    /// The time given.
    Until(BusTime, oneshot::Sender<Result<f64>>),
}

impl Wait {
    fn deadline(&self) -> BusTime {
        match self {
            Wait::Recv(t, _) | Wait::Until(t, _) => *t,
        }
    }
}

/// What ends a fault that an action started.
enum End {
    /// The bit errors or overloads of action `0`.
    Rule(usize),
    /// The babbling idiot's flood.
    Babble,
}

struct Driver {
    running: Running,
    /// The program's node.
    id: NodeId,
    inbox: Rc<RefCell<Inbox>>,
    actions: Actions,
    /// Actions carried out so far.
    acted: usize,
    /// Faults to end, and when.
    ends: Vec<(BusTime, End)>,
    paced: bool,
    /// When every node has booted, until the first frame is sent in virtual time (which waits
    /// for it); `None` after.
    boot: Option<BusTime>,
    /// The longest frame's time on this bus: 160 bit times (29-bit identifier, 8 data bytes,
    /// every stuff bit, intermission). The bus runs this long at a time for a `send` that waits
    /// for room, and at most this long for a `recv(0)` in virtual time.
    longest_frame: BusDuration,
    /// The controller is in listen-only mode.
    listen_only: bool,
    /// A slice computed ahead ([`super::Session::slice`]), and how running it went: handed over
    /// with the next slice asked for (a failure then). `None` when the last call was another.
    ahead: Option<Result<()>>,
}

/// How the program stands on the bus.
pub(super) struct Setup {
    /// Its node's name.
    pub name: String,
    /// Bus time paced by the wall clock.
    pub paced: bool,
    /// It receives its own frames.
    pub own_frames: bool,
    /// Whose error frames it receives.
    pub error_frames: ErrorFrames,
    /// When every node has booted: in virtual time the first frame sent waits for it.
    pub ready: BusTime,
}

/// Runs the harvester's thread (see the module doc).
pub(super) fn drive(
    h: Harvester,
    setup: Setup,
    mut commands: mpsc::UnboundedReceiver<Command>,
    ready: oneshot::Sender<Result<()>>,
) {
    let paced = setup.paced;
    let system = match runtime(!paced) {
        Ok(rt) => System::with_tokio_rt(move || rt),
        Err(e) => {
            let _ = ready.send(Err(Error::Internal(format!("no runtime: {e}"))));
            return;
        }
    };
    system.block_on(async move {
        let mut d = match Driver::start(&h, setup).await {
            Ok(d) => {
                let _ = ready.send(Ok(()));
                d
            }
            Err(e) => {
                let _ = ready.send(Err(e));
                return;
            }
        };
        if paced {
            d.run_paced(commands).await;
            return;
        }
        loop {
            // The next command usually follows at once: look for it awake a little first.
            let mut next = None;
            let started = std::time::Instant::now();
            loop {
                match commands.try_recv() {
                    Ok(c) => {
                        next = Some(c);
                        break;
                    }
                    Err(mpsc::error::TryRecvError::Empty) => {
                        if !super::look_again(started) {
                            break;
                        }
                    }
                    Err(mpsc::error::TryRecvError::Disconnected) => return,
                }
            }
            let c = match next {
                Some(c) => c,
                None => match commands.recv().await {
                    Some(c) => c,
                    None => return,
                },
            };
            d.carry_out(c).await;
        }
    });
}

impl Driver {
    async fn start(h: &Harvester, setup: Setup) -> Result<Driver> {
        let Setup {
            name,
            paced,
            own_frames,
            error_frames,
            ready,
        } = setup;
        let inbox = Rc::new(RefCell::new(Inbox::default()));
        inbox.borrow_mut().own_frames = own_frames;
        let running = harvester::begin(h, paced, Vec::new()).await?;
        let actor = NodeActor::new(name.clone(), Box::new(Program::new(inbox.clone()))).start();
        let id = running
            .hub
            .send(Attach {
                controller: ControllerConfig::named(name),
                node: Some(actor.recipient()),
                reaction: std::time::Duration::ZERO,
            })
            .await?;
        if error_frames != ErrorFrames::None {
            let errors = inbox.borrow().errors.clone();
            let observe = move |seen: &ObservedError| {
                if error_frames == ErrorFrames::Own && seen.node != id {
                    return Heard::Noted;
                }
                let e = ErrorReceived {
                    at_s: seen.at.as_secs_f64(),
                    controller: seen.name.clone(),
                    can_id: seen.frame.can_id,
                    data: seen.frame.data,
                };
                if program::lock(&errors).take(seen.at, e) {
                    Heard::StopThere
                } else {
                    Heard::Noted
                }
            };
            running.hub.send(ObserveErrors(Box::new(observe))).await?;
        }
        Ok(Driver {
            running,
            id,
            inbox,
            actions: Actions::new("the session".into()),
            acted: 0,
            ends: Vec::new(),
            paced,
            boot: (!paced).then_some(ready),
            longest_frame: BusDuration::from_nanos(
                160_000_000_000 / u64::from(h.config.network.bitrate.max(1)),
            ),
            listen_only: false,
            ahead: None,
        })
    }

    /// Hands `frame` to the controller; in virtual time, first waits for the nodes' boot (the
    /// first time), then, while the transmit queue is full, runs the bus a frame's time at a
    /// time until there is room or `timeout` s have passed. Answers whether it was queued.
    async fn send(&mut self, frame: Frame, timeout: f64) -> Result<bool> {
        if self.listen_only {
            return Err(Error::BadInput(
                "the program's controller is in listen-only mode: it sends nothing".into(),
            ));
        }
        if let Some(ready) = self.boot.take() {
            self.advance(ready, |_| false).await?;
        }
        let end = self.running.now() + BusDuration::from_secs_f64(timeout);
        loop {
            let queued = self.running.hub.send(Submit { node: self.id, frame }).await??;
            if queued || self.paced || self.running.now() >= end {
                return Ok(queued);
            }
            let next = (self.running.now() + self.longest_frame).min(end);
            self.advance(next, |_| false).await?;
        }
    }

    async fn carry_out(&mut self, c: Command) {
        // Any other call ends the slices: it is carried out where the bus stands.
        if !matches!(c, Command::Slice(_)) {
            self.ahead = None;
        }
        match c {
            Command::Filters(filters, tx) => {
                self.inbox.borrow_mut().set_filters(filters);
                let _ = tx.send(Ok(()));
            }
            Command::Recv(timeout, tx) => {
                let _ = tx.send(self.recv(timeout).await);
            }
            Command::Send(frame, timeout, tx) => {
                let _ = tx.send(self.send(frame, timeout).await);
            }
            Command::ListenOnly(on, tx) => {
                self.listen_only = on;
                let online = ControllerCommand::Online {
                    listen_only: on,
                    self_test: false,
                };
                self.inbox.borrow_mut().commands.push_back(online);
                let _ = tx.send(self.poke().await);
            }
            Command::Own(tx) => {
                let snap = self.running.hub.send(GetSnapshot).await;
                let id = self.id.index();
                let listen_only = self.listen_only;
                let _ = tx.send(snap.map_err(Error::from).and_then(|s| {
                    let n = s
                        .nodes
                        .get(id)
                        .ok_or_else(|| Error::Internal("the program's node is not on the bus".into()))?;
                    Ok(Own {
                        state: NodeState::of(n),
                        listen_only,
                    })
                }));
            }
            Command::Periodic(frames, period, duration, tx) => {
                let now = self.running.now();
                let end = duration.map(|d| now + BusDuration::from_secs_f64(d));
                let period = BusDuration::from_secs_f64(period);
                let task = self.inbox.borrow_mut().start_task(frames, period, now, end);
                // The node hears of its new deadline at a wake: one now.
                let _ = tx.send(self.poke().await.map(|()| task));
            }
            Command::StopPeriodic(task, tx) => {
                let _ = tx.send(Ok(self.inbox.borrow_mut().stop_task(task)));
            }
            Command::ModifyPeriodic(task, frames, tx) => {
                let _ = tx.send(Ok(self.inbox.borrow_mut().modify_task(task, frames)));
            }
            Command::Sent(tx) => {
                let snap = self.running.hub.send(GetSnapshot).await;
                let id = self.id.index();
                let _ = tx.send(
                    snap.map_err(Error::from)
                        .map(|s| s.nodes.get(id).map_or(0, |n| n.counters.tx_frames)),
                );
            }
            Command::States(tx) => {
                let snap = self.running.hub.send(GetSnapshot).await;
                let _ = tx.send(
                    snap.map_err(Error::from)
                        .map(|s| s.nodes.iter().map(NodeState::of).collect()),
                );
            }
            Command::Display(tx) => {
                let shown = self
                    .running
                    .display
                    .as_ref()
                    .map(|d| serde_json::to_string(&*d.borrow()))
                    .transpose()
                    .map_err(Error::from);
                let _ = tx.send(shown);
            }
            Command::Input(input, value, tx) => {
                let now = self.running.now();
                let set = self.running.plant.borrow_mut().set_input_at(now, &input, value);
                let _ = tx.send(set.map_err(Error::from));
            }
            Command::Act(text, tx) => {
                let _ = tx.send(self.act(&text).await);
            }
            Command::Check(text, tx) => {
                let _ = tx.send(self.check(&text).await);
            }
            Command::Slice(tx) => {
                if self.paced {
                    let e = Error::BadInput("slices of the bus are for virtual time".into());
                    let _ = tx.send(Err(e));
                    return;
                }
                // The first slice is computed now; each later one was computed ahead.
                let ran = match self.ahead.take() {
                    Some(ran) => ran,
                    None => {
                        let end = self.running.now() + BusDuration::from_secs_f64(super::SLICE_S);
                        self.advance(end, |_| false).await
                    }
                };
                if let Err(e) = ran {
                    let _ = tx.send(Err(e));
                    return;
                }
                let now = self.running.now();
                let mut items = Vec::new();
                while let Some(d) = self.inbox.borrow_mut().pop(now) {
                    items.push(d);
                }
                let _ = tx.send(Ok((now.as_secs_f64(), items)));
                // The next slice, while the caller works through this one.
                let end = now + BusDuration::from_secs_f64(super::SLICE_S);
                self.ahead = Some(self.advance(end, |_| false).await);
            }
            Command::RunFor(seconds, tx) => {
                let end = self.running.now() + BusDuration::from_secs_f64(seconds);
                let ran = self.advance(end, |_| false).await;
                let _ = tx.send(ran.map(|()| self.running.now().as_secs_f64()));
            }
        }
    }

    /// Runs the bus paced by the wall clock until the session is dropped: slice by slice,
    /// carrying out the commands in between and answering the waits as their frame or their time
    /// comes.
    async fn run_paced(&mut self, mut commands: mpsc::UnboundedReceiver<Command>) {
        let mut waits: VecDeque<Wait> = VecDeque::new();
        // Set when the bus failed: waits are answered with it from then on.
        let mut broken: Option<String> = None;
        loop {
            loop {
                let now = self.running.now();
                match commands.try_recv() {
                    Ok(Command::Recv(t, tx)) => {
                        waits.push_back(Wait::Recv(now + BusDuration::from_secs_f64(t), tx));
                    }
                    Ok(Command::RunFor(t, tx)) => {
                        waits.push_back(Wait::Until(now + BusDuration::from_secs_f64(t), tx));
                    }
                    Ok(c) => self.carry_out(c).await,
                    Err(mpsc::error::TryRecvError::Empty) => break,
                    Err(mpsc::error::TryRecvError::Disconnected) => return,
                }
            }
            if let Some(why) = &broken {
                for w in waits.drain(..) {
                    let e = || Error::Internal(why.clone());
                    match w {
                        Wait::Recv(_, tx) => drop(tx.send(Err(e()))),
                        Wait::Until(_, tx) => drop(tx.send(Err(e()))),
                    }
                }
                // Nothing runs any more: sleep until the next command.
                match commands.recv().await {
                    Some(Command::Recv(_, tx)) => waits.push_back(Wait::Recv(BusTime::ZERO, tx)),
                    Some(Command::RunFor(_, tx)) => waits.push_back(Wait::Until(BusTime::ZERO, tx)),
                    Some(c) => self.carry_out(c).await,
                    None => return,
                }
                continue;
            }
            self.answer(&mut waits);
            let now = self.running.now();
            let end = waits.iter().map(Wait::deadline).fold(now + SLICE, BusTime::min);
            let receiving = waits.iter().any(|w| matches!(w, Wait::Recv(..)));
            self.inbox.borrow_mut().set_waiting(receiving);
            let inbox = self.inbox.clone();
            let ran = self
                .advance(end, move |now| receiving && inbox.borrow().ready(now))
                .await;
            self.inbox.borrow_mut().set_waiting(false);
            if let Err(e) = ran {
                broken = Some(e.report().to_string());
            }
        }
    }

    /// Answers the waits whose frame or time has come: frames go to the `recv`s in the order
    /// they were called.
    fn answer(&mut self, waits: &mut VecDeque<Wait>) {
        let now = self.running.now();
        let mut left = VecDeque::with_capacity(waits.len());
        for w in waits.drain(..) {
            match w {
                Wait::Recv(t, tx) => match self.inbox.borrow_mut().pop(now) {
                    Some(r) => {
                        let _ = tx.send(Ok(Some(r)));
                    }
                    None if now >= t => {
                        let _ = tx.send(Ok(None));
                    }
                    None => left.push_back(Wait::Recv(t, tx)),
                },
                Wait::Until(t, tx) if now >= t => {
                    let _ = tx.send(Ok(now.as_secs_f64()));
                }
                w => left.push_back(w),
            }
        }
        *waits = left;
    }

    async fn poke(&self) -> Result<()> {
        self.running.hub.send(Control::Poke(self.id)).await??;
        Ok(())
    }

    /// The next frame within `timeout` s; a `recv(0)` with nothing waiting runs the bus up to
    /// the longest frame's time, so that a loop of them moves bus time as a real bus moves.
    async fn recv(&mut self, timeout: f64) -> Result<Option<Delivered>> {
        let timeout = if timeout == 0.0 {
            self.longest_frame
        } else {
            BusDuration::from_secs_f64(timeout)
        };
        let end = self.running.now() + timeout;
        loop {
            if let Some(r) = self.inbox.borrow_mut().pop(self.running.now()) {
                return Ok(Some(r));
            }
            if self.running.now() >= end {
                return Ok(None);
            }
            self.inbox.borrow_mut().set_waiting(true);
            let inbox = self.inbox.clone();
            let waited = self.advance(end, move |now| inbox.borrow().ready(now)).await;
            self.inbox.borrow_mut().set_waiting(false);
            waited?;
        }
    }

    /// Runs to `end`, or until `done`, ending the actions' faults when they fall due.
    async fn advance(&mut self, end: BusTime, done: impl Fn(BusTime) -> bool) -> Result<()> {
        loop {
            let due = self.ends.iter().map(|(t, _)| *t).min();
            let stop = due.map_or(end, |t| t.min(end)).max(self.running.now());
            self.running.run_until_or(stop, &done).await?;
            while let Some(i) = self.ends.iter().position(|(t, _)| *t <= self.running.now()) {
                match self.ends.remove(i).1 {
                    End::Rule(index) => self.actions.end_rule(&self.running, index).await?,
                    End::Babble => self.actions.end_babble(&self.running).await?,
                }
            }
            if self.running.now() >= end || done(self.running.now()) {
                return Ok(());
            }
        }
    }

    /// Verdicts on expectations written as in a scenario, against the run so far.
    async fn check(&mut self, text: &str) -> Result<Vec<Verdict>> {
        const FILE: &str = "the expectations";
        let expect: Vec<Expect> = if text.trim_start().starts_with('[') {
            nodes::parse_ron(FILE, text)?
        } else {
            vec![nodes::parse_ron(FILE, text)?]
        };
        let h = self.running.harvester().clone();
        let checks = scenario::resolve_expectations(FILE, &h, self.running.node_ids(), &expect)
            .map_err(|problems| Error::Config(nodes::Error::Invalid(problems)))?;
        let snap = self.running.hub.send(GetSnapshot).await?;
        let monitor = self
            .running
            .node("F5")
            .zip(self.running.display.as_ref().map(|d| d.borrow().tally));
        let books = Books::gather(&snap, monitor, None);
        Ok(scenario::check_all(&checks, &self.running, &snap, &books, &[]))
    }

    async fn act(&mut self, text: &str) -> Result<()> {
        let action: Action = nodes::parse_ron("the action", text)?;
        let index = self.acted;
        self.acted += 1;
        let step = Step {
            at_s: self.running.now().as_secs_f64(),
            action,
        };
        // The same resolution as a scenario's step, against the nodes on the bus now.
        let plan = scenario::resolve_action("the action", self.running.node_ids(), index, &step)
            .map_err(|problems| Error::Config(nodes::Error::Invalid(problems)))?;
        for (at, todo) in plan.todo {
            match todo {
                Todo::Act { index, act, .. } => self.actions.act(&mut self.running, index, act).await?,
                Todo::EndRule(index) => self.ends.push((at, End::Rule(index))),
                Todo::EndBabble => self.ends.push((at, End::Babble)),
            }
        }
        Ok(())
    }
}
