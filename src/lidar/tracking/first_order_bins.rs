//! The expected-value first-order return of a vegetation segment of a LiDAR first flight,
//! stratified by digitiser bin (DART 5 paper §4; physics.md §9.2, §9.6), and the waveform
//! binner as the photon engine's receiver tally.

use crate::lidar::waveform::WaveformBinner;
use crate::photon::engine::tally::ReturnTally;
use crate::photon::sampling::Uniform01;
use rand_xoshiro::Xoshiro256PlusPlus;

/// Most strata of one vegetation segment in [`bin_first_order`] (a 1 m cell spans ~7 bins of
/// 1 ns; longer segments group consecutive bins per stratum).
pub(crate) const MAX_FIRST_ORDER_STRATA: f64 = 32.0;

/// Largest ratio h/l0 (one digitiser bin h, m, over the segment start's distance from the
/// receiver l0, m) for which [`bin_first_order`] estimates single-bin strata by
/// [`inv_sq_mean`] instead of a random point. Every such stratum `[a, b]` then has
/// `w/R ≤ h/l0 < 1e-3` (`w = b − a ≤ h`, `R = l0 + μ ≥ l0`), where the terms that
/// [`inv_sq_mean`] drops are below 5.4e-11 of the stratum's value. ALS at 1000 m with 1 ns
/// bins: h/l0 ≈ 1.5e-4; TLS at a few metres (≈ 0.05) keeps the random point.
pub(crate) const FIRST_ORDER_MOMENT_RATIO: f64 = 1e-3;

/// Mean offset from `a` and variance, m and m², of the truncated exponential density
/// `∝ e^{−αu}` on a stratum `[a, a + w]` (`α > 0` m⁻¹, `ia = 1/α` m, `w > 0` m), given
/// `em = e^{−αw} − 1` (already computed for the stratum's mass). With `t = αw`:
/// `μ − a = 1/α − w e^{−t}/(1 − e^{−t})`, `σ² = 1/α² − w² e^{−t}/(1 − e^{−t})²` (from
/// `log Z = log(1 − e^{−αw}) − log α`, `μ = −∂ log Z/∂α`, `σ² = ∂² log Z/∂α²`): one division.
/// Both cancel for small `t` (errors `~2ε/t` of `w` and `~4ε/t²` of `w²`: 4e-13 and 1e-9 at
/// `t = 1e-3`); below `t = 1e-3` the Bernoulli series (`1/(eᵗ − 1) = Σ Bₙ tⁿ⁻¹/n!`)
/// `(μ − a)/w = 1/2 − t/12 + t³/720 − …` and `σ²/w² = 1/12 − t²/240 + t⁴/6048 − …`, cut
/// after the terms shown (≤ 3e-20 and 2e-16). [`inv_sq_mean`] needs far less: at
/// `w/R = 1e-3` an error of 5e-9 `w` in the offset or 3e-6 `w²` in the variance moves it
/// by 1e-11 relative.
#[inline]
pub(crate) fn trunc_exp_moments(alpha: f64, ia: f64, w: f64, em: f64) -> (f64, f64) {
    let t = alpha * w;
    if t < 1e-3 {
        let t2 = t * t;
        (
            w * (0.5 - t * (1.0 / 12.0 - t2 * (1.0 / 720.0))),
            w * w * (1.0 / 12.0 - t2 * (1.0 / 240.0)),
        )
    } else {
        let iem = 1.0 / em;
        let g = w * (1.0 + em) * iem; // −w e^{−t}/(1 − e^{−t})
        (ia + g, ia * ia - w * g * iem)
    }
}

/// Estimate of `E[1/(l0 + u)²]`, m⁻², for `u` with mean at distance `r` from the receiver
/// (`r = l0 + μ`, m) and variance `var` (m²), from the Taylor expansion of `(r + x)⁻²` about
/// `x = 0`: `E = r⁻²(1 + 3σ²/r² − 4m₃/r³ + 5m₄/r⁴ − …)` with the central moments `m_n`; the
/// first two terms are kept. For the truncated exponential of a stratum of width `w` (any
/// `αw > 0`): `|m₃| ≤ 0.01325 w³` (largest, 0.0132455 w³, at `αw = 2.745`), `m₄ ≤ w⁴/80`
/// (the uniform limit), and `|m_n| ≤ w^{n−2}σ² ≤ w^n/12` (`|x| ≤ w`, `σ² ≤ w²/12`); the
/// unit test checks the first two by quadrature. With `ρ = w/r ≤ 1e-3` the dropped terms are
/// at most `0.053ρ³ + 0.0625ρ⁴ + Σ_{n≥5}(n+1)ρⁿ/12 < 5.4e-11` relative. `var = 0`: `1/r²`.
#[inline(always)]
pub(crate) fn inv_sq_mean(r: f64, var: f64) -> f64 {
    let q = 1.0 / (r * r);
    q * (1.0 + 3.0 * var * q)
}

/// Offset from the stratum start and variance of the point at which [`bin_first_order`]
/// evaluates `1/(l0 + u)²` in a stratum of width `w` (`em = e^{−αw} − 1`): the moments of
/// the stratum's truncated exponential ([`trunc_exp_moments`], `moments`), or a point drawn
/// from it by inverse CDF with variance 0.
#[inline(always)]
pub(crate) fn stratum_point(
    moments: bool,
    alpha: f64,
    ia: f64,
    w: f64,
    em: f64,
    rng: &mut Xoshiro256PlusPlus,
) -> (f64, f64) {
    if moments {
        trunc_exp_moments(alpha, ia, w, em)
    } else {
        (-(rng.next_f64() * em).ln_1p() * ia, 0.0)
    }
}

/// Bins the forced first-order return of a vegetation segment of a LiDAR first flight
/// ([`Ctx::first_flight`](crate::photon::engine::context::Ctx::first_flight); DART 5 paper §4, physics.md §9.2, §9.6): energy density
/// `base · e^{−αu}/(l0 + u)²` J m⁻¹ over the distance `u ∈ [0, ell]` m from the segment start,
/// `l0` m the distance from the receiver at `u = 0` (recorded at path `2(l0 + u)`), `α > 0`
/// m⁻¹. Strata: the digitiser bins (before the gate, after it, and groups of `kb` bins beyond
/// [`MAX_FIRST_ORDER_STRATA`]); in each `[a, b]` the exact mass `e^{−αa}(1 − e^{−α(b−a)})/α`
/// times an estimate of the mean of `1/(l0 + u)²` under the density `∝ e^{−αu}` on `[a, b]`.
/// Single-bin strata in the gate far from the receiver (`h/l0 <`
/// [`FIRST_ORDER_MOMENT_RATIO`]): the deterministic moment estimate [`inv_sq_mean`] (bias
/// < 5.4e-11 relative, no random draw; the whole strata share one mean offset and variance,
/// having one width). Other strata: `1/(l0 + u)²` at `u` drawn from the density (inverse CDF),
/// unbiased for every bin; the whole strata share one uniform (the same offset from their
/// start: each point still has its stratum's density), the two end strata draw their own.
pub(crate) fn bin_first_order(
    wave: &mut WaveformBinner,
    l0: f64,
    ell: f64,
    alpha: f64,
    base: f64,
    rng: &mut Xoshiro256PlusPlus,
) {
    let h = 0.5 * wave.bin_len_m(); // one bin, in distance along the ray
    let n = wave.n_bins() as f64;
    // Bin coordinate of the segment's ends.
    let x0 = (2.0 * l0 - wave.bin_start_path_m(0)) / (2.0 * h);
    let x1 = x0 + ell / h;
    if !(x0.is_finite() && x1.is_finite() && alpha > 0.0 && ell > 0.0) {
        return;
    }
    let kb = ceil_small((x1.min(n) - x0.max(0.0)) / MAX_FIRST_ORDER_STRATA).max(1.0);
    // Single-bin strata in the gate take the moment estimate (whole strata are such strata).
    let moments = kb == 1.0 && h < FIRST_ORDER_MOMENT_RATIO * l0;
    // Whole strata: width kb·h, shared offset and variance (the uniform drawn here unless
    // they take the moments; the libm calls made at the first whole stratum only: a segment
    // over one or two bins has none).
    let v_full = if moments { 0.0 } else { rng.next_f64() };
    let ia = 1.0 / alpha; // m
    let mut full: Option<(f64, f64, f64)> = None;
    let mut full = move || {
        *full.get_or_insert_with(|| {
            let w = kb * h;
            let em = (-alpha * w).exp_m1();
            let (off, var) = if moments {
                trunc_exp_moments(alpha, ia, w, em)
            } else {
                (-(v_full * em).ln_1p() * ia, 0.0)
            };
            (em, off, var)
        })
    };
    // Common case: one bin per stratum and the segment well inside the gate. The strata are
    // visited in the order of the general loop below, with its arithmetic (the same values
    // bit for bit), without its per-stratum gate, grouping and edge logic: stratum k is bin k,
    // from ⌊x0⌋; the first and the last have their own point, the whole ones between share
    // the offset.
    if kb == 1.0 && x0 >= 0.0 && x1 < n - 1.0 {
        let mut k = (x0 as i64) as f64; // ⌊x0⌋ (0 ≤ x0 < n)
        let k0 = k as usize;
        let mut ki = k0; // the same bin as an index (k < x1 < n − 1 throughout)
        let (mut a, mut ea) = (0.0, 1.0);
        let mut rejected = 0;
        let bins = wave.first_order_bins_mut();
        // A packet as `WaveformBinner::add_first_order_at` books it (finite and ≥ 0, else
        // counted as rejected).
        let mut book = |i: usize, e: f64| {
            if crate::lidar::waveform::bookable(e) {
                bins[i].add(e);
            } else {
                rejected += 1;
            }
        };
        loop {
            let edge = k + 1.0;
            if edge >= x1 {
                // Last stratum [a, ell] (the only one when the segment lies in one bin).
                if ell > a {
                    let em = (-alpha * (ell - a)).exp_m1();
                    let (off, var) = stratum_point(moments, alpha, ia, ell - a, em, rng);
                    let r = l0 + clamp_between(a + off, a, ell);
                    book(ki, base * (ea * -em * ia) * inv_sq_mean(r, var));
                }
                break;
            }
            let bx = (edge - x0) * h;
            let b = if bx < ell { bx } else { ell };
            if !(b > a) {
                // Both ends rounded to ell (the bin ends are strictly increasing): the general
                // loop stops here too.
                break;
            }
            let (em, off, var) = if a > 0.0 {
                full()
            } else {
                let em = (-alpha * (b - a)).exp_m1();
                let (off, var) = stratum_point(moments, alpha, ia, b - a, em, rng);
                (em, off, var)
            };
            let r = l0 + clamp_between(a + off, a, b);
            book(ki, base * (ea * -em * ia) * inv_sq_mean(r, var));
            ea *= 1.0 + em;
            a = b;
            k = edge;
            ki += 1;
        }
        // Bins k0..=ki (ki < n − 1): the last one booked, or the one after it.
        wave.mark_written(k0, ki + 1);
        wave.reject(rejected);
        return;
    }
    let mut xa = x0;
    let mut ea = 1.0; // e^{−α a}
    let mut a = 0.0;
    // Strata: ≤ MAX_FIRST_ORDER_STRATA + 2 (+ rounding steps); the cap only guards the loop.
    for _ in 0..(2 * MAX_FIRST_ORDER_STRATA as usize + 8) {
        if a >= ell {
            break;
        }
        let in_gate = (0.0..n).contains(&xa);
        let edge = if xa < 0.0 {
            0.0
        } else if xa >= n {
            f64::INFINITY
        } else {
            // ⌊xa/kb⌋ by truncation (xa ≥ 0 here; no libm call).
            ((((xa / kb) as i64) as f64 + 1.0) * kb).min(n)
        };
        let xb = edge.min(x1);
        let b = if xb >= x1 {
            ell
        } else {
            ((xb - x0) * h).min(ell)
        };
        if !(b > a) {
            // Rounding at an edge: step past it.
            xa = xb.max(xa) + f64::EPSILON * xa.abs().max(1.0);
            continue;
        }
        let whole = in_gate && a > 0.0 && xb < x1 && edge == xa + kb;
        let (em, off, var) = if whole {
            full()
        } else {
            let em = (-alpha * (b - a)).exp_m1(); // e^{−α(b−a)} − 1 ≤ 0
            let (off, var) = stratum_point(moments && in_gate, alpha, ia, b - a, em, rng);
            (em, off, var)
        };
        let mass = ea * -em * ia;
        let r = l0 + (a + off).clamp(a, b);
        let e = base * mass * inv_sq_mean(r, var);
        if in_gate && kb == 1.0 {
            wave.add_first_order_at(xa as usize, e);
        } else {
            wave.add(2.0 * r, e, 1);
        }
        ea *= 1.0 + em;
        a = b;
        xa = xb;
    }
}

/// `u` clamped to `[a, b]` (`a ≤ b`), as `f64::clamp` (NaN stays NaN) without its checks.
#[inline(always)]
pub(crate) fn clamp_between(u: f64, a: f64, b: f64) -> f64 {
    if u < a {
        a
    } else if u > b {
        b
    } else {
        u
    }
}

/// `x − ⌊x⌋` for `0 ≤ x < 2⁶³` (the fractional part of a lattice coordinate), by truncation:
/// the same value as `x.fract()` without its libm call. Through `i64` (one conversion each
/// way; the `u64` round trip costs ~20 instructions on x86-64), the same integer for these `x`.
#[inline]
pub(crate) fn unit_fract(x: f64) -> f64 {
    x - (x as i64) as f64
}

/// `⌈v⌉` for `v < 2⁶³` by truncation (no libm call), except that it gives `+0` where `ceil`
/// gives `−0` (`−1 < v < 0`) and `−2⁶³` below `−2⁶³`: the same after `max(1.0)`, as its
/// caller takes.
#[inline]
pub(crate) fn ceil_small(v: f64) -> f64 {
    let t = (v as i64) as f64;
    if t < v { t + 1.0 } else { t }
}

/// The waveform binner as the photon walk's receiver tally: peel-offs go to their path-length
/// bin, first-order segments to [`bin_first_order`].
impl ReturnTally for WaveformBinner {
    #[inline]
    fn book(&mut self, path_m: f64, energy_j: f64, order: u32) {
        WaveformBinner::add(self, path_m, energy_j, order);
    }

    fn first_order_segment(
        &mut self,
        l0: f64,
        ell: f64,
        alpha: f64,
        base: f64,
        rng: &mut Xoshiro256PlusPlus,
    ) {
        bin_first_order(self, l0, ell, alpha, base, rng);
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}
