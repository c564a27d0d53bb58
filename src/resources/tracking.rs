//! Resources of the Direction, Phase and Radiative stages, and the flux tracker's parameter
//! and optics types they hold ([`TrackingParams`], [`KernelIsa`], [`TrackOptics`]; the
//! Radiative engine re-exports them from `radiative::engine`).

use crate::direction::DirectionSet;
use crate::phase::{PhaseTable, TableParams};
use crate::scene::desc::{Preset, RadiativeDesc, TurbidSubfaces};
use bevy_ecs::prelude::Resource;
use glam::DVec3;

/// Smallest direction count of the reference preset (BRF within 1 % of DISORT at 75° view
/// zenith in the NIR needs ≥ 400 directions; tests/radiative_oracles.rs).
pub const REFERENCE_MIN_DIRECTIONS: usize = 400;

/// The scene's direction parameters (resource inserted at spawn; defaults when absent).
#[derive(Debug, Clone, Default, Resource)]
pub struct DirectionRequest(pub crate::direction::DirectionParams);

/// Settings of the Direction/Phase/Radiative stages after applying preset and scene knobs.
#[derive(Debug, Clone, Resource)]
pub struct RadiativeSettings {
    /// Preset in force.
    pub preset: Preset,
    /// Tracking parameters.
    pub tracking: TrackingParams,
    /// Phase-table sampling.
    pub tables: TableParams,
    /// Store interception per incident direction (exact) instead of per angular sector.
    pub per_direction_stores: bool,
    /// Oversampling factor η of the orthographic images (pixels of Δx/η × Δy/η).
    pub image_oversampling: u32,
}

impl RadiativeSettings {
    /// Preset values, then the scene's explicit knobs.
    pub fn resolve(preset: Preset, scene: Option<&RadiativeDesc>) -> Self {
        let (tracking, tables, per_dir) = match preset {
            Preset::Preview => (TrackingParams::preview(), TableParams::preview(), false),
            Preset::Default => (
                TrackingParams::dart_default(),
                TableParams::dart_default(),
                false,
            ),
            Preset::Reference => (TrackingParams::reference(), TableParams::reference(), true),
        };
        let mut s = Self {
            preset,
            tracking,
            tables,
            per_direction_stores: per_dir,
            image_oversampling: 1,
        };
        if let Some(r) = scene {
            if let Some(x) = r.max_iterations {
                s.tracking.max_iterations = x;
            }
            if let Some(x) = r.albedo_threshold {
                s.tracking.albedo_threshold = x;
            }
            if let Some(x) = r.ray_threshold {
                s.tracking.ray_threshold = x;
            }
            if let Some(x) = r.launch_spacing_m {
                s.tracking.launch_spacing_m = Some(x);
            }
            if let Some(x) = r.extrapolate {
                s.tracking.extrapolate = x;
            }
            if let Some(x) = r.per_direction_stores {
                s.per_direction_stores = x;
            }
            if let Some(x) = r.turbid_subfaces {
                s.tracking.turbid_subfaces = x;
            }
            if let Some(x) = r.turbid_exit_grouping {
                s.tracking.turbid_exit_grouping = x;
            }
            s.image_oversampling = r.image_oversampling.max(1);
        }
        s
    }
}

/// The discrete directions of the scene (Direction stage).
#[derive(Debug, Clone, Resource)]
pub struct Directions {
    /// The set.
    pub set: DirectionSet,
    /// Propagation vector of the direct sun beam (downward, exact).
    pub sun: DVec3,
    /// Interception slot of each tiling direction.
    pub sector_of: Vec<u16>,
    /// Number of interception slots for tiling directions (the exact sun has one more).
    pub n_sectors: usize,
}

/// Optics of every material as the tracker needs it (Phase stage).
#[derive(Debug, Clone, Resource)]
pub struct OpticsTables {
    /// Per material id.
    pub optics: Vec<TrackOptics>,
    /// Bytes held by the phase tables.
    pub bytes: usize,
    /// Largest relative row renormalisation (sector-integration error of the tables).
    pub max_renormalisation: f64,
}

/// Exact Lambertian fractions per facet (front, back), computed when facets exist.
#[derive(Debug, Clone, Default, Resource)]
pub struct FacetFractions(pub Vec<(Vec<f32>, Vec<f32>)>);

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
    /// facets and `launch_target_se` (see
    /// [`launch_plan`](crate::radiative::engine::launch_plan)).
    pub launch_spacing_m: Option<f64>,
    /// Target standard error of the direct-sun interception (fraction of the sun power) that
    /// the automatic launch spacing aims at (see
    /// [`launch_plan`](crate::radiative::engine::launch_plan)).
    pub launch_target_se: f64,
    /// Largest number of sun launch points the automatic spacing may use; also bounds the
    /// number of ground scattering points (columns × D²) of the automatic sub-cell factor.
    pub max_launch_points: usize,
    /// Largest sub-cell factor D the automatic choice may use (see
    /// [`launch_plan`](crate::radiative::engine::launch_plan)); the scene's `grid.subcells` is
    /// a minimum.
    pub max_auto_subcells: u32,
    /// Extrapolate the remaining orders geometrically.
    pub extrapolate: bool,
    /// Maximum scene crossings of one ray in repetitive scenes (DART default 1000).
    pub max_crossings: u32,
    /// Empty-space skipping: rays jump over boxes of empty cells (no tracked turbid entry, no
    /// facet) found from a chessboard distance field ([`crate::radiative::dda::skip_field`])
    /// instead of visiting them one by one; the same cells, segment ends and products bit for
    /// bit ([`crate::radiative::dda::Dda::skip_to`]). Off: every cell is visited (kept for the
    /// equality tests).
    pub skip_empty: bool,
    /// Turbid interception stores per incident face / sub-face (DART 5 paper §3.2, Figure 7;
    /// see [`TurbidSubfaces`]).
    pub turbid_subfaces: TurbidSubfaces,
    /// With `Faces` / `Subfaces`: a turbid cell's scattered rays are followed to the cell's
    /// exit and merged per (exit face or sub-face, direction) (DART 5 paper Figure 7c).
    pub turbid_exit_grouping: bool,
    /// The lean tracker's rays queued per chunk and walked sixteen (AVX-512, single-precision
    /// geometry: [`TrackingParams::batch_f32`]), eight (AVX-512, double precision) or four
    /// (AVX2) at a time (see the `walk` module of `radiative`). In double precision: the same
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
    /// (default on; `walk::batch::wide32`: each lane's traversal in its cell's frame, path
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
    /// Largest number of nominal rays in one chunk of emitters (default [`CHUNK_RAYS`]): bounds the memory of the chunks in flight on
    /// large scenes. Scenes of up to 16 such chunks per pass are cut into 16 chunks whatever
    /// this is; on larger ones it sets the chunking, hence the summation order (products
    /// within ~1e-15 relative).
    #[serde(skip)]
    pub chunk_rays: usize,
}

/// Default of [`TrackingParams::chunk_rays`]: the largest number of rays (nominal: emitters ×
/// rays per emitter) in one chunk of the flux tracking. A chunk's event lists (facet, ground
/// and image hits, at most one per ray, ≤ 68 B each with two channels) stay under ~70 MB, and
/// only the chunks in flight are held.
pub const CHUNK_RAYS: usize = 1 << 20;

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
            chunk_rays: CHUNK_RAYS,
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
