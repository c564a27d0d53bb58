//! Authoring types of the LiDAR instruments (`lidars` in a scene; DART 5 paper §4): the
//! instrument, its estimator and sampler, beam profile, returns method, platform and pulse
//! pattern, photon counting. Re-exported by [`crate::scene::desc`].

use super::*;

pub(crate) fn default_edge_intensity() -> f64 {
    0.368
}
fn default_pulse_energy() -> f64 {
    1.0
}
fn default_fwhm_ns() -> f64 {
    4.0
}
fn default_aperture() -> f64 {
    0.1
}
fn default_bin_ns() -> f64 {
    1.0
}
/// Default photons (beam rays) per LiDAR pulse whose first-order return the column quadrature
/// scores (see [`LidarDesc::photons_per_pulse`]).
pub const DEFAULT_LIDAR_PHOTONS: u32 = 48;

/// Default photons (beam rays) per LiDAR pulse that scores its first-order return per beam
/// ray (oblique and terrestrial beams, footprints over more grid columns than beam rays; see
/// [`LidarDesc::photons_per_pulse`]).
pub const DEFAULT_LIDAR_PHOTONS_PER_RAY: u32 = 72;
fn default_lidar_order() -> u32 {
    100
}
fn default_gate_m() -> f64 {
    10.0
}

/// A LiDAR instrument (monostatic: receiver at the emitter). Defaults follow DART's XSD where
/// it has one (edge intensity 0.368, pulse energy 1 J, aperture 0.1 m², 1 ns bins).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LidarDesc {
    /// Name (products go to `DIR/lidar/<name>/`).
    pub name: String,
    /// The scene band whose optical properties the laser sees.
    pub band: String,
    /// Where the instrument is and where its pulses go.
    pub platform: LidarPlatform,
    /// Beam footprint radius at the reference range (airborne: at z = 0; terrestrial: 1 m), m,
    /// where the Gaussian profile has fallen to `edge_intensity`.
    #[serde(default)]
    pub footprint_radius_m: Option<f64>,
    /// Alternatively the full beam divergence, mrad (radius = range · tan(divergence/2)).
    #[serde(default)]
    pub divergence_mrad: Option<f64>,
    /// Relative intensity at the footprint edge (DART `gaussian_sigma_illu`, default 0.368).
    #[serde(default = "default_edge_intensity")]
    pub edge_intensity: f64,
    /// Receiver field of view: radius at the reference range, m (default: 3 × the footprint
    /// radius, which sees the whole truncated footprint).
    #[serde(default)]
    pub fov_radius_m: Option<f64>,
    /// Pulse energy, J (results scale linearly; default 1).
    #[serde(default = "default_pulse_energy")]
    pub pulse_energy_j: f64,
    /// Gaussian pulse FWHM, ns (default 4).
    #[serde(default = "default_fwhm_ns")]
    pub pulse_fwhm_ns: f64,
    /// Receiver aperture area, m² (DART `sensorArea`, default 0.1).
    #[serde(default = "default_aperture")]
    pub aperture_m2: f64,
    /// Digitiser bin, ns (default 1).
    #[serde(default = "default_bin_ns")]
    pub bin_ns: f64,
    /// Photons (beam rays) per pulse, for every pulse. Default (absent): chosen per pulse for
    /// the same waveform error, ~1.0 % on the forest ALS bench (docs/performance.md, LiDAR) — 48
    /// ([`DEFAULT_LIDAR_PHOTONS`]) for a pulse whose first-order return the column quadrature
    /// of the `ExpectedValue` estimator scores (exactly vertical from above the grid, see
    /// `FirstOrderColumns`), 72 ([`DEFAULT_LIDAR_PHOTONS_PER_RAY`]) for a pulse that scores it
    /// per beam ray (oblique or terrestrial beams, footprints over more columns than beam
    /// rays, the other estimators): 48 rays there give 1.29 %. With the `ExpectedValue`
    /// estimator and the first free paths on a golden-ratio sequence, those counts match the
    /// error of the former defaults (1000 photons of `Legacy`, 600 of `Stratified`) at ~1/17
    /// and 1/10 of their instructions. Tuned on that forest (flat ground, 0.3 m footprint over
    /// 1 m cells); scenes whose returns differ in kind (e.g. BRDF surfaces, which keep the
    /// collision estimator) may need another count for that error, and so do footprints over
    /// many grid columns, whose returns differ from column to column: the GEDI example
    /// (`assets/scenes/lidar_gedi.ron`, 12.5 m over 1 m cells, against 200,000 rays) has a
    /// 15 % waveform error at the default, 9.4 % at 200 rays, 4.4 % at 1000 and 2.1 % at 5000
    /// (∝ 1/√rays, mostly multiple scattering); a footprint wider than 2 cells without this
    /// field gets a warning in the run's notes.
    #[serde(default)]
    pub photons_per_pulse: Option<u32>,
    /// Scattering orders traced (default 100).
    #[serde(default = "default_lidar_order")]
    pub max_order: u32,
    /// Range recorded beyond the farthest scene point (two-way gate margin), m (default 10).
    #[serde(default = "default_gate_m")]
    pub gate_margin_m: f64,
    /// Photon-counting detector (ICESat-2-like); absent: waveform LiDAR.
    #[serde(default)]
    pub photon_counting: Option<PhotonCountingDesc>,
    /// Transverse beam profile over ρ/R (DART 5 paper §4: any angular distribution):
    /// `Gaussian(edge_intensity: ..)`, `Uniform`, `Tabulated(points: [(ρ/R, I), ..])`;
    /// default: Gaussian with `edge_intensity`.
    #[serde(default)]
    pub beam: Option<BeamProfile>,
    /// How discrete returns are extracted from each waveform (default: Gaussian
    /// decomposition; `PeakDetection` costs ~3 µs per waveform against 8–25 ms for the
    /// decomposition of a 1000-photon Monte Carlo waveform, and resolves returns ≥ 3σ apart).
    #[serde(default)]
    pub returns: ReturnsMethod,
    /// Scattering-direction sampling of the photon tracking: `Discrete` (DART's Ray-Carlo over
    /// the discrete directions, default) or `Continuous` (exact phase functions).
    #[serde(default)]
    pub sampler: LidarSampler,
    /// Estimator of the photon tracking (default `ExpectedValue`; see [`LidarEstimator`]).
    #[serde(default)]
    pub estimator: LidarEstimator,
    /// `ExpectedValue` and `Stratified` estimators: how many of the `photons_per_pulse` beam
    /// rays go on, on average, past their first interaction into multiple scattering (Russian
    /// roulette with survival `scattering/photons`, weights divided by it: unbiased). Default:
    /// all of them; at most `photons_per_pulse` (at most 48 when that is absent). Ignored by
    /// `Legacy`.
    #[serde(default)]
    pub scattering_photons_per_pulse: Option<u32>,
    /// Fusion product (DART 5 paper §6, Figure 19): attach the passive spectral radiance of the
    /// co-registered orthographic image to every discrete return (`fusion.las`, LAS point
    /// format 7, RGB from the first three bands and one extra-bytes value per band). Asks for
    /// the passive run (default false: a LiDAR-only scene runs no flux tracking).
    #[serde(default)]
    pub fusion: bool,
}

impl LidarDesc {
    /// Whether this instrument needs the passive solver's radiance: the fusion product, or
    /// the solar background of a photon-counting detector.
    pub fn needs_passive(&self) -> bool {
        self.fusion || self.photon_counting.is_some()
    }
}

/// Estimator of a LiDAR's photon tracking (physics.md §9.2; DART 5 paper §4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum LidarEstimator {
    /// `Stratified` for the first flight, whose walk also scores the first-order return of a
    /// Lambertian flat ground it reaches, or a Lambertian facet it ends on, with its
    /// transmittance e^{−τ} (instead of at the surface collision only); every later flight is walked once for its collision and the
    /// expected-value return toward the receiver along it (one point per crossed vegetation
    /// cell, the walk going on past the collision to twice its optical depth, a Lambertian
    /// ground reached scored the same way), instead of the collision estimator. On the forest
    /// ALS bench: first-order error ÷ 3.5, multiple-scattering variance ÷ ~4 at ~1.3× the
    /// instructions per continued ray (README of 4df2100, LiDAR speed against error).
    #[default]
    ExpectedValue,
    /// Beam rays on a randomly shifted low-discrepancy (R2) lattice over the footprint; the
    /// first flight is walked once, sampling its collision and the expected-value first-order
    /// return together, the latter integrated bin by bin (one stratified point per digitiser
    /// bin of each crossed vegetation cell, exact-backscatter leaf intensity); later orders use
    /// the collision estimator for `scattering_photons_per_pulse` of the rays.
    Stratified,
    /// The estimator before 2026-11-26: independent beam rays, one forced point per crossed
    /// vegetation cell (one-leaf intensity with a sampled normal), a second walk of the first
    /// flight for its collision, every photon continued. Kept as the reference of the tests.
    Legacy,
}

/// Scattering-direction sampling of a LiDAR's photon tracking (DART 5 paper §4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum LidarSampler {
    /// DART's Ray-Carlo: multiple scattering along the discrete directions (alias tables over
    /// the Phase-stage rows); the pulse itself and every receiver peel-off keep their exact
    /// directions.
    #[default]
    Discrete,
    /// Exact continuous phase functions.
    Continuous,
}

/// DART's default `gaussian_sigma_illu`: relative intensity at the footprint edge (≈ 1/e).
pub const DART_EDGE_RELATIVE_INTENSITY: f64 = 0.368;

/// Default of [`BeamProfile::Gaussian`]'s `edge_intensity` in scene files (DART's
/// `gaussian_sigma_illu`, 0.368).
fn default_beam_edge_intensity() -> f64 {
    DART_EDGE_RELATIVE_INTENSITY
}

/// Transverse (radial) intensity profile of the emitted beam, independent of its size.
///
/// DART 5 paper §4: "Photons launched within ΔΩ_footprint can have any angular distribution
/// (e.g., Gaussian)". The profile is stated as relative intensity (irradiance on the plane normal
/// to the beam axis at the reference range) against the **normalised radius** `x = ρ/R`, R being
/// the nominal footprint radius at that range (from `footprint_radius_m` or the divergence,
/// physics.md §9.1). Because packets leave the emitter along `axis·H + offset`, an off-axis angle α
/// maps to `x = tan α / tan α_half` (α_half = half divergence). To use a table measured against
/// the angle, `I(α)` in W sr⁻¹, take `x = tan α/tan α_half` and intensity `I(α) cos³α`; for
/// α_half ≤ 10 mrad, `x = α/α_half` and `I(α)` unchanged are exact to < 1.5e-4 relative.
///
/// Serialises as a RON/serde enum like the scene `*Desc` types, e.g. `Gaussian(edge_intensity:
/// 0.368)`, `Uniform`, `Tabulated(points: [(0.0, 1.0), (0.8, 1.0), (1.0, 0.0)])`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum BeamProfile {
    /// Gaussian `I(x) = exp(−x²/(2s²))`, `s = 1/√(−2 ln edge_intensity)` (physics.md §9.1,
    /// DART `gaussian_sigma_illu`); unbounded, so the sampler's truncation radius matters.
    Gaussian {
        /// Relative intensity at the footprint edge x = 1, in (0, 1) (default 0.368 ≈ 1/e).
        #[serde(default = "default_beam_edge_intensity")]
        edge_intensity: f64,
    },
    /// Top hat: constant intensity for x ≤ 1, zero beyond.
    Uniform,
    /// Piecewise-linear relative intensity through `points = [(x_i, I_i)]`, `x_i = ρ/R`
    /// strictly increasing from `x_0 ≥ 0`, `I_i` finite and ≥ 0, not all zero, at least two
    /// points. The intensity is zero for `x < x_0` (an annular beam if `x_0 > 0`) and for
    /// `x > x_last`; the table may extend beyond x = 1. Only the shape matters (the scale of
    /// `I_i` is irrelevant).
    Tabulated {
        /// `(normalised radius ρ/R, relative intensity)` nodes.
        points: Vec<(f64, f64)>,
    },
}

impl Default for BeamProfile {
    /// DART's default beam: Gaussian with edge intensity 0.368.
    fn default() -> Self {
        BeamProfile::Gaussian {
            edge_intensity: DART_EDGE_RELATIVE_INTENSITY,
        }
    }
}

impl BeamProfile {
    /// Short name for logs: `"Gaussian"`, `"uniform"` or `"tabulated"`.
    pub fn name(&self) -> &'static str {
        match self {
            BeamProfile::Gaussian { .. } => "Gaussian",
            BeamProfile::Uniform => "uniform",
            BeamProfile::Tabulated { .. } => "tabulated",
        }
    }

    /// Checks the profile's own parameters: the Gaussian's edge intensity in (0, 1); the rules
    /// of [`BeamProfile::Tabulated`] (at least two points, finite radii from x₀ ≥ 0 strictly
    /// increasing, finite intensities ≥ 0 not all zero) and a finite, positive energy
    /// `∫ I(x) x dx` (the radii neither overflow nor underflow it). The message names the
    /// offending parameter or table point. The LiDAR's sampler table
    /// (`lidar::pulse::sampler::RadialTable`) starts with this check.
    pub fn check(&self) -> Result<(), String> {
        match self {
            &BeamProfile::Gaussian { edge_intensity: s } => {
                if s > 0.0 && s < 1.0 {
                    Ok(())
                } else {
                    Err(format!("edge_intensity = {s}: must lie in (0, 1)"))
                }
            }
            BeamProfile::Uniform => Ok(()),
            BeamProfile::Tabulated { points } => Self::check_table(points),
        }
    }

    /// The table rules of [`BeamProfile::check`] on the `points` of a
    /// [`BeamProfile::Tabulated`]. The energy is summed over the segments as the
    /// exact integral of the linear intensity times x, `(h/3)(c₀ + c₁ + c₂)` with the Bernstein
    /// coefficients `c = (I_a a, (I_a b + I_b a)/2, I_b b)` of the intensities over their maximum
    /// (the terms of the sampler's cumulative table).
    pub fn check_table(points: &[(f64, f64)]) -> Result<(), String> {
        let bad = |i: usize, msg: &str| {
            format!(
                "beam profile table: point {i} ({}, {}): {msg}",
                points[i].0, points[i].1
            )
        };
        if points.len() < 2 {
            return Err(format!(
                "beam profile table: needs at least 2 points (normalised radius, intensity), got {}",
                points.len()
            ));
        }
        let mut max_i: f64 = 0.0;
        for (i, &(x, v)) in points.iter().enumerate() {
            if !x.is_finite() {
                return Err(bad(i, "normalised radius must be finite"));
            }
            if i == 0 && x < 0.0 {
                return Err(bad(i, "normalised radius must be >= 0"));
            }
            if i > 0 && !(x > points[i - 1].0) {
                return Err(bad(
                    i,
                    "normalised radii must be strictly increasing (this one is not greater than the previous one)",
                ));
            }
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(i, "relative intensity must be finite and >= 0"));
            }
            max_i = max_i.max(v);
        }
        if !(max_i > 0.0) {
            return Err(
                "beam profile table: all intensities are zero (the beam carries no energy)".into(),
            );
        }
        let total: f64 = points
            .windows(2)
            .map(|s| {
                let ((a, ia), (b, ib)) = (s[0], s[1]);
                let (ia, ib) = (ia / max_i, ib / max_i);
                (b - a) / 3.0 * (ia * a + 0.5 * (ia * b + ib * a) + ib * b)
            })
            .sum();
        if !(total.is_finite() && total > 0.0) {
            return Err(format!(
                "beam profile table: total energy {total:e} is not finite and > 0 (normalised radii out of range?)"
            ));
        }
        Ok(())
    }
}

/// How discrete returns are extracted from a waveform (scene files: `GaussianDecomposition`
/// or `PeakDetection`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ReturnsMethod {
    /// Levenberg–Marquardt decomposition into bin-integrated Gaussians
    /// ([`detect_returns_with`](crate::lidar::returns::detect_returns_with)): the reference;
    /// separates overlapping returns and adds components where the residual exceeds the floor.
    /// ~60 µs per 400-bin waveform with 3–6 clean returns, 7–25 ms when noise makes it fit
    /// 10–15 components.
    #[default]
    GaussianDecomposition,
    /// Prominent local maxima with interpolated centre, half-maximum width and valley-split
    /// energy ([`detect_peaks`](crate::lidar::returns::detect_peaks)): O(n_bins), 2.5–4.5 µs
    /// per 400-bin waveform. Returns closer than 2.5σ (equal) to 3σ (1 : 0.5) are seen as one;
    /// see [`detect_peaks`](crate::lidar::returns::detect_peaks) for the biases.
    PeakDetection,
}

/// Platform and pulse pattern of a LiDAR.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum LidarPlatform {
    /// Airborne or spaceborne: the sensor flies at `altitude_m` (above z = 0) and looks along
    /// the view direction (zenith/azimuth of the ground→sensor direction); each pulse is aimed
    /// at a footprint centre on the plane z = 0.
    Airborne {
        /// Sensor altitude above z = 0, m (GLAS: 600 000).
        altitude_m: f64,
        /// View zenith (ground→sensor), degrees (0: nadir).
        #[serde(default)]
        view_zenith_deg: f64,
        /// View azimuth (ground→sensor), degrees.
        #[serde(default)]
        view_azimuth_deg: f64,
        /// Footprint centres.
        pulses: PulsePattern,
    },
    /// Terrestrial scanner inside the scene: an angular grid of pulse directions.
    Terrestrial {
        /// Scanner position, m.
        position_m: (f64, f64, f64),
        /// Zenith angles of the pulse directions (ground→target... i.e. propagation zenith
        /// measured from +z): (first, last, step), degrees.
        zenith_deg: (f64, f64, f64),
        /// Azimuths: (first, last, step), degrees.
        azimuth_deg: (f64, f64, f64),
    },
}

/// Footprint centres of airborne pulses (on the plane z = 0), within 100 scene sizes of the
/// scene (x in [−100 X, 101 X], y in [−100 Y, 101 Y]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum PulsePattern {
    /// One pulse.
    Single((f64, f64)),
    /// An explicit list.
    List(Vec<(f64, f64)>),
    /// Parallel flight lines: the first from `start` to `end`, the others offset to the left
    /// by `line_spacing_m`; pulses every `pulse_spacing_m` along each line.
    Scan {
        /// First line start, m.
        start: (f64, f64),
        /// First line end, m.
        end: (f64, f64),
        /// Number of lines.
        lines: u32,
        /// Spacing between lines, m.
        line_spacing_m: f64,
        /// Spacing between pulses along a line, m.
        pulse_spacing_m: f64,
    },
}

/// Photon-counting detector (physics.md §9.5; DART XSD defaults).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhotonCountingDesc {
    /// Quantum efficiency (DART `quantEff`, default 0.15).
    #[serde(default = "default_qe")]
    pub quantum_efficiency: f64,
    /// Dead time, ns (default 2.5).
    #[serde(default = "default_dead")]
    pub dead_time_ns: f64,
    /// Dark count rate, Hz (default 100).
    #[serde(default = "default_dark")]
    pub dark_count_hz: f64,
    /// Receiver filter bandwidth, nm (default 0.03, ATLAS-like).
    #[serde(default = "default_filter")]
    pub filter_bandwidth_nm: f64,
    /// Laser wavelength, nm (photon energy).
    pub wavelength_nm: f64,
    /// Shots simulated per pulse position (default 1).
    #[serde(default = "default_shots")]
    pub shots: u32,
}

fn default_qe() -> f64 {
    0.15
}
fn default_dead() -> f64 {
    2.5
}
fn default_dark() -> f64 {
    100.0
}
fn default_filter() -> f64 {
    0.03
}
fn default_shots() -> u32 {
    1
}
