//! Peel-off, the local estimate (Ray-Carlo eqs. 1–2, DART 5 paper §4; physics.md §3.3, §9.2):
//! forced peel-off along a whole flight (K points per cell crossing), peel-off toward the views
//! or toward a LiDAR receiver with its return transmittance (shadow ray or column sums), and
//! the turbid peel-off phase.

use super::context::{Bands, Ctx, PerMaterial, Photon, Receiver};
use super::input::{FluidMaterial, PhotonOptics};
use super::tally::BatchOut;
use super::walk::return_transmittance;
use crate::photon::sampling::Uniform01;
use crate::photon::small::Small;
use crate::physics::lad::VolscattKernel;
use crate::radiative::dda::{Dda, Exit, floor_i64};
use crate::scene::desc::BoundaryMode;
use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::PI;
use std::ops::ControlFlow;

/// State of a forced peel-off walk ([`Ctx::forced_peel`]) carried from cell to cell.
struct ForcedWalk {
    /// Forced points per segment (K ≥ 1).
    k_pts: u32,
    /// Flight direction.
    d_in: DVec3,
    /// Optical depth per band from the walk's start.
    tau: Bands,
    /// Return optical depth per band from the walk's start (the emitter side), when `exact`.
    tau_ret: Bands,
    /// Receiver mode on the straight flight from the emitter: the return transmittance of a
    /// point is the walk's own (until a one-sided facet is crossed from behind).
    exact: bool,
    /// Per-band weight factors of the point being emitted.
    fac: Bands,
    /// Path length walked before the last re-entry through a side, m.
    travelled: f64,
    /// Unwrapped minus wrapped position (repetitive scenes), m.
    shift: DVec3,
}

/// One cell segment `[t0, t0 + ell]` of a forced walk (distances along the DDA's ray, m).
struct ForcedSegment<'a> {
    /// Cell index.
    c: usize,
    /// Segment start.
    t0: f64,
    /// Segment length.
    ell: f64,
    /// Vegetation extinction `Σ G_m u_m`, m⁻¹.
    kv: f64,
    /// Return extinction of the exact mode, m⁻¹ (0 otherwise).
    kr: f64,
    /// The cell's fluid, if any.
    fl: Option<&'a FluidMaterial>,
}

impl ForcedSegment<'_> {
    /// Fluid extinction σ_b of band `b` (0 without a fluid), m⁻¹.
    fn sig(&self, b: usize) -> f64 {
        self.fl.map_or(0.0, |f| f.sigma_e[b])
    }
}

impl Ctx<'_> {
    /// Forced (expected-value) peel-off along the whole coming flight (Ray-Carlo K points per
    /// crossing of a cell, DART 5 paper §4). Fluid cells (and, in LiDAR receiver mode, turbid
    /// vegetation too): for every segment `[t0, t0+ℓ]` reached with per-band optical depth τ_b,
    /// K points u drawn from a truncated exponential `q(u)` each contribute
    /// `w_b e^{−τ_b} σ_b e^{−(k_v+σ_b)u}/(K q(u)) · f_b(Ω→receiver or view) · T_b`, whose
    /// expectation is the collision peel-off of the flight (which is then not done at the
    /// actual collisions of those media). Fluids: `f = ω P(Θ)/(4π)`; vegetation: the leaf
    /// intensity `Γ/(πG)` (spherical closed form, else the one-leaf estimate with a sampled
    /// normal). The walk stops at the first facet, the ground, the top, an isolated side or when
    /// min_b τ_b > 30 (e^{−30} ≈ 1e-13).
    ///
    /// Receiver mode on the straight flight from the emitter (`ph.direct`): the receiver sits at
    /// the emitter (monostatic), so the return path of a forced point is the flight walked so
    /// far, reversed: its transmittance comes from the optical depth already accumulated
    /// instead of a separate ray (same cells, G(−Ω) = G(Ω); turbid materials with a leaf size
    /// add nothing on the way back, the exact-backscatter limit of
    /// [`crate::radiative::engine::hotspot_terms_path`]; equal to the ray's value to rounding).
    /// A cell where the flight crosses a one-sided facet from behind (which the return ray
    /// would hit) falls back to the ray. Returns, in that mode, the return transmittance at
    /// the end of the walk when it ends on a facet (`Some(f)`) or the bottom (`None`), for the
    /// collision peel-off of the flight's surface hit.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn forced_peel(
        &self,
        ph: &Photon,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) -> Option<(Option<u32>, Bands)> {
        let spec = self.inp.spec;
        let nb = self.nb;
        let mut walk = ForcedWalk {
            k_pts: self.inp.params.fluid_peel_points.max(1),
            d_in: ph.d,
            tau: Bands::from_elem(0.0, nb),
            tau_ret: Bands::from_elem(0.0, nb),
            exact: self.receiver.is_some() && ph.order == 0 && ph.direct,
            fac: Bands::from_elem(0.0, nb),
            travelled: 0.0,
            shift: ph.shift,
        };
        let mut p = ph.p;
        let mut skip = ph.skip_facet;
        let mut crossings = 0u32;
        'restart: loop {
            let mut dda = Dda::new(spec, p, ph.d)?;
            loop {
                let c = dda.index();
                let r = self.empty[c];
                if r == 0
                    && let ControlFlow::Break(end) =
                        self.forced_cell(ph, &mut walk, &dda, skip, g_cur, rng, out, scratch, tr)
                {
                    return end;
                }
                match dda.advance() {
                    Exit::Inside => {}
                    Exit::Top => return None,
                    Exit::Bottom => return walk.exact.then_some((None, walk.tau_ret)),
                    Exit::Side(axis, s) => {
                        crossings += 1;
                        if spec.boundary == BoundaryMode::Isolated
                            || crossings > self.inp.params.max_crossings
                            || ph.path + walk.travelled > self.max_path
                        {
                            return None;
                        }
                        let e = dda.point(dda.t);
                        match self.wrap(e, axis, s, ph.d) {
                            Some((q, ta)) => {
                                walk.travelled += dda.t + ta;
                                walk.shift += e + ph.d * ta - q;
                                p = q;
                                skip = None;
                                continue 'restart;
                            }
                            None => return None,
                        }
                    }
                }
            }
        }
    }

    /// One cell crossing of the forced walk ([`Ctx::forced_peel`]) in the non-empty cell the
    /// DDA is in: the segment to the cell's exit or to its first facet hit, its forced points
    /// (fluid, and turbid vegetation in receiver mode), then the optical depths grow by the
    /// segment's. Breaks with the walk's result when the segment ends on a facet or the walk
    /// has become opaque (min_b τ_b > 30).
    #[allow(clippy::too_many_arguments)]
    fn forced_cell(
        &self,
        ph: &Photon,
        walk: &mut ForcedWalk,
        dda: &Dda,
        skip: Option<u32>,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) -> ControlFlow<Option<(Option<u32>, Bands)>> {
        let c = dda.index();
        let t0 = dda.t;
        let mut t1 = dda.t_exit();
        let fhit = if self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1] {
            self.facet_hit(dda, ph.d, t0, t1, skip)
        } else {
            None
        };
        if let Some((_, th)) = fhit {
            t1 = th.max(t0);
        }
        if walk.exact
            && self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1]
            && self.facet_behind(dda, ph.d, t0, t1)
        {
            walk.exact = false;
        }
        let ell = t1 - t0;
        let kv = self.k_veg(c, g_cur);
        // Return extinction: turbid materials without a leaf size (with one, the return
        // goes back through the same gaps).
        let kr = if walk.exact {
            self.k_return(c, g_cur)
        } else {
            0.0
        };
        let seg = ForcedSegment {
            c,
            t0,
            ell,
            kv,
            kr,
            fl: self.fluid_of(c),
        };
        if ell > 0.0 {
            if let Some(f) = seg.fl {
                self.forced_fluid_points(ph, walk, &seg, f, dda, rng, out, scratch, tr);
            }
            if self.receiver.is_some() && kv > 0.0 {
                self.forced_turbid_points(ph, walk, &seg, dda, g_cur, rng, out, scratch, tr);
            }
            for (b, t) in walk.tau.iter_mut().enumerate() {
                *t += (kv + seg.sig(b)) * ell;
            }
            if walk.exact {
                for (b, t) in walk.tau_ret.iter_mut().enumerate() {
                    *t += (kr + seg.sig(b)) * ell;
                }
            }
        }
        if let Some((f, _)) = fhit {
            return ControlFlow::Break(walk.exact.then_some((Some(f), walk.tau_ret.clone())));
        }
        if walk.tau.iter().cloned().fold(f64::INFINITY, f64::min) > 30.0 {
            return ControlFlow::Break(None);
        }
        ControlFlow::Continue(())
    }

    /// The K forced points of a fluid segment: u from the truncated exponential of the
    /// majorant `k_m = k_v + max_b σ_b` over the segment, each weighted
    /// `e^{−τ_b} σ_b e^{−(k_v+σ_b)u}/(K q(u))` with the fluid's intensity `ω P(Θ)/(4π)`.
    #[allow(clippy::too_many_arguments)]
    fn forced_fluid_points(
        &self,
        ph: &Photon,
        walk: &mut ForcedWalk,
        seg: &ForcedSegment,
        f: &FluidMaterial,
        dda: &Dda,
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) {
        let nb = self.nb;
        let k_pts = walk.k_pts;
        let d_in = walk.d_in;
        let (kv, ell) = (seg.kv, seg.ell);
        let km = kv + f.sigma_e.iter().cloned().fold(0.0, f64::max);
        let norm = -(-km * ell).exp_m1(); // 1 − e^{−k_m ℓ}
        if km > 0.0 && norm > 0.0 {
            for _ in 0..k_pts {
                let u = -(1.0 - rng.next_f64() * norm).ln() / km;
                let q = km * (-km * u).exp() / norm;
                for (b, x) in walk.fac.iter_mut().enumerate() {
                    *x = (-walk.tau[b]).exp() * f.sigma_e[b] * (-(kv + f.sigma_e[b]) * u).exp()
                        / (q * k_pts as f64);
                }
                let mut phase = |ov: DVec3, s: &mut [f64]| {
                    let pv = f.phase.eval_dirs(d_in, ov) / (4.0 * PI);
                    for b in 0..nb {
                        s[b] = f.ssa[b] * pv;
                    }
                    true
                };
                let at = dda.point(seg.t0 + u);
                self.forced_point(ph, walk, seg, at, u, &mut phase, out, scratch, tr);
            }
        }
    }

    /// The K forced points of a turbid segment in receiver mode: u with density
    /// `k_v e^{−k_v u}/(1 − e^{−k_v ℓ})`, per-band weight `e^{−τ_b − σ_b u}(1 − e^{−k_v ℓ})/K`, a
    /// material in proportion to its extinction and its leaf intensity `Γ/(πG)` (closed form,
    /// or the one-leaf estimate with a sampled normal).
    #[allow(clippy::too_many_arguments)]
    fn forced_turbid_points(
        &self,
        ph: &Photon,
        walk: &mut ForcedWalk,
        seg: &ForcedSegment,
        dda: &Dda,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) {
        let nb = self.nb;
        let k_pts = walk.k_pts;
        let d_in = walk.d_in;
        let (kv, ell) = (seg.kv, seg.ell);
        let norm = -(-kv * ell).exp_m1();
        for _ in 0..k_pts {
            let u = -(1.0 - rng.next_f64() * norm).ln() / kv;
            // Density kv e^{−kv u}/norm; per-band weight e^{−τ_b − σ_b u}·norm/K.
            for (b, x) in walk.fac.iter_mut().enumerate() {
                *x = (-walk.tau[b] - seg.sig(b) * u).exp() * norm / k_pts as f64;
            }
            // Material in proportion to its extinction.
            let mid = self.pick_turbid(seg.c, g_cur, rng.next_f64() * kv);
            let Some((mid, tm)) = mid else { continue };
            let PhotonOptics::Turbid {
                sampler,
                kernel,
                rho,
                tau: tl,
                ..
            } = &self.inp.optics[mid]
            else {
                continue;
            };
            let g_in = g_cur[tm].max(1e-12);
            let closed = kernel.is_closed_form();
            let n = if closed {
                DVec3::Z
            } else {
                sampler.sample_normal(d_in, rng)
            };
            let mut phase = |ov: DVec3, s: &mut [f64]| {
                turbid_peel_phase(kernel, closed, n, d_in, ov, g_in, rho, tl, &mut s[..nb])
            };
            let at = dda.point(seg.t0 + u);
            self.forced_point(ph, walk, seg, at, u, &mut phase, out, scratch, tr);
        }
    }

    /// Emits one forced point at `at`, a distance `u` into the segment: `phase` gives the
    /// intensity per unit weight toward the receiver or a view, times the weight factors
    /// `walk.fac`; in receiver mode the return transmittance is the walk's own (exact) or a
    /// return ray's.
    #[allow(clippy::too_many_arguments)]
    fn forced_point(
        &self,
        ph: &Photon,
        walk: &ForcedWalk,
        seg: &ForcedSegment,
        at: DVec3,
        u: f64,
        phase: &mut dyn FnMut(DVec3, &mut [f64]) -> bool,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) {
        let nb = self.nb;
        let fac = &walk.fac;
        let mut t_ret = Bands::from_elem(0.0, nb);
        if walk.exact {
            for (b, t) in t_ret.iter_mut().enumerate() {
                *t = return_transmittance(walk.tau_ret[b] + (seg.kr + seg.sig(b)) * u);
            }
        }
        let mut g = |_: usize, ov: DVec3, s: &mut [f64]| {
            if !phase(ov, s) {
                return false;
            }
            for b in 0..nb {
                s[b] *= fac[b];
            }
            true
        };
        match &self.receiver {
            Some(rx) => self.peel_receiver(
                rx,
                ph,
                (at, walk.shift, ph.path + walk.travelled + seg.t0 + u),
                None,
                walk.exact.then_some(&t_ret[..]),
                out,
                scratch,
                tr,
                &mut g,
            ),
            None => self.peel(ph, at, None, false, out, scratch, tr, &mut g),
        }
    }

    /// Receiver-mode peel-off (Ray-Carlo eqs. 1–2 with the standard local estimate, physics.md
    /// §9.2): from the event at `p` (wrapped; unwrapped = p + shift) toward the receiver at
    /// distance r, energy `w · f(u) · T(p → receiver) · A |u·axis| / r²` (f = intensity per unit
    /// weight, sr⁻¹), recorded at path length `path + r` with its scattering order; only events
    /// inside the receiver's field of view count.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn peel_receiver(
        &self,
        rx: &Receiver,
        ph: &Photon,
        (p, shift, path): (DVec3, DVec3, f64),
        skip: Option<u32>,
        known: Option<&[f64]>,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
        mut f: impl FnMut(usize, DVec3, &mut [f64]) -> bool,
    ) {
        let m = p + shift;
        let mut u = rx.position - m;
        let r = u.length();
        if r <= 0.0 {
            return;
        }
        u /= r;
        let cos_rx = -u.dot(rx.axis);
        if cos_rx < rx.cos_fov {
            return;
        }
        if !f(usize::MAX, u, scratch) {
            return;
        }
        if let Some(t) = known {
            tr.copy_from_slice(t);
            // Debug builds (the tests) check the reuse against the shadow ray it replaces.
            #[cfg(debug_assertions)]
            {
                let mut ray = Bands::from_elem(0.0, tr.len());
                self.transmittance_to_receiver(ph, p, u, r, skip, &mut ray);
                for (a, b) in ray.iter().zip(t) {
                    debug_assert!(
                        (a - b).abs() <= 1e-9 * a.max(*b) + 1e-25,
                        "first-flight return transmittance {b:e} vs shadow ray {a:e}"
                    );
                }
            }
        } else {
            self.transmittance_to_receiver(ph, p, u, r, skip, tr);
        }
        if tr.iter().all(|&t| t <= 0.0) {
            return;
        }
        let solid = rx.aperture_m2 * cos_rx / (r * r);
        let e = ph.w[0] * scratch[0] * tr[0] * solid;
        if let Some(wave) = out.wave.as_mut() {
            wave.book(path + r, e, ph.order + 1);
        }
    }

    /// Transmittance from `p` along `u` over the distance `r` to the receiver, with the
    /// first-order gap correlation (leaf size > 0) of a photon that has not scattered yet.
    pub(crate) fn transmittance_to_receiver(
        &self,
        ph: &Photon,
        p: DVec3,
        u: DVec3,
        r: f64,
        skip: Option<u32>,
        tr: &mut [f64],
    ) {
        let g: PerMaterial<f64> = Small::from_fn(self.tur_ids.len(), |tm| self.g_of(tm, u.z));
        // First-order return: back through the gaps the pulse came through (leaf size > 0).
        let hs: PerMaterial<[f64; 2]> = if ph.order == 0 && self.hs_leaf.iter().any(|&l| l > 0.0) {
            Small::from_fn(self.tur_ids.len(), |tm| {
                crate::radiative::engine::hotspot_terms_path(
                    ph.d,
                    u,
                    self.g_of(tm, ph.d.z),
                    g[tm],
                    self.hs_leaf[tm],
                )
            })
        } else {
            Small::from_elem([0.0; 2], 0)
        };
        if hs.is_empty()
            && skip.is_none()
            && let Some(t) = self.column_transmittance(p, u, r, &g)
        {
            // Debug builds (the tests) check the column sums against the shadow walk.
            #[cfg(debug_assertions)]
            {
                super::context::COLUMN_RETURNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                self.transmittance(p, u, r, &g, &hs, skip, tr);
                for &a in tr.iter() {
                    debug_assert!(
                        (a - t).abs() <= 1e-9 * a.max(t) + 1e-25,
                        "column return transmittance {t:e} vs shadow ray {a:e}"
                    );
                }
            }
            tr.iter_mut().for_each(|x| *x = t);
            return;
        }
        self.transmittance(p, u, r, &g, &hs, skip, tr);
    }

    /// Reflectance of the flat ground when it is Lambertian (band 0), else `None`.
    pub(crate) fn lambert_ground(&self) -> Option<f64> {
        self.inp
            .flat_ground
            .and_then(|g| match &self.inp.optics[g as usize] {
                PhotonOptics::Lambert { r, .. } => r.first().copied(),
                _ => None,
            })
    }

    /// Return transmittance from the wrapped point `p` along the unit vector `u` to a receiver
    /// at distance `r` (m), from the column sums ([`ColumnDepth`](crate::photon::engine::context::ColumnDepth)), when they are exact: the ray
    /// leaves through the top of the grid before reaching the receiver, stays strictly inside
    /// the point's column (both ends of the in-grid part inside it: the column is convex) and
    /// the cells it crosses hold no facet and no fluid. `g` holds G(u) per tracked turbid
    /// material. Optical depth `Σ_m G_m [A_m + u_{f,m} Δz]/u_z` (Δz from the point to its
    /// cell's top); `None`: use the shadow walk.
    #[inline]
    pub(crate) fn column_transmittance(
        &self,
        p: DVec3,
        u: DVec3,
        r: f64,
        g: &[f64],
    ) -> Option<f64> {
        let col = self.columns.as_deref()?;
        let spec = self.inp.spec;
        if !(u.z > 0.0) {
            return None;
        }
        let s = (spec.top() - p.z) / u.z;
        if !(s >= 0.0 && s < r) {
            return None;
        }
        let q = p + u * s;
        let mut ij = [0usize; 2];
        for a in 0..2 {
            let x0 = (p[a] - spec.origin[a]) / spec.cell[a];
            let x1 = (q[a] - spec.origin[a]) / spec.cell[a];
            let i = floor_i64(x0) as f64;
            if !(i >= 0.0
                && i < spec.n[a] as f64
                && x0 > i
                && x1 > i
                && x0 < i + 1.0
                && x1 < i + 1.0)
            {
                return None;
            }
            ij[a] = i as usize;
        }
        let k =
            floor_i64((p.z - spec.origin.z) / spec.cell.z).clamp(0, spec.n[2] as i64 - 1) as f64;
        let c = spec.index(ij[0], ij[1], k as usize);
        if !col.clear[c] {
            return None;
        }
        let dz = (spec.origin.z + (k + 1.0) * spec.cell.z - p.z).clamp(0.0, spec.cell.z);
        let base = c * col.ntm;
        let mut tau = 0.0;
        for tm in 0..col.ntm {
            tau += g[tm] * (col.above[base + tm] + col.dens[base + tm] * dz);
        }
        Some(return_transmittance(tau / u.z))
    }

    /// Adds `w_b · f_b · T_b(view)` to the peel tally of every view, where `f(v, out)` fills the
    /// per-band intensity factors (sr⁻¹) toward view v (and returns false if all are zero).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn peel(
        &self,
        ph: &Photon,
        p: DVec3,
        skip: Option<u32>,
        ground: bool,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
        mut f: impl FnMut(usize, DVec3, &mut [f64]) -> bool,
    ) {
        if let Some(rx) = &self.receiver {
            self.peel_receiver(
                rx,
                ph,
                (p, ph.shift, ph.path),
                skip,
                ph.ret.as_deref(),
                out,
                scratch,
                tr,
                f,
            );
            return;
        }
        for v in 0..self.inp.views.len() {
            // Transmittance first: deep in dense canopies it underflows and the (costly for
            // non-spherical LADs) phase value is not needed. Contributions below 1e-30 of the
            // photon weight are dropped (relative bias < 1e-30).
            let d = self.inp.views[v];
            let hs: &[[f64; 2]] = match self.hs_view.get(v) {
                Some(h) if ph.order == 0 && ph.off == 0 => h,
                _ => &[],
            };
            self.transmittance(p, d, f64::INFINITY, &self.g_view[v], hs, skip, tr);
            if tr.iter().all(|&t| t < 1e-30) || !f(v, d, scratch) {
                continue;
            }
            let base = self.sum.view(v, ph.off);
            let comp = match (ph.order, ground) {
                (0, false) => 0,
                (0, true) => 1,
                _ => 2,
            };
            let cbase = self.sum.view_component(v, comp, ph.off);
            for b in 0..self.nb {
                let x = ph.w[b] * scratch[b] * tr[b];
                out.summary[base + b] += x;
                out.summary[cbase + b] += x;
            }
            // Under an atmosphere: on to the TOA through the column.
            if let Some(atm) = self.inp.atmosphere {
                for b in 0..self.nb {
                    out.summary[self.sum.toa_view(v, ph.off + b)] +=
                        ph.w[b] * scratch[b] * tr[b] * atm.view_transmittance(v, b);
                }
            }
        }
        if !self.cameras.is_empty() {
            self.peel_cameras(ph, p, skip, out, scratch, tr, &mut f);
        }
    }
}

/// Peel-off radiant intensity per unit intercepted weight of a turbid leaf event toward
/// `ov`, per band, into `s` (sr⁻¹): Γ_b(Ω'→Ω_v)/(π G(Ω')) (physics.md §3.3). Spherical LAD
/// (`closed`): its closed form from the kernel's (Γ_ρ, Γ_τ). Other LADs: the unbiased one-leaf
/// estimate given the sampled leaf normal `n`: ρ_b|Ω_v·n|/π on the incidence side, τ_b|Ω_v·n|/π
/// beyond (E_n[·] = Γ_b/(π G)). Returns whether any band is positive.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn turbid_peel_phase(
    kernel: &VolscattKernel,
    closed: bool,
    n: DVec3,
    d_in: DVec3,
    ov: DVec3,
    g_in: f64,
    rho: &[f64],
    tau: &[f64],
    s: &mut [f64],
) -> bool {
    if closed {
        let (gr, gt) = kernel.gamma_components(d_in, ov);
        let norm = 1.0 / (PI * g_in);
        for ((s, r), t) in s.iter_mut().zip(rho).zip(tau) {
            *s = (r * gr + t * gt) * norm;
        }
    } else {
        let c = ov.dot(n);
        let f = if c > 0.0 { rho } else { tau };
        for (s, f) in s.iter_mut().zip(f) {
            *s = f * c.abs() / PI;
        }
    }
    s.iter().any(|&x| x > 0.0)
}
