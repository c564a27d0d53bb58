//! Input/output: atomic writes, EXR products, mesh import.

pub mod atomic;
pub mod csv_text;
pub mod exr_out;
pub mod las_out;
pub mod leaf_list;
pub mod mesh;
pub mod rami_mes;
