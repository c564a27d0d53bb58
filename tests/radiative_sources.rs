//! The Radiative engine's source seam (`RadiativeInput::emitters`): any (point, direction,
//! power) pairs are tracked from iteration 1 like the sun and sky, and counted in the source —
//! the entry point for thermal emission, atmosphere path radiance and lamps.

use glam::DVec3;
use lumenscape::direction::{DirectionSet, direction_from_deg};
use lumenscape::radiative::engine::{
    Emission, RadiativeInput, RadiativeResult, TrackingParams, run,
};
use lumenscape::resources::grid::{CellGrid, GridSpec};
use lumenscape::scene::desc::BoundaryMode;

fn ground_scene(e_dir: f64, emitters: &[Emission]) -> RadiativeResult {
    let spec = GridSpec {
        n: [2, 2, 2],
        cell: DVec3::new(1.0, 1.0, 1.0),
        origin: DVec3::ZERO,
        subcells: 1,
        boundary: BoundaryMode::Repetitive,
        topography_offset: (0.0, 0.0),
    };
    let grid = CellGrid {
        turbid_start: vec![0; 9],
        turbid: vec![],
        facet_start: vec![0; 9],
        facet_ids: vec![],
    };
    let dirs = DirectionSet::with_count(100).unwrap();
    let n_dirs = dirs.tiling().len();
    let sector_of: Vec<u16> = (0..n_dirs as u16).collect();
    let image_of = vec![u32::MAX; n_dirs];
    let input = RadiativeInput {
        spec: &spec,
        grid: &grid,
        facets: &[],
        facet_fractions: &[],
        facet_brdf: &[],
        facet_tables: &[],
        dirs: &dirs,
        sector_of: &sector_of,
        n_sectors: n_dirs,
        optics: &[],
        image_of: &image_of,
        image_oversampling: 1,
        flat_ground: Some(vec![0.4]),
        ground_brdf: None,
        sun: -direction_from_deg(30.0, 0.0),
        e_dir: vec![e_dir],
        e_diff: vec![0.0],
        params: TrackingParams::dart_default(),
        emitters,
        thermal: None,
    };
    run(&input)
}

/// Emitters that reproduce the sun's launch grid (same points, the sun's direction index, the
/// same power) give the sun-driven products to rounding; closure holds.
#[test]
fn emitters_reproduce_the_sun_source() {
    let sun = ground_scene(1.0, &[]);
    let (nx, ny) = sun.launch.sun_n;
    let n_dirs = sun.escaped.len() / sun.n_channels;
    let da = 4.0 / (nx * ny) as f64;
    let mut em = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            em.push(Emission {
                origin: DVec3::new(
                    (i as f64 + 0.5) * 2.0 / nx as f64,
                    (j as f64 + 0.5) * 2.0 / ny as f64,
                    2.0,
                ),
                dir: n_dirs,
                power: vec![da],
                skip_facet: None,
            });
        }
    }
    let e = ground_scene(0.0, &em);
    assert!((e.source[0] - sun.source[0]).abs() < 1e-12);
    for (a, b) in e.escaped.iter().zip(&sun.escaped) {
        assert!((a - b).abs() <= 1e-12 * sun.source[0], "{a} vs {b}");
    }
    let abs_e: f64 = e.absorbed_ground.iter().sum();
    let abs_s: f64 = sun.absorbed_ground.iter().sum();
    assert!((abs_e - abs_s).abs() <= 1e-12 * sun.source[0]);
    let closure = e.source[0] - e.escaped.iter().sum::<f64>() - abs_e - e.lost[0] - e.remaining[0];
    assert!(closure.abs() <= 1e-9 * e.source[0], "closure {closure}");
}

/// A Lambertian thermal-like emission of the ground (exitance M per m², split over the upward
/// directions by ∫|μ|dΩ/π) escapes whole over bare ground, with an isotropic radiance:
/// escaped power per projected solid angle is the same in every direction.
#[test]
fn isotropic_ground_emission_escapes_with_isotropic_radiance() {
    let dirs = DirectionSet::with_count(100).unwrap();
    let tiling = dirs.tiling();
    let m = 3.0; // W m⁻²
    let mut em = Vec::new();
    for c in 0..4 {
        let centre = DVec3::new(0.5 + (c % 2) as f64, 0.5 + (c / 2) as f64, 0.0);
        for (j, d) in tiling.iter().enumerate() {
            if d.omega.z > 0.0 {
                em.push(Emission {
                    origin: centre,
                    dir: j,
                    power: vec![m * 1.0 * d.projected_sr / std::f64::consts::PI],
                    skip_facet: None,
                });
            }
        }
    }
    let r = ground_scene(0.0, &em);
    let total: f64 = em.iter().map(|e| e.power[0]).sum();
    assert!((r.source[0] - total).abs() < 1e-12 * total);
    assert!((r.escaped.iter().sum::<f64>() - total).abs() < 1e-12 * total);
    for (j, d) in tiling.iter().enumerate().filter(|(_, d)| d.omega.z > 0.0) {
        let radiance = r.escaped[j] / (4.0 * d.projected_sr);
        assert!(
            (radiance - m / std::f64::consts::PI).abs() < 1e-12,
            "direction {j}: {radiance}"
        );
    }
}
