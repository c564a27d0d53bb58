//! Unit tests of the LiDAR pulse tracking: truncated-exponential moments of the first-order
//! binning, the column quadrature's footprint sampling and the lattice truncation forms.

use super::columns::{point_at_squared_distance, sample_in_rect};
use super::first_order_bins::{
    FIRST_ORDER_MOMENT_RATIO, ceil_small, inv_sq_mean, trunc_exp_moments, unit_fract,
};

/// The truncation forms give the libm values bit for bit where they are used:
/// `ceil_small(v).max(1)` = `v.ceil().max(1)` for every finite `v` below 2⁶³ (and far
/// below −2⁶³), `unit_fract(x)` = `x − (x as u64)` (its previous form) on `[0, 2⁶³)`.
#[test]
fn truncation_forms_match_libm() {
    let vs = [
        -1e300,
        -1e19,
        -3.5,
        -1.0,
        -0.5,
        -0.0,
        0.0,
        1e-300,
        0.25,
        1.0,
        1.0 + 1e-15,
        2.5,
        31.99,
        32.0,
        4.5e15,
        9e15,
        1e18,
    ];
    for v in vs {
        assert_eq!(
            ceil_small(v).max(1.0).to_bits(),
            v.ceil().max(1.0).to_bits(),
            "{v:e}"
        );
        if v >= 0.0 {
            // The u64 form it replaces, bit for bit; `fract` by value (−0 vs +0 at −0).
            assert_eq!(unit_fract(v).to_bits(), (v - (v as u64) as f64).to_bits());
            assert_eq!(unit_fract(v), v.fract(), "{v:e}");
        }
        if v >= 1.0 {
            assert_eq!(ceil_small(v).to_bits(), v.ceil().to_bits(), "{v:e}");
        }
    }
}

/// ∫_a^b f by composite 5-point Gauss–Legendre on `m` equal panels (exact for degree 9 per
/// panel; the integrands here are smooth and the panels short: error ≲ 1e-15 relative).
fn quad(f: impl Fn(f64) -> f64, a: f64, b: f64, m: usize) -> f64 {
    const X: [f64; 5] = [
        -0.906_179_845_938_664,
        -0.538_469_310_105_683_1,
        0.0,
        0.538_469_310_105_683_1,
        0.906_179_845_938_664,
    ];
    const W: [f64; 5] = [
        0.236_926_885_056_189_1,
        0.478_628_670_499_366_5,
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
    ];
    let h = (b - a) / m as f64;
    let mut s = 0.0;
    for p in 0..m {
        let c = a + (p as f64 + 0.5) * h;
        s += X
            .iter()
            .zip(W)
            .map(|(x, w)| w * f(c + 0.5 * h * x))
            .sum::<f64>();
    }
    0.5 * h * s
}

/// Panels for the density e^{−t x} on [0, cut(t)]: at most 1/8 of a decay length each.
fn panels(t: f64) -> usize {
    (8.0 * t.min(60.0)).ceil().max(64.0) as usize
}

/// Integration range of the density e^{−t x} on [0, 1]: up to 60 decay lengths (the rest,
/// below e^{−60} ≈ 1e-26 relative, is dropped).
fn cut(t: f64) -> f64 {
    (60.0 / t).min(1.0)
}

/// `αw` from 1e-8 to 1e5, both sides of the series switch (1e-3) and the m₃ maximum.
const TS: [f64; 17] = [
    1e-8, 1e-6, 1e-4, 0.999e-3, 1e-3, 1.001e-3, 1e-2, 0.1, 0.5, 1.0, 2.8, 5.0, 10.0, 50.0, 200.0,
    1000.0, 1e5,
];

/// Mean offset and variance of the truncated exponential of a stratum (both branches of
/// [`trunc_exp_moments`]) against quadrature: within 1e-12 w and 1e-8 w² (the closed
/// forms' cancellation at the switch αw = 1e-3: ~4e-13 w and ~1e-9 w²; 5e-9 w and 3e-6 w²
/// would still keep [`inv_sq_mean`] within 1e-11 of its value).
#[test]
fn truncated_exponential_moments_match_quadrature() {
    for &w in &[0.15, 1.0, 7.0] {
        for &t in &TS {
            let alpha = t / w;
            let em = (-t).exp_m1();
            let (off, var) = trunc_exp_moments(alpha, 1.0 / alpha, w, em);
            let (m, top) = (panels(t), w * cut(t));
            let z = quad(|u| (-alpha * u).exp(), 0.0, top, m);
            let mu = quad(|u| u * (-alpha * u).exp(), 0.0, top, m) / z;
            let v = quad(|u| (u - mu).powi(2) * (-alpha * u).exp(), 0.0, top, m) / z;
            assert!(
                (off - mu).abs() <= 1e-12 * w,
                "αw = {t}, w = {w} m: mean offset {off} vs {mu} m"
            );
            assert!(
                (var - v).abs() <= 1e-8 * w * w,
                "αw = {t}, w = {w} m: variance {var} vs {v} m²"
            );
        }
    }
}

/// The central-moment bounds the estimate's bias bound rests on ([`inv_sq_mean`]):
/// `σ² ≤ w²/12`, `|m₃| ≤ 0.01325 w³`, `m₄ ≤ w⁴/80` for every `αw > 0` (by quadrature on a
/// grid of 10 points per decade from 1e-4 to 1e4 and at the m₃ maximum, relative slack
/// 1e-9 for the quadrature).
#[test]
fn truncated_exponential_central_moment_bounds() {
    let mut ts: Vec<f64> = (-40..=40).map(|k| 10f64.powf(k as f64 / 10.0)).collect();
    ts.extend([2.7, 2.73, 2.745, 2.76, 2.8]);
    let mut m3_max: f64 = 0.0;
    for t in ts {
        let (m, top) = (panels(t), cut(t));
        let z = quad(|x| (-t * x).exp(), 0.0, top, m);
        let mu = quad(|x| x * (-t * x).exp(), 0.0, top, m) / z;
        let c = |n: i32| quad(|x| (x - mu).powi(n) * (-t * x).exp(), 0.0, top, m) / z;
        let (m2, m3, m4) = (c(2), c(3), c(4));
        assert!(m2 <= (1.0 + 1e-9) / 12.0, "αw = {t}: σ²/w² = {m2}");
        assert!(m3.abs() <= 0.01325, "αw = {t}: m3/w³ = {m3}");
        assert!(m4 <= (1.0 + 1e-9) / 80.0, "αw = {t}: m4/w⁴ = {m4}");
        m3_max = m3_max.max(m3.abs());
    }
    // The bound is tight (the maximum 0.0132455 at αw = 2.745).
    assert!(m3_max > 0.013245, "largest m3/w³ {m3_max}");
}

/// A stratum's first-order energy by the moment estimate, `M · inv_sq_mean(l0 + μ, σ²)`
/// with the exact mass `M = e^{−αa}(1 − e^{−αw})/α`, against the integral
/// `∫_a^b e^{−αu}/(l0 + u)² du` by quadrature: relative error ≤ 1e-10 (the stated bound
/// 5.4e-11 plus rounding) for w/(l0 + a) up to the threshold [`FIRST_ORDER_MOMENT_RATIO`],
/// αw from 1e-8 to 1e5 and ranges from 1 m to 10 km. Without the variance term the error
/// at the threshold would be ~ρ²/4 = 2.5e-7.
#[test]
fn moment_estimate_matches_first_order_integral() {
    let mut worst: f64 = 0.0;
    for &l0 in &[1.0, 30.0, 985.0, 1e4] {
        for &ratio in &[FIRST_ORDER_MOMENT_RATIO * 0.999_999, 3e-4, 1e-5] {
            for &a_rel in &[0.0, 0.37] {
                for &t in &TS {
                    let a = a_rel * l0 * 1e-3; // a few strata into the segment
                    let w = ratio * (l0 + a);
                    let alpha = t / w;
                    let em = (-t).exp_m1();
                    let (off, var) = trunc_exp_moments(alpha, 1.0 / alpha, w, em);
                    // e^{−αa}, the mass's start factor (scaled out: the ratio is what matters).
                    let mass = -em / alpha;
                    let est = mass * inv_sq_mean(l0 + a + off, var);
                    let exact = quad(
                        |u| (-alpha * u).exp() / (l0 + a + u).powi(2),
                        0.0,
                        w * cut(t),
                        panels(t),
                    );
                    let rel = (est / exact - 1.0).abs();
                    worst = worst.max(rel);
                    assert!(
                        rel <= 1e-10,
                        "l0 = {l0} m, a = {a} m, w/R = {ratio}, αw = {t}: {est} vs {exact} ({rel:e})"
                    );
                }
            }
        }
    }
    println!("worst relative error {worst:e}");
}

/// The far-photon roulette's survival probability from the receiver's field-of-view cone:
/// 1 inside the cone and up to ρ₀ beyond its edge, (ρ₀/e)² beyond (e the distance outside
/// the cone, m), never below the floor; a nadir airborne receiver (cone radius grows with
/// the range below it) and a horizontal terrestrial one (behind the scanner, the lateral
/// distance alone).
/// `point_at_squared_distance` gives a point of the rectangle at the asked squared
/// distance (relative 1e-12) whenever it lies between the rectangle's least and largest
/// squared distances, and the nearest point otherwise.
#[test]
fn point_at_squared_distance_stays_in_the_rectangle() {
    let rects = [
        [0.2, 0.9, -0.3, 0.4],
        [-1.0, 0.0, -0.5, 0.5],
        [-1.0, -0.2, -1.5, -0.505],
        [0.0, 1.0, 0.0, 1.0],
        [-0.3, 0.3, -0.3, 0.3],
    ];
    for r in rects {
        let near = (0.0f64.clamp(r[0], r[1]), 0.0f64.clamp(r[2], r[3]));
        let lo = near.0 * near.0 + near.1 * near.1;
        let hi = r[0].abs().max(r[1].abs()).powi(2) + r[2].abs().max(r[3].abs()).powi(2);
        for k in 0..=20 {
            let r2 = lo + (hi - lo) * k as f64 / 20.0;
            let (x, y) = point_at_squared_distance(r, r2);
            assert!(
                x >= r[0] && x <= r[1] && y >= r[2] && y <= r[3],
                "{r:?} {r2}"
            );
            assert!((x * x + y * y - r2).abs() <= 1e-12 * hi, "{r:?}: {r2}");
        }
        assert_eq!(point_at_squared_distance(r, 0.5 * lo), near);
    }
}

/// `sample_in_rect` draws from the footprint's density over a rectangle: every point inside
/// the rectangle and the footprint's disk, and the mean ρ² over 40,000 draws equal to the
/// rectangle's m2/m0 ([`crate::lidar::pulse::FootprintMoments`]) within 5 standard errors,
/// on a strip, a rectangle across the axis and one cut by the truncation circle.
#[test]
fn strip_samples_follow_the_footprint_density() {
    use rand_xoshiro::rand_core::SeedableRng;
    let profile =
        crate::lidar::pulse::FootprintProfile::from_edge_intensity(0.3, 0.368).expect("profile");
    let fp = crate::lidar::pulse::FootprintSampler::new(&profile, 0.9).expect("sampler");
    let mom = fp.moments();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
    for rect in [
        [0.3, 0.33, -0.5, 0.5],
        [-0.2, 0.1, -0.05, 0.4],
        [0.5, 2.0, 0.3, 2.0],
    ] {
        let (m0, m2) = mom.rect(rect[0], rect[1], rect[2], rect[3]);
        let n = 40_000;
        let v: Vec<f64> = (0..n)
            .map(|_| {
                let (x, y) = sample_in_rect(&fp, 0.9, rect, &mut rng).expect("draw");
                assert!(x >= rect[0] && x <= rect[1] && y >= rect[2] && y <= rect[3]);
                assert!(x * x + y * y <= 0.81);
                x * x + y * y
            })
            .collect();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let se = (var / n as f64).sqrt();
        assert!(
            (mean - m2 / m0).abs() < 5.0 * se,
            "{rect:?}: mean ρ² {mean} vs {} (SE {se})",
            m2 / m0
        );
    }
}
