//! Pure physics: formulas with their sources and units, no ECS.
pub mod atmosphere;
pub mod brdf;
pub mod geodesy;
pub mod lad;
pub mod phase;
pub mod prospect;
pub mod spectral;
pub mod sun;
pub mod thermal;
