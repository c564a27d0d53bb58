//! `forest`: a seeded stand of trees of one or more species (DART trees: facet trunk + turbid
//! crown) on flat ground or on a DEM slope (continuous-topography repetitive scene).

use super::*;
use crate::random::{stream, uniform};

/// A species of the forest generator.
#[derive(Debug, Clone, PartialEq)]
pub struct ForestSpecies {
    /// Template.
    pub species: SpeciesDesc,
    /// Number of trees.
    pub count: usize,
}

/// Parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct ForestParams {
    /// Scene side, metres.
    pub size_m: f64,
    /// Cell size, metres.
    pub cell_m: f64,
    /// Species and counts (default: a broadleaf ellipsoid and a conifer cone).
    pub species: Vec<ForestSpecies>,
    /// Minimum distance between trunks, metres.
    pub min_spacing_m: f64,
    /// Ground slope along +x, degrees (0 = flat ground).
    pub slope_deg: f64,
    /// Random seed.
    pub seed: u64,
    /// Bands.
    pub bands: Vec<BandOptics>,
    /// Sun zenith, degrees.
    pub sun_zenith_deg: f64,
    /// Sun azimuth, degrees.
    pub sun_azimuth_deg: f64,
    /// Randomise crown sizes by ±this fraction (0 = identical trees).
    pub size_jitter: f64,
}

/// A broadleaf species: ellipsoid crown, LAI-defined foliage.
pub fn broadleaf(count: usize) -> ForestSpecies {
    ForestSpecies {
        species: SpeciesDesc {
            name: "broadleaf".into(),
            trunk: Some(TrunkDesc {
                height_m: 4.0,
                diameter_m: 0.3,
                sides: 8,
                optics: "bark".into(),
            }),
            crown: CrownDesc {
                shape: CrownShape::Ellipsoid,
                base_height_m: 3.0,
                height_m: 6.0,
                radius_x_m: 2.5,
                radius_y_m: None,
                top_radius_fraction: None,
                foliage: FoliageDesc::LeafAreaDensity(0.8),
                vertical_profile: vec![],
                radial_profile: vec![],
                optics: "vegetation".into(),
            },
        },
        count,
    }
}

/// A conifer species: cone crown with a vertical profile denser at the bottom.
pub fn conifer(count: usize) -> ForestSpecies {
    ForestSpecies {
        species: SpeciesDesc {
            name: "conifer".into(),
            trunk: Some(TrunkDesc {
                height_m: 9.0,
                diameter_m: 0.25,
                sides: 8,
                optics: "bark".into(),
            }),
            crown: CrownDesc {
                shape: CrownShape::Cone,
                base_height_m: 2.0,
                height_m: 8.0,
                radius_x_m: 1.8,
                radius_y_m: None,
                top_radius_fraction: None,
                foliage: FoliageDesc::LeafAreaDensity(1.2),
                vertical_profile: vec![1.5, 1.2, 1.0, 0.8],
                radial_profile: vec![],
                optics: "needles".into(),
            },
        },
        count,
    }
}

impl Default for ForestParams {
    fn default() -> Self {
        Self {
            size_m: 40.0,
            cell_m: 1.0,
            species: vec![broadleaf(12), conifer(12)],
            min_spacing_m: 3.0,
            slope_deg: 0.0,
            seed: 7,
            bands: vec![BandOptics::red(), BandOptics::nir()],
            sun_zenith_deg: 30.0,
            sun_azimuth_deg: 225.0,
            size_jitter: 0.0,
        }
    }
}

/// Builds the scene. With `size_jitter > 0` each tree gets its own species copy with scaled
/// crown dimensions (seeded); otherwise trees are placed randomly by the spawn step.
pub fn forest(p: &ForestParams) -> SceneDesc {
    let (bands, mut optics) = standard_optics(&p.bands, LadDesc::Spherical);
    optics.insert(
        "needles".into(),
        OpticsDesc::Turbid {
            leaf: "leaf".into(),
            lad: LadDesc::Erectophile,
            leaf_size_m: 0.005,
            specular: None,
        },
    );
    optics.insert(
        "bark".into(),
        OpticsDesc::Lambertian {
            reflectance: p.bands.iter().map(|b| (b.soil_r * 1.2).min(0.9)).collect(),
            diffuse_transmittance: vec![],
            direct_transmittance: vec![],
        },
    );
    let topography = if p.slope_deg == 0.0 {
        TopographyDesc::Flat
    } else {
        let n = (p.size_m / p.cell_m).round() as usize + 1;
        let s = p.slope_deg.to_radians().tan();
        let mut z = Vec::with_capacity(n * n);
        for _j in 0..n {
            for i in 0..n {
                z.push(s * i as f64 * p.cell_m);
            }
        }
        TopographyDesc::Raster(RasterDesc {
            nodes: (n, n),
            spacing_m: (p.cell_m, p.cell_m),
            origin_m: (0.0, 0.0),
            altitude_m: z,
        })
    };
    let species: Vec<SpeciesDesc> = p.species.iter().map(|s| s.species.clone()).collect();
    let counts: Vec<usize> = p.species.iter().map(|s| s.count).collect();
    let stand = if p.size_jitter > 0.0 {
        // Each tree is its own species with a jittered crown; positions drawn here.
        let mut rng = stream(p.seed, 3, 0);
        let mut sp = Vec::new();
        let mut cnt = Vec::new();
        for s in &p.species {
            for _ in 0..s.count {
                let f = 1.0 + p.size_jitter * (2.0 * uniform(&mut rng) - 1.0);
                let mut t = s.species.clone();
                t.crown.radius_x_m *= f;
                t.crown.height_m *= f;
                sp.push(t);
                cnt.push(1);
            }
        }
        TreeStandDesc {
            species: sp,
            placement: PlacementDesc::Random {
                counts: cnt,
                min_spacing_m: p.min_spacing_m,
                region_m: None,
                polygon_m: None,
            },
        }
    } else {
        TreeStandDesc {
            species,
            placement: PlacementDesc::Random {
                counts,
                min_spacing_m: p.min_spacing_m,
                region_m: None,
                polygon_m: None,
            },
        }
    };
    SceneDesc {
        version: SCENE_FORMAT_VERSION,
        name: format!(
            "forest {} trees",
            p.species.iter().map(|s| s.count).sum::<usize>()
        ),
        seed: p.seed,
        grid: cube_grid(
            p.size_m,
            p.cell_m,
            if p.slope_deg == 0.0 {
                BoundaryMode::Repetitive
            } else {
                BoundaryMode::RepetitiveContinuousTopography
            },
        ),
        bands,
        optics,
        illumination: sun(p.sun_zenith_deg, p.sun_azimuth_deg),
        objects: vec![
            ObjectDesc::Ground(GroundDesc {
                optics: "soil".into(),
                topography,
            }),
            ObjectDesc::TreeStand(stand),
        ],
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
