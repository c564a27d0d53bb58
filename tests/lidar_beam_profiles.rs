//! Transverse beam profiles of the LiDAR emitter (`BeamProfile`, `FootprintSampler::from_beam`;
//! DART 5 paper §4 "any angular distribution", physics.md §9.1).
//!
//! Every expected value is computed here independently of the implementation: the Gaussian and
//! top-hat radial CDFs in closed form, the tabulated CDF by Simpson's rule on each segment (exact,
//! since a linear intensity times ρ is quadratic).

use lumenscape::lidar::LidarError;
use lumenscape::lidar::pulse::{BeamProfile, FootprintProfile, FootprintSampler};
use std::f64::consts::PI;

/// SplitMix64 (Steele, Lea & Flood 2014): a self-contained seeded generator for the tests.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1) from the 53 high bits.
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Upper tail of χ² with an even number of degrees of freedom `k`:
/// `Q = e^{−x/2} Σ_{j<k/2} (x/2)^j/j!` (Abramowitz & Stegun 26.4.21).
fn chi2_sf_even(x: f64, k: u32) -> f64 {
    assert!(k.is_multiple_of(2));
    let h = 0.5 * x;
    let mut term = 1.0;
    let mut sum = 1.0;
    for j in 1..k / 2 {
        term *= h / j as f64;
        sum += term;
    }
    (-h).exp() * sum
}

/// Independent piecewise-linear interpolation of a table (0 outside).
fn table_intensity(points: &[(f64, f64)], x: f64) -> f64 {
    let n = points.len();
    if x < points[0].0 || x > points[n - 1].0 {
        return 0.0;
    }
    for k in 0..n - 1 {
        let (a, ia) = points[k];
        let (b, ib) = points[k + 1];
        if x <= b {
            return ia + (ib - ia) * (x - a) / (b - a);
        }
    }
    points[n - 1].1
}

/// `∫_0^x I(x') x' dx'` of a table by Simpson's rule per segment (exact for the quadratic
/// integrand).
fn table_mass(points: &[(f64, f64)], x: f64) -> f64 {
    let f = |t: f64| table_intensity(points, t) * t;
    let mut m = 0.0;
    for k in 0..points.len() - 1 {
        let a = points[k].0;
        let b = points[k + 1].0.min(x);
        if b <= a {
            break;
        }
        // Interior evaluations only, so that a step at a node does not leak in.
        let ia = points[k].1;
        let ib = ia + (points[k + 1].1 - ia) * (b - a) / (points[k + 1].0 - a);
        let fm = f(0.5 * (a + b));
        m += (b - a) / 6.0 * (ia * a + 4.0 * fm + ib * b);
    }
    m
}

/// A test case: a profile, its nominal radius and truncation, and the independent CDF of the
/// untruncated beam energy within radius r (m).
struct Case {
    name: &'static str,
    beam: BeamProfile,
    radius_m: f64,
    truncation_m: f64,
    cdf: Box<dyn Fn(f64) -> f64>,
    /// Inner and outer radius of the emitted distribution (m).
    support_m: (f64, f64),
}

fn gaussian_case(name: &'static str, edge: f64, r: f64, trunc: f64) -> Case {
    let sigma = r / (-2.0 * edge.ln()).sqrt();
    Case {
        name,
        beam: BeamProfile::Gaussian {
            edge_intensity: edge,
        },
        radius_m: r,
        truncation_m: trunc,
        cdf: Box::new(move |x: f64| {
            if x <= 0.0 {
                0.0
            } else {
                -(-0.5 * (x / sigma).powi(2)).exp_m1()
            }
        }),
        support_m: (0.0, trunc),
    }
}

fn uniform_case(name: &'static str, r: f64, trunc: f64) -> Case {
    Case {
        name,
        beam: BeamProfile::Uniform,
        radius_m: r,
        truncation_m: trunc,
        cdf: Box::new(move |x: f64| (x.max(0.0) / r).min(1.0).powi(2)),
        support_m: (0.0, trunc.min(r)),
    }
}

fn table_case(name: &'static str, points: Vec<(f64, f64)>, r: f64, trunc: f64) -> Case {
    let total = table_mass(&points, f64::INFINITY);
    let p2 = points.clone();
    // Inner edge: first abscissa, or the end of a leading zero-intensity run.
    let mut inner = points[0].0;
    for k in 0..points.len() - 1 {
        if points[k].1 == 0.0 && points[k + 1].1 == 0.0 {
            inner = points[k + 1].0;
        } else {
            break;
        }
    }
    let mut outer = points[points.len() - 1].0;
    for k in (1..points.len()).rev() {
        if points[k].1 == 0.0 && points[k - 1].1 == 0.0 {
            outer = points[k - 1].0;
        } else {
            break;
        }
    }
    Case {
        name,
        beam: BeamProfile::Tabulated { points },
        radius_m: r,
        truncation_m: trunc,
        cdf: Box::new(move |x: f64| (table_mass(&p2, x / r) / total).min(1.0)),
        support_m: (inner * r, (outer * r).min(trunc)),
    }
}

/// Nodes of a piecewise-linear approximation of the DART Gaussian (edge 0.368) on [0, 3] with
/// step `h` in ρ/R.
fn gaussian_table(edge: f64, h: f64) -> Vec<(f64, f64)> {
    let s2 = 1.0 / (-2.0 * edge.ln());
    let n = (3.0 / h).round() as usize;
    (0..=n)
        .map(|i| {
            let x = i as f64 * h;
            (x, (-0.5 * x * x / s2).exp())
        })
        .collect()
}

fn cases() -> Vec<Case> {
    vec![
        gaussian_case("gaussian DART, cut 3R", 0.368, 12.5, 37.5),
        gaussian_case("gaussian edge 0.1, cut R", 0.1, 0.3, 0.3),
        gaussian_case("gaussian edge 0.9, no cut", 0.9, 2.0, f64::INFINITY),
        uniform_case("uniform, no cut", 2.0, f64::INFINITY),
        uniform_case("uniform, cut 0.6R", 2.0, 1.2),
        table_case(
            "table = uniform",
            vec![(0.0, 3.0), (0.4, 3.0), (1.0, 3.0)],
            2.0,
            f64::INFINITY,
        ),
        table_case(
            "table ≈ gaussian (h = 0.01)",
            gaussian_table(0.368, 0.01),
            12.5,
            37.5,
        ),
        table_case(
            "table annulus",
            vec![(0.3, 0.0), (0.6, 1.0), (1.2, 0.2), (1.5, 0.0)],
            1.0,
            f64::INFINITY,
        ),
        table_case(
            "table edge-bright",
            vec![(0.0, 0.0), (1.0, 1.0)],
            0.5,
            f64::INFINITY,
        ),
        table_case(
            "table step at 0.2, cut mid-segment",
            vec![(0.2, 1.0), (0.5, 0.2), (0.9, 0.7), (2.0, 0.0)],
            1.0,
            1.3,
        ),
        table_case(
            "table dark ring",
            vec![(0.0, 1.0), (0.3, 0.0), (0.6, 0.0), (1.0, 1.0)],
            1.0,
            f64::INFINITY,
        ),
        table_case(
            "table trailing zeros, large intensities",
            vec![(0.0, 2e300), (0.5, 1e300), (0.8, 0.0), (1.4, 0.0)],
            3.0,
            f64::INFINITY,
        ),
    ]
}

fn sampler(c: &Case) -> FootprintSampler {
    FootprintSampler::from_beam(&c.beam, c.radius_m, c.truncation_m)
        .unwrap_or_else(|e| panic!("{}: {e}", c.name))
}

/// The radial density integrates to 1 over the plane (to 1e-12) and `energy_fraction_within`
/// equals the independent CDF (to 1e-13); the lost fraction is the CDF's complement at the
/// truncation radius.
#[test]
fn profiles_are_normalised() {
    let mut worst_norm: f64 = 0.0;
    let mut worst_cdf: f64 = 0.0;
    for c in cases() {
        let s = sampler(&c);
        // ∫ density 2πρ dρ by composite Simpson on pieces where the integrand is smooth.
        let breaks: Vec<f64> = match &c.beam {
            BeamProfile::Gaussian { edge_intensity } => {
                let sigma = c.radius_m / (-2.0 * edge_intensity.ln()).sqrt();
                vec![0.0, 14.0 * sigma]
            }
            BeamProfile::Uniform => vec![0.0, c.radius_m],
            BeamProfile::Tabulated { points } => points.iter().map(|p| p.0 * c.radius_m).collect(),
        };
        let n_sub = if matches!(c.beam, BeamProfile::Gaussian { .. }) {
            40_000
        } else {
            2
        };
        let mut total = 0.0;
        for w in breaks.windows(2) {
            let (a, b) = (w[0], w[1]);
            let h = (b - a) / n_sub as f64;
            // Stay strictly inside the piece at its ends (steps at nodes).
            let f = |r: f64| {
                let r = r.clamp(a + 1e-15 * b, b - 1e-15 * b);
                s.energy_density_per_m2(r) * 2.0 * PI * r
            };
            let mut acc = f(a) + f(b);
            for i in 1..n_sub {
                acc += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            total += acc * h / 3.0;
        }
        let outer = breaks.last().copied().unwrap();
        let err = (total - 1.0).abs();
        worst_norm = worst_norm.max(err);
        assert!(err < 1e-12, "{}: ∫ density = {total}", c.name);
        if !matches!(c.beam, BeamProfile::Gaussian { .. }) {
            assert_eq!(s.energy_density_per_m2(outer * 1.5), 0.0, "{}", c.name);
        }

        for i in 0..=400 {
            let r = c.support_m.0.max(0.0) * 0.5 + i as f64 / 400.0 * 1.6 * outer;
            let d = (s.energy_fraction_within(r) - (c.cdf)(r)).abs();
            worst_cdf = worst_cdf.max(d);
            assert!(d < 1e-13, "{}: F({r}) off by {d:e}", c.name);
        }
        assert_eq!(s.energy_fraction_within(0.0), 0.0);
        assert_eq!(s.energy_fraction_within(-1.0), 0.0);
        assert!((s.energy_fraction_within(f64::INFINITY) - 1.0).abs() < 1e-15);
        let lost = 1.0 - (c.cdf)(c.truncation_m);
        assert!(
            (s.lost_energy_fraction() - lost).abs() < 1e-13,
            "{}: lost {} vs {lost}",
            c.name,
            s.lost_energy_fraction()
        );
    }
    println!("worst |∫ density − 1| = {worst_norm:.2e}; worst |F − F_indep| = {worst_cdf:.2e}");
}

/// χ² goodness of fit of sampled radii against the independent truncated radial CDF: 51
/// equiprobable bins (50 d.o.f.), 102 000 seeded draws per profile. Bonferroni: each test must
/// have p > 1e-4/(number of profiles), so the family-wise false-alarm rate is ≤ 1e-4. A wrong
/// CDF (a table tapering to 0.7 at the edge tested as a top hat) must be rejected (p < 1e-10): the test has
/// power.
#[test]
fn sampled_radii_follow_the_radial_cdf() {
    const K: usize = 51;
    const N: usize = 102_000;
    let cs = cases();
    let threshold = 1e-4 / cs.len() as f64;
    let chi2 = |s: &FootprintSampler, cdf: &dyn Fn(f64) -> f64, kept: f64, seed: u64| {
        let mut rng = SplitMix64(seed);
        let mut counts = [0usize; K];
        for _ in 0..N {
            let [x, y] = s.sample_footprint_point(rng.uniform(), rng.uniform());
            let r = (x * x + y * y).sqrt();
            let p = cdf(r) / kept;
            counts[((p * K as f64) as usize).min(K - 1)] += 1;
        }
        let e = N as f64 / K as f64;
        let x2: f64 = counts.iter().map(|&o| (o as f64 - e).powi(2) / e).sum();
        (x2, chi2_sf_even(x2, (K - 1) as u32))
    };
    let mut min_p: f64 = 1.0;
    for (i, c) in cs.iter().enumerate() {
        let s = sampler(c);
        let kept = (c.cdf)(c.truncation_m);
        let (x2, p) = chi2(&s, &*c.cdf, kept, 0xBEA4_0000 + i as u64);
        println!("{:<42} χ² = {x2:7.2} (50 dof), p = {p:.3}", c.name);
        min_p = min_p.min(p);
        assert!(p > threshold, "{}: χ² = {x2}, p = {p:e}", c.name);
    }
    println!("min p = {min_p:.3} (threshold {threshold:.1e})");
    // Power: a table tapering to 0.7 at the edge is not a top hat.
    let tapered = FootprintSampler::from_beam(
        &BeamProfile::Tabulated {
            points: vec![(0.0, 1.0), (1.0, 0.7)],
        },
        1.0,
        f64::INFINITY,
    )
    .unwrap();
    let top_hat = |r: f64| r.clamp(0.0, 1.0).powi(2);
    let (x2, p) = chi2(&tapered, &top_hat, 1.0, 7);
    println!("power check (taper 0.7 vs top hat): χ² = {x2:.1}, p = {p:.1e}");
    assert!(p < 1e-10, "χ² = {x2}");
}

/// Inverse-CDF exactness: `F(sample_radius(u))/kept = u` to 1e-12 on a grid of u (including
/// 0 and 1 − 2⁻⁵³), with the independent CDF; radii are monotone in u and stay in the support.
#[test]
fn radius_is_the_exact_inverse_cdf() {
    let mut worst: f64 = 0.0;
    for c in cases() {
        let s = sampler(&c);
        let kept = (c.cdf)(c.truncation_m);
        let mut us: Vec<f64> = (0..=20_000).map(|i| i as f64 / 20_000.0).collect();
        us.extend([
            1e-300,
            1e-16,
            1e-9,
            0.5,
            1.0 - 1e-12,
            1.0 - f64::EPSILON / 2.0,
        ]);
        us.sort_by(f64::total_cmp);
        let mut prev = -1.0;
        for &u in &us {
            let r = s.sample_radius_m(u);
            assert!(r.is_finite(), "{}: u = {u}", c.name);
            assert!(r >= prev, "{}: not monotone at u = {u}", c.name);
            prev = r;
            assert!(
                r >= c.support_m.0 * (1.0 - 1e-14) && r <= c.support_m.1 * (1.0 + 1e-14),
                "{}: r = {r} outside {:?}",
                c.name,
                c.support_m
            );
            let u_clamped = u.min(1.0 - f64::EPSILON / 2.0);
            let d = ((c.cdf)(r) / kept - u_clamped).abs();
            worst = worst.max(d);
            assert!(d < 1e-12, "{}: u = {u}, F(r)/kept off by {d:e}", c.name);
        }
    }
    println!("worst |F(r(u))/kept − u| = {worst:.2e}");
}

/// The Gaussian through `from_beam` draws exactly the same points as the original constructor,
/// and both equal the pre-existing formula `ρ = σ√(−2 ln(1 − u₁q))`, `φ = 2πu₂`, bit for bit.
#[test]
fn gaussian_from_beam_is_bit_identical() {
    let mut rng = SplitMix64(42);
    let mut n = 0usize;
    for edge in [0.368, 0.1, 0.9, 1e-6] {
        for r in [0.3, 12.5, 35.0] {
            for trunc in [r, 3.0 * r, f64::INFINITY] {
                let prof = FootprintProfile::from_edge_intensity(r, edge).unwrap();
                let old = FootprintSampler::new(&prof, trunc).unwrap();
                let new = FootprintSampler::from_beam(
                    &BeamProfile::Gaussian {
                        edge_intensity: edge,
                    },
                    r,
                    trunc,
                )
                .unwrap();
                assert_eq!(old, new);
                assert_eq!(
                    old.lost_energy_fraction().to_bits(),
                    new.lost_energy_fraction().to_bits()
                );
                let q = prof.energy_fraction_within(trunc);
                let mut us: Vec<(f64, f64)> = (0..20_000)
                    .map(|_| (rng.uniform(), rng.uniform()))
                    .collect();
                us.extend([(0.0, 0.0), (1.0 - f64::EPSILON / 2.0, 0.999), (0.5, 0.25)]);
                for (u1, u2) in us {
                    let a = old.sample_footprint_point(u1, u2);
                    let b = new.sample_footprint_point(u1, u2);
                    // The formula of the original implementation.
                    let rho = prof.sigma_m() * (-2.0 * (-u1 * q).ln_1p()).sqrt();
                    let phi = 2.0 * PI * u2;
                    let c = [rho * phi.cos(), rho * phi.sin()];
                    for k in 0..2 {
                        assert_eq!(a[k].to_bits(), b[k].to_bits());
                        assert_eq!(a[k].to_bits(), c[k].to_bits());
                    }
                    n += 1;
                }
            }
        }
    }
    println!("{n} Gaussian draws bit-identical");
}

/// Top hat: E[ρ²] = R²/2 (R_t²/2 when truncated inside R). Stratified u gives it to rounding
/// (ρ² = R²u exactly); random draws within 5 standard errors (ρ²/R² ~ U(0, 1), sd 1/√12).
#[test]
fn uniform_mean_square_radius() {
    for (r, trunc) in [(2.0, f64::INFINITY), (2.0, 2.0), (0.7, 0.35)] {
        let s = FootprintSampler::from_beam(&BeamProfile::Uniform, r, trunc).unwrap();
        let re = trunc.min(r);
        let expect = 0.5 * re * re;
        assert_eq!(s.lost_energy_fraction(), 1.0 - (re / r).powi(2));
        let n = 100_000;
        let strat: f64 = (0..n)
            .map(|i| s.sample_radius_m((i as f64 + 0.5) / n as f64).powi(2))
            .sum::<f64>()
            / n as f64;
        assert!((strat / expect - 1.0).abs() < 1e-12, "{strat} vs {expect}");
        let mut rng = SplitMix64(99);
        let m: f64 = (0..n)
            .map(|_| {
                let [x, y] = s.sample_footprint_point(rng.uniform(), rng.uniform());
                x * x + y * y
            })
            .sum::<f64>()
            / n as f64;
        let se = re * re / 12f64.sqrt() / (n as f64).sqrt();
        let z = (m - expect) / se;
        println!(
            "uniform R = {r}, R_t = {trunc}: stratified rel. err {:.1e}, random z = {z:.2}",
            strat / expect - 1.0
        );
        assert!(z.abs() < 5.0, "z = {z}");
    }
}

/// A constant table reproduces the top hat: same energy fractions (1e-15) and the same radius
/// for every u (1e-14 relative), whatever its nodes and scale.
#[test]
fn constant_table_reproduces_uniform() {
    let r = 1.7;
    let u = FootprintSampler::from_beam(&BeamProfile::Uniform, r, f64::INFINITY).unwrap();
    for points in [
        vec![(0.0, 1.0), (1.0, 1.0)],
        vec![
            (0.0, 5e-3),
            (0.25, 5e-3),
            (0.5, 5e-3),
            (0.9, 5e-3),
            (1.0, 5e-3),
        ],
    ] {
        let t = FootprintSampler::from_beam(
            &BeamProfile::Tabulated {
                points: points.clone(),
            },
            r,
            f64::INFINITY,
        )
        .unwrap();
        assert_eq!(t.lost_energy_fraction(), 0.0);
        let mut worst_f: f64 = 0.0;
        let mut worst_r: f64 = 0.0;
        for i in 0..=1000 {
            let rr = i as f64 / 1000.0 * 1.2 * r;
            worst_f =
                worst_f.max((t.energy_fraction_within(rr) - u.energy_fraction_within(rr)).abs());
            assert_eq!(t.relative_intensity(rr), u.relative_intensity(rr));
            let v = i as f64 / 1000.0;
            let (a, b) = (t.sample_radius_m(v), u.sample_radius_m(v));
            if b > 0.0 {
                worst_r = worst_r.max((a / b - 1.0).abs());
            } else {
                assert_eq!(a, 0.0);
            }
        }
        println!(
            "{} nodes: worst ΔF = {worst_f:.1e}, worst radius rel. diff = {worst_r:.1e}",
            points.len()
        );
        assert!(worst_f < 1e-15 && worst_r < 1e-14);
    }
}

/// A 301-node table of the DART Gaussian on [0, 3R] matches the Gaussian truncated at 3R.
/// Bound: linear interpolation errs by at most δ = h² max|I''|/8 = h²/(8s²) (s = σ/R), so
/// |ΔM(x)| ≤ δx²/2 and |ΔF(x)| ≤ δ(x²/2 + 9/2)/(M_tot − 9δ/2), M_tot = s²(1 − e^{−9/(2s²)}).
#[test]
fn gaussian_table_approximates_gaussian() {
    let (edge, r) = (0.368, 12.5);
    for h in [0.05, 0.01] {
        let tab = FootprintSampler::from_beam(
            &BeamProfile::Tabulated {
                points: gaussian_table(edge, h),
            },
            r,
            f64::INFINITY,
        )
        .unwrap();
        let g = FootprintSampler::from_beam(
            &BeamProfile::Gaussian {
                edge_intensity: edge,
            },
            r,
            3.0 * r,
        )
        .unwrap();
        let s2 = 1.0 / (-2.0 * f64::ln(edge));
        let delta = h * h / (8.0 * s2);
        let m_tot = s2 * (1.0 - (-4.5 / s2).exp());
        let kept = 1.0 - g.lost_energy_fraction();
        let mut worst: f64 = 0.0;
        for i in 1..=300 {
            let x = i as f64 / 100.0;
            let f_g = g.energy_fraction_within(x * r) / kept;
            let d = (tab.energy_fraction_within(x * r) - f_g).abs();
            let bound = delta * (0.5 * x * x + 4.5) / (m_tot - 4.5 * delta);
            assert!(d <= bound, "h = {h}, x = {x}: ΔF = {d:e} > {bound:e}");
            worst = worst.max(d);
        }
        // Mean ρ² of the two samplers by stratified inversion.
        let n = 50_000;
        let m2 = |s: &FootprintSampler| {
            (0..n)
                .map(|i| s.sample_radius_m((i as f64 + 0.5) / n as f64).powi(2))
                .sum::<f64>()
                / n as f64
        };
        let rel = m2(&tab) / m2(&g) - 1.0;
        println!(
            "gaussian table h = {h}: worst ΔF = {worst:.2e} (bound at x = 3: {:.2e}); E[ρ²] rel. diff {rel:.1e}",
            delta * 9.0 / (m_tot - 4.5 * delta)
        );
        assert!(rel.abs() < 4.0 * delta / m_tot);
    }
}

fn table_err(points: Vec<(f64, f64)>) -> String {
    let beam = BeamProfile::Tabulated { points };
    let e1 = LidarError::InvalidInput(beam.check().unwrap_err());
    let e2 = FootprintSampler::from_beam(&beam, 1.0, f64::INFINITY).unwrap_err();
    assert_eq!(e1, e2);
    e1.to_string()
}

/// Bad tables and parameters give errors naming the offending point or parameter.
#[test]
fn bad_inputs_are_rejected() {
    type BadTable = (Vec<(f64, f64)>, &'static [&'static str]);
    let cases: Vec<BadTable> = vec![
        (vec![], &["at least 2 points", "got 0"]),
        (vec![(0.0, 1.0)], &["at least 2 points", "got 1"]),
        (
            vec![(-0.1, 1.0), (1.0, 1.0)],
            &["point 0 (-0.1, 1)", ">= 0"],
        ),
        (
            vec![(0.0, 1.0), (0.5, 1.0), (0.5, 1.0)],
            &["point 2 (0.5, 1)", "strictly increasing"],
        ),
        (
            vec![(0.0, 1.0), (0.7, 1.0), (0.4, 1.0)],
            &["point 2 (0.4, 1)", "strictly increasing"],
        ),
        (
            vec![(0.0, 1.0), (f64::NAN, 1.0)],
            &["point 1 (NaN, 1)", "finite"],
        ),
        (
            vec![(0.0, 1.0), (f64::INFINITY, 1.0)],
            &["point 1 (inf, 1)", "finite"],
        ),
        (
            vec![(0.0, 1.0), (1.0, -0.5)],
            &["point 1 (1, -0.5)", "intensity must be finite and >= 0"],
        ),
        (
            vec![(0.0, f64::NAN), (1.0, 1.0)],
            &["point 0 (0, NaN)", "intensity"],
        ),
        (
            vec![(0.0, 1.0), (1.0, f64::INFINITY)],
            &["point 1 (1, inf)", "intensity"],
        ),
        (
            vec![(0.0, 0.0), (0.5, 0.0), (1.0, 0.0)],
            &["all intensities are zero"],
        ),
        (
            vec![(0.0, 1.0), (1e200, 1.0)],
            &["total energy", "not finite"],
        ),
    ];
    for (points, needles) in cases {
        let msg = table_err(points.clone());
        for n in needles {
            assert!(msg.contains(n), "{points:?}: `{msg}` lacks `{n}`");
        }
    }
    for edge in [0.0, 1.0, f64::NAN, -0.2] {
        let b = BeamProfile::Gaussian {
            edge_intensity: edge,
        };
        assert!(b.check().is_err());
        assert!(FootprintSampler::from_beam(&b, 1.0, 3.0).is_err());
    }
    for beam in [BeamProfile::default(), BeamProfile::Uniform] {
        for r in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = FootprintSampler::from_beam(&beam, r, 3.0).unwrap_err();
            assert!(e.to_string().contains("radius_m"), "{e}");
        }
        for t in [0.0, -1.0, f64::NAN] {
            let e = FootprintSampler::from_beam(&beam, 1.0, t).unwrap_err();
            assert!(e.to_string().contains("truncation_radius_m"), "{e}");
        }
    }
    // Truncation inside the dark centre of an annular beam: nothing would be emitted.
    let ring = BeamProfile::Tabulated {
        points: vec![(0.5, 1.0), (1.0, 1.0)],
    };
    let e = FootprintSampler::from_beam(&ring, 2.0, 0.9).unwrap_err();
    assert!(e.to_string().contains("truncation_radius_m") && e.to_string().contains("dark centre"));
    assert!(FootprintSampler::from_beam(&ring, 2.0, 1.01).is_ok());
}

/// Hard uniforms (0, tiny, 1 − 2⁻⁵³, 1, NaN, ±∞, out of range) never give NaN; u₁ = 0 lands on
/// the inner edge and u₁ → 1 on the outer edge of the emitted distribution.
#[test]
fn no_nan_at_extreme_uniforms() {
    let hard = [
        0.0,
        5e-324,
        1e-300,
        1e-17,
        1.0 - f64::EPSILON / 2.0,
        1.0,
        f64::NAN,
        -1.0,
        2.0,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for c in cases() {
        let s = sampler(&c);
        for &u1 in &hard {
            for &u2 in &hard {
                let [x, y] = s.sample_footprint_point(u1, u2);
                assert!(x.is_finite() && y.is_finite(), "{}: ({u1}, {u2})", c.name);
            }
        }
        let r0 = s.sample_radius_m(0.0);
        assert!(
            (r0 - c.support_m.0).abs() <= 1e-15 * c.radius_m,
            "{}: r(0) = {r0}",
            c.name
        );
        let r1 = s.sample_radius_m(1.0);
        if c.support_m.1.is_finite() {
            assert!(
                (r1 - c.support_m.1).abs() <= 1e-6 * c.radius_m,
                "{}: r(1) = {r1} vs {}",
                c.name,
                c.support_m.1
            );
        } else {
            assert!(
                r1.is_finite() && r1 > 3.0 * c.radius_m,
                "{}: r(1) = {r1}",
                c.name
            );
        }
        for rho in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e300] {
            assert!(!s.energy_density_per_m2(rho).is_nan() || rho.is_nan());
            assert!(!s.energy_fraction_within(rho).is_nan());
        }
    }
}

/// The profile is a scene-file field: RON forms, the Gaussian default edge intensity, unknown
/// fields rejected, JSON round trip.
#[test]
fn beam_profile_serde() {
    let g: BeamProfile = ron::from_str("Gaussian(edge_intensity: 0.2)").unwrap();
    assert_eq!(
        g,
        BeamProfile::Gaussian {
            edge_intensity: 0.2
        }
    );
    let d: BeamProfile = ron::from_str("Gaussian()").unwrap();
    assert_eq!(d, BeamProfile::default());
    let u: BeamProfile = ron::from_str("Uniform").unwrap();
    assert_eq!(u, BeamProfile::Uniform);
    let t: BeamProfile =
        ron::from_str("Tabulated(points: [(0.0, 1.0), (0.8, 1.0), (1.0, 0.0)])").unwrap();
    assert_eq!(
        t,
        BeamProfile::Tabulated {
            points: vec![(0.0, 1.0), (0.8, 1.0), (1.0, 0.0)]
        }
    );
    assert!(ron::from_str::<BeamProfile>("Gaussian(edge: 0.2)").is_err());
    assert!(ron::from_str::<BeamProfile>("TopHat").is_err());
    for b in [g, u, t] {
        let back: BeamProfile = ron::from_str(&ron::to_string(&b).unwrap()).unwrap();
        assert_eq!(back, b);
        let back: BeamProfile = serde_json::from_str(&serde_json::to_string(&b).unwrap()).unwrap();
        assert_eq!(back, b);
    }
    assert_eq!(BeamProfile::Uniform.name(), "uniform");
}
