//! LiDAR (DART 5 paper §4, "Ray-Carlo"; physics.md §9). LiDAR builds on the photon engine
//! ([`crate::photon::engine`]), never the reverse.
//!
//! * [`tracking`]: the pulse tracking in receiver mode — each pulse's beam rays traced by the
//!   photon engine, every return (energy in J, total path length in m, scattering order) booked
//!   into a [`waveform::WaveformBinner`]; [`simulate`]: a whole instrument's pulses, by chunks,
//!   through tracking, convolution, returns and photon counting.
//!
//! Everything after the binner does not depend on the photon engine:
//!
//! * [`pulse`]: emitted pulse in time ([`pulse::PulseShape`], Gaussian, truncated) and space
//!   ([`pulse::FootprintProfile`], Gaussian beam; footprint radius from divergence; oblique
//!   footprint ellipse; truncated footprint sampling) — physics.md §9.1.
//! * [`waveform`]: path-length binning with out-of-gate accounting, area-preserving convolution
//!   with the pulse and receiver response, the analytic first-order waveform of a turbid canopy
//!   over a Lambertian ground in its two variants (independent and hotspot-correlated gaps), and the
//!   bare-ground return — physics.md §9.4, §9.6, §13 item 12.
//! * [`returns`]: discrete returns by peak detection and Gaussian decomposition
//!   (Levenberg–Marquardt on bin-integrated Gaussians).
//! * [`photon_counting`]: detector model, mean signal and solar background counts, exact Poisson
//!   draws and sequential dead-time simulation for single-photon LiDAR — physics.md §9.5.
//! * [`waveform_io`]: compact waveform products (little-endian f32 binary + CSV index) and SVG
//!   quick-looks.
//! * [`run`]: the results of an instrument ([`run::LidarRun`]) and of the stage
//!   ([`run::LidarProducts`]).
//! * [`spool`]: per-pulse results of a streamed scan in temporary files (memory bounded by a
//!   chunk).
//! * [`special`]: erf/erfc and log-factorial used by the above.
//!
//! Energies are `f64` joules everywhere: single packets of 1e-13 J (GLAS-like geometry) are far
//! from the f64 underflow limit and survive binning, convolution and counting.
//!
//! Point clouds are written by [`crate::io::las_out`] (LAS 1.4, point formats 6 and 7).

pub mod photon_counting;
pub mod products;
pub mod pulse;
pub mod returns;
pub mod run;
pub mod simulate;
pub mod special;
pub mod spool;
pub mod tracking;
pub mod waveform;
pub mod waveform_io;

/// Speed of light in vacuum (m s⁻¹, exact SI; physics.md §0).
pub const SPEED_OF_LIGHT_M_PER_S: f64 = 299_792_458.0;

/// Planck constant (J s, exact SI; physics.md §0).
pub const PLANCK_J_S: f64 = 6.626_070_15e-34;

/// Errors of the LiDAR building blocks: every message names the offending parameter or file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LidarError {
    /// A scalar parameter is out of its valid range (NaN, infinite, negative, zero...).
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name, with its unit suffix.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// What the valid range is.
        reason: &'static str,
    },
    /// A data array is unusable (wrong length, NaN or negative entries...).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A product could not be written or read; the message starts with the file name.
    #[error("{0}")]
    Io(String),
}

/// Checks that `value` is finite and strictly positive.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<f64, LidarError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(LidarError::InvalidParameter {
            name,
            value,
            reason: "must be finite and > 0",
        })
    }
}

/// Checks that `value` is finite and non-negative.
pub(crate) fn check_non_negative(name: &'static str, value: f64) -> Result<f64, LidarError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(LidarError::InvalidParameter {
            name,
            value,
            reason: "must be finite and >= 0",
        })
    }
}

/// Checks that `value` lies in [0, 1].
pub(crate) fn check_unit_interval(name: &'static str, value: f64) -> Result<f64, LidarError> {
    if (0.0..=1.0).contains(&value) {
        Ok(value)
    } else {
        Err(LidarError::InvalidParameter {
            name,
            value,
            reason: "must lie in [0, 1]",
        })
    }
}

/// Neumaier (improved Kahan) compensated sum of a slice: the error does not grow with the
/// number of terms (Neumaier 1974, *ZAMM* 54:39), so sums over many tiny weights stay exact to
/// a few ulps.
pub fn compensated_sum(values: &[f64]) -> f64 {
    let mut acc = NeumaierSum::default();
    for &v in values {
        acc.add(v);
    }
    acc.value()
}

/// Running Neumaier compensated sum (Neumaier 1974).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NeumaierSum {
    sum: f64,
    compensation: f64,
}

impl NeumaierSum {
    /// Adds one term.
    #[inline]
    pub fn add(&mut self, x: f64) {
        let t = self.sum + x;
        if self.sum.abs() >= x.abs() {
            self.compensation += (self.sum - t) + x;
        } else {
            self.compensation += (x - t) + self.sum;
        }
        self.sum = t;
    }

    /// Adds another running sum (used to merge per-thread tallies).
    #[inline]
    pub fn merge(&mut self, other: &NeumaierSum) {
        self.add(other.sum);
        self.add(other.compensation);
    }

    /// The compensated value.
    #[inline]
    pub fn value(&self) -> f64 {
        self.sum + self.compensation
    }
}

/// Memory the LiDAR simulation of one instrument holds at its peak, bytes, as named terms:
///
/// * `photon context`: the photon engine's per-cell tables (as for the passive Monte Carlo
///   solver: the facet bounding box per cell, 6 f64, and the column tables of the first-flight
///   sampler, two f64 per cell and turbid material and one flag per cell, when cells × turbid
///   materials ≤ 2²³).
/// * `pulse chunk`: the results of one chunk of pulses (at most `chunk_pulses`, see
///   [`simulate::LidarChunks`]) held until it is written or spooled: per pulse the waveform,
///   one f64 per digitiser bin over the two-way travel time through the grid's height plus the
///   pulse kernel (±3 FWHM), and ~256 bytes of records (energies, returns).
/// * `footprint moments`: the beam footprint's rectangle-moment table
///   ([`pulse::FootprintMoments`], kept in a process-wide cache): per radial interval (at least
///   `MOMENT_SPLIT` = 6; 8 on the example instruments, whose footprints have two profile
///   nodes) `MOMENT_CELLS`² cells of 32 f64.
///
/// `grid_height_m` is the grid's height, `n_cells` its cells, `turbid_materials` the scene's
/// turbid materials, `facet_refs` its facet references.
pub fn memory_terms(
    desc: &crate::scene::desc::LidarDesc,
    n_cells: usize,
    turbid_materials: usize,
    grid_height_m: f64,
    chunk_pulses: usize,
    facet_refs: usize,
) -> Vec<(&'static str, f64)> {
    let f = |x: usize| x as f64;
    let context = crate::photon::context_bytes(n_cells, turbid_materials, facet_refs);
    let pulses = simulate::PulsePlan::new(desc)
        .len()
        .min(chunk_pulses.max(1));
    // Light travels 0.15 m (two-way) per ns.
    let bin_ns = if desc.bin_ns > 0.0 { desc.bin_ns } else { 1.0 };
    let bins = (grid_height_m.max(0.0) / 0.15 + 6.0 * desc.pulse_fwhm_ns.max(0.0)) / bin_ns;
    let per_pulse = 8.0 * bins.min(1e9) + 256.0;
    let intervals = pulse::moments::MOMENT_SPLIT + 2.0;
    let cells = f(pulse::moments::MOMENT_CELLS).powi(2);
    vec![
        ("photon context", context),
        ("pulse chunk", f(pulses) * per_pulse),
        ("footprint moments", intervals * cells * 32.0 * 8.0),
    ]
}
