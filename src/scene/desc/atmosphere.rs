//! Authoring types of the atmosphere (`atmosphere` in a scene; DART 5 paper §2, Fig. 1;
//! physics.md §4): a plane-parallel layered atmosphere between the scene top (bottom of the
//! atmosphere, BOA) and the top of the atmosphere (TOA), made of molecules, aerosols and an
//! absorbing gas. Re-exported by [`crate::scene::desc`].

use super::*;
use crate::physics::atmosphere::{AtmosphereModel, Constituent};
use crate::physics::phase::{AIR_DEPOLARIZATION, FluidPhase};

fn default_toa_km() -> f64 {
    100.0
}
fn default_molecule_h_km() -> f64 {
    8.4
}
fn default_aerosol_h_km() -> f64 {
    1.0
}
fn default_pressure() -> f64 {
    1013.25
}
fn default_depolarization() -> f64 {
    AIR_DEPOLARIZATION
}
fn default_reference_nm() -> f64 {
    550.0
}

/// Default interior layer boundaries, km above the ground (those above the scene top and below
/// the TOA are used).
pub const DEFAULT_ATMOSPHERE_LEVELS_KM: [f64; 12] = [
    0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0, 8.0, 12.0, 20.0, 30.0, 50.0,
];

/// The atmosphere over the scene: a plane-parallel stack of horizontally infinite layers from
/// the scene top (BOA) to `toa_altitude_km`, each of constant composition. Its presence makes
/// the given illumination a top-of-atmosphere irradiance; the diffuse sky then comes from the
/// atmosphere (so `illumination.skyl` must be 0 or absent).
///
/// Every constituent's column optical depth is spread over the layers along its exponential
/// profile `σ_e(z) ∝ e^{−z/H}` (physics.md §4.4), renormalised so that the layers between the
/// scene top and the TOA hold exactly the given column.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AtmosphereDesc {
    /// Top-of-atmosphere altitude above the scene's ground level (z = 0), km (default 100);
    /// must lie above the scene top.
    #[serde(default = "default_toa_km")]
    pub toa_altitude_km: f64,
    /// Interior layer boundaries, km above the ground, strictly increasing, between the scene
    /// top and `toa_altitude_km` (default: 0.25, 0.5, 1, 1.5, 2, 3, 5, 8, 12, 20, 30, 50 km,
    /// those inside that range).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layer_altitudes_km: Option<Vec<f64>>,
    /// Air molecules (Rayleigh scattering).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub molecules: Option<MoleculesDesc>,
    /// Aerosols.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aerosols: Option<AerosolsDesc>,
    /// An absorbing gas (no scattering): its absorption optical depth per band (user given; no
    /// spectral database is shipped).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gas: Option<GasDesc>,
}

/// Air molecules: Rayleigh scattering with depolarisation (physics.md §4.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoleculesDesc {
    /// Rayleigh optical depth of the column per band; absent: Bodhaine et al. (1999, eq. 30)
    /// at each band's wavelength, scaled by `pressure_hpa`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau: Option<Vec<f64>>,
    /// Surface pressure for the Bodhaine optical depth, hPa (default 1013.25).
    #[serde(default = "default_pressure")]
    pub pressure_hpa: f64,
    /// Depolarisation ratio ρ_n of the Rayleigh phase function, in [0, 0.5) (default 0.0279,
    /// air); 0 gives the pure `3/4 (1 + cos² Θ)`.
    #[serde(default = "default_depolarization")]
    pub depolarization: f64,
    /// Scale height of the exponential profile, km (default 8.4).
    #[serde(default = "default_molecule_h_km")]
    pub scale_height_km: f64,
}

/// Aerosols: extinction optical depth per band, or at a reference wavelength with an Ångström
/// exponent; single-scattering albedo; phase function.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AerosolsDesc {
    /// Extinction optical depth of the column per band (alternative to `tau_reference`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau: Option<Vec<f64>>,
    /// Extinction optical depth at `reference_wavelength_nm` (alternative to `tau`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau_reference: Option<f64>,
    /// Wavelength of `tau_reference`, nm (default 550).
    #[serde(default = "default_reference_nm")]
    pub reference_wavelength_nm: f64,
    /// Ångström exponent α: `τ(λ) = τ_ref (λ/λ_ref)^{−α}` (default 0: flat).
    #[serde(default)]
    pub angstrom_exponent: f64,
    /// Single-scattering albedo per band, in [0, 1].
    pub ssa: Vec<f64>,
    /// Phase function: `HenyeyGreenstein(g: 0.7)`, `TwoTermHg(a: 0.95, g1: 0.79, g2: 0.4)`
    /// (DART's defaults) or `Isotropic`.
    pub phase: FluidPhase,
    /// Scale height of the exponential profile, km (default 1).
    #[serde(default = "default_aerosol_h_km")]
    pub scale_height_km: f64,
}

/// An absorbing gas: absorption optical depth of the column per band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GasDesc {
    /// Absorption optical depth per band.
    pub tau: Vec<f64>,
    /// Scale height of the exponential profile, km (default 8.4).
    #[serde(default = "default_molecule_h_km")]
    pub scale_height_km: f64,
}

impl AtmosphereDesc {
    /// Layer boundaries in metres above the ground: the BOA `boa_m` (the scene top), the
    /// interior boundaries strictly between it and the TOA, the TOA.
    pub fn levels_m(&self, boa_m: f64) -> Vec<f64> {
        let toa = self.toa_altitude_km * 1000.0;
        let interior: Vec<f64> = match &self.layer_altitudes_km {
            Some(l) => l.clone(),
            None => DEFAULT_ATMOSPHERE_LEVELS_KM.to_vec(),
        };
        let mut v = vec![boa_m];
        v.extend(
            interior
                .iter()
                .map(|k| k * 1000.0)
                .filter(|&z| z > boa_m && z < toa),
        );
        v.push(toa);
        v
    }

    /// The layered model for bands of centre wavelengths `wavelengths_nm` over a scene whose
    /// top lies `boa_m` metres above the ground (validated description).
    pub fn model(&self, wavelengths_nm: &[f64], boa_m: f64) -> AtmosphereModel {
        let nb = wavelengths_nm.len();
        let rayleigh = self.molecules.as_ref().map(|m| Constituent {
            tau: match &m.tau {
                Some(t) => t.clone(),
                None => wavelengths_nm
                    .iter()
                    .map(|l| {
                        crate::physics::atmosphere::rayleigh_optical_depth(
                            l / 1000.0,
                            m.pressure_hpa,
                        )
                    })
                    .collect(),
            },
            scale_height_m: m.scale_height_km * 1000.0,
        });
        let aerosol = self.aerosols.as_ref().map(|a| Constituent {
            tau: match (&a.tau, a.tau_reference) {
                (Some(t), _) => t.clone(),
                (None, Some(t)) => wavelengths_nm
                    .iter()
                    .map(|&l| {
                        crate::physics::atmosphere::angstrom_optical_depth(
                            t,
                            a.reference_wavelength_nm,
                            a.angstrom_exponent,
                            l,
                        )
                    })
                    .collect(),
                (None, None) => vec![0.0; nb],
            },
            scale_height_m: a.scale_height_km * 1000.0,
        });
        let gas = self.gas.as_ref().map(|g| Constituent {
            tau: g.tau.clone(),
            scale_height_m: g.scale_height_km * 1000.0,
        });
        AtmosphereModel::new(
            self.levels_m(boa_m),
            rayleigh.as_ref(),
            aerosol.as_ref(),
            gas.as_ref(),
            self.aerosols
                .as_ref()
                .map(|a| a.ssa.clone())
                .unwrap_or_default(),
            FluidPhase::Rayleigh {
                depolarization: self
                    .molecules
                    .as_ref()
                    .map_or(AIR_DEPOLARIZATION, |m| m.depolarization),
            },
            self.aerosols
                .as_ref()
                .map_or(FluidPhase::Isotropic, |a| a.phase),
            nb,
        )
    }
}
