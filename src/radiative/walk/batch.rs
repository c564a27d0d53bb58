//! The batched walk of the lean tracker: rays that [`Ctx::walk_lean`] would walk one by one
//! (dense accumulator, `turbid_subfaces: Off`, 1, 2 or 4 channels, a scene that
//! [`Ctx::simple`] covers) are queued per chunk ([`Ctx::queue`]) and walked L at a time, one
//! per lane ([`Ctx::flush`]): by default 16 lanes in single-precision geometry on CPUs with
//! AVX-512 (module `wide32`, [`crate::radiative::engine::TrackingParams::batch_f32`]); otherwise (this module's
//! double-precision walk) 8 lanes in AVX-512 registers on CPUs that have it, 4 in AVX2
//! elsewhere on x86-64 ([`crate::radiative::lanes`]; `pulp` runtime detection, no unsafe
//! code; without AVX2 the queued rays are walked one by one by [`Ctx::walk_lean`]). Per
//! crossing, the lanes' segment lengths, attenuations (`e^{−kℓ}`, [`attenuation_l`]),
//! interception points ([`HalfBarycentres::eval_l`]), power updates and DDA steps
//! ([`DdaL::step_at`]) are computed lane-wise without a branch on the data; the cell records
//! are read and the interceptions booked lane by lane in lane order (the lanes' weighted
//! points transposed into one row per lane, [`Lanes::rows7`]); the lanes that leave a
//! repetitive scene through a side re-enter on the opposite side lane-wise
//! ([`DdaL::wrap_sides_l`]); a lane whose ray ends (top, bottom, lost side, threshold, wrap
//! limit) or meets a rare event (empty-space skip) leaves the lane-wise path, and a finished
//! lane is refilled with the next queued ray ([`DdaL::start_with`], the three axes in one
//! vector).
//!
//! Each ray goes through the same operations as in [`Ctx::walk_lean`] (the same physics: DART 5
//! flux tracking, Gastellu-Etchegorry et al. 2015, Remote Sens. 7, 1667–1701, §3), so its own
//! contributions are the same bits; only the order in which the rays' contributions are summed
//! into the chunk's accumulators changes (with the lane count: 8-lane and 4-lane products
//! differ in the last bits, ~1e-15 relative). The queue is filled and refilled in the chunk's
//! own order, so products do not depend on the threads. L independent rays in flight hide the
//! latency of one ray's dependency chain, and the unpredictable per-axis branch of the scalar
//! DDA becomes a mask.

use crate::radiative::dda::DirStart;
#[cfg(target_arch = "x86_64")]
use crate::radiative::dda::{DdaL, Exit};
use crate::radiative::engine::{ChunkOut, Ctx, TurAcc};
#[cfg(target_arch = "x86_64")]
use crate::radiative::engine::{DenseView, add, record};
#[cfg(target_arch = "x86_64")]
use crate::radiative::fastmath::{HalfBarycentres, attenuation_l};
#[cfg(target_arch = "x86_64")]
use crate::radiative::lanes::Lanes;
#[cfg(target_arch = "x86_64")]
use crate::scene::desc::BoundaryMode;
use glam::DVec3;
#[cfg(target_arch = "x86_64")]
use pulp::x86::V3;

#[cfg(target_arch = "x86_64")]
mod wide32;
#[cfg(target_arch = "x86_64")]
pub(in crate::radiative) use wide32::LaneDir32;
#[cfg(target_arch = "x86_64")]
pub(in crate::radiative) use wide32::fits as fits32;
/// Placeholder off x86-64 (no single-precision walk there).
#[cfg(not(target_arch = "x86_64"))]
#[derive(Debug, Clone, Copy, Default)]
pub(in crate::radiative) struct LaneDir32;

/// [`LaneDir32`] of every direction of `ctx` (sun last) when the single-precision 16-lane walk
/// runs ([`crate::radiative::engine::TrackingParams::batch_f32`] on an AVX-512 CPU, a grid that fits its `i32`
/// indices); empty otherwise.
pub(in crate::radiative) fn lane_dirs32(ctx: &Ctx) -> Vec<LaneDir32> {
    #[cfg(target_arch = "x86_64")]
    if super::batched_f32(ctx) {
        return ctx
            .omega
            .iter()
            .map(|&d| LaneDir32::new(ctx.inp.spec, d))
            .collect();
    }
    Vec::new()
}

/// Queued rays after which a chunk's queue is walked (about 20 KiB of queue: long enough that
/// the lanes stay full for all but the last few rays).
const FLUSH_AT: usize = 256;

/// [`FLUSH_AT`] of the single-precision 16-lane walk: with twice the lanes, the passes at the
/// queue's end where lanes run out weigh more (measured, paired, Default 100 0.2: 512 rays
/// 1.03× of 256 together with `bottom_at`, 1024 a further 1.016×).
const FLUSH_AT_WIDE: usize = 1024;

/// A ray waiting for the batched walk: start point (m), tiling direction, channel powers (W,
/// the first `w` used), factor on its power threshold (see [`ChunkOut::ray_scale`]) and the
/// emitter's footprint (m, for images).
#[derive(Debug, Clone, Copy)]
pub(in crate::radiative) struct Queued {
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
pub(in crate::radiative) struct LaneDir {
    start: DirStart,
    min_ray: f64,
    g: f64,
    slot: usize,
}

/// [`LaneDir`] of every direction of `ctx` (sun last).
pub(in crate::radiative) fn lane_dirs(ctx: &Ctx) -> Vec<LaneDir> {
    (0..ctx.omega.len())
        .map(|dir| LaneDir {
            start: DirStart::new(ctx.inp.spec, ctx.omega[dir]),
            min_ray: ctx.min_ray * ctx.ray_factor[dir],
            g: ctx.g_dir.get(dir * ctx.n_tm).copied().unwrap_or(0.0),
            slot: ctx.slot_of(dir),
        })
        .collect()
}

/// Whether dispatch target `arch` runs the batched walk (x86-64 with AVX2 and FMA: 4 lanes;
/// with AVX-512: 8).
pub(in crate::radiative) fn available(arch: &pulp::Arch) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        matches!(arch, pulp::Arch::V4(_) | pulp::Arch::V3(_))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = arch;
        false
    }
}

/// The instruction set the flux-tracking walks run on this CPU by default (for the benches'
/// records): `"AVX-512"` (the batched walk on 16 single-precision or 8 double-precision
/// lanes), `"AVX2"` (4 lanes), or `"baseline"` (rays one by one).
pub fn kernel_isa() -> &'static str {
    instruction_set(crate::radiative::engine::KernelIsa::Best)
}

/// The instruction set the walks run on this CPU under cap `isa` (see [`kernel_isa`]).
pub fn instruction_set(isa: crate::radiative::engine::KernelIsa) -> &'static str {
    match crate::radiative::engine::isa_arch(isa) {
        #[cfg(target_arch = "x86_64")]
        pulp::Arch::V4(_) => "AVX-512",
        #[cfg(target_arch = "x86_64")]
        pulp::Arch::V3(_) => "AVX2",
        _ => "baseline",
    }
}

/// Rays the batched walk has in flight on this CPU under cap `isa`, with or without the
/// single-precision walk (`batch_f32`, [`crate::radiative::engine::TrackingParams::batch_f32`]): 16 (AVX-512,
/// single precision), 8 (AVX-512), 4 (AVX2), 1 (no batched walk). Products of runs with the
/// same count are the same bits; between 8 and 4 they differ in the last bits (summation
/// order), between 16 and the others by ~3e-7 relative (single-precision geometry).
pub fn batch_lanes(isa: crate::radiative::engine::KernelIsa, batch_f32: bool) -> usize {
    match crate::radiative::engine::isa_arch(isa) {
        #[cfg(target_arch = "x86_64")]
        pulp::Arch::V4(_) if batch_f32 => 16,
        #[cfg(target_arch = "x86_64")]
        pulp::Arch::V4(_) => 8,
        #[cfg(target_arch = "x86_64")]
        pulp::Arch::V3(_) => 4,
        _ => 1,
    }
}

impl Ctx<'_> {
    /// Queues a ray for the batched walk instead of walking it now (see the module doc); the
    /// queue is walked when it is long enough and by [`Ctx::flush`] at the end of the chunk.
    pub(in crate::radiative) fn queue(&self, p: DVec3, dir: usize, pw: &[f64], out: &mut ChunkOut) {
        let mut q = Queued {
            p,
            dir: dir as u32,
            pw: [0.0; 4],
            ray_scale: out.ray_scale,
            foot: out.foot,
        };
        q.pw[..self.w].copy_from_slice(&pw[..self.w]);
        out.queue.push(q);
        if out.queue.len() >= self.flush_at() {
            self.flush(out);
        }
    }

    /// [`Ctx::queue`] of a ray of powers `v[ch] · share` (W, the products `send` forms).
    #[inline]
    pub(in crate::radiative) fn queue_scaled(
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
        if out.queue.len() >= self.flush_at() {
            self.flush(out);
        }
    }

    /// Queue length at which the queue is walked.
    #[inline(always)]
    fn flush_at(&self) -> usize {
        if super::select(self, false, true) != super::WalkKind::BatchF32 {
            FLUSH_AT
        } else {
            FLUSH_AT_WIDE
        }
    }

    /// Walks every queued ray (in queue order into the lanes); a no-op on an empty queue.
    pub(in crate::radiative) fn flush(&self, out: &mut ChunkOut) {
        if out.queue.is_empty() {
            return;
        }
        let queue = std::mem::take(&mut out.queue);
        let mut tur = out.tur.take().expect("accumulator");
        #[cfg(target_arch = "x86_64")]
        if super::select(self, false, true) == super::WalkKind::BatchF32 {
            match self.w {
                1 => self.walk_wide::<1>(&queue, &mut tur, out),
                2 => self.walk_wide::<2>(&queue, &mut tur, out),
                _ => self.walk_wide::<4>(&queue, &mut tur, out),
            }
            out.tur = Some(tur);
            out.queue = queue;
            out.queue.clear();
            return;
        }
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
        if let pulp::Arch::V4(_) | pulp::Arch::V3(_) = self.arch {
            let mut view = tur
                .view()
                .expect("rays are queued with a dense accumulator only");
            view.w = W;
            /// The walk's arguments, run by `pulp` with the target's instruction set: 8 lanes
            /// in AVX-512 registers (`V4`), 4 in AVX2 (`V3`).
            struct Walk<'c, 'v, 'o, 'x, const W: usize> {
                ctx: &'c Ctx<'x>,
                queue: &'o [Queued],
                view: &'o mut DenseView<'v>,
                out: &'o mut ChunkOut,
            }
            impl<const W: usize> Walk<'_, '_, '_, '_, W> {
                #[inline(always)]
                fn run<S: Lanes<L>, const L: usize>(self, s: S) {
                    let ctx = self.ctx;
                    if ctx.n_tm == 1 {
                        ctx.walk_batch_body::<S, L, W, true>(s, self.queue, self.view, self.out)
                    } else {
                        ctx.walk_batch_body::<S, L, W, false>(s, self.queue, self.view, self.out)
                    }
                }
            }
            /// The walk on L lanes of token `S`, run by `pulp` with that token's instruction set:
            /// 8 lanes with AVX-512 (`V4`), 4 with AVX2 (`V3`; 8 lanes as two AVX2 halves, the
            /// same bits as AVX-512, measured 40 against 55 Mcross/s/core: spills in 16
            /// registers).
            struct WalkOn<'c, 'v, 'o, 'x, S, const L: usize, const W: usize>(
                Walk<'c, 'v, 'o, 'x, W>,
                S,
            );
            impl<S: Lanes<L>, const L: usize, const W: usize> pulp::WithSimd
                for WalkOn<'_, '_, '_, '_, S, L, W>
            {
                type Output = ();
                #[inline(always)]
                fn with_simd<T: pulp::Simd>(self, _simd: T) {
                    self.0.run::<S, L>(self.1)
                }
            }
            let walk = Walk::<W> {
                ctx: self,
                queue,
                view: &mut view,
                out,
            };
            if let pulp::Arch::V4(v4) = self.arch {
                return pulp::Simd::vectorize(v4, WalkOn::<_, 8, W>(walk, v4));
            }
            if let pulp::Arch::V3(v3) = self.arch {
                return pulp::Simd::vectorize(v3, WalkOn::<_, 4, W>(walk, v3));
            }
        }
        // No AVX2: the rays one by one, in queue order.
        let (foot, scale) = (out.foot, out.ray_scale);
        for q in queue {
            let mut pw = q.pw;
            (out.foot, out.ray_scale) = (q.foot, q.ray_scale);
            self.trace_lean(q.p, q.dir as usize, &mut pw, tur, out);
        }
        (out.foot, out.ray_scale) = (foot, scale);
    }

    /// The body of [`Ctx::walk_batch`] on L lanes (inlined into the AVX2 and AVX-512 copies);
    /// `ONE_TM`: the scene has one tracked turbid material.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn walk_batch_body<S: Lanes<L>, const L: usize, const W: usize, const ONE_TM: bool>(
        &self,
        s: S,
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
        let rec = &mut *view.rec;
        let touched = &mut *view.touched;
        let mut ln = InFlight::<W, L> {
            dda: DdaL::default(),
            act: 0,
            pw: [[0.0; L]; W],
            psum: [0.0; L],
            min_ray: [0.0; L],
            g: [0.0; L],
            g_row: [0; L],
            slot: [0; L],
            dirs: [0; L],
            foot: [(0.0, 0.0); L],
            wraps: [0.0; L],
            next: 0,
        };
        ln.dda.set_grid(spec);
        let mut n_cross = 0u64;
        let mut n_skip = 0u64;
        let foot_saved = out.foot;
        let v3 = s.v3();
        for l in 0..L {
            ln.refill(v3, self, l, queue, out);
        }
        let sp = |v: f64| s.splat(v);
        let zero = sp(0.0);
        while ln.act != 0 {
            // Cell records, lane by lane; the lanes in empty cells at distance r > 1 jump over
            // the empty box around them (an event).
            let (mut dens, mut idx, mut tms) = ([0.0; L], [0u32; L], [0u64; L]);
            let far = cell_records(scells, &ln.dda.lin, &mut dens, &mut idx, &mut tms);
            let dens = s.ld(dens);
            let occ = s.gt(dens, zero);
            // Empty cells at distance r = tm > 1 (an empty cell's tm is its skip distance).
            let skip = !s.bits(occ) & far & ln.act;
            let g = if ONE_TM {
                s.ld(ln.g)
            } else {
                let occ = s.bits(occ);
                s.ld(std::array::from_fn(|l| {
                    // An empty cell's tm is its skip distance, not a material: no G read.
                    let tm = if occ >> l & 1 != 0 {
                        tms[l] as usize
                    } else {
                        0
                    };
                    g_dir.get(ln.g_row[l] + tm).copied().unwrap_or(0.0)
                }))
            };
            let k = s.mul(g, dens);
            let act = s.mask(ln.act);
            let t0 = s.ld(ln.dda.t);
            let t1 = ln.dda.t_exit(s);
            let ell = s.sub(t1, t0);
            let hit_m = s.and(s.and(act, occ), s.and(s.gt(t1, t0), s.gt(k, zero)));
            let hit = s.bits(hit_m);
            let x = s.sel(hit_m, s.mul(k, ell), zero);
            let (frac, tr) = attenuation_l(s, x);
            let (s1, s2) = hb.eval_l(s, x, ell, hit_m);
            let psum = s.ld(ln.psum);
            let wtv = s.mul(psum, frac);
            let point = |a: usize, sv: S::F| -> S::F {
                let o = s.ld(ln.dda.origin[a]);
                let d = s.ld(ln.dda.dir[a]);
                s.add(o, s.mul(d, s.add(t0, sv)))
            };
            let p1 = [point(0, s1), point(1, s1), point(2, s1)];
            let p2 = [point(0, s2), point(1, s2), point(2, s2)];
            let mut gain = [[0.0; L]; W];
            for c in 0..W {
                let pwc = s.ld(ln.pw[c]);
                gain[c] = s.st(s.mul(pwc, frac));
                // Lanes without a hit have x = 0, so tr = 1 − 0 = 1 exactly and `pw · tr` is pw:
                // no select (which the compiler turns into a masked store, `vmaskmovpd` in the
                // AVX2 copy, slow on AMD CPUs).
                ln.pw[c] = s.st(s.mul(pwc, tr));
            }
            // The weighted interception points lane-wise (`p · wt`, the scalar walk's products),
            // then one row per lane: [p1 · wt, p2 · wt, wt].
            let pw_pt = |v: S::F| s.mul(v, wtv);
            let rows = s.rows7([
                pw_pt(p1[0]),
                pw_pt(p1[1]),
                pw_pt(p1[2]),
                pw_pt(p2[0]),
                pw_pt(p2[1]),
                pw_pt(p2[2]),
                wtv,
            ]);
            // Interceptions booked lane by lane (a fixed order).
            for l in 0..L {
                if hit & (1 << l) == 0 {
                    continue;
                }
                let e = record(rec, touched, idx[l] as usize);
                let r = &mut tur[e * ns + ln.slot[l]];
                for c in 0..W {
                    r[c] += gain[c][l];
                }
                let q = &mut pts[e];
                for i in 0..7 {
                    q[i] += rows[l][i];
                }
            }
            // The channel sum in channel order (as `pw.iter().sum()`).
            let mut psum = s.ld(ln.pw[0]);
            for c in 1..W {
                psum = s.add(psum, s.ld(ln.pw[c]));
            }
            ln.psum = s.st(psum);
            let dead = hit & s.bits(s.lt(psum, s.ld(ln.min_ray)));
            let go = ln.act & !skip & !dead;
            let out_m = ln.dda.step_at(s, t1, s.mask(go));
            n_cross += ln.act.count_ones() as u64;
            let mut out_b = go & s.bits(out_m);
            // Lanes past the wrap limit (lost).
            let mut over = 0u32;
            if out_b != 0 && !isolated {
                // Lanes that left through a side only (top and bottom win at a tie, as in
                // `Dda::exit_kind`): wrapped to the opposite side lane-wise.
                let side = out_b & !s.bits(ln.dda.z_outside(s));
                if side != 0 {
                    let wraps = s.add(s.ld(ln.wraps), ln.dda.wrap_sides_l(s, s.mask(side)));
                    ln.wraps = s.st(wraps);
                    over = side & s.bits(s.gt(wraps, sp(max_crossings as f64)));
                    out_b &= !side;
                }
            }
            let ev = skip | dead | over | out_b;
            if ev == 0 {
                continue;
            }
            n_skip += self.lane_events(v3, &mut ln, (ev, dead | over, skip), &tms, queue, out);
        }
        out.foot = foot_saved;
        out.crossings += n_cross;
        out.skipped += n_skip;
    }

    /// The scalar events of the lanes in `ev` after a crossing (physics.md §6.3): lanes in
    /// `lost` (power under the threshold, or past the wrap limit) are booked as lost; lanes in
    /// `skip` jump over the empty box around their cell (`tms`: the cells' records, an empty
    /// cell's being its skip distance); the others escape through the top, reach the bottom or
    /// leave through a side (lost in isolated scenes, else wrapped up to `max_crossings`).
    /// Each finished lane is refilled from `queue`. Returns the empty cells jumped over.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn lane_events<const W: usize, const L: usize>(
        &self,
        v3: V3,
        ln: &mut InFlight<W, L>,
        (ev, lost, skip): (u32, u32, u32),
        tms: &[u64; L],
        queue: &[Queued],
        out: &mut ChunkOut,
    ) -> u64 {
        let isolated = self.inp.spec.boundary == BoundaryMode::Isolated;
        let max_crossings = self.inp.params.max_crossings;
        let mut n_skip = 0u64;
        for l in 0..L {
            if ev & (1 << l) == 0 {
                continue;
            }
            let lane_pw: [f64; W] = std::array::from_fn(|c| ln.pw[c][l]);
            let finished = if lost & (1 << l) != 0 {
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
                ln.refill(v3, self, l, queue, out);
            }
        }
        n_skip
    }
}

/// The cell records of the lanes' cells `lin` into `dens` (densities), `idx` (accumulator
/// indices) and `tms` (records: an empty cell's is its skip distance); returns, as bits, the
/// lanes in cells whose record is > 1. The bits are formed in scalar registers: a vector load
/// of the lanes' just-stored values would wait for the stores to retire (no store-to-load
/// forwarding from several stores).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn cell_records<const L: usize>(
    scells: &[crate::radiative::engine::SimpleCell],
    lin: &[i64; L],
    dens: &mut [f64; L],
    idx: &mut [u32; L],
    tms: &mut [u64; L],
) -> u32 {
    let mut far = 0u32;
    for l in 0..L {
        let sc = scells[lin[l] as usize];
        dens[l] = sc.density;
        idx[l] = sc.idx;
        tms[l] = sc.tm as u64;
        far |= ((sc.tm > 1) as u32) << l;
    }
    far
}

/// Per-lane state of the batched walk: traversal, active lanes (bit l), channel powers
/// `pw[c][l]` and their sum, power threshold, start of the G row (and the single material's
/// G), slot, direction, footprint, side wraps (integer-valued); `next`: the next queued ray.
#[cfg(target_arch = "x86_64")]
struct InFlight<const W: usize, const L: usize> {
    dda: DdaL<L>,
    act: u32,
    pw: [[f64; L]; W],
    psum: [f64; L],
    min_ray: [f64; L],
    g: [f64; L],
    g_row: [usize; L],
    slot: [usize; L],
    dirs: [usize; L],
    foot: [(f64, f64); L],
    wraps: [f64; L],
    next: usize,
}

#[cfg(target_arch = "x86_64")]
impl<const W: usize, const L: usize> InFlight<W, L> {
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
