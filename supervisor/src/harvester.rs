//! The emulated harvester: its config file, and the assembly of hub, plant, monitor and the 20
//! scripted nodes.

use crate::BadInput;
use actix::prelude::*;
use bus::bits::BitRate;
use bus::engine::{BusConfig, ControllerConfig, Filter, NodeId};
use bus::filter::{CAN_EFF_FLAG, SocketCanFilter, SocketCanFilterSet};
use bus::hub::{Attach, GetCrashed, Hub, HubConfig, Replace, RunUntil};
use bus::ident::Address;
use bus::node::{Crash, NodeActor};
use bus::time::BusTime;
use nodes::monitor::{DisplayHandle, Monitor, MonitorConfig};
use nodes::plant::{Plant, PlantConfig, PlantHandle};
use nodes::script::{NodeScript, ScriptedNode, SharedEnv};
use nodes::{Error, Problem};
use serde::Deserialize;
use std::cell::RefCell;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Duration;

/// `configs/harvester.ron`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Harvester")]
pub struct HarvesterConfig {
    /// Machine name.
    pub name: String,
    /// Bit rate, bit/s: 125000, 250000, 500000 or 1000000.
    pub bitrate: u32,
    /// The run's seed.
    pub seed: u64,
    /// Delay from monitor power-up to field-node power-up, ms.
    pub time_relay_ms: u64,
    /// Reaction time of the field nodes, µs.
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
    pub path: PathBuf,
    /// The config.
    pub config: HarvesterConfig,
    /// The node scripts, in config order.
    pub scripts: Vec<NodeScript>,
}

impl Harvester {
    /// Reads and checks a harvester config and every script it names; every problem is
    /// reported at once. Each file is read with [`nodes::file::read_text`]: at most
    /// [`nodes::file::MAX_FILE`] bytes.
    pub fn load(path: &Path) -> Result<Harvester, Error> {
        let text = nodes::file::read_text(path)?;
        let signals = nodes::environment::PlantSignals;
        Harvester::from_text(path, &text, |script| nodes::script::load(script, &signals))
    }

    /// As [`Harvester::load`] with the config's text already read: `path` is where it came from
    /// (problems name it; node scripts are relative to its directory) and `script` reads, parses
    /// and validates the node script at a path, as [`nodes::script::load`] does.
    pub fn from_text(
        path: &Path,
        text: &str,
        mut script: impl FnMut(&Path) -> Result<NodeScript, Error>,
    ) -> Result<Harvester, Error> {
        let file = path.display().to_string();
        let config: HarvesterConfig = nodes::parse_ron(&file, text)?;
        let mut problems = Vec::new();
        if BitRate::new(config.bitrate)
            .and_then(|r| r.exact_bit_time_ns())
            .is_none()
        {
            problems.push(Problem::at(
                &file,
                "bitrate",
                format!("{} bit/s: use 125000, 250000, 500000 or 1000000", config.bitrate),
            ));
        }
        if config.nodes.is_empty() {
            problems.push(Problem::at(&file, "nodes", "no nodes"));
        }
        if config.monitor.calibration_samples == 0 {
            problems.push(Problem::at(
                &file,
                "monitor.calibration_samples",
                "must be at least 1",
            ));
        }
        problems.extend(
            nodes::environment::validate_plant(&config.plant)
                .into_iter()
                .map(|(field, m)| Problem::at(&file, format!("plant.{field}"), m)),
        );
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut scripts = Vec::new();
        for (i, rel) in config.nodes.iter().enumerate() {
            match script(&dir.join(rel)) {
                Ok(s) => scripts.push(s),
                Err(Error::Invalid(p)) => problems.extend(p),
                Err(Error::Io { path, source }) => problems.push(Problem::at(
                    &file,
                    format!("nodes[{i}]"),
                    format!("cannot read {path}: {source}"),
                )),
            }
        }
        let mut seen = std::collections::BTreeMap::new();
        for s in &scripts {
            if s.address == Address::MONITOR.0 {
                problems.push(Problem::at(
                    &file,
                    "nodes",
                    format!("{} takes the monitor's address F5", s.name),
                ));
            }
            if let Some(other) = seen.insert(s.address, s.name.clone()) {
                problems.push(Problem::at(
                    &file,
                    "nodes",
                    format!("{} and {other} both have address {:02X}", s.name, s.address),
                ));
            }
        }
        if problems.is_empty() {
            Ok(Harvester {
                path: path.to_path_buf(),
                config,
                scripts,
            })
        } else {
            Err(Error::Invalid(problems))
        }
    }

    /// Leaves nodes out (a real device takes each one's place); "F5" is the monitor.
    pub fn without(&mut self, names: &[String]) -> Result<(), Error> {
        let mut problems = Vec::new();
        for n in names {
            if n == "F5" {
                self.config.monitor.enabled = false;
            } else if let Some(i) = self.scripts.iter().position(|s| &s.name == n) {
                self.scripts.remove(i);
            } else {
                let file = self.path.display().to_string();
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

/// Turns a config error into bad input for the command line. A default config (`configs/...`,
/// relative to the working directory) that is not there gets told how to point at one: an
/// installed harvemu run outside the repository does not find its defaults.
pub fn bad(e: Error) -> anyhow::Error {
    let hint = match &e {
        Error::Io { path, source }
            if source.kind() == std::io::ErrorKind::NotFound && path.starts_with("configs/") =>
        {
            DEFAULT_CONFIG_HINT
        }
        _ => "",
    };
    BadInput(format!("{e}{hint}")).into()
}

/// The controller of a node: a field node's as its script declares it; the monitor's keeps every
/// extended frame addressed to it (a PC-side CAN interface filtering on the destination byte).
fn controller(name: &str, spec: &Spec) -> anyhow::Result<ControllerConfig> {
    let filter = match spec {
        Spec::Monitor => Filter::SocketCan(SocketCanFilterSet(vec![SocketCanFilter::new(
            CAN_EFF_FLAG | (u32::from(Address::MONITOR.0) << 8),
            CAN_EFF_FLAG | 0xFF00,
        )])),
        // Loaded scripts have been validated, so this only fails for a script built in code.
        Spec::Script(script) => script.filter.to_filter().map_err(|problems| {
            let what: Vec<String> = problems
                .iter()
                .map(|p| format!("filter{}: {}", p.field, p.message))
                .collect();
            BadInput(format!("node {name}: {}", what.join("; ")))
        })?,
    };
    Ok(ControllerConfig::named(name).with_filter(filter))
}

/// Appended to "configs/...: No such file or directory".
pub const DEFAULT_CONFIG_HINT: &str = "; the default configs are read from configs/ in the \
     current directory: run harvemu in the harvemu repository, or give a config's path \
     (`harvemu run PATH/harvester.ron`, `--config FILE` for replay, dbc and bench, \
     `harvemu soak PATH/soak_24h.ron`)";

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
    /// What happened: `crashed: ...`, `restarted`, `gave up ...`, `power cycle`.
    pub what: String,
}

/// What a node is rebuilt from.
#[derive(Clone)]
enum Spec {
    Monitor,
    Script(Box<NodeScript>),
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

/// A harvester running on a hub.
pub struct Running {
    /// The hub.
    pub hub: Addr<Hub>,
    /// The plant.
    pub plant: PlantHandle,
    /// Node ids by name, monitor first.
    pub nodes: Vec<(String, NodeId)>,
    /// The monitor's display, when the monitor is emulated.
    pub display: Option<DisplayHandle>,
    /// Crashes, restarts and power cycles so far.
    pub events: Vec<SupervisorEvent>,
    harvester: Harvester,
    members: Vec<Member>,
    now: BusTime,
}

fn build(
    h: &Harvester,
    spec: &Spec,
    plant: &PlantHandle,
    display: &Option<DisplayHandle>,
    power_on: BusTime,
) -> Box<dyn bus::node::NodeLogic> {
    match spec {
        Spec::Monitor => {
            let display = display.clone().unwrap_or_default();
            Box::new(Monitor::with_display(h.config.monitor.clone(), display, power_on))
        }
        Spec::Script(script) => {
            let env: SharedEnv = plant.clone();
            let seed = h.config.seed ^ (u64::from(script.address) << 32) ^ power_on.as_nanos();
            Box::new(ScriptedNode::new((**script).clone(), env, power_on, seed))
        }
    }
}

/// Builds the harvester on a new hub and runs it through start-up: the monitor from time 0, the
/// field nodes from the time relay on. Must run inside an actix system.
pub async fn start(h: &Harvester, trace: Option<Box<dyn Write>>) -> anyhow::Result<Running> {
    let c = &h.config;
    let bitrate = BitRate::new(c.bitrate).ok_or_else(|| BadInput(format!("bit rate {}", c.bitrate)))?;
    let hub_config = HubConfig {
        bus: BusConfig {
            bitrate,
            seed: c.seed,
        },
        ..HubConfig::default()
    };
    let hub = Hub::new(hub_config, trace)?.start();
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
    };
    if c.monitor.enabled {
        running
            .attach("F5", Spec::Monitor, c.monitor.reaction_us, BusTime::ZERO)
            .await?;
    }
    // Start-up as in the source: the monitor first, then the time relay starts every node.
    running.hub.send(RunUntil(h.relay())).await??;
    running.now = h.relay();
    for script in &h.scripts {
        let spec = Spec::Script(Box::new(script.clone()));
        running
            .attach(&script.name, spec, c.reaction_us, h.relay())
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
    ) -> anyhow::Result<()> {
        let controller = controller(name, &spec)?;
        let logic = build(&self.harvester, &spec, &self.plant, &self.display, power_on);
        let actor = NodeActor::new(name, logic).start();
        let id = self
            .hub
            .send(Attach {
                controller,
                node: Some(actor.clone().recipient()),
                reaction: Duration::from_micros(reaction_us),
            })
            .await?;
        self.nodes.push((name.to_string(), id));
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

    /// Bus time reached.
    pub fn now(&self) -> BusTime {
        self.now
    }

    /// Runs the bus to `until`, looking after crashed nodes on the way: the hub stops at a crash,
    /// and at every restart that falls due.
    pub async fn run_until(&mut self, until: BusTime) -> anyhow::Result<()> {
        while self.now < until {
            // The hub stops early by itself when a node crashes; restarts are due at known times.
            let next = self
                .members
                .iter()
                .filter_map(|m| m.restart_at)
                .fold(until, BusTime::min)
                .max(self.now);
            self.now = self.hub.send(RunUntil(next)).await??;
            self.supervise().await?;
        }
        Ok(())
    }

    /// Notes crashes and restarts what is due, by the restart policy.
    async fn supervise(&mut self) -> anyhow::Result<()> {
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
                    what: format!("crashed: {why}"),
                });
                let window = BusTime((policy.window_s * 1e9) as u64).as_nanos();
                m.restarts
                    .retain(|t| now.as_nanos().saturating_sub(t.as_nanos()) < window);
                if m.restarts.len() as u32 >= policy.max_restarts {
                    m.down = true;
                    let what = format!(
                        "gave up after {} restarts in {} s",
                        m.restarts.len(),
                        policy.window_s
                    );
                    self.events.push(SupervisorEvent {
                        at: now,
                        node: m.name.clone(),
                        what,
                    });
                } else {
                    m.restart_at = Some(now + policy.backoff_ms.saturating_mul(1_000_000));
                }
            }
        }
        for i in 0..self.members.len() {
            if self.members[i].restart_at.is_some_and(|t| t <= now) {
                self.restart(i, now).await?;
                self.events.push(SupervisorEvent {
                    at: now,
                    node: self.members[i].name.clone(),
                    what: "restarted".into(),
                });
            }
        }
        Ok(())
    }

    /// Rebuilds node `i` from its spec: a new actor with new logic that powers on at
    /// `power_on`, behind the node's controller (which is reset).
    async fn rebuild(&mut self, i: usize, power_on: BusTime) -> anyhow::Result<()> {
        let logic = build(
            &self.harvester,
            &self.members[i].spec,
            &self.plant,
            &self.display,
            power_on,
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
    async fn restart(&mut self, i: usize, now: BusTime) -> anyhow::Result<()> {
        self.rebuild(i, now).await?;
        self.members[i].restarts.push(now);
        Ok(())
    }

    /// Makes a node's logic crash at its next wake.
    pub async fn crash(&self, name: &str) -> anyhow::Result<()> {
        let actor = self
            .actor(name)
            .ok_or_else(|| anyhow::anyhow!("no node {name}"))?;
        actor.send(Crash).await?;
        Ok(())
    }

    /// Switches the whole machine off and on: every node is rebuilt and boots again (the monitor
    /// at once, the field nodes after the time relay), every controller is reset.
    pub async fn power_cycle(&mut self) -> anyhow::Result<()> {
        let now = self.now;
        self.events.push(SupervisorEvent {
            at: now,
            node: "*".into(),
            what: "power cycle".into(),
        });
        let relay = now + self.harvester.config.time_relay_ms.saturating_mul(1_000_000);
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
