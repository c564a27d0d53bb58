//! What the photon engine takes (DART 5 paper §4): the scattering-direction sampler choice and
//! the per-row discrete samplers over the Phase tables (alias or Box), the per-material optics
//! (turbid leaves, Lambertian and BRDF surfaces, fluids), the fluid fields, the run parameters
//! and the scene arrays of one run ([`PhotonInput`]).

use crate::direction::DirectionSet;
use crate::phase::PhaseTable;
use crate::photon::sampling::{AliasTable, BoxTable, BrdfSampler, LeafSampler};
use crate::physics::brdf::Brdf;
use crate::physics::lad::{GTable, VolscattKernel};
use crate::physics::phase::FluidPhase;
use crate::resources::facets::Facet;
use crate::resources::grid::{CellGrid, GridSpec};
use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;

/// The direction sampler is a run setting ([`crate::resources::scene::SamplerKind`]).
pub use crate::resources::scene::SamplerKind;

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
    pub(crate) fn sample(&self, rng: &mut Xoshiro256PlusPlus) -> usize {
        match self {
            RowSampler::Alias(a) => a.sample(rng),
            RowSampler::Box(b) => b.sample(rng),
        }
    }
    #[inline]
    pub(crate) fn probability(&self, j: usize) -> f64 {
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
    /// cells, segment ends and results bit for bit ([`Dda::skip_to`](crate::radiative::dda::Dda::skip_to)). Off: kept for the
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
    /// The atmosphere over the scene, if any: sun photons then start at its top.
    pub atmosphere: Option<&'a super::atmosphere::PhotonAtmosphere>,
    /// Flat ground optics (material id into `optics`) if the ground is the plane z0.
    pub flat_ground: Option<u32>,
    /// View directions (upward unit vectors) that get peel-off estimates.
    pub views: Vec<DVec3>,
    /// Frame cameras that get peel-off images (sensor stage; empty: none).
    pub cameras: Vec<crate::geometry::camera::FrameCamera>,
    /// Propagation vector of the direct sun beam (downward).
    pub sun: DVec3,
    /// Direct irradiance on a horizontal plane per band, W m⁻² (µm⁻¹).
    pub e_dir: Vec<f64>,
    /// Diffuse sky irradiance on a horizontal plane per band (isotropic sky).
    pub e_diff: Vec<f64>,
    /// Thermal emission (issue #34): `ε B(T)` per element and band and the thermal sky
    /// radiance. `Some`: a thermal run (emission and thermal sky photons on the thermal
    /// channels `nb..2 nb`; `e_dir` and `e_diff` must be zero, see [`super::emission`]).
    pub thermal: Option<&'a crate::radiative::engine::ThermalSources>,
    /// Parameters.
    pub params: PhotonParams,
}
