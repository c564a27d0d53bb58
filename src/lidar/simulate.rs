//! A LiDAR instrument run (DART 5 paper §4, Figs. 11–14; physics.md §9): pulse geometry from the
//! scene description, forward photon tracking of every pulse with peel-off to the monostatic
//! receiver ([`crate::lidar::tracking::run_lidar`]), convolution with the emitted pulse, discrete
//! returns, photon counting with solar background from the passive radiance, fusion with the
//! passive image.
//!
//! **Turbid cells and the return path.** The first-order return of a turbid material with a
//! leaf size l > 0 (`leaf_size_m`, DART `dimFoliar`) goes back through the gaps the pulse came
//! through (Kuusk 1985 correlation, [`crate::radiative::engine::hotspot_terms_path`]): for a
//! monostatic receiver the return path is then transmitted one way only, `e^{−G u r}` (physics.md
//! §9.6, second limit), as facet leaves are. With `leaf_size_m: 0` the cells are a pure turbid
//! medium with independent gaps (two-way `e^{−2G u r}`, first limit). Both limits are tested
//! against the analytic waveform; multiple-scattering returns are not correlated. The passive
//! solvers apply the same correlation to first-order sun radiation (the hotspot).

use crate::direction::direction_from_deg;
use crate::lidar::photon_counting::{
    Detector, mean_signal_counts, simulate_shot, solar_background_rate,
};
use crate::lidar::pulse::{BeamProfile, FootprintSampler, PulseKernel, PulseShape};
use crate::lidar::run::{CountedPhoton, LidarRun, PulseRecord, StreamedRun};
use crate::lidar::spool::{PulseEntry, Spool, spool_counted};
use crate::lidar::tracking::{Beam, Pulse, PulseResult, run_lidar_chunks};
use crate::lidar::waveform::{Waveform, WaveformBinner};
use crate::lidar::waveform_io::WaveformStream;
use crate::photon::engine::PhotonInput;
use crate::scene::desc::{
    DEFAULT_LIDAR_PHOTONS, DEFAULT_LIDAR_PHOTONS_PER_RAY, LidarDesc, LidarPlatform,
    PhotonCountingDesc, PulsePattern,
};
use glam::DVec3;

/// The run settings of the LiDAR chunks ([`crate::resources::scene::RunSettings`]).
pub use crate::resources::scene::{DEFAULT_CHUNK_PULSES, FarRoulette};

/// Passive spectral radiance at sensor level, per band, on the grid's columns (or one value
/// for the whole scene), W m⁻² sr⁻¹ µm⁻¹.
#[derive(Debug, Clone)]
pub struct PassiveRadiance {
    /// Columns along x and y (1 × 1: scene average).
    pub n: (usize, usize),
    /// Pixel size, m.
    pub cell: (f64, f64),
    /// `[band][i + nx·j]`.
    pub per_band: Vec<Vec<f64>>,
    /// Where it comes from (for products).
    pub source: String,
}

impl PassiveRadiance {
    /// Radiance of band `b` at (x, y) (periodic).
    pub fn at(&self, x: f64, y: f64, b: usize) -> f64 {
        let (nx, ny) = self.n;
        let i = ((x / self.cell.0).floor() as i64).rem_euclid(nx as i64) as usize;
        let j = ((y / self.cell.1).floor() as i64).rem_euclid(ny as i64) as usize;
        self.per_band[b][i + nx * j]
    }
}

/// Pulses of an instrument: (ID, emitter, axis) and the reference range at which footprint
/// offsets are defined. Airborne: emitter above the footprint centre on z = 0 along the view
/// direction; terrestrial: the scanner position, directions from the angular grid, reference
/// range 1 m. The whole list: a long scan is better generated on demand ([`PulsePlan`]).
pub fn pulses_of(desc: &LidarDesc) -> (Vec<Pulse>, f64) {
    let plan = PulsePlan::new(desc);
    (plan.iter().collect(), plan.reference_range_m)
}

/// The pulses of an instrument ([`pulses_of`]) generated on demand by index, so that a scan of
/// millions of pulses is never held in memory: pulse `i` is the same value as the `i`-th of
/// the list, bit for bit.
#[derive(Debug, Clone)]
pub struct PulsePlan<'a> {
    kind: PlanKind<'a>,
    /// Range at which the footprint offsets are defined (m).
    pub reference_range_m: f64,
}

#[derive(Debug, Clone)]
enum PlanKind<'a> {
    /// Emitters at `range` along `v` above footprint centres on z = 0.
    Airborne {
        v: DVec3,
        range: f64,
        centres: Centres<'a>,
    },
    /// Every azimuth for each zenith (degrees), from one position.
    Terrestrial {
        position: DVec3,
        zeniths: Vec<f64>,
        azimuths: Vec<f64>,
    },
}

#[derive(Debug, Clone)]
enum Centres<'a> {
    List(&'a [(f64, f64)]),
    /// `lines` parallel lines of `n` pulses from `start` along the unit vector `u`.
    Scan {
        start: (f64, f64),
        u: (f64, f64),
        n: usize,
        lines: usize,
        line_spacing_m: f64,
        pulse_spacing_m: f64,
    },
}

impl<'a> PulsePlan<'a> {
    /// The plan of `desc`'s platform.
    pub fn new(desc: &'a LidarDesc) -> Self {
        match &desc.platform {
            LidarPlatform::Airborne {
                altitude_m,
                view_zenith_deg,
                view_azimuth_deg,
                pulses,
            } => {
                let v = direction_from_deg(*view_zenith_deg, *view_azimuth_deg);
                let range = altitude_m / v.z;
                let centres = match pulses {
                    PulsePattern::Single(p) => Centres::List(std::slice::from_ref(p)),
                    PulsePattern::List(ps) => Centres::List(ps),
                    PulsePattern::Scan {
                        start,
                        end,
                        lines,
                        line_spacing_m,
                        pulse_spacing_m,
                    } => {
                        let (dx, dy) = (end.0 - start.0, end.1 - start.1);
                        let len = (dx * dx + dy * dy).sqrt();
                        let u = if len > 0.0 {
                            (dx / len, dy / len)
                        } else {
                            (1.0, 0.0)
                        };
                        Centres::Scan {
                            start: *start,
                            u,
                            n: (len / pulse_spacing_m + 1e-9).floor() as usize + 1,
                            lines: *lines as usize,
                            line_spacing_m: *line_spacing_m,
                            pulse_spacing_m: *pulse_spacing_m,
                        }
                    }
                };
                Self {
                    kind: PlanKind::Airborne { v, range, centres },
                    reference_range_m: range,
                }
            }
            LidarPlatform::Terrestrial {
                position_m,
                zenith_deg,
                azimuth_deg,
            } => {
                let steps = |(a, b, s): (f64, f64, f64)| -> Vec<f64> {
                    let n = ((b - a) / s + 1e-9).floor() as usize + 1;
                    (0..n).map(|k| a + k as f64 * s).collect()
                };
                Self {
                    kind: PlanKind::Terrestrial {
                        position: DVec3::new(position_m.0, position_m.1, position_m.2),
                        zeniths: steps(*zenith_deg),
                        azimuths: steps(*azimuth_deg),
                    },
                    reference_range_m: 1.0,
                }
            }
        }
    }

    /// Number of pulses.
    pub fn len(&self) -> usize {
        match &self.kind {
            PlanKind::Airborne { centres, .. } => match centres {
                Centres::List(ps) => ps.len(),
                Centres::Scan { n, lines, .. } => n * lines,
            },
            PlanKind::Terrestrial {
                zeniths, azimuths, ..
            } => zeniths.len() * azimuths.len(),
        }
    }

    /// Whether the plan has no pulse.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Pulse `i` (`i < len()`), ID `i`.
    pub fn get(&self, i: usize) -> Pulse {
        match &self.kind {
            PlanKind::Airborne { v, range, centres } => {
                let (x, y) = match centres {
                    Centres::List(ps) => ps[i],
                    Centres::Scan {
                        start,
                        u: (ux, uy),
                        n,
                        line_spacing_m,
                        pulse_spacing_m,
                        ..
                    } => {
                        let (l, k) = (i / n, i % n);
                        let off = l as f64 * line_spacing_m;
                        let s = k as f64 * pulse_spacing_m;
                        (start.0 + ux * s - uy * off, start.1 + uy * s + ux * off)
                    }
                };
                Pulse {
                    id: i as u64,
                    emitter: DVec3::new(x, y, 0.0) + *v * *range,
                    axis: -*v,
                }
            }
            PlanKind::Terrestrial {
                position,
                zeniths,
                azimuths,
            } => {
                let (z, a) = (zeniths[i / azimuths.len()], azimuths[i % azimuths.len()]);
                let (zr, ar) = (z.to_radians(), a.to_radians());
                Pulse {
                    id: i as u64,
                    emitter: *position,
                    axis: DVec3::new(zr.sin() * ar.cos(), zr.sin() * ar.sin(), zr.cos())
                        .normalize(),
                }
            }
        }
    }

    /// The pulses in order.
    pub fn iter(&self) -> impl Iterator<Item = Pulse> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }
}

/// Returns settings of the LiDAR pipeline (noise floor 1e-3 of the waveform's peak): up to 15
/// returns (the LAS limit); at most 200 Levenberg–Marquardt iterations per fit, a safety cap
/// that the fit's convergence tests pre-empt in 97–99 % of the fits of the forest bench.
pub fn pipeline_decomposition_settings() -> crate::lidar::returns::DecompositionSettings {
    crate::lidar::returns::DecompositionSettings {
        max_components: 15,
        max_iterations: 200,
        ..Default::default()
    }
}

/// Footprint centre of a pulse on the plane z = 0 (the emitter itself for upward beams), m.
fn footprint_centre(pl: &PulseRecord) -> (f64, f64) {
    let c = if pl.axis.z < 0.0 {
        pl.emitter + pl.axis * (pl.emitter.z / -pl.axis.z)
    } else {
        pl.emitter
    };
    (c.x, c.y)
}

/// How an instrument's pulses are run: by chunks, the waveforms of a long scan streamed to
/// disk while it runs when there is an output folder, with a progress bar if asked.
#[derive(Debug, Clone)]
pub struct LidarChunks {
    /// Pulses per chunk ([`DEFAULT_CHUNK_PULSES`] by default).
    pub chunk_pulses: usize,
    /// The instrument's product folder (`DIR/lidar/<name>`) when the run writes products: a
    /// scan of more pulses than one chunk is then streamed.
    pub stream_dir: Option<std::path::PathBuf>,
    /// A progress bar of the pulses on stderr (advanced per chunk).
    pub progress: bool,
    /// The far-photon roulette of the expected-value estimator
    /// ([`crate::lidar::tracking::Beam::far_roulette_m`]).
    pub far_roulette: FarRoulette,
    /// The expected-value estimator's column quadrature of the first-order return where it
    /// applies ([`crate::lidar::tracking::Beam::first_order_columns`]; default true).
    pub first_order_columns: bool,
}

impl Default for LidarChunks {
    fn default() -> Self {
        Self {
            chunk_pulses: DEFAULT_CHUNK_PULSES,
            stream_dir: None,
            progress: false,
            far_roulette: FarRoulette::Auto,
            first_order_columns: true,
        }
    }
}

/// Distance scale ρ₀ (m) of the expected-value estimator's far-photon roulette
/// ([`crate::lidar::tracking::Beam::far_roulette_m`]): the larger of
/// [`crate::photon::engine::FAR_ROULETTE_CELLS`] horizontal cell sizes and the mean free path
/// `1/k̄` in the vegetation, `k̄ = ½ ū_f` with `ū_f` the mean leaf-area density (m²/m³) of the
/// cells that hold turbid vegetation (½: the mean of G(Ω) over all directions, for every leaf
/// angle distribution). A survival scale below a mean free path costs variance: on the LAI-4
/// layer of the roulette's test (0.25 m cells, mean free path 1 m), ρ₀ = 0.5 m raises the
/// standard error of the multiple-scattering energy from 0.22 to 0.36 %, ρ₀ = 1, 2 or 4 m
/// leaves it at 0.20–0.22 %.
fn far_roulette_scale_m(input: &PhotonInput) -> f64 {
    let grid = input.grid;
    let (mut sum, mut cells) = (0.0, 0u64);
    for c in 0..grid.turbid_start.len().saturating_sub(1) {
        let e = grid.turbid_of(c);
        if !e.is_empty() {
            cells += 1;
            sum += e.iter().map(|e| e.density as f64).sum::<f64>();
        }
    }
    let cells_m =
        crate::photon::engine::FAR_ROULETTE_CELLS * input.spec.cell[0].max(input.spec.cell[1]);
    let mfp = if sum > 0.0 {
        cells as f64 / (0.5 * sum)
    } else {
        0.0
    };
    cells_m.max(mfp)
}

/// Footprint radius (in grid cells) above which a LiDAR without `photons_per_pulse` gets a
/// warning in its notes: the default beam-ray counts were tuned on a footprint of 0.3 cell.
const WIDE_FOOTPRINT_CELLS: f64 = 2.0;

/// Runs one instrument. `input` must carry the laser band's optics only (one band); `band` is
/// the scene band index (for the passive radiance); `box_lo`/`box_hi` the grid box (gate).
/// Pulses run by chunks of [`LidarChunks::chunk_pulses`]; with a `stream_dir` and more pulses
/// than one chunk, each chunk's waveforms are written to temporary files as soon as it is done
/// ([`LidarRun::streamed`]) and only the first quick-looks' waveforms stay in memory. The
/// products are the same bytes either way.
///
/// Steps: the beam's footprint (`beam_footprint`), the range gate (`range_gate`), the tracking
/// parameters (`beam`), the pulse kernel and the gate's time axis, the run's notes
/// (`run_notes`), then the pulses by chunks (`ScanOutputs::add_chunk`: waveforms and returns,
/// photon counting, fusion, streaming).
pub fn simulate_lidar(
    desc: &LidarDesc,
    band: usize,
    input: &PhotonInput,
    box_lo: DVec3,
    box_hi: DVec3,
    passive: Option<&PassiveRadiance>,
    chunks: &LidarChunks,
) -> Result<LidarRun, String> {
    let t0 = std::time::Instant::now();
    // Generated on demand: a scan's pulse list is not held in memory.
    let plan = PulsePlan::new(desc);
    let ref_range = plan.reference_range_m;
    let (shape, footprint) = beam_footprint(desc, ref_range)?;
    let gate = range_gate(desc, &plan, box_lo, box_hi, &shape);
    let beam = beam(desc, input, chunks, &shape, footprint, ref_range, gate);
    let pulse = PulseShape::from_fwhm_ns(desc.pulse_fwhm_ns, 3.0)
        .map_err(|e| format!("lidar `{}`: {e}", desc.name))?;
    // The full time axis of the convolved waveforms (range gate widened by the pulse kernel):
    // stored waveforms are trimmed to their non-zero bins, photon counting needs the whole gate.
    // The pulse kernel on the digitiser's bins: the same for every pulse, computed once (it
    // cost ~3.5k instructions per pulse, as much again as the convolution itself).
    let kernel = pulse
        .kernel(desc.bin_ns)
        .map_err(|e| format!("lidar `{}`: {e}", desc.name))?;
    let gate_axis = {
        let b = WaveformBinner::new(gate.0, gate.1, desc.bin_ns)
            .map_err(|e| format!("lidar `{}`: {e}", desc.name))?;
        let w = b.waveform();
        (
            w.t0_ns - kernel.centre as f64 * w.dt_ns,
            w.n_bins() + kernel.weights.len() - 1,
        )
    };
    let notes = run_notes(desc, input, passive, chunks, &shape, &beam);
    // Photon counting: the detector, once.
    let detector = desc.photon_counting.as_ref().map(|pc| Detector {
        quantum_efficiency: pc.quantum_efficiency,
        dead_time_ns: pc.dead_time_ns,
        dark_count_hz: pc.dark_count_hz,
        ..Detector::dart_default()
    });
    let chunk = chunks.chunk_pulses.max(1);
    let err = |e: crate::lidar::LidarError| format!("lidar `{}`: {e}", desc.name);
    let cx = ChunkContext {
        desc,
        band,
        seed: input.params.seed,
        passive,
        fov_half: shape.fov_half,
        kernel,
        gate_axis,
        detector,
        fusion: desc.fusion && passive.is_some(),
    };
    // Streamed: waveforms and spools of the pulses' entries and detections.
    let writers = match &chunks.stream_dir {
        Some(dir) if plan.len() > chunk => Some((
            WaveformStream::create(dir).map_err(err)?,
            WaveformStream::create(&dir.join("raw")).map_err(err)?,
            Spool::create(dir, "pulses")?,
            Spool::create(dir, "counted")?,
        )),
        _ => None,
    };
    let bar = crate::io::progress::progress_bar(chunks.progress, plan.len() as u64, "LiDAR pulses");
    let mut outs = ScanOutputs {
        records: Vec::with_capacity(if writers.is_some() {
            crate::lidar::products::QUICKLOOKS
        } else {
            plan.len()
        }),
        counted: Vec::new(),
        background_rate_hz: Vec::new(),
        fusion_radiance: Vec::new(),
        noise: 0,
        writers,
    };
    run_lidar_chunks(input, &beam, plan.iter(), chunk, |part, results| {
        outs.add_chunk(&cx, part, results)?;
        bar.inc(part.len() as u64);
        Ok(())
    })?;
    bar.finish_and_clear();
    outs.finish(desc, cx.fusion, notes, t0)
}

/// The beam's transverse profile and extent ([`beam_footprint`]).
struct BeamShape {
    /// Nominal footprint radius at the reference range, m.
    radius: f64,
    /// Transverse profile (the scene's `beam`, else Gaussian with `edge_intensity`).
    profile: BeamProfile,
    /// Truncation of the profile, in footprint radii.
    reach: f64,
    /// Half-angle of the receiver's field of view, rad.
    fov_half: f64,
}

/// The beam's footprint at the reference range `ref_range` (DART 5 paper §4; physics.md
/// §9.1): the radius (given, or from the divergence), the profile truncated at 3 radii or at
/// the end of a longer table (the lost fraction is reported), its sampler, and the receiver's
/// field of view (`fov_radius_m`, else the truncated footprint).
fn beam_footprint(
    desc: &LidarDesc,
    ref_range: f64,
) -> Result<(BeamShape, FootprintSampler), String> {
    let radius = match (desc.footprint_radius_m, desc.divergence_mrad) {
        (Some(r), _) => r,
        (None, Some(d)) => ref_range * (0.5e-3 * d).tan(),
        _ => return Err("footprint_radius_m or divergence_mrad is required".into()),
    };
    let profile = desc.beam.clone().unwrap_or(BeamProfile::Gaussian {
        edge_intensity: desc.edge_intensity,
    });
    // Truncate the profile at 3 footprint radii, or at the end of a longer table (the lost
    // fraction is reported).
    let reach = match &profile {
        BeamProfile::Tabulated { points } => points.last().map_or(1.0, |p| p.0).max(3.0),
        _ => 3.0,
    };
    let footprint = FootprintSampler::from_beam(&profile, radius, reach * radius)
        .map_err(|e| format!("lidar `{}`: {e}", desc.name))?;
    let fov_r = desc.fov_radius_m.unwrap_or(reach * radius);
    let fov_half = (fov_r / ref_range).atan();
    let shape = BeamShape {
        radius,
        profile,
        reach,
        fov_half,
    };
    Ok((shape, footprint))
}

/// The range gate (two-way path lengths, m) from the grid box over every pulse of the plan,
/// plus the margin for multiple scattering. Airborne: from the top plane to the bottom one
/// over the beam's cone (half-angle α of the truncated footprint at the reference range): the
/// footprint's edge rays reach the bottom plane later than the axis by the factor
/// cos θ/cos(θ + α) (θ the axis zenith; 1 + α²/2 at nadir), which a wide beam at long range
/// makes larger than the margin (footprint 900 m at 30 km: 13.5 m). An emitter inside the
/// box: from 0 to its farthest corner.
fn range_gate(
    desc: &LidarDesc,
    plan: &PulsePlan,
    box_lo: DVec3,
    box_hi: DVec3,
    shape: &BeamShape,
) -> (f64, f64) {
    let alpha = (shape.reach * shape.radius / plan.reference_range_m).atan();
    let mut d_min = f64::INFINITY;
    let mut d_max: f64 = 0.0;
    for pl in plan.iter() {
        let corners = (0..8).map(|k| {
            DVec3::new(
                if k & 1 == 0 { box_lo.x } else { box_hi.x },
                if k & 2 == 0 { box_lo.y } else { box_hi.y },
                if k & 4 == 0 { box_lo.z } else { box_hi.z },
            )
        });
        let inside = (0..3).all(|a| pl.emitter[a] >= box_lo[a] && pl.emitter[a] <= box_hi[a]);
        match &desc.platform {
            LidarPlatform::Airborne { .. } if !inside => {
                // To the top plane and to the bottom plane, over the cone (along the axis
                // where the cone's edge nears the horizontal).
                let theta = (-pl.axis.z).clamp(-1.0, 1.0).acos();
                let near = (theta - alpha).max(0.0).cos();
                let far = if theta + alpha < 1.5 {
                    (theta + alpha).cos()
                } else {
                    -pl.axis.z
                };
                d_min = d_min.min((pl.emitter.z - box_hi.z) / near);
                d_max = d_max.max((pl.emitter.z - box_lo.z) / far);
            }
            _ => {
                d_min = 0.0;
                for c in corners {
                    d_max = d_max.max((c - pl.emitter).length());
                }
            }
        }
    }
    (
        (2.0 * d_min - 1.0).max(0.0),
        2.0 * d_max + 2.0 * desc.gate_margin_m + 1.0,
    )
}

/// The tracking parameters of the instrument's pulses ([`Beam`]): footprint, field of view,
/// receiver, energy, beam-ray counts, range gate and estimator settings (the far-photon
/// roulette's scale from the scene unless given, [`far_roulette_scale_m`]).
fn beam(
    desc: &LidarDesc,
    input: &PhotonInput,
    chunks: &LidarChunks,
    shape: &BeamShape,
    footprint: FootprintSampler,
    ref_range: f64,
    gate: (f64, f64),
) -> Beam {
    Beam {
        footprint,
        reference_range_m: ref_range,
        cos_fov: shape.fov_half.cos(),
        aperture_m2: desc.aperture_m2,
        energy_j: desc.pulse_energy_j,
        photons: desc.photons_per_pulse.unwrap_or(DEFAULT_LIDAR_PHOTONS),
        photons_per_ray: desc
            .photons_per_pulse
            .unwrap_or(DEFAULT_LIDAR_PHOTONS_PER_RAY),
        gate_m: gate,
        bin_ns: desc.bin_ns,
        estimator: desc.estimator,
        scattering_photons: desc.scattering_photons_per_pulse.unwrap_or(u32::MAX),
        far_roulette_m: match chunks.far_roulette {
            FarRoulette::Auto => far_roulette_scale_m(input),
            FarRoulette::ScaleM(m) if m > 0.0 => m,
            _ => 0.0,
        },
        first_order_columns: chunks.first_order_columns,
    }
}

/// The run's notes (in lidar.json): the footprint, field of view, gate, returns method and
/// sampler; the return-path correlation of turbid cells; the first-order estimator; the beam
/// rays per pulse (with a warning for a wide footprint at the default count); the photon
/// counting's background source.
fn run_notes(
    desc: &LidarDesc,
    input: &PhotonInput,
    passive: Option<&PassiveRadiance>,
    chunks: &LidarChunks,
    shape: &BeamShape,
    beam: &Beam,
) -> Vec<String> {
    let (radius, profile, reach, fov_half) =
        (shape.radius, &shape.profile, shape.reach, shape.fov_half);
    let ref_range = beam.reference_range_m;
    let gate = beam.gate_m;
    let mut notes = vec![format!(
        "footprint: {} profile{}, radius {radius:.4} m at {ref_range:.1} m, truncated at {reach} radii (energy outside: {:.2e}); receiver FOV half-angle {:.3e} rad; gate {:.3}–{:.3} m of path; returns: {:?}; sampler: {:?}",
        profile.name(),
        match profile {
            BeamProfile::Gaussian { edge_intensity } =>
                format!(" (edge intensity {edge_intensity})"),
            _ => String::new(),
        },
        beam.footprint.lost_energy_fraction(),
        fov_half,
        gate.0,
        gate.1,
        desc.returns,
        desc.sampler
    )];
    notes.push("turbid cells: first-order returns go back through the gaps the pulse came through when the material has leaf_size_m > 0 (Kuusk correlation: one-way transmittance for a monostatic receiver); leaf_size_m 0 = independent gaps (two-way); facets are exactly correlated".into());
    if desc.estimator == crate::scene::desc::LidarEstimator::ExpectedValue {
        notes.push(if chunks.first_order_columns {
            "first order: column quadrature for exactly vertical pulses from above the grid whose footprint spans at most 64 grid columns and as many as beam rays, with no column of facets under half the beam rays (the footprint's exact mass over each column times one column ray; strips between columns, columns with facets and columns whose rays' arrival times spread over 1 % of a bin sampled), per beam ray otherwise".into()
        } else {
            "first order: per beam ray (column quadrature off)".into()
        });
    }
    notes.push(match desc.photons_per_pulse {
        Some(n) => format!("beam rays per pulse: {n} (photons_per_pulse)"),
        None => format!(
            "beam rays per pulse: {DEFAULT_LIDAR_PHOTONS} for a pulse whose first order the column quadrature scores, {DEFAULT_LIDAR_PHOTONS_PER_RAY} for the others (photons_per_pulse absent: the same ~1 % waveform error on the forest ALS bench)"
        ),
    });
    // The default counts hold their error for footprints of about a grid cell; a footprint
    // over many columns averages returns that differ from column to column.
    let cell = input.spec.cell.x.max(input.spec.cell.y);
    if desc.photons_per_pulse.is_none() && radius > WIDE_FOOTPRINT_CELLS * cell {
        notes.push(format!(
            "warning: photons_per_pulse absent, but the footprint (radius {radius:.3} m at {ref_range:.1} m) spans ~{:.0} grid columns, while the default beam-ray count was tuned on a 0.3 m footprint over 1 m cells: expect a larger waveform error (the GEDI example, 12.5 m over 1 m cells: 15 % at the default, 4.4 % at 1000 rays, 2.1 % at 5000); set photons_per_pulse",
            std::f64::consts::PI * (reach * radius / cell).powi(2)
        ));
    }
    // Photon counting: the note on the background source.
    if desc.photon_counting.is_some() {
        if let Some(pr) = passive {
            notes.push(format!(
                "photon counting: solar background from {}",
                pr.source
            ));
        } else {
            notes.push("photon counting: no passive radiance available (run the flux-tracking solver): solar background omitted, dark counts only".into());
        }
    }
    notes
}

/// What every chunk of an instrument run uses ([`simulate_lidar`]).
struct ChunkContext<'a> {
    /// The instrument.
    desc: &'a LidarDesc,
    /// Scene band of the laser (for the passive radiance).
    band: usize,
    /// Scene seed (photon-counting streams).
    seed: u64,
    /// Passive radiance (photon-counting background, fusion).
    passive: Option<&'a PassiveRadiance>,
    /// Half-angle of the receiver's field of view, rad.
    fov_half: f64,
    /// The emitted pulse on the digitiser's bins.
    kernel: PulseKernel,
    /// Time axis of the convolved waveforms over the whole gate: (t0, ns; bins).
    gate_axis: (f64, usize),
    /// Photon-counting detector, when the instrument has one.
    detector: Option<Detector>,
    /// Fusion product: passive radiance at each footprint centre.
    fusion: bool,
}

/// What an instrument run accumulates chunk by chunk ([`ScanOutputs::add_chunk`]): in memory,
/// or, for a streamed scan, in the temporary files of `writers` (the records of the
/// quick-looks only).
struct ScanOutputs {
    records: Vec<PulseRecord>,
    counted: Vec<CountedPhoton>,
    background_rate_hz: Vec<f64>,
    fusion_radiance: Vec<Vec<f64>>,
    /// Noise detections (solar background, dark counts) spooled so far.
    noise: usize,
    /// Convolved and raw waveforms, pulse entries and detections of a streamed scan.
    writers: Option<(WaveformStream, WaveformStream, Spool, Spool)>,
}

impl ScanOutputs {
    /// One chunk's tracked pulses (`results`, in the order of `part`): their records
    /// ([`pulse_records`]), photon counting, fusion radiance, and for a streamed scan the
    /// chunk written out.
    fn add_chunk(
        &mut self,
        cx: &ChunkContext,
        part: &[Pulse],
        results: Vec<PulseResult>,
    ) -> Result<(), String> {
        let mut recs = pulse_records(cx, part, results)?;
        if let (Some(pc), Some(det)) = (&cx.desc.photon_counting, &cx.detector) {
            self.count_photons(cx, pc, det, &recs)?;
        }
        if let Some(pr) = cx.passive.filter(|_| cx.fusion) {
            self.fusion_radiance.extend(recs.iter().map(|pl| {
                let (x, y) = footprint_centre(pl);
                (0..pr.per_band.len()).map(|b| pr.at(x, y, b)).collect()
            }));
        }
        self.stream_chunk(cx, &mut recs)?;
        self.records.extend(recs);
        Ok(())
    }

    /// Photon counting of a chunk's pulses (physics.md §9.5): the solar background rate at
    /// each footprint centre, then every shot drawn from the mean signal over the whole gate
    /// (each pulse with its own stream), detections placed along the beam axis.
    fn count_photons(
        &mut self,
        cx: &ChunkContext,
        pc: &PhotonCountingDesc,
        det: &Detector,
        recs: &[PulseRecord],
    ) -> Result<(), String> {
        let desc = cx.desc;
        for pl in recs {
            let (x, y) = footprint_centre(pl);
            let radiance = cx.passive.map_or(0.0, |pr| pr.at(x, y, cx.band));
            let rate = solar_background_rate(
                radiance,
                pc.filter_bandwidth_nm * 1e-3,
                desc.aperture_m2,
                cx.fov_half,
                det,
                pc.wavelength_nm,
            )
            .map_err(|e| format!("lidar `{}`: {e}", desc.name))?;
            self.background_rate_hz.push(rate);
            // The mean signal over the whole gate (zero outside the stored bins), so that
            // background and dark counts and the dead time cover the full range gate.
            let (t0_gate, n_gate) = cx.gate_axis;
            let dt = pl.waveform.dt_ns;
            let padded = pl.waveform.padded_to(t0_gate, n_gate);
            let signal = mean_signal_counts(&padded.total, pc.wavelength_nm, det)
                .map_err(|e| format!("lidar `{}`: {e}", desc.name))?;
            let bg_bin = rate * dt * 1e-9;
            let mut rng = crate::random::stream(
                cx.seed,
                crate::lidar::tracking::LIDAR_STREAM ^ 0x5043,
                pl.id,
            );
            for shot in 0..pc.shots {
                let dets = simulate_shot(&signal, bg_bin, t0_gate, dt, det, &mut rng)
                    .map_err(|e| format!("lidar `{}`: {e}", desc.name))?;
                for d in dets {
                    let range = 0.5 * d.time_ns * 1e-9 * crate::lidar::SPEED_OF_LIGHT_M_PER_S;
                    self.counted.push(CountedPhoton {
                        pulse: pl.id,
                        shot,
                        position: pl.emitter + pl.axis * range,
                        time_ns: d.time_ns,
                        is_noise: d.is_noise,
                    });
                }
            }
        }
        Ok(())
    }

    /// A streamed scan: the chunk's waveforms (convolved and raw) appended to their files, its
    /// pulse entries (with background rates and fused radiances) and detections to the spools,
    /// and of its records only those the quick-looks still need kept. Without writers:
    /// nothing.
    fn stream_chunk(
        &mut self,
        cx: &ChunkContext,
        recs: &mut Vec<PulseRecord>,
    ) -> Result<(), String> {
        let err = |e: crate::lidar::LidarError| format!("lidar `{}`: {e}", cx.desc.name);
        if let Some((wf, raw, pulse_spool, counted_spool)) = &mut self.writers {
            wf.append(&recs.iter().map(|p| (p.id, &p.waveform)).collect::<Vec<_>>())
                .map_err(err)?;
            raw.append(&recs.iter().map(|p| (p.id, &p.raw)).collect::<Vec<_>>())
                .map_err(err)?;
            // Everything else of the chunk goes to the spools: memory stays bounded by a chunk.
            let mut rates = self.background_rate_hz.drain(..);
            let mut radiances = self.fusion_radiance.drain(..);
            for p in recs.iter() {
                PulseEntry::of(p, rates.next(), radiances.next()).spool(pulse_spool)?;
            }
            drop((rates, radiances));
            for c in self.counted.drain(..) {
                self.noise += usize::from(c.is_noise);
                spool_counted(&c, counted_spool)?;
            }
            // Keep the quick-looks' pulses (with their waveforms) only.
            let keep = crate::lidar::products::QUICKLOOKS.saturating_sub(self.records.len());
            recs.truncate(keep);
        }
        Ok(())
    }

    /// The instrument's [`LidarRun`]: a streamed scan's files closed ([`StreamedRun`]), the
    /// wall time since `t0`.
    fn finish(
        self,
        desc: &LidarDesc,
        fusion: bool,
        notes: Vec<String>,
        t0: std::time::Instant,
    ) -> Result<LidarRun, String> {
        let err = |e: crate::lidar::LidarError| format!("lidar `{}`: {e}", desc.name);
        let streamed = match self.writers {
            Some((wf, raw, pulse_spool, counted_spool)) => Some(std::sync::Arc::new(StreamedRun {
                waveforms: wf.finish().map_err(err)?,
                raw: raw.finish().map_err(err)?,
                pulses: pulse_spool.finish()?,
                counted: counted_spool.finish()?,
                noise: self.noise,
                fusion,
            })),
            None => None,
        };
        Ok(LidarRun {
            desc: desc.clone(),
            pulses: self.records,
            counted: self.counted,
            background_rate_hz: self.background_rate_hz,
            fusion_radiance: (fusion && streamed.is_none()).then_some(self.fusion_radiance),
            notes,
            seconds: t0.elapsed().as_secs_f64(),
            streamed,
        })
    }
}

/// A chunk's pulse records: each pulse's received waveform convolved with the pulse kernel on
/// the whole gate axis, its returns detected there (the decomposition's fit sees the zero bins
/// around the returns), the stored waveforms trimmed. In parallel; records in pulse order.
fn pulse_records(
    cx: &ChunkContext,
    part: &[Pulse],
    results: Vec<PulseResult>,
) -> Result<Vec<PulseRecord>, String> {
    let desc = cx.desc;
    let kernel = &cx.kernel;
    let gate_axis = cx.gate_axis;
    // Convolution and returns per pulse, in parallel (each pulse is independent; the
    // order of the records is the order of the pulses).
    use rayon::prelude::*;
    results
        .into_par_iter()
        .zip(part.par_iter())
        .map_init(
            // The convolved waveform on the whole gate axis, reused by the pulses of a
            // rayon task: zero outside the bins a pulse reached, which are cleared after
            // it (no allocation and zeroing of the gate per pulse).
            || Waveform::zeros(gate_axis.0, desc.bin_ns, gate_axis.1),
            |padded, (r, pl)| -> Result<PulseRecord, String> {
                // Returns are detected on the whole gate (the decomposition's fit sees the
                // zero bins around the returns); the stored waveform is trimmed.
                let reached = r
                    .waveform
                    .convolve_into(kernel, padded)
                    .map_err(|e| format!("lidar `{}` pulse {}: {e}", desc.name, r.id))?;
                // (Zero outside the reached bins.)
                let peak = padded.total[reached.clone()]
                    .iter()
                    .cloned()
                    .fold(0.0, f64::max);
                let returns = if peak > 0.0 {
                    crate::lidar::returns::detect_returns_method_within(
                        padded,
                        1e-3 * peak,
                        desc.returns,
                        &pipeline_decomposition_settings(),
                        reached.clone(),
                    )
                    .map_err(|e| format!("lidar `{}` pulse {}: {e}", desc.name, r.id))
                } else {
                    Ok(Vec::new())
                };
                let waveform = padded.trimmed_within(reached.clone());
                padded.total[reached.clone()].fill(0.0);
                padded.first_order[reached].fill(0.0);
                let returns = returns?;
                Ok(PulseRecord {
                    id: r.id,
                    emitter: pl.emitter,
                    axis: pl.axis,
                    received_j: r.waveform.total_energy_j(),
                    first_order_j: r.waveform.first_order_energy_j(),
                    raw: r.waveform,
                    waveform,
                    out_of_gate_j: r.out_of_gate_j,
                    missed_j: r.missed_j,
                    returns,
                })
            },
        )
        .collect::<Result<Vec<_>, String>>()
}
