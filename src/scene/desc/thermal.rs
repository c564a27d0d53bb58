//! Authoring types of thermal-infrared runs (`thermal` in a scene; issue #34; DART 5 paper
//! §2–§3; physics.md §7): the mode and the temperatures. Re-exported by
//! [`crate::scene::desc`].

use super::*;

/// Thermal emission: the run's mode and the temperature of every emitting element. Absent: a
/// solar-only (`R`) run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalDesc {
    /// `R` (reflected sunlight only), `T` (thermal emission only) or `RT` (both: what a
    /// sensor at 3–5 µm sees by day). `lumenscape run --mode` overrides it.
    pub mode: RunMode,
    /// Temperature of the elements made of each optics key, K (turbid plots, crowns and leaves
    /// converted to turbid take their turbid or leaf key's; facets and the ground their own
    /// key's). Keys must exist in `optics`.
    #[serde(default)]
    pub temperatures_k: BTreeMap<String, f64>,
    /// Illumination-driven temperatures per optics key, `(shaded, sunlit)` K (DART assigns
    /// temperatures from illumination): each element made of the key gets `shaded + f
    /// (sunlit − shaded)`, f the fraction of it the direct sun reaches (turbid leaves: the
    /// mean of the direct beam's transmittance over the cell's leaves; facets and ground
    /// columns: the lit share of their area), from a sun-only pass of the scene's sun. A key
    /// is in `temperatures_k` or here, not both.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub sunlit_temperatures_k: BTreeMap<String, (f64, f64)>,
    /// Temperature of every optics key not in `temperatures_k`, K. Without it every key used
    /// by an emitting element needs a temperature.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_temperature_k: Option<f64>,
    /// Brightness temperature of an isotropic downwelling sky radiance B(T_sky), K (in `T`
    /// and `RT`; the sky then lights the scene in every thermal band). Absent: a cold sky (no
    /// downwelling thermal radiance).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sky_temperature_k: Option<f64>,
}

/// What a run simulates (DART's R, T and R+T modes; physics.md §7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum RunMode {
    /// Reflected sunlight (and sky light) only.
    #[default]
    R,
    /// Thermal emission only (sun and solar sky off).
    T,
    /// Both, on separate channels of one run (`summary.json` gives the solar and thermal parts
    /// and their sum).
    RT,
}

impl RunMode {
    /// Whether the run has thermal emission.
    pub fn thermal(self) -> bool {
        matches!(self, RunMode::T | RunMode::RT)
    }

    /// Whether the run has the sun and solar sky.
    pub fn solar(self) -> bool {
        matches!(self, RunMode::R | RunMode::RT)
    }

    /// The mode's name in products (`R`, `T`, `R+T`).
    pub fn name(self) -> &'static str {
        match self {
            RunMode::R => "R",
            RunMode::T => "T",
            RunMode::RT => "R+T",
        }
    }
}

/// Largest temperature accepted, K (the Planck function stays finite in f64 far beyond).
pub const MAX_TEMPERATURE_K: f64 = 1.0e5;

impl ThermalDesc {
    /// The temperature of optics key `key`, K, if any.
    pub fn temperature_of(&self, key: &str) -> Option<f64> {
        self.temperatures_k
            .get(key)
            .copied()
            .or_else(|| self.sunlit_temperatures_k.get(key).map(|p| p.0))
            .or(self.default_temperature_k)
    }

    /// The temperature of an element made of `key` lit over a fraction `f` ∈ [0, 1] by the
    /// direct sun, K: its `sunlit_temperatures_k` interpolation, else [`Self::temperature_of`].
    pub fn temperature_at(&self, key: &str, f: f64) -> Option<f64> {
        match self.sunlit_temperatures_k.get(key) {
            Some(&(shaded, sunlit)) => Some(shaded + f.clamp(0.0, 1.0) * (sunlit - shaded)),
            None => self.temperature_of(key),
        }
    }
}
