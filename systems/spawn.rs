//! The spawn step (ECS glue of the scene format): a validated [`SceneDesc`] becomes entities
//! and resources of a bevy `World`.
//!
//! External files (DEM rasters, meshes) are read here, trees of stands are placed (seeded), and
//! every object gets absolute coordinates (scene frame, metres, z = altitude). Maket then turns
//! the entities into the cell grid.

use crate::components::*;
use crate::geometry::crown::CrownGeom;
use crate::geometry::polygon::signed_area;
use crate::geometry::shapes::Roof;
use crate::geometry::terrain::Terrain;
use crate::random::{stream, uniform};
use crate::resources::materials::{Material, MaterialKind, Materials};
use crate::resources::scene::{SceneInfo, TerrainRes, Warnings};
use crate::scene::desc::*;
use crate::scene::error::SceneError;
use crate::scene::terrain_input::build_terrain;
use crate::scene::validate::{SceneSource, validate};
use bevy_ecs::prelude::*;
use glam::{DMat4, DVec3};
use std::f64::consts::PI;

/// Leaf area of a crown from its foliage description.
pub fn crown_geom(c: &CrownDesc, x: f64, y: f64, ground_z: f64) -> CrownGeom {
    let rx = c.radius_x_m;
    let ry = c.radius_y_m.unwrap_or(rx);
    let top_fraction = match c.shape {
        CrownShape::Trapezoid => c.top_radius_fraction.unwrap_or(1.0),
        CrownShape::Cylinder => 1.0,
        _ => 0.0,
    };
    let g = CrownGeom {
        shape: c.shape,
        center: (x, y),
        z_base: ground_z + c.base_height_m,
        height: c.height_m,
        radius: (rx, ry),
        top_fraction,
        vertical: c.vertical_profile.clone(),
        radial: c.radial_profile.clone(),
        u0: 1.0,
    };
    let leaf_area = match c.foliage {
        FoliageDesc::LeafArea(a) => a,
        FoliageDesc::Lai(l) => l * PI * rx * ry,
        // Mean density over the crown volume.
        FoliageDesc::LeafAreaDensity(u) => u * g.volume(),
    };
    g.with_leaf_area(leaf_area)
}

fn spawn_tree(
    world: &mut World,
    idx: u32,
    trunk: Option<&TrunkDesc>,
    crown: &CrownDesc,
    x: f64,
    y: f64,
    terrain: &Terrain,
    mats: &Materials,
) {
    let gz = terrain.height(x, y);
    let geom = crown_geom(crown, x, y, gz);
    let crown_c = TurbidCrown {
        geom,
        material: mats.id(&crown.optics).expect("validated"),
    };
    match trunk {
        Some(t) => {
            world.spawn((
                SourceObject(idx),
                crown_c,
                Trunk {
                    base: DVec3::new(x, y, gz),
                    height: t.height_m,
                    diameter: t.diameter_m,
                    sides: t.sides,
                    material: mats.id(&t.optics).expect("validated"),
                },
            ));
        }
        None => {
            world.spawn((SourceObject(idx), crown_c));
        }
    }
}

/// Random placement with a minimum spacing (dart throwing with a hash grid), per species
/// counts, seeded by (scene seed, object index); with `polygon`, only points inside it.
fn place_random(
    counts: &[usize],
    min_spacing: f64,
    region: (f64, f64, f64, f64),
    polygon: Option<&[glam::DVec2]>,
    periodic: Option<(f64, f64)>,
    seed: u64,
    idx: u32,
) -> Result<Vec<(usize, f64, f64)>, String> {
    let total: usize = counts.iter().sum();
    let mut rng = stream(seed, 1, idx as u64);
    let (x0, y0, x1, y1) = region;
    let cell = min_spacing.max(1e-9);
    let gx = (((x1 - x0) / cell).ceil() as usize).clamp(1, 4096);
    let gy = (((y1 - y0) / cell).ceil() as usize).clamp(1, 4096);
    let (cw, ch) = ((x1 - x0) / gx as f64, (y1 - y0) / gy as f64);
    let mut buckets: Vec<Vec<(f64, f64)>> = vec![Vec::new(); gx * gy];
    let mut out = Vec::with_capacity(total);
    let max_attempts = 1000 * total.max(1);
    let mut attempts = 0;
    for (sp, &n) in counts.iter().enumerate() {
        let mut placed = 0;
        while placed < n {
            attempts += 1;
            if attempts > max_attempts {
                return Err(format!(
                    "placed only {} of {total} trees with a minimum spacing of {} m after {max_attempts} attempts: reduce the counts or the spacing",
                    out.len(),
                    crate::scene::validate::num(min_spacing)
                ));
            }
            let x = x0 + (x1 - x0) * uniform(&mut rng);
            let y = y0 + (y1 - y0) * uniform(&mut rng);
            if polygon
                .is_some_and(|p| !crate::geometry::polygon::contains(p, glam::DVec2::new(x, y)))
            {
                continue;
            }
            let bi = (((x - x0) / cw) as usize).min(gx - 1);
            let bj = (((y - y0) / ch) as usize).min(gy - 1);
            // At most the whole bucket grid: a larger reach (a huge spacing) would only visit
            // the same buckets again (and loop for ~forever).
            let reach_i = ((min_spacing / cw).ceil() as i64).min(gx as i64);
            let reach_j = ((min_spacing / ch).ceil() as i64).min(gy as i64);
            let mut ok = true;
            'scan: for dj in -reach_j..=reach_j {
                for di in -reach_i..=reach_i {
                    let (mut ii, mut jj) = (bi as i64 + di, bj as i64 + dj);
                    if periodic.is_some() {
                        ii = ii.rem_euclid(gx as i64);
                        jj = jj.rem_euclid(gy as i64);
                    } else if ii < 0 || jj < 0 || ii >= gx as i64 || jj >= gy as i64 {
                        continue;
                    }
                    for &(px, py) in &buckets[ii as usize + gx * jj as usize] {
                        let (mut dx, mut dy) = ((px - x).abs(), (py - y).abs());
                        if let Some((sx, sy)) = periodic {
                            dx = dx.min(sx - dx);
                            dy = dy.min(sy - dy);
                        }
                        if dx * dx + dy * dy < min_spacing * min_spacing {
                            ok = false;
                            break 'scan;
                        }
                    }
                }
            }
            if ok {
                buckets[bi + gx * bj].push((x, y));
                out.push((sp, x, y));
                placed += 1;
            }
        }
    }
    Ok(out)
}

/// Leaf dimension (m) of a facet→turbid conversion, for the hotspot (DART `dimFoliar`): the
/// square root of the mean area per leaf, `√(Σ area / leaves)`. Leaves of a disk list are
/// `sides` triangles each; mesh leaves count one triangle each. 0 when there is no area.
pub fn leaf_dimension(tris: &[[DVec3; 3]], leaves: usize) -> f64 {
    let area: f64 = tris
        .iter()
        .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
        .sum();
    if leaves == 0 || !(area > 0.0) {
        return 0.0;
    }
    (area / leaves as f64).sqrt()
}

/// Area-weighted histogram of leaf inclinations (18 bins of 5°) of a set of triangles: the LAD
/// kept by the facet→turbid conversion (DART 5 paper §2, supportive tools).
pub fn inclination_histogram(tris: &[[DVec3; 3]]) -> Vec<f64> {
    let mut h = vec![0.0; 18];
    for t in tris {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        let a = 0.5 * n.length();
        if a <= 0.0 {
            continue;
        }
        let incl = (n.z.abs() / n.length()).clamp(0.0, 1.0).acos();
        let b = ((incl / (PI / 2.0) * 18.0) as usize).min(17);
        h[b] += a;
    }
    h
}

fn mesh_transform(m: &MeshDesc, is_gltf: bool, ground_z: f64) -> DMat4 {
    let y_up = m.y_up.unwrap_or(is_gltf);
    let axes = if y_up {
        crate::io::mesh::gltf_y_up_to_z_up()
    } else {
        DMat4::IDENTITY
    };
    DMat4::from_translation(DVec3::new(
        m.translation_m.0,
        m.translation_m.1,
        m.translation_m.2 + ground_z,
    )) * DMat4::from_rotation_z(m.rotation_z_deg.to_radians())
        * DMat4::from_scale(DVec3::splat(m.scale))
        * axes
}

/// A scene error of a referenced file or of an object's field, given the scene line of the
/// field (`field`: the object's path); an unreadable file is named with the scene line of its
/// `path`.
fn located(src: &SceneSource, field: &str, e: SceneError) -> SceneError {
    match e {
        SceneError::Invalid { at, field, message }
            if at.line_col.is_none() && at.file == src.path =>
        {
            SceneError::Invalid {
                at: src.at(&field),
                field,
                message,
            }
        }
        // A referenced file that cannot be read: name it, and the scene line that refers to it.
        SceneError::Io { path, source } => src.invalid(
            format!("{field}.path"),
            format!("{}: cannot read file: {source}", path.display()),
        ),
        other => other,
    }
}

/// Spawns a validated scene into `world` (resources `SceneInfo`, `Materials`, `TerrainRes`,
/// `Warnings`, and one or more entities per object).
pub fn spawn_scene(
    world: &mut World,
    desc: &SceneDesc,
    src: &SceneSource,
) -> Result<(), SceneError> {
    validate(desc, src)?;
    // Band responses (SRF files read here), then per-band optics (PROSPECT leaves integrated
    // over the responses) and the sun (date and place resolved to final angles).
    let responses = crate::scene::resolve::band_responses(desc, src)?;
    let mut mats = Materials::from_desc(&desc.optics, &desc.bands, &responses)
        .map_err(|e| src.invalid(e.field, e.message))?;
    let sun = crate::scene::resolve::illumination(desc, src)?;
    let mut warnings = Vec::new();
    let base_dir = src.base_dir();
    let size = desc.grid.size_m;
    let georef = match &desc.georeference {
        Some(g) => Some(
            crate::scene::georef::Georeference::from_desc(g)
                .map_err(|(f, m)| src.invalid(format!("georeference.{f}"), m))?,
        ),
        None => None,
    };
    // Terrain first: every object sits on it.
    let mut terrain = Terrain::Flat(0.0);
    for (i, o) in desc.objects.iter().enumerate() {
        if let ObjectDesc::Ground(g) = o {
            let field = format!("objects[{i}].topography");
            terrain = build_terrain(
                &g.topography,
                &base_dir,
                &src.path,
                &field,
                size,
                georef.as_ref(),
            )
            .map_err(|e| located(src, &field, e))?;
            world.spawn((
                SourceObject(i as u32),
                Ground {
                    optics: mats.id(&g.optics).expect("validated"),
                },
            ));
        }
    }
    let periodic = (desc.grid.boundary != BoundaryMode::Isolated).then_some(size);
    let ctx = SpawnCtx {
        desc,
        src,
        base_dir,
        size,
        terrain: &terrain,
        periodic,
    };
    for (i, o) in desc.objects.iter().enumerate() {
        let idx = i as u32;
        match o {
            ObjectDesc::Ground(_) => {}
            ObjectDesc::Tree(t) => spawn_tree(
                world,
                idx,
                t.trunk.as_ref(),
                &t.crown,
                t.position_m.0,
                t.position_m.1,
                &terrain,
                &mats,
            ),
            ObjectDesc::TreeStand(s) => spawn_stand(world, &ctx, i, s, &mats, desc.seed)?,
            ObjectDesc::TurbidPlot(p) => spawn_plot(world, idx, p, &mats),
            ObjectDesc::Building(b) => spawn_building(world, &ctx, idx, b, &mats),
            ObjectDesc::Water(w) => spawn_water(world, &ctx, idx, w, &mats),
            ObjectDesc::Leaves(l) => spawn_leaves(world, &ctx, idx, l, &mats),
            ObjectDesc::LeafList(l) => {
                spawn_leaf_list(world, &ctx, i, l, &mut mats, &mut warnings)?
            }
            ObjectDesc::Mesh(m) => spawn_mesh(world, &ctx, i, m, &mut mats, &mut warnings)?,
            ObjectDesc::LandCover(l) => {
                // The map's objects, spawned as the same objects written by hand.
                let field = format!("objects[{i}]");
                let objects = crate::scene::landcover::expand_land_cover(
                    l,
                    &ctx.base_dir,
                    &src.path,
                    &field,
                    georef.as_ref(),
                    size,
                    desc.grid.boundary == BoundaryMode::Isolated,
                )
                .map_err(|e| located(src, &field, e))?;
                for (k, o) in objects.iter().enumerate() {
                    match o {
                        // Each rectangle's stand draws from its own stream.
                        ObjectDesc::TreeStand(s) => {
                            let seed =
                                desc.seed ^ (k as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                            spawn_stand(world, &ctx, i, s, &mats, seed).map_err(|e| match e {
                                // A placement that does not fit: the class's entry is at fault.
                                SceneError::Invalid { message, .. } => {
                                    src.invalid(format!("objects[{i}].classes"), message)
                                }
                                other => other,
                            })?
                        }
                        ObjectDesc::TurbidPlot(p) => spawn_plot(world, idx, p, &mats),
                        ObjectDesc::Building(b) => spawn_building(world, &ctx, idx, b, &mats),
                        ObjectDesc::Water(w) => spawn_water(world, &ctx, idx, w, &mats),
                        _ => {
                            unreachable!("land-cover classes are plots, stands, water or buildings")
                        }
                    }
                }
            }
        }
    }
    let g = &desc.grid;
    world.insert_resource(SceneInfo {
        name: desc.name.clone(),
        source: src.path.clone(),
        seed: desc.seed,
        bands: crate::scene::resolve::bands_with_wavelengths(&desc.bands, &responses),
        band_responses: responses,
        illumination: sun.illumination,
        irradiance_distance_factor: sun.irradiance_distance_factor,
        solar_position: sun.solar_position,
        size,
        cell: g.cell_m,
        height: g.height_m,
        subcells: g.subcells,
        boundary: g.boundary,
        georeference: georef,
    });
    world.insert_resource(mats);
    if let Some(th) = desc.thermal.as_ref().filter(|t| t.mode.thermal()) {
        world.insert_resource(crate::resources::scene::ThermalRun {
            mode: th.mode,
            desc: th.clone(),
        });
    }
    world.insert_resource(crate::resources::tracking::DirectionRequest(
        desc.directions.clone().unwrap_or_default(),
    ));
    let preset = world
        .get_resource::<crate::resources::scene::RunSettings>()
        .and_then(|s| s.preset)
        .or(desc.radiative.as_ref().and_then(|r| r.preset))
        .unwrap_or_default();
    let mut radiative =
        crate::resources::tracking::RadiativeSettings::resolve(preset, desc.radiative.as_ref());
    if let Some(eta) = world
        .get_resource::<crate::resources::scene::RunSettings>()
        .and_then(|s| s.image_oversampling)
    {
        radiative.image_oversampling = eta.max(1);
    }
    if let Some(s) = world.get_resource::<crate::resources::scene::RunSettings>() {
        radiative.tracking.skip_empty = s.skip_empty;
        radiative.tracking.batch_walk = s.batch_walk;
        radiative.tracking.batch_f32 = s.batch_f32;
        radiative.tracking.chunk_rays = s.chunk_rays;
        radiative.tracking.kernel_isa = s.kernel_isa;
        radiative.tracking.progress = s.progress;
    }
    world.insert_resource(radiative);
    world.insert_resource(TerrainRes(terrain));
    // Model only what the scene needs: no passive solve for a LiDAR-only scene, LiDAR work
    // only with instruments.
    if !desc.runs_passive() {
        world.insert_resource(crate::resources::scene::SkipPassive);
    }
    // LiDAR work exists only with instruments.
    if let Some(l) = desc.lidars.as_ref().filter(|l| !l.is_empty()) {
        world.insert_resource(crate::resources::lidar::LidarInstruments(l.clone()));
    }
    // Atmosphere work exists only with an `atmosphere` section; only the Monte Carlo solver
    // tracks through it so far.
    if let Some(a) = &desc.atmosphere {
        let mc = world
            .get_resource::<crate::resources::scene::RunSettings>()
            .is_some_and(|s| s.solver.is_monte_carlo());
        if !mc && desc.runs_passive() {
            return Err(SceneError::NotSupported {
                at: src.at("atmosphere"),
                field: "atmosphere".into(),
                message: "flux tracking through the atmosphere is planned (issue #33); run with `--solver monte-carlo`".into(),
            });
        }
        world.insert_resource(crate::resources::atmosphere::Atmosphere {
            desc: a.clone(),
            toa_at: src.at("atmosphere.toa_altitude_km"),
        });
    }
    if let Some(s) = desc.sensors.as_ref().filter(|s| !s.is_empty()) {
        let mc = world
            .get_resource::<crate::resources::scene::RunSettings>()
            .is_some_and(|r| r.solver.is_monte_carlo());
        if !mc {
            warnings.push(format!(
                "{}: sensors: frame cameras are imaged by the Monte Carlo solver only \
                 (`--solver monte-carlo`); this run writes no sensor products",
                src.path.display()
            ));
        }
        world.insert_resource(crate::resources::sensors::SensorInstruments(s.clone()));
    }
    world.insert_resource(Warnings(warnings));
    Ok(())
}

/// What every object's spawn reads: the scene, its source (for errors with file and line), the
/// folder its file paths are relative to, the extent, the ground and the periodic extent.
struct SpawnCtx<'a> {
    desc: &'a SceneDesc,
    src: &'a SceneSource,
    base_dir: std::path::PathBuf,
    size: (f64, f64),
    terrain: &'a Terrain,
    periodic: Option<(f64, f64)>,
}

/// A turbid material made from the leaf optics `optics` for leaves converted to turbid (a leaf
/// list or mesh group with `as_turbid`): the LAD is the triangles' inclination histogram and the
/// leaf size their mean dimension (hotspot).
fn turbid_from_leaf(
    mats: &mut Materials,
    optics: &str,
    name: String,
    tris: &[[DVec3; 3]],
    leaves: usize,
) -> u32 {
    let (r, t) = match &mats.list[mats.id(optics).expect("validated") as usize].kind {
        MaterialKind::Leaf {
            reflectance,
            transmittance,
        } => (reflectance.clone(), transmittance.clone()),
        _ => unreachable!("validated as a leaf"),
    };
    mats.push(Material {
        name,
        kind: MaterialKind::Turbid {
            reflectance: r,
            transmittance: t,
            lad: LadDesc::Histogram {
                bins: inclination_histogram(tris),
            },
            leaf_size_m: leaf_dimension(tris, leaves),
            specular: None,
        },
    })
}

/// A tree stand: explicit positions or seeded random placement, one tree entity per position.
fn spawn_stand(
    world: &mut World,
    ctx: &SpawnCtx,
    i: usize,
    s: &TreeStandDesc,
    mats: &Materials,
    seed: u64,
) -> Result<(), SceneError> {
    let idx = i as u32;
    let list = match &s.placement {
        PlacementDesc::Explicit(l) => l.clone(),
        PlacementDesc::Random {
            counts,
            min_spacing_m,
            region_m,
            polygon_m,
        } => {
            let mut region = region_m.unwrap_or((0.0, 0.0, ctx.size.0, ctx.size.1));
            let poly: Option<Vec<glam::DVec2>> = polygon_m
                .as_ref()
                .map(|p| p.iter().map(|&(x, y)| glam::DVec2::new(x, y)).collect());
            if let Some(p) = &poly {
                // The polygon's bounding box within the region.
                let (x0, y0, x1, y1) = p.iter().fold(
                    (f64::MAX, f64::MAX, f64::MIN, f64::MIN),
                    |(a, b, c, d), v| (a.min(v.x), b.min(v.y), c.max(v.x), d.max(v.y)),
                );
                region = (
                    region.0.max(x0),
                    region.1.max(y0),
                    region.2.min(x1),
                    region.3.min(y1),
                );
            }
            let per = if region_m.is_none() && poly.is_none() {
                ctx.periodic
            } else {
                None
            };
            place_random(
                counts,
                *min_spacing_m,
                region,
                poly.as_deref(),
                per,
                seed,
                idx,
            )
            .map_err(|m| ctx.src.invalid(format!("objects[{i}].placement"), m))?
        }
    };
    for (sp, x, y) in list {
        let spd = &s.species[sp];
        spawn_tree(
            world,
            idx,
            spd.trunk.as_ref(),
            &spd.crown,
            x,
            y,
            ctx.terrain,
            mats,
        );
    }
    Ok(())
}

/// A turbid plot: its footprint polygon and leaf area density.
fn spawn_plot(world: &mut World, idx: u32, p: &TurbidPlotDesc, mats: &Materials) {
    let poly = footprint_polygon(&p.footprint);
    let area = signed_area(&poly);
    let thickness = p.top_m - p.bottom_m;
    let density = match p.foliage {
        FoliageDesc::LeafAreaDensity(u) => u,
        FoliageDesc::Lai(l) => l / thickness,
        FoliageDesc::LeafArea(a) => a / (area * thickness),
    };
    world.spawn((
        SourceObject(idx),
        TurbidPlot {
            footprint: poly,
            bottom: p.bottom_m,
            top: p.top_m,
            density,
            material: mats.id(&p.optics).expect("validated"),
        },
    ));
}

/// A building standing on the lowest ground point under its footprint.
fn spawn_building(world: &mut World, ctx: &SpawnCtx, idx: u32, b: &BuildingDesc, mats: &Materials) {
    let poly = footprint_polygon(&b.footprint);
    let base_z = poly
        .iter()
        .map(|v| ctx.terrain.height(v.x, v.y))
        .fold(f64::INFINITY, f64::min);
    world.spawn((
        SourceObject(idx),
        Building {
            footprint: poly,
            base_z,
            wall_height: b.wall_height_m,
            roof: match b.roof {
                RoofDesc::Flat => Roof::Flat,
                RoofDesc::Gable { ridge_height_m } => Roof::Gable(ridge_height_m),
            },
            wall_material: mats.id(&b.wall_optics).expect("validated"),
            roof_material: mats.id(&b.roof_optics).expect("validated"),
        },
    ));
}

/// A water surface, by default 1 cm above the highest ground point under its footprint.
fn spawn_water(world: &mut World, ctx: &SpawnCtx, idx: u32, w: &WaterDesc, mats: &Materials) {
    let poly = footprint_polygon(&w.footprint);
    let altitude = w.altitude_m.unwrap_or_else(|| {
        poly.iter()
            .map(|v| ctx.terrain.height(v.x, v.y))
            .fold(f64::NEG_INFINITY, f64::max)
            + 0.01
    });
    world.spawn((
        SourceObject(idx),
        WaterBody {
            footprint: poly,
            altitude,
            material: mats.id(&w.optics).expect("validated"),
        },
    ));
}

/// Inline disk leaves, as facets on the ground.
fn spawn_leaves(world: &mut World, ctx: &SpawnCtx, idx: u32, l: &LeavesDesc, mats: &Materials) {
    let material = mats.id(&l.optics).expect("validated");
    let mut tris = Vec::with_capacity(l.disks.len() * l.sides as usize);
    for d in &l.disks {
        let c = DVec3::new(d.0, d.1, d.2 + ctx.terrain.height(d.0, d.1));
        tris.extend(crate::geometry::shapes::disk_polygon(
            c,
            DVec3::new(d.3, d.4, d.5),
            l.radius_m,
            l.sides,
        ));
    }
    world.spawn((
        SourceObject(idx),
        ImportedMesh {
            path: "<inline leaves>".into(),
            parts: vec![MeshPart {
                name: "leaves".into(),
                triangles: tris,
                material,
                two_sided: l.two_sided,
                as_turbid: false,
            }],
        },
    ));
}

/// A RAMI leaf-list file: disk leaves as facets, or converted to a turbid material.
fn spawn_leaf_list(
    world: &mut World,
    ctx: &SpawnCtx,
    i: usize,
    l: &LeafListDesc,
    mats: &mut Materials,
    warnings: &mut Vec<String>,
) -> Result<(), SceneError> {
    let idx = i as u32;
    let path = ctx.base_dir.join(&l.path);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        ctx.src.invalid(
            format!("objects[{i}].path"),
            format!("{}: cannot read file: {e}", path.display()),
        )
    })?;
    let list = crate::io::leaf_list::parse_leaf_list(&text, &path)
        .map_err(|m| ctx.src.invalid(format!("objects[{i}].path"), m))?;
    if list.renormalised > 0 {
        warnings.push(format!(
            "{}: normalised {} leaf normals that were not of unit length",
            path.display(),
            list.renormalised
        ));
    }
    let t = DVec3::new(l.translation_m.0, l.translation_m.1, l.translation_m.2);
    let mut tris = Vec::with_capacity(list.leaves.len() * l.sides as usize);
    for leaf in &list.leaves {
        let mut c = leaf.center + t;
        if l.wrap {
            c.x = c.x.rem_euclid(ctx.size.0);
            c.y = c.y.rem_euclid(ctx.size.1);
        } else if ctx.desc.grid.boundary == BoundaryMode::Isolated
            && (c.x - leaf.radius < 0.0
                || c.y - leaf.radius < 0.0
                || c.x + leaf.radius > ctx.size.0
                || c.y + leaf.radius > ctx.size.1)
        {
            return Err(ctx.src.invalid(
                format!("objects[{i}].path"),
                format!(
                    "{}: a leaf at ({:.3}, {:.3}) lies outside the isolated scene",
                    path.display(),
                    c.x,
                    c.y
                ),
            ));
        }
        c.z += ctx.terrain.height(c.x, c.y);
        tris.extend(crate::geometry::shapes::disk_polygon(
            c,
            leaf.normal,
            leaf.radius,
            l.sides,
        ));
    }
    let material = if l.as_turbid {
        turbid_from_leaf(
            mats,
            &l.optics,
            format!("{}@objects[{i}]", l.optics),
            &tris,
            list.leaves.len(),
        )
    } else {
        mats.id(&l.optics).expect("validated")
    };
    world.spawn((
        SourceObject(idx),
        ImportedMesh {
            path,
            parts: vec![MeshPart {
                name: "leaves".into(),
                triangles: tris,
                material,
                two_sided: true,
                as_turbid: l.as_turbid,
            }],
        },
    ));
    Ok(())
}

/// An imported glTF/GLB/OBJ mesh: each group with its optics, as facets or turbid.
fn spawn_mesh(
    world: &mut World,
    ctx: &SpawnCtx,
    i: usize,
    m: &MeshDesc,
    mats: &mut Materials,
    warnings: &mut Vec<String>,
) -> Result<(), SceneError> {
    let idx = i as u32;
    let path = ctx.base_dir.join(&m.path);
    let mut mesh = crate::io::mesh::load_mesh(&path)
        .map_err(|e| ctx.src.invalid(format!("objects[{i}].path"), e.to_string()))?;
    for w in &mesh.warnings {
        warnings.push(format!("{}: {w}", path.display()));
    }
    if mesh.skipped_non_triangle > 0 {
        warnings.push(format!(
            "{}: skipped {} non-triangle primitives",
            path.display(),
            mesh.skipped_non_triangle
        ));
    }
    let rep = mesh.clean_triangles();
    if rep.removed_degenerate + rep.removed_non_finite > 0 {
        warnings.push(format!(
            "{}: skipped {} degenerate and {} non-finite triangles",
            path.display(),
            rep.removed_degenerate,
            rep.removed_non_finite
        ));
    }
    let is_gltf = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"));
    let gz = ctx.terrain.height(m.translation_m.0, m.translation_m.1);
    mesh.transform(mesh_transform(m, is_gltf, gz));
    let mut parts = Vec::new();
    for g in &mesh.groups {
        let Some(k) = m.groups.iter().position(|o| o.group == g.name) else {
            let names: Vec<&str> = mesh.groups.iter().map(|g| g.name.as_str()).collect();
            return Err(ctx.src.invalid(
                format!("objects[{i}].groups"),
                format!(
                    "mesh group `{}` of {} has no optics (groups in the file: {})",
                    g.name,
                    path.display(),
                    names.join(", ")
                ),
            ));
        };
        let go = &m.groups[k];
        if g.triangles.is_empty() {
            continue;
        }
        let material = if go.as_turbid {
            turbid_from_leaf(
                mats,
                &go.optics,
                format!("{}@objects[{i}]/{}", go.optics, g.name),
                &g.triangles,
                g.triangles.len(),
            )
        } else {
            mats.id(&go.optics).expect("validated")
        };
        parts.push(MeshPart {
            name: g.name.clone(),
            triangles: g.triangles.clone(),
            material,
            two_sided: go.two_sided,
            as_turbid: go.as_turbid,
        });
    }
    for (k, go) in m.groups.iter().enumerate() {
        if !mesh.groups.iter().any(|g| g.name == go.group) {
            return Err(ctx.src.invalid(
                format!("objects[{i}].groups[{k}].group"),
                format!("{} has no group `{}`", path.display(), go.group),
            ));
        }
    }
    if parts.is_empty() {
        return Err(ctx.src.invalid(
            format!("objects[{i}].path"),
            format!("{}: the mesh has no triangles", path.display()),
        ));
    }
    if ctx.desc.grid.boundary == BoundaryMode::Isolated {
        let (lo, hi) = parts
            .iter()
            .flat_map(|p| p.triangles.iter().flatten())
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            });
        if lo.x < 0.0 || lo.y < 0.0 || hi.x > ctx.size.0 || hi.y > ctx.size.1 {
            return Err(ctx.src.invalid(format!("objects[{i}].translation_m"), format!("the transformed mesh spans x [{:.3}, {:.3}], y [{:.3}, {:.3}] m, outside the isolated scene", lo.x, hi.x, lo.y, hi.y)));
        }
    }
    world.spawn((SourceObject(idx), ImportedMesh { path, parts }));
    Ok(())
}
