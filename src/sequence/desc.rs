//! The sequence file (RON, versioned like scenes): a base scene and the axes of a parameter
//! sweep, DART's "sequence" tool (DART 5 paper §2). Example (`assets/sequences/lai_cab_sun.ron`):
//!
//! ```ron
//! (
//!     version: 1,
//!     name: "LAI × Cab × sun",
//!     base: "../scenes/prospect_sentinel2.ron",
//!     axes: [
//!         (name: "lai", path: "objects[1].foliage", values: [0.5, 3.0, 6.0]),
//!         (name: "cab", path: "optics.leaf.cab_ug_cm2", range: (from: 10.0, to: 80.0, steps: 8)),
//!         (name: "sza", path: "illumination.sun_zenith_deg", values: [0.0, 30.0], zip: "sun"),
//!         (name: "saa", path: "illumination.sun_azimuth_deg", values: [0.0, 90.0], zip: "sun"),
//!     ],
//! )
//! ```

use serde::{Deserialize, Serialize};

/// The sequence-format version this program reads.
pub const SEQUENCE_FORMAT_VERSION: u32 = 1;

/// A whole sequence file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SequenceDesc {
    /// Sequence-format version; must equal [`SEQUENCE_FORMAT_VERSION`].
    pub version: u32,
    /// Human-readable name, copied into the plan.
    #[serde(default)]
    pub name: String,
    /// The base scene file, relative to the sequence file's folder (relative paths inside the
    /// scene stay relative to the scene's own folder).
    pub base: String,
    /// The axes. Axes without `zip` combine as a full grid (the last axis varies fastest); axes
    /// that share a `zip` label advance together and must have equally many values.
    pub axes: Vec<AxisDesc>,
    /// Products kept in each point's folder, as paths relative to it (`summary.json` is always
    /// kept: `gather` reads it; it holds every BRF). Default: `["summary.json"]` — a look-up
    /// table rarely needs each point's images and budgets; list them (`"brf.csv"`, `"images"`,
    /// `"budget"`, `"lai.exr"`, …) to keep them (with images, budgets or Maket rasters each
    /// point runs on its own instead of sharing a run with the points that differ from it only
    /// in per-band values).
    #[serde(default)]
    pub keep: Option<Vec<String>>,
    /// Whether points that differ only in per-band values share one run as its bands
    /// (default true; `false`: every point runs on its own, bit for bit as `lumenscape run`
    /// would run its scene; see [`crate::sequence::merge`]).
    #[serde(default)]
    pub share: Option<bool>,
}

/// One axis: a scene field and the values it takes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisDesc {
    /// Column name in the table (default: the path).
    #[serde(default)]
    pub name: Option<String>,
    /// The scene field, as in validation messages: `illumination.sun_zenith_deg`,
    /// `optics.leaf.reflectance[0]`, `objects[1].foliage`. Enum variant names may be omitted
    /// (`optics.leaf.cab_ug_cm2` reaches the `ProspectLeaf`'s field; `objects[1].foliage` set
    /// to a number sets the `Lai(…)`'s value).
    pub path: String,
    /// The values, in RON (numbers, strings, lists, …).
    #[serde(default)]
    pub values: Option<Vec<ron::Value>>,
    /// Evenly spaced numbers instead of `values`.
    #[serde(default)]
    pub range: Option<RangeDesc>,
    /// Label of a zipped group: axes with the same label take their i-th values together.
    #[serde(default)]
    pub zip: Option<String>,
}

/// `steps` evenly spaced numbers from `from` to `to` (both included; one step: `from`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeDesc {
    /// First value.
    pub from: f64,
    /// Last value.
    pub to: f64,
    /// Number of values (≥ 1).
    pub steps: usize,
}

impl RangeDesc {
    /// The values: `from + (to − from) · i / (steps − 1)`, the last exactly `to`.
    pub fn values(&self) -> Vec<f64> {
        match self.steps {
            0 => Vec::new(),
            1 => vec![self.from],
            n => (0..n)
                .map(|i| {
                    if i + 1 == n {
                        self.to
                    } else {
                        self.from + (self.to - self.from) * i as f64 / (n - 1) as f64
                    }
                })
                .collect(),
        }
    }
}
