//! Unit tests of the emitted pulse and footprint: pulse kernels, footprint radii and oblique
//! footprints, radial-table sampling against its CDF, and the footprint moments against
//! Monte Carlo and quadrature.

use super::sampler::*;
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
        (e.area_m2 - PI * e.semi_axis_incidence_plane_m * e.semi_axis_perpendicular_m).abs() < 1e-9
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
    assert!(BeamProfile::default().check().is_ok());
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
