//! The tracker's read-only context of one run ([`Ctx`]: flat cell records, G rows, slot
//! rows, launch and walk settings) and its per-ray helpers shared by every walk: incidence
//! slots, incident (sub-)face stores, cell exits, escapes through the top and hits on the
//! flat ground (physics.md §3.6, §5, §6.3; DART 5 paper §3.2).

use super::*;

/// A cell as the tracker reads it: its turbid entries `Ctx::ents[ent_lo..ent_hi]` and its
/// facet refs `CellGrid::facet_ids[fac_lo..fac_hi]` (one 16-byte read per crossing).
#[derive(Debug, Clone, Copy, Default)]
pub(in crate::radiative) struct CellRec {
    pub(in crate::radiative) ent_lo: u32,
    pub(in crate::radiative) ent_hi: u32,
    pub(in crate::radiative) fac_lo: u32,
    pub(in crate::radiative) fac_hi: u32,
}

/// A turbid entry whose material is tracked: entry index (into `CellGrid::turbid`), turbid
/// material slot, and leaf area volume density u_f (m² m⁻³).
#[derive(Debug, Clone, Copy)]
pub(in crate::radiative) struct Ent {
    pub(in crate::radiative) idx: u32,
    pub(in crate::radiative) tm: u32,
    pub(in crate::radiative) density: f64,
}

pub(in crate::radiative) struct Ctx<'a> {
    pub(in crate::radiative) inp: &'a RadiativeInput<'a>,
    pub(in crate::radiative) w: usize,
    pub(in crate::radiative) nb: usize,
    /// First thermal channel (`nb · (1 + sky)`; equal to `w` in a run without them).
    pub(in crate::radiative) thermal_base: usize,
    pub(in crate::radiative) n_dirs: usize,
    pub(in crate::radiative) n_slots: usize,
    /// Direction vectors (tiling) + sun last.
    pub(in crate::radiative) omega: Vec<DVec3>,
    /// Turbid material slot per material id (column of `g_dir`), or u32::MAX.
    pub(in crate::radiative) tur_mat: Vec<u32>,
    /// Number of turbid materials.
    pub(in crate::radiative) n_tm: usize,
    /// G per (direction incl. sun, turbid material): the row of one direction is contiguous.
    pub(in crate::radiative) g_dir: Vec<f64>,
    /// What the tracker reads per cell.
    pub(in crate::radiative) cells: Vec<CellRec>,
    /// Turbid entries with a tracked material, in cell order (see [`CellRec`]).
    pub(in crate::radiative) ents: Vec<Ent>,
    /// Cell index of each turbid entry.
    pub(in crate::radiative) entry_cell: Vec<u32>,
    pub(in crate::radiative) size: (f64, f64),
    /// Ray threshold of a tile of the largest solid angle, W (see
    /// [`TrackingParams::ray_threshold`]); direction j uses `min_ray · ray_factor[j]`.
    pub(in crate::radiative) min_ray: f64,
    /// `ΔΩ_j / ΔΩ_max` per direction (≤ 1; the sun's entry, last, is 1).
    pub(in crate::radiative) ray_factor: Vec<f64>,
    /// Phase rows averaged over each interception slot: `[turbid material][band][slot][dir]`.
    pub(in crate::radiative) slot_rows: Vec<f64>,
    /// BRDF-ground rows averaged over each slot (weights ∫|μ|dΩ): `[band][slot][dir]`.
    pub(in crate::radiative) ground_rows: Vec<f64>,
    /// Sub-cell factor D of the facet and ground scattering points.
    pub(in crate::radiative) sub: u32,
    /// Compact index of each RPV/Hapke facet ref (`u32::MAX`: Lambertian facet).
    pub(in crate::radiative) brdf_ref: Vec<u32>,
    /// Number of RPV/Hapke facet refs.
    pub(in crate::radiative) n_brdf_refs: usize,
    /// RPV/Hapke facet rows averaged over each slot: `[set][band][slot][dir]`.
    pub(in crate::radiative) facet_rows: Vec<f64>,
    /// Hotspot correlation per (tiling direction, turbid material): `[b, c]` per unit path
    /// length, see [`hotspot_terms`]; all zero when the direction goes down or the material has
    /// no leaf size.
    pub(in crate::radiative) hs: Vec<[f64; 2]>,
    /// Whether a first-order sun ray along each tiling direction is hotspot-correlated.
    pub(in crate::radiative) hs_dir: Vec<bool>,
    /// Pixel grid of the orthographic images.
    pub(in crate::radiative) image_grid: ImageGrid,
    /// The scene fits [`Ctx::trace_simple`]: no facets, at most one tracked turbid entry per
    /// cell, no topography offset (hotspot rays always take [`Ctx::trace_w`]).
    pub(in crate::radiative) simple: bool,
    /// Per cell, for [`Ctx::trace_simple`]: its turbid entry (density 0: none).
    pub(in crate::radiative) scells: Vec<SimpleCell>,
    /// The lean tracker's rays go through the batched walk (see [`TrackingParams::batch_walk`]):
    /// [`Ctx::simple`], `turbid_subfaces: Off` and 1, 2 or 4 channels.
    pub(in crate::radiative) batch: bool,
    /// Per cell, for [`Ctx::trace_w`]: 0 for a cell with a tracked turbid entry or a facet, 1
    /// for an empty cell crossed one by one, else its chessboard distance r in cells to the
    /// nearest such cell ([`skip_field`]; no r when [`TrackingParams::skip_empty`] is off): a
    /// ray in it jumps over the box of cells within r − 1.
    pub(in crate::radiative) skip: Vec<u8>,
    /// Turbid interception storage mode.
    pub(in crate::radiative) subfaces: TurbidSubfaces,
    /// Turbid incident stores per entry: 1 (`Off`, `Blend`), 7 (`Faces`), 6 D² + 1 (`Subfaces`).
    pub(in crate::radiative) tstores: usize,
    /// Sub-faces per face side D (1 for `Faces`).
    pub(in crate::radiative) face_d: u32,
    /// Turbid points records per accumulator index: 1, or the slot count (`Blend`).
    pub(in crate::radiative) pts_per: usize,
    /// Per direction (sun last), what a lane of the batched walk takes at a ray start
    /// ([`batch::LaneDir`]; empty when [`Ctx::batch`] is off).
    pub(in crate::radiative) lane_dirs: Vec<batch::LaneDir>,
    /// The same for the single-precision 16-lane walk (empty unless it runs:
    /// [`TrackingParams::batch_f32`], AVX-512, a grid of `i32` indices).
    pub(in crate::radiative) lane_dirs32: Vec<batch::LaneDir32>,
    /// Per cell, for the single-precision walk: [`SimpleCell`] packed into 8 bytes, the
    /// density as `f32` bits (0 for no entry) in the low half, the entry index (empty cell: its
    /// skip distance) in the high half (empty unless that walk runs).
    pub(in crate::radiative) scells32: Vec<u64>,
    /// Where the walks dispatch ([`TrackingParams::kernel_isa`] on this CPU).
    pub(in crate::radiative) arch: pulp::Arch,
    /// The facets of each cell in `f32` for the prefilter of [`Ctx::trace_w`]'s facet scan
    /// (empty when the scene has none).
    pub(in crate::radiative) packs: crate::geometry::facet_packs::FacetPacks,
}

/// Smallest empty-space distance from which the flux-tracking walks jump
/// ([`skip_field`]). Measured (callgrind, forest Preview): from distance 2 the jumps cost 7 %
/// more instructions than they saved, from 3 2.4 %, from 4 they break even.
pub(in crate::radiative) const MIN_SKIP_DISTANCE: u8 = 4;

/// A cell as [`Ctx::trace_simple`] reads it (16 bytes): leaf area volume density u_f
/// (m² m⁻³, 0 for a cell without tracked turbid entry), turbid material slot (column of the
/// G rows) and entry index (into `CellGrid::turbid`). A cell without entry holds in `tm` its
/// empty-space distance (see [`Ctx::skip`]; no extra read per crossing).
#[derive(Debug, Clone, Copy, Default)]
pub(in crate::radiative) struct SimpleCell {
    pub(in crate::radiative) density: f64,
    pub(in crate::radiative) tm: u32,
    pub(in crate::radiative) idx: u32,
}

impl Ctx<'_> {
    /// BRDF-ground row of an interception slot (tiling sectors only).
    #[inline]
    pub(in crate::radiative) fn ground_row(&self, band: usize, slot: usize) -> &[f64] {
        let base = (band * self.n_slots + slot) * self.n_dirs;
        &self.ground_rows[base..base + self.n_dirs]
    }

    /// RPV/Hapke facet row of table set `set` for an interception slot (the sun's included).
    #[inline]
    pub(in crate::radiative) fn facet_row(&self, set: usize, band: usize, slot: usize) -> &[f64] {
        let base = ((set * self.nb + band) * self.n_slots + slot) * self.n_dirs;
        &self.facet_rows[base..base + self.n_dirs]
    }

    /// Phase row of an interception slot (tiling sectors only).
    #[inline]
    pub(in crate::radiative) fn slot_row(&self, tm: usize, band: usize, slot: usize) -> &[f64] {
        let n_sec = self.n_slots - 1;
        let base = ((tm * self.nb + band) * n_sec + slot) * self.n_dirs;
        &self.slot_rows[base..base + self.n_dirs]
    }

    /// Sub-cell (of D³) of cell `c` that holds `p`.
    #[inline]
    pub(in crate::radiative) fn sub_of(&self, c: usize, p: DVec3) -> u32 {
        let [i, j, k] = self.inp.spec.ijk(c);
        self.sub_index(p, [i, j, k], 3)
    }

    /// Sub-cell index of `p` in the cell (or, for `axes = 2`, the ground column) whose integer
    /// position is `ijk`: D per axis along the first `axes` axes.
    #[inline]
    pub(in crate::radiative) fn sub_index(&self, p: DVec3, ijk: [usize; 3], axes: usize) -> u32 {
        if self.sub == 1 {
            return 0;
        }
        let spec = self.inp.spec;
        let d = self.sub as f64;
        let lo = spec.origin + DVec3::new(ijk[0] as f64, ijk[1] as f64, ijk[2] as f64) * spec.cell;
        let mut idx = 0;
        for a in (0..axes).rev() {
            let s =
                floor_i64((p[a] - lo[a]) / spec.cell[a] * d).clamp(0, self.sub as i64 - 1) as u32;
            idx = idx * self.sub + s;
        }
        idx
    }

    /// Turbid accumulator index and points record of an interception by entry `e` (index into
    /// `CellGrid::turbid`) on a segment that starts at `q0` along `d`, from slot `slot` (see
    /// [`TurAcc`] and [`TurbidSubfaces`]).
    #[inline(always)]
    pub(in crate::radiative) fn acc_index(
        &self,
        e: u32,
        q0: DVec3,
        d: DVec3,
        slot: u32,
    ) -> (u32, u32) {
        if self.tstores == 1 {
            return (e, if self.pts_per == 1 { 0 } else { slot });
        }
        let c = self.entry_cell[e as usize] as usize;
        (e * self.tstores as u32 + self.entry_store(c, q0, d), 0)
    }

    /// Incident store of a crossing of cell `c` whose segment starts at `q0` along `d` (see
    /// [`entry_store`]).
    #[inline]
    pub(in crate::radiative) fn entry_store(&self, c: usize, q0: DVec3, d: DVec3) -> u32 {
        let spec = self.inp.spec;
        let [i, j, k] = spec.ijk(c);
        let lo = spec.origin + DVec3::new(i as f64, j as f64, k as f64) * spec.cell;
        entry_store(lo, spec.cell, q0, d, self.face_d)
    }

    /// Where a ray leaving `o` inside cell `c` along `d` leaves the cell (see [`cell_exit`]).
    pub(in crate::radiative) fn cell_exit(
        &self,
        c: usize,
        o: DVec3,
        d: DVec3,
    ) -> (f64, DVec3, u32) {
        let spec = self.inp.spec;
        let [i, j, k] = spec.ijk(c);
        let lo = spec.origin + DVec3::new(i as f64, j as f64, k as f64) * spec.cell;
        cell_exit(lo, spec.cell, o, d, self.face_d)
    }

    /// A turbid cell's scattered ray `share × v` (W per channel) from `o` inside cell `c` along
    /// tiling direction `j`, followed to the cell's exit (exact attenuation `e^{−kℓ}`, the
    /// re-intercepted part booked to the cell's inside store with its two interception points,
    /// as the tracker would) and added to the exit group of its exit store and direction (DART
    /// 5 paper §3.2, Figure 7c; traced after the cell's stores are done, see
    /// [`emit_turbid_records`]).
    #[allow(clippy::too_many_arguments)]
    pub(in crate::radiative) fn to_exit(
        &self,
        c: usize,
        o: DVec3,
        j: usize,
        v: &[f64],
        share: f64,
        sc: &mut ExitGroups,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        let w = self.w;
        let d = self.omega[j];
        for (a, b) in pw.iter_mut().zip(v) {
            *a = b * share;
        }
        let (ell, q, s) = self.cell_exit(c, o, d);
        let cr = self.cells[c];
        let ents = &self.ents[cr.ent_lo as usize..cr.ent_hi as usize];
        let gd = &self.g_dir[j * self.n_tm..(j + 1) * self.n_tm];
        let k: f64 = ents.iter().map(|e| gd[e.tm as usize] * e.density).sum();
        out.crossings += 1;
        if k > 0.0 && ell > 0.0 {
            let x = k * ell;
            let (frac, tr) = attenuation(x);
            let (s1, s2) = HalfBarycentres::get().eval(x, ell);
            let (p1, p2) = (o + d * s1, o + d * s2);
            let psum: f64 = crate::radiative::walk::channel_sum(pw);
            let slot = self.slot_of(j) as u32;
            let mut tur = out.tur.take().expect("accumulator");
            for e in ents {
                let sh = gd[e.tm as usize] * e.density / k;
                let eq = self.acc_index(e.idx, o, d, slot);
                tur.add(eq, slot, pw, frac, sh, p1, p2, psum * frac * sh);
            }
            out.tur = Some(tur);
            for x in pw.iter_mut() {
                *x *= tr;
            }
        }
        let psum: f64 = crate::radiative::walk::channel_sum(pw);
        if psum <= 0.0 {
            add(&mut out.lost, pw);
            return;
        }
        let g = j * sc.n_exit + s as usize;
        if !sc.flag[g] {
            sc.flag[g] = true;
            sc.touched.push(g as u32);
        }
        let rec = &mut sc.group[g * (w + 4)..(g + 1) * (w + 4)];
        for (r, x) in rec.iter_mut().zip(pw.iter()) {
            *r += x;
        }
        rec[w] += q.x * psum;
        rec[w + 1] += q.y * psum;
        rec[w + 2] += q.z * psum;
        rec[w + 3] += psum;
    }

    pub(in crate::radiative) fn slot_of(&self, dir: usize) -> usize {
        if dir == self.n_dirs {
            self.n_slots - 1
        } else {
            self.inp.sector_of[dir] as usize
        }
    }

    /// Books power leaving the scene top at `p` along tiling direction `dir`: scene exitance,
    /// and the orthographic image of that direction if it has one (the exit point is projected
    /// along the direction onto the reference plane z0, wrapped in repetitive scenes; the
    /// power is spread over the pixels under the emitting element's footprint `out.foot` at
    /// the merge, see [`crate::radiative::images`]).
    pub(in crate::radiative) fn escape(
        &self,
        p: DVec3,
        dir: usize,
        pw: &[f64],
        out: &mut ChunkOut,
    ) {
        if dir >= self.n_dirs {
            add(&mut out.lost, pw);
            return;
        }
        let base = dir * self.w;
        for (r, v) in out.escaped[base..base + pw.len()].iter_mut().zip(pw) {
            *r += v;
        }
        let img = self.inp.image_of.get(dir).copied().unwrap_or(u32::MAX);
        if img == u32::MAX || self.omega[dir].z <= 0.0 {
            return;
        }
        let spec = self.inp.spec;
        let d = self.omega[dir];
        let mut x = p.x - (p.z - spec.origin.z) * d.x / d.z - spec.origin.x;
        let mut y = p.y - (p.z - spec.origin.z) * d.y / d.z - spec.origin.y;
        // Continuous topography (issue #31): the reference surface is the mean terrain plane
        // z = z0 + g·(x, y), g = offsets / sizes, not z = z0. It is invariant under the
        // scene's translation (X, 0, offset_x), so a ray's exit point, lowered or raised by
        // its side wraps, projects where its emitting element does (modulo X), and the
        // projected tile fills the image once (onto z = z0 a slope's tile covers X(1 − g v_x/
        // v_z) × Y: a gap band, the riser seen obliquely). Views that do not see the mean
        // plane from above keep z0.
        if spec.topography_offset != (0.0, 0.0) {
            let g = (
                spec.topography_offset.0 / self.size.0,
                spec.topography_offset.1 / self.size.1,
            );
            let den = d.z - g.0 * d.x - g.1 * d.y;
            if den > 0.0 {
                let (rx, ry) = (p.x - spec.origin.x, p.y - spec.origin.y);
                let t = (p.z - spec.origin.z - g.0 * rx - g.1 * ry) / den;
                x = rx - t * d.x;
                y = ry - t * d.y;
            }
        }
        if out.foot_shift != (0.0, 0.0) {
            // Continuous topography, DEM ground facet: see `ChunkOut::foot_shift`.
            x += out.foot_shift.0;
            y += out.foot_shift.1;
        }
        if spec.boundary != BoundaryMode::Isolated {
            x = rem_euclid_period(x, self.size.0);
            y = rem_euclid_period(y, self.size.1);
        } else if self.image_grid.misses((x, y), out.foot) {
            return;
        }
        out.img_key.push(img);
        out.img_pos.push([x, y, out.foot.0, out.foot.1]);
        out.img_val.extend_from_slice(pw);
    }

    /// A ray leaving the grid through the bottom at `hp` with powers `pw` (sum `psum`) from
    /// slot `slot`: intercepted by the flat ground (one event per column and sub-column), or
    /// lost when the scene has none.
    pub(in crate::radiative) fn bottom(
        &self,
        hp: DVec3,
        slot: u32,
        pw: &[f64],
        psum: f64,
        out: &mut ChunkOut,
    ) {
        let spec = self.inp.spec;
        if self.inp.flat_ground.is_some() {
            let i = floor_i64((hp.x - spec.origin.x) / spec.cell.x).clamp(0, spec.n[0] as i64 - 1)
                as usize;
            let j = floor_i64((hp.y - spec.origin.y) / spec.cell.y).clamp(0, spec.n[1] as i64 - 1)
                as usize;
            self.bottom_at(i, j, hp, slot, pw, psum, out);
        } else {
            add(&mut out.lost, pw);
        }
    }

    /// [`Ctx::bottom`] of a ray whose ground column (i, j) is known (the single-precision
    /// walk's lane cell): the same booking without locating the column.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(in crate::radiative) fn bottom_at(
        &self,
        i: usize,
        j: usize,
        hp: DVec3,
        slot: u32,
        pw: &[f64],
        psum: f64,
        out: &mut ChunkOut,
    ) {
        if self.inp.flat_ground.is_none() {
            return add(&mut out.lost, pw);
        }
        let n0 = self.inp.spec.n[0];
        let sub = self.sub_index(hp, [i, j, 0], 2);
        out.gnd_key.push(((i + n0 * j) as u32, slot, sub));
        out.gnd_val.extend_from_slice(pw);
        out.gnd_val.extend_from_slice(&[hp.x, hp.y, hp.z, psum]);
    }
}
