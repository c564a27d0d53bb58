//! Scene-wide resources set by the spawn step: scene info, terrain, run settings (with the
//! setting types the engines read: the Monte Carlo [`SamplerKind`], the LiDAR chunk size and
//! [`FarRoulette`]), stage errors.

use crate::geometry::terrain::Terrain;
use crate::physics::spectral::SpectralBand;
use crate::physics::sun::SolarPosition;
use crate::scene::desc::{BandDesc, BoundaryMode};
use bevy_ecs::prelude::Resource;
use std::path::PathBuf;

/// Scene-wide facts copied from the description.
#[derive(Debug, Clone, Resource)]
pub struct SceneInfo {
    /// Scene name.
    pub name: String,
    /// Scene file (or `<generated>`).
    pub source: PathBuf,
    /// Seed of every random choice.
    pub seed: u64,
    /// Bands as written, except that a `sensor_band`/`srf_file` band given without
    /// `wavelength_nm` gets its response's centroid there, nm (so `wavelength_nm` > 0 always).
    pub bands: Vec<BandDesc>,
    /// Spectral response of each band (same order as `bands`): monochromatic, Gaussian, or the
    /// tabulated SRF of a sensor band or SRF file (files are read once, at spawn).
    pub band_responses: Vec<SpectralBand>,
    /// Sun and sky, resolved: final sun angles whichever way the scene gave them.
    pub illumination: Illumination,
    /// The factor (1 AU / d)² that `illumination.irradiance_w_m2_um` was multiplied by (Earth–Sun
    /// distance d at the scene's `sun_position` date); `None` when no correction was applied
    /// (explicit angles, or `earth_sun_distance_correction: false`).
    pub irradiance_distance_factor: Option<f64>,
    /// The full NREL SPA result when the sun was given by `sun_position` (zenith, refraction,
    /// compass azimuth, Earth–Sun distance, …); `None` for explicit angles.
    pub solar_position: Option<SolarPosition>,
    /// Scene extent (x, y), metres.
    pub size: (f64, f64),
    /// Cell size, metres.
    pub cell: (f64, f64, f64),
    /// User-fixed scene height, metres.
    pub height: Option<f64>,
    /// Sub-cell factor D.
    pub subcells: u32,
    /// Boundary mode.
    pub boundary: BoundaryMode,
    /// Where the scene lies on a map (`georeference` of the scene); `None`: no geospatial
    /// products.
    pub georeference: Option<crate::scene::georef::Georeference>,
}

pub use crate::scene::resolve::Illumination;

/// The ground shape (flat when the scene has no `Ground` with a DEM).
#[derive(Debug, Clone, Resource)]
pub struct TerrainRes(pub Terrain);

/// The thermal part of a run (issue #34): the scene's `thermal` section in a `T` or `R+T`
/// run. Absent: a solar-only run (no emission work).
#[derive(Debug, Clone, Resource)]
pub struct ThermalRun {
    /// `T` or `RT`.
    pub mode: crate::scene::desc::RunMode,
    /// Temperatures (validated: every emitting optics key has one, or the leaf key of a turbid
    /// key takes the turbid key's).
    pub desc: crate::scene::desc::ThermalDesc,
}

/// Run settings that are not part of the scene.
#[derive(Debug, Clone, Resource)]
pub struct RunSettings {
    /// Refuse grids whose estimated memory exceeds this many bytes.
    pub max_memory_bytes: u64,
    /// Show progress bars.
    pub progress: bool,
    /// Accuracy preset chosen on the command line (overrides the scene's preset; the scene's
    /// individual knobs still apply).
    pub preset: Option<crate::scene::desc::Preset>,
    /// Which passive solver runs: DART flux tracking (Radiative stage, the default) or the
    /// Monte Carlo photon tracker (Photon stage).
    pub solver: Solver,
    /// Oversampling factor η of the orthographic images chosen on the command line
    /// (overrides the scene's `radiative.image_oversampling`).
    pub image_oversampling: Option<u32>,
    /// Empty-space skipping in the ray and photon walks (default on; same products bit for
    /// bit, see [`crate::radiative::dda::Dda::skip_to`]). Off: every cell is visited (kept for
    /// the equality tests and for measuring).
    pub skip_empty: bool,
    /// The flux tracker's batched 8- or 4-ray walk (default on; products agree with the
    /// one-ray walk to rounding, see [`crate::radiative::engine::TrackingParams::batch_walk`]).
    /// Off: one ray at a time (kept for the equality tests and for measuring).
    pub batch_walk: bool,
    /// Most capable instruction set of the flux-tracking walks (default: the best this CPU
    /// has; products equal to rounding on each, see
    /// [`crate::radiative::engine::TrackingParams::kernel_isa`]).
    pub kernel_isa: crate::resources::tracking::KernelIsa,
    /// The batched walk in single-precision geometry on 16 lanes on AVX-512 CPUs (default on;
    /// see [`crate::radiative::engine::TrackingParams::batch_f32`]). Off: the double-precision
    /// batched walk on 8 lanes, whose products agree with the one-ray walk's to rounding.
    pub batch_f32: bool,
    /// Largest number of nominal rays in one chunk of the flux tracking (default
    /// [`crate::resources::tracking::CHUNK_RAYS`]; see
    /// [`crate::resources::tracking::TrackingParams::chunk_rays`]): for tests of the chunk
    /// scheduler on small scenes.
    pub chunk_rays: usize,
    /// LiDAR pulses tracked per chunk; with an output folder, a scan of more pulses than one
    /// chunk streams its waveforms to disk chunk by chunk (memory bounded by a chunk, same
    /// products; [`crate::lidar::simulate::LidarChunks`]).
    pub lidar_chunk_pulses: usize,
    /// The LiDAR expected-value estimator's far-photon roulette (default: its distance scale
    /// from the scene; every setting has the same expectation,
    /// [`FarRoulette`]).
    pub lidar_far_roulette: FarRoulette,
    /// The LiDAR expected-value estimator's column quadrature of the first-order return
    /// (default on; off: every beam ray scores its own first order, the same expectation,
    /// [`crate::lidar::tracking::Beam::first_order_columns`]).
    pub lidar_first_order_columns: bool,
}

/// Passive solver.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Solver {
    /// Discrete-ordinate flux tracking (Radiative stage).
    #[default]
    FluxTracking,
    /// Forward Monte Carlo (Photon stage) with `photons` photons and a direction sampler.
    MonteCarlo {
        /// Photons (sun + sky).
        photons: u64,
        /// Direction sampler.
        sampler: SamplerKind,
    },
}

impl Solver {
    /// True for the Monte Carlo solver.
    pub fn is_monte_carlo(&self) -> bool {
        matches!(self, Solver::MonteCarlo { .. })
    }
    /// True when the Phase stage's tables are needed (flux tracking or discrete Monte Carlo).
    pub fn needs_phase_tables(&self) -> bool {
        match self {
            Solver::FluxTracking => true,
            Solver::MonteCarlo { sampler, .. } => sampler.is_discrete(),
        }
    }
}

/// How the photon engine draws scattering directions (`photon::engine` re-exports it).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum SamplerKind {
    /// Exact continuous phase functions: the unbiased reference.
    Continuous,
    /// DART Ray-Carlo over the discrete directions, Walker/Vose alias tables.
    Alias,
    /// DART Ray-Carlo over the discrete directions, DART's Box method.
    Box {
        /// Largest max/min probability ratio inside a class.
        gamma: f64,
        /// Box budget per incident row.
        max_boxes: usize,
    },
}

impl SamplerKind {
    /// True for the discrete (Ray-Carlo) modes.
    pub fn is_discrete(&self) -> bool {
        !matches!(self, SamplerKind::Continuous)
    }
    /// Name used in products.
    pub fn name(&self) -> &'static str {
        match self {
            SamplerKind::Continuous => "continuous",
            SamplerKind::Alias => "alias",
            SamplerKind::Box { .. } => "box",
        }
    }
}

/// Pulses tracked per chunk: the memory of a streamed scan is bounded by one chunk's waveforms
/// (plus every pulse's returns and energies); 8192 pulses keep both cores busy and each
/// chunk's parallel tail short.
pub const DEFAULT_CHUNK_PULSES: usize = 8192;

/// The expected-value estimator's far-photon roulette of multiple scattering
/// ([`crate::lidar::tracking::Beam::far_roulette_m`]); every setting has the same expectation.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum FarRoulette {
    /// Distance scale ρ₀ from the scene (`far_roulette_scale_m`; the default).
    #[default]
    Auto,
    /// A given distance scale ρ₀ (m, > 0): for tests and studies.
    ScaleM(f64),
    /// Every multiple-scattering photon goes on (for the equality tests and for measuring).
    Off,
}

impl Default for RunSettings {
    fn default() -> Self {
        Self {
            max_memory_bytes: default_max_memory(),
            progress: false,
            preset: None,
            solver: Solver::FluxTracking,
            image_oversampling: None,
            skip_empty: true,
            batch_walk: true,
            kernel_isa: Default::default(),
            batch_f32: true,
            chunk_rays: crate::resources::tracking::CHUNK_RAYS,
            lidar_chunk_pulses: DEFAULT_CHUNK_PULSES,
            lidar_far_roulette: Default::default(),
            lidar_first_order_columns: true,
        }
    }
}

/// 75 % of the machine's physical memory (from /proc/meminfo; 16 GiB if it cannot be read).
pub fn default_max_memory() -> u64 {
    let total = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("MemTotal:"))
                .and_then(|l| {
                    l.split_whitespace()
                        .nth(1)
                        .and_then(|v| v.parse::<u64>().ok())
                })
        })
        .map(|kib| kib * 1024)
        .unwrap_or(16 << 30);
    total / 4 * 3
}

/// Where products go (inserted by the CLI or the caller; without it nothing is written).
#[derive(Debug, Clone, Resource)]
pub struct OutputDir(pub PathBuf);

/// Which products the Output stage writes (absent: every product). Entries are paths relative
/// to the output folder, files (`brf.csv`, `lai.exr`) or folders (`images`, `budget`,
/// `lidar`); `summary.json` is always written. Sequences keep only what a look-up table
/// needs (`crate::sequence`).
#[derive(Debug, Clone, Resource)]
pub struct ProductSelection(pub Vec<String>);

impl ProductSelection {
    /// Whether the product at `rel` (a file or a folder) is wanted.
    pub fn wants(&self, rel: &str) -> bool {
        rel == "summary.json"
            || self.0.iter().any(|k| {
                k == rel || k.starts_with(&format!("{rel}/")) || rel.starts_with(&format!("{k}/"))
            })
    }
}

/// Present when the scene needs no passive solve (a LiDAR-only scene, or `passive: false`;
/// [`crate::scene::desc::SceneDesc::runs_passive`]): the Radiative stage and the Photon stage's
/// passive Monte Carlo do not run and write no passive products. Absent (every other scene,
/// and worlds built through the Rust API without a scene description): they run.
#[derive(Debug, Clone, Copy, Default, Resource)]
pub struct SkipPassive;

/// Errors raised by systems; the simulation stops after the stage that raised one.
#[derive(Debug, Clone, Default, Resource)]
pub struct StageErrors(pub Vec<String>);

/// Warnings raised while building the scene (degenerate triangles skipped, …).
#[derive(Debug, Clone, Default, Resource)]
pub struct Warnings(pub Vec<String>);
