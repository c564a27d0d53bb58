//! Radiative speed against error (harness = false). For the turbid-layer scene (LAI 3, red and
//! NIR, sun zenith 20°, 1 m × 1 m periodic) it runs each preset × direction count × cell size and
//! prints wall time, cell crossings per second per core, the process peak RSS and the worst BRF
//! and albedo errors against the DISORT oracle (assets/reference/turbid_canopy_disort.csv); then
//! the forest scene's timing, and the cost of the orthographic images (the forest with 21 exact
//! views at image oversampling η = 1, 2, 4). `cargo bench --bench radiative` (`-- --quick` for
//! fewer rows;
//! `-- --dump FILE` writes every row's albedos and BRFs, full precision, one JSON object per
//! line, to compare products between two builds; `-- --row NAME` runs only the row so named,
//! e.g. `--row "Default 100 0.2"`, `--row "forest Default"` or `--row "forest images η 2"`, so
//! that `valgrind --tool=callgrind` can count the instructions of one row; `-- --subfaces MODE`
//! sets the turbid interception stores of every row, `off`, `faces`, `subfaces` or `blend`
//! (DART 5 paper §3.2, Figure 7; default: the preset's), `--exit-grouping` merges a turbid
//! cell's scattered rays per exit sub-face (Figure 7c), `--ray-threshold X` sets the ray-power
//! threshold, `--cells 0.5,0.25` the turbid-layer cell sizes; `-- --no-skip` turns empty-space
//! skipping off (every cell visited), `-- --no-batch` the batched walk (rays one at a
//! time), `-- --avx2` / `-- --baseline` cap the walks' instruction set (`--avx2`: the batched
//! walk on 4 lanes instead of 8, products equal to ~1e-15)).
//!
//! Scale rows (not in the default run, one per process so that the peak RSS is the row's):
//! `--row "stand 200 m"` and `--row "stand 1 km"`, the seeded stands of the Maket bench (400 and
//! 10 000 trees, 4 m minimum spacing, 1 m cells, 12 m grid), default preset, 100 directions plus
//! the principal plane as exact views, and `--row "disk canopy 10 m"` (12 732 discs of 5 cm,
//! 154 724 facets, 0.5 m cells, 21 exact views); they print wall and CPU seconds, peak RSS,
//! crossings per CPU-second and, with `--mc N`, the worst exact-view BRF difference against a
//! Monte Carlo run of N photons on the same scene (in % and in the Monte Carlo standard
//! errors) and the Monte Carlo run's CPU seconds.
//!
//! Throughput columns: `Mcross/s/core` is visited cell crossings (empty cells jumped over by
//! empty-space skipping are not counted; the forest line prints them apart) / (wall time of
//! the engine run × threads), i.e. including emission, merging and extrapolation; `kernel` is
//! visited cell crossings /
//! `RadiativeResult::kernel_seconds`, the thread-seconds spent inside the ray-tracking loops
//! only (source launch loops and each emitter's loop over its outgoing directions).

use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::{LadDesc, Preset, RadiativeDesc, TurbidSubfaces};
use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
use lumenscape::scene::generators::{BandOptics, forest, rami_directions};
use lumenscape::simulation::Simulation;
use std::time::Instant;

mod common;
use common::{cpu_seconds, peak_rss_mib};

/// Spawns and runs every stage of `desc` with `preset`: (wall seconds, products).
fn run_timed(
    desc: &lumenscape::scene::desc::SceneDesc,
    preset: Preset,
) -> (f64, RadiativeProducts) {
    let t0 = Instant::now();
    let mut sim = Simulation::from_desc(
        desc,
        &SceneSource::generated(),
        RunSettings {
            preset: Some(preset),
            // `--no-skip`: every cell visited (empty-space skipping off), for comparisons.
            skip_empty: !std::env::args().any(|a| a == "--no-skip"),
            // `--no-batch`: the one-ray-at-a-time walk, for comparisons.
            batch_walk: !std::env::args().any(|a| a == "--no-batch"),
            // `--f64`: the double-precision 8-lane batched walk instead of the default
            // single-precision 16-lane one (AVX-512), for comparisons.
            batch_f32: !std::env::args().any(|a| a == "--f64"),
            // `--avx2` / `--baseline`: cap the walks' instruction set, for comparisons.
            kernel_isa: if std::env::args().any(|a| a == "--baseline") {
                lumenscape::radiative::engine::KernelIsa::Baseline
            } else if std::env::args().any(|a| a == "--avx2") {
                lumenscape::radiative::engine::KernelIsa::Avx2
            } else {
                lumenscape::radiative::engine::KernelIsa::Best
            },
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

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let mut dump = args
        .iter()
        .position(|a| a == "--dump")
        .and_then(|i| args.get(i + 1))
        .map(|path| std::fs::File::create(path).expect("dump file"));
    let mut write_dump = |name: String, p: &RadiativeProducts| {
        use std::io::Write;
        if let Some(f) = dump.as_mut() {
            let bands: Vec<serde_json::Value> = p
                .bands
                .iter()
                .map(|b| {
                    serde_json::json!({
                        "albedo": b.albedo,
                        "fabs": b.fabs,
                        "ftran": b.ftran,
                        "closure": b.energy_closure,
                        "brf": b.brf.iter().map(|e| e.brf).collect::<Vec<f64>>(),
                    })
                })
                .collect();
            let line = serde_json::json!({"row": name, "bands": bands, "crossings": p.crossings});
            writeln!(f, "{line}").expect("dump write");
        }
    };
    let only = args
        .iter()
        .position(|a| a == "--row")
        .and_then(|i| args.get(i + 1))
        .cloned();
    let wanted = |name: &str| only.as_deref().is_none_or(|o| o == name);
    let subfaces = args
        .iter()
        .position(|a| a == "--subfaces")
        .and_then(|i| args.get(i + 1))
        .map(|m| match m.as_str() {
            "off" => TurbidSubfaces::Off,
            "faces" => TurbidSubfaces::Faces,
            "subfaces" => TurbidSubfaces::Subfaces,
            "blend" => TurbidSubfaces::Blend,
            _ => panic!("--subfaces off|faces|subfaces|blend, not {m}"),
        });
    let ray_threshold: Option<f64> = args
        .iter()
        .position(|a| a == "--ray-threshold")
        .and_then(|i| args.get(i + 1))
        .map(|x| x.parse().expect("--ray-threshold X"));
    let cells: Vec<f64> = args
        .iter()
        .position(|a| a == "--cells")
        .and_then(|i| args.get(i + 1))
        .map_or(vec![0.5, 0.2], |x| {
            x.split(',')
                .map(|c| c.parse().expect("--cells A,B"))
                .collect()
        });
    let with_mode = |d: &mut lumenscape::scene::desc::SceneDesc| {
        if subfaces.is_some() {
            d.radiative
                .get_or_insert_with(Default::default)
                .turbid_subfaces = subfaces;
        }
        if args.iter().any(|a| a == "--exit-grouping") {
            d.radiative
                .get_or_insert_with(Default::default)
                .turbid_exit_grouping = Some(true);
        }
        if ray_threshold.is_some() {
            d.radiative
                .get_or_insert_with(Default::default)
                .ray_threshold = ray_threshold;
        }
    };
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
    println!(
        "turbid layer LAI 3, sun 20°, red+NIR, {threads} threads, kernel {}, turbid stores {}",
        lumenscape::radiative::engine::kernel_isa(),
        subfaces.map_or("of the preset".to_string(), |m| format!("{m:?}"))
    );
    println!(
        "{:>9} {:>5} {:>6} {:>9} {:>6} {:>14} {:>7} {:>10} {:>11} {:>11}",
        "preset",
        "dirs",
        "cell",
        "wall_s",
        "iters",
        "Mcross/s/core",
        "kernel",
        "peakRSS",
        "worstBRF%",
        "worstAlb%"
    );
    let presets = if quick {
        vec![Preset::Default]
    } else {
        vec![Preset::Preview, Preset::Default, Preset::Reference]
    };
    for preset in presets {
        // The reference preset needs at least 400 directions: one row per cell size.
        let dir_counts: &[usize] = if preset == Preset::Reference {
            &[400]
        } else {
            &[100, 400]
        };
        for &dirs in dir_counts {
            for &cell in &cells {
                let n = dirs;
                let name = format!("{preset:?} {n} {cell}");
                if !wanted(&name) {
                    continue;
                }
                let mut d = turbid_layer(&TurbidLayerParams {
                    lai: 3.0,
                    lad: LadDesc::Spherical,
                    bands: vec![BandOptics::red(), BandOptics::nir()],
                    height_m: 2.0,
                    cell_m: cell,
                    size_m: 1.0,
                    sun_zenith_deg: 20.0,
                    sun_azimuth_deg: 0.0,
                });
                common::no_hotspot(&mut d);
                d.directions.as_mut().unwrap().count = dirs;
                with_mode(&mut d);
                let (wall, p) = run_timed(&d, preset);
                let (mut wb, mut wa) = (0.0f64, 0.0f64);
                for r in &rows {
                    let b = if r[1] == "red" { 0 } else { 1 };
                    let vz: f64 = r[3].parse().unwrap();
                    let az = if vz >= 0.0 { 0.0 } else { 180.0 };
                    let got = p.brf_at(b, vz.abs(), az).unwrap().brf;
                    wb = wb.max((got / r[4].parse::<f64>().unwrap() - 1.0).abs());
                    wa = wa.max((p.bands[b].albedo / r[5].parse::<f64>().unwrap() - 1.0).abs());
                }
                let rate = p.crossings as f64 / p.tracking_seconds / threads as f64 / 1e6;
                let kernel = p.crossings as f64 / p.raw.kernel_seconds / 1e6;
                write_dump(name, &p);
                println!(
                    "{:>9} {:>5} {:>6} {:>9.3} {:>6} {:>14.2} {:>7.2} {:>8.1}MiB {:>11.3} {:>11.3} lost {:.1e} closure {:.1e}",
                    format!("{preset:?}"),
                    n,
                    cell,
                    wall,
                    p.iterations,
                    rate,
                    kernel,
                    peak_rss_mib(),
                    100.0 * wb,
                    100.0 * wa,
                    p.bands.iter().map(|b| b.flost).fold(0.0, f64::max),
                    p.bands.iter().map(|b| b.energy_closure).fold(0.0, f64::max)
                );
            }
        }
    }
    // Dense cells (physics.md §3.6 pitfalls: u_f = 50 m²/m³, LAI 25 in 0.5 m, red): albedo and
    // wall time per cell size, where the interception points matter most.
    for cell in [0.25, 0.125, 0.0625, 0.03125] {
        let name = format!("dense {cell}");
        if !wanted(&name) {
            continue;
        }
        let mut d = turbid_layer(&TurbidLayerParams {
            lai: 25.0,
            height_m: 0.5,
            cell_m: cell,
            size_m: 1.0,
            ..Default::default()
        });
        with_mode(&mut d);
        let (wall, p) = run_timed(&d, Preset::Default);
        write_dump(name, &p);
        println!(
            "dense u_f 50, cell {cell}: wall {wall:.3} s, albedo {:.6}, BRF nadir {:.6}, closure {:.1e}, peak RSS {:.1} MiB",
            p.bands[0].albedo,
            p.brf_at(0, 0.0, 0.0).map_or(f64::NAN, |e| e.brf),
            p.bands[0].energy_closure,
            peak_rss_mib()
        );
    }
    // Forest scene (no oracle): timing and throughput.
    let mut f = forest::forest(&forest::ForestParams {
        size_m: 40.0,
        ..Default::default()
    });
    with_mode(&mut f);
    for preset in [Preset::Preview, Preset::Default] {
        if !wanted(&format!("forest {preset:?}")) {
            continue;
        }
        let (wall, p) = run_timed(&f, preset);
        write_dump(format!("forest {preset:?}"), &p);
        println!(
            "forest 40 m, 24 trees, 1 m cells, {preset:?}: wall {wall:.2} s, {} iterations, {:.1} M visited + {:.1} M skipped cells, {:.2} Mcrossings/s/core (kernel {:.2}), closure {:.1e}, peak RSS {:.1} MiB",
            p.iterations,
            p.crossings as f64 / 1e6,
            p.skipped as f64 / 1e6,
            p.crossings as f64 / p.tracking_seconds / threads as f64 / 1e6,
            p.crossings as f64 / p.raw.kernel_seconds / 1e6,
            p.bands.iter().map(|b| b.energy_closure).fold(0.0, f64::max),
            peak_rss_mib()
        );
    }
    // Sparse stand under a tall grid (empty-space skipping's case): 120 m, 6 trees, 60 m of
    // grid height (mostly air).
    if wanted("sparse Preview") {
        let mut sp = forest::forest(&forest::ForestParams {
            size_m: 120.0,
            species: vec![forest::broadleaf(3), forest::conifer(3)],
            ..Default::default()
        });
        sp.grid.height_m = Some(60.0);
        let (wall, p) = run_timed(&sp, Preset::Preview);
        write_dump("sparse Preview".into(), &p);
        println!(
            "sparse 120 m, 6 trees, 60 m high, Preview: wall {wall:.2} s, {:.1} M visited + {:.1} M skipped cells, {:.2} Mcrossings/s/core (kernel {:.2}), closure {:.1e}",
            p.crossings as f64 / 1e6,
            p.skipped as f64 / 1e6,
            p.crossings as f64 / p.tracking_seconds / threads as f64 / 1e6,
            p.crossings as f64 / p.raw.kernel_seconds / 1e6,
            p.bands.iter().map(|b| b.energy_closure).fold(0.0, f64::max),
        );
    }
    for (name, size, n) in [("stand 200 m", 200.0, 200), ("stand 1 km", 1000.0, 5000)] {
        if only.as_deref() == Some(name) {
            scale_row(name, &stand(size, n), &args);
        }
    }
    if only.as_deref() == Some("disk canopy 10 m") {
        // `lumenscape generate disk-canopy --size 10 --lai 1`: 12 732 discs, 154 724 facets.
        let d = lumenscape::scene::generators::disk_canopy::disk_canopy(
            &lumenscape::scene::generators::disk_canopy::DiskCanopyParams {
                size_m: 10.0,
                ..Default::default()
            },
        )
        .expect("disk canopy");
        scale_row("disk canopy 10 m", &d, &args);
    }
    // Orthographic images: the forest with nadir and the principal/orthogonal planes every 15°
    // (21 exact views, 21 images), η = 1, 2, 4 (footprints spread over Δx/η pixels).
    let mut fi = f.clone();
    fi.directions = Some(rami_directions(225.0));
    for eta in [1u32, 2, 4] {
        if !wanted(&format!("forest images η {eta}")) {
            continue;
        }
        fi.radiative = Some(RadiativeDesc {
            image_oversampling: eta,
            turbid_subfaces: subfaces,
            turbid_exit_grouping: Some(args.iter().any(|a| a == "--exit-grouping")),
            ..Default::default()
        });
        let (wall, p) = run_timed(&fi, Preset::Default);
        write_dump(format!("forest images η {eta}"), &p);
        println!(
            "forest 40 m, 21 images, η {eta} ({} × {} pixels): wall {wall:.2} s, tracking {:.2} s, kernel {:.2} thread-s, images {:.1} MiB",
            p.raw.image_grid.n.0,
            p.raw.image_grid.n.1,
            p.tracking_seconds,
            p.raw.kernel_seconds,
            (p.raw.images.len() * 8) as f64 / (1 << 20) as f64
        );
    }
}

/// The Maket bench's seeded stand of `2 n` trees on `size` m, 1 m cells, the principal plane as
/// exact views.
fn stand(size: f64, n: usize) -> lumenscape::scene::desc::SceneDesc {
    use lumenscape::scene::generators::principal_plane_directions;
    let mut d = forest::forest(&forest::ForestParams {
        size_m: size,
        cell_m: 1.0,
        species: vec![forest::broadleaf(n), forest::conifer(n)],
        min_spacing_m: 4.0,
        seed: 11,
        ..Default::default()
    });
    d.directions = Some(principal_plane_directions(
        d.illumination.sun_azimuth_deg.unwrap_or(0.0),
    ));
    d
}

/// One scale row (see the module doc): scene `d`, flux tracking at the default preset, and with
/// `--mc N` the worst BRF difference over the exact views against N Monte Carlo photons.
fn scale_row(name: &str, d: &lumenscape::scene::desc::SceneDesc, args: &[String]) {
    use lumenscape::resources::scene::Solver;
    let (c0, t0) = (cpu_seconds(), Instant::now());
    let (_, p) = run_timed(d, Preset::Default);
    let (wall, cpu) = (t0.elapsed().as_secs_f64(), cpu_seconds() - c0);
    println!(
        "{name}, Default: wall {wall:.1} s, CPU {cpu:.1} s, peak RSS {:.0} MiB, {} iterations, {:.2} G crossings, {:.1} M crossings per CPU-s, closure {:.1e}",
        peak_rss_mib(),
        p.iterations,
        p.crossings as f64 / 1e9,
        p.crossings as f64 / cpu / 1e6,
        p.bands.iter().map(|b| b.energy_closure).fold(0.0, f64::max),
    );
    let Some(photons) = args
        .iter()
        .position(|a| a == "--mc")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse::<f64>().ok())
    else {
        return;
    };
    let (c1, t1) = (cpu_seconds(), Instant::now());
    let mut sim = Simulation::from_desc(
        d,
        &SceneSource::generated(),
        RunSettings {
            solver: Solver::MonteCarlo {
                photons: photons as u64,
                sampler: lumenscape::resources::scene::SamplerKind::Continuous,
            },
            ..Default::default()
        },
    )
    .expect("scene");
    sim.run(None).expect("run");
    let m = sim.resource::<RadiativeProducts>().clone();
    let (mut worst_rel, mut worst_z): (f64, f64) = (0.0, 0.0);
    for (bm, bf) in m.bands.iter().zip(&p.bands) {
        for (e, f) in bm.brf.iter().zip(&bf.brf) {
            if e.estimator == Some("peel-off") {
                worst_rel = worst_rel.max((f.brf / e.brf - 1.0).abs());
                worst_z = worst_z.max((f.brf - e.brf).abs() / e.brf_se.unwrap_or(f64::NAN));
            }
        }
    }
    println!(
        "{name}: Monte Carlo {photons:.0} photons in {:.1} s wall, {:.1} CPU s; worst exact-view |FT − MC| {:.2} % = {:.1} σ",
        t1.elapsed().as_secs_f64(),
        cpu_seconds() - c1,
        100.0 * worst_rel,
        worst_z
    );
}
