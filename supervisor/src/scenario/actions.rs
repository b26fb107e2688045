//! Timeline actions carried out on the running harvester: bus faults through the hub, sensor
//! faults through the node interface ([`NodeLogic::inject`](bus::node::NodeLogic::inject)),
//! plant inputs, crashes and power cycles.
//!
//! Contract: an action takes effect at the bus time the run has reached; one the harvester
//! cannot carry out ends the run with an error. A fault a node's logic refuses is bad input
//! (exit code 2), named with the scenario's file, the timeline step, the node and the fault.

use super::babbler::Babblers;
use super::model::{Action, ErrorKind, Hits, SeenBy, Target};
use crate::Error;
use crate::harvester::Running;
use bus::candump::parse_frame;
use bus::engine::{BitPosition, Effect, NodeId, Rule, RuleId, Schedule};
use bus::node::NodeFault;
use bus_runtime::hub::{Control, Submit};
use bus_runtime::node::Inject;
use std::collections::BTreeMap;

/// What the actions so far left running: error rules until their end, and the babblers.
pub(crate) struct Actions {
    /// The scenario's file, for errors.
    file: String,
    /// Rules by timeline entry, so that its `until_s` removes them.
    rules: BTreeMap<usize, RuleId>,
    babblers: Babblers,
}

impl Actions {
    /// None yet, for the scenario in `file`.
    pub(crate) fn new(file: String) -> Actions {
        Actions {
            file,
            rules: BTreeMap::new(),
            babblers: Babblers::default(),
        }
    }

    /// Carries out timeline entry `index`.
    pub(crate) async fn act(
        &mut self,
        running: &mut Running,
        index: usize,
        action: Action,
    ) -> crate::Result<()> {
        let id = |n: &str| running.node(n).ok_or_else(|| Error::NoNode(n.into()));
        match action {
            Action::BitErrors {
                target,
                hits,
                kind,
                seen_by,
                ..
            } => {
                let effect = match kind {
                    ErrorKind::Bit => Effect::Bit,
                    ErrorKind::Stuff => Effect::Stuff,
                    ErrorKind::Crc => Effect::Crc,
                    ErrorKind::Form => Effect::Form,
                };
                let seen_by = match seen_by {
                    SeenBy::All => bus::engine::SeenBy::All,
                    SeenBy::Nodes(names) => {
                        bus::engine::SeenBy::Nodes(names.iter().map(|n| id(n)).collect::<Result<_, _>>()?)
                    }
                };
                let rule = Rule {
                    target: engine_target(&target, &id)?,
                    schedule: engine_schedule(hits),
                    bit: BitPosition::Random,
                    effect,
                    seen_by,
                };
                self.add_rule(running, index, rule).await?;
            }
            Action::Overload {
                target,
                hits,
                by,
                frames,
                ..
            } => {
                let seen_by = if by.is_empty() {
                    bus::engine::SeenBy::All
                } else {
                    bus::engine::SeenBy::Nodes(by.iter().map(|n| id(n)).collect::<Result<_, _>>()?)
                };
                let rule = Rule {
                    target: engine_target(&target, &id)?,
                    schedule: engine_schedule(hits),
                    bit: BitPosition::Random,
                    effect: Effect::Overload(frames),
                    seen_by,
                };
                self.add_rule(running, index, rule).await?;
            }
            Action::AckFailure(n) => drop(running.hub.send(Control::SetAck(id(&n)?, false)).await??),
            Action::AckRestored(n) => drop(running.hub.send(Control::SetAck(id(&n)?, true)).await??),
            Action::Disconnect(n) => drop(running.hub.send(Control::SetConnected(id(&n)?, false)).await??),
            Action::Reconnect(n) => drop(running.hub.send(Control::SetConnected(id(&n)?, true)).await??),
            Action::Hang(n) => drop(running.hub.send(Control::SetHung(id(&n)?, true)).await??),
            Action::Resume(n) => drop(running.hub.send(Control::SetHung(id(&n)?, false)).await??),
            Action::Crash(n) => running.crash(&n).await?,
            Action::Babble { frame, .. } => self.babblers.start(running, parse_frame(&frame)?).await?,
            Action::SendFrame { node, frame } => {
                let frame = parse_frame(&frame)?;
                running
                    .hub
                    .send(Submit {
                        node: id(&node)?,
                        frame,
                    })
                    .await??;
            }
            Action::SensorFault { node, signal, fault } => {
                let fault = NodeFault::Sensor {
                    signal,
                    reads: fault.into(),
                };
                let at = format!("{}: timeline[{index}]", self.file);
                inject(running, &at, &node, fault).await?
            }
            Action::SensorRepaired { node, signal } => {
                let at = format!("{}: timeline[{index}]", self.file);
                inject(running, &at, &node, NodeFault::SensorRepaired { signal }).await?
            }
            Action::Plant { input, value } => {
                let now = running.now();
                running.plant.borrow_mut().set_input_at(now, &input, value)?;
            }
            Action::PowerCycle => running.power_cycle().await?,
        }
        Ok(())
    }

    /// Ends the bit errors or overloads of timeline entry `index`, if they still run.
    pub(crate) async fn end_rule(&mut self, running: &Running, index: usize) -> crate::Result<()> {
        if let Some(id) = self.rules.remove(&index) {
            running.hub.send(Control::RemoveRule(id)).await??;
        }
        Ok(())
    }

    /// Ends the flood of a babbling idiot, if one runs.
    pub(crate) async fn end_babble(&mut self, running: &Running) -> crate::Result<()> {
        self.babblers.stop(running).await
    }

    async fn add_rule(&mut self, running: &Running, index: usize, rule: Rule) -> crate::Result<()> {
        if let Some(r) = running.hub.send(Control::AddRule(rule)).await?? {
            self.rules.insert(index, r);
        }
        Ok(())
    }
}

/// Hands a fault to a node's logic, from now on; a refusal is an error naming the step (`at`), the
/// node and the fault.
async fn inject(running: &Running, at: &str, node: &str, fault: NodeFault) -> crate::Result<()> {
    let actor = running
        .actor(node)
        .ok_or_else(|| Error::BadInput(format!("no node {node}")))?;
    let now = running.now();
    let described = describe(&fault);
    let down = || {
        Error::BadInput(format!(
            "{at}: node {node} is down (it crashed and has not restarted yet): cannot apply {described}"
        ))
    };
    if !actor.connected() {
        return Err(down());
    }
    actor
        .send(Inject { fault, now })
        .await
        .map_err(|_| down())?
        .map_err(|refused| Error::BadInput(format!("{at}: node {node} refused {described}: {refused}")))
}

/// A fault in words, for errors.
fn describe(fault: &NodeFault) -> String {
    match fault {
        NodeFault::Sensor { signal, reads } => format!("the sensor fault {reads:?} on {signal}"),
        NodeFault::SensorRepaired { signal } => format!("the repair of the sensor of {signal}"),
    }
}

/// The engine's form of the frames a fault targets.
fn engine_target(
    target: &Target,
    id: &dyn Fn(&str) -> crate::Result<NodeId>,
) -> crate::Result<bus::engine::Target> {
    Ok(match target {
        Target::Any => bus::engine::Target::Any,
        Target::Node(n) => bus::engine::Target::Node(id(n)?),
        Target::Id(text) => bus::engine::Target::Id {
            id: u32::from_str_radix(text, 16).map_err(|e| Error::Internal(e.to_string()))?,
            mask: 0x1FFF_FFFF,
        },
        Target::Priority(p) => {
            let (id, mask) = protocol::ident::Priority::new(*p)?.id_and_mask();
            bus::engine::Target::Id { id, mask }
        }
    })
}

/// The engine's form of which targeted frames are hit.
fn engine_schedule(hits: Hits) -> Schedule {
    match hits {
        Hits::Once => Schedule::Once,
        Hits::EveryNth(n) => Schedule::EveryNth(n),
        Hits::Always => Schedule::Always,
        Hits::BitErrorRate(r) => Schedule::BitErrorRate(r),
    }
}

#[cfg(test)]
mod tests;
