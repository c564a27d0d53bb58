//! Local frames, the cosine hemisphere and the fluid phase functions (isotropic,
//! Henyey–Greenstein, two-term HG, depolarised Rayleigh; physics.md §4.2).

use super::Uniform01;
use crate::physics::phase::{FluidPhase, henyey_greenstein_sample};
use glam::DVec3;
use std::f64::consts::TAU;

/// `v` if it is unit length (to 1e-12), else `v` normalised, else `+z` (zero or non-finite).
#[inline]
pub(crate) fn unit_or_z(v: DVec3) -> DVec3 {
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
pub(crate) fn direction_about(axis: DVec3, cos_theta: f64, phi: f64) -> DVec3 {
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
pub(crate) const G_MAX: f64 = 1.0 - 1e-9;

#[inline]
pub(crate) fn sane_g(g: f64) -> f64 {
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
