//! Phase stage (DART 5 paper §2, "Phase" module): for every turbid material a component of the
//! scene uses, the fraction of intercepted power scattered from each incident direction (and the
//! exact sun direction) into each discrete direction, per band (physics.md §2.5, §3.3); facet
//! materials become Lambertian (R, T_d, T_dir) models. Only what the scene uses is tabulated.

use crate::components::{ImportedMesh, TurbidCrown, TurbidPlot};
use crate::phase::vegetation_unit_tables;
use crate::physics::lad::{LeafAngleDistribution, LeafOptics};
use crate::radiative::engine::TrackOptics;
use crate::resources::materials::{MaterialKind, Materials};
use crate::resources::scene::StageErrors;
use crate::resources::tracking::{Directions, OpticsTables, RadiativeSettings};
use bevy_ecs::prelude::*;

/// Phase · reads Materials, Directions, RadiativeSettings, TurbidCrown, TurbidPlot,
/// ImportedMesh · writes OpticsTables.
pub fn tabulate_phase(
    mats: Res<Materials>,
    dirs: Res<Directions>,
    settings: Res<RadiativeSettings>,
    crowns: Query<&TurbidCrown>,
    plots: Query<&TurbidPlot>,
    meshes: Query<&ImportedMesh>,
    mut errors: ResMut<StageErrors>,
    mut commands: Commands,
) {
    let used = crate::systems::used_turbid(mats.list.len(), &crowns, &plots, &meshes);
    let mut optics = Vec::with_capacity(mats.list.len());
    let mut bytes = 0;
    let mut renorm = 0.0f64;
    for (id, m) in mats.list.iter().enumerate() {
        let o = match &m.kind {
            MaterialKind::Turbid {
                reflectance,
                transmittance,
                lad,
                specular,
                leaf_size_m,
            } if used[id] => {
                let lad = match LeafAngleDistribution::new(lad) {
                    Ok(l) => l,
                    Err(e) => {
                        errors.0.push(format!("material `{}`: {e}", m.name));
                        optics.push(TrackOptics::Unused);
                        continue;
                    }
                };
                let unit = vegetation_unit_tables(
                    &dirs.set,
                    &lad,
                    specular.map(|s| s.refractive_index),
                    Some(dirs.sun),
                    &settings.tables,
                );
                let mut tables = Vec::new();
                for b in 0..reflectance.len() {
                    let mut leaf = LeafOptics::lambertian(reflectance[b], transmittance[b]);
                    leaf.specular = *specular;
                    match unit.for_band(&leaf) {
                        Ok(t) => {
                            bytes += t.bytes();
                            renorm = renorm.max(t.max_renormalisation());
                            tables.push(t);
                        }
                        Err(e) => errors.0.push(format!("material `{}`: {e}", m.name)),
                    }
                }
                // Extinction uses the exact Ross G-function of the LAD (the tables' rows are
                // renormalised to the albedo, so they need not share its binning).
                let mut g: Vec<f64> = dirs
                    .set
                    .tiling()
                    .iter()
                    .map(|d| lad.g_function(d.omega.z))
                    .collect();
                g.push(lad.g_function(dirs.sun.z));
                TrackOptics::Turbid {
                    g,
                    tables,
                    leaf_size_m: *leaf_size_m,
                }
            }
            k => match k.lambert_parts() {
                Some((r, t, t_dir)) => TrackOptics::Lambert { r, t, t_dir },
                None => TrackOptics::Unused,
            },
        };
        optics.push(o);
    }
    commands.insert_resource(OpticsTables {
        optics,
        bytes,
        max_renormalisation: renorm,
    });
}

/// The Phase stage's systems.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub enum PhaseSystems {
    /// Phase tables of the turbid materials the scene uses.
    Tabulate,
}

/// True when the phase tables are needed: a passive solver that uses the discrete directions
/// runs, or a LiDAR samples them (`sampler: Discrete`).
fn phase_tables_needed(
    s: Res<crate::resources::scene::RunSettings>,
    skip: Option<Res<crate::resources::scene::SkipPassive>>,
    l: Option<Res<crate::resources::lidar::LidarInstruments>>,
) -> bool {
    (skip.is_none() && s.solver.needs_phase_tables())
        || l.is_some_and(|l| {
            l.0.iter()
                .any(|d| d.sampler == crate::scene::desc::LidarSampler::Discrete)
        })
}

/// Adds the Phase stage's systems to its schedule (they run only when the tables are needed).
pub fn add_systems(s: &mut Schedule) {
    s.add_systems(
        tabulate_phase
            .in_set(PhaseSystems::Tabulate)
            .run_if(resource_exists::<Directions>)
            .run_if(phase_tables_needed),
    );
}
