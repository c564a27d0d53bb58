//! Land-cover import (issue #37), stage-level through the built binary: a classification
//! GeoTIFF (written by the `tiff` crate's own encoder) and a class table become objects.
//!
//! * a map of one class gives products byte-identical to the same plot written by hand;
//! * the leaf area of each turbid class equals the class's area inside the scene (edge pixels
//!   clipped, not dropped; 3 m pixels over 2 m cells, so cells are shared by classes) × its LAI
//!   to 1e-9 relative (the objects; the grid's f32 densities to 1e-7);
//! * the example scene `assets/scenes/landcover.ron` runs and writes its GeoTIFF products.

#[path = "common/geo.rs"]
mod geo;
use geo::{Dem, Sample, dem_tiff};
use std::path::{Path, PathBuf};
use std::process::Command;
use tiff::encoder::Compression;

fn scene(objects: &str) -> String {
    format!(
        r#"(
    version: 1,
    georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0)),
    grid: (size_m: (20.0, 20.0), cell_m: (2.0, 2.0, 1.0), boundary: Isolated),
    bands: [(name: "red", wavelength_nm: 670.0), (name: "nir", wavelength_nm: 865.0)],
    optics: {{
        "leaf": BiLambertian(reflectance: [0.05, 0.45], transmittance: [0.02, 0.4]),
        "grass": Turbid(leaf: "leaf", lad: Spherical),
        "crop": Turbid(leaf: "leaf", lad: Planophile),
        "soil": Lambertian(reflectance: [0.1, 0.25]),
        "water": Lambertian(reflectance: [0.02, 0.01]),
        "wall": Lambertian(reflectance: [0.3, 0.35]),
    }},
    illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 20.0),
    directions: (count: 40, exact: [(zenith_deg: 0.0, azimuth_deg: 0.0)]),
    radiative: (preset: Preview),
    objects: [
        Ground((optics: "soil")),
        {objects}
    ],
)
"#
    )
}

/// Writes `text` (and `files`) into a fresh folder and runs `cmd` (`run` or `maket`) on it;
/// returns the output folder.
fn run(name: &str, cmd: &str, text: &str, files: &[(&str, &[u8])]) -> PathBuf {
    geo::run_scene("landcover", name, cmd, text, files)
}

/// A class map of `pixel_m` pixels from (E, N) = `tie` (top-left), `f(c, r)` the class code.
fn class_map(
    nx: usize,
    ny: usize,
    pixel_m: f64,
    tie: (f64, f64),
    f: impl Fn(usize, usize) -> f64,
) -> Dem {
    Dem {
        nx,
        ny,
        values: (0..nx * ny).map(|k| f(k % nx, k / nx)).collect(),
        tie,
        pixel_m,
        epsg: Some(32631),
        nodata: None,
        raster_type: 1,
    }
}

const PLOT: &str = r#"TurbidPlot((footprint: Box((0.0, 0.0, 20.0, 20.0)), bottom_m: 0.0, top_m: 1.0, foliage: Lai(2.0), optics: "grass")),"#;
const LAND_COVER: &str = r#"LandCover((path: "lc.tif", classes: {
            1: TurbidPlot(top_m: 1.0, foliage: Lai(2.0), optics: "grass"),
            2: TurbidPlot(bottom_m: 0.5, top_m: 2.0, foliage: Lai(3.5), optics: "crop"),
            3: Water(optics: "water"),
            4: Building(wall_height_m: 4.0, wall_optics: "wall", roof_optics: "wall"),
            0: Nothing,
        })),"#;

fn products(out: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    for d in ["", "images", "budget"] {
        for e in std::fs::read_dir(out.join(d)).unwrap() {
            let p = e.unwrap().path();
            let n = p.file_name().unwrap().to_string_lossy().into_owned();
            if p.is_file() && n != "summary.json" && n != "maket.json" {
                v.push((format!("{d}/{n}"), std::fs::read(&p).unwrap()));
            }
        }
    }
    v.sort();
    v
}

#[test]
fn a_map_of_one_class_gives_the_products_of_the_hand_written_plot() {
    // 5 m pixels from 5 m west and north of the scene: the scene's edges cut pixels.
    let map = class_map(6, 6, 5.0, (499_995.0, 4_800_025.0), |_, _| 1.0);
    let tif = dem_tiff(&map, Sample::U16, Compression::Lzw);
    let by_hand = run("one_class_hand", "run", &scene(PLOT), &[]);
    let mapped = run(
        "one_class_map",
        "run",
        &scene(LAND_COVER),
        &[("lc.tif", &tif)],
    );
    let (a, b) = (products(&by_hand), products(&mapped));
    assert_eq!(
        a.iter().map(|x| &x.0).collect::<Vec<_>>(),
        b.iter().map(|x| &x.0).collect::<Vec<_>>()
    );
    assert!(a.len() >= 10);
    for ((n, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "{n} differs from the hand-written scene's");
    }
}

#[test]
fn leaf_area_per_class_is_its_clipped_area_times_its_lai() {
    // 3 m pixels from (499998.5, 4800021.5): 9 × 9 pixels cover the 20 m scene with partial
    // pixels on every side; classes in stripes and blocks, with water, a building and bare
    // pixels.
    let (tie, px, n) = ((499_998.5, 4_800_021.5), 3.0, 9);
    let code = |c: usize, r: usize| -> f64 {
        match (c, r) {
            (6, 6) => 3.0,
            (5, 2) => 4.0,
            (c, r) if c < 3 && r < 4 => 1.0,
            (c, _) if c % 3 == 1 => 2.0,
            (c, r) if (c + r) % 4 == 0 => 0.0,
            _ => 1.0,
        }
    };
    let map = class_map(n, n, px, tie, code);
    let tif = dem_tiff(&map, Sample::U16, Compression::Uncompressed);
    let out = run("classes", "maket", &scene(LAND_COVER), &[("lc.tif", &tif)]);
    // Class area inside the scene [0, 20]², edge pixels clipped.
    let mut area = [0.0f64; 5];
    for r in 0..n {
        for c in 0..n {
            let x0 = (tie.0 + c as f64 * px - 500_000.0).clamp(0.0, 20.0);
            let x1 = (tie.0 + (c + 1) as f64 * px - 500_000.0).clamp(0.0, 20.0);
            let y1 = (tie.1 - r as f64 * px - 4_800_000.0).clamp(0.0, 20.0);
            let y0 = (tie.1 - (r + 1) as f64 * px - 4_800_000.0).clamp(0.0, 20.0);
            area[code(c, r) as usize] += (x1 - x0) * (y1 - y0);
        }
    }
    assert!((area.iter().sum::<f64>() - 400.0).abs() < 1e-9);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("maket.json")).unwrap()).unwrap();
    for (material, class, lai) in [("grass", 1, 2.0), ("crop", 2, 3.5)] {
        let want = area[class] * lai;
        // The objects' leaf area to 1e-9; the grid's to 1e-7 (cell densities are stored as f32,
        // relative rounding 6e-8: docs/architecture.md, Maket).
        for (key, tol) in [("analytic_m2", 1e-9), ("rasterised_m2", 1e-7)] {
            let got = report["leaf_area"][material][key].as_f64().unwrap();
            assert!(
                ((got - want) / want).abs() < tol,
                "{material} {key}: {got} m² against {want} m² (class area {} m² × LAI {lai})",
                area[class]
            );
        }
    }
    // Water and the building become facets of their own optics.
    let facets = &report["facet_area_m2"];
    assert!(
        (facets["water"].as_f64().unwrap() - area[3]).abs() < 1e-9,
        "{facets}"
    );
    assert!(facets["wall"].as_f64().unwrap() > area[4], "{facets}");
}

/// The stand classes' tree counts (10 m² of leaves per tree, materials `grass` at 3000 and
/// `crop` at 1250 trees per hectare) equal density × `area_ha`, to within one tree.
fn assert_stand_counts(report: &serde_json::Value, area_ha: f64) {
    for (material, density) in [("grass", 3000.0), ("crop", 1250.0)] {
        let trees = report["leaf_area"][material]["analytic_m2"]
            .as_f64()
            .unwrap()
            / 10.0;
        let want = density * area_ha;
        assert!(
            (trees - want).abs() <= 1.0 && (trees - trees.round()).abs() < 1e-9,
            "{material}: {trees} trees for {want}"
        );
    }
}

/// A tree-stand class gets its density × its area in trees (to within one per species), from a
/// seeded placement: the same map gives the same trees, another seed other positions.
#[test]
fn a_tree_stand_class_gets_its_density_times_its_area() {
    // 4 m pixels from (499998, 4800022): class 5 in a 3 × 2 block of the interior and a single
    // pixel, trees of 10 m² leaf area each (two species, 3000 and 1250 per hectare).
    let code = |c: usize, r: usize| match (c, r) {
        (1..=3, 2..=3) | (4, 1) => 5.0,
        _ => 1.0,
    };
    let map = class_map(6, 6, 4.0, (499_998.0, 4_800_022.0), code);
    let tif = dem_tiff(&map, Sample::U16, Compression::Uncompressed);
    let stand = r#"LandCover((path: "lc.tif", classes: {
            1: Nothing,
            5: TreeStand(species: [
                (name: "a", crown: (shape: Ellipsoid, base_height_m: 2.0, height_m: 2.0, radius_x_m: 0.8, foliage: LeafArea(10.0), optics: "grass")),
                (name: "b", crown: (shape: Cone, base_height_m: 1.0, height_m: 3.0, radius_x_m: 0.6, foliage: LeafArea(10.0), optics: "crop")),
            ], trees_per_ha: [3000.0, 1250.0], min_spacing_m: 0.5),
        })),"#;
    let area_ha = 7.0 * 16.0 / 1e4;
    let text = scene(stand);
    let a = run("stand_a", "maket", &text, &[("lc.tif", &tif)]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.join("maket.json")).unwrap()).unwrap();
    assert_stand_counts(&report, area_ha);
    let b = run("stand_b", "maket", &text, &[("lc.tif", &tif)]);
    let seeded = run(
        "stand_seed",
        "maket",
        &text.replace("version: 1,", "version: 1, seed: 7,"),
        &[("lc.tif", &tif)],
    );
    let density = |o: &Path| std::fs::read(o.join("density.csv")).unwrap();
    assert_eq!(
        density(&a),
        density(&b),
        "the same map gives the same trees"
    );
    assert_ne!(
        density(&a),
        density(&seeded),
        "another seed places them elsewhere"
    );
}

/// In a rotated scene (+x at bearing 60°) each rectangle is the rotated polygon clipped to the
/// scene: the classes still tile the scene, so the leaf area of two classes of one LAI is the
/// scene's area × LAI to 1e-9, and each class gets its share.
#[test]
fn a_rotated_scene_tiles_the_classes_as_polygons() {
    let text = scene(LAND_COVER)
        .replace(
            "origin_map_m: (500000.0, 4800000.0))",
            "origin_map_m: (500000.0, 4800000.0), x_axis_bearing_deg: 60.0)",
        )
        .replace(
            "foliage: Lai(3.5), optics: \"crop\"",
            "foliage: Lai(2.0), optics: \"crop\"",
        );
    // 3 m pixels from (499975, 4800030): the scene's rotated map box inside.
    let map = class_map(16, 12, 3.0, (499_975.0, 4_800_030.0), |c, r| {
        if (c / 2 + r) % 3 == 0 { 2.0 } else { 1.0 }
    });
    let tif = dem_tiff(&map, Sample::U16, Compression::Uncompressed);
    let out = run("rotated_classes", "maket", &text, &[("lc.tif", &tif)]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("maket.json")).unwrap()).unwrap();
    let la = |m: &str| report["leaf_area"][m]["analytic_m2"].as_f64().unwrap();
    let total = la("grass") + la("crop");
    assert!(
        ((total - 800.0) / 800.0).abs() < 1e-9,
        "total leaf area {total} m²"
    );
    assert!(
        la("crop") > 100.0 && la("grass") > 300.0,
        "{} {}",
        la("grass"),
        la("crop")
    );
}

/// Tree-stand classes in a rotated scene (+x at bearing 60°): the trunks are placed inside
/// each class polygon (clipped rotated rectangle), and a class covering the whole scene gets
/// its density × the scene's area in trees (to within one per species).
#[test]
fn a_rotated_scene_gets_its_tree_stands() {
    let stand = r#"LandCover((path: "lc.tif", classes: {
            5: TreeStand(species: [
                (name: "a", crown: (shape: Ellipsoid, base_height_m: 2.0, height_m: 2.0, radius_x_m: 0.8, foliage: LeafArea(10.0), optics: "grass")),
                (name: "b", crown: (shape: Cone, base_height_m: 1.0, height_m: 3.0, radius_x_m: 0.6, foliage: LeafArea(10.0), optics: "crop")),
            ], trees_per_ha: [3000.0, 1250.0], min_spacing_m: 0.5),
        })),"#;
    let text = scene(stand).replace(
        "origin_map_m: (500000.0, 4800000.0))",
        "origin_map_m: (500000.0, 4800000.0), x_axis_bearing_deg: 60.0)",
    );
    assert!(text.contains("x_axis_bearing_deg: 60.0"));
    // 3 m pixels from (499975, 4800030), all of class 5: they cover the rotated scene.
    let map = class_map(16, 12, 3.0, (499_975.0, 4_800_030.0), |_, _| 5.0);
    let tif = dem_tiff(&map, Sample::U16, Compression::Uncompressed);
    let out = run("rotated_stand", "maket", &text, &[("lc.tif", &tif)]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("maket.json")).unwrap()).unwrap();
    let area_ha = 400.0 / 1e4;
    assert_stand_counts(&report, area_ha);
}

/// The example scene runs and writes its georeferenced products.
#[test]
fn the_example_land_cover_scene_runs() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::temp_dir().join(format!("lumenscape-landcover-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("example");
    let _ = std::fs::remove_dir_all(&out);
    let o = Command::new(env!("CARGO_BIN_EXE_lumenscape"))
        .args([
            "run",
            root.join("assets/scenes/landcover.ron").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "lai.tif",
        "dsm.tif",
        "images/view_000.0_000.0.tif",
        "images/view_000.0_000.0.hdr",
    ] {
        assert!(out.join(f).exists(), "{f}");
    }
}
