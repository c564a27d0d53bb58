//! Geometry: polygons, triangles, crown shapes and their cell overlaps, terrain, facet shapes,
//! the pinhole camera model.

pub mod camera;
pub mod crown;
pub mod facet_packs;
pub mod polygon;
pub mod quadrature;
pub mod shapes;
pub mod terrain;
pub mod triangle;
