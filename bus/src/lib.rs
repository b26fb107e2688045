//! The pure core of harvemu: everything about a CAN bus that can be said without a clock, a
//! socket or an actor.
//!
//! Contract:
//! - [`Frame`] is a classic CAN 2.0 frame (data or remote, base or extended, DLC 0–8) on the
//!   `embedded-can` identifier types; [`Frame::arbitration`] orders frames exactly as the bus
//!   arbitrates them.
//! - [`bits`] produces the exact stuffed bitstream of a frame, its CRC-15 and its length, so that
//!   bus time can be kept in bit times.
//! - [`filter`] holds acceptance filters as the SJA1000, the AT89C51CC family and SocketCAN apply them.
//! - [`fault`] is the TEC/REC fault-confinement state machine.
//! - [`engine`] is the bit-exact bus: arbitration, stuffing, errors, fault confinement and
//!   statistics, in bus time, driven by its caller.
//! - [`node::NodeLogic`] is the sans-IO contract every emulated node implements, and
//!   [`node::drive`] feeds it one wake's inputs.
//! - [`time`] is bus time and the epoch that stamps it onto wall-clock dates.
//! - [`trace`] formats the engine's events as candump lines.
//! - [`candump`] reads and writes the `ID#DATA` frame notation of can-utils.
//! - [`tracefile`] reads candump logs and Vector ASC traces, and writes ASC.
//! - [`schedule::Scheduler`] runs the engine and wakes the nodes at their deadlines and inputs:
//!   the hub's whole policy (reaction times, buffering, register-level wakes, crashes, hangs,
//!   trace order), stepped by a driver that gives it the wall clock and carries its wakes.
//! - [`pacing`] decides when a real-time hub commits bus time, and the overrun policy (bus time
//!   slips after a stall instead of bursting); it is given the wall clock, it does not read it.
//! - [`sja1000`] is the SJA1000 stand-alone CAN controller at register level (BasicCAN and
//!   PeliCAN), sans-IO: a CPU reads and writes its registers, the bus answers its actions.
//! - [`at89c51cc`] is the AT89C51CC03's on-chip CAN controller at register level (15 message
//!   objects behind CANPAGE), sans-IO, speaking the same [`sja1000::Action`] and
//!   [`sja1000::BusSide`] as the SJA1000.
//! - [`text::quote`] cuts input quoted in error messages to a few dozen characters.
//!
//! Nothing here does I/O, reads a clock, runs an async runtime or an actor, or panics on input;
//! fallible input gives [`Error`]. A test (`tests/pure.rs`) checks over `cargo metadata` that no
//! async runtime, actor framework or socket crate is among this crate's dependencies. The
//! runtime (hub actor, node actor, wall timer, socketcand gateway, SocketCAN) is the
//! `bus-runtime` crate; the harvester's own protocol is the `protocol` crate.
#![warn(missing_docs)]

pub mod at89c51cc;
pub mod bits;
pub mod candump;
pub mod engine;
mod error;
pub mod fault;
pub mod filter;
mod frame;
pub mod node;
pub mod pacing;
pub mod schedule;
pub mod sja1000;
pub mod text;
pub mod time;
pub mod trace;
pub mod tracefile;

pub use embedded_can::{ExtendedId, Id, StandardId};
pub use error::Error;
pub use frame::{ArbitrationKey, Frame, extended_id, standard_id};
