//! Validation of the scene's LiDARs (part of [`super::validate`]): instrument, beam, platform
//! (airborne aim points and scan lines, terrestrial scanner), pulse count and photon-counting
//! detector; every error names the field path (`lidars[i]...`).

use super::*;

/// The LiDAR sections of [`validate`].
impl V<'_> {
    /// LiDAR `i`: name, band, instrument, platform, pulse count, photon counting.
    pub(super) fn lidar(&self, i: usize, l: &LidarDesc) -> R {
        let (desc, src) = (self.desc, self.src);
        let f = |x: &str| format!("lidars[{i}].{x}");
        if l.name.trim().is_empty() || l.name.contains(['/', '\\']) {
            return Err(src.invalid(f("name"), "needs a name usable as a folder name"));
        }
        if desc
            .lidars
            .iter()
            .flatten()
            .take(i)
            .any(|o| o.name == l.name)
        {
            return Err(src.invalid(f("name"), format!("`{}` is used twice", l.name)));
        }
        if !desc.bands.iter().any(|b| b.name == l.band) {
            return Err(src.invalid(f("band"), format!("no band named `{}` in `bands`", l.band)));
        }
        self.lidar_instrument(i, l)?;
        self.lidar_platform(i, &l.platform)?;
        let n = lidar_pulse_count(l);
        if n == 0 || n > MAX_LIDAR_PULSES {
            return Err(src.invalid(
                f("platform"),
                format!("asks for {n} pulses (allowed: 1 to {MAX_LIDAR_PULSES})"),
            ));
        }
        if let Some(pc) = &l.photon_counting {
            self.photon_counting(i, pc)?;
        }
        Ok(())
    }

    /// LiDAR `i`'s beam, receiver, pulse and photon settings.
    fn lidar_instrument(&self, i: usize, l: &LidarDesc) -> R {
        let src = self.src;
        let f = |x: &str| format!("lidars[{i}].{x}");
        match (l.footprint_radius_m, l.divergence_mrad) {
            (Some(r), None) => self.positive(&f("footprint_radius_m"), r)?,
            (None, Some(d)) => self.in_range(&f("divergence_mrad"), d, 1e-9, 1000.0)?,
            _ => {
                return Err(src.invalid(
                    f("footprint_radius_m"),
                    "give exactly one of footprint_radius_m and divergence_mrad",
                ));
            }
        }
        self.in_range(&f("edge_intensity"), l.edge_intensity, 1e-6, 0.999)?;
        if let Some(beam) = &l.beam {
            if l.edge_intensity != crate::scene::desc::default_edge_intensity() {
                return Err(src.invalid(
                    f("edge_intensity"),
                    "with a `beam` profile, give the edge intensity inside it (`Gaussian(edge_intensity: ..)`)",
                ));
            }
            if let crate::scene::desc::BeamProfile::Gaussian { edge_intensity } = beam {
                self.in_range(&f("beam.edge_intensity"), *edge_intensity, 1e-6, 0.999)?;
            }
            if let Err(e) = beam.check() {
                return Err(src.invalid(f("beam"), format!("invalid input: {e}")));
            }
        }
        if let Some(r) = l.fov_radius_m {
            self.positive(&f("fov_radius_m"), r)?;
        }
        self.positive(&f("pulse_energy_j"), l.pulse_energy_j)?;
        self.positive(&f("pulse_fwhm_ns"), l.pulse_fwhm_ns)?;
        self.positive(&f("aperture_m2"), l.aperture_m2)?;
        self.in_range(&f("bin_ns"), l.bin_ns, 1e-3, 1e3)?;
        self.non_negative(&f("gate_margin_m"), l.gate_margin_m)?;
        if l.photons_per_pulse == Some(0) {
            return Err(src.invalid(f("photons_per_pulse"), "must be at least 1"));
        }
        if l.max_order == 0 {
            return Err(src.invalid(f("max_order"), "must be at least 1"));
        }
        if let Some(n) = l.scattering_photons_per_pulse
            && (n == 0
                || n > l
                    .photons_per_pulse
                    .unwrap_or(crate::scene::desc::DEFAULT_LIDAR_PHOTONS))
        {
            return Err(src.invalid(
                f("scattering_photons_per_pulse"),
                "must be between 1 and photons_per_pulse (every order ≥ 2 needs photons)",
            ));
        }
        Ok(())
    }

    /// LiDAR `i`'s platform: airborne (altitude, view, pulses) or terrestrial (position,
    /// angular scan).
    fn lidar_platform(&self, i: usize, platform: &LidarPlatform) -> R {
        let (desc, src) = (self.desc, self.src);
        let f = |x: &str| format!("lidars[{i}].{x}");
        match platform {
            LidarPlatform::Airborne {
                altitude_m,
                view_zenith_deg,
                view_azimuth_deg,
                pulses,
            } => {
                self.positive(&f("platform.altitude_m"), *altitude_m)?;
                self.in_range(&f("platform.view_zenith_deg"), *view_zenith_deg, 0.0, 80.0)?;
                self.finite(&f("platform.view_azimuth_deg"), *view_azimuth_deg)?;
                self.lidar_pulses(i, pulses)?;
            }
            LidarPlatform::Terrestrial {
                position_m,
                zenith_deg,
                azimuth_deg,
            } => {
                let (sx, sy) = desc.grid.size_m;
                if !(position_m.0 >= 0.0
                    && position_m.0 <= sx
                    && position_m.1 >= 0.0
                    && position_m.1 <= sy)
                {
                    return Err(src.invalid(
                        f("platform.position_m"),
                        format!(
                            "a terrestrial scanner must stand inside the scene [0, {sx}] × [0, {sy}]"
                        ),
                    ));
                }
                self.finite(&f("platform.position_m"), position_m.2)?;
                for (name, (a, b, s)) in [("zenith_deg", zenith_deg), ("azimuth_deg", azimuth_deg)]
                {
                    let fld = f(&format!("platform.{name}"));
                    self.finite(&fld, *a)?;
                    self.finite(&fld, *b)?;
                    self.positive(&fld, *s)?;
                    if b < a {
                        return Err(src.invalid(fld, "needs (first, last, step) with last ≥ first"));
                    }
                }
                if zenith_deg.0 < 0.0 || zenith_deg.1 > 180.0 {
                    return Err(
                        src.invalid(f("platform.zenith_deg"), "zenith angles lie in [0, 180]")
                    );
                }
            }
        }
        Ok(())
    }

    /// An airborne LiDAR's aim points (within 100 scene sizes) and scan lines.
    fn lidar_pulses(&self, i: usize, pulses: &PulsePattern) -> R {
        let (desc, src) = (self.desc, self.src);
        let f = |x: &str| format!("lidars[{i}].{x}");
        // Aim points within 100 scene sizes of the scene: farther, a pulse misses every
        // object of an isolated scene, and coordinates that large lose the precision the
        // first-flight geometry needs (1e12 m: 1e-4 m steps).
        let (sx, sy) = desc.grid.size_m;
        let aim = |p: (f64, f64)| -> R {
            self.finite(&f("platform.pulses"), p.0)?;
            self.finite(&f("platform.pulses"), p.1)?;
            if !(-100.0 * sx..=101.0 * sx).contains(&p.0)
                || !(-100.0 * sy..=101.0 * sy).contains(&p.1)
            {
                return Err(src.invalid(
                    f("platform.pulses"),
                    format!(
                        "aim point ({}, {}) m lies more than 100 scene sizes away from the scene [0, {sx}] × [0, {sy}] m",
                        num(p.0),
                        num(p.1)
                    ),
                ));
            }
            Ok(())
        };
        match pulses {
            PulsePattern::Single(p) => aim(*p)?,
            PulsePattern::List(ps) => {
                if ps.is_empty() {
                    return Err(src.invalid(f("platform.pulses"), "the pulse list is empty"));
                }
                for p in ps {
                    aim(*p)?;
                }
            }
            PulsePattern::Scan {
                start,
                end,
                lines,
                line_spacing_m,
                pulse_spacing_m,
            } => {
                aim(*start)?;
                aim(*end)?;
                if *lines == 0 {
                    return Err(src.invalid(f("platform.pulses.lines"), "must be at least 1"));
                }
                self.non_negative(&f("platform.pulses.line_spacing_m"), *line_spacing_m)?;
                self.positive(&f("platform.pulses.pulse_spacing_m"), *pulse_spacing_m)?;
            }
        }
        Ok(())
    }

    /// LiDAR `i`'s photon-counting detector.
    fn photon_counting(&self, i: usize, pc: &PhotonCountingDesc) -> R {
        let src = self.src;
        let f = |x: &str| format!("lidars[{i}].{x}");
        self.in_range(
            &f("photon_counting.quantum_efficiency"),
            pc.quantum_efficiency,
            0.0,
            1.0,
        )?;
        self.non_negative(&f("photon_counting.dead_time_ns"), pc.dead_time_ns)?;
        self.non_negative(&f("photon_counting.dark_count_hz"), pc.dark_count_hz)?;
        self.positive(
            &f("photon_counting.filter_bandwidth_nm"),
            pc.filter_bandwidth_nm,
        )?;
        self.positive(&f("photon_counting.wavelength_nm"), pc.wavelength_nm)?;
        if pc.shots == 0 {
            return Err(src.invalid(f("photon_counting.shots"), "must be at least 1"));
        }
        Ok(())
    }
}
