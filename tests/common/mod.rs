//! Shared fixtures for the integration tests.
#![allow(dead_code)]

use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::*;
use lumenscape::simulation::{Simulation, Stage};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Path of a file under the crate root.
pub fn asset(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// A one-band scene with leaf, turbid, soil and wall optics and no objects.
pub fn base_scene(size: (f64, f64), cell: (f64, f64, f64), boundary: BoundaryMode) -> SceneDesc {
    let mut optics = BTreeMap::new();
    optics.insert(
        "leaf".to_string(),
        OpticsDesc::BiLambertian {
            reflectance: vec![0.05],
            transmittance: vec![0.02],
        },
    );
    optics.insert(
        "veg".to_string(),
        OpticsDesc::Turbid {
            leaf: "leaf".into(),
            lad: LadDesc::Spherical,
            leaf_size_m: 0.01,
            specular: None,
        },
    );
    optics.insert(
        "soil".to_string(),
        OpticsDesc::Lambertian {
            reflectance: vec![0.1],
            diffuse_transmittance: vec![],
            direct_transmittance: vec![],
        },
    );
    SceneDesc {
        version: 1,
        name: "test".into(),
        seed: 5,
        grid: GridDesc {
            size_m: size,
            cell_m: cell,
            height_m: None,
            subcells: 2,
            boundary,
        },
        bands: vec![BandDesc {
            name: "red".into(),
            wavelength_nm: 670.0,
            fwhm_nm: 0.0,
            sensor_band: None,
            srf_file: None,
        }],
        optics,
        illumination: IlluminationDesc {
            sun_zenith_deg: Some(30.0),
            sun_azimuth_deg: Some(0.0),
            sun_position: None,
            skyl: vec![],
            irradiance_w_m2_um: vec![],
        },
        objects: vec![],
        atmosphere: None,
        sensors: None,
        lidars: None,
        directions: None,
        radiative: None,
    }
}

/// Spawns and runs the Maket stage.
pub fn run_maket(desc: &SceneDesc) -> Simulation {
    let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), RunSettings::default())
        .expect("scene spawns");
    sim.run_stage(Stage::Maket).expect("maket runs");
    sim
}

/// A crown description.
pub fn crown(
    shape: CrownShape,
    rx: f64,
    ry: Option<f64>,
    h: f64,
    foliage: FoliageDesc,
) -> CrownDesc {
    CrownDesc {
        shape,
        base_height_m: 1.3,
        height_m: h,
        radius_x_m: rx,
        radius_y_m: ry,
        top_radius_fraction: (shape == CrownShape::Trapezoid).then_some(0.35),
        foliage,
        vertical_profile: vec![],
        radial_profile: vec![],
        optics: "veg".into(),
    }
}

/// A one-band Lambertian facet property.
pub fn lambertian(r: f64) -> OpticsDesc {
    OpticsDesc::Lambertian {
        reflectance: vec![r],
        diffuse_transmittance: vec![],
        direct_transmittance: vec![],
    }
}

/// A flat-roofed building on a box footprint with `wall` optics for walls and roof.
pub fn box_building(b: (f64, f64, f64, f64), wall_height_m: f64) -> ObjectDesc {
    ObjectDesc::Building(BuildingDesc {
        footprint: FootprintDesc::Box(b),
        wall_height_m,
        roof: RoofDesc::Flat,
        wall_optics: "wall".into(),
        roof_optics: "wall".into(),
    })
}

/// Flat ground with the `soil` property.
pub fn flat_ground() -> ObjectDesc {
    ObjectDesc::Ground(GroundDesc {
        optics: "soil".into(),
        topography: TopographyDesc::Flat,
    })
}

/// A 12 m periodic forest of four trees (two broadleaf, two conifers): the small shared scene
/// of the determinism and image tests.
pub fn small_forest() -> SceneDesc {
    use lumenscape::scene::generators::forest::{ForestParams, broadleaf, conifer, forest};
    forest(&ForestParams {
        size_m: 12.0,
        species: vec![broadleaf(2), conifer(2)],
        ..Default::default()
    })
}
