//! The emulated harvester: its config file, and the assembly of hub, plant, monitor and the 20
//! scripted nodes.

use crate::configs::Source;
use actix::prelude::*;
use bus::bits::BitRate;
use bus::engine::{BusConfig, ControllerConfig, Filter, NodeId};
use bus::filter::SocketCanFilterSet;
use bus::node::CrashCause;
use bus::time::{BusDuration, BusTime};
use bus::trace::Sink;
use bus_runtime::hub::{AttachControllers, GetCrashed, Hub, HubConfig, Replace, RunUntil};
use bus_runtime::node::{Crash, NodeActor};
use nodes::firmware::{FirmwareNode, FirmwareSpec};
use nodes::monitor::{DisplayHandle, Monitor, MonitorConfig};
use nodes::plant::{Plant, PlantConfig, PlantHandle};
use nodes::script::{NodeScript, ScriptedNode, SharedEnv};
use nodes::{Error, Problem};
use protocol::ident::Address;
use serde::Deserialize;
use std::cell::RefCell;
use std::path::Path;
use std::rc::Rc;
use std::sync::Arc;
use std::time::Duration;

/// `configs/harvester.ron`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Harvester")]
pub struct HarvesterConfig {
    /// Machine name.
    pub name: String,
    /// Bit rate, bit/s: 10000 to 1000000, with an exact bit time on the bus clock
    /// (`BitRate::RULE`: 30000, 125000, 250000, 500000 and 1000000 among them).
    pub bitrate: u32,
    /// The run's seed.
    pub seed: u64,
    /// Delay from monitor power-up to field-node power-up, ms.
    pub time_relay_ms: u64,
    /// Reaction time of the field nodes, µs (at most [`MAX_REACTION_US`]).
    pub reaction_us: u64,
    /// The monitor.
    #[serde(default)]
    pub monitor: MonitorConfig,
    /// Node script files, relative to the config file.
    pub nodes: Vec<String>,
    /// The plant.
    #[serde(default)]
    pub plant: PlantConfig,
    /// How crashed nodes are restarted.
    #[serde(default)]
    pub restart: RestartPolicy,
}

/// A loaded, validated harvester.
#[derive(Clone, Debug)]
pub struct Harvester {
    /// Where it was read from.
    pub source: Source,
    /// The config.
    pub config: HarvesterConfig,
    /// The node scripts, in config order.
    pub scripts: Vec<NodeScript>,
    /// The firmware nodes, in config order.
    pub firmware: Vec<Arc<FirmwareSpec>>,
    /// Read from a `Network(...)` file: a plain bus, no harvester around it (no plant signals
    /// worth showing).
    pub network: bool,
    /// Where bus time zero lies on the wall clock in the trace and the gateway's frames; `None`
    /// for the hub's default (the wall clock in real time, [`bus::time::Epoch::FIXED`] in
    /// virtual time). A command that writes the trace itself sets it, so that both agree.
    pub epoch: Option<bus::time::Epoch>,
}

impl Harvester {
    /// Reads and checks a harvester config and every script it names; every problem is
    /// reported at once. `path` is read as [`Source::file`] says: from disk when something is
    /// there, else the built-in copy.
    pub fn load(path: &Path) -> Result<Harvester, Error> {
        Harvester::open(&Source::file(path))
    }

    /// [`Harvester::load`] from a source: each file is read with [`Source::read`] (from disk at
    /// most [`nodes::file::MAX_FILE`] bytes), the node scripts beside the config, in the
    /// built-in tree when the config is built in.
    pub fn open(source: &Source) -> Result<Harvester, Error> {
        let (source, text) = source.read()?;
        let signals = nodes::environment::PlantSignals;
        Harvester::parse(&source, &text, |script| {
            let (found, text) = script.read()?;
            let file = found.to_string();
            if nodes::script::top_name(&text) == Some("Firmware") {
                let spec = nodes::firmware::load(&file, &found.path, &text, &found.reader())?;
                return Ok(NodeFile::Firmware(Arc::new(spec)));
            }
            nodes::script::from_file_text(&file, &found.path, &text, &signals, &found.reader())
                .map(|s| NodeFile::Script(Box::new(s)))
        })
    }

    /// As [`Harvester::load`] with the config's text already read: `path` is where it came from
    /// (problems name it; node scripts are relative to its directory) and `script` reads, parses
    /// and validates the node script at a path, as [`nodes::script::load`] does.
    pub fn from_text(
        path: &Path,
        text: &str,
        mut script: impl FnMut(&Path) -> Result<NodeScript, Error>,
    ) -> Result<Harvester, Error> {
        Harvester::parse(&Source::file(path), text, |s| {
            script(&s.path).map(|s| NodeFile::Script(Box::new(s)))
        })
    }

    fn parse(
        source: &Source,
        text: &str,
        mut script: impl FnMut(&Source) -> Result<NodeFile, Error>,
    ) -> Result<Harvester, Error> {
        let file = source.to_string();
        let network = nodes::script::top_name(text) == Some("Network");
        let config: HarvesterConfig = match nodes::script::top_name(text) {
            Some("Network") => nodes::parse_ron::<crate::network::NetworkConfig>(&file, text)?.into(),
            _ => nodes::parse_ron(&file, text)?,
        };
        let mut problems = Vec::new();
        if BitRate::for_bus(config.bitrate).is_none() {
            problems.push(Problem::at(
                &file,
                "bitrate",
                format!("{} bit/s: {}", config.bitrate, BitRate::RULE),
            ));
        }
        if config.nodes.is_empty() {
            problems.push(Problem::at(&file, "nodes", "no nodes"));
        }
        for (field, us) in [
            ("reaction_us", config.reaction_us),
            ("monitor.reaction_us", config.monitor.reaction_us),
        ] {
            if us > MAX_REACTION_US {
                problems.push(Problem::at(
                    &file,
                    field,
                    format!(
                        "{us} µs is over {MAX_REACTION_US} µs (one second), the longest \
                         interrupt-to-answer time harvemu takes"
                    ),
                ));
            }
        }
        problems.extend(
            config
                .monitor
                .validate()
                .into_iter()
                .map(|(field, m)| Problem::at(&file, format!("monitor.{field}"), m)),
        );
        let restart = &config.restart;
        if !(restart.window_s.is_finite() && restart.window_s >= 0.0) {
            problems.push(Problem::at(
                &file,
                "restart.window_s",
                format!("{} is not a number >= 0", restart.window_s),
            ));
        }
        problems.extend(
            nodes::environment::validate_plant(&config.plant)
                .into_iter()
                .map(|(field, m)| Problem::at(&file, format!("plant.{field}"), m)),
        );
        let mut scripts = Vec::new();
        let mut places = Vec::new();
        let mut firmware = Vec::new();
        let mut firmware_places = Vec::new();
        for (i, rel) in config.nodes.iter().enumerate() {
            match script(&source.beside(rel)) {
                Ok(NodeFile::Script(s)) => {
                    scripts.push(*s);
                    places.push(format!("nodes[{i}] ({rel})"));
                }
                Ok(NodeFile::Firmware(f)) => {
                    firmware.push(f);
                    firmware_places.push(format!("nodes[{i}] ({rel})"));
                }
                Err(Error::Invalid(p)) => problems.extend(p),
                Err(Error::Io { path, source }) => problems.push(Problem::at(
                    &file,
                    format!("nodes[{i}]"),
                    format!("cannot read {path}: {source}"),
                )),
            }
        }
        problems.extend(clashes(&file, &scripts, &places));
        problems.extend(firmware_clashes(
            &file,
            &scripts,
            &places,
            &firmware,
            &firmware_places,
        ));
        if problems.is_empty() {
            Ok(Harvester {
                source: source.clone(),
                config,
                scripts,
                firmware,
                network,
                epoch: None,
            })
        } else {
            Err(Error::Invalid(problems))
        }
    }

    /// Leaves nodes out (a real device takes each one's place); "F5" is the monitor. Names are
    /// unique (loading checks it), so each name leaves out exactly one node.
    pub fn without(&mut self, names: &[String]) -> Result<(), Error> {
        let mut problems = Vec::new();
        for n in names {
            if n == "F5" {
                self.config.monitor.enabled = false;
            } else if let Some(i) = self.scripts.iter().position(|s| &s.name == n) {
                self.scripts.remove(i);
            } else if let Some(i) = self.firmware.iter().position(|f| &f.name == n) {
                self.firmware.remove(i);
            } else {
                let file = self.source.to_string();
                problems.push(Problem::at(
                    &file,
                    "nodes",
                    format!("--without {n}: no such node"),
                ));
            }
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(Error::Invalid(problems))
        }
    }

    /// The time at which the field nodes power up.
    pub fn relay(&self) -> BusTime {
        BusTime::from_millis(self.config.time_relay_ms)
    }
}

/// The longest reaction time a config may give (`reaction_us`, `monitor.reaction_us`): one
/// second. An MCU's interrupt latency is microseconds; far beyond a second a node would answer
/// after the run, and at 2^64 − 1 µs the hub's clock saturates and the node never hears a frame.
pub const MAX_REACTION_US: u64 = 1_000_000;

/// Nodes that would be mistaken for one another: two with one name (`--without`, scenarios and
/// traces pick nodes by name), one named F5 (the monitor's name), two with one address, or one
/// at the monitor's address. `places[i]` says where `scripts[i]` is in the config.
fn clashes(file: &str, scripts: &[NodeScript], places: &[String]) -> Vec<Problem> {
    let mut problems = Vec::new();
    let problem = |s: &NodeScript, place: &str, message: String| Problem {
        file: file.to_string(),
        position: None,
        node: Some(s.name.clone()),
        field: Some(place.to_string()),
        message,
    };
    let mut names = std::collections::BTreeMap::new();
    let mut addresses = std::collections::BTreeMap::new();
    for (s, place) in scripts.iter().zip(places) {
        if s.name == "F5" {
            problems.push(problem(s, place, "F5 is the monitor's name".into()));
        }
        if s.address == Address::MONITOR.0 {
            problems.push(problem(s, place, "takes the monitor's address F5".into()));
        }
        if let Some(other) = names.insert(s.name.as_str(), place) {
            problems.push(problem(
                s,
                place,
                format!("{other} has the same name: every node needs a name of its own"),
            ));
        }
        if let Some((other, name)) = addresses.insert(s.address, (place, &s.name)) {
            problems.push(problem(
                s,
                place,
                format!("{other} (node {name}) has the same address {:02X}", s.address),
            ));
        }
    }
    problems
}

/// What a node file holds: a behaviour script or a firmware node.
pub enum NodeFile {
    /// A behaviour script (or an instance of a template).
    Script(Box<NodeScript>),
    /// A firmware image on an emulated CPU.
    Firmware(Arc<FirmwareSpec>),
}

/// Firmware nodes whose names (or their further chips' names on the bus) clash with each other,
/// with a script's or with the monitor's.
fn firmware_clashes(
    file: &str,
    scripts: &[NodeScript],
    places: &[String],
    firmware: &[Arc<FirmwareSpec>],
    firmware_places: &[String],
) -> Vec<Problem> {
    let mut problems = Vec::new();
    let mut seen: std::collections::BTreeMap<&str, &String> = scripts
        .iter()
        .zip(places)
        .map(|(s, p)| (s.name.as_str(), p))
        .collect();
    for (f, place) in firmware.iter().zip(firmware_places) {
        let problem = |message: String| Problem {
            file: file.to_string(),
            position: None,
            node: Some(f.name.clone()),
            field: Some(place.clone()),
            message,
        };
        if f.name == "F5" {
            problems.push(problem("F5 is the monitor's name".into()));
        }
        if let Some(other) = seen.insert(f.name.as_str(), place) {
            problems.push(problem(format!(
                "{other} has the same name: every node needs a name of its own"
            )));
        }
    }
    // A firmware node's further chips are controllers on the bus with names of their own.
    for (f, place) in firmware.iter().zip(firmware_places) {
        for k in 1..f.chips.len() {
            let chip = f.controller_name(k);
            if let Some(other) = seen.get(chip.as_str()) {
                problems.push(Problem {
                    file: file.to_string(),
                    position: None,
                    node: Some(f.name.clone()),
                    field: Some(place.clone()),
                    message: format!("its controllers[{k}] is {chip} on the bus, the name of {other}"),
                });
            }
        }
    }
    problems
}

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

/// How crashed nodes are restarted (the `restart` section of the harvester config).
#[derive(Clone, Debug, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RestartPolicy {
    /// Restarts allowed within `window_s`; beyond that the node stays down.
    pub max_restarts: u32,
    /// The window, s.
    pub window_s: f64,
    /// Delay from a crash to the restart, ms.
    pub backoff_ms: u64,
}

impl Default for RestartPolicy {
    fn default() -> Self {
        RestartPolicy {
            max_restarts: 3,
            window_s: 60.0,
            backoff_ms: 100,
        }
    }
}

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

/// What a node is rebuilt from.
#[derive(Clone)]
enum Spec {
    Monitor,
    Script(Box<NodeScript>),
    Firmware(Arc<FirmwareSpec>),
}

/// One supervised node.
struct Member {
    name: String,
    id: NodeId,
    spec: Spec,
    actor: Addr<NodeActor>,
    restarts: Vec<BusTime>,
    restart_at: Option<BusTime>,
    down: bool,
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
    harvester: Harvester,
    members: Vec<Member>,
    now: BusTime,
    /// When the time relay powers up the field nodes, until they are attached.
    field_nodes_at: Option<BusTime>,
    /// An instruction trace of a firmware node, set before the field nodes are attached.
    pub cpu_trace: Option<CpuTraceRequest>,
}

fn build(
    h: &Harvester,
    spec: &Spec,
    plant: &PlantHandle,
    display: &Option<DisplayHandle>,
    power_on: BusTime,
    cpu_trace: Option<&CpuTraceRequest>,
) -> Box<dyn bus::node::NodeLogic> {
    match spec {
        Spec::Monitor => {
            let display = display.clone().unwrap_or_default();
            Box::new(Monitor::with_display(h.config.monitor.clone(), display, power_on))
        }
        Spec::Firmware(spec) => {
            let env: SharedEnv = plant.clone();
            let mut node =
                FirmwareNode::new(spec.clone(), power_on, f64::from(h.config.bitrate)).with_plant(env);
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
            let seed = h.config.seed ^ (u64::from(script.address) << 32) ^ power_on.as_nanos();
            Box::new(ScriptedNode::new((**script).clone(), env, power_on, seed))
        }
    }
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
    let bitrate =
        BitRate::new(c.bitrate).ok_or_else(|| crate::Error::BadInput(format!("bit rate {}", c.bitrate)))?;
    let mut hub_config = HubConfig {
        bus: BusConfig {
            bitrate,
            seed: c.seed,
            latency_class: protocol::ident::latency_class,
        },
        ..HubConfig::new(paced)
    };
    if let Some(epoch) = h.epoch {
        hub_config.epoch = epoch;
    }
    let hub = Hub::new(hub_config, sinks)?.start();
    let plant: PlantHandle = Rc::new(RefCell::new(Plant::new(c.plant.clone(), c.seed)));
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
    };
    if c.monitor.enabled {
        running
            .attach("F5", Spec::Monitor, c.monitor.reaction_us, BusTime::ZERO)
            .await?;
    }
    Ok(running)
}

impl Running {
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
        let id = ids.first().copied().ok_or(bus_runtime::Error::NoControllers)?;
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
            let (tx, rx) = std::sync::mpsc::channel();
            let asked = m
                .actor
                .send(bus_runtime::node::Apply(Box::new(move |logic| {
                    let _ = tx.send(logic.hardware(at));
                })))
                .await;
            if let Some(state) = asked.ok().and_then(|()| rx.recv().ok()).flatten() {
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
            let _ = m
                .actor
                .send(bus_runtime::node::Apply(Box::new(move |logic| {
                    logic.run_ends(at)
                })))
                .await;
        }
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
        self.run_until_or(until, || false).await
    }

    /// [`Running::run_until`], but back early, where the hub stopped for a node that asked
    /// ([`bus::node::NodeLogic::stop_here`]), once `done` says so.
    pub async fn run_until_or(&mut self, until: BusTime, done: impl Fn() -> bool) -> crate::Result<()> {
        loop {
            if self.field_nodes_at.is_some_and(|t| t <= self.now) {
                self.attach_field_nodes().await?;
            }
            if self.now >= until || done() {
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
            self.attach(&script.name, spec, h.config.reaction_us, relay)
                .await?;
        }
        // A firmware node's reaction is its own code's: the hub hands it everything at once.
        for f in &h.firmware {
            self.attach(&f.name, Spec::Firmware(f.clone()), 0, relay).await?;
        }
        Ok(())
    }

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
    async fn supervise(&mut self) -> crate::Result<()> {
        let now = self.now;
        let crashed = self.hub.send(GetCrashed).await?;
        let policy = self.harvester.config.restart.clone();
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
        );
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
            .ok_or_else(|| crate::Error::NoNode(name.into()))?;
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

#[cfg(test)]
mod tests {
    use super::*;

    const CONFIG: &str = r#"Harvester(name: "x", bitrate: 250000, seed: 1, time_relay_ms: 500,
        reaction_us: 200, nodes: ["nodes/d0.ron", "nodes/missing.ron"])"#;

    fn real(path: &Path) -> Result<NodeScript, Error> {
        let file = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../configs")
            .join(path);
        nodes::script::load(&file, &nodes::environment::PlantSignals)
    }

    #[test]
    fn from_text_reads_scripts_beside_the_config_through_the_caller() {
        let mut asked = Vec::new();
        let result = Harvester::from_text(Path::new("cfg/harvester.ron"), CONFIG, |p| {
            asked.push(p.to_path_buf());
            real(p.strip_prefix("cfg").unwrap())
        });
        assert_eq!(
            asked,
            [Path::new("cfg/nodes/d0.ron"), Path::new("cfg/nodes/missing.ron")]
        );
        let Err(Error::Invalid(problems)) = result else {
            panic!("a missing script is a problem");
        };
        assert_eq!(problems.len(), 1);
        assert_eq!(problems[0].file, "cfg/harvester.ron");
        assert_eq!(problems[0].field.as_deref(), Some("nodes[1]"));
    }

    /// The config's problems, as text, with scripts read by `script`.
    fn problems(text: &str, script: impl FnMut(&Path) -> Result<NodeScript, Error>) -> Vec<String> {
        match Harvester::from_text(Path::new("h.ron"), text, script) {
            Ok(_) => Vec::new(),
            Err(e) => e
                .to_string()
                .lines()
                .skip(1)
                .map(|l| l.trim().to_string())
                .collect(),
        }
    }

    /// Three scripts: d0.ron as itself, and as copies renamed or readdressed by the file name.
    fn three(p: &Path) -> Result<NodeScript, Error> {
        let mut s = real(Path::new("nodes/d0.ron"))?;
        match p.file_name().and_then(|n| n.to_str()) {
            Some("b.ron") => s.address = 0xD1,
            Some("c.ron") => s.name = "F5".into(),
            _ => {}
        }
        Ok(s)
    }

    const THREE: &str = r#"Harvester(name: "x", bitrate: 250000, seed: 1, time_relay_ms: 500,
        reaction_us: 200, nodes: ["a.ron", "b.ron", "c.ron"])"#;

    /// `--without D0` removed the first D0 and left the other running: names must be unique.
    #[test]
    fn two_nodes_with_one_name_or_address_are_refused_with_both_places() {
        assert_eq!(
            problems(THREE, three),
            [
                "h.ron: node D0: nodes[1] (b.ron): nodes[0] (a.ron) has the same name: every node \
                 needs a name of its own",
                "h.ron: node F5: nodes[2] (c.ron): F5 is the monitor's name",
                "h.ron: node F5: nodes[2] (c.ron): nodes[0] (a.ron) (node D0) has the same address D0",
            ]
        );
    }

    #[test]
    fn a_reaction_time_over_a_second_is_refused() {
        let one = |t: &str| t.replace(r#", "b.ron", "c.ron""#, "");
        assert!(problems(&one(THREE).replace("200", "1000000"), three).is_empty());
        let text = one(THREE).replace(
            "reaction_us: 200",
            "reaction_us: 18446744073709551615, \
            monitor: (reaction_us: 1000001)",
        );
        assert_eq!(
            problems(&text, three),
            [
                "h.ron: reaction_us: 18446744073709551615 µs is over 1000000 µs (one second), \
                 the longest interrupt-to-answer time harvemu takes",
                "h.ron: monitor.reaction_us: 1000001 µs is over 1000000 µs (one second), the \
                 longest interrupt-to-answer time harvemu takes",
            ]
        );
    }

    #[test]
    fn every_rate_with_an_exact_bit_time_is_taken_and_the_message_says_so() {
        let one = THREE.replace(r#", "b.ron", "c.ron""#, "");
        // 30 kbit/s (an 80C51 + SJA1000 board's rate) has a bit time of 33 333.3 ns.
        for ok in [10_000, 30_000, 50_000, 100_000, 125_000, 800_000, 1_000_000] {
            let text = one.replace("250000", &ok.to_string());
            assert!(problems(&text, three).is_empty(), "{ok}");
        }
        // 7 and 33.3 kbit/s have primes other than 2, 3 and 5 in them (7, 37).
        for bad in [0, 7_000, 9_999, 33_300, 70_000, 2_000_000] {
            let text = one.replace("250000", &bad.to_string());
            let p = problems(&text, three);
            assert_eq!(p.len(), 1, "{p:?}");
            assert!(
                p[0].starts_with(&format!("h.ron: bitrate: {bad} bit/s: a bit rate must be 10000 to 1000000 bit/s with a bit time the bus clock holds exactly")),
                "{p:?}"
            );
        }
    }

    /// Values the monitor sends must fit the field that carries them, and the plant input the
    /// receiving node writes them to: otherwise the monitor cannot encode them and stays silent.
    #[test]
    fn monitor_values_outside_what_carries_them_are_refused() {
        let text = THREE.replace(r#", "b.ron", "c.ron""#, "").replace(
            "reaction_us: 200,",
            "reaction_us: 200, monitor: (target_reference: 0, \
             cruise: (min_kmh: 9.0, max_kmh: 20.0, step_kmh: inf)),",
        );
        assert_eq!(
            problems(&text, three),
            [
                "h.ron: monitor.target_reference: 0 is outside 1..=65535, what \
                 flow.calibrate.target_reference and plant input sensor.target_reference can carry",
                "h.ron: monitor.cruise.max_kmh: 20 is outside 0..=12, what speed.setpoint.setpoint \
                 and plant input speed.setpoint can carry",
                "h.ron: monitor.cruise.step_kmh: inf is not a number >= 0",
            ]
        );
        let inverted = THREE.replace(r#", "b.ron", "c.ron""#, "").replace(
            "reaction_us: 200,",
            "reaction_us: 200, monitor: (cruise: (min_kmh: 6.0, max_kmh: 2.0)),",
        );
        assert_eq!(
            problems(&inverted, three),
            ["h.ron: monitor.cruise.min_kmh: 6 is above cruise.max_kmh 2"]
        );
    }

    /// A huge time relay loaded, then overflowed the bus clock when the run computed it.
    #[test]
    fn a_huge_time_relay_is_never_rather_than_an_overflow() {
        let text = CONFIG
            .replace("time_relay_ms: 500", "time_relay_ms: 18446744073709551615")
            .replace(r#", "nodes/missing.ron""#, "");
        let h = Harvester::from_text(Path::new("harvester.ron"), &text, real).unwrap();
        assert_eq!(h.scripts.len(), 1);
        assert_eq!(h.relay(), BusTime::NEVER);
    }
}
