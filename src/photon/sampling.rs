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

use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;
use rand_xoshiro::rand_core::Rng;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

use crate::physics::brdf::{Brdf, BrdfError, LocalGeometry, MU_MIN};
use crate::physics::lad::{Lad, LeafAngleDistribution, LeafSpecular, VolscattKernel};
use crate::physics::phase::{FluidPhase, henyey_greenstein_sample};

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

// ---------------------------------------------------------------------------------------------
// Alias method
// ---------------------------------------------------------------------------------------------

/// Walker's (1977) alias table with Vose's (1991) numerically robust construction
/// (physics.md §9.3): `prob[j] ∈ [0, 1]` and `alias[j]` per entry; a draw takes one uniform
/// `u`, sets `x = uN`, `j = ⌊x⌋`, and returns `j` if `x − j < prob[j]`, else `alias[j]`.
///
/// * **Exact**: entry `i` is drawn with probability
///   `(prob[i] + Σ_{j: alias[j]=i} (1 − prob[j]))/N` (see [`Self::probability`]), equal to the
///   normalised weight up to floating rounding (~1e-16 relative) and the 53-bit resolution of
///   the uniform (`N·2⁻⁵³` absolute), independently of the dynamic range of the weights.
///   Zero weights get `prob = 0` and are never drawn.
/// * **Cost**: build O(N); draw O(1) (one uniform, one multiply, two loads);
///   [`Self::probability`] O(1). Memory 20 bytes per entry (`prob: f64`, `alias: u32` for
///   sampling, plus the realised probability `f64` for O(1) reweighting), i.e. 20 MB for a full
///   1000 × 1000 phase matrix (12 bytes per entry are touched by a draw).
#[derive(Debug, Clone, PartialEq)]
pub struct AliasTable {
    prob: Vec<f64>,
    alias: Vec<u32>,
    /// Realised probability of every entry (computed from `prob`/`alias` at build time).
    p: Vec<f64>,
}

impl AliasTable {
    /// Builds the table from non-negative weights (normalised internally).
    ///
    /// Errors: empty list, a negative/NaN/infinite weight, all weights zero, more than
    /// [`MAX_TABLE_LEN`] entries.
    pub fn new(weights: &[f64]) -> Result<Self, SamplingError> {
        let p = normalised_weights(weights)?;
        let n = p.len();
        let nf = n as f64;
        let mut scaled: Vec<f64> = p.iter().map(|x| x * nf).collect();
        let mut prob = vec![1.0; n];
        let mut alias: Vec<u32> = (0..n as u32).collect();
        // Vose: zero entries are paired first (a large entry always exists while any zero entry
        // is unprocessed, since the unprocessed entries average exactly 1), then the small ones.
        let mut zeros: Vec<usize> = Vec::new();
        let mut small: Vec<usize> = Vec::new();
        let mut large: Vec<usize> = Vec::new();
        for (i, &s) in scaled.iter().enumerate() {
            if s == 0.0 {
                zeros.push(i);
            } else if s < 1.0 {
                small.push(i);
            } else {
                large.push(i);
            }
        }
        while let Some(&l) = large.last() {
            let s = if let Some(z) = zeros.pop() {
                z
            } else if let Some(s) = small.pop() {
                s
            } else {
                break;
            };
            prob[s] = scaled[s];
            alias[s] = l as u32;
            // Vose's order of operations: (p_l + p_s) − 1 loses less than p_l − (1 − p_s).
            scaled[l] = (scaled[l] + scaled[s]) - 1.0;
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // Leftovers have scaled value 1 in exact arithmetic: they keep prob = 1 (their own
        // column). A zero entry can only be left over through gross round-off; never sample it.
        if !zeros.is_empty() {
            let argmax = p
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .map_or(0, |(i, _)| i);
            for z in zeros {
                prob[z] = 0.0;
                alias[z] = argmax as u32;
            }
        }
        let p = realised_alias_probabilities(&prob, &alias);
        Ok(Self { prob, alias, p })
    }

    /// Draws an index with one uniform deviate.
    #[inline]
    pub fn sample(&self, rng: &mut impl Uniform01) -> usize {
        let n = self.prob.len();
        let x = rng.next_f64() * n as f64;
        let j = (x as usize).min(n - 1);
        if x - (j as f64) < self.prob[j] {
            j
        } else {
            self.alias[j] as usize
        }
    }

    /// The probability with which the table draws entry `i` (0 outside the table), O(1):
    /// `(prob[i] + Σ_{j: alias[j]=i} (1 − prob[j]))/N`, computed from the table itself at build
    /// time. Equals the normalised weight to ~1e-15 relative.
    #[inline]
    pub fn probability(&self, i: usize) -> f64 {
        self.p.get(i).copied().unwrap_or(0.0)
    }

    /// All realised probabilities.
    pub fn probabilities(&self) -> Vec<f64> {
        self.p.clone()
    }

    /// Number of entries N.
    pub fn len(&self) -> usize {
        self.prob.len()
    }

    /// Always false (a table has at least one entry).
    pub fn is_empty(&self) -> bool {
        self.prob.is_empty()
    }

    /// Heap and inline memory of the table in bytes (`20 N + 72`).
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.prob.len() * std::mem::size_of::<f64>()
            + self.alias.len() * std::mem::size_of::<u32>()
            + self.p.len() * std::mem::size_of::<f64>()
    }
}

/// `(prob[i] + Σ_{j: alias[j]=i, j≠i} (1 − prob[j]))/N` for every entry (O(N)).
fn realised_alias_probabilities(prob: &[f64], alias: &[u32]) -> Vec<f64> {
    let n = prob.len() as f64;
    let mut p = prob.to_vec();
    for (j, &a) in alias.iter().enumerate() {
        if a as usize != j {
            p[a as usize] += 1.0 - prob[j];
        }
    }
    p.iter().map(|x| x / n).collect()
}

// ---------------------------------------------------------------------------------------------
// DART's Box method
// ---------------------------------------------------------------------------------------------

/// Resolution actually used by a [`BoxTable`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxResolution {
    /// Number of classes K.
    pub classes: usize,
    /// Ideal (real-valued) number of level-1 boxes of the least probable class.
    pub m1: f64,
    /// Ideal (real-valued) number of level-2 boxes of the least probable direction of each class.
    pub m2: f64,
    /// Level-1 boxes (class indices), `Σ_k C_k`.
    pub level1_boxes: usize,
    /// Level-2 boxes (direction indices), `Σ_j B_j`.
    pub level2_boxes: usize,
}

/// DART's **Box method** (Gastellu-Etchegorry et al. 2015, *Remote Sens.* 7:1667, §4.2;
/// physics.md §9.3), two-level form.
///
/// Construction, for one phase row `p_j` (normalised weights):
/// 1. the directions with `p_j > 0` are sorted by decreasing probability and grouped greedily
///    into classes: a class starts at the most probable remaining direction `p_first` and takes
///    the following ones while `p_first/p_j < γ` (max/min ratio inside a class `< γ`);
/// 2. **level 1**: class `k` (probability `P_k = Σ_{j∈k} p_j`) gets
///    `C_k = max(1, round(m1 · P_k/P_min))` boxes holding `k` (`P_min` = least probable class);
/// 3. **level 2**: inside class `k` (least probable member `q_k`), direction `j` gets
///    `B_j = max(1, round(m2 · p_j/q_k))` boxes holding `j`;
/// 4. a draw picks a level-1 box uniformly (first uniform), then a level-2 box of that class
///    uniformly (second uniform). Zero weights have no box and are never drawn.
///
/// The real resolutions `m1, m2` are chosen to fit the budget `max_boxes` (`Σ C_k + Σ B_j ≤
/// max_boxes`, found by bisection on a common scale): along the ratio
/// `m1/m2 = √(A·P_min)` that minimises the bias bound `≈ 1/m1 + 1/m2` for the box cost
/// `m1/P_min + m2·A`, with `A = Σ_j p_j/q_{k(j)} ≤ γN`. If that leaves `m1 < 1` (dynamic range
/// of the class probabilities too large for the budget), the budget is instead split
/// `√K : √A` between the levels (minimising the total-variation proxy `K/(4M₁) + 1/(4m2)`),
/// small classes keep one box (so no positive probability becomes zero) and the a-priori bound
/// below does not apply ([`Self::bias_bound`] returns `None`).
///
/// **Bias** (quantisation of the box counts): the realised probability is
/// `p̂_j = (C_k/ΣC)(B_j/S_k)`, `S_k = Σ_{j∈k} B_j` ([`Self::probability`]). With
/// `ε1 = 1/(2 m1)`, `ε2 = 1/(2 m2)` and `m1, m2 ≥ 1`, each count errs by at most half a box, so
/// `max_j |p̂_j − p_j|/p_j ≤ (1+ε1)(1+ε2)/((1−ε1)(1−ε2)) − 1 ≈ 1/m1 + 1/m2` and the total
/// variation `½Σ|p̂ − p| ≤` half of that ([`Self::bias_bound`]). At the optimal split this is
/// `≈ (√(1/P_min) + √A)²/M` for a budget of M boxes: larger γ means fewer classes (a larger
/// `P_min`) but a larger A — DART's memory/accuracy trade-off.
///
/// Measured (`tests/photon_samplers.rs`, HG g = 0.85 and planophile-leaf rows over N = 100–1000
/// equal-area sectors, γ = 2): with 10 / 100 / 1000 boxes per direction (40 / 400 / 4000
/// bytes of boxes per direction) the max relative bias is ≈ 0.09 / 0.01 / 0.001 and the total variation
/// ≈ 1.4e-2 / 1.5e-3 / 1.5e-4 (with 10 boxes per direction and N = 100 the HG row falls back to
/// `m1 < 1` and one direction is off by 470 %); the alias table is exact with 20 bytes per
/// direction. Release speed on one core, one hot row (two runs on a shared machine): alias
/// 55–105 M draws/s, Box 20–98 M draws/s (slowest with 1000 boxes per direction, as its
/// 4 MB rows outgrow the caches).
///
/// Memory: 4 bytes per box plus 4 bytes per class, plus 8 bytes per direction for the realised
/// probabilities ([`Self::probability`] is O(1)). Draw: two uniforms, two loads.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxTable {
    n: usize,
    gamma: f64,
    level1: Vec<u32>,
    class_start: Vec<u32>,
    level2: Vec<u32>,
    resolution: BoxResolution,
    /// Realised probability of every direction.
    p_hat: Vec<f64>,
}

struct BoxPlan {
    classes: Vec<(usize, usize)>, // ranges into `order`
    order: Vec<usize>,
    class_p: Vec<f64>,
    class_min: Vec<f64>,
    p_min_class: f64,
}

impl BoxPlan {
    fn counts(&self, p: &[f64], m1: f64, m2: f64) -> (usize, usize) {
        let mut c1 = 0usize;
        let mut c2 = 0usize;
        for (k, &(s, e)) in self.classes.iter().enumerate() {
            c1 += box_count(m1 * self.class_p[k] / self.p_min_class);
            for &j in &self.order[s..e] {
                c2 += box_count(m2 * p[j] / self.class_min[k]);
            }
        }
        (c1, c2)
    }
}

#[inline]
fn box_count(x: f64) -> usize {
    // Saturating: the budget search never asks for more than u32::MAX boxes in total.
    (x.round().min(u32::MAX as f64) as usize).max(1)
}

impl BoxTable {
    /// Builds the two-level Box table for `weights` with class ratio threshold `gamma > 1` and
    /// a budget of `max_boxes` boxes (4 bytes each) in total.
    ///
    /// Errors: invalid weights (as [`AliasTable::new`]), `gamma` not finite or `≤ 1`,
    /// `max_boxes` above `u32::MAX` or below one box per class plus one per non-zero direction.
    pub fn new(weights: &[f64], gamma: f64, max_boxes: usize) -> Result<Self, SamplingError> {
        let p = normalised_weights(weights)?;
        if !(gamma.is_finite() && gamma > 1.0) {
            return Err(SamplingError::Parameter {
                name: "gamma",
                value: gamma,
                reason: "the class max/min probability ratio must be finite and > 1",
            });
        }
        if max_boxes > u32::MAX as usize {
            return Err(SamplingError::Parameter {
                name: "max_boxes",
                value: max_boxes as f64,
                reason: "at most 4294967295 boxes (u32 indices)",
            });
        }
        // 1. Sort the non-zero directions by decreasing probability, group into classes.
        let mut order: Vec<usize> = (0..p.len()).filter(|&j| p[j] > 0.0).collect();
        order.sort_by(|&a, &b| p[b].total_cmp(&p[a]).then(a.cmp(&b)));
        let mut classes = Vec::new();
        let mut s = 0;
        while s < order.len() {
            let head = p[order[s]];
            let mut e = s + 1;
            while e < order.len() && head / p[order[e]] < gamma {
                e += 1;
            }
            classes.push((s, e));
            s = e;
        }
        let class_p: Vec<f64> = classes
            .iter()
            .map(|&(s, e)| order[s..e].iter().map(|&j| p[j]).sum())
            .collect();
        let class_min: Vec<f64> = classes.iter().map(|&(_, e)| p[order[e - 1]]).collect();
        let p_min_class = class_p.iter().copied().fold(f64::INFINITY, f64::min);
        let plan = BoxPlan {
            classes,
            order,
            class_p,
            class_min,
            p_min_class,
        };
        let k = plan.classes.len();
        let needed = k + plan.order.len();
        if max_boxes < needed {
            return Err(SamplingError::BudgetTooSmall {
                budget: max_boxes,
                needed,
            });
        }
        // 2. Resolution: bisection on a common scale along the chosen (m1, m2) direction.
        let a_cost: f64 = plan
            .classes
            .iter()
            .enumerate()
            .map(|(c, &(s, e))| {
                plan.order[s..e]
                    .iter()
                    .map(|&j| p[j] / plan.class_min[c])
                    .sum::<f64>()
            })
            .sum();
        let c1 = 1.0 / plan.p_min_class;
        let fit = |d1: f64, d2: f64| -> (f64, f64) {
            let total = |sc: f64| {
                let (x, y) = plan.counts(&p, sc * d1, sc * d2);
                x + y
            };
            let (mut lo, mut hi) = (0.0f64, 1.0f64);
            let mut guard = 0;
            while total(hi) <= max_boxes && guard < 2100 {
                lo = hi;
                hi *= 2.0;
                guard += 1;
            }
            for _ in 0..64 {
                let mid = 0.5 * (lo + hi);
                if total(mid) <= max_boxes {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            (lo * d1, lo * d2)
        };
        // Optimal ratio for the relative-bias proxy: m1/m2 = √(A/c1).
        let (mut m1, mut m2) = fit(a_cost.sqrt(), c1.sqrt());
        if m1 < 1.0 {
            // Level-1 cost per unit m1 is c1 boxes; split the budget √K : √A (M1 = m1·c1).
            let (d1, d2) = ((k as f64).sqrt() / c1, 1.0 / a_cost.sqrt());
            let (x1, x2) = fit(d1, d2);
            m1 = x1;
            m2 = x2;
        }
        // 3. Fill the arrays.
        let mut level1 = Vec::new();
        let mut class_start = Vec::with_capacity(k + 1);
        let mut level2 = Vec::new();
        class_start.push(0u32);
        for (c, &(s, e)) in plan.classes.iter().enumerate() {
            let nc = box_count(m1 * plan.class_p[c] / plan.p_min_class);
            level1.extend(std::iter::repeat_n(c as u32, nc));
            for &j in &plan.order[s..e] {
                let nb = box_count(m2 * p[j] / plan.class_min[c]);
                level2.extend(std::iter::repeat_n(j as u32, nb));
            }
            class_start.push(level2.len() as u32);
        }
        let resolution = BoxResolution {
            classes: k,
            m1,
            m2,
            level1_boxes: level1.len(),
            level2_boxes: level2.len(),
        };
        let mut table = Self {
            n: p.len(),
            gamma,
            level1,
            class_start,
            level2,
            resolution,
            p_hat: Vec::new(),
        };
        table.p_hat = table.count_probabilities();
        Ok(table)
    }

    /// Draws a direction index with two uniforms (class box, then direction box).
    #[inline]
    pub fn sample(&self, rng: &mut impl Uniform01) -> usize {
        let n1 = self.level1.len();
        let b1 = ((rng.next_f64() * n1 as f64) as usize).min(n1 - 1);
        let k = self.level1[b1] as usize;
        let s = self.class_start[k] as usize;
        let len = self.class_start[k + 1] as usize - s;
        let b2 = ((rng.next_f64() * len as f64) as usize).min(len - 1);
        self.level2[s + b2] as usize
    }

    /// All realised (quantised) probabilities `p̂_j = (C_k/ΣC)(B_j/S_k)`.
    pub fn probabilities(&self) -> Vec<f64> {
        self.p_hat.clone()
    }

    /// Counts the boxes of every direction (O(boxes)).
    fn count_probabilities(&self) -> Vec<f64> {
        let k = self.class_start.len() - 1;
        let mut c = vec![0usize; k];
        for &b in &self.level1 {
            c[b as usize] += 1;
        }
        let n1 = self.level1.len() as f64;
        let mut p = vec![0.0; self.n];
        for (class, &ck) in c.iter().enumerate() {
            let s = self.class_start[class] as usize;
            let e = self.class_start[class + 1] as usize;
            let w = ck as f64 / n1 / (e - s) as f64;
            for &j in &self.level2[s..e] {
                p[j as usize] += w;
            }
        }
        p
    }

    /// Realised (quantised) probability of direction `i`, O(1) (0 for zero weights and
    /// out-of-range indices). Reweighting a draw by `p_j/p̂_j` removes the Box bias exactly,
    /// since `p̂_j > 0` wherever `p_j > 0`.
    #[inline]
    pub fn probability(&self, i: usize) -> f64 {
        self.p_hat.get(i).copied().unwrap_or(0.0)
    }

    /// A-priori bound on `max_j |p̂_j − p_j|/p_j`, `(1+ε1)(1+ε2)/((1−ε1)(1−ε2)) − 1` with
    /// `ε_i = 1/(2 m_i)`; `None` when the budget forced `m1 < 1` or `m2 < 1` (then measure the
    /// bias with [`Self::probabilities`]). The total variation is at most half this bound.
    pub fn bias_bound(&self) -> Option<f64> {
        let BoxResolution { m1, m2, .. } = self.resolution;
        if m1 >= 1.0 && m2 >= 1.0 {
            let (e1, e2) = (0.5 / m1, 0.5 / m2);
            Some((1.0 + e1) * (1.0 + e2) / ((1.0 - e1) * (1.0 - e2)) - 1.0)
        } else {
            None
        }
    }

    /// Resolution and box counts actually used.
    pub fn resolution(&self) -> BoxResolution {
        self.resolution
    }

    /// Class ratio threshold γ.
    pub fn gamma(&self) -> f64 {
        self.gamma
    }

    /// Number of directions N (including zero-weight ones).
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false (a table has at least one direction).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Heap and inline memory in bytes: 4 per box, 4 per class (+1), 8 per direction, plus the
    /// struct.
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + 4 * (self.level1.len() + self.level2.len() + self.class_start.len())
            + 8 * self.p_hat.len()
    }
}

// ---------------------------------------------------------------------------------------------
// Frames, cosine hemisphere, fluid phase functions
// ---------------------------------------------------------------------------------------------

/// `v` if it is unit length (to 1e-12), else `v` normalised, else `+z` (zero or non-finite).
#[inline]
fn unit_or_z(v: DVec3) -> DVec3 {
    let l2 = v.length_squared();
    if (l2 - 1.0).abs() <= 1e-12 {
        v
    } else {
        v.normalize_or(DVec3::Z)
    }
}

/// Two unit vectors `(t1, t2)` such that `(t1, t2, n)` is a right-handed orthonormal basis
/// (Duff, Burgess, Christensen, Hery, Kensler, Liani & Villemin 2017, "Building an orthonormal
/// basis, revisited", JCGT 6(1), Listing 3): branch-free except for `sign(n_z)`, accurate to
/// ~1e-16 everywhere including `n = ±z` (no singularity, unlike Frisvad 2012).
/// `n` is normalised first if needed (zero or non-finite input is read as `+z`).
#[inline]
pub fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let n = unit_or_z(n);
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Unit direction at polar cosine `cos_theta` and azimuth `phi` (rad) about `axis` (unit),
/// in the frame of [`orthonormal_basis`].
#[inline]
fn direction_about(axis: DVec3, cos_theta: f64, phi: f64) -> DVec3 {
    let c = cos_theta.clamp(-1.0, 1.0);
    let s = (1.0 - c * c).max(0.0).sqrt();
    let (t1, t2) = orthonormal_basis(axis);
    let (sp, cp) = phi.sin_cos();
    (axis * c + (t1 * cp + t2 * sp) * s).normalize_or(axis)
}

/// Cosine-weighted direction on the hemisphere around `normal`: pdf `(Ω·n)/π` per steradian
/// (Malley's method: uniform point on the unit disc, `r = √ξ1`, `φ = 2πξ2`, lifted to
/// `z = √(1 − ξ1)`; e.g. Pharr, Jakob & Humphreys, *PBR* 4th ed. §A.5.3). Two uniforms.
/// The result satisfies `Ω·n ≥ 0` (> 0 except with probability 2⁻⁵³).
#[inline]
pub fn sample_cosine_hemisphere(normal: DVec3, rng: &mut impl Uniform01) -> DVec3 {
    let n = unit_or_z(normal);
    let u1 = rng.next_f64();
    let u2 = rng.next_f64();
    let r = u1.sqrt();
    let (sp, cp) = (TAU * u2).sin_cos();
    let z = (1.0 - u1).sqrt();
    let (t1, t2) = orthonormal_basis(n);
    (t1 * (r * cp) + t2 * (r * sp) + n * z).normalize_or(n)
}

/// Largest |g| used by the HG samplers (|g| → 1 is a Dirac lobe; clamping keeps the inverse
/// CDF finite, and `FluidPhase::validate` already limits |g| to 0.999).
const G_MAX: f64 = 1.0 - 1e-9;

#[inline]
fn sane_g(g: f64) -> f64 {
    if g.is_finite() {
        g.clamp(-G_MAX, G_MAX)
    } else {
        0.0
    }
}

/// Exact inverse-CDF sample of `cos Θ` for the depolarised Rayleigh phase function (Hansen &
/// Travis 1974; physics.md §4.2) `P(cos Θ) ∝ (1+3γ) + (1−γ)cos²Θ`, `γ = ρ_n/(2 − ρ_n)`,
/// from a uniform `xi ∈ [0, 1)`.
///
/// The CDF `F(μ) = [A(μ+1) + B(μ³+1)/3]/(2A + 2B/3)` (`A = 1+3γ`, `B = 1−γ`) is inverted by
/// solving the depressed cubic `μ³ + pμ + q = 0` with `p = 3A/B > 0` and `q = (p + 1)(1 − 2ξ)`,
/// whose single real root is given in the cancellation-free hyperbolic form
/// `μ = −2√(p/3) · sinh(⅓ asinh((3q/2p)·√(3/p)))` (Cardano's formula rewritten; ρ_n = 0 gives
/// p = 3, q = 4 − 8ξ). Accuracy ~1e-15; `ρ_n` is clamped to `[0, 0.5)`.
pub fn rayleigh_cos_sample(rho_n: f64, xi: f64) -> f64 {
    let rho = if rho_n.is_finite() {
        rho_n.clamp(0.0, 0.499_999)
    } else {
        0.0
    };
    let gam = rho / (2.0 - rho);
    let a = 1.0 + 3.0 * gam;
    let b = 1.0 - gam;
    let p = 3.0 * a / b;
    let q = (p + 1.0) * (1.0 - 2.0 * xi);
    let arg = 1.5 * q / p * (3.0 / p).sqrt();
    (-2.0 * (p / 3.0).sqrt() * (arg.asinh() / 3.0).sinh()).clamp(-1.0, 1.0)
}

/// Exact sample of the scattering cosine `cos Θ = Ω'·Ω` of a fluid phase function
/// (physics.md §4.2), consuming one uniform (two for the two-term HG: lobe, then cosine):
///
/// * isotropic: `cos Θ = 1 − 2ξ`;
/// * Henyey–Greenstein: inverse CDF `[1 + g² − ((1 − g²)/(1 − g + 2gξ))²]/(2g)`
///   ([`henyey_greenstein_sample`]; isotropic for |g| < 1e-6);
/// * two-term HG `a P_HG(g1) + (1 − a) P_HG(−g2)` (Kattawar 1975; `g2 > 0` is the backward
///   lobe as in `phase.rs`): lobe 1 with probability `a`, then that lobe's inverse CDF — exact
///   because the mixture weights are the lobes' normalised masses;
/// * Rayleigh with depolarisation: [`rayleigh_cos_sample`].
///
/// Out-of-range parameters are clamped (|g| ≤ 1 − 1e-9, a ∈ [0, 1]) so no NaN is produced;
/// validate phases with `FluidPhase::validate` first.
pub fn sample_fluid_cos(phase: &FluidPhase, rng: &mut impl Uniform01) -> f64 {
    match *phase {
        FluidPhase::Isotropic => 1.0 - 2.0 * rng.next_f64(),
        FluidPhase::Rayleigh { depolarization } => {
            rayleigh_cos_sample(depolarization, rng.next_f64())
        }
        FluidPhase::HenyeyGreenstein { g } => henyey_greenstein_sample(sane_g(g), rng.next_f64()),
        FluidPhase::TwoTermHg { a, g1, g2 } => {
            let a = if a.is_finite() {
                a.clamp(0.0, 1.0)
            } else {
                1.0
            };
            let g = if rng.next_f64() < a { g1 } else { -g2 };
            henyey_greenstein_sample(sane_g(g), rng.next_f64())
        }
    }
}

/// Exact sample of the outgoing propagation direction `Ω` for a photon travelling along
/// `omega_in` and scattered by a fluid with normalised phase function `P(Ω'·Ω)`
/// (pdf `P/(4π)` per steradian): `cos Θ` from [`sample_fluid_cos`], azimuth uniform about
/// `omega_in` (one more uniform). Unit length; valid along ±z and for |g| up to 0.999.
pub fn sample_fluid_phase(phase: &FluidPhase, omega_in: DVec3, rng: &mut impl Uniform01) -> DVec3 {
    let w = unit_or_z(omega_in);
    let c = sample_fluid_cos(phase, rng);
    let phi = TAU * rng.next_f64();
    direction_about(w, c, phi)
}

// ---------------------------------------------------------------------------------------------
// Leaves
// ---------------------------------------------------------------------------------------------

/// Shape of the envelope of one inclination piece: `s(θ)` with the target `f(θ) = r(θ)·s(θ)`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum PieceShape {
    /// `s = 1`.
    Flat,
    /// `s = θ^(α−1)` (beta LAD with ν = α < 1: integrable singularity at θ = 0).
    Left(f64),
    /// `s = (π/2 − θ)^(α−1)` (beta LAD with μ = α < 1: singularity at θ = π/2).
    Right(f64),
}

/// One piece `[a, b]` of the rejection envelope of the leaf-normal sampler.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    a: f64,
    b: f64,
    shape: PieceShape,
    /// Upper bound of the regular factor `r = f/s` on the piece (rad⁻¹ for Flat pieces).
    rmax: f64,
    /// Lower bound of `r` (used only to refine the envelope).
    rmin: f64,
    /// `∫_a^b s(θ) dθ`.
    mass: f64,
    /// `cos a` and `sin b`: bounds of `cos θ`, `sin θ` on the piece.
    cos_a: f64,
    sin_b: f64,
    /// Pre-computed `(a^α, b^α)` (Left) or `((π/2−b)^α, (π/2−a)^α)` (Right).
    pw: (f64, f64),
}

impl Piece {
    fn new(a: f64, b: f64, shape: PieceShape, density: &LadDensity) -> Self {
        let (mass, pw) = match shape {
            PieceShape::Flat => (b - a, (0.0, 0.0)),
            PieceShape::Left(al) => {
                let (x, y) = (a.powf(al), b.powf(al));
                ((y - x) / al, (x, y))
            }
            PieceShape::Right(al) => {
                let (x, y) = ((FRAC_PI_2 - b).max(0.0).powf(al), (FRAC_PI_2 - a).powf(al));
                ((y - x) / al, (x, y))
            }
        };
        // r is monotone on every piece (pieces are split at the LAD's monotonicity breaks), so
        // its extrema are at the ends; the midpoint covers piecewise-constant (histogram) LADs.
        let m = 0.5 * (a + b);
        let (ra, rm, rb) = if density.piecewise_constant() {
            let v = density.regular(m, shape);
            (v, v, v)
        } else {
            (
                density.regular(a, shape),
                density.regular(m, shape),
                density.regular(b, shape),
            )
        };
        let rmax = ra.max(rm).max(rb);
        let rmin = ra.min(rm).min(rb);
        Self {
            a,
            b,
            shape,
            // Safety factor against round-off in the monotone evaluation (exactness needs
            // r ≤ rmax everywhere; 1e-9 costs 1e-9 in efficiency).
            rmax: if rmax.is_finite() {
                rmax * (1.0 + 1e-9)
            } else {
                0.0
            },
            rmin: if rmin.is_finite() { rmin.max(0.0) } else { 0.0 },
            mass,
            cos_a: a.cos(),
            sin_b: b.sin(),
            pw,
        }
    }

    /// Samples θ on the piece from the envelope shape `s(θ)` with one uniform.
    #[inline]
    fn sample(&self, u: f64) -> f64 {
        match self.shape {
            PieceShape::Flat => self.a + (self.b - self.a) * u,
            PieceShape::Left(al) => (self.pw.0 + u * (self.pw.1 - self.pw.0))
                .powf(1.0 / al)
                .clamp(self.a, self.b),
            PieceShape::Right(al) => {
                let d = (self.pw.0 + u * (self.pw.1 - self.pw.0)).powf(1.0 / al);
                (FRAC_PI_2 - d).clamp(self.a, self.b)
            }
        }
    }

    fn weight_cos(&self) -> f64 {
        self.rmax * self.cos_a * self.mass
    }

    fn weight_sin(&self) -> f64 {
        self.rmax * self.sin_b * self.mass
    }

    fn excess_cos(&self) -> f64 {
        (self.rmax * self.cos_a - self.rmin * self.b.cos()) * self.mass
    }

    fn excess_sin(&self) -> f64 {
        (self.rmax * self.sin_b - self.rmin * self.a.sin()) * self.mass
    }
}

/// The inclination density `f(θ_L)` of a LAD, with the beta family factorised as
/// `f = K θ^(ν−1) (π/2 − θ)^(μ−1)` so its integrable endpoint singularities can be sampled
/// exactly.
#[derive(Debug, Clone, PartialEq)]
enum LadDensity {
    General(LeafAngleDistribution),
    Beta { k: f64, mu: f64, nu: f64 },
}

impl LadDensity {
    fn piecewise_constant(&self) -> bool {
        matches!(self, Self::General(l) if matches!(l.lad(), Lad::Histogram { .. }))
    }

    /// `f(θ)` in rad⁻¹.
    #[inline]
    fn f(&self, theta: f64) -> f64 {
        match self {
            Self::General(l) => l.pdf(theta),
            Self::Beta { k, mu, nu } => {
                k * theta.powf(nu - 1.0) * (FRAC_PI_2 - theta).max(0.0).powf(mu - 1.0)
            }
        }
    }

    /// Regular factor `r = f/s` for the piece shape (finite at the singular end).
    #[inline]
    fn regular(&self, theta: f64, shape: PieceShape) -> f64 {
        match (self, shape) {
            (_, PieceShape::Flat) => self.f(theta),
            (Self::Beta { k, mu, .. }, PieceShape::Left(_)) => {
                k * (FRAC_PI_2 - theta).max(0.0).powf(mu - 1.0)
            }
            (Self::Beta { k, nu, .. }, PieceShape::Right(_)) => k * theta.powf(nu - 1.0),
            (Self::General(_), _) => self.f(theta),
        }
    }
}

/// Interior points of `(0, π/2)` where `f(θ_L)` may change monotonicity (or jump).
fn lad_breaks(lad: &LeafAngleDistribution) -> Vec<f64> {
    match lad.lad() {
        Lad::Plagiophile | Lad::Extremophile => vec![FRAC_PI_4],
        Lad::EllipsoidalChi { .. } | Lad::Ellipsoidal { .. } => {
            // f ∝ sinθ/(cos²θ + χ² sin²θ)²: df/dθ ∝ cosθ [1 − 3(χ² − 1) sin²θ] (mode if χ² > 4/3).
            let chi = lad.ellipsoidal_chi().unwrap_or(1.0);
            let d = 3.0 * (chi * chi - 1.0);
            if d > 1.0 {
                vec![(1.0 / d).sqrt().asin()]
            } else {
                Vec::new()
            }
        }
        Lad::Beta { mu, nu } => {
            // d/dt ln f = (ν − 1)/t − (μ − 1)/(1 − t) = 0 at t* = (ν − 1)/(ν + μ − 2).
            let den = nu + mu - 2.0;
            let t = if den != 0.0 { (nu - 1.0) / den } else { -1.0 };
            if t > 0.0 && t < 1.0 {
                vec![t * FRAC_PI_2, FRAC_PI_4]
            } else {
                vec![FRAC_PI_4]
            }
        }
        Lad::Histogram { bins } => {
            let n = bins.len();
            (1..n).map(|k| FRAC_PI_2 * k as f64 / n as f64).collect()
        }
        _ => Vec::new(),
    }
}

/// Outcome of a bi-Lambertian leaf scattering event.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeafEvent {
    /// Outgoing propagation direction (unit).
    pub dir: DVec3,
    /// Leaf normal (unit), oriented to face the photon: `normal·omega_in < 0`.
    pub normal: DVec3,
    /// True for reflection (`dir·normal > 0`, back to the incoming side), false for
    /// transmission (`dir·normal < 0`).
    pub reflected: bool,
}

/// Branch taken by a leaf with a specular component.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LeafBranch {
    /// Lambertian reflection (per-band multiplier `ρ_b / branch_probability`).
    Reflected,
    /// Lambertian transmission (multiplier `τ_b / branch_probability`).
    Transmitted,
    /// Specular (mirror) reflection (multiplier `s_b(cos_incidence) / branch_probability`,
    /// with `s_b = LeafSpecular::fraction` of that band).
    Specular,
}

/// Outcome of [`LeafSampler::scatter_specular`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeafSpecularEvent {
    /// Outgoing propagation direction (unit).
    pub dir: DVec3,
    /// Leaf normal (unit) facing the photon (`normal·omega_in < 0`).
    pub normal: DVec3,
    /// Branch taken.
    pub branch: LeafBranch,
    /// Probability with which this branch was chosen given the normal (> 0).
    pub branch_probability: f64,
    /// `|omega_in·normal|`, the local incidence cosine (for `s_b` of other bands).
    pub cos_incidence: f64,
}

/// Exact sampler of leaf normals and bi-Lambertian leaf scattering for one leaf angle
/// distribution (Ross 1981; physics.md §3.1–3.3).
///
/// **Normals.** A photon travelling along Ω' hits leaves with normal density
/// `∝ g_L(Ω_L)|Ω'·Ω_L|` (`g_L = f(θ_L)/sin θ_L`, azimuths uniform), normalised by `2πG(Ω')`.
/// Written in (θ_L, φ_L) the target is `f(θ_L)·|μ' cos θ_L + s' sin θ_L cos(φ_L − φ')|`
/// (μ' = Ω'_z, s' = √(1 − μ'²)). It is sampled by **exact rejection** from the envelope
/// `r̄_i s_i(θ)(|μ'| cos a_i + s' sin b_i)` on pieces `[a_i, b_i]` of `[0, π/2]` with φ_L
/// uniform, where
/// * the pieces are split at every point where `f` may change monotonicity (π/4 for plagio-
///   and extremophile, the ellipsoidal mode `sin²θ = 1/(3(χ²−1))`, the beta mode
///   `t = (ν−1)/(ν+μ−2)`, histogram bin edges), so `r̄_i = max(r(a), r(m), r(b))·(1 + 1e-9)` is
///   a true upper bound of the regular factor `r = f/s`;
/// * `s_i = 1`, or `θ^(ν−1)` / `(π/2 − θ)^(μ−1)` next to an integrable singularity of a beta
///   LAD with exponent below 1 (sampled by its exact inverse CDF), so singular LADs are exact;
/// * `|Ω'·Ω_L| ≤ |μ'| cos θ + s' sin θ ≤ |μ'| cos a_i + s' sin b_i` on the piece; the envelope is
///   a fixed mixture of two alias tables (weights `r̄ cos a·∫s` and `r̄ sin b·∫s`) mixed with
///   probabilities `∝ |μ'|E_c : s'E_s`, so no table depends on the incidence;
/// * the pieces are refined (≤ 1024 extra) until the envelope exceeds the lower envelope by
///   < 2 % for both weights.
///
/// The accepted normal is flipped to face the photon. Expected trials per normal:
/// `(|μ'|E_c + s'E_s)/G(μ')` ([`Self::expected_trials`]), measured 1.00–1.01 at nadir and
/// 1.6–1.9 at oblique or grazing incidence for the classical, beta (0.433, 0.433) and
/// ellipsoidal (χ = 2 and 100) LADs — the uniform azimuth bounds `|A + B cos φ|` by `|A| + |B|`.
/// Release speed: 2–4.5 M leaf scatterings per second on one core.
///
/// **Scattering.** [`Self::scatter`] then reflects (probability `p_reflect`, outgoing direction
/// cosine-distributed about the normal, on the photon's incoming side) or transmits (cosine-
/// distributed on the far side). With the normal density above, the outgoing density of the
/// reflected branch is `Γ_ρ(Ω'→Ω)/(π G)` and of the transmitted branch `Γ_τ/(π G)` (Γ of unit
/// ρ or τ), so for leaf optics `(ρ_b, τ_b)` of band b the multiplier `ρ_b/p` (reflected) or
/// `τ_b/(1−p)` (transmitted) gives `E[w'·δ(Ω)] = (ρ_b Γ_ρ + τ_b Γ_τ)/(πG) = Γ_b/(πG)`: the
/// estimator is **unbiased** for every band and any `p ∈ (0, 1)` (p = 0 or 1 is allowed only
/// when every τ_b, resp. ρ_b, is 0). The engine's choice `p = Σρ/Σ(ρ+τ)` with multipliers
/// `ρ_b/(ω̄ p)`, `τ_b/(ω̄(1−p))` after an implicit-capture factor ω̄ is the same estimator.
#[derive(Debug, Clone)]
pub struct LeafSampler {
    density: LadDensity,
    pieces: Vec<Piece>,
    table_cos: AliasTable,
    table_sin: AliasTable,
    mass_cos: f64,
    mass_sin: f64,
    /// `∫ f(θ_L) cos²θ_L dθ_L / ∫ f dθ_L` (tanh–sinh on the LAD's pieces, ~1e-13): the second
    /// moment of the normal's vertical component, for [`LeafSampler::mean_abs_cos`].
    mean_cos2: f64,
}

/// Hard cap of rejection trials per normal (never reached for valid LADs: the acceptance
/// probability is ≥ G/(|μ'|E_c + s'E_s) > 0; the cap only guards against an infinite loop).
const MAX_TRIALS: usize = 1 << 20;

impl LeafSampler {
    /// Builds the sampler (≈ 100–1100 envelope pieces, two alias tables; ~10–60 kB).
    ///
    /// Errors only if the envelope is degenerate (impossible for a validated LAD).
    pub fn new(lad: &LeafAngleDistribution) -> Result<Self, SamplingError> {
        let density = match lad.lad() {
            Lad::Beta { mu, nu } => {
                let (mu, nu) = (*mu, *nu);
                // K from the LAD itself at θ = π/4, where both factors are regular.
                let x = FRAC_PI_4;
                let k = lad.pdf(x) / (x.powf(nu - 1.0) * x.powf(mu - 1.0));
                LadDensity::Beta { k, mu, nu }
            }
            _ => LadDensity::General(lad.clone()),
        };
        // Initial edges: 32 equal pieces (not for histograms) plus the monotonicity breaks.
        let mut edges: Vec<f64> = vec![0.0, FRAC_PI_2];
        if !density.piecewise_constant() {
            edges.extend((1..32).map(|k| FRAC_PI_2 * k as f64 / 32.0));
        }
        edges.extend(lad_breaks(lad));
        edges.sort_by(f64::total_cmp);
        edges.dedup_by(|a, b| (*a - *b).abs() <= 1e-13);
        let shape_of = |a: f64, b: f64| match &density {
            LadDensity::Beta { nu, .. } if *nu < 1.0 && b <= FRAC_PI_4 + 1e-15 => {
                PieceShape::Left(*nu)
            }
            LadDensity::Beta { mu, .. } if *mu < 1.0 && a >= FRAC_PI_4 - 1e-15 => {
                PieceShape::Right(*mu)
            }
            _ => PieceShape::Flat,
        };
        let mut pieces: Vec<Piece> = edges
            .windows(2)
            .map(|w| Piece::new(w[0], w[1], shape_of(w[0], w[1]), &density))
            .collect();
        // Refinement: split the piece with the largest relative excess until both envelopes
        // are within 2 % of their lower bounds.
        let max_pieces = pieces.len() + 1024;
        while pieces.len() < max_pieces {
            let tc: f64 = pieces.iter().map(Piece::weight_cos).sum();
            let ts: f64 = pieces.iter().map(Piece::weight_sin).sum();
            let ec: f64 = pieces.iter().map(Piece::excess_cos).sum();
            let es: f64 = pieces.iter().map(Piece::excess_sin).sum();
            if ec <= 0.02 * tc && es <= 0.02 * ts {
                break;
            }
            let (worst, _) = pieces
                .iter()
                .enumerate()
                .map(|(i, p)| (i, p.excess_cos() / tc + p.excess_sin() / ts))
                .fold(
                    (0, f64::NEG_INFINITY),
                    |acc, x| if x.1 > acc.1 { x } else { acc },
                );
            let p = pieces[worst];
            let m = 0.5 * (p.a + p.b);
            if !(m > p.a && m < p.b) {
                break;
            }
            pieces[worst] = Piece::new(p.a, m, p.shape, &density);
            pieces.insert(worst + 1, Piece::new(m, p.b, p.shape, &density));
        }
        let wc: Vec<f64> = pieces.iter().map(Piece::weight_cos).collect();
        let ws: Vec<f64> = pieces.iter().map(Piece::weight_sin).collect();
        let table_cos = AliasTable::new(&wc)?;
        let table_sin = AliasTable::new(&ws)?;
        let mass_cos = wc.iter().sum();
        let mass_sin = ws.iter().sum();
        let total = lad.total();
        let mean_cos2 = if total > 0.0 {
            (lad.integrate(0.0, FRAC_PI_2, &[], |t| t.cos() * t.cos()) / total).clamp(0.0, 1.0)
        } else {
            1.0 / 3.0
        };
        Ok(Self {
            density,
            pieces,
            table_cos,
            table_sin,
            mass_cos,
            mass_sin,
            mean_cos2,
        })
    }

    /// `E[|Ω'·Ω_L|]` over the normals [`Self::sample_normal`] draws for a photon along Ω' with
    /// direction cosine `mu` (density `f(θ_L)|Ω'·Ω_L|/G(μ')`, azimuth uniform), given `g` =
    /// G(μ'): `M₂(μ')/G(μ')` with `M₂ = μ'² ⟨cos²θ_L⟩ + ½(1 − μ'²)⟨sin²θ_L⟩` (the azimuth mean
    /// of `(Ω'·Ω_L)²`, physics.md §3.2–3.3). Times ρ_L/π it is the exact-backscatter peel-off
    /// intensity `Γ(Ω' → −Ω')/(π G)` per unit intercepted weight of a bi-Lambertian leaf
    /// (spherical LAD: ⟨cos²⟩ = 1/3, G = ½, giving 2ρ_L/(3π) = Γ_π/(πG) with Γ_π = ρ_L/3),
    /// the expectation of the one-leaf estimate `ρ_L|Ω_v·Ω_L|/π` at `Ω_v = −Ω'`. Dimensionless.
    pub fn mean_abs_cos(&self, mu: f64, g: f64) -> f64 {
        let m2 = (mu * mu).min(1.0);
        let second = m2 * self.mean_cos2 + 0.5 * (1.0 - m2) * (1.0 - self.mean_cos2);
        if g > 0.0 { second / g } else { 0.0 }
    }

    /// Number of envelope pieces.
    pub fn pieces(&self) -> usize {
        self.pieces.len()
    }

    /// Memory of the sampler in bytes (pieces and alias tables; the LAD copy excluded).
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.pieces.len() * std::mem::size_of::<Piece>()
            + self.table_cos.bytes()
            + self.table_sin.bytes()
    }

    /// Expected number of rejection trials per normal for incidence `omega_in`, given the LAD's
    /// `G(μ')` (e.g. `LeafAngleDistribution::g_function`): `(|μ'|E_c + s'E_s)/G`.
    pub fn expected_trials(&self, omega_in: DVec3, g: f64) -> f64 {
        let w = unit_or_z(omega_in);
        let am = w.z.abs().min(1.0);
        let s = (1.0 - am * am).max(0.0).sqrt();
        (am * self.mass_cos + s * self.mass_sin) / g
    }

    /// Inclination density `f(θ_L)` (rad⁻¹) the sampler targets (equals
    /// `LeafAngleDistribution::pdf` to round-off; the beta family uses its factorised form).
    pub fn inclination_pdf(&self, theta_l: f64) -> f64 {
        if (0.0..=FRAC_PI_2).contains(&theta_l) {
            self.density.f(theta_l)
        } else {
            0.0
        }
    }

    /// Draws a leaf normal with density `∝ g_L(Ω_L)|Ω'·Ω_L|` (exact; see the type docs),
    /// oriented so that `Ω_L·Ω' ≤ 0` (facing the photon). Unit length. About four uniforms per
    /// trial.
    pub fn sample_normal(&self, omega_in: DVec3, rng: &mut impl Uniform01) -> DVec3 {
        let w = unit_or_z(omega_in);
        let am = w.z.abs().min(1.0);
        let s = (w.x * w.x + w.y * w.y).sqrt().min(1.0);
        let pc = am * self.mass_cos / (am * self.mass_cos + s * self.mass_sin);
        let mut n = DVec3::Z;
        for _ in 0..MAX_TRIALS {
            let table = if rng.next_f64() < pc {
                &self.table_cos
            } else {
                &self.table_sin
            };
            let piece = &self.pieces[table.sample(rng)];
            let theta = piece.sample(rng.next_f64());
            let (st, ct) = theta.sin_cos();
            let (sp, cp) = (TAU * rng.next_f64()).sin_cos();
            n = DVec3::new(st * cp, st * sp, ct);
            let d = w.dot(n);
            let bound = piece.rmax * (am * piece.cos_a + s * piece.sin_b);
            if rng.next_f64() * bound < self.density.regular(theta, piece.shape) * d.abs() {
                return if d > 0.0 { -n } else { n };
            }
        }
        if w.dot(n) > 0.0 { -n } else { n }
    }

    /// Samples a bi-Lambertian leaf scattering event (see the type docs): normal from
    /// [`Self::sample_normal`], then reflection with probability `p_reflect` (cosine-weighted
    /// about the normal, `dir·normal > 0`) or transmission (cosine-weighted about −normal).
    /// `p_reflect` is clamped to `[0, 1]` (NaN reads as 0.5).
    pub fn scatter(&self, omega_in: DVec3, p_reflect: f64, rng: &mut impl Uniform01) -> LeafEvent {
        let p = if p_reflect.is_nan() {
            0.5
        } else {
            p_reflect.clamp(0.0, 1.0)
        };
        let normal = self.sample_normal(omega_in, rng);
        let reflected = rng.next_f64() < p;
        let axis = if reflected { normal } else { -normal };
        LeafEvent {
            dir: sample_cosine_hemisphere(axis, rng),
            normal,
            reflected,
        }
    }

    /// Samples a leaf event with a specular (cuticle) component (physics.md §3.3, §5.4
    /// applied to leaves; `lad.rs` `gamma_specular`): normal from [`Self::sample_normal`]; with
    /// `c = |Ω'·Ω_L|` and `s = spec.fraction(c)`, the specular branch (mirror direction
    /// `Ω' − 2(Ω'·Ω_L)Ω_L`) is taken with probability `p_s = s/(s + albedo)`, otherwise
    /// reflection/transmission as [`Self::scatter`] with probabilities `(1 − p_s)p_reflect`,
    /// `(1 − p_s)(1 − p_reflect)`.
    ///
    /// `albedo` is a representative Lambertian albedo ω̄ = ρ + τ (only the efficiency depends on
    /// it). Exact and unbiased: with the per-band multipliers listed in [`LeafBranch`],
    /// `E[w'δ(Ω)] = (Γ_b + Γ_spec,b)/(πG)`, the specular part integrating to
    /// `lad::specular_albedo`.
    pub fn scatter_specular(
        &self,
        omega_in: DVec3,
        p_reflect: f64,
        albedo: f64,
        spec: &LeafSpecular,
        rng: &mut impl Uniform01,
    ) -> LeafSpecularEvent {
        let w = unit_or_z(omega_in);
        let p = if p_reflect.is_nan() {
            0.5
        } else {
            p_reflect.clamp(0.0, 1.0)
        };
        let alb = if albedo.is_finite() {
            albedo.max(0.0)
        } else {
            0.0
        };
        let normal = self.sample_normal(w, rng);
        let d = w.dot(normal);
        let c = d.abs().min(1.0);
        let s = spec.fraction(c);
        let s = if s.is_finite() { s.max(0.0) } else { 0.0 };
        let ps = if s > 0.0 { s / (s + alb) } else { 0.0 };
        let u = rng.next_f64();
        if u < ps {
            let dir = (w - 2.0 * d * normal).normalize_or(-w);
            return LeafSpecularEvent {
                dir,
                normal,
                branch: LeafBranch::Specular,
                branch_probability: ps,
                cos_incidence: c,
            };
        }
        let reflected = rng.next_f64() < p;
        let axis = if reflected { normal } else { -normal };
        LeafSpecularEvent {
            dir: sample_cosine_hemisphere(axis, rng),
            normal,
            branch: if reflected {
                LeafBranch::Reflected
            } else {
                LeafBranch::Transmitted
            },
            branch_probability: (1.0 - ps) * if reflected { p } else { 1.0 - p },
            cos_incidence: c,
        }
    }
}

/// Unit components `(Γ_ρ, Γ_τ)` of the leaf area scattering phase function for peel-off
/// (physics.md §3.3; Γ = ρ_L Γ_ρ + τ_L Γ_τ, Ross convention): a thin wrapper over
/// `VolscattKernel::gamma_components`, which uses the Shultis & Myneni (1988) closed form when
/// the kernel was built for a spherical LAD without `force_bins`, and Verhoef's volscatt summed
/// over inclination bins otherwise (error O(n_bins⁻²)). Dimensionless.
#[inline]
pub fn leaf_gamma_parts(kernel: &VolscattKernel, omega_in: DVec3, omega_out: DVec3) -> (f64, f64) {
    kernel.gamma_components(unit_or_z(omega_in), unit_or_z(omega_out))
}

/// Peel-off density of a bi-Lambertian leaf event (sr⁻¹): the fraction of power intercepted
/// along Ω' that is scattered per unit solid angle toward Ω,
/// `(ρ Γ_ρ + τ Γ_τ)/(π G(Ω'))` (physics.md §3.3; it integrates to ω_L over 4π). `g` is the
/// G-function at Ω' consistent with the kernel (`VolscattKernel::g_binned`, or the exact
/// `LeafAngleDistribution::g_function`). Returns 0 when `g ≤ 0`.
pub fn leaf_scatter_density(
    kernel: &VolscattKernel,
    g: f64,
    omega_in: DVec3,
    omega_out: DVec3,
    rho: f64,
    tau: f64,
) -> f64 {
    if g.is_nan() || g <= 0.0 {
        return 0.0;
    }
    let (r, t) = leaf_gamma_parts(kernel, omega_in, omega_out);
    (rho * r + tau * t) / (PI * g)
}

// ---------------------------------------------------------------------------------------------
// Surfaces (BRDF importance sampling)
// ---------------------------------------------------------------------------------------------

/// Grid of the tabulated proposal of a [`BrdfSampler`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BrdfGrid {
    /// Number of equal-width bins of the incidence cosine μ_i ∈ [0, 1] (one table each).
    pub incidence_bins: usize,
    /// Number of equal-width cells of the outgoing cosine μ_o ∈ [0, 1].
    pub mu_bins: usize,
    /// Number of equal-width cells of the relative azimuth ψ ∈ [0, π] (mirror-symmetric BRFs).
    pub psi_bins: usize,
}

impl Default for BrdfGrid {
    /// 16 × 32 × 32: 16 384 cells, 328 kB, ~66 k BRF evaluations to build.
    fn default() -> Self {
        Self {
            incidence_bins: 16,
            mu_bins: 32,
            psi_bins: 32,
        }
    }
}

/// One importance sample of a surface BRF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrdfSample {
    /// Outgoing propagation direction (unit, `dir·normal ≥ 0`).
    pub dir: DVec3,
    /// Importance weight `BRF(Ω_i, Ω_o)·μ_o/(π·pdf(Ω_o))`, with `E[weight] = ρ_DH(μ_i)`.
    pub weight: f64,
    /// Proposal density of `dir` per steradian.
    pub pdf: f64,
}

/// Importance sampler of the reflected direction of Lambertian, RPV and Hapke surfaces
/// (physics.md §1.4, §5.2–5.3), **exact and unbiased** for any incidence.
///
/// The proposal is tabulated: for each incidence bin k (μ_i ∈ [k, k+1)/n_i, representative
/// cosine at the bin centre) an [`AliasTable`] over the cells of a (μ_o, ψ) grid with weights
/// `v_cell + 0.02·mean(v)`, where `v_cell` is the 2 × 2 Gauss–Legendre average of `BRF·μ_o`
/// over the cell (∝ the cell's share of `∫BRF μ dΩ`, since `dΩ = dμ dφ`) and the 2 % floor
/// keeps the pdf positive wherever the BRF can be. A draw picks a cell, a uniform point inside
/// it and a random sign of the relative azimuth (ψ ∈ [0, π] → ±ψ), so
/// `pdf(Ω_o) = p_cell/(2 Δμ Δψ)` sr⁻¹ ([`Self::pdf`]). The weight uses the exact BRF at the
/// true incidence, `w = BRF·μ_o/(π pdf)`, hence `E[w] = (1/π)∫BRF μ_o dΩ = ρ_DH(μ_i)`
/// (`Brdf::albedo_dh`) exactly, and `E[w·1_B] = ∫_B BRF μ_o dΩ/π` for any set of directions B;
/// the table only affects the variance. Lambertian surfaces use exact cosine sampling
/// (`w = reflectance`).
///
/// Cost: build `n_i·n_μ·n_ψ·4` BRF evaluations (release, default grid: 6–11 ms for RPV,
/// 45–60 ms for Hapke); draws 3.6 M/s (RPV) and 1 M/s (Hapke) on one core; memory
/// `20·n_i·n_μ·n_ψ` bytes (alias table + realised cell probability; 328 kB default); a draw
/// is one alias draw, one BRF evaluation and four uniforms.
#[derive(Debug, Clone)]
pub struct BrdfSampler {
    brdf: Brdf,
    grid: BrdfGrid,
    tables: Vec<AliasTable>,
    /// Realised cell probabilities of every table, flattened (`k·n_μ·n_ψ + cell`).
    probs: Vec<f64>,
}

/// One proposal draw in facet coordinates.
struct Draw {
    dir: DVec3,
    pdf: f64,
    mu_i: f64,
    mu_o: f64,
    cos_psi: f64,
}

/// Relative floor of the tabulated proposal (fraction of the mean cell weight).
const BRDF_FLOOR: f64 = 0.02;

impl BrdfSampler {
    /// Builds the sampler on `grid` (use `BrdfGrid::default()` unless studying the variance)
    /// for a BRDF (`Brdf::validate` is called).
    ///
    /// Errors: invalid BRDF parameters; a grid dimension of 0 or more than 10⁸ cells in total.
    pub fn new(brdf: &Brdf, grid: BrdfGrid) -> Result<Self, SamplingError> {
        brdf.validate()?;
        let BrdfGrid {
            incidence_bins: ni,
            mu_bins: nm,
            psi_bins: np,
        } = grid;
        for (name, v) in [("incidence_bins", ni), ("mu_bins", nm), ("psi_bins", np)] {
            if v == 0 {
                return Err(SamplingError::Parameter {
                    name,
                    value: 0.0,
                    reason: "grid dimensions must be ≥ 1",
                });
            }
        }
        let cells = ni.saturating_mul(nm).saturating_mul(np);
        if cells > 100_000_000 {
            return Err(SamplingError::Parameter {
                name: "incidence_bins × mu_bins × psi_bins",
                value: cells as f64,
                reason: "at most 1e8 cells",
            });
        }
        let mut tables = Vec::new();
        let mut probs = Vec::new();
        if !brdf.is_lambertian() {
            // 2-point Gauss–Legendre abscissae on [0, 1].
            let gl = [0.5 - 0.5 / 3f64.sqrt(), 0.5 + 0.5 / 3f64.sqrt()];
            let (dm, dp) = (1.0 / nm as f64, PI / np as f64);
            let cos_psi: Vec<f64> = (0..np)
                .flat_map(|m| gl.map(|x| ((m as f64 + x) * dp).cos()))
                .collect();
            tables.reserve(ni);
            for k in 0..ni {
                let mu_i = ((k as f64 + 0.5) / ni as f64).clamp(MU_MIN, 1.0);
                let mut w = Vec::with_capacity(nm * np);
                for j in 0..nm {
                    let mus = gl.map(|x| (j as f64 + x) * dm);
                    for m in 0..np {
                        let mut v = 0.0;
                        for mu_o in mus {
                            for cp in &cos_psi[2 * m..2 * m + 2] {
                                let geo = LocalGeometry {
                                    mu_i,
                                    mu_v: mu_o.clamp(MU_MIN, 1.0),
                                    cos_psi: *cp,
                                };
                                v += brdf.brf_local(&geo) * mu_o;
                            }
                        }
                        w.push(if v.is_finite() { v.max(0.0) } else { 0.0 });
                    }
                }
                let mean = w.iter().sum::<f64>() / w.len() as f64;
                let floor = if mean > 0.0 { BRDF_FLOOR * mean } else { 1.0 };
                for x in &mut w {
                    *x += floor;
                }
                let t = AliasTable::new(&w)?;
                probs.extend(t.probabilities());
                tables.push(t);
            }
        }
        Ok(Self {
            brdf: *brdf,
            grid,
            tables,
            probs,
        })
    }

    /// The surface model.
    pub fn brdf(&self) -> &Brdf {
        &self.brdf
    }

    /// The proposal grid.
    pub fn grid(&self) -> BrdfGrid {
        self.grid
    }

    /// Memory of the tables in bytes.
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.tables.iter().map(AliasTable::bytes).sum::<usize>()
            + 8 * self.probs.len()
    }

    /// Facet frame: unit normal, incidence cosine and the in-plane unit vector toward the source.
    fn frame(normal: DVec3, omega_in: DVec3) -> Option<(DVec3, f64, DVec3, DVec3)> {
        let n = unit_or_z(normal);
        let s = -unit_or_z(omega_in);
        let mu_i = s.dot(n);
        if mu_i.is_nan() || mu_i <= 0.0 {
            return None;
        }
        let a = s - mu_i * n;
        let la = a.length();
        let (t1, t2) = if la > 1e-12 {
            let t1 = a / la;
            (t1, n.cross(t1))
        } else {
            orthonormal_basis(n)
        };
        Some((n, mu_i.min(1.0), t1, t2))
    }

    fn bin(&self, mu_i: f64) -> usize {
        ((mu_i * self.grid.incidence_bins as f64) as usize).min(self.grid.incidence_bins - 1)
    }

    /// Draws a direction from the proposal (no BRF evaluation).
    fn draw(&self, normal: DVec3, omega_in: DVec3, rng: &mut impl Uniform01) -> Option<Draw> {
        let (n, mu_i, t1, t2) = Self::frame(normal, omega_in)?;
        if self.brdf.is_lambertian() {
            let dir = sample_cosine_hemisphere(n, rng);
            let mu_o = dir.dot(n).clamp(0.0, 1.0);
            return Some(Draw {
                dir,
                pdf: mu_o / PI,
                mu_i,
                mu_o,
                cos_psi: 1.0,
            });
        }
        let k = self.bin(mu_i);
        let cell = self.tables[k].sample(rng);
        let (nm, np) = (self.grid.mu_bins, self.grid.psi_bins);
        let (j, m) = (cell / np, cell % np);
        let (dm, dp) = (1.0 / nm as f64, PI / np as f64);
        let mu_o = ((j as f64 + rng.next_f64()) * dm).min(1.0);
        let psi = (m as f64 + rng.next_f64()) * dp;
        let sign = if rng.next_f64() < 0.5 { 1.0 } else { -1.0 };
        let so = (1.0 - mu_o * mu_o).max(0.0).sqrt();
        let (sp, cp) = psi.sin_cos();
        Some(Draw {
            dir: (n * mu_o + (t1 * cp + t2 * (sign * sp)) * so).normalize_or(n),
            pdf: self.probs[k * nm * np + cell] / (2.0 * dm * dp),
            mu_i,
            mu_o,
            cos_psi: cp,
        })
    }

    /// Draws a reflected direction for a ray travelling along `omega_in` onto a facet of unit
    /// `normal` (front side: `omega_in·normal < 0`), with its importance weight and pdf.
    /// Returns `None` when the ray does not hit the front side.
    pub fn sample(
        &self,
        normal: DVec3,
        omega_in: DVec3,
        rng: &mut impl Uniform01,
    ) -> Option<BrdfSample> {
        let d = self.draw(normal, omega_in, rng)?;
        if let Brdf::Lambertian { reflectance } = self.brdf {
            return Some(BrdfSample {
                dir: d.dir,
                weight: reflectance,
                pdf: d.pdf,
            });
        }
        let geo = LocalGeometry {
            mu_i: d.mu_i.clamp(MU_MIN, 1.0),
            mu_v: d.mu_o.clamp(MU_MIN, 1.0),
            cos_psi: d.cos_psi,
        };
        let weight = self.brdf.brf_local(&geo) * d.mu_o / (PI * d.pdf);
        Some(BrdfSample {
            dir: d.dir,
            weight: if weight.is_finite() { weight } else { 0.0 },
            pdf: d.pdf,
        })
    }

    /// Direction and proposal pdf only (sr⁻¹), for callers that weight several bands
    /// themselves (`w_b ← w_b BRF_b μ_o/(π pdf)`); `(normal, 0)` when the ray does not hit the
    /// front side. Same draw as [`Self::sample`] without the BRF evaluation.
    pub fn sample_dir(
        &self,
        normal: DVec3,
        omega_in: DVec3,
        rng: &mut impl Uniform01,
    ) -> (DVec3, f64) {
        match self.draw(normal, omega_in, rng) {
            Some(d) => (d.dir, d.pdf),
            None => (unit_or_z(normal), 0.0),
        }
    }

    /// Proposal density (sr⁻¹) of drawing `omega_out` for incidence `omega_in` on a facet of
    /// unit `normal`: `p_cell/(2ΔμΔψ)` (Lambertian: `μ_o/π`); 0 behind the facet or when the
    /// incidence is not on the front side.
    pub fn pdf(&self, normal: DVec3, omega_in: DVec3, omega_out: DVec3) -> f64 {
        let Some((n, mu_i, t1, t2)) = Self::frame(normal, omega_in) else {
            return 0.0;
        };
        let v = unit_or_z(omega_out);
        let mu_o = v.dot(n);
        if mu_o.is_nan() || mu_o < 0.0 {
            return 0.0;
        }
        if self.brdf.is_lambertian() {
            return mu_o.min(1.0) / PI;
        }
        let (x, y) = (v.dot(t1), v.dot(t2));
        let psi = if x * x + y * y > 0.0 {
            y.abs().atan2(x)
        } else {
            0.0
        };
        let (nm, np) = (self.grid.mu_bins, self.grid.psi_bins);
        let j = ((mu_o * nm as f64) as usize).min(nm - 1);
        let m = ((psi / PI * np as f64) as usize).min(np - 1);
        let (dm, dp) = (1.0 / nm as f64, PI / np as f64);
        self.probs[self.bin(mu_i) * nm * np + j * np + m] / (2.0 * dm * dp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_xoshiro::rand_core::SeedableRng;

    fn rng(seed: u64) -> Xoshiro256PlusPlus {
        Xoshiro256PlusPlus::seed_from_u64(seed)
    }

    #[test]
    fn uniform01_is_in_unit_interval_with_mean_half() {
        let mut r = rng(1);
        let n = 100_000;
        let mut s = 0.0;
        for _ in 0..n {
            let u = r.next_f64();
            assert!((0.0..1.0).contains(&u));
            s += u;
        }
        // σ of the mean = 1/√(12n) ≈ 9.1e-4; 5σ.
        assert!((s / n as f64 - 0.5).abs() < 4.6e-3);
    }

    #[test]
    fn alias_probabilities_are_the_normalised_weights() {
        let w = [3.0, 0.0, 1e-9, 7.5, 0.25, 0.0, 1.0];
        let t = AliasTable::new(&w).unwrap();
        let sum: f64 = w.iter().sum();
        let p = t.probabilities();
        for (i, (&wi, &pi)) in w.iter().zip(&p).enumerate() {
            assert!((pi - wi / sum).abs() <= 1e-15, "{i}: {pi} vs {}", wi / sum);
            assert!((t.probability(i) - pi).abs() <= 1e-16);
        }
        assert_eq!(t.probability(1), 0.0);
        assert_eq!(t.probability(99), 0.0);
        assert_eq!(t.len(), 7);
        assert_eq!(t.bytes(), std::mem::size_of::<AliasTable>() + 20 * 7);
    }

    #[test]
    fn alias_rejects_bad_weights() {
        assert_eq!(AliasTable::new(&[]), Err(SamplingError::Empty));
        assert_eq!(AliasTable::new(&[0.0, 0.0]), Err(SamplingError::AllZero(2)));
        assert!(matches!(
            AliasTable::new(&[1.0, -1.0]),
            Err(SamplingError::InvalidWeight { index: 1, .. })
        ));
        assert!(matches!(
            AliasTable::new(&[1.0, f64::NAN]),
            Err(SamplingError::InvalidWeight { index: 1, .. })
        ));
        assert!(matches!(
            AliasTable::new(&[f64::INFINITY]),
            Err(SamplingError::InvalidWeight { index: 0, .. })
        ));
        // Huge weights do not overflow the normalisation.
        let t = AliasTable::new(&[f64::MAX, f64::MAX]).unwrap();
        assert!((t.probability(0) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn single_nonzero_weight_is_always_drawn() {
        let w = [0.0, 0.0, 0.0, 2.5, 0.0];
        let a = AliasTable::new(&w).unwrap();
        let b = BoxTable::new(&w, 2.0, 16).unwrap();
        let mut r = rng(2);
        for _ in 0..10_000 {
            assert_eq!(a.sample(&mut r), 3);
            assert_eq!(b.sample(&mut r), 3);
        }
        assert_eq!(b.probabilities(), vec![0.0, 0.0, 0.0, 1.0, 0.0]);
        assert_eq!(BoxTable::new(&[1.0], 1.5, 2).unwrap().sample(&mut r), 0);
    }

    #[test]
    fn box_table_structure_and_errors() {
        let w: Vec<f64> = (0..50).map(|i| 1.0 + (i % 7) as f64 * 3.0).collect();
        let b = BoxTable::new(&w, 2.0, 5000).unwrap();
        let res = b.resolution();
        assert!(res.level1_boxes + res.level2_boxes <= 5000);
        assert!(res.m1 >= 1.0 && res.m2 >= 1.0, "{res:?}");
        let p = b.probabilities();
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let sum: f64 = w.iter().sum();
        let bound = b.bias_bound().unwrap();
        for (pi, wi) in p.iter().zip(&w) {
            assert!((pi / (wi / sum) - 1.0).abs() <= bound);
        }
        assert_eq!(
            b.bytes(),
            std::mem::size_of::<BoxTable>()
                + 4 * (res.level1_boxes + res.level2_boxes + res.classes + 1)
                + 8 * w.len()
        );
        assert!(matches!(
            BoxTable::new(&w, 1.0, 5000),
            Err(SamplingError::Parameter { name: "gamma", .. })
        ));
        assert!(matches!(
            BoxTable::new(&w, f64::NAN, 5000),
            Err(SamplingError::Parameter { name: "gamma", .. })
        ));
        assert!(matches!(
            BoxTable::new(&w, 2.0, 10),
            Err(SamplingError::BudgetTooSmall { budget: 10, .. })
        ));
        // Class ratio below γ inside every class.
        let sorted = {
            let mut v = w.clone();
            v.sort_by(|a, b| b.total_cmp(a));
            v
        };
        assert!(sorted[0] / sorted[sorted.len() - 1] >= 2.0);
    }

    #[test]
    fn box_table_with_extreme_dynamic_range_keeps_support() {
        // 1e-12 dynamic range cannot be resolved with 1000 boxes: no a-priori bound, but every
        // positive direction keeps a positive probability and the budget holds.
        let w = [1.0, 1e-12, 0.5, 0.0, 1e-6];
        let b = BoxTable::new(&w, 4.0, 1000).unwrap();
        let res = b.resolution();
        assert!(res.level1_boxes + res.level2_boxes <= 1000);
        assert!(b.bias_bound().is_none());
        let p = b.probabilities();
        for (pi, wi) in p.iter().zip(&w) {
            assert_eq!(*pi > 0.0, *wi > 0.0);
        }
    }

    #[test]
    fn total_variation_basics() {
        assert_eq!(total_variation(&[0.5, 0.5], &[0.5, 0.5]), 0.0);
        assert!((total_variation(&[1.0, 0.0], &[0.0, 1.0]) - 1.0).abs() < 1e-15);
        assert!((total_variation(&[0.5, 0.5], &[1.0]) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn rayleigh_inverse_cdf_is_exact() {
        for rho in [0.0, AIR, 0.3] {
            let gam: f64 = rho / (2.0 - rho);
            let (a, b) = (1.0 + 3.0 * gam, 1.0 - gam);
            let cdf =
                |m: f64| (a * (m + 1.0) + b * (m * m * m + 1.0) / 3.0) / (2.0 * a + 2.0 * b / 3.0);
            for k in 0..=1000 {
                let xi = k as f64 / 1000.0;
                let mu = rayleigh_cos_sample(rho, xi);
                assert!(
                    (cdf(mu) - xi).abs() < 1e-14,
                    "rho {rho} xi {xi}: {}",
                    cdf(mu)
                );
            }
        }
    }
    const AIR: f64 = crate::physics::phase::AIR_DEPOLARIZATION;

    #[test]
    fn orthonormal_basis_is_orthonormal_everywhere() {
        let mut r = rng(3);
        let mut dirs = vec![
            DVec3::Z,
            -DVec3::Z,
            DVec3::new(0.0, 0.0, -0.0),
            DVec3::X,
            DVec3::new(1e-300, 0.0, -1.0),
            DVec3::new(0.0, 1e-9, -1.0).normalize(),
        ];
        for _ in 0..1000 {
            dirs.push(sample_fluid_phase(&FluidPhase::Isotropic, DVec3::Z, &mut r));
        }
        for n in dirs {
            let nn = unit_or_z(n);
            let (t1, t2) = orthonormal_basis(n);
            for (x, y) in [(t1, t2), (t1, nn), (t2, nn)] {
                assert!(x.dot(y).abs() < 1e-14, "{n}");
            }
            assert!((t1.length() - 1.0).abs() < 1e-14 && (t2.length() - 1.0).abs() < 1e-14);
            assert!((t1.cross(t2) - nn).length() < 1e-14, "right-handed {n}");
        }
        // Degenerate inputs read as +z.
        let (t1, t2) = orthonormal_basis(DVec3::new(f64::NAN, 0.0, 0.0));
        assert!(t1.is_finite() && t2.is_finite());
    }

    #[test]
    fn beta_factorisation_matches_lad_pdf() {
        for (mu, nu) in [(0.433, 0.433), (2.77, 1.172), (1.5, 0.6), (0.3, 3.0)] {
            let lad = Lad::Beta { mu, nu }.resolve().unwrap();
            let s = LeafSampler::new(&lad).unwrap();
            for k in 1..100 {
                let t = FRAC_PI_2 * k as f64 / 100.0;
                let (a, b) = (s.inclination_pdf(t), lad.pdf(t));
                assert!(
                    (a / b - 1.0).abs() < 1e-12,
                    "beta({mu},{nu}) θ={t}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn leaf_normals_face_the_photon() {
        let lad = Lad::Planophile.resolve().unwrap();
        let s = LeafSampler::new(&lad).unwrap();
        let mut r = rng(4);
        for w in [
            DVec3::new(0.3, -0.2, -0.9).normalize(),
            -DVec3::Z,
            DVec3::Z,
            DVec3::X,
        ] {
            for _ in 0..2000 {
                let n = s.sample_normal(w, &mut r);
                assert!((n.length() - 1.0).abs() < 1e-12);
                assert!(n.dot(w) <= 0.0);
                let e = s.scatter(w, 0.4, &mut r);
                let d = e.dir.dot(e.normal);
                assert!(if e.reflected { d >= 0.0 } else { d <= 0.0 });
            }
        }
    }

    #[test]
    fn brdf_sampler_errors() {
        let bad = Brdf::Rpv {
            rho0: -1.0,
            k: 0.5,
            theta: 0.0,
            rho_c: None,
        };
        assert!(matches!(
            BrdfSampler::new(&bad, BrdfGrid::default()),
            Err(SamplingError::Brdf(_))
        ));
        let ok = Brdf::Lambertian { reflectance: 0.3 };
        let g = BrdfGrid {
            mu_bins: 0,
            ..BrdfGrid::default()
        };
        assert!(matches!(
            BrdfSampler::new(&ok, g),
            Err(SamplingError::Parameter {
                name: "mu_bins",
                ..
            })
        ));
        let s = BrdfSampler::new(&ok, BrdfGrid::default()).unwrap();
        // Back-side incidence: no sample.
        let mut r = rng(5);
        assert!(s.sample(DVec3::Z, DVec3::Z, &mut r).is_none());
        assert_eq!(s.pdf(DVec3::Z, DVec3::Z, DVec3::Z), 0.0);
    }
}
