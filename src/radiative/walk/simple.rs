//! The lean walks of the common case (see [`Ctx::simple`]): `trace_simple` / `walk_simple`
//! (one ray, any channel count and accumulator) and `walk_lean` (dense accumulator,
//! `turbid_subfaces: Off`, 1, 2 or 4 channels). DART 5 flux tracking (Gastellu-Etchegorry
//! et al. 2015, §3; physics.md §3.6).

use crate::radiative::dda::{Dda, Exit};
use crate::radiative::engine::*;
use crate::radiative::fastmath::{HalfBarycentres, attenuation};
use crate::scene::desc::{BoundaryMode, TurbidSubfaces};
use glam::DVec3;

impl Ctx<'_> {
    /// Lean tracker for the common case (see [`Ctx::simple`]): turbid cells with at most one
    /// tracked entry, no facets, no hotspot, flat top and bottom, repetitive boundaries without
    /// an altitude offset or isolated ones. Same physics and bookkeeping as [`Ctx::trace_w`]
    /// (DART 5 flux tracking, Gastellu-Etchegorry et al. 2015, Remote Sens. 7, 1667–1701, §3:
    /// one exact attenuation `e^{−kℓ}` per crossing, the two interception points per crossing,
    /// the ray dropped below the power threshold; the cells walked by the Amanatides & Woo 1987
    /// DDA of [`crate::radiative::dda`]), with one 16-byte cell record per crossing
    /// (`k = G_m(Ω) u_m` from the ray's G row), the periodic re-entries done in place
    /// ([`Dda::wrap_sides`]), no facet, hotspot or restart logic, and the dense accumulator's
    /// slices borrowed once per ray.
    pub(in crate::radiative) fn trace_simple<const W: usize>(
        &self,
        p: DVec3,
        dir: usize,
        pw: &mut [f64],
        tur: &mut TurAcc,
        out: &mut ChunkOut,
    ) {
        let w = if W == 0 { self.w } else { W };
        let slot = self.slot_of(dir) as u32;
        let d = self.omega[dir];
        match tur.view() {
            Some(mut view) => {
                // The channel count as the walk knows it (a constant when W > 0).
                view.w = w;
                if self.subfaces == TurbidSubfaces::Off {
                    // 1, 2 and 4 channels go to the lean walk ([`super::select`]).
                    self.walk_simple::<W>(p, dir, pw, out, |e, pw, frac, p1, p2, wt, _| {
                        view.add_entry(e, slot, pw, frac, 1.0, p1, p2, wt)
                    });
                    return;
                }
                self.walk_simple::<W>(p, dir, pw, out, |e, pw, frac, p1, p2, wt, q0| {
                    let eq = self.acc_index(e, q0, d, slot);
                    view.add(eq, slot, pw, frac, 1.0, p1, p2, wt)
                });
            }
            None => self.walk_simple::<W>(p, dir, pw, out, |e, pw, frac, p1, p2, wt, q0| {
                let eq = self.acc_index(e, q0, d, slot);
                tur.add(eq, slot, pw, frac, 1.0, p1, p2, wt)
            }),
        }
    }

    /// [`Ctx::walk_lean`] for the channel count `self.w` (1, 2 or 4) with the dense
    /// accumulator's arrays borrowed for the ray.
    pub(in crate::radiative) fn trace_lean(
        &self,
        p: DVec3,
        dir: usize,
        pw: &mut [f64],
        tur: &mut TurAcc,
        out: &mut ChunkOut,
    ) {
        let mut view = tur
            .view()
            .expect("the lean walk takes the dense accumulator");
        // The channel count as the walk knows it (a constant).
        view.w = self.w;
        match self.w {
            1 => self.walk_lean::<1>(p, dir, pw, &mut view, out),
            2 => self.walk_lean::<2>(p, dir, pw, &mut view, out),
            _ => self.walk_lean::<4>(p, dir, pw, &mut view, out),
        }
    }

    /// The walk of [`Ctx::trace_simple`]; `sink(entry, pw, 1 − e^{−kℓ}, p1, p2, weight, q0)`
    /// books each interception (`q0`: the point where the segment starts, m).
    #[inline(always)]
    pub(in crate::radiative) fn walk_simple<const W: usize>(
        &self,
        p: DVec3,
        dir: usize,
        pw: &mut [f64],
        out: &mut ChunkOut,
        mut sink: impl FnMut(u32, &[f64], f64, DVec3, DVec3, f64, DVec3),
    ) {
        let w = if W == 0 { self.w } else { W };
        let pw = &mut pw[..w];
        let spec = self.inp.spec;
        let d = self.omega[dir];
        let slot = self.slot_of(dir) as u32;
        let n_tm = self.n_tm;
        let gd = &self.g_dir[dir * n_tm..(dir + 1) * n_tm];
        let hb = HalfBarycentres::get();
        let isolated = spec.boundary == BoundaryMode::Isolated;
        let max_crossings = self.inp.params.max_crossings;
        let min_ray = self.min_ray * self.ray_factor[dir] * out.ray_scale;
        let scells = &self.scells[..];
        out.rays += 1;
        let Some(mut dda) = Dda::new(spec, p, d) else {
            add(&mut out.lost, pw);
            return;
        };
        let mut n_cross = 0u64;
        let mut wraps = 0u32;
        let mut psum: f64 = crate::radiative::walk::channel_sum(pw);
        // The traversal's origin, kept in a local (changes only at a wrap).
        let mut o = dda.origin();
        let mut n_skip = 0u64;
        loop {
            n_cross += 1;
            let sc = scells[dda.index()];
            let t0 = dda.t;
            let t1 = dda.t_exit();
            let exit = if sc.density > 0.0 {
                if t1 > t0 {
                    let ell = t1 - t0;
                    let k = gd[sc.tm as usize] * sc.density;
                    if k > 0.0 {
                        let x = k * ell;
                        let (frac, tr) = attenuation(x);
                        let (s1, s2) = hb.eval(x, ell);
                        let p1 = o + d * (t0 + s1);
                        let p2 = o + d * (t0 + s2);
                        sink(sc.idx, pw, frac, p1, p2, psum * frac, o + d * t0);
                        for v in pw.iter_mut() {
                            *v *= tr;
                        }
                        psum = crate::radiative::walk::channel_sum(pw);
                        if psum < min_ray {
                            add(&mut out.lost, pw);
                            break;
                        }
                    }
                }
                dda.advance_at(t1)
            } else if sc.tm > 1 {
                // Empty cell at distance r = sc.tm: jump over the empty box around it.
                let h = sc.tm as i64 - 1;
                let (e, faces) = dda.skip_to(h, dda.skip_exit(h));
                n_skip += faces - 1;
                e
            } else {
                dda.advance_at(t1)
            };
            match exit {
                Exit::Inside => {}
                Exit::Top => {
                    self.escape(dda.point(dda.t), dir, pw, out);
                    break;
                }
                Exit::Bottom => {
                    self.bottom(dda.point(dda.t), slot, pw, psum, out);
                    break;
                }
                Exit::Side(..) => {
                    if isolated {
                        add(&mut out.lost, pw);
                        break;
                    }
                    wraps += dda.wrap_sides();
                    o = dda.origin();
                    if wraps > max_crossings {
                        add(&mut out.lost, pw);
                        break;
                    }
                }
            }
        }
        out.crossings += n_cross;
        out.skipped += n_skip;
    }

    /// [`Ctx::walk_simple`] with the dense accumulator and `turbid_subfaces: Off` for `W`
    /// channels (1, 2 or 4): the same operations in the same order (products bit-identical),
    /// written so that the per-crossing path stays in registers — the channel powers in a
    /// `[f64; W]`, the traversal stepped by [`Dda::step_at`] (no exit bookkeeping per
    /// crossing), every exit, wrap and skip out of the straight path — and compiled for
    /// AVX2 + FMA where the CPU has them (`pulp` runtime dispatch; the same IEEE operations,
    /// no contraction, so the same bits as the baseline code path).
    pub(in crate::radiative) fn walk_lean<const W: usize>(
        &self,
        p: DVec3,
        dir: usize,
        pw_io: &mut [f64],
        view: &mut DenseView,
        out: &mut ChunkOut,
    ) {
        /// The walk's arguments, run by `pulp` in the best instruction set it detects.
        struct Walk<'c, 'v, 'o, 'x, const W: usize> {
            ctx: &'c Ctx<'x>,
            p: DVec3,
            dir: usize,
            pw: &'o mut [f64],
            view: &'o mut DenseView<'v>,
            out: &'o mut ChunkOut,
        }
        impl<const W: usize> pulp::WithSimd for Walk<'_, '_, '_, '_, W> {
            type Output = ();
            #[inline(always)]
            fn with_simd<S: pulp::Simd>(self, _simd: S) {
                // One tracked turbid material (the common case): its G hoisted out of the walk.
                if self.ctx.n_tm == 1 {
                    self.ctx
                        .walk_lean_body::<W, true>(self.p, self.dir, self.pw, self.view, self.out)
                } else {
                    self.ctx
                        .walk_lean_body::<W, false>(self.p, self.dir, self.pw, self.view, self.out)
                }
            }
        }
        self.arch.dispatch(Walk::<W> {
            ctx: self,
            p,
            dir,
            pw: pw_io,
            view,
            out,
        })
    }

    /// The body of [`Ctx::walk_lean`] (inlined into each instruction-set copy); `ONE_TM`: the
    /// scene has one tracked turbid material (every turbid cell's `tm` is 0).
    #[inline(always)]
    pub(in crate::radiative) fn walk_lean_body<const W: usize, const ONE_TM: bool>(
        &self,
        p: DVec3,
        dir: usize,
        pw_io: &mut [f64],
        view: &mut DenseView,
        out: &mut ChunkOut,
    ) {
        let mut pw = [0.0; W];
        pw.copy_from_slice(&pw_io[..W]);
        let spec = self.inp.spec;
        let d = self.omega[dir];
        let slot = self.slot_of(dir);
        let n_tm = self.n_tm;
        let gd = &self.g_dir[dir * n_tm..(dir + 1) * n_tm];
        // Read only when `ONE_TM` (a scene may have no tracked turbid material at all).
        let g0 = gd.first().copied().unwrap_or(0.0);
        let hb = HalfBarycentres::get();
        let isolated = spec.boundary == BoundaryMode::Isolated;
        let max_crossings = self.inp.params.max_crossings;
        let min_ray = self.min_ray * self.ray_factor[dir] * out.ray_scale;
        let scells = &self.scells[..];
        let ns = view.ns;
        let tur = &mut *view.tur;
        let pts = &mut *view.pts;
        let rec = &mut *view.rec;
        let touched = &mut *view.touched;
        out.rays += 1;
        let Some(mut dda) = Dda::new(spec, p, d) else {
            add(&mut out.lost, &pw);
            return;
        };
        let mut n_cross = 0u64;
        let mut wraps = 0u32;
        let mut psum: f64 = crate::radiative::walk::channel_sum(&pw);
        // The traversal's origin, kept in a local (changes only at a wrap).
        let mut o = dda.origin();
        let mut n_skip = 0u64;
        loop {
            n_cross += 1;
            let sc = scells[dda.index()];
            let t0 = dda.t;
            let t1 = dda.t_exit();
            let inside = if sc.density > 0.0 {
                if t1 > t0 {
                    let ell = t1 - t0;
                    let g = if ONE_TM { g0 } else { gd[sc.tm as usize] };
                    let k = g * sc.density;
                    if k > 0.0 {
                        let x = k * ell;
                        let (frac, tr) = attenuation(x);
                        let (s1, s2) = hb.eval(x, ell);
                        let p1 = o + d * (t0 + s1);
                        let p2 = o + d * (t0 + s2);
                        let wt = psum * frac;
                        let e = record(rec, touched, sc.idx as usize);
                        let s = (e * ns + slot) * W;
                        let r: &mut [f64; W] = (&mut tur[s..s + W]).try_into().expect("W");
                        for c in 0..W {
                            r[c] += pw[c] * frac;
                        }
                        let q: &mut [f64; 7] = (&mut pts[e * 7..e * 7 + 7]).try_into().expect("7");
                        q[0] += p1.x * wt;
                        q[1] += p1.y * wt;
                        q[2] += p1.z * wt;
                        q[3] += p2.x * wt;
                        q[4] += p2.y * wt;
                        q[5] += p2.z * wt;
                        q[6] += wt;
                        for v in pw.iter_mut() {
                            *v *= tr;
                        }
                        psum = crate::radiative::walk::channel_sum(&pw);
                        if psum < min_ray {
                            add(&mut out.lost, &pw);
                            break;
                        }
                    }
                }
                dda.step_at(t1)
            } else if sc.tm > 1 {
                // Empty cell at distance r = sc.tm: jump over the empty box around it.
                let h = sc.tm as i64 - 1;
                let (e, faces) = dda.skip_to(h, dda.skip_exit(h));
                n_skip += faces - 1;
                e == Exit::Inside
            } else {
                dda.step_at(t1)
            };
            if inside {
                continue;
            }
            match dda.exit_kind() {
                Exit::Inside => {}
                Exit::Top => {
                    self.escape(dda.point(dda.t), dir, &pw, out);
                    break;
                }
                Exit::Bottom => {
                    self.bottom(dda.point(dda.t), slot as u32, &pw, psum, out);
                    break;
                }
                Exit::Side(..) => {
                    if isolated {
                        add(&mut out.lost, &pw);
                        break;
                    }
                    wraps += dda.wrap_sides();
                    o = dda.origin();
                    if wraps > max_crossings {
                        add(&mut out.lost, &pw);
                        break;
                    }
                }
            }
        }
        pw_io[..W].copy_from_slice(&pw);
        out.crossings += n_cross;
        out.skipped += n_skip;
    }
}
