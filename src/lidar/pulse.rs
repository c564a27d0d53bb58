//! Emitted LiDAR pulse: Gaussian temporal profile; transverse (footprint) beam profile —
//! Gaussian ([`FootprintProfile`]) or any radial distribution ([`BeamProfile`]: Gaussian,
//! uniform top hat, piecewise-linear table); footprint size from beam divergence, oblique
//! footprints, and exact inverse-CDF footprint sampling ([`FootprintSampler`])
//! (physics.md §9.1; DART 5 paper §4 and DART's LiDAR parameter schema).
//!
//! Units: times in ns, lengths in m, angles in rad.

use super::special::normal_interval;
use super::{LidarError, check_non_negative, check_positive};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// `FWHM = 2√(2 ln 2) σ` for a Gaussian.
pub const FWHM_PER_SIGMA: f64 = 2.354_820_045_030_949_3;

/// DART's default `gaussian_sigma_illu`: relative intensity at the footprint edge (≈ 1/e).
pub const DART_EDGE_RELATIVE_INTENSITY: f64 = 0.368;

/// DART's default `gaussian_pulse_cut`: the pulse is truncated at ±3σ_t.
pub const DART_PULSE_CUT_SIGMA: f64 = 3.0;

/// Largest accepted kernel half-length (bins): protects against absurd σ/Δt ratios.
const MAX_KERNEL_HALF_BINS: f64 = 1.0e6;

/// Gaussian temporal pulse `s(t) = exp(−t²/(2σ_t²))/(σ_t√(2π))`, truncated at `±cut·σ_t` and
/// renormalised to unit area (physics.md §9.1, [dart-xsd]). `t = 0` is the pulse centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PulseShape {
    sigma_ns: f64,
    cut_sigma: f64,
}

/// A pulse discretised on a waveform's bins: `weights[j]` is the fraction of the pulse energy
/// falling in the bin whose centre is `(j − centre)·Δt` from the pulse centre; Σ weights = 1.
#[derive(Debug, Clone, PartialEq)]
pub struct PulseKernel {
    /// Bin-integrated, truncated and renormalised pulse (sums to 1 to rounding).
    pub weights: Vec<f64>,
    /// Index of the zero-delay bin.
    pub centre: usize,
}

impl PulseShape {
    /// Pulse from its standard deviation `sigma_ns` (ns) and truncation `cut_sigma` (in σ units).
    pub fn from_sigma_ns(sigma_ns: f64, cut_sigma: f64) -> Result<Self, LidarError> {
        check_positive("sigma_ns", sigma_ns)?;
        check_positive("cut_sigma", cut_sigma)?;
        Ok(Self {
            sigma_ns,
            cut_sigma,
        })
    }

    /// Pulse from its full width at half maximum (ns): `σ_t = FWHM/(2√(2 ln 2))`.
    pub fn from_fwhm_ns(fwhm_ns: f64, cut_sigma: f64) -> Result<Self, LidarError> {
        check_positive("fwhm_ns", fwhm_ns)?;
        Self::from_sigma_ns(fwhm_ns / FWHM_PER_SIGMA, cut_sigma)
    }

    /// DART's parametrisation: half pulse duration `t_half_ns` measured at relative power
    /// `relative_power` p ∈ (0, 1) (DART default p = 0.5, i.e. `t_half` is the HWHM):
    /// `σ_t = t_h/√(−2 ln p)` (physics.md §9.1).
    pub fn from_half_duration_ns(
        t_half_ns: f64,
        relative_power: f64,
        cut_sigma: f64,
    ) -> Result<Self, LidarError> {
        check_positive("t_half_ns", t_half_ns)?;
        if !(relative_power > 0.0 && relative_power < 1.0) {
            return Err(LidarError::InvalidParameter {
                name: "relative_power",
                value: relative_power,
                reason: "must lie in (0, 1)",
            });
        }
        Self::from_sigma_ns(t_half_ns / (-2.0 * relative_power.ln()).sqrt(), cut_sigma)
    }

    /// DART defaults for a given half duration: p = 0.5 (HWHM), cut at ±3σ.
    pub fn dart_default(t_half_ns: f64) -> Result<Self, LidarError> {
        Self::from_half_duration_ns(t_half_ns, 0.5, DART_PULSE_CUT_SIGMA)
    }

    /// Standard deviation σ_t (ns).
    pub fn sigma_ns(&self) -> f64 {
        self.sigma_ns
    }

    /// Full width at half maximum (ns).
    pub fn fwhm_ns(&self) -> f64 {
        self.sigma_ns * FWHM_PER_SIGMA
    }

    /// Truncation in units of σ_t.
    pub fn cut_sigma(&self) -> f64 {
        self.cut_sigma
    }

    /// Half support `cut·σ_t` (ns).
    pub fn half_support_ns(&self) -> f64 {
        self.cut_sigma * self.sigma_ns
    }

    /// Fraction of the untruncated Gaussian kept by the truncation, `P(|Z| < cut)`.
    pub fn kept_fraction(&self) -> f64 {
        normal_interval(-self.cut_sigma, self.cut_sigma)
    }

    /// Truncated, unit-area pulse density (ns⁻¹) at `t_ns` from the pulse centre.
    pub fn density_per_ns(&self, t_ns: f64) -> f64 {
        if !(t_ns.abs() <= self.half_support_ns()) {
            return 0.0;
        }
        let z = t_ns / self.sigma_ns;
        (-0.5 * z * z).exp() / (self.sigma_ns * (2.0 * PI).sqrt() * self.kept_fraction())
    }

    /// Discretises the pulse on bins of width `dt_ns`: weight j is the exact integral of the
    /// truncated Gaussian over `[(j−c−½)Δt, (j−c+½)Δt]` (c = centre index), then the weights are
    /// divided by their sum so that convolution preserves area exactly (to rounding). The
    /// discretisation adds the bin-box variance Δt²/12 to the pulse variance, as any binned
    /// waveform does.
    pub fn kernel(&self, dt_ns: f64) -> Result<PulseKernel, LidarError> {
        check_positive("dt_ns", dt_ns)?;
        let half_bins = (self.half_support_ns() / dt_ns + 0.5).floor();
        if half_bins > MAX_KERNEL_HALF_BINS {
            return Err(LidarError::InvalidParameter {
                name: "dt_ns",
                value: dt_ns,
                reason: "too small for this pulse: kernel would exceed 2e6 bins",
            });
        }
        let m = half_bins as usize;
        let cut = self.cut_sigma;
        let mut weights = Vec::with_capacity(2 * m + 1);
        for j in 0..=2 * m {
            let offset = j as f64 - m as f64;
            let a = ((offset - 0.5) * dt_ns / self.sigma_ns).max(-cut);
            let b = ((offset + 0.5) * dt_ns / self.sigma_ns).min(cut);
            weights.push(normal_interval(a, b));
        }
        let sum: f64 = super::compensated_sum(&weights);
        if !(sum > 0.0) {
            return Err(LidarError::InvalidInput(
                "pulse kernel has zero area (cut too small?)".into(),
            ));
        }
        for w in &mut weights {
            *w /= sum;
        }
        Ok(PulseKernel { weights, centre: m })
    }
}

/// How a beam divergence angle is quoted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DivergenceAngle {
    /// Full cone angle (apex to apex across the beam): α_half = angle/2. Usual for instrument
    /// specifications (e.g. "0.5 mrad divergence").
    Full,
    /// Half cone angle α_half (DART's footprint angle convention).
    Half,
}

/// Footprint radius at the ground for a nadir beam, `R_fp = H tan α_half` (physics.md §9.1).
///
/// * `altitude_m`: sensor height above the reference ground (m, > 0);
/// * `divergence_rad`: divergence angle (rad), interpreted according to `convention`; α_half
///   must be in (0, π/2).
pub fn footprint_radius_m(
    altitude_m: f64,
    divergence_rad: f64,
    convention: DivergenceAngle,
) -> Result<f64, LidarError> {
    check_positive("altitude_m", altitude_m)?;
    check_positive("divergence_rad", divergence_rad)?;
    let half = match convention {
        DivergenceAngle::Full => 0.5 * divergence_rad,
        DivergenceAngle::Half => divergence_rad,
    };
    if half >= 0.5 * PI {
        return Err(LidarError::InvalidParameter {
            name: "divergence_rad",
            value: divergence_rad,
            reason: "half angle must be < π/2",
        });
    }
    Ok(altitude_m * half.tan())
}

/// Solid angle of a cone of half angle `half_angle_rad`: `Ω = 2π(1 − cos α) = 4π sin²(α/2)`
/// (the second form avoids cancellation for mrad beams). Used for the illumination cone ΔΩ_fp
/// and the receiver FOV Ω_FOV (physics.md §9.1, §9.5).
pub fn cone_solid_angle_sr(half_angle_rad: f64) -> Result<f64, LidarError> {
    check_non_negative("half_angle_rad", half_angle_rad)?;
    if half_angle_rad > PI {
        return Err(LidarError::InvalidParameter {
            name: "half_angle_rad",
            value: half_angle_rad,
            reason: "must be <= π",
        });
    }
    let s = (0.5 * half_angle_rad).sin();
    Ok(4.0 * PI * s * s)
}

/// Footprint of a beam of zenith θ_L over flat ground: an ellipse with semi-axis `R/cos²θ` in
/// the plane of incidence and `R/cosθ` across it, area `S_fp/cos³θ` (DART 5 paper §4,
/// physics.md §9.1). `R` is the nadir footprint radius for the same *altitude* (the slant range
/// is `H/cosθ`, which gives the first 1/cosθ; the projection on the ground the second one). The
/// same relation gives the receiver FOV footprint `S_view = S_FOV/cos³θ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObliqueFootprint {
    /// Semi-axis in the plane of incidence, `R/cos²θ` (m).
    pub semi_axis_incidence_plane_m: f64,
    /// Semi-axis perpendicular to the plane of incidence, `R/cosθ` (m).
    pub semi_axis_perpendicular_m: f64,
    /// Ellipse area `πR²/cos³θ` (m²).
    pub area_m2: f64,
}

impl ObliqueFootprint {
    /// Ellipse for nadir radius `radius_nadir_m` (m) and beam zenith `zenith_rad` ∈ [0, π/2).
    /// Rejects grazing beams with cos θ < 1e-6 (the footprint would be unbounded).
    pub fn new(radius_nadir_m: f64, zenith_rad: f64) -> Result<Self, LidarError> {
        check_non_negative("radius_nadir_m", radius_nadir_m)?;
        let mu = zenith_rad.cos();
        if !((0.0..0.5 * PI).contains(&zenith_rad) && mu >= 1e-6) {
            return Err(LidarError::InvalidParameter {
                name: "zenith_rad",
                value: zenith_rad,
                reason: "must lie in [0, π/2) with cos θ >= 1e-6",
            });
        }
        Ok(Self {
            semi_axis_incidence_plane_m: radius_nadir_m / (mu * mu),
            semi_axis_perpendicular_m: radius_nadir_m / mu,
            area_m2: PI * radius_nadir_m * radius_nadir_m / (mu * mu * mu),
        })
    }
}

/// Gaussian transverse beam profile `I(ρ) = I_0 exp(−ρ²/(2σ²))` over a footprint of nominal
/// radius R (physics.md §9.1, DART `gaussian_sigma_illu`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootprintProfile {
    radius_m: f64,
    sigma_m: f64,
}

impl FootprintProfile {
    /// Profile whose relative intensity at the footprint edge ρ = R is `edge_relative_intensity`
    /// s ∈ (0, 1) (DART's `gaussian_sigma_illu`): `σ = R/√(−2 ln s)`.
    pub fn from_edge_intensity(
        radius_m: f64,
        edge_relative_intensity: f64,
    ) -> Result<Self, LidarError> {
        check_positive("radius_m", radius_m)?;
        let s = edge_relative_intensity;
        if !(s > 0.0 && s < 1.0) {
            return Err(LidarError::InvalidParameter {
                name: "edge_relative_intensity",
                value: s,
                reason: "must lie in (0, 1)",
            });
        }
        Ok(Self {
            radius_m,
            sigma_m: radius_m / (-2.0 * s.ln()).sqrt(),
        })
    }

    /// DART default profile (edge intensity 0.368, σ ≈ R/√2).
    pub fn dart_default(radius_m: f64) -> Result<Self, LidarError> {
        Self::from_edge_intensity(radius_m, DART_EDGE_RELATIVE_INTENSITY)
    }

    /// Nominal footprint radius R (m).
    pub fn radius_m(&self) -> f64 {
        self.radius_m
    }

    /// Gaussian σ of the transverse profile (m).
    pub fn sigma_m(&self) -> f64 {
        self.sigma_m
    }

    /// Intensity relative to the beam axis, `exp(−ρ²/(2σ²))`.
    pub fn relative_intensity(&self, rho_m: f64) -> f64 {
        (-0.5 * (rho_m / self.sigma_m).powi(2)).exp()
    }

    /// Fraction of the pulse energy per unit area at distance ρ from the axis (m⁻²),
    /// `exp(−ρ²/(2σ²))/(2πσ²)`; integrates to 1 over the plane.
    pub fn energy_density_per_m2(&self, rho_m: f64) -> f64 {
        self.relative_intensity(rho_m) / (2.0 * PI * self.sigma_m * self.sigma_m)
    }

    /// Fraction of the pulse energy inside radius `r_m`: `1 − exp(−r²/(2σ²))` (0 for r ≤ 0).
    pub fn energy_fraction_within(&self, r_m: f64) -> f64 {
        if !(r_m > 0.0) {
            return 0.0;
        }
        -(-0.5 * (r_m / self.sigma_m).powi(2)).exp_m1()
    }
}

/// Default of [`BeamProfile::Gaussian`]'s `edge_intensity` in scene files (DART's
/// `gaussian_sigma_illu`, 0.368).
fn default_beam_edge_intensity() -> f64 {
    DART_EDGE_RELATIVE_INTENSITY
}

/// Transverse (radial) intensity profile of the emitted beam, independent of its size.
///
/// DART 5 paper §4: "Photons launched within ΔΩ_footprint can have any angular distribution
/// (e.g., Gaussian)". The profile is stated as relative intensity (irradiance on the plane normal
/// to the beam axis at the reference range) against the **normalised radius** `x = ρ/R`, R being
/// the nominal footprint radius at that range (from `footprint_radius_m` or the divergence,
/// physics.md §9.1). Because packets leave the emitter along `axis·H + offset`, an off-axis angle α
/// maps to `x = tan α / tan α_half` (α_half = half divergence). To use a table measured against
/// the angle, `I(α)` in W sr⁻¹, take `x = tan α/tan α_half` and intensity `I(α) cos³α`; for
/// α_half ≤ 10 mrad, `x = α/α_half` and `I(α)` unchanged are exact to < 1.5e-4 relative.
///
/// Serialises as a RON/serde enum like the scene `*Desc` types, e.g. `Gaussian(edge_intensity:
/// 0.368)`, `Uniform`, `Tabulated(points: [(0.0, 1.0), (0.8, 1.0), (1.0, 0.0)])`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum BeamProfile {
    /// Gaussian `I(x) = exp(−x²/(2s²))`, `s = 1/√(−2 ln edge_intensity)` (physics.md §9.1,
    /// DART `gaussian_sigma_illu`); unbounded, so the sampler's truncation radius matters.
    Gaussian {
        /// Relative intensity at the footprint edge x = 1, in (0, 1) (default 0.368 ≈ 1/e).
        #[serde(default = "default_beam_edge_intensity")]
        edge_intensity: f64,
    },
    /// Top hat: constant intensity for x ≤ 1, zero beyond.
    Uniform,
    /// Piecewise-linear relative intensity through `points = [(x_i, I_i)]`, `x_i = ρ/R`
    /// strictly increasing from `x_0 ≥ 0`, `I_i` finite and ≥ 0, not all zero, at least two
    /// points. The intensity is zero for `x < x_0` (an annular beam if `x_0 > 0`) and for
    /// `x > x_last`; the table may extend beyond x = 1. Only the shape matters (the scale of
    /// `I_i` is irrelevant).
    Tabulated {
        /// `(normalised radius ρ/R, relative intensity)` nodes.
        points: Vec<(f64, f64)>,
    },
}

impl Default for BeamProfile {
    /// DART's default beam: Gaussian with edge intensity 0.368.
    fn default() -> Self {
        BeamProfile::Gaussian {
            edge_intensity: DART_EDGE_RELATIVE_INTENSITY,
        }
    }
}

impl BeamProfile {
    /// Short name for logs: `"Gaussian"`, `"uniform"` or `"tabulated"`.
    pub fn name(&self) -> &'static str {
        match self {
            BeamProfile::Gaussian { .. } => "Gaussian",
            BeamProfile::Uniform => "uniform",
            BeamProfile::Tabulated { .. } => "tabulated",
        }
    }

    /// Checks the parameters (edge intensity in (0, 1); table rules of
    /// [`BeamProfile::Tabulated`]); the error names the offending parameter or table point.
    pub fn validate(&self) -> Result<(), LidarError> {
        match self {
            BeamProfile::Gaussian { edge_intensity } => {
                FootprintProfile::from_edge_intensity(1.0, *edge_intensity).map(|_| ())
            }
            BeamProfile::Uniform => Ok(()),
            BeamProfile::Tabulated { points } => RadialTable::new(points).map(|_| ()),
        }
    }
}

/// Validated piecewise-linear radial profile in normalised radius x = ρ/R, with the exact
/// cumulative energy `M(x) = ∫_0^x I(x') x' dx'` at every node (the 2πR² factor cancels in all
/// fractions).
#[derive(Debug, Clone, PartialEq)]
struct RadialTable {
    /// Nodes x_i (strictly increasing, x_0 ≥ 0).
    x: Vec<f64>,
    /// Intensities at the nodes divided by their maximum (so in [0, 1]).
    intensity: Vec<f64>,
    /// `M(x_i)`; `cum[0] = 0`.
    cum: Vec<f64>,
}

/// Bernstein coefficients of the energy density `I(x)·x` on a segment [a, b] where I is linear
/// from `ia` to `ib`: `I(x)x = c0(1−t)² + 2c1 t(1−t) + c2 t²`, `t = (x−a)/(b−a)`. Product of two
/// non-negative degree-1 Bernstein polynomials, hence all three are ≥ 0 (no cancellation).
fn segment_bernstein(a: f64, b: f64, ia: f64, ib: f64) -> [f64; 3] {
    [ia * a, 0.5 * (ia * b + ib * a), ib * b]
}

/// Energy `∫_a^{a+t h} I(x) x dx` of a segment, from its Bernstein coefficients:
/// `(h/3)[c0 t(3 − 3t + t²) + c1 t²(3 − 2t) + c2 t³]`, each term ≥ 0 on t ∈ [0, 1].
fn segment_mass(h: f64, c: [f64; 3], t: f64) -> f64 {
    h / 3.0 * (c[0] * t * (3.0 + t * (t - 3.0)) + c[1] * t * t * (3.0 - 2.0 * t) + c[2] * t * t * t)
}

/// Solves `H(t) = v` on [0, 1] for the normalised segment CDF
/// `H(t) = w0(1 − (1 − t)³) + w1(3t² − 2t³) + w2 t³` (w ≥ 0, Σw = 1), i.e. the exact CDF of a
/// linear intensity times ρ on one segment (a cubic). Solved on the half where the root is small
/// (using the mirror symmetry `1 − H(1 − t)` ↔ swapped weights) by Newton's method safeguarded by
/// bisection (Press et al., *Numerical Recipes* 3rd ed. §9.4, `rtsafe`); converges to the
/// machine precision of t. Returns a value in [0, 1] for any v (NaN-free).
fn invert_segment_cdf(w: [f64; 3], v: f64) -> f64 {
    invert_segment_cdf_counted(w, v).0
}

/// [`invert_segment_cdf`] also returning the number of Newton/bisection iterations.
fn invert_segment_cdf_counted(w: [f64; 3], v: f64) -> (f64, u32) {
    let v = v.clamp(0.0, 1.0);
    if v > 0.5 {
        let (t, n) = invert_segment_cdf_low([w[2], w[1], w[0]], 1.0 - v);
        return (1.0 - t, n);
    }
    invert_segment_cdf_low(w, v)
}

/// [`invert_segment_cdf_counted`] for v ≤ 1/2 (root in the lower part, relative precision kept
/// near 0).
fn invert_segment_cdf_low(w: [f64; 3], v: f64) -> (f64, u32) {
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
    /// Validates the table (see [`BeamProfile::Tabulated`]) and integrates it exactly.
    fn new(points: &[(f64, f64)]) -> Result<Self, LidarError> {
        let bad = |i: usize, msg: &str| {
            LidarError::InvalidInput(format!(
                "beam profile table: point {i} ({}, {}): {msg}",
                points[i].0, points[i].1
            ))
        };
        if points.len() < 2 {
            return Err(LidarError::InvalidInput(format!(
                "beam profile table: needs at least 2 points (normalised radius, intensity), got {}",
                points.len()
            )));
        }
        let mut max_i: f64 = 0.0;
        for (i, &(x, v)) in points.iter().enumerate() {
            if !x.is_finite() {
                return Err(bad(i, "normalised radius must be finite"));
            }
            if i == 0 && x < 0.0 {
                return Err(bad(i, "normalised radius must be >= 0"));
            }
            if i > 0 && !(x > points[i - 1].0) {
                return Err(bad(
                    i,
                    "normalised radii must be strictly increasing (this one is not greater than the previous one)",
                ));
            }
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(i, "relative intensity must be finite and >= 0"));
            }
            max_i = max_i.max(v);
        }
        if !(max_i > 0.0) {
            return Err(LidarError::InvalidInput(
                "beam profile table: all intensities are zero (the beam carries no energy)".into(),
            ));
        }
        let x: Vec<f64> = points.iter().map(|p| p.0).collect();
        let intensity: Vec<f64> = points.iter().map(|p| p.1 / max_i).collect();
        let mut cum = Vec::with_capacity(x.len());
        cum.push(0.0);
        let mut acc = super::NeumaierSum::default();
        for k in 0..x.len() - 1 {
            let c = segment_bernstein(x[k], x[k + 1], intensity[k], intensity[k + 1]);
            acc.add(segment_mass(x[k + 1] - x[k], c, 1.0));
            cum.push(acc.value());
        }
        let total = acc.value();
        if !(total.is_finite() && total > 0.0) {
            return Err(LidarError::InvalidInput(format!(
                "beam profile table: total energy {total:e} is not finite and > 0 (normalised radii out of range?)"
            )));
        }
        Ok(Self { x, intensity, cum })
    }

    /// Total energy `M(x_last)`.
    fn total(&self) -> f64 {
        *self.cum.last().expect("table has >= 2 nodes")
    }

    /// Index k of the segment [x_k, x_{k+1}] containing `x` (x inside [x_0, x_last]).
    fn segment_of(&self, x: f64) -> usize {
        let n = self.x.len();
        self.x.partition_point(|&xi| xi <= x).clamp(1, n - 1) - 1
    }

    /// Intensity relative to the table maximum at normalised radius `x` (0 outside the table).
    fn relative_intensity(&self, x: f64) -> f64 {
        let n = self.x.len();
        if !(x >= self.x[0] && x <= self.x[n - 1]) {
            return 0.0;
        }
        let k = self.segment_of(x);
        let t = ((x - self.x[k]) / (self.x[k + 1] - self.x[k])).clamp(0.0, 1.0);
        self.intensity[k] + t * (self.intensity[k + 1] - self.intensity[k])
    }

    /// Exact `M(x)`.
    fn mass_within(&self, x: f64) -> f64 {
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
    fn radius_for_mass(&self, m: f64) -> f64 {
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
enum RadialShape {
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
    radius_m: f64,
    truncation_radius_m: f64,
    kept_fraction: f64,
    shape: RadialShape,
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

/// Cells per radial interval along `u` and along `w` in the [`FootprintMoments`] tables.
const MOMENT_CELLS: usize = 40;
/// Radial intervals of the [`FootprintMoments`] tables are at most `reach/MOMENT_SPLIT` long.
const MOMENT_SPLIT: f64 = 6.0;
/// The untruncated Gaussian is cut where the tail mass `exp(−r²/(2σ²))` is 1e-16.
const GAUSSIAN_CUT_TAIL: f64 = 1e-16;

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
    reach_m: f64,
    /// `E[ρ²]` of the truncated distribution (m²).
    total_m2: f64,
    /// Interval bounds `0 = τ_0 < … < τ_n = reach` (m).
    tau: Vec<f64>,
    /// `1/(τ_{k+1} − τ_k)` (m⁻¹).
    inv_len: Vec<f64>,
    /// Bicubic coefficients `a_mn` (index `4m + n`) of `P0` then `P2` (m²) per cell, cell
    /// `(k·CELLS + iu)·CELLS + iw`.
    cells: Vec<[f64; 32]>,
}

/// Derivative in index units of grid values (≥ 5) by 4th-order finite differences (central
/// inside, one-sided at the two first and last nodes; Abramowitz & Stegun 25.3.6 family).
fn fd_derivative(f: &[f64]) -> Vec<f64> {
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
fn hermite_cell(f: [[f64; 4]; 4]) -> [f64; 16] {
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
struct RadialMoments<'a> {
    sampler: &'a FootprintSampler,
    /// Table only: `∫_0^{x_i} x³ I(x) dx` at the nodes.
    cum2: Vec<f64>,
}

impl RadialMoments<'_> {
    fn new(sampler: &FootprintSampler) -> RadialMoments<'_> {
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
    fn segment_m2(t: &RadialTable, k: usize, tau: f64) -> f64 {
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

    fn eval(&self, r: f64) -> (f64, f64) {
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
    fn locate(&self, r0: f64) -> (usize, f64) {
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
    fn p_at(&self, row: usize, s: f64, w: f64) -> (f64, f64) {
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
    fn half(&self, c: f64) -> (f64, f64) {
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
    fn quadrant(&self, a: f64, b: f64) -> (f64, f64) {
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

/// Checks a truncation radius: > 0 or +∞.
fn check_truncation(truncation_radius_m: f64) -> Result<(), LidarError> {
    if truncation_radius_m > 0.0 {
        Ok(())
    } else {
        Err(LidarError::InvalidParameter {
            name: "truncation_radius_m",
            value: truncation_radius_m,
            reason: "must be > 0 (or infinite)",
        })
    }
}

/// Maps any value into [0, 1) (NaN → 0).
pub(crate) fn clamp_unit(u: f64) -> f64 {
    if u >= 0.0 {
        u.min(1.0 - f64::EPSILON / 2.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniforms in [0, 1) from a xorshift64 generator (Marsaglia 2003) seeded with `state`
    /// (not 0): the tests' own deterministic stream.
    fn xorshift(mut state: u64) -> impl FnMut() -> f64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    #[test]
    fn pulse_widths() {
        let p = PulseShape::from_fwhm_ns(4.0, 3.0).unwrap();
        assert!((p.sigma_ns() * FWHM_PER_SIGMA - 4.0).abs() < 1e-12);
        // DART: HWHM at p = 0.5 -> FWHM = 2 t_h.
        let d = PulseShape::dart_default(2.0).unwrap();
        assert!((d.fwhm_ns() - 4.0).abs() < 1e-12);
        // Half duration at 1/e² power: σ = t_h / 2.
        let e = PulseShape::from_half_duration_ns(2.0, (-2.0f64).exp(), 3.0).unwrap();
        assert!((e.sigma_ns() - 1.0).abs() < 1e-12);
        assert!(PulseShape::from_fwhm_ns(f64::NAN, 3.0).is_err());
        assert!(PulseShape::from_half_duration_ns(1.0, 1.0, 3.0).is_err());
        assert!(PulseShape::from_sigma_ns(1.0, 0.0).is_err());
    }

    #[test]
    fn density_integrates_to_one() {
        let p = PulseShape::from_sigma_ns(1.3, 3.0).unwrap();
        let n = 20000;
        let h = 2.0 * p.half_support_ns() / n as f64;
        let s: f64 = (0..n)
            .map(|i| p.density_per_ns(-p.half_support_ns() + (i as f64 + 0.5) * h) * h)
            .sum();
        assert!((s - 1.0).abs() < 1e-7, "{s}");
        assert_eq!(p.density_per_ns(4.0), 0.0);
    }

    #[test]
    fn kernel_is_normalised_and_symmetric() {
        for (sigma, dt) in [(1.0, 1.0), (0.1, 1.0), (5.0, 0.25), (1e-6, 1.0)] {
            let k = PulseShape::from_sigma_ns(sigma, 3.0)
                .unwrap()
                .kernel(dt)
                .unwrap();
            let s: f64 = k.weights.iter().sum();
            assert!((s - 1.0).abs() < 1e-14);
            let n = k.weights.len();
            assert_eq!(n, 2 * k.centre + 1);
            for j in 0..n {
                assert!((k.weights[j] - k.weights[n - 1 - j]).abs() < 1e-15);
            }
        }
        // Kernel variance = σ² + Δt²/12 (bin box), up to the ±3σ truncation effect.
        let p = PulseShape::from_sigma_ns(3.0, 6.0).unwrap();
        let k = p.kernel(0.5).unwrap();
        let var: f64 = k
            .weights
            .iter()
            .enumerate()
            .map(|(j, w)| w * ((j as f64 - k.centre as f64) * 0.5).powi(2))
            .sum();
        assert!((var - (9.0 + 0.25 / 12.0)).abs() < 1e-6, "{var}");
    }

    #[test]
    fn footprint_geometry() {
        // 0.5 mrad full divergence at 1000 m -> R = 1000 tan(0.25 mrad) = 0.25 m.
        let r = footprint_radius_m(1000.0, 0.5e-3, DivergenceAngle::Full).unwrap();
        assert!((r - 1000.0 * (0.25e-3f64).tan()).abs() < 1e-12);
        let rh = footprint_radius_m(1000.0, 0.25e-3, DivergenceAngle::Half).unwrap();
        assert_eq!(r, rh);
        // GLAS-like: 70 m footprint diameter at 600 km.
        let half = (35.0f64 / 600e3).atan();
        let rg = footprint_radius_m(600e3, half, DivergenceAngle::Half).unwrap();
        assert!((rg - 35.0).abs() < 1e-9);
        assert!(footprint_radius_m(1000.0, PI, DivergenceAngle::Full).is_err());
        assert!(footprint_radius_m(-1.0, 1e-3, DivergenceAngle::Full).is_err());
        // Cone solid angle: small-angle limit πα², hemisphere 2π.
        let a = 1e-4;
        let om = cone_solid_angle_sr(a).unwrap();
        assert!((om / (PI * a * a) - 1.0).abs() < 1e-8);
        assert!((cone_solid_angle_sr(0.5 * PI).unwrap() - 2.0 * PI).abs() < 1e-14);
        // Oblique ellipse: area = π a b and = S_fp / cos³θ.
        let th = 30f64.to_radians();
        let e = ObliqueFootprint::new(10.0, th).unwrap();
        let mu = th.cos();
        assert!(
            (e.area_m2 - PI * e.semi_axis_incidence_plane_m * e.semi_axis_perpendicular_m).abs()
                < 1e-9
        );
        assert!((e.area_m2 - PI * 100.0 / mu.powi(3)).abs() < 1e-9);
        assert!(ObliqueFootprint::new(10.0, 0.5 * PI).is_err());
        assert!(ObliqueFootprint::new(10.0, f64::NAN).is_err());
    }

    #[test]
    fn footprint_profile() {
        let p = FootprintProfile::dart_default(10.0).unwrap();
        // σ = R/√(−2 ln 0.368) ≈ R/√2.
        assert!((p.sigma_m() - 10.0 / (-2.0 * 0.368f64.ln()).sqrt()).abs() < 1e-12);
        assert!((p.relative_intensity(10.0) - 0.368).abs() < 1e-12);
        // Energy inside R: 1 − s = 0.632.
        assert!((p.energy_fraction_within(10.0) - 0.632).abs() < 1e-12);
        assert_eq!(p.energy_fraction_within(-1.0), 0.0);
        assert!(FootprintProfile::from_edge_intensity(10.0, 1.0).is_err());
        // Density integrates to 1 over the plane (radial midpoint rule).
        let n = 200000;
        let rmax = 12.0 * p.sigma_m();
        let h = rmax / n as f64;
        let s: f64 = (0..n)
            .map(|i| {
                let r = (i as f64 + 0.5) * h;
                p.energy_density_per_m2(r) * 2.0 * PI * r * h
            })
            .sum();
        assert!((s - 1.0).abs() < 1e-8, "{s}");
    }

    /// The per-segment cubic inversion: `|H(t(v)) − v| ≤ 1e-15` (≈ 4.5 ulp of 1; evaluating H
    /// near 1 itself rounds by a few ulp) for weights with and
    /// without zero components, including the degenerate pure-t², pure-t³ and mirrored cases, and
    /// the iteration count stays small (mean ≤ 4.5, max ≤ 10 over 2e5 draws).
    #[test]
    fn segment_cdf_inversion() {
        let h_of = |w: [f64; 3], t: f64| {
            w[0] * t * (3.0 + t * (t - 3.0)) + w[1] * t * t * (3.0 - 2.0 * t) + w[2] * t * t * t
        };
        let mut next = xorshift(0x1234_5678_9abc_def0u64);
        let fixed = [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.5, 0.5],
            [0.5, 0.5, 0.0],
            [0.5, 0.0, 0.5],
            [1e-12, 1.0 - 2e-12, 1e-12],
        ];
        let (mut total, mut max_it, mut worst) = (0u64, 0u32, 0.0f64);
        let n = 200_000;
        for i in 0..n {
            let w = if i % 4 == 0 {
                fixed[(i / 4) % fixed.len()]
            } else {
                let w = [next(), next(), next()];
                let s = w[0] + w[1] + w[2];
                [w[0] / s, w[1] / s, w[2] / s]
            };
            let v = match i % 7 {
                0 => next() * 1e-12,
                1 => 1.0 - next() * 1e-12,
                2 => next() * 1e-300,
                _ => next(),
            };
            let (t, it) = invert_segment_cdf_counted(w, v);
            assert!((0.0..=1.0).contains(&t), "{w:?} {v}");
            worst = worst.max((h_of(w, t) - v).abs());
            total += it as u64;
            max_it = max_it.max(it);
        }
        let mean = total as f64 / n as f64;
        assert!(worst <= 1e-15, "worst |H(t) − v| = {worst:e}");
        println!(
            "segment inversion: worst |H(t) − v| = {worst:.1e}, iterations mean {mean:.2}, max {max_it}"
        );
        assert!(mean <= 4.5 && max_it <= 10, "mean {mean}, max {max_it}");
        assert_eq!(invert_segment_cdf([0.0, 1.0, 0.0], 0.0), 0.0);
        assert_eq!(invert_segment_cdf([0.0, 1.0, 0.0], 1.0), 1.0);
        assert_eq!(invert_segment_cdf([0.2, 0.3, 0.5], f64::NAN), 0.0);
    }

    #[test]
    fn beam_profile_defaults() {
        assert_eq!(
            BeamProfile::default(),
            BeamProfile::Gaussian {
                edge_intensity: DART_EDGE_RELATIVE_INTENSITY
            }
        );
        assert!(BeamProfile::default().validate().is_ok());
        // Segment masses add up to the closed form of a constant table: x²/2.
        let t = RadialTable::new(&[(0.0, 2.0), (0.3, 2.0), (1.0, 2.0)]).unwrap();
        assert!((t.total() - 0.5).abs() < 1e-16);
        assert!((t.mass_within(0.5) - 0.125).abs() < 1e-16);
    }

    #[test]
    fn truncated_sampler_edges() {
        let p = FootprintProfile::dart_default(10.0).unwrap();
        let s = FootprintSampler::new(&p, 10.0).unwrap();
        assert!((s.lost_energy_fraction() - 0.368).abs() < 1e-12);
        // u1 -> 1 reaches the truncation radius, u1 = 0 the axis; bad uniforms are clamped.
        let [x, y] = s.sample_footprint_point(1.0 - 1e-16, 0.0);
        assert!(((x * x + y * y).sqrt() - 10.0).abs() < 1e-6);
        assert_eq!(s.sample_footprint_point(0.0, 0.3), [0.0, 0.0]);
        let [x, y] = s.sample_footprint_point(f64::NAN, 2.0);
        assert!(x.is_finite() && y.is_finite());
        let inf = FootprintSampler::new(&p, f64::INFINITY).unwrap();
        assert_eq!(inf.lost_energy_fraction(), 0.0);
        let [x, y] = inf.sample_footprint_point(1.0 - f64::EPSILON / 2.0, 0.7);
        assert!(x.is_finite() && y.is_finite());
        assert!(FootprintSampler::new(&p, 0.0).is_err());
    }

    /// Profiles of the rectangle-moment tests: (name, sampler, radii where the density or its
    /// slope jumps, for the independent reference quadratures). R = 2.5 m to exercise units.
    fn moment_profiles() -> Vec<(&'static str, FootprintSampler, Vec<f64>)> {
        let r = 2.5;
        let g = FootprintProfile::dart_default(r).unwrap();
        let table = BeamProfile::Tabulated {
            points: vec![(0.3, 0.5), (0.6, 1.0), (0.9, 0.2), (1.1, 0.0)],
        };
        vec![
            (
                "gaussian 3R",
                FootprintSampler::new(&g, 3.0 * r).unwrap(),
                vec![3.0 * r],
            ),
            (
                "gaussian inf",
                FootprintSampler::new(&g, f64::INFINITY).unwrap(),
                vec![],
            ),
            (
                "uniform",
                FootprintSampler::from_beam(&BeamProfile::Uniform, r, f64::INFINITY).unwrap(),
                vec![r],
            ),
            (
                "uniform 0.7R",
                FootprintSampler::from_beam(&BeamProfile::Uniform, r, 0.7 * r).unwrap(),
                vec![0.7 * r],
            ),
            (
                "annular table",
                FootprintSampler::from_beam(&table, r, r).unwrap(),
                vec![0.3 * r, 0.6 * r, 0.9 * r, r],
            ),
        ]
    }

    /// Adaptive Gauss–Legendre (8 points, bisection until two halves agree with the whole to
    /// `tol`) of a vector integrand; independent of the library's polar quadrature.
    fn adaptive(f: &dyn Fn(f64) -> [f64; 2], a: f64, b: f64, tol: f64, depth: u32) -> [f64; 2] {
        let (gl_x, gl_w) = crate::physics::lad::gauss_legendre(8);
        let gl = |a: f64, b: f64| {
            let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
            let mut s = [0.0; 2];
            for (x, w) in gl_x.iter().zip(&gl_w) {
                let y = f(m + h * x);
                s[0] += w * h * y[0];
                s[1] += w * h * y[1];
            }
            s
        };
        fn rec(
            gl: &dyn Fn(f64, f64) -> [f64; 2],
            a: f64,
            b: f64,
            whole: [f64; 2],
            tol: f64,
            depth: u32,
        ) -> [f64; 2] {
            let m = 0.5 * (a + b);
            let (l, r) = (gl(a, m), gl(m, b));
            let s = [l[0] + r[0], l[1] + r[1]];
            if depth == 0 || ((s[0] - whole[0]).abs() <= tol && (s[1] - whole[1]).abs() <= tol) {
                return s;
            }
            let x = rec(gl, a, m, l, 0.5 * tol, depth - 1);
            let y = rec(gl, m, b, r, 0.5 * tol, depth - 1);
            [x[0] + y[0], x[1] + y[1]]
        }
        if !(b > a) {
            return [0.0; 2];
        }
        rec(&gl, a, b, gl(a, b), tol, depth)
    }

    /// Integral over sorted cut points (pieces between consecutive cuts).
    fn pieces(f: &dyn Fn(f64) -> [f64; 2], mut cuts: Vec<f64>, tol: f64) -> [f64; 2] {
        cuts.sort_by(f64::total_cmp);
        let mut s = [0.0; 2];
        for c in cuts.windows(2) {
            let v = adaptive(f, c[0], c[1], tol, 40);
            s[0] += v[0];
            s[1] += v[1];
        }
        s
    }

    /// Brute-force `(m0, m2)` of a rectangle: Cartesian iterated adaptive quadrature of the
    /// truncated, renormalised density `energy_density_per_m2(ρ)/kept` (ρ < R_t), split at the
    /// axes and wherever a line crosses a jump radius.
    fn brute_rect(s: &FootprintSampler, jumps: &[f64], reach: f64, rect: [f64; 4]) -> [f64; 2] {
        let kept = 1.0 - s.lost_energy_fraction();
        let rt = s.truncation_radius_m();
        let dens = |rho: f64| {
            if rho < rt {
                s.energy_density_per_m2(rho) / kept
            } else {
                0.0
            }
        };
        let clip = |v: f64| v.clamp(-reach, reach);
        let [x0, x1, y0, y1] = [clip(rect[0]), clip(rect[1]), clip(rect[2]), clip(rect[3])];
        let mut radii = jumps.to_vec();
        radii.push(reach);
        let inner = |x: f64| {
            let mut cuts = vec![y0, y1];
            for &t in &radii {
                if t > x.abs() {
                    let y = (t * t - x * x).sqrt();
                    cuts.extend([y, -y]);
                }
            }
            cuts.push(0.0);
            cuts.retain(|&c| c >= y0 && c <= y1);
            let f = |y: f64| {
                let r2 = x * x + y * y;
                let d = dens(r2.sqrt());
                [d, d * r2]
            };
            pieces(&f, cuts, 1e-15)
        };
        let mut cuts = vec![x0, x1, 0.0];
        for &t in &radii {
            cuts.extend([t, -t]);
            for y in [y0, y1] {
                if y.abs() < t {
                    let x = (t * t - y * y).sqrt();
                    cuts.extend([x, -x]);
                }
            }
        }
        cuts.retain(|&c| c >= x0 && c <= x1);
        pieces(&inner, cuts, 1e-12)
    }

    /// Whole plane: m0 = 1 (1e-9: only rounding of the corner sums) and m2 = E[ρ²] from an
    /// independent 1D quadrature of ρ²·2πρ·density (1e-9·reach²: adaptive quadrature to 1e-13).
    #[test]
    fn footprint_moments_whole_plane() {
        for (name, s, jumps) in moment_profiles() {
            let m = s.moments();
            let reach = m.reach_m();
            let inf = f64::INFINITY;
            let (m0, m2) = m.rect(-inf, inf, -inf, inf);
            let kept = 1.0 - s.lost_energy_fraction();
            let rt = s.truncation_radius_m();
            let f = |r: f64| {
                let d = if r < rt {
                    s.energy_density_per_m2(r) / kept
                } else {
                    0.0
                };
                [2.0 * PI * r * d, 2.0 * PI * r * r * r * d]
            };
            let mut cuts = jumps.clone();
            cuts.extend([0.0, reach]);
            let e = pieces(&f, cuts, 1e-14);
            println!(
                "{name}: reach {reach:.4} m, m0 {m0:.15}, m2 {m2:.12} vs {:.12}",
                e[1]
            );
            assert!((m0 - 1.0).abs() < 1e-9, "{name}: {m0}");
            assert!((e[0] - 1.0).abs() < 1e-9, "{name}: reference mass {}", e[0]);
            assert!(
                (m2 - e[1]).abs() < 1e-9 * reach * reach,
                "{name}: {m2} vs {}",
                e[1]
            );
            // A finite rectangle holding the whole disk gives the same.
            let big = 1.5 * reach;
            let (b0, b2) = m.rect(-big, big, -big, big);
            assert!((b0 - 1.0).abs() < 1e-9 && (b2 - m2).abs() < 1e-9 * reach * reach);
        }
    }

    /// Random and special rectangles against [`brute_rect`]: |Δm0| ≤ 1e-7 and
    /// |Δm2| ≤ 1e-7·reach² (the stated accuracy of `rect`; the reference is good to ~1e-11).
    #[test]
    fn footprint_moments_against_brute_force() {
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15u64);
        let inf = f64::INFINITY;
        for (name, s, jumps) in moment_profiles() {
            let m = s.moments();
            let reach = m.reach_m();
            let rr = s.radius_m();
            let mut rects: Vec<[f64; 4]> = vec![
                [0.0, inf, 0.0, inf],
                [-inf, 0.0, 0.0, inf],
                [0.3 * rr, inf, -inf, inf],
                [-inf, -0.45 * rr, -inf, inf],
                [-inf, inf, 0.2 * rr, 0.2 * rr + 1e-6 * rr],
                [0.5 * rr, 0.5 * rr + 1e-6 * rr, -inf, inf],
                [0.0, 1e-6 * rr, 0.0, 1e-6 * rr],
                [-0.1 * rr, 0.2 * rr, -0.3 * rr, 0.05 * rr],
                [0.0, 0.0 + 0.5 * rr, -0.5 * rr, 0.0],
            ];
            // Corners on the jump circles (truncation and table nodes) and on the axes.
            for &t in jumps.iter().chain([reach].iter()) {
                let c = t / 2f64.sqrt();
                rects.push([c, inf, c, inf]);
                rects.push([-c, c, -inf, -c]);
                rects.push([0.0, t, 0.0, 0.5 * t]);
                rects.push([0.6 * t, (t * t - 0.01 * t * t).sqrt(), 0.1 * t, 0.8 * t]);
                rects.push([t - 1e-6 * rr, t, -1e-3 * rr, 1e-3 * rr]);
                rects.push([-t, -t + 1e-6 * rr, -inf, inf]);
            }
            for _ in 0..80 {
                let mut v = [0.0; 4];
                for x in v.iter_mut() {
                    *x = (2.4 * next() - 1.2) * reach;
                }
                if next() < 0.2 {
                    v[1] = v[0] + 1e-6 * rr * next();
                }
                let (x0, x1) = (v[0].min(v[1]), v[0].max(v[1]));
                let (y0, y1) = (v[2].min(v[3]), v[2].max(v[3]));
                rects.push([x0, x1, y0, y1]);
            }
            let (mut w0, mut w2) = (0.0f64, 0.0f64);
            for r in &rects {
                let (m0, m2) = m.rect(r[0], r[1], r[2], r[3]);
                let b = brute_rect(&s, &jumps, reach, *r);
                let (e0, e2) = ((m0 - b[0]).abs(), (m2 - b[1]).abs() / (reach * reach));
                assert!(e0 <= 1e-7, "{name} {r:?}: m0 {m0} vs {}", b[0]);
                assert!(e2 <= 1e-7, "{name} {r:?}: m2 {m2} vs {}", b[1]);
                w0 = w0.max(e0);
                w2 = w2.max(e2);
            }
            println!(
                "{name}: {} rects, worst |Δm0| {w0:.1e}, |Δm2|/reach² {w2:.1e}",
                rects.len()
            );
        }
    }

    /// Splitting a rectangle into 2×2 pieces adds up to the whole (1e-9: the shared corner
    /// values are identical, only rounding remains); degenerate inputs are NaN-free and empty.
    #[test]
    fn footprint_moments_additivity_and_degenerate() {
        let inf = f64::INFINITY;
        for (name, s, _) in moment_profiles() {
            let m = s.moments();
            let reach = m.reach_m();
            let xs = [-0.7 * reach, 0.1 * reach, 0.95 * reach];
            let ys = [-inf, -0.2 * reach, 0.4 * reach];
            let whole = m.rect(xs[0], xs[2], ys[0], ys[2]);
            let mut sum = (0.0, 0.0);
            for i in 0..2 {
                for j in 0..2 {
                    let p = m.rect(xs[i], xs[i + 1], ys[j], ys[j + 1]);
                    sum = (sum.0 + p.0, sum.1 + p.1);
                }
            }
            assert!((sum.0 - whole.0).abs() < 1e-9, "{name}");
            assert!((sum.1 - whole.1).abs() < 1e-9 * reach * reach, "{name}");
            for r in [
                [1.0, 1.0, 0.0, 1.0],
                [1.0, 0.5, 0.0, 1.0],
                [0.0, 1.0, 0.3, -0.3],
                [f64::NAN, 1.0, 0.0, 1.0],
                [inf, inf, -inf, inf],
                [-inf, -inf, 0.0, 1.0],
            ] {
                assert_eq!(m.rect(r[0], r[1], r[2], r[3]), (0.0, 0.0), "{name} {r:?}");
            }
            let specials = [
                -inf,
                -2.0 * reach,
                -reach,
                -0.0,
                0.0,
                1e-300,
                reach,
                3.0 * reach,
                inf,
            ];
            for &a in &specials {
                for &b in &specials {
                    for &c in &specials {
                        for &d in &specials {
                            let (m0, m2) = m.rect(a, b, c, d);
                            assert!(m0.is_finite() && m2.is_finite(), "{name} {a} {b} {c} {d}");
                            assert!(m0 > -1e-7 && m0 < 1.0 + 1e-7, "{name} {a} {b} {c} {d}");
                        }
                    }
                }
            }
            // Far outside: exactly zero.
            assert_eq!(m.rect(2.0 * reach, inf, -inf, inf), (0.0, 0.0));
        }
    }

    /// Ties the moments to the sampler actually used: 2e6 fixed-seed draws from
    /// `sample_footprint_point`; counts and ρ² sums in a few rectangles agree with m0 and m2
    /// within 5 standard errors (binomial for m0, sample variance of ρ²·1(rect) for m2).
    #[test]
    fn footprint_moments_match_sampler() {
        use rand_xoshiro::Xoshiro256PlusPlus;
        use rand_xoshiro::rand_core::{Rng, SeedableRng};
        let n = 2_000_000usize;
        let inf = f64::INFINITY;
        for (name, s, _) in moment_profiles() {
            let m = s.moments();
            let rr = s.radius_m();
            let rects = [
                [0.0, inf, 0.0, inf],
                [-0.2 * rr, 0.5 * rr, -0.1 * rr, 0.9 * rr],
                [0.6 * rr, 1.2 * rr, -inf, 0.3 * rr],
                [-0.05 * rr, 0.05 * rr, -inf, inf],
            ];
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(0x5eed_2025);
            let mut cnt = [0u64; 4];
            let mut s2 = [0.0f64; 4];
            let mut s4 = [0.0f64; 4];
            for _ in 0..n {
                let u1 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
                let u2 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
                let [x, y] = s.sample_footprint_point(u1, u2);
                let r2 = x * x + y * y;
                for (k, r) in rects.iter().enumerate() {
                    if x > r[0] && x < r[1] && y > r[2] && y < r[3] {
                        cnt[k] += 1;
                        s2[k] += r2;
                        s4[k] += r2 * r2;
                    }
                }
            }
            let nf = n as f64;
            for (k, r) in rects.iter().enumerate() {
                let (m0, m2) = m.rect(r[0], r[1], r[2], r[3]);
                let p = cnt[k] as f64 / nf;
                let se0 = (m0 * (1.0 - m0) / nf).sqrt().max(1.0 / nf);
                let mean2 = s2[k] / nf;
                let se2 = ((s4[k] / nf - mean2 * mean2) / nf).sqrt().max(1e-300);
                let (z0, z2) = ((p - m0) / se0, (mean2 - m2) / se2);
                println!("{name} rect {k}: m0 {m0:.6} z {z0:+.2}, m2 {m2:.6} z {z2:+.2}");
                assert!(
                    z0.abs() < 5.0 && z2.abs() < 5.0,
                    "{name} {r:?}: z {z0} {z2}"
                );
            }
        }
    }

    /// Cost probe (ignored): build time per profile, then `MOMENTS_CALLS` (env, default 0)
    /// `rect` calls on the annular table over random rectangles of a voxel-like size; run under
    /// `valgrind --tool=callgrind` with 0 and N calls, the instruction difference / N is the
    /// per-call cost.
    #[test]
    #[ignore]
    fn footprint_moments_cost() {
        let calls: usize = std::env::var("MOMENTS_CALLS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        let which: usize = std::env::var("MOMENTS_PROFILE")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(4);
        let profiles = moment_profiles();
        for (name, s, _) in &profiles {
            let t = std::time::Instant::now();
            let m = s.moments();
            println!("{name}: build {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(&m);
        }
        let (_, s, _) = &profiles[which];
        let m = s.moments();
        let reach = m.reach_m();
        let mut state = 0x1234_5678u64;
        let mut acc = 0.0;
        for _ in 0..calls {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let x0 = ((state >> 11) as f64 / (1u64 << 53) as f64 * 2.4 - 1.2) * reach;
            let y0 = ((state >> 20) as f64 / (1u64 << 44) as f64 * 2.4 - 1.2) * reach;
            let (m0, m2) =
                std::hint::black_box(&m).rect(x0, x0 + 0.2 * reach, y0, y0 + 0.2 * reach);
            acc += m0 + m2;
        }
        println!("acc {acc}");
    }
}
