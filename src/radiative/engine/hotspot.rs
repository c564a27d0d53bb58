//! The hotspot correlation of first-order sun rays (physics.md §3.5; Kuusk 1985, SAILH):
//! per-material terms and their exact integral per crossing.

use super::*;

/// Hotspot terms of one turbid material for the first-order sun ray scattered along `view`
/// (upward), per unit path length: `[b, c]` such that at distance s (m) from the scattering
/// point the extinction coefficient along the ray is `u_f (G_v − b e^{−c s})` instead of
/// `u_f G_v`. This is physics.md §3.5, the SAILH joint gap probability of Kuusk 1985 /
/// Verhoef 1998 put into the ray tracking: per unit *height* z = s μ_v the extinction is
/// `u_f (k_v − √(k_s k_v) e^{−c_z z})` with `k_s = G_s/μ_s`, `k_v = G_v/μ_v`,
/// `c_z = 2Δ/(l (k_s + k_v))` (m⁻¹), `Δ = |tan θ_v e_v − tan θ_s e_s|` the horizontal separation
/// of the sun and view rays per unit height and `l` the leaf dimension, m; so
/// `b = √(k_s k_v) μ_v` and `c = c_z μ_v`. `sun` is the propagation vector of the beam
/// (downward). `[0, 0]` for downward views.
pub fn hotspot_terms(
    sun: DVec3,
    view: DVec3,
    g_sun: f64,
    g_view: f64,
    leaf_size_m: f64,
) -> [f64; 2] {
    let (mu_s, mu_v) = (-sun.z, view.z);
    if mu_s <= 0.0 || mu_v <= 0.0 || leaf_size_m <= 0.0 || g_sun <= 0.0 || g_view <= 0.0 {
        return [0.0; 2];
    }
    let (ks, kv) = (g_sun / mu_s, g_view / mu_v);
    let dx = view.x / mu_v + sun.x / mu_s;
    let dy = view.y / mu_v + sun.y / mu_s;
    let delta = (dx * dx + dy * dy).sqrt();
    [
        (ks * kv).sqrt() * mu_v,
        2.0 * delta / (leaf_size_m * (ks + kv)) * mu_v,
    ]
}

/// Hotspot terms per unit path length for any geometry (the LiDAR return, physics.md §9.6
/// "hotspot caveat"): a ray leaving a first-order collision along `d_out` after arriving along
/// `d_in` (propagation vectors) is at distance s from the reversed incoming ray by
/// `s |d_out + d_in|`; the gaps stay correlated over a leaf dimension `l` (Kuusk 1985), so the
/// extinction coefficient along it is `u_f (G_out − b e^{−c s})` with `b = √(G_in G_out)` and
/// `c = 2|d_out + d_in| / (l (G_in + G_out))` (m⁻¹). Near backscatter in a horizontal layer this
/// is [`hotspot_terms`] to first order in the angle; exactly at backscatter (a monostatic
/// LiDAR whose receiver sits at the emitter) `b = G` and `c = 0`: the return crosses no
/// leaf it has not already passed (one-way transmittance). A separation `|d_out + d_in|` up to
/// [`BACKSCATTER_ROUNDING`] is the rounding of an exact backscatter and gives `c = 0` (see
/// there). `[0, 0]` when `l = 0`.
pub fn hotspot_terms_path(
    d_in: DVec3,
    d_out: DVec3,
    g_in: f64,
    g_out: f64,
    leaf_size_m: f64,
) -> [f64; 2] {
    if leaf_size_m <= 0.0 || g_in <= 0.0 || g_out <= 0.0 {
        return [0.0; 2];
    }
    let sep = (d_out + d_in).length();
    let sep = if sep <= BACKSCATTER_ROUNDING {
        0.0
    } else {
        sep
    };
    [
        (g_in * g_out).sqrt(),
        2.0 * sep / (leaf_size_m * (g_in + g_out)),
    ]
}

/// Largest separation `|d_out + d_in|` (radians, to first order) that
/// [`hotspot_terms_path`] takes for an exact backscatter. A monostatic LiDAR's return
/// direction, computed from the scattering point and the receiver position, is the reversed
/// flight only to rounding (1e-16 for a 500 km orbit, up to ~1e-13 for a terrestrial scanner
/// 0.1 m from a point 100 m from the origin); kept, that rounding becomes a decorrelation
/// `c ∝ sep / l` that the path length amplifies (a 65 km cell with 1 cm leaves: relative
/// 1e-9 of the return optical depth, scene-fuzz case 9202). 1e-12 rad moves a ray by 6.5e-8 m
/// over 65 km, far below any leaf size.
pub const BACKSCATTER_ROUNDING: f64 = 1e-12;

/// `∫_{z0}^{z0+dz} e^{−c z} dz` (m), stable for c → 0 and large c·z (z, dz in m, c in m⁻¹).
#[inline]
pub fn hotspot_integral(c: f64, z0: f64, dz: f64) -> f64 {
    let x = c * dz;
    if x < 1e-9 {
        crate::radiative::fastmath::exp(-c * z0) * dz * (1.0 - 0.5 * x)
    } else {
        crate::radiative::fastmath::exp(-c * z0) * attenuation(x).0 / c
    }
}
