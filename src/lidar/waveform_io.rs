//! Compact waveform products (physics.md §9.4, design.md §5 "LiDAR: waveforms"):
//!
//! * `waveforms.f32` — for each pulse, in index order: `n_bins` little-endian f32 of the total
//!   waveform, then `n_bins` f32 of the first-order waveform (J per bin; f32 keeps 7 significant
//!   digits and its normal range reaches 1.2e-38 J, far below the 1e-13 J packets of
//!   GLAS-like geometries);
//! * `waveforms_index.csv` — `pulse_id,t0_ns,dt_ns,n_bins,byte_offset,total_energy_j,
//!   first_order_energy_j`, where `byte_offset` locates the total waveform (first-order follows
//!   at `byte_offset + 4·n_bins`) and the energies are exact f64 sums;
//! * [`waveform_svg`] — a self-contained SVG quick-look (no external crate).
//!
//! Both files are written atomically (temporary file + rename, the index last): after an error
//! no partial product is left.

use super::LidarError;
use super::waveform::Waveform;
use crate::io::atomic::{tmp_path, write_atomic};
use std::fmt::Write as _;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// File name of the binary waveform data.
pub const WAVEFORM_DATA_FILE: &str = "waveforms.f32";
/// File name of the CSV index.
pub const WAVEFORM_INDEX_FILE: &str = "waveforms_index.csv";
/// Header line of the CSV index.
pub const WAVEFORM_INDEX_HEADER: &str =
    "pulse_id,t0_ns,dt_ns,n_bins,byte_offset,total_energy_j,first_order_energy_j";

/// Paths written by [`write_waveforms`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WaveformFiles {
    /// Binary data file.
    pub data: PathBuf,
    /// CSV index.
    pub index: PathBuf,
}

/// One row of the CSV index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveformIndexRow {
    /// Pulse identifier.
    pub pulse_id: u64,
    /// Start of bin 0 (ns).
    pub t0_ns: f64,
    /// Bin width (ns).
    pub dt_ns: f64,
    /// Number of bins.
    pub n_bins: usize,
    /// Byte offset of the total waveform in the data file.
    pub byte_offset: u64,
    /// Total energy (J, f64 sum of the original waveform).
    pub total_energy_j: f64,
    /// First-order energy (J).
    pub first_order_energy_j: f64,
}

/// Appends waveforms in the product format: data bytes to `data`, index lines to `index`
/// (header written by [`WaveformWriter::new`]), tracking the byte offset. Shared by the
/// in-memory [`write_waveforms`] and the file-backed [`WaveformStream`], so both give the same
/// bytes.
struct WaveformWriter<D: Write, I: Write> {
    data: D,
    index: I,
    offset: u64,
}

impl<D: Write, I: Write> WaveformWriter<D, I> {
    fn new(data: D, mut index: I) -> std::io::Result<Self> {
        writeln!(index, "{WAVEFORM_INDEX_HEADER}")?;
        Ok(Self {
            data,
            index,
            offset: 0,
        })
    }

    /// Appends one waveform (validated by the caller).
    fn append(&mut self, id: u64, w: &Waveform) -> std::io::Result<()> {
        let mut bytes = Vec::with_capacity(8 * w.n_bins());
        for v in w.total.iter().chain(&w.first_order) {
            bytes.extend_from_slice(&(*v as f32).to_le_bytes());
        }
        self.data.write_all(&bytes)?;
        // `{:e}` prints the shortest representation that round-trips exactly.
        writeln!(
            self.index,
            "{id},{:e},{:e},{},{},{:e},{:e}",
            w.t0_ns,
            w.dt_ns,
            w.n_bins(),
            self.offset,
            w.total_energy_j(),
            w.first_order_energy_j()
        )?;
        self.offset += bytes.len() as u64;
        Ok(())
    }
}

fn validate_all(waveforms: &[(u64, &Waveform)]) -> Result<(), LidarError> {
    for (id, w) in waveforms {
        w.validate()
            .map_err(|e| LidarError::InvalidInput(format!("pulse {id}: {e}")))?;
    }
    Ok(())
}

/// Writes `waveforms` (pulse id, waveform) into `dir` (created if missing). Every waveform is
/// validated first (finite, non-negative); nothing is written if one is invalid.
pub fn write_waveforms(
    dir: &Path,
    waveforms: &[(u64, &Waveform)],
) -> Result<WaveformFiles, LidarError> {
    validate_all(waveforms)?;
    std::fs::create_dir_all(dir)
        .map_err(|e| LidarError::Io(format!("{}: cannot create folder: {e}", dir.display())))?;
    let data_path = dir.join(WAVEFORM_DATA_FILE);
    let index_path = dir.join(WAVEFORM_INDEX_FILE);

    let total_bins: usize = waveforms.iter().map(|(_, w)| 2 * w.n_bins()).sum();
    let mut wr = WaveformWriter::new(
        Vec::with_capacity(4 * total_bins),
        Vec::with_capacity(64 * (waveforms.len() + 1)),
    )
    .map_err(|e| LidarError::Io(e.to_string()))?;
    for (id, w) in waveforms {
        wr.append(*id, w)
            .map_err(|e| LidarError::Io(e.to_string()))?;
    }
    write_atomic(&data_path, &wr.data).map_err(LidarError::Io)?;
    if let Err(e) = write_atomic(&index_path, &wr.index) {
        let _ = std::fs::remove_file(&data_path);
        let _ = std::fs::remove_file(tmp_path(&index_path));
        return Err(LidarError::Io(e));
    }
    Ok(WaveformFiles {
        data: data_path,
        index: index_path,
    })
}

/// The waveform product of a long scan written chunk by chunk (memory bounded by one chunk
/// instead of the whole scan), into temporary files next to the final ones. The bytes are
/// those of [`write_waveforms`] on the same waveforms in the same order.
/// [`WaveformStream::finish`] closes the files; [`StreamedWaveforms::commit`] renames them into
/// place (data first, index last, as [`write_waveforms`]). Until then nothing is visible
/// under the final names, and dropping either value removes the temporary files: after an
/// error no partial product is left.
pub struct WaveformStream {
    writer: WaveformWriter<BufWriter<File>, BufWriter<File>>,
    files: StreamedWaveforms,
}

/// Closed temporary files of a [`WaveformStream`], waiting for [`StreamedWaveforms::commit`].
#[derive(Debug)]
pub struct StreamedWaveforms {
    tmp: WaveformFiles,
    fin: WaveformFiles,
    committed: AtomicBool,
}

/// A temporary name unique within the process (the scan may be re-run in the same folder).
fn stream_tmp(path: &Path) -> PathBuf {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(
        ".{name}.stream-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ))
}

impl WaveformStream {
    /// Starts a product in `dir` (created if missing).
    pub fn create(dir: &Path) -> Result<Self, LidarError> {
        std::fs::create_dir_all(dir)
            .map_err(|e| LidarError::Io(format!("{}: cannot create folder: {e}", dir.display())))?;
        let fin = WaveformFiles {
            data: dir.join(WAVEFORM_DATA_FILE),
            index: dir.join(WAVEFORM_INDEX_FILE),
        };
        let tmp = WaveformFiles {
            data: stream_tmp(&fin.data),
            index: stream_tmp(&fin.index),
        };
        let files = StreamedWaveforms {
            tmp,
            fin,
            committed: AtomicBool::new(false),
        };
        let open = |p: &Path| {
            File::create(p)
                .map(BufWriter::new)
                .map_err(|e| LidarError::Io(format!("{}: cannot create: {e}", p.display())))
        };
        // `files` exists before the files do: an error below removes what was created.
        let data = open(&files.tmp.data)?;
        let index = open(&files.tmp.index)?;
        let writer = WaveformWriter::new(data, index).map_err(|e| {
            LidarError::Io(format!("{}: cannot write: {e}", files.tmp.index.display()))
        })?;
        Ok(Self { writer, files })
    }

    /// Appends waveforms (pulse id, waveform), validated first: nothing of the batch is
    /// written if one is invalid.
    pub fn append(&mut self, waveforms: &[(u64, &Waveform)]) -> Result<(), LidarError> {
        validate_all(waveforms)?;
        for (id, w) in waveforms {
            self.writer.append(*id, w).map_err(|e| {
                LidarError::Io(format!(
                    "{}: cannot write: {e}",
                    self.files.tmp.data.display()
                ))
            })?;
        }
        Ok(())
    }

    /// Flushes and closes the temporary files.
    pub fn finish(self) -> Result<StreamedWaveforms, LidarError> {
        let Self { writer, files } = self;
        let WaveformWriter { data, index, .. } = writer;
        for (w, p) in [(data, &files.tmp.data), (index, &files.tmp.index)] {
            let f = w
                .into_inner()
                .map_err(|e| LidarError::Io(format!("{}: cannot write: {e}", p.display())))?;
            f.sync_all()
                .map_err(|e| LidarError::Io(format!("{}: cannot write: {e}", p.display())))?;
        }
        Ok(files)
    }
}

impl StreamedWaveforms {
    /// Renames the temporary files to their final names (data, then index). Afterwards the
    /// value owns nothing; a second call is an error.
    pub fn commit(&self) -> Result<WaveformFiles, LidarError> {
        if self.committed.swap(true, Ordering::AcqRel) {
            return Err(LidarError::Io(format!(
                "{}: already committed",
                self.fin.data.display()
            )));
        }
        let mv = |from: &Path, to: &Path| {
            std::fs::rename(from, to)
                .map_err(|e| LidarError::Io(format!("{}: cannot write: {e}", to.display())))
        };
        let res = mv(&self.tmp.data, &self.fin.data).and_then(|()| {
            mv(&self.tmp.index, &self.fin.index).inspect_err(|_| {
                let _ = std::fs::remove_file(&self.fin.data);
            })
        });
        if res.is_err() {
            let _ = std::fs::remove_file(&self.tmp.data);
            let _ = std::fs::remove_file(&self.tmp.index);
        }
        res.map(|()| self.fin.clone())
    }

    /// Final paths of the product.
    pub fn files(&self) -> &WaveformFiles {
        &self.fin
    }
}

impl Drop for StreamedWaveforms {
    fn drop(&mut self) {
        if !*self.committed.get_mut() {
            let _ = std::fs::remove_file(&self.tmp.data);
            let _ = std::fs::remove_file(&self.tmp.index);
        }
    }
}

/// Reads back a product written by [`write_waveforms`] (values as stored, i.e. f32-rounded).
pub fn read_waveforms(dir: &Path) -> Result<Vec<(WaveformIndexRow, Waveform)>, LidarError> {
    let index_path = dir.join(WAVEFORM_INDEX_FILE);
    let data_path = dir.join(WAVEFORM_DATA_FILE);
    let text = std::fs::read_to_string(&index_path)
        .map_err(|e| LidarError::Io(format!("{}: cannot read: {e}", index_path.display())))?;
    let data = std::fs::read(&data_path)
        .map_err(|e| LidarError::Io(format!("{}: cannot read: {e}", data_path.display())))?;
    let bad = |line: usize, what: &str| {
        LidarError::Io(format!("{}:{line}: {what}", index_path.display()))
    };
    let mut lines = text.lines();
    if lines.next() != Some(WAVEFORM_INDEX_HEADER) {
        return Err(bad(1, "unexpected header"));
    }
    let mut out = Vec::new();
    for (ln, line) in lines.enumerate() {
        let ln = ln + 2;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 7 {
            return Err(bad(ln, "expected 7 fields"));
        }
        let pf = |s: &str| s.parse::<f64>().map_err(|_| bad(ln, "bad number"));
        let pu = |s: &str| s.parse::<u64>().map_err(|_| bad(ln, "bad integer"));
        let row = WaveformIndexRow {
            pulse_id: pu(f[0])?,
            t0_ns: pf(f[1])?,
            dt_ns: pf(f[2])?,
            n_bins: pu(f[3])? as usize,
            byte_offset: pu(f[4])?,
            total_energy_j: pf(f[5])?,
            first_order_energy_j: pf(f[6])?,
        };
        let start = row.byte_offset as usize;
        let end = row
            .n_bins
            .checked_mul(8)
            .and_then(|b| b.checked_add(start))
            .filter(|&e| e <= data.len())
            .ok_or_else(|| bad(ln, "waveform extends past the end of the data file"))?;
        let vals: Vec<f64> = data[start..end]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64)
            .collect();
        let (total, first) = vals.split_at(row.n_bins);
        out.push((
            row,
            Waveform {
                t0_ns: row.t0_ns,
                dt_ns: row.dt_ns,
                total: total.to_vec(),
                first_order: first.to_vec(),
            },
        ));
    }
    Ok(out)
}

/// SVG quick-look of a waveform: total (black) and first order (orange dashed) energy per bin
/// against time (ns), linear axes with ticks, 720×400 px. An empty or invalid waveform gives an
/// SVG that says so instead of a plot.
pub fn waveform_svg(w: &Waveform) -> String {
    const W: f64 = 720.0;
    const H: f64 = 400.0;
    const ML: f64 = 90.0;
    const MR: f64 = 20.0;
    const MT: f64 = 30.0;
    const MB: f64 = 50.0;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{W}" height="{H}" fill="white"/>"#);
    let message = match w.validate() {
        Err(e) => Some(format!("invalid waveform: {e}")),
        Ok(()) if w.is_empty() => Some("empty waveform".to_string()),
        Ok(()) => None,
    };
    if let Some(m) = message {
        let m = m
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;");
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{m}</text>"#,
            W / 2.0,
            H / 2.0
        );
        s.push_str("</svg>\n");
        return s;
    }
    let n = w.n_bins();
    let t_lo = w.t0_ns;
    let t_hi = w.t0_ns + n as f64 * w.dt_ns;
    let ymax = w
        .total
        .iter()
        .chain(&w.first_order)
        .cloned()
        .fold(0.0, f64::max);
    let ytop = if ymax > 0.0 { ymax * 1.05 } else { 1.0 };
    let px = |t: f64| ML + (t - t_lo) / (t_hi - t_lo) * (W - ML - MR);
    let py = |v: f64| H - MB - v / ytop * (H - MT - MB);
    // Axes.
    let _ = writeln!(
        s,
        r#"<path d="M{ML} {MT} L{ML} {} L{} {}" fill="none" stroke="black"/>"#,
        H - MB,
        W - MR,
        H - MB
    );
    for t in nice_ticks(t_lo, t_hi) {
        let x = px(t);
        let _ = writeln!(
            s,
            r#"<line x1="{x:.1}" y1="{}" x2="{x:.1}" y2="{}" stroke="black"/><text x="{x:.1}" y="{}" text-anchor="middle">{}</text>"#,
            H - MB,
            H - MB + 5.0,
            H - MB + 18.0,
            fmt_tick(t)
        );
    }
    for v in nice_ticks(0.0, ytop) {
        let y = py(v);
        let _ = writeln!(
            s,
            r#"<line x1="{}" y1="{y:.1}" x2="{ML}" y2="{y:.1}" stroke="black"/><text x="{}" y="{:.1}" text-anchor="end">{}</text>"#,
            ML - 5.0,
            ML - 8.0,
            y + 4.0,
            fmt_tick(v)
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">time (ns)</text>"#,
        (ML + W - MR) / 2.0,
        H - 10.0
    );
    let _ = writeln!(
        s,
        r#"<text x="16" y="{}" text-anchor="middle" transform="rotate(-90 16 {})">energy per bin (J)</text>"#,
        (MT + H - MB) / 2.0,
        (MT + H - MB) / 2.0
    );
    // Curves as step-free polylines through bin centres.
    for (vals, style) in [
        (
            &w.first_order,
            r##"stroke="#e07000" stroke-dasharray="6 3""##,
        ),
        (&w.total, r#"stroke="black""#),
    ] {
        let mut pts = String::with_capacity(16 * n);
        for (i, v) in vals.iter().enumerate() {
            let _ = write!(pts, "{:.2},{:.2} ", px(w.bin_centre_ns(i)), py(*v));
        }
        let _ = writeln!(
            s,
            r#"<polyline points="{}" fill="none" {style} stroke-width="1.5"/>"#,
            pts.trim_end()
        );
    }
    // Legend.
    let _ = writeln!(
        s,
        r##"<line x1="{0}" y1="14" x2="{1}" y2="14" stroke="black" stroke-width="1.5"/><text x="{2}" y="18">total</text><line x1="{3}" y1="14" x2="{4}" y2="14" stroke="#e07000" stroke-dasharray="6 3" stroke-width="1.5"/><text x="{5}" y="18">first order</text>"##,
        W - 250.0,
        W - 225.0,
        W - 220.0,
        W - 160.0,
        W - 135.0,
        W - 130.0
    );
    s.push_str("</svg>\n");
    s
}

/// About five round-valued ticks covering [lo, hi].
fn nice_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = hi - lo;
    if !(span > 0.0 && span.is_finite()) {
        return vec![lo];
    }
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|st| span / st <= 6.0)
        .unwrap_or(10.0 * mag);
    let mut t = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while t <= hi + 1e-9 * step && out.len() < 20 {
        out.push(t);
        t += step;
    }
    out
}

fn fmt_tick(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e-2 && v.abs() < 1e5 {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The streamed product is the bytes of the in-memory one; an invalid waveform writes
    /// nothing of its batch; a stream dropped before `commit` leaves no file.
    #[test]
    fn streamed_products_match_and_vanish_when_dropped() {
        let root = std::env::temp_dir().join(format!("ls-wfstream-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let w = |k: usize| Waveform {
            t0_ns: 10.0 + k as f64,
            dt_ns: 0.5,
            total: (0..k + 1).map(|i| 1e-13 * (i + 1) as f64).collect(),
            first_order: (0..k + 1).map(|i| 1e-14 * i as f64).collect(),
        };
        let all: Vec<Waveform> = (0..5).map(w).collect();
        let pairs: Vec<(u64, &Waveform)> = all
            .iter()
            .enumerate()
            .map(|(i, w)| (i as u64 * 3, w))
            .collect();
        let mem = root.join("mem");
        write_waveforms(&mem, &pairs).unwrap();
        let st = root.join("st");
        let mut s = WaveformStream::create(&st).unwrap();
        s.append(&pairs[..2]).unwrap();
        let mut bad = w(1);
        bad.total[0] = f64::NAN;
        assert!(s.append(&[(99, &all[2]), (100, &bad)]).is_err());
        s.append(&pairs[2..]).unwrap();
        let files = s.finish().unwrap();
        assert!(
            !st.join(WAVEFORM_DATA_FILE).exists(),
            "visible before commit"
        );
        files.commit().unwrap();
        assert!(files.commit().is_err());
        for f in [WAVEFORM_DATA_FILE, WAVEFORM_INDEX_FILE] {
            assert_eq!(
                std::fs::read(mem.join(f)).unwrap(),
                std::fs::read(st.join(f)).unwrap(),
                "{f}"
            );
        }
        drop(files);
        assert!(
            st.join(WAVEFORM_DATA_FILE).exists(),
            "committed files removed"
        );
        // Dropped before commit (an error elsewhere): nothing left in the folder.
        let gone = root.join("gone");
        let mut s = WaveformStream::create(&gone).unwrap();
        s.append(&pairs).unwrap();
        drop(s.finish().unwrap());
        assert_eq!(std::fs::read_dir(&gone).unwrap().count(), 0);
        let mut s = WaveformStream::create(&gone).unwrap();
        s.append(&pairs).unwrap();
        drop(s);
        assert_eq!(std::fs::read_dir(&gone).unwrap().count(), 0);
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn ticks() {
        let t = nice_ticks(0.0, 10.0);
        assert_eq!(t, vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        assert_eq!(nice_ticks(3.0, 3.0), vec![3.0]);
        assert_eq!(fmt_tick(2.5), "2.5");
        assert_eq!(fmt_tick(1e-13), "1.00e-13");
    }

    #[test]
    fn svg_for_empty_and_invalid() {
        let s = waveform_svg(&Waveform::zeros(0.0, 1.0, 0));
        assert!(s.contains("empty waveform") && s.ends_with("</svg>\n"));
        let mut w = Waveform::zeros(0.0, 1.0, 3);
        w.total[0] = f64::NAN;
        assert!(waveform_svg(&w).contains("invalid waveform"));
        let z = waveform_svg(&Waveform::zeros(0.0, 1.0, 3));
        assert!(!z.contains("NaN"));
    }
}
