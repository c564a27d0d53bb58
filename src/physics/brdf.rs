//! Facet reflectance models: Lambertian, RPV, Hapke (Eradiate's 6-parameter variant), unpolarised
//! Fresnel reflectance, DART's specular lobe, facet direct transmittance, and directional–
//! hemispherical albedo by quadrature (physics.md §5).
//!
//! Stage: pure physics used by the Phase stage (facet tables) and the Radiative stage.
//!
//! Conventions: every model is evaluated **from vectors** (physics.md §1.4 pitfall ii). A facet has
//! unit normal `n` on its front side; `omega_in` is the *propagation* vector of the incident ray
//! (pointing into the facet, `omega_in·n < 0`), `omega_out` the propagation vector of the
//! reflected ray (`omega_out·n > 0`). Internally `μ_i = −omega_in·n`, `μ_v = omega_out·n`, and the
//! relative azimuth ψ is measured in the facet plane between the directions *to the source* and
//! *to the viewer*: **ψ = 0 when source and viewer are on the same side** (backscatter, hotspot),
//! as in RPV/SAIL and the Eradiate plugins. The phase angle g satisfies
//! `cos g = μ_i μ_v + sin θ_i sin θ_v cos ψ` (g = 0 at the hotspot). BRF = π × BRDF.
//! Cosines are clamped to ≥ 1e-6 (physics.md §1.4 pitfall iii); no function returns NaN.

use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, PI};

use crate::physics::lad::{gauss_legendre, tanh_sinh};

/// Smallest cosine used in `1/μ` or `μ^(k−1)` terms (physics.md §1.4).
pub const MU_MIN: f64 = 1e-6;

/// Unpolarised Fresnel reflectance for a wave going from index `n1` into `n2` at incidence cosine
/// `cos_i` (physics.md §5.4; Born & Wolf §1.5): `R_F = (r_s² + r_p²)/2`, with
/// `r_s = (n1 cos θ_i − n2 cos θ_t)/(n1 cos θ_i + n2 cos θ_t)`,
/// `r_p = (n1 cos θ_t − n2 cos θ_i)/(n1 cos θ_t + n2 cos θ_i)`, `sin θ_t = (n1/n2) sin θ_i`;
/// 1 beyond the critical angle and at grazing incidence. `cos_i` uses its absolute value.
pub fn fresnel_unpolarized(cos_i: f64, n1: f64, n2: f64) -> f64 {
    let ci = cos_i.abs().min(1.0);
    if !(n1 > 0.0 && n2 > 0.0 && ci.is_finite()) {
        return 1.0;
    }
    let si = (1.0 - ci * ci).max(0.0).sqrt();
    let st = n1 / n2 * si;
    if st >= 1.0 {
        return 1.0;
    }
    let ct = (1.0 - st * st).sqrt();
    let rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    let rp = (n1 * ct - n2 * ci) / (n1 * ct + n2 * ci);
    (0.5 * (rs * rs + rp * rp)).clamp(0.0, 1.0)
}

/// Facet direct (undeviated) transmittance along a ray of cosine `mu` to the facet normal:
/// `T_dir^(1/|μ|)` (physics.md §5.1; seed §3.1). `t_dir` is the transmittance along the normal.
/// |μ| is clamped at 1e-6, so grazing rays are not transmitted (for `t_dir < 1`).
pub fn direct_transmittance(t_dir: f64, mu: f64) -> f64 {
    let t = t_dir.clamp(0.0, 1.0);
    if t == 1.0 {
        return 1.0;
    }
    let m = mu.abs().max(MU_MIN);
    t.powf(1.0 / m)
}

/// Facet-local geometry of one (incident, outgoing) pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalGeometry {
    /// Cosine of the incidence angle (direction to the source · n), ≥ 1e-6.
    pub mu_i: f64,
    /// Cosine of the view angle (outgoing propagation · n), ≥ 1e-6.
    pub mu_v: f64,
    /// Cosine of the relative azimuth ψ (ψ = 0: source and viewer on the same side).
    pub cos_psi: f64,
}

impl LocalGeometry {
    /// Builds the local geometry from a facet normal and propagation vectors (unit or not).
    /// Returns `None` when the ray does not hit the front side or does not leave from it.
    pub fn from_vectors(normal: DVec3, omega_in: DVec3, omega_out: DVec3) -> Option<Self> {
        let n = normal.normalize_or_zero();
        let s = -omega_in.normalize_or_zero();
        let v = omega_out.normalize_or_zero();
        let mu_i = s.dot(n);
        let mu_v = v.dot(n);
        if !(mu_i > 0.0 && mu_v > 0.0) {
            return None;
        }
        let a = s - mu_i * n;
        let b = v - mu_v * n;
        let (la, lb) = (a.length(), b.length());
        let cos_psi = if la > 1e-12 && lb > 1e-12 {
            (a.dot(b) / (la * lb)).clamp(-1.0, 1.0)
        } else {
            1.0
        };
        Some(Self {
            mu_i: mu_i.clamp(MU_MIN, 1.0),
            mu_v: mu_v.clamp(MU_MIN, 1.0),
            cos_psi,
        })
    }

    /// From zenith angles (rad) and relative azimuth ψ (rad, 0 = same side).
    pub fn from_angles(theta_i: f64, theta_v: f64, psi: f64) -> Self {
        Self {
            mu_i: theta_i.cos().clamp(MU_MIN, 1.0),
            mu_v: theta_v.cos().clamp(MU_MIN, 1.0),
            cos_psi: psi.cos(),
        }
    }

    /// Cosine of the phase angle g (0 at the hotspot).
    pub fn cos_phase(&self) -> f64 {
        let si = (1.0 - self.mu_i * self.mu_i).max(0.0).sqrt();
        let sv = (1.0 - self.mu_v * self.mu_v).max(0.0).sqrt();
        (self.mu_i * self.mu_v + si * sv * self.cos_psi).clamp(-1.0, 1.0)
    }
}

/// Error raised by invalid facet optical parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name} = {value} is invalid: {reason}")]
pub struct BrdfError {
    /// Parameter name.
    pub name: &'static str,
    /// Offending value.
    pub value: f64,
    /// Allowed range.
    pub reason: &'static str,
}

fn chk(name: &'static str, value: f64, ok: bool, reason: &'static str) -> Result<(), BrdfError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(BrdfError {
            name,
            value,
            reason,
        })
    }
}

/// A facet reflectance model as written in a scene (RON: `Lambertian(reflectance: 0.2)`,
/// `Rpv(rho0: 0.1, k: 0.8, theta: -0.1, rho_c: Some(0.1))`,
/// `Hapke(w: 0.5, b: 0.2, c: 0.5, theta_bar_deg: 30, b0: 0, h: 0)`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Brdf {
    /// Lambertian: BRF = reflectance.
    Lambertian {
        /// Hemispherical reflectance, `[0, 1]`.
        reflectance: f64,
    },
    /// Rahman–Pinty–Verstraete (1993), 4-parameter "ρ_c" form (physics.md §5.2):
    /// `BRF = ρ0 [μ_i μ_v (μ_i + μ_v)]^(k−1) F(g) [1 + (1 − ρ_c)/(1 + G)]`,
    /// `F(g) = (1 − Θ²)/(1 + Θ² + 2Θ cos g)^{3/2}` (Θ < 0: backward scattering),
    /// `G = √(tan²θ_i + tan²θ_v − 2 tanθ_i tanθ_v cos ψ)`. Same as Eradiate's `rpv` plugin.
    Rpv {
        /// Amplitude ρ0 (> 0).
        rho0: f64,
        /// Minnaert-like bowl/bell exponent k (> 0).
        k: f64,
        /// Henyey–Greenstein asymmetry Θ (DART's `g`), `(−1, 1)`.
        theta: f64,
        /// Hotspot parameter ρ_c (DART's `h`); `None` means ρ_c = ρ0 (3-parameter RPV).
        #[serde(default)]
        rho_c: Option<f64>,
    },
    /// Hapke (1984) with the 2-lobe phase function of Eradiate's `hapke` plugin (see
    /// [`hapke_brf`]).
    Hapke {
        /// Single-scattering albedo w, `[0, 1]`.
        w: f64,
        /// HG lobe asymmetry b, `[0, 1]`.
        b: f64,
        /// Back/forward lobe weight c, `[0, 1]`.
        c: f64,
        /// Mean roughness slope angle θ̄ in degrees, `[0, 90)`.
        theta_bar_deg: f64,
        /// Shadow-hiding opposition amplitude B0, `[0, 1]`.
        b0: f64,
        /// Opposition width h, `[0, 1]`.
        h: f64,
    },
}

/// RPV BRF (Rahman, Pinty & Verstraete 1993, JGR 98:20791, eqs. 3–6; Eradiate handbook form),
/// see [`Brdf::Rpv`]. Dimensionless.
pub fn rpv_brf(geo: &LocalGeometry, rho0: f64, k: f64, theta: f64, rho_c: f64) -> f64 {
    let (mi, mv) = (geo.mu_i.max(MU_MIN), geo.mu_v.max(MU_MIN));
    let ti = (1.0 - mi * mi).max(0.0).sqrt() / mi;
    let tv = (1.0 - mv * mv).max(0.0).sqrt() / mv;
    let cg = geo.cos_phase();
    let f = (1.0 - theta * theta)
        / (1.0 + theta * theta + 2.0 * theta * cg)
            .max(1e-300)
            .powf(1.5);
    let g = (ti * ti + tv * tv - 2.0 * ti * tv * geo.cos_psi)
        .max(0.0)
        .sqrt();
    let m = (mi * mv * (mi + mv)).powf(k - 1.0);
    (rho0 * m * f * (1.0 + (1.0 - rho_c) / (1.0 + g))).max(0.0)
}

/// Hapke BRF exactly as Eradiate's Mitsuba plugin `hapke` (eradiate/mitsuba3,
/// `src/eradiate_plugins/bsdfs/hapke.cpp`; Hapke 1984 Icarus 59:41 eqs. 1–3, 14–18, 31–36,
/// 45–58, with Hapke 2002's H-function approximation):
///
/// `BRF = (w/4) · μ_0e/((μ_0e + μ_e) μ_0) · [P(g)(1 + B(g)) + H(μ_0e)H(μ_e) − 1] · S(i, e, ψ)`
///
/// * `P(g) = (1−c)(1−b²)/(1+2b cos g+b²)^{3/2} + c(1−b²)/(1−2b cos g+b²)^{3/2}`
///   (note: with this sign convention c weights the lobe that peaks at g = 0, i.e. backscatter);
/// * `B(g) = B0/(1 + tan(g/2)/h)` (shadow-hiding opposition effect);
/// * `H(x) = 1/(1 − w x [r0 + (1 − 2 r0 x)/2 · ln((1+x)/x)])`, `r0 = (1−γ)/(1+γ)`, `γ = √(1−w)`;
/// * `μ_0e, μ_e, η_0e, η_e, S` are Hapke's (1984) rough-surface effective cosines and shadowing
///   function with `χ(θ̄) = 1/√(1 + π tan²θ̄)`, `E1(x) = exp(−(2/π) cot θ̄ cot x)`,
///   `E2(x) = exp(−(1/π) cot²θ̄ cot²x)`, `f(ψ) = exp(−2 tan(ψ/2))`, split into the cases
///   `i ≤ e` and `e < i` as in eqs. 46–51.
///
/// Edge cases (no NaN): `h = 0` gives B = 0 except at g = 0 exactly (B0); cosines ≥ 1e-6.
///
/// **Mapping to DART's Hapke inputs (W, C1–C4, H1, H2) is an open question** (physics.md §5.3,
/// §14): the natural reading is `W = w`, `(H1, H2) = (B0, h)` and C1–C4 phase-function
/// coefficients (e.g. a double HG `(b, c)` or a Legendre form `1 + b cos g + c(3cos²g−1)/2`);
/// DART has no θ̄ roughness in that list. Pin it once DART reference runs exist.
#[allow(clippy::too_many_arguments)]
pub fn hapke_brf(
    geo: &LocalGeometry,
    w: f64,
    b: f64,
    c: f64,
    theta_bar_deg: f64,
    b0: f64,
    h: f64,
) -> f64 {
    let mu_0 = geo.mu_i.clamp(MU_MIN, 1.0);
    let mu = geo.mu_v.clamp(MU_MIN, 1.0);
    let i = mu_0.acos();
    let e = mu.acos();
    let sin_i = i.sin();
    let sin_e = e.sin();
    let cos_phi = geo.cos_psi.clamp(-1.0, 1.0);
    let phi = cos_phi.acos(); // ∈ [0, π]
    let tan_theta = theta_bar_deg.to_radians().tan();

    let chi = 1.0 / (1.0 + PI * tan_theta * tan_theta).sqrt();
    let e1 = |x: f64| (-2.0 / PI / tan_theta / x.tan()).exp();
    let e2 = |x: f64| (-1.0 / PI / (tan_theta * tan_theta) / (x.tan() * x.tan())).exp();
    let h_fn = |x: f64| {
        let x = x.max(1e-12);
        let gamma = (1.0 - w).max(0.0).sqrt();
        let r0 = (1.0 - gamma) / (1.0 + gamma);
        1.0 / (1.0 - w * x * (r0 + (1.0 - 2.0 * r0 * x) * 0.5 * ((1.0 + x) / x).ln()))
    };
    // eval_mu(tan θ̄, a = max(i,e), b = min(i,e), cos_x, sin_x, φ, opt_cos_phi, sign)
    let eval_mu = |a: f64, bb: f64, cos_x: f64, sin_x: f64, opt_cos_phi: f64, sign: f64| {
        let s2 = (phi * 0.5).sin();
        chi * (cos_x
            + sin_x * tan_theta * (opt_cos_phi * e2(a) + sign * s2 * s2 * e2(bb))
                / (2.0 - e1(a) - phi / PI * e1(bb)))
    };
    let (a, bb) = if e <= i { (i, e) } else { (e, i) };
    let mu_eg = if e <= i {
        eval_mu(a, bb, mu, sin_e, cos_phi, 1.0)
    } else {
        eval_mu(a, bb, mu, sin_e, 1.0, -1.0)
    };
    let mu_0eg = if e <= i {
        eval_mu(a, bb, mu_0, sin_i, 1.0, -1.0)
    } else {
        eval_mu(a, bb, mu_0, sin_i, cos_phi, 1.0)
    };
    let mu_ratio = mu_0eg / (mu_0eg + mu_eg) / mu_0;

    let cos_g = (mu_0 * mu + sin_i * sin_e * cos_phi).clamp(-1.0, 1.0);
    let g = cos_g.acos();
    let nb = 1.0 - b * b;
    let p = (1.0 - c) * nb / (1.0 + 2.0 * b * cos_g + b * b).powf(1.5)
        + c * nb / (1.0 - 2.0 * b * cos_g + b * b).max(1e-300).powf(1.5);
    let bg = if b0 == 0.0 {
        0.0
    } else if h == 0.0 {
        if g == 0.0 { b0 } else { 0.0 }
    } else {
        b0 / (1.0 + (g / 2.0).tan() / h)
    };
    let m = h_fn(mu_0eg) * h_fn(mu_eg) - 1.0;
    let f = (-2.0 * (phi / 2.0).clamp(0.0, FRAC_PI_2 - f64::EPSILON).tan()).exp();
    let eta_0e = chi * (mu_0 + sin_i * tan_theta * e2(i) / (2.0 - e1(i)));
    let eta_e = chi * (mu + sin_e * tan_theta * e2(e) / (2.0 - e1(e)));
    let (opt_mu, opt_eta) = if e < i { (mu, eta_e) } else { (mu_0, eta_0e) };
    let s = (mu_eg * mu_0 * chi) / (eta_e * eta_0e * (1.0 - f + f * chi * opt_mu / opt_eta));
    let v = w * 0.25 * mu_ratio * (p * (1.0 + bg) + m) * s;
    if v.is_finite() { v.max(0.0) } else { 0.0 }
}

impl Brdf {
    /// Checks the parameter ranges (Hapke ranges as in the Eradiate plugin; RPV: ρ0 > 0, k > 0,
    /// |Θ| < 1, ρ_c finite).
    pub fn validate(&self) -> Result<(), BrdfError> {
        match *self {
            Self::Lambertian { reflectance } => chk(
                "reflectance",
                reflectance,
                (0.0..=1.0).contains(&reflectance),
                "must be in [0, 1]",
            ),
            Self::Rpv {
                rho0,
                k,
                theta,
                rho_c,
            } => {
                chk(
                    "rho0",
                    rho0,
                    rho0 > 0.0 && rho0 <= 10.0,
                    "must be in (0, 10]",
                )?;
                chk("k", k, k > 0.0 && k <= 5.0, "must be in (0, 5]")?;
                chk("theta", theta, theta.abs() < 1.0, "must be in (-1, 1)")?;
                if let Some(h) = rho_c {
                    chk("rho_c", h, h.abs() <= 10.0, "must be in [-10, 10]")?;
                }
                Ok(())
            }
            Self::Hapke {
                w,
                b,
                c,
                theta_bar_deg,
                b0,
                h,
            } => {
                let unit = |x: f64| (0.0..=1.0).contains(&x);
                chk("w", w, unit(w), "must be in [0, 1]")?;
                chk("b", b, unit(b) && b < 1.0, "must be in [0, 1)")?;
                chk("c", c, unit(c), "must be in [0, 1]")?;
                chk(
                    "theta_bar_deg",
                    theta_bar_deg,
                    (0.0..90.0).contains(&theta_bar_deg),
                    "must be in [0, 90)",
                )?;
                chk("b0", b0, unit(b0), "must be in [0, 1]")?;
                chk("h", h, unit(h), "must be in [0, 1]")
            }
        }
    }

    /// True for the Lambertian model (facet tables then use exact projected solid angles).
    pub fn is_lambertian(&self) -> bool {
        matches!(self, Self::Lambertian { .. })
    }

    /// BRF for the local geometry (dimensionless; BRDF = BRF/π).
    pub fn brf_local(&self, geo: &LocalGeometry) -> f64 {
        match *self {
            Self::Lambertian { reflectance } => reflectance,
            Self::Rpv {
                rho0,
                k,
                theta,
                rho_c,
            } => rpv_brf(geo, rho0, k, theta, rho_c.unwrap_or(rho0)),
            Self::Hapke {
                w,
                b,
                c,
                theta_bar_deg,
                b0,
                h,
            } => hapke_brf(geo, w, b, c, theta_bar_deg, b0, h),
        }
    }

    /// BRF from a facet normal and propagation vectors (0 when the geometry is not front-side
    /// in and front-side out).
    pub fn brf(&self, normal: DVec3, omega_in: DVec3, omega_out: DVec3) -> f64 {
        LocalGeometry::from_vectors(normal, omega_in, omega_out).map_or(0.0, |g| self.brf_local(&g))
    }

    /// Directional–hemispherical ("black-sky") albedo `ρ_DH(μ_i) = (1/π)∫ BRF μ_v dΩ_v`
    /// (physics.md §1.4, §5.2) with the default resolution (tanh–sinh in μ_v × 720 azimuths,
    /// relative accuracy ~1e-5 for the oracle parameter sets). Not clipped.
    pub fn albedo_dh(&self, mu_i: f64) -> f64 {
        self.albedo_dh_with(mu_i, 720)
    }

    /// [`Self::albedo_dh`] with `n_phi` midpoint azimuths over ψ ∈ [0, π] (mirror symmetry) and
    /// tanh–sinh in μ_v (split at μ_v = μ_i where the hotspot kink lies).
    pub fn albedo_dh_with(&self, mu_i: f64, n_phi: usize) -> f64 {
        if let Self::Lambertian { reflectance } = *self {
            return reflectance;
        }
        let mu_i = mu_i.clamp(MU_MIN, 1.0);
        let n_phi = n_phi.max(2) / 2;
        let mut s = 0.0;
        let inner = |mu_v: f64| {
            let mut a = 0.0;
            for m in 0..n_phi {
                let psi = PI * (m as f64 + 0.5) / n_phi as f64;
                let geo = LocalGeometry {
                    mu_i,
                    mu_v: mu_v.max(MU_MIN),
                    cos_psi: psi.cos(),
                };
                a += self.brf_local(&geo);
            }
            a * PI / n_phi as f64 * 2.0 * mu_v
        };
        for (lo, hi) in [(0.0, mu_i), (mu_i, 1.0)] {
            s += tanh_sinh(lo, hi, |x, _, _| inner(x));
        }
        s / PI
    }
}

/// DART's facet specular component (physics.md §5.4) [rec shape]: specular fraction
/// `s(θ_i) = min(1, factor · R_F(θ_i; 1 → n))`, spread over the directions within `width_deg` of
/// the mirror direction; the diffuse part is scaled by `1 − s`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpecularLobe {
    /// Refractive index of the surface (> 1).
    pub refractive_index: f64,
    /// Half-width of the lobe around the mirror direction, degrees, `[0, 90]`.
    pub width_deg: f64,
    /// Multiplicative factor on the Fresnel reflectance (`specularIntensityFactor`), ≥ 0.
    pub factor: f64,
}

impl SpecularLobe {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), BrdfError> {
        chk(
            "refractive_index",
            self.refractive_index,
            self.refractive_index > 1.0 && self.refractive_index <= 5.0,
            "must be in (1, 5]",
        )?;
        chk(
            "width_deg",
            self.width_deg,
            (0.0..=90.0).contains(&self.width_deg),
            "must be in [0, 90]",
        )?;
        chk(
            "factor",
            self.factor,
            self.factor >= 0.0 && self.factor <= 100.0,
            "must be in [0, 100]",
        )
    }

    /// Specular fraction of intercepted power for incidence cosine `cos_i` (to the normal).
    pub fn fraction(&self, cos_i: f64) -> f64 {
        (self.factor * fresnel_unpolarized(cos_i, 1.0, self.refractive_index)).min(1.0)
    }

    /// Cone solid angle of the lobe, `2π(1 − cos δ)` (sr).
    pub fn solid_angle_sr(&self) -> f64 {
        2.0 * PI * (1.0 - self.width_deg.to_radians().cos())
    }
}

/// Mirror direction of propagation vector `omega_in` about unit `normal`: `Ω − 2(Ω·n)n`.
pub fn mirror(omega_in: DVec3, normal: DVec3) -> DVec3 {
    omega_in - 2.0 * omega_in.dot(normal) * normal
}

/// Bi-hemispherical ("white-sky") albedo by Gauss–Legendre quadrature,
/// `ρ_BH = 2∫_0^1 ρ_DH(μ) μ dμ` with `n` nodes (physics.md §1.4).
pub fn albedo_bh(brdf: &Brdf, n: usize) -> f64 {
    let (x, w) = gauss_legendre(n.max(2));
    // 2∫_0^1 ρ_DH μ dμ with μ = (x + 1)/2, dμ = dx/2.
    x.iter()
        .zip(&w)
        .map(|(x, w)| {
            let mu = 0.5 * (x + 1.0);
            w * brdf.albedo_dh(mu) * mu
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn rpv_physics_md_values() {
        // physics.md §5.2: ρ0 = 0.1, k = 0.8, Θ = −0.1, h = 0.1.
        let m = Brdf::Rpv {
            rho0: 0.1,
            k: 0.8,
            theta: -0.1,
            rho_c: Some(0.1),
        };
        for (ti, tv, psi, want) in [
            (30.0, 30.0, 0.0, 0.24487),
            (30.0, 30.0, 180.0, 0.15344),
            (30.0, 0.0, 0.0, 0.18453),
            (60.0, 45.0, 90.0, 0.16763),
        ] {
            let g = LocalGeometry::from_angles(
                f64::to_radians(ti),
                f64::to_radians(tv),
                f64::to_radians(psi),
            );
            let v = m.brf_local(&g);
            assert!((v - want).abs() < 6e-6, "{ti} {tv} {psi}: {v} vs {want}");
        }
    }

    #[test]
    fn fresnel_limits() {
        let r0 = ((1.5f64 - 1.0) / 2.5).powi(2);
        assert!((fresnel_unpolarized(1.0, 1.0, 1.5) - r0).abs() < 1e-15);
        assert_eq!(fresnel_unpolarized(0.0, 1.0, 1.5), 1.0);
        assert_eq!(fresnel_unpolarized(0.1, 1.5, 1.0), 1.0); // total internal reflection
    }

    #[test]
    fn lambertian_albedo_and_transmittance() {
        assert_eq!(Brdf::Lambertian { reflectance: 0.3 }.albedo_dh(0.5), 0.3);
        assert!((direct_transmittance(0.5, 0.5) - 0.25).abs() < 1e-15);
        assert_eq!(direct_transmittance(0.5, 0.0), 0.0);
    }

    proptest! {
        #[test]
        fn brdfs_are_reciprocal_and_finite(ti in 0.0f64..1.5, tv in 0.0f64..1.5, psi in 0.0f64..std::f64::consts::PI) {
            for m in [
                Brdf::Rpv { rho0: 0.25, k: 0.6, theta: -0.2, rho_c: Some(0.5) },
                Brdf::Hapke { w: 0.6, b: 0.3, c: 0.7, theta_bar_deg: 20.0, b0: 0.8, h: 0.06 },
                Brdf::Hapke { w: 0.5, b: 0.2, c: 0.5, theta_bar_deg: 30.0, b0: 0.0, h: 0.0 },
            ] {
                let a = m.brf_local(&LocalGeometry::from_angles(ti, tv, psi));
                let b = m.brf_local(&LocalGeometry::from_angles(tv, ti, psi));
                prop_assert!(a.is_finite() && a >= 0.0);
                prop_assert!((a - b).abs() <= 1e-9 * a.abs().max(1e-3), "{:?} {} {}", m, a, b);
            }
        }
    }
}
