//! The discrete direction set of the Direction stage (physics.md §2.2–2.4, §6.3).
//!
//! Input: [`DirectionParams`] (the scene's `directions` section). Output: [`DirectionSet`], a
//! plain list of [`Direction`]s that **tile 4π exactly** (regular, oversampled and exact
//! directions) followed by fictive directions (which receive flux for images but are never
//! re-scattered and are excluded from every 4π sum), plus a lookup tree for flexible directions
//! ([`DirectionSet::find_sector`], O(log N)) and the angular-sector partition used to store
//! intercepted power.
//!
//! Algorithm (\[rec\], physics.md §2.2–2.3; same invariants as Yin et al. 2013 "IUSD"):
//! 1. each hemisphere is tiled separately (the horizon is always a boundary) by a zonal
//!    equal-area tiling: a polar cap plus K rings whose exact boundaries are recomputed from
//!    cumulative cell counts, so every sector has exactly `ΔΩ = 2π/n` (or equal *projected* solid
//!    angle `π/n` in the cosine-weighted variant); alternate rings are offset by half a cell;
//! 2. oversampled regions (cone or zenith/azimuth box): every sector whose centre lies in the
//!    region (and the one containing the region's centre) is re-tiled into near-square children
//!    of (about) the requested solid angle — a p×q grid in (μ, φ), or a zonal sub-tiling of a cap;
//! 3. exact directions (sun hotspot, view directions): the sector containing the direction is
//!    split into a sub-rectangle of the requested solid angle whose representative direction is
//!    the requested vector *bit for bit*, plus near-square remainders. Sectors already smaller than
//!    1.5× the requested solid angle are simply re-labelled exact (representative replaced).
//!
//! Every split partitions a rectangle of `(μ, φ)` space, so `Σ ΔΩ = 4π`, each hemisphere `2π`
//! and `Σ μ̄ ΔΩ = π` per hemisphere (with the sector-mean `μ̄ = (μ_min+μ_max)/2`, stored as
//! [`Direction::projected_sr`]) hold to rounding (~1e-15) whatever is inserted.
//!
//! Conventions: `omega` is a unit **propagation** vector, z up, azimuth φ anticlockwise from +x
//! (DART, physics.md §1.1). Upward directions (μ > 0) have the same angles as DART's
//! ground→sensor view directions; downward ones (zenith > 90°) are "sun to ground" propagation
//! angles. A direction with μ = 0 exactly belongs to the upper hemisphere.

use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

mod tiling;
pub use tiling::DirectionSet;
#[cfg(test)]
mod tests;

/// DART's default number of directions (XSD `numberOfPropagationDirections`).
pub const DEFAULT_COUNT: usize = 100;
/// DART's default solid angle of exact/oversampled directions, sr.
pub const DEFAULT_EXACT_SOLID_ANGLE_SR: f64 = 0.001;
/// DART's default number of angular sectors for interception storage.
pub const DEFAULT_SECTORS: usize = 10;
/// Largest number of directions a set may hold (tables are O(N²)).
pub const MAX_DIRECTIONS: usize = 200_000;

/// What a direction is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum DirectionKind {
    /// A sector of the zonal tiling (possibly a remainder of a split).
    Regular,
    /// A requested exact direction; `tag` is its index in [`DirectionParams::exact`] (the first
    /// request when several requests coincide).
    Exact {
        /// Index of the request in `DirectionParams::exact`.
        tag: u32,
    },
    /// A child of an oversampled region.
    Oversampled,
    /// A fictive direction (not part of the 4π tiling); `tag` indexes `DirectionParams::fictive`.
    Fictive {
        /// Index of the request in `DirectionParams::fictive`.
        tag: u32,
    },
}

impl DirectionKind {
    /// Lower-case name used by the CLI (`regular`, `exact`, `oversampled`, `fictive`).
    pub fn name(&self) -> &'static str {
        match self {
            Self::Regular => "regular",
            Self::Exact { .. } => "exact",
            Self::Oversampled => "oversampled",
            Self::Fictive { .. } => "fictive",
        }
    }
}

/// One discrete direction and its sector `[μ_min, μ_max] × [φ_min, φ_max]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Direction {
    /// Representative unit propagation vector (z up). Regular sectors: sector-mean μ and mid
    /// azimuth (polar caps: the vertical); exact directions: the requested vector exactly.
    pub omega: DVec3,
    /// Lower bound of μ = cos θ over the sector (signed; `mu_min < mu_max`).
    pub mu_min: f64,
    /// Upper bound of μ over the sector.
    pub mu_max: f64,
    /// Start azimuth of the sector, radians in `[0, 2π)`.
    pub phi_min: f64,
    /// End azimuth, radians (`phi_max − phi_min ∈ (0, 2π]`, may exceed 2π numerically).
    pub phi_max: f64,
    /// Solid angle ΔΩ = (φ_max − φ_min)(μ_max − μ_min), sr.
    pub solid_angle_sr: f64,
    /// Exact projected solid angle `∫|μ| dΩ = Δφ |μ_max² − μ_min²|/2` (= μ̄ ΔΩ), sr.
    pub projected_sr: f64,
    /// Kind of direction.
    pub kind: DirectionKind,
    /// Angular sector (group of neighbouring directions) used to store intercepted power.
    pub sector: u16,
}

impl Direction {
    /// Zenith angle of `omega`, degrees in `[0, 180]`.
    pub fn zenith_deg(&self) -> f64 {
        self.omega.z.clamp(-1.0, 1.0).acos().to_degrees()
    }

    /// Azimuth of `omega` (anticlockwise from +x), degrees in `[0, 360)`; 0 for vertical vectors.
    pub fn azimuth_deg(&self) -> f64 {
        azimuth(self.omega).to_degrees()
    }

    /// Zenith bounds `(θ_min, θ_max)` of the sector, radians.
    pub fn theta_bounds(&self) -> (f64, f64) {
        (
            self.mu_max.clamp(-1.0, 1.0).acos(),
            self.mu_min.clamp(-1.0, 1.0).acos(),
        )
    }

    /// Sector-mean cosine `(μ_min + μ_max)/2`.
    pub fn mean_mu(&self) -> f64 {
        0.5 * (self.mu_min + self.mu_max)
    }

    /// True for upward directions (μ ≥ 0 sector).
    pub fn is_upward(&self) -> bool {
        self.mu_min >= 0.0
    }

    /// True when part of the 4π tiling (not fictive).
    pub fn is_regular_tiling(&self) -> bool {
        !matches!(self.kind, DirectionKind::Fictive { .. })
    }

    /// Aspect ratio `Δθ / (sin θ̄ Δφ)` of the sector (θ̄ = mid zenith); `None` for polar caps.
    pub fn aspect_ratio(&self) -> Option<f64> {
        let dphi = self.phi_max - self.phi_min;
        if dphi >= TAU - 1e-9 {
            return None;
        }
        let (t0, t1) = self.theta_bounds();
        let s = (0.5 * (t0 + t1)).sin();
        if s <= 0.0 {
            None
        } else {
            Some((t1 - t0) / (s * dphi))
        }
    }

    /// Appends `s × s` equal-solid-angle sub-samples of the sector (midpoints in μ and φ) with
    /// their solid angles to `out` (cleared first). Fictive directions give one sample
    /// (`omega`, ΔΩ). Used to integrate phase functions over sectors (physics.md §2.5).
    pub fn sub_samples(&self, s: usize, out: &mut Vec<(DVec3, f64)>) {
        out.clear();
        if matches!(self.kind, DirectionKind::Fictive { .. }) {
            out.push((self.omega, self.solid_angle_sr));
            return;
        }
        let s = s.max(1);
        let dmu = (self.mu_max - self.mu_min) / s as f64;
        let dphi = (self.phi_max - self.phi_min) / s as f64;
        let w = self.solid_angle_sr / (s * s) as f64;
        for a in 0..s {
            let mu = self.mu_min + (a as f64 + 0.5) * dmu;
            let st = (1.0 - mu * mu).max(0.0).sqrt();
            for b in 0..s {
                let phi = self.phi_min + (b as f64 + 0.5) * dphi;
                let (sp, cp) = phi.sin_cos();
                out.push((DVec3::new(st * cp, st * sp, mu), w));
            }
        }
    }
}

/// Unit vector from zenith and azimuth in degrees (propagation-vector angles, physics.md §0).
pub fn direction_from_deg(zenith_deg: f64, azimuth_deg: f64) -> DVec3 {
    let (st, ct) = zenith_deg.to_radians().sin_cos();
    let (sp, cp) = azimuth_deg.to_radians().sin_cos();
    DVec3::new(st * cp, st * sp, ct)
}

fn azimuth(v: DVec3) -> f64 {
    if v.x == 0.0 && v.y == 0.0 {
        0.0
    } else {
        v.y.atan2(v.x).rem_euclid(TAU)
    }
}

/// A requested exact (or fictive) direction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExactDirection {
    /// Zenith of the propagation vector, degrees `[0, 180]` (< 90: upward = view direction).
    pub zenith_deg: f64,
    /// Azimuth of the propagation vector, degrees anticlockwise from +x.
    pub azimuth_deg: f64,
    /// Optional label (e.g. "hotspot", "view:nadir").
    #[serde(default)]
    pub label: Option<String>,
    /// Solid angle of this direction, sr (default: `exact_solid_angle_sr`).
    #[serde(default)]
    pub solid_angle_sr: Option<f64>,
}

impl ExactDirection {
    /// An unlabelled exact direction with the default solid angle.
    pub fn new(zenith_deg: f64, azimuth_deg: f64) -> Self {
        Self {
            zenith_deg,
            azimuth_deg,
            label: None,
            solid_angle_sr: None,
        }
    }

    /// The unit propagation vector.
    pub fn omega(&self) -> DVec3 {
        direction_from_deg(self.zenith_deg, self.azimuth_deg)
    }
}

/// A region re-tiled with smaller directions (DART "oversampled regions").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum OversampleRegion {
    /// Cone around a propagation direction.
    Cone {
        /// Axis zenith, degrees `[0, 180]`.
        zenith_deg: f64,
        /// Axis azimuth, degrees.
        azimuth_deg: f64,
        /// Cone half-angle, degrees `(0, 90]`.
        half_angle_deg: f64,
        /// Requested solid angle per direction, sr.
        solid_angle_sr: f64,
    },
    /// Zenith × azimuth box (azimuths may wrap: `azimuth_min_deg > azimuth_max_deg` crosses 0°).
    Box {
        /// Minimum zenith, degrees.
        zenith_min_deg: f64,
        /// Maximum zenith, degrees.
        zenith_max_deg: f64,
        /// Start azimuth, degrees.
        azimuth_min_deg: f64,
        /// End azimuth, degrees.
        azimuth_max_deg: f64,
        /// Requested solid angle per direction, sr.
        solid_angle_sr: f64,
    },
}

impl OversampleRegion {
    fn solid_angle(&self) -> f64 {
        match self {
            Self::Cone { solid_angle_sr, .. } | Self::Box { solid_angle_sr, .. } => *solid_angle_sr,
        }
    }

    fn contains(&self, v: DVec3) -> bool {
        match *self {
            Self::Cone {
                zenith_deg,
                azimuth_deg,
                half_angle_deg,
                ..
            } => {
                let axis = direction_from_deg(zenith_deg, azimuth_deg);
                v.dot(axis) >= half_angle_deg.to_radians().cos() - 1e-15
            }
            Self::Box {
                zenith_min_deg,
                zenith_max_deg,
                azimuth_min_deg,
                azimuth_max_deg,
                ..
            } => {
                let z = v.z.clamp(-1.0, 1.0).acos().to_degrees();
                if z < zenith_min_deg || z > zenith_max_deg {
                    return false;
                }
                let a = azimuth(v).to_degrees();
                let lo = azimuth_min_deg.rem_euclid(360.0);
                (a - lo).rem_euclid(360.0) <= azimuth_span_deg(azimuth_min_deg, azimuth_max_deg)
            }
        }
    }

    fn centre(&self) -> DVec3 {
        match *self {
            Self::Cone {
                zenith_deg,
                azimuth_deg,
                ..
            } => direction_from_deg(zenith_deg, azimuth_deg),
            Self::Box {
                zenith_min_deg,
                zenith_max_deg,
                azimuth_min_deg,
                azimuth_max_deg,
                ..
            } => direction_from_deg(
                0.5 * (zenith_min_deg + zenith_max_deg),
                azimuth_min_deg + 0.5 * azimuth_span_deg(azimuth_min_deg, azimuth_max_deg),
            ),
        }
    }

    fn area_estimate(&self) -> f64 {
        match *self {
            Self::Cone { half_angle_deg, .. } => TAU * (1.0 - half_angle_deg.to_radians().cos()),
            Self::Box {
                zenith_min_deg,
                zenith_max_deg,
                azimuth_min_deg,
                azimuth_max_deg,
                ..
            } => {
                let span = azimuth_span_deg(azimuth_min_deg, azimuth_max_deg).to_radians();
                span * (zenith_min_deg.to_radians().cos() - zenith_max_deg.to_radians().cos()).abs()
            }
        }
    }
}

/// Width of the azimuth range from `min_deg` anticlockwise to `max_deg`, degrees in (0, 360]
/// (the range may wrap through 0°; a whole turn, e.g. 0 to 360, is 360, not 0). Validation
/// rejects `min_deg == max_deg`.
fn azimuth_span_deg(min_deg: f64, max_deg: f64) -> f64 {
    let span = (max_deg - min_deg).rem_euclid(360.0);
    if span == 0.0 && max_deg != min_deg {
        360.0
    } else {
        span
    }
}

/// Parameters of the Direction stage (the scene's `directions` section). Every field has a
/// default; unknown fields are rejected. RON example:
/// `(count: 400, exact: [(zenith_deg: 30, azimuth_deg: 0, label: Some("hotspot"))],
///   oversample: [Cone(zenith_deg: 30, azimuth_deg: 0, half_angle_deg: 10, solid_angle_sr: 0.002)])`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DirectionParams {
    /// Number of regular directions over 4π (DART default 100; odd values round up to even).
    pub count: usize,
    /// Equal *projected* solid angle per sector instead of equal solid angle (DART
    /// `ifCosWeighted`).
    pub cos_weighted: bool,
    /// Number of zenith rings per hemisphere (DART `numberOfLayers`; `None` = automatic).
    pub layers: Option<usize>,
    /// Directions made exact by sector splitting (propagation angles); in a scene file they are
    /// view directions, zenith in [0, 90].
    pub exact: Vec<ExactDirection>,
    /// Oversampled regions.
    pub oversample: Vec<OversampleRegion>,
    /// Fictive directions (receive flux, never re-scattered; outside the 4π sum). Built and
    /// tabulated (`lumenscape directions --fictive`), but a scene file must leave this empty: no
    /// solver computes radiance along them yet (flux tracking walks the tiling directions only,
    /// Monte Carlo peels off toward the exact ones), so `check` and `run` refuse a non-empty
    /// list naming its line; list such view directions under `exact`.
    pub fictive: Vec<ExactDirection>,
    /// Default solid angle of exact and fictive directions, sr (DART default 0.001).
    pub exact_solid_angle_sr: f64,
    /// Number of angular sectors for interception storage (DART default 10).
    pub sectors: usize,
}

impl Default for DirectionParams {
    fn default() -> Self {
        Self {
            count: DEFAULT_COUNT,
            cos_weighted: false,
            layers: None,
            exact: Vec::new(),
            oversample: Vec::new(),
            fictive: Vec::new(),
            exact_solid_angle_sr: DEFAULT_EXACT_SOLID_ANGLE_SR,
            sectors: DEFAULT_SECTORS,
        }
    }
}

impl DirectionParams {
    /// DART defaults with `count` directions.
    pub fn with_count(count: usize) -> Self {
        Self {
            count,
            ..Self::default()
        }
    }
}

/// Invalid direction parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("directions.{field}: {reason}")]
pub struct DirectionError {
    /// Field path inside the `directions` section (e.g. `exact[1].zenith_deg`).
    pub field: String,
    /// What is wrong.
    pub reason: String,
}

fn derr(field: impl Into<String>, reason: impl Into<String>) -> DirectionError {
    DirectionError {
        field: field.into(),
        reason: reason.into(),
    }
}

// ---------------------------------------------------------------------------------------------
// Internal tree (hemisphere-local coordinates u = |μ| ∈ [0, 1], φ ∈ [0, 2π))
// ---------------------------------------------------------------------------------------------

fn validate(p: &DirectionParams) -> Result<(), DirectionError> {
    if p.count < 16 || p.count > MAX_DIRECTIONS {
        return Err(derr(
            "count",
            format!("{} is outside [16, {MAX_DIRECTIONS}]", p.count),
        ));
    }
    if let Some(k) = p.layers {
        let n_h = p.count.div_ceil(2);
        if k < 1 || k > n_h - 1 {
            return Err(derr("layers", format!("{k} is outside [1, {}]", n_h - 1)));
        }
    }
    let sa = |f: String, v: f64| -> Result<(), DirectionError> {
        if v.is_finite() && v > 0.0 && v <= 0.5 {
            Ok(())
        } else {
            Err(derr(f, format!("solid angle {v} sr is outside (0, 0.5]")))
        }
    };
    sa("exact_solid_angle_sr".into(), p.exact_solid_angle_sr)?;
    if p.sectors < 1 || p.sectors > u16::MAX as usize {
        return Err(derr(
            "sectors",
            format!("{} is outside [1, 65535]", p.sectors),
        ));
    }
    for (name, list) in [("exact", &p.exact), ("fictive", &p.fictive)] {
        for (i, e) in list.iter().enumerate() {
            if !(e.zenith_deg.is_finite() && (0.0..=180.0).contains(&e.zenith_deg)) {
                return Err(derr(
                    format!("{name}[{i}].zenith_deg"),
                    format!("{} is outside [0, 180]", e.zenith_deg),
                ));
            }
            if !e.azimuth_deg.is_finite() {
                return Err(derr(format!("{name}[{i}].azimuth_deg"), "must be finite"));
            }
            if let Some(w) = e.solid_angle_sr {
                sa(format!("{name}[{i}].solid_angle_sr"), w)?;
            }
        }
    }
    let mut extra = 0.0;
    for (i, r) in p.oversample.iter().enumerate() {
        let f = |s: &str| format!("oversample[{i}].{s}");
        match *r {
            OversampleRegion::Cone {
                zenith_deg,
                azimuth_deg,
                half_angle_deg,
                solid_angle_sr,
            } => {
                if !(zenith_deg.is_finite() && (0.0..=180.0).contains(&zenith_deg)) {
                    return Err(derr(f("zenith_deg"), "must be in [0, 180]"));
                }
                if !azimuth_deg.is_finite() {
                    return Err(derr(f("azimuth_deg"), "must be finite"));
                }
                if !(half_angle_deg.is_finite() && half_angle_deg > 0.0 && half_angle_deg <= 90.0) {
                    return Err(derr(f("half_angle_deg"), "must be in (0, 90]"));
                }
                if !(solid_angle_sr.is_finite() && (1e-6..=0.5).contains(&solid_angle_sr)) {
                    return Err(derr(f("solid_angle_sr"), "must be in [1e-6, 0.5]"));
                }
            }
            OversampleRegion::Box {
                zenith_min_deg,
                zenith_max_deg,
                azimuth_min_deg,
                azimuth_max_deg,
                solid_angle_sr,
            } => {
                if !(zenith_min_deg.is_finite()
                    && zenith_max_deg.is_finite()
                    && 0.0 <= zenith_min_deg
                    && zenith_min_deg < zenith_max_deg
                    && zenith_max_deg <= 180.0)
                {
                    return Err(derr(
                        f("zenith_min_deg"),
                        "need 0 ≤ zenith_min_deg < zenith_max_deg ≤ 180",
                    ));
                }
                if !(azimuth_min_deg.is_finite() && azimuth_max_deg.is_finite()) {
                    return Err(derr(f("azimuth_min_deg"), "azimuths must be finite"));
                }
                if azimuth_min_deg == azimuth_max_deg {
                    return Err(derr(
                        f("azimuth_max_deg"),
                        "equals azimuth_min_deg: the azimuth range is empty (0 and 360 give every azimuth)",
                    ));
                }
                if !(solid_angle_sr.is_finite() && (1e-6..=0.5).contains(&solid_angle_sr)) {
                    return Err(derr(f("solid_angle_sr"), "must be in [1e-6, 0.5]"));
                }
            }
        }
        // Re-tiled parents can extend one parent size beyond the region: bound generously.
        let parent = 4.0 * PI / p.count as f64;
        let rad = r.area_estimate().sqrt() + 2.0 * parent.sqrt();
        extra += (rad * rad).min(4.0 * PI) / r.solid_angle();
    }
    if p.count as f64 + extra > MAX_DIRECTIONS as f64 {
        return Err(derr(
            "oversample",
            format!(
                "would create about {:.0} directions (limit {MAX_DIRECTIONS})",
                p.count as f64 + extra
            ),
        ));
    }
    Ok(())
}
