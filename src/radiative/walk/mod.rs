//! The flux-tracking walks: every ray of the Radiative engine goes from its start point through
//! the cell grid to its exit (top, bottom, lost side, power threshold), booking what each
//! cell crossing intercepts (DART 5 flux tracking, Gastellu-Etchegorry et al. 2015, Remote
//! Sens. 7, 1667–1701, §3; physics.md §3.5, §3.6, §5, §6.3). Five kernels walk the rays, all
//! with the same physics; [`select`] is the one place that says which one takes a ray (per ray
//! in [`Ctx::trace_any`] and where the turbid emitters queue their rays directly, per queue
//! in [`Ctx::flush`], and for the accumulator's single-precision records), from two settings
//! of the run ([`batched`] and [`batched_f32`], kept in [`Ctx::batch`] and
//! [`Ctx::lane_dirs32`]) and two facts of the ray (hotspot-correlated; dense accumulator).
//!
//! | [`WalkKind`] | kernel | runs when | bits |
//! |---|---|---|---|
//! | `OneRay` | [`Ctx::trace_w`] (`one_ray`) | hotspot-correlated first-order sun rays, or the scene is not [`Ctx::simple`] (facets, several tracked turbid entries in a cell, topography offset) | the reference one-ray walk; the same bits on every instruction set |
//! | `Simple` | [`Ctx::walk_simple`] (`simple`) | a simple scene and one of: the sparse accumulator (grids above the dense limit), `turbid_subfaces` ≠ `Off`, a channel count other than 1, 2, 4 | same operations per crossing as `OneRay`'s turbid path, one 16-byte cell record; same bits on every instruction set |
//! | `Lean` | [`Ctx::walk_lean`] (`simple`) | a simple scene, dense accumulator, `turbid_subfaces: Off`, 1, 2 or 4 channels, and no batched walk (`batch_walk` off, or no AVX2) | bit-identical to `Simple` on the same rays (the same operations in the same order) |
//! | `BatchF64` | `Ctx::walk_batch` (`batch`): 8 lanes (AVX-512) or 4 (AVX2) | as `Lean`, with `batch_walk` on, x86-64 with AVX2 (`kernel_isa`), and not `BatchF32` | per ray the same bits as `Lean`; only the summation order of the rays' contributions changes: products within ~1e-15 relative of `Lean`'s, 8-lane and 4-lane products differ in the last bits; bit-identical on any thread count |
//! | `BatchF32` | `Ctx::walk_wide` (`batch::wide32`): 16 lanes, `f32` geometry | as `BatchF64`, with `batch_f32` on, AVX-512 (`kernel_isa`), a grid that fits `i32` indices | products within ~3e-7 relative of the f64 walks' on 0.1–1 m cells (3.4e-6 on 20 m cells); bit-identical on any thread count |
//!
//! Rays of `BatchF64` / `BatchF32` are queued per chunk ([`Ctx::queue`]) and walked when the
//! queue is long enough and at the end of the chunk ([`Ctx::flush`]). Without AVX2 the
//! batched walk never runs (`Lean` instead). Channel counts 1, 2 and 4 get copies of the
//! kernels with the channel loops unrolled (const generic `W`; `W = 0`: any count). Not a
//! grid walk: with `turbid_exit_grouping`, a turbid store's scattered rays are first followed
//! to their cell's exit inside the cell ([`Ctx::to_exit`]), then the merged exit rays are
//! traced through [`Ctx::trace`] like any other.

pub(in crate::radiative) mod batch;
mod one_ray;
mod simple;

use crate::radiative::engine::*;
use crate::scene::desc::TurbidSubfaces;
use glam::DVec3;

impl Ctx<'_> {
    /// Traces one ray; `pw` holds the channel powers and is consumed.
    pub(in crate::radiative) fn trace(
        &self,
        p: DVec3,
        dir: usize,
        skip_facet: Option<u32>,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        self.trace_any::<false>(p, dir, skip_facet, pw, out);
    }

    /// [`Ctx::trace`] for a first-order sun ray leaving its scattering point `p` along an
    /// upward direction: turbid extinction gets the hotspot correlation of [`hotspot_terms`]
    /// (the ray goes back through the gaps the sun came through).
    pub(in crate::radiative) fn trace_hotspot(
        &self,
        p: DVec3,
        dir: usize,
        skip_facet: Option<u32>,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        self.trace_any::<true>(p, dir, skip_facet, pw, out);
    }

    /// Dispatches the ray to the walk [`select`] picks, in its copy specialised for the channel
    /// count (1, 2 or 4 channels: loops over channels unrolled), with the turbid accumulators
    /// taken out of `out` for the ray's duration (queued rays: at the flush).
    pub(in crate::radiative) fn trace_any<const HS: bool>(
        &self,
        p: DVec3,
        dir: usize,
        skip_facet: Option<u32>,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        let dense = matches!(out.tur.as_deref(), Some(TurAcc::Dense { .. }));
        let kind = select(self, HS, dense);
        if kind.batched() {
            self.queue(p, dir, pw, out);
            return;
        }
        let mut tur = out.tur.take().expect("accumulator");
        match (kind, self.w) {
            (WalkKind::Lean, _) => self.trace_lean(p, dir, pw, &mut tur, out),
            (WalkKind::Simple, 1) => self.trace_simple::<1>(p, dir, pw, &mut tur, out),
            (WalkKind::Simple, 2) => self.trace_simple::<2>(p, dir, pw, &mut tur, out),
            (WalkKind::Simple, 4) => self.trace_simple::<4>(p, dir, pw, &mut tur, out),
            (WalkKind::Simple, _) => self.trace_simple::<0>(p, dir, pw, &mut tur, out),
            (_, 1) => self.trace_w::<1, HS>(p, dir, skip_facet, pw, &mut tur, out),
            (_, 2) => self.trace_w::<2, HS>(p, dir, skip_facet, pw, &mut tur, out),
            (_, 4) => self.trace_w::<4, HS>(p, dir, skip_facet, pw, &mut tur, out),
            _ => self.trace_w::<0, HS>(p, dir, skip_facet, pw, &mut tur, out),
        }
        out.tur = Some(tur);
    }
}

/// The walk kernels (see the module doc's table).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(in crate::radiative) enum WalkKind {
    /// The general one-ray walk [`Ctx::trace_w`].
    OneRay,
    /// The one-ray walk of simple scenes [`Ctx::walk_simple`].
    Simple,
    /// [`Ctx::walk_simple`] specialised for the dense accumulator, `turbid_subfaces: Off` and
    /// 1, 2 or 4 channels: [`Ctx::walk_lean`].
    Lean,
    /// The batched double-precision walk (8 lanes with AVX-512, 4 with AVX2).
    BatchF64,
    /// The batched single-precision-geometry walk on 16 lanes (AVX-512).
    BatchF32,
}

impl WalkKind {
    /// The ray is queued for the batched walk ([`Ctx::queue`]) instead of walked now.
    #[inline(always)]
    pub(in crate::radiative) fn batched(self) -> bool {
        matches!(self, WalkKind::BatchF64 | WalkKind::BatchF32)
    }
}

/// The walk that takes a ray of the run of `ctx` (see the module doc's table): `hotspot`, the
/// ray carries the hotspot correlation of a first-order sun ray; `dense`, the chunk's turbid
/// accumulator is the dense one.
#[inline(always)]
pub(in crate::radiative) fn select(ctx: &Ctx, hotspot: bool, dense: bool) -> WalkKind {
    if hotspot || !ctx.simple {
        WalkKind::OneRay
    } else if !dense || ctx.subfaces != TurbidSubfaces::Off || !matches!(ctx.w, 1 | 2 | 4) {
        WalkKind::Simple
    } else if !ctx.batch {
        WalkKind::Lean
    } else if ctx.lane_dirs32.is_empty() {
        WalkKind::BatchF64
    } else {
        WalkKind::BatchF32
    }
}

/// Per run: whether the `Lean` rays are batched ([`Ctx::batch`]): a [`Ctx::simple`] scene,
/// [`TrackingParams::batch_walk`], `turbid_subfaces: Off`, 1, 2 or 4 channels (`w`), and the
/// batched walk available on dispatch target `arch` (x86-64 with AVX2).
pub(in crate::radiative) fn batched(
    simple: bool,
    params: &TrackingParams,
    w: usize,
    arch: &pulp::Arch,
) -> bool {
    simple
        && params.batch_walk
        && params.turbid_subfaces == TurbidSubfaces::Off
        && matches!(w, 1 | 2 | 4)
        && batch::available(arch)
}

/// Per run, when [`batched`]: whether the batched walk is the single-precision 16-lane one
/// ([`TrackingParams::batch_f32`], an AVX-512 dispatch target, a grid that fits its `i32`
/// indices).
pub(in crate::radiative) fn batched_f32(ctx: &Ctx) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        ctx.inp.params.batch_f32
            && matches!(ctx.arch, pulp::Arch::V4(_))
            && batch::fits32(ctx.inp.spec)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = ctx;
        false
    }
}

/// Σ of a ray's channel powers, W, for the ray-power threshold and the interception weights.
/// Up to 8 channels (every run of one to four bands, with or without sky) in channel order, as
/// the batched walk sums; more channels (shared multi-band runs, hyperspectral scenes) in four
/// interleaved partial sums that the compiler vectorises: a serial chain of 256 additions per
/// crossing was ~60 % of such walks (the sum differs from channel order by rounding only).
#[inline(always)]
pub(in crate::radiative) fn channel_sum(pw: &[f64]) -> f64 {
    if pw.len() <= 8 {
        return pw.iter().sum();
    }
    let mut acc = [0.0f64; 4];
    let chunks = pw.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for k in 0..4 {
            acc[k] += c[k];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for &v in rest {
        s += v;
    }
    s
}
