//! Thermal emission photons (issue #34; physics.md §7.2; DART 5 paper §2–§4): the Monte Carlo
//! counterpart of the flux tracking's thermal sources (`radiative::engine::thermal`), on the
//! thermal channels `nb..2 nb` of a thermal run (channel block 0 is the zero sun).
//!
//! * **Power per element** (W per spectral unit, from `ε B(T)` in W m⁻² sr⁻¹ µm⁻¹): a turbid
//!   entry of leaf area density u in a cell of volume V emits `ε B u V ∫G dΩ = 2π ε B u V`
//!   (the emission coefficient `j(Ω) = ε u G(Ω) B` of a leaf medium; ∫G dΩ = 2π, Ross 1981);
//!   a Lambertian facet of area A emits `ε B A I(T_dir)` per emitting side (both sides when
//!   two-sided), `I(T) = ∫_{2π} μ (1 − T^{1/μ}) dΩ` (Kirchhoff: the absorptance of a beam along
//!   −Ω; `I(0) = π`); a flat-ground column of area a emits `π ε B a`; the sky, an isotropic
//!   downwelling radiance `L_sky`, sends `π L_sky A` through the top.
//! * **Choice**: one uniform picks the element from a cumulative table of the elements' total
//!   (band-summed) powers, built once per run; the photon's weight in band b is
//!   `P_b / (q N)` (q the element's probability, N the run's photons), so every band's
//!   expectation is its own emitted power.
//! * **Position and direction**: turbid: uniform in the cell, direction uniform on the sphere
//!   with weight factor `4π G(Ω)/∫G dΩ = 2 G(Ω)`; facet: uniform on the triangle, a random side
//!   of a two-sided facet, cosine direction on it with weight factor
//!   `π (1 − T_dir^{1/μ}) / I(T_dir)`; ground: uniform in the column at the ground plane,
//!   cosine upward. A weight factor's departure from 1 is booked in the weight balance (with
//!   the roulette's, expectation 0), so the energy closes exactly in every realisation.
//! * **Peel-off** from the emission point itself (the local estimate of the emission's
//!   intensity toward each view, sr⁻¹ per unit weight): turbid `G(v)/(2π)`, facet
//!   `|n·v| (1 − T_dir^{1/|n·v|}) / (I(T_dir) · sides)` toward an emitting side, ground `v_z/π`.

use super::context::{Ctx, Photon};
use super::input::PhotonOptics;
use super::tally::BatchOut;
use crate::photon::sampling::{Uniform01, sample_cosine_hemisphere};
use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::PI;

/// Thermal photon stream purpose tag (see `random::stream`): thermal batches draw from their
/// own streams, independent of the solar run's of an `R+T` run.
pub const THERMAL_STREAM: u64 = 0x0054_4845_524d_414c; // "THERMAL"

/// An emitting element of a Monte Carlo thermal run.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Emitter {
    /// Turbid entry (index of `CellGrid::turbid`) in cell `cell`, tracked turbid material `tm`.
    Turbid { cell: u32, tm: u32 },
    /// Facet (Lambertian optics).
    Facet(u32),
    /// Flat-ground column `i + n_x j`.
    Ground(u32),
    /// The thermal sky (launched at the top like the solar sky).
    Sky,
}

/// The emitting elements of a thermal run with their per-band powers and the cumulative
/// table of their total powers (built once per run).
#[derive(Debug, Clone, Default)]
pub(crate) struct EmissionTable {
    /// Elements with a positive total power.
    pub(crate) elements: Vec<Emitter>,
    /// Power per element and band `[element][band]`, W (per spectral unit).
    pub(crate) power: Vec<f64>,
    /// Cumulative total power (inclusive), W.
    cum: Vec<f64>,
    /// Emitted power per band of the scene's elements (sky excluded), W.
    pub(crate) emitted: Vec<f64>,
    /// Sky power per band through the top, W.
    pub(crate) sky: Vec<f64>,
}

/// `I(T) = ∫_{2π} μ (1 − T^{1/μ}) dΩ = 2π ∫₀¹ μ (1 − T^{1/μ}) dμ`, sr: the projected solid
/// angle weighted by a facet's absorptance of a beam with direct transmittance `T` at normal
/// incidence (`T^{1/μ}` along μ); π for T = 0. Midpoint rule on 4096 points in μ (error
/// < 1e-7 of π: the integrand is smooth on [0, 1] and its derivatives vanish at μ → 0).
pub(crate) fn facet_emission_sr(t: f64) -> f64 {
    if t <= 0.0 {
        return PI;
    }
    let n = 4096;
    let s: f64 = (0..n)
        .map(|i| {
            let mu = (i as f64 + 0.5) / n as f64;
            mu * (1.0 - t.powf(1.0 / mu))
        })
        .sum();
    2.0 * PI * s / n as f64
}

impl EmissionTable {
    /// The table of a thermal run (`ctx.inp.thermal` set): turbid entries with a tracked
    /// material and a density, Lambertian facets, flat-ground columns and the sky, each with
    /// some positive power.
    pub(crate) fn new(ctx: &Ctx) -> Self {
        let inp = ctx.inp;
        let Some(th) = inp.thermal else {
            return Self::default();
        };
        let nb = ctx.nb;
        let spec = inp.spec;
        let grid = inp.grid;
        let mut t = EmissionTable {
            emitted: vec![0.0; nb],
            sky: vec![0.0; nb],
            ..Default::default()
        };
        let eb = |v: &[f64], i: usize, b: usize| v.get(i * nb + b).copied().unwrap_or(0.0);
        let push = |t: &mut EmissionTable, el: Emitter, p: &[f64]| {
            let tot: f64 = p.iter().sum();
            if tot > 0.0 && p.iter().all(|&x| x >= 0.0) {
                t.elements.push(el);
                t.power.extend_from_slice(p);
                let last = t.cum.last().copied().unwrap_or(0.0);
                t.cum.push(last + tot);
                if !matches!(el, Emitter::Sky) {
                    t.emitted.iter_mut().zip(p).for_each(|(a, x)| *a += x);
                }
            }
        };
        let mut p = vec![0.0; nb];
        let vol = spec.cell_volume();
        for c in 0..grid.turbid_start.len().saturating_sub(1) {
            for k in grid.turbid_start[c] as usize..grid.turbid_start[c + 1] as usize {
                let e = &grid.turbid[k];
                let tm = ctx.tur_mat[e.material as usize];
                if tm == u32::MAX || e.density <= 0.0 {
                    continue;
                }
                for (b, x) in p.iter_mut().enumerate() {
                    *x = 2.0 * PI * eb(&th.turbid, k, b) * e.density as f64 * vol;
                }
                push(&mut t, Emitter::Turbid { cell: c as u32, tm }, &p);
            }
        }
        for (f, fa) in inp.facets.iter().enumerate() {
            let PhotonOptics::Lambert { t_dir, .. } = &inp.optics[fa.material as usize] else {
                continue;
            };
            let area = 0.5 * (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).length();
            let sides = if fa.two_sided { 2.0 } else { 1.0 };
            for (b, x) in p.iter_mut().enumerate() {
                let td = t_dir.get(b).copied().unwrap_or(0.0);
                *x = sides * eb(&th.facet, f, b) * area * facet_emission_sr(td);
            }
            push(&mut t, Emitter::Facet(f as u32), &p);
        }
        if inp.flat_ground.is_some() {
            let a = spec.cell.x * spec.cell.y;
            for c in 0..spec.n[0] * spec.n[1] {
                for (b, x) in p.iter_mut().enumerate() {
                    *x = PI * eb(&th.ground, c, b) * a;
                }
                push(&mut t, Emitter::Ground(c as u32), &p);
            }
        }
        let area = ctx.size.0 * ctx.size.1;
        for (b, x) in p.iter_mut().enumerate() {
            *x = PI * th.sky.get(b).copied().unwrap_or(0.0) * area;
        }
        t.sky.copy_from_slice(&p);
        push(&mut t, Emitter::Sky, &p);
        t
    }

    /// Total power of all elements and the sky (band sum), W.
    pub(crate) fn total(&self) -> f64 {
        self.cum.last().copied().unwrap_or(0.0)
    }

    /// The element of uniform `u` ∈ [0, 1): the first whose cumulative power exceeds `u` of
    /// the total.
    pub(crate) fn pick(&self, u: f64) -> usize {
        let x = u * self.total();
        self.cum
            .partition_point(|&c| c <= x)
            .min(self.elements.len() - 1)
    }

    /// Per-band weights of element `k` for a run of `n_total` photons: `P_b / (q N)` with
    /// `q = P_k / P_total` (band sums).
    pub(crate) fn weights(&self, k: usize, n_total: f64, nb: usize, w: &mut [f64]) {
        let prev = if k == 0 { 0.0 } else { self.cum[k - 1] };
        let pk = self.cum[k] - prev;
        let f = self.total() / (pk * n_total);
        for b in 0..nb {
            w[b] = self.power[k * nb + b] * f;
        }
    }
}

/// Launches one emission photon from element `el` (not the sky) with weights `ph.w` already
/// set: position and the peel-off of the emission toward the views, then the direction and
/// its weight factor (its departure from 1 booked in the weight balance). False when the
/// photon carries nothing.
#[allow(clippy::too_many_arguments)]
pub(crate) fn launch_emission(
    ctx: &Ctx,
    el: Emitter,
    ph: &mut Photon,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    scratch: &mut [f64],
    tr: &mut [f64],
) -> bool {
    let inp = ctx.inp;
    let spec = inp.spec;
    let nb = ctx.nb;
    let discrete = inp.params.sampler.is_discrete();
    ph.skip_facet = None;
    match el {
        Emitter::Turbid { cell, tm } => {
            let lo = spec.cell_lo(cell as usize);
            let p = lo + DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * spec.cell;
            ctx.peel(ph, p, None, false, out, scratch, tr, |_, ov, s| {
                let f = ctx.g_of(tm as usize, ov.z) / (2.0 * PI);
                s[..nb].iter_mut().for_each(|x| *x = f);
                f > 0.0
            });
            let z = 1.0 - 2.0 * rng.next_f64();
            let phi = 2.0 * PI * rng.next_f64();
            let r = (1.0 - z * z).max(0.0).sqrt();
            ph.d = DVec3::new(r * phi.cos(), r * phi.sin(), z);
            if discrete {
                ph.di = inp.dirs.find_sector(ph.d);
                ph.d = ctx.omega[ph.di];
            }
            let f = 2.0 * ctx.g_of(tm as usize, ph.d.z);
            reweight(ph, out, |_| f);
            ph.p = p;
        }
        Emitter::Facet(fi) => {
            let fa = &inp.facets[fi as usize];
            let e1 = fa.v[1] - fa.v[0];
            let e2 = fa.v[2] - fa.v[0];
            let (mut r1, mut r2) = (rng.next_f64(), rng.next_f64());
            if r1 + r2 > 1.0 {
                (r1, r2) = (1.0 - r1, 1.0 - r2);
            }
            let p = fa.v[0] + e1 * r1 + e2 * r2;
            let n = e1.cross(e2).normalize();
            let PhotonOptics::Lambert { t_dir, .. } = &inp.optics[fa.material as usize] else {
                return false;
            };
            let two = fa.two_sided;
            let sides = if two { 2.0 } else { 1.0 };
            let absorb = |b: usize, mu: f64| {
                let t = t_dir.get(b).copied().unwrap_or(0.0);
                if t > 0.0 {
                    1.0 - t.powf(1.0 / mu.max(1e-6))
                } else {
                    1.0
                }
            };
            let sr: Vec<f64> = (0..nb)
                .map(|b| facet_emission_sr(t_dir.get(b).copied().unwrap_or(0.0)))
                .collect();
            ctx.peel(ph, p, Some(fi), false, out, scratch, tr, |_, ov, s| {
                let c = n.dot(ov);
                if !two && c <= 0.0 {
                    return false;
                }
                for b in 0..nb {
                    s[b] = c.abs() * absorb(b, c.abs()) / (sr[b] * sides);
                }
                true
            });
            let side = if two && rng.next_f64() < 0.5 { -n } else { n };
            ph.d = sample_cosine_hemisphere(side, rng);
            if discrete {
                ph.di = inp.dirs.find_sector(ph.d);
                ph.d = ctx.omega[ph.di];
            }
            let mu = side.dot(ph.d).abs();
            reweight(ph, out, |b| absorb(b, mu) * PI / sr[b]);
            ph.p = p;
            ph.skip_facet = Some(fi);
        }
        Emitter::Ground(c) => {
            let c = c as usize;
            let (i, j) = (c % spec.n[0], c / spec.n[0]);
            let p = spec.origin
                + DVec3::new(
                    (i as f64 + rng.next_f64()) * spec.cell.x,
                    (j as f64 + rng.next_f64()) * spec.cell.y,
                    0.0,
                );
            ctx.peel(ph, p, None, true, out, scratch, tr, |_, ov, s| {
                let f = ov.z / PI;
                s[..nb].iter_mut().for_each(|x| *x = f);
                f > 0.0
            });
            ctx.ground_direction(ph, rng);
            ph.p = p;
        }
        Emitter::Sky => return false,
    }
    ph.w0 = ph.w.iter().cloned().fold(0.0, f64::max);
    ph.w0 > 0.0
}

/// Step of [`launch_emission`]: multiplies band b's weight by `f(b)`, booking `w (1 − f)` in
/// the weight balance (expectation 0: every factor has mean 1 over its direction sampling).
fn reweight(ph: &mut Photon, out: &mut BatchOut, f: impl Fn(usize) -> f64) {
    let off = ph.off;
    for b in 0..ph.w.len() {
        let fb = f(b);
        out.roulette[off + b] += ph.w[b] * (1.0 - fb);
        ph.w[b] *= fb;
    }
}
