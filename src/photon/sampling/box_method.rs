//! DART's two-level "Box method" over a discrete distribution ([`BoxTable`]; DART 5 paper
//! §4.2): integer box counts, so its probabilities are quantised; it reports the
//! probabilities it really realises and an a-priori bound of its bias.

use super::{SamplingError, Uniform01, normalised_weights};

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
    pub(crate) n: usize,
    pub(crate) gamma: f64,
    pub(crate) level1: Vec<u32>,
    pub(crate) class_start: Vec<u32>,
    pub(crate) level2: Vec<u32>,
    pub(crate) resolution: BoxResolution,
    /// Realised probability of every direction.
    pub(crate) p_hat: Vec<f64>,
}

pub(crate) struct BoxPlan {
    pub(crate) classes: Vec<(usize, usize)>, // ranges into `order`
    pub(crate) order: Vec<usize>,
    pub(crate) class_p: Vec<f64>,
    pub(crate) class_min: Vec<f64>,
    pub(crate) p_min_class: f64,
}

impl BoxPlan {
    pub(crate) fn counts(&self, p: &[f64], m1: f64, m2: f64) -> (usize, usize) {
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
pub(crate) fn box_count(x: f64) -> usize {
    // Saturating: the budget search never asks for more than u32::MAX boxes in total.
    (x.round().min(u32::MAX as f64) as usize).max(1)
}

impl BoxTable {
    /// Builds the two-level Box table for `weights` with class ratio threshold `gamma > 1` and
    /// a budget of `max_boxes` boxes (4 bytes each) in total.
    ///
    /// Errors: invalid weights (as [`AliasTable::new`](super::alias::AliasTable::new)), `gamma` not finite or `≤ 1`,
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
    pub(crate) fn count_probabilities(&self) -> Vec<f64> {
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
