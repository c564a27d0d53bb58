//! Photon stage (DART 5 paper §4): forward Monte Carlo photon tracking of sun and sky
//! radiation through the Maket grid ([`crate::photon::engine`]), the passive Monte Carlo solver
//! chosen with `--solver monte-carlo`. Same products as the Radiative stage, with standard
//! errors.
//!
//! Reads GridSpec, CellGrid, FacetStore, Directions, OpticsTables (discrete samplers only),
//! RunSettings, SceneInfo, Materials, TerrainRes, Ground, TurbidCrown, TurbidPlot, ImportedMesh,
//! the Atmosphere when the scene has one (sun photons then start at its top and the products
//! gain the TOA block), SensorInstruments (optional) and ThermalRun (`T` and `R+T` modes:
//! a thermal run of emission photons, joined with the solar run in `R+T`, issue #34); writes
//! RadiativeProducts and, with sensors, SensorProducts.

use crate::components::{Ground, ImportedMesh, TurbidCrown, TurbidPlot};
use crate::photon::engine::{PhotonAtmosphere, PhotonInput, PhotonOptics, PhotonParams, run};
use crate::photon::material_optics::{LadCache, build_photon_optics};
use crate::photon::products::{join_thermal_products, photon_products, thermal_photon_products};
use crate::photon::sensors::{CameraSpec, sensor_products};
use crate::radiative::thermal::thermal_sources;
use crate::resources::facets::FacetStore;
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::materials::Materials;
use crate::resources::scene::{
    RunSettings, SceneInfo, Solver, StageErrors, TerrainRes, ThermalRun,
};
use crate::resources::sensors::SensorInstruments;
use crate::resources::tracking::{Directions, OpticsTables};
use crate::scene::desc::InstrumentDesc;
use crate::systems::{TrackingScene, tracking_scene, used_turbid};
use bevy_ecs::prelude::*;

/// The LAD-derived photon optics shared by the passive Monte Carlo solver and every LiDAR
/// instrument of the Photon stage ([`LadCache`]). Inserted empty by
/// [`crate::simulation::Simulation`].
#[derive(Default, Resource)]
pub struct LadOpticsCache(pub LadCache);

/// Photon · reads the Maket grid, directions, materials and illumination · writes
/// RadiativeProducts.
#[allow(clippy::too_many_arguments)]
pub fn track_photons(
    info: Res<SceneInfo>,
    spec: Res<GridSpec>,
    grid: Res<CellGrid>,
    facets: Res<FacetStore>,
    dirs: Res<Directions>,
    tables: Option<Res<OpticsTables>>,
    settings: Res<RunSettings>,
    mats: Res<Materials>,
    terrain: Res<TerrainRes>,
    grounds: Query<&Ground>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    mut errors: ResMut<StageErrors>,
    (mut cache, atmosphere): (
        ResMut<LadOpticsCache>,
        Option<Res<crate::resources::atmosphere::Atmosphere>>,
    ),
    (sensors, thermal_run, buildings, mut commands): (
        Option<Res<SensorInstruments>>,
        Option<Res<ThermalRun>>,
        Query<&crate::components::Building>,
        Commands,
    ),
) {
    let Solver::MonteCarlo { photons, sampler } = settings.solver else {
        return;
    };
    let nb = info.bands.len();
    let used = used_turbid(mats.list.len(), &crowns, &plots, &meshes);
    let optics =
        match build_photon_optics(&mats, &used, tables.as_deref(), sampler, nb, &mut cache.0) {
            Ok(o) => o,
            Err(e) => {
                errors.0.push(e);
                return;
            }
        };
    let scene = tracking_scene(&info, &spec, &terrain, grounds.iter().next(), &facets);
    let tiling = dirs.set.tiling();
    let view_dir: Vec<usize> = tiling
        .iter()
        .enumerate()
        .filter(|(_, d)| {
            matches!(d.kind, crate::direction::DirectionKind::Exact { .. }) && d.omega.z > 0.0
        })
        .map(|(j, _)| j)
        .collect();
    let params = PhotonParams {
        skip_empty: settings.skip_empty,
        ..PhotonParams::new(photons, info.seed, sampler)
    };
    let views: Vec<_> = view_dir.iter().map(|&j| tiling[j].omega).collect();
    // The atmosphere over the scene top, per band (absent: no atmosphere work).
    let atm = match atmosphere.as_deref() {
        Some(a) => {
            let wl: Vec<f64> = info.bands.iter().map(|b| b.wavelength_nm).collect();
            let model = a.desc.model(&wl, spec.top());
            if model.levels_m[model.n_layers()] <= spec.top() {
                errors.0.push(format!(
                    "{}: field `atmosphere.toa_altitude_km`: must lie above the scene top ({} m)",
                    a.toa_at,
                    spec.top()
                ));
                return;
            }
            let tau: Vec<f64> = (0..nb).map(|b| model.tau_total(b)).collect();
            Some((PhotonAtmosphere::new(&model, &views), tau))
        }
        None => None,
    };
    let cams = sensors
        .as_deref()
        .map(|s| camera_specs(s, &scene.band_names))
        .unwrap_or_default();
    // Thermal emission (issue #34): ε B(T) per element, as in flux tracking.
    let thermal = match thermal_run.as_deref() {
        Some(t) => {
            if atm.is_some() || !cams.is_empty() {
                errors.0.push(format!(
                    "{}: field `thermal.mode`: mode {} with the Monte Carlo solver runs without an atmosphere and sensors (not supported together yet)",
                    info.source.display(),
                    t.mode.name()
                ));
                return;
            }
            // Not in the Monte Carlo emission yet: a BRDF ground's directional emissivity and
            // illumination-driven temperatures (flux tracking has both).
            let brdf_ground = scene.flat_ground.is_some_and(|g| {
                matches!(
                    mats.list[g as usize].kind,
                    crate::resources::materials::MaterialKind::Rpv(_)
                        | crate::resources::materials::MaterialKind::Hapke(_)
                )
            });
            if brdf_ground || !t.desc.sunlit_temperatures_k.is_empty() {
                errors.0.push(format!(
                    "{}: field `thermal`: mode {} with the Monte Carlo solver does not model {} yet (flux tracking does)",
                    info.source.display(),
                    t.mode.name(),
                    if brdf_ground {
                        "the emission of an RPV/Hapke ground"
                    } else {
                        "`sunlit_temperatures_k`"
                    }
                ));
                return;
            }
            let footprints: Vec<_> = buildings.iter().map(|b| b.footprint.clone()).collect();
            match thermal_sources(
                t,
                &info,
                &mats,
                (&grid, &facets, &spec),
                scene.flat_ground,
                &footprints,
                None,
            ) {
                Ok(s) => Some(s),
                Err(e) => {
                    errors.0.push(e);
                    return;
                }
            }
        }
        None => None,
    };
    let solar = thermal_run.as_deref().is_none_or(|t| t.mode.solar());
    let thermal_products = thermal.as_ref().map(|th| {
        let input = PhotonInput {
            views: views.clone(),
            e_dir: vec![0.0; nb],
            e_diff: vec![0.0; nb],
            thermal: Some(th),
            ..photon_input(
                &spec,
                &grid,
                &facets,
                &dirs,
                &scene,
                &optics,
                params.clone(),
            )
        };
        let t0 = std::time::Instant::now();
        let raw = run(&input);
        let secs = t0.elapsed().as_secs_f64();
        thermal_photon_products(
            raw,
            &params,
            &dirs.set,
            &view_dir,
            &scene.band_names,
            &info.band_responses,
            scene.area_m2,
            &scene.ground_facet,
            secs,
        )
    });
    if !solar {
        if let Some(p) = thermal_products {
            commands.insert_resource(p);
        }
        return;
    }
    let input = PhotonInput {
        views,
        cameras: cams.iter().map(|c| c.camera.clone()).collect(),
        atmosphere: atm.as_ref().map(|a| &a.0),
        e_dir: scene.e_dir.clone(),
        e_diff: scene.e_diff.clone(),
        ..photon_input(
            &spec,
            &grid,
            &facets,
            &dirs,
            &scene,
            &optics,
            params.clone(),
        )
    };
    let t0 = std::time::Instant::now();
    let raw = run(&input);
    let secs = t0.elapsed().as_secs_f64();
    if !cams.is_empty() {
        commands.insert_resource(sensor_products(
            &raw,
            &cams,
            &scene.band_names,
            &scene.e_dir,
            &scene.e_diff,
        ));
    }
    let products = photon_products(
        raw,
        &params,
        &dirs.set,
        &view_dir,
        &scene.band_names,
        scene.area_m2,
        &scene.e_dir,
        &scene.e_diff,
        &scene.ground_facet,
        secs,
        atm.as_ref().map(|a| &a.1[..]),
    );
    commands.insert_resource(match thermal_products {
        // R+T: the solar run joined with the thermal one.
        Some(t) => join_thermal_products(
            products,
            t,
            &scene.e_dir,
            &scene.e_diff,
            &info.band_responses,
        ),
        None => products,
    });
}

/// The frame cameras of the scene's sensors, with the scene bands each records (all when its
/// `bands` is empty).
fn camera_specs(s: &SensorInstruments, band_names: &[String]) -> Vec<CameraSpec> {
    s.0.iter()
        .filter_map(|d| {
            let InstrumentDesc::FrameCamera(c) = &d.instrument;
            let bands = if d.bands.is_empty() {
                (0..band_names.len()).collect()
            } else {
                d.bands
                    .iter()
                    .filter_map(|b| band_names.iter().position(|n| n == b))
                    .collect()
            };
            Some(CameraSpec {
                name: d.name.clone(),
                bands,
                camera: c.model()?,
            })
        })
        .collect()
}

/// The photon engine's input over the scene's grid, facets, directions and ground, with
/// `optics` and `params`: no peel-off views and no sun or sky power (a LiDAR's input; the
/// passive solver adds its views and irradiances).
pub fn photon_input<'a>(
    spec: &'a GridSpec,
    grid: &'a CellGrid,
    facets: &'a FacetStore,
    dirs: &'a Directions,
    scene: &'a TrackingScene,
    optics: &'a [PhotonOptics],
    params: PhotonParams,
) -> PhotonInput<'a> {
    PhotonInput {
        spec,
        grid,
        facets: &facets.facets,
        ground_facet: &scene.ground_facet,
        dirs: &dirs.set,
        optics,
        fluid: None,
        atmosphere: None,
        flat_ground: scene.flat_ground,
        views: Vec::new(),
        cameras: Vec::new(),
        sun: dirs.sun,
        e_dir: vec![0.0],
        e_diff: vec![0.0],
        thermal: None,
        params,
    }
}

/// The Photon stage's systems, in order: the passive Monte Carlo solver, then the LiDARs (whose
/// photon counting and fusion read the passive radiance).
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub enum PhotonSystems {
    /// Passive Monte Carlo (`--solver monte-carlo`).
    Passive,
    /// LiDAR instruments ([`crate::systems::lidar`]).
    Lidar,
}

/// Adds the Photon stage's systems: the passive Monte Carlo solver when chosen, then every LiDAR.
pub fn add_systems(s: &mut Schedule) {
    s.configure_sets((PhotonSystems::Passive, PhotonSystems::Lidar).chain());
    s.add_systems((
        track_photons
            .in_set(PhotonSystems::Passive)
            .run_if(resource_exists::<Directions>)
            .run_if(resource_exists::<CellGrid>)
            .run_if(|s: Res<RunSettings>| s.solver.is_monte_carlo())
            .run_if(not(resource_exists::<crate::resources::scene::SkipPassive>))
            .run_if(crate::systems::no_stage_error),
        crate::systems::lidar::run_lidars
            .in_set(PhotonSystems::Lidar)
            .run_if(resource_exists::<crate::resources::lidar::LidarInstruments>)
            .run_if(resource_exists::<Directions>)
            .run_if(resource_exists::<CellGrid>)
            .run_if(crate::systems::no_stage_error),
    ));
}
