//! Photon stage (DART 5 paper §4, "Ray-Carlo"): forward Monte Carlo photon tracking over the
//! same scene representation as the Radiative stage (turbid cells, facets, ground, boundaries).
//!
//! * [`sampling`]: scattering-direction samplers — discrete (Walker/Vose alias tables and DART's
//!   Box method over the discrete directions) and continuous (exact leaf, fluid and surface
//!   phase functions).
//! * [`engine`]: the photon tracker (free paths, events, peel-off, roulette, seeded batches).
//! * [`material_optics`]: the Monte Carlo optics of every material (LAD samplers shared per LAD).
//! * [`products`]: the Radiative stage's products with standard errors.
//! * [`sensors`]: the frame-camera images (sensor stage) with per-pixel standard errors.
//! * [`small`]: inline short arrays (no allocation per scattering event).

pub mod engine;
pub mod material_optics;
pub mod products;
pub mod sampling;
pub mod sensors;
pub mod small;

/// What the Photon stage's memory depends on, counted before anything is allocated.
#[derive(Debug, Clone, Default)]
pub struct PhotonCounts {
    /// Grid cells.
    pub n_cells: usize,
    /// Turbid materials of the scene.
    pub turbid_materials: usize,
    /// Turbid entries (the Maket plan's count).
    pub turbid_entries: usize,
    /// Facets.
    pub n_facets: usize,
    /// Facet references (facet–cell pairs).
    pub facet_refs: usize,
    /// Grid columns.
    pub n_columns: usize,
    /// Tiling directions.
    pub n_dirs: usize,
    /// Channels (bands × (1 + sky)).
    pub channels: usize,
    /// Photon batches (the run's `PhotonParams::batches`).
    pub batches: usize,
    /// Pixels of all frame cameras (sensor stage; 0: none).
    pub camera_pixels: usize,
}

/// The photon engine's context (Monte Carlo and LiDAR), bytes: the facet packs of the scan
/// prefilter ([`FacetPacks::bytes_for`](crate::geometry::facet_packs::FacetPacks::bytes_for)),
/// per cell the facet bounding box (6 f64) and, when cells × turbid materials ≤ 2²³, the column
/// tables of the first-flight sampler (two f64 per cell and material, one flag per cell).
pub fn context_bytes(n_cells: usize, turbid_materials: usize, facet_refs: usize) -> f64 {
    let f = |x: usize| x as f64;
    let columns = if n_cells.saturating_mul(turbid_materials) <= 1 << 23 {
        f(n_cells) * (16.0 * f(turbid_materials) + 1.0)
    } else {
        0.0
    };
    f(n_cells) * 48.0 + columns + crate::geometry::facet_packs::FacetPacks::bytes_for(facet_refs)
}

/// Memory the Photon stage (passive Monte Carlo) holds at its peak, bytes, as named terms:
///
/// * `photon context`: [`context_bytes`].
/// * `batch tallies`: a wave of up to 16 batches is held until merged; each keeps absorbed and
///   intercepted power per turbid entry, facet and column (dense f64 arrays of ≤ 2¹⁸ values,
///   hashed records above) and its escape summary.
/// * `products`: the merged absorbed and intercepted power per element and the per-batch
///   escape sums for the standard errors.
/// * `camera images` (scenes with frame cameras): the per-batch pixel tallies of a wave, the
///   merged sums and squares, the images and the writer's copies.
pub fn memory_terms(c: &PhotonCounts) -> Vec<(&'static str, f64)> {
    let f = |x: usize| x as f64;
    let w = f(c.channels.max(1));
    let context = context_bytes(c.n_cells, c.turbid_materials, c.facet_refs);
    let tally = |n: usize| (f(n) * w).min(f(1 << 18)) * 8.0;
    let wave = f(c.batches.clamp(1, 16));
    let summary = 8.0 * w * (f(c.n_dirs) * 4.0 + 16.0);
    let batch = 2.0 * (tally(c.turbid_entries) + tally(c.n_facets) + tally(c.n_columns)) + summary;
    let elements = f(c.turbid_entries) + f(c.n_facets) + f(c.n_columns);
    let products = 2.0 * 8.0 * w * elements + f(c.batches) * summary;
    let mut terms = vec![
        ("photon context", context),
        ("batch tallies", wave * batch),
        ("products", products),
    ];
    if c.camera_pixels > 0 {
        // Per batch of the wave a value per pixel and channel; merged: the sum per channel
        // and the sum of squares per band; products: radiance and SE per band, and the
        // writer's copies of one image (four layers).
        let px = f(c.camera_pixels);
        terms.push((
            "camera images",
            8.0 * px * (wave * w + w + w + 4.0 * w + 4.0),
        ));
    }
    terms
}
