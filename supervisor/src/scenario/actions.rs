//! Timeline actions carried out on the running harvester: bus faults through the hub, sensor
//! faults through the node interface ([`NodeLogic::inject`](bus::node::NodeLogic::inject)),
//! plant inputs, crashes and power cycles.
//!
//! Contract: an action, resolved before the run ([`Act`]), takes effect at the bus time the run
//! has reached; one the harvester cannot carry out ends the run with an error. A fault a node's logic refuses is bad input
//! (exit code 2), named with the scenario's file, the timeline step, the node and the fault.

use super::babbler::Babblers;
use super::plan::Act;
use crate::Error;
use crate::harvester::Running;
use bus::engine::{DisturbCounts, Rule, RuleId};
use bus::node::NodeFault;
use bus_runtime::hub::{Control, GetDisturbCounts, Submit};
use bus_runtime::node::Inject;
use std::collections::BTreeMap;

/// What the actions so far left running: error rules until their end, and the babblers.
pub(crate) struct Actions {
    /// The scenario's file, for errors.
    file: String,
    /// Rules by timeline entry, so that its `until_s` removes them.
    rules: BTreeMap<usize, RuleId>,
    /// Every disturbance rule installed, by timeline entry (for its hits and misses).
    disturbs: Vec<(usize, RuleId)>,
    babblers: Babblers,
}

impl Actions {
    /// None yet, for the scenario in `file`.
    pub(crate) fn new(file: String) -> Actions {
        Actions {
            file,
            rules: BTreeMap::new(),
            disturbs: Vec::new(),
            babblers: Babblers::default(),
        }
    }

    /// Carries out timeline entry `index`, resolved.
    pub(crate) async fn act(&mut self, running: &mut Running, index: usize, act: Act) -> crate::Result<()> {
        let control = |c: Control| async { running.hub.send(c).await?.map(drop).map_err(crate::Error::from) };
        match act {
            Act::Rule(rule) => return self.add_rule(running, index, rule).await,
            Act::Ack(n, on) => control(Control::SetAck(n, on)).await?,
            Act::Connect(n, on) => control(Control::SetConnected(n, on)).await?,
            Act::Hang(n, on) => control(Control::SetHung(n, on)).await?,
            Act::Crash(n) => running.crash(&n).await?,
            Act::Babble(frame) => self.babblers.start(running, frame).await?,
            Act::Send(node, frame) => drop(running.hub.send(Submit { node, frame }).await??),
            Act::Inject { node, fault } => {
                let at = format!("{}: timeline[{index}]", self.file);
                inject(running, &at, &node, fault).await?
            }
            Act::Plant { input, value } => {
                let now = running.now();
                running.plant.borrow_mut().set_input_at(now, &input, value)?;
            }
            Act::PowerCycle => running.power_cycle().await?,
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
        let disturb = matches!(rule.effect, bus::engine::Effect::Disturb(_));
        if let Some(r) = running.hub.send(Control::AddRule(rule)).await?? {
            self.rules.insert(index, r);
            if disturb {
                self.disturbs.push((index, r));
            }
        }
        Ok(())
    }

    /// Hits and misses of every disturbance the timeline installed, by timeline entry.
    pub(crate) async fn disturbed(&self, running: &Running) -> crate::Result<Vec<(usize, DisturbCounts)>> {
        let ids = self.disturbs.iter().map(|(_, id)| *id).collect();
        let counts = running.hub.send(GetDisturbCounts(ids)).await?;
        Ok(self
            .disturbs
            .iter()
            .zip(counts)
            .filter_map(|((index, _), c)| c.map(|c| (*index, c)))
            .collect())
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

#[cfg(test)]
mod tests;
