//! Plane-parallel layered atmosphere over the Earth scene (DART 5 paper §2, Fig. 1 "upper
//! atmosphere"; physics.md §4): molecules (Rayleigh), aerosols and absorbing gases, each with an
//! exponential vertical profile, cut into horizontally infinite layers of constant composition
//! between the bottom of the atmosphere (BOA, the scene top) and the top of the atmosphere (TOA).
//!
//! Optical depths of a constituent follow `σ_e(z) ∝ e^{−z/H}` (physics.md §4.4); a layer
//! `[z0, z1]` gets the exact integral `τ (e^{−z0/H} − e^{−z1/H}) / (e^{−z_BOA/H} − e^{−z_TOA/H})`,
//! so the layers of a constituent sum to its column optical depth `τ` between BOA and TOA.

use super::phase::FluidPhase;

/// Rayleigh optical depth of the whole air column (Bodhaine et al. 1999, *J. Atmos. Oceanic
/// Technol.* 16:1854, eq. 30; physics.md §4.3): sea level, 45° latitude, 360 ppm CO₂, scaled by
/// surface pressure `p/1013.25 hPa`. `wavelength_um` in µm, `pressure_hpa` in hPa;
/// dimensionless. 0.55 µm, 1013.25 hPa → 0.09707.
pub fn rayleigh_optical_depth(wavelength_um: f64, pressure_hpa: f64) -> f64 {
    let l2 = wavelength_um * wavelength_um;
    let num = 1.0455996 - 341.29061 / l2 - 0.90230850 * l2;
    let den = 1.0 + 0.0027059889 / l2 - 85.968563 * l2;
    0.0021520 * num / den * pressure_hpa / 1013.25
}

/// Ångström law `τ(λ) = τ_ref (λ/λ_ref)^{−α}` (Ångström 1929): aerosol optical depth at
/// `wavelength_nm` from the optical depth `tau_ref` at `reference_nm` and the exponent `alpha`.
pub fn angstrom_optical_depth(
    tau_ref: f64,
    reference_nm: f64,
    alpha: f64,
    wavelength_nm: f64,
) -> f64 {
    tau_ref * (wavelength_nm / reference_nm).powf(-alpha)
}

/// Fraction of an exponential profile of scale height `h` (m) between `z0` and `z1` relative to
/// its part between `lo` and `hi` (all altitudes in m): `(e^{−z0/H} − e^{−z1/H}) /
/// (e^{−lo/H} − e^{−hi/H})`, evaluated relative to `lo` (no underflow for thin scale heights).
pub fn exponential_fraction(z0: f64, z1: f64, lo: f64, hi: f64, h: f64) -> f64 {
    let e = |z: f64| (-(z - lo) / h).exp();
    let total = 1.0 - e(hi);
    if total <= 0.0 {
        return 0.0;
    }
    (e(z0) - e(z1)) / total
}

/// One constituent's column between BOA and TOA: optical depth per band, scale height.
#[derive(Debug, Clone, PartialEq)]
pub struct Constituent {
    /// Column optical depth between BOA and TOA per band (dimensionless).
    pub tau: Vec<f64>,
    /// Exponential scale height, m.
    pub scale_height_m: f64,
}

/// The layered atmosphere of a scene, per band: what the solvers read.
#[derive(Debug, Clone, PartialEq)]
pub struct AtmosphereModel {
    /// Layer boundaries, altitude above the scene's ground level z = 0, m, increasing: the
    /// first is the BOA (scene top), the last the TOA.
    pub levels_m: Vec<f64>,
    /// Rayleigh scattering optical depth `[layer][band]`.
    pub tau_rayleigh: Vec<Vec<f64>>,
    /// Aerosol extinction optical depth `[layer][band]`.
    pub tau_aerosol: Vec<Vec<f64>>,
    /// Gas absorption optical depth `[layer][band]`.
    pub tau_gas: Vec<Vec<f64>>,
    /// Aerosol single-scattering albedo per band.
    pub aerosol_ssa: Vec<f64>,
    /// Molecular phase function (Rayleigh with depolarisation, physics.md §4.2).
    pub rayleigh_phase: FluidPhase,
    /// Aerosol phase function (Henyey–Greenstein, two-term HG or isotropic).
    pub aerosol_phase: FluidPhase,
}

impl AtmosphereModel {
    /// Layers from the boundaries `levels_m` (BOA first, TOA last) and the three constituents
    /// (absent = none); `aerosol_ssa` per band. Every constituent's column is spread over the
    /// layers by [`exponential_fraction`].
    pub fn new(
        levels_m: Vec<f64>,
        rayleigh: Option<&Constituent>,
        aerosol: Option<&Constituent>,
        gas: Option<&Constituent>,
        aerosol_ssa: Vec<f64>,
        rayleigh_phase: FluidPhase,
        aerosol_phase: FluidPhase,
        n_bands: usize,
    ) -> Self {
        let n_layers = levels_m.len().saturating_sub(1);
        let (lo, hi) = (levels_m[0], levels_m[n_layers]);
        let split = |c: Option<&Constituent>| -> Vec<Vec<f64>> {
            (0..n_layers)
                .map(|l| {
                    (0..n_bands)
                        .map(|b| match c {
                            Some(c) => {
                                c.tau[b]
                                    * exponential_fraction(
                                        levels_m[l],
                                        levels_m[l + 1],
                                        lo,
                                        hi,
                                        c.scale_height_m,
                                    )
                            }
                            None => 0.0,
                        })
                        .collect()
                })
                .collect()
        };
        Self {
            tau_rayleigh: split(rayleigh),
            tau_aerosol: split(aerosol),
            tau_gas: split(gas),
            levels_m,
            aerosol_ssa: if aerosol_ssa.is_empty() {
                vec![1.0; n_bands]
            } else {
                aerosol_ssa
            },
            rayleigh_phase,
            aerosol_phase,
        }
    }

    /// Number of layers.
    pub fn n_layers(&self) -> usize {
        self.levels_m.len().saturating_sub(1)
    }

    /// Extinction optical depth of layer `l` in band `b`.
    pub fn tau_layer(&self, l: usize, b: usize) -> f64 {
        self.tau_rayleigh[l][b] + self.tau_aerosol[l][b] + self.tau_gas[l][b]
    }

    /// Column extinction optical depth between BOA and TOA in band `b`.
    pub fn tau_total(&self, b: usize) -> f64 {
        (0..self.n_layers()).map(|l| self.tau_layer(l, b)).sum()
    }

    /// Direct (beam) transmittance of the whole column along a path of direction cosine `mu`
    /// (plane-parallel, Beer's law): `e^{−τ/|μ|}`.
    pub fn direct_transmittance(&self, b: usize, mu: f64) -> f64 {
        (-self.tau_total(b) / mu.abs()).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bodhaine_matches_the_tabulated_values() {
        // physics.md §4.3 (Bodhaine et al. 1999, their Table 3 to 4 digits).
        for (l, t) in [(0.4, 0.36021), (0.55, 0.09707), (0.865, 0.01549)] {
            let x = rayleigh_optical_depth(l, 1013.25);
            assert!((x / t - 1.0).abs() < 2e-4, "{l}: {x} vs {t}");
        }
    }

    #[test]
    fn layers_sum_to_the_column() {
        let c = Constituent {
            tau: vec![0.3, 0.1],
            scale_height_m: 1000.0,
        };
        let m = AtmosphereModel::new(
            vec![20.0, 500.0, 2000.0, 100_000.0],
            Some(&c),
            None,
            None,
            vec![],
            FluidPhase::air(),
            FluidPhase::Isotropic,
            2,
        );
        assert!((m.tau_total(0) - 0.3).abs() < 1e-14);
        assert!((m.tau_total(1) - 0.1).abs() < 1e-14);
        let expect0 =
            0.3 * (1.0 - (-480.0f64 / 1000.0).exp()) / (1.0 - (-99_980.0f64 / 1000.0).exp());
        assert!(
            (m.tau_rayleigh[0][0] - expect0).abs() < 1e-14,
            "{}",
            m.tau_rayleigh[0][0]
        );
    }
}
