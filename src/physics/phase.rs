//! Fluid phase functions (atmosphere gases, aerosols, smoke, water), normalised so that
//! `(1/4π)∫_{4π} P dΩ = 1` (physics.md §4.2).
//!
//! Stage: pure physics used by the Phase stage (fluid phase tables) and later by the atmosphere
//! and Monte Carlo stages. Angles: Θ is the scattering angle between propagation vectors,
//! `cos Θ = Ω'·Ω` (Θ = 0 forward, π backward).
//!
//! Sources: Henyey & Greenstein (1941); Hansen & Travis (1974, eq. 2.15) for the depolarised
//! Rayleigh phase function; Kattawar (1975) for the two-term HG family.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Air's depolarisation ratio ρ_n ≈ 0.0279 (Young 1980; used by Bodhaine et al. 1999).
pub const AIR_DEPOLARIZATION: f64 = 0.0279;

/// Isotropic phase function, `P = 1`.
#[inline]
pub fn isotropic(_cos_theta: f64) -> f64 {
    1.0
}

/// Rayleigh phase function with depolarisation ratio `rho_n` (Hansen & Travis 1974):
/// `γ = ρ_n/(2 − ρ_n)`, `P(Θ) = 3/(4(1+2γ)) [(1+3γ) + (1−γ) cos²Θ]`; ρ_n = 0 gives
/// `(3/4)(1 + cos²Θ)`. Dimensionless, normalised.
#[inline]
pub fn rayleigh(cos_theta: f64, rho_n: f64) -> f64 {
    let g = rho_n / (2.0 - rho_n);
    let c = cos_theta.clamp(-1.0, 1.0);
    3.0 / (4.0 * (1.0 + 2.0 * g)) * ((1.0 + 3.0 * g) + (1.0 - g) * c * c)
}

/// Henyey–Greenstein phase function `P = (1 − g²)/(1 + g² − 2g cos Θ)^{3/2}` (Henyey &
/// Greenstein 1941), asymmetry parameter `g ∈ (−1, 1)` = mean cosine. Normalised.
#[inline]
pub fn henyey_greenstein(cos_theta: f64, g: f64) -> f64 {
    let c = cos_theta.clamp(-1.0, 1.0);
    let d = (1.0 + g * g - 2.0 * g * c).max(1e-300);
    (1.0 - g * g) / (d * d.sqrt())
}

/// Two-term HG (Kattawar 1975; DART aerosol model): `P = a P_HG(g1) + (1 − a) P_HG(−g2)`.
///
/// **Sign convention of g2** (physics.md §4.2, an open question against DART output): `g2 > 0`
/// describes a *backward* lobe, i.e. the second term is `P_HG(Θ; −g2)`. Mean cosine
/// `a g1 − (1 − a) g2`.
#[inline]
pub fn two_term_hg(cos_theta: f64, a: f64, g1: f64, g2: f64) -> f64 {
    a * henyey_greenstein(cos_theta, g1) + (1.0 - a) * henyey_greenstein(cos_theta, -g2)
}

/// Inverse-CDF sample of `cos Θ` for HG with uniform `xi ∈ [0, 1)` (physics.md §4.2):
/// `cos Θ = [1 + g² − ((1 − g²)/(1 − g + 2g ξ))²]/(2g)`; isotropic when |g| < 1e-6.
pub fn henyey_greenstein_sample(g: f64, xi: f64) -> f64 {
    if g.abs() < 1e-6 {
        return (1.0 - 2.0 * xi).clamp(-1.0, 1.0);
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
}

/// Error raised by an invalid fluid phase function.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name} = {value} is invalid: {reason}")]
pub struct PhaseError {
    /// Parameter name.
    pub name: &'static str,
    /// Offending value.
    pub value: f64,
    /// Allowed range.
    pub reason: &'static str,
}

/// A fluid phase function as written in a scene (RON: `Isotropic`,
/// `Rayleigh(depolarization: 0.0279)`, `HenyeyGreenstein(g: 0.7)`,
/// `TwoTermHg(a: 0.95, g1: 0.79, g2: 0.4)`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum FluidPhase {
    /// `P = 1`.
    Isotropic,
    /// Molecular scattering with depolarisation ratio ρ_n ∈ [0, 0.5).
    Rayleigh {
        /// Depolarisation ratio ρ_n (air: 0.0279).
        depolarization: f64,
    },
    /// Single HG lobe, `g ∈ (−1, 1)`.
    HenyeyGreenstein {
        /// Asymmetry parameter (mean cosine).
        g: f64,
    },
    /// Two-term HG; `g2 > 0` is a backward lobe (see [`two_term_hg`]).
    TwoTermHg {
        /// Weight of the forward lobe, `[0, 1]`.
        a: f64,
        /// Forward asymmetry, `[0, 1)`.
        g1: f64,
        /// Backward asymmetry (magnitude), `[0, 1)`.
        g2: f64,
    },
}

impl FluidPhase {
    /// DART's aerosol defaults (XSD): two-term HG with a = 0.95, g1 = 0.79, g2 = 0.4.
    pub fn dart_aerosol_default() -> Self {
        Self::TwoTermHg {
            a: 0.95,
            g1: 0.79,
            g2: 0.4,
        }
    }

    /// Air molecules with ρ_n = 0.0279.
    pub fn air() -> Self {
        Self::Rayleigh {
            depolarization: AIR_DEPOLARIZATION,
        }
    }

    /// Checks parameter ranges (|g| < 0.999 keeps tables and samplers well conditioned).
    pub fn validate(&self) -> Result<(), PhaseError> {
        let chk = |name, value: f64, ok: bool, reason| {
            if value.is_finite() && ok {
                Ok(())
            } else {
                Err(PhaseError {
                    name,
                    value,
                    reason,
                })
            }
        };
        match *self {
            Self::Isotropic => Ok(()),
            Self::Rayleigh { depolarization } => chk(
                "depolarization",
                depolarization,
                (0.0..0.5).contains(&depolarization),
                "must be in [0, 0.5)",
            ),
            Self::HenyeyGreenstein { g } => {
                chk("g", g, g.abs() <= 0.999, "must be in [-0.999, 0.999]")
            }
            Self::TwoTermHg { a, g1, g2 } => {
                chk("a", a, (0.0..=1.0).contains(&a), "must be in [0, 1]")?;
                chk(
                    "g1",
                    g1,
                    (0.0..=0.999).contains(&g1),
                    "must be in [0, 0.999]",
                )?;
                chk(
                    "g2",
                    g2,
                    (0.0..=0.999).contains(&g2),
                    "must be in [0, 0.999]",
                )
            }
        }
    }

    /// Phase function value `P(cos Θ)` (normalised, dimensionless).
    #[inline]
    pub fn eval(&self, cos_theta: f64) -> f64 {
        match *self {
            Self::Isotropic => isotropic(cos_theta),
            Self::Rayleigh { depolarization } => rayleigh(cos_theta, depolarization),
            Self::HenyeyGreenstein { g } => henyey_greenstein(cos_theta, g),
            Self::TwoTermHg { a, g1, g2 } => two_term_hg(cos_theta, a, g1, g2),
        }
    }

    /// `P(Ω'·Ω)` from incident and outgoing propagation vectors (unit).
    #[inline]
    pub fn eval_dirs(&self, omega_in: DVec3, omega_out: DVec3) -> f64 {
        self.eval(omega_in.dot(omega_out))
    }

    /// Analytic mean cosine `⟨cos Θ⟩ = (1/4π)∫P cos Θ dΩ`.
    pub fn mean_cosine(&self) -> f64 {
        match *self {
            Self::Isotropic | Self::Rayleigh { .. } => 0.0,
            Self::HenyeyGreenstein { g } => g,
            Self::TwoTermHg { a, g1, g2 } => a * g1 - (1.0 - a) * g2,
        }
    }

    /// How peaked the phase function is: 0 for isotropic/Rayleigh, else the largest |g| of its HG
    /// lobes (tables refine the sub-sampling around the lobes when ≥ 0.3).
    pub fn peakedness(&self) -> f64 {
        match *self {
            Self::Isotropic | Self::Rayleigh { .. } => 0.0,
            Self::HenyeyGreenstein { g } => g.abs(),
            Self::TwoTermHg { g1, g2, .. } => g1.abs().max(g2.abs()),
        }
    }

    /// `(1/4π)∫P dΩ` by Gauss–Legendre quadrature in cos Θ with `n` nodes split at the lobe
    /// (a self-check; 1 to ~1e-12 for n ≥ 200 and |g| ≤ 0.9).
    pub fn normalisation(&self, n: usize) -> f64 {
        integrate_cos(n, |c| self.eval(c)) / 2.0
    }
}

/// `∫_{-1}^{1} f(c) dc` with composite Gauss–Legendre on panels graded geometrically toward
/// `c = ±1` (edges `±(1 − 2^-k)`, k = 1..10, and 0), where HG lobes peak; about `n` nodes.
pub(crate) fn integrate_cos<F: Fn(f64) -> f64>(n: usize, f: F) -> f64 {
    let per = (n / 24).max(4);
    let (x, w) = crate::physics::lad::gauss_legendre(per);
    let mut edges = vec![-1.0, 0.0, 1.0];
    for k in 1..=10 {
        let e = 1.0 - 0.5f64.powi(k);
        edges.push(e);
        edges.push(-e);
    }
    edges.sort_by(f64::total_cmp);
    let mut s = 0.0;
    for p in edges.windows(2) {
        let (a, b) = (p[0], p[1]);
        let h = 0.5 * (b - a);
        for (xi, wi) in x.iter().zip(&w) {
            s += wi * h * f(a + h * (xi + 1.0));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn normalised_and_mean_cosines() {
        for p in [
            FluidPhase::Isotropic,
            FluidPhase::air(),
            FluidPhase::Rayleigh {
                depolarization: 0.0,
            },
            FluidPhase::HenyeyGreenstein { g: 0.7 },
            FluidPhase::HenyeyGreenstein { g: -0.3 },
            FluidPhase::dart_aerosol_default(),
        ] {
            p.validate().unwrap();
            assert!((p.normalisation(1024) - 1.0).abs() < 1e-9, "{p:?}");
            let mc = integrate_cos(1024, |c| c * p.eval(c)) / 2.0;
            assert!((mc - p.mean_cosine()).abs() < 1e-9, "{p:?} {mc}");
        }
    }

    proptest! {
        #[test]
        fn hg_sampling_is_inverse_cdf(g in -0.95f64..0.95, xi in 0.0f64..1.0) {
            // Analytic CDF ∫_{-1}^{c} P/2 dc' = (1−g²)/(2g)[(1+g²−2gc)^(-1/2) − 1/(1+g)] equals ξ.
            prop_assume!(g.abs() > 1e-3);
            let c = henyey_greenstein_sample(g, xi);
            prop_assert!((-1.0..=1.0).contains(&c));
            let cdf = (1.0 - g * g) / (2.0 * g) * (1.0 / (1.0 + g * g - 2.0 * g * c).sqrt() - 1.0 / (1.0 + g));
            prop_assert!((cdf - xi).abs() < 1e-9, "cdf {} xi {}", cdf, xi);
        }
    }
}
