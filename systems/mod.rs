//! The DART modules as ECS stages. This folder lives outside `src/` but in the same crate
//! (`#[path]` in `lib.rs`); only `src/simulation.rs` imports it.
//!
//! Stages with systems: Direction (discrete directions), Phase (tables; skipped by the
//! continuous Monte Carlo solver), Maket (scene → cell grid), Radiative (flux tracking, the
//! default passive solver), Photon (Monte Carlo passive solver with `--solver monte-carlo`, then
//! the scene's LiDARs) and Output (products). Sensor has a schedule label but no systems yet
//! (open issue); a scene never silently gets results from it.
//!
//! Shared by the tracking systems: [`tracking_scene`] (flat ground, DEM facets, horizontal
//! irradiances, band names, area) and [`used_turbid`] (the turbid materials a component uses).

pub mod direction;
pub mod lidar;
pub mod maket;
pub mod output;
pub mod phase;
pub mod photon;
pub mod radiative;
pub mod spawn;

use crate::components::{Ground, ImportedMesh, TurbidCrown, TurbidPlot};
use crate::geometry::terrain::Terrain;
use crate::resources::facets::{FacetKind, FacetStore};
use crate::resources::grid::GridSpec;
use crate::resources::materials::MaterialId;
use crate::resources::scene::{SceneInfo, StageErrors, TerrainRes};
use bevy_ecs::prelude::{Query, Res};

/// Run condition: true while no system of the stage has reported an error (later systems of a
/// stage are gated with `run_if(no_stage_error)`).
pub fn no_stage_error(e: Res<StageErrors>) -> bool {
    e.0.is_empty()
}

/// What the tracking systems (flux tracking, the passive Monte Carlo solver, the LiDARs) take
/// from the scene besides the grid, the facets, the directions and the optics; built by
/// [`tracking_scene`].
pub struct TrackingScene {
    /// Material of the ground when it is the plane z0 (a `Ground` over flat terrain).
    pub flat_ground: Option<MaterialId>,
    /// Whether each facet belongs to a DEM ground (its absorption is ground absorption).
    pub ground_facet: Vec<bool>,
    /// Direct irradiance on a horizontal plane per band, `E (1 − SKYL)`, W m⁻² µm⁻¹.
    pub e_dir: Vec<f64>,
    /// Diffuse sky irradiance on a horizontal plane per band, `E SKYL`, W m⁻² µm⁻¹.
    pub e_diff: Vec<f64>,
    /// Band names, in band order.
    pub band_names: Vec<String>,
    /// Horizontal area of the scene, m².
    pub area_m2: f64,
}

/// The scene facts every tracking system hands its engine and its products ([`TrackingScene`]);
/// `ground` is the scene's `Ground` entity, if any. A band without an irradiance gets 1, without
/// a SKYL 0.
pub fn tracking_scene(
    info: &SceneInfo,
    spec: &GridSpec,
    terrain: &TerrainRes,
    ground: Option<&Ground>,
    facets: &FacetStore,
) -> TrackingScene {
    let nb = info.bands.len();
    let flat_ground = match (&terrain.0, ground) {
        (Terrain::Flat(_), Some(g)) => Some(g.optics),
        _ => None,
    };
    let ground_facet: Vec<bool> = facets
        .facets
        .iter()
        .map(|f| f.kind == FacetKind::Ground)
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
    TrackingScene {
        flat_ground,
        ground_facet,
        e_dir,
        e_diff,
        band_names: info.bands.iter().map(|b| b.name.clone()).collect(),
        area_m2: spec.n[0] as f64 * spec.cell.x * spec.n[1] as f64 * spec.cell.y,
    }
}

/// Turbid materials used by crowns, plots and turbid meshes (`used[id]`).
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
