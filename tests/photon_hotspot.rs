//! Issue #38: the Monte Carlo (Photon) solver's albedo, fabs and ftran carry the same hotspot
//! model as its peel-off BRFs (physics.md §3.5): a first-order sun photon's next flight uses the
//! hotspot-correlated turbid extinction its peel-off transmittance uses. On a turbid layer with
//! a leaf size, the Monte Carlo albedo equals the projected-solid-angle integral of its own
//! peel-off BRFs over every upward sector (within 4 standard errors), equals flux tracking's
//! albedo within 1 %, and energy closes.

use lumenscape::direction::{DirectionParams, DirectionSet, ExactDirection, OversampleRegion};
use lumenscape::photon::engine::SamplerKind;
use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::scene::{RunSettings, Solver};
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::*;
use lumenscape::scene::generators::BandOptics;
use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
use lumenscape::simulation::Simulation;

const Z: f64 = 4.0;

fn run(desc: &SceneDesc, settings: RunSettings) -> RadiativeProducts {
    let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), settings)
        .unwrap_or_else(|e| panic!("{e}"));
    sim.run(None).unwrap_or_else(|e| panic!("{e}"));
    sim.resource::<RadiativeProducts>().clone()
}

/// Every upward sector of a regular tiling (oversampled around the hotspot, the view toward the
/// sun) made an exact (peel-off) direction of its own: the sector's whole solid angle, its
/// representative direction.
fn all_peel_off_directions(sun_zenith_deg: f64) -> DirectionParams {
    let base = DirectionParams {
        count: 200,
        oversample: vec![OversampleRegion::Cone {
            zenith_deg: sun_zenith_deg,
            azimuth_deg: 0.0,
            half_angle_deg: 6.0,
            solid_angle_sr: 0.001,
        }],
        ..Default::default()
    };
    let set = DirectionSet::new(&base).unwrap();
    let exact = set
        .tiling()
        .iter()
        .filter(|d| d.omega.z > 0.0)
        .map(|d| ExactDirection {
            zenith_deg: d.omega.z.clamp(-1.0, 1.0).acos().to_degrees(),
            azimuth_deg: d.omega.y.atan2(d.omega.x).to_degrees().rem_euclid(360.0),
            label: None,
            solid_angle_sr: Some(d.solid_angle_sr),
        })
        .collect();
    DirectionParams { exact, ..base }
}

fn layer(leaf_size_m: f64, cell_m: f64) -> SceneDesc {
    let sza = 20.0;
    let mut d = turbid_layer(&TurbidLayerParams {
        lai: 3.0,
        lad: LadDesc::Spherical,
        bands: vec![BandOptics::red()],
        height_m: 2.0,
        cell_m,
        size_m: cell_m,
        sun_zenith_deg: sza,
        sun_azimuth_deg: 0.0,
    });
    for o in d.optics.values_mut() {
        if let OpticsDesc::Turbid { leaf_size_m: l, .. } = o {
            *l = leaf_size_m;
        }
    }
    d.directions = Some(all_peel_off_directions(sza));
    d
}

/// (albedo, SE) of Monte Carlo and (Σ_j BRF_j ∫_j μ dΩ/π, SE) of its peel-off BRFs over every
/// upward sector; the SE of the sum is bounded by Σ_j w_j SE_j (fully correlated BRFs).
fn albedo_and_brf_integral(p: &RadiativeProducts, d: &SceneDesc) -> ((f64, f64), (f64, f64)) {
    let set = DirectionSet::new(d.directions.as_ref().unwrap()).unwrap();
    let up: Vec<_> = set.tiling().iter().filter(|x| x.omega.z > 0.0).collect();
    let b = &p.bands[0];
    assert_eq!(b.brf.len(), up.len());
    let (mut s, mut se) = (0.0, 0.0);
    for (e, dir) in b.brf.iter().zip(&up) {
        assert_eq!(
            e.estimator,
            Some("peel-off"),
            "sector {dir:?} not peeled off"
        );
        let w = dir.projected_sr / std::f64::consts::PI;
        s += e.brf * w;
        se += e.brf_se.unwrap() * w;
    }
    ((b.albedo, b.albedo_se.unwrap()), (s, se))
}

#[test]
fn monte_carlo_albedo_carries_the_hotspot_of_its_brfs() {
    for leaf in [0.01, 0.05] {
        let d = layer(leaf, 2.0);
        let mc = run(
            &d,
            RunSettings {
                solver: Solver::MonteCarlo {
                    photons: 150_000,
                    sampler: SamplerKind::Continuous,
                },
                ..Default::default()
            },
        );
        common_closes(&mc, leaf);
        let ((a, a_se), (i, i_se)) = albedo_and_brf_integral(&mc, &d);
        let se = (a_se * a_se + i_se * i_se).sqrt();
        let ft = run(
            &layer(leaf, 0.25),
            RunSettings {
                preset: Some(Preset::Default),
                ..Default::default()
            },
        );
        let a_ft = ft.bands[0].albedo;
        eprintln!(
            "leaf {leaf} m: MC albedo {a:.6} ± {a_se:.6}, BRF integral {i:.6} ± {i_se:.6} \
             (z {:.2}), flux tracking {a_ft:.6} (MC/FT − 1 = {:+.3} %)",
            (a - i) / se,
            100.0 * (a / a_ft - 1.0)
        );
        assert!(
            se < 0.01 * a,
            "leaf {leaf}: SE {se} too large for the comparison"
        );
        assert!(
            (a - i).abs() <= Z * se,
            "leaf {leaf}: MC albedo {a} vs its BRF integral {i} (SE {se})"
        );
        assert!(
            (a / a_ft - 1.0).abs() <= 0.01,
            "leaf {leaf}: MC albedo {a} vs flux tracking {a_ft}"
        );
    }
}

fn common_closes(p: &RadiativeProducts, leaf: f64) {
    for b in &p.bands {
        assert!(
            b.energy_closure <= 1e-9,
            "leaf {leaf}: energy closure {:e}",
            b.energy_closure
        );
        assert!(b.albedo.is_finite() && b.fabs.is_finite() && b.ftran.is_finite());
    }
}

/// Measurement probe (not run by default): `HS_LEAF`, `HS_PHOTONS`, `HS_FT` (1: flux tracking
/// too) from the environment.
#[test]
#[ignore]
fn probe() {
    let env = |k: &str, d: f64| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let leaf = env("HS_LEAF", 0.0);
    let n = env("HS_PHOTONS", 200_000.0) as u64;
    let d = layer(leaf, env("HS_MC_CELL", 2.0));
    let t = std::time::Instant::now();
    let mc = run(
        &d,
        RunSettings {
            solver: Solver::MonteCarlo {
                photons: n,
                sampler: SamplerKind::Continuous,
            },
            ..Default::default()
        },
    );
    let ((a, a_se), (i, i_se)) = albedo_and_brf_integral(&mc, &d);
    let b = &mc.bands[0];
    eprintln!(
        "leaf {leaf}: MC albedo {a:.6} ± {a_se:.6} fabs {:.6} ftran {:.6}, BRF integral {i:.6} ± {i_se:.6}, {:.1} s",
        b.fabs,
        b.ftran,
        t.elapsed().as_secs_f64()
    );
    if env("HS_FT", 0.0) > 0.0 {
        let t = std::time::Instant::now();
        let ft = run(
            &layer(leaf, env("HS_CELL", 0.25)),
            RunSettings {
                preset: Some(Preset::Default),
                ..Default::default()
            },
        );
        let b = &ft.bands[0];
        eprintln!(
            "FT albedo {:.6} fabs {:.6} ftran {:.6}, {:.1} s",
            b.albedo,
            b.fabs,
            b.ftran,
            t.elapsed().as_secs_f64()
        );
    }
}
