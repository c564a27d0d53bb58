//! Unit tests of the scattering-direction samplers: alias and Box tables against their
//! distributions, frames, fluid phase functions, leaf and BRDF samplers against their densities.

use super::alias::*;
use super::box_method::*;
use super::brdf::*;
use super::frames::*;
use super::leaf::*;
use super::*;
use crate::physics::brdf::Brdf;
use crate::physics::lad::Lad;
use crate::physics::phase::FluidPhase;
use glam::DVec3;
use rand_xoshiro::rand_core::SeedableRng;
use std::f64::consts::FRAC_PI_2;

fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

#[test]
fn uniform01_is_in_unit_interval_with_mean_half() {
    let mut r = rng(1);
    let n = 100_000;
    let mut s = 0.0;
    for _ in 0..n {
        let u = r.next_f64();
        assert!((0.0..1.0).contains(&u));
        s += u;
    }
    // σ of the mean = 1/√(12n) ≈ 9.1e-4; 5σ.
    assert!((s / n as f64 - 0.5).abs() < 4.6e-3);
}

#[test]
fn alias_probabilities_are_the_normalised_weights() {
    let w = [3.0, 0.0, 1e-9, 7.5, 0.25, 0.0, 1.0];
    let t = AliasTable::new(&w).unwrap();
    let sum: f64 = w.iter().sum();
    let p = t.probabilities();
    for (i, (&wi, &pi)) in w.iter().zip(&p).enumerate() {
        assert!((pi - wi / sum).abs() <= 1e-15, "{i}: {pi} vs {}", wi / sum);
        assert!((t.probability(i) - pi).abs() <= 1e-16);
    }
    assert_eq!(t.probability(1), 0.0);
    assert_eq!(t.probability(99), 0.0);
    assert_eq!(t.len(), 7);
    assert_eq!(t.bytes(), std::mem::size_of::<AliasTable>() + 20 * 7);
}

#[test]
fn alias_rejects_bad_weights() {
    assert_eq!(AliasTable::new(&[]), Err(SamplingError::Empty));
    assert_eq!(AliasTable::new(&[0.0, 0.0]), Err(SamplingError::AllZero(2)));
    assert!(matches!(
        AliasTable::new(&[1.0, -1.0]),
        Err(SamplingError::InvalidWeight { index: 1, .. })
    ));
    assert!(matches!(
        AliasTable::new(&[1.0, f64::NAN]),
        Err(SamplingError::InvalidWeight { index: 1, .. })
    ));
    assert!(matches!(
        AliasTable::new(&[f64::INFINITY]),
        Err(SamplingError::InvalidWeight { index: 0, .. })
    ));
    // Huge weights do not overflow the normalisation.
    let t = AliasTable::new(&[f64::MAX, f64::MAX]).unwrap();
    assert!((t.probability(0) - 0.5).abs() < 1e-15);
}

#[test]
fn single_nonzero_weight_is_always_drawn() {
    let w = [0.0, 0.0, 0.0, 2.5, 0.0];
    let a = AliasTable::new(&w).unwrap();
    let b = BoxTable::new(&w, 2.0, 16).unwrap();
    let mut r = rng(2);
    for _ in 0..10_000 {
        assert_eq!(a.sample(&mut r), 3);
        assert_eq!(b.sample(&mut r), 3);
    }
    assert_eq!(b.probabilities(), vec![0.0, 0.0, 0.0, 1.0, 0.0]);
    assert_eq!(BoxTable::new(&[1.0], 1.5, 2).unwrap().sample(&mut r), 0);
}

#[test]
fn box_table_structure_and_errors() {
    let w: Vec<f64> = (0..50).map(|i| 1.0 + (i % 7) as f64 * 3.0).collect();
    let b = BoxTable::new(&w, 2.0, 5000).unwrap();
    let res = b.resolution();
    assert!(res.level1_boxes + res.level2_boxes <= 5000);
    assert!(res.m1 >= 1.0 && res.m2 >= 1.0, "{res:?}");
    let p = b.probabilities();
    assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    let sum: f64 = w.iter().sum();
    let bound = b.bias_bound().unwrap();
    for (pi, wi) in p.iter().zip(&w) {
        assert!((pi / (wi / sum) - 1.0).abs() <= bound);
    }
    assert_eq!(
        b.bytes(),
        std::mem::size_of::<BoxTable>()
            + 4 * (res.level1_boxes + res.level2_boxes + res.classes + 1)
            + 8 * w.len()
    );
    assert!(matches!(
        BoxTable::new(&w, 1.0, 5000),
        Err(SamplingError::Parameter { name: "gamma", .. })
    ));
    assert!(matches!(
        BoxTable::new(&w, f64::NAN, 5000),
        Err(SamplingError::Parameter { name: "gamma", .. })
    ));
    assert!(matches!(
        BoxTable::new(&w, 2.0, 10),
        Err(SamplingError::BudgetTooSmall { budget: 10, .. })
    ));
    // Class ratio below γ inside every class.
    let sorted = {
        let mut v = w.clone();
        v.sort_by(|a, b| b.total_cmp(a));
        v
    };
    assert!(sorted[0] / sorted[sorted.len() - 1] >= 2.0);
}

#[test]
fn box_table_with_extreme_dynamic_range_keeps_support() {
    // 1e-12 dynamic range cannot be resolved with 1000 boxes: no a-priori bound, but every
    // positive direction keeps a positive probability and the budget holds.
    let w = [1.0, 1e-12, 0.5, 0.0, 1e-6];
    let b = BoxTable::new(&w, 4.0, 1000).unwrap();
    let res = b.resolution();
    assert!(res.level1_boxes + res.level2_boxes <= 1000);
    assert!(b.bias_bound().is_none());
    let p = b.probabilities();
    for (pi, wi) in p.iter().zip(&w) {
        assert_eq!(*pi > 0.0, *wi > 0.0);
    }
}

#[test]
fn total_variation_basics() {
    assert_eq!(total_variation(&[0.5, 0.5], &[0.5, 0.5]), 0.0);
    assert!((total_variation(&[1.0, 0.0], &[0.0, 1.0]) - 1.0).abs() < 1e-15);
    assert!((total_variation(&[0.5, 0.5], &[1.0]) - 0.5).abs() < 1e-15);
}

#[test]
fn rayleigh_inverse_cdf_is_exact() {
    for rho in [0.0, AIR, 0.3] {
        let gam: f64 = rho / (2.0 - rho);
        let (a, b) = (1.0 + 3.0 * gam, 1.0 - gam);
        let cdf =
            |m: f64| (a * (m + 1.0) + b * (m * m * m + 1.0) / 3.0) / (2.0 * a + 2.0 * b / 3.0);
        for k in 0..=1000 {
            let xi = k as f64 / 1000.0;
            let mu = rayleigh_cos_sample(rho, xi);
            assert!(
                (cdf(mu) - xi).abs() < 1e-14,
                "rho {rho} xi {xi}: {}",
                cdf(mu)
            );
        }
    }
}
const AIR: f64 = crate::physics::phase::AIR_DEPOLARIZATION;

#[test]
fn orthonormal_basis_is_orthonormal_everywhere() {
    let mut r = rng(3);
    let mut dirs = vec![
        DVec3::Z,
        -DVec3::Z,
        DVec3::new(0.0, 0.0, -0.0),
        DVec3::X,
        DVec3::new(1e-300, 0.0, -1.0),
        DVec3::new(0.0, 1e-9, -1.0).normalize(),
    ];
    for _ in 0..1000 {
        dirs.push(sample_fluid_phase(&FluidPhase::Isotropic, DVec3::Z, &mut r));
    }
    for n in dirs {
        let nn = unit_or_z(n);
        let (t1, t2) = orthonormal_basis(n);
        for (x, y) in [(t1, t2), (t1, nn), (t2, nn)] {
            assert!(x.dot(y).abs() < 1e-14, "{n}");
        }
        assert!((t1.length() - 1.0).abs() < 1e-14 && (t2.length() - 1.0).abs() < 1e-14);
        assert!((t1.cross(t2) - nn).length() < 1e-14, "right-handed {n}");
    }
    // Degenerate inputs read as +z.
    let (t1, t2) = orthonormal_basis(DVec3::new(f64::NAN, 0.0, 0.0));
    assert!(t1.is_finite() && t2.is_finite());
}

#[test]
fn beta_factorisation_matches_lad_pdf() {
    for (mu, nu) in [(0.433, 0.433), (2.77, 1.172), (1.5, 0.6), (0.3, 3.0)] {
        let lad = Lad::Beta { mu, nu }.resolve().unwrap();
        let s = LeafSampler::new(&lad).unwrap();
        for k in 1..100 {
            let t = FRAC_PI_2 * k as f64 / 100.0;
            let (a, b) = (s.inclination_pdf(t), lad.pdf(t));
            assert!(
                (a / b - 1.0).abs() < 1e-12,
                "beta({mu},{nu}) θ={t}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn leaf_normals_face_the_photon() {
    let lad = Lad::Planophile.resolve().unwrap();
    let s = LeafSampler::new(&lad).unwrap();
    let mut r = rng(4);
    for w in [
        DVec3::new(0.3, -0.2, -0.9).normalize(),
        -DVec3::Z,
        DVec3::Z,
        DVec3::X,
    ] {
        for _ in 0..2000 {
            let n = s.sample_normal(w, &mut r);
            assert!((n.length() - 1.0).abs() < 1e-12);
            assert!(n.dot(w) <= 0.0);
            let e = s.scatter(w, 0.4, &mut r);
            let d = e.dir.dot(e.normal);
            assert!(if e.reflected { d >= 0.0 } else { d <= 0.0 });
        }
    }
}

#[test]
fn brdf_sampler_errors() {
    let bad = Brdf::Rpv {
        rho0: -1.0,
        k: 0.5,
        theta: 0.0,
        rho_c: None,
    };
    assert!(matches!(
        BrdfSampler::new(&bad, BrdfGrid::default()),
        Err(SamplingError::Brdf(_))
    ));
    let ok = Brdf::Lambertian { reflectance: 0.3 };
    let g = BrdfGrid {
        mu_bins: 0,
        ..BrdfGrid::default()
    };
    assert!(matches!(
        BrdfSampler::new(&ok, g),
        Err(SamplingError::Parameter {
            name: "mu_bins",
            ..
        })
    ));
    let s = BrdfSampler::new(&ok, BrdfGrid::default()).unwrap();
    // Back-side incidence: no sample.
    let mut r = rng(5);
    assert!(s.sample(DVec3::Z, DVec3::Z, &mut r).is_none());
    assert_eq!(s.pdf(DVec3::Z, DVec3::Z, DVec3::Z), 0.0);
}
