//! Issue 7 in scenes: PROSPECT leaves integrated over band responses (shipped sensor SRFs, SRF
//! files, Gaussian and monochromatic bands), the sun from a date and a place (NREL SPA) resolved
//! into `SceneInfo`, and the bad-input cases, each naming its field and line.
//!
//! Expected values are recomputed here independently of the band-integration code: the SRFs are
//! read from the CSV files (or the Gaussian formula), and ∫ S X dλ / ∫ S dλ is a trapezoid sum
//! on a 0.01 nm grid of the linear interpolants of S and of the 1 nm PROSPECT spectrum.

mod common;
use common::asset;
use lumenscape::physics::prospect::{
    LeafSpectrum, ProspectData, ProspectModel, ProspectParams, prospect,
};
use lumenscape::resources::materials::{MaterialKind, Materials};
use lumenscape::resources::scene::{RunSettings, SceneInfo};
use lumenscape::scene::error::SceneError;
use lumenscape::simulation::Simulation;
use std::path::PathBuf;

/// A turbid layer seen by seven bands of every response form, a PROSPECT-D leaf (turbid), a
/// PROSPECT-5 leaf (disk leaves, as facets) and the sun from a date and place.
const SCENE: &str = r#"(
    version: 1,
    name: "prospect bands",
    grid: (size_m: (2.0, 2.0), cell_m: (0.5, 0.5, 0.5), boundary: Repetitive),
    bands: [
        (name: "green", sensor_band: ("sentinel2a_msi", "B03")),
        (name: "red", sensor_band: ("sentinel2a_msi", "B4")),
        (name: "nir", sensor_band: ("Sentinel-2A MSI", "b08")),
        (name: "swir", sensor_band: ("landsat8_oli", "B6"), wavelength_nm: 1610.0),
        (name: "edge", srf_file: "triangle_srf.csv"),
        (name: "g550", wavelength_nm: 550.0, fwhm_nm: 20.0),
        (name: "m670", wavelength_nm: 670.0),
    ],
    optics: {
        "leaf": ProspectLeaf(
            model: D,
            n: 1.5,
            cab_ug_cm2: 40.0,
            car_ug_cm2: 8.0,
            anth_ug_cm2: 1.0,
            cbrown: 0.0,
            cw_cm: 0.01,
            cm_g_cm2: 0.009,
        ),
        "old_leaf": ProspectLeaf(model: P5, n: 2.1, cab_ug_cm2: 60.0, car_ug_cm2: 10.0, cbrown: 0.1, cw_cm: 0.013, cm_g_cm2: 0.016),
        "veg": Turbid(leaf: "leaf", lad: Spherical),
        "soil": Lambertian(reflectance: [0.1, 0.12, 0.2, 0.25, 0.18, 0.1, 0.12]),
    },
    illumination: (
        sun_position: (
            utc: "2021-06-21T11:00:00",
            latitude_deg: 43.6047,
            longitude_deg: 1.4442,
            altitude_m: 146.0,
        ),
        irradiance_w_m2_um: [1800.0, 1500.0, 1000.0, 240.0, 1400.0, 1850.0, 1500.0],
    ),
    objects: [
        Ground((optics: "soil")),
        TurbidPlot((footprint: Box((0.0, 0.0, 2.0, 2.0)), top_m: 1.0, foliage: Lai(2.0), optics: "veg")),
        Leaves((radius_m: 0.05, optics: "old_leaf", disks: [(1.0, 1.0, 1.5, 0.0, 0.2, 1.0)])),
    ],
)
"#;

/// The tabulated response of band `edge`: a triangle 700–720–760 nm (peak 2, any scale).
const TRIANGLE_SRF: &str = "# test SRF\nwavelength_nm,response\n700,0\n720,2\n760,0\n";

/// A fresh folder per test (tests run in parallel threads of one process).
fn dir(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "lumenscape-optics-sun-{}-{test}",
        std::process::id()
    ));
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join("triangle_srf.csv"), TRIANGLE_SRF).unwrap();
    d
}

fn load(test: &str, text: &str) -> Result<Simulation, SceneError> {
    let p = dir(test).join("scene.ron");
    std::fs::write(&p, text).unwrap();
    Simulation::load(&p, RunSettings::default())
}

fn leaf_values(m: &Materials, name: &str) -> (Vec<f64>, Vec<f64>) {
    let mat = m
        .list
        .iter()
        .find(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material `{name}`"));
    match &mat.kind {
        MaterialKind::Leaf {
            reflectance,
            transmittance,
        }
        | MaterialKind::Turbid {
            reflectance,
            transmittance,
            ..
        } => (reflectance.clone(), transmittance.clone()),
        other => panic!("`{name}` is not a leaf: {other:?}"),
    }
}

/// Linear interpolation in a table (0 outside, as an SRF).
fn interp(x: &[f64], y: &[f64], at: f64) -> f64 {
    if at < x[0] || at > x[x.len() - 1] {
        return 0.0;
    }
    let k = x.partition_point(|&v| v <= at).clamp(1, x.len() - 1);
    let t = (at - x[k - 1]) / (x[k] - x[k - 1]);
    y[k - 1] + t * (y[k] - y[k - 1])
}

/// One band's response as a function of wavelength (nm).
enum Response {
    Table(Vec<f64>, Vec<f64>),
    Gaussian { center: f64, fwhm: f64 },
    Mono(f64),
}

impl Response {
    fn at(&self, wl: f64) -> f64 {
        match self {
            Response::Table(x, y) => interp(x, y, wl),
            Response::Gaussian { center, fwhm } => {
                let sigma = fwhm / (8.0 * 2f64.ln()).sqrt();
                (-0.5 * ((wl - center) / sigma).powi(2)).exp()
            }
            Response::Mono(_) => unreachable!(),
        }
    }
    fn support(&self) -> (f64, f64) {
        match self {
            Response::Table(x, _) => (x[0], x[x.len() - 1]),
            Response::Gaussian { center, fwhm } => (center - 4.0 * fwhm, center + 4.0 * fwhm),
            Response::Mono(w) => (*w, *w),
        }
    }
}

/// Band of a sensor file in `assets/sensors/` (long format `band,wavelength_nm,response`).
fn sensor_srf(file: &str, band: &str) -> Response {
    let text = std::fs::read_to_string(asset(&format!("assets/sensors/{file}"))).unwrap();
    let (mut x, mut y) = (vec![], vec![]);
    for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f[0] == band {
            x.push(f[1].parse().unwrap());
            y.push(f[2].parse().unwrap());
        }
    }
    assert!(x.len() > 2, "{file}: no band {band}");
    Response::Table(x, y)
}

/// ∫ S X dλ / ∫ S dλ by the trapezoid rule on a 0.01 nm grid (X: 1 nm spectrum, linear).
fn band_mean(leaf: &LeafSpectrum, values: &[f64], s: &Response) -> f64 {
    if let Response::Mono(w) = s {
        return interp(&leaf.wavelength_nm, values, *w);
    }
    let (lo, hi) = s.support();
    let (lo, hi) = (lo.max(400.0), hi.min(2500.0));
    let n = ((hi - lo) / 0.01).round() as usize;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..=n {
        let wl = lo + (hi - lo) * i as f64 / n as f64;
        let w = if i == 0 || i == n { 0.5 } else { 1.0 };
        let sv = s.at(wl);
        num += w * sv * interp(&leaf.wavelength_nm, values, wl);
        den += w * sv;
    }
    num / den
}

fn responses() -> Vec<(&'static str, Response)> {
    vec![
        ("green", sensor_srf("sentinel2a_msi.csv", "B03")),
        ("red", sensor_srf("sentinel2a_msi.csv", "B04")),
        ("nir", sensor_srf("sentinel2a_msi.csv", "B08")),
        ("swir", sensor_srf("landsat8_oli.csv", "B6")),
        (
            "edge",
            Response::Table(vec![700.0, 720.0, 760.0], vec![0.0, 2.0, 0.0]),
        ),
        (
            "g550",
            Response::Gaussian {
                center: 550.0,
                fwhm: 20.0,
            },
        ),
        ("m670", Response::Mono(670.0)),
    ]
}

#[test]
fn prospect_leaves_equal_the_srf_weighted_prospect_average() {
    let sim = load("prospect", SCENE).unwrap_or_else(|e| panic!("{e}"));
    let mats = sim.resource::<Materials>();
    let cases = [
        (
            "leaf",
            ProspectModel::D,
            ProspectParams {
                n: 1.5,
                cab_ug_cm2: 40.0,
                car_ug_cm2: 8.0,
                anth_ug_cm2: 1.0,
                cbrown: 0.0,
                cw_cm: 0.01,
                cm_g_cm2: 0.009,
            },
        ),
        (
            "old_leaf",
            ProspectModel::P5,
            ProspectParams {
                n: 2.1,
                cab_ug_cm2: 60.0,
                car_ug_cm2: 10.0,
                anth_ug_cm2: 0.0,
                cbrown: 0.1,
                cw_cm: 0.013,
                cm_g_cm2: 0.016,
            },
        ),
    ];
    let bands = responses();
    let mut worst_tab: f64 = 0.0;
    let mut worst_gauss: f64 = 0.0;
    for (name, model, params) in cases {
        let spectrum = prospect(model, &params, ProspectData::builtin()).unwrap();
        let (r, t) = leaf_values(mats, name);
        assert_eq!((r.len(), t.len()), (bands.len(), bands.len()));
        for (b, (band, s)) in bands.iter().enumerate() {
            for (what, got, values) in [
                ("R", r[b], &spectrum.reflectance),
                ("T", t[b], &spectrum.transmittance),
            ] {
                let expect = band_mean(&spectrum, values, s);
                let err = (got - expect).abs();
                println!(
                    "{name} {band} {what}: scene {got:.8} recomputed {expect:.8} |diff| {err:.2e}"
                );
                match s {
                    // Monochromatic: the 1 nm value itself (670 nm is a grid node).
                    Response::Mono(w) => {
                        let k = spectrum.wavelength_nm.iter().position(|x| x == w).unwrap();
                        assert_eq!(got, values[k], "{name} {band} {what}");
                    }
                    // The library samples the Gaussian at FWHM/40 and interpolates linearly.
                    Response::Gaussian { .. } => {
                        worst_gauss = worst_gauss.max(err);
                        assert!(err <= 1e-5, "{name} {band} {what}: {got} vs {expect}");
                    }
                    Response::Table(..) => {
                        worst_tab = worst_tab.max(err);
                        assert!(err <= 1e-7, "{name} {band} {what}: {got} vs {expect}");
                    }
                }
            }
        }
    }
    println!("worst |diff|: tabulated SRFs {worst_tab:.2e}, Gaussian {worst_gauss:.2e}");
    // The turbid material carries its PROSPECT leaf's values.
    let (tr, tt) = leaf_values(mats, "veg");
    assert_eq!((tr, tt), leaf_values(mats, "leaf"));
    // Band centroids fill in the nominal wavelengths that were omitted; a given one is kept.
    let info = sim.resource::<SceneInfo>();
    let wl: Vec<f64> = info.bands.iter().map(|b| b.wavelength_nm).collect();
    assert!((wl[1] - 664.6).abs() < 1.0, "S2A B04 centroid {}", wl[1]);
    assert!((wl[2] - 832.8).abs() < 2.0, "S2A B08 centroid {}", wl[2]);
    assert_eq!(wl[3], 1610.0);
    assert!(
        (wl[4] - (700.0 + 720.0 + 760.0) / 3.0).abs() < 1e-9,
        "triangle centroid {}",
        wl[4]
    );
    assert_eq!(info.band_responses.len(), 7);
}

/// Rows of `assets/reference/solar_position_spa.csv` as (header → value) lookups.
fn spa_rows() -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(asset("assets/reference/solar_position_spa.csv")).unwrap();
    let mut lines = text
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'));
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}

/// A one-band scene whose sun is `sun` (the inside of `illumination: ( … )`).
fn sun_scene(sun: &str) -> String {
    format!(
        r#"(
    version: 1,
    grid: (size_m: (2.0, 2.0), cell_m: (1.0, 1.0, 1.0), boundary: Repetitive),
    bands: [(name: "red", wavelength_nm: 670.0)],
    optics: {{ "soil": Lambertian(reflectance: [0.1]) }},
    illumination: (
{sun}
        irradiance_w_m2_um: [1500.0],
    ),
    objects: [Ground((optics: "soil"))],
)
"#
    )
}

fn angle_diff(a: f64, b: f64) -> f64 {
    ((a - b + 540.0).rem_euclid(360.0) - 180.0).abs()
}

#[test]
fn sun_position_reproduces_the_spa_reference_in_scene_convention() {
    const TOL_DEG: f64 = 0.01;
    let mut worst: f64 = 0.0;
    for row in spa_rows() {
        let g = |k: &str| row[k].parse::<f64>().unwrap();
        let case = &row["case"];
        let position = |bearing: f64, refraction: bool| {
            format!(
                "        sun_position: (\n            utc: \"{}\",\n            latitude_deg: {}, longitude_deg: {}, altitude_m: {},\n            pressure_hpa: {}, temperature_c: {}, delta_t_s: {},\n            scene_x_bearing_deg: {bearing}, refraction: {refraction},\n        ),\n",
                row["utc"],
                row["latitude_deg"],
                row["longitude_deg_east"],
                row["altitude_m"],
                row["pressure_hPa"],
                row["temperature_C"],
                row["delta_t_s"]
            )
        };
        for (bearing, refraction) in [(90.0, true), (0.0, true), (90.0, false)] {
            let zenith = if refraction {
                g("apparent_zenith_deg")
            } else {
                g("zenith_deg")
            };
            let text = sun_scene(&position(bearing, refraction));
            let test = format!("spa-{case}-{bearing}-{refraction}");
            if zenith >= 90.0 {
                // Polar night, or the sun just below the horizon without refraction.
                let e = load(&test, &text)
                    .err()
                    .unwrap_or_else(|| panic!("{case}: sun below the horizon accepted"));
                let msg = e.to_string();
                println!("{case} (refraction {refraction}): {msg}");
                assert!(
                    msg.contains("illumination.sun_position.utc")
                        && msg.contains("below the horizon"),
                    "{msg}"
                );
                assert_eq!(line_of(&e), Some(line_containing(&text, "utc:")), "{msg}");
                continue;
            }
            let sim = load(&test, &text).unwrap_or_else(|e| panic!("{case}: {e}"));
            let info = sim.resource::<SceneInfo>();
            let il = &info.illumination;
            // Scene azimuth φ = (β − γ) mod 360°, γ from north clockwise (physics.md §1.1).
            let azimuth = (bearing - g("azimuth_deg")).rem_euclid(360.0);
            let (dz, da) = (
                (il.sun_zenith_deg - zenith).abs(),
                angle_diff(il.sun_azimuth_deg, azimuth),
            );
            println!(
                "{case} β={bearing} refraction {refraction}: zenith {:.6} (ref {zenith:.6}), azimuth {:.6} (ref {azimuth:.6}), |diff| {dz:.1e}°, {da:.1e}°",
                il.sun_zenith_deg, il.sun_azimuth_deg
            );
            assert!(
                dz <= TOL_DEG,
                "{case}: zenith {} vs {zenith}",
                il.sun_zenith_deg
            );
            // At a pole the azimuth is SPA's limit along the meridian (degenerate but reproduced).
            assert!(
                da <= TOL_DEG,
                "{case}: azimuth {} vs {azimuth}",
                il.sun_azimuth_deg
            );
            worst = worst.max(dz).max(da);
            // Earth–Sun distance: irradiance scaled by (1 AU / d)², and said so.
            let factor = 1.0 / g("earth_sun_distance_au").powi(2);
            let applied = info
                .irradiance_distance_factor
                .expect("distance factor recorded");
            assert!(
                (applied - factor).abs() <= 1e-6 * factor,
                "{case}: factor {applied} vs {factor}"
            );
            assert!((il.irradiance_w_m2_um[0] - 1500.0 * factor).abs() <= 1e-9 * 1500.0 * factor);
            assert!(info.solar_position.is_some());
            assert_eq!(il.skyl, vec![0.0]);
        }
    }
    println!("worst |diff| against SPA (pvlib): {worst:.2e}°");
}

#[test]
fn the_golden_spa_case_and_the_distance_switch() {
    // The NREL SPA paper's example (Reda & Andreas 2004, Table A5.1): apparent zenith
    // 50.11162°, azimuth 194.34024° from north → 255.65976° anticlockwise from +x (east).
    let sun = "        sun_position: (utc: \"2003-10-17T19:30:30\", latitude_deg: 39.742476, longitude_deg: -105.1786,\n            altitude_m: 1830.14, pressure_hpa: 820.0, temperature_c: 11.0, delta_t_s: 67.0),\n";
    let sim = load("golden", &sun_scene(sun)).unwrap_or_else(|e| panic!("{e}"));
    let info = sim.resource::<SceneInfo>();
    println!(
        "golden: zenith {:.7}° azimuth {:.7}°",
        info.illumination.sun_zenith_deg, info.illumination.sun_azimuth_deg
    );
    assert!((info.illumination.sun_zenith_deg - 50.11162202).abs() <= 0.01);
    assert!(angle_diff(info.illumination.sun_azimuth_deg, 255.6597595) <= 0.01);
    assert!(
        (info.irradiance_distance_factor.unwrap() - 1.0 / 0.9965422974f64.powi(2)).abs() < 1e-6
    );
    // The correction can be turned off.
    let off = sun.replace(
        "delta_t_s: 67.0)",
        "delta_t_s: 67.0, earth_sun_distance_correction: false)",
    );
    let sim = load("golden-off", &sun_scene(&off)).unwrap_or_else(|e| panic!("{e}"));
    let info = sim.resource::<SceneInfo>();
    assert_eq!(info.irradiance_distance_factor, None);
    assert_eq!(info.illumination.irradiance_w_m2_um, vec![1500.0]);
    // Explicit angles are copied, with no correction and no SPA result.
    let sim = load(
        "explicit",
        &sun_scene("        sun_zenith_deg: 30.0, sun_azimuth_deg: Some(45.0),\n"),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let info = sim.resource::<SceneInfo>();
    assert_eq!(
        (
            info.illumination.sun_zenith_deg,
            info.illumination.sun_azimuth_deg
        ),
        (30.0, 45.0)
    );
    assert_eq!(info.irradiance_distance_factor, None);
    assert!(info.solar_position.is_none());
}

fn line_of(e: &SceneError) -> Option<usize> {
    match e {
        SceneError::Syntax { at, .. }
        | SceneError::Invalid { at, .. }
        | SceneError::NotSupported { at, .. } => at.line_col.map(|l| l.0),
        SceneError::Io { .. } => None,
    }
}

fn line_containing(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .unwrap_or_else(|| panic!("`{needle}` not in text"))
        + 1
}

#[test]
fn bad_inputs_name_their_field_and_line() {
    // (name, replace, by, field named in the message, text on the expected line, words of the message)
    let cases: &[(&str, &str, &str, &str, &str, &str)] = &[
        (
            "both_sun_forms",
            "        sun_position: (\n",
            "        sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0,\n        sun_position: (\n",
            "illumination.sun_position",
            "sun_position:",
            "not both",
        ),
        (
            "no_sun",
            "            altitude_m: 146.0,\n        ),\n",
            "            altitude_m: 146.0,\n        ),\n",
            "",
            "",
            "",
        ),
        (
            "sun_below_horizon",
            "2021-06-21T11:00:00",
            "2021-06-21T23:00:00",
            "illumination.sun_position.utc",
            "utc:",
            "below the horizon",
        ),
        (
            "bad_utc",
            "2021-06-21T11:00:00",
            "2021-06-31T11:00:00",
            "illumination.sun_position.utc",
            "utc:",
            "2021-06-31",
        ),
        (
            "bad_latitude",
            "latitude_deg: 43.6047",
            "latitude_deg: 95.0",
            "illumination.sun_position.latitude_deg",
            "latitude_deg: 95.0",
            "[-90, 90]",
        ),
        (
            "unknown_sensor",
            "(\"sentinel2a_msi\", \"B03\")",
            "(\"sentinel9_msi\", \"B03\")",
            "bands[0].sensor_band",
            "sentinel9_msi",
            "unknown sensor `sentinel9_msi`",
        ),
        (
            "unknown_band",
            "(\"sentinel2a_msi\", \"B4\")",
            "(\"sentinel2a_msi\", \"B14\")",
            "bands[1].sensor_band",
            "B14",
            "no band `B14`",
        ),
        (
            "missing_srf_file",
            "srf_file: \"triangle_srf.csv\"",
            "srf_file: \"no_such_srf.csv\"",
            "bands[4].srf_file",
            "no_such_srf.csv",
            "no_such_srf.csv: cannot read file",
        ),
        (
            "both_band_forms",
            "(name: \"edge\", srf_file:",
            "(name: \"edge\", sensor_band: (\"modis_terra\", \"B1\"), srf_file:",
            "bands[4].srf_file",
            "name: \"edge\"",
            "not both",
        ),
        (
            "fwhm_with_srf",
            "(name: \"nir\", sensor_band: (\"Sentinel-2A MSI\", \"b08\"))",
            "(name: \"nir\", sensor_band: (\"Sentinel-2A MSI\", \"b08\"), fwhm_nm: 30.0)",
            "bands[2].fwhm_nm",
            "fwhm_nm: 30.0",
            "takes no `fwhm_nm`",
        ),
        (
            "no_wavelength",
            "(name: \"m670\", wavelength_nm: 670.0)",
            "(name: \"m670\")",
            "bands[6].wavelength_nm",
            "name: \"m670\"",
            "needs a `wavelength_nm`",
        ),
        (
            "prospect_n_below_1",
            "            n: 1.5,\n",
            "            n: 0.8,\n",
            "optics[\"leaf\"].n",
            "n: 0.8,",
            "N must be >= 1",
        ),
        (
            "prospect_negative_cab",
            "cab_ug_cm2: 60.0",
            "cab_ug_cm2: -60.0",
            "optics[\"old_leaf\"].cab_ug_cm2",
            "cab_ug_cm2: -60.0",
            "non-negative",
        ),
        (
            "prospect_outside_400_2500",
            "(name: \"m670\", wavelength_nm: 670.0)",
            "(name: \"m670\", wavelength_nm: 380.0)",
            "optics[\"leaf\"]",
            "\"leaf\": ProspectLeaf(",
            "band `m670`",
        ),
        (
            "prospect_unknown_field",
            "cbrown: 0.0,",
            "cbrown: 0.0, cbrwn: 0.1,",
            "cbrwn",
            "cbrwn",
            "cbrwn",
        ),
    ];
    for &(name, from, to, field, line_text, words) in cases {
        let text = if name == "no_sun" {
            // Drop the whole sun_position block.
            let a = SCENE.find("        sun_position: (").unwrap();
            let b = SCENE[a..].find("        ),\n").unwrap() + a + "        ),\n".len();
            format!("{}{}", &SCENE[..a], &SCENE[b..])
        } else {
            SCENE.replace(from, to)
        };
        assert_ne!(text, SCENE, "{name}: replacement did not apply");
        let e = match load(&format!("bad-{name}"), &text) {
            Ok(_) => panic!("{name}: expected an error"),
            Err(e) => e,
        };
        let msg = e.to_string();
        println!("{name}: {msg}");
        assert!(
            msg.contains("scene.ron"),
            "{name}: message does not name the file: {msg}"
        );
        if name == "no_sun" {
            assert!(
                matches!(e, SceneError::Invalid { ref field, .. } if field == "illumination"),
                "{msg}"
            );
            assert!(
                msg.contains("sun_zenith_deg") && msg.contains("sun_position"),
                "{msg}"
            );
            assert_eq!(
                line_of(&e),
                Some(line_containing(&text, "illumination:")),
                "{msg}"
            );
            continue;
        }
        if name == "prospect_unknown_field" {
            assert!(matches!(e, SceneError::Syntax { .. }), "{msg}");
        } else {
            assert!(matches!(e, SceneError::Invalid { .. }), "{name}: {msg}");
            assert!(
                msg.contains(&format!("field `{field}`")),
                "{name}: message does not name `{field}`: {msg}"
            );
        }
        assert!(
            msg.contains(words),
            "{name}: message lacks `{words}`: {msg}"
        );
        assert_eq!(
            line_of(&e),
            Some(line_containing(&text, line_text)),
            "{name}: {msg}"
        );
    }
}
