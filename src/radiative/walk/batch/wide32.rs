//! The batched walk in single-precision geometry on 16 lanes (AVX-512; the default there,
//! [`crate::radiative::engine::TrackingParams::batch_f32`]): the rays of [`Ctx::walk_batch`], each lane's
//! traversal kept in the frame of its current cell (issue #4).
//!
//! Per lane: the entry point in the current cell's frame (m, in [0, size] per axis, `f32`),
//! the distance from it to the next boundary of each axis (`f32`), the cell indices (`i32`).
//! A crossing moves the point to the exit (the stepped axes onto their entry face, exactly),
//! so `f32` keeps the geometry to ~1e-7 of a cell whatever the scene size or ray length (the
//! 1 mm and 20 m cell tests visit the same crossings); a repetitive wrap moves only the
//! indices. Per crossing, lane-wise: segment ℓ = the nearest boundary, optical depth
//! `x = k ℓ` (`k = G u_f`), the intercepted fraction `1 − e^{−x}` (single-precision
//! polynomial, promoted; the transmitted fraction is formed in double so that the two sum to
//! 1: energy closes as in the f64 walk), the half-barycentres (degree-5 `f32` polynomials
//! below x = 1, the f64 table's pieces rounded to `f32` above), the interception points in the
//! cell's frame weighted in `f32` and added in `f64` to a record of their own (`pts_loc` of
//! the dense accumulator, moved to scene coordinates at the merge: Σ wt (c + p) = c Σ wt +
//! Σ wt p, c the cell's corner), the channel powers (`f64`). The bookings are lane by lane in
//! lane order, so products stay bit-identical on any thread count.
//!
//! Same physics as the f64 walks (DART 5 flux tracking, Gastellu-Etchegorry et al. 2015,
//! Remote Sens. 7, 1667–1701, §3); the products differ from theirs by ≤ 2.5e-7 relative on
//! 0.1–1 m cells and 3.4e-6 on 20 m cells (the f32 exponential), the DISORT errors are
//! unchanged to the printed digits (tests `f32_walk_*` in `tests/batch_walk.rs`; README of
//! 4df2100, Kernel).

use super::{ChunkOut, Ctx, Queued};
use crate::radiative::dda::{Dda, Exit, exit_of};
use crate::radiative::engine::{DenseView, TurAcc, add, record};
use crate::radiative::fastmath::{HB_ALLOC, HB_POLY_DEG, HalfBarycentres};
use crate::resources::grid::GridSpec;
use crate::scene::desc::BoundaryMode;
use core::arch::x86_64::{__m256, __m256d, __m512, __m512d, __m512i};
use glam::DVec3;
use pulp::{cast, f64x8, x86::V4};

/// Lanes of the walk (one `f32` per lane in a 512-bit register).
const L: usize = 16;

/// What a lane takes from its direction at a ray start (formed once per direction).
#[derive(Debug, Clone, Copy, Default)]
pub(in crate::radiative) struct LaneDir32 {
    /// Unit direction.
    dir: [f32; 3],
    /// Cell size over |d|: the distance between two boundaries of the axis (+∞ for d = 0).
    delta: [f32; 3],
    /// Coordinate of the point in the next cell's frame after a step along the axis: 0 for a
    /// step of +1, the cell size for −1.
    face: [f32; 3],
    /// Step −1, 0 or 1, and its linear-index increment.
    step: [i32; 3],
    dlin: [i32; 3],
    /// Per axis x, y, z (index 3: padding, for the start's vector): `1/d` (±∞ for a zero
    /// component), and all ones where the step is +1, −1, or not 0.
    inv4: [f64; 4],
    up4: [u64; 4],
    down4: [u64; 4],
    moves4: [u64; 4],
}

/// The grid's origin, cell sizes, `n + 1e-9` and `n − 1` per axis x, y, z (index 3: padding,
/// a unit cell at 0), for [`Wide::start`].
#[derive(Debug, Clone, Copy)]
struct Grid4 {
    lo: [f64; 4],
    size: [f64; 4],
    n_hi: [f64; 4],
    n_m1: [f64; 4],
    n: [i32; 3],
}

impl Grid4 {
    fn new(spec: &GridSpec) -> Self {
        let n = spec.n.map(|v| v as f64);
        Grid4 {
            lo: [spec.origin.x, spec.origin.y, spec.origin.z, 0.0],
            size: [spec.cell.x, spec.cell.y, spec.cell.z, 1.0],
            n_hi: [n[0] + 1e-9, n[1] + 1e-9, n[2] + 1e-9, 1.0 + 1e-9],
            n_m1: [n[0] - 1.0, n[1] - 1.0, n[2] - 1.0, 0.0],
            n: spec.n.map(|v| v as i32),
        }
    }
}

impl LaneDir32 {
    pub(in crate::radiative) fn new(spec: &GridSpec, d: DVec3) -> Self {
        let n = spec.n.map(|v| v as i32);
        let stride = [1, n[0], n[0] * n[1]];
        let mut c = LaneDir32::default();
        for a in 0..3 {
            let size = spec.cell[a];
            let step = (d[a] > 0.0) as i32 - (d[a] < 0.0) as i32;
            c.dir[a] = d[a] as f32;
            c.inv4[a] = 1.0 / d[a];
            c.delta[a] = if step == 0 {
                f32::INFINITY
            } else {
                (size * c.inv4[a].abs()) as f32
            };
            c.face[a] = if step < 0 { size as f32 } else { 0.0 };
            c.step[a] = step;
            c.dlin[a] = step * stride[a];
            let all = |b: bool| if b { u64::MAX } else { 0 };
            (c.up4[a], c.down4[a], c.moves4[a]) = (all(step > 0), all(step < 0), all(step != 0));
        }
        c.inv4[3] = 1.0;
        c
    }
}

/// Whether a grid fits the walk's `i32` indices (linear indices and one period beyond).
pub(in crate::radiative) fn fits(spec: &GridSpec) -> bool {
    let n: u64 = spec.n.iter().map(|&v| v as u64 + 2).product();
    n < (i32::MAX as u64) / 4
}

/// Per-lane state (structure of arrays, lane l at index l).
struct Wide<const W: usize> {
    org: [[f32; L]; 3],
    tmax: [[f32; L]; 3],
    dir: [[f32; L]; 3],
    delta: [[f32; L]; 3],
    face: [[f32; L]; 3],
    cell: [[i32; L]; 3],
    step: [[i32; L]; 3],
    dlin: [[i32; L]; 3],
    lin: [i32; L],
    act: u32,
    pw: [[f64; L]; W],
    psum: [f64; L],
    min_ray: [f64; L],
    g: [f32; L],
    g_row: [usize; L],
    slot: [usize; L],
    dirs: [usize; L],
    foot: [(f64, f64); L],
    wraps: [u32; L],
    next: usize,
}

impl<const W: usize> Wide<W> {
    fn new() -> Self {
        let (f3, i3) = ([[0.0; L]; 3], [[0; L]; 3]);
        Wide {
            org: f3,
            tmax: f3,
            dir: f3,
            delta: f3,
            face: f3,
            cell: i3,
            step: i3,
            dlin: i3,
            lin: [0; L],
            act: 0,
            pw: [[0.0; L]; W],
            psum: [0.0; L],
            min_ray: [0.0; L],
            g: [0.0; L],
            g_row: [0; L],
            slot: [0; L],
            dirs: [0; L],
            foot: [(0.0, 0.0); L],
            wraps: [0; L],
            next: 0,
        }
    }

    /// Lane l's traversal from scene point `p` along the direction of `dc` (the cell as
    /// [`Dda::new`] finds it: on a boundary, the cell the ray enters); false if `p` is outside
    /// the grid box.
    /// The three axes side by side in one vector (per axis the operations of the one-axis
    /// form [`Wide::set_axis`]: `rel = (p − lo)/size`, `⌊rel⌋`, the cell below on a boundary
    /// crossed downward, clamped; the point in the cell's frame, clamped to it; the distance
    /// to the exit boundary).
    #[inline(always)]
    fn start(&mut self, v: V4, l: usize, g: &Grid4, p: DVec3, dc: &LaneDir32) -> bool {
        let a = v.avx;
        let sp = |c: f64| a._mm256_set1_pd(c);
        let (zero, lo, size): (__m256d, __m256d, __m256d) = (sp(0.0), cast(g.lo), cast(g.size));
        let pv: __m256d = cast([p.x, p.y, p.z, 0.0]);
        let rel = a._mm256_div_pd(a._mm256_sub_pd(pv, lo), size);
        let ok = a._mm256_and_pd(
            a._mm256_cmp_pd::<0x1D>(rel, sp(-1e-9)),
            a._mm256_cmp_pd::<0x12>(rel, cast(g.n_hi)),
        );
        if a._mm256_movemask_pd(ok) & 7 != 7 {
            return false;
        }
        let fl = a._mm256_floor_pd(rel);
        let below = a._mm256_and_pd(a._mm256_cmp_pd::<0x00>(rel, fl), cast(dc.down4));
        let idx = a._mm256_blendv_pd(fl, a._mm256_sub_pd(fl, sp(1.0)), below);
        let idx = a._mm256_min_pd(a._mm256_max_pd(idx, zero), cast(g.n_m1));
        let corner = a._mm256_add_pd(lo, a._mm256_mul_pd(idx, size));
        let local = a._mm256_min_pd(a._mm256_max_pd(a._mm256_sub_pd(pv, corner), zero), size);
        let bb = a._mm256_and_pd(size, cast(dc.up4));
        let tm = a._mm256_mul_pd(a._mm256_sub_pd(bb, local), cast(dc.inv4));
        let tm = a._mm256_blendv_pd(sp(f64::INFINITY), tm, cast(dc.moves4));
        let tm = a._mm256_max_pd(tm, zero);
        let local: [f32; 4] = cast(a._mm256_cvtpd_ps(local));
        let tm: [f32; 4] = cast(a._mm256_cvtpd_ps(tm));
        let idx: [i32; 4] = cast(a._mm256_cvttpd_epi32(idx));
        for ax in 0..3 {
            self.cell[ax][l] = idx[ax];
            self.org[ax][l] = local[ax];
            self.tmax[ax][l] = tm[ax];
            self.dir[ax][l] = dc.dir[ax];
            self.delta[ax][l] = dc.delta[ax];
            self.face[ax][l] = dc.face[ax];
            self.step[ax][l] = dc.step[ax];
            self.dlin[ax][l] = dc.dlin[ax];
        }
        let n = g.n;
        self.lin[l] = idx[0] + n[0] * (idx[1] + n[1] * idx[2]);
        true
    }

    /// Axis `a` of lane l: cell index `i`, point `local` (m) in the cell's frame.
    #[inline(always)]
    fn set_axis(&mut self, l: usize, a: usize, i: i32, local: f64, dc: &LaneDir32, size: f64) {
        let tm = match dc.step[a] {
            1 => (size - local) * dc.inv4[a],
            -1 => -local * dc.inv4[a],
            _ => f64::INFINITY,
        };
        self.cell[a][l] = i;
        self.org[a][l] = local as f32;
        self.tmax[a][l] = tm.max(0.0) as f32;
        self.dir[a][l] = dc.dir[a];
        self.delta[a][l] = dc.delta[a];
        self.face[a][l] = dc.face[a];
        self.step[a][l] = dc.step[a];
        self.dlin[a][l] = dc.dlin[a];
    }

    /// Lane l's point in scene coordinates (m): the cell's corner plus the point in its frame.
    #[inline]
    fn point(&self, l: usize, spec: &GridSpec) -> DVec3 {
        DVec3::from_array(std::array::from_fn(|a| {
            spec.origin[a] + self.cell[a][l] as f64 * spec.cell[a] + self.org[a][l] as f64
        }))
    }

    /// Lane l after an empty-space jump of the one-ray traversal `d` (same ray): its cell,
    /// linear index, point and boundary distances.
    fn set_from(&mut self, l: usize, spec: &GridSpec, d: &Dda, dc: &LaneDir32) {
        let p = d.point(d.t);
        let tm = d.t_max();
        for a in 0..3 {
            let size = spec.cell[a];
            let i = d.cell[a] as i32;
            let local = (p[a] - (spec.origin[a] + i as f64 * size)).clamp(0.0, size);
            self.set_axis(l, a, i, local, dc, size);
            if dc.step[a] != 0 {
                self.tmax[a][l] = (tm[a] - d.t).max(0.0) as f32;
            }
        }
        self.lin[l] = d.index() as i32;
    }

    /// [`Dda::exit_kind`] of lane l.
    #[inline]
    fn exit_kind(&self, l: usize, n: [i32; 3]) -> Exit {
        let c = |v: &[[i32; L]; 3]| std::array::from_fn(|a| v[a][l] as i64);
        exit_of(c(&self.cell), n.map(|v| v as i64), c(&self.step))
    }

    /// Repetitive wrap of lane l's side axes outside the grid (the indices move by one period;
    /// the point in the cell's frame does not); the number of axes wrapped.
    #[inline]
    fn wrap_sides(&mut self, l: usize, n: [i32; 3]) -> u32 {
        let mut k = 0;
        for (a, stride) in [(0, 1), (1, n[0])] {
            let c = self.cell[a][l];
            if c < 0 || c >= n[a] {
                let back = if c < 0 { n[a] } else { -n[a] };
                self.cell[a][l] += back;
                self.lin[l] += back * stride;
                k += 1;
            }
        }
        k
    }

    /// The step of the lanes in `go` in the cell frame: the point moves to the exit at distance
    /// `ell`; the stepped axes enter the next cell on their entry face (exactly), their
    /// distance becomes a whole cell's; the other axes' distances shrink by `ell`. Returns, as
    /// bits, the stepped lanes whose new cell index is outside the grid (`nv`: the grid's
    /// cells per axis) on a stepped axis.
    #[inline(always)]
    fn step(&mut self, v: V4, go: u32, ell: __m512, nv: &[__m512i; 3]) -> u16 {
        let f = v.avx512f;
        let ld = |a: &[f32; L]| -> __m512 { cast(*a) };
        let ldi = |a: &[i32; L]| -> __m512i { cast(*a) };
        let gm = go as u16;
        let mut outside = 0u16;
        let mut lin = ldi(&self.lin);
        for a in 0..3 {
            let tm = ld(&self.tmax[a]);
            let m = gm & f._mm512_cmp_ps_mask::<0x12>(tm, ell);
            let o0 = ld(&self.org[a]);
            let o = f._mm512_mask_fmadd_ps(ld(&self.dir[a]), gm, ell, o0);
            let o = f._mm512_mask_blend_ps(gm, o0, o);
            let o = f._mm512_mask_blend_ps(m, o, ld(&self.face[a]));
            self.org[a] = cast(o);
            let tn = f._mm512_mask_sub_ps(tm, gm, tm, ell);
            self.tmax[a] = cast(f._mm512_mask_blend_ps(m, tn, ld(&self.delta[a])));
            let c0 = ldi(&self.cell[a]);
            let c = f._mm512_mask_add_epi32(c0, m, c0, ldi(&self.step[a]));
            self.cell[a] = cast(c);
            lin = f._mm512_mask_add_epi32(lin, m, lin, ldi(&self.dlin[a]));
            // Outside the grid: the index is −1 or n (one unsigned comparison with n).
            outside |= m & f._mm512_cmpge_epu32_mask(c, nv[a]);
        }
        self.lin = cast(lin);
        outside
    }

    /// Side exits of a repetitive scene among the lanes `out_b` that left the grid: the
    /// indices move by one period (`n`: cells per axis, `nv` as vectors) and the lanes' wrap
    /// counts grow. Returns, as bits, the wrapped lanes past `max_crossings` wraps, and the
    /// lanes of `out_b` that left through the top or bottom.
    #[inline(always)]
    fn wrap_side_exits(
        &mut self,
        v: V4,
        out_b: u32,
        nv: &[__m512i; 3],
        n: [i32; 3],
        max_crossings: u32,
    ) -> (u32, u32) {
        let f = v.avx512f;
        let ldi = |a: &[i32; L]| -> __m512i { cast(*a) };
        let zout = f._mm512_cmpge_epu32_mask(ldi(&self.cell[2]), nv[2]) as u32;
        let side = out_b & !zout;
        if side == 0 {
            return (0, out_b);
        }
        let sm = side as u16;
        let mut lin = ldi(&self.lin);
        let mut wr: __m512i = cast(self.wraps);
        for (a, stride) in [(0usize, 1i32), (1, n[0])] {
            let c = ldi(&self.cell[a]);
            let w = sm & f._mm512_cmpge_epu32_mask(c, nv[a]);
            let back = f._mm512_mullo_epi32(ldi(&self.step[a]), f._mm512_set1_epi32(-n[a]));
            self.cell[a] = cast(f._mm512_mask_add_epi32(c, w, c, back));
            let bl = f._mm512_mullo_epi32(back, f._mm512_set1_epi32(stride));
            lin = f._mm512_mask_add_epi32(lin, w, lin, bl);
            wr = f._mm512_mask_add_epi32(wr, w, wr, f._mm512_set1_epi32(1));
        }
        self.lin = cast(lin);
        self.wraps = cast(wr);
        let over =
            side & f._mm512_cmpgt_epu32_mask(wr, f._mm512_set1_epi32(max_crossings as i32)) as u32;
        (over, out_b & !side)
    }

    /// Takes the next queued ray that starts inside the grid into lane l (rays that do not are
    /// booked as lost, as in the f64 walks); parks the lane when the queue is done.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn refill(
        &mut self,
        v: V4,
        g: &Grid4,
        ctx: &Ctx,
        dirs: &[LaneDir32],
        l: usize,
        q: &[Queued],
        out: &mut ChunkOut,
    ) {
        loop {
            let Some(r) = q.get(self.next) else {
                self.act &= !(1 << l);
                self.lin[l] = 0;
                return;
            };
            self.next += 1;
            out.rays += 1;
            let dir = r.dir as usize;
            if !self.start(v, l, g, r.p, &dirs[dir]) {
                add(&mut out.lost, &r.pw[..W]);
                continue;
            }
            let ld = &ctx.lane_dirs[dir];
            self.act |= 1 << l;
            for c in 0..W {
                self.pw[c][l] = r.pw[c];
            }
            self.psum[l] = r.pw[..W].iter().sum();
            self.min_ray[l] = ld.min_ray * r.ray_scale;
            self.g_row[l] = dir * ctx.n_tm;
            self.g[l] = ld.g as f32;
            self.slot[l] = ld.slot;
            self.dirs[l] = dir;
            self.foot[l] = r.foot;
            self.wraps[l] = 0;
            return;
        }
    }
}

/// `(1 − e^{−x}, e^{−x})` of 16 lanes, promoted to double (lanes 0–7, 8–15), and the first
/// in single precision. Single-precision: the series `x(1 − x/2 + x²/6 − x³/24)` below 1/32
/// (relative error < 2e-8 there), else `2^{−x log₂e}` by a degree-6 polynomial of the
/// fraction and `vscalefps` (relative error ~2e-7; Cody & Waite-style reduction, J.-M.
/// Muller, *Elementary Functions*, 3rd ed., §11). The promoted pair sums to 1 in double: the
/// series value is the intercepted fraction and the transmitted one is 1 − it; above, the
/// transmitted fraction is the exponential and the intercepted one 1 − it.
#[inline(always)]
fn atten16(v: V4, x: __m512) -> ([__m512d; 2], [__m512d; 2], __m512) {
    let f = v.avx512f;
    let sp = |c: f32| f._mm512_set1_ps(c);
    let mut s = f._mm512_fnmadd_ps(x, sp(1.0 / 24.0), sp(1.0 / 6.0));
    s = f._mm512_fnmadd_ps(x, s, sp(0.5));
    s = f._mm512_fnmadd_ps(x, s, sp(1.0));
    s = f._mm512_mul_ps(x, s);
    let xe = f._mm512_min_ps(x, sp(150.0));
    let y = f._mm512_mul_ps(xe, sp(-std::f32::consts::LOG2_E));
    let n = f._mm512_roundscale_ps::<0x08>(y);
    let r = f._mm512_sub_ps(y, n);
    let mut p = f._mm512_fmadd_ps(r, sp(1.540_353e-4), sp(1.339_887e-3));
    p = f._mm512_fmadd_ps(r, p, sp(9.618_437e-3));
    p = f._mm512_fmadd_ps(r, p, sp(5.550_332e-2));
    p = f._mm512_fmadd_ps(r, p, sp(2.402_264e-1));
    p = f._mm512_fmadd_ps(r, p, sp(6.931_472e-1));
    p = f._mm512_fmadd_ps(r, p, sp(1.0));
    let e = f._mm512_scalef_ps(p, n);
    let small = f._mm512_cmp_ps_mask::<0x11>(x, sp(1.0 / 32.0));
    let val = f._mm512_mask_blend_ps(small, e, s);
    let one = f._mm512_set1_pd(1.0);
    let lo = f._mm512_cvtps_pd(f._mm512_castps512_ps256(val));
    let hi = f._mm512_cvtps_pd(v.avx512dq._mm512_extractf32x8_ps::<1>(val));
    let (sl, sh) = (small as u8, (small >> 8) as u8);
    let (clo, chi) = (f._mm512_sub_pd(one, lo), f._mm512_sub_pd(one, hi));
    (
        [
            f._mm512_mask_blend_pd(sl, clo, lo),
            f._mm512_mask_blend_pd(sh, chi, hi),
        ],
        [
            f._mm512_mask_blend_pd(sl, lo, clo),
            f._mm512_mask_blend_pd(sh, hi, chi),
        ],
        f._mm512_mask_blend_ps(small, f._mm512_sub_ps(sp(1.0), e), s),
    )
}

/// 8 × 8 transposes of `f32` in both 256-bit halves of eight registers at once: element j of
/// half h of output i is element i of half h of input j.
#[inline(always)]
fn transpose8x2(v: V4, r: [__m512; 8]) -> [__m512; 8] {
    let f = v.avx512f;
    let t: [__m512; 8] = std::array::from_fn(|i| {
        let (a, b) = (r[2 * (i / 2)], r[2 * (i / 2) + 1]);
        if i % 2 == 0 {
            f._mm512_unpacklo_ps(a, b)
        } else {
            f._mm512_unpackhi_ps(a, b)
        }
    });
    let s = [
        f._mm512_shuffle_ps::<0x44>(t[0], t[2]),
        f._mm512_shuffle_ps::<0xEE>(t[0], t[2]),
        f._mm512_shuffle_ps::<0x44>(t[1], t[3]),
        f._mm512_shuffle_ps::<0xEE>(t[1], t[3]),
        f._mm512_shuffle_ps::<0x44>(t[4], t[6]),
        f._mm512_shuffle_ps::<0xEE>(t[4], t[6]),
        f._mm512_shuffle_ps::<0x44>(t[5], t[7]),
        f._mm512_shuffle_ps::<0xEE>(t[5], t[7]),
    ];
    // Per 256-bit half: (low 128 bits of a, low of b) and (high of a, high of b).
    let lo: __m512i = cast([0i32, 1, 2, 3, 16, 17, 18, 19, 8, 9, 10, 11, 24, 25, 26, 27]);
    let hi: __m512i = cast([
        4i32, 5, 6, 7, 20, 21, 22, 23, 12, 13, 14, 15, 28, 29, 30, 31,
    ]);
    let p = |a, i, b| f._mm512_permutex2var_ps(a, i, b);
    [
        p(s[0], lo, s[4]),
        p(s[1], lo, s[5]),
        p(s[2], lo, s[6]),
        p(s[3], lo, s[7]),
        p(s[0], hi, s[4]),
        p(s[1], hi, s[5]),
        p(s[2], hi, s[6]),
        p(s[3], hi, s[7]),
    ]
}

/// Half-barycentres of 16 segments (distances from the entry, m): the pieces of
/// [`HalfBarycentres`] in single precision (rows of lanes l and l + 8 loaded into one register,
/// one two-half transpose), the series below 2⁻¹⁴ and the dense limit from 64 as in
/// [`HalfBarycentres::eval`].
#[inline(always)]
fn hb16(
    v: V4,
    rows: &[[f32; 8]; HB_ALLOC],
    first: u32,
    range: (f32, f32),
    x: __m512,
    ell: __m512,
) -> (__m512, __m512) {
    let f = v.avx512f;
    let sp = |c: f32| f._mm512_set1_ps(c);
    // x < 1 (a cell's optical depth, the common case): the degree-5 polynomials
    // (`HalfBarycentres::poly32`, the operations of `eval_poly32`).
    let c = HalfBarycentres::poly32();
    let (mut pa, mut pb) = (sp(c[2 * HB_POLY_DEG]), sp(c[2 * HB_POLY_DEG + 1]));
    for i in (0..HB_POLY_DEG).rev() {
        pa = f._mm512_fmadd_ps(pa, x, sp(c[2 * i]));
        pb = f._mm512_fmadd_ps(pb, x, sp(c[2 * i + 1]));
    }
    let (pa, pb) = (f._mm512_mul_ps(ell, pa), f._mm512_mul_ps(ell, pb));
    let poly = f._mm512_cmp_ps_mask::<0x11>(x, sp(1.0));
    if poly == u16::MAX {
        return (pa, pb);
    }
    let (a, b) = hb16_table(v, rows, first, range, x, ell);
    (
        f._mm512_mask_blend_ps(poly, a, pa),
        f._mm512_mask_blend_ps(poly, b, pb),
    )
}

/// [`hb16`] for x ≥ 1: the table's pieces.
#[inline(always)]
fn hb16_table(
    v: V4,
    rows: &[[f32; 8]; HB_ALLOC],
    first: u32,
    range: (f32, f32),
    x: __m512,
    ell: __m512,
) -> (__m512, __m512) {
    let f = v.avx512f;
    let sp = |c: f32| f._mm512_set1_ps(c);
    let bits = f._mm512_castps_si512(x);
    let bin = f._mm512_and_si512(
        f._mm512_sub_epi32(
            f._mm512_srli_epi32::<18>(bits),
            f._mm512_set1_epi32(first as i32),
        ),
        f._mm512_set1_epi32(HB_ALLOC as i32 - 1),
    );
    let start =
        f._mm512_castsi512_ps(f._mm512_and_si512(bits, f._mm512_set1_epi32(!((1 << 18) - 1))));
    let t = f._mm512_sub_ps(x, start);
    let ba: [u32; L] = cast(bin);
    // Rows of lanes l and l + 8 in one register (two 32-byte loads: a 64-byte load of two
    // 32-byte stores would not be forwarded).
    let mut pair = [f._mm512_setzero_ps(); 8];
    for (l, p) in pair.iter_mut().enumerate() {
        let a: __m256 = cast(rows[ba[l] as usize]);
        let b: __m256 = cast(rows[ba[l + 8] as usize]);
        *p = v
            .avx512dq
            ._mm512_insertf32x8::<1>(f._mm512_castps256_ps512(a), b);
    }
    let c = transpose8x2(v, pair);
    let h = |c0, c1, c2, c3| {
        let p = f._mm512_fmadd_ps(t, c3, c2);
        let p = f._mm512_fmadd_ps(t, p, c1);
        f._mm512_mul_ps(ell, f._mm512_fmadd_ps(t, p, c0))
    };
    let a = h(c[0], c[2], c[4], c[6]);
    let b = h(c[1], c[3], c[5], c[7]);
    let big = f._mm512_cmp_ps_mask::<0x1D>(x, sp(range.1));
    let small = f._mm512_cmp_ps_mask::<0x11>(x, sp(range.0));
    if big | small == 0 {
        return (a, b);
    }
    let l2 = std::f32::consts::LN_2;
    let u = f._mm512_div_ps(ell, x);
    let a = f._mm512_mask_blend_ps(big, a, f._mm512_mul_ps(sp(1.0 - l2), u));
    let b = f._mm512_mask_blend_ps(big, b, f._mm512_mul_ps(sp(1.0 + l2), u));
    let x12 = f._mm512_mul_ps(x, sp(1.0 / 12.0));
    let sa = f._mm512_mul_ps(ell, f._mm512_sub_ps(sp(0.25), x12));
    let sb = f._mm512_mul_ps(ell, f._mm512_sub_ps(sp(0.75), x12));
    (
        f._mm512_mask_blend_ps(small, a, sa),
        f._mm512_mask_blend_ps(small, b, sb),
    )
}

impl Ctx<'_> {
    /// Walks the queued rays on 16 lanes (this module's doc); `tur` must be the dense
    /// accumulator with the local points records (the walk runs only where
    /// [`super::lane_dirs32`] is not empty: AVX-512, so the queue is otherwise walked by
    /// [`Ctx::walk_batch`]).
    pub(in crate::radiative) fn walk_wide<const W: usize>(
        &self,
        queue: &[Queued],
        tur: &mut TurAcc,
        out: &mut ChunkOut,
    ) {
        let pulp::Arch::V4(v4) = self.arch else {
            return self.walk_batch::<W>(queue, tur, out);
        };
        let (mut view, loc) = tur
            .view_local()
            .expect("rays are queued with a dense accumulator only");
        view.w = W;
        /// The walk's arguments, run with AVX-512 enabled.
        struct Run<'c, 'v, 'o, 'x, const W: usize> {
            ctx: &'c Ctx<'x>,
            queue: &'o [Queued],
            view: &'o mut DenseView<'v>,
            loc: &'o mut [f64],
            out: &'o mut ChunkOut,
            v4: V4,
        }
        impl<const W: usize> pulp::WithSimd for Run<'_, '_, '_, '_, W> {
            type Output = ();
            #[inline(always)]
            fn with_simd<T: pulp::Simd>(self, _simd: T) {
                let r = self;
                if r.ctx.n_tm == 1 {
                    r.ctx
                        .walk_wide32::<W, true>(r.v4, r.queue, r.view, r.loc, r.out)
                } else {
                    r.ctx
                        .walk_wide32::<W, false>(r.v4, r.queue, r.view, r.loc, r.out)
                }
            }
        }
        pulp::Simd::vectorize(
            v4,
            Run::<W> {
                ctx: self,
                queue,
                view: &mut view,
                loc,
                out,
                v4,
            },
        )
    }

    /// The walk of [`super`]'s module doc on 16 lanes in single-precision geometry (this
    /// module's doc); `ONE_TM`: the scene has one tracked turbid material.
    ///
    /// It stays longer than the project's ~150 lines because the other splits slow the default
    /// kernel (median user time of interleaved pairs, one thread, `turbid-layer --size 6
    /// --cell-size 0.2`, where rays end every ~19 crossings): the end-of-ray events out of line
    /// (`#[inline(never)]`, entered with AVX-512) +1.8 %, the cell-record fetch as an
    /// `#[inline(always)]` helper +3 %, both with the other helpers +3.7 %; the step and side
    /// wraps ([`Wide::step`], [`Wide::wrap_side_exits`]) cost nothing.
    #[inline(always)]
    pub(in crate::radiative) fn walk_wide32<const W: usize, const ONE_TM: bool>(
        &self,
        v: V4,
        queue: &[Queued],
        view: &mut DenseView,
        loc: &mut [f64],
        out: &mut ChunkOut,
    ) {
        let f = v.avx512f;
        let spec = self.inp.spec;
        let n = spec.n.map(|v| v as i32);
        let ncell = (spec.n[0] * spec.n[1] * spec.n[2]) as u32;
        let dirs = &self.lane_dirs32[..];
        let g_dir = &self.g_dir[..];
        let (hb_rows, hb_first, hb_range) = HalfBarycentres::rows32();
        let isolated = spec.boundary == BoundaryMode::Isolated;
        let max_crossings = self.inp.params.max_crossings;
        let scells = &self.scells[..];
        let packed = &self.scells32[..];
        let ns = view.ns;
        let tur: &mut [[f64; W]] = view.tur.as_chunks_mut::<W>().0;
        let pts_loc: &mut [[[f64; 4]; 2]] = loc.as_chunks_mut::<4>().0.as_chunks_mut::<2>().0;
        let rec = &mut *view.rec;
        let touched = &mut *view.touched;
        let mut ln = Wide::<W>::new();
        let grid4 = Grid4::new(spec);
        let nv: [__m512i; 3] = std::array::from_fn(|a| f._mm512_set1_epi32(n[a]));
        let mut n_cross = 0u64;
        let mut n_skip = 0u64;
        let foot_saved = out.foot;
        for l in 0..L {
            ln.refill(v, &grid4, self, dirs, l, queue, out);
        }
        let sp = |c: f32| f._mm512_set1_ps(c);
        let ld = |a: &[f32; L]| -> __m512 { cast(*a) };
        let zero = sp(0.0);
        while ln.act != 0 {
            let (dens, idx, tms, far) = if ONE_TM {
                // One 8-byte packed record per lane (density bits, entry or skip distance),
                // split lane-wise into the two halves.
                let mut rec = [0u64; L];
                for l in 0..L {
                    // Lanes are inside the grid here (parked lanes: cell 0).
                    rec[l] = packed[(ln.lin[l] as u32).min(ncell - 1) as usize];
                }
                let r: [__m512i; 2] = cast(rec);
                let even: __m512i =
                    cast([0u32, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30]);
                let odd: __m512i =
                    cast([1u32, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31]);
                let dens = f._mm512_castsi512_ps(f._mm512_permutex2var_epi32(r[0], even, r[1]));
                let hi = f._mm512_permutex2var_epi32(r[0], odd, r[1]);
                let far = f._mm512_cmpgt_epu32_mask(hi, f._mm512_set1_epi32(1)) as u32;
                let hi: [u32; L] = cast(hi);
                (dens, hi, hi, far)
            } else {
                let mut dens = [0.0f32; L];
                let mut idx = [0u32; L];
                let mut tms = [0u32; L];
                let mut far = 0u32;
                for l in 0..L {
                    let sc = scells[(ln.lin[l] as u32).min(ncell - 1) as usize];
                    dens[l] = sc.density as f32;
                    idx[l] = sc.idx;
                    tms[l] = sc.tm;
                    far |= ((sc.tm > 1) as u32) << l;
                }
                (ld(&dens), idx, tms, far)
            };
            let occ = f._mm512_cmp_ps_mask::<0x1E>(dens, zero) as u32;
            let skip = !occ & far & ln.act;
            let g = if ONE_TM {
                ld(&ln.g)
            } else {
                ld(&std::array::from_fn(|l| {
                    let tm = if occ >> l & 1 != 0 {
                        tms[l] as usize
                    } else {
                        0
                    };
                    g_dir.get(ln.g_row[l] + tm).copied().unwrap_or(0.0) as f32
                }))
            };
            let k = f._mm512_mul_ps(g, dens);
            let ell = f._mm512_min_ps(
                ld(&ln.tmax[2]),
                f._mm512_min_ps(ld(&ln.tmax[1]), ld(&ln.tmax[0])),
            );
            let hit = ln.act
                & occ
                & f._mm512_cmp_ps_mask::<0x1E>(ell, zero) as u32
                & f._mm512_cmp_ps_mask::<0x1E>(k, zero) as u32;
            let x = f._mm512_maskz_mul_ps(hit as u16, k, ell);
            let (frac, tr, frac32) = atten16(v, x);
            let (s1, s2) = hb16(v, hb_rows, hb_first, hb_range, x, ell);
            let mut gain = [[0.0f64; L]; W];
            let mut wt = [f._mm512_setzero_pd(); 2];
            let psum: [f64x8; 2] = cast(ln.psum);
            for h in 0..2 {
                wt[h] = f._mm512_mul_pd(cast(psum[h]), frac[h]);
                for c in 0..W {
                    let pwc: [[f64; 8]; 2] = cast(ln.pw[c]);
                    let pwc: __m512d = cast(pwc[h]);
                    let gh: [f64; 8] = cast(f._mm512_mul_pd(pwc, frac[h]));
                    gain[c][8 * h..8 * h + 8].copy_from_slice(&gh);
                    // Lanes without a hit have x = 0: tr = 1 − 0 = 1 exactly.
                    let nh: [f64; 8] = cast(f._mm512_mul_pd(pwc, tr[h]));
                    ln.pw[c][8 * h..8 * h + 8].copy_from_slice(&nh);
                }
            }
            // Interception points in the cell frame (f32), then in scene coordinates and
            // weighted in double: one row per lane [p1 · wt, p2 · wt, wt].
            let p1: [__m512; 3] =
                std::array::from_fn(|a| f._mm512_fmadd_ps(ld(&ln.dir[a]), s1, ld(&ln.org[a])));
            let p2: [__m512; 3] =
                std::array::from_fn(|a| f._mm512_fmadd_ps(ld(&ln.dir[a]), s2, ld(&ln.org[a])));
            // Interception points weighted in the cell frame, one row per lane
            // [p₁ wt, p₂ wt, wt, 0] (f32; promoted at the add into the local records).
            let w32 = f._mm512_mul_ps(
                cast([
                    f._mm512_cvtpd_ps(cast(psum[0])),
                    f._mm512_cvtpd_ps(cast(psum[1])),
                ]),
                frac32,
            );
            let rv = transpose8x2(
                v,
                [
                    f._mm512_mul_ps(p1[0], w32),
                    f._mm512_mul_ps(p1[1], w32),
                    f._mm512_mul_ps(p1[2], w32),
                    f._mm512_mul_ps(p2[0], w32),
                    f._mm512_mul_ps(p2[1], w32),
                    f._mm512_mul_ps(p2[2], w32),
                    w32,
                    zero,
                ],
            );
            let rows: [[[f32; 4]; 4]; 8] = cast(rv);
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
                // The lane's row promoted by halves and added to the record as two 32-byte
                // read-modify-writes (one 64-byte add would read a record just written by two
                // 32-byte stores: not forwarded on Zen 4).
                // (Lane l's row is half l / 8 of register l % 8, read in place.)
                let half = &rows[l % 8][2 * (l / 8)..2 * (l / 8) + 2];
                let q = &mut pts_loc[e];
                for (qh, r) in q.iter_mut().zip(half) {
                    let add = v
                        .avx
                        ._mm256_add_pd(cast(*qh), v.avx._mm256_cvtps_pd(cast(*r)));
                    *qh = cast(add);
                }
            }
            // The channel sum in channel order.
            let mut dead = 0u32;
            for h in 0..2 {
                let pwh = |c: usize| -> __m512d {
                    let a: [[f64; 8]; 2] = cast(ln.pw[c]);
                    cast(a[h])
                };
                let mut ps = pwh(0);
                for c in 1..W {
                    ps = f._mm512_add_pd(ps, pwh(c));
                }
                let ps8: [f64; 8] = cast(ps);
                ln.psum[8 * h..8 * h + 8].copy_from_slice(&ps8);
                let mr: [[f64; 8]; 2] = cast(ln.min_ray);
                dead |= (f._mm512_cmp_pd_mask::<0x11>(ps, cast(mr[h])) as u32) << (8 * h);
            }
            let dead = dead & hit;
            let go = ln.act & !skip & !dead;
            let mut out_b = go & ln.step(v, go, ell, &nv) as u32;
            n_cross += ln.act.count_ones() as u64;
            let mut over = 0u32;
            if out_b != 0 && !isolated {
                (over, out_b) = ln.wrap_side_exits(v, out_b, &nv, n, max_crossings);
            }
            let ev = skip | dead | over | out_b;
            if ev == 0 {
                continue;
            }
            for l in 0..L {
                if ev & (1 << l) == 0 {
                    continue;
                }
                let lane_pw: [f64; W] = std::array::from_fn(|c| ln.pw[c][l]);
                let dc = &dirs[ln.dirs[l]];
                // Empty cell at distance r = tm: jump over the empty box around it with the
                // one-ray traversal, started at the lane's point (inside the grid box, so it
                // starts; otherwise the ray is booked as lost).
                let jumped = if skip & (1 << l) != 0 && (dead | over) & (1 << l) == 0 {
                    match Dda::new(spec, ln.point(l, spec), self.omega[ln.dirs[l]]) {
                        Some(mut d) => {
                            let h = tms[l] as i64 - 1;
                            let (e, faces) = d.skip_to(h, d.skip_exit(h));
                            n_skip += faces - 1;
                            ln.set_from(l, spec, &d, dc);
                            Some(e == Exit::Inside)
                        }
                        None => None,
                    }
                } else {
                    Some(false)
                };
                let finished = if (dead | over) & (1 << l) != 0 || jumped.is_none() {
                    add(&mut out.lost, &lane_pw);
                    true
                } else if jumped == Some(true) {
                    false
                } else {
                    match ln.exit_kind(l, n) {
                        Exit::Inside => false,
                        Exit::Top => {
                            out.foot = ln.foot[l];
                            self.escape(ln.point(l, spec), ln.dirs[l], &lane_pw, out);
                            true
                        }
                        Exit::Bottom => {
                            let slot = ln.slot[l] as u32;
                            let (i, j) = (ln.cell[0][l], ln.cell[1][l]);
                            let (i, j) = (i.clamp(0, n[0] - 1), j.clamp(0, n[1] - 1));
                            let hp = ln.point(l, spec);
                            let psum = ln.psum[l];
                            self.bottom_at(i as usize, j as usize, hp, slot, &lane_pw, psum, out);
                            true
                        }
                        Exit::Side(..) => {
                            if isolated {
                                add(&mut out.lost, &lane_pw);
                                true
                            } else {
                                ln.wraps[l] += ln.wrap_sides(l, n);
                                if ln.wraps[l] > max_crossings {
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
                    ln.refill(v, &grid4, self, dirs, l, queue, out);
                }
            }
        }
        out.foot = foot_saved;
        out.crossings += n_cross;
        out.skipped += n_skip;
    }
}
