//! A plain CAN network instead of the harvester: a bit rate and node files (behaviour scripts
//! or firmware), with no monitor and no time relay, for benches such as the lab in
//! `configs/firmware/`.

use crate::harvester::{HarvesterConfig, RestartPolicy};
use nodes::monitor::MonitorConfig;
use serde::Deserialize;

/// `Network(name: "seed lab", bitrate: 30000, nodes: ["sender.ron", "receiver.ron"])`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Network")]
pub struct NetworkConfig {
    /// Name of the network.
    pub name: String,
    /// Bit rate, bit/s, as the harvester's.
    pub bitrate: u32,
    /// Node files, relative to this file (or absolute).
    pub nodes: Vec<String>,
    /// The run's seed (scripts' randomness, the injection generator).
    #[serde(default)]
    pub seed: u64,
    /// Reaction time of scripted nodes, µs (firmware nodes react in their own code).
    #[serde(default = "reaction")]
    pub reaction_us: u64,
    /// How crashed nodes are restarted.
    #[serde(default)]
    pub restart: RestartPolicy,
}

fn reaction() -> u64 {
    100
}

impl From<NetworkConfig> for HarvesterConfig {
    /// A harvester config without the monitor, whose nodes power up at once.
    fn from(n: NetworkConfig) -> HarvesterConfig {
        HarvesterConfig {
            name: n.name,
            bitrate: n.bitrate,
            seed: n.seed,
            time_relay_ms: 0,
            reaction_us: n.reaction_us,
            monitor: MonitorConfig {
                enabled: false,
                ..MonitorConfig::default()
            },
            nodes: n.nodes,
            plant: Default::default(),
            restart: n.restart,
        }
    }
}
