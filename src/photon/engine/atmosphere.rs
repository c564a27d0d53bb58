//! Monte Carlo through the plane-parallel layered atmosphere over the scene (DART 5 paper §2
//! Fig. 1 upper atmosphere, §4 Monte Carlo; physics.md §4): one photon path through the
//! atmosphere and the Earth scene. Sun photons start at the top of the atmosphere (TOA); a
//! photon reaching the bottom of the atmosphere (BOA, the scene top) enters the scene at its
//! horizontal position wrapped into the scene (the scene repeats without end under the
//! horizontally infinite layers, as the repetitive boundary does); a photon leaving the scene
//! through its top goes on in the atmosphere until it escapes through the TOA, is absorbed, or
//! comes back down.
//!
//! * **Free paths** (physics.md §4.1): layers hold constant extinction `σ_b` per band; the
//!   flight is sampled with the layer majorant `σ̂ = max_b σ_b` and every band's weight is
//!   multiplied by its likelihood ratio — `σ_b e^{−τ_b} / (σ̂ e^{−τ̂})` at a collision,
//!   `e^{−τ_b} / e^{−τ̂}` when the flight leaves the atmosphere — which is unbiased for every
//!   band (`E[w'_b] = w_b`); the weight change goes to the atmosphere's balance account
//!   (expectation 0), so energy closes in every realisation. With one band the ratio is 1.
//! * **Collisions**: the scatterer (molecules or aerosols) is drawn band-weighted (the engine's
//!   rule, `q_k ∝ Σ_b w_b σ_{s,k,b}/σ_b`) and the weights become `w_b σ_{s,k,b}/(σ_b q_k)`; what
//!   is lost is absorbed in the layer. The new direction is drawn from that scatterer's phase
//!   function (Rayleigh with depolarisation, HG, two-term HG, isotropic; physics.md §4.2).
//! * **Peel-off to the TOA** (local estimate, Ray-Carlo eqs. 1–2): at every collision the
//!   intensity `w_b Σ_k σ_{s,k,b} P_k(Θ) / (4π σ_b) · e^{−τ_b(z→TOA)/μ_v}` toward each view; a
//!   peel-off from the scene reaches the TOA with the column's transmittance `e^{−τ_b/μ_v}`
//!   ([`PhotonAtmosphere::view_transmittance`]). The same collisions peel off down to the BOA
//!   along `−Ω_v` with `e^{−τ_b(BOA→z)/μ_v}`: the diffuse sky radiance the scene receives from
//!   the direction Ω_v (DART's `L_BOA(Ω↓)`, physics.md §10.1 stage 1, here with the scene's
//!   coupling included).

use super::context::{Bands, Ctx, Photon};
use super::tally::BatchOut;
use super::trace::next_order;
use crate::photon::sampling::{Uniform01, sample_fluid_phase};
use crate::physics::atmosphere::AtmosphereModel;
use crate::physics::phase::FluidPhase;
use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::PI;

/// The layered atmosphere as the photon engine reads it: per layer and band the extinction and
/// scattering coefficients, the optical depth from every level to the TOA, and the column's
/// transmittance toward every view.
#[derive(Debug, Clone)]
pub struct PhotonAtmosphere {
    /// Level altitudes above the BOA (scene top), m; `z[0] = 0`, last = TOA.
    z: Vec<f64>,
    /// Bands.
    nb: usize,
    /// Extinction coefficient `[layer · nb + band]`, m⁻¹.
    sig_e: Vec<f64>,
    /// Molecular (Rayleigh) scattering coefficient, m⁻¹.
    sig_r: Vec<f64>,
    /// Aerosol scattering coefficient (ω σ_e,aerosol), m⁻¹.
    sig_a: Vec<f64>,
    /// Majorant per layer, `max_b σ_e`, m⁻¹.
    maj: Vec<f64>,
    /// Optical depth from level `i` to the TOA `[i · nb + band]`.
    tau_top: Vec<f64>,
    /// Molecular phase function.
    rayleigh: FluidPhase,
    /// Aerosol phase function.
    aerosol: FluidPhase,
    /// Column transmittance `e^{−τ_b/μ_v}` toward every view `[view · nb + band]`.
    view_t: Vec<f64>,
}

impl PhotonAtmosphere {
    /// The engine's tables of `model` (levels relative to its BOA) for the peel-off views
    /// `views` (upward unit vectors).
    pub fn new(model: &AtmosphereModel, views: &[DVec3]) -> Self {
        let nl = model.n_layers();
        let nb = model.aerosol_ssa.len();
        let boa = model.levels_m[0];
        let z: Vec<f64> = model.levels_m.iter().map(|l| l - boa).collect();
        let mut sig_e = vec![0.0; nl * nb];
        let mut sig_r = vec![0.0; nl * nb];
        let mut sig_a = vec![0.0; nl * nb];
        let mut maj = vec![0.0; nl];
        for l in 0..nl {
            let dz = z[l + 1] - z[l];
            for b in 0..nb {
                let i = l * nb + b;
                sig_e[i] = model.tau_layer(l, b) / dz;
                sig_r[i] = model.tau_rayleigh[l][b] / dz;
                sig_a[i] = model.aerosol_ssa[b] * model.tau_aerosol[l][b] / dz;
                maj[l] = f64::max(maj[l], sig_e[i]);
            }
        }
        let mut tau_top = vec![0.0; (nl + 1) * nb];
        for l in (0..nl).rev() {
            for b in 0..nb {
                tau_top[l * nb + b] = tau_top[(l + 1) * nb + b] + model.tau_layer(l, b);
            }
        }
        let view_t = views
            .iter()
            .flat_map(|v| (0..nb).map(move |b| (b, v.z)))
            .map(|(b, mu)| (-tau_top[b] / mu.max(1e-12)).exp())
            .collect();
        Self {
            z,
            nb,
            sig_e,
            sig_r,
            sig_a,
            maj,
            tau_top,
            rayleigh: model.rayleigh_phase,
            aerosol: model.aerosol_phase,
            view_t,
        }
    }

    /// Number of layers.
    pub fn n_layers(&self) -> usize {
        self.z.len() - 1
    }

    /// Thickness of the atmosphere (TOA above the BOA), m.
    pub fn height_m(&self) -> f64 {
        self.z[self.z.len() - 1]
    }

    /// Column transmittance toward view `v` in band `b`, `e^{−τ_b/μ_v}`.
    #[inline]
    pub fn view_transmittance(&self, v: usize, b: usize) -> f64 {
        self.view_t[v * self.nb + b]
    }

    /// Optical depth in band `b` from altitude `z` (m above the BOA) inside layer `l` to the TOA.
    fn tau_to_top(&self, l: usize, z: f64, b: usize) -> f64 {
        self.tau_top[(l + 1) * self.nb + b]
            + self.sig_e[l * self.nb + b] * (self.z[l + 1] - z).max(0.0)
    }
}

/// Where a flight through the atmosphere ended.
enum Flight {
    /// A collision in layer `l`.
    Collision(usize),
    /// Through the TOA.
    Escaped,
    /// Down through the BOA into the scene.
    Boa,
    /// A horizontal flight in a layer without extinction (never ends).
    Lost,
}

/// One photon in the atmosphere from altitude `z` (m above the BOA; in layer 0 going up from
/// the scene top, or at the TOA going down) along `ph.d`, horizontal position `ph.p.x, ph.p.y`:
/// flights, collisions with peel-off to the TOA, the order and roulette bookkeeping of the
/// engine ([`next_order`]), until the photon escapes through the TOA (booked), dies or is lost,
/// or comes down to the BOA: then it is placed at the scene top (position wrapped into the
/// scene) and `true` is returned, for the scene's tracking to go on.
pub(crate) fn atmosphere_walk(
    ctx: &Ctx,
    atm: &PhotonAtmosphere,
    ph: &mut Photon,
    mut z: f64,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
) -> bool {
    let nb = ctx.nb;
    let off = ph.off;
    let nl = atm.n_layers();
    let mut l = if ph.d.z < 0.0 { nl - 1 } else { 0 };
    let mut tau = Bands::from_elem(0.0, nb);
    loop {
        let tau_star = -(1.0 - rng.next_f64()).ln();
        tau.iter_mut().for_each(|t| *t = 0.0);
        let (flight, tau_hat) = fly(atm, ph, &mut z, &mut l, tau_star, &mut tau);
        // Likelihood ratio of every band against the majorant's flight (see the module doc).
        let old = ph.w.clone();
        for b in 0..nb {
            let mut r = (tau_hat - tau[b]).exp();
            if let Flight::Collision(l) = flight {
                r *= atm.sig_e[l * nb + b] / atm.maj[l];
            }
            ph.w[b] *= r;
            out.summary[ctx.sum.atm_balance(off + b)] += old[b] - ph.w[b];
        }
        let l_here = match flight {
            Flight::Collision(l) => l,
            Flight::Escaped => {
                for b in 0..nb {
                    out.summary[ctx.sum.toa_escaped(off + b)] += ph.w[b];
                }
                return false;
            }
            Flight::Lost => {
                for b in 0..nb {
                    out.summary[ctx.sum.atm_lost(off + b)] += ph.w[b];
                }
                return false;
            }
            Flight::Boa => {
                enter_scene(ctx, ph, out);
                return true;
            }
        };
        if !collide(ctx, atm, ph, z, l_here, rng, out) {
            return false;
        }
        // The engine's order cap and weight-window roulette; what they book belongs to the
        // atmosphere's accounts.
        let (r0, l0): (Bands, Bands) = (
            Bands::from_fn(nb, |b| out.roulette[off + b]),
            Bands::from_fn(nb, |b| out.lost[off + b]),
        );
        let goes_on = next_order(ctx, ph, rng, out);
        for b in 0..nb {
            out.summary[ctx.sum.atm_balance(off + b)] += out.roulette[off + b] - r0[b];
            out.summary[ctx.sum.atm_lost(off + b)] += out.lost[off + b] - l0[b];
            out.roulette[off + b] = r0[b];
            out.lost[off + b] = l0[b];
        }
        if !goes_on {
            return false;
        }
        l = l_here;
    }
}

/// A flight of majorant optical depth `tau_star` from `z` in layer `l` along `ph.d` (updates
/// `z`, `l`, the horizontal position and `tau`, the optical depth per band travelled); returns
/// where it ended and the majorant optical depth travelled.
fn fly(
    atm: &PhotonAtmosphere,
    ph: &mut Photon,
    z: &mut f64,
    l: &mut usize,
    tau_star: f64,
    tau: &mut [f64],
) -> (Flight, f64) {
    let nb = atm.nb;
    let nl = atm.n_layers();
    let mu = ph.d.z;
    let mut acc = 0.0;
    loop {
        let s_exit = if mu > 0.0 {
            ((atm.z[*l + 1] - *z) / mu).max(0.0)
        } else if mu < 0.0 {
            ((atm.z[*l] - *z) / mu).max(0.0)
        } else {
            f64::INFINITY
        };
        let m = atm.maj[*l];
        let s_coll = if m > 0.0 {
            (tau_star - acc) / m
        } else {
            f64::INFINITY
        };
        let s = s_coll.min(s_exit);
        if !s.is_finite() {
            return (Flight::Lost, acc);
        }
        for (b, t) in tau.iter_mut().enumerate() {
            *t += atm.sig_e[*l * nb + b] * s;
        }
        ph.p.x += ph.d.x * s;
        ph.p.y += ph.d.y * s;
        if s_coll < s_exit {
            *z += mu * s;
            return (Flight::Collision(*l), tau_star);
        }
        acc += m * s;
        if mu > 0.0 {
            *z = atm.z[*l + 1];
            if *l + 1 == nl {
                return (Flight::Escaped, acc);
            }
            *l += 1;
        } else {
            *z = atm.z[*l];
            if *l == 0 {
                return (Flight::Boa, acc);
            }
            *l -= 1;
        }
    }
}

/// A collision at altitude `z` in layer `l`: peel-off to the TOA toward every view, then the
/// band-weighted choice of the scatterer with its absorption booked in the layer and a new
/// direction from its phase function. False when nothing scatters (every band absorbed).
#[allow(clippy::too_many_arguments)]
fn collide(
    ctx: &Ctx,
    atm: &PhotonAtmosphere,
    ph: &mut Photon,
    z: f64,
    l: usize,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
) -> bool {
    let nb = ctx.nb;
    let off = ph.off;
    out.events += 1;
    let fr = Bands::from_fn(nb, |b| {
        let e = atm.sig_e[l * nb + b];
        if e > 0.0 {
            atm.sig_r[l * nb + b] / e
        } else {
            0.0
        }
    });
    let fa = Bands::from_fn(nb, |b| {
        let e = atm.sig_e[l * nb + b];
        if e > 0.0 {
            atm.sig_a[l * nb + b] / e
        } else {
            0.0
        }
    });
    for (v, &ov) in ctx.inp.views.iter().enumerate() {
        // Up to the TOA along Ω_v, and down to the BOA along −Ω_v (the diffuse sky).
        let mu = ov.z.max(1e-12);
        let c = ph.d.dot(ov);
        let (pr, pa) = (atm.rayleigh.eval(c), atm.aerosol.eval(c));
        let (qr, qa) = (atm.rayleigh.eval(-c), atm.aerosol.eval(-c));
        for b in 0..nb {
            let up = atm.tau_to_top(l, z, b);
            let t = (-up / mu).exp();
            out.summary[ctx.sum.toa_view(v, off + b)] +=
                ph.w[b] * (fr[b] * pr + fa[b] * pa) / (4.0 * PI) * t;
            let t = (-(atm.tau_top[b] - up).max(0.0) / mu).exp();
            out.summary[ctx.sum.boa_sky(v, off + b)] +=
                ph.w[b] * (fr[b] * qr + fa[b] * qa) / (4.0 * PI) * t;
        }
    }
    let (mut qr, mut qa) = (0.0, 0.0);
    for b in 0..nb {
        qr += ph.w[b] * fr[b];
        qa += ph.w[b] * fa[b];
    }
    let abs = out.summary.as_mut_slice();
    let q = qr + qa;
    if q <= 0.0 {
        for b in 0..nb {
            abs[ctx.sum.atm_absorbed(l, off + b)] += ph.w[b];
            ph.w[b] = 0.0;
        }
        return false;
    }
    let molecules = rng.next_f64() * q < qr;
    let (f, p) = if molecules {
        (&fr, qr / q)
    } else {
        (&fa, qa / q)
    };
    for b in 0..nb {
        let w = ph.w[b] * f[b] / p;
        abs[ctx.sum.atm_absorbed(l, off + b)] += ph.w[b] - w;
        ph.w[b] = w;
    }
    let phase = if molecules {
        &atm.rayleigh
    } else {
        &atm.aerosol
    };
    ph.d = sample_fluid_phase(phase, ph.d, rng);
    true
}

/// A photon coming down through the BOA: booked as entering the scene (direct sun when it has
/// not scattered), placed at the scene top with its horizontal position wrapped into the scene;
/// in discrete mode its direction is snapped to the containing discrete direction.
fn enter_scene(ctx: &Ctx, ph: &mut Photon, out: &mut BatchOut) {
    let inp = ctx.inp;
    let spec = inp.spec;
    for b in 0..ctx.nb {
        out.summary[ctx.sum.boa_down(ph.off + b)] += ph.w[b];
        if ph.order == 0 {
            out.summary[ctx.sum.boa_direct(ph.off + b)] += ph.w[b];
        }
    }
    let wrap = |x: f64, o: f64, len: f64| {
        let u = (x - o).rem_euclid(len);
        o + if u < len { u } else { 0.0 }
    };
    ph.p = DVec3::new(
        wrap(ph.p.x, spec.origin.x, ctx.size.0),
        wrap(ph.p.y, spec.origin.y, ctx.size.1),
        spec.top(),
    );
    ph.skip_facet = None;
    if inp.params.sampler.is_discrete() && ph.order > 0 {
        ph.di = inp.dirs.find_sector(ph.d);
        ph.d = ctx.omega[ph.di];
    }
}
