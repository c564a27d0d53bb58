//! The Maket cell grid (resource `CellGrid`): per-cell turbid leaf area density per material
//! and per-cell facet lists, both in compressed-row form over all cells.

use crate::resources::materials::MaterialId;
use crate::scene::desc::BoundaryMode;
use bevy_ecs::prelude::Resource;
use glam::DVec3;

/// Geometry of the grid.
#[derive(Debug, Clone, PartialEq, Resource)]
pub struct GridSpec {
    /// Cells along x, y, z.
    pub n: [usize; 3],
    /// Cell size, metres.
    pub cell: DVec3,
    /// Position of the grid corner (0, 0, z0), metres; z0 is the lowest ground or object point.
    pub origin: DVec3,
    /// Sub-cell factor D.
    pub subcells: u32,
    /// Boundary mode.
    pub boundary: BoundaryMode,
    /// Ground-altitude offsets between opposite sides (along x, along y), metres, used by
    /// `RepetitiveContinuousTopography` (zero otherwise).
    pub topography_offset: (f64, f64),
}

impl GridSpec {
    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    /// Linear index of cell (i, j, k): x fastest, then y, then z.
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.n[0] * (j + self.n[1] * k)
    }

    /// (i, j, k) of a linear index.
    pub fn ijk(&self, idx: usize) -> [usize; 3] {
        let i = idx % self.n[0];
        let j = (idx / self.n[0]) % self.n[1];
        [i, j, idx / (self.n[0] * self.n[1])]
    }

    /// Lower corner of the cell with linear index `c`, m.
    pub fn cell_lo(&self, c: usize) -> DVec3 {
        let [i, j, k] = self.ijk(c);
        self.cell_box(i as i64, j as i64, k as i64).0
    }

    /// Lower and upper corners of cell (i, j, k) (integer indices may lie outside the grid for
    /// periodic objects).
    pub fn cell_box(&self, i: i64, j: i64, k: i64) -> (DVec3, DVec3) {
        let lo = self.origin + DVec3::new(i as f64, j as f64, k as f64) * self.cell;
        (lo, lo + self.cell)
    }

    /// Volume of one cell, m³.
    pub fn cell_volume(&self) -> f64 {
        self.cell.x * self.cell.y * self.cell.z
    }

    /// Wraps a horizontal index into the grid for repetitive scenes; `None` if outside an
    /// isolated scene.
    pub fn wrap(&self, i: i64, axis: usize) -> Option<usize> {
        let n = self.n[axis] as i64;
        match self.boundary {
            BoundaryMode::Isolated => (0..n).contains(&i).then_some(i as usize),
            _ => Some(i.rem_euclid(n) as usize),
        }
    }

    /// Scene top altitude, metres.
    pub fn top(&self) -> f64 {
        self.origin.z + self.n[2] as f64 * self.cell.z
    }

    /// Slack, metres, by which a facet hit may lie outside the cell segment `[t0, t1]` of a ray
    /// and still count (a facet lying in a cell face is hit at `t1` of one cell and `t0` of the
    /// next, each rounded). It scales with the scene: 1e-12 of the largest cell side, and at least
    /// 8 ulps of the largest coordinate of the grid box (the rounding of a hit distance computed
    /// from points that far from 0). A fixed 1e-12 m lost the hits on walls in cell faces of
    /// 10-km scenes (`huge_and_tiny_scenes_give_the_products_of_the_metre_scene`); for metre
    /// cells in scenes under ~500 m it is 1e-12 m, as before.
    pub fn hit_tolerance(&self) -> f64 {
        let far = self.origin.abs()
            + DVec3::new(self.n[0] as f64, self.n[1] as f64, self.n[2] as f64) * self.cell;
        (1e-12 * self.cell.max_element()).max(8.0 * f64::EPSILON * far.max_element())
    }

    // --- Continuous topography (issue #31; physics.md §6.1, §6.5) ---------------------------

    /// Signed widths (L_x, L_y), m, by which a downward source direction `d` (sun or sky
    /// direction) widens (> 0) or narrows (< 0) the launch region on the top plane of a
    /// `RepetitiveContinuousTopography` scene: `L_a = offset_a · d_a / |d_z|`; zero otherwise.
    ///
    /// The scene is invariant under the translation (X, 0, offset_x) (and likewise along y),
    /// not under (X, 0, 0): the top planes of neighbouring tiles form a staircase, and a tile
    /// receives, besides the rays crossing its own top plane, the rays crossing the riser of
    /// height |offset| between its top and its lower neighbour's top on the side the light
    /// comes from (or loses the rays that its higher neighbour's riser sends onto it). Per
    /// tile, the intercepted direct power is `E_dir (X Y + L_x Y + L_y X)` (up to the `L_x L_y`
    /// corner term, kept when both are positive), which is `E_dir X Y (n·s)/(n_z cos θ_s)` for
    /// a uniform slope of normal n and sun vector s: the irradiance of a tilted plane per unit
    /// horizontal area.
    pub fn topo_launch_span(&self, d: DVec3) -> (f64, f64) {
        if self.boundary != BoundaryMode::RepetitiveContinuousTopography || d.z >= 0.0 {
            return (0.0, 0.0);
        }
        let (ox, oy) = self.topography_offset;
        (ox * d.x / -d.z, oy * d.y / -d.z)
    }

    /// Horizontal area of the launch region of [`GridSpec::topo_launch_point`] for a source
    /// direction `d`, m² (the scene's X·Y without continuous topography).
    /// A direction descending more slowly than the terrain (L_a ≤ −X) lights none of it
    /// directly: area 0.
    pub fn topo_launch_area(&self, size: (f64, f64), d: DVec3) -> f64 {
        let (lx, ly) = self.topo_launch_span(d);
        let corner = if lx > 0.0 && ly > 0.0 { lx * ly } else { 0.0 };
        ((size.0 + lx).max(0.0) * (size.1 + ly).max(0.0) - corner).max(0.0)
    }

    /// Start point in the scene of the source ray along `d` at launch coordinates `(u, v)`
    /// (m from the origin, `u ∈ [0, X + L_x)`, `v ∈ [0, Y + L_y)`, see
    /// [`GridSpec::topo_launch_span`]): the point (u, v) of the top plane when it lies over the
    /// tile, else the point where the ray crosses the riser of the neighbouring tile, brought
    /// back into this tile with its altitude offset. A launch coordinate with a negative span
    /// skips the strip the higher neighbour's riser already lights. `None`: the corner of two
    /// widened strips, or a riser point that does not land inside the scene box (mixed
    /// signs, second order): the caller books its power as lost.
    pub fn topo_launch_point(&self, size: (f64, f64), u: f64, v: f64, d: DVec3) -> Option<DVec3> {
        let (lx, ly) = self.topo_launch_span(d);
        let (ox, oy) = self.topography_offset;
        // Launch coordinate → position on the plane z = top (relative to the origin).
        let x = if ox < 0.0 { u - lx } else { u };
        let y = if oy < 0.0 { v - ly } else { v };
        let kx = if x < 0.0 {
            -1.0
        } else {
            (x >= size.0) as i32 as f64
        };
        let ky = if y < 0.0 {
            -1.0
        } else {
            (y >= size.1) as i32 as f64
        };
        let mut p = DVec3::new(x, y, self.top());
        if kx != 0.0 && ky != 0.0 {
            return None;
        }
        if kx != 0.0 || ky != 0.0 {
            // Back along the ray to the face of the neighbouring tile it entered through.
            let t = if kx != 0.0 {
                (x - if kx > 0.0 { size.0 } else { 0.0 }) / d.x
            } else {
                (y - if ky > 0.0 { size.1 } else { 0.0 }) / d.y
            };
            p -= d * t;
            p.x -= kx * size.0;
            p.y -= ky * size.1;
            p.z -= kx * ox + ky * oy;
            // Snap onto the entry face (rounding) and wrap the other axis with its offset.
            if kx != 0.0 {
                p.x = if kx > 0.0 { 0.0 } else { size.0 };
                let k = (p.y / size.1).floor();
                p.y -= k * size.1;
                p.z -= k * oy;
            } else {
                p.y = if ky > 0.0 { 0.0 } else { size.1 };
                let k = (p.x / size.0).floor();
                p.x -= k * size.0;
                p.z -= k * ox;
            }
            if p.z > self.top() || p.z < self.origin.z {
                return None;
            }
        }
        Some(DVec3::new(p.x + self.origin.x, p.y + self.origin.y, p.z))
    }

    /// A ray in air above the scene top (`q.z > top`, coming down along `d`, `d.z < 0`) in a
    /// `RepetitiveContinuousTopography` scene: marches through the empty air of the repeated
    /// tiles (each side crossing shifts the altitude by the offset) until the ray reaches the
    /// top plane or comes back inside the box below it. Returns the point (inside the box or
    /// on its top plane) and the distance marched, m; `None` after `max_crossings` side
    /// crossings (descending more slowly than the terrain: it never meets the ground again).
    /// The flux tracker's march of `radiative::engine` (`radiative::walk`, `Ctx::trace_w`), shared with the
    /// Monte Carlo walk.
    pub fn descend_through_air(
        &self,
        mut q: DVec3,
        d: DVec3,
        size: (f64, f64),
        max_crossings: u32,
    ) -> Option<(DVec3, f64)> {
        let top = self.top();
        let mut s = 0.0;
        let mut crossings = 0u32;
        while q.z > top {
            let t_top = (top - q.z) / d.z;
            let mut side: Option<(usize, f64)> = None;
            for a in 0..2 {
                let len = if a == 0 { size.0 } else { size.1 };
                let t = if d[a] > 0.0 {
                    (self.origin[a] + len - q[a]) / d[a]
                } else if d[a] < 0.0 {
                    (self.origin[a] - q[a]) / d[a]
                } else {
                    f64::INFINITY
                };
                if side.is_none_or(|v| t < v.1) {
                    side = Some((a, t));
                }
            }
            match side {
                Some((a, t)) if t < t_top => {
                    crossings += 1;
                    if crossings > max_crossings {
                        return None;
                    }
                    q += d * t.max(0.0);
                    s += t.max(0.0);
                    let (len, off) = if a == 0 {
                        (size.0, self.topography_offset.0)
                    } else {
                        (size.1, self.topography_offset.1)
                    };
                    let sg = if d[a] > 0.0 { 1.0 } else { -1.0 };
                    q.z -= sg * off;
                    q[a] = if sg > 0.0 {
                        self.origin[a]
                    } else {
                        self.origin[a] + len
                    };
                }
                _ => {
                    q += d * t_top;
                    s += t_top;
                    q.z = top;
                }
            }
        }
        Some((q, s))
    }
}

/// Turbid content of one cell for one material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurbidEntry {
    /// Turbid material.
    pub material: MaterialId,
    /// One-sided leaf area volume density u_f, m² m⁻³.
    pub density: f32,
}

/// The rasterised scene.
#[derive(Debug, Clone, Default, Resource)]
pub struct CellGrid {
    /// `turbid[turbid_start[c]..turbid_start[c+1]]` are the entries of cell c (sorted by material).
    pub turbid_start: Vec<u32>,
    /// Turbid entries.
    pub turbid: Vec<TurbidEntry>,
    /// `facet_ids[facet_start[c]..facet_start[c+1]]` are the facets overlapping cell c.
    pub facet_start: Vec<u32>,
    /// Facet indices into the facet store.
    pub facet_ids: Vec<u32>,
}

impl CellGrid {
    /// Turbid entries of cell `c`.
    pub fn turbid_of(&self, c: usize) -> &[TurbidEntry] {
        &self.turbid[self.turbid_start[c] as usize..self.turbid_start[c + 1] as usize]
    }

    /// Facets of cell `c`.
    pub fn facets_of(&self, c: usize) -> &[u32] {
        &self.facet_ids[self.facet_start[c] as usize..self.facet_start[c + 1] as usize]
    }

    /// The facets of each cell packed for the scan prefilter of the solvers
    /// ([`FacetPacks`](crate::geometry::facet_packs::FacetPacks)); empty without facets (or
    /// when the rows do not match `spec`).
    pub fn facet_packs(
        &self,
        spec: &GridSpec,
        facets: &[crate::resources::facets::Facet],
    ) -> crate::geometry::facet_packs::FacetPacks {
        if self.facet_ids.is_empty() || self.facet_start.len() != spec.n_cells() + 1 {
            return Default::default();
        }
        crate::geometry::facet_packs::FacetPacks::new(
            &self.facet_start,
            &self.facet_ids,
            |c| spec.cell_lo(c),
            |f| facets[f as usize].v,
        )
    }

    /// Bytes held by the arrays.
    pub fn bytes(&self) -> usize {
        4 * (self.turbid_start.len() + self.facet_start.len() + self.facet_ids.len())
            + std::mem::size_of::<TurbidEntry>() * self.turbid.len()
    }
}

/// Builds compressed rows from (cell, value) pairs sorted by cell.
pub fn compress<T: Copy>(n_cells: usize, sorted: &[(u32, T)]) -> (Vec<u32>, Vec<T>) {
    let mut start = vec![0u32; n_cells + 1];
    for (c, _) in sorted {
        start[*c as usize + 1] += 1;
    }
    for c in 0..n_cells {
        start[c + 1] += start[c];
    }
    (start, sorted.iter().map(|(_, v)| *v).collect())
}
