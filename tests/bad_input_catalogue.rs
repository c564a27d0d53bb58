//! The bad-input catalogue (issue #31): a table of mutated scenes, referenced files (mesh,
//! raster, leaf list, spectral response) and command-line arguments. Every case runs the built
//! binary twice, `check` and `run --out DIR`, and asserts that
//!
//! * both exit with a non-zero code that is not a panic's (101), with no "panicked" text;
//! * stderr names the file (the scene, or the referenced file) and the field or line
//!   (`needle`: a field path such as `grid.size_m`, a file name, or a flag);
//! * `run` wrote nothing: the `--out` folder is absent or empty.
//!
//! Scene cases start from small inline scenes ([`BASE`], [`LIDAR`]) and replace one piece of
//! text (the replacement must apply); a few start from the example scenes in `assets/scenes`.
//! GeoTIFF DEM cases (issue #37) write a `d.tif` made by the `tiff` crate's own encoder
//! (`common/geo.rs`) when they run.

use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "common/geo.rs"]
mod geo;

/// A small valid scene with every object kind that needs no file.
const BASE: &str = r#"(
    version: 1,
    grid: (size_m: (10.0, 10.0), cell_m: (1.0, 1.0, 1.0), boundary: Isolated),
    bands: [(name: "red", wavelength_nm: 670.0)],
    optics: {
        "leaf": BiLambertian(reflectance: [0.05], transmittance: [0.02]),
        "veg": Turbid(leaf: "leaf", lad: Spherical),
        "soil": Lambertian(reflectance: [0.1]),
        "wall": Lambertian(reflectance: [0.3]),
    },
    illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0, skyl: [0.1]),
    directions: Some((count: 40, exact: [(zenith_deg: 0.0, azimuth_deg: 0.0, label: Some("nadir"))])),
    radiative: (preset: Preview),
    objects: [
        Ground((optics: "soil")),
        Tree((
            position_m: (5.0, 5.0),
            crown: (shape: Ellipsoid, base_height_m: 1.0, height_m: 3.0, radius_x_m: 1.5,
                    foliage: LeafAreaDensity(0.8), optics: "veg"),
            trunk: Some((height_m: 1.0, diameter_m: 0.2, sides: 6, optics: "wall")),
        )),
        TurbidPlot((footprint: Box((0.0, 0.0, 3.0, 3.0)), bottom_m: 0.0, top_m: 1.0,
                    foliage: Lai(2.0), optics: "veg")),
        Building((footprint: Box((6.0, 0.5, 9.0, 2.5)), wall_height_m: 3.0,
                  roof: Gable(ridge_height_m: 1.0), wall_optics: "wall", roof_optics: "wall")),
        Water((footprint: Polygon([(0.5, 6.0), (3.0, 6.0), (3.0, 9.0)]), optics: "soil")),
        Leaves((radius_m: 0.1, sides: 8, optics: "leaf",
                disks: [(8.0, 8.0, 1.0, 0.0, 0.0, 1.0)])),
    ],
)
"#;

/// A LiDAR-only scene (one airborne instrument).
const LIDAR: &str = r#"(
    version: 1,
    grid: (size_m: (10.0, 10.0), cell_m: (1.0, 1.0, 1.0), boundary: Isolated),
    bands: [(name: "nir", wavelength_nm: 1064.0)],
    optics: {
        "leaf": BiLambertian(reflectance: [0.45], transmittance: [0.4]),
        "veg": Turbid(leaf: "leaf", lad: Spherical),
        "soil": Lambertian(reflectance: [0.3]),
    },
    illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0),
    lidars: Some([(
        name: "als",
        band: "nir",
        platform: Airborne(altitude_m: 500.0, view_zenith_deg: 0.0,
                           pulses: Scan(start: (2.0, 5.0), end: (8.0, 5.0), lines: 1,
                                        line_spacing_m: 1.0, pulse_spacing_m: 1.0)),
        footprint_radius_m: Some(0.3),
        bin_ns: 1.0,
    )]),
    objects: [
        Ground((optics: "soil")),
        Tree((position_m: (5.0, 5.0),
              crown: (shape: Ellipsoid, base_height_m: 1.0, height_m: 3.0, radius_x_m: 1.5,
                      foliage: Lai(2.0), optics: "veg"))),
    ],
)
"#;

/// A mutated scene: the base text, `from` replaced by `to` (once), plus an optional referenced
/// file written beside it; the command; and the needle stderr must contain.
struct Case {
    name: &'static str,
    base: Base,
    from: &'static str,
    to: &'static str,
    /// A file (name, content) written beside the scene.
    file: Option<(&'static str, &'static [u8])>,
    /// A file (name, maker of its content) written beside the scene: GeoTIFFs made by the
    /// `tiff` crate when the case runs.
    made: Option<(&'static str, fn() -> Vec<u8>)>,
    /// Extra CLI arguments (after the scene path).
    args: &'static [&'static str],
    /// Text stderr must contain (field path, file name or flag).
    needle: &'static str,
    /// The file stderr must name ("" = the scene file).
    names: &'static str,
}

#[derive(Clone, Copy)]
enum Base {
    Inline,
    Lidar,
    /// An example scene of `assets/scenes` (file references are not resolved: pick scenes
    /// without them).
    Asset(&'static str),
}

const fn c(name: &'static str, from: &'static str, to: &'static str, needle: &'static str) -> Case {
    Case {
        name,
        base: Base::Inline,
        from,
        to,
        file: None,
        made: None,
        args: &[],
        needle,
        names: "",
    }
}

const fn lidar(
    name: &'static str,
    from: &'static str,
    to: &'static str,
    needle: &'static str,
) -> Case {
    Case {
        base: Base::Lidar,
        ..c(name, from, to, needle)
    }
}

const fn asset(
    name: &'static str,
    scene: &'static str,
    from: &'static str,
    to: &'static str,
    needle: &'static str,
) -> Case {
    Case {
        base: Base::Asset(scene),
        ..c(name, from, to, needle)
    }
}

/// A case whose scene references a file with bad content; stderr must name that file.
const fn file(
    name: &'static str,
    from: &'static str,
    to: &'static str,
    f: (&'static str, &'static [u8]),
    needle: &'static str,
) -> Case {
    Case {
        file: Some(f),
        names: f.0,
        ..c(name, from, to, needle)
    }
}

/// A scene referencing a valid file with a bad scene field; stderr must name the scene.
const fn scene_file(
    name: &'static str,
    from: &'static str,
    to: &'static str,
    f: (&'static str, &'static [u8]),
    needle: &'static str,
) -> Case {
    Case {
        file: Some(f),
        ..c(name, from, to, needle)
    }
}

/// A GeoTIFF DEM case: the base scene with a georeference and a GeoTiff ground reading `d.tif`,
/// made by `make`; stderr must name `d.tif` and `needle`.
const fn geotiff(name: &'static str, make: fn() -> Vec<u8>, needle: &'static str) -> Case {
    Case {
        made: Some(("d.tif", make)),
        names: "d.tif",
        ..c(name, GEO_FROM, GEO_TO, needle)
    }
}

/// A GeoTIFF DEM case whose fault is in the scene (`to` replaces the georeferenced base's
/// ground); stderr must name the scene and `needle`.
const fn geotiff_scene(
    name: &'static str,
    from: &'static str,
    to: &'static str,
    needle: &'static str,
) -> Case {
    Case {
        made: Some(("d.tif", good_dem)),
        ..c(name, from, to, needle)
    }
}

/// A valid scene with bad command-line arguments; stderr must name the flag.
const fn args(name: &'static str, a: &'static [&'static str], needle: &'static str) -> Case {
    Case {
        args: a,
        names: "-",
        ..c(name, "version: 1", "version: 1", needle)
    }
}

/// Needle: the named file (the scene, or the referenced file) followed by `:LINE`.
const LINE: &str = "<line>";

const GROUND: &str = "Ground((optics: \"soil\")),";

fn tmp() -> PathBuf {
    let d = std::env::temp_dir().join(format!("lumenscape-catalogue-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn base_text(b: Base) -> String {
    match b {
        Base::Inline => BASE.to_string(),
        Base::Lidar => LIDAR.to_string(),
        Base::Asset(n) => std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("assets/scenes")
                .join(n),
        )
        .unwrap(),
    }
}

/// Runs one case; returns a description of what went wrong, if anything.
fn run_case(case: &Case) -> Result<(), String> {
    let dir = tmp().join(case.name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let base = base_text(case.base);
    // `a||b` → `x||y`: several replacements.
    let mut text = base.clone();
    for (from, to) in case.from.split("||").zip(case.to.split("||")) {
        let next = text.replacen(from, to, 1);
        if from != to && next == text {
            return Err(format!("replacement `{from}` did not apply"));
        }
        text = next;
    }
    let scene = dir.join(format!("{}.ron", case.name));
    std::fs::write(&scene, &text).unwrap();
    if let Some((n, content)) = case.file {
        std::fs::write(dir.join(n), content).unwrap();
    }
    if let Some((n, make)) = case.made {
        std::fs::write(dir.join(n), make()).unwrap();
    }
    let out_dir = dir.join("out");
    let named = match case.names {
        "" => scene.display().to_string(),
        "-" => String::new(),
        n => n.to_string(),
    };
    for cmd in ["check", "run"] {
        let mut a: Vec<String> = vec![cmd.into(), scene.display().to_string()];
        if cmd == "run" {
            a.extend([
                "--out".into(),
                out_dir.display().to_string(),
                "--quiet".into(),
            ]);
        }
        a.extend(case.args.iter().map(|s| s.to_string()));
        let out = Command::new(env!("CARGO_BIN_EXE_lumenscape"))
            .args(&a)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        let code = out.status.code();
        if out.status.success() || code == Some(101) || code.is_none() {
            return Err(format!("{cmd}: exit {code:?}\n{err}"));
        }
        if err.contains("panicked") || err.trim().is_empty() {
            return Err(format!("{cmd}: {err}"));
        }
        // `LINE`: the scene file followed by its line number (`scene.ron:12:5`).
        let needle_ok = if case.needle == LINE {
            err.match_indices(&format!("{named}:"))
                .any(|(i, m)| err[i + m.len()..].starts_with(|c: char| c.is_ascii_digit()))
        } else {
            err.contains(case.needle)
        };
        if !err.contains(&named) || !needle_ok {
            return Err(format!(
                "{cmd}: stderr does not name `{named}` and `{}`:\n{err}",
                case.needle
            ));
        }
        if let Ok(mut rd) = std::fs::read_dir(&out_dir)
            && rd.next().is_some()
        {
            return Err(format!("{cmd}: files written to {}", out_dir.display()));
        }
    }
    Ok(())
}

fn run_all(cases: &[Case]) {
    let mut failed = Vec::new();
    for case in cases {
        if let Err(e) = run_case(case) {
            failed.push(format!("[{}] {e}", case.name));
        }
    }
    assert!(
        failed.is_empty(),
        "{} of {} cases failed:\n{}",
        failed.len(),
        cases.len(),
        failed.join("\n")
    );
}

const GRID: &[Case] = &[
    c(
        "overflow_size",
        "size_m: (10.0, 10.0)",
        "size_m: (2.0, 1e308)",
        "grid.size_m",
    ),
    c(
        "huge_size",
        "size_m: (10.0, 10.0)",
        "size_m: (1e300, 1e300)",
        "grid.size_m",
    ),
    c(
        "inf_size",
        "size_m: (10.0, 10.0)",
        "size_m: (inf, 10.0)",
        "grid.size_m",
    ),
    c(
        "zero_size",
        "size_m: (10.0, 10.0)",
        "size_m: (0.0, 10.0)",
        "grid.size_m",
    ),
    c(
        "negative_size",
        "size_m: (10.0, 10.0)",
        "size_m: (-10.0, 10.0)",
        "grid.size_m",
    ),
    c(
        "nan_size",
        "size_m: (10.0, 10.0)",
        "size_m: (NaN, 10.0)",
        "grid.size_m",
    ),
    c(
        "tiny_cell",
        "cell_m: (1.0, 1.0, 1.0)",
        "cell_m: (1e-300, 1.0, 1.0)",
        "grid.",
    ),
    c(
        "many_columns",
        "size_m: (10.0, 10.0)",
        "size_m: (1e5, 1e5)",
        "grid.size_m",
    ),
    c(
        "zero_cell_z",
        "cell_m: (1.0, 1.0, 1.0)",
        "cell_m: (1.0, 1.0, 0.0)",
        "grid.cell_m",
    ),
    c(
        "nan_cell_z",
        "cell_m: (1.0, 1.0, 1.0)",
        "cell_m: (1.0, 1.0, NaN)",
        "grid.cell_m",
    ),
    c(
        "tiny_cell_z",
        "cell_m: (1.0, 1.0, 1.0)",
        "cell_m: (1.0, 1.0, 1e-300)",
        "grid.cell_m",
    ),
    c(
        "tiny_cell_z_height",
        "cell_m: (1.0, 1.0, 1.0), boundary: Isolated",
        "cell_m: (1.0, 1.0, 1e-12), boundary: Isolated, height_m: 10.0",
        "grid.height_m",
    ),
    c(
        "huge_height",
        "boundary: Isolated",
        "boundary: Isolated, height_m: 1e300",
        "grid.height_m",
    ),
    c(
        "negative_height",
        "boundary: Isolated",
        "boundary: Isolated, height_m: -1.0",
        "grid.height_m",
    ),
    c(
        "low_height",
        "boundary: Isolated",
        "boundary: Isolated, height_m: 1.5",
        "grid.height_m",
    ),
    c(
        "zero_subcells",
        "boundary: Isolated",
        "boundary: Isolated, subcells: 0",
        "grid.subcells",
    ),
    c(
        "many_subcells",
        "boundary: Isolated",
        "boundary: Isolated, subcells: 17",
        "grid.subcells",
    ),
    c(
        "fractional_cells",
        "cell_m: (1.0, 1.0, 1.0)",
        "cell_m: (3.0, 1.0, 1.0)",
        "grid.cell_m",
    ),
    c(
        "unknown_boundary",
        "boundary: Isolated",
        "boundary: Closed",
        "Closed",
    ),
    c(
        "huge_crown",
        "height_m: 3.0, radius_x_m",
        "height_m: 1e300, radius_x_m",
        "grid.cell_m",
    ),
    c(
        "huge_building",
        "wall_height_m: 3.0",
        "wall_height_m: 1e300",
        "grid.cell_m",
    ),
];

const BANDS: &[Case] = &[
    c(
        "no_bands",
        "bands: [(name: \"red\", wavelength_nm: 670.0)]",
        "bands: []",
        "bands",
    ),
    c(
        "empty_band_name",
        "(name: \"red\",",
        "(name: \" \",",
        "bands[0].name",
    ),
    c(
        "duplicate_band",
        "bands: [(name: \"red\", wavelength_nm: 670.0)]",
        "bands: [(name: \"red\", wavelength_nm: 670.0), (name: \"red\", wavelength_nm: 700.0)]",
        "bands[1].name",
    ),
    c(
        "negative_fwhm",
        "wavelength_nm: 670.0)",
        "wavelength_nm: 670.0, fwhm_nm: -1.0)",
        "bands[0].fwhm_nm",
    ),
    c(
        "nan_fwhm",
        "wavelength_nm: 670.0)",
        "wavelength_nm: 670.0, fwhm_nm: NaN)",
        "bands[0].fwhm_nm",
    ),
    c(
        "unknown_sensor",
        "wavelength_nm: 670.0)",
        "sensor_band: Some((\"hubble\", \"B4\")))",
        "bands[0]",
    ),
    c(
        "sensor_and_srf",
        "wavelength_nm: 670.0)",
        "sensor_band: Some((\"sentinel2a_msi\", \"B4\")), srf_file: Some(\"x.csv\"))",
        "srf_file",
    ),
    c(
        "missing_srf",
        "wavelength_nm: 670.0)",
        "srf_file: Some(\"nope.csv\"))",
        "nope.csv",
    ),
    file(
        "srf_decreasing",
        "wavelength_nm: 670.0)",
        "srf_file: Some(\"dec.csv\"))",
        ("dec.csv", b"wavelength_nm,response\n700,1\n650,1\n"),
        LINE,
    ),
    file(
        "srf_no_header",
        "wavelength_nm: 670.0)",
        "srf_file: Some(\"nohead.csv\"))",
        ("nohead.csv", b"650,1\n700,1\n"),
        "nohead.csv",
    ),
    file(
        "srf_negative",
        "wavelength_nm: 670.0)",
        "srf_file: Some(\"neg.csv\"))",
        ("neg.csv", b"wavelength_nm,response\n650,1\n700,-1\n"),
        "negative response -1 at 700 nm",
    ),
    file(
        "srf_text",
        "wavelength_nm: 670.0)",
        "srf_file: Some(\"text.csv\"))",
        ("text.csv", b"wavelength_nm,response\n650,abc\n"),
        LINE,
    ),
    file(
        "srf_binary",
        "wavelength_nm: 670.0)",
        "srf_file: Some(\"bin.csv\"))",
        ("bin.csv", b"\xff\xfe\x00\x01\x02"),
        "bin.csv",
    ),
    file(
        "srf_all_zero",
        "wavelength_nm: 670.0)",
        "srf_file: Some(\"zero.csv\"))",
        ("zero.csv", b"wavelength_nm,response\n650,0\n700,0\n"),
        "zero.csv",
    ),
];

const OPTICS: &[Case] = &[
    c(
        "reflectance_above_one",
        "reflectance: [0.1]",
        "reflectance: [1.5]",
        "reflectance",
    ),
    c(
        "reflectance_negative",
        "reflectance: [0.1]",
        "reflectance: [-0.1]",
        "reflectance",
    ),
    c(
        "reflectance_nan",
        "reflectance: [0.1]",
        "reflectance: [NaN]",
        "reflectance",
    ),
    c(
        "reflectance_two_values",
        "reflectance: [0.1]",
        "reflectance: [0.1, 0.2]",
        "reflectance",
    ),
    c(
        "reflectance_empty",
        "reflectance: [0.1]",
        "reflectance: []",
        "reflectance",
    ),
    c(
        "leaf_r_plus_t",
        "transmittance: [0.02]",
        "transmittance: [0.97]",
        "optics[\"leaf\"]",
    ),
    c(
        "duplicate_optics_leaf",
        "\"soil\": Lambertian(reflectance: [0.1]),",
        "\"soil\": Lambertian(reflectance: [0.1]),\n        \"leaf\": BiLambertian(reflectance: [0.3], transmittance: [0.3]),",
        "`leaf` is defined twice",
    ),
    c(
        "duplicate_optics_soil",
        "\"wall\": Lambertian(reflectance: [0.3]),",
        "\"wall\": Lambertian(reflectance: [0.3]),\n        \"soil\": Lambertian(reflectance: [0.2]),",
        "optics[\"soil\"]",
    ),
    c(
        "unknown_optics_kind",
        "Lambertian(reflectance: [0.3])",
        "Mirror(reflectance: [0.3])",
        "Mirror",
    ),
    c(
        "turbid_leaf_unknown",
        "Turbid(leaf: \"leaf\"",
        "Turbid(leaf: \"lef\"",
        "optics[\"veg\"].leaf",
    ),
    c(
        "turbid_leaf_not_leaf",
        "Turbid(leaf: \"leaf\"",
        "Turbid(leaf: \"soil\"",
        "optics[\"veg\"].leaf",
    ),
    c(
        "turbid_leaf_size",
        "lad: Spherical)",
        "lad: Spherical, leaf_size_m: -0.1)",
        "leaf_size_m",
    ),
    c(
        "turbid_lad_unknown",
        "lad: Spherical",
        "lad: Spiky",
        "Spiky",
    ),
    c(
        "rpv_k",
        "\"wall\": Lambertian(reflectance: [0.3]),",
        "\"wall\": Rpv(rho0: [0.1], k: [20.0], theta: [0.0]),",
        "optics[\"wall\"].k",
    ),
    c(
        "hapke_roughness",
        "\"wall\": Lambertian(reflectance: [0.3]),",
        "\"wall\": Hapke(w: [0.5], b: [0.2], c: [0.5], roughness_deg: 70.0, b0: 1.0, h: 0.1),",
        "roughness_deg",
    ),
    c(
        "ground_turbid_optics",
        GROUND,
        "Ground((optics: \"veg\")),",
        "objects[0].optics",
    ),
    c(
        "crown_facet_optics",
        "foliage: LeafAreaDensity(0.8), optics: \"veg\"",
        "foliage: LeafAreaDensity(0.8), optics: \"soil\"",
        "objects[1].crown.optics",
    ),
    c(
        "trunk_turbid_optics",
        "sides: 6, optics: \"wall\"",
        "sides: 6, optics: \"veg\"",
        "objects[1].trunk.optics",
    ),
];

const ILLUMINATION: &[Case] = &[
    c(
        "sun_below_horizon",
        "sun_zenith_deg: 30.0",
        "sun_zenith_deg: 95.0",
        "sun_zenith_deg",
    ),
    c(
        "sun_negative",
        "sun_zenith_deg: 30.0",
        "sun_zenith_deg: -5.0",
        "sun_zenith_deg",
    ),
    c(
        "sun_nan",
        "sun_zenith_deg: 30.0",
        "sun_zenith_deg: NaN",
        "sun_zenith_deg",
    ),
    c(
        "sun_horizon",
        "sun_zenith_deg: 30.0",
        "sun_zenith_deg: 90.0",
        "sun_zenith_deg",
    ),
    c(
        "sun_azimuth_inf",
        "sun_azimuth_deg: 0.0",
        "sun_azimuth_deg: inf",
        "sun_azimuth_deg",
    ),
    c(
        "sun_azimuth_missing",
        "sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0,",
        "sun_zenith_deg: 30.0,",
        "sun_azimuth_deg",
    ),
    c(
        "sun_missing",
        "sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0,",
        "",
        "illumination",
    ),
    c(
        "skyl_above_one",
        "skyl: [0.1]",
        "skyl: [1.5]",
        "illumination.skyl",
    ),
    c(
        "skyl_two_values",
        "skyl: [0.1]",
        "skyl: [0.1, 0.1]",
        "illumination.skyl",
    ),
    c(
        "irradiance_negative",
        "skyl: [0.1]",
        "skyl: [0.1], irradiance_w_m2_um: [-1.0]",
        "irradiance_w_m2_um",
    ),
];

const DIRECTIONS: &[Case] = &[
    c(
        "view_zenith_120",
        "exact: [(zenith_deg: 0.0",
        "exact: [(zenith_deg: 120.0",
        "directions.exact[0].zenith_deg",
    ),
    c(
        "view_zenith_90_5",
        "exact: [(zenith_deg: 0.0",
        "exact: [(zenith_deg: 90.5",
        "directions.exact[0].zenith_deg",
    ),
    c(
        "view_zenith_negative",
        "exact: [(zenith_deg: 0.0",
        "exact: [(zenith_deg: -10.0",
        "directions.exact[0].zenith_deg",
    ),
    c(
        "view_zenith_nan",
        "exact: [(zenith_deg: 0.0",
        "exact: [(zenith_deg: NaN",
        "directions.exact[0].zenith_deg",
    ),
    c(
        "view_zenith_second",
        "label: Some(\"nadir\"))]",
        "label: Some(\"nadir\")), (zenith_deg: 180.0, azimuth_deg: 0.0)]",
        "directions.exact[1].zenith_deg",
    ),
    c(
        "view_azimuth_inf",
        "azimuth_deg: 0.0, label",
        "azimuth_deg: inf, label",
        "directions.exact[0].azimuth_deg",
    ),
    c(
        "fictive_direction_refused",
        "count: 40,",
        "count: 40, fictive: [(zenith_deg: 20.0, azimuth_deg: 0.0)],",
        "directions.fictive",
    ),
    c(
        "direction_count_small",
        "count: 40",
        "count: 5",
        "directions.count",
    ),
    c(
        "direction_count_huge",
        "count: 40",
        "count: 1000000000",
        "directions.count",
    ),
    c(
        "direction_sectors_zero",
        "count: 40,",
        "count: 40, sectors: 0,",
        "directions.sectors",
    ),
    c(
        "direction_solid_angle",
        "count: 40,",
        "count: 40, exact_solid_angle_sr: 2.0,",
        "directions.exact_solid_angle_sr",
    ),
    c(
        "direction_layers_zero",
        "count: 40,",
        "count: 40, layers: Some(0),",
        "directions.layers",
    ),
];

const CROWNS: &[Case] = &[
    c(
        "lad_1e6",
        "LeafAreaDensity(0.8)",
        "LeafAreaDensity(1e6)",
        "objects[1].crown.foliage",
    ),
    c(
        "lad_1e300",
        "LeafAreaDensity(0.8)",
        "LeafAreaDensity(1e300)",
        "[0, 100] m²/m³",
    ),
    c(
        "lad_inf",
        "LeafAreaDensity(0.8)",
        "LeafAreaDensity(inf)",
        "objects[1].crown.foliage",
    ),
    c(
        "lad_negative",
        "LeafAreaDensity(0.8)",
        "LeafAreaDensity(-0.8)",
        "objects[1].crown.foliage",
    ),
    c(
        "lad_nan",
        "LeafAreaDensity(0.8)",
        "LeafAreaDensity(NaN)",
        "objects[1].crown.foliage",
    ),
    c(
        "lai_1e6",
        "LeafAreaDensity(0.8)",
        "Lai(1e6)",
        "[0, 100] m²/m²",
    ),
    c(
        "lai_1e300",
        "LeafAreaDensity(0.8)",
        "Lai(1e300)",
        "objects[1].crown.foliage",
    ),
    c(
        "lai_inf",
        "LeafAreaDensity(0.8)",
        "Lai(inf)",
        "objects[1].crown.foliage",
    ),
    c(
        "lai_101",
        "LeafAreaDensity(0.8)",
        "Lai(101.0)",
        "objects[1].crown.foliage",
    ),
    c(
        "leaf_area_1e300",
        "LeafAreaDensity(0.8)",
        "LeafArea(1e300)",
        "objects[1].crown.foliage",
    ),
    c(
        "leaf_area_dense",
        "LeafAreaDensity(0.8)",
        "LeafArea(1e6)",
        "LAI 100 over the",
    ),
    c(
        "crown_radius_zero",
        "radius_x_m: 1.5",
        "radius_x_m: 0.0",
        "objects[1].crown.radius_x_m",
    ),
    c(
        "crown_radius_y_huge",
        "radius_x_m: 1.5,",
        "radius_x_m: 1.5, radius_y_m: 1e300,",
        "objects[1].position_m",
    ),
    c(
        "crown_height_inf",
        "height_m: 3.0, radius_x_m",
        "height_m: inf, radius_x_m",
        "objects[1].crown.height_m",
    ),
    c(
        "crown_base_negative",
        "base_height_m: 1.0",
        "base_height_m: -1.0",
        "objects[1].crown.base_height_m",
    ),
    c(
        "trapezoid_no_fraction",
        "shape: Ellipsoid",
        "shape: Trapezoid",
        "objects[1].crown.shape",
    ),
    c(
        "fraction_not_trapezoid",
        "radius_x_m: 1.5,",
        "radius_x_m: 1.5, top_radius_fraction: 0.5,",
        "top_radius_fraction",
    ),
    c(
        "vertical_profile_negative",
        "radius_x_m: 1.5,",
        "radius_x_m: 1.5, vertical_profile: [-1.0, 1.0],",
        "vertical_profile",
    ),
    c(
        "vertical_profile_zero",
        "radius_x_m: 1.5,",
        "radius_x_m: 1.5, vertical_profile: [0.0, 0.0],",
        "vertical_profile",
    ),
    c(
        "position_nan",
        "position_m: (5.0, 5.0)",
        "position_m: (NaN, 5.0)",
        "objects[1].position_m",
    ),
    c(
        "position_outside",
        "position_m: (5.0, 5.0)",
        "position_m: (9.5, 5.0)",
        "outside the isolated scene",
    ),
    c(
        "trunk_sides",
        "sides: 6, optics: \"wall\"",
        "sides: 2, optics: \"wall\"",
        "objects[1].trunk.sides",
    ),
    c(
        "trunk_diameter",
        "diameter_m: 0.2",
        "diameter_m: 0.0",
        "objects[1].trunk.diameter_m",
    ),
    c(
        "crown_shape_unknown",
        "shape: Ellipsoid",
        "shape: Pyramid",
        "Pyramid",
    ),
];

const OTHER_OBJECTS: &[Case] = &[
    c(
        "plot_top_below_bottom",
        "bottom_m: 0.0, top_m: 1.0",
        "bottom_m: 2.0, top_m: 1.0",
        "objects[2].top_m",
    ),
    c(
        "plot_lai_1e6",
        "foliage: Lai(2.0)",
        "foliage: Lai(1e6)",
        "objects[2].foliage",
    ),
    c(
        "plot_lad_huge",
        "foliage: Lai(2.0)",
        "foliage: LeafAreaDensity(1e9)",
        "objects[2].foliage",
    ),
    c(
        "plot_leaf_area_huge",
        "foliage: Lai(2.0)",
        "foliage: LeafArea(1e12)",
        "objects[2].foliage",
    ),
    c(
        "plot_polygon_two",
        "footprint: Box((0.0, 0.0, 3.0, 3.0))",
        "footprint: Polygon([(0.0, 0.0), (1.0, 1.0)])",
        "objects[2].footprint",
    ),
    c(
        "plot_polygon_crossing",
        "footprint: Box((0.0, 0.0, 3.0, 3.0))",
        "footprint: Polygon([(0.0, 0.0), (2.0, 2.0), (2.0, 0.0), (0.0, 2.0)])",
        "objects[2].footprint",
    ),
    c(
        "plot_box_reversed",
        "footprint: Box((0.0, 0.0, 3.0, 3.0))",
        "footprint: Box((3.0, 0.0, 0.0, 3.0))",
        "objects[2].footprint",
    ),
    c(
        "plot_outside",
        "footprint: Box((0.0, 0.0, 3.0, 3.0))",
        "footprint: Box((0.0, 0.0, 13.0, 3.0))",
        "objects[2].footprint",
    ),
    c(
        "building_wall_negative",
        "wall_height_m: 3.0",
        "wall_height_m: -3.0",
        "objects[3].wall_height_m",
    ),
    c(
        "building_gable_polygon",
        "footprint: Box((6.0, 0.5, 9.0, 2.5))",
        "footprint: Polygon([(6.0, 0.5), (9.0, 0.5), (7.0, 2.5)])",
        "objects[3].roof",
    ),
    c(
        "building_ridge_zero",
        "ridge_height_m: 1.0",
        "ridge_height_m: 0.0",
        "objects[3].roof.ridge_height_m",
    ),
    c(
        "building_optics_unknown",
        "wall_optics: \"wall\"",
        "wall_optics: \"brick\"",
        "objects[3].wall_optics",
    ),
    c(
        "water_altitude_nan",
        "optics: \"soil\")),\n        Leaves",
        "optics: \"soil\", altitude_m: NaN)),\n        Leaves",
        "objects[4].altitude_m",
    ),
    c(
        "water_polygon_flat",
        "Polygon([(0.5, 6.0), (3.0, 6.0), (3.0, 9.0)])",
        "Polygon([(0.5, 6.0), (1.0, 6.0), (2.0, 6.0)])",
        "objects[4].footprint",
    ),
    c(
        "leaves_radius_zero",
        "radius_m: 0.1",
        "radius_m: 0.0",
        "objects[5].radius_m",
    ),
    c("leaves_sides", "sides: 8", "sides: 2", "objects[5].sides"),
    c(
        "leaves_zero_normal",
        "(8.0, 8.0, 1.0, 0.0, 0.0, 1.0)",
        "(8.0, 8.0, 1.0, 0.0, 0.0, 0.0)",
        "objects[5].disks[0]",
    ),
    c(
        "leaves_nan",
        "(8.0, 8.0, 1.0, 0.0, 0.0, 1.0)",
        "(8.0, NaN, 1.0, 0.0, 0.0, 1.0)",
        "objects[5].disks[0]",
    ),
    c(
        "two_grounds",
        GROUND,
        "Ground((optics: \"soil\")), Ground((optics: \"soil\")),",
        "objects[1]",
    ),
    c(
        "raster_one_node",
        GROUND,
        "Ground((optics: \"soil\", topography: Raster((nodes: (1, 2), spacing_m: (10.0, 10.0), altitude_m: [0.0, 0.0])))),",
        "objects[0].topography.nodes",
    ),
    c(
        "raster_count",
        GROUND,
        "Ground((optics: \"soil\", topography: Raster((nodes: (2, 2), spacing_m: (10.0, 10.0), altitude_m: [0.0, 0.0, 0.0])))),",
        "objects[0].topography.altitude_m",
    ),
    c(
        "raster_nan",
        GROUND,
        "Ground((optics: \"soil\", topography: Raster((nodes: (2, 2), spacing_m: (10.0, 10.0), altitude_m: [0.0, NaN, 0.0, 0.0])))),",
        "objects[0].topography.altitude_m[1]",
    ),
    c(
        "raster_spacing",
        GROUND,
        "Ground((optics: \"soil\", topography: Raster((nodes: (2, 2), spacing_m: (0.0, 10.0), altitude_m: [0.0, 0.0, 0.0, 0.0])))),",
        "objects[0].topography.spacing_m",
    ),
    c(
        "raster_huge_altitude",
        GROUND,
        "Ground((optics: \"soil\", topography: Raster((nodes: (2, 2), spacing_m: (10.0, 10.0), altitude_m: [0.0, 1e300, 0.0, 0.0])))),",
        "grid.cell_m",
    ),
    c(
        "raster_nodes_overflow",
        GROUND,
        "Ground((optics: \"soil\", topography: Raster((nodes: (4294967296, 4294967296), spacing_m: (10.0, 10.0), altitude_m: [0.0])))),",
        "objects[0].topography.nodes",
    ),
    c(
        "points_two",
        GROUND,
        "Ground((optics: \"soil\", topography: Points(points_m: [(0.0, 0.0, 0.0), (10.0, 10.0, 0.0)]))),",
        "objects[0].topography.points_m",
    ),
    c(
        "mesh_missing",
        GROUND,
        "Ground((optics: \"soil\")), Mesh((path: \"nope.obj\", groups: [(group: \"a\", optics: \"soil\")])),",
        "nope.obj",
    ),
    c(
        "leaf_list_missing",
        GROUND,
        "Ground((optics: \"soil\")), LeafList((path: \"nope.txt\", optics: \"leaf\")),",
        "nope.txt",
    ),
    c(
        "raster_file_missing",
        GROUND,
        "Ground((optics: \"soil\", topography: RasterFile((path: \"nope.asc\", format: EsriAscii)))),",
        "nope.asc",
    ),
];

const MESH: &str = "Ground((optics: \"soil\")), Mesh((path: \"m.obj\", groups: [(group: \"a\", optics: \"wall\")])),";

const FILES: &[Case] = &[
    file("mesh_empty", GROUND, MESH, ("m.obj", b"# nothing\n"), "m.obj"),
    file("mesh_bad_face", GROUND, MESH, ("m.obj", b"o a\nv 1 1 0\nv 2 1 0\nf 1 2 9\n"), "m.obj"),
    file("mesh_garbage", GROUND, MESH, ("m.obj", b"\x00\x01\x02 not an obj \xff\n"), "m.obj"),
    file("mesh_unlisted_group", GROUND, MESH, ("m.obj", b"o b\nv 1 1 0\nv 2 1 0\nv 1 2 0\nf 1 2 3\n"), "m.obj"),
    file("mesh_nan_vertex", GROUND, MESH, ("m.obj", b"o a\nv 1 1 0\nv NaN 1 0\nv 1 2 0\nf 1 2 3\n"), "m.obj"),
    scene_file("mesh_zero_scale", GROUND, "Ground((optics: \"soil\")), Mesh((path: \"m.obj\", scale: 0.0, groups: [(group: \"a\", optics: \"wall\")])),", ("m.obj", b"o a\nv 1 1 0\nv 2 1 0\nv 1 2 0\nf 1 2 3\n"), "scale"),
    scene_file("mesh_inf_translation", GROUND, "Ground((optics: \"soil\")), Mesh((path: \"m.obj\", translation_m: (inf, 0.0, 0.0), groups: [(group: \"a\", optics: \"wall\")])),", ("m.obj", b"o a\nv 1 1 0\nv 2 1 0\nv 1 2 0\nf 1 2 3\n"), "translation_m"),
    scene_file("mesh_no_groups", GROUND, "Ground((optics: \"soil\")), Mesh((path: \"m.obj\", groups: [])),", ("m.obj", b"o a\nv 1 1 0\nv 2 1 0\nv 1 2 0\nf 1 2 3\n"), "groups"),
    file("gltf_garbage", GROUND, "Ground((optics: \"soil\")), Mesh((path: \"m.gltf\", groups: [(group: \"a\", optics: \"wall\")])),", ("m.gltf", b"{ not json"), "m.gltf"),
    file("glb_garbage", GROUND, "Ground((optics: \"soil\")), Mesh((path: \"m.glb\", groups: [(group: \"a\", optics: \"wall\")])),", ("m.glb", b"glTF\x02\x00\x00\x00"), "m.glb"),
    file("leaf_list_short_line", GROUND, "Ground((optics: \"soil\")), LeafList((path: \"l.txt\", optics: \"leaf\")),", ("l.txt", b"0.05 5 5 1 0 0 1\n0.05 5 5\n"), LINE),
    file("leaf_list_negative_radius", GROUND, "Ground((optics: \"soil\")), LeafList((path: \"l.txt\", optics: \"leaf\")),", ("l.txt", b"-0.05 5 5 1 0 0 1\n"), "l.txt"),
    file("leaf_list_nan", GROUND, "Ground((optics: \"soil\")), LeafList((path: \"l.txt\", optics: \"leaf\")),", ("l.txt", b"0.05 NaN 5 1 0 0 1\n"), "l.txt"),
    file("leaf_list_text", GROUND, "Ground((optics: \"soil\")), LeafList((path: \"l.txt\", optics: \"leaf\")),", ("l.txt", b"leaf one two three\n"), LINE),
    file("leaf_list_zero_normal", GROUND, "Ground((optics: \"soil\")), LeafList((path: \"l.txt\", optics: \"leaf\")),", ("l.txt", b"0.05 5 5 1 0 0 0\n"), "l.txt"),
    file("leaf_list_empty", GROUND, "Ground((optics: \"soil\")), LeafList((path: \"l.txt\", optics: \"leaf\")),", ("l.txt", b"# no leaves\n"), "l.txt"),
    scene_file("leaf_list_sides", GROUND, "Ground((optics: \"soil\")), LeafList((path: \"l.txt\", optics: \"leaf\", sides: 2)),", ("l.txt", b"0.05 5 5 1 0 0 1\n"), "sides"),
    file("esri_no_header", GROUND, "Ground((optics: \"soil\", topography: RasterFile((path: \"d.asc\", format: EsriAscii)))),", ("d.asc", b"1 2 3\n4 5 6\n"), "d.asc"),
    file("esri_short", GROUND, "Ground((optics: \"soil\", topography: RasterFile((path: \"d.asc\", format: EsriAscii)))),", ("d.asc", b"ncols 3\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 5\n1 2 3\n4 5 6\n"), "d.asc"),
    file("esri_text_value", GROUND, "Ground((optics: \"soil\", topography: RasterFile((path: \"d.asc\", format: EsriAscii)))),", ("d.asc", b"ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 10\n1 x\n4 5\n"), "d.asc"),
    file("esri_zero_cellsize", GROUND, "Ground((optics: \"soil\", topography: RasterFile((path: \"d.asc\", format: EsriAscii)))),", ("d.asc", b"ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 0\n1 2\n4 5\n"), "d.asc"),
    file("esri_huge_ncols", GROUND, "Ground((optics: \"soil\", topography: RasterFile((path: \"d.asc\", format: EsriAscii)))),", ("d.asc", b"ncols 99999999999\nnrows 99999999999\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n4 5\n"), "d.asc"),
    file("binary_short", GROUND, "Ground((optics: \"soil\", topography: RasterFile((path: \"d.bin\", format: BinaryF32(nodes: (3, 3), spacing_m: (5.0, 5.0)))))),", ("d.bin", b"\x00\x00\x80\x3f"), "d.bin"),
    file("binary_nodes_overflow", GROUND, "Ground((optics: \"soil\", topography: RasterFile((path: \"d.bin\", format: BinaryF32(nodes: (4294967296, 4294967296), spacing_m: (5.0, 5.0)))))),", ("d.bin", b"\x00\x00\x80\x3f"), "d.bin"),
    file("binary_nan", GROUND, "Ground((optics: \"soil\", topography: RasterFile((path: \"d.bin\", format: BinaryF32(nodes: (2, 2), spacing_m: (10.0, 10.0)))))),", ("d.bin", b"\x00\x00\xc0\x7f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00"), "d.bin"),
];

/// The georeferenced base: origin (500000, 4800000) in EPSG:32631, ground from `d.tif`.
const GEO_FROM: &str = "version: 1,||Ground((optics: \"soil\")),";
const GEO_TO: &str = "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||Ground((optics: \"soil\", topography: RasterFile((path: \"d.tif\", format: GeoTiff)))),";

/// A DEM covering the base scene's map extent: 8 × 8 pixels of 2 m from (499997, 4800013).
fn base_dem() -> geo::Dem {
    geo::Dem {
        nx: 8,
        ny: 8,
        values: (0..64).map(|k| 10.0 + 0.25 * (k % 8) as f64).collect(),
        tie: (499_997.0, 4_800_013.0),
        pixel_m: 2.0,
        epsg: Some(32631),
        nodata: None,
        raster_type: 1,
    }
}

fn tif(d: &geo::Dem) -> Vec<u8> {
    geo::dem_tiff(
        d,
        geo::Sample::F32,
        tiff::encoder::Compression::Uncompressed,
    )
}

fn good_dem() -> Vec<u8> {
    tif(&base_dem())
}

/// The georeferenced base with a land-cover map `d.tif` whose table knows class 1 only.
const LC_FROM: &str = "version: 1,||Ground((optics: \"soil\")),";
const LC_TO: &str = "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||Ground((optics: \"soil\")), LandCover((path: \"d.tif\", classes: {1: TurbidPlot(top_m: 1.0, foliage: Lai(2.0), optics: \"veg\")})),";

/// A class map over the base scene (classes 1, and `other` at pixel (3, 4)).
fn class_map(other: f64) -> Vec<u8> {
    let mut d = geo::Dem {
        values: vec![1.0; 64],
        ..base_dem()
    };
    d.values[3 + 8 * 4] = other;
    geo::dem_tiff(
        &d,
        geo::Sample::F32,
        tiff::encoder::Compression::Uncompressed,
    )
}

/// A land-cover case: stderr must name `names` ("" the scene, else the file) and `needle`.
const fn land_cover(
    name: &'static str,
    from: &'static str,
    to: &'static str,
    make: fn() -> Vec<u8>,
    names: &'static str,
    needle: &'static str,
) -> Case {
    Case {
        made: Some(("d.tif", make)),
        names,
        ..c(name, from, to, needle)
    }
}

const GEOSPATIAL: &[Case] = &[
    c(
        "geo_crs_geographic",
        "version: 1,",
        "version: 1, georeference: (crs: Epsg(4326), origin_map_m: (500000.0, 4800000.0)),",
        "georeference.crs",
    ),
    c(
        "geo_crs_unknown",
        "version: 1,",
        "version: 1, georeference: (crs: Epsg(12), origin_map_m: (500000.0, 4800000.0)),",
        "georeference.crs",
    ),
    c(
        "geo_crs_huge",
        "version: 1,",
        "version: 1, georeference: (crs: Epsg(4294967295), origin_map_m: (500000.0, 4800000.0)),",
        "georeference.crs",
    ),
    c(
        "geo_wkt_geographic",
        "version: 1,",
        "version: 1, georeference: (crs: Wkt(\"GEOGCS[\\\"WGS 84\\\"]\"), origin_map_m: (0.0, 0.0)),",
        "georeference.crs",
    ),
    c(
        "geo_wkt_feet",
        "version: 1,",
        "version: 1, georeference: (crs: Wkt(\"PROJCS[\\\"x\\\",UNIT[\\\"foot\\\",0.3048]]\"), origin_map_m: (0.0, 0.0)),",
        "georeference.crs",
    ),
    c(
        "geo_origin_inf",
        "version: 1,",
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (inf, 0.0)),",
        "georeference.origin_map_m",
    ),
    c(
        "geo_bearing_range",
        "version: 1,",
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (0.0, 0.0), x_axis_bearing_deg: 360.0),",
        "georeference.x_axis_bearing_deg",
    ),
    c(
        "geo_unknown_field",
        "version: 1,",
        "version: 1, georeference: (crs: Epsg(32631), origin_m: (0.0, 0.0)),",
        LINE,
    ),
    geotiff_scene(
        "dem_tif_without_georeference",
        GROUND,
        "Ground((optics: \"soil\", topography: RasterFile((path: \"d.tif\", format: GeoTiff)))),",
        "topography",
    ),
    // Rotated 30°, the scene's map bounding box leaves the DEM that covers it north-up.
    land_cover(
        "dem_tif_rotated_scene_outside",
        GEO_FROM,
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0), x_axis_bearing_deg: 30.0),||Ground((optics: \"soil\", topography: RasterFile((path: \"d.tif\", format: GeoTiff)))),",
        good_dem,
        "d.tif",
        "extent",
    ),
    land_cover(
        "landcover_stand_does_not_fit",
        LC_FROM,
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||Ground((optics: \"soil\")), LandCover((path: \"d.tif\", classes: {1: TreeStand(species: [(name: \"a\", crown: (shape: Ellipsoid, base_height_m: 1.0, height_m: 2.0, radius_x_m: 1.0, foliage: Lai(1.0), optics: \"veg\"))], trees_per_ha: [100000.0], min_spacing_m: 5.0)})),",
        || class_map(1.0),
        "",
        "objects[1].classes",
    ),
    geotiff_scene(
        "dem_tif_origin_m",
        GEO_FROM,
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||Ground((optics: \"soil\", topography: RasterFile((path: \"d.tif\", format: GeoTiff, origin_m: (1.0, 0.0))))),",
        "origin_m",
    ),
    geotiff_scene(
        "dem_tif_missing",
        GEO_FROM,
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||Ground((optics: \"soil\", topography: RasterFile((path: \"nope.tif\", format: GeoTiff)))),",
        "nope.tif",
    ),
    geotiff(
        "dem_tif_wrong_crs",
        || {
            tif(&geo::Dem {
                epsg: Some(32632),
                ..base_dem()
            })
        },
        "ProjectedCRSGeoKey",
    ),
    geotiff(
        "dem_tif_no_geokeys",
        || {
            tif(&geo::Dem {
                epsg: None,
                ..base_dem()
            })
        },
        "ModelTiepointTag",
    ),
    geotiff(
        "dem_tif_nodata_everywhere",
        || {
            tif(&geo::Dem {
                values: vec![-9999.0; 64],
                nodata: Some(-9999.0),
                ..base_dem()
            })
        },
        "GDAL_NODATA",
    ),
    geotiff(
        "dem_tif_nodata_inside",
        || {
            let mut d = base_dem();
            d.values[3 + 8 * 4] = -9999.0;
            d.nodata = Some(-9999.0);
            tif(&d)
        },
        "GDAL_NODATA",
    ),
    geotiff(
        "dem_tif_nan_inside",
        || {
            let mut d = base_dem();
            d.values[3 + 8 * 4] = f64::NAN;
            tif(&d)
        },
        "GDAL_NODATA",
    ),
    geotiff(
        "dem_tif_extent_outside",
        || {
            tif(&geo::Dem {
                tie: (600_000.0, 4_800_013.0),
                ..base_dem()
            })
        },
        "extent",
    ),
    geotiff(
        "dem_tif_extent_partly_outside",
        || {
            tif(&geo::Dem {
                tie: (500_001.0, 4_800_013.0),
                ..base_dem()
            })
        },
        "extent",
    ),
    geotiff("dem_tif_palette_16bit", geo::palette_tiff, "palette"),
    geotiff("dem_tif_rgb", geo::rgb_tiff, "bands"),
    geotiff(
        "dem_tif_truncated",
        || {
            let b = good_dem();
            b[..b.len() / 2].to_vec()
        },
        "image",
    ),
    geotiff(
        "dem_tif_not_a_tiff",
        || b"ncols 2\nnrows 2\n".to_vec(),
        "image",
    ),
    geotiff("dem_tif_empty", Vec::new, "image"),
    land_cover(
        "landcover_unknown_class",
        LC_FROM,
        LC_TO,
        || class_map(7.0),
        "",
        "objects[1].classes",
    ),
    land_cover(
        "landcover_fractional_code",
        LC_FROM,
        LC_TO,
        || class_map(1.5),
        "d.tif",
        "image",
    ),
    land_cover(
        "landcover_outside",
        LC_FROM,
        LC_TO,
        || {
            tif(&geo::Dem {
                values: vec![1.0; 64],
                tie: (400_000.0, 4_800_013.0),
                ..base_dem()
            })
        },
        "d.tif",
        "extent",
    ),
    land_cover(
        "landcover_wrong_crs",
        LC_FROM,
        LC_TO,
        || {
            tif(&geo::Dem {
                values: vec![1.0; 64],
                epsg: Some(32630),
                ..base_dem()
            })
        },
        "d.tif",
        "ProjectedCRSGeoKey",
    ),
    land_cover(
        "landcover_without_georeference",
        GROUND,
        "Ground((optics: \"soil\")), LandCover((path: \"d.tif\", classes: {1: Nothing})),",
        || class_map(1.0),
        "",
        "objects[1]",
    ),
    land_cover(
        "landcover_leaf_area",
        LC_FROM,
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||Ground((optics: \"soil\")), LandCover((path: \"d.tif\", classes: {1: TurbidPlot(top_m: 1.0, foliage: LeafArea(20.0), optics: \"veg\")})),",
        || class_map(1.0),
        "",
        "foliage",
    ),
    land_cover(
        "landcover_bad_optics",
        LC_FROM,
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||Ground((optics: \"soil\")), LandCover((path: \"d.tif\", classes: {1: Water(optics: \"veg\")})),",
        || class_map(1.0),
        "",
        "optics",
    ),
    c(
        "sun_position_no_place",
        "illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0, skyl: [0.1]),",
        "illumination: (sun_position: (utc: \"2024-06-21T10:00:00\"), skyl: [0.1]),",
        "illumination.sun_position.latitude_deg",
    ),
    c(
        "sun_position_laea_crs",
        "version: 1,||illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0, skyl: [0.1]),",
        "version: 1, georeference: (crs: Epsg(3035), origin_map_m: (4321000.0, 3210000.0)),||illumination: (sun_position: (utc: \"2024-06-21T10:00:00\"), skyl: [0.1]),",
        "illumination.sun_position.latitude_deg",
    ),
    c(
        "sun_position_half_place",
        "version: 1,||illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0, skyl: [0.1]),",
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||illumination: (sun_position: (utc: \"2024-06-21T10:00:00\", latitude_deg: 43.0), skyl: [0.1]),",
        "illumination.sun_position.latitude_deg",
    ),
    land_cover(
        "landcover_stand_densities",
        LC_FROM,
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||Ground((optics: \"soil\")), LandCover((path: \"d.tif\", classes: {1: TreeStand(species: [(name: \"a\", crown: (shape: Ellipsoid, base_height_m: 1.0, height_m: 2.0, radius_x_m: 1.0, foliage: Lai(1.0), optics: \"veg\"))], trees_per_ha: [100.0, 50.0])})),",
        || class_map(1.0),
        "",
        "trees_per_ha",
    ),
    land_cover(
        "landcover_missing",
        LC_FROM,
        "version: 1, georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),||Ground((optics: \"soil\")), LandCover((path: \"nope.tif\", classes: {1: Nothing})),",
        || class_map(1.0),
        "",
        "nope.tif",
    ),
];

const LIDARS: &[Case] = &[
    lidar(
        "lidar_band",
        "band: \"nir\",\n        platform",
        "band: \"swir\",\n        platform",
        "lidars[0].band",
    ),
    lidar(
        "lidar_footprint",
        "footprint_radius_m: Some(0.3)",
        "footprint_radius_m: Some(-1.0)",
        "lidars[0].footprint_radius_m",
    ),
    lidar(
        "lidar_both_footprints",
        "footprint_radius_m: Some(0.3),",
        "footprint_radius_m: Some(0.3), divergence_mrad: Some(0.5),",
        "lidars[0].footprint_radius_m",
    ),
    lidar(
        "lidar_edge",
        "bin_ns: 1.0,",
        "bin_ns: 1.0, edge_intensity: 1.5,",
        "lidars[0].edge_intensity",
    ),
    lidar(
        "lidar_view_zenith",
        "view_zenith_deg: 0.0",
        "view_zenith_deg: 85.0",
        "lidars[0].platform.view_zenith_deg",
    ),
    lidar(
        "lidar_pulse_spacing_tiny",
        "pulse_spacing_m: 1.0",
        "pulse_spacing_m: 1e-300",
        "lidars[0].platform",
    ),
    lidar(
        "lidar_lines_zero",
        "lines: 1,",
        "lines: 0,",
        "lidars[0].platform.pulses.lines",
    ),
    lidar(
        "lidar_lines_huge",
        "lines: 1,",
        "lines: 4000000000,",
        "lidars[0].platform",
    ),
    lidar(
        "lidar_bin_zero",
        "bin_ns: 1.0",
        "bin_ns: 0.0",
        "lidars[0].bin_ns",
    ),
    lidar(
        "lidar_altitude",
        "altitude_m: 500.0",
        "altitude_m: -500.0",
        "lidars[0].platform.altitude_m",
    ),
    lidar(
        "lidar_max_order",
        "bin_ns: 1.0,",
        "bin_ns: 1.0, max_order: 0,",
        "lidars[0].max_order",
    ),
    lidar(
        "lidar_photons_zero",
        "bin_ns: 1.0,",
        "bin_ns: 1.0, photons_per_pulse: Some(0),",
        "lidars[0].photons_per_pulse",
    ),
    lidar(
        "lidar_name_slash",
        "name: \"als\"",
        "name: \"a/b\"",
        "lidars[0].name",
    ),
    lidar(
        "lidar_terrestrial_outside",
        "platform: Airborne(altitude_m: 500.0, view_zenith_deg: 0.0,\n                           pulses: Scan(start: (2.0, 5.0), end: (8.0, 5.0), lines: 1,\n                                        line_spacing_m: 1.0, pulse_spacing_m: 1.0)),",
        "platform: Terrestrial(position_m: (20.0, 5.0, 1.5), zenith_deg: (30.0, 150.0, 10.0), azimuth_deg: (0.0, 350.0, 10.0)),",
        "lidars[0].platform.position_m",
    ),
    lidar(
        "lidar_terrestrial_tiny_step",
        "platform: Airborne(altitude_m: 500.0, view_zenith_deg: 0.0,\n                           pulses: Scan(start: (2.0, 5.0), end: (8.0, 5.0), lines: 1,\n                                        line_spacing_m: 1.0, pulse_spacing_m: 1.0)),",
        "platform: Terrestrial(position_m: (5.0, 5.0, 1.5), zenith_deg: (30.0, 150.0, 1e-300), azimuth_deg: (0.0, 350.0, 1e-300)),",
        "lidars[0].platform",
    ),
    lidar(
        "lidar_passive_false_ok_but_bad_band",
        "version: 1,",
        "version: 1, passive: Some(false), name: 7,",
        LINE,
    ),
];

const SECTIONS_AND_SYNTAX: &[Case] = &[
    c(
        "radiative_eta_zero",
        "radiative: (preset: Preview)",
        "radiative: (preset: Preview, image_oversampling: 0)",
        "radiative.image_oversampling",
    ),
    c(
        "radiative_eta_pixels",
        "radiative: (preset: Preview)||size_m: (10.0, 10.0)",
        "radiative: (preset: Preview, image_oversampling: 64)||size_m: (1000.0, 1000.0)",
        "radiative.image_oversampling",
    ),
    c(
        "radiative_albedo",
        "radiative: (preset: Preview)",
        "radiative: (preset: Preview, albedo_threshold: Some(-1.0))",
        "radiative.albedo_threshold",
    ),
    c(
        "radiative_iterations",
        "radiative: (preset: Preview)",
        "radiative: (preset: Preview, max_iterations: Some(0))",
        "radiative.max_iterations",
    ),
    c(
        "radiative_preset",
        "radiative: (preset: Preview)",
        "radiative: (preset: Ultra)",
        "Ultra",
    ),
    c(
        "sensor_below_ground",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"cam\", instrument: FrameCamera((position_m: (5.0, 5.0, -2.0), attitude: LookAt(target_m: (5.0, 5.0, 0.0)), pixels: (8, 8), fov_deg: Some(20.0))))]),",
        "sensors[0].instrument.position_m",
    ),
    c(
        "sensor_no_optics",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"cam\", instrument: FrameCamera((position_m: (5.0, 5.0, 50.0), attitude: LookAt(target_m: (5.0, 5.0, 0.0)), pixels: (8, 8))))]),",
        "sensors[0].instrument.fov_deg",
    ),
    c(
        "sensor_both_optics",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"cam\", instrument: FrameCamera((position_m: (5.0, 5.0, 50.0), attitude: LookAt(target_m: (5.0, 5.0, 0.0)), pixels: (8, 8), fov_deg: Some(20.0), focal_length_mm: Some(35.0), pixel_pitch_um: Some(5.0))))]),",
        "sensors[0].instrument.fov_deg",
    ),
    c(
        "sensor_fov_too_wide",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"cam\", instrument: FrameCamera((position_m: (5.0, 5.0, 50.0), attitude: LookAt(target_m: (5.0, 5.0, 0.0)), pixels: (8, 8), fov_deg: Some(179.0))))]),",
        "sensors[0].instrument.fov_deg",
    ),
    c(
        "sensor_zero_pixels",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"cam\", instrument: FrameCamera((position_m: (5.0, 5.0, 50.0), attitude: LookAt(target_m: (5.0, 5.0, 0.0)), pixels: (0, 8), fov_deg: Some(20.0))))]),",
        "sensors[0].instrument.pixels",
    ),
    c(
        "sensor_look_at_itself",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"cam\", instrument: FrameCamera((position_m: (5.0, 5.0, 50.0), attitude: LookAt(target_m: (5.0, 5.0, 50.0)), pixels: (8, 8), fov_deg: Some(20.0))))]),",
        "sensors[0].instrument.attitude.target_m",
    ),
    c(
        "sensor_zenith_range",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"cam\", instrument: FrameCamera((position_m: (5.0, 5.0, 50.0), attitude: Angles(zenith_deg: 200.0, azimuth_deg: 0.0), pixels: (8, 8), fov_deg: Some(20.0))))]),",
        "sensors[0].instrument.attitude.zenith_deg",
    ),
    c(
        "sensor_unknown_field",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"cam\", instrument: FrameCamera((position_m: (5.0, 5.0, 50.0), attitude: LookAt(target_m: (5.0, 5.0, 0.0)), pixels: (8, 8), fov_deg: Some(20.0), fov: 3.0)))]),",
        "fov",
    ),
    c(
        "sensor_unknown_band",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"cam\", bands: [\"nir\"], instrument: FrameCamera((position_m: (5.0, 5.0, 50.0), attitude: LookAt(target_m: (5.0, 5.0, 0.0)), pixels: (8, 8), fov_deg: Some(20.0))))]),",
        "sensors[0].bands[0]",
    ),
    c(
        "sensor_bad_name",
        "version: 1,",
        "version: 1, sensors: Some([(name: \"a/b\", instrument: FrameCamera((position_m: (5.0, 5.0, 50.0), attitude: LookAt(target_m: (5.0, 5.0, 0.0)), pixels: (8, 8), fov_deg: Some(20.0))))]),",
        "sensors[0].name",
    ),
    c(
        "atmosphere_isolated",
        "version: 1,",
        "version: 1, atmosphere: (molecules: ()),",
        "grid.boundary",
    ),
    c(
        "atmosphere_no_constituent",
        "version: 1,",
        "version: 1, atmosphere: (toa_altitude_km: 50.0),",
        "atmosphere",
    ),
    c("version_two", "version: 1,", "version: 2,", "version"),
    c(
        "thermal_unknown_key",
        "version: 1,",
        "version: 1, thermal: (mode: T, temperatures_k: {\"bark\": 300.0}, default_temperature_k: Some(300.0)),",
        "thermal.temperatures_k.bark",
    ),
    c(
        "thermal_negative_temperature",
        "version: 1,",
        "version: 1, thermal: (mode: T, temperatures_k: {\"soil\": -3.0}, default_temperature_k: Some(300.0)),",
        "thermal.temperatures_k.soil",
    ),
    c(
        "thermal_nan_sky",
        "version: 1,",
        "version: 1, thermal: (mode: RT, default_temperature_k: Some(300.0), sky_temperature_k: Some(NaN)),",
        "thermal.sky_temperature_k",
    ),
    c(
        "thermal_missing_temperature",
        "version: 1,",
        "version: 1, thermal: (mode: T, temperatures_k: {\"veg\": 300.0, \"soil\": 310.0}),",
        "thermal.temperatures_k",
    ),
    c(
        "thermal_sunlit_and_fixed",
        "version: 1,",
        "version: 1, thermal: (mode: T, temperatures_k: {\"soil\": 300.0}, sunlit_temperatures_k: {\"soil\": (290.0, 310.0)}, default_temperature_k: Some(300.0)),",
        "thermal.sunlit_temperatures_k.soil",
    ),
    c(
        "thermal_missing_mode",
        "version: 1,",
        "version: 1, thermal: (default_temperature_k: Some(300.0)),",
        "thermal",
    ),
    c(
        "missing_paren",
        "sun_azimuth_deg: 0.0, skyl: [0.1])",
        "sun_azimuth_deg: 0.0, skyl: [0.1]",
        LINE,
    ),
    c(
        "unknown_top_field",
        "version: 1,",
        "version: 1, colour: \"red\",",
        "colour",
    ),
    c(
        "unknown_crown_field",
        "radius_x_m: 1.5,",
        "radius_x_m: 1.5, radius_z_m: 2.0,",
        "radius_z_m",
    ),
    c(
        "string_for_number",
        "radius_x_m: 1.5",
        "radius_x_m: \"big\"",
        LINE,
    ),
    c(
        "missing_grid",
        "grid: (size_m: (10.0, 10.0), cell_m: (1.0, 1.0, 1.0), boundary: Isolated),",
        "",
        "grid",
    ),
    c(
        "unknown_object",
        GROUND,
        "Ground((optics: \"soil\")), Cloud((density: 1.0)),",
        "Cloud",
    ),
    c("negative_count_type", "sides: 8", "sides: -8", LINE),
    asset(
        "default_lad_huge",
        "default.ron",
        "leaf_size_m: 0.05)",
        "leaf_size_m: -0.05)",
        "leaf_size_m",
    ),
    c(
        "trunk_sides_huge",
        "sides: 6, optics: \"wall\"",
        "sides: 100000, optics: \"wall\"",
        "objects[1].trunk.sides",
    ),
    c(
        "leaves_sides_huge",
        "sides: 8",
        "sides: 4000000000",
        "objects[5].sides",
    ),
    // Fuzzer regressions: a 1e300 m trunk overflowed the plan's cell ranges; pulses aimed
    // 1e12 m away broke the first-flight geometry.
    asset(
        "urban_trunk_huge",
        "lidar_multipulse_urban.ron",
        "diameter_m: 0.25",
        "diameter_m: 1e300",
        "--max-memory",
    ),
    asset(
        "als_pulse_far",
        "lidar_als.ron",
        "pulses: Single((2.0, 2.0))",
        "pulses: Single((1e12, 2.0))",
        "lidars[0].platform.pulses",
    ),
    asset(
        "als_pulse_far_negative",
        "lidar_als.ron",
        "pulses: Single((2.0, 2.0))",
        "pulses: Single((-1e308, 2.0))",
        "lidars[0].platform.pulses",
    ),
    // Fuzzer regressions: a huge spacing looped ~forever; counts overflowed their sum.
    asset(
        "default_spacing_huge",
        "default.ron",
        "min_spacing_m: 4.0",
        "min_spacing_m: 1e300",
        "objects[1].placement",
    ),
    asset(
        "default_counts_overflow",
        "default.ron",
        "counts: [5, 5]",
        "counts: [18446744073709551615, 5]",
        "objects[1].placement.counts",
    ),
    asset(
        "default_counts_huge",
        "default.ron",
        "counts: [5, 5]",
        "counts: [5000000, 5]",
        "objects[1].placement.counts",
    ),
    asset(
        "turbid_layer_view_down",
        "turbid_layer.ron",
        "zenith_deg: 75.0",
        "zenith_deg: 105.0",
        "directions.exact[",
    ),
    asset(
        "turbid_layer_lai",
        "turbid_layer.ron",
        "foliage: Lai(3.0)",
        "foliage: Lai(3e6)",
        "foliage",
    ),
    asset(
        "urban_sun",
        "urban.ron",
        "sun_zenith_deg",
        "sun_zenith_deg: 120.0, _x",
        LINE,
    ),
    asset(
        "lidar_als_band",
        "lidar_als.ron",
        "band: \"",
        "band: \"none_",
        "lidars[0].band",
    ),
];

const CLI: &[Case] = &[
    args("photons_with_flux", &["--photons", "1000"], "--photons"),
    args("mode_t_without_thermal", &["--mode", "t"], "--mode T"),
    args("sampler_with_flux", &["--sampler", "alias"], "--sampler"),
    args("box_gamma_with_flux", &["--box-gamma", "3"], "--box-gamma"),
    args(
        "box_budget_with_flux",
        &["--box-budget", "10"],
        "--box-budget",
    ),
    args(
        "box_gamma_without_box",
        &["--solver", "monte-carlo", "--box-gamma", "3"],
        "--box-gamma",
    ),
    args(
        "box_gamma_below_one",
        &[
            "--solver",
            "monte-carlo",
            "--sampler",
            "box",
            "--box-gamma",
            "0.5",
        ],
        "--box-gamma",
    ),
    args(
        "box_gamma_nan",
        &[
            "--solver",
            "monte-carlo",
            "--sampler",
            "box",
            "--box-gamma",
            "NaN",
        ],
        "--box-gamma",
    ),
    args(
        "photons_zero",
        &["--solver", "monte-carlo", "--photons", "0"],
        "--photons",
    ),
    args("max_memory_text", &["--max-memory", "lots"], "--max-memory"),
    args("max_memory_zero", &["--max-memory", "0"], "--max-memory"),
    args("max_memory_tiny", &["--max-memory", "1K"], "--max-memory"),
    args(
        "eta_zero",
        &["--image-oversampling", "0"],
        "--image-oversampling",
    ),
    args(
        "eta_65",
        &["--image-oversampling", "65"],
        "--image-oversampling",
    ),
    args("solver_unknown", &["--solver", "magic"], "--solver"),
    args("preset_unknown", &["--preset", "ultra"], "--preset"),
    args("isa_unknown", &["--isa", "sse9"], "--isa"),
];

#[test]
fn grid_cases() {
    run_all(GRID);
}

#[test]
fn band_and_spectral_response_cases() {
    run_all(BANDS);
}

#[test]
fn optics_cases() {
    run_all(OPTICS);
}

#[test]
fn illumination_and_direction_cases() {
    run_all(ILLUMINATION);
    run_all(DIRECTIONS);
}

#[test]
fn crown_cases() {
    run_all(CROWNS);
}

#[test]
fn other_object_cases() {
    run_all(OTHER_OBJECTS);
}

#[test]
fn referenced_file_cases() {
    run_all(FILES);
}

#[test]
fn lidar_cases() {
    run_all(LIDARS);
}

#[test]
fn section_and_syntax_cases() {
    run_all(SECTIONS_AND_SYNTAX);
}

#[test]
fn geospatial_cases() {
    run_all(GEOSPATIAL);
}

#[test]
fn cli_cases() {
    run_all(CLI);
}

/// The catalogue holds at least 100 cases, each with a unique name (one folder each), and the
/// base scenes themselves pass `check` (so every failure above is the mutation's).
#[test]
fn catalogue_is_complete_and_its_bases_are_valid() {
    let all: Vec<&Case> = [
        GRID,
        BANDS,
        OPTICS,
        ILLUMINATION,
        DIRECTIONS,
        CROWNS,
        OTHER_OBJECTS,
        FILES,
        LIDARS,
        SECTIONS_AND_SYNTAX,
        GEOSPATIAL,
        CLI,
    ]
    .iter()
    .flat_map(|s| s.iter())
    .collect();
    eprintln!("{} catalogue cases", all.len());
    assert!(all.len() >= 100, "{} cases", all.len());
    let mut names: Vec<&str> = all.iter().map(|c| c.name).collect();
    names.sort_unstable();
    let n = names.len();
    names.dedup();
    assert_eq!(names.len(), n, "duplicate case names");
    for (name, text) in [("base", BASE), ("lidar_base", LIDAR)] {
        let p = tmp().join(format!("{name}.ron"));
        std::fs::write(&p, text).unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_lumenscape"))
            .args(["check", p.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
