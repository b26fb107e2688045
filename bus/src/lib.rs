//! The pure core of harvemu: everything about a CAN bus that can be said without a clock, a
//! socket or an actor.
//!
//! Contract:
//! - [`Frame`] is a classic CAN 2.0 frame (data or remote, base or extended, DLC 0–8) on the
//!   `embedded-can` identifier types; [`Frame::arbitration`] orders frames exactly as the bus
//!   arbitrates them.
//! - [`ident::AppId`] is the harvester's 29-bit application identifier (priority | frame type |
//!   destination | source) with `parse`/`emit`; [`ident::Address`] names the nodes.
//! - [`bits`] produces the exact stuffed bitstream of a frame, its CRC-15 and its length, so that
//!   bus time can be kept in bit times.
//! - [`filter`] holds the acceptance filters of the controllers the harvester uses.
//! - [`fault`] is the TEC/REC fault-confinement state machine.
//! - [`catalogue`] is the one list of every harvester message; decoding, the monitor and the DBC
//!   export all read it.
//! - [`candump`] reads and writes the `ID#DATA` frame notation of can-utils.
//! - [`tracefile`] reads candump logs and Vector ASC traces, and writes ASC.
//! - [`pacing`] decides when a real-time hub commits bus time, and the overrun policy (bus time
//!   slips after a stall instead of bursting); it is given the wall clock, it does not read it.
//! - [`text::quote`] cuts input quoted in error messages to a few dozen characters.
//!
//! Nothing here does I/O, reads a clock or panics on input; fallible input gives [`Error`].
#![warn(missing_docs)]

pub mod backend;
pub mod bits;
pub mod candump;
pub mod catalogue;
pub mod engine;
mod error;
pub mod fault;
pub mod filter;
mod frame;
pub mod gateway;
pub mod hub;
pub mod ident;
pub mod node;
pub mod pacing;
pub mod text;
pub mod time;
pub mod trace;
pub mod tracefile;
mod wall_timer;

pub use embedded_can::{ExtendedId, Id, StandardId};
pub use error::Error;
pub use frame::{ArbitrationKey, Frame};
