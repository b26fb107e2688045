//! Firmware nodes: an unmodified 80C51 image (Intel HEX) running on the [`mcs51`] core, with
//! SJA1000 CAN controllers ([`bus::sja1000`]) in its external data space, as a node's logic.
//!
//! Contract: a [`FirmwareNode`] is deterministic: the same image, inputs and input times give
//! the same frames at the same times and the same state, run after run. Its time is its machine
//! cycles (12 oscillator periods each), placed exactly on bus time. It reads and writes the
//! controller's registers as the board would; the controller's requests (join or leave the bus,
//! transmit, abort, counters, bus-off recovery) reach the bus at the cycle the firmware made
//! them, and what the bus does reaches the registers at the moment it happens. A CPU fault
//! (reserved opcode, stack past internal RAM) stops the node for good: [`NodeLogic::failed`]
//! reports it and the supervisor treats it as a crash.
//!
//! [`NodeLogic::failed`]: bus::node::NodeLogic::failed

mod dump;
mod machine;
mod node;
mod spec;
mod wiring;

pub use dump::hex;
pub use node::{CHUNK, CpuTrace, FirmwareNode};
pub use spec::{
    AnalogWire, CHIP_WINDOW, ChipSpec, Direction, FirmwareSpec, MAX_CLOCK_HZ, MAX_VREF_MV, MAX_XTAL_HZ, Pin,
    PinWire, Reader, load,
};
