//! Atmosphere resource: the scene's `atmosphere` section (spawned only when the scene has one;
//! a scene without it runs no atmosphere work). The Photon stage resolves it per band over the
//! scene top ([`crate::scene::desc::AtmosphereDesc::model`]).

use crate::scene::desc::AtmosphereDesc;
use bevy_ecs::prelude::Resource;

/// The scene's atmosphere, as validated.
#[derive(Debug, Clone, Resource)]
pub struct Atmosphere(pub AtmosphereDesc);
