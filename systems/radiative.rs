//! Radiative stage (DART 5 paper §3): discrete-ordinate flux tracking of sun and sky radiation
//! through the Maket grid ([`crate::radiative::engine`]).
//!
//! Reads GridSpec, CellGrid, FacetStore, Directions, OpticsTables, RadiativeSettings,
//! SceneInfo, Materials, TerrainRes, Ground; writes RadiativeProducts.

use crate::components::Ground;
use crate::phase::lambertian_facet_fractions;
use crate::radiative::engine::{
    RadiativeInput, ThermalSources, TrackOptics, remap_wrong_side, run,
};
use crate::radiative::products::RadiativeProducts;
use crate::resources::facets::{FacetKind, FacetStore};
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
    let lit = thermal_run
        .as_deref()
        .filter(|t| !t.desc.sunlit_temperatures_k.is_empty())
        .map(|_| {
            let mut params = settings.tracking.clone();
            params.max_iterations = 1;
            params.progress = false;
            let inp = RadiativeInput {
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
                image_of: &[],
                image_oversampling: 1,
                flat_ground: flat_ground.clone(),
                ground_brdf: ground_brdf.clone(),
                sun: dirs.sun,
                e_dir: scene.e_dir.clone(),
                e_diff: vec![0.0; nb],
                params,
                emitters: &[],
                thermal: None,
            };
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

/// Step of [`track_flux`]: `ε B(T)` per turbid entry, facet and flat-ground column and band
/// (physics.md §7.1–7.2): B the band-averaged Planck radiance at the temperature of the
/// element's optics key (a material derived from a key, `key@objects[i]`, takes the key's),
/// ε Kirchhoff's `1 − ρ_L − τ_L` (turbid leaves), `1 − R − T_d` (Lambertian facets) or
/// `1 − ρ` (Lambertian ground); the thermal sky `B(T_sky)`. What lies in contact inside a
/// building does not emit (its rays would start in the ground or pass through the one-sided
/// shell from inside): floors (one-sided wall facets facing down), DEM facets whose centroid is
/// under a footprint, and a flat-ground column's share covered by footprints.
fn thermal_sources(
    run: &ThermalRun,
    info: &SceneInfo,
    mats: &Materials,
    (grid, facets, spec): (&CellGrid, &FacetStore, &GridSpec),
    flat_ground: Option<crate::resources::materials::MaterialId>,
    footprints: &[Vec<glam::DVec2>],
    lit: Option<&SunlitFractions>,
) -> Result<ThermalSources, String> {
    let nb = info.bands.len();
    let planck = |t: f64| -> Result<Vec<f64>, String> {
        info.band_responses
            .iter()
            .map(|r| {
                crate::physics::thermal::band_planck(r, t)
                    .map_err(|e| format!("{}: thermal: {e}", info.source.display()))
            })
            .collect()
    };
    // ε B per material and band (`None`: the material does not emit).
    let mut per_mat: Vec<Option<Vec<f64>>> = Vec::with_capacity(mats.list.len());
    let mut eps_mat: Vec<Option<Vec<f64>>> = Vec::with_capacity(mats.list.len());
    for m in &mats.list {
        let key = m.name.split('@').next().unwrap_or(&m.name);
        let eps: Option<Vec<f64>> = match &m.kind {
            MaterialKind::Turbid {
                reflectance,
                transmittance,
                ..
            }
            | MaterialKind::Leaf {
                reflectance,
                transmittance,
            } => Some(
                (0..nb)
                    .map(|b| 1.0 - reflectance[b] - transmittance.get(b).copied().unwrap_or(0.0))
                    .collect(),
            ),
            MaterialKind::Lambertian {
                reflectance,
                diffuse_transmittance,
                ..
            } => Some(
                (0..nb)
                    .map(|b| {
                        1.0 - reflectance[b] - diffuse_transmittance.get(b).copied().unwrap_or(0.0)
                    })
                    .collect(),
            ),
            // A flat ground with a BRDF: B(T), the tracker applies 1 − ρ_dh(Ω) per direction
            // (validation refuses BRDF facets in thermal runs).
            MaterialKind::Rpv(_) | MaterialKind::Hapke(_) => Some(vec![1.0; nb]),
        };
        eps_mat.push(eps.clone());
        per_mat.push(match (eps, run.desc.temperature_of(key)) {
            (Some(eps), Some(t)) => {
                let b = planck(t)?;
                Some((0..nb).map(|i| eps[i].max(0.0) * b[i]).collect())
            }
            _ => None,
        });
    }
    let need = |id: crate::resources::materials::MaterialId| -> Result<&Vec<f64>, String> {
        per_mat[id as usize].as_ref().ok_or_else(|| {
            let m = &mats.list[id as usize];
            format!(
                "{}: thermal.temperatures_k: no temperature for optics `{}` (mode {}), which an emitting element is made of",
                info.source.display(),
                m.name.split('@').next().unwrap_or(&m.name),
                run.mode.name()
            )
        })
    };
    let mut out = ThermalSources::default();
    out.turbid.reserve(grid.turbid.len() * nb);
    // ε B at an element's own temperature when its key's temperature follows illumination
    // (`sunlit_temperatures_k`), else its material's (`per_mat`).
    let mut at_f = LitPlanck::new(run, info, mats, &eps_mat);
    for (k, e) in grid.turbid.iter().enumerate() {
        match lit.and_then(|l| at_f.get(e.material, l.turbid[k])) {
            Some(v) => out.turbid.extend_from_slice(&v?),
            None => out.turbid.extend_from_slice(need(e.material)?),
        }
    }
    let under_building = |q: glam::DVec2| {
        footprints
            .iter()
            .any(|p| crate::geometry::polygon::contains(p, q))
    };
    out.facet.reserve(facets.facets.len() * nb);
    for f in &facets.facets {
        let n = (f.v[1] - f.v[0])
            .cross(f.v[2] - f.v[0])
            .normalize_or(glam::DVec3::Z);
        let c = (f.v[0] + f.v[1] + f.v[2]) / 3.0;
        let buried = match f.kind {
            FacetKind::Wall => !f.two_sided && n.z < -0.99,
            FacetKind::Ground => under_building(c.truncate()),
            _ => false,
        };
        if buried {
            out.facet.extend(std::iter::repeat_n(0.0, nb));
        } else {
            let i = out.facet.len() / nb.max(1);
            match lit.and_then(|l| at_f.get(f.material, l.facet[i])) {
                Some(v) => out.facet.extend_from_slice(&v?),
                None => out.facet.extend_from_slice(need(f.material)?),
            }
        }
    }
    if let Some(g) = flat_ground {
        let eb = need(g)?;
        let (dx, dy) = (spec.cell.x, spec.cell.y);
        for c in 0..spec.n[0] * spec.n[1] {
            let (i, j) = ((c % spec.n[0]) as f64, (c / spec.n[0]) as f64);
            let (x0, y0) = (spec.origin.x + i * dx, spec.origin.y + j * dy);
            let covered: f64 = footprints
                .iter()
                .map(|p| crate::geometry::polygon::rect_overlap_area(p, x0, y0, x0 + dx, y0 + dy))
                .sum::<f64>()
                / (dx * dy);
            let open = (1.0 - covered).clamp(0.0, 1.0);
            match lit.and_then(|l| at_f.get(g, l.ground[c])) {
                Some(v) => out.ground.extend(v?.iter().map(|v| v * open)),
                None => out.ground.extend(eb.iter().map(|v| v * open)),
            }
        }
    }
    if let Some(t) = run.desc.sky_temperature_k {
        out.sky = planck(t)?;
    }
    Ok(out)
}

/// The directly lit fraction of every element (for `sunlit_temperatures_k`), from a
/// launch-only pass of the sun (no sky, no scattering): per turbid entry the direct power it
/// intercepted over `E⊥ G(Ω_s) u V` (the mean transmittance of the direct beam over its
/// leaves), per facet over `E⊥ A |n·Ω_s| (1 − T_dir^{1/|μ|})` (its lit area share), per
/// flat-ground column over `E_h a`; clamped to [0, 1].
struct SunlitFractions {
    turbid: Vec<f64>,
    facet: Vec<f64>,
    ground: Vec<f64>,
}

/// Step of [`track_flux`]: [`SunlitFractions`] of the launch-only result `r` of `inp`.
fn sunlit_fractions(
    inp: &RadiativeInput,
    r: &crate::radiative::engine::RadiativeResult,
) -> SunlitFractions {
    let w = r.n_channels;
    // The first band the sun lights (the fractions are geometric: any band gives them).
    let b = inp.e_dir.iter().position(|&e| e > 0.0);
    let mu_s = (-inp.sun.z).max(1e-12);
    let spec = inp.spec;
    let frac = |x: f64, full: f64| {
        if full > 0.0 {
            (x / full).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let Some(b) = b else {
        return SunlitFractions {
            turbid: vec![0.0; inp.grid.turbid.len()],
            facet: vec![0.0; inp.facets.len()],
            ground: vec![0.0; spec.n[0] * spec.n[1]],
        };
    };
    let e_perp = inp.e_dir[b] / mu_s;
    let vol = spec.cell.x * spec.cell.y * spec.cell.z;
    let turbid = inp
        .grid
        .turbid
        .iter()
        .enumerate()
        .map(|(k, e)| {
            let g = match &inp.optics[e.material as usize] {
                TrackOptics::Turbid { g, .. } => g.last().copied().unwrap_or(0.5),
                _ => 0.0,
            };
            frac(
                r.intercepted_turbid[k * w + b],
                e_perp * g * e.density as f64 * vol,
            )
        })
        .collect();
    let facet = inp
        .facets
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let n2 = (f.v[1] - f.v[0]).cross(f.v[2] - f.v[0]);
            let mu = n2.normalize_or(glam::DVec3::Z).dot(inp.sun).abs();
            let open = match &inp.optics[f.material as usize] {
                TrackOptics::Lambert { t_dir, .. } => {
                    let t = t_dir.get(b).copied().unwrap_or(0.0);
                    if t > 0.0 {
                        1.0 - t.powf(1.0 / mu.max(1e-12))
                    } else {
                        1.0
                    }
                }
                _ => 1.0,
            };
            frac(
                r.intercepted_facet[i * w + b],
                e_perp * 0.5 * n2.length() * mu * open,
            )
        })
        .collect();
    let a = spec.cell.x * spec.cell.y;
    let ground = (0..spec.n[0] * spec.n[1])
        .map(|c| frac(r.intercepted_ground[c * w + b], inp.e_dir[b] * a))
        .collect();
    SunlitFractions {
        turbid,
        facet,
        ground,
    }
}

/// `ε B(T(f))` per band for materials whose key's temperature follows illumination, cached
/// per (material, f to 1e-4).
struct LitPlanck<'a> {
    run: &'a ThermalRun,
    info: &'a SceneInfo,
    mats: &'a Materials,
    eps: &'a [Option<Vec<f64>>],
    cache: HashMap<(u32, u32), Vec<f64>>,
}

impl<'a> LitPlanck<'a> {
    fn new(
        run: &'a ThermalRun,
        info: &'a SceneInfo,
        mats: &'a Materials,
        eps: &'a [Option<Vec<f64>>],
    ) -> Self {
        LitPlanck {
            run,
            info,
            mats,
            eps,
            cache: HashMap::new(),
        }
    }

    /// `ε B` of material `m` lit over fraction `f`; `Ok(None)` when its key's temperature does
    /// not follow illumination.
    fn get(&mut self, m: u32, f: f64) -> Option<Result<Vec<f64>, String>> {
        let mat = &self.mats.list[m as usize];
        let key = mat.name.split('@').next().unwrap_or(&mat.name);
        if !self.run.desc.sunlit_temperatures_k.contains_key(key) {
            return None;
        }
        let eps = self.eps[m as usize].as_ref()?;
        let q = (f.clamp(0.0, 1.0) * 1e4).round() as u32;
        if let Some(v) = self.cache.get(&(m, q)) {
            return Some(Ok(v.clone()));
        }
        let t = self.run.desc.temperature_at(key, q as f64 * 1e-4)?;
        let v: Result<Vec<f64>, String> = self
            .info
            .band_responses
            .iter()
            .zip(eps)
            .map(|(r, e)| {
                crate::physics::thermal::band_planck(r, t)
                    .map(|b| e.max(0.0) * b)
                    .map_err(|e| format!("{}: thermal: {e}", self.info.source.display()))
            })
            .collect();
        if let Ok(v) = &v {
            self.cache.insert((m, q), v.clone());
        }
        Some(v)
    }
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
