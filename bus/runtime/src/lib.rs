//! The bus at run time: the pure core of the `bus` crate given a clock, actors and sockets.
//!
//! Contract:
//! - [`hub::Hub`] is the actor that drives the scheduler ([`bus::schedule::Scheduler`], which owns
//!   the engine and decides every wake): it carries each wake to the node's actor and the answer
//!   back, and gives the scheduler the wall clock, paced (real time, with the overrun policy of
//!   [`bus::pacing`]) or not at all (virtual time, as fast as the nodes answer).
//! - [`node::NodeActor`] drives one sans-IO [`bus::node::NodeLogic`]; a panic in the logic is
//!   caught and reported to the hub as a crash, never taking the process down.
//! - [`gateway`] serves the hub to socketcand clients (python-can's `socketcand` interface) over
//!   TCP, raw and BCM mode.
//! - `backend::socketcan` (feature `socketcan`, Linux) bridges the hub to a SocketCAN interface.
//!
//! Failures are [`Error`]s with their `io::Error` as source; nothing here panics on input.
#![warn(missing_docs)]

#[cfg(feature = "socketcan")]
pub mod backend;
mod error;
pub mod gateway;
pub mod hub;
pub mod node;
mod wall_timer;

pub use error::Error;
