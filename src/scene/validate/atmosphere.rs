//! Validation of the scene's atmosphere (part of [`super::validate`]): TOA and layer altitudes,
//! molecules, aerosols and gas per band, and what the atmosphere cannot be combined with yet;
//! every error names the field path (`atmosphere...`).

use super::*;

/// The atmosphere section of [`validate`].
impl V<'_> {
    /// The atmosphere, when present.
    pub(super) fn atmosphere(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        let Some(a) = &desc.atmosphere else {
            return Ok(());
        };
        self.in_range(
            "atmosphere.toa_altitude_km",
            a.toa_altitude_km,
            0.001,
            1000.0,
        )?;
        if let Some(h) = desc.grid.height_m
            && h.is_finite()
            && h >= a.toa_altitude_km * 1000.0
        {
            return Err(src.invalid(
                "atmosphere.toa_altitude_km",
                format!(
                    "must lie above the scene top ({} m), got {} km",
                    num(h),
                    num(a.toa_altitude_km)
                ),
            ));
        }
        if let Some(l) = &a.layer_altitudes_km {
            for (i, &z) in l.iter().enumerate() {
                let f = format!("atmosphere.layer_altitudes_km[{i}]");
                self.in_range(&f, z, 0.0, a.toa_altitude_km)?;
                if i > 0 && z <= l[i - 1] {
                    return Err(src.invalid(f, "must be strictly increasing"));
                }
            }
        }
        if a.molecules.is_none() && a.aerosols.is_none() && a.gas.is_none() {
            return Err(src.invalid(
                "atmosphere",
                "needs at least one of `molecules`, `aerosols`, `gas`",
            ));
        }
        if let Some(m) = &a.molecules {
            self.molecules(m)?;
        }
        if let Some(ae) = &a.aerosols {
            self.aerosols(ae)?;
        }
        if let Some(g) = &a.gas {
            self.bands("atmosphere.gas.tau", &g.tau, 0.0, 100.0, false)?;
            self.in_range(
                "atmosphere.gas.scale_height_km",
                g.scale_height_km,
                0.01,
                100.0,
            )?;
        }
        // What the atmosphere cannot be combined with (yet).
        if desc.lidars.as_ref().is_some_and(|l| !l.is_empty()) {
            return Err(SceneError::NotSupported {
                at: src.at("atmosphere"),
                field: "atmosphere".into(),
                message: "LiDAR through the atmosphere is planned (issue #33): remove `lidars` or `atmosphere`".into(),
            });
        }
        if desc.grid.boundary != BoundaryMode::Repetitive {
            return Err(src.invalid(
                "grid.boundary",
                "an atmosphere needs `Repetitive` (the plane-parallel layers lie over the scene repeated without end)",
            ));
        }
        if desc.illumination.skyl.iter().any(|&s| s != 0.0) {
            return Err(src.invalid(
                "illumination.skyl",
                "must be 0 with an atmosphere (the atmosphere makes the diffuse sky; the irradiance is then at the top of the atmosphere)",
            ));
        }
        Ok(())
    }

    /// Molecules: τ per band or Bodhaine's from wavelengths in its range, pressure,
    /// depolarisation, scale height.
    fn molecules(&self, m: &MoleculesDesc) -> R {
        match &m.tau {
            Some(t) => self.bands("atmosphere.molecules.tau", t, 0.0, 100.0, false)?,
            None => {
                // Bodhaine et al. (1999) eq. 30 is fitted over 0.25–4 µm.
                for (i, b) in self.desc.bands.iter().enumerate() {
                    if b.wavelength_nm != 0.0 && !(250.0..=4000.0).contains(&b.wavelength_nm) {
                        return Err(self.src.invalid(
                            format!("bands[{i}].wavelength_nm"),
                            format!(
                                "the Rayleigh optical depth of Bodhaine et al. needs 250–4000 nm, got {} (give `atmosphere.molecules.tau`)",
                                num(b.wavelength_nm)
                            ),
                        ));
                    }
                }
            }
        }
        self.in_range(
            "atmosphere.molecules.pressure_hpa",
            m.pressure_hpa,
            1.0,
            2000.0,
        )?;
        self.in_range(
            "atmosphere.molecules.depolarization",
            m.depolarization,
            0.0,
            0.49,
        )?;
        self.in_range(
            "atmosphere.molecules.scale_height_km",
            m.scale_height_km,
            0.01,
            100.0,
        )
    }

    /// Aerosols: exactly one of τ per band and τ at a reference wavelength, Ångström
    /// exponent, single-scattering albedo, phase function, scale height.
    fn aerosols(&self, a: &AerosolsDesc) -> R {
        let src = self.src;
        match (&a.tau, a.tau_reference) {
            (Some(t), None) => self.bands("atmosphere.aerosols.tau", t, 0.0, 100.0, false)?,
            (None, Some(t)) => {
                self.in_range("atmosphere.aerosols.tau_reference", t, 0.0, 100.0)?;
                for (i, b) in self.desc.bands.iter().enumerate() {
                    if b.wavelength_nm < 0.0 {
                        return Err(src.invalid(
                            format!("bands[{i}].wavelength_nm"),
                            "must be > 0 for the Ångström law",
                        ));
                    }
                }
            }
            _ => {
                return Err(src.invalid(
                    "atmosphere.aerosols.tau",
                    "give exactly one of `tau` (per band) and `tau_reference`",
                ));
            }
        }
        self.in_range(
            "atmosphere.aerosols.reference_wavelength_nm",
            a.reference_wavelength_nm,
            100.0,
            100_000.0,
        )?;
        self.in_range(
            "atmosphere.aerosols.angstrom_exponent",
            a.angstrom_exponent,
            -5.0,
            5.0,
        )?;
        self.bands("atmosphere.aerosols.ssa", &a.ssa, 0.0, 1.0, false)?;
        if let Err(e) = a.phase.validate() {
            return Err(src.invalid(
                format!("atmosphere.aerosols.phase.{}", e.name),
                format!("{}, got {}", e.reason, num(e.value)),
            ));
        }
        self.in_range(
            "atmosphere.aerosols.scale_height_km",
            a.scale_height_km,
            0.01,
            100.0,
        )
    }
}
