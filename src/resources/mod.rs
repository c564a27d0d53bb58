//! Resources: world data shared between stages.

pub mod facets;
pub mod grid;
pub mod lidar;
pub mod maket_report;
pub mod materials;
pub mod scene;
pub mod tracking;

// Transitional re-exports of the modules that moved to their stage folders.
pub use crate::direction as directions;
pub use crate::phase as phase_tables;
