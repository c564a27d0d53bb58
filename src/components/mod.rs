//! Components: plain data on scene entities. Each scene object of the RON file becomes one or
//! more entities carrying these; Maket systems read them to build the cell grid and facets.

use crate::geometry::crown::CrownGeom;
use crate::geometry::shapes::Roof;
use crate::resources::materials::MaterialId;
use bevy_ecs::prelude::Component;
use glam::{DVec2, DVec3};

/// Which object of the scene file an entity came from (index into `objects`), for reports and
/// error messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Component)]
pub struct SourceObject(pub u32);

/// The ground (at most one entity). Its shape is the [`crate::resources::scene::TerrainRes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Component)]
pub struct Ground {
    /// Facet material of the ground.
    pub optics: MaterialId,
}

/// A turbid tree crown placed in the grid frame.
#[derive(Debug, Clone, PartialEq, Component)]
pub struct TurbidCrown {
    /// Shape, placement and density.
    pub geom: CrownGeom,
    /// Turbid material.
    pub material: MaterialId,
}

/// A tree trunk: a closed prism of facets.
#[derive(Debug, Clone, Copy, PartialEq, Component)]
pub struct Trunk {
    /// Centre of the trunk base (grid frame), metres.
    pub base: DVec3,
    /// Height, metres.
    pub height: f64,
    /// Diameter, metres.
    pub diameter: f64,
    /// Number of prism sides.
    pub sides: u32,
    /// Facet material.
    pub material: MaterialId,
}

/// A turbid plot following the terrain.
#[derive(Debug, Clone, PartialEq, Component)]
pub struct TurbidPlot {
    /// Anticlockwise footprint polygon, metres.
    pub footprint: Vec<DVec2>,
    /// Bottom and top above the local ground, metres.
    pub bottom: f64,
    /// Top above the local ground, metres.
    pub top: f64,
    /// Leaf area density, m² m⁻³.
    pub density: f64,
    /// Turbid material.
    pub material: MaterialId,
}

impl TurbidPlot {
    /// Horizontal bounding box of the footprint: (min corner, max corner), metres.
    pub fn footprint_bounds(&self) -> (DVec2, DVec2) {
        self.footprint
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            })
    }
}

/// A building.
#[derive(Debug, Clone, PartialEq, Component)]
pub struct Building {
    /// Anticlockwise footprint, metres.
    pub footprint: Vec<DVec2>,
    /// Altitude of the floor (grid frame), metres.
    pub base_z: f64,
    /// Wall height, metres.
    pub wall_height: f64,
    /// Roof.
    pub roof: Roof,
    /// Wall material.
    pub wall_material: MaterialId,
    /// Roof material.
    pub roof_material: MaterialId,
}

/// A water body.
#[derive(Debug, Clone, PartialEq, Component)]
pub struct WaterBody {
    /// Anticlockwise footprint, metres.
    pub footprint: Vec<DVec2>,
    /// Surface altitude (grid frame), metres.
    pub altitude: f64,
    /// Facet material.
    pub material: MaterialId,
}

/// One group of an imported mesh, already transformed into the grid frame.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshPart {
    /// Group name in the file.
    pub name: String,
    /// Triangles, metres.
    pub triangles: Vec<[DVec3; 3]>,
    /// Material (a turbid material when `as_turbid`).
    pub material: MaterialId,
    /// Both faces interact.
    pub two_sided: bool,
    /// Converted to turbid cells by Maket.
    pub as_turbid: bool,
}

/// An imported mesh.
#[derive(Debug, Clone, PartialEq, Component)]
pub struct ImportedMesh {
    /// Source file.
    pub path: std::path::PathBuf,
    /// Groups.
    pub parts: Vec<MeshPart>,
}

pub use crate::geometry::shapes::Roof as RoofShape;
