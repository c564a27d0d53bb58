//! Results of the LiDAR instruments (the Photon stage's LiDAR products, written by the Output
//! stage): per instrument a [`LidarRun`] of [`PulseRecord`]s and photon-counting
//! [`CountedPhoton`]s, held in memory or, for a streamed scan, in temporary files
//! ([`StreamedRun`]); the stage hands them on as the [`LidarProducts`] resource (physics.md §9).

use crate::lidar::returns::Return;
use crate::lidar::spool::{ClosedSpool, CountedPhotons, PulseEntries, PulseEntry};
use crate::lidar::waveform::Waveform;
use crate::scene::desc::LidarDesc;
use bevy_ecs::prelude::Resource;
use glam::DVec3;

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
    /// from pulse to pulse and an all-zero waveform is empty.
    pub raw: Waveform,
    /// Received waveform convolved with the emitted pulse (total and first order), J per bin;
    /// trimmed like `raw`.
    pub waveform: Waveform,
    /// Received energy inside the range gate (sum of `raw.total`), J.
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
    /// The products of a streamed scan (an output folder was set and the scan had more pulses
    /// than one chunk, see [`crate::lidar::simulate::LidarChunks`]), in temporary files written
    /// while it ran: the waveforms (convolved, then raw) and the spools of the pulses' entries
    /// and photon-counting detections ([`crate::lidar::spool`]). A streamed run keeps in memory
    /// only the first [`crate::lidar::products::QUICKLOOKS`] pulses (with their waveforms):
    /// `counted`, `background_rate_hz` and `fusion_radiance` are empty and every pulse is read
    /// through [`LidarRun::pulse_entries`] / [`LidarRun::counted_photons`], which serve both
    /// kinds of run. The Output stage renames the waveform files into place; dropped, the
    /// temporary files are removed.
    pub streamed: Option<std::sync::Arc<StreamedRun>>,
}

/// Products of a streamed scan, waiting in temporary files for the Output stage.
#[derive(Debug)]
pub struct StreamedRun {
    /// `waveforms.f32` + index of the convolved waveforms.
    pub waveforms: crate::lidar::waveform_io::StreamedWaveforms,
    /// The same for the raw (unconvolved) waveforms, under `raw/`.
    pub raw: crate::lidar::waveform_io::StreamedWaveforms,
    /// Every pulse's [`PulseEntry`], in pulse order.
    pub pulses: ClosedSpool,
    /// Every photon-counting detection, in pulse order.
    pub counted: ClosedSpool,
    /// Detections of `counted` that are noise (solar background or dark counts).
    pub noise: usize,
    /// Whether the entries carry the fused passive radiance.
    pub fusion: bool,
}

/// An iterator over a run's pulses or detections, read from memory or from a spool.
pub type Entries<'a, T> = Box<dyn Iterator<Item = Result<T, String>> + 'a>;

impl LidarRun {
    /// Number of pulses of the run (streamed or not; `pulses` of a streamed run holds only the
    /// first [`crate::lidar::products::QUICKLOOKS`]).
    pub fn pulse_count(&self) -> usize {
        match &self.streamed {
            Some(st) => st.pulses.records,
            None => self.pulses.len(),
        }
    }

    /// Every pulse in order, without waveforms, with its photon-counting background rate and
    /// fused radiance: from memory, or read back from the spool of a streamed run.
    pub fn pulse_entries(&self) -> Result<Entries<'_, PulseEntry>, String> {
        if let Some(st) = &self.streamed {
            return Ok(Box::new(PulseEntries::new(&st.pulses)?));
        }
        Ok(Box::new(self.pulses.iter().enumerate().map(|(k, p)| {
            Ok(PulseEntry::of(
                p,
                self.background_rate_hz.get(k).copied(),
                self.fusion_radiance.as_ref().map(|f| f[k].clone()),
            ))
        })))
    }

    /// Every photon-counting detection in order (from memory or from the spool).
    pub fn counted_photons(&self) -> Result<Entries<'_, CountedPhoton>, String> {
        if let Some(st) = &self.streamed {
            return Ok(Box::new(CountedPhotons::new(&st.counted)?));
        }
        Ok(Box::new(self.counted.iter().map(|c| Ok(*c))))
    }

    /// Photon-counting detections and, of them, noise (solar background and dark counts).
    pub fn counted_totals(&self) -> (usize, usize) {
        match &self.streamed {
            Some(st) => (st.counted.records, st.noise),
            None => (
                self.counted.len(),
                self.counted.iter().filter(|c| c.is_noise).count(),
            ),
        }
    }

    /// Whether the pulses carry the fused passive radiance (fusion product).
    pub fn has_fusion(&self) -> bool {
        match &self.streamed {
            Some(st) => st.fusion,
            None => self.fusion_radiance.is_some(),
        }
    }
}

/// The Photon stage's LiDAR results.
#[derive(Debug, Clone, Default, Resource)]
pub struct LidarProducts(pub Vec<LidarRun>);
