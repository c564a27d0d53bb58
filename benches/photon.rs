//! Monte Carlo speed against error (harness = false). `cargo bench --bench photon`
//! (`-- --quick` for fewer rows).
//!
//! `-- --samplers`: the scattering-direction samplers' speed and memory instead (alias against
//! Box tables, continuous samplers; see `samplers`).
//!
//! 1. Turbid layer (LAI 3, red + NIR, sun 20°, principal-plane views): continuous Monte Carlo at
//!    increasing photon counts → wall time, photons/s/core, worst relative BRF standard error,
//!    worst |error| and |z| against DISORT; the photon count and time needed for 1 % and 0.3 %
//!    worst BRF standard error (SE ∝ N^−1/2, measured at the largest run); the flux-tracking
//!    solver's time and error on the same scene next to it; the discrete samplers (alias, Box).
//! 2. Forest (40 m, 24 trees) and disk canopy: same Monte Carlo figures, and the difference
//!    between flux tracking (default preset) and Monte Carlo in units of σ.

use glam::DVec3;
use lumenscape::photon::engine::SamplerKind;
use lumenscape::photon::sampling::{
    AliasTable, BoxTable, BrdfGrid, BrdfSampler, LeafSampler, sample_fluid_phase, total_variation,
};
use lumenscape::physics::lad::Lad;
use lumenscape::physics::phase::FluidPhase;
use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::scene::{RunSettings, Solver};
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::{LadDesc, Preset, SceneDesc};
use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
use lumenscape::scene::generators::{BandOptics, disk_canopy, forest, principal_plane_directions};
use lumenscape::simulation::Simulation;
use rand_xoshiro::Xoshiro256PlusPlus;
use rand_xoshiro::rand_core::SeedableRng;
use std::time::Instant;

mod common;
use common::peak_rss_mib;
#[path = "../tests/fixtures/sampler_rows.rs"]
mod sampler_rows;
use sampler_rows::{hg_row, incoming, leaf_row, reference_brdfs};

fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

fn run(desc: &SceneDesc, solver: Solver, preset: Option<Preset>) -> (f64, RadiativeProducts) {
    let t0 = Instant::now();
    let mut sim = Simulation::from_desc(
        desc,
        &SceneSource::generated(),
        RunSettings {
            solver,
            preset,
            ..Default::default()
        },
    )
    .unwrap();
    sim.run(None).unwrap();
    (
        t0.elapsed().as_secs_f64(),
        sim.resource::<RadiativeProducts>().clone(),
    )
}

/// Worst relative SE over the peel-off BRFs of every band.
fn worst_rel_se(p: &RadiativeProducts) -> f64 {
    p.bands
        .iter()
        .flat_map(|b| b.brf.iter())
        .filter(|e| e.estimator == Some("peel-off"))
        .map(|e| e.brf_se.unwrap_or(f64::NAN) / e.brf)
        .fold(0.0, f64::max)
}

fn mc(photons: u64, sampler: SamplerKind) -> Solver {
    Solver::MonteCarlo { photons, sampler }
}

fn main() {
    if std::env::args().any(|a| a == "--samplers") {
        samplers();
        return;
    }
    let quick = std::env::args().any(|a| a == "--quick");
    let threads = rayon::current_num_threads();
    let oracle = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/reference/turbid_canopy_disort.csv"
    ))
    .expect("oracle");
    let rows: Vec<Vec<String>> = oracle
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(String::from).collect())
        .filter(|r: &Vec<String>| r[0] == "3" && r[2] == "20")
        .collect();
    let errors = |p: &RadiativeProducts| -> (f64, f64) {
        let (mut we, mut wz) = (0.0f64, 0.0f64);
        for r in &rows {
            let b = if r[1] == "red" { 0 } else { 1 };
            let vz: f64 = r[3].parse().unwrap();
            let az = if vz >= 0.0 { 0.0 } else { 180.0 };
            let e = p.brf_at(b, vz.abs(), az).unwrap();
            let want: f64 = r[4].parse().unwrap();
            we = we.max((e.brf / want - 1.0).abs());
            if let Some(se) = e.brf_se {
                wz = wz.max((e.brf - want).abs() / se);
            }
        }
        (we, wz)
    };
    let mut layer = turbid_layer(&TurbidLayerParams {
        lai: 3.0,
        lad: LadDesc::Spherical,
        bands: vec![BandOptics::red(), BandOptics::nir()],
        height_m: 2.0,
        cell_m: 1.0,
        size_m: 1.0,
        sun_zenith_deg: 20.0,
        sun_azimuth_deg: 0.0,
    });
    common::no_hotspot(&mut layer);
    layer.directions = Some(principal_plane_directions(0.0));
    println!("turbid layer LAI 3, sun 20°, red+NIR, 11 principal-plane views, {threads} threads");
    println!(
        "{:>12} {:>10} {:>9} {:>14} {:>10} {:>11} {:>8} {:>9}",
        "solver",
        "photons",
        "wall_s",
        "photons/s/core",
        "worstSE%",
        "worstErr%",
        "worst|z|",
        "peakRSS"
    );
    let counts: Vec<u64> = if quick {
        vec![100_000]
    } else {
        vec![100_000, 400_000, 1_600_000]
    };
    let mut last = (0u64, 0.0f64, 0.0f64);
    for &n in &counts {
        let (wall, p) = run(&layer, mc(n, SamplerKind::Continuous), None);
        let (we, wz) = errors(&p);
        let se = worst_rel_se(&p);
        let info = p.monte_carlo.as_ref().unwrap();
        println!(
            "{:>12} {:>10} {:>9.3} {:>14.0} {:>10.3} {:>11.3} {:>8.2} {:>6.1}MiB",
            "continuous",
            n,
            wall,
            info.photons_per_second_per_core,
            100.0 * se,
            100.0 * we,
            wz,
            peak_rss_mib()
        );
        last = (n, wall, se);
    }
    let (n, wall, se) = last;
    for target in [0.01, 0.003] {
        let need = n as f64 * (se / target).powi(2);
        println!(
            "  continuous MC for {:.1} % worst BRF SE: ≈ {:.2e} photons, ≈ {:.1} s (projected from the {} run)",
            100.0 * target,
            need,
            wall * need / n as f64,
            n
        );
    }
    for (name, sampler) in [
        ("alias", SamplerKind::Alias),
        (
            "box",
            SamplerKind::Box {
                gamma: 2.0,
                max_boxes: 4096,
            },
        ),
    ] {
        let n = *counts.last().unwrap();
        let (wall, p) = run(&layer, mc(n, sampler), Some(Preset::Default));
        let (we, wz) = errors(&p);
        println!(
            "{:>12} {:>10} {:>9.3} {:>14.0} {:>10.3} {:>11.3} {:>8.2} {:>6.1}MiB",
            name,
            n,
            wall,
            p.monte_carlo.as_ref().unwrap().photons_per_second_per_core,
            100.0 * worst_rel_se(&p),
            100.0 * we,
            wz,
            peak_rss_mib()
        );
    }
    for preset in [Preset::Default, Preset::Reference] {
        let mut d = layer.clone();
        d.grid.cell_m = (0.2, 0.2, 0.2);
        let (wall, p) = run(&d, Solver::FluxTracking, Some(preset));
        let (we, _) = errors(&p);
        println!(
            "{:>12} {:>10} {:>9.3} {:>14} {:>10} {:>11.3} {:>8} {:>6.1}MiB   (0.2 m cells)",
            format!("FT {preset:?}"),
            "-",
            wall,
            "-",
            "-",
            100.0 * we,
            "-",
            peak_rss_mib()
        );
    }
    // Facet and crown scenes: Monte Carlo figures and the flux-tracking difference in σ.
    let mut fo = forest::forest(&forest::ForestParams {
        size_m: 40.0,
        ..Default::default()
    });
    fo.directions = Some(principal_plane_directions(
        fo.illumination.sun_azimuth_deg.unwrap_or(0.0),
    ));
    let mut dc =
        disk_canopy::disk_canopy(&disk_canopy::DiskCanopyParams::default()).expect("disk canopy");
    dc.directions = Some(principal_plane_directions(
        dc.illumination.sun_azimuth_deg.unwrap_or(0.0),
    ));
    let n = if quick { 50_000 } else { 400_000 };
    for (name, d) in [("forest 40 m", &fo), ("disk canopy", &dc)] {
        let (wall, p) = run(d, mc(n, SamplerKind::Continuous), None);
        let (wft, q) = run(d, Solver::FluxTracking, Some(Preset::Default));
        let mut worst_dz: f64 = 0.0;
        let mut worst_rel: f64 = 0.0;
        for (bp, bq) in p.bands.iter().zip(&q.bands) {
            for (e, f) in bp.brf.iter().zip(&bq.brf) {
                if e.estimator == Some("peel-off") {
                    worst_dz = worst_dz.max((e.brf - f.brf).abs() / e.brf_se.unwrap());
                    worst_rel = worst_rel.max((f.brf / e.brf - 1.0).abs());
                }
            }
        }
        let se = worst_rel_se(&p);
        println!(
            "{name}: MC {n} photons {wall:.2} s, {:.0} photons/s/core, worst BRF SE {:.2} % (→ 1 %: {:.1} s, 0.3 %: {:.1} s projected); flux tracking (default) {wft:.2} s, worst |FT − MC| {:.2} % = {:.1} σ; peak RSS {:.1} MiB",
            p.monte_carlo.as_ref().unwrap().photons_per_second_per_core,
            100.0 * se,
            wall * (se / 0.01).powi(2),
            wall * (se / 0.003).powi(2),
            100.0 * worst_rel,
            worst_dz,
            peak_rss_mib()
        );
    }
}

/// The samplers row (`--samplers`): alias against Box tables on HG and planophile-leaf phase
/// rows of 100, 400 and 1000 directions (build time, bytes per row, draws per second, largest
/// relative bias and total variation against the row), then the continuous samplers' draws per
/// second (fluid phase functions, leaves of five LADs at three incidences, BRDFs).
fn samplers() {
    let draws = 20_000_000usize;
    println!("| row | N | sampler | bytes/row | Mdraws/s | max rel. bias | TV |");
    println!("|---|---|---|---|---|---|---|");
    for n in [100usize, 400, 1000] {
        for (row_name, row) in [
            ("HG g=0.85", hg_row(n, 0.85)),
            ("leaf planophile", leaf_row(n)),
        ] {
            let sum: f64 = row.iter().sum();
            let p: Vec<f64> = row.iter().map(|x| x / sum).collect();
            let t0 = Instant::now();
            let a = AliasTable::new(&row).unwrap();
            let build_a = t0.elapsed().as_secs_f64();
            let mut r = rng(1);
            let t0 = Instant::now();
            let mut acc = 0usize;
            for _ in 0..draws {
                acc = acc.wrapping_add(a.sample(&mut r));
            }
            let dt = t0.elapsed().as_secs_f64();
            let tv = total_variation(&p, &a.probabilities());
            println!(
                "| {row_name} | {n} | alias (build {:.1} µs) | {} | {:.0} | {:.1e} | {tv:.1e} |",
                build_a * 1e6,
                a.bytes(),
                draws as f64 / dt / 1e6,
                p.iter()
                    .zip(a.probabilities())
                    .map(|(x, y)| (y / x - 1.0).abs())
                    .fold(0.0, f64::max)
            );
            std::hint::black_box(acc);
            for (gamma, per) in [(2.0, 10usize), (2.0, 100), (2.0, 1000), (8.0, 100)] {
                let t0 = Instant::now();
                let b = BoxTable::new(&row, gamma, per * n).unwrap();
                let build_b = t0.elapsed().as_secs_f64();
                let q = b.probabilities();
                let max_rel = p
                    .iter()
                    .zip(&q)
                    .map(|(x, y)| (y / x - 1.0).abs())
                    .fold(0.0, f64::max);
                let mut r = rng(2);
                let t0 = Instant::now();
                let mut acc = 0usize;
                for _ in 0..draws {
                    acc = acc.wrapping_add(b.sample(&mut r));
                }
                let dt = t0.elapsed().as_secs_f64();
                std::hint::black_box(acc);
                println!(
                    "| {row_name} | {n} | box γ={gamma} M={per}N (K={}, build {:.0} µs, bound {:.1e}) | {} | {:.0} | {max_rel:.1e} | {:.1e} |",
                    b.resolution().classes,
                    build_b * 1e6,
                    b.bias_bound().unwrap_or(f64::NAN),
                    b.bytes(),
                    draws as f64 / dt / 1e6,
                    total_variation(&p, &q)
                );
            }
        }
    }
    // Continuous samplers (draws/s).
    let mut r = rng(3);
    let w = incoming(40.0);
    let m = 2_000_000usize;
    for phase in [
        FluidPhase::HenyeyGreenstein { g: 0.85 },
        FluidPhase::air(),
        FluidPhase::dart_aerosol_default(),
    ] {
        let t0 = Instant::now();
        let mut acc = DVec3::ZERO;
        for _ in 0..m {
            acc += sample_fluid_phase(&phase, w, &mut r);
        }
        std::hint::black_box(acc);
        println!(
            "{phase:?}: {:.1} M/s",
            m as f64 / t0.elapsed().as_secs_f64() / 1e6
        );
    }
    for lad in [
        Lad::Spherical,
        Lad::Planophile,
        Lad::EllipsoidalChi { chi: 2.0 },
        Lad::Beta {
            mu: 0.433,
            nu: 0.433,
        },
        Lad::EllipsoidalChi { chi: 100.0 },
    ] {
        let d = lad.resolve().unwrap();
        let s = LeafSampler::new(&d).unwrap();
        for deg in [0.0, 60.0, 89.9] {
            let w = incoming(deg);
            let t0 = Instant::now();
            let mut acc = DVec3::ZERO;
            for _ in 0..m {
                acc += s.scatter(w, 0.5, &mut r).dir;
            }
            std::hint::black_box(acc);
            println!(
                "leaf {lad:?} at {deg}°: {:.1} M/s, expected trials {:.3}, {} pieces, {} bytes",
                m as f64 / t0.elapsed().as_secs_f64() / 1e6,
                s.expected_trials(w, d.g_function(w.z)),
                s.pieces(),
                s.bytes()
            );
        }
    }
    for (name, brdf, _) in reference_brdfs().into_iter().step_by(3) {
        let t0 = Instant::now();
        let s = BrdfSampler::new(&brdf, BrdfGrid::default()).unwrap();
        let build = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let mut acc = 0.0;
        for _ in 0..m {
            acc += s.sample(DVec3::Z, w, &mut r).unwrap().weight;
        }
        std::hint::black_box(acc);
        println!(
            "BRDF {name}: build {:.1} ms, {:.1} M/s, {} bytes",
            build * 1e3,
            m as f64 / t0.elapsed().as_secs_f64() / 1e6,
            s.bytes()
        );
    }
}
