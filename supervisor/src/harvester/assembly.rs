//! Putting a harvester together on a hub: each node's controllers and logic, the monitor at
//! once and the field nodes at the time relay, and running the bus to a time.

use super::{Harvester, SupervisorEvent};
use actix::prelude::*;
use bus::bits::BitRate;
use bus::engine::{BusConfig, ControllerConfig, Filter, NodeId};
use bus::filter::SocketCanFilterSet;
use bus::time::{BusDuration, BusTime};
use bus::trace::Sink;
use bus_runtime::hub::{AttachControllers, Hub, HubConfig, RunUntil};
use bus_runtime::node::NodeActor;
use nodes::firmware::{FirmwareNode, FirmwareSpec};
use nodes::monitor::{DisplayHandle, Monitor};
use nodes::plant::{Plant, PlantHandle};
use nodes::script::{NodeScript, ScriptedNode, SharedEnv};
use protocol::ident::Address;
use std::cell::RefCell;
use std::rc::Rc;
use std::sync::Arc;
use std::time::Duration;

/// A node's controllers: a field node's as its script declares it; the monitor's keeps every
/// extended frame addressed to it (a PC-side CAN interface filtering on the destination byte); a
/// firmware node has one for each of its chips.
fn controllers(name: &str, spec: &Spec) -> crate::Result<Vec<ControllerConfig>> {
    let filter = match spec {
        Spec::Monitor => Filter::SocketCan(SocketCanFilterSet(vec![protocol::ident::to_node_filter(
            Address::MONITOR,
        )])),
        // Each controller is a chip's: it filters itself, and leaves bus off when the firmware
        // says so (an SJA1000) or by itself (the AT89C51CC03's). A node without a chip still has
        // one on the bus, which its firmware never takes out of reset.
        Spec::Firmware(f) => {
            let chip = |k: usize, by_itself: bool| ControllerConfig {
                recovery: if by_itself {
                    bus::engine::Recovery::Automatic
                } else {
                    bus::engine::Recovery::OnRequest
                },
                ..ControllerConfig::handing_over(f.controller_name(k))
            };
            if f.chips.is_empty() {
                return Ok(vec![chip(0, false)]);
            }
            return Ok(f
                .chips
                .iter()
                .enumerate()
                .map(|(k, c)| chip(k, c.recovers_by_itself()))
                .collect());
        }
        // Loaded scripts have been validated, so this only fails for a script built in code.
        Spec::Script(script) => script.filter.to_filter().map_err(|problems| {
            let what: Vec<String> = problems
                .iter()
                .map(|p| format!("filter{}: {}", p.field, p.message))
                .collect();
            crate::Error::BadInput(format!("node {name}: {}", what.join("; ")))
        })?,
    };
    Ok(vec![ControllerConfig::named(name).with_filter(filter)])
}

/// What a node is rebuilt from.
#[derive(Clone)]
pub(super) enum Spec {
    Monitor,
    Script(Box<NodeScript>),
    Firmware(Arc<FirmwareSpec>),
}

/// One supervised node.
pub(super) struct Member {
    pub(super) name: String,
    pub(super) id: NodeId,
    pub(super) spec: Spec,
    pub(super) actor: Addr<NodeActor>,
    pub(super) restarts: Vec<BusTime>,
    pub(super) restart_at: Option<BusTime>,
    pub(super) down: bool,
}

/// Where lines of text go, one call each.
pub type LineSink = Rc<RefCell<dyn FnMut(&str)>>;

/// An instruction trace asked for (`harvemu run --trace-cpu`): the node, the window, and where
/// its lines go. A node rebuilt after a crash or a power cycle is traced again.
#[derive(Clone)]
pub struct CpuTraceRequest {
    /// The firmware node.
    pub node: String,
    /// First instant traced.
    pub from: BusTime,
    /// Last instant traced.
    pub to: BusTime,
    /// Takes each line.
    pub out: LineSink,
}

/// A harvester running on a hub.
pub struct Running {
    /// The hub.
    pub hub: Addr<Hub>,
    /// The plant.
    pub plant: PlantHandle,
    /// Controller ids by name, monitor first: a node's, and a firmware node's further chips' as
    /// `NAME.k` ([`FirmwareSpec::controller_name`]).
    pub nodes: Vec<(String, NodeId)>,
    /// The monitor's display, when the monitor is emulated.
    pub display: Option<DisplayHandle>,
    /// Crashes, restarts and power cycles so far.
    pub events: Vec<SupervisorEvent>,
    pub(super) harvester: Harvester,
    pub(super) members: Vec<Member>,
    pub(super) now: BusTime,
    /// When the time relay powers up the field nodes, until they are attached.
    pub(super) field_nodes_at: Option<BusTime>,
    /// An instruction trace of a firmware node, set before the field nodes are attached.
    pub cpu_trace: Option<CpuTraceRequest>,
    /// Code coverage of the firmware nodes, when [`Harvester::coverage`] asks for it
    /// ([`crate::coverage`]); [`Running::end_coverage`] gives it.
    pub coverage: Option<crate::coverage::SharedCollector>,
    /// Crashes the hub has told of ([`Hub::crashes`]), and how many supervision has looked at:
    /// a stop with none new and no restart due needs no look at the hub.
    pub(super) crashes: std::sync::Arc<std::sync::atomic::AtomicU64>,
    pub(super) crashes_seen: u64,
}

pub(super) fn build(
    h: &Harvester,
    spec: &Spec,
    plant: &PlantHandle,
    display: &Option<DisplayHandle>,
    power_on: BusTime,
    cpu_trace: Option<&CpuTraceRequest>,
    coverage: Option<&crate::coverage::SharedCollector>,
) -> Box<dyn bus::node::NodeLogic> {
    match spec {
        Spec::Monitor => {
            let display = display.clone().unwrap_or_default();
            let relay = h.relay();
            let expected = h
                .expected
                .iter()
                .map(|(_, a, boot_ms)| (*a, relay.saturating_add(BusDuration::from_millis(*boot_ms))));
            Box::new(Monitor::with_display(h.config.monitor.clone(), display, power_on).expecting(expected))
        }
        Spec::Firmware(spec) => {
            let env: SharedEnv = plant.clone();
            let seed =
                h.config.network.seed ^ (u64::from(spec.address.unwrap_or(0)) << 32) ^ power_on.as_nanos();
            let mut node = FirmwareNode::new(spec.clone(), power_on, f64::from(h.config.network.bitrate))
                .with_plant(env, seed);
            if let Some(c) = coverage {
                node = node.with_coverage(c.counts_for(spec));
            }
            if let Some(t) = cpu_trace.filter(|t| t.node == spec.name) {
                let out = t.out.clone();
                node.trace_cpu(nodes::firmware::CpuTrace {
                    from: t.from,
                    to: t.to,
                    sink: Box::new(move |line| (out.borrow_mut())(line)),
                });
            }
            Box::new(node)
        }
        Spec::Script(script) => {
            let env: SharedEnv = plant.clone();
            // A DBC network's nodes have no address: their names tell their randomness apart.
            let own = if script.database.is_some() {
                name_seed(&script.name)
            } else {
                u64::from(script.address) << 32
            };
            let seed = h.config.network.seed ^ own ^ power_on.as_nanos();
            Box::new(ScriptedNode::new((**script).clone(), env, power_on, seed))
        }
    }
}

/// A number from a node's name (FNV-1a), the same on every run.
fn name_seed(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// Builds the harvester on a new hub and runs it through start-up: the monitor from time 0, the
/// field nodes from the time relay on. Must run inside an actix system. `paced`: in real time
/// (else virtual time, as fast as the nodes answer; see [`HubConfig::paced`]).
pub async fn start(h: &Harvester, paced: bool, sinks: Vec<Box<dyn Sink>>) -> crate::Result<Running> {
    let mut running = begin(h, paced, sinks).await?;
    running.run_until(h.relay()).await?;
    Ok(running)
}

/// Builds the harvester on a new hub at time 0 with the monitor attached, its trace going to
/// `sinks`; the field nodes are
/// attached when [`Running::run_until`] reaches the time relay. Start-up is thus an ordinary
/// stretch of the run, which a caller can stop at any moment (a huge time relay, a signal).
pub async fn begin(h: &Harvester, paced: bool, sinks: Vec<Box<dyn Sink>>) -> crate::Result<Running> {
    let c = &h.config;
    let bitrate = BitRate::new(c.network.bitrate)
        .ok_or_else(|| crate::Error::BadInput(format!("bit rate {}", c.network.bitrate)))?;
    let mut hub_config = HubConfig {
        bus: BusConfig {
            bitrate,
            seed: c.network.seed,
            latency_class: protocol::ident::latency_class,
        },
        ..HubConfig::new(paced)
    };
    if let Some(epoch) = h.epoch {
        hub_config.epoch = epoch;
    }
    let hub = Hub::new(hub_config, sinks)?;
    let crashes = hub.crashes();
    let hub = hub.start();
    let plant: PlantHandle = Rc::new(RefCell::new(Plant::new(c.plant.clone(), c.network.seed)));
    let display: Option<DisplayHandle> = c.monitor.enabled.then(DisplayHandle::default);
    let mut running = Running {
        hub,
        plant,
        nodes: Vec::new(),
        display,
        events: Vec::new(),
        harvester: h.clone(),
        members: Vec::new(),
        now: BusTime::ZERO,
        field_nodes_at: Some(h.relay()),
        cpu_trace: None,
        coverage: h.coverage.then(Default::default),
        crashes,
        crashes_seen: 0,
    };
    if c.monitor.enabled {
        running
            .attach("F5", Spec::Monitor, c.monitor.reaction_us, BusTime::ZERO)
            .await?;
    }
    Ok(running)
}

impl Running {
    /// The DBC database of a network imported from one (its scripts name it), for showing its
    /// frames by name; `None` for the harvester.
    pub fn database(&self) -> Option<&protocol::database::Database> {
        self.harvester.scripts.iter().find_map(|s| s.db.as_deref())
    }

    async fn attach(
        &mut self,
        name: &str,
        spec: Spec,
        reaction_us: u64,
        power_on: BusTime,
    ) -> crate::Result<()> {
        let controllers = controllers(name, &spec)?;
        let logic = build(
            &self.harvester,
            &spec,
            &self.plant,
            &self.display,
            power_on,
            self.cpu_trace.as_ref(),
            self.coverage.as_ref(),
        );
        let actor = NodeActor::new(name, logic).start();
        let names: Vec<String> = controllers.iter().map(|c| c.name.clone()).collect();
        let ids = self
            .hub
            .send(AttachControllers {
                controllers,
                node: Some(actor.clone().recipient()),
                reaction: Duration::from_micros(reaction_us),
            })
            .await??;
        let id = ids
            .first()
            .copied()
            .ok_or(bus_runtime::Error::Bus(bus::Error::NoControllers))?;
        self.nodes.extend(names.into_iter().zip(ids));
        self.members.push(Member {
            name: name.to_string(),
            id,
            spec,
            actor,
            restarts: Vec::new(),
            restart_at: None,
            down: false,
        });
        Ok(())
    }

    /// The nodes on the bus now, with their ids (a firmware node's first controller's), in the
    /// order they were attached.
    pub fn node_ids(&self) -> Vec<(String, NodeId)> {
        self.members.iter().map(|m| (m.name.clone(), m.id)).collect()
    }

    /// The node called `name`.
    pub fn node(&self, name: &str) -> Option<NodeId> {
        self.members.iter().find(|m| m.name == name).map(|m| m.id)
    }

    /// The actor of the node called `name` (for fault injection).
    pub fn actor(&self, name: &str) -> Option<Addr<NodeActor>> {
        self.members
            .iter()
            .find(|m| m.name == name)
            .map(|m| m.actor.clone())
    }

    /// Each firmware node's hardware at bus time `at` (where its last input left it, run on to
    /// `at`), by name in config order; a node whose actor is gone is left out.
    pub async fn hardware(&self, at: BusTime) -> Vec<(String, bus::node::HardwareState)> {
        let mut states = Vec::new();
        for m in self
            .members
            .iter()
            .filter(|m| matches!(m.spec, Spec::Firmware(_)))
        {
            if let Ok(Some(state)) = m.actor.send(bus_runtime::node::ReadHardware(at)).await {
                states.push((m.name.clone(), state));
            }
        }
        states
    }

    /// Tells the node an instruction trace follows ([`Running::cpu_trace`]) that the run ends at
    /// `at`, so that its trace reaches the end: a node is traced as its wakes move it on, and
    /// one idling in a loop is woken seldom.
    pub async fn end_cpu_trace(&self, at: BusTime) {
        let Some(trace) = &self.cpu_trace else {
            return;
        };
        for m in self.members.iter().filter(|m| m.name == trace.node) {
            // A node whose actor is gone has no trace to end.
            let _ = m.actor.send(bus_runtime::node::RunEnds(at)).await;
        }
    }

    /// Tells every firmware node that the run ends at `at`, so that its counts reach it, and
    /// gives the run's coverage; `None` when coverage is off.
    pub async fn end_coverage(&self, at: BusTime) -> Option<crate::coverage::Coverage> {
        let collector = self.coverage.as_ref()?;
        for m in self
            .members
            .iter()
            .filter(|m| matches!(m.spec, Spec::Firmware(_)))
        {
            // A node whose actor is gone counted what it ran already.
            let _ = m.actor.send(bus_runtime::node::RunEnds(at)).await;
        }
        Some(collector.take())
    }

    /// The harvester (or network) it runs.
    pub fn harvester(&self) -> &Harvester {
        &self.harvester
    }

    /// Bus time reached.
    pub fn now(&self) -> BusTime {
        self.now
    }

    /// Runs the bus to `until`, looking after crashed nodes on the way: the hub stops at a crash,
    /// at every restart that falls due and at the time relay, where the field nodes are attached
    /// (as in the source: the monitor first, then the time relay starts every node).
    pub async fn run_until(&mut self, until: BusTime) -> crate::Result<()> {
        self.run_until_or(until, |_| false).await
    }

    /// [`Running::run_until`], but back early, where the hub stopped for a node or an observer
    /// that asked ([`bus::node::NodeLogic::stop_here`], [`bus::schedule::Heard::StopThere`]),
    /// once `done` says so at the bus time reached.
    pub async fn run_until_or(
        &mut self,
        until: BusTime,
        done: impl Fn(BusTime) -> bool,
    ) -> crate::Result<()> {
        loop {
            if self.field_nodes_at.is_some_and(|t| t <= self.now) {
                self.attach_field_nodes().await?;
            }
            if self.now >= until || done(self.now) {
                return Ok(());
            }
            // The hub stops early by itself when a node crashes or asks to (`done` then says
            // whether to go on); restarts are due at known times.
            let next = self
                .members
                .iter()
                .filter_map(|m| m.restart_at)
                .chain(self.field_nodes_at)
                .fold(until, BusTime::min)
                .max(self.now);
            self.now = self.hub.send(RunUntil(next)).await??;
            self.supervise().await?;
        }
    }

    async fn attach_field_nodes(&mut self) -> crate::Result<()> {
        let Some(relay) = self.field_nodes_at.take() else {
            return Ok(());
        };
        let h = self.harvester.clone();
        for script in &h.scripts {
            let spec = Spec::Script(Box::new(script.clone()));
            self.attach(&script.name, spec, h.config.network.reaction_us, relay)
                .await?;
        }
        // A firmware node's reaction is its own code's: the hub hands it everything at once.
        for f in &h.firmware {
            self.attach(&f.name, Spec::Firmware(f.clone()), 0, relay).await?;
        }
        Ok(())
    }
}
