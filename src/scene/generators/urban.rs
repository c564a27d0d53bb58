//! `urban`: a block of buildings (flat and gable roofs) separated by streets, with a few street
//! trees, on flat ground; isolated scene.

use super::*;
use crate::random::{stream, uniform};

/// Parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct UrbanParams {
    /// Buildings per side of the block grid.
    pub blocks: usize,
    /// Building footprint side, metres.
    pub building_m: f64,
    /// Street width, metres.
    pub street_m: f64,
    /// Wall height range (min, max), metres.
    pub wall_height_m: (f64, f64),
    /// Cell size, metres.
    pub cell_m: f64,
    /// Random seed (heights, roof types).
    pub seed: u64,
    /// Bands.
    pub bands: Vec<BandOptics>,
    /// Sun zenith, degrees.
    pub sun_zenith_deg: f64,
    /// Sun azimuth, degrees.
    pub sun_azimuth_deg: f64,
}

impl Default for UrbanParams {
    fn default() -> Self {
        Self {
            blocks: 3,
            building_m: 12.0,
            street_m: 8.0,
            wall_height_m: (6.0, 15.0),
            cell_m: 1.0,
            seed: 3,
            bands: vec![BandOptics::red(), BandOptics::nir()],
            sun_zenith_deg: 35.0,
            sun_azimuth_deg: 200.0,
        }
    }
}

/// Builds the scene.
pub fn urban(p: &UrbanParams) -> SceneDesc {
    let pitch = p.building_m + p.street_m;
    let size = p.blocks as f64 * pitch;
    let (bands, mut optics) = standard_optics(&p.bands, LadDesc::Spherical);
    let lam = |r: f64| OpticsDesc::Lambertian {
        reflectance: vec![r; p.bands.len()],
        diffuse_transmittance: vec![],
        direct_transmittance: vec![],
    };
    optics.insert("wall".into(), lam(0.3));
    optics.insert("roof".into(), lam(0.15));
    optics.insert("asphalt".into(), lam(0.08));
    optics.insert("bark".into(), lam(0.2));
    let mut rng = stream(p.seed, 4, 0);
    let mut objects = vec![flat_ground("asphalt")];
    let mut trees = Vec::new();
    for bj in 0..p.blocks {
        for bi in 0..p.blocks {
            let x0 = bi as f64 * pitch + 0.5 * p.street_m;
            let y0 = bj as f64 * pitch + 0.5 * p.street_m;
            let h = p.wall_height_m.0 + (p.wall_height_m.1 - p.wall_height_m.0) * uniform(&mut rng);
            let roof = if uniform(&mut rng) < 0.5 {
                RoofDesc::Flat
            } else {
                RoofDesc::Gable {
                    ridge_height_m: 0.3 * p.building_m,
                }
            };
            objects.push(ObjectDesc::Building(BuildingDesc {
                footprint: FootprintDesc::Box((x0, y0, x0 + p.building_m, y0 + p.building_m * 0.8)),
                wall_height_m: (h * 10.0).round() / 10.0,
                roof,
                wall_optics: "wall".into(),
                roof_optics: "roof".into(),
            }));
            // One street tree at the corner of each block.
            let (tx, ty) = (
                bi as f64 * pitch + 0.5 * p.street_m,
                bj as f64 * pitch + 0.25 * p.street_m,
            );
            trees.push((0usize, tx.max(1.6), ty.max(1.6)));
        }
    }
    objects.push(ObjectDesc::TreeStand(TreeStandDesc {
        species: vec![SpeciesDesc {
            name: "street tree".into(),
            trunk: Some(TrunkDesc {
                height_m: 3.0,
                diameter_m: 0.25,
                sides: 8,
                optics: "bark".into(),
            }),
            crown: CrownDesc {
                shape: CrownShape::Ellipsoid,
                base_height_m: 2.5,
                height_m: 4.0,
                radius_x_m: 1.5,
                radius_y_m: None,
                top_radius_fraction: None,
                foliage: FoliageDesc::Lai(3.0),
                vertical_profile: vec![],
                radial_profile: vec![],
                optics: "vegetation".into(),
            },
        }],
        placement: PlacementDesc::Explicit(trees),
    }));
    SceneDesc {
        version: SCENE_FORMAT_VERSION,
        name: format!("urban block {}x{}", p.blocks, p.blocks),
        seed: p.seed,
        grid: cube_grid(size, p.cell_m, BoundaryMode::Isolated),
        bands,
        optics,
        illumination: sun(p.sun_zenith_deg, p.sun_azimuth_deg),
        objects,
        atmosphere: None,
        sensors: None,
        lidars: None,
        directions: None,
        radiative: None,
        passive: None,
        georeference: None,
        thermal: None,
    }
}
