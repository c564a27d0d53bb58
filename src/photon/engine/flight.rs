//! Receiver-mode (LiDAR) flights scored along their walk (DART 5 paper §4; physics.md §9.2,
//! §9.6): the first flight from the emitter with its expected-value first-order return
//! stratified by digitiser bin ([`Ctx::first_flight`]), the multiple-scattering flights'
//! expected-value return ([`Ctx::scatter_flight`]), the walk they share
//! ([`Ctx::walk_flight`]) and its scoring interface ([`FlightScore`]).

use super::context::{Ctx, Hit, PerMaterial, Photon, Receiver};
use super::input::PhotonOptics;
use super::peel_off::turbid_peel_phase;
use super::scores::{FirstOrderScore, ScatterScore};
use super::tally::BatchOut;
use super::walk::{cross_empty, fly_skip};
use crate::photon::sampling::Uniform01;
use crate::photon::small::Small;
use crate::radiative::dda::{Dda, Exit};
use crate::scene::desc::BoundaryMode;
use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::PI;
use std::ops::ControlFlow;

impl Ctx<'_> {
    /// The LiDAR first flight from the emitter in one walk (receiver mode, `ph.order == 0`,
    /// `ph.direct`, one band, no fluid; [`LidarEstimator::Stratified`](crate::scene::desc::LidarEstimator::Stratified) and
    /// [`LidarEstimator::ExpectedValue`](crate::scene::desc::LidarEstimator::ExpectedValue)): the collision is
    /// sampled as [`Ctx::fly`] does (same free path, cells, facet and exit rules, so the same
    /// hit distribution: [`Ctx::walk_flight`]), and along the same walk the expected-value
    /// (forced) first-order return of the whole flight is binned ([`FirstOrderScore`]; DART 5
    /// paper §4 forced peel-off, physics.md §9.2, §9.6).
    ///
    /// Every point of this flight lies on the ray from the monostatic receiver, so the return
    /// direction is −Ω, at the distance L walked from the emitter, recorded at path 2L, with
    /// cosine Ω·axis to the receiver axis, and the return transmittance is the optical depth
    /// already walked (see [`Ctx::forced_peel`]). A vegetation segment `u ∈ [0, ℓ]` entered at
    /// distance L₀ with optical depth τ (and return depth τ_r) then sends
    /// `w e^{−τ−τ_r} Σ_m k_m f_m e^{−(k_v + k_r)u} · A (Ω·axis)/(L₀ + u)²` J per metre, with
    /// `f_m = ρ_m ⟨|Ω·Ω_L|⟩_m/π` (sr⁻¹) the exact-backscatter intensity per unit intercepted
    /// weight ([`crate::photon::sampling::LeafSampler::mean_abs_cos`]; the expectation of the
    /// one-leaf estimate). That density is integrated by stratified sampling with the digitiser
    /// bins as strata (at most `MAX_FIRST_ORDER_STRATA` per segment, grouping bins beyond):
    /// per stratum the exact mass of `e^{−αu}` times `1/(L₀ + u)²` at one point drawn from
    /// `e^{−αu}` inside it. Unbiased, and only the slowly varying `1/(L₀ + u)²` is sampled,
    /// so the first-order waveform has no per-bin sampling noise left for a given beam ray.
    /// A cell where the flight crosses a one-sided facet from behind (a hit for the return)
    /// switches the rest of the walk to one forced point per segment with a shadow ray.
    ///
    /// [`LidarEstimator::ExpectedValue`](crate::scene::desc::LidarEstimator::ExpectedValue): when the walk reaches a Lambertian flat ground (no
    /// facet crossed from behind), the ground's first-order return is scored there with the
    /// probability `e^{−τ_g}` of reaching it: `w e^{−τ_g} (ρ_g μ_r/π) T_ret A (Ω·axis)/r²` J
    /// (μ_r the cosine of the return direction, T_ret from the walk), and the ground collision
    /// of the flight is not peeled off (`Photon::surface_scored`): an unbiased expected value
    /// that removes the 0-or-1 noise of the ground return under the crowns. A Lambertian facet
    /// that ends the walk is scored the same way with its collision peel-off (reflected
    /// `(1 − t_d) ρ |n·u|/π` on the incidence side, `(1 − t_d) τ |n·u|/π` beyond, t_d the direct
    /// transmittance).
    ///
    /// Returns the hit (the photon's path, shift and position updated as [`Ctx::fly`] does)
    /// and, when the flight ends on a surface with no volume collision before it, the return
    /// optical depth there (for the surface's own collision peel-off).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn first_flight(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) -> (Hit, Option<f64>) {
        let Some(rx) = self.receiver else {
            return (self.fly(ph, g_cur, rng, out), None);
        };
        let tau_star = -(1.0 - ph.first_u.unwrap_or_else(|| rng.next_f64())).ln();
        let mut score = self.first_order_score(rx, ph, g_cur);
        let mut io = FlightIo {
            rng,
            out,
            scratch,
            tr,
        };
        self.walk_flight(ph, g_cur, tau_star, &mut io, &mut score)
    }

    /// The first-order scoring of a flight from the emitter ([`FirstOrderScore`]).
    pub(crate) fn first_order_score<'g>(
        &self,
        rx: Receiver,
        ph: &Photon,
        g_cur: &'g [f64],
    ) -> FirstOrderScore<'g> {
        let d = ph.d;
        let cos_rx = d.dot(rx.axis);
        // Exact-backscatter intensity per unit intercepted weight, per turbid material.
        let back: PerMaterial<f64> = Small::from_fn(self.tur_ids.len(), |tm| {
            match &self.inp.optics[self.tur_ids[tm] as usize] {
                PhotonOptics::Turbid { sampler, rho, .. } => {
                    rho[0] * sampler.mean_abs_cos(d.z, g_cur[tm]) / PI
                }
                _ => 0.0,
            }
        });
        FirstOrderScore {
            rx,
            d,
            cos_rx,
            in_fov: cos_rx >= rx.cos_fov,
            back,
            w: ph.w[0],
            g_cur,
            tau_ret: 0.0,
            exact: true,
            kr: 0.0,
            kf: 0.0,
        }
    }

    /// A LiDAR flight past the first scattering (receiver mode, `ph.order ≥ 1`, one band, no
    /// fluid; `ms_stop = c ≥ 1`): the collision is sampled as [`Ctx::fly`] does (same free path
    /// τ*, cells, facet and exit rules, so the same hit distribution: [`Ctx::walk_flight`])
    /// and, along the same walk, the single-scattering return of the flight toward the
    /// receiver is integrated instead of being taken at the collision only ([`ScatterScore`];
    /// expected-value estimator, DART 5 paper §4 forced peel-off applied to every order;
    /// physics.md §9.2).
    ///
    /// The walk goes on past the collision up to the optical depth `c τ*` (or the first facet,
    /// the ground, the top or an isolated side): a point at depth τ(u) is reached with
    /// probability `Q(u) = e^{−τ(u)/c}`, so the return density
    /// `w e^{−τ(u)} Σ_m k_m f_m T_ret A (u_r·axis)/r²` J m⁻¹ (k_m = G_m u_{f,m} m⁻¹, f_m the leaf
    /// intensity per unit intercepted weight toward the receiver, sr⁻¹, T_ret the return
    /// transmittance, A the aperture m², r the distance m) is scored divided by Q: weight
    /// `e^{−(1−1/c)τ}`. Unbiased for any c ≥ 1 (c = 1: the track-length estimator, c = ∞: the
    /// expected value along the whole ray, cut at (1 − 1/c)τ > 30, e^{−30} ≈ 1e-13). One point
    /// per crossed vegetation cell, drawn with density ∝ e^{−(1−1/c)k_v u}, carries the
    /// segment's exact mass; its material is drawn in proportion to k_m. A Lambertian flat
    /// ground reached by the walk is scored the same way (`w e^{−(1−1/c)τ_g} ρ_g μ/π T_ret A
    /// cos/r²`). The turbid and ground collisions of such a flight are then not peeled off.
    /// Discrete sampler: `f_m` is the Phase-stage row of the flight's direction toward the
    /// receiver's sector (T/ΔΩ), as the collision peel-off uses.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn scatter_flight(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        rng: &mut Xoshiro256PlusPlus,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
    ) -> Hit {
        let Some(rx) = self.receiver else {
            return self.fly(ph, g_cur, rng, out);
        };
        let tau_star = -(1.0 - rng.next_f64()).ln();
        let mut score = ScatterScore {
            rx,
            d: ph.d,
            g_cur,
            discrete: self.inp.params.sampler.is_discrete(),
            lambert_ground: self.lambert_ground(),
            tau_stop: self.ms_stop * tau_star,
            keep: 1.0 - 1.0 / self.ms_stop,
            fov_tan2: if rx.cos_fov > 0.0 {
                (1.0 - rx.cos_fov * rx.cos_fov) / (rx.cos_fov * rx.cos_fov)
            } else {
                -1.0
            },
        };
        let mut io = FlightIo {
            rng,
            out,
            scratch,
            tr,
        };
        self.walk_flight(ph, g_cur, tau_star, &mut io, &mut score).0
    }

    /// The walk of a LiDAR flight shared by [`Ctx::first_flight`] and [`Ctx::scatter_flight`]:
    /// the collision at the free optical path `tau_star` is sampled as [`Ctx::fly_to`] does
    /// (same cells, facet, exit and wrap rules, so the same hit), while `score` integrates the
    /// flight's return toward the receiver over every vegetation segment walked
    /// ([`FlightScore::segment`]) and at the facet or flat ground that ends the walk. The walk
    /// goes on past the collision until `score` stops it ([`FlightScore::stop`]), a facet, the
    /// ground, the top or an isolated side. A stop before the collision (the forced estimate
    /// cut at a large optical depth) flies the photon again from its start with the same free
    /// path ([`Ctx::fly_to`]). Returns the hit (the photon's path, shift and position updated
    /// as [`Ctx::fly`] does) and, when the flight ends on a surface with no collision before
    /// it, [`FlightScore::surface_ret`].
    pub(crate) fn walk_flight<S: FlightScore>(
        &self,
        ph: &mut Photon,
        g_cur: &[f64],
        tau_star: f64,
        io: &mut FlightIo,
        score: &mut S,
    ) -> (Hit, Option<f64>) {
        let spec = self.inp.spec;
        let mut w = FlightWalk {
            d: ph.d,
            path0: ph.path,
            left: tau_star,
            tau: 0.0,
            skip: ph.skip_facet,
            shift: ph.shift,
            crossings: 0,
            travelled: 0.0,
            coll: None,
            ret: None,
        };
        let p = ph.p;
        // How the walk ended when no collision came first (None: stopped, fly again).
        let end: Option<Hit> = 'walk: {
            let Some(mut dda) = Dda::new_inline(spec, p, w.d) else {
                break 'walk Some(Hit::Lost);
            };
            loop {
                io.out.crossings += 1;
                let c = dda.index();
                let r = self.empty[c];
                let exit = if r != 0 {
                    if r > 1 {
                        fly_skip(&mut dda, r, &mut io.out.skipped)
                    } else {
                        cross_empty(&mut dda, &self.empty, &mut io.out.crossings)
                    }
                } else {
                    match self.flight_cell(ph, &mut w, &mut dda, io, score) {
                        ControlFlow::Continue(exit) => exit,
                        ControlFlow::Break(end) => break 'walk end,
                    }
                };
                if let ControlFlow::Break(end) =
                    self.flight_exit(ph, &mut w, &mut dda, exit, io, score)
                {
                    break 'walk end;
                }
            }
        };
        if let Some((c, q, path, sh)) = w.coll {
            ph.path = path;
            ph.shift = sh;
            return (Hit::Volume { c, p: q }, None);
        }
        match end {
            Some(hit) => (hit, w.ret),
            // A walk with no collision to sample (τ* = ∞: a column ray of `FirstOrderColumns`).
            None if tau_star == f64::INFINITY => (Hit::Lost, None),
            // Stopped before the free path ran out (the first flight's forced walk at τ > 30,
            // probability e^{−30}): the flight goes on from its start with the same free path.
            None => (self.fly_to(ph, g_cur, tau_star, io.rng, io.out), None),
        }
    }

    /// One non-empty cell of a flight's walk ([`Ctx::walk_flight`]): the segment to the cell's
    /// exit or its first facet hit, the collision sampled in it when the free path runs out
    /// there, the segment scored ([`FlightScore::segment`]) and its optical depth added. Breaks
    /// with the walk's end when a facet ends it (scored, [`FlightScore::facet`]) or `score`
    /// stops it (`None`); else advances the DDA and continues with its exit.
    #[inline(always)]
    fn flight_cell<S: FlightScore>(
        &self,
        ph: &mut Photon,
        w: &mut FlightWalk,
        dda: &mut Dda,
        io: &mut FlightIo,
        score: &mut S,
    ) -> ControlFlow<Option<Hit>, Exit> {
        let c = dda.index();
        let t0 = dda.t;
        let mut t1 = dda.t_exit();
        let has_facets = self.inp.grid.facet_start[c] < self.inp.grid.facet_start[c + 1];
        let fhit = if has_facets {
            self.facet_hit(dda, w.d, t0, t1, w.skip)
        } else {
            None
        };
        if let Some((_, th)) = fhit {
            t1 = th.max(t0);
        }
        let kv = score.cell(self, c, dda, (t0, t1), has_facets);
        let ell = t1 - t0;
        if ell > 0.0 && kv > 0.0 {
            let dt = ell * kv;
            if w.coll.is_none() {
                if dt >= w.left {
                    let t = t0 + w.left / kv;
                    w.coll = Some((c, dda.point(t), w.path0 + w.travelled + t, w.shift));
                } else {
                    w.left -= dt;
                }
            }
            let seg = Segment {
                c,
                dda,
                t0,
                ell,
                kv,
                tau: w.tau,
                l0: w.path0 + w.travelled + t0,
                shift: w.shift,
            };
            score.segment(self, ph, io, &seg);
            w.tau += dt;
        }
        if let Some((f, th)) = fhit {
            let at = (dda.point(th), w.shift, w.path0 + w.travelled + th);
            if score.facet(self, ph, io, f, at, w.tau) {
                ph.surface_scored = true;
            }
            if w.coll.is_none() {
                ph.path = at.2;
                ph.shift = w.shift;
                w.ret = score.surface_ret();
            }
            return ControlFlow::Break(Some(Hit::Facet { f, p: at.0 }));
        }
        if score.stop(w.tau, w.coll.is_some()) {
            return ControlFlow::Break(None);
        }
        ControlFlow::Continue(dda.advance())
    }

    /// Where a flight's walk goes after the DDA left a cell through `exit`: on inside, or
    /// through a repetitive side into the wrapped point (the DDA restarted in place); else it
    /// breaks with its end: an escape through the top, the flat ground or bottom (scored,
    /// [`FlightScore::ground`]), or a loss (isolated side, crossings or path limit, failed
    /// re-entry). Without a collision before it, the photon's path, position and shift are
    /// those of the end.
    #[inline(always)]
    fn flight_exit<S: FlightScore>(
        &self,
        ph: &mut Photon,
        w: &mut FlightWalk,
        dda: &mut Dda,
        exit: Exit,
        io: &mut FlightIo,
        score: &mut S,
    ) -> ControlFlow<Option<Hit>> {
        let spec = self.inp.spec;
        match exit {
            Exit::Inside => ControlFlow::Continue(()),
            Exit::Top => {
                if w.coll.is_none() {
                    ph.path = w.path0 + w.travelled + dda.t;
                    ph.p = dda.point(dda.t);
                    ph.shift = w.shift;
                }
                ControlFlow::Break(Some(Hit::Escape))
            }
            Exit::Bottom => {
                let at = (dda.point(dda.t), w.shift, w.path0 + w.travelled + dda.t);
                if score.ground(self, ph, io, at, w.tau) {
                    ph.surface_scored = true;
                }
                if w.coll.is_none() {
                    ph.path = at.2;
                    ph.shift = w.shift;
                }
                ControlFlow::Break(Some(if self.inp.flat_ground.is_some() {
                    w.ret = score.surface_ret();
                    Hit::Ground { p: at.0 }
                } else {
                    Hit::Lost
                }))
            }
            Exit::Side(axis, s) => {
                if spec.boundary == BoundaryMode::Isolated {
                    return ControlFlow::Break(Some(Hit::Lost));
                }
                w.crossings += 1;
                if w.crossings > self.inp.params.max_crossings
                    || w.path0 + w.travelled + dda.t > self.max_path
                {
                    return ControlFlow::Break(Some(Hit::Lost));
                }
                let e = dda.point(dda.t);
                match self.wrap(e, axis, s, w.d) {
                    Some((q, ta)) => {
                        w.travelled += dda.t + ta;
                        w.shift += e + w.d * ta - q;
                        w.skip = None;
                        // The same direction from q: restarted in place.
                        if dda.restart(spec, q) {
                            return ControlFlow::Continue(());
                        }
                        ControlFlow::Break(Some(Hit::Lost))
                    }
                    None => {
                        // (Continuous topography: see `Ctx::fly_exit`.)
                        let topo = spec.topography_offset != (0.0, 0.0);
                        ControlFlow::Break(Some(if w.d.z > 0.0 || topo {
                            Hit::Escape
                        } else {
                            Hit::Lost
                        }))
                    }
                }
            }
        }
    }

    /// Debug builds: the first flight's return geometry and transmittance (distance `l0 + u`
    /// along the ray, direction −Ω, optical depth `τ_r + k_r u`) against the point's actual
    /// vector to the receiver and the shadow ray they replace (relative 1e-9).
    #[cfg(debug_assertions)]
    pub(crate) fn check_first_flight_return(
        &self,
        ph: &Photon,
        (at, shift, l0): (DVec3, DVec3, f64),
        d: DVec3,
        (tau_ret, kr, u): (f64, f64, f64),
    ) {
        let Some(rx) = &self.receiver else { return };
        let m = at + d * u + shift;
        let v = rx.position - m;
        let r = v.length();
        debug_assert!(
            (r - (l0 + u)).abs() <= 1e-9 * r.max(1.0),
            "first-flight distance {} vs {r}",
            l0 + u
        );
        let mut ray = [0.0];
        self.transmittance_to_receiver(ph, at + d * u, v / r, r, None, &mut ray);
        let t = super::walk::return_transmittance(tau_ret + kr * u);
        debug_assert!(
            (ray[0] - t).abs() <= 1e-9 * ray[0].max(t) + 1e-25,
            "first-flight return transmittance {t:e} vs shadow ray {:e}",
            ray[0]
        );
    }
}

/// The random stream and outputs a flight's walk and its scoring share ([`Ctx::walk_flight`]).
pub(crate) struct FlightIo<'x> {
    pub(crate) rng: &'x mut Xoshiro256PlusPlus,
    pub(crate) out: &'x mut BatchOut,
    /// Peel-off intensity scratch (one band).
    pub(crate) scratch: &'x mut [f64],
    /// Return transmittance scratch (one band).
    pub(crate) tr: &'x mut [f64],
}

impl FlightIo<'_> {
    /// [`Ctx::peel_receiver`] of the point `at` = (point, shift, path) with these scratches.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(crate) fn peel(
        &mut self,
        ctx: &Ctx,
        rx: &Receiver,
        ph: &Photon,
        at: (DVec3, DVec3, f64),
        skip: Option<u32>,
        known: Option<&[f64]>,
        f: impl FnMut(usize, DVec3, &mut [f64]) -> bool,
    ) {
        ctx.peel_receiver(rx, ph, at, skip, known, self.out, self.scratch, self.tr, f);
    }

    /// A forced turbid point at `at` of a flight along `d`, scored with `fac` times the leaf
    /// intensity of `material` toward the receiver ([`turbid_peel_phase`]: the spherical closed
    /// form, else the one-leaf estimate with a normal drawn here), `g_in` = G(d).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(crate) fn peel_leaf(
        &mut self,
        ctx: &Ctx,
        rx: &Receiver,
        ph: &Photon,
        at: (DVec3, DVec3, f64),
        material: &PhotonOptics,
        d: DVec3,
        g_in: f64,
        fac: f64,
    ) {
        let PhotonOptics::Turbid {
            sampler,
            kernel,
            rho,
            tau,
            ..
        } = material
        else {
            return;
        };
        let closed = kernel.is_closed_form();
        let n = if closed {
            DVec3::Z
        } else {
            sampler.sample_normal(d, self.rng)
        };
        self.peel(ctx, rx, ph, at, None, None, |_, ov, s| {
            if !turbid_peel_phase(kernel, closed, n, d, ov, g_in, rho, tau, s) {
                return false;
            }
            s[0] *= fac;
            true
        });
    }

    /// The Lambertian flat ground's return at `at` (reflectance factor `fac` = weight × ρ_g/π,
    /// times μ toward the receiver), with the return transmittance `known` when given.
    #[inline]
    pub(crate) fn peel_ground(
        &mut self,
        ctx: &Ctx,
        rx: &Receiver,
        ph: &Photon,
        at: (DVec3, DVec3, f64),
        known: Option<&[f64]>,
        fac: f64,
    ) {
        self.peel(ctx, rx, ph, at, None, known, |_, ov, s| {
            s[0] = fac * ov.z;
            s[0] > 0.0
        });
    }
}

/// State of a flight's walk ([`Ctx::walk_flight`]) carried from cell to cell.
struct FlightWalk {
    /// Flight direction.
    d: DVec3,
    /// Path length from the emitter at the walk's start, m.
    path0: f64,
    /// Free optical path left before the collision.
    left: f64,
    /// Optical depth walked.
    tau: f64,
    /// Facet not to hit (the one the flight starts on).
    skip: Option<u32>,
    /// Unwrapped minus wrapped position, m.
    shift: DVec3,
    /// Side crossings (repetitive scenes).
    crossings: u32,
    /// Path length walked before the last re-entry through a side, m.
    travelled: f64,
    /// The sampled collision: (cell, point, path, shift).
    coll: Option<(usize, DVec3, f64, DVec3)>,
    /// The surface's return optical depth when the flight ends on it with no collision before
    /// ([`FlightScore::surface_ret`]).
    ret: Option<f64>,
}

/// One vegetation segment of a flight's walk ([`Ctx::walk_flight`]): the part
/// `[t0, t0 + ell]` (m along the current DDA ray, ell > 0) of the flight inside cell `c`, with
/// vegetation extinction `kv` > 0 (m⁻¹).
pub(crate) struct Segment<'d> {
    pub(crate) c: usize,
    pub(crate) dda: &'d Dda,
    pub(crate) t0: f64,
    pub(crate) ell: f64,
    pub(crate) kv: f64,
    /// Optical depth walked before the segment.
    pub(crate) tau: f64,
    /// Path length from the emitter at `t0`, m.
    pub(crate) l0: f64,
    /// Unwrapped minus wrapped position, m.
    pub(crate) shift: DVec3,
}

/// What a LiDAR flight scores toward the receiver along its walk ([`Ctx::walk_flight`]):
/// [`FirstOrderScore`] (the first flight) and [`ScatterScore`] (later flights).
pub(crate) trait FlightScore {
    /// The vegetation extinction k_v (m⁻¹) of the non-empty cell `c` over `[t0, t1]` along the
    /// walk's ray (`facets`: the cell holds facets), from which the walk samples the collision.
    fn cell(&mut self, ctx: &Ctx, c: usize, dda: &Dda, t0t1: (f64, f64), facets: bool) -> f64;
    /// Scores the return of a vegetation segment (after the collision sampling in it).
    fn segment(&mut self, ctx: &Ctx, ph: &Photon, io: &mut FlightIo, seg: &Segment);
    /// Scores the return of facet `f`, which ends the walk at `at` = (point, shift, path) after
    /// the optical depth `tau`; whether it did (its collision is then not peeled off). Default:
    /// not scored.
    fn facet(
        &mut self,
        _ctx: &Ctx,
        _ph: &Photon,
        _io: &mut FlightIo,
        _f: u32,
        _at: (DVec3, DVec3, f64),
        _tau: f64,
    ) -> bool {
        false
    }
    /// Scores the return of the flat ground (or bottom) that ends the walk at `at` after the
    /// optical depth `tau`; whether it did.
    fn ground(
        &mut self,
        ctx: &Ctx,
        ph: &Photon,
        io: &mut FlightIo,
        at: (DVec3, DVec3, f64),
        tau: f64,
    ) -> bool;
    /// Whether the walk stops after a cell at optical depth `tau` (`collided`: the collision
    /// is already sampled).
    fn stop(&self, tau: f64, collided: bool) -> bool;
    /// The return optical depth of the surface that ends a flight with no collision before it
    /// (for the surface's collision peel-off), when known (default: not).
    fn surface_ret(&self) -> Option<f64> {
        None
    }
}
