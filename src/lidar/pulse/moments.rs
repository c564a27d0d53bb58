//! Moments of the truncated footprint over axis-aligned rectangles ([`FootprintMoments`]; the
//! column quadrature of the LiDAR first-order return, physics.md §9.2, §9.6): corner masses
//! by Gauss–Legendre quadrature at construction, bicubic Hermite interpolation at query.

use super::sampler::{FootprintSampler, RadialShape, RadialTable};
use std::f64::consts::PI;

/// Cells per radial interval along `u` and along `w` in the [`FootprintMoments`] tables.
pub(crate) const MOMENT_CELLS: usize = 40;
/// Radial intervals of the [`FootprintMoments`] tables are at most `reach/MOMENT_SPLIT` long.
pub(crate) const MOMENT_SPLIT: f64 = 6.0;
/// The untruncated Gaussian is cut where the tail mass `exp(−r²/(2σ²))` is 1e-16.
pub(crate) const GAUSSIAN_CUT_TAIL: f64 = 1e-16;

/// Moments of the truncated, renormalised footprint distribution of a [`FootprintSampler`] over
/// axis-aligned rectangles of the transverse plane, built once per instrument by
/// [`FootprintSampler::moments`].
///
/// **Method.** A rectangle is a signed sum of four corner masses `Q(a, b)` of
/// `{x > a, y > b}`; with the mirror symmetries of a radial density every `Q` reduces to the
/// half-plane mass `H(c)` of `{x > c}` and the quadrant mass `C(a, b)`, a, b, c ≥ 0. In polar
/// coordinates `C(a, b) = [P(a, b) + P(b, a)]/(2π)` and `H(c) = P(c, 0)/π`, with
/// `P(a, b) = ∫_{θ0}^{arccos(a/R_t)} [M(R_t) − M(a/cos θ)] dθ`, `θ0 = atan2(b, a)`, M the radial
/// CDF F (for m0) or the partial second moment `G(r) = ∫_0^r r'² dF(r')` (m², for m2), both
/// normalised by the kept mass `F(R_t)`. At construction `P` is computed by composite 8-point
/// Gauss–Legendre quadrature in `v` with `a/cos θ = a cosh v` (`θ = gd v`, `dθ = sech v dv`,
/// which removes the square-root behaviour at `r = a`), split where `a cosh v` crosses a radius
/// at which the density or its slope jumps, on a grid over corner radius `r0 = √(a² + b²)` and
/// direction `w = b/(a + b)`. The radius axis is cut into intervals ending at those radii; within
/// `[τ_lo, τ_hi]` the variable is `u = √((τ_hi − r0)/(τ_hi − τ_lo))`, which makes the
/// `(τ_hi − r0)^{3/2}` behaviour of `P` below a density jump smooth. Queries use bicubic
/// Hermite interpolation (derivatives from 4th-order finite differences of the grid), with no
/// transcendental function besides three square roots per corner.
///
/// Units: lengths in m, m0 dimensionless, m2 in m².
#[derive(Debug, Clone)]
pub struct FootprintMoments {
    pub(crate) reach_m: f64,
    /// `E[ρ²]` of the truncated distribution (m²).
    pub(crate) total_m2: f64,
    /// Interval bounds `0 = τ_0 < … < τ_n = reach` (m).
    pub(crate) tau: Vec<f64>,
    /// `1/(τ_{k+1} − τ_k)` (m⁻¹).
    pub(crate) inv_len: Vec<f64>,
    /// Bicubic coefficients `a_mn` (index `4m + n`) of `P0` then `P2` (m²) per cell, cell
    /// `(k·CELLS + iu)·CELLS + iw`.
    pub(crate) cells: Vec<[f64; 32]>,
}

/// Derivative in index units of grid values (≥ 5) by 4th-order finite differences (central
/// inside, one-sided at the two first and last nodes; Abramowitz & Stegun 25.3.6 family).
pub(crate) fn fd_derivative(f: &[f64]) -> Vec<f64> {
    let n = f.len() - 1;
    let mut d = vec![0.0; n + 1];
    d[0] = (-25.0 * f[0] + 48.0 * f[1] - 36.0 * f[2] + 16.0 * f[3] - 3.0 * f[4]) / 12.0;
    d[1] = (-3.0 * f[0] - 10.0 * f[1] + 18.0 * f[2] - 6.0 * f[3] + f[4]) / 12.0;
    for i in 2..n - 1 {
        d[i] = (f[i - 2] - 8.0 * f[i - 1] + 8.0 * f[i + 1] - f[i + 2]) / 12.0;
    }
    d[n - 1] = (3.0 * f[n] + 10.0 * f[n - 1] - 18.0 * f[n - 2] + 6.0 * f[n - 3] - f[n - 4]) / 12.0;
    d[n] =
        (25.0 * f[n] - 48.0 * f[n - 1] + 36.0 * f[n - 2] - 16.0 * f[n - 3] + 3.0 * f[n - 4]) / 12.0;
    d
}

/// Bicubic Hermite coefficients `A = M F Mᵀ` on the unit cell from values, derivatives and cross
/// derivative at its corners (index units), `F` ordered as in the usual bicubic-interpolation
/// formulation (Press et al., *Numerical Recipes* 3rd ed. §3.6.1).
pub(crate) fn hermite_cell(f: [[f64; 4]; 4]) -> [f64; 16] {
    const M: [[f64; 4]; 4] = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [-3.0, 3.0, -2.0, -1.0],
        [2.0, -2.0, 1.0, 1.0],
    ];
    let mut mf = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            mf[i][j] = (0..4).map(|k| M[i][k] * f[k][j]).sum();
        }
    }
    let mut a = [0.0; 16];
    for i in 0..4 {
        for j in 0..4 {
            a[4 * i + j] = (0..4).map(|k| mf[i][k] * M[j][k]).sum();
        }
    }
    a
}

/// `(F(r), G(r))` of the untruncated radial profile: energy fraction within r and
/// `G(r) = ∫_0^r r'² dF(r')` (m²). Gaussian `G = 2σ²F − r² e^{−r²/(2σ²)}`; uniform
/// `F = x², G = R²x⁴/2` (x = min(r/R, 1)); table from the exact per-segment polynomials.
pub(crate) struct RadialMoments<'a> {
    pub(crate) sampler: &'a FootprintSampler,
    /// Table only: `∫_0^{x_i} x³ I(x) dx` at the nodes.
    pub(crate) cum2: Vec<f64>,
}

impl RadialMoments<'_> {
    pub(crate) fn new(sampler: &FootprintSampler) -> RadialMoments<'_> {
        let mut cum2 = Vec::new();
        if let RadialShape::Tabulated(t) = &sampler.shape {
            cum2.push(0.0);
            for k in 0..t.x.len() - 1 {
                let h = t.x[k + 1] - t.x[k];
                let prev = cum2[k];
                cum2.push(prev + Self::segment_m2(t, k, h));
            }
        }
        RadialMoments { sampler, cum2 }
    }

    /// `∫_{x_k}^{x_k+τ} x³ I(x) dx` with I linear on the segment, expanded in the local τ.
    pub(crate) fn segment_m2(t: &RadialTable, k: usize, tau: f64) -> f64 {
        let a = t.x[k];
        let ia = t.intensity[k];
        let s = (t.intensity[k + 1] - ia) / (t.x[k + 1] - a);
        // (a+τ)³(ia + sτ) = Σ c_n τ^n.
        let c = [
            a * a * a * ia,
            3.0 * a * a * ia + a * a * a * s,
            3.0 * a * ia + 3.0 * a * a * s,
            ia + 3.0 * a * s,
            s,
        ];
        let mut acc = 0.0;
        let mut p = tau;
        for (n, cn) in c.iter().enumerate() {
            acc += cn * p / (n + 1) as f64;
            p *= tau;
        }
        acc
    }

    pub(crate) fn eval(&self, r: f64) -> (f64, f64) {
        let s = self.sampler;
        if !(r > 0.0) {
            return (0.0, 0.0);
        }
        match &s.shape {
            RadialShape::Gaussian { sigma_m } => {
                let q = -0.5 * (r / sigma_m).powi(2);
                let f = -q.exp_m1();
                (f, 2.0 * sigma_m * sigma_m * f - r * r * q.exp())
            }
            RadialShape::Uniform => {
                let x = (r / s.radius_m).min(1.0);
                (x * x, 0.5 * s.radius_m * s.radius_m * x.powi(4))
            }
            RadialShape::Tabulated(t) => {
                let x = r / s.radius_m;
                let n = t.x.len();
                let g = if !(x > t.x[0]) {
                    0.0
                } else if x >= t.x[n - 1] {
                    self.cum2[n - 1]
                } else {
                    let k = t.segment_of(x);
                    self.cum2[k] + Self::segment_m2(t, k, (x - t.x[k]).max(0.0))
                };
                (
                    (t.mass_within(x) / t.total()).min(1.0),
                    s.radius_m * s.radius_m * g / t.total(),
                )
            }
        }
    }
}

impl FootprintSampler {
    /// [`Self::moments`] through a process-wide cache of the last
    /// [`FOOTPRINT_MOMENTS_CACHE`] samplers (equal samplers share one table): a table costs
    /// 10–40 ms to build, which runs that each simulate one instrument (look-up tables, the
    /// tests) would otherwise pay again and again.
    pub fn moments_shared(&self) -> std::sync::Arc<FootprintMoments> {
        type Cache = Vec<(FootprintSampler, std::sync::Arc<FootprintMoments>)>;
        static CACHE: std::sync::Mutex<Cache> = std::sync::Mutex::new(Vec::new());
        let lock = || CACHE.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, m)) = lock().iter().find(|(s, _)| s == self) {
            return m.clone();
        }
        // Built outside the lock (two threads may both build one; either is kept).
        let m = std::sync::Arc::new(self.moments());
        let mut c = lock();
        if c.len() >= FOOTPRINT_MOMENTS_CACHE {
            c.remove(0);
        }
        c.push((self.clone(), m.clone()));
        m
    }

    /// Precomputes the rectangle moments of this sampler's truncated, renormalised distribution
    /// (see [`FootprintMoments`]); a few ms to a few tens of ms (tables with many nodes take
    /// longer: one set of grids per radial interval between nodes).
    pub fn moments(&self) -> FootprintMoments {
        let rm = RadialMoments::new(self);
        // 8-point Gauss–Legendre rule on [−1, 1].
        let (gl_x, gl_w) = crate::physics::lad::gauss_legendre(8);
        // Outer edge of the support and the radii where the density or its slope jumps.
        let mut natural: Vec<f64> = Vec::new();
        let support = match &self.shape {
            RadialShape::Gaussian { sigma_m } => sigma_m * (-2.0 * GAUSSIAN_CUT_TAIL.ln()).sqrt(),
            RadialShape::Uniform => self.radius_m,
            RadialShape::Tabulated(t) => {
                natural.extend(t.x.iter().map(|x| x * self.radius_m));
                self.radius_m * t.x[t.x.len() - 1]
            }
        };
        let reach = self.truncation_radius_m.min(support);
        natural.retain(|&r| r > 0.0 && r < reach);
        natural.insert(0, 0.0);
        natural.push(reach);
        let mut tau = vec![0.0];
        for pair in natural.windows(2) {
            let m = ((pair[1] - pair[0]) / (reach / MOMENT_SPLIT))
                .ceil()
                .max(1.0) as usize;
            for i in 1..=m {
                tau.push(if i == m {
                    pair[1]
                } else {
                    pair[0] + (pair[1] - pair[0]) * i as f64 / m as f64
                });
            }
        }
        let (k0, k2) = rm.eval(reach);
        let total_m2 = k2 / k0;
        // P(a, b) for the grid: (P0, P2/m²), normalised by the kept mass k0.
        let p_of = |r0: f64, w: f64| -> (f64, f64) {
            let psi = w.atan2(1.0 - w);
            if r0 <= 0.0 {
                let ang = 0.5 * PI - psi;
                return (ang, ang * total_m2);
            }
            if r0 >= reach || w >= 1.0 {
                return (0.0, 0.0);
            }
            let n = w.hypot(1.0 - w);
            let a = r0 * (1.0 - w) / n;
            let b = r0 * w / n;
            let v0 = (b / a).asinh();
            let v1 = (reach / a).acosh();
            let mut cuts = vec![v0];
            cuts.extend(
                tau.iter()
                    .filter(|&&t| t > r0 && t < reach)
                    .map(|&t| (t / a).acosh())
                    .filter(|&v| v > v0 && v < v1),
            );
            cuts.push(v1);
            let (mut s0, mut s2) = (0.0, 0.0);
            for c in cuts.windows(2) {
                let pieces = ((c[1] - c[0]) / 0.2).ceil().max(1.0) as usize;
                let h = (c[1] - c[0]) / pieces as f64;
                for p in 0..pieces {
                    let mid = c[0] + (p as f64 + 0.5) * h;
                    for (x, wt) in gl_x.iter().zip(&gl_w) {
                        let v = mid + 0.5 * h * x;
                        let (f, g) = rm.eval((a * v.cosh()).min(reach));
                        let ww = 0.5 * h * wt / v.cosh();
                        s0 += ww * (k0 - f);
                        s2 += ww * (k2 - g);
                    }
                }
            }
            (s0 / k0, s2 / k0)
        };
        let nc = MOMENT_CELLS;
        let inv_len: Vec<f64> = tau.windows(2).map(|t| 1.0 / (t[1] - t[0])).collect();
        // The intervals' cells in parallel (each interval's values depend on it alone, so the
        // table is the same on any number of threads).
        use rayon::prelude::*;
        let per_interval: Vec<Vec<[f64; 32]>> = (0..tau.len() - 1)
            .into_par_iter()
            .map(|k| {
                let (lo, hi) = (tau[k], tau[k + 1]);
                // Grid values [moment][i_u][i_w].
                let mut val = vec![vec![vec![0.0; nc + 1]; nc + 1]; 2];
                for i in 0..=nc {
                    let u = i as f64 / nc as f64;
                    let r0 = if i == nc { lo } else { hi - (hi - lo) * u * u };
                    for j in 0..=nc {
                        let (p0, p2) = p_of(r0, j as f64 / nc as f64);
                        val[0][i][j] = p0;
                        val[1][i][j] = p2;
                    }
                }
                let mut coef = vec![[0.0; 32]; nc * nc];
                for (mo, v) in val.iter().enumerate() {
                    let dw: Vec<Vec<f64>> = v.iter().map(|row| fd_derivative(row)).collect();
                    let col = |g: &Vec<Vec<f64>>, j: usize| -> Vec<f64> {
                        fd_derivative(&g.iter().map(|row| row[j]).collect::<Vec<_>>())
                    };
                    let du: Vec<Vec<f64>> = (0..=nc).map(|j| col(v, j)).collect(); // [j][i]
                    let duw: Vec<Vec<f64>> = (0..=nc).map(|j| col(&dw, j)).collect();
                    for iu in 0..nc {
                        for iw in 0..nc {
                            let (i0, i1, j0, j1) = (iu, iu + 1, iw, iw + 1);
                            let a = hermite_cell([
                                [v[i0][j0], v[i0][j1], dw[i0][j0], dw[i0][j1]],
                                [v[i1][j0], v[i1][j1], dw[i1][j0], dw[i1][j1]],
                                [du[j0][i0], du[j1][i0], duw[j0][i0], duw[j1][i0]],
                                [du[j0][i1], du[j1][i1], duw[j0][i1], duw[j1][i1]],
                            ]);
                            coef[iu * nc + iw][16 * mo..16 * mo + 16].copy_from_slice(&a);
                        }
                    }
                }
                coef
            })
            .collect();
        let cells: Vec<[f64; 32]> = per_interval.into_iter().flatten().collect();
        FootprintMoments {
            reach_m: reach,
            total_m2,
            tau,
            inv_len,
            cells,
        }
    }
}

impl FootprintMoments {
    /// Radius (m) beyond which the distribution has no mass: the truncation radius, the outer
    /// edge of a uniform or tabulated profile, or for an untruncated Gaussian the radius where
    /// the tail mass is 1e-16 (`σ√(−2 ln 1e-16)` ≈ 8.6σ).
    pub fn reach_m(&self) -> f64 {
        self.reach_m
    }

    /// `E[ρ²]` (m²) of the truncated, renormalised distribution (the whole-plane m2).
    pub fn mean_square_radius_m2(&self) -> f64 {
        self.total_m2
    }

    /// Row of cells (interval k, u-cell iu) and local u-coordinate `s ∈ [0, 1]` of the cell for
    /// a corner radius `r0 < reach` (m).
    #[inline]
    pub(crate) fn locate(&self, r0: f64) -> (usize, f64) {
        let n = self.tau.len() - 1;
        let k = (self.tau.partition_point(|&t| t <= r0).max(1) - 1).min(n - 1);
        let u = ((self.tau[k + 1] - r0) * self.inv_len[k])
            .clamp(0.0, 1.0)
            .sqrt();
        let s = u * MOMENT_CELLS as f64;
        let iu = (s as usize).min(MOMENT_CELLS - 1);
        (k * MOMENT_CELLS + iu, s - iu as f64)
    }

    /// Interpolated `(P0, P2)` at row `row` (from [`Self::locate`]), local u-coordinate `s`,
    /// direction `w ∈ [0, 1]`.
    #[inline]
    pub(crate) fn p_at(&self, row: usize, s: f64, w: f64) -> (f64, f64) {
        let t = w.clamp(0.0, 1.0) * MOMENT_CELLS as f64;
        let iw = (t as usize).min(MOMENT_CELLS - 1);
        let t = t - iw as f64;
        let c = &self.cells[row * MOMENT_CELLS + iw];
        let poly = |o: usize| {
            let r = |m: usize| {
                let b = o + 4 * m;
                c[b] + t * (c[b + 1] + t * (c[b + 2] + t * c[b + 3]))
            };
            r(0) + s * (r(1) + s * (r(2) + s * r(3)))
        };
        (poly(0), poly(16))
    }

    /// Half-plane moments of `{x > c}`, c ≥ 0: `H(c) = P(c, 0)/π`.
    #[inline]
    pub(crate) fn half(&self, c: f64) -> (f64, f64) {
        if !(c < self.reach_m) {
            return (0.0, 0.0);
        }
        let (row, s) = self.locate(c);
        let cl = &self.cells[row * MOMENT_CELLS];
        let p0 = cl[0] + s * (cl[4] + s * (cl[8] + s * cl[12]));
        let p2 = cl[16] + s * (cl[20] + s * (cl[24] + s * cl[28]));
        (p0 / PI, p2 / PI)
    }

    /// Quadrant moments of `{x > a, y > b}`, a, b ≥ 0: `[P(a, b) + P(b, a)]/(2π)`.
    #[inline]
    pub(crate) fn quadrant(&self, a: f64, b: f64) -> (f64, f64) {
        let r2 = a * a + b * b;
        if !(r2 < self.reach_m * self.reach_m) {
            return (0.0, 0.0);
        }
        let r0 = r2.sqrt();
        let sum = a + b;
        let w = if sum > 0.0 { b / sum } else { 0.5 };
        let (row, s) = self.locate(r0);
        let (p0, p2) = self.p_at(row, s, w);
        let (q0, q2) = self.p_at(row, s, 1.0 - w);
        let k = 0.5 / PI;
        (k * (p0 + q0), k * (p2 + q2))
    }

    /// Moments `(m0, m2)` of the corner `{x > a, y > b}` for any a, b (±∞ allowed), from
    /// `Self::half` and `Self::quadrant` by the mirror symmetries of the radial density:
    /// [`Self::rect`] is the signed sum of four (callers with many rectangles on one grid of
    /// lines share them).
    #[inline]
    pub fn corner(&self, a: f64, b: f64) -> (f64, f64) {
        match (a >= 0.0, b >= 0.0) {
            (true, true) => self.quadrant(a, b),
            (false, true) => {
                let (h0, h2) = self.half(b);
                let (c0, c2) = self.quadrant(-a, b);
                (h0 - c0, h2 - c2)
            }
            (true, false) => {
                let (h0, h2) = self.half(a);
                let (c0, c2) = self.quadrant(a, -b);
                (h0 - c0, h2 - c2)
            }
            (false, false) => {
                let (ha0, ha2) = self.half(-a);
                let (hb0, hb2) = self.half(-b);
                let (c0, c2) = self.quadrant(-a, -b);
                (1.0 - ha0 - hb0 + c0, self.total_m2 - ha2 - hb2 + c2)
            }
        }
    }

    /// `(m0, m2)` of the rectangle `[x0, x1] × [y0, y1]` (m, transverse plane; bounds may be
    /// ±∞): m0 = probability that [`FootprintSampler::sample_footprint_point`] falls inside
    /// (1 for the whole plane), m2 = `E[ρ² · 1(rect)]` (m²). Zero for `x0 ≥ x1`, `y0 ≥ y1` or NaN
    /// bounds. Accuracy ≤ 1e-7 absolute in m0 and ≤ 1e-7·reach² in m2 (see the tests); a few
    /// hundred instructions per call.
    pub fn rect(&self, x0: f64, x1: f64, y0: f64, y1: f64) -> (f64, f64) {
        if !(x0 < x1 && y0 < y1) {
            return (0.0, 0.0);
        }
        let a = self.corner(x0, y0);
        let b = self.corner(x1, y0);
        let c = self.corner(x0, y1);
        let d = self.corner(x1, y1);
        (a.0 - b.0 - c.0 + d.0, a.1 - b.1 - c.1 + d.1)
    }
}

/// Footprint samplers whose moment tables [`FootprintSampler::moments_shared`] keeps.
pub const FOOTPRINT_MOMENTS_CACHE: usize = 8;
