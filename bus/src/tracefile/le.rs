//! Little-endian fields of binary trace records (BLF objects, MF4 blocks), read without
//! panicking: a field past the end of its bytes reads as 0, so callers check lengths first and
//! never index out of range.

/// The little-endian u16 at `at`, 0 past the end.
pub(super) fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([byte(b, at), byte(b, at + 1)])
}

/// The little-endian u32 at `at`, 0 past the end.
pub(super) fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([byte(b, at), byte(b, at + 1), byte(b, at + 2), byte(b, at + 3)])
}

/// The little-endian u64 at `at`, 0 past the end.
pub(super) fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from(u32_at(b, at)) | (u64::from(u32_at(b, at + 4)) << 32)
}

/// The byte at `at`, 0 past the end.
pub(super) fn byte(b: &[u8], at: usize) -> u8 {
    b.get(at).copied().unwrap_or(0)
}
