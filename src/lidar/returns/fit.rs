//! The Levenberg–Marquardt fitter of the Gaussian decomposition (Marquardt 1963, *J. SIAM*
//! 11:431; Madsen, Nielsen & Tingleff 2004, MINPACK stopping tests), its envelope Cholesky
//! solve (George & Liu 1981) and the normal tail and density `(Φ(−z), φ(z))` it evaluates
//! (Abramowitz & Stegun 7.1.2).

use super::DecompositionSettings;
use super::decompose::{Comp, Evaluation, FitStats};
use std::f64::consts::FRAC_1_SQRT_2;

/// Levenberg–Marquardt fitter with its reusable buffers.
pub(crate) struct Fitter<'a> {
    pub(crate) y: &'a [f64],
    pub(crate) min_w: f64,
    pub(crate) max_iter: usize,
    pub(crate) rel_tol: f64,
    /// χ² of residuals of 8 ulp rms, `64 ε² Σ y²`: the rounding floor.
    pub(crate) rounding_chi2: f64,
    /// Evaluation at the current parameters (after [`Fitter::fit`]: at its result).
    pub(crate) cur: Evaluation,
    /// Evaluation at the trial step.
    pub(crate) next: Evaluation,
    pub(crate) trial: Vec<Comp>,
    pub(crate) jtj: Vec<f64>,
    pub(crate) jtr: Vec<f64>,
    pub(crate) a: Vec<f64>,
    pub(crate) step: Vec<f64>,
    /// First non-zero column of each row of the normal matrix (its envelope).
    pub(crate) first: Vec<usize>,
    /// Counters (diagnostics).
    pub(crate) stats: FitStats,
    /// Also run the legacy fitter from the same start (diagnostics, [`FitStats::chi2_pairs`]).
    pub(crate) compare: bool,
}

impl<'a> Fitter<'a> {
    pub(crate) fn new(y: &'a [f64], settings: &DecompositionSettings) -> Self {
        Self {
            y,
            min_w: settings.min_width_bins,
            max_iter: settings.max_iterations,
            rel_tol: settings.relative_tolerance,
            rounding_chi2: 64.0
                * f64::EPSILON
                * f64::EPSILON
                * y.iter().map(|v| v * v).sum::<f64>(),
            cur: Evaluation::default(),
            next: Evaluation::default(),
            trial: Vec::new(),
            jtj: Vec::new(),
            jtr: Vec::new(),
            a: Vec::new(),
            step: Vec::new(),
            first: Vec::new(),
            stats: FitStats::default(),
            compare: false,
        }
    }

    /// Projects every component onto the feasible set (e ≥ 0, min_w ≤ σ ≤ n, −n ≤ μ ≤ 2n).
    pub(crate) fn project(&self, comps: &mut [Comp]) {
        let n = self.y.len() as f64;
        for c in comps {
            c.e = c.e.max(0.0);
            c.s = c.s.clamp(self.min_w, n.max(1.0));
            c.mu = c.mu.clamp(-n, 2.0 * n);
        }
    }

    /// Normal equations `JᵀJ`, `Jᵀr` at the current evaluation, and the envelope of `JᵀJ`.
    pub(crate) fn normal_equations(&mut self, comps: &[Comp]) {
        let np = 3 * comps.len();
        let ev = &self.cur;
        self.jtj.clear();
        self.jtj.resize(np * np, 0.0);
        self.jtr.clear();
        self.jtr.resize(np, 0.0);
        self.first.clear();
        self.first.extend((0..np).map(|p| p - p % 3));
        // Each dot product accumulates bin by bin from −0.0 as `Iterator::sum` does, so the
        // fused loops below (one pass over the bins for the 3 or 9 products of a block) give
        // the same bits as separate sums.
        for j in 0..comps.len() {
            let (lo, hi, off) = ev.spans[j];
            let len = hi - lo;
            let (e1, m1, s1) = (
                &ev.d_e[off..off + len],
                &ev.d_mu[off..off + len],
                &ev.d_s[off..off + len],
            );
            let (yj, mj) = (&self.y[lo..hi], &ev.model[lo..hi]);
            let mut r3 = [-0.0f64; 3];
            for k in 0..len {
                let res = yj[k] - mj[k];
                r3[0] += e1[k] * res;
                r3[1] += m1[k] * res;
                r3[2] += s1[k] * res;
            }
            self.jtr[3 * j..3 * j + 3].copy_from_slice(&r3);
            for l in j..comps.len() {
                let (lo2, hi2, off2) = ev.spans[l];
                let (a, b) = (lo.max(lo2), hi.min(hi2));
                if a >= b {
                    continue;
                }
                let n = b - a;
                let (u0, u1, u2) = (
                    &e1[a - lo..b - lo],
                    &m1[a - lo..b - lo],
                    &s1[a - lo..b - lo],
                );
                let o2 = off2 + a - lo2;
                let (v0, v1, v2) = (
                    &ev.d_e[o2..o2 + n],
                    &ev.d_mu[o2..o2 + n],
                    &ev.d_s[o2..o2 + n],
                );
                let mut acc = [-0.0f64; 9];
                for k in 0..n {
                    let u = [u0[k], u1[k], u2[k]];
                    let v = [v0[k], v1[k], v2[k]];
                    for p in 0..3 {
                        for q in 0..3 {
                            acc[3 * p + q] += u[p] * v[q];
                        }
                    }
                }
                for p in 0..3 {
                    for q in 0..3 {
                        let s = acc[3 * p + q];
                        let (r, c) = (3 * j + p, 3 * l + q);
                        self.jtj[r * np + c] = s;
                        self.jtj[c * np + r] = s;
                    }
                }
                // Row block l couples back to column block j.
                for q in 0..3 {
                    let row = 3 * l + q;
                    self.first[row] = self.first[row].min(3 * j);
                }
            }
        }
    }

    /// Levenberg–Marquardt from `comps` (sorted by centre on return); returns the final χ²
    /// (normalised units). Afterwards `self.cur` holds the evaluation of the result.
    ///
    /// Algorithm: Madsen, Nielsen & Tingleff 2004, *Methods for non-linear least squares
    /// problems* (2nd ed., IMM, DTU), Algorithm 3.16, with Marquardt's scaled damping
    /// `(JᵀJ + λ diag(JᵀJ)) h = Jᵀr` (Marquardt 1963; the scaling makes λ independent of the
    /// units of energy, centre and width), applied to the bin-integrated Gaussian model of
    /// Hofton, Minster & Blair 2000.
    ///
    /// Damping: for the first [`LM_MARQUARDT_ITERATIONS`] iterations Marquardt's schedule
    /// (λ₀ = 1e-3; ÷10 after an accepted step, ×10 after a rejected one), the schedule of the
    /// previous fitter, so a fit follows the same path and never ends above it; its greedy
    /// Gauss–Newton-like steps also find the lower minima more often (per fit from the same
    /// start, Nielsen's update from the first iteration ended lower in 20 % and higher in 16 %
    /// of the forest bench's fits). A fit still running after that (slow linear convergence
    /// along a flat χ² valley of overlapping components) switches to Nielsen's update (MNT
    /// eq. 3.13): an accepted step of gain ratio `ρ = (χ² − χ²_new) / predicted reduction`
    /// multiplies λ by `max(1/3, 1 − (2ρ − 1)³)` and resets ν = 2, a rejected one multiplies λ
    /// by ν and doubles ν.
    ///
    /// Stopping rules (scale-free; MNT §3.2 and the tests of MINPACK, Moré 1978):
    /// * **gradient**: every Jacobian column is within [`LM_GTOL`] of orthogonal to the
    ///   residual (`|J_pᵀr| ≤ gtol ‖J_p‖ ‖r‖`, MINPACK's gtol: a stationary point);
    /// * **step**: a step moves no component by more than [`LM_XTOL`] relative
    ///   (`|Δe| ≤ xtol e`, `|Δμ|, |Δσ| ≤ xtol σ`: centres are measured in widths);
    /// * **reduction**: the actual and the predicted relative reductions of χ² by an accepted
    ///   step are both ≤ [`LM_FTOL`] (MINPACK's ftol);
    /// * χ² at its rounding floor, or no damping gives a step that reduces χ²;
    /// * the iteration cap (`max_iterations`, 200 in the LiDAR pipeline): a safety net that the
    ///   tests pre-empt in 97–99 % of the forest bench's fits (the previous rule, a step gaining
    ///   < 1e-13, left 32–37 % of them at its 60-iteration cap).
    pub(crate) fn fit(&mut self, comps: &mut [Comp]) -> f64 {
        if !self.compare {
            return self.lm(comps, false);
        }
        // Diagnostics: the legacy fit from the same start, uncounted, then the real one.
        let mut old = comps.to_vec();
        let counters = self.stats.clone();
        let chi2_old = self.lm(&mut old, true);
        self.stats = counters;
        let chi2 = self.lm(comps, false);
        self.stats.chi2_pairs.push((chi2_old, chi2));
        chi2
    }

    /// The Levenberg–Marquardt loop of [`Fitter::fit`]; `legacy`: the previous fitter
    /// (Marquardt's ×10 / ×0.1 damping schedule, stop when an accepted step gains < 1e-13
    /// relative or at the cap; kept for the comparison of [`detect_returns_stats`](super::detect_returns_stats)).
    pub(crate) fn lm(&mut self, comps: &mut [Comp], legacy: bool) -> f64 {
        self.project(comps);
        comps.sort_by(|a, b| a.mu.total_cmp(&b.mu));
        let np = 3 * comps.len();
        self.cur.compute(self.y, comps);
        self.stats.fits += 1;
        self.stats.evaluations += 1;
        let mut chi2 = self.cur.chi2;
        let mut lambda = LM_LAMBDA0;
        let mut nu = 2.0;
        let mut converged = false;
        // Relative improvements of the last three accepted steps.
        let mut recent = [f64::INFINITY; 3];
        let cap = if legacy {
            self.max_iter.min(LEGACY_CAP)
        } else {
            self.max_iter
        };
        for it in 0..cap {
            let marquardt = legacy || it < LM_MARQUARDT_ITERATIONS;
            if !(chi2 > 1e-30) || (!legacy && chi2 <= self.rounding_chi2) {
                converged = true;
                break;
            }
            self.stats.iterations += 1;
            self.normal_equations(comps);
            if !legacy {
                // Gradient test: largest cosine between the residual and a Jacobian column.
                let rnorm = chi2.sqrt();
                let mut cos_max: f64 = 0.0;
                for p in 0..np {
                    let d = self.jtj[p * np + p];
                    if d > 0.0 {
                        cos_max = cos_max.max(self.jtr[p].abs() / (d.sqrt() * rnorm));
                    }
                }
                if cos_max <= LM_GTOL {
                    converged = true;
                    break;
                }
            }
            let max_diag = (0..np).map(|p| self.jtj[p * np + p]).fold(0.0, f64::max);
            let mut accepted = false;
            let mut done = false;
            let mut improvement = 0.0;
            let lambda_max = if marquardt { 1e12 } else { 1e16 };
            while lambda < lambda_max {
                self.a.clear();
                self.a.extend_from_slice(&self.jtj);
                for p in 0..np {
                    self.a[p * np + p] += lambda * self.jtj[p * np + p] + 1e-14 * max_diag;
                }
                self.step.clear();
                self.step.extend_from_slice(&self.jtr);
                if !envelope_cholesky_solve(&mut self.a, &mut self.step, &self.first, np) {
                    if marquardt {
                        lambda *= 10.0;
                    } else {
                        lambda *= nu;
                        nu *= 2.0;
                    }
                    continue;
                }
                // Predicted reduction of χ² by the linear model: ‖r‖² − ‖r − J h‖²
                // = hᵀ(Jᵀr) + hᵀ D h, D the added diagonal (MNT eq. 3.14 with χ² = 2F).
                let mut predicted = 0.0;
                for p in 0..np {
                    let h = self.step[p];
                    let d = lambda * self.jtj[p * np + p] + 1e-14 * max_diag;
                    predicted += h * (self.jtr[p] + d * h);
                }
                self.trial.clear();
                self.trial.extend_from_slice(comps);
                for (j, c) in self.trial.iter_mut().enumerate() {
                    c.e += self.step[3 * j];
                    c.mu += self.step[3 * j + 1];
                    c.s += self.step[3 * j + 2];
                }
                let mut trial = std::mem::take(&mut self.trial);
                self.project(&mut trial);
                // Step test on the projected step, component by component (before sorting).
                let small_step = !legacy
                    && trial.iter().zip(comps.iter()).all(|(t, c)| {
                        (t.e - c.e).abs() <= LM_XTOL * c.e
                            && (t.mu - c.mu).abs() <= LM_XTOL * c.s
                            && (t.s - c.s).abs() <= LM_XTOL * c.s
                    });
                self.trial = trial;
                // A step may reorder the centres; the envelope needs them sorted.
                self.trial.sort_by(|a, b| a.mu.total_cmp(&b.mu));
                self.next.compute(self.y, &self.trial);
                self.stats.evaluations += 1;
                let chi2_new = self.next.chi2;
                if chi2_new < chi2 {
                    let actual = chi2 - chi2_new;
                    improvement = actual / chi2;
                    if marquardt {
                        lambda = (lambda * 0.1).max(1e-12);
                    } else {
                        let rho = if predicted > 0.0 {
                            actual / predicted
                        } else {
                            0.0
                        };
                        lambda =
                            (lambda * (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0)).max(1e-15);
                        nu = 2.0;
                    }
                    if !legacy {
                        done =
                            small_step || (improvement <= LM_FTOL && predicted <= LM_FTOL * chi2);
                    }
                    comps.copy_from_slice(&self.trial);
                    std::mem::swap(&mut self.cur, &mut self.next);
                    chi2 = chi2_new;
                    accepted = true;
                    break;
                }
                if chi2 <= self.rounding_chi2 || small_step {
                    // χ² is at its rounding floor, or the step no longer moves the
                    // parameters: no step can be resolved any more.
                    break;
                }
                if marquardt {
                    lambda *= 10.0;
                } else {
                    lambda *= nu;
                    nu *= 2.0;
                }
            }
            recent[it % 3] = improvement;
            if !accepted
                || done
                || (legacy && improvement < 1e-13)
                || recent.iter().sum::<f64>() < self.rel_tol
            {
                converged = true;
                break;
            }
        }
        if !converged {
            self.stats.capped += 1;
        }
        chi2
    }
}

/// Iteration cap of the legacy fitter run by [`detect_returns_stats`](super::detect_returns_stats) for comparison (the
/// previous LiDAR pipeline setting).
pub(crate) const LEGACY_CAP: usize = 60;
/// Iterations with Marquardt's damping schedule before `Fitter::fit` switches to Nielsen's.
pub const LM_MARQUARDT_ITERATIONS: usize = 60;
/// Initial damping λ of [`Fitter::fit`] (relative to diag(JᵀJ); MNT's τ = 1e-3).
pub(crate) const LM_LAMBDA0: f64 = 1e-3;
/// Gradient tolerance of `Fitter::fit`: largest cosine between the residual and a Jacobian
/// column at a stationary point. The three tolerances are ~√ε, MINPACK's defaults (1.49e-8):
/// on the forest bench (256 pulses × 2 samplers), 1e-10 instead cost 22 % more fit
/// instructions (fits creeping along flat valleys gain ~1e-9 per step for dozens of steps),
/// and left 4 instead of 30 of ~1560 fits more than 1e-6 above the legacy fitter.
pub const LM_GTOL: f64 = 1e-8;
/// Step tolerance of `Fitter::fit`: relative change of energies, and of centres and widths
/// in units of the width.
pub const LM_XTOL: f64 = 1e-8;
/// Reduction tolerance of `Fitter::fit`: actual and predicted relative reductions of χ².
pub const LM_FTOL: f64 = 1e-8;

/// Solves `a x = b` in place (`b` becomes x) for a symmetric positive-definite row-major
/// n×n matrix whose row `i` has no non-zero left of column `first[i]` (its envelope), by
/// Cholesky factorisation `a = L Lᵀ` restricted to the envelope (fill-in stays inside it;
/// George & Liu 1981, *Computer Solution of Large Sparse Positive Definite Systems*, ch. 4).
/// Returns false if the matrix is not numerically positive definite.
pub(crate) fn envelope_cholesky_solve(
    a: &mut [f64],
    b: &mut [f64],
    first: &[usize],
    n: usize,
) -> bool {
    // L overwrites the lower triangle; its diagonal is stored inverted (one division per row).
    for i in 0..n {
        let fi = first[i];
        for j in fi..=i {
            let fj = first[j].max(fi);
            let (ri, rj) = (&a[i * n..i * n + j], &a[j * n..j * n + j]);
            let dot: f64 = ri[fj..j].iter().zip(&rj[fj..j]).map(|(x, y)| x * y).sum();
            let s = a[i * n + j] - dot;
            if j == i {
                if !(s > 0.0) || !s.is_finite() {
                    return false;
                }
                a[i * n + i] = 1.0 / s.sqrt();
            } else {
                a[i * n + j] = s * a[j * n + j];
            }
        }
    }
    // L y = b.
    for i in 0..n {
        let dot: f64 = (first[i]..i).map(|k| a[i * n + k] * b[k]).sum();
        b[i] = (b[i] - dot) * a[i * n + i];
    }
    // Lᵀ x = y.
    for i in (0..n).rev() {
        let xi = b[i] * a[i * n + i];
        b[i] = xi;
        for k in first[i]..i {
            b[k] -= a[i * n + k] * xi;
        }
    }
    b.iter().all(|v| v.is_finite())
}

// ------------------------------------------------------------------------ normal tail

/// Upper tail and density of the standard normal at |z|: `(Q(|z|), φ(z))` with
/// `Q(x) = ½ erfc(x/√2)` and `φ(z) = e^{−z²/2}/√(2π)`, sharing one `exp`.
///
/// `Q(x) = φ(x) M(x)` with Mills' ratio `M` (Abramowitz & Stegun 1964, eq. 26.2.1 and
/// 7.1.2) evaluated on [0, 12) by a degree-15 near-minimax polynomial per unit interval
/// (`MILLS`, relative error < 1.5e-17); `z²` is split exactly (Dekker 1971, *Numer. Math.*
/// 18:224) so `exp`'s argument carries no rounding. Relative error < 1e-14 for both values
/// on |z| < 12 (checked against 50-digit mpmath values); beyond, `libm::erfc` (the tail is
/// below 2e-33 there). Costs one `exp` and a 16-term polynomial (Estrin's scheme): about half
/// of `libm::erfc` plus `exp` for the same pair.
pub fn normal_tail_and_pdf(z: f64) -> (f64, f64) {
    const FRAC_1_SQRT_2PI: f64 = 0.398_942_280_401_432_7;
    let x = z.abs();
    if !(x < 38.0) {
        // φ underflows (e^{−722}); NaN propagates.
        return if x.is_nan() {
            (f64::NAN, f64::NAN)
        } else {
            (0.0, 0.0)
        };
    }
    // x² = h + l exactly.
    let h = x * x;
    let t = 134_217_729.0 * x;
    let xh = t - (t - x);
    let xl = x - xh;
    let l = ((xh * xh - h) + 2.0 * xh * xl) + xl * xl;
    let pdf = (-0.5 * h).exp() * (1.0 - 0.5 * l) * FRAC_1_SQRT_2PI;
    if x < 12.0 {
        let k = x as usize;
        let u = x - (k as f64 + 0.5);
        let c = &MILLS[k];
        // Estrin's scheme: a 4-deep dependency chain instead of Horner's 15.
        let u2 = u * u;
        let u4 = u2 * u2;
        let u8 = u4 * u4;
        let p01 = c[0] + c[1] * u;
        let p23 = c[2] + c[3] * u;
        let p45 = c[4] + c[5] * u;
        let p67 = c[6] + c[7] * u;
        let p89 = c[8] + c[9] * u;
        let pab = c[10] + c[11] * u;
        let pcd = c[12] + c[13] * u;
        let pef = c[14] + c[15] * u;
        let q0 = p01 + p23 * u2;
        let q1 = p45 + p67 * u2;
        let q2 = p89 + pab * u2;
        let q3 = pcd + pef * u2;
        let m = (q0 + q1 * u4) + (q2 + q3 * u4) * u8;
        (pdf * m, pdf)
    } else {
        (0.5 * libm::erfc(x * FRAC_1_SQRT_2), pdf)
    }
}

/// Mills' ratio `M(z) = Q(z)/φ(z) = √(π/2) erfcx(z/√2)` on `[k, k+1)`, k = 0…11: coefficients
/// of a polynomial in `u = z − (k + ½)`, lowest degree first. Generated with mpmath 1.3
/// (`chebyfit` of the 50-digit `M` on each interval, 16 coefficients); worst relative
/// approximation error 1.4e-17.
#[rustfmt::skip]
pub(crate) const MILLS: [[f64; 16]; 12] = [
    [0.8763644564536923, -0.5618177717731538, 0.297727785283562, -0.13765129304379262, 0.05722553469005981, -0.021807705139636965, 0.007720280364796585, -0.002563937854409546, 0.000804788750043179, -0.00024017144747512611, 6.84718367681833e-05, -1.872182521399934e-05, 4.918653757912386e-06, -1.2490563194085124e-06, 3.245947108012785e-07, -7.70509383675e-08],
    [0.5158156382179634, -0.22627654267305497, 0.08820041210419056, -0.031325308172256455, 0.010303112461441867, -0.0031741278960139407, 0.0009236534365444435, -0.00025552110601233897, 6.754646735353924e-05, -1.713348767553033e-05, 4.184664884340517e-06, -9.869675032775848e-07, 2.2515580646752385e-07, -4.987972133271391e-08, 1.1219305425332043e-08, -2.3470458044710493e-09],
    [0.35426511132979366, -0.11433722167551583, 0.034211028570502046, -0.009603216749753576, 0.002550746674029138, -0.0006452700129358837, 0.00015626194029399657, -3.6373594606758855e-05, 8.165994026782861e-06, -1.7731787489967223e-06, 3.7330638318748784e-07, -7.63563818270698e-08, 1.5193398837487475e-08, -2.9488506490773727e-09, 5.780823500400691e-10, -1.0691029152545348e-10],
    [0.26656776896822376, -0.06701280861121685, 0.01601146941448239, -0.0036575552201761606, 0.0008025065359664353, -0.0001697564688587083, 3.4726482494204786e-05, -6.887682876038507e-06, 1.3274490423141508e-06, -2.490679080973226e-07, 4.557123195820543e-08, -8.142645130558667e-09, 1.4222126234680326e-09, -2.4326100107203466e-10, 4.1883961102283895e-11, -6.879571390908064e-12],
    [0.21257058044203178, -0.04343238801085694, 0.008562417196587771, -0.0016338368754039913, 0.0003025378143174509, -5.4483342195090663e-05, 9.56046240664557e-06, -1.637323052212577e-06, 2.740635830951596e-07, -4.489299147613309e-08, 7.204519536897349e-09, -1.133881665905156e-09, 1.751360526580789e-10, -2.6580604438184176e-11, 4.052002555375566e-12, -5.944340498610954e-13],
    [0.1763229857571027, -0.030223578335935124, 0.005046652454729764, -0.0008223299449738075, 0.00013095943934345546, -2.0410605716960275e-05, 3.1168513167011664e-06, -4.6684621073415325e-07, 6.86496446213413e-08, -9.91924052679908e-09, 1.4093829113318527e-09, -1.9705814691659544e-10, 2.7126764764571516e-11, -3.679686602169525e-12, 5.006365643418228e-13, -6.599812949103445e-14],
    [0.1504369887362691, -0.022159573214250952, 0.0031998814218189477, -0.00045344799080926417, 6.311737038968263e-05, -8.637016655265382e-06, 1.1627936884102944e-06, -1.541225258004971e-07, 2.012465882760597e-08, -2.590249259975403e-09, 3.288039557574465e-10, -4.1184023872523697e-11, 5.091881826511292e-12, -6.217931015127056e-13, 7.608683496045355e-14, -9.069917497389227e-15],
    [0.13107935580449176, -0.016904831466311773, 0.0021465599035767296, -0.00026854406316209996, 3.3119857465245006e-05, -4.029026434552485e-06, 4.836932010169972e-07, -5.7332489560836284e-08, 6.712441162221978e-09, -7.765756478325126e-10, 8.881239416264054e-11, -1.0043891934545889e-11, 1.1235350725248097e-12, -1.2436917571800035e-13, 1.3786955697324647e-14, -1.4951977754133632e-15],
    [0.11608206338598229, -0.013302461219150533, 0.0015055715116013837, -0.00016836779017959035, 1.8611323768716442e-05, -2.0343076291001153e-06, 2.1995148689426191e-07, -2.353142721415085e-08, 2.491794446461749e-09, -2.612416018387008e-10, 2.712408552166473e-11, -2.7897180209408624e-12, 2.8427866708110355e-13, -2.871052550403796e-14, 2.9026085272080583e-15, -2.8805778913965715e-16],
    [0.10413358157959825, -0.010730974993816613, 0.001094659569170216, -0.00011056969556652037, 1.1061865322068104e-05, -1.0963950013746778e-06, 1.0768546816811454e-07, -1.0483293396803851e-08, 1.0117726122517678e-09, -9.682817553496542e-11, 9.190494961736926e-12, -8.653162350118617e-13, 8.083022158672282e-14, -7.492629990341976e-15, 6.950610634655532e-16, -6.346519383776685e-17],
    [0.09439676005522439, -0.008834019420143953, 0.0008197780718564388, -7.54498885504486e-05, 6.888560519182145e-06, -6.24000619807213e-07, 5.609233520106903e-08, -5.004442885142502e-09, 4.4321061337081703e-10, -3.897016051106869e-11, 3.402392913775373e-12, -2.9500329176359496e-13, 2.5404326802276594e-14, -2.173204517821744e-15, 1.8601017058535193e-16, -1.570554950104655e-17],
    [0.08631338487354935, -0.007396073954182387, 0.0006292672002259543, -5.316705052797095e-05, 4.461529788572094e-06, -3.718915918783723e-07, 3.0796080328469026e-08, -2.5338097287115833e-09, 2.0715855603234714e-10, -1.6831814922042217e-11, 1.3592684717314056e-12, -1.0911162302543118e-13, 8.706930875765479e-15, -6.907856288941118e-16, 5.4828280295714356e-17, -4.300592616372621e-18],
];
