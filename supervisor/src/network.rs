//! A plain CAN network, the base of every bus harvemu runs: a bit rate and node files
//! (behaviour scripts or firmware), a seed and a restart policy. A `Network(...)` file is one on
//! its own, for benches such as the lab in `configs/firmware/`; the harvester
//! ([`crate::harvester::HarvesterConfig`]) is a network with the monitor, the time relay and
//! the plant around it.

use serde::Deserialize;

/// `Network(name: "seed lab", bitrate: 30000, nodes: ["sender.ron", "receiver.ron"])`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Network")]
pub struct NetworkConfig {
    /// Name of the network (of the machine, for a harvester).
    pub name: String,
    /// Bit rate, bit/s: 10000 to 1000000, with an exact bit time on the bus clock
    /// (`BitRate::RULE`: 30000, 125000, 250000, 500000 and 1000000 among them).
    pub bitrate: u32,
    /// Node files, relative to this file (or absolute).
    pub nodes: Vec<String>,
    /// The run's seed (scripts' randomness, the injection generator, the plant).
    #[serde(default)]
    pub seed: u64,
    /// Reaction time of scripted nodes, µs (at most
    /// [`crate::harvester::MAX_REACTION_US`]; firmware nodes react in their own code).
    #[serde(default = "reaction")]
    pub reaction_us: u64,
    /// How crashed nodes are restarted.
    #[serde(default)]
    pub restart: RestartPolicy,
}

fn reaction() -> u64 {
    100
}

/// How crashed nodes are restarted (the `restart` section of a network or harvester config).
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
