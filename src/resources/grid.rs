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
