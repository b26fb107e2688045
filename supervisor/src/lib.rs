//! The harvemu supervisor: the command line and the pieces of it that tests drive in-process.
//!
//! Contract: every command reports bad input as a [`BadInput`] error (one line, exit code 2) and
//! never panics on it.

pub mod bench;
pub mod dbc;
pub mod harvester;
pub mod inspect;
pub mod realtime;
pub mod record;
pub mod replay;
pub mod report;
pub mod run;
pub mod scenario;
pub mod scenarios_cli;
pub mod soak;
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
