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
    /// Directions made exact by sector splitting (propagation angles).
    pub exact: Vec<ExactDirection>,
    /// Oversampled regions.
    pub oversample: Vec<OversampleRegion>,
    /// Fictive directions (receive flux, never re-scattered; outside the 4π sum).
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

#[derive(Debug, Clone, Copy, PartialEq)]
struct Rect {
    u0: f64,
    u1: f64,
    phi0: f64,
    dphi: f64,
}

impl Rect {
    fn area(&self) -> f64 {
        self.dphi * (self.u1 - self.u0)
    }
    fn full_ring(&self) -> bool {
        self.dphi >= TAU - 1e-12
    }
    fn is_cap(&self) -> bool {
        self.full_ring() && self.u1 >= 1.0
    }
    fn rel_phi(&self, phi: f64) -> f64 {
        (phi - self.phi0).rem_euclid(TAU)
    }
    fn contains(&self, u: f64, phi: f64) -> bool {
        u >= self.u0 && u <= self.u1 && (self.full_ring() || self.rel_phi(phi) <= self.dphi)
    }
    fn centre(&self) -> (f64, f64) {
        if self.is_cap() {
            (1.0, 0.0)
        } else {
            (
                0.5 * (self.u0 + self.u1),
                (self.phi0 + 0.5 * self.dphi).rem_euclid(TAU),
            )
        }
    }
    fn theta_extent(&self) -> (f64, f64) {
        (self.u1.min(1.0).acos(), self.u0.max(0.0).acos())
    }
    /// Δθ and sin θ̄ Δφ (angular height and width).
    fn shape(&self) -> (f64, f64) {
        let (t0, t1) = self.theta_extent();
        let w = (0.5 * (t0 + t1)).sin().max(1e-12) * self.dphi;
        (t1 - t0, w)
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum LeafKind {
    Regular,
    Oversampled,
    Exact(u32),
}

#[derive(Debug, Clone, PartialEq)]
struct Leaf {
    rect: Rect,
    kind: LeafKind,
    /// Exact representative (global vector) when set.
    rep: Option<DVec3>,
    id: usize,
}

#[derive(Debug, Clone, PartialEq)]
struct Ring {
    u0: f64,
    u1: f64,
    phi0: f64,
    cells: Vec<Node>,
}

#[derive(Debug, Clone, PartialEq)]
enum Node {
    Leaf(Leaf),
    /// Rings sorted from the highest u (pole side) down; each ring splits `extent.dphi` equally.
    Zonal {
        extent: Rect,
        rings: Vec<Ring>,
    },
    List {
        extent: Rect,
        children: Vec<Node>,
    },
}

impl Node {
    fn extent(&self) -> Rect {
        match self {
            Node::Leaf(l) => l.rect,
            Node::Zonal { extent, .. } | Node::List { extent, .. } => *extent,
        }
    }

    /// The leaf id of a zonal node's polar cap when `u` lies in it: the first ring (highest u)
    /// has one cell, a leaf, and `u ≥ u0` of that ring ([`zonal_cell`] then returns (0, 0)
    /// whatever φ). `None` otherwise (use [`Node::lookup`]).
    #[inline]
    fn cap_leaf(&self, u: f64) -> Option<usize> {
        if let Node::Zonal { rings, .. } = self
            && let Some(r) = rings.first()
            && r.u0 <= u
            && let [Node::Leaf(l)] = r.cells.as_slice()
        {
            return Some(l.id);
        }
        None
    }

    fn lookup(&self, u: f64, phi: f64) -> usize {
        match self {
            Node::Leaf(l) => l.id,
            Node::Zonal { extent, rings } => {
                let (k, j) = zonal_cell(extent, rings, u, phi);
                rings[k].cells[j].lookup(u, phi)
            }
            Node::List { children, .. } => children[pick_child(children, u, phi)].lookup(u, phi),
        }
    }

    fn for_each_leaf_mut(&mut self, f: &mut dyn FnMut(&mut Node)) {
        if matches!(self, Node::Leaf(_)) {
            f(self);
            return;
        }
        match self {
            Node::Zonal { rings, .. } => {
                for r in rings {
                    for c in &mut r.cells {
                        c.for_each_leaf_mut(f);
                    }
                }
            }
            Node::List { children, .. } => {
                for c in children {
                    c.for_each_leaf_mut(f);
                }
            }
            Node::Leaf(_) => {}
        }
    }

    fn leaf_mut(&mut self, u: f64, phi: f64) -> &mut Node {
        // Same descent as `lookup`, returning the leaf node.
        let idx: Option<(usize, usize)> = match self {
            Node::Leaf(_) => None,
            Node::Zonal { extent, rings } => Some(zonal_cell(extent, rings, u, phi)),
            Node::List { children, .. } => Some((usize::MAX, pick_child(children, u, phi))),
        };
        match (self, idx) {
            (n @ Node::Leaf(_), _) => n,
            (Node::Zonal { rings, .. }, Some((k, j))) => rings[k].cells[j].leaf_mut(u, phi),
            (Node::List { children, .. }, Some((_, i))) => children[i].leaf_mut(u, phi),
            (n, None) => n,
        }
    }
}

/// (ring, cell) of a zonal node containing (u, φ): ring by binary search on u, cell by the
/// azimuth offset from the ring's start (points outside a partial ring's azimuth range go to
/// the nearer end cell).
fn zonal_cell(extent: &Rect, rings: &[Ring], u: f64, phi: f64) -> (usize, usize) {
    let k = rings.partition_point(|r| r.u0 > u).min(rings.len() - 1);
    let r = &rings[k];
    let m = r.cells.len();
    let w = extent.dphi / m as f64;
    // (rem_euclid is a libm fmod call; inside [0, 2π) it returns its argument.)
    let mut rel = phi - r.phi0;
    if !(0.0..TAU).contains(&rel) {
        rel = rel.rem_euclid(TAU);
    }
    if !extent.full_ring() && rel > extent.dphi {
        rel = if rel > extent.dphi + 0.5 * (TAU - extent.dphi) {
            0.0
        } else {
            extent.dphi
        };
    }
    (k, ((rel / w) as usize).min(m - 1))
}

/// The child of a split node containing (u, φ); ties at shared boundaries go to the first
/// child, points lost to rounding to the nearest child.
fn pick_child(children: &[Node], u: f64, phi: f64) -> usize {
    if let Some(i) = children.iter().position(|c| c.extent().contains(u, phi)) {
        return i;
    }
    let mut best = (f64::INFINITY, 0usize);
    for (i, c) in children.iter().enumerate() {
        let e = c.extent();
        let du = if u < e.u0 {
            e.u0 - u
        } else if u > e.u1 {
            u - e.u1
        } else {
            0.0
        };
        let rel = e.rel_phi(phi);
        let dp = if e.full_ring() || rel <= e.dphi {
            0.0
        } else {
            (rel - e.dphi).min(TAU - rel)
        };
        if du + dp < best.0 {
            best = (du + dp, i);
        }
    }
    best.1
}

fn leaf(rect: Rect, kind: LeafKind) -> Node {
    Node::Leaf(Leaf {
        rect,
        kind,
        rep: None,
        id: 0,
    })
}

/// Zonal tiling of the cap `u ∈ [u_lo, 1]` × 2π into `n` cells of equal measure (equal solid
/// angle, or equal projected solid angle when `cos_weighted`) — physics.md §2.2 steps 1–5.
fn zonal_tiling(
    u_lo: f64,
    n: usize,
    layers: Option<usize>,
    cos_weighted: bool,
    kind: LeafKind,
) -> Node {
    let extent = Rect {
        u0: u_lo,
        u1: 1.0,
        phi0: 0.0,
        dphi: TAU,
    };
    let n = n.max(1);
    if n == 1 {
        return leaf(extent, kind);
    }
    // Measure coordinate s(u) ∈ [0, S]: 1 − u (solid angle) or 1 − u² (projected).
    let s_of = |u: f64| if cos_weighted { 1.0 - u * u } else { 1.0 - u };
    let u_of = |s: f64| {
        if cos_weighted {
            (1.0 - s).max(0.0).sqrt()
        } else {
            1.0 - s
        }
    };
    let s_tot = s_of(u_lo);
    if n < 5 {
        // Too few cells for a cap and a ring of ≥ 3: n wedges from the pole.
        let ring = Ring {
            u0: u_lo,
            u1: 1.0,
            phi0: 0.0,
            cells: (0..n)
                .map(|j| {
                    leaf(
                        Rect {
                            u0: u_lo,
                            u1: 1.0,
                            phi0: j as f64 * TAU / n as f64,
                            dphi: TAU / n as f64,
                        },
                        kind,
                    )
                })
                .collect(),
        };
        return Node::Zonal {
            extent,
            rings: vec![ring],
        };
    }
    let cell = s_tot / n as f64;
    let u_cap = u_of(cell);
    let theta_c = u_cap.acos();
    let theta_end = u_lo.acos();
    let d_omega = TAU * (1.0 - u_lo) / n as f64;
    let mut k_rings = match layers {
        Some(k) => k.clamp(1, n - 1),
        None => (((theta_end - theta_c) / d_omega.sqrt()).round() as usize).max(1),
    };
    let counts = loop {
        let mut counts = Vec::with_capacity(k_rings);
        let mut carry = 0.0;
        let mut used = 0usize;
        for k in 1..=k_rings {
            let ta = theta_c + (k - 1) as f64 * (theta_end - theta_c) / k_rings as f64;
            let tb = theta_c + k as f64 * (theta_end - theta_c) / k_rings as f64;
            let ideal = (s_of(tb.cos()) - s_of(ta.cos())) / cell;
            let m = if k == k_rings {
                n as i64 - 1 - used as i64
            } else {
                ((ideal + carry).round() as i64).max(1)
            };
            carry += ideal - m as f64;
            counts.push(m);
            used += m.max(0) as usize;
        }
        let min_m = if layers.is_some() { 1 } else { 3 };
        if counts.iter().all(|&m| m >= min_m) || k_rings == 1 {
            break counts;
        }
        k_rings -= 1;
    };
    let mut rings = Vec::with_capacity(k_rings + 1);
    rings.push(Ring {
        u0: u_cap,
        u1: 1.0,
        phi0: 0.0,
        cells: vec![leaf(
            Rect {
                u0: u_cap,
                u1: 1.0,
                phi0: 0.0,
                dphi: TAU,
            },
            kind,
        )],
    });
    let mut cum = 1usize;
    let mut u_hi = u_cap;
    for (k, &m) in counts.iter().enumerate() {
        let m = m.max(1) as usize;
        cum += m;
        let u_low = if k + 1 == counts.len() {
            u_lo
        } else {
            u_of(cum as f64 * cell)
        };
        let w = TAU / m as f64;
        let phi0 = if k % 2 == 0 { 0.0 } else { 0.5 * w };
        let cells = (0..m)
            .map(|j| {
                leaf(
                    Rect {
                        u0: u_low,
                        u1: u_hi,
                        phi0: (phi0 + j as f64 * w).rem_euclid(TAU),
                        dphi: w,
                    },
                    kind,
                )
            })
            .collect();
        rings.push(Ring {
            u0: u_low,
            u1: u_hi,
            phi0,
            cells,
        });
        u_hi = u_low;
    }
    Node::Zonal { extent, rings }
}

/// Splits a rectangle into a p × q grid of equal-solid-angle, near-square cells, about
/// `area/target` of them (at least `q_min` columns; caps use a zonal sub-tiling).
fn grid_split(rect: Rect, target: f64, kind: LeafKind) -> Node {
    let c = ((rect.area() / target).round() as usize).max(1);
    if rect.is_cap() {
        let mut z = zonal_tiling(rect.u0, c, None, false, kind);
        if let Node::Zonal { extent, .. } | Node::List { extent, .. } = &mut z {
            *extent = rect;
        }
        return z;
    }
    let (h, w) = rect.shape();
    let q_min = if rect.dphi > FRAC_PI_2 + 1e-12 {
        (rect.dphi / FRAC_PI_2).ceil() as usize
    } else {
        1
    };
    let mut p = (((c as f64) * h / w).sqrt().round() as usize).max(1);
    let mut q = ((c as f64 / p as f64).round() as usize).max(1);
    if q < q_min {
        q = q_min;
        p = ((c as f64 / q as f64).round() as usize).max(1);
    }
    if p == 1 && q == 1 {
        return leaf(rect, kind);
    }
    let du = (rect.u1 - rect.u0) / p as f64;
    let wq = rect.dphi / q as f64;
    let rings = (0..p)
        .map(|r| {
            let u1 = if r == 0 {
                rect.u1
            } else {
                rect.u1 - r as f64 * du
            };
            let u0 = if r + 1 == p {
                rect.u0
            } else {
                rect.u1 - (r + 1) as f64 * du
            };
            let cells = (0..q)
                .map(|j| {
                    let a = rect.phi0 + j as f64 * wq;
                    let d = if j + 1 == q {
                        rect.phi0 + rect.dphi - a
                    } else {
                        wq
                    };
                    leaf(
                        Rect {
                            u0,
                            u1,
                            phi0: a.rem_euclid(TAU),
                            dphi: d,
                        },
                        kind,
                    )
                })
                .collect();
            Ring {
                u0,
                u1,
                phi0: rect.phi0,
                cells,
            }
        })
        .collect();
    Node::Zonal {
        extent: rect,
        rings,
    }
}

/// Hemisphere-local (u, φ) of a global vector and its hemisphere (0 upper, 1 lower).
fn local(v: DVec3) -> (usize, f64, f64) {
    let len = v.length();
    if !(len.is_finite() && len > 0.0) {
        return (0, 1.0, 0.0);
    }
    let z = v.z / len;
    let hemi = if z >= 0.0 { 0 } else { 1 };
    (hemi, z.abs().min(1.0), azimuth(v))
}

fn global(hemi: usize, u: f64, phi: f64) -> DVec3 {
    let st = (1.0 - u * u).max(0.0).sqrt();
    let (sp, cp) = phi.sin_cos();
    DVec3::new(st * cp, st * sp, if hemi == 0 { u } else { -u })
}

/// Splits leaf `l` so that `target` (global, hemisphere-local `(ut, pt)`) becomes an exact
/// direction of about `omega` sr (physics.md §2.3).
fn split_for_exact(l: &Leaf, ut: f64, pt: f64, target: DVec3, omega: f64, tag: u32) -> Node {
    let r = l.rect;
    let exact = |rect: Rect| {
        Node::Leaf(Leaf {
            rect,
            kind: LeafKind::Exact(tag),
            rep: Some(target),
            id: 0,
        })
    };
    if r.area() <= 1.5 * omega {
        return exact(r);
    }
    let rem_kind = l.kind;
    let target_size = r.area();
    let mut children = Vec::new();
    let st = (1.0 - ut * ut).max(0.0).sqrt();
    if st < 1e-9 && r.is_cap() {
        // Exact zenith/nadir: a small cap plus an annulus cut into near-square wedges.
        let u_s = 1.0 - omega / TAU;
        children.push(exact(Rect {
            u0: u_s,
            u1: 1.0,
            phi0: 0.0,
            dphi: TAU,
        }));
        let ann = Rect {
            u0: r.u0,
            u1: u_s,
            phi0: 0.0,
            dphi: TAU,
        };
        let (h, w) = ann.shape();
        let q = ((w / h).round() as usize).max(3);
        let wq = TAU / q as f64;
        for j in 0..q {
            children.push(leaf(
                Rect {
                    u0: r.u0,
                    u1: u_s,
                    phi0: j as f64 * wq,
                    dphi: wq,
                },
                rem_kind,
            ));
        }
        return Node::List {
            extent: r,
            children,
        };
    }
    let half = omega.sqrt() / 2.0;
    let cap_phi = if r.full_ring() {
        FRAC_PI_4
    } else {
        (0.5 * r.dphi).min(FRAC_PI_4)
    };
    let mut dphi_h = (half / st.max(1e-12)).min(cap_phi);
    let mut du_h = omega / (4.0 * dphi_h);
    if 2.0 * du_h > r.u1 - r.u0 {
        du_h = 0.5 * (r.u1 - r.u0);
        dphi_h = (omega / (4.0 * du_h)).min(cap_phi);
    }
    // μ range shifted inside the parent, then thin remainders snapped away.
    let (mut lo, mut hi) = (ut - du_h, ut + du_h);
    if lo < r.u0 {
        hi += r.u0 - lo;
        lo = r.u0;
    }
    if hi > r.u1 {
        lo -= hi - r.u1;
        hi = r.u1;
    }
    lo = lo.max(r.u0);
    if lo - r.u0 < 0.25 * (hi - lo) {
        lo = r.u0;
    }
    if r.u1 - hi < 0.25 * (hi - lo) {
        hi = r.u1;
    }
    // Azimuth range, relative to the parent's start.
    let (a, b) = if r.full_ring() {
        let a = (pt - dphi_h).rem_euclid(TAU);
        (a, a + 2.0 * dphi_h)
    } else {
        let rel = r.rel_phi(pt).min(r.dphi);
        let (mut a, mut b) = (rel - dphi_h, rel + dphi_h);
        if a < 0.0 {
            b -= a;
            a = 0.0;
        }
        if b > r.dphi {
            a -= b - r.dphi;
            b = r.dphi;
        }
        a = a.max(0.0);
        if a < 0.25 * (b - a) {
            a = 0.0;
        }
        if r.dphi - b < 0.25 * (b - a) {
            b = r.dphi;
        }
        (r.phi0 + a, r.phi0 + b)
    };
    children.push(exact(Rect {
        u0: lo,
        u1: hi,
        phi0: a.rem_euclid(TAU),
        dphi: b - a,
    }));
    let mut rems = Vec::new();
    if hi < r.u1 {
        rems.push(Rect {
            u0: hi,
            u1: r.u1,
            phi0: r.phi0,
            dphi: r.dphi,
        });
    }
    if lo > r.u0 {
        rems.push(Rect {
            u0: r.u0,
            u1: lo,
            phi0: r.phi0,
            dphi: r.dphi,
        });
    }
    if r.full_ring() {
        rems.push(Rect {
            u0: lo,
            u1: hi,
            phi0: b.rem_euclid(TAU),
            dphi: TAU - (b - a),
        });
    } else {
        if a > r.phi0 {
            rems.push(Rect {
                u0: lo,
                u1: hi,
                phi0: r.phi0,
                dphi: a - r.phi0,
            });
        }
        if b < r.phi0 + r.dphi {
            rems.push(Rect {
                u0: lo,
                u1: hi,
                phi0: b.rem_euclid(TAU),
                dphi: r.phi0 + r.dphi - b,
            });
        }
    }
    for rem in rems {
        if rem.area() <= 0.0 {
            continue;
        }
        children.push(grid_split(rem, target_size, rem_kind));
    }
    Node::List {
        extent: r,
        children,
    }
}

/// Splits an exact leaf holding representative `a` so that a second exact direction `b` gets
/// its own half (cut midway between them along the more separated axis).
fn split_two_exact(
    l: &Leaf,
    hemi_u_a: (f64, f64),
    b: (f64, f64),
    target_b: DVec3,
    tag_b: u32,
) -> Node {
    let r = l.rect;
    let (ua, pa) = hemi_u_a;
    let (ub, pb) = b;
    let st = (1.0 - (0.5 * (ua + ub)).powi(2)).max(0.0).sqrt();
    let dtheta = (ua.clamp(-1.0, 1.0).acos() - ub.clamp(-1.0, 1.0).acos()).abs();
    let ra = r.rel_phi(pa);
    let rb = r.rel_phi(pb);
    let dphi = (ra - rb).abs().min(TAU - (ra - rb).abs()) * st;
    let mk = |rect: Rect, rep: Option<DVec3>, tag: u32| {
        Node::Leaf(Leaf {
            rect,
            kind: LeafKind::Exact(tag),
            rep,
            id: 0,
        })
    };
    let tag_a = match l.kind {
        LeafKind::Exact(t) => t,
        _ => 0,
    };
    let (ra_rect, rb_rect) = if dtheta >= dphi || r.full_ring() {
        let cut = 0.5 * (ua + ub);
        let low = Rect {
            u0: r.u0,
            u1: cut,
            ..r
        };
        let high = Rect {
            u0: cut,
            u1: r.u1,
            ..r
        };
        if ua > ub { (high, low) } else { (low, high) }
    } else {
        let cut = 0.5 * (ra + rb);
        let first = Rect { dphi: cut, ..r };
        let second = Rect {
            phi0: (r.phi0 + cut).rem_euclid(TAU),
            dphi: r.dphi - cut,
            ..r
        };
        if ra < rb {
            (first, second)
        } else {
            (second, first)
        }
    };
    Node::List {
        extent: r,
        children: vec![
            mk(ra_rect, l.rep, tag_a),
            mk(rb_rect, Some(target_b), tag_b),
        ],
    }
}

// ---------------------------------------------------------------------------------------------
// The public set
// ---------------------------------------------------------------------------------------------

/// The discrete directions of a scene: regular/oversampled/exact directions tiling 4π (indices
/// `0..n_regular()`, upper hemisphere first, pole to horizon) then fictive directions.
#[derive(Debug, Clone, Serialize)]
pub struct DirectionSet {
    /// All directions (tiling first, fictive last).
    pub directions: Vec<Direction>,
    n_regular: usize,
    n_sectors: usize,
    exact_index: Vec<usize>,
    params: DirectionParams,
    #[serde(skip)]
    roots: Vec<Node>,
}

impl DirectionSet {
    /// Builds the set (validation errors name the offending field).
    pub fn new(params: &DirectionParams) -> Result<Self, DirectionError> {
        validate(params)?;
        let n_h = params.count.div_ceil(2);
        let mut roots: Vec<Node> = (0..2)
            .map(|_| {
                zonal_tiling(
                    0.0,
                    n_h,
                    params.layers,
                    params.cos_weighted,
                    LeafKind::Regular,
                )
            })
            .collect();

        // Oversampled regions.
        for region in &params.oversample {
            let w = region.solid_angle();
            let centre = region.centre();
            let (ch, cu, cp) = local(centre);
            for (hemi, root) in roots.iter_mut().enumerate() {
                root.for_each_leaf_mut(&mut |node| {
                    let Node::Leaf(l) = node else { return };
                    let (u, p) = l.rect.centre();
                    let inside = region.contains(global(hemi, u, p))
                        || (hemi == ch && l.rect.contains(cu, cp));
                    if inside && l.rect.area() > 1.5 * w {
                        *node = grid_split(l.rect, w, LeafKind::Oversampled);
                    }
                });
            }
        }

        // Exact directions.
        let mut alias: Vec<(usize, u32)> = Vec::new();
        for (k, e) in params.exact.iter().enumerate() {
            let target = e.omega();
            let (hemi, ut, pt) = local(target);
            let w = e.solid_angle_sr.unwrap_or(params.exact_solid_angle_sr);
            let node = roots[hemi].leaf_mut(ut, pt);
            let Node::Leaf(l) = node else {
                unreachable!("leaf_mut returns a leaf")
            };
            match (l.kind, l.rep) {
                (LeafKind::Exact(t), Some(rep)) => {
                    if rep.angle_between(target) < 1e-9 {
                        alias.push((k, t));
                    } else {
                        let (_, ua, pa) = local(rep);
                        *node = split_two_exact(l, (ua, pa), (ut, pt), target, k as u32);
                    }
                }
                _ => *node = split_for_exact(l, ut, pt, target, w, k as u32),
            }
        }

        // Number the leaves and emit directions.
        let mut directions = Vec::new();
        for (hemi, root) in roots.iter_mut().enumerate() {
            root.for_each_leaf_mut(&mut |node| {
                let Node::Leaf(l) = node else { return };
                l.id = directions.len();
                directions.push(emit(hemi, l));
            });
        }
        let n_regular = directions.len();
        let mut exact_index = vec![usize::MAX; params.exact.len()];
        for (i, d) in directions.iter().enumerate() {
            if let DirectionKind::Exact { tag } = d.kind {
                exact_index[tag as usize] = i;
            }
        }
        for (k, t) in alias {
            exact_index[k] = exact_index[t as usize];
        }

        // Angular sectors.
        let n_sectors = assign_sectors(&mut directions, params.sectors);

        // Fictive directions (appended, sector of their containing tiling direction).
        let mut set = Self {
            directions,
            n_regular,
            n_sectors,
            exact_index,
            params: params.clone(),
            roots,
        };
        for (k, f) in params.fictive.iter().enumerate() {
            let v = f.omega();
            let w = f.solid_angle_sr.unwrap_or(params.exact_solid_angle_sr);
            let host = set.find_sector(v);
            let (mu, phi) = (v.z, azimuth(v));
            let half_mu = (0.25 * w).sqrt().min(1.0);
            let dphi = w / (2.0 * half_mu);
            set.directions.push(Direction {
                omega: v,
                mu_min: (mu - half_mu).max(-1.0),
                mu_max: (mu + half_mu).min(1.0),
                phi_min: (phi - 0.5 * dphi).rem_euclid(TAU),
                phi_max: (phi - 0.5 * dphi).rem_euclid(TAU) + dphi,
                solid_angle_sr: w,
                projected_sr: mu.abs() * w,
                kind: DirectionKind::Fictive { tag: k as u32 },
                sector: set.directions[host].sector,
            });
        }
        Ok(set)
    }

    /// DART defaults with `count` directions.
    pub fn with_count(count: usize) -> Result<Self, DirectionError> {
        Self::new(&DirectionParams::with_count(count))
    }

    /// The parameters the set was built from.
    pub fn params(&self) -> &DirectionParams {
        &self.params
    }

    /// Number of all directions (tiling + fictive).
    pub fn len(&self) -> usize {
        self.directions.len()
    }

    /// True when empty (never, for a valid set).
    pub fn is_empty(&self) -> bool {
        self.directions.is_empty()
    }

    /// Number of directions tiling 4π (indices `0..n_regular`).
    pub fn n_regular(&self) -> usize {
        self.n_regular
    }

    /// The directions tiling 4π.
    pub fn tiling(&self) -> &[Direction] {
        &self.directions[..self.n_regular]
    }

    /// The fictive directions (indices `n_regular..len`).
    pub fn fictive(&self) -> &[Direction] {
        &self.directions[self.n_regular..]
    }

    /// Number of (non-empty) angular sectors; `Direction::sector < n_sectors`.
    pub fn n_sectors(&self) -> usize {
        self.n_sectors
    }

    /// Index of the direction made exact for request `k` of `DirectionParams::exact`.
    pub fn exact_index(&self, k: usize) -> Option<usize> {
        self.exact_index
            .get(k)
            .copied()
            .filter(|&i| i != usize::MAX)
    }

    /// Index of the tiling direction whose sector contains `omega` (a propagation vector, need
    /// not be normalised) — the flexible-direction hook (seed eq. 4): O(log N) (binary search of
    /// the ring by μ, then azimuth arithmetic, then at most a few split children).
    /// μ = 0 goes to the upper hemisphere; zero or non-finite vectors map to the +z cap.
    pub fn find_sector(&self, omega: DVec3) -> usize {
        // Fast path (same result as the full lookup): a direction inside the polar cap of its
        // hemisphere (the first ring holds one leaf, so neither the azimuth nor the ring search
        // matters), e.g. every return toward a nadir LiDAR receiver.
        let len = omega.length();
        if len.is_finite() && len > 0.0 {
            let z = omega.z / len;
            let h = if z >= 0.0 { 0 } else { 1 };
            if let Some(id) = self.roots[h].cap_leaf(z.abs().min(1.0)) {
                return id;
            }
        }
        let (h, u, p) = local(omega);
        self.roots[h].lookup(u, p)
    }

    /// Σ ΔΩ over the tiling (4π).
    pub fn total_solid_angle(&self) -> f64 {
        self.tiling().iter().map(|d| d.solid_angle_sr).sum()
    }

    /// `[(ΣΔΩ, Σ μ̄ΔΩ) upper, (ΣΔΩ, Σ |μ̄|ΔΩ) lower]` over the tiling (2π and π each).
    pub fn hemisphere_sums(&self) -> [(f64, f64); 2] {
        let mut s = [(0.0, 0.0); 2];
        for d in self.tiling() {
            let h = if d.is_upward() { 0 } else { 1 };
            s[h].0 += d.solid_angle_sr;
            s[h].1 += d.projected_sr;
        }
        s
    }

    /// (min, max) aspect ratio `Δθ/(sin θ̄ Δφ)` over regular (non-split, non-cap) sectors.
    pub fn aspect_ratio_range(&self) -> (f64, f64) {
        self.aspect_range(|d| d.kind == DirectionKind::Regular)
    }

    /// (min, max) aspect ratio over every non-cap tiling sector (remainders included).
    pub fn aspect_ratio_range_all(&self) -> (f64, f64) {
        self.aspect_range(|_| true)
    }

    fn aspect_range(&self, keep: impl Fn(&Direction) -> bool) -> (f64, f64) {
        self.tiling()
            .iter()
            .filter(|d| keep(d))
            .filter_map(|d| d.aspect_ratio())
            .fold((f64::INFINITY, 0.0f64), |(a, b), r| (a.min(r), b.max(r)))
    }

    /// Indices of the tiling directions in angular sector `k`.
    pub fn sector_members(&self, k: u16) -> Vec<usize> {
        (0..self.n_regular)
            .filter(|&i| self.directions[i].sector == k)
            .collect()
    }
}

fn emit(hemi: usize, l: &Leaf) -> Direction {
    let r = l.rect;
    let (mu_min, mu_max) = if hemi == 0 {
        (r.u0, r.u1)
    } else {
        (-r.u1, -r.u0)
    };
    let omega = match l.rep {
        Some(v) => v,
        None => {
            let (u, p) = r.centre();
            global(hemi, u, p)
        }
    };
    let kind = match l.kind {
        LeafKind::Regular => DirectionKind::Regular,
        LeafKind::Oversampled => DirectionKind::Oversampled,
        LeafKind::Exact(tag) => DirectionKind::Exact { tag },
    };
    let phi_min = r.phi0.rem_euclid(TAU);
    Direction {
        omega,
        mu_min,
        mu_max,
        phi_min,
        phi_max: phi_min + r.dphi,
        solid_angle_sr: r.dphi * (r.u1 - r.u0),
        projected_sr: 0.5 * r.dphi * (r.u1 * r.u1 - r.u0 * r.u0),
        kind,
        sector: 0,
    }
}

/// Groups neighbouring directions into `k` angular sectors (physics.md §6.3 [rec]): a coarse
/// zonal tiling with ⌈k/2⌉ cells in the upper and ⌊k/2⌋ in the lower hemisphere; each direction
/// joins the coarse cell containing its representative; empty cells are dropped. Returns the
/// number of sectors. `k ≥ n` gives one sector per direction.
fn assign_sectors(dirs: &mut [Direction], k: usize) -> usize {
    let n = dirs.len();
    if k >= n {
        for (i, d) in dirs.iter_mut().enumerate() {
            d.sector = i as u16;
        }
        return n;
    }
    if k <= 1 {
        dirs.iter_mut().for_each(|d| d.sector = 0);
        return 1;
    }
    let ku = k.div_ceil(2);
    let kl = (k / 2).max(1);
    let mut coarse = [
        zonal_tiling(0.0, ku, None, false, LeafKind::Regular),
        zonal_tiling(0.0, kl, None, false, LeafKind::Regular),
    ];
    for c in &mut coarse {
        let mut id = 0;
        c.for_each_leaf_mut(&mut |node| {
            if let Node::Leaf(l) = node {
                l.id = id;
                id += 1;
            }
        });
    }
    let raw: Vec<usize> = dirs
        .iter()
        .map(|d| {
            // The sector's own hemisphere decides (a horizon representative may sit at μ = 0).
            let (_, u, p) = local(d.omega);
            let hh = if d.is_upward() { 0 } else { 1 };
            (if hh == 0 { 0 } else { ku }) + coarse[hh].lookup(u, p)
        })
        .collect();
    let mut map = vec![usize::MAX; ku + kl];
    let mut used: Vec<usize> = raw.clone();
    used.sort_unstable();
    used.dedup();
    for (new, &old) in used.iter().enumerate() {
        map[old] = new;
    }
    for (d, r) in dirs.iter_mut().zip(raw) {
        d.sector = map[r] as u16;
    }
    used.len()
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn azimuth_box_span_and_the_empty_range() {
        assert_eq!(azimuth_span_deg(0.0, 360.0), 360.0);
        assert_eq!(azimuth_span_deg(350.0, 10.0), 20.0);
        assert_eq!(azimuth_span_deg(10.0, 350.0), 340.0);
        let region = |lo: f64, hi: f64| DirectionParams {
            count: 100,
            oversample: vec![OversampleRegion::Box {
                zenith_min_deg: 10.0,
                zenith_max_deg: 40.0,
                azimuth_min_deg: lo,
                azimuth_max_deg: hi,
                solid_angle_sr: 0.01,
            }],
            ..DirectionParams::default()
        };
        // A whole turn is a valid box and oversamples every azimuth.
        let set = DirectionSet::new(&region(0.0, 360.0)).expect("0..360 is valid");
        assert!(
            set.tiling()
                .iter()
                .any(|d| d.kind == DirectionKind::Oversampled)
        );
        // Equal bounds: an empty range, rejected with the field named (it used to pass and
        // oversample nothing while the direction-count bound counted a whole turn).
        let e = DirectionSet::new(&region(90.0, 90.0)).expect_err("empty azimuth range");
        let m = e.to_string();
        assert!(m.contains("azimuth_max_deg") && m.contains("empty"), "{m}");
    }

    #[test]
    fn default_set_identities() {
        let s = DirectionSet::with_count(100).unwrap();
        assert_eq!(s.n_regular(), 100);
        assert!((s.total_solid_angle() - 4.0 * PI).abs() < 1e-12);
        for (o, p) in s.hemisphere_sums() {
            assert!((o - TAU).abs() < 1e-12 && (p - PI).abs() < 1e-12);
        }
        let (a, b) = s.aspect_ratio_range();
        assert!(a > 0.5 && b < 2.0, "{a} {b}");
        for (i, d) in s.tiling().iter().enumerate() {
            assert_eq!(s.find_sector(d.omega), i);
        }
        assert!(s.n_sectors() == 10);
    }

    #[test]
    fn ron_roundtrip_of_params() {
        let txt = "(count: 50, exact: [(zenith_deg: 30, azimuth_deg: 0, label: Some(\"hotspot\"))], oversample: [Cone(zenith_deg: 30, azimuth_deg: 0, half_angle_deg: 10, solid_angle_sr: 0.002)])";
        let p: DirectionParams = ron::from_str(txt).unwrap();
        assert_eq!(p.count, 50);
        assert_eq!(p.sectors, 10);
        assert!(ron::from_str::<DirectionParams>("(cont: 50)").is_err());
    }
}
