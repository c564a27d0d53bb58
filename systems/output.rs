//! Output stage: writes the products of the stages that ran into `OutputDir`, through the
//! writers of [`crate::output`] (Maket, passive solvers) and [`crate::lidar::products`].

use crate::output::maket::write_maket;
use crate::output::radiative::write_radiative;
use crate::resources::facets::FacetStore;
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::maket_report::MaketReport;
use crate::resources::materials::Materials;
use crate::resources::scene::{ProductSelection, StageErrors};
use bevy_ecs::prelude::*;

pub use crate::resources::scene::OutputDir;

/// Output · reads GridSpec, CellGrid, FacetStore, Materials, MaketReport, SceneInfo (its
/// georeference) · writes files into `OutputDir`.
#[allow(clippy::too_many_arguments)]
pub fn write_maket_products(
    out: Res<OutputDir>,
    info: Option<Res<crate::resources::scene::SceneInfo>>,
    spec: Res<GridSpec>,
    grid: Res<CellGrid>,
    facets: Res<FacetStore>,
    mats: Res<Materials>,
    report: Res<MaketReport>,
    sel: Option<Res<ProductSelection>>,
    mut errors: ResMut<StageErrors>,
) {
    let wanted = ["maket.json", "lai.exr", "dsm.exr", "density.csv"];
    if sel.is_some_and(|s| !wanted.iter().any(|p| s.wants(p))) {
        return;
    }
    let georef = info.as_ref().and_then(|i| i.georeference.as_ref());
    if let Err(e) = write_maket(&out.0, &spec, &grid, &facets, &mats, &report, georef) {
        errors.0.push(e);
    }
}

/// Output · reads RadiativeProducts, GridSpec, CellGrid, FacetStore, Materials, SceneInfo ·
/// writes `summary.json`, `brf.csv`, the radiative budget (`budget/cells.csv`,
/// `budget/layers.csv`, `budget/elements.csv`) and, with SensorProducts, the camera images
/// (`sensors/`) into `OutputDir`.
#[allow(clippy::too_many_arguments)]
pub fn write_radiative_products(
    out: Res<OutputDir>,
    products: Res<crate::radiative::products::RadiativeProducts>,
    info: Res<crate::resources::scene::SceneInfo>,
    settings: Res<crate::resources::tracking::RadiativeSettings>,
    dirs: Res<crate::resources::tracking::Directions>,
    spec: Res<GridSpec>,
    grid: Res<CellGrid>,
    facets: Res<FacetStore>,
    mats: Res<Materials>,
    memory: Option<Res<crate::resources::memory::MemoryPlan>>,
    sel: Option<Res<ProductSelection>>,
    sensors: Option<Res<crate::photon::sensors::SensorProducts>>,
    mut errors: ResMut<StageErrors>,
) {
    let wants = |p: &str| sel.as_deref().is_none_or(|s| s.wants(p));
    if let Err(e) = write_radiative(
        &out.0,
        &products,
        &info,
        &settings,
        &dirs,
        &spec,
        &grid,
        &facets,
        &mats,
        memory.as_deref(),
        sensors.as_deref(),
        &wants,
    ) {
        errors.0.push(e);
    }
}

/// Output · reads LidarProducts, SceneInfo · writes `DIR/lidar/<instrument>/` (waveforms, LAS
/// returns, fusion and photon-counting clouds, quick-looks, lidar.json).
pub fn write_lidar_products(
    out: Res<OutputDir>,
    products: Res<crate::lidar::run::LidarProducts>,
    info: Res<crate::resources::scene::SceneInfo>,
    memory: Option<Res<crate::resources::memory::MemoryPlan>>,
    sel: Option<Res<ProductSelection>>,
    mut errors: ResMut<StageErrors>,
) {
    if sel.is_some_and(|s| !s.wants("lidar")) {
        return;
    }
    let names: Vec<String> = info.bands.iter().map(|b| b.name.clone()).collect();
    if let Err(e) =
        crate::lidar::products::write_lidar(&out.0, &products.0, &names, memory.as_deref())
    {
        errors.0.push(e);
    }
}

/// The Output stage's systems (each writes the products of one stage that ran).
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub enum OutputSystems {
    /// Maket, Radiative/Photon and LiDAR products.
    Write,
}

/// Adds the Output stage's systems: each runs when an output folder is set and its stage's
/// products exist; `summary.json` is written last (its measured peak covers the others).
pub fn add_systems(s: &mut Schedule) {
    use crate::systems::no_stage_error;
    s.add_systems(
        (
            write_maket_products
                .run_if(resource_exists::<OutputDir>)
                .run_if(resource_exists::<CellGrid>)
                .run_if(resource_exists::<MaketReport>)
                .run_if(no_stage_error),
            write_lidar_products
                .run_if(resource_exists::<OutputDir>)
                .run_if(resource_exists::<crate::lidar::run::LidarProducts>)
                .run_if(no_stage_error),
            write_radiative_products
                .run_if(resource_exists::<OutputDir>)
                .run_if(resource_exists::<crate::radiative::products::RadiativeProducts>)
                .run_if(no_stage_error),
        )
            .chain()
            .in_set(OutputSystems::Write),
    );
}
