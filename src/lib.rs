//! # lumenscape
//!
//! A 3D radiative-transfer simulator for optical remote sensing, re-implementing DART 5
//! (Gastellu-Etchegorry et al. 2015, *Remote Sens.* 7:1667). Scenes (trees, turbid plots,
//! buildings, water, DEM terrain, imported meshes) are written in RON or built by generators,
//! spawned as bevy_ecs entities, and processed by stages in DART order.
//!
//! ```no_run
//! use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
//! use lumenscape::scene::SceneSource;
//! use lumenscape::simulation::{Simulation, Stage};
//! use lumenscape::resources::{maket_report::MaketReport, scene::RunSettings};
//!
//! // A horizontally homogeneous turbid canopy (LAI 3, spherical LAD) on a periodic scene.
//! let desc = turbid_layer(&TurbidLayerParams::default());
//! let mut sim = Simulation::from_desc(&desc, &SceneSource::generated(), RunSettings::default())?;
//! sim.run_stage(Stage::Maket)?;
//! let report = sim.resource::<MaketReport>();
//! for (material, la) in &report.leaf_area {
//!     println!("{material}: {:.3} m² of leaves", la.rasterised_m2.unwrap_or(0.0));
//! }
//! // Save what was generated as RON, to edit or diff it:
//! std::fs::write("layer.ron", lumenscape::scene::to_ron(&desc))?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod cli;
pub mod components;
pub mod direction;
pub mod geometry;
pub mod io;
pub mod lidar;
pub mod maket;
pub mod memory;
pub mod output;
pub mod phase;
pub mod photon;
pub mod physics;
pub mod radiative;
pub mod random;
pub mod resources;
pub mod scene;
pub mod sequence;
pub mod simulation;
#[path = "../systems/mod.rs"]
pub mod systems;
