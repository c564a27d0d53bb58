//! Monte Carlo scattering-direction samplers of the Photon stage (DART 5 paper §4,
//! "Ray-Carlo"; physics.md §9.2–9.3).
//!
//! Two families:
//!
//! * **Discrete** samplers over the N discrete directions of a phase row `𝒫(j|i)` (DART 5 paper
//!   eq. 3): [`AliasTable`] (Walker 1977, with Vose 1991's numerically robust construction;
//!   exact, O(1) per draw, 20 bytes per direction) and [`BoxTable`] (DART's two-level "Box
//!   method", paper §4.2; integer box counts, so its probabilities are *quantised*: it reports
//!   the probabilities it really realises and an a-priori bound of its bias).
//! * **Continuous** samplers that draw exact directions from the analytic kernels:
//!   fluid phase functions ([`sample_fluid_phase`]: isotropic, Henyey–Greenstein, two-term HG,
//!   depolarised Rayleigh; physics.md §4.2), bi-Lambertian (and optionally specular) leaves of
//!   any leaf angle distribution ([`LeafSampler`]; physics.md §3.2–3.3), Lambertian / RPV / Hapke
//!   surfaces ([`BrdfSampler`]; physics.md §5.2–5.3), and the cosine hemisphere.
//!
//! Conventions (physics.md §0): directions are unit **propagation** vectors, z up (a photon
//! travelling down has `z < 0`); `cos Θ = Ω'·Ω` is the scattering angle; leaf normals are
//! two-sided and leaf azimuths uniform; Γ is in the Ross convention
//! `(1/π)∫Γ(Ω'→Ω)dΩ = ω_L G(Ω')`. Every sampler draws its uniforms from a [`Uniform01`]
//! generator (implemented for `Xoshiro256PlusPlus`, which every Monte Carlo work item seeds from
//! (scene seed, stage, item index)), so runs are bit-reproducible.
//!
//! Robustness: no public function panics or returns NaN on the hard cases (grazing incidence
//! `μ = 1e-6`, directions exactly along ±z, `|g| = 0.999`, a weight row with a single non-zero
//! entry); invalid user data (weights, budgets, BRDF parameters) is rejected with a
//! [`SamplingError`] at construction time. Hot-path functions taking directions normalise
//! their inputs when they are not unit length and fall back to `+z` for zero or non-finite
//! vectors.

use rand_xoshiro::Xoshiro256PlusPlus;
use rand_xoshiro::rand_core::Rng;

use crate::physics::brdf::BrdfError;

mod alias;
mod box_method;
mod brdf;
mod frames;
mod leaf;
#[cfg(test)]
mod tests;

pub use alias::AliasTable;
pub use box_method::{BoxResolution, BoxTable};
pub use brdf::{BrdfGrid, BrdfSample, BrdfSampler};
pub use frames::{
    orthonormal_basis, rayleigh_cos_sample, sample_cosine_hemisphere, sample_fluid_cos,
    sample_fluid_phase,
};
pub use leaf::{
    LeafBranch, LeafEvent, LeafSampler, LeafSpecularEvent, leaf_gamma_parts, leaf_scatter_density,
};

// ---------------------------------------------------------------------------------------------
// Errors and random numbers
// ---------------------------------------------------------------------------------------------

/// Errors raised when building a sampler from user data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SamplingError {
    /// The weight (probability) list is empty.
    #[error("cannot build a sampler from an empty weight list")]
    Empty,
    /// More entries than the `u32` indices of the tables can address.
    #[error("{len} weights: at most {max} entries are supported")]
    TooLarge {
        /// Number of weights given.
        len: usize,
        /// Largest supported number.
        max: usize,
    },
    /// A weight is negative, NaN or infinite.
    #[error("weight[{index}] = {value} is invalid: weights must be finite and ≥ 0")]
    InvalidWeight {
        /// Position of the offending weight.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// Every weight is zero: there is nothing to sample.
    #[error("all {0} weights are zero: nothing to sample")]
    AllZero(usize),
    /// The Box-method memory budget cannot hold one box per class and per direction.
    #[error(
        "box budget of {budget} boxes is below the minimum {needed} (one box per class plus one per non-zero direction)"
    )]
    BudgetTooSmall {
        /// Budget given (boxes).
        budget: usize,
        /// Smallest budget that can represent the row.
        needed: usize,
    },
    /// A scalar parameter is out of range.
    #[error("{name} = {value} is invalid: {reason}")]
    Parameter {
        /// Parameter name.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// What is allowed.
        reason: &'static str,
    },
    /// Invalid surface reflectance parameters.
    #[error("invalid BRDF: {0}")]
    Brdf(#[from] BrdfError),
}

/// Source of uniform random numbers in `[0, 1)` with 53 random bits (the full f64 mantissa).
pub trait Uniform01 {
    /// Next uniform deviate `k · 2⁻⁵³`, `k ∈ [0, 2⁵³)`.
    fn next_f64(&mut self) -> f64;
}

impl Uniform01 for Xoshiro256PlusPlus {
    /// Top 53 bits of `next_u64` scaled by `2⁻⁵³` (Vigna's recommended conversion; the low bits
    /// of xoshiro256++ are as good as the high ones, the top ones are used by convention).
    #[inline]
    fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }
}

impl<R: Uniform01 + ?Sized> Uniform01 for &mut R {
    #[inline]
    fn next_f64(&mut self) -> f64 {
        (**self).next_f64()
    }
}

/// Largest number of entries of a discrete table (indices are stored as `u32`).
pub const MAX_TABLE_LEN: usize = u32::MAX as usize;

/// Validates a weight row and returns it normalised to sum 1 (scaled by the largest weight
/// first, so sums of huge weights cannot overflow).
fn normalised_weights(weights: &[f64]) -> Result<Vec<f64>, SamplingError> {
    if weights.is_empty() {
        return Err(SamplingError::Empty);
    }
    if weights.len() > MAX_TABLE_LEN {
        return Err(SamplingError::TooLarge {
            len: weights.len(),
            max: MAX_TABLE_LEN,
        });
    }
    let mut wmax: f64 = 0.0;
    for (index, &value) in weights.iter().enumerate() {
        if !(value.is_finite() && value >= 0.0) {
            return Err(SamplingError::InvalidWeight { index, value });
        }
        wmax = wmax.max(value);
    }
    if wmax <= 0.0 {
        return Err(SamplingError::AllZero(weights.len()));
    }
    let scaled: Vec<f64> = weights.iter().map(|w| w / wmax).collect();
    let sum: f64 = scaled.iter().sum();
    Ok(scaled.into_iter().map(|w| w / sum).collect())
}

/// Total variation distance `½ Σ_i |a_i − b_i|` between two probability vectors (each expected
/// to sum to 1; a missing entry of the shorter vector counts as 0). It is the largest difference
/// of the probability of any event under the two distributions, in `[0, 1]`.
pub fn total_variation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().max(b.len());
    let mut s = 0.0;
    for i in 0..n {
        let x = a.get(i).copied().unwrap_or(0.0);
        let y = b.get(i).copied().unwrap_or(0.0);
        s += (x - y).abs();
    }
    0.5 * s
}
