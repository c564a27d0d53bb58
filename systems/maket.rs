//! Maket stage (DART 5 paper §2, "Maket" module): scene entities → cell grid. ECS glue over
//! the engine in [`crate::maket`].
//!
//! Reads the object components spawned from the scene (`TurbidCrown`, `Trunk`, `TurbidPlot`,
//! `Building`, `WaterBody`, `ImportedMesh`, `Ground` + `TerrainRes`) and writes `FacetStore`,
//! `GridSpec`, `MemoryEstimate`, `CellGrid`, `FacetBvh` and `MaketReport`. The systems run in
//! physical order (`MaketSystems`): facets, plan (memory check before any allocation),
//! rasterise turbid media, assign facets to cells, build the BVH, summarise.

use crate::components::*;
use crate::maket::facets::FacetObjects;
use crate::maket::report::make_report;
use crate::maket::{TurbidObjects, facets, plan, rasterise};
use crate::resources::facets::{FacetBvh, FacetStore};
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::maket_report::MemoryEstimate;
use crate::resources::materials::Materials;
use crate::resources::scene::{RunSettings, SceneInfo, StageErrors, TerrainRes, Warnings};
use crate::systems::no_stage_error;
use bevy_ecs::prelude::*;

/// The Maket systems in execution order.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub enum MaketSystems {
    /// Objects → facets.
    Facets,
    /// Grid extent and memory estimate.
    Plan,
    /// Turbid media → per-cell leaf area density.
    Rasterise,
    /// Facets → cells.
    Assign,
    /// BVH.
    Accelerate,
    /// Report.
    Summarise,
}

/// Adds the Maket systems to a schedule.
pub fn add_systems(s: &mut Schedule) {
    s.configure_sets(
        (
            MaketSystems::Facets,
            MaketSystems::Plan,
            MaketSystems::Rasterise,
            MaketSystems::Assign,
            MaketSystems::Accelerate,
            MaketSystems::Summarise,
        )
            .chain(),
    );
    add_plan_systems(s);
    s.add_systems((
        rasterise_turbid
            .in_set(MaketSystems::Rasterise)
            .run_if(no_stage_error),
        assign_facets_to_cells
            .in_set(MaketSystems::Assign)
            .run_if(no_stage_error),
        build_facet_bvh
            .in_set(MaketSystems::Accelerate)
            .run_if(no_stage_error),
        summarise_maket
            .in_set(MaketSystems::Summarise)
            .run_if(no_stage_error),
    ));
}

/// Adds only the facet and plan systems (what `lumenscape check` runs).
pub fn add_plan_systems(s: &mut Schedule) {
    s.configure_sets((MaketSystems::Facets, MaketSystems::Plan).chain());
    s.add_systems((
        build_facets.in_set(MaketSystems::Facets),
        plan_grid.in_set(MaketSystems::Plan).run_if(no_stage_error),
    ));
}

/// The turbid objects of the world, in query order.
fn turbid_objects<'a>(
    crowns: &'a Query<&TurbidCrown>,
    plots: &'a Query<&TurbidPlot>,
    meshes: &'a Query<&ImportedMesh>,
) -> TurbidObjects<'a> {
    TurbidObjects {
        crowns: crowns.iter().collect(),
        plots: plots.iter().collect(),
        meshes: meshes.iter().collect(),
    }
}

/// Maket · reads Ground, Trunk, Building, WaterBody, ImportedMesh, TerrainRes · writes FacetStore.
#[allow(clippy::too_many_arguments)]
pub fn build_facets(
    info: Res<SceneInfo>,
    terrain: Res<TerrainRes>,
    grounds: Query<(&SourceObject, &Ground)>,
    trunks: Query<(&SourceObject, &Trunk)>,
    buildings: Query<(&SourceObject, &Building)>,
    waters: Query<(&SourceObject, &WaterBody)>,
    meshes: Query<(&SourceObject, &ImportedMesh)>,
    mut warnings: ResMut<Warnings>,
    mut errors: ResMut<StageErrors>,
    mut commands: Commands,
) {
    let objects = FacetObjects {
        grounds: grounds.iter().collect(),
        trunks: trunks.iter().collect(),
        buildings: buildings.iter().collect(),
        waters: waters.iter().collect(),
        meshes: meshes.iter().collect(),
    };
    let store = facets::build_facets(&info, &terrain.0, &objects, &mut warnings.0, &mut errors.0);
    commands.insert_resource(store);
}

/// Maket · reads SceneInfo, TerrainRes, FacetStore, TurbidCrown, TurbidPlot, ImportedMesh,
/// RunSettings · writes GridSpec, MemoryEstimate (or a StageErrors entry when over the limit).
#[allow(clippy::too_many_arguments)]
pub fn plan_grid(
    info: Res<SceneInfo>,
    terrain: Res<TerrainRes>,
    facets: Res<FacetStore>,
    settings: Res<RunSettings>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    mut errors: ResMut<StageErrors>,
    mut commands: Commands,
) {
    let objects = turbid_objects(&crowns, &plots, &meshes);
    match plan::plan_grid(
        &info,
        &terrain.0,
        &facets,
        settings.max_memory_bytes,
        &objects,
    ) {
        Ok(p) => {
            errors.0.extend(p.over_limit);
            commands.insert_resource(p.spec);
            commands.insert_resource(p.est);
        }
        Err(e) => errors.0.push(e),
    }
}

/// Maket · reads GridSpec, TurbidCrown, TurbidPlot, ImportedMesh (as_turbid parts), TerrainRes ·
/// writes CellGrid (turbid part), conserving each object's leaf area
/// ([`rasterise::rasterise_turbid`]).
pub fn rasterise_turbid(
    spec: Res<GridSpec>,
    terrain: Res<TerrainRes>,
    settings: Res<RunSettings>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    mut commands: Commands,
) {
    let objects = turbid_objects(&crowns, &plots, &meshes);
    let grid = rasterise::rasterise_turbid(&spec, &terrain.0, settings.progress, &objects);
    commands.insert_resource(grid);
}

/// Maket · reads GridSpec, FacetStore · writes CellGrid (facet part)
/// ([`rasterise::assign_facets_to_cells`]).
pub fn assign_facets_to_cells(
    spec: Res<GridSpec>,
    facets: Res<FacetStore>,
    mut grid: ResMut<CellGrid>,
) {
    let (start, ids) = rasterise::assign_facets_to_cells(&spec, &facets);
    grid.facet_start = start;
    grid.facet_ids = ids;
}

/// Maket · reads FacetStore, GridSpec · writes FacetBvh (only when the scene has facets).
pub fn build_facet_bvh(spec: Res<GridSpec>, facets: Res<FacetStore>, mut commands: Commands) {
    if let Some(bvh) = rasterise::build_facet_bvh(&spec, &facets) {
        commands.insert_resource(bvh);
    }
}

/// Maket · reads everything Maket wrote · writes MaketReport.
#[allow(clippy::too_many_arguments)]
pub fn summarise_maket(
    spec: Res<GridSpec>,
    est: Res<MemoryEstimate>,
    mats: Res<Materials>,
    facets: Res<FacetStore>,
    grid: Option<Res<CellGrid>>,
    bvh: Option<Res<FacetBvh>>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    warnings: Res<Warnings>,
    mut commands: Commands,
) {
    let objects = turbid_objects(&crowns, &plots, &meshes);
    let report = make_report(
        &spec,
        &est,
        &mats,
        &facets,
        grid.as_deref(),
        bvh.as_deref(),
        &objects,
        &warnings,
    );
    commands.insert_resource(report);
}

/// Maket · reads what the plan systems wrote · returns the report before rasterisation (what
/// `lumenscape check` prints).
#[allow(clippy::too_many_arguments)]
pub fn plan_report(
    spec: Res<GridSpec>,
    est: Res<MemoryEstimate>,
    mats: Res<Materials>,
    facets: Res<FacetStore>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    warnings: Res<Warnings>,
) -> crate::resources::maket_report::MaketReport {
    let objects = turbid_objects(&crowns, &plots, &meshes);
    make_report(&spec, &est, &mats, &facets, None, None, &objects, &warnings)
}
