//! Resources: world data shared between stages.

pub mod atmosphere;
pub mod facets;
pub mod grid;
pub mod lidar;
pub mod maket_report;
pub mod materials;
pub mod memory;
pub mod scene;
pub mod sensors;
pub mod tracking;
