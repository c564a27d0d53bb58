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
use crate::photon::engine::{PhotonInput, PhotonParams, run};
use crate::photon::material_optics::{LadCache, build_photon_optics};
use crate::photon::products::photon_products;
use crate::resources::facets::{FacetKind, FacetStore};
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::materials::Materials;
use crate::resources::scene::{RunSettings, SceneInfo, Solver, StageErrors, TerrainRes};
use crate::resources::tracking::{Directions, OpticsTables};
use bevy_ecs::prelude::*;

/// The LAD-derived photon optics shared by the passive Monte Carlo solver and every LiDAR
/// instrument of the Photon stage ([`LadCache`]). Inserted empty by
/// [`crate::simulation::Simulation`].
#[derive(Default, Resource)]
pub struct LadOpticsCache(pub LadCache);

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
    let optics =
        match build_photon_optics(&mats, &used, tables.as_deref(), sampler, nb, &mut cache.0) {
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
