//! The Maket engine (DART 5 paper §2, "Maket" module): scene objects → the cell grid the
//! trackers walk. Plain functions over components and resources (the ECS glue that calls them is
//! `systems/maket.rs`), in physical order: [`facets`] (objects → triangles), [`plan`] (grid
//! extent and memory estimate before any allocation), [`rasterise`] (turbid media → leaf area
//! density per cell with exact conservation; facets → cells; the facet BVH), [`report`].

pub mod facets;
pub mod plan;
pub mod rasterise;
pub mod report;

use crate::components::{ImportedMesh, TurbidCrown, TurbidPlot};

/// The turbid objects of a scene (crowns, plots, meshes whose parts are converted to turbid).
pub struct TurbidObjects<'a> {
    /// Tree crowns.
    pub crowns: Vec<&'a TurbidCrown>,
    /// Turbid plots.
    pub plots: Vec<&'a TurbidPlot>,
    /// Imported meshes (their `as_turbid` parts).
    pub meshes: Vec<&'a ImportedMesh>,
}
