//! The emulated harvester: its config file, and the assembly of hub, plant, monitor and the 20
//! scripted nodes.

use crate::BadInput;
use actix::prelude::*;
use bus::bits::BitRate;
use bus::engine::{BusConfig, ControllerConfig, Filter, NodeId};
use bus::filter::{CAN_EFF_FLAG, SocketCanFilter, SocketCanFilterSet};
use bus::hub::{Attach, Hub, HubConfig, RunUntil};
use bus::ident::Address;
use bus::node::NodeActor;
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

fn problem(file: &str, field: &str, message: impl Into<String>) -> Problem {
    Problem {
        file: file.to_string(),
        position: None,
        node: None,
        field: Some(field.to_string()),
        message: message.into(),
    }
}

impl Harvester {
    /// Reads and checks a harvester config and every script it names; every problem is
    /// reported at once.
    pub fn load(path: &Path) -> Result<Harvester, Error> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: file.clone(),
            source,
        })?;
        let config: HarvesterConfig = nodes::parse_ron(&file, &text)?;
        let mut problems = Vec::new();
        if BitRate::new(config.bitrate)
            .and_then(|r| r.exact_bit_time_ns())
            .is_none()
        {
            problems.push(problem(
                &file,
                "bitrate",
                format!("{} bit/s: use 125000, 250000, 500000 or 1000000", config.bitrate),
            ));
        }
        if config.nodes.is_empty() {
            problems.push(problem(&file, "nodes", "no nodes"));
        }
        if config.monitor.calibration_samples == 0 {
            problems.push(problem(
                &file,
                "monitor.calibration_samples",
                "must be at least 1",
            ));
        }
        problems.extend(
            nodes::environment::validate_plant(&config.plant)
                .into_iter()
                .map(|(field, m)| problem(&file, &format!("plant.{field}"), m)),
        );
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut scripts = Vec::new();
        let signals = nodes::environment::PlantSignals;
        for (i, rel) in config.nodes.iter().enumerate() {
            match nodes::script::load(&dir.join(rel), &signals) {
                Ok(s) => scripts.push(s),
                Err(Error::Invalid(p)) => problems.extend(p),
                Err(Error::Io { path, source }) => problems.push(problem(
                    &file,
                    &format!("nodes[{i}]"),
                    format!("cannot read {path}: {source}"),
                )),
            }
        }
        let mut seen = std::collections::BTreeMap::new();
        for s in &scripts {
            if s.address == Address::MONITOR.0 {
                problems.push(problem(
                    &file,
                    "nodes",
                    format!("{} takes the monitor's address F5", s.name),
                ));
            }
            if let Some(other) = seen.insert(s.address, s.name.clone()) {
                problems.push(problem(
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

    /// The time at which the field nodes power up.
    pub fn relay(&self) -> BusTime {
        BusTime::from_millis(self.config.time_relay_ms)
    }
}

/// Turns a config error into bad input for the command line.
pub fn bad(e: Error) -> anyhow::Error {
    BadInput(e.to_string()).into()
}

/// A controller that keeps frames addressed to `me`.
fn controller(name: &str, me: Address) -> ControllerConfig {
    let filter = SocketCanFilterSet(vec![SocketCanFilter::new(
        CAN_EFF_FLAG | (u32::from(me.0) << 8),
        CAN_EFF_FLAG | 0xFF00,
    )]);
    ControllerConfig::named(name).with_filter(Filter::SocketCan(filter))
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
    let mut nodes = Vec::new();
    let mut display = None;
    if c.monitor.enabled {
        let monitor = Monitor::new(c.monitor.clone());
        display = Some(monitor.display());
        let actor = NodeActor::new("F5", Box::new(monitor)).start();
        let id = hub
            .send(Attach {
                controller: controller("F5", Address::MONITOR),
                node: Some(actor.recipient()),
                reaction: Duration::from_micros(c.monitor.reaction_us),
            })
            .await?;
        nodes.push(("F5".to_string(), id));
    }
    // Start-up as in the source: the monitor first, then the time relay starts every node.
    hub.send(RunUntil(h.relay())).await??;
    for script in &h.scripts {
        let env: SharedEnv = plant.clone();
        let name = script.name.clone();
        let address = Address(script.address);
        let seed = c.seed ^ (u64::from(script.address) << 32);
        let logic = ScriptedNode::new(script.clone(), env, h.relay(), seed);
        let actor = NodeActor::new(name.clone(), Box::new(logic)).start();
        let id = hub
            .send(Attach {
                controller: controller(&name, address),
                node: Some(actor.recipient()),
                reaction: Duration::from_micros(c.reaction_us),
            })
            .await?;
        nodes.push((name, id));
    }
    Ok(Running {
        hub,
        plant,
        nodes,
        display,
    })
}
