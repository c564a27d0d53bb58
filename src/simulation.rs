//! The simulation: a bevy `World` holding the scene's entities and resources, and one schedule
//! per DART module, run in DART order (Direction, Phase, Maket, Radiative, Photon, Sensor,
//! Output). A stage runs only when the scene needs it and when it exists.

use crate::resources::scene::{RunSettings, StageErrors};
use crate::scene::desc::SceneDesc;
use crate::scene::error::SceneError;
use crate::scene::{SceneSource, load_scene};
use crate::systems::maket::add_plan_systems;
use crate::systems::output::OutputDir;
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
    /// Sensor images by flux tracking (not implemented yet; the Monte Carlo solver images
    /// frame cameras in the Photon stage).
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
        use crate::systems::{direction, maket, output, phase, photon, radiative};
        for stage in Stage::ALL {
            let mut s = Schedule::new(stage);
            match stage {
                Stage::Direction => direction::add_systems(&mut s),
                Stage::Phase => phase::add_systems(&mut s),
                Stage::Maket => maket::add_systems(&mut s),
                Stage::Radiative => radiative::add_systems(&mut s),
                // The passive Monte Carlo solver, then the LiDARs.
                Stage::Photon => photon::add_systems(&mut s),
                Stage::Output => output::add_systems(&mut s),
                // No systems yet: the schedule exists so that the order is fixed, and `run`
                // reports the stage as not implemented.
                Stage::Sensor => {}
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
        use crate::resources::{grid::GridSpec, maket_report::MemoryEstimate};
        use bevy_ecs::system::RunSystemOnce;
        if !self.world.contains_resource::<MemoryEstimate>()
            || !self.world.contains_resource::<GridSpec>()
        {
            return None;
        }
        self.world
            .run_system_once(crate::systems::maket::plan_report)
            .ok()
    }

    /// The memory estimate of every stage of this run ([`crate::memory::estimate`]), from the
    /// planned grid (facets and grid extent; no allocation of the grid). The facets and
    /// warnings planning builds are dropped again (the Maket stage builds them), so that a run
    /// after this one is unchanged. `lumenscape run` inserts the result as a resource (written
    /// into `summary.json`) after checking it against `--max-memory`.
    pub fn memory_plan(&mut self) -> Result<crate::resources::memory::MemoryPlan, StageError> {
        let warnings = self
            .world
            .get_resource::<crate::resources::scene::Warnings>()
            .cloned();
        let rss = crate::memory::current_rss_bytes();
        let planned = self.plan();
        let report = self.plan_report();
        let plan = report.map(|r| crate::memory::estimate(&self.world, &r, rss));
        self.world
            .remove_resource::<crate::resources::facets::FacetStore>();
        if let Some(w) = warnings {
            self.world.insert_resource(w);
        }
        planned?;
        plan.ok_or_else(|| StageError {
            stage: Stage::Maket,
            messages: vec!["planning produced no grid".into()],
        })
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
