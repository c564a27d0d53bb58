//! Every example scene in assets/scenes loads, runs Maket and Output, round-trips through RON,
//! and writes its products atomically.

mod common;
use common::asset;
use lumenscape::io::exr_out::read_exr_channels;
use lumenscape::resources::grid::{CellGrid, GridSpec};
use lumenscape::resources::maket_report::MaketReport;
use lumenscape::scene::{load_scene, parse_scene, to_ron};
use lumenscape::simulation::Simulation;
use std::path::PathBuf;

fn scenes() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(asset("assets/scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    v.sort();
    for name in [
        "default.ron",
        "turbid_layer.ron",
        "disk_canopy.ron",
        "forest_dem.ron",
        "urban.ron",
        "mesh_import.ron",
    ] {
        assert!(
            v.iter().any(|p| p.ends_with(name)),
            "missing example scene {name}"
        );
    }
    v
}

#[test]
fn every_example_scene_round_trips_through_ron() {
    for p in scenes() {
        let (desc, _) = load_scene(&p).unwrap_or_else(|e| panic!("{e}"));
        let text = to_ron(&desc);
        let again = parse_scene(&text, &p)
            .unwrap_or_else(|e| panic!("{}: re-parse failed: {e}\n{text}", p.display()));
        assert_eq!(desc, again, "{}", p.display());
    }
}

#[test]
fn every_example_scene_runs_and_writes_products() {
    let out_root = std::env::temp_dir().join(format!("lumenscape-scenes-{}", std::process::id()));
    for p in scenes() {
        let mut sim = Simulation::load(&p, Default::default()).unwrap_or_else(|e| panic!("{e}"));
        let out = out_root.join(p.file_stem().unwrap());
        sim.run(Some(&out))
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        let r = sim.resource::<MaketReport>().clone();
        for (m, la) in &r.leaf_area {
            let got = la.rasterised_m2.unwrap_or(0.0);
            assert!(
                (got - la.analytic_m2).abs() <= 1e-6 * la.analytic_m2,
                "{}: `{m}` {got} vs {}",
                p.display(),
                la.analytic_m2
            );
        }
        // The passive solver runs unless the scene is LiDAR-only (`SceneDesc::runs_passive`):
        // then no passive product is written and the LiDAR products are.
        let (desc, _) = load_scene(&p).unwrap();
        let passive = sim.get_resource::<lumenscape::radiative::products::RadiativeProducts>();
        assert_eq!(passive.is_some(), desc.runs_passive(), "{}", p.display());
        if let Some(rp) = passive {
            // Energy closes on every example scene (absorbed + escaped + lost = sources).
            for b in &rp.bands {
                assert!(
                    b.energy_closure <= 1e-9,
                    "{}: band {} energy closure {:e}",
                    p.display(),
                    b.band,
                    b.energy_closure
                );
                assert!(
                    b.brf.iter().all(|e| e.brf.is_finite()),
                    "{}: NaN BRF",
                    p.display()
                );
            }
            for f in [
                "summary.json",
                "brf.csv",
                "budget/cells.csv",
                "budget/layers.csv",
                "budget/elements.csv",
            ] {
                assert!(out.join(f).is_file(), "{}: {f} missing", p.display());
            }
            // The per-cell budget adds up to the scene's absorbed fraction (vegetation, facets and
            // ground): Σ fabs_cell × A_column / A_scene = fabs + fabs_ground.
            let cells_csv = std::fs::read_to_string(out.join("budget/cells.csv")).unwrap();
            let col_frac = 1.0 / (spec_n_columns(&sim) as f64);
            for b in &rp.bands {
                let s: f64 = cells_csv
                    .lines()
                    .skip(1)
                    .filter(|l| l.split(',').nth(3) == Some(b.band.as_str()))
                    .map(|l| l.split(',').nth(4).unwrap().parse::<f64>().unwrap())
                    .sum::<f64>()
                    * col_frac;
                let want = b.fabs + b.fabs_ground;
                assert!(
                    (s - want).abs() <= 1e-6 * want.max(1e-9) + 1e-12,
                    "{}: band {} per-cell budget sums to {s}, scene {want}",
                    p.display(),
                    b.band
                );
            }
        } else {
            for f in ["summary.json", "brf.csv", "budget"] {
                assert!(!out.join(f).exists(), "{}: {f} written", p.display());
            }
            for l in desc.lidars.iter().flatten() {
                let d = out.join("lidar").join(&l.name);
                assert!(
                    d.join("returns.las").is_file(),
                    "{}: {} has no returns.las",
                    p.display(),
                    l.name
                );
            }
        }
        for f in ["maket.json", "lai.exr", "dsm.exr", "density.csv"] {
            assert!(out.join(f).is_file(), "{}: {f} missing", p.display());
        }
        // No temporary file is left behind.
        for e in std::fs::read_dir(&out).unwrap() {
            let n = e.unwrap().file_name().into_string().unwrap();
            assert!(!n.contains(".tmp-"), "{n} left behind");
        }
        // The LAI map integrates to the rasterised leaf area.
        let spec = sim.resource::<GridSpec>().clone();
        let (nx, ny, chans) = read_exr_channels(&out.join("lai.exr")).unwrap();
        assert_eq!((nx, ny), (spec.n[0], spec.n[1]));
        let total = chans
            .iter()
            .find(|(n, _)| n == "lai.total")
            .expect("total channel");
        let la: f64 = total.1.iter().map(|v| *v as f64).sum::<f64>() * spec.cell.x * spec.cell.y;
        let expected: f64 = r
            .leaf_area
            .values()
            .map(|l| l.rasterised_m2.unwrap_or(0.0))
            .sum();
        assert!(
            (la - expected).abs() <= 1e-5 * expected.max(1e-9),
            "{}: LAI map {la} vs {expected}",
            p.display()
        );
        let g = sim.resource::<CellGrid>();
        assert!(
            g.turbid
                .iter()
                .all(|e| e.density.is_finite() && e.density >= 0.0)
        );
        // maket.json parses back.
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("maket.json")).unwrap())
                .unwrap();
        assert_eq!(j["n_cells"].as_u64(), Some(spec.n_cells() as u64));
    }
    let _ = std::fs::remove_dir_all(out_root);
}

#[test]
fn generators_give_valid_scenes_that_round_trip() {
    use lumenscape::scene::generators::*;
    let descs = vec![
        turbid_layer::turbid_layer(&Default::default()),
        disk_canopy::disk_canopy(&disk_canopy::DiskCanopyParams {
            size_m: 1.0,
            ..Default::default()
        })
        .unwrap(),
        forest::forest(&Default::default()),
        forest::forest(&forest::ForestParams {
            slope_deg: 12.0,
            size_jitter: 0.3,
            ..Default::default()
        }),
        urban::urban(&Default::default()),
    ];
    for d in descs {
        lumenscape::scene::validate::validate(&d, &lumenscape::scene::SceneSource::generated())
            .unwrap();
        let again = parse_scene(&to_ron(&d), std::path::Path::new("<generated>")).unwrap();
        assert_eq!(d, again);
    }
}

#[test]
fn disk_canopy_has_the_requested_leaf_area_and_no_intersecting_disks() {
    use lumenscape::scene::desc::ObjectDesc;
    use lumenscape::scene::generators::disk_canopy::*;
    let p = DiskCanopyParams {
        lai: 2.0,
        size_m: 1.0,
        ..Default::default()
    };
    let d = disk_canopy(&p).unwrap();
    let ObjectDesc::Leaves(l) = &d.objects[1] else {
        panic!()
    };
    let n = l.disks.len() as f64;
    let lai = n * std::f64::consts::PI * l.radius_m * l.radius_m / (p.size_m * p.size_m);
    // Rounding the disk count: |LAI error| ≤ πr²/(2 X²).
    assert!(
        (lai - 2.0).abs() <= std::f64::consts::PI * 0.0025 / 2.0 + 1e-12,
        "{lai}"
    );
    let disks: Vec<(glam::DVec3, glam::DVec3)> = l
        .disks
        .iter()
        .map(|d| {
            (
                glam::DVec3::new(d.0, d.1, d.2),
                glam::DVec3::new(d.3, d.4, d.5),
            )
        })
        .collect();
    for i in 0..disks.len() {
        for j in i + 1..disks.len() {
            let mut dd = disks[j].0 - disks[i].0;
            dd.x -= p.size_m * (dd.x / p.size_m).round();
            dd.y -= p.size_m * (dd.y / p.size_m).round();
            assert!(
                !disks_intersect(
                    disks[i].0,
                    disks[i].1,
                    disks[i].0 + dd,
                    disks[j].1,
                    l.radius_m
                ),
                "disks {i} and {j} intersect"
            );
        }
        // Inside the canopy layer.
        let half = l.radius_m * (1.0 - disks[i].1.z * disks[i].1.z).sqrt();
        assert!(disks[i].0.z - half >= -1e-12 && disks[i].0.z + half <= p.height_m + 1e-12);
    }
    // Spherical LAD: mean |cos| of the normal = 1/2 (the normal's zenith is uniform in cosine).
    let mean_cos = disks.iter().map(|d| d.1.z).sum::<f64>() / n;
    assert!(
        (mean_cos - 0.5).abs() < 4.0 * (1.0 / 12f64).sqrt() / n.sqrt(),
        "{mean_cos}"
    );
}

fn spec_n_columns(sim: &Simulation) -> usize {
    let s = sim.resource::<GridSpec>();
    s.n[0] * s.n[1]
}

/// Model only what the scene needs: a LiDAR-only scene (lidar_als.ron) runs no passive solver
/// and writes no passive product, and its LiDAR products are those of the same scene with the
/// passive run forced (`passive: Some(true)`): the passive solve feeds only the fusion product
/// and the photon-counting background. `fusion: true` asks for the passive run by itself.
#[test]
fn lidar_only_scenes_skip_the_passive_solver_and_keep_their_waveforms() {
    use lumenscape::lidar::run::LidarProducts;
    use lumenscape::radiative::products::RadiativeProducts;
    use lumenscape::scene::SceneSource;
    let (desc, _) = load_scene(&asset("assets/scenes/lidar_als.ron")).unwrap();
    assert!(desc.lidars.as_ref().is_some_and(|l| !l.is_empty()));
    let run = |d: &lumenscape::scene::desc::SceneDesc| {
        let mut sim = Simulation::from_desc(d, &SceneSource::generated(), Default::default())
            .unwrap_or_else(|e| panic!("{e}"));
        sim.run(None).unwrap_or_else(|e| panic!("{e}"));
        let waves = format!("{:?}", sim.resource::<LidarProducts>().0[0].pulses);
        let fusion = sim.resource::<LidarProducts>().0[0]
            .fusion_radiance
            .is_some();
        (
            sim.get_resource::<RadiativeProducts>().is_some(),
            waves,
            fusion,
        )
    };
    let (passive, lean, fusion) = run(&desc);
    assert!(
        !passive && !fusion,
        "a LiDAR-only scene ran the passive solver"
    );
    let mut forced = desc.clone();
    forced.passive = Some(true);
    let (passive, full, fusion) = run(&forced);
    assert!(passive && !fusion);
    assert!(lean == full, "the passive run changed the LiDAR products");
    let mut fused = desc.clone();
    fused.lidars.as_mut().unwrap()[0].fusion = true;
    let (passive, _, fusion) = run(&fused);
    assert!(
        passive && fusion,
        "fusion: true did not ask for the passive run"
    );
    // The CLI says so, and writes the LiDAR products only.
    let out_dir =
        std::env::temp_dir().join(format!("lumenscape-lidar-only-{}", std::process::id()));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_lumenscape"))
        .args([
            "run",
            asset("assets/scenes/lidar_als.ron").to_str().unwrap(),
            "--out",
        ])
        .arg(&out_dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("passive solver: not run"), "{stdout}");
    assert!(!out_dir.join("summary.json").exists());
    assert!(out_dir.join("lidar").is_dir());
    let _ = std::fs::remove_dir_all(out_dir);
}

/// A scan longer than one chunk streams its waveforms to disk while it runs (memory bounded by
/// a chunk): the products are the same bytes as those written from memory, the in-memory
/// results (returns, photon-counting points, energies) are identical, no temporary file is
/// left, and a failed write leaves no partial product.
#[test]
fn streamed_lidar_scans_write_the_same_products_and_leave_nothing_behind() {
    use lumenscape::lidar::run::LidarProducts;
    use lumenscape::resources::scene::RunSettings;
    use lumenscape::scene::SceneSource;
    use lumenscape::scene::desc::{LidarPlatform, PhotonCountingDesc, PulsePattern};
    let (mut desc, _) = load_scene(&asset("assets/scenes/lidar_als.ron")).unwrap();
    {
        let l = &mut desc.lidars.as_mut().unwrap()[0];
        l.photons_per_pulse = Some(64);
        l.max_order = 20;
        // A few detected photons per shot (photon-counting regime).
        l.pulse_energy_j = 1e-10;
        if let LidarPlatform::Airborne { pulses, .. } = &mut l.platform {
            *pulses = PulsePattern::List(
                (0..40)
                    .map(|k| (0.3 + 0.09 * k as f64, 0.5 + 0.07 * k as f64))
                    .collect(),
            );
        }
        // The fusion product (passive radiance per pulse) and photon counting (dark counts and
        // solar background per chunk).
        l.fusion = true;
        l.photon_counting = Some(PhotonCountingDesc {
            quantum_efficiency: 0.5,
            dead_time_ns: 2.5,
            dark_count_hz: 1e6,
            filter_bandwidth_nm: 0.03,
            wavelength_nm: 1064.0,
            shots: 2,
        });
    }
    let root = std::env::temp_dir().join(format!("lumenscape-stream-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let run = |chunk: usize, out: Option<&std::path::Path>| {
        let settings = RunSettings {
            lidar_chunk_pulses: chunk,
            // The passive run (photon-counting background) is not what is tested here.
            preset: Some(lumenscape::scene::desc::Preset::Preview),
            ..Default::default()
        };
        let mut sim = Simulation::from_desc(&desc, &SceneSource::generated(), settings)
            .unwrap_or_else(|e| panic!("{e}"));
        let res = sim.run(out).map(|_| ());
        (sim, res)
    };
    // Every pulse's entry (energies, returns, background rate, fused radiance) and every
    // detection, read from memory or from the spools.
    let summary = |sim: &Simulation| {
        let r = &sim.resource::<LidarProducts>().0[0];
        let entries: Vec<_> = r
            .pulse_entries()
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        let counted: Vec<_> = r
            .counted_photons()
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        assert_eq!(entries.len(), 40);
        assert!(
            entries
                .iter()
                .all(|e| e.fusion_radiance.is_some() && e.background_rate_hz.is_some())
        );
        (
            format!("{entries:?}"),
            format!("{counted:?}"),
            r.streamed.is_some(),
            r.counted_totals(),
        )
    };
    // The same scan from memory (one chunk) and streamed (chunks of 7, the last one partial).
    let (a_dir, b_dir) = (root.join("memory"), root.join("streamed"));
    let (sim_a, res) = run(8192, Some(&a_dir));
    res.unwrap();
    let (sim_b, res) = run(7, Some(&b_dir));
    res.unwrap();
    let (a, b) = (summary(&sim_a), summary(&sim_b));
    assert!(
        !a.2 && b.2,
        "streamed only with an output folder and > 1 chunk"
    );
    assert!(!b.1.is_empty(), "no photon-counting points");
    assert_eq!(
        a.0, b.0,
        "streaming changed returns, energies or fused radiances"
    );
    assert_eq!(a.1, b.1, "streaming changed the photon-counting points");
    assert_eq!(a.3, b.3, "streaming changed the detection counts");
    // Streamed: only the quick-looks' pulses (with their waveforms) stay in memory, and
    // nothing of the per-pulse vectors.
    let rb = &sim_b.resource::<LidarProducts>().0[0];
    let kept = lumenscape::lidar::products::QUICKLOOKS;
    assert_eq!(rb.pulses.len(), kept);
    assert!(rb.pulses.iter().all(|p| p.raw.n_bins() > 0));
    assert!(rb.counted.is_empty() && rb.background_rate_hz.is_empty());
    assert!(rb.fusion_radiance.is_none() && rb.has_fusion());
    drop((sim_a, sim_b));
    // Every file under lidar/ is the same bytes (lidar.json without its timings); none is a
    // leftover temporary file.
    fn files(dir: &std::path::Path) -> Vec<PathBuf> {
        let mut v = Vec::new();
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                v.extend(files(&p));
            } else {
                v.push(p);
            }
        }
        v.sort();
        v
    }
    let rel = |d: &std::path::Path| -> Vec<PathBuf> {
        files(&d.join("lidar"))
            .into_iter()
            .map(|p| p.strip_prefix(d).unwrap().to_path_buf())
            .collect()
    };
    let names = rel(&a_dir);
    assert_eq!(names, rel(&b_dir));
    for f in [
        "raw/waveforms.f32",
        "returns.las",
        "fusion.las",
        "photon_counting.las",
    ] {
        assert!(names.iter().any(|p| p.ends_with(f)), "no {f}");
    }
    for p in &names {
        let name = p.file_name().unwrap().to_string_lossy();
        assert!(
            !name.starts_with('.'),
            "temporary file left: {}",
            p.display()
        );
        let (x, y) = (
            std::fs::read(a_dir.join(p)).unwrap(),
            std::fs::read(b_dir.join(p)).unwrap(),
        );
        if name == "lidar.json" {
            let strip = |b: &[u8]| {
                let mut v: serde_json::Value = serde_json::from_slice(b).unwrap();
                let o = v.as_object_mut().unwrap();
                o.remove("seconds");
                o.remove("pulses_per_second_per_core");
                v
            };
            assert_eq!(strip(&x), strip(&y), "{}", p.display());
        } else {
            assert!(x == y, "{} differs when streamed", p.display());
        }
    }
    // A write that fails at the end (the data file's name is taken by a folder) reports the
    // file and leaves no temporary or partial waveform file.
    let d_dir = root.join("fails");
    let inst = d_dir.join("lidar").join("als");
    std::fs::create_dir_all(inst.join("waveforms.f32")).unwrap();
    let (sim_d, res) = run(7, Some(&d_dir));
    let err = res.expect_err("a taken file name did not fail").to_string();
    assert!(err.contains("waveforms.f32"), "{err}");
    drop(sim_d);
    for p in files(&inst) {
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            !name.starts_with('.') && !name.starts_with("waveforms"),
            "left behind after the error: {}",
            p.display()
        );
    }
    let _ = std::fs::remove_dir_all(&root);
}
