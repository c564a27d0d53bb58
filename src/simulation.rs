//! The simulation: a bevy `World` holding the scene's entities and resources, and one schedule
//! per DART module, run in DART order (Direction, Phase, Maket, Radiative, Photon, Sensor,
//! Output). A stage runs only when the scene needs it and when it exists.

use crate::resources::scene::{RunSettings, StageErrors};
use crate::scene::desc::SceneDesc;
use crate::scene::error::SceneError;
use crate::scene::{SceneSource, load_scene};
use crate::systems::maket::{add_maket_systems, add_plan_systems, no_stage_error};
use crate::systems::output::{OutputDir, write_maket_products};
use crate::systems::spawn::spawn_scene;
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleLabel;
use std::path::Path;

/// The stages (DART modules), in execution order.
#[derive(ScheduleLabel, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    /// Discrete directions.
    Direction,
    /// Phase-function tables.
    Phase,
    /// Scene → cell grid.
    Maket,
    /// Discrete-ordinate flux tracking.
    Radiative,
    /// Monte Carlo photons (passive Monte Carlo solver).
    Photon,
    /// Sensor images (not implemented yet).
    Sensor,
    /// Products.
    Output,
}

impl Stage {
    /// Every stage in DART order.
    pub const ALL: [Stage; 7] = [
        Stage::Direction,
        Stage::Phase,
        Stage::Maket,
        Stage::Radiative,
        Stage::Photon,
        Stage::Sensor,
        Stage::Output,
    ];

    /// True when the stage has systems in this version.
    pub fn implemented(self) -> bool {
        matches!(
            self,
            Stage::Direction
                | Stage::Phase
                | Stage::Maket
                | Stage::Radiative
                | Stage::Photon
                | Stage::Output
        )
    }
}

/// A stage reported an error.
#[derive(Debug, thiserror::Error)]
#[error("{stage:?} stage: {}", messages.join("; "))]
pub struct StageError {
    /// Stage.
    pub stage: Stage,
    /// Messages.
    pub messages: Vec<String>,
}

/// A scene loaded into a World, ready to run stages.
pub struct Simulation {
    /// The ECS world.
    pub world: World,
}

impl Simulation {
    /// Spawns a scene description (validated first) with the given settings.
    pub fn from_desc(
        desc: &SceneDesc,
        src: &SceneSource,
        settings: RunSettings,
    ) -> Result<Self, SceneError> {
        let mut world = World::new();
        world.insert_resource(settings);
        world.init_resource::<StageErrors>();
        world.init_resource::<crate::systems::photon::LadOpticsCache>();
        spawn_scene(&mut world, desc, src)?;
        let mut sim = Self { world };
        sim.add_schedules();
        Ok(sim)
    }

    /// Loads, validates and spawns a scene file.
    pub fn load(path: &Path, settings: RunSettings) -> Result<Self, SceneError> {
        let (desc, src) = load_scene(path)?;
        Self::from_desc(&desc, &src, settings)
    }

    fn add_schedules(&mut self) {
        for stage in Stage::ALL {
            let mut s = Schedule::new(stage);
            match stage {
                Stage::Direction => {
                    s.add_systems(crate::systems::direction::build_directions);
                }
                Stage::Phase => {
                    s.add_systems(
                        crate::systems::phase::tabulate_phase
                            .run_if(resource_exists::<crate::resources::tracking::Directions>)
                            .run_if(
                                |s: Res<RunSettings>,
                                 skip: Option<Res<crate::resources::scene::SkipPassive>>,
                                 l: Option<Res<crate::resources::lidar::LidarInstruments>>| {
                                    (skip.is_none() && s.solver.needs_phase_tables())
                                        || l.is_some_and(|l| {
                                            l.0.iter().any(|d| {
                                                d.sampler
                                                    == crate::scene::desc::LidarSampler::Discrete
                                            })
                                        })
                                },
                            ),
                    );
                }
                Stage::Maket => add_maket_systems(&mut s),
                Stage::Radiative => {
                    s.add_systems(
                        crate::systems::radiative::track_flux
                            .run_if(resource_exists::<crate::resources::tracking::OpticsTables>)
                            .run_if(resource_exists::<crate::resources::grid::CellGrid>)
                            .run_if(|s: Res<RunSettings>| !s.solver.is_monte_carlo())
                            .run_if(not(resource_exists::<crate::resources::scene::SkipPassive>))
                            .run_if(no_stage_error),
                    );
                }
                Stage::Photon => {
                    s.add_systems(
                        (
                            crate::systems::photon::track_photons
                                .run_if(resource_exists::<crate::resources::tracking::Directions>)
                                .run_if(resource_exists::<crate::resources::grid::CellGrid>)
                                .run_if(|s: Res<RunSettings>| s.solver.is_monte_carlo())
                                .run_if(not(
                                    resource_exists::<crate::resources::scene::SkipPassive>,
                                ))
                                .run_if(no_stage_error),
                            crate::systems::lidar::run_lidars
                                .run_if(
                                    resource_exists::<crate::resources::lidar::LidarInstruments>,
                                )
                                .run_if(resource_exists::<crate::resources::tracking::Directions>)
                                .run_if(resource_exists::<crate::resources::grid::CellGrid>)
                                .run_if(no_stage_error),
                        )
                            .chain(),
                    );
                }
                Stage::Output => {
                    s.add_systems((
                        write_maket_products
                            .run_if(resource_exists::<OutputDir>)
                            .run_if(resource_exists::<crate::resources::grid::CellGrid>)
                            .run_if(resource_exists::<crate::resources::maket_report::MaketReport>)
                            .run_if(no_stage_error),
                        crate::systems::output::write_radiative_products
                            .run_if(resource_exists::<OutputDir>)
                            .run_if(
                                resource_exists::<crate::radiative::products::RadiativeProducts>,
                            )
                            .run_if(no_stage_error),
                        crate::systems::output::write_lidar_products
                            .run_if(resource_exists::<OutputDir>)
                            .run_if(resource_exists::<crate::resources::lidar::LidarProducts>)
                            .run_if(no_stage_error),
                    ));
                }
                // Not implemented yet: the schedule exists so that ordering is fixed; it has no
                // systems, so it does nothing (and `run` reports it as skipped).
                _ => {}
            }
            self.world.add_schedule(s);
        }
    }

    /// Runs one stage; fails if a system reported an error.
    pub fn run_stage(&mut self, stage: Stage) -> Result<(), StageError> {
        self.world.run_schedule(stage);
        let errs = std::mem::take(&mut self.world.resource_mut::<StageErrors>().0);
        if errs.is_empty() {
            Ok(())
        } else {
            Err(StageError {
                stage,
                messages: errs,
            })
        }
    }

    /// Runs only the facet and planning part of Maket (grid size and memory estimate, no
    /// allocation of the cell grid): what `lumenscape check` reports.
    pub fn plan(&mut self) -> Result<(), StageError> {
        let mut s = Schedule::default();
        add_plan_systems(&mut s);
        s.run(&mut self.world);
        let errs = std::mem::take(&mut self.world.resource_mut::<StageErrors>().0);
        if errs.is_empty() {
            Ok(())
        } else {
            Err(StageError {
                stage: Stage::Maket,
                messages: errs,
            })
        }
    }

    /// The Maket report available after [`Simulation::plan`] (areas, cells, memory estimate; no
    /// rasterisation), or `None` if planning did not get that far.
    pub fn plan_report(&mut self) -> Option<crate::resources::maket_report::MaketReport> {
        use crate::components::{ImportedMesh, TurbidCrown, TurbidPlot};
        use crate::resources::{
            facets::FacetStore, grid::GridSpec, maket_report::MemoryEstimate, materials::Materials,
            scene::Warnings,
        };
        use bevy_ecs::system::RunSystemOnce;
        if !self.world.contains_resource::<MemoryEstimate>()
            || !self.world.contains_resource::<GridSpec>()
        {
            return None;
        }
        self.world
            .run_system_once(
                |spec: Res<GridSpec>,
                 est: Res<MemoryEstimate>,
                 mats: Res<Materials>,
                 facets: Res<FacetStore>,
                 crowns: Query<&TurbidCrown>,
                 plots: Query<&TurbidPlot>,
                 meshes: Query<&ImportedMesh>,
                 warnings: Res<Warnings>| {
                    crate::systems::maket::make_report(
                        &spec, &est, &mats, &facets, None, None, &crowns, &plots, &meshes,
                        &warnings,
                    )
                },
            )
            .ok()
    }

    /// Runs every implemented stage in order, writing products into `out` when given.
    /// Returns the stages that ran.
    pub fn run(&mut self, out: Option<&Path>) -> Result<Vec<Stage>, StageError> {
        if let Some(o) = out {
            self.world.insert_resource(OutputDir(o.to_path_buf()));
        }
        let mut ran = Vec::new();
        for stage in Stage::ALL {
            if stage.implemented() {
                self.run_stage(stage)?;
                ran.push(stage);
            }
        }
        Ok(ran)
    }

    /// A resource of the world (panics if absent: for tests and callers that ran the stage).
    pub fn resource<R: Resource>(&self) -> &R {
        self.world.resource::<R>()
    }

    /// A resource of the world, if present (e.g. `RadiativeProducts` exists only when the
    /// passive solver ran).
    pub fn get_resource<R: Resource>(&self) -> Option<&R> {
        self.world.get_resource::<R>()
    }
}
