//! The shared tracking context of one run ([`Ctx`]; DART 5 paper §4): turbid material indices,
//! tiling directions, peel-off views with their G and hotspot terms (physics.md §3.5), the
//! empty-space skip field, the per-cell facet boxes, the per-column vertical optical depths of
//! receiver mode ([`ColumnDepth`], physics.md §9.2), the LiDAR [`Receiver`] and the photon
//! state ([`Photon`]).

use super::input::{PhotonInput, PhotonOptics};
use super::result::Summary;
use super::walk::MIN_SKIP_DISTANCE;
use crate::photon::sampling::AliasTable;
use crate::photon::small::Small;
use crate::radiative::dda::skip_field;
use glam::DVec3;

/// How a transmittance ray leaves the grid box.
pub(crate) enum ExitTo {
    /// Through the top (or out of an isolated scene toward the receiver): done.
    Receiver,
    /// Through the bottom, or lost: zero transmittance.
    Blocked,
    /// Through a repetitive side: continues from this re-entry point.
    Wrapped(DVec3),
}

/// Where a flight ends.
pub(crate) enum Hit {
    /// Volume collision in cell `c` at point `p`.
    Volume { c: usize, p: DVec3 },
    /// Facet `f` at point `p`.
    Facet { f: u32, p: DVec3 },
    /// Flat ground at point `p`.
    Ground { p: DVec3 },
    /// Left through the top at `p`.
    Escape,
    /// Lost (isolated side, bottom leak, crossing cap).
    Lost,
}

#[derive(Clone)]
pub(crate) struct Ctx<'a> {
    pub(crate) inp: &'a PhotonInput<'a>,
    pub(crate) nb: usize,
    pub(crate) w: usize,
    pub(crate) sum: Summary,
    pub(crate) size: (f64, f64),
    /// Turbid material index per material id (u32::MAX: not turbid).
    pub(crate) tur_mat: Vec<u32>,
    /// Material ids of turbid materials.
    pub(crate) tur_ids: Vec<u32>,
    /// G toward each view `[view][turbid material]`.
    pub(crate) g_view: Vec<Vec<f64>>,
    /// Hotspot terms per view and turbid material (see
    /// [`crate::radiative::engine::hotspot_terms`]) for the peel-off of first-order sun
    /// photons; empty rows when no material has a leaf size.
    pub(crate) hs_view: Vec<Vec<[f64; 2]>>,
    /// Leaf dimension per turbid material, m (hotspot; all zero: none).
    pub(crate) hs_leaf: Vec<f64>,
    /// G of the sun direction per tracked turbid material when some material has a leaf size
    /// (the hotspot terms of first-order sun flights, [`Ctx::fly_hotspot`]); empty otherwise.
    pub(crate) g_sun: Vec<f64>,
    /// Tiling direction vectors.
    pub(crate) omega: Vec<DVec3>,
    /// Sector containing each view and its solid angle (discrete-mode peel-off).
    pub(crate) view_sector: Vec<usize>,
    /// LiDAR receiver (receiver mode: peel-off toward it instead of the views).
    pub(crate) receiver: Option<Receiver>,
    /// Per cell: 0 when it has something to interact with (a facet, a turbid entry with a
    /// density, a fluid), else its chessboard distance in cells to the nearest such cell
    /// ([`skip_field`]: 1 for a cell crossed one by one, and for every empty cell when
    /// [`PhotonParams::skip_empty`](crate::photon::engine::PhotonParams::skip_empty) is off). Walks cross an empty cell without looking at its
    /// contents, and flights from a cell at distance r ≥ 2 jump over the box of cells within
    /// r − 1
    /// (same results bit for bit: an empty cell adds nothing to optical depths and draws no
    /// random numbers).
    pub(crate) empty: std::sync::Arc<[u8]>,
    /// Receiver mode: the end of the range gate (path length, m); photons that can no longer
    /// be recorded before it are dropped (booked as lost, see [`Ctx::beyond_gate`]).
    pub(crate) max_path: f64,
    /// Receiver mode: the first flight from the emitter uses [`Ctx::first_flight`] (one walk,
    /// first order stratified by digitiser bin) instead of [`Ctx::forced_peel`] + [`Ctx::fly`].
    pub(crate) stratified: bool,
    /// Receiver mode: survival probability of a photon past its first interaction (Russian
    /// roulette into multiple scattering, weight divided by it; 1: every photon goes on).
    pub(crate) continue_prob: f64,
    /// Receiver mode: per-column vertical optical-depth sums for the return transmittance of
    /// peel-offs whose ray to the receiver stays in one grid column ([`ColumnDepth`]).
    pub(crate) columns: Option<std::sync::Arc<ColumnDepth>>,
    /// Receiver mode ([`LidarEstimator::ExpectedValue`](crate::scene::desc::LidarEstimator::ExpectedValue)): expected-value multiple-scattering
    /// return along every flight past the first ([`Ctx::scatter_flight`]) with the stop factor
    /// `c` ≥ 1, and expected-value first-order ground return in [`Ctx::first_flight`] (0: off,
    /// the collision estimator).
    pub(crate) ms_stop: f64,
    /// Receiver mode ([`LidarEstimator::ExpectedValue`](crate::scene::desc::LidarEstimator::ExpectedValue)): the far-photon roulette's distance
    /// scale ρ₀ (m) and the tangent of the receiver's FOV half-angle (see
    /// [`far_roulette_survival`](crate::photon::engine::events::far_roulette_survival)); ρ₀ = 0: off.
    pub(crate) far_roulette: (f64, f64),
    /// Per cell (empty: the scene has no facets): a box `[lo, hi]` (x, y, z lo then hi) that
    /// holds every point of the cell's facets near the cell ([`facet_boxes`]); a ray segment
    /// that misses it hits none of them ([`Ctx::facet_hit`], [`Ctx::facet_behind`]).
    pub(crate) facet_box: std::sync::Arc<[[f64; 6]]>,
    /// The facets of each cell in `f32` for the prefilter of the facet scans
    /// ([`Ctx::facet_hit`], [`Ctx::facet_behind`]); empty when the scene has none.
    pub(crate) packs: std::sync::Arc<crate::geometry::facet_packs::FacetPacks>,
    /// Discrete sampler: the upward tiling directions (their ids) and an alias table of their
    /// projected solid angles `∫ μ dΩ` (π in all), for the Lambertian flat ground's reflection
    /// ([`Ctx::ground_direction`]); `None` with the continuous sampler.
    pub(crate) ground_dirs: Option<(AliasTable, Vec<u32>)>,
    /// Frame cameras of the sensor stage ([`Ctx::peel_cameras`]); empty: none.
    pub(crate) cameras: std::sync::Arc<[super::camera::CameraPeel]>,
    /// Length of a batch's camera tally ([`BatchOut::cams`](super::tally::BatchOut)).
    pub(crate) cam_len: usize,
}

/// Per cell, the bounding box of the cell's facets (their vertices' box, widened by a margin
/// `m`) cut to the cell widened by `2m`, with `m` four hit tolerances plus 1e-9 of the sum of
/// the largest |coordinate| and the largest cell side: a facet hit that [`Ctx::facet_hit`] accepts lies on the facet
/// (barycentric slack 1e-12) within the hit tolerance of the cell segment, so inside this box
/// (rounding included); cells without facets get an empty box. Empty when the scene has none.
pub(crate) fn facet_boxes(inp: &PhotonInput) -> Vec<[f64; 6]> {
    let spec = inp.spec;
    let grid = inp.grid;
    let n_cells = spec.n_cells();
    if grid.facet_ids.is_empty() || grid.facet_start.len() != n_cells + 1 {
        return Vec::new();
    }
    let tol = spec.hit_tolerance();
    let far = inp
        .facets
        .iter()
        .flat_map(|f| f.v.iter())
        .fold(0.0f64, |a, v| a.max(v.abs().max_element()));
    let m = 4.0 * tol + 1e-9 * (far + spec.cell.max_element());
    // Cells without facets: an empty box (lo > hi), which no ray meets.
    const EMPTY: [f64; 6] = [1.0, 1.0, 1.0, -1.0, -1.0, -1.0];
    let mut out = vec![EMPTY; n_cells];
    for (c, b) in out.iter_mut().enumerate() {
        let ids = grid.facets_of(c);
        if ids.is_empty() {
            continue;
        }
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(-f64::INFINITY));
        for &f in ids {
            for v in &inp.facets[f as usize].v {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
        }
        let [i, j, k] = spec.ijk(c);
        let (clo, chi) = spec.cell_box(i as i64, j as i64, k as i64);
        let lo = (lo - m).max(clo - 2.0 * m);
        let hi = (hi + m).min(chi + 2.0 * m);
        *b = [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z];
    }
    out
}

/// Whether the ray `o + t d`, `t ∈ [ta, tb]`, meets the box `b` (slab test; a NaN bound from
/// a degenerate direction component keeps the ray: conservative).
#[inline]
pub(crate) fn ray_meets_box(b: &[f64; 6], o: DVec3, d: DVec3, ta: f64, tb: f64) -> bool {
    let (mut lo, mut hi) = (ta, tb);
    for a in 0..3 {
        let (bl, bh) = (b[a], b[a + 3]);
        if d[a] != 0.0 {
            let inv = 1.0 / d[a];
            let (t1, t2) = ((bl - o[a]) * inv, (bh - o[a]) * inv);
            lo = lo.max(t1.min(t2));
            hi = hi.min(t1.max(t2));
        } else if !(o[a] >= bl && o[a] <= bh) {
            return false;
        }
    }
    lo <= hi
}

/// Per-column cumulative vertical leaf-area sums of the tracked turbid materials (computed once
/// per LiDAR run), giving the exact return transmittance of a point whose straight ray to a
/// receiver above the grid stays in the point's column and meets no facet (DART 5 paper §4,
/// physics.md §9.2): such a ray crosses the cells above the point with path lengths `Δz/u_z`,
/// so its optical depth is `Σ_m G_m(u) [A_m(c) + u_{f,m}(c)(z_top(c) − z)]/u_z`, where
/// `A_m(c) = Σ_{cells above c} u_{f,m} Δz` (m² m⁻², one-sided leaf area above the cell) and
/// `u_{f,m}(c)` (m² m⁻³) is the density of the point's own cell. Equal to the shadow walk of
/// [`Ctx::transmittance`] to rounding (debug builds check every use against it).
pub(crate) struct ColumnDepth {
    /// Tracked turbid materials.
    pub(crate) ntm: usize,
    /// `above[c·ntm + tm]`: `A_m(c)`, m² m⁻².
    pub(crate) above: Vec<f64>,
    /// `dens[c·ntm + tm]`: `u_{f,m}(c)`, m² m⁻³.
    pub(crate) dens: Vec<f64>,
    /// Whether cell c and every cell above it hold no facet and no fluid.
    pub(crate) clear: Vec<bool>,
}

/// Debug builds: how many return transmittances were taken from the column sums
/// (`ColumnDepth`), each checked against the shadow walk it replaces (for the tests).
#[cfg(debug_assertions)]
pub static COLUMN_RETURNS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Largest `cells × tracked materials` of a [`ColumnDepth`] (two f64 arrays: 128 MiB); larger
/// grids keep the shadow walk.
pub(crate) const MAX_COLUMN_ENTRIES: usize = 1 << 23;

impl ColumnDepth {
    pub(crate) fn new(ctx: &Ctx) -> Option<Self> {
        let spec = ctx.inp.spec;
        let grid = ctx.inp.grid;
        let ntm = ctx.tur_ids.len();
        let n_cells = spec.n_cells();
        if ntm == 0
            || n_cells * ntm > MAX_COLUMN_ENTRIES
            || grid.turbid_start.len() != n_cells + 1
            || grid.facet_start.len() != n_cells + 1
        {
            return None;
        }
        let mut above = vec![0.0; n_cells * ntm];
        let mut dens = vec![0.0; n_cells * ntm];
        let mut clear = vec![false; n_cells];
        let (nx, ny, nz) = (spec.n[0], spec.n[1], spec.n[2]);
        for j in 0..ny {
            for i in 0..nx {
                let mut acc: PerMaterial<f64> = Small::from_elem(0.0, ntm);
                let mut ok = true;
                for k in (0..nz).rev() {
                    let c = spec.index(i, j, k);
                    for e in grid.turbid_of(c) {
                        let tm = ctx.tur_mat[e.material as usize];
                        if tm != u32::MAX {
                            dens[c * ntm + tm as usize] += e.density as f64;
                        }
                    }
                    ok &=
                        grid.facet_start[c] == grid.facet_start[c + 1] && ctx.fluid_of(c).is_none();
                    clear[c] = ok;
                    for tm in 0..ntm {
                        above[c * ntm + tm] = acc[tm];
                        acc[tm] += dens[c * ntm + tm] * spec.cell.z;
                    }
                }
            }
        }
        Some(Self {
            ntm,
            above,
            dens,
            clear,
        })
    }
}

/// A LiDAR receiver (DART 5 paper §4; physics.md §9.2): peel-off goes toward a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Receiver {
    /// Position (unwrapped scene coordinates), m.
    pub position: DVec3,
    /// Looking direction (unit, from the receiver toward the scene).
    pub axis: DVec3,
    /// Cosine of the field-of-view half-angle.
    pub cos_fov: f64,
    /// Aperture area, m².
    pub aperture_m2: f64,
}

/// Per-band values of one photon (inline up to 4 bands: no allocation per event).
pub(crate) type Bands = Small<f64, 4>;

/// Per-turbid-material scratch (inline up to 8 materials).
pub(crate) type PerMaterial<T> = Small<T, 8>;

/// Photon state.
pub(crate) struct Photon {
    pub(crate) p: DVec3,
    pub(crate) d: DVec3,
    /// Path length travelled since emission, m (LiDAR timing).
    pub(crate) path: f64,
    /// Unwrapped position minus wrapped position (repetitive scenes), m.
    pub(crate) shift: DVec3,
    /// Discrete direction index (tiling index, or n_dirs for the sun) in discrete mode.
    pub(crate) di: usize,
    /// Weight per band (inline up to 4 bands).
    pub(crate) w: Bands,
    pub(crate) w0: f64,
    /// Channel offset (0: sun, nb: sky).
    pub(crate) off: usize,
    pub(crate) order: u32,
    pub(crate) skip_facet: Option<u32>,
    /// Receiver mode: still on the straight flight from the emitter (order 0, no facet passed
    /// through), so the return path to the (monostatic) receiver is this flight reversed.
    pub(crate) direct: bool,
    /// Receiver mode: transmittance back to the receiver of the current event, when the
    /// forced walk of the first flight already computed it (see [`Ctx::forced_peel`]).
    pub(crate) ret: Option<Bands>,
    /// Receiver mode: the walk of the current flight reached the Lambertian flat ground (or,
    /// first flight, a Lambertian facet) and scored its return with the expected value
    /// ([`Ctx::first_flight`] and [`Ctx::scatter_flight`] of [`LidarEstimator::ExpectedValue`](crate::scene::desc::LidarEstimator::ExpectedValue)),
    /// so the surface collision of this flight is not peeled off.
    pub(crate) surface_scored: bool,
    /// Receiver mode: the uniform of the first flight's free path (`τ* = −ln(1 − u)`), from
    /// the pulse's beam-ray lattice ([`Ctx::first_flight`]); `None`: drawn from the stream.
    pub(crate) first_u: Option<f64>,
    /// Receiver mode: a beam ray whose first-order return is part of the pulse's column
    /// quadrature (`lidar::tracking`'s `FirstOrderColumns`): its first flight only samples the collision (the
    /// first-order return of its whole flight, surface included, is not scored again).
    pub(crate) first_order_done: bool,
    /// Path length (m, [`Photon::path`]) at the photon's last scattering event: the origin of
    /// the distance s of the hotspot-corrected first flight after a first-order sun event
    /// ([`Ctx::fly_hotspot`]).
    pub(crate) scatter_path: f64,
    /// After a hotspot-corrected flight ([`Ctx::fly_hotspot`]) ending in a turbid collision:
    /// the local effective G per tracked turbid material at the collision point
    /// (`G − b e^{−c s}`, 0 where the crossing's clamped depth is still 0), from which the
    /// collided material is drawn; empty otherwise (then G of the flight).
    pub(crate) hs_k: PerMaterial<f64>,
}

impl<'a> Ctx<'a> {
    /// The shared tracking context: turbid material indices, tiling directions, peel-off views
    /// (G and sector per view), `nb` bands and `w` channels; no receiver.
    pub(crate) fn new(inp: &'a PhotonInput<'a>, nb: usize, w: usize) -> Self {
        let spec = inp.spec;
        let mut tur_mat = vec![u32::MAX; inp.optics.len()];
        let mut tur_ids = Vec::new();
        for (i, o) in inp.optics.iter().enumerate() {
            if matches!(o, PhotonOptics::Turbid { .. }) {
                tur_mat[i] = tur_ids.len() as u32;
                tur_ids.push(i as u32);
            }
        }
        let tiling = inp.dirs.tiling();
        let mut ctx = Ctx {
            inp,
            nb,
            w,
            sum: Summary {
                w,
                n_dirs: tiling.len(),
                n_views: inp.views.len(),
                atm_layers: inp.atmosphere.map_or(0, |a| a.n_layers()),
            },
            size: (
                spec.n[0] as f64 * spec.cell.x,
                spec.n[1] as f64 * spec.cell.y,
            ),
            tur_mat,
            tur_ids,
            g_view: Vec::new(),
            hs_view: Vec::new(),
            hs_leaf: Vec::new(),
            g_sun: Vec::new(),
            omega: tiling.iter().map(|d| d.omega).collect(),
            view_sector: inp.views.iter().map(|v| inp.dirs.find_sector(*v)).collect(),
            receiver: None,
            max_path: f64::INFINITY,
            stratified: false,
            continue_prob: 1.0,
            columns: None,
            ms_stop: 0.0,
            far_roulette: (0.0, 0.0),
            empty: std::sync::Arc::from(Vec::new()),
            facet_box: std::sync::Arc::from(facet_boxes(inp)),
            packs: std::sync::Arc::new(inp.grid.facet_packs(inp.spec, inp.facets)),
            ground_dirs: None,
            cameras: std::sync::Arc::from(Vec::new()),
            cam_len: 0,
        };
        if inp.params.sampler.is_discrete() {
            let (ids, weights): (Vec<u32>, Vec<f64>) = tiling
                .iter()
                .enumerate()
                .filter(|(_, d)| d.is_upward() && d.projected_sr > 0.0)
                .map(|(i, d)| (i as u32, d.projected_sr))
                .unzip();
            ctx.ground_dirs = AliasTable::new(&weights).ok().map(|t| (t, ids));
        }
        let grid = inp.grid;
        let empty: Vec<bool> = (0..grid.facet_start.len().saturating_sub(1))
            .map(|c| {
                grid.facet_start[c] == grid.facet_start[c + 1]
                    && grid
                        .turbid_of(c)
                        .iter()
                        .all(|e| ctx.tur_mat[e.material as usize] == u32::MAX || e.density == 0.0)
                    && ctx.fluid_of(c).is_none()
            })
            .collect();
        ctx.empty = if empty.len() == spec.n.iter().product::<usize>() {
            skip_field(spec.n, inp.params.skip_empty, MIN_SKIP_DISTANCE, |c| {
                !empty[c]
            })
            .into()
        } else {
            empty.iter().map(|&e| e as u8).collect()
        };
        ctx.g_view = inp
            .views
            .iter()
            .map(|v| (0..ctx.tur_ids.len()).map(|tm| ctx.g_of(tm, v.z)).collect())
            .collect();
        // Hotspot (physics.md §3.5): the peel-off of a photon's first collision with the direct
        // sun beam goes back through the gaps the sun came through.
        let leaf: Vec<f64> = ctx
            .tur_ids
            .iter()
            .map(|&m| match &inp.optics[m as usize] {
                PhotonOptics::Turbid { leaf_size_m, .. } => *leaf_size_m,
                _ => 0.0,
            })
            .collect();
        if leaf.iter().any(|&l| l > 0.0) {
            let g_sun: Vec<f64> = (0..ctx.tur_ids.len())
                .map(|tm| ctx.g_of(tm, inp.sun.z))
                .collect();
            ctx.hs_view = inp
                .views
                .iter()
                .zip(&ctx.g_view)
                .map(|(&v, gv)| {
                    (0..ctx.tur_ids.len())
                        .map(|tm| {
                            crate::radiative::engine::hotspot_terms(
                                inp.sun, v, g_sun[tm], gv[tm], leaf[tm],
                            )
                        })
                        .collect()
                })
                .collect();
            ctx.g_sun = g_sun;
        }
        ctx.hs_leaf = leaf;
        let (cams, len) = super::camera::camera_peels(&ctx, &inp.cameras, w);
        ctx.cameras = cams.into();
        ctx.cam_len = len;
        ctx
    }
}
