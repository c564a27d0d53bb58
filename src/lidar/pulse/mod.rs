//! Emitted LiDAR pulse: Gaussian temporal profile; transverse (footprint) beam profile —
//! Gaussian ([`FootprintProfile`]) or any radial distribution ([`BeamProfile`]: Gaussian,
//! uniform top hat, piecewise-linear table); footprint size from beam divergence, oblique
//! footprints, and exact inverse-CDF footprint sampling ([`FootprintSampler`])
//! (physics.md §9.1; DART 5 paper §4 and DART's LiDAR parameter schema).
//!
//! Units: times in ns, lengths in m, angles in rad.

use super::special::normal_interval;
use super::{LidarError, check_non_negative, check_positive};
use std::f64::consts::PI;

pub(crate) mod moments;
mod sampler;
#[cfg(test)]
mod tests;

pub use moments::{FOOTPRINT_MOMENTS_CACHE, FootprintMoments};
pub use sampler::FootprintSampler;

/// `FWHM = 2√(2 ln 2) σ` for a Gaussian.
pub const FWHM_PER_SIGMA: f64 = 2.354_820_045_030_949_3;

/// DART's default `gaussian_sigma_illu` (a scene default, [`crate::scene::desc`]).
pub use crate::scene::desc::DART_EDGE_RELATIVE_INTENSITY;

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

/// The beam profile is a scene field ([`crate::scene::desc::BeamProfile`], whose
/// [`BeamProfile::check`] holds its parameter rules).
pub use crate::scene::desc::BeamProfile;

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
