//! The DART modules as ECS stages. This folder lives outside `src/` but in the same crate
//! (`#[path]` in `lib.rs`); only `src/simulation.rs` imports it.
//!
//! Stages with systems: Direction (discrete directions), Phase (tables; skipped by the
//! continuous Monte Carlo solver), Maket (scene → cell grid), Radiative (flux tracking, the
//! default passive solver), Photon (Monte Carlo passive solver with `--solver monte-carlo`, then
//! the scene's LiDARs) and Output (products). Sensor has a schedule label but no systems yet
//! (open issue); a scene never silently gets results from it.

pub mod direction;
pub mod lidar;
pub mod maket;
pub mod output;
pub mod phase;
pub mod photon;
pub mod radiative;
pub mod spawn;

use crate::resources::scene::StageErrors;
use bevy_ecs::prelude::Res;

/// Run condition: true while no system of the stage has reported an error (later systems of a
/// stage are gated with `run_if(no_stage_error)`).
pub fn no_stage_error(e: Res<StageErrors>) -> bool {
    e.0.is_empty()
}
