//! Direction stage (DART 5 paper §2, "Direction" module): builds the discrete directions from
//! the scene's `directions` section (physics.md §2), keeps the sun direction exact, and groups
//! directions into interception slots (angular sectors, or one per direction).

use crate::direction::{DirectionSet, direction_from_deg};
use crate::resources::scene::{SceneInfo, StageErrors};
use crate::resources::tracking::{
    DirectionRequest, Directions, REFERENCE_MIN_DIRECTIONS, RadiativeSettings,
};
use bevy_ecs::prelude::*;

/// Direction · reads SceneInfo, DirectionRequest, RadiativeSettings · writes Directions.
pub fn build_directions(
    info: Res<SceneInfo>,
    req: Res<DirectionRequest>,
    settings: Res<RadiativeSettings>,
    mut errors: ResMut<StageErrors>,
    mut commands: Commands,
) {
    // The reference preset needs at least REFERENCE_MIN_DIRECTIONS directions (BRF within 1 %
    // of DISORT at 75° view zenith in the NIR needs ≥ 400; see tests/radiative_oracles.rs).
    let mut params = req.0.clone();
    if settings.preset == crate::scene::desc::Preset::Reference
        && params.count < REFERENCE_MIN_DIRECTIONS
    {
        params.count = REFERENCE_MIN_DIRECTIONS;
    }
    let set = match DirectionSet::new(&params) {
        Ok(s) => s,
        Err(e) => {
            errors.0.push(e.to_string());
            return;
        }
    };
    let il = &info.illumination;
    // Ground→sun vector; the beam propagates along its opposite.
    let sun = -direction_from_deg(il.sun_zenith_deg, il.sun_azimuth_deg);
    let tiling = set.tiling();
    // Interception slots: one per direction (reference preset) or DART's angular sectors.
    let (sector_of, n_sectors) = if settings.per_direction_stores {
        (
            (0..tiling.len()).map(|j| j as u16).collect::<Vec<u16>>(),
            tiling.len(),
        )
    } else {
        (tiling.iter().map(|d| d.sector).collect(), set.n_sectors())
    };
    commands.insert_resource(Directions {
        set,
        sun,
        sector_of,
        n_sectors,
    });
}

/// The Direction stage's systems.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub enum DirectionSystems {
    /// Discrete directions, sun and view directions, interception slots.
    Build,
}

/// Adds the Direction stage's systems to its schedule.
pub fn add_systems(s: &mut Schedule) {
    s.add_systems(build_directions.in_set(DirectionSystems::Build));
}
