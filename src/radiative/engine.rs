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
//!   sector. Each crossing books the barycentres of the first and second halves of its
//!   intercepted energy (DART stores two points per crossing; physics.md §3.6); their sum gives
//!   the cell's barycentre p̄ of intercepted energy. The power a cell scatters into direction
//!   j leaves two rays, half each, from `(x̄ ± σx, ȳ ± σy, z*_j)`: per axis the source is the
//!   maximum-entropy density with p̄'s position in the cell as mean (the truncated
//!   exponential, which is exactly Beer's-law interception along an axis), σ its horizontal
//!   spread ([`max_entropy_sigma`]) and z*_j the height at which one ray carries the exact
//!   expectation of its vertical profile through a homogeneous medium along j
//!   ([`exp_moment_position`]). On the DISORT layer the worst BRF error then no longer depends
//!   on the cell size (docs/performance.md). Rays scattered by a cell start *inside* it, so
//!   within-cell re-interception is tracked, not approximated.
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
//! * **Determinism and memory**: emitters are processed in fixed chunks (16 per pass, more
//!   on large scenes so that no chunk holds more than `chunk_rays` rays; independent of the
//!   thread count) and chunk results are merged in chunk order as they finish (`stream.rs`),
//!   so products are bit-identical on any number of threads and only the chunks in flight
//!   are held.

mod accumulators;
mod ctx;
mod emit;
mod geometry;
mod hotspot;
mod iterate;
mod launch;
mod merge;
mod stream;
#[cfg(test)]
mod tests;
mod thermal;

pub use crate::radiative::walk::batch::{batch_lanes, instruction_set, kernel_isa};
/// The tracker's parameter and optics types live with the stage's settings
/// ([`crate::resources::tracking`]).
pub use crate::resources::tracking::{KernelIsa, TrackOptics, TrackingParams};
pub(in crate::radiative) use accumulators::*;
pub use accumulators::{CHUNK_RAYS, DENSE_BYTES, dense_bytes};
pub(in crate::radiative) use ctx::*;
pub(in crate::radiative) use emit::*;
pub(in crate::radiative) use geometry::*;
pub use geometry::{
    barycentre, cell_exit, entry_store, exp_moment_position, half_barycentres,
    half_barycentres_fast, half_barycentres_with, intersect, max_entropy_sigma,
};
pub use hotspot::{BACKSCATTER_ROUNDING, hotspot_integral, hotspot_terms, hotspot_terms_path};
pub use iterate::run;
pub(in crate::radiative) use iterate::*;
pub use launch::{LaunchPlan, facet_outline_m, launch_plan, remap_wrong_side};
pub(in crate::radiative) use merge::*;
pub use stream::ahead;
pub(in crate::radiative) use stream::*;
pub use thermal::ThermalSources;
pub(in crate::radiative) use thermal::*;

use super::dda::{floor_i64, skip_field};
use super::fastmath::{HalfBarycentres, attenuation};
use super::images::{ImageGrid, rem_euclid_period};
use crate::direction::DirectionSet;
use crate::phase::PhaseTable;
use crate::radiative::walk::batch;
use crate::resources::facets::{Facet, FacetKind};
use crate::resources::grid::{CellGrid, GridSpec};
use crate::scene::desc::{BoundaryMode, TurbidSubfaces};
use glam::DVec3;
use rayon::prelude::*;

/// The `pulp` dispatch target of a [`KernelIsa`] cap on this CPU (the type is a setting, in
/// `resources::tracking`; its dispatch belongs to the walks).
pub(crate) fn isa_arch(isa: KernelIsa) -> pulp::Arch {
    #[cfg(target_arch = "x86_64")]
    {
        match isa {
            KernelIsa::Best => pulp::Arch::new(),
            KernelIsa::Avx2 => pulp::x86::V3::try_new().map_or(pulp::Arch::Scalar, pulp::Arch::V3),
            KernelIsa::Baseline => pulp::Arch::Scalar,
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = isa;
        pulp::Arch::new()
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
    /// Thermal emission (issue #34): `ε B(T)` per element and band, tracked on its own set of
    /// channels after the sun and sky ones; `None` for a solar-only (R) run.
    pub thermal: Option<&'a ThermalSources>,
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
    /// Channels per element (bands × (1 + sky + thermal)).
    pub n_channels: usize,
    /// Bands.
    pub n_bands: usize,
    /// Whether the sky channels exist.
    pub has_sky: bool,
    /// Whether the thermal channels exist (the last `n_bands` channels: emission and the
    /// thermal sky, see [`ThermalSources`]).
    pub has_thermal: bool,
    /// Source power entering the scene per channel, W.
    pub source: Vec<f64>,
    /// The thermal sky's part of the thermal channels' `source` per band, W (empty without
    /// thermal channels).
    pub thermal_sky_source: Vec<f64>,
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
    /// Which walk traced the lean rays (flux tracking only; `None` for Monte Carlo).
    pub walk: Option<WalkInfo>,
}

/// Which walk traced the flux-tracking rays of a run (`summary.json` key `walk`): the batched
/// walk's dispatch target, precision and lanes, or the baseline one-ray walk. Runs with the
/// same `WalkInfo` give the same product bits on any CPU; `f32` (16 lanes, AVX-512) and `f64`
/// walks differ by ~3e-7 relative, 8 and 4 `f64` lanes in the last bits (summation order).
/// Hotspot-correlated rays and scenes outside the lean tracker (facets, several turbid entries
/// per cell, topography, incident-face stores) are always walked one by one in `f64`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct WalkInfo {
    /// `avx512`, `avx2` (the batched walk on that instruction set) or `baseline` (rays one by
    /// one, portable code: no batched walk on this CPU, or the scene or settings exclude it).
    pub kernel: &'static str,
    /// `f32` (single-precision geometry of the 16-lane walk) or `f64`.
    pub precision: &'static str,
    /// Rays in flight: 16, 8, 4, or 1 (baseline).
    pub lanes: u32,
}

impl RadiativeResult {
    /// An `R+T` result from a solar run (`self`, no thermal channels) and a thermal run `t` of
    /// the same scene (its last `n_bands` channels the thermal ones): every per-element array
    /// gets the solar run's channels, then `t`'s thermal ones. Two runs rather than one with
    /// both channel sets, because the scattering points of a run are the barycentres of all its
    /// channels' interceptions: sharing them would move the solar scattering points towards
    /// the (uniform) thermal ones (measured: solar albedo −2.3 % on a turbid layer).
    /// Run statistics add up; `iterations` and `converged` are the solar run's when it needed
    /// more iterations.
    pub fn with_thermal_of(self, t: RadiativeResult) -> RadiativeResult {
        let (w, nb) = (self.n_channels, self.n_bands);
        let tw = t.n_channels;
        let join = |a: &[f64], b: &[f64]| -> Vec<f64> {
            let n = a.len() / w.max(1);
            let mut out = Vec::with_capacity(n * (w + nb));
            for e in 0..n {
                out.extend_from_slice(&a[e * w..(e + 1) * w]);
                out.extend_from_slice(&b[e * tw + tw - nb..(e + 1) * tw]);
            }
            out
        };
        let mut escaped_per_iteration = Vec::new();
        for i in 0..self
            .escaped_per_iteration
            .len()
            .max(t.escaped_per_iteration.len())
        {
            let a = self
                .escaped_per_iteration
                .get(i)
                .cloned()
                .unwrap_or(vec![0.0; w]);
            let b = t
                .escaped_per_iteration
                .get(i)
                .cloned()
                .unwrap_or(vec![0.0; tw]);
            escaped_per_iteration.push(join(&a, &b));
        }
        RadiativeResult {
            n_channels: w + nb,
            n_bands: nb,
            has_sky: self.has_sky,
            has_thermal: true,
            source: join(&self.source, &t.source),
            thermal_sky_source: t.thermal_sky_source.clone(),
            escaped: join(&self.escaped, &t.escaped),
            images: join(&self.images, &t.images),
            image_grid: self.image_grid,
            escaped_per_iteration,
            absorbed_turbid: join(&self.absorbed_turbid, &t.absorbed_turbid),
            intercepted_turbid: join(&self.intercepted_turbid, &t.intercepted_turbid),
            absorbed_facet: join(&self.absorbed_facet, &t.absorbed_facet),
            intercepted_facet: join(&self.intercepted_facet, &t.intercepted_facet),
            absorbed_ground: join(&self.absorbed_ground, &t.absorbed_ground),
            intercepted_ground: join(&self.intercepted_ground, &t.intercepted_ground),
            lost: join(&self.lost, &t.lost),
            remaining: join(&self.remaining, &t.remaining),
            iterations: self.iterations.max(t.iterations),
            q: join(&self.q, &t.q),
            converged: self.converged && t.converged,
            rays: self.rays + t.rays,
            crossings: self.crossings + t.crossings,
            skipped: self.skipped + t.skipped,
            kernel_seconds: self.kernel_seconds + t.kernel_seconds,
            launch: self.launch,
            walk: self.walk,
        }
    }
}
