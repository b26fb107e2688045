//! The harvester's CAN protocol, apart from any bus or node: what its frames mean.
//!
//! Contract:
//! - [`ident::AppId`] is the 29-bit application identifier (priority | frame type | destination |
//!   source) with `parse`/`emit`; [`ident::Address`] names the nodes; [`ident::latency_class`]
//!   sorts frames into the engine's latency classes by that priority.
//! - [`catalogue`] is the one list of every harvester message; decoding, the monitor and the DBC
//!   export all read it.
//! - [`database`] reads a DBC file into a network's messages and signals, for networks that are
//!   not the harvester.
//!
//! Nothing here does I/O or panics on input; fallible input gives [`Error`].
#![warn(missing_docs)]

pub mod catalogue;
pub mod database;
mod error;
pub mod ident;

pub use error::Error;
