//! Unit tests of the launch plan, the crossing geometry and the half-barycentres.

use super::*;

fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3], kind: FacetKind) -> Facet {
    Facet {
        v: [DVec3::from(a), DVec3::from(b), DVec3::from(c)],
        material: 0,
        object: 0,
        kind,
        two_sided: true,
    }
}

/// A square of two triangles has an outline of 4 sides; a 12-triangle fan disk has the
/// 12-gon's perimeter (spokes are shared); a DEM of two squares counts only its border.
#[test]
fn facet_outline_counts_unshared_edges() {
    let sq = [
        tri([0., 0., 1.], [1., 0., 1.], [1., 1., 1.], FacetKind::Mesh),
        tri([0., 0., 1.], [1., 1., 1.], [0., 1., 1.], FacetKind::Mesh),
    ];
    assert!((facet_outline_m(&sq) - 4.0).abs() < 1e-12);
    let n = 12;
    let r = 0.05;
    let p = |k: usize| {
        let a = 2.0 * std::f64::consts::PI * (k % n) as f64 / n as f64;
        [r * a.cos(), r * a.sin(), 0.5]
    };
    let fan: Vec<Facet> = (0..n)
        .map(|k| tri([0., 0., 0.5], p(k), p(k + 1), FacetKind::Mesh))
        .collect();
    let per = 2.0 * n as f64 * r * (std::f64::consts::PI / n as f64).sin();
    assert!((facet_outline_m(&fan) - per).abs() < 1e-12);
}

/// The outline is the same to the last bit on every call (it sets the launch spacing, so
/// a run-to-run difference would change the products): 300 separate triangles with
/// irrational side lengths, whose sum depends on the summation order.
#[test]
fn facet_outline_is_the_same_on_every_call() {
    let tris: Vec<Facet> = (0..300)
        .map(|k| {
            let (x, s) = (k as f64 * 1.7, 0.1 + (k as f64 * 0.37).sin().abs());
            tri(
                [x, 0., 1.],
                [x + s, 0.3 * s, 1.],
                [x + 0.2, s * 1.3, 1.2],
                FacetKind::Mesh,
            )
        })
        .collect();
    let first = facet_outline_m(&tris).to_bits();
    for _ in 0..20 {
        assert_eq!(facet_outline_m(&tris).to_bits(), first);
    }
}

/// Without facets the grid is cell/4 and D is the scene's; with small facets the spacing
/// meets the target SE and D follows the facet size; a tiny target is capped by the budget.
#[test]
fn launch_plan_follows_the_facets_and_respects_the_budget() {
    let params = TrackingParams::dart_default();
    let none = launch_plan((2.0, 2.0), (0.5, 0.5), &[], 2, 50, &params);
    assert_eq!(none.sun_n, (16, 16));
    assert_eq!(none.subcells, 2);
    assert_eq!(none.predicted_se, 0.0);
    let n = 12;
    let r = 0.05;
    let mut leaves = Vec::new();
    for i in 0..10 {
        let c = [0.1 + 0.18 * i as f64, 1.0, 0.5];
        let p = |k: usize| {
            let a = 2.0 * std::f64::consts::PI * (k % n) as f64 / n as f64;
            [c[0] + r * a.cos(), c[1] + r * a.sin(), 0.5]
        };
        for k in 0..n {
            leaves.push(tri(c, p(k), p(k + 1), FacetKind::Mesh));
        }
    }
    let plan = launch_plan((2.0, 2.0), (0.5, 0.5), &leaves, 2, 50, &params);
    assert!(!plan.capped);
    assert!(
        plan.predicted_se <= params.launch_target_se * 1.05,
        "{plan:?}"
    );
    assert!(plan.sun_spacing_m < 0.125);
    // 2A/L of the 12-gons ≈ 0.048 m → D = ceil(0.5/0.048) = 11, capped at the preset's 8.
    assert_eq!(plan.subcells, 8, "{plan:?}");
    assert!(plan.sky_spacing_m >= plan.sun_spacing_m);
    let tight = TrackingParams {
        launch_target_se: 1e-9,
        max_launch_points: 10_000,
        ..TrackingParams::dart_default()
    };
    let capped = launch_plan((2.0, 2.0), (0.5, 0.5), &leaves, 2, 50, &tight);
    assert!(capped.capped);
    assert!(capped.sun_n.0 * capped.sun_n.1 <= 10_201, "{capped:?}");
    assert!(16 * capped.subcells * capped.subcells <= 10_000);
}

/// The small-kℓ series and the closed form agree where they meet, and the closed form is the
/// mean of s under k e^{−ks} (checked by quadrature).
#[test]
fn entry_store_follows_the_face_edge_vertex_and_sun_rules() {
    let lo = DVec3::new(0.0, 0.0, 1.0);
    let cell = DVec3::ONE;
    let down = DVec3::new(0.2, 0.0, -1.0).normalize();
    // Sun launch on the scene top (the top face of a top cell): face 5, sub-face from (x, y).
    assert_eq!(
        entry_store(lo, cell, DVec3::new(0.3, 0.8, 2.0), down, 2),
        1 + 5 * 4 + 1
    );
    assert_eq!(
        entry_store(lo, cell, DVec3::new(0.3, 0.8, 2.0), down, 1),
        1 + 5
    );
    // Started inside: store 0; on a face but leaving through it: not an entry.
    assert_eq!(entry_store(lo, cell, DVec3::new(0.5, 0.5, 1.5), down, 2), 0);
    let left = DVec3::new(-0.6, 0.0, 0.8);
    assert_eq!(entry_store(lo, cell, DVec3::new(0.0, 0.5, 1.5), left, 2), 0);
    // Low-x face entered going +x: face 0, sub-face over (y, z).
    let right = DVec3::new(0.8, 0.0, 0.6);
    assert_eq!(
        entry_store(lo, cell, DVec3::new(0.0, 0.7, 1.2), right, 2),
        1 + 2
    );
    // Edge of the low-x and top faces: the larger |d_a| wins, a tie goes to z.
    let q = DVec3::new(0.0, 0.5, 2.0);
    assert_eq!(
        entry_store(lo, cell, q, DVec3::new(0.6, 0.0, -0.8), 1),
        1 + 5
    );
    assert_eq!(entry_store(lo, cell, q, DVec3::new(0.8, 0.0, -0.6), 1), 1);
    let diag = DVec3::new(1.0, 0.0, -1.0).normalize();
    assert_eq!(entry_store(lo, cell, q, diag, 1), 1 + 5);
    // Vertex, equal components: z; then y before x.
    let v = DVec3::new(0.0, 0.0, 2.0);
    assert_eq!(
        entry_store(lo, cell, v, DVec3::new(1.0, 1.0, -1.0).normalize(), 1),
        1 + 5
    );
    assert_eq!(
        entry_store(
            lo,
            cell,
            DVec3::new(0.0, 0.0, 1.5),
            DVec3::new(1.0, 1.0, 0.0).normalize(),
            1
        ),
        1 + 2
    );
    // Within FACE_TOL of the face still counts; a sub-face boundary goes up (floor).
    let q = DVec3::new(0.5, 0.25, 2.0 - 1e-12);
    assert_eq!(entry_store(lo, cell, q, down, 2), 1 + 5 * 4 + 2);
}

#[test]
fn cell_exit_reaches_the_first_face_and_puts_edges_on_both_planes() {
    let lo = DVec3::new(0.0, 0.0, 1.0);
    let cell = DVec3::new(1.0, 2.0, 0.5);
    let o = DVec3::new(0.5, 1.0, 1.25);
    // Straight up: 0.25 m to the top face (face 5), sub-face of the centre (D = 2: (1, 1)).
    let (ell, q, s) = cell_exit(lo, cell, o, DVec3::Z, 2);
    assert!((ell - 0.25).abs() < 1e-15);
    assert_eq!(q, DVec3::new(0.5, 1.0, 1.5));
    assert_eq!(s, 1 + 5 * 4 + 3);
    // Down along −x: bottom at 0.25/0.6 m, −x side at 0.5/0.8 m → bottom (face 4).
    let d = DVec3::new(-0.8, 0.0, -0.6);
    let (ell, q, s) = cell_exit(lo, cell, o, d, 1);
    assert!((ell - 0.25 / 0.6).abs() < 1e-12);
    assert_eq!(q.z, 1.0);
    assert_eq!(s, 1 + 4);
    // Through an edge (x and z planes at the same distance): both coordinates exactly on
    // their planes, the face of the larger |d_a| (z), and the point is on the cell.
    let d = DVec3::new(0.5, 0.0, 0.25).normalize();
    let (ell, q, s) = cell_exit(lo, cell, o, d, 1);
    assert_eq!((q.x, q.z), (1.0, 1.5));
    assert!((ell - (0.5f64.powi(2) + 0.25f64.powi(2)).sqrt()).abs() < 1e-12);
    assert_eq!(s, 1 + 1, "x has the larger component: face +x (1)");
    let d = DVec3::new(0.25, 0.0, 0.25).normalize();
    let o2 = DVec3::new(0.75, 1.0, 1.25);
    let (_, q, s) = cell_exit(lo, cell, o2, d, 1);
    assert_eq!((q.x, q.z), (1.0, 1.5));
    assert_eq!(s, 1 + 5, "tie: the higher axis (z)");
}

#[test]
fn half_barycentres_are_the_means_of_each_half() {
    let (k, ell) = (1.0, 1e-4 * 1.0001);
    let exact = half_barycentres(k, ell);
    let series = (ell * (0.25 - k * ell / 12.0), ell * (0.75 - k * ell / 12.0));
    assert!(
        (exact.0 / series.0 - 1.0).abs() < 1e-6 && (exact.1 / series.1 - 1.0).abs() < 1e-6,
        "{exact:?} {series:?}"
    );
    for (k, ell) in [(0.7, 0.5), (30.0, 1.0), (1e-2, 3.0)] {
        let (s1, s2) = half_barycentres(k, ell);
        let s_half = -((1.0 + (-k * ell).exp()) / 2.0).ln() / k;
        let n = 200_000;
        let (mut m1, mut w1, mut m2, mut w2) = (0.0, 0.0, 0.0, 0.0);
        for i in 0..n {
            let s = (i as f64 + 0.5) / n as f64 * ell;
            let wgt = (-k * s).exp();
            if s < s_half {
                m1 += s * wgt;
                w1 += wgt;
            } else {
                m2 += s * wgt;
                w2 += wgt;
            }
        }
        assert!(
            (s1 - m1 / w1).abs() < 1e-4 * ell && (s2 - m2 / w2).abs() < 1e-4 * ell,
            "k {k}: {s1} {s2} vs {} {}",
            m1 / w1,
            m2 / w2
        );
        assert!(
            (w1 - w2).abs() < 1e-3 * (w1 + w2),
            "halves carry equal energy"
        );
    }
}

#[test]
fn tabulated_half_barycentres_match_the_closed_form() {
    let mut worst: f64 = 0.0;
    for i in 0..20_000 {
        let x = 1e-5 * (1e7f64).powf(i as f64 / 19_999.0);
        let (a, b) = half_barycentres(x, 1.0);
        let (c, d) = half_barycentres_fast(x, 1.0);
        worst = worst.max((a - c).abs()).max((b - d).abs());
    }
    assert!(worst < 1e-6, "worst |Δs|/ℓ = {worst:e}");
}

/// The maximum-entropy spread recovers the standard deviation of a Beer's-law interception
/// density from its mean (checked against direct quadrature of `u e^{−ux}/(1 − e^{−u})`), is
/// 1/√12 for a centred mean and symmetric about ½.
#[test]
fn max_entropy_sigma_recovers_beer_law_spread() {
    for u in [1e-6, 0.01, 0.3, 1.0, 3.0, 10.0, 50.0, 300.0] {
        let n = 200_000;
        let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let x = (i as f64 + 0.5) / n as f64;
            let f = (-u * x).exp();
            s0 += f;
            s1 += f * x;
            s2 += f * x * x;
        }
        let m = s1 / s0;
        let sd = (s2 / s0 - m * m).sqrt();
        let got = max_entropy_sigma(m);
        assert!((got / sd - 1.0).abs() < 1e-4, "u {u}: {got} vs {sd}");
        assert!(
            (max_entropy_sigma(1.0 - m) / got - 1.0).abs() < 1e-13,
            "symmetry at u {u}"
        );
        // Continuous: a relative change of 1e-13 in the mean moves σ by O(1e-13).
        let near = max_entropy_sigma(m * (1.0 + 1e-13));
        assert!(
            (near / got - 1.0).abs() < 1e-11,
            "u {u}: σ jumps ({near} vs {got})"
        );
    }
    assert!((max_entropy_sigma(0.5) - (1.0f64 / 12.0).sqrt()).abs() < 1e-15);
    for m in [
        0.0,
        1e-300,
        1e-12,
        1.0,
        1.0 - 1e-16,
        -1.0,
        2.0,
        f64::MIN_POSITIVE,
    ] {
        let s = max_entropy_sigma(m);
        assert!(s.is_finite() && (0.0..1e-6).contains(&s), "m {m}: {s}");
    }
}

/// The exponential-moment position reproduces ⟨e^{cx}⟩ of the maximum-entropy density
/// (direct quadrature), tends to the mean for c → 0 and to the support's ends for |c| → ∞,
/// and stays finite for extreme inputs.
#[test]
fn exp_moment_position_matches_the_exponential_moment() {
    for u in [0.0, 1e-6, 0.3, 2.0, 30.0, -5.0] {
        for c in [-50.0, -4.8, -0.5, 1e-12, 0.7, 4.8, 60.0] {
            let n = 400_000;
            let (mut z0, mut z1, mut ze) = (0.0f64, 0.0, 0.0);
            for i in 0..n {
                let x = (i as f64 + 0.5) / n as f64;
                let f = (-u * x).exp();
                z0 += f;
                z1 += f * x;
                ze += f * (c * x).exp();
            }
            let m = z1 / z0;
            let x = exp_moment_position(m, c);
            let got = (c * x).exp();
            let want = ze / z0;
            assert!(
                (got / want - 1.0).abs() < 1e-4,
                "u {u} c {c}: {got} vs {want}"
            );
        }
    }
    assert!((exp_moment_position(0.3, 0.0) - 0.3).abs() < 1e-9);
    assert!(exp_moment_position(0.5, 1e9) > 0.9999);
    assert!(exp_moment_position(0.5, -1e9) < 1e-4);
    for m in [0.0, 1.0, 1e-300, -3.0, 7.0] {
        for c in [0.0, -1e300, 1e300, 3.0] {
            let x = exp_moment_position(m, c);
            assert!((0.0..=1.0).contains(&x), "m {m} c {c}: {x}");
        }
    }
}

/// The return of a monostatic LiDAR: a separation at rounding level (the reversed flight
/// recomputed from positions, 1 ulp off) is an exact backscatter (`c = 0`, one-way
/// transmittance), while a true separation keeps its decorrelation `2|d_out + d_in|/(l ΣG)`.
#[test]
fn hotspot_path_rounding_is_exact_backscatter() {
    let d_in = DVec3::new(
        -1.3833974432568404e-7,
        1.2666272291392999e-8,
        -0.9999999999999905,
    );
    let d_out = DVec3::new(
        1.3833974432568264e-7,
        -1.2666272291392266e-8,
        0.9999999999999903,
    );
    let sep = (d_out + d_in).length();
    assert!(sep > 0.0 && sep <= BACKSCATTER_ROUNDING, "{sep:e}");
    assert_eq!(hotspot_terms_path(d_in, d_out, 0.5, 0.5, 0.01), [0.5, 0.0]);
    assert_eq!(hotspot_terms_path(d_in, -d_in, 0.5, 0.5, 0.01), [0.5, 0.0]);
    // 1e-6 rad off the reversed flight: c = 2e-6 / (0.01 × 1) m⁻¹.
    let tilted = (-d_in + DVec3::new(1e-6, 0.0, 0.0)).normalize();
    let [b, c] = hotspot_terms_path(d_in, tilted, 0.5, 0.5, 0.01);
    assert_eq!(b, 0.5);
    assert!((c - 2.0 * (tilted + d_in).length() / 0.01).abs() <= 1e-12 * c && c > 1.9e-4);
    assert_eq!(hotspot_terms_path(d_in, d_out, 0.5, 0.5, 0.0), [0.0, 0.0]);
}
