//! The harvester's thread: it starts the harvester with the program on its bus, then carries out
//! the session's commands one at a time, until the session is dropped.

use super::program::{Inbox, Program};
use super::{Command, NodeState, Received};
use crate::harvester::{self, Harvester, Running};
use crate::scenario::{Action, Actions};
use crate::{Error, Result};
use actix::prelude::*;
use bus::engine::{ControllerConfig, NodeId};
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::{Attach, Control, GetSnapshot, Submit, runtime};
use bus_runtime::node::NodeActor;
use std::cell::RefCell;
use std::rc::Rc;
use tokio::sync::{mpsc, oneshot};

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
}

/// Runs the harvester's thread (see the module doc).
pub(super) fn drive(
    h: Harvester,
    name: String,
    mut commands: mpsc::UnboundedReceiver<Command>,
    ready: oneshot::Sender<Result<()>>,
) {
    let system = match runtime(true) {
        Ok(rt) => System::with_tokio_rt(move || rt),
        Err(e) => {
            let _ = ready.send(Err(Error::Internal(format!("no runtime: {e}"))));
            return;
        }
    };
    system.block_on(async move {
        let mut d = match Driver::start(&h, name).await {
            Ok(d) => {
                let _ = ready.send(Ok(()));
                d
            }
            Err(e) => {
                let _ = ready.send(Err(e));
                return;
            }
        };
        loop {
            // The next command usually follows at once: look for it awake a little first.
            let mut next = None;
            for _ in 0..20_000 {
                match commands.try_recv() {
                    Ok(c) => {
                        next = Some(c);
                        break;
                    }
                    Err(mpsc::error::TryRecvError::Empty) => std::hint::spin_loop(),
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
    async fn start(h: &Harvester, name: String) -> Result<Driver> {
        let inbox = Rc::new(RefCell::new(Inbox::default()));
        let running = harvester::begin(h, false, Vec::new()).await?;
        let actor = NodeActor::new(name.clone(), Box::new(Program::new(inbox.clone()))).start();
        let id = running
            .hub
            .send(Attach {
                controller: ControllerConfig::named(name),
                node: Some(actor.recipient()),
                reaction: std::time::Duration::ZERO,
            })
            .await?;
        Ok(Driver {
            running,
            id,
            inbox,
            actions: Actions::new("the session".into()),
            acted: 0,
            ends: Vec::new(),
        })
    }

    async fn carry_out(&mut self, c: Command) {
        match c {
            Command::Filters(filters, tx) => {
                self.inbox.borrow_mut().set_filters(filters);
                let _ = tx.send(Ok(()));
            }
            Command::Recv(timeout, tx) => {
                let _ = tx.send(self.recv(timeout).await);
            }
            Command::Send(frame, tx) => {
                let sent = self.running.hub.send(Submit { node: self.id, frame }).await;
                let _ = tx.send(match sent {
                    Ok(Ok(true)) => Ok(()),
                    Ok(Ok(false)) => Err(Error::BadInput(
                        "the program's transmit queue is full: the frame was not sent".into(),
                    )),
                    Ok(Err(e)) => Err(e.into()),
                    Err(e) => Err(e.into()),
                });
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
                let _ = tx.send(snap.map_err(Error::from).map(|s| {
                    s.nodes
                        .iter()
                        .map(|n| NodeState {
                            name: n.name.clone(),
                            state: n.state.to_string(),
                            tec: n.tec,
                            rec: n.rec,
                        })
                        .collect()
                }));
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
            Command::RunFor(seconds, tx) => {
                let end = self.running.now() + BusDuration::from_secs_f64(seconds);
                let ran = self.advance(end, || false).await;
                let _ = tx.send(ran.map(|()| self.running.now().as_secs_f64()));
            }
        }
    }

    async fn poke(&self) -> Result<()> {
        self.running.hub.send(Control::Poke(self.id)).await??;
        Ok(())
    }

    async fn recv(&mut self, timeout: f64) -> Result<Option<Received>> {
        let end = self.running.now() + BusDuration::from_secs_f64(timeout);
        loop {
            if let Some(r) = self.inbox.borrow_mut().pop() {
                return Ok(Some(r));
            }
            if self.running.now() >= end {
                return Ok(None);
            }
            self.inbox.borrow_mut().waiting = true;
            let inbox = self.inbox.clone();
            let waited = self.advance(end, move || !inbox.borrow().is_empty()).await;
            self.inbox.borrow_mut().waiting = false;
            waited?;
        }
    }

    /// Runs to `end`, or until `done`, ending the actions' faults when they fall due.
    async fn advance(&mut self, end: BusTime, done: impl Fn() -> bool) -> Result<()> {
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
            if self.running.now() >= end || done() {
                return Ok(());
            }
        }
    }

    async fn act(&mut self, text: &str) -> Result<()> {
        let action: Action = nodes::parse_ron("the action", text)?;
        let index = self.acted;
        self.acted += 1;
        let ends = match &action {
            Action::BitErrors { until_s: Some(u), .. } | Action::Overload { until_s: Some(u), .. } => {
                Some((*u, End::Rule(index)))
            }
            Action::Babble { until_s, .. } => Some((*until_s, End::Babble)),
            _ => None,
        };
        if let Some((u, _)) = &ends
            && !(u.is_finite() && *u >= 0.0)
        {
            return Err(Error::BadInput(format!("until_s {u} is not a bus time")));
        }
        self.actions.act(&mut self.running, index, action).await?;
        if let Some((u, what)) = ends {
            self.ends.push((BusTime::from_secs_f64(u), what));
        }
        Ok(())
    }
}
