//! The photon walk through the cell grid (DART 5 paper §4; physics.md §9.2): exact free paths
//! in turbid cells (`τ* = −ln ξ` accumulated over the DDA segments) with delta tracking in
//! fluids (Woodcock 1965), facet hits per cell, the repetitive and isolated boundaries,
//! empty-space jumps, and transmittance (shadow) rays.

use super::context::{Ctx, ExitTo, Hit, PerMaterial, Photon, ray_meets_box};
use super::input::{FluidMaterial, PhotonOptics};
use super::tally::BatchOut;
use crate::photon::sampling::{Uniform01, sample_cosine_hemisphere};
use crate::radiative::dda::{Dda, Exit, floor_i64};
use crate::radiative::engine::intersect;
use crate::scene::desc::BoundaryMode;
use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;

impl Ctx<'_> {
    /// The direction of a photon reflected by the Lambertian flat ground (cosine-weighted
    /// about +z). Discrete sampler: the upward tiling direction whose sector holds a
    /// cosine-weighted direction, drawn with its probability `∫_sector μ dΩ / π` (the projected
    /// solid angle of its (μ, φ) rectangle, [`crate::direction::Direction::projected_sr`])
    /// from an alias table: the same distribution as drawing the direction and looking up its
    /// sector, in one draw instead of two, a sine, a cosine and the sector search.
    #[inline]
    pub(crate) fn ground_direction(&self, ph: &mut Photon, rng: &mut Xoshiro256PlusPlus) {
        match &self.ground_dirs {
            Some((table, ids)) => {
                ph.di = ids[table.sample(rng)] as usize;
                ph.d = self.omega[ph.di];
            }
            None => ph.d = sample_cosine_hemisphere(DVec3::Z, rng),
        }
    }

    /// Range-gate culling (receiver mode): a photon at unwrapped position m = p + shift after
    /// a path L can only be recorded at a path L' + |R − m'| ≥ L + |R − m| (triangle
    /// inequality: L' ≥ L + |m' − m| for any later event m', and |R − m'| ≥ |R − m| − |m' − m|),
    /// so once `L + |R − m|` exceeds the gate end none of its peel-offs can land inside the gate
    /// and it is stopped. What it would have recorded after the gate is not counted, so the
    /// after-gate part of `out_of_gate_j` is a lower bound. Without a receiver: `L > max_path`
    /// (never, max_path = ∞).
    #[inline]
    pub(crate) fn beyond_gate(&self, ph: &Photon) -> bool {
        match &self.receiver {
            Some(rx) => ph.path + (rx.position - (ph.p + ph.shift)).length() > self.max_path,
            None => ph.path > self.max_path,
        }
    }

    #[inline]
    pub(crate) fn g_of(&self, tm: usize, mu: f64) -> f64 {
        match &self.inp.optics[self.tur_ids[tm] as usize] {
            PhotonOptics::Turbid { g, .. } => g.eval(mu),
            _ => 0.0,
        }
    }

    /// Vegetation extinction per turbid entry of cell `c` for direction cosine `mu` (uses the
    /// per-flight G cache `g_cur`), and the fluid extinction per band.
    #[inline]
    pub(crate) fn k_veg(&self, c: usize, g_cur: &[f64]) -> f64 {
        let grid = self.inp.grid;
        let mut k = 0.0;
        for e in grid.turbid_of(c) {
            let tm = self.tur_mat[e.material as usize];
            if tm != u32::MAX {
                k += g_cur[tm as usize] * e.density as f64;
            }
        }
        k
    }

    #[inline]
    pub(crate) fn fluid_of(&self, c: usize) -> Option<&FluidMaterial> {
        let f = self.inp.fluid?;
        let i = *f.cell.get(c)?;
        (i != u16::MAX).then(|| &f.materials[i as usize])
    }

    pub(crate) fn column(&self, p: DVec3) -> u32 {
        let spec = self.inp.spec;
        // (floor_i64: no libm call; NaN gives column 0 as before.)
        let i =
            floor_i64((p.x - spec.origin.x) / spec.cell.x).clamp(0, spec.n[0] as i64 - 1) as usize;
        let j =
            floor_i64((p.y - spec.origin.y) / spec.cell.y).clamp(0, spec.n[1] as i64 - 1) as usize;
        (i + spec.n[0] * j) as u32
    }

    /// Re-entry point after leaving through a side (repetitive boundaries, with the altitude
    /// offset of continuous topography) of a ray along `d`, and the distance marched through
    /// air after it (0 but with continuous topography); `None` if the point leaves the grid
    /// vertically.
    pub(crate) fn wrap(&self, mut q: DVec3, axis: usize, s: i64, d: DVec3) -> Option<(DVec3, f64)> {
        let spec = self.inp.spec;
        let (len, off) = if axis == 0 {
            (self.size.0, spec.topography_offset.0)
        } else {
            (self.size.1, spec.topography_offset.1)
        };
        q[axis] -= s as f64 * len;
        q.z -= s as f64 * off;
        q[axis] = if s > 0 {
            spec.origin[axis]
        } else {
            spec.origin[axis] + len
        };
        // Continuous topography (issue #31): re-entering above the top while going down is
        // air over a lower neighbouring tile, not an exit: march through it (as the flux
        // tracker does) until the ray comes back inside or reaches the top plane.
        if q.z > spec.top() && d.z < 0.0 {
            return spec.descend_through_air(q, d, self.size, self.inp.params.max_crossings);
        }
        (q.z <= spec.top() && q.z >= spec.origin.z).then_some((q, 0.0))
    }

    /// Nearest facet hit in the current cell of `dda` along the segment `[t0, t1]` of the ray
    /// from its start `o = dda.point(0)` along `d`.
    #[inline]
    pub(crate) fn facet_hit(
        &self,
        dda: &Dda,
        d: DVec3,
        t0: f64,
        t1: f64,
        skip: Option<u32>,
    ) -> Option<(u32, f64)> {
        let (c, o) = (dda.index(), dda.point(0.0));
        let grid = self.inp.grid;
        let tol = self.inp.spec.hit_tolerance();
        if let Some(b) = self.facet_box.get(c)
            && !ray_meets_box(b, o, d, t0 - tol, t1 + tol)
        {
            return None;
        }
        let mut hit: Option<(u32, f64)> = None;
        let test = |r: usize| {
            let f = grid.facet_ids[r];
            if Some(f) == skip {
                return;
            }
            let fa = &self.inp.facets[f as usize];
            if let Some(t) = intersect(&fa.v, o, d)
                && t >= t0 - tol
                && t <= t1 + tol
                && hit.is_none_or(|h| t < h.1)
            {
                let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]);
                if n.dot(d) < 0.0 || fa.two_sided {
                    hit = Some((f, t));
                }
            }
        };
        self.scan_facets(dda, d, (t0, t1), test);
        hit
    }

    /// Calls `test(r)` in increasing order for the facet references `r` of the current cell of
    /// `dda` that the segment `[t0, t1]` (± the hit tolerance) of its ray along `d` may cross:
    /// all those it does cross
    /// ([`FacetPacks::scan`](crate::geometry::facet_packs::FacetPacks::scan)).
    #[inline]
    fn scan_facets(&self, dda: &Dda, d: DVec3, (t0, t1): (f64, f64), test: impl FnMut(usize)) {
        let (c, o, ijk) = (dda.index(), dda.point(0.0), dda.cell);
        let grid = self.inp.grid;
        let tol = self.inp.spec.hit_tolerance();
        let refs = (
            grid.facet_start[c] as usize,
            grid.facet_start[c + 1] as usize,
        );
        let corner = || self.inp.spec.cell_box(ijk[0], ijk[1], ijk[2]).0;
        let seg = (-tol, t1 - t0 + tol);
        self.packs.scan(refs, corner, o + d * t0, d, seg, test);
    }

    /// True if the segment `[t0, t1]` of the ray of `dda` along `d` in its current cell crosses
    /// a one-sided facet from behind (not a hit for this ray, but one for the reversed ray).
    pub(crate) fn facet_behind(&self, dda: &Dda, d: DVec3, t0: f64, t1: f64) -> bool {
        let (c, o) = (dda.index(), dda.point(0.0));
        let tol = self.inp.spec.hit_tolerance();
        if let Some(b) = self.facet_box.get(c)
            && !ray_meets_box(b, o, d, t0 - tol, t1 + tol)
        {
            return false;
        }
        let grid = self.inp.grid;
        let mut behind = false;
        self.scan_facets(dda, d, (t0, t1), |r| {
            if behind {
                return;
            }
            let fa = &self.inp.facets[grid.facet_ids[r] as usize];
            behind = !fa.two_sided
                && (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).dot(d) >= 0.0
                && intersect(&fa.v, o, d).is_some_and(|t| t >= t0 - tol && t <= t1 + tol);
        });
        behind
    }

    /// The tracked turbid material of cell `c` whose share of the extinction `Σ_m G_m u_m`
    /// (m⁻¹, `g_cur` = G per tracked material along the flight) contains `r` ∈ [0, k_v):
    /// (material id, tracked-material index); the last one when rounding leaves `r` beyond the
    /// sum; `None` when the cell holds no tracked material.
    #[inline]
    pub(crate) fn pick_turbid(
        &self,
        c: usize,
        g_cur: &[f64],
        mut r: f64,
    ) -> Option<(usize, usize)> {
        let mut mid = None;
        for e in self.inp.grid.turbid_of(c) {
            let tm = self.tur_mat[e.material as usize];
            if tm == u32::MAX {
                continue;
            }
            let k = g_cur[tm as usize] * e.density as f64;
            mid = Some((e.material as usize, tm as usize));
            if r < k {
                break;
            }
            r -= k;
        }
        mid
    }

    /// Extinction of the return path of a first-order LiDAR photon in cell `c` (m⁻¹): turbid
    /// materials without a leaf size only (see [`Ctx::forced_peel`]); `g_cur` holds G of the
    /// flight, equal to G of the reversed direction.
    #[inline]
    pub(crate) fn k_return(&self, c: usize, g_cur: &[f64]) -> f64 {
        let mut k = 0.0;
        for e in self.inp.grid.turbid_of(c) {
            let tm = self.tur_mat[e.material as usize];
            // hs_leaf is finite and >= 0 (validated scene input): no leaf size means 0.
            if tm != u32::MAX && self.hs_leaf[tm as usize] <= 0.0 {
                k += g_cur[tm as usize] * e.density as f64;
            }
        }
        k
    }

    /// Flies the photon to its next event; handles null collisions and boundary wrapping.
    #[inline]
    pub(crate) fn fly(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
    ) -> Hit {
        let tau_star = -(1.0 - rng.next_f64()).ln();
        self.fly_to(ph, g_cur, tau_star, rng, out)
    }

    /// [`Ctx::fly`] with the free optical path `tau_star` given.
    pub(crate) fn fly_to(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        tau_star: f64,
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
    ) -> Hit {
        self.fly_with(ph, &Uniform { g: g_cur }, tau_star, rng, out)
    }

    /// The free flight of a first-order sun photon ([`Ctx::fly`] with the hotspot correlation,
    /// physics.md §3.5): the photon's first event scattered the direct sun beam (passive mode,
    /// sun channel, some turbid material with a leaf size), so, as its peel-off transmittance
    /// ([`Ctx::transmittance`]) does, the turbid extinction at distance s from the scattering
    /// point is `u_f (G − b e^{−c s})` with `hs` = [b, c] per tracked turbid material
    /// ([`crate::radiative::engine::hotspot_terms`] of the sun and the flight direction). A
    /// crossing of a cell from distance s0 over ℓ adds the optical depth
    /// `u_f max(0, G ℓ − b ∫_{s0}^{s0+ℓ} e^{−c s} ds)` per turbid entry (exactly the peel-off's
    /// per-crossing depth), so the probability of leaving the layer along the flight is the
    /// peel-off's transmittance. Within the crossing the depth to distance x,
    /// `F(x) = Σ u_f max(0, G x − b ∫_{s0}^{s0+x} e^{−c s} ds)`, is nondecreasing (each term is
    /// a convex function that is 0 at x = 0, clamped at 0), so the collision where the free path
    /// τ* runs out is its inverse ([`Ctx::hs_invert`], safeguarded Newton to 1e-12 relative).
    /// The colliding material is then drawn in proportion to the local `u_f (G − b e^{−c s})`
    /// (kept in `ph.hs_k`), fluids as in [`Ctx::fly`] with this local vegetation extinction.
    pub(crate) fn fly_hotspot(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        hs: &[[f64; 2]],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
    ) -> Hit {
        let tau_star = -(1.0 - rng.next_f64()).ln();
        self.fly_with(ph, &Hotspot { g: g_cur, hs }, tau_star, rng, out)
    }

    /// The free flight shared by [`Ctx::fly_to`] and [`Ctx::fly_hotspot`]: the DDA walk with
    /// empty-space jumps, facet hits, boundary wrapping, the collision where the free optical
    /// path `tau_star` runs out (the vegetation extinction along the flight given by `ext`) and
    /// fluid null collisions against the majorant.
    fn fly_with<E: FlightExtinction>(
        &self,
        ph: &mut Photon,
        ext: &E,
        mut tau_star: f64,
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
    ) -> Hit {
        let spec = self.inp.spec;
        let mut crossings = 0u32;
        'restart: loop {
            let Some(mut dda) = Dda::new_inline(spec, ph.p, ph.d) else {
                return Hit::Lost;
            };
            loop {
                out.crossings += 1;
                let c = dda.index();
                let r = self.empty[c];
                if r != 0 {
                    // An empty cell: crossed unread, or the empty box around it jumped over
                    // (the jump out of line: the common path keeps its code).
                    let exit = if r > 1 {
                        fly_skip(&mut dda, r, &mut out.skipped)
                    } else {
                        cross_empty(&mut dda, &self.empty, &mut out.crossings)
                    };
                    match exit {
                        Exit::Inside => continue,
                        exit => match self.fly_exit(exit, &dda, ph, &mut crossings) {
                            Some(hit) => return hit,
                            None => continue 'restart,
                        },
                    }
                }
                let t0 = dda.t;
                let mut t1 = dda.t_exit();
                let fhit = if self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1] {
                    self.facet_hit(&dda, ph.d, t0, t1, ph.skip_facet)
                } else {
                    None
                };
                if let Some((_, th)) = fhit {
                    t1 = th.max(t0);
                }
                let fl = self.fluid_of(c);
                let kf = fl.map_or(0.0, |f| f.sigma_e.iter().cloned().fold(0.0, f64::max));
                if t1 > t0
                    && let Some((dt, kv)) = ext.depth(self, ph, c, t0, t1 - t0, kf)
                {
                    if dt >= tau_star {
                        let cr = Crossing {
                            c,
                            t0,
                            ell: t1 - t0,
                            kf,
                            dt,
                            kv,
                        };
                        let x = ext.invert(self, ph, &cr, tau_star);
                        let t = t0 + x;
                        let p = dda.point(t);
                        let (kv, hk) = ext.local(self, ph, &cr, x);
                        let k = kv + kf;
                        // Fluid null collision (band-dependent extinction below the majorant).
                        if let Some(f) = fl
                            && rng.next_f64() * k >= kv
                        {
                            let mut sw = 0.0;
                            let mut sq = 0.0;
                            for (b, wb) in ph.w.iter().enumerate() {
                                sw += wb;
                                sq += wb * f.sigma_e[b] / kf;
                            }
                            let q = if sw > 0.0 { sq / sw } else { 1.0 };
                            if rng.next_f64() >= q {
                                // Null: continue straight from p with a new free path.
                                for (b, wb) in ph.w.iter_mut().enumerate() {
                                    *wb *= (1.0 - f.sigma_e[b] / kf) / (1.0 - q);
                                }
                                ph.path += t;
                                ph.p = p;
                                tau_star = -(1.0 - rng.next_f64()).ln();
                                continue 'restart;
                            }
                            for (b, wb) in ph.w.iter_mut().enumerate() {
                                *wb *= (f.sigma_e[b] / kf) / q;
                            }
                            ph.path += t;
                            return Hit::Volume {
                                c: c | FLUID_BIT,
                                p,
                            };
                        }
                        if let Some(hk) = hk {
                            ph.hs_k = hk;
                        }
                        ph.path += t;
                        return Hit::Volume { c, p };
                    }
                    tau_star -= dt;
                }
                if let Some((f, th)) = fhit {
                    ph.path += th;
                    return Hit::Facet {
                        f,
                        p: dda.point(th),
                    };
                }
                match dda.advance() {
                    Exit::Inside => {}
                    exit => match self.fly_exit(exit, &dda, ph, &mut crossings) {
                        Some(hit) => return hit,
                        None => continue 'restart,
                    },
                }
            }
        }
    }

    /// Vegetation optical depth of a hotspot-corrected crossing of cell `c` from distance `s0`
    /// (m from the scattering point) over `x` m: `Σ u_f max(0, G x − b ∫_{s0}^{s0+x} e^{−c s} ds)`
    /// per tracked turbid entry (the same per-entry expression as [`Ctx::transmittance`]).
    #[inline]
    pub(crate) fn hs_depth(
        &self,
        c: usize,
        g_cur: &[f64],
        hs: &[[f64; 2]],
        s0: f64,
        x: f64,
    ) -> f64 {
        let mut tau = 0.0;
        for e in self.inp.grid.turbid_of(c) {
            let tm = self.tur_mat[e.material as usize];
            if tm == u32::MAX {
                continue;
            }
            let g = g_cur[tm as usize];
            match hs.get(tm as usize) {
                Some(&[b, cc]) if b > 0.0 => {
                    let corr = b * crate::radiative::engine::hotspot_integral(cc, s0, x);
                    tau += e.density as f64 * (g * x - corr).max(0.0);
                }
                _ => tau += g * e.density as f64 * x,
            }
        }
        tau
    }

    /// The distance x ∈ [0, ℓ] into a hotspot-corrected crossing ([`Ctx::fly_hotspot`]) where
    /// the optical depth `kf x + F(x)` (`F` = [`Ctx::hs_depth`], nondecreasing) reaches
    /// `tau_star` ≤ `dt` = its value at ℓ: safeguarded Newton in a shrinking bracket, to
    /// 1e-12 relative in optical depth (or a bracket of 1e-14 ℓ).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn hs_invert(
        &self,
        c: usize,
        g_cur: &[f64],
        hs: &[[f64; 2]],
        s0: f64,
        ell: f64,
        kf: f64,
        tau_star: f64,
        dt: f64,
    ) -> f64 {
        let (mut lo, mut hi) = (0.0, ell);
        let mut x = (tau_star / dt * ell).clamp(0.0, ell);
        for _ in 0..200 {
            let v = kf * x + self.hs_depth(c, g_cur, hs, s0, x) - tau_star;
            if v.abs() <= 1e-12 * tau_star || hi - lo <= 1e-14 * ell {
                return x;
            }
            if v > 0.0 {
                hi = x;
            } else {
                lo = x;
            }
            // Derivative: the local extinction (clamped entries contribute 0).
            let mut dv = kf;
            for e in self.inp.grid.turbid_of(c) {
                let tm = self.tur_mat[e.material as usize];
                if tm != u32::MAX {
                    let tm = tm as usize;
                    dv += e.density as f64 * hs_local_g(g_cur[tm], hs.get(tm).copied(), s0, x);
                }
            }
            let xn = if dv > 0.0 { x - v / dv } else { f64::NAN };
            x = if xn > lo && xn < hi {
                xn
            } else {
                0.5 * (lo + hi)
            };
        }
        x
    }

    /// A flight leaves the grid box through `exit` (not `Exit::Inside`) at `dda.t`: the hit it
    /// ends with, or `None` after wrapping through a repetitive side (the photon then restarts
    /// from its new position).
    #[inline]
    pub(crate) fn fly_exit(
        &self,
        exit: Exit,
        dda: &Dda,
        ph: &mut Photon,
        crossings: &mut u32,
    ) -> Option<Hit> {
        let spec = self.inp.spec;
        match exit {
            Exit::Inside => None,
            Exit::Top => {
                ph.path += dda.t;
                ph.p = dda.point(dda.t);
                Some(Hit::Escape)
            }
            Exit::Bottom => {
                ph.path += dda.t;
                let p = dda.point(dda.t);
                Some(if self.inp.flat_ground.is_some() {
                    Hit::Ground { p }
                } else {
                    Hit::Lost
                })
            }
            Exit::Side(axis, s) => {
                if spec.boundary == BoundaryMode::Isolated {
                    return Some(Hit::Lost);
                }
                *crossings += 1;
                if *crossings > self.inp.params.max_crossings {
                    return Some(Hit::Lost);
                }
                let e = dda.point(dda.t);
                if ph.path + dda.t > self.max_path {
                    return Some(Hit::Lost);
                }
                match self.wrap(e, axis, s, ph.d) {
                    Some((q, ta)) => {
                        ph.path += dda.t + ta;
                        // Unwrapped position = wrapped + shift (LiDAR geometry).
                        ph.shift += e + ph.d * ta - q;
                        ph.p = q;
                        ph.skip_facet = None;
                        None
                    }
                    // (Continuous topography: a downward photon that never meets the
                    // terrain again has gone down the slope for good, as in the flux tracker.)
                    None => Some(if ph.d.z > 0.0 || spec.topography_offset != (0.0, 0.0) {
                        Hit::Escape
                    } else {
                        Hit::Lost
                    }),
                }
            }
        }
    }

    /// Transmittance per band from `p` along `d` to the top of the scene or over `max_dist`
    /// metres (turbid and fluid extinction, facets opaque unless directly transmitting);
    /// `g_dir` holds G(d) per turbid material; `hs` (empty: none) the hotspot terms per turbid
    /// material of a first-order photon's peel-off (the turbid extinction coefficient at
    /// distance s from `p` is `u_f (G − b e^{−c s})`, physics.md §3.5).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn transmittance(
        &self,
        p: DVec3,
        d: DVec3,
        max_dist: f64,
        g_dir: &[f64],
        hs: &[[f64; 2]],
        skip: Option<u32>,
        t_out: &mut [f64],
    ) {
        let spec = self.inp.spec;
        let mut travelled = 0.0;
        t_out.iter_mut().for_each(|t| *t = 1.0);
        let mut tau_v = 0.0; // band-independent optical depth (vegetation)
        let mut p = p;
        let mut skip = skip;
        let mut crossings = 0u32;
        'restart: loop {
            let Some(mut dda) = Dda::new(spec, p, d) else {
                t_out.iter_mut().for_each(|t| *t = 0.0);
                return;
            };
            loop {
                let c = dda.index();
                let t0 = dda.t;
                let mut t1 = dda.t_exit();
                // Receiver inside the grid (terrestrial LiDAR): stop at its distance.
                let reached = travelled + t1 >= max_dist;
                // Empty cells (no facet, no turbid density, no fluid) are crossed unread.
                let r = self.empty[c];
                if r == 0 {
                    if reached {
                        t1 = (max_dist - travelled).max(t0);
                    }
                    let fhit = if self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1] {
                        self.facet_hit(&dda, d, t0, t1, skip)
                    } else {
                        None
                    };
                    if let Some((_, th)) = fhit {
                        t1 = th.max(t0);
                    }
                    let ell = t1 - t0;
                    if ell > 0.0 {
                        for e in self.inp.grid.turbid_of(c) {
                            let tm = self.tur_mat[e.material as usize];
                            if tm != u32::MAX {
                                let g = g_dir[tm as usize];
                                match hs.get(tm as usize) {
                                    Some(&[b, c]) if b > 0.0 => {
                                        let corr = b * crate::radiative::engine::hotspot_integral(
                                            c,
                                            travelled + t0,
                                            ell,
                                        );
                                        tau_v += e.density as f64 * (g * ell - corr).max(0.0);
                                    }
                                    _ => tau_v += g * e.density as f64 * ell,
                                }
                            }
                        }
                        if let Some(f) = self.fluid_of(c) {
                            for (t, s) in t_out.iter_mut().zip(&f.sigma_e) {
                                *t *= (-s * ell).exp();
                            }
                        }
                    }
                    if tau_v > 69.1 {
                        // e^{−69.1} < 1e-30: below the peel-off cut.
                        t_out.iter_mut().for_each(|t| *t = 0.0);
                        return;
                    }
                    if let Some((f, th)) = fhit {
                        let fa = &self.inp.facets[f as usize];
                        let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize();
                        let mu = n.dot(d).abs().max(1e-6);
                        match &self.inp.optics[fa.material as usize] {
                            PhotonOptics::Lambert { t_dir, .. }
                                if t_dir.iter().any(|&x| x > 0.0) =>
                            {
                                for (t, td) in t_out.iter_mut().zip(t_dir) {
                                    *t *= if *td > 0.0 { td.powf(1.0 / mu) } else { 0.0 };
                                }
                                travelled += th;
                                p = dda.point(th);
                                skip = Some(f);
                                continue 'restart;
                            }
                            _ => {
                                t_out.iter_mut().for_each(|t| *t = 0.0);
                                return;
                            }
                        }
                    }
                }
                if reached {
                    break 'restart;
                }
                // Empty box around the cell: jumped over unless the receiver distance is
                // reached inside it (then crossed cell by cell up to it).
                match dda.advance() {
                    Exit::Inside => {}
                    exit => match self.transmittance_exit(exit, &dda, &mut crossings) {
                        ExitTo::Receiver => break 'restart,
                        ExitTo::Blocked => {
                            t_out.iter_mut().for_each(|t| *t = 0.0);
                            return;
                        }
                        ExitTo::Wrapped(q) => {
                            travelled += dda.t;
                            p = q;
                            skip = None;
                            continue 'restart;
                        }
                    },
                }
            }
        }
        let tv = (-tau_v).exp();
        t_out.iter_mut().for_each(|t| *t *= tv);
    }

    /// A transmittance ray leaves the grid box through `exit` (not `Exit::Inside`) at `dda.t`.
    #[inline]
    pub(crate) fn transmittance_exit(&self, exit: Exit, dda: &Dda, crossings: &mut u32) -> ExitTo {
        let spec = self.inp.spec;
        match exit {
            Exit::Inside | Exit::Top => ExitTo::Receiver,
            Exit::Bottom => ExitTo::Blocked,
            Exit::Side(axis, s) => {
                *crossings += 1;
                if spec.boundary == BoundaryMode::Isolated && self.receiver.is_some() {
                    // Outside an isolated scene there is nothing: the return reaches the
                    // receiver.
                    return ExitTo::Receiver;
                }
                if spec.boundary == BoundaryMode::Isolated
                    || *crossings > self.inp.params.max_crossings
                {
                    return ExitTo::Blocked;
                }
                match self.wrap(dda.point(dda.t), axis, s, dda.dir()) {
                    Some((q, _)) => ExitTo::Wrapped(q),
                    None => ExitTo::Receiver,
                }
            }
        }
    }
}

/// Transmittance `e^{−τ}` of a return optical depth τ, zero beyond τ = 69.1 (e^{−69.1} < 1e-30,
/// the cut of [`Ctx::transmittance`]).
#[inline]
pub(crate) fn return_transmittance(tau: f64) -> f64 {
    if tau > 69.1 { 0.0 } else { (-tau).exp() }
}

/// One crossing of a non-empty cell in a free flight ([`Ctx::fly_with`]): cell `c`, entered
/// at distance `t0` along the flight, `ell` m long, fluid majorant `kf` (m⁻¹), its optical depth
/// `dt` and, for a constant vegetation extinction, that extinction `kv` (m⁻¹).
struct Crossing {
    c: usize,
    t0: f64,
    ell: f64,
    kf: f64,
    dt: f64,
    kv: f64,
}

/// The vegetation extinction along a free flight ([`Ctx::fly_with`]): a crossing's optical depth
/// and constant extinction (`None`: nothing can collide in it), the distance into it where a
/// free path `tau` ≤ its depth runs out, and the vegetation extinction at that point (m⁻¹)
/// with the per-material G to keep for the choice of the colliding material (`None`: the
/// flight's own).
trait FlightExtinction {
    fn depth(
        &self,
        ctx: &Ctx,
        ph: &Photon,
        c: usize,
        t0: f64,
        ell: f64,
        kf: f64,
    ) -> Option<(f64, f64)>;
    fn invert(&self, ctx: &Ctx, ph: &Photon, x: &Crossing, tau: f64) -> f64;
    fn local(
        &self,
        ctx: &Ctx,
        ph: &Photon,
        x: &Crossing,
        at: f64,
    ) -> (f64, Option<PerMaterial<f64>>);
}

/// The ordinary flight: extinction `k = Σ G u_f + kf`, constant in each cell.
struct Uniform<'a> {
    g: &'a [f64],
}

impl FlightExtinction for Uniform<'_> {
    #[inline(always)]
    fn depth(
        &self,
        ctx: &Ctx,
        _: &Photon,
        c: usize,
        _: f64,
        ell: f64,
        kf: f64,
    ) -> Option<(f64, f64)> {
        let kv = ctx.k_veg(c, self.g);
        let k = kv + kf;
        (k > 0.0).then_some((ell * k, kv))
    }
    #[inline(always)]
    fn invert(&self, _: &Ctx, _: &Photon, x: &Crossing, tau: f64) -> f64 {
        tau / (x.kv + x.kf)
    }
    #[inline(always)]
    fn local(&self, _: &Ctx, _: &Photon, x: &Crossing, _: f64) -> (f64, Option<PerMaterial<f64>>) {
        (x.kv, None)
    }
}

/// The first-order sun flight with the hotspot correlation (see [`Ctx::fly_hotspot`]): `hs` =
/// [b, c] per tracked turbid material; distances from the scattering point.
struct Hotspot<'a> {
    g: &'a [f64],
    hs: &'a [[f64; 2]],
}

impl FlightExtinction for Hotspot<'_> {
    #[inline(always)]
    fn depth(
        &self,
        ctx: &Ctx,
        ph: &Photon,
        c: usize,
        t0: f64,
        ell: f64,
        kf: f64,
    ) -> Option<(f64, f64)> {
        // Distance from the scattering point at the segment's start.
        let s0 = ph.path - ph.scatter_path + t0;
        let dt = kf * ell + ctx.hs_depth(c, self.g, self.hs, s0, ell);
        (dt > 0.0).then_some((dt, 0.0))
    }
    #[inline(always)]
    fn invert(&self, ctx: &Ctx, ph: &Photon, x: &Crossing, tau: f64) -> f64 {
        let s0 = ph.path - ph.scatter_path + x.t0;
        ctx.hs_invert(x.c, self.g, self.hs, s0, x.ell, x.kf, tau, x.dt)
    }
    /// The local `u_f (G − b e^{−c s})` per material at the collision.
    fn local(
        &self,
        ctx: &Ctx,
        ph: &Photon,
        cr: &Crossing,
        x: f64,
    ) -> (f64, Option<PerMaterial<f64>>) {
        let (c, t0, kf) = (cr.c, cr.t0, cr.kf);
        let s0 = ph.path - ph.scatter_path + t0;
        let mut kv = 0.0;
        let mut hk = PerMaterial::from_elem(0.0, self.g.len());
        for e in ctx.inp.grid.turbid_of(c) {
            let tm = ctx.tur_mat[e.material as usize];
            if tm == u32::MAX {
                continue;
            }
            let tm = tm as usize;
            let g = hs_local_g(self.g[tm], self.hs.get(tm).copied(), s0, x);
            hk[tm] = g;
            kv += g * e.density as f64;
        }
        if kv <= 0.0 && kf <= 0.0 {
            // (Rounding at the clamp's kink: the flight's own G.)
            hk.iter_mut().zip(self.g).for_each(|(h, g)| *h = *g);
            kv = ctx.k_veg(c, self.g);
        }
        (kv, Some(hk))
    }
}

/// The local effective G (m² m⁻² per unit `u_f`) at distance `x` into a hotspot-corrected
/// crossing that starts at distance `s0` from the scattering point: `G − b e^{−c (s0 + x)}`
/// where the crossing's clamped depth `max(0, G x − b ∫ e^{−c s})` is positive (its
/// derivative), 0 where it is still clamped; `G` without hotspot terms.
#[inline]
pub(crate) fn hs_local_g(g: f64, hs: Option<[f64; 2]>, s0: f64, x: f64) -> f64 {
    match hs {
        Some([b, c]) if b > 0.0 => {
            let f = g * x - b * crate::radiative::engine::hotspot_integral(c, s0, x);
            let k = g - b * (-c * (s0 + x)).exp();
            if f > 0.0 || (x == 0.0 && k > 0.0) {
                k.max(0.0)
            } else {
                0.0
            }
        }
        _ => g,
    }
}

/// Marks a fluid collision in `Hit::Volume::c`.
pub(crate) const FLUID_BIT: usize = 1 << 63;

/// Smallest empty-space distance from which the Photon flights jump ([`skip_field`](crate::radiative::dda::skip_field)): an empty
/// cell costs them only ~20 instructions, so short jumps do not pay (measured, callgrind,
/// LiDAR forest discrete-peak: jumping from distance 4 cost 27 M more instructions than it
/// saved over 64 pulses; the urban scan +7 %). From 8 only long runs of empty air jump.
pub(crate) const MIN_SKIP_DISTANCE: u8 = 8;

/// A flight's jump from an empty cell at distance `r` ≥ 2 ([`Dda::skip_to`]), counting the
/// cells skipped. Out of line and cold (measured: inlined into the Photon walks' loops, the
/// jump code made the common path of the LiDAR forest 5 % longer). Only the flights
/// ([`Ctx::fly`]) jump: the same branch in the forced walk and the transmittance rays cost the
/// LiDAR forest 2 % (`trace_photon` 751.5 M → 766.5 M instructions over 64 pulses) without
/// ever jumping there; they cross empty cells one by one, unread.
#[cold]
#[inline(never)]
pub(crate) fn fly_skip(dda: &mut Dda, r: u8, skipped: &mut u64) -> Exit {
    let h = r as i64 - 1;
    let (e, faces) = dda.skip_to(h, dda.skip_exit(h));
    *skipped += faces - 1;
    e
}

/// Crosses the run of empty cells crossed one by one (field value 1, see [`skip_field`](crate::radiative::dda::skip_field)) that
/// starts at the current cell of `dda`: steps until the ray enters a cell with another value
/// (returns [`Exit::Inside`] there) or leaves the grid (returns the exit [`Dda::advance`] would
/// report), adding the empty cells entered on the way to `crossings` (the caller counts the
/// current one and the cell it stops in). The same cells, segment ends and exit as a loop of
/// [`Dda::advance`] calls (bit for bit: [`Dda::step_at`] moves into the same state), in a loop
/// that reads nothing else: an empty cell adds nothing to optical depths and draws nothing.
#[inline(always)]
pub(crate) fn cross_empty(dda: &mut Dda, empty: &[u8], crossings: &mut u64) -> Exit {
    let mut n = 0u64;
    let exit = loop {
        if !dda.step_at(dda.t_exit()) {
            break dda.exit_kind();
        }
        if empty[dda.index()] != 1 {
            break Exit::Inside;
        }
        n += 1;
    };
    *crossings += n;
    exit
}
