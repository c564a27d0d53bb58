//! Thermal emission of a turbid cell through its faces (issue #34; physics.md §7.2; DART 5
//! paper §2–§3): the temperature-independent "geometric factor" that DART pre-computes per cell
//! face, direction and turbid type,
//!
//! `F_f(Ω) = ∫_{S_f} (n_f·Ω) [1 − exp(−k ℓ(x, −Ω))] dS`,  m²,
//!
//! where ℓ(x, −Ω) is the in-cell path traced backwards from the face point x and k = G(Ω) u_f
//! the extinction coefficient (m⁻¹). The power a homogeneous isothermal cell emits through
//! face f into a sector ΔΩ around Ω is `ε_L B(T) F_f(Ω) ΔΩ` (W per unit spectral interval for
//! B in W m⁻² sr⁻¹ µm⁻¹). By reciprocity F_f(Ω) is also the power that a uniform beam of unit
//! irradiance (normal to the beam) travelling along −Ω deposits in the cell after entering
//! through face f — the interception the flux tracker computes for such a beam — which is what
//! lets an isothermal closed scene radiate B(T) (Kirchhoff).
//!
//! Checks (tests): k → ∞ gives the cell's projected area on each exit face, area·(n·Ω);
//! k → 0 gives k·V in total (∫ over the exit faces of (n·Ω) ℓ dS is the cell volume); along an
//! axis, area·(1 − e^{−k c}) exactly.

use glam::DVec3;

/// The geometric factors `F_f(Ω)`, m², of a box cell of size `size` (m) with extinction
/// coefficient `k` (m⁻¹) for direction `omega` (unit), per face in the order −x, +x, −y, +y,
/// −z, +z (0 for faces Ω does not leave through), by the midpoint rule with `n × n` points per
/// face (DART's default 40; the integrand has a kink where ℓ switches entry face, so the error
/// falls as 1/n² away from it and as 1/n across it).
pub fn face_factors(size: DVec3, k: f64, omega: DVec3, n: usize) -> [f64; 6] {
    let mut out = [0.0; 6];
    let n = n.max(1);
    for axis in 0..3 {
        let mu = omega[axis];
        if mu == 0.0 {
            continue;
        }
        // The exit face: +axis when Ω points that way.
        let face = 2 * axis + usize::from(mu > 0.0);
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let (du, dv) = (size[u] / n as f64, size[v] / n as f64);
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let mut x = DVec3::ZERO;
                x[axis] = if mu > 0.0 { size[axis] } else { 0.0 };
                x[u] = (i as f64 + 0.5) * du;
                x[v] = (j as f64 + 0.5) * dv;
                let l = back_path(size, x, omega);
                sum += -(-k * l).exp_m1();
            }
        }
        out[face] = mu.abs() * sum * du * dv;
    }
    out
}

/// Length of the segment from `x` (on or in the box `[0, size]`) backwards along `−omega` to the
/// box boundary, m.
fn back_path(size: DVec3, x: DVec3, omega: DVec3) -> f64 {
    let mut l = f64::INFINITY;
    for a in 0..3 {
        let d = -omega[a];
        if d > 0.0 {
            l = l.min((size[a] - x[a]) / d);
        } else if d < 0.0 {
            l = l.min(-x[a] / d);
        }
    }
    l.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(theta_deg: f64, phi_deg: f64) -> DVec3 {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    /// Along +z only the top face emits, exactly area·(1 − e^{−k c}).
    #[test]
    fn along_an_axis_the_top_face_gives_the_slab_value() {
        let size = DVec3::new(0.5, 0.8, 1.2);
        for k in [0.1, 1.0, 7.0] {
            let f = face_factors(size, k, DVec3::Z, 8);
            let want = 0.5 * 0.8 * (1.0 - (-k * 1.2f64).exp());
            assert!((f[5] - want).abs() < 1e-14 * want.max(1.0), "{k}: {f:?}");
            assert_eq!(f[4] + f[0] + f[1] + f[2] + f[3], 0.0);
        }
    }

    /// Black cell (k → ∞): each exit face gives its projected area; thin cell (k → 0): the
    /// total is k·V (to first order), for oblique directions too.
    #[test]
    fn thick_and_thin_limits() {
        let size = DVec3::new(1.0, 0.5, 0.7);
        for (t, p) in [(30.0, 20.0), (70.0, 135.0), (110.0, 250.0), (89.0, 10.0)] {
            let o = dir(t, p);
            let f = face_factors(size, 1e9, o, 40);
            let area = [
                size.y * size.z,
                size.y * size.z,
                size.x * size.z,
                size.x * size.z,
                size.x * size.y,
                size.x * size.y,
            ];
            for a in 0..3 {
                let face = 2 * a + usize::from(o[a] > 0.0);
                let want = area[face] * o[a].abs();
                assert!(
                    (f[face] - want).abs() < 1e-9 * want.max(1e-12),
                    "{t} {p}: {f:?}"
                );
            }
            let k = 1e-6;
            let v = size.x * size.y * size.z;
            let total: f64 = face_factors(size, k, o, 200).iter().sum();
            assert!(
                ((total - k * v) / (k * v)).abs() < 2e-3,
                "{t} {p}: {total} vs {}",
                k * v
            );
        }
    }

    /// The factors converge with the number of points per face (the kink where ℓ changes entry
    /// face costs first order): 40 points per face (DART's default) within 0.5 % of 400.
    #[test]
    fn forty_points_per_face_are_within_half_a_percent() {
        let size = DVec3::new(0.5, 0.5, 0.5);
        for (t, p) in [(35.0, 10.0), (60.0, 45.0), (80.0, 200.0)] {
            let o = dir(t, p);
            let coarse = face_factors(size, 2.0, o, 40);
            let fine = face_factors(size, 2.0, o, 400);
            for (c, f) in coarse.iter().zip(&fine) {
                assert!((c - f).abs() <= 5e-3 * f.max(1e-12), "{t} {p}: {c} vs {f}");
            }
        }
    }
}
