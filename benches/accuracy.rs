//! Flux-tracking accuracy against cell size (harness = false): the horizontally homogeneous
//! turbid layer (spherical LAD, bi-Lambertian leaves, no hotspot: the medium DISORT solves
//! exactly) for every LAI, sun zenith and band of the DISORT oracle
//! (`assets/reference/turbid_canopy_disort_ext.csv`: LAI 1, 3, 5, sun zenith 0, 20, 35, 50°), at each cell size. Prints, per cell size, the
//! worst BRF error (principal plane, view zenith −75…75°) and the worst albedo, absorption and
//! transmission errors over all cases, with the wall time, so that the table reads as error
//! against cost; `--detail` prints every case.
//!
//! `cargo bench --bench accuracy` (default preset, 100 directions, cells 1, 0.5, 0.25, 0.2 m,
//! layer 2 m high on 1 m × 1 m). Options: `-- --cells 1,0.5` the cell sizes (m), `--preset
//! reference|default|preview`, `--dirs N`, `--lai 1,3`, `--sza 0,20`, `--per-direction` (interception stored per incident
//! direction instead of per angular sector), `--detail`.

use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::{LadDesc, Preset};
use lumenscape::scene::generators::BandOptics;
use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
use lumenscape::simulation::Simulation;
use std::collections::BTreeMap;
use std::time::Instant;

mod common;

/// `--name a,b,c` as numbers, or `default`.
fn list(args: &[String], name: &str, default: &[f64]) -> Vec<f64> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map_or(default.to_vec(), |x| {
            x.split(',')
                .map(|c| c.parse().unwrap_or_else(|_| panic!("{name} A,B,…")))
                .collect()
        })
}

/// One oracle case: (LAI, band index, sun zenith) → rows (signed view zenith, BRF) and the
/// albedo, canopy absorption and soil irradiance (direct + diffuse).
struct Case {
    brf: Vec<(f64, f64)>,
    albedo: f64,
    a_canopy: f64,
    t_soil: f64,
}

fn oracle() -> BTreeMap<(u64, usize, u64), Case> {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/reference/turbid_canopy_disort_ext.csv"
    ))
    .expect("oracle");
    let mut cases: BTreeMap<(u64, usize, u64), Case> = BTreeMap::new();
    for l in text.lines().skip(1) {
        let r: Vec<f64> = l
            .split(',')
            .enumerate()
            .map(|(i, x)| {
                if i == 1 {
                    if x == "red" { 0.0 } else { 1.0 }
                } else {
                    x.parse().expect("oracle number")
                }
            })
            .collect();
        let key = (r[0].to_bits(), r[1] as usize, r[2].to_bits());
        let c = cases.entry(key).or_insert(Case {
            brf: Vec::new(),
            albedo: r[5],
            a_canopy: r[8],
            t_soil: r[6] + r[7],
        });
        c.brf.push((r[3], r[4]));
    }
    cases
}

fn run(
    lai: f64,
    sza: f64,
    cell: f64,
    preset: Preset,
    dirs: usize,
    per_direction: bool,
) -> (f64, RadiativeProducts) {
    let mut d = turbid_layer(&TurbidLayerParams {
        lai,
        lad: LadDesc::Spherical,
        bands: vec![BandOptics::red(), BandOptics::nir()],
        height_m: 2.0,
        cell_m: cell,
        size_m: 1.0,
        sun_zenith_deg: sza,
        sun_azimuth_deg: 0.0,
    });
    common::no_hotspot(&mut d);
    d.directions.as_mut().expect("directions").count = dirs;
    if per_direction {
        d.radiative
            .get_or_insert_with(Default::default)
            .per_direction_stores = Some(true);
    }
    let t0 = Instant::now();
    let mut sim = Simulation::from_desc(
        &d,
        &SceneSource::generated(),
        RunSettings {
            preset: Some(preset),
            ..Default::default()
        },
    )
    .expect("scene");
    sim.run(None).expect("run");
    (
        t0.elapsed().as_secs_f64(),
        sim.resource::<RadiativeProducts>().clone(),
    )
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let cells = list(&args, "--cells", &[1.0, 0.5, 0.25, 0.2]);
    let preset = match args
        .iter()
        .position(|a| a == "--preset")
        .and_then(|i| args.get(i + 1))
        .map(String::as_str)
    {
        None | Some("default") => Preset::Default,
        Some("reference") => Preset::Reference,
        Some("preview") => Preset::Preview,
        Some(p) => panic!("--preset default|reference|preview, not {p}"),
    };
    let dirs = list(&args, "--dirs", &[100.0])[0] as usize;
    let detail = args.iter().any(|a| a == "--detail");
    let per_direction = args.iter().any(|a| a == "--per-direction");
    let cases = oracle();
    let lais = list(&args, "--lai", &[]);
    let szas = list(&args, "--sza", &[]);
    let wanted: Vec<(f64, f64)> = {
        let mut v: Vec<(f64, f64)> = cases
            .keys()
            .map(|&(l, _, s)| (f64::from_bits(l), f64::from_bits(s)))
            .filter(|(l, s)| {
                (lais.is_empty() || lais.contains(l)) && (szas.is_empty() || szas.contains(s))
            })
            .collect();
        v.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
        v.dedup();
        v
    };
    println!(
        "turbid layer 2 m high, {preset:?} preset, {dirs} directions; errors against DISORT over LAI × sun zenith {wanted:?} × (red, NIR); BRF: principal plane −75…75°"
    );
    println!(
        "{:>6} {:>9} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "cell_m", "wall_s", "worstBRF%", "meanBRF%", "albedo%", "fabs%", "ftran%"
    );
    for &cell in &cells {
        let (mut wall, mut wb, mut sb, mut nb, mut wa, mut wf, mut wt) =
            (0.0, 0.0f64, 0.0, 0usize, 0.0f64, 0.0f64, 0.0f64);
        for &(lai, sza) in &wanted {
            let (t, p) = run(lai, sza, cell, preset, dirs, per_direction);
            wall += t;
            for band in 0..2 {
                let c = &cases[&(lai.to_bits(), band, sza.to_bits())];
                let b = &p.bands[band];
                let mut case_worst = 0.0f64;
                let mut line = String::new();
                for &(vz, brf) in &c.brf {
                    let az = if vz >= 0.0 { 0.0 } else { 180.0 };
                    let got = p.brf_at(band, vz.abs(), az).expect("view").brf;
                    let e = got / brf - 1.0;
                    case_worst = case_worst.max(e.abs());
                    sb += e.abs();
                    nb += 1;
                    line += &format!(" {:+.2}", 100.0 * e);
                }
                let ea = b.albedo / c.albedo - 1.0;
                let ef = b.fabs / c.a_canopy - 1.0;
                let et = b.ftran / c.t_soil - 1.0;
                wb = wb.max(case_worst);
                wa = wa.max(ea.abs());
                wf = wf.max(ef.abs());
                wt = wt.max(et.abs());
                if detail {
                    println!(
                        "  cell {cell} LAI {lai} sza {sza} {}: BRF % by vz{line} | albedo {:+.3} % fabs {:+.3} % ftran {:+.3} % closure {:.1e}",
                        ["red", "NIR"][band],
                        100.0 * ea,
                        100.0 * ef,
                        100.0 * et,
                        b.energy_closure
                    );
                }
            }
        }
        println!(
            "{:>6} {:>9.3} {:>10.3} {:>10.3} {:>10.3} {:>10.3} {:>10.3}",
            cell,
            wall,
            100.0 * wb,
            100.0 * sb / nb as f64,
            100.0 * wa,
            100.0 * wf,
            100.0 * wt
        );
    }
}
