//! The general one-ray walk [`Ctx::trace_w`]: facets, several turbid entries per cell,
//! sub-face stores, topography, the hotspot correlation (DART 5 flux tracking,
//! Gastellu-Etchegorry et al. 2015, §3; physics.md §3.5, §3.6, §5).

use crate::radiative::dda::{Dda, Exit};
use crate::radiative::engine::*;
use crate::radiative::fastmath::{HalfBarycentres, attenuation};
use crate::scene::desc::{BoundaryMode, TurbidSubfaces};
use glam::DVec3;

/// Extinction coefficient of turbid entry `e` along a segment of length `ell` (m) starting at
/// distance `s0` (m) from the ray's origin, m⁻¹: `G u_f`, or with the hotspot correlation of a
/// first-order sun ray (`HS`, physics.md §3.5) `u_f (G − b ∫e^{−c s} ds / ℓ)`, floored at 0.
/// `gd`: G per material along the direction; `hsv`: (b, c) per material.
#[inline(always)]
fn extinction<const HS: bool>(e: &Ent, gd: &[f64], hsv: &[[f64; 2]], s0: f64, ell: f64) -> f64 {
    let g = gd[e.tm as usize];
    if HS {
        let [b, c] = hsv[e.tm as usize];
        if b > 0.0 {
            let corr = b * hotspot_integral(c, s0, ell) / ell;
            return e.density * (g - corr).max(0.0);
        }
    }
    g * e.density
}

/// How a ray left through a side of the grid ([`Ctx::side_exit`]).
enum Side {
    /// Wrapped in place: the traversal goes on.
    Wrapped,
    /// Re-entered on the opposite side at this point (a new traversal).
    Reentered(DVec3),
    /// Lost or escaped: the ray ends.
    Ended,
}

/// The per-ray constants of [`Ctx::trace_w`] that its turbid segments read.
#[derive(Clone, Copy)]
struct RayConsts<'a> {
    /// Unit propagation vector.
    d: DVec3,
    /// Incidence slot of the direction.
    slot: u32,
    /// `turbid_subfaces: Off` (one store per entry and slot).
    off: bool,
    /// G of every turbid material along the direction.
    gd: &'a [f64],
    /// Hotspot terms (b, c) per turbid material (empty unless hotspot-correlated).
    hsv: &'a [[f64; 2]],
    /// Ray-power threshold, W.
    min_ray: f64,
}

impl Ctx<'_> {
    /// [`Ctx::trace`] for `W` channels (`W = 0`: any count, read from `self.w`); `HS`: with the
    /// hotspot correlation of a first-order sun ray (see [`Ctx::trace_hotspot`]).
    ///
    /// Per crossing: one [`CellRec`] read; the facet loop only in cells with facets; the turbid
    /// extinction `k = Σ_m G_m(Ω) u_m` from the ray's row of G per material; cells with one
    /// entry skip the share computation (share = 1 exactly); the channel sum of `pw` is carried
    /// from one crossing to the next instead of being recomputed.
    #[allow(clippy::too_many_arguments)]
    pub(in crate::radiative) fn trace_w<const W: usize, const HS: bool>(
        &self,
        mut p: DVec3,
        dir: usize,
        mut skip_facet: Option<u32>,
        pw: &mut [f64],
        tur: &mut TurAcc,
        out: &mut ChunkOut,
    ) {
        let w = if W == 0 { self.w } else { W };
        let pw = &mut pw[..w];
        let spec = self.inp.spec;
        let d = self.omega[dir];
        let slot = self.slot_of(dir) as u32;
        let n_tm = self.n_tm;
        // G of every turbid material along this direction.
        let gd = &self.g_dir[dir * n_tm..(dir + 1) * n_tm];
        let hsv: &[[f64; 2]] = if HS {
            &self.hs[dir * n_tm..(dir + 1) * n_tm]
        } else {
            &[]
        };
        let min_ray = self.min_ray * self.ray_factor[dir] * out.ray_scale;
        let off = self.subfaces == TurbidSubfaces::Off;
        let ray = RayConsts {
            d,
            slot,
            off,
            gd,
            hsv,
            min_ray,
        };
        let t_tol = spec.hit_tolerance();
        // Distance travelled from the ray's origin to the current restart point, m.
        let mut s_base = 0.0;
        out.rays += 1;
        let mut n_cross = 0u64;
        let mut n_skip = 0u64;
        let mut crossings = 0u32;
        'restart: loop {
            let Some(mut dda) = Dda::new_inline(spec, p, d) else {
                // Started outside the grid (numerical edge): book as lost.
                add(&mut out.lost, pw);
                break 'restart;
            };
            // Σ pw, kept equal to `channel_sum(pw)` whenever `pw` changes.
            let mut psum: f64 = crate::radiative::walk::channel_sum(pw);
            loop {
                n_cross += 1;
                let c = dda.index();
                let cr = self.cells[c];
                let t0 = dda.t;
                let mut t1 = dda.t_exit();
                // How the cell is left (a jump from an empty cell, else one advance).
                let exit = 'cell: {
                    // Facets in this cell: nearest hit inside the segment.
                    let mut hit: Option<(u32, u32, f64)> = None;
                    if cr.fac_lo != cr.fac_hi {
                        let o = dda.point(0.0);
                        hit = self.nearest_facet(dda.cell, cr, o, d, (t0, t1), t_tol, skip_facet);
                        if let Some((_, _, th)) = hit {
                            t1 = th.max(t0);
                        }
                    }
                    // Turbid attenuation over [t0, t1].
                    if cr.ent_lo == cr.ent_hi {
                        // An empty cell (no turbid entry, no facet: nothing for the facet, turbid
                        // or hotspot bookkeeping) at distance r ≥ 2: jump over the empty box
                        // around it (tested here, where the walk already knows the cell has no
                        // turbid entry: no extra test in the other cells).
                        if cr.fac_lo == cr.fac_hi {
                            let r = self.skip[c];
                            if r > 1 {
                                let h = r as i64 - 1;
                                let (e, faces) = dda.skip_to(h, dda.skip_exit(h));
                                n_skip += faces - 1;
                                break 'cell e;
                            }
                        }
                    } else if t1 > t0
                        && !self.turbid_segment::<HS>(
                            &self.ents[cr.ent_lo as usize..cr.ent_hi as usize],
                            &dda,
                            (t0, t1),
                            &ray,
                            s_base,
                            pw,
                            &mut psum,
                            tur,
                            out,
                        )
                    {
                        break 'restart;
                    }
                    if let Some((r, f, th)) = hit {
                        let hp = dda.point(th);
                        let any_direct = self.facet_hit(r, f, hp, c, slot, d, pw, psum, out);
                        if !any_direct || crate::radiative::walk::channel_sum(pw) < min_ray {
                            add(&mut out.lost, pw);
                            break 'restart;
                        }
                        // Directly transmitted part continues from the hit point.
                        s_base += th;
                        p = hp;
                        skip_facet = Some(f);
                        continue 'restart;
                    }
                    dda.advance()
                };
                match exit {
                    Exit::Inside => {}
                    Exit::Top => {
                        self.escape(dda.point(dda.t), dir, pw, out);
                        break 'restart;
                    }
                    Exit::Bottom => {
                        self.bottom(dda.point(dda.t), slot, pw, psum, out);
                        break 'restart;
                    }
                    Exit::Side(axis, s) => {
                        // The facet skipped at the start is in another tile now.
                        skip_facet = None;
                        match self.side_exit(
                            &mut dda,
                            (axis, s),
                            dir,
                            &mut crossings,
                            &mut s_base,
                            pw,
                            out,
                        ) {
                            Side::Wrapped => continue,
                            Side::Reentered(q) => {
                                p = q;
                                continue 'restart;
                            }
                            Side::Ended => break 'restart,
                        }
                    }
                }
            }
        }
        out.crossings += n_cross;
        out.skipped += n_skip;
    }

    /// Turbid attenuation of the ray over `[t0, t1]` of a cell with the turbid entries `ents`
    /// (physics.md §3.6; DART 5 paper §3): `k = Σ_m G_m(Ω) u_m` (hotspot-corrected when `HS`,
    /// physics.md §3.5), the intercepted `1 − e^{−kℓ}` booked per entry in proportion to its
    /// extinction with the two half-barycentre points, `pw` and `psum` attenuated. Returns
    /// false when the ray's power fell under the threshold (booked as lost).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn turbid_segment<const HS: bool>(
        &self,
        ents: &[Ent],
        dda: &Dda,
        (t0, t1): (f64, f64),
        ray: &RayConsts,
        s_base: f64,
        pw: &mut [f64],
        psum: &mut f64,
        tur: &mut TurAcc,
        out: &mut ChunkOut,
    ) -> bool {
        let RayConsts {
            d,
            slot,
            off,
            gd,
            hsv,
            min_ray,
        } = *ray;
        let hb = HalfBarycentres::get();
        let ell = t1 - t0;
        // Distance of the segment from the ray's origin, m.
        let s0 = if HS { s_base + t0 } else { 0.0 };
        // Extinction coefficient of one entry along this segment, m⁻¹.
        let k_of = |e: &Ent| -> f64 { extinction::<HS>(e, gd, hsv, s0, ell) };
        let mut k = 0.0;
        for e in ents {
            k += k_of(e);
        }
        if k > 0.0 {
            let x = k * ell;
            // (1 − e^{−kℓ}, e^{−kℓ})
            let (frac, tr) = attenuation(x);
            // Interception points: barycentres of the two halves of the intercepted
            // energy.
            let (s1, s2) = hb.eval(x, ell);
            let p1 = dda.point(t0 + s1);
            let p2 = dda.point(t0 + s2);
            let wsum = *psum * frac;
            if off {
                if let [e] = ents {
                    // One material: share = k/k = 1 exactly.
                    tur.add_entry(e.idx, slot, pw, frac, 1.0, p1, p2, wsum);
                } else {
                    for e in ents {
                        let share = k_of(e) / k;
                        tur.add_entry(e.idx, slot, pw, frac, share, p1, p2, wsum * share);
                    }
                }
            } else {
                // Incident (sub-)face stores, or per-slot points.
                let q0 = dda.point(t0);
                for e in ents {
                    let share = if ents.len() == 1 { 1.0 } else { k_of(e) / k };
                    let eq = self.acc_index(e.idx, q0, d, slot);
                    tur.add(eq, slot, pw, frac, share, p1, p2, wsum * share);
                }
            }
            for v in pw.iter_mut() {
                *v *= tr;
            }
            *psum = crate::radiative::walk::channel_sum(pw);
            if *psum < min_ray {
                add(&mut out.lost, pw);
                return false;
            }
        }
        true
    }

    /// The ray left the grid through side `(axis, s)` at `dda.t`: lost (isolated scene, or
    /// more than `max_crossings` wraps), wrapped in place (repetitive scene without altitude
    /// offset: the traversal goes on), re-entered on the opposite side at the returned point
    /// (continuous topography, [`Ctx::reenter`]), or escaped through the top while re-entering.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn side_exit(
        &self,
        dda: &mut Dda,
        (axis, s): (usize, i64),
        dir: usize,
        crossings: &mut u32,
        s_base: &mut f64,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) -> Side {
        let spec = self.inp.spec;
        if spec.boundary == BoundaryMode::Isolated {
            add(&mut out.lost, pw);
            return Side::Ended;
        }
        if spec.topography_offset == (0.0, 0.0) {
            *crossings += dda.wrap_sides();
            if *crossings > self.inp.params.max_crossings {
                add(&mut out.lost, pw);
                return Side::Ended;
            }
            return Side::Wrapped;
        }
        *crossings += 1;
        if *crossings > self.inp.params.max_crossings {
            add(&mut out.lost, pw);
            return Side::Ended;
        }
        *s_base += dda.t;
        let q = match self.reenter(
            dda.point(dda.t),
            self.omega[dir],
            (axis, s),
            crossings,
            s_base,
        ) {
            Ok(q) => q,
            Err(q) => {
                self.escape(q, dir, pw, out);
                return Side::Ended;
            }
        };
        if q.z < spec.origin.z {
            add(&mut out.lost, pw);
            return Side::Ended;
        }
        Side::Reentered(q)
    }

    /// The nearest facet of cell `ijk` (record `cr`) that the ray from `o` along `d` hits within
    /// the segment `[t0, t1]` (± `t_tol`), from its front or on a two-sided facet, ignoring
    /// `skip_facet`: (facet ref, facet, distance). The exact test runs in reference order on
    /// the references that the `f32` prefilter ([`FacetPacks`]) keeps: the result is the
    /// plain scan's.
    ///
    /// [`FacetPacks`]: crate::geometry::facet_packs::FacetPacks
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn nearest_facet(
        &self,
        ijk: [i64; 3],
        cr: CellRec,
        o: DVec3,
        d: DVec3,
        (t0, t1): (f64, f64),
        t_tol: f64,
        skip_facet: Option<u32>,
    ) -> Option<(u32, u32, f64)> {
        let grid = self.inp.grid;
        let mut hit: Option<(u32, u32, f64)> = None;
        let test = |r: usize| {
            let f = grid.facet_ids[r];
            if Some(f) == skip_facet {
                return;
            }
            let fa = &self.inp.facets[f as usize];
            if let Some(t) = intersect(&fa.v, o, d)
                && t >= t0 - t_tol
                && t <= t1 + t_tol
                && hit.is_none_or(|h| t < h.2)
            {
                let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]);
                let front = n.dot(d) < 0.0;
                if front || fa.two_sided {
                    hit = Some((r as u32, f, t));
                }
            }
        };
        let refs = (cr.fac_lo as usize, cr.fac_hi as usize);
        let corner = || self.inp.spec.cell_box(ijk[0], ijk[1], ijk[2]).0;
        let seg = (-t_tol, t1 - t0 + t_tol);
        self.packs.scan(refs, corner, o + d * t0, d, seg, test);
        hit
    }

    /// Books a hit of facet `f` (ref `r`) at `hp` in cell `c` (physics.md §5.1): the
    /// intercepted power per channel (all but the direct transmittance `T_dir^{1/|μ|}`) with
    /// the hit point, `pw` left with the directly transmitted part; whether any is left.
    #[inline(always)]
    fn facet_hit(
        &self,
        r: u32,
        f: u32,
        hp: DVec3,
        c: usize,
        slot: u32,
        d: DVec3,
        pw: &mut [f64],
        psum: f64,
        out: &mut ChunkOut,
    ) -> bool {
        let fa = &self.inp.facets[f as usize];
        let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize();
        let mu = n.dot(d).abs().max(1e-6);
        let from_front = n.dot(d) < 0.0;
        let t_dir = match &self.inp.optics[fa.material as usize] {
            TrackOptics::Lambert { t_dir, .. } => Some(t_dir),
            _ => None,
        };
        let mut any_direct = false;
        out.fac_key
            .push((r, f, from_front, self.sub_of(c, hp), slot));
        for (ch, v) in pw.iter_mut().enumerate() {
            let td = t_dir.map_or(0.0, |t| t[ch % self.nb]);
            let through = if td > 0.0 { td.powf(1.0 / mu) } else { 0.0 };
            out.fac_val.push(*v * (1.0 - through));
            *v *= through;
            any_direct |= *v > 0.0;
        }
        out.fac_val.extend_from_slice(&[hp.x, hp.y, hp.z, psum]);
        any_direct
    }

    /// A ray that left through side `axis` (step `s`) at `q` re-entered on the opposite side
    /// of a repetitive scene with continuous topography (the ground `off` lower or higher):
    /// above the neighbouring tile's top while going down it marches through the empty air of
    /// the repeated tiles (each side crossing shifts the altitude) until it reaches the top
    /// plane or comes back inside the box. `Ok`: the point where it goes on; `Err`: it escapes
    /// from there (up, or down the slope for ever: more than `max_crossings`).
    #[inline(always)]
    fn reenter(
        &self,
        mut q: DVec3,
        d: DVec3,
        (axis, s): (usize, i64),
        crossings: &mut u32,
        s_base: &mut f64,
    ) -> Result<DVec3, DVec3> {
        let spec = self.inp.spec;
        let (len, off) = if axis == 0 {
            (self.size.0, spec.topography_offset.0)
        } else {
            (self.size.1, spec.topography_offset.1)
        };
        // Leaving through +x re-enters at x = 0 where the ground is `off` lower.
        q[axis] -= s as f64 * len;
        q.z -= s as f64 * off;
        q[axis] = if s > 0 {
            spec.origin[axis]
        } else {
            spec.origin[axis] + len
        };
        if q.z > spec.top() && d.z >= 0.0 {
            return Err(q);
        }
        // Continuous topography: re-entering above the neighbouring tile's top
        // while going down — march through the empty air of the repeated tiles
        // (each side crossing shifts the altitude) until the ray reaches the top
        // plane or comes back inside the box.
        while q.z > spec.top() {
            let t_top = (spec.top() - q.z) / d.z;
            let mut side: Option<(usize, i64, f64)> = None;
            for a in 0..2 {
                let len = if a == 0 { self.size.0 } else { self.size.1 };
                let t = if d[a] > 0.0 {
                    (spec.origin[a] + len - q[a]) / d[a]
                } else if d[a] < 0.0 {
                    (spec.origin[a] - q[a]) / d[a]
                } else {
                    f64::INFINITY
                };
                if side.is_none_or(|s| t < s.2) {
                    side = Some((a, if d[a] > 0.0 { 1 } else { -1 }, t));
                }
            }
            match side {
                Some((a, s, t)) if t < t_top => {
                    *crossings += 1;
                    if *crossings > self.inp.params.max_crossings {
                        // Descending more slowly than the terrain: it goes
                        // down the slope forever without meeting it again —
                        // it has left the scene (a downward escape).
                        return Err(q);
                    }
                    q += d * t.max(0.0);
                    *s_base += t.max(0.0);
                    let (len, off) = if a == 0 {
                        (self.size.0, spec.topography_offset.0)
                    } else {
                        (self.size.1, spec.topography_offset.1)
                    };
                    let _ = len;
                    q.z -= s as f64 * off;
                    q[a] = if s > 0 {
                        spec.origin[a]
                    } else {
                        spec.origin[a] + len
                    };
                }
                _ => {
                    q += d * t_top;
                    *s_base += t_top;
                    q.z = spec.top();
                }
            }
        }
        Ok(q)
    }
}
