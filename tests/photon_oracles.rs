//! Photon stage (Monte Carlo solver) against exact oracles: DISORT turbid canopy and fluid
//! slabs (assets/reference), the flat Lambertian ground, Beer's-law gap fractions; cross-check
//! with the flux-tracking solver; energy closure, hard cases and determinism.
//!
//! Statistical tests are z-tests with a fixed seed: |MC − exact| ≤ Z·SE, Z = 4 (two-sided
//! false-alarm rate 6.3e-5 per comparison, < 1 % over the ~150 comparisons of this file, for a
//! seed drawn at random; the seeds are fixed, so the outcome is reproducible). Each test also
//! asserts that the standard errors are small enough for the comparison to mean something.

mod common;
use common::*;
use glam::DVec3;
use lumenscape::direction::{DirectionParams, DirectionSet, ExactDirection};
use lumenscape::photon::engine::*;
use lumenscape::physics::phase::FluidPhase;
use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::grid::{CellGrid, GridSpec};
use lumenscape::resources::scene::{RunSettings, Solver};
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::*;
use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
use lumenscape::scene::generators::{BandOptics, principal_plane_directions};
use lumenscape::simulation::Simulation;

const Z: f64 = 4.0;

fn run_mc(desc: &SceneDesc, photons: u64, sampler: SamplerKind) -> RadiativeProducts {
    let settings = RunSettings {
        solver: Solver::MonteCarlo { photons, sampler },
        ..Default::default()
    };
    let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), settings)
        .unwrap_or_else(|e| panic!("{e}"));
    sim.run(None).unwrap_or_else(|e| panic!("{e}"));
    sim.resource::<RadiativeProducts>().clone()
}

fn run_ft(desc: &SceneDesc, preset: Preset) -> RadiativeProducts {
    let settings = RunSettings {
        preset: Some(preset),
        ..Default::default()
    };
    let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), settings)
        .unwrap_or_else(|e| panic!("{e}"));
    sim.run(None).unwrap_or_else(|e| panic!("{e}"));
    sim.resource::<RadiativeProducts>().clone()
}

fn assert_closes(p: &RadiativeProducts, what: &str) {
    for b in &p.bands {
        assert!(
            b.energy_closure <= 1e-9,
            "{what}: band {} energy closure {:e}",
            b.band,
            b.energy_closure
        );
        assert!(
            b.albedo.is_finite() && b.fabs.is_finite() && b.ftran.is_finite(),
            "{what}: NaN in {b:?}"
        );
        for e in &b.brf {
            assert!(
                e.brf.is_finite() && e.brf_se.is_some_and(f64::is_finite),
                "{what}: BRF {e:?}"
            );
        }
    }
}

/// Principal-plane directions only (11 views), to keep peel-off cost down.
fn layer(lai: f64, sza: f64, bands: Vec<BandOptics>) -> SceneDesc {
    let mut d = turbid_layer(&TurbidLayerParams {
        lai,
        lad: LadDesc::Spherical,
        bands,
        height_m: 2.0,
        cell_m: 1.0,
        size_m: 1.0,
        sun_zenith_deg: sza,
        sun_azimuth_deg: 0.0,
    });
    no_hotspot(&mut d);
    d.directions = Some(principal_plane_directions(0.0));
    d
}

fn brf_pp(p: &RadiativeProducts, b: usize, vz: f64) -> (f64, f64) {
    let az = if vz >= 0.0 { 0.0 } else { 180.0 };
    let e = p.brf_at(b, vz.abs(), az).unwrap();
    assert!((e.zenith_deg - vz.abs()).abs() < 1e-9, "view {vz} missing");
    assert_eq!(e.estimator, Some("peel-off"));
    (e.brf, e.brf_se.unwrap())
}

#[test]
fn continuous_monte_carlo_matches_disort_turbid_canopy() {
    let rows = disort_rows();
    let (mut worst_z, mut worst_rel, mut worst_se): (f64, f64, f64) = (0.0, 0.0, 0.0);
    for lai in [1.0, 3.0] {
        for sza in [0.0, 20.0] {
            let p = run_mc(
                &layer(lai, sza, vec![BandOptics::red(), BandOptics::nir()]),
                200_000,
                SamplerKind::Continuous,
            );
            assert_closes(&p, "disort layer");
            for (b, band) in ["red", "nir"].iter().enumerate() {
                let bp = &p.bands[b];
                for r in rows.iter().filter(|r| {
                    r[0].parse::<f64>().unwrap() == lai
                        && r[1] == *band
                        && r[2].parse::<f64>().unwrap() == sza
                }) {
                    let vz: f64 = r[3].parse().unwrap();
                    let want: f64 = r[4].parse().unwrap();
                    let (got, se) = brf_pp(&p, b, vz);
                    let z = (got - want).abs() / se;
                    worst_z = worst_z.max(z);
                    worst_rel = worst_rel.max((got / want - 1.0).abs());
                    worst_se = worst_se.max(se / want);
                    assert!(
                        z <= Z,
                        "LAI {lai} sza {sza} {band} vz {vz}: BRF {got} ± {se} vs DISORT {want} (z = {z:.2})"
                    );
                    assert!(se < 0.02 * want, "SE {se} too large for {want}");
                    let alb: f64 = r[5].parse().unwrap();
                    let za = (bp.albedo - alb).abs() / bp.albedo_se.unwrap();
                    assert!(za <= Z, "albedo {} vs {alb} (z = {za:.2})", bp.albedo);
                    let tran: f64 = r[6].parse::<f64>().unwrap() + r[7].parse::<f64>().unwrap();
                    let zt = (bp.ftran - tran).abs() / bp.ftran_se.unwrap();
                    assert!(zt <= Z, "ftran {} vs {tran} (z = {zt:.2})", bp.ftran);
                    let abs_c: f64 = r[8].parse().unwrap();
                    let zc = (bp.fabs - abs_c).abs() / bp.fabs_se.unwrap();
                    assert!(zc <= Z, "fabs {} vs {abs_c} (z = {zc:.2})", bp.fabs);
                }
            }
        }
    }
    eprintln!(
        "continuous MC vs DISORT canopy: worst |z| {worst_z:.2}, worst relative error {:.3} %, worst relative SE {:.3} %",
        100.0 * worst_rel,
        100.0 * worst_se
    );
}

#[test]
fn flat_lambertian_ground_is_exact_in_monte_carlo() {
    for (sza, skyl) in [(30.0, 0.0), (75.0, 0.3), (89.0, 0.0)] {
        let mut d = base_scene((4.0, 4.0), (1.0, 1.0, 1.0), BoundaryMode::Repetitive);
        d.objects.push(flat_ground());
        d.illumination.sun_zenith_deg = Some(sza);
        if skyl > 0.0 {
            d.illumination.skyl = vec![skyl];
        }
        d.directions = Some(lumenscape::scene::generators::rami_directions(0.0));
        let p = run_mc(&d, 20_000, SamplerKind::Continuous);
        assert_closes(&p, "ground");
        let b = &p.bands[0];
        // Every photon reaches the ground and leaves with weight ρ: albedo = ρ exactly, and
        // the peel-off estimate ρ μ_v/π is the same for every photon.
        assert!((b.albedo - 0.1).abs() < 1e-9, "albedo {}", b.albedo);
        for e in b.brf.iter().filter(|e| e.estimator == Some("peel-off")) {
            assert!((e.brf - 0.1).abs() < 1e-9, "sza {sza}: {e:?}");
            if let Some(h) = e.hdrf {
                assert!((h - 0.1).abs() < 1e-9, "HDRF {h}");
            }
        }
    }
}

#[test]
fn black_leaves_transmit_by_beers_law() {
    for lai in [1.0, 3.0] {
        let mut d = layer(
            lai,
            30.0,
            vec![BandOptics {
                leaf_r: 0.0,
                leaf_t: 0.0,
                ..BandOptics::red()
            }],
        );
        d.directions = Some(DirectionParams::default());
        let p = run_mc(&d, 100_000, SamplerKind::Continuous);
        assert_closes(&p, "black leaves");
        let b = &p.bands[0];
        let want = (-0.5 * lai / 30f64.to_radians().cos()).exp();
        let z = (b.ftran - want).abs() / b.ftran_se.unwrap();
        assert!(
            z <= Z,
            "LAI {lai}: ftran {} ± {:?} vs {want}",
            b.ftran,
            b.ftran_se
        );
        assert!(b.ftran_se.unwrap() < 0.01 * want);
    }
}

/// A plane-parallel fluid slab of optical depth `tau` (1 m thick, 1 km wide periodic cell)
/// over a Lambertian ground, run through the engine directly.
fn slab(
    tau: f64,
    ssa: f64,
    phase: FluidPhase,
    ground: f64,
    sza: f64,
    views: &[(f64, f64)],
    photons: u64,
    k_points: u32,
) -> (Vec<f64>, Vec<f64>) {
    let spec = GridSpec {
        n: [1, 1, 1],
        cell: DVec3::new(1000.0, 1000.0, 1.0),
        origin: DVec3::ZERO,
        subcells: 1,
        boundary: BoundaryMode::Repetitive,
        topography_offset: (0.0, 0.0),
    };
    let grid = CellGrid {
        turbid_start: vec![0, 0],
        turbid: vec![],
        facet_start: vec![0, 0],
        facet_ids: vec![],
    };
    let fluid = FluidField {
        cell: vec![0],
        materials: vec![FluidMaterial {
            sigma_e: vec![tau],
            ssa: vec![ssa],
            phase,
        }],
    };
    let dirs = DirectionSet::with_count(100).unwrap();
    let optics = vec![PhotonOptics::Lambert {
        r: vec![ground],
        t: vec![0.0],
        t_dir: vec![0.0],
    }];
    let sun_pos = lumenscape::direction::direction_from_deg(sza, 0.0);
    let input = PhotonInput {
        spec: &spec,
        grid: &grid,
        facets: &[],
        ground_facet: &[],
        dirs: &dirs,
        optics: &optics,
        fluid: Some(&fluid),
        atmosphere: None,
        flat_ground: Some(0),
        views: views
            .iter()
            .map(|&(z, a)| lumenscape::direction::direction_from_deg(z, a))
            .collect(),
        cameras: Vec::new(),
        sun: -sun_pos,
        e_dir: vec![1.0],
        e_diff: vec![0.0],
        thermal: None,
        params: PhotonParams {
            fluid_peel_points: k_points,
            ..PhotonParams::new(photons, 11, SamplerKind::Continuous)
        },
    };
    let r = run(&input);
    let area = 1e6;
    let mut brf = Vec::new();
    let mut se = Vec::new();
    for (v, &(z, _)) in views.iter().enumerate() {
        let f = std::f64::consts::PI / (area * z.to_radians().cos());
        brf.push(r.peel[v] * f);
        se.push(sum_standard_error(&r.batch_summaries, r.summary.view(v, 0)) * f);
    }
    (brf, se)
}

#[test]
fn fluid_slabs_match_disort() {
    let text = std::fs::read_to_string(asset("assets/reference/disort_slabs.csv")).unwrap();
    let rows: Vec<Vec<String>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    let mut worst_z: f64 = 0.0;
    let mut worst_rel: f64 = 0.0;
    let mut n = 0;
    for case in [
        "iso_ssa0.9_tau0.1_black",
        "iso_ssa0.9_tau1_black",
        "iso_ssa0.99_tau1_black",
        "iso_ssa0.99_tau10_black",
        "iso_ssa0.9_deep_tau100_black",
        "rayleigh_tau0.1_lamb0.2",
        "rayleigh_tau0.3_lamb0.2",
    ] {
        for sza in [30.0, 60.0] {
            let sel: Vec<&Vec<String>> = rows
                .iter()
                .filter(|r| {
                    r[0] == case
                        && r[6].parse::<f64>().unwrap() == sza
                        && [0.0, 30.0, 60.0].contains(&r[7].parse::<f64>().unwrap())
                        && [0.0, 180.0].contains(&r[9].parse::<f64>().unwrap())
                })
                .collect();
            assert!(!sel.is_empty(), "{case} sza {sza}: no rows");
            let r0 = sel[0];
            let phase = match r0[1].as_str() {
                "isotropic" => FluidPhase::Isotropic,
                "rayleigh" => FluidPhase::Rayleigh {
                    depolarization: 0.0,
                },
                other => panic!("phase {other}"),
            };
            let ssa: f64 = r0[3].parse().unwrap();
            let tau: f64 = r0[4].parse().unwrap();
            let ground: f64 = r0[5].parse().unwrap();
            // relaz_backscatter0 = 0: viewer on the sun side (view azimuth = sun azimuth 0).
            let views: Vec<(f64, f64)> = sel
                .iter()
                .map(|r| (r[7].parse().unwrap(), r[9].parse().unwrap()))
                .collect();
            // K = 0: peel-off at the actual collisions; K = 4: DART's K points per crossing of
            // a fluid cell (forced, expected-value estimate).
            let mut se_k = [0.0; 2];
            for (ik, k) in [0u32, 4].into_iter().enumerate() {
                let (brf, se) = slab(tau, ssa, phase, ground, sza, &views, 50_000, k);
                for (i, r) in sel.iter().enumerate() {
                    let want: f64 = r[10].parse().unwrap();
                    let z = (brf[i] - want).abs() / se[i];
                    worst_z = worst_z.max(z);
                    worst_rel = worst_rel.max((brf[i] / want - 1.0).abs());
                    n += 1;
                    se_k[ik] += se[i] / want;
                    assert!(
                        z <= Z,
                        "{case} K {k} sza {sza} view {:?}: BRF {} ± {} vs DISORT {want} (z {z:.2})",
                        views[i],
                        brf[i],
                        se[i]
                    );
                    assert!(se[i] < 0.03 * want, "{case}: SE {} vs {want}", se[i]);
                }
            }
            eprintln!(
                "{case} sza {sza}: mean relative SE {:.3} % (K = 0) vs {:.3} % (K = 4)",
                100.0 * se_k[0] / sel.len() as f64,
                100.0 * se_k[1] / sel.len() as f64
            );
        }
    }
    eprintln!(
        "fluid slabs: {n} BRFs, worst |z| = {worst_z:.2}, worst relative error {:.3} %",
        100.0 * worst_rel
    );
}

#[test]
fn monte_carlo_is_bit_identical_on_1_2_and_8_threads() {
    let mut d = small_forest();
    d.directions = Some(principal_plane_directions(225.0));
    let run_with = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| run_mc(&d, 20_000, SamplerKind::Continuous))
    };
    let a = run_with(1);
    assert_closes(&a, "forest");
    for t in [2, 8] {
        let b = run_with(t);
        for (x, y) in a.bands.iter().zip(&b.bands) {
            assert_eq!(x.albedo.to_bits(), y.albedo.to_bits(), "{t} threads");
            assert_eq!(x.fabs.to_bits(), y.fabs.to_bits());
            for (e, f) in x.brf.iter().zip(&y.brf) {
                assert_eq!(e.brf.to_bits(), f.brf.to_bits());
                assert_eq!(e.brf_se.map(f64::to_bits), f.brf_se.map(f64::to_bits));
            }
        }
        assert_eq!(a.raw.absorbed_turbid, b.raw.absorbed_turbid);
        assert_eq!(a.raw.absorbed_facet, b.raw.absorbed_facet);
    }
}

/// Worst |FT − MC| over the peel-off BRFs, relative to MC, and in units of the MC SE.
fn compare(ft: &RadiativeProducts, mc: &RadiativeProducts) -> (f64, f64, f64) {
    let (mut rel, mut z, mut alb): (f64, f64, f64) = (0.0, 0.0, 0.0);
    for (b, (bp, bq)) in mc.bands.iter().zip(&ft.bands).enumerate() {
        alb = alb.max((bq.albedo / bp.albedo - 1.0).abs());
        for e in bp.brf.iter().filter(|e| e.estimator == Some("peel-off")) {
            // Direction sets differ between presets: match exact directions by direction.
            let f = ft.brf_at(b, e.zenith_deg, e.azimuth_deg).unwrap();
            assert!((f.zenith_deg - e.zenith_deg).abs() < 1e-9);
            {
                rel = rel.max((f.brf / e.brf - 1.0).abs());
                z = z.max((e.brf - f.brf).abs() / e.brf_se.unwrap());
            }
        }
    }
    (rel, z, alb)
}

/// The cross-check: flux tracking and continuous Monte Carlo agree within 3σ + the
/// flux-tracking discretisation error. δ = 5 % is what `cargo bench --bench radiative` reports
/// for the default preset (100 directions) at 0.5 m cells against DISORT (worst BRF 5.0 %), so
/// the forest runs at 0.5 m cells. Measured: worst 2.9 % (MC at 100 000 photons).
#[test]
fn flux_tracking_and_monte_carlo_agree_on_a_small_forest() {
    const DELTA: f64 = 0.05;
    let mut d = small_forest();
    d.grid.cell_m = (0.5, 0.5, 0.5);
    d.directions = Some(principal_plane_directions(
        d.illumination.sun_azimuth_deg.unwrap_or(0.0),
    ));
    let mc = run_mc(&d, 100_000, SamplerKind::Continuous);
    assert_closes(&mc, "small forest MC");
    let ft = run_ft(&d, Preset::Default);
    let mut n = 0;
    for (b, bp) in mc.bands.iter().enumerate() {
        for e in bp.brf.iter().filter(|e| e.estimator == Some("peel-off")) {
            let f = ft.brf_at(b, e.zenith_deg, e.azimuth_deg).unwrap();
            assert!((f.zenith_deg - e.zenith_deg).abs() < 1e-9);
            let se = e.brf_se.unwrap();
            assert!(se < 0.01 * e.brf, "SE {se} too large");
            let tol = 3.0 * se + DELTA * e.brf;
            assert!(
                (f.brf - e.brf).abs() <= tol,
                "{} view {:.0}/{:.0}: flux tracking {} vs Monte Carlo {} ± {se}",
                bp.band,
                e.zenith_deg,
                e.azimuth_deg,
                f.brf,
                e.brf
            );
            n += 1;
        }
    }
    assert_eq!(n, 22);
    let (rel, z, alb) = compare(&ft, &mc);
    eprintln!(
        "small forest (0.5 m cells), default preset vs MC: worst BRF difference {:.2} % ({z:.1} σ), albedo {:.2} %",
        100.0 * rel,
        100.0 * alb
    );
}

#[test]
fn discrete_ray_carlo_samplers_match_disort_within_the_angular_discretisation() {
    let rows = disort_rows();
    for sampler in [
        SamplerKind::Alias,
        SamplerKind::Box {
            gamma: 2.0,
            max_boxes: 4096,
        },
    ] {
        let p = run_mc(
            &layer(3.0, 20.0, vec![BandOptics::red(), BandOptics::nir()]),
            200_000,
            sampler,
        );
        assert_closes(&p, "discrete");
        let (mut worst, mut worst_alb): (f64, f64) = (0.0, 0.0);
        for (b, band) in ["red", "nir"].iter().enumerate() {
            for r in rows
                .iter()
                .filter(|r| r[0] == "3" && r[1] == *band && r[2] == "20")
            {
                let vz: f64 = r[3].parse().unwrap();
                let want: f64 = r[4].parse().unwrap();
                let (got, se) = brf_pp(&p, b, vz);
                worst = worst.max(((got - want).abs() - 3.0 * se).max(0.0) / want);
                let alb: f64 = r[5].parse().unwrap();
                worst_alb = worst_alb.max((p.bands[b].albedo / alb - 1.0).abs());
                // Ray-Carlo snaps scattered directions to the 100-direction tiling: allow the
                // default preset's angular discretisation error (δ = 2 %, radiative bench:
                // default preset, 100 directions, 0.2 m cells, worst BRF 2.5 % incl. spatial).
                let tol = |se: f64, v: f64| Z * se + 0.02 * v;
                assert!(
                    (got - want).abs() <= tol(se, want),
                    "{} {band} vz {vz}: {got} ± {se} vs {want}",
                    sampler.name()
                );
                let ab = &p.bands[b];
                assert!(
                    (ab.albedo - alb).abs() <= tol(ab.albedo_se.unwrap(), alb),
                    "{} {band} albedo {} vs {alb}",
                    sampler.name(),
                    ab.albedo
                );
            }
        }
        eprintln!(
            "{}: worst BRF error beyond 3σ {:.2} %, worst albedo error {:.2} %",
            sampler.name(),
            100.0 * worst,
            100.0 * worst_alb
        );
    }
}

#[test]
fn every_example_scene_closes_energy_in_monte_carlo() {
    for name in [
        "default",
        "turbid_layer",
        "disk_canopy",
        "forest_dem",
        "urban",
        "mesh_import",
        "prospect_sentinel2",
    ] {
        let path = asset(&format!("assets/scenes/{name}.ron"));
        let settings = RunSettings {
            solver: Solver::MonteCarlo {
                photons: 5_000,
                sampler: SamplerKind::Continuous,
            },
            ..Default::default()
        };
        let mut sim = Simulation::load(&path, settings).unwrap_or_else(|e| panic!("{e}"));
        sim.run(None).unwrap_or_else(|e| panic!("{name}: {e}"));
        let p = sim.resource::<RadiativeProducts>();
        assert_eq!(p.solver, "monte-carlo");
        assert_closes(p, name);
    }
}

#[test]
fn hard_cases_stay_finite_and_closed_in_monte_carlo() {
    // Grazing sun and views, leaf albedo near 1, very dense cells, tiny cells.
    let grazing = {
        let mut d = layer(3.0, 89.0, vec![BandOptics::nir()]);
        let mut p = principal_plane_directions(0.0);
        p.exact.push(ExactDirection::new(89.0, 0.0));
        d.directions = Some(p);
        d
    };
    let white = layer(
        3.0,
        30.0,
        vec![BandOptics {
            leaf_r: 0.5,
            leaf_t: 0.499,
            soil_r: 0.999,
            ..BandOptics::nir()
        }],
    );
    let dense = turbid_layer(&TurbidLayerParams {
        lai: 100.0,
        lad: LadDesc::Planophile,
        bands: vec![BandOptics::nir()],
        height_m: 2.0,
        cell_m: 0.5,
        size_m: 1.0,
        sun_zenith_deg: 45.0,
        sun_azimuth_deg: 30.0,
    });
    let tiny = turbid_layer(&TurbidLayerParams {
        lai: 2.0,
        lad: LadDesc::Erectophile,
        bands: vec![BandOptics::red()],
        height_m: 0.02,
        cell_m: 0.002,
        size_m: 0.01,
        sun_zenith_deg: 0.0,
        sun_azimuth_deg: 0.0,
    });
    for (what, d) in [
        ("grazing", grazing),
        ("albedo 0.999", white),
        ("u_f 50", dense),
        ("2 mm cells", tiny),
    ] {
        let t0 = std::time::Instant::now();
        let p = run_mc(&d, 20_000, SamplerKind::Continuous);
        eprintln!(
            "{what}: {:.1} s, {} events",
            t0.elapsed().as_secs_f64(),
            p.monte_carlo.as_ref().unwrap().events
        );
        assert_closes(&p, what);
        let mc = p.monte_carlo.as_ref().unwrap();
        for (b, bp) in p.bands.iter().enumerate() {
            // The roulette balance has expectation 0: it must stay within noise.
            assert!(
                mc.roulette_balance[b].abs() < 0.02,
                "{what}: roulette balance {}",
                mc.roulette_balance[b]
            );
            assert!(
                bp.albedo >= 0.0 && bp.albedo <= 1.0 + 1e-9,
                "{what}: {bp:?}"
            );
        }
    }
}

/// Reciprocity (physics.md §13 test 7): a horizontally homogeneous turbid layer over a
/// Lambertian soil has BRF(Ω_s → Ω_v) = BRF(Ω_v → Ω_s), for any LAD and all orders. Exercises
/// the exact leaf sampler and the one-leaf peel-off estimator of non-spherical LADs.
#[test]
fn monte_carlo_brf_is_reciprocal_for_non_spherical_lads() {
    for lad in [LadDesc::Planophile, LadDesc::Erectophile] {
        let run_pair = |s: (f64, f64), v: (f64, f64)| {
            let mut d = turbid_layer(&TurbidLayerParams {
                lai: 2.0,
                lad: lad.clone(),
                bands: vec![BandOptics::nir()],
                height_m: 2.0,
                cell_m: 1.0,
                size_m: 1.0,
                sun_zenith_deg: s.0,
                sun_azimuth_deg: s.1,
            });
            d.directions = Some(DirectionParams {
                exact: vec![ExactDirection::new(v.0, v.1)],
                ..DirectionParams::default()
            });
            let p = run_mc(&d, 200_000, SamplerKind::Continuous);
            let e = p.brf_at(0, v.0, v.1).unwrap().clone();
            assert_eq!(e.estimator, Some("peel-off"));
            (e.brf, e.brf_se.unwrap())
        };
        let (a, sa) = run_pair((30.0, 0.0), (60.0, 135.0));
        let (b, sb) = run_pair((60.0, 135.0), (30.0, 0.0));
        let z = (a - b).abs() / (sa * sa + sb * sb).sqrt();
        eprintln!("{lad:?}: BRF {a:.5} ± {sa:.5} vs reciprocal {b:.5} ± {sb:.5} (z {z:.2})");
        assert!(z <= Z, "{lad:?}: reciprocity broken: {a} vs {b}");
        assert!(sa < 0.01 * a && sb < 0.01 * b);
    }
}

/// Facet geometry against an independent ray cast: the direct transmittance (gap fraction) of
/// the shipped disk canopy with black leaves equals the fraction of random sun rays that miss
/// every disk, computed here by brute force against the true circular disks (3 × 4 periodic
/// copies), independently of the engine's grid, DDA and triangles. z-test on the difference
/// (the 12-gon leaves have the disks' exact area; their shape difference is far below the SE).
#[test]
fn disk_canopy_gap_fraction_matches_an_independent_ray_cast() {
    let desc = black_disk_canopy();
    let p = run_mc(&desc, 100_000, SamplerKind::Continuous);
    let b = &p.bands[0];
    let (gap, se_gap) = disk_canopy_gap_fraction(&desc, 40_000);
    let se = (se_gap.powi(2) + b.ftran_se.unwrap().powi(2)).sqrt();
    let z = (b.ftran - gap).abs() / se;
    eprintln!(
        "disk canopy gap fraction: MC {:.4} ± {:.4}, independent ray cast {gap:.4} ± {se_gap:.4} (z {z:.2})",
        b.ftran,
        b.ftran_se.unwrap()
    );
    assert!(z <= Z);
}

/// Small facets (the shipped disk canopy: r = 5 cm discs, 0.25 m cells): flux tracking with
/// the default preset — launch grid and sub-cell scattering points chosen from the facet size
/// (`radiative::engine::launch_plan`) — agrees with continuous Monte Carlo in the exact
/// principal-plane directions within 3σ + δ, δ = 5 % as for the small forest above. Measured
/// (release, 2 M photons): worst 4.3 %, rms 2.2 % (D = 6); D = 12 gives 2.1 % / 0.8 %. The former
/// fixed cell/4 launch grid and D = 2 erred by up to 21 % (exact) and 41 % (sectors).
#[test]
fn flux_tracking_and_monte_carlo_agree_on_the_disk_canopy() {
    const DELTA: f64 = 0.05;
    let mut d = lumenscape::scene::load_scene(&asset("assets/scenes/disk_canopy.ron"))
        .unwrap()
        .0;
    d.directions = Some(principal_plane_directions(
        d.illumination.sun_azimuth_deg.unwrap_or(0.0),
    ));
    let mc = run_mc(&d, 400_000, SamplerKind::Continuous);
    let ft = run_ft(&d, Preset::Default);
    let mut worst: f64 = 0.0;
    let mut n = 0;
    for e in mc.bands[0]
        .brf
        .iter()
        .filter(|e| e.estimator == Some("peel-off"))
    {
        let f = ft.brf_at(0, e.zenith_deg, e.azimuth_deg).unwrap();
        assert!((f.zenith_deg - e.zenith_deg).abs() < 1e-9);
        let se = e.brf_se.unwrap();
        assert!(se < 0.01 * e.brf, "SE {se} too large");
        worst = worst.max((f.brf - e.brf).abs() / e.brf);
        assert!(
            (f.brf - e.brf).abs() <= 3.0 * se + DELTA * e.brf,
            "view {:.0}/{:.0}: flux tracking {} vs Monte Carlo {} ± {se}",
            e.zenith_deg,
            e.azimuth_deg,
            f.brf,
            e.brf
        );
        n += 1;
    }
    assert_eq!(n, 11);
    eprintln!(
        "disk canopy, default preset vs MC: worst exact-direction BRF difference {:.2} %",
        100.0 * worst
    );
}

/// `run --solver monte-carlo` writes the Radiative products with standard errors.
#[test]
fn monte_carlo_products_carry_standard_errors() {
    let out = std::env::temp_dir().join(format!("lumenscape-mc-{}", std::process::id()));
    let mut d = layer(1.0, 20.0, vec![BandOptics::red()]);
    d.illumination.skyl = vec![0.2];
    let settings = RunSettings {
        solver: Solver::MonteCarlo {
            photons: 5_000,
            sampler: SamplerKind::Continuous,
        },
        ..Default::default()
    };
    let mut sim = Simulation::from_desc(&d, &SceneSource::generated(), settings).unwrap();
    sim.run(Some(&out)).unwrap();
    let csv = std::fs::read_to_string(out.join("brf.csv")).unwrap();
    assert!(
        csv.starts_with(
            "band,zenith_deg,azimuth_deg,solid_angle_sr,kind,brf,hdrf,brf_se,hdrf_se,estimator\n"
        ),
        "{}",
        csv.lines().next().unwrap()
    );
    assert!(csv.contains(",peel-off\n") && csv.contains(",escape\n"));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["solver"], "monte-carlo");
    assert_eq!(s["monte_carlo"]["photons"], 5_056); // 64 batches of 79
    let band = &s["bands"][0];
    for k in ["albedo_se", "fabs_se", "ftran_se"] {
        assert!(band[k].as_f64().is_some_and(|x| x > 0.0), "{k}: {band}");
    }
    assert!(band["brf"][0]["brf_se"].as_f64().is_some());
    assert!(band["brf"][0]["hdrf_se"].as_f64().is_some());
    std::fs::remove_dir_all(&out).ok();
}

/// The RAMI components add up, and single scattering matches the closed form of physics.md
/// §3.4 (§13 test 4: spherical LAD, ρ = τ = 0.45, LAI 1 and 3, black soil, sun 30°).
#[test]
fn single_scattering_component_matches_the_closed_form() {
    for (lai, rows) in [
        (
            1.0,
            [
                (0.0, 0.0, 0.09497),
                (30.0, 0.0, 0.11862),
                (30.0, 180.0, 0.08517),
            ],
        ),
        (
            3.0,
            [
                (0.0, 0.0, 0.13831),
                (30.0, 0.0, 0.16778),
                (30.0, 180.0, 0.12047),
            ],
        ),
    ] {
        let mut d = turbid_layer(&TurbidLayerParams {
            lai,
            lad: LadDesc::Spherical,
            bands: vec![BandOptics {
                leaf_r: 0.45,
                leaf_t: 0.45,
                soil_r: 0.0,
                ..BandOptics::nir()
            }],
            height_m: 2.0,
            cell_m: 1.0,
            size_m: 1.0,
            sun_zenith_deg: 30.0,
            sun_azimuth_deg: 0.0,
        });
        no_hotspot(&mut d);
        d.directions = Some(DirectionParams {
            exact: rows.iter().map(|r| ExactDirection::new(r.0, r.1)).collect(),
            ..DirectionParams::default()
        });
        let p = run_mc(&d, 100_000, SamplerKind::Continuous);
        for (vz, az, want) in rows {
            let e = p.brf_at(0, vz, az).unwrap();
            let (co, uc, mlt) = (
                e.brf_co_sgl.unwrap(),
                e.brf_uc_sgl.unwrap(),
                e.brf_mlt.unwrap(),
            );
            assert!((co + uc + mlt - e.brf).abs() < 1e-12 * e.brf.max(1e-300) + 1e-15);
            assert_eq!(uc, 0.0, "black soil");
            let se = e.brf_components_se.unwrap()[0];
            assert!(se > 0.0 && se < 0.01 * want);
            let z = (co - want).abs() / se;
            assert!(
                z <= Z,
                "LAI {lai} view {vz}/{az}: BRF1 {co} vs {want} (z {z:.2})"
            );
        }
    }
}

/// Convergence study (ignored: ~3 min in release, `cargo test --release --test photon_oracles
/// -- --ignored disk_canopy_albedo`): the flux-tracking albedo of the disk canopy converges to
/// the continuous Monte Carlo albedo as the number of discrete directions grows, so the default
/// preset's −1.6 % albedo gap is the angular discretisation of 100 directions, not a bias.
/// Measured 2026-11-25 (MC 2 M photons 0.045207 ± 0.000028): 100 dirs 0.044470 (−1.63 %), 400
/// 0.044960 (−0.55 %), 1000 0.045130 (−0.17 %), 2000 0.045191 (−0.04 %). Asserted: the error
/// shrinks at each step, and with 2000 directions it is within 3σ + 0.1 % of Monte Carlo.
#[test]
#[ignore]
fn disk_canopy_albedo_converges_to_monte_carlo_with_directions() {
    let d0 = lumenscape::scene::load_scene(&asset("assets/scenes/disk_canopy.ron"))
        .unwrap()
        .0;
    let mc = run_mc(&d0, 2_000_000, SamplerKind::Continuous);
    let (want, se) = (mc.bands[0].albedo, mc.bands[0].albedo_se.unwrap());
    let mut last = f64::INFINITY;
    for n in [100, 400, 2000] {
        let mut d = d0.clone();
        let mut p = d.directions.clone().unwrap_or_default();
        p.count = n;
        d.directions = Some(p);
        let ft = run_ft(&d, Preset::Default);
        let err = (ft.bands[0].albedo - want).abs();
        eprintln!(
            "disk canopy, {n} directions: FT albedo {:.6} vs MC {want:.6} ± {se:.6} ({:+.2} %)",
            ft.bands[0].albedo,
            100.0 * (ft.bands[0].albedo / want - 1.0)
        );
        assert!(
            err < last,
            "{n} directions: error {err} did not shrink (was {last})"
        );
        last = err;
    }
    assert!(
        last <= 3.0 * se + 1e-3 * want,
        "2000 directions: error {last}"
    );
}

/// Monte Carlo has no length scale of its own either (see the Radiative stage's
/// `huge_and_tiny_scenes_give_the_products_of_the_metre_scene`): a building with walls in cell
/// faces and a turbid crown, scaled by exact powers of two (2⁻¹⁰ ≈ 1 mm and 2¹³ ≈ 8 km cells,
/// u_f ∝ 1/s, leaf size ∝ s), follows the same photon paths with the same seed, so every product matches the
/// metre scene to 1e-9 relative (summation rounding only).
#[test]
fn huge_and_tiny_scenes_follow_the_photon_paths_of_the_metre_scene() {
    let make = |s: f64| {
        let mut d = base_scene((6.0 * s, 6.0 * s), (s, s, s), BoundaryMode::Repetitive);
        d.objects.push(flat_ground());
        d.optics.insert("wall".into(), lambertian(0.3));
        d.objects
            .push(box_building((1.0 * s, 1.5 * s, 3.5 * s, 4.0 * s), 2.5 * s));
        d.objects.push(ObjectDesc::TurbidPlot(TurbidPlotDesc {
            footprint: FootprintDesc::Box((4.0 * s, 0.0, 6.0 * s, 3.0 * s)),
            bottom_m: 0.0,
            top_m: 2.0 * s,
            foliage: FoliageDesc::Lai(2.0),
            optics: "veg".into(),
        }));
        d.grid.height_m = Some(4.0 * s);
        // The leaf dimension is a length too (hotspot-correlated first-order flights, #38).
        for o in d.optics.values_mut() {
            if let OpticsDesc::Turbid { leaf_size_m, .. } = o {
                *leaf_size_m *= s;
            }
        }
        d
    };
    let p1 = run_mc(&make(1.0), 20_000, SamplerKind::Continuous);
    assert_closes(&p1, "1 m");
    for s in [2f64.powi(-10), 2f64.powi(13)] {
        let p = run_mc(&make(s), 20_000, SamplerKind::Continuous);
        assert_closes(&p, &format!("×{s}"));
        assert_same_products(&p1, &p, 1e-9, &format!("×{s} against 1 m"));
    }
}
