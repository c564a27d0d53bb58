//! Atmosphere resource: the scene's `atmosphere` section (spawned only when the scene has one;
//! a scene without it runs no atmosphere work). The Photon stage resolves it per band over the
//! scene top ([`crate::scene::desc::AtmosphereDesc::model`]).

use crate::scene::desc::AtmosphereDesc;
use bevy_ecs::prelude::Resource;

/// The scene's atmosphere, as validated.
#[derive(Debug, Clone, Resource)]
pub struct Atmosphere {
    /// The section.
    pub desc: AtmosphereDesc,
    /// Where `atmosphere.toa_altitude_km` is (or would be) in the scene file, for the error
    /// of a TOA below the scene top (known only once the Maket stage has sized the grid).
    pub toa_at: crate::scene::error::Location,
}
