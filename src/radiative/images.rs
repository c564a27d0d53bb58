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

/// Shares of the interval of length `len` centred on `c` in pixels `[i·px, (i+1)·px)`,
/// `i ∈ 0..n` (indices wrapped modulo `n` when `wrap`, else pixels outside are dropped):
/// overlap / len; `len = 0` (or not positive): the pixel holding `c`, share 1.
fn axis_shares(c: f64, len: f64, px: f64, n: usize, wrap: bool, out: &mut Vec<(usize, f64)>) {
    out.clear();
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
        return;
    }
    if len.is_nan() || len <= 0.0 {
        if let Some(i) = place((c / px).floor() as i64) {
            out.push((i, 1.0));
        }
        return;
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
