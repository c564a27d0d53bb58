//! Sensor resources: the scene's instruments at a finite distance (inserted only when the
//! scene has a non-empty `sensors` section; DART 5 paper §5).

use crate::scene::desc::SensorDesc;
use bevy_ecs::prelude::Resource;

/// The scene's sensors.
#[derive(Debug, Clone, Resource)]
pub struct SensorInstruments(pub Vec<SensorDesc>);
