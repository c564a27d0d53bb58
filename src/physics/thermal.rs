//! Thermal emission: Planck's law, its band average over a spectral response, the brightness
//! temperature that inverts them, and Stefan–Boltzmann (physics.md §7.1; Planck 1901; CODATA
//! 2018 exact constants). Radiances are spectral, W m⁻² sr⁻¹ µm⁻¹; wavelengths nm;
//! temperatures K.
//!
//! The foundation of the thermal mode (issue #34): emission sources for the solvers and the
//! brightness-temperature products are built on these functions.

use super::spectral::{SpectralBand, SpectralError};

/// Planck constant, J s (CODATA 2018, exact).
pub const H: f64 = 6.626_070_15e-34;
/// Speed of light in vacuum, m s⁻¹ (exact).
pub const C: f64 = 299_792_458.0;
/// Boltzmann constant, J K⁻¹ (CODATA 2018, exact).
pub const K_B: f64 = 1.380_649e-23;
/// Stefan–Boltzmann constant σ = 2π⁵k⁴/(15h³c²), W m⁻² K⁻⁴.
pub const SIGMA_SB: f64 = 5.670_374_419e-8;

/// First radiation constant for radiance 2hc², W m² sr⁻¹.
const C1L: f64 = 2.0 * H * C * C;
/// Second radiation constant hc/k, m K.
const C2: f64 = H * C / K_B;

/// Planck's spectral radiance `B_λ(T) = 2hc²/λ⁵ / (exp(hc/(λkT)) − 1)` of a blackbody at
/// `t_k` K and `wavelength_nm` nm, W m⁻² sr⁻¹ µm⁻¹ (physics.md §7.1). `expm1` keeps the
/// Rayleigh–Jeans end exact; the Wien end returns 0 once the exponent passes 700 (below
/// 1e-300 of the peak). 0 for T ≤ 0.
pub fn planck(wavelength_nm: f64, t_k: f64) -> f64 {
    if !(t_k > 0.0 && wavelength_nm > 0.0) {
        return 0.0;
    }
    let l = wavelength_nm * 1e-9;
    let x = C2 / (l * t_k);
    if x > 700.0 {
        return 0.0;
    }
    C1L / l.powi(5) / x.exp_m1() * 1e-6
}

/// `∂B_λ/∂T`, W m⁻² sr⁻¹ µm⁻¹ K⁻¹ (for Newton steps).
fn planck_dt(wavelength_nm: f64, t_k: f64) -> f64 {
    let l = wavelength_nm * 1e-9;
    let x = C2 / (l * t_k);
    if x > 700.0 {
        return 0.0;
    }
    let b = planck(wavelength_nm, t_k);
    // dB/dT = B · x eˣ / ((eˣ − 1) T)
    b * x / (t_k * (1.0 - (-x).exp()))
}

/// The temperature of the blackbody whose radiance at `wavelength_nm` is `radiance`
/// (W m⁻² sr⁻¹ µm⁻¹): `T_B = (hc/(λk)) / ln(1 + 2hc²/(λ⁵ L))` (physics.md §7.1), K; 0 for
/// L ≤ 0.
pub fn brightness_temperature(wavelength_nm: f64, radiance: f64) -> f64 {
    if !(radiance > 0.0 && wavelength_nm > 0.0) {
        return 0.0;
    }
    let l = wavelength_nm * 1e-9;
    (C2 / l) / (C1L / (l.powi(5) * radiance * 1e6)).ln_1p()
}

/// Band-averaged Planck radiance `∫ S(λ) B_λ(T) dλ / ∫ S(λ) dλ`, W m⁻² sr⁻¹ µm⁻¹ (physics.md
/// §7.1; DART integrates over the band with 1000 steps). The response is piecewise linear
/// between its samples and B is smooth on the scale of a sample step, so each step is
/// integrated by Gauss–Legendre with 4 nodes (exact for the product of a line and a cubic).
/// A monochromatic band gives `B_λ(T)` at its wavelength.
pub fn band_planck(band: &SpectralBand, t_k: f64) -> Result<f64, SpectralError> {
    let Some(srf) = band.to_srf()? else {
        let SpectralBand::Monochromatic { wavelength_nm } = band else {
            unreachable!("only monochromatic bands have no SRF")
        };
        return Ok(planck(*wavelength_nm, t_k));
    };
    let s = srf.as_spectrum();
    let (w, v) = (s.wavelength_nm(), s.values());
    // Gauss–Legendre nodes and weights on [−1, 1], 4 points.
    const X: [f64; 4] = [
        -0.861_136_311_594_052_6,
        -0.339_981_043_584_856_3,
        0.339_981_043_584_856_3,
        0.861_136_311_594_052_6,
    ];
    const W: [f64; 4] = [
        0.347_854_845_137_453_9,
        0.652_145_154_862_546_1,
        0.652_145_154_862_546_1,
        0.347_854_845_137_453_9,
    ];
    let (mut num, mut den) = (0.0, 0.0);
    for k in 0..w.len().saturating_sub(1) {
        let (a, b) = (w[k], w[k + 1]);
        let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
        for (x, wt) in X.iter().zip(W) {
            let lam = mid + half * x;
            let resp = v[k] + (v[k + 1] - v[k]) * (lam - a) / (b - a);
            num += wt * half * resp * planck(lam, t_k);
            den += wt * half * resp;
        }
    }
    if den > 0.0 {
        Ok(num / den)
    } else {
        Err(SpectralError::Invalid(format!(
            "{}: the response integrates to 0",
            band.describe()
        )))
    }
}

/// The brightness temperature of a band: the T with [`band_planck`]`(band, T) = radiance`, K,
/// by Newton steps on the band's centroid derivative, safeguarded by bisection (the band
/// radiance increases with T). 0 for radiance ≤ 0. Converged to 1e-9 K.
pub fn band_brightness_temperature(
    band: &SpectralBand,
    radiance: f64,
) -> Result<f64, SpectralError> {
    if let SpectralBand::Monochromatic { wavelength_nm } = band {
        return Ok(brightness_temperature(*wavelength_nm, radiance));
    }
    if !(radiance > 0.0) {
        return Ok(0.0);
    }
    let centroid = band.centroid_nm()?;
    let (mut lo, mut hi) = (1e-3_f64, 1e5_f64);
    let mut t = brightness_temperature(centroid, radiance).clamp(lo, hi);
    for _ in 0..200 {
        let f = band_planck(band, t)? - radiance;
        if f > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        let d = planck_dt(centroid, t);
        let mut next = if d > 0.0 { t - f / d } else { 0.5 * (lo + hi) };
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - t).abs() < 1e-9 || hi - lo < 1e-9 {
            return Ok(next);
        }
        t = next;
    }
    Ok(t)
}

/// Stefan–Boltzmann exitance of a grey body, `M = ε σ T⁴`, W m⁻² (its radiance is M/π).
pub fn stefan_boltzmann(emissivity: f64, t_k: f64) -> f64 {
    emissivity * SIGMA_SB * t_k.powi(4)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// physics.md §7.1's check values.
    #[test]
    fn planck_matches_the_reference_values() {
        for (lam_um, t, want) in [
            (10.0, 300.0, 9.924033),
            (3.9, 300.0, 0.602537),
            (11.0, 250.0, 3.972817),
        ] {
            let b = planck(lam_um * 1e3, t);
            assert!(
                (b - want).abs() < 5e-7 * want,
                "B({lam_um} µm, {t} K) = {b}"
            );
        }
    }

    #[test]
    fn brightness_temperature_inverts_planck() {
        for lam in [500.0, 3_900.0, 10_000.0, 12_000.0, 1e6] {
            for t in [50.0, 250.0, 300.0, 1_000.0, 6_000.0] {
                let b = planck(lam, t);
                if b > 1e-200 {
                    let tb = brightness_temperature(lam, b);
                    assert!((tb - t).abs() < 1e-9 * t, "{lam} nm {t} K → {tb}");
                }
            }
        }
        assert_eq!(brightness_temperature(10_000.0, 0.0), 0.0);
        assert_eq!(planck(10_000.0, 0.0), 0.0);
        // Wien end: no overflow, no NaN.
        assert_eq!(planck(100.0, 10.0), 0.0);
    }

    /// π ∫ B_λ dλ = σ T⁴ (Stefan–Boltzmann): 1–1000 µm at 300 K holds all but 1e-4 of the
    /// exitance (459.30 W m⁻², physics.md §7.1); midpoint sum in ln λ.
    #[test]
    fn the_integral_of_planck_is_stefan_boltzmann() {
        let (lo, hi, n) = (1_000.0_f64, 1_000_000.0_f64, 200_000);
        let h = (hi.ln() - lo.ln()) / n as f64;
        let integral: f64 = (0..n)
            .map(|i| {
                let l = (lo.ln() + (i as f64 + 0.5) * h).exp();
                planck(l, 300.0) * l * h * 1e-3 // µm⁻¹ × dλ in µm
            })
            .sum();
        let m = std::f64::consts::PI * integral;
        assert!((m - 459.30).abs() < 0.06, "{m}");
        assert!((stefan_boltzmann(1.0, 300.0) - 459.30).abs() < 0.01);
        assert!((m - stefan_boltzmann(1.0, 300.0)).abs() < 1e-4 * m);
    }

    /// A band's Planck average: a narrow band equals the monochromatic value; a wide uniform
    /// band equals the mean of B over it (fine midpoint sum); the band brightness temperature
    /// inverts it.
    #[test]
    fn band_planck_and_its_inverse() {
        let narrow = SpectralBand::Gaussian {
            center_nm: 10_000.0,
            fwhm_nm: 1.0,
        };
        let b = band_planck(&narrow, 300.0).unwrap();
        assert!((b / planck(10_000.0, 300.0) - 1.0).abs() < 1e-6, "{b}");
        let wide = SpectralBand::Interval {
            center_nm: 10_500.0,
            width_nm: 3_000.0,
        };
        let n = 100_000;
        let mean: f64 = (0..n)
            .map(|i| planck(9_000.0 + 3_000.0 * (i as f64 + 0.5) / n as f64, 300.0))
            .sum::<f64>()
            / n as f64;
        // A two-sample interval: 4 Gauss nodes over 3 µm of a smooth B.
        let got = band_planck(&wide, 300.0).unwrap();
        assert!((got / mean - 1.0).abs() < 1e-6, "{got} vs {mean}");
        for t in [200.0, 273.15, 300.0, 330.0] {
            for band in [&narrow, &wide] {
                let l = band_planck(band, t).unwrap();
                let tb = band_brightness_temperature(band, l).unwrap();
                assert!((tb - t).abs() < 1e-6, "{} {t} K → {tb}", band.describe());
            }
        }
    }
}
