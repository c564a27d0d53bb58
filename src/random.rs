//! Seeded random streams: every Monte Carlo work item (a photon batch, a LiDAR pulse, a tree of a
//! stand) draws from its own Xoshiro256++ stream seeded from (scene seed, purpose, item), so
//! results are bit-identical whatever the thread count.

use rand_xoshiro::Xoshiro256PlusPlus;
use rand_xoshiro::rand_core::{Rng, SeedableRng};

/// Uniform draw in [0, 1) with 53 random bits.
pub fn uniform(rng: &mut Xoshiro256PlusPlus) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A generator stream for (scene seed, purpose, item): reproducible whatever the thread count.
pub fn stream(seed: u64, purpose: u64, item: u64) -> Xoshiro256PlusPlus {
    // SplitMix64-style mixing of the three words into one seed.
    let mut z = seed
        ^ purpose.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ item.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    Xoshiro256PlusPlus::seed_from_u64(z ^ (z >> 31))
}
