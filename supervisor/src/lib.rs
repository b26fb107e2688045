//! The harvemu supervisor: the command line and the pieces of it that tests drive in-process.
//!
//! Contract: every command fails with one [`Error`]: bad input as [`Error::BadInput`],
//! [`Error::Config`] or [`Error::Input`] (one line, exit code 2), an output that cannot be
//! created or written as [`Error::Output`] naming the file (exit code 3), and never panics on
//! either; any other error is harvemu's own (exit code 70). [`exit`] turns a command's end into
//! the documented exit code.

pub mod bench;
pub mod campaign;
pub mod configs;
pub mod convert;
pub mod coverage;
pub mod dbc;
pub mod error;
pub mod exit;
pub mod harvester;
pub mod import;
pub mod inspect;
pub mod network;
pub mod output;
pub mod realtime;
pub mod record;
pub mod replay;
pub mod report;
pub mod run;
pub mod say;
pub mod scenario;
pub mod scenarios_cli;
pub mod session;
pub mod soak;
pub mod stop;
pub mod traces;
pub mod tui;

pub use error::{Error, Result};
