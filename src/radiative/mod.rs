//! The Radiative stage's engine: DART flux tracking over the cell grid (see [`engine`]) and
//! the 3D digital differential analyser it walks the grid with ([`dda`]).

pub mod dda;
pub mod engine;
pub mod products;
