//! Node logic of the emulated harvester: the behaviour of each field node, the plant model they
//! sample and the reference monitor, all as sans-IO state machines driven by `now` and frames.
//!
//! Contract: nothing here reads a clock, does I/O or draws randomness except from a seeded
//! generator handed in. (The node logic arrives with the harvester issue; the crate exists now so
//! that the workspace has its final shape.)
#![warn(missing_docs)]
