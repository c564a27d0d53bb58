//! `turbid-layer`: a horizontally homogeneous turbid canopy over Lambertian soil on a
//! repetitive (infinite) scene — the 1D case of the DISORT oracles.

use super::*;

/// Parameters (defaults: the RAMI red case of `assets/scenes/turbid_layer.ron`).
#[derive(Debug, Clone, PartialEq)]
pub struct TurbidLayerParams {
    /// Leaf area index, m² m⁻².
    pub lai: f64,
    /// Leaf angle distribution.
    pub lad: LadDesc,
    /// Bands with their optics.
    pub bands: Vec<BandOptics>,
    /// Canopy height, metres.
    pub height_m: f64,
    /// Cell size (horizontal and vertical), metres.
    pub cell_m: f64,
    /// Scene side, metres (a whole number of cells).
    pub size_m: f64,
    /// Sun zenith (ground→sun), degrees.
    pub sun_zenith_deg: f64,
    /// Sun azimuth (ground→sun, anticlockwise from +x), degrees.
    pub sun_azimuth_deg: f64,
}

impl Default for TurbidLayerParams {
    fn default() -> Self {
        Self {
            lai: 3.0,
            lad: LadDesc::Spherical,
            bands: vec![BandOptics::red()],
            height_m: 2.0,
            cell_m: 0.5,
            size_m: 2.0,
            sun_zenith_deg: 20.0,
            sun_azimuth_deg: 0.0,
        }
    }
}

/// Builds the scene.
pub fn turbid_layer(p: &TurbidLayerParams) -> SceneDesc {
    let (bands, optics) = standard_optics(&p.bands, p.lad.clone());
    SceneDesc {
        version: SCENE_FORMAT_VERSION,
        name: format!("turbid layer LAI {}", p.lai),
        seed: 0,
        grid: cube_grid(p.size_m, p.cell_m, BoundaryMode::Repetitive),
        bands,
        optics,
        illumination: sun(p.sun_zenith_deg, p.sun_azimuth_deg),
        objects: vec![
            flat_ground("soil"),
            ObjectDesc::TurbidPlot(TurbidPlotDesc {
                footprint: FootprintDesc::Box((0.0, 0.0, p.size_m, p.size_m)),
                bottom_m: 0.0,
                top_m: p.height_m,
                foliage: FoliageDesc::Lai(p.lai),
                optics: "vegetation".into(),
            }),
        ],
        atmosphere: None,
        sensors: None,
        lidars: None,
        directions: Some(rami_directions(p.sun_azimuth_deg)),
        radiative: None,
        passive: None,
        georeference: None,
        thermal: None,
    }
}
