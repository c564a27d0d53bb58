//! Radiative stage against truths we did not compute: DISORT (assets/reference), analytic
//! solutions (Lambertian ground, Beer's law, single-scattering closed form), energy closure,
//! hard cases and thread-count determinism.

mod common;
use common::*;
use lumenscape::physics::lad::LeafAngleDistribution;
use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::*;
use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
use lumenscape::scene::generators::{BandOptics, rami_directions};
use lumenscape::simulation::Simulation;

use common::run_radiative as run;

fn assert_closes(p: &RadiativeProducts, tol: f64, what: &str) {
    for b in &p.bands {
        assert!(
            b.energy_closure <= tol,
            "{what}: band {} energy closure {:e} > {tol:e}",
            b.band,
            b.energy_closure
        );
        assert!(
            b.albedo.is_finite() && b.fabs.is_finite() && b.ftran.is_finite(),
            "{what}: NaN in {b:?}"
        );
        for e in &b.brf {
            assert!(e.brf.is_finite() && e.brf >= 0.0, "{what}: BRF {e:?}");
        }
    }
}

/// The pure turbid layer of the oracles (no hotspot: DISORT and the closed forms have point
/// scatterers).
fn layer(lai: f64, sza: f64, cell: f64, bands: Vec<BandOptics>, lad: LadDesc) -> SceneDesc {
    let mut d = turbid_layer(&TurbidLayerParams {
        lai,
        lad,
        bands,
        height_m: 2.0,
        cell_m: cell,
        size_m: 1.0,
        sun_zenith_deg: sza,
        sun_azimuth_deg: 0.0,
    });
    no_hotspot(&mut d);
    d
}

/// BRF of the entry nearest to view zenith `vz` in the principal plane (vz > 0: sun side).
fn brf_pp(p: &RadiativeProducts, b: usize, vz: f64, sun_az: f64) -> f64 {
    let az = if vz >= 0.0 { sun_az } else { sun_az + 180.0 };
    let e = p.brf_at(b, vz.abs(), az).unwrap();
    assert!(
        (e.zenith_deg - vz.abs()).abs() < 1e-9,
        "exact view direction {vz} missing: nearest {e:?}"
    );
    e.brf
}

/// Worst relative errors (BRF over the principal plane −75…75°, albedo, soil irradiance
/// `ftran`) of the turbid layer against the extended DISORT table (LAI 1, 3, 5; sun zenith 0,
/// 20, 35, 50°; red and NIR) with `preset`, `dirs` directions and `cell` m cells; energy must
/// close in every run.
fn disort_worst(preset: Preset, dirs: usize, cell: f64) -> (f64, f64, f64) {
    let rows = disort_ext_rows();
    let (mut wb, mut wa, mut wt) = (0.0f64, 0.0f64, 0.0f64);
    for lai in [1.0, 3.0, 5.0] {
        for sza in [0.0, 20.0, 35.0, 50.0] {
            let mut d = layer(
                lai,
                sza,
                cell,
                vec![BandOptics::red(), BandOptics::nir()],
                LadDesc::Spherical,
            );
            d.directions.as_mut().unwrap().count = dirs;
            let p = run(&d, Some(preset));
            assert_closes(&p, 1e-9, "disort case");
            for (b, band) in ["red", "nir"].iter().enumerate() {
                for r in rows.iter().filter(|r| {
                    r[0].parse::<f64>().unwrap() == lai
                        && r[1] == *band
                        && r[2].parse::<f64>().unwrap() == sza
                }) {
                    let vz: f64 = r[3].parse().unwrap();
                    let want: f64 = r[4].parse().unwrap();
                    wb = wb.max((brf_pp(&p, b, vz, 0.0) / want - 1.0).abs());
                    let alb: f64 = r[5].parse().unwrap();
                    wa = wa.max((p.bands[b].albedo / alb - 1.0).abs());
                    let tran: f64 = r[6].parse::<f64>().unwrap() + r[7].parse::<f64>().unwrap();
                    wt = wt.max((p.bands[b].ftran / tran - 1.0).abs());
                }
            }
        }
    }
    eprintln!(
        "DISORT, {preset:?} preset, {dirs} directions, {cell} m cells: worst BRF error {:.3} %, albedo {:.3} %, ftran {:.3} %",
        100.0 * wb,
        100.0 * wa,
        100.0 * wt
    );
    (wb, wa, wt)
}

#[test]
fn turbid_canopy_matches_disort_with_the_reference_preset() {
    // 0.5 m cells (optical depth up to 0.6 per cell at LAI 5): the moment-matched emission
    // (physics.md §3.6) leaves no cell-size error worth a finer grid here; 400 directions
    // (the reference preset's minimum) for the angular part. Measured: BRF 0.48 %, albedo
    // 0.29 %, ftran 0.37 % (docs/performance.md); bounds: BRF 1 % (the goal), albedo
    // and ftran 0.5 %.
    let (b, a, t) = disort_worst(Preset::Reference, 400, 0.5);
    assert!(b < 0.01, "worst BRF error {b}");
    assert!(a < 0.005, "worst albedo error {a}");
    assert!(t < 0.005, "worst ftran error {t}");
}

#[test]
fn turbid_canopy_matches_disort_at_coarse_cells_with_the_default_preset() {
    // The generator's default 0.5 m cells and DART's default 100 directions: the error is the
    // angular discretisation's (the same at 0.25 m; docs/performance.md). Measured: BRF
    // 2.10 %, albedo 1.06 %, ftran 0.28 %; bounds 2.5 %, 1.25 %, 0.5 %.
    let (b, a, t) = disort_worst(Preset::Default, 100, 0.5);
    assert!(b < 0.025, "worst BRF error {b}");
    assert!(a < 0.0125, "worst albedo error {a}");
    assert!(t < 0.005, "worst ftran error {t}");
    // 1 m cells (two cells over the 2 m canopy, optical depth 1.25 per cell at LAI 5): the
    // BRF stays within 2.5 % (measured 2.13 %); the soil irradiance of the densest NIR cases
    // is 3.3 % high (one barycentre per cell cannot describe light entering a thick cell from
    // above and below at once; bound 4 %).
    let (b, a, t) = disort_worst(Preset::Default, 100, 1.0);
    assert!(b < 0.025, "worst BRF error {b}");
    assert!(a < 0.0125, "worst albedo error {a}");
    assert!(t < 0.04, "worst ftran error {t}");
}

#[test]
fn flat_lambertian_ground_has_brf_equal_to_reflectance_everywhere() {
    for (sza, skyl) in [(0.0, 0.0), (30.0, 0.3), (85.0, 0.0), (89.0, 0.5)] {
        let mut d = base_scene((4.0, 4.0), (1.0, 1.0, 1.0), BoundaryMode::Repetitive);
        d.objects.push(flat_ground());
        d.illumination.sun_zenith_deg = Some(sza);
        d.illumination.skyl = vec![skyl];
        d.directions = Some(rami_directions(0.0));
        let p = run(&d, None);
        assert_closes(&p, 1e-9, "flat ground");
        let b = &p.bands[0];
        for e in &b.brf {
            assert!((e.brf - 0.1).abs() < 1e-6, "sza {sza}: BRF {e:?}");
            if let Some(h) = e.hdrf {
                assert!((h - 0.1).abs() < 1e-6, "sza {sza}: HDRF {e:?}");
            }
        }
        assert!(
            (b.albedo - 0.1).abs() < 1e-9 && (b.fabs_ground - 0.9).abs() < 1e-9,
            "{b:?}"
        );
        // One scattering iteration suffices: the next changes nothing.
        assert!(p.iterations <= 3, "{} iterations", p.iterations);
    }
}

#[test]
fn black_leaves_transmit_the_direct_beam_by_beers_law_for_every_lad() {
    let lads = [
        LadDesc::Spherical,
        LadDesc::Uniform,
        LadDesc::Planophile,
        LadDesc::Erectophile,
        LadDesc::Plagiophile,
        LadDesc::Extremophile,
        LadDesc::Ellipsoidal {
            mean_angle_deg: 30.0,
        },
        LadDesc::Beta {
            mu: 2.770,
            nu: 1.172,
        },
    ];
    for lad in lads {
        for sza in [0.0, 37.0, 70.0] {
            let black = BandOptics {
                name: "b".into(),
                wavelength_nm: 500.0,
                leaf_r: 0.0,
                leaf_t: 0.0,
                soil_r: 0.0,
            };
            let d = layer(2.0, sza, 0.5, vec![black], lad.clone());
            let p = run(&d, None);
            assert_closes(&p, 1e-9, "black leaves");
            let g = LeafAngleDistribution::new(&lad)
                .unwrap()
                .g_function(sza.to_radians().cos());
            let expected = (-g * 2.0 / sza.to_radians().cos()).exp();
            let got = p.bands[0].ftran;
            assert!(
                (got - expected).abs() < 1e-6,
                "{lad:?} sza {sza}: T = {got} vs exp(-G LAI/μ) = {expected}"
            );
            assert!((p.bands[0].fabs - (1.0 - expected)).abs() < 1e-6);
        }
    }
}

#[test]
fn single_scattering_over_black_soil_matches_the_closed_form() {
    // physics.md §13 test 4: spherical LAD, ρ = τ = 0.45, sun (30°, φ = 0); first order only.
    let cases = [
        (1.0, 0.0, 0.0, 0.09497),
        (1.0, 30.0, 0.0, 0.11862),
        (1.0, 30.0, 180.0, 0.08517),
        (3.0, 0.0, 0.0, 0.13831),
        (3.0, 30.0, 0.0, 0.16778),
        (3.0, 30.0, 180.0, 0.12047),
    ];
    let mut errs = Vec::new();
    for cell in [0.5, 0.1] {
        let mut worst: f64 = 0.0;
        for lai in [1.0, 3.0] {
            let band = BandOptics {
                name: "g".into(),
                wavelength_nm: 550.0,
                leaf_r: 0.45,
                leaf_t: 0.45,
                soil_r: 0.0,
            };
            let mut d = layer(lai, 30.0, cell, vec![band], LadDesc::Spherical);
            // Sources then one scattering iteration: the exitance is exactly first order.
            d.radiative = Some(RadiativeDesc {
                max_iterations: Some(2),
                extrapolate: Some(false),
                ..Default::default()
            });
            let p = run(&d, None);
            assert_closes(&p, 1e-9, "single scattering");
            for &(l, vz, daz, want) in cases.iter().filter(|c| c.0 == lai) {
                let _ = l;
                let e = p.brf_at(0, vz, daz).unwrap();
                worst = worst.max((e.brf / want - 1.0).abs());
            }
        }
        errs.push(worst);
    }
    eprintln!(
        "single-scattering BRF worst relative error: {:.3} % (0.5 m cells), {:.3} % (0.1 m cells)",
        100.0 * errs[0],
        100.0 * errs[1]
    );
    // Below 0.5 % at both cell sizes: the moment-matched emission (physics.md §3.6) makes the
    // first order independent of the cell size (measured 0.227 % at 0.5 m and 0.1 m: the
    // remainder does not depend on the cell size).
    assert!(errs[0] < 0.005 && errs[1] < 0.005, "{errs:?}");
}

#[test]
fn hard_cases_keep_energy_closed_without_nan() {
    // Grazing sun, grazing view, leaf albedo 0.999, very dense and very thin cells.
    let near_white = BandOptics {
        name: "w".into(),
        wavelength_nm: 800.0,
        leaf_r: 0.5,
        leaf_t: 0.499,
        soil_r: 0.3,
    };
    for (what, d) in [
        (
            "sun 85°",
            layer(3.0, 85.0, 0.5, vec![BandOptics::nir()], LadDesc::Spherical),
        ),
        (
            "sun 89°",
            layer(3.0, 89.0, 0.5, vec![BandOptics::nir()], LadDesc::Planophile),
        ),
        (
            "albedo 0.999",
            layer(3.0, 30.0, 0.5, vec![near_white], LadDesc::Spherical),
        ),
        (
            "dense u_f = 50",
            turbid_layer(&TurbidLayerParams {
                lai: 25.0,
                height_m: 0.5,
                cell_m: 0.25,
                size_m: 1.0,
                ..Default::default()
            }),
        ),
        ("thin cells", {
            let mut d = layer(1.0, 40.0, 0.5, vec![BandOptics::red()], LadDesc::Spherical);
            d.grid.cell_m = (0.5, 0.5, 0.02);
            d
        }),
        ("view 89°", {
            let mut d = layer(2.0, 30.0, 0.5, vec![BandOptics::red()], LadDesc::Spherical);
            d.directions
                .as_mut()
                .unwrap()
                .exact
                .push(lumenscape::direction::ExactDirection::new(89.0, 0.0));
            d
        }),
        (
            "sun through cell vertices",
            layer(
                1.0,
                (2f64.sqrt()).atan().to_degrees(),
                0.5,
                vec![BandOptics::red()],
                LadDesc::Spherical,
            ),
        ),
    ] {
        let p = run(&d, None);
        assert_closes(&p, 1e-9, what);
        let b = &p.bands[0];
        assert!(
            b.albedo > 0.0 && b.albedo < 1.0,
            "{what}: albedo {}",
            b.albedo
        );
        if what == "albedo 0.999" {
            // Almost nothing is absorbed by leaves, the soil absorbs 70 % of what reaches it.
            assert!(
                p.converged,
                "{what}: did not converge in {} iterations",
                p.iterations
            );
        }
    }
}

#[test]
fn facets_in_cell_faces_and_isolated_sides_keep_energy_closed() {
    let mut d = base_scene((6.0, 6.0), (1.0, 1.0, 1.0), BoundaryMode::Isolated);
    d.objects.push(flat_ground());
    d.optics.insert("wall".into(), lambertian(0.3));
    d.objects.push(box_building((1.0, 1.0, 4.0, 3.0), 3.0));
    d.grid.height_m = Some(5.0);
    let p = run(&d, None);
    assert_closes(&p, 1e-9, "building in cell faces");
    assert!(p.bands[0].flost > 0.0, "isolated scene loses side exits");
}

#[test]
fn products_are_bit_identical_on_1_2_and_8_threads() {
    // With images (three exact views, η = 2: footprints spread over 0.5 m pixels).
    let mut d = small_forest();
    d.directions = Some(lumenscape::direction::DirectionParams {
        exact: [(0.0, 0.0), (30.0, 225.0), (55.0, 100.0)]
            .into_iter()
            .map(|(z, a)| lumenscape::direction::ExactDirection {
                zenith_deg: z,
                azimuth_deg: a,
                label: None,
                solid_angle_sr: None,
            })
            .collect(),
        ..Default::default()
    });
    d.radiative = Some(RadiativeDesc {
        image_oversampling: 2,
        ..Default::default()
    });
    let go = |n| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap();
        pool.install(|| {
            let p = run(&d, Some(Preset::Preview));
            let r = p.raw;
            (
                r.escaped.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                r.absorbed_turbid
                    .iter()
                    .map(|v| v.to_bits())
                    .collect::<Vec<_>>(),
                r.absorbed_facet
                    .iter()
                    .map(|v| v.to_bits())
                    .collect::<Vec<_>>(),
                r.images.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            )
        })
    };
    let one = go(1);
    assert_eq!(
        one.3.len(),
        3 * 24 * 24 * 2,
        "three η = 2 images of 24 × 24 pixels, 2 bands"
    );
    assert!(one.3.iter().any(|&b| f64::from_bits(b) > 0.0));
    assert_eq!(one, go(2));
    assert_eq!(one, go(8));
}

#[test]
fn orthographic_images_average_to_the_direction_brf() {
    let d = small_forest();
    let mut d = d;
    d.directions = Some(rami_directions(225.0));
    let out = std::env::temp_dir().join(format!("lumenscape-img-{}", std::process::id()));
    let mut sim = Simulation::from_desc(
        &d,
        &SceneSource::generated(),
        RunSettings {
            preset: Some(Preset::Preview),
            ..Default::default()
        },
    )
    .unwrap();
    sim.run(Some(&out)).unwrap();
    let p = sim.resource::<RadiativeProducts>().clone();
    let mut n = 0;
    for e in std::fs::read_dir(out.join("images")).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_some_and(|x| x == "exr") {
            let (nx, ny, ch) = lumenscape::io::exr_out::read_exr_channels(&path).unwrap();
            let name = path.file_stem().unwrap().to_string_lossy().to_string();
            let parts: Vec<f64> = name
                .trim_start_matches("view_")
                .split('_')
                .map(|s| s.parse().unwrap())
                .collect();
            for (b, band) in ["red", "nir"].iter().enumerate() {
                let c = ch
                    .iter()
                    .find(|(k, _)| k.ends_with(&format!("brf.{b:02}_{band}")))
                    .expect("band channel");
                let mean = c.1.iter().map(|v| *v as f64).sum::<f64>() / (nx * ny) as f64;
                let want = p.brf_at(b, parts[0], parts[1]).unwrap().brf;
                assert!(
                    (mean - want).abs() <= 1e-5 * want.max(1e-3),
                    "{name} {band}: image mean {mean} vs BRF {want}"
                );
            }
            assert!(out.join("images").join(format!("{name}.png")).is_file());
            n += 1;
        }
    }
    assert_eq!(n, 21, "one image per exact view direction");
    let _ = std::fs::remove_dir_all(out);
}

#[test]
fn rpv_and_hapke_ground_reflect_their_brf() {
    let models = brdf_models();
    for (desc, model) in models {
        for sza in [0.0, 30.0, 60.0] {
            let mut d = base_scene((2.0, 2.0), (1.0, 1.0, 1.0), BoundaryMode::Repetitive);
            d.optics.insert("brdf".into(), desc.clone());
            d.objects.push(ObjectDesc::Ground(GroundDesc {
                optics: "brdf".into(),
                topography: TopographyDesc::Flat,
            }));
            d.illumination.sun_zenith_deg = Some(sza);
            d.directions = Some(rami_directions(0.0));
            let mut sim =
                Simulation::from_desc(&d, &SceneSource::generated(), RunSettings::default())
                    .unwrap();
            sim.run(None).unwrap();
            let p = sim.resource::<RadiativeProducts>().clone();
            let dirs = sim
                .resource::<lumenscape::resources::tracking::Directions>()
                .set
                .clone();
            assert_closes(&p, 1e-9, "brdf ground");
            let sun_in = -lumenscape::direction::direction_from_deg(sza, 0.0);
            // Albedo = directional–hemispherical reflectance (rows are renormalised to it).
            let rho_dh = model.albedo_dh(sza.to_radians().cos());
            assert!(
                (p.bands[0].albedo - rho_dh.min(1.0)).abs() < 1e-6,
                "{model:?} sza {sza}: albedo {} vs ρ_DH {rho_dh}",
                p.bands[0].albedo
            );
            for e in p.bands[0].brf.iter().filter(|e| e.kind == "exact") {
                let view = lumenscape::direction::direction_from_deg(e.zenith_deg, e.azimuth_deg);
                // A discrete direction's BRF is the μ-weighted mean of the BRF over its sector
                // (exact sectors are 0.001 sr): recompute that mean independently with a
                // 64 × 64 midpoint rule over the sector bounds. Remaining difference: the row
                // renormalisation to ρ_DH (≤ 1e-3, reported by the Phase stage) → 0.3 %.
                let s = dirs
                    .tiling()
                    .iter()
                    .find(|s| s.omega.dot(view) > 1.0 - 1e-12)
                    .expect("exact sector");
                let (mut num, mut den) = (0.0, 0.0);
                for a in 0..64 {
                    let mu = s.mu_min + (a as f64 + 0.5) / 64.0 * (s.mu_max - s.mu_min);
                    for b in 0..64 {
                        let phi = s.phi_min + (b as f64 + 0.5) / 64.0 * (s.phi_max - s.phi_min);
                        let st = (1.0 - mu * mu).sqrt();
                        let o = glam::DVec3::new(st * phi.cos(), st * phi.sin(), mu);
                        num += model.brf(glam::DVec3::Z, sun_in, o) * mu;
                        den += mu;
                    }
                }
                let want = num / den;
                let point = model.brf(glam::DVec3::Z, sun_in, view);
                assert!(
                    (e.brf - want).abs() < 3e-3 * want.max(1e-3),
                    "{model:?} sza {sza} view ({}, {}): {} vs sector mean {want} (point value {point})",
                    e.zenith_deg,
                    e.azimuth_deg,
                    e.brf
                );
            }
        }
    }
}

#[test]
fn specular_leaves_add_reflection_and_keep_energy_closed() {
    let base = layer(3.0, 40.0, 0.5, vec![BandOptics::red()], LadDesc::Planophile);
    let plain = run(&base, None);
    let mut spec = base.clone();
    if let Some(OpticsDesc::Turbid { specular, .. }) = spec.optics.get_mut("vegetation") {
        *specular = Some(lumenscape::physics::lad::LeafSpecular {
            refractive_index: 1.47,
            factor: 0.5,
        });
    }
    let p = run(&spec, None);
    assert_closes(&p, 1e-9, "specular leaves");
    assert!(
        p.bands[0].albedo > plain.bands[0].albedo,
        "specular reflection raises the albedo: {} vs {}",
        p.bands[0].albedo,
        plain.bands[0].albedo
    );
    // Planophile leaves mirror the sun towards the specular direction (view zenith = sun zenith,
    // opposite azimuth): the forward BRF rises more than the backward one.
    let gain =
        |vz: f64, az: f64| p.brf_at(0, vz, az).unwrap().brf / plain.brf_at(0, vz, az).unwrap().brf;
    assert!(
        gain(45.0, 180.0) > gain(45.0, 0.0),
        "forward gain {} vs backward {}",
        gain(45.0, 180.0),
        gain(45.0, 0.0)
    );
    // ρ + τ + factor > 1 is refused with the field named.
    let mut bad = base.clone();
    if let Some(OpticsDesc::Turbid { specular, .. }) = bad.optics.get_mut("vegetation") {
        *specular = Some(lumenscape::physics::lad::LeafSpecular {
            refractive_index: 1.47,
            factor: 0.99,
        });
    }
    let e = Simulation::from_desc(&bad, &SceneSource::generated(), RunSettings::default())
        .err()
        .expect("refused");
    assert!(e.to_string().contains("specular"), "{e}");
}

/// Small facets: the sun launch grid and the sub-cell scattering points follow the facet size
/// (`radiative::engine::launch_plan`). The black-leaf disk canopy (r = 5 cm discs, 0.25 m
/// cells) transmits the direct sun as an independent ray cast against the true discs says,
/// within 4 combined standard errors (the plan's predicted lattice SE and the cast's binomial
/// SE). The former fixed cell/4 grid (6.25 cm) gave 0.5586 against 0.534 (≈ 9 of its SE).
#[test]
fn small_facets_get_a_launch_grid_that_resolves_them() {
    let desc = black_disk_canopy();
    let p = run(&desc, None);
    let plan = p.launch.expect("flux tracking reports its launch plan");
    let (gap, se_gap) = disk_canopy_gap_fraction(&desc, 200_000);
    let ft = p.bands[0].ftran;
    let se = (plan.predicted_se.powi(2) + se_gap.powi(2)).sqrt();
    eprintln!(
        "disk canopy black leaves: FT direct transmittance {ft:.4} (launch spacing {:.4} m, predicted SE {:.4}, D = {}), ray cast {gap:.4} ± {se_gap:.4}",
        plan.sun_spacing_m, plan.predicted_se, plan.subcells
    );
    assert!(plan.predicted_se <= 2.5e-3, "target 2e-3 (default preset)");
    assert!(plan.subcells >= 5, "leaf radius 5 cm in 25 cm cells");
    assert!((ft - gap).abs() <= 4.0 * se, "{ft} vs {gap}");
    assert_closes(&p, 1e-9, "disk canopy");
}

/// RPV and Hapke on DEM facets (per-normal BRDF tables). An infinite plane cannot see itself,
/// so everything it reflects escapes: the scene albedo (per unit horizontal irradiance) is the
/// facet's directional–hemispherical reflectance at the *local* sun incidence, ρ_DH(μ_local)
/// (the rows are renormalised to it), to 1e-6 — for a flat DEM (μ_local = μ_s) and for a
/// uniformly tilted DEM continued across the sides (slope 0.3, RepetitiveContinuousTopography;
/// within the ±0.9° normal quantisation). Light reflected down the slope more gently than the
/// slope never meets it again and escapes downward; before the air march of
/// `Ctx::trace` it was booked as lost (−2 %).
/// The flat DEM's exact-direction BRFs equal the flat-ground path's to 1e-9 (same tables).
#[test]
fn rpv_and_hapke_dem_facets_reflect_their_local_albedo() {
    let models = brdf_models();
    let slope = 0.3;
    for (desc, model) in models {
        for sza in [0.0, 40.0] {
            for tilted in [false, true] {
                let boundary = if tilted {
                    BoundaryMode::RepetitiveContinuousTopography
                } else {
                    BoundaryMode::Repetitive
                };
                let mut d = base_scene((2.0, 2.0), (0.5, 0.5, 0.5), boundary);
                d.optics.insert("brdf".into(), desc.clone());
                let s = if tilted { slope } else { 0.0 };
                let mut alt = Vec::new();
                for _j in 0..3 {
                    for i in 0..3 {
                        alt.push(s * i as f64);
                    }
                }
                d.objects.push(ObjectDesc::Ground(GroundDesc {
                    optics: "brdf".into(),
                    topography: TopographyDesc::Raster(RasterDesc {
                        nodes: (3, 3),
                        spacing_m: (1.0, 1.0),
                        origin_m: Default::default(),
                        altitude_m: alt,
                    }),
                }));
                d.illumination.sun_zenith_deg = Some(sza);
                d.illumination.sun_azimuth_deg = Some(0.0);
                d.directions = Some(rami_directions(0.0));
                let p = run(&d, None);
                let what = format!("{model:?} sza {sza} tilted {tilted}");
                assert_closes(&p, 1e-9, &what);
                let n = glam::DVec3::new(-s, 0.0, 1.0).normalize();
                let sun_in = -lumenscape::direction::direction_from_deg(sza, 0.0);
                let mu_local = -sun_in.dot(n);
                let rho_dh = model.albedo_dh(mu_local).min(1.0);
                // Per unit horizontal irradiance the plane intercepts all of it.
                let alb = p.bands[0].albedo;
                eprintln!(
                    "{what}: albedo {alb:.6} vs ρ_DH(μ_local = {mu_local:.4}) {rho_dh:.6} (lost {:.2e}, ftran {:.4}, fabs {:.4})",
                    p.bands[0].flost, p.bands[0].ftran, p.bands[0].fabs
                );
                // Facet normals are quantised to 1/64 per component (≤ 0.9°) to share tables:
                // the albedo must lie within ρ_DH over normals tilted ±0.9° from the true one
                // (1e-6 for the quadrature), exactly ρ_DH for the flat DEM.
                let (mut lo, mut hi) = (rho_dh, rho_dh);
                if tilted {
                    for k in -4..=4 {
                        let a = (k as f64 * 0.225f64).to_radians();
                        let rot = glam::DQuat::from_rotation_y(a);
                        let r = model.albedo_dh(-sun_in.dot(rot * n)).min(1.0);
                        lo = lo.min(r);
                        hi = hi.max(r);
                    }
                }
                assert!(
                    alb >= lo - 1e-6 && alb <= hi + 1e-6,
                    "{what}: {alb} vs ρ_DH in [{lo}, {hi}]"
                );
                if !tilted {
                    let mut f = d.clone();
                    if let Some(ObjectDesc::Ground(g)) = f.objects.last_mut() {
                        g.topography = TopographyDesc::Flat;
                    }
                    let q = run(&f, None);
                    for (a, b) in p.bands[0].brf.iter().zip(&q.bands[0].brf) {
                        assert!(
                            (a.brf - b.brf).abs() <= 1e-9 * b.brf.max(1e-3),
                            "{what}: DEM {a:?} vs flat {b:?}"
                        );
                    }
                }
            }
        }
    }
}

/// The RPV and Hapke parameter sets of the BRDF tests, as scene optics and as models.
fn brdf_models() -> [(OpticsDesc, lumenscape::physics::brdf::Brdf); 2] {
    use lumenscape::physics::brdf::Brdf;
    [
        (
            OpticsDesc::Rpv {
                rho0: vec![0.1],
                k: vec![0.8],
                theta: vec![-0.1],
                rho_c: None,
            },
            Brdf::Rpv {
                rho0: 0.1,
                k: 0.8,
                theta: -0.1,
                rho_c: None,
            },
        ),
        (
            OpticsDesc::Hapke {
                w: vec![0.6],
                b: vec![0.3],
                c: vec![0.4],
                roughness_deg: 15.0,
                b0: 0.5,
                h: 0.1,
            },
            Brdf::Hapke {
                w: 0.6,
                b: 0.3,
                c: 0.4,
                theta_bar_deg: 15.0,
                b0: 0.5,
                h: 0.1,
            },
        ),
    ]
}

/// DART's ray threshold is per steradian times the ray's solid angle (physics.md §6.4), so the
/// 0.001 sr exact view directions are tracked as far as the 4π/100 sr tiles they were cut from:
/// with the default preset's 1e-7, every exact-view BRF of the LAI 3 layer stays within 0.1 % of
/// the same run with the threshold at 1e-13 (nothing dropped). Measured: 0.0011 % worst (the
/// threshold applied to every ray alike, without the ΔΩ factor, gave 0.77 % here and 2.48 %
/// instead of 1.61 % against DISORT at 0.2 m cells).
#[test]
fn ray_threshold_scales_with_the_solid_angle_of_the_ray() {
    let base = layer(
        3.0,
        20.0,
        0.25,
        vec![BandOptics::red(), BandOptics::nir()],
        LadDesc::Spherical,
    );
    let with = |thr: Option<f64>| {
        let mut d = base.clone();
        let mut r = d.radiative.clone().unwrap_or_default();
        r.ray_threshold = thr;
        d.radiative = Some(r);
        run(&d, Some(Preset::Default))
    };
    let dflt = with(None);
    let exact = with(Some(1e-13));
    assert_closes(&dflt, 1e-9, "default threshold");
    let mut worst: f64 = 0.0;
    let mut n = 0;
    for b in 0..2 {
        for (e, x) in dflt.bands[b].brf.iter().zip(&exact.bands[b].brf) {
            assert_eq!(e.zenith_deg, x.zenith_deg);
            if e.kind != "exact" {
                continue;
            }
            n += 1;
            worst = worst.max((e.brf / x.brf - 1.0).abs());
        }
    }
    assert!(n >= 20, "{n} exact views");
    eprintln!(
        "default vs no ray threshold, exact views: worst {:.4} %",
        100.0 * worst
    );
    assert!(
        worst < 1e-3,
        "exact-view BRFs moved {:.3} % by the ray threshold",
        100.0 * worst
    );
}

/// Radiative transfer has no length scale of its own: scaling every length of a scene by `s`
/// while keeping its optical depths (LAI fixed, so u_f ∝ 1/s) and its reflectances leaves
/// every BRF, albedo, absorbed and transmitted fraction unchanged. Millimetre and ten-kilometre
/// scenes check that no absolute epsilon, threshold or launch spacing hides in the tracker (DDA,
/// facet hits in cell faces, facet offsets, empty-space skipping, sub-cells, ray-power threshold).
/// - Power-of-two scales (2⁻¹⁰ ≈ 1 mm, 2¹³ ≈ 8 km) scale every length exactly, so any
///   difference beyond summation rounding comes from an absolute length in the code: 1e-9
///   relative. The building has walls in cell faces and edges on sub-cell boundaries (this test
///   found a fixed 1e-12 m facet-hit slack that lost wall hits at 8 km).
/// - Decimal scales (1e-3, 1e4) round every length, which may flip knife-edge decisions of the
///   discretisation: a ray whose power sits at the ray-stopping threshold, a hit exactly on a
///   sub-cell boundary (measured: 3e-8 on the turbid layer; 2.6e-3 in grazing BRFs when the
///   building's edges lie on sub-cell boundaries, which is why that building is moved off them
///   here). Tolerance 1e-6 relative, 30× the measured 3.5e-8.
#[test]
fn huge_and_tiny_scenes_give_the_products_of_the_metre_scene() {
    fn turbid(s: f64) -> SceneDesc {
        let mut d = turbid_layer(&TurbidLayerParams {
            lai: 3.0,
            lad: LadDesc::Spherical,
            bands: vec![BandOptics::red(), BandOptics::nir()],
            height_m: 2.0 * s,
            cell_m: 0.5 * s,
            size_m: 1.0 * s,
            sun_zenith_deg: 30.0,
            sun_azimuth_deg: 0.0,
        });
        no_hotspot(&mut d);
        d
    }
    /// A building on 1 m cells; `on_faces`: its walls in cell faces and its edges on sub-cell
    /// boundaries.
    fn urban(s: f64, on_faces: bool) -> SceneDesc {
        let mut d = base_scene((6.0 * s, 6.0 * s), (s, s, s), BoundaryMode::Repetitive);
        d.objects.push(flat_ground());
        d.optics.insert("wall".into(), lambertian(0.3));
        let (b, h) = if on_faces {
            ((1.0, 1.5, 3.5, 4.0), 2.5)
        } else {
            ((1.1, 1.3, 3.7, 4.1), 2.3)
        };
        d.objects
            .push(box_building((b.0 * s, b.1 * s, b.2 * s, b.3 * s), h * s));
        d.grid.height_m = Some(4.0 * s);
        d
    }
    let exact = [2f64.powi(-10), 2f64.powi(13)];
    let decimal = [1e-3, 1e4];
    let cases: [(&str, &dyn Fn(f64) -> SceneDesc, &[f64]); 3] = [
        (
            "turbid layer",
            &turbid,
            &[exact[0], exact[1], decimal[0], decimal[1]],
        ),
        ("building in faces", &|s| urban(s, true), &exact),
        (
            "building off faces",
            &|s| urban(s, false),
            &[exact[0], exact[1], decimal[0], decimal[1]],
        ),
    ];
    for (what, make, scales) in cases {
        let p1 = run(&make(1.0), None);
        assert_closes(&p1, 1e-9, what);
        for &s in scales {
            let tol = if s.log2().fract() == 0.0 { 1e-9 } else { 1e-6 };
            let p = run(&make(s), None);
            assert_closes(&p, 1e-9, &format!("{what} ×{s}"));
            assert_same_products(&p1, &p, tol, &format!("{what} ×{s} against 1 m"));
        }
    }
}
