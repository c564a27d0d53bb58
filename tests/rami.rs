//! RAMI benchmark scenes (issue 8): the generators reproduce the published RAMI-3 parameters,
//! the `.mes` writer and reader round-trip, and small HOM cases run end to end through both
//! solvers into ROMC files that are parsed back and checked against exact identities and the
//! DISORT oracle (`assets/reference/turbid_canopy_disort.csv`).
//!
//! Statistical checks are z-tests at Z = 4 with fixed seeds (as in `photon_oracles.rs`), each
//! with an assertion that the standard error is small enough to mean something.

mod common;
use common::disort_rows;
use lumenscape::cli::rami as rami_cli;
use lumenscape::io::rami_mes::*;
use lumenscape::photon::engine::SamplerKind;
use lumenscape::resources::maket_report::MaketReport;
use lumenscape::resources::scene::{RunSettings, Solver};
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::*;
use lumenscape::scene::generators::rami::*;
use lumenscape::simulation::{Simulation, Stage};
use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::{Path, PathBuf};

const Z: f64 = 4.0;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lumenscape-rami-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn opts() -> RamiOptions {
    RamiOptions::default()
}

fn band_optics(d: &SceneDesc) -> (f64, f64, f64) {
    let (r, t) = match &d.optics["leaf"] {
        OpticsDesc::BiLambertian {
            reflectance,
            transmittance,
        } => (reflectance[0], transmittance[0]),
        o => panic!("leaf optics {o:?}"),
    };
    let s = match &d.optics["soil"] {
        OpticsDesc::Lambertian { reflectance, .. } => reflectance[0],
        o => panic!("soil optics {o:?}"),
    };
    (r, t, s)
}

fn turbid_of(d: &SceneDesc) -> (LadDesc, f64) {
    match &d.optics["vegetation"] {
        OpticsDesc::Turbid {
            lad, leaf_size_m, ..
        } => (lad.clone(), *leaf_size_m),
        o => panic!("vegetation optics {o:?}"),
    }
}

/// The published optics of a band tag (module table of `generators::rami`).
fn published_optics(tag: &str) -> (f64, f64, f64) {
    match tag {
        "RED" => (0.0546, 0.0149, 0.127),
        "NIR" => (0.4957, 0.4409, 0.159),
        "NR1" => (0.5, 0.5, 1.0),
        t => panic!("{t}"),
    }
}

fn check_common(d: &SceneDesc, case: &RamiCase, id: &str) {
    let tag = id.split('_').nth(3).unwrap();
    assert_eq!(band_optics(d), published_optics(tag), "{id}");
    assert_eq!(d.illumination.sun_zenith_deg, Some(case.sun_zenith_deg));
    assert_eq!(d.illumination.sun_azimuth_deg, Some(0.0));
    assert_eq!(d.grid.boundary, BoundaryMode::Repetitive);
    let dirs = d.directions.as_ref().unwrap();
    assert_eq!(dirs.exact.len(), 2 * VIEWS_PER_PLANE, "{id}");
    lumenscape::scene::validate::validate(d, &SceneSource::generated())
        .unwrap_or_else(|e| panic!("{id}: {e}"));
}

#[test]
fn hom_generators_reproduce_the_published_parameters() {
    let mut n = 0;
    for (scene, rep, lnds, bands, szas) in PUBLISHED.iter().filter(|p| p.0.starts_with("HOM")) {
        let (lai, height) = match *scene {
            "HOM01" | "HOM11" => (1.0, 1.0),
            "HOM02" | "HOM12" => (2.0, 1.0),
            "HOM03" | "HOM13" => (3.0, 2.0),
            "HOM05" | "HOM15" => (5.0, 1.0),
            s => panic!("{s}"),
        };
        for lnd in *lnds {
            let lad = match *lnd {
                "ERE" => LadDesc::Erectophile,
                "PLA" => LadDesc::Planophile,
                "UNI" => LadDesc::Spherical,
                l => panic!("{l}"),
            };
            for band in *bands {
                for sza in *szas {
                    let id = format!("{scene}_{rep}_{lnd}_{band}_{sza:02}");
                    let case = RamiCase::parse(&id).unwrap();
                    let size = 2.0;
                    let d = rami_hom(
                        &case,
                        &RamiOptions {
                            size_m: Some(size),
                            ..opts()
                        },
                    )
                    .unwrap();
                    check_common(&d, &case, &id);
                    let (tl, leaf_size) = turbid_of(&d);
                    if *rep == "TUR" {
                        assert_eq!(tl, lad, "{id}");
                        assert_eq!(leaf_size, 0.0, "{id}: dimensionless scatterers");
                        let plot = d
                            .objects
                            .iter()
                            .find_map(|o| match o {
                                ObjectDesc::TurbidPlot(p) => Some(p),
                                _ => None,
                            })
                            .unwrap();
                        assert_eq!(plot.foliage, FoliageDesc::Lai(lai), "{id}");
                        assert_eq!((plot.bottom_m, plot.top_m), (0.0, height), "{id}");
                    } else {
                        let leaves = d
                            .objects
                            .iter()
                            .find_map(|o| match o {
                                ObjectDesc::Leaves(l) => Some(l),
                                _ => None,
                            })
                            .unwrap();
                        assert_eq!(leaves.radius_m, 0.1, "{id}");
                        // LAI from the leaf count: exact to within half a disc.
                        let disc = PI * 0.1 * 0.1;
                        let got = leaves.disks.len() as f64 * disc / (size * size);
                        assert!(
                            (got - lai).abs() <= 0.5 * disc / (size * size),
                            "{id}: LAI {got}"
                        );
                        for &(x, y, z, nx, ny, nz) in &leaves.disks {
                            let st =
                                (nx * nx + ny * ny).sqrt() / (nx * nx + ny * ny + nz * nz).sqrt();
                            assert!((0.0..size).contains(&x) && (0.0..size).contains(&y));
                            assert!(z >= 0.1 * st - 1e-12 && z <= height - 0.1 * st + 1e-12);
                        }
                    }
                    n += 1;
                }
            }
        }
    }
    assert_eq!(n, 52, "number of published HOM experiments");
}

/// ∫₀^{π/2} g(θ) f(θ) dθ by Simpson's rule (2000 intervals).
fn lad_moment(f: impl Fn(f64) -> f64, g: impl Fn(f64) -> f64) -> f64 {
    let n = 2000;
    let h = FRAC_PI_2 / n as f64;
    (0..=n)
        .map(|i| {
            let t = i as f64 * h;
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * f(t) * g(t)
        })
        .sum::<f64>()
        * h
        / 3.0
}

/// z-test of the mean leaf inclination of generated discs against the LAD's (the generator must
/// not bias orientations when it rejects intersecting discs).
fn check_inclinations(leaves: &LeavesDesc, f: impl Fn(f64) -> f64, what: &str) {
    let mean = lad_moment(&f, |t| t);
    let var = lad_moment(&f, |t| t * t) - mean * mean;
    let n = leaves.disks.len() as f64;
    let got = leaves
        .disks
        .iter()
        .map(|&(_, _, _, nx, ny, nz)| (nx * nx + ny * ny).sqrt().atan2(nz.abs()))
        .sum::<f64>()
        / n;
    let se = (var / n).sqrt();
    let z = (got - mean).abs() / se;
    eprintln!(
        "{what} inclinations: mean {:.3}° vs LAD {:.3}° (SE {:.3}°, z {z:.2})",
        got.to_degrees(),
        mean.to_degrees(),
        se.to_degrees()
    );
    assert!(z <= Z, "{what}: z {z:.2}");
    assert!(se.to_degrees() < 0.3, "{what}: too few discs to test");
}

fn leaves_of(d: &SceneDesc) -> &LeavesDesc {
    d.objects
        .iter()
        .find_map(|o| match o {
            ObjectDesc::Leaves(l) => Some(l),
            _ => None,
        })
        .unwrap()
}

/// The full-size HOM13 canopy has exactly the disc count of RAMI's leaf file (59 683 discs of
/// radius 0.1 m on 25 × 25 m², LAI 3) and planophile normals; HOM03_DIS has erectophile ones.
#[test]
fn discrete_hom_scenes_match_the_rami_leaf_file_and_lnd() {
    let case = RamiCase::parse("HOM13_DIS_PLA_NIR_20").unwrap();
    let d = rami_hom(&case, &opts()).unwrap();
    assert_eq!(d.grid.size_m, (25.0, 25.0));
    let leaves = leaves_of(&d);
    assert_eq!(leaves.disks.len(), 59_683);
    let lai = leaves.disks.len() as f64 * PI * 0.01 / 625.0;
    assert!((lai - 3.0).abs() < 1e-5, "LAI {lai}");
    check_inclinations(
        leaves,
        |t| 2.0 / PI * (1.0 + (2.0 * t).cos()),
        "HOM13 planophile",
    );
    let case = RamiCase::parse("HOM03_DIS_ERE_RED_50").unwrap();
    let d = rami_hom(
        &case,
        &RamiOptions {
            size_m: Some(10.0),
            ..opts()
        },
    )
    .unwrap();
    check_inclinations(
        leaves_of(&d),
        |t| 2.0 / PI * (1.0 - (2.0 * t).cos()),
        "HOM03 erectophile",
    );
}

#[test]
fn het_generators_reproduce_the_published_parameters() {
    for id in [
        "HET01_DIS_UNI_RED_20",
        "HET01_DIS_UNI_NIR_50",
        "HET01_DIS_UNI_NR1_20",
        "HET02_TUR_UNI_NIR_20",
    ] {
        let case = RamiCase::parse(id).unwrap();
        let d = rami_het01(&case, &opts()).unwrap();
        check_common(&d, &case, id);
        assert_eq!(d.grid.size_m, (100.0, 100.0));
        assert_eq!(d.grid.height_m, Some(30.0));
        let (lad, leaf_size) = turbid_of(&d);
        assert_eq!(lad, LadDesc::Spherical, "RAMI 'uniform' normals");
        assert_eq!(leaf_size, if id.starts_with("HET01") { 0.1 } else { 0.0 });
        let crowns: Vec<(f64, f64, &CrownDesc)> = d
            .objects
            .iter()
            .filter_map(|o| match o {
                ObjectDesc::Tree(t) => Some((t.position_m.0, t.position_m.1, &t.crown)),
                _ => None,
            })
            .collect();
        assert_eq!(crowns.len(), 15, "{id}");
        for (i, (x, y, c)) in crowns.iter().enumerate() {
            assert_eq!(c.shape, CrownShape::Ellipsoid);
            assert_eq!((c.radius_x_m, c.radius_y_m, c.height_m), (10.0, None, 20.0));
            assert_eq!(c.foliage, FoliageDesc::Lai(5.0));
            let zc = c.base_height_m + 10.0;
            assert!((11.0..=19.0).contains(&zc), "{id}: centre height {zc}");
            // Disjoint horizontal projections (periodic): the covered fraction is Σ π r² / A.
            for (x2, y2, _) in &crowns[..i] {
                let dx = (x - x2) - 100.0 * ((x - x2) / 100.0).round();
                let dy = (y - y2) - 100.0 * ((y - y2) / 100.0).round();
                assert!(dx.hypot(dy) >= 20.0 - 1e-9);
            }
        }
        let cover = 15.0 * PI * 100.0 / 1e4;
        assert!(
            (cover - 0.471).abs() < 5e-4,
            "published coverage 0.471, got {cover}"
        );
    }
    assert!(RamiCase::parse("HET01_TUR_UNI_RED_20").is_err());
}

/// A HET01 scene built from a (small) one-sphere leaf file instances it in every sphere: the
/// Maket leaf area is exactly 15 × the file's.
#[test]
fn het01_leaf_file_is_instanced_in_every_sphere() {
    let dir = tmp("het-leaves");
    let file = dir.join("sphere.txt");
    std::fs::write(
        &file,
        "0.1 0 0 0 0 0 1\n0.1 3 -2 4 0.6 0 0.8\n0.1 -5 5 -6 1 0 0\n",
    )
    .unwrap();
    let case = RamiCase::parse("HET01_DIS_UNI_NIR_20").unwrap();
    let d = rami_het01(
        &case,
        &RamiOptions {
            cell_m: Some(5.0),
            leaves: Some(file.to_string_lossy().into_owned()),
            ..opts()
        },
    )
    .unwrap();
    let lists: Vec<&LeafListDesc> = d
        .objects
        .iter()
        .filter_map(|o| match o {
            ObjectDesc::LeafList(l) => Some(l),
            _ => None,
        })
        .collect();
    assert_eq!(lists.len(), 15);
    let centres = het_sphere_centres(1).unwrap();
    for (l, c) in lists.iter().zip(&centres) {
        assert_eq!(l.translation_m, *c);
        assert!(l.wrap);
    }
    let mut sim =
        Simulation::from_desc(&d, &SceneSource::generated(), RunSettings::default()).unwrap();
    sim.run_stage(Stage::Maket).unwrap();
    let got = sim.resource::<MaketReport>().facet_area_m2["leaf"];
    let want = 15.0 * 3.0 * PI * 0.01;
    assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Values with up to 6 decimals survive writing and reading; writing what was read gives the
/// same bytes.
#[test]
fn mes_writer_round_trips() {
    let view = |vz: f64, p: Plane, k: f64| PlaneView {
        view_zenith_deg: vz,
        view_azimuth_deg: p.view_azimuth_deg(vz, 0.0),
        brf: 0.3 + 0.01 * k.sin(),
        brf_se: Some(1e-3 * (1.0 + k.cos().abs())),
        co_sgl: Some(0.1 + 0.001 * k),
        uc_sgl: Some(0.05),
        mlt: Some(0.15 + 0.01 * k.sin() - 0.001 * k),
        components_se: Some([1e-4, 2e-5, 3e-4 * (1.0 + k.cos().abs())]),
        estimator: Some("peel-off".into()),
    };
    let plane = |p: Plane| {
        signed_view_zeniths_deg()
            .into_iter()
            .enumerate()
            .map(|(i, vz)| view(vz, p, i as f64))
            .collect::<Vec<_>>()
    };
    let m = RamiMeasurements {
        experiment: "HOM13_DIS_PLA_NIR_20".into(),
        model: "lumen".into(),
        band: "nir".into(),
        solver: "monte-carlo".into(),
        sun_zenith_deg: 20.0,
        sun_azimuth_deg: 0.0,
        brfpp: plane(Plane::Principal),
        brfop: plane(Plane::Orthogonal),
        brf1: 0.4123456789,
        brf1_se: Some(2.5e-3),
        fabs: 0.161234567,
        fabs_se: Some(1e-3),
        ftran: 0.50987654,
        ftran_se: None,
    };
    let files = m.mes_files();
    assert_eq!(files.len(), 11);
    let mut seen = BTreeMap::new();
    for (name, text) in &files {
        let (meas, content) = parse_mes(name, text).unwrap();
        seen.insert(meas.id(), ());
        match content {
            MesContent::Brf(t) => {
                assert_eq!(write_brf_table(&t), *text, "{name}: bytes differ");
                assert_eq!(t.ratio_filtered_rays, -1.0);
                match meas {
                    Measurement::Brf(p, c) => {
                        assert_eq!(t.rows.len(), 76);
                        for (r, v) in t.rows.iter().zip(m.plane(p)) {
                            assert!((r.brf - v.component(c).unwrap()).abs() <= 5e-7);
                            assert!((r.sza_rad - 20f64.to_radians()).abs() <= 5e-7);
                            assert!(
                                (r.vza_rad - v.view_zenith_deg.abs().to_radians()).abs() <= 5e-7
                            );
                            let cs = v.components_se.unwrap();
                            let se = match c {
                                Component::Total => v.brf_se.unwrap(),
                                Component::CoSgl => cs[0],
                                Component::UcSgl => cs[1],
                                Component::Mlt => cs[2],
                            };
                            assert!((r.std_dev - se).abs() <= 5e-7);
                        }
                    }
                    Measurement::Brf1 => {
                        assert!((t.rows[0].brf - 0.412346).abs() < 1e-12);
                        assert!((t.rows[0].std_dev - 0.0025).abs() < 1e-12);
                    }
                    _ => unreachable!(),
                }
            }
            MesContent::Percent(x) => {
                assert_eq!(write_percent(x), *text);
                let want = if meas == Measurement::Fabs {
                    16.1234567
                } else {
                    50.987654
                };
                assert!((x - want).abs() <= 5e-7, "{name}: {x}");
            }
        }
    }
    assert_eq!(seen.len(), 11);
    // Malformed content is reported with its line.
    let (name, text) = &files[0];
    let broken = text.replacen("\t", " x", 5);
    let e = parse_mes(name, &broken).unwrap_err();
    assert!(e.to_string().contains(name) && e.line >= 1, "{e}");
}

struct RunOut {
    dir: PathBuf,
    summary: serde_json::Value,
}

fn run(d: &SceneDesc, solver: Solver, name: &str) -> RunOut {
    let settings = RunSettings {
        solver,
        preset: (!solver.is_monte_carlo()).then_some(Preset::Preview),
        ..Default::default()
    };
    let dir = tmp(name);
    let mut sim = Simulation::from_desc(d, &SceneSource::generated(), settings)
        .unwrap_or_else(|e| panic!("{e}"));
    sim.run(Some(&dir)).unwrap_or_else(|e| panic!("{e}"));
    let summary =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    RunOut { dir, summary }
}

/// `lumenscape rami-mes` on a run: returns the parsed files and measurements.json.
fn convert(r: &RunOut, case: &str) -> (BTreeMap<String, MesContent>, RamiMeasurements) {
    let mut log = Vec::new();
    rami_cli::run(
        &rami_cli::Args {
            run: r.dir.clone(),
            case: case.into(),
            model: "lumen".into(),
            band: None,
            out: None,
        },
        &mut log,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let out = r.dir.join("rami");
    let mut files = BTreeMap::new();
    for e in std::fs::read_dir(&out).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if name.ends_with(".mes") {
            let (m, c) = parse_mes(&name, &std::fs::read_to_string(&p).unwrap())
                .unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(name, file_name(m, "lumen", case));
            files.insert(m.id(), c);
        }
    }
    let json: RamiMeasurements =
        serde_json::from_str(&std::fs::read_to_string(out.join("measurements.json")).unwrap())
            .unwrap();
    (files, json)
}

fn table<'a>(f: &'a BTreeMap<String, MesContent>, id: &str) -> &'a BrfTable {
    match &f[id] {
        MesContent::Brf(t) => t,
        c => panic!("{id}: {c:?}"),
    }
}

fn percent(f: &BTreeMap<String, MesContent>, id: &str) -> f64 {
    match &f[id] {
        MesContent::Percent(x) => *x / 100.0,
        c => panic!("{id}: {c:?}"),
    }
}

/// Checks shared by every run: the file set, finite values, the RAMI components adding up to
/// the BRF (Monte Carlo), and the energy identity brf1 + fabs + (1 − ρ_soil) ftran = 1 − lost
/// (ground absorption of a Lambertian soil is (1 − ρ_soil) × what reaches it; `lost` is the
/// run's lost fraction, plus the Russian-roulette balance in Monte Carlo).
fn check_files(f: &BTreeMap<String, MesContent>, r: &RunOut, soil: f64, mc: bool, what: &str) {
    assert_eq!(f.len(), if mc { 11 } else { 5 }, "{what}: {:?}", f.keys());
    for p in ["brfpp", "brfop"] {
        let t = table(f, p);
        assert_eq!(t.rows.len(), 76);
        for (i, row) in t.rows.iter().enumerate() {
            assert!(row.brf.is_finite() && row.brf >= 0.0, "{what} {p} row {i}");
            assert_eq!(row.std_dev >= 0.0, mc, "{what}: std dev column");
            if mc {
                let parts: f64 = ["_co_sgl", "_uc_sgl", "_mlt"]
                    .iter()
                    .map(|c| table(f, &format!("{p}{c}")).rows[i].brf)
                    .sum();
                // Each value is rounded to 6 decimals in the files.
                assert!(
                    (parts - row.brf).abs() <= 2e-6,
                    "{what} {p} row {i}: parts {parts} vs {}",
                    row.brf
                );
            }
        }
    }
    let b = &r.summary["bands"][0];
    let mut lost = b["flost"].as_f64().unwrap();
    if mc {
        lost += r.summary["monte_carlo"]["roulette_balance"][0]
            .as_f64()
            .unwrap();
    }
    let brf1 = table(f, "brf1").rows[0].brf;
    let sum = brf1 + percent(f, "fabs") + (1.0 - soil) * percent(f, "ftran") + lost;
    assert!(
        (sum - 1.0).abs() <= 2e-6,
        "{what}: energy identity off by {:e}",
        sum - 1.0
    );
}

/// HOM03_TUR_UNI_{NIR}_20 is the DISORT oracle's case (spherical LAD, no hot spot, LAI 3,
/// sun 20°): the Monte Carlo run converted to .mes files matches DISORT at the RAMI views it
/// shares (±15°, ±45°, ±75°), and in brf1, fabs and ftran. Flux tracking (preview) writes the
/// files without the scattering-order parts.
#[test]
fn hom_turbid_case_runs_end_to_end_and_matches_disort() {
    let id = "HOM03_TUR_UNI_NIR_20";
    let d = rami_hom(&RamiCase::parse(id).unwrap(), &opts()).unwrap();
    let rows: Vec<Vec<String>> = disort_rows()
        .into_iter()
        .filter(|r: &Vec<String>| r[0] == "3" && r[1] == "nir" && r[2] == "20")
        .collect();
    assert_eq!(rows.len(), 11);
    let mc = run(
        &d,
        Solver::MonteCarlo {
            photons: 20_000,
            sampler: SamplerKind::Continuous,
        },
        "hom03-mc",
    );
    let (f, m) = convert(&mc, id);
    check_files(&f, &mc, 0.159, true, "HOM03 MC");
    let pp = table(&f, "brfpp");
    let mut worst: f64 = 0.0;
    let mut compared = 0;
    for r in &rows {
        // DISORT: vz > 0 on the sun side; RAMI: negative on the sun side.
        let vz_rami = -r[3].parse::<f64>().unwrap();
        let Some(i) = signed_view_zeniths_deg().iter().position(|v| *v == vz_rami) else {
            continue;
        };
        let want: f64 = r[4].parse().unwrap();
        let (got, se) = (pp.rows[i].brf, pp.rows[i].std_dev);
        let z = (got - want).abs() / se;
        worst = worst.max(z);
        assert!(
            z <= Z,
            "brfpp {vz_rami}: {got} ± {se} vs DISORT {want} (z {z:.2})"
        );
        assert!(se < 0.02 * want, "SE {se} too large");
        compared += 1;
    }
    assert_eq!(compared, 6);
    let r = &rows[0];
    let v = |k: usize| r[k].parse::<f64>().unwrap();
    for (what, got, se, want) in [
        (
            "brf1",
            table(&f, "brf1").rows[0].brf,
            m.brf1_se.unwrap(),
            v(5),
        ),
        ("fabs", percent(&f, "fabs"), m.fabs_se.unwrap(), v(8)),
        (
            "ftran",
            percent(&f, "ftran"),
            m.ftran_se.unwrap(),
            v(6) + v(7),
        ),
    ] {
        let z = (got - want).abs() / se;
        worst = worst.max(z);
        assert!(z <= Z, "{what}: {got} ± {se} vs DISORT {want} (z {z:.2})");
        assert!(se < 0.02 * want, "{what}: SE {se} too large");
    }
    eprintln!("HOM03_TUR_UNI_NIR_20 Monte Carlo .mes vs DISORT: worst |z| {worst:.2}");
    // The sun-zenith tag must match the run.
    let e = rami_cli::run(
        &rami_cli::Args {
            run: mc.dir.clone(),
            case: "HOM03_TUR_UNI_NIR_50".into(),
            model: "lumen".into(),
            band: None,
            out: Some(mc.dir.join("other")),
        },
        &mut Vec::new(),
    )
    .unwrap_err();
    assert!(e.contains("sun zenith"), "{e}");

    let ft = run(&d, Solver::FluxTracking, "hom03-ft");
    let (f, _) = convert(&ft, id);
    check_files(&f, &ft, 0.159, false, "HOM03 flux tracking");
    for p in [&mc, &ft] {
        std::fs::remove_dir_all(&p.dir).ok();
    }
}

/// A small discrete case (HOM13 on 0.5 × 0.5 m: 24 discs) runs end to end through both solvers.
#[test]
fn small_discrete_hom_case_runs_end_to_end() {
    let id = "HOM13_DIS_PLA_RED_20";
    let d = rami_hom(
        &RamiCase::parse(id).unwrap(),
        &RamiOptions {
            size_m: Some(0.5),
            ..opts()
        },
    )
    .unwrap();
    assert_eq!(leaves_of(&d).disks.len(), 24);
    let mc = run(
        &d,
        Solver::MonteCarlo {
            photons: 4_000,
            sampler: SamplerKind::Continuous,
        },
        "hom13-mc",
    );
    let (f, m) = convert(&mc, id);
    check_files(&f, &mc, 0.127, true, "HOM13 MC");
    assert_eq!(m.band, "red");
    assert!(
        m.brfpp
            .iter()
            .all(|v| v.estimator.as_deref() == Some("peel-off"))
    );
    let ft = run(&d, Solver::FluxTracking, "hom13-ft");
    let (f, _) = convert(&ft, id);
    check_files(&f, &ft, 0.127, false, "HOM13 flux tracking");
    for p in [&mc, &ft] {
        std::fs::remove_dir_all(&p.dir).ok();
    }
}

/// `generate rami` prints the generator's scene; `rami-mes` refuses runs without the RAMI
/// views and bad model names.
#[test]
fn cli_generates_and_refuses_bad_runs() {
    use lumenscape::cli::generate::{Args, Kind, run as generate};
    let mut out = Vec::new();
    generate(
        &Args {
            kind: Kind::Rami {
                case: "HOM01_TUR_ERE_NR1_30".into(),
                size: None,
                cell_size: None,
                seed: 1,
                sun_azimuth: 0.0,
                leaves: None,
            },
        },
        &mut out,
    )
    .unwrap_or_else(|e| panic!("{}", e.message));
    let text = String::from_utf8(out).unwrap();
    let parsed = lumenscape::scene::parse_scene(&text, Path::new("gen.ron")).unwrap();
    let case = RamiCase::parse("HOM01_TUR_ERE_NR1_30").unwrap();
    assert_eq!(parsed, rami_hom(&case, &opts()).unwrap());

    let dir = tmp("bad-run");
    let summary = serde_json::json!({
        "solver": "flux-tracking",
        "settings": {"sun_zenith_deg": 30.0, "sun_azimuth_deg": 0.0},
        "bands": [{"band": "nr1", "albedo": 0.9, "fabs": 0.0, "ftran": 0.8,
                   "brf": [{"zenith_deg": 15.0, "azimuth_deg": 0.0, "kind": "exact", "brf": 0.9}]}]
    });
    std::fs::write(dir.join("summary.json"), summary.to_string()).unwrap();
    let args = |model: &str| rami_cli::Args {
        run: dir.clone(),
        case: "HOM01_TUR_ERE_NR1_30".into(),
        model: model.into(),
        band: None,
        out: None,
    };
    let e = rami_cli::run(&args("lumen"), &mut Vec::new()).unwrap_err();
    assert!(e.contains("generate rami"), "{e}");
    let e = rami_cli::run(&args("bad-name!"), &mut Vec::new()).unwrap_err();
    assert!(e.contains("model name"), "{e}");
    let e = rami_cli::run(
        &rami_cli::Args {
            run: dir.join("missing"),
            ..args("lumen")
        },
        &mut Vec::new(),
    )
    .unwrap_err();
    assert!(e.contains("summary.json"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
