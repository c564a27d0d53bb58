//! LiDAR resources: the instruments of the scene (spawned only when the scene has a `lidars`
//! section). The Photon stage's LiDAR results are the LiDAR engine's (`lidar::run`).

use crate::scene::desc::LidarDesc;
use bevy_ecs::prelude::Resource;

/// The scene's LiDAR instruments.
#[derive(Debug, Clone, Resource)]
pub struct LidarInstruments(pub Vec<LidarDesc>);
