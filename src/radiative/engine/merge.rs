//! The chunk merge: chunk outputs are added into the stores and the result in chunk order
//! (bit-identical products on any thread count; physics.md §6.4).

use super::*;

/// Merges one chunk output into the stores and the result (called in chunk order by
/// [`stream_chunks`]); `esc` gets the escaped power per channel.
pub(in crate::radiative) fn merge_one(
    ctx: &Ctx,
    out: &ChunkOut,
    st: &mut Stores,
    res: &mut RadiativeResult,
    esc: &mut [f64],
) {
    let w = ctx.w;
    let mut scratch = crate::radiative::images::SpreadScratch::default();
    debug_assert!(out.queue.is_empty(), "every queued ray walked");
    res.rays += out.rays;
    res.crossings += out.crossings;
    res.skipped += out.skipped;
    res.kernel_seconds += out.kernel_seconds;
    add(&mut res.escaped, &out.escaped);
    for (k, v) in out.escaped.iter().enumerate() {
        esc[k % w] += v;
    }
    add(&mut res.lost, &out.lost);
    merge_images(ctx, out, res, &mut scratch);
    merge_turbid(ctx, out, st, res);
    merge_facets(ctx, out, st, res);
    merge_ground(ctx, out, st, res);
    for (k, &(e, ch)) in out.absorbed_turbid.iter().enumerate() {
        res.absorbed_turbid[e as usize * w + ch] += out.absorbed_val[k];
    }
    let off = out.absorbed_turbid.len();
    for (k, &(f, ch)) in out.absorbed_facet.iter().enumerate() {
        res.absorbed_facet[f as usize * w + ch] += out.absorbed_val[off + k];
    }
    let off = off + out.absorbed_facet.len();
    for (k, &(c, ch)) in out.absorbed_ground.iter().enumerate() {
        res.absorbed_ground[c as usize * w + ch] += out.absorbed_val[off + k];
    }
}

/// After the last chunk of a pass: the scattering points of the stores sorted and turned into
/// barycentres.
pub(in crate::radiative) fn finish_merge(ctx: &Ctx, st: &mut Stores) {
    st.fac_pts.finish(ctx.inp.grid.facet_ids.len());
    st.trec.finish();
    let spec = ctx.inp.spec;
    st.gnd_pts.finish(spec.n[0] * spec.n[1]);
}

/// One output's image events: power spread over the pixels under the footprint, in event
/// order (physics.md §7.2).
fn merge_images(
    ctx: &Ctx,
    out: &ChunkOut,
    res: &mut RadiativeResult,
    scratch: &mut crate::radiative::images::SpreadScratch,
) {
    let w = ctx.w;
    // Image events: power spread over the pixels under the footprint, in event order.
    let npx = ctx.image_grid.pixels();
    for (n, &img) in out.img_key.iter().enumerate() {
        let [x, y, fx, fy] = out.img_pos[n];
        let v = &out.img_val[n * w..(n + 1) * w];
        let image = &mut res.images[img as usize * npx * w..(img as usize + 1) * npx * w];
        let grid = &ctx.image_grid;
        if w == 2 {
            // Two channels (the common case): the pixel rows as pairs, the same operations.
            let rows = image.as_chunks_mut::<2>().0;
            let v = [v[0], v[1]];
            grid.spread((x, y), (fx, fy), scratch, |px, share| {
                let r = &mut rows[px];
                r[0] += v[0] * share;
                r[1] += v[1] * share;
            });
        } else {
            grid.spread((x, y), (fx, fy), scratch, |px, share| {
                for (r, p) in image[px * w..(px + 1) * w].iter_mut().zip(v) {
                    *r += p * share;
                }
            });
        }
    }
}

/// One output's turbid interceptions into the stores (per entry and slot, or per incident
/// (sub-)face record) and the intercepted products.
fn merge_turbid(ctx: &Ctx, out: &ChunkOut, st: &mut Stores, res: &mut RadiativeResult) {
    let (w, ns) = (ctx.w, ctx.n_slots);
    let acc = &out.ctur;
    if ctx.subfaces != TurbidSubfaces::Off {
        {
            let tr = &mut st.trec;
            acc.for_each_tur(|key, v| {
                let t = (key / ns as u64) as u32;
                let slot = (key % ns as u64) as usize;
                let r = tr.rec(t);
                let e = t as usize / ctx.tstores;
                let rec = &mut tr.pow[(r * ns + slot) * w..(r * ns + slot + 1) * w];
                let it = &mut res.intercepted_turbid[e * w..(e + 1) * w];
                for ((p, i), x) in rec.iter_mut().zip(it.iter_mut()).zip(v) {
                    *p += x;
                    *i += x;
                }
            });
            let np = tr.np as u64;
            acc.for_each_pts(|key, v| {
                let r = tr.rec((key / np) as u32);
                let q = (key % np) as usize;
                let p = &mut tr.pts[(r * tr.np + q) * 8..(r * tr.np + q + 1) * 8];
                for a in 0..3 {
                    p[a] += v[a];
                    p[4 + a] += v[3 + a];
                }
                p[3] += v[6];
                p[7] += v[6];
            });
        }
    } else {
        acc.for_each_tur(|key, v| {
            let e = key as usize / ns;
            let base = key as usize * w;
            for ch in 0..w {
                st.tur[base + ch] += v[ch];
                res.intercepted_turbid[e * w + ch] += v[ch];
            }
        });
    }
    if ctx.subfaces == TurbidSubfaces::Off {
        // Barycentres of the first and second halves of the intercepted energy.
        acc.for_each_pts(|e, v| {
            let pts = &mut st.tur_pts[e as usize];
            for a in 0..3 {
                pts[a] += v[a];
                pts[4 + a] += v[3 + a];
            }
            pts[3] += v[6];
            pts[7] += v[6];
        });
        // The single-precision walk's records, from their cell's frame: Σ wt (c + p) =
        // c Σ wt + Σ wt p, c the cell's corner.
        acc.for_each_pts_local(|e, v| {
            let spec = ctx.inp.spec;
            let [i, j, k] = spec.ijk(ctx.entry_cell[e as usize] as usize);
            let c = spec.origin + DVec3::new(i as f64, j as f64, k as f64) * spec.cell;
            let pts = &mut st.tur_pts[e as usize];
            for a in 0..3 {
                pts[a] += c[a] * v[6] + v[a];
                pts[4 + a] += c[a] * v[6] + v[3 + a];
            }
            pts[3] += v[6];
            pts[7] += v[6];
        });
    }
}

/// One output's facet hits into the facet stores and points, with the absorbed part of
/// Lambertian facets booked (physics.md §5.1).
fn merge_facets(ctx: &Ctx, out: &ChunkOut, st: &mut Stores, res: &mut RadiativeResult) {
    let (w, ns) = (ctx.w, ctx.n_slots);
    let stride = w + 4;
    for (n, &(r, f, from_front, sub, slot)) in out.fac_key.iter().enumerate() {
        let v = &out.fac_val[n * stride..(n + 1) * stride];
        let fa = &ctx.inp.facets[f as usize];
        if let Some(&bi) = ctx.brdf_ref.get(r as usize)
            && bi != u32::MAX
        {
            // RPV/Hapke: stored whole per incidence slot; absorption booked at emission.
            for ch in 0..w {
                res.intercepted_facet[f as usize * w + ch] += v[ch];
                st.fac_slot[(bi as usize * ns + slot as usize) * w + ch] += v[ch];
            }
            st.fac_pts
                .add(r, sub, DVec3::new(v[w], v[w + 1], v[w + 2]), v[w + 3]);
            continue;
        }
        let (rr, tt) = match &ctx.inp.optics[fa.material as usize] {
            TrackOptics::Lambert { r, t, .. } => (r.as_slice(), t.as_slice()),
            _ => (&[][..], &[][..]),
        };
        for ch in 0..w {
            let b = ch % ctx.nb;
            let (rb, tb) = (
                rr.get(b).copied().unwrap_or(0.0),
                tt.get(b).copied().unwrap_or(0.0),
            );
            let i = v[ch];
            res.intercepted_facet[f as usize * w + ch] += i;
            res.absorbed_facet[f as usize * w + ch] += i * (1.0 - rb - tb);
            // Reflected to the incidence side, transmitted to the other side.
            let (to_front, to_back) = if from_front {
                (rb * i, tb * i)
            } else {
                (tb * i, rb * i)
            };
            st.fac_front[r as usize * w + ch] += to_front;
            st.fac_back[r as usize * w + ch] += to_back;
        }
        st.fac_pts
            .add(r, sub, DVec3::new(v[w], v[w + 1], v[w + 2]), v[w + 3]);
    }
}

/// One output's ground hits into the ground stores and points (physics.md §5.2).
fn merge_ground(ctx: &Ctx, out: &ChunkOut, st: &mut Stores, res: &mut RadiativeResult) {
    let (w, ns) = (ctx.w, ctx.n_slots);
    let stride = w + 4;
    let gr = ctx.inp.flat_ground.as_deref().unwrap_or(&[]);
    let brdf = ctx.inp.ground_brdf.is_some();
    for (n, &(col, slot, sub)) in out.gnd_key.iter().enumerate() {
        let v = &out.gnd_val[n * stride..(n + 1) * stride];
        for ch in 0..w {
            res.intercepted_ground[col as usize * w + ch] += v[ch];
            if brdf {
                // Stored whole per incidence slot; absorption is booked at emission.
                st.gnd[(col as usize * ns + slot as usize) * w + ch] += v[ch];
            } else {
                let rb = gr.get(ch % ctx.nb).copied().unwrap_or(0.0);
                res.absorbed_ground[col as usize * w + ch] += v[ch] * (1.0 - rb);
                st.gnd[col as usize * w + ch] += v[ch] * rb;
            }
        }
        st.gnd_pts
            .add(col, sub, DVec3::new(v[w], v[w + 1], v[w + 2]), v[w + 3]);
    }
}
