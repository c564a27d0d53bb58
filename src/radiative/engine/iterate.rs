//! The iteration loop ([`run`]; physics.md §6.4, DART 5 paper §3): the context is built,
//! the sun and sky are launched, then each iteration scatters what the previous one
//! intercepted until the scene exitance converges; the remaining orders are extrapolated
//! geometrically ([`Increments`]).

use super::*;
use crate::radiative::walk;

/// Runs the flux tracking.
pub fn run(inp: &RadiativeInput) -> RadiativeResult {
    let (mut ctx, plan, mut source) = context(inp);
    let (w, n_dirs) = (ctx.w, ctx.n_dirs);
    let tiling = inp.dirs.tiling();
    // Facet fractions fallback (renormalised cosine) computed once if not provided.
    let approx_fractions: Vec<(Vec<f32>, Vec<f32>)> =
        if inp.facet_fractions.len() == inp.facets.len() {
            Vec::new()
        } else {
            inp.facets
                .par_iter()
                .map(|f| cosine_fractions(&ctx, f))
                .collect()
        };
    let fractions: &[(Vec<f32>, Vec<f32>)] = if approx_fractions.is_empty() {
        inp.facet_fractions
    } else {
        &approx_fractions
    };
    // Thermal emission (issue #34): its elements and source, in the source before the ray
    // threshold is set from it.
    let thermal = thermal_elements(&ctx);
    let mut thermal_sky = Vec::new();
    if inp.thermal.is_some() {
        let (t, sky) = thermal_source(&ctx, &thermal, fractions, |d| thermal_sky_area(&ctx, d));
        for b in 0..ctx.nb {
            source[ctx.thermal_base + b] += t[b] + sky[b];
        }
        thermal_sky = sky;
        let rays = thermal_rays(&ctx, &plan, thermal.len());
        ctx.min_ray = inp.params.ray_threshold * source.iter().sum::<f64>() / rays;
    }
    let ctx = ctx;
    let mut res = new_result(&ctx, plan, &source);
    res.thermal_sky_source = thermal_sky;
    let mut stores = new_stores(&ctx);
    let mut last = vec![0.0; w]; // escaped in the last iteration
    let mut pools = Pools::default();
    // One bar per pass (the launch, then each iteration): chunks merged, with an ETA.
    let bar = crate::io::progress::progress_bar(inp.params.progress, 0, "flux tracking");
    bar.set_message("flux tracking: sun and sky");
    launch(&ctx, &plan, &thermal, fractions, &mut pools, &bar, |o| {
        merge_one(&ctx, o, &mut stores, &mut res, &mut last)
    });
    finish_merge(&ctx, &mut stores);
    res.escaped_per_iteration.push(last.clone());
    res.iterations = 1;
    let ground_fr: Vec<f64> = (0..n_dirs)
        .map(|j| {
            if ctx.omega[j].z > 0.0 {
                tiling[j].projected_sr / std::f64::consts::PI
            } else {
                0.0
            }
        })
        .collect();
    // --- Scattering iterations.
    let mut prev_pending = pending(&stores, w);
    let mut prev_estimate = f64::NAN;
    res.q = vec![0.0; w];
    let mut last_inc = Increments::new(&res);
    while res.iterations < inp.params.max_iterations {
        bar.reset();
        bar.set_message(format!(
            "flux tracking: iteration {}/{}",
            res.iterations + 1,
            inp.params.max_iterations
        ));
        let pend = prev_pending.clone();
        if pend.iter().sum::<f64>() <= 1e-15 * source.iter().sum::<f64>() {
            res.converged = true;
            break;
        }
        let before = Increments::new(&res);
        let mut new_stores = new_stores(&ctx);
        let mut esc = vec![0.0; w];
        let first = res.iterations == 1;
        emit(
            &ctx,
            &stores,
            first,
            fractions,
            &ground_fr,
            &mut pools,
            &bar,
            |o| merge_one(&ctx, o, &mut new_stores, &mut res, &mut esc),
        );
        finish_merge(&ctx, &mut new_stores);
        // Absorption at emission: intercepted − emitted, booked in `emit` via res? (see below)
        stores = new_stores;
        res.iterations += 1;
        res.escaped_per_iteration.push(esc.clone());
        let now = pending(&stores, w);
        for ch in 0..w {
            res.q[ch] = if pend[ch] > 0.0 {
                now[ch] / pend[ch]
            } else {
                0.0
            };
        }
        last_inc = Increments::diff(&before, &res);
        // Extrapolated albedo estimate (all channels).
        let esc_total: f64 = res.escaped.iter().sum();
        let extra: f64 = (0..w)
            .map(|ch| {
                if res.q[ch] < 1.0 {
                    esc[ch] * res.q[ch] / (1.0 - res.q[ch])
                } else {
                    0.0
                }
            })
            .sum();
        let estimate = (esc_total + extra) / source.iter().sum::<f64>();
        prev_pending = now;
        if res.iterations >= 3
            && (estimate - prev_estimate).abs()
                <= inp.params.albedo_threshold * estimate.abs().max(1e-300)
        {
            res.converged = true;
            break;
        }
        prev_estimate = estimate;
    }
    bar.finish_and_clear();
    extrapolate(&ctx, &stores, &last_inc, &mut res);
    res
}

/// The tracker's context of one run (cell records, G and slot rows, thresholds, walk
/// settings), the launch plan and the source power per channel (W).
fn context<'a>(inp: &'a RadiativeInput<'a>) -> (Ctx<'a>, LaunchPlan, Vec<f64>) {
    let spec = inp.spec;
    let nb = inp.e_dir.len();
    let has_sky = inp.e_diff.iter().any(|&e| e > 0.0);
    let has_thermal = inp.thermal.is_some();
    let w = nb * (1 + usize::from(has_sky) + usize::from(has_thermal));
    let thermal_base = nb * (1 + usize::from(has_sky));
    let tiling = inp.dirs.tiling();
    let n_dirs = tiling.len();
    let n_sectors = inp.n_sectors;
    let n_slots = n_sectors + 1;
    let mut omega: Vec<DVec3> = tiling.iter().map(|d| d.omega).collect();
    omega.push(inp.sun);
    let (tur_mat, tur_ids, g_dir) = turbid_tables(inp, n_dirs);
    let n_tm = tur_ids.len();
    let entry_cell = entry_cells(inp);
    let (ents, cells) = cell_records(inp, &tur_mat);
    let size = (
        spec.n[0] as f64 * spec.cell.x,
        spec.n[1] as f64 * spec.cell.y,
    );
    // Launch grids on the top plane.
    let n_sky_dirs = if has_sky || inp.thermal.is_some_and(|t| t.has_sky()) {
        tiling.iter().filter(|d| d.omega.z < 0.0).count()
    } else {
        0
    };
    let plan = launch_plan(
        size,
        (spec.cell.x, spec.cell.y),
        inp.facets,
        spec.subcells,
        n_sky_dirs,
        &inp.params,
    );
    let source = source_powers(inp, size, has_sky, w);
    let n_source_rays = (plan.sun_n.0 * plan.sun_n.1) as f64
        + (plan.sky_n.0 * plan.sky_n.1 * n_sky_dirs) as f64
        + inp.emitters.len() as f64;
    let min_ray = inp.params.ray_threshold * source.iter().sum::<f64>() / n_source_rays;
    // DART's threshold is per steradian × the ray's ΔΩ (physics.md §6.4): relative to the
    // largest tile, so the regular tiles keep `min_ray` and an exact view direction of 0.001 sr
    // is tracked as far as the tile it was cut from.
    let ray_factor = ray_factors(tiling);
    // Rows of the interception slots: the phase rows of each slot's member directions,
    // averaged with the power a smooth diffuse field deposits along each member: ∝ G(Ω_i) ΔΩ_i
    // for turbid cells, ∝ ∫_{ΔΩ_i}|μ|dΩ for the ground. One direction per slot (reference
    // preset) gives the exact rows.
    let n_sec = n_slots - 1;
    let slot_rows = slot_rows(inp, &tur_ids, n_sec);
    let ground_rows = ground_rows(inp, n_sec);
    let (brdf_ref, n_brdf_refs, facet_rows) = facet_rows(inp, n_sec);
    // Hotspot terms (physics.md §3.5): sun–view gap correlation of first-order sun rays.
    let hs = hotspot_table(inp, &tur_ids, &g_dir, &omega);
    let hs_dir: Vec<bool> = (0..n_dirs)
        .map(|j| (0..n_tm).any(|tm| hs[j * n_tm + tm][0] > 0.0))
        .collect();
    // The lean tracker's cells, when the scene fits it.
    let simple = cells
        .iter()
        .all(|c| c.fac_lo == c.fac_hi && c.ent_hi - c.ent_lo <= 1)
        && spec.topography_offset == (0.0, 0.0);
    // Empty-space distance per cell: a cell is occupied when a walk does anything in it (a
    // tracked turbid entry or a facet; the ground and the box's faces are exits of the DDA).
    let skip = skip_field(spec.n, inp.params.skip_empty, MIN_SKIP_DISTANCE, |c| {
        cells[c].fac_lo != cells[c].fac_hi || cells[c].ent_lo != cells[c].ent_hi
    });
    let scells = if simple {
        simple_cells(&cells, &ents, &skip)
    } else {
        Vec::new()
    };
    let (tstores, face_d, pts_per) = subface_layout(inp, plan.subcells, n_slots);
    // Where the walks dispatch (the batched walk only where it has AVX2 + FMA).
    let arch = super::isa_arch(inp.params.kernel_isa);
    let mut ctx = Ctx {
        inp,
        w,
        nb,
        thermal_base,
        n_dirs,
        n_slots,
        omega,
        tur_mat,
        n_tm,
        g_dir,
        cells,
        ents,
        entry_cell,
        size,
        min_ray,
        ray_factor,
        slot_rows,
        ground_rows,
        sub: plan.subcells.max(1),
        brdf_ref,
        n_brdf_refs,
        facet_rows,
        hs,
        hs_dir,
        image_grid: ImageGrid::new(spec, inp.image_oversampling),
        simple,
        batch: walk::batched(simple, &inp.params, w, &arch),
        scells,
        skip,
        subfaces: inp.params.turbid_subfaces,
        tstores,
        face_d,
        pts_per,
        lane_dirs: Vec::new(),
        lane_dirs32: Vec::new(),
        scells32: Vec::new(),
        arch,
        packs: inp.grid.facet_packs(inp.spec, inp.facets),
    };
    if ctx.batch {
        batch_tables(&mut ctx);
    }
    (ctx, plan, source)
}

/// Step of [`context`]: the tracked (turbid) materials — the tracker index of each material
/// (`u32::MAX` when not turbid), the material of each tracker index, and G transposed to
/// `[direction][tracker material]` (`n_dirs` tiling directions + the sun).
fn turbid_tables(inp: &RadiativeInput, n_dirs: usize) -> (Vec<u32>, Vec<usize>, Vec<f64>) {
    let mut tur_mat = vec![u32::MAX; inp.optics.len()];
    let mut g_flat = Vec::new();
    let mut tur_ids = Vec::new();
    for (m, o) in inp.optics.iter().enumerate() {
        if let TrackOptics::Turbid { g, .. } = o {
            tur_mat[m] = tur_ids.len() as u32;
            tur_ids.push(m);
            g_flat.extend_from_slice(g);
        }
    }
    let n_tm = tur_ids.len();
    let mut g_dir = vec![0.0; (n_dirs + 1) * n_tm];
    for tm in 0..n_tm {
        for dir in 0..=n_dirs {
            g_dir[dir * n_tm + tm] = g_flat[tm * (n_dirs + 1) + dir];
        }
    }
    (tur_mat, tur_ids, g_dir)
}

/// Step of [`context`]: the cell of each turbid entry of the grid.
fn entry_cells(inp: &RadiativeInput) -> Vec<u32> {
    let grid = inp.grid;
    let mut entry_cell = vec![0u32; grid.turbid.len()];
    for c in 0..inp.spec.n_cells() {
        for e in grid.turbid_start[c]..grid.turbid_start[c + 1] {
            entry_cell[e as usize] = c as u32;
        }
    }
    entry_cell
}

/// Step of [`context`]: the source power per channel (W) — sun then sky per band over the
/// scene's top area (`size`), or over the launch region of each direction on continuous
/// topography, plus the emitters' powers.
fn source_powers(inp: &RadiativeInput, size: (f64, f64), has_sky: bool, w: usize) -> Vec<f64> {
    let spec = inp.spec;
    let nb = inp.e_dir.len();
    let tiling = inp.dirs.tiling();
    let area = size.0 * size.1;
    let mut source = vec![0.0; w];
    for b in 0..nb {
        source[b] = inp.e_dir[b] * area;
        if has_sky {
            source[nb + b] = inp.e_diff[b] * area;
        }
    }
    // Continuous topography (issue #31): the launch region of each source direction follows
    // the staircase of tile tops (`GridSpec::topo_launch_span`), so the sources are the
    // powers launched over it.
    if spec.topography_offset != (0.0, 0.0) {
        for b in 0..nb {
            source[b] = inp.e_dir[b] * spec.topo_launch_area(size, inp.sun);
            if has_sky {
                source[nb + b] = tiling
                    .iter()
                    .filter(|d| d.omega.z < 0.0)
                    .map(|d| {
                        inp.e_diff[b] / std::f64::consts::PI
                            * d.projected_sr
                            * spec.topo_launch_area(size, d.omega)
                    })
                    .sum();
            }
        }
    }
    for e in inp.emitters {
        for (s, v) in source.iter_mut().zip(&e.power) {
            *s += v;
        }
    }
    source
}

/// Step of [`run`]: the launch area of the sky rays along `d` (the scene's top area, or the
/// launch region on continuous topography), m².
fn thermal_sky_area(ctx: &Ctx, d: DVec3) -> f64 {
    let spec = ctx.inp.spec;
    if spec.topography_offset != (0.0, 0.0) {
        spec.topo_launch_area(ctx.size, d)
    } else {
        ctx.size.0 * ctx.size.1
    }
}

/// Step of [`run`]: the nominal source rays of a thermal run (the launch grids' rays, the
/// emitters, two rays per direction and emitting element), for the ray threshold.
fn thermal_rays(ctx: &Ctx, plan: &LaunchPlan, elements: usize) -> f64 {
    let n_down = ctx.omega[..ctx.n_dirs].iter().filter(|d| d.z < 0.0).count();
    ((plan.sun_n.0 * plan.sun_n.1) as f64
        + (plan.sky_n.0 * plan.sky_n.1 * n_down) as f64
        + ctx.inp.emitters.len() as f64
        + (2 * elements * ctx.n_dirs) as f64)
        .max(1.0)
}

/// Step of [`context`]: the turbid-store layout of the subface setting — stores per turbid
/// entry, the face subdivision and the points per slot.
fn subface_layout(inp: &RadiativeInput, subcells: u32, n_slots: usize) -> (usize, u32, usize) {
    let tstores = match inp.params.turbid_subfaces {
        TurbidSubfaces::Off | TurbidSubfaces::Blend => 1,
        TurbidSubfaces::Faces => 7,
        TurbidSubfaces::Subfaces => 6 * (subcells.clamp(1, MAX_FACE_D) as usize).pow(2) + 1,
    };
    let face_d = if inp.params.turbid_subfaces == TurbidSubfaces::Subfaces {
        subcells.clamp(1, MAX_FACE_D)
    } else {
        1
    };
    let pts_per = if inp.params.turbid_subfaces == TurbidSubfaces::Blend {
        n_slots
    } else {
        1
    };
    (tstores, face_d, pts_per)
}

/// The tracker's turbid entries (tracked materials only) and one record per cell (its entries
/// and facet refs).
fn cell_records(inp: &RadiativeInput, tur_mat: &[u32]) -> (Vec<Ent>, Vec<CellRec>) {
    let grid = inp.grid;
    let n_cells = inp.spec.n_cells();
    let mut ents = Vec::with_capacity(grid.turbid.len());
    let mut cells = Vec::with_capacity(n_cells);
    for c in 0..n_cells {
        let ent_lo = ents.len() as u32;
        for e in grid.turbid_start[c]..grid.turbid_start[c + 1] {
            let te = &grid.turbid[e as usize];
            let tm = tur_mat[te.material as usize];
            if tm != u32::MAX {
                ents.push(Ent {
                    idx: e,
                    tm,
                    density: te.density as f64,
                });
            }
        }
        cells.push(CellRec {
            ent_lo,
            ent_hi: ents.len() as u32,
            fac_lo: grid.facet_start.get(c).copied().unwrap_or(0),
            fac_hi: grid.facet_start.get(c + 1).copied().unwrap_or(0),
        });
    }
    (ents, cells)
}

/// Factor on the power threshold per direction (sun last, 1): DART's threshold is per
/// steradian × the ray's ΔΩ (physics.md §6.4), relative to the largest tile.
fn ray_factors(tiling: &[crate::direction::Direction]) -> Vec<f64> {
    let d_omega_max = tiling
        .iter()
        .map(|d| d.solid_angle_sr)
        .fold(0.0_f64, f64::max);
    let mut ray_factor: Vec<f64> = tiling
        .iter()
        .map(|d| {
            if d_omega_max > 0.0 {
                (d.solid_angle_sr / d_omega_max).min(1.0)
            } else {
                1.0
            }
        })
        .collect();
    ray_factor.push(1.0);
    ray_factor
}

/// The turbid materials' slot rows per band, `[material][band][slot][dir]` (see [`context`]).
fn slot_rows(inp: &RadiativeInput, tur_ids: &[usize], n_sec: usize) -> Vec<f64> {
    let tiling = inp.dirs.tiling();
    let (nb, n_dirs) = (inp.e_dir.len(), tiling.len());
    let mut slot_rows = Vec::with_capacity(tur_ids.len() * nb * n_sec * n_dirs);
    for &m in tur_ids {
        let TrackOptics::Turbid { g, tables, .. } = &inp.optics[m] else {
            unreachable!("tur_ids holds turbid materials only");
        };
        let weights: Vec<f64> = tiling
            .iter()
            .enumerate()
            .map(|(i, d)| g[i] * d.solid_angle_sr)
            .collect();
        for table in tables.iter().take(nb) {
            slot_rows.extend(slot_average_rows(
                table,
                &weights,
                inp.sector_of,
                n_sec,
                n_dirs,
            ));
        }
    }
    slot_rows
}

/// Hotspot terms per (tiling direction, turbid material) (physics.md §3.5), `[0, 0]` without
/// the hotspot (see [`hotspot_terms`]).
fn hotspot_table(
    inp: &RadiativeInput,
    tur_ids: &[usize],
    g_dir: &[f64],
    omega: &[DVec3],
) -> Vec<[f64; 2]> {
    let (n_dirs, n_tm) = (inp.dirs.tiling().len(), tur_ids.len());
    let mut hs = vec![[0.0; 2]; n_dirs * n_tm];
    for (tm, &m) in tur_ids.iter().enumerate() {
        let TrackOptics::Turbid { leaf_size_m, .. } = &inp.optics[m] else {
            unreachable!("tur_ids holds turbid materials only");
        };
        if *leaf_size_m > 0.0 && inp.sun.z < 0.0 {
            let g_sun = g_dir[n_dirs * n_tm + tm];
            for j in 0..n_dirs {
                hs[j * n_tm + tm] =
                    hotspot_terms(inp.sun, omega[j], g_sun, g_dir[j * n_tm + tm], *leaf_size_m);
            }
        }
    }
    hs
}

/// The ground BRDF's rows per band (physics.md §5.2): the slot-averaged rows, then the sun row
/// last, `[band][slot 0..=n_sec][dir]` (empty for a Lambertian ground).
fn ground_rows(inp: &RadiativeInput, n_sec: usize) -> Vec<f64> {
    let tiling = inp.dirs.tiling();
    let (nb, n_dirs) = (inp.e_dir.len(), tiling.len());
    let mut ground_rows = Vec::new();
    if let Some(tables) = &inp.ground_brdf {
        let weights: Vec<f64> = tiling.iter().map(|d| d.projected_sr).collect();
        for table in tables.iter().take(nb) {
            // Slots, then the sun row last: `[band][slot 0..=n_sec][dir]`.
            ground_rows.extend(slot_average_rows(
                table,
                &weights,
                inp.sector_of,
                n_sec,
                n_dirs,
            ));
            ground_rows.extend(
                table
                    .row(table.sun_row().unwrap_or(0))
                    .iter()
                    .take(n_dirs)
                    .map(|&x| x as f64),
            );
        }
    }
    ground_rows
}

/// RPV/Hapke facets (physics.md §5.1): per facet ref of the grid, its compact BRDF ref index
/// (`u32::MAX`: Lambertian), the number of such refs, and the slot-averaged rows per table set
/// (`[set][band][slot 0..=n_sec][dir]`, the sun row last), with the wrong-side power remapped.
fn facet_rows(inp: &RadiativeInput, n_sec: usize) -> (Vec<u32>, usize, Vec<f64>) {
    let grid = inp.grid;
    let tiling = inp.dirs.tiling();
    let (nb, n_dirs) = (inp.e_dir.len(), tiling.len());
    // RPV/Hapke facets: compact ref index and slot-averaged rows per table set (weights: the
    // projected solid angle |n·Ω_i| ΔΩ_i of each member incidence on the set's facets).
    let mut brdf_ref = Vec::new();
    let mut n_brdf_refs = 0;
    let mut facet_rows = Vec::new();
    if !inp.facet_tables.is_empty() {
        brdf_ref = grid
            .facet_ids
            .iter()
            .map(|&f| {
                if inp
                    .facet_brdf
                    .get(f as usize)
                    .is_some_and(|&s| s != u32::MAX)
                {
                    n_brdf_refs += 1;
                    n_brdf_refs as u32 - 1
                } else {
                    u32::MAX
                }
            })
            .collect();
        let mut normal = vec![DVec3::Z; inp.facet_tables.len()];
        for (f, &s) in inp.facet_brdf.iter().enumerate() {
            if s != u32::MAX {
                let v = &inp.facets[f].v;
                normal[s as usize] = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or(DVec3::Z);
            }
        }
        let dir_omega: Vec<DVec3> = tiling.iter().map(|d| d.omega).collect();
        let dir_regular: Vec<bool> = tiling
            .iter()
            .map(|d| d.kind == crate::direction::DirectionKind::Regular)
            .collect();
        for (s, set) in inp.facet_tables.iter().enumerate() {
            let weights: Vec<f64> = tiling
                .iter()
                .map(|d| (-d.omega.dot(normal[s])).max(0.0) * d.solid_angle_sr)
                .collect();
            for table in set.iter().take(nb) {
                // Slots, then the sun row last: `[set][band][slot 0..=n_sec][dir]`.
                let mut rows = slot_average_rows(table, &weights, inp.sector_of, n_sec, n_dirs);
                rows.extend(
                    table
                        .row(table.sun_row().unwrap_or(0))
                        .iter()
                        .take(n_dirs)
                        .map(|&x| x as f64),
                );
                for row in rows.chunks_mut(n_dirs) {
                    remap_wrong_side(row, normal[s], &dir_omega, &dir_regular);
                }
                facet_rows.extend(rows);
            }
        }
    }
    (brdf_ref, n_brdf_refs, facet_rows)
}

/// The walks' cells of a simple scene ([`SimpleCell`]): the cell's tracked turbid entry, or
/// its empty-space distance from `skip`.
fn simple_cells(cells: &[CellRec], ents: &[Ent], skip: &[u8]) -> Vec<SimpleCell> {
    cells
        .iter()
        .zip(skip)
        .map(|(c, &r)| match ents.get(c.ent_lo as usize) {
            Some(e) if c.ent_hi > c.ent_lo && e.density > 0.0 => SimpleCell {
                density: e.density,
                tm: e.tm,
                idx: e.idx,
            },
            // An entry of zero density: nothing happens in the cell, but it is not
            // counted as empty (r = 0, visited).
            _ => SimpleCell {
                tm: r as u32,
                ..SimpleCell::default()
            },
        })
        .collect()
}

/// The batched walk's per-direction lane constants, and the single-precision walk's packed
/// cells when that walk runs (see [`crate::radiative::walk`]).
fn batch_tables(ctx: &mut Ctx) {
    ctx.lane_dirs = batch::lane_dirs(ctx);
    ctx.lane_dirs32 = batch::lane_dirs32(ctx);
    if !ctx.lane_dirs32.is_empty() {
        ctx.scells32 = ctx
            .scells
            .iter()
            .map(|c| {
                let d = if c.density > 0.0 {
                    (c.density as f32).max(f32::MIN_POSITIVE)
                } else {
                    0.0
                };
                let hi = if c.density > 0.0 { c.idx } else { c.tm };
                d.to_bits() as u64 | (hi as u64) << 32
            })
            .collect();
    }
}

/// The result before the first iteration: every product zero, sized for the run of `ctx`.
fn new_result(ctx: &Ctx, plan: LaunchPlan, source: &[f64]) -> RadiativeResult {
    let inp = ctx.inp;
    let (spec, grid) = (inp.spec, inp.grid);
    let (w, nb, n_dirs) = (ctx.w, ctx.nb, ctx.n_dirs);
    let has_sky = inp.e_diff.iter().any(|&e| e > 0.0);
    RadiativeResult {
        n_channels: w,
        n_bands: nb,
        has_sky,
        has_thermal: inp.thermal.is_some(),
        source: source.to_vec(),
        escaped: vec![0.0; n_dirs * w],
        images: vec![
            0.0;
            inp.image_of.iter().filter(|&&i| i != u32::MAX).count()
                * ctx.image_grid.pixels()
                * w
        ],
        image_grid: ctx.image_grid,
        absorbed_turbid: vec![0.0; grid.turbid.len() * w],
        intercepted_turbid: vec![0.0; grid.turbid.len() * w],
        absorbed_facet: vec![0.0; inp.facets.len() * w],
        intercepted_facet: vec![0.0; inp.facets.len() * w],
        absorbed_ground: vec![0.0; spec.n[0] * spec.n[1] * w],
        intercepted_ground: vec![0.0; spec.n[0] * spec.n[1] * w],
        lost: vec![0.0; w],
        remaining: vec![0.0; w],
        launch: plan,
        walk: Some(walk_info(ctx)),
        ..Default::default()
    }
}

/// Which walk the run's lean rays take (see [`WalkInfo`]).
fn walk_info(ctx: &Ctx) -> WalkInfo {
    if !ctx.batch {
        return WalkInfo {
            kernel: "baseline",
            precision: "f64",
            lanes: 1,
        };
    }
    let f32_walk = !ctx.lane_dirs32.is_empty();
    let lanes = batch_lanes(ctx.inp.params.kernel_isa, f32_walk) as u32;
    WalkInfo {
        kernel: match lanes {
            16 | 8 => "avx512",
            4 => "avx2",
            _ => "baseline",
        },
        precision: if f32_walk { "f32" } else { "f64" },
        lanes,
    }
}

/// Iteration 1: the sun and sky launch points on the top plane in fixed chunks of rows, then
/// the other sources (emitters) in fixed chunks after them (physics.md §6.1, §6.2); the
/// chunks' outputs go to `merge_one` in that order ([`stream_chunks`]).
#[allow(clippy::too_many_arguments)]
fn launch(
    ctx: &Ctx,
    plan: &LaunchPlan,
    thermal: &[ThermalElement],
    fractions: &[(Vec<f32>, Vec<f32>)],
    pools: &mut Pools,
    progress: &indicatif::ProgressBar,
    merge_one: impl FnMut(&ChunkOut) + Send,
) {
    let inp = ctx.inp;
    let spec = inp.spec;
    let (w, nb, n_dirs, size) = (ctx.w, ctx.nb, ctx.n_dirs, ctx.size);
    let tiling = inp.dirs.tiling();
    let has_sky = inp.e_diff.iter().any(|&e| e > 0.0);
    // The thermal sky (issue #34): launched with the solar sky, on the thermal channels.
    let th_sky: &[f64] = inp.thermal.map_or(&[], |t| &t.sky);
    let thermal_sky = th_sky.iter().any(|&v| v > 0.0);
    let tb = ctx.thermal_base;
    let area = size.0 * size.1;
    // --- Iteration 1: sources. Launch points in fixed chunks of rows.
    let top = spec.top();
    let topo = spec.topography_offset != (0.0, 0.0);
    let sky_dirs: Vec<usize> = if has_sky || thermal_sky {
        (0..n_dirs).filter(|&j| ctx.omega[j].z < 0.0).collect()
    } else {
        Vec::new()
    };
    // Rows of launch points: the sun grid's rows, then the sky grid's (false/true); one list
    // cut into fixed chunks, so the order of accumulation does not depend on the threads.
    let has_sun = inp.e_dir.iter().any(|&e| e > 0.0);
    let mut rows: Vec<(bool, usize)> = Vec::new();
    if has_sun {
        rows.extend((0..plan.sun_n.1).map(|j| (false, j)));
    }
    if !sky_dirs.is_empty() {
        rows.extend((0..plan.sky_n.1).map(|j| (true, j)));
    }
    // Nominal rays per row: one per sun launch point, one per sky direction per sky point.
    let row_rays = plan.sun_n.0.max(plan.sky_n.0 * sky_dirs.len());
    let rl = chunk_len(rows.len(), row_rays, inp.params.chunk_rays);
    let n_rows = rows.len().div_ceil(rl);
    let el = chunk_len(inp.emitters.len(), 1, inp.params.chunk_rays);
    let n_em = inp.emitters.len().div_ceil(el);
    let tl = chunk_len(thermal.len(), 2 * n_dirs, inp.params.chunk_rays);
    let n_th = thermal.len().div_ceil(tl);
    progress.set_length((n_rows + n_em + n_th) as u64);
    let run_rows = |chunk: &[(bool, usize)], out: &mut ChunkOut| {
        let mut pw = vec![0.0; w];
        let t_kernel = std::time::Instant::now();
        for &(sky, jy) in chunk {
            let (nlx, nly) = if sky { plan.sky_n } else { plan.sun_n };
            let da = area / (nlx * nly) as f64;
            for ix in 0..nlx {
                let p = DVec3::new(
                    spec.origin.x + (ix as f64 + 0.5) * size.0 / nlx as f64,
                    spec.origin.y + (jy as f64 + 0.5) * size.1 / nly as f64,
                    top,
                );
                // Continuous topography (issue #31): launch point and area of ray `ix` over
                // the direction's launch region (`GridSpec::topo_launch_point`).
                let topo_launch = |d: DVec3| -> (Option<DVec3>, f64) {
                    if !topo {
                        return (Some(p), da);
                    }
                    let (lx, ly) = spec.topo_launch_span(d);
                    let u = (ix as f64 + 0.5) * (size.0 + lx) / nlx as f64;
                    let v = (jy as f64 + 0.5) * (size.1 + ly) / nly as f64;
                    // (Clamped at 0: a direction below the terrain's downhill slope.)
                    let da = (size.0 + lx).max(0.0) * (size.1 + ly).max(0.0) / (nlx * nly) as f64;
                    (spec.topo_launch_point(size, u, v, d), da)
                };
                if !sky {
                    pw.iter_mut().for_each(|v| *v = 0.0);
                    let (p, da) = topo_launch(inp.sun);
                    for b in 0..nb {
                        pw[b] = inp.e_dir[b] * da;
                    }
                    match p {
                        Some(p) => ctx.trace(p, n_dirs, None, &mut pw, out),
                        None => add(&mut out.lost, &pw),
                    }
                    continue;
                }
                for &j in &sky_dirs {
                    pw.iter_mut().for_each(|v| *v = 0.0);
                    let (p, da) = topo_launch(ctx.omega[j]);
                    // L_sky = E_diff/π; power = L ΔA ∫_{ΔΩ}|μ|dΩ (physics.md §6.1).
                    for b in 0..nb {
                        if has_sky {
                            pw[nb + b] =
                                inp.e_diff[b] / std::f64::consts::PI * da * tiling[j].projected_sr;
                        }
                        if thermal_sky {
                            pw[tb + b] =
                                th_sky.get(b).copied().unwrap_or(0.0) * da * tiling[j].projected_sr;
                        }
                    }
                    match p {
                        Some(p) => ctx.trace(p, j, None, &mut pw, out),
                        None => add(&mut out.lost, &pw),
                    }
                }
            }
        }
        ctx.flush(out);
        out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
    };
    // Other sources, in fixed chunks after the launch rows.
    let run_emitters = |chunk: &[crate::radiative::engine::Emission], out: &mut ChunkOut| {
        let mut pw = vec![0.0; w];
        for e in chunk {
            pw.iter_mut().for_each(|v| *v = 0.0);
            for (a, b) in pw.iter_mut().zip(&e.power) {
                *a = *b;
            }
            if e.dir <= n_dirs && pw.iter().any(|&v| v > 0.0) {
                ctx.trace(e.origin, e.dir, e.skip_facet, &mut pw, out);
            } else {
                add(&mut out.lost, &pw);
            }
        }
        ctx.flush(out);
    };
    // Thermal emission (issue #34), in fixed chunks after the other sources.
    let run_thermal = |chunk: &[ThermalElement], out: &mut ChunkOut| {
        let mut outgoing = vec![0.0; n_dirs * w];
        let mut pw = vec![0.0; w];
        let mut scratch = ThermalScratch::default();
        for &e in chunk {
            let src = thermal_emitter(ctx, e, fractions, &mut outgoing, &mut scratch);
            let split = matches!(e, ThermalElement::Turbid(_));
            send_emitter(ctx, &src, split, false, &outgoing, &mut pw, out);
        }
        let t_kernel = std::time::Instant::now();
        ctx.flush(out);
        out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
    };
    stream_chunks(
        ctx,
        n_rows + n_em + n_th,
        pools,
        progress,
        |i, out| {
            if i < n_rows {
                run_rows(&rows[i * rl..((i + 1) * rl).min(rows.len())], out);
            } else if i < n_rows + n_em {
                let i = i - n_rows;
                let n = inp.emitters.len();
                run_emitters(&inp.emitters[i * el..((i + 1) * el).min(n)], out);
            } else {
                let i = i - n_rows - n_em;
                run_thermal(&thermal[i * tl..((i + 1) * tl).min(thermal.len())], out);
            }
        },
        merge_one,
    );
}

/// The orders after the last iteration (physics.md §6.4): extrapolated geometrically from the
/// last iteration's increments and ratio `q` when `extrapolate` is on (at least two
/// iterations), else the pending power booked as remaining.
fn extrapolate(ctx: &Ctx, stores: &Stores, last_inc: &Increments, res: &mut RadiativeResult) {
    let (inp, w) = (ctx.inp, ctx.w);
    // --- Remaining stores: extrapolate (or book as remaining).
    let pend = pending(stores, w);
    if inp.params.extrapolate && res.iterations >= 2 {
        let mut fac = vec![0.0; w];
        for ch in 0..w {
            let q = res.q[ch];
            fac[ch] = if q > 0.0 && q < 1.0 {
                q / (1.0 - q)
            } else {
                0.0
            };
        }
        last_inc.apply(res, &fac);
        for ch in 0..w {
            // Geometric tail: exactly the pending power when q comes from the same iteration.
            let tail = last_inc.total(ch) * fac[ch];
            res.remaining[ch] = pend[ch] - tail;
        }
    } else {
        res.remaining = pend;
    }
}

/// An empty chunk output (its turbid accumulator is lent by [`stream_chunks`]).
pub(in crate::radiative) fn new_out(ctx: &Ctx) -> ChunkOut {
    ChunkOut {
        escaped: vec![0.0; ctx.n_dirs * ctx.w],
        lost: vec![0.0; ctx.w],
        ray_scale: 1.0,
        ..Default::default()
    }
}

/// A worker's zeroed turbid accumulator over every accumulator index of the run.
pub(in crate::radiative) fn new_acc(ctx: &Ctx) -> Box<TurAcc> {
    Box::new(TurAcc::new(
        ctx.inp.grid.turbid.len() * ctx.tstores,
        ctx.n_slots,
        ctx.w,
        ctx.pts_per,
        walk::select(ctx, false, true) == walk::WalkKind::BatchF32,
    ))
}

pub(in crate::radiative) fn new_stores(ctx: &Ctx) -> Stores {
    let w = ctx.w;
    let grid = ctx.inp.grid;
    let spec = ctx.inp.spec;
    let off = ctx.subfaces == TurbidSubfaces::Off;
    let n_dense = if off { grid.turbid.len() } else { 0 };
    Stores {
        tur: vec![0.0; n_dense * ctx.n_slots * w],
        tur_pts: vec![[0.0; 8]; n_dense],
        trec: TurRecords::new(ctx.n_slots * w, ctx.pts_per),
        fac_front: vec![0.0; grid.facet_ids.len() * w],
        fac_back: vec![0.0; grid.facet_ids.len() * w],
        fac_slot: vec![0.0; ctx.n_brdf_refs * ctx.n_slots * w],
        fac_pts: SubPoints::default(),
        gnd: vec![
            0.0;
            spec.n[0]
                * spec.n[1]
                * w
                * if ctx.inp.ground_brdf.is_some() {
                    ctx.n_slots
                } else {
                    1
                }
        ],
        gnd_pts: SubPoints::default(),
    }
}

/// Power intercepted and not yet scattered or absorbed, per channel.
pub(in crate::radiative) fn pending(s: &Stores, w: usize) -> Vec<f64> {
    let mut p = vec![0.0; w];
    for (chunk, out) in [
        (&s.tur, 0),
        (&s.fac_front, 0),
        (&s.fac_back, 0),
        (&s.fac_slot, 0),
        (&s.gnd, 0),
        (&s.trec.pow, 0),
    ] {
        let _ = out;
        for (i, v) in chunk.iter().enumerate() {
            p[i % w] += v;
        }
    }
    p
}

/// Snapshot of additive products, to take the increments of one iteration.
#[derive(Clone)]
pub(in crate::radiative) struct Increments {
    pub(in crate::radiative) escaped: Vec<f64>,
    pub(in crate::radiative) images: Vec<f64>,
    pub(in crate::radiative) absorbed_turbid: Vec<f64>,
    pub(in crate::radiative) absorbed_facet: Vec<f64>,
    pub(in crate::radiative) absorbed_ground: Vec<f64>,
    pub(in crate::radiative) intercepted_ground: Vec<f64>,
    pub(in crate::radiative) intercepted_turbid: Vec<f64>,
    pub(in crate::radiative) intercepted_facet: Vec<f64>,
    pub(in crate::radiative) lost: Vec<f64>,
    pub(in crate::radiative) w: usize,
}

impl Increments {
    pub(in crate::radiative) fn new(r: &RadiativeResult) -> Self {
        Self {
            escaped: r.escaped.clone(),
            images: r.images.clone(),
            absorbed_turbid: r.absorbed_turbid.clone(),
            absorbed_facet: r.absorbed_facet.clone(),
            absorbed_ground: r.absorbed_ground.clone(),
            intercepted_ground: r.intercepted_ground.clone(),
            intercepted_turbid: r.intercepted_turbid.clone(),
            intercepted_facet: r.intercepted_facet.clone(),
            lost: r.lost.clone(),
            w: r.n_channels,
        }
    }
    pub(in crate::radiative) fn diff(a: &Self, r: &RadiativeResult) -> Self {
        let d =
            |x: &Vec<f64>, y: &Vec<f64>| y.iter().zip(x).map(|(b, a)| b - a).collect::<Vec<f64>>();
        Self {
            escaped: d(&a.escaped, &r.escaped),
            images: d(&a.images, &r.images),
            absorbed_turbid: d(&a.absorbed_turbid, &r.absorbed_turbid),
            absorbed_facet: d(&a.absorbed_facet, &r.absorbed_facet),
            absorbed_ground: d(&a.absorbed_ground, &r.absorbed_ground),
            intercepted_ground: d(&a.intercepted_ground, &r.intercepted_ground),
            intercepted_turbid: d(&a.intercepted_turbid, &r.intercepted_turbid),
            intercepted_facet: d(&a.intercepted_facet, &r.intercepted_facet),
            lost: d(&a.lost, &r.lost),
            w: a.w,
        }
    }
    /// Adds `inc × fac[channel]` to every additive product.
    pub(in crate::radiative) fn apply(&self, r: &mut RadiativeResult, fac: &[f64]) {
        let w = self.w;
        let ap = |dst: &mut Vec<f64>, src: &Vec<f64>| {
            for (i, (d, s)) in dst.iter_mut().zip(src).enumerate() {
                *d += s * fac[i % w];
            }
        };
        ap(&mut r.escaped, &self.escaped);
        ap(&mut r.images, &self.images);
        ap(&mut r.absorbed_turbid, &self.absorbed_turbid);
        ap(&mut r.absorbed_facet, &self.absorbed_facet);
        ap(&mut r.absorbed_ground, &self.absorbed_ground);
        ap(&mut r.intercepted_ground, &self.intercepted_ground);
        ap(&mut r.intercepted_turbid, &self.intercepted_turbid);
        ap(&mut r.intercepted_facet, &self.intercepted_facet);
        ap(&mut r.lost, &self.lost);
    }
    /// Energy that left the pending pool in this iteration: escaped + absorbed + lost.
    pub(in crate::radiative) fn total(&self, ch: usize) -> f64 {
        let w = self.w;
        let s = |v: &Vec<f64>| v.iter().skip(ch).step_by(w).sum::<f64>();
        s(&self.escaped)
            + s(&self.absorbed_turbid)
            + s(&self.absorbed_facet)
            + s(&self.absorbed_ground)
            + s(&self.lost)
    }
}
