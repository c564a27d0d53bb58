//! Per-chunk and per-run bookkeeping of the flux tracking (DART 5 paper §3.2, physics.md
//! §3.6, §6.3): the turbid accumulators ([`KeyAcc`], [`TurAcc`], [`DenseView`]), one
//! chunk's output ([`ChunkOut`]), the interception stores between iterations ([`Stores`],
//! [`TurRecords`], [`SubPoints`]) and the constants that size them.

use super::*;

/// Emitters (or source rows) are split into this many chunks whatever the thread count
/// (more on large scenes, see [`chunk_len`]), and chunk results are merged in chunk order:
/// deterministic on any number of threads.
pub(in crate::radiative) const N_CHUNKS: usize = 16;

pub use crate::resources::tracking::CHUNK_RAYS;

/// Largest dense turbid accumulator, bytes of address space (one per worker thread, see
/// `stream_chunks`; allocated zeroed, resident only where a chunk's records are written: a
/// prefix of its rows, and 4 B per index); larger index spaces (the incident-face stores of big
/// scenes) use hash maps. A constant, not a share of the machine's memory: the choice selects
/// the walk kernel, and products must not depend on the machine.
pub const DENSE_BYTES: usize = 4 << 30;

/// Largest number of turbid sub-faces per face side D (`Subfaces`: 6 D² + 1 stores per cell;
/// larger sub-cell factors are clamped to it).
pub(in crate::radiative) const MAX_FACE_D: u32 = 8;

/// A segment starting within this fraction of the cell size of a face, pointing into the cell
/// through it, entered through that face (see [`Ctx::entry_store`]).
pub(in crate::radiative) const FACE_TOL: f64 = 1e-9;

/// Hash map of the per-run bookkeeping ([`KeyAcc`], [`TurRecords`], [`SubPoints`]): small
/// integer keys from the scene itself, so foldhash's fixed-seed fast hasher instead of SipHash
/// (SipHash's `hash_one` + `write` were 34 M instructions, 1.2 % of the Default 100 0.2 bench
/// row). Iteration order is never relied on (records are kept in first-touch order or sorted).
pub(in crate::radiative) type FastMap<K, V> =
    std::collections::HashMap<K, V, foldhash::fast::FixedState>;

/// Per-chunk hash-map accumulator of fixed-width records keyed by an index (the turbid
/// accumulators of large grids, see [`TurAcc`]). Accumulation inside a chunk is sequential, so
/// results do not depend on scheduling.
pub(in crate::radiative) struct KeyAcc {
    pub(in crate::radiative) width: usize,
    pub(in crate::radiative) index: FastMap<u64, usize>,
    pub(in crate::radiative) keys: Vec<u64>,
    pub(in crate::radiative) data: Vec<f64>,
}

impl KeyAcc {
    pub(in crate::radiative) fn new(width: usize) -> Self {
        KeyAcc {
            width,
            index: Default::default(),
            keys: Vec::new(),
            data: Vec::new(),
        }
    }

    /// Forgets every record (keeping the allocations).
    pub(in crate::radiative) fn clear(&mut self) {
        self.index.clear();
        self.keys.clear();
        self.data.clear();
    }

    #[inline(always)]
    pub(in crate::radiative) fn get(&mut self, key: u64) -> &mut [f64] {
        let w = self.width;
        let (keys, data) = (&mut self.keys, &mut self.data);
        let off = *self.index.entry(key).or_insert_with(|| {
            keys.push(key);
            data.extend(std::iter::repeat_n(0.0, w));
            data.len() - w
        });
        &mut self.data[off..off + w]
    }

    /// Visits every record that was touched, in first-touch order.
    pub(in crate::radiative) fn for_each(&self, mut f: impl FnMut(u64, &[f64])) {
        for (i, &k) in self.keys.iter().enumerate() {
            f(k, &self.data[i * self.width..(i + 1) * self.width]);
        }
    }
}

/// Per-chunk turbid accumulators: intercepted power per (accumulator index t, incidence slot)
/// and the weighted interception points per (t, point record q < P) (Σw·p_first (3),
/// Σw·p_second (3), Σw), written once per cell crossing. The accumulator index is the turbid
/// entry, or (entry × stores + incident (sub-)face store) with [`TurbidSubfaces`] `Faces` /
/// `Subfaces`; P is 1, or the slot count with `Blend` (points per incidence slot). Dense (small
/// grids, the common case): flat arrays of records in first-touch order ([`record`]: the
/// index → record map is checked once per crossing; the arrays are allocated zeroed for every
/// index, but only the rows of the touched records are ever written, so only those pages are
/// resident), checked once per
/// crossing for both records (every power record of an index comes with a points record);
/// records are visited per touched index, slots ascending, skipping all-zero slots. Sparse
/// (large grids): [`KeyAcc`] hash maps.
pub(in crate::radiative) enum TurAcc {
    Dense {
        ns: usize,
        w: usize,
        np: usize,
        tur: Vec<f64>,
        pts: Vec<f64>,
        /// Points records of the single-precision batched walk (`batch::wide32`), 8 per index:
        /// `[Σ wt p₁, Σ wt p₂, Σ wt, 0]` with p in the frame of the index's cell (its corner
        /// at 0), added to `pts` in scene coordinates at the merge
        /// ([`TurAcc::for_each_pts_local`]); empty when that walk does not run.
        pts_loc: Vec<f64>,
        /// Record of each index plus one (0: not touched in this chunk).
        rec: Vec<u32>,
        /// The touched indices, by record.
        touched: Vec<u32>,
    },
    Sparse {
        ns: usize,
        np: usize,
        tur: KeyAcc,
        pts: KeyAcc,
    },
}

/// The dense accumulator's arrays borrowed once (per ray in the lean tracker), with the
/// channel count `w` that may be a compile-time constant there.
pub(in crate::radiative) struct DenseView<'a> {
    pub(in crate::radiative) ns: usize,
    pub(in crate::radiative) w: usize,
    pub(in crate::radiative) np: usize,
    pub(in crate::radiative) tur: &'a mut [f64],
    pub(in crate::radiative) pts: &'a mut [f64],
    pub(in crate::radiative) rec: &'a mut [u32],
    pub(in crate::radiative) touched: &'a mut Vec<u32>,
}

/// The record of accumulator index `e` in a dense accumulator (`rec`: record + 1 per index, 0
/// when untouched; `touched`: the indices by record), created as the next row at `e`'s first
/// touch. Records are rows in first-touch order, so a chunk's records fill a prefix of the
/// arrays however large the grid.
#[inline(always)]
pub(in crate::radiative) fn record(rec: &mut [u32], touched: &mut Vec<u32>, e: usize) -> usize {
    let r = rec[e];
    if r != 0 {
        return r as usize - 1;
    }
    touched.push(e as u32);
    rec[e] = touched.len() as u32;
    touched.len() - 1
}

impl DenseView<'_> {
    /// One interception by accumulator index `e` from slot `slot`: `pw[ch] · f1 · f2` W per
    /// channel, and the two interception points with weight `wt` into points record `q`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(in crate::radiative) fn add(
        &mut self,
        (e, q): (u32, u32),
        slot: u32,
        pw: &[f64],
        f1: f64,
        f2: f64,
        p1: DVec3,
        p2: DVec3,
        wt: f64,
    ) {
        let r = self.add_power(e as usize, slot, pw, f1, f2);
        let pi = (r * self.np + q as usize) * 7;
        add_points(&mut self.pts[pi..pi + 7], p1, p2, wt);
    }

    /// The power part of a booking: `pw[ch] · f1 · f2` W per channel into (index `e`, `slot`);
    /// returns `e`'s record.
    #[inline(always)]
    pub(in crate::radiative) fn add_power(
        &mut self,
        e: usize,
        slot: u32,
        pw: &[f64],
        f1: f64,
        f2: f64,
    ) -> usize {
        let r = record(self.rec, self.touched, e);
        let w = self.w;
        let s = (r * self.ns + slot as usize) * w;
        for (x, v) in self.tur[s..s + w].iter_mut().zip(pw) {
            *x += v * f1 * f2;
        }
        r
    }

    /// [`DenseView::add`] with `turbid_subfaces: Off` (index = entry, one points record).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(in crate::radiative) fn add_entry(
        &mut self,
        e: u32,
        slot: u32,
        pw: &[f64],
        f1: f64,
        f2: f64,
        p1: DVec3,
        p2: DVec3,
        wt: f64,
    ) {
        let r = self.add_power(e as usize, slot, pw, f1, f2);
        add_points(&mut self.pts[r * 7..r * 7 + 7], p1, p2, wt);
    }
}

impl TurAcc {
    /// The dense arrays borrowed as one [`DenseView`] (`None`: the sparse maps).
    #[inline(always)]
    pub(in crate::radiative) fn view(&mut self) -> Option<DenseView<'_>> {
        match self {
            TurAcc::Dense {
                ns,
                w,
                np,
                tur,
                pts,
                rec,
                touched,
                ..
            } => Some(DenseView {
                ns: *ns,
                w: *w,
                np: *np,
                tur,
                pts,
                rec,
                touched,
            }),
            TurAcc::Sparse { .. } => None,
        }
    }

    /// [`TurAcc::view`] and the single-precision walk's local points records (empty unless
    /// that walk runs).
    #[cfg(target_arch = "x86_64")]
    pub(in crate::radiative) fn view_local(&mut self) -> Option<(DenseView<'_>, &mut [f64])> {
        match self {
            TurAcc::Dense {
                ns,
                w,
                np,
                tur,
                pts,
                pts_loc,
                rec,
                touched,
            } => Some((
                DenseView {
                    ns: *ns,
                    w: *w,
                    np: *np,
                    tur,
                    pts,
                    rec,
                    touched,
                },
                pts_loc,
            )),
            TurAcc::Sparse { .. } => None,
        }
    }

    /// Back to the state [`TurAcc::new`] builds: the dense arrays zeroed on the touched
    /// records (the only rows written), the sparse maps emptied.
    pub(in crate::radiative) fn reset(&mut self) {
        if let TurAcc::Dense {
            pts_loc, touched, ..
        } = self
            && !pts_loc.is_empty()
        {
            pts_loc[..touched.len() * 8].fill(0.0);
        }
        if let Some(v) = self.view() {
            let n = v.touched.len();
            v.tur[..n * v.ns * v.w].fill(0.0);
            v.pts[..n * v.np * 7].fill(0.0);
            for &e in v.touched.iter() {
                v.rec[e as usize] = 0;
            }
            v.touched.clear();
        } else if let TurAcc::Sparse { tur, pts, .. } = self {
            tur.clear();
            pts.clear();
        }
    }

    /// `n_index` accumulator indices, `ns` slots, `w` channels, `np` points records per index.
    /// `local`: with the records of the single-precision batched walk (dense only).
    pub(in crate::radiative) fn new(
        n_index: usize,
        ns: usize,
        w: usize,
        np: usize,
        local: bool,
    ) -> Self {
        if dense_bytes(n_index, ns, w, np, local) <= DENSE_BYTES {
            TurAcc::Dense {
                ns,
                w,
                np,
                tur: vec![0.0; n_index * ns * w],
                pts: vec![0.0; n_index * np * 7],
                pts_loc: if local {
                    vec![0.0; n_index * 8]
                } else {
                    Vec::new()
                },
                rec: vec![0; n_index],
                touched: Vec::new(),
            }
        } else {
            TurAcc::Sparse {
                ns,
                np,
                tur: KeyAcc::new(w),
                pts: KeyAcc::new(7),
            }
        }
    }

    /// One interception by accumulator index `eq.0` from slot `slot`: `pw[ch] · f1 · f2` W per
    /// channel, and the two interception points with weight `wt` into points record `eq.1`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(in crate::radiative) fn add(
        &mut self,
        eq: (u32, u32),
        slot: u32,
        pw: &[f64],
        f1: f64,
        f2: f64,
        p1: DVec3,
        p2: DVec3,
        wt: f64,
    ) {
        if let Some(mut v) = self.view() {
            return v.add(eq, slot, pw, f1, f2, p1, p2, wt);
        }
        if let TurAcc::Sparse { ns, np, tur, pts } = self {
            let rec = tur.get(eq.0 as u64 * *ns as u64 + slot as u64);
            for (r, v) in rec.iter_mut().zip(pw) {
                *r += v * f1 * f2;
            }
            add_points(pts.get(eq.0 as u64 * *np as u64 + eq.1 as u64), p1, p2, wt);
        }
    }

    /// [`TurAcc::add`] with `turbid_subfaces: Off` (index = entry, one points record).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(in crate::radiative) fn add_entry(
        &mut self,
        e: u32,
        slot: u32,
        pw: &[f64],
        f1: f64,
        f2: f64,
        p1: DVec3,
        p2: DVec3,
        wt: f64,
    ) {
        if let Some(mut v) = self.view() {
            return v.add_entry(e, slot, pw, f1, f2, p1, p2, wt);
        }
        if let TurAcc::Sparse { ns, tur, pts, .. } = self {
            let rec = tur.get(e as u64 * *ns as u64 + slot as u64);
            for (r, v) in rec.iter_mut().zip(pw) {
                *r += v * f1 * f2;
            }
            add_points(pts.get(e as u64), p1, p2, wt);
        }
    }

    /// Visits the power records: (`index × ns + slot`, W per channel).
    pub(in crate::radiative) fn for_each_tur(&self, mut f: impl FnMut(u64, &[f64])) {
        match self {
            TurAcc::Dense {
                ns,
                w,
                tur,
                touched,
                ..
            } => {
                for (r, &e) in touched.iter().enumerate() {
                    for slot in 0..*ns {
                        let key = e as usize * *ns + slot;
                        let v = &tur[(r * *ns + slot) * *w..(r * *ns + slot + 1) * *w];
                        if v.iter().any(|&x| x != 0.0) {
                            f(key as u64, v);
                        }
                    }
                }
            }
            TurAcc::Sparse { tur, .. } => tur.for_each(f),
        }
    }

    /// Visits the points records: (`index × np + q`, 7 values); with several records per
    /// index, the ones without weight are skipped.
    pub(in crate::radiative) fn for_each_pts(&self, mut f: impl FnMut(u64, &[f64])) {
        match self {
            TurAcc::Dense {
                np, pts, touched, ..
            } => {
                for (r, &e) in touched.iter().enumerate() {
                    for q in 0..*np {
                        let key = e as usize * *np + q;
                        let v = &pts[(r * *np + q) * 7..(r * *np + q) * 7 + 7];
                        if *np == 1 || v[6] != 0.0 {
                            f(key as u64, v);
                        }
                    }
                }
            }
            TurAcc::Sparse { pts, .. } => pts.for_each(f),
        }
    }

    /// Visits the single-precision walk's points records of the touched indices: (index,
    /// `[Σ wt p₁, Σ wt p₂, Σ wt]` in the index's cell frame); none without that walk.
    pub(in crate::radiative) fn for_each_pts_local(&self, mut f: impl FnMut(u64, &[f64])) {
        if let TurAcc::Dense {
            pts_loc, touched, ..
        } = self
            && !pts_loc.is_empty()
        {
            for (r, &e) in touched.iter().enumerate() {
                let v = &pts_loc[r * 8..r * 8 + 7];
                if v[6] != 0.0 {
                    f(e as u64, v);
                }
            }
        }
    }
}

/// Bytes of a dense turbid accumulator (`TurAcc`) of `n_index` indices, `ns` slots, `w` channels, `np` points
/// records per index (`local`: with the single-precision walk's records), the record map
/// included.
pub fn dense_bytes(n_index: usize, ns: usize, w: usize, np: usize, local: bool) -> usize {
    let per = (ns * w + np * 7 + if local { 8 } else { 0 }) * 8 + 4;
    n_index.saturating_mul(per)
}

/// Items per chunk when `n` items of `rays_per_item` nominal rays each are split into
/// [`N_CHUNKS`] contiguous ranges, or into more when a range would hold more than
/// `chunk_rays` ([`TrackingParams::chunk_rays`]) rays. A function of the scene and settings
/// only (never of the thread count).
pub(in crate::radiative) fn chunk_len(n: usize, rays_per_item: usize, chunk_rays: usize) -> usize {
    let cap = (chunk_rays / rays_per_item.max(1)).max(1);
    n.div_ceil(N_CHUNKS).clamp(1, cap)
}

/// One chunk's turbid records, compacted from the worker's accumulator at the chunk's end in the
/// order the merge reads them ([`TurAcc::for_each_tur`], [`TurAcc::for_each_pts`],
/// [`TurAcc::for_each_pts_local`]): power records (key, W values), points records (key, 7
/// values) and the single-precision walk's local points records (entry, 7 values). Its size is
/// proportional to what the chunk touched, not to the grid.
#[derive(Default)]
pub(in crate::radiative) struct CompactTur {
    w: usize,
    tur_key: Vec<u64>,
    tur_val: Vec<f64>,
    pts_key: Vec<u64>,
    pts_val: Vec<f64>,
    loc_key: Vec<u64>,
    loc_val: Vec<f64>,
}

impl CompactTur {
    /// Takes every record of `acc` (whose power records have `w` values), then resets `acc`.
    pub(in crate::radiative) fn take_from(&mut self, acc: &mut TurAcc, w: usize) {
        self.clear();
        self.w = w;
        acc.for_each_tur(|k, v| {
            self.tur_key.push(k);
            self.tur_val.extend_from_slice(v);
        });
        acc.for_each_pts(|k, v| {
            self.pts_key.push(k);
            self.pts_val.extend_from_slice(v);
        });
        acc.for_each_pts_local(|k, v| {
            self.loc_key.push(k);
            self.loc_val.extend_from_slice(v);
        });
        acc.reset();
    }

    pub(in crate::radiative) fn clear(&mut self) {
        self.tur_key.clear();
        self.tur_val.clear();
        self.pts_key.clear();
        self.pts_val.clear();
        self.loc_key.clear();
        self.loc_val.clear();
    }

    /// The power records as [`TurAcc::for_each_tur`] visited them.
    pub(in crate::radiative) fn for_each_tur(&self, mut f: impl FnMut(u64, &[f64])) {
        for (k, v) in self
            .tur_key
            .iter()
            .zip(self.tur_val.chunks_exact(self.w.max(1)))
        {
            f(*k, v);
        }
    }

    /// The points records as [`TurAcc::for_each_pts`] visited them.
    pub(in crate::radiative) fn for_each_pts(&self, mut f: impl FnMut(u64, &[f64])) {
        for (k, v) in self.pts_key.iter().zip(self.pts_val.chunks_exact(7)) {
            f(*k, v);
        }
    }

    /// The local points records as [`TurAcc::for_each_pts_local`] visited them.
    pub(in crate::radiative) fn for_each_pts_local(&self, mut f: impl FnMut(u64, &[f64])) {
        for (k, v) in self.loc_key.iter().zip(self.loc_val.chunks_exact(7)) {
            f(*k, v);
        }
    }
}

/// Per-chunk results, merged in chunk order.
#[derive(Default)]
pub(in crate::radiative) struct ChunkOut {
    /// Turbid interceptions and interception points while the chunk runs: the worker's
    /// accumulator, lent by [`stream_chunks`] (boxed: taken out for each ray's duration by
    /// moving a pointer); `None` once the chunk has finished.
    pub(in crate::radiative) tur: Option<Box<TurAcc>>,
    /// The finished chunk's turbid records, compacted from `tur`.
    pub(in crate::radiative) ctur: CompactTur,
    /// Facet events: (facet-ref index, facet id, from_front, sub-cell, slot); values: W
    /// intercepted + hit(3) + weight.
    pub(in crate::radiative) fac_key: Vec<(u32, u32, bool, u32, u32)>,
    pub(in crate::radiative) fac_val: Vec<f64>,
    /// Ground events: (column, slot, sub-column); values: W + hit(3) + weight.
    pub(in crate::radiative) gnd_key: Vec<(u32, u32, u32)>,
    pub(in crate::radiative) gnd_val: Vec<f64>,
    pub(in crate::radiative) escaped: Vec<f64>,
    /// Horizontal size (x, y) of the element emitting the ray being traced, m ((0, 0): a
    /// point); set before each [`Ctx::trace`] call, read when the ray escapes.
    pub(in crate::radiative) foot: (f64, f64),
    /// Continuous topography (issue #31): horizontal shift, m, from a DEM ground facet's
    /// scattering point to the centre of its sub-cell column, added to the projected exit
    /// point so that the footprint boxes of the pieces of a sub-cell cut by a facet edge
    /// stay on that sub-cell (the barycentre of a partial piece is off-centre: diagonal
    /// stripes along the DEM triangles' diagonals); (0, 0) otherwise.
    pub(in crate::radiative) foot_shift: (f64, f64),
    /// Image events: image index; exit point projected onto z0 (x, y from the grid origin,
    /// wrapped in repetitive scenes) and footprint (x, y), m; values: W per channel.
    pub(in crate::radiative) img_key: Vec<u32>,
    pub(in crate::radiative) img_pos: Vec<[f64; 4]>,
    pub(in crate::radiative) img_val: Vec<f64>,
    pub(in crate::radiative) lost: Vec<f64>,
    pub(in crate::radiative) absorbed_turbid: Vec<(u32, usize)>,
    pub(in crate::radiative) absorbed_facet: Vec<(u32, usize)>,
    pub(in crate::radiative) absorbed_ground: Vec<(u32, usize)>,
    pub(in crate::radiative) absorbed_val: Vec<f64>,
    pub(in crate::radiative) rays: u64,
    pub(in crate::radiative) crossings: u64,
    /// Empty cells jumped over (see [`RadiativeResult::skipped`]).
    pub(in crate::radiative) skipped: u64,
    /// Thread-seconds spent tracking (see [`RadiativeResult::kernel_seconds`]).
    pub(in crate::radiative) kernel_seconds: f64,
    /// Factor on the ray-power threshold of the ray being traced (1; a turbid incident store's
    /// share of its entry's power while the store emits, see [`emit_turbid_records`]).
    pub(in crate::radiative) ray_scale: f64,
    /// Rays waiting for the batched walk ([`Ctx::queue`], walked by [`Ctx::flush`] before the
    /// chunk ends).
    pub(in crate::radiative) queue: Vec<batch::Queued>,
}

impl ChunkOut {
    /// Empties a merged output for another chunk: the state [`new_out`] builds (zeroed sums,
    /// empty event lists, no counts, threshold factor 1), the arrays keeping their allocations.
    /// The dense turbid accumulator is zeroed on its touched entries only (the only ones ever
    /// written, see [`DenseView::add_power`]).
    pub(in crate::radiative) fn reset(&mut self) {
        // Every field named, so that a new one cannot be forgotten here.
        let ChunkOut {
            tur,
            ctur,
            fac_key,
            fac_val,
            gnd_key,
            gnd_val,
            escaped,
            foot,
            foot_shift,
            img_key,
            img_pos,
            img_val,
            lost,
            absorbed_turbid,
            absorbed_facet,
            absorbed_ground,
            absorbed_val,
            rays,
            crossings,
            skipped,
            kernel_seconds,
            ray_scale,
            queue,
        } = self;
        if let Some(t) = tur.as_deref_mut() {
            t.reset();
        }
        ctur.clear();
        fac_key.clear();
        fac_val.clear();
        gnd_key.clear();
        gnd_val.clear();
        escaped.fill(0.0);
        *foot = (0.0, 0.0);
        *foot_shift = (0.0, 0.0);
        img_key.clear();
        img_pos.clear();
        img_val.clear();
        lost.fill(0.0);
        absorbed_turbid.clear();
        absorbed_facet.clear();
        absorbed_ground.clear();
        absorbed_val.clear();
        (*rays, *crossings, *skipped) = (0, 0, 0);
        *kernel_seconds = 0.0;
        *ray_scale = 1.0;
        queue.clear();
    }
}

/// Mutable per-iteration element stores.
pub(in crate::radiative) struct Stores {
    /// Turbid: `[entry][slot][channel]` intercepted power.
    pub(in crate::radiative) tur: Vec<f64>,
    /// Turbid scattering points per entry: up (sum xyz, w), down (sum xyz, w).
    pub(in crate::radiative) tur_pts: Vec<[f64; 8]>,
    /// Facet refs: `[ref][channel]` reflected-to-front, then transmitted-to-back... stored as
    /// front-side and back-side emitted power.
    pub(in crate::radiative) fac_front: Vec<f64>,
    pub(in crate::radiative) fac_back: Vec<f64>,
    /// RPV/Hapke facet refs: `[brdf ref][slot][channel]` intercepted power (scattered and
    /// absorbed at emission).
    pub(in crate::radiative) fac_slot: Vec<f64>,
    /// Facet-ref scattering points per sub-cell.
    pub(in crate::radiative) fac_pts: SubPoints,
    /// Flat ground per column.
    pub(in crate::radiative) gnd: Vec<f64>,
    /// Ground-column scattering points per sub-column.
    pub(in crate::radiative) gnd_pts: SubPoints,
    /// Turbid stores of the `Faces`, `Subfaces` and `Blend` modes (`tur` and `tur_pts` are
    /// then empty).
    pub(in crate::radiative) trec: TurRecords,
}

/// Turbid stores of the [`TurbidSubfaces`] `Faces`, `Subfaces` and `Blend` modes, sparse (only
/// the stores that intercepted something exist; entries × 6D²+1 dense stores would not fit
/// large scenes): one record per accumulator index t (entry × stores + incident store, or the
/// entry for `Blend`), created at first touch in merge order (deterministic), with the power
/// `[slot][channel]` (W) and the points `[q][8]` (q < `np`; up Σw·xyz, Σw, down Σw·xyz, Σw;
/// w = intercepted power summed over channels, W). [`TurRecords::finish`] sorts the records by
/// index, so the records of one entry are consecutive, stores ascending.
#[derive(Default)]
pub(in crate::radiative) struct TurRecords {
    pub(in crate::radiative) ns_w: usize,
    pub(in crate::radiative) np: usize,
    pub(in crate::radiative) index: FastMap<u32, u32>,
    pub(in crate::radiative) keys: Vec<u32>,
    pub(in crate::radiative) pow: Vec<f64>,
    pub(in crate::radiative) pts: Vec<f64>,
    /// After `finish`: record numbers sorted by index.
    pub(in crate::radiative) order: Vec<u32>,
}

impl TurRecords {
    pub(in crate::radiative) fn new(ns_w: usize, np: usize) -> Self {
        TurRecords {
            ns_w,
            np,
            ..Default::default()
        }
    }

    /// Record number of index `t` (created when new).
    pub(in crate::radiative) fn rec(&mut self, t: u32) -> usize {
        let (keys, pow, pts) = (&mut self.keys, &mut self.pow, &mut self.pts);
        let (ns_w, np) = (self.ns_w, self.np);
        *self.index.entry(t).or_insert_with(|| {
            keys.push(t);
            pow.extend(std::iter::repeat_n(0.0, ns_w));
            pts.extend(std::iter::repeat_n(0.0, np * 8));
            keys.len() as u32 - 1
        }) as usize
    }

    pub(in crate::radiative) fn finish(&mut self) {
        let mut order: Vec<u32> = (0..self.keys.len() as u32).collect();
        order.sort_unstable_by_key(|&r| self.keys[r as usize]);
        self.order = order;
        self.index = Default::default();
    }
}

/// Scattering points of elements (facet refs or ground columns) per sub-cell: Σ w·p and Σ w
/// per (element, sub-cell), w = intercepted power summed over channels, W. Accumulated in
/// merge order (deterministic), then sorted by (element, sub-cell) for the emission.
#[derive(Default)]
pub(in crate::radiative) struct SubPoints {
    pub(in crate::radiative) acc: FastMap<(u32, u32), [f64; 4]>,
    /// After `finish`: points of element e are `pts[start[e]..start[e + 1]]`.
    pub(in crate::radiative) start: Vec<u32>,
    /// After `finish`: (barycentre, share of the element's weight).
    pub(in crate::radiative) pts: Vec<(DVec3, f64)>,
}

impl SubPoints {
    #[inline]
    pub(in crate::radiative) fn add(&mut self, elem: u32, sub: u32, p: DVec3, w: f64) {
        let a = self.acc.entry((elem, sub)).or_insert([0.0; 4]);
        a[0] += p.x * w;
        a[1] += p.y * w;
        a[2] += p.z * w;
        a[3] += w;
    }

    /// Sorts the points and turns sums into barycentres and weight shares.
    pub(in crate::radiative) fn finish(&mut self, n_elem: usize) {
        let mut keys: Vec<(u32, u32)> = self.acc.keys().copied().collect();
        keys.sort_unstable();
        let mut total = vec![0.0; n_elem];
        for k in &keys {
            total[k.0 as usize] += self.acc[k][3];
        }
        self.start = vec![0; n_elem + 1];
        self.pts.clear();
        for k in &keys {
            let a = self.acc[k];
            let t = total[k.0 as usize];
            if a[3] > 0.0 && t > 0.0 {
                self.pts
                    .push((DVec3::new(a[0], a[1], a[2]) / a[3], a[3] / t));
                self.start[k.0 as usize + 1] += 1;
            }
        }
        for e in 0..n_elem {
            self.start[e + 1] += self.start[e];
        }
        self.acc = Default::default();
    }

    /// Points of element `e` (empty: the element has no weighted point).
    pub(in crate::radiative) fn of(&self, e: usize) -> &[(DVec3, f64)] {
        match self.start.get(e + 1) {
            Some(&end) => &self.pts[self.start[e] as usize..end as usize],
            None => &[],
        }
    }
}
