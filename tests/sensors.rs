//! Sensor stage (issue #35): frame cameras imaged by the Monte Carlo solver's peel-off
//! (next-event estimation to the pinhole, DART 5 paper §5 eq. 5; physics.md §8.1).
//!
//! References we did not write: a Lambertian ground of reflectance ρ has the reflectance factor
//! ρ in every direction, so every pixel of any camera looking at it reads ρ; a camera far away
//! with a narrow field of view sees the scene along one direction, so its image mean is the
//! orthographic BRF of that direction (here the peel-off BRF of the same run).

mod common;

use common::asset;
use lumenscape::photon::sensors::{SensorImage, SensorProducts};
use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::scene::{RunSettings, SamplerKind, Solver};
use lumenscape::scene::desc::*;
use lumenscape::scene::load_scene;
use lumenscape::simulation::Simulation;

fn mc(photons: u64) -> RunSettings {
    RunSettings {
        solver: Solver::MonteCarlo {
            photons,
            sampler: SamplerKind::Continuous,
        },
        ..Default::default()
    }
}

/// Runs `desc` with `settings`; the passive products and the camera images.
fn run(desc: &SceneDesc, settings: RunSettings) -> (RadiativeProducts, Vec<SensorImage>) {
    let mut sim =
        Simulation::from_desc(desc, &lumenscape::scene::SceneSource::generated(), settings)
            .unwrap_or_else(|e| panic!("{e}"));
    sim.run(None).unwrap_or_else(|e| panic!("{e}"));
    let cams = sim
        .get_resource::<SensorProducts>()
        .map(|s| s.0.clone())
        .unwrap_or_default();
    (sim.resource::<RadiativeProducts>().clone(), cams)
}

fn camera_flat() -> SceneDesc {
    load_scene(&asset("assets/scenes/camera_flat.ron"))
        .unwrap()
        .0
}

fn frame(c: &mut SceneDesc) -> &mut FrameCameraDesc {
    let InstrumentDesc::FrameCamera(f) = &mut c.sensors.as_mut().unwrap()[0].instrument;
    f
}

/// Largest |z| = |RF − ρ|/SE over the pixels, and the image mean's error and SE.
fn lambert_check(img: &SensorImage, rho: f64) -> (f64, f64, f64) {
    let rf = img.reflectance(0);
    let se = img.reflectance_se(0);
    let mut zmax = 0.0f64;
    for (r, s) in rf.iter().zip(&se) {
        assert!(*s > 0.0 && s.is_finite(), "pixel SE {s}");
        zmax = zmax.max((r - rho).abs() / s);
    }
    let (m, mse) = img.mean_reflectance(0);
    (zmax, m - rho, mse)
}

#[test]
fn nadir_camera_over_a_lambertian_ground_reads_its_reflectance_in_every_pixel() {
    // 64 × 64 pixels, 30° FOV, 100 m up (assets/scenes/camera_flat.ron); ρ = 0.3.
    // Per pixel ~1.6 % SE at 300 000 photons: with 4096 pixels and 64 batches (a t
    // distribution with 63 degrees of freedom), |z| ≤ 5 holds for all of them with
    // probability > 99 %; measured max |z| = 4.56 with this seed. The image mean to 4 SE and
    // 0.5 % of ρ.
    let (_, cams) = run(&camera_flat(), mc(300_000));
    let img = &cams[0];
    assert_eq!((img.camera.nx, img.camera.ny), (64, 64));
    let (zmax, err, mse) = lambert_check(img, 0.3);
    eprintln!("nadir: max |z| {zmax:.2}, mean error {err:.2e} ± {mse:.1e}");
    assert!(zmax <= 5.0, "max |z| {zmax}");
    assert!(
        err.abs() <= 4.0 * mse && err.abs() < 1.5e-3,
        "{err} ± {mse}"
    );
}

#[test]
fn oblique_camera_over_a_lambertian_ground_sees_its_periodic_copies() {
    // 45° view zenith, rolled 20°, 150 m from its target: the 30° × 30° view spans ~150 m of
    // ground across its far side, several 60 m tiles of the repetitive scene (each event is
    // peeled off from its periodic copies in view). Every pixel still reads ρ.
    let mut d = camera_flat();
    let f = frame(&mut d);
    f.position_m = (30.0 - 150.0 * 0.5f64.sqrt(), 30.0, 150.0 * 0.5f64.sqrt());
    f.attitude = AttitudeDesc::Angles {
        zenith_deg: 45.0,
        azimuth_deg: 180.0,
        roll_deg: 20.0,
    };
    f.pixels = (32, 24);
    let (_, cams) = run(&d, mc(150_000));
    let (zmax, err, mse) = lambert_check(&cams[0], 0.3);
    eprintln!("oblique: max |z| {zmax:.2}, mean error {err:.2e} ± {mse:.1e}");
    assert!(zmax <= 5.0, "max |z| {zmax}");
    assert!(err.abs() <= 4.0 * mse && err.abs() < 3e-3, "{err} ± {mse}");
}

#[test]
fn small_tiles_seen_many_times_are_sampled_without_bias() {
    // A 4 m repetitive tile under the nadir camera's 54 m footprint: ~200 periodic copies of
    // every event in view, of which a systematic sample of 16 is peeled off (weighted
    // n/16). Every pixel still reads ρ (16 × 16 pixels, 5 SE as above).
    let mut d = camera_flat();
    d.grid.size_m = (4.0, 4.0);
    d.grid.cell_m = (4.0, 4.0, 1.0);
    frame(&mut d).pixels = (16, 16);
    let (_, cams) = run(&d, mc(100_000));
    let (zmax, err, mse) = lambert_check(&cams[0], 0.3);
    eprintln!("small tile: max |z| {zmax:.2}, mean error {err:.2e} ± {mse:.1e}");
    assert!(zmax <= 5.0, "max |z| {zmax}");
    assert!(err.abs() <= 4.0 * mse && err.abs() < 3e-3, "{err} ± {mse}");
}

#[test]
fn isolated_scene_camera_sees_the_ground_inside_and_nothing_outside() {
    // The same ground as an isolated 60 m scene seen from 100 m with a 60° FOV (115 m across):
    // pixels over the scene read ρ, pixels beyond its edges see nothing (radiance 0).
    let mut d = camera_flat();
    d.grid.boundary = BoundaryMode::Isolated;
    let f = frame(&mut d);
    f.fov_deg = Some(60.0);
    f.pixels = (16, 16);
    let (_, cams) = run(&d, mc(100_000));
    let img = &cams[0];
    let (rf, se) = (img.reflectance(0), img.reflectance_se(0));
    let mut zmax = 0.0f64;
    for j in 0..16 {
        for i in 0..16 {
            // Pixel footprint on the ground: inside [0, 60]² or outside entirely.
            let cam = &img.camera;
            let (x0, x1, y0, y1) = cam.pixel_rect(i, j);
            let corners = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)].map(|(x, y)| {
                let d = cam.direction_of(x, y);
                cam.position + d * (-cam.position.z / d.z)
            });
            let inside =
                |p: &glam::DVec3| (0.0..=60.0).contains(&p.x) && (0.0..=60.0).contains(&p.y);
            let px = i + 16 * j;
            if corners.iter().all(inside) {
                zmax = zmax.max((rf[px] - 0.3).abs() / se[px]);
            } else if !corners.iter().any(inside) {
                assert_eq!(rf[px], 0.0, "pixel ({i}, {j}) outside the scene");
            }
        }
    }
    eprintln!("isolated: max |z| {zmax:.2}");
    assert!(zmax > 0.0 && zmax <= 5.0, "max |z| {zmax}");
}

#[test]
fn far_narrow_camera_reproduces_the_orthographic_brf_of_a_turbid_layer() {
    // The turbid layer (LAI 3, spherical LAD, hotspot leaf size 0.01 m, 2 m repetitive tile)
    // seen from 10 km along its exact view direction (30°, 0°) with a 0.02° FOV (~3.5 m of
    // canopy, 4 × 4 pixels): the image mean is the BRF of that direction. Both come from the
    // same photons, so they differ by much less than their SEs (measured −6.2e-4 relative, SE
    // 2.6e-3); asserted to 3 combined SE and 1 % relative.
    let mut d = load_scene(&asset("assets/scenes/turbid_layer.ron"))
        .unwrap()
        .0;
    let (zen, dist) = (30f64.to_radians(), 1e4);
    d.sensors = Some(vec![SensorDesc {
        name: "far".into(),
        bands: vec![],
        instrument: InstrumentDesc::FrameCamera(FrameCameraDesc {
            position_m: (1.0 + dist * zen.sin(), 1.0, 1.0 + dist * zen.cos()),
            attitude: AttitudeDesc::LookAt {
                target_m: (1.0, 1.0, 1.0),
                roll_deg: 0.0,
            },
            pixels: (4, 4),
            fov_deg: Some(0.02),
            focal_length_mm: None,
            pixel_pitch_um: None,
        }),
    }]);
    let (p, cams) = run(&d, mc(40_000));
    let e = p.bands[0]
        .brf
        .iter()
        .find(|e| (e.zenith_deg - 30.0).abs() < 1e-9 && e.azimuth_deg.abs() < 1e-9)
        .expect("the exact direction (30°, 0°)");
    let (brf, brf_se) = (e.brf, e.brf_se.unwrap());
    let (m, mse) = cams[0].mean_reflectance(0);
    let rel = (m - brf) / brf;
    eprintln!("far camera {m:.5} ± {mse:.1e} against BRF {brf:.5} ± {brf_se:.1e} ({rel:+.2e})");
    assert!(
        (m - brf).abs() <= 3.0 * (mse * mse + brf_se * brf_se).sqrt(),
        "{m} vs {brf}"
    );
    assert!(rel.abs() < 0.01, "{rel}");
}

#[test]
fn a_camera_changes_no_other_product_and_is_the_same_on_any_thread_count() {
    // The peel-off to the camera draws no random number and books nothing else: albedo, fabs,
    // ftran and every BRF are the same bits with and without it (energy bookkeeping
    // unchanged); batches are merged in order, so the image is the same on 1 or 2 threads.
    let d = camera_flat();
    let mut bare = d.clone();
    bare.sensors = None;
    let (p0, none) = run(&bare, mc(20_000));
    assert!(none.is_empty());
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| run(&d, mc(20_000)));
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap()
        .install(|| run(&d, mc(20_000)));
    common::assert_same_products(&p0, &one.0, 0.0, "with a camera");
    for (b0, b1) in p0.bands.iter().zip(&one.0.bands) {
        assert_eq!(b0.albedo_se, b1.albedo_se);
        assert_eq!(b0.fabs, b1.fabs);
    }
    assert_eq!(one.1[0].radiance, two.1[0].radiance);
    assert_eq!(one.1[0].radiance_se, two.1[0].radiance_se);
}

#[test]
fn a_roof_appears_where_the_pinhole_projection_puts_it() {
    // An isolated 20 m scene, black ground and walls, a white (ρ = 1) flat roof 8 m × 4 m at
    // 5 m, seen from 40 m straight above with a 40° FOV (40 × 40 pixels, ~1.3 m at the roof):
    // only the roof scatters, so a pixel whose footprint on the roof plane lies outside the
    // roof reads exactly 0, and one wholly inside it reads 1 (the roof's reflectance factor;
    // 5 SE). Both sets border the roof's edges, so its corners are placed to within a pixel
    // by the pinhole projection.
    let mut d = camera_flat();
    d.grid = GridDesc {
        size_m: (20.0, 20.0),
        cell_m: (1.0, 1.0, 1.0),
        height_m: Some(8.0),
        subcells: 2,
        boundary: BoundaryMode::Isolated,
    };
    d.optics.insert("soil".into(), common::lambertian(0.0));
    d.optics.insert("black".into(), common::lambertian(0.0));
    d.optics.insert("white".into(), common::lambertian(1.0));
    d.objects.push(ObjectDesc::Building(BuildingDesc {
        footprint: FootprintDesc::Box((6.0, 8.0, 14.0, 12.0)),
        wall_height_m: 5.0,
        roof: RoofDesc::Flat,
        wall_optics: "black".into(),
        roof_optics: "white".into(),
    }));
    let f = frame(&mut d);
    f.position_m = (10.0, 10.0, 40.0);
    f.attitude = AttitudeDesc::LookAt {
        target_m: (10.0, 10.0, 0.0),
        roll_deg: 0.0,
    };
    f.fov_deg = Some(40.0);
    f.pixels = (40, 40);
    let (_, cams) = run(&d, mc(100_000));
    let img = &cams[0];
    let cam = &img.camera;
    let (rf, se) = (img.reflectance(0), img.reflectance_se(0));
    let (mut inside, mut outside, mut zmax) = (0, 0, 0.0f64);
    for j in 0..40 {
        for i in 0..40 {
            let (x0, x1, y0, y1) = cam.pixel_rect(i, j);
            let on_roof = |x: f64, y: f64| {
                let d = cam.direction_of(x, y);
                cam.position + d * ((5.0 - cam.position.z) / d.z)
            };
            let (a, b) = (on_roof(x0, y0), on_roof(x1, y1));
            let (lo, hi) = (a.min(b), a.max(b));
            let px = i + 40 * j;
            if lo.x >= 6.0 && hi.x <= 14.0 && lo.y >= 8.0 && hi.y <= 12.0 {
                inside += 1;
                zmax = zmax.max((rf[px] - 1.0).abs() / se[px]);
            } else if hi.x <= 6.0 || lo.x >= 14.0 || hi.y <= 8.0 || lo.y >= 12.0 {
                outside += 1;
                assert_eq!(rf[px], 0.0, "pixel ({i}, {j}) off the roof");
            }
        }
    }
    eprintln!("roof: {inside} pixels inside (max |z| {zmax:.2}), {outside} outside");
    assert!(inside >= 50 && outside >= 1400, "{inside} {outside}");
    assert!(zmax <= 5.0, "max |z| {zmax}");
}

#[test]
fn hard_cases_a_camera_on_a_cell_corner_inside_a_canopy_and_pixels_above_the_horizon() {
    // Inside the turbid layer, on a cell corner (1, 1, 1): finite, non-negative pixels, some
    // light. Over the flat ground, 10 m up at an 80° view zenith with a 30° FOV: the rows above
    // the horizon see nothing (0), rows whose ground lies within 300 m read ρ (5 SE).
    let mut d = load_scene(&asset("assets/scenes/turbid_layer.ron"))
        .unwrap()
        .0;
    d.sensors = camera_flat().sensors;
    let f = frame(&mut d);
    f.position_m = (1.0, 1.0, 1.0);
    f.attitude = AttitudeDesc::LookAt {
        target_m: (1.0, 1.0, 0.0),
        roll_deg: 0.0,
    };
    f.pixels = (8, 8);
    f.fov_deg = Some(90.0);
    let (_, cams) = run(&d, mc(5_000));
    let rf = cams[0].reflectance(0);
    assert!(rf.iter().all(|x| x.is_finite() && *x >= 0.0), "{rf:?}");
    assert!(rf.iter().sum::<f64>() > 0.0);

    let mut d = camera_flat();
    let f = frame(&mut d);
    f.position_m = (30.0, 30.0, 10.0);
    f.attitude = AttitudeDesc::Angles {
        zenith_deg: 80.0,
        azimuth_deg: 270.0,
        roll_deg: 0.0,
    };
    f.pixels = (16, 16);
    let (_, cams) = run(&d, mc(100_000));
    let img = &cams[0];
    let (rf, se) = (img.reflectance(0), img.reflectance_se(0));
    let (mut sky, mut near, mut zmax) = (0, 0, 0.0f64);
    for j in 0..16 {
        for i in 0..16 {
            let cam = &img.camera;
            let (x0, x1, y0, y1) = cam.pixel_rect(i, j);
            let ds = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)].map(|(x, y)| cam.direction_of(x, y));
            let px = i + 16 * j;
            if ds.iter().all(|d| d.z >= 0.0) {
                sky += 1;
                assert_eq!(rf[px], 0.0, "pixel ({i}, {j}) above the horizon");
            } else if ds.iter().all(|d| d.z < 0.0 && 10.0 / -d.z < 300.0) {
                near += 1;
                zmax = zmax.max((rf[px] - 0.3).abs() / se[px]);
            }
        }
    }
    eprintln!("horizon: {sky} sky pixels, {near} near-ground pixels, max |z| {zmax:.2}");
    assert!(sky >= 16 && near >= 16, "{sky} {near}");
    assert!(zmax <= 5.0, "max |z| {zmax}");
}

#[test]
fn camera_products_on_disk_match_the_image_and_keep_its_orientation() {
    // `lumenscape run` of an isolated 60 m ground seen from (30, 45, 100) m with a 30° FOV:
    // the image's top rows look past y = 60 m (nothing there), its bottom rows at the ground.
    // The EXR (read back in map order: last row = top of the camera image) holds radiance,
    // reflectance and their SEs; the sidecar and summary.json carry the same mean.
    let text = std::fs::read_to_string(asset("assets/scenes/camera_flat.ron"))
        .unwrap()
        .replace("boundary: Repetitive", "boundary: Isolated")
        .replace("(30.0, 30.0, 100.0)", "(30.0, 45.0, 100.0)")
        .replace("(30.0, 30.0, 0.0)", "(30.0, 45.0, 0.0)")
        .replace("(64, 64)", "(16, 16)");
    let dir = std::env::temp_dir().join(format!("lumenscape-sensors-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("cam.ron");
    std::fs::write(&scene, text).unwrap();
    let out = dir.join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_lumenscape"))
        .args([
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .args(["--quiet", "--solver", "monte-carlo", "--photons", "20000"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (nx, ny, ch) =
        lumenscape::io::exr_out::read_exr_channels(&out.join("sensors/drone.exr")).unwrap();
    assert_eq!((nx, ny), (16, 16));
    let names: Vec<&str> = ch.iter().map(|c| c.0.as_str()).collect();
    for n in [
        "radiance.00_red",
        "radiance_se.00_red",
        "reflectance.00_red",
        "reflectance_se.00_red",
    ] {
        assert!(names.contains(&n), "{names:?}");
    }
    let rf = &ch.iter().find(|c| c.0 == "reflectance.00_red").unwrap().1;
    let row = |j: usize| {
        rf[nx * j..nx * (j + 1)]
            .iter()
            .map(|&x| x as f64)
            .sum::<f64>()
    };
    assert_eq!(
        row(ny - 1),
        0.0,
        "top of the camera image: beyond the scene"
    );
    assert!(row(0) > 0.0, "bottom of the camera image: the ground");
    let mean = rf.iter().map(|&x| x as f64).sum::<f64>() / (nx * ny) as f64;
    let read = |p: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join(p)).unwrap()).unwrap()
    };
    let side = read("sensors/drone.json");
    let summary = read("summary.json");
    let m_side = side["bands"][0]["mean_reflectance_factor"]
        .as_f64()
        .unwrap();
    let m_sum = summary["sensors"][0]["bands"][0]["mean_reflectance_factor"]
        .as_f64()
        .unwrap();
    assert_eq!(m_side, m_sum);
    assert!((mean - m_side).abs() < 1e-6, "{mean} {m_side}");
    assert_eq!(side["camera"]["pixels"], serde_json::json!([16, 16]));
    assert!(
        side["view_geometry"]["view_zenith_deg"]["max"]
            .as_f64()
            .unwrap()
            > 15.0
    );
    assert!(out.join("sensors/drone.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
