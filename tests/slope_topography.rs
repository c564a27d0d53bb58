//! Continuous-topography scenes (`RepetitiveContinuousTopography`, issue #31) against the
//! exact answers of a bare, uniformly sloped Lambertian ground (physics.md §1.4, §6.1, §6.5,
//! §6.6, §8.1, §9.6).
//!
//! A uniform slope under continuous topography is an infinite tilted plane z = g_x x + g_y y
//! (unit normal n = (−g_x, −g_y, 1)/√(1 + g²)). Under a sun of unit vector s (towards the sun,
//! zenith θ_s) every point of it receives E⊥ (n·s) per unit surface area, i.e.
//! E⊥ (n·s)/n_z per unit horizontal area, and it scatters once (a plane does not see itself):
//! * albedo (exitance / incident power) = ρ;
//! * Lambertian radiance ρ E⊥ (n·s)/π in every direction, so the BRF of physics.md §1.4
//!   (π L / (E⊥ cos θ_s)) is ρ (n·s)/cos θ_s in every view and in every image pixel (a
//!   sun-facing slope is brighter than ρ, a slope facing away darker; with the sun at the
//!   zenith it is ρ cos α, α the slope angle — not ρ);
//! * a nadir LiDAR pulse of energy Q hits the plane at incidence α and the receiver of area
//!   A at range R collects Q ρ cos α A / (π R²) (the flat-ground law of physics.md §9.6 with
//!   the Lambertian cosine of the tilted surface).
//!
//! Before the fixes of issue #31 the flux tracker launched the sun over the tile's own top
//! plane only and missed the rays entering through the "riser" between the tile top and its
//! lower neighbour's top (a band of ground without direct sun: the black band of the default
//! scene's nadir image), and the Monte Carlo walk counted as lost every photon re-entering
//! above the top of the box while going down.

mod common;
use common::*;
use lumenscape::direction::{DirectionKind, DirectionParams, ExactDirection};
use lumenscape::lidar::run::LidarProducts;
use lumenscape::photon::engine::SamplerKind;
use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::scene::{RunSettings, Solver};
use lumenscape::resources::tracking::Directions;
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::*;
use lumenscape::simulation::Simulation;

const SZA: f64 = 30.0;

/// A 20 m continuous-topography scene of 1 m cells over the plane z = g_x x + g_y y (a 5 m
/// raster), Lambertian soil ρ, sun (30°, `saz`), exact views nadir and (40°, 300°), images
/// with oversampling `eta`.
fn slope_scene(g: (f64, f64), rho: f64, saz: f64, eta: u32) -> SceneDesc {
    let mut d = base_scene(
        (20.0, 20.0),
        (1.0, 1.0, 1.0),
        BoundaryMode::RepetitiveContinuousTopography,
    );
    d.optics.insert("soil".into(), lambertian(rho));
    let altitude_m = (0..5)
        .flat_map(|j| (0..5).map(move |i| g.0 * 5.0 * i as f64 + g.1 * 5.0 * j as f64))
        .collect();
    d.objects.push(ObjectDesc::Ground(GroundDesc {
        optics: "soil".into(),
        topography: TopographyDesc::Raster(RasterDesc {
            nodes: (5, 5),
            spacing_m: (5.0, 5.0),
            origin_m: Default::default(),
            altitude_m,
        }),
    }));
    d.illumination.sun_zenith_deg = Some(SZA);
    d.illumination.sun_azimuth_deg = Some(saz);
    d.directions = Some(DirectionParams {
        exact: vec![
            ExactDirection::new(0.0, 0.0),
            ExactDirection::new(40.0, 300.0),
        ],
        ..Default::default()
    });
    d.radiative = Some(RadiativeDesc {
        image_oversampling: eta,
        ..Default::default()
    });
    d
}

/// Unit vector of (zenith, azimuth), degrees.
fn unit(zen: f64, az: f64) -> glam::DVec3 {
    let (t, p) = (zen.to_radians(), az.to_radians());
    glam::DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// Scene BRF of the plane z = g_x x + g_y y in the view (zenith, azimuth) (see the module
/// doc): ρ (n·s)(n·v)/(n_z v_z cos θ_s).
fn plane_brf(g: (f64, f64), rho: f64, saz: f64, view: (f64, f64)) -> f64 {
    let (s, v) = (unit(SZA, saz), unit(view.0, view.1));
    let n = glam::DVec3::new(-g.0, -g.1, 1.0).normalize();
    rho * n.dot(s) * n.dot(v) / (n.z * v.z * s.z)
}

fn run(desc: &SceneDesc, settings: RunSettings) -> (RadiativeProducts, Vec<(usize, f64)>) {
    let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), settings)
        .unwrap_or_else(|e| panic!("{e}"));
    sim.run(None).unwrap_or_else(|e| panic!("{e}"));
    let set = sim.resource::<Directions>().set.clone();
    // (tiling index, projected solid angle) of the image directions, in image order.
    let views = set
        .tiling()
        .iter()
        .enumerate()
        .filter(|(_, d)| matches!(d.kind, DirectionKind::Exact { .. }) && d.omega.z > 0.0)
        .map(|(j, d)| (j, d.projected_sr))
        .collect();
    (sim.resource::<RadiativeProducts>().clone(), views)
}

fn exact_brf(p: &RadiativeProducts, zenith: f64) -> (f64, Option<f64>) {
    let e = p.bands[0]
        .brf
        .iter()
        .find(|e| e.kind == "exact" && (e.zenith_deg - zenith).abs() < 1e-6)
        .unwrap_or_else(|| panic!("no exact view at {zenith}°"));
    (e.brf, e.brf_se)
}

/// Flux tracking on bare sloped grounds: albedo ρ (to 1e-9: one scattering, no sampling), energy
/// closure, and the BRF ρ (n·s)/cos θ_s of the nadir and the (40°, 300°) view, in every pixel
/// of their images (η = 1 and 8), the image summing to the direction's exitance. Slopes 8 %
/// and 20 % along x, sun up the slope (225°, the default scene's case: the black band), down
/// it (45°) and across it (90°, 300°); the same slope along y; and the flat-ground control
/// (continuous topography with zero offsets, and a plain repetitive flat ground).
#[test]
fn flux_tracking_images_of_a_bare_slope_are_the_plane_brf_in_every_pixel() {
    let mut cases = vec![];
    for g in [(0.08, 0.0), (0.2, 0.0), (0.0, 0.2), (0.0, 0.0)] {
        for saz in [225.0, 45.0, 90.0, 300.0] {
            cases.push((g, 0.1, saz, 1));
        }
    }
    cases.push(((0.08, 0.0), 0.3, 225.0, 8));
    cases.push(((0.2, 0.0), 0.3, 45.0, 8));
    let mut worst_px: f64 = 0.0;
    let mut worst_brf: f64 = 0.0;
    let mut worst_alb: f64 = 0.0;
    for (g, rho, saz, eta) in cases {
        let d = slope_scene(g, rho, saz, eta);
        let (p, views) = run(&d, RunSettings::default());
        let b = &p.bands[0];
        let what = format!("slope {g:?} ρ {rho} sun az {saz} η {eta}");
        worst_alb = worst_alb.max((b.albedo - rho).abs());
        assert!((b.albedo - rho).abs() < 1e-9, "{what}: albedo {}", b.albedo);
        assert!(
            b.energy_closure < 1e-9,
            "{what}: closure {}",
            b.energy_closure
        );
        assert!(b.flost < 1e-9, "{what}: lost {}", b.flost);
        let r = &p.raw;
        let (w, npx) = (r.n_channels, r.image_grid.pixels());
        for (k, (&(j, _psr), (zen, vaz))) in
            views.iter().zip([(0.0, 0.0), (40.0, 300.0)]).enumerate()
        {
            let want = plane_brf(g, rho, saz, (zen, vaz));
            let (brf, _) = exact_brf(&p, zen);
            worst_brf = worst_brf.max((brf / want - 1.0).abs());
            assert!(
                (brf / want - 1.0).abs() < 1e-3,
                "{what}: view {zen}°: BRF {brf} vs plane {want}"
            );
            let px: Vec<f64> = (0..npx).map(|q| r.images[(k * npx + q) * w]).collect();
            let sum: f64 = px.iter().sum();
            let esc = r.escaped[j * w];
            assert!(
                (sum / esc - 1.0).abs() < 1e-9,
                "{what}: Σ pixels {sum} vs {esc}"
            );
            // Pixel BRF = direction BRF × pixel power / mean pixel power.
            for (q, v) in px.iter().enumerate() {
                let v = brf * v * npx as f64 / sum;
                worst_px = worst_px.max((v / want - 1.0).abs());
                assert!(
                    (v / want - 1.0).abs() < 1e-3,
                    "{what}: view {zen}° pixel ({}, {}): BRF {v} vs plane {want}",
                    q % r.image_grid.n.0,
                    q / r.image_grid.n.0
                );
            }
        }
    }
    println!(
        "bare slopes, flux tracking: worst |albedo − ρ| {worst_alb:.1e} (limit 1e-9), worst \
         BRF error {worst_brf:.1e} (limit 1e-3), worst pixel error {worst_px:.1e} (limit 1e-3)"
    );
}

/// Monte Carlo on bare sloped grounds: albedo ρ and the nadir BRF ρ (n·s)/cos θ_s within 4
/// standard errors, no photon lost, energy closed; the sun up, down and across the slope.
#[test]
fn monte_carlo_on_a_bare_slope_loses_nothing_and_gives_the_plane_brf() {
    for (g, saz) in [((0.2, 0.0), 225.0), ((0.2, 0.0), 45.0), ((0.08, 0.0), 90.0)] {
        let d = slope_scene(g, 0.1, saz, 1);
        let settings = RunSettings {
            solver: Solver::MonteCarlo {
                photons: 200_000,
                sampler: SamplerKind::Continuous,
            },
            ..Default::default()
        };
        let (p, _) = run(&d, settings);
        let b = &p.bands[0];
        let what = format!("slope {g:?} sun az {saz}");
        assert!(b.flost < 1e-12, "{what}: lost fraction {}", b.flost);
        assert!(
            b.energy_closure < 1e-9,
            "{what}: closure {}",
            b.energy_closure
        );
        let se = b.albedo_se.unwrap().max(1e-12);
        println!(
            "{what}: MC albedo {} ± {se:.1e} ({:.2} SE from ρ)",
            b.albedo,
            (b.albedo - 0.1) / se
        );
        assert!(
            (b.albedo - 0.1).abs() <= 4.0 * se + 1e-9,
            "{what}: albedo {}",
            b.albedo
        );
        let want = plane_brf(g, 0.1, saz, (0.0, 0.0));
        let (brf, brf_se) = exact_brf(&p, 0.0);
        let brf_se = brf_se.unwrap();
        println!(
            "{what}: MC nadir BRF {brf} ± {brf_se:.1e} vs plane {want} ({:.2} SE)",
            (brf - want) / brf_se
        );
        // (A bare plane scatters once: the peel-off estimate is nearly exact, its standard
        // error ~1e-17; the floor 1e-9 · BRF covers the rounding of the sums.)
        assert!(
            (brf - want).abs() <= 4.0 * brf_se + 1e-9 * want,
            "{what}: nadir BRF {brf} vs {want}"
        );
    }
}

/// A nadir LiDAR pulse (1 J, 0.1 m² aperture, 10 km) over a bare continuous-topography
/// slope (20 % along x, ρ = 0.3): the received energy is Q ρ cos α A / (π R²), R the range
/// to the ground under the pulse (within 1 %: the Monte Carlo error of 2000 photons on a
/// single-scattering plane is far smaller; the flat ground of `lidar_stage.rs` holds 1 %).
#[test]
fn nadir_lidar_over_a_bare_slope_returns_rho_cos_alpha_over_pi() {
    let h = 10_000.0;
    let g = 0.2;
    let mut d = base_scene(
        (4.0, 4.0),
        (0.5, 0.5, 0.5),
        BoundaryMode::RepetitiveContinuousTopography,
    );
    d.optics.insert("soil".into(), lambertian(0.3));
    d.objects.push(ObjectDesc::Ground(GroundDesc {
        optics: "soil".into(),
        topography: TopographyDesc::Raster(RasterDesc {
            nodes: (3, 3),
            spacing_m: (2.0, 2.0),
            origin_m: Default::default(),
            altitude_m: (0..3)
                .flat_map(|_| (0..3).map(|i| g * 2.0 * i as f64))
                .collect(),
        }),
    }));
    d.lidars = Some(vec![lidar(
        "slope",
        h,
        PulsePattern::Single((2.0, 2.0)),
        2000,
    )]);
    let mut sim = Simulation::from_desc(&d, &SceneSource::generated(), RunSettings::default())
        .unwrap_or_else(|e| panic!("{e}"));
    sim.run(None).unwrap_or_else(|e| panic!("{e}"));
    let runs = sim.resource::<LidarProducts>().0.clone();
    let p = &runs[0].pulses[0];
    let got = p.raw.total_energy_j();
    // Ground altitude at the pulse centre (2, 2): g·2 = 0.4 m above the lowest point; the
    // platform altitude is counted from that lowest point (z0 = 0 here).
    let r = h - g * 2.0;
    let cos_a = 1.0 / (1.0 + g * g).sqrt();
    let want = 1.0 * 0.3 * cos_a * 0.1 / (std::f64::consts::PI * r * r);
    println!(
        "nadir LiDAR on a 20 % slope: received {got:e} J vs ρ cos α A/(π R²) = {want:e} J \
         ({:+.3} %)",
        100.0 * (got / want - 1.0)
    );
    assert!(
        (got / want - 1.0).abs() < 0.01,
        "received {got:e} J vs analytic {want:e} J"
    );
}
