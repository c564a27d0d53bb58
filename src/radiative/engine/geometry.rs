//! Geometry of one cell crossing (DART 5 paper §3.2, Figure 7; physics.md §3.6): incident
//! (sub-)face stores, cell exits, the half-barycentres of the intercepted energy, the
//! ray–triangle intersection, and small array helpers.

use super::*;

/// Incident store of a crossing of the cell `[lo, lo + cell]` whose segment starts at `q0`
/// along `d`, with D = `dd` sub-faces per face side (DART 5 paper §3.2, Figure 7: turbid
/// interception is stored per incident cell sub-face). 0: the ray started inside the cell
/// (scattered from a point of this cell, or restarted on a facet of it); else
/// `1 + face · D² + sub-face`, face `2a + [d_a < 0]` for the face of axis a the ray enters
/// through (0 −x, 1 +x, 2 −y, 3 +y, 4 bottom, 5 top), sub-face `i·D + j` over the face's two
/// other axes in increasing order. Rules: the segment's start lies on a face when within
/// `FACE_TOL` cell sizes of it and the ray points into the cell through it; a start on an
/// edge or a vertex (several such faces) is booked to the face the ray crosses most squarely,
/// the largest |d_a| (ties: the higher axis, so z before y before x); a start on a sub-face
/// boundary goes to the sub-face given by the floor of its position (clamped into 0..D). Sun
/// and sky rays start on the scene top plane: the top face of the top cell, sub-face from the
/// launch point (x, y).
pub fn entry_store(lo: DVec3, cell: DVec3, q0: DVec3, d: DVec3, dd: u32) -> u32 {
    let rel = (q0 - lo) / cell;
    let mut best: Option<(usize, f64)> = None;
    for a in 0..3 {
        let on = if d[a] > 0.0 {
            rel[a] <= FACE_TOL
        } else if d[a] < 0.0 {
            rel[a] >= 1.0 - FACE_TOL
        } else {
            false
        };
        if on && best.is_none_or(|(_, m)| d[a].abs() >= m) {
            best = Some((a, d[a].abs()));
        }
    }
    let Some((a, _)) = best else {
        return 0;
    };
    let face = 2 * a as u32 + (d[a] < 0.0) as u32;
    1 + face * dd * dd + sub_face(rel, a, dd)
}

/// Sub-face `i·D + j` of the point at relative position `rel` (in cell sizes) on a face of
/// axis `a`: i, j = ⌊D · rel⌋ over the two other axes in increasing order, clamped into 0..D.
pub(in crate::radiative) fn sub_face(rel: DVec3, a: usize, dd: u32) -> u32 {
    let (b0, b1) = match a {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let cell_of = |x: f64| floor_i64(x * dd as f64).clamp(0, dd as i64 - 1) as u32;
    cell_of(rel[b0]) * dd + cell_of(rel[b1])
}

/// Where a ray leaving `o` (inside the cell `[lo, lo + cell]`) along `d` leaves the cell:
/// (distance ℓ, m; exit point, on the exit face; exit store `1 + face · D² + sub-face` with the
/// numbering of [`entry_store`], face `2a + [d_a > 0]`). An exit through an edge or a vertex
/// (exit distances equal within `FACE_TOL` cell sizes) goes to the face with the largest
/// |d_a|, ties to the higher axis, and the exit point is put exactly on every plane it
/// reaches (so the tracker starts the merged ray in the diagonal neighbour).
pub fn cell_exit(lo: DVec3, cell: DVec3, o: DVec3, d: DVec3, dd: u32) -> (f64, DVec3, u32) {
    let plane = |a: usize| lo[a] + if d[a] > 0.0 { cell[a] } else { 0.0 };
    let t_of = |a: usize| {
        if d[a] == 0.0 {
            f64::INFINITY
        } else {
            ((plane(a) - o[a]) / d[a]).max(0.0)
        }
    };
    let t = [t_of(0), t_of(1), t_of(2)];
    let t_min = t[0].min(t[1]).min(t[2]);
    let tied = |a: usize| t[a] <= t_min + FACE_TOL * cell[a] / d[a].abs().max(1e-300);
    let mut best = 2;
    let mut m = -1.0;
    for a in 0..3 {
        if tied(a) && d[a].abs() >= m {
            best = a;
            m = d[a].abs();
        }
    }
    let mut q = o + d * t_min;
    for a in 0..3 {
        if tied(a) {
            q[a] = plane(a);
        }
    }
    let face = 2 * best as u32 + (d[best] > 0.0) as u32;
    (
        t_min,
        q,
        1 + face * dd * dd + sub_face((q - lo) / cell, best, dd),
    )
}

/// Adds one interception's weighted points to a points record: Σw·p_first (3),
/// Σw·p_second (3), Σw.
#[inline(always)]
pub(in crate::radiative) fn add_points(pr: &mut [f64], p1: DVec3, p2: DVec3, wt: f64) {
    let pr = &mut pr[..7];
    pr[0] += p1.x * wt;
    pr[1] += p1.y * wt;
    pr[2] += p1.z * wt;
    pr[3] += p2.x * wt;
    pr[4] += p2.y * wt;
    pr[5] += p2.z * wt;
    pr[6] += wt;
}

/// `[slot][dir]` rows: the table rows of each slot's member directions averaged with `weights`.
pub(in crate::radiative) fn slot_average_rows(
    table: &PhaseTable,
    weights: &[f64],
    sector_of: &[u16],
    n_sec: usize,
    n_dirs: usize,
) -> Vec<f64> {
    let mut rows = vec![0.0; n_sec * n_dirs];
    let mut wsum = vec![0.0; n_sec];
    for (i, &wt) in weights.iter().enumerate() {
        let s = sector_of[i] as usize;
        wsum[s] += wt;
        for (j, v) in table.row(i).iter().take(n_dirs).enumerate() {
            rows[s * n_dirs + j] += wt * *v as f64;
        }
    }
    for (s, ws) in wsum.iter().enumerate() {
        if *ws > 0.0 {
            rows[s * n_dirs..(s + 1) * n_dirs]
                .iter_mut()
                .for_each(|v| *v /= ws);
        }
    }
    rows
}

#[inline]
pub(in crate::radiative) fn add(acc: &mut [f64], v: &[f64]) {
    for (a, b) in acc.iter_mut().zip(v) {
        *a += b;
    }
}

/// Distances from the entry of the barycentres of the first and second halves of the energy
/// intercepted along a segment of length ℓ with extinction k (physics.md §3.6 \[rec\]); the split
/// point is `s½ = −ln((1 + e^{−kℓ})/2)/k`. Series for small kℓ.
pub fn half_barycentres(k: f64, ell: f64) -> (f64, f64) {
    let x = k * ell;
    half_barycentres_with(k, ell, (-x).exp(), -(-x).exp_m1())
}

/// Tabulated [`half_barycentres`] (the tracker's hot path: no logarithm per crossing), see
/// [`HalfBarycentres::eval`] (within 1e-8 ℓ of the closed form).
#[inline]
pub fn half_barycentres_fast(k: f64, ell: f64) -> (f64, f64) {
    HalfBarycentres::get().eval(k * ell, ell)
}

/// [`half_barycentres`] given `e = e^{−kℓ}` and `f = 1 − e` (computed once by the tracker).
/// With `h = e^{−k s½} = (1 + e)/2`, the means of s under the density k e^{−ks} are
/// `s̄₁ = 1/k − s½ h/(1 − h)` on [0, s½] and `s̄₂ = 1/k + (s½ h − ℓ e)/(h − e)` on [s½, ℓ],
/// with `1 − h = h − e = f/2`. Series for small kℓ: `ℓ(1/4 − kℓ/12)` and `ℓ(3/4 − kℓ/12)`.
#[inline]
pub fn half_barycentres_with(k: f64, ell: f64, e: f64, f: f64) -> (f64, f64) {
    let x = k * ell;
    if x < 1e-4 {
        return (ell * (0.25 - x / 12.0), ell * (0.75 - x / 12.0));
    }
    let h = 0.5 * (1.0 + e);
    // ln h = ln(1 − f/2) without the rounding of h (kℓ → 0: s½ ≈ ℓ/2 to full precision).
    let s_half = -(-0.5 * f).ln_1p() / k;
    let den = 0.5 * f;
    let inv_k = 1.0 / k;
    (
        (inv_k - s_half * h / den).clamp(0.0, s_half),
        (inv_k + (s_half * h - ell * e) / den).clamp(s_half, ell),
    )
}

/// Distance from the entry of the barycentre of the energy intercepted along a segment of
/// length ℓ with extinction k: `s̄ = 1/k − ℓ e^{−kℓ}/(1 − e^{−kℓ})` (physics.md §3.6), with the
/// series `ℓ/2 − kℓ²/12` for small kℓ.
pub fn barycentre(k: f64, ell: f64) -> f64 {
    let x = k * ell;
    if x < 1e-4 {
        return ell * (0.5 - x / 12.0);
    }
    if x > 700.0 {
        return 1.0 / k;
    }
    1.0 / k - ell * (-x).exp() / (-(-x).exp_m1())
}

pub use crate::geometry::triangle::intersect;

pub(in crate::radiative) fn cell_centre(spec: &GridSpec, c: usize) -> DVec3 {
    let [i, j, k] = spec.ijk(c);
    spec.origin + (DVec3::new(i as f64, j as f64, k as f64) + 0.5) * spec.cell
}

/// Mean of the truncated exponential density `∝ e^{−u x}` on x ∈ [0, 1]:
/// `1/u − 1/(e^u − 1)`; for |u| < ¼ its Bernoulli series `1/2 − u/12 + u³/720 − u⁵/30240 +
/// u⁷/1209600 − u⁹/47900160` (the closed form cancels there).
fn trunc_exp_mean(u: f64) -> f64 {
    if u.abs() < 0.25 {
        let u2 = u * u;
        return 0.5
            - u * (1.0 / 12.0
                - u2 * (1.0 / 720.0
                    - u2 * (1.0 / 30240.0 - u2 * (1.0 / 1209600.0 - u2 / 47900160.0))));
    }
    1.0 / u - 1.0 / u.exp_m1()
}

/// Variance of the density of [`trunc_exp_mean`]: `1/u² − e^u/(e^u − 1)²`; for |u| < ¼ the
/// series `1/12 − u²/240 + u⁴/6048 − u⁶/172800 + u⁸/5322240` (the derivative of the mean's).
fn trunc_exp_var(u: f64) -> f64 {
    if u.abs() < 0.25 {
        let u2 = u * u;
        return 1.0 / 12.0
            - u2 * (1.0 / 240.0 - u2 * (1.0 / 6048.0 - u2 * (1.0 / 172800.0 - u2 / 5322240.0)));
    }
    if u > 40.0 {
        // e^u/(e^u − 1)² < e^{−40}: the untruncated exponential (and no overflow).
        return 1.0 / (u * u);
    }
    let e = u.exp_m1();
    1.0 / (u * u) - (e + 1.0) / (e * e)
}

/// The rate u ≥ 0 of the truncated exponential on [0, 1] whose mean is `m` ∈ (0, ½]: Newton
/// steps on the monotone mean (`d mean/du = −variance`) kept inside the bracket [0, 1/m] (the
/// mean lies below 1/u), with bisection when a step leaves it (Press et al. 2007, `rtsafe`).
fn trunc_exp_rate(m: f64) -> f64 {
    if m >= 0.5 {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0, 1.0 / m);
    let mut u = if m > 0.3 {
        12.0 * (0.5 - m)
    } else {
        1.0 / m - 1.0
    };
    for _ in 0..100 {
        let f = trunc_exp_mean(u) - m;
        if f > 0.0 {
            lo = u;
        } else {
            hi = u;
        }
        let v = trunc_exp_var(u);
        let mut next = u + f / v;
        if !(next > lo && next < hi) || v <= 0.0 {
            next = 0.5 * (lo + hi);
        }
        if (next - u).abs() <= 1e-15 * u.max(1e-3) {
            return next;
        }
        u = next;
    }
    u
}

/// Within-cell spread of the intercepted energy along one axis, from its mean alone: the
/// standard deviation, in units of the cell width, of the maximum-entropy density on [0, 1]
/// with mean `m` (Jaynes 1957: the truncated exponential `∝ e^{−u x}`). This is the exact
/// spread of single-direction interception in a homogeneous cell (Beer's law along the axis:
/// `u = kΔ/|μ|`); a uniform source has m = ½ and σ = 1/√12. Symmetric: σ(m) = σ(1 − m).
pub fn max_entropy_sigma(m: f64) -> f64 {
    // The density for 1 − m is the mirror image: solve for the mean below ½ (u ≥ 0).
    let m = m.min(1.0 - m).clamp(1e-9, 0.5);
    trunc_exp_var(trunc_exp_rate(m)).max(0.0).sqrt()
}

/// `ln Z(v)`, `Z(v) = ∫₀¹ e^{−v x} dx = (1 − e^{−v})/v` (Z(0) = 1), without overflow for any
/// finite v (series `−v/2 + v²/24` near 0).
fn ln_trunc_exp_norm(v: f64) -> f64 {
    if v.abs() < 1e-4 {
        return -0.5 * v + v * v / 24.0;
    }
    if v > 0.0 {
        (-(-v).exp_m1()).ln() - v.ln()
    } else {
        let w = -v;
        w + (-(-w).exp_m1()).ln() - w.ln()
    }
}

/// The position x* ∈ [0, 1] (cell widths) with `e^{c x*} = ⟨e^{c x}⟩` under the
/// maximum-entropy density of mean `m` on [0, 1] (see [`max_entropy_sigma`]):
/// `x* = ln(Z(u − c)/Z(u))/c` for the density `∝ e^{−u x}` (mirrored for m > ½). In a
/// homogeneous medium everything a ray from height z sends downstream along a direction of
/// vertical cosine μ is proportional to `e^{c z}` with `c = ±kΔz/|μ|` (+ upwards), so one
/// emission height x* per direction reproduces the source's exact expectation (physics.md
/// §3.6); `c → 0` gives the mean.
pub fn exp_moment_position(m: f64, c: f64) -> f64 {
    MaxEntropyProfile::new(m).position(c)
}

/// The maximum-entropy density on [0, 1] with a given mean (see [`max_entropy_sigma`]): the
/// density `∝ e^{−u x}` (`flip`: mirrored, `∝ e^{−u(1−x)}`), with what does not depend on the
/// direction (`ln Z(u)`, the mean) computed once per cell.
#[derive(Debug, Clone, Copy)]
pub struct MaxEntropyProfile {
    u: f64,
    flip: bool,
    ln_z: f64,
    mean: f64,
}

impl MaxEntropyProfile {
    /// The profile whose mean is `m` (clamped into [0, 1]).
    pub fn new(m: f64) -> Self {
        let u = trunc_exp_rate(m.min(1.0 - m).clamp(1e-9, 0.5));
        MaxEntropyProfile {
            u,
            flip: m > 0.5,
            ln_z: ln_trunc_exp_norm(u),
            mean: trunc_exp_mean(u),
        }
    }

    /// [`exp_moment_position`] of this profile for the exponent `c`.
    pub fn position(&self, c: f64) -> f64 {
        // Mirrored density x' = 1 − x: ⟨e^{cx}⟩ = e^c ⟨e^{−c x'}⟩.
        let cc = if self.flip { -c } else { c };
        let x = if cc.abs() < 1e-9 {
            self.mean
        } else {
            let cc = cc.clamp(-1e6, 1e6);
            (ln_trunc_exp_norm(self.u - cc) - self.ln_z) / cc
        };
        let x = x.clamp(0.0, 1.0);
        if self.flip { 1.0 - x } else { x }
    }
}
