//! Walker's alias method over a discrete distribution ([`AliasTable`]; Walker 1977, with
//! Vose 1991's numerically robust construction): exact, O(1) per draw (DART 5 paper eq. 3).

use super::{SamplingError, Uniform01, normalised_weights};

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
    pub(crate) prob: Vec<f64>,
    pub(crate) alias: Vec<u32>,
    /// Realised probability of every entry (computed from `prob`/`alias` at build time).
    pub(crate) p: Vec<f64>,
}

impl AliasTable {
    /// Builds the table from non-negative weights (normalised internally).
    ///
    /// Errors: empty list, a negative/NaN/infinite weight, all weights zero, more than
    /// [`MAX_TABLE_LEN`](super::MAX_TABLE_LEN) entries.
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
pub(crate) fn realised_alias_probabilities(prob: &[f64], alias: &[u32]) -> Vec<f64> {
    let n = prob.len() as f64;
    let mut p = prob.to_vec();
    for (j, &a) in alias.iter().enumerate() {
        if a as usize != j {
            p[a as usize] += 1.0 - prob[j];
        }
    }
    p.iter().map(|x| x / n).collect()
}
