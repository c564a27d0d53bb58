//! Special functions for the LiDAR blocks: error function, complementary error function,
//! standard normal interval probabilities and log-factorials (Rust's `f64::erf` is unstable).
//!
//! Accuracy (checked against CPython's `math.erf`/`math.erfc`, which use the same double-precision
//! targets): relative error < 1e-14 for `erf` everywhere and for `erfc(x)` with x ≥ 2.5;
//! absolute error < 1e-15 for `erfc(x)`, x < 2.5. `ln_factorial` is accurate to ~1e-15 relative.

use std::f64::consts::{FRAC_2_SQRT_PI, PI, SQRT_2};

/// Switch point between the power series (for erf) and the continued fraction (for erfc).
const ERF_SWITCH: f64 = 2.5;

/// Error function `erf(x) = (2/√π)∫_0^x e^{−t²}dt`.
///
/// For |x| < 2.5 the all-positive series `erf(x) = (2/√π) e^{−x²} Σ_n 2ⁿx^{2n+1}/(1·3···(2n+1))`
/// (Abramowitz & Stegun 1964, eq. 7.1.6) is summed (no cancellation); beyond, `1 − erfc(|x|)`.
/// NaN propagates.
pub fn erf(x: f64) -> f64 {
    libm::erf(x)
}

/// Reference `erf` by series / continued fraction (slow; kept to cross-check [`erf`]).
pub fn erf_reference(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    let ax = x.abs();
    let v = if ax < ERF_SWITCH {
        erf_series(ax)
    } else {
        1.0 - erfc_continued_fraction(ax)
    };
    v.copysign(x)
}

/// Complementary error function `erfc(x) = 1 − erf(x)`, accurate in the upper tail.
///
/// For x ≥ 2.5 the Laplace continued fraction
/// `erfc(x) = (e^{−x²}/√π) · 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + …))))`
/// (Abramowitz & Stegun 1964, eq. 7.1.14) is evaluated with the modified Lentz method.
///
/// Evaluated with `libm::erfc` (the musl/FreeBSD implementation, < 1 ulp): the series and
/// continued fraction below cost ~50× more and dominated the LiDAR return fitting.
pub fn erfc(x: f64) -> f64 {
    libm::erfc(x)
}

/// Reference `erfc` by series / continued fraction (slow; kept to cross-check [`erfc`]).
pub fn erfc_reference(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x >= ERF_SWITCH {
        erfc_continued_fraction(x)
    } else if x >= 0.0 {
        1.0 - erf_series(x)
    } else {
        1.0 + erf(-x)
    }
}

fn erf_series(x: f64) -> f64 {
    // x in [0, 2.5): at most ~60 terms.
    let x2 = x * x;
    let mut term = x;
    let mut sum = x;
    let mut n = 0.0;
    while n < 200.0 {
        n += 1.0;
        term *= 2.0 * x2 / (2.0 * n + 1.0);
        sum += term;
        if term < 1e-17 * sum {
            break;
        }
    }
    FRAC_2_SQRT_PI * (-x2).exp() * sum
}

fn erfc_continued_fraction(x: f64) -> f64 {
    // x ≥ 2.5. Beyond ~27 the result underflows to 0.
    if x > 27.3 {
        return 0.0;
    }
    // f = x + a1/(x + a2/(x + ...)), a_n = n/2; erfc = e^{-x²}/(√π f).
    let tiny = 1e-300;
    let mut f = x;
    let mut c = x;
    let mut d = 0.0;
    for n in 1..500 {
        let a = n as f64 * 0.5;
        d = x + a * d;
        if d.abs() < tiny {
            d = tiny;
        }
        c = x + a / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    (-x * x).exp() / (f * PI.sqrt())
}

/// Standard normal CDF `Φ(z) = ½ erfc(−z/√2)`.
pub fn normal_cdf(z: f64) -> f64 {
    0.5 * erfc(-z / SQRT_2)
}

/// Probability that a standard normal variable falls in `[a, b)`, computed without cancellation
/// in either tail (uses erfc differences when both limits are on the same side of 0).
/// Returns 0 when `b <= a`.
pub fn normal_interval(a: f64, b: f64) -> f64 {
    if b <= a || a.is_nan() || b.is_nan() {
        return 0.0;
    }
    let p = if a >= 0.0 {
        0.5 * (erfc(a / SQRT_2) - erfc(b / SQRT_2))
    } else if b <= 0.0 {
        0.5 * (erfc(-b / SQRT_2) - erfc(-a / SQRT_2))
    } else {
        0.5 * (erf(b / SQRT_2) - erf(a / SQRT_2))
    };
    p.max(0.0)
}

/// Standard normal density `φ(z) = e^{−z²/2}/√(2π)`.
pub fn normal_pdf(z: f64) -> f64 {
    (-0.5 * z * z).exp() / (2.0 * PI).sqrt()
}

/// `ln(k!)`: logarithm of the floating-point product for k < 30, Stirling's series with six
/// correction terms above (absolute error < 1e-14; Abramowitz & Stegun 1964, eq. 6.1.40).
pub fn ln_factorial(k: u64) -> f64 {
    if k < 30 {
        let mut p = 1.0f64;
        for i in 2..=k {
            p *= i as f64;
        }
        return p.ln();
    }
    let n = k as f64;
    0.5 * (2.0 * PI * n).ln() + n * n.ln() - n + stirling_correction(n)
}

/// Stirling correction `δ(n) = ln(n!) − [½ln(2πn) + n ln n − n]` for n ≥ 10: series
/// 1/(12n) − 1/(360n³) + 1/(1260n⁵) − 1/(1680n⁷) + 1/(1188n⁹) − 691/(360360n¹¹), truncation
/// error < 1/(156 n¹³) ≤ 6.5e-16 at n = 10.
pub(crate) fn stirling_correction(n: f64) -> f64 {
    let inv = 1.0 / n;
    let inv2 = inv * inv;
    inv * (1.0 / 12.0
        - inv2
            * (1.0 / 360.0
                - inv2
                    * (1.0 / 1260.0
                        - inv2 * (1.0 / 1680.0 - inv2 * (1.0 / 1188.0 - inv2 * 691.0 / 360360.0)))))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference values from CPython 3 `math.erf` / `math.erfc` (correctly rounded libm).
    #[test]
    fn erf_matches_reference_values() {
        let cases = [
            (1e-10, 1.1283791670955126e-10),
            (0.1, 0.1124629160182849),
            (0.5, 0.5204998778130465),
            (1.0, 0.8427007929497149),
            (2.0, 0.9953222650189527),
            (2.4999, 0.9995928300996666),
            (3.0, 0.9999779095030014),
        ];
        for (x, want) in cases {
            let got = erf(x);
            assert!(
                ((got - want) / want).abs() < 1e-14,
                "erf({x}) = {got}, want {want}"
            );
            assert!((erf(-x) + want).abs() < 1e-14 * want);
        }
    }

    #[test]
    fn erfc_matches_reference_values() {
        let cases = [
            (0.5, 0.4795001221869535),
            (2.0, 0.004677734981047265),
            (2.5, 0.0004069520174449589),
            (3.0, 2.2090496998585438e-05),
            (5.0, 1.5374597944280351e-12),
            (10.0, 2.088487583762545e-45),
            (26.0, 5.663192408856143e-296),
        ];
        for (x, want) in cases {
            let got = erfc(x);
            assert!(
                ((got - want) / want).abs() < 1e-13,
                "erfc({x}) = {got}, want {want}"
            );
        }
        assert_eq!(erfc(30.0), 0.0);
        assert!((erfc(-1.0) - 1.842700792949715).abs() < 1e-15);
        assert!(erf(f64::NAN).is_nan() && erfc(f64::NAN).is_nan());
        assert_eq!(erf(f64::INFINITY), 1.0);
        assert_eq!(erf(f64::NEG_INFINITY), -1.0);
    }

    #[test]
    fn normal_interval_is_consistent() {
        // Total probability and symmetric intervals.
        assert!((normal_interval(-40.0, 40.0) - 1.0).abs() < 1e-15);
        assert!((normal_interval(-1.0, 1.0) - 0.6826894921370859).abs() < 1e-15);
        // Far tail without cancellation: P(Z > 6) = 9.865876450377012e-10.
        let tail = normal_interval(6.0, f64::INFINITY);
        assert!((tail / 9.865876450377012e-10 - 1.0).abs() < 1e-13);
        assert_eq!(normal_interval(1.0, 1.0), 0.0);
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-16);
    }

    #[test]
    fn stirling_correction_matches_at_switch() {
        // δ(10) from the exact ln(10!) = ln 3628800.
        let n = 10.0f64;
        let exact = 3628800f64.ln() - (0.5 * (2.0 * PI * n).ln() + n * n.ln() - n);
        // The reference itself carries ~4 ulp of 15 (7e-15) from the subtraction.
        assert!(
            (stirling_correction(n) - exact).abs() < 1e-14,
            "{}",
            stirling_correction(n) - exact
        );
    }

    #[test]
    fn ln_factorial_matches_products() {
        let mut exact = 0.0f64;
        for k in 1..=170u64 {
            exact += (k as f64).ln();
            let got = ln_factorial(k);
            assert!(
                (got - exact).abs() <= 1e-14 * exact.max(1.0),
                "ln({k}!) = {got}, want {exact}"
            );
        }
        assert_eq!(ln_factorial(0), 0.0);
    }
}

#[cfg(test)]
mod libm_tests {
    use super::*;

    /// libm's erf/erfc agree with the series / continued-fraction references.
    #[test]
    fn libm_matches_the_references() {
        let mut x = -6.0;
        while x <= 27.0 {
            let (a, b) = (erfc(x), erfc_reference(x));
            // The reference computes erfc = 1 − erf below 2.5: absolute error ~1e-16 there.
            assert!(
                (a - b).abs() <= 1e-13 * b.abs() + 2e-15,
                "erfc({x}): {a} vs {b}"
            );
            let (c, d) = (erf(x), erf_reference(x));
            assert!((c - d).abs() <= 1e-14, "erf({x}): {c} vs {d}");
            x += 0.0137;
        }
    }
}
