//! Inline elementary functions of the flux-tracking kernel (one of each per cell crossing):
//! [`exp`] (table-driven, ≤ 2 ulp from `f64::exp`), the attenuation pair
//! [`attenuation`] `(1 − e^{−x}, e^{−x})`, and the tabulated interception points
//! [`HalfBarycentres`] (physics.md §3.6). They exist because the libm calls (`exp_m1`,
//! `ln`) were a third of the kernel's instructions; each is tested against the libm form.
#[cfg(target_arch = "x86_64")]
use super::lanes::Lanes;

/// `2^{j/128}`, j = 0..127, correctly rounded (computed with 60-digit decimals).
const EXP2_TABLE: [f64; 128] = [
    1.0,
    1.0054299011128027,
    1.0108892860517005,
    1.016378314910953,
    1.0218971486541166,
    1.0274459491187637,
    1.0330248790212284,
    1.0386341019613787,
    1.0442737824274138,
    1.0499440858006872,
    1.0556451783605572,
    1.061377227289262,
    1.0671404006768237,
    1.0729348675259756,
    1.0787607977571199,
    1.0846183622133092,
    1.0905077326652577,
    1.0964290818163769,
    1.102382583307841,
    1.1083684117236787,
    1.1143867425958924,
    1.1204377524096067,
    1.1265216186082418,
    1.1326385195987192,
    1.1387886347566916,
    1.1449721444318042,
    1.1511892299529827,
    1.1574400736337511,
    1.1637248587775775,
    1.1700437696832502,
    1.1763969916502812,
    1.182784710984341,
    1.189207115002721,
    1.1956643920398273,
    1.202156731452703,
    1.2086843236265816,
    1.215247359980469,
    1.2218460329727576,
    1.22848053610687,
    1.2351510639369334,
    1.241857812073484,
    1.2486009771892048,
    1.255380757024691,
    1.2621973503942507,
    1.2690509571917332,
    1.275941778396392,
    1.2828700160787783,
    1.2898358734066657,
    1.2968395546510096,
    1.3038812651919358,
    1.3109612115247644,
    1.318079601266064,
    1.3252366431597413,
    1.3324325470831615,
    1.339667524053303,
    1.3469417862329458,
    1.3542555469368927,
    1.3616090206382248,
    1.3690024229745905,
    1.3764359707545302,
    1.383909881963832,
    1.3914243757719262,
    1.3989796725383112,
    1.4065759938190154,
    std::f64::consts::SQRT_2,
    1.4218926021691656,
    1.42961333839197,
    1.4373759974489824,
    1.4451808069770467,
    1.4530279958490526,
    1.460917794180647,
    1.4688504333369818,
    1.4768261459394993,
    1.4848451658727524,
    1.4929077282912648,
    1.5010140696264256,
    1.5091644275934228,
    1.5173590411982147,
    1.5255981507445384,
    1.533881997840956,
    1.5422108254079407,
    1.550584877685,
    1.559004400237837,
    1.567469639965553,
    1.5759808451078865,
    1.5845382652524937,
    1.593142151342267,
    1.6017927556826934,
    1.6104903319492543,
    1.6192351351948637,
    1.6280274218573478,
    1.6368674497669644,
    1.645755478153965,
    1.6546917676561943,
    1.6636765803267364,
    1.6727101796415966,
    1.681792830507429,
    1.6909247992693053,
    1.7001063537185235,
    1.709337763100463,
    1.718619298122478,
    1.7279512309618377,
    1.7373338352737062,
    1.746767386199169,
    1.7562521603732995,
    1.7657884359332727,
    1.7753764925265212,
    1.785016611318935,
    1.7947090750031072,
    1.804454167806624,
    1.8142521755003989,
    1.8241033854070534,
    1.8340080864093424,
    1.843966568958626,
    1.8539791250833855,
    1.864046048397789,
    1.8741676341103,
    1.8843441790323345,
    1.8945759815869656,
    1.9048633418176741,
    1.9152065613971474,
    1.925605943636125,
    1.9360617934922943,
    1.9465744175792332,
    1.9571441241754002,
    1.9677712232331759,
    1.978456026387951,
    1.9891988469672663,
];

/// `2^{j/32}`, j = 0..31: every fourth entry of [`EXP2_TABLE`] (`2^{4j/128}`), so correctly
/// rounded. 32 entries fit two 512-bit registers: the 8-lane walk reads them with one
/// two-register permute (`vpermt2pd`) instead of eight scalar loads.
pub(super) const EXP2_32: [f64; 32] = {
    let mut t = [0.0; 32];
    let mut j = 0;
    while j < 32 {
        t[j] = EXP2_TABLE[4 * j];
        j += 1;
    }
    t
};

/// `32/ln 2` (`128/ln 2` divided by 4: exact).
const INV_LN2_N: f64 = 184.6649652337873 / 4.0;
/// `ln 2 / 32` split (`ln 2 / 128`'s split times 4: exact): `LN2_N_HI` has its 32 low mantissa
/// bits cleared, so `k · LN2_N_HI` is exact for |k| < 2²¹ (x ∈ (−708, 709) gives |k| < 2¹⁵).
const LN2_N_HI: f64 = 0.005415208637714386 * 4.0;
const LN2_N_LO: f64 = 3.710410186743494e-09 * 4.0;
/// `1.5 · 2⁵²`: adding it rounds a |z| < 2⁵¹ to the nearest integer, held in the low bits.
const SHIFT: f64 = 6755399441055744.0;

/// `e^x`, within 2 ulp of `f64::exp` (unit test over [−745, 709] and the special values).
///
/// Tang's table method (Tang 1989, ACM TOMS 15(2) 144–157): `x = (32 m + j) ln2/32 + r`
/// with |r| ≤ ln2/64, `e^x = 2^m · 2^{j/32} · e^r`, `e^r − 1` by its degree-6 Taylor
/// polynomial (truncation < 4e-18). Outside (−708, 709) (subnormal or infinite results,
/// NaN) it defers to `f64::exp`.
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    if !(x > -708.0 && x < 709.0) {
        return x.exp();
    }
    exp_normal(x)
}

/// [`exp`] for x ∈ (−708, 709) (normal results), without the range check.
#[inline(always)]
fn exp_normal(x: f64) -> f64 {
    let (t, p, scale) = exp_parts(x);
    (t + t * p) * scale
}

/// Tang's reduction of x ∈ (−708, 709) (see [`exp`]): `(2^{j/32}, e^r − 1, 2^m)`, so that
/// `e^x = (2^{j/32} + 2^{j/32} (e^r − 1)) 2^m`.
#[inline(always)]
fn exp_parts(x: f64) -> (f64, f64, f64) {
    let z = x * INV_LN2_N;
    let shifted = z + SHIFT;
    let kf = shifted - SHIFT;
    let k = (shifted.to_bits() as i64).wrapping_sub(SHIFT.to_bits() as i64);
    let r = (x - kf * LN2_N_HI) - kf * LN2_N_LO;
    let p = r + r
        * r
        * (0.5 + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0)))));
    let t = EXP2_32[(k & 31) as usize];
    let m = k >> 5;
    // 2^m is a normal number for m in [−1022, 1023] (here m ∈ [−1022, 1023]).
    let scale = f64::from_bits(((m + 1023) as u64) << 52);
    (t, p, scale)
}

/// Attenuation over an optical path x = kℓ ≥ 0: `(1 − e^{−x}, e^{−x})` (intercepted and
/// transmitted fractions), from one reduction of [`exp`] (Tang 1989): with
/// `e^{−x} = T (1 + p)`, `T = 2^{j/32} 2^m` and `p = e^r − 1`, the transmitted fraction is
/// [`exp`]'s `(2^{j/32} + 2^{j/32} p) 2^m` and the intercepted one `(1 − T) − T p`. For
/// x < ln 2/64 (T = 1) that is `−p`, the polynomial itself: no cancellation (relative
/// truncation < 4e-16); above, `1 − T` is exact while T ≥ 1/2 (Sterbenz) and the error is
/// T's rounding (half an ulp) over 1 − e^{−x} ≥ 0.0108: relative error < 2e-14.
/// `f64::exp` from x = 708 (e^{−x} subnormal). The two always sum to 1 within one
/// rounding, so the tracked energy closes per crossing.
#[inline(always)]
pub fn attenuation(x: f64) -> (f64, f64) {
    if x < 708.0 {
        let (t, p, scale) = exp_parts(-x);
        let tt = t * scale;
        ((1.0 - tt) - tt * p, (t + t * p) * scale)
    } else {
        let e = (-x).exp();
        (1.0 - e, e)
    }
}

/// [`attenuation`] of L optical paths at once (4 lanes in AVX2, 8 in AVX-512; see
/// [`super::lanes`]), the same bits per lane: `exp_parts`'s operations lane-wise (the table
/// read by [`Lanes::exp2_32`], `2^m` built from the exponent bits), no branch on x; only
/// lanes with x ≥ 708 (`f64::exp`, e^{−x} subnormal) take the scalar form.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub fn attenuation_l<S: Lanes<L>, const L: usize>(s: S, x: S::F) -> (S::F, S::F) {
    let sp = |v: f64| s.splat(v);
    let (add, sub, mul) = (|a, b| s.add(a, b), |a, b| s.sub(a, b), |a, b| s.mul(a, b));
    // exp_parts of −x (lanes with x ≥ 708 computed at 0 and replaced below).
    let xe = s.sel(s.lt(x, sp(708.0)), x, sp(0.0));
    let y = s.xor(xe, sp(-0.0));
    let z = mul(y, sp(INV_LN2_N));
    let shifted = add(z, sp(SHIFT));
    let kf = sub(shifted, sp(SHIFT));
    let k = s.sub_u(s.f_bits(shifted), s.splat_u(SHIFT.to_bits()));
    let r = sub(sub(y, mul(kf, sp(LN2_N_HI))), mul(kf, sp(LN2_N_LO)));
    let mut p = add(sp(1.0 / 120.0), mul(r, sp(1.0 / 720.0)));
    p = add(sp(1.0 / 24.0), mul(r, p));
    p = add(sp(1.0 / 6.0), mul(r, p));
    p = add(sp(0.5), mul(r, p));
    p = add(r, mul(mul(r, r), p));
    let t = s.exp2_32(k);
    // 2^m with m = k >> 5 (arithmetic): k ≥ −708·32/ln 2 − 1 > −1023·32 for x < 708, so the
    // logical shift of k + 1023·32 gives m + 1023.
    let biased = s.add_u(k, s.splat_u(1023 << 5));
    let scale = s.f_from_bits(s.shl52(s.shr5(biased)));
    let mut tr = mul(add(t, mul(t, p)), scale);
    let tt = mul(t, scale);
    let mut frac = sub(sub(sp(1.0), tt), mul(tt, p));
    if s.bits(s.nlt(x, sp(708.0))) != 0 {
        let xa = s.st(x);
        let mut fa = s.st(frac);
        let mut ta = s.st(tr);
        for l in 0..L {
            if !(xa[l] < 708.0) {
                (fa[l], ta[l]) = attenuation(xa[l]);
            }
        }
        frac = s.ld(fa);
        tr = s.ld(ta);
    }
    (frac, tr)
}

/// Mantissa bits of x that index [`HalfBarycentres`]: 2⁵ = 32 bins per octave.
const HB_BITS: u32 = 5;
/// Tabulated range of x = kℓ: [2⁻¹⁴, 2⁶).
const HB_X0: f64 = 1.0 / 16384.0;
const HB_X1: f64 = 64.0;
/// Number of bins: 20 octaves × 2^HB_BITS.
const HB_N: usize = 20 << HB_BITS;
/// Bins allocated: [`HB_N`] rounded up to a power of two, so that the index is masked instead
/// of bound-checked in the hot path (the padding bins are never read).
pub(crate) const HB_ALLOC: usize = HB_N.next_power_of_two();

/// Cubic pieces of the relative interception points `s₁/ℓ`, `s₂/ℓ` of
/// [`super::engine::half_barycentres`] as functions of x = kℓ, one per bin of x: the bins are
/// the top `HB_BITS` mantissa bits of x within each octave of [2⁻¹⁴, 2⁶) (640 bins,
/// 64 bytes each), so the bin index is a shift of x's bits (no logarithm). Each piece
/// interpolates the closed form at the 4 Chebyshev nodes of its bin, in the offset from the
/// bin's start.
pub struct HalfBarycentres {
    /// Per bin: the s₁/ℓ and s₂/ℓ coefficients interleaved, `[c0₁, c0₂, c1₁, c1₂, …]`, so
    /// that the two Horner evaluations run as one on pairs (no shuffles).
    bins: Box<[[f64; 8]; HB_ALLOC]>,
}

impl HalfBarycentres {
    /// The shared table (built once, 40 KiB).
    pub fn get() -> &'static Self {
        static TABLE: std::sync::OnceLock<HalfBarycentres> = std::sync::OnceLock::new();
        TABLE.get_or_init(Self::build)
    }

    fn build() -> Self {
        let first = HB_X0.to_bits() >> (52 - HB_BITS);
        let last = HB_X1.to_bits() >> (52 - HB_BITS);
        let mut bins: Vec<[f64; 8]> = (first..last)
            .map(|b| {
                let x_lo = f64::from_bits(b << (52 - HB_BITS));
                let x_hi = f64::from_bits((b + 1) << (52 - HB_BITS));
                let h = x_hi - x_lo;
                let nodes: [f64; 4] = std::array::from_fn(|i| {
                    0.5 * h * (1.0 - ((2 * i + 1) as f64 * std::f64::consts::PI / 8.0).cos())
                });
                let mut out = [0.0; 8];
                for half in 0..2 {
                    let ys: [f64; 4] = std::array::from_fn(|i| {
                        let (a, b) = super::engine::half_barycentres(x_lo + nodes[i], 1.0);
                        if half == 0 { a } else { b }
                    });
                    for (i, c) in cubic_through(&nodes, &ys).into_iter().enumerate() {
                        out[2 * i + half] = c;
                    }
                }
                out
            })
            .collect();
        bins.resize(HB_ALLOC, [0.0; 8]);
        Self {
            bins: bins
                .into_boxed_slice()
                .try_into()
                .expect("20 octaves of bins, padded"),
        }
    }

    /// The coefficient rows in single precision, and the shift and first bin of an f32 x:
    /// row `((x.to_bits() >> 18) − first) & (len − 1)` is the piece of x ∈ [2⁻¹⁴, 64) (an f32
    /// keeps the same 5 leading mantissa bits as the f64 of the same value, so the bins are
    /// the same pieces), evaluated at `t = x − (x with its low 18 bits cleared)`.
    /// Also the range of the pieces, [2⁻¹⁴, 64) (below: the series, above: the dense limit).
    /// (A table of its own, 20 KiB, built once on first use.)
    pub fn rows32() -> (&'static [[f32; 8]; HB_ALLOC], u32, (f32, f32)) {
        const { assert!(23 - HB_BITS == 18) };
        static TABLE: std::sync::OnceLock<Box<[[f32; 8]; HB_ALLOC]>> = std::sync::OnceLock::new();
        let rows = TABLE.get_or_init(|| {
            let t = Self::get();
            let v: Vec<[f32; 8]> = t.bins.iter().map(|r| r.map(|c| c as f32)).collect();
            v.into_boxed_slice()
                .try_into()
                .expect("20 octaves of bins, padded")
        });
        (
            rows,
            (HB_X0 as f32).to_bits() >> 18,
            (HB_X0 as f32, HB_X1 as f32),
        )
    }

    /// Single-precision polynomials of s₁/ℓ and s₂/ℓ for optical depths x ∈ [0, 1) (the
    /// common case: a cell's optical depth), `[c₀₁, c₀₂, c₁₁, c₁₂, …]` for
    /// `c₀ + x (c₁ + … + x c₅)`: degree 5 through the closed form
    /// ([`super::engine::half_barycentres`]) at 6 Chebyshev nodes of [0, 1] (interpolation
    /// error ≤ 1.1e-8, below f32 resolution; unit test `hb_poly32_matches_the_closed_form`).
    pub fn poly32() -> &'static [f32; 2 * (HB_POLY_DEG + 1)] {
        static COEF: std::sync::OnceLock<[f32; 2 * (HB_POLY_DEG + 1)]> = std::sync::OnceLock::new();
        COEF.get_or_init(|| {
            const N: usize = HB_POLY_DEG + 1;
            let nodes: [f64; N] = std::array::from_fn(|i| {
                0.5 * (1.0 - ((2 * i + 1) as f64 * std::f64::consts::PI / (2 * N) as f64).cos())
            });
            let mut out = [0.0f32; 2 * N];
            for half in 0..2 {
                let ys: [f64; N] = std::array::from_fn(|i| {
                    let (a, b) = super::engine::half_barycentres(nodes[i], 1.0);
                    if half == 0 { a } else { b }
                });
                for (i, c) in poly_through(&nodes, &ys).into_iter().enumerate() {
                    out[2 * i + half] = c as f32;
                }
            }
            out
        })
    }

    /// [`HalfBarycentres::poly32`] evaluated for one segment (x < 1, ℓ in m): the operations
    /// of the 16-lane walk (fused multiply-adds), so the same bits.
    pub fn eval_poly32(x: f32, ell: f32) -> (f32, f32) {
        let c = Self::poly32();
        let (mut a, mut b) = (c[2 * HB_POLY_DEG], c[2 * HB_POLY_DEG + 1]);
        for i in (0..HB_POLY_DEG).rev() {
            a = a.mul_add(x, c[2 * i]);
            b = b.mul_add(x, c[2 * i + 1]);
        }
        (ell * a, ell * b)
    }

    /// Distances from the segment entry (m) of the barycentres of the first and second halves
    /// of the energy intercepted along a segment of length ℓ (m) and optical depth x = kℓ:
    /// the series `ℓ(1/4 − x/12)`, `ℓ(3/4 − x/12)` below 2⁻¹⁴, the dense limit
    /// `ℓ(1 ∓ ln 2)/x` from 64, the cubic pieces between (within 1e-8 ℓ of the closed form,
    /// unit test).
    #[inline(always)]
    pub fn eval(&self, x: f64, ell: f64) -> (f64, f64) {
        if x < HB_X0 {
            return (ell * (0.25 - x / 12.0), ell * (0.75 - x / 12.0));
        }
        if x >= HB_X1 {
            let l2 = std::f64::consts::LN_2;
            let u = ell / x;
            return ((1.0 - l2) * u, (1.0 + l2) * u);
        }
        let bits = x.to_bits();
        let first = HB_X0.to_bits() >> (52 - HB_BITS);
        // x ∈ [2⁻¹⁴, 2⁶): the index is below HB_N; the mask only spares the bound check.
        let c = &self.bins[((bits >> (52 - HB_BITS)) - first) as usize & (HB_ALLOC - 1)];
        let t = x - f64::from_bits(bits & !((1u64 << (52 - HB_BITS)) - 1));
        (
            ell * (c[0] + t * (c[2] + t * (c[4] + t * c[6]))),
            ell * (c[1] + t * (c[3] + t * (c[5] + t * c[7]))),
        )
    }

    /// [`HalfBarycentres::eval`] of L segments at once (4 lanes in AVX2, 8 in AVX-512; see
    /// [`super::lanes`]), the same bits per lane: the three forms (series, cubic piece, dense
    /// limit) are computed on every lane and the result selected (no branch on x; the bin
    /// index is masked into the table for any x). The bins' coefficient rows are read as
    /// 128-bit pairs (cₖ₁, cₖ₂) and unpacked into one vector per coefficient
    /// ([`Lanes::pair_columns`]), so the two Horner evaluations run lane-wise (the same
    /// operations in the same order as [`HalfBarycentres::eval`]). Only the lanes of `live` are
    /// guaranteed: the series and dense-limit forms (two divisions and their selects) are
    /// computed only when a live lane needs them (x < 2⁻¹⁴ or x ≥ 64, rare in the
    /// flux-tracking walk); the other lanes may then hold the cubic piece of an x outside its
    /// range.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub fn eval_l<S: Lanes<L>, const L: usize>(
        &self,
        s: S,
        x: S::F,
        ell: S::F,
        live: S::M,
    ) -> (S::F, S::F) {
        const { assert!(52 - HB_BITS == 47) };
        let first = HB_X0.to_bits() >> (52 - HB_BITS);
        let bits = s.f_bits(x);
        let bin: [u64; L] = s.st_u(s.and_u(
            s.sub_u(s.shr47(bits), s.splat_u(first)),
            s.splat_u(HB_ALLOC as u64 - 1),
        ));
        // t = x − (x with its low 52 − HB_BITS mantissa bits cleared): the offset in the bin.
        let start = s.f_from_bits(s.and_u(bits, s.splat_u(!((1u64 << (52 - HB_BITS)) - 1))));
        let t = s.sub(x, start);
        let rows: [&[f64; 8]; L] = std::array::from_fn(|l| &self.bins[bin[l] as usize]);
        let (ca, cb) = s.pair_columns(rows);
        let a = horner(s, ell, t, ca);
        let b = horner(s, ell, t, cb);
        let sp = |v: f64| s.splat(v);
        let big = s.ge(x, sp(HB_X1));
        let small = s.lt(x, sp(HB_X0));
        let odd = s.and(live, s.or(big, small));
        if s.bits(odd) == 0 {
            return (a, b);
        }
        let l2 = std::f64::consts::LN_2;
        let u = s.div(ell, x);
        let a = s.sel(big, s.mul(sp(1.0 - l2), u), a);
        let b = s.sel(big, s.mul(sp(1.0 + l2), u), b);
        let x12 = s.div(x, sp(12.0));
        let sa = s.mul(ell, s.sub(sp(0.25), x12));
        let sb = s.mul(ell, s.sub(sp(0.75), x12));
        (s.sel(small, sa, a), s.sel(small, sb, b))
    }
}

/// `ℓ (c0 + t (c1 + t (c2 + t c3)))` lane-wise (the operations of [`HalfBarycentres::eval`]).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn horner<S: Lanes<L>, const L: usize>(s: S, ell: S::F, t: S::F, c: [S::F; 4]) -> S::F {
    let p = s.add(c[2], s.mul(t, c[3]));
    let p = s.add(c[1], s.mul(t, p));
    s.mul(ell, s.add(c[0], s.mul(t, p)))
}

/// Degree of [`HalfBarycentres::poly32`].
pub const HB_POLY_DEG: usize = 5;

/// Monomial coefficients of the polynomial of degree n − 1 through the n points (t_i, y_i)
/// (Newton divided differences, expanded).
fn poly_through<const N: usize>(t: &[f64; N], y: &[f64; N]) -> [f64; N] {
    let mut d = *y;
    for j in 1..N {
        for i in (j..N).rev() {
            d[i] = (d[i] - d[i - 1]) / (t[i] - t[i - j]);
        }
    }
    // p(t) = d0 + (t − t0)(d1 + (t − t1)(… + (t − t_{n−2}) d_{n−1})), expanded by Horner.
    let mut c = [0.0; N];
    c[0] = d[N - 1];
    for i in (0..N - 1).rev() {
        // c ← c · (t − t_i) + d_i
        for k in (1..N).rev() {
            c[k] = c[k - 1] - t[i] * c[k];
        }
        c[0] = d[i] - t[i] * c[0];
    }
    c
}

/// Monomial coefficients `c0 + c1 t + c2 t² + c3 t³` of the cubic through (t_i, y_i) (Newton
/// divided differences, expanded).
fn cubic_through(t: &[f64; 4], y: &[f64; 4]) -> [f64; 4] {
    let mut d = *y;
    for j in 1..4 {
        for i in (j..4).rev() {
            d[i] = (d[i] - d[i - 1]) / (t[i] - t[i - j]);
        }
    }
    // p(t) = d0 + (t − t0)(d1 + (t − t1)(d2 + (t − t2) d3)), expanded by Horner on polynomials.
    let mut c = [d[3], 0.0, 0.0, 0.0];
    for i in (0..3).rev() {
        // c ← c · (t − t_i) + d_i
        let mut n = [0.0; 4];
        for k in 0..4 {
            if k + 1 < 4 {
                n[k + 1] += c[k];
            }
            n[k] -= c[k] * t[i];
        }
        n[0] += d[i];
        c = n;
    }
    c
}

#[cfg(test)]
mod tests {
    /// The single-precision polynomials of the half-barycentres against the closed form on
    /// [0, 1): within 2e-7 ℓ (f32 resolution of values in [0, 1] is 6e-8; interpolation error
    /// ≤ 1.1e-8).
    #[test]
    fn hb_poly32_matches_the_closed_form() {
        let mut worst = 0f64;
        for i in 0..=2000 {
            let x = if i == 0 {
                1e-9
            } else {
                i as f64 / 2000.0 * 0.999_999
            };
            let (a, b) = crate::radiative::engine::half_barycentres(x, 1.0);
            let (p, q) = super::HalfBarycentres::eval_poly32(x as f32, 1.0);
            worst = worst.max((p as f64 - a).abs()).max((q as f64 - b).abs());
        }
        println!("worst |s - s_poly32| / ell = {worst:.2e}");
        assert!(worst <= 2e-7, "{worst:e}");
    }

    use super::*;

    /// Distance in units in the last place between two finite positive doubles.
    fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    #[test]
    fn exp_is_within_two_ulp_of_libm_over_the_whole_range() {
        // Dense sweep of [−745, 709.78] plus random arguments, tiny arguments and the edges.
        let mut worst = 0;
        let mut check = |x: f64| {
            let (a, b) = (exp(x), x.exp());
            if b == 0.0 || b.is_infinite() || a == 0.0 {
                assert_eq!(a, b, "exp({x:e})");
                return;
            }
            let u = ulps(a, b);
            assert!(u <= 2, "exp({x:e}) = {a:e}, libm {b:e}: {u} ulp");
            worst = worst.max(u);
        };
        let n = 2_000_000;
        for i in 0..=n {
            check(-745.2 + (709.78 + 745.2) * i as f64 / n as f64);
        }
        // Where the optical depths live: [0, 50] finely.
        for i in 0..=n {
            check(-50.0 * i as f64 / n as f64);
        }
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..1_000_000 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            check(-745.0 + 1454.0 * (s >> 11) as f64 / (1u64 << 53) as f64);
        }
        for x in [
            0.0, -0.0, 1e-300, -1e-300, 5e-324, -5e-324, 1e-17, -1e-17, 1e-9, -1e-9, 0.0027,
            -0.0027, 1.0, -1.0, 708.0, -708.0, 709.0, -709.0, 709.7, 710.0, -744.0, -745.2, -746.0,
            -1e300, 1e300,
        ] {
            check(x);
        }
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-0.0), 1.0);
        assert_eq!(exp(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp(f64::INFINITY), f64::INFINITY);
        assert!(exp(f64::NAN).is_nan());
        assert!(worst <= 2, "worst {worst} ulp");
    }

    /// The lane-wise forms of the batched walk give the scalar forms' bits on every lane, on a
    /// dense sweep of x over [0, 800] (0, tiny, 2⁻¹⁴ and 1/32 and 64 and 708 ± 1 ulp, the
    /// table's bin edges) with unequal segment lengths per lane: 4 lanes (AVX2) and, where the
    /// CPU has AVX-512, 8.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn lane_forms_are_bit_identical_to_the_scalar_forms() {
        // A CPU without the set says so (the test did not run there), not a silent pass.
        match pulp::x86::V3::try_new() {
            Some(simd) => lane_forms_match::<_, 4>(simd),
            None => eprintln!("skipped: CPU lacks AVX2 (4 lanes)"),
        }
        match pulp::x86::V4::try_new() {
            Some(simd) => lane_forms_match::<_, 8>(simd),
            None => eprintln!("skipped: CPU lacks AVX-512 (8 lanes)"),
        }
    }

    #[cfg(target_arch = "x86_64")]
    fn lane_forms_match<S: Lanes<L>, const L: usize>(s: S) {
        let mut xs = vec![
            0.0,
            1e-300,
            1e-20,
            1e-9,
            1.0 / 16384.0,
            1.0 / 32.0,
            64.0,
            700.0,
        ];
        xs.extend([708.0, 709.0, 745.0, 800.0, f64::MIN_POSITIVE]);
        for x in xs.clone() {
            xs.push(f64::from_bits(x.to_bits() + 1));
            if x > 0.0 {
                xs.push(f64::from_bits(x.to_bits() - 1));
            }
        }
        xs.extend((0..200_000).map(|i| 1e-6 * (8e8f64).powf(i as f64 / 199_999.0)));
        while xs.len() % L != 0 {
            xs.push(0.5);
        }
        let hb = HalfBarycentres::get();
        let lens = [0.2, 0.7, 1.0, 0.013, 3.0, 0.05, 0.41, 1e-3];
        for (n, c) in xs.chunks(L).enumerate() {
            let x: [f64; L] = std::array::from_fn(|l| c[l]);
            let ell: [f64; L] = std::array::from_fn(|l| lens[l] + n as f64 * 1e-6);
            let (f, t) = attenuation_l(s, s.ld(x));
            let (f, t) = (s.st(f), s.st(t));
            // Every lane live, and a mask cycling through the subsets (the rare forms' branch
            // taken and skipped): the live lanes must be the scalar bits.
            let live_bits = (n % (1 << L)) as u32;
            let (s1, s2) = hb.eval_l(s, s.ld(x), s.ld(ell), s.mask(u32::MAX));
            let (s1, s2) = (s.st(s1), s.st(s2));
            let (p1, p2) = hb.eval_l(s, s.ld(x), s.ld(ell), s.mask(live_bits));
            let (p1, p2) = (s.st(p1), s.st(p2));
            for l in 0..L {
                let (fs, ts) = attenuation(x[l]);
                assert_eq!(
                    (f[l].to_bits(), t[l].to_bits()),
                    (fs.to_bits(), ts.to_bits()),
                    "x {} ({L} lanes)",
                    x[l]
                );
                let (a, b) = hb.eval(x[l], ell[l]);
                assert_eq!(
                    (s1[l].to_bits(), s2[l].to_bits()),
                    (a.to_bits(), b.to_bits()),
                    "x {} ({L} lanes)",
                    x[l]
                );
                if live_bits >> l & 1 == 1 {
                    assert_eq!(
                        (p1[l].to_bits(), p2[l].to_bits()),
                        (a.to_bits(), b.to_bits()),
                        "x {} (lane {l} of live mask {live_bits:b})",
                        x[l]
                    );
                }
            }
        }
    }

    #[test]
    fn attenuation_matches_expm1_and_sums_to_one() {
        let mut worst_f: f64 = 0.0;
        for i in 0..=200_000 {
            // x from 1e-12 to 800, log-spaced, and exactly 0.
            let x = if i == 0 {
                0.0
            } else {
                1e-12 * (8e14f64).powf(i as f64 / 200_000.0)
            };
            let (f, t) = attenuation(x);
            let f_ref = -(-x).exp_m1();
            let t_ref = (-x).exp();
            if f_ref > 0.0 {
                worst_f = worst_f.max((f / f_ref - 1.0).abs());
            } else {
                assert_eq!(f, 0.0);
            }
            assert!(
                (t - t_ref).abs() <= 4.0 * f64::EPSILON * t_ref.max(1e-300) + 1e-300
                    || (t - t_ref).abs() <= 2.0 * f64::EPSILON,
                "x {x:e}: {t:e} vs {t_ref:e}"
            );
            assert!(
                (f + t - 1.0).abs() <= f64::EPSILON,
                "x {x:e}: f + t = {}",
                f + t
            );
            assert!((0.0..=1.0).contains(&f) && (0.0..=1.0).contains(&t));
        }
        eprintln!("attenuation: worst relative error of 1 − e^−x {worst_f:.2e}");
        assert!(
            worst_f < 2e-14,
            "worst relative error of 1 − e^−x: {worst_f:e}"
        );
        assert_eq!(attenuation(0.0), (0.0, 1.0));
        assert_eq!(attenuation(f64::INFINITY), (1.0, 0.0));
    }

    #[test]
    fn tabulated_half_barycentres_match_the_closed_form() {
        let tab = HalfBarycentres::get();
        let mut worst: f64 = 0.0;
        for i in 0..200_000 {
            let x = 1e-6 * (1e8f64).powf(i as f64 / 199_999.0);
            let (a, b) = super::super::engine::half_barycentres(x, 1.0);
            let (c, d) = tab.eval(x, 1.0);
            worst = worst.max((a - c).abs()).max((b - d).abs());
        }
        assert!(worst < 1e-8, "worst |Δs|/ℓ = {worst:e}");
        // Bin edges, the range ends and a zero-length segment.
        for x in [HB_X0, HB_X1, 1.0, 2.0, 0.5, 63.999_999] {
            let (a, b) = super::super::engine::half_barycentres(x / 0.3, 0.3);
            let (c, d) = tab.eval(x, 0.3);
            assert!(
                (a - c).abs() < 3e-9 && (b - d).abs() < 3e-9,
                "x {x}: {a} {b} vs {c} {d}"
            );
        }
        assert_eq!(tab.eval(0.0, 0.0), (0.0, 0.0));
    }
}
