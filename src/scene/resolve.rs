//! Resolution of the spectral and solar parts of a scene description: each band's spectral
//! response (Gaussian, a band of the shipped sensor library, a tabulated SRF file) and the sun
//! from a date and a place (NREL SPA).
//!
//! Validation calls the file-free parts (sensor and band names, the sun above the horizon) so
//! that `check` reports them with their field and line; the spawn step calls everything (SRF
//! files are read there) and stores the results in `resources::scene::SceneInfo`, so that later
//! stages only see final angles and per-band values.

use super::desc::{BandDesc, SceneDesc, SunPositionDesc};
use super::error::SceneError;
use super::validate::SceneSource;
use crate::physics::spectral::{Sensor, SensorId, SpectralBand, SpectralError, Srf};
use crate::physics::sun::{
    Observer, Refraction, SPA_ATMOS_REFRACT_DEG, SceneAngles, SolarPosition, SunError, UtcDateTime,
    delta_t_estimate_s, solar_position,
};
use std::path::Path;

/// Name of a shipped sensor as written in scenes (the stem of its file in `assets/sensors/`,
/// e.g. `sentinel2a_msi`).
pub fn sensor_scene_name(id: SensorId) -> &'static str {
    id.file_name().trim_end_matches(".csv")
}

/// The shipped sensor called `name`: its scene name (`sentinel2a_msi`, `landsat8_oli`,
/// `modis_terra`) or display name (`Sentinel-2A MSI`); case, spaces, `-` and `_` are ignored.
pub fn sensor_id(name: &str) -> Option<SensorId> {
    let key = |s: &str| -> String {
        s.chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .map(|c| c.to_ascii_lowercase())
            .collect()
    };
    let k = key(name);
    SensorId::ALL
        .into_iter()
        .find(|&id| key(sensor_scene_name(id)) == k || key(id.name()) == k)
}

/// Checks the fields of a band without reading files: one response form only, `fwhm_nm` and
/// `wavelength_nm` consistent with it, known shipped sensor and band names, a non-empty SRF
/// path, a Gaussian that stays at positive wavelengths.
///
/// Errors are `(sub-field, message)`, the sub-field being the `BandDesc` field at fault
/// (`wavelength_nm`, `fwhm_nm`, `sensor_band`, `srf_file`).
pub fn check_band(b: &BandDesc) -> Result<(), (&'static str, String)> {
    if b.sensor_band.is_some() && b.srf_file.is_some() {
        return Err((
            "srf_file",
            "give either `sensor_band` or `srf_file`, not both".to_string(),
        ));
    }
    if b.sensor_band.is_none() && b.srf_file.is_none() {
        if !(b.wavelength_nm.is_finite() && b.wavelength_nm > 0.0) {
            return Err((
                "wavelength_nm",
                format!(
                    "a band needs a `wavelength_nm` > 0 (or a `sensor_band` or `srf_file`), got {}",
                    b.wavelength_nm
                ),
            ));
        }
        return plain_band(b)
            .validate()
            .map_err(|e| ("fwhm_nm", e.to_string()));
    }
    if b.fwhm_nm != 0.0 {
        return Err((
            "fwhm_nm",
            format!(
                "a band with a tabulated response (`sensor_band` or `srf_file`) takes no `fwhm_nm`, got {}",
                b.fwhm_nm
            ),
        ));
    }
    if !(b.wavelength_nm.is_finite() && b.wavelength_nm >= 0.0) {
        return Err((
            "wavelength_nm",
            format!(
                "must be a finite number >= 0 (0 or omitted: the response's centroid), got {}",
                b.wavelength_nm
            ),
        ));
    }
    if let Some(file) = &b.srf_file
        && file.trim().is_empty()
    {
        return Err(("srf_file", "the file path is empty".to_string()));
    }
    if let Some((sensor, band)) = &b.sensor_band {
        shipped_band(sensor, band)?;
    }
    Ok(())
}

/// A monochromatic (`fwhm_nm` 0) or Gaussian band.
fn plain_band(b: &BandDesc) -> SpectralBand {
    if b.fwhm_nm > 0.0 {
        SpectralBand::Gaussian {
            center_nm: b.wavelength_nm,
            fwhm_nm: b.fwhm_nm,
        }
    } else {
        SpectralBand::Monochromatic {
            wavelength_nm: b.wavelength_nm,
        }
    }
}

/// The measured response of band `band` of the shipped sensor `sensor`.
fn shipped_band(sensor: &str, band: &str) -> Result<SpectralBand, (&'static str, String)> {
    let id = sensor_id(sensor).ok_or_else(|| {
        let names: Vec<&str> = SensorId::ALL.into_iter().map(sensor_scene_name).collect();
        (
            "sensor_band",
            format!("unknown sensor `{sensor}` (shipped: {})", names.join(", ")),
        )
    })?;
    let s = Sensor::builtin(id);
    let sb = s.band(band).ok_or_else(|| {
        let bands: Vec<&str> = s.bands.iter().map(|b| b.name.as_str()).collect();
        (
            "sensor_band",
            format!(
                "sensor `{}` has no band `{band}` (bands: {})",
                sensor_scene_name(id),
                bands.join(", ")
            ),
        )
    })?;
    Ok(sb.to_band())
}

/// The spectral response of a band (see [`check_band`] for the errors); `base_dir` is the
/// folder `srf_file` paths are relative to. An unreadable or malformed SRF file is an error on
/// the sub-field `srf_file` naming the file (and its line).
pub fn band_response(
    b: &BandDesc,
    base_dir: &Path,
) -> Result<SpectralBand, (&'static str, String)> {
    check_band(b)?;
    if let Some((sensor, band)) = &b.sensor_band {
        return shipped_band(sensor, band);
    }
    if let Some(file) = &b.srf_file {
        let srf = Srf::load_csv(base_dir.join(file)).map_err(|e| {
            let msg = match e {
                SpectralError::Io { path, source } => {
                    format!("{path}: cannot read file: {source}")
                }
                other => other.to_string(),
            };
            ("srf_file", msg)
        })?;
        return Ok(SpectralBand::Tabulated(srf));
    }
    Ok(plain_band(b))
}

/// The spectral responses of all bands of a scene (reads SRF files); errors name
/// `bands[i].<field>` and its line.
pub fn band_responses(
    desc: &SceneDesc,
    src: &SceneSource,
) -> Result<Vec<SpectralBand>, SceneError> {
    let base_dir = src.base_dir();
    desc.bands
        .iter()
        .enumerate()
        .map(|(i, b)| {
            band_response(b, &base_dir).map_err(|(f, m)| src.invalid(format!("bands[{i}].{f}"), m))
        })
        .collect()
}

/// The bands with `wavelength_nm` filled in: a tabulated band given without it (0) gets its
/// response's centroid ∫ λ S dλ / ∫ S dλ, nm.
pub fn bands_with_wavelengths(bands: &[BandDesc], responses: &[SpectralBand]) -> Vec<BandDesc> {
    bands
        .iter()
        .zip(responses)
        .map(|(b, r)| {
            let mut b = b.clone();
            if b.wavelength_nm == 0.0 {
                b.wavelength_nm = r.centroid_nm().unwrap_or(0.0);
            }
            b
        })
        .collect()
}

fn sun_error(e: SunError) -> (&'static str, String) {
    match &e {
        SunError::InvalidTime { .. } => ("utc", e.to_string()),
        SunError::InvalidInput { field, .. } => (*field, e.to_string()),
    }
}

/// The NREL SPA sun position of a `sun_position` (refraction per its settings) and the sun's
/// viewing angles in the scene convention: zenith = the apparent zenith when `refraction` is on
/// (the geometric one otherwise), azimuth φ = (β − γ) mod 360° anticlockwise from +x.
///
/// Errors are `(sub-field, message)`; a sun at or below the horizon (zenith ≥ 90°) is an error
/// on the sub-field `utc`.
pub fn sun_from_position(
    p: &SunPositionDesc,
    georeference: Option<&crate::scene::desc::GeoreferenceDesc>,
    size: (f64, f64),
) -> Result<(SolarPosition, SceneAngles), (&'static str, String)> {
    let time = UtcDateTime::parse(&p.utc).map_err(sun_error)?;
    // The place and the bearing of +x from the georeference (scene centre), when not given.
    let derived = || -> Result<(f64, f64, f64), (&'static str, String)> {
        let g = georeference.ok_or((
            "latitude_deg",
            "give latitude_deg and longitude_deg (or a scene georeference to take them from)"
                .to_string(),
        ))?;
        let g = crate::scene::georef::Georeference::from_desc(g)
            .map_err(|(_, m)| ("latitude_deg", format!("the georeference is invalid: {m}")))?;
        g.geographic(size.0 / 2.0, size.1 / 2.0).map_err(|m| {
            (
                "latitude_deg",
                format!("{m}; give latitude_deg, longitude_deg and scene_x_bearing_deg"),
            )
        })
    };
    let (latitude_deg, longitude_deg) = match (p.latitude_deg, p.longitude_deg) {
        (Some(la), Some(lo)) => (la, lo),
        (None, None) => {
            let (la, lo, _) = derived()?;
            (la, lo)
        }
        (Some(_), None) | (None, Some(_)) => {
            return Err((
                "latitude_deg",
                "give both latitude_deg and longitude_deg, or neither (georeferenced scene)"
                    .to_string(),
            ));
        }
    };
    let bearing = match p.scene_x_bearing_deg {
        Some(b) => b,
        None if georeference.is_some() => derived()?.2,
        None => crate::physics::sun::DEFAULT_SCENE_X_BEARING_DEG,
    };
    if !bearing.is_finite() {
        return Err((
            "scene_x_bearing_deg",
            format!("must be a finite angle, got {bearing}"),
        ));
    }
    let observer = Observer {
        latitude_deg,
        longitude_deg,
        altitude_m: p.altitude_m,
    };
    let refraction = Refraction {
        pressure_hpa: p.pressure_hpa,
        temperature_c: p.temperature_c,
        atmos_refract_deg: SPA_ATMOS_REFRACT_DEG,
    };
    let delta_t_s = p
        .delta_t_s
        .unwrap_or_else(|| delta_t_estimate_s(time.year, time.month));
    let pos = solar_position(
        &time,
        &observer,
        delta_t_s,
        p.refraction.then_some(&refraction),
    )
    .map_err(sun_error)?;
    let angles = pos.scene_angles(bearing);
    if angles.zenith_deg.is_nan() || angles.zenith_deg >= 90.0 {
        return Err((
            "utc",
            format!(
                "the sun is below the horizon at {time} UTC, latitude {}°, longitude {}° ({} zenith {:.4}°): choose a daytime date and time",
                latitude_deg,
                longitude_deg,
                if p.refraction {
                    "apparent"
                } else {
                    "geometric"
                },
                angles.zenith_deg
            ),
        ));
    }
    Ok((pos, angles))
}

/// Sun and diffuse sky as the stages see them (resolved from `scene::desc::IlluminationDesc` at
/// spawn): the date-and-place form is already turned into angles, and every list has one value
/// per band.
#[derive(Debug, Clone, PartialEq)]
pub struct Illumination {
    /// Sun zenith angle of the ground→sun direction, degrees, in [0, 90) (the apparent,
    /// refracted zenith when the scene asked for refraction).
    pub sun_zenith_deg: f64,
    /// Sun azimuth of the ground→sun direction, degrees, anticlockwise from +x (DART convention).
    pub sun_azimuth_deg: f64,
    /// Diffuse sky fraction SKYL = E_diff / (E_dir + E_diff) per band (0 when not given).
    pub skyl: Vec<f64>,
    /// Total bottom-of-atmosphere irradiance on a horizontal plane per band, W m⁻² µm⁻¹ (1 when
    /// not given: products are then relative), including the Earth–Sun distance factor
    /// `SceneInfo::irradiance_distance_factor` when one was applied.
    pub irradiance_w_m2_um: Vec<f64>,
}

/// Illumination resolved for the stages, with what the spawn step records beside it.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedIllumination {
    /// Final angles and per-band lists.
    pub illumination: Illumination,
    /// (1 AU / d)² applied to the irradiance, when applied.
    pub irradiance_distance_factor: Option<f64>,
    /// The SPA result, when the sun was given by date and place.
    pub solar_position: Option<SolarPosition>,
}

/// Resolves the scene's illumination (validated): explicit angles are copied; a
/// `sun_position` is turned into angles by SPA and, unless `earth_sun_distance_correction` is
/// false, the irradiance is scaled by (1 AU / d)² (`physics::sun::irradiance_distance_factor`).
/// Missing `skyl` becomes 0 and missing irradiance 1 in every band.
pub fn illumination(
    desc: &SceneDesc,
    src: &SceneSource,
) -> Result<ResolvedIllumination, SceneError> {
    let il = &desc.illumination;
    let nb = desc.bands.len();
    let (zenith, azimuth, factor, pos) = match (
        &il.sun_position,
        il.sun_zenith_deg,
        il.sun_azimuth_deg,
    ) {
        (Some(p), _, _) => {
            let (pos, angles) = sun_from_position(p, desc.georeference.as_ref(), desc.grid.size_m)
                .map_err(|(f, m)| src.invalid(format!("illumination.sun_position.{f}"), m))?;
            let factor = p
                .earth_sun_distance_correction
                .then(|| pos.irradiance_factor());
            (angles.zenith_deg, angles.azimuth_deg, factor, Some(pos))
        }
        (None, Some(z), Some(a)) => (z, a, None, None),
        (None, _, _) => {
            return Err(src.invalid(
                    "illumination",
                    "the sun is missing: give `sun_zenith_deg` and `sun_azimuth_deg`, or `sun_position`",
                ));
        }
    };
    let per_band = |v: &[f64], default: f64| -> Vec<f64> {
        if v.is_empty() {
            vec![default; nb]
        } else {
            v.to_vec()
        }
    };
    let k = factor.unwrap_or(1.0);
    Ok(ResolvedIllumination {
        illumination: Illumination {
            sun_zenith_deg: zenith,
            sun_azimuth_deg: azimuth,
            skyl: per_band(&il.skyl, 0.0),
            irradiance_w_m2_um: per_band(&il.irradiance_w_m2_um, 1.0)
                .into_iter()
                .map(|e| e * k)
                .collect(),
        },
        irradiance_distance_factor: factor,
        solar_position: pos,
    })
}
