//! Pure physics: formulas with their sources and units, no ECS.
pub mod prospect;
pub mod spectral;
pub mod sun;
