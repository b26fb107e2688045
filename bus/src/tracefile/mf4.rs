//! MF4 (ASAM MDF 4) with the bus-logging groups, in and out.
