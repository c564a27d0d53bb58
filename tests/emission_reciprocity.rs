//! Kirchhoff's reciprocity between the turbid-cell emission factor and the flux tracker's
//! interception (issue #34 groundwork; physics.md §7.2): a black-leaved 1 m³ turbid cell
//! floating over a black ground in an isolated scene, lit by the sun from Ω, absorbs
//! `E_⊥ Σ_f F_f(Ω)` — the same geometric factor through which it would emit `ε B(T) F_f(Ω)`
//! into Ω (`radiative::emission::face_factors`). If the two disagree, a thermal mode built on
//! them would not give B(T) in an isothermal scene.

use lumenscape::radiative::emission::face_factors;
use lumenscape::scene::parse_scene;
use std::path::Path;

mod common;

/// The cell's absorbed fraction of the scene's sun power (`fabs`), sun at (`zenith`,
/// `azimuth`) (ground→sun, degrees), leaf area density `u` (m² m⁻³), spherical LAD.
fn fabs(zenith: f64, azimuth: f64, u: f64) -> f64 {
    let text = format!(
        r#"(
    version: 1,
    grid: (size_m: (6.0, 6.0), cell_m: (1.0, 1.0, 1.0), height_m: Some(3.0), boundary: Isolated),
    bands: [(name: "b", wavelength_nm: 670.0)],
    optics: {{
        "black": BiLambertian(reflectance: [0.0], transmittance: [0.0]),
        "veg": Turbid(leaf: "black", lad: Spherical, leaf_size_m: 0.0),
        "soil": Lambertian(reflectance: [0.0]),
    }},
    illumination: (sun_zenith_deg: {zenith}, sun_azimuth_deg: {azimuth}),
    radiative: (launch_spacing_m: Some(0.01)),
    objects: [
        Ground((optics: "soil")),
        TurbidPlot((footprint: Box((2.0, 2.0, 3.0, 3.0)), bottom_m: 1.0, top_m: 2.0,
                    foliage: LeafAreaDensity({u}), optics: "veg")),
    ],
)"#
    );
    let desc = parse_scene(&text, Path::new("<test>")).unwrap_or_else(|e| panic!("{e}"));
    common::run_radiative(&desc, None).bands[0].fabs
}

#[test]
fn a_black_cell_absorbs_what_its_emission_factor_says() {
    for (zenith, azimuth, u) in [(0.0, 0.0, 1.0), (30.0, 20.0, 1.0), (55.0, 130.0, 3.0)] {
        let (t, p) = (f64::to_radians(zenith), f64::to_radians(azimuth));
        // Ω: towards the sun; the beam travels along −Ω and enters through Ω's exit faces.
        let omega = glam::DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        // Spherical LAD: G = 1/2 in every direction.
        let k = 0.5 * u;
        let f: f64 = face_factors(glam::DVec3::ONE, k, omega, 400).iter().sum();
        // Irradiance normal to the beam E⊥ = E_h / cos θ, scene area 36 m², E_h = 1.
        let want = f / t.cos() / 36.0;
        let got = fabs(zenith, azimuth, u);
        let rel = (got - want).abs() / want;
        eprintln!("sun {zenith}°/{azimuth}°, u {u}: fabs {got:.6} vs factor {want:.6} ({rel:.2e})");
        // Measured ≤ 2.4e-5: the 1 cm sun lattice and the 400² face rule; 1e-3 leaves room for
        // neither to hide a wrong G, path length or face.
        assert!(rel < 1e-3, "sun {zenith}/{azimuth}, u {u}: {got} vs {want}");
    }
}
