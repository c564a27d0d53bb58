//! The Output engine: product writers of the stages that ran (DART 5 paper §2; the output
//! contract of docs/user-guide.md). Every file is written atomically (temporary file + rename,
//! [`crate::io::atomic`]), so no half-written product is ever left behind. The LiDAR products
//! are written by [`crate::lidar::products`]. The ECS glue that calls these writers is
//! `systems/output.rs`.

pub mod geo;
pub mod maket;
pub mod radiative;
pub mod sensors;
