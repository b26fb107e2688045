//! The one error type of the supervisor, and the exit code each kind of error gives.
//!
//! Contract: every variant belongs to one of three kinds, which [`Error::exit_code`] tells
//! apart: bad input (exit code 2: [`Error::BadInput`], [`Error::Config`], [`Error::Interface`],
//! [`Error::Input`]), an output that failed (exit code 3: [`Error::Output`]), and harvemu's own
//! failure (exit code 70: the rest). A variant's message says what and where; an I/O error is
//! kept as the [`source`](std::error::Error::source), not in the message, and [`Report`] prints
//! the message followed by each cause (`message: cause: cause`), as `harvemu` shows it.

use crate::exit;
use std::fmt;
use std::io;
use thiserror::Error;

/// Every way a `harvemu` command can fail.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum Error {
    /// The user's arguments, config, scenario or trace are wrong: one line naming what and where.
    #[error("{0}")]
    BadInput(String),
    /// A harvester config, node script or scenario with problems, or one that could not be read.
    /// Not a [`source`](std::error::Error::source): `nodes::Error` already says its cause.
    #[error("{0}")]
    Config(nodes::Error),
    /// A CAN interface (`--iface`) that cannot be opened. Its message says what to do about it;
    /// the system's reason stays inside, as the runtime error's source.
    #[error("{0}")]
    Interface(bus_runtime::Error),
    /// An input file (a trace to replay) could not be opened.
    #[error("cannot open {}", .path.display())]
    Input {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: io::Error,
    },
    /// An output (trace, report, JUnit XML, DBC, exported config, standard output) could not
    /// be created or written completely.
    #[error("cannot {verb} {what}")]
    Output {
        /// What failed: `create` or `write`.
        verb: &'static str,
        /// The file or stream, as the user named it (`standard output` for that).
        what: String,
        /// Why.
        #[source]
        source: io::Error,
    },
    /// The runtime failed: a hub that could not start, a gateway that could not listen.
    #[error(transparent)]
    Runtime(#[from] bus_runtime::Error),
    /// The core refused something harvemu built itself.
    #[error(transparent)]
    Bus(#[from] bus::Error),
    /// The protocol refused something harvemu built itself (a priority out of range).
    #[error(transparent)]
    Protocol(#[from] protocol::Error),
    /// An actor is gone (the run is ending or one failed), so it could not answer.
    #[error(transparent)]
    Mailbox(#[from] actix::MailboxError),
    /// The system refused what harvemu needs to run (signal handling, the terminal).
    #[error(transparent)]
    System(io::Error),
    /// The plant refused an input a scenario set (scenarios are checked against it before).
    #[error(transparent)]
    Plant(#[from] nodes::plant::PlantError),
    /// A measurement or report that would not encode as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// Any other failure of harvemu itself (a thread that died, a node that did not answer).
    #[error("{0}")]
    Internal(String),
}

/// The supervisor's result.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// The exit code this error gives: [`exit::BAD_INPUT`], [`exit::OUTPUT_FAILED`] or
    /// [`exit::INTERNAL`].
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::BadInput(_) | Error::Config(_) | Error::Interface(_) | Error::Input { .. } => {
                exit::BAD_INPUT
            }
            // The address is the user's: in use, not on this machine, or not theirs to take.
            Error::Runtime(bus_runtime::Error::Listen { .. }) => exit::BAD_INPUT,
            Error::Output { .. } => exit::OUTPUT_FAILED,
            // Neither the input's fault nor an output's: an actor gone, a runtime that could
            // not start, a bug.
            Error::Runtime(_)
            | Error::Bus(_)
            | Error::Protocol(_)
            | Error::Mailbox(_)
            | Error::System(_)
            | Error::Json(_)
            | Error::Plant(_)
            | Error::Internal(_) => exit::INTERNAL,
        }
    }

    /// The error followed by its causes: what `harvemu` prints.
    pub fn report(&self) -> Report<'_> {
        Report(self)
    }
}

impl From<nodes::Error> for Error {
    fn from(e: nodes::Error) -> Error {
        Error::Config(e)
    }
}

/// An error and its chain of causes, `message: cause: cause`.
pub struct Report<'a>(&'a Error);

impl fmt::Display for Report<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)?;
        let mut cause = std::error::Error::source(self.0);
        while let Some(c) = cause {
            write!(f, ": {c}")?;
            cause = c.source();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_report_says_each_cause_once() {
        let missing = || io::Error::from_raw_os_error(2);
        let input = Error::Input {
            path: "t.log".into(),
            source: missing(),
        };
        assert_eq!(
            input.report().to_string(),
            "cannot open t.log: No such file or directory (os error 2)"
        );
        // nodes::Error says its cause itself: the report does not repeat it.
        let config = Error::from(nodes::Error::Io {
            path: "h.ron".into(),
            source: missing(),
        });
        assert_eq!(
            config.report().to_string(),
            "h.ron: No such file or directory (os error 2)"
        );
        assert_eq!(config.exit_code(), exit::BAD_INPUT);
        let listen = Error::from(bus_runtime::Error::Listen {
            addr: "127.0.0.1:1".parse().unwrap(),
            source: io::Error::from_raw_os_error(98),
        });
        assert_eq!(
            listen.report().to_string(),
            "cannot listen on 127.0.0.1:1: Address already in use (os error 98)"
        );
        assert_eq!(listen.exit_code(), exit::BAD_INPUT);
    }
}
