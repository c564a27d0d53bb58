//! LiDAR products under `DIR/lidar/<instrument>/` (issue #6): waveforms (convolved with the
//! pulse, total and first order) as little-endian f32 + CSV index, the unconvolved received
//! energies in `raw/`, discrete returns as a LAS 1.4 point cloud (PDRF 6, pulse ID in an
//! extra-bytes dimension), the fusion product (PDRF 7: RGB from the first three bands and one
//! extra-bytes radiance per band, by pulse ID), photon-counting point clouds, SVG quick-looks and
//! `lidar.json` (energies per pulse, notes, timings). Every file is written atomically.

use crate::io::atomic::{write_atomic, write_atomic_with};
use crate::io::las_out::{LasPoint, write_las_stream};
use crate::lidar::run::LidarRun;
use crate::lidar::spool::PulseEntry;
use crate::lidar::waveform_io::{waveform_svg, write_waveforms};
use std::path::Path;

/// Pulse repetition period used for the LAS GPS time of pulse `id` (`id × 1e-5 s`, 100 kHz):
/// the scene has no flight clock, the time only orders pulses.
pub const PULSE_PERIOD_S: f64 = 1e-5;

/// Quick-looks written per instrument (the first pulses).
pub const QUICKLOOKS: usize = 8;

/// Writes every instrument's products.
/// `memory`: the run's memory estimate, recorded in each `lidar.json` with the peak resident
/// set measured when that file is written.
pub fn write_lidar(
    dir: &Path,
    runs: &[LidarRun],
    band_names: &[String],
    memory: Option<&crate::resources::memory::MemoryPlan>,
) -> Result<(), String> {
    for run in runs {
        let d = dir.join("lidar").join(&run.desc.name);
        std::fs::create_dir_all(d.join("raw"))
            .map_err(|e| format!("{}: cannot create folder: {e}", d.display()))?;
        if let Some(st) = &run.streamed {
            // Written while the scan ran: move the files into place.
            st.waveforms
                .commit()
                .map_err(|e| format!("{}: {e}", d.display()))?;
            st.raw
                .commit()
                .map_err(|e| format!("{}: {e}", d.display()))?;
        } else {
            let wf: Vec<_> = run.pulses.iter().map(|p| (p.id, &p.waveform)).collect();
            write_waveforms(&d, &wf).map_err(|e| format!("{}: {e}", d.display()))?;
            let raw: Vec<_> = run.pulses.iter().map(|p| (p.id, &p.raw)).collect();
            write_waveforms(&d.join("raw"), &raw).map_err(|e| format!("{}: {e}", d.display()))?;
        }
        for p in run.pulses.iter().take(QUICKLOOKS) {
            write_atomic(
                &d.join(format!("waveform_{:06}.svg", p.id)),
                waveform_svg(&p.waveform).as_bytes(),
            )?;
        }
        // Discrete returns, streamed from the run's pulses (two passes: the intensity and
        // the fusion colours are scaled by the scan's maxima).
        let fail = |e: String| format!("{}: {e}", d.display());
        let (mut emax, mut lmax) = (0.0f64, 0.0f64);
        for e in run.pulse_entries().map_err(fail)? {
            let e = e.map_err(fail)?;
            emax = e.returns.iter().map(|r| r.energy_j).fold(emax, f64::max);
            if let Some(rad) = &e.fusion_radiance {
                lmax = rad.iter().cloned().fold(lmax, f64::max);
            }
        }
        let lmax = lmax.max(1e-300);
        // The points of one pulse: returns by range, at most 15.
        let points_of_pulse = |p: &PulseEntry, fused: bool| -> Vec<LasPoint> {
            let mut rs = p.returns.clone();
            rs.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
            let n = rs.len().min(15);
            let mut out = Vec::with_capacity(n);
            for (i, r) in rs.iter().take(15).enumerate() {
                let pos = p.emitter + p.axis * r.range_m;
                let mut pt = LasPoint {
                    x: pos.x,
                    y: pos.y,
                    z: pos.z,
                    intensity: if emax > 0.0 {
                        (r.energy_j / emax * 65535.0).round().clamp(0.0, 65535.0) as u16
                    } else {
                        0
                    },
                    return_number: (i + 1) as u8,
                    number_of_returns: n as u8,
                    pulse_id: p.id,
                    gps_time: p.id as f64 * PULSE_PERIOD_S,
                    classification: 0,
                    scanner_channel: 0,
                    rgb: None,
                    extra: Vec::new(),
                };
                if fused && let Some(rad) = &p.fusion_radiance {
                    let c = |b: usize| {
                        (rad.get(b).or(rad.last()).copied().unwrap_or(0.0) / lmax * 65535.0)
                            .round()
                            .clamp(0.0, 65535.0) as u16
                    };
                    // RGB: bands 3, 2, 1 of the scene (or the available ones).
                    let nbd = rad.len();
                    pt.rgb = Some([c(2.min(nbd - 1)), c(1.min(nbd - 1)), c(0)]);
                    pt.extra = rad.clone();
                }
                out.push(pt);
            }
            out
        };
        let points_of = &points_of_pulse;
        // Points of every pulse, in order, from a fresh pass over the entries.
        let stream = |fused: bool| -> Result<_, String> {
            Ok(run.pulse_entries()?.flat_map(move |e| match e {
                Ok(e) => points_of(&e, fused).into_iter().map(Ok).collect::<Vec<_>>(),
                Err(e) => vec![Err(e)],
            }))
        };
        write_las_stream(
            &d.join("returns.las"),
            false,
            stream(false).map_err(fail)?,
            [1e-3; 3],
            [0.0; 3],
            &[],
        )?;
        if run.has_fusion() {
            let names: Vec<String> = band_names.iter().map(|b| format!("radiance_{b}")).collect();
            write_las_stream(
                &d.join("fusion.las"),
                true,
                stream(true).map_err(fail)?,
                [1e-3; 3],
                [0.0; 3],
                &names,
            )?;
        }
        if run.counted_totals().0 > 0 {
            let pts = run.counted_photons().map_err(fail)?.map(|c| {
                c.map(|c| LasPoint {
                    x: c.position.x,
                    y: c.position.y,
                    z: c.position.z,
                    intensity: 1,
                    return_number: 1,
                    number_of_returns: 1,
                    pulse_id: c.pulse,
                    gps_time: c.pulse as f64 * PULSE_PERIOD_S + c.time_ns * 1e-9,
                    // ASPRS: 1 unclassified (signal), 7 low noise (solar background, dark).
                    classification: if c.is_noise { 7 } else { 1 },
                    scanner_channel: 0,
                    rgb: None,
                    extra: Vec::new(),
                })
            });
            write_las_stream(
                &d.join("photon_counting.las"),
                false,
                pts,
                [1e-3; 3],
                [0.0; 3],
                &[],
            )?;
        }
        write_summary(&d.join("lidar.json"), run, memory)?;
    }
    Ok(())
}

/// `lidar.json`, serialised straight into the file (no JSON tree of the whole scan in memory:
/// a 250 000-pulse scan's tree took ~300 MiB). Keys in byte order within every object, as
/// `serde_json::Value` (a `BTreeMap`) prints them.
fn write_summary(
    path: &Path,
    run: &LidarRun,
    memory: Option<&crate::resources::memory::MemoryPlan>,
) -> Result<(), String> {
    use serde::Serialize;
    /// One pulse (fields in key order).
    #[derive(Serialize)]
    struct PulseSummary {
        axis: [f64; 3],
        emitter_m: [f64; 3],
        first_order_j: f64,
        id: u64,
        missed_j: f64,
        out_of_gate_j: f64,
        received_j: f64,
        returns: usize,
    }
    /// The pulses, serialised one by one as they are read (from memory or the spool).
    struct PerPulse<'a>(&'a LidarRun);
    impl Serialize for PerPulse<'_> {
        fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            use serde::ser::{Error, SerializeSeq};
            let mut seq = s.serialize_seq(Some(self.0.pulse_count()))?;
            for p in self.0.pulse_entries().map_err(S::Error::custom)? {
                let p = p.map_err(S::Error::custom)?;
                seq.serialize_element(&PulseSummary {
                    axis: p.axis.to_array(),
                    emitter_m: p.emitter.to_array(),
                    first_order_j: p.first_order_j,
                    id: p.id,
                    missed_j: p.missed_j,
                    out_of_gate_j: p.out_of_gate_j,
                    received_j: p.received_j,
                    returns: p.returns.len(),
                })?;
            }
            seq.end()
        }
    }
    /// The background rates, per pulse (photon counting; empty otherwise).
    struct Rates<'a>(&'a LidarRun);
    impl Serialize for Rates<'_> {
        fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            use serde::ser::{Error, SerializeSeq};
            let mut seq = s.serialize_seq(None)?;
            for p in self.0.pulse_entries().map_err(S::Error::custom)? {
                if let Some(r) = p.map_err(S::Error::custom)?.background_rate_hz {
                    seq.serialize_element(&r)?;
                }
            }
            seq.end()
        }
    }
    /// The whole file (fields in key order).
    #[derive(Serialize)]
    struct Summary<'a> {
        background_rate_hz: Rates<'a>,
        docs: serde_json::Value,
        instrument: serde_json::Value,
        #[serde(skip_serializing_if = "Option::is_none")]
        memory: Option<serde_json::Value>,
        notes: &'a [String],
        per_pulse: PerPulse<'a>,
        photon_counting_detections: usize,
        photon_counting_noise: usize,
        pulses: usize,
        pulses_per_second_per_core: f64,
        seconds: f64,
    }
    let threads = rayon::current_num_threads().max(1) as f64;
    let summary = Summary {
        background_rate_hz: Rates(run),
        docs: serde_json::json!({
            "received_j": "energy received inside the range gate (raw waveform), J",
            "first_order_j": "first-order part of received_j, J",
            "out_of_gate_j": "energy received outside the range gate, J: exact before the gate; after the gate a lower bound, since photons whose path so far plus their distance to the receiver exceeds the gate end can never be recorded inside it and are stopped",
            "missed_j": "emitted energy that missed the scene (isolated scenes), J",
        }),
        // Through a `Value`, so that its keys are sorted as everywhere else in the file.
        instrument: serde_json::to_value(&run.desc)
            .map_err(|e| format!("{}: {e}", path.display()))?,
        memory: memory.map(|m| m.record()),
        notes: &run.notes,
        per_pulse: PerPulse(run),
        photon_counting_detections: run.counted_totals().0,
        photon_counting_noise: run.counted_totals().1,
        pulses: run.pulse_count(),
        pulses_per_second_per_core: run.pulse_count() as f64 / (run.seconds.max(1e-9) * threads),
        seconds: run.seconds,
    };
    write_atomic_with(path, |w| {
        serde_json::to_writer_pretty(w, &summary).map_err(std::io::Error::other)
    })
}
