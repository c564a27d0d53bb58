//! Discrete returns by Gaussian decomposition (Hofton, Minster & Blair 2000, *IEEE TGRS*
//! 38:1989; Wagner et al. 2006, *ISPRS J.* 60:100): initial components from the waveform's
//! peaks, components added at the largest residual, merged and dropped, each set fitted by
//! [`super::fit`]'s Levenberg–Marquardt; the bin-integrated model and its Jacobian.

use super::fit::{Fitter, normal_tail_and_pdf};
use super::{DecompositionSettings, Return, prepare};
use crate::lidar::LidarError;
use crate::lidar::special::{erf, normal_interval};
use crate::lidar::waveform::{Waveform, range_m_from_time_ns};
use std::f64::consts::FRAC_1_SQRT_2;

/// Extracts returns from `w.total` by Gaussian decomposition with explicit settings (the
/// [`ReturnsMethod::GaussianDecomposition`](super::ReturnsMethod::GaussianDecomposition) method; conventions as [`detect_returns`](super::detect_returns)).
pub fn detect_returns_with(
    w: &Waveform,
    noise_floor_j: f64,
    settings: &DecompositionSettings,
) -> Result<Vec<Return>, LidarError> {
    decompose(w, noise_floor_j, settings, None)
}

/// Counters of the Levenberg–Marquardt fits of one decomposition (diagnostics, see
/// [`detect_returns_stats`]).
#[doc(hidden)]
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FitStats {
    /// Levenberg–Marquardt fits run (initial fit, trial additions, refits after pruning).
    pub fits: u64,
    /// Fits stopped by the iteration cap instead of a convergence test.
    pub capped: u64,
    /// Iterations (normal-equation builds) over all fits.
    pub iterations: u64,
    /// Model evaluations over all fits.
    pub evaluations: u64,
    /// Residual sum of squares of the returned model against `w.total` (J²).
    pub rss_j2: f64,
    /// Per fit: final χ² (normalised) of the legacy fitter (Marquardt's ×10 / ×0.1 damping,
    /// stop when a step gains < 1e-13 relative or at the cap) and of the current one, both
    /// from the same start (filled by [`detect_returns_stats`] only).
    pub chi2_pairs: Vec<(f64, f64)>,
}

/// [`detect_returns_with`] and the counters of its fits (diagnostics for the LiDAR bench).
#[doc(hidden)]
pub fn detect_returns_stats(
    w: &Waveform,
    noise_floor_j: f64,
    settings: &DecompositionSettings,
) -> Result<(Vec<Return>, FitStats), LidarError> {
    let mut st = FitStats::default();
    let r = decompose(w, noise_floor_j, settings, Some(&mut st))?;
    Ok((r, st))
}

pub(crate) fn decompose(
    w: &Waveform,
    noise_floor_j: f64,
    settings: &DecompositionSettings,
    stats: Option<&mut FitStats>,
) -> Result<Vec<Return>, LidarError> {
    let Some((ymax, floor_j)) = prepare(w, noise_floor_j, settings)? else {
        if let Some(st) = stats {
            st.rss_j2 = w.total.iter().map(|v| v * v).sum();
        }
        return Ok(Vec::new());
    };
    // Normalised problem: values / ymax, time in bins.
    let y: Vec<f64> = w.total.iter().map(|v| v / ymax).collect();
    let floor = floor_j / ymax;
    let n = y.len();
    let peaks = find_peaks(&y, floor, settings.max_components);
    if peaks.is_empty() {
        if let Some(st) = stats {
            st.rss_j2 = w.total.iter().map(|v| v * v).sum();
        }
        return Ok(Vec::new());
    }
    let mut fitter = Fitter::new(&y, settings);
    fitter.compare = stats.is_some();
    let mut comps: Vec<Comp> = peaks.iter().map(|&i| initial_guess(&y, i)).collect();
    let mut chi2 = fitter.fit(&mut comps);

    // Residual-driven additions (the fitter's current model is that of `comps`).
    let mut trial: Vec<Comp> = Vec::with_capacity(settings.max_components);
    while comps.len() < settings.max_components {
        let (imax, rmax) = y
            .iter()
            .zip(&fitter.cur.model)
            .map(|(a, b)| a - b)
            .enumerate()
            .fold(
                (0, f64::MIN),
                |acc, (i, r)| if r > acc.1 { (i, r) } else { acc },
            );
        if rmax <= floor {
            break;
        }
        let mut widths: Vec<f64> = comps.iter().map(|c| c.s).collect();
        widths.sort_by(f64::total_cmp);
        let s = widths[widths.len() / 2];
        let mu = imax as f64 + 0.5;
        let p = normal_interval(-0.5 / s, 0.5 / s).max(1e-300);
        trial.clear();
        trial.extend_from_slice(&comps);
        trial.push(Comp { e: rmax / p, mu, s });
        let chi2_trial = fitter.fit(&mut trial);
        if chi2_trial < chi2 * (1.0 - 1e-3) {
            std::mem::swap(&mut comps, &mut trial);
            chi2 = chi2_trial;
        } else {
            break;
        }
    }

    // Prune weak components and merge coincident ones, then refit.
    for _ in 0..settings.max_components {
        let before = comps.len();
        comps.retain(|c| c.e > 0.0 && c.peak_bin() >= 0.5 * floor);
        comps.sort_by(|a, b| a.mu.total_cmp(&b.mu));
        let mut merged: Vec<Comp> = Vec::with_capacity(comps.len());
        for c in comps.drain(..) {
            if let Some(last) = merged.last_mut()
                && (c.mu - last.mu).abs() < 0.25 * c.s.max(last.s)
            {
                let e = last.e + c.e;
                let mu = (last.e * last.mu + c.e * c.mu) / e;
                let var = (last.e * (last.s * last.s + (last.mu - mu).powi(2))
                    + c.e * (c.s * c.s + (c.mu - mu).powi(2)))
                    / e;
                *last = Comp {
                    e,
                    mu,
                    s: var.sqrt(),
                };
                continue;
            }
            merged.push(c);
        }
        comps = merged;
        if comps.len() == before || comps.is_empty() {
            break;
        }
        fitter.fit(&mut comps);
    }

    if let Some(st) = stats {
        *st = std::mem::take(&mut fitter.stats);
        let mut ev = Evaluation::default();
        ev.compute(&y, &comps);
        st.rss_j2 = ev.chi2 * ymax * ymax;
    }
    let mut out: Vec<Return> = comps
        .iter()
        .filter(|c| c.mu > -0.5 * n as f64 && c.mu < 1.5 * n as f64)
        .map(|c| {
            let time_ns = w.t0_ns + c.mu * w.dt_ns;
            Return {
                time_ns,
                range_m: range_m_from_time_ns(time_ns),
                amplitude_j_per_bin: c.peak_bin() * ymax,
                width_ns: c.s * w.dt_ns,
                energy_j: c.e * ymax,
            }
        })
        .collect();
    out.sort_by(|a, b| a.time_ns.total_cmp(&b.time_ns));
    Ok(out)
}

/// One Gaussian component in normalised units: energy `e` (units of ymax·bin), centre `mu`
/// and width `s` in bins (bin i spans [i, i+1)).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Comp {
    pub(crate) e: f64,
    pub(crate) mu: f64,
    pub(crate) s: f64,
}

impl Comp {
    /// Energy of a bin centred on the peak.
    pub(crate) fn peak_bin(&self) -> f64 {
        self.e * normal_interval(-0.5 / self.s, 0.5 / self.s)
    }

    /// Bins where the component is non-negligible (±10σ).
    pub(crate) fn window(&self, n: usize) -> (usize, usize) {
        let lo = (self.mu - 10.0 * self.s - 1.0).floor().max(0.0);
        let hi = (self.mu + 10.0 * self.s + 1.0).ceil().max(0.0);
        let lo = (lo as usize).min(n);
        let hi = (hi as usize).min(n);
        (lo, hi)
    }
}

/// Peaks above `floor` with prominence ≥ `floor`, strongest `max` kept, in index order.
pub(crate) fn find_peaks(y: &[f64], floor: f64, max: usize) -> Vec<usize> {
    let n = y.len();
    let mut peaks: Vec<(usize, f64)> = Vec::new();
    let mut i = 0;
    while i < n {
        // Plateau [i, j].
        let mut j = i;
        while j + 1 < n && y[j + 1] == y[i] {
            j += 1;
        }
        let left_lower = i == 0 || y[i - 1] < y[i];
        let right_lower = j + 1 == n || y[j + 1] < y[j];
        if left_lower && right_lower && y[i] > floor {
            let centre = (i + j) / 2;
            let h = y[i];
            let side_min = |range: &mut dyn Iterator<Item = usize>| -> f64 {
                let mut m = f64::INFINITY;
                let mut any = false;
                for k in range {
                    if y[k] > h {
                        break;
                    }
                    any = true;
                    m = m.min(y[k]);
                }
                if any { m } else { 0.0 }
            };
            let lmin = side_min(&mut (0..i).rev());
            let rmin = side_min(&mut (j + 1..n));
            let prominence = h - lmin.max(rmin);
            if prominence >= floor {
                peaks.push((centre, prominence));
            }
        }
        i = j + 1;
    }
    if peaks.len() > max {
        peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
        peaks.truncate(max);
    }
    let mut idx: Vec<usize> = peaks.into_iter().map(|p| p.0).collect();
    idx.sort_unstable();
    idx
}

/// Initial component at peak bin `i`.
pub(crate) fn initial_guess(y: &[f64], i: usize) -> Comp {
    let n = y.len();
    let h = y[i];
    // Sub-bin centre by 3-point Gaussian (log-parabola) interpolation.
    let mut delta = 0.0;
    if i > 0 && i + 1 < n && y[i - 1] > 0.0 && y[i + 1] > 0.0 {
        let (a, b, c) = (y[i - 1].ln(), h.ln(), y[i + 1].ln());
        let den = a - 2.0 * b + c;
        if den < 0.0 {
            delta = (0.5 * (a - c) / den).clamp(-0.5, 0.5);
        }
    }
    // Half-maximum crossings.
    let half = 0.5 * h;
    let mut left = None;
    let mut k = i;
    while k > 0 {
        if y[k - 1] > y[k] {
            break;
        }
        if y[k - 1] < half {
            let f = (y[k] - half) / (y[k] - y[k - 1]);
            left = Some(i as f64 - (k as f64 - f));
            break;
        }
        k -= 1;
    }
    let mut right = None;
    let mut k = i;
    while k + 1 < n {
        if y[k + 1] > y[k] {
            break;
        }
        if y[k + 1] < half {
            let f = (y[k] - half) / (y[k] - y[k + 1]);
            right = Some(k as f64 + f - i as f64);
            break;
        }
        k += 1;
    }
    let hw = match (left, right) {
        (Some(l), Some(r)) => 0.5 * (l + r),
        (Some(l), None) => l,
        (None, Some(r)) => r,
        (None, None) => 1.0,
    };
    let s = ((hw * 2.0 / crate::lidar::pulse::FWHM_PER_SIGMA).powi(2) - 1.0 / 12.0)
        .max(0.09)
        .sqrt();
    let mu = i as f64 + 0.5 + delta;
    let p = normal_interval((i as f64 - mu) / s, (i as f64 + 1.0 - mu) / s).max(1e-12);
    Comp { e: h / p, mu, s }
}

/// Model, per-bin probabilities and Jacobian of a set of components at one parameter point.
#[derive(Debug, Default)]
pub(crate) struct Evaluation {
    /// Model value per bin.
    pub(crate) model: Vec<f64>,
    /// Σ (y − model)².
    pub(crate) chi2: f64,
    /// Per component: bin window `[lo, hi)` and offset of its first bin in the flat arrays.
    pub(crate) spans: Vec<(usize, usize, usize)>,
    /// ∂model/∂e (the bin probability), ∂model/∂μ and ∂model/∂σ per component window bin.
    pub(crate) d_e: Vec<f64>,
    pub(crate) d_mu: Vec<f64>,
    pub(crate) d_s: Vec<f64>,
}

impl Evaluation {
    /// Evaluates `comps` on `n` bins against the data `y`.
    pub(crate) fn compute(&mut self, y: &[f64], comps: &[Comp]) {
        let n = y.len();
        self.model.clear();
        self.model.resize(n, 0.0);
        self.spans.clear();
        self.d_e.clear();
        self.d_mu.clear();
        self.d_s.clear();
        for c in comps {
            let (lo, hi) = c.window(n);
            self.spans.push((lo, hi, self.d_e.len()));
            if lo >= hi {
                continue;
            }
            let inv_s = 1.0 / c.s;
            // Boundary k of bin i is at z = (i − μ)/σ (the same expression as the bins' own).
            let mut za = (lo as f64 - c.mu) / c.s;
            let (mut ta, mut pa) = normal_tail_and_pdf(za);
            for i in lo..hi {
                let zb = (i as f64 + 1.0 - c.mu) / c.s;
                let (tb, pb) = normal_tail_and_pdf(zb);
                let p = if za >= 0.0 {
                    ta - tb
                } else if zb <= 0.0 {
                    tb - ta
                } else {
                    0.5 * (erf(zb * FRAC_1_SQRT_2) - erf(za * FRAC_1_SQRT_2))
                }
                .max(0.0);
                self.model[i] += c.e * p;
                self.d_e.push(p);
                self.d_mu.push(c.e * (pa - pb) * inv_s);
                self.d_s.push(c.e * (za * pa - zb * pb) * inv_s);
                (za, ta, pa) = (zb, tb, pb);
            }
        }
        self.chi2 = y
            .iter()
            .zip(&self.model)
            .map(|(y, m)| (y - m) * (y - m))
            .sum();
    }
}
