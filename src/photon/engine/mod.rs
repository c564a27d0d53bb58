//! Forward Monte Carlo photon tracking (DART 5 paper §4, "Ray-Carlo"; Gastellu-Etchegorry et
//! al. 2016, *Remote Sens. Environ.* 184: eqs. 1–3) over the Radiative stage's scene
//! representation: turbid cells (exact free paths), facets (found per cell), the flat ground, DEM
//! facets and the repetitive / isolated boundaries.
//!
//! This module is a plain engine over flat arrays (no ECS): [`PhotonInput`] in,
//! [`PhotonResult`] out.
//!
//! * **Photons** are weighted packets carrying one weight per band (W). Geometry (free paths,
//!   scattering directions) is shared by all bands; band-dependent probabilities are handled by
//!   importance reweighting: an outcome `k` with per-band probabilities `p_b(k)` is drawn with
//!   `q(k) ∝ Σ_b w_b p_b(k)` and every band weight becomes `w_b p_b(k)/q(k)` — unbiased for each
//!   band (E[w'_b] = w_b Σ_k p_b(k)). What a photon loses at an event is booked as absorbed
//!   there (`w_b − w'_b`), so per-band energy closes *exactly* in every realisation (the booked
//!   absorption is an unbiased estimate, and can be negative for one event in a minority band).
//! * **Free paths** in turbid cells are exact: `τ* = −ln ξ`, accumulated over the DDA segments
//!   with `k = Σ_m G_m(Ω) u_m` (+ fluid extinction), physics.md §9.2. Fluids with band-dependent
//!   extinction use the largest band extinction as the sampling majorant and a per-band
//!   real/null-collision reweighting (delta tracking, Woodcock 1965; unbiased).
//! * **Scattering directions**: continuous mode samples the exact leaf kernel (physics.md
//!   §3.3), Lambertian cosine lobes, the fluid phase functions and tabulated BRDF importance
//!   sampling; discrete mode (DART's Ray-Carlo) draws turbid scattering among the discrete
//!   directions from the Phase tables with an alias or Box table per incident row, and snaps
//!   surface scattering to the containing discrete sector.
//! * **Peel-off** (local estimate, Ray-Carlo eqs. 1–2): at every scattering event the intensity
//!   scattered toward each requested view direction, attenuated to the top of the scene, is
//!   tallied — exact phase value in continuous mode, the containing sector's tabulated value in
//!   discrete mode. BRFs in the view directions come from these tallies; every other discrete
//!   direction gets the escape-counting sector mean.
//! * **Russian roulette** on the relative weight (weight window: survive with probability
//!   `r/r_min`, weights scaled up by `r_min/r`), its balance kept as a separate account
//!   (expectation 0) so that closure stays exact.
//! * **Determinism**: photons run in a fixed number of batches, each with its own
//!   `Xoshiro256PlusPlus` stream from (scene seed, batch index); batch tallies are merged in batch
//!   order, so results are bit-identical on any number of threads. The spread of the batch
//!   estimates gives the standard errors.
//!
//! Modules, in the order a photon meets them:
//!
//! * [`atmosphere`]: the plane-parallel atmosphere over the scene (TOA launch, flights,
//!   collisions, peel-off to the TOA).
//! * [`input`]: what the engine takes (optics, fluids, parameters, discrete-direction rows);
//!   [`result`]: what it returns (tallies per batch, standard errors).
//! * `context`: the shared tracking context (`Ctx`), the photon state and the
//!   per-cell facet boxes and column sums built once per run.
//! * `walk`: free paths through the cell grid, facet hits, boundaries and transmittance rays.
//! * `peel_off`: peel-off (local estimate) toward the views or a LiDAR receiver; `camera`:
//!   toward the pixels of frame cameras (sensor stage).
//! * `flight` and `scores`: receiver-mode flights whose return is scored along the walk.
//! * `events`: band-weighted event choice, Russian roulette, BRDF events, far-photon
//!   roulette.
//! * `trace`: one photon's history from its entry to its escape, loss or death.
//! * `passive`: the passive (sun and sky) run over seeded batches; [`emission`]: the thermal
//!   emission photons of a thermal run (issue #34).
//! * `tally`: per-batch accumulators and the receiver tally interface (`ReturnTally`)
//!   that the LiDAR pulse tracking (`lidar::tracking`, which depends on this engine, never the
//!   reverse) books its waveforms through.

pub mod atmosphere;
pub(crate) mod camera;
pub(crate) mod context;
pub mod emission;
pub(crate) mod events;
pub(crate) mod flight;
pub mod input;
pub(crate) mod passive;
pub(crate) mod peel_off;
pub mod result;
pub(crate) mod scores;
pub(crate) mod tally;
#[cfg(test)]
mod tests;
pub(crate) mod trace;
pub(crate) mod walk;

pub use atmosphere::PhotonAtmosphere;
#[cfg(debug_assertions)]
pub use context::COLUMN_RETURNS;
pub use context::Receiver;
pub use emission::THERMAL_STREAM;
pub use events::FAR_ROULETTE_CELLS;
pub use input::{
    DiscreteRows, FluidField, FluidMaterial, PhotonInput, PhotonOptics, PhotonParams, RowSampler,
    SamplerKind,
};
pub use passive::{PHOTON_STREAM, run};
pub use result::{PhotonResult, Summary, sum_standard_error};
