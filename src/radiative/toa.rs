//! Top-of-atmosphere products of a scene under an atmosphere (summary.json `toa`, one block
//! per band; docs/guide/products.md): TOA albedo and reflectance factor per view direction,
//! TOA radiance, the atmosphere's absorption per layer, the bottom-of-atmosphere irradiance and
//! the energy balance of atmosphere and scene together.

use serde::Serialize;

/// TOA reflectance factor toward one view direction.
#[derive(Debug, Clone, Serialize)]
pub struct ToaBrf {
    /// View zenith angle, degrees.
    pub zenith_deg: f64,
    /// View azimuth, degrees (the scene's convention, as `brf`).
    pub azimuth_deg: f64,
    /// TOA reflectance factor `π L_TOA / E⊥_TOA` (E⊥_TOA: the scene's irradiance on a
    /// horizontal plane at the TOA).
    pub brf: f64,
    /// Standard error of `brf` (Monte Carlo).
    pub brf_se: f64,
    /// TOA radiance `brf · E⊥_TOA / π`, W m⁻² sr⁻¹ µm⁻¹ (relative when the scene's irradiance
    /// is the default 1).
    pub radiance_w_m2_sr_um: f64,
    /// Diffuse sky at the bottom of the atmosphere seen looking toward this direction (the
    /// downward radiance travelling along the opposite direction, direct sun excluded, with the
    /// scene–atmosphere multiple reflections), as a factor `π L↓_BOA / E⊥_TOA`.
    pub boa_sky: f64,
    /// Standard error of `boa_sky`.
    pub boa_sky_se: f64,
}

/// TOA products of one band; fractions are of the power entering through the TOA.
#[derive(Debug, Clone, Serialize)]
pub struct ToaBand {
    /// Band name.
    pub band: String,
    /// Power leaving through the TOA (planetary albedo of the scene and its atmosphere).
    pub albedo: f64,
    /// Standard error of `albedo`.
    pub albedo_se: f64,
    /// Absorbed in the atmosphere (all layers).
    pub fabs_atmosphere: f64,
    /// Absorbed in each layer, lowest first.
    pub fabs_layers: Vec<f64>,
    /// Absorbed in the scene (vegetation, facets and ground).
    pub fabs_scene: f64,
    /// Lost (order cap; scene losses included).
    pub flost: f64,
    /// |1 − (TOA escape + absorbed + lost + roulette balance)/input|.
    pub energy_closure: f64,
    /// Downward irradiance on the scene top (BOA) per horizontal m², direct + diffuse, with
    /// the scene–atmosphere multiple reflections: W m⁻² µm⁻¹ (relative to the TOA irradiance
    /// unit).
    pub boa_irradiance_w_m2_um: f64,
    /// Unscattered (direct sun) part of `boa_irradiance_w_m2_um`.
    pub boa_direct_irradiance_w_m2_um: f64,
    /// Column optical depth between BOA and TOA.
    pub optical_depth: f64,
    /// TOA reflectance factors per view direction (the scene's exact upward directions).
    pub brf: Vec<ToaBrf>,
}
