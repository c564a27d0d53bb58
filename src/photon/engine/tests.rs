//! Unit tests of the photon engine's far-photon roulette (receiver mode).

use super::context::Receiver;
use super::events::{FAR_ROULETTE_MIN_SURVIVAL, far_roulette_survival};
use glam::DVec3;

#[test]
fn far_roulette_survival_follows_the_distance_outside_the_fov_cone() {
    let tan = 1e-3; // FOV half-angle tangent: radius 1 m at 1000 m
    let rho0 = 2.0;
    let nadir = Receiver {
        position: DVec3::new(10.0, 20.0, 1000.0),
        axis: -DVec3::Z,
        cos_fov: 1.0 / (1.0f64 + tan * tan).sqrt(),
        aperture_m2: 0.1,
    };
    let q = |rx: &Receiver, m: DVec3| far_roulette_survival(rx, m, (rho0, tan));
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b;
    // On the axis, inside the cone, and at the cone edge + ρ₀ (cone radius 1 m at z = 0).
    assert_eq!(q(&nadir, DVec3::new(10.0, 20.0, 0.0)), 1.0);
    assert_eq!(q(&nadir, DVec3::new(10.9, 20.0, 0.0)), 1.0);
    assert_eq!(q(&nadir, DVec3::new(12.9, 20.0, 0.0)), 1.0);
    // e = 4 m outside the cone at z = 0 (lateral 5 m): (2/4)².
    assert!(close(q(&nadir, DVec3::new(10.0, 25.0, 0.0)), 0.25));
    // The cone is narrower higher up: lateral 5 m at z = 500 m is e = 4.5 m.
    assert!(close(
        q(&nadir, DVec3::new(15.0, 20.0, 500.0)),
        (2.0f64 / 4.5).powi(2)
    ));
    // Far away: the floor.
    assert_eq!(
        q(&nadir, DVec3::new(500.0, 20.0, 0.0)),
        FAR_ROULETTE_MIN_SURVIVAL
    );
    // Terrestrial, looking along +x from (0, 0, 1.5): 3 m behind the scanner, 6 m to the
    // side: e = 6 m (no cone behind the apex).
    let tls = Receiver {
        position: DVec3::new(0.0, 0.0, 1.5),
        axis: DVec3::X,
        ..nadir
    };
    assert!(close(
        q(&tls, DVec3::new(-3.0, 6.0, 1.5)),
        (2.0f64 / 6.0).powi(2)
    ));
    // In front, 10 m along the axis (cone radius 0.01 m), 1.01 m to the side: e = 1 m ≤ ρ₀.
    assert_eq!(q(&tls, DVec3::new(10.0, 0.0, 2.51)), 1.0);
}
