//! Photon stage (DART 5 paper §4): forward Monte Carlo photon tracking of sun and sky
//! radiation through the Maket grid ([`crate::photon::engine`]), the passive Monte Carlo solver
//! chosen with `--solver monte-carlo`. Same products as the Radiative stage, with standard
//! errors.
//!
//! Reads GridSpec, CellGrid, FacetStore, Directions, OpticsTables (discrete samplers only),
//! RunSettings, SceneInfo, Materials, TerrainRes, Ground, TurbidCrown, TurbidPlot, ImportedMesh;
//! writes RadiativeProducts.

use crate::components::{Ground, ImportedMesh, TurbidCrown, TurbidPlot};
use crate::geometry::terrain::Terrain;
use crate::photon::engine::{DiscreteRows, PhotonInput, PhotonOptics, PhotonParams, run};
use crate::photon::products::photon_products;
use crate::photon::sampling::{BrdfSampler, LeafSampler};
use crate::physics::lad::{GTable, LeafAngleDistribution, VolscattKernel};
use crate::radiative::engine::TrackOptics;
use crate::resources::facets::{FacetKind, FacetStore};
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::materials::{MaterialKind, Materials};
use crate::resources::scene::{RunSettings, SceneInfo, Solver, StageErrors, TerrainRes};
use crate::resources::tracking::{Directions, OpticsTables};
use crate::scene::desc::LadDesc;
use bevy_ecs::prelude::*;
use std::sync::Arc;

/// Inclination bins of the Γ kernel used for peel-off values of non-spherical LADs (the
/// spherical LAD uses its closed form); the binning error is O(n⁻²) (physics.md §3.3).
pub const PEEL_LAD_BINS: usize = 180;
/// Intervals of the G(μ) table (interpolation error ≈ 1e-8 for the classical LADs).
pub const G_TABLE_INTERVALS: usize = 4096;

/// The LAD-derived part of a turbid material's photon optics (leaf-normal sampler, Γ kernel,
/// G table), by far the costly part of [`build_photon_optics`]: the G table alone is
/// [`G_TABLE_INTERVALS`]` + 1` tanh–sinh quadratures (≈320 M instructions for a non-spherical
/// LAD). Built once per LAD and run, and shared by the passive Monte Carlo solver and every
/// LiDAR instrument of the Photon stage (keyed by the LAD itself, so materials with the same
/// LAD share one entry). Inserted empty by [`crate::simulation::Simulation`].
#[derive(Default, Resource)]
pub struct LadOpticsCache(Vec<(LadDesc, Arc<LadOptics>)>);

/// One entry of [`LadOpticsCache`].
#[derive(Debug)]
pub struct LadOptics {
    sampler: LeafSampler,
    kernel: VolscattKernel,
    g: GTable,
}

impl LadOpticsCache {
    /// The optics of `lad`, built on first use.
    fn get(&mut self, lad: &LadDesc) -> Result<Arc<LadOptics>, String> {
        if let Some((_, o)) = self.0.iter().find(|(l, _)| l == lad) {
            return Ok(o.clone());
        }
        let d = LeafAngleDistribution::new(lad).map_err(|e| e.to_string())?;
        let o = Arc::new(LadOptics {
            sampler: LeafSampler::new(&d).map_err(|e| e.to_string())?,
            kernel: VolscattKernel::new(&d, PEEL_LAD_BINS, false),
            g: GTable::new(&d, G_TABLE_INTERVALS),
        });
        self.0.push((lad.clone(), o.clone()));
        Ok(o)
    }
}

/// Photon · reads the Maket grid, directions, materials and illumination · writes
/// RadiativeProducts.
#[allow(clippy::too_many_arguments)]
pub fn track_photons(
    info: Res<SceneInfo>,
    spec: Res<GridSpec>,
    grid: Res<CellGrid>,
    facets: Res<FacetStore>,
    dirs: Res<Directions>,
    tables: Option<Res<OpticsTables>>,
    settings: Res<RunSettings>,
    mats: Res<Materials>,
    terrain: Res<TerrainRes>,
    grounds: Query<&Ground>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    mut errors: ResMut<StageErrors>,
    mut cache: ResMut<LadOpticsCache>,
    mut commands: Commands,
) {
    let Solver::MonteCarlo { photons, sampler } = settings.solver else {
        return;
    };
    let nb = info.bands.len();
    let used = used_turbid(mats.list.len(), &crowns, &plots, &meshes);
    let optics = match build_photon_optics(&mats, &used, tables.as_deref(), sampler, nb, &mut cache)
    {
        Ok(o) => o,
        Err(e) => {
            errors.0.push(e);
            return;
        }
    };
    let flat_ground = match (&terrain.0, grounds.iter().next()) {
        (Terrain::Flat(_), Some(g)) => Some(g.optics),
        _ => None,
    };
    let tiling = dirs.set.tiling();
    let view_dir: Vec<usize> = tiling
        .iter()
        .enumerate()
        .filter(|(_, d)| {
            matches!(d.kind, crate::direction::DirectionKind::Exact { .. }) && d.omega.z > 0.0
        })
        .map(|(j, _)| j)
        .collect();
    let il = &info.illumination;
    let e_tot: Vec<f64> = (0..nb)
        .map(|b| il.irradiance_w_m2_um.get(b).copied().unwrap_or(1.0))
        .collect();
    let skyl: Vec<f64> = (0..nb)
        .map(|b| il.skyl.get(b).copied().unwrap_or(0.0))
        .collect();
    let e_dir: Vec<f64> = (0..nb).map(|b| e_tot[b] * (1.0 - skyl[b])).collect();
    let e_diff: Vec<f64> = (0..nb).map(|b| e_tot[b] * skyl[b]).collect();
    let ground_facet: Vec<bool> = facets
        .facets
        .iter()
        .map(|f| f.kind == FacetKind::Ground)
        .collect();
    let params = PhotonParams {
        skip_empty: settings.skip_empty,
        ..PhotonParams::new(photons, info.seed, sampler)
    };
    let input = PhotonInput {
        spec: &spec,
        grid: &grid,
        facets: &facets.facets,
        ground_facet: &ground_facet,
        dirs: &dirs.set,
        optics: &optics,
        fluid: None,
        flat_ground,
        views: view_dir.iter().map(|&j| tiling[j].omega).collect(),
        sun: dirs.sun,
        e_dir: e_dir.clone(),
        e_diff: e_diff.clone(),
        params: params.clone(),
    };
    let t0 = std::time::Instant::now();
    let raw = run(&input);
    let secs = t0.elapsed().as_secs_f64();
    let names: Vec<String> = info.bands.iter().map(|b| b.name.clone()).collect();
    let area = spec.n[0] as f64 * spec.cell.x * spec.n[1] as f64 * spec.cell.y;
    commands.insert_resource(photon_products(
        raw,
        &params,
        &dirs.set,
        &view_dir,
        &names,
        area,
        &e_dir,
        &e_diff,
        &ground_facet,
        secs,
    ));
}

/// Photon-tracker optics of every material (`used[id]`: turbid materials a component uses);
/// the LAD-derived parts come from (and go into) `cache`.
pub fn build_photon_optics(
    mats: &Materials,
    used: &[bool],
    tables: Option<&OpticsTables>,
    sampler: crate::photon::engine::SamplerKind,
    nb: usize,
    cache: &mut LadOpticsCache,
) -> Result<Vec<PhotonOptics>, String> {
    let mut optics = Vec::with_capacity(mats.list.len());
    for (id, m) in mats.list.iter().enumerate() {
        let o = match &m.kind {
            MaterialKind::Turbid {
                reflectance,
                transmittance,
                lad,
                specular,
                leaf_size_m,
            } if used[id] => {
                if specular.is_some() {
                    return Err(format!(
                        "material `{}`: specular leaves are not supported by the Monte Carlo solver yet (use the flux-tracking solver)",
                        m.name
                    ));
                }
                let lo = cache
                    .get(lad)
                    .map_err(|e| format!("material `{}`: {e}", m.name))?;
                let discrete = if sampler.is_discrete() {
                    let Some(TrackOptics::Turbid { tables, .. }) =
                        tables.and_then(|t| t.optics.get(id))
                    else {
                        return Err(format!(
                            "material `{}`: discrete Monte Carlo needs the Phase tables",
                            m.name
                        ));
                    };
                    match DiscreteRows::new(tables.clone(), sampler) {
                        Ok(r) => Some(r),
                        Err(e) => {
                            return Err(format!("material `{}`: {e}", m.name));
                        }
                    }
                } else {
                    None
                };
                PhotonOptics::Turbid {
                    sampler: lo.sampler.clone(),
                    kernel: lo.kernel.clone(),
                    g: lo.g.clone(),
                    rho: reflectance.clone(),
                    tau: transmittance.clone(),
                    discrete,
                    leaf_size_m: *leaf_size_m,
                }
            }
            MaterialKind::Lambertian { .. } | MaterialKind::Leaf { .. } => {
                let (r, t, t_dir) = m.kind.lambert_parts().expect("Lambertian kind");
                PhotonOptics::Lambert { r, t, t_dir }
            }
            k @ (MaterialKind::Rpv(_) | MaterialKind::Hapke(_)) => {
                let models = k.brdf_models(nb).expect("RPV/Hapke");
                // The sampler follows band 0's BRDF; other bands are reweighted (unbiased:
                // RPV and Hapke BRFs are positive wherever band 0's is).
                match BrdfSampler::new(&models[0], Default::default()) {
                    Ok(sampler) => PhotonOptics::Brdf { models, sampler },
                    Err(e) => {
                        return Err(format!("material `{}`: {e}", m.name));
                    }
                }
            }
            _ => PhotonOptics::Unused,
        };
        optics.push(o);
    }
    Ok(optics)
}

/// Turbid materials used by crowns, plots and turbid meshes.
pub fn used_turbid(
    n: usize,
    crowns: &Query<&TurbidCrown>,
    plots: &Query<&TurbidPlot>,
    meshes: &Query<&ImportedMesh>,
) -> Vec<bool> {
    let mut used = vec![false; n];
    for c in crowns {
        used[c.material as usize] = true;
    }
    for p in plots {
        used[p.material as usize] = true;
    }
    for m in meshes {
        for part in m.parts.iter().filter(|p| p.as_turbid) {
            used[part.material as usize] = true;
        }
    }
    used
}

/// The Photon stage's systems, in order: the passive Monte Carlo solver, then the LiDARs (whose
/// photon counting and fusion read the passive radiance).
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub enum PhotonSystems {
    /// Passive Monte Carlo (`--solver monte-carlo`).
    Passive,
    /// LiDAR instruments ([`crate::systems::lidar`]).
    Lidar,
}

/// Adds the Photon stage's systems: the passive Monte Carlo solver when chosen, then every LiDAR.
pub fn add_systems(s: &mut Schedule) {
    s.configure_sets((PhotonSystems::Passive, PhotonSystems::Lidar).chain());
    s.add_systems((
        track_photons
            .in_set(PhotonSystems::Passive)
            .run_if(resource_exists::<Directions>)
            .run_if(resource_exists::<CellGrid>)
            .run_if(|s: Res<RunSettings>| s.solver.is_monte_carlo())
            .run_if(not(resource_exists::<crate::resources::scene::SkipPassive>))
            .run_if(crate::systems::no_stage_error),
        crate::systems::lidar::run_lidars
            .in_set(PhotonSystems::Lidar)
            .run_if(resource_exists::<crate::resources::lidar::LidarInstruments>)
            .run_if(resource_exists::<Directions>)
            .run_if(resource_exists::<CellGrid>)
            .run_if(crate::systems::no_stage_error),
    ));
}
