//! LiDAR pulse tracking in receiver mode (DART 5 paper §4, "Ray-Carlo" LiDAR; physics.md §9.2,
//! §9.6): pulses of photons from an emitter, peel-off toward the monostatic receiver and
//! path-length binning into a waveform per pulse. The photon walk itself (free paths, facet
//! hits, peel-off, the receiver-mode flights) is [`crate::photon::engine`]'s; this module
//! builds the receiver-mode context, launches each pulse's beam rays and books their returns
//! into a [`WaveformBinner`] through the engine's receiver tally.
//!
//! * this file: the instrument ([`Beam`]) and its pulses ([`Pulse`]), [`run_lidar`] and
//!   [`run_lidar_chunks`] (pulses in parallel, one random stream per pulse), the per-worker
//!   state.
//! * `run_pulse`: one pulse — its beam rays on a low-discrepancy lattice over the footprint,
//!   their tracking, and the column quadrature of the first-order return.
//! * `columns`: the column quadrature of the first-order return of near-nadir pulses
//!   (`FirstOrderColumns`).
//! * `first_order_bins`: the expected-value first-order return of a vegetation segment,
//!   stratified by digitiser bin (the binner's side of the engine's receiver tally).

mod columns;
mod first_order_bins;
mod run_pulse;
#[cfg(test)]
mod tests;

use crate::lidar::waveform::WaveformBinner;
use crate::photon::engine::context::{ColumnDepth, Ctx, Receiver};
use crate::photon::engine::events::MS_STOP_FACTOR;
use crate::photon::engine::input::PhotonInput;
use crate::photon::engine::tally::{Acc, BatchOut};
use crate::scene::desc::LidarEstimator;
use columns::FirstOrderColumns;
use glam::DVec3;
use rayon::prelude::*;
use run_pulse::run_pulse;
use std::collections::HashMap;

/// Photon stream purpose tag of LiDAR pulses.
pub const LIDAR_STREAM: u64 = 0x4c_49_44_41_52; // "LIDAR"

/// One LiDAR pulse (its receiver is at the emitter: monostatic).
#[derive(Debug, Clone, PartialEq)]
pub struct Pulse {
    /// Pulse ID (also selects its random stream).
    pub id: u64,
    /// Emitter and receiver position (unwrapped scene coordinates), m.
    pub emitter: DVec3,
    /// Beam axis (unit propagation direction).
    pub axis: DVec3,
}

/// Beam and receiver shared by the pulses of one instrument.
#[derive(Debug, Clone)]
pub struct Beam {
    /// Transverse profile sampler at `reference_range_m` (offsets in metres).
    pub footprint: crate::lidar::pulse::FootprintSampler,
    /// Range at which the footprint offsets are drawn, m.
    pub reference_range_m: f64,
    /// Cosine of the receiver FOV half-angle.
    pub cos_fov: f64,
    /// Receiver aperture, m².
    pub aperture_m2: f64,
    /// Pulse energy, J.
    pub energy_j: f64,
    /// Photons (beam rays) of a pulse whose first-order return the column quadrature scores
    /// (`FirstOrderColumns`; the quadrature is planned for this count).
    pub photons: u32,
    /// Photons (beam rays) of a pulse that scores its first-order return per beam ray (the
    /// quadrature does not apply, is off, or falls back).
    pub photons_per_ray: u32,
    /// Path-length gate `[min, max]`, m (two-way).
    pub gate_m: (f64, f64),
    /// Digitiser bin, ns.
    pub bin_ns: f64,
    /// Estimator of the tracking.
    pub estimator: LidarEstimator,
    /// `Stratified`, `ExpectedValue`: expected number of beam rays per pulse continued past their first
    /// interaction into multiple scattering (≥ the pulse's beam rays: all).
    pub scattering_photons: u32,
    /// `ExpectedValue`: distance scale ρ₀ (m) of the far-photon roulette of multiple scattering
    /// (`far_roulette_survival`); 0: off.
    pub far_roulette_m: f64,
    /// `ExpectedValue`: the first-order return by the column quadrature where it applies
    /// (`FirstOrderColumns`); false: every beam ray scores its own (for the equality tests
    /// and for measuring).
    pub first_order_columns: bool,
}
/// Result of one pulse.
#[derive(Debug, Clone)]
pub struct PulseResult {
    /// Pulse ID.
    pub id: u64,
    /// Received energy per bin (total and first order), before pulse-shape convolution, J;
    /// trimmed to the bins between the first and the last non-zero one
    /// ([`crate::lidar::waveform::Waveform::trim`]: `t0_ns` is that of the first kept bin).
    pub waveform: crate::lidar::waveform::Waveform,
    /// Received energy outside the gate, J: exact before the gate; after the gate a lower bound
    /// (photons that can no longer be recorded inside the gate are stopped, see
    /// `Ctx::beyond_gate`, and what they would have sent after the gate is not counted).
    pub out_of_gate_j: f64,
    /// Emitted energy that missed the scene (isolated scenes), J.
    pub missed_j: f64,
}

/// Runs LiDAR pulses. `inp` must hold single-band optics (the laser's band) and no views; the
/// pulses run in parallel, each with its own stream (seed, pulse ID) and sequential photons, so
/// waveforms are bit-identical on any number of threads.
pub fn run_lidar(
    inp: &PhotonInput,
    beam: &Beam,
    pulses: &[Pulse],
) -> Result<Vec<PulseResult>, String> {
    let mut all = Vec::with_capacity(pulses.len());
    run_lidar_chunks(
        inp,
        beam,
        pulses.iter().cloned(),
        pulses.len().max(1),
        |_, r| {
            all.extend(r);
            Ok(())
        },
    )?;
    Ok(all)
}

/// [`run_lidar`] by chunks of `chunk` pulses (in order): `each` receives every chunk's pulses
/// and results before the next chunk runs, so a long scan's pulses and waveforms need not all
/// be in memory at once (`pulses` may generate them on demand). The tracking context (column
/// depths) is built once. Results are those of [`run_lidar`] bit for bit: each pulse has its
/// own random stream (seed, pulse ID).
pub fn run_lidar_chunks(
    inp: &PhotonInput,
    beam: &Beam,
    pulses: impl IntoIterator<Item = Pulse>,
    chunk: usize,
    mut each: impl FnMut(&[Pulse], Vec<PulseResult>) -> Result<(), String>,
) -> Result<(), String> {
    let mut base = Ctx::new(inp, 1, 1);
    base.columns = ColumnDepth::new(&base).map(std::sync::Arc::new);
    let first_order = FirstOrderColumns::new(&base, beam).map(std::sync::Arc::new);
    // Validate the binner once.
    WaveformBinner::new(beam.gate_m.0, beam.gate_m.1, beam.bin_ns).map_err(|e| e.to_string())?;
    let mut pulses = pulses.into_iter();
    loop {
        let part: Vec<Pulse> = pulses.by_ref().take(chunk.max(1)).collect();
        if part.is_empty() {
            return Ok(());
        }
        let results = part
            .par_iter()
            .map_init(
                || PulseState::new(&base, beam, first_order.clone()),
                |st, pl| run_pulse(st, beam, pl),
            )
            .collect();
        each(&part, results)?;
    }
}

/// What the pulses of one worker reuse (built once per rayon task, not per pulse): the
/// receiver-mode context (only the receiver's position and axis change from pulse to pulse),
/// the tallies with their waveform binner, and the tracking scratch. Every pulse starts from
/// the state of a new one ([`PulseState::reset`]), so the products do not depend on which
/// pulses a thread ran before (the same bits on any number of threads).
pub(crate) struct PulseState<'a> {
    pub(crate) ctx: Ctx<'a>,
    pub(crate) out: BatchOut,
    pub(crate) g_cur: Vec<f64>,
    pub(crate) scratch: Vec<f64>,
    pub(crate) tr: Vec<f64>,
    /// The run's column quadrature of the first order, when it applies.
    pub(crate) first_order: Option<std::sync::Arc<FirstOrderColumns>>,
}

impl<'a> PulseState<'a> {
    pub(crate) fn new(
        base: &Ctx<'a>,
        beam: &Beam,
        first_order: Option<std::sync::Arc<FirstOrderColumns>>,
    ) -> Self {
        let ctx = Ctx {
            receiver: Some(Receiver {
                position: DVec3::ZERO,
                axis: DVec3::NEG_Z,
                cos_fov: beam.cos_fov,
                aperture_m2: beam.aperture_m2,
            }),
            max_path: beam.gate_m.1,
            stratified: beam.estimator != LidarEstimator::Legacy,
            ms_stop: match beam.estimator {
                LidarEstimator::ExpectedValue => MS_STOP_FACTOR,
                _ => 0.0,
            },
            far_roulette: match beam.estimator {
                LidarEstimator::ExpectedValue
                    if beam.far_roulette_m > 0.0 && beam.cos_fov > 0.0 =>
                {
                    (
                        beam.far_roulette_m,
                        (1.0 - beam.cos_fov * beam.cos_fov).max(0.0).sqrt() / beam.cos_fov,
                    )
                }
                _ => (0.0, 0.0),
            },
            // Set per pulse (its beam rays), see `run_pulse`.
            continue_prob: continue_prob(beam, beam.photons),
            ..base.clone()
        };
        let binner =
            WaveformBinner::new(beam.gate_m.0, beam.gate_m.1, beam.bin_ns).expect("validated gate");
        let out = BatchOut {
            summary: vec![0.0; ctx.sum.len()],
            abs_tur: Acc::sink(1),
            int_tur: Acc::sink(1),
            abs_fac: Acc::sink(1),
            int_fac: Acc::sink(1),
            abs_gnd: Acc::sink(1),
            int_gnd: Acc::sink(1),
            abs_fluid: HashMap::new(),
            lost: vec![0.0],
            roulette: vec![0.0],
            events: 0,
            crossings: 0,
            skipped: 0,
            wave: Some(Box::new(binner)),
            cams: Vec::new(),
        };
        let g_cur = vec![0.0; ctx.tur_ids.len()];
        Self {
            ctx,
            out,
            g_cur,
            scratch: vec![0.0; 1],
            tr: vec![0.0; 1],
            first_order,
        }
    }

    /// Back to the state of [`PulseState::new`] for the pulse `pl` (its receiver). The binner
    /// is left as [`WaveformBinner::take_trimmed`] leaves it: as new.
    /// [`WaveformBinner::take_trimmed`]: WaveformBinner::take_trimmed
    pub(crate) fn reset(&mut self, pl: &Pulse) {
        if let Some(r) = self.ctx.receiver.as_mut() {
            r.position = pl.emitter;
            r.axis = pl.axis;
        }
        let o = &mut self.out;
        o.summary.fill(0.0);
        for a in [
            &mut o.abs_tur,
            &mut o.int_tur,
            &mut o.abs_fac,
            &mut o.int_fac,
            &mut o.abs_gnd,
            &mut o.int_gnd,
        ] {
            a.reset();
        }
        o.abs_fluid.clear();
        o.lost.fill(0.0);
        o.roulette.fill(0.0);
        (o.events, o.crossings, o.skipped) = (0, 0, 0);
        self.g_cur.fill(0.0);
        self.scratch.fill(0.0);
        self.tr.fill(0.0);
    }
}

/// Survival probability of a pulse's beam rays past their first interaction (the
/// multiple-scattering roulette of [`Beam::scattering_photons`]) when it has `n_rays` of them.
pub(crate) fn continue_prob(beam: &Beam, n_rays: u32) -> f64 {
    match beam.estimator {
        LidarEstimator::Stratified | LidarEstimator::ExpectedValue if n_rays > 0 => {
            (beam.scattering_photons as f64 / n_rays as f64).clamp(0.0, 1.0)
        }
        _ => 1.0,
    }
}

/// The waveform binner of a pulse's tallies (the receiver tally [`PulseState::new`] gives them).
fn binner(out: &mut BatchOut) -> &mut WaveformBinner {
    out.wave
        .as_mut()
        .and_then(|w| w.as_any_mut().downcast_mut::<WaveformBinner>())
        .expect("binner")
}
