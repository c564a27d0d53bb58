//! The two scorings of a receiver-mode flight's walk ([`FlightScore`]; DART 5 paper §4,
//! physics.md §9.2, §9.6): [`FirstOrderScore`] (the first flight: first-order return booked
//! into the receiver tally by digitiser bin, expected-value surface return) and
//! [`ScatterScore`] (later flights: the return toward the receiver integrated along the
//! flight).

use super::context::{Ctx, PerMaterial, Photon, Receiver};
use super::flight::{FlightIo, FlightScore, Segment};
use super::input::PhotonOptics;
use super::walk::return_transmittance;
use crate::photon::sampling::Uniform01;
use crate::radiative::dda::Dda;
use glam::DVec3;
use std::f64::consts::PI;

/// The first flight's scoring ([`Ctx::first_flight`]): the first-order return of the
/// vegetation binned by digitiser bin, and with [`LidarEstimator::ExpectedValue`](crate::scene::desc::LidarEstimator::ExpectedValue) the
/// Lambertian ground or facet that ends the walk, with the return transmittance from the
/// optical depth walked.
pub(crate) struct FirstOrderScore<'g> {
    pub(crate) rx: Receiver,
    /// Flight direction.
    pub(crate) d: DVec3,
    /// Cosine of the flight to the receiver axis.
    pub(crate) cos_rx: f64,
    pub(crate) in_fov: bool,
    /// Exact-backscatter intensity per unit intercepted weight per turbid material, sr⁻¹.
    pub(crate) back: PerMaterial<f64>,
    /// Photon weight, J.
    pub(crate) w: f64,
    pub(crate) g_cur: &'g [f64],
    /// Return optical depth walked (materials without a leaf size).
    pub(crate) tau_ret: f64,
    /// No one-sided facet crossed from behind yet: the return is the flight reversed.
    pub(crate) exact: bool,
    /// Current cell: return extinction k_r (m⁻¹) and Σ k_m f_m (m⁻¹ sr⁻¹).
    pub(crate) kr: f64,
    pub(crate) kf: f64,
}

impl FlightScore for FirstOrderScore<'_> {
    #[inline]
    fn cell(&mut self, ctx: &Ctx, c: usize, dda: &Dda, (t0, t1): (f64, f64), facets: bool) -> f64 {
        if self.exact && facets && ctx.facet_behind(dda, self.d, t0, t1) {
            self.exact = false;
        }
        // Extinction (m⁻¹): vegetation k_v, return k_r (materials without a leaf size), and
        // Σ k_m f_m (m⁻¹ sr⁻¹), in one pass over the cell's entries.
        let (mut kv, mut kr, mut kf) = (0.0, 0.0, 0.0);
        for e in ctx.inp.grid.turbid_of(c) {
            let tm = ctx.tur_mat[e.material as usize];
            if tm != u32::MAX {
                let k = self.g_cur[tm as usize] * e.density as f64;
                kv += k;
                kf += k * self.back[tm as usize];
                // hs_leaf ≥ 0 (validated): no leaf size means 0.
                if ctx.hs_leaf[tm as usize] <= 0.0 {
                    kr += k;
                }
            }
        }
        self.kr = kr;
        self.kf = kf;
        kv
    }

    #[inline]
    fn segment(&mut self, ctx: &Ctx, ph: &Photon, io: &mut FlightIo, seg: &Segment) {
        let &Segment {
            c,
            dda,
            t0,
            ell,
            kv,
            tau,
            l0,
            shift,
        } = seg;
        let (rx, d, g_cur) = (self.rx, self.d, self.g_cur);
        if self.in_fov {
            if self.exact {
                let base = self.w
                    * (-tau).exp()
                    * return_transmittance(self.tau_ret)
                    * self.kf
                    * rx.aperture_m2
                    * self.cos_rx;
                if base > 0.0 {
                    #[cfg(debug_assertions)]
                    ctx.check_first_flight_return(
                        ph,
                        (dda.point(t0), shift, l0),
                        d,
                        (self.tau_ret, self.kr, 0.5 * ell),
                    );
                    if let Some(wave) = io.out.wave.as_mut() {
                        wave.first_order_segment(l0, ell, kv + self.kr, base, io.rng);
                    }
                }
            } else {
                // One forced point with a shadow ray (see `Ctx::first_flight`).
                let norm = -(-kv * ell).exp_m1();
                let u = -(1.0 - io.rng.next_f64() * norm).ln() / kv;
                if let Some((mid, tm)) = ctx.pick_turbid(c, g_cur, io.rng.next_f64() * kv) {
                    let at = (dda.point(t0 + u), shift, l0 + u);
                    let fac = (-tau).exp() * norm;
                    let g_in = g_cur[tm].max(1e-12);
                    io.peel_leaf(ctx, &rx, ph, at, &ctx.inp.optics[mid], d, g_in, fac);
                }
            }
        }
        if self.exact {
            self.tau_ret += self.kr * ell;
        }
    }

    #[inline]
    fn facet(
        &mut self,
        ctx: &Ctx,
        ph: &Photon,
        io: &mut FlightIo,
        f: u32,
        at: (DVec3, DVec3, f64),
        tau: f64,
    ) -> bool {
        // `ExpectedValue`: a Lambertian facet's first-order return, scored with the
        // probability e^{−τ} of reaching it (as the ground below); past a one-sided facet
        // crossed from behind, with a shadow ray to the receiver.
        if ctx.ms_stop <= 0.0 {
            return false;
        }
        let fa = &ctx.inp.facets[f as usize];
        let PhotonOptics::Lambert { r, t, t_dir } = &ctx.inp.optics[fa.material as usize] else {
            return false;
        };
        // The facet collision's peel-off (`trace_photon`), band 0.
        let d = self.d;
        let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]).normalize();
        let n_in = if n.dot(d) < 0.0 { n } else { -n };
        let mu = n.dot(d).abs().max(1e-6);
        let td = t_dir.first().copied().unwrap_or(0.0);
        let through = if td > 0.0 { td.powf(1.0 / mu) } else { 0.0 };
        let pr = (1.0 - through) * r.first().copied().unwrap_or(0.0);
        let pt = (1.0 - through) * t.first().copied().unwrap_or(0.0);
        let fac = (-tau).exp() / PI;
        let t_ret = [return_transmittance(self.tau_ret)];
        let known = self.exact.then_some(&t_ret[..]);
        io.peel(ctx, &self.rx, ph, at, Some(f), known, |_, ov, s| {
            let c = n_in.dot(ov);
            s[0] = fac * if c > 0.0 { pr } else { pt } * c.abs();
            s[0] > 0.0
        });
        true
    }

    #[inline]
    fn ground(
        &mut self,
        ctx: &Ctx,
        ph: &Photon,
        io: &mut FlightIo,
        at: (DVec3, DVec3, f64),
        tau: f64,
    ) -> bool {
        // `ExpectedValue`: the walk reached a Lambertian ground, whose first-order return is
        // scored with the probability e^{−τ} of getting there (w e^{−τ} ρ_g μ/π T_ret A
        // cos/r², the return transmittance from the walk, or past a one-sided facet crossed
        // from behind a shadow ray) instead of at the ground collision only.
        if ctx.ms_stop <= 0.0 {
            return false;
        }
        let Some(rg) = ctx.lambert_ground() else {
            return false;
        };
        let fac = (-tau).exp() * rg / PI;
        let t_ret = [return_transmittance(self.tau_ret)];
        io.peel_ground(ctx, &self.rx, ph, at, self.exact.then_some(&t_ret[..]), fac);
        true
    }

    #[inline]
    fn stop(&self, tau: f64, _collided: bool) -> bool {
        // e^{−30} ≈ 1e-13: the forced estimate stops (as `forced_peel`).
        tau > 30.0
    }

    #[inline]
    fn surface_ret(&self) -> Option<f64> {
        self.exact.then_some(self.tau_ret)
    }
}

/// The scoring of a flight past the first scattering ([`Ctx::scatter_flight`]): one forced
/// point per vegetation segment up to the stop depth `c τ*`, and the Lambertian flat ground,
/// weighted by `e^{−(1−1/c)τ}`.
pub(crate) struct ScatterScore<'g> {
    pub(crate) rx: Receiver,
    /// Flight direction.
    pub(crate) d: DVec3,
    pub(crate) g_cur: &'g [f64],
    /// Discrete (Ray-Carlo) sampler: the Phase-stage rows give the leaf intensity.
    pub(crate) discrete: bool,
    /// Reflectance of the flat ground when Lambertian.
    pub(crate) lambert_ground: Option<f64>,
    /// Stop depth `c τ*`.
    pub(crate) tau_stop: f64,
    /// `1 − 1/c`.
    pub(crate) keep: f64,
    /// `tan²` of the receiver's FOV half-angle (< 0: a FOV of 90° or more, no segment test).
    pub(crate) fov_tan2: f64,
}

/// Whether every point of the segment from `a` along the unit vector `d` over `len` (m,
/// unwrapped coordinates) lies outside the field of view of `rx` (`tan2` = tan² of its
/// half-angle, FOV < 90°): the segment's least distance ρ from the receiver axis exceeds the
/// cone radius `s_max tan α` at the largest along-axis distance `s_max` of its ends (s is linear
/// along the segment, and a point at along-axis distance s ≤ s_max lies in the cone only if
/// ρ ≤ s tan α), with a relative margin of 1e-6 so that rounding never drops a point in view.
/// Such a segment scores nothing ([`Ctx::peel_receiver`] drops points out of view).
#[inline]
pub(crate) fn segment_out_of_fov(rx: &Receiver, tan2: f64, a: DVec3, d: DVec3, len: f64) -> bool {
    let ax = rx.axis;
    let va = a - rx.position;
    let (sa, sd) = (va.dot(ax), d.dot(ax));
    let s_max = sa.max(sa + sd * len);
    if !(s_max > 0.0) {
        return s_max <= 0.0;
    }
    // Perpendicular parts of the start and of the direction; least |pa + t pd| on [0, len].
    let pa = va - ax * sa;
    let pd = d - ax * sd;
    let pd2 = pd.length_squared();
    let t = if pd2 > 0.0 {
        (-pa.dot(pd) / pd2).clamp(0.0, len)
    } else {
        0.0
    };
    let rho2 = (pa + pd * t).length_squared();
    rho2 > (1.0 + 1e-6) * s_max * s_max * tan2
}

impl FlightScore for ScatterScore<'_> {
    #[inline]
    fn cell(&mut self, ctx: &Ctx, c: usize, _dda: &Dda, _t0t1: (f64, f64), _facets: bool) -> f64 {
        ctx.k_veg(c, self.g_cur)
    }

    #[inline]
    fn segment(&mut self, ctx: &Ctx, ph: &Photon, io: &mut FlightIo, seg: &Segment) {
        let &Segment {
            c,
            dda,
            t0,
            ell,
            kv,
            tau,
            l0,
            shift,
        } = seg;
        let (rx, d, g_cur, keep) = (self.rx, self.d, self.g_cur, self.keep);
        // Forced return over [t0, t0 + ℓ_f], ℓ_f up to the stop depth.
        let ell_f = if tau + ell * kv > self.tau_stop {
            ((self.tau_stop - tau) / kv).clamp(0.0, ell)
        } else {
            ell
        };
        if ell_f <= 0.0 {
            return;
        }
        // Nothing to score (and no draws) when the whole segment is out of the receiver's view.
        if self.fov_tan2 >= 0.0
            && segment_out_of_fov(&rx, self.fov_tan2, dda.point(t0) + shift, d, ell_f)
        {
            return;
        }
        let beta = keep * kv;
        let v = io.rng.next_f64();
        let (u, mass) = if beta * ell_f > 1e-12 {
            let em = (-beta * ell_f).exp_m1();
            (-(v * em).ln_1p() / beta, -em / beta)
        } else {
            (v * ell_f, ell_f)
        };
        let fac = (-keep * tau).exp() * mass * kv;
        let Some((mid, tm)) = ctx.pick_turbid(c, g_cur, io.rng.next_f64() * kv) else {
            return;
        };
        let material = &ctx.inp.optics[mid];
        let at = (dda.point(t0 + u.min(ell_f)), shift, l0 + u.min(ell_f));
        match material {
            PhotonOptics::Turbid {
                discrete: Some(rows),
                ..
            } if self.discrete => {
                let row = ph.di.min(rows.samplers.len() - 1);
                io.peel(ctx, &rx, ph, at, None, None, |_, ov, s| {
                    let m = ctx.inp.dirs.find_sector(ov);
                    let dom = ctx.inp.dirs.tiling()[m].solid_angle_sr;
                    s[0] = fac * rows.tables[0].get(row, m) as f64 / dom;
                    s[0] > 0.0
                });
            }
            _ => io.peel_leaf(ctx, &rx, ph, at, material, d, g_cur[tm].max(1e-12), fac),
        }
    }

    #[inline]
    fn ground(
        &mut self,
        ctx: &Ctx,
        ph: &Photon,
        io: &mut FlightIo,
        at: (DVec3, DVec3, f64),
        tau: f64,
    ) -> bool {
        let Some(rg) = self.lambert_ground else {
            return false;
        };
        // The walk reached the ground: Q = e^{−τ_g/c}.
        let fac = (-self.keep * tau).exp() * rg / PI;
        io.peel_ground(ctx, &self.rx, ph, at, None, fac);
        true
    }

    #[inline]
    fn stop(&self, tau: f64, collided: bool) -> bool {
        collided && (tau >= self.tau_stop || self.keep * tau > 30.0)
    }
}
