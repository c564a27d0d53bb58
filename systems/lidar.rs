//! LiDAR (DART 5 paper §4): every instrument of the scene's `lidars` section, simulated by the
//! photon engine in receiver mode ([`crate::lidar::simulate`]). Runs in the Photon stage, after
//! the passive solver, whose radiance feeds the photon-counting solar background and the fusion
//! product.
//!
//! Reads LidarInstruments, SceneInfo, GridSpec, CellGrid, FacetStore, Directions, Materials,
//! TerrainRes, Ground, TurbidCrown, TurbidPlot, ImportedMesh, RadiativeProducts (optional),
//! ImageDirections (optional), OpticsTables (discrete sampler), RunSettings and OutputDir
//! (optional: a scan longer than one chunk streams its waveforms into the output folder while it
//! runs); writes LidarProducts.

use crate::components::{Ground, ImportedMesh, TurbidCrown, TurbidPlot};
use crate::lidar::run::LidarProducts;
use crate::lidar::simulate::{DEFAULT_CHUNK_PULSES, LidarChunks, PassiveRadiance, simulate_lidar};
use crate::photon::engine::{PhotonParams, SamplerKind};
use crate::photon::material_optics::build_photon_optics;
use crate::radiative::products::RadiativeProducts;
use crate::resources::facets::FacetStore;
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::lidar::LidarInstruments;
use crate::resources::materials::Materials;
use crate::resources::scene::{SceneInfo, StageErrors, TerrainRes};
use crate::resources::tracking::{Directions, OpticsTables};
use crate::scene::desc::LidarSampler;
use crate::systems::photon::{LadOpticsCache, photon_input};
use crate::systems::radiative::ImageDirections;
use crate::systems::{tracking_scene, used_turbid};
use bevy_ecs::prelude::*;

/// Passive radiance at sensor level for the LiDAR: the orthographic image of the exact view
/// direction closest to the LiDAR's (within 2°) when the flux-tracking solver made one, else the
/// scene-mean radiance in the nearest direction.
fn passive_radiance(
    p: &RadiativeProducts,
    images: Option<&ImageDirections>,
    dirs: &Directions,
    spec: &GridSpec,
    view: glam::DVec3,
) -> Option<PassiveRadiance> {
    let raw = &p.raw;
    let nb = raw.n_bands;
    let w = raw.n_channels;
    let (nx, ny) = (spec.n[0], spec.n[1]);
    let ig = raw.image_grid;
    let a_px = ig.pixel_m.0 * ig.pixel_m.1;
    let tiling = dirs.set.tiling();
    if let Some(img) = images
        && !raw.images.is_empty()
    {
        let best = tiling
            .iter()
            .enumerate()
            .filter(|(j, _)| img.0.get(*j).is_some_and(|&k| k != u32::MAX))
            .max_by(|a, b| a.1.omega.dot(view).total_cmp(&b.1.omega.dot(view)));
        if let Some((j, d)) = best
            && d.omega.dot(view) > 2f64.to_radians().cos()
        {
            let k = img.0[j] as usize;
            let npx = ig.pixels();
            let per_band = (0..nb)
                .map(|b| {
                    (0..npx)
                        .map(|px| {
                            let base = (k * npx + px) * w;
                            let mut v = raw.images[base + b];
                            if raw.has_sky {
                                v += raw.images[base + nb + b];
                            }
                            v / (a_px * d.projected_sr)
                        })
                        .collect()
                })
                .collect();
            return Some(PassiveRadiance {
                n: ig.n,
                cell: ig.pixel_m,
                per_band,
                source: format!(
                    "the flux-tracking image at view ({:.1}°, {:.1}°), {:.3} × {:.3} m pixels",
                    d.zenith_deg(),
                    d.azimuth_deg(),
                    ig.pixel_m.0,
                    ig.pixel_m.1
                ),
            });
        }
    }
    // Scene mean in the nearest upward direction: L = Σ escaped / (A ∫|μ|dΩ).
    let area = nx as f64 * spec.cell.x * ny as f64 * spec.cell.y;
    let (j, d) = tiling
        .iter()
        .enumerate()
        .filter(|(_, d)| d.omega.z > 0.0)
        .max_by(|a, b| a.1.omega.dot(view).total_cmp(&b.1.omega.dot(view)))?;
    let per_band = (0..nb)
        .map(|b| {
            let mut v = raw.escaped[j * w + b];
            if raw.has_sky {
                v += raw.escaped[j * w + nb + b];
            }
            vec![v / (area * d.projected_sr)]
        })
        .collect();
    Some(PassiveRadiance {
        n: (1, 1),
        cell: (nx as f64 * spec.cell.x, ny as f64 * spec.cell.y),
        per_band,
        source: format!(
            "the scene-mean passive radiance at ({:.1}°, {:.1}°) (no image in that direction)",
            d.zenith_deg(),
            d.azimuth_deg()
        ),
    })
}

/// Photon · LiDAR instruments · writes LidarProducts.
#[allow(clippy::too_many_arguments)]
pub fn run_lidars(
    instruments: Res<LidarInstruments>,
    info: Res<SceneInfo>,
    spec: Res<GridSpec>,
    grid: Res<CellGrid>,
    facets: Res<FacetStore>,
    dirs: Res<Directions>,
    mats: Res<Materials>,
    terrain: Res<TerrainRes>,
    (passive, images, tables, run, out): (
        Option<Res<RadiativeProducts>>,
        Option<Res<ImageDirections>>,
        Option<Res<OpticsTables>>,
        Option<Res<crate::resources::scene::RunSettings>>,
        Option<Res<crate::resources::scene::OutputDir>>,
    ),
    grounds: Query<&Ground>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    mut errors: ResMut<StageErrors>,
    mut cache: ResMut<LadOpticsCache>,
    mut commands: Commands,
) {
    let nb = info.bands.len();
    let used = used_turbid(mats.list.len(), &crowns, &plots, &meshes);
    // Optics per sampler kind, built once for the instruments that use it.
    let mut built: [Option<Vec<crate::photon::engine::PhotonOptics>>; 2] = [None, None];
    let scene = tracking_scene(&info, &spec, &terrain, grounds.iter().next(), &facets);
    let box_lo = spec.origin;
    let box_hi = spec.origin
        + glam::DVec3::new(
            spec.n[0] as f64 * spec.cell.x,
            spec.n[1] as f64 * spec.cell.y,
            spec.n[2] as f64 * spec.cell.z,
        );
    let mut runs = Vec::new();
    for l in &instruments.0 {
        let Some(band) = info.bands.iter().position(|b| b.name == l.band) else {
            errors
                .0
                .push(format!("lidar `{}`: no band `{}`", l.name, l.band));
            return;
        };
        if let crate::scene::desc::LidarPlatform::Airborne { altitude_m, .. } = &l.platform
            && *altitude_m <= box_hi.z
        {
            errors.0.push(format!(
                "lidar `{}`: altitude {altitude_m} m is not above the scene top ({:.3} m)",
                l.name, box_hi.z
            ));
            return;
        }
        let (slot, kind) = match l.sampler {
            LidarSampler::Discrete => (0, SamplerKind::Alias),
            LidarSampler::Continuous => (1, SamplerKind::Continuous),
        };
        if built[slot].is_none() {
            match build_photon_optics(&mats, &used, tables.as_deref(), kind, nb, &mut cache.0) {
                Ok(o) => built[slot] = Some(o),
                Err(e) => {
                    errors.0.push(format!("lidar `{}`: {e}", l.name));
                    return;
                }
            }
        }
        let all = built[slot].as_ref().expect("built above");
        let optics: Vec<_> = all.iter().map(|o| o.select_band(band)).collect();
        let mut params = PhotonParams::new(0, info.seed, kind);
        params.max_order = l.max_order;
        params.skip_empty = run.as_ref().is_none_or(|r| r.skip_empty);
        // One forced peel-off point per crossing of a turbid or fluid cell (see
        // `PhotonParams::fluid_peel_points`) where the first flight is not integrated bin by
        // bin (`Legacy` estimator, flights through a facet, fluids): at hundreds of photons
        // per pulse the first-order waveform is already smooth, and each point costs a trace
        // to the receiver.
        params.fluid_peel_points = 1;
        let input = photon_input(&spec, &grid, &facets, &dirs, &scene, &optics, params);
        let plan = crate::lidar::simulate::PulsePlan::new(l);
        let view = plan.iter().next().map_or(glam::DVec3::Z, |p| -p.axis);
        let pr = passive
            .as_ref()
            .and_then(|p| passive_radiance(p, images.as_deref(), &dirs, &spec, view));
        let chunks = LidarChunks {
            chunk_pulses: run
                .as_ref()
                .map_or(DEFAULT_CHUNK_PULSES, |r| r.lidar_chunk_pulses),
            stream_dir: out.as_ref().map(|o| o.0.join("lidar").join(&l.name)),
            progress: run.as_ref().is_some_and(|r| r.progress),
            far_roulette: run
                .as_ref()
                .map_or(Default::default(), |r| r.lidar_far_roulette),
            first_order_columns: run.as_ref().is_none_or(|r| r.lidar_first_order_columns),
        };
        match simulate_lidar(l, band, &input, box_lo, box_hi, pr.as_ref(), &chunks) {
            Ok(r) => runs.push(r),
            Err(e) => {
                errors.0.push(e);
                return;
            }
        }
    }
    commands.insert_resource(LidarProducts(runs));
}
