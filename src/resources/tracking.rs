//! Resources of the Direction, Phase and Radiative stages.

use crate::direction::DirectionSet;
use crate::phase::TableParams;
use crate::radiative::engine::{TrackOptics, TrackingParams};
use crate::scene::desc::{Preset, RadiativeDesc};
use bevy_ecs::prelude::Resource;
use glam::DVec3;

/// Smallest direction count of the reference preset (BRF within 1 % of DISORT at 75° view
/// zenith in the NIR needs ≥ 400 directions; tests/radiative_oracles.rs).
pub const REFERENCE_MIN_DIRECTIONS: usize = 400;

/// The scene's direction parameters (resource inserted at spawn; defaults when absent).
#[derive(Debug, Clone, Default, Resource)]
pub struct DirectionRequest(pub crate::direction::DirectionParams);

/// Settings of the Direction/Phase/Radiative stages after applying preset and scene knobs.
#[derive(Debug, Clone, Resource)]
pub struct RadiativeSettings {
    /// Preset in force.
    pub preset: Preset,
    /// Tracking parameters.
    pub tracking: TrackingParams,
    /// Phase-table sampling.
    pub tables: TableParams,
    /// Store interception per incident direction (exact) instead of per angular sector.
    pub per_direction_stores: bool,
    /// Oversampling factor η of the orthographic images (pixels of Δx/η × Δy/η).
    pub image_oversampling: u32,
}

impl RadiativeSettings {
    /// Preset values, then the scene's explicit knobs.
    pub fn resolve(preset: Preset, scene: Option<&RadiativeDesc>) -> Self {
        let (tracking, tables, per_dir) = match preset {
            Preset::Preview => (TrackingParams::preview(), TableParams::preview(), false),
            Preset::Default => (
                TrackingParams::dart_default(),
                TableParams::dart_default(),
                false,
            ),
            Preset::Reference => (TrackingParams::reference(), TableParams::reference(), true),
        };
        let mut s = Self {
            preset,
            tracking,
            tables,
            per_direction_stores: per_dir,
            image_oversampling: 1,
        };
        if let Some(r) = scene {
            if let Some(x) = r.max_iterations {
                s.tracking.max_iterations = x;
            }
            if let Some(x) = r.albedo_threshold {
                s.tracking.albedo_threshold = x;
            }
            if let Some(x) = r.ray_threshold {
                s.tracking.ray_threshold = x;
            }
            if let Some(x) = r.launch_spacing_m {
                s.tracking.launch_spacing_m = Some(x);
            }
            if let Some(x) = r.extrapolate {
                s.tracking.extrapolate = x;
            }
            if let Some(x) = r.per_direction_stores {
                s.per_direction_stores = x;
            }
            if let Some(x) = r.turbid_subfaces {
                s.tracking.turbid_subfaces = x;
            }
            if let Some(x) = r.turbid_exit_grouping {
                s.tracking.turbid_exit_grouping = x;
            }
            s.image_oversampling = r.image_oversampling.max(1);
        }
        s
    }
}

/// The discrete directions of the scene (Direction stage).
#[derive(Debug, Clone, Resource)]
pub struct Directions {
    /// The set.
    pub set: DirectionSet,
    /// Propagation vector of the direct sun beam (downward, exact).
    pub sun: DVec3,
    /// Interception slot of each tiling direction.
    pub sector_of: Vec<u16>,
    /// Number of interception slots for tiling directions (the exact sun has one more).
    pub n_sectors: usize,
}

/// Optics of every material as the tracker needs it (Phase stage).
#[derive(Debug, Clone, Resource)]
pub struct OpticsTables {
    /// Per material id.
    pub optics: Vec<TrackOptics>,
    /// Bytes held by the phase tables.
    pub bytes: usize,
    /// Largest relative row renormalisation (sector-integration error of the tables).
    pub max_renormalisation: f64,
}

/// Exact Lambertian fractions per facet (front, back), computed when facets exist.
#[derive(Debug, Clone, Default, Resource)]
pub struct FacetFractions(pub Vec<(Vec<f32>, Vec<f32>)>);
