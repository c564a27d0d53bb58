//! Statistical tests of the Photon-stage samplers (`lumenscape::photon::sampling`).
//!
//! Every goodness-of-fit test is a Pearson χ² test at a false-alarm rate of 1e-3: the statistic
//! over bins (consecutive bins pooled until the expected count is ≥ 5) is compared with the
//! 0.999 quantile of χ²(dof) from the Wilson–Hilferty approximation (conservative by < 2 % for
//! dof ≥ 5). Bins of zero expected probability must stay empty. All generators are
//! `Xoshiro256PlusPlus` with fixed seeds, so the tests are deterministic.
//!
//! Expected bin probabilities never come from the code under test: they are analytic (phase
//! functions by Gauss–Legendre quadrature of `FluidPhase::eval`, LAD integrals by tanh–sinh of
//! `f(θ_L)χ_s`, Γ by quadrature of `VolscattKernel::gamma_components`, BRF bin integrals by
//! quadrature of `Brdf::brf_local`), except for the Box table, which is tested against its own
//! quantised probabilities (and its bias against the true ones is bounded separately).
//!
//! The speed/memory study of alias vs Box is a bench row: `cargo bench --bench photon --
//! --samplers`.

use glam::DVec3;
use lumenscape::photon::sampling::*;
use lumenscape::physics::brdf::{Brdf, LocalGeometry};
use lumenscape::physics::lad::{
    Lad, LeafSpecular, VolscattKernel, chi_s, gamma_specular, gamma_spherical, gauss_legendre,
    specular_albedo,
};
use lumenscape::physics::phase::{AIR_DEPOLARIZATION, FluidPhase};
use rand_xoshiro::Xoshiro256PlusPlus;
use rand_xoshiro::rand_core::SeedableRng;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

#[path = "fixtures/sampler_rows.rs"]
mod sampler_rows;
use sampler_rows::*;

const N_SAMPLES: usize = 200_000;

fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

// ---------------------------------------------------------------------------------------------
// Statistics helpers
// ---------------------------------------------------------------------------------------------

/// Φ⁻¹(1 − 1e-3).
const Z_999: f64 = 3.090_232_306_167_813;

/// 0.999 quantile of χ²(dof), Wilson–Hilferty (1931).
fn chi2_crit(dof: usize) -> f64 {
    let k = dof.max(1) as f64;
    let h = 2.0 / (9.0 * k);
    k * (1.0 - h + Z_999 * h.sqrt()).powi(3)
}

/// Pearson χ² of `counts` (total n) against `probs` (normalised), pooling consecutive bins
/// until the expected count is ≥ 5; asserts that zero-probability bins are empty.
/// Returns (statistic, dof).
fn chi2(counts: &[u64], probs: &[f64], n: u64) -> (f64, usize) {
    assert_eq!(counts.len(), probs.len());
    let ps: f64 = probs.iter().sum();
    assert!(
        (ps - 1.0).abs() < 1e-9,
        "expected probabilities sum to {ps}"
    );
    assert_eq!(counts.iter().sum::<u64>(), n);
    let mut groups: Vec<(f64, f64)> = Vec::new();
    let (mut e, mut o) = (0.0, 0.0);
    for (&c, &p) in counts.iter().zip(probs) {
        if p == 0.0 {
            assert_eq!(c, 0, "a zero-probability bin received samples");
            continue;
        }
        e += p * n as f64;
        o += c as f64;
        if e >= 5.0 {
            groups.push((o, e));
            e = 0.0;
            o = 0.0;
        }
    }
    if e > 0.0 || o > 0.0 {
        if let Some(last) = groups.last_mut() {
            last.0 += o;
            last.1 += e;
        } else {
            groups.push((o, e));
        }
    }
    let stat = groups.iter().map(|(o, e)| (o - e) * (o - e) / e).sum();
    (stat, groups.len().saturating_sub(1))
}

fn assert_gof(name: &str, counts: &[u64], probs: &[f64]) {
    let n = counts.iter().sum();
    let (stat, dof) = chi2(counts, probs, n);
    let crit = chi2_crit(dof);
    println!("{name}: χ² = {stat:.1}, dof = {dof}, crit(1e-3) = {crit:.1}");
    assert!(dof >= 1, "{name}: no degrees of freedom");
    assert!(
        stat < crit,
        "{name}: χ² = {stat:.1} ≥ {crit:.1} (dof {dof})"
    );
}

fn assert_unit(v: DVec3, what: &str) {
    assert!(v.is_finite(), "{what}: non-finite {v}");
    assert!(
        (v.length() - 1.0).abs() < 1e-12,
        "{what}: |v| = {}",
        v.length()
    );
}

/// `∫_a^b f` by composite Gauss–Legendre (`panels` × `n` nodes).
fn gl_integrate(a: f64, b: f64, panels: usize, n: usize, f: impl Fn(f64) -> f64) -> f64 {
    let (x, w) = gauss_legendre(n);
    let h = (b - a) / panels as f64;
    let mut s = 0.0;
    for p in 0..panels {
        let lo = a + p as f64 * h;
        for (xi, wi) in x.iter().zip(&w) {
            s += wi * 0.5 * h * f(lo + 0.5 * h * (xi + 1.0));
        }
    }
    s
}

/// Frame about `axis` built independently of the code under test (Gram–Schmidt).
fn test_frame(axis: DVec3) -> (DVec3, DVec3) {
    let r = if axis.x.abs() < 0.9 {
        DVec3::X
    } else {
        DVec3::Y
    };
    let e1 = (r - r.dot(axis) * axis).normalize();
    (e1, axis.cross(e1))
}

/// Azimuth of `v` about `axis` in [0, 2π) in the frame (e1, e2).
fn azimuth(v: DVec3, e1: DVec3, e2: DVec3) -> f64 {
    let a = v.dot(e2).atan2(v.dot(e1));
    if a < 0.0 { a + TAU } else { a }
}

fn bin(x: f64, lo: f64, hi: f64, n: usize) -> usize {
    (((x - lo) / (hi - lo) * n as f64).floor().max(0.0) as usize).min(n - 1)
}

// ---------------------------------------------------------------------------------------------
// Discrete samplers
// ---------------------------------------------------------------------------------------------

/// Random weights with zeros and a 1e-9 dynamic range.
fn random_weights(n: usize, seed: u64) -> Vec<f64> {
    let mut r = rng(seed);
    (0..n)
        .map(|_| {
            let u = r.next_f64();
            if u < 0.1 {
                0.0
            } else {
                10f64.powf(-9.0 * r.next_f64())
            }
        })
        .collect()
}

#[test]
fn alias_table_chi2_with_zeros_and_1e9_dynamic_range() {
    for (n, seed) in [(7usize, 11u64), (300, 12), (2000, 13)] {
        let w = random_weights(n, seed);
        let t = AliasTable::new(&w).unwrap();
        let sum: f64 = w.iter().sum();
        let p: Vec<f64> = w.iter().map(|x| x / sum).collect();
        // Realised probabilities are the normalised weights (relative 1e-12 even at 1e-9).
        for (i, (&q, &pi)) in t.probabilities().iter().zip(&p).enumerate() {
            assert!(
                (q - pi).abs() <= 1e-12 * pi + 1e-18,
                "entry {i}: {q} vs {pi}"
            );
        }
        let mut r = rng(seed + 100);
        let mut counts = vec![0u64; n];
        for _ in 0..N_SAMPLES {
            counts[t.sample(&mut r)] += 1;
        }
        assert_gof(&format!("alias N={n}"), &counts, &p);
    }
}

#[test]
fn box_table_chi2_against_its_own_probabilities() {
    let rows: Vec<(String, Vec<f64>)> = vec![
        ("HG 0.85, N=400".into(), hg_row(400, 0.85)),
        ("random N=300".into(), random_weights(300, 21)),
    ];
    for (name, w) in rows {
        for (gamma, budget) in [(2.0, 20_000usize), (10.0, 200_000)] {
            let b = BoxTable::new(&w, gamma, budget).unwrap();
            let res = b.resolution();
            assert!(res.level1_boxes + res.level2_boxes <= budget);
            let p = b.probabilities();
            assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let mut r = rng(22);
            let mut counts = vec![0u64; w.len()];
            for _ in 0..N_SAMPLES {
                counts[b.sample(&mut r)] += 1;
            }
            assert_gof(&format!("box {name} γ={gamma} M={budget}"), &counts, &p);
        }
    }
}

#[test]
fn box_table_bias_is_within_its_documented_bound() {
    println!("row            γ     budget   classes     m1      m2    max|p̂−p|/p   bound     TV");
    for (name, w) in [
        ("HG0.85 N=400", hg_row(400, 0.85)),
        ("HG0.85 N=1000", hg_row(1000, 0.85)),
    ] {
        let sum: f64 = w.iter().sum();
        let p: Vec<f64> = w.iter().map(|x| x / sum).collect();
        let mut last_bound = f64::INFINITY;
        for gamma in [1.5, 2.0, 4.0, 16.0] {
            for budget in [10 * w.len(), 100 * w.len(), 1000 * w.len()] {
                let b = BoxTable::new(&w, gamma, budget).unwrap();
                let q = b.probabilities();
                let max_rel = p
                    .iter()
                    .zip(&q)
                    .filter(|(pi, _)| **pi > 0.0)
                    .map(|(pi, qi)| (qi / pi - 1.0).abs())
                    .fold(0.0, f64::max);
                let tv = total_variation(&p, &q);
                let res = b.resolution();
                let bound = b.bias_bound();
                println!(
                    "{name:14} {gamma:4} {budget:8} {:6} {:8.2} {:7.2} {max_rel:12.3e} {:9.3e} {tv:9.3e}",
                    res.classes,
                    res.m1,
                    res.m2,
                    bound.unwrap_or(f64::NAN)
                );
                if let Some(bound) = bound {
                    assert!(
                        max_rel <= bound * (1.0 + 1e-9),
                        "{name} γ {gamma} M {budget}"
                    );
                    assert!(tv <= 0.5 * bound * (1.0 + 1e-9));
                    if budget == 1000 * w.len() {
                        last_bound = last_bound.min(bound);
                    }
                }
                // Support is preserved: every positive probability stays positive.
                assert!(p.iter().zip(&q).all(|(a, b)| (*a > 0.0) == (*b > 0.0)));
            }
        }
        // With 1000 boxes per direction the Box method reaches < 2 % on these rows.
        assert!(last_bound < 0.02, "{name}: best bound {last_bound}");
    }
}

// ---------------------------------------------------------------------------------------------
// Fluid phase functions and the cosine hemisphere
// ---------------------------------------------------------------------------------------------

/// χ² of sampled directions in (cos Θ, azimuth about `axis`) bins against `pdf_cos` (density of
/// cos Θ on [−1, 1]) × uniform azimuth.
fn polar_gof(
    name: &str,
    axis: DVec3,
    n_c: usize,
    n_a: usize,
    pdf_cos: impl Fn(f64) -> f64,
    mut sample: impl FnMut() -> DVec3,
) {
    let (e1, e2) = test_frame(axis);
    let mut counts = vec![0u64; n_c * n_a];
    for _ in 0..N_SAMPLES {
        let d = sample();
        assert_unit(d, name);
        let c = d.dot(axis).clamp(-1.0, 1.0);
        let i = bin(c, -1.0, 1.0, n_c);
        let j = bin(azimuth(d, e1, e2), 0.0, TAU, n_a);
        counts[i * n_a + j] += 1;
    }
    let mut probs = Vec::with_capacity(n_c * n_a);
    for i in 0..n_c {
        let a = -1.0 + 2.0 * i as f64 / n_c as f64;
        let b = -1.0 + 2.0 * (i + 1) as f64 / n_c as f64;
        let pc = gl_integrate(a, b, 4, 24, &pdf_cos);
        for _ in 0..n_a {
            probs.push(pc / n_a as f64);
        }
    }
    let s: f64 = probs.iter().sum();
    assert!((s - 1.0).abs() < 1e-9, "{name}: expected sums to {s}");
    let probs: Vec<f64> = probs.iter().map(|p| p / s).collect();
    assert_gof(name, &counts, &probs);
}

fn fluid_gof(phase: FluidPhase, seed: u64) {
    phase.validate().unwrap();
    let axes = [DVec3::new(0.3, -0.5, -0.8).normalize(), -DVec3::Z, DVec3::Z];
    for (k, w) in axes.into_iter().enumerate() {
        let mut r = rng(seed + k as u64);
        polar_gof(
            &format!("{phase:?} along {w}"),
            w,
            40,
            8,
            |c| phase.eval(c) / 2.0,
            || sample_fluid_phase(&phase, w, &mut r),
        );
    }
}

#[test]
fn henyey_greenstein_chi2() {
    for (i, g) in [0.0001, 0.3, 0.85, -0.6].into_iter().enumerate() {
        fluid_gof(FluidPhase::HenyeyGreenstein { g }, 100 + 10 * i as u64);
    }
}

#[test]
fn two_term_hg_isotropic_and_rayleigh_chi2() {
    fluid_gof(FluidPhase::dart_aerosol_default(), 200);
    fluid_gof(
        FluidPhase::TwoTermHg {
            a: 0.6,
            g1: 0.5,
            g2: 0.7,
        },
        210,
    );
    fluid_gof(FluidPhase::Isotropic, 220);
    fluid_gof(
        FluidPhase::Rayleigh {
            depolarization: 0.0,
        },
        230,
    );
    fluid_gof(
        FluidPhase::Rayleigh {
            depolarization: AIR_DEPOLARIZATION,
        },
        240,
    );
}

#[test]
fn cosine_hemisphere_chi2() {
    for (k, n) in [DVec3::new(0.2, 0.7, -0.3).normalize(), -DVec3::Z, DVec3::Z]
        .into_iter()
        .enumerate()
    {
        let mut r = rng(300 + k as u64);
        polar_gof(
            &format!("cosine hemisphere about {n}"),
            n,
            40,
            8,
            |c| if c > 0.0 { 2.0 * c } else { 0.0 },
            || sample_cosine_hemisphere(n, &mut r),
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Leaves
// ---------------------------------------------------------------------------------------------

fn all_lads() -> Vec<Lad> {
    vec![
        Lad::Spherical,
        Lad::Uniform,
        Lad::Planophile,
        Lad::Erectophile,
        Lad::Plagiophile,
        Lad::Extremophile,
        Lad::EllipsoidalChi { chi: 0.5 },
        Lad::EllipsoidalChi { chi: 2.0 },
        Lad::Beta {
            mu: 0.433,
            nu: 0.433,
        },
        Lad::Beta {
            mu: 2.77,
            nu: 1.172,
        },
        Lad::Beta { mu: 1.5, nu: 0.6 },
        Lad::Histogram {
            bins: vec![0.1, 0.5, 0.2, 0.0, 0.7],
        },
    ]
}

/// `(1/2π)∫_{φ1}^{φ2} |A + B cos φ| dφ` in closed form (split at the roots).
fn abs_cos_integral(a: f64, b: f64, p1: f64, p2: f64) -> f64 {
    let mut pts = vec![p1, p2];
    if b.abs() > a.abs() {
        let r = (-a / b).acos();
        for x in [r, TAU - r] {
            if x > p1 && x < p2 {
                pts.push(x);
            }
        }
    }
    pts.sort_by(f64::total_cmp);
    let prim = |x: f64| a * x + b * x.sin();
    let mut s = 0.0;
    for w in pts.windows(2) {
        let m = 0.5 * (w[0] + w[1]);
        let sign = if a + b * m.cos() >= 0.0 { 1.0 } else { -1.0 };
        s += sign * (prim(w[1]) - prim(w[0]));
    }
    s / TAU
}

/// Upper-hemisphere normal of a two-sided leaf.
fn up(n: DVec3) -> DVec3 {
    if n.z < 0.0 { -n } else { n }
}

#[test]
fn leaf_normal_inclination_marginals_chi2() {
    // Marginal of θ_L: ∝ f(θ_L) χ_s(μ', θ_L) (= f |cos θ_L| |μ'| at nadir), normalised by G(μ').
    let n_t = 30;
    for (li, lad) in all_lads().into_iter().enumerate() {
        let d = lad.resolve().unwrap();
        let s = LeafSampler::new(&d).unwrap();
        for (k, deg) in [0.0, 60.0, 85.0].into_iter().enumerate() {
            let w = incoming(deg);
            let mu = w.z;
            let kink = FRAC_PI_2 - mu.abs().acos();
            let g = d.g_function(mu);
            let probs: Vec<f64> = (0..n_t)
                .map(|i| {
                    let a = FRAC_PI_2 * i as f64 / n_t as f64;
                    let b = FRAC_PI_2 * (i + 1) as f64 / n_t as f64;
                    d.integrate(a, b, &[kink], |t| chi_s(mu, t)) / g
                })
                .collect();
            let ps: f64 = probs.iter().sum();
            assert!((ps - 1.0).abs() < 1e-6, "{lad:?}: {ps}");
            let mut r = rng(400 + 10 * li as u64 + k as u64);
            let mut counts = vec![0u64; n_t];
            for _ in 0..N_SAMPLES {
                let n = s.sample_normal(w, &mut r);
                assert!(n.dot(w) <= 0.0);
                let th = up(n).z.clamp(-1.0, 1.0).acos();
                counts[bin(th, 0.0, FRAC_PI_2, n_t)] += 1;
            }
            let probs: Vec<f64> = probs.iter().map(|p| p / ps).collect();
            assert_gof(&format!("normals θ_L {lad:?} at {deg}°"), &counts, &probs);
        }
    }
}

#[test]
fn leaf_normal_joint_inclination_azimuth_chi2() {
    // Joint (θ_L, φ_L − φ') density f(θ_L)|Ω'·Ω_L|/(2πG), azimuth integral in closed form.
    let (n_t, n_p) = (9, 12);
    for (li, lad) in [
        Lad::Spherical,
        Lad::Planophile,
        Lad::Erectophile,
        Lad::Beta {
            mu: 0.433,
            nu: 0.433,
        },
    ]
    .into_iter()
    .enumerate()
    {
        let d = lad.resolve().unwrap();
        let s = LeafSampler::new(&d).unwrap();
        for (k, deg) in [35.0, 85.0].into_iter().enumerate() {
            let w = incoming(deg);
            let (mu, sp) = (w.z, w.x);
            let kink = FRAC_PI_2 - mu.abs().acos();
            let g = d.g_function(mu);
            let mut probs = Vec::new();
            for i in 0..n_t {
                let a = FRAC_PI_2 * i as f64 / n_t as f64;
                let b = FRAC_PI_2 * (i + 1) as f64 / n_t as f64;
                for j in 0..n_p {
                    let (p1, p2) = (
                        TAU * j as f64 / n_p as f64,
                        TAU * (j + 1) as f64 / n_p as f64,
                    );
                    let v = d.integrate(a, b, &[kink], |t| {
                        abs_cos_integral(mu * t.cos(), sp * t.sin(), p1, p2)
                    });
                    probs.push(v / g);
                }
            }
            let ps: f64 = probs.iter().sum();
            assert!((ps - 1.0).abs() < 1e-6, "{lad:?} {deg}: {ps}");
            let mut r = rng(500 + 10 * li as u64 + k as u64);
            let mut counts = vec![0u64; n_t * n_p];
            for _ in 0..N_SAMPLES {
                let n = up(s.sample_normal(w, &mut r));
                let th = n.z.clamp(-1.0, 1.0).acos();
                let ph = azimuth(n, DVec3::X, DVec3::Y);
                counts[bin(th, 0.0, FRAC_PI_2, n_t) * n_p + bin(ph, 0.0, TAU, n_p)] += 1;
            }
            let probs: Vec<f64> = probs.iter().map(|p| p / ps).collect();
            assert_gof(
                &format!("normals (θ_L, φ_L) {lad:?} at {deg}°"),
                &counts,
                &probs,
            );
        }
    }
}

/// Bin integrals over (μ ∈ [−1, 1] in `n_m` bins) × (azimuth ∈ [0, 2π) in `n_p` bins) of
/// `f(Ω)` by `q × q` Gauss–Legendre per bin.
fn sphere_bin_integrals(n_m: usize, n_p: usize, q: usize, f: impl Fn(DVec3) -> f64) -> Vec<f64> {
    let (x, wq) = gauss_legendre(q);
    let mut out = Vec::with_capacity(n_m * n_p);
    for i in 0..n_m {
        let (a, b) = (
            -1.0 + 2.0 * i as f64 / n_m as f64,
            -1.0 + 2.0 * (i + 1) as f64 / n_m as f64,
        );
        for j in 0..n_p {
            let (c, e) = (
                TAU * j as f64 / n_p as f64,
                TAU * (j + 1) as f64 / n_p as f64,
            );
            let mut s = 0.0;
            for (xi, wi) in x.iter().zip(&wq) {
                let mu = a + 0.5 * (b - a) * (xi + 1.0);
                let st = (1.0 - mu * mu).max(0.0).sqrt();
                for (xj, wj) in x.iter().zip(&wq) {
                    let phi = c + 0.5 * (e - c) * (xj + 1.0);
                    s += wi * wj * f(DVec3::new(st * phi.cos(), st * phi.sin(), mu));
                }
            }
            out.push(s * 0.25 * (b - a) * (e - c));
        }
    }
    out
}

#[test]
fn leaf_scattering_matches_gamma_chi2() {
    // Outgoing directions vs ∫_bin Γ(Ω'→Ω)dΩ/(π G ω), Γ = ρΓ_ρ + τΓ_τ from the volscatt kernel
    // (closed form for the spherical LAD), G = g_binned (its exact row sum).
    let (rho, tau) = (0.45, 0.35);
    let (n_m, n_p) = (12, 12);
    for (li, lad) in [Lad::Spherical, Lad::Planophile, Lad::Erectophile]
        .into_iter()
        .enumerate()
    {
        let d = lad.resolve().unwrap();
        let kernel = VolscattKernel::new(&d, 180, false);
        let s = LeafSampler::new(&d).unwrap();
        for (k, deg) in [30.0, 85.0].into_iter().enumerate() {
            let w = incoming(deg);
            let g = kernel.g_binned(w.z);
            let probs = sphere_bin_integrals(n_m, n_p, 8, |o| {
                leaf_scatter_density(&kernel, g, w, o, rho, tau) / (rho + tau)
            });
            let ps: f64 = probs.iter().sum();
            assert!((ps - 1.0).abs() < 2e-3, "{lad:?} {deg}°: Σ = {ps}");
            let mut r = rng(600 + 10 * li as u64 + k as u64);
            let mut counts = vec![0u64; n_m * n_p];
            for _ in 0..N_SAMPLES {
                let e = s.scatter(w, rho / (rho + tau), &mut r);
                assert_unit(e.dir, "leaf dir");
                let ph = azimuth(e.dir, DVec3::X, DVec3::Y);
                counts[bin(e.dir.z, -1.0, 1.0, n_m) * n_p + bin(ph, 0.0, TAU, n_p)] += 1;
            }
            let probs: Vec<f64> = probs.iter().map(|p| p / ps).collect();
            assert_gof(
                &format!("leaf scattering {lad:?} at {deg}°"),
                &counts,
                &probs,
            );
        }
    }
}

#[test]
fn specular_leaf_events_are_unbiased() {
    // Weighted specular-branch histogram vs ∫_bin Γ_spec/(πG) (lad::gamma_specular), the total
    // weight vs ρ + τ + specular_albedo, both as z-tests at the 1e-3 false-alarm rate.
    let d = Lad::Spherical.resolve().unwrap();
    let s = LeafSampler::new(&d).unwrap();
    let spec = LeafSpecular {
        refractive_index: 1.5,
        factor: 0.8,
    };
    let (rho, tau) = (0.1, 0.05);
    let (n_m, n_p) = (10, 12);
    for (k, deg) in [20.0, 70.0].into_iter().enumerate() {
        let w = incoming(deg);
        let g = d.g_function(w.z);
        let expect =
            sphere_bin_integrals(n_m, n_p, 8, |o| gamma_specular(&d, w, o, &spec) / (PI * g));
        let mut sum_w = vec![0.0; n_m * n_p];
        let mut sum_w2 = vec![0.0; n_m * n_p];
        let (mut tot, mut tot2) = (0.0, 0.0);
        let mut r = rng(700 + k as u64);
        for _ in 0..N_SAMPLES {
            let e = s.scatter_specular(w, rho / (rho + tau), rho + tau, &spec, &mut r);
            assert_unit(e.dir, "specular dir");
            let m = match e.branch {
                LeafBranch::Specular => spec.fraction(e.cos_incidence),
                LeafBranch::Reflected => rho,
                LeafBranch::Transmitted => tau,
            } / e.branch_probability;
            tot += m;
            tot2 += m * m;
            if e.branch == LeafBranch::Specular {
                let ph = azimuth(e.dir, DVec3::X, DVec3::Y);
                let i = bin(e.dir.z, -1.0, 1.0, n_m) * n_p + bin(ph, 0.0, TAU, n_p);
                sum_w[i] += m;
                sum_w2[i] += m * m;
            }
        }
        let nf = N_SAMPLES as f64;
        let mut chi = 0.0;
        let mut dof = 0;
        for i in 0..n_m * n_p {
            let mean = sum_w[i] / nf;
            let var = (sum_w2[i] / nf - mean * mean) / nf;
            if var > 0.0 {
                chi += (mean - expect[i]).powi(2) / var;
                dof += 1;
            } else {
                assert!(
                    expect[i] < 1e-6,
                    "bin {i}: no samples, expected {}",
                    expect[i]
                );
            }
        }
        println!(
            "specular {deg}°: Σz² = {chi:.1} over {dof} bins (crit {:.1})",
            chi2_crit(dof)
        );
        assert!(chi < chi2_crit(dof), "specular histogram at {deg}°");
        let mean = tot / nf;
        let sd = ((tot2 / nf - mean * mean) / nf).sqrt();
        let want = rho + tau + specular_albedo(&d, w, &spec, 180, 720);
        println!("specular {deg}°: E[w] = {mean:.6} ± {sd:.1e}, expected {want:.6}");
        assert!((mean - want).abs() < Z_999 * sd + 1e-4 * want);
    }
}

#[test]
fn peel_off_gamma_uses_closed_form_for_spherical_lad() {
    let sph = Lad::Spherical.resolve().unwrap();
    let k = VolscattKernel::new(&sph, 90, false);
    assert!(k.is_closed_form());
    let mut r = rng(800);
    for _ in 0..1000 {
        let a = sample_fluid_phase(&FluidPhase::Isotropic, DVec3::Z, &mut r);
        let b = sample_fluid_phase(&FluidPhase::Isotropic, DVec3::Z, &mut r);
        let (gr, gt) = leaf_gamma_parts(&k, a, b);
        assert_eq!(gr, gamma_spherical(a, b, 1.0, 0.0));
        assert_eq!(gt, gamma_spherical(a, b, 0.0, 1.0));
    }
    // The peel-off density integrates to ω_L for a binned LAD (quadrature 1e-3).
    let pla = Lad::Planophile.resolve().unwrap();
    let k = VolscattKernel::new(&pla, 90, false);
    assert!(!k.is_closed_form());
    for w in [incoming(0.0), incoming(50.0), incoming(89.9)] {
        let g = k.g_binned(w.z);
        let tot: f64 =
            sphere_bin_integrals(12, 12, 8, |o| leaf_scatter_density(&k, g, w, o, 0.4, 0.3))
                .iter()
                .sum();
        assert!((tot - 0.7).abs() < 1.5e-3, "{w}: {tot}");
    }
}

// ---------------------------------------------------------------------------------------------
// Surfaces
// ---------------------------------------------------------------------------------------------

#[test]
fn brdf_sampler_is_exact_and_unbiased() {
    // Tilted facet so that the facet frame is exercised.
    let normal = DVec3::new(0.3, -0.2, 1.0).normalize();
    let (e1, e2) = test_frame(normal);
    let grid = BrdfGrid::default();
    let (n_m, n_p) = (10, 9); // test bins in (μ_o, |ψ|), not aligned with the proposal grid
    let (gx, gw) = gauss_legendre(16);
    let configs = reference_brdfs();
    let mut albedo_z = Vec::new();
    for (ci, (name, brdf, sza)) in configs.iter().cloned().enumerate() {
        let sampler = BrdfSampler::new(&brdf, grid).unwrap();
        let ti = sza.to_radians();
        let mu_i = ti.cos();
        // Direction to the source at azimuth 0.7 rad in the test frame.
        let src = normal * mu_i + (e1 * 0.7f64.cos() + e2 * 0.7f64.sin()) * ti.sin();
        let w_in = -src;
        let src_h = src - src.dot(normal) * normal;
        // In-plane axis toward the source; at normal incidence the azimuth origin is arbitrary
        // (the BRF does not depend on it) and the sampler uses `orthonormal_basis(normal).0`.
        let t1 = if src_h.length() < 1e-9 {
            orthonormal_basis(normal).0
        } else {
            src_h.normalize()
        };
        let t2 = normal.cross(t1);
        let psi_of = |d: DVec3| {
            let a = azimuth(d, t1, t2);
            if a > PI { TAU - a } else { a }
        };
        let dir_at = |mu: f64, psi: f64| {
            let st = (1.0 - mu * mu).max(0.0).sqrt();
            normal * mu + (t1 * psi.cos() + t2 * psi.sin()) * st
        };
        // (a) proposal probabilities of the test bins: the pdf is constant on the proposal cells,
        // so overlap areas give the exact bin probabilities.
        let (gm, gp) = (grid.mu_bins, grid.psi_bins);
        let mut prop = vec![0.0; n_m * n_p];
        for j in 0..gm {
            for m in 0..gp {
                let (ma, mb) = (j as f64 / gm as f64, (j + 1) as f64 / gm as f64);
                let (pa, pb) = (PI * m as f64 / gp as f64, PI * (m + 1) as f64 / gp as f64);
                let pdf = sampler.pdf(normal, w_in, dir_at(0.5 * (ma + mb), 0.5 * (pa + pb)));
                for ti_ in 0..n_m {
                    let (ta, tb) = (ti_ as f64 / n_m as f64, (ti_ + 1) as f64 / n_m as f64);
                    let om = (mb.min(tb) - ma.max(ta)).max(0.0);
                    if om == 0.0 {
                        continue;
                    }
                    for tp in 0..n_p {
                        let (qa, qb) = (
                            PI * tp as f64 / n_p as f64,
                            PI * (tp + 1) as f64 / n_p as f64,
                        );
                        let op = (pb.min(qb) - pa.max(qa)).max(0.0);
                        prop[ti_ * n_p + tp] += 2.0 * pdf * om * op;
                    }
                }
            }
        }
        let ps: f64 = prop.iter().sum();
        assert!((ps - 1.0).abs() < 1e-12, "{name}: proposal sums to {ps}");
        // (b) expected weighted bin integrals ∫_B BRF μ_o dΩ/π (both azimuth signs).
        let mut want = vec![0.0; n_m * n_p];
        for ti_ in 0..n_m {
            let (ta, tb) = (ti_ as f64 / n_m as f64, (ti_ + 1) as f64 / n_m as f64);
            for tp in 0..n_p {
                let (qa, qb) = (
                    PI * tp as f64 / n_p as f64,
                    PI * (tp + 1) as f64 / n_p as f64,
                );
                let mut s = 0.0;
                for (xa, wa) in gx.iter().zip(&gw) {
                    let mu = ta + 0.5 * (tb - ta) * (xa + 1.0);
                    for (xb, wb) in gx.iter().zip(&gw) {
                        let psi = qa + 0.5 * (qb - qa) * (xb + 1.0);
                        let geo = LocalGeometry {
                            mu_i,
                            mu_v: mu.max(1e-6),
                            cos_psi: psi.cos(),
                        };
                        s += wa * wb * brdf.brf_local(&geo) * mu;
                    }
                }
                want[ti_ * n_p + tp] = s * 0.25 * (tb - ta) * (qb - qa) * 2.0 / PI;
            }
        }
        let mut counts = vec![0u64; n_m * n_p];
        let mut sw = vec![0.0; n_m * n_p];
        let mut sw2 = vec![0.0; n_m * n_p];
        let (mut tot, mut tot2) = (0.0, 0.0);
        let mut r = rng(900 + ci as u64);
        for _ in 0..N_SAMPLES {
            let smp = sampler.sample(normal, w_in, &mut r).unwrap();
            assert_unit(smp.dir, &name);
            let mu = smp.dir.dot(normal);
            assert!(mu >= 0.0);
            let i = bin(mu, 0.0, 1.0, n_m) * n_p + bin(psi_of(smp.dir), 0.0, PI, n_p);
            counts[i] += 1;
            sw[i] += smp.weight;
            sw2[i] += smp.weight * smp.weight;
            tot += smp.weight;
            tot2 += smp.weight * smp.weight;
            // The returned pdf is the sampler's pdf of that direction.
            let p2 = sampler.pdf(normal, w_in, smp.dir);
            assert!((p2 / smp.pdf - 1.0).abs() < 1e-9 || (mu * grid.mu_bins as f64).fract() < 1e-9);
        }
        assert_gof(&format!("BRDF proposal {name} sza {sza}"), &counts, &prop);
        let nf = N_SAMPLES as f64;
        let mut chi = 0.0;
        for i in 0..n_m * n_p {
            let mean = sw[i] / nf;
            let var = (sw2[i] / nf - mean * mean) / nf;
            assert!(var > 0.0, "{name}: empty bin {i}");
            chi += (mean - want[i]).powi(2) / var;
        }
        let crit = chi2_crit(n_m * n_p);
        println!("BRDF weights {name} sza {sza}: Σz² = {chi:.1} (crit {crit:.1})");
        assert!(
            chi < crit,
            "{name} sza {sza}: weighted histogram Σz² = {chi:.1}"
        );
        let mean = tot / nf;
        let sd = ((tot2 / nf - mean * mean) / nf).sqrt();
        let albedo = brdf.albedo_dh(mu_i);
        let z = (mean - albedo) / sd;
        println!("  E[w] = {mean:.5} ± {sd:.1e}, albedo_dh = {albedo:.5} (z = {z:.2})");
        albedo_z.push(z);
    }
    // E[w] = ρ_DH(μ_i): every |z| below the Bonferroni threshold for a family-wise false-alarm
    // rate of 1e-3 over the 18 configurations (Φ⁻¹(1 − 1e-3/36) = 4.031; a plain 3σ per test
    // would false-alarm with probability 1 − 0.9973¹⁸ ≈ 5 %), and jointly Σz² < χ²₁₈(0.999).
    let z_bonf = 4.030_934_372_846_465;
    for (z, (name, _, sza)) in albedo_z.iter().zip(&configs) {
        assert!(
            z.abs() < z_bonf,
            "{name} sza {sza}: E[w] off albedo_dh by {z:.2}σ"
        );
    }
    let chi: f64 = albedo_z.iter().map(|z| z * z).sum();
    println!(
        "E[w] vs albedo_dh: Σz² = {chi:.1} over {} configurations",
        albedo_z.len()
    );
    assert!(chi < chi2_crit(albedo_z.len()));
}

#[test]
fn lambertian_brdf_sampler_is_cosine_with_constant_weight() {
    let s = BrdfSampler::new(&Brdf::Lambertian { reflectance: 0.3 }, BrdfGrid::default()).unwrap();
    let n = DVec3::new(-0.4, 0.1, 0.9).normalize();
    let w_in = -(n + DVec3::X * 0.5).normalize();
    let mut r = rng(950);
    polar_gof(
        "Lambertian BRDF sampler",
        n,
        40,
        8,
        |c| if c > 0.0 { 2.0 * c } else { 0.0 },
        || {
            let smp = s.sample(n, w_in, &mut r).unwrap();
            assert_eq!(smp.weight, 0.3);
            assert!((smp.pdf - smp.dir.dot(n) / PI).abs() < 1e-15);
            smp.dir
        },
    );
}

// ---------------------------------------------------------------------------------------------
// Hard cases
// ---------------------------------------------------------------------------------------------

#[test]
fn hard_cases_give_finite_unit_directions() {
    let mut r = rng(1000);
    let grazing = DVec3::new((1.0f64 - 1e-12).sqrt(), 0.0, -1e-6);
    let dirs = [DVec3::Z, -DVec3::Z, grazing, -grazing, DVec3::X];
    // Fluid phases with |g| = 0.999 along ±z.
    for phase in [
        FluidPhase::HenyeyGreenstein { g: 0.999 },
        FluidPhase::HenyeyGreenstein { g: -0.999 },
        FluidPhase::TwoTermHg {
            a: 0.5,
            g1: 0.999,
            g2: 0.999,
        },
        FluidPhase::air(),
    ] {
        for w in dirs {
            let mut mean = 0.0;
            for _ in 0..20_000 {
                let d = sample_fluid_phase(&phase, w, &mut r);
                assert_unit(d, "fluid");
                mean += d.dot(w);
            }
            mean /= 20_000.0;
            // Mean cosine within 5σ (σ ≤ 1/√n).
            assert!(
                (mean - phase.mean_cosine()).abs() < 5.0 / 20_000f64.sqrt(),
                "{phase:?}"
            );
        }
    }
    for w in dirs {
        assert_unit(sample_cosine_hemisphere(w, &mut r), "cosine");
    }
    // Leaves at grazing incidence and along ±z, including extreme LADs.
    let mut lads = all_lads();
    lads.extend([
        Lad::EllipsoidalChi { chi: 100.0 },
        Lad::EllipsoidalChi { chi: 0.01 },
        Lad::Beta { mu: 0.05, nu: 0.05 },
        Lad::Beta {
            mu: 100.0,
            nu: 0.05,
        },
        Lad::Histogram {
            bins: vec![0.0, 0.0, 1.0],
        },
    ]);
    let spec = LeafSpecular {
        refractive_index: 1.45,
        factor: 1.0,
    };
    for lad in lads {
        let d = lad.resolve().unwrap();
        let s = LeafSampler::new(&d).unwrap();
        for w in dirs {
            for _ in 0..2000 {
                let n = s.sample_normal(w, &mut r);
                assert_unit(n, "normal");
                assert!(n.dot(w) <= 0.0);
                let e = s.scatter(w, 0.5, &mut r);
                assert_unit(e.dir, "leaf scatter");
                let e = s.scatter_specular(w, 0.5, 0.0, &spec, &mut r);
                assert_unit(e.dir, "leaf specular");
                assert!(e.branch_probability > 0.0 && e.branch_probability <= 1.0);
            }
            let trials = s.expected_trials(w, d.g_function(w.z));
            assert!(
                trials.is_finite() && trials >= 1.0 - 1e-9,
                "{lad:?}: {trials}"
            );
        }
        let k = VolscattKernel::new(&d, 90, false);
        for a in dirs {
            for b in dirs {
                let (gr, gt) = leaf_gamma_parts(&k, a, b);
                assert!(gr.is_finite() && gt.is_finite() && gr >= 0.0 && gt >= 0.0);
            }
        }
    }
    // Surfaces at μ_i = 1e-6 and at normal incidence.
    for (_, brdf, _) in reference_brdfs().into_iter().step_by(3) {
        let s = BrdfSampler::new(&brdf, BrdfGrid::default()).unwrap();
        for w in [grazing, -DVec3::Z] {
            for _ in 0..2000 {
                let smp = s.sample(DVec3::Z, w, &mut r).unwrap();
                assert_unit(smp.dir, "brdf");
                assert!(smp.weight.is_finite() && smp.weight >= 0.0 && smp.pdf > 0.0);
            }
        }
        assert!(
            s.sample(DVec3::Z, DVec3::new(1.0, 0.0, 0.0), &mut r)
                .is_none()
        );
        assert_eq!(s.sample_dir(DVec3::Z, DVec3::Z, &mut r).1, 0.0);
        // `sample_dir` makes the same draw as `sample` from the same stream.
        let w = DVec3::new(0.5, 0.1, -0.8).normalize();
        let (mut r1, mut r2) = (rng(1001), rng(1001));
        for _ in 0..100 {
            let a = s.sample(DVec3::Z, w, &mut r1).unwrap();
            let (d, p) = s.sample_dir(DVec3::Z, w, &mut r2);
            assert_eq!((a.dir, a.pdf), (d, p));
        }
    }
    // Discrete tables with a single non-zero entry.
    let w = [0.0, 0.0, 1e-300, 0.0];
    let a = AliasTable::new(&w).unwrap();
    let b = BoxTable::new(&w, 2.0, 2).unwrap();
    for _ in 0..1000 {
        assert_eq!(a.sample(&mut r), 2);
        assert_eq!(b.sample(&mut r), 2);
    }
}
