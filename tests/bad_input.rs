//! Bad input: every case gives a clear error naming the file, line/column and field, and the
//! CLI exits non-zero; nothing panics and no product is half-written.

mod common;
use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::error::SceneError;
use lumenscape::simulation::Simulation;
use std::path::{Path, PathBuf};
use std::process::Command;

const GOOD: &str = r#"(
    version: 1,
    grid: (size_m: (10.0, 10.0), cell_m: (1.0, 1.0, 1.0), boundary: Isolated),
    bands: [(name: "red", wavelength_nm: 670.0)],
    optics: {
        "leaf": BiLambertian(reflectance: [0.05], transmittance: [0.02]),
        "veg": Turbid(leaf: "leaf", lad: Spherical),
        "soil": Lambertian(reflectance: [0.1]),
    },
    illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0),
    objects: [
        Ground((optics: "soil")),
        Tree((
            position_m: (5.0, 5.0),
            crown: (shape: Ellipsoid, base_height_m: 1.0, height_m: 3.0, radius_x_m: 1.5,
                    foliage: LeafAreaDensity(0.8), optics: "veg"),
        )),
    ],
)
"#;

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("lumenscape-bad-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the `lumenscape` binary with `args`.
fn cli(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lumenscape"))
        .args(args)
        .output()
        .unwrap()
}

fn write(name: &str, text: &str) -> PathBuf {
    let p = dir().join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Loads a scene text (written to a file) and returns the error message, which must name the
/// file; `line` is the expected line, when the error should carry one.
fn error_of(name: &str, text: &str) -> (SceneError, String) {
    let p = write(name, text);
    let e = match Simulation::load(&p, RunSettings::default()) {
        Ok(_) => panic!("{name}: expected an error"),
        Err(e) => e,
    };
    let msg = e.to_string();
    assert!(
        msg.contains(&p.display().to_string()),
        "{name}: message does not name the file: {msg}"
    );
    (e, msg)
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
        .expect("needle in text")
        + 1
}

#[test]
fn good_scene_loads() {
    let p = write("good.ron", GOOD);
    Simulation::load(&p, RunSettings::default()).unwrap();
}

#[test]
fn ron_syntax_error_names_line_and_column() {
    let text = GOOD.replace("sun_azimuth_deg: 0.0)", "sun_azimuth_deg: 0.0");
    let (e, msg) = error_of("syntax.ron", &text);
    assert!(matches!(e, SceneError::Syntax { .. }), "{msg}");
    assert!(line_of(&e).is_some(), "{msg}");
}

#[test]
fn unknown_field_is_an_error_at_its_line() {
    let text = GOOD.replace("radius_x_m: 1.5,", "radius_x_m: 1.5, radius_z_m: 2.0,");
    let (e, msg) = error_of("unknown.ron", &text);
    assert!(msg.contains("radius_z_m"), "{msg}");
    assert_eq!(
        line_of(&e),
        Some(line_containing(&text, "radius_z_m")),
        "{msg}"
    );
}

#[test]
fn missing_files_are_reported() {
    let p = dir().join("does_not_exist.ron");
    let e = Simulation::load(&p, RunSettings::default())
        .err()
        .expect("error");
    assert!(matches!(e, SceneError::Io { .. }));
    assert!(e.to_string().contains("does_not_exist.ron"));
    let text = GOOD.replace("Ground((optics: \"soil\")),", "Ground((optics: \"soil\", topography: RasterFile((path: \"nope.asc\", format: EsriAscii)))),");
    let (_, msg) = error_of("missing_dem.ron", &text);
    assert!(msg.contains("nope.asc"), "{msg}");
    let text = GOOD.replace("Ground((optics: \"soil\")),", "Ground((optics: \"soil\")), Mesh((path: \"nope.obj\", groups: [(group: \"a\", optics: \"soil\")])),");
    let (e, msg) = error_of("missing_mesh.ron", &text);
    assert!(msg.contains("nope.obj"), "{msg}");
    assert_eq!(line_of(&e), Some(line_containing(&text, "nope.obj")));
}

#[test]
fn negative_and_nan_densities_and_sizes_are_rejected_with_their_field() {
    for (name, from, to, field) in [
        (
            "neg_density.ron",
            "LeafAreaDensity(0.8)",
            "LeafAreaDensity(-0.8)",
            "foliage",
        ),
        (
            "nan_density.ron",
            "LeafAreaDensity(0.8)",
            "LeafAreaDensity(NaN)",
            "foliage",
        ),
        (
            "neg_radius.ron",
            "radius_x_m: 1.5",
            "radius_x_m: -1.5",
            "radius_x_m",
        ),
        (
            "nan_height.ron",
            "height_m: 3.0",
            "height_m: NaN",
            "height_m",
        ),
        (
            "zero_cell.ron",
            "cell_m: (1.0, 1.0, 1.0)",
            "cell_m: (1.0, 0.0, 1.0)",
            "cell_m",
        ),
        (
            "neg_cell.ron",
            "cell_m: (1.0, 1.0, 1.0)",
            "cell_m: (-1.0, 1.0, 1.0)",
            "cell_m",
        ),
        (
            "bad_sun.ron",
            "sun_zenith_deg: 30.0",
            "sun_zenith_deg: 95.0",
            "sun_zenith_deg",
        ),
        ("bad_version.ron", "version: 1", "version: 7", "version"),
        (
            "bad_optics_ref.ron",
            "optics: \"veg\"",
            "optics: \"vegg\"",
            "optics",
        ),
        (
            "wrong_band_count.ron",
            "reflectance: [0.1]",
            "reflectance: [0.1, 0.2]",
            "reflectance",
        ),
        (
            "non_whole_cells.ron",
            "size_m: (10.0, 10.0)",
            "size_m: (10.5, 10.0)",
            "cell_m",
        ),
    ] {
        let text = GOOD.replace(from, to);
        assert_ne!(text, GOOD, "{name}: replacement did not apply");
        let (e, msg) = error_of(name, &text);
        assert!(matches!(e, SceneError::Invalid { .. }), "{name}: {msg}");
        assert!(
            msg.contains(field),
            "{name}: message does not name `{field}`: {msg}"
        );
        assert_eq!(
            line_of(&e),
            Some(line_containing(&text, to)),
            "{name}: {msg}"
        );
    }
}

#[test]
fn leaf_reflectance_plus_transmittance_above_one_is_rejected() {
    let text = GOOD.replace("transmittance: [0.02]", "transmittance: [0.97]");
    let (e, msg) = error_of("rt.ron", &text);
    assert!(msg.contains("reflectance + transmittance"), "{msg}");
    assert_eq!(line_of(&e), Some(line_containing(&text, "\"leaf\"")));
}

#[test]
fn objects_outside_an_isolated_scene_are_rejected() {
    let text = GOOD.replace("position_m: (5.0, 5.0)", "position_m: (9.0, 5.0)");
    let (e, msg) = error_of("outside.ron", &text);
    assert!(msg.contains("outside the isolated scene"), "{msg}");
    assert_eq!(line_of(&e), Some(line_containing(&text, "position_m")));
}

#[test]
fn an_empty_atmosphere_is_refused_at_its_line() {
    let text = GOOD.replacen("    version: 1,", "    version: 1,\n    atmosphere: (),", 1);
    let (e, msg) = error_of("atmosphere.ron", &text);
    assert!(
        msg.contains("atmosphere") && msg.contains("at least one"),
        "{msg}"
    );
    assert_eq!(line_of(&e), Some(3));
}

#[test]
fn bad_lidar_fields_are_named_with_their_line() {
    let lidar = "    lidars: Some([(\n        name: \"als\",\n        band: \"nope\",\n        platform: Airborne(altitude_m: 500.0, pulses: Single((1.0, 1.0))),\n        footprint_radius_m: Some(0.2),\n    )]),";
    let text = GOOD.replacen("    version: 1,", &format!("    version: 1,\n{lidar}"), 1);
    let (_, msg) = error_of("lidar_band.ron", &text);
    assert!(
        msg.contains("lidars[0].band") && msg.contains("nope"),
        "{msg}"
    );
    let text = GOOD.replacen(
        "    version: 1,",
        &format!(
            "    version: 1,\n{}",
            lidar.replace("\"nope\"", "\"red\"").replace(
                "footprint_radius_m: Some(0.2)",
                "footprint_radius_m: Some(-1.0)"
            )
        ),
        1,
    );
    let (e, msg) = error_of("lidar_fp.ron", &text);
    assert!(msg.contains("lidars[0].footprint_radius_m"), "{msg}");
    assert_eq!(line_of(&e), Some(7), "{msg}");
    // A beam table whose radii go backwards: the field, its line and the offending point.
    let text = GOOD.replacen(
        "    version: 1,",
        &format!(
            "    version: 1,\n{}",
            lidar.replace("\"nope\"", "\"red\"").replace(
                "footprint_radius_m: Some(0.2),",
                "footprint_radius_m: Some(0.2),\n        beam: Some(Tabulated(points: [(0.0, 1.0), (0.5, 1.0), (0.4, 0.0)])),"
            )
        ),
        1,
    );
    let (e, msg) = error_of("lidar_beam.ron", &text);
    assert!(
        msg.contains("lidars[0].beam") && msg.contains("point 2"),
        "{msg}"
    );
    assert_eq!(line_of(&e), Some(8), "{msg}");
    // `passive: false` with a fusion product: the passive radiance is needed, so refused,
    // naming the field and its line.
    let text = GOOD.replacen(
        "    version: 1,",
        &format!(
            "    version: 1,\n    passive: Some(false),\n{}",
            lidar.replace("\"nope\"", "\"red\"").replace(
                "footprint_radius_m: Some(0.2),",
                "footprint_radius_m: Some(0.2),\n        fusion: true,"
            )
        ),
        1,
    );
    let (e, msg) = error_of("lidar_fusion.ron", &text);
    assert!(
        msg.contains("passive") && msg.contains("fusion") && msg.contains("`als`"),
        "{msg}"
    );
    assert_eq!(line_of(&e), Some(3), "{msg}");
}

#[test]
fn degenerate_triangles_are_skipped_with_a_counted_warning_and_empty_meshes_fail() {
    let obj = "o leafy\nv 1 1 0\nv 2 1 0\nv 1 2 0\nv 3 1 0\nf 1 2 3\nf 1 2 4\nf 2 2 3\n";
    write("degen.obj", obj);
    let text = GOOD.replace("Ground((optics: \"soil\")),", "Ground((optics: \"soil\")), Mesh((path: \"degen.obj\", groups: [(group: \"leafy\", optics: \"leaf\", two_sided: true)])),");
    let p = write("degen.ron", &text);
    let mut sim = Simulation::load(&p, RunSettings::default()).unwrap();
    sim.run_stage(lumenscape::simulation::Stage::Maket).unwrap();
    let r = sim.resource::<lumenscape::resources::maket_report::MaketReport>();
    assert_eq!(r.facet_count.get("leaf"), Some(&1), "{r:?}");
    assert!(
        r.warnings.iter().any(|w| w.contains("2 degenerate")),
        "{:?}",
        r.warnings
    );
    write("empty.obj", "# nothing\n");
    let text = GOOD.replace("Ground((optics: \"soil\")),", "Ground((optics: \"soil\")), Mesh((path: \"empty.obj\", groups: [(group: \"a\", optics: \"leaf\")])),");
    let (_, msg) = error_of("empty.ron", &text);
    assert!(msg.contains("empty.obj"), "{msg}");
}

#[test]
fn cli_exits_non_zero_with_file_line_and_field() {
    let text = GOOD.replace("radius_x_m: 1.5", "radius_x_m: -1.5");
    let p = write("cli_bad.ron", &text);
    let out = cli(&["check", p.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    let line = line_containing(&text, "radius_x_m");
    assert!(
        err.contains(&format!("{}:{line}:", p.display())) && err.contains("radius_x_m"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    // Good scene: exit 0, summary on stdout.
    let p = write("cli_good.ron", GOOD);
    let out = cli(&["check", p.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("leaf area `veg`"));
}

#[test]
fn grids_above_the_memory_limit_are_refused_before_allocation() {
    let p = write("mem.ron", GOOD);
    let out_dir = dir().join("mem_out");
    let out = cli(&[
        "maket",
        p.to_str().unwrap(),
        "--max-memory",
        "1K",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--max-memory"), "{err}");
    assert!(
        !out_dir.join("maket.json").exists(),
        "no product after a refused run"
    );
    let out = cli(&["maket", p.to_str().unwrap(), "--max-memory", "lots"]);
    assert!(!out.status.success());
}

#[test]
fn unknown_fields_inside_enum_variants_are_errors() {
    let text = GOOD.replace("Ground((optics: \"soil\")),", "Ground((optics: \"soil\", topography: Raster((nodes: (2, 2), spacing_m: (10.0, 10.0), altitude_m: [0, 0, 0, 0], smooth: true)))),");
    let (e, msg) = error_of("unknown_in_enum.ron", &text);
    assert!(msg.contains("smooth"), "{msg}");
    assert_eq!(line_of(&e), Some(line_containing(&text, "smooth")));
}

#[test]
fn bad_image_oversampling_is_rejected_with_its_field_and_line() {
    let with = |v: &str| {
        GOOD.replace(
            "    illumination:",
            &format!("    radiative: (image_oversampling: {v}),\n    illumination:"),
        )
    };
    let ok = write("eta_ok.ron", &with("3"));
    Simulation::load(&ok, RunSettings::default()).expect("η = 3 is valid");
    for (name, v, what) in [
        ("eta_zero.ron", "0", "1..=64"),
        ("eta_big.ron", "65", "1..=64"),
        ("eta_negative.ron", "-2", ""),
        ("eta_float.ron", "1.5", ""),
    ] {
        let text = with(v);
        let (e, msg) = error_of(name, &text);
        assert!(msg.contains(what), "{name}: {msg}");
        if !what.is_empty() {
            assert!(matches!(e, SceneError::Invalid { .. }), "{name}: {msg}");
            assert!(
                msg.contains("radiative.image_oversampling"),
                "{name}: {msg}"
            );
            assert_eq!(
                line_of(&e),
                Some(line_containing(&text, "image_oversampling")),
                "{name}: {msg}"
            );
        } else {
            assert!(line_of(&e).is_some(), "{name}: {msg}");
        }
    }
    // 10⁶ columns × 10² pixels each exceed the image size limit.
    let text = with("10").replace("size_m: (10.0, 10.0)", "size_m: (1000.0, 1000.0)");
    let (e, msg) = error_of("eta_pixels.ron", &text);
    assert!(matches!(e, SceneError::Invalid { .. }), "{msg}");
    assert!(
        msg.contains("radiative.image_oversampling") && msg.contains("pixels"),
        "{msg}"
    );
}

/// Fictive directions are refused (issue #31): no solver computes radiance along them (flux
/// tracking walks the tiling directions only; Monte Carlo peels off toward the exact ones), so
/// they would appear in no product. The error names the file, the line of `fictive:` and the
/// field, and points to `directions.exact`; an empty list is accepted.
#[test]
fn fictive_directions_are_refused_naming_the_field_and_line() {
    let text = GOOD.replace(
        "    objects: [",
        "    directions: Some((\n        count: 40,\n        fictive: [(zenith_deg: 20.0, azimuth_deg: 0.0)],\n    )),\n    objects: [",
    );
    let (e, msg) = error_of("fictive.ron", &text);
    assert!(matches!(e, SceneError::NotSupported { .. }), "{msg}");
    assert!(
        msg.contains("fictive.ron")
            && msg.contains("directions.fictive")
            && msg.contains("directions.exact"),
        "{msg}"
    );
    assert_eq!(
        line_of(&e),
        Some(line_containing(&text, "fictive: [")),
        "{msg}"
    );
    let empty = text.replace("[(zenith_deg: 20.0, azimuth_deg: 0.0)]", "[]");
    if let Err(e) = Simulation::load(&write("fictive_empty.ron", &empty), RunSettings::default()) {
        panic!("an empty fictive list is accepted: {e}");
    }
}

/// `--image-oversampling η` overrides the scene's η: nadir images of the 10 × 10-cell scene
/// are 10η × 10η pixels and `summary.json` records η.
#[test]
fn cli_image_oversampling_sets_the_image_pixels() {
    let text = GOOD.replace(
        "    objects: [",
        "    directions: Some((count: 40, exact: [(zenith_deg: 0.0, azimuth_deg: 0.0, label: Some(\"nadir\"))])),\n    objects: [",
    );
    let p = write("eta.ron", &text);
    let out_dir = run_preview(&p, &["--image-oversampling", "3"], "eta_out");
    let mut n = 0;
    for e in std::fs::read_dir(out_dir.join("images")).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_some_and(|x| x == "exr") {
            let (nx, ny, _) = lumenscape::io::exr_out::read_exr_channels(&path).unwrap();
            assert_eq!((nx, ny), (30, 30), "{}", path.display());
            n += 1;
        }
    }
    assert!(n >= 1, "no image written");
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["settings"]["image_oversampling"], 3);
}

/// A bad `--image-oversampling` is refused with a message naming the option, exit non-zero,
/// and no product: 0 and 65 are outside 1..=64; 9 on a 1000 × 1000-cell grid makes images of
/// 8.1e7 pixels, above the 2^26 limit.
#[test]
fn cli_image_oversampling_out_of_range_is_refused() {
    let p = write("eta_bad.ron", GOOD);
    for eta in ["0", "65", "x"] {
        let out = cli(&["check", p.to_str().unwrap(), "--image-oversampling", eta]);
        assert!(!out.status.success(), "η {eta} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--image-oversampling"), "{err}");
    }
    let big = write(
        "eta_big.ron",
        &GOOD.replace("size_m: (10.0, 10.0)", "size_m: (1000.0, 1000.0)"),
    );
    let (code, err) = run_refused(&big, &["--image-oversampling", "9"], "eta_big_out");
    assert_eq!(code, Some(1));
    assert!(
        err.contains("--image-oversampling 9")
            && err.contains("eta_big.ron")
            && err.contains("limit"),
        "{err}"
    );
}

#[test]
fn bad_turbid_subfaces_fields_are_rejected_with_their_field_and_line() {
    let with = |v: &str| {
        GOOD.replace(
            "    illumination:",
            &format!("    radiative: ({v}),\n    illumination:"),
        )
    };
    for ok in [
        "turbid_subfaces: Some(Subfaces), turbid_exit_grouping: Some(true)",
        "turbid_subfaces: Some(Faces)",
        "turbid_subfaces: Some(Blend), turbid_exit_grouping: Some(false)",
        "turbid_exit_grouping: Some(true)",
    ] {
        let p = write("subfaces_ok.ron", &with(ok));
        Simulation::load(&p, RunSettings::default()).unwrap_or_else(|e| panic!("{ok}: {e}"));
    }
    // Unknown mode and wrong types: syntax errors at the field's line naming what is wrong.
    for (name, v, what) in [
        (
            "subfaces_variant.ron",
            "turbid_subfaces: Some(Quads)",
            "Quads",
        ),
        ("subfaces_type.ron", "turbid_subfaces: Some(2)", ""),
        ("grouping_type.ron", "turbid_exit_grouping: Some(1)", ""),
    ] {
        let text = with(v);
        let (e, msg) = error_of(name, &text);
        assert!(matches!(e, SceneError::Syntax { .. }), "{name}: {msg}");
        assert!(msg.contains(what), "{name}: {msg}");
        assert_eq!(
            line_of(&e),
            Some(line_containing(&text, "turbid_")),
            "{name}: {msg}"
        );
    }
    // Exit grouping acts on incident-face stores only.
    for v in ["Off", "Blend"] {
        let text = with(&format!(
            "turbid_subfaces: Some({v}),\n        turbid_exit_grouping: Some(true)"
        ));
        let (e, msg) = error_of("grouping_without_faces.ron", &text);
        assert!(matches!(e, SceneError::Invalid { .. }), "{v}: {msg}");
        assert!(msg.contains("radiative.turbid_exit_grouping"), "{v}: {msg}");
        assert_eq!(
            line_of(&e),
            Some(line_containing(&text, "turbid_exit_grouping")),
            "{v}: {msg}"
        );
        // The CLI refuses it with a non-zero exit, naming the file and the field.
        let p = write("grouping_without_faces_cli.ron", &text);
        let out = cli(&["check", p.to_str().unwrap()]);
        assert!(!out.status.success(), "{v}: check accepted the scene");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("grouping_without_faces_cli.ron")
                && err.contains("radiative.turbid_exit_grouping"),
            "{v}: {err}"
        );
    }
}

/// `--isa` caps the walks' instruction set and `summary.json` records what ran: with `avx2`
/// the batched walk on 4 lanes (where the CPU has AVX2), with `baseline` one ray at a time;
/// the albedo agrees with the default run to 1e-12 relative (the same rays, summed in another
/// order; 1e-6 where the default is the single-precision walk); an unknown value is refused
/// naming the option, with no product.
#[test]
fn cli_isa_caps_the_instruction_set_and_is_recorded() {
    use lumenscape::radiative::engine::{KernelIsa, batch_lanes, instruction_set};
    let p = write("isa.ron", GOOD);
    let run = |isa: &str| {
        let out_dir = run_preview(&p, &["--isa", isa], &format!("isa_{isa}"));
        let s: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out_dir.join("summary.json")).unwrap()).unwrap();
        s
    };
    let best = run("best");
    let albedo = |s: &serde_json::Value| s["bands"][0]["albedo"].as_f64().unwrap();
    for (arg, cap) in [
        ("best", KernelIsa::Best),
        ("avx2", KernelIsa::Avx2),
        ("baseline", KernelIsa::Baseline),
    ] {
        let s = if arg == "best" {
            best.clone()
        } else {
            run(arg)
        };
        assert_eq!(
            s["settings"]["instruction_set"],
            instruction_set(cap),
            "{arg}"
        );
        assert_eq!(
            s["settings"]["batch_lanes"],
            batch_lanes(cap, true),
            "{arg}"
        );
        // The walk that ran (issue #31): at most the cap's lanes; the kernel and precision go
        // with the lanes.
        let walk = &s["walk"];
        let lanes = walk["lanes"].as_u64().expect("walk.lanes") as usize;
        assert!(lanes <= batch_lanes(cap, true), "{arg}: {walk}");
        let expect = match lanes {
            16 => ("avx512", "f32"),
            8 => ("avx512", "f64"),
            4 => ("avx2", "f64"),
            1 => ("baseline", "f64"),
            _ => panic!("{arg}: {walk}"),
        };
        assert_eq!(
            (walk["kernel"].as_str(), walk["precision"].as_str()),
            (Some(expect.0), Some(expect.1)),
            "{arg}: {walk}"
        );
        if arg == "baseline" {
            assert_eq!(lanes, 1, "{arg}: {walk}");
        }
        // 1e-12 between the f64 walks (the same rays summed in another order); 1e-6 where
        // the default ran the single-precision walk (16 lanes: ~3e-7, see
        // `tests/batch_walk.rs`).
        let tol = if batch_lanes(KernelIsa::Best, true) == 16 && arg != "best" {
            1e-6
        } else {
            1e-12
        };
        let (a, b) = (albedo(&s), albedo(&best));
        assert!(
            a > 0.0 && ((a - b) / b).abs() <= tol,
            "{arg}: albedo {a} vs {b}"
        );
    }
    assert_eq!(batch_lanes(KernelIsa::Baseline, true), 1);
    let (_, err) = run_refused(&p, &["--isa", "avx1024"], "isa_bad");
    assert!(err.contains("--isa"), "{err}");
}

/// `lumenscape run SCENE --quiet --preset preview extra… --out DIR`, which must succeed: DIR.
fn run_preview(scene: &Path, extra: &[&str], out_name: &str) -> PathBuf {
    let out_dir = dir().join(out_name);
    let mut args = vec![
        "run",
        scene.to_str().unwrap(),
        "--quiet",
        "--preset",
        "preview",
    ];
    args.extend_from_slice(extra);
    args.extend(["--out", out_dir.to_str().unwrap()]);
    let out = cli(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out_dir
}

/// `lumenscape run SCENE extra… --out DIR`, which must fail without creating DIR: the exit code
/// and stderr.
fn run_refused(scene: &Path, extra: &[&str], out_name: &str) -> (Option<i32>, String) {
    let out_dir = dir().join(out_name);
    let mut args = vec!["run", scene.to_str().unwrap()];
    args.extend_from_slice(extra);
    args.extend(["--out", out_dir.to_str().unwrap()]);
    let out = cli(&args);
    assert!(!out.status.success(), "{extra:?} accepted");
    assert!(!out_dir.exists(), "no output folder after a refused run");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Products of an earlier run are never mixed with new ones: a second run into the same folder
/// replaces the whole folder (a stale file of the earlier run is gone), and a folder holding
/// other files is refused (naming `--force`) and left untouched unless `--force` is given.
#[test]
fn output_folders_are_replaced_whole_and_foreign_files_are_protected() {
    let scene = common::asset("assets/scenes/turbid_layer.ron");
    let run_into = |out_dir: &Path, force: bool| {
        let mut a = vec![
            "run",
            scene.to_str().unwrap(),
            "--quiet",
            "--preset",
            "preview",
            "--out",
            out_dir.to_str().unwrap(),
        ];
        if force {
            a.push("--force");
        }
        cli(&a)
    };
    // An earlier run's folder is replaced as a whole.
    let out_dir = dir().join("staged-out");
    let _ = std::fs::remove_dir_all(&out_dir);
    let first = run_into(&out_dir, false);
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let stale = out_dir.join("images").join("stale_view.exr");
    std::fs::create_dir_all(stale.parent().unwrap()).unwrap();
    std::fs::write(&stale, b"earlier run").unwrap();
    let again = run_into(&out_dir, false);
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    assert!(out_dir.join("summary.json").exists());
    assert!(
        !stale.exists(),
        "a product of the earlier run was left beside the new ones"
    );
    // A folder with other files is protected.
    let mine = dir().join("my-notes");
    let _ = std::fs::remove_dir_all(&mine);
    std::fs::create_dir_all(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), b"mine").unwrap();
    let refused = run_into(&mine, false);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success(),
        "a folder of other files was overwritten"
    );
    assert!(
        err.contains("not empty") && err.contains("--force"),
        "{err}"
    );
    assert!(mine.join("notes.txt").exists());
    assert!(!mine.join("summary.json").exists());
    let forced = run_into(&mine, true);
    assert!(
        forced.status.success(),
        "{}",
        String::from_utf8_lossy(&forced.stderr)
    );
    assert!(mine.join("summary.json").exists() && !mine.join("notes.txt").exists());
    // No staging folder is left beside the products.
    let leftovers: Vec<_> = std::fs::read_dir(dir())
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains(".partial-"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// An output folder that cannot be created is reported before any simulation work, with its
/// path, a non-zero exit and nothing written.
#[test]
fn an_output_folder_that_cannot_be_created_is_reported_first() {
    let scene = common::asset("assets/scenes/turbid_layer.ron");
    let blocker = dir().join("out-blocker-file");
    std::fs::write(&blocker, b"a file, not a folder").unwrap();
    let out_dir = blocker.join("products");
    let out = cli(&[
        "run",
        scene.to_str().unwrap(),
        "--quiet",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("out-blocker-file"), "{err}");
    assert!(!String::from_utf8_lossy(&out.stdout).contains("products written"));
}

#[test]
fn cli_generate_leaf_size_sets_every_turbid_material_and_refuses_negative_sizes() {
    // `--leaf-size 0`: the pure turbid medium of the oracles (no hotspot) in every turbid
    // material of the generated scene; a negative size is refused with a non-zero exit.
    for kind in ["turbid-layer", "forest", "urban"] {
        let out = cli(&["generate", kind, "--leaf-size", "0"]);
        assert!(out.status.success(), "{kind}: {out:?}");
        let text = String::from_utf8(out.stdout).unwrap();
        let n = text.matches("leaf_size_m:").count();
        assert!(n > 0, "{kind}: no turbid material");
        assert_eq!(n, text.matches("leaf_size_m: 0.0,").count(), "{kind}");
        let out = cli(&["generate", kind, "--leaf-size=-0.01"]);
        assert!(!out.status.success(), "{kind}: negative leaf size accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--leaf-size"), "{kind}: {err}");
    }
}
