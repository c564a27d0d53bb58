//! Shared fixtures for the integration tests.
#![allow(dead_code)]

use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::*;
use lumenscape::simulation::{Simulation, Stage};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Path of a file under the crate root.
pub fn asset(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// Runs the scene's stages with `preset` (None: the scene's own) and returns the Radiative
/// products; any error panics with its message.
pub fn run_radiative(
    desc: &SceneDesc,
    preset: Option<Preset>,
) -> lumenscape::radiative::products::RadiativeProducts {
    let settings = RunSettings {
        preset,
        ..Default::default()
    };
    let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), settings)
        .unwrap_or_else(|e| panic!("{e}"));
    sim.run(None).unwrap_or_else(|e| panic!("{e}"));
    sim.resource::<lumenscape::radiative::products::RadiativeProducts>()
        .clone()
}

/// Rows of a CSV oracle under `assets/reference/`, header skipped, fields as strings.
fn oracle_rows(file: &str) -> Vec<Vec<String>> {
    std::fs::read_to_string(asset(&format!("assets/reference/{file}")))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(String::from).collect())
        .collect()
}

/// Rows of the DISORT turbid-canopy oracle (`assets/reference/turbid_canopy_disort.csv`, header
/// skipped), fields as strings: lai, band, sun zenith, view zenith, BRF, albedo, ….
pub fn disort_rows() -> Vec<Vec<String>> {
    oracle_rows("turbid_canopy_disort.csv")
}

/// Rows of the extended DISORT oracle (`assets/reference/turbid_canopy_disort_ext.csv`: LAI 1,
/// 3, 5; sun zenith 0, 20, 35, 50°), fields as in [`disort_rows`].
pub fn disort_ext_rows() -> Vec<Vec<String>> {
    oracle_rows("turbid_canopy_disort_ext.csv")
}

/// A one-band scene with leaf, turbid, soil and wall optics and no objects.
pub fn base_scene(size: (f64, f64), cell: (f64, f64, f64), boundary: BoundaryMode) -> SceneDesc {
    let mut optics = BTreeMap::new();
    optics.insert(
        "leaf".to_string(),
        OpticsDesc::BiLambertian {
            reflectance: vec![0.05],
            transmittance: vec![0.02],
        },
    );
    optics.insert(
        "veg".to_string(),
        OpticsDesc::Turbid {
            leaf: "leaf".into(),
            lad: LadDesc::Spherical,
            leaf_size_m: 0.01,
            specular: None,
        },
    );
    optics.insert(
        "soil".to_string(),
        OpticsDesc::Lambertian {
            reflectance: vec![0.1],
            diffuse_transmittance: vec![],
            direct_transmittance: vec![],
        },
    );
    SceneDesc {
        version: 1,
        name: "test".into(),
        seed: 5,
        grid: GridDesc {
            size_m: size,
            cell_m: cell,
            height_m: None,
            subcells: 2,
            boundary,
        },
        bands: vec![BandDesc {
            name: "red".into(),
            wavelength_nm: 670.0,
            fwhm_nm: 0.0,
            sensor_band: None,
            srf_file: None,
        }],
        optics,
        illumination: IlluminationDesc {
            sun_zenith_deg: Some(30.0),
            sun_azimuth_deg: Some(0.0),
            sun_position: None,
            skyl: vec![],
            irradiance_w_m2_um: vec![],
        },
        objects: vec![],
        atmosphere: None,
        sensors: None,
        lidars: None,
        directions: None,
        radiative: None,
        passive: None,
        georeference: None,
        thermal: None,
    }
}

/// Spawns and runs the Maket stage.
pub fn run_maket(desc: &SceneDesc) -> Simulation {
    let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), RunSettings::default())
        .expect("scene spawns");
    sim.run_stage(Stage::Maket).expect("maket runs");
    sim
}

/// A crown description.
pub fn crown(
    shape: CrownShape,
    rx: f64,
    ry: Option<f64>,
    h: f64,
    foliage: FoliageDesc,
) -> CrownDesc {
    CrownDesc {
        shape,
        base_height_m: 1.3,
        height_m: h,
        radius_x_m: rx,
        radius_y_m: ry,
        top_radius_fraction: (shape == CrownShape::Trapezoid).then_some(0.35),
        foliage,
        vertical_profile: vec![],
        radial_profile: vec![],
        optics: "veg".into(),
    }
}

/// A one-band Lambertian facet property.
pub fn lambertian(r: f64) -> OpticsDesc {
    OpticsDesc::Lambertian {
        reflectance: vec![r],
        diffuse_transmittance: vec![],
        direct_transmittance: vec![],
    }
}

/// A flat-roofed building on a box footprint with `wall` optics for walls and roof.
pub fn box_building(b: (f64, f64, f64, f64), wall_height_m: f64) -> ObjectDesc {
    ObjectDesc::Building(BuildingDesc {
        footprint: FootprintDesc::Box(b),
        wall_height_m,
        roof: RoofDesc::Flat,
        wall_optics: "wall".into(),
        roof_optics: "wall".into(),
    })
}

/// Flat ground with the `soil` property.
pub fn flat_ground() -> ObjectDesc {
    ObjectDesc::Ground(GroundDesc {
        optics: "soil".into(),
        topography: TopographyDesc::Flat,
    })
}

/// A 12 m periodic forest of four trees (two broadleaf, two conifers): the small shared scene
/// of the determinism and image tests.
pub fn small_forest() -> SceneDesc {
    use lumenscape::scene::generators::forest::{ForestParams, broadleaf, conifer, forest};
    forest(&ForestParams {
        size_m: 12.0,
        species: vec![broadleaf(2), conifer(2)],
        ..Default::default()
    })
}

/// Gap fraction of a scene's `Leaves` disks along its sun direction by brute force: random
/// rays from above against the true circular disks (3 × 4 periodic copies), independent of the
/// engine's grid, DDA and triangles. Returns (gap, its binomial standard error).
#[allow(dead_code)]
pub fn disk_canopy_gap_fraction(desc: &SceneDesc, n_rays: u32) -> (f64, f64) {
    use glam::DVec3;
    let leaves = desc
        .objects
        .iter()
        .find_map(|o| match o {
            ObjectDesc::Leaves(l) => Some(l.clone()),
            _ => None,
        })
        .expect("a Leaves object");
    let sza = desc.illumination.sun_zenith_deg.unwrap().to_radians();
    let saz = desc.illumination.sun_azimuth_deg.unwrap().to_radians();
    let d = -DVec3::new(sza.sin() * saz.cos(), sza.sin() * saz.sin(), sza.cos());
    let (sx, sy) = desc.grid.size_m;
    let top = leaves.disks.iter().map(|k| k.2).fold(0.0, f64::max) + 0.2;
    let mut rng = lumenscape::random::stream(99, 1, 2);
    let mut miss = 0u32;
    for _ in 0..n_rays {
        let o = DVec3::new(
            lumenscape::random::uniform(&mut rng) * sx,
            lumenscape::random::uniform(&mut rng) * sy,
            top,
        );
        let blocked = leaves.disks.iter().any(|k| {
            let n = DVec3::new(k.3, k.4, k.5).normalize();
            (-3..=1).any(|ix| {
                (-1..=1).any(|iy| {
                    let c = DVec3::new(k.0 + ix as f64 * sx, k.1 + iy as f64 * sy, k.2);
                    let den = d.dot(n);
                    if den.abs() < 1e-12 {
                        return false;
                    }
                    let t = (c - o).dot(n) / den;
                    t > 0.0 && (o + d * t - c).length() <= leaves.radius_m
                })
            })
        });
        if !blocked {
            miss += 1;
        }
    }
    let gap = miss as f64 / n_rays as f64;
    (gap, (gap * (1.0 - gap) / n_rays as f64).sqrt())
}

/// The shipped disk canopy (assets/scenes/disk_canopy.ron) with black leaves.
pub fn black_disk_canopy() -> SceneDesc {
    let path = asset("assets/scenes/disk_canopy.ron");
    let (mut desc, _) = lumenscape::scene::load_scene(&path).unwrap();
    for o in desc.optics.values_mut() {
        if let OpticsDesc::BiLambertian {
            reflectance,
            transmittance,
        } = o
        {
            reflectance.iter_mut().for_each(|x| *x = 0.0);
            transmittance.iter_mut().for_each(|x| *x = 0.0);
        }
    }
    desc
}

/// Sets the leaf size of every turbid material to 0 (no hotspot): the scene is then the pure
/// turbid medium of point scatterers that DISORT and the single-scattering closed forms solve
/// (physics.md §3.4, §13 tests 3–4; the hotspot has its own oracles in radiative_hotspot.rs).
pub fn no_hotspot(d: &mut SceneDesc) {
    for o in d.optics.values_mut() {
        if let OpticsDesc::Turbid { leaf_size_m, .. } = o {
            *leaf_size_m = 0.0;
        }
    }
}

/// Asserts that `p` has the products of the reference run `p1` (albedo, fabs, ftran and every
/// BRF of every band) to `tol` relative (floor 1e-12 absolute on values near 0).
#[allow(dead_code)]
pub fn assert_same_products(
    p1: &lumenscape::radiative::products::RadiativeProducts,
    p: &lumenscape::radiative::products::RadiativeProducts,
    tol: f64,
    what: &str,
) {
    let close = |a: f64, b: f64| (a - b).abs() <= tol * a.abs().max(b.abs()).max(1e-12);
    assert_eq!(p1.bands.len(), p.bands.len(), "{what}: band count");
    for (b1, b) in p1.bands.iter().zip(&p.bands) {
        for (name, x1, x) in [
            ("albedo", b1.albedo, b.albedo),
            ("fabs", b1.fabs, b.fabs),
            ("ftran", b1.ftran, b.ftran),
        ] {
            assert!(
                close(x1, x),
                "{what} band {}: {name} {x} against {x1} (tolerance {tol:e})",
                b.band
            );
        }
        assert_eq!(b1.brf.len(), b.brf.len(), "{what}: BRF count");
        for (e1, e) in b1.brf.iter().zip(&b.brf) {
            assert!(
                close(e1.brf, e.brf),
                "{what} band {}: BRF {} against {} (view {}°, {}°; tolerance {tol:e})",
                b.band,
                e.brf,
                e1.brf,
                e.zenith_deg,
                e.azimuth_deg
            );
        }
    }
}

/// A nadir airborne LiDAR in band `red` (0.3 m footprint, 1 J Gaussian pulses of 2 ns, 1 ns
/// bins, discrete sampler, Gaussian decomposition) at `altitude_m` above the lowest ground.
pub fn lidar(name: &str, altitude_m: f64, pulses: PulsePattern, photons: u32) -> LidarDesc {
    LidarDesc {
        name: name.into(),
        band: "red".into(),
        platform: LidarPlatform::Airborne {
            altitude_m,
            view_zenith_deg: 0.0,
            view_azimuth_deg: 0.0,
            pulses,
        },
        footprint_radius_m: Some(0.3),
        divergence_mrad: None,
        edge_intensity: 0.368,
        fov_radius_m: None,
        pulse_energy_j: 1.0,
        pulse_fwhm_ns: 2.0,
        aperture_m2: 0.1,
        bin_ns: 1.0,
        photons_per_pulse: Some(photons),
        max_order: 100,
        gate_margin_m: 10.0,
        photon_counting: None,
        beam: None,
        returns: lumenscape::lidar::returns::ReturnsMethod::GaussianDecomposition,
        sampler: LidarSampler::Discrete,
        estimator: Default::default(),
        scattering_photons_per_pulse: None,
        fusion: false,
    }
}

/// Thermal band of the thermal tests, nm (10 µm, monochromatic).
pub const TIR_NM: f64 = 10_000.0;

/// A turbid layer (spherical LAD, no hotspot) of leaf area index `lai` over a Lambertian soil
/// in one monochromatic thermal band ([`TIR_NM`]), leaf `(r, t)`, soil reflectance `soil`,
/// cells of `cell` m, with the exact views `(zenith, azimuth)` (degrees) added to the
/// generator's.
pub fn tir_layer(
    lai: f64,
    leaf: (f64, f64),
    soil: f64,
    cell: f64,
    views: &[(f64, f64)],
) -> SceneDesc {
    use lumenscape::scene::generators::BandOptics;
    use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
    let mut d = turbid_layer(&TurbidLayerParams {
        lai,
        bands: vec![BandOptics {
            name: "tir".into(),
            wavelength_nm: TIR_NM,
            leaf_r: leaf.0,
            leaf_t: leaf.1,
            soil_r: soil,
        }],
        cell_m: cell,
        ..Default::default()
    });
    no_hotspot(&mut d);
    let dirs = d.directions.as_mut().expect("generator directions");
    for &(z, a) in views {
        dirs.exact.push(lumenscape::direction::ExactDirection {
            zenith_deg: z,
            azimuth_deg: a,
            label: None,
            solid_angle_sr: None,
        });
    }
    d
}

/// A `thermal` section: mode, default temperature, per-key temperatures, sky temperature.
pub fn thermal_section(
    mode: RunMode,
    default_k: Option<f64>,
    per_key: &[(&str, f64)],
    sky_k: Option<f64>,
) -> ThermalDesc {
    ThermalDesc {
        mode,
        temperatures_k: per_key
            .iter()
            .map(|(k, t)| (k.to_string(), *t))
            .collect::<BTreeMap<_, _>>(),
        sunlit_temperatures_k: Default::default(),
        default_temperature_k: default_k,
        sky_temperature_k: sky_k,
    }
}

/// The example disc canopy (`assets/scenes/disk_canopy.ron`) in the thermal band ([`TIR_NM`])
/// with thermal-infrared optics: leaves r 0.02, t 0.01; soil 0.05.
pub fn tir_disk_canopy() -> SceneDesc {
    let (mut d, _) =
        lumenscape::scene::load_scene(&asset("assets/scenes/disk_canopy.ron")).unwrap();
    d.bands[0].wavelength_nm = TIR_NM;
    for (k, o) in d.optics.iter_mut() {
        match o {
            OpticsDesc::BiLambertian {
                reflectance,
                transmittance,
            } => {
                *reflectance = vec![0.02];
                *transmittance = vec![0.01];
            }
            OpticsDesc::Lambertian { reflectance, .. } => *reflectance = vec![0.05],
            _ => assert_eq!(k, "vegetation"),
        }
    }
    d
}
