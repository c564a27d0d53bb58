//! Programmatic scene generators. Each returns a [`SceneDesc`], so
//! anything generated can be saved as RON and diffed; the CLI exposes them as
//! `lumenscape generate KIND`.

pub mod disk_canopy;
pub mod forest;
pub mod rami;
pub mod turbid_layer;
pub mod urban;

use super::desc::*;
use std::collections::BTreeMap;

/// Optics of one band for the simple generators: leaf reflectance and transmittance, soil
/// reflectance.
#[derive(Debug, Clone, PartialEq)]
pub struct BandOptics {
    /// Band name.
    pub name: String,
    /// Wavelength, nm.
    pub wavelength_nm: f64,
    /// Leaf reflectance.
    pub leaf_r: f64,
    /// Leaf transmittance.
    pub leaf_t: f64,
    /// Soil (Lambertian) reflectance.
    pub soil_r: f64,
}

impl BandOptics {
    /// The RAMI red band used by the oracles (leaf r 0.0546, t 0.0149, soil 0.127).
    pub fn red() -> Self {
        Self {
            name: "red".into(),
            wavelength_nm: 670.0,
            leaf_r: 0.0546,
            leaf_t: 0.0149,
            soil_r: 0.127,
        }
    }
    /// The RAMI near-infrared band (leaf r 0.4957, t 0.4409, soil 0.159).
    pub fn nir() -> Self {
        Self {
            name: "nir".into(),
            wavelength_nm: 865.0,
            leaf_r: 0.4957,
            leaf_t: 0.4409,
            soil_r: 0.159,
        }
    }

    /// Parses `NAME:leaf_r,leaf_t,soil_r` (wavelength taken from well-known names, else 0 →
    /// error) or `NAME@WAVELENGTH:leaf_r,leaf_t,soil_r`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let (head, vals) = s
            .split_once(':')
            .ok_or_else(|| format!("band `{s}`: expected NAME[@NM]:leaf_r,leaf_t,soil_r"))?;
        let (name, wl) = match head.split_once('@') {
            Some((n, w)) => (
                n.to_string(),
                w.parse::<f64>()
                    .map_err(|_| format!("band `{s}`: bad wavelength `{w}`"))?,
            ),
            None => {
                let wl = match head {
                    "blue" => 490.0,
                    "green" => 560.0,
                    "red" => 670.0,
                    "nir" => 865.0,
                    "swir1" => 1610.0,
                    "swir2" => 2190.0,
                    _ => {
                        return Err(format!(
                            "band `{s}`: unknown band name `{head}`: give its wavelength as NAME@NM"
                        ));
                    }
                };
                (head.to_string(), wl)
            }
        };
        let v: Vec<f64> = vals
            .split(',')
            .map(|x| {
                x.trim()
                    .parse::<f64>()
                    .map_err(|_| format!("band `{s}`: `{x}` is not a number"))
            })
            .collect::<Result<_, _>>()?;
        if v.len() != 3 {
            return Err(format!(
                "band `{s}`: expected three values leaf_r,leaf_t,soil_r"
            ));
        }
        Ok(Self {
            name,
            wavelength_nm: wl,
            leaf_r: v[0],
            leaf_t: v[1],
            soil_r: v[2],
        })
    }
}

/// Bands, a `leaf` (BiLambertian), a `vegetation` (Turbid) and a `soil` (Lambertian) entry.
pub fn standard_optics(
    bands: &[BandOptics],
    lad: LadDesc,
) -> (Vec<BandDesc>, BTreeMap<String, OpticsDesc>) {
    let bd = bands
        .iter()
        .map(|b| BandDesc {
            name: b.name.clone(),
            wavelength_nm: b.wavelength_nm,
            fwhm_nm: 0.0,
            sensor_band: None,
            srf_file: None,
        })
        .collect();
    let mut o = BTreeMap::new();
    o.insert(
        "leaf".to_string(),
        OpticsDesc::BiLambertian {
            reflectance: bands.iter().map(|b| b.leaf_r).collect(),
            transmittance: bands.iter().map(|b| b.leaf_t).collect(),
        },
    );
    o.insert(
        "vegetation".to_string(),
        OpticsDesc::Turbid {
            leaf: "leaf".into(),
            lad,
            leaf_size_m: 0.01,
            specular: None,
        },
    );
    o.insert(
        "soil".to_string(),
        OpticsDesc::Lambertian {
            reflectance: bands.iter().map(|b| b.soil_r).collect(),
            diffuse_transmittance: vec![],
            direct_transmittance: vec![],
        },
    );
    (bd, o)
}

/// DART directions (100, DART default) with the RAMI view directions made exact: principal
/// plane, view zenith 0–75° every 15° on the sun side (view azimuth = sun azimuth) and the
/// opposite side, and the same zeniths in the cross plane (sun azimuth ± 90°)
/// (Pinty et al. 2004, RAMI-2 measurement protocol).
pub fn rami_directions(sun_azimuth_deg: f64) -> crate::direction::DirectionParams {
    use crate::direction::{DirectionParams, ExactDirection};
    let mut exact = vec![ExactDirection {
        zenith_deg: 0.0,
        azimuth_deg: 0.0,
        label: Some("nadir".into()),
        solid_angle_sr: None,
    }];
    for (plane, az) in [("pp+", 0.0), ("pp-", 180.0), ("op+", 90.0), ("op-", 270.0)] {
        for k in 1..=5 {
            let z = 15.0 * k as f64;
            exact.push(ExactDirection {
                zenith_deg: z,
                azimuth_deg: (sun_azimuth_deg + az).rem_euclid(360.0),
                label: Some(format!("{plane}{z}")),
                solid_angle_sr: None,
            });
        }
    }
    DirectionParams {
        exact,
        ..DirectionParams::default()
    }
}

/// Nadir and the principal plane every 15° up to 75° on both sides of the sun (11 exact view
/// directions): the cheapest set for oracle comparisons (each exact direction costs a peel-off
/// trace per Monte Carlo event).
pub fn principal_plane_directions(sun_azimuth_deg: f64) -> crate::direction::DirectionParams {
    use crate::direction::{DirectionParams, ExactDirection};
    let mut exact = vec![ExactDirection::new(0.0, 0.0)];
    for k in 1..=5 {
        let z = 15.0 * k as f64;
        exact.push(ExactDirection::new(z, sun_azimuth_deg));
        exact.push(ExactDirection::new(z, sun_azimuth_deg + 180.0));
    }
    DirectionParams {
        exact,
        ..DirectionParams::default()
    }
}

/// Sun-only illumination.
pub fn sun(zenith_deg: f64, azimuth_deg: f64) -> IlluminationDesc {
    IlluminationDesc {
        sun_zenith_deg: Some(zenith_deg),
        sun_azimuth_deg: Some(azimuth_deg),
        sun_position: None,
        skyl: vec![],
        irradiance_w_m2_um: vec![],
    }
}

/// The generators' grid: square horizontal extent `size_m` (m), cubic cells of `cell_m` (m),
/// height from the objects, 2 × 2 × 2 facet sub-cells.
pub fn cube_grid(size_m: f64, cell_m: f64, boundary: BoundaryMode) -> GridDesc {
    GridDesc {
        size_m: (size_m, size_m),
        cell_m: (cell_m, cell_m, cell_m),
        height_m: None,
        subcells: 2,
        boundary,
    }
}

/// A flat ground of material `optics`.
pub fn flat_ground(optics: &str) -> ObjectDesc {
    ObjectDesc::Ground(GroundDesc {
        optics: optics.into(),
        topography: TopographyDesc::Flat,
    })
}
