//! 3D digital differential analyser over the cell grid (Amanatides & Woo 1987, "A fast voxel
//! traversal algorithm for ray tracing", Eurographics '87): yields the cells a ray crosses with
//! the entry and exit distances (metres along the unit direction).
//!
//! Pitfalls handled (physics.md §6.2): direction components of exactly 0 (t = ∞), rays starting
//! on a cell boundary (the start cell is the one the ray enters), ties between axes (all tied
//! axes step in the same call, so a ray along an edge or through a vertex steps diagonally
//! instead of visiting a zero-length segment), accumulated error (boundaries are recomputed from
//! integer indices, not accumulated).
//!
//! Speed (the flux-tracking kernel runs one [`Dda::advance`] per cell crossing): the plane at
//! which the ray leaves cell i along an axis is `b_base + i · size` (`b_base` set per ray,
//! recomputed from the integer index, not accumulated), its distance multiplies by a
//! precomputed `1/d` instead of dividing (Amanatides & Woo's `tDelta` idea), `floor` is an integer
//! truncation with a correction ([`floor_i64`], no libm call), and a repetitive-boundary
//! re-entry moves the traversal state in place ([`Dda::wrap_sides`]) instead of building a new
//! one.

use crate::resources::grid::GridSpec;
use glam::DVec3;

/// `⌊x⌋` as an integer, by truncation and a correction for negative non-integers (no libm
/// call). Exact for |x| < 2⁶³; NaN gives 0 (Rust's saturating `as`), like `x.floor() as i64`.
#[inline(always)]
pub fn floor_i64(x: f64) -> i64 {
    let i = x as i64;
    i - ((i as f64) > x) as i64
}

/// What ends a segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// The ray moves into a neighbouring cell inside the grid.
    Inside,
    /// The ray leaves through a side face: axis (0 = x, 1 = y) and sign of the step.
    Side(usize, i64),
    /// The ray leaves through the top.
    Top,
    /// The ray leaves through the bottom.
    Bottom,
}

/// Traversal state.
#[derive(Debug, Clone)]
pub struct Dda {
    /// Current cell (i, j, k).
    pub cell: [i64; 3],
    step: [i64; 3],
    t_max: [f64; 3],
    /// Distance at which the current segment starts.
    pub t: f64,
    origin: DVec3,
    dir: DVec3,
    /// `1/dir` per axis (±∞ for a zero component; only read for axes that step).
    inv: DVec3,
    size: DVec3,
    n: [i64; 3],
    /// Linear index of `cell` (kept up to date by [`Dda::advance`] while inside the grid).
    lin: i64,
    /// Linear-index increment of one step along each axis (`step × stride`).
    dlin: [i64; 3],
    /// Linear-index stride of each axis.
    stride: [i64; 3],
    /// Per axis, `lo + [step > 0] · size`: the ray leaves the cell of index i at the plane
    /// `b_base + i · size` (the same expression for every axis, so ties at vertices stay exact).
    b_base: [f64; 3],
}

impl Dda {
    /// Starts at `p` (inside the grid box, boundaries included) along the unit vector `d`.
    /// Returns `None` if `p` is outside the grid box.
    pub fn new(spec: &GridSpec, p: DVec3, d: DVec3) -> Option<Self> {
        let n = [spec.n[0] as i64, spec.n[1] as i64, spec.n[2] as i64];
        let size = spec.cell;
        let lo = spec.origin;
        let inv = DVec3::ONE / d;
        let mut cell = [0i64; 3];
        let mut step = [0i64; 3];
        let mut t_max = [f64::INFINITY; 3];
        for a in 0..3 {
            let rel = (p[a] - lo[a]) / size[a];
            if !(rel >= -1e-9 && rel <= n[a] as f64 + 1e-9) {
                return None;
            }
            let mut idx = floor_i64(rel);
            // On a boundary: take the cell the ray enters.
            if rel == idx as f64 && d[a] < 0.0 {
                idx -= 1;
            }
            idx = idx.clamp(0, n[a] - 1);
            cell[a] = idx;
            if d[a] > 0.0 {
                step[a] = 1;
                t_max[a] = ((lo[a] + (idx + 1) as f64 * size[a]) - p[a]) * inv[a];
            } else if d[a] < 0.0 {
                step[a] = -1;
                t_max[a] = ((lo[a] + idx as f64 * size[a]) - p[a]) * inv[a];
            }
            t_max[a] = t_max[a].max(0.0);
        }
        let stride = [1, n[0], n[0] * n[1]];
        let b_base: [f64; 3] =
            std::array::from_fn(|a| lo[a] + (step[a] > 0) as i64 as f64 * size[a]);
        Some(Self {
            cell,
            step,
            t_max,
            t: 0.0,
            origin: p,
            dir: d,
            inv,
            size,
            n,
            lin: cell[0] + n[0] * (cell[1] + n[1] * cell[2]),
            dlin: [
                step[0] * stride[0],
                step[1] * stride[1],
                step[2] * stride[2],
            ],
            stride,
            b_base,
        })
    }

    /// Linear index of the current cell.
    #[inline]
    pub fn index(&self) -> usize {
        self.lin as usize
    }

    /// Distance at which the ray leaves the current cell.
    #[inline]
    pub fn t_exit(&self) -> f64 {
        // A plain comparison (one `minsd`) rather than `f64::min`'s NaN handling: t_max is
        // never NaN (an axis with d = 0 never steps and keeps +∞).
        let m = |a: f64, b: f64| if b < a { b } else { a };
        m(m(self.t_max[0], self.t_max[1]), self.t_max[2])
    }

    /// The point at distance 0 (moved by one period at each [`Dda::wrap_sides`]).
    #[inline]
    pub fn origin(&self) -> DVec3 {
        self.origin
    }

    /// Point at distance t.
    #[inline]
    pub fn point(&self, t: f64) -> DVec3 {
        self.origin + self.dir * t
    }

    /// Distance at which the ray leaves the cell whose index along `a` is `idx`.
    #[inline(always)]
    fn boundary_t(&self, a: usize, idx: i64) -> f64 {
        (self.b_base[a] + idx as f64 * self.size[a] - self.origin[a]) * self.inv[a]
    }

    /// Moves to the next cell; reports how the current one was left.
    #[inline]
    pub fn advance(&mut self) -> Exit {
        self.advance_at(self.t_exit())
    }

    /// [`Dda::advance`] given `te = self.t_exit()` (already computed by the caller).
    #[inline(always)]
    pub fn advance_at(&mut self, te: f64) -> Exit {
        debug_assert_eq!(te, self.t_exit());
        self.t = te;
        // Step every axis whose boundary is reached at te (ties: edges and vertices).
        let mut exit = Exit::Inside;
        for a in 0..3 {
            if self.t_max[a] <= te {
                self.cell[a] += self.step[a];
                self.lin += self.dlin[a];
                let idx = self.cell[a];
                if idx < 0 || idx >= self.n[a] {
                    let e = match a {
                        2 if self.step[2] > 0 => Exit::Top,
                        2 => Exit::Bottom,
                        _ => Exit::Side(a, self.step[a]),
                    };
                    // Vertical exits win over side exits at a tie (top/bottom are final).
                    if matches!(e, Exit::Top | Exit::Bottom) || exit == Exit::Inside {
                        exit = e;
                    }
                } else {
                    self.t_max[a] = self.boundary_t(a, idx);
                }
            }
        }
        exit
    }

    /// Repetitive boundary without an altitude offset: after [`Dda::advance`] returned
    /// [`Exit::Side`], moves every side axis that left the grid to the opposite face (the
    /// cell on the other side, the ray's origin shifted by one period so that distances go on
    /// from `t`; the state is then as if the ray had been started at the wrapped exit point).
    /// Returns the number of axes wrapped (2 when the ray left through a vertical edge).
    #[inline]
    pub fn wrap_sides(&mut self) -> u32 {
        let mut wrapped = 0;
        for a in 0..2 {
            let idx = self.cell[a];
            if idx >= 0 && idx < self.n[a] {
                continue;
            }
            let back = if idx < 0 { self.n[a] } else { -self.n[a] };
            self.cell[a] += back;
            self.lin += back * self.stride[a];
            self.origin[a] += back as f64 * self.size[a];
            self.t_max[a] = self.boundary_t(a, self.cell[a]).max(self.t);
            wrapped += 1;
        }
        wrapped
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::desc::BoundaryMode;

    fn spec() -> GridSpec {
        GridSpec {
            n: [4, 3, 2],
            cell: DVec3::new(1.0, 2.0, 0.5),
            origin: DVec3::new(0.0, 0.0, 10.0),
            subcells: 2,
            boundary: BoundaryMode::Repetitive,
            topography_offset: (0.0, 0.0),
        }
    }

    #[test]
    fn segment_lengths_sum_to_path_length() {
        let s = spec();
        let p = DVec3::new(0.3, 0.7, 11.0);
        let d = DVec3::new(0.6, 0.3, -0.5).normalize();
        let mut dda = Dda::new(&s, p, d).unwrap();
        let mut total = 0.0;
        loop {
            let t0 = dda.t;
            let e = dda.advance();
            total += dda.t - t0;
            if e != Exit::Inside {
                break;
            }
        }
        // The ray leaves first through whichever face it reaches first.
        let tx = (4.0 - 0.3) / d.x;
        let ty = (6.0 - 0.7) / d.y;
        let tzb = (11.0 - 10.0) / -d.z;
        assert!((total - tx.min(ty).min(tzb)).abs() < 1e-12);
    }

    #[test]
    fn ray_along_a_vertex_diagonal_never_has_zero_length_segments() {
        let s = GridSpec {
            n: [5, 5, 5],
            cell: DVec3::ONE,
            origin: DVec3::ZERO,
            subcells: 2,
            boundary: BoundaryMode::Isolated,
            topography_offset: (0.0, 0.0),
        };
        let d = DVec3::new(1.0, 1.0, -1.0).normalize();
        let mut dda = Dda::new(&s, DVec3::new(0.0, 0.0, 5.0), d).unwrap();
        let mut count = 0;
        loop {
            let t0 = dda.t;
            let e = dda.advance();
            assert!(dda.t - t0 > 1e-9, "zero-length segment");
            count += 1;
            if e != Exit::Inside {
                break;
            }
        }
        assert_eq!(
            count, 5,
            "diagonal through vertices visits one cell per layer"
        );
    }

    #[test]
    fn floor_i64_is_floor() {
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999_999_999,
            -2.000_000_001,
            1e15 + 0.5,
            -1e15 - 0.5,
            4503599627370497.0,
            -4503599627370497.0,
            1e-300,
            -1e-300,
        ] {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }

    #[test]
    fn in_place_wrap_matches_a_new_traversal_from_the_wrapped_point() {
        let s = GridSpec {
            n: [5, 4, 10],
            cell: DVec3::new(0.2, 0.25, 0.2),
            origin: DVec3::new(-0.5, 1.0, 3.0),
            subcells: 2,
            boundary: BoundaryMode::Repetitive,
            topography_offset: (0.0, 0.0),
        };
        let period = [1.0, 1.0];
        for (p, d) in [
            (
                DVec3::new(0.3137, 1.7071, 4.9913),
                DVec3::new(0.8, 0.3, -0.2),
            ),
            (
                DVec3::new(-0.1011, 1.1234, 4.9),
                DVec3::new(-0.7, -0.6, -0.1),
            ),
            (
                DVec3::new(0.0123, 1.5377, 4.0171),
                DVec3::new(0.5, -0.9, 0.05),
            ),
        ] {
            let d = d.normalize();
            let mut a = Dda::new(&s, p, d).unwrap();
            let mut cells = Vec::new();
            let mut total = 0.0;
            // Reference: restart from the wrapped exit point after every side exit.
            let mut q = p;
            let mut b = Dda::new(&s, q, d).unwrap();
            let mut b_base = 0.0;
            for _ in 0..200 {
                let (ca, ta) = (a.index(), a.t);
                let (cb, tb) = (b.index(), b_base + b.t);
                assert_eq!(ca, cb, "{:?} {:?} t {} {}", a.cell, b.cell, ta, tb);
                assert!((ta - tb).abs() < 1e-9, "{ta} {tb}");
                cells.push(ca);
                let t0 = a.t;
                let ea = a.advance();
                total += a.t - t0;
                let eb = b.advance();
                match ea {
                    Exit::Inside => assert_eq!(eb, Exit::Inside),
                    Exit::Side(..) => {
                        assert!(matches!(eb, Exit::Side(..)));
                        a.wrap_sides();
                        b_base += b.t;
                        q = b.point(b.t);
                        for ax in 0..2 {
                            let rel = (q[ax] - s.origin[ax]) / period[ax];
                            if rel <= 1e-12 && d[ax] < 0.0 {
                                q[ax] += period[ax];
                            } else if rel >= 1.0 - 1e-12 && d[ax] > 0.0 {
                                q[ax] -= period[ax];
                            }
                        }
                        b = Dda::new(&s, q, d).unwrap();
                        // A vertical edge: the reference steps the second axis next time.
                        if b.t_exit() < 1e-12 {
                            b.advance();
                            b_base += b.t;
                            let r = b.point(b.t);
                            b = Dda::new(&s, r, d).unwrap();
                        }
                    }
                    Exit::Top | Exit::Bottom => {
                        assert_eq!(ea, eb);
                        break;
                    }
                }
            }
            assert!(total > 0.0 && cells.len() > 10);
            // The wrapped point is the point at the same distance on the re-entered side.
            let pt = a.point(a.t);
            assert!(pt.x >= s.origin.x - 1e-9 && pt.x <= s.origin.x + 1.0 + 1e-9);
        }
    }
}
