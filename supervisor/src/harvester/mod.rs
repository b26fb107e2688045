//! The emulated harvester: its config file (`config`), the assembly of hub, plant, monitor and
//! the 20 scripted nodes (`assembly`), and the supervision of the running nodes
//! (`supervision`).

mod assembly;
mod config;
mod supervision;

pub use assembly::{CpuTraceRequest, LineSink, Running, begin, start};
pub use config::{Harvester, HarvesterConfig, MAX_REACTION_US, NodeFile, RestartPolicy};
pub use supervision::{Happened, SupervisorEvent};
