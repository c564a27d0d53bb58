//! Forward Monte Carlo photon tracking (DART 5 paper §4, "Ray-Carlo"; Gastellu-Etchegorry et
//! al. 2016, *Remote Sens. Environ.* 184: eqs. 1–3) over the Radiative stage's scene
//! representation: turbid cells (exact free paths), facets (found per cell), the flat ground, DEM
//! facets and the repetitive / isolated boundaries.
//!
//! This module is a plain engine over flat arrays (no ECS): [`PhotonInput`] in,
//! [`PhotonResult`] out.
//!
//! * **Photons** are weighted packets carrying one weight per band (W). Geometry (free paths,
//!   scattering directions) is shared by all bands; band-dependent probabilities are handled by
//!   importance reweighting: an outcome `k` with per-band probabilities `p_b(k)` is drawn with
//!   `q(k) ∝ Σ_b w_b p_b(k)` and every band weight becomes `w_b p_b(k)/q(k)` — unbiased for each
//!   band (E[w'_b] = w_b Σ_k p_b(k)). What a photon loses at an event is booked as absorbed
//!   there (`w_b − w'_b`), so per-band energy closes *exactly* in every realisation (the booked
//!   absorption is an unbiased estimate, and can be negative for one event in a minority band).
//! * **Free paths** in turbid cells are exact: `τ* = −ln ξ`, accumulated over the DDA segments
//!   with `k = Σ_m G_m(Ω) u_m` (+ fluid extinction), physics.md §9.2. Fluids with band-dependent
//!   extinction use the largest band extinction as the sampling majorant and a per-band
//!   real/null-collision reweighting (delta tracking, Woodcock 1965; unbiased).
//! * **Scattering directions**: continuous mode samples the exact leaf kernel (physics.md
//!   §3.3), Lambertian cosine lobes, the fluid phase functions and tabulated BRDF importance
//!   sampling; discrete mode (DART's Ray-Carlo) draws turbid scattering among the discrete
//!   directions from the Phase tables with an alias or Box table per incident row, and snaps
//!   surface scattering to the containing discrete sector.
//! * **Peel-off** (local estimate, Ray-Carlo eqs. 1–2): at every scattering event the intensity
//!   scattered toward each requested view direction, attenuated to the top of the scene, is
//!   tallied — exact phase value in continuous mode, the containing sector's tabulated value in
//!   discrete mode. BRFs in the view directions come from these tallies; every other discrete
//!   direction gets the escape-counting sector mean.
//! * **Russian roulette** on the relative weight (weight window: survive with probability
//!   `r/r_min`, weights scaled up by `r_min/r`), its balance kept as a separate account
//!   (expectation 0) so that closure stays exact.
//! * **Determinism**: photons run in a fixed number of batches, each with its own
//!   `Xoshiro256PlusPlus` stream from (scene seed, batch index); batch tallies are merged in batch
//!   order, so results are bit-identical on any number of threads. The spread of the batch
//!   estimates gives the standard errors.

use crate::photon::sampling::{
    AliasTable, BoxTable, BrdfSampler, LeafSampler, Uniform01, sample_cosine_hemisphere,
    sample_fluid_phase,
};
use crate::photon::small::Small;
use crate::physics::brdf::Brdf;
use crate::physics::lad::{GTable, VolscattKernel};
use crate::physics::phase::FluidPhase;
use crate::radiative::dda::{Dda, Exit, floor_i64, skip_field};
use crate::radiative::engine::intersect;
use crate::resources::directions::DirectionSet;
use crate::resources::facets::Facet;
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::phase_tables::PhaseTable;
use crate::scene::desc::{BoundaryMode, LidarEstimator};
use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use std::collections::HashMap;
use std::f64::consts::PI;

/// How scattering directions are drawn.
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

/// Discrete outgoing-direction sampler of one incident row.
#[derive(Debug, Clone)]
pub enum RowSampler {
    /// Alias table.
    Alias(AliasTable),
    /// Box table.
    Box(BoxTable),
}

impl RowSampler {
    #[inline]
    fn sample(&self, rng: &mut Xoshiro256PlusPlus) -> usize {
        match self {
            RowSampler::Alias(a) => a.sample(rng),
            RowSampler::Box(b) => b.sample(rng),
        }
    }
    #[inline]
    fn probability(&self, j: usize) -> f64 {
        match self {
            RowSampler::Alias(a) => a.probability(j),
            RowSampler::Box(b) => b.probability(j),
        }
    }
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        match self {
            RowSampler::Alias(a) => a.bytes(),
            RowSampler::Box(b) => b.bytes(),
        }
    }
}

/// Discrete (Ray-Carlo) data of a turbid material: per-band Phase tables (rows: tiling
/// incidences then the sun; columns: tiling directions) and one sampler per row built on the
/// band-mean row.
#[derive(Debug, Clone)]
pub struct DiscreteRows {
    /// Phase tables per band.
    pub tables: Vec<PhaseTable>,
    /// Sampler per row (`None` for an all-zero row: black leaves).
    pub samplers: Vec<Option<RowSampler>>,
}

impl DiscreteRows {
    /// Builds the row samplers from the band-mean of the tables' rows.
    pub fn new(tables: Vec<PhaseTable>, kind: SamplerKind) -> Result<Self, String> {
        let n_rows = tables.first().map_or(0, |t| t.n_rows());
        let mut samplers = Vec::with_capacity(n_rows);
        for i in 0..n_rows {
            let n = tables[0].n_cols();
            let mut mean = vec![0.0; n];
            for t in &tables {
                for (m, v) in mean.iter_mut().zip(t.row(i)) {
                    *m += *v as f64;
                }
            }
            if mean.iter().all(|&v| v <= 0.0) {
                samplers.push(None);
                continue;
            }
            let s = match kind {
                SamplerKind::Box { gamma, max_boxes } => RowSampler::Box(
                    BoxTable::new(&mean, gamma, max_boxes).map_err(|e| e.to_string())?,
                ),
                _ => RowSampler::Alias(AliasTable::new(&mean).map_err(|e| e.to_string())?),
            };
            samplers.push(Some(s));
        }
        Ok(Self { tables, samplers })
    }

    /// Bytes held by the samplers.
    pub fn bytes(&self) -> usize {
        self.samplers.iter().flatten().map(RowSampler::bytes).sum()
    }
}

/// Optical model of one material as the photon tracker needs it.
// One value per material, read in the hot loops: the turbid variant is kept inline (no Box).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub enum PhotonOptics {
    /// Not used by the tracker.
    Unused,
    /// Turbid vegetation (bi-Lambertian leaves, any LAD).
    Turbid {
        /// Exact leaf-normal / scattering sampler.
        sampler: LeafSampler,
        /// Area scattering function kernel (peel-off values Γ_ρ, Γ_τ).
        kernel: VolscattKernel,
        /// G(|μ|) table (extinction).
        g: GTable,
        /// Leaf reflectance per band.
        rho: Vec<f64>,
        /// Leaf transmittance per band.
        tau: Vec<f64>,
        /// Ray-Carlo tables (discrete mode only).
        discrete: Option<DiscreteRows>,
        /// Leaf dimension for the hotspot, m (DART `dimFoliar`; 0 = no hotspot).
        leaf_size_m: f64,
    },
    /// Lambertian facet (a bi-Lambertian leaf is R = ρ_L, T_d = τ_L, T_dir = 0).
    Lambert {
        /// Reflectance per band.
        r: Vec<f64>,
        /// Diffuse transmittance per band.
        t: Vec<f64>,
        /// Direct transmittance at normal incidence per band.
        t_dir: Vec<f64>,
    },
    /// Opaque surface with a BRDF (RPV, Hapke) per band; the sampler is built on one of them
    /// and the others are reweighted.
    Brdf {
        /// Model per band.
        models: Vec<Brdf>,
        /// Importance sampler.
        sampler: BrdfSampler,
    },
}

impl PhotonOptics {
    /// The same optics restricted to band `b` (LiDAR: one laser band).
    pub fn select_band(&self, b: usize) -> PhotonOptics {
        let one = |v: &Vec<f64>| vec![v.get(b).copied().unwrap_or(0.0)];
        match self {
            PhotonOptics::Unused => PhotonOptics::Unused,
            PhotonOptics::Turbid {
                sampler,
                kernel,
                g,
                rho,
                tau,
                discrete,
                leaf_size_m,
            } => PhotonOptics::Turbid {
                sampler: sampler.clone(),
                kernel: kernel.clone(),
                g: g.clone(),
                rho: one(rho),
                tau: one(tau),
                discrete: discrete.as_ref().map(|d| DiscreteRows {
                    tables: d.tables.get(b).cloned().into_iter().collect(),
                    samplers: d.samplers.clone(),
                }),
                leaf_size_m: *leaf_size_m,
            },
            PhotonOptics::Lambert { r, t, t_dir } => PhotonOptics::Lambert {
                r: one(r),
                t: one(t),
                t_dir: one(t_dir),
            },
            PhotonOptics::Brdf { models, sampler } => PhotonOptics::Brdf {
                models: models.get(b).cloned().into_iter().collect(),
                sampler: sampler.clone(),
            },
        }
    }
}

/// A fluid (atmosphere, aerosol, smoke, water) constituent filling cells (physics.md §4.1).
#[derive(Debug, Clone)]
pub struct FluidMaterial {
    /// Extinction coefficient per band, m⁻¹.
    pub sigma_e: Vec<f64>,
    /// Single-scattering albedo per band.
    pub ssa: Vec<f64>,
    /// Phase function.
    pub phase: FluidPhase,
}

/// Fluid content of the grid: one optional fluid per cell.
#[derive(Debug, Clone, Default)]
pub struct FluidField {
    /// Fluid index per cell (`u16::MAX`: none).
    pub cell: Vec<u16>,
    /// Fluids.
    pub materials: Vec<FluidMaterial>,
}

/// Parameters of a Monte Carlo run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PhotonParams {
    /// Photons (sun + sky), at least one per batch.
    pub photons: u64,
    /// Batches (fixed whatever the thread count; ≥ 2 for standard errors).
    pub batches: u32,
    /// Scene seed.
    pub seed: u64,
    /// Direction sampler.
    pub sampler: SamplerKind,
    /// Russian roulette below this weight relative to the photon's initial weight.
    pub roulette_threshold: f64,
    /// K: peel-off points drawn per crossing of a fluid cell (DART 5 paper §4: "K interception
    /// events per crossing of large atmospheric cells"); 0 = peel off at the actual fluid
    /// collisions only.
    pub fluid_peel_points: u32,
    /// Scattering orders beyond this are lost (DART caps orders too).
    pub max_order: u32,
    /// Maximum scene crossings of one flight in repetitive scenes.
    pub max_crossings: u32,
    /// Empty-space skipping: flights jump over boxes of empty cells (no facet, no turbid entry
    /// with a density, no fluid) found from a chessboard distance field
    /// ([`crate::radiative::dda::skip_field`]) instead of crossing them one by one; same
    /// cells, segment ends and results bit for bit ([`Dda::skip_to`]). Off: kept for the
    /// equality tests.
    pub skip_empty: bool,
}

impl PhotonParams {
    /// Defaults: 64 batches, roulette below 1e-2, K = 4 fluid peel-off points per crossing,
    /// 10 000 orders, 10 000 crossings.
    pub fn new(photons: u64, seed: u64, sampler: SamplerKind) -> Self {
        Self {
            photons,
            batches: 64,
            seed,
            sampler,
            roulette_threshold: 1e-2,
            fluid_peel_points: 4,
            max_order: 10_000,
            max_crossings: 10_000,
            skip_empty: true,
        }
    }
}

/// Everything the engine reads.
pub struct PhotonInput<'a> {
    /// Grid geometry.
    pub spec: &'a GridSpec,
    /// Cell contents.
    pub grid: &'a CellGrid,
    /// Facets (absolute coordinates).
    pub facets: &'a [Facet],
    /// True for the facets of a DEM ground (their absorption is ground absorption).
    pub ground_facet: &'a [bool],
    /// Discrete directions (escape sectors; discrete-mode scattering directions).
    pub dirs: &'a DirectionSet,
    /// Optics per material id.
    pub optics: &'a [PhotonOptics],
    /// Fluids, if any.
    pub fluid: Option<&'a FluidField>,
    /// Flat ground optics (material id into `optics`) if the ground is the plane z0.
    pub flat_ground: Option<u32>,
    /// View directions (upward unit vectors) that get peel-off estimates.
    pub views: Vec<DVec3>,
    /// Propagation vector of the direct sun beam (downward).
    pub sun: DVec3,
    /// Direct irradiance on a horizontal plane per band, W m⁻² (µm⁻¹).
    pub e_dir: Vec<f64>,
    /// Diffuse sky irradiance on a horizontal plane per band (isotropic sky).
    pub e_diff: Vec<f64>,
    /// Parameters.
    pub params: PhotonParams,
}

/// What the engine computed; per-element arrays hold `n_channels` values per element.
#[derive(Debug, Clone, Default)]
pub struct PhotonResult {
    /// Channels (bands × (1 + sky)).
    pub n_channels: usize,
    /// Bands.
    pub n_bands: usize,
    /// Whether sky channels exist.
    pub has_sky: bool,
    /// Source power per channel, W.
    pub source: Vec<f64>,
    /// Escaped power per tiling direction `[dir][channel]`, W (escape counting).
    pub escaped: Vec<f64>,
    /// Peel-off intensity toward each view `[view][channel]`, W sr⁻¹.
    pub peel: Vec<f64>,
    /// Absorbed per turbid entry, W.
    pub absorbed_turbid: Vec<f64>,
    /// Intercepted (collided) per turbid entry, W.
    pub intercepted_turbid: Vec<f64>,
    /// Absorbed per facet, W.
    pub absorbed_facet: Vec<f64>,
    /// Intercepted per facet, W.
    pub intercepted_facet: Vec<f64>,
    /// Absorbed by the flat ground per column, W.
    pub absorbed_ground: Vec<f64>,
    /// Intercepted by the flat ground per column, W.
    pub intercepted_ground: Vec<f64>,
    /// Absorbed by fluids per cell that holds one (`[cell][channel]`, sparse: cell ids in
    /// `fluid_cells`), W.
    pub absorbed_fluid: Vec<f64>,
    /// Cells of `absorbed_fluid`.
    pub fluid_cells: Vec<u32>,
    /// Lost (isolated sides, bottom leaks, order/crossing caps), W.
    pub lost: Vec<f64>,
    /// Russian-roulette balance (killed minus added weight; expectation 0), W.
    pub roulette: Vec<f64>,
    /// Per-batch summaries (see [`Summary`]), for standard errors.
    pub batch_summaries: Vec<Vec<f64>>,
    /// Layout of the summaries.
    pub summary: Summary,
    /// Photons traced.
    pub photons: u64,
    /// Scattering events.
    pub events: u64,
    /// Cell crossings of the flights (visited cells).
    pub crossings: u64,
    /// Empty cells the flights jumped over (empty-space skipping, not in `crossings`).
    pub skipped: u64,
}

/// Layout of a batch summary vector: per channel escaped, absorbed (vegetation, facets,
/// fluids), absorbed by the ground, intercepted by the ground; then escaped per tiling
/// direction and channel; then peel-off per view and channel.
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// Channels.
    pub w: usize,
    /// Tiling directions.
    pub n_dirs: usize,
    /// Views.
    pub n_views: usize,
}

impl Summary {
    /// Length of a summary vector.
    pub fn len(&self) -> usize {
        4 * self.w + self.n_dirs * self.w + 4 * self.n_views * self.w
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Index of escaped power of channel `ch`.
    pub fn escaped(&self, ch: usize) -> usize {
        ch
    }
    /// Index of non-ground absorption of channel `ch`.
    pub fn absorbed(&self, ch: usize) -> usize {
        self.w + ch
    }
    /// Index of ground absorption.
    pub fn absorbed_ground(&self, ch: usize) -> usize {
        2 * self.w + ch
    }
    /// Index of ground interception.
    pub fn ground(&self, ch: usize) -> usize {
        3 * self.w + ch
    }
    /// Index of escaped power in tiling direction `j`.
    pub fn dir(&self, j: usize, ch: usize) -> usize {
        4 * self.w + j * self.w + ch
    }
    /// Index of the peel-off intensity toward view `v`.
    pub fn view(&self, v: usize, ch: usize) -> usize {
        4 * self.w + self.n_dirs * self.w + v * self.w + ch
    }
    /// Index of a RAMI component of the peel-off toward view `v`: 0 = single scattering by
    /// the vegetation (and other non-ground elements; RAMI `co_sgl`), 1 = single scattering by
    /// the ground of light that met nothing else on the way down or up (`uc_sgl`), 2 = multiple
    /// scattering (`mlt`).
    pub fn view_component(&self, v: usize, comp: usize, ch: usize) -> usize {
        4 * self.w
            + self.n_dirs * self.w
            + self.n_views * self.w
            + (comp * self.n_views + v) * self.w
            + ch
    }
}

/// Standard error of the sum over batches of component `i`: `√(B/(B−1) Σ_k (S_k − S̄)²)`.
pub fn sum_standard_error(batches: &[Vec<f64>], i: usize) -> f64 {
    let b = batches.len();
    if b < 2 {
        return f64::NAN;
    }
    let mean = batches.iter().map(|s| s[i]).sum::<f64>() / b as f64;
    let ss: f64 = batches.iter().map(|s| (s[i] - mean).powi(2)).sum();
    (b as f64 / (b as f64 - 1.0) * ss).sqrt()
}

/// Per-element accumulator (dense when small, hashed otherwise).
struct Acc {
    width: usize,
    dense: Option<Vec<f64>>,
    sparse: HashMap<u32, Vec<f64>>,
    /// Discards everything (LiDAR pulses keep no radiative budget).
    sink: bool,
}

impl Acc {
    fn new(n: usize, width: usize) -> Self {
        let dense = (n * width <= 1 << 18).then(|| vec![0.0; n * width]);
        Self {
            width,
            dense,
            sparse: HashMap::new(),
            sink: false,
        }
    }
    /// All records back to zero (a sink reused for the next pulse).
    fn reset(&mut self) {
        if let Some(d) = self.dense.as_mut() {
            d.fill(0.0);
        }
        self.sparse.clear();
    }
    fn sink(width: usize) -> Self {
        Self {
            width,
            dense: Some(vec![0.0; width]),
            sparse: HashMap::new(),
            sink: true,
        }
    }
    /// The record of `key` (a sink: its scratch record), inlined up to the record lookup
    /// (every LiDAR event books into sinks).
    #[inline(always)]
    fn get(&mut self, key: u32) -> &mut [f64] {
        let w = self.width;
        if self.sink {
            return &mut self.dense.as_mut().expect("sink buffer")[..w];
        }
        self.record(key)
    }

    /// [`Acc::get`] of a non-sink accumulator.
    #[inline(never)]
    fn record(&mut self, key: u32) -> &mut [f64] {
        let w = self.width;
        match &mut self.dense {
            Some(d) => &mut d[key as usize * w..(key as usize + 1) * w],
            None => self.sparse.entry(key).or_insert_with(|| vec![0.0; w]),
        }
    }
    /// Visits every record (dense: all keys; sparse: sorted keys).
    fn for_each(&self, mut f: impl FnMut(u32, &[f64])) {
        if self.sink {
            return;
        }
        match &self.dense {
            Some(d) => {
                for (k, v) in d.chunks(self.width).enumerate() {
                    f(k as u32, v)
                }
            }
            None => {
                let mut keys: Vec<&u32> = self.sparse.keys().collect();
                keys.sort_unstable();
                for k in keys {
                    f(*k, &self.sparse[k])
                }
            }
        }
    }

    fn add_into(&self, out: &mut [f64]) {
        match &self.dense {
            Some(d) => out.iter_mut().zip(d).for_each(|(o, v)| *o += v),
            None => {
                // Keys in sorted order: merging is deterministic.
                let mut keys: Vec<&u32> = self.sparse.keys().collect();
                keys.sort_unstable();
                for k in keys {
                    let v = &self.sparse[k];
                    let s = *k as usize * self.width;
                    out[s..s + self.width]
                        .iter_mut()
                        .zip(v)
                        .for_each(|(o, x)| *o += x);
                }
            }
        }
    }
}

/// Tallies of one batch.
struct BatchOut {
    summary: Vec<f64>,
    abs_tur: Acc,
    int_tur: Acc,
    abs_fac: Acc,
    int_fac: Acc,
    abs_gnd: Acc,
    int_gnd: Acc,
    abs_fluid: HashMap<u32, Vec<f64>>,
    lost: Vec<f64>,
    roulette: Vec<f64>,
    events: u64,
    crossings: u64,
    skipped: u64,
    /// LiDAR receiver tallies (receiver mode only).
    wave: Option<crate::lidar::waveform::WaveformBinner>,
}

/// How a transmittance ray leaves the grid box.
enum ExitTo {
    /// Through the top (or out of an isolated scene toward the receiver): done.
    Receiver,
    /// Through the bottom, or lost: zero transmittance.
    Blocked,
    /// Through a repetitive side: continues from this re-entry point.
    Wrapped(DVec3),
}

/// Where a flight ends.
enum Hit {
    /// Volume collision in cell `c` at point `p`.
    Volume { c: usize, p: DVec3 },
    /// Facet `f` at point `p`.
    Facet { f: u32, p: DVec3 },
    /// Flat ground at point `p`.
    Ground { p: DVec3 },
    /// Left through the top at `p`.
    Escape,
    /// Lost (isolated side, bottom leak, crossing cap).
    Lost,
}

#[derive(Clone)]
struct Ctx<'a> {
    inp: &'a PhotonInput<'a>,
    nb: usize,
    w: usize,
    sum: Summary,
    size: (f64, f64),
    /// Turbid material index per material id (u32::MAX: not turbid).
    tur_mat: Vec<u32>,
    /// Material ids of turbid materials.
    tur_ids: Vec<u32>,
    /// G toward each view `[view][turbid material]`.
    g_view: Vec<Vec<f64>>,
    /// Hotspot terms per view and turbid material (see
    /// [`crate::radiative::engine::hotspot_terms`]) for the peel-off of first-order sun
    /// photons; empty rows when no material has a leaf size.
    hs_view: Vec<Vec<[f64; 2]>>,
    /// Leaf dimension per turbid material, m (hotspot; all zero: none).
    hs_leaf: Vec<f64>,
    /// Tiling direction vectors.
    omega: Vec<DVec3>,
    /// Sector containing each view and its solid angle (discrete-mode peel-off).
    view_sector: Vec<usize>,
    /// LiDAR receiver (receiver mode: peel-off toward it instead of the views).
    receiver: Option<Receiver>,
    /// Per cell: 0 when it has something to interact with (a facet, a turbid entry with a
    /// density, a fluid), else its chessboard distance in cells to the nearest such cell
    /// ([`skip_field`]: 1 for a cell crossed one by one, and for every empty cell when
    /// [`PhotonParams::skip_empty`] is off). Walks cross an empty cell without looking at its
    /// contents, and flights from a cell at distance r ≥ 2 jump over the box of cells within
    /// r − 1
    /// (same results bit for bit: an empty cell adds nothing to optical depths and draws no
    /// random numbers).
    empty: std::sync::Arc<[u8]>,
    /// Receiver mode: the end of the range gate (path length, m); photons that can no longer
    /// be recorded before it are dropped (booked as lost, see [`Ctx::beyond_gate`]).
    max_path: f64,
    /// Receiver mode: the first flight from the emitter uses [`Ctx::first_flight`] (one walk,
    /// first order stratified by digitiser bin) instead of [`Ctx::forced_peel`] + [`Ctx::fly`].
    stratified: bool,
    /// Receiver mode: survival probability of a photon past its first interaction (Russian
    /// roulette into multiple scattering, weight divided by it; 1: every photon goes on).
    continue_prob: f64,
    /// Receiver mode: per-column vertical optical-depth sums for the return transmittance of
    /// peel-offs whose ray to the receiver stays in one grid column ([`ColumnDepth`]).
    columns: Option<std::sync::Arc<ColumnDepth>>,
    /// Receiver mode ([`LidarEstimator::ExpectedValue`]): expected-value multiple-scattering
    /// return along every flight past the first ([`Ctx::scatter_flight`]) with the stop factor
    /// `c` ≥ 1, and expected-value first-order ground return in [`Ctx::first_flight`] (0: off,
    /// the collision estimator).
    ms_stop: f64,
    /// Receiver mode ([`LidarEstimator::ExpectedValue`]): the far-photon roulette's distance
    /// scale ρ₀ (m) and the tangent of the receiver's FOV half-angle (see
    /// [`far_roulette_survival`]); ρ₀ = 0: off.
    far_roulette: (f64, f64),
    /// Per cell (empty: the scene has no facets): a box `[lo, hi]` (x, y, z lo then hi) that
    /// holds every point of the cell's facets near the cell ([`facet_boxes`]); a ray segment
    /// that misses it hits none of them ([`Ctx::facet_hit`], [`Ctx::facet_behind`]).
    facet_box: std::sync::Arc<[[f64; 6]]>,
    /// Discrete sampler: the upward tiling directions (their ids) and an alias table of their
    /// projected solid angles `∫ μ dΩ` (π in all), for the Lambertian flat ground's reflection
    /// ([`Ctx::ground_direction`]); `None` with the continuous sampler.
    ground_dirs: Option<(AliasTable, Vec<u32>)>,
}

/// Per cell, the bounding box of the cell's facets (their vertices' box, widened by a margin
/// `m`) cut to the cell widened by `2m`, with `m` four hit tolerances plus 1e-9 of the sum of
/// the largest |coordinate| and the largest cell side: a facet hit that [`Ctx::facet_hit`] accepts lies on the facet
/// (barycentric slack 1e-12) within the hit tolerance of the cell segment, so inside this box
/// (rounding included); cells without facets get an empty box. Empty when the scene has none.
fn facet_boxes(inp: &PhotonInput) -> Vec<[f64; 6]> {
    let spec = inp.spec;
    let grid = inp.grid;
    let n_cells = spec.n_cells();
    if grid.facet_ids.is_empty() || grid.facet_start.len() != n_cells + 1 {
        return Vec::new();
    }
    let tol = spec.hit_tolerance();
    let far = inp
        .facets
        .iter()
        .flat_map(|f| f.v.iter())
        .fold(0.0f64, |a, v| a.max(v.abs().max_element()));
    let m = 4.0 * tol + 1e-9 * (far + spec.cell.max_element());
    // Cells without facets: an empty box (lo > hi), which no ray meets.
    const EMPTY: [f64; 6] = [1.0, 1.0, 1.0, -1.0, -1.0, -1.0];
    let mut out = vec![EMPTY; n_cells];
    for (c, b) in out.iter_mut().enumerate() {
        let ids = grid.facets_of(c);
        if ids.is_empty() {
            continue;
        }
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(-f64::INFINITY));
        for &f in ids {
            for v in &inp.facets[f as usize].v {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
        }
        let [i, j, k] = spec.ijk(c);
        let (clo, chi) = spec.cell_box(i as i64, j as i64, k as i64);
        let lo = (lo - m).max(clo - 2.0 * m);
        let hi = (hi + m).min(chi + 2.0 * m);
        *b = [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z];
    }
    out
}

/// Whether the ray `o + t d`, `t ∈ [ta, tb]`, meets the box `b` (slab test; a NaN bound from
/// a degenerate direction component keeps the ray: conservative).
#[inline]
fn ray_meets_box(b: &[f64; 6], o: DVec3, d: DVec3, ta: f64, tb: f64) -> bool {
    let (mut lo, mut hi) = (ta, tb);
    for a in 0..3 {
        let (bl, bh) = (b[a], b[a + 3]);
        if d[a] != 0.0 {
            let inv = 1.0 / d[a];
            let (t1, t2) = ((bl - o[a]) * inv, (bh - o[a]) * inv);
            lo = lo.max(t1.min(t2));
            hi = hi.min(t1.max(t2));
        } else if !(o[a] >= bl && o[a] <= bh) {
            return false;
        }
    }
    lo <= hi
}

/// Per-column cumulative vertical leaf-area sums of the tracked turbid materials (computed once
/// per LiDAR run), giving the exact return transmittance of a point whose straight ray to a
/// receiver above the grid stays in the point's column and meets no facet (DART 5 paper §4,
/// physics.md §9.2): such a ray crosses the cells above the point with path lengths `Δz/u_z`,
/// so its optical depth is `Σ_m G_m(u) [A_m(c) + u_{f,m}(c)(z_top(c) − z)]/u_z`, where
/// `A_m(c) = Σ_{cells above c} u_{f,m} Δz` (m² m⁻², one-sided leaf area above the cell) and
/// `u_{f,m}(c)` (m² m⁻³) is the density of the point's own cell. Equal to the shadow walk of
/// [`Ctx::transmittance`] to rounding (debug builds check every use against it).
struct ColumnDepth {
    /// Tracked turbid materials.
    ntm: usize,
    /// `above[c·ntm + tm]`: `A_m(c)`, m² m⁻².
    above: Vec<f64>,
    /// `dens[c·ntm + tm]`: `u_{f,m}(c)`, m² m⁻³.
    dens: Vec<f64>,
    /// Whether cell c and every cell above it hold no facet and no fluid.
    clear: Vec<bool>,
}

/// Debug builds: how many return transmittances were taken from the column sums
/// (`ColumnDepth`), each checked against the shadow walk it replaces (for the tests).
#[cfg(debug_assertions)]
pub static COLUMN_RETURNS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Largest `cells × tracked materials` of a [`ColumnDepth`] (two f64 arrays: 128 MiB); larger
/// grids keep the shadow walk.
const MAX_COLUMN_ENTRIES: usize = 1 << 23;

impl ColumnDepth {
    fn new(ctx: &Ctx) -> Option<Self> {
        let spec = ctx.inp.spec;
        let grid = ctx.inp.grid;
        let ntm = ctx.tur_ids.len();
        let n_cells = spec.n_cells();
        if ntm == 0
            || n_cells * ntm > MAX_COLUMN_ENTRIES
            || grid.turbid_start.len() != n_cells + 1
            || grid.facet_start.len() != n_cells + 1
        {
            return None;
        }
        let mut above = vec![0.0; n_cells * ntm];
        let mut dens = vec![0.0; n_cells * ntm];
        let mut clear = vec![false; n_cells];
        let (nx, ny, nz) = (spec.n[0], spec.n[1], spec.n[2]);
        for j in 0..ny {
            for i in 0..nx {
                let mut acc: PerMaterial<f64> = Small::from_elem(0.0, ntm);
                let mut ok = true;
                for k in (0..nz).rev() {
                    let c = spec.index(i, j, k);
                    for e in grid.turbid_of(c) {
                        let tm = ctx.tur_mat[e.material as usize];
                        if tm != u32::MAX {
                            dens[c * ntm + tm as usize] += e.density as f64;
                        }
                    }
                    ok &=
                        grid.facet_start[c] == grid.facet_start[c + 1] && ctx.fluid_of(c).is_none();
                    clear[c] = ok;
                    for tm in 0..ntm {
                        above[c * ntm + tm] = acc[tm];
                        acc[tm] += dens[c * ntm + tm] * spec.cell.z;
                    }
                }
            }
        }
        Some(Self {
            ntm,
            above,
            dens,
            clear,
        })
    }
}

/// A LiDAR receiver (DART 5 paper §4; physics.md §9.2): peel-off goes toward a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Receiver {
    /// Position (unwrapped scene coordinates), m.
    pub position: DVec3,
    /// Looking direction (unit, from the receiver toward the scene).
    pub axis: DVec3,
    /// Cosine of the field-of-view half-angle.
    pub cos_fov: f64,
    /// Aperture area, m².
    pub aperture_m2: f64,
}

/// Per-band values of one photon (inline up to 4 bands: no allocation per event).
type Bands = Small<f64, 4>;

/// Per-turbid-material scratch (inline up to 8 materials).
type PerMaterial<T> = Small<T, 8>;

/// Photon state.
struct Photon {
    p: DVec3,
    d: DVec3,
    /// Path length travelled since emission, m (LiDAR timing).
    path: f64,
    /// Unwrapped position minus wrapped position (repetitive scenes), m.
    shift: DVec3,
    /// Discrete direction index (tiling index, or n_dirs for the sun) in discrete mode.
    di: usize,
    /// Weight per band (inline up to 4 bands).
    w: Bands,
    w0: f64,
    /// Channel offset (0: sun, nb: sky).
    off: usize,
    order: u32,
    skip_facet: Option<u32>,
    /// Receiver mode: still on the straight flight from the emitter (order 0, no facet passed
    /// through), so the return path to the (monostatic) receiver is this flight reversed.
    direct: bool,
    /// Receiver mode: transmittance back to the receiver of the current event, when the
    /// forced walk of the first flight already computed it (see [`Ctx::forced_peel`]).
    ret: Option<Bands>,
    /// Receiver mode: the walk of the current flight reached the Lambertian flat ground (or,
    /// first flight, a Lambertian facet) and scored its return with the expected value
    /// ([`Ctx::first_flight`] and [`Ctx::scatter_flight`] of [`LidarEstimator::ExpectedValue`]),
    /// so the surface collision of this flight is not peeled off.
    surface_scored: bool,
    /// Receiver mode: the uniform of the first flight's free path (`τ* = −ln(1 − u)`), from
    /// the pulse's beam-ray lattice ([`Ctx::first_flight`]); `None`: drawn from the stream.
    first_u: Option<f64>,
    /// Receiver mode: a beam ray whose first-order return is part of the pulse's column
    /// quadrature ([`FirstOrderColumns`]): its first flight only samples the collision (the
    /// first-order return of its whole flight, surface included, is not scored again).
    first_order_done: bool,
}

impl<'a> Ctx<'a> {
    /// The shared tracking context: turbid material indices, tiling directions, peel-off views
    /// (G and sector per view), `nb` bands and `w` channels; no receiver.
    fn new(inp: &'a PhotonInput<'a>, nb: usize, w: usize) -> Self {
        let spec = inp.spec;
        let mut tur_mat = vec![u32::MAX; inp.optics.len()];
        let mut tur_ids = Vec::new();
        for (i, o) in inp.optics.iter().enumerate() {
            if matches!(o, PhotonOptics::Turbid { .. }) {
                tur_mat[i] = tur_ids.len() as u32;
                tur_ids.push(i as u32);
            }
        }
        let tiling = inp.dirs.tiling();
        let mut ctx = Ctx {
            inp,
            nb,
            w,
            sum: Summary {
                w,
                n_dirs: tiling.len(),
                n_views: inp.views.len(),
            },
            size: (
                spec.n[0] as f64 * spec.cell.x,
                spec.n[1] as f64 * spec.cell.y,
            ),
            tur_mat,
            tur_ids,
            g_view: Vec::new(),
            hs_view: Vec::new(),
            hs_leaf: Vec::new(),
            omega: tiling.iter().map(|d| d.omega).collect(),
            view_sector: inp.views.iter().map(|v| inp.dirs.find_sector(*v)).collect(),
            receiver: None,
            max_path: f64::INFINITY,
            stratified: false,
            continue_prob: 1.0,
            columns: None,
            ms_stop: 0.0,
            far_roulette: (0.0, 0.0),
            empty: std::sync::Arc::from(Vec::new()),
            facet_box: std::sync::Arc::from(facet_boxes(inp)),
            ground_dirs: None,
        };
        if inp.params.sampler.is_discrete() {
            let (ids, weights): (Vec<u32>, Vec<f64>) = tiling
                .iter()
                .enumerate()
                .filter(|(_, d)| d.is_upward() && d.projected_sr > 0.0)
                .map(|(i, d)| (i as u32, d.projected_sr))
                .unzip();
            ctx.ground_dirs = AliasTable::new(&weights).ok().map(|t| (t, ids));
        }
        let grid = inp.grid;
        let empty: Vec<bool> = (0..grid.facet_start.len().saturating_sub(1))
            .map(|c| {
                grid.facet_start[c] == grid.facet_start[c + 1]
                    && grid
                        .turbid_of(c)
                        .iter()
                        .all(|e| ctx.tur_mat[e.material as usize] == u32::MAX || e.density == 0.0)
                    && ctx.fluid_of(c).is_none()
            })
            .collect();
        ctx.empty = if empty.len() == spec.n.iter().product::<usize>() {
            skip_field(spec.n, inp.params.skip_empty, MIN_SKIP_DISTANCE, |c| {
                !empty[c]
            })
            .into()
        } else {
            empty.iter().map(|&e| e as u8).collect()
        };
        ctx.g_view = inp
            .views
            .iter()
            .map(|v| (0..ctx.tur_ids.len()).map(|tm| ctx.g_of(tm, v.z)).collect())
            .collect();
        // Hotspot (physics.md §3.5): the peel-off of a photon's first collision with the direct
        // sun beam goes back through the gaps the sun came through.
        let leaf: Vec<f64> = ctx
            .tur_ids
            .iter()
            .map(|&m| match &inp.optics[m as usize] {
                PhotonOptics::Turbid { leaf_size_m, .. } => *leaf_size_m,
                _ => 0.0,
            })
            .collect();
        if leaf.iter().any(|&l| l > 0.0) {
            let g_sun: Vec<f64> = (0..ctx.tur_ids.len())
                .map(|tm| ctx.g_of(tm, inp.sun.z))
                .collect();
            ctx.hs_view = inp
                .views
                .iter()
                .zip(&ctx.g_view)
                .map(|(&v, gv)| {
                    (0..ctx.tur_ids.len())
                        .map(|tm| {
                            crate::radiative::engine::hotspot_terms(
                                inp.sun, v, g_sun[tm], gv[tm], leaf[tm],
                            )
                        })
                        .collect()
                })
                .collect();
        }
        ctx.hs_leaf = leaf;
        ctx
    }
}

impl Ctx<'_> {
    /// The direction of a photon reflected by the Lambertian flat ground (cosine-weighted
    /// about +z). Discrete sampler: the upward tiling direction whose sector holds a
    /// cosine-weighted direction, drawn with its probability `∫_sector μ dΩ / π` (the projected
    /// solid angle of its (μ, φ) rectangle, [`crate::resources::directions::Direction::projected_sr`])
    /// from an alias table: the same distribution as drawing the direction and looking up its
    /// sector, in one draw instead of two, a sine, a cosine and the sector search.
    #[inline]
    fn ground_direction(&self, ph: &mut Photon, rng: &mut Xoshiro256PlusPlus) {
        match &self.ground_dirs {
            Some((table, ids)) => {
                ph.di = ids[table.sample(rng)] as usize;
                ph.d = self.omega[ph.di];
            }
            None => ph.d = sample_cosine_hemisphere(DVec3::Z, rng),
        }
    }

    /// Range-gate culling (receiver mode): a photon at unwrapped position m = p + shift after
    /// a path L can only be recorded at a path L' + |R − m'| ≥ L + |R − m| (triangle
    /// inequality: L' ≥ L + |m' − m| for any later event m', and |R − m'| ≥ |R − m| − |m' − m|),
    /// so once `L + |R − m|` exceeds the gate end none of its peel-offs can land inside the gate
    /// and it is stopped. What it would have recorded after the gate is not counted, so the
    /// after-gate part of `out_of_gate_j` is a lower bound. Without a receiver: `L > max_path`
    /// (never, max_path = ∞).
    #[inline]
    fn beyond_gate(&self, ph: &Photon) -> bool {
        match &self.receiver {
            Some(rx) => ph.path + (rx.position - (ph.p + ph.shift)).length() > self.max_path,
            None => ph.path > self.max_path,
        }
    }

    #[inline]
    fn g_of(&self, tm: usize, mu: f64) -> f64 {
        match &self.inp.optics[self.tur_ids[tm] as usize] {
            PhotonOptics::Turbid { g, .. } => g.eval(mu),
            _ => 0.0,
        }
    }

    /// Vegetation extinction per turbid entry of cell `c` for direction cosine `mu` (uses the
    /// per-flight G cache `g_cur`), and the fluid extinction per band.
    #[inline]
    fn k_veg(&self, c: usize, g_cur: &[f64]) -> f64 {
        let grid = self.inp.grid;
        let mut k = 0.0;
        for e in grid.turbid_of(c) {
            let tm = self.tur_mat[e.material as usize];
            if tm != u32::MAX {
                k += g_cur[tm as usize] * e.density as f64;
            }
        }
        k
    }

    #[inline]
    fn fluid_of(&self, c: usize) -> Option<&FluidMaterial> {
        let f = self.inp.fluid?;
        let i = *f.cell.get(c)?;
        (i != u16::MAX).then(|| &f.materials[i as usize])
    }

    fn column(&self, p: DVec3) -> u32 {
        let spec = self.inp.spec;
        // (floor_i64: no libm call; NaN gives column 0 as before.)
        let i =
            floor_i64((p.x - spec.origin.x) / spec.cell.x).clamp(0, spec.n[0] as i64 - 1) as usize;
        let j =
            floor_i64((p.y - spec.origin.y) / spec.cell.y).clamp(0, spec.n[1] as i64 - 1) as usize;
        (i + spec.n[0] * j) as u32
    }

    /// Re-entry point after leaving through a side (repetitive boundaries, with the altitude
    /// offset of continuous topography); `None` if the point leaves the grid vertically.
    fn wrap(&self, mut q: DVec3, axis: usize, s: i64) -> Option<DVec3> {
        let spec = self.inp.spec;
        let (len, off) = if axis == 0 {
            (self.size.0, spec.topography_offset.0)
        } else {
            (self.size.1, spec.topography_offset.1)
        };
        q[axis] -= s as f64 * len;
        q.z -= s as f64 * off;
        q[axis] = if s > 0 {
            spec.origin[axis]
        } else {
            spec.origin[axis] + len
        };
        (q.z <= spec.top() && q.z >= spec.origin.z).then_some(q)
    }

    /// Nearest facet hit in cell `c` along the segment `[t0, t1]` of a ray from `o` along `d`.
    #[inline]
    fn facet_hit(
        &self,
        c: usize,
        o: DVec3,
        d: DVec3,
        t0: f64,
        t1: f64,
        skip: Option<u32>,
    ) -> Option<(u32, f64)> {
        let grid = self.inp.grid;
        let tol = self.inp.spec.hit_tolerance();
        if let Some(b) = self.facet_box.get(c)
            && !ray_meets_box(b, o, d, t0 - tol, t1 + tol)
        {
            return None;
        }
        let mut hit: Option<(u32, f64)> = None;
        for &f in grid.facets_of(c) {
            if Some(f) == skip {
                continue;
            }
            let fa = &self.inp.facets[f as usize];
            if let Some(t) = intersect(&fa.v, o, d)
                && t >= t0 - tol
                && t <= t1 + tol
                && hit.is_none_or(|h| t < h.1)
            {
                let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]);
                if n.dot(d) < 0.0 || fa.two_sided {
                    hit = Some((f, t));
                }
            }
        }
        hit
    }

    /// True if the segment `[t0, t1]` of the ray from `o` along `d` in cell `c` crosses a
    /// one-sided facet from behind (not a hit for this ray, but one for the reversed ray).
    fn facet_behind(&self, c: usize, o: DVec3, d: DVec3, t0: f64, t1: f64) -> bool {
        let tol = self.inp.spec.hit_tolerance();
        if let Some(b) = self.facet_box.get(c)
            && !ray_meets_box(b, o, d, t0 - tol, t1 + tol)
        {
            return false;
        }
        self.inp.grid.facets_of(c).iter().any(|&f| {
            let fa = &self.inp.facets[f as usize];
            !fa.two_sided
                && (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).dot(d) >= 0.0
                && intersect(&fa.v, o, d).is_some_and(|t| t >= t0 - tol && t <= t1 + tol)
        })
    }

    /// The tracked turbid material of cell `c` whose share of the extinction `Σ_m G_m u_m`
    /// (m⁻¹, `g_cur` = G per tracked material along the flight) contains `r` ∈ [0, k_v):
    /// (material id, tracked-material index); the last one when rounding leaves `r` beyond the
    /// sum; `None` when the cell holds no tracked material.
    #[inline]
    fn pick_turbid(&self, c: usize, g_cur: &[f64], mut r: f64) -> Option<(usize, usize)> {
        let mut mid = None;
        for e in self.inp.grid.turbid_of(c) {
            let tm = self.tur_mat[e.material as usize];
            if tm == u32::MAX {
                continue;
            }
            let k = g_cur[tm as usize] * e.density as f64;
            mid = Some((e.material as usize, tm as usize));
            if r < k {
                break;
            }
            r -= k;
        }
        mid
    }

    /// Extinction of the return path of a first-order LiDAR photon in cell `c` (m⁻¹): turbid
    /// materials without a leaf size only (see [`Ctx::forced_peel`]); `g_cur` holds G of the
    /// flight, equal to G of the reversed direction.
    #[inline]
    fn k_return(&self, c: usize, g_cur: &[f64]) -> f64 {
        let mut k = 0.0;
        for e in self.inp.grid.turbid_of(c) {
            let tm = self.tur_mat[e.material as usize];
            // hs_leaf is finite and >= 0 (validated scene input): no leaf size means 0.
            if tm != u32::MAX && self.hs_leaf[tm as usize] <= 0.0 {
                k += g_cur[tm as usize] * e.density as f64;
            }
        }
        k
    }

    /// Flies the photon to its next event; handles null collisions and boundary wrapping.
    #[inline]
    fn fly(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
    ) -> Hit {
        let tau_star = -(1.0 - rng.next_f64()).ln();
        self.fly_to(ph, g_cur, tau_star, rng, out)
    }

    /// [`Ctx::fly`] with the free optical path `tau_star` given.
    fn fly_to(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        mut tau_star: f64,
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
    ) -> Hit {
        let spec = self.inp.spec;
        let mut crossings = 0u32;
        'restart: loop {
            let Some(mut dda) = Dda::new_inline(spec, ph.p, ph.d) else {
                return Hit::Lost;
            };
            loop {
                out.crossings += 1;
                let c = dda.index();
                let r = self.empty[c];
                if r != 0 {
                    // An empty cell: crossed unread, or the empty box around it jumped over
                    // (the jump out of line: the common path keeps its code).
                    let exit = if r > 1 {
                        fly_skip(&mut dda, r, &mut out.skipped)
                    } else {
                        cross_empty(&mut dda, &self.empty, &mut out.crossings)
                    };
                    match exit {
                        Exit::Inside => continue,
                        exit => match self.fly_exit(exit, &dda, ph, &mut crossings) {
                            Some(hit) => return hit,
                            None => continue 'restart,
                        },
                    }
                }
                let t0 = dda.t;
                let mut t1 = dda.t_exit();
                let fhit = if self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1] {
                    self.facet_hit(c, dda.point(0.0), ph.d, t0, t1, ph.skip_facet)
                } else {
                    None
                };
                if let Some((_, th)) = fhit {
                    t1 = th.max(t0);
                }
                let kv = self.k_veg(c, g_cur);
                let fl = self.fluid_of(c);
                let kf = fl.map_or(0.0, |f| f.sigma_e.iter().cloned().fold(0.0, f64::max));
                let k = kv + kf;
                if k > 0.0 && t1 > t0 {
                    let dt = (t1 - t0) * k;
                    if dt >= tau_star {
                        let t = t0 + tau_star / k;
                        let p = dda.point(t);
                        // Fluid null collision (band-dependent extinction below the majorant).
                        if let Some(f) = fl
                            && rng.next_f64() * k >= kv
                        {
                            let mut sw = 0.0;
                            let mut sq = 0.0;
                            for (b, wb) in ph.w.iter().enumerate() {
                                sw += wb;
                                sq += wb * f.sigma_e[b] / kf;
                            }
                            let q = if sw > 0.0 { sq / sw } else { 1.0 };
                            if rng.next_f64() >= q {
                                // Null: continue straight from p with a new free path.
                                for (b, wb) in ph.w.iter_mut().enumerate() {
                                    *wb *= (1.0 - f.sigma_e[b] / kf) / (1.0 - q);
                                }
                                ph.path += t;
                                ph.p = p;
                                tau_star = -(1.0 - rng.next_f64()).ln();
                                continue 'restart;
                            }
                            for (b, wb) in ph.w.iter_mut().enumerate() {
                                *wb *= (f.sigma_e[b] / kf) / q;
                            }
                            ph.path += t;
                            return Hit::Volume {
                                c: c | FLUID_BIT,
                                p,
                            };
                        }
                        ph.path += t;
                        return Hit::Volume { c, p };
                    }
                    tau_star -= dt;
                }
                if let Some((f, th)) = fhit {
                    ph.path += th;
                    return Hit::Facet {
                        f,
                        p: dda.point(th),
                    };
                }
                match dda.advance() {
                    Exit::Inside => {}
                    exit => match self.fly_exit(exit, &dda, ph, &mut crossings) {
                        Some(hit) => return hit,
                        None => continue 'restart,
                    },
                }
            }
        }
    }

    /// A flight leaves the grid box through `exit` (not `Exit::Inside`) at `dda.t`: the hit it
    /// ends with, or `None` after wrapping through a repetitive side (the photon then restarts
    /// from its new position).
    #[inline]
    fn fly_exit(&self, exit: Exit, dda: &Dda, ph: &mut Photon, crossings: &mut u32) -> Option<Hit> {
        let spec = self.inp.spec;
        match exit {
            Exit::Inside => None,
            Exit::Top => {
                ph.path += dda.t;
                ph.p = dda.point(dda.t);
                Some(Hit::Escape)
            }
            Exit::Bottom => {
                ph.path += dda.t;
                let p = dda.point(dda.t);
                Some(if self.inp.flat_ground.is_some() {
                    Hit::Ground { p }
                } else {
                    Hit::Lost
                })
            }
            Exit::Side(axis, s) => {
                if spec.boundary == BoundaryMode::Isolated {
                    return Some(Hit::Lost);
                }
                *crossings += 1;
                if *crossings > self.inp.params.max_crossings {
                    return Some(Hit::Lost);
                }
                let e = dda.point(dda.t);
                if ph.path + dda.t > self.max_path {
                    return Some(Hit::Lost);
                }
                match self.wrap(e, axis, s) {
                    Some(q) => {
                        ph.path += dda.t;
                        // Unwrapped position = wrapped + shift (LiDAR geometry).
                        ph.shift += e - q;
                        ph.p = q;
                        ph.skip_facet = None;
                        None
                    }
                    None => Some(if ph.d.z > 0.0 { Hit::Escape } else { Hit::Lost }),
                }
            }
        }
    }

    /// Transmittance per band from `p` along `d` to the top of the scene or over `max_dist`
    /// metres (turbid and fluid extinction, facets opaque unless directly transmitting);
    /// `g_dir` holds G(d) per turbid material; `hs` (empty: none) the hotspot terms per turbid
    /// material of a first-order photon's peel-off (the turbid extinction coefficient at
    /// distance s from `p` is `u_f (G − b e^{−c s})`, physics.md §3.5).
    #[allow(clippy::too_many_arguments)]
    fn transmittance(
        &self,
        p: DVec3,
        d: DVec3,
        max_dist: f64,
        g_dir: &[f64],
        hs: &[[f64; 2]],
        skip: Option<u32>,
        t_out: &mut [f64],
    ) {
        let spec = self.inp.spec;
        let mut travelled = 0.0;
        t_out.iter_mut().for_each(|t| *t = 1.0);
        let mut tau_v = 0.0; // band-independent optical depth (vegetation)
        let mut p = p;
        let mut skip = skip;
        let mut crossings = 0u32;
        'restart: loop {
            let Some(mut dda) = Dda::new(spec, p, d) else {
                t_out.iter_mut().for_each(|t| *t = 0.0);
                return;
            };
            loop {
                let c = dda.index();
                let t0 = dda.t;
                let mut t1 = dda.t_exit();
                // Receiver inside the grid (terrestrial LiDAR): stop at its distance.
                let reached = travelled + t1 >= max_dist;
                // Empty cells (no facet, no turbid density, no fluid) are crossed unread.
                let r = self.empty[c];
                if r == 0 {
                    if reached {
                        t1 = (max_dist - travelled).max(t0);
                    }
                    let fhit = if self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1] {
                        self.facet_hit(c, dda.point(0.0), d, t0, t1, skip)
                    } else {
                        None
                    };
                    if let Some((_, th)) = fhit {
                        t1 = th.max(t0);
                    }
                    let ell = t1 - t0;
                    if ell > 0.0 {
                        for e in self.inp.grid.turbid_of(c) {
                            let tm = self.tur_mat[e.material as usize];
                            if tm != u32::MAX {
                                let g = g_dir[tm as usize];
                                match hs.get(tm as usize) {
                                    Some(&[b, c]) if b > 0.0 => {
                                        let corr = b * crate::radiative::engine::hotspot_integral(
                                            c,
                                            travelled + t0,
                                            ell,
                                        );
                                        tau_v += e.density as f64 * (g * ell - corr).max(0.0);
                                    }
                                    _ => tau_v += g * e.density as f64 * ell,
                                }
                            }
                        }
                        if let Some(f) = self.fluid_of(c) {
                            for (t, s) in t_out.iter_mut().zip(&f.sigma_e) {
                                *t *= (-s * ell).exp();
                            }
                        }
                    }
                    if tau_v > 69.1 {
                        // e^{−69.1} < 1e-30: below the peel-off cut.
                        t_out.iter_mut().for_each(|t| *t = 0.0);
                        return;
                    }
                    if let Some((f, th)) = fhit {
                        let fa = &self.inp.facets[f as usize];
                        let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize();
                        let mu = n.dot(d).abs().max(1e-6);
                        match &self.inp.optics[fa.material as usize] {
                            PhotonOptics::Lambert { t_dir, .. }
                                if t_dir.iter().any(|&x| x > 0.0) =>
                            {
                                for (t, td) in t_out.iter_mut().zip(t_dir) {
                                    *t *= if *td > 0.0 { td.powf(1.0 / mu) } else { 0.0 };
                                }
                                travelled += th;
                                p = dda.point(th);
                                skip = Some(f);
                                continue 'restart;
                            }
                            _ => {
                                t_out.iter_mut().for_each(|t| *t = 0.0);
                                return;
                            }
                        }
                    }
                }
                if reached {
                    break 'restart;
                }
                // Empty box around the cell: jumped over unless the receiver distance is
                // reached inside it (then crossed cell by cell up to it).
                match dda.advance() {
                    Exit::Inside => {}
                    exit => match self.transmittance_exit(exit, &dda, &mut crossings) {
                        ExitTo::Receiver => break 'restart,
                        ExitTo::Blocked => {
                            t_out.iter_mut().for_each(|t| *t = 0.0);
                            return;
                        }
                        ExitTo::Wrapped(q) => {
                            travelled += dda.t;
                            p = q;
                            skip = None;
                            continue 'restart;
                        }
                    },
                }
            }
        }
        let tv = (-tau_v).exp();
        t_out.iter_mut().for_each(|t| *t *= tv);
    }

    /// A transmittance ray leaves the grid box through `exit` (not `Exit::Inside`) at `dda.t`.
    #[inline]
    fn transmittance_exit(&self, exit: Exit, dda: &Dda, crossings: &mut u32) -> ExitTo {
        let spec = self.inp.spec;
        match exit {
            Exit::Inside | Exit::Top => ExitTo::Receiver,
            Exit::Bottom => ExitTo::Blocked,
            Exit::Side(axis, s) => {
                *crossings += 1;
                if spec.boundary == BoundaryMode::Isolated && self.receiver.is_some() {
                    // Outside an isolated scene there is nothing: the return reaches the
                    // receiver.
                    return ExitTo::Receiver;
                }
                if spec.boundary == BoundaryMode::Isolated
                    || *crossings > self.inp.params.max_crossings
                {
                    return ExitTo::Blocked;
                }
                match self.wrap(dda.point(dda.t), axis, s) {
                    Some(q) => ExitTo::Wrapped(q),
                    None => ExitTo::Receiver,
                }
            }
        }
    }

    /// The LiDAR first flight from the emitter in one walk (receiver mode, `ph.order == 0`,
    /// `ph.direct`, one band, no fluid; [`LidarEstimator::Stratified`] and
    /// [`LidarEstimator::ExpectedValue`]): the collision is
    /// sampled as [`Ctx::fly`] does (same free path, cells, facet and exit rules, so the same
    /// hit distribution: [`Ctx::walk_flight`]), and along the same walk the expected-value
    /// (forced) first-order return of the whole flight is binned ([`FirstOrderScore`]; DART 5
    /// paper §4 forced peel-off, physics.md §9.2, §9.6).
    ///
    /// Every point of this flight lies on the ray from the monostatic receiver, so the return
    /// direction is −Ω, at the distance L walked from the emitter, recorded at path 2L, with
    /// cosine Ω·axis to the receiver axis, and the return transmittance is the optical depth
    /// already walked (see [`Ctx::forced_peel`]). A vegetation segment `u ∈ [0, ℓ]` entered at
    /// distance L₀ with optical depth τ (and return depth τ_r) then sends
    /// `w e^{−τ−τ_r} Σ_m k_m f_m e^{−(k_v + k_r)u} · A (Ω·axis)/(L₀ + u)²` J per metre, with
    /// `f_m = ρ_m ⟨|Ω·Ω_L|⟩_m/π` (sr⁻¹) the exact-backscatter intensity per unit intercepted
    /// weight ([`crate::photon::sampling::LeafSampler::mean_abs_cos`]; the expectation of the
    /// one-leaf estimate). That density is integrated by stratified sampling with the digitiser
    /// bins as strata (at most [`MAX_FIRST_ORDER_STRATA`] per segment, grouping bins beyond):
    /// per stratum the exact mass of `e^{−αu}` times `1/(L₀ + u)²` at one point drawn from
    /// `e^{−αu}` inside it. Unbiased, and only the slowly varying `1/(L₀ + u)²` is sampled,
    /// so the first-order waveform has no per-bin sampling noise left for a given beam ray.
    /// A cell where the flight crosses a one-sided facet from behind (a hit for the return)
    /// switches the rest of the walk to one forced point per segment with a shadow ray.
    ///
    /// [`LidarEstimator::ExpectedValue`]: when the walk reaches a Lambertian flat ground (no
    /// facet crossed from behind), the ground's first-order return is scored there with the
    /// probability `e^{−τ_g}` of reaching it: `w e^{−τ_g} (ρ_g μ_r/π) T_ret A (Ω·axis)/r²` J
    /// (μ_r the cosine of the return direction, T_ret from the walk), and the ground collision
    /// of the flight is not peeled off (`Photon::surface_scored`): an unbiased expected value
    /// that removes the 0-or-1 noise of the ground return under the crowns. A Lambertian facet
    /// that ends the walk is scored the same way with its collision peel-off (reflected
    /// `(1 − t_d) ρ |n·u|/π` on the incidence side, `(1 − t_d) τ |n·u|/π` beyond, t_d the direct
    /// transmittance).
    ///
    /// Returns the hit (the photon's path, shift and position updated as [`Ctx::fly`] does)
    /// and, when the flight ends on a surface with no volume collision before it, the return
    /// optical depth there (for the surface's own collision peel-off).
    #[allow(clippy::too_many_arguments)]
    fn first_flight(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) -> (Hit, Option<f64>) {
        let Some(rx) = self.receiver else {
            return (self.fly(ph, g_cur, rng, out), None);
        };
        let tau_star = -(1.0 - ph.first_u.unwrap_or_else(|| rng.next_f64())).ln();
        let mut score = self.first_order_score(rx, ph, g_cur);
        let mut io = FlightIo {
            rng,
            out,
            scratch,
            tr,
        };
        self.walk_flight(ph, g_cur, tau_star, &mut io, &mut score)
    }

    /// The first-order scoring of a flight from the emitter ([`FirstOrderScore`]).
    fn first_order_score<'g>(
        &self,
        rx: Receiver,
        ph: &Photon,
        g_cur: &'g [f64],
    ) -> FirstOrderScore<'g> {
        let d = ph.d;
        let cos_rx = d.dot(rx.axis);
        // Exact-backscatter intensity per unit intercepted weight, per turbid material.
        let back: PerMaterial<f64> = Small::from_fn(self.tur_ids.len(), |tm| {
            match &self.inp.optics[self.tur_ids[tm] as usize] {
                PhotonOptics::Turbid { sampler, rho, .. } => {
                    rho[0] * sampler.mean_abs_cos(d.z, g_cur[tm]) / PI
                }
                _ => 0.0,
            }
        });
        FirstOrderScore {
            rx,
            d,
            cos_rx,
            in_fov: cos_rx >= rx.cos_fov,
            back,
            w: ph.w[0],
            g_cur,
            tau_ret: 0.0,
            exact: true,
            kr: 0.0,
            kf: 0.0,
        }
    }

    /// A LiDAR flight past the first scattering (receiver mode, `ph.order ≥ 1`, one band, no
    /// fluid; `ms_stop = c ≥ 1`): the collision is sampled as [`Ctx::fly`] does (same free path
    /// τ*, cells, facet and exit rules, so the same hit distribution: [`Ctx::walk_flight`])
    /// and, along the same walk, the single-scattering return of the flight toward the
    /// receiver is integrated instead of being taken at the collision only ([`ScatterScore`];
    /// expected-value estimator, DART 5 paper §4 forced peel-off applied to every order;
    /// physics.md §9.2).
    ///
    /// The walk goes on past the collision up to the optical depth `c τ*` (or the first facet,
    /// the ground, the top or an isolated side): a point at depth τ(u) is reached with
    /// probability `Q(u) = e^{−τ(u)/c}`, so the return density
    /// `w e^{−τ(u)} Σ_m k_m f_m T_ret A (u_r·axis)/r²` J m⁻¹ (k_m = G_m u_{f,m} m⁻¹, f_m the leaf
    /// intensity per unit intercepted weight toward the receiver, sr⁻¹, T_ret the return
    /// transmittance, A the aperture m², r the distance m) is scored divided by Q: weight
    /// `e^{−(1−1/c)τ}`. Unbiased for any c ≥ 1 (c = 1: the track-length estimator, c = ∞: the
    /// expected value along the whole ray, cut at (1 − 1/c)τ > 30, e^{−30} ≈ 1e-13). One point
    /// per crossed vegetation cell, drawn with density ∝ e^{−(1−1/c)k_v u}, carries the
    /// segment's exact mass; its material is drawn in proportion to k_m. A Lambertian flat
    /// ground reached by the walk is scored the same way (`w e^{−(1−1/c)τ_g} ρ_g μ/π T_ret A
    /// cos/r²`). The turbid and ground collisions of such a flight are then not peeled off.
    /// Discrete sampler: `f_m` is the Phase-stage row of the flight's direction toward the
    /// receiver's sector (T/ΔΩ), as the collision peel-off uses.
    #[allow(clippy::too_many_arguments)]
    fn scatter_flight(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) -> Hit {
        let Some(rx) = self.receiver else {
            return self.fly(ph, g_cur, rng, out);
        };
        let tau_star = -(1.0 - rng.next_f64()).ln();
        let mut score = ScatterScore {
            rx,
            d: ph.d,
            g_cur,
            discrete: self.inp.params.sampler.is_discrete(),
            lambert_ground: self.lambert_ground(),
            tau_stop: self.ms_stop * tau_star,
            keep: 1.0 - 1.0 / self.ms_stop,
            fov_tan2: if rx.cos_fov > 0.0 {
                (1.0 - rx.cos_fov * rx.cos_fov) / (rx.cos_fov * rx.cos_fov)
            } else {
                -1.0
            },
        };
        let mut io = FlightIo {
            rng,
            out,
            scratch,
            tr,
        };
        self.walk_flight(ph, g_cur, tau_star, &mut io, &mut score).0
    }

    /// The walk of a LiDAR flight shared by [`Ctx::first_flight`] and [`Ctx::scatter_flight`]:
    /// the collision at the free optical path `tau_star` is sampled as [`Ctx::fly_to`] does
    /// (same cells, facet, exit and wrap rules, so the same hit), while `score` integrates the
    /// flight's return toward the receiver over every vegetation segment walked
    /// ([`FlightScore::segment`]) and at the facet or flat ground that ends the walk. The walk
    /// goes on past the collision until `score` stops it ([`FlightScore::stop`]), a facet, the
    /// ground, the top or an isolated side. A stop before the collision (the forced estimate
    /// cut at a large optical depth) flies the photon again from its start with the same free
    /// path ([`Ctx::fly_to`]). Returns the hit (the photon's path, shift and position updated
    /// as [`Ctx::fly`] does) and, when the flight ends on a surface with no collision before
    /// it, [`FlightScore::surface_ret`].
    fn walk_flight<S: FlightScore>(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        tau_star: f64,
        io: &mut FlightIo,
        score: &mut S,
    ) -> (Hit, Option<f64>) {
        let spec = self.inp.spec;
        let d = ph.d;
        let path0 = ph.path;
        let mut left = tau_star;
        let mut tau = 0.0;
        let p = ph.p;
        let mut skip = ph.skip_facet;
        let mut shift = ph.shift;
        let mut crossings = 0u32;
        let mut travelled = 0.0;
        // The sampled collision: (cell, point, path, shift).
        let mut coll: Option<(usize, DVec3, f64, DVec3)> = None;
        // How the walk ended when no collision came first (None: stopped, fly again).
        let end: Option<Hit>;
        let mut ret = None;
        'walk: {
            let Some(mut dda) = Dda::new_inline(spec, p, d) else {
                end = Some(Hit::Lost);
                break 'walk;
            };
            loop {
                io.out.crossings += 1;
                let c = dda.index();
                let r = self.empty[c];
                let exit = if r != 0 {
                    if r > 1 {
                        fly_skip(&mut dda, r, &mut io.out.skipped)
                    } else {
                        cross_empty(&mut dda, &self.empty, &mut io.out.crossings)
                    }
                } else {
                    let t0 = dda.t;
                    let mut t1 = dda.t_exit();
                    let has_facets =
                        self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1];
                    let fhit = if has_facets {
                        self.facet_hit(c, dda.point(0.0), d, t0, t1, skip)
                    } else {
                        None
                    };
                    if let Some((_, th)) = fhit {
                        t1 = th.max(t0);
                    }
                    let kv = score.cell(self, c, &dda, (t0, t1), has_facets);
                    let ell = t1 - t0;
                    if ell > 0.0 && kv > 0.0 {
                        let dt = ell * kv;
                        if coll.is_none() {
                            if dt >= left {
                                let t = t0 + left / kv;
                                coll = Some((c, dda.point(t), path0 + travelled + t, shift));
                            } else {
                                left -= dt;
                            }
                        }
                        let seg = Segment {
                            c,
                            dda: &dda,
                            t0,
                            ell,
                            kv,
                            tau,
                            l0: path0 + travelled + t0,
                            shift,
                        };
                        score.segment(self, ph, io, &seg);
                        tau += dt;
                    }
                    if let Some((f, th)) = fhit {
                        let at = (dda.point(th), shift, path0 + travelled + th);
                        if score.facet(self, ph, io, f, at, tau) {
                            ph.surface_scored = true;
                        }
                        if coll.is_none() {
                            ph.path = at.2;
                            ph.shift = shift;
                            ret = score.surface_ret();
                        }
                        end = Some(Hit::Facet { f, p: at.0 });
                        break 'walk;
                    }
                    if score.stop(tau, coll.is_some()) {
                        end = None;
                        break 'walk;
                    }
                    dda.advance()
                };
                match exit {
                    Exit::Inside => {}
                    Exit::Top => {
                        if coll.is_none() {
                            ph.path = path0 + travelled + dda.t;
                            ph.p = dda.point(dda.t);
                            ph.shift = shift;
                        }
                        end = Some(Hit::Escape);
                        break 'walk;
                    }
                    Exit::Bottom => {
                        let at = (dda.point(dda.t), shift, path0 + travelled + dda.t);
                        if score.ground(self, ph, io, at, tau) {
                            ph.surface_scored = true;
                        }
                        if coll.is_none() {
                            ph.path = at.2;
                            ph.shift = shift;
                        }
                        end = Some(if self.inp.flat_ground.is_some() {
                            ret = score.surface_ret();
                            Hit::Ground { p: at.0 }
                        } else {
                            Hit::Lost
                        });
                        break 'walk;
                    }
                    Exit::Side(axis, s) => {
                        if spec.boundary == BoundaryMode::Isolated {
                            end = Some(Hit::Lost);
                            break 'walk;
                        }
                        crossings += 1;
                        if crossings > self.inp.params.max_crossings
                            || path0 + travelled + dda.t > self.max_path
                        {
                            end = Some(Hit::Lost);
                            break 'walk;
                        }
                        let e = dda.point(dda.t);
                        match self.wrap(e, axis, s) {
                            Some(q) => {
                                travelled += dda.t;
                                shift += e - q;
                                skip = None;
                                // The same direction from q: restarted in place.
                                if dda.restart(spec, q) {
                                    continue;
                                }
                                end = Some(Hit::Lost);
                                break 'walk;
                            }
                            None => {
                                end = Some(if d.z > 0.0 { Hit::Escape } else { Hit::Lost });
                                break 'walk;
                            }
                        }
                    }
                }
            }
        }
        if let Some((c, q, path, sh)) = coll {
            ph.path = path;
            ph.shift = sh;
            return (Hit::Volume { c, p: q }, None);
        }
        match end {
            Some(hit) => (hit, ret),
            // A walk with no collision to sample (τ* = ∞: a column ray of `FirstOrderColumns`).
            None if tau_star == f64::INFINITY => (Hit::Lost, None),
            // Stopped before the free path ran out (the first flight's forced walk at τ > 30,
            // probability e^{−30}): the flight goes on from its start with the same free path.
            None => (self.fly_to(ph, g_cur, tau_star, io.rng, io.out), None),
        }
    }

    /// Debug builds: the first flight's return geometry and transmittance (distance `l0 + u`
    /// along the ray, direction −Ω, optical depth `τ_r + k_r u`) against the point's actual
    /// vector to the receiver and the shadow ray they replace (relative 1e-9).
    #[cfg(debug_assertions)]
    fn check_first_flight_return(
        &self,
        ph: &Photon,
        (at, shift, l0): (DVec3, DVec3, f64),
        d: DVec3,
        (tau_ret, kr, u): (f64, f64, f64),
    ) {
        let Some(rx) = &self.receiver else { return };
        let m = at + d * u + shift;
        let v = rx.position - m;
        let r = v.length();
        debug_assert!(
            (r - (l0 + u)).abs() <= 1e-9 * r.max(1.0),
            "first-flight distance {} vs {r}",
            l0 + u
        );
        let mut ray = [0.0];
        self.transmittance_to_receiver(ph, at + d * u, v / r, r, None, &mut ray);
        let t = return_transmittance(tau_ret + kr * u);
        debug_assert!(
            (ray[0] - t).abs() <= 1e-9 * ray[0].max(t) + 1e-25,
            "first-flight return transmittance {t:e} vs shadow ray {:e}",
            ray[0]
        );
    }

    /// Forced (expected-value) peel-off along the whole coming flight (Ray-Carlo K points per
    /// crossing of a cell, DART 5 paper §4). Fluid cells (and, in LiDAR receiver mode, turbid
    /// vegetation too): for every segment `[t0, t0+ℓ]` reached with per-band optical depth τ_b,
    /// K points u drawn from a truncated exponential `q(u)` each contribute
    /// `w_b e^{−τ_b} σ_b e^{−(k_v+σ_b)u}/(K q(u)) · f_b(Ω→receiver or view) · T_b`, whose
    /// expectation is the collision peel-off of the flight (which is then not done at the
    /// actual collisions of those media). Fluids: `f = ω P(Θ)/(4π)`; vegetation: the leaf
    /// intensity `Γ/(πG)` (spherical closed form, else the one-leaf estimate with a sampled
    /// normal). The walk stops at the first facet, the ground, the top, an isolated side or when
    /// min_b τ_b > 30 (e^{−30} ≈ 1e-13).
    ///
    /// Receiver mode on the straight flight from the emitter (`ph.direct`): the receiver sits at
    /// the emitter (monostatic), so the return path of a forced point is the flight walked so
    /// far, reversed: its transmittance comes from the optical depth already accumulated
    /// instead of a separate ray (same cells, G(−Ω) = G(Ω); turbid materials with a leaf size
    /// add nothing on the way back, the exact-backscatter limit of
    /// [`crate::radiative::engine::hotspot_terms_path`]; equal to the ray's value to rounding).
    /// A cell where the flight crosses a one-sided facet from behind (which the return ray
    /// would hit) falls back to the ray. Returns, in that mode, the return transmittance at
    /// the end of the walk when it ends on a facet (`Some(f)`) or the bottom (`None`), for the
    /// collision peel-off of the flight's surface hit.
    #[allow(clippy::too_many_arguments)]
    fn forced_peel(
        &self,
        ph: &Photon,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) -> Option<(Option<u32>, Bands)> {
        let spec = self.inp.spec;
        let nb = self.nb;
        let receiver = self.receiver;
        let k_pts = self.inp.params.fluid_peel_points.max(1);
        let mut tau = Bands::from_elem(0.0, nb);
        let mut p = ph.p;
        let mut skip = ph.skip_facet;
        let mut crossings = 0u32;
        let mut travelled = 0.0;
        let mut shift = ph.shift;
        let d_in = ph.d;
        let mut fac = Bands::from_elem(0.0, nb);
        // Return optical depth per band from the walk's start (the emitter side), and whether it
        // is used (see above).
        let mut tau_ret = Bands::from_elem(0.0, nb);
        let mut exact = receiver.is_some() && ph.order == 0 && ph.direct;
        'restart: loop {
            let mut dda = Dda::new(spec, p, ph.d)?;
            loop {
                let c = dda.index();
                let r = self.empty[c];
                if r == 0 {
                    let t0 = dda.t;
                    let mut t1 = dda.t_exit();
                    let fhit = if self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1] {
                        self.facet_hit(c, dda.point(0.0), ph.d, t0, t1, skip)
                    } else {
                        None
                    };
                    if let Some((_, th)) = fhit {
                        t1 = th.max(t0);
                    }
                    if exact
                        && self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1]
                        && self.facet_behind(c, dda.point(0.0), ph.d, t0, t1)
                    {
                        exact = false;
                    }
                    let ell = t1 - t0;
                    let kv = self.k_veg(c, g_cur);
                    // Return extinction: turbid materials without a leaf size (with one, the return
                    // goes back through the same gaps).
                    let kr = if exact { self.k_return(c, g_cur) } else { 0.0 };
                    let fl = self.fluid_of(c);
                    let sig = |b: usize| fl.map_or(0.0, |f| f.sigma_e[b]);
                    // Emits one forced point: `fac` holds the per-band weight factors.
                    let emit = |at: DVec3,
                                u: f64,
                                fac: &[f64],
                                phase: &mut dyn FnMut(DVec3, &mut [f64]) -> bool,
                                out: &mut BatchOut,
                                scratch: &mut [f64],
                                tr: &mut [f64]| {
                        let mut t_ret = Bands::from_elem(0.0, nb);
                        if exact {
                            for (b, t) in t_ret.iter_mut().enumerate() {
                                *t = return_transmittance(tau_ret[b] + (kr + sig(b)) * u);
                            }
                        }
                        let mut g = |_: usize, ov: DVec3, s: &mut [f64]| {
                            if !phase(ov, s) {
                                return false;
                            }
                            for b in 0..nb {
                                s[b] *= fac[b];
                            }
                            true
                        };
                        match &receiver {
                            Some(rx) => self.peel_receiver(
                                rx,
                                ph,
                                (at, shift, ph.path + travelled + t0 + u),
                                None,
                                exact.then_some(&t_ret[..]),
                                out,
                                scratch,
                                tr,
                                &mut g,
                            ),
                            None => self.peel(ph, at, None, false, out, scratch, tr, &mut g),
                        }
                    };
                    if ell > 0.0 {
                        if let Some(f) = fl {
                            let km = kv + f.sigma_e.iter().cloned().fold(0.0, f64::max);
                            let norm = -(-km * ell).exp_m1(); // 1 − e^{−k_m ℓ}
                            if km > 0.0 && norm > 0.0 {
                                for _ in 0..k_pts {
                                    let u = -(1.0 - rng.next_f64() * norm).ln() / km;
                                    let q = km * (-km * u).exp() / norm;
                                    for (b, x) in fac.iter_mut().enumerate() {
                                        *x = (-tau[b]).exp()
                                            * f.sigma_e[b]
                                            * (-(kv + f.sigma_e[b]) * u).exp()
                                            / (q * k_pts as f64);
                                    }
                                    let mut phase = |ov: DVec3, s: &mut [f64]| {
                                        let pv = f.phase.eval_dirs(d_in, ov) / (4.0 * PI);
                                        for b in 0..nb {
                                            s[b] = f.ssa[b] * pv;
                                        }
                                        true
                                    };
                                    emit(dda.point(t0 + u), u, &fac, &mut phase, out, scratch, tr);
                                }
                            }
                        }
                        if receiver.is_some() && kv > 0.0 {
                            let norm = -(-kv * ell).exp_m1();
                            for _ in 0..k_pts {
                                let u = -(1.0 - rng.next_f64() * norm).ln() / kv;
                                // Density kv e^{−kv u}/norm; per-band weight e^{−τ_b − σ_b u}·norm/K.
                                for (b, x) in fac.iter_mut().enumerate() {
                                    *x = (-tau[b] - sig(b) * u).exp() * norm / k_pts as f64;
                                }
                                // Material in proportion to its extinction.
                                let mid = self.pick_turbid(c, g_cur, rng.next_f64() * kv);
                                let Some((mid, tm)) = mid else { continue };
                                let PhotonOptics::Turbid {
                                    sampler,
                                    kernel,
                                    rho,
                                    tau: tl,
                                    ..
                                } = &self.inp.optics[mid]
                                else {
                                    continue;
                                };
                                let g_in = g_cur[tm].max(1e-12);
                                let closed = kernel.is_closed_form();
                                let n = if closed {
                                    DVec3::Z
                                } else {
                                    sampler.sample_normal(d_in, rng)
                                };
                                let mut phase = |ov: DVec3, s: &mut [f64]| {
                                    turbid_peel_phase(
                                        kernel,
                                        closed,
                                        n,
                                        d_in,
                                        ov,
                                        g_in,
                                        rho,
                                        tl,
                                        &mut s[..nb],
                                    )
                                };
                                emit(dda.point(t0 + u), u, &fac, &mut phase, out, scratch, tr);
                            }
                        }
                        for (b, t) in tau.iter_mut().enumerate() {
                            *t += (kv + sig(b)) * ell;
                        }
                        if exact {
                            for (b, t) in tau_ret.iter_mut().enumerate() {
                                *t += (kr + sig(b)) * ell;
                            }
                        }
                    }
                    if let Some((f, _)) = fhit {
                        return exact.then_some((Some(f), tau_ret));
                    }
                    if tau.iter().cloned().fold(f64::INFINITY, f64::min) > 30.0 {
                        return None;
                    }
                }
                match dda.advance() {
                    Exit::Inside => {}
                    Exit::Top => return None,
                    Exit::Bottom => return exact.then_some((None, tau_ret)),
                    Exit::Side(axis, s) => {
                        crossings += 1;
                        if spec.boundary == BoundaryMode::Isolated
                            || crossings > self.inp.params.max_crossings
                            || ph.path + travelled > self.max_path
                        {
                            return None;
                        }
                        let e = dda.point(dda.t);
                        match self.wrap(e, axis, s) {
                            Some(q) => {
                                travelled += dda.t;
                                shift += e - q;
                                p = q;
                                skip = None;
                                continue 'restart;
                            }
                            None => return None,
                        }
                    }
                }
            }
        }
    }

    /// Receiver-mode peel-off (Ray-Carlo eqs. 1–2 with the standard local estimate, physics.md
    /// §9.2): from the event at `p` (wrapped; unwrapped = p + shift) toward the receiver at
    /// distance r, energy `w · f(u) · T(p → receiver) · A |u·axis| / r²` (f = intensity per unit
    /// weight, sr⁻¹), recorded at path length `path + r` with its scattering order; only events
    /// inside the receiver's field of view count.
    #[allow(clippy::too_many_arguments)]
    fn peel_receiver(
        &self,
        rx: &Receiver,
        ph: &Photon,
        (p, shift, path): (DVec3, DVec3, f64),
        skip: Option<u32>,
        known: Option<&[f64]>,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
        mut f: impl FnMut(usize, DVec3, &mut [f64]) -> bool,
    ) {
        let m = p + shift;
        let mut u = rx.position - m;
        let r = u.length();
        if r <= 0.0 {
            return;
        }
        u /= r;
        let cos_rx = -u.dot(rx.axis);
        if cos_rx < rx.cos_fov {
            return;
        }
        if !f(usize::MAX, u, scratch) {
            return;
        }
        if let Some(t) = known {
            tr.copy_from_slice(t);
            // Debug builds (the tests) check the reuse against the shadow ray it replaces.
            #[cfg(debug_assertions)]
            {
                let mut ray = Bands::from_elem(0.0, tr.len());
                self.transmittance_to_receiver(ph, p, u, r, skip, &mut ray);
                for (a, b) in ray.iter().zip(t) {
                    debug_assert!(
                        (a - b).abs() <= 1e-9 * a.max(*b) + 1e-25,
                        "first-flight return transmittance {b:e} vs shadow ray {a:e}"
                    );
                }
            }
        } else {
            self.transmittance_to_receiver(ph, p, u, r, skip, tr);
        }
        if tr.iter().all(|&t| t <= 0.0) {
            return;
        }
        let solid = rx.aperture_m2 * cos_rx / (r * r);
        let e = ph.w[0] * scratch[0] * tr[0] * solid;
        if let Some(wave) = out.wave.as_mut() {
            wave.add(path + r, e, ph.order + 1);
        }
    }

    /// Transmittance from `p` along `u` over the distance `r` to the receiver, with the
    /// first-order gap correlation (leaf size > 0) of a photon that has not scattered yet.
    fn transmittance_to_receiver(
        &self,
        ph: &Photon,
        p: DVec3,
        u: DVec3,
        r: f64,
        skip: Option<u32>,
        tr: &mut [f64],
    ) {
        let g: PerMaterial<f64> = Small::from_fn(self.tur_ids.len(), |tm| self.g_of(tm, u.z));
        // First-order return: back through the gaps the pulse came through (leaf size > 0).
        let hs: PerMaterial<[f64; 2]> = if ph.order == 0 && self.hs_leaf.iter().any(|&l| l > 0.0) {
            Small::from_fn(self.tur_ids.len(), |tm| {
                crate::radiative::engine::hotspot_terms_path(
                    ph.d,
                    u,
                    self.g_of(tm, ph.d.z),
                    g[tm],
                    self.hs_leaf[tm],
                )
            })
        } else {
            Small::from_elem([0.0; 2], 0)
        };
        if hs.is_empty()
            && skip.is_none()
            && let Some(t) = self.column_transmittance(p, u, r, &g)
        {
            // Debug builds (the tests) check the column sums against the shadow walk.
            #[cfg(debug_assertions)]
            {
                COLUMN_RETURNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                self.transmittance(p, u, r, &g, &hs, skip, tr);
                for &a in tr.iter() {
                    debug_assert!(
                        (a - t).abs() <= 1e-9 * a.max(t) + 1e-25,
                        "column return transmittance {t:e} vs shadow ray {a:e}"
                    );
                }
            }
            tr.iter_mut().for_each(|x| *x = t);
            return;
        }
        self.transmittance(p, u, r, &g, &hs, skip, tr);
    }

    /// Reflectance of the flat ground when it is Lambertian (band 0), else `None`.
    fn lambert_ground(&self) -> Option<f64> {
        self.inp
            .flat_ground
            .and_then(|g| match &self.inp.optics[g as usize] {
                PhotonOptics::Lambert { r, .. } => r.first().copied(),
                _ => None,
            })
    }

    /// Return transmittance from the wrapped point `p` along the unit vector `u` to a receiver
    /// at distance `r` (m), from the column sums ([`ColumnDepth`]), when they are exact: the ray
    /// leaves through the top of the grid before reaching the receiver, stays strictly inside
    /// the point's column (both ends of the in-grid part inside it: the column is convex) and
    /// the cells it crosses hold no facet and no fluid. `g` holds G(u) per tracked turbid
    /// material. Optical depth `Σ_m G_m [A_m + u_{f,m} Δz]/u_z` (Δz from the point to its
    /// cell's top); `None`: use the shadow walk.
    #[inline]
    fn column_transmittance(&self, p: DVec3, u: DVec3, r: f64, g: &[f64]) -> Option<f64> {
        let col = self.columns.as_deref()?;
        let spec = self.inp.spec;
        if !(u.z > 0.0) {
            return None;
        }
        let s = (spec.top() - p.z) / u.z;
        if !(s >= 0.0 && s < r) {
            return None;
        }
        let q = p + u * s;
        let mut ij = [0usize; 2];
        for a in 0..2 {
            let x0 = (p[a] - spec.origin[a]) / spec.cell[a];
            let x1 = (q[a] - spec.origin[a]) / spec.cell[a];
            let i = floor_i64(x0) as f64;
            if !(i >= 0.0
                && i < spec.n[a] as f64
                && x0 > i
                && x1 > i
                && x0 < i + 1.0
                && x1 < i + 1.0)
            {
                return None;
            }
            ij[a] = i as usize;
        }
        let k =
            floor_i64((p.z - spec.origin.z) / spec.cell.z).clamp(0, spec.n[2] as i64 - 1) as f64;
        let c = spec.index(ij[0], ij[1], k as usize);
        if !col.clear[c] {
            return None;
        }
        let dz = (spec.origin.z + (k + 1.0) * spec.cell.z - p.z).clamp(0.0, spec.cell.z);
        let base = c * col.ntm;
        let mut tau = 0.0;
        for tm in 0..col.ntm {
            tau += g[tm] * (col.above[base + tm] + col.dens[base + tm] * dz);
        }
        Some(return_transmittance(tau / u.z))
    }

    /// Adds `w_b · f_b · T_b(view)` to the peel tally of every view, where `f(v, out)` fills the
    /// per-band intensity factors (sr⁻¹) toward view v (and returns false if all are zero).
    #[allow(clippy::too_many_arguments)]
    fn peel(
        &self,
        ph: &Photon,
        p: DVec3,
        skip: Option<u32>,
        ground: bool,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
        mut f: impl FnMut(usize, DVec3, &mut [f64]) -> bool,
    ) {
        if let Some(rx) = &self.receiver {
            self.peel_receiver(
                rx,
                ph,
                (p, ph.shift, ph.path),
                skip,
                ph.ret.as_deref(),
                out,
                scratch,
                tr,
                f,
            );
            return;
        }
        for v in 0..self.inp.views.len() {
            // Transmittance first: deep in dense canopies it underflows and the (costly for
            // non-spherical LADs) phase value is not needed. Contributions below 1e-30 of the
            // photon weight are dropped (relative bias < 1e-30).
            let d = self.inp.views[v];
            let hs: &[[f64; 2]] = match self.hs_view.get(v) {
                Some(h) if ph.order == 0 && ph.off == 0 => h,
                _ => &[],
            };
            self.transmittance(p, d, f64::INFINITY, &self.g_view[v], hs, skip, tr);
            if tr.iter().all(|&t| t < 1e-30) || !f(v, d, scratch) {
                continue;
            }
            let base = self.sum.view(v, ph.off);
            let comp = match (ph.order, ground) {
                (0, false) => 0,
                (0, true) => 1,
                _ => 2,
            };
            let cbase = self.sum.view_component(v, comp, ph.off);
            for b in 0..self.nb {
                let x = ph.w[b] * scratch[b] * tr[b];
                out.summary[base + b] += x;
                out.summary[cbase + b] += x;
            }
        }
    }
}

/// The random stream and outputs a flight's walk and its scoring share ([`Ctx::walk_flight`]).
struct FlightIo<'x> {
    rng: &'x mut Xoshiro256PlusPlus,
    out: &'x mut BatchOut,
    /// Peel-off intensity scratch (one band).
    scratch: &'x mut [f64],
    /// Return transmittance scratch (one band).
    tr: &'x mut [f64],
}

impl FlightIo<'_> {
    /// [`Ctx::peel_receiver`] of the point `at` = (point, shift, path) with these scratches.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn peel(
        &mut self,
        ctx: &Ctx,
        rx: &Receiver,
        ph: &Photon,
        at: (DVec3, DVec3, f64),
        skip: Option<u32>,
        known: Option<&[f64]>,
        f: impl FnMut(usize, DVec3, &mut [f64]) -> bool,
    ) {
        ctx.peel_receiver(rx, ph, at, skip, known, self.out, self.scratch, self.tr, f);
    }

    /// A forced turbid point at `at` of a flight along `d`, scored with `fac` times the leaf
    /// intensity of `material` toward the receiver ([`turbid_peel_phase`]: the spherical closed
    /// form, else the one-leaf estimate with a normal drawn here), `g_in` = G(d).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn peel_leaf(
        &mut self,
        ctx: &Ctx,
        rx: &Receiver,
        ph: &Photon,
        at: (DVec3, DVec3, f64),
        material: &PhotonOptics,
        d: DVec3,
        g_in: f64,
        fac: f64,
    ) {
        let PhotonOptics::Turbid {
            sampler,
            kernel,
            rho,
            tau,
            ..
        } = material
        else {
            return;
        };
        let closed = kernel.is_closed_form();
        let n = if closed {
            DVec3::Z
        } else {
            sampler.sample_normal(d, self.rng)
        };
        self.peel(ctx, rx, ph, at, None, None, |_, ov, s| {
            if !turbid_peel_phase(kernel, closed, n, d, ov, g_in, rho, tau, s) {
                return false;
            }
            s[0] *= fac;
            true
        });
    }

    /// The Lambertian flat ground's return at `at` (reflectance factor `fac` = weight × ρ_g/π,
    /// times μ toward the receiver), with the return transmittance `known` when given.
    #[inline]
    fn peel_ground(
        &mut self,
        ctx: &Ctx,
        rx: &Receiver,
        ph: &Photon,
        at: (DVec3, DVec3, f64),
        known: Option<&[f64]>,
        fac: f64,
    ) {
        self.peel(ctx, rx, ph, at, None, known, |_, ov, s| {
            s[0] = fac * ov.z;
            s[0] > 0.0
        });
    }
}

/// One vegetation segment of a flight's walk ([`Ctx::walk_flight`]): the part
/// `[t0, t0 + ell]` (m along the current DDA ray, ell > 0) of the flight inside cell `c`, with
/// vegetation extinction `kv` > 0 (m⁻¹).
struct Segment<'d> {
    c: usize,
    dda: &'d Dda,
    t0: f64,
    ell: f64,
    kv: f64,
    /// Optical depth walked before the segment.
    tau: f64,
    /// Path length from the emitter at `t0`, m.
    l0: f64,
    /// Unwrapped minus wrapped position, m.
    shift: DVec3,
}

/// What a LiDAR flight scores toward the receiver along its walk ([`Ctx::walk_flight`]):
/// [`FirstOrderScore`] (the first flight) and [`ScatterScore`] (later flights).
trait FlightScore {
    /// The vegetation extinction k_v (m⁻¹) of the non-empty cell `c` over `[t0, t1]` along the
    /// walk's ray (`facets`: the cell holds facets), from which the walk samples the collision.
    fn cell(&mut self, ctx: &Ctx, c: usize, dda: &Dda, t0t1: (f64, f64), facets: bool) -> f64;
    /// Scores the return of a vegetation segment (after the collision sampling in it).
    fn segment(&mut self, ctx: &Ctx, ph: &Photon, io: &mut FlightIo, seg: &Segment);
    /// Scores the return of facet `f`, which ends the walk at `at` = (point, shift, path) after
    /// the optical depth `tau`; whether it did (its collision is then not peeled off). Default:
    /// not scored.
    fn facet(
        &mut self,
        _ctx: &Ctx,
        _ph: &Photon,
        _io: &mut FlightIo,
        _f: u32,
        _at: (DVec3, DVec3, f64),
        _tau: f64,
    ) -> bool {
        false
    }
    /// Scores the return of the flat ground (or bottom) that ends the walk at `at` after the
    /// optical depth `tau`; whether it did.
    fn ground(
        &mut self,
        ctx: &Ctx,
        ph: &Photon,
        io: &mut FlightIo,
        at: (DVec3, DVec3, f64),
        tau: f64,
    ) -> bool;
    /// Whether the walk stops after a cell at optical depth `tau` (`collided`: the collision
    /// is already sampled).
    fn stop(&self, tau: f64, collided: bool) -> bool;
    /// The return optical depth of the surface that ends a flight with no collision before it
    /// (for the surface's collision peel-off), when known (default: not).
    fn surface_ret(&self) -> Option<f64> {
        None
    }
}

/// The first flight's scoring ([`Ctx::first_flight`]): the first-order return of the
/// vegetation binned by digitiser bin, and with [`LidarEstimator::ExpectedValue`] the
/// Lambertian ground or facet that ends the walk, with the return transmittance from the
/// optical depth walked.
struct FirstOrderScore<'g> {
    rx: Receiver,
    /// Flight direction.
    d: DVec3,
    /// Cosine of the flight to the receiver axis.
    cos_rx: f64,
    in_fov: bool,
    /// Exact-backscatter intensity per unit intercepted weight per turbid material, sr⁻¹.
    back: PerMaterial<f64>,
    /// Photon weight, J.
    w: f64,
    g_cur: &'g [f64],
    /// Return optical depth walked (materials without a leaf size).
    tau_ret: f64,
    /// No one-sided facet crossed from behind yet: the return is the flight reversed.
    exact: bool,
    /// Current cell: return extinction k_r (m⁻¹) and Σ k_m f_m (m⁻¹ sr⁻¹).
    kr: f64,
    kf: f64,
}

impl FlightScore for FirstOrderScore<'_> {
    #[inline]
    fn cell(&mut self, ctx: &Ctx, c: usize, dda: &Dda, (t0, t1): (f64, f64), facets: bool) -> f64 {
        if self.exact && facets && ctx.facet_behind(c, dda.point(0.0), self.d, t0, t1) {
            self.exact = false;
        }
        // Extinction (m⁻¹): vegetation k_v, return k_r (materials without a leaf size), and
        // Σ k_m f_m (m⁻¹ sr⁻¹), in one pass over the cell's entries.
        let (mut kv, mut kr, mut kf) = (0.0, 0.0, 0.0);
        for e in ctx.inp.grid.turbid_of(c) {
            let tm = ctx.tur_mat[e.material as usize];
            if tm != u32::MAX {
                let k = self.g_cur[tm as usize] * e.density as f64;
                kv += k;
                kf += k * self.back[tm as usize];
                // hs_leaf ≥ 0 (validated): no leaf size means 0.
                if ctx.hs_leaf[tm as usize] <= 0.0 {
                    kr += k;
                }
            }
        }
        self.kr = kr;
        self.kf = kf;
        kv
    }

    #[inline]
    fn segment(&mut self, ctx: &Ctx, ph: &Photon, io: &mut FlightIo, seg: &Segment) {
        let &Segment {
            c,
            dda,
            t0,
            ell,
            kv,
            tau,
            l0,
            shift,
        } = seg;
        let (rx, d, g_cur) = (self.rx, self.d, self.g_cur);
        if self.in_fov {
            if self.exact {
                let base = self.w
                    * (-tau).exp()
                    * return_transmittance(self.tau_ret)
                    * self.kf
                    * rx.aperture_m2
                    * self.cos_rx;
                if base > 0.0 {
                    #[cfg(debug_assertions)]
                    ctx.check_first_flight_return(
                        ph,
                        (dda.point(t0), shift, l0),
                        d,
                        (self.tau_ret, self.kr, 0.5 * ell),
                    );
                    if let Some(wave) = io.out.wave.as_mut() {
                        bin_first_order(wave, l0, ell, kv + self.kr, base, io.rng);
                    }
                }
            } else {
                // One forced point with a shadow ray (see `Ctx::first_flight`).
                let norm = -(-kv * ell).exp_m1();
                let u = -(1.0 - io.rng.next_f64() * norm).ln() / kv;
                if let Some((mid, tm)) = ctx.pick_turbid(c, g_cur, io.rng.next_f64() * kv) {
                    let at = (dda.point(t0 + u), shift, l0 + u);
                    let fac = (-tau).exp() * norm;
                    let g_in = g_cur[tm].max(1e-12);
                    io.peel_leaf(ctx, &rx, ph, at, &ctx.inp.optics[mid], d, g_in, fac);
                }
            }
        }
        if self.exact {
            self.tau_ret += self.kr * ell;
        }
    }

    #[inline]
    fn facet(
        &mut self,
        ctx: &Ctx,
        ph: &Photon,
        io: &mut FlightIo,
        f: u32,
        at: (DVec3, DVec3, f64),
        tau: f64,
    ) -> bool {
        // `ExpectedValue`: a Lambertian facet's first-order return, scored with the
        // probability e^{−τ} of reaching it (as the ground below); past a one-sided facet
        // crossed from behind, with a shadow ray to the receiver.
        if ctx.ms_stop <= 0.0 {
            return false;
        }
        let fa = &ctx.inp.facets[f as usize];
        let PhotonOptics::Lambert { r, t, t_dir } = &ctx.inp.optics[fa.material as usize] else {
            return false;
        };
        // The facet collision's peel-off (`trace_photon`), band 0.
        let d = self.d;
        let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize();
        let n_in = if n.dot(d) < 0.0 { n } else { -n };
        let mu = n.dot(d).abs().max(1e-6);
        let td = t_dir.first().copied().unwrap_or(0.0);
        let through = if td > 0.0 { td.powf(1.0 / mu) } else { 0.0 };
        let pr = (1.0 - through) * r.first().copied().unwrap_or(0.0);
        let pt = (1.0 - through) * t.first().copied().unwrap_or(0.0);
        let fac = (-tau).exp() / PI;
        let t_ret = [return_transmittance(self.tau_ret)];
        let known = self.exact.then_some(&t_ret[..]);
        io.peel(ctx, &self.rx, ph, at, Some(f), known, |_, ov, s| {
            let c = n_in.dot(ov);
            s[0] = fac * if c > 0.0 { pr } else { pt } * c.abs();
            s[0] > 0.0
        });
        true
    }

    #[inline]
    fn ground(
        &mut self,
        ctx: &Ctx,
        ph: &Photon,
        io: &mut FlightIo,
        at: (DVec3, DVec3, f64),
        tau: f64,
    ) -> bool {
        // `ExpectedValue`: the walk reached a Lambertian ground, whose first-order return is
        // scored with the probability e^{−τ} of getting there (w e^{−τ} ρ_g μ/π T_ret A
        // cos/r², the return transmittance from the walk, or past a one-sided facet crossed
        // from behind a shadow ray) instead of at the ground collision only.
        if ctx.ms_stop <= 0.0 {
            return false;
        }
        let Some(rg) = ctx.lambert_ground() else {
            return false;
        };
        let fac = (-tau).exp() * rg / PI;
        let t_ret = [return_transmittance(self.tau_ret)];
        io.peel_ground(ctx, &self.rx, ph, at, self.exact.then_some(&t_ret[..]), fac);
        true
    }

    #[inline]
    fn stop(&self, tau: f64, _collided: bool) -> bool {
        // e^{−30} ≈ 1e-13: the forced estimate stops (as `forced_peel`).
        tau > 30.0
    }

    #[inline]
    fn surface_ret(&self) -> Option<f64> {
        self.exact.then_some(self.tau_ret)
    }
}

/// The scoring of a flight past the first scattering ([`Ctx::scatter_flight`]): one forced
/// point per vegetation segment up to the stop depth `c τ*`, and the Lambertian flat ground,
/// weighted by `e^{−(1−1/c)τ}`.
struct ScatterScore<'g> {
    rx: Receiver,
    /// Flight direction.
    d: DVec3,
    g_cur: &'g [f64],
    /// Discrete (Ray-Carlo) sampler: the Phase-stage rows give the leaf intensity.
    discrete: bool,
    /// Reflectance of the flat ground when Lambertian.
    lambert_ground: Option<f64>,
    /// Stop depth `c τ*`.
    tau_stop: f64,
    /// `1 − 1/c`.
    keep: f64,
    /// `tan²` of the receiver's FOV half-angle (< 0: a FOV of 90° or more, no segment test).
    fov_tan2: f64,
}

/// Whether every point of the segment from `a` along the unit vector `d` over `len` (m,
/// unwrapped coordinates) lies outside the field of view of `rx` (`tan2` = tan² of its
/// half-angle, FOV < 90°): the segment's least distance ρ from the receiver axis exceeds the
/// cone radius `s_max tan α` at the largest along-axis distance `s_max` of its ends (s is linear
/// along the segment, and a point at along-axis distance s ≤ s_max lies in the cone only if
/// ρ ≤ s tan α), with a relative margin of 1e-6 so that rounding never drops a point in view.
/// Such a segment scores nothing ([`Ctx::peel_receiver`] drops points out of view).
#[inline]
fn segment_out_of_fov(rx: &Receiver, tan2: f64, a: DVec3, d: DVec3, len: f64) -> bool {
    let ax = rx.axis;
    let va = a - rx.position;
    let (sa, sd) = (va.dot(ax), d.dot(ax));
    let s_max = sa.max(sa + sd * len);
    if !(s_max > 0.0) {
        return s_max <= 0.0;
    }
    // Perpendicular parts of the start and of the direction; least |pa + t pd| on [0, len].
    let pa = va - ax * sa;
    let pd = d - ax * sd;
    let pd2 = pd.length_squared();
    let t = if pd2 > 0.0 {
        (-pa.dot(pd) / pd2).clamp(0.0, len)
    } else {
        0.0
    };
    let rho2 = (pa + pd * t).length_squared();
    rho2 > (1.0 + 1e-6) * s_max * s_max * tan2
}

impl FlightScore for ScatterScore<'_> {
    #[inline]
    fn cell(&mut self, ctx: &Ctx, c: usize, _dda: &Dda, _t0t1: (f64, f64), _facets: bool) -> f64 {
        ctx.k_veg(c, self.g_cur)
    }

    #[inline]
    fn segment(&mut self, ctx: &Ctx, ph: &Photon, io: &mut FlightIo, seg: &Segment) {
        let &Segment {
            c,
            dda,
            t0,
            ell,
            kv,
            tau,
            l0,
            shift,
        } = seg;
        let (rx, d, g_cur, keep) = (self.rx, self.d, self.g_cur, self.keep);
        // Forced return over [t0, t0 + ℓ_f], ℓ_f up to the stop depth.
        let ell_f = if tau + ell * kv > self.tau_stop {
            ((self.tau_stop - tau) / kv).clamp(0.0, ell)
        } else {
            ell
        };
        if ell_f <= 0.0 {
            return;
        }
        // Nothing to score (and no draws) when the whole segment is out of the receiver's view.
        if self.fov_tan2 >= 0.0
            && segment_out_of_fov(&rx, self.fov_tan2, dda.point(t0) + shift, d, ell_f)
        {
            return;
        }
        let beta = keep * kv;
        let v = io.rng.next_f64();
        let (u, mass) = if beta * ell_f > 1e-12 {
            let em = (-beta * ell_f).exp_m1();
            (-(v * em).ln_1p() / beta, -em / beta)
        } else {
            (v * ell_f, ell_f)
        };
        let fac = (-keep * tau).exp() * mass * kv;
        let Some((mid, tm)) = ctx.pick_turbid(c, g_cur, io.rng.next_f64() * kv) else {
            return;
        };
        let material = &ctx.inp.optics[mid];
        let at = (dda.point(t0 + u.min(ell_f)), shift, l0 + u.min(ell_f));
        match material {
            PhotonOptics::Turbid {
                discrete: Some(rows),
                ..
            } if self.discrete => {
                let row = ph.di.min(rows.samplers.len() - 1);
                io.peel(ctx, &rx, ph, at, None, None, |_, ov, s| {
                    let m = ctx.inp.dirs.find_sector(ov);
                    let dom = ctx.inp.dirs.tiling()[m].solid_angle_sr;
                    s[0] = fac * rows.tables[0].get(row, m) as f64 / dom;
                    s[0] > 0.0
                });
            }
            _ => io.peel_leaf(ctx, &rx, ph, at, material, d, g_cur[tm].max(1e-12), fac),
        }
    }

    #[inline]
    fn ground(
        &mut self,
        ctx: &Ctx,
        ph: &Photon,
        io: &mut FlightIo,
        at: (DVec3, DVec3, f64),
        tau: f64,
    ) -> bool {
        let Some(rg) = self.lambert_ground else {
            return false;
        };
        // The walk reached the ground: Q = e^{−τ_g/c}.
        let fac = (-self.keep * tau).exp() * rg / PI;
        io.peel_ground(ctx, &self.rx, ph, at, None, fac);
        true
    }

    #[inline]
    fn stop(&self, tau: f64, collided: bool) -> bool {
        collided && (tau >= self.tau_stop || self.keep * tau > 30.0)
    }
}

/// Peel-off radiant intensity per unit intercepted weight of a turbid leaf event toward
/// `ov`, per band, into `s` (sr⁻¹): Γ_b(Ω'→Ω_v)/(π G(Ω')) (physics.md §3.3). Spherical LAD
/// (`closed`): its closed form from the kernel's (Γ_ρ, Γ_τ). Other LADs: the unbiased one-leaf
/// estimate given the sampled leaf normal `n`: ρ_b|Ω_v·n|/π on the incidence side, τ_b|Ω_v·n|/π
/// beyond (E_n[·] = Γ_b/(π G)). Returns whether any band is positive.
#[allow(clippy::too_many_arguments)]
#[inline]
fn turbid_peel_phase(
    kernel: &VolscattKernel,
    closed: bool,
    n: DVec3,
    d_in: DVec3,
    ov: DVec3,
    g_in: f64,
    rho: &[f64],
    tau: &[f64],
    s: &mut [f64],
) -> bool {
    if closed {
        let (gr, gt) = kernel.gamma_components(d_in, ov);
        let norm = 1.0 / (PI * g_in);
        for ((s, r), t) in s.iter_mut().zip(rho).zip(tau) {
            *s = (r * gr + t * gt) * norm;
        }
    } else {
        let c = ov.dot(n);
        let f = if c > 0.0 { rho } else { tau };
        for (s, f) in s.iter_mut().zip(f) {
            *s = f * c.abs() / PI;
        }
    }
    s.iter().any(|&x| x > 0.0)
}

/// Most strata of one vegetation segment in [`bin_first_order`] (a 1 m cell spans ~7 bins of
/// 1 ns; longer segments group consecutive bins per stratum).
const MAX_FIRST_ORDER_STRATA: f64 = 32.0;

/// Largest ratio h/l0 (one digitiser bin h, m, over the segment start's distance from the
/// receiver l0, m) for which [`bin_first_order`] estimates single-bin strata by
/// [`inv_sq_mean`] instead of a random point. Every such stratum `[a, b]` then has
/// `w/R ≤ h/l0 < 1e-3` (`w = b − a ≤ h`, `R = l0 + μ ≥ l0`), where the terms that
/// [`inv_sq_mean`] drops are below 5.4e-11 of the stratum's value. ALS at 1000 m with 1 ns
/// bins: h/l0 ≈ 1.5e-4; TLS at a few metres (≈ 0.05) keeps the random point.
const FIRST_ORDER_MOMENT_RATIO: f64 = 1e-3;

/// Mean offset from `a` and variance, m and m², of the truncated exponential density
/// `∝ e^{−αu}` on a stratum `[a, a + w]` (`α > 0` m⁻¹, `ia = 1/α` m, `w > 0` m), given
/// `em = e^{−αw} − 1` (already computed for the stratum's mass). With `t = αw`:
/// `μ − a = 1/α − w e^{−t}/(1 − e^{−t})`, `σ² = 1/α² − w² e^{−t}/(1 − e^{−t})²` (from
/// `log Z = log(1 − e^{−αw}) − log α`, `μ = −∂ log Z/∂α`, `σ² = ∂² log Z/∂α²`): one division.
/// Both cancel for small `t` (errors `~2ε/t` of `w` and `~4ε/t²` of `w²`: 4e-13 and 1e-9 at
/// `t = 1e-3`); below `t = 1e-3` the Bernoulli series (`1/(eᵗ − 1) = Σ Bₙ tⁿ⁻¹/n!`)
/// `(μ − a)/w = 1/2 − t/12 + t³/720 − …` and `σ²/w² = 1/12 − t²/240 + t⁴/6048 − …`, cut
/// after the terms shown (≤ 3e-20 and 2e-16). [`inv_sq_mean`] needs far less: at
/// `w/R = 1e-3` an error of 5e-9 `w` in the offset or 3e-6 `w²` in the variance moves it
/// by 1e-11 relative.
#[inline]
fn trunc_exp_moments(alpha: f64, ia: f64, w: f64, em: f64) -> (f64, f64) {
    let t = alpha * w;
    if t < 1e-3 {
        let t2 = t * t;
        (
            w * (0.5 - t * (1.0 / 12.0 - t2 * (1.0 / 720.0))),
            w * w * (1.0 / 12.0 - t2 * (1.0 / 240.0)),
        )
    } else {
        let iem = 1.0 / em;
        let g = w * (1.0 + em) * iem; // −w e^{−t}/(1 − e^{−t})
        (ia + g, ia * ia - w * g * iem)
    }
}

/// Estimate of `E[1/(l0 + u)²]`, m⁻², for `u` with mean at distance `r` from the receiver
/// (`r = l0 + μ`, m) and variance `var` (m²), from the Taylor expansion of `(r + x)⁻²` about
/// `x = 0`: `E = r⁻²(1 + 3σ²/r² − 4m₃/r³ + 5m₄/r⁴ − …)` with the central moments `m_n`; the
/// first two terms are kept. For the truncated exponential of a stratum of width `w` (any
/// `αw > 0`): `|m₃| ≤ 0.01325 w³` (largest, 0.0132455 w³, at `αw = 2.745`), `m₄ ≤ w⁴/80`
/// (the uniform limit), and `|m_n| ≤ w^{n−2}σ² ≤ w^n/12` (`|x| ≤ w`, `σ² ≤ w²/12`); the
/// unit test checks the first two by quadrature. With `ρ = w/r ≤ 1e-3` the dropped terms are
/// at most `0.053ρ³ + 0.0625ρ⁴ + Σ_{n≥5}(n+1)ρⁿ/12 < 5.4e-11` relative. `var = 0`: `1/r²`.
#[inline(always)]
fn inv_sq_mean(r: f64, var: f64) -> f64 {
    let q = 1.0 / (r * r);
    q * (1.0 + 3.0 * var * q)
}

/// Offset from the stratum start and variance of the point at which [`bin_first_order`]
/// evaluates `1/(l0 + u)²` in a stratum of width `w` (`em = e^{−αw} − 1`): the moments of
/// the stratum's truncated exponential ([`trunc_exp_moments`], `moments`), or a point drawn
/// from it by inverse CDF with variance 0.
#[inline(always)]
fn stratum_point(
    moments: bool,
    alpha: f64,
    ia: f64,
    w: f64,
    em: f64,
    rng: &mut Xoshiro256PlusPlus,
) -> (f64, f64) {
    if moments {
        trunc_exp_moments(alpha, ia, w, em)
    } else {
        (-(rng.next_f64() * em).ln_1p() * ia, 0.0)
    }
}

/// Bins the forced first-order return of a vegetation segment of a LiDAR first flight
/// ([`Ctx::first_flight`]; DART 5 paper §4, physics.md §9.2, §9.6): energy density
/// `base · e^{−αu}/(l0 + u)²` J m⁻¹ over the distance `u ∈ [0, ell]` m from the segment start,
/// `l0` m the distance from the receiver at `u = 0` (recorded at path `2(l0 + u)`), `α > 0`
/// m⁻¹. Strata: the digitiser bins (before the gate, after it, and groups of `kb` bins beyond
/// [`MAX_FIRST_ORDER_STRATA`]); in each `[a, b]` the exact mass `e^{−αa}(1 − e^{−α(b−a)})/α`
/// times an estimate of the mean of `1/(l0 + u)²` under the density `∝ e^{−αu}` on `[a, b]`.
/// Single-bin strata in the gate far from the receiver (`h/l0 <`
/// [`FIRST_ORDER_MOMENT_RATIO`]): the deterministic moment estimate [`inv_sq_mean`] (bias
/// < 5.4e-11 relative, no random draw; the whole strata share one mean offset and variance,
/// having one width). Other strata: `1/(l0 + u)²` at `u` drawn from the density (inverse CDF),
/// unbiased for every bin; the whole strata share one uniform (the same offset from their
/// start: each point still has its stratum's density), the two end strata draw their own.
fn bin_first_order(
    wave: &mut crate::lidar::waveform::WaveformBinner,
    l0: f64,
    ell: f64,
    alpha: f64,
    base: f64,
    rng: &mut Xoshiro256PlusPlus,
) {
    let h = 0.5 * wave.bin_len_m(); // one bin, in distance along the ray
    let n = wave.n_bins() as f64;
    // Bin coordinate of the segment's ends.
    let x0 = (2.0 * l0 - wave.bin_start_path_m(0)) / (2.0 * h);
    let x1 = x0 + ell / h;
    if !(x0.is_finite() && x1.is_finite() && alpha > 0.0 && ell > 0.0) {
        return;
    }
    let kb = ceil_small((x1.min(n) - x0.max(0.0)) / MAX_FIRST_ORDER_STRATA).max(1.0);
    // Single-bin strata in the gate take the moment estimate (whole strata are such strata).
    let moments = kb == 1.0 && h < FIRST_ORDER_MOMENT_RATIO * l0;
    // Whole strata: width kb·h, shared offset and variance (the uniform drawn here unless
    // they take the moments; the libm calls made at the first whole stratum only: a segment
    // over one or two bins has none).
    let v_full = if moments { 0.0 } else { rng.next_f64() };
    let ia = 1.0 / alpha; // m
    let mut full: Option<(f64, f64, f64)> = None;
    let mut full = move || {
        *full.get_or_insert_with(|| {
            let w = kb * h;
            let em = (-alpha * w).exp_m1();
            let (off, var) = if moments {
                trunc_exp_moments(alpha, ia, w, em)
            } else {
                (-(v_full * em).ln_1p() * ia, 0.0)
            };
            (em, off, var)
        })
    };
    // Common case: one bin per stratum and the segment well inside the gate. The strata are
    // visited in the order of the general loop below, with its arithmetic (the same values
    // bit for bit), without its per-stratum gate, grouping and edge logic: stratum k is bin k,
    // from ⌊x0⌋; the first and the last have their own point, the whole ones between share
    // the offset.
    if kb == 1.0 && x0 >= 0.0 && x1 < n - 1.0 {
        let mut k = (x0 as i64) as f64; // ⌊x0⌋ (0 ≤ x0 < n)
        let k0 = k as usize;
        let mut ki = k0; // the same bin as an index (k < x1 < n − 1 throughout)
        let (mut a, mut ea) = (0.0, 1.0);
        let mut rejected = 0;
        let bins = wave.first_order_bins_mut();
        // A packet as `WaveformBinner::add_first_order_at` books it (finite and ≥ 0, else
        // counted as rejected).
        let mut book = |i: usize, e: f64| {
            if crate::lidar::waveform::bookable(e) {
                bins[i].add(e);
            } else {
                rejected += 1;
            }
        };
        loop {
            let edge = k + 1.0;
            if edge >= x1 {
                // Last stratum [a, ell] (the only one when the segment lies in one bin).
                if ell > a {
                    let em = (-alpha * (ell - a)).exp_m1();
                    let (off, var) = stratum_point(moments, alpha, ia, ell - a, em, rng);
                    let r = l0 + clamp_between(a + off, a, ell);
                    book(ki, base * (ea * -em * ia) * inv_sq_mean(r, var));
                }
                break;
            }
            let bx = (edge - x0) * h;
            let b = if bx < ell { bx } else { ell };
            if !(b > a) {
                // Both ends rounded to ell (the bin ends are strictly increasing): the general
                // loop stops here too.
                break;
            }
            let (em, off, var) = if a > 0.0 {
                full()
            } else {
                let em = (-alpha * (b - a)).exp_m1();
                let (off, var) = stratum_point(moments, alpha, ia, b - a, em, rng);
                (em, off, var)
            };
            let r = l0 + clamp_between(a + off, a, b);
            book(ki, base * (ea * -em * ia) * inv_sq_mean(r, var));
            ea *= 1.0 + em;
            a = b;
            k = edge;
            ki += 1;
        }
        // Bins k0..=ki (ki < n − 1): the last one booked, or the one after it.
        wave.mark_written(k0, ki + 1);
        wave.reject(rejected);
        return;
    }
    let mut xa = x0;
    let mut ea = 1.0; // e^{−α a}
    let mut a = 0.0;
    // Strata: ≤ MAX_FIRST_ORDER_STRATA + 2 (+ rounding steps); the cap only guards the loop.
    for _ in 0..(2 * MAX_FIRST_ORDER_STRATA as usize + 8) {
        if a >= ell {
            break;
        }
        let in_gate = (0.0..n).contains(&xa);
        let edge = if xa < 0.0 {
            0.0
        } else if xa >= n {
            f64::INFINITY
        } else {
            // ⌊xa/kb⌋ by truncation (xa ≥ 0 here; no libm call).
            ((((xa / kb) as i64) as f64 + 1.0) * kb).min(n)
        };
        let xb = edge.min(x1);
        let b = if xb >= x1 {
            ell
        } else {
            ((xb - x0) * h).min(ell)
        };
        if !(b > a) {
            // Rounding at an edge: step past it.
            xa = xb.max(xa) + f64::EPSILON * xa.abs().max(1.0);
            continue;
        }
        let whole = in_gate && a > 0.0 && xb < x1 && edge == xa + kb;
        let (em, off, var) = if whole {
            full()
        } else {
            let em = (-alpha * (b - a)).exp_m1(); // e^{−α(b−a)} − 1 ≤ 0
            let (off, var) = stratum_point(moments && in_gate, alpha, ia, b - a, em, rng);
            (em, off, var)
        };
        let mass = ea * -em * ia;
        let r = l0 + (a + off).clamp(a, b);
        let e = base * mass * inv_sq_mean(r, var);
        if in_gate && kb == 1.0 {
            wave.add_first_order_at(xa as usize, e);
        } else {
            wave.add(2.0 * r, e, 1);
        }
        ea *= 1.0 + em;
        a = b;
        xa = xb;
    }
}

/// `u` clamped to `[a, b]` (`a ≤ b`), as `f64::clamp` (NaN stays NaN) without its checks.
#[inline(always)]
fn clamp_between(u: f64, a: f64, b: f64) -> f64 {
    if u < a {
        a
    } else if u > b {
        b
    } else {
        u
    }
}

/// `x − ⌊x⌋` for `0 ≤ x < 2⁶³` (the fractional part of a lattice coordinate), by truncation:
/// the same value as `x.fract()` without its libm call. Through `i64` (one conversion each
/// way; the `u64` round trip costs ~20 instructions on x86-64), the same integer for these `x`.
#[inline]
fn unit_fract(x: f64) -> f64 {
    x - (x as i64) as f64
}

/// `⌈v⌉` for `v < 2⁶³` by truncation (no libm call), except that it gives `+0` where `ceil`
/// gives `−0` (`−1 < v < 0`) and `−2⁶³` below `−2⁶³`: the same after `max(1.0)`, as its
/// caller takes.
#[inline]
fn ceil_small(v: f64) -> f64 {
    let t = (v as i64) as f64;
    if t < v { t + 1.0 } else { t }
}

/// Transmittance `e^{−τ}` of a return optical depth τ, zero beyond τ = 69.1 (e^{−69.1} < 1e-30,
/// the cut of [`Ctx::transmittance`]).
#[inline]
fn return_transmittance(tau: f64) -> f64 {
    if tau > 69.1 { 0.0 } else { (-tau).exp() }
}

/// Marks a fluid collision in `Hit::Volume::c`.
const FLUID_BIT: usize = 1 << 63;

/// Chooses an outcome among `p[k][b]` (per-band probabilities) with `q_k ∝ Σ_b w_b p_b(k)` and
/// reweights `w` by `p_b(k)/q_k`; returns `None` (weights zeroed) when every outcome has
/// probability zero in every band.
fn choose(w: &mut [f64], p: &[&[f64]], rng: &mut Xoshiro256PlusPlus) -> Option<usize> {
    let mut q: [f64; 4] = [0.0; 4];
    let mut tot = 0.0;
    for (k, pk) in p.iter().enumerate() {
        q[k] = w.iter().zip(pk.iter()).map(|(a, b)| a * b).sum();
        tot += q[k];
    }
    if tot <= 0.0 || !tot.is_finite() {
        w.iter_mut().for_each(|x| *x = 0.0);
        return None;
    }
    let u = rng.next_f64() * tot;
    let mut acc = 0.0;
    let mut k_sel = p.len() - 1;
    for k in 0..p.len() {
        acc += q[k];
        if u < acc && q[k] > 0.0 {
            k_sel = k;
            break;
        }
    }
    while q[k_sel] <= 0.0 {
        k_sel -= 1;
    }
    let qk = q[k_sel] / tot;
    for (b, x) in w.iter_mut().enumerate() {
        *x *= p[k_sel][b] / qk;
    }
    Some(k_sel)
}

/// Runs the Monte Carlo simulation.
pub fn run(inp: &PhotonInput) -> PhotonResult {
    let spec = inp.spec;
    let nb = inp.e_dir.len();
    let has_sky = inp.e_diff.iter().any(|&e| e > 0.0);
    let w = nb * if has_sky { 2 } else { 1 };
    let n_dirs = inp.dirs.tiling().len();
    let ctx = Ctx::new(inp, nb, w);
    let area = ctx.size.0 * ctx.size.1;
    let mut source = vec![0.0; w];
    for b in 0..nb {
        source[b] = inp.e_dir[b] * area;
        if has_sky {
            source[nb + b] = inp.e_diff[b] * area;
        }
    }
    let n_batches = inp.params.batches.max(1) as u64;
    let per_batch = inp.params.photons.div_ceil(n_batches).max(1);
    let n_entries = inp.grid.turbid.len();
    let n_facets = inp.facets.len();
    let n_cols = spec.n[0] * spec.n[1];
    let mut res = PhotonResult {
        n_channels: w,
        n_bands: nb,
        has_sky,
        source: source.clone(),
        escaped: vec![0.0; n_dirs * w],
        peel: vec![0.0; inp.views.len() * w],
        absorbed_turbid: vec![0.0; n_entries * w],
        intercepted_turbid: vec![0.0; n_entries * w],
        absorbed_facet: vec![0.0; n_facets * w],
        intercepted_facet: vec![0.0; n_facets * w],
        absorbed_ground: vec![0.0; n_cols * w],
        intercepted_ground: vec![0.0; n_cols * w],
        lost: vec![0.0; w],
        roulette: vec![0.0; w],
        summary: ctx.sum.clone(),
        photons: per_batch * n_batches,
        ..Default::default()
    };
    let mut fluid_abs: std::collections::BTreeMap<u32, Vec<f64>> = Default::default();
    // Batches run in waves (bounded memory); merged in batch order.
    let wave = 16u64;
    let mut b0 = 0u64;
    while b0 < n_batches {
        let b1 = (b0 + wave).min(n_batches);
        let outs: Vec<BatchOut> = (b0..b1)
            .into_par_iter()
            .map(|b| run_batch(&ctx, b, per_batch, &source))
            .collect();
        for o in outs {
            let s = &o.summary;
            for j in 0..n_dirs {
                for ch in 0..w {
                    res.escaped[j * w + ch] += s[ctx.sum.dir(j, ch)];
                }
            }
            for v in 0..inp.views.len() {
                for ch in 0..w {
                    res.peel[v * w + ch] += s[ctx.sum.view(v, ch)];
                }
            }
            o.abs_tur.add_into(&mut res.absorbed_turbid);
            o.int_tur.add_into(&mut res.intercepted_turbid);
            o.abs_fac.add_into(&mut res.absorbed_facet);
            o.int_fac.add_into(&mut res.intercepted_facet);
            o.abs_gnd.add_into(&mut res.absorbed_ground);
            o.int_gnd.add_into(&mut res.intercepted_ground);
            let mut keys: Vec<_> = o.abs_fluid.keys().copied().collect();
            keys.sort_unstable();
            for k in keys {
                let e = fluid_abs.entry(k).or_insert_with(|| vec![0.0; w]);
                e.iter_mut()
                    .zip(&o.abs_fluid[&k])
                    .for_each(|(a, b)| *a += b);
            }
            res.lost.iter_mut().zip(&o.lost).for_each(|(a, b)| *a += b);
            res.roulette
                .iter_mut()
                .zip(&o.roulette)
                .for_each(|(a, b)| *a += b);
            res.events += o.events;
            res.crossings += o.crossings;
            res.skipped += o.skipped;
            res.batch_summaries.push(o.summary);
        }
        b0 = b1;
    }
    for (k, v) in fluid_abs {
        res.fluid_cells.push(k);
        res.absorbed_fluid.extend(v);
    }
    res
}

/// Smallest empty-space distance from which the Photon flights jump ([`skip_field`]): an empty
/// cell costs them only ~20 instructions, so short jumps do not pay (measured, callgrind,
/// LiDAR forest discrete-peak: jumping from distance 4 cost 27 M more instructions than it
/// saved over 64 pulses; the urban scan +7 %). From 8 only long runs of empty air jump.
const MIN_SKIP_DISTANCE: u8 = 8;

/// A flight's jump from an empty cell at distance `r` ≥ 2 ([`Dda::skip_to`]), counting the
/// cells skipped. Out of line and cold (measured: inlined into the Photon walks' loops, the
/// jump code made the common path of the LiDAR forest 5 % longer). Only the flights
/// ([`Ctx::fly`]) jump: the same branch in the forced walk and the transmittance rays cost the
/// LiDAR forest 2 % (`trace_photon` 751.5 M → 766.5 M instructions over 64 pulses) without
/// ever jumping there; they cross empty cells one by one, unread.
#[cold]
#[inline(never)]
fn fly_skip(dda: &mut Dda, r: u8, skipped: &mut u64) -> Exit {
    let h = r as i64 - 1;
    let (e, faces) = dda.skip_to(h, dda.skip_exit(h));
    *skipped += faces - 1;
    e
}

/// Crosses the run of empty cells crossed one by one (field value 1, see [`skip_field`]) that
/// starts at the current cell of `dda`: steps until the ray enters a cell with another value
/// (returns [`Exit::Inside`] there) or leaves the grid (returns the exit [`Dda::advance`] would
/// report), adding the empty cells entered on the way to `crossings` (the caller counts the
/// current one and the cell it stops in). The same cells, segment ends and exit as a loop of
/// [`Dda::advance`] calls (bit for bit: [`Dda::step_at`] moves into the same state), in a loop
/// that reads nothing else: an empty cell adds nothing to optical depths and draws nothing.
#[inline(always)]
fn cross_empty(dda: &mut Dda, empty: &[u8], crossings: &mut u64) -> Exit {
    let mut n = 0u64;
    let exit = loop {
        if !dda.step_at(dda.t_exit()) {
            break dda.exit_kind();
        }
        if empty[dda.index()] != 1 {
            break Exit::Inside;
        }
        n += 1;
    };
    *crossings += n;
    exit
}

/// Photon stream purpose tag (see `scene::spawn::stream`).
pub const PHOTON_STREAM: u64 = 0x5048_4f54_4f4e; // "PHOTON"

fn run_batch(ctx: &Ctx, batch: u64, n: u64, source: &[f64]) -> BatchOut {
    let inp = ctx.inp;
    let spec = inp.spec;
    let (nb, w) = (ctx.nb, ctx.w);
    let n_entries = inp.grid.turbid.len();
    let n_cols = spec.n[0] * spec.n[1];
    let mut out = BatchOut {
        summary: vec![0.0; ctx.sum.len()],
        abs_tur: Acc::new(n_entries, w),
        int_tur: Acc::new(n_entries, w),
        abs_fac: Acc::new(inp.facets.len(), w),
        int_fac: Acc::new(inp.facets.len(), w),
        abs_gnd: Acc::new(n_cols, w),
        int_gnd: Acc::new(n_cols, w),
        abs_fluid: HashMap::new(),
        lost: vec![0.0; w],
        roulette: vec![0.0; w],
        events: 0,
        crossings: 0,
        skipped: 0,
        wave: None,
    };
    let mut rng = crate::scene::spawn::stream(inp.params.seed, PHOTON_STREAM, batch);
    let has_sky = w > nb;
    let n_total = n * inp.params.batches.max(1) as u64;
    // Sun and sky photons alternate inside the batch.
    let (n_sun, n_sky) = if has_sky {
        (n.div_ceil(2), n / 2)
    } else {
        (n, 0)
    };
    let tot_sun = n_total as f64 * n_sun as f64 / n as f64;
    let tot_sky = n_total as f64 * n_sky as f64 / n as f64;
    let n_tur = ctx.tur_ids.len();
    let mut g_cur = vec![0.0; n_tur];
    let mut scratch = vec![0.0; nb];
    let mut tr = vec![0.0; nb];
    let mut ph = Photon {
        p: DVec3::ZERO,
        d: DVec3::ZERO,
        path: 0.0,
        shift: DVec3::ZERO,
        di: 0,
        w: Bands::from_elem(0.0, nb),
        w0: 0.0,
        off: 0,
        order: 0,
        skip_facet: None,
        direct: false,
        ret: None,
        surface_scored: false,
        first_u: None,
        first_order_done: false,
    };
    let n_dirs = ctx.omega.len();
    let discrete = inp.params.sampler.is_discrete();
    for i in 0..n_sun + n_sky {
        let sky = i >= n_sun;
        let x = spec.origin.x + rng.next_f64() * ctx.size.0;
        let y = spec.origin.y + rng.next_f64() * ctx.size.1;
        ph.p = DVec3::new(x, y, spec.top());
        ph.off = if sky { nb } else { 0 };
        for b in 0..nb {
            ph.w[b] = if sky {
                source[nb + b] / tot_sky
            } else {
                source[b] / tot_sun
            };
        }
        ph.w0 = ph.w.iter().cloned().fold(0.0, f64::max);
        if ph.w0 <= 0.0 {
            continue;
        }
        if sky {
            // Isotropic sky: cosine-weighted downward directions.
            ph.d = sample_cosine_hemisphere(DVec3::NEG_Z, &mut rng);
            if discrete {
                ph.di = inp.dirs.find_sector(ph.d);
                ph.d = ctx.omega[ph.di];
            }
        } else {
            ph.d = inp.sun;
            ph.di = n_dirs;
        }
        ph.order = 0;
        ph.skip_facet = None;
        trace_photon(
            ctx,
            &mut ph,
            &mut rng,
            &mut out,
            &mut g_cur,
            &mut scratch,
            &mut tr,
        );
    }
    // Per-batch absorption summaries (non-ground: turbid, non-ground facets, fluids; ground:
    // flat ground (booked per event) and DEM facets).
    let gf = inp.ground_facet;
    let mut absorbed = vec![0.0; w];
    let mut abs_dem = vec![0.0; w];
    let mut int_dem = vec![0.0; w];
    out.abs_tur
        .for_each(|_, v| absorbed.iter_mut().zip(v).for_each(|(a, x)| *a += x));
    out.abs_fac.for_each(|k, v| {
        let t = if gf.get(k as usize).copied().unwrap_or(false) {
            &mut abs_dem
        } else {
            &mut absorbed
        };
        t.iter_mut().zip(v).for_each(|(a, x)| *a += x)
    });
    out.int_fac.for_each(|k, v| {
        if gf.get(k as usize).copied().unwrap_or(false) {
            int_dem.iter_mut().zip(v).for_each(|(a, x)| *a += x)
        }
    });
    let mut keys: Vec<_> = out.abs_fluid.keys().copied().collect();
    keys.sort_unstable();
    for k in keys {
        absorbed
            .iter_mut()
            .zip(&out.abs_fluid[&k])
            .for_each(|(a, x)| *a += x);
    }
    for ch in 0..w {
        out.summary[ctx.sum.absorbed(ch)] += absorbed[ch];
        out.summary[ctx.sum.absorbed_ground(ch)] += abs_dem[ch];
        out.summary[ctx.sum.ground(ch)] += int_dem[ch];
    }
    out
}

#[allow(clippy::too_many_arguments)]
fn trace_photon(
    ctx: &Ctx,
    ph: &mut Photon,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    g_cur: &mut [f64],
    scratch: &mut [f64],
    tr: &mut [f64],
) {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let off = ph.off;
    let discrete = inp.params.sampler.is_discrete();
    let n_dirs = ctx.omega.len();
    loop {
        for (tm, g) in g_cur.iter_mut().enumerate() {
            *g = ctx.g_of(tm, ph.d.z);
        }
        // Forced peel-off: fluids (K > 0) toward the views, and in LiDAR receiver mode turbid
        // vegetation and fluids toward the receiver on the first flight.
        let forced_fluid = inp.fluid.is_some() && inp.params.fluid_peel_points > 0;
        // Receiver mode: first flight only (a smooth first-order waveform); later orders use
        // the collision estimator (one receiver trace per event instead of one per crossing).
        ph.ret = None;
        ph.surface_scored = false;
        // Receiver mode past the first scattering: expected-value return along the flight
        // (`Ctx::scatter_flight`); its turbid and Lambertian-ground collisions are not peeled.
        let ms_forced = ctx.ms_stop >= 1.0
            && ph.order >= 1
            && nb == 1
            && inp.fluid.is_none()
            && ctx.receiver.is_some();
        let hit = if ms_forced {
            ctx.scatter_flight(ph, g_cur, rng, out, scratch, tr)
        } else if ctx.stratified
            && ph.order == 0
            && ph.direct
            && nb == 1
            && inp.fluid.is_none()
            && ctx.receiver.is_some()
        {
            if ph.first_order_done {
                // The first-order return is the column quadrature's: the collision only (the
                // same free path and hit as `Ctx::first_flight`'s), and no peel-off of the
                // surface it may end on.
                let tau_star = -(1.0 - ph.first_u.unwrap_or_else(|| rng.next_f64())).ln();
                let hit = ctx.fly_to(ph, g_cur, tau_star, rng, out);
                ph.surface_scored = true;
                hit
            } else {
                // One walk: collision and stratified first-order return (`Ctx::first_flight`).
                let (hit, ret) = ctx.first_flight(ph, g_cur, rng, out, scratch, tr);
                ph.ret = ret.map(|t| Small::from_elem(return_transmittance(t), 1));
                hit
            }
        } else {
            let walk_end = if (ctx.receiver.is_some() && ph.order == 0)
                || (ctx.receiver.is_none() && forced_fluid && !inp.views.is_empty())
            {
                ctx.forced_peel(ph, g_cur, rng, out, scratch, tr)
            } else {
                None
            };
            let hit = ctx.fly(ph, g_cur, rng, out);
            // First flight ending on the surface its forced walk ended on: the collision
            // peel-off reuses the walk's return transmittance (see `Ctx::forced_peel`).
            ph.ret = match (&hit, walk_end) {
                (Hit::Facet { f, .. }, Some((Some(g), tau))) if *f == g => {
                    Some(Small::from_fn(tau.len(), |b| return_transmittance(tau[b])))
                }
                (Hit::Ground { .. }, Some((None, tau))) => {
                    Some(Small::from_fn(tau.len(), |b| return_transmittance(tau[b])))
                }
                _ => None,
            };
            hit
        };
        match hit {
            Hit::Escape => {
                let j = if discrete && ph.di < n_dirs {
                    ph.di
                } else {
                    inp.dirs.find_sector(ph.d)
                };
                for b in 0..nb {
                    out.summary[ctx.sum.escaped(off + b)] += ph.w[b];
                    out.summary[ctx.sum.dir(j, off + b)] += ph.w[b];
                }
                return;
            }
            Hit::Lost => {
                for b in 0..nb {
                    out.lost[off + b] += ph.w[b];
                }
                return;
            }
            Hit::Volume { c, p } if c & FLUID_BIT != 0 => {
                let c = c & !FLUID_BIT;
                let f = ctx.fluid_of(c).expect("fluid cell");
                out.events += 1;
                // Peel-off: intensity ω P(Θ)/(4π) per unit weight (unless the K-point forced
                // estimate along the flight already accounted for fluid collisions).
                let d_in = ph.d;
                let forced_here = match ctx.receiver {
                    Some(_) => ph.order == 0,
                    None => inp.params.fluid_peel_points > 0,
                };
                if !forced_here {
                    ctx.peel(ph, p, None, false, out, scratch, tr, |_, ov, s| {
                        let pv = f.phase.eval_dirs(d_in, ov) / (4.0 * PI);
                        for b in 0..nb {
                            s[b] = f.ssa[b] * pv;
                        }
                        true
                    });
                }
                let acc = out
                    .abs_fluid
                    .entry(c as u32)
                    .or_insert_with(|| vec![0.0; ctx.w]);
                for b in 0..nb {
                    let w_new = ph.w[b] * f.ssa[b];
                    acc[off + b] += ph.w[b] - w_new;
                    ph.w[b] = w_new;
                }
                let d_new = sample_fluid_phase(&f.phase, ph.d, rng);
                ph.d = d_new;
                if discrete {
                    ph.di = inp.dirs.find_sector(ph.d);
                    ph.d = ctx.omega[ph.di];
                }
                ph.p = p;
                ph.skip_facet = None;
            }
            Hit::Volume { c, p } => {
                out.events += 1;
                // Material in proportion to its extinction.
                let entries = inp.grid.turbid_of(c);
                let start = inp.grid.turbid_start[c] as usize;
                let kv = ctx.k_veg(c, g_cur);
                let mut u = rng.next_f64() * kv;
                let mut sel = entries.len() - 1;
                for (i, e) in entries.iter().enumerate() {
                    let tm = ctx.tur_mat[e.material as usize];
                    if tm == u32::MAX {
                        continue;
                    }
                    let k = g_cur[tm as usize] * e.density as f64;
                    if u < k {
                        sel = i;
                        break;
                    }
                    u -= k;
                }
                let entry = (start + sel) as u32;
                let mid = entries[sel].material as usize;
                let tm = ctx.tur_mat[mid] as usize;
                let PhotonOptics::Turbid {
                    sampler,
                    kernel,
                    rho,
                    tau,
                    discrete: drows,
                    ..
                } = &inp.optics[mid]
                else {
                    return;
                };
                {
                    let it = out.int_tur.get(entry);
                    for b in 0..nb {
                        it[off + b] += ph.w[b];
                    }
                }
                let d_in = ph.d;
                let g_in = g_cur[tm].max(1e-12);
                let w_before = ph.w.clone();
                match drows {
                    Some(rows) if discrete => {
                        let row = ph.di.min(rows.samplers.len() - 1);
                        // Peel-off with the containing sector's tabulated value: T_{i,m}/ΔΩ_m
                        // (LiDAR receiver mode, first flight: done by the forced estimate).
                        let forced = (ctx.receiver.is_some() && ph.order == 0) || ms_forced;
                        ctx.peel(ph, p, None, false, out, scratch, tr, |v, ov, s| {
                            if forced {
                                return false;
                            }
                            let m = match ctx.view_sector.get(v) {
                                Some(&m) => m,
                                None => inp.dirs.find_sector(ov),
                            };
                            let dom = inp.dirs.tiling()[m].solid_angle_sr;
                            for b in 0..nb {
                                s[b] = rows.tables[b].get(row, m) as f64 / dom;
                            }
                            true
                        });
                        let Some(smp) = &rows.samplers[row] else {
                            // Black leaves: everything absorbed.
                            let a = out.abs_tur.get(entry);
                            for b in 0..nb {
                                a[off + b] += ph.w[b];
                            }
                            return;
                        };
                        let j = smp.sample(rng);
                        let qj = smp.probability(j).max(1e-300);
                        for b in 0..nb {
                            ph.w[b] *= rows.tables[b].get(row, j) as f64 / qj;
                        }
                        ph.di = j;
                        ph.d = ctx.omega[j];
                    }
                    _ => {
                        let (mut sr, mut sw) = (0.0, 0.0);
                        for b in 0..nb {
                            sr += ph.w[b] * rho[b];
                            sw += ph.w[b] * (rho[b] + tau[b]);
                        }
                        if sw <= 0.0 {
                            let a = out.abs_tur.get(entry);
                            for b in 0..nb {
                                a[off + b] += ph.w[b];
                            }
                            return;
                        }
                        let p_r = sr / sw;
                        let ev = sampler.scatter(d_in, p_r, rng);
                        // Peel-off: the radiant intensity per unit intercepted weight toward
                        // Ω_v is Γ_b(Ω'→Ω_v)/(π G(Ω')) (physics.md §3.3). Spherical LAD: its
                        // closed form. Other LADs: the unbiased one-leaf estimate given the
                        // leaf normal n drawn for this event (density ∝ g_L|Ω'·n|/G, facing
                        // the photon): ρ_b|Ω_v·n|/π on the incidence side (Ω_v·n > 0), τ_b|Ω_v·n|/π
                        // beyond — E_n[·] = Γ_b/(π G) exactly, with no quadrature of Γ (whose
                        // binned evaluation costs ~10 µs and errs by up to 0.5 % at 180 bins).
                        let closed = kernel.is_closed_form();
                        let n = ev.normal;
                        // (LiDAR receiver mode: done by the forced estimate along the flight.)
                        let forced = (ctx.receiver.is_some() && ph.order == 0) || ms_forced;
                        ctx.peel(ph, p, None, false, out, scratch, tr, |_, ov, s| {
                            if forced {
                                return false;
                            }
                            turbid_peel_phase(
                                kernel,
                                closed,
                                n,
                                d_in,
                                ov,
                                g_in,
                                rho,
                                tau,
                                &mut s[..nb],
                            )
                        });
                        // w_b ← w_b ρ_b/p_r (reflection) or w_b τ_b/(1 − p_r) (transmission):
                        // E[w'_b] = w_b (ρ_b + τ_b) for every band.
                        for b in 0..nb {
                            ph.w[b] *= if ev.reflected {
                                rho[b] / p_r
                            } else {
                                tau[b] / (1.0 - p_r)
                            };
                        }
                        ph.d = ev.dir;
                    }
                }
                let a = out.abs_tur.get(entry);
                for b in 0..nb {
                    a[off + b] += w_before[b] - ph.w[b];
                }
                ph.p = p;
                ph.skip_facet = None;
            }
            Hit::Facet { f, p } => {
                out.events += 1;
                let fa = &inp.facets[f as usize];
                let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize();
                let front = n.dot(ph.d) < 0.0;
                let n_in = if front { n } else { -n }; // normal on the incidence side
                let mu = n.dot(ph.d).abs().max(1e-6);
                let w_before = ph.w.clone();
                let is_ground_facet = inp.ground_facet.get(f as usize).copied().unwrap_or(false);
                let mut passed_through = false;
                match &inp.optics[fa.material as usize] {
                    PhotonOptics::Lambert { r, t, t_dir } => {
                        let mut pd = Bands::from_elem(0.0, nb);
                        let mut pr = Bands::from_elem(0.0, nb);
                        let mut pt = Bands::from_elem(0.0, nb);
                        let nbx = nb;
                        for b in 0..nbx {
                            let through = if t_dir[b] > 0.0 {
                                t_dir[b].powf(1.0 / mu)
                            } else {
                                0.0
                            };
                            pd[b] = through;
                            pr[b] = (1.0 - through) * r[b];
                            pt[b] = (1.0 - through) * t[b];
                        }
                        {
                            let it = out.int_fac.get(f);
                            for b in 0..nbx {
                                it[off + b] += ph.w[b] * (1.0 - pd[b]);
                            }
                        }
                        // Peel-off: reflected ρ|n·v|/π on the incidence side, τ|n·v|/π beyond
                        // (unless the flight's walk scored it: `Photon::surface_scored`).
                        let scored = ph.surface_scored;
                        ctx.peel(
                            ph,
                            p,
                            Some(f),
                            is_ground_facet,
                            out,
                            scratch,
                            tr,
                            |_, ov, s| {
                                if scored {
                                    return false;
                                }
                                let c = n_in.dot(ov);
                                let mut any = false;
                                for b in 0..nbx {
                                    s[b] = if c > 0.0 { pr[b] } else { pt[b] } * c.abs() / PI;
                                    any |= s[b] > 0.0;
                                }
                                any
                            },
                        );
                        let k =
                            choose(&mut ph.w[..nbx], &[&pd[..nbx], &pr[..nbx], &pt[..nbx]], rng);
                        match k {
                            None => {}
                            Some(0) => passed_through = true,
                            Some(1) => {
                                ph.d = sample_cosine_hemisphere(n_in, rng);
                            }
                            _ => {
                                ph.d = sample_cosine_hemisphere(-n_in, rng);
                            }
                        }
                        if discrete && k.is_some_and(|k| k > 0) {
                            ph.di = inp.dirs.find_sector(ph.d);
                            ph.d = ctx.omega[ph.di];
                        }
                    }
                    PhotonOptics::Brdf { models, sampler } => {
                        {
                            let it = out.int_fac.get(f);
                            for b in 0..nb {
                                it[off + b] += ph.w[b];
                            }
                        }
                        brdf_event(
                            ctx,
                            ph,
                            p,
                            Some(f),
                            n_in,
                            models,
                            sampler,
                            rng,
                            out,
                            scratch,
                            tr,
                        );
                    }
                    _ => {
                        for b in 0..nb {
                            ph.w[b] = 0.0;
                        }
                    }
                }
                let a = out.abs_fac.get(f);
                for b in 0..nb {
                    a[off + b] += w_before[b] - ph.w[b];
                }
                ph.p = p;
                ph.skip_facet = Some(f);
                if passed_through {
                    // Direct transmission is not a scattering event: same order, same flight
                    // direction (continue without the roulette/order bookkeeping); the return
                    // path now crosses this facet too.
                    ph.direct = false;
                    continue;
                }
            }
            Hit::Ground { p } => {
                out.events += 1;
                let col = ctx.column(p);
                {
                    let it = out.int_gnd.get(col);
                    for b in 0..nb {
                        it[off + b] += ph.w[b];
                        out.summary[ctx.sum.ground(off + b)] += ph.w[b];
                    }
                }
                let w_before = ph.w.clone();
                let gid = inp.flat_ground.expect("flat ground") as usize;
                match &inp.optics[gid] {
                    PhotonOptics::Lambert { r, .. } => {
                        // (Scored by the walk of an expected-value flight.)
                        let scored = ph.surface_scored;
                        ctx.peel(ph, p, None, true, out, scratch, tr, |_, ov, s| {
                            if scored {
                                return false;
                            }
                            let c = ov.z;
                            for b in 0..nb {
                                s[b] = r[b] * c / PI;
                            }
                            true
                        });
                        for b in 0..nb {
                            ph.w[b] *= r[b];
                        }
                        ctx.ground_direction(ph, rng);
                    }
                    PhotonOptics::Brdf { models, sampler } => {
                        brdf_event(
                            ctx,
                            ph,
                            p,
                            None,
                            DVec3::Z,
                            models,
                            sampler,
                            rng,
                            out,
                            scratch,
                            tr,
                        );
                    }
                    _ => ph.w.iter_mut().for_each(|x| *x = 0.0),
                }
                let a = out.abs_gnd.get(col);
                for b in 0..nb {
                    a[off + b] += w_before[b] - ph.w[b];
                    out.summary[ctx.sum.absorbed_ground(off + b)] += w_before[b] - ph.w[b];
                }
                ph.p = p;
                ph.skip_facet = None;
            }
        }
        ph.order += 1;
        if ctx.beyond_gate(ph) {
            for b in 0..nb {
                out.lost[off + b] += ph.w[b];
            }
            return;
        }
        let wmax = ph.w.iter().cloned().fold(0.0, f64::max);
        if wmax <= 0.0 || !wmax.is_finite() {
            return;
        }
        // Receiver mode: Russian roulette into multiple scattering after the first interaction
        // (its first-order return is already recorded), survival `continue_prob`.
        if ph.order == 1
            && ctx.continue_prob < 1.0
            && !roulette_survives(ph, ctx.continue_prob, rng, &mut out.roulette[off..off + nb])
        {
            return;
        }
        if ph.order > inp.params.max_order {
            for b in 0..nb {
                out.lost[off + b] += ph.w[b];
            }
            return;
        }
        // Receiver mode, expected-value estimator: a photon that scattered far outside the
        // receiver's field of view goes on with the survival probability of its distance.
        if ctx.far_roulette.0 > 0.0
            && let Some(rx) = &ctx.receiver
        {
            let q = far_roulette_survival(rx, ph.p + ph.shift, ctx.far_roulette);
            if q < 1.0 && !roulette_survives(ph, q, rng, &mut out.roulette[off..off + nb]) {
                return;
            }
        }
        let r = wmax / ph.w0;
        let thr = inp.params.roulette_threshold;
        if r < thr {
            if rng.next_f64() * thr < r {
                let s = thr / r;
                for b in 0..nb {
                    out.roulette[off + b] -= ph.w[b] * (s - 1.0);
                    ph.w[b] *= s;
                }
            } else {
                for b in 0..nb {
                    out.roulette[off + b] += ph.w[b];
                }
                return;
            }
        }
    }
}

/// Russian roulette with survival probability `q` (0 < q < 1): the photon goes on with its
/// weights divided by `q` (returns true) or stops (false); `balance` (one entry per band, W)
/// books killed minus added weight, whose expectation is 0.
#[inline]
fn roulette_survives(
    ph: &mut Photon,
    q: f64,
    rng: &mut Xoshiro256PlusPlus,
    balance: &mut [f64],
) -> bool {
    if rng.next_f64() < q {
        for (r, w) in balance.iter_mut().zip(ph.w.iter_mut()) {
            *r -= *w * (1.0 / q - 1.0);
            *w /= q;
        }
        true
    } else {
        for (r, w) in balance.iter_mut().zip(ph.w.iter()) {
            *r += *w;
        }
        false
    }
}

/// Scattering by an opaque BRDF surface (RPV, Hapke) with normal `n_in` on the incidence
/// side: peel-off `w_b BRF_b(Ω_i, Ω_v) |n·Ω_v|/π`, then importance sampling with weights
/// `BRF_b μ_o/(π pdf)` (E = directional-hemispherical albedo; physics.md §5.2–5.3).
#[allow(clippy::too_many_arguments)]
fn brdf_event(
    ctx: &Ctx,
    ph: &mut Photon,
    p: DVec3,
    skip: Option<u32>,
    n_in: DVec3,
    models: &[Brdf],
    sampler: &BrdfSampler,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    scratch: &mut [f64],
    tr: &mut [f64],
) {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let d_in = ph.d;
    ctx.peel(
        ph,
        p,
        skip,
        skip.is_none_or(|f| inp.ground_facet.get(f as usize).copied().unwrap_or(false)),
        out,
        scratch,
        tr,
        |_, ov, s| {
            let c = n_in.dot(ov);
            if c <= 0.0 {
                return false;
            }
            for b in 0..nb {
                s[b] = models[b].brf(n_in, d_in, ov) * c / PI;
            }
            true
        },
    );
    let Some(smp) = sampler.sample(n_in, d_in, rng) else {
        ph.w.iter_mut().for_each(|x| *x = 0.0);
        return;
    };
    let (dir, pdf) = (smp.dir, smp.pdf);
    let c = n_in.dot(dir);
    if pdf <= 0.0 || c <= 0.0 {
        ph.w.iter_mut().for_each(|x| *x = 0.0);
        return;
    }
    for b in 0..nb {
        ph.w[b] *= models[b].brf(n_in, d_in, dir) * c / (PI * pdf);
    }
    ph.d = dir;
    if inp.params.sampler.is_discrete() {
        ph.di = inp.dirs.find_sector(ph.d);
        ph.d = ctx.omega[ph.di];
    }
}

// ---------------------------------------------------------------------------------------------
// LiDAR (DART 5 paper §4, physics.md §9): pulses of photons from an emitter, peel-off toward
// the monostatic receiver, path-length binning.
// ---------------------------------------------------------------------------------------------

/// Stop factor `c` of [`LidarEstimator::ExpectedValue`] ([`Ctx::scatter_flight`]): the walk of
/// a multiple-scattering flight goes on to `c` times its collision's optical depth; c = 1: the
/// track-length estimator (the return integrated along the flight up to its collision). On the
/// forest ALS error study of session 10 (600 photons, 8 realizations) c = 1, 1.5, 2, 3, 4 and ∞
/// gave 0.82, 0.79, 0.73, 0.74, 0.76 and 0.75 % total error, and c = 2 was chosen. Re-measured
/// with session 15's default (72 rays, far-photon roulette; 768 realizations, standard error
/// 0.002 %): c = 1 0.996 % at 711.1k instructions per pulse, c = 2 1.003 % at 752.0k (384: c =
/// 1.25 1.001 % at 729.2k, 1.5 0.999 % at 738.3k): c = 1 has the lowest error and cost (README of
/// 4df2100, LiDAR speed against error).
const MS_STOP_FACTOR: f64 = 1.0;

/// Smallest distance scale ρ₀ of the far-photon roulette (`far_roulette_survival`), in
/// horizontal cell sizes (the larger of x and y); the scene's mean free path in the vegetation
/// raises it (`crate::lidar::simulate::far_roulette_scale_m`).
pub const FAR_ROULETTE_CELLS: f64 = 2.0;

/// Smallest survival probability of the far-photon roulette ([`far_roulette_survival`]): a
/// survivor's weight grows at most 64-fold, so a rare survivor that reaches the field of view
/// again adds no spike larger than that to a waveform.
const FAR_ROULETTE_MIN_SURVIVAL: f64 = 1.0 / 64.0;

/// Survival probability of a LiDAR photon about to fly on from the unwrapped point `m` (m)
/// after a scattering event (receiver mode, [`LidarEstimator::ExpectedValue`]): with `e` the
/// distance of `m` outside the receiver's field-of-view cone (lateral distance from the axis
/// minus the cone's radius `tan θ_FOV · s` at the point's range `s` along the axis; m),
/// `q = min(1, (ρ₀/e)²)`, at least [`FAR_ROULETTE_MIN_SURVIVAL`]. Russian roulette (survivors
/// carry `w/q`, so every expectation is unchanged; Lux & Koblinger 1991, ch. 6, weight
/// windows): a photon there can only reach the waveform again by further scattering back into
/// the cone, which its distance makes unlikely. On the forest ALS bench (1 m cells, 0.3 m
/// footprint, 0.9 m FOV radius) the multiple-scattering flights that start more than 2 m
/// outside the cone are 37 % of them but carry 1.6 % of the multiple-scattering return (their
/// later orders included). The scale: `max(2 cells, mean free path)` (4.6 m there): total
/// waveform error of the error study 0.997 → 1.002 % (384 realizations, standard error
/// 0.003 %, with the stop factor c = 2 of the time) for 7.9 % fewer instructions per pulse; ρ₀ = 2 m saves 13 % (1.001 %), 1 m 16 % but
/// with rare large errors (1.024 ± 0.010 %); on a denser layer (mean free path 1 m) ρ₀ = 0.5 m
/// raises the noise of the multiple-scattering energy 1.6-fold (README of 4df2100,
/// LiDAR speed against error). `(ρ₀, tan θ_FOV)` as stored in [`Ctx::far_roulette`].
#[inline]
fn far_roulette_survival(rx: &Receiver, m: DVec3, (rho0, tan_fov): (f64, f64)) -> f64 {
    let v = m - rx.position;
    let s = v.dot(rx.axis);
    let lateral = (v - s * rx.axis).length();
    let e = lateral - tan_fov * s.max(0.0);
    if e > rho0 {
        let r = rho0 / e;
        (r * r).max(FAR_ROULETTE_MIN_SURVIVAL)
    } else {
        1.0
    }
}

/// Photon stream purpose tag of LiDAR pulses.
pub const LIDAR_STREAM: u64 = 0x4c_49_44_41_52; // "LIDAR"

/// One LiDAR pulse (its receiver is at the emitter: monostatic).
#[derive(Debug, Clone, PartialEq)]
pub struct Pulse {
    /// Pulse ID (also selects its random stream).
    pub id: u64,
    /// Emitter and receiver position (unwrapped scene coordinates), m.
    pub emitter: DVec3,
    /// Beam axis (unit propagation direction).
    pub axis: DVec3,
}

/// Beam and receiver shared by the pulses of one instrument.
#[derive(Debug, Clone)]
pub struct Beam {
    /// Transverse profile sampler at `reference_range_m` (offsets in metres).
    pub footprint: crate::lidar::pulse::FootprintSampler,
    /// Range at which the footprint offsets are drawn, m.
    pub reference_range_m: f64,
    /// Cosine of the receiver FOV half-angle.
    pub cos_fov: f64,
    /// Receiver aperture, m².
    pub aperture_m2: f64,
    /// Pulse energy, J.
    pub energy_j: f64,
    /// Photons (beam rays) of a pulse whose first-order return the column quadrature scores
    /// (`FirstOrderColumns`; the quadrature is planned for this count).
    pub photons: u32,
    /// Photons (beam rays) of a pulse that scores its first-order return per beam ray (the
    /// quadrature does not apply, is off, or falls back).
    pub photons_per_ray: u32,
    /// Path-length gate `[min, max]`, m (two-way).
    pub gate_m: (f64, f64),
    /// Digitiser bin, ns.
    pub bin_ns: f64,
    /// Estimator of the tracking.
    pub estimator: LidarEstimator,
    /// `Stratified`, `ExpectedValue`: expected number of beam rays per pulse continued past their first
    /// interaction into multiple scattering (≥ the pulse's beam rays: all).
    pub scattering_photons: u32,
    /// `ExpectedValue`: distance scale ρ₀ (m) of the far-photon roulette of multiple scattering
    /// (`far_roulette_survival`); 0: off.
    pub far_roulette_m: f64,
    /// `ExpectedValue`: the first-order return by the column quadrature where it applies
    /// (`FirstOrderColumns`); false: every beam ray scores its own (for the equality tests
    /// and for measuring).
    pub first_order_columns: bool,
}

/// Most grid columns a pulse's footprint window may span for the column quadrature of its
/// first-order return ([`FirstOrderColumns`]; also at most the beam rays).
const MAX_FIRST_ORDER_COLUMNS: usize = 64;

/// Column quadrature of the first-order return of near-nadir pulses
/// ([`LidarEstimator::ExpectedValue`]). The first-order return of a beam ray that stays inside
/// one grid column from the top of the grid to its bottom, and whose column holds no facet,
/// depends only on that column: turbid cells are horizontally homogeneous and the ground is
/// flat, so every such ray crosses the same cells over the same lengths, to within the relative
/// path difference ρ²/(2R²) of its transverse offset ρ at the reference range R (m) — which
/// shifts its arrival times by up to `(E_z − z)(ρ²_max − ρ²_min)/(2R²)` over the column, kept
/// below [`COLUMN_TIMING_TOLERANCE`] of a digitiser bin (else the column is sampled, below). For a vertical beam axis the set of offsets whose ray stays in column c is a rectangle
/// (the column's sides scaled to the top and the bottom planes: the ray reaches height z at the
/// emitter's x, y plus the offset times (z_e − z)/R), so the pulse's first-order return is
/// `Σ_c m₀(c) F_c` with `m₀(c)` the beam energy fraction over that rectangle (exact, from the
/// footprint profile, [`crate::lidar::pulse::FootprintMoments`]) and `F_c` the first-order
/// return of one ray of the column (the walk and scoring of [`Ctx::first_flight`], weight
/// `E m₀(c)`), taken at an offset whose ρ² is the column's mean ρ² under the profile, so the
/// path-length and angle terms, linear in ρ² to O(ρ⁴/R⁴), are those of the column's mean.
/// The rest of the footprint is stratified the same way: each strip of offsets whose rays
/// cross a column side between the two planes (the rectangles between the columns' ones) gets
/// one ray drawn from the footprint over it, weight `E m₀` (strips lighter than
/// [`STRIP_ROULETTE_MASS`] by Russian roulette), and each column with facets (or whose arrival
/// times spread too much) `⌈m₀ N⌉` rays drawn over it (N beam rays), weight `E m₀/⌈m₀ N⌉`:
/// unbiased, with a variance of `m₀²` times the spread of the return inside the rectangle
/// (zero where it is uniform, e.g. bare ground or a flat roof). Columns outside an isolated
/// grid get none (their rays miss the scene, as the beam rays there do). The beam rays then only sample
/// their collision for multiple scattering (their first order is not scored again,
/// [`Photon::first_order_done`]). DART 5 paper §4 computes the first order by forced peel-off
/// along each ray; this is that integral over the footprint done by quadrature and stratified
/// sampling instead of by the beam rays.
///
/// Used when the estimator is `ExpectedValue`, one band, no fluid, the flat ground (if any)
/// is Lambertian, no continuous-topography offset, the column sums exist ([`ColumnDepth`]),
/// every beam ray lies inside the receiver's FOV (relative slack 1e-12 on the cosine), and,
/// per pulse, the axis is exactly vertical (downward), the emitter above the grid and the
/// footprint's window at the bottom plane spans at most [`MAX_FIRST_ORDER_COLUMNS`] columns
/// and the beam rays, and no column with facets or fluids holds [`HEAVY_COLUMN_RAYS`] beam
/// rays on average.
pub(crate) struct FirstOrderColumns {
    /// The footprint's moments over rectangles.
    moments: std::sync::Arc<crate::lidar::pulse::FootprintMoments>,
    /// Radius beyond which the footprint has no energy, m (at the reference range).
    reach: f64,
    /// Most window columns per pulse.
    max_columns: usize,
}

/// One pulse's window of grid columns for [`FirstOrderColumns`].
struct PulseColumns {
    /// Window columns along x and y.
    ni: usize,
    nj: usize,
    /// Per axis, the `2n` ends of the window's `2n − 1` intervals of transverse offsets (m, at
    /// the reference range), increasing: interval `2i` holds the offsets whose rays stay in
    /// column `i` from the top plane to the bottom one, interval `2i + 1` those whose rays
    /// cross the side between columns `i` and `i + 1` in between (a strip).
    bx: [f64; 2 * MAX_FIRST_ORDER_COLUMNS],
    by: [f64; 2 * MAX_FIRST_ORDER_COLUMNS],
    /// Bit `j·ni + i`: window column (i, j) is in the grid and holds no facet and no fluid.
    clear: u64,
    /// Bit `j·ni + i`: window column (i, j) is in the grid (always, but for isolated grids).
    inside: u64,
    /// One-way path spread per unit ρ² at the bottom plane, `s_bot/(2R)` (m⁻¹): the rays of
    /// offsets ρ₁ and ρ₂ reach it with paths differing by `(ρ₂² − ρ₁²)·spread` (to O(ρ⁴/R⁴)).
    spread: f64,
}

/// Largest spread of one-way path lengths over a clear column's offsets, as a fraction of a
/// digitiser bin (one way), for its one column ray ([`FirstOrderColumns`]): the column ray books
/// the column's return at the paths of its mean ρ², while the column's rays arrive spread over
/// `spread·(ρ²_max − ρ²_min)`, so beyond this a clear column gets rays drawn over it instead
/// (whose arrival times are exact). Forest bench (0.9 m truncation at 1000 m, 1 ns bins): at
/// most 0.27 % of a bin, every clear column keeps its column ray; a 30 m UAV over the same
/// footprint: up to 9 %.
const COLUMN_TIMING_TOLERANCE: f64 = 0.01;

impl PulseColumns {
    /// Whether the beam ray of transverse offset `(px, py)` (m, at the reference range) scores
    /// its own first-order return: it lies outside the window's partition (rounding at the
    /// footprint's edge; no rectangle holds it). Others are the quadrature's.
    #[inline]
    fn scores_own(&self, px: f64, py: f64) -> bool {
        let inside = |b: &[f64], v: f64| v >= b[0] && v < b[b.len() - 1];
        !(inside(&self.bx[..2 * self.ni], px) && inside(&self.by[..2 * self.nj], py))
    }
}

impl FirstOrderColumns {
    fn new(ctx: &Ctx, beam: &Beam) -> Option<Self> {
        let inp = ctx.inp;
        if !beam.first_order_columns
            || beam.estimator != LidarEstimator::ExpectedValue
            || beam.photons == 0
            || ctx.nb != 1
            || inp.fluid.is_some()
            || ctx.columns.is_none()
            || (inp.flat_ground.is_some() && ctx.lambert_ground().is_none())
            || inp.spec.topography_offset != (0.0, 0.0)
        {
            return None;
        }
        let moments = beam.footprint.moments_shared();
        let reach = moments.reach_m();
        let r = beam.reference_range_m;
        if !(reach.is_finite() && reach > 0.0 && r > 0.0 && r.is_finite()) {
            return None;
        }
        // Every beam ray inside the receiver's FOV (the default FOV is the truncated footprint).
        if r / (r * r + reach * reach).sqrt() < beam.cos_fov * (1.0 - 1e-12) {
            return None;
        }
        Some(Self {
            moments,
            reach,
            max_columns: MAX_FIRST_ORDER_COLUMNS.min(beam.photons as usize),
        })
    }

    /// The window of columns of pulse `pl`, when the quadrature applies to it.
    fn pulse(&self, ctx: &Ctx, beam: &Beam, pl: &Pulse) -> Option<PulseColumns> {
        let spec = ctx.inp.spec;
        let (top, bottom) = (spec.top(), spec.origin.z);
        if pl.axis.x != 0.0 || pl.axis.y != 0.0 || !(pl.axis.z < 0.0) || !(pl.emitter.z > top) {
            return None;
        }
        let r = beam.reference_range_m;
        let (s_top, s_bot) = ((pl.emitter.z - top) / r, (pl.emitter.z - bottom) / r);
        let cell = (spec.cell.x, spec.cell.y);
        let rb = self.reach * s_bot;
        let i0 = ((pl.emitter.x - rb - spec.origin.x) / cell.0).floor();
        let i1 = ((pl.emitter.x + rb - spec.origin.x) / cell.0).floor();
        let j0 = ((pl.emitter.y - rb - spec.origin.y) / cell.1).floor();
        let j1 = ((pl.emitter.y + rb - spec.origin.y) / cell.1).floor();
        if !(i0.is_finite() && i1.is_finite() && j0.is_finite() && j1.is_finite())
            || i1 - i0 >= 64.0
            || j1 - j0 >= 64.0
            || i0.abs() > 1e15
            || j0.abs() > 1e15
        {
            return None;
        }
        let (ni, nj) = ((i1 - i0) as usize + 1, (j1 - j0) as usize + 1);
        if ni * nj > self.max_columns {
            return None;
        }
        let depth = ctx.columns.as_deref()?;
        let (nx, ny) = (spec.n[0] as i64, spec.n[1] as i64);
        let isolated = spec.boundary == BoundaryMode::Isolated;
        let (mut clear, mut inside) = (0u64, 0u64);
        for kj in 0..nj {
            for ki in 0..ni {
                let (i, j) = (i0 as i64 + ki as i64, j0 as i64 + kj as i64);
                let (iw, jw) = if isolated {
                    if !(0..nx).contains(&i) || !(0..ny).contains(&j) {
                        continue;
                    }
                    (i, j)
                } else {
                    (i.rem_euclid(nx), j.rem_euclid(ny))
                };
                inside |= 1 << (kj * ni + ki);
                if depth.clear[spec.index(iw as usize, jw as usize, 0)] {
                    clear |= 1 << (kj * ni + ki);
                }
            }
        }
        // The interval ends: column k's sides x0 < x1 (relative to the emitter) are crossed by
        // the ray of offset p at the top plane at p = x/s_top and at the bottom one at
        // p = x/s_bot; the ray stays in the column for p in [max(x0/s_top, x0/s_bot),
        // min(x1/s_top, x1/s_bot)].
        let ends = |lo: f64, c: f64, n: usize, out: &mut [f64; 2 * MAX_FIRST_ORDER_COLUMNS]| {
            for k in 0..n {
                let x0 = lo + k as f64 * c;
                let x1 = x0 + c;
                out[2 * k] = (x0 / s_top).max(x0 / s_bot);
                out[2 * k + 1] = (x1 / s_top).min(x1 / s_bot);
            }
            // Increasing (a column narrower than the drift of its rays would break it).
            out[..2 * n].windows(2).all(|w| w[0] <= w[1])
        };
        let mut bx = [0.0; 2 * MAX_FIRST_ORDER_COLUMNS];
        let mut by = [0.0; 2 * MAX_FIRST_ORDER_COLUMNS];
        let lo = (
            spec.origin.x + i0 * cell.0 - pl.emitter.x,
            spec.origin.y + j0 * cell.1 - pl.emitter.y,
        );
        if !(ends(lo.0, cell.0, ni, &mut bx) && ends(lo.1, cell.1, nj, &mut by)) {
            return None;
        }
        Some(PulseColumns {
            ni,
            nj,
            bx,
            by,
            clear,
            inside,
            spread: s_bot / (2.0 * r),
        })
    }
}

/// Footprint mass below which a strip rectangle of [`FirstOrderColumns`] is sampled by Russian
/// roulette (probability m/`STRIP_ROULETTE_MASS`, weight `STRIP_ROULETTE_MASS`) instead of
/// always: its variance is at most `STRIP_ROULETTE_MASS` × m × E[F²] per rectangle.
const STRIP_ROULETTE_MASS: f64 = 1e-4;

/// Beam rays (on average) from which a column with facets or fluids under a pulse's footprint
/// makes the pulse keep its beam rays' own first-order returns instead of
/// [`FirstOrderColumns`] (whose rays drawn over such a column are extra walks: a roof under
/// most of the footprint costs about as many walks again, and the beam rays' own returns are
/// already exact on a flat roof). Letting such columns keep their own beam rays inside the
/// quadrature instead is no option: the number of beam rays there fluctuates by about one
/// while the rest of the footprint is integrated exactly, which on the urban scan's flat roofs
/// raised the first-order energy's standard error a thousandfold. Forest bench at 48 beam
/// rays (384 realizations): every such column drawn 0.9905 ± 0.0033 % waveform error at
/// 409.7k instructions/pulse, none drawn (beam rays' own inside the quadrature) 1.0175 ±
/// 0.0035 % at 408.1k; no forest column holds half the beam rays.
const HEAVY_COLUMN_RAYS: f64 = 24.0;

/// A transverse offset drawn from the footprint's density restricted to the rectangle
/// `[x0, x1, y0, y1]` ∩ the footprint's disk of radius `reach` (m), by rejection from the
/// uniform density over the rectangle's part of the disk's bounding square, with the bound
/// [`crate::lidar::pulse::FootprintSampler::max_relative_intensity_within`] over the
/// rectangle's distances from the axis (von Neumann 1951). `None` after 4096 rejections (a
/// rectangle whose mass is a sliver of the disk's edge; its caller then skips it).
fn sample_in_rect(
    fp: &crate::lidar::pulse::FootprintSampler,
    reach: f64,
    [x0, x1, y0, y1]: [f64; 4],
    rng: &mut Xoshiro256PlusPlus,
) -> Option<(f64, f64)> {
    let (x0, x1, y0, y1) = (x0.max(-reach), x1.min(reach), y0.max(-reach), y1.min(reach));
    if !(x0 < x1 && y0 < y1) {
        return None;
    }
    let near = (0.0f64.clamp(x0, x1), 0.0f64.clamp(y0, y1));
    let far = (x0.abs().max(x1.abs()), y0.abs().max(y1.abs()));
    let r0 = (near.0 * near.0 + near.1 * near.1).sqrt();
    let r1 = (far.0 * far.0 + far.1 * far.1).sqrt().min(reach);
    let bound = fp.max_relative_intensity_within(r0, r1);
    if !(bound > 0.0) {
        return None;
    }
    for _ in 0..4096 {
        let x = x0 + (x1 - x0) * rng.next_f64();
        let y = y0 + (y1 - y0) * rng.next_f64();
        let r2 = x * x + y * y;
        if r2 <= reach * reach && rng.next_f64() * bound < fp.relative_intensity(r2.sqrt()) {
            return Some((x, y));
        }
    }
    None
}

/// A point of the rectangle `[x0, x1, y0, y1]` (non-empty) at squared distance `r2` (m²) from
/// the origin when one exists (for `r2` between the rectangle's least and largest squared
/// distances, as the mean ρ² over it is), else its nearest: on the segment from the
/// rectangle's nearest point to its farthest corner, along which the squared distance grows.
fn point_at_squared_distance([x0, x1, y0, y1]: [f64; 4], r2: f64) -> (f64, f64) {
    let c = (0.0f64.clamp(x0, x1), 0.0f64.clamp(y0, y1));
    let f = (
        if x0.abs() > x1.abs() { x0 } else { x1 },
        if y0.abs() > y1.abs() { y0 } else { y1 },
    );
    let dl = (f.0 - c.0, f.1 - c.1);
    let a = dl.0 * dl.0 + dl.1 * dl.1;
    let b = c.0 * dl.0 + c.1 * dl.1;
    let cc = c.0 * c.0 + c.1 * c.1 - r2;
    if !(a > 0.0) || !(cc < 0.0) {
        return c;
    }
    let t = ((-b + (b * b - a * cc).max(0.0).sqrt()) / a).clamp(0.0, 1.0);
    (c.0 + t * dl.0, c.1 + t * dl.1)
}

/// Result of one pulse.
#[derive(Debug, Clone)]
pub struct PulseResult {
    /// Pulse ID.
    pub id: u64,
    /// Received energy per bin (total and first order), before pulse-shape convolution, J;
    /// trimmed to the bins between the first and the last non-zero one
    /// ([`crate::lidar::waveform::Waveform::trim`]: `t0_ns` is that of the first kept bin).
    pub waveform: crate::lidar::waveform::Waveform,
    /// Received energy outside the gate, J: exact before the gate; after the gate a lower bound
    /// (photons that can no longer be recorded inside the gate are stopped, see
    /// `Ctx::beyond_gate`, and what they would have sent after the gate is not counted).
    pub out_of_gate_j: f64,
    /// Emitted energy that missed the scene (isolated scenes), J.
    pub missed_j: f64,
}

/// Runs LiDAR pulses. `inp` must hold single-band optics (the laser's band) and no views; the
/// pulses run in parallel, each with its own stream (seed, pulse ID) and sequential photons, so
/// waveforms are bit-identical on any number of threads.
pub fn run_lidar(
    inp: &PhotonInput,
    beam: &Beam,
    pulses: &[Pulse],
) -> Result<Vec<PulseResult>, String> {
    let mut all = Vec::with_capacity(pulses.len());
    run_lidar_chunks(
        inp,
        beam,
        pulses.iter().cloned(),
        pulses.len().max(1),
        |_, r| {
            all.extend(r);
            Ok(())
        },
    )?;
    Ok(all)
}

/// [`run_lidar`] by chunks of `chunk` pulses (in order): `each` receives every chunk's pulses
/// and results before the next chunk runs, so a long scan's pulses and waveforms need not all
/// be in memory at once (`pulses` may generate them on demand). The tracking context (column
/// depths) is built once. Results are those of [`run_lidar`] bit for bit: each pulse has its
/// own random stream (seed, pulse ID).
pub fn run_lidar_chunks(
    inp: &PhotonInput,
    beam: &Beam,
    pulses: impl IntoIterator<Item = Pulse>,
    chunk: usize,
    mut each: impl FnMut(&[Pulse], Vec<PulseResult>) -> Result<(), String>,
) -> Result<(), String> {
    let mut base = Ctx::new(inp, 1, 1);
    base.columns = ColumnDepth::new(&base).map(std::sync::Arc::new);
    let first_order = FirstOrderColumns::new(&base, beam).map(std::sync::Arc::new);
    // Validate the binner once.
    crate::lidar::waveform::WaveformBinner::new(beam.gate_m.0, beam.gate_m.1, beam.bin_ns)
        .map_err(|e| e.to_string())?;
    let mut pulses = pulses.into_iter();
    loop {
        let part: Vec<Pulse> = pulses.by_ref().take(chunk.max(1)).collect();
        if part.is_empty() {
            return Ok(());
        }
        let results = part
            .par_iter()
            .map_init(
                || PulseState::new(&base, beam, first_order.clone()),
                |st, pl| run_pulse(st, beam, pl),
            )
            .collect();
        each(&part, results)?;
    }
}

/// What the pulses of one worker reuse (built once per rayon task, not per pulse): the
/// receiver-mode context (only the receiver's position and axis change from pulse to pulse),
/// the tallies with their waveform binner, and the tracking scratch. Every pulse starts from
/// the state of a new one ([`PulseState::reset`]), so the products do not depend on which
/// pulses a thread ran before (the same bits on any number of threads).
struct PulseState<'a> {
    ctx: Ctx<'a>,
    out: BatchOut,
    g_cur: Vec<f64>,
    scratch: Vec<f64>,
    tr: Vec<f64>,
    /// The run's column quadrature of the first order, when it applies.
    first_order: Option<std::sync::Arc<FirstOrderColumns>>,
}

impl<'a> PulseState<'a> {
    fn new(
        base: &Ctx<'a>,
        beam: &Beam,
        first_order: Option<std::sync::Arc<FirstOrderColumns>>,
    ) -> Self {
        let ctx = Ctx {
            receiver: Some(Receiver {
                position: DVec3::ZERO,
                axis: DVec3::NEG_Z,
                cos_fov: beam.cos_fov,
                aperture_m2: beam.aperture_m2,
            }),
            max_path: beam.gate_m.1,
            stratified: beam.estimator != LidarEstimator::Legacy,
            ms_stop: match beam.estimator {
                LidarEstimator::ExpectedValue => MS_STOP_FACTOR,
                _ => 0.0,
            },
            far_roulette: match beam.estimator {
                LidarEstimator::ExpectedValue
                    if beam.far_roulette_m > 0.0 && beam.cos_fov > 0.0 =>
                {
                    (
                        beam.far_roulette_m,
                        (1.0 - beam.cos_fov * beam.cos_fov).max(0.0).sqrt() / beam.cos_fov,
                    )
                }
                _ => (0.0, 0.0),
            },
            // Set per pulse (its beam rays), see `run_pulse`.
            continue_prob: continue_prob(beam, beam.photons),
            ..base.clone()
        };
        let binner =
            crate::lidar::waveform::WaveformBinner::new(beam.gate_m.0, beam.gate_m.1, beam.bin_ns)
                .expect("validated gate");
        let out = BatchOut {
            summary: vec![0.0; ctx.sum.len()],
            abs_tur: Acc::sink(1),
            int_tur: Acc::sink(1),
            abs_fac: Acc::sink(1),
            int_fac: Acc::sink(1),
            abs_gnd: Acc::sink(1),
            int_gnd: Acc::sink(1),
            abs_fluid: HashMap::new(),
            lost: vec![0.0],
            roulette: vec![0.0],
            events: 0,
            crossings: 0,
            skipped: 0,
            wave: Some(binner),
        };
        let g_cur = vec![0.0; ctx.tur_ids.len()];
        Self {
            ctx,
            out,
            g_cur,
            scratch: vec![0.0; 1],
            tr: vec![0.0; 1],
            first_order,
        }
    }

    /// Back to the state of [`PulseState::new`] for the pulse `pl` (its receiver). The binner
    /// is left as [`WaveformBinner::take_trimmed`] leaves it: as new.
    ///
    /// [`WaveformBinner::take_trimmed`]: crate::lidar::waveform::WaveformBinner::take_trimmed
    fn reset(&mut self, pl: &Pulse) {
        if let Some(r) = self.ctx.receiver.as_mut() {
            r.position = pl.emitter;
            r.axis = pl.axis;
        }
        let o = &mut self.out;
        o.summary.fill(0.0);
        for a in [
            &mut o.abs_tur,
            &mut o.int_tur,
            &mut o.abs_fac,
            &mut o.int_fac,
            &mut o.abs_gnd,
            &mut o.int_gnd,
        ] {
            a.reset();
        }
        o.abs_fluid.clear();
        o.lost.fill(0.0);
        o.roulette.fill(0.0);
        (o.events, o.crossings, o.skipped) = (0, 0, 0);
        self.g_cur.fill(0.0);
        self.scratch.fill(0.0);
        self.tr.fill(0.0);
    }
}

/// Survival probability of a pulse's beam rays past their first interaction (the
/// multiple-scattering roulette of [`Beam::scattering_photons`]) when it has `n_rays` of them.
fn continue_prob(beam: &Beam, n_rays: u32) -> f64 {
    match beam.estimator {
        LidarEstimator::Stratified | LidarEstimator::ExpectedValue if n_rays > 0 => {
            (beam.scattering_photons as f64 / n_rays as f64).clamp(0.0, 1.0)
        }
        _ => 1.0,
    }
}

fn run_pulse(st: &mut PulseState, beam: &Beam, pl: &Pulse) -> PulseResult {
    st.reset(pl);
    let PulseState {
        ctx,
        out,
        g_cur,
        scratch,
        tr,
        first_order,
    } = st;
    // The column quadrature of this pulse's first-order return, when it applies.
    let mut columns = first_order
        .as_deref()
        .and_then(|fo| fo.pulse(&*ctx, beam, pl).map(|pc| (fo, pc)));
    // The footprint's moments over the corners {x > bx, y > by} of the window's interval ends
    // (each shared by up to four rectangles); a pulse with a heavy column of facets or fluids
    // keeps its beam rays' own first order ([`HEAVY_COLUMN_RAYS`]).
    let mut corner = [(0.0, 0.0); 4 * MAX_FIRST_ORDER_COLUMNS];
    if let Some((fo, pc)) = columns.as_mut() {
        let nx = 2 * pc.ni;
        for ky in 0..2 * pc.nj {
            for kx in 0..nx {
                corner[ky * nx + kx] = fo.moments.corner(pc.bx[kx], pc.by[ky]);
            }
        }
        let heavy = (0..pc.ni * pc.nj).any(|k| {
            let (kx, ky) = (2 * (k % pc.ni), 2 * (k / pc.ni));
            let q = |i: usize, j: usize| corner[(ky + j) * nx + kx + i].0;
            let m0 = q(0, 0) - q(1, 0) - q(0, 1) + q(1, 1);
            pc.clear >> k & 1 == 0
                && pc.inside >> k & 1 == 1
                && m0 * beam.photons as f64 >= HEAVY_COLUMN_RAYS
        });
        if heavy {
            columns = None;
        }
    }
    // The pulse's beam rays: the quadrature's count, or the per-ray count without it; the
    // share of them continued into multiple scattering.
    let n_rays = if columns.is_some() {
        beam.photons
    } else {
        beam.photons_per_ray
    };
    ctx.continue_prob = continue_prob(beam, n_rays);
    let ctx = &*ctx;
    let inp = ctx.inp;
    let spec = inp.spec;
    let mut rng = crate::scene::spawn::stream(inp.params.seed, LIDAR_STREAM, pl.id);
    let (e1, e2) = crate::photon::sampling::orthonormal_basis(pl.axis);
    let w0 = beam.energy_j / n_rays.max(1) as f64;
    let mut missed = 0.0;
    let top = spec.top();
    let inside = |q: DVec3| {
        (0..3).all(|a| {
            q[a] >= spec.origin[a] && q[a] <= spec.origin[a] + spec.n[a] as f64 * spec.cell[a]
        })
    };
    // A beam ray's entry into the grid: the wrapped start point, its path from the emitter
    // (m) and its shift (unwrapped minus wrapped); `None`: it misses the scene.
    let enter = |d: DVec3| -> Option<(DVec3, f64, DVec3)> {
        // Entry point: the emitter itself inside the grid (terrestrial), else the top plane.
        let (start, s) = if inside(pl.emitter) {
            (pl.emitter, 0.0)
        } else if d.z < 0.0 && pl.emitter.z >= top {
            let s = (pl.emitter.z - top) / -d.z;
            (pl.emitter + d * s, s)
        } else {
            return None;
        };
        let mut q = start;
        let mut shift = DVec3::ZERO;
        if spec.boundary != BoundaryMode::Isolated {
            for a in 0..2 {
                let len = if a == 0 { ctx.size.0 } else { ctx.size.1 };
                // (rem_euclid is a libm fmod call; inside [0, len) it returns its argument.)
                let raw = q[a] - spec.origin[a];
                let rel = if (0.0..len).contains(&raw) {
                    raw
                } else {
                    raw.rem_euclid(len)
                };
                let wrapped = spec.origin[a] + rel;
                shift[a] = q[a] - wrapped;
                q[a] = wrapped;
            }
            // Continuous topography: a point k tiles along +x maps to the base tile k·offset
            // lower (as `wrap` does when a ray leaves through +x).
            if shift.x != 0.0 || shift.y != 0.0 {
                let kx = (shift.x / ctx.size.0).round();
                let ky = (shift.y / ctx.size.1).round();
                let dz = kx * spec.topography_offset.0 + ky * spec.topography_offset.1;
                q.z -= dz;
                shift.z += dz;
            }
        } else if !inside(DVec3::new(q.x, q.y, top.min(q.z))) {
            return None;
        }
        Some((q, s, shift))
    };
    // A photon of weight `w` (J) leaving the emitter along `d`, at its entry into the grid.
    let launch = |d: DVec3, w: f64| {
        enter(d).map(|(q, s, shift)| Photon {
            p: q,
            d,
            path: s,
            shift,
            di: if inp.params.sampler.is_discrete() {
                inp.dirs.find_sector(d)
            } else {
                0
            },
            w: Bands::from_elem(w, 1),
            w0: w,
            off: 0,
            order: 0,
            skip_facet: None,
            direct: true,
            ret: None,
            surface_scored: false,
            first_u: None,
            first_order_done: false,
        })
    };
    // Stratified: beam rays on the R2 lattice (Roberts 2018: additive recurrence with the
    // plastic number φ₂, low discrepancy for every count) shifted by one uniform per axis
    // (Cranley & Patterson 1976), so each ray is uniform on the unit square (unbiased) while
    // the set covers the footprint evenly. The uniform of each ray's first free path
    // (τ* = −ln(1 − u₃), [`Ctx::first_flight`]) follows its own shifted golden-ratio sequence
    // (Weyl), so the first collision depths of a pulse's rays cover [0, ∞) evenly too: each u₃
    // is uniform (unbiased). On the forest error study it takes the multiple-scattering part of
    // the error from 213 % to 152 % of itself at 90 rays (the R3 lattice over all three
    // coordinates instead: 170 %, and the footprint coverage, hence the first order, worsens).
    const PHI2: f64 = 1.324_717_957_244_746;
    const INV_GOLDEN: f64 = 0.618_033_988_749_894_9;
    let lattice = ctx.stratified.then(|| {
        (
            [1.0 / PHI2, 1.0 / (PHI2 * PHI2), INV_GOLDEN],
            [rng.next_f64(), rng.next_f64(), rng.next_f64()],
        )
    });
    for i in 0..n_rays {
        let (u1, u2, u3) = match lattice {
            Some((a, s)) => (
                unit_fract(s[0] + i as f64 * a[0]),
                unit_fract(s[1] + i as f64 * a[1]),
                Some(unit_fract(s[2] + i as f64 * a[2])),
            ),
            None => (rng.next_f64(), rng.next_f64(), None),
        };
        let [dx, dy] = beam.footprint.sample_footprint_point(u1, u2);
        let offset = e1 * dx + e2 * dy;
        let d = (pl.axis * beam.reference_range_m + offset).normalize();
        let Some(mut ph) = launch(d, w0) else {
            missed += w0;
            continue;
        };
        ph.first_u = u3;
        // With the column quadrature, the beam rays only sample their collisions.
        ph.first_order_done = columns
            .as_ref()
            .is_some_and(|(_, pc)| !pc.scores_own(offset.x, offset.y));
        // Discrete mode: the pulse keeps its exact direction (its first scattering uses the
        // rows of the sector that contains it); later orders follow the discrete directions.
        trace_photon(ctx, &mut ph, &mut rng, out, g_cur, scratch, tr);
    }
    // The first-order return of the rays that stay in one clear column: one column ray each.
    if let Some((fo, pc)) = &columns {
        let (nx, ny) = (2 * pc.ni, 2 * pc.nj);
        // One digitiser bin in one-way path, m.
        let bin_one_way = out.wave.as_ref().map_or(0.0, |w| 0.5 * w.bin_len_m());
        for k in 0..(nx - 1) * (ny - 1) {
            let (kx, ky) = (k % (nx - 1), k / (nx - 1));
            let rect = [pc.bx[kx], pc.bx[kx + 1], pc.by[ky], pc.by[ky + 1]];
            let q = |i: usize, j: usize| corner[(ky + j) * nx + kx + i];
            let m0 = q(0, 0).0 - q(1, 0).0 - q(0, 1).0 + q(1, 1).0;
            let m2 = q(0, 0).1 - q(1, 0).1 - q(0, 1).1 + q(1, 1).1;
            if !(m0 > 0.0) {
                continue;
            }
            let column = kx % 2 == 0 && ky % 2 == 0;
            let col = ky / 2 * pc.ni + kx / 2;
            if column && pc.inside >> col & 1 == 0 {
                // Outside an isolated grid: its beam rays miss the scene (booked as missed).
                continue;
            }
            // One column ray when the column is clear and its rays' arrival times agree.
            let clear = column && pc.clear >> col & 1 == 1 && {
                let near = (
                    0.0f64.clamp(rect[0], rect[1]),
                    0.0f64.clamp(rect[2], rect[3]),
                );
                let far = (
                    rect[0].abs().max(rect[1].abs()),
                    rect[2].abs().max(rect[3].abs()),
                );
                let r2_min = near.0 * near.0 + near.1 * near.1;
                let r2_max = (far.0 * far.0 + far.1 * far.1).min(fo.reach * fo.reach);
                pc.spread * (r2_max - r2_min) <= COLUMN_TIMING_TOLERANCE * bin_one_way
            };
            // Rays of this rectangle: (count, weight fraction each); a clear column's is one
            // column ray at its mean ρ², the others are drawn from the footprint over it.
            let (count, mass) = if clear {
                (1, m0)
            } else if column {
                // A column with facets (or whose rays' arrival times spread over more than
                // `COLUMN_TIMING_TOLERANCE` of a bin): as many rays as the beam rays it holds
                // on average (at least one), drawn over it.
                let k = ceil_small(m0 * n_rays as f64).max(1.0);
                (k as u32, m0 / k)
            } else if m0 < STRIP_ROULETTE_MASS {
                // A light strip: Russian roulette.
                if rng.next_f64() * STRIP_ROULETTE_MASS >= m0 {
                    continue;
                }
                (1, STRIP_ROULETTE_MASS)
            } else {
                (1, m0)
            };
            for _ in 0..count {
                let p = if clear {
                    point_at_squared_distance(rect, m2 / m0)
                } else {
                    match sample_in_rect(&beam.footprint, fo.reach, rect, &mut rng) {
                        Some(p) => p,
                        None => continue,
                    }
                };
                let d = (pl.axis * beam.reference_range_m + DVec3::new(p.0, p.1, 0.0)).normalize();
                let Some(mut ph) = launch(d, beam.energy_j * mass) else {
                    continue;
                };
                for (tm, g) in g_cur.iter_mut().enumerate() {
                    *g = ctx.g_of(tm, d.z);
                }
                // The first flight's walk and scoring with no collision (u = 1: τ* = ∞): walked
                // to the ground, the top or the optical depth 30; nothing goes on into
                // multiple scattering.
                ph.first_u = Some(1.0);
                ctx.first_flight(&mut ph, g_cur, &mut rng, out, scratch, tr);
            }
        }
    }
    // Only the bins between the first and last return are kept (memory of long scans); the
    // binner is left as new for the thread's next pulse.
    let (waveform, l) = out.wave.as_mut().expect("binner").take_trimmed();
    PulseResult {
        id: pl.id,
        waveform,
        out_of_gate_j: l.before_j + l.after_j,
        missed_j: missed,
    }
}

#[cfg(test)]
mod tests {
    use super::{
        FAR_ROULETTE_MIN_SURVIVAL, FIRST_ORDER_MOMENT_RATIO, Receiver, ceil_small,
        far_roulette_survival, inv_sq_mean, point_at_squared_distance, sample_in_rect,
        trunc_exp_moments, unit_fract,
    };
    use glam::DVec3;

    /// The truncation forms give the libm values bit for bit where they are used:
    /// `ceil_small(v).max(1)` = `v.ceil().max(1)` for every finite `v` below 2⁶³ (and far
    /// below −2⁶³), `unit_fract(x)` = `x − (x as u64)` (its previous form) on `[0, 2⁶³)`.
    #[test]
    fn truncation_forms_match_libm() {
        let vs = [
            -1e300,
            -1e19,
            -3.5,
            -1.0,
            -0.5,
            -0.0,
            0.0,
            1e-300,
            0.25,
            1.0,
            1.0 + 1e-15,
            2.5,
            31.99,
            32.0,
            4.5e15,
            9e15,
            1e18,
        ];
        for v in vs {
            assert_eq!(
                ceil_small(v).max(1.0).to_bits(),
                v.ceil().max(1.0).to_bits(),
                "{v:e}"
            );
            if v >= 0.0 {
                // The u64 form it replaces, bit for bit; `fract` by value (−0 vs +0 at −0).
                assert_eq!(unit_fract(v).to_bits(), (v - (v as u64) as f64).to_bits());
                assert_eq!(unit_fract(v), v.fract(), "{v:e}");
            }
            if v >= 1.0 {
                assert_eq!(ceil_small(v).to_bits(), v.ceil().to_bits(), "{v:e}");
            }
        }
    }

    /// ∫_a^b f by composite 5-point Gauss–Legendre on `m` equal panels (exact for degree 9 per
    /// panel; the integrands here are smooth and the panels short: error ≲ 1e-15 relative).
    fn quad(f: impl Fn(f64) -> f64, a: f64, b: f64, m: usize) -> f64 {
        const X: [f64; 5] = [
            -0.906_179_845_938_664,
            -0.538_469_310_105_683_1,
            0.0,
            0.538_469_310_105_683_1,
            0.906_179_845_938_664,
        ];
        const W: [f64; 5] = [
            0.236_926_885_056_189_1,
            0.478_628_670_499_366_5,
            0.568_888_888_888_888_9,
            0.478_628_670_499_366_5,
            0.236_926_885_056_189_1,
        ];
        let h = (b - a) / m as f64;
        let mut s = 0.0;
        for p in 0..m {
            let c = a + (p as f64 + 0.5) * h;
            s += X
                .iter()
                .zip(W)
                .map(|(x, w)| w * f(c + 0.5 * h * x))
                .sum::<f64>();
        }
        0.5 * h * s
    }

    /// Panels for the density e^{−t x} on [0, cut(t)]: at most 1/8 of a decay length each.
    fn panels(t: f64) -> usize {
        (8.0 * t.min(60.0)).ceil().max(64.0) as usize
    }

    /// Integration range of the density e^{−t x} on [0, 1]: up to 60 decay lengths (the rest,
    /// below e^{−60} ≈ 1e-26 relative, is dropped).
    fn cut(t: f64) -> f64 {
        (60.0 / t).min(1.0)
    }

    /// `αw` from 1e-8 to 1e5, both sides of the series switch (1e-3) and the m₃ maximum.
    const TS: [f64; 17] = [
        1e-8, 1e-6, 1e-4, 0.999e-3, 1e-3, 1.001e-3, 1e-2, 0.1, 0.5, 1.0, 2.8, 5.0, 10.0, 50.0,
        200.0, 1000.0, 1e5,
    ];

    /// Mean offset and variance of the truncated exponential of a stratum (both branches of
    /// [`trunc_exp_moments`]) against quadrature: within 1e-12 w and 1e-8 w² (the closed
    /// forms' cancellation at the switch αw = 1e-3: ~4e-13 w and ~1e-9 w²; 5e-9 w and 3e-6 w²
    /// would still keep [`inv_sq_mean`] within 1e-11 of its value).
    #[test]
    fn truncated_exponential_moments_match_quadrature() {
        for &w in &[0.15, 1.0, 7.0] {
            for &t in &TS {
                let alpha = t / w;
                let em = (-t).exp_m1();
                let (off, var) = trunc_exp_moments(alpha, 1.0 / alpha, w, em);
                let (m, top) = (panels(t), w * cut(t));
                let z = quad(|u| (-alpha * u).exp(), 0.0, top, m);
                let mu = quad(|u| u * (-alpha * u).exp(), 0.0, top, m) / z;
                let v = quad(|u| (u - mu).powi(2) * (-alpha * u).exp(), 0.0, top, m) / z;
                assert!(
                    (off - mu).abs() <= 1e-12 * w,
                    "αw = {t}, w = {w} m: mean offset {off} vs {mu} m"
                );
                assert!(
                    (var - v).abs() <= 1e-8 * w * w,
                    "αw = {t}, w = {w} m: variance {var} vs {v} m²"
                );
            }
        }
    }

    /// The central-moment bounds the estimate's bias bound rests on ([`inv_sq_mean`]):
    /// `σ² ≤ w²/12`, `|m₃| ≤ 0.01325 w³`, `m₄ ≤ w⁴/80` for every `αw > 0` (by quadrature on a
    /// grid of 10 points per decade from 1e-4 to 1e4 and at the m₃ maximum, relative slack
    /// 1e-9 for the quadrature).
    #[test]
    fn truncated_exponential_central_moment_bounds() {
        let mut ts: Vec<f64> = (-40..=40).map(|k| 10f64.powf(k as f64 / 10.0)).collect();
        ts.extend([2.7, 2.73, 2.745, 2.76, 2.8]);
        let mut m3_max: f64 = 0.0;
        for t in ts {
            let (m, top) = (panels(t), cut(t));
            let z = quad(|x| (-t * x).exp(), 0.0, top, m);
            let mu = quad(|x| x * (-t * x).exp(), 0.0, top, m) / z;
            let c = |n: i32| quad(|x| (x - mu).powi(n) * (-t * x).exp(), 0.0, top, m) / z;
            let (m2, m3, m4) = (c(2), c(3), c(4));
            assert!(m2 <= (1.0 + 1e-9) / 12.0, "αw = {t}: σ²/w² = {m2}");
            assert!(m3.abs() <= 0.01325, "αw = {t}: m3/w³ = {m3}");
            assert!(m4 <= (1.0 + 1e-9) / 80.0, "αw = {t}: m4/w⁴ = {m4}");
            m3_max = m3_max.max(m3.abs());
        }
        // The bound is tight (the maximum 0.0132455 at αw = 2.745).
        assert!(m3_max > 0.013245, "largest m3/w³ {m3_max}");
    }

    /// A stratum's first-order energy by the moment estimate, `M · inv_sq_mean(l0 + μ, σ²)`
    /// with the exact mass `M = e^{−αa}(1 − e^{−αw})/α`, against the integral
    /// `∫_a^b e^{−αu}/(l0 + u)² du` by quadrature: relative error ≤ 1e-10 (the stated bound
    /// 5.4e-11 plus rounding) for w/(l0 + a) up to the threshold [`FIRST_ORDER_MOMENT_RATIO`],
    /// αw from 1e-8 to 1e5 and ranges from 1 m to 10 km. Without the variance term the error
    /// at the threshold would be ~ρ²/4 = 2.5e-7.
    #[test]
    fn moment_estimate_matches_first_order_integral() {
        let mut worst: f64 = 0.0;
        for &l0 in &[1.0, 30.0, 985.0, 1e4] {
            for &ratio in &[FIRST_ORDER_MOMENT_RATIO * 0.999_999, 3e-4, 1e-5] {
                for &a_rel in &[0.0, 0.37] {
                    for &t in &TS {
                        let a = a_rel * l0 * 1e-3; // a few strata into the segment
                        let w = ratio * (l0 + a);
                        let alpha = t / w;
                        let em = (-t).exp_m1();
                        let (off, var) = trunc_exp_moments(alpha, 1.0 / alpha, w, em);
                        // e^{−αa}, the mass's start factor (scaled out: the ratio is what matters).
                        let mass = -em / alpha;
                        let est = mass * inv_sq_mean(l0 + a + off, var);
                        let exact = quad(
                            |u| (-alpha * u).exp() / (l0 + a + u).powi(2),
                            0.0,
                            w * cut(t),
                            panels(t),
                        );
                        let rel = (est / exact - 1.0).abs();
                        worst = worst.max(rel);
                        assert!(
                            rel <= 1e-10,
                            "l0 = {l0} m, a = {a} m, w/R = {ratio}, αw = {t}: {est} vs {exact} ({rel:e})"
                        );
                    }
                }
            }
        }
        println!("worst relative error {worst:e}");
    }

    /// The far-photon roulette's survival probability from the receiver's field-of-view cone:
    /// 1 inside the cone and up to ρ₀ beyond its edge, (ρ₀/e)² beyond (e the distance outside
    /// the cone, m), never below the floor; a nadir airborne receiver (cone radius grows with
    /// the range below it) and a horizontal terrestrial one (behind the scanner, the lateral
    /// distance alone).
    /// `point_at_squared_distance` gives a point of the rectangle at the asked squared
    /// distance (relative 1e-12) whenever it lies between the rectangle's least and largest
    /// squared distances, and the nearest point otherwise.
    #[test]
    fn point_at_squared_distance_stays_in_the_rectangle() {
        let rects = [
            [0.2, 0.9, -0.3, 0.4],
            [-1.0, 0.0, -0.5, 0.5],
            [-1.0, -0.2, -1.5, -0.505],
            [0.0, 1.0, 0.0, 1.0],
            [-0.3, 0.3, -0.3, 0.3],
        ];
        for r in rects {
            let near = (0.0f64.clamp(r[0], r[1]), 0.0f64.clamp(r[2], r[3]));
            let lo = near.0 * near.0 + near.1 * near.1;
            let hi = r[0].abs().max(r[1].abs()).powi(2) + r[2].abs().max(r[3].abs()).powi(2);
            for k in 0..=20 {
                let r2 = lo + (hi - lo) * k as f64 / 20.0;
                let (x, y) = point_at_squared_distance(r, r2);
                assert!(
                    x >= r[0] && x <= r[1] && y >= r[2] && y <= r[3],
                    "{r:?} {r2}"
                );
                assert!((x * x + y * y - r2).abs() <= 1e-12 * hi, "{r:?}: {r2}");
            }
            assert_eq!(point_at_squared_distance(r, 0.5 * lo), near);
        }
    }

    /// `sample_in_rect` draws from the footprint's density over a rectangle: every point inside
    /// the rectangle and the footprint's disk, and the mean ρ² over 40,000 draws equal to the
    /// rectangle's m2/m0 ([`crate::lidar::pulse::FootprintMoments`]) within 5 standard errors,
    /// on a strip, a rectangle across the axis and one cut by the truncation circle.
    #[test]
    fn strip_samples_follow_the_footprint_density() {
        use rand_xoshiro::rand_core::SeedableRng;
        let profile = crate::lidar::pulse::FootprintProfile::from_edge_intensity(0.3, 0.368)
            .expect("profile");
        let fp = crate::lidar::pulse::FootprintSampler::new(&profile, 0.9).expect("sampler");
        let mom = fp.moments();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
        for rect in [
            [0.3, 0.33, -0.5, 0.5],
            [-0.2, 0.1, -0.05, 0.4],
            [0.5, 2.0, 0.3, 2.0],
        ] {
            let (m0, m2) = mom.rect(rect[0], rect[1], rect[2], rect[3]);
            let n = 40_000;
            let v: Vec<f64> = (0..n)
                .map(|_| {
                    let (x, y) = sample_in_rect(&fp, 0.9, rect, &mut rng).expect("draw");
                    assert!(x >= rect[0] && x <= rect[1] && y >= rect[2] && y <= rect[3]);
                    assert!(x * x + y * y <= 0.81);
                    x * x + y * y
                })
                .collect();
            let mean = v.iter().sum::<f64>() / n as f64;
            let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            let se = (var / n as f64).sqrt();
            assert!(
                (mean - m2 / m0).abs() < 5.0 * se,
                "{rect:?}: mean ρ² {mean} vs {} (SE {se})",
                m2 / m0
            );
        }
    }

    #[test]
    fn far_roulette_survival_follows_the_distance_outside_the_fov_cone() {
        let tan = 1e-3; // FOV half-angle tangent: radius 1 m at 1000 m
        let rho0 = 2.0;
        let nadir = Receiver {
            position: DVec3::new(10.0, 20.0, 1000.0),
            axis: -DVec3::Z,
            cos_fov: 1.0 / (1.0f64 + tan * tan).sqrt(),
            aperture_m2: 0.1,
        };
        let q = |rx: &Receiver, m: DVec3| far_roulette_survival(rx, m, (rho0, tan));
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b;
        // On the axis, inside the cone, and at the cone edge + ρ₀ (cone radius 1 m at z = 0).
        assert_eq!(q(&nadir, DVec3::new(10.0, 20.0, 0.0)), 1.0);
        assert_eq!(q(&nadir, DVec3::new(10.9, 20.0, 0.0)), 1.0);
        assert_eq!(q(&nadir, DVec3::new(12.9, 20.0, 0.0)), 1.0);
        // e = 4 m outside the cone at z = 0 (lateral 5 m): (2/4)².
        assert!(close(q(&nadir, DVec3::new(10.0, 25.0, 0.0)), 0.25));
        // The cone is narrower higher up: lateral 5 m at z = 500 m is e = 4.5 m.
        assert!(close(
            q(&nadir, DVec3::new(15.0, 20.0, 500.0)),
            (2.0f64 / 4.5).powi(2)
        ));
        // Far away: the floor.
        assert_eq!(
            q(&nadir, DVec3::new(500.0, 20.0, 0.0)),
            FAR_ROULETTE_MIN_SURVIVAL
        );
        // Terrestrial, looking along +x from (0, 0, 1.5): 3 m behind the scanner, 6 m to the
        // side: e = 6 m (no cone behind the apex).
        let tls = Receiver {
            position: DVec3::new(0.0, 0.0, 1.5),
            axis: DVec3::X,
            ..nadir
        };
        assert!(close(
            q(&tls, DVec3::new(-3.0, 6.0, 1.5)),
            (2.0f64 / 6.0).powi(2)
        ));
        // In front, 10 m along the axis (cone radius 0.01 m), 1.01 m to the side: e = 1 m ≤ ρ₀.
        assert_eq!(q(&tls, DVec3::new(10.0, 0.0, 2.51)), 1.0);
    }
}
