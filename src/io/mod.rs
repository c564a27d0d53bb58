//! Input/output: atomic writes, EXR products, GeoTIFF and ENVI rasters, mesh import, progress
//! bars.

pub mod atomic;
pub mod csv_text;
pub mod envi;
pub mod exr_out;
pub mod geotiff;
pub mod las_out;
pub mod leaf_list;
pub mod mesh;
pub mod progress;
pub mod rami_mes;
