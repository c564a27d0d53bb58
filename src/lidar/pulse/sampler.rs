//! Exact inverse-CDF sampling of a truncated radial footprint profile ([`FootprintSampler`];
//! physics.md §9.1): the validated piecewise-linear radial table with its cumulative energy,
//! per-segment Bernstein forms of the energy density and their CDF inversion.

use super::{BeamProfile, FootprintProfile, check_truncation, clamp_unit};
use crate::lidar::{LidarError, check_positive};
use std::f64::consts::PI;

/// Validated piecewise-linear radial profile in normalised radius x = ρ/R, with the exact
/// cumulative energy `M(x) = ∫_0^x I(x') x' dx'` at every node (the 2πR² factor cancels in all
/// fractions).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RadialTable {
    /// Nodes x_i (strictly increasing, x_0 ≥ 0).
    pub(crate) x: Vec<f64>,
    /// Intensities at the nodes divided by their maximum (so in [0, 1]).
    pub(crate) intensity: Vec<f64>,
    /// `M(x_i)`; `cum[0] = 0`.
    pub(crate) cum: Vec<f64>,
}

/// Bernstein coefficients of the energy density `I(x)·x` on a segment [a, b] where I is linear
/// from `ia` to `ib`: `I(x)x = c0(1−t)² + 2c1 t(1−t) + c2 t²`, `t = (x−a)/(b−a)`. Product of two
/// non-negative degree-1 Bernstein polynomials, hence all three are ≥ 0 (no cancellation).
pub(crate) fn segment_bernstein(a: f64, b: f64, ia: f64, ib: f64) -> [f64; 3] {
    [ia * a, 0.5 * (ia * b + ib * a), ib * b]
}

/// Energy `∫_a^{a+t h} I(x) x dx` of a segment, from its Bernstein coefficients:
/// `(h/3)[c0 t(3 − 3t + t²) + c1 t²(3 − 2t) + c2 t³]`, each term ≥ 0 on t ∈ [0, 1].
pub(crate) fn segment_mass(h: f64, c: [f64; 3], t: f64) -> f64 {
    h / 3.0 * (c[0] * t * (3.0 + t * (t - 3.0)) + c[1] * t * t * (3.0 - 2.0 * t) + c[2] * t * t * t)
}

/// Solves `H(t) = v` on [0, 1] for the normalised segment CDF
/// `H(t) = w0(1 − (1 − t)³) + w1(3t² − 2t³) + w2 t³` (w ≥ 0, Σw = 1), i.e. the exact CDF of a
/// linear intensity times ρ on one segment (a cubic). Solved on the half where the root is small
/// (using the mirror symmetry `1 − H(1 − t)` ↔ swapped weights) by Newton's method safeguarded by
/// bisection (Press et al., *Numerical Recipes* 3rd ed. §9.4, `rtsafe`); converges to the
/// machine precision of t. Returns a value in [0, 1] for any v (NaN-free).
pub(crate) fn invert_segment_cdf(w: [f64; 3], v: f64) -> f64 {
    invert_segment_cdf_counted(w, v).0
}

/// [`invert_segment_cdf`] also returning the number of Newton/bisection iterations.
pub(crate) fn invert_segment_cdf_counted(w: [f64; 3], v: f64) -> (f64, u32) {
    let v = v.clamp(0.0, 1.0);
    if v > 0.5 {
        let (t, n) = invert_segment_cdf_low([w[2], w[1], w[0]], 1.0 - v);
        return (1.0 - t, n);
    }
    invert_segment_cdf_low(w, v)
}

/// [`invert_segment_cdf_counted`] for v ≤ 1/2 (root in the lower part, relative precision kept
/// near 0).
pub(crate) fn invert_segment_cdf_low(w: [f64; 3], v: f64) -> (f64, u32) {
    if !(v > 0.0) {
        return (0.0, 0);
    }
    let h_of = |t: f64| {
        w[0] * t * (3.0 + t * (t - 3.0)) + w[1] * t * t * (3.0 - 2.0 * t) + w[2] * t * t * t
    };
    let dh_of = |t: f64| {
        let s = 1.0 - t;
        3.0 * (w[0] * s * s + 2.0 * w[1] * t * s + w[2] * t * t)
    };
    // Each of the three terms is ≥ 0 and bounded below by w0·t, w1·t², w2·t³ on [0, 1], so the
    // root lies below min(v/w0, √(v/w1), ∛(v/w2)); start from the smallest of the small-t
    // approximate roots v/(3w0), √(v/(3w1)), ∛(v/w2).
    let mut hi = 1.0f64;
    let mut guess = f64::INFINITY;
    if w[0] > 0.0 {
        hi = hi.min(v / w[0]);
        guess = guess.min(v / (3.0 * w[0]));
    }
    if w[1] > 0.0 {
        hi = hi.min((v / w[1]).sqrt());
        guess = guess.min((v / (3.0 * w[1])).sqrt());
    }
    if w[2] > 0.0 {
        hi = hi.min((v / w[2]).cbrt());
        guess = guess.min((v / w[2]).cbrt());
    }
    let mut lo = 0.0f64;
    let mut t = if guess > 0.0 && guess <= hi {
        guess
    } else {
        0.5 * hi
    };
    let mut dt_old = 1.0f64;
    let mut iterations = 0;
    while iterations < 200 {
        iterations += 1;
        let g = h_of(t) - v;
        // Converged once the residual is at the rounding level of evaluating H (a few ulp of v).
        if g.abs() <= 4.0 * f64::EPSILON * v {
            return (t, iterations);
        }
        if g < 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        let d = dh_of(t);
        let newton = t - g / d;
        let dt;
        if d > 0.0 && newton > lo && newton < hi && (2.0 * g).abs() <= (dt_old * d).abs() {
            dt = t - newton;
            t = newton;
        } else {
            let mid = 0.5 * (lo + hi);
            dt = t - mid;
            t = mid;
        }
        dt_old = dt;
        if dt.abs() <= 2.0 * f64::EPSILON * t || hi - lo <= 2.0 * f64::EPSILON * hi {
            break;
        }
    }
    (t.clamp(0.0, 1.0), iterations)
}

impl RadialTable {
    /// Checks the table ([`BeamProfile::check_table`]) and integrates it exactly.
    pub(crate) fn new(points: &[(f64, f64)]) -> Result<Self, LidarError> {
        BeamProfile::check_table(points).map_err(LidarError::InvalidInput)?;
        let max_i = points.iter().fold(0.0f64, |m, p| m.max(p.1));
        let x: Vec<f64> = points.iter().map(|p| p.0).collect();
        let intensity: Vec<f64> = points.iter().map(|p| p.1 / max_i).collect();
        let mut cum = Vec::with_capacity(x.len());
        cum.push(0.0);
        let mut acc = crate::lidar::NeumaierSum::default();
        for k in 0..x.len() - 1 {
            let c = segment_bernstein(x[k], x[k + 1], intensity[k], intensity[k + 1]);
            acc.add(segment_mass(x[k + 1] - x[k], c, 1.0));
            cum.push(acc.value());
        }
        let total = acc.value();
        // The check's plain sum of the same terms has passed; the compensated one can differ
        // only at the rounding level next to the largest f64.
        if !(total.is_finite() && total > 0.0) {
            return Err(LidarError::InvalidInput(format!(
                "beam profile table: total energy {total:e} is not finite and > 0 (normalised radii out of range?)"
            )));
        }
        Ok(Self { x, intensity, cum })
    }

    /// Total energy `M(x_last)`.
    pub(crate) fn total(&self) -> f64 {
        *self.cum.last().expect("table has >= 2 nodes")
    }

    /// Index k of the segment [x_k, x_{k+1}] containing `x` (x inside [x_0, x_last]).
    pub(crate) fn segment_of(&self, x: f64) -> usize {
        let n = self.x.len();
        self.x.partition_point(|&xi| xi <= x).clamp(1, n - 1) - 1
    }

    /// Intensity relative to the table maximum at normalised radius `x` (0 outside the table).
    pub(crate) fn relative_intensity(&self, x: f64) -> f64 {
        let n = self.x.len();
        if !(x >= self.x[0] && x <= self.x[n - 1]) {
            return 0.0;
        }
        let k = self.segment_of(x);
        let t = ((x - self.x[k]) / (self.x[k + 1] - self.x[k])).clamp(0.0, 1.0);
        self.intensity[k] + t * (self.intensity[k + 1] - self.intensity[k])
    }

    /// Exact `M(x)`.
    pub(crate) fn mass_within(&self, x: f64) -> f64 {
        let n = self.x.len();
        if !(x > self.x[0]) {
            return 0.0;
        }
        if x >= self.x[n - 1] {
            return self.total();
        }
        let k = self.segment_of(x);
        let h = self.x[k + 1] - self.x[k];
        let t = ((x - self.x[k]) / h).clamp(0.0, 1.0);
        let c = segment_bernstein(
            self.x[k],
            self.x[k + 1],
            self.intensity[k],
            self.intensity[k + 1],
        );
        self.cum[k] + segment_mass(h, c, t)
    }

    /// Normalised radius `x` with `M(x) = m` (0 ≤ m ≤ total), by exact per-segment inversion.
    pub(crate) fn radius_for_mass(&self, m: f64) -> f64 {
        let n = self.x.len();
        // Last segment whose start mass is <= m; zero-energy segments are skipped because the
        // next segment starts at the same cumulative mass.
        let k = (self.cum.partition_point(|&c| c <= m).clamp(1, n - 1)) - 1;
        let (a, b) = (self.x[k], self.x[k + 1]);
        let (ia, ib) = (self.intensity[k], self.intensity[k + 1]);
        let h = b - a;
        let seg = self.cum[k + 1] - self.cum[k];
        let r = (m - self.cum[k]).max(0.0);
        if !(seg > 0.0 && r > 0.0) {
            return a;
        }
        if r >= seg {
            return b;
        }
        let tau = if ia == ib {
            // Constant intensity: I(aτ + τ²/2) = r, the quadratic solved without cancellation.
            let q = 2.0 * r / ia;
            q / (a + (a * a + q).sqrt())
        } else {
            let c = segment_bernstein(a, b, ia, ib);
            let s = c[0] + c[1] + c[2];
            let w = [c[0] / s, c[1] / s, c[2] / s];
            h * invert_segment_cdf(w, r / seg)
        };
        (a + tau.clamp(0.0, h)).min(b)
    }
}

/// Radial shape held by a [`FootprintSampler`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum RadialShape {
    /// Gaussian of standard deviation σ (m).
    Gaussian { sigma_m: f64 },
    /// Top hat of radius R.
    Uniform,
    /// Piecewise-linear table in ρ/R.
    Tabulated(RadialTable),
}

/// Draws transverse positions (offsets in the plane normal to the beam at the reference range)
/// from a beam profile — Gaussian ([`FootprintProfile`]) or any [`BeamProfile`] — truncated at a
/// stated radius. Radii are drawn by exact inversion of the radial CDF, so one uniform gives one
/// radius, monotonically.
#[derive(Debug, Clone, PartialEq)]
pub struct FootprintSampler {
    pub(crate) radius_m: f64,
    pub(crate) truncation_radius_m: f64,
    pub(crate) kept_fraction: f64,
    pub(crate) shape: RadialShape,
}

impl FootprintSampler {
    /// Gaussian sampler truncated at `truncation_radius_m` (m, > 0, may be `f64::INFINITY` for no
    /// truncation). The energy beyond the radius is not emitted; its fraction is
    /// [`Self::lost_energy_fraction`] = `exp(−R_t²/(2σ²))`.
    pub fn new(profile: &FootprintProfile, truncation_radius_m: f64) -> Result<Self, LidarError> {
        check_truncation(truncation_radius_m)?;
        Ok(Self {
            radius_m: profile.radius_m,
            truncation_radius_m,
            kept_fraction: profile.energy_fraction_within(truncation_radius_m),
            shape: RadialShape::Gaussian {
                sigma_m: profile.sigma_m,
            },
        })
    }

    /// Sampler of any [`BeamProfile`] for a footprint of nominal radius `radius_m` (m, > 0: the
    /// R of `x = ρ/R`), truncated at `truncation_radius_m` (m, > 0 or infinite). Gaussian beams
    /// give exactly [`Self::new`] (same draws, bit for bit). Errors: invalid radius, truncation
    /// or profile, or a truncation radius inside the dark centre of an annular table (nothing
    /// would be emitted).
    pub fn from_beam(
        beam: &BeamProfile,
        radius_m: f64,
        truncation_radius_m: f64,
    ) -> Result<Self, LidarError> {
        check_positive("radius_m", radius_m)?;
        check_truncation(truncation_radius_m)?;
        let (shape, kept_fraction) = match beam {
            BeamProfile::Gaussian { edge_intensity } => {
                let profile = FootprintProfile::from_edge_intensity(radius_m, *edge_intensity)?;
                return Self::new(&profile, truncation_radius_m);
            }
            BeamProfile::Uniform => {
                let x = (truncation_radius_m / radius_m).min(1.0);
                (RadialShape::Uniform, x * x)
            }
            BeamProfile::Tabulated { points } => {
                let table = RadialTable::new(points)?;
                let kept = table.mass_within(truncation_radius_m / radius_m) / table.total();
                (RadialShape::Tabulated(table), kept.min(1.0))
            }
        };
        if !(kept_fraction > 0.0) {
            return Err(LidarError::InvalidParameter {
                name: "truncation_radius_m",
                value: truncation_radius_m,
                reason: "lies inside the dark centre of the beam profile: no energy would be emitted",
            });
        }
        Ok(Self {
            radius_m,
            truncation_radius_m,
            kept_fraction,
            shape,
        })
    }

    /// Nominal footprint radius R (m) — the scale of the profile's normalised radius.
    pub fn radius_m(&self) -> f64 {
        self.radius_m
    }

    /// Truncation radius (m).
    pub fn truncation_radius_m(&self) -> f64 {
        self.truncation_radius_m
    }

    /// Fraction of the beam energy outside the truncation radius (not emitted, to be
    /// booked as a loss or used to rescale packet weights by `1/(1 − lost)` if the caller wants
    /// the full pulse energy inside the truncated footprint). Zero for uniform and tabulated
    /// beams lying within the truncation radius.
    pub fn lost_energy_fraction(&self) -> f64 {
        1.0 - self.kept_fraction
    }

    /// Intensity at distance `rho_m` (m) from the axis relative to the profile's maximum
    /// (Gaussian: `exp(−ρ²/(2σ²))`; uniform: 1 inside R; table: interpolated, divided by the
    /// largest tabulated value). Ignores the truncation.
    pub fn relative_intensity(&self, rho_m: f64) -> f64 {
        let rho = rho_m.abs();
        match &self.shape {
            RadialShape::Gaussian { sigma_m } => (-0.5 * (rho / sigma_m).powi(2)).exp(),
            RadialShape::Uniform => {
                if rho <= self.radius_m {
                    1.0
                } else {
                    0.0
                }
            }
            RadialShape::Tabulated(t) => t.relative_intensity(rho / self.radius_m),
        }
    }

    /// Largest [`Self::relative_intensity`] over the distances `[r0_m, r1_m]` (m, `0 ≤ r0 ≤ r1`)
    /// from the axis, ignoring the truncation: Gaussian at `r0`, uniform 1 if `r0 ≤ R`, table
    /// at the ends and the nodes in between (piecewise linear, so the largest is at one of
    /// them). A bound for rejection sampling over a region of the footprint.
    pub fn max_relative_intensity_within(&self, r0_m: f64, r1_m: f64) -> f64 {
        let end = self
            .relative_intensity(r0_m)
            .max(self.relative_intensity(r1_m));
        match &self.shape {
            RadialShape::Tabulated(t) => {
                let (x0, x1) = (r0_m / self.radius_m, r1_m / self.radius_m);
                t.x.iter()
                    .zip(&t.intensity)
                    .filter(|(x, _)| (x0..=x1).contains(*x))
                    .fold(end, |m, (_, i)| m.max(*i))
            }
            _ => end,
        }
    }

    /// Fraction of the (untruncated) beam energy per unit area at distance `rho_m` from the axis
    /// (m⁻²); integrates to 1 over the plane.
    pub fn energy_density_per_m2(&self, rho_m: f64) -> f64 {
        let r2 = self.radius_m * self.radius_m;
        match &self.shape {
            RadialShape::Gaussian { sigma_m } => {
                self.relative_intensity(rho_m) / (2.0 * PI * sigma_m * sigma_m)
            }
            RadialShape::Uniform => self.relative_intensity(rho_m) / (PI * r2),
            RadialShape::Tabulated(t) => {
                self.relative_intensity(rho_m) / (2.0 * PI * r2 * t.total())
            }
        }
    }

    /// Fraction of the (untruncated) beam energy inside radius `r_m` (m): Gaussian
    /// `1 − exp(−r²/(2σ²))`, uniform `min(r/R, 1)²`, table `M(r/R)/M(∞)` with the exact
    /// piecewise-cubic `M(x) = ∫_0^x I(x')x' dx'` (0 for r ≤ 0).
    pub fn energy_fraction_within(&self, r_m: f64) -> f64 {
        if !(r_m > 0.0) {
            return 0.0;
        }
        match &self.shape {
            RadialShape::Gaussian { sigma_m } => -(-0.5 * (r_m / sigma_m).powi(2)).exp_m1(),
            RadialShape::Uniform => {
                let x = (r_m / self.radius_m).min(1.0);
                x * x
            }
            RadialShape::Tabulated(t) => (t.mass_within(r_m / self.radius_m) / t.total()).min(1.0),
        }
    }

    /// Radius (m) of the emitted distribution for a uniform `u1` in [0, 1) (clamped): the exact
    /// inverse of the truncated radial CDF `energy_fraction_within(ρ)/(1 − lost)`, monotone in u1,
    /// 0 (or the inner edge of an annular table) at u1 = 0 and the truncation radius or the outer
    /// edge of the profile as u1 → 1. Gaussian: `ρ = σ√(−2 ln(1 − u₁q))`, `q = 1 − e^{−R_t²/(2σ²)}`
    /// (Box & Muller 1958); uniform: `ρ = R√(u₁q)`; table: cumulative-energy search and exact
    /// solution of the per-segment cubic CDF (see [`BeamProfile::Tabulated`]).
    pub fn sample_radius_m(&self, u1: f64) -> f64 {
        let u1 = clamp_unit(u1);
        match &self.shape {
            RadialShape::Gaussian { sigma_m } => {
                sigma_m * (-2.0 * (-u1 * self.kept_fraction).ln_1p()).sqrt()
            }
            RadialShape::Uniform => self.radius_m * (u1 * self.kept_fraction).sqrt(),
            RadialShape::Tabulated(t) => {
                let x = t.radius_for_mass(u1 * self.kept_fraction * t.total());
                (self.radius_m * x).min(self.truncation_radius_m)
            }
        }
    }

    /// Transverse offset `[dx, dy]` (m, in the plane normal to the beam) from two uniforms in
    /// [0, 1) (values outside are clamped): radius [`Self::sample_radius_m`]`(u1)`, azimuth
    /// `φ = 2π u2`. Exact for the truncated profile, no rejection.
    pub fn sample_footprint_point(&self, u1: f64, u2: f64) -> [f64; 2] {
        let rho = self.sample_radius_m(u1);
        let phi = 2.0 * PI * clamp_unit(u2);
        [rho * phi.cos(), rho * phi.sin()]
    }
}
