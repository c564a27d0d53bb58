//! Scene-wide resources set by the spawn step: scene info, terrain, run settings, stage errors.

use crate::geometry::terrain::Terrain;
use crate::scene::desc::{BandDesc, BoundaryMode, IlluminationDesc};
use bevy_ecs::prelude::Resource;
use std::path::PathBuf;

/// Scene-wide facts copied from the description.
#[derive(Debug, Clone, Resource)]
pub struct SceneInfo {
    /// Scene name.
    pub name: String,
    /// Scene file (or `<generated>`).
    pub source: PathBuf,
    /// Seed of every random choice.
    pub seed: u64,
    /// Bands.
    pub bands: Vec<BandDesc>,
    /// Sun and sky.
    pub illumination: IlluminationDesc,
    /// Scene extent (x, y), metres.
    pub size: (f64, f64),
    /// Cell size, metres.
    pub cell: (f64, f64, f64),
    /// User-fixed scene height, metres.
    pub height: Option<f64>,
    /// Sub-cell factor D.
    pub subcells: u32,
    /// Boundary mode.
    pub boundary: BoundaryMode,
}

/// The ground shape (flat when the scene has no `Ground` with a DEM).
#[derive(Debug, Clone, Resource)]
pub struct TerrainRes(pub Terrain);

/// Run settings that are not part of the scene.
#[derive(Debug, Clone, Resource)]
pub struct RunSettings {
    /// Refuse grids whose estimated memory exceeds this many bytes.
    pub max_memory_bytes: u64,
    /// Show progress bars.
    pub progress: bool,
}

impl Default for RunSettings {
    fn default() -> Self {
        Self {
            max_memory_bytes: default_max_memory(),
            progress: false,
        }
    }
}

/// 75 % of the machine's physical memory (from /proc/meminfo; 16 GiB if it cannot be read).
pub fn default_max_memory() -> u64 {
    let total = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("MemTotal:"))
                .and_then(|l| {
                    l.split_whitespace()
                        .nth(1)
                        .and_then(|v| v.parse::<u64>().ok())
                })
        })
        .map(|kib| kib * 1024)
        .unwrap_or(16 << 30);
    total / 4 * 3
}

/// Errors raised by systems; the simulation stops after the stage that raised one.
#[derive(Debug, Clone, Default, Resource)]
pub struct StageErrors(pub Vec<String>);

/// Warnings raised while building the scene (degenerate triangles skipped, …).
#[derive(Debug, Clone, Default, Resource)]
pub struct Warnings(pub Vec<String>);
