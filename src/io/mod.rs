//! Input/output: atomic writes, EXR products, mesh import, progress bars.

pub mod atomic;
pub mod csv_text;
pub mod exr_out;
pub mod las_out;
pub mod leaf_list;
pub mod mesh;
pub mod progress;
pub mod rami_mes;
