//! Maket: facet objects (DEM ground, trunks, buildings, water, imported meshes) → the scene's
//! triangle list (DART 5 paper §2, "Maket"; physics.md §5). Flat ground is not tiled: the
//! trackers treat it as the exact plane z = z0.

use super::rasterise::wrap_triangle;
use crate::components::*;
use crate::geometry::shapes::{building_shell, horizontal_polygon, trunk_prism};
use crate::geometry::terrain::Terrain;
use crate::geometry::triangle::is_degenerate;
use crate::resources::facets::{Facet, FacetKind, FacetStore};
use crate::resources::scene::SceneInfo;
use crate::scene::desc::BoundaryMode;
use glam::DVec3;

/// The facet objects of a scene, each with the index of the scene object it came from.
pub struct FacetObjects<'a> {
    /// DEM grounds.
    pub grounds: Vec<(&'a SourceObject, &'a Ground)>,
    /// Tree trunks.
    pub trunks: Vec<(&'a SourceObject, &'a Trunk)>,
    /// Buildings (walls and roofs).
    pub buildings: Vec<(&'a SourceObject, &'a Building)>,
    /// Water surfaces.
    pub waters: Vec<(&'a SourceObject, &'a WaterBody)>,
    /// Imported meshes (their facet parts).
    pub meshes: Vec<(&'a SourceObject, &'a ImportedMesh)>,
}

/// Every facet object → triangles (Maket: ground, trunks, buildings, water, mesh facets).
/// Degenerate triangles are skipped (a warning counts them); on repetitive scenes a triangle
/// crossing a side is wrapped back inside (areas kept). Objects whose footprint cannot be
/// triangulated are reported in `errors`.
pub fn build_facets(
    info: &SceneInfo,
    terrain: &Terrain,
    objects: &FacetObjects,
    warnings: &mut Vec<String>,
    errors: &mut Vec<String>,
) -> FacetStore {
    let FacetObjects {
        grounds,
        trunks,
        buildings,
        waters,
        meshes,
    } = objects;
    let (sx, sy) = info.size;
    let periodic = info.boundary != BoundaryMode::Isolated;
    let mut facets = Vec::new();
    let mut degenerate = 0usize;
    let mut push =
        |tris: Vec<[DVec3; 3]>, material, object, kind, two_sided, facets: &mut Vec<Facet>| {
            let mut pieces = Vec::with_capacity(tris.len());
            for t in tris {
                if is_degenerate(&t) {
                    degenerate += 1;
                    continue;
                }
                if periodic {
                    wrap_triangle(t, sx, sy, &mut pieces);
                } else {
                    pieces.push(t);
                }
            }
            facets.extend(pieces.into_iter().map(|v| Facet {
                v,
                material,
                object,
                kind,
                two_sided,
            }));
        };
    for (o, g) in grounds {
        push(
            terrain.triangles(sx, sy),
            g.optics,
            o.0,
            FacetKind::Ground,
            false,
            &mut facets,
        );
    }
    for (o, t) in trunks {
        push(
            trunk_prism(t.base, t.height, t.diameter, t.sides),
            t.material,
            o.0,
            FacetKind::Trunk,
            false,
            &mut facets,
        );
    }
    for (o, b) in buildings {
        match building_shell(&b.footprint, b.base_z, b.wall_height, b.roof) {
            Some((walls, roof)) => {
                push(
                    walls,
                    b.wall_material,
                    o.0,
                    FacetKind::Wall,
                    false,
                    &mut facets,
                );
                push(
                    roof,
                    b.roof_material,
                    o.0,
                    FacetKind::Roof,
                    false,
                    &mut facets,
                );
            }
            None => errors.push(format!(
                "objects[{}]: the building footprint cannot be triangulated",
                o.0
            )),
        }
    }
    for (o, w) in waters {
        match horizontal_polygon(&w.footprint, w.altitude) {
            Some(t) => push(t, w.material, o.0, FacetKind::Water, false, &mut facets),
            None => errors.push(format!(
                "objects[{}]: the water footprint cannot be triangulated",
                o.0
            )),
        }
    }
    for (o, m) in meshes {
        for p in m.parts.iter().filter(|p| !p.as_turbid) {
            push(
                p.triangles.clone(),
                p.material,
                o.0,
                FacetKind::Mesh,
                p.two_sided,
                &mut facets,
            );
        }
    }
    if degenerate > 0 {
        warnings.push(format!("skipped {degenerate} degenerate facets"));
    }
    FacetStore { facets }
}
