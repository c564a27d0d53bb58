//! Maket: the grid's extent (z0 = the lowest ground or object point, the top, the cell counts,
//! the continuous-topography edge offsets) and the memory estimate, computed from bounding boxes
//! before anything is allocated (checked against `--max-memory`).

use super::TurbidObjects;
use super::rasterise::cell_range;
use crate::components::*;
use crate::geometry::terrain::Terrain;
use crate::resources::facets::{Facet, FacetStore};
use crate::resources::grid::GridSpec;
use crate::resources::maket_report::MemoryEstimate;
use crate::resources::scene::SceneInfo;
use crate::scene::desc::BoundaryMode;
use crate::scene::validate::num;
use glam::DVec3;

/// The planned grid.
pub struct GridPlan {
    /// Grid extent and cells.
    pub spec: GridSpec,
    /// Memory estimate.
    pub est: MemoryEstimate,
    /// The refusal message when the estimate exceeds the memory limit.
    pub over_limit: Option<String>,
}

fn turbid_bounds(
    crowns: &[&TurbidCrown],
    plots: &[&TurbidPlot],
    meshes: &[&ImportedMesh],
    terrain: &Terrain,
) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for c in crowns {
        lo = lo.min(c.geom.z_base);
        hi = hi.max(c.geom.z_base + c.geom.height);
    }
    for p in plots {
        for v in &p.footprint {
            let g = terrain.height(v.x, v.y);
            lo = lo.min(g + p.bottom);
            hi = hi.max(g + p.top);
        }
    }
    for m in meshes {
        for v in m
            .parts
            .iter()
            .filter(|p| p.as_turbid)
            .flat_map(|p| p.triangles.iter().flatten())
        {
            lo = lo.min(v.z);
            hi = hi.max(v.z);
        }
    }
    (lo, hi)
}

/// The grid's extent and the memory estimate (upper bounds from bounding boxes), before any
/// allocation. `Err` when the objects reach above the scene's height; otherwise the plan, with
/// `over_limit` set when the estimate exceeds `max_memory_bytes` (`--max-memory`).
pub fn plan_grid(
    info: &SceneInfo,
    terrain: &Terrain,
    facets: &FacetStore,
    max_memory_bytes: u64,
    objects: &TurbidObjects,
) -> Result<GridPlan, String> {
    let (sx, sy) = info.size;
    let (dx, dy, dz) = info.cell;
    let (z0, top) = z_extent(info, terrain, facets, objects)?;
    let nf = cell_counts(info, z0, top)?;
    let n = nf.map(|x| x as usize);
    let topography_offset = if info.boundary == BoundaryMode::RepetitiveContinuousTopography {
        terrain.edge_offsets(sx, sy)
    } else {
        (0.0, 0.0)
    };
    let spec = GridSpec {
        n,
        cell: DVec3::new(dx, dy, dz),
        origin: DVec3::new(0.0, 0.0, z0),
        subcells: info.subcells,
        boundary: info.boundary,
        topography_offset,
    };
    let est = memory_estimate(info, &spec, top, terrain, facets, max_memory_bytes, objects);
    let peak = est.peak_bytes;
    let over_limit = (peak > max_memory_bytes).then(|| {
        format!(
            "{}: the grid of {} × {} × {} cells needs an estimated {:.2} GiB, above the limit of {:.2} GiB (--max-memory): use larger cells or a smaller scene",
            info.source.display(),
            n[0],
            n[1],
            n[2],
            peak as f64 / (1u64 << 30) as f64,
            max_memory_bytes as f64 / (1u64 << 30) as f64
        )
    });
    Ok(GridPlan {
        spec,
        est,
        over_limit,
    })
}

/// Step of [`plan_grid`]: the grid's vertical extent `(z0, top)` — z0 the lowest ground, turbid
/// or facet point (0 when there is none), top the highest object point but at least one cell
/// above z0. `Err` when the top is not finite.
fn z_extent(
    info: &SceneInfo,
    terrain: &Terrain,
    facets: &FacetStore,
    objects: &TurbidObjects,
) -> Result<(f64, f64), String> {
    let TurbidObjects {
        crowns,
        plots,
        meshes,
    } = objects;
    let (sx, sy) = info.size;
    let dz = info.cell.2;
    let ground_lo = match terrain {
        Terrain::Flat(z) => *z,
        t => t
            .triangles(sx, sy)
            .iter()
            .flatten()
            .map(|v| v.z)
            .fold(f64::INFINITY, f64::min),
    };
    let (tl, th) = turbid_bounds(crowns, plots, meshes, terrain);
    let (fl, fh) = facets
        .facets
        .iter()
        .flat_map(|f| f.v)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v.z), b.max(v.z))
        });
    let z0 = ground_lo.min(tl).min(fl);
    let z0 = if z0.is_finite() { z0 } else { 0.0 };
    let top = th.max(fh).max(z0 + dz);
    if !top.is_finite() {
        return Err(format!(
            "{}: the objects reach z = {top} m: no grid can hold them (check heights, altitudes and mesh scales)",
            info.source.display()
        ));
    }
    Ok((z0, top))
}

/// Step of [`plan_grid`]: the cell counts (x, y, z) in floating point, from the scene size, the
/// cell size and the scene height (or the objects' top). `Err` when the objects reach above the
/// scene height or the grid would exceed `MAX_GRID_CELLS`.
fn cell_counts(info: &SceneInfo, z0: f64, top: f64) -> Result<[f64; 3], String> {
    let (sx, sy) = info.size;
    let (dx, dy, dz) = info.cell;
    // Cell counts in floating point first: an `as usize` cast saturates, and the products of
    // saturated counts overflow (a 2 × 1e308 m scene planned "5.8 KiB").
    let nz = match info.height {
        Some(h) => {
            if top > z0 + h + 1e-9 {
                return Err(format!(
                    "{}: grid.height_m: objects reach {:.3} m above the lowest point, above the scene height {h} m",
                    info.source.display(),
                    top - z0
                ));
            }
            (h / dz).ceil().max(1.0)
        }
        None => (((top - z0) / dz) - 1e-9).ceil().max(1.0),
    };
    let nf = [(sx / dx).round().max(1.0), (sy / dy).round().max(1.0), nz];
    let max_cells = crate::scene::validate::MAX_GRID_CELLS;
    if nf[0] * nf[1] * nf[2] > max_cells as f64 {
        let field = if info.height.is_some() {
            "grid.height_m"
        } else {
            "grid.cell_m"
        };
        return Err(format!(
            "{}: {field}: the grid would have {} × {} × {} = {:.3e} cells (objects from z = {} to {} m in cells of {} × {} × {} m), above the limit of {max_cells} cells: use larger cells or a smaller scene",
            info.source.display(),
            num(nf[0]),
            num(nf[1]),
            num(nf[2]),
            nf[0] * nf[1] * nf[2],
            num(z0),
            num(top),
            num(dx),
            num(dy),
            num(dz)
        ));
    }
    Ok(nf)
}

/// Step of [`plan_grid`]: the memory estimate of the grid `spec` whose objects reach up to
/// `top`: turbid entries counted as the cells each crown's volume meets ([`crown_cells`]) and
/// the bounding-box cells of plots and turbid mesh triangles (upper bounds: entries of one
/// material in one cell merge); facet–cell references counted with the assignment's own
/// triangle–box test ([`facet_cells`]).
fn memory_estimate(
    info: &SceneInfo,
    spec: &GridSpec,
    top: f64,
    terrain: &Terrain,
    facets: &FacetStore,
    max_memory_bytes: u64,
    objects: &TurbidObjects,
) -> MemoryEstimate {
    let TurbidObjects {
        crowns,
        plots,
        meshes,
    } = objects;
    let (dx, dy, dz) = info.cell;
    let z0 = spec.origin.z;
    // Saturating arithmetic: an estimate that saturates exceeds any memory limit and is
    // refused by the caller, instead of wrapping to a small number.
    let n_cells = spec.n_cells() as u64;
    let bbox_cells = |lo: DVec3, hi: DVec3| -> u64 {
        let (a, b) = cell_range(lo.x, hi.x, 0.0, dx);
        let (c, d) = cell_range(lo.y, hi.y, 0.0, dy);
        let (e, f) = cell_range(lo.z, hi.z, z0, dz);
        let span = |a: i64, b: i64| b.saturating_sub(a).max(0) as u64;
        span(a, b)
            .saturating_mul(span(c, d))
            .saturating_mul(span(e, f))
    };
    // Crowns of one material that share a cell make one entry: cells marked per material in
    // a bit set (1 bit per cell and material) when that stays small, else counted per crown.
    let mut turbid_max = 0u64;
    let mut materials: Vec<u32> = crowns.iter().map(|c| c.material).collect();
    materials.sort_unstable();
    materials.dedup();
    let words = spec.n_cells().div_ceil(64);
    if words.saturating_mul(materials.len()) <= 1 << 23 {
        for m in &materials {
            let mut bits = vec![0u64; words];
            for c in crowns.iter().filter(|c| c.material == *m) {
                let n = crown_cells(&c.geom, spec, |i| bits[i / 64] |= 1 << (i % 64));
                if n == u64::MAX {
                    turbid_max = u64::MAX;
                }
            }
            let set: u64 = bits.iter().map(|w| w.count_ones() as u64).sum();
            turbid_max = turbid_max.saturating_add(set);
        }
    } else {
        for c in crowns.iter() {
            turbid_max = turbid_max.saturating_add(crown_cells(&c.geom, spec, |_| {}));
        }
    }
    for p in plots.iter() {
        // The layer follows the terrain: from the lowest ground under its footprint's vertices
        // plus its bottom to the highest plus its top (within the grid).
        let (lo, hi) = p.footprint_bounds();
        let (g_lo, g_hi) = p
            .footprint
            .iter()
            .map(|v| terrain.height(v.x, v.y))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), g| {
                (a.min(g), b.max(g))
            });
        let (za, zb) = if g_lo.is_finite() && g_hi.is_finite() {
            ((g_lo + p.bottom).max(z0), (g_hi + p.top).min(top))
        } else {
            (z0, top)
        };
        turbid_max = turbid_max.saturating_add(bbox_cells(lo.extend(za), hi.extend(zb.max(za))));
    }
    for m in meshes.iter() {
        for t in m
            .parts
            .iter()
            .filter(|p| p.as_turbid)
            .flat_map(|p| &p.triangles)
        {
            turbid_max = turbid_max.saturating_add(bbox_cells(
                t[0].min(t[1]).min(t[2]),
                t[0].max(t[1]).max(t[2]),
            ));
        }
    }
    let refs_max: u64 = facets
        .facets
        .iter()
        .map(|f| facet_cells(&f.v, spec))
        .fold(0u64, u64::saturating_add);
    let n_facets = facets.facets.len() as u64;
    let cell_index_bytes = 8 * (n_cells + 1);
    let facet_bytes = n_facets.saturating_mul(std::mem::size_of::<Facet>() as u64 + 36 + 64);
    // Build buffers: (cell, material, area) triples of 16 B and (cell, facet) pairs of 8 B.
    let peak = cell_index_bytes
        .saturating_add(turbid_max.saturating_mul(8 + 16))
        .saturating_add(refs_max.saturating_mul(4 + 8))
        .saturating_add(facet_bytes);
    MemoryEstimate {
        cell_index_bytes,
        turbid_entries_max: turbid_max,
        facet_refs_max: refs_max,
        facet_bytes,
        peak_bytes: peak,
        limit_bytes: max_memory_bytes,
    }
}

/// Cells of `g` whose box meets the crown's volume (the cells its rasterisation can give leaf
/// area; wrapped in repetitive scenes, cut at the sides of isolated ones), counted without
/// allocating; `visit` gets each one's cell index. A crown over more than 2²⁷ bounding-box
/// cells is not visited cell by cell: `u64::MAX` (such a grid is over any memory limit). A cell box meets the crown when the box's horizontal rectangle meets the
/// crown's widest cross-section within the box's height range: the cross-sections are nested
/// ellipses about one axis, so that test is exact. 0 for a crown without leaves.
pub fn crown_cells(
    c: &crate::geometry::crown::CrownGeom,
    g: &GridSpec,
    mut visit: impl FnMut(usize),
) -> u64 {
    if !(c.u0 > 0.0) {
        return 0;
    }
    let b = c.bounds();
    let (i0, i1) = cell_range(b[0], b[3], g.origin.x, g.cell.x);
    let (j0, j1) = cell_range(b[1], b[4], g.origin.y, g.cell.y);
    let (k0, k1) = cell_range(b[2], b[5], g.origin.z, g.cell.z);
    if box_cells((i0, i1), (j0, j1), (k0, k1)) > COUNT_LIMIT {
        return u64::MAX;
    }
    let (zb, zt) = (c.z_base, c.z_base + c.height);
    let (rx, ry) = c.radius;
    if !(rx > 0.0 && ry > 0.0) {
        return 0;
    }
    let mut n = 0u64;
    for k in k0.max(0)..k1.min(g.n[2] as i64) {
        let (lo, hi) = g.cell_box(0, 0, k);
        let (za, zc) = (lo.z.max(zb), hi.z.min(zt));
        if zc <= za {
            continue;
        }
        // Largest relative radius over [za, zc]: s is unimodal (ellipsoid: widest at mid-height;
        // cone, trapezoid: at the base; cylinder: constant).
        let mid = zb + 0.5 * c.height;
        let mut s = c.s(za).max(c.s(zc));
        if (za..=zc).contains(&mid) {
            s = s.max(c.s(mid));
        }
        if c.shape == crate::geometry::crown::CrownShape::Cylinder {
            s = 1.0;
        }
        if !(s > 0.0) {
            continue;
        }
        for j in j0..j1 {
            let Some(jw) = g.wrap(j, 1) else {
                continue;
            };
            let y0 = g.origin.y + j as f64 * g.cell.y;
            let dy = (y0 - c.center.1).max(c.center.1 - (y0 + g.cell.y)).max(0.0) / ry;
            for i in i0..i1 {
                let Some(iw) = g.wrap(i, 0) else {
                    continue;
                };
                let x0 = g.origin.x + i as f64 * g.cell.x;
                let dx = (x0 - c.center.0).max(c.center.0 - (x0 + g.cell.x)).max(0.0) / rx;
                if dx * dx + dy * dy < s * s {
                    n += 1;
                    visit(g.index(iw, jw, k as usize));
                }
            }
        }
    }
    n
}

/// Cells of `g` a facet triangle `v` is listed in by the facet assignment (the same cells and
/// the same triangle–box test as [`super::rasterise::assign_facets_to_cells`]), counted
/// without allocating.
pub fn facet_cells(v: &[DVec3; 3], g: &GridSpec) -> u64 {
    let lo = v[0].min(v[1]).min(v[2]);
    let hi = v[0].max(v[1]).max(v[2]);
    let (i0, i1) = cell_range(lo.x, hi.x, g.origin.x, g.cell.x);
    let (j0, j1) = cell_range(lo.y, hi.y, g.origin.y, g.cell.y);
    let (k0, k1) = cell_range(lo.z, hi.z, g.origin.z, g.cell.z);
    if box_cells((i0, i1), (j0, j1), (k0, k1)) > COUNT_LIMIT {
        return box_cells((i0, i1), (j0, j1), (k0, k1));
    }
    let mut n = 0u64;
    for k in (k0.saturating_sub(1)).max(0)..(k1.saturating_add(1)).min(g.n[2] as i64) {
        for j in (j0.saturating_sub(1)).max(0)..(j1.saturating_add(1)).min(g.n[1] as i64) {
            for i in (i0.saturating_sub(1)).max(0)..(i1.saturating_add(1)).min(g.n[0] as i64) {
                let (blo, bhi) = g.cell_box(i, j, k);
                if crate::geometry::triangle::overlaps_box(v, blo, bhi) {
                    n += 1;
                }
            }
        }
    }
    n
}

/// Above this many bounding-box cells an object's cells are not counted one by one (the
/// bounding-box count is taken: such a grid is far above any memory limit anyway).
const COUNT_LIMIT: u64 = 1 << 27;

/// Cells of the index box `[i0, i1) × [j0, j1) × [k0, k1)` (saturating).
fn box_cells(i: (i64, i64), j: (i64, i64), k: (i64, i64)) -> u64 {
    let span = |(a, b): (i64, i64)| b.saturating_sub(a).max(0) as u64;
    span(i).saturating_mul(span(j)).saturating_mul(span(k))
}
