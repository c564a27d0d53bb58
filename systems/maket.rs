//! Maket stage (DART 5 paper §2, "Maket" module): scene entities → cell grid.
//!
//! Reads the object components spawned from the scene (`TurbidCrown`, `Trunk`, `TurbidPlot`,
//! `Building`, `WaterBody`, `ImportedMesh`, `Ground` + `TerrainRes`) and writes `FacetStore`,
//! `GridSpec`, `MemoryEstimate`, `CellGrid`, `FacetBvh` and `MaketReport`. The systems run in
//! physical order (`MaketSystems`): facets, plan (memory check before any allocation),
//! rasterise turbid media, assign facets to cells, build the BVH, summarise.

use crate::components::*;
use crate::geometry::polygon::rect_overlap_area;
use crate::geometry::shapes::{building_shell, horizontal_polygon, trunk_prism};
use crate::geometry::terrain::Terrain;
use crate::geometry::triangle::{area, clip_to_box, is_degenerate, overlaps_box, polygon_area};
use crate::resources::facets::{Facet, FacetBvh, FacetKind, FacetStore};
use crate::resources::grid::{CellGrid, GridSpec, TurbidEntry, compress};
use crate::resources::maket_report::{MaketReport, MemoryEstimate};
use crate::resources::materials::Materials;
use crate::resources::scene::{RunSettings, SceneInfo, StageErrors, TerrainRes, Warnings};
use crate::scene::desc::BoundaryMode;
use crate::systems::no_stage_error;
use bevy_ecs::prelude::*;
use glam::DVec3;
use rayon::prelude::*;

/// The Maket systems in execution order.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub enum MaketSystems {
    /// Objects → facets.
    Facets,
    /// Grid extent and memory estimate.
    Plan,
    /// Turbid media → per-cell leaf area density.
    Rasterise,
    /// Facets → cells.
    Assign,
    /// BVH.
    Accelerate,
    /// Report.
    Summarise,
}

/// Adds the Maket systems to a schedule.
pub fn add_systems(s: &mut Schedule) {
    s.configure_sets(
        (
            MaketSystems::Facets,
            MaketSystems::Plan,
            MaketSystems::Rasterise,
            MaketSystems::Assign,
            MaketSystems::Accelerate,
            MaketSystems::Summarise,
        )
            .chain(),
    );
    add_plan_systems(s);
    s.add_systems((
        rasterise_turbid
            .in_set(MaketSystems::Rasterise)
            .run_if(no_stage_error),
        assign_facets_to_cells
            .in_set(MaketSystems::Assign)
            .run_if(no_stage_error),
        build_facet_bvh
            .in_set(MaketSystems::Accelerate)
            .run_if(no_stage_error),
        summarise_maket
            .in_set(MaketSystems::Summarise)
            .run_if(no_stage_error),
    ));
}

/// Adds only the facet and plan systems (what `lumenscape check` runs).
pub fn add_plan_systems(s: &mut Schedule) {
    s.configure_sets((MaketSystems::Facets, MaketSystems::Plan).chain());
    s.add_systems((
        build_facets.in_set(MaketSystems::Facets),
        plan_grid.in_set(MaketSystems::Plan).run_if(no_stage_error),
    ));
}

/// Splits a triangle crossing the side of a repetitive scene into pieces translated back
/// inside `[0, sx] × [0, sy]` (exact: areas are kept).
fn wrap_triangle(t: [DVec3; 3], sx: f64, sy: f64, out: &mut Vec<[DVec3; 3]>) {
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

/// Maket · reads Ground, Trunk, Building, WaterBody, ImportedMesh, TerrainRes · writes FacetStore.
#[allow(clippy::too_many_arguments)]
pub fn build_facets(
    info: Res<SceneInfo>,
    terrain: Res<TerrainRes>,
    grounds: Query<(&SourceObject, &Ground)>,
    trunks: Query<(&SourceObject, &Trunk)>,
    buildings: Query<(&SourceObject, &Building)>,
    waters: Query<(&SourceObject, &WaterBody)>,
    meshes: Query<(&SourceObject, &ImportedMesh)>,
    mut warnings: ResMut<Warnings>,
    mut errors: ResMut<StageErrors>,
    mut commands: Commands,
) {
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
    for (o, g) in &grounds {
        push(
            terrain.0.triangles(sx, sy),
            g.optics,
            o.0,
            FacetKind::Ground,
            false,
            &mut facets,
        );
    }
    for (o, t) in &trunks {
        push(
            trunk_prism(t.base, t.height, t.diameter, t.sides),
            t.material,
            o.0,
            FacetKind::Trunk,
            false,
            &mut facets,
        );
    }
    for (o, b) in &buildings {
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
            None => errors.0.push(format!(
                "objects[{}]: the building footprint cannot be triangulated",
                o.0
            )),
        }
    }
    for (o, w) in &waters {
        match horizontal_polygon(&w.footprint, w.altitude) {
            Some(t) => push(t, w.material, o.0, FacetKind::Water, false, &mut facets),
            None => errors.0.push(format!(
                "objects[{}]: the water footprint cannot be triangulated",
                o.0
            )),
        }
    }
    for (o, m) in &meshes {
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
        warnings
            .0
            .push(format!("skipped {degenerate} degenerate facets"));
    }
    commands.insert_resource(FacetStore { facets });
}

fn turbid_bounds(
    crowns: &Query<&TurbidCrown>,
    plots: &Query<&TurbidPlot>,
    meshes: &Query<&ImportedMesh>,
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

/// Cell-index range `[a, b)` covering the interval `[lo, hi]` along an axis.
fn cell_range(lo: f64, hi: f64, origin: f64, d: f64) -> (i64, i64) {
    let a = ((lo - origin) / d).floor() as i64;
    let b = ((hi - origin) / d).ceil() as i64;
    (a, b.max(a + 1))
}

/// Maket · reads SceneInfo, TerrainRes, FacetStore, TurbidCrown, TurbidPlot, ImportedMesh,
/// RunSettings · writes GridSpec, MemoryEstimate (or a StageErrors entry when over the limit).
#[allow(clippy::too_many_arguments)]
pub fn plan_grid(
    info: Res<SceneInfo>,
    terrain: Res<TerrainRes>,
    facets: Res<FacetStore>,
    settings: Res<RunSettings>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    mut errors: ResMut<StageErrors>,
    mut commands: Commands,
) {
    let (sx, sy) = info.size;
    let (dx, dy, dz) = info.cell;
    let ground_lo = match &terrain.0 {
        Terrain::Flat(z) => *z,
        t => t
            .triangles(sx, sy)
            .iter()
            .flatten()
            .map(|v| v.z)
            .fold(f64::INFINITY, f64::min),
    };
    let (tl, th) = turbid_bounds(&crowns, &plots, &meshes, &terrain.0);
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
    let nz = match info.height {
        Some(h) => {
            if top > z0 + h + 1e-9 {
                errors.0.push(format!(
                    "grid.height_m: objects reach {:.3} m above the lowest point, above the scene height {h} m",
                    top - z0
                ));
                return;
            }
            (h / dz).ceil().max(1.0) as usize
        }
        None => (((top - z0) / dz) - 1e-9).ceil().max(1.0) as usize,
    };
    let n = [(sx / dx).round() as usize, (sy / dy).round() as usize, nz];
    let topography_offset = if info.boundary == BoundaryMode::RepetitiveContinuousTopography {
        terrain.0.edge_offsets(sx, sy)
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
    // Memory estimate (upper bounds from bounding boxes), before any allocation.
    let n_cells = spec.n_cells() as u64;
    let bbox_cells = |lo: DVec3, hi: DVec3| -> u64 {
        let (a, b) = cell_range(lo.x, hi.x, 0.0, dx);
        let (c, d) = cell_range(lo.y, hi.y, 0.0, dy);
        let (e, f) = cell_range(lo.z, hi.z, z0, dz);
        ((b - a) * (d - c) * (f - e)) as u64
    };
    let mut turbid_max = 0u64;
    for c in &crowns {
        let b = c.geom.bounds();
        turbid_max += bbox_cells(DVec3::new(b[0], b[1], b[2]), DVec3::new(b[3], b[4], b[5]));
    }
    for p in &plots {
        let (lo, hi) = p.footprint_bounds();
        turbid_max += bbox_cells(lo.extend(z0), hi.extend(top));
    }
    for m in &meshes {
        for t in m
            .parts
            .iter()
            .filter(|p| p.as_turbid)
            .flat_map(|p| &p.triangles)
        {
            turbid_max += bbox_cells(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
        }
    }
    let refs_max: u64 = facets
        .facets
        .iter()
        .map(|f| {
            bbox_cells(
                f.v[0].min(f.v[1]).min(f.v[2]),
                f.v[0].max(f.v[1]).max(f.v[2]),
            )
        })
        .sum();
    let nf = facets.facets.len() as u64;
    let cell_index_bytes = 8 * (n_cells + 1);
    let facet_bytes = nf * (std::mem::size_of::<Facet>() as u64 + 36 + 64);
    // Build buffers: (cell, material, area) triples of 16 B and (cell, facet) pairs of 8 B.
    let peak = cell_index_bytes + turbid_max * (8 + 16) + refs_max * (4 + 8) + facet_bytes;
    let est = MemoryEstimate {
        cell_index_bytes,
        turbid_entries_max: turbid_max,
        facet_refs_max: refs_max,
        facet_bytes,
        peak_bytes: peak,
        limit_bytes: settings.max_memory_bytes,
    };
    if peak > settings.max_memory_bytes {
        errors.0.push(format!(
            "the grid of {} × {} × {} cells needs an estimated {:.2} GiB, above the limit of {:.2} GiB (--max-memory): use larger cells or a smaller scene",
            n[0],
            n[1],
            n[2],
            peak as f64 / (1u64 << 30) as f64,
            settings.max_memory_bytes as f64 / (1u64 << 30) as f64
        ));
    }
    commands.insert_resource(spec);
    commands.insert_resource(est);
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
    let _ = rect_overlap_area;
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

/// Maket · reads GridSpec, TurbidCrown, TurbidPlot, ImportedMesh (as_turbid parts), TerrainRes ·
/// writes CellGrid (turbid part). Leaf area is conserved: each object's leaf area is split among
/// cells by exact overlap (crowns: analytic cross-sections + adaptive quadrature; plots: exact
/// polygon clipping; meshes: exact triangle clipping), so Σ density × volume = analytic area.
pub fn rasterise_turbid(
    spec: Res<GridSpec>,
    terrain: Res<TerrainRes>,
    settings: Res<RunSettings>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    mut commands: Commands,
) {
    let g = &*spec;
    let crown_list: Vec<&TurbidCrown> = crowns.iter().collect();
    let bar = crate::io::progress::progress_bar(
        settings.progress,
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
    for p in &plots {
        triples.extend(rasterise_plot(p, g, &terrain.0));
    }
    for m in &meshes {
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
    commands.insert_resource(CellGrid {
        turbid_start,
        turbid,
        facet_start: Vec::new(),
        facet_ids: Vec::new(),
    });
}

/// Maket · reads GridSpec, FacetStore · writes CellGrid (facet part): each facet is listed in
/// every cell its triangle overlaps (exact separating-axis test; a facet lying in a cell face
/// is listed in both cells).
pub fn assign_facets_to_cells(
    spec: Res<GridSpec>,
    facets: Res<FacetStore>,
    mut grid: ResMut<CellGrid>,
) {
    let g = &*spec;
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
    let (start, ids) = compress(g.n_cells(), &pairs);
    grid.facet_start = start;
    grid.facet_ids = ids;
}

/// Maket · reads FacetStore, GridSpec · writes FacetBvh (only when the scene has facets).
pub fn build_facet_bvh(spec: Res<GridSpec>, facets: Res<FacetStore>, mut commands: Commands) {
    if facets.facets.is_empty() {
        return;
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
    commands.insert_resource(FacetBvh { bvh, triangles });
}

/// Maket · reads everything Maket wrote · writes MaketReport.
#[allow(clippy::too_many_arguments)]
pub fn summarise_maket(
    spec: Res<GridSpec>,
    est: Res<MemoryEstimate>,
    mats: Res<Materials>,
    facets: Res<FacetStore>,
    grid: Option<Res<CellGrid>>,
    bvh: Option<Res<FacetBvh>>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    warnings: Res<Warnings>,
    mut commands: Commands,
) {
    let report = make_report(
        &spec,
        &est,
        &mats,
        &facets,
        grid.as_deref(),
        bvh.as_deref(),
        &crowns,
        &plots,
        &meshes,
        &warnings,
    );
    commands.insert_resource(report);
}

/// Builds the report (also used by `check` before rasterisation).
#[allow(clippy::too_many_arguments)]
pub fn make_report(
    spec: &GridSpec,
    est: &MemoryEstimate,
    mats: &Materials,
    facets: &FacetStore,
    grid: Option<&CellGrid>,
    bvh: Option<&FacetBvh>,
    crowns: &Query<&TurbidCrown>,
    plots: &Query<&TurbidPlot>,
    meshes: &Query<&ImportedMesh>,
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
    let name = |m: u32| mats.list[m as usize].name.clone();
    for c in crowns {
        r.leaf_area.entry(name(c.material)).or_default().analytic_m2 += c.geom.leaf_area();
    }
    for p in plots {
        let a = crate::geometry::polygon::signed_area(&p.footprint).abs();
        r.leaf_area.entry(name(p.material)).or_default().analytic_m2 +=
            p.density * a * (p.top - p.bottom);
    }
    for m in meshes {
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
