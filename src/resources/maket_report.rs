//! What Maket built, for `lumenscape check`, `maket.json` and tests (resource `MaketReport`).

use bevy_ecs::prelude::Resource;
use serde::Serialize;
use std::collections::BTreeMap;

/// Memory the Maket stage will need, estimated before allocation.
#[derive(Debug, Clone, Default, Serialize, Resource)]
pub struct MemoryEstimate {
    /// Cell-index arrays (two compressed-row start arrays), bytes.
    pub cell_index_bytes: u64,
    /// Upper bound of turbid entries (bounding-box cells of every turbid object).
    pub turbid_entries_max: u64,
    /// Upper bound of facet–cell references.
    pub facet_refs_max: u64,
    /// Facet storage and BVH, bytes.
    pub facet_bytes: u64,
    /// Peak estimate (including build buffers), bytes.
    pub peak_bytes: u64,
    /// The limit in force, bytes.
    pub limit_bytes: u64,
}

/// Per-material leaf area.
#[derive(Debug, Clone, Default, Serialize)]
pub struct LeafAreaReport {
    /// Analytic leaf area of the objects using this material, m².
    pub analytic_m2: f64,
    /// Leaf area stored in the cells (Σ density × cell volume), m² (after rasterisation).
    pub rasterised_m2: Option<f64>,
}

/// Summary of the Maket stage.
#[derive(Debug, Clone, Default, Serialize, Resource)]
pub struct MaketReport {
    /// Cells along x, y, z.
    pub cells: [usize; 3],
    /// Cell size, metres.
    pub cell_m: [f64; 3],
    /// Grid origin altitude z0 and top, metres.
    pub z_range_m: [f64; 2],
    /// Total number of cells.
    pub n_cells: u64,
    /// Cells holding turbid vegetation (after rasterisation).
    pub turbid_cells: Option<u64>,
    /// Cells overlapped by at least one facet (after assignment).
    pub facet_cells: Option<u64>,
    /// Leaf area per turbid material.
    pub leaf_area: BTreeMap<String, LeafAreaReport>,
    /// Facet count per material.
    pub facet_count: BTreeMap<String, u64>,
    /// Facet area per material, m².
    pub facet_area_m2: BTreeMap<String, f64>,
    /// Facet area per element type, m².
    pub facet_area_by_kind_m2: BTreeMap<String, f64>,
    /// Ground-altitude offsets between opposite sides (x, y), metres.
    pub topography_offset_m: (f64, f64),
    /// Memory estimate made before allocation.
    pub memory: MemoryEstimate,
    /// Bytes actually held by the grid, facets and BVH (after the stage).
    pub memory_used_bytes: Option<u64>,
    /// Warnings.
    pub warnings: Vec<String>,
}
