//! DART flux tracking (discrete-ordinate ray tracking; Gastellu-Etchegorry et al. 1996, 2015
//! §3): radiation is propagated along the discrete directions through the cell grid; what is
//! intercepted at iteration i−1 is scattered at iteration i along every discrete direction with
//! the Phase tables, until the scene exitance converges; the remaining orders are extrapolated
//! geometrically (physics.md §6.4).
//!
//! This module is a plain engine over flat arrays (no ECS): [`RadiativeInput`] in,
//! [`RadiativeResult`] out.
//!
//! * **Channels.** A ray carries one power per band, and, when the scene has sky light, a
//!   second set for the sky-originated part (so that BRF = sun only and HDRF = sun + sky come
//!   out of one run): `W = n_bands × (1 + sky)` values. Geometry and attenuation are traced once
//!   for all channels (extinction does not depend on the band).
//! * **Turbid cells** attenuate exactly, `W_out = W e^{−kℓ}`, `k = Σ_m G_m(Ω) u_m`; the intercepted
//!   power is split among the cell's materials in proportion to `G_m u_m` (physics.md §3.6) and
//!   stored per (cell, material, incident angular sector); the exact sun direction is its own
//!   sector. Two interception points per crossing, the barycentres of the first and second halves
//!   of the intercepted energy (DART stores two points per crossing; physics.md §3.6). Scattered
//!   power leaves *both* points, half from each — a two-point quadrature of the interception
//!   distribution. (physics.md's \[rec\] of sending backward scattering from the first point and
//!   forward from the second biases the exitance by O(cell optical depth): +6 % BRF at 0.25 m
//!   cells on the LAI-3 DISORT case, against −0.96 % … +0 % for the two-point quadrature and
//!   −2 % for a single barycentre.) Rays scattered by a cell start *inside* it, so within-cell
//!   re-interception is tracked, not approximated.
//! * **Turbid sub-faces** (`TrackingParams::turbid_subfaces`, DART 5 paper §3.2 and Figure 7;
//!   physics.md §3.6, §6.3, §6.6): DART stores a turbid cell's interception per *incident cell
//!   sub-face* (the one the ray entered through, D × D per face) and per incident sector, with
//!   interception points per sub-face, and scatters from each. `Off` (every preset's default)
//!   keeps one store per (cell, slot) and one point pair per cell; `Faces` / `Subfaces` keep
//!   power and a point pair per incident face (6) or sub-face (6 D²) plus one store for rays
//!   that start inside the cell, each scattering its own power from its own points (sparse
//!   records: only stores that intercepted something exist); with `turbid_exit_grouping` the
//!   rays of all of a cell's stores are followed to the cell's exit and merged per (exit face or
//!   sub-face, direction) as in Figure 7c. `Blend` keeps one ray pair per (cell, direction),
//!   from the barycentre of per-slot points weighted by the power each slot sends into the
//!   direction. Entry rules ([`entry_store`]): a segment starting on a face the ray points into
//!   entered through it; edges and vertices go to the face of the largest |d_a| (ties: z, then
//!   y, then x); sun and sky rays enter through the top face of the top cells. Measured
//!   (docs/performance.md, "The turbid sub-face option"): on the DISORT layer none of these
//!   beats a finer grid at equal wall time; in dense cells (u_f = 50) `Faces` at 0.25 m gets
//!   the albedo of a ~0.1 m grid for 2× the time of the 0.25 m grid.
//! * **Facets** (Lambertian reflectance R, diffuse transmittance T_d, direct transmittance T_dir):
//!   intercepted `W(1 − T_dir^{1/|μ|})`, reflected `R` to the incidence side and transmitted `T_d`
//!   to the other side with the exact projected-solid-angle fractions (physics.md §5.1, §2.5);
//!   one store and one scattering point (barycentre of hits) per (facet, cell).
//! * **Flat ground** is the exact plane z = z0 (Lambertian), one store per column.
//! * **Hotspot** (physics.md §3.5; Kuusk 1985, SAILH): what turbid cells, facets and the ground
//!   scatter of the direct sun beam (the first emission after the launch) goes up through the
//!   same gaps the sun came through: along it the extinction of a turbid material of leaf size
//!   l > 0 per unit height z above the scattering point is `u_f (k_v − √(k_s k_v) e^{−c z})`,
//!   `c = 2Δ/(l(k_s+k_v))`, integrated exactly per cell crossing. In a homogeneous layer this
//!   is SAILH's joint gap probability. Sky light and higher orders are not correlated. Energy
//!   still closes exactly (the correlated ray is tracked like any other).
//! * **Boundaries**: repetitive (re-entry on the opposite side, with the altitude offset in
//!   continuous-topography scenes) or isolated (lost); escapes through the top are the scene
//!   exitance per direction; everything else is booked as lost (thresholds, crossings limit,
//!   isolated sides, bottom leaks) so the budget closes.
//! * **Determinism**: emitters are processed in fixed chunks (independent of the thread count)
//!   and chunk results are merged in chunk order, so products are bit-identical on any number
//!   of threads.

mod batch;
pub use batch::{batch_lanes, instruction_set, kernel_isa};

use super::dda::{Dda, Exit, floor_i64, skip_field};
use super::fastmath::{HalfBarycentres, attenuation};
use super::images::{ImageGrid, rem_euclid_period};
use crate::resources::directions::DirectionSet;
use crate::resources::facets::{Facet, FacetKind};
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::phase_tables::PhaseTable;
use crate::scene::desc::{BoundaryMode, TurbidSubfaces};
use glam::DVec3;
use rayon::prelude::*;

/// Optical model of one material as the tracker needs it.
#[derive(Debug, Clone)]
pub enum TrackOptics {
    /// Not used by the tracker (e.g. a leaf only referenced by turbid materials).
    Unused,
    /// Turbid vegetation.
    Turbid {
        /// G(Ω_j) for every direction j, then G(Ω_sun) last.
        g: Vec<f64>,
        /// Phase table per band (rows: tiling directions then the sun).
        tables: Vec<PhaseTable>,
        /// Leaf dimension for the hotspot, m (DART `dimFoliar`; 0 = no hotspot).
        leaf_size_m: f64,
    },
    /// Lambertian facet (a bi-Lambertian leaf is R = ρ_L, T_d = τ_L).
    Lambert {
        /// Reflectance per band.
        r: Vec<f64>,
        /// Diffuse transmittance per band.
        t: Vec<f64>,
        /// Direct transmittance at normal incidence per band.
        t_dir: Vec<f64>,
    },
}

/// Stopping and sampling parameters of the flux tracking.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TrackingParams {
    /// Maximum number of iterations (DART `numberOfIteration`, default 20).
    pub max_iterations: u32,
    /// Stop when the relative change of the extrapolated scene albedo between two iterations is
    /// below this (DART `albedoThreshold`, default 1e-3).
    pub albedo_threshold: f64,
    /// A ray of direction j whose power falls below this fraction of the mean source-ray power,
    /// times `ΔΩ_j / ΔΩ_max` (its solid angle over the largest tiling solid angle), is dropped
    /// and booked as lost (DART `lightPropagationThreshold`, default 1e-7; the threshold is
    /// per steradian times the ray's ΔΩ, physics.md §6.4, so the small exact and oversampled
    /// directions are not dropped earlier than the tiles they were cut from).
    pub ray_threshold: f64,
    /// Spacing of the sun and sky launch points on the top plane, metres (DART
    /// `distanceBetweenIlluminationSubCenters`, default 0.1 m); `None`: chosen from the
    /// facets and `launch_target_se` (see [`launch_plan`]).
    pub launch_spacing_m: Option<f64>,
    /// Target standard error of the direct-sun interception (fraction of the sun power) that
    /// the automatic launch spacing aims at (see [`launch_plan`]).
    pub launch_target_se: f64,
    /// Largest number of sun launch points the automatic spacing may use; also bounds the
    /// number of ground scattering points (columns × D²) of the automatic sub-cell factor.
    pub max_launch_points: usize,
    /// Largest sub-cell factor D the automatic choice may use (see [`launch_plan`]); the
    /// scene's `grid.subcells` is a minimum.
    pub max_auto_subcells: u32,
    /// Extrapolate the remaining orders geometrically.
    pub extrapolate: bool,
    /// Maximum scene crossings of one ray in repetitive scenes (DART default 1000).
    pub max_crossings: u32,
    /// Empty-space skipping: rays jump over boxes of empty cells (no tracked turbid entry, no
    /// facet) found from a chessboard distance field ([`super::dda::skip_field`]) instead
    /// of visiting them one by one; the same cells, segment ends and products bit for bit
    /// ([`Dda::skip_to`]). Off: every cell is visited (kept for the equality tests).
    pub skip_empty: bool,
    /// Turbid interception stores per incident face / sub-face (DART 5 paper §3.2, Figure 7;
    /// see [`TurbidSubfaces`]).
    pub turbid_subfaces: TurbidSubfaces,
    /// With `Faces` / `Subfaces`: a turbid cell's scattered rays are followed to the cell's
    /// exit and merged per (exit face or sub-face, direction) (DART 5 paper Figure 7c).
    pub turbid_exit_grouping: bool,
    /// The lean tracker's rays queued per chunk and walked sixteen (AVX-512, single-precision
    /// geometry: [`TrackingParams::batch_f32`]), eight (AVX-512, double precision) or four
    /// (AVX2) at a time (see the `batch` module of the engine). In double precision: the same
    /// rays, each with the same operations as the one-ray walk, so the products agree to
    /// rounding (only the summation order of the rays' contributions changes). Off: one ray
    /// at a time (kept for the equality tests and for measuring).
    pub batch_walk: bool,
    /// Most capable instruction set the walks may use (default: the best this CPU has; the
    /// others for reproducing bits across machines, the equality tests and measuring). Every
    /// ray gets the same IEEE operations on every instruction set (no contraction); the one-ray
    /// walks give the same bits on all, the batched walk the same bits on all CPUs that run the
    /// same lane count (8 with AVX-512, 4 with AVX2 or under `Avx2`), and products within
    /// ~1e-15 relative between the two counts (summation order).
    #[serde(skip)]
    pub kernel_isa: KernelIsa,
    /// The batched walk in single-precision geometry on 16 lanes where the CPU has AVX-512
    /// (default on; `batch` module, `wide32`: each lane's traversal in its cell's frame, path
    /// lengths, fractions and interception points in `f32`; powers, bookings and energy
    /// closure in `f64`): products within ~3e-7 relative of the f64 walks' on cells of 0.1–1 m
    /// (3.4e-6 with 20 m cells), 1.4× faster (README of 4df2100, Kernel). Off, or on CPUs without
    /// AVX-512: the f64 batched walk (8 or 4 lanes).
    #[serde(skip)]
    pub batch_f32: bool,
    /// A progress bar of the iterations on stderr (a display setting, not written with the
    /// products).
    #[serde(skip)]
    pub progress: bool,
}

/// Instruction set cap of the flux-tracking walks ([`TrackingParams::kernel_isa`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum KernelIsa {
    /// The best the CPU has: AVX-512 (the batched walk on 16 single-precision or 8
    /// double-precision lanes, the one-ray walks compiled with it), else AVX2 + FMA, else the
    /// baseline.
    #[default]
    Best,
    /// At most AVX2 + FMA (what CPUs without AVX-512 run: the batched walk on 4 lanes).
    Avx2,
    /// The baseline x86-64 code: one ray at a time (no batched walk).
    Baseline,
}

impl KernelIsa {
    /// The `pulp` dispatch target for this cap on this CPU.
    pub(crate) fn arch(self) -> pulp::Arch {
        #[cfg(target_arch = "x86_64")]
        {
            match self {
                KernelIsa::Best => pulp::Arch::new(),
                KernelIsa::Avx2 => {
                    pulp::x86::V3::try_new().map_or(pulp::Arch::Scalar, pulp::Arch::V3)
                }
                KernelIsa::Baseline => pulp::Arch::Scalar,
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = self;
            pulp::Arch::new()
        }
    }
}

impl TrackingParams {
    /// DART's documented defaults (pytools4dart XSD): 20 iterations, albedo threshold 1e-3,
    /// light-propagation threshold 1e-7, extrapolation on, 1000 crossings.
    pub fn dart_default() -> Self {
        Self {
            max_iterations: 20,
            albedo_threshold: 1e-3,
            ray_threshold: 1e-7,
            launch_spacing_m: None,
            launch_target_se: 2e-3,
            max_launch_points: 1 << 22,
            max_auto_subcells: 8,
            extrapolate: true,
            max_crossings: 1000,
            skip_empty: true,
            turbid_subfaces: TurbidSubfaces::Off,
            turbid_exit_grouping: false,
            batch_walk: true,
            kernel_isa: KernelIsa::Best,
            batch_f32: true,
            progress: false,
        }
    }
    /// Fast look: 10 iterations, threshold 1e-2.
    pub fn preview() -> Self {
        Self {
            max_iterations: 10,
            albedo_threshold: 1e-2,
            ray_threshold: 1e-6,
            launch_target_se: 1e-2,
            max_launch_points: 1 << 20,
            max_auto_subcells: 4,
            ..Self::dart_default()
        }
    }
    /// Reference accuracy: 100 iterations, threshold 1e-6, ray threshold 1e-10.
    pub fn reference() -> Self {
        Self {
            max_iterations: 100,
            albedo_threshold: 1e-6,
            ray_threshold: 1e-10,
            launch_target_se: 5e-4,
            max_launch_points: 1 << 24,
            max_auto_subcells: 16,
            ..Self::dart_default()
        }
    }
}

/// Everything the engine reads.
pub struct RadiativeInput<'a> {
    /// Grid geometry.
    pub spec: &'a GridSpec,
    /// Cell contents.
    pub grid: &'a CellGrid,
    /// Facets (absolute coordinates).
    pub facets: &'a [Facet],
    /// Lambertian fractions per facet: (front, back) over tiling directions (same order as
    /// `dirs.tiling()`), or empty to use the renormalised cosine approximation.
    pub facet_fractions: &'a [(Vec<f32>, Vec<f32>)],
    /// Table set of each facet with an RPV/Hapke material (`u32::MAX`: Lambertian); empty when
    /// no facet has one.
    pub facet_brdf: &'a [u32],
    /// Per table set, one BRDF facet table per band (rows: tiling incidences then the sun;
    /// physics.md §5.2–5.3, renormalised to min(1, ρ_DH)).
    pub facet_tables: &'a [Vec<PhaseTable>],
    /// Discrete directions.
    pub dirs: &'a DirectionSet,
    /// Interception slot of each tiling direction (a slot scatters with the phase rows of its
    /// members averaged, see `slot_average_rows`).
    pub sector_of: &'a [u16],
    /// Number of slots for tiling directions.
    pub n_sectors: usize,
    /// Optics per material id.
    pub optics: &'a [TrackOptics],
    /// Image index of each tiling direction (`u32::MAX`: no image).
    pub image_of: &'a [u32],
    /// Image oversampling factor η ≥ 1 (0 is taken as 1): image pixels are (Δx/η, Δy/η) and
    /// escaping fluxes are spread over them (see [`super::images`]).
    pub image_oversampling: u32,
    /// Flat ground material (Lambertian reflectance per band), if the ground is the plane z0.
    pub flat_ground: Option<Vec<f64>>,
    /// Flat ground with a BRDF (RPV, Hapke): one phase table per band for the horizontal
    /// normal (rows: tiling incidences then the sun, renormalised to min(1, ρ_DH); physics.md
    /// §5.2–5.3). When given, `flat_ground` only marks that the plane exists.
    pub ground_brdf: Option<Vec<PhaseTable>>,
    /// Propagation vector of the direct sun beam (downward).
    pub sun: DVec3,
    /// Direct irradiance on a horizontal plane per band, W m⁻² (µm⁻¹).
    pub e_dir: Vec<f64>,
    /// Diffuse sky irradiance on a horizontal plane per band (isotropic sky), W m⁻² (µm⁻¹);
    /// all zero = no sky channels.
    pub e_diff: Vec<f64>,
    /// Parameters.
    pub params: TrackingParams,
    /// Other sources (the seam for thermal emission, atmosphere path radiance, lamps): power
    /// put into (point, direction) pairs and tracked from iteration 1 with the sun and sky.
    pub emitters: &'a [Emission],
}

/// One source ray: `power` (W, per channel: bands, then the sky channels if the run has them)
/// leaves `origin` (inside the grid box) along tiling direction `dir` (or the sun's,
/// `dir = n_dirs`), ignoring facet `skip_facet` (the emitting facet). Counted in the source.
#[derive(Debug, Clone, PartialEq)]
pub struct Emission {
    /// Start point, m.
    pub origin: DVec3,
    /// Tiling direction index (or the number of tiling directions for the sun's).
    pub dir: usize,
    /// Power per channel, W.
    pub power: Vec<f64>,
    /// Facet the ray starts on (not intersected), if any.
    pub skip_facet: Option<u32>,
}

/// What the engine computed; every array is per channel (`n_channels` values per element).
#[derive(Debug, Clone, Default)]
pub struct RadiativeResult {
    /// Channels per element (bands × (1 + sky)).
    pub n_channels: usize,
    /// Bands.
    pub n_bands: usize,
    /// Whether the sky channels exist.
    pub has_sky: bool,
    /// Source power entering the scene per channel, W.
    pub source: Vec<f64>,
    /// Power escaping through the top per tiling direction, `[dir][channel]`, W (extrapolated).
    pub escaped: Vec<f64>,
    /// Orthographic images: `[image][pixel i + n_x·j][channel]` escaped power, W
    /// (extrapolated); pixel grid in `image_grid`.
    pub images: Vec<f64>,
    /// Pixel grid of `images` (η, pixel counts and size).
    pub image_grid: ImageGrid,
    /// Escaped power per iteration (scene total per channel), for convergence reports.
    pub escaped_per_iteration: Vec<Vec<f64>>,
    /// Power absorbed per turbid entry (index of `CellGrid::turbid`), W.
    pub absorbed_turbid: Vec<f64>,
    /// Power intercepted per turbid entry, W.
    pub intercepted_turbid: Vec<f64>,
    /// Power absorbed per facet, W.
    pub absorbed_facet: Vec<f64>,
    /// Power intercepted per facet, W.
    pub intercepted_facet: Vec<f64>,
    /// Power absorbed by the flat ground per column `i + nx·j`, W.
    pub absorbed_ground: Vec<f64>,
    /// Power intercepted by the flat ground per column, W.
    pub intercepted_ground: Vec<f64>,
    /// Power booked as lost (thresholds, crossings, isolated sides, leaks), W.
    pub lost: Vec<f64>,
    /// Power left unscattered when the iterations stopped (zero after extrapolation), W.
    pub remaining: Vec<f64>,
    /// Iterations run (1 = sources only).
    pub iterations: u32,
    /// Geometric ratio used for the extrapolation per channel.
    pub q: Vec<f64>,
    /// True when the albedo threshold was met.
    pub converged: bool,
    /// Rays traced.
    pub rays: u64,
    /// Cell crossings the walks visited (read the cell's contents).
    pub crossings: u64,
    /// Empty cells the walks jumped over without visiting them (empty-space skipping;
    /// `crossings + skipped` is the crossing count of the walk that visits every cell, to
    /// within rays through cell edges and vertices, which count once per axis here).
    pub skipped: u64,
    /// Thread-seconds spent tracking rays, summed over all chunks and iterations: the wall time
    /// of each source chunk's launch loop and of each emitter's loop over its outgoing
    /// directions (ray set-up and `Ctx::trace` calls), measured inside the worker threads.
    /// Excludes the emission products (phase rows × intercepted power), the active-emitter
    /// scan, chunk allocation, merging and extrapolation. Tracking throughput per core is
    /// `crossings / kernel_seconds` (time a worker spends descheduled counts as kernel time).
    pub kernel_seconds: f64,
    /// How the sources were sampled on the top plane.
    pub launch: LaunchPlan,
}

/// Sun and sky launch grids on the top plane (see [`launch_plan`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct LaunchPlan {
    /// Sun launch points along x and y.
    pub sun_n: (usize, usize),
    /// Sky launch points along x and y (per downward direction).
    pub sky_n: (usize, usize),
    /// Sun launch spacing (geometric mean of x and y), m.
    pub sun_spacing_m: f64,
    /// Sky launch spacing, m.
    pub sky_spacing_m: f64,
    /// Unshared facet edge length (outline perimeter of all facets), m.
    pub facet_outline_m: f64,
    /// Predicted standard error of the direct-sun interception by facets, as a fraction of the
    /// sun power (0 without facets).
    pub predicted_se: f64,
    /// True when `max_launch_points` capped the spacing above what the target asked for.
    pub capped: bool,
    /// Sub-cell factor D used for facet and ground scattering points (D³ sub-cells per cell,
    /// D² per ground column).
    pub subcells: u32,
    /// Typical facet size `2 A / L` (area over outline, = the radius of a disk leaf) of the
    /// non-ground facets, m (0 without such facets).
    pub facet_size_m: f64,
}

/// Moves the part of an emission row that a facet would send along directions on its wrong
/// side (`ω·n ≤ 0`: a sector straddling the facet plane whose centre lies behind it) to the
/// front-side direction closest to the mirror image `ω − 2(ω·n)n`. Without it that power would
/// start into the facet and, for one-sided ground facets, leave through the grid bottom as
/// "lost" (−2 % albedo on a 17° RPV slope). Only `eligible` directions receive (the regular
/// sectors: an exact view direction's tiny sector must not collect a large sector's power).
/// The row sum is unchanged.
pub fn remap_wrong_side<T>(row: &mut [T], normal: DVec3, omega: &[DVec3], eligible: &[bool])
where
    T: Copy + Default + PartialEq + std::ops::AddAssign,
{
    for j in 0..row.len().min(omega.len()) {
        if row[j] == T::default() || omega[j].dot(normal) > 0.0 {
            continue;
        }
        let m = omega[j] - 2.0 * omega[j].dot(normal) * normal;
        let best = omega
            .iter()
            .enumerate()
            .filter(|(k, o)| o.dot(normal) > 0.0 && eligible.get(*k).copied().unwrap_or(false))
            .max_by(|a, b| a.1.dot(m).total_cmp(&b.1.dot(m)))
            .map(|(k, _)| k);
        if let Some(k) = best
            && k < row.len()
        {
            let v = row[j];
            row[j] = T::default();
            row[k] += v;
        }
    }
}

/// Total length of the facet edges that no other facet shares: the outline of the opaque
/// shapes as the sun sees them (a leaf made of 12 triangles counts its rim, not its spokes; a
/// closed DEM counts only its border). Edges are matched by their exact vertex coordinates, m.
pub fn facet_outline_m<'a>(facets: impl IntoIterator<Item = &'a Facet>) -> f64 {
    // Ordered map: the boundary lengths are summed in key order, the same on every run (a
    // std HashMap's random seed changed the summation order, hence the last bits of the
    // launch spacing, from run to run).
    use std::collections::BTreeMap;
    let key = |a: DVec3| [a.x.to_bits(), a.y.to_bits(), a.z.to_bits()];
    let mut edges: BTreeMap<([u64; 3], [u64; 3]), (u32, f64)> = BTreeMap::new();
    for f in facets {
        for k in 0..3 {
            let (a, b) = (f.v[k], f.v[(k + 1) % 3]);
            let (ka, kb) = (key(a), key(b));
            let e = if ka <= kb { (ka, kb) } else { (kb, ka) };
            let ent = edges.entry(e).or_insert((0, (a - b).length()));
            ent.0 += 1;
        }
    }
    edges
        .values()
        .filter(|(n, _)| *n == 1)
        .map(|(_, l)| l)
        .sum()
}

/// Chooses the sun and sky launch grids on the top plane of a scene of `size` (m) with cells
/// of `cell` (m).
///
/// The power of each launch ray goes whole to the first facet it meets, so a facet's direct
/// interception is estimated by counting lattice points inside its projection. For a convex
/// shape of perimeter `P` under a lattice of spacing `s` with a random offset, the count error
/// has variance ≈ 0.5 · P / (2π s) points (measured by simulation for circles of radius 0.5–8
/// lattice spacings: 0.34–0.53 R; the lattice-point discrepancy of the circle problem grows
/// like R), i.e. an area variance of `P s³ / (4π)`. Summing over independent facet outlines of
/// total length `L` and dividing by the scene area `A` gives the standard error of the directly
/// intercepted fraction: `SE = sqrt(L s³ / (4π)) / A`. The spacing is the largest one with
/// `SE ≤ target`, never above cell/4 (turbid sampling) and never so small that the sun grid
/// exceeds `max_points` (then `capped`). Sky rays average over the downward directions
/// (`n_sky_dirs` independent lattices), so the sky grid may be coarser by `n_sky_dirs^{1/3}` at
/// the same error, again at most cell/4. A scene-given spacing is used as is for both.
///
/// The same reasoning sets the sub-cell factor D of the scattering points (DART 5 paper §3:
/// one scattering point per facet and sub-cell): a facet or ground column scatters from the
/// barycentre of what it intercepted in each of its D³ (ground: D²) sub-cells, so each
/// scattered direction is sampled by one ray per occupied sub-cell. Shadows and gaps have the
/// size of the facets, so D = ceil(cell / r) with r = 2A/L the typical facet size (area over
/// outline of the non-ground facets: a disk leaf's radius), at least the scene's D, at most
/// `max_auto_subcells`, and reduced until columns × D² ≤ `max_launch_points`.
///
/// Checked in tests/radiative_oracles.rs (black-leaf disk canopy against an independent ray
/// cast: 1.3 cm spacing, error within the predicted SE).
pub fn launch_plan(
    size: (f64, f64),
    cell: (f64, f64),
    facets: &[Facet],
    scene_subcells: u32,
    n_sky_dirs: usize,
    params: &TrackingParams,
) -> LaunchPlan {
    let area = size.0 * size.1;
    let outline = if facets.is_empty() {
        0.0
    } else {
        facet_outline_m(facets)
    };
    let objects = facets.iter().filter(|f| f.kind != FacetKind::Ground);
    let obj_area: f64 = objects
        .clone()
        .map(|f| 0.5 * (f.v[1] - f.v[0]).cross(f.v[2] - f.v[0]).length())
        .sum();
    let obj_outline = facet_outline_m(objects);
    let facet_size_m = if obj_outline > 0.0 {
        2.0 * obj_area / obj_outline
    } else {
        0.0
    };
    let grid_of = |s: f64| {
        (
            ((size.0 / s).round() as usize).max(1),
            ((size.1 / s).round() as usize).max(1),
        )
    };
    let spacing_of = |n: (usize, usize)| ((size.0 / n.0 as f64) * (size.1 / n.1 as f64)).sqrt();
    let se_of = |s: f64| (outline * s.powi(3) / (4.0 * std::f64::consts::PI)).sqrt() / area;
    let quarter = cell.0.min(cell.1) / 4.0;
    let mut capped = false;
    let (sun_s, sky_s) = if let Some(s) = params.launch_spacing_m {
        (s, s)
    } else {
        let target = params.launch_target_se.max(1e-12);
        let mut s = if outline > 0.0 {
            (target * target * area * area * 4.0 * std::f64::consts::PI / outline).cbrt()
        } else {
            f64::INFINITY
        }
        .min(quarter);
        let min_s = (area / params.max_launch_points.max(1) as f64).sqrt();
        if s < min_s {
            s = min_s;
            capped = true;
        }
        let sky = (s * (n_sky_dirs.max(1) as f64).cbrt()).min(quarter).max(s);
        (s, sky)
    };
    let sun_n = grid_of(sun_s);
    let sky_n = grid_of(sky_s);
    let sun_spacing_m = spacing_of(sun_n);
    let mut subcells = scene_subcells.max(1);
    if facet_size_m > 0.0 {
        let columns = (size.0 / cell.0).round().max(1.0) * (size.1 / cell.1).round().max(1.0);
        let mut d = ((cell.0.min(cell.1) / facet_size_m).ceil() as u32)
            .min(params.max_auto_subcells.max(1));
        while d > 1 && columns * (d * d) as f64 > params.max_launch_points as f64 {
            d -= 1;
        }
        subcells = subcells.max(d);
    }
    LaunchPlan {
        subcells,
        facet_size_m,
        sun_n,
        sky_n,
        sun_spacing_m,
        sky_spacing_m: spacing_of(sky_n),
        facet_outline_m: outline,
        predicted_se: se_of(sun_spacing_m),
        capped,
    }
}

/// Emitters (or source rows) are split into this many chunks whatever the thread count, and
/// chunk results are merged in chunk order: deterministic on any number of threads.
const N_CHUNKS: usize = 16;

/// Largest dense per-chunk accumulator, in f64 values (8 MiB); larger grids use hash maps.
const DENSE_LIMIT: usize = 1 << 20;

/// Largest number of turbid sub-faces per face side D (`Subfaces`: 6 D² + 1 stores per cell;
/// larger sub-cell factors are clamped to it).
const MAX_FACE_D: u32 = 8;

/// A segment starting within this fraction of the cell size of a face, pointing into the cell
/// through it, entered through that face (see [`Ctx::entry_store`]).
const FACE_TOL: f64 = 1e-9;

/// Hash map of the per-run bookkeeping ([`KeyAcc`], [`TurRecords`], [`SubPoints`]): small
/// integer keys from the scene itself, so foldhash's fixed-seed fast hasher instead of SipHash
/// (SipHash's `hash_one` + `write` were 34 M instructions, 1.2 % of the Default 100 0.2 bench
/// row). Iteration order is never relied on (records are kept in first-touch order or sorted).
type FastMap<K, V> = std::collections::HashMap<K, V, foldhash::fast::FixedState>;

/// Per-chunk hash-map accumulator of fixed-width records keyed by an index (the turbid
/// accumulators of large grids, see [`TurAcc`]). Accumulation inside a chunk is sequential, so
/// results do not depend on scheduling.
struct KeyAcc {
    width: usize,
    index: FastMap<u64, usize>,
    keys: Vec<u64>,
    data: Vec<f64>,
}

impl KeyAcc {
    fn new(width: usize) -> Self {
        KeyAcc {
            width,
            index: Default::default(),
            keys: Vec::new(),
            data: Vec::new(),
        }
    }

    /// Forgets every record (keeping the allocations).
    fn clear(&mut self) {
        self.index.clear();
        self.keys.clear();
        self.data.clear();
    }

    #[inline(always)]
    fn get(&mut self, key: u64) -> &mut [f64] {
        let w = self.width;
        let (keys, data) = (&mut self.keys, &mut self.data);
        let off = *self.index.entry(key).or_insert_with(|| {
            keys.push(key);
            data.extend(std::iter::repeat_n(0.0, w));
            data.len() - w
        });
        &mut self.data[off..off + w]
    }

    /// Visits every record that was touched, in first-touch order.
    fn for_each(&self, mut f: impl FnMut(u64, &[f64])) {
        for (i, &k) in self.keys.iter().enumerate() {
            f(k, &self.data[i * self.width..(i + 1) * self.width]);
        }
    }
}

/// Per-chunk turbid accumulators: intercepted power per (accumulator index t, incidence slot)
/// and the weighted interception points per (t, point record q < P) (Σw·p_first (3),
/// Σw·p_second (3), Σw), written once per cell crossing. The accumulator index is the turbid
/// entry, or (entry × stores + incident (sub-)face store) with [`TurbidSubfaces`] `Faces` /
/// `Subfaces`; P is 1, or the slot count with `Blend` (points per incidence slot). Dense (small
/// grids, the common case): flat arrays with one first-touch flag per index, checked once per
/// crossing for both records (every power record of an index comes with a points record);
/// records are visited per touched index, slots ascending, skipping all-zero slots. Sparse
/// (large grids): [`KeyAcc`] hash maps.
enum TurAcc {
    Dense {
        ns: usize,
        w: usize,
        np: usize,
        tur: Vec<f64>,
        pts: Vec<f64>,
        /// Points records of the single-precision batched walk (`batch::wide32`), 8 per index:
        /// `[Σ wt p₁, Σ wt p₂, Σ wt, 0]` with p in the frame of the index's cell (its corner
        /// at 0), added to `pts` in scene coordinates at the merge
        /// ([`TurAcc::for_each_pts_local`]); empty when that walk does not run.
        pts_loc: Vec<f64>,
        flag: Vec<bool>,
        touched: Vec<u32>,
    },
    Sparse {
        ns: usize,
        np: usize,
        tur: KeyAcc,
        pts: KeyAcc,
    },
}

/// The dense accumulator's arrays borrowed once (per ray in the lean tracker), with the
/// channel count `w` that may be a compile-time constant there.
struct DenseView<'a> {
    ns: usize,
    w: usize,
    np: usize,
    tur: &'a mut [f64],
    pts: &'a mut [f64],
    flag: &'a mut [bool],
    touched: &'a mut Vec<u32>,
}

impl DenseView<'_> {
    /// One interception by accumulator index `e` from slot `slot`: `pw[ch] · f1 · f2` W per
    /// channel, and the two interception points with weight `wt` into points record `q`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn add(
        &mut self,
        (e, q): (u32, u32),
        slot: u32,
        pw: &[f64],
        f1: f64,
        f2: f64,
        p1: DVec3,
        p2: DVec3,
        wt: f64,
    ) {
        let e = e as usize;
        self.add_power(e, slot, pw, f1, f2);
        let pi = (e * self.np + q as usize) * 7;
        add_points(&mut self.pts[pi..pi + 7], p1, p2, wt);
    }

    /// The power part of a booking: `pw[ch] · f1 · f2` W per channel into (index `e`, `slot`),
    /// and `e` marked touched.
    #[inline(always)]
    fn add_power(&mut self, e: usize, slot: u32, pw: &[f64], f1: f64, f2: f64) {
        if !self.flag[e] {
            self.flag[e] = true;
            self.touched.push(e as u32);
        }
        let w = self.w;
        let s = (e * self.ns + slot as usize) * w;
        for (r, v) in self.tur[s..s + w].iter_mut().zip(pw) {
            *r += v * f1 * f2;
        }
    }

    /// [`DenseView::add`] with `turbid_subfaces: Off` (index = entry, one points record).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn add_entry(
        &mut self,
        e: u32,
        slot: u32,
        pw: &[f64],
        f1: f64,
        f2: f64,
        p1: DVec3,
        p2: DVec3,
        wt: f64,
    ) {
        let e = e as usize;
        self.add_power(e, slot, pw, f1, f2);
        add_points(&mut self.pts[e * 7..e * 7 + 7], p1, p2, wt);
    }
}

impl TurAcc {
    /// The dense arrays borrowed as one [`DenseView`] (`None`: the sparse maps).
    #[inline(always)]
    fn view(&mut self) -> Option<DenseView<'_>> {
        match self {
            TurAcc::Dense {
                ns,
                w,
                np,
                tur,
                pts,
                flag,
                touched,
                ..
            } => Some(DenseView {
                ns: *ns,
                w: *w,
                np: *np,
                tur,
                pts,
                flag,
                touched,
            }),
            TurAcc::Sparse { .. } => None,
        }
    }

    /// [`TurAcc::view`] and the single-precision walk's local points records (empty unless
    /// that walk runs).
    #[cfg(target_arch = "x86_64")]
    fn view_local(&mut self) -> Option<(DenseView<'_>, &mut [f64])> {
        match self {
            TurAcc::Dense {
                ns,
                w,
                np,
                tur,
                pts,
                pts_loc,
                flag,
                touched,
            } => Some((
                DenseView {
                    ns: *ns,
                    w: *w,
                    np: *np,
                    tur,
                    pts,
                    flag,
                    touched,
                },
                pts_loc,
            )),
            TurAcc::Sparse { .. } => None,
        }
    }

    /// Back to the state [`TurAcc::new`] builds: the dense arrays zeroed on the touched
    /// indices (the only ones written), the sparse maps emptied.
    fn reset(&mut self) {
        if let TurAcc::Dense {
            pts_loc, touched, ..
        } = self
            && !pts_loc.is_empty()
        {
            for &e in touched.iter() {
                pts_loc[e as usize * 8..(e as usize + 1) * 8].fill(0.0);
            }
        }
        if let Some(v) = self.view() {
            let (rec, prec) = (v.ns * v.w, v.np * 7);
            for &e in v.touched.iter() {
                let e = e as usize;
                v.tur[e * rec..(e + 1) * rec].fill(0.0);
                v.pts[e * prec..(e + 1) * prec].fill(0.0);
                v.flag[e] = false;
            }
            v.touched.clear();
        } else if let TurAcc::Sparse { tur, pts, .. } = self {
            tur.clear();
            pts.clear();
        }
    }

    /// `n_index` accumulator indices, `ns` slots, `w` channels, `np` points records per index.
    /// `local`: with the records of the single-precision batched walk (dense only).
    fn new(n_index: usize, ns: usize, w: usize, np: usize, local: bool) -> Self {
        if n_index * ns * w <= DENSE_LIMIT && n_index * np * 7 <= DENSE_LIMIT {
            TurAcc::Dense {
                ns,
                w,
                np,
                tur: vec![0.0; n_index * ns * w],
                pts: vec![0.0; n_index * np * 7],
                pts_loc: if local {
                    vec![0.0; n_index * 8]
                } else {
                    Vec::new()
                },
                flag: vec![false; n_index],
                touched: Vec::new(),
            }
        } else {
            TurAcc::Sparse {
                ns,
                np,
                tur: KeyAcc::new(w),
                pts: KeyAcc::new(7),
            }
        }
    }

    /// One interception by accumulator index `eq.0` from slot `slot`: `pw[ch] · f1 · f2` W per
    /// channel, and the two interception points with weight `wt` into points record `eq.1`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn add(
        &mut self,
        eq: (u32, u32),
        slot: u32,
        pw: &[f64],
        f1: f64,
        f2: f64,
        p1: DVec3,
        p2: DVec3,
        wt: f64,
    ) {
        if let Some(mut v) = self.view() {
            return v.add(eq, slot, pw, f1, f2, p1, p2, wt);
        }
        if let TurAcc::Sparse { ns, np, tur, pts } = self {
            let rec = tur.get(eq.0 as u64 * *ns as u64 + slot as u64);
            for (r, v) in rec.iter_mut().zip(pw) {
                *r += v * f1 * f2;
            }
            add_points(pts.get(eq.0 as u64 * *np as u64 + eq.1 as u64), p1, p2, wt);
        }
    }

    /// [`TurAcc::add`] with `turbid_subfaces: Off` (index = entry, one points record).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn add_entry(
        &mut self,
        e: u32,
        slot: u32,
        pw: &[f64],
        f1: f64,
        f2: f64,
        p1: DVec3,
        p2: DVec3,
        wt: f64,
    ) {
        if let Some(mut v) = self.view() {
            return v.add_entry(e, slot, pw, f1, f2, p1, p2, wt);
        }
        if let TurAcc::Sparse { ns, tur, pts, .. } = self {
            let rec = tur.get(e as u64 * *ns as u64 + slot as u64);
            for (r, v) in rec.iter_mut().zip(pw) {
                *r += v * f1 * f2;
            }
            add_points(pts.get(e as u64), p1, p2, wt);
        }
    }

    /// Visits the power records: (`index × ns + slot`, W per channel).
    fn for_each_tur(&self, mut f: impl FnMut(u64, &[f64])) {
        match self {
            TurAcc::Dense {
                ns,
                w,
                tur,
                touched,
                ..
            } => {
                for &e in touched {
                    for slot in 0..*ns {
                        let key = e as usize * *ns + slot;
                        let v = &tur[key * *w..(key + 1) * *w];
                        if v.iter().any(|&x| x != 0.0) {
                            f(key as u64, v);
                        }
                    }
                }
            }
            TurAcc::Sparse { tur, .. } => tur.for_each(f),
        }
    }

    /// Visits the points records: (`index × np + q`, 7 values); with several records per
    /// index, the ones without weight are skipped.
    fn for_each_pts(&self, mut f: impl FnMut(u64, &[f64])) {
        match self {
            TurAcc::Dense {
                np, pts, touched, ..
            } => {
                for &e in touched {
                    for q in 0..*np {
                        let key = e as usize * *np + q;
                        let v = &pts[key * 7..key * 7 + 7];
                        if *np == 1 || v[6] != 0.0 {
                            f(key as u64, v);
                        }
                    }
                }
            }
            TurAcc::Sparse { pts, .. } => pts.for_each(f),
        }
    }

    /// Visits the single-precision walk's points records of the touched indices: (index,
    /// `[Σ wt p₁, Σ wt p₂, Σ wt]` in the index's cell frame); none without that walk.
    fn for_each_pts_local(&self, mut f: impl FnMut(u64, &[f64])) {
        if let TurAcc::Dense {
            pts_loc, touched, ..
        } = self
            && !pts_loc.is_empty()
        {
            for &e in touched {
                let v = &pts_loc[e as usize * 8..e as usize * 8 + 7];
                if v[6] != 0.0 {
                    f(e as u64, v);
                }
            }
        }
    }
}

/// Splits `n` items into at most [`N_CHUNKS`] contiguous ranges.
fn chunk_len(n: usize) -> usize {
    n.div_ceil(N_CHUNKS).max(1)
}

/// Per-chunk results, merged in chunk order.
#[derive(Default)]
struct ChunkOut {
    /// Turbid interceptions and interception points (boxed: taken out for each ray's duration
    /// by moving a pointer).
    tur: Option<Box<TurAcc>>,
    /// Facet events: (facet-ref index, facet id, from_front, sub-cell, slot); values: W
    /// intercepted + hit(3) + weight.
    fac_key: Vec<(u32, u32, bool, u32, u32)>,
    fac_val: Vec<f64>,
    /// Ground events: (column, slot, sub-column); values: W + hit(3) + weight.
    gnd_key: Vec<(u32, u32, u32)>,
    gnd_val: Vec<f64>,
    escaped: Vec<f64>,
    /// Horizontal size (x, y) of the element emitting the ray being traced, m ((0, 0): a
    /// point); set before each [`Ctx::trace`] call, read when the ray escapes.
    foot: (f64, f64),
    /// Image events: image index; exit point projected onto z0 (x, y from the grid origin,
    /// wrapped in repetitive scenes) and footprint (x, y), m; values: W per channel.
    img_key: Vec<u32>,
    img_pos: Vec<[f64; 4]>,
    img_val: Vec<f64>,
    lost: Vec<f64>,
    absorbed_turbid: Vec<(u32, usize)>,
    absorbed_facet: Vec<(u32, usize)>,
    absorbed_ground: Vec<(u32, usize)>,
    absorbed_val: Vec<f64>,
    rays: u64,
    crossings: u64,
    /// Empty cells jumped over (see [`RadiativeResult::skipped`]).
    skipped: u64,
    /// Thread-seconds spent tracking (see [`RadiativeResult::kernel_seconds`]).
    kernel_seconds: f64,
    /// Factor on the ray-power threshold of the ray being traced (1; a turbid incident store's
    /// share of its entry's power while the store emits, see [`emit_turbid_records`]).
    ray_scale: f64,
    /// Rays waiting for the batched walk ([`Ctx::queue`], walked by [`Ctx::flush`] before the
    /// chunk ends).
    queue: Vec<batch::Queued>,
}

impl ChunkOut {
    /// Empties a merged output for another chunk: the state [`new_out`] builds (zeroed sums,
    /// empty event lists, no counts, threshold factor 1), the arrays keeping their allocations.
    /// The dense turbid accumulator is zeroed on its touched entries only (the only ones ever
    /// written, see [`DenseView::add_power`]).
    fn reset(&mut self) {
        // Every field named, so that a new one cannot be forgotten here.
        let ChunkOut {
            tur,
            fac_key,
            fac_val,
            gnd_key,
            gnd_val,
            escaped,
            foot,
            img_key,
            img_pos,
            img_val,
            lost,
            absorbed_turbid,
            absorbed_facet,
            absorbed_ground,
            absorbed_val,
            rays,
            crossings,
            skipped,
            kernel_seconds,
            ray_scale,
            queue,
        } = self;
        if let Some(t) = tur.as_deref_mut() {
            t.reset();
        }
        fac_key.clear();
        fac_val.clear();
        gnd_key.clear();
        gnd_val.clear();
        escaped.fill(0.0);
        *foot = (0.0, 0.0);
        img_key.clear();
        img_pos.clear();
        img_val.clear();
        lost.fill(0.0);
        absorbed_turbid.clear();
        absorbed_facet.clear();
        absorbed_ground.clear();
        absorbed_val.clear();
        (*rays, *crossings, *skipped) = (0, 0, 0);
        *kernel_seconds = 0.0;
        *ray_scale = 1.0;
        queue.clear();
    }
}

/// Mutable per-iteration element stores.
struct Stores {
    /// Turbid: `[entry][slot][channel]` intercepted power.
    tur: Vec<f64>,
    /// Turbid scattering points per entry: up (sum xyz, w), down (sum xyz, w).
    tur_pts: Vec<[f64; 8]>,
    /// Facet refs: `[ref][channel]` reflected-to-front, then transmitted-to-back... stored as
    /// front-side and back-side emitted power.
    fac_front: Vec<f64>,
    fac_back: Vec<f64>,
    /// RPV/Hapke facet refs: `[brdf ref][slot][channel]` intercepted power (scattered and
    /// absorbed at emission).
    fac_slot: Vec<f64>,
    /// Facet-ref scattering points per sub-cell.
    fac_pts: SubPoints,
    /// Flat ground per column.
    gnd: Vec<f64>,
    /// Ground-column scattering points per sub-column.
    gnd_pts: SubPoints,
    /// Turbid stores of the `Faces`, `Subfaces` and `Blend` modes (`tur` and `tur_pts` are
    /// then empty).
    trec: TurRecords,
}

/// Turbid stores of the [`TurbidSubfaces`] `Faces`, `Subfaces` and `Blend` modes, sparse (only
/// the stores that intercepted something exist; entries × 6D²+1 dense stores would not fit
/// large scenes): one record per accumulator index t (entry × stores + incident store, or the
/// entry for `Blend`), created at first touch in merge order (deterministic), with the power
/// `[slot][channel]` (W) and the points `[q][8]` (q < `np`; up Σw·xyz, Σw, down Σw·xyz, Σw;
/// w = intercepted power summed over channels, W). [`TurRecords::finish`] sorts the records by
/// index, so the records of one entry are consecutive, stores ascending.
#[derive(Default)]
struct TurRecords {
    ns_w: usize,
    np: usize,
    index: FastMap<u32, u32>,
    keys: Vec<u32>,
    pow: Vec<f64>,
    pts: Vec<f64>,
    /// After `finish`: record numbers sorted by index.
    order: Vec<u32>,
}

impl TurRecords {
    fn new(ns_w: usize, np: usize) -> Self {
        TurRecords {
            ns_w,
            np,
            ..Default::default()
        }
    }

    /// Record number of index `t` (created when new).
    fn rec(&mut self, t: u32) -> usize {
        let (keys, pow, pts) = (&mut self.keys, &mut self.pow, &mut self.pts);
        let (ns_w, np) = (self.ns_w, self.np);
        *self.index.entry(t).or_insert_with(|| {
            keys.push(t);
            pow.extend(std::iter::repeat_n(0.0, ns_w));
            pts.extend(std::iter::repeat_n(0.0, np * 8));
            keys.len() as u32 - 1
        }) as usize
    }

    fn finish(&mut self) {
        let mut order: Vec<u32> = (0..self.keys.len() as u32).collect();
        order.sort_unstable_by_key(|&r| self.keys[r as usize]);
        self.order = order;
        self.index = Default::default();
    }
}

/// Scattering points of elements (facet refs or ground columns) per sub-cell: Σ w·p and Σ w
/// per (element, sub-cell), w = intercepted power summed over channels, W. Accumulated in
/// merge order (deterministic), then sorted by (element, sub-cell) for the emission.
#[derive(Default)]
struct SubPoints {
    acc: FastMap<(u32, u32), [f64; 4]>,
    /// After `finish`: points of element e are `pts[start[e]..start[e + 1]]`.
    start: Vec<u32>,
    /// After `finish`: (barycentre, share of the element's weight).
    pts: Vec<(DVec3, f64)>,
}

impl SubPoints {
    #[inline]
    fn add(&mut self, elem: u32, sub: u32, p: DVec3, w: f64) {
        let a = self.acc.entry((elem, sub)).or_insert([0.0; 4]);
        a[0] += p.x * w;
        a[1] += p.y * w;
        a[2] += p.z * w;
        a[3] += w;
    }

    /// Sorts the points and turns sums into barycentres and weight shares.
    fn finish(&mut self, n_elem: usize) {
        let mut keys: Vec<(u32, u32)> = self.acc.keys().copied().collect();
        keys.sort_unstable();
        let mut total = vec![0.0; n_elem];
        for k in &keys {
            total[k.0 as usize] += self.acc[k][3];
        }
        self.start = vec![0; n_elem + 1];
        self.pts.clear();
        for k in &keys {
            let a = self.acc[k];
            let t = total[k.0 as usize];
            if a[3] > 0.0 && t > 0.0 {
                self.pts
                    .push((DVec3::new(a[0], a[1], a[2]) / a[3], a[3] / t));
                self.start[k.0 as usize + 1] += 1;
            }
        }
        for e in 0..n_elem {
            self.start[e + 1] += self.start[e];
        }
        self.acc = Default::default();
    }

    /// Points of element `e` (empty: the element has no weighted point).
    fn of(&self, e: usize) -> &[(DVec3, f64)] {
        match self.start.get(e + 1) {
            Some(&end) => &self.pts[self.start[e] as usize..end as usize],
            None => &[],
        }
    }
}

/// A cell as the tracker reads it: its turbid entries `Ctx::ents[ent_lo..ent_hi]` and its
/// facet refs `CellGrid::facet_ids[fac_lo..fac_hi]` (one 16-byte read per crossing).
#[derive(Debug, Clone, Copy, Default)]
struct CellRec {
    ent_lo: u32,
    ent_hi: u32,
    fac_lo: u32,
    fac_hi: u32,
}

/// A turbid entry whose material is tracked: entry index (into `CellGrid::turbid`), turbid
/// material slot, and leaf area volume density u_f (m² m⁻³).
#[derive(Debug, Clone, Copy)]
struct Ent {
    idx: u32,
    tm: u32,
    density: f64,
}

struct Ctx<'a> {
    inp: &'a RadiativeInput<'a>,
    w: usize,
    nb: usize,
    n_dirs: usize,
    n_slots: usize,
    /// Direction vectors (tiling) + sun last.
    omega: Vec<DVec3>,
    /// Turbid material slot per material id (column of `g_dir`), or u32::MAX.
    tur_mat: Vec<u32>,
    /// Number of turbid materials.
    n_tm: usize,
    /// G per (direction incl. sun, turbid material): the row of one direction is contiguous.
    g_dir: Vec<f64>,
    /// What the tracker reads per cell.
    cells: Vec<CellRec>,
    /// Turbid entries with a tracked material, in cell order (see [`CellRec`]).
    ents: Vec<Ent>,
    /// Cell index of each turbid entry.
    entry_cell: Vec<u32>,
    size: (f64, f64),
    /// Ray threshold of a tile of the largest solid angle, W (see
    /// [`TrackingParams::ray_threshold`]); direction j uses `min_ray · ray_factor[j]`.
    min_ray: f64,
    /// `ΔΩ_j / ΔΩ_max` per direction (≤ 1; the sun's entry, last, is 1).
    ray_factor: Vec<f64>,
    /// Phase rows averaged over each interception slot: `[turbid material][band][slot][dir]`.
    slot_rows: Vec<f64>,
    /// BRDF-ground rows averaged over each slot (weights ∫|μ|dΩ): `[band][slot][dir]`.
    ground_rows: Vec<f64>,
    /// Sub-cell factor D of the facet and ground scattering points.
    sub: u32,
    /// Compact index of each RPV/Hapke facet ref (`u32::MAX`: Lambertian facet).
    brdf_ref: Vec<u32>,
    /// Number of RPV/Hapke facet refs.
    n_brdf_refs: usize,
    /// RPV/Hapke facet rows averaged over each slot: `[set][band][slot][dir]`.
    facet_rows: Vec<f64>,
    /// Hotspot correlation per (tiling direction, turbid material): `[b, c]` per unit path
    /// length, see [`hotspot_terms`]; all zero when the direction goes down or the material has
    /// no leaf size.
    hs: Vec<[f64; 2]>,
    /// Whether a first-order sun ray along each tiling direction is hotspot-correlated.
    hs_dir: Vec<bool>,
    /// Pixel grid of the orthographic images.
    image_grid: ImageGrid,
    /// The scene fits [`Ctx::trace_simple`]: no facets, at most one tracked turbid entry per
    /// cell, no topography offset (hotspot rays always take [`Ctx::trace_w`]).
    simple: bool,
    /// Per cell, for [`Ctx::trace_simple`]: its turbid entry (density 0: none).
    scells: Vec<SimpleCell>,
    /// The lean tracker's rays go through the batched walk (see [`TrackingParams::batch_walk`]):
    /// [`Ctx::simple`], `turbid_subfaces: Off` and 1, 2 or 4 channels.
    batch: bool,
    /// Per cell, for [`Ctx::trace_w`]: 0 for a cell with a tracked turbid entry or a facet, 1
    /// for an empty cell crossed one by one, else its chessboard distance r in cells to the
    /// nearest such cell ([`skip_field`]; no r when [`TrackingParams::skip_empty`] is off): a
    /// ray in it jumps over the box of cells within r − 1.
    skip: Vec<u8>,
    /// Turbid interception storage mode.
    subfaces: TurbidSubfaces,
    /// Turbid incident stores per entry: 1 (`Off`, `Blend`), 7 (`Faces`), 6 D² + 1 (`Subfaces`).
    tstores: usize,
    /// Sub-faces per face side D (1 for `Faces`).
    face_d: u32,
    /// Turbid points records per accumulator index: 1, or the slot count (`Blend`).
    pts_per: usize,
    /// Per direction (sun last), what a lane of the batched walk takes at a ray start
    /// ([`batch::LaneDir`]; empty when [`Ctx::batch`] is off).
    lane_dirs: Vec<batch::LaneDir>,
    /// The same for the single-precision 16-lane walk (empty unless it runs:
    /// [`TrackingParams::batch_f32`], AVX-512, a grid of `i32` indices).
    lane_dirs32: Vec<batch::LaneDir32>,
    /// Per cell, for the single-precision walk: [`SimpleCell`] packed into 8 bytes, the
    /// density as `f32` bits (0 for no entry) in the low half, the entry index (empty cell: its
    /// skip distance) in the high half (empty unless that walk runs).
    scells32: Vec<u64>,
    /// Where the walks dispatch ([`TrackingParams::kernel_isa`] on this CPU).
    arch: pulp::Arch,
}

/// Smallest empty-space distance from which the flux-tracking walks jump
/// ([`skip_field`]). Measured (callgrind, forest Preview): from distance 2 the jumps cost 7 %
/// more instructions than they saved, from 3 2.4 %, from 4 they break even.
const MIN_SKIP_DISTANCE: u8 = 4;

/// A cell as [`Ctx::trace_simple`] reads it (16 bytes): leaf area volume density u_f
/// (m² m⁻³, 0 for a cell without tracked turbid entry), turbid material slot (column of the
/// G rows) and entry index (into `CellGrid::turbid`). A cell without entry holds in `tm` its
/// empty-space distance (see [`Ctx::skip`]; no extra read per crossing).
#[derive(Debug, Clone, Copy, Default)]
struct SimpleCell {
    density: f64,
    tm: u32,
    idx: u32,
}

impl Ctx<'_> {
    /// BRDF-ground row of an interception slot (tiling sectors only).
    #[inline]
    fn ground_row(&self, band: usize, slot: usize) -> &[f64] {
        let base = (band * self.n_slots + slot) * self.n_dirs;
        &self.ground_rows[base..base + self.n_dirs]
    }

    /// RPV/Hapke facet row of table set `set` for an interception slot (the sun's included).
    #[inline]
    fn facet_row(&self, set: usize, band: usize, slot: usize) -> &[f64] {
        let base = ((set * self.nb + band) * self.n_slots + slot) * self.n_dirs;
        &self.facet_rows[base..base + self.n_dirs]
    }

    /// Phase row of an interception slot (tiling sectors only).
    #[inline]
    fn slot_row(&self, tm: usize, band: usize, slot: usize) -> &[f64] {
        let n_sec = self.n_slots - 1;
        let base = ((tm * self.nb + band) * n_sec + slot) * self.n_dirs;
        &self.slot_rows[base..base + self.n_dirs]
    }

    /// Sub-cell (of D³) of cell `c` that holds `p`.
    #[inline]
    fn sub_of(&self, c: usize, p: DVec3) -> u32 {
        let [i, j, k] = self.inp.spec.ijk(c);
        self.sub_index(p, [i, j, k], 3)
    }

    /// Sub-cell index of `p` in the cell (or, for `axes = 2`, the ground column) whose integer
    /// position is `ijk`: D per axis along the first `axes` axes.
    #[inline]
    fn sub_index(&self, p: DVec3, ijk: [usize; 3], axes: usize) -> u32 {
        if self.sub == 1 {
            return 0;
        }
        let spec = self.inp.spec;
        let d = self.sub as f64;
        let lo = spec.origin + DVec3::new(ijk[0] as f64, ijk[1] as f64, ijk[2] as f64) * spec.cell;
        let mut idx = 0;
        for a in (0..axes).rev() {
            let s =
                floor_i64((p[a] - lo[a]) / spec.cell[a] * d).clamp(0, self.sub as i64 - 1) as u32;
            idx = idx * self.sub + s;
        }
        idx
    }

    /// Turbid accumulator index and points record of an interception by entry `e` (index into
    /// `CellGrid::turbid`) on a segment that starts at `q0` along `d`, from slot `slot` (see
    /// [`TurAcc`] and [`TurbidSubfaces`]).
    #[inline(always)]
    fn acc_index(&self, e: u32, q0: DVec3, d: DVec3, slot: u32) -> (u32, u32) {
        if self.tstores == 1 {
            return (e, if self.pts_per == 1 { 0 } else { slot });
        }
        let c = self.entry_cell[e as usize] as usize;
        (e * self.tstores as u32 + self.entry_store(c, q0, d), 0)
    }

    /// Incident store of a crossing of cell `c` whose segment starts at `q0` along `d` (see
    /// [`entry_store`]).
    #[inline]
    fn entry_store(&self, c: usize, q0: DVec3, d: DVec3) -> u32 {
        let spec = self.inp.spec;
        let [i, j, k] = spec.ijk(c);
        let lo = spec.origin + DVec3::new(i as f64, j as f64, k as f64) * spec.cell;
        entry_store(lo, spec.cell, q0, d, self.face_d)
    }

    /// Where a ray leaving `o` inside cell `c` along `d` leaves the cell (see [`cell_exit`]).
    fn cell_exit(&self, c: usize, o: DVec3, d: DVec3) -> (f64, DVec3, u32) {
        let spec = self.inp.spec;
        let [i, j, k] = spec.ijk(c);
        let lo = spec.origin + DVec3::new(i as f64, j as f64, k as f64) * spec.cell;
        cell_exit(lo, spec.cell, o, d, self.face_d)
    }

    /// A turbid cell's scattered ray `share × v` (W per channel) from `o` inside cell `c` along
    /// tiling direction `j`, followed to the cell's exit (exact attenuation `e^{−kℓ}`, the
    /// re-intercepted part booked to the cell's inside store with its two interception points,
    /// as the tracker would) and added to the exit group of its exit store and direction (DART
    /// 5 paper §3.2, Figure 7c; traced after the cell's stores are done, see
    /// [`emit_turbid_records`]).
    #[allow(clippy::too_many_arguments)]
    fn to_exit(
        &self,
        c: usize,
        o: DVec3,
        j: usize,
        v: &[f64],
        share: f64,
        sc: &mut ExitGroups,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        let w = self.w;
        let d = self.omega[j];
        for (a, b) in pw.iter_mut().zip(v) {
            *a = b * share;
        }
        let (ell, q, s) = self.cell_exit(c, o, d);
        let cr = self.cells[c];
        let ents = &self.ents[cr.ent_lo as usize..cr.ent_hi as usize];
        let gd = &self.g_dir[j * self.n_tm..(j + 1) * self.n_tm];
        let k: f64 = ents.iter().map(|e| gd[e.tm as usize] * e.density).sum();
        out.crossings += 1;
        if k > 0.0 && ell > 0.0 {
            let x = k * ell;
            let (frac, tr) = attenuation(x);
            let (s1, s2) = HalfBarycentres::get().eval(x, ell);
            let (p1, p2) = (o + d * s1, o + d * s2);
            let psum: f64 = pw.iter().sum();
            let slot = self.slot_of(j) as u32;
            let mut tur = out.tur.take().expect("accumulator");
            for e in ents {
                let sh = gd[e.tm as usize] * e.density / k;
                let eq = self.acc_index(e.idx, o, d, slot);
                tur.add(eq, slot, pw, frac, sh, p1, p2, psum * frac * sh);
            }
            out.tur = Some(tur);
            for x in pw.iter_mut() {
                *x *= tr;
            }
        }
        let psum: f64 = pw.iter().sum();
        if psum <= 0.0 {
            add(&mut out.lost, pw);
            return;
        }
        let g = j * sc.n_exit + s as usize;
        if !sc.flag[g] {
            sc.flag[g] = true;
            sc.touched.push(g as u32);
        }
        let rec = &mut sc.group[g * (w + 4)..(g + 1) * (w + 4)];
        for (r, x) in rec.iter_mut().zip(pw.iter()) {
            *r += x;
        }
        rec[w] += q.x * psum;
        rec[w + 1] += q.y * psum;
        rec[w + 2] += q.z * psum;
        rec[w + 3] += psum;
    }

    fn slot_of(&self, dir: usize) -> usize {
        if dir == self.n_dirs {
            self.n_slots - 1
        } else {
            self.inp.sector_of[dir] as usize
        }
    }

    /// Books power leaving the scene top at `p` along tiling direction `dir`: scene exitance,
    /// and the orthographic image of that direction if it has one (the exit point is projected
    /// along the direction onto the reference plane z0, wrapped in repetitive scenes; the
    /// power is spread over the pixels under the emitting element's footprint `out.foot` at
    /// the merge, see [`super::images`]).
    fn escape(&self, p: DVec3, dir: usize, pw: &[f64], out: &mut ChunkOut) {
        if dir >= self.n_dirs {
            add(&mut out.lost, pw);
            return;
        }
        let base = dir * self.w;
        for (r, v) in out.escaped[base..base + pw.len()].iter_mut().zip(pw) {
            *r += v;
        }
        let img = self.inp.image_of.get(dir).copied().unwrap_or(u32::MAX);
        if img == u32::MAX || self.omega[dir].z <= 0.0 {
            return;
        }
        let spec = self.inp.spec;
        let d = self.omega[dir];
        let mut x = p.x - (p.z - spec.origin.z) * d.x / d.z - spec.origin.x;
        let mut y = p.y - (p.z - spec.origin.z) * d.y / d.z - spec.origin.y;
        if spec.boundary != BoundaryMode::Isolated {
            x = rem_euclid_period(x, self.size.0);
            y = rem_euclid_period(y, self.size.1);
        } else if self.image_grid.misses((x, y), out.foot) {
            return;
        }
        out.img_key.push(img);
        out.img_pos.push([x, y, out.foot.0, out.foot.1]);
        out.img_val.extend_from_slice(pw);
    }

    /// A ray leaving the grid through the bottom at `hp` with powers `pw` (sum `psum`) from
    /// slot `slot`: intercepted by the flat ground (one event per column and sub-column), or
    /// lost when the scene has none.
    fn bottom(&self, hp: DVec3, slot: u32, pw: &[f64], psum: f64, out: &mut ChunkOut) {
        let spec = self.inp.spec;
        if self.inp.flat_ground.is_some() {
            let i = floor_i64((hp.x - spec.origin.x) / spec.cell.x).clamp(0, spec.n[0] as i64 - 1)
                as usize;
            let j = floor_i64((hp.y - spec.origin.y) / spec.cell.y).clamp(0, spec.n[1] as i64 - 1)
                as usize;
            self.bottom_at(i, j, hp, slot, pw, psum, out);
        } else {
            add(&mut out.lost, pw);
        }
    }

    /// [`Ctx::bottom`] of a ray whose ground column (i, j) is known (the single-precision
    /// walk's lane cell): the same booking without locating the column.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn bottom_at(
        &self,
        i: usize,
        j: usize,
        hp: DVec3,
        slot: u32,
        pw: &[f64],
        psum: f64,
        out: &mut ChunkOut,
    ) {
        if self.inp.flat_ground.is_none() {
            return add(&mut out.lost, pw);
        }
        let n0 = self.inp.spec.n[0];
        let sub = self.sub_index(hp, [i, j, 0], 2);
        out.gnd_key.push(((i + n0 * j) as u32, slot, sub));
        out.gnd_val.extend_from_slice(pw);
        out.gnd_val.extend_from_slice(&[hp.x, hp.y, hp.z, psum]);
    }

    /// Lean tracker for the common case (see [`Ctx::simple`]): turbid cells with at most one
    /// tracked entry, no facets, no hotspot, flat top and bottom, repetitive boundaries without
    /// an altitude offset or isolated ones. Same physics and bookkeeping as [`Ctx::trace_w`]
    /// (DART 5 flux tracking, Gastellu-Etchegorry et al. 2015, Remote Sens. 7, 1667–1701, §3:
    /// one exact attenuation `e^{−kℓ}` per crossing, the two interception points per crossing,
    /// the ray dropped below the power threshold; the cells walked by the Amanatides & Woo 1987
    /// DDA of [`super::dda`]), with one 16-byte cell record per crossing
    /// (`k = G_m(Ω) u_m` from the ray's G row), the periodic re-entries done in place
    /// ([`Dda::wrap_sides`]), no facet, hotspot or restart logic, and the dense accumulator's
    /// slices borrowed once per ray.
    fn trace_simple<const W: usize>(
        &self,
        p: DVec3,
        dir: usize,
        pw: &mut [f64],
        tur: &mut TurAcc,
        out: &mut ChunkOut,
    ) {
        let w = if W == 0 { self.w } else { W };
        let slot = self.slot_of(dir) as u32;
        let d = self.omega[dir];
        match tur.view() {
            Some(mut view) => {
                // The channel count as the walk knows it (a constant when W > 0).
                view.w = w;
                if self.subfaces == TurbidSubfaces::Off {
                    // The channel counts with a specialised lean walk (the others: below).
                    match W {
                        1 => return self.walk_lean::<1>(p, dir, pw, &mut view, out),
                        2 => return self.walk_lean::<2>(p, dir, pw, &mut view, out),
                        4 => return self.walk_lean::<4>(p, dir, pw, &mut view, out),
                        _ => {}
                    }
                    self.walk_simple::<W>(p, dir, pw, out, |e, pw, frac, p1, p2, wt, _| {
                        view.add_entry(e, slot, pw, frac, 1.0, p1, p2, wt)
                    });
                    return;
                }
                self.walk_simple::<W>(p, dir, pw, out, |e, pw, frac, p1, p2, wt, q0| {
                    let eq = self.acc_index(e, q0, d, slot);
                    view.add(eq, slot, pw, frac, 1.0, p1, p2, wt)
                });
            }
            None => self.walk_simple::<W>(p, dir, pw, out, |e, pw, frac, p1, p2, wt, q0| {
                let eq = self.acc_index(e, q0, d, slot);
                tur.add(eq, slot, pw, frac, 1.0, p1, p2, wt)
            }),
        }
    }

    /// The walk of [`Ctx::trace_simple`]; `sink(entry, pw, 1 − e^{−kℓ}, p1, p2, weight, q0)`
    /// books each interception (`q0`: the point where the segment starts, m).
    #[inline(always)]
    fn walk_simple<const W: usize>(
        &self,
        p: DVec3,
        dir: usize,
        pw: &mut [f64],
        out: &mut ChunkOut,
        mut sink: impl FnMut(u32, &[f64], f64, DVec3, DVec3, f64, DVec3),
    ) {
        let w = if W == 0 { self.w } else { W };
        let pw = &mut pw[..w];
        let spec = self.inp.spec;
        let d = self.omega[dir];
        let slot = self.slot_of(dir) as u32;
        let n_tm = self.n_tm;
        let gd = &self.g_dir[dir * n_tm..(dir + 1) * n_tm];
        let hb = HalfBarycentres::get();
        let isolated = spec.boundary == BoundaryMode::Isolated;
        let max_crossings = self.inp.params.max_crossings;
        let min_ray = self.min_ray * self.ray_factor[dir] * out.ray_scale;
        let scells = &self.scells[..];
        out.rays += 1;
        let Some(mut dda) = Dda::new(spec, p, d) else {
            add(&mut out.lost, pw);
            return;
        };
        let mut n_cross = 0u64;
        let mut wraps = 0u32;
        let mut psum: f64 = pw.iter().sum();
        // The traversal's origin, kept in a local (changes only at a wrap).
        let mut o = dda.origin();
        let mut n_skip = 0u64;
        loop {
            n_cross += 1;
            let sc = scells[dda.index()];
            let t0 = dda.t;
            let t1 = dda.t_exit();
            let exit = if sc.density > 0.0 {
                if t1 > t0 {
                    let ell = t1 - t0;
                    let k = gd[sc.tm as usize] * sc.density;
                    if k > 0.0 {
                        let x = k * ell;
                        let (frac, tr) = attenuation(x);
                        let (s1, s2) = hb.eval(x, ell);
                        let p1 = o + d * (t0 + s1);
                        let p2 = o + d * (t0 + s2);
                        sink(sc.idx, pw, frac, p1, p2, psum * frac, o + d * t0);
                        for v in pw.iter_mut() {
                            *v *= tr;
                        }
                        psum = pw.iter().sum();
                        if psum < min_ray {
                            add(&mut out.lost, pw);
                            break;
                        }
                    }
                }
                dda.advance_at(t1)
            } else if sc.tm > 1 {
                // Empty cell at distance r = sc.tm: jump over the empty box around it.
                let h = sc.tm as i64 - 1;
                let (e, faces) = dda.skip_to(h, dda.skip_exit(h));
                n_skip += faces - 1;
                e
            } else {
                dda.advance_at(t1)
            };
            match exit {
                Exit::Inside => {}
                Exit::Top => {
                    self.escape(dda.point(dda.t), dir, pw, out);
                    break;
                }
                Exit::Bottom => {
                    self.bottom(dda.point(dda.t), slot, pw, psum, out);
                    break;
                }
                Exit::Side(..) => {
                    if isolated {
                        add(&mut out.lost, pw);
                        break;
                    }
                    wraps += dda.wrap_sides();
                    o = dda.origin();
                    if wraps > max_crossings {
                        add(&mut out.lost, pw);
                        break;
                    }
                }
            }
        }
        out.crossings += n_cross;
        out.skipped += n_skip;
    }

    /// [`Ctx::walk_simple`] with the dense accumulator and `turbid_subfaces: Off` for `W`
    /// channels (1, 2 or 4): the same operations in the same order (products bit-identical),
    /// written so that the per-crossing path stays in registers — the channel powers in a
    /// `[f64; W]`, the traversal stepped by [`Dda::step_at`] (no exit bookkeeping per
    /// crossing), every exit, wrap and skip out of the straight path — and compiled for
    /// AVX2 + FMA where the CPU has them (`pulp` runtime dispatch; the same IEEE operations,
    /// no contraction, so the same bits as the baseline code path).
    fn walk_lean<const W: usize>(
        &self,
        p: DVec3,
        dir: usize,
        pw_io: &mut [f64],
        view: &mut DenseView,
        out: &mut ChunkOut,
    ) {
        /// The walk's arguments, run by `pulp` in the best instruction set it detects.
        struct Walk<'c, 'v, 'o, 'x, const W: usize> {
            ctx: &'c Ctx<'x>,
            p: DVec3,
            dir: usize,
            pw: &'o mut [f64],
            view: &'o mut DenseView<'v>,
            out: &'o mut ChunkOut,
        }
        impl<const W: usize> pulp::WithSimd for Walk<'_, '_, '_, '_, W> {
            type Output = ();
            #[inline(always)]
            fn with_simd<S: pulp::Simd>(self, _simd: S) {
                // One tracked turbid material (the common case): its G hoisted out of the walk.
                if self.ctx.n_tm == 1 {
                    self.ctx
                        .walk_lean_body::<W, true>(self.p, self.dir, self.pw, self.view, self.out)
                } else {
                    self.ctx
                        .walk_lean_body::<W, false>(self.p, self.dir, self.pw, self.view, self.out)
                }
            }
        }
        self.arch.dispatch(Walk::<W> {
            ctx: self,
            p,
            dir,
            pw: pw_io,
            view,
            out,
        })
    }

    /// The body of [`Ctx::walk_lean`] (inlined into each instruction-set copy); `ONE_TM`: the
    /// scene has one tracked turbid material (every turbid cell's `tm` is 0).
    #[inline(always)]
    fn walk_lean_body<const W: usize, const ONE_TM: bool>(
        &self,
        p: DVec3,
        dir: usize,
        pw_io: &mut [f64],
        view: &mut DenseView,
        out: &mut ChunkOut,
    ) {
        let mut pw = [0.0; W];
        pw.copy_from_slice(&pw_io[..W]);
        let spec = self.inp.spec;
        let d = self.omega[dir];
        let slot = self.slot_of(dir);
        let n_tm = self.n_tm;
        let gd = &self.g_dir[dir * n_tm..(dir + 1) * n_tm];
        // Read only when `ONE_TM` (a scene may have no tracked turbid material at all).
        let g0 = gd.first().copied().unwrap_or(0.0);
        let hb = HalfBarycentres::get();
        let isolated = spec.boundary == BoundaryMode::Isolated;
        let max_crossings = self.inp.params.max_crossings;
        let min_ray = self.min_ray * self.ray_factor[dir] * out.ray_scale;
        let scells = &self.scells[..];
        let ns = view.ns;
        let tur = &mut *view.tur;
        let pts = &mut *view.pts;
        let flag = &mut *view.flag;
        let touched = &mut *view.touched;
        out.rays += 1;
        let Some(mut dda) = Dda::new(spec, p, d) else {
            add(&mut out.lost, &pw);
            return;
        };
        let mut n_cross = 0u64;
        let mut wraps = 0u32;
        let mut psum: f64 = pw.iter().sum();
        // The traversal's origin, kept in a local (changes only at a wrap).
        let mut o = dda.origin();
        let mut n_skip = 0u64;
        loop {
            n_cross += 1;
            let sc = scells[dda.index()];
            let t0 = dda.t;
            let t1 = dda.t_exit();
            let inside = if sc.density > 0.0 {
                if t1 > t0 {
                    let ell = t1 - t0;
                    let g = if ONE_TM { g0 } else { gd[sc.tm as usize] };
                    let k = g * sc.density;
                    if k > 0.0 {
                        let x = k * ell;
                        let (frac, tr) = attenuation(x);
                        let (s1, s2) = hb.eval(x, ell);
                        let p1 = o + d * (t0 + s1);
                        let p2 = o + d * (t0 + s2);
                        let wt = psum * frac;
                        let e = sc.idx as usize;
                        if !flag[e] {
                            flag[e] = true;
                            touched.push(e as u32);
                        }
                        let s = (e * ns + slot) * W;
                        let r: &mut [f64; W] = (&mut tur[s..s + W]).try_into().expect("W");
                        for c in 0..W {
                            r[c] += pw[c] * frac;
                        }
                        let q: &mut [f64; 7] = (&mut pts[e * 7..e * 7 + 7]).try_into().expect("7");
                        q[0] += p1.x * wt;
                        q[1] += p1.y * wt;
                        q[2] += p1.z * wt;
                        q[3] += p2.x * wt;
                        q[4] += p2.y * wt;
                        q[5] += p2.z * wt;
                        q[6] += wt;
                        for v in pw.iter_mut() {
                            *v *= tr;
                        }
                        psum = pw.iter().sum();
                        if psum < min_ray {
                            add(&mut out.lost, &pw);
                            break;
                        }
                    }
                }
                dda.step_at(t1)
            } else if sc.tm > 1 {
                // Empty cell at distance r = sc.tm: jump over the empty box around it.
                let h = sc.tm as i64 - 1;
                let (e, faces) = dda.skip_to(h, dda.skip_exit(h));
                n_skip += faces - 1;
                e == Exit::Inside
            } else {
                dda.step_at(t1)
            };
            if inside {
                continue;
            }
            match dda.exit_kind() {
                Exit::Inside => {}
                Exit::Top => {
                    self.escape(dda.point(dda.t), dir, &pw, out);
                    break;
                }
                Exit::Bottom => {
                    self.bottom(dda.point(dda.t), slot as u32, &pw, psum, out);
                    break;
                }
                Exit::Side(..) => {
                    if isolated {
                        add(&mut out.lost, &pw);
                        break;
                    }
                    wraps += dda.wrap_sides();
                    o = dda.origin();
                    if wraps > max_crossings {
                        add(&mut out.lost, &pw);
                        break;
                    }
                }
            }
        }
        pw_io[..W].copy_from_slice(&pw);
        out.crossings += n_cross;
        out.skipped += n_skip;
    }

    /// Traces one ray; `pw` holds the channel powers and is consumed.
    fn trace(
        &self,
        p: DVec3,
        dir: usize,
        skip_facet: Option<u32>,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        self.trace_any::<false>(p, dir, skip_facet, pw, out);
    }

    /// [`Ctx::trace`] for a first-order sun ray leaving its scattering point `p` along an
    /// upward direction: turbid extinction gets the hotspot correlation of [`hotspot_terms`]
    /// (the ray goes back through the gaps the sun came through).
    fn trace_hotspot(
        &self,
        p: DVec3,
        dir: usize,
        skip_facet: Option<u32>,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        self.trace_any::<true>(p, dir, skip_facet, pw, out);
    }

    /// Dispatches to a copy of the tracker specialised for the channel count (1, 2 or 4
    /// channels: loops over channels unrolled), with the turbid accumulators taken out of `out`
    /// for the ray's duration.
    fn trace_any<const HS: bool>(
        &self,
        p: DVec3,
        dir: usize,
        skip_facet: Option<u32>,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        if !HS && self.batch && matches!(out.tur.as_deref(), Some(TurAcc::Dense { .. })) {
            self.queue(p, dir, pw, out);
            return;
        }
        let mut tur = out.tur.take().expect("accumulator");
        let simple = !HS && self.simple;
        match (self.w, simple) {
            (1, true) => self.trace_simple::<1>(p, dir, pw, &mut tur, out),
            (2, true) => self.trace_simple::<2>(p, dir, pw, &mut tur, out),
            (4, true) => self.trace_simple::<4>(p, dir, pw, &mut tur, out),
            (_, true) => self.trace_simple::<0>(p, dir, pw, &mut tur, out),
            (1, false) => self.trace_w::<1, HS>(p, dir, skip_facet, pw, &mut tur, out),
            (2, false) => self.trace_w::<2, HS>(p, dir, skip_facet, pw, &mut tur, out),
            (4, false) => self.trace_w::<4, HS>(p, dir, skip_facet, pw, &mut tur, out),
            _ => self.trace_w::<0, HS>(p, dir, skip_facet, pw, &mut tur, out),
        }
        out.tur = Some(tur);
    }

    /// [`Ctx::trace`] for `W` channels (`W = 0`: any count, read from `self.w`); `HS`: with the
    /// hotspot correlation of a first-order sun ray (see [`Ctx::trace_hotspot`]).
    ///
    /// Per crossing: one [`CellRec`] read; the facet loop only in cells with facets; the turbid
    /// extinction `k = Σ_m G_m(Ω) u_m` from the ray's row of G per material; cells with one
    /// entry skip the share computation (share = 1 exactly); the channel sum of `pw` is carried
    /// from one crossing to the next instead of being recomputed.
    #[allow(clippy::too_many_arguments)]
    fn trace_w<const W: usize, const HS: bool>(
        &self,
        mut p: DVec3,
        dir: usize,
        mut skip_facet: Option<u32>,
        pw: &mut [f64],
        tur: &mut TurAcc,
        out: &mut ChunkOut,
    ) {
        let w = if W == 0 { self.w } else { W };
        let pw = &mut pw[..w];
        let spec = self.inp.spec;
        let grid = self.inp.grid;
        let d = self.omega[dir];
        let slot = self.slot_of(dir) as u32;
        let n_tm = self.n_tm;
        // G of every turbid material along this direction.
        let gd = &self.g_dir[dir * n_tm..(dir + 1) * n_tm];
        let hsv: &[[f64; 2]] = if HS {
            &self.hs[dir * n_tm..(dir + 1) * n_tm]
        } else {
            &[]
        };
        let min_ray = self.min_ray * self.ray_factor[dir] * out.ray_scale;
        let off = self.subfaces == TurbidSubfaces::Off;
        let t_tol = spec.hit_tolerance();
        // Distance travelled from the ray's origin to the current restart point, m.
        let mut s_base = 0.0;
        let hb = HalfBarycentres::get();
        // Repetitive boundary without altitude offset: re-entries move the DDA in place.
        let wrap_in_place =
            spec.boundary != BoundaryMode::Isolated && spec.topography_offset == (0.0, 0.0);
        out.rays += 1;
        let mut n_cross = 0u64;
        let mut n_skip = 0u64;
        let mut crossings = 0u32;
        'restart: loop {
            let Some(mut dda) = Dda::new_inline(spec, p, d) else {
                // Started outside the grid (numerical edge): book as lost.
                add(&mut out.lost, pw);
                break 'restart;
            };
            // Σ pw, kept equal to `pw.iter().sum()` whenever `pw` changes.
            let mut psum: f64 = pw.iter().sum();
            loop {
                n_cross += 1;
                let c = dda.index();
                let cr = self.cells[c];
                let t0 = dda.t;
                let mut t1 = dda.t_exit();
                // How the cell is left (a jump from an empty cell, else one advance).
                let exit = 'cell: {
                    // Facets in this cell: nearest hit inside the segment.
                    let mut hit: Option<(u32, u32, f64)> = None;
                    if cr.fac_lo != cr.fac_hi {
                        let o = dda.point(0.0);
                        for r in cr.fac_lo as usize..cr.fac_hi as usize {
                            let f = grid.facet_ids[r];
                            if Some(f) == skip_facet {
                                continue;
                            }
                            let fa = &self.inp.facets[f as usize];
                            if let Some(t) = intersect(&fa.v, o, d)
                                && t >= t0 - t_tol
                                && t <= t1 + t_tol
                                && hit.is_none_or(|h| t < h.2)
                            {
                                let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]);
                                let front = n.dot(d) < 0.0;
                                if front || fa.two_sided {
                                    hit = Some((r as u32, f, t));
                                }
                            }
                        }
                        if let Some((_, _, th)) = hit {
                            t1 = th.max(t0);
                        }
                    }
                    // Turbid attenuation over [t0, t1].
                    if cr.ent_lo == cr.ent_hi {
                        // An empty cell (no turbid entry, no facet: nothing for the facet, turbid
                        // or hotspot bookkeeping) at distance r ≥ 2: jump over the empty box
                        // around it (tested here, where the walk already knows the cell has no
                        // turbid entry: no extra test in the other cells).
                        if cr.fac_lo == cr.fac_hi {
                            let r = self.skip[c];
                            if r > 1 {
                                let h = r as i64 - 1;
                                let (e, faces) = dda.skip_to(h, dda.skip_exit(h));
                                n_skip += faces - 1;
                                break 'cell e;
                            }
                        }
                    } else if t1 > t0 {
                        let ell = t1 - t0;
                        let ents = &self.ents[cr.ent_lo as usize..cr.ent_hi as usize];
                        // Distance of the segment from the ray's origin, m.
                        let s0 = if HS { s_base + t0 } else { 0.0 };
                        // Extinction coefficient of one entry along this segment, m⁻¹.
                        let k_of = |e: &Ent| -> f64 {
                            let g = gd[e.tm as usize];
                            if HS {
                                let [b, c] = hsv[e.tm as usize];
                                if b > 0.0 {
                                    let corr = b * hotspot_integral(c, s0, ell) / ell;
                                    return e.density * (g - corr).max(0.0);
                                }
                            }
                            g * e.density
                        };
                        let mut k = 0.0;
                        for e in ents {
                            k += k_of(e);
                        }
                        if k > 0.0 {
                            let x = k * ell;
                            // (1 − e^{−kℓ}, e^{−kℓ})
                            let (frac, tr) = attenuation(x);
                            // Interception points: barycentres of the two halves of the intercepted
                            // energy.
                            let (s1, s2) = hb.eval(x, ell);
                            let p1 = dda.point(t0 + s1);
                            let p2 = dda.point(t0 + s2);
                            let wsum = psum * frac;
                            if off {
                                if let [e] = ents {
                                    // One material: share = k/k = 1 exactly.
                                    tur.add_entry(e.idx, slot, pw, frac, 1.0, p1, p2, wsum);
                                } else {
                                    for e in ents {
                                        let share = k_of(e) / k;
                                        tur.add_entry(
                                            e.idx,
                                            slot,
                                            pw,
                                            frac,
                                            share,
                                            p1,
                                            p2,
                                            wsum * share,
                                        );
                                    }
                                }
                            } else {
                                // Incident (sub-)face stores, or per-slot points.
                                let q0 = dda.point(t0);
                                for e in ents {
                                    let share = if ents.len() == 1 { 1.0 } else { k_of(e) / k };
                                    let eq = self.acc_index(e.idx, q0, d, slot);
                                    tur.add(eq, slot, pw, frac, share, p1, p2, wsum * share);
                                }
                            }
                            for v in pw.iter_mut() {
                                *v *= tr;
                            }
                            psum = pw.iter().sum();
                            if psum < min_ray {
                                add(&mut out.lost, pw);
                                break 'restart;
                            }
                        }
                    }
                    if let Some((r, f, th)) = hit {
                        let fa = &self.inp.facets[f as usize];
                        let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize();
                        let mu = n.dot(d).abs().max(1e-6);
                        let from_front = n.dot(d) < 0.0;
                        let hp = dda.point(th);
                        let t_dir = match &self.inp.optics[fa.material as usize] {
                            TrackOptics::Lambert { t_dir, .. } => Some(t_dir),
                            _ => None,
                        };
                        let mut any_direct = false;
                        out.fac_key
                            .push((r, f, from_front, self.sub_of(c, hp), slot));
                        for (ch, v) in pw.iter_mut().enumerate() {
                            let td = t_dir.map_or(0.0, |t| t[ch % self.nb]);
                            let through = if td > 0.0 { td.powf(1.0 / mu) } else { 0.0 };
                            out.fac_val.push(*v * (1.0 - through));
                            *v *= through;
                            any_direct |= *v > 0.0;
                        }
                        out.fac_val.extend_from_slice(&[hp.x, hp.y, hp.z, psum]);
                        if !any_direct || pw.iter().sum::<f64>() < min_ray {
                            add(&mut out.lost, pw);
                            break 'restart;
                        }
                        // Directly transmitted part continues from the hit point.
                        s_base += th;
                        p = hp;
                        skip_facet = Some(f);
                        continue 'restart;
                    }
                    dda.advance()
                };
                match exit {
                    Exit::Inside => {}
                    Exit::Top => {
                        self.escape(dda.point(dda.t), dir, pw, out);
                        break 'restart;
                    }
                    Exit::Bottom => {
                        self.bottom(dda.point(dda.t), slot, pw, psum, out);
                        break 'restart;
                    }
                    Exit::Side(axis, s) => {
                        if spec.boundary == BoundaryMode::Isolated {
                            add(&mut out.lost, pw);
                            break 'restart;
                        }
                        if wrap_in_place {
                            crossings += dda.wrap_sides();
                            if crossings > self.inp.params.max_crossings {
                                add(&mut out.lost, pw);
                                break 'restart;
                            }
                            // The facet skipped at the start is in another tile now.
                            skip_facet = None;
                            continue;
                        }
                        crossings += 1;
                        if crossings > self.inp.params.max_crossings {
                            add(&mut out.lost, pw);
                            break 'restart;
                        }
                        s_base += dda.t;
                        let mut q = dda.point(dda.t);
                        let (len, off) = if axis == 0 {
                            (self.size.0, spec.topography_offset.0)
                        } else {
                            (self.size.1, spec.topography_offset.1)
                        };
                        // Leaving through +x re-enters at x = 0 where the ground is `off` lower.
                        q[axis] -= s as f64 * len;
                        q.z -= s as f64 * off;
                        q[axis] = if s > 0 {
                            spec.origin[axis]
                        } else {
                            spec.origin[axis] + len
                        };
                        if q.z > spec.top() && d.z >= 0.0 {
                            self.escape(q, dir, pw, out);
                            break 'restart;
                        }
                        // Continuous topography: re-entering above the neighbouring tile's top
                        // while going down — march through the empty air of the repeated tiles
                        // (each side crossing shifts the altitude) until the ray reaches the top
                        // plane or comes back inside the box.
                        while q.z > spec.top() {
                            let t_top = (spec.top() - q.z) / d.z;
                            let mut side: Option<(usize, i64, f64)> = None;
                            for a in 0..2 {
                                let len = if a == 0 { self.size.0 } else { self.size.1 };
                                let t = if d[a] > 0.0 {
                                    (spec.origin[a] + len - q[a]) / d[a]
                                } else if d[a] < 0.0 {
                                    (spec.origin[a] - q[a]) / d[a]
                                } else {
                                    f64::INFINITY
                                };
                                if side.is_none_or(|s| t < s.2) {
                                    side = Some((a, if d[a] > 0.0 { 1 } else { -1 }, t));
                                }
                            }
                            match side {
                                Some((a, s, t)) if t < t_top => {
                                    crossings += 1;
                                    if crossings > self.inp.params.max_crossings {
                                        // Descending more slowly than the terrain: it goes
                                        // down the slope forever without meeting it again —
                                        // it has left the scene (a downward escape).
                                        self.escape(q, dir, pw, out);
                                        break 'restart;
                                    }
                                    q += d * t.max(0.0);
                                    s_base += t.max(0.0);
                                    let (len, off) = if a == 0 {
                                        (self.size.0, spec.topography_offset.0)
                                    } else {
                                        (self.size.1, spec.topography_offset.1)
                                    };
                                    let _ = len;
                                    q.z -= s as f64 * off;
                                    q[a] = if s > 0 {
                                        spec.origin[a]
                                    } else {
                                        spec.origin[a] + len
                                    };
                                }
                                _ => {
                                    q += d * t_top;
                                    s_base += t_top;
                                    q.z = spec.top();
                                }
                            }
                        }
                        if q.z < spec.origin.z {
                            add(&mut out.lost, pw);
                            break 'restart;
                        }
                        p = q;
                        skip_facet = None;
                        continue 'restart;
                    }
                }
            }
        }
        out.crossings += n_cross;
        out.skipped += n_skip;
    }
}

/// Incident store of a crossing of the cell `[lo, lo + cell]` whose segment starts at `q0`
/// along `d`, with D = `dd` sub-faces per face side (DART 5 paper §3.2, Figure 7: turbid
/// interception is stored per incident cell sub-face). 0: the ray started inside the cell
/// (scattered from a point of this cell, or restarted on a facet of it); else
/// `1 + face · D² + sub-face`, face `2a + [d_a < 0]` for the face of axis a the ray enters
/// through (0 −x, 1 +x, 2 −y, 3 +y, 4 bottom, 5 top), sub-face `i·D + j` over the face's two
/// other axes in increasing order. Rules: the segment's start lies on a face when within
/// `FACE_TOL` cell sizes of it and the ray points into the cell through it; a start on an
/// edge or a vertex (several such faces) is booked to the face the ray crosses most squarely,
/// the largest |d_a| (ties: the higher axis, so z before y before x); a start on a sub-face
/// boundary goes to the sub-face given by the floor of its position (clamped into 0..D). Sun
/// and sky rays start on the scene top plane: the top face of the top cell, sub-face from the
/// launch point (x, y).
pub fn entry_store(lo: DVec3, cell: DVec3, q0: DVec3, d: DVec3, dd: u32) -> u32 {
    let rel = (q0 - lo) / cell;
    let mut best: Option<(usize, f64)> = None;
    for a in 0..3 {
        let on = if d[a] > 0.0 {
            rel[a] <= FACE_TOL
        } else if d[a] < 0.0 {
            rel[a] >= 1.0 - FACE_TOL
        } else {
            false
        };
        if on && best.is_none_or(|(_, m)| d[a].abs() >= m) {
            best = Some((a, d[a].abs()));
        }
    }
    let Some((a, _)) = best else {
        return 0;
    };
    let face = 2 * a as u32 + (d[a] < 0.0) as u32;
    1 + face * dd * dd + sub_face(rel, a, dd)
}

/// Sub-face `i·D + j` of the point at relative position `rel` (in cell sizes) on a face of
/// axis `a`: i, j = ⌊D · rel⌋ over the two other axes in increasing order, clamped into 0..D.
fn sub_face(rel: DVec3, a: usize, dd: u32) -> u32 {
    let (b0, b1) = match a {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let cell_of = |x: f64| floor_i64(x * dd as f64).clamp(0, dd as i64 - 1) as u32;
    cell_of(rel[b0]) * dd + cell_of(rel[b1])
}

/// Where a ray leaving `o` (inside the cell `[lo, lo + cell]`) along `d` leaves the cell:
/// (distance ℓ, m; exit point, on the exit face; exit store `1 + face · D² + sub-face` with the
/// numbering of [`entry_store`], face `2a + [d_a > 0]`). An exit through an edge or a vertex
/// (exit distances equal within `FACE_TOL` cell sizes) goes to the face with the largest
/// |d_a|, ties to the higher axis, and the exit point is put exactly on every plane it
/// reaches (so the tracker starts the merged ray in the diagonal neighbour).
pub fn cell_exit(lo: DVec3, cell: DVec3, o: DVec3, d: DVec3, dd: u32) -> (f64, DVec3, u32) {
    let plane = |a: usize| lo[a] + if d[a] > 0.0 { cell[a] } else { 0.0 };
    let t_of = |a: usize| {
        if d[a] == 0.0 {
            f64::INFINITY
        } else {
            ((plane(a) - o[a]) / d[a]).max(0.0)
        }
    };
    let t = [t_of(0), t_of(1), t_of(2)];
    let t_min = t[0].min(t[1]).min(t[2]);
    let tied = |a: usize| t[a] <= t_min + FACE_TOL * cell[a] / d[a].abs().max(1e-300);
    let mut best = 2;
    let mut m = -1.0;
    for a in 0..3 {
        if tied(a) && d[a].abs() >= m {
            best = a;
            m = d[a].abs();
        }
    }
    let mut q = o + d * t_min;
    for a in 0..3 {
        if tied(a) {
            q[a] = plane(a);
        }
    }
    let face = 2 * best as u32 + (d[best] > 0.0) as u32;
    (
        t_min,
        q,
        1 + face * dd * dd + sub_face((q - lo) / cell, best, dd),
    )
}

/// Adds one interception's weighted points to a points record: Σw·p_first (3),
/// Σw·p_second (3), Σw.
#[inline(always)]
fn add_points(pr: &mut [f64], p1: DVec3, p2: DVec3, wt: f64) {
    let pr = &mut pr[..7];
    pr[0] += p1.x * wt;
    pr[1] += p1.y * wt;
    pr[2] += p1.z * wt;
    pr[3] += p2.x * wt;
    pr[4] += p2.y * wt;
    pr[5] += p2.z * wt;
    pr[6] += wt;
}

/// `[slot][dir]` rows: the table rows of each slot's member directions averaged with `weights`.
fn slot_average_rows(
    table: &PhaseTable,
    weights: &[f64],
    sector_of: &[u16],
    n_sec: usize,
    n_dirs: usize,
) -> Vec<f64> {
    let mut rows = vec![0.0; n_sec * n_dirs];
    let mut wsum = vec![0.0; n_sec];
    for (i, &wt) in weights.iter().enumerate() {
        let s = sector_of[i] as usize;
        wsum[s] += wt;
        for (j, v) in table.row(i).iter().take(n_dirs).enumerate() {
            rows[s * n_dirs + j] += wt * *v as f64;
        }
    }
    for (s, ws) in wsum.iter().enumerate() {
        if *ws > 0.0 {
            rows[s * n_dirs..(s + 1) * n_dirs]
                .iter_mut()
                .for_each(|v| *v /= ws);
        }
    }
    rows
}

#[inline]
fn add(acc: &mut [f64], v: &[f64]) {
    for (a, b) in acc.iter_mut().zip(v) {
        *a += b;
    }
}

/// Distances from the entry of the barycentres of the first and second halves of the energy
/// intercepted along a segment of length ℓ with extinction k (physics.md §3.6 \[rec\]); the split
/// point is `s½ = −ln((1 + e^{−kℓ})/2)/k`. Series for small kℓ.
pub fn half_barycentres(k: f64, ell: f64) -> (f64, f64) {
    let x = k * ell;
    half_barycentres_with(k, ell, (-x).exp(), -(-x).exp_m1())
}

/// Tabulated [`half_barycentres`] (the tracker's hot path: no logarithm per crossing), see
/// [`HalfBarycentres::eval`] (within 1e-8 ℓ of the closed form).
#[inline]
pub fn half_barycentres_fast(k: f64, ell: f64) -> (f64, f64) {
    HalfBarycentres::get().eval(k * ell, ell)
}

/// [`half_barycentres`] given `e = e^{−kℓ}` and `f = 1 − e` (computed once by the tracker).
/// With `h = e^{−k s½} = (1 + e)/2`, the means of s under the density k e^{−ks} are
/// `s̄₁ = 1/k − s½ h/(1 − h)` on [0, s½] and `s̄₂ = 1/k + (s½ h − ℓ e)/(h − e)` on [s½, ℓ],
/// with `1 − h = h − e = f/2`. Series for small kℓ: `ℓ(1/4 − kℓ/12)` and `ℓ(3/4 − kℓ/12)`.
#[inline]
pub fn half_barycentres_with(k: f64, ell: f64, e: f64, f: f64) -> (f64, f64) {
    let x = k * ell;
    if x < 1e-4 {
        return (ell * (0.25 - x / 12.0), ell * (0.75 - x / 12.0));
    }
    let h = 0.5 * (1.0 + e);
    // ln h = ln(1 − f/2) without the rounding of h (kℓ → 0: s½ ≈ ℓ/2 to full precision).
    let s_half = -(-0.5 * f).ln_1p() / k;
    let den = 0.5 * f;
    let inv_k = 1.0 / k;
    (
        (inv_k - s_half * h / den).clamp(0.0, s_half),
        (inv_k + (s_half * h - ell * e) / den).clamp(s_half, ell),
    )
}

/// Distance from the entry of the barycentre of the energy intercepted along a segment of
/// length ℓ with extinction k: `s̄ = 1/k − ℓ e^{−kℓ}/(1 − e^{−kℓ})` (physics.md §3.6), with the
/// series `ℓ/2 − kℓ²/12` for small kℓ.
pub fn barycentre(k: f64, ell: f64) -> f64 {
    let x = k * ell;
    if x < 1e-4 {
        return ell * (0.5 - x / 12.0);
    }
    if x > 700.0 {
        return 1.0 / k;
    }
    1.0 / k - ell * (-x).exp() / (-(-x).exp_m1())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3], kind: FacetKind) -> Facet {
        Facet {
            v: [DVec3::from(a), DVec3::from(b), DVec3::from(c)],
            material: 0,
            object: 0,
            kind,
            two_sided: true,
        }
    }

    /// A square of two triangles has an outline of 4 sides; a 12-triangle fan disk has the
    /// 12-gon's perimeter (spokes are shared); a DEM of two squares counts only its border.
    #[test]
    fn facet_outline_counts_unshared_edges() {
        let sq = [
            tri([0., 0., 1.], [1., 0., 1.], [1., 1., 1.], FacetKind::Mesh),
            tri([0., 0., 1.], [1., 1., 1.], [0., 1., 1.], FacetKind::Mesh),
        ];
        assert!((facet_outline_m(&sq) - 4.0).abs() < 1e-12);
        let n = 12;
        let r = 0.05;
        let p = |k: usize| {
            let a = 2.0 * std::f64::consts::PI * (k % n) as f64 / n as f64;
            [r * a.cos(), r * a.sin(), 0.5]
        };
        let fan: Vec<Facet> = (0..n)
            .map(|k| tri([0., 0., 0.5], p(k), p(k + 1), FacetKind::Mesh))
            .collect();
        let per = 2.0 * n as f64 * r * (std::f64::consts::PI / n as f64).sin();
        assert!((facet_outline_m(&fan) - per).abs() < 1e-12);
    }

    /// The outline is the same to the last bit on every call (it sets the launch spacing, so
    /// a run-to-run difference would change the products): 300 separate triangles with
    /// irrational side lengths, whose sum depends on the summation order.
    #[test]
    fn facet_outline_is_the_same_on_every_call() {
        let tris: Vec<Facet> = (0..300)
            .map(|k| {
                let (x, s) = (k as f64 * 1.7, 0.1 + (k as f64 * 0.37).sin().abs());
                tri(
                    [x, 0., 1.],
                    [x + s, 0.3 * s, 1.],
                    [x + 0.2, s * 1.3, 1.2],
                    FacetKind::Mesh,
                )
            })
            .collect();
        let first = facet_outline_m(&tris).to_bits();
        for _ in 0..20 {
            assert_eq!(facet_outline_m(&tris).to_bits(), first);
        }
    }

    /// Without facets the grid is cell/4 and D is the scene's; with small facets the spacing
    /// meets the target SE and D follows the facet size; a tiny target is capped by the budget.
    #[test]
    fn launch_plan_follows_the_facets_and_respects_the_budget() {
        let params = TrackingParams::dart_default();
        let none = launch_plan((2.0, 2.0), (0.5, 0.5), &[], 2, 50, &params);
        assert_eq!(none.sun_n, (16, 16));
        assert_eq!(none.subcells, 2);
        assert_eq!(none.predicted_se, 0.0);
        let n = 12;
        let r = 0.05;
        let mut leaves = Vec::new();
        for i in 0..10 {
            let c = [0.1 + 0.18 * i as f64, 1.0, 0.5];
            let p = |k: usize| {
                let a = 2.0 * std::f64::consts::PI * (k % n) as f64 / n as f64;
                [c[0] + r * a.cos(), c[1] + r * a.sin(), 0.5]
            };
            for k in 0..n {
                leaves.push(tri(c, p(k), p(k + 1), FacetKind::Mesh));
            }
        }
        let plan = launch_plan((2.0, 2.0), (0.5, 0.5), &leaves, 2, 50, &params);
        assert!(!plan.capped);
        assert!(
            plan.predicted_se <= params.launch_target_se * 1.05,
            "{plan:?}"
        );
        assert!(plan.sun_spacing_m < 0.125);
        // 2A/L of the 12-gons ≈ 0.048 m → D = ceil(0.5/0.048) = 11, capped at the preset's 8.
        assert_eq!(plan.subcells, 8, "{plan:?}");
        assert!(plan.sky_spacing_m >= plan.sun_spacing_m);
        let tight = TrackingParams {
            launch_target_se: 1e-9,
            max_launch_points: 10_000,
            ..TrackingParams::dart_default()
        };
        let capped = launch_plan((2.0, 2.0), (0.5, 0.5), &leaves, 2, 50, &tight);
        assert!(capped.capped);
        assert!(capped.sun_n.0 * capped.sun_n.1 <= 10_201, "{capped:?}");
        assert!(16 * capped.subcells * capped.subcells <= 10_000);
    }

    /// The small-kℓ series and the closed form agree where they meet, and the closed form is the
    /// mean of s under k e^{−ks} (checked by quadrature).
    #[test]
    fn entry_store_follows_the_face_edge_vertex_and_sun_rules() {
        let lo = DVec3::new(0.0, 0.0, 1.0);
        let cell = DVec3::ONE;
        let down = DVec3::new(0.2, 0.0, -1.0).normalize();
        // Sun launch on the scene top (the top face of a top cell): face 5, sub-face from (x, y).
        assert_eq!(
            entry_store(lo, cell, DVec3::new(0.3, 0.8, 2.0), down, 2),
            1 + 5 * 4 + 1
        );
        assert_eq!(
            entry_store(lo, cell, DVec3::new(0.3, 0.8, 2.0), down, 1),
            1 + 5
        );
        // Started inside: store 0; on a face but leaving through it: not an entry.
        assert_eq!(entry_store(lo, cell, DVec3::new(0.5, 0.5, 1.5), down, 2), 0);
        let left = DVec3::new(-0.6, 0.0, 0.8);
        assert_eq!(entry_store(lo, cell, DVec3::new(0.0, 0.5, 1.5), left, 2), 0);
        // Low-x face entered going +x: face 0, sub-face over (y, z).
        let right = DVec3::new(0.8, 0.0, 0.6);
        assert_eq!(
            entry_store(lo, cell, DVec3::new(0.0, 0.7, 1.2), right, 2),
            1 + 2
        );
        // Edge of the low-x and top faces: the larger |d_a| wins, a tie goes to z.
        let q = DVec3::new(0.0, 0.5, 2.0);
        assert_eq!(
            entry_store(lo, cell, q, DVec3::new(0.6, 0.0, -0.8), 1),
            1 + 5
        );
        assert_eq!(entry_store(lo, cell, q, DVec3::new(0.8, 0.0, -0.6), 1), 1);
        let diag = DVec3::new(1.0, 0.0, -1.0).normalize();
        assert_eq!(entry_store(lo, cell, q, diag, 1), 1 + 5);
        // Vertex, equal components: z; then y before x.
        let v = DVec3::new(0.0, 0.0, 2.0);
        assert_eq!(
            entry_store(lo, cell, v, DVec3::new(1.0, 1.0, -1.0).normalize(), 1),
            1 + 5
        );
        assert_eq!(
            entry_store(
                lo,
                cell,
                DVec3::new(0.0, 0.0, 1.5),
                DVec3::new(1.0, 1.0, 0.0).normalize(),
                1
            ),
            1 + 2
        );
        // Within FACE_TOL of the face still counts; a sub-face boundary goes up (floor).
        let q = DVec3::new(0.5, 0.25, 2.0 - 1e-12);
        assert_eq!(entry_store(lo, cell, q, down, 2), 1 + 5 * 4 + 2);
    }

    #[test]
    fn cell_exit_reaches_the_first_face_and_puts_edges_on_both_planes() {
        let lo = DVec3::new(0.0, 0.0, 1.0);
        let cell = DVec3::new(1.0, 2.0, 0.5);
        let o = DVec3::new(0.5, 1.0, 1.25);
        // Straight up: 0.25 m to the top face (face 5), sub-face of the centre (D = 2: (1, 1)).
        let (ell, q, s) = cell_exit(lo, cell, o, DVec3::Z, 2);
        assert!((ell - 0.25).abs() < 1e-15);
        assert_eq!(q, DVec3::new(0.5, 1.0, 1.5));
        assert_eq!(s, 1 + 5 * 4 + 3);
        // Down along −x: bottom at 0.25/0.6 m, −x side at 0.5/0.8 m → bottom (face 4).
        let d = DVec3::new(-0.8, 0.0, -0.6);
        let (ell, q, s) = cell_exit(lo, cell, o, d, 1);
        assert!((ell - 0.25 / 0.6).abs() < 1e-12);
        assert_eq!(q.z, 1.0);
        assert_eq!(s, 1 + 4);
        // Through an edge (x and z planes at the same distance): both coordinates exactly on
        // their planes, the face of the larger |d_a| (z), and the point is on the cell.
        let d = DVec3::new(0.5, 0.0, 0.25).normalize();
        let (ell, q, s) = cell_exit(lo, cell, o, d, 1);
        assert_eq!((q.x, q.z), (1.0, 1.5));
        assert!((ell - (0.5f64.powi(2) + 0.25f64.powi(2)).sqrt()).abs() < 1e-12);
        assert_eq!(s, 1 + 1, "x has the larger component: face +x (1)");
        let d = DVec3::new(0.25, 0.0, 0.25).normalize();
        let o2 = DVec3::new(0.75, 1.0, 1.25);
        let (_, q, s) = cell_exit(lo, cell, o2, d, 1);
        assert_eq!((q.x, q.z), (1.0, 1.5));
        assert_eq!(s, 1 + 5, "tie: the higher axis (z)");
    }

    #[test]
    fn half_barycentres_are_the_means_of_each_half() {
        let (k, ell) = (1.0, 1e-4 * 1.0001);
        let exact = half_barycentres(k, ell);
        let series = (ell * (0.25 - k * ell / 12.0), ell * (0.75 - k * ell / 12.0));
        assert!(
            (exact.0 / series.0 - 1.0).abs() < 1e-6 && (exact.1 / series.1 - 1.0).abs() < 1e-6,
            "{exact:?} {series:?}"
        );
        for (k, ell) in [(0.7, 0.5), (30.0, 1.0), (1e-2, 3.0)] {
            let (s1, s2) = half_barycentres(k, ell);
            let s_half = -((1.0 + (-k * ell).exp()) / 2.0).ln() / k;
            let n = 200_000;
            let (mut m1, mut w1, mut m2, mut w2) = (0.0, 0.0, 0.0, 0.0);
            for i in 0..n {
                let s = (i as f64 + 0.5) / n as f64 * ell;
                let wgt = (-k * s).exp();
                if s < s_half {
                    m1 += s * wgt;
                    w1 += wgt;
                } else {
                    m2 += s * wgt;
                    w2 += wgt;
                }
            }
            assert!(
                (s1 - m1 / w1).abs() < 1e-4 * ell && (s2 - m2 / w2).abs() < 1e-4 * ell,
                "k {k}: {s1} {s2} vs {} {}",
                m1 / w1,
                m2 / w2
            );
            assert!(
                (w1 - w2).abs() < 1e-3 * (w1 + w2),
                "halves carry equal energy"
            );
        }
    }

    #[test]
    fn tabulated_half_barycentres_match_the_closed_form() {
        let mut worst: f64 = 0.0;
        for i in 0..20_000 {
            let x = 1e-5 * (1e7f64).powf(i as f64 / 19_999.0);
            let (a, b) = half_barycentres(x, 1.0);
            let (c, d) = half_barycentres_fast(x, 1.0);
            worst = worst.max((a - c).abs()).max((b - d).abs());
        }
        assert!(worst < 1e-6, "worst |Δs|/ℓ = {worst:e}");
    }
}

/// Möller–Trumbore ray–triangle intersection (Möller & Trumbore 1997), both faces; distance or
/// `None`.
#[inline]
pub fn intersect(v: &[DVec3; 3], o: DVec3, d: DVec3) -> Option<f64> {
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - v[0];
    let u = s.dot(p) * inv;
    if !(-1e-12..=1.0 + 1e-12).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let vv = d.dot(q) * inv;
    if vv < -1e-12 || u + vv > 1.0 + 1e-12 {
        return None;
    }
    Some(e2.dot(q) * inv)
}

/// Runs the flux tracking.
pub fn run(inp: &RadiativeInput) -> RadiativeResult {
    let spec = inp.spec;
    let grid = inp.grid;
    let nb = inp.e_dir.len();
    let has_sky = inp.e_diff.iter().any(|&e| e > 0.0);
    let w = nb * if has_sky { 2 } else { 1 };
    let tiling = inp.dirs.tiling();
    let n_dirs = tiling.len();
    let n_sectors = inp.n_sectors;
    let n_slots = n_sectors + 1;
    let mut omega: Vec<DVec3> = tiling.iter().map(|d| d.omega).collect();
    omega.push(inp.sun);
    // Turbid materials.
    let mut tur_mat = vec![u32::MAX; inp.optics.len()];
    let mut g_flat = Vec::new();
    let mut tur_ids = Vec::new();
    for (m, o) in inp.optics.iter().enumerate() {
        if let TrackOptics::Turbid { g, .. } = o {
            tur_mat[m] = tur_ids.len() as u32;
            tur_ids.push(m);
            g_flat.extend_from_slice(g);
        }
    }
    let n_cells = spec.n_cells();
    let mut entry_cell = vec![0u32; grid.turbid.len()];
    for c in 0..n_cells {
        for e in grid.turbid_start[c]..grid.turbid_start[c + 1] {
            entry_cell[e as usize] = c as u32;
        }
    }
    // Tracker tables: G transposed to [direction][material]; per-cell records.
    let n_tm = tur_ids.len();
    let mut g_dir = vec![0.0; (n_dirs + 1) * n_tm];
    for tm in 0..n_tm {
        for dir in 0..=n_dirs {
            g_dir[dir * n_tm + tm] = g_flat[tm * (n_dirs + 1) + dir];
        }
    }
    let mut ents = Vec::with_capacity(grid.turbid.len());
    let mut cells = Vec::with_capacity(n_cells);
    for c in 0..n_cells {
        let ent_lo = ents.len() as u32;
        for e in grid.turbid_start[c]..grid.turbid_start[c + 1] {
            let te = &grid.turbid[e as usize];
            let tm = tur_mat[te.material as usize];
            if tm != u32::MAX {
                ents.push(Ent {
                    idx: e,
                    tm,
                    density: te.density as f64,
                });
            }
        }
        cells.push(CellRec {
            ent_lo,
            ent_hi: ents.len() as u32,
            fac_lo: grid.facet_start.get(c).copied().unwrap_or(0),
            fac_hi: grid.facet_start.get(c + 1).copied().unwrap_or(0),
        });
    }
    let size = (
        spec.n[0] as f64 * spec.cell.x,
        spec.n[1] as f64 * spec.cell.y,
    );
    let area = size.0 * size.1;
    // Launch grids on the top plane.
    let n_sky_dirs = if has_sky {
        tiling.iter().filter(|d| d.omega.z < 0.0).count()
    } else {
        0
    };
    let plan = launch_plan(
        size,
        (spec.cell.x, spec.cell.y),
        inp.facets,
        spec.subcells,
        n_sky_dirs,
        &inp.params,
    );
    let mut source = vec![0.0; w];
    for b in 0..nb {
        source[b] = inp.e_dir[b] * area;
        if has_sky {
            source[nb + b] = inp.e_diff[b] * area;
        }
    }
    for e in inp.emitters {
        for (s, v) in source.iter_mut().zip(&e.power) {
            *s += v;
        }
    }
    let n_source_rays = (plan.sun_n.0 * plan.sun_n.1) as f64
        + (plan.sky_n.0 * plan.sky_n.1 * n_sky_dirs) as f64
        + inp.emitters.len() as f64;
    let min_ray = inp.params.ray_threshold * source.iter().sum::<f64>() / n_source_rays;
    // DART's threshold is per steradian × the ray's ΔΩ (physics.md §6.4): relative to the
    // largest tile, so the regular tiles keep `min_ray` and an exact view direction of 0.001 sr
    // is tracked as far as the tile it was cut from.
    let d_omega_max = tiling
        .iter()
        .map(|d| d.solid_angle_sr)
        .fold(0.0_f64, f64::max);
    let mut ray_factor: Vec<f64> = tiling
        .iter()
        .map(|d| {
            if d_omega_max > 0.0 {
                (d.solid_angle_sr / d_omega_max).min(1.0)
            } else {
                1.0
            }
        })
        .collect();
    ray_factor.push(1.0);
    // Rows of the interception slots: the phase rows of each slot's member directions,
    // averaged with the power a smooth diffuse field deposits along each member: ∝ G(Ω_i) ΔΩ_i
    // for turbid cells, ∝ ∫_{ΔΩ_i}|μ|dΩ for the ground. One direction per slot (reference
    // preset) gives the exact rows.
    let n_sec = n_slots - 1;
    let mut slot_rows = Vec::with_capacity(tur_ids.len() * nb * n_sec * n_dirs);
    for &m in &tur_ids {
        let TrackOptics::Turbid { g, tables, .. } = &inp.optics[m] else {
            unreachable!("tur_ids holds turbid materials only");
        };
        let weights: Vec<f64> = tiling
            .iter()
            .enumerate()
            .map(|(i, d)| g[i] * d.solid_angle_sr)
            .collect();
        for table in tables.iter().take(nb) {
            slot_rows.extend(slot_average_rows(
                table,
                &weights,
                inp.sector_of,
                n_sec,
                n_dirs,
            ));
        }
    }
    let mut ground_rows = Vec::new();
    if let Some(tables) = &inp.ground_brdf {
        let weights: Vec<f64> = tiling.iter().map(|d| d.projected_sr).collect();
        for table in tables.iter().take(nb) {
            // Slots, then the sun row last: `[band][slot 0..=n_sec][dir]`.
            ground_rows.extend(slot_average_rows(
                table,
                &weights,
                inp.sector_of,
                n_sec,
                n_dirs,
            ));
            ground_rows.extend(
                table
                    .row(table.sun_row().unwrap_or(0))
                    .iter()
                    .take(n_dirs)
                    .map(|&x| x as f64),
            );
        }
    }
    // RPV/Hapke facets: compact ref index and slot-averaged rows per table set (weights: the
    // projected solid angle |n·Ω_i| ΔΩ_i of each member incidence on the set's facets).
    let mut brdf_ref = Vec::new();
    let mut n_brdf_refs = 0;
    let mut facet_rows = Vec::new();
    if !inp.facet_tables.is_empty() {
        brdf_ref = grid
            .facet_ids
            .iter()
            .map(|&f| {
                if inp
                    .facet_brdf
                    .get(f as usize)
                    .is_some_and(|&s| s != u32::MAX)
                {
                    n_brdf_refs += 1;
                    n_brdf_refs as u32 - 1
                } else {
                    u32::MAX
                }
            })
            .collect();
        let mut normal = vec![DVec3::Z; inp.facet_tables.len()];
        for (f, &s) in inp.facet_brdf.iter().enumerate() {
            if s != u32::MAX {
                let v = &inp.facets[f].v;
                normal[s as usize] = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or(DVec3::Z);
            }
        }
        let dir_omega: Vec<DVec3> = tiling.iter().map(|d| d.omega).collect();
        let dir_regular: Vec<bool> = tiling
            .iter()
            .map(|d| d.kind == crate::resources::directions::DirectionKind::Regular)
            .collect();
        for (s, set) in inp.facet_tables.iter().enumerate() {
            let weights: Vec<f64> = tiling
                .iter()
                .map(|d| (-d.omega.dot(normal[s])).max(0.0) * d.solid_angle_sr)
                .collect();
            for table in set.iter().take(nb) {
                // Slots, then the sun row last: `[set][band][slot 0..=n_sec][dir]`.
                let mut rows = slot_average_rows(table, &weights, inp.sector_of, n_sec, n_dirs);
                rows.extend(
                    table
                        .row(table.sun_row().unwrap_or(0))
                        .iter()
                        .take(n_dirs)
                        .map(|&x| x as f64),
                );
                for row in rows.chunks_mut(n_dirs) {
                    remap_wrong_side(row, normal[s], &dir_omega, &dir_regular);
                }
                facet_rows.extend(rows);
            }
        }
    }
    // Hotspot terms (physics.md §3.5): sun–view gap correlation of first-order sun rays.
    let mut hs = vec![[0.0; 2]; n_dirs * n_tm];
    for (tm, &m) in tur_ids.iter().enumerate() {
        let TrackOptics::Turbid { leaf_size_m, .. } = &inp.optics[m] else {
            unreachable!("tur_ids holds turbid materials only");
        };
        if *leaf_size_m > 0.0 && inp.sun.z < 0.0 {
            let g_sun = g_dir[n_dirs * n_tm + tm];
            for j in 0..n_dirs {
                hs[j * n_tm + tm] =
                    hotspot_terms(inp.sun, omega[j], g_sun, g_dir[j * n_tm + tm], *leaf_size_m);
            }
        }
    }
    let hs_dir: Vec<bool> = (0..n_dirs)
        .map(|j| (0..n_tm).any(|tm| hs[j * n_tm + tm][0] > 0.0))
        .collect();
    // The lean tracker's cells, when the scene fits it.
    let simple = cells
        .iter()
        .all(|c| c.fac_lo == c.fac_hi && c.ent_hi - c.ent_lo <= 1)
        && spec.topography_offset == (0.0, 0.0);
    // Empty-space distance per cell: a cell is occupied when a walk does anything in it (a
    // tracked turbid entry or a facet; the ground and the box's faces are exits of the DDA).
    let skip = skip_field(spec.n, inp.params.skip_empty, MIN_SKIP_DISTANCE, |c| {
        cells[c].fac_lo != cells[c].fac_hi || cells[c].ent_lo != cells[c].ent_hi
    });
    let scells: Vec<SimpleCell> = if simple {
        cells
            .iter()
            .zip(&skip)
            .map(|(c, &r)| match ents.get(c.ent_lo as usize) {
                Some(e) if c.ent_hi > c.ent_lo && e.density > 0.0 => SimpleCell {
                    density: e.density,
                    tm: e.tm,
                    idx: e.idx,
                },
                // An entry of zero density: nothing happens in the cell, but it is not
                // counted as empty (r = 0, visited).
                _ => SimpleCell {
                    tm: r as u32,
                    ..SimpleCell::default()
                },
            })
            .collect()
    } else {
        Vec::new()
    };
    // Where the walks dispatch (the batched walk only where it has AVX2 + FMA).
    let arch = inp.params.kernel_isa.arch();
    let mut ctx = Ctx {
        inp,
        w,
        nb,
        n_dirs,
        n_slots,
        omega,
        tur_mat,
        n_tm,
        g_dir,
        cells,
        ents,
        entry_cell,
        size,
        min_ray,
        ray_factor,
        slot_rows,
        ground_rows,
        sub: plan.subcells.max(1),
        brdf_ref,
        n_brdf_refs,
        facet_rows,
        hs,
        hs_dir,
        image_grid: ImageGrid::new(spec, inp.image_oversampling),
        simple,
        batch: simple
            && inp.params.batch_walk
            && inp.params.turbid_subfaces == TurbidSubfaces::Off
            && matches!(w, 1 | 2 | 4)
            && batch::available(&arch),
        scells,
        skip,
        subfaces: inp.params.turbid_subfaces,
        tstores: match inp.params.turbid_subfaces {
            TurbidSubfaces::Off | TurbidSubfaces::Blend => 1,
            TurbidSubfaces::Faces => 7,
            TurbidSubfaces::Subfaces => {
                6 * (plan.subcells.clamp(1, MAX_FACE_D) as usize).pow(2) + 1
            }
        },
        face_d: if inp.params.turbid_subfaces == TurbidSubfaces::Subfaces {
            plan.subcells.clamp(1, MAX_FACE_D)
        } else {
            1
        },
        pts_per: if inp.params.turbid_subfaces == TurbidSubfaces::Blend {
            n_slots
        } else {
            1
        },
        lane_dirs: Vec::new(),
        lane_dirs32: Vec::new(),
        scells32: Vec::new(),
        arch,
    };
    if ctx.batch {
        ctx.lane_dirs = batch::lane_dirs(&ctx);
        ctx.lane_dirs32 = batch::lane_dirs32(&ctx);
        if !ctx.lane_dirs32.is_empty() {
            ctx.scells32 = ctx
                .scells
                .iter()
                .map(|c| {
                    let d = if c.density > 0.0 {
                        (c.density as f32).max(f32::MIN_POSITIVE)
                    } else {
                        0.0
                    };
                    let hi = if c.density > 0.0 { c.idx } else { c.tm };
                    d.to_bits() as u64 | (hi as u64) << 32
                })
                .collect();
        }
    }
    let mut res = RadiativeResult {
        n_channels: w,
        n_bands: nb,
        has_sky,
        source: source.clone(),
        escaped: vec![0.0; n_dirs * w],
        images: vec![
            0.0;
            inp.image_of.iter().filter(|&&i| i != u32::MAX).count()
                * ctx.image_grid.pixels()
                * w
        ],
        image_grid: ctx.image_grid,
        absorbed_turbid: vec![0.0; grid.turbid.len() * w],
        intercepted_turbid: vec![0.0; grid.turbid.len() * w],
        absorbed_facet: vec![0.0; inp.facets.len() * w],
        intercepted_facet: vec![0.0; inp.facets.len() * w],
        absorbed_ground: vec![0.0; spec.n[0] * spec.n[1] * w],
        intercepted_ground: vec![0.0; spec.n[0] * spec.n[1] * w],
        lost: vec![0.0; w],
        remaining: vec![0.0; w],
        launch: plan,
        ..Default::default()
    };
    // --- Iteration 1: sources. Launch points in fixed chunks of rows.
    let top = spec.top();
    let sky_dirs: Vec<usize> = if has_sky {
        (0..n_dirs).filter(|&j| ctx.omega[j].z < 0.0).collect()
    } else {
        Vec::new()
    };
    // Rows of launch points: the sun grid's rows, then the sky grid's (false/true); one list
    // cut into fixed chunks, so the order of accumulation does not depend on the threads.
    let has_sun = inp.e_dir.iter().any(|&e| e > 0.0);
    let mut rows: Vec<(bool, usize)> = Vec::new();
    if has_sun {
        rows.extend((0..plan.sun_n.1).map(|j| (false, j)));
    }
    if !sky_dirs.is_empty() {
        rows.extend((0..plan.sky_n.1).map(|j| (true, j)));
    }
    let outs: Vec<ChunkOut> = rows
        .par_chunks(chunk_len(rows.len()))
        .map(|chunk| {
            let mut out = new_out(&ctx);
            let mut pw = vec![0.0; w];
            let t_kernel = std::time::Instant::now();
            for &(sky, jy) in chunk {
                let (nlx, nly) = if sky { plan.sky_n } else { plan.sun_n };
                let da = area / (nlx * nly) as f64;
                for ix in 0..nlx {
                    let p = DVec3::new(
                        spec.origin.x + (ix as f64 + 0.5) * size.0 / nlx as f64,
                        spec.origin.y + (jy as f64 + 0.5) * size.1 / nly as f64,
                        top,
                    );
                    if !sky {
                        pw.iter_mut().for_each(|v| *v = 0.0);
                        for b in 0..nb {
                            pw[b] = inp.e_dir[b] * da;
                        }
                        ctx.trace(p, n_dirs, None, &mut pw, &mut out);
                        continue;
                    }
                    for &j in &sky_dirs {
                        pw.iter_mut().for_each(|v| *v = 0.0);
                        // L_sky = E_diff/π; power = L ΔA ∫_{ΔΩ}|μ|dΩ (physics.md §6.1).
                        for b in 0..nb {
                            pw[nb + b] =
                                inp.e_diff[b] / std::f64::consts::PI * da * tiling[j].projected_sr;
                        }
                        ctx.trace(p, j, None, &mut pw, &mut out);
                    }
                }
            }
            ctx.flush(&mut out);
            out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
            out
        })
        .collect();
    // Other sources, in fixed chunks after the launch rows.
    let mut outs = outs;
    outs.extend(
        inp.emitters
            .par_chunks(chunk_len(inp.emitters.len()))
            .map(|chunk| {
                let mut out = new_out(&ctx);
                let mut pw = vec![0.0; w];
                for e in chunk {
                    pw.iter_mut().for_each(|v| *v = 0.0);
                    for (a, b) in pw.iter_mut().zip(&e.power) {
                        *a = *b;
                    }
                    if e.dir <= n_dirs && pw.iter().any(|&v| v > 0.0) {
                        ctx.trace(e.origin, e.dir, e.skip_facet, &mut pw, &mut out);
                    } else {
                        add(&mut out.lost, &pw);
                    }
                }
                ctx.flush(&mut out);
                out
            })
            .collect::<Vec<_>>(),
    );
    let mut stores = new_stores(&ctx);
    let mut last = vec![0.0; w]; // escaped in the last iteration
    let mut pool: Vec<ChunkOut> = Vec::new();
    merge(&ctx, outs, &mut stores, &mut res, &mut last, &mut pool);
    res.escaped_per_iteration.push(last.clone());
    res.iterations = 1;
    // Facet fractions fallback (renormalised cosine) computed once if not provided.
    let approx_fractions: Vec<(Vec<f32>, Vec<f32>)> =
        if inp.facet_fractions.len() == inp.facets.len() {
            Vec::new()
        } else {
            inp.facets
                .par_iter()
                .map(|f| cosine_fractions(&ctx, f))
                .collect()
        };
    let fractions: &[(Vec<f32>, Vec<f32>)] = if approx_fractions.is_empty() {
        inp.facet_fractions
    } else {
        &approx_fractions
    };
    let ground_fr: Vec<f64> = (0..n_dirs)
        .map(|j| {
            if ctx.omega[j].z > 0.0 {
                tiling[j].projected_sr / std::f64::consts::PI
            } else {
                0.0
            }
        })
        .collect();
    // --- Scattering iterations.
    let mut prev_pending = pending(&stores, w);
    let mut prev_estimate = f64::NAN;
    res.q = vec![0.0; w];
    let mut last_inc = Increments::new(&res);
    let bar = crate::io::progress::progress_bar(
        inp.params.progress,
        inp.params.max_iterations as u64,
        "flux tracking: iterations",
    );
    while res.iterations < inp.params.max_iterations {
        bar.set_position(res.iterations as u64);
        let pend = prev_pending.clone();
        if pend.iter().sum::<f64>() <= 1e-15 * source.iter().sum::<f64>() {
            res.converged = true;
            break;
        }
        let before = Increments::new(&res);
        let outs = emit(
            &ctx,
            &stores,
            res.iterations == 1,
            fractions,
            &ground_fr,
            &mut pool,
        );
        let mut new_stores = new_stores(&ctx);
        let mut esc = vec![0.0; w];
        merge(&ctx, outs, &mut new_stores, &mut res, &mut esc, &mut pool);
        // Absorption at emission: intercepted − emitted, booked in `emit` via res? (see below)
        stores = new_stores;
        res.iterations += 1;
        res.escaped_per_iteration.push(esc.clone());
        let now = pending(&stores, w);
        for ch in 0..w {
            res.q[ch] = if pend[ch] > 0.0 {
                now[ch] / pend[ch]
            } else {
                0.0
            };
        }
        last_inc = Increments::diff(&before, &res);
        // Extrapolated albedo estimate (all channels).
        let esc_total: f64 = res.escaped.iter().sum();
        let extra: f64 = (0..w)
            .map(|ch| {
                if res.q[ch] < 1.0 {
                    esc[ch] * res.q[ch] / (1.0 - res.q[ch])
                } else {
                    0.0
                }
            })
            .sum();
        let estimate = (esc_total + extra) / source.iter().sum::<f64>();
        prev_pending = now;
        if res.iterations >= 3
            && (estimate - prev_estimate).abs()
                <= inp.params.albedo_threshold * estimate.abs().max(1e-300)
        {
            res.converged = true;
            break;
        }
        prev_estimate = estimate;
    }
    // --- Remaining stores: extrapolate (or book as remaining).
    bar.finish_and_clear();
    let pend = pending(&stores, w);
    if inp.params.extrapolate && res.iterations >= 2 {
        let mut fac = vec![0.0; w];
        for ch in 0..w {
            let q = res.q[ch];
            fac[ch] = if q > 0.0 && q < 1.0 {
                q / (1.0 - q)
            } else {
                0.0
            };
        }
        last_inc.apply(&mut res, &fac);
        for ch in 0..w {
            // Geometric tail: exactly the pending power when q comes from the same iteration.
            let tail = last_inc.total(ch) * fac[ch];
            res.remaining[ch] = pend[ch] - tail;
        }
    } else {
        res.remaining = pend;
    }
    res
}

fn new_out(ctx: &Ctx) -> ChunkOut {
    let ne = ctx.inp.grid.turbid.len();
    ChunkOut {
        escaped: vec![0.0; ctx.n_dirs * ctx.w],
        lost: vec![0.0; ctx.w],
        ray_scale: 1.0,
        tur: Some(Box::new(TurAcc::new(
            ne * ctx.tstores,
            ctx.n_slots,
            ctx.w,
            ctx.pts_per,
            !ctx.lane_dirs32.is_empty(),
        ))),
        ..Default::default()
    }
}

fn new_stores(ctx: &Ctx) -> Stores {
    let w = ctx.w;
    let grid = ctx.inp.grid;
    let spec = ctx.inp.spec;
    let off = ctx.subfaces == TurbidSubfaces::Off;
    let n_dense = if off { grid.turbid.len() } else { 0 };
    Stores {
        tur: vec![0.0; n_dense * ctx.n_slots * w],
        tur_pts: vec![[0.0; 8]; n_dense],
        trec: TurRecords::new(ctx.n_slots * w, ctx.pts_per),
        fac_front: vec![0.0; grid.facet_ids.len() * w],
        fac_back: vec![0.0; grid.facet_ids.len() * w],
        fac_slot: vec![0.0; ctx.n_brdf_refs * ctx.n_slots * w],
        fac_pts: SubPoints::default(),
        gnd: vec![
            0.0;
            spec.n[0]
                * spec.n[1]
                * w
                * if ctx.inp.ground_brdf.is_some() {
                    ctx.n_slots
                } else {
                    1
                }
        ],
        gnd_pts: SubPoints::default(),
    }
}

/// Power intercepted and not yet scattered or absorbed, per channel.
fn pending(s: &Stores, w: usize) -> Vec<f64> {
    let mut p = vec![0.0; w];
    for (chunk, out) in [
        (&s.tur, 0),
        (&s.fac_front, 0),
        (&s.fac_back, 0),
        (&s.fac_slot, 0),
        (&s.gnd, 0),
        (&s.trec.pow, 0),
    ] {
        let _ = out;
        for (i, v) in chunk.iter().enumerate() {
            p[i % w] += v;
        }
    }
    p
}

/// Snapshot of additive products, to take the increments of one iteration.
#[derive(Clone)]
struct Increments {
    escaped: Vec<f64>,
    images: Vec<f64>,
    absorbed_turbid: Vec<f64>,
    absorbed_facet: Vec<f64>,
    absorbed_ground: Vec<f64>,
    intercepted_ground: Vec<f64>,
    intercepted_turbid: Vec<f64>,
    intercepted_facet: Vec<f64>,
    lost: Vec<f64>,
    w: usize,
}

impl Increments {
    fn new(r: &RadiativeResult) -> Self {
        Self {
            escaped: r.escaped.clone(),
            images: r.images.clone(),
            absorbed_turbid: r.absorbed_turbid.clone(),
            absorbed_facet: r.absorbed_facet.clone(),
            absorbed_ground: r.absorbed_ground.clone(),
            intercepted_ground: r.intercepted_ground.clone(),
            intercepted_turbid: r.intercepted_turbid.clone(),
            intercepted_facet: r.intercepted_facet.clone(),
            lost: r.lost.clone(),
            w: r.n_channels,
        }
    }
    fn diff(a: &Self, r: &RadiativeResult) -> Self {
        let d =
            |x: &Vec<f64>, y: &Vec<f64>| y.iter().zip(x).map(|(b, a)| b - a).collect::<Vec<f64>>();
        Self {
            escaped: d(&a.escaped, &r.escaped),
            images: d(&a.images, &r.images),
            absorbed_turbid: d(&a.absorbed_turbid, &r.absorbed_turbid),
            absorbed_facet: d(&a.absorbed_facet, &r.absorbed_facet),
            absorbed_ground: d(&a.absorbed_ground, &r.absorbed_ground),
            intercepted_ground: d(&a.intercepted_ground, &r.intercepted_ground),
            intercepted_turbid: d(&a.intercepted_turbid, &r.intercepted_turbid),
            intercepted_facet: d(&a.intercepted_facet, &r.intercepted_facet),
            lost: d(&a.lost, &r.lost),
            w: a.w,
        }
    }
    /// Adds `inc × fac[channel]` to every additive product.
    fn apply(&self, r: &mut RadiativeResult, fac: &[f64]) {
        let w = self.w;
        let ap = |dst: &mut Vec<f64>, src: &Vec<f64>| {
            for (i, (d, s)) in dst.iter_mut().zip(src).enumerate() {
                *d += s * fac[i % w];
            }
        };
        ap(&mut r.escaped, &self.escaped);
        ap(&mut r.images, &self.images);
        ap(&mut r.absorbed_turbid, &self.absorbed_turbid);
        ap(&mut r.absorbed_facet, &self.absorbed_facet);
        ap(&mut r.absorbed_ground, &self.absorbed_ground);
        ap(&mut r.intercepted_ground, &self.intercepted_ground);
        ap(&mut r.intercepted_turbid, &self.intercepted_turbid);
        ap(&mut r.intercepted_facet, &self.intercepted_facet);
        ap(&mut r.lost, &self.lost);
    }
    /// Energy that left the pending pool in this iteration: escaped + absorbed + lost.
    fn total(&self, ch: usize) -> f64 {
        let w = self.w;
        let s = |v: &Vec<f64>| v.iter().skip(ch).step_by(w).sum::<f64>();
        s(&self.escaped)
            + s(&self.absorbed_turbid)
            + s(&self.absorbed_facet)
            + s(&self.absorbed_ground)
            + s(&self.lost)
    }
}

/// Merges chunk outputs (in order) into the stores and the result.
/// Each output with a dense turbid accumulator is then emptied ([`ChunkOut::reset`]) into
/// `pool`, for the next iteration's chunks (its arrays keep their allocations: no new zeroed
/// accumulator, no regrowth of the event lists).
fn merge(
    ctx: &Ctx,
    outs: Vec<ChunkOut>,
    st: &mut Stores,
    res: &mut RadiativeResult,
    esc: &mut [f64],
    pool: &mut Vec<ChunkOut>,
) {
    let w = ctx.w;
    let ns = ctx.n_slots;
    let mut scratch = super::images::SpreadScratch::default();
    for mut out in outs {
        debug_assert!(out.queue.is_empty(), "every queued ray walked");
        res.rays += out.rays;
        res.crossings += out.crossings;
        res.skipped += out.skipped;
        res.kernel_seconds += out.kernel_seconds;
        add(&mut res.escaped, &out.escaped);
        for (k, v) in out.escaped.iter().enumerate() {
            esc[k % w] += v;
        }
        add(&mut res.lost, &out.lost);
        // Image events: power spread over the pixels under the footprint, in event order.
        let npx = ctx.image_grid.pixels();
        for (n, &img) in out.img_key.iter().enumerate() {
            let [x, y, fx, fy] = out.img_pos[n];
            let v = &out.img_val[n * w..(n + 1) * w];
            let image = &mut res.images[img as usize * npx * w..(img as usize + 1) * npx * w];
            let grid = &ctx.image_grid;
            if w == 2 {
                // Two channels (the common case): the pixel rows as pairs, the same operations.
                let rows = image.as_chunks_mut::<2>().0;
                let v = [v[0], v[1]];
                grid.spread((x, y), (fx, fy), &mut scratch, |px, share| {
                    let r = &mut rows[px];
                    r[0] += v[0] * share;
                    r[1] += v[1] * share;
                });
            } else {
                grid.spread((x, y), (fx, fy), &mut scratch, |px, share| {
                    for (r, p) in image[px * w..(px + 1) * w].iter_mut().zip(v) {
                        *r += p * share;
                    }
                });
            }
        }
        if ctx.subfaces != TurbidSubfaces::Off {
            if let Some(acc) = &out.tur {
                let tr = &mut st.trec;
                acc.for_each_tur(|key, v| {
                    let t = (key / ns as u64) as u32;
                    let slot = (key % ns as u64) as usize;
                    let r = tr.rec(t);
                    let e = t as usize / ctx.tstores;
                    let rec = &mut tr.pow[(r * ns + slot) * w..(r * ns + slot + 1) * w];
                    let it = &mut res.intercepted_turbid[e * w..(e + 1) * w];
                    for ((p, i), x) in rec.iter_mut().zip(it.iter_mut()).zip(v) {
                        *p += x;
                        *i += x;
                    }
                });
                let np = tr.np as u64;
                acc.for_each_pts(|key, v| {
                    let r = tr.rec((key / np) as u32);
                    let q = (key % np) as usize;
                    let p = &mut tr.pts[(r * tr.np + q) * 8..(r * tr.np + q + 1) * 8];
                    for a in 0..3 {
                        p[a] += v[a];
                        p[4 + a] += v[3 + a];
                    }
                    p[3] += v[6];
                    p[7] += v[6];
                });
            }
        } else if let Some(acc) = &out.tur {
            acc.for_each_tur(|key, v| {
                let e = key as usize / ns;
                let base = key as usize * w;
                for ch in 0..w {
                    st.tur[base + ch] += v[ch];
                    res.intercepted_turbid[e * w + ch] += v[ch];
                }
            });
        }
        if let Some(acc) = &out.tur
            && ctx.subfaces == TurbidSubfaces::Off
        {
            // Barycentres of the first and second halves of the intercepted energy.
            acc.for_each_pts(|e, v| {
                let pts = &mut st.tur_pts[e as usize];
                for a in 0..3 {
                    pts[a] += v[a];
                    pts[4 + a] += v[3 + a];
                }
                pts[3] += v[6];
                pts[7] += v[6];
            });
            // The single-precision walk's records, from their cell's frame: Σ wt (c + p) =
            // c Σ wt + Σ wt p, c the cell's corner.
            acc.for_each_pts_local(|e, v| {
                let spec = ctx.inp.spec;
                let [i, j, k] = spec.ijk(ctx.entry_cell[e as usize] as usize);
                let c = spec.origin + DVec3::new(i as f64, j as f64, k as f64) * spec.cell;
                let pts = &mut st.tur_pts[e as usize];
                for a in 0..3 {
                    pts[a] += c[a] * v[6] + v[a];
                    pts[4 + a] += c[a] * v[6] + v[3 + a];
                }
                pts[3] += v[6];
                pts[7] += v[6];
            });
        }
        let stride = w + 4;
        for (n, &(r, f, from_front, sub, slot)) in out.fac_key.iter().enumerate() {
            let v = &out.fac_val[n * stride..(n + 1) * stride];
            let fa = &ctx.inp.facets[f as usize];
            if let Some(&bi) = ctx.brdf_ref.get(r as usize)
                && bi != u32::MAX
            {
                // RPV/Hapke: stored whole per incidence slot; absorption booked at emission.
                for ch in 0..w {
                    res.intercepted_facet[f as usize * w + ch] += v[ch];
                    st.fac_slot[(bi as usize * ns + slot as usize) * w + ch] += v[ch];
                }
                st.fac_pts
                    .add(r, sub, DVec3::new(v[w], v[w + 1], v[w + 2]), v[w + 3]);
                continue;
            }
            let (rr, tt) = match &ctx.inp.optics[fa.material as usize] {
                TrackOptics::Lambert { r, t, .. } => (r.as_slice(), t.as_slice()),
                _ => (&[][..], &[][..]),
            };
            for ch in 0..w {
                let b = ch % ctx.nb;
                let (rb, tb) = (
                    rr.get(b).copied().unwrap_or(0.0),
                    tt.get(b).copied().unwrap_or(0.0),
                );
                let i = v[ch];
                res.intercepted_facet[f as usize * w + ch] += i;
                res.absorbed_facet[f as usize * w + ch] += i * (1.0 - rb - tb);
                // Reflected to the incidence side, transmitted to the other side.
                let (to_front, to_back) = if from_front {
                    (rb * i, tb * i)
                } else {
                    (tb * i, rb * i)
                };
                st.fac_front[r as usize * w + ch] += to_front;
                st.fac_back[r as usize * w + ch] += to_back;
            }
            st.fac_pts
                .add(r, sub, DVec3::new(v[w], v[w + 1], v[w + 2]), v[w + 3]);
        }
        let stride = w + 4;
        let gr = ctx.inp.flat_ground.as_deref().unwrap_or(&[]);
        let brdf = ctx.inp.ground_brdf.is_some();
        for (n, &(col, slot, sub)) in out.gnd_key.iter().enumerate() {
            let v = &out.gnd_val[n * stride..(n + 1) * stride];
            for ch in 0..w {
                res.intercepted_ground[col as usize * w + ch] += v[ch];
                if brdf {
                    // Stored whole per incidence slot; absorption is booked at emission.
                    st.gnd[(col as usize * ns + slot as usize) * w + ch] += v[ch];
                } else {
                    let rb = gr.get(ch % ctx.nb).copied().unwrap_or(0.0);
                    res.absorbed_ground[col as usize * w + ch] += v[ch] * (1.0 - rb);
                    st.gnd[col as usize * w + ch] += v[ch] * rb;
                }
            }
            st.gnd_pts
                .add(col, sub, DVec3::new(v[w], v[w + 1], v[w + 2]), v[w + 3]);
        }
        for (k, &(e, ch)) in out.absorbed_turbid.iter().enumerate() {
            res.absorbed_turbid[e as usize * w + ch] += out.absorbed_val[k];
        }
        let off = out.absorbed_turbid.len();
        for (k, &(f, ch)) in out.absorbed_facet.iter().enumerate() {
            res.absorbed_facet[f as usize * w + ch] += out.absorbed_val[off + k];
        }
        let off = off + out.absorbed_facet.len();
        for (k, &(c, ch)) in out.absorbed_ground.iter().enumerate() {
            res.absorbed_ground[c as usize * w + ch] += out.absorbed_val[off + k];
        }
        // Dense accumulators only: recycling every output made the sparse (incident-face
        // store) runs slower and larger (forest Default, `--subfaces subfaces`, 2 threads on a
        // loaded host: 93.5 s / 652 MiB before, 188.5 s / 1143 MiB with every output recycled;
        // a recycled sparse map keeps its largest capacity).
        if let Some(TurAcc::Dense { .. }) = out.tur.as_deref() {
            out.reset();
            pool.push(out);
        }
    }
    st.fac_pts.finish(ctx.inp.grid.facet_ids.len());
    st.trec.finish();
    let spec = ctx.inp.spec;
    st.gnd_pts.finish(spec.n[0] * spec.n[1]);
}

/// Renormalised-cosine Lambertian fractions (used when exact fractions were not provided).
fn cosine_fractions(ctx: &Ctx, f: &Facet) -> (Vec<f32>, Vec<f32>) {
    let n = (f.v[1] - f.v[0])
        .cross(f.v[2] - f.v[0])
        .normalize_or(DVec3::Z);
    let tiling = ctx.inp.dirs.tiling();
    let mut fr: Vec<f64> = tiling
        .iter()
        .map(|d| n.dot(d.omega).max(0.0) * d.solid_angle_sr)
        .collect();
    let mut bk: Vec<f64> = tiling
        .iter()
        .map(|d| (-n.dot(d.omega)).max(0.0) * d.solid_angle_sr)
        .collect();
    let (sf, sb): (f64, f64) = (fr.iter().sum(), bk.iter().sum());
    fr.iter_mut().for_each(|x| *x /= sf);
    bk.iter_mut().for_each(|x| *x /= sb);
    (
        fr.iter().map(|&x| x as f32).collect(),
        bk.iter().map(|&x| x as f32).collect(),
    )
}

/// Traces `share × v` (channel powers, W) from `o` along tiling direction `j`, ignoring facet
/// `skip`. With `hs_j` (first emission after the launch, so the sun channels hold only
/// scattered direct sun) the sun channels go on a hotspot-correlated ray and the sky channels
/// on an ordinary one.
#[allow(clippy::too_many_arguments)]
fn send(
    ctx: &Ctx,
    o: DVec3,
    j: usize,
    skip: Option<u32>,
    v: &[f64],
    share: f64,
    hs_j: bool,
    pw: &mut [f64],
    out: &mut ChunkOut,
) {
    if !hs_j {
        for (a, b) in pw.iter_mut().zip(v) {
            *a = b * share;
        }
        ctx.trace(o, j, skip, pw, out);
        return;
    }
    let nb = ctx.nb;
    for (ch, (a, b)) in pw.iter_mut().zip(v).enumerate() {
        *a = if ch < nb { b * share } else { 0.0 };
    }
    if pw.iter().any(|&x| x > 0.0) {
        ctx.trace_hotspot(o, j, skip, pw, out);
    }
    if v.len() > nb && v[nb..].iter().any(|&x| x != 0.0) {
        for (ch, (a, b)) in pw.iter_mut().zip(v).enumerate() {
            *a = if ch < nb { 0.0 } else { b * share };
        }
        ctx.trace(o, j, skip, pw, out);
    }
}

/// Iteration i: scatters every store of iteration i−1 along every tiling direction; `first`:
/// the stores are those of the launch (direct sun and sky).
fn emit(
    ctx: &Ctx,
    st: &Stores,
    first: bool,
    fractions: &[(Vec<f32>, Vec<f32>)],
    ground_fr: &[f64],
    pool: &mut Vec<ChunkOut>,
) -> Vec<ChunkOut> {
    let w = ctx.w;
    let nb = ctx.nb;
    let ns = ctx.n_slots;
    let n_dirs = ctx.n_dirs;
    let grid = ctx.inp.grid;
    let spec = ctx.inp.spec;
    let tiling = ctx.inp.dirs.tiling();
    // Emitters in a fixed order: turbid entries (or, with incident-face stores, the groups of
    // records of one entry, entries ascending), facet refs, ground columns.
    let off = ctx.subfaces == TurbidSubfaces::Off;
    let mut groups: Vec<std::ops::Range<usize>> = Vec::new();
    if !off {
        let tr = &st.trec;
        let mut lo = 0;
        for n in 1..=tr.order.len() {
            let entry = |n: usize| tr.keys[tr.order[n] as usize] as usize / ctx.tstores;
            if n == tr.order.len() || entry(n) != entry(lo) {
                groups.push(lo..n);
                lo = n;
            }
        }
    }
    let n_t = if off { grid.turbid.len() } else { groups.len() };
    let n_f = grid.facet_ids.len();
    let n_g = spec.n[0] * spec.n[1];
    let active: Vec<usize> = (0..n_t + n_f + n_g)
        .filter(|&k| {
            if k < n_t && !off {
                let tr = &st.trec;
                groups[k].clone().any(|n| {
                    let r = tr.order[n] as usize;
                    tr.pow[r * tr.ns_w..(r + 1) * tr.ns_w]
                        .iter()
                        .any(|&v| v > 0.0)
                })
            } else if k < n_t {
                st.tur[k * ns * w..(k + 1) * ns * w]
                    .iter()
                    .any(|&v| v > 0.0)
            } else if k < n_t + n_f {
                let r = k - n_t;
                let bi = ctx.brdf_ref.get(r).copied().unwrap_or(u32::MAX) as usize;
                if bi != u32::MAX as usize {
                    return st.fac_slot[bi * ns * w..(bi + 1) * ns * w]
                        .iter()
                        .any(|&v| v > 0.0);
                }
                st.fac_front[r * w..(r + 1) * w]
                    .iter()
                    .chain(&st.fac_back[r * w..(r + 1) * w])
                    .any(|&v| v > 0.0)
            } else {
                let c = k - n_t - n_f;
                let gs = st.gnd.len() / n_g;
                st.gnd[c * gs..(c + 1) * gs].iter().any(|&v| v > 0.0)
            }
        })
        .collect();
    // One output per chunk, recycled from the previous iterations' merged ones (emptied: the
    // state `new_out` builds) or new.
    let cl = chunk_len(active.len());
    let outs: Vec<ChunkOut> = (0..active.len().div_ceil(cl))
        .map(|_| pool.pop().unwrap_or_else(|| new_out(ctx)))
        .collect();
    active
        .par_chunks(cl)
        .zip(outs)
        .map(|(chunk, mut out)| {
            let mut outgoing = vec![0.0; n_dirs * w];
            let mut pw = vec![0.0; w];
            let mut intercepted = vec![0.0; w];
            let mut scratch = RecScratch::default();
            for &k in chunk {
                if k < n_t && !off {
                    let hs = first && ctx.inp.emitters.is_empty();
                    let recs = &st.trec.order[groups[k].clone()];
                    emit_turbid_records(ctx, st, recs, hs, &mut scratch, &mut pw, &mut out);
                    continue;
                }
                outgoing.iter_mut().for_each(|v| *v = 0.0);
                intercepted.iter_mut().for_each(|v| *v = 0.0);
                let (origin_up, origin_dn, skip, normal);
                // Facets and ground: scattering points per sub-cell (barycentre, share).
                let mut points: &[(DVec3, f64)] = &[];
                let mut ground = false;
                if k < n_t {
                    let e = &grid.turbid[k];
                    let TrackOptics::Turbid { tables, .. } = &ctx.inp.optics[e.material as usize]
                    else {
                        continue;
                    };
                    for slot in 0..ns {
                        let base = (k * ns + slot) * w;
                        let wv = &st.tur[base..base + w];
                        if wv.iter().all(|&v| v == 0.0) {
                            continue;
                        }
                        let tm = ctx.tur_mat[e.material as usize] as usize;
                        for ch in 0..w {
                            let val = wv[ch];
                            if val == 0.0 {
                                continue;
                            }
                            intercepted[ch] += val;
                            // `outgoing[j · w + ch] += val · trow[j]` for every direction j, by
                            // rows of w (no bounds check per direction).
                            let rows = outgoing.chunks_exact_mut(w);
                            if slot == ns - 1 {
                                let trow = tables[ch % nb].row(tables[0].sun_row().unwrap_or(0));
                                for (o, &t) in rows.zip(&trow[..n_dirs]) {
                                    o[ch] += val * t as f64;
                                }
                            } else {
                                let trow = ctx.slot_row(tm, ch % nb, slot);
                                for (o, &t) in rows.zip(&trow[..n_dirs]) {
                                    o[ch] += val * t;
                                }
                            }
                        }
                    }
                    let p = &st.tur_pts[k];
                    let cell = ctx.entry_cell[k] as usize;
                    let centre = cell_centre(spec, cell);
                    origin_up = if p[3] > 0.0 {
                        DVec3::new(p[0], p[1], p[2]) / p[3]
                    } else {
                        centre
                    };
                    origin_dn = if p[7] > 0.0 {
                        DVec3::new(p[4], p[5], p[6]) / p[7]
                    } else {
                        centre
                    };
                    skip = None;
                    normal = None;
                    for ch in 0..w {
                        let emitted: f64 = (0..n_dirs).map(|j| outgoing[j * w + ch]).sum();
                        let a = intercepted[ch] - emitted;
                        if a != 0.0 {
                            out.absorbed_turbid.push((k as u32, ch));
                            out.absorbed_val.push(a);
                        }
                    }
                } else if k < n_t + n_f {
                    let r = k - n_t;
                    let f = grid.facet_ids[r];
                    let (fr, bk) = &fractions[f as usize];
                    let bi = ctx.brdf_ref.get(r).copied().unwrap_or(u32::MAX);
                    if bi != u32::MAX {
                        // RPV/Hapke: rows of each incidence slot (the sun's last).
                        let set = ctx.inp.facet_brdf[f as usize] as usize;
                        let bi = bi as usize;
                        scatter_slots(
                            &st.fac_slot[bi * ns * w..(bi + 1) * ns * w],
                            (w, nb, n_dirs),
                            |b, slot| ctx.facet_row(set, b, slot),
                            &mut outgoing,
                            |ch, a| {
                                out.absorbed_facet.push((f, ch));
                                out.absorbed_val.push(a);
                            },
                        );
                    }
                    for ch in (0..w).filter(|_| bi == u32::MAX) {
                        let (a, b) = (st.fac_front[r * w + ch], st.fac_back[r * w + ch]);
                        for j in 0..n_dirs {
                            outgoing[j * w + ch] += a * fr[j] as f64 + b * bk[j] as f64;
                        }
                        let emitted: f64 = (0..n_dirs).map(|j| outgoing[j * w + ch]).sum();
                        let lossy = a + b - emitted;
                        if lossy != 0.0 {
                            out.absorbed_facet.push((f, ch));
                            out.absorbed_val.push(lossy);
                        }
                    }
                    let fa = &ctx.inp.facets[f as usize];
                    let centroid = (fa.v[0] + fa.v[1] + fa.v[2]) / 3.0;
                    points = st.fac_pts.of(r);
                    origin_up = centroid;
                    origin_dn = centroid;
                    skip = Some(f);
                    normal = Some((fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize());
                } else {
                    let c = k - n_t - n_f;
                    if ctx.inp.ground_brdf.is_some() {
                        scatter_slots(
                            &st.gnd[c * ns * w..(c + 1) * ns * w],
                            (w, nb, n_dirs),
                            |b, slot| ctx.ground_row(b, slot),
                            &mut outgoing,
                            |ch, a| {
                                out.absorbed_ground.push((c as u32, ch));
                                out.absorbed_val.push(a);
                            },
                        );
                    } else {
                        for ch in 0..w {
                            let a = st.gnd[c * w + ch];
                            for j in 0..n_dirs {
                                outgoing[j * w + ch] += a * ground_fr[j];
                            }
                            let emitted: f64 = (0..n_dirs).map(|j| outgoing[j * w + ch]).sum();
                            if a - emitted != 0.0 {
                                out.absorbed_ground.push((c as u32, ch));
                                out.absorbed_val.push(a - emitted);
                            }
                        }
                    }
                    let o = cell_centre(spec, c);
                    points = st.gnd_pts.of(c);
                    ground = true;
                    origin_up = DVec3::new(o.x, o.y, spec.origin.z);
                    origin_dn = origin_up;
                    skip = None;
                    normal = None;
                }
                let split = k < n_t;
                // First-order sun rays (what turbid cells, facets and the ground scatter of the
                // direct beam) get the hotspot correlation through turbid cells on their way up.
                let hs = first && ctx.inp.emitters.is_empty();
                // Horizontal size of the emitting element, for the image footprints: a turbid
                // cell, a facet or ground sub-cell, or (no scattering point) a column / a point.
                out.foot = if split || (ground && points.is_empty()) {
                    (spec.cell.x, spec.cell.y)
                } else if points.is_empty() {
                    (0.0, 0.0)
                } else {
                    let d = ctx.sub as f64;
                    (spec.cell.x / d, spec.cell.y / d)
                };
                let t_kernel = std::time::Instant::now();
                // Rays without the hotspot go to the batched walk's queue (see
                // `Ctx::trace_any`).
                let queued = ctx.batch && matches!(out.tur.as_deref(), Some(TurAcc::Dense { .. }));
                for j in 0..n_dirs {
                    let v = &outgoing[j * w..(j + 1) * w];
                    if v.iter().all(|&x| x == 0.0) {
                        continue;
                    }
                    if split {
                        // Two-point quadrature of the interception distribution: half the power
                        // from the barycentre of each half of the intercepted energy.
                        let hs_j = hs && ctx.hs_dir[j];
                        for o in [origin_up, origin_dn] {
                            if !hs_j && queued {
                                // What `send` does for this ray (powers v · 0.5, then
                                // `Ctx::queue`).
                                ctx.queue_scaled(o, j, v, 0.5, &mut out);
                            } else {
                                send(ctx, o, j, None, v, 0.5, hs_j, &mut pw, &mut out);
                            }
                        }
                        continue;
                    }
                    let fallback = [(
                        if tiling[j].omega.z > 0.0 {
                            origin_up
                        } else {
                            origin_dn
                        },
                        1.0,
                    )];
                    let pts = if points.is_empty() {
                        &fallback[..]
                    } else {
                        points
                    };
                    for &(pt, share) in pts {
                        let mut origin = if ground {
                            DVec3::new(pt.x, pt.y, spec.origin.z)
                        } else {
                            pt
                        };
                        if let Some(n) = normal {
                            // Start just off the facet on the side the ray leaves through.
                            let side = n.dot(tiling[j].omega).signum();
                            origin += n * side * 1e-9 * spec.cell.min_element();
                        }
                        let hs_j = hs && ctx.hs_dir[j];
                        send(ctx, origin, j, skip, v, share, hs_j, &mut pw, &mut out);
                    }
                }
                out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
            }
            // The rays still queued.
            let t_kernel = std::time::Instant::now();
            ctx.flush(&mut out);
            out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
            out
        })
        .collect()
}

/// Scratch arrays of [`emit_turbid_records`].
#[derive(Default)]
struct RecScratch {
    outgoing: Vec<f64>,
    intercepted: Vec<f64>,
    emitted: Vec<f64>,
    /// `Blend`: power one slot sends along each direction (channels summed), W.
    cj: Vec<f64>,
    /// `Blend`: per direction Σ c·p_up (3), Σ c·p_down (3), Σ c.
    acc: Vec<[f64; 7]>,
    /// Exit groups.
    ex: ExitGroups,
}

/// Rays leaving one turbid cell, grouped per (direction, exit store) (DART 5 paper Figure 7c).
#[derive(Default)]
struct ExitGroups {
    /// Exit stores per cell (6 D² + 1; see [`Ctx::entry_store`]).
    n_exit: usize,
    /// Exit groups `[direction][exit store]`: W per channel, Σ W·q (3), Σ W.
    group: Vec<f64>,
    /// Whether each exit group holds something.
    flag: Vec<bool>,
    /// Exit groups holding something (`direction × n_exit + exit store`).
    touched: Vec<u32>,
}

/// Scatters the turbid stores of one entry in the `Faces`, `Subfaces` and `Blend` modes (DART 5
/// paper §3.2, Figure 7; physics.md §3.6, §6.3): `recs` are the entry's records (see
/// [`TurRecords`]). Each record's power per slot goes along every direction j with the slot's
/// phase row (the sun's row for the sun slot), as in `Off`. `Faces`/`Subfaces`: each non-empty
/// incident store sends its own power from its own two points (half from the barycentre of the
/// first half of its intercepted energy, half from the second's). `Blend`: one pair of rays per
/// direction j, from the barycentres of the per-slot points weighted by the power each slot
/// sends into j. With `turbid_exit_grouping` (cells without facets) the rays of all the
/// entry's stores are first followed to the cell's exit by [`Ctx::to_exit`] and then traced
/// merged, one per (direction, exit face or sub-face) from the power-weighted barycentre of the
/// exit points (Figure 7c); first-order sun rays with the hotspot correlation are traced from
/// their own points (the correlation depends on the path from the scattering point). The power
/// not scattered is booked as absorbed by the entry.
fn emit_turbid_records(
    ctx: &Ctx,
    st: &Stores,
    recs: &[u32],
    hs: bool,
    sc: &mut RecScratch,
    pw: &mut [f64],
    out: &mut ChunkOut,
) {
    let (w, nb, ns, n_dirs) = (ctx.w, ctx.nb, ctx.n_slots, ctx.n_dirs);
    let spec = ctx.inp.spec;
    let tr = &st.trec;
    let k = tr.keys[recs[0] as usize] as usize / ctx.tstores;
    let ent = &ctx.inp.grid.turbid[k];
    let TrackOptics::Turbid { tables, .. } = &ctx.inp.optics[ent.material as usize] else {
        return;
    };
    let tm = ctx.tur_mat[ent.material as usize] as usize;
    let centre = cell_centre(spec, ctx.entry_cell[k] as usize);
    let barycentre = |p: &[f64]| -> (DVec3, DVec3) {
        let up = if p[3] > 0.0 {
            DVec3::new(p[0], p[1], p[2]) / p[3]
        } else {
            centre
        };
        let dn = if p[7] > 0.0 {
            DVec3::new(p[4], p[5], p[6]) / p[7]
        } else {
            centre
        };
        (up, dn)
    };
    sc.outgoing.resize(n_dirs * w, 0.0);
    sc.intercepted.clear();
    sc.intercepted.resize(w, 0.0);
    sc.emitted.clear();
    sc.emitted.resize(w, 0.0);
    let blend = ctx.subfaces == TurbidSubfaces::Blend;
    let cell = ctx.entry_cell[k] as usize;
    let cr = ctx.cells[cell];
    // Exit grouping (Figure 7c) in cells without facets (a facet could be hit before the exit).
    let group = !blend && ctx.inp.params.turbid_exit_grouping && cr.fac_lo == cr.fac_hi;
    if group {
        sc.ex.n_exit = 6 * (ctx.face_d * ctx.face_d) as usize + 1;
        let n = n_dirs * sc.ex.n_exit;
        if sc.ex.flag.len() != n {
            sc.ex.flag = vec![false; n];
            sc.ex.group = vec![0.0; n * (w + 4)];
        }
    }
    if blend {
        sc.cj.resize(n_dirs, 0.0);
        sc.acc.clear();
        sc.acc.resize(n_dirs, [0.0; 7]);
    }
    out.foot = (spec.cell.x, spec.cell.y);
    let sun_row = tables[0].sun_row().unwrap_or(0);
    let power = |r: u32| -> f64 {
        let r = r as usize;
        tr.pow[r * tr.ns_w..(r + 1) * tr.ns_w].iter().sum()
    };
    let total: f64 = recs.iter().map(|&r| power(r)).sum();
    for &r in recs {
        // The store's rays are dropped below its share of the threshold of the entry's rays:
        // splitting an entry's emission into stores does not make its rays less significant.
        out.ray_scale = if blend || total <= 0.0 {
            1.0
        } else {
            power(r) / total
        };
        let r = r as usize;
        sc.outgoing.iter_mut().for_each(|v| *v = 0.0);
        for slot in 0..ns {
            let base = (r * ns + slot) * w;
            let wv = &tr.pow[base..base + w];
            if wv.iter().all(|&v| v == 0.0) {
                continue;
            }
            if blend {
                sc.cj.iter_mut().for_each(|v| *v = 0.0);
            }
            for ch in 0..w {
                let val = wv[ch];
                if val == 0.0 {
                    continue;
                }
                sc.intercepted[ch] += val;
                let mut put = |j: usize, t: f64| {
                    let c = val * t;
                    sc.outgoing[j * w + ch] += c;
                    if blend {
                        sc.cj[j] += c;
                    }
                };
                if slot == ns - 1 {
                    let trow = tables[ch % nb].row(sun_row);
                    for (j, &t) in trow.iter().take(n_dirs).enumerate() {
                        put(j, t as f64);
                    }
                } else {
                    let trow = ctx.slot_row(tm, ch % nb, slot);
                    for (j, &t) in trow.iter().enumerate() {
                        put(j, t);
                    }
                }
            }
            if blend {
                let pb = (r * ns + slot) * 8;
                let (pu, pd) = barycentre(&tr.pts[pb..pb + 8]);
                for (a, &c) in sc.acc.iter_mut().zip(&sc.cj) {
                    if c != 0.0 {
                        a[0] += c * pu.x;
                        a[1] += c * pu.y;
                        a[2] += c * pu.z;
                        a[3] += c * pd.x;
                        a[4] += c * pd.y;
                        a[5] += c * pd.z;
                        a[6] += c;
                    }
                }
            }
        }
        let (pu, pd) = if blend {
            (centre, centre)
        } else {
            barycentre(&tr.pts[r * 8..r * 8 + 8])
        };
        let t_kernel = std::time::Instant::now();
        // Rays without the hotspot go to the batched walk's queue (see `Ctx::trace_any`).
        let queued = ctx.batch && matches!(out.tur.as_deref(), Some(TurAcc::Dense { .. }));
        for j in 0..n_dirs {
            let v = &sc.outgoing[j * w..(j + 1) * w];
            if v.iter().all(|&x| x == 0.0) {
                continue;
            }
            for (e, x) in sc.emitted.iter_mut().zip(v) {
                *e += x;
            }
            let (o_up, o_dn) = if blend {
                let a = &sc.acc[j];
                if a[6] > 0.0 {
                    (
                        DVec3::new(a[0], a[1], a[2]) / a[6],
                        DVec3::new(a[3], a[4], a[5]) / a[6],
                    )
                } else {
                    (centre, centre)
                }
            } else {
                (pu, pd)
            };
            // Two-point quadrature of the store's interception distribution.
            let hs_j = hs && ctx.hs_dir[j];
            for o in [o_up, o_dn] {
                if group && !hs_j {
                    ctx.to_exit(cell, o, j, v, 0.5, &mut sc.ex, pw, out);
                } else if !hs_j && queued {
                    // What `send` does for this ray (powers v · 0.5, then `Ctx::queue`).
                    ctx.queue_scaled(o, j, v, 0.5, out);
                } else {
                    send(ctx, o, j, None, v, 0.5, hs_j, pw, out);
                }
            }
        }
        out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
    }
    if group {
        // The rays that left the cell through the same exit store along the same direction,
        // merged (DART 5 paper §3.2, Figure 7c): one ray per (exit sub-face, direction) from
        // the power-weighted barycentre of their exit points.
        let t_kernel = std::time::Instant::now();
        let ne = sc.ex.n_exit;
        sc.ex.touched.sort_unstable();
        let mut n = 0;
        while n < sc.ex.touched.len() {
            let j = sc.ex.touched[n] as usize / ne;
            let mut m = n;
            let mut total = 0.0;
            while m < sc.ex.touched.len() && sc.ex.touched[m] as usize / ne == j {
                total += sc.ex.group[sc.ex.touched[m] as usize * (w + 4) + w + 3];
                m += 1;
            }
            for &g in &sc.ex.touched[n..m] {
                let g = g as usize * (w + 4);
                let rec = &mut sc.ex.group[g..g + w + 4];
                let wt = rec[w + 3];
                if wt > 0.0 {
                    let o = DVec3::new(rec[w], rec[w + 1], rec[w + 2]) / wt;
                    pw.copy_from_slice(&rec[..w]);
                    out.ray_scale = if total > 0.0 { wt / total } else { 1.0 };
                    ctx.trace(o, j, None, pw, out);
                }
                rec.iter_mut().for_each(|x| *x = 0.0);
            }
            n = m;
        }
        for &g in &sc.ex.touched {
            sc.ex.flag[g as usize] = false;
        }
        sc.ex.touched.clear();
        out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
    }
    out.ray_scale = 1.0;
    for ch in 0..w {
        let a = sc.intercepted[ch] - sc.emitted[ch];
        if a != 0.0 {
            out.absorbed_turbid.push((k as u32, ch));
            out.absorbed_val.push(a);
        }
    }
}

/// Scatters one element's power stored per incidence slot (`stored[slot · w + ch]`, w channels
/// of `nb` bands) with each slot's row (`row(band, slot)`, over the tiling directions) into
/// `outgoing[dir · w + ch]`, and reports per channel the stored power not scattered
/// (absorbed, W) through `absorbed(ch, W)` when it is not zero.
fn scatter_slots<'r>(
    stored: &[f64],
    (w, nb, n_dirs): (usize, usize, usize),
    row: impl Fn(usize, usize) -> &'r [f64],
    outgoing: &mut [f64],
    mut absorbed: impl FnMut(usize, f64),
) {
    let ns = stored.len() / w;
    for ch in 0..w {
        let b = ch % nb;
        let mut a = 0.0;
        for slot in 0..ns {
            let val = stored[slot * w + ch];
            if val == 0.0 {
                continue;
            }
            a += val;
            let r = row(b, slot);
            for j in 0..n_dirs {
                outgoing[j * w + ch] += val * r[j];
            }
        }
        let emitted: f64 = (0..n_dirs).map(|j| outgoing[j * w + ch]).sum();
        if a - emitted != 0.0 {
            absorbed(ch, a - emitted);
        }
    }
}

/// Hotspot terms of one turbid material for the first-order sun ray scattered along `view`
/// (upward), per unit path length: `[b, c]` such that at distance s (m) from the scattering
/// point the extinction coefficient along the ray is `u_f (G_v − b e^{−c s})` instead of
/// `u_f G_v`. This is physics.md §3.5, the SAILH joint gap probability of Kuusk 1985 /
/// Verhoef 1998 put into the ray tracking: per unit *height* z = s μ_v the extinction is
/// `u_f (k_v − √(k_s k_v) e^{−c_z z})` with `k_s = G_s/μ_s`, `k_v = G_v/μ_v`,
/// `c_z = 2Δ/(l (k_s + k_v))` (m⁻¹), `Δ = |tan θ_v e_v − tan θ_s e_s|` the horizontal separation
/// of the sun and view rays per unit height and `l` the leaf dimension, m; so
/// `b = √(k_s k_v) μ_v` and `c = c_z μ_v`. `sun` is the propagation vector of the beam
/// (downward). `[0, 0]` for downward views.
pub fn hotspot_terms(
    sun: DVec3,
    view: DVec3,
    g_sun: f64,
    g_view: f64,
    leaf_size_m: f64,
) -> [f64; 2] {
    let (mu_s, mu_v) = (-sun.z, view.z);
    if mu_s <= 0.0 || mu_v <= 0.0 || leaf_size_m <= 0.0 || g_sun <= 0.0 || g_view <= 0.0 {
        return [0.0; 2];
    }
    let (ks, kv) = (g_sun / mu_s, g_view / mu_v);
    let dx = view.x / mu_v + sun.x / mu_s;
    let dy = view.y / mu_v + sun.y / mu_s;
    let delta = (dx * dx + dy * dy).sqrt();
    [
        (ks * kv).sqrt() * mu_v,
        2.0 * delta / (leaf_size_m * (ks + kv)) * mu_v,
    ]
}

/// Hotspot terms per unit path length for any geometry (the LiDAR return, physics.md §9.6
/// "hotspot caveat"): a ray leaving a first-order collision along `d_out` after arriving along
/// `d_in` (propagation vectors) is at distance s from the reversed incoming ray by
/// `s |d_out + d_in|`; the gaps stay correlated over a leaf dimension `l` (Kuusk 1985), so the
/// extinction coefficient along it is `u_f (G_out − b e^{−c s})` with `b = √(G_in G_out)` and
/// `c = 2|d_out + d_in| / (l (G_in + G_out))` (m⁻¹). Near backscatter in a horizontal layer this
/// is [`hotspot_terms`] to first order in the angle; exactly at backscatter (a monostatic
/// LiDAR whose receiver sits at the emitter) `b = G` and `c = 0`: the return crosses no
/// leaf it has not already passed (one-way transmittance). `[0, 0]` when `l = 0`.
pub fn hotspot_terms_path(
    d_in: DVec3,
    d_out: DVec3,
    g_in: f64,
    g_out: f64,
    leaf_size_m: f64,
) -> [f64; 2] {
    if leaf_size_m <= 0.0 || g_in <= 0.0 || g_out <= 0.0 {
        return [0.0; 2];
    }
    [
        (g_in * g_out).sqrt(),
        2.0 * (d_out + d_in).length() / (leaf_size_m * (g_in + g_out)),
    ]
}

/// `∫_{z0}^{z0+dz} e^{−c z} dz` (m), stable for c → 0 and large c·z (z, dz in m, c in m⁻¹).
#[inline]
pub fn hotspot_integral(c: f64, z0: f64, dz: f64) -> f64 {
    let x = c * dz;
    if x < 1e-9 {
        super::fastmath::exp(-c * z0) * dz * (1.0 - 0.5 * x)
    } else {
        super::fastmath::exp(-c * z0) * attenuation(x).0 / c
    }
}

fn cell_centre(spec: &GridSpec, c: usize) -> DVec3 {
    let [i, j, k] = spec.ijk(c);
    spec.origin + (DVec3::new(i as f64, j as f64, k as f64) + 0.5) * spec.cell
}
