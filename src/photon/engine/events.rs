//! Scattering-event helpers of the photon trace (DART 5 paper §4): the band-weighted choice of
//! an outcome with importance reweighting, Russian roulette, opaque BRDF surface events
//! (physics.md §5.2–5.3) and receiver mode's far-photon roulette (Lux & Koblinger 1991, ch. 6).

use super::context::{Ctx, Photon, Receiver};
use super::tally::BatchOut;
use crate::photon::sampling::{BrdfSampler, Uniform01};
use crate::physics::brdf::Brdf;
use glam::DVec3;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::PI;

/// Chooses an outcome among `p[k][b]` (per-band probabilities) with `q_k ∝ Σ_b w_b p_b(k)` and
/// reweights `w` by `p_b(k)/q_k`; returns `None` (weights zeroed) when every outcome has
/// probability zero in every band.
pub(crate) fn choose(w: &mut [f64], p: &[&[f64]], rng: &mut Xoshiro256PlusPlus) -> Option<usize> {
    let mut q: [f64; 4] = [0.0; 4];
    let mut tot = 0.0;
    for (k, pk) in p.iter().enumerate() {
        q[k] = w.iter().zip(pk.iter()).map(|(a, b)| a * b).sum();
        tot += q[k];
    }
    if tot <= 0.0 || !tot.is_finite() {
        w.iter_mut().for_each(|x| *x = 0.0);
        return None;
    }
    let u = rng.next_f64() * tot;
    let mut acc = 0.0;
    let mut k_sel = p.len() - 1;
    for k in 0..p.len() {
        acc += q[k];
        if u < acc && q[k] > 0.0 {
            k_sel = k;
            break;
        }
    }
    while q[k_sel] <= 0.0 {
        k_sel -= 1;
    }
    let qk = q[k_sel] / tot;
    for (b, x) in w.iter_mut().enumerate() {
        *x *= p[k_sel][b] / qk;
    }
    Some(k_sel)
}

/// Russian roulette with survival probability `q` (0 < q < 1): the photon goes on with its
/// weights divided by `q` (returns true) or stops (false); `balance` (one entry per band, W)
/// books killed minus added weight, whose expectation is 0.
#[inline]
pub(crate) fn roulette_survives(
    ph: &mut Photon,
    q: f64,
    rng: &mut Xoshiro256PlusPlus,
    balance: &mut [f64],
) -> bool {
    if rng.next_f64() < q {
        for (r, w) in balance.iter_mut().zip(ph.w.iter_mut()) {
            *r -= *w * (1.0 / q - 1.0);
            *w /= q;
        }
        true
    } else {
        for (r, w) in balance.iter_mut().zip(ph.w.iter()) {
            *r += *w;
        }
        false
    }
}

/// Scattering by an opaque BRDF surface (RPV, Hapke) with normal `n_in` on the incidence
/// side: peel-off `w_b BRF_b(Ω_i, Ω_v) |n·Ω_v|/π`, then importance sampling with weights
/// `BRF_b μ_o/(π pdf)` (E = directional-hemispherical albedo; physics.md §5.2–5.3).
#[allow(clippy::too_many_arguments)]
pub(crate) fn brdf_event(
    ctx: &Ctx,
    ph: &mut Photon,
    p: DVec3,
    skip: Option<u32>,
    n_in: DVec3,
    models: &[Brdf],
    sampler: &BrdfSampler,
    rng: &mut Xoshiro256PlusPlus,
    out: &mut BatchOut,
    scratch: &mut [f64],
    tr: &mut [f64],
) {
    let inp = ctx.inp;
    let nb = ctx.nb;
    let d_in = ph.d;
    ctx.peel(
        ph,
        p,
        skip,
        skip.is_none_or(|f| inp.ground_facet.get(f as usize).copied().unwrap_or(false)),
        out,
        scratch,
        tr,
        |_, ov, s| {
            let c = n_in.dot(ov);
            if c <= 0.0 {
                return false;
            }
            for b in 0..nb {
                s[b] = models[b].brf(n_in, d_in, ov) * c / PI;
            }
            true
        },
    );
    let Some(smp) = sampler.sample(n_in, d_in, rng) else {
        ph.w.iter_mut().for_each(|x| *x = 0.0);
        return;
    };
    let (dir, pdf) = (smp.dir, smp.pdf);
    let c = n_in.dot(dir);
    if pdf <= 0.0 || c <= 0.0 {
        ph.w.iter_mut().for_each(|x| *x = 0.0);
        return;
    }
    for b in 0..nb {
        ph.w[b] *= models[b].brf(n_in, d_in, dir) * c / (PI * pdf);
    }
    ph.d = dir;
    if inp.params.sampler.is_discrete() {
        ph.di = inp.dirs.find_sector(ph.d);
        ph.d = ctx.omega[ph.di];
    }
}

/// Stop factor `c` of [`LidarEstimator::ExpectedValue`](crate::scene::desc::LidarEstimator::ExpectedValue) ([`Ctx::scatter_flight`]): the walk of
/// a multiple-scattering flight goes on to `c` times its collision's optical depth; c = 1: the
/// track-length estimator (the return integrated along the flight up to its collision). On the
/// forest ALS error study (600 photons, 8 realizations) c = 1, 1.5, 2, 3, 4 and ∞ gave 0.82,
/// 0.79, 0.73, 0.74, 0.76 and 0.75 % total error with the estimator's first settings; with the
/// current defaults (72 rays, far-photon roulette; 768 realizations, standard error 0.002 %): c = 1 0.996 % at 711.1k instructions per pulse, c = 2 1.003 % at 752.0k (384: c =
/// 1.25 1.001 % at 729.2k, 1.5 0.999 % at 738.3k): c = 1 has the lowest error and cost (README of
/// 4df2100, LiDAR speed against error).
pub(crate) const MS_STOP_FACTOR: f64 = 1.0;

/// Smallest distance scale ρ₀ of the far-photon roulette (`far_roulette_survival`), in
/// horizontal cell sizes (the larger of x and y); the scene's mean free path in the vegetation
/// raises it (`lidar::simulate::far_roulette_scale_m`).
pub const FAR_ROULETTE_CELLS: f64 = 2.0;

/// Smallest survival probability of the far-photon roulette ([`far_roulette_survival`]): a
/// survivor's weight grows at most 64-fold, so a rare survivor that reaches the field of view
/// again adds no spike larger than that to a waveform.
pub(crate) const FAR_ROULETTE_MIN_SURVIVAL: f64 = 1.0 / 64.0;

/// Survival probability of a LiDAR photon about to fly on from the unwrapped point `m` (m)
/// after a scattering event (receiver mode, [`LidarEstimator::ExpectedValue`](crate::scene::desc::LidarEstimator::ExpectedValue)): with `e` the
/// distance of `m` outside the receiver's field-of-view cone (lateral distance from the axis
/// minus the cone's radius `tan θ_FOV · s` at the point's range `s` along the axis; m),
/// `q = min(1, (ρ₀/e)²)`, at least [`FAR_ROULETTE_MIN_SURVIVAL`]. Russian roulette (survivors
/// carry `w/q`, so every expectation is unchanged; Lux & Koblinger 1991, ch. 6, weight
/// windows): a photon there can only reach the waveform again by further scattering back into
/// the cone, which its distance makes unlikely. On the forest ALS bench (1 m cells, 0.3 m
/// footprint, 0.9 m FOV radius) the multiple-scattering flights that start more than 2 m
/// outside the cone are 37 % of them but carry 1.6 % of the multiple-scattering return (their
/// later orders included). The scale: `max(2 cells, mean free path)` (4.6 m there): total
/// waveform error of the error study 0.997 → 1.002 % (384 realizations, standard error
/// 0.003 %, with the stop factor c = 2 of the time) for 7.9 % fewer instructions per pulse; ρ₀ = 2 m saves 13 % (1.001 %), 1 m 16 % but
/// with rare large errors (1.024 ± 0.010 %); on a denser layer (mean free path 1 m) ρ₀ = 0.5 m
/// raises the noise of the multiple-scattering energy 1.6-fold (README of 4df2100,
/// LiDAR speed against error). `(ρ₀, tan θ_FOV)` as stored in [`Ctx::far_roulette`].
#[inline]
pub(crate) fn far_roulette_survival(rx: &Receiver, m: DVec3, (rho0, tan_fov): (f64, f64)) -> f64 {
    let v = m - rx.position;
    let s = v.dot(rx.axis);
    let lateral = (v - s * rx.axis).length();
    let e = lateral - tan_fov * s.max(0.0);
    if e > rho0 {
        let r = rho0 / e;
        (r * r).max(FAR_ROULETTE_MIN_SURVIVAL)
    } else {
        1.0
    }
}
