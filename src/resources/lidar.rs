//! LiDAR resources: the instruments of the scene (spawned only when the scene has a `lidars`
//! section) and the Photon stage's LiDAR results (written by the Output stage).

use crate::lidar::returns::Return;
use crate::lidar::waveform::Waveform;
use crate::scene::desc::LidarDesc;
use bevy_ecs::prelude::Resource;
use glam::DVec3;

/// The scene's LiDAR instruments.
#[derive(Debug, Clone, Resource)]
pub struct LidarInstruments(pub Vec<LidarDesc>);

/// One simulated pulse.
#[derive(Debug, Clone)]
pub struct PulseRecord {
    /// Pulse ID (unique within the instrument).
    pub id: u64,
    /// Emitter position (scene coordinates), m.
    pub emitter: DVec3,
    /// Beam axis (unit propagation direction).
    pub axis: DVec3,
    /// Received energy per bin before the pulse shape (total and first order), J. Trimmed to
    /// the bins from the first to the last non-zero one ([`Waveform::trim`]): `t0_ns` differs
    /// from pulse to pulse and an all-zero waveform is empty. Empty (no bins) for the pulses
    /// whose waveforms were streamed to disk ([`LidarRun::streamed`]).
    pub raw: Waveform,
    /// Received waveform convolved with the emitted pulse (total and first order), J per bin;
    /// trimmed like `raw`, and empty like it when streamed.
    pub waveform: Waveform,
    /// Received energy inside the range gate (sum of `raw.total`, kept when streamed), J.
    pub received_j: f64,
    /// First-order part of `received_j`, J.
    pub first_order_j: f64,
    /// Received energy outside the range gate, J: exact before the gate, a lower bound after it
    /// (photons that can no longer be recorded inside the gate are stopped early).
    pub out_of_gate_j: f64,
    /// Emitted energy that missed the scene (isolated scenes), J.
    pub missed_j: f64,
    /// Discrete returns (Gaussian decomposition of `waveform.total`).
    pub returns: Vec<Return>,
}

/// A photon-counting detection turned into a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CountedPhoton {
    /// Pulse ID.
    pub pulse: u64,
    /// Shot index for this pulse.
    pub shot: u32,
    /// Position (along the beam axis at the detection's range), m.
    pub position: DVec3,
    /// Detection time after emission, ns.
    pub time_ns: f64,
    /// True for solar background or dark counts.
    pub is_noise: bool,
}

/// Results of one instrument.
#[derive(Debug, Clone)]
pub struct LidarRun {
    /// Instrument description.
    pub desc: LidarDesc,
    /// Pulses.
    pub pulses: Vec<PulseRecord>,
    /// Photon-counting detections (when the instrument has a detector).
    pub counted: Vec<CountedPhoton>,
    /// Solar background rate used per pulse (photo-electrons s⁻¹), photon counting only.
    pub background_rate_hz: Vec<f64>,
    /// Spectral radiance of the co-registered passive image at each pulse's footprint centre,
    /// per scene band (W m⁻² sr⁻¹ µm⁻¹), when a passive image exists (fusion product).
    pub fusion_radiance: Option<Vec<Vec<f64>>>,
    /// Notes (what was approximated or skipped).
    pub notes: Vec<String>,
    /// Wall time, s.
    pub seconds: f64,
    /// The waveform products already written to temporary files when the scan was streamed
    /// (an output folder was set and the scan had more pulses than one chunk, see
    /// [`crate::lidar::simulate::LidarChunks`]): convolved, then raw. Their pulses keep
    /// returns and energies in memory, but waveforms only for the first
    /// [`crate::lidar::products::QUICKLOOKS`] pulses. The Output stage renames the files into
    /// place; dropped without that, the temporary files are removed.
    pub streamed: Option<std::sync::Arc<StreamedRun>>,
}

/// Waveform products of a streamed scan, waiting in temporary files for the Output stage.
#[derive(Debug)]
pub struct StreamedRun {
    /// `waveforms.f32` + index of the convolved waveforms.
    pub waveforms: crate::lidar::waveform_io::StreamedWaveforms,
    /// The same for the raw (unconvolved) waveforms, under `raw/`.
    pub raw: crate::lidar::waveform_io::StreamedWaveforms,
}

/// The Photon stage's LiDAR results.
#[derive(Debug, Clone, Default, Resource)]
pub struct LidarProducts(pub Vec<LidarRun>);
