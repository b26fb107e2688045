use std::net::SocketAddr;
use thiserror::Error;

/// Every way the runtime can fail: the core's refusals, and the outside world's.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum Error {
    /// The core refused a configuration, a frame or a request (a bad bit rate, an unknown node,
    /// a node without controllers).
    #[error(transparent)]
    Bus(#[from] bus::Error),
    /// The hub actor is gone (the run is ending), so it could not answer.
    #[error("the hub stopped")]
    HubStopped,
    /// The socketcand gateway could not listen on its address.
    #[error("cannot listen on {addr}")]
    Listen {
        /// The address asked for.
        addr: SocketAddr,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A SocketCAN interface could not be opened or set up; `hint` says what to do about it.
    #[error("cannot open CAN interface {iface}{hint}")]
    Interface {
        /// The interface's name.
        iface: String,
        /// Advice for the user, empty or starting with "; ".
        hint: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// Some other I/O failed: `what` was being done.
    #[error("{what}")]
    Io {
        /// What was being done.
        what: &'static str,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

impl From<actix::MailboxError> for Error {
    fn from(_: actix::MailboxError) -> Error {
        Error::HubStopped
    }
}
