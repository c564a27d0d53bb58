//! Maket: the report of what the grid holds (`maket.json`): leaf area per material, analytic
//! against rasterised (the conservation check), facets per material and kind, occupied cells,
//! memory estimated and used, warnings.

use super::TurbidObjects;
use crate::geometry::triangle::area;
use crate::resources::facets::{Facet, FacetBvh, FacetStore};
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::maket_report::{MaketReport, MemoryEstimate};
use crate::resources::materials::Materials;
use crate::resources::scene::Warnings;

/// The Maket report: leaf area per material (analytic and rasterised), facet counts and areas,
/// occupied cells, memory estimate and use (also used by `check` before rasterisation).
#[allow(clippy::too_many_arguments)]
pub fn make_report(
    spec: &GridSpec,
    est: &MemoryEstimate,
    mats: &Materials,
    facets: &FacetStore,
    grid: Option<&CellGrid>,
    bvh: Option<&FacetBvh>,
    objects: &TurbidObjects,
    warnings: &Warnings,
) -> MaketReport {
    let mut r = MaketReport {
        cells: spec.n,
        cell_m: spec.cell.to_array(),
        z_range_m: [spec.origin.z, spec.top()],
        n_cells: spec.n_cells() as u64,
        topography_offset_m: spec.topography_offset,
        memory: est.clone(),
        warnings: warnings.0.clone(),
        ..Default::default()
    };
    let TurbidObjects {
        crowns,
        plots,
        meshes,
    } = objects;
    let name = |m: u32| mats.list[m as usize].name.clone();
    for c in crowns.iter() {
        r.leaf_area.entry(name(c.material)).or_default().analytic_m2 += c.geom.leaf_area();
    }
    for p in plots.iter() {
        let a = crate::geometry::polygon::signed_area(&p.footprint).abs();
        r.leaf_area.entry(name(p.material)).or_default().analytic_m2 +=
            p.density * a * (p.top - p.bottom);
    }
    for m in meshes.iter() {
        for part in m.parts.iter().filter(|p| p.as_turbid) {
            r.leaf_area
                .entry(name(part.material))
                .or_default()
                .analytic_m2 += part.triangles.iter().map(area).sum::<f64>();
        }
    }
    for f in &facets.facets {
        *r.facet_count.entry(name(f.material)).or_default() += 1;
        *r.facet_area_m2.entry(name(f.material)).or_default() += area(&f.v);
        *r.facet_area_by_kind_m2
            .entry(format!("{:?}", f.kind))
            .or_default() += area(&f.v);
    }
    if let Some(g) = grid {
        let vol = spec.cell_volume();
        for e in &g.turbid {
            let la = r.leaf_area.entry(name(e.material)).or_default();
            *la.rasterised_m2.get_or_insert(0.0) += e.density as f64 * vol;
        }
        let n = spec.n_cells();
        r.turbid_cells = Some(
            (0..n)
                .filter(|&c| g.turbid_start[c + 1] > g.turbid_start[c])
                .count() as u64,
        );
        if !g.facet_start.is_empty() {
            r.facet_cells = Some(
                (0..n)
                    .filter(|&c| g.facet_start[c + 1] > g.facet_start[c])
                    .count() as u64,
            );
        }
        let bvh_bytes = bvh.map_or(0, |b| {
            b.triangles.len() * 36
                + b.bvh.nodes.len() * std::mem::size_of_val(&b.bvh.nodes[0])
                + b.bvh.primitive_indices.len() * 4
        });
        r.memory_used_bytes = Some(
            (g.bytes() + facets.facets.len() * std::mem::size_of::<Facet>() + bvh_bytes) as u64,
        );
    }
    r
}
