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
use std::path::{Path, PathBuf};

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

/// Writes `waveforms` (pulse id, waveform) into `dir` (created if missing). Every waveform is
/// validated first (finite, non-negative); nothing is written if one is invalid.
pub fn write_waveforms(
    dir: &Path,
    waveforms: &[(u64, &Waveform)],
) -> Result<WaveformFiles, LidarError> {
    for (id, w) in waveforms {
        w.validate()
            .map_err(|e| LidarError::InvalidInput(format!("pulse {id}: {e}")))?;
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| LidarError::Io(format!("{}: cannot create folder: {e}", dir.display())))?;
    let data_path = dir.join(WAVEFORM_DATA_FILE);
    let index_path = dir.join(WAVEFORM_INDEX_FILE);

    let total_bins: usize = waveforms.iter().map(|(_, w)| 2 * w.n_bins()).sum();
    let mut data = Vec::with_capacity(4 * total_bins);
    let mut index = String::with_capacity(64 * (waveforms.len() + 1));
    index.push_str(WAVEFORM_INDEX_HEADER);
    index.push('\n');
    for (id, w) in waveforms {
        let offset = data.len() as u64;
        for v in w.total.iter().chain(&w.first_order) {
            data.extend_from_slice(&(*v as f32).to_le_bytes());
        }
        // `{:e}` prints the shortest representation that round-trips exactly.
        let _ = writeln!(
            index,
            "{id},{:e},{:e},{},{offset},{:e},{:e}",
            w.t0_ns,
            w.dt_ns,
            w.n_bins(),
            w.total_energy_j(),
            w.first_order_energy_j()
        );
    }
    write_atomic(&data_path, &data).map_err(LidarError::Io)?;
    if let Err(e) = write_atomic(&index_path, index.as_bytes()) {
        let _ = std::fs::remove_file(&data_path);
        let _ = std::fs::remove_file(tmp_path(&index_path));
        return Err(LidarError::Io(e));
    }
    Ok(WaveformFiles {
        data: data_path,
        index: index_path,
    })
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
