//! The harvemu supervisor: the command line and the pieces of it that tests drive in-process.
//!
//! Contract: every command reports bad input as a [`BadInput`] error (one line, exit code 2),
//! an output that cannot be created or written as an [`OutputFailed`] error naming the file
//! (exit code 3), and never panics on either. [`exit`] turns a command's end into the documented
//! exit code.

pub mod bench;
pub mod configs;
pub mod dbc;
pub mod exit;
pub mod harvester;
pub mod inspect;
pub mod network;
pub mod output;
pub mod realtime;
pub mod record;
pub mod replay;
pub mod report;
pub mod run;
pub mod scenario;
pub mod scenarios_cli;
pub mod soak;
pub mod stop;
pub mod tui;

/// An error that the user caused: reported on one line, exit code 2.
#[derive(Debug)]
pub struct BadInput(pub String);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadInput {}

/// An output (trace, report, JUnit XML, DBC, exported config) that could not be created or
/// written completely: reported on one line naming the file, exit code 3.
#[derive(Debug)]
pub struct OutputFailed(pub String);

impl std::fmt::Display for OutputFailed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for OutputFailed {}
