//! The Radiative stage's engine: DART flux tracking over the cell grid (see [`engine`]) and
//! the 3D digital differential analyser it walks the grid with ([`dda`]), and the pixel grid
//! of its orthographic images ([`images`]).

pub mod dda;
pub mod engine;
pub mod fastmath;
pub mod images;
#[cfg(target_arch = "x86_64")]
pub mod lanes;
pub mod products;
mod walk;

/// Above this many (facet × direction) pairs, facets use the renormalised cosine fractions
/// instead of exact projected solid angles (memory and set-up time).
pub const EXACT_FRACTIONS_LIMIT: usize = 20_000_000;

/// Memory the Direction/Phase/Radiative stages need, bytes: phase tables (f32, N+1 rows × N
/// columns per used turbid material and band), exact facet fractions (2N f32 per facet), and
/// the interception stores (two generations of `entries × slots × channels` f64, plus facet and
/// ground stores and up to 16 dense chunk accumulators of at most 8 MiB), and the orthographic
/// images (`image_pixels` = pixels of all images together; three copies: the result and the two
/// snapshots of the extrapolation). `turbid_stores` = (power stores, point pairs) per turbid
/// entry: (1, 1) with `turbid_subfaces: Off`, (S, S) with `Faces` / `Subfaces` (S = 7 or
/// 6 D² + 1; the worst case of every store touched), (1, slots) with `Blend`.
#[allow(clippy::too_many_arguments)]
pub fn memory_estimate(
    n_dirs: usize,
    slots: usize,
    turbid_stores: (usize, usize),
    n_bands: usize,
    sky: bool,
    turbid_materials: usize,
    turbid_entries: usize,
    facet_refs: usize,
    n_facets: usize,
    n_columns: usize,
    image_pixels: usize,
) -> u64 {
    let w = n_bands * if sky { 2 } else { 1 };
    let tables = turbid_materials * n_bands * crate::phase::bytes(n_dirs + 1, n_dirs, 1);
    let fractions = if n_facets * n_dirs <= EXACT_FRACTIONS_LIMIT {
        n_facets * 2 * n_dirs * 4
    } else {
        0
    };
    let (ts, tp) = (turbid_stores.0.max(1), turbid_stores.1.max(1));
    let stores = 2
        * 8
        * (turbid_entries * (ts * slots * w + tp * 8)
            + facet_refs * (2 * w + 4)
            + n_columns * (w + 4));
    let products = 8 * w * (3 * turbid_entries + 3 * n_facets + 3 * n_columns + n_dirs);
    let chunks = 16
        * 8
        * ((turbid_entries * ts * slots * w).min(1 << 20) + (turbid_entries * tp * 7).min(1 << 20));
    // Exit groups of the face stores (per worker thread: n_dirs × stores × (w + 4) values).
    let exit_groups = if ts > 1 {
        rayon::current_num_threads() * 8 * n_dirs * ts * (w + 4)
    } else {
        0
    };
    let images = 3 * 8 * w * image_pixels;
    (tables + fractions + stores + products + chunks + images + exit_groups) as u64
}
