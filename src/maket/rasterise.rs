//! Maket: turbid media → per-cell leaf area density with exact leaf-area conservation, and
//! facets → cells (DART 5 paper §2, "Maket"; physics.md §5). Crowns: analytic ellipse-ring ∩
//! rectangle areas integrated over z by adaptive Gauss–Legendre; plots: exact polygon clipping ×
//! layer thickness, following the terrain; meshes converted to turbid: exact triangle ∩ box
//! clipping; facets: the exact separating-axis triangle–box test.

use super::TurbidObjects;
use crate::components::*;
use crate::geometry::terrain::Terrain;
use crate::geometry::triangle::{clip_to_box, is_degenerate, overlaps_box, polygon_area};
use crate::resources::facets::{FacetBvh, FacetStore};
use crate::resources::grid::{CellGrid, GridSpec, TurbidEntry, compress};
use crate::scene::desc::BoundaryMode;
use glam::DVec3;
use rayon::prelude::*;

/// Splits a triangle crossing the side of a repetitive scene into pieces translated back
/// inside `[0, sx] × [0, sy]` (exact: areas are kept).
pub fn wrap_triangle(t: [DVec3; 3], sx: f64, sy: f64, out: &mut Vec<[DVec3; 3]>) {
    let lo = t[0].min(t[1]).min(t[2]);
    let hi = t[0].max(t[1]).max(t[2]);
    if lo.x >= 0.0 && lo.y >= 0.0 && hi.x <= sx && hi.y <= sy {
        out.push(t);
        return;
    }
    for di in -1..=1 {
        for dj in -1..=1 {
            let shift = DVec3::new(di as f64 * sx, dj as f64 * sy, 0.0);
            let tt = [t[0] + shift, t[1] + shift, t[2] + shift];
            let poly = clip_to_box(&tt, DVec3::new(0.0, 0.0, -1e300), DVec3::new(sx, sy, 1e300));
            for k in 1..poly.len().saturating_sub(1) {
                let piece = [poly[0], poly[k], poly[k + 1]];
                if !is_degenerate(&piece) {
                    out.push(piece);
                }
            }
        }
    }
}

/// Cell-index range `[a, b)` covering the interval `[lo, hi]` along an axis.
pub fn cell_range(lo: f64, hi: f64, origin: f64, d: f64) -> (i64, i64) {
    let a = ((lo - origin) / d).floor() as i64;
    let b = ((hi - origin) / d).ceil() as i64;
    // Saturating: a coordinate beyond ±9.2e18 cells saturates the casts (the plan then
    // refuses the grid as over the memory limit).
    (a, b.max(a.saturating_add(1)))
}

/// Leaf area (m²) of one turbid object per cell, as (cell index, material, leaf area) triples.
type Triples = Vec<(u32, u32, f64)>;

fn rasterise_crown(c: &TurbidCrown, g: &GridSpec) -> Triples {
    let b = c.geom.bounds();
    let (i0, i1) = cell_range(b[0], b[3], g.origin.x, g.cell.x);
    let (j0, j1) = cell_range(b[1], b[4], g.origin.y, g.cell.y);
    let (k0, k1) = cell_range(b[2], b[5], g.origin.z, g.cell.z);
    let mut out = Vec::new();
    for k in k0.max(0)..k1.min(g.n[2] as i64) {
        for j in j0..j1 {
            let Some(jw) = g.wrap(j, 1) else { continue };
            for i in i0..i1 {
                let Some(iw) = g.wrap(i, 0) else { continue };
                let (lo, hi) = g.cell_box(i, j, k);
                let la = c
                    .geom
                    .leaf_area_in_box([lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]);
                if la > 0.0 {
                    out.push((g.index(iw, jw, k as usize) as u32, c.material, la));
                }
            }
        }
    }
    out
}

fn rasterise_plot(p: &TurbidPlot, g: &GridSpec, terrain: &Terrain) -> Triples {
    let (lo, hi) = p.footprint_bounds();
    let (i0, i1) = cell_range(lo.x, hi.x, g.origin.x, g.cell.x);
    let (j0, j1) = cell_range(lo.y, hi.y, g.origin.y, g.cell.y);
    let mut out = Vec::new();
    for j in j0..j1 {
        let Some(jw) = g.wrap(j, 1) else { continue };
        for i in i0..i1 {
            let Some(iw) = g.wrap(i, 0) else { continue };
            let (clo, chi) = g.cell_box(i, j, 0);
            let clipped =
                crate::geometry::polygon::clip_to_rect(&p.footprint, clo.x, clo.y, chi.x, chi.y);
            let a = crate::geometry::polygon::signed_area(&clipped).abs();
            if a <= 0.0 {
                continue;
            }
            // The layer follows the terrain: its base is the ground under the clipped part's centroid.
            let centroid =
                clipped.iter().fold(glam::DVec2::ZERO, |s, v| s + *v) / clipped.len() as f64;
            let gz = terrain.height(
                centroid.x.rem_euclid(g.n[0] as f64 * g.cell.x),
                centroid.y.rem_euclid(g.n[1] as f64 * g.cell.y),
            );
            let (za, zb) = (gz + p.bottom, gz + p.top);
            let (k0, k1) = cell_range(za, zb, g.origin.z, g.cell.z);
            for k in k0.max(0)..k1.min(g.n[2] as i64) {
                let cz0 = g.origin.z + k as f64 * g.cell.z;
                let dzk = (zb.min(cz0 + g.cell.z) - za.max(cz0)).max(0.0);
                if dzk > 0.0 {
                    out.push((
                        g.index(iw, jw, k as usize) as u32,
                        p.material,
                        p.density * a * dzk,
                    ));
                }
            }
        }
    }
    out
}

fn rasterise_mesh_part(part: &MeshPart, g: &GridSpec) -> Triples {
    let mut out = Vec::new();
    let (sx, sy) = (g.n[0] as f64 * g.cell.x, g.n[1] as f64 * g.cell.y);
    let mut pieces = Vec::new();
    for t in &part.triangles {
        pieces.clear();
        if g.boundary == BoundaryMode::Isolated {
            pieces.push(*t);
        } else {
            wrap_triangle(*t, sx, sy, &mut pieces);
        }
        for p in &pieces {
            let lo = p[0].min(p[1]).min(p[2]);
            let hi = p[0].max(p[1]).max(p[2]);
            let (i0, i1) = cell_range(lo.x, hi.x, g.origin.x, g.cell.x);
            let (j0, j1) = cell_range(lo.y, hi.y, g.origin.y, g.cell.y);
            let (k0, k1) = cell_range(lo.z, hi.z, g.origin.z, g.cell.z);
            for k in k0.max(0)..k1.min(g.n[2] as i64) {
                for j in j0.max(0)..j1.min(g.n[1] as i64) {
                    for i in i0.max(0)..i1.min(g.n[0] as i64) {
                        let (blo, bhi) = g.cell_box(i, j, k);
                        let a = polygon_area(&clip_to_box(p, blo, bhi));
                        if a > 0.0 {
                            out.push((
                                g.index(i as usize, j as usize, k as usize) as u32,
                                part.material,
                                a,
                            ));
                        }
                    }
                }
            }
        }
    }
    out
}

/// Turbid objects → the turbid part of the cell grid. Leaf area is conserved: each object's leaf area is split among
/// cells by exact overlap (crowns: analytic cross-sections + adaptive quadrature; plots: exact
/// polygon clipping; meshes: exact triangle clipping), so Σ density × volume = analytic area.
pub fn rasterise_turbid(
    g: &GridSpec,
    terrain: &Terrain,
    progress: bool,
    objects: &TurbidObjects,
) -> CellGrid {
    let TurbidObjects {
        crowns: crown_list,
        plots,
        meshes,
    } = objects;
    let bar = crate::io::progress::progress_bar(
        progress,
        crown_list.len() as u64,
        "Maket: rasterising crowns",
    );
    let mut triples: Triples = crown_list
        .par_iter()
        .flat_map_iter(|c| {
            let t = rasterise_crown(c, g);
            bar.inc(1);
            t
        })
        .collect();
    bar.finish_and_clear();
    for p in plots {
        triples.extend(rasterise_plot(p, g, terrain));
    }
    for m in meshes {
        for part in m.parts.iter().filter(|p| p.as_turbid) {
            triples.extend(rasterise_mesh_part(part, g));
        }
    }
    // Merge per (cell, material); sorting makes the result independent of thread scheduling.
    triples.par_sort_unstable_by(|a, b| (a.0, a.1).cmp(&(b.0, b.1)).then(a.2.total_cmp(&b.2)));
    let vol = g.cell_volume();
    let mut merged: Vec<(u32, TurbidEntry)> = Vec::new();
    let mut k = 0;
    while k < triples.len() {
        let (c, m) = (triples[k].0, triples[k].1);
        let mut sum = 0.0;
        while k < triples.len() && triples[k].0 == c && triples[k].1 == m {
            sum += triples[k].2;
            k += 1;
        }
        merged.push((
            c,
            TurbidEntry {
                material: m,
                density: (sum / vol) as f32,
            },
        ));
    }
    let (turbid_start, turbid) = compress(g.n_cells(), &merged);
    CellGrid {
        turbid_start,
        turbid,
        facet_start: Vec::new(),
        facet_ids: Vec::new(),
    }
}

/// The facet part of the cell grid (row starts, facet ids): each facet is listed in
/// every cell its triangle overlaps (exact separating-axis test; a facet lying in a cell face
/// is listed in both cells).
pub fn assign_facets_to_cells(g: &GridSpec, facets: &FacetStore) -> (Vec<u32>, Vec<u32>) {
    let mut pairs: Vec<(u32, u32)> = facets
        .facets
        .par_iter()
        .enumerate()
        .flat_map_iter(|(id, f)| {
            let lo = f.v[0].min(f.v[1]).min(f.v[2]);
            let hi = f.v[0].max(f.v[1]).max(f.v[2]);
            let (i0, i1) = cell_range(lo.x, hi.x, g.origin.x, g.cell.x);
            let (j0, j1) = cell_range(lo.y, hi.y, g.origin.y, g.cell.y);
            let (k0, k1) = cell_range(lo.z, hi.z, g.origin.z, g.cell.z);
            let mut out = Vec::new();
            // Include the neighbour cells when a vertex lies exactly on a cell boundary.
            for k in (k0 - 1).max(0)..(k1 + 1).min(g.n[2] as i64) {
                for j in (j0 - 1).max(0)..(j1 + 1).min(g.n[1] as i64) {
                    for i in (i0 - 1).max(0)..(i1 + 1).min(g.n[0] as i64) {
                        let (blo, bhi) = g.cell_box(i, j, k);
                        if overlaps_box(&f.v, blo, bhi) {
                            out.push((
                                g.index(i as usize, j as usize, k as usize) as u32,
                                id as u32,
                            ));
                        }
                    }
                }
            }
            out
        })
        .collect();
    pairs.par_sort_unstable();
    compress(g.n_cells(), &pairs)
}

/// The BVH of the facets (obvhs compressed-wide BVH, medium build), in grid-origin coordinates;
/// `None` when the scene has no facets.
pub fn build_facet_bvh(spec: &GridSpec, facets: &FacetStore) -> Option<FacetBvh> {
    if facets.facets.is_empty() {
        return None;
    }
    let o = spec.origin;
    let triangles: Vec<obvhs::triangle::Triangle> = facets
        .facets
        .iter()
        .map(|f| obvhs::triangle::Triangle {
            v0: (f.v[0] - o).as_vec3().into(),
            v1: (f.v[1] - o).as_vec3().into(),
            v2: (f.v[2] - o).as_vec3().into(),
        })
        .collect();
    let mut t = std::time::Duration::ZERO;
    let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
        &triangles,
        obvhs::BvhBuildParams::medium_build(),
        &mut t,
    );
    Some(FacetBvh { bvh, triangles })
}
