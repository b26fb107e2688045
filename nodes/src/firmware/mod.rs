//! Firmware nodes: an unmodified 80C51 image (Intel HEX) running on the [`mcs51`] core, with
//! SJA1000 CAN controllers ([`bus::sja1000`]) in its external data space, or on an AT89C51CC03
//! with that chip's own controller ([`bus::at89c51cc`]) behind its SFRs, as a node's logic. Each
//! chip is a controller of its own on the bus; SJA1000 INT outputs wired to one CPU pin pull it
//! low together (open drain). The AT89C51CC03's ADC channels and port pins can be wired to plant
//! signals.
//!
//! Contract: a [`FirmwareNode`] is deterministic: the same image, inputs and input times give
//! the same frames at the same times and the same state, run after run. Its time is its
//! oscillator clocks (12 a machine cycle, 6 in X2 mode), placed exactly on bus time. It reads
//! and writes the controllers' registers as the board would; a controller's requests (join or
//! leave the bus, transmit, abort, counters, bus-off recovery) reach the bus at the clock the
//! firmware made them, and what the bus does reaches the registers at the moment it happens.
//! Wired inputs are read from the plant at least every millisecond and at every input, and are
//! steady in between. A CPU fault (reserved opcode, stack past internal RAM) stops the node for
//! good: [`NodeLogic::failed`] reports it and the supervisor treats it as a crash. Given counts
//! ([`FirmwareNode::with_coverage`]), it adds exactly the instructions of the path it takes
//! ([`coverage`]), and counting changes nothing else.
//!
//! [`NodeLogic::failed`]: bus::node::NodeLogic::failed

mod beside;
pub mod coverage;
pub mod debuginfo;
mod dump;
mod machine;
mod node;
mod spec;
mod wires;
mod wiring;

pub use beside::{Debug, SourceFile};
pub use dump::hex;
pub use node::{CHUNK, CpuTrace, FirmwareNode};
pub use spec::{
    CHIP_WINDOW, ChipSpec, FirmwareSpec, MAX_CLOCK_HZ, MAX_CONFIG, MAX_VREF_MV, MAX_XTAL_HZ, Pin, Reader,
    load,
};
pub use wires::{AnalogWire, DacWire, Direction, PinWire};
