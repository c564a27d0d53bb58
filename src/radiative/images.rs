//! Orthographic images of the flux tracking (DART 5 paper §3.2 and §5; physics.md §6.6, §8.1).
//!
//! Images have pixels of (Δx/η, Δy/η), η the user's oversampling factor (scene field
//! `radiative.image_oversampling`), i.e. `n_x·η × n_y·η` pixels over the scene. Every upward
//! flux that leaves the scene along an image direction Ω is projected along Ω onto the reference
//! plane z0 and its power is spread ("étalement") over the pixels that the projected footprint
//! of its emitting element overlaps, in proportion to the overlap area. The footprint is an
//! axis-aligned box of the element's horizontal size centred on the projected exit point (a
//! turbid cell: Δx × Δy; a facet or ground sub-cell scattering point: (Δx/D) × (Δy/D); an
//! element of unknown size: a point, whose power goes to the one pixel holding it).
//! Repetitive scenes wrap the box around the scene; isolated scenes clip it (the clipped part
//! is not imaged). The shares of one flux sum to 1 when nothing is clipped, so an image holds
//! exactly the exitance of its direction.

use crate::resources::grid::GridSpec;
use crate::scene::desc::BoundaryMode;

/// Scratch buffers of [`ImageGrid::spread`]: (pixel index, share) along x and along y.
#[derive(Debug, Clone, Default)]
pub struct SpreadScratch {
    x: Vec<(usize, f64)>,
    y: Vec<(usize, f64)>,
}

/// Pixel grid of the orthographic images.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct ImageGrid {
    /// Oversampling factor η (pixels per cell along x and along y).
    pub oversampling: u32,
    /// Pixels along x and y (grid columns × η).
    pub n: (usize, usize),
    /// Pixel size (Δx/η, Δy/η), m.
    pub pixel_m: (f64, f64),
    /// Footprints wrap around the scene (repetitive boundaries) instead of being clipped.
    #[serde(skip)]
    pub wrap: bool,
}

impl ImageGrid {
    /// The image grid of a scene grid with oversampling `eta` (0 is taken as 1).
    pub fn new(spec: &GridSpec, eta: u32) -> Self {
        let eta = eta.max(1);
        let e = eta as f64;
        Self {
            oversampling: eta,
            n: (spec.n[0] * eta as usize, spec.n[1] * eta as usize),
            pixel_m: (spec.cell.x / e, spec.cell.y / e),
            wrap: spec.boundary != BoundaryMode::Isolated,
        }
    }

    /// Pixels per image.
    pub fn pixels(&self) -> usize {
        self.n.0 * self.n.1
    }

    /// Calls `f(pixel, share)` for every pixel (index `i + n_x·j`) overlapped by the box of
    /// size `size` (m, x and y; 0 along an axis: a point along it) centred on `(x, y)` (m, from
    /// the grid origin), with the fraction of the box area inside that pixel.
    pub fn spread(
        &self,
        (x, y): (f64, f64),
        size: (f64, f64),
        scratch: &mut SpreadScratch,
        mut f: impl FnMut(usize, f64),
    ) {
        // The common case (at most FAST pixels per axis: a footprint of about a pixel) on the
        // stack; the same shares in the same order as the general path below.
        if let Some(ax) = axis_shares_fast(x, size.0, self.pixel_m.0, self.n.0, self.wrap) {
            if ax.len == 0 {
                return;
            }
            if let Some(ay) = axis_shares_fast(y, size.1, self.pixel_m.1, self.n.1, self.wrap) {
                for (&j, &wy) in ay.k[..ay.len].iter().zip(&ay.w[..ay.len]) {
                    for (&i, &wx) in ax.k[..ax.len].iter().zip(&ax.w[..ax.len]) {
                        f(i + self.n.0 * j, wx * wy);
                    }
                }
                return;
            }
        }
        let SpreadScratch { x: sx, y: sy } = scratch;
        axis_shares(x, size.0, self.pixel_m.0, self.n.0, self.wrap, sx);
        if sx.is_empty() {
            return;
        }
        axis_shares(y, size.1, self.pixel_m.1, self.n.1, self.wrap, sy);
        for &(j, wy) in sy.iter() {
            for &(i, wx) in sx.iter() {
                f(i + self.n.0 * j, wx * wy);
            }
        }
    }

    /// Whether a box of size `size` centred on `(x, y)` misses the image entirely (only
    /// possible without wrapping).
    pub fn misses(&self, (x, y): (f64, f64), size: (f64, f64)) -> bool {
        if self.wrap {
            return false;
        }
        let (w, h) = (
            self.n.0 as f64 * self.pixel_m.0,
            self.n.1 as f64 * self.pixel_m.1,
        );
        let outside =
            |c: f64, len: f64, extent: f64| c + 0.5 * len < 0.0 || c - 0.5 * len >= extent;
        outside(x, size.0, w) || outside(y, size.1, h)
    }
}

/// `⌊x⌋` as an integer, as `x.floor() as i64` (saturating, NaN gives 0) without the libm
/// call: truncation and a correction for negative non-integers.
#[inline(always)]
fn floor_to_i64(x: f64) -> i64 {
    let i = x as i64;
    i.saturating_sub(((i as f64) > x) as i64)
}

/// Pixel index `i` placed in `0..n`: wrapped (`i mod n`, as `i.rem_euclid(n)`) when `wrap`,
/// else `None` outside. One period either side without the integer division.
#[inline(always)]
fn place(i: i64, n: i64, wrap: bool) -> Option<usize> {
    if (0..n).contains(&i) {
        Some(i as usize)
    } else if !wrap {
        None
    } else if i < 0 && i >= -n {
        Some((i + n) as usize)
    } else if i >= n && i - n < n {
        Some((i - n) as usize)
    } else {
        Some(i.rem_euclid(n) as usize)
    }
}

/// The interval `[a, b]` of [`axis_shares`] and its first and last pixel indices (unplaced),
/// or `None` for a point (`len` not positive or NaN).
#[inline(always)]
fn axis_span(c: f64, len: f64, px: f64) -> Option<(f64, f64, i64, i64)> {
    if len.is_nan() || len <= 0.0 {
        return None;
    }
    let (a, b) = (c - 0.5 * len, c + 0.5 * len);
    Some((a, b, floor_to_i64(a / px), floor_to_i64(b / px)))
}

/// Share of pixel `i` in the interval `[a, b]` of length `len` (see [`axis_shares`]): `None`
/// when they do not overlap.
#[inline(always)]
fn pixel_share(a: f64, b: f64, len: f64, px: f64, i: i64) -> Option<f64> {
    let lo = a.max(i as f64 * px);
    let hi = b.min((i + 1) as f64 * px);
    (hi > lo).then(|| (hi - lo) / len)
}

/// Pixels per axis that [`ImageGrid::spread`] handles without its scratch vectors.
const FAST: usize = 4;

/// At most [`FAST`] (pixel index, share) pairs of one axis.
struct AxisShares {
    k: [usize; FAST],
    w: [f64; FAST],
    len: usize,
}

/// [`axis_shares`] when the interval spans at most [`FAST`] pixels (`None` otherwise): the
/// same pairs in the same order, on the stack.
#[inline(always)]
fn axis_shares_fast(c: f64, len: f64, px: f64, n: usize, wrap: bool) -> Option<AxisShares> {
    let mut out = AxisShares {
        k: [0; FAST],
        w: [0.0; FAST],
        len: 0,
    };
    if !c.is_finite() || n == 0 {
        return Some(out);
    }
    let n_i = n as i64;
    let Some((a, b, i0, i1)) = axis_span(c, len, px) else {
        if let Some(i) = place(floor_to_i64(c / px), n_i, wrap) {
            out.k[0] = i;
            out.w[0] = 1.0;
            out.len = 1;
        }
        return Some(out);
    };
    // i0 ≤ i1 (a ≤ b); a wrapped difference (an infinite interval) takes the general path.
    if i1.wrapping_sub(i0) as u64 >= FAST as u64 {
        return None;
    }
    for i in i0..=i1 {
        if let Some(s) = pixel_share(a, b, len, px, i)
            && let Some(k) = place(i, n_i, wrap)
        {
            out.k[out.len] = k;
            out.w[out.len] = s;
            out.len += 1;
        }
    }
    Some(out)
}

/// Shares of the interval of length `len` centred on `c` in pixels `[i·px, (i+1)·px)`,
/// `i ∈ 0..n` (indices wrapped modulo `n` when `wrap`, else pixels outside are dropped):
/// overlap / len; `len = 0` (or not positive): the pixel holding `c`, share 1.
fn axis_shares(c: f64, len: f64, px: f64, n: usize, wrap: bool, out: &mut Vec<(usize, f64)>) {
    out.clear();
    if !c.is_finite() || n == 0 {
        return;
    }
    let n_i = n as i64;
    let Some((a, b, i0, i1)) = axis_span(c, len, px) else {
        if let Some(i) = place(floor_to_i64(c / px), n_i, wrap) {
            out.push((i, 1.0));
        }
        return;
    };
    for i in i0..=i1 {
        if let Some(s) = pixel_share(a, b, len, px, i)
            && let Some(k) = place(i, n_i, wrap)
        {
            out.push((k, s));
        }
    }
}

/// `x.rem_euclid(s)` (s > 0), the same bits, without the libm `fmod` for `x ∈ (−2s, 2s)`:
/// there the remainder is `x`, `x − s` or `x + s`, exact by Sterbenz's lemma (as `fmod`'s is),
/// and the negative case adds `s` once more like `rem_euclid` (a zero remainder of a negative
/// `x` is −0, as `fmod` gives).
#[inline(always)]
pub fn rem_euclid_period(x: f64, s: f64) -> f64 {
    if !(s > 0.0) {
        return x.rem_euclid(s);
    }
    if x >= 0.0 {
        if x < s {
            return x;
        }
        if x < 2.0 * s {
            return x - s;
        }
    } else if x > -s {
        return x + s;
    } else if x > -2.0 * s {
        let r = x + s;
        return if r == 0.0 { -0.0 } else { r + s };
    }
    x.rem_euclid(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn grid(boundary: BoundaryMode, eta: u32) -> ImageGrid {
        ImageGrid::new(
            &GridSpec {
                n: [3, 2, 1],
                cell: DVec3::new(1.0, 2.0, 1.0),
                origin: DVec3::ZERO,
                subcells: 1,
                boundary,
                topography_offset: (0.0, 0.0),
            },
            eta,
        )
    }

    fn image(g: &ImageGrid, c: (f64, f64), s: (f64, f64)) -> Vec<f64> {
        let mut v = vec![0.0; g.pixels()];
        g.spread(c, s, &mut SpreadScratch::default(), |p, w| v[p] += w);
        v
    }

    #[test]
    fn pixel_size_is_the_cell_over_eta() {
        let g = grid(BoundaryMode::Repetitive, 3);
        assert_eq!(g.n, (9, 6));
        assert!((g.pixel_m.0 - 1.0 / 3.0).abs() < 1e-15 && (g.pixel_m.1 - 2.0 / 3.0).abs() < 1e-15);
        assert_eq!(grid(BoundaryMode::Isolated, 0).n, (3, 2));
    }

    #[test]
    fn shares_are_overlap_areas_and_sum_to_one() {
        let g = grid(BoundaryMode::Repetitive, 2);
        // A 1 × 1 m box centred at (0.75, 1.0): x over [0.25, 1.25] → pixels 0 (0.25), 1 (0.5),
        // 2 (0.25); y over [0.5, 1.5] → pixels 0 (1/2), 1 (1/2) of 1 m pixels.
        let v = image(&g, (0.75, 1.0), (1.0, 1.0));
        let want = [
            (0, 0.125),
            (1, 0.25),
            (2, 0.125),
            (6, 0.125),
            (7, 0.25),
            (8, 0.125),
        ];
        for (p, x) in v.iter().enumerate() {
            let w = want.iter().find(|q| q.0 == p).map_or(0.0, |q| q.1);
            assert!((x - w).abs() < 1e-15, "pixel {p}: {x} vs {w}");
        }
        // A point goes whole to its pixel.
        let v = image(&g, (1.2, 3.9), (0.0, 0.0));
        assert_eq!(v[2 + 6 * 3], 1.0);
        assert!((v.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }

    /// The former `axis_shares` (libm floor, `rem_euclid`), the reference of the fast forms.
    fn axis_shares_reference(c: f64, len: f64, px: f64, n: usize, wrap: bool) -> Vec<(usize, f64)> {
        let mut out = Vec::new();
        let n_i = n as i64;
        let place = |i: i64| -> Option<usize> {
            if wrap {
                Some(i.rem_euclid(n_i) as usize)
            } else if (0..n_i).contains(&i) {
                Some(i as usize)
            } else {
                None
            }
        };
        if !c.is_finite() || n == 0 {
            return out;
        }
        if len.is_nan() || len <= 0.0 {
            if let Some(i) = place((c / px).floor() as i64) {
                out.push((i, 1.0));
            }
            return out;
        }
        let (a, b) = (c - 0.5 * len, c + 0.5 * len);
        let (i0, i1) = ((a / px).floor() as i64, (b / px).floor() as i64);
        for i in i0..=i1 {
            let lo = a.max(i as f64 * px);
            let hi = b.min((i + 1) as f64 * px);
            if hi > lo
                && let Some(k) = place(i)
            {
                out.push((k, (hi - lo) / len));
            }
        }
        out
    }

    #[test]
    fn fast_shares_and_remainders_are_the_reference_bits() {
        // A fixed pseudo-random sweep (64-bit LCG) over centres, lengths (points, about a
        // pixel, several pixels), pixel sizes and both boundary modes, plus edge values.
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut u = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut cases = vec![
            (0.0, 1.0, 0.5, 4),
            (-0.0, 0.0, 0.5, 4),
            (2.0, 1.0, 0.5, 4),
            (-2.0, 0.5, 0.5, 4),
            (1e300, 0.0, 0.5, 4),
            (-1e300, 0.0, 0.5, 4),
            (-1e19, 0.0, 1.0, 3),
            (0.3, f64::NAN, 0.5, 4),
            (0.3, 1e-300, 0.5, 4),
        ];
        for _ in 0..20000 {
            let px = [0.1, 0.25, 1.0 / 3.0, 0.7, 2.0][(u() * 5.0) as usize];
            let n = 1 + (u() * 9.0) as usize;
            let c = (u() * 6.0 - 3.0) * n as f64 * px;
            let len = match (u() * 4.0) as usize {
                0 => 0.0,
                1 => px,
                2 => u() * 2.0 * px,
                _ => u() * 8.0 * px,
            };
            cases.push((c, len, px, n));
        }
        for &(c, len, px, n) in &cases {
            for wrap in [false, true] {
                let want = axis_shares_reference(c, len, px, n, wrap);
                let mut got = Vec::new();
                axis_shares(c, len, px, n, wrap, &mut got);
                let bits = |v: &[(usize, f64)]| -> Vec<(usize, u64)> {
                    v.iter().map(|&(k, w)| (k, w.to_bits())).collect()
                };
                assert_eq!(
                    bits(&got),
                    bits(&want),
                    "c {c} len {len} px {px} n {n} {wrap}"
                );
                if let Some(f) = axis_shares_fast(c, len, px, n, wrap) {
                    let fast: Vec<(usize, f64)> = (0..f.len).map(|i| (f.k[i], f.w[i])).collect();
                    assert_eq!(bits(&fast), bits(&want), "fast c {c} len {len}");
                }
            }
            let period = n as f64 * px;
            for x in [
                c,
                c * 0.5,
                -c,
                period,
                -period,
                2.0 * period,
                -2.0 * period,
                -0.0,
            ] {
                let (got, want) = (rem_euclid_period(x, period), x.rem_euclid(period));
                assert_eq!(got.to_bits(), want.to_bits(), "{x} mod {period}");
            }
        }
        assert_eq!(rem_euclid_period(-1e-20, 1.0), (-1e-20f64).rem_euclid(1.0));
        assert!(rem_euclid_period(1.0, f64::NAN).is_nan());
    }

    #[test]
    fn repetitive_boxes_wrap_and_isolated_boxes_are_clipped() {
        let g = grid(BoundaryMode::Repetitive, 1);
        // Box over x ∈ [−0.5, 0.5]: half in pixel 0, half in the last column (wrapped); even
        // a box wider than the scene keeps all of its power.
        let v = image(&g, (0.0, 1.0), (1.0, 0.0));
        assert!((v[0] - 0.5).abs() < 1e-15 && (v[2] - 0.5).abs() < 1e-15);
        let v = image(&g, (0.3, 1.0), (7.5, 5.0));
        assert!((v.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        let g = grid(BoundaryMode::Isolated, 1);
        let v = image(&g, (0.0, 1.0), (1.0, 0.0));
        assert!((v[0] - 0.5).abs() < 1e-15 && v.iter().sum::<f64>() == 0.5);
        assert!(g.misses((-0.6, 1.0), (1.0, 1.0)) && !g.misses((-0.4, 1.0), (1.0, 1.0)));
        assert!(image(&g, (3.5, 1.0), (0.0, 0.0)).iter().all(|&x| x == 0.0));
    }
}
