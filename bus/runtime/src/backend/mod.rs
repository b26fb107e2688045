//! Real interfaces for the emulated bus.

pub mod socketcan;
