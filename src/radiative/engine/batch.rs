//! The batched 4-ray walk of the lean tracker: rays that [`Ctx::walk_lean`] would walk one by
//! one (dense accumulator, `turbid_subfaces: Off`, 1, 2 or 4 channels, a scene that
//! [`Ctx::simple`] covers) are queued per chunk ([`Ctx::queue`]) and walked four at a time,
//! one per lane ([`Ctx::flush`]), in AVX2 (x86-64 CPUs that have it, `pulp` runtime detection,
//! no unsafe code; elsewhere the queued rays are walked one by one by [`Ctx::walk_lean`]). Per crossing, the four lanes' segment lengths, attenuations
//! (`e^{−kℓ}`, [`attenuation_x4`]), interception points ([`HalfBarycentres::eval_x4`]), power
//! updates and DDA steps ([`Dda4::step_at`]) are computed lane-wise without a branch on the data;
//! the cell records are read and the interceptions booked lane by lane in lane order; the
//! lanes that leave a repetitive scene through a side re-enter on the opposite side lane-wise
//! ([`Dda4::wrap_sides_x4`]); a lane whose ray ends (top, bottom, lost side, threshold, wrap
//! limit) or meets a rare event (empty-space skip) leaves the lane-wise path, and a finished
//! lane is refilled with the next queued ray ([`Dda4::start`], the three axes in one vector).
//!
//! Each ray goes through the same operations as in [`Ctx::walk_lean`] (the same physics: DART 5
//! flux tracking, Gastellu-Etchegorry et al. 2015, Remote Sens. 7, 1667–1701, §3), so its own
//! contributions are the same bits; only the order in which the rays' contributions are summed
//! into the chunk's accumulators changes. The queue is filled and refilled in the chunk's own
//! order, so products do not depend on the threads. Four independent rays in flight hide the
//! latency of one ray's dependency chain, and the unpredictable per-axis branch of the scalar
//! DDA becomes a mask.

use super::{ChunkOut, Ctx, TurAcc};
#[cfg(target_arch = "x86_64")]
use super::{DenseView, add};
use crate::radiative::dda::DirStart;
#[cfg(target_arch = "x86_64")]
use crate::radiative::dda::{Dda4, Exit};
#[cfg(target_arch = "x86_64")]
use crate::radiative::fastmath::{HalfBarycentres, attenuation_x4, transpose4};
#[cfg(target_arch = "x86_64")]
use crate::scene::desc::BoundaryMode;
use glam::DVec3;
#[cfg(target_arch = "x86_64")]
use pulp::{cast, f64x4, m64x4, x86::V3};

/// Queued rays after which a chunk's queue is walked (about 20 KiB of queue: long enough that
/// the lanes stay full for all but the last few rays).
const FLUSH_AT: usize = 256;

/// A ray waiting for the batched walk: start point (m), tiling direction, channel powers (W,
/// the first `w` used), factor on its power threshold (see [`ChunkOut::ray_scale`]) and the
/// emitter's footprint (m, for images).
#[derive(Debug, Clone, Copy)]
pub(super) struct Queued {
    p: DVec3,
    dir: u32,
    pw: [f64; 4],
    ray_scale: f64,
    foot: (f64, f64),
}

/// What a lane takes at the start of a ray along one direction: the traversal's direction
/// constants, the power threshold before the ray's own factor (`min_ray · ray_factor`, the
/// first product of the one-ray walk's threshold), the single material's G (read only when
/// the scene has exactly one) and the interception slot.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct LaneDir {
    start: DirStart,
    min_ray: f64,
    g: f64,
    slot: usize,
}

/// [`LaneDir`] of every direction of `ctx` (sun last).
pub(super) fn lane_dirs(ctx: &Ctx) -> Vec<LaneDir> {
    (0..ctx.omega.len())
        .map(|dir| LaneDir {
            start: DirStart::new(ctx.inp.spec, ctx.omega[dir]),
            min_ray: ctx.min_ray * ctx.ray_factor[dir],
            g: ctx.g_dir.get(dir * ctx.n_tm).copied().unwrap_or(0.0),
            slot: ctx.slot_of(dir),
        })
        .collect()
}

/// The AVX2 + FMA token the batched walk runs with on dispatch target `arch` (AVX-512 targets
/// run the same code); `None`: no batched walk (rays one by one).
#[cfg(target_arch = "x86_64")]
fn lane_simd(arch: &pulp::Arch) -> Option<V3> {
    match arch {
        pulp::Arch::V4(v4) => Some(**v4),
        pulp::Arch::V3(v3) => Some(*v3),
        _ => None,
    }
}

/// Whether dispatch target `arch` runs the batched walk (x86-64 with AVX2 and FMA).
pub(super) fn available(arch: &pulp::Arch) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        lane_simd(arch).is_some()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = arch;
        false
    }
}

/// The instruction set the flux-tracking walks run on this CPU by default (for the benches'
/// records): `"AVX-512"` (the AVX2 code compiled with AVX-512 available), `"AVX2"`, or
/// `"baseline"`.
pub fn kernel_isa() -> &'static str {
    match super::KernelIsa::Best.arch() {
        #[cfg(target_arch = "x86_64")]
        pulp::Arch::V4(_) => "AVX-512",
        #[cfg(target_arch = "x86_64")]
        pulp::Arch::V3(_) => "AVX2",
        _ => "baseline",
    }
}

impl Ctx<'_> {
    /// Queues a ray for the batched walk instead of walking it now (see the module doc); the
    /// queue is walked when it is long enough and by [`Ctx::flush`] at the end of the chunk.
    pub(super) fn queue(&self, p: DVec3, dir: usize, pw: &[f64], out: &mut ChunkOut) {
        let mut q = Queued {
            p,
            dir: dir as u32,
            pw: [0.0; 4],
            ray_scale: out.ray_scale,
            foot: out.foot,
        };
        q.pw[..self.w].copy_from_slice(&pw[..self.w]);
        out.queue.push(q);
        if out.queue.len() >= FLUSH_AT {
            self.flush(out);
        }
    }

    /// [`Ctx::queue`] of a ray of powers `v[ch] · share` (W, the products `send` forms).
    #[inline]
    pub(super) fn queue_scaled(
        &self,
        p: DVec3,
        dir: usize,
        v: &[f64],
        share: f64,
        out: &mut ChunkOut,
    ) {
        let mut q = Queued {
            p,
            dir: dir as u32,
            pw: [0.0; 4],
            ray_scale: out.ray_scale,
            foot: out.foot,
        };
        for (a, b) in q.pw.iter_mut().zip(&v[..self.w]) {
            *a = b * share;
        }
        out.queue.push(q);
        if out.queue.len() >= FLUSH_AT {
            self.flush(out);
        }
    }

    /// Walks every queued ray (in queue order into the lanes); a no-op on an empty queue.
    pub(super) fn flush(&self, out: &mut ChunkOut) {
        if out.queue.is_empty() {
            return;
        }
        let queue = std::mem::take(&mut out.queue);
        let mut tur = out.tur.take().expect("accumulator");
        match self.w {
            1 => self.walk_batch::<1>(&queue, &mut tur, out),
            2 => self.walk_batch::<2>(&queue, &mut tur, out),
            _ => self.walk_batch::<4>(&queue, &mut tur, out),
        }
        out.tur = Some(tur);
        // The queue's allocation is kept for the next rays.
        out.queue = queue;
        out.queue.clear();
    }

    fn walk_batch<const W: usize>(&self, queue: &[Queued], tur: &mut TurAcc, out: &mut ChunkOut) {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = lane_simd(&self.arch) {
            let mut view = tur
                .view()
                .expect("rays are queued with a dense accumulator only");
            view.w = W;
            /// The walk's arguments, run by `pulp` in AVX2 + FMA.
            struct Walk<'c, 'v, 'o, 'x, const W: usize> {
                ctx: &'c Ctx<'x>,
                simd: V3,
                queue: &'o [Queued],
                view: &'o mut DenseView<'v>,
                out: &'o mut ChunkOut,
            }
            impl<const W: usize> pulp::WithSimd for Walk<'_, '_, '_, '_, W> {
                type Output = ();
                #[inline(always)]
                fn with_simd<S: pulp::Simd>(self, _simd: S) {
                    let (ctx, simd) = (self.ctx, self.simd);
                    if ctx.n_tm == 1 {
                        ctx.walk_batch_body::<W, true>(simd, self.queue, self.view, self.out)
                    } else {
                        ctx.walk_batch_body::<W, false>(simd, self.queue, self.view, self.out)
                    }
                }
            }
            let walk = Walk::<W> {
                ctx: self,
                simd,
                queue,
                view: &mut view,
                out,
            };
            // The same AVX2 operations compiled with AVX-512 available where the CPU has it
            // (32 vector registers instead of 16, EVEX compares into mask registers): the same
            // IEEE operations on the same values, so the same bits.
            if let pulp::Arch::V4(v4) = self.arch {
                return pulp::Simd::vectorize(v4, walk);
            }
            return pulp::Simd::vectorize(simd, walk);
        }
        // No AVX2: the rays one by one, in queue order.
        let (foot, scale) = (out.foot, out.ray_scale);
        for q in queue {
            let mut pw = q.pw;
            (out.foot, out.ray_scale) = (q.foot, q.ray_scale);
            self.trace_simple::<W>(q.p, q.dir as usize, &mut pw, tur, out);
        }
        (out.foot, out.ray_scale) = (foot, scale);
    }

    /// The body of [`Ctx::walk_batch`] (inlined into the AVX2 copy); `ONE_TM`: the scene has
    /// one tracked turbid material.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn walk_batch_body<const W: usize, const ONE_TM: bool>(
        &self,
        simd: V3,
        queue: &[Queued],
        view: &mut DenseView,
        out: &mut ChunkOut,
    ) {
        let spec = self.inp.spec;
        let g_dir = &self.g_dir[..];
        let hb = HalfBarycentres::get();
        let isolated = spec.boundary == BoundaryMode::Isolated;
        let max_crossings = self.inp.params.max_crossings;
        let scells = &self.scells[..];
        let ns = view.ns;
        // The records as rows (one bounds check per booking instead of a range check): the
        // channel powers of (entry, slot) and the seven point sums of an entry.
        let tur: &mut [[f64; W]] = view.tur.as_chunks_mut::<W>().0;
        let pts: &mut [[f64; 7]] = view.pts.as_chunks_mut::<7>().0;
        let flag = &mut *view.flag;
        let touched = &mut *view.touched;
        let mut ln = Lanes::<W> {
            dda: Dda4::default(),
            act: 0,
            pw: [[0.0; 4]; W],
            psum: [0.0; 4],
            min_ray: [0.0; 4],
            g: [0.0; 4],
            g_row: [0; 4],
            slot: [0; 4],
            dirs: [0; 4],
            foot: [(0.0, 0.0); 4],
            wraps: [0.0; 4],
            next: 0,
        };
        ln.dda.set_grid(spec);
        let mut n_cross = 0u64;
        let mut n_skip = 0u64;
        let foot_saved = out.foot;
        for l in 0..4 {
            ln.refill(simd, self, l, queue, out);
        }
        let sp = |v: f64| simd.splat_f64x4(v);
        let zero = sp(0.0);
        // Lane bit masks as vector masks (one table row per 4-bit mask).
        const MASKS: [[u64; 4]; 16] = {
            let mut t = [[0u64; 4]; 16];
            let mut b = 0;
            while b < 16 {
                let mut l = 0;
                while l < 4 {
                    if b & (1 << l) != 0 {
                        t[b][l] = u64::MAX;
                    }
                    l += 1;
                }
                b += 1;
            }
            t
        };
        let mask = |bits: u32| -> m64x4 { cast(MASKS[(bits & 15) as usize]) };
        let bits = |m: m64x4| -> u32 { simd.avx._mm256_movemask_pd(cast(m)) as u32 };
        while ln.act != 0 {
            // Cell records, lane by lane; the lanes in empty cells at distance r > 1 jump over
            // the empty box around them (an event).
            let mut dens = [0.0; 4];
            let mut idx = [0u32; 4];
            let mut tms = [0u64; 4];
            for l in 0..4 {
                let sc = scells[ln.dda.lin[l] as usize];
                dens[l] = sc.density;
                idx[l] = sc.idx;
                tms[l] = sc.tm as u64;
            }
            let dens: f64x4 = cast(dens);
            let occ = simd.cmp_gt_f64x4(dens, zero);
            // Empty cells at distance r = tm > 1 (an empty cell's tm is its skip distance).
            let far = simd.cmp_gt_u64x4(cast(tms), simd.splat_u64x4(1));
            let skip = bits(simd.andnot_m64x4(occ, far)) & ln.act;
            let g: f64x4 = if ONE_TM {
                cast(ln.g)
            } else {
                let occ: [u64; 4] = cast(occ);
                cast::<[f64; 4], f64x4>(std::array::from_fn(|l| {
                    // An empty cell's tm is its skip distance, not a material: no G read.
                    let tm = if occ[l] != 0 { tms[l] as usize } else { 0 };
                    g_dir.get(ln.g_row[l] + tm).copied().unwrap_or(0.0)
                }))
            };
            let k = simd.mul_f64x4(g, dens);
            let act = mask(ln.act);
            let t0: f64x4 = cast(ln.dda.t);
            let t1 = ln.dda.t_exit(simd);
            let ell = simd.sub_f64x4(t1, t0);
            let hit_m = simd.and_m64x4(
                simd.and_m64x4(act, occ),
                simd.and_m64x4(simd.cmp_gt_f64x4(t1, t0), simd.cmp_gt_f64x4(k, zero)),
            );
            let hit = bits(hit_m);
            let x = simd.select_f64x4(hit_m, simd.mul_f64x4(k, ell), zero);
            let (frac, tr) = attenuation_x4(simd, x);
            let (s1, s2) = hb.eval_x4(simd, x, ell, hit_m);
            let psum: f64x4 = cast(ln.psum);
            let wt: [f64; 4] = cast(simd.mul_f64x4(psum, frac));
            let point = |a: usize, s: f64x4| -> [f64; 4] {
                let o: f64x4 = cast(ln.dda.origin[a]);
                let d: f64x4 = cast(ln.dda.dir[a]);
                cast(simd.add_f64x4(o, simd.mul_f64x4(d, simd.add_f64x4(t0, s))))
            };
            let p1 = [point(0, s1), point(1, s1), point(2, s1)];
            let p2 = [point(0, s2), point(1, s2), point(2, s2)];
            let mut gain = [[0.0; 4]; W];
            for c in 0..W {
                let pwc: f64x4 = cast(ln.pw[c]);
                gain[c] = cast(simd.mul_f64x4(pwc, frac));
                // Lanes without a hit have x = 0, so tr = 1 − 0 = 1 exactly and `pw · tr` is pw:
                // no select (which the compiler turns into a masked store, `vmaskmovpd`, slow
                // on AMD CPUs without AVX-512).
                ln.pw[c] = cast(simd.mul_f64x4(pwc, tr));
            }
            // The weighted interception points lane-wise (`p · wt`, the scalar walk's products),
            // then one row per lane: [p1x, p1y, p1z, p2x] · wt and [p2y · wt, p2z · wt, wt, 0].
            let wtv: f64x4 = cast(wt);
            let pw_pt = |v: [f64; 4]| simd.mul_f64x4(cast(v), wtv);
            let rows_a: [[f64; 4]; 4] = transpose4(
                simd,
                [pw_pt(p1[0]), pw_pt(p1[1]), pw_pt(p1[2]), pw_pt(p2[0])],
            )
            .map(cast);
            let rows_b: [[f64; 4]; 4] =
                transpose4(simd, [pw_pt(p2[1]), pw_pt(p2[2]), wtv, zero]).map(cast);
            // Interceptions booked lane by lane (a fixed order).
            for l in 0..4 {
                if hit & (1 << l) == 0 {
                    continue;
                }
                let e = idx[l] as usize;
                if !flag[e] {
                    flag[e] = true;
                    touched.push(e as u32);
                }
                let r = &mut tur[e * ns + ln.slot[l]];
                for c in 0..W {
                    r[c] += gain[c][l];
                }
                let q = &mut pts[e];
                for i in 0..4 {
                    q[i] += rows_a[l][i];
                }
                for i in 0..3 {
                    q[4 + i] += rows_b[l][i];
                }
            }
            // The channel sum in channel order (as `pw.iter().sum()`).
            let mut psum: f64x4 = cast(ln.pw[0]);
            for c in 1..W {
                psum = simd.add_f64x4(psum, cast(ln.pw[c]));
            }
            ln.psum = cast(psum);
            let dead = hit & bits(simd.cmp_lt_f64x4(psum, cast(ln.min_ray)));
            let go = ln.act & !skip & !dead;
            let out_m = ln.dda.step_at(simd, t1, mask(go));
            n_cross += ln.act.count_ones() as u64;
            let mut out_b = go & bits(out_m);
            // Lanes past the wrap limit (lost).
            let mut over = 0u32;
            if out_b != 0 && !isolated {
                // Lanes that left through a side only (top and bottom win at a tie, as in
                // `Dda::exit_kind`): wrapped to the opposite side lane-wise.
                let side = out_b & !bits(ln.dda.z_outside(simd));
                if side != 0 {
                    let wraps =
                        simd.add_f64x4(cast(ln.wraps), ln.dda.wrap_sides_x4(simd, mask(side)));
                    ln.wraps = cast(wraps);
                    over = side & bits(simd.cmp_gt_f64x4(wraps, sp(max_crossings as f64)));
                    out_b &= !side;
                }
            }
            let ev = skip | dead | over | out_b;
            if ev == 0 {
                continue;
            }
            for l in 0..4 {
                if ev & (1 << l) == 0 {
                    continue;
                }
                let lane_pw: [f64; W] = std::array::from_fn(|c| ln.pw[c][l]);
                let finished = if (dead | over) & (1 << l) != 0 {
                    add(&mut out.lost, &lane_pw);
                    true
                } else if skip & (1 << l) != 0 && {
                    // Empty cell at distance r = tm: jump over the empty box around it.
                    let mut d = ln.dda.lane(l);
                    let h = tms[l] as i64 - 1;
                    let (e, faces) = d.skip_to(h, d.skip_exit(h));
                    n_skip += faces - 1;
                    ln.dda.set_lane(l, &d);
                    e == Exit::Inside
                } {
                    false
                } else {
                    match ln.dda.exit_kind(l) {
                        Exit::Inside => false,
                        Exit::Top => {
                            out.foot = ln.foot[l];
                            self.escape(ln.dda.point(l), ln.dirs[l], &lane_pw, out);
                            true
                        }
                        Exit::Bottom => {
                            let slot = ln.slot[l] as u32;
                            self.bottom(ln.dda.point(l), slot, &lane_pw, ln.psum[l], out);
                            true
                        }
                        Exit::Side(..) => {
                            if isolated {
                                add(&mut out.lost, &lane_pw);
                                true
                            } else {
                                ln.wraps[l] += ln.dda.wrap_sides(l) as f64;
                                if ln.wraps[l] > max_crossings as f64 {
                                    add(&mut out.lost, &lane_pw);
                                    true
                                } else {
                                    false
                                }
                            }
                        }
                    }
                };
                if finished {
                    ln.refill(simd, self, l, queue, out);
                }
            }
        }
        out.foot = foot_saved;
        out.crossings += n_cross;
        out.skipped += n_skip;
    }
}

/// Per-lane state of the batched walk: traversal, active lanes (bit l), channel powers
/// `pw[c][l]` and their sum, power threshold, start of the G row (and the single material's
/// G), slot, direction, footprint, side wraps (integer-valued); `next`: the next queued ray.
#[cfg(target_arch = "x86_64")]
struct Lanes<const W: usize> {
    dda: Dda4,
    act: u32,
    pw: [[f64; 4]; W],
    psum: [f64; 4],
    min_ray: [f64; 4],
    g: [f64; 4],
    g_row: [usize; 4],
    slot: [usize; 4],
    dirs: [usize; 4],
    foot: [(f64, f64); 4],
    wraps: [f64; 4],
    next: usize,
}

#[cfg(target_arch = "x86_64")]
impl<const W: usize> Lanes<W> {
    /// Takes the next queued ray that starts inside the grid into lane l (rays that do not are
    /// booked as lost, as in the scalar walk); parks the lane when the queue is done.
    #[inline(always)]
    fn refill(&mut self, simd: V3, ctx: &Ctx, l: usize, queue: &[Queued], out: &mut ChunkOut) {
        loop {
            let Some(q) = queue.get(self.next) else {
                self.act &= !(1 << l);
                self.dda.park(l);
                return;
            };
            self.next += 1;
            out.rays += 1;
            let dir = q.dir as usize;
            let ld = &ctx.lane_dirs[dir];
            if !self.dda.start_with(simd, l, q.p, &ld.start) {
                add(&mut out.lost, &q.pw[..W]);
                continue;
            }
            self.act |= 1 << l;
            for c in 0..W {
                self.pw[c][l] = q.pw[c];
            }
            self.psum[l] = q.pw[..W].iter().sum();
            // The same threshold as the one-ray walk's.
            self.min_ray[l] = ld.min_ray * q.ray_scale;
            self.g_row[l] = dir * ctx.n_tm;
            // The single material's G (read only when the scene has exactly one).
            self.g[l] = ld.g;
            self.slot[l] = ld.slot;
            self.dirs[l] = dir;
            self.foot[l] = q.foot;
            self.wraps[l] = 0.0;
            return;
        }
    }
}
