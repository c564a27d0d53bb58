//! Validation of the `thermal` section (part of [`super::validate`]; issue #34): the
//! temperatures (finite, in (0, 1e5] K), their keys (optics keys), and in the `T` and `RT`
//! modes a temperature for every optics key an emitting element can be made of; RPV/Hapke keys
//! only as a flat ground's.

use super::*;

/// The thermal section of [`validate`].
impl V<'_> {
    /// Whether optics `key` is used by a flat `Ground` and by no other object (the objects'
    /// RON holds every optics reference as a quoted string).
    fn flat_ground_only(&self, key: &str) -> bool {
        let quoted = format!("\"{key}\"");
        let mut ground = false;
        for o in &self.desc.objects {
            match o {
                ObjectDesc::Ground(g) if g.optics == key => {
                    if !matches!(g.topography, TopographyDesc::Flat) {
                        return false;
                    }
                    ground = true;
                }
                other => {
                    if ron::to_string(other).is_ok_and(|t| t.contains(&quoted)) {
                        return false;
                    }
                }
            }
        }
        ground
    }

    /// Temperatures, keys and the surfaces thermal emission does not model yet.
    pub(super) fn thermal(&self) -> R {
        let Some(th) = &self.desc.thermal else {
            return Ok(());
        };
        let check_t = |field: String, t: f64| -> R {
            if t.is_finite() && t > 0.0 && t <= MAX_TEMPERATURE_K {
                Ok(())
            } else {
                Err(self.src.invalid(
                    field,
                    format!(
                        "temperature {} K must be in (0, {MAX_TEMPERATURE_K}] K",
                        num(t)
                    ),
                ))
            }
        };
        for (key, &t) in &th.temperatures_k {
            let f = format!("thermal.temperatures_k.{key}");
            if !self.desc.optics.contains_key(key) {
                return Err(self
                    .src
                    .invalid(f, format!("`{key}` is not a key of `optics`")));
            }
            check_t(f, t)?;
        }
        for (key, &(shaded, sunlit)) in &th.sunlit_temperatures_k {
            let f = format!("thermal.sunlit_temperatures_k.{key}");
            if !self.desc.optics.contains_key(key) {
                return Err(self
                    .src
                    .invalid(f, format!("`{key}` is not a key of `optics`")));
            }
            if th.temperatures_k.contains_key(key) {
                return Err(self.src.invalid(
                    f,
                    format!(
                        "`{key}` also has a temperature in `temperatures_k`: give one of the two"
                    ),
                ));
            }
            check_t(f.clone(), shaded)?;
            check_t(f, sunlit)?;
        }
        if let Some(t) = th.default_temperature_k {
            check_t("thermal.default_temperature_k".into(), t)?;
        }
        if let Some(t) = th.sky_temperature_k {
            check_t("thermal.sky_temperature_k".into(), t)?;
        }
        if !th.mode.thermal() {
            return Ok(());
        }
        // Leaf keys only referenced by turbid keys take the turbid key's temperature.
        let turbid_leaves: Vec<&str> = self
            .desc
            .optics
            .values()
            .filter_map(|o| match o {
                OpticsDesc::Turbid { leaf, .. } => Some(leaf.as_str()),
                _ => None,
            })
            .collect();
        for (key, o) in &self.desc.optics {
            let f = format!("optics.{key}");
            match o {
                OpticsDesc::Rpv { .. } | OpticsDesc::Hapke { .. }
                    if !self.flat_ground_only(key) =>
                {
                    return Err(SceneError::NotSupported {
                        at: self.src.at(&f),
                        field: f,
                        message: format!(
                            "thermal emission (mode {}) of RPV and Hapke surfaces is modelled for a flat ground only: use a Lambertian key here, or mode R",
                            th.mode.name()
                        ),
                    });
                }
                OpticsDesc::BiLambertian { .. } | OpticsDesc::ProspectLeaf { .. }
                    if turbid_leaves.contains(&key.as_str()) => {}
                _ => {
                    if th.temperature_of(key).is_none() {
                        return Err(self.src.invalid(
                            "thermal.temperatures_k",
                            format!(
                                "no temperature for optics `{key}` (mode {}): give `temperatures_k: {{\"{key}\": …}}` or `default_temperature_k`",
                                th.mode.name()
                            ),
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}
