//! Looking after the nodes while the harvester runs: crashes seen, restarts by the restart
//! policy, nodes given up, injected crashes and power cycles, each told as a [`SupervisorEvent`].

use super::Running;
use super::assembly::{Spec, build};
use actix::prelude::*;
use bus::node::CrashCause;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::{GetCrashed, Replace};
use bus_runtime::node::{Crash, NodeActor};

/// A crash, restart or power cycle, for traces' readers and reports.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SupervisorEvent {
    /// Bus time.
    pub at: BusTime,
    /// The node ("*" for the whole machine).
    pub node: String,
    /// What happened.
    pub what: Happened,
}

/// What the supervisor saw or did; `Display` gives the text outputs show.
#[derive(Clone, Debug, PartialEq)]
pub enum Happened {
    /// The node's logic crashed: `crashed: why`.
    Crashed(CrashCause),
    /// The supervisor restarted it.
    Restarted,
    /// It crashed more often than the restart policy allows, and stays down.
    GaveUp {
        /// Restarts within the window.
        restarts: usize,
        /// The policy's window, seconds.
        window_s: f64,
    },
    /// The whole machine was switched off and on.
    PowerCycle,
    /// A crash was asked for while the node was down already.
    NotCrashedDown,
}

impl Happened {
    /// A crash that fault injection did not ask for.
    pub fn is_own_crash(&self) -> bool {
        matches!(self, Happened::Crashed(c) if *c != CrashCause::Injected)
    }
}

impl std::fmt::Display for Happened {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Happened::Crashed(why) => write!(f, "crashed: {why}"),
            Happened::Restarted => f.write_str("restarted"),
            Happened::GaveUp { restarts, window_s } => {
                write!(f, "gave up after {restarts} restarts in {window_s} s")
            }
            Happened::PowerCycle => f.write_str("power cycle"),
            Happened::NotCrashedDown => f.write_str("not crashed: it is down"),
        }
    }
}

/// Written as its text, as outputs show it.
impl serde::Serialize for Happened {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl Running {
    /// The nodes that crashed more often than the restart policy allows and stay down, when the
    /// crash that put them down was not injected on purpose ([`Running::crash`]).
    pub fn down_by_themselves(&self) -> Vec<String> {
        let mut down = Vec::new();
        for m in self.members.iter().filter(|m| m.down) {
            let last_crash = self
                .events
                .iter()
                .rev()
                .find(|e| e.node == m.name && matches!(e.what, Happened::Crashed(_)));
            if last_crash.is_some_and(|e| e.what.is_own_crash()) {
                down.push(m.name.clone());
            }
        }
        down
    }

    /// Notes crashes and restarts what is due, by the restart policy.
    pub(super) async fn supervise(&mut self) -> crate::Result<()> {
        let now = self.now;
        let told = self.crashes.load(std::sync::atomic::Ordering::Acquire);
        let due = self
            .members
            .iter()
            .any(|m| m.restart_at.is_some_and(|t| t <= now));
        if told == self.crashes_seen && !due {
            return Ok(());
        }
        self.crashes_seen = told;
        let crashed = self.hub.send(GetCrashed).await?;
        let policy = self.harvester.config.network.restart.clone();
        for m in &mut self.members {
            let why = crashed
                .iter()
                .find(|(id, _)| *id == m.id)
                .map(|(_, why)| why.clone());
            if let Some(why) = why
                && m.restart_at.is_none()
                && !m.down
            {
                self.events.push(SupervisorEvent {
                    at: now,
                    node: m.name.clone(),
                    what: Happened::Crashed(why),
                });
                let window = BusDuration::from_nanos((policy.window_s * 1e9) as u64);
                m.restarts.retain(|t| now - *t < window);
                if m.restarts.len() as u32 >= policy.max_restarts {
                    m.down = true;
                    self.events.push(SupervisorEvent {
                        at: now,
                        node: m.name.clone(),
                        what: Happened::GaveUp {
                            restarts: m.restarts.len(),
                            window_s: policy.window_s,
                        },
                    });
                } else {
                    m.restart_at = Some(now + BusDuration::from_millis(policy.backoff_ms));
                }
            }
        }
        for i in 0..self.members.len() {
            if self.members[i].restart_at.is_some_and(|t| t <= now) {
                self.restart(i, now).await?;
                self.events.push(SupervisorEvent {
                    at: now,
                    node: self.members[i].name.clone(),
                    what: Happened::Restarted,
                });
            }
        }
        Ok(())
    }

    /// Rebuilds node `i` from its spec: a new actor with new logic that powers on at
    /// `power_on`, behind the node's controller (which is reset).
    async fn rebuild(&mut self, i: usize, power_on: BusTime) -> crate::Result<()> {
        let logic = build(
            &self.harvester,
            &self.members[i].spec,
            &self.plant,
            &self.display,
            power_on,
            self.cpu_trace.as_ref(),
            self.coverage.as_ref(),
        );
        // The node it replaces counts what it ran up to now.
        if self.coverage.is_some() && matches!(self.members[i].spec, Spec::Firmware(_)) {
            let _ = self.members[i]
                .actor
                .send(bus_runtime::node::RunEnds(self.now))
                .await;
        }
        let actor = NodeActor::new(self.members[i].name.clone(), logic).start();
        self.hub
            .send(Replace {
                node: self.members[i].id,
                actor: actor.clone().recipient(),
            })
            .await??;
        let m = &mut self.members[i];
        m.actor = actor;
        m.restart_at = None;
        Ok(())
    }

    /// Restarts a crashed node now, counting the restart against the policy.
    async fn restart(&mut self, i: usize, now: BusTime) -> crate::Result<()> {
        self.rebuild(i, now).await?;
        self.members[i].restarts.push(now);
        Ok(())
    }

    /// Makes a node's logic crash at its next wake. A node that is down already (crashed and
    /// not restarted yet, or given up) has nothing to crash: that is noted as an event.
    pub async fn crash(&mut self, name: &str) -> crate::Result<()> {
        let m = self
            .members
            .iter()
            .find(|m| m.name == name)
            .ok_or_else(|| crate::Error::BadInput(format!("no node {name} on the bus")))?;
        if m.down || m.restart_at.is_some() || !m.actor.connected() {
            self.events.push(SupervisorEvent {
                at: self.now,
                node: name.into(),
                what: Happened::NotCrashedDown,
            });
            return Ok(());
        }
        m.actor.send(Crash).await?;
        Ok(())
    }

    /// Switches the whole machine off and on: every node is rebuilt and boots again (the monitor
    /// at once, the field nodes after the time relay), every controller is reset.
    pub async fn power_cycle(&mut self) -> crate::Result<()> {
        let now = self.now;
        self.events.push(SupervisorEvent {
            at: now,
            node: "*".into(),
            what: Happened::PowerCycle,
        });
        let relay = now + BusDuration::from_millis(self.harvester.config.time_relay_ms);
        for i in 0..self.members.len() {
            let power_on = if matches!(self.members[i].spec, Spec::Monitor) {
                now
            } else {
                relay
            };
            self.rebuild(i, power_on).await?;
            self.members[i].down = false;
        }
        Ok(())
    }
}
