//! Single-photon (photon-counting) LiDAR from mean waveforms (physics.md §9.5; DART 5 paper §4;
//! DART schema `quantEff`, dead time, dark count).
//!
//! * Mean signal photo-electrons per bin `n_k = η_q η_opt E_k λ/(hc)`.
//! * Solar background rate `R_sun = η_q η_opt (λ/hc) L̄_λ Δλ A Ω_FOV` (photons s⁻¹), dark counts
//!   `R_dark` per channel; mean background per bin `(R_sun + R_dark)Δt`.
//! * One shot: counts are Poisson; each channel has its own non-paralysable dead time; the
//!   signal and the solar background are shared equally among channels. Randomness comes from a
//!   [`UniformSource`] so the engine can pass its seeded `Xoshiro256PlusPlus`.
//!
//! Units: energies J, wavelengths nm, times ns (rates Hz), radiance W m⁻² sr⁻¹ µm⁻¹.

use super::pulse::{clamp_unit, cone_solid_angle_sr};
use super::special::{ln_factorial, stirling_correction};
use super::{
    LidarError, PLANCK_J_S, SPEED_OF_LIGHT_M_PER_S, check_non_negative, check_positive,
    check_unit_interval,
};

/// Source of uniform random numbers in [0, 1).
///
/// Implemented for closures `FnMut() -> f64` and for `rand_xoshiro::Xoshiro256PlusPlus`
/// (53 high bits of `next_u64`).
pub trait UniformSource {
    /// Next uniform in [0, 1).
    fn next_uniform(&mut self) -> f64;
}

impl<F: FnMut() -> f64> UniformSource for F {
    fn next_uniform(&mut self) -> f64 {
        self()
    }
}

impl UniformSource for rand_xoshiro::Xoshiro256PlusPlus {
    fn next_uniform(&mut self) -> f64 {
        use rand_xoshiro::rand_core::Rng;
        uniform_from_u64(self.next_u64())
    }
}

/// Uniform in [0, 1) from the 53 high bits of a 64-bit random integer.
pub fn uniform_from_u64(x: u64) -> f64 {
    (x >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Photon-counting detector (physics.md §9.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detector {
    /// Quantum efficiency η_q (DART `quantEff`, default 0.15).
    pub quantum_efficiency: f64,
    /// Optical (receiver) efficiency η_opt (default 1).
    pub optical_efficiency: f64,
    /// Non-paralysable dead time per channel after each detection (ns; DART default 2.5,
    /// unit assumed ns).
    pub dead_time_ns: f64,
    /// Dark count rate per channel (Hz; DART default 100, unit assumed Hz).
    pub dark_count_hz: f64,
    /// Number of independent channels (ATLAS/MABEL-like arrays); each receives 1/channels of
    /// the signal and of the solar background.
    pub channels: u16,
}

impl Default for Detector {
    fn default() -> Self {
        Self::dart_default()
    }
}

impl Detector {
    /// DART defaults: η_q = 0.15, η_opt = 1, dead time 2.5 ns, dark count 100 Hz, 1 channel.
    pub fn dart_default() -> Self {
        Self {
            quantum_efficiency: 0.15,
            optical_efficiency: 1.0,
            dead_time_ns: 2.5,
            dark_count_hz: 100.0,
            channels: 1,
        }
    }

    /// Checks every field (efficiencies in [0, 1], finite non-negative dead time and dark
    /// rate, at least one channel).
    pub fn validate(&self) -> Result<(), LidarError> {
        check_unit_interval("quantum_efficiency", self.quantum_efficiency)?;
        check_unit_interval("optical_efficiency", self.optical_efficiency)?;
        check_non_negative("dead_time_ns", self.dead_time_ns)?;
        check_non_negative("dark_count_hz", self.dark_count_hz)?;
        if self.channels == 0 {
            return Err(LidarError::InvalidParameter {
                name: "channels",
                value: 0.0,
                reason: "must be >= 1",
            });
        }
        Ok(())
    }

    /// Overall detection efficiency η_q η_opt.
    pub fn efficiency(&self) -> f64 {
        self.quantum_efficiency * self.optical_efficiency
    }
}

/// Photon energy `hc/λ` (J) at `wavelength_nm` (nm, > 0).
pub fn photon_energy_j(wavelength_nm: f64) -> Result<f64, LidarError> {
    check_positive("wavelength_nm", wavelength_nm)?;
    Ok(PLANCK_J_S * SPEED_OF_LIGHT_M_PER_S / (wavelength_nm * 1e-9))
}

/// Mean signal photo-electrons per bin `n_k = η_q η_opt E_k λ/(hc)` (physics.md §9.5) for the
/// whole detector (all channels). Energies must be finite and ≥ 0 (J).
pub fn mean_signal_counts(
    energies_j: &[f64],
    wavelength_nm: f64,
    det: &Detector,
) -> Result<Vec<f64>, LidarError> {
    det.validate()?;
    let hv = photon_energy_j(wavelength_nm)?;
    if let Some((i, e)) = energies_j
        .iter()
        .enumerate()
        .find(|(_, e)| !(e.is_finite() && **e >= 0.0))
    {
        return Err(LidarError::InvalidInput(format!(
            "energies_j[{i}] = {e}: must be finite and >= 0"
        )));
    }
    let eta = det.efficiency();
    Ok(energies_j.iter().map(|e| eta * e / hv).collect())
}

/// Solar background photo-electron rate (s⁻¹) for the whole detector (physics.md §9.5):
/// `R_sun = η_q η_opt (λ/hc) L̄_λ Δλ A Ω_FOV`, `Ω_FOV = 2π(1 − cos α_FOV)`.
///
/// * `radiance_w_m2_sr_um`: mean spectral radiance entering the FOV (W m⁻² sr⁻¹ µm⁻¹), e.g.
///   from the passive image of the same scene at sensor level; over a Lambertian ground without
///   atmosphere `ρ E⊥_λ cos θ_s/π`;
/// * `filter_bandwidth_um`: receiver filter width Δλ (µm);
/// * `aperture_m2`: receiver area A (m²);
/// * `fov_half_angle_rad`: receiver FOV half angle (rad).
pub fn solar_background_rate(
    radiance_w_m2_sr_um: f64,
    filter_bandwidth_um: f64,
    aperture_m2: f64,
    fov_half_angle_rad: f64,
    det: &Detector,
    wavelength_nm: f64,
) -> Result<f64, LidarError> {
    det.validate()?;
    check_non_negative("radiance_w_m2_sr_um", radiance_w_m2_sr_um)?;
    check_non_negative("filter_bandwidth_um", filter_bandwidth_um)?;
    check_non_negative("aperture_m2", aperture_m2)?;
    let omega = cone_solid_angle_sr(fov_half_angle_rad)?;
    let hv = photon_energy_j(wavelength_nm)?;
    Ok(det.efficiency() * radiance_w_m2_sr_um * filter_bandwidth_um * aperture_m2 * omega / hv)
}

/// One detection (photo-electron event) of a shot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// Channel index (0-based).
    pub channel: u16,
    /// Bin index on the input arrays.
    pub bin: usize,
    /// Detection time (ns, same axis as the waveform; sub-bin resolution).
    pub time_ns: f64,
    /// True when the event came from the solar background or a dark count.
    pub is_noise: bool,
}

/// Largest expected number of events per shot accepted by [`simulate_shot`].
pub const MAX_EXPECTED_EVENTS_PER_SHOT: f64 = 1.0e7;

/// Simulates one shot of a photon-counting detector (physics.md §9.5).
///
/// * `mean_signal_per_bin`: mean signal photo-electrons per bin for the whole detector
///   ([`mean_signal_counts`]), finite and ≥ 0;
/// * `background_per_bin`: mean solar-background photo-electrons per bin for the whole detector
///   (`solar_background_rate · Δt`), ≥ 0. Dark counts (`det.dark_count_hz` per channel) are
///   added here;
/// * `t0_ns`, `dt_ns`: time axis of the bins (bin k = `[t0 + kΔt, t0 + (k+1)Δt)`).
///
/// Rates are constant within a bin and split equally among `det.channels`. With zero dead time
/// each channel and bin draws independent exact Poisson counts for signal and noise
/// ([`poisson`]), placed uniformly in the bin. With dead time τ the channel is simulated
/// sequentially in continuous time: the next arrival after the detector becomes live is drawn
/// exactly from the piecewise-constant-rate Poisson process (exponential variate, walked across
/// bins — the continuous-time form of `P(first in bin k) = e^{−Σ_{j<k} n_j}(1 − e^{−n_k})`),
/// labelled signal or noise with probability proportional to the two rates, and the channel is
/// blind for τ afterwards (non-paralysable; arrivals while blind are lost). Detections are
/// returned sorted by time (then channel).
pub fn simulate_shot<R: UniformSource + ?Sized>(
    mean_signal_per_bin: &[f64],
    background_per_bin: f64,
    t0_ns: f64,
    dt_ns: f64,
    det: &Detector,
    rng: &mut R,
) -> Result<Vec<Detection>, LidarError> {
    det.validate()?;
    check_non_negative("background_per_bin", background_per_bin)?;
    check_positive("dt_ns", dt_ns)?;
    if !t0_ns.is_finite() {
        return Err(LidarError::InvalidParameter {
            name: "t0_ns",
            value: t0_ns,
            reason: "must be finite",
        });
    }
    if let Some((i, x)) = mean_signal_per_bin
        .iter()
        .enumerate()
        .find(|(_, x)| !(x.is_finite() && **x >= 0.0))
    {
        return Err(LidarError::InvalidInput(format!(
            "mean_signal_per_bin[{i}] = {x}: must be finite and >= 0"
        )));
    }
    let n = mean_signal_per_bin.len();
    if n == 0 {
        return Ok(Vec::new());
    }
    let channels = det.channels as usize;
    let share = 1.0 / channels as f64;
    let noise_per_bin_ch = background_per_bin * share + det.dark_count_hz * dt_ns * 1e-9;
    let expected: f64 = mean_signal_per_bin.iter().sum::<f64>()
        + background_per_bin
        + channels as f64 * n as f64 * det.dark_count_hz * dt_ns * 1e-9;
    if !(expected <= MAX_EXPECTED_EVENTS_PER_SHOT) {
        return Err(LidarError::InvalidInput(format!(
            "expected {expected:e} events in one shot (max {MAX_EXPECTED_EVENTS_PER_SHOT:e}): \
             not a photon-counting regime"
        )));
    }
    let mut out = Vec::new();
    for ch in 0..channels {
        let ch16 = ch as u16;
        if det.dead_time_ns == 0.0 {
            for (k, &sig) in mean_signal_per_bin.iter().enumerate() {
                let ns = poisson(sig * share, rng);
                let nb = poisson(noise_per_bin_ch, rng);
                for m in 0..ns + nb {
                    let u = clamp_unit(rng.next_uniform());
                    out.push(Detection {
                        channel: ch16,
                        bin: k,
                        time_ns: t0_ns + (k as f64 + u) * dt_ns,
                        is_noise: m >= ns,
                    });
                }
            }
        } else {
            simulate_channel_dead_time(
                mean_signal_per_bin,
                share,
                noise_per_bin_ch,
                t0_ns,
                dt_ns,
                det.dead_time_ns,
                ch16,
                rng,
                &mut out,
            );
        }
    }
    out.sort_by(|a, b| {
        a.time_ns
            .total_cmp(&b.time_ns)
            .then(a.channel.cmp(&b.channel))
    });
    Ok(out)
}

#[allow(clippy::too_many_arguments)]
fn simulate_channel_dead_time<R: UniformSource + ?Sized>(
    signal: &[f64],
    share: f64,
    noise_per_bin: f64,
    t0_ns: f64,
    dt_ns: f64,
    dead_ns: f64,
    channel: u16,
    rng: &mut R,
    out: &mut Vec<Detection>,
) {
    let n = signal.len();
    // Time measured in bins from the gate start.
    let dead_bins = dead_ns / dt_ns;
    let mut t = 0.0f64;
    let mut k = 0usize;
    'shot: loop {
        // Exponential variate: integrated rate (mean events) to the next arrival.
        let mut e = -(1.0 - clamp_unit(rng.next_uniform())).ln();
        loop {
            if k >= n {
                break 'shot;
            }
            let rate = signal[k] * share + noise_per_bin; // events per bin
            let avail = rate * (k as f64 + 1.0 - t);
            if rate > 0.0 && e < avail {
                t = (t + e / rate).min(k as f64 + 1.0);
                break;
            }
            e -= avail;
            k += 1;
            t = k as f64;
        }
        let rate = signal[k] * share + noise_per_bin;
        let is_noise = clamp_unit(rng.next_uniform()) * rate < noise_per_bin;
        out.push(Detection {
            channel,
            bin: k,
            time_ns: t0_ns + t * dt_ns,
            is_noise,
        });
        t += dead_bins;
        if !(t < n as f64) {
            break;
        }
        k = (t.floor() as usize).max(k);
    }
}

/// Exact Poisson variate of mean `lambda` from a [`UniformSource`].
///
/// * λ < 10: sequential inversion of the CDF (Devroye 1986, *Non-Uniform Random Variate
///   Generation*, §X.3.2), one uniform;
/// * λ ≥ 10: PTRS, transformed rejection with squeeze (Hörmann 1993, *Insurance: Mathematics
///   and Economics* 12:39, algorithm PTRS), with the acceptance test evaluated through the
///   stable saddle-point form of `ln p(k)` (Loader 2000) so it stays exact up to λ ≈ 1e15.
///
/// λ ≤ 0, NaN or infinite returns 0 (callers validate; this is a hot-loop function).
pub fn poisson<R: UniformSource + ?Sized>(lambda: f64, rng: &mut R) -> u64 {
    if !(lambda > 0.0 && lambda.is_finite()) {
        return 0;
    }
    if lambda < 10.0 {
        let u = clamp_unit(rng.next_uniform());
        let mut k = 0u64;
        let mut p = (-lambda).exp();
        let mut f = p;
        while u >= f {
            k += 1;
            p *= lambda / k as f64;
            if p == 0.0 {
                break; // rounding left F < u at the far tail: stop there
            }
            f += p;
        }
        return k;
    }
    let slam = lambda.sqrt();
    let b = 0.931 + 2.53 * slam;
    let a = -0.059 + 0.02483 * b;
    let inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
    let vr = 0.9277 - 3.6224 / (b - 2.0);
    loop {
        let u = clamp_unit(rng.next_uniform()) - 0.5;
        let v = clamp_unit(rng.next_uniform());
        let us = 0.5 - u.abs();
        if us <= 0.0 {
            continue;
        }
        let kf = ((2.0 * a / us + b) * u + lambda + 0.43).floor();
        if us >= 0.07 && v <= vr {
            return kf.max(0.0) as u64;
        }
        if kf < 0.0 || (us < 0.013 && v > us) {
            continue;
        }
        let lhs = v.ln() + inv_alpha.ln() - (a / (us * us) + b).ln();
        if lhs <= ln_poisson_pmf(kf, lambda) {
            return kf as u64;
        }
    }
}

/// `ln P(K = k)` for K ~ Poisson(λ), k ≥ 0 integral (as f64): direct for k < 10, otherwise
/// `−k ln(1 + (k−λ)/λ) + (k − λ) − ½ln(2πk) − δ(k)` with δ the Stirling correction, which avoids
/// the cancellation of `k ln λ − λ − ln k!` at large λ (Loader 2000, "Fast and accurate
/// computation of binomial probabilities").
pub fn ln_poisson_pmf(k: f64, lambda: f64) -> f64 {
    if k < 10.0 {
        return k * lambda.ln() - lambda - ln_factorial(k as u64);
    }
    let d = (k - lambda) / lambda;
    -k * d.ln_1p() + (k - lambda)
        - 0.5 * (2.0 * std::f64::consts::PI * k).ln()
        - stirling_correction(k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn photon_numbers() {
        // physics.md §9.5: photon energy at 1064 nm = 1.86696e-19 J; 1 µJ = 5.3563e12 photons.
        let hv = photon_energy_j(1064.0).unwrap();
        assert!((hv / 1.86696e-19 - 1.0).abs() < 5e-6, "{hv}");
        let det = Detector {
            quantum_efficiency: 1.0,
            ..Detector::dart_default()
        };
        let n = mean_signal_counts(&[1e-6], 1064.0, &det).unwrap();
        assert!((n[0] / 5.3563e12 - 1.0).abs() < 1e-5, "{}", n[0]);
        let d15 = mean_signal_counts(&[1e-6], 1064.0, &Detector::default()).unwrap();
        assert!((d15[0] / n[0] - 0.15).abs() < 1e-15);
        assert!(mean_signal_counts(&[f64::NAN], 1064.0, &det).is_err());
        assert!(mean_signal_counts(&[-1.0], 1064.0, &det).is_err());
        assert!(mean_signal_counts(&[1.0], 0.0, &det).is_err());
        assert!(mean_signal_counts(&[], 532.0, &det).unwrap().is_empty());
    }

    #[test]
    fn ln_pmf_forms_agree() {
        for lambda in [10.5, 37.0, 1234.5] {
            for k in [10u64, 11, 20, 40, 100, 1000, 1300] {
                let direct = k as f64 * f64::ln(lambda) - lambda - ln_factorial(k);
                let stable = ln_poisson_pmf(k as f64, lambda);
                assert!(
                    (direct - stable).abs() < 1e-10 * direct.abs().max(1.0),
                    "{k} {lambda}"
                );
            }
        }
    }

    #[test]
    fn detector_validation() {
        assert!(Detector::default().validate().is_ok());
        for bad in [
            Detector {
                quantum_efficiency: 1.5,
                ..Detector::default()
            },
            Detector {
                dead_time_ns: -1.0,
                ..Detector::default()
            },
            Detector {
                dark_count_hz: f64::NAN,
                ..Detector::default()
            },
            Detector {
                channels: 0,
                ..Detector::default()
            },
        ] {
            assert!(bad.validate().is_err());
        }
    }

    #[test]
    fn poisson_edge_cases() {
        let mut r = || 0.5;
        assert_eq!(poisson(0.0, &mut r), 0);
        assert_eq!(poisson(-1.0, &mut r), 0);
        assert_eq!(poisson(f64::NAN, &mut r), 0);
        // u just below 1 terminates for a small mean.
        let mut hi = || 1.0 - f64::EPSILON / 2.0;
        assert!(poisson(3.0, &mut hi) < 100);
    }
}
