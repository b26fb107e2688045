//! Node logic of the emulated harvester: the behaviour-script interpreter that runs every field
//! node, the plant model the nodes sample, and the monitor, all as sans-IO state machines driven
//! by bus time and frames.
//!
//! Contract: nothing here reads a clock, does I/O (except [`file::read_text`], which reads
//! configs, scripts, templates and scenarios up to [`file::MAX_FILE`], and [`script::load`] and
//! [`script::disk`], which use it; [`script::expand`] reads a template only through the reader
//! its caller passes) or draws randomness except
//! from generators seeded by the run's seed and the node.
//! Bad scripts give [`Error`] listing every problem with file, node and field.
#![warn(missing_docs)]

pub mod environment;
mod error;
pub mod file;
pub mod firmware;
pub mod monitor;
pub mod plant;
pub mod ron_path;
pub mod script;

pub use error::{Error, Problem, parse_ron};
