//! Lane-wise operations of the batched walk (`walk::batch`, [`super::dda::DdaL`],
//! [`super::fastmath::attenuation_l`], [`super::fastmath::HalfBarycentres::eval_l`]) on `L`
//! f64 lanes: 4 lanes in AVX2 + FMA registers ([`V3`], x86-64 CPUs since 2013–2015) or 8 in
//! AVX-512 registers ([`V4`]). Each operation is the one IEEE operation per lane that the
//! scalar walk does (no fused multiply-add, no reassociation), so a ray walked in either lane
//! width gives the same bits as the one-ray walk; only the number of rays in flight changes,
//! and with it the order in which the rays' contributions are summed (8-lane and 4-lane
//! products differ in the last bits, ~1e-15 relative; `--isa avx2` runs 4 lanes everywhere).
//! `pulp` runtime detection, no unsafe code.
//!
//! Measured on the 2-core Zen 4 host (turbid layer, Default preset, 100 directions, 0.2 m
//! cells, medians of alternating runs): 8 lanes 61 Mcross/s/core against 55 for 4 lanes in
//! AVX2 registers on the same CPU. The 8 lanes pay only with 8 × 8 transposes in registers
//! ([`transpose8`]: the booking rows and the half-barycentre coefficients) and no vector load of
//! values just stored lane by lane (store-to-load forwarding fails and the load waits for the
//! stores to retire); 8 lanes as two AVX2 halves run 40 (spills in 16 registers), so AVX2
//! CPUs walk 4.

use super::fastmath::EXP2_32;
use pulp::{b8, cast, f64x4, f64x8, m64x4, u64x4, u64x8, x86::V3, x86::V4};

/// `L` f64 lanes and their masks (see the module doc). `F`: L doubles, `U`: L 64-bit integers
/// (two's complement where signed), `M`: a mask with one bit per lane.
pub trait Lanes<const L: usize>: Copy {
    /// L doubles.
    type F: Copy;
    /// L 64-bit integers.
    type U: Copy;
    /// One bit per lane.
    type M: Copy;
    /// The AVX2 token (the per-ray parts run on the three axes in one 4-lane vector).
    fn v3(self) -> V3;
    /// Lanes from an array.
    fn ld(self, a: [f64; L]) -> Self::F;
    /// Lanes to an array.
    fn st(self, a: Self::F) -> [f64; L];
    /// Integer lanes from an array.
    fn ld_u(self, a: [u64; L]) -> Self::U;
    /// Integer lanes to an array.
    fn st_u(self, a: Self::U) -> [u64; L];
    /// `v` in every lane.
    fn splat(self, v: f64) -> Self::F;
    /// `v` in every integer lane.
    fn splat_u(self, v: u64) -> Self::U;
    /// `a + b`.
    fn add(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a − b`.
    fn sub(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a · b`.
    fn mul(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a / b`.
    fn div(self, a: Self::F, b: Self::F) -> Self::F;
    /// `if a < b { a } else { b }` (`vminpd`).
    fn min(self, a: Self::F, b: Self::F) -> Self::F;
    /// `if a > b { a } else { b }` (`vmaxpd`).
    fn max(self, a: Self::F, b: Self::F) -> Self::F;
    /// Bitwise `a ^ b`.
    fn xor(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a > b` (false for NaN).
    fn gt(self, a: Self::F, b: Self::F) -> Self::M;
    /// `a < b` (false for NaN).
    fn lt(self, a: Self::F, b: Self::F) -> Self::M;
    /// `a <= b` (false for NaN).
    fn le(self, a: Self::F, b: Self::F) -> Self::M;
    /// `a >= b` (false for NaN).
    fn ge(self, a: Self::F, b: Self::F) -> Self::M;
    /// `a == b`.
    fn eq(self, a: Self::F, b: Self::F) -> Self::M;
    /// `!(a < b)` (true for NaN).
    fn nlt(self, a: Self::F, b: Self::F) -> Self::M;
    /// Per lane, `if m { a } else { b }`.
    fn sel(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F;
    /// Per integer lane, `if m { a } else { b }`.
    fn sel_u(self, m: Self::M, a: Self::U, b: Self::U) -> Self::U;
    /// `a & b` of masks.
    fn and(self, a: Self::M, b: Self::M) -> Self::M;
    /// `a | b` of masks.
    fn or(self, a: Self::M, b: Self::M) -> Self::M;
    /// `!a & b` of masks.
    fn andnot(self, a: Self::M, b: Self::M) -> Self::M;
    /// The mask as bits (bit l: lane l).
    fn bits(self, m: Self::M) -> u32;
    /// Bits (bit l: lane l) as a mask.
    fn mask(self, bits: u32) -> Self::M;
    /// Wrapping `a + b`.
    fn add_u(self, a: Self::U, b: Self::U) -> Self::U;
    /// Wrapping `a − b`.
    fn sub_u(self, a: Self::U, b: Self::U) -> Self::U;
    /// Bitwise `a & b`.
    fn and_u(self, a: Self::U, b: Self::U) -> Self::U;
    /// Unsigned `a > b`.
    fn gt_u(self, a: Self::U, b: Self::U) -> Self::M;
    /// Logical `a >> 5`.
    fn shr5(self, a: Self::U) -> Self::U;
    /// `2^{j/32}` with j = the low 5 bits of each lane of `k` (`fastmath::EXP2_32`).
    fn exp2_32(self, k: Self::U) -> Self::F;
    /// Logical `a >> 47` (`52 −` the half-barycentre table's mantissa bits).
    fn shr47(self, a: Self::U) -> Self::U;
    /// `a << 52`.
    fn shl52(self, a: Self::U) -> Self::U;
    /// The doubles' bits.
    fn f_bits(self, a: Self::F) -> Self::U;
    /// Bits as doubles.
    fn f_from_bits(self, a: Self::U) -> Self::F;
    /// The eight coefficients of each lane's row as eight vectors, split as the first of
    /// each pair and the second ([`super::fastmath::HalfBarycentres`]'s cubic pieces `ca`,
    /// `cb`): `ca[k]` lane l = `rows[l][2k]`, `cb[k]` lane l = `rows[l][2k + 1]`.
    fn pair_columns(self, rows: [&[f64; 8]; L]) -> ([Self::F; 4], [Self::F; 4]);
    /// The seven vectors `v` as one row per lane (`row[l][i]` = lane l of `v[i]`, element 7
    /// zero).
    fn rows7(self, v: [Self::F; 7]) -> [[f64; 8]; L];
}

/// The one-line operations of a [`Lanes`] impl, each forwarded to the token's own method: the
/// `(F, F) → F`, `(F, F) → M`, `(U, U) → U` and `U → U` ones, the selects, and the conversions
/// between lanes and arrays (`pulp::cast`).
macro_rules! forward {
    (
        ff_f: [$($ff:ident => $fff:ident),*],
        ff_m: [$($fm:ident => $ffm:ident),*],
        uu_u: [$($uu:ident => $fuu:ident),*],
        u_u: [$($u1:ident => $fu1:expr),*],
        sel: $sel:ident, sel_u: $sel_u:ident, gt_u: $gt_u:ident,
        splat: $splat:ident, splat_u: $splat_u:ident, n: $n:literal
    ) => {
        $(
            #[inline(always)]
            fn $ff(self, a: Self::F, b: Self::F) -> Self::F {
                self.$fff(a, b)
            }
        )*
        $(
            #[inline(always)]
            fn $fm(self, a: Self::F, b: Self::F) -> Self::M {
                self.$ffm(a, b)
            }
        )*
        $(
            #[inline(always)]
            fn $uu(self, a: Self::U, b: Self::U) -> Self::U {
                self.$fuu(a, b)
            }
        )*
        $(
            #[inline(always)]
            fn $u1(self, a: Self::U) -> Self::U {
                $fu1(self, a)
            }
        )*
        #[inline(always)]
        fn sel(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F {
            self.$sel(m, a, b)
        }
        #[inline(always)]
        fn sel_u(self, m: Self::M, a: Self::U, b: Self::U) -> Self::U {
            self.$sel_u(m, a, b)
        }
        #[inline(always)]
        fn gt_u(self, a: Self::U, b: Self::U) -> Self::M {
            self.$gt_u(a, b)
        }
        #[inline(always)]
        fn splat(self, v: f64) -> Self::F {
            self.$splat(v)
        }
        #[inline(always)]
        fn splat_u(self, v: u64) -> Self::U {
            self.$splat_u(v)
        }
        #[inline(always)]
        fn ld(self, a: [f64; $n]) -> Self::F {
            cast(a)
        }
        #[inline(always)]
        fn st(self, a: Self::F) -> [f64; $n] {
            cast(a)
        }
        #[inline(always)]
        fn ld_u(self, a: [u64; $n]) -> Self::U {
            cast(a)
        }
        #[inline(always)]
        fn st_u(self, a: Self::U) -> [u64; $n] {
            cast(a)
        }
        #[inline(always)]
        fn f_bits(self, a: Self::F) -> Self::U {
            cast(a)
        }
        #[inline(always)]
        fn f_from_bits(self, a: Self::U) -> Self::F {
            cast(a)
        }
    };
}

impl Lanes<4> for V3 {
    type F = f64x4;
    type U = u64x4;
    type M = m64x4;
    forward! {
        ff_f: [add => add_f64x4, sub => sub_f64x4, mul => mul_f64x4, div => div_f64x4,
               min => min_f64x4, max => max_f64x4, xor => xor_f64x4],
        ff_m: [gt => cmp_gt_f64x4, lt => cmp_lt_f64x4, le => cmp_le_f64x4, ge => cmp_ge_f64x4,
               eq => cmp_eq_f64x4, nlt => cmp_not_lt_f64x4],
        uu_u: [add_u => wrapping_add_u64x4, sub_u => wrapping_sub_u64x4, and_u => and_u64x4],
        u_u: [shr5 => |s: V3, a| s.shr_const_u64x4::<5>(a),
              shr47 => |s: V3, a| s.shr_const_u64x4::<47>(a),
              shl52 => |s: V3, a| s.shl_const_u64x4::<52>(a)],
        sel: select_f64x4, sel_u: select_u64x4, gt_u: cmp_gt_u64x4,
        splat: splat_f64x4, splat_u: splat_u64x4, n: 4
    }
    #[inline(always)]
    fn v3(self) -> V3 {
        self
    }
    #[inline(always)]
    fn exp2_32(self, k: u64x4) -> f64x4 {
        let ka: [u64; 4] = cast(k);
        cast(ka.map(|j| EXP2_32[(j & 31) as usize]))
    }
    #[inline(always)]
    fn and(self, a: m64x4, b: m64x4) -> m64x4 {
        self.and_m64x4(a, b)
    }
    #[inline(always)]
    fn or(self, a: m64x4, b: m64x4) -> m64x4 {
        self.or_m64x4(a, b)
    }
    #[inline(always)]
    fn andnot(self, a: m64x4, b: m64x4) -> m64x4 {
        self.andnot_m64x4(a, b)
    }
    #[inline(always)]
    fn bits(self, m: m64x4) -> u32 {
        self.avx._mm256_movemask_pd(cast(m)) as u32
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> m64x4 {
        // One table row per 4-bit mask.
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
        cast(MASKS[(bits & 15) as usize])
    }
    #[inline(always)]
    fn pair_columns(self, rows: [&[f64; 8]; 4]) -> ([f64x4; 4], [f64x4; 4]) {
        // Pair k (cₖ₁, cₖ₂) of lane l's row as one 128-bit value.
        let pair = |l: usize, k: usize| -> core::arch::x86_64::__m128d {
            cast([rows[l][2 * k], rows[l][2 * k + 1]])
        };
        let avx = self.avx;
        let mut ca = [self.splat_f64x4(0.0); 4];
        let mut cb = [self.splat_f64x4(0.0); 4];
        for k in 0..4 {
            // [pair of lane 0, pair of lane 2] and [lane 1, lane 3]: their low elements
            // interleaved are cₖ₁ of lanes 0..3, their high elements cₖ₂.
            let a = avx._mm256_setr_m128d(pair(0, k), pair(2, k));
            let b = avx._mm256_setr_m128d(pair(1, k), pair(3, k));
            ca[k] = cast(avx._mm256_unpacklo_pd(a, b));
            cb[k] = cast(avx._mm256_unpackhi_pd(a, b));
        }
        (ca, cb)
    }
    #[inline(always)]
    fn rows7(self, v: [f64x4; 7]) -> [[f64; 8]; 4] {
        let zero = self.splat_f64x4(0.0);
        let a: [[f64; 4]; 4] = transpose4(self, [v[0], v[1], v[2], v[3]]).map(cast);
        let b: [[f64; 4]; 4] = transpose4(self, [v[4], v[5], v[6], zero]).map(cast);
        std::array::from_fn(|l| {
            [
                a[l][0], a[l][1], a[l][2], a[l][3], b[l][0], b[l][1], b[l][2], 0.0,
            ]
        })
    }
}

/// The 4 × 4 transpose of four vectors (8 shuffles): element i of output j is element j of
/// input i.
#[inline(always)]
pub fn transpose4(simd: V3, r: [f64x4; 4]) -> [f64x4; 4] {
    let avx = simd.avx;
    let a01 = avx._mm256_unpacklo_pd(cast(r[0]), cast(r[1]));
    let a23 = avx._mm256_unpacklo_pd(cast(r[2]), cast(r[3]));
    let b01 = avx._mm256_unpackhi_pd(cast(r[0]), cast(r[1]));
    let b23 = avx._mm256_unpackhi_pd(cast(r[2]), cast(r[3]));
    [
        cast(avx._mm256_permute2f128_pd::<0x20>(a01, a23)),
        cast(avx._mm256_permute2f128_pd::<0x20>(b01, b23)),
        cast(avx._mm256_permute2f128_pd::<0x31>(a01, a23)),
        cast(avx._mm256_permute2f128_pd::<0x31>(b01, b23)),
    ]
}

/// The 8 × 8 transpose of eight vectors (24 shuffles): element i of output j is element j of
/// input i. Unpacks within 128-bit pairs, then two stages of 128-bit shuffles (`vshuff64x2`,
/// imm 0x88: pairs 0 and 2 of each input; 0xDD: pairs 1 and 3).
#[inline(always)]
pub fn transpose8(simd: V4, r: [f64x8; 8]) -> [f64x8; 8] {
    let f = simd.avx512f;
    let r: [core::arch::x86_64::__m512d; 8] = r.map(cast);
    // t[2i] = lo(r[2i], r[2i+1]), t[2i+1] = hi(r[2i], r[2i+1]).
    let t: [core::arch::x86_64::__m512d; 8] = std::array::from_fn(|i| {
        let (a, b) = (r[2 * (i / 2)], r[2 * (i / 2) + 1]);
        if i % 2 == 0 {
            f._mm512_unpacklo_pd(a, b)
        } else {
            f._mm512_unpackhi_pd(a, b)
        }
    });
    let u = [
        f._mm512_shuffle_f64x2::<0x88>(t[0], t[2]),
        f._mm512_shuffle_f64x2::<0xDD>(t[0], t[2]),
        f._mm512_shuffle_f64x2::<0x88>(t[1], t[3]),
        f._mm512_shuffle_f64x2::<0xDD>(t[1], t[3]),
        f._mm512_shuffle_f64x2::<0x88>(t[4], t[6]),
        f._mm512_shuffle_f64x2::<0xDD>(t[4], t[6]),
        f._mm512_shuffle_f64x2::<0x88>(t[5], t[7]),
        f._mm512_shuffle_f64x2::<0xDD>(t[5], t[7]),
    ];
    [
        cast(f._mm512_shuffle_f64x2::<0x88>(u[0], u[4])),
        cast(f._mm512_shuffle_f64x2::<0x88>(u[2], u[6])),
        cast(f._mm512_shuffle_f64x2::<0x88>(u[1], u[5])),
        cast(f._mm512_shuffle_f64x2::<0x88>(u[3], u[7])),
        cast(f._mm512_shuffle_f64x2::<0xDD>(u[0], u[4])),
        cast(f._mm512_shuffle_f64x2::<0xDD>(u[2], u[6])),
        cast(f._mm512_shuffle_f64x2::<0xDD>(u[1], u[5])),
        cast(f._mm512_shuffle_f64x2::<0xDD>(u[3], u[7])),
    ]
}

impl Lanes<8> for V4 {
    type F = f64x8;
    type U = u64x8;
    type M = b8;
    forward! {
        ff_f: [add => add_f64x8, sub => sub_f64x8, mul => mul_f64x8, div => div_f64x8,
               min => min_f64x8, max => max_f64x8],
        ff_m: [gt => cmp_gt_f64x8, lt => cmp_lt_f64x8, le => cmp_le_f64x8, ge => cmp_ge_f64x8,
               eq => cmp_eq_f64x8, nlt => cmp_not_lt_f64x8],
        uu_u: [add_u => wrapping_add_u64x8, sub_u => wrapping_sub_u64x8, and_u => and_u64x8],
        u_u: [shr5 => |s: V4, a| s.shr_const_u64x8::<5>(a),
              shr47 => |s: V4, a| s.shr_const_u64x8::<47>(a),
              shl52 => |s: V4, a| s.shl_const_u64x8::<52>(a)],
        sel: select_f64x8, sel_u: select_u64x8, gt_u: cmp_gt_u64x8,
        splat: splat_f64x8, splat_u: splat_u64x8, n: 8
    }
    #[inline(always)]
    fn v3(self) -> V3 {
        *self
    }
    #[inline(always)]
    fn exp2_32(self, k: u64x8) -> f64x8 {
        // Two two-register permutes (bits 0–3 of each index pick one of 16 entries, higher
        // bits ignored), then bit 4 picks the half.
        let f = self.avx512f;
        let part = |o: usize| -> core::arch::x86_64::__m512d {
            cast::<[f64; 8], _>(std::array::from_fn(|i| EXP2_32[o + i]))
        };
        let idx: core::arch::x86_64::__m512i = cast(k);
        let t0 = f._mm512_permutex2var_pd(part(0), idx, part(8));
        let t1 = f._mm512_permutex2var_pd(part(16), idx, part(24));
        let upper = f._mm512_test_epi64_mask(idx, cast(self.splat_u64x8(16)));
        self.select_f64x8(b8(upper), cast(t1), cast(t0))
    }
    #[inline(always)]
    fn xor(self, a: f64x8, b: f64x8) -> f64x8 {
        cast(self.xor_u64x8(cast(a), cast(b)))
    }
    #[inline(always)]
    fn and(self, a: b8, b: b8) -> b8 {
        b8(a.0 & b.0)
    }
    #[inline(always)]
    fn or(self, a: b8, b: b8) -> b8 {
        b8(a.0 | b.0)
    }
    #[inline(always)]
    fn andnot(self, a: b8, b: b8) -> b8 {
        b8(!a.0 & b.0)
    }
    #[inline(always)]
    fn bits(self, m: b8) -> u32 {
        m.0 as u32
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> b8 {
        b8(bits as u8)
    }
    #[inline(always)]
    fn pair_columns(self, rows: [&[f64; 8]; 8]) -> ([f64x8; 4], [f64x8; 4]) {
        // One 64-byte row per lane, transposed: column k is coefficient k of every lane.
        let c = transpose8(self, rows.map(|r| cast(*r)));
        (
            std::array::from_fn(|k| c[2 * k]),
            std::array::from_fn(|k| c[2 * k + 1]),
        )
    }
    #[inline(always)]
    fn rows7(self, v: [f64x8; 7]) -> [[f64; 8]; 8] {
        let zero = self.splat_f64x8(0.0);
        transpose8(
            self,
            std::array::from_fn(|i| if i < 7 { v[i] } else { zero }),
        )
        .map(cast)
    }
}
