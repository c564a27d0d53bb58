//! Radiative stage (DART 5 paper §3): discrete-ordinate flux tracking of sun and sky radiation
//! through the Maket grid ([`crate::radiative::engine`]).
//!
//! Reads GridSpec, CellGrid, FacetStore, Directions, OpticsTables, RadiativeSettings,
//! SceneInfo, Materials, TerrainRes, Ground; writes RadiativeProducts.

use crate::components::Ground;
use crate::phase::lambertian_facet_fractions;
use crate::radiative::engine::{RadiativeInput, TrackOptics, remap_wrong_side, run};
use crate::radiative::products::RadiativeProducts;
use crate::radiative::thermal::{sunlit_fractions, thermal_sources};
use crate::resources::facets::FacetStore;
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::materials::{MaterialKind, Materials};
use crate::resources::scene::{SceneInfo, StageErrors, TerrainRes, ThermalRun};
use crate::resources::tracking::{Directions, OpticsTables, RadiativeSettings};
use crate::systems::tracking_scene;
use bevy_ecs::prelude::*;
use rayon::prelude::*;
use std::collections::HashMap;

use crate::radiative::EXACT_FRACTIONS_LIMIT;

/// Image index of each tiling direction (`u32::MAX`: none), for the Output stage.
#[derive(Debug, Clone, Resource)]
pub struct ImageDirections(pub Vec<u32>);

/// Radiative · reads the Maket grid, directions, tables and illumination · writes
/// RadiativeProducts.
#[allow(clippy::too_many_arguments)]
pub fn track_flux(
    info: Res<SceneInfo>,
    spec: Res<GridSpec>,
    grid: Res<CellGrid>,
    facets: Res<FacetStore>,
    dirs: Res<Directions>,
    tables: Res<OpticsTables>,
    settings: Res<RadiativeSettings>,
    mats: Res<Materials>,
    terrain: Res<TerrainRes>,
    grounds: Query<&Ground>,
    (thermal_run, buildings): (Option<Res<ThermalRun>>, Query<&crate::components::Building>),
    mut errors: ResMut<StageErrors>,
    mut commands: Commands,
) {
    let nb = info.bands.len();
    // RPV / Hapke facets (DEM, roofs, meshes): one table set (per band) per material and facet
    // normal, normals quantised to 1/64 per component (≤ 0.9°) so a DEM shares tables.
    let (facet_brdf, facet_tables) =
        match brdf_facet_tables(&facets.facets, &mats, &dirs, &settings, nb) {
            Ok(t) => t,
            Err(e) => {
                errors.0.push(e);
                return;
            }
        };
    let scene = tracking_scene(&info, &spec, &terrain, grounds.iter().next(), &facets);
    let flat_ground = scene
        .flat_ground
        .map(|g| match &mats.list[g as usize].kind {
            MaterialKind::Lambertian { reflectance, .. }
            | MaterialKind::Leaf { reflectance, .. } => reflectance.clone(),
            _ => vec![0.0; nb],
        });
    let ground_brdf = match ground_brdf_tables(scene.flat_ground, &mats, &dirs, &settings, nb) {
        Ok(t) => t,
        Err(e) => {
            errors.0.push(e);
            return;
        }
    };
    let fractions = exact_facet_fractions(&facets, &dirs);
    let optics: Vec<TrackOptics> = tables.optics.clone();
    // Thermal emission (issue #34): ε B(T) per element; a `T` run has no sun and solar sky.
    // Illumination-driven temperatures need each element's directly lit fraction first: a
    // launch-only pass of the sun.
    let image_of = image_indices(&dirs);
    let make_input = |e_dir: Vec<f64>, e_diff: Vec<f64>, thermal| RadiativeInput {
        spec: &spec,
        grid: &grid,
        facets: &facets.facets,
        facet_fractions: &fractions,
        facet_brdf: &facet_brdf,
        facet_tables: &facet_tables,
        dirs: &dirs.set,
        sector_of: &dirs.sector_of,
        n_sectors: dirs.n_sectors,
        optics: &optics,
        image_of: &image_of,
        image_oversampling: settings.image_oversampling,
        flat_ground: flat_ground.clone(),
        ground_brdf: ground_brdf.clone(),
        sun: dirs.sun,
        e_dir,
        e_diff,
        params: settings.tracking.clone(),
        emitters: &[],
        thermal,
    };
    let lit = thermal_run
        .as_deref()
        .filter(|t| !t.desc.sunlit_temperatures_k.is_empty())
        .map(|_| {
            let mut inp = make_input(scene.e_dir.clone(), vec![0.0; nb], None);
            inp.params.max_iterations = 1;
            inp.params.progress = false;
            sunlit_fractions(&inp, &run(&inp))
        });
    let thermal = match thermal_run.as_deref() {
        Some(t) => match thermal_sources(
            t,
            &info,
            &mats,
            (&grid, &facets, &spec),
            scene.flat_ground,
            &buildings
                .iter()
                .map(|b| b.footprint.clone())
                .collect::<Vec<_>>(),
            lit.as_ref(),
        ) {
            Ok(s) => Some(s),
            Err(e) => {
                errors.0.push(e);
                return;
            }
        },
        None => None,
    };
    let solar = thermal_run.as_deref().is_none_or(|t| t.mode.solar());
    let (e_dir, e_diff) = if solar {
        (scene.e_dir.clone(), scene.e_diff.clone())
    } else {
        (vec![0.0; nb], vec![0.0; nb])
    };
    let t0 = std::time::Instant::now();
    let raw = match (thermal.as_ref(), solar) {
        // R+T: the solar run, then the thermal one (see `RadiativeResult::with_thermal_of`).
        (Some(th), true) => {
            let solar_run = run(&make_input(e_dir.clone(), e_diff.clone(), None));
            let thermal_run = run(&make_input(vec![0.0; nb], vec![0.0; nb], Some(th)));
            solar_run.with_thermal_of(thermal_run)
        }
        _ => run(&make_input(e_dir.clone(), e_diff.clone(), thermal.as_ref())),
    };
    let secs = t0.elapsed().as_secs_f64();
    commands.insert_resource(ImageDirections(image_of));
    let mut products = RadiativeProducts::new(
        raw,
        &dirs.set,
        &scene.band_names,
        scene.area_m2,
        &e_dir,
        &e_diff,
        &scene.ground_facet,
        secs,
    );
    if let Some(t) = thermal_run.as_deref() {
        // The mean terrain plane of a continuous-topography scene (its altitude offsets
        // between opposite sides), the reference of the radiances.
        let (ox, oy) = spec.topography_offset;
        let (sx, sy) = info.size;
        let normal = glam::DVec3::new(-ox / sx, -oy / sy, 1.0).normalize();
        products = products.with_thermal(
            t.mode,
            &dirs.set,
            &info.band_responses,
            scene.area_m2,
            normal,
        );
    }
    commands.insert_resource(products);
}

/// Step of [`track_flux`]: the RPV / Hapke tables of the flat ground (one facet table per band
/// for the horizontal normal); `None` for a Lambertian ground or no flat ground.
fn ground_brdf_tables(
    flat_ground: Option<crate::resources::materials::MaterialId>,
    mats: &Materials,
    dirs: &Directions,
    settings: &RadiativeSettings,
    nb: usize,
) -> Result<Option<Vec<crate::phase::PhaseTable>>, String> {
    let mut ground_brdf = None;
    if let Some(g) = flat_ground {
        let m = &mats.list[g as usize];
        let per_band = m.kind.brdf_models(nb);
        if let Some(models) = per_band {
            let mut tables_b = Vec::new();
            for model in &models {
                match crate::phase::brdf_facet_table(
                    &dirs.set,
                    model,
                    glam::DVec3::Z,
                    Some(dirs.sun),
                    &settings.tables,
                ) {
                    Ok(t) => tables_b.push(t),
                    Err(e) => return Err(format!("ground material `{}`: {e}", m.name)),
                }
            }
            ground_brdf = Some(tables_b);
        }
    }
    Ok(ground_brdf)
}

/// Step of [`track_flux`]: the exact Lambertian scattering fractions (front, back) per facet
/// and tiling direction, when the facets × directions stay within `EXACT_FRACTIONS_LIMIT`
/// (empty otherwise: the tracker falls back to renormalised cosines).
fn exact_facet_fractions(facets: &FacetStore, dirs: &Directions) -> Vec<(Vec<f32>, Vec<f32>)> {
    let n_dirs = dirs.set.tiling().len();
    let omega: Vec<glam::DVec3> = dirs.set.tiling().iter().map(|d| d.omega).collect();
    let regular: Vec<bool> = dirs
        .set
        .tiling()
        .iter()
        .map(|d| d.kind == crate::direction::DirectionKind::Regular)
        .collect();
    if facets.facets.len() * n_dirs <= EXACT_FRACTIONS_LIMIT {
        // One computation per distinct unit normal: a flat DEM's triangles, the sides of trunks
        // of one shape, a building's parallel walls and the triangles of one flat leaf (a disc
        // fan, a quad) share theirs, and the exact fractions (tanh–sinh quadrature per
        // straddling sector) were ~10 % of the forest bench's instructions and ~20 % of a disc
        // canopy's. Normals are the same when equal to 2⁻³² per component (the cross products
        // of one flat polygon's triangles differ by rounding only); the fractions, smooth in
        // the normal, then differ by ~1e-10, below the f32 they are stored in.
        let normals: Vec<glam::DVec3> = facets
            .facets
            .iter()
            .map(|f| {
                (f.v[1] - f.v[0])
                    .cross(f.v[2] - f.v[0])
                    .normalize_or(glam::DVec3::Z)
            })
            .collect();
        let mut slot_of: HashMap<[i64; 3], usize> = HashMap::new();
        let mut distinct: Vec<glam::DVec3> = Vec::new();
        let which: Vec<usize> = normals
            .iter()
            .map(|n| {
                *slot_of
                    .entry(n.to_array().map(|x| (x * 4_294_967_296.0).round() as i64))
                    .or_insert_with(|| {
                        distinct.push(*n);
                        distinct.len() - 1
                    })
            })
            .collect();
        let per_normal: Vec<(Vec<f32>, Vec<f32>)> = distinct
            .par_iter()
            .map(|&n| {
                let fr = lambertian_facet_fractions(&dirs.set, n);
                let mut front: Vec<f32> = fr.front[..n_dirs].iter().map(|&x| x as f32).collect();
                let mut back: Vec<f32> = fr.back[..n_dirs].iter().map(|&x| x as f32).collect();
                remap_wrong_side(&mut front, n, &omega, &regular);
                remap_wrong_side(&mut back, -n, &omega, &regular);
                (front, back)
            })
            .collect();
        which.iter().map(|&i| per_normal[i].clone()).collect()
    } else {
        Vec::new()
    }
}

/// Step of [`track_flux`]: the image index of each tiling direction — orthographic images for
/// every exact upward direction (the view directions a scene asks for), `u32::MAX` otherwise.
fn image_indices(dirs: &Directions) -> Vec<u32> {
    let mut n_img = 0u32;
    dirs.set
        .tiling()
        .iter()
        .map(|d| {
            if matches!(d.kind, crate::direction::DirectionKind::Exact { .. }) && d.omega.z > 0.0 {
                n_img += 1;
                n_img - 1
            } else {
                u32::MAX
            }
        })
        .collect()
}

/// Table sets of the RPV/Hapke facets: `facet_brdf[f]` indexes `sets` (u32::MAX for other
/// facets); each set holds one [`brdf_facet_table`](crate::phase::brdf_facet_table)
/// per band for the facet's material and its normal quantised to 1/64 per component (≤ 0.9°:
/// far below the sector width of the direction sets), so facets with the same orientation share
/// one set.
#[allow(clippy::type_complexity)]
fn brdf_facet_tables(
    facets: &[crate::resources::facets::Facet],
    mats: &Materials,
    dirs: &Directions,
    settings: &RadiativeSettings,
    nb: usize,
) -> Result<(Vec<u32>, Vec<Vec<crate::phase::PhaseTable>>), String> {
    use std::collections::HashMap;
    let mut key_of: HashMap<(u32, [i32; 3]), u32> = HashMap::new();
    let mut keys: Vec<(u32, [i32; 3])> = Vec::new();
    let mut facet_brdf = vec![u32::MAX; facets.len()];
    for (i, f) in facets.iter().enumerate() {
        if mats.list[f.material as usize]
            .kind
            .brdf_models(nb)
            .is_none()
        {
            continue;
        }
        let n = (f.v[1] - f.v[0])
            .cross(f.v[2] - f.v[0])
            .normalize_or(glam::DVec3::Z);
        let q = [
            (n.x * 64.0).round() as i32,
            (n.y * 64.0).round() as i32,
            (n.z * 64.0).round() as i32,
        ];
        let k = (f.material, q);
        let id = *key_of.entry(k).or_insert_with(|| {
            keys.push(k);
            keys.len() as u32 - 1
        });
        facet_brdf[i] = id;
    }
    let sets: Result<Vec<_>, String> = keys
        .par_iter()
        .map(|(m, q)| {
            let mat = &mats.list[*m as usize];
            let n = glam::DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64)
                .normalize_or(glam::DVec3::Z);
            let models = mat.kind.brdf_models(nb).expect("BRDF material");
            models
                .iter()
                .map(|model| {
                    crate::phase::brdf_facet_table(
                        &dirs.set,
                        model,
                        n,
                        Some(dirs.sun),
                        &settings.tables,
                    )
                    .map_err(|e| format!("material `{}`: {e}", mat.name))
                })
                .collect()
        })
        .collect();
    Ok((facet_brdf, sets?))
}

/// The Radiative stage's systems.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub enum RadiativeSystems {
    /// Flux tracking (illumination, iterations, extrapolation, products).
    Track,
}

/// Adds the Radiative stage's systems: flux tracking runs when the flux-tracking solver is chosen,
/// the scene runs a passive solver and Maket and Phase produced their resources.
pub fn add_systems(s: &mut Schedule) {
    s.add_systems(
        track_flux
            .in_set(RadiativeSystems::Track)
            .run_if(resource_exists::<OpticsTables>)
            .run_if(resource_exists::<CellGrid>)
            .run_if(|s: Res<crate::resources::scene::RunSettings>| !s.solver.is_monte_carlo())
            .run_if(not(resource_exists::<crate::resources::scene::SkipPassive>))
            .run_if(crate::systems::no_stage_error),
    );
}
