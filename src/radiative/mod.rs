//! The Radiative stage's engine: DART flux tracking over the cell grid (see [`engine`]) and
//! the 3D digital differential analyser it walks the grid with ([`dda`]), and the pixel grid
//! of its orthographic images ([`images`]).

pub mod dda;
pub mod emission;
pub mod engine;
pub mod fastmath;
pub mod images;
#[cfg(target_arch = "x86_64")]
pub mod lanes;
pub mod products;
pub mod thermal;
pub mod toa;
mod walk;

/// Above this many (facet × direction) pairs, facets use the renormalised cosine fractions
/// instead of exact projected solid angles (memory and set-up time).
pub const EXACT_FRACTIONS_LIMIT: usize = 20_000_000;

/// What the Radiative stage's memory depends on, counted before anything is allocated (from
/// the Maket plan, the direction set and the launch plan).
#[derive(Debug, Clone, Default)]
pub struct RadiativeCounts {
    /// Tiling directions N (regular + exact + oversampled).
    pub n_dirs: usize,
    /// Downward tiling directions (sky launch directions).
    pub n_down: usize,
    /// Interception slots per store (sectors or directions, + the sun's).
    pub slots: usize,
    /// (power stores, point pairs) per turbid entry: (1, 1) with `turbid_subfaces: Off`, (S, S)
    /// with `Faces` / `Subfaces` (S = 7 or 6 D² + 1; the worst case of every store touched),
    /// (1, slots) with `Blend`.
    pub turbid_stores: (usize, usize),
    /// Bands.
    pub n_bands: usize,
    /// Whether the scene has sky light (a second channel set per band).
    pub sky: bool,
    /// Turbid materials with phase tables.
    pub turbid_materials: usize,
    /// Turbid entries (cell, material) (the Maket plan's count).
    pub turbid_entries: usize,
    /// Facet–cell references (the Maket plan's count).
    pub facet_refs: usize,
    /// Facets.
    pub n_facets: usize,
    /// Scattering points of the two-sided facets (leaves: they scatter into every direction):
    /// (facet, cell, sub-cell) pieces, sub-cells of the launch plan's factor D.
    pub facet_points: usize,
    /// Rays the one-sided facets' scattering points send per scattering iteration: (downward,
    /// upward) (each point sends one ray per direction of its normal's hemisphere, of which a
    /// share θ/π points down for a normal at zenith angle θ).
    pub one_sided_rays: (f64, f64),
    /// Grid columns.
    pub n_columns: usize,
    /// Whether the ground is the flat plane z0 (ground stores per column).
    pub flat_ground: bool,
    /// Sub-cell factor D of the facet and ground scattering points (launch plan).
    pub subcells: usize,
    /// Sun launch points (launch plan).
    pub sun_points: usize,
    /// Sky launch points per downward direction (launch plan; 0 without sky light).
    pub sky_points: usize,
    /// Orthographic images (exact upward directions).
    pub n_images: usize,
    /// Pixels of all images together.
    pub image_pixels: usize,
    /// Worker threads.
    pub threads: usize,
    /// Thermal emission (issue #34): `Some(solar)` in a `T` (false) or `R+T` (true) run.
    pub thermal: Option<bool>,
}

/// Memory the Direction/Phase/Radiative stages hold at their peak, bytes, as named terms
/// (`f64` so that absurd counts saturate instead of overflowing):
///
/// * `phase tables`: f32, N+1 rows × N columns per turbid material and band.
/// * `facet fractions`: exact Lambertian fractions, 2 N f32 per facet (and its two vectors'
///   headers), when facets × N ≤ [`EXACT_FRACTIONS_LIMIT`].
/// * `interception stores`: two generations (the one being scattered, the one being filled)
///   of `entries × stores × slots × channels` f64 and the point records, facet front/back
///   stores per reference, ground stores per column.
/// * `turbid accumulators`: one dense turbid accumulator per worker thread
///   ([`engine::dense_bytes`], at most [`engine::DENSE_BYTES`]), and the compacted turbid
///   records of the chunks held (as many as for [`chunk_event_bytes`]; a chunk's rays cross
///   the whole scene, so each holds up to every entry's records: an 8-byte key and the same
///   values).
/// * `facet packs`: the facets of each cell in `f32` for the scan prefilter
///   ([`FacetPacks::bytes_for`](crate::geometry::facet_packs::FacetPacks::bytes_for)).
/// * `chunk events`: [`chunk_event_bytes`].
/// * `products`: absorbed and intercepted power per turbid entry, facet and column, the
///   increments of the extrapolation (three copies) and the images (result and two snapshots).
pub fn memory_terms(c: &RadiativeCounts) -> Vec<(&'static str, f64)> {
    let f = |x: usize| x as f64;
    let nd = f(c.n_dirs);
    let nb = f(c.n_bands);
    let w = channels(c);
    let tables = f(c.turbid_materials) * nb * ((nd + 1.0) * nd * 4.0 + 3.0 * (nd + 1.0) * 8.0);
    let fractions = if c.n_facets.saturating_mul(c.n_dirs) <= EXACT_FRACTIONS_LIMIT {
        f(c.n_facets) * (2.0 * nd * 4.0 + 48.0)
    } else {
        0.0
    };
    let (ts, tp) = (f(c.turbid_stores.0.max(1)), f(c.turbid_stores.1.max(1)));
    let entries = f(c.turbid_entries);
    let slots = f(c.slots);
    let cols = f(c.n_columns);
    let stores = 2.0
        * 8.0
        * (entries * (ts * slots * w + tp * 8.0)
            + f(c.facet_refs) * (2.0 * w + 4.0)
            + cols * (w + 4.0));
    // Per index ([`engine::dense_bytes`]): slots × channels power values, 7 point values per
    // record, 8 values of the single-precision walk's local points, and its 4-byte record
    // number; a chunk's records fill a prefix, and its rays cross the whole scene, so every
    // entry's record is taken.
    let per_index = f(engine::dense_bytes(
        1,
        c.slots,
        w as usize,
        c.turbid_stores.1.max(1),
        true,
    ));
    let accumulator = (entries * ts * per_index).min(f(engine::DENSE_BYTES));
    let compact = entries * ts * (per_index + 16.0);
    let held = f(engine::ahead(c.threads));
    let exit_groups = if ts > 1.0 {
        f(c.threads) * 8.0 * nd * ts * (w + 4.0)
    } else {
        0.0
    };
    let mut products = 8.0 * w * (3.0 * 2.0 * (entries + f(c.n_facets) + cols) + 2.0 * nd)
        + 3.0 * 8.0 * w * f(c.image_pixels);
    if let Some(solar) = c.thermal {
        // ε B per element and band, the emitting elements (16 bytes each), and in `R+T` the
        // solar run's result held while the thermal run goes, then both joined.
        products +=
            8.0 * nb * (entries + f(c.n_facets) + cols) + 16.0 * (entries + f(c.n_facets) + cols);
        if solar {
            products += 2.0 * 8.0 * w * (2.0 * (entries + f(c.n_facets) + cols) + nd)
                + 2.0 * 8.0 * w * f(c.image_pixels);
        }
    }
    vec![
        ("phase tables", tables),
        ("facet fractions", fractions),
        ("interception stores", stores),
        (
            "turbid accumulators",
            f(c.threads) * accumulator + held.min(16.0) * compact + exit_groups,
        ),
        (
            "facet packs",
            crate::geometry::facet_packs::FacetPacks::bytes_for(c.facet_refs),
        ),
        ("chunk events", chunk_event_bytes(c)),
        ("products", products),
    ]
}

/// Channels per element of the largest run: bands × (1 + sky) for the solar run, bands × 2
/// (the zero sun set and the thermal one) for a thermal run.
fn channels(c: &RadiativeCounts) -> f64 {
    let nb = c.n_bands as f64;
    let solar = nb * if c.sky { 2.0 } else { 1.0 };
    if c.thermal.is_some() {
        solar.max(2.0 * nb)
    } else {
        solar
    }
}

/// Share of the upward rays of a scattering iteration that meet a facet (an event) before
/// they escape; every downward ray ends in an event (on the ground or a facet). Calibrated on
/// the example scenes (docs/performance.md, "Memory").
pub const UPWARD_HIT_SHARE: f64 = 0.25;

/// Event lists of the flux tracking's chunks in flight, bytes. A chunk keeps the facet,
/// ground and image hits of its rays (per hit a key of 12–20 bytes and the channel powers,
/// hit point and weight: 8 (W + 4) bytes) until it is merged; chunks are merged in order as
/// they finish, so at most [`engine::ahead`] + threads chunks of a pass are held (and their
/// recycled allocations); the finished chunks waiting for their turn and the running ones
/// rarely reach that bound together, and [`engine::ahead`] chunks (2 per thread + 2) are
/// taken (on the example scenes the event memory measured is 50–85 % of the in-flight
/// bound). A pass is cut into 16 chunks, or into more of at most
/// [`engine::CHUNK_RAYS`] nominal rays (2 N per scattering emitter). The largest pass is the
/// launch (each sun ray and each sky ray per downward direction ends in one hit) or a
/// scattering iteration: every turbid entry sends a ray pair along every direction, every
/// two-sided facet scattering point a ray along every direction, one-sided ones along the
/// directions of their normal's hemisphere, ground sub-columns along every upward direction;
/// every downward ray and a share [`UPWARD_HIT_SHARE`] of the upward ones end in a hit, and
/// each emitter adds one image event per image direction.
pub fn chunk_event_bytes(c: &RadiativeCounts) -> f64 {
    let f = |x: usize| x as f64;
    let w = channels(c);
    let nd = f(c.n_dirs);
    let n_down = f(c.n_down);
    let n_up = nd - n_down;
    let ground_points = if c.flat_ground {
        f(c.n_columns) * f(c.subcells.max(1)).powi(2)
    } else {
        0.0
    };
    // A thermal run's emission pass: the ground emits from up to (4 D)² points per column
    // (at most 2²² in the scene; `engine::thermal`).
    let ground_points = if c.thermal.is_some() && c.flat_ground {
        (16.0 * ground_points).min(f(1 << 22)).max(ground_points)
    } else {
        ground_points
    };
    let hit = 16.0 + 8.0 * (w + 4.0);
    let image = 36.0 + 8.0 * w;
    let in_flight = f(engine::ahead(c.threads));
    // Share of a pass held: the chunks in flight out of the pass's chunks.
    let held = |items: f64, nominal_rays: f64| {
        let chunks = items
            .min(16.0)
            .max((nominal_rays / f(engine::CHUNK_RAYS)).ceil())
            .max(1.0);
        (in_flight / chunks).min(1.0)
    };
    let launch_rays = f(c.sun_points) + f(c.sky_points) * n_down;
    let rows = (f(c.sun_points).sqrt()
        + if c.sky_points > 0 {
            f(c.sky_points).sqrt()
        } else {
            0.0
        })
    .max(1.0);
    let launch = launch_rays * hit * held(rows, launch_rays);
    let two_sided = 2.0 * f(c.turbid_entries) + f(c.facet_points);
    let emitters = two_sided + ground_points;
    let down = n_down * two_sided + c.one_sided_rays.0;
    let up = n_up * (two_sided + ground_points) + c.one_sided_rays.1;
    let scatter_items = f(c.turbid_entries) + f(c.facet_refs) + f(c.n_columns);
    let scatter = ((down + UPWARD_HIT_SHARE * up) * hit + emitters * f(c.n_images) * image)
        * held(scatter_items, scatter_items * 2.0 * nd);
    launch.max(scatter)
}
