//! Memory estimate per stage, made before anything big is allocated (`lumenscape check`,
//! `lumenscape run --max-memory`, `summary.json` key `memory`), and the measured peak resident
//! set of the process ([`peak_rss_bytes`]).
//!
//! Each stage's estimate is what is resident while it runs: the process baseline, what earlier
//! stages left for it (the Maket grid, facets and BVH; the passive solver's products), and its
//! own terms, each named and modelled from the scene's counts (cells, turbid entries, facet
//! references, directions, launch points, bands, images, photons, pulses) in the stage's own
//! module: [`crate::maket::plan`], [`crate::radiative::memory_terms`],
//! [`crate::photon::memory_terms`], [`crate::lidar::memory_terms`] and [`output_terms`] here.
//! The peak estimate is the largest stage estimate. docs/performance.md ("Memory") compares
//! it with the measured peak on every example scene.

use crate::resources::maket_report::MaketReport;
pub use crate::resources::memory::{
    BASELINE_BYTES, BASELINE_GROWTH_BYTES, BASELINE_GROWTH_NO_FLUX_BYTES, MemoryPlan, MemoryTerm,
    StageMemory, baseline_bytes, current_rss_bytes, peak_rss_bytes,
};
use bevy_ecs::world::World;

/// Bytes (saturating) of an `f64` estimate.
fn to_bytes(x: f64) -> u64 {
    if x.is_nan() {
        u64::MAX
    } else {
        x.max(0.0) as u64
    }
}

/// A stage from its terms (the baseline first).
fn stage(name: &str, terms: Vec<(String, f64)>) -> StageMemory {
    let total: f64 = terms.iter().map(|t| t.1).sum();
    StageMemory {
        stage: name.into(),
        bytes: to_bytes(total),
        terms: terms
            .into_iter()
            .map(|(name, b)| MemoryTerm {
                name,
                bytes: to_bytes(b),
            })
            .collect(),
    }
}

/// Writer buffers of the Output stage, bytes: `density.csv` (one line of ~40 bytes per turbid
/// entry) and `budget/cells.csv` (one line of ~48 bytes per band and non-empty cell: turbid
/// entries, facet references and ground columns) are built as strings before their atomic
/// write, the per-reference facet shares (f64) of the budget, and the images' EXR and PNG
/// encoding buffers (f32 per pixel and band, twice).
pub fn output_terms(
    turbid_entries: usize,
    facet_refs: usize,
    n_columns: usize,
    n_bands: usize,
    image_pixels: usize,
    passive: bool,
) -> Vec<(&'static str, f64)> {
    let f = |x: usize| x as f64;
    let density = 40.0 * f(turbid_entries);
    let mut t = vec![("density.csv", density)];
    if passive {
        let cells = 48.0 * f(n_bands) * (f(turbid_entries) + f(facet_refs) + f(n_columns))
            + 8.0 * f(facet_refs);
        t.push(("budget/cells.csv", cells));
        t.push(("images", 2.0 * 4.0 * f(n_bands) * f(image_pixels)));
    }
    t
}

/// The memory estimate of running the scene of `world` (after the Maket plan systems;
/// `report` the plan report; `rss` the process's resident set before planning,
/// [`current_rss_bytes`]): one [`StageMemory`] per stage that will run, and the peak.
pub fn estimate(world: &World, report: &MaketReport, rss: Option<u64>) -> MemoryPlan {
    use crate::resources::scene::{RunSettings, SceneInfo, SkipPassive, Solver};
    use crate::resources::tracking::{
        DirectionRequest, REFERENCE_MIN_DIRECTIONS, RadiativeSettings,
    };
    let threads = rayon::current_num_threads();
    let run = world.resource::<RunSettings>().clone();
    let info = world.resource::<SceneInfo>().clone();
    let settings = world.resource::<RadiativeSettings>().clone();
    let passive = world.get_resource::<SkipPassive>().is_none();
    let est = &report.memory;
    let f = |x: u64| x as f64;
    let n_bands = info.bands.len();
    let sky = info.illumination.skyl.iter().any(|&s| s > 0.0);
    let w = n_bands * if sky { 2 } else { 1 };
    let n_cells = report.n_cells as usize;
    let n_columns = report.cells[0].saturating_mul(report.cells[1]);
    let n_facets = report.facet_count.values().sum::<u64>() as usize;
    let entries = est.turbid_entries_max as usize;
    let refs = est.facet_refs_max as usize;
    let turbid_materials = report.leaf_area.len();
    let mc = matches!(run.solver, Solver::MonteCarlo { .. });
    let baseline = baseline_bytes(rss, passive && !mc);
    let base = ("baseline".to_string(), f(baseline));
    // What Maket leaves for the later stages: the cell index, the entries (8 bytes), the facet
    // references (4 bytes), the facets and their BVH.
    let grid_held = f(est.cell_index_bytes)
        + 8.0 * f(est.turbid_entries_max)
        + 4.0 * f(est.facet_refs_max)
        + f(est.facet_bytes);
    let held = ("Maket grid, facets, BVH".to_string(), grid_held);
    let mut stages = vec![stage(
        "Maket",
        vec![
            base.clone(),
            (
                "Maket build (grid, facets, BVH, build buffers)".into(),
                f(est.peak_bytes),
            ),
        ],
    )];

    // Direction set and images (flux tracking).
    let mut params = world.resource::<DirectionRequest>().0.clone();
    if settings.preset == crate::scene::desc::Preset::Reference {
        params.count = params.count.max(REFERENCE_MIN_DIRECTIONS);
    }
    let set = crate::direction::DirectionSet::new(&params).ok();
    let (n_dirs, n_down, n_images, slots) = set.as_ref().map_or((0, 0, 0, 1), |set| {
        let t = set.tiling();
        let n_images = t
            .iter()
            .filter(|d| {
                matches!(d.kind, crate::direction::DirectionKind::Exact { .. }) && d.omega.z > 0.0
            })
            .count();
        let slots = if settings.per_direction_stores {
            t.len()
        } else {
            set.n_sectors()
        } + 1;
        (
            t.len(),
            t.iter().filter(|d| d.omega.z < 0.0).count(),
            n_images,
            slots,
        )
    });
    let eta = settings.image_oversampling.max(1) as usize;
    let image_pixels = n_images.saturating_mul(n_columns).saturating_mul(eta * eta);
    let mut products_held = 0.0;
    if passive && !mc {
        let counts = radiative_counts(
            world,
            report,
            &settings,
            (n_dirs, n_down, slots, n_images, image_pixels),
        );
        let terms = crate::radiative::memory_terms(&counts);
        products_held = terms
            .iter()
            .filter(|t| t.0 == "products")
            .map(|t| t.1)
            .sum::<f64>();
        let mut all = vec![base.clone(), held.clone()];
        all.extend(terms.into_iter().map(|(n, b)| (n.to_string(), b)));
        stages.push(stage("Radiative", all));
    }
    if passive && let Solver::MonteCarlo { photons, sampler } = &run.solver {
        let batches = crate::photon::engine::PhotonParams::new(*photons, info.seed, *sampler)
            .batches as usize;
        let terms = crate::photon::memory_terms(&crate::photon::PhotonCounts {
            n_cells,
            turbid_materials,
            turbid_entries: entries,
            n_facets,
            facet_refs: refs,
            n_columns,
            n_dirs,
            channels: w,
            batches,
            camera_pixels: world
                .get_resource::<crate::resources::sensors::SensorInstruments>()
                .map_or(0, |s| {
                    s.0.iter()
                        .map(|d| match &d.instrument {
                            crate::scene::desc::InstrumentDesc::FrameCamera(c) => {
                                c.pixels.0 as usize * c.pixels.1 as usize
                            }
                        })
                        .sum()
                }),
        });
        products_held =
            2.0 * 8.0 * (entries as f64 + n_facets as f64 + n_columns as f64) * w as f64;
        let mut all = vec![base.clone(), held.clone()];
        all.extend(terms.into_iter().map(|(n, b)| (n.to_string(), b)));
        stages.push(stage("Photon", all));
    }
    let products = ("passive products".to_string(), products_held);
    if let Some(lidars) = world.get_resource::<crate::resources::lidar::LidarInstruments>() {
        let height = report.z_range_m[1] - report.z_range_m[0];
        // Instruments run one after the other: the largest one's terms.
        let mut worst: Vec<(&'static str, f64)> = Vec::new();
        for d in &lidars.0 {
            let t = crate::lidar::memory_terms(
                d,
                n_cells,
                turbid_materials,
                height,
                run.lidar_chunk_pulses,
                refs,
            );
            if t.iter().map(|x| x.1).sum::<f64>() > worst.iter().map(|x| x.1).sum::<f64>() {
                worst = t;
            }
        }
        let mut all = vec![base.clone(), held.clone(), products.clone()];
        all.extend(worst.into_iter().map(|(n, b)| (n.to_string(), b)));
        stages.push(stage("LiDAR", all));
    }
    let mut all = vec![base, held, products];
    all.extend(
        output_terms(
            entries,
            refs,
            n_columns,
            n_bands,
            if mc { 0 } else { image_pixels },
            passive,
        )
        .into_iter()
        .map(|(n, b)| (n.to_string(), b)),
    );
    stages.push(stage("Output", all));
    let peak = stages
        .iter()
        .max_by_key(|s| s.bytes)
        .map(|s| (s.bytes, s.stage.clone()))
        .unwrap_or_default();
    MemoryPlan {
        baseline_bytes: baseline,
        threads,
        stages,
        peak_bytes: peak.0,
        peak_stage: peak.1,
    }
}

/// The counts the Radiative estimate depends on: the plan's entries and references, the
/// direction set's counts `(directions, downward, slots, images, image pixels)`, the
/// turbid stores of the `turbid_subfaces` mode, and the engine's own launch plan (launch
/// points, sub-cell factor D of the scattering points).
fn radiative_counts(
    world: &World,
    report: &MaketReport,
    settings: &crate::resources::tracking::RadiativeSettings,
    dirs: (usize, usize, usize, usize, usize),
) -> crate::radiative::RadiativeCounts {
    use crate::resources::facets::{FacetKind, FacetStore};
    use crate::resources::grid::GridSpec;
    use crate::scene::desc::TurbidSubfaces;
    let (n_dirs, n_down, slots, n_images, image_pixels) = dirs;
    let info = world
        .resource::<crate::resources::scene::SceneInfo>()
        .clone();
    let sky = info.illumination.skyl.iter().any(|&s| s > 0.0);
    let sun = info.illumination.sun_zenith_deg < 90.0;
    let spec = world.get_resource::<GridSpec>().cloned();
    let empty = FacetStore::default();
    let facets = world.get_resource::<FacetStore>().unwrap_or(&empty);
    let flat_ground = !facets.facets.iter().any(|f| f.kind == FacetKind::Ground)
        && world
            .iter_entities()
            .any(|e| e.contains::<crate::components::Ground>());
    let (size, cell, scene_d) = spec.as_ref().map_or(((1.0, 1.0), (1.0, 1.0, 1.0), 1), |g| {
        (
            (g.n[0] as f64 * g.cell.x, g.n[1] as f64 * g.cell.y),
            (g.cell.x, g.cell.y, g.cell.z),
            g.subcells,
        )
    });
    // The sky launch: the solar sky, or a thermal run's sky (issue #34).
    let thermal_sky = world
        .get_resource::<crate::resources::scene::ThermalRun>()
        .is_some_and(|t| t.desc.sky_temperature_k.is_some());
    let n_sky = if sky || thermal_sky { n_down } else { 0 };
    let plan = crate::radiative::engine::launch_plan(
        size,
        (cell.0, cell.1),
        &facets.facets,
        scene_d,
        n_sky,
        &settings.tracking,
    );
    let d = plan.subcells.max(1) as f64;
    // Facet scattering points: the sub-cells (of side s = cell/D) each facet crosses, at
    // least one per facet reference. A planar piece of area A, unit normal n and perimeter P
    // crosses on average A (|n_x|/(s_y s_z) + |n_y|/(s_x s_z) + |n_z|/(s_x s_y)) sub-cell
    // faces through its area, and its edges add P (|t_x|/s_x + |t_y|/s_y + |t_z|/s_z) / 2
    // more (t: the edges' unit directions).
    let (sx, sy, sz) = (cell.0 / d, cell.1 / d, cell.2 / d);
    let n_dirs_f = n_dirs as f64;
    let (mut two_sided, mut one_sided, mut one_rays) = (0.0, 0.0, (0.0, 0.0));
    for f in &facets.facets {
        let n2 = (f.v[1] - f.v[0]).cross(f.v[2] - f.v[0]);
        let area = 0.5 * n2.length();
        let n = n2.normalize_or(glam::DVec3::Z);
        let mut pieces =
            area * (n.x.abs() / (sy * sz) + n.y.abs() / (sx * sz) + n.z.abs() / (sx * sy));
        for e in 0..3 {
            let t = f.v[(e + 1) % 3] - f.v[e];
            pieces += 0.5 * (t.x.abs() / sx + t.y.abs() / sy + t.z.abs() / sz);
        }
        let pieces = pieces.max(1.0);
        if f.two_sided {
            two_sided += pieces;
        } else {
            one_sided += pieces;
            // Share θ/π of the normal's hemisphere below the horizon.
            let down = n.z.clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
            one_rays.0 += pieces * 0.5 * n_dirs_f * down;
            one_rays.1 += pieces * 0.5 * n_dirs_f * (1.0 - down);
        }
    }
    // At least one point per facet reference.
    let refs = report.memory.facet_refs_max as f64;
    if two_sided + one_sided < refs && two_sided + one_sided > 0.0 {
        let k = refs / (two_sided + one_sided);
        two_sided *= k;
        one_rays = (one_rays.0 * k, one_rays.1 * k);
    }
    let subcells = spec.as_ref().map_or(1, |g| g.subcells.clamp(1, 8) as usize);
    let turbid_stores = match settings.tracking.turbid_subfaces {
        TurbidSubfaces::Off => (1, 1),
        TurbidSubfaces::Faces => (7, 7),
        TurbidSubfaces::Subfaces => (6 * subcells * subcells + 1, 6 * subcells * subcells + 1),
        TurbidSubfaces::Blend => (1, slots),
    };
    crate::radiative::RadiativeCounts {
        n_dirs,
        n_down,
        slots,
        turbid_stores,
        n_bands: info.bands.len(),
        sky,
        turbid_materials: report.leaf_area.len(),
        turbid_entries: report.memory.turbid_entries_max as usize,
        facet_refs: report.memory.facet_refs_max as usize,
        n_facets: facets.facets.len(),
        facet_points: two_sided.min(usize::MAX as f64) as usize,
        one_sided_rays: one_rays,
        n_columns: report.cells[0].saturating_mul(report.cells[1]),
        flat_ground,
        subcells: plan.subcells as usize,
        sun_points: if sun {
            plan.sun_n.0.saturating_mul(plan.sun_n.1)
        } else {
            0
        },
        sky_points: if sky || thermal_sky {
            plan.sky_n.0.saturating_mul(plan.sky_n.1)
        } else {
            0
        },
        n_images,
        image_pixels,
        threads: rayon::current_num_threads(),
        thermal: world
            .get_resource::<crate::resources::scene::ThermalRun>()
            .map(|t| t.mode.solar()),
    }
}
