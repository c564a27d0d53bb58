//! The passive Monte Carlo run (DART 5 paper §4; Gastellu-Etchegorry et al. 2016, eqs. 1–3):
//! sun and sky photons in seeded batches (one `Xoshiro256PlusPlus` stream per batch), merged in
//! batch order into a [`PhotonResult`] with standard errors; in a thermal run, emission and
//! thermal sky photons instead ([`super::emission`]).

use super::context::{Bands, Ctx, Photon};
use super::emission::{EmissionTable, Emitter, THERMAL_STREAM, launch_emission};
use super::input::PhotonInput;
use super::result::PhotonResult;
use super::tally::{Acc, BatchOut};
use super::trace::trace_photon;
use crate::photon::sampling::{Uniform01, sample_cosine_hemisphere};
use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// Runs the Monte Carlo simulation.
pub fn run(inp: &PhotonInput) -> PhotonResult {
    let spec = inp.spec;
    let nb = inp.e_dir.len();
    // A thermal run (issue #34): channels [sun (zero), thermal]; its sky is the thermal one.
    let thermal = inp.thermal.is_some();
    let has_sky = !thermal && inp.e_diff.iter().any(|&e| e > 0.0);
    let w = nb * if has_sky || thermal { 2 } else { 1 };
    let n_dirs = inp.dirs.tiling().len();
    let ctx = Ctx::new(inp, nb, w);
    let table = EmissionTable::new(&ctx);
    let area = ctx.size.0 * ctx.size.1;
    let mut source = vec![0.0; w];
    for b in 0..nb {
        // Continuous topography (issue #31): the sun's launch region follows the staircase
        // of tile tops (`GridSpec::topo_launch_span`; X·Y without the offset).
        source[b] = if spec.topography_offset != (0.0, 0.0) {
            inp.e_dir[b] * spec.topo_launch_area(ctx.size, inp.sun)
        } else {
            inp.e_dir[b] * area
        };
        if has_sky {
            source[nb + b] = inp.e_diff[b] * area;
        }
        if thermal {
            source[nb + b] = table.emitted[b] + table.sky[b];
        }
    }
    let n_batches = inp.params.batches.max(1) as u64;
    let per_batch = inp.params.photons.div_ceil(n_batches).max(1);
    let n_entries = inp.grid.turbid.len();
    let n_facets = inp.facets.len();
    let n_cols = spec.n[0] * spec.n[1];
    let mut res = PhotonResult {
        n_channels: w,
        n_bands: nb,
        has_sky,
        has_thermal: thermal,
        thermal_sky_source: table.sky.clone(),
        source: source.clone(),
        escaped: vec![0.0; n_dirs * w],
        peel: vec![0.0; inp.views.len() * w],
        absorbed_turbid: vec![0.0; n_entries * w],
        intercepted_turbid: vec![0.0; n_entries * w],
        absorbed_facet: vec![0.0; n_facets * w],
        intercepted_facet: vec![0.0; n_facets * w],
        absorbed_ground: vec![0.0; n_cols * w],
        intercepted_ground: vec![0.0; n_cols * w],
        lost: vec![0.0; w],
        roulette: vec![0.0; w],
        summary: ctx.sum.clone(),
        photons: per_batch * n_batches,
        camera: vec![0.0; ctx.cam_len],
        camera_sq: vec![0.0; ctx.cam_len / w * nb],
        camera_mean_sq: vec![0.0; ctx.cameras.len() * nb],
        ..Default::default()
    };
    let mut fluid_abs: std::collections::BTreeMap<u32, Vec<f64>> = Default::default();
    // Batches run in waves (bounded memory); merged in batch order.
    let wave = 16u64;
    let mut b0 = 0u64;
    while b0 < n_batches {
        let b1 = (b0 + wave).min(n_batches);
        let outs: Vec<BatchOut> = (b0..b1)
            .into_par_iter()
            .map(|b| {
                if thermal {
                    run_thermal_batch(&ctx, &table, b, per_batch)
                } else {
                    run_batch(&ctx, b, per_batch, &source)
                }
            })
            .collect();
        for o in outs {
            let s = &o.summary;
            for j in 0..n_dirs {
                for ch in 0..w {
                    res.escaped[j * w + ch] += s[ctx.sum.dir(j, ch)];
                }
            }
            for v in 0..inp.views.len() {
                for ch in 0..w {
                    res.peel[v * w + ch] += s[ctx.sum.view(v, ch)];
                }
            }
            o.abs_tur.add_into(&mut res.absorbed_turbid);
            o.int_tur.add_into(&mut res.intercepted_turbid);
            o.abs_fac.add_into(&mut res.absorbed_facet);
            o.int_fac.add_into(&mut res.intercepted_facet);
            o.abs_gnd.add_into(&mut res.absorbed_ground);
            o.int_gnd.add_into(&mut res.intercepted_ground);
            let mut keys: Vec<_> = o.abs_fluid.keys().copied().collect();
            keys.sort_unstable();
            for k in keys {
                let e = fluid_abs.entry(k).or_insert_with(|| vec![0.0; w]);
                e.iter_mut()
                    .zip(&o.abs_fluid[&k])
                    .for_each(|(a, b)| *a += b);
            }
            res.lost.iter_mut().zip(&o.lost).for_each(|(a, b)| *a += b);
            res.roulette
                .iter_mut()
                .zip(&o.roulette)
                .for_each(|(a, b)| *a += b);
            res.events += o.events;
            res.crossings += o.crossings;
            res.skipped += o.skipped;
            res.batch_summaries.push(o.summary);
            // Camera pixels: the sum over batches, and per band the sum of squares of the
            // batch's sun + sky value (standard errors, `sensor_products`).
            for (px, v) in o.cams.chunks(w).enumerate() {
                for (ch, x) in v.iter().enumerate() {
                    res.camera[px * w + ch] += x;
                }
                for b in 0..nb {
                    let t = v[b] + if has_sky { v[nb + b] } else { 0.0 };
                    res.camera_sq[px * nb + b] += t * t;
                }
            }
            for (k, cp) in ctx.cameras.iter().enumerate() {
                let n = cp.cam.nx * cp.cam.ny;
                for b in 0..nb {
                    let m = o.cams[cp.base..cp.base + n * w]
                        .chunks(w)
                        .map(|v| v[b] + if has_sky { v[nb + b] } else { 0.0 })
                        .sum::<f64>()
                        / n as f64;
                    res.camera_mean_sq[k * nb + b] += m * m;
                }
            }
        }
        b0 = b1;
    }
    for (k, v) in fluid_abs {
        res.fluid_cells.push(k);
        res.absorbed_fluid.extend(v);
    }
    res
}

/// Photon stream purpose tag (see `random::stream`).
pub const PHOTON_STREAM: u64 = 0x5048_4f54_4f4e; // "PHOTON"

/// One batch of `n` photons (stream `batch` of the run's seed): each photon is launched
/// ([`launch_photon`]) and traced, then the batch's absorption summaries are booked
/// ([`book_summaries`]).
pub(crate) fn run_batch(ctx: &Ctx, batch: u64, n: u64, source: &[f64]) -> BatchOut {
    let inp = ctx.inp;
    let (nb, w) = (ctx.nb, ctx.w);
    let mut out = new_batch_out(ctx);
    let mut rng = crate::random::stream(inp.params.seed, PHOTON_STREAM, batch);
    let has_sky = w > nb;
    let n_total = n * inp.params.batches.max(1) as u64;
    // Sun and sky photons alternate inside the batch.
    let (n_sun, n_sky) = if has_sky {
        (n.div_ceil(2), n / 2)
    } else {
        (n, 0)
    };
    let tot_sun = n_total as f64 * n_sun as f64 / n as f64;
    let tot_sky = n_total as f64 * n_sky as f64 / n as f64;
    let n_tur = ctx.tur_ids.len();
    let mut g_cur = vec![0.0; n_tur];
    let mut scratch = vec![0.0; nb];
    let mut tr = vec![0.0; nb];
    let mut ph = new_photon(nb);
    for i in 0..n_sun + n_sky {
        let sky = i >= n_sun;
        let tot = if sky { tot_sky } else { tot_sun };
        if !launch_photon(ctx, &mut ph, &mut rng, &mut out, source, sky, tot) {
            continue;
        }
        ph.order = 0;
        ph.skip_facet = None;
        // Under an atmosphere, sun photons start at its top and reach the scene (if at all)
        // through it (`atmosphere::atmosphere_walk`).
        if let Some(atm) = inp.atmosphere
            && !super::atmosphere::atmosphere_walk(
                ctx,
                atm,
                &mut ph,
                atm.height_m(),
                &mut rng,
                &mut out,
            )
        {
            continue;
        }
        trace_photon(
            ctx,
            &mut ph,
            &mut rng,
            &mut out,
            &mut g_cur,
            &mut scratch,
            &mut tr,
        );
    }
    book_summaries(ctx, &mut out);
    out
}

/// One batch of `n` photons of a thermal run (stream `batch` of the run's seed under
/// [`THERMAL_STREAM`]): each photon picks an emitting element or the sky from `table`
/// (probability ∝ its band-summed power), is launched from it ([`launch_emission`], or like a
/// solar sky photon on the thermal channels) and traced.
pub(crate) fn run_thermal_batch(ctx: &Ctx, table: &EmissionTable, batch: u64, n: u64) -> BatchOut {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let mut out = new_batch_out(ctx);
    if table.total() <= 0.0 {
        return out;
    }
    let mut rng = crate::random::stream(inp.params.seed, THERMAL_STREAM, batch);
    let n_total = (n * inp.params.batches.max(1) as u64) as f64;
    let n_tur = ctx.tur_ids.len();
    let mut g_cur = vec![0.0; n_tur];
    let mut scratch = vec![0.0; nb];
    let mut tr = vec![0.0; nb];
    let mut wb = vec![0.0; nb];
    let mut ph = new_photon(nb);
    // The sky's source as `launch_photon` reads it: weights P_b / (q N) over N photons.
    let mut sky_source = vec![0.0; 2 * nb];
    for _ in 0..n {
        let k = table.pick(rng.next_f64());
        table.weights(k, n_total, nb, &mut wb);
        // Per band the launched weight is random (elements differ in spectrum); its departure
        // from the nominal share of the source goes to the weight balance (expectation 0), so
        // the energy closes exactly.
        for b in 0..nb {
            out.roulette[nb + b] += (table.emitted[b] + table.sky[b]) / n_total - wb[b];
        }
        ph.order = 0;
        ph.skip_facet = None;
        ph.off = nb;
        let el = table.elements[k];
        let go = if matches!(el, Emitter::Sky) {
            sky_source[nb..].copy_from_slice(&wb);
            launch_photon(ctx, &mut ph, &mut rng, &mut out, &sky_source, true, 1.0)
        } else {
            ph.w.iter_mut().zip(&wb).for_each(|(w, x)| *w = *x);
            launch_emission(ctx, el, &mut ph, &mut rng, &mut out, &mut scratch, &mut tr)
        };
        if !go {
            continue;
        }
        ph.order = 0;
        trace_photon(
            ctx,
            &mut ph,
            &mut rng,
            &mut out,
            &mut g_cur,
            &mut scratch,
            &mut tr,
        );
    }
    book_summaries(ctx, &mut out);
    out
}

/// Step of [`run_batch`]: the batch's empty tallies.
fn new_batch_out(ctx: &Ctx) -> BatchOut {
    let inp = ctx.inp;
    let spec = inp.spec;
    let w = ctx.w;
    let n_entries = inp.grid.turbid.len();
    let n_cols = spec.n[0] * spec.n[1];
    BatchOut {
        summary: vec![0.0; ctx.sum.len()],
        abs_tur: Acc::new(n_entries, w),
        int_tur: Acc::new(n_entries, w),
        abs_fac: Acc::new(inp.facets.len(), w),
        int_fac: Acc::new(inp.facets.len(), w),
        abs_gnd: Acc::new(n_cols, w),
        int_gnd: Acc::new(n_cols, w),
        abs_fluid: HashMap::new(),
        lost: vec![0.0; w],
        roulette: vec![0.0; w],
        events: 0,
        crossings: 0,
        skipped: 0,
        wave: None,
        cams: vec![0.0; ctx.cam_len],
    }
}

/// Step of [`run_batch`]: the photon record reused by every photon of the batch (zeroed).
fn new_photon(nb: usize) -> Photon {
    Photon {
        p: DVec3::ZERO,
        d: DVec3::ZERO,
        path: 0.0,
        shift: DVec3::ZERO,
        di: 0,
        w: Bands::from_elem(0.0, nb),
        w0: 0.0,
        off: 0,
        order: 0,
        skip_facet: None,
        direct: false,
        ret: None,
        surface_scored: false,
        first_u: None,
        first_order_done: false,
        scatter_path: 0.0,
        hs_k: crate::photon::small::Small::from_elem(0.0, 0),
    }
}

/// Step of [`run_batch`]: launches one sun or sky photon at the top of the scene — position
/// (two uniforms), weight (`source` over `tot` photons of its kind), direction (the sun, or a
/// cosine-weighted sky direction) and, on continuous topography, the launch point over the
/// direction's launch region. False when the photon is not traced (zero weight, or lost or
/// weighted out at launch; booked in `out`).
fn launch_photon(
    ctx: &Ctx,
    ph: &mut Photon,
    rng: &mut rand_xoshiro::Xoshiro256PlusPlus,
    out: &mut BatchOut,
    source: &[f64],
    sky: bool,
    tot: f64,
) -> bool {
    let inp = ctx.inp;
    let spec = inp.spec;
    let nb = ctx.nb;
    let n_dirs = ctx.omega.len();
    let discrete = inp.params.sampler.is_discrete();
    let x = spec.origin.x + rng.next_f64() * ctx.size.0;
    let y = spec.origin.y + rng.next_f64() * ctx.size.1;
    ph.p = DVec3::new(x, y, spec.top());
    ph.off = if sky { nb } else { 0 };
    for b in 0..nb {
        ph.w[b] = if sky {
            source[nb + b] / tot
        } else {
            source[b] / tot
        };
    }
    ph.w0 = ph.w.iter().cloned().fold(0.0, f64::max);
    if ph.w0 <= 0.0 {
        return false;
    }
    if sky {
        // Isotropic sky: cosine-weighted downward directions.
        ph.d = sample_cosine_hemisphere(DVec3::NEG_Z, rng);
        if discrete {
            ph.di = inp.dirs.find_sector(ph.d);
            ph.d = ctx.omega[ph.di];
        }
    } else {
        ph.d = inp.sun;
        ph.di = n_dirs;
    }
    // Continuous topography (issue #31): the same two uniforms placed over the launch
    // region of the photon's direction (`GridSpec::topo_launch_point`); a sky photon's
    // weight scales with that region's area (mean X·Y over the cosine-weighted sky).
    if spec.topography_offset != (0.0, 0.0) {
        let (lx, ly) = spec.topo_launch_span(ph.d);
        let u = (x - spec.origin.x) / ctx.size.0 * (ctx.size.0 + lx);
        let v = (y - spec.origin.y) / ctx.size.1 * (ctx.size.1 + ly);
        if sky {
            // The weight change w (1 − f) has expectation 0 over the cosine-weighted sky
            // (E[L_x] = E[L_y] = 0; the corner term L_x L_y of two offsets is second
            // order): booked in the weight balance with the roulette's, so energy closes.
            let f = spec.topo_launch_area(ctx.size, ph.d) / (ctx.size.0 * ctx.size.1);
            for b in 0..nb {
                out.roulette[ph.off + b] += ph.w[b] * (1.0 - f);
            }
            ph.w.iter_mut().for_each(|w| *w *= f);
            ph.w0 *= f;
            if f <= 0.0 {
                return false;
            }
        }
        match spec.topo_launch_point(ctx.size, u, v, ph.d) {
            Some(p) => ph.p = p,
            None => {
                for b in 0..nb {
                    out.lost[ph.off + b] += ph.w[b];
                }
                return false;
            }
        }
    }
    true
}

/// Step of [`run_batch`]: the batch's absorption summaries (non-ground: turbid, non-ground
/// facets, fluids; ground: flat ground (booked per event) and DEM facets).
fn book_summaries(ctx: &Ctx, out: &mut BatchOut) {
    let w = ctx.w;
    let gf = ctx.inp.ground_facet;
    let mut absorbed = vec![0.0; w];
    let mut abs_dem = vec![0.0; w];
    let mut int_dem = vec![0.0; w];
    out.abs_tur
        .for_each(|_, v| absorbed.iter_mut().zip(v).for_each(|(a, x)| *a += x));
    out.abs_fac.for_each(|k, v| {
        let t = if gf.get(k as usize).copied().unwrap_or(false) {
            &mut abs_dem
        } else {
            &mut absorbed
        };
        t.iter_mut().zip(v).for_each(|(a, x)| *a += x)
    });
    out.int_fac.for_each(|k, v| {
        if gf.get(k as usize).copied().unwrap_or(false) {
            int_dem.iter_mut().zip(v).for_each(|(a, x)| *a += x)
        }
    });
    let mut keys: Vec<_> = out.abs_fluid.keys().copied().collect();
    keys.sort_unstable();
    for k in keys {
        absorbed
            .iter_mut()
            .zip(&out.abs_fluid[&k])
            .for_each(|(a, x)| *a += x);
    }
    for ch in 0..w {
        out.summary[ctx.sum.absorbed(ch)] += absorbed[ch];
        out.summary[ctx.sum.absorbed_ground(ch)] += abs_dem[ch];
        out.summary[ctx.sum.ground(ch)] += int_dem[ch];
    }
}
