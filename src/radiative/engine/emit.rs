//! Emission of the stored interceptions (physics.md §3.6, §5.1, §6.3; DART 5 paper §3.2,
//! Figure 7): each store scatters its power along the tiling directions with its phase or
//! Lambertian rows and the rays are traced; turbid records per (sub-)face with exit
//! grouping.

use super::*;
use crate::radiative::walk;

/// Renormalised-cosine Lambertian fractions (used when exact fractions were not provided).
pub(in crate::radiative) fn cosine_fractions(ctx: &Ctx, f: &Facet) -> (Vec<f32>, Vec<f32>) {
    let n = (f.v[1] - f.v[0])
        .cross(f.v[2] - f.v[0])
        .normalize_or(DVec3::Z);
    let tiling = ctx.inp.dirs.tiling();
    let mut fr: Vec<f64> = tiling
        .iter()
        .map(|d| n.dot(d.omega).max(0.0) * d.solid_angle_sr)
        .collect();
    let mut bk: Vec<f64> = tiling
        .iter()
        .map(|d| (-n.dot(d.omega)).max(0.0) * d.solid_angle_sr)
        .collect();
    let (sf, sb): (f64, f64) = (fr.iter().sum(), bk.iter().sum());
    fr.iter_mut().for_each(|x| *x /= sf);
    bk.iter_mut().for_each(|x| *x /= sb);
    (
        fr.iter().map(|&x| x as f32).collect(),
        bk.iter().map(|&x| x as f32).collect(),
    )
}

/// Traces `share × v` (channel powers, W) from `o` along tiling direction `j`, ignoring facet
/// `skip`. With `hs_j` (first emission after the launch, so the sun channels hold only
/// scattered direct sun) the sun channels go on a hotspot-correlated ray and the sky channels
/// on an ordinary one.
#[allow(clippy::too_many_arguments)]
pub(in crate::radiative) fn send(
    ctx: &Ctx,
    o: DVec3,
    j: usize,
    skip: Option<u32>,
    v: &[f64],
    share: f64,
    hs_j: bool,
    pw: &mut [f64],
    out: &mut ChunkOut,
) {
    if !hs_j {
        for (a, b) in pw.iter_mut().zip(v) {
            *a = b * share;
        }
        ctx.trace(o, j, skip, pw, out);
        return;
    }
    let nb = ctx.nb;
    for (ch, (a, b)) in pw.iter_mut().zip(v).enumerate() {
        *a = if ch < nb { b * share } else { 0.0 };
    }
    if pw.iter().any(|&x| x > 0.0) {
        ctx.trace_hotspot(o, j, skip, pw, out);
    }
    if v.len() > nb && v[nb..].iter().any(|&x| x != 0.0) {
        for (ch, (a, b)) in pw.iter_mut().zip(v).enumerate() {
            *a = if ch < nb { 0.0 } else { b * share };
        }
        ctx.trace(o, j, skip, pw, out);
    }
}

/// Iteration i: scatters every store of iteration i−1 along every tiling direction; `first`:
/// the stores are those of the launch (direct sun and sky). The chunks' outputs go to
/// `merge_one` in chunk order ([`stream_chunks`]); `progress` counts the chunks.
#[allow(clippy::too_many_arguments)]
pub(in crate::radiative) fn emit(
    ctx: &Ctx,
    st: &Stores,
    first: bool,
    fractions: &[(Vec<f32>, Vec<f32>)],
    ground_fr: &[f64],
    pools: &mut Pools,
    progress: &indicatif::ProgressBar,
    merge_one: impl FnMut(&ChunkOut) + Send,
) {
    let w = ctx.w;
    let ns = ctx.n_slots;
    let n_dirs = ctx.n_dirs;
    let grid = ctx.inp.grid;
    let spec = ctx.inp.spec;
    // Emitters in a fixed order: turbid entries (or, with incident-face stores, the groups of
    // records of one entry, entries ascending), facet refs, ground columns.
    let off = ctx.subfaces == TurbidSubfaces::Off;
    let mut groups: Vec<std::ops::Range<usize>> = Vec::new();
    if !off {
        let tr = &st.trec;
        let mut lo = 0;
        for n in 1..=tr.order.len() {
            let entry = |n: usize| tr.keys[tr.order[n] as usize] as usize / ctx.tstores;
            if n == tr.order.len() || entry(n) != entry(lo) {
                groups.push(lo..n);
                lo = n;
            }
        }
    }
    let n_t = if off { grid.turbid.len() } else { groups.len() };
    let n_f = grid.facet_ids.len();
    let n_g = spec.n[0] * spec.n[1];
    let active: Vec<usize> = (0..n_t + n_f + n_g)
        .filter(|&k| {
            if k < n_t && !off {
                let tr = &st.trec;
                groups[k].clone().any(|n| {
                    let r = tr.order[n] as usize;
                    tr.pow[r * tr.ns_w..(r + 1) * tr.ns_w]
                        .iter()
                        .any(|&v| v > 0.0)
                })
            } else if k < n_t {
                st.tur[k * ns * w..(k + 1) * ns * w]
                    .iter()
                    .any(|&v| v > 0.0)
            } else if k < n_t + n_f {
                let r = k - n_t;
                let bi = ctx.brdf_ref.get(r).copied().unwrap_or(u32::MAX) as usize;
                if bi != u32::MAX as usize {
                    return st.fac_slot[bi * ns * w..(bi + 1) * ns * w]
                        .iter()
                        .any(|&v| v > 0.0);
                }
                st.fac_front[r * w..(r + 1) * w]
                    .iter()
                    .chain(&st.fac_back[r * w..(r + 1) * w])
                    .any(|&v| v > 0.0)
            } else {
                let c = k - n_t - n_f;
                let gs = st.gnd.len() / n_g;
                st.gnd[c * gs..(c + 1) * gs].iter().any(|&v| v > 0.0)
            }
        })
        .collect();
    // Chunks of emitters, each of at most `CHUNK_RAYS` nominal rays (two per direction).
    let cl = chunk_len(active.len(), 2 * n_dirs, ctx.inp.params.chunk_rays);
    let n_chunks = active.len().div_ceil(cl);
    progress.set_length(n_chunks as u64);
    stream_chunks(
        ctx,
        n_chunks,
        pools,
        progress,
        |i, out| {
            let chunk = &active[i * cl..((i + 1) * cl).min(active.len())];
            let mut outgoing = vec![0.0; n_dirs * w];
            let mut pw = vec![0.0; w];
            let mut intercepted = vec![0.0; w];
            let mut scratch = RecScratch::default();
            for &k in chunk {
                if k < n_t && !off {
                    let hs = first && ctx.inp.emitters.is_empty();
                    let recs = &st.trec.order[groups[k].clone()];
                    emit_turbid_records(ctx, st, recs, hs, &mut scratch, &mut pw, out);
                    continue;
                }
                outgoing.iter_mut().for_each(|v| *v = 0.0);
                intercepted.iter_mut().for_each(|v| *v = 0.0);
                let src = if k < n_t {
                    match turbid_emitter(ctx, st, k, &mut outgoing, &mut intercepted, out) {
                        Some(src) => src,
                        None => continue,
                    }
                } else if k < n_t + n_f {
                    facet_emitter(ctx, st, k - n_t, fractions, &mut outgoing, out)
                } else {
                    ground_emitter(ctx, st, k - n_t - n_f, ground_fr, &mut outgoing, out)
                };
                send_emitter(ctx, &src, k < n_t, first, &outgoing, &mut pw, out);
            }
            // The rays still queued.
            let t_kernel = std::time::Instant::now();
            ctx.flush(out);
            out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
        },
        merge_one,
    );
}

/// Where one emitter's rays start: the barycentres of the upper and lower halves of the
/// intercepted energy (turbid) or the facet's centroid / the column's centre (`up`, `dn`), the
/// facet the rays ignore, the facet's normal, the scattering points per sub-cell (barycentre,
/// share; facets and ground) and whether it is a ground column.
pub(in crate::radiative) struct Emitter<'s> {
    pub(in crate::radiative) origin_up: DVec3,
    pub(in crate::radiative) origin_dn: DVec3,
    pub(in crate::radiative) skip: Option<u32>,
    pub(in crate::radiative) normal: Option<DVec3>,
    pub(in crate::radiative) points: &'s [(DVec3, f64)],
    pub(in crate::radiative) ground: bool,
    /// Turbid: the two emission points' offsets from the barycentre (m; the horizontal
    /// signs alternate over directions), the first point's weight, and the cell's bounds
    /// (see [`turbid_emitter`]); `None` for other emitters.
    pub(in crate::radiative) pair: Option<TurbidPair>,
}

/// The two emission points of a turbid cell (physics.md §3.6): per direction, the height z*
/// at which one ray carries the exact expectation of the source's vertical distribution
/// through a homogeneous medium ([`MaxEntropyProfile::position`]), and horizontally the
/// barycentre ± the spread per axis (the horizontal signs alternate over directions), half
/// the power each.
#[derive(Clone, Copy)]
pub(in crate::radiative) struct TurbidPair {
    /// Cell index.
    cell: usize,
    /// The vertical maximum-entropy density.
    profile: MaxEntropyProfile,
    /// Horizontal offsets (m).
    dx: f64,
    dy: f64,
    lo: DVec3,
    hi: DVec3,
}

impl TurbidPair {
    /// The pair of cell `cell` (`centre`, size `size`, m) whose intercepted energy has its
    /// barycentre at `mean`: per axis the maximum-entropy density with that mean.
    pub(in crate::radiative) fn new(cell: usize, mean: DVec3, centre: DVec3, size: DVec3) -> Self {
        let lo = centre - 0.5 * size;
        let rel = ((mean - lo) / size).clamp(DVec3::ZERO, DVec3::ONE);
        TurbidPair {
            cell,
            profile: MaxEntropyProfile::new(rel.z),
            dx: max_entropy_sigma(rel.x) * size.x,
            dy: max_entropy_sigma(rel.y) * size.y,
            lo,
            hi: lo + size,
        }
    }

    /// The pair with its points kept at or above height `z` (m; a thermal source in a cell
    /// the terrain crosses starts above the ground, `engine::thermal`).
    pub(in crate::radiative) fn above(mut self, z: f64) -> Self {
        self.lo.z = z.clamp(self.lo.z, self.hi.z - 1e-3 * (self.hi.z - self.lo.z));
        self
    }

    /// The two points for direction `j` from barycentre `origin`, inside the cell by 1e-6 of
    /// its size, with their power shares.
    fn points(&self, ctx: &Ctx, origin: DVec3, j: usize) -> [(DVec3, f64); 2] {
        let d = ctx.omega[j];
        let cr = ctx.cells[self.cell];
        let gd = &ctx.g_dir[j * ctx.n_tm..(j + 1) * ctx.n_tm];
        let k: f64 = ctx.ents[cr.ent_lo as usize..cr.ent_hi as usize]
            .iter()
            .map(|e| gd[e.tm as usize] * e.density)
            .sum();
        let dz = self.hi.z - self.lo.z;
        // Downstream ∝ e^{c z/Δz}: c = kΔz/μ (μ signed; a horizontal ray: no dependence).
        let c = if d.z.abs() > 1e-12 { k * dz / d.z } else { 0.0 };
        let z = self.lo.z + dz * self.profile.position(c);
        let h = DVec3::new(
            if j & 1 == 0 { self.dx } else { -self.dx },
            if j & 2 == 0 { self.dy } else { -self.dy },
            0.0,
        );
        let eps = 1e-6 * (self.hi - self.lo);
        let inside = |p: DVec3| p.clamp(self.lo + eps, self.hi - eps);
        let o = DVec3::new(origin.x, origin.y, z);
        [(inside(o + h), 0.5), (inside(o - h), 0.5)]
    }
}

/// Channels up to which a slot is scattered channel by channel (each channel's directions a
/// contiguous, vectorised run at stride w); above, direction by direction (each direction's w
/// channels contiguous: with hundreds of channels the channel order strode through
/// `outgoing` by w per direction, 40 % of such a run).
const CHANNEL_MAJOR_MAX: usize = 8;

/// `outgoing[j · w + r · nb + b] += wv[r · nb + b] · row(b)[j]` for every direction
/// j < `n_dirs`, copy r < `reps` (sun and sky channels) and band b < `nb`. Both loop orders add
/// the same products once per element, so the sums do not depend on the order (channels whose
/// `wv` is 0 are skipped: they would add +0).
#[inline]
fn scatter_slot<'r, T: Copy + 'r>(
    outgoing: &mut [f64],
    wv: &[f64],
    (nb, reps, n_dirs): (usize, usize, usize),
    row: impl Fn(usize) -> &'r [T],
    to_f64: impl Fn(T) -> f64,
) {
    let w = nb * reps;
    if w <= CHANNEL_MAJOR_MAX {
        for (ch, &val) in wv.iter().enumerate() {
            if val == 0.0 {
                continue;
            }
            let r = row(ch % nb);
            for (o, &t) in outgoing.chunks_exact_mut(w).zip(&r[..n_dirs]) {
                o[ch] += val * to_f64(t);
            }
        }
        return;
    }
    let rows: Vec<&[T]> = (0..nb).map(&row).collect();
    for (j, o) in outgoing.chunks_exact_mut(w).take(n_dirs).enumerate() {
        for r in 0..reps {
            let (o, v) = (&mut o[r * nb..(r + 1) * nb], &wv[r * nb..(r + 1) * nb]);
            for ((o, &v), row) in o.iter_mut().zip(v).zip(&rows) {
                *o += v * to_f64(row[j]);
            }
        }
    }
}

/// Turbid entry `k` (`turbid_subfaces: Off`): its stored power per slot scattered with the
/// slot rows into `outgoing[dir · w + ch]` (physics.md §3.6), the absorbed rest booked; `None`
/// for an entry whose material is not turbid.
fn turbid_emitter<'s>(
    ctx: &Ctx,
    st: &'s Stores,
    k: usize,
    outgoing: &mut [f64],
    intercepted: &mut [f64],
    out: &mut ChunkOut,
) -> Option<Emitter<'s>> {
    let (w, nb, ns, n_dirs) = (ctx.w, ctx.nb, ctx.n_slots, ctx.n_dirs);
    let (grid, spec) = (ctx.inp.grid, ctx.inp.spec);
    let (origin_up, origin_dn, skip, normal);
    let e = &grid.turbid[k];
    let TrackOptics::Turbid { tables, .. } = &ctx.inp.optics[e.material as usize] else {
        return None;
    };
    for slot in 0..ns {
        let base = (k * ns + slot) * w;
        let wv = &st.tur[base..base + w];
        if wv.iter().all(|&v| v == 0.0) {
            continue;
        }
        let tm = ctx.tur_mat[e.material as usize] as usize;
        for (i, &v) in intercepted.iter_mut().zip(wv) {
            if v != 0.0 {
                *i += v;
            }
        }
        // `outgoing[j · w + ch] += wv[ch] · row_{ch mod nb}[j]` for every direction j and
        // channel ch ([`scatter_slot`]).
        let dims = (nb, w / nb, n_dirs);
        if slot == ns - 1 {
            let srow = tables[0].sun_row().unwrap_or(0);
            scatter_slot(outgoing, wv, dims, |b| tables[b].row(srow), |t| t as f64);
        } else {
            scatter_slot(outgoing, wv, dims, |b| ctx.slot_row(tm, b, slot), |t| t);
        }
    }
    let p = &st.tur_pts[k];
    let cell = ctx.entry_cell[k] as usize;
    let centre = cell_centre(spec, cell);
    // The barycentre of the intercepted energy and the two emission points of its within-cell
    // distribution (physics.md §3.6).
    let wsum = p[3] + p[7];
    let mean = if wsum > 0.0 {
        (DVec3::new(p[0], p[1], p[2]) + DVec3::new(p[4], p[5], p[6])) / wsum
    } else {
        centre
    };
    let pair = TurbidPair::new(cell, mean, centre, spec.cell);
    origin_up = mean;
    origin_dn = mean;
    skip = None;
    normal = None;
    for ch in 0..w {
        let emitted: f64 = (0..n_dirs).map(|j| outgoing[j * w + ch]).sum();
        let a = intercepted[ch] - emitted;
        if a != 0.0 {
            out.absorbed_turbid.push((k as u32, ch));
            out.absorbed_val.push(a);
        }
    }
    Some(Emitter {
        origin_up,
        origin_dn,
        skip,
        normal,
        points: &[],
        ground: false,
        pair: Some(pair),
    })
}

/// Facet ref `r`: its front and back power scattered Lambertian (exact or cosine fractions) or
/// with its RPV/Hapke slot rows into `outgoing` (physics.md §5.1), the absorbed rest booked.
fn facet_emitter<'s>(
    ctx: &Ctx,
    st: &'s Stores,
    r: usize,
    fractions: &[(Vec<f32>, Vec<f32>)],
    outgoing: &mut [f64],
    out: &mut ChunkOut,
) -> Emitter<'s> {
    let (w, nb, ns, n_dirs) = (ctx.w, ctx.nb, ctx.n_slots, ctx.n_dirs);
    let grid = ctx.inp.grid;
    let (origin_up, origin_dn, skip, normal, points);
    let f = grid.facet_ids[r];
    let (fr, bk) = &fractions[f as usize];
    let bi = ctx.brdf_ref.get(r).copied().unwrap_or(u32::MAX);
    if bi != u32::MAX {
        // RPV/Hapke: rows of each incidence slot (the sun's last).
        let set = ctx.inp.facet_brdf[f as usize] as usize;
        let bi = bi as usize;
        scatter_slots(
            &st.fac_slot[bi * ns * w..(bi + 1) * ns * w],
            (w, nb, n_dirs),
            |b, slot| ctx.facet_row(set, b, slot),
            outgoing,
            |ch, a| {
                out.absorbed_facet.push((f, ch));
                out.absorbed_val.push(a);
            },
        );
    }
    for ch in (0..w).filter(|_| bi == u32::MAX) {
        let (a, b) = (st.fac_front[r * w + ch], st.fac_back[r * w + ch]);
        for j in 0..n_dirs {
            outgoing[j * w + ch] += a * fr[j] as f64 + b * bk[j] as f64;
        }
        let emitted: f64 = (0..n_dirs).map(|j| outgoing[j * w + ch]).sum();
        let lossy = a + b - emitted;
        if lossy != 0.0 {
            out.absorbed_facet.push((f, ch));
            out.absorbed_val.push(lossy);
        }
    }
    let fa = &ctx.inp.facets[f as usize];
    let centroid = (fa.v[0] + fa.v[1] + fa.v[2]) / 3.0;
    points = st.fac_pts.of(r);
    origin_up = centroid;
    origin_dn = centroid;
    skip = Some(f);
    normal = Some((fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize());
    Emitter {
        origin_up,
        origin_dn,
        skip,
        normal,
        points,
        ground: false,
        pair: None,
    }
}

/// Ground column `c`: its power scattered Lambertian or with the ground BRDF's slot rows into
/// `outgoing` (physics.md §5.2), the absorbed rest booked.
fn ground_emitter<'s>(
    ctx: &Ctx,
    st: &'s Stores,
    c: usize,
    ground_fr: &[f64],
    outgoing: &mut [f64],
    out: &mut ChunkOut,
) -> Emitter<'s> {
    let (w, nb, ns, n_dirs) = (ctx.w, ctx.nb, ctx.n_slots, ctx.n_dirs);
    let spec = ctx.inp.spec;
    let (origin_up, origin_dn, skip, normal, points, ground);
    if ctx.inp.ground_brdf.is_some() {
        scatter_slots(
            &st.gnd[c * ns * w..(c + 1) * ns * w],
            (w, nb, n_dirs),
            |b, slot| ctx.ground_row(b, slot),
            outgoing,
            |ch, a| {
                out.absorbed_ground.push((c as u32, ch));
                out.absorbed_val.push(a);
            },
        );
    } else {
        for ch in 0..w {
            let a = st.gnd[c * w + ch];
            for j in 0..n_dirs {
                outgoing[j * w + ch] += a * ground_fr[j];
            }
            let emitted: f64 = (0..n_dirs).map(|j| outgoing[j * w + ch]).sum();
            if a - emitted != 0.0 {
                out.absorbed_ground.push((c as u32, ch));
                out.absorbed_val.push(a - emitted);
            }
        }
    }
    let o = cell_centre(spec, c);
    points = st.gnd_pts.of(c);
    ground = true;
    origin_up = DVec3::new(o.x, o.y, spec.origin.z);
    origin_dn = origin_up;
    skip = None;
    normal = None;
    Emitter {
        origin_up,
        origin_dn,
        skip,
        normal,
        points,
        ground,
        pair: None,
    }
}

/// Sends an emitter's `outgoing` power along every tiling direction: from the cell's two
/// emission points per direction (turbid, `split`: [`TurbidPair`]) or from each scattering
/// point; first-order sun
/// rays (`first`) with the hotspot correlation.
pub(in crate::radiative) fn send_emitter(
    ctx: &Ctx,
    src: &Emitter,
    split: bool,
    first: bool,
    outgoing: &[f64],
    pw: &mut [f64],
    out: &mut ChunkOut,
) {
    let (w, n_dirs) = (ctx.w, ctx.n_dirs);
    let spec = ctx.inp.spec;
    let tiling = ctx.inp.dirs.tiling();
    let Emitter {
        origin_up,
        origin_dn,
        skip,
        normal,
        points,
        ground,
        pair,
    } = *src;
    // First-order sun rays (what turbid cells, facets and the ground scatter of the
    // direct beam) get the hotspot correlation through turbid cells on their way up.
    let hs = first && ctx.inp.emitters.is_empty();
    // Horizontal size of the emitting element, for the image footprints: a turbid
    // cell, a facet or ground sub-cell, or (no scattering point) a column / a point.
    out.foot = if split || (ground && points.is_empty()) {
        (spec.cell.x, spec.cell.y)
    } else if points.is_empty() {
        (0.0, 0.0)
    } else {
        let d = ctx.sub as f64;
        (spec.cell.x / d, spec.cell.y / d)
    };
    let t_kernel = std::time::Instant::now();
    // Rays without the hotspot go to the batched walk's queue (see
    // `Ctx::trace_any`).
    let dense = matches!(out.tur.as_deref(), Some(TurAcc::Dense { .. }));
    for j in 0..n_dirs {
        let v = &outgoing[j * w..(j + 1) * w];
        if v.iter().all(|&x| x == 0.0) {
            continue;
        }
        if split {
            // Two-point quadrature of the interception distribution: half the power
            // from the barycentre of each half of the intercepted energy.
            let hs_j = hs && ctx.hs_dir[j];
            let pts = pair.map_or([(origin_up, 0.5), (origin_dn, 0.5)], |p| {
                p.points(ctx, origin_up, j)
            });
            for (o, share) in pts {
                if walk::select(ctx, hs_j, dense).batched() {
                    // What `send` does for this ray (powers v · share, then
                    // `Ctx::queue`).
                    ctx.queue_scaled(o, j, v, share, out);
                } else {
                    send(ctx, o, j, None, v, share, hs_j, pw, out);
                }
            }
            continue;
        }
        let fallback = [(
            if tiling[j].omega.z > 0.0 {
                origin_up
            } else {
                origin_dn
            },
            1.0,
        )];
        let pts = if points.is_empty() {
            &fallback[..]
        } else {
            points
        };
        for &(pt, share) in pts {
            let mut origin = if ground {
                DVec3::new(pt.x, pt.y, spec.origin.z)
            } else {
                pt
            };
            if let Some(n) = normal {
                // Start just off the facet on the side the ray leaves through.
                let side = n.dot(tiling[j].omega).signum();
                origin += n * side * 1e-9 * spec.cell.min_element();
            }
            // Continuous topography (issue #31): DEM ground facet footprints on their
            // sub-cell column (see `ChunkOut::foot_shift`).
            if spec.boundary == BoundaryMode::RepetitiveContinuousTopography
                && !points.is_empty()
                && skip.is_some_and(|f| ctx.inp.facets[f as usize].kind == FacetKind::Ground)
            {
                let centre = |x: f64, o: f64, c: f64| {
                    let s = c / ctx.sub as f64;
                    o + ((x - o) / s).floor() * s + 0.5 * s
                };
                out.foot_shift = (
                    centre(pt.x, spec.origin.x, spec.cell.x) - pt.x,
                    centre(pt.y, spec.origin.y, spec.cell.y) - pt.y,
                );
            }
            let hs_j = hs && ctx.hs_dir[j];
            send(ctx, origin, j, skip, v, share, hs_j, pw, out);
            out.foot_shift = (0.0, 0.0);
        }
    }
    out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
}

/// Scratch arrays of [`emit_turbid_records`].
#[derive(Default)]
pub(in crate::radiative) struct RecScratch {
    pub(in crate::radiative) outgoing: Vec<f64>,
    pub(in crate::radiative) intercepted: Vec<f64>,
    pub(in crate::radiative) emitted: Vec<f64>,
    /// `Blend`: power one slot sends along each direction (channels summed), W.
    pub(in crate::radiative) cj: Vec<f64>,
    /// `Blend`: per direction Σ c·p_up (3), Σ c·p_down (3), Σ c.
    pub(in crate::radiative) acc: Vec<[f64; 7]>,
    /// Exit groups.
    pub(in crate::radiative) ex: ExitGroups,
}

/// Rays leaving one turbid cell, grouped per (direction, exit store) (DART 5 paper Figure 7c).
#[derive(Default)]
pub(in crate::radiative) struct ExitGroups {
    /// Exit stores per cell (6 D² + 1; see [`Ctx::entry_store`]).
    pub(in crate::radiative) n_exit: usize,
    /// Exit groups `[direction][exit store]`: W per channel, Σ W·q (3), Σ W.
    pub(in crate::radiative) group: Vec<f64>,
    /// Whether each exit group holds something.
    pub(in crate::radiative) flag: Vec<bool>,
    /// Exit groups holding something (`direction × n_exit + exit store`).
    pub(in crate::radiative) touched: Vec<u32>,
}

/// Scatters the turbid stores of one entry in the `Faces`, `Subfaces` and `Blend` modes (DART 5
/// paper §3.2, Figure 7; physics.md §3.6, §6.3): `recs` are the entry's records (see
/// [`TurRecords`]). Each record's power per slot goes along every direction j with the slot's
/// phase row (the sun's row for the sun slot), as in `Off`. `Faces`/`Subfaces`: each non-empty
/// incident store sends its own power from its own two points ([`TurbidPair`] about the
/// store's barycentre). `Blend`: one pair of rays per direction j, about the barycentre of the
/// per-slot points weighted by the power each slot sends into j. With `turbid_exit_grouping` (cells without facets) the rays of all the
/// entry's stores are first followed to the cell's exit by [`Ctx::to_exit`] and then traced
/// merged, one per (direction, exit face or sub-face) from the power-weighted barycentre of the
/// exit points (Figure 7c); first-order sun rays with the hotspot correlation are traced from
/// their own points (the correlation depends on the path from the scattering point). The power
/// not scattered is booked as absorbed by the entry.
pub(in crate::radiative) fn emit_turbid_records(
    ctx: &Ctx,
    st: &Stores,
    recs: &[u32],
    hs: bool,
    sc: &mut RecScratch,
    pw: &mut [f64],
    out: &mut ChunkOut,
) {
    let (w, n_dirs) = (ctx.w, ctx.n_dirs);
    let spec = ctx.inp.spec;
    let tr = &st.trec;
    let k = tr.keys[recs[0] as usize] as usize / ctx.tstores;
    let ent = &ctx.inp.grid.turbid[k];
    let TrackOptics::Turbid { tables, .. } = &ctx.inp.optics[ent.material as usize] else {
        return;
    };
    let tm = ctx.tur_mat[ent.material as usize] as usize;
    let centre = cell_centre(spec, ctx.entry_cell[k] as usize);
    sc.outgoing.resize(n_dirs * w, 0.0);
    sc.intercepted.clear();
    sc.intercepted.resize(w, 0.0);
    sc.emitted.clear();
    sc.emitted.resize(w, 0.0);
    let blend = ctx.subfaces == TurbidSubfaces::Blend;
    let cell = ctx.entry_cell[k] as usize;
    let cr = ctx.cells[cell];
    // Exit grouping (Figure 7c) in cells without facets (a facet could be hit before the exit).
    let group = !blend && ctx.inp.params.turbid_exit_grouping && cr.fac_lo == cr.fac_hi;
    if group {
        sc.ex.n_exit = 6 * (ctx.face_d * ctx.face_d) as usize + 1;
        let n = n_dirs * sc.ex.n_exit;
        if sc.ex.flag.len() != n {
            sc.ex.flag = vec![false; n];
            sc.ex.group = vec![0.0; n * (w + 4)];
        }
    }
    if blend {
        sc.cj.resize(n_dirs, 0.0);
        sc.acc.clear();
        sc.acc.resize(n_dirs, [0.0; 7]);
    }
    out.foot = (spec.cell.x, spec.cell.y);
    let sun_row = tables[0].sun_row().unwrap_or(0);
    let power = |r: u32| -> f64 {
        let r = r as usize;
        tr.pow[r * tr.ns_w..(r + 1) * tr.ns_w].iter().sum()
    };
    let total: f64 = recs.iter().map(|&r| power(r)).sum();
    for &r in recs {
        // The store's rays are dropped below its share of the threshold of the entry's rays:
        // splitting an entry's emission into stores does not make its rays less significant.
        out.ray_scale = if blend || total <= 0.0 {
            1.0
        } else {
            power(r) / total
        };
        let r = r as usize;
        sc.outgoing.iter_mut().for_each(|v| *v = 0.0);
        scatter_record(ctx, tr, r, (tables, tm, sun_row), blend, centre, sc);
        let rec_mean = if blend {
            centre
        } else {
            let (pu, pd) = half_points(&tr.pts[r * 8..r * 8 + 8], centre);
            0.5 * (pu + pd)
        };
        let rec_pair = TurbidPair::new(cell, rec_mean, centre, spec.cell);
        let t_kernel = std::time::Instant::now();
        // Rays without the hotspot go to the batched walk's queue (see `Ctx::trace_any`).
        let dense = matches!(out.tur.as_deref(), Some(TurAcc::Dense { .. }));
        for j in 0..n_dirs {
            let v = &sc.outgoing[j * w..(j + 1) * w];
            if v.iter().all(|&x| x == 0.0) {
                continue;
            }
            for (e, x) in sc.emitted.iter_mut().zip(v) {
                *e += x;
            }
            let pts = if blend {
                let a = &sc.acc[j];
                if a[6] > 0.0 {
                    let m = (DVec3::new(a[0], a[1], a[2]) + DVec3::new(a[3], a[4], a[5]))
                        / (2.0 * a[6]);
                    TurbidPair::new(cell, m, centre, spec.cell).points(ctx, m, j)
                } else {
                    TurbidPair::new(cell, centre, centre, spec.cell).points(ctx, centre, j)
                }
            } else {
                rec_pair.points(ctx, rec_mean, j)
            };
            // Two-point quadrature of the store's interception distribution.
            let hs_j = hs && ctx.hs_dir[j];
            for (o, share) in pts {
                if group && !hs_j {
                    ctx.to_exit(cell, o, j, v, share, &mut sc.ex, pw, out);
                } else if walk::select(ctx, hs_j, dense).batched() {
                    // What `send` does for this ray (powers v · share, then `Ctx::queue`).
                    ctx.queue_scaled(o, j, v, share, out);
                } else {
                    send(ctx, o, j, None, v, share, hs_j, pw, out);
                }
            }
        }
        out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
    }
    if group {
        trace_exit_groups(ctx, &mut sc.ex, pw, out);
    }
    out.ray_scale = 1.0;
    for ch in 0..w {
        let a = sc.intercepted[ch] - sc.emitted[ch];
        if a != 0.0 {
            out.absorbed_turbid.push((k as u32, ch));
            out.absorbed_val.push(a);
        }
    }
}

/// The barycentres of the first and second halves of a points record's intercepted energy
/// (`[Σ wt p₁ (3), Σ wt, Σ wt p₂ (3), Σ wt]`), `centre` for an empty half.
fn half_points(p: &[f64], centre: DVec3) -> (DVec3, DVec3) {
    let up = if p[3] > 0.0 {
        DVec3::new(p[0], p[1], p[2]) / p[3]
    } else {
        centre
    };
    let dn = if p[7] > 0.0 {
        DVec3::new(p[4], p[5], p[6]) / p[7]
    } else {
        centre
    };
    (up, dn)
}

/// One record `r` of [`emit_turbid_records`]: its power per slot along every direction with the
/// slot's phase row (the sun's row for the sun slot; `rows`: the material's tables, turbid
/// material slot and sun row) into `sc.outgoing`, its intercepted power into
/// `sc.intercepted`; `blend`: the per-direction power-weighted points into `sc.acc`.
fn scatter_record(
    ctx: &Ctx,
    tr: &TurRecords,
    r: usize,
    (tables, tm, sun_row): (&[PhaseTable], usize, usize),
    blend: bool,
    centre: DVec3,
    sc: &mut RecScratch,
) {
    let (w, nb, ns, n_dirs) = (ctx.w, ctx.nb, ctx.n_slots, ctx.n_dirs);
    for slot in 0..ns {
        let base = (r * ns + slot) * w;
        let wv = &tr.pow[base..base + w];
        if wv.iter().all(|&v| v == 0.0) {
            continue;
        }
        if blend {
            sc.cj.iter_mut().for_each(|v| *v = 0.0);
        }
        for ch in 0..w {
            let val = wv[ch];
            if val == 0.0 {
                continue;
            }
            sc.intercepted[ch] += val;
            let mut put = |j: usize, t: f64| {
                let c = val * t;
                sc.outgoing[j * w + ch] += c;
                if blend {
                    sc.cj[j] += c;
                }
            };
            if slot == ns - 1 {
                let trow = tables[ch % nb].row(sun_row);
                for (j, &t) in trow.iter().take(n_dirs).enumerate() {
                    put(j, t as f64);
                }
            } else {
                let trow = ctx.slot_row(tm, ch % nb, slot);
                for (j, &t) in trow.iter().enumerate() {
                    put(j, t);
                }
            }
        }
        if blend {
            let pb = (r * ns + slot) * 8;
            let (pu, pd) = half_points(&tr.pts[pb..pb + 8], centre);
            for (a, &c) in sc.acc.iter_mut().zip(&sc.cj) {
                if c != 0.0 {
                    a[0] += c * pu.x;
                    a[1] += c * pu.y;
                    a[2] += c * pu.z;
                    a[3] += c * pd.x;
                    a[4] += c * pd.y;
                    a[5] += c * pd.z;
                    a[6] += c;
                }
            }
        }
    }
}

/// The rays of a cell's stores that left it through the same exit store along the same
/// direction, merged and traced (DART 5 paper §3.2, Figure 7c): one ray per (exit sub-face,
/// direction) from the power-weighted barycentre of their exit points; `ex` emptied.
fn trace_exit_groups(ctx: &Ctx, ex: &mut ExitGroups, pw: &mut [f64], out: &mut ChunkOut) {
    let w = ctx.w;
    // The rays that left the cell through the same exit store along the same direction,
    // merged (DART 5 paper §3.2, Figure 7c): one ray per (exit sub-face, direction) from
    // the power-weighted barycentre of their exit points.
    let t_kernel = std::time::Instant::now();
    let ne = ex.n_exit;
    ex.touched.sort_unstable();
    let mut n = 0;
    while n < ex.touched.len() {
        let j = ex.touched[n] as usize / ne;
        let mut m = n;
        let mut total = 0.0;
        while m < ex.touched.len() && ex.touched[m] as usize / ne == j {
            total += ex.group[ex.touched[m] as usize * (w + 4) + w + 3];
            m += 1;
        }
        for &g in &ex.touched[n..m] {
            let g = g as usize * (w + 4);
            let rec = &mut ex.group[g..g + w + 4];
            let wt = rec[w + 3];
            if wt > 0.0 {
                let o = DVec3::new(rec[w], rec[w + 1], rec[w + 2]) / wt;
                pw.copy_from_slice(&rec[..w]);
                out.ray_scale = if total > 0.0 { wt / total } else { 1.0 };
                ctx.trace(o, j, None, pw, out);
            }
            rec.iter_mut().for_each(|x| *x = 0.0);
        }
        n = m;
    }
    for &g in &ex.touched {
        ex.flag[g as usize] = false;
    }
    ex.touched.clear();
    out.kernel_seconds += t_kernel.elapsed().as_secs_f64();
}

/// Scatters one element's power stored per incidence slot (`stored[slot · w + ch]`, w channels
/// of `nb` bands) with each slot's row (`row(band, slot)`, over the tiling directions) into
/// `outgoing[dir · w + ch]`, and reports per channel the stored power not scattered
/// (absorbed, W) through `absorbed(ch, W)` when it is not zero.
pub(in crate::radiative) fn scatter_slots<'r>(
    stored: &[f64],
    (w, nb, n_dirs): (usize, usize, usize),
    row: impl Fn(usize, usize) -> &'r [f64],
    outgoing: &mut [f64],
    mut absorbed: impl FnMut(usize, f64),
) {
    let ns = stored.len() / w;
    for ch in 0..w {
        let b = ch % nb;
        let mut a = 0.0;
        for slot in 0..ns {
            let val = stored[slot * w + ch];
            if val == 0.0 {
                continue;
            }
            a += val;
            let r = row(b, slot);
            for j in 0..n_dirs {
                outgoing[j * w + ch] += val * r[j];
            }
        }
        let emitted: f64 = (0..n_dirs).map(|j| outgoing[j * w + ch]).sum();
        if a - emitted != 0.0 {
            absorbed(ch, a - emitted);
        }
    }
}
