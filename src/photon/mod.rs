//! Photon stage (DART 5 paper §4, "Ray-Carlo"): forward Monte Carlo photon tracking over the
//! same scene representation as the Radiative stage (turbid cells, facets, ground, boundaries).
//!
//! * [`sampling`]: scattering-direction samplers — discrete (Walker/Vose alias tables and DART's
//!   Box method over the discrete directions) and continuous (exact leaf, fluid and surface
//!   phase functions).
//! * [`engine`]: the photon tracker (free paths, events, peel-off, roulette, seeded batches).
//! * [`material_optics`]: the Monte Carlo optics of every material (LAD samplers shared per LAD).
//! * [`products`]: the Radiative stage's products with standard errors.
//! * [`small`]: inline short arrays (no allocation per scattering event).

pub mod engine;
pub mod material_optics;
pub mod products;
pub mod sampling;
pub mod small;
