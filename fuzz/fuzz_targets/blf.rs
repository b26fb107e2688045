//! The blf reader on any bytes (`harvemu_fuzz::binary_trace`): no panic; one error at most,
//! naming a record and a byte offset inside the input; what reads whole is written back in the
//! format and reads back the same.
#![no_main]

use bus::tracefile::FileFormat;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    harvemu_fuzz::binary_trace(FileFormat::Blf, input);
});
