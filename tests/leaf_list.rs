//! RAMI leaf-list import (issue 8, first part): exact leaf area, facet counts, facet→turbid,
//! line-numbered errors and normal renormalisation warnings.

mod common;
use lumenscape::resources::maket_report::MaketReport;
use lumenscape::resources::scene::RunSettings;
use lumenscape::simulation::{Simulation, Stage};
use std::f64::consts::PI;

const LEAVES: &str = "# RAMI-style leaf list: radius x y z nx ny nz\n0.1 1.0 1.0 0.5 0 0 1\n0.05, 2.5, 1.5, 0.8, 0.3, 0.1, 0.9   # not unit length\n\n0.08 3.9 3.9 0.3 1 0 0\n";

fn scene(dir: &std::path::Path, list: &str, as_turbid: bool, wrap: bool) -> std::path::PathBuf {
    std::fs::write(dir.join("leaves.txt"), list).unwrap();
    let text = format!(
        r#"(
    version: 1,
    grid: (size_m: (4.0, 4.0), cell_m: (0.5, 0.5, 0.25), boundary: Repetitive),
    bands: [(name: "red", wavelength_nm: 670.0)],
    optics: {{
        "leaf": BiLambertian(reflectance: [0.05], transmittance: [0.03]),
        "soil": Lambertian(reflectance: [0.1]),
    }},
    illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 0.0),
    objects: [
        Ground((optics: "soil")),
        LeafList((path: "leaves.txt", optics: "leaf", sides: 16, as_turbid: {as_turbid}, wrap: {wrap})),
    ],
)
"#
    );
    let p = dir.join("scene.ron");
    std::fs::write(&p, text).unwrap();
    p
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("lumenscape-leaflist-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn leaf_list_gives_exact_leaf_area_and_facet_count() {
    let area = PI * (0.01 + 0.0025 + 0.0064);
    let d = tmp("facets");
    let mut sim =
        Simulation::load(&scene(&d, LEAVES, false, true), RunSettings::default()).unwrap();
    sim.run_stage(Stage::Maket).unwrap();
    let r = sim.resource::<MaketReport>();
    // The leaf at x = 3.9 m with r = 0.08 m crosses the periodic side: split, not lost.
    let got = r.facet_area_m2["leaf"];
    assert!((got - area).abs() < 1e-12, "{got} vs {area}");
    assert!(r.facet_count["leaf"] >= 3 * 16, "{}", r.facet_count["leaf"]);
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("normalised 1 leaf normals")),
        "{:?}",
        r.warnings
    );
    // Facet → turbid keeps the leaf area per cell exactly.
    let d = tmp("turbid");
    let mut sim = Simulation::load(&scene(&d, LEAVES, true, true), RunSettings::default()).unwrap();
    sim.run_stage(Stage::Maket).unwrap();
    let r = sim.resource::<MaketReport>();
    let la = r.leaf_area.values().next().unwrap().rasterised_m2.unwrap();
    assert!((la - area).abs() < 1e-6 * area, "{la} vs {area}");
}

#[test]
fn malformed_leaf_lists_give_line_numbered_errors() {
    let d = tmp("bad");
    for (list, line, what) in [
        ("0.1 1 1 0.5 0 0 1\n0.1 1 1 oops 0 0 1\n", 2, "not a number"),
        ("# header\n0 1 1 0.5 0 0 1\n", 2, "radius"),
        ("0.1 1 1 0.5 0 0\n", 1, "7 values"),
        ("0.1 1 1 0.5 0 0 0\n", 1, "zero length"),
    ] {
        let e = Simulation::load(&scene(&d, list, false, false), RunSettings::default())
            .err()
            .expect("error");
        let msg = e.to_string();
        assert!(
            msg.contains(&format!("leaves.txt:{line}:")) && msg.contains(what),
            "{msg}"
        );
        assert!(
            msg.contains("scene.ron"),
            "the scene file is named too: {msg}"
        );
    }
}

#[test]
fn disk_canopy_generator_uses_a_leaf_list() {
    use lumenscape::scene::generators::disk_canopy::{DiskCanopyParams, disk_canopy_from_list};
    let d = tmp("gen");
    let list = d.join("leaves.txt");
    std::fs::write(&list, LEAVES).unwrap();
    let desc = disk_canopy_from_list(
        &DiskCanopyParams {
            size_m: 4.0,
            cell_m: 0.5,
            ..Default::default()
        },
        &list.to_string_lossy(),
    );
    let mut sim = Simulation::from_desc(
        &desc,
        &lumenscape::scene::SceneSource::generated(),
        RunSettings::default(),
    )
    .unwrap();
    sim.run_stage(Stage::Maket).unwrap();
    let area = PI * (0.01 + 0.0025 + 0.0064);
    let got = sim.resource::<MaketReport>().facet_area_m2["leaf"];
    assert!((got - area).abs() < 1e-12, "{got} vs {area}");
}
