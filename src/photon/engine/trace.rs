//! One photon's history (DART 5 paper §4, Ray-Carlo): flights, collisions with vegetation,
//! facets, fluids and the ground, scattering directions (physics.md §3.3, §5), peel-off at
//! every event and Russian roulette, until the photon escapes, is lost or dies.

use super::context::{Bands, Ctx, Hit, PerMaterial, Photon};
use super::events::{brdf_event, choose, far_roulette_survival, roulette_survives};
use super::input::{DiscreteRows, PhotonOptics};
use super::peel_off::turbid_peel_phase;
use super::tally::BatchOut;
use super::walk::{FLUID_BIT, return_transmittance};
use crate::photon::sampling::{Uniform01, sample_cosine_hemisphere, sample_fluid_phase};
use crate::photon::small::Small;
use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::PI;

/// One photon's history from its current state (DART 5 paper §4): a flight ([`flight`]), the
/// event at its end (escape, loss, or a turbid, fluid, facet or ground collision), then the
/// order, gate and roulette bookkeeping ([`next_order`]), until it escapes, is lost or dies.
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_photon(
    ctx: &Ctx,
    ph: &mut Photon,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    g_cur: &mut [f64],
    scratch: &mut [f64],
    tr: &mut [f64],
) {
    let nb = ctx.nb;
    let off = ph.off;
    loop {
        let (hit, ms_forced) = flight(ctx, ph, rng, out, g_cur, scratch, tr);
        match hit {
            Hit::Escape => {
                escape(ctx, ph, out);
                // Under an atmosphere the photon goes on up through it, and may come back.
                if let Some(atm) = ctx.inp.atmosphere
                    && super::atmosphere::atmosphere_walk(ctx, atm, ph, 0.0, rng, out)
                {
                    ph.scatter_path = ph.path;
                    continue;
                }
                return;
            }
            Hit::Lost => {
                for b in 0..nb {
                    out.lost[off + b] += ph.w[b];
                }
                return;
            }
            Hit::Volume { c, p } if c & FLUID_BIT != 0 => {
                fluid_event(ctx, ph, c, p, rng, out, scratch, tr);
            }
            Hit::Volume { c, p } => {
                if !turbid_event(ctx, ph, c, p, ms_forced, rng, out, g_cur, scratch, tr) {
                    return;
                }
            }
            Hit::Facet { f, p } => {
                if facet_event(ctx, ph, f, p, rng, out, scratch, tr) {
                    // Direct transmission is not a scattering event: same order, same flight
                    // direction (continue without the roulette/order bookkeeping); the return
                    // path now crosses this facet too.
                    ph.direct = false;
                    continue;
                }
            }
            Hit::Ground { p } => {
                ground_event(ctx, ph, p, rng, out, scratch, tr);
            }
        }
        // (Origin of the distance s of a hotspot-corrected flight, `Ctx::fly_hotspot`.)
        ph.scatter_path = ph.path;
        if !next_order(ctx, ph, rng, out) {
            return;
        }
    }
}

/// The photon's next flight from `ph.p` along `ph.d` (`g_cur` ← G of every turbid material in
/// that direction) with the estimator of its mode: in receiver mode past the first scattering,
/// the expected-value return along the flight (`Ctx::scatter_flight`); the stratified
/// estimator's first flight (`Ctx::first_flight`, or the collision only once the column
/// quadrature scored the first order); otherwise a free flight (`Ctx::fly`), after the forced
/// peel-off walk where one applies (`Ctx::forced_peel`). Sets `ph.ret` and
/// `ph.surface_scored` for the collision's peel-off. Returns the hit and whether the flight was
/// an expected-value multiple-scattering one (its turbid collisions are not peeled).
#[allow(clippy::too_many_arguments)]
fn flight(
    ctx: &Ctx,
    ph: &mut Photon,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    g_cur: &mut [f64],
    scratch: &mut [f64],
    tr: &mut [f64],
) -> (Hit, bool) {
    let inp = ctx.inp;
    let nb = ctx.nb;
    for (tm, g) in g_cur.iter_mut().enumerate() {
        *g = ctx.g_of(tm, ph.d.z);
    }
    // Forced peel-off: fluids (K > 0) toward the views, and in LiDAR receiver mode turbid
    // vegetation and fluids toward the receiver on the first flight.
    let forced_fluid = inp.fluid.is_some() && inp.params.fluid_peel_points > 0;
    // Receiver mode: first flight only (a smooth first-order waveform); later orders use
    // the collision estimator (one receiver trace per event instead of one per crossing).
    ph.ret = None;
    ph.surface_scored = false;
    if !ph.hs_k.is_empty() {
        ph.hs_k = Small::from_elem(0.0, 0);
    }
    // Receiver mode past the first scattering: expected-value return along the flight
    // (`Ctx::scatter_flight`); its turbid and Lambertian-ground collisions are not peeled.
    let ms_forced = ctx.ms_stop >= 1.0
        && ph.order >= 1
        && nb == 1
        && inp.fluid.is_none()
        && ctx.receiver.is_some();
    let hit = if ms_forced {
        ctx.scatter_flight(ph, g_cur, rng, out, scratch, tr)
    } else if ctx.stratified
        && ph.order == 0
        && ph.direct
        && nb == 1
        && inp.fluid.is_none()
        && ctx.receiver.is_some()
    {
        if ph.first_order_done {
            // The first-order return is the column quadrature's: the collision only (the
            // same free path and hit as `Ctx::first_flight`'s), and no peel-off of the
            // surface it may end on.
            let tau_star = -(1.0 - ph.first_u.unwrap_or_else(|| rng.next_f64())).ln();
            let hit = ctx.fly_to(ph, g_cur, tau_star, rng, out);
            ph.surface_scored = true;
            hit
        } else {
            // One walk: collision and stratified first-order return (`Ctx::first_flight`).
            let (hit, ret) = ctx.first_flight(ph, g_cur, rng, out, scratch, tr);
            ph.ret = ret.map(|t| Small::from_elem(return_transmittance(t), 1));
            hit
        }
    } else {
        let walk_end = if (ctx.receiver.is_some() && ph.order == 0)
            || (ctx.receiver.is_none() && forced_fluid && !inp.views.is_empty())
        {
            ctx.forced_peel(ph, g_cur, rng, out, scratch, tr)
        } else {
            None
        };
        let hit = if ctx.receiver.is_none()
            && ph.order == 1
            && ph.off == 0
            && ph.d.z > 0.0
            && !ctx.g_sun.is_empty()
        {
            // First-order sun photon going up: the hotspot-correlated flight its peel-off
            // transmittance assumed (physics.md §3.5, `Ctx::fly_hotspot`).
            let hs: PerMaterial<[f64; 2]> = Small::from_fn(g_cur.len(), |tm| {
                crate::radiative::engine::hotspot_terms(
                    inp.sun,
                    ph.d,
                    ctx.g_sun[tm],
                    g_cur[tm],
                    ctx.hs_leaf[tm],
                )
            });
            ctx.fly_hotspot(ph, g_cur, &hs, rng, out)
        } else {
            ctx.fly(ph, g_cur, rng, out)
        };
        // First flight ending on the surface its forced walk ended on: the collision
        // peel-off reuses the walk's return transmittance (see `Ctx::forced_peel`).
        ph.ret = match (&hit, walk_end) {
            (Hit::Facet { f, .. }, Some((Some(g), tau))) if *f == g => {
                Some(Small::from_fn(tau.len(), |b| return_transmittance(tau[b])))
            }
            (Hit::Ground { .. }, Some((None, tau))) => {
                Some(Small::from_fn(tau.len(), |b| return_transmittance(tau[b])))
            }
            _ => None,
        };
        hit
    };
    (hit, ms_forced)
}

/// An escape through the top: the escaped weight, in total and in the discrete direction of
/// the photon (its own in discrete mode, else the sector containing it).
fn escape(ctx: &Ctx, ph: &Photon, out: &mut BatchOut) {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let off = ph.off;
    let discrete = inp.params.sampler.is_discrete();
    let n_dirs = ctx.omega.len();
    let j = if discrete && ph.di < n_dirs {
        ph.di
    } else {
        inp.dirs.find_sector(ph.d)
    };
    for b in 0..nb {
        out.summary[ctx.sum.escaped(off + b)] += ph.w[b];
        out.summary[ctx.sum.dir(j, off + b)] += ph.w[b];
    }
}

/// A collision with turbid vegetation in cell `c` at `p` (DART 5 paper §4; physics.md §3.3):
/// the material in proportion to its extinction, its interception tally, then the scattering
/// of the discrete (Ray-Carlo rows, [`discrete_turbid_scatter`]) or continuous mode (leaf
/// sampler) with its peel-off, unless a forced estimate accounted for it (receiver mode: the
/// first flight, or an expected-value flight, `ms_forced`); the absorption is the weight lost.
/// Returns false when the photon ends here (black leaves, or a material without turbid optics).
#[allow(clippy::too_many_arguments)]
fn turbid_event(
    ctx: &Ctx,
    ph: &mut Photon,
    c: usize,
    p: DVec3,
    ms_forced: bool,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    g_cur: &[f64],
    scratch: &mut [f64],
    tr: &mut [f64],
) -> bool {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let off = ph.off;
    let discrete = inp.params.sampler.is_discrete();
    out.events += 1;
    let entries = inp.grid.turbid_of(c);
    let start = inp.grid.turbid_start[c] as usize;
    // After a hotspot-corrected flight: in proportion to the local extinction there.
    let g_pick: &[f64] = if ph.hs_k.is_empty() { g_cur } else { &ph.hs_k };
    let sel = select_turbid_entry(ctx, c, g_pick, rng);
    let entry = (start + sel) as u32;
    let mid = entries[sel].material as usize;
    let tm = ctx.tur_mat[mid] as usize;
    let PhotonOptics::Turbid {
        sampler,
        kernel,
        rho,
        tau,
        discrete: drows,
        ..
    } = &inp.optics[mid]
    else {
        return false;
    };
    {
        let it = out.int_tur.get(entry);
        for b in 0..nb {
            it[off + b] += ph.w[b];
        }
    }
    let d_in = ph.d;
    let g_in = g_cur[tm].max(1e-12);
    let w_before = ph.w.clone();
    // Peel-off done by the forced estimate (LiDAR receiver mode, first flight) or along an
    // expected-value flight.
    let forced = (ctx.receiver.is_some() && ph.order == 0) || ms_forced;
    match drows {
        Some(rows) if discrete => {
            if !discrete_turbid_scatter(ctx, ph, p, rows, entry, forced, rng, out, scratch, tr) {
                return false;
            }
        }
        _ => {
            let (mut sr, mut sw) = (0.0, 0.0);
            for b in 0..nb {
                sr += ph.w[b] * rho[b];
                sw += ph.w[b] * (rho[b] + tau[b]);
            }
            if sw <= 0.0 {
                let a = out.abs_tur.get(entry);
                for b in 0..nb {
                    a[off + b] += ph.w[b];
                }
                return false;
            }
            let p_r = sr / sw;
            let ev = sampler.scatter(d_in, p_r, rng);
            // Peel-off: the radiant intensity per unit intercepted weight toward
            // Ω_v is Γ_b(Ω'→Ω_v)/(π G(Ω')) (physics.md §3.3). Spherical LAD: its
            // closed form. Other LADs: the unbiased one-leaf estimate given the
            // leaf normal n drawn for this event (density ∝ g_L|Ω'·n|/G, facing
            // the photon): ρ_b|Ω_v·n|/π on the incidence side (Ω_v·n > 0), τ_b|Ω_v·n|/π
            // beyond — E_n[·] = Γ_b/(π G) exactly, with no quadrature of Γ (whose
            // binned evaluation costs ~10 µs and errs by up to 0.5 % at 180 bins).
            let closed = kernel.is_closed_form();
            let n = ev.normal;
            ctx.peel(ph, p, None, false, out, scratch, tr, |_, ov, s| {
                if forced {
                    return false;
                }
                turbid_peel_phase(kernel, closed, n, d_in, ov, g_in, rho, tau, &mut s[..nb])
            });
            // w_b ← w_b ρ_b/p_r (reflection) or w_b τ_b/(1 − p_r) (transmission):
            // E[w'_b] = w_b (ρ_b + τ_b) for every band.
            for b in 0..nb {
                ph.w[b] *= if ev.reflected {
                    rho[b] / p_r
                } else {
                    tau[b] / (1.0 - p_r)
                };
            }
            ph.d = ev.dir;
        }
    }
    let a = out.abs_tur.get(entry);
    for b in 0..nb {
        a[off + b] += w_before[b] - ph.w[b];
    }
    ph.p = p;
    ph.skip_facet = None;
    true
}

/// The turbid entry of cell `c` the photon collides with, drawn in proportion to each tracked
/// material's extinction `G_m u_m` (`g_cur`: G of every turbid material in the flight
/// direction); the last entry when rounding leaves the draw past the sum.
fn select_turbid_entry(ctx: &Ctx, c: usize, g_cur: &[f64], rng: &mut Xoshiro256PlusPlus) -> usize {
    let entries = ctx.inp.grid.turbid_of(c);
    let kv = ctx.k_veg(c, g_cur);
    let mut u = rng.next_f64() * kv;
    let mut sel = entries.len() - 1;
    for (i, e) in entries.iter().enumerate() {
        let tm = ctx.tur_mat[e.material as usize];
        if tm == u32::MAX {
            continue;
        }
        let k = g_cur[tm as usize] * e.density as f64;
        if u < k {
            sel = i;
            break;
        }
        u -= k;
    }
    sel
}

/// Discrete-mode (Ray-Carlo) scattering at a turbid collision at `p`: peel-off with the
/// containing sector's tabulated value `T_{i,m}/ΔΩ_m` (unless `forced`), then a discrete
/// direction drawn from the incident row's sampler, the weights reweighted by table value over
/// sampling probability. Returns false for black leaves (everything absorbed, booked on
/// `entry`).
#[allow(clippy::too_many_arguments)]
fn discrete_turbid_scatter(
    ctx: &Ctx,
    ph: &mut Photon,
    p: DVec3,
    rows: &DiscreteRows,
    entry: u32,
    forced: bool,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    scratch: &mut [f64],
    tr: &mut [f64],
) -> bool {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let off = ph.off;
    let row = ph.di.min(rows.samplers.len() - 1);
    ctx.peel(ph, p, None, false, out, scratch, tr, |v, ov, s| {
        if forced {
            return false;
        }
        let m = match ctx.view_sector.get(v) {
            Some(&m) => m,
            None => inp.dirs.find_sector(ov),
        };
        let dom = inp.dirs.tiling()[m].solid_angle_sr;
        for b in 0..nb {
            s[b] = rows.tables[b].get(row, m) as f64 / dom;
        }
        true
    });
    let Some(smp) = &rows.samplers[row] else {
        // Black leaves: everything absorbed.
        let a = out.abs_tur.get(entry);
        for b in 0..nb {
            a[off + b] += ph.w[b];
        }
        return false;
    };
    let j = smp.sample(rng);
    let qj = smp.probability(j).max(1e-300);
    for b in 0..nb {
        ph.w[b] *= rows.tables[b].get(row, j) as f64 / qj;
    }
    ph.di = j;
    ph.d = ctx.omega[j];
    true
}

/// After an event: the scattering order goes up, then the photon stops when it is past the
/// range gate (receiver mode; booked as lost), has no weight left, loses a Russian roulette
/// (receiver mode: into multiple scattering with survival `continue_prob`, and the far-photon
/// roulette of the expected-value estimator), is past `max_order` (lost), or loses the weight
/// window's roulette (its balance kept in `out.roulette`). Returns whether it goes on.
pub(crate) fn next_order(
    ctx: &Ctx,
    ph: &mut Photon,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
) -> bool {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let off = ph.off;
    ph.order += 1;
    if ctx.beyond_gate(ph) {
        for b in 0..nb {
            out.lost[off + b] += ph.w[b];
        }
        return false;
    }
    let wmax = ph.w.iter().cloned().fold(0.0, f64::max);
    if wmax <= 0.0 || !wmax.is_finite() {
        return false;
    }
    // Receiver mode: Russian roulette into multiple scattering after the first interaction
    // (its first-order return is already recorded), survival `continue_prob`.
    if ph.order == 1
        && ctx.continue_prob < 1.0
        && !roulette_survives(ph, ctx.continue_prob, rng, &mut out.roulette[off..off + nb])
    {
        return false;
    }
    if ph.order > inp.params.max_order {
        for b in 0..nb {
            out.lost[off + b] += ph.w[b];
        }
        return false;
    }
    // Receiver mode, expected-value estimator: a photon that scattered far outside the
    // receiver's field of view goes on with the survival probability of its distance.
    if ctx.far_roulette.0 > 0.0
        && let Some(rx) = &ctx.receiver
    {
        let q = far_roulette_survival(rx, ph.p + ph.shift, ctx.far_roulette);
        if q < 1.0 && !roulette_survives(ph, q, rng, &mut out.roulette[off..off + nb]) {
            return false;
        }
    }
    let r = wmax / ph.w0;
    let thr = inp.params.roulette_threshold;
    if r < thr {
        if rng.next_f64() * thr < r {
            let s = thr / r;
            for b in 0..nb {
                out.roulette[off + b] -= ph.w[b] * (s - 1.0);
                ph.w[b] *= s;
            }
        } else {
            for b in 0..nb {
                out.roulette[off + b] += ph.w[b];
            }
            return false;
        }
    }
    true
}

/// A collision with the flat ground at `p` (DART 5 paper §4): interception and absorption
/// tallies of its column, then Lambertian reflection (peel-off, cosine-weighted direction) or
/// a BRDF event (physics.md §5.2–5.3); other optics absorb the photon.
#[allow(clippy::too_many_arguments)]
fn ground_event(
    ctx: &Ctx,
    ph: &mut Photon,
    p: DVec3,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    scratch: &mut [f64],
    tr: &mut [f64],
) {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let off = ph.off;
    out.events += 1;
    let col = ctx.column(p);
    {
        let it = out.int_gnd.get(col);
        for b in 0..nb {
            it[off + b] += ph.w[b];
            out.summary[ctx.sum.ground(off + b)] += ph.w[b];
        }
    }
    let w_before = ph.w.clone();
    let gid = inp.flat_ground.expect("flat ground") as usize;
    match &inp.optics[gid] {
        PhotonOptics::Lambert { r, .. } => {
            // (Scored by the walk of an expected-value flight.)
            let scored = ph.surface_scored;
            ctx.peel(ph, p, None, true, out, scratch, tr, |_, ov, s| {
                if scored {
                    return false;
                }
                let c = ov.z;
                for b in 0..nb {
                    s[b] = r[b] * c / PI;
                }
                true
            });
            for b in 0..nb {
                ph.w[b] *= r[b];
            }
            ctx.ground_direction(ph, rng);
        }
        PhotonOptics::Brdf { models, sampler } => {
            brdf_event(
                ctx,
                ph,
                p,
                None,
                DVec3::Z,
                models,
                sampler,
                rng,
                out,
                scratch,
                tr,
            );
        }
        _ => ph.w.iter_mut().for_each(|x| *x = 0.0),
    }
    let a = out.abs_gnd.get(col);
    for b in 0..nb {
        a[off + b] += w_before[b] - ph.w[b];
        out.summary[ctx.sum.absorbed_ground(off + b)] += w_before[b] - ph.w[b];
    }
    ph.p = p;
    ph.skip_facet = None;
}

/// A collision with facet `f` at `p` (DART 5 paper §4; physics.md §5): interception and
/// absorption tallies, then a Lambertian facet's direct transmission, reflection or diffuse
/// transmission (peel-off, band-weighted choice) or a BRDF event; other optics absorb the
/// photon. Returns whether the photon passed straight through (direct transmission).
#[allow(clippy::too_many_arguments)]
fn facet_event(
    ctx: &Ctx,
    ph: &mut Photon,
    f: u32,
    p: DVec3,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    scratch: &mut [f64],
    tr: &mut [f64],
) -> bool {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let off = ph.off;
    let discrete = inp.params.sampler.is_discrete();
    out.events += 1;
    let fa = &inp.facets[f as usize];
    let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize();
    let front = n.dot(ph.d) < 0.0;
    let n_in = if front { n } else { -n }; // normal on the incidence side
    let mu = n.dot(ph.d).abs().max(1e-6);
    let w_before = ph.w.clone();
    let is_ground_facet = inp.ground_facet.get(f as usize).copied().unwrap_or(false);
    let mut passed_through = false;
    match &inp.optics[fa.material as usize] {
        PhotonOptics::Lambert { r, t, t_dir } => {
            let mut pd = Bands::from_elem(0.0, nb);
            let mut pr = Bands::from_elem(0.0, nb);
            let mut pt = Bands::from_elem(0.0, nb);
            let nbx = nb;
            for b in 0..nbx {
                let through = if t_dir[b] > 0.0 {
                    t_dir[b].powf(1.0 / mu)
                } else {
                    0.0
                };
                pd[b] = through;
                pr[b] = (1.0 - through) * r[b];
                pt[b] = (1.0 - through) * t[b];
            }
            {
                let it = out.int_fac.get(f);
                for b in 0..nbx {
                    it[off + b] += ph.w[b] * (1.0 - pd[b]);
                }
            }
            // Peel-off: reflected ρ|n·v|/π on the incidence side, τ|n·v|/π beyond
            // (unless the flight's walk scored it: `Photon::surface_scored`).
            let scored = ph.surface_scored;
            ctx.peel(
                ph,
                p,
                Some(f),
                is_ground_facet,
                out,
                scratch,
                tr,
                |_, ov, s| {
                    if scored {
                        return false;
                    }
                    let c = n_in.dot(ov);
                    let mut any = false;
                    for b in 0..nbx {
                        s[b] = if c > 0.0 { pr[b] } else { pt[b] } * c.abs() / PI;
                        any |= s[b] > 0.0;
                    }
                    any
                },
            );
            let k = choose(&mut ph.w[..nbx], &[&pd[..nbx], &pr[..nbx], &pt[..nbx]], rng);
            match k {
                None => {}
                Some(0) => passed_through = true,
                Some(1) => {
                    ph.d = sample_cosine_hemisphere(n_in, rng);
                }
                _ => {
                    ph.d = sample_cosine_hemisphere(-n_in, rng);
                }
            }
            if discrete && k.is_some_and(|k| k > 0) {
                ph.di = inp.dirs.find_sector(ph.d);
                ph.d = ctx.omega[ph.di];
            }
        }
        PhotonOptics::Brdf { models, sampler } => {
            {
                let it = out.int_fac.get(f);
                for b in 0..nb {
                    it[off + b] += ph.w[b];
                }
            }
            brdf_event(
                ctx,
                ph,
                p,
                Some(f),
                n_in,
                models,
                sampler,
                rng,
                out,
                scratch,
                tr,
            );
        }
        _ => {
            for b in 0..nb {
                ph.w[b] = 0.0;
            }
        }
    }
    let a = out.abs_fac.get(f);
    for b in 0..nb {
        a[off + b] += w_before[b] - ph.w[b];
    }
    ph.p = p;
    ph.skip_facet = Some(f);
    passed_through
}

/// A fluid collision in cell `c` (with [`FLUID_BIT`]) at `p` (physics.md §4.2): peel-off with
/// the phase function unless the forced estimate along the flight accounted for it, absorption
/// `1 − ω` booked per band, and a new direction from the phase function.
#[allow(clippy::too_many_arguments)]
fn fluid_event(
    ctx: &Ctx,
    ph: &mut Photon,
    c: usize,
    p: DVec3,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    scratch: &mut [f64],
    tr: &mut [f64],
) {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let off = ph.off;
    let discrete = inp.params.sampler.is_discrete();
    let c = c & !FLUID_BIT;
    let f = ctx.fluid_of(c).expect("fluid cell");
    out.events += 1;
    // Peel-off: intensity ω P(Θ)/(4π) per unit weight (unless the K-point forced
    // estimate along the flight already accounted for fluid collisions).
    let d_in = ph.d;
    let forced_here = match ctx.receiver {
        Some(_) => ph.order == 0,
        None => inp.params.fluid_peel_points > 0,
    };
    if !forced_here {
        ctx.peel(ph, p, None, false, out, scratch, tr, |_, ov, s| {
            let pv = f.phase.eval_dirs(d_in, ov) / (4.0 * PI);
            for b in 0..nb {
                s[b] = f.ssa[b] * pv;
            }
            true
        });
    }
    let acc = out
        .abs_fluid
        .entry(c as u32)
        .or_insert_with(|| vec![0.0; ctx.w]);
    for b in 0..nb {
        let w_new = ph.w[b] * f.ssa[b];
        acc[off + b] += ph.w[b] - w_new;
        ph.w[b] = w_new;
    }
    let d_new = sample_fluid_phase(&f.phase, ph.d, rng);
    ph.d = d_new;
    if discrete {
        ph.di = inp.dirs.find_sector(ph.d);
        ph.d = ctx.omega[ph.di];
    }
    ph.p = p;
    ph.skip_facet = None;
}
