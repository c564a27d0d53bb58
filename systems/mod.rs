//! The DART modules as ECS stages. This folder lives outside `src/` but in the same crate
//! (`#[path]` in `lib.rs`); only `src/simulation.rs` imports it.
//!
//! Stages that exist so far: Maket (scene → cell grid) and Output (Maket products). Direction,
//! Phase, Radiative, Photon and Sensor have schedule labels and run conditions but no systems
//! yet (see the open issues); a scene never silently gets results from them.

pub mod direction;
pub mod lidar;
pub mod maket;
pub mod output;
pub mod phase;
pub mod photon;
pub mod radiative;
