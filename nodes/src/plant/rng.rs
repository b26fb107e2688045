//! Seeded random streams, one per purpose.
//!
//! Each stream is a ChaCha8 generator seeded from a hash of the run seed and a label naming what
//! the stream is for, so adding a stream (or drawing more from one) never changes another, and
//! the same seed gives the same plant on every platform and toolchain (no std hasher involved).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// SplitMix64's finaliser: a bijective mix with good avalanche.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// FNV-1a of the label, a fixed function unlike `std`'s hashers.
fn fnv1a(label: &str) -> u64 {
    label.bytes().fold(0xCBF2_9CE4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01B3)
    })
}

/// The generator for `label` under the run seed `seed`.
pub(crate) fn stream(seed: u64, label: &str) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(mix(mix(seed) ^ fnv1a(label)))
}

/// A standard normal sample (Box–Muller; `rand` 0.9 has no normal distribution without
/// `rand_distr`). Always draws exactly two uniforms, so streams stay aligned.
pub(crate) fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // 1 - u is in (0, 1], so the logarithm is finite.
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (core::f64::consts::TAU * u2).cos()
}

/// A uniform sample in `[-1, 1)`.
pub(crate) fn symmetric(rng: &mut ChaCha8Rng) -> f64 {
    rng.random::<f64>() * 2.0 - 1.0
}
