//! Vector BLF (binary logging) in and out.
