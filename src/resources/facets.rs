//! Facets of the scene (resource `FacetStore`) and their BVH (obvhs CWBVH, f32, grid frame).

use crate::resources::materials::MaterialId;
use bevy_ecs::prelude::Resource;
use glam::DVec3;

/// What a facet belongs to (for budgets per element type).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub enum FacetKind {
    /// DEM ground.
    Ground,
    /// Tree trunk.
    Trunk,
    /// Building wall or floor.
    Wall,
    /// Building roof.
    Roof,
    /// Water surface.
    Water,
    /// Imported mesh.
    Mesh,
}

/// One triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Facet {
    /// Vertices (grid frame), metres; the front side is given by the right-hand rule.
    pub v: [DVec3; 3],
    /// Material.
    pub material: MaterialId,
    /// Source object index in the scene file.
    pub object: u32,
    /// Element type.
    pub kind: FacetKind,
    /// Both faces interact (leaves); otherwise only the front face does (DART 5 §3.1).
    pub two_sided: bool,
}

/// All facets of the scene.
#[derive(Debug, Clone, Default, Resource)]
pub struct FacetStore {
    /// Facets; the index is the facet id.
    pub facets: Vec<Facet>,
}

/// Bounding-volume hierarchy over the facets (absent when the scene has none).
#[derive(Resource)]
pub struct FacetBvh {
    /// The CWBVH.
    pub bvh: obvhs::cwbvh::CwBvh,
    /// f32 triangles in facet-id order, for intersection callbacks.
    pub triangles: Vec<obvhs::triangle::Triangle>,
}

impl FacetBvh {
    /// Closest hit along a ray (origin, unit direction, max distance): (facet id, distance).
    pub fn closest_hit(&self, origin: DVec3, dir: DVec3, t_max: f64) -> Option<(u32, f64)> {
        use obvhs::ray::{Ray, RayHit};
        let ray = Ray::new(
            origin.as_vec3().into(),
            dir.as_vec3().into(),
            0.0,
            t_max as f32,
        );
        let mut hit = RayHit::none();
        let tris = &self.triangles;
        let prim = &self.bvh.primitive_indices;
        if self
            .bvh
            .ray_traverse(ray, &mut hit, |r, id| tris[prim[id] as usize].intersect(r))
        {
            Some((prim[hit.primitive_id as usize], hit.t as f64))
        } else {
            None
        }
    }
}
