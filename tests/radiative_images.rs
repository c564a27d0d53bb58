//! Orthographic images of the Radiative stage with spatial oversampling η and footprint
//! spreading ("étalement"; DART 5 paper §3.2; physics.md §6.6, §8.1): every image holds its
//! direction's exitance, a flat Lambertian ground images as BRF = ρ in every pixel at any η,
//! a sharp reflectance edge lands where it truly is (nadir and oblique views, η = 4), and the
//! EXR files carry the pixel size (Δx/η, Δy/η).

mod common;
use common::*;
use glam::DVec3;
use lumenscape::direction::{
    DirectionKind, DirectionParams, DirectionSet, ExactDirection, direction_from_deg,
};
use lumenscape::phase::lambertian_facet_fractions;
use lumenscape::radiative::engine::{
    RadiativeInput, RadiativeResult, TrackOptics, TrackingParams, remap_wrong_side, run,
};
use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::facets::{Facet, FacetKind};
use lumenscape::resources::grid::{CellGrid, GridSpec, compress};
use lumenscape::resources::scene::RunSettings;
use lumenscape::resources::tracking::Directions;
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::*;
use lumenscape::simulation::Simulation;
use std::f64::consts::PI;

/// Runs a scene (writing products to `out` if given); returns the products and directions.
fn run_scene(
    desc: &SceneDesc,
    preset: Option<Preset>,
    out: Option<&std::path::Path>,
) -> (RadiativeProducts, DirectionSet) {
    let settings = RunSettings {
        preset,
        ..Default::default()
    };
    let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), settings)
        .unwrap_or_else(|e| panic!("{e}"));
    sim.run(out).unwrap_or_else(|e| panic!("{e}"));
    (
        sim.resource::<RadiativeProducts>().clone(),
        sim.resource::<Directions>().set.clone(),
    )
}

fn with_eta(desc: &SceneDesc, eta: u32) -> SceneDesc {
    let mut d = desc.clone();
    d.radiative = Some(RadiativeDesc {
        image_oversampling: eta,
        ..Default::default()
    });
    d
}

/// Tiling index of each image (images are the exact upward directions, in tiling order).
fn image_directions(set: &DirectionSet) -> Vec<usize> {
    set.tiling()
        .iter()
        .enumerate()
        .filter(|(_, d)| matches!(d.kind, DirectionKind::Exact { .. }) && d.omega.z > 0.0)
        .map(|(j, _)| j)
        .collect()
}

/// Power of channel `ch` in every pixel of image `k`, W.
fn image_power(r: &RadiativeResult, k: usize, ch: usize) -> Vec<f64> {
    let (w, npx) = (r.n_channels, r.image_grid.pixels());
    (0..npx).map(|p| r.images[(k * npx + p) * w + ch]).collect()
}

/// BRF of every pixel of image `k`, band channel `ch` (sun channel: the BRF; sky channel
/// added: the HDRF), from the definition π W / (A_pixel ∫_{ΔΩ}|μ|dΩ E) (physics.md §8.1).
fn pixel_reflectance(r: &RadiativeResult, k: usize, projected_sr: f64, sky: bool) -> Vec<f64> {
    let g = r.image_grid;
    let a_px = g.pixel_m.0 * g.pixel_m.1;
    let area = a_px * g.pixels() as f64;
    let nb = r.n_bands;
    let sun = image_power(r, k, 0);
    if !sky {
        let e = r.source[0] / area;
        return sun
            .iter()
            .map(|w| PI * w / (a_px * projected_sr * e))
            .collect();
    }
    let e = (r.source[0] + r.source[nb]) / area;
    let skyp = image_power(r, k, nb);
    sun.iter()
        .zip(&skyp)
        .map(|(a, b)| PI * (a + b) / (a_px * projected_sr * e))
        .collect()
}

/// (a) Each image holds exactly its direction's exitance for η = 1, 2, 3 (turbid crowns, trunk
/// facets and the ground all spread their footprints, wrapped around the repetitive scene),
/// and the exitance itself does not depend on η (bit-identical).
#[test]
fn every_image_sums_to_its_direction_exitance_for_any_eta() {
    let mut d = small_forest();
    d.directions = Some(DirectionParams {
        exact: vec![
            ExactDirection::new(0.0, 0.0),
            ExactDirection::new(30.0, 225.0),
            ExactDirection::new(55.0, 100.0),
        ],
        ..Default::default()
    });
    let mut escaped_eta1: Option<Vec<u64>> = None;
    let mut worst: f64 = 0.0;
    for eta in [1, 2, 3] {
        let (p, set) = run_scene(&with_eta(&d, eta), Some(Preset::Preview), None);
        let r = &p.raw;
        assert_eq!(r.image_grid.oversampling, eta);
        assert_eq!(r.image_grid.n, (12 * eta as usize, 12 * eta as usize));
        let dirs = image_directions(&set);
        assert_eq!(dirs.len(), 3);
        for (k, &j) in dirs.iter().enumerate() {
            for ch in 0..r.n_channels {
                let sum: f64 = image_power(r, k, ch).iter().sum();
                let want = r.escaped[j * r.n_channels + ch];
                assert!(want > 0.0);
                let err = (sum / want - 1.0).abs();
                worst = worst.max(err);
                assert!(
                    err <= 1e-9,
                    "η {eta}, image {k}, channel {ch}: Σ pixels {sum} vs exitance {want}"
                );
            }
        }
        let bits: Vec<u64> = r.escaped.iter().map(|v| v.to_bits()).collect();
        match &escaped_eta1 {
            None => escaped_eta1 = Some(bits),
            Some(b) => assert_eq!(b, &bits, "η {eta} changed the exitance"),
        }
    }
    println!("image sums vs exitance: worst relative difference {worst:.2e} (limit 1e-9)");
}

/// (b) Flat Lambertian ground (ρ = 0.1), any sun, with and without sky: every pixel of every
/// view image has BRF (and HDRF) = ρ for η = 1, 2, 3. The ground scatters from D² sub-column
/// points (D = 2 here); spreading each over its (Δx/D)² footprint tiles the plane exactly,
/// whereas the bare points would leave η = 3 pixels with 0 or 2 points' worth.
#[test]
fn flat_lambertian_ground_images_are_rho_in_every_pixel_for_any_eta() {
    let mut worst: f64 = 0.0;
    for (sza, skyl) in [(0.0, 0.0), (30.0, 0.3), (85.0, 0.0)] {
        for eta in [1, 2, 3] {
            let mut d = base_scene((4.0, 4.0), (1.0, 1.0, 1.0), BoundaryMode::Repetitive);
            d.objects.push(flat_ground());
            d.illumination.sun_zenith_deg = Some(sza);
            d.illumination.skyl = vec![skyl];
            d.directions = Some(DirectionParams {
                exact: vec![
                    ExactDirection::new(0.0, 0.0),
                    ExactDirection::new(20.0, 60.0),
                    ExactDirection::new(50.0, 200.0),
                ],
                ..Default::default()
            });
            let (p, set) = run_scene(&with_eta(&d, eta), None, None);
            let r = &p.raw;
            assert_eq!(r.image_grid.pixels(), 16 * (eta * eta) as usize);
            for (k, &j) in image_directions(&set).iter().enumerate() {
                let psr = set.tiling()[j].projected_sr;
                for sky in [false, true].into_iter().filter(|&s| !s || skyl > 0.0) {
                    for (px, v) in pixel_reflectance(r, k, psr, sky).iter().enumerate() {
                        worst = worst.max((v - 0.1).abs());
                        assert!(
                            (v - 0.1).abs() < 1e-6,
                            "sza {sza} SKYL {skyl} η {eta} image {k} pixel {px} (sky {sky}): {v}"
                        );
                    }
                }
            }
        }
    }
    println!("flat ground images: worst |BRF − ρ| {worst:.2e} (limit 1e-6)");
}

/// A 4 × 2 × 2 m repetitive scene, 1 m cells, D sub-cells: a black flat ground half covered
/// (x ∈ [0, 2] m, all y) by a white horizontal opaque plate (ρ = 0.6) at z = 1.5 m made of
/// squares of the sub-cell size 1/D m (two triangles each); near-nadir sun, launch grid of
/// 1/16 m. Views: nadir and (40°, 30°). Returns the result, the direction set and the image
/// directions.
fn plate_scene(eta: u32, subcells: u32) -> (RadiativeResult, DirectionSet, Vec<usize>) {
    let spec = GridSpec {
        n: [4, 2, 2],
        cell: DVec3::ONE,
        origin: DVec3::ZERO,
        subcells,
        boundary: BoundaryMode::Repetitive,
        topography_offset: (0.0, 0.0),
    };
    let (zp, s) = (1.5, 1.0 / subcells as f64);
    let mut facets = Vec::new();
    for a in 0..2 * subcells {
        for b in 0..2 * subcells {
            let (x, y) = (a as f64 * s, b as f64 * s);
            let p = |u: f64, v: f64| DVec3::new(x + u, y + v, zp);
            // Counter-clockwise seen from above: normal +z.
            for v in [
                [p(0.0, 0.0), p(s, 0.0), p(s, s)],
                [p(0.0, 0.0), p(s, s), p(0.0, s)],
            ] {
                facets.push(Facet {
                    v,
                    material: 0,
                    object: 0,
                    kind: FacetKind::Roof,
                    two_sided: false,
                });
            }
        }
    }
    let mut pairs: Vec<(u32, u32)> = facets
        .iter()
        .enumerate()
        .map(|(f, fa)| {
            let c = (fa.v[0] + fa.v[1] + fa.v[2]) / 3.0;
            (spec.index(c.x as usize, c.y as usize, 1) as u32, f as u32)
        })
        .collect();
    pairs.sort();
    let (facet_start, facet_ids) = compress(spec.n_cells(), &pairs);
    let grid = CellGrid {
        turbid_start: vec![0; spec.n_cells() + 1],
        turbid: vec![],
        facet_start,
        facet_ids,
    };
    let dirs = DirectionSet::new(&DirectionParams {
        exact: vec![
            ExactDirection::new(0.0, 0.0),
            ExactDirection::new(40.0, 30.0),
        ],
        ..Default::default()
    })
    .unwrap();
    let tiling = dirs.tiling();
    let n_dirs = tiling.len();
    let omega: Vec<DVec3> = tiling.iter().map(|d| d.omega).collect();
    let regular: Vec<bool> = tiling
        .iter()
        .map(|d| d.kind == DirectionKind::Regular)
        .collect();
    let fr = lambertian_facet_fractions(&dirs, DVec3::Z);
    let mut front: Vec<f32> = fr.front[..n_dirs].iter().map(|&x| x as f32).collect();
    let mut back: Vec<f32> = fr.back[..n_dirs].iter().map(|&x| x as f32).collect();
    remap_wrong_side(&mut front, DVec3::Z, &omega, &regular);
    remap_wrong_side(&mut back, -DVec3::Z, &omega, &regular);
    let fractions = vec![(front, back); facets.len()];
    let images = image_directions(&dirs);
    let mut image_of = vec![u32::MAX; n_dirs];
    for (k, &j) in images.iter().enumerate() {
        image_of[j] = k as u32;
    }
    let sector_of: Vec<u16> = (0..n_dirs as u16).collect();
    let optics = [TrackOptics::Lambert {
        r: vec![0.6],
        t: vec![0.0],
        t_dir: vec![0.0],
    }];
    // Sun hits shifted by a third of the launch spacing along x (0.5 m below the top), so no
    // launch ray meets a triangle edge exactly.
    let launch: f64 = 1.0 / 16.0;
    let sun_zenith = (launch / 3.0 / 0.5).atan().to_degrees();
    let input = RadiativeInput {
        spec: &spec,
        grid: &grid,
        facets: &facets,
        facet_fractions: &fractions,
        facet_brdf: &[],
        facet_tables: &[],
        dirs: &dirs,
        sector_of: &sector_of,
        n_sectors: n_dirs,
        optics: &optics,
        image_of: &image_of,
        image_oversampling: eta,
        flat_ground: Some(vec![0.0]),
        ground_brdf: None,
        sun: -direction_from_deg(sun_zenith, 0.0),
        e_dir: vec![1.0],
        e_diff: vec![0.0],
        params: TrackingParams {
            launch_spacing_m: Some(launch),
            ..TrackingParams::dart_default()
        },
        emitters: &[],
        thermal: None,
    };
    let r = run(&input);
    assert_eq!(r.launch.subcells, subcells);
    (r, dirs, images)
}

/// (c) Sharp edge at η = 4 (0.25 m pixels), with scattering points on sub-cells of 0.25 m
/// (D = 4) and of 0.5 m (D = 2: two triangle points per sub-cell, which bare points would put
/// in two of its four pixels, BRF 0 and 2ρ): in the nadir image and in the (40°, 30°) image
/// (the plate at 1.5 m projects 1.5·tan 40°·cos 30° = 1.090 m towards −x onto z0), both plate
/// edges lie within one fine pixel of their true position in every row (where the profile
/// crosses ρ/2), and every pixel not within one pixel of an edge has its exact BRF (ρ = 0.6 on
/// the plate, 0 on the black ground) to 1e-6.
#[test]
fn a_sharp_edge_lands_within_one_fine_pixel_at_eta_4() {
    for subcells in [4, 2] {
        sharp_edge(subcells);
    }
}

fn sharp_edge(subcells: u32) {
    let (r, dirs, images) = plate_scene(4, subcells);
    let g = r.image_grid;
    assert_eq!(g.n, (16, 8));
    let px = g.pixel_m.0;
    assert!((px - 0.25).abs() < 1e-15);
    let rho = 0.6;
    let scene_x = 4.0;
    // Periodic distance on x.
    let pdist = |a: f64, b: f64| {
        let d = (a - b).rem_euclid(scene_x);
        d.min(scene_x - d)
    };
    for (k, &j) in images.iter().enumerate() {
        let d = &dirs.tiling()[j];
        let shift = 1.5 * d.omega.x / d.omega.z;
        let edges = [
            (0.0 - shift).rem_euclid(scene_x),
            (2.0 - shift).rem_euclid(scene_x),
        ];
        let on_plate = |x: f64| (x + shift).rem_euclid(scene_x) < 2.0;
        let brf = pixel_reflectance(&r, k, d.projected_sr, false);
        let (mut worst_far, mut worst_edge): (f64, f64) = (0.0, 0.0);
        for row in 0..g.n.1 {
            let prof: Vec<f64> = (0..g.n.0).map(|i| brf[i + g.n.0 * row]).collect();
            for (i, &v) in prof.iter().enumerate() {
                let (lo, hi) = (i as f64 * px, (i + 1) as f64 * px);
                let near = edges.iter().any(|&e| {
                    pdist(lo, e) < px + 1e-9 || pdist(hi, e) < px + 1e-9 || (lo < e && e < hi)
                });
                if near {
                    continue;
                }
                let want = if on_plate(0.5 * (lo + hi)) { rho } else { 0.0 };
                worst_far = worst_far.max((v - want).abs());
                assert!(
                    (v - want).abs() < 1e-6,
                    "view {k} row {row} pixel {i}: BRF {v} vs {want}"
                );
            }
            // Edges: where the periodic profile through pixel centres crosses ρ/2.
            let n = prof.len();
            let mut crossings = Vec::new();
            for i in 0..n {
                let (a, b) = (prof[i] - 0.5 * rho, prof[(i + 1) % n] - 0.5 * rho);
                if (a >= 0.0) != (b >= 0.0) {
                    let t = a / (a - b);
                    crossings.push(((i as f64 + 0.5 + t) * px).rem_euclid(scene_x));
                }
            }
            assert_eq!(crossings.len(), 2, "view {k} row {row}: {prof:?}");
            for e in edges {
                let err = crossings
                    .iter()
                    .map(|&c| pdist(c, e))
                    .fold(f64::INFINITY, f64::min);
                worst_edge = worst_edge.max(err);
                assert!(
                    err <= px,
                    "view {k} row {row}: edge {e:.4} m found {crossings:?} (pixel {px} m)"
                );
            }
        }
        println!(
            "D {subcells}, view ({:.0}°, {:.0}°): true edges {:.4} and {:.4} m; worst edge offset {:.4} m \
             (limit {px} m); worst |BRF − exact| away from edges {worst_far:.2e}",
            d.zenith_deg(),
            d.azimuth_deg(),
            edges[0],
            edges[1],
            worst_edge
        );
    }
}

/// The EXR images have η·n_x × η·n_y pixels, carry the pixel size (Δx/η, Δy/η) and η in
/// their header, and (flat Lambertian ground) read back as BRF = ρ; `summary.json` records
/// the image grid.
#[test]
fn exr_images_carry_the_oversampled_pixel_size() {
    let mut d = base_scene((4.0, 3.0), (1.0, 0.5, 1.0), BoundaryMode::Repetitive);
    d.objects.push(flat_ground());
    d.directions = Some(DirectionParams {
        exact: vec![
            ExactDirection::new(0.0, 0.0),
            ExactDirection::new(35.0, 120.0),
        ],
        ..Default::default()
    });
    let d = with_eta(&d, 3);
    let out = std::env::temp_dir().join(format!("lumenscape-img-eta-{}", std::process::id()));
    let _ = run_scene(&d, None, Some(&out));
    let mut n = 0;
    for e in std::fs::read_dir(out.join("images")).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_none_or(|x| x != "exr") {
            continue;
        }
        let (nx, ny, ch) = lumenscape::io::exr_out::read_exr_channels(&path).unwrap();
        assert_eq!((nx, ny), (12, 18));
        let brf = &ch
            .iter()
            .find(|(k, _)| k.ends_with("brf.00_red"))
            .unwrap()
            .1;
        for v in brf {
            assert!((*v as f64 - 0.1).abs() < 1e-6, "{}: {v}", path.display());
        }
        let meta = lumenscape::io::exr_out::read_exr_values(&path).unwrap();
        let get = |k: &str| meta.iter().find(|m| m.0 == k).map(|m| m.1).unwrap();
        assert!((get("pixel_size_x_m") - 1.0 / 3.0).abs() < 1e-15);
        assert!((get("pixel_size_y_m") - 0.5 / 3.0).abs() < 1e-15);
        assert!((get("pixelAspectRatio") - 0.5).abs() < 1e-7);
        assert_eq!(get("image_oversampling"), 3.0);
        let png = path.with_extension("png");
        let bytes = std::fs::read(&png).unwrap();
        // PNG IHDR: width and height, big-endian, at bytes 16..24.
        let dim = |o: usize| u32::from_be_bytes(bytes[o..o + 4].try_into().unwrap());
        assert_eq!((dim(16), dim(20)), (12, 18));
        n += 1;
    }
    assert_eq!(n, 2);
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["images"]["oversampling"], 3);
    assert_eq!(summary["images"]["n"], serde_json::json!([12, 18]));
    assert_eq!(summary["settings"]["image_oversampling"], 3);
    let _ = std::fs::remove_dir_all(out);
}
