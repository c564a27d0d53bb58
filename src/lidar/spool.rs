//! Per-pulse results of a streamed LiDAR scan, spooled to temporary files while the scan runs
//! so that the memory of a scan is bounded by one chunk whatever its number of pulses.
//!
//! A long scan ([`crate::lidar::simulate::LidarChunks`]) writes its waveforms to disk chunk by
//! chunk ([`crate::lidar::waveform_io::WaveformStream`]); everything else it produces per pulse
//! (energies, discrete returns, solar background rate, fused radiance) and per photon-counting
//! detection goes to a [`Spool`]: a temporary file of little-endian 64-bit words in the product
//! folder, read back in pulse order by the Output stage ([`PulseEntries`], [`CountedPhotons`]).
//! Values are stored as their bit patterns (`f64::to_bits`): read back bit for bit, so the
//! products of a streamed scan are the bytes of the same scan run in memory. A spool file is
//! removed when its [`ClosedSpool`] is dropped (after the run, or after an error).

use crate::lidar::returns::Return;
use crate::lidar::run::{CountedPhoton, PulseRecord};
use glam::DVec3;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A temporary name unique within the process, hidden in `dir`.
fn spool_path(dir: &Path, what: &str) -> PathBuf {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    dir.join(format!(
        ".{what}.spool-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ))
}

/// A spool being written: 64-bit words appended to a temporary file.
#[derive(Debug)]
pub struct Spool {
    writer: BufWriter<File>,
    closed: ClosedSpool,
}

/// A finished spool file, read back with [`ClosedSpool::words`]; removed when dropped.
#[derive(Debug)]
pub struct ClosedSpool {
    path: PathBuf,
    /// Records (pulses or detections) in the file.
    pub records: usize,
}

impl Drop for ClosedSpool {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

impl Spool {
    /// Starts a spool of `what` (a name for the file and the messages) in `dir`.
    pub fn create(dir: &Path, what: &str) -> Result<Self, String> {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("{}: cannot create folder: {e}", dir.display()))?;
        // `closed` exists before the file does: an error below removes what was created.
        let closed = ClosedSpool {
            path: spool_path(dir, what),
            records: 0,
        };
        let writer = File::create(&closed.path)
            .map(BufWriter::new)
            .map_err(|e| format!("{}: cannot create: {e}", closed.path.display()))?;
        Ok(Self { writer, closed })
    }

    /// Appends one record of words.
    pub fn push(&mut self, words: &[u64]) -> Result<(), String> {
        for w in words {
            self.writer
                .write_all(&w.to_le_bytes())
                .map_err(|e| format!("{}: cannot write: {e}", self.closed.path.display()))?;
        }
        self.closed.records += 1;
        Ok(())
    }

    /// Flushes and closes the file.
    pub fn finish(self) -> Result<ClosedSpool, String> {
        let Spool { writer, closed } = self;
        writer
            .into_inner()
            .map_err(|e| format!("{}: cannot write: {}", closed.path.display(), e.error()))?;
        Ok(closed)
    }
}

impl ClosedSpool {
    /// The words of the file, from the start.
    pub fn words(&self) -> Result<Words, String> {
        let f = File::open(&self.path)
            .map_err(|e| format!("{}: cannot read: {e}", self.path.display()))?;
        Ok(Words {
            reader: BufReader::new(f),
            path: self.path.clone(),
        })
    }
}

/// Sequential reader of a spool's words.
pub struct Words {
    reader: BufReader<File>,
    path: PathBuf,
}

impl Words {
    /// The next word (an error at the end of the file: records are read by count).
    pub fn word(&mut self) -> Result<u64, String> {
        let mut b = [0u8; 8];
        self.reader
            .read_exact(&mut b)
            .map_err(|e| format!("{}: cannot read: {e}", self.path.display()))?;
        Ok(u64::from_le_bytes(b))
    }

    /// The next word as an `f64` (bit pattern).
    pub fn f64(&mut self) -> Result<f64, String> {
        self.word().map(f64::from_bits)
    }

    /// The next three words as a vector.
    pub fn dvec3(&mut self) -> Result<DVec3, String> {
        Ok(DVec3::new(self.f64()?, self.f64()?, self.f64()?))
    }

    /// The next word as a count.
    pub fn count(&mut self) -> Result<usize, String> {
        let v = self.word()?;
        usize::try_from(v).map_err(|_| format!("{}: corrupt count {v}", self.path.display()))
    }
}

/// One pulse of a LiDAR run as the products need it (no waveforms): energies, returns, and the
/// per-pulse values of photon counting and fusion.
#[derive(Debug, Clone, PartialEq)]
pub struct PulseEntry {
    /// Pulse ID.
    pub id: u64,
    /// Emitter position (scene coordinates), m.
    pub emitter: DVec3,
    /// Beam axis (unit propagation direction).
    pub axis: DVec3,
    /// Received energy inside the range gate, J.
    pub received_j: f64,
    /// First-order part of `received_j`, J.
    pub first_order_j: f64,
    /// Received energy outside the range gate, J.
    pub out_of_gate_j: f64,
    /// Emitted energy that missed the scene, J.
    pub missed_j: f64,
    /// Discrete returns, in the order of detection.
    pub returns: Vec<Return>,
    /// Solar background rate (photo-electrons s⁻¹), photon-counting instruments only.
    pub background_rate_hz: Option<f64>,
    /// Passive spectral radiance at the footprint centre per scene band (W m⁻² sr⁻¹ µm⁻¹),
    /// fusion only.
    pub fusion_radiance: Option<Vec<f64>>,
}

impl PulseEntry {
    /// The entry of a pulse record, with its background rate and fused radiance.
    pub fn of(
        p: &PulseRecord,
        background_rate_hz: Option<f64>,
        fusion_radiance: Option<Vec<f64>>,
    ) -> Self {
        Self {
            id: p.id,
            emitter: p.emitter,
            axis: p.axis,
            received_j: p.received_j,
            first_order_j: p.first_order_j,
            out_of_gate_j: p.out_of_gate_j,
            missed_j: p.missed_j,
            returns: p.returns.clone(),
            background_rate_hz,
            fusion_radiance,
        }
    }

    /// Appends the entry to a pulse spool: id, emitter, axis, four energies, the returns
    /// (count, then five values each), then the optional background rate and radiances (count
    /// + values; a count of `u64::MAX` for none).
    pub fn spool(&self, s: &mut Spool) -> Result<(), String> {
        let mut w: Vec<u64> = Vec::with_capacity(16 + 5 * self.returns.len());
        w.push(self.id);
        for v in self
            .emitter
            .to_array()
            .into_iter()
            .chain(self.axis.to_array())
        {
            w.push(v.to_bits());
        }
        for v in [
            self.received_j,
            self.first_order_j,
            self.out_of_gate_j,
            self.missed_j,
        ] {
            w.push(v.to_bits());
        }
        w.push(self.returns.len() as u64);
        for r in &self.returns {
            for v in [
                r.time_ns,
                r.range_m,
                r.amplitude_j_per_bin,
                r.width_ns,
                r.energy_j,
            ] {
                w.push(v.to_bits());
            }
        }
        match self.background_rate_hz {
            Some(v) => w.extend([1, v.to_bits()]),
            None => w.push(0),
        }
        match &self.fusion_radiance {
            Some(v) => {
                w.push(v.len() as u64);
                w.extend(v.iter().map(|x| x.to_bits()));
            }
            None => w.push(u64::MAX),
        }
        s.push(&w)
    }

    fn read(w: &mut Words) -> Result<Self, String> {
        let id = w.word()?;
        let emitter = w.dvec3()?;
        let axis = w.dvec3()?;
        let (received_j, first_order_j, out_of_gate_j, missed_j) =
            (w.f64()?, w.f64()?, w.f64()?, w.f64()?);
        let n = w.count()?;
        let mut returns = Vec::with_capacity(n.min(64));
        for _ in 0..n {
            returns.push(Return {
                time_ns: w.f64()?,
                range_m: w.f64()?,
                amplitude_j_per_bin: w.f64()?,
                width_ns: w.f64()?,
                energy_j: w.f64()?,
            });
        }
        let background_rate_hz = match w.word()? {
            0 => None,
            _ => Some(w.f64()?),
        };
        let fusion_radiance = match w.word()? {
            u64::MAX => None,
            n => {
                let mut v = Vec::with_capacity((n as usize).min(4096));
                for _ in 0..n {
                    v.push(w.f64()?);
                }
                Some(v)
            }
        };
        Ok(Self {
            id,
            emitter,
            axis,
            received_j,
            first_order_j,
            out_of_gate_j,
            missed_j,
            returns,
            background_rate_hz,
            fusion_radiance,
        })
    }
}

/// The pulses of a spool, in order.
pub struct PulseEntries {
    words: Words,
    left: usize,
}

impl PulseEntries {
    /// Reads the pulses of `spool`.
    pub fn new(spool: &ClosedSpool) -> Result<Self, String> {
        Ok(Self {
            words: spool.words()?,
            left: spool.records,
        })
    }
}

impl Iterator for PulseEntries {
    type Item = Result<PulseEntry, String>;
    fn next(&mut self) -> Option<Self::Item> {
        if self.left == 0 {
            return None;
        }
        self.left -= 1;
        Some(PulseEntry::read(&mut self.words))
    }
}

/// Appends a photon-counting detection to a spool (7 words).
pub fn spool_counted(c: &CountedPhoton, s: &mut Spool) -> Result<(), String> {
    s.push(&[
        c.pulse,
        u64::from(c.shot),
        c.position.x.to_bits(),
        c.position.y.to_bits(),
        c.position.z.to_bits(),
        c.time_ns.to_bits(),
        u64::from(c.is_noise),
    ])
}

/// The photon-counting detections of a spool, in order.
pub struct CountedPhotons {
    words: Words,
    left: usize,
}

impl CountedPhotons {
    /// Reads the detections of `spool`.
    pub fn new(spool: &ClosedSpool) -> Result<Self, String> {
        Ok(Self {
            words: spool.words()?,
            left: spool.records,
        })
    }

    fn read(&mut self) -> Result<CountedPhoton, String> {
        let w = &mut self.words;
        let pulse = w.word()?;
        let shot = w.word()?;
        Ok(CountedPhoton {
            pulse,
            shot: u32::try_from(shot).map_err(|_| format!("corrupt shot index {shot}"))?,
            position: w.dvec3()?,
            time_ns: w.f64()?,
            is_noise: w.word()? != 0,
        })
    }
}

impl Iterator for CountedPhotons {
    type Item = Result<CountedPhoton, String>;
    fn next(&mut self) -> Option<Self::Item> {
        if self.left == 0 {
            return None;
        }
        self.left -= 1;
        Some(self.read())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Entries and detections read back bit for bit (NaN payloads, −0, subnormals included),
    /// and the file vanishes with its spool.
    #[test]
    fn spooled_records_read_back_bit_for_bit_and_vanish() {
        let dir = std::env::temp_dir().join(format!("lumenscape-spool-{}", std::process::id()));
        let r = Return {
            time_ns: 3.25,
            range_m: -0.0,
            amplitude_j_per_bin: 5e-324,
            width_ns: f64::from_bits(0x7ff8_0000_0000_0001),
            energy_j: 1e-13,
        };
        let entries = vec![
            PulseEntry {
                id: 7,
                emitter: DVec3::new(1.0, -2.0, 3e5),
                axis: DVec3::NEG_Z,
                received_j: 1.5e-9,
                first_order_j: 1e-9,
                out_of_gate_j: 0.0,
                missed_j: 2e-300,
                returns: vec![r, r],
                background_rate_hz: Some(1.25e6),
                fusion_radiance: Some(vec![0.1, 0.2, 0.3]),
            },
            PulseEntry {
                id: u64::MAX - 1,
                emitter: DVec3::ZERO,
                axis: DVec3::X,
                received_j: 0.0,
                first_order_j: 0.0,
                out_of_gate_j: 1.0,
                missed_j: 0.0,
                returns: vec![],
                background_rate_hz: None,
                fusion_radiance: Some(vec![]),
            },
            PulseEntry {
                id: 0,
                emitter: DVec3::ONE,
                axis: DVec3::Y,
                received_j: 1.0,
                first_order_j: 0.5,
                out_of_gate_j: 0.0,
                missed_j: 0.0,
                returns: vec![r],
                background_rate_hz: None,
                fusion_radiance: None,
            },
        ];
        let mut s = Spool::create(&dir, "pulses").unwrap();
        for e in &entries {
            e.spool(&mut s).unwrap();
        }
        let closed = s.finish().unwrap();
        assert_eq!(closed.records, 3);
        let back: Vec<PulseEntry> = PulseEntries::new(&closed)
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        assert_eq!(format!("{back:?}"), format!("{entries:?}"));
        assert_eq!(back[0].returns[0].width_ns.to_bits(), 0x7ff8_0000_0000_0001);
        assert_eq!(back[0].returns[0].range_m.to_bits(), (-0.0f64).to_bits());
        // Twice: a closed spool is read again from its start.
        assert_eq!(PulseEntries::new(&closed).unwrap().count(), 3);

        let counted = vec![
            CountedPhoton {
                pulse: 3,
                shot: 1,
                position: DVec3::new(0.5, 0.25, -1.0),
                time_ns: 6671.28,
                is_noise: true,
            },
            CountedPhoton {
                pulse: 4,
                shot: u32::MAX,
                position: DVec3::ZERO,
                time_ns: 0.0,
                is_noise: false,
            },
        ];
        let mut s = Spool::create(&dir, "counted").unwrap();
        for c in &counted {
            spool_counted(c, &mut s).unwrap();
        }
        let closed_c = s.finish().unwrap();
        let back: Vec<CountedPhoton> = CountedPhotons::new(&closed_c)
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        assert_eq!(back, counted);

        let paths = [closed.path.clone(), closed_c.path.clone()];
        assert!(paths.iter().all(|p| p.exists()));
        drop((closed, closed_c));
        assert!(paths.iter().all(|p| !p.exists()), "spool files left");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
