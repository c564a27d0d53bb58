//! Micro-kernel prototype of the flux-tracking pass (issue #4, session 11): the batched walk's
//! per-crossing work on a periodic 5 × 5 × 10 turbid layer (0.2 m cells, k = 0.75 m⁻¹, 2
//! channels, 10 slots, random start points and directions; 20.6 crossings per ray like the
//! Default 100 0.2 bench row), in these forms:
//! - `64`: f64 × 4 lanes shaped like `walk_batch_body` (absolute distances, world frame, table
//!   `exp` and half-barycentres by scalar row loads, points weighted in f64, booking per lane);
//! - `32`: f32 × 8 lanes in a cell-local frame (each lane's entry point in the current cell's
//!   frame and the distances to the next boundaries, rebased at every crossing, so f32 keeps
//!   ~1e-7 of a cell whatever the scene size or ray length; periodic wraps only move indices),
//!   table-free f32 `exp`, f32 half-barycentre rows (8 × 8 transpose), the intercepted fraction
//!   promoted to f64 and the transmitted one as 1 − it in f64 (closure by construction), powers
//!   and bookings in f64;
//! - `32p`: as `32` with the weighted points formed in f32 and promoted at the add;
//! - `64z`: `64` on f64 × 8 lanes in AVX-512 zmm registers (`walk64z`: `__mmask8` compares,
//!   mask blends and masked adds, one 8 × 8 transpose for the table rows and one for the
//!   booking rows), per lane the same operations as `64`, so the same crossings and totals
//!   (only the summation order of the bookings differs); `64zv`: the 7 point sums of a booked
//!   lane by one masked zmm read-modify-write from the transposed register;
//! - `g` suffix: the table reads by AVX2 gathers (`_mm256_i64gather_pd` / `_mm256_i32gather_ps`);
//!   `nb`: without the booking (points, transposes, scatter adds); `nh`: without the
//!   half-barycentres.
//!
//! Run: `cargo run --release -- 32 1000000` (rate = crossings / thread CPU time from
//! /proc/thread-self/schedstat, so that a loaded host still compares forms); instructions:
//! `valgrind --tool=callgrind ./target/release/kernel_f32x8_proto 32 100000`.
//!
//! Measured 2026-11-26 on the 2-core EPYC (Zen 4, family 25 model 17 — not Zen 3 as first
//! written; these forms use AVX2 + FMA only), 1e6 rays (20.57 M crossings),
//! CPU-time rates over 3 alternated runs, and callgrind instructions per crossing (1e5 rays):
//!
//! | form | Mcross/s (CPU) | instructions / crossing |
//! |---|---|---|
//! | 64 | 44.3–47.7 | 150.1 |
//! | 64g (gathers) | 37.6–40.6 | 145.6 |
//! | 64nb (no booking) | 56.4–56.8 | 81.3 |
//! | 32 | 62.2–64.9 | 113.2 |
//! | 32g (gathers) | 44.2–57.2 | 108.6 |
//! | 32p (f32 points) | 66.3–68.4 | 107.8 |
//! | 32nb (no booking) | 105.2–108.1 | 43.5 |
//!
//! Reading: f32 × 8 is 1.37–1.47× the f64 × 4 pass (113 / 108 against 150 instructions per
//! crossing); gathers save 3–4 % of the instructions and are slower on this CPU (dropped); the
//! booking of one interception (the 2 powers and 7 point sums read-modified-written into the
//! crossed cell's records, the weighted points and their transposes) is ~65–70 instructions and
//! ~13 cycles per crossing in either width — without it the f32 × 8 pass runs at ~107 M/s, with
//! it at ~66 M/s. Both forms visit the same cells on these rays but 2 of 20.6 M crossings.
//!
//! f64 × 8 (AVX-512), measured 2026-11-27 on the same Zen 4 (AVX-512 F/DQ/BW/VL), 1e6 rays,
//! CPU-time rates over 4 alternated runs per form (load average 0.8–1.5: the other core partly
//! busy; this clock counts CPU time in ~4 ms steps, ±1–2 % on these runs). Both builds are the
//! crate's release profile; "native" adds `-C target-cpu=native` (znver4). The same day `32`
//! ran at 81.6–85.7 and `32nb` at 135–139 (default build), so all rates are above the
//! 2026-11-26 table's; compare forms within one table only. valgrind 3.19 cannot decode
//! AVX-512, so no instruction counts:
//!
//! | form | Mcross/s (CPU), default | Mcross/s (CPU), native |
//! |---|---|---|
//! | 64 | 58.4–60.5 | 60.5–61.2 |
//! | 64z (f64 × 8, zmm) | 67.7–69.5 | 79.1–80.4 |
//! | 64zv (zmm row add) | 75.6–77.9 | 74.5–79.1 |
//! | 64nb (no booking) | 70.4–72.4 | 73.5–74.5 |
//! | 64z-nb (no booking) | 116.9–119.6 | 116.9–119.6 |
//!
//! Reading: `64z` gives the same 20 566 520 crossings and the same intercepted / lost totals
//! to all printed digits as `64` (out differs by 2e-16 relative). Without the booking (which
//! here also drops the half-barycentres, dead without the points) 8 lanes are 1.6× the 4 lanes;
//! with it 1.15–1.3× (default / native build; 1.3× with the masked row add): the per-lane
//! booking (flag, 2 gains, 7 point sums into the crossed cell's records) is the same scalar
//! work per crossing in either width and now bounds the pass: 4–6 of 12.5–14.5 ns per crossing
//! (64z − 64z-nb). `64z*` need AVX-512 (no run-time check).
//! f32 × 16 (AVX-512 zmm, session 20, `walk32z`: `walk32`'s cell-frame pass on 16 lanes,
//! `__mmask16` compares and blends, the half-barycentre rows of lanes l and l + 8 loaded into
//! one register and one two-half 8 × 8 transpose, `vscalefps` for 2^n), 1e6 rays, 2026-11-27
//! (two alternated runs each; the same day `32p` ran at 90–95, `32nb` at 135–139, `64z` at
//! 71.4):
//!
//! | form | Mcross/s (CPU) |
//! |---|---|
//! | 32z (f32 × 16, rows promoted and added to the f64 record) | 111.8–116.9 |
//! | 32zr (f32 × 16, an f32 points record: one 32-byte add) | 114.3–122.5 |
//! | 32z-nb (no booking) | 214.3–223.6 |
//!
//! Reading: on 16 lanes the pass is 1.6× `64z` (the product's form) with the booking and 1.8×
//! without; an f32 points record adds only 3–5 %. (A first build ran at 60 M/s: the
//! `_mm512_insertf32x8` inside an `array::from_fn` closure was not inlined — intrinsics in
//! closures of a `#[target_feature]` function need a plain loop.) Ported into the product
//! (session 20, `src/radiative/engine/batch/wide32.rs`, the default on AVX-512) the pass first
//! measured 1.18× the product's f64 × 8 walk, not 1.6×: the product's per-lane scalar work
//! (cell records, events, refills, side wraps) that this prototype does not have took the
//! rest; with that work cut (README of 4df2100, Kernel) it runs 1.42× (102–103 against 70–72
//! Mcross/s/core on one thread).
//!
//! Not product code: `unsafe` intrinsics, simplified events (no empty-space skip, no sky/ground
//! events, no wrap limit).
#![allow(unsafe_op_in_unsafe_fn, clippy::all)]
use std::arch::x86_64::*;

const NX: usize = 5;
const NY: usize = 5;
const NZ: usize = 10;
const SIZE: f64 = 0.2;
const NS: usize = 10;
const W: usize = 2;
const G: f64 = 0.5;
const DENS: f64 = 1.5;

#[derive(Clone, Copy)]
struct Ray {
    p: [f64; 3],
    d: [f64; 3],
    pw: [f64; 2],
    slot: usize,
    min_ray: f64,
}

struct Acc {
    tur: Vec<f64>,
    pts: Vec<f64>,
    pts32: Vec<f32>,
    flag: Vec<bool>,
    touched: Vec<u32>,
    lost: f64,
    out: f64,
    crossings: u64,
}

impl Acc {
    fn new() -> Self {
        let n = NX * NY * NZ;
        Acc {
            tur: vec![0.0; n * NS * W],
            pts: vec![0.0; n * 8],
            pts32: vec![0.0; n * 8],
            flag: vec![false; n],
            touched: Vec::new(),
            lost: 0.0,
            out: 0.0,
            crossings: 0,
        }
    }
}

fn rays(n: usize) -> Vec<Ray> {
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let mut rnd = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let mu: f64 = 0.05 + 0.95 * rnd();
            let up = rnd() < 0.5;
            let phi = 2.0 * std::f64::consts::PI * rnd();
            let st = (1.0 - mu * mu).sqrt();
            let d = [st * phi.cos(), st * phi.sin(), if up { mu } else { -mu }];
            let p = [
                rnd() * NX as f64 * SIZE,
                rnd() * NY as f64 * SIZE,
                rnd() * NZ as f64 * SIZE,
            ];
            Ray {
                p,
                d,
                pw: [0.3, 0.5],
                slot: (rnd() * NS as f64) as usize,
                min_ray: 1e-3,
            }
        })
        .collect()
}

// ---------------------------------------------------------------- tables
struct Tables {
    exp2: [f64; 128],
    hb64: Vec<[f64; 8]>,
    hb32: Vec<[f32; 8]>,
}

fn hb_closed(x: f64) -> (f64, f64) {
    if x < 1e-4 {
        return (0.25 - x / 12.0, 0.75 - x / 12.0);
    }
    let e = (-x).exp();
    let f = -(-x).exp_m1();
    let h = 0.5 * (1.0 + e);
    let s_half = -(-0.5 * f).ln_1p() / x;
    let den = 0.5 * f;
    let inv_k = 1.0 / x;
    (inv_k - s_half * h / den, inv_k + (s_half * h - e) / den)
}

impl Tables {
    fn new() -> Self {
        let exp2 = std::array::from_fn(|j| 2f64.powf(j as f64 / 128.0));
        // f64: bins of 2^-14..2^6, 32 per octave, constant pieces (values irrelevant to counts).
        let first = (1.0f64 / 16384.0).to_bits() >> 47;
        let mut hb64 = vec![[0.0; 8]; 1024];
        for b in 0..640u64 {
            let x = f64::from_bits((first + b) << 47);
            let (a, c) = hb_closed(x);
            hb64[b as usize] = [a, c, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        }
        let first32 = (1.0f32 / 16384.0).to_bits() >> 18;
        let mut hb32 = vec![[0.0f32; 8]; 1024];
        for b in 0..640u32 {
            let x = f32::from_bits((first32 + b) << 18) as f64;
            let (a, c) = hb_closed(x);
            hb32[b as usize] = [a as f32, c as f32, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        }
        Tables { exp2, hb64, hb32 }
    }
}

// ---------------------------------------------------------------- f64x4 (repo-shaped)
#[derive(Default)]
struct L64 {
    cell: [[f64; 4]; 3],
    step: [[f64; 4]; 3],
    tmax: [[f64; 4]; 3],
    t: [f64; 4],
    org: [[f64; 4]; 3],
    dir: [[f64; 4]; 3],
    inv: [[f64; 4]; 3],
    bb: [[f64; 4]; 3],
    lin: [i64; 4],
    dlin: [[i64; 4]; 3],
    pw: [[f64; 4]; W],
    psum: [f64; 4],
    minr: [f64; 4],
    slot: [usize; 4],
    act: u32,
    next: usize,
}

const NN: [usize; 3] = [NX, NY, NZ];
const STRIDE: [i64; 3] = [1, NX as i64, (NX * NY) as i64];

impl L64 {
    #[inline(always)]
    fn refill(&mut self, l: usize, q: &[Ray]) {
        let Some(r) = q.get(self.next) else {
            self.act &= !(1 << l);
            self.lin[l] = 0;
            return;
        };
        self.next += 1;
        let mut lin = 0i64;
        for a in 0..3 {
            let rel = r.p[a] / SIZE;
            let idx = rel.floor().clamp(0.0, NN[a] as f64 - 1.0);
            let up = r.d[a] > 0.0;
            let inv = 1.0 / r.d[a];
            let step = if up { 1.0 } else { -1.0 };
            let bb = if up { SIZE } else { 0.0 };
            self.cell[a][l] = idx;
            self.step[a][l] = step;
            self.org[a][l] = r.p[a];
            self.dir[a][l] = r.d[a];
            self.inv[a][l] = inv;
            self.bb[a][l] = bb;
            self.tmax[a][l] = ((bb + idx * SIZE) - r.p[a]) * inv;
            self.dlin[a][l] = step as i64 * STRIDE[a];
            lin += idx as i64 * STRIDE[a];
        }
        self.t[l] = 0.0;
        self.lin[l] = lin;
        self.act |= 1 << l;
        self.pw[0][l] = r.pw[0];
        self.pw[1][l] = r.pw[1];
        self.psum[l] = r.pw[0] + r.pw[1];
        self.minr[l] = r.min_ray;
        self.slot[l] = r.slot;
    }
}

#[inline(always)]
unsafe fn transpose4(r: [__m256d; 4]) -> [__m256d; 4] {
    let a01 = _mm256_unpacklo_pd(r[0], r[1]);
    let a23 = _mm256_unpacklo_pd(r[2], r[3]);
    let b01 = _mm256_unpackhi_pd(r[0], r[1]);
    let b23 = _mm256_unpackhi_pd(r[2], r[3]);
    [
        _mm256_permute2f128_pd::<0x20>(a01, a23),
        _mm256_permute2f128_pd::<0x20>(b01, b23),
        _mm256_permute2f128_pd::<0x31>(a01, a23),
        _mm256_permute2f128_pd::<0x31>(b01, b23),
    ]
}

#[inline(always)]
unsafe fn atten64<const GATHER: bool>(tb: &Tables, x: __m256d) -> (__m256d, __m256d) {
    let sp = |v: f64| _mm256_set1_pd(v);
    let mut f = _mm256_sub_pd(sp(1.0 / 720.0), _mm256_mul_pd(x, sp(1.0 / 5040.0)));
    for c in [1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0] {
        f = _mm256_sub_pd(sp(c), _mm256_mul_pd(x, f));
    }
    f = _mm256_mul_pd(x, f);
    let xe = _mm256_blendv_pd(sp(0.0), x, _mm256_cmp_pd::<_CMP_LT_OQ>(x, sp(708.0)));
    let y = _mm256_xor_pd(xe, sp(-0.0));
    const SHIFT: f64 = 6755399441055744.0;
    let z = _mm256_mul_pd(y, sp(184.6649652337873));
    let shifted = _mm256_add_pd(z, sp(SHIFT));
    let kf = _mm256_sub_pd(shifted, sp(SHIFT));
    let k = _mm256_sub_epi64(
        _mm256_castpd_si256(shifted),
        _mm256_set1_epi64x(SHIFT.to_bits() as i64),
    );
    let r = _mm256_sub_pd(
        _mm256_sub_pd(y, _mm256_mul_pd(kf, sp(0.005415208637714386))),
        _mm256_mul_pd(kf, sp(3.710410186743494e-09)),
    );
    let mut p = _mm256_add_pd(sp(1.0 / 24.0), _mm256_mul_pd(r, sp(1.0 / 120.0)));
    p = _mm256_add_pd(sp(1.0 / 6.0), _mm256_mul_pd(r, p));
    p = _mm256_add_pd(sp(0.5), _mm256_mul_pd(r, p));
    p = _mm256_add_pd(r, _mm256_mul_pd(_mm256_mul_pd(r, r), p));
    let t = if GATHER {
        _mm256_i64gather_pd::<8>(
            tb.exp2.as_ptr(),
            _mm256_and_si256(k, _mm256_set1_epi64x(127)),
        )
    } else {
        let mut ka = [0i64; 4];
        _mm256_storeu_si256(ka.as_mut_ptr() as *mut __m256i, k);
        _mm256_setr_pd(
            tb.exp2[(ka[0] & 127) as usize],
            tb.exp2[(ka[1] & 127) as usize],
            tb.exp2[(ka[2] & 127) as usize],
            tb.exp2[(ka[3] & 127) as usize],
        )
    };
    let biased = _mm256_add_epi64(k, _mm256_set1_epi64x(1023 << 7));
    let scale = _mm256_castsi256_pd(_mm256_slli_epi64::<52>(_mm256_srli_epi64::<7>(biased)));
    let e = _mm256_mul_pd(_mm256_add_pd(t, _mm256_mul_pd(t, p)), scale);
    let small = _mm256_cmp_pd::<_CMP_LT_OQ>(x, sp(1.0 / 32.0));
    let frac = _mm256_blendv_pd(_mm256_sub_pd(sp(1.0), e), f, small);
    let tr = _mm256_blendv_pd(e, _mm256_sub_pd(sp(1.0), f), small);
    (frac, tr)
}

#[inline(always)]
unsafe fn hb64<const GATHER: bool>(tb: &Tables, x: __m256d, ell: __m256d) -> (__m256d, __m256d) {
    let sp = |v: f64| _mm256_set1_pd(v);
    let first = (1.0f64 / 16384.0).to_bits() >> 47;
    let bits = _mm256_castpd_si256(x);
    let bin = _mm256_and_si256(
        _mm256_sub_epi64(
            _mm256_srli_epi64::<47>(bits),
            _mm256_set1_epi64x(first as i64),
        ),
        _mm256_set1_epi64x(1023),
    );
    let start = _mm256_castsi256_pd(_mm256_and_si256(
        bits,
        _mm256_set1_epi64x(!((1i64 << 47) - 1)),
    ));
    let t = _mm256_sub_pd(x, start);
    let [c0a, c0b, c1a, c1b, c2a, c2b, c3a, c3b] = if GATHER {
        let base = tb.hb64.as_ptr() as *const f64;
        let off = _mm256_slli_epi64::<3>(bin);
        std::array::from_fn(|i| _mm256_i64gather_pd::<8>(base.add(i), off))
    } else {
        let mut ba = [0u64; 4];
        _mm256_storeu_si256(ba.as_mut_ptr() as *mut __m256i, bin);
        let mut lo = [_mm256_setzero_pd(); 4];
        let mut hi = [_mm256_setzero_pd(); 4];
        for l in 0..4 {
            let r = tb.hb64[ba[l] as usize].as_ptr();
            lo[l] = _mm256_loadu_pd(r);
            hi[l] = _mm256_loadu_pd(r.add(4));
        }
        let [c0a, c0b, c1a, c1b] = transpose4(lo);
        let [c2a, c2b, c3a, c3b] = transpose4(hi);
        [c0a, c0b, c1a, c1b, c2a, c2b, c3a, c3b]
    };
    let h = |c0, c1, c2, c3| {
        let p = _mm256_add_pd(c2, _mm256_mul_pd(t, c3));
        let p = _mm256_add_pd(c1, _mm256_mul_pd(t, p));
        _mm256_mul_pd(ell, _mm256_add_pd(c0, _mm256_mul_pd(t, p)))
    };
    let a = h(c0a, c1a, c2a, c3a);
    let b = h(c0b, c1b, c2b, c3b);
    let l2 = std::f64::consts::LN_2;
    let u = _mm256_div_pd(ell, x);
    let big = _mm256_cmp_pd::<_CMP_GE_OQ>(x, sp(64.0));
    let a = _mm256_blendv_pd(a, _mm256_mul_pd(sp(1.0 - l2), u), big);
    let b = _mm256_blendv_pd(b, _mm256_mul_pd(sp(1.0 + l2), u), big);
    let small = _mm256_cmp_pd::<_CMP_LT_OQ>(x, sp(1.0 / 16384.0));
    let x12 = _mm256_div_pd(x, sp(12.0));
    let sa = _mm256_mul_pd(ell, _mm256_sub_pd(sp(0.25), x12));
    let sb = _mm256_mul_pd(ell, _mm256_sub_pd(sp(0.75), x12));
    (
        _mm256_blendv_pd(a, sa, small),
        _mm256_blendv_pd(b, sb, small),
    )
}

#[target_feature(enable = "avx2,fma")]
#[inline(never)]
unsafe fn walk64<const GATHER: bool, const MODE: u8>(tb: &Tables, q: &[Ray], acc: &mut Acc) {
    let mut ln = L64::default();
    for l in 0..4 {
        ln.refill(l, q);
    }
    let sp = |v: f64| _mm256_set1_pd(v);
    let zero = sp(0.0);
    let mut n_cross = 0u64;
    let (tur, pts, flag, touched) = (&mut acc.tur, &mut acc.pts, &mut acc.flag, &mut acc.touched);
    let mask = |b: u32| {
        _mm256_castsi256_pd(_mm256_setr_epi64x(
            -((b & 1) as i64),
            -(((b >> 1) & 1) as i64),
            -(((b >> 2) & 1) as i64),
            -(((b >> 3) & 1) as i64),
        ))
    };
    while ln.act != 0 {
        let mut dens = [0.0; 4];
        let mut idx = [0u32; 4];
        for l in 0..4 {
            let lin = ln.lin[l] as usize;
            dens[l] = if lin < NX * NY * NZ { DENS } else { 0.0 };
            idx[l] = lin as u32;
        }
        let dens = _mm256_loadu_pd(dens.as_ptr());
        let occ = _mm256_cmp_pd::<_CMP_GT_OQ>(dens, zero);
        let k = _mm256_mul_pd(sp(G), dens);
        let act = mask(ln.act);
        let t0 = _mm256_loadu_pd(ln.t.as_ptr());
        let tmp = ln.tmax.as_ptr();
        let tm = |a: usize| _mm256_loadu_pd((*tmp.add(a)).as_ptr());
        let t1 = _mm256_min_pd(tm(2), _mm256_min_pd(tm(1), tm(0)));
        let ell = _mm256_sub_pd(t1, t0);
        let hit_m = _mm256_and_pd(
            _mm256_and_pd(act, occ),
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(t1, t0),
                _mm256_cmp_pd::<_CMP_GT_OQ>(k, zero),
            ),
        );
        let hit = _mm256_movemask_pd(hit_m) as u32;
        let x = _mm256_and_pd(hit_m, _mm256_mul_pd(k, ell));
        let (frac, tr) = atten64::<GATHER>(tb, x);
        let (s1, s2) = if MODE & 2 != 0 {
            (_mm256_mul_pd(ell, sp(0.25)), _mm256_mul_pd(ell, sp(0.75)))
        } else {
            hb64::<GATHER>(tb, x, ell)
        };
        let psum = _mm256_loadu_pd(ln.psum.as_ptr());
        let wt = _mm256_mul_pd(psum, frac);
        let point = |a: usize, s: __m256d| {
            let o = _mm256_loadu_pd(ln.org[a].as_ptr());
            let d = _mm256_loadu_pd(ln.dir[a].as_ptr());
            _mm256_mul_pd(_mm256_add_pd(o, _mm256_mul_pd(d, _mm256_add_pd(t0, s))), wt)
        };
        let mut gain = [[0.0; 4]; W];
        for c in 0..W {
            let pwc = _mm256_loadu_pd(ln.pw[c].as_ptr());
            _mm256_storeu_pd(gain[c].as_mut_ptr(), _mm256_mul_pd(pwc, frac));
            _mm256_storeu_pd(
                ln.pw[c].as_mut_ptr(),
                _mm256_blendv_pd(pwc, _mm256_mul_pd(pwc, tr), hit_m),
            );
        }
        let ra = transpose4([point(0, s1), point(1, s1), point(2, s1), point(0, s2)]);
        let rb = transpose4([point(1, s2), point(2, s2), wt, zero]);
        let mut rows_a = [[0.0; 4]; 4];
        let mut rows_b = [[0.0; 4]; 4];
        for l in 0..4 {
            _mm256_storeu_pd(rows_a[l].as_mut_ptr(), ra[l]);
            _mm256_storeu_pd(rows_b[l].as_mut_ptr(), rb[l]);
        }
        for l in 0..4 {
            if hit & (1 << l) == 0 || MODE & 1 != 0 {
                continue;
            }
            let e = idx[l] as usize;
            if MODE & 4 == 0 && !flag[e] {
                flag[e] = true;
                touched.push(e as u32);
            }
            let s = (e * NS + ln.slot[l]) * W;
            let r: &mut [f64; W] = (&mut tur[s..s + W]).try_into().unwrap();
            for c in 0..W {
                r[c] += gain[c][l];
            }
            let qq: &mut [f64; 7] = (&mut pts[e * 8..e * 8 + 7]).try_into().unwrap();
            for i in 0..4 {
                qq[i] += rows_a[l][i];
            }
            for i in 0..3 {
                qq[4 + i] += rows_b[l][i];
            }
        }
        let psum = _mm256_add_pd(
            _mm256_loadu_pd(ln.pw[0].as_ptr()),
            _mm256_loadu_pd(ln.pw[1].as_ptr()),
        );
        _mm256_storeu_pd(ln.psum.as_mut_ptr(), psum);
        let dead = hit
            & _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(
                psum,
                _mm256_loadu_pd(ln.minr.as_ptr()),
            )) as u32;
        let go = ln.act & !dead;
        let gom = mask(go);
        // step_at
        let mut outside = _mm256_setzero_pd();
        for a in 0..3 {
            let tmax = tm(a);
            let m = _mm256_and_pd(gom, _mm256_cmp_pd::<_CMP_LE_OQ>(tmax, t1));
            let c = _mm256_add_pd(
                _mm256_loadu_pd(ln.cell[a].as_ptr()),
                _mm256_and_pd(m, _mm256_loadu_pd(ln.step[a].as_ptr())),
            );
            _mm256_storeu_pd(ln.cell[a].as_mut_ptr(), c);
            let lin = _mm256_add_epi64(
                _mm256_loadu_si256(ln.lin.as_ptr() as *const __m256i),
                _mm256_and_si256(
                    _mm256_castpd_si256(m),
                    _mm256_loadu_si256(ln.dlin[a].as_ptr() as *const __m256i),
                ),
            );
            _mm256_storeu_si256(ln.lin.as_mut_ptr() as *mut __m256i, lin);
            let inside = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GE_OQ>(c, zero),
                _mm256_cmp_pd::<_CMP_LT_OQ>(c, sp(NN[a] as f64)),
            );
            outside = _mm256_or_pd(outside, _mm256_andnot_pd(inside, m));
            let bt = _mm256_mul_pd(
                _mm256_sub_pd(
                    _mm256_add_pd(
                        _mm256_loadu_pd(ln.bb[a].as_ptr()),
                        _mm256_mul_pd(c, sp(SIZE)),
                    ),
                    _mm256_loadu_pd(ln.org[a].as_ptr()),
                ),
                _mm256_loadu_pd(ln.inv[a].as_ptr()),
            );
            _mm256_storeu_pd(ln.tmax[a].as_mut_ptr(), _mm256_blendv_pd(tmax, bt, m));
        }
        _mm256_storeu_pd(ln.t.as_mut_ptr(), _mm256_blendv_pd(t0, t1, gom));
        n_cross += ln.act.count_ones() as u64;
        let mut out_b = go & _mm256_movemask_pd(outside) as u32;
        if out_b != 0 {
            let cz = _mm256_loadu_pd(ln.cell[2].as_ptr());
            let zout = _mm256_movemask_pd(_mm256_or_pd(
                _mm256_cmp_pd::<_CMP_LT_OQ>(cz, zero),
                _mm256_cmp_pd::<_CMP_GE_OQ>(cz, sp(NZ as f64)),
            )) as u32;
            let side = out_b & !zout;
            if side != 0 {
                // wrap_sides_x4
                let sm = mask(side);
                let t = _mm256_loadu_pd(ln.t.as_ptr());
                for a in 0..2 {
                    let c = _mm256_loadu_pd(ln.cell[a].as_ptr());
                    let n = sp(NN[a] as f64);
                    let below = _mm256_and_pd(sm, _mm256_cmp_pd::<_CMP_LT_OQ>(c, zero));
                    let above = _mm256_and_pd(sm, _mm256_cmp_pd::<_CMP_GE_OQ>(c, n));
                    let w = _mm256_or_pd(below, above);
                    let back =
                        _mm256_blendv_pd(_mm256_and_pd(above, sp(-(NN[a] as f64))), n, below);
                    let c = _mm256_add_pd(c, back);
                    _mm256_storeu_pd(ln.cell[a].as_mut_ptr(), c);
                    let nl = NN[a] as i64 * STRIDE[a];
                    let dl = _mm256_or_si256(
                        _mm256_and_si256(_mm256_castpd_si256(below), _mm256_set1_epi64x(nl)),
                        _mm256_and_si256(_mm256_castpd_si256(above), _mm256_set1_epi64x(-nl)),
                    );
                    let lin =
                        _mm256_add_epi64(_mm256_loadu_si256(ln.lin.as_ptr() as *const __m256i), dl);
                    _mm256_storeu_si256(ln.lin.as_mut_ptr() as *mut __m256i, lin);
                    let period = NN[a] as f64 * SIZE;
                    let o0 = _mm256_loadu_pd(ln.org[a].as_ptr());
                    let o1 = _mm256_add_pd(o0, _mm256_blendv_pd(sp(-period), sp(period), below));
                    let o = _mm256_blendv_pd(o0, o1, w);
                    _mm256_storeu_pd(ln.org[a].as_mut_ptr(), o);
                    let bt = _mm256_mul_pd(
                        _mm256_sub_pd(
                            _mm256_add_pd(
                                _mm256_loadu_pd(ln.bb[a].as_ptr()),
                                _mm256_mul_pd(c, sp(SIZE)),
                            ),
                            o,
                        ),
                        _mm256_loadu_pd(ln.inv[a].as_ptr()),
                    );
                    _mm256_storeu_pd(
                        ln.tmax[a].as_mut_ptr(),
                        _mm256_blendv_pd(tm(a), _mm256_max_pd(bt, t), w),
                    );
                }
                out_b &= !side;
            }
        }
        let ev = dead | out_b;
        if ev == 0 {
            continue;
        }
        for l in 0..4 {
            if ev & (1 << l) == 0 {
                continue;
            }
            let p = ln.pw[0][l] + ln.pw[1][l];
            if dead & (1 << l) != 0 {
                acc.lost += p;
            } else {
                acc.out += p;
            }
            ln.refill(l, q);
        }
    }
    acc.crossings += n_cross;
}

// ---------------------------------------------------------------- f64x8 (AVX-512, zmm)
/// `L64` with 8 lanes, 64-byte aligned so that each lane row is one zmm load.
#[derive(Default)]
#[repr(C, align(64))]
struct L64z {
    cell: [[f64; 8]; 3],
    step: [[f64; 8]; 3],
    tmax: [[f64; 8]; 3],
    t: [f64; 8],
    org: [[f64; 8]; 3],
    dir: [[f64; 8]; 3],
    inv: [[f64; 8]; 3],
    bb: [[f64; 8]; 3],
    lin: [i64; 8],
    dlin: [[i64; 8]; 3],
    pw: [[f64; 8]; W],
    psum: [f64; 8],
    minr: [f64; 8],
    slot: [usize; 8],
    act: u32,
    next: usize,
}

impl L64z {
    /// Same per-lane set-up as `L64::refill`.
    #[inline(always)]
    fn refill(&mut self, l: usize, q: &[Ray]) {
        let Some(r) = q.get(self.next) else {
            self.act &= !(1 << l);
            self.lin[l] = 0;
            return;
        };
        self.next += 1;
        let mut lin = 0i64;
        for a in 0..3 {
            let rel = r.p[a] / SIZE;
            let idx = rel.floor().clamp(0.0, NN[a] as f64 - 1.0);
            let up = r.d[a] > 0.0;
            let inv = 1.0 / r.d[a];
            let step = if up { 1.0 } else { -1.0 };
            let bb = if up { SIZE } else { 0.0 };
            self.cell[a][l] = idx;
            self.step[a][l] = step;
            self.org[a][l] = r.p[a];
            self.dir[a][l] = r.d[a];
            self.inv[a][l] = inv;
            self.bb[a][l] = bb;
            self.tmax[a][l] = ((bb + idx * SIZE) - r.p[a]) * inv;
            self.dlin[a][l] = step as i64 * STRIDE[a];
            lin += idx as i64 * STRIDE[a];
        }
        self.t[l] = 0.0;
        self.lin[l] = lin;
        self.act |= 1 << l;
        self.pw[0][l] = r.pw[0];
        self.pw[1][l] = r.pw[1];
        self.psum[l] = r.pw[0] + r.pw[1];
        self.minr[l] = r.min_ray;
        self.slot[l] = r.slot;
    }
}

/// 8 × 8 f64 transpose: out[i][l] = r[l][i] (8 unpacks + 16 128-bit lane shuffles).
#[inline(always)]
unsafe fn transpose8z(r: [__m512d; 8]) -> [__m512d; 8] {
    let t0 = _mm512_unpacklo_pd(r[0], r[1]);
    let t1 = _mm512_unpackhi_pd(r[0], r[1]);
    let t2 = _mm512_unpacklo_pd(r[2], r[3]);
    let t3 = _mm512_unpackhi_pd(r[2], r[3]);
    let t4 = _mm512_unpacklo_pd(r[4], r[5]);
    let t5 = _mm512_unpackhi_pd(r[4], r[5]);
    let t6 = _mm512_unpacklo_pd(r[6], r[7]);
    let t7 = _mm512_unpackhi_pd(r[6], r[7]);
    // u0: r0[0] r1[0] r0[4] r1[4] r2[0] r3[0] r2[4] r3[4], …
    let u0 = _mm512_shuffle_f64x2::<0x88>(t0, t2);
    let u1 = _mm512_shuffle_f64x2::<0xDD>(t0, t2);
    let u2 = _mm512_shuffle_f64x2::<0x88>(t1, t3);
    let u3 = _mm512_shuffle_f64x2::<0xDD>(t1, t3);
    let u4 = _mm512_shuffle_f64x2::<0x88>(t4, t6);
    let u5 = _mm512_shuffle_f64x2::<0xDD>(t4, t6);
    let u6 = _mm512_shuffle_f64x2::<0x88>(t5, t7);
    let u7 = _mm512_shuffle_f64x2::<0xDD>(t5, t7);
    [
        _mm512_shuffle_f64x2::<0x88>(u0, u4),
        _mm512_shuffle_f64x2::<0x88>(u2, u6),
        _mm512_shuffle_f64x2::<0x88>(u1, u5),
        _mm512_shuffle_f64x2::<0x88>(u3, u7),
        _mm512_shuffle_f64x2::<0xDD>(u0, u4),
        _mm512_shuffle_f64x2::<0xDD>(u2, u6),
        _mm512_shuffle_f64x2::<0xDD>(u1, u5),
        _mm512_shuffle_f64x2::<0xDD>(u3, u7),
    ]
}

/// `atten64` on 8 lanes: the same operations (no FMA contraction), mask blends.
#[inline(always)]
unsafe fn atten64z(tb: &Tables, x: __m512d) -> (__m512d, __m512d) {
    let sp = |v: f64| _mm512_set1_pd(v);
    let mut f = _mm512_sub_pd(sp(1.0 / 720.0), _mm512_mul_pd(x, sp(1.0 / 5040.0)));
    for c in [1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0] {
        f = _mm512_sub_pd(sp(c), _mm512_mul_pd(x, f));
    }
    f = _mm512_mul_pd(x, f);
    let xe = _mm512_maskz_mov_pd(_mm512_cmp_pd_mask::<_CMP_LT_OQ>(x, sp(708.0)), x);
    let y = _mm512_xor_pd(xe, sp(-0.0));
    const SHIFT: f64 = 6755399441055744.0;
    let z = _mm512_mul_pd(y, sp(184.6649652337873));
    let shifted = _mm512_add_pd(z, sp(SHIFT));
    let kf = _mm512_sub_pd(shifted, sp(SHIFT));
    let k = _mm512_sub_epi64(
        _mm512_castpd_si512(shifted),
        _mm512_set1_epi64(SHIFT.to_bits() as i64),
    );
    let r = _mm512_sub_pd(
        _mm512_sub_pd(y, _mm512_mul_pd(kf, sp(0.005415208637714386))),
        _mm512_mul_pd(kf, sp(3.710410186743494e-09)),
    );
    let mut p = _mm512_add_pd(sp(1.0 / 24.0), _mm512_mul_pd(r, sp(1.0 / 120.0)));
    p = _mm512_add_pd(sp(1.0 / 6.0), _mm512_mul_pd(r, p));
    p = _mm512_add_pd(sp(0.5), _mm512_mul_pd(r, p));
    p = _mm512_add_pd(r, _mm512_mul_pd(_mm512_mul_pd(r, r), p));
    let mut ka = [0i64; 8];
    _mm512_storeu_si512(ka.as_mut_ptr() as *mut __m512i, k);
    let t = _mm512_setr_pd(
        tb.exp2[(ka[0] & 127) as usize],
        tb.exp2[(ka[1] & 127) as usize],
        tb.exp2[(ka[2] & 127) as usize],
        tb.exp2[(ka[3] & 127) as usize],
        tb.exp2[(ka[4] & 127) as usize],
        tb.exp2[(ka[5] & 127) as usize],
        tb.exp2[(ka[6] & 127) as usize],
        tb.exp2[(ka[7] & 127) as usize],
    );
    let biased = _mm512_add_epi64(k, _mm512_set1_epi64(1023 << 7));
    let scale = _mm512_castsi512_pd(_mm512_slli_epi64::<52>(_mm512_srli_epi64::<7>(biased)));
    let e = _mm512_mul_pd(_mm512_add_pd(t, _mm512_mul_pd(t, p)), scale);
    let small = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(x, sp(1.0 / 32.0));
    let frac = _mm512_mask_blend_pd(small, _mm512_sub_pd(sp(1.0), e), f);
    let tr = _mm512_mask_blend_pd(small, e, _mm512_sub_pd(sp(1.0), f));
    (frac, tr)
}

/// `hb64` on 8 lanes: 8 row loads and one 8 × 8 transpose.
#[inline(always)]
unsafe fn hb64z(tb: &Tables, x: __m512d, ell: __m512d) -> (__m512d, __m512d) {
    let sp = |v: f64| _mm512_set1_pd(v);
    let first = (1.0f64 / 16384.0).to_bits() >> 47;
    let bits = _mm512_castpd_si512(x);
    let bin = _mm512_and_si512(
        _mm512_sub_epi64(
            _mm512_srli_epi64::<47>(bits),
            _mm512_set1_epi64(first as i64),
        ),
        _mm512_set1_epi64(1023),
    );
    let start = _mm512_castsi512_pd(_mm512_and_si512(
        bits,
        _mm512_set1_epi64(!((1i64 << 47) - 1)),
    ));
    let t = _mm512_sub_pd(x, start);
    let mut ba = [0u64; 8];
    _mm512_storeu_si512(ba.as_mut_ptr() as *mut __m512i, bin);
    let rows: [__m512d; 8] =
        std::array::from_fn(|l| _mm512_loadu_pd(tb.hb64[ba[l] as usize].as_ptr()));
    let [c0a, c0b, c1a, c1b, c2a, c2b, c3a, c3b] = transpose8z(rows);
    let h = |c0, c1, c2, c3| {
        let p = _mm512_add_pd(c2, _mm512_mul_pd(t, c3));
        let p = _mm512_add_pd(c1, _mm512_mul_pd(t, p));
        _mm512_mul_pd(ell, _mm512_add_pd(c0, _mm512_mul_pd(t, p)))
    };
    let a = h(c0a, c1a, c2a, c3a);
    let b = h(c0b, c1b, c2b, c3b);
    let l2 = std::f64::consts::LN_2;
    let u = _mm512_div_pd(ell, x);
    let big = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(x, sp(64.0));
    let a = _mm512_mask_blend_pd(big, a, _mm512_mul_pd(sp(1.0 - l2), u));
    let b = _mm512_mask_blend_pd(big, b, _mm512_mul_pd(sp(1.0 + l2), u));
    let small = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(x, sp(1.0 / 16384.0));
    let x12 = _mm512_div_pd(x, sp(12.0));
    let sa = _mm512_mul_pd(ell, _mm512_sub_pd(sp(0.25), x12));
    let sb = _mm512_mul_pd(ell, _mm512_sub_pd(sp(0.75), x12));
    (
        _mm512_mask_blend_pd(small, a, sa),
        _mm512_mask_blend_pd(small, b, sb),
    )
}

/// `walk64::<false, MODE>` on 8 lanes of f64 in zmm registers: `__mmask8` compares, mask
/// blends / masked adds for the `and`/`blendv` selections, one 8 × 8 transpose for the
/// booking rows (7 values + a zero per lane). Per lane the same operations as `walk64`, so
/// the same cells and crossings; only the lanes' interleaving (hence the summation order of
/// the bookings and of `out`/`lost`) differs. MODE: 0 full, 1 no booking, 2 each booked
/// lane's 7 point sums by one masked zmm read-modify-write from the transposed register.
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,fma")]
#[inline(never)]
unsafe fn walk64z<const MODE: u8>(tb: &Tables, q: &[Ray], acc: &mut Acc) {
    let mut ln = L64z::default();
    for l in 0..8 {
        ln.refill(l, q);
    }
    let sp = |v: f64| _mm512_set1_pd(v);
    let zero = sp(0.0);
    let mut n_cross = 0u64;
    let (tur, pts, flag, touched) = (&mut acc.tur, &mut acc.pts, &mut acc.flag, &mut acc.touched);
    let ld = |p: &[f64; 8]| _mm512_loadu_pd(p.as_ptr());
    let ldi = |p: &[i64; 8]| _mm512_loadu_si512(p.as_ptr() as *const __m512i);
    while ln.act != 0 {
        let mut dens = [0.0; 8];
        let mut idx = [0u32; 8];
        for l in 0..8 {
            let lin = ln.lin[l] as usize;
            dens[l] = if lin < NX * NY * NZ { DENS } else { 0.0 };
            idx[l] = lin as u32;
        }
        let dens = _mm512_loadu_pd(dens.as_ptr());
        let occ = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(dens, zero);
        let k = _mm512_mul_pd(sp(G), dens);
        let act = ln.act as __mmask8;
        let t0 = ld(&ln.t);
        let t1 = _mm512_min_pd(
            ld(&ln.tmax[2]),
            _mm512_min_pd(ld(&ln.tmax[1]), ld(&ln.tmax[0])),
        );
        let ell = _mm512_sub_pd(t1, t0);
        let hit_m = act
            & occ
            & _mm512_cmp_pd_mask::<_CMP_GT_OQ>(t1, t0)
            & _mm512_cmp_pd_mask::<_CMP_GT_OQ>(k, zero);
        let hit = hit_m as u32;
        let x = _mm512_maskz_mov_pd(hit_m, _mm512_mul_pd(k, ell));
        let (frac, tr) = atten64z(tb, x);
        let (s1, s2) = hb64z(tb, x, ell);
        let psum = ld(&ln.psum);
        let wt = _mm512_mul_pd(psum, frac);
        let point = |a: usize, s: __m512d| {
            let o = ld(&ln.org[a]);
            let d = ld(&ln.dir[a]);
            _mm512_mul_pd(_mm512_add_pd(o, _mm512_mul_pd(d, _mm512_add_pd(t0, s))), wt)
        };
        let mut gain = [[0.0; 8]; W];
        for c in 0..W {
            let pwc = ld(&ln.pw[c]);
            _mm512_storeu_pd(gain[c].as_mut_ptr(), _mm512_mul_pd(pwc, frac));
            _mm512_storeu_pd(
                ln.pw[c].as_mut_ptr(),
                _mm512_mask_mul_pd(pwc, hit_m, pwc, tr),
            );
        }
        if MODE & 1 == 0 {
            let rv = transpose8z([
                point(0, s1),
                point(1, s1),
                point(2, s1),
                point(0, s2),
                point(1, s2),
                point(2, s2),
                wt,
                zero,
            ]);
            let mut rows = [[0.0; 8]; 8];
            if MODE & 2 == 0 {
                for l in 0..8 {
                    _mm512_storeu_pd(rows[l].as_mut_ptr(), rv[l]);
                }
            }
            for l in 0..8 {
                if hit & (1 << l) == 0 {
                    continue;
                }
                let e = idx[l] as usize;
                if !flag[e] {
                    flag[e] = true;
                    touched.push(e as u32);
                }
                let s = (e * NS + ln.slot[l]) * W;
                let r: &mut [f64; W] = (&mut tur[s..s + W]).try_into().unwrap();
                for c in 0..W {
                    r[c] += gain[c][l];
                }
                let qq: &mut [f64; 7] = (&mut pts[e * 8..e * 8 + 7]).try_into().unwrap();
                if MODE & 2 != 0 {
                    // The lane's row straight from the transpose: one masked 7-wide
                    // read-modify-write (same sums as the scalar adds).
                    let pq = qq.as_mut_ptr();
                    let v = _mm512_add_pd(_mm512_maskz_loadu_pd(0x7F, pq), rv[l]);
                    _mm512_mask_storeu_pd(pq, 0x7F, v);
                } else {
                    for i in 0..7 {
                        qq[i] += rows[l][i];
                    }
                }
            }
        }
        let psum = _mm512_add_pd(ld(&ln.pw[0]), ld(&ln.pw[1]));
        _mm512_storeu_pd(ln.psum.as_mut_ptr(), psum);
        let dead = hit & _mm512_cmp_pd_mask::<_CMP_LT_OQ>(psum, ld(&ln.minr)) as u32;
        let go = ln.act & !dead;
        let gom = go as __mmask8;
        // step_at
        let mut outside: __mmask8 = 0;
        for a in 0..3 {
            let tmax = ld(&ln.tmax[a]);
            let m = gom & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(tmax, t1);
            let c0 = ld(&ln.cell[a]);
            let c = _mm512_mask_add_pd(c0, m, c0, ld(&ln.step[a]));
            _mm512_storeu_pd(ln.cell[a].as_mut_ptr(), c);
            let lin0 = ldi(&ln.lin);
            let lin = _mm512_mask_add_epi64(lin0, m, lin0, ldi(&ln.dlin[a]));
            _mm512_storeu_si512(ln.lin.as_mut_ptr() as *mut __m512i, lin);
            let inside = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(c, zero)
                & _mm512_cmp_pd_mask::<_CMP_LT_OQ>(c, sp(NN[a] as f64));
            outside |= m & !inside;
            let bt = _mm512_mul_pd(
                _mm512_sub_pd(
                    _mm512_add_pd(ld(&ln.bb[a]), _mm512_mul_pd(c, sp(SIZE))),
                    ld(&ln.org[a]),
                ),
                ld(&ln.inv[a]),
            );
            _mm512_storeu_pd(ln.tmax[a].as_mut_ptr(), _mm512_mask_blend_pd(m, tmax, bt));
        }
        _mm512_storeu_pd(ln.t.as_mut_ptr(), _mm512_mask_blend_pd(gom, t0, t1));
        n_cross += ln.act.count_ones() as u64;
        let mut out_b = go & outside as u32;
        if out_b != 0 {
            let cz = ld(&ln.cell[2]);
            let zout = (_mm512_cmp_pd_mask::<_CMP_LT_OQ>(cz, zero)
                | _mm512_cmp_pd_mask::<_CMP_GE_OQ>(cz, sp(NZ as f64)))
                as u32;
            let side = out_b & !zout;
            if side != 0 {
                // wrap_sides_x4 on 8 lanes
                let sm = side as __mmask8;
                let t = ld(&ln.t);
                for a in 0..2 {
                    let c = ld(&ln.cell[a]);
                    let n = sp(NN[a] as f64);
                    let below = sm & _mm512_cmp_pd_mask::<_CMP_LT_OQ>(c, zero);
                    let above = sm & _mm512_cmp_pd_mask::<_CMP_GE_OQ>(c, n);
                    let w = below | above;
                    let back = _mm512_mask_blend_pd(
                        below,
                        _mm512_maskz_mov_pd(above, sp(-(NN[a] as f64))),
                        n,
                    );
                    let c = _mm512_add_pd(c, back);
                    _mm512_storeu_pd(ln.cell[a].as_mut_ptr(), c);
                    let nl = NN[a] as i64 * STRIDE[a];
                    let dl = _mm512_mask_mov_epi64(
                        _mm512_maskz_mov_epi64(above, _mm512_set1_epi64(-nl)),
                        below,
                        _mm512_set1_epi64(nl),
                    );
                    let lin = _mm512_add_epi64(ldi(&ln.lin), dl);
                    _mm512_storeu_si512(ln.lin.as_mut_ptr() as *mut __m512i, lin);
                    let period = NN[a] as f64 * SIZE;
                    let o0 = ld(&ln.org[a]);
                    let o1 =
                        _mm512_add_pd(o0, _mm512_mask_blend_pd(below, sp(-period), sp(period)));
                    let o = _mm512_mask_blend_pd(w, o0, o1);
                    _mm512_storeu_pd(ln.org[a].as_mut_ptr(), o);
                    let bt = _mm512_mul_pd(
                        _mm512_sub_pd(_mm512_add_pd(ld(&ln.bb[a]), _mm512_mul_pd(c, sp(SIZE))), o),
                        ld(&ln.inv[a]),
                    );
                    _mm512_storeu_pd(
                        ln.tmax[a].as_mut_ptr(),
                        _mm512_mask_blend_pd(w, ld(&ln.tmax[a]), _mm512_max_pd(bt, t)),
                    );
                }
                out_b &= !side;
            }
        }
        let ev = dead | out_b;
        if ev == 0 {
            continue;
        }
        for l in 0..8 {
            if ev & (1 << l) == 0 {
                continue;
            }
            let p = ln.pw[0][l] + ln.pw[1][l];
            if dead & (1 << l) != 0 {
                acc.lost += p;
            } else {
                acc.out += p;
            }
            ln.refill(l, q);
        }
    }
    acc.crossings += n_cross;
}

// ---------------------------------------------------------------- f32x8, cell-local frame
/// Per lane: the ray's entry point in the current cell's frame (m, in [0, size] per axis) and
/// the distance to each axis' next boundary from there; rebased at every crossing, so f32
/// holds the geometry to ~1e-7 of a cell whatever the scene size or the ray length.
#[derive(Default)]
#[repr(C, align(32))]
struct L32 {
    org: [[f32; 8]; 3],
    tmax: [[f32; 8]; 3],
    dir: [[f32; 8]; 3],
    delta: [[f32; 8]; 3],
    /// Entry coordinate when stepping into the next cell along an axis: 0 (d > 0) or size.
    face: [[f32; 8]; 3],
    cell: [[i32; 8]; 3],
    step: [[i32; 8]; 3],
    dlin: [[i32; 8]; 3],
    lin: [i32; 8],
    pw: [[f64; 8]; W],
    psum: [f64; 8],
    minr: [f64; 8],
    g: [f32; 8],
    slot: [usize; 8],
    act: u32,
    next: usize,
}

impl L32 {
    #[inline(always)]
    fn refill(&mut self, l: usize, q: &[Ray]) {
        let Some(r) = q.get(self.next) else {
            self.act &= !(1 << l);
            self.lin[l] = 0;
            return;
        };
        self.next += 1;
        let mut lin = 0i32;
        for a in 0..3 {
            let rel = r.p[a] / SIZE;
            let idx = rel.floor().clamp(0.0, NN[a] as f64 - 1.0);
            let up = r.d[a] > 0.0;
            let local = r.p[a] - idx * SIZE;
            let inv = 1.0 / r.d[a];
            let bb = if up { SIZE } else { 0.0 };
            self.org[a][l] = local as f32;
            self.dir[a][l] = r.d[a] as f32;
            self.tmax[a][l] = ((bb - local) * inv) as f32;
            self.delta[a][l] = (SIZE * inv.abs()) as f32;
            self.face[a][l] = if up { 0.0 } else { SIZE as f32 };
            self.cell[a][l] = idx as i32;
            self.step[a][l] = if up { 1 } else { -1 };
            self.dlin[a][l] = self.step[a][l] * STRIDE[a] as i32;
            lin += idx as i32 * STRIDE[a] as i32;
        }
        self.lin[l] = lin;
        self.act |= 1 << l;
        self.pw[0][l] = r.pw[0];
        self.pw[1][l] = r.pw[1];
        self.psum[l] = r.pw[0] + r.pw[1];
        self.minr[l] = r.min_ray;
        self.g[l] = G as f32;
        self.slot[l] = r.slot;
    }
}

/// (1 − e^{−x}, e^{−x}) in f32, table-free: series to x⁴ below 1/32, else 2^{−x log2 e}
/// with a degree-6 polynomial for 2^r, r ∈ [−½, ½]; returned promoted to f64 (lanes 0–3,
/// 4–7), the transmitted fraction as 1 − intercepted in f64 so that they sum to 1.
#[inline(always)]
unsafe fn atten32(x: __m256) -> ([__m256d; 2], [__m256d; 2], __m256) {
    let sp = |v: f32| _mm256_set1_ps(v);
    let mut f = _mm256_fnmadd_ps(x, sp(1.0 / 24.0), sp(1.0 / 6.0));
    f = _mm256_fnmadd_ps(x, f, sp(0.5));
    f = _mm256_fnmadd_ps(x, f, sp(1.0));
    f = _mm256_mul_ps(x, f);
    let xe = _mm256_min_ps(x, sp(87.0));
    let y = _mm256_mul_ps(xe, sp(-std::f32::consts::LOG2_E));
    let n = _mm256_round_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(y);
    let r = _mm256_sub_ps(y, n);
    let mut p = _mm256_fmadd_ps(r, sp(1.540_353e-4), sp(1.339_887e-3));
    p = _mm256_fmadd_ps(r, p, sp(9.618_437e-3));
    p = _mm256_fmadd_ps(r, p, sp(5.550_332e-2));
    p = _mm256_fmadd_ps(r, p, sp(2.402_264e-1));
    p = _mm256_fmadd_ps(r, p, sp(6.931_472e-1));
    p = _mm256_fmadd_ps(r, p, sp(1.0));
    let scale = _mm256_castsi256_ps(_mm256_slli_epi32::<23>(_mm256_add_epi32(
        _mm256_cvtps_epi32(n),
        _mm256_set1_epi32(127),
    )));
    let e = _mm256_mul_ps(p, scale);
    let small = _mm256_cmp_ps::<_CMP_LT_OQ>(x, sp(1.0 / 32.0));
    // Promote: the series value where small, e^{−x} elsewhere; the other as 1 − it in f64.
    let v = _mm256_blendv_ps(e, f, small);
    let one = _mm256_set1_pd(1.0);
    let lo = _mm256_cvtps_pd(_mm256_castps256_ps128(v));
    let hi = _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(v));
    let sm_lo = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(
        _mm256_castps_si256(small),
    )));
    let sm_hi = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_extracti128_si256::<1>(
        _mm256_castps_si256(small),
    )));
    let (clo, chi) = (_mm256_sub_pd(one, lo), _mm256_sub_pd(one, hi));
    (
        [
            _mm256_blendv_pd(clo, lo, sm_lo),
            _mm256_blendv_pd(chi, hi, sm_hi),
        ],
        [
            _mm256_blendv_pd(lo, clo, sm_lo),
            _mm256_blendv_pd(hi, chi, sm_hi),
        ],
        _mm256_blendv_ps(_mm256_sub_ps(sp(1.0), e), f, small),
    )
}

#[inline(always)]
unsafe fn transpose8(r: [__m256; 8]) -> [__m256; 8] {
    let t0 = _mm256_unpacklo_ps(r[0], r[1]);
    let t1 = _mm256_unpackhi_ps(r[0], r[1]);
    let t2 = _mm256_unpacklo_ps(r[2], r[3]);
    let t3 = _mm256_unpackhi_ps(r[2], r[3]);
    let t4 = _mm256_unpacklo_ps(r[4], r[5]);
    let t5 = _mm256_unpackhi_ps(r[4], r[5]);
    let t6 = _mm256_unpacklo_ps(r[6], r[7]);
    let t7 = _mm256_unpackhi_ps(r[6], r[7]);
    let s0 = _mm256_shuffle_ps::<0x44>(t0, t2);
    let s1 = _mm256_shuffle_ps::<0xEE>(t0, t2);
    let s2 = _mm256_shuffle_ps::<0x44>(t1, t3);
    let s3 = _mm256_shuffle_ps::<0xEE>(t1, t3);
    let s4 = _mm256_shuffle_ps::<0x44>(t4, t6);
    let s5 = _mm256_shuffle_ps::<0xEE>(t4, t6);
    let s6 = _mm256_shuffle_ps::<0x44>(t5, t7);
    let s7 = _mm256_shuffle_ps::<0xEE>(t5, t7);
    [
        _mm256_permute2f128_ps::<0x20>(s0, s4),
        _mm256_permute2f128_ps::<0x20>(s1, s5),
        _mm256_permute2f128_ps::<0x20>(s2, s6),
        _mm256_permute2f128_ps::<0x20>(s3, s7),
        _mm256_permute2f128_ps::<0x31>(s0, s4),
        _mm256_permute2f128_ps::<0x31>(s1, s5),
        _mm256_permute2f128_ps::<0x31>(s2, s6),
        _mm256_permute2f128_ps::<0x31>(s3, s7),
    ]
}

/// Half-barycentres s₁/ℓ, s₂/ℓ · ℓ in f32: per lane one 32-byte row of 8 coefficients
/// (plain loads, or one gather per coefficient with GATHER), 8 × 8 transpose, two Horners.
#[inline(always)]
unsafe fn hb32<const GATHER: bool>(tb: &Tables, x: __m256, ell: __m256) -> (__m256, __m256) {
    let sp = |v: f32| _mm256_set1_ps(v);
    let first = ((1.0f32 / 16384.0).to_bits() >> 18) as i32;
    let bits = _mm256_castps_si256(x);
    let bin = _mm256_and_si256(
        _mm256_sub_epi32(_mm256_srli_epi32::<18>(bits), _mm256_set1_epi32(first)),
        _mm256_set1_epi32(1023),
    );
    let start = _mm256_castsi256_ps(_mm256_and_si256(
        bits,
        _mm256_set1_epi32(!((1i32 << 18) - 1)),
    ));
    let t = _mm256_sub_ps(x, start);
    let c: [__m256; 8] = if GATHER {
        let base = tb.hb32.as_ptr() as *const f32;
        let off = _mm256_slli_epi32::<3>(bin);
        std::array::from_fn(|i| _mm256_i32gather_ps::<4>(base.add(i), off))
    } else {
        let mut ba = [0i32; 8];
        _mm256_storeu_si256(ba.as_mut_ptr() as *mut __m256i, bin);
        let rows: [__m256; 8] =
            std::array::from_fn(|l| _mm256_loadu_ps(tb.hb32[ba[l] as usize].as_ptr()));
        transpose8(rows)
    };
    let h = |c0, c1, c2, c3| {
        let p = _mm256_fmadd_ps(t, c3, c2);
        let p = _mm256_fmadd_ps(t, p, c1);
        _mm256_mul_ps(ell, _mm256_fmadd_ps(t, p, c0))
    };
    let a = h(c[0], c[2], c[4], c[6]);
    let b = h(c[1], c[3], c[5], c[7]);
    let l2 = std::f32::consts::LN_2;
    let u = _mm256_div_ps(ell, x);
    let big = _mm256_cmp_ps::<_CMP_GE_OQ>(x, sp(64.0));
    let a = _mm256_blendv_ps(a, _mm256_mul_ps(sp(1.0 - l2), u), big);
    let b = _mm256_blendv_ps(b, _mm256_mul_ps(sp(1.0 + l2), u), big);
    let small = _mm256_cmp_ps::<_CMP_LT_OQ>(x, sp(1.0 / 16384.0));
    let x12 = _mm256_mul_ps(x, sp(1.0 / 12.0));
    let sa = _mm256_mul_ps(ell, _mm256_sub_ps(sp(0.25), x12));
    let sb = _mm256_mul_ps(ell, _mm256_sub_ps(sp(0.75), x12));
    (
        _mm256_blendv_ps(a, sa, small),
        _mm256_blendv_ps(b, sb, small),
    )
}

#[inline(always)]
unsafe fn lo_hi(v: __m256) -> [__m256d; 2] {
    [
        _mm256_cvtps_pd(_mm256_castps256_ps128(v)),
        _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(v)),
    ]
}

#[target_feature(enable = "avx2,fma")]
#[inline(never)]
unsafe fn walk32<const GATHER: bool, const MODE: u8>(tb: &Tables, q: &[Ray], acc: &mut Acc) {
    let mut ln = L32::default();
    for l in 0..8 {
        ln.refill(l, q);
    }
    let sp = |v: f32| _mm256_set1_ps(v);
    let zero = sp(0.0);
    let mut n_cross = 0u64;
    let (tur, pts, flag, touched) = (&mut acc.tur, &mut acc.pts, &mut acc.flag, &mut acc.touched);
    let ld = |p: &[f32; 8]| _mm256_loadu_ps(p.as_ptr());
    let ldi = |p: &[i32; 8]| _mm256_loadu_si256(p.as_ptr() as *const __m256i);
    let mask8 = |b: u32| {
        let v = _mm256_set1_epi32(b as i32);
        let bitsel = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(v, bitsel), bitsel))
    };
    let ncell = (NX * NY * NZ) as u32;
    while ln.act != 0 {
        let mut dens = [0.0f32; 8];
        for l in 0..8 {
            dens[l] = if (ln.lin[l] as u32) < ncell {
                DENS as f32
            } else {
                0.0
            };
        }
        let dens = ld(&dens);
        let occ = _mm256_cmp_ps::<_CMP_GT_OQ>(dens, zero);
        let k = _mm256_mul_ps(ld(&ln.g), dens);
        let act = mask8(ln.act);
        let ell = _mm256_min_ps(
            ld(&ln.tmax[2]),
            _mm256_min_ps(ld(&ln.tmax[1]), ld(&ln.tmax[0])),
        );
        let hit_m = _mm256_and_ps(
            _mm256_and_ps(act, occ),
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GT_OQ>(ell, zero),
                _mm256_cmp_ps::<_CMP_GT_OQ>(k, zero),
            ),
        );
        let hit = _mm256_movemask_ps(hit_m) as u32;
        let x = _mm256_and_ps(hit_m, _mm256_mul_ps(k, ell));
        let (frac, tr, frac32) = atten32(x);
        let (s1, s2) = if MODE & 2 != 0 {
            (_mm256_mul_ps(ell, sp(0.25)), _mm256_mul_ps(ell, sp(0.75)))
        } else {
            hb32::<GATHER>(tb, x, ell)
        };
        let hm = [
            _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(
                _mm256_castps_si256(hit_m),
            ))),
            _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_extracti128_si256::<1>(
                _mm256_castps_si256(hit_m),
            ))),
        ];
        let mut wt = [_mm256_setzero_pd(); 2];
        let mut gain = [[0.0f64; 8]; W];
        for h in 0..2 {
            wt[h] = _mm256_mul_pd(_mm256_loadu_pd(ln.psum.as_ptr().add(4 * h)), frac[h]);
            for c in 0..W {
                let pwc = _mm256_loadu_pd(ln.pw[c].as_ptr().add(4 * h));
                _mm256_storeu_pd(gain[c].as_mut_ptr().add(4 * h), _mm256_mul_pd(pwc, frac[h]));
                _mm256_storeu_pd(
                    ln.pw[c].as_mut_ptr().add(4 * h),
                    _mm256_blendv_pd(pwc, _mm256_mul_pd(pwc, tr[h]), hm[h]),
                );
            }
        }
        if MODE & 8 != 0 {
            // Points and weights in f32: one 8 × 8 transpose, each lane's row promoted at the add.
            let ps32 = _mm256_insertf128_ps::<1>(
                _mm256_castps128_ps256(_mm256_cvtpd_ps(_mm256_loadu_pd(ln.psum.as_ptr()))),
                _mm256_cvtpd_ps(_mm256_loadu_pd(ln.psum.as_ptr().add(4))),
            );
            let w32 = _mm256_mul_ps(ps32, frac32);
            let p = |a: usize, s: __m256| {
                _mm256_mul_ps(_mm256_fmadd_ps(ld(&ln.dir[a]), s, ld(&ln.org[a])), w32)
            };
            let rows = transpose8([
                p(0, s1),
                p(1, s1),
                p(2, s1),
                p(0, s2),
                p(1, s2),
                p(2, s2),
                w32,
                zero,
            ]);
            for l in 0..8 {
                if hit & (1 << l) == 0 {
                    continue;
                }
                let e = ln.lin[l] as usize;
                if !flag[e] {
                    flag[e] = true;
                    touched.push(e as u32);
                }
                let s = (e * NS + ln.slot[l]) * W;
                let r: &mut [f64; W] = (&mut tur[s..s + W]).try_into().unwrap();
                for c in 0..W {
                    r[c] += gain[c][l];
                }
                let qq: &mut [f64; 8] = (&mut pts[e * 8..e * 8 + 8]).try_into().unwrap();
                let rl = rows[l];
                let a = _mm256_add_pd(
                    _mm256_loadu_pd(qq.as_ptr()),
                    _mm256_cvtps_pd(_mm256_castps256_ps128(rl)),
                );
                let b = _mm256_add_pd(
                    _mm256_loadu_pd(qq.as_ptr().add(4)),
                    _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(rl)),
                );
                _mm256_storeu_pd(qq.as_mut_ptr(), a);
                _mm256_storeu_pd(qq.as_mut_ptr().add(4), b);
            }
        } else {
            // Points in the cell frame (f32), promoted and weighted in f64.
            let p = |a: usize, s: __m256| lo_hi(_mm256_fmadd_ps(ld(&ln.dir[a]), s, ld(&ln.org[a])));
            let pt = [p(0, s1), p(1, s1), p(2, s1), p(0, s2), p(1, s2), p(2, s2)];
            let mut rows_a = [[0.0; 4]; 8];
            let mut rows_b = [[0.0; 4]; 8];
            for h in 0..2 {
                let m = |i: usize| _mm256_mul_pd(pt[i][h], wt[h]);
                let ra = transpose4([m(0), m(1), m(2), m(3)]);
                let rb = transpose4([m(4), m(5), wt[h], _mm256_setzero_pd()]);
                for l in 0..4 {
                    _mm256_storeu_pd(rows_a[4 * h + l].as_mut_ptr(), ra[l]);
                    _mm256_storeu_pd(rows_b[4 * h + l].as_mut_ptr(), rb[l]);
                }
            }
            for l in 0..8 {
                if hit & (1 << l) == 0 || MODE & 1 != 0 {
                    continue;
                }
                let e = ln.lin[l] as usize;
                if MODE & 4 == 0 && !flag[e] {
                    flag[e] = true;
                    touched.push(e as u32);
                }
                let s = (e * NS + ln.slot[l]) * W;
                let r: &mut [f64; W] = (&mut tur[s..s + W]).try_into().unwrap();
                for c in 0..W {
                    r[c] += gain[c][l];
                }
                let qq: &mut [f64; 7] = (&mut pts[e * 8..e * 8 + 7]).try_into().unwrap();
                for i in 0..4 {
                    qq[i] += rows_a[l][i];
                }
                for i in 0..3 {
                    qq[4 + i] += rows_b[l][i];
                }
            }
        }
        let mut dead = 0u32;
        for h in 0..2 {
            let ps = _mm256_add_pd(
                _mm256_loadu_pd(ln.pw[0].as_ptr().add(4 * h)),
                _mm256_loadu_pd(ln.pw[1].as_ptr().add(4 * h)),
            );
            _mm256_storeu_pd(ln.psum.as_mut_ptr().add(4 * h), ps);
            dead |= (_mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(
                ps,
                _mm256_loadu_pd(ln.minr.as_ptr().add(4 * h)),
            )) as u32)
                << (4 * h);
        }
        dead &= hit;
        let go = ln.act & !dead;
        let gom = _mm256_castps_si256(mask8(go));
        // Step in the cell frame: move to the exit point, the stepped axes enter the next
        // cell through their entry face; the others' distances shrink by ℓ.
        let mut outside = _mm256_setzero_si256();
        let mut lin = ldi(&ln.lin);
        for a in 0..3 {
            let tmax = ld(&ln.tmax[a]);
            let m = _mm256_and_si256(
                gom,
                _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OQ>(tmax, ell)),
            );
            let mf = _mm256_castsi256_ps(m);
            let o = _mm256_fmadd_ps(ld(&ln.dir[a]), ell, ld(&ln.org[a]));
            let o = _mm256_blendv_ps(o, ld(&ln.face[a]), mf);
            _mm256_storeu_ps(ln.org[a].as_mut_ptr(), o);
            let tn = _mm256_blendv_ps(_mm256_sub_ps(tmax, ell), ld(&ln.delta[a]), mf);
            _mm256_storeu_ps(ln.tmax[a].as_mut_ptr(), tn);
            let c = _mm256_add_epi32(ldi(&ln.cell[a]), _mm256_and_si256(m, ldi(&ln.step[a])));
            _mm256_storeu_si256(ln.cell[a].as_mut_ptr() as *mut __m256i, c);
            lin = _mm256_add_epi32(lin, _mm256_and_si256(m, ldi(&ln.dlin[a])));
            // Outside: c < 0 or c ≥ n (one signed compare of n − 1 − c … as two compares).
            let out_a = _mm256_or_si256(
                _mm256_cmpgt_epi32(_mm256_setzero_si256(), c),
                _mm256_cmpgt_epi32(c, _mm256_set1_epi32(NN[a] as i32 - 1)),
            );
            outside = _mm256_or_si256(outside, _mm256_and_si256(out_a, m));
        }
        // Lanes not in `go` (dead or parked) are refilled before their frame is read again.
        _mm256_storeu_si256(ln.lin.as_mut_ptr() as *mut __m256i, lin);
        n_cross += ln.act.count_ones() as u64;
        let mut out_b = go & _mm256_movemask_ps(_mm256_castsi256_ps(outside)) as u32;
        if out_b != 0 {
            let cz = ldi(&ln.cell[2]);
            let zout = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_or_si256(
                _mm256_cmpgt_epi32(_mm256_setzero_si256(), cz),
                _mm256_cmpgt_epi32(cz, _mm256_set1_epi32(NZ as i32 - 1)),
            ))) as u32;
            let side = out_b & !zout;
            if side != 0 {
                // Periodic sides in the cell frame: only the cell index and the linear index
                // move by one period.
                let sm = _mm256_castps_si256(mask8(side));
                let mut lin = ldi(&ln.lin);
                for a in 0..2 {
                    let c = ldi(&ln.cell[a]);
                    let n = NN[a] as i32;
                    let below = _mm256_and_si256(sm, _mm256_cmpgt_epi32(_mm256_setzero_si256(), c));
                    let above =
                        _mm256_and_si256(sm, _mm256_cmpgt_epi32(c, _mm256_set1_epi32(n - 1)));
                    let back = _mm256_sub_epi32(
                        _mm256_and_si256(below, _mm256_set1_epi32(n)),
                        _mm256_and_si256(above, _mm256_set1_epi32(n)),
                    );
                    _mm256_storeu_si256(
                        ln.cell[a].as_mut_ptr() as *mut __m256i,
                        _mm256_add_epi32(c, back),
                    );
                    lin = _mm256_add_epi32(
                        lin,
                        _mm256_mullo_epi32(back, _mm256_set1_epi32(STRIDE[a] as i32)),
                    );
                }
                _mm256_storeu_si256(ln.lin.as_mut_ptr() as *mut __m256i, lin);
                out_b &= !side;
            }
        }
        let ev = dead | out_b;
        if ev == 0 {
            continue;
        }
        for l in 0..8 {
            if ev & (1 << l) == 0 {
                continue;
            }
            let p = ln.pw[0][l] + ln.pw[1][l];
            if dead & (1 << l) != 0 {
                acc.lost += p;
            } else {
                acc.out += p;
            }
            ln.refill(l, q);
        }
    }
    acc.crossings += n_cross;
}

// ---------------------------------------------------------------- f32x16, cell-local frame (zmm)
/// `L32` on 16 lanes (AVX-512, session 20).
struct L32z {
    org: [[f32; 16]; 3],
    tmax: [[f32; 16]; 3],
    dir: [[f32; 16]; 3],
    delta: [[f32; 16]; 3],
    face: [[f32; 16]; 3],
    cell: [[i32; 16]; 3],
    step: [[i32; 16]; 3],
    dlin: [[i32; 16]; 3],
    lin: [i32; 16],
    pw: [[f64; 16]; W],
    psum: [f64; 16],
    minr: [f64; 16],
    g: [f32; 16],
    slot: [usize; 16],
    act: u32,
    next: usize,
}

impl Default for L32z {
    fn default() -> Self {
        L32z {
            org: [[0.0; 16]; 3],
            tmax: [[0.0; 16]; 3],
            dir: [[0.0; 16]; 3],
            delta: [[0.0; 16]; 3],
            face: [[0.0; 16]; 3],
            cell: [[0; 16]; 3],
            step: [[0; 16]; 3],
            dlin: [[0; 16]; 3],
            lin: [0; 16],
            pw: [[0.0; 16]; W],
            psum: [0.0; 16],
            minr: [0.0; 16],
            g: [0.0; 16],
            slot: [0; 16],
            act: 0,
            next: 0,
        }
    }
}

impl L32z {
    /// Same per-lane set-up as `L32::refill`.
    #[inline(always)]
    fn refill(&mut self, l: usize, q: &[Ray]) {
        let Some(r) = q.get(self.next) else {
            self.act &= !(1 << l);
            self.lin[l] = 0;
            return;
        };
        self.next += 1;
        let mut lin = 0i32;
        for a in 0..3 {
            let rel = r.p[a] / SIZE;
            let idx = rel.floor().clamp(0.0, NN[a] as f64 - 1.0);
            let up = r.d[a] > 0.0;
            let local = r.p[a] - idx * SIZE;
            let inv = 1.0 / r.d[a];
            let bb = if up { SIZE } else { 0.0 };
            self.org[a][l] = local as f32;
            self.dir[a][l] = r.d[a] as f32;
            self.tmax[a][l] = ((bb - local) * inv) as f32;
            self.delta[a][l] = (SIZE * inv.abs()) as f32;
            self.face[a][l] = if up { 0.0 } else { SIZE as f32 };
            self.cell[a][l] = idx as i32;
            self.step[a][l] = if up { 1 } else { -1 };
            self.dlin[a][l] = self.step[a][l] * STRIDE[a] as i32;
            lin += idx as i32 * STRIDE[a] as i32;
        }
        self.lin[l] = lin;
        self.act |= 1 << l;
        self.pw[0][l] = r.pw[0];
        self.pw[1][l] = r.pw[1];
        self.psum[l] = r.pw[0] + r.pw[1];
        self.minr[l] = r.min_ray;
        self.g[l] = G as f32;
        self.slot[l] = r.slot;
    }
}

/// 8 × 8 f32 transpose in each 256-bit half of 8 zmm registers at once: out[i] half h, lane j
/// = r[j] half h, element i.
#[inline(always)]
unsafe fn transpose8x2(r: [__m512; 8]) -> [__m512; 8] {
    let t0 = _mm512_unpacklo_ps(r[0], r[1]);
    let t1 = _mm512_unpackhi_ps(r[0], r[1]);
    let t2 = _mm512_unpacklo_ps(r[2], r[3]);
    let t3 = _mm512_unpackhi_ps(r[2], r[3]);
    let t4 = _mm512_unpacklo_ps(r[4], r[5]);
    let t5 = _mm512_unpackhi_ps(r[4], r[5]);
    let t6 = _mm512_unpacklo_ps(r[6], r[7]);
    let t7 = _mm512_unpackhi_ps(r[6], r[7]);
    let s0 = _mm512_shuffle_ps::<0x44>(t0, t2);
    let s1 = _mm512_shuffle_ps::<0xEE>(t0, t2);
    let s2 = _mm512_shuffle_ps::<0x44>(t1, t3);
    let s3 = _mm512_shuffle_ps::<0xEE>(t1, t3);
    let s4 = _mm512_shuffle_ps::<0x44>(t4, t6);
    let s5 = _mm512_shuffle_ps::<0xEE>(t4, t6);
    let s6 = _mm512_shuffle_ps::<0x44>(t5, t7);
    let s7 = _mm512_shuffle_ps::<0xEE>(t5, t7);
    // Per 256-bit half: (low 128 of a, low 128 of b) and (high of a, high of b).
    let lo = _mm512_setr_epi32(0, 1, 2, 3, 16, 17, 18, 19, 8, 9, 10, 11, 24, 25, 26, 27);
    let hi = _mm512_setr_epi32(4, 5, 6, 7, 20, 21, 22, 23, 12, 13, 14, 15, 28, 29, 30, 31);
    let p = |a, i, b| _mm512_permutex2var_ps(a, i, b);
    [
        p(s0, lo, s4),
        p(s1, lo, s5),
        p(s2, lo, s6),
        p(s3, lo, s7),
        p(s0, hi, s4),
        p(s1, hi, s5),
        p(s2, hi, s6),
        p(s3, hi, s7),
    ]
}

/// `atten32` on 16 lanes: (intercepted, transmitted) promoted to f64 (lanes 0–7, 8–15), the
/// second as 1 − the first where the series is used, and the intercepted fraction in f32.
#[inline(always)]
unsafe fn atten32z(x: __m512) -> ([__m512d; 2], [__m512d; 2], __m512) {
    let sp = |v: f32| _mm512_set1_ps(v);
    let mut f = _mm512_fnmadd_ps(x, sp(1.0 / 24.0), sp(1.0 / 6.0));
    f = _mm512_fnmadd_ps(x, f, sp(0.5));
    f = _mm512_fnmadd_ps(x, f, sp(1.0));
    f = _mm512_mul_ps(x, f);
    let xe = _mm512_min_ps(x, sp(87.0));
    let y = _mm512_mul_ps(xe, sp(-std::f32::consts::LOG2_E));
    let n = _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(y);
    let r = _mm512_sub_ps(y, n);
    let mut p = _mm512_fmadd_ps(r, sp(1.540_353e-4), sp(1.339_887e-3));
    p = _mm512_fmadd_ps(r, p, sp(9.618_437e-3));
    p = _mm512_fmadd_ps(r, p, sp(5.550_332e-2));
    p = _mm512_fmadd_ps(r, p, sp(2.402_264e-1));
    p = _mm512_fmadd_ps(r, p, sp(6.931_472e-1));
    p = _mm512_fmadd_ps(r, p, sp(1.0));
    let e = _mm512_scalef_ps(p, n);
    let small = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(x, sp(1.0 / 32.0));
    let v = _mm512_mask_blend_ps(small, e, f);
    let one = _mm512_set1_pd(1.0);
    let lo = _mm512_cvtps_pd(_mm512_castps512_ps256(v));
    let hi = _mm512_cvtps_pd(_mm512_extractf32x8_ps::<1>(v));
    let (sl, sh) = (small as u8, (small >> 8) as u8);
    let (clo, chi) = (_mm512_sub_pd(one, lo), _mm512_sub_pd(one, hi));
    (
        [_mm512_mask_blend_pd(sl, clo, lo), _mm512_mask_blend_pd(sh, chi, hi)],
        [_mm512_mask_blend_pd(sl, lo, clo), _mm512_mask_blend_pd(sh, hi, chi)],
        _mm512_mask_blend_ps(small, _mm512_sub_ps(sp(1.0), e), f),
    )
}

/// `hb32` on 16 lanes: rows loaded in pairs (lanes l and l + 8 in one zmm), one two-half
/// 8 × 8 transpose.
#[inline(always)]
unsafe fn hb32z(tb: &Tables, x: __m512, ell: __m512) -> (__m512, __m512) {
    let sp = |v: f32| _mm512_set1_ps(v);
    let first = ((1.0f32 / 16384.0).to_bits() >> 18) as i32;
    let bits = _mm512_castps_si512(x);
    let bin = _mm512_and_si512(
        _mm512_sub_epi32(_mm512_srli_epi32::<18>(bits), _mm512_set1_epi32(first)),
        _mm512_set1_epi32(1023),
    );
    let start = _mm512_castsi512_ps(_mm512_and_si512(
        bits,
        _mm512_set1_epi32(!((1i32 << 18) - 1)),
    ));
    let t = _mm512_sub_ps(x, start);
    let mut ba = [0i32; 16];
    _mm512_storeu_si512(ba.as_mut_ptr() as *mut __m512i, bin);
    let mut rows = [_mm512_setzero_ps(); 8];
    for l in 0..8 {
        let (a, b) = (ba[l] as usize, ba[l + 8] as usize);
        rows[l] = _mm512_insertf32x8::<1>(
            _mm512_castps256_ps512(_mm256_loadu_ps(tb.hb32[a].as_ptr())),
            _mm256_loadu_ps(tb.hb32[b].as_ptr()),
        );
    }
    let c = transpose8x2(rows);
    let h = |c0, c1, c2, c3| {
        let p = _mm512_fmadd_ps(t, c3, c2);
        let p = _mm512_fmadd_ps(t, p, c1);
        _mm512_mul_ps(ell, _mm512_fmadd_ps(t, p, c0))
    };
    let a = h(c[0], c[2], c[4], c[6]);
    let b = h(c[1], c[3], c[5], c[7]);
    let l2 = std::f32::consts::LN_2;
    let u = _mm512_div_ps(ell, x);
    let big = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(x, sp(64.0));
    let a = _mm512_mask_blend_ps(big, a, _mm512_mul_ps(sp(1.0 - l2), u));
    let b = _mm512_mask_blend_ps(big, b, _mm512_mul_ps(sp(1.0 + l2), u));
    let small = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(x, sp(1.0 / 16384.0));
    let x12 = _mm512_mul_ps(x, sp(1.0 / 12.0));
    let sa = _mm512_mul_ps(ell, _mm512_sub_ps(sp(0.25), x12));
    let sb = _mm512_mul_ps(ell, _mm512_sub_ps(sp(0.75), x12));
    (
        _mm512_mask_blend_ps(small, a, sa),
        _mm512_mask_blend_ps(small, b, sb),
    )
}

/// The f32 × 16 pass. MODE bit 1: no booking; bit 16: point sums in an f32 record (one 32-byte
/// read-modify-write per booking; otherwise promoted and added to the f64 record as `32p`).
#[target_feature(enable = "avx512f,avx512dq,avx512bw,avx512vl,avx2,fma")]
#[inline(never)]
unsafe fn walk32z<const MODE: u8>(tb: &Tables, q: &[Ray], acc: &mut Acc) {
    let mut ln = L32z::default();
    for l in 0..16 {
        ln.refill(l, q);
    }
    let sp = |v: f32| _mm512_set1_ps(v);
    let zero = sp(0.0);
    let mut n_cross = 0u64;
    let (tur, pts, flag, touched) = (&mut acc.tur, &mut acc.pts, &mut acc.flag, &mut acc.touched);
    let pts32 = &mut acc.pts32;
    let ld = |p: &[f32; 16]| _mm512_loadu_ps(p.as_ptr());
    let ldi = |p: &[i32; 16]| _mm512_loadu_si512(p.as_ptr() as *const __m512i);
    let ncell = (NX * NY * NZ) as u32;
    while ln.act != 0 {
        let mut dens = [0.0f32; 16];
        for l in 0..16 {
            dens[l] = if (ln.lin[l] as u32) < ncell {
                DENS as f32
            } else {
                0.0
            };
        }
        let dens = ld(&dens);
        let occ = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(dens, zero);
        let k = _mm512_mul_ps(ld(&ln.g), dens);
        let act = ln.act as __mmask16;
        let ell = _mm512_min_ps(
            ld(&ln.tmax[2]),
            _mm512_min_ps(ld(&ln.tmax[1]), ld(&ln.tmax[0])),
        );
        let hit_m = act
            & occ
            & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(ell, zero)
            & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(k, zero);
        let hit = hit_m as u32;
        let x = _mm512_maskz_mul_ps(hit_m, k, ell);
        let (frac, tr, frac32) = atten32z(x);
        let (s1, s2) = hb32z(tb, x, ell);
        let mut gain = [[0.0f64; 16]; W];
        for h in 0..2 {
            let hm = (hit_m >> (8 * h)) as u8;
            for c in 0..W {
                let pwc = _mm512_loadu_pd(ln.pw[c].as_ptr().add(8 * h));
                _mm512_storeu_pd(gain[c].as_mut_ptr().add(8 * h), _mm512_mul_pd(pwc, frac[h]));
                _mm512_storeu_pd(
                    ln.pw[c].as_mut_ptr().add(8 * h),
                    _mm512_mask_mul_pd(pwc, hm, pwc, tr[h]),
                );
            }
        }
        if MODE & 1 == 0 {
            let ps32 = _mm512_insertf32x8::<1>(
                _mm512_castps256_ps512(_mm512_cvtpd_ps(_mm512_loadu_pd(ln.psum.as_ptr()))),
                _mm512_cvtpd_ps(_mm512_loadu_pd(ln.psum.as_ptr().add(8))),
            );
            let w32 = _mm512_mul_ps(ps32, frac32);
            let p = |a: usize, s: __m512| {
                _mm512_mul_ps(_mm512_fmadd_ps(ld(&ln.dir[a]), s, ld(&ln.org[a])), w32)
            };
            let rv = transpose8x2([
                p(0, s1),
                p(1, s1),
                p(2, s1),
                p(0, s2),
                p(1, s2),
                p(2, s2),
                w32,
                zero,
            ]);
            for l in 0..16 {
                if hit & (1 << l) == 0 {
                    continue;
                }
                let rl = if l < 8 {
                    _mm512_castps512_ps256(rv[l])
                } else {
                    _mm512_extractf32x8_ps::<1>(rv[l - 8])
                };
                let e = ln.lin[l] as usize;
                if !flag[e] {
                    flag[e] = true;
                    touched.push(e as u32);
                }
                let s = (e * NS + ln.slot[l]) * W;
                let r: &mut [f64; W] = (&mut tur[s..s + W]).try_into().unwrap();
                for c in 0..W {
                    r[c] += gain[c][l];
                }
                if MODE & 16 != 0 {
                    let qq: &mut [f32; 8] = (&mut pts32[e * 8..e * 8 + 8]).try_into().unwrap();
                    _mm256_storeu_ps(qq.as_mut_ptr(), _mm256_add_ps(_mm256_loadu_ps(qq.as_ptr()), rl));
                } else {
                    let qq: &mut [f64; 8] = (&mut pts[e * 8..e * 8 + 8]).try_into().unwrap();
                    let v = _mm512_add_pd(_mm512_loadu_pd(qq.as_ptr()), _mm512_cvtps_pd(rl));
                    _mm512_storeu_pd(qq.as_mut_ptr(), v);
                }
            }
        }
        let mut dead = 0u32;
        for h in 0..2 {
            let ps = _mm512_add_pd(
                _mm512_loadu_pd(ln.pw[0].as_ptr().add(8 * h)),
                _mm512_loadu_pd(ln.pw[1].as_ptr().add(8 * h)),
            );
            _mm512_storeu_pd(ln.psum.as_mut_ptr().add(8 * h), ps);
            dead |= (_mm512_cmp_pd_mask::<_CMP_LT_OQ>(ps, _mm512_loadu_pd(ln.minr.as_ptr().add(8 * h)))
                as u32)
                << (8 * h);
        }
        dead &= hit;
        let go = ln.act & !dead;
        let gom = go as __mmask16;
        let mut outside: __mmask16 = 0;
        let mut lin = ldi(&ln.lin);
        for a in 0..3 {
            let tmax = ld(&ln.tmax[a]);
            let m = gom & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(tmax, ell);
            let o = _mm512_fmadd_ps(ld(&ln.dir[a]), ell, ld(&ln.org[a]));
            let o = _mm512_mask_blend_ps(m, o, ld(&ln.face[a]));
            _mm512_storeu_ps(ln.org[a].as_mut_ptr(), o);
            let tn = _mm512_mask_blend_ps(m, _mm512_sub_ps(tmax, ell), ld(&ln.delta[a]));
            _mm512_storeu_ps(ln.tmax[a].as_mut_ptr(), tn);
            let c0 = ldi(&ln.cell[a]);
            let c = _mm512_mask_add_epi32(c0, m, c0, ldi(&ln.step[a]));
            _mm512_storeu_si512(ln.cell[a].as_mut_ptr() as *mut __m512i, c);
            lin = _mm512_mask_add_epi32(lin, m, lin, ldi(&ln.dlin[a]));
            let inside = _mm512_cmplt_epu32_mask(c, _mm512_set1_epi32(NN[a] as i32));
            outside |= m & !inside;
        }
        _mm512_storeu_si512(ln.lin.as_mut_ptr() as *mut __m512i, lin);
        n_cross += ln.act.count_ones() as u64;
        let mut out_b = go & outside as u32;
        if out_b != 0 {
            let cz = ldi(&ln.cell[2]);
            let zout = _mm512_cmpge_epu32_mask(cz, _mm512_set1_epi32(NZ as i32)) as u32;
            let side = out_b & !zout;
            if side != 0 {
                let sm = side as __mmask16;
                let mut lin = ldi(&ln.lin);
                for a in 0..2 {
                    let c = ldi(&ln.cell[a]);
                    let n = NN[a] as i32;
                    let below = sm & _mm512_cmplt_epi32_mask(c, _mm512_setzero_si512());
                    let above = sm & _mm512_cmpgt_epi32_mask(c, _mm512_set1_epi32(n - 1));
                    let back = _mm512_mask_mov_epi32(
                        _mm512_maskz_mov_epi32(above, _mm512_set1_epi32(-n)),
                        below,
                        _mm512_set1_epi32(n),
                    );
                    _mm512_storeu_si512(
                        ln.cell[a].as_mut_ptr() as *mut __m512i,
                        _mm512_add_epi32(c, back),
                    );
                    lin = _mm512_add_epi32(
                        lin,
                        _mm512_mullo_epi32(back, _mm512_set1_epi32(STRIDE[a] as i32)),
                    );
                }
                _mm512_storeu_si512(ln.lin.as_mut_ptr() as *mut __m512i, lin);
                out_b &= !side;
            }
        }
        let ev = dead | out_b;
        if ev == 0 {
            continue;
        }
        for l in 0..16 {
            if ev & (1 << l) == 0 {
                continue;
            }
            let p = ln.pw[0][l] + ln.pw[1][l];
            if dead & (1 << l) != 0 {
                acc.lost += p;
            } else {
                acc.out += p;
            }
            ln.refill(l, q);
        }
    }
    acc.crossings += n_cross;
}

fn main() {
    let which = std::env::args().nth(1).unwrap_or("64".into());
    let n: usize = std::env::args()
        .nth(2)
        .map_or(200_000, |s| s.parse().unwrap());
    let tb = Tables::new();
    let q = rays(n);
    let mut acc = Acc::new();
    let cpu = || -> f64 {
        let s = std::fs::read_to_string("/proc/thread-self/schedstat").unwrap();
        s.split_whitespace().next().unwrap().parse::<f64>().unwrap() * 1e-9
    };
    let t0 = cpu();
    unsafe {
        match which.as_str() {
            "64" => walk64::<false, 0>(&tb, &q, &mut acc),
            "64g" => walk64::<true, 0>(&tb, &q, &mut acc),
            "64nb" => walk64::<false, 1>(&tb, &q, &mut acc),
            "64nh" => walk64::<false, 2>(&tb, &q, &mut acc),
            "64nbh" => walk64::<false, 3>(&tb, &q, &mut acc),
            "64nf" => walk64::<false, 4>(&tb, &q, &mut acc),
            "64z" => walk64z::<0>(&tb, &q, &mut acc),
            "64z-nb" => walk64z::<1>(&tb, &q, &mut acc),
            "64zv" => walk64z::<2>(&tb, &q, &mut acc),
            "32nf" => walk32::<false, 4>(&tb, &q, &mut acc),
            "32p" => walk32::<false, 8>(&tb, &q, &mut acc),
            "32nb" => walk32::<false, 1>(&tb, &q, &mut acc),
            "32nh" => walk32::<false, 2>(&tb, &q, &mut acc),
            "32nbh" => walk32::<false, 3>(&tb, &q, &mut acc),
            "32" => walk32::<false, 0>(&tb, &q, &mut acc),
            "32g" => walk32::<true, 0>(&tb, &q, &mut acc),
            "32z" => walk32z::<0>(&tb, &q, &mut acc),
            "32z-nb" => walk32z::<1>(&tb, &q, &mut acc),
            "32zr" => walk32z::<16>(&tb, &q, &mut acc),
            _ => panic!(),
        }
    }
    let dt = cpu() - t0;
    let tur: f64 = acc.tur.iter().sum();
    let w: f64 = acc.pts.iter().skip(6).step_by(7).sum::<f64>()
        + acc.pts32.iter().skip(6).step_by(8).map(|&v| v as f64).sum::<f64>();
    println!(
        "{which}: {} crossings ({:.2}/ray), {:.1} Mcross/s, intercepted {:.6}, out {:.6}, lost {:.6}, closure {:.3e}, wt {:.6}",
        acc.crossings,
        acc.crossings as f64 / n as f64,
        acc.crossings as f64 / dt / 1e6,
        tur,
        acc.out,
        acc.lost,
        (tur + acc.out + acc.lost) / (0.8 * n as f64) - 1.0,
        w
    );
}
