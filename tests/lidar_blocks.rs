//! Engine-independent LiDAR building blocks (physics.md §9, §13 item 12): analytic first-order
//! waveforms, binning and convolution identities, Gaussian decomposition accuracy, photon
//! statistics (Poisson exactness, dead time), LAS 1.4 round trips and waveform products.
//!
//! Statistical tests use fixed seeds; each states its false-alarm rate under a correct
//! implementation.

use lumenscape::io::las_out::{
    EXTRA_BYTES_DESCRIPTOR_LEN, LasPoint, PULSE_ID_NAME, read_las, write_las,
};
use lumenscape::lidar::photon_counting::{
    Detector, UniformSource, mean_signal_counts, photon_energy_j, poisson, simulate_shot,
    solar_background_rate,
};
use lumenscape::lidar::pulse::{FootprintProfile, FootprintSampler, PulseShape};
use lumenscape::lidar::returns::{Return, detect_returns};
use lumenscape::lidar::special::normal_interval;
use lumenscape::lidar::waveform::{
    AnalyticFirstOrder, FirstOrderCanopy, GapCorrelation, Waveform, WaveformBinner,
    analytic_first_order, bare_ground_energy_j, path_m_from_time_ns,
};
use lumenscape::lidar::waveform_io::{read_waveforms, waveform_svg, write_waveforms};
use lumenscape::lidar::{SPEED_OF_LIGHT_M_PER_S, compensated_sum};
use rand_xoshiro::Xoshiro256PlusPlus;
use rand_xoshiro::rand_core::SeedableRng;
use std::f64::consts::PI;
use std::path::PathBuf;

fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

fn scratch_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lumenscape_lidar_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

// ---------------------------------------------------------------- analytic first order (§9.6)

fn example_canopy(correlation: GapCorrelation) -> FirstOrderCanopy {
    // physics.md §9.6 example: A = 0.1 m², R = 1000 m, ρ_L = 0.45 (Γ_π = ρ_L/3, spherical,
    // G = 0.5), ρ_g = 0.3, LAI = 2; canopy 20 m thick.
    FirstOrderCanopy {
        pulse_energy_j: 1.0,
        aperture_m2: 0.1,
        range_top_m: 1000.0,
        height_m: 20.0,
        lai: 2.0,
        g_function: 0.5,
        gamma_backscatter: 0.45 / 3.0,
        rho_ground: 0.3,
        correlation,
    }
}

fn gate_for(p: &FirstOrderCanopy) -> (f64, f64) {
    (
        2.0 * (p.range_top_m - 5.0),
        2.0 * (p.range_top_m + p.height_m + 5.0),
    )
}

#[test]
fn analytic_first_order_matches_printed_example() {
    let p = example_canopy(GapCorrelation::Independent);
    let (lo, hi) = gate_for(&p);
    let a = analytic_first_order(&p, lo, hi, 1.0).unwrap();
    // Printed to 6 significant digits: half a unit of the last digit.
    assert!(
        (a.canopy_energy_j - 4.12847e-9).abs() <= 0.5e-14,
        "{}",
        a.canopy_energy_j
    );
    assert!(
        (a.ground_energy_j - 1.29236e-9).abs() <= 0.5e-14,
        "{}",
        a.ground_energy_j
    );
    // Whole return inside the gate: the bins sum to E_c + E_g.
    let sum = a.waveform.total_energy_j();
    assert!(a.out_of_gate_j.abs() < 1e-24);
    assert!((sum / (a.canopy_energy_j + a.ground_energy_j) - 1.0).abs() < 1e-13);
    assert_eq!(a.waveform.total, a.waveform.first_order);
}

/// Per-bin exactness: every bin equals a fine midpoint quadrature of dE/dr over its range
/// interval (quadrature error ~1e-9 relative with 4000 sub-steps).
#[test]
fn analytic_first_order_bins_are_exact_integrals() {
    for corr in [GapCorrelation::Independent, GapCorrelation::Correlated] {
        let p = example_canopy(corr);
        let (lo, hi) = gate_for(&p);
        let dt = 0.7;
        let a = analytic_first_order(&p, lo, hi, dt).unwrap();
        let k = match corr {
            GapCorrelation::Independent => 2.0 * p.g_function,
            GapCorrelation::Correlated => p.g_function,
        };
        let c = p.pulse_energy_j * p.aperture_m2 / p.range_top_m.powi(2);
        let uf = p.lai / p.height_m;
        let r_t = p.range_top_m;
        let r_g = r_t + p.height_m;
        let density = |r: f64| {
            if (r_t..r_g).contains(&r) {
                c * uf * p.gamma_backscatter / PI * (-k * uf * (r - r_t)).exp()
            } else {
                0.0
            }
        };
        let bin_len = path_m_from_time_ns(dt);
        let ground_bin = ((2.0 * r_g - lo) / bin_len).floor() as usize;
        let mut worst: f64 = 0.0;
        for (i, &e) in a.waveform.total.iter().enumerate() {
            let ra = 0.5 * (lo + i as f64 * bin_len);
            let rb = 0.5 * (lo + (i + 1) as f64 * bin_len);
            // Quadrature over the part of the bin inside the canopy (no discontinuity).
            let (qa, qb) = (ra.max(r_t), rb.min(r_g));
            let m = 4000;
            let h = (qb - qa) / m as f64;
            let mut q: f64 = if qb > qa {
                (0..m).map(|j| density(qa + (j as f64 + 0.5) * h) * h).sum()
            } else {
                0.0
            };
            if i == ground_bin {
                q += a.ground_energy_j;
            }
            let scale = a.canopy_energy_j * 1e-3;
            let err = (e - q).abs() / scale.max(q);
            worst = worst.max(err);
        }
        // Midpoint rule on an exponential: relative error ≈ (k u_f h)²/24 < 1e-12.
        assert!(
            worst < 1e-9,
            "{corr:?}: worst per-bin relative error {worst:e}"
        );
        eprintln!(
            "analytic first order {corr:?}: worst per-bin rel. error vs quadrature {worst:.2e}"
        );
    }
}

#[test]
fn analytic_first_order_correlated_variant_and_limits() {
    let p = example_canopy(GapCorrelation::Correlated);
    let (lo, hi) = gate_for(&p);
    let a = analytic_first_order(&p, lo, hi, 1.0).unwrap();
    let c = 0.1 / 1e6;
    let ec = c * 0.15 * (1.0 - (-0.5f64 * 2.0).exp()) / (PI * 0.5);
    let eg = c * 0.3 / PI * (-0.5f64 * 2.0).exp();
    assert!((a.canopy_energy_j / ec - 1.0).abs() < 1e-13);
    assert!((a.ground_energy_j / eg - 1.0).abs() < 1e-13);
    // One-way transmittance: the hotspot variant returns more from canopy and ground.
    let ind =
        analytic_first_order(&example_canopy(GapCorrelation::Independent), lo, hi, 1.0).unwrap();
    assert!(a.canopy_energy_j > ind.canopy_energy_j && a.ground_energy_j > ind.ground_energy_j);

    // Dense horizontal-leaf canopy, correlated: tends to the Lambertian E0 A ρ_L/(π R²).
    let dense = FirstOrderCanopy {
        lai: 40.0,
        g_function: 1.0,
        gamma_backscatter: 0.45,
        ..p
    };
    let d = analytic_first_order(&dense, lo, hi, 1.0).unwrap();
    let lambertian = c * 0.45 / PI;
    assert!((d.canopy_energy_j / lambertian - 1.0).abs() < 1e-15);
    assert!(d.ground_energy_j < 1e-17 * lambertian);

    // LAI = 0: the bare-ground value E0 (A/R²) ρ_g/π (physics.md §13 item 12).
    let bare = FirstOrderCanopy {
        lai: 0.0,
        height_m: 0.0,
        ..p
    };
    let b = analytic_first_order(&bare, lo, hi, 1.0).unwrap();
    let want = bare_ground_energy_j(1.0, 0.1, 1000.0, 0.3, 1.0).unwrap();
    assert_eq!(b.canopy_energy_j, 0.0);
    assert!((b.ground_energy_j / want - 1.0).abs() < 1e-15);
    assert!((b.waveform.total_energy_j() / want - 1.0).abs() < 1e-15);

    // A gate that cuts the ground off books it as out of gate.
    let cut = analytic_first_order(&p, lo, 2.0 * (p.range_top_m + 10.0), 1.0).unwrap();
    let inside = cut.waveform.total_energy_j();
    assert!(
        ((inside + cut.out_of_gate_j) / (cut.canopy_energy_j + cut.ground_energy_j) - 1.0).abs()
            < 1e-13
    );
    assert!(cut.out_of_gate_j > cut.ground_energy_j);

    // Bad input.
    assert!(analytic_first_order(&FirstOrderCanopy { lai: f64::NAN, ..p }, lo, hi, 1.0).is_err());
    assert!(analytic_first_order(&FirstOrderCanopy { height_m: 0.0, ..p }, lo, hi, 1.0).is_err());
    assert!(analytic_first_order(&p, lo, hi, 0.0).is_err());
}

// ------------------------------------------------------------- binning and convolution (§9.4)

fn moments(w: &[f64]) -> (f64, f64, f64) {
    let s = compensated_sum(w);
    let m = w.iter().enumerate().map(|(i, v)| i as f64 * v).sum::<f64>() / s;
    let v = w
        .iter()
        .enumerate()
        .map(|(i, x)| (i as f64 - m).powi(2) * x)
        .sum::<f64>()
        / s;
    (s, m, v)
}

/// Convolution preserves area exactly (to rounding), shifts the centroid by the kernels'
/// means and adds their variances — identities of discrete convolution.
#[test]
fn convolution_preserves_area_centroid_and_adds_variance() {
    let mut r = rng(7);
    let n = 400;
    let mut w = Waveform::zeros(6000.0, 0.5, n);
    for i in 0..n {
        if r.next_uniform() < 0.3 {
            w.total[i] = r.next_uniform() * 1e-9;
            w.first_order[i] = w.total[i] * r.next_uniform();
        }
    }
    let receiver: Vec<f64> = (0..12).map(|j| (-(j as f64) / 3.0).exp()).collect();
    for (pulse, rx) in [
        (PulseShape::from_fwhm_ns(4.0, 3.0).unwrap(), None),
        (
            PulseShape::dart_default(1.5).unwrap(),
            Some(receiver.as_slice()),
        ),
        (PulseShape::from_sigma_ns(0.05, 3.0).unwrap(), None),
        (
            PulseShape::from_sigma_ns(20.0, 5.0).unwrap(),
            Some(receiver.as_slice()),
        ),
    ] {
        let out = w.convolve(&pulse, rx).unwrap();
        let k = pulse.kernel(w.dt_ns).unwrap();
        let (_, km, kv) = moments(&k.weights);
        let (hm, hv) = match rx {
            Some(h) => {
                let (_, m, v) = moments(h);
                (m, v)
            }
            None => (0.0, 0.0),
        };
        for (a, b) in [(&w.total, &out.total), (&w.first_order, &out.first_order)] {
            let (s0, m0, v0) = moments(a);
            let (s1, m1, v1) = moments(b);
            assert!((s1 / s0 - 1.0).abs() < 1e-13, "area {s0} -> {s1}");
            // Centroid in absolute time.
            let t_in = w.t0_ns + (m0 + 0.5) * w.dt_ns;
            let t_out = out.t0_ns + (m1 + 0.5) * out.dt_ns;
            let shift = (km - k.centre as f64 + hm) * w.dt_ns;
            assert!((t_out - t_in - shift).abs() < 1e-9, "centroid");
            assert!(
                (v1 - (v0 + kv + hv)).abs() < 1e-8 * v1,
                "variance {v1} vs {}",
                v0 + kv + hv
            );
        }
        assert!(out.total.iter().all(|v| v.is_finite() && *v >= 0.0));
    }
}

/// GLAS-like packets (1e-13 J) survive binning (compensated sums over 1e6 packets),
/// convolution and photon counting without underflow or NaN.
#[test]
fn glas_like_weights_survive_the_chain() {
    // 600 km range, 70 m footprint: gate of ±30 m around the ground.
    let range = 600e3;
    let mut b = WaveformBinner::new(2.0 * (range - 30.0), 2.0 * (range + 30.0), 1.0).unwrap();
    let mut r = rng(11);
    let n_packets = 1_000_000u64;
    let w = 1e-13;
    for _ in 0..n_packets {
        let path = 2.0 * (range - 20.0 + 40.0 * r.next_uniform());
        b.add(path, w, 1 + (r.next_uniform() * 3.0) as u32);
    }
    let wf = b.waveform();
    let total = wf.total_energy_j();
    let want = n_packets as f64 * w;
    assert!(
        (total / want - 1.0).abs() < 1e-14,
        "binned {total:e} vs {want:e}"
    );
    assert_eq!(b.losses().before_j + b.losses().after_j, 0.0);
    // A single 1e-13 J packet through convolution and counting.
    let mut single = WaveformBinner::new(2.0 * (range - 30.0), 2.0 * (range + 30.0), 1.0).unwrap();
    single.add(2.0 * range, 1e-13, 1);
    let conv = single
        .waveform()
        .convolve(&PulseShape::from_fwhm_ns(5.0, 3.0).unwrap(), None)
        .unwrap();
    assert!((conv.total_energy_j() / 1e-13 - 1.0).abs() < 1e-14);
    assert!(conv.total.iter().all(|v| v.is_finite() && *v >= 0.0));
    let tail_min = conv
        .total
        .iter()
        .cloned()
        .filter(|v| *v > 0.0)
        .fold(f64::MAX, f64::min);
    assert!(tail_min > 1e-20, "kernel tails kept in f64: {tail_min:e}");
    let counts = mean_signal_counts(&conv.total, 1064.0, &Detector::default()).unwrap();
    let n_sum: f64 = counts.iter().sum();
    let want_n = 0.15 * 1e-13 / photon_energy_j(1064.0).unwrap();
    assert!((n_sum / want_n - 1.0).abs() < 1e-13);
    let mut u = rng(12);
    let shot = simulate_shot(
        &counts,
        0.01,
        conv.t0_ns,
        conv.dt_ns,
        &Detector::default(),
        &mut u,
    )
    .unwrap();
    assert!(shot.iter().all(|d| d.time_ns.is_finite()));
    // And a waveform decomposition at that scale.
    let ret = detect_returns(&conv, 0.0).unwrap();
    assert_eq!(ret.len(), 1);
    assert!((ret[0].energy_j / 1e-13 - 1.0).abs() < 0.02);
    assert!((ret[0].range_m - range).abs() < 0.25 * path_m_from_time_ns(1.0));
}

// ------------------------------------------------------------------- returns extraction

struct Truth {
    t_ns: f64,
    sigma_ns: f64,
    energy: f64,
}

fn bin_integrated(t0: f64, dt: f64, n: usize, comps: &[Truth]) -> Waveform {
    let mut w = Waveform::zeros(t0, dt, n);
    for i in 0..n {
        let (a, b) = (t0 + i as f64 * dt, t0 + (i + 1) as f64 * dt);
        w.total[i] = comps
            .iter()
            .map(|c| {
                c.energy * normal_interval((a - c.t_ns) / c.sigma_ns, (b - c.t_ns) / c.sigma_ns)
            })
            .sum();
    }
    w.first_order = w.total.clone();
    w
}

fn centre_sampled(t0: f64, dt: f64, n: usize, comps: &[Truth]) -> Waveform {
    let mut w = Waveform::zeros(t0, dt, n);
    for i in 0..n {
        let t = t0 + (i as f64 + 0.5) * dt;
        w.total[i] = comps
            .iter()
            .map(|c| {
                let z = (t - c.t_ns) / c.sigma_ns;
                c.energy * dt * (-0.5 * z * z).exp() / (c.sigma_ns * (2.0 * PI).sqrt())
            })
            .sum();
    }
    w.first_order = w.total.clone();
    w
}

/// Returns worst |Δt|/dt and worst relative energy error.
fn match_returns(ret: &[Return], truth: &[Truth], dt: f64) -> (f64, f64) {
    assert_eq!(ret.len(), truth.len(), "found {ret:?}");
    let mut wt: f64 = 0.0;
    let mut we: f64 = 0.0;
    for (r, t) in ret.iter().zip(truth) {
        wt = wt.max((r.time_ns - t.t_ns).abs() / dt);
        we = we.max((r.energy_j / t.energy - 1.0).abs());
        let range = 0.5 * t.t_ns * 1e-9 * SPEED_OF_LIGHT_M_PER_S;
        assert!((r.range_m - range).abs() <= 0.25 * 0.5 * path_m_from_time_ns(dt) + 1e-9);
    }
    (wt, we)
}

fn truth_sets() -> Vec<Vec<Truth>> {
    let t0 = 6670.0;
    vec![
        vec![Truth {
            t_ns: t0 + 40.3,
            sigma_ns: 2.0,
            energy: 3e-9,
        }],
        vec![
            Truth {
                t_ns: t0 + 25.77,
                sigma_ns: 1.7,
                energy: 2e-9,
            },
            Truth {
                t_ns: t0 + 41.2,
                sigma_ns: 2.6,
                energy: 1.1e-9,
            },
        ],
        // Canopy top, understory (3.5σ from it) and ground.
        vec![
            Truth {
                t_ns: t0 + 20.4,
                sigma_ns: 2.0,
                energy: 1.5e-9,
            },
            Truth {
                t_ns: t0 + 27.41,
                sigma_ns: 2.0,
                energy: 0.8e-9,
            },
            Truth {
                t_ns: t0 + 60.05,
                sigma_ns: 1.8,
                energy: 2.5e-9,
            },
        ],
    ]
}

/// Noise-free synthetic waveforms (bin-integrated and centre-sampled Gaussians, 1–3
/// components): centres to < bin/4 and energies to 2 % (the brief's tolerances); measured
/// errors are printed.
#[test]
fn decomposition_recovers_noise_free_gaussians() {
    let (t0, dt, n) = (6670.0, 1.0, 90);
    let mut worst = [(0.0f64, 0.0f64); 2];
    for truth in truth_sets() {
        for (k, w) in [
            bin_integrated(t0, dt, n, &truth),
            centre_sampled(t0, dt, n, &truth),
        ]
        .iter()
        .enumerate()
        {
            let ret = detect_returns(w, 1e-14).unwrap();
            let (et, ee) = match_returns(&ret, &truth, dt);
            assert!(et < 0.25, "centre error {et} bins");
            assert!(ee < 0.02, "energy error {ee}");
            worst[k] = (worst[k].0.max(et), worst[k].1.max(ee));
        }
    }
    for (k, what) in ["bin-integrated", "centre-sampled"].iter().enumerate() {
        eprintln!(
            "decomposition noise-free {what}: worst centre error {:.2e} bin, worst energy error {:.2e}",
            worst[k].0, worst[k].1
        );
    }
}

/// Impulses at bin centres convolved with a ±3σ truncated pulse kernel (the real pipeline).
#[test]
fn decomposition_of_convolved_impulses() {
    let dt = 1.0;
    let mut b = WaveformBinner::new(2000.0, 2040.0, dt).unwrap();
    let bin_len = b.bin_len_m();
    let truth_bins = [(20usize, 2e-12), (45, 7e-13), (100, 1.5e-12)];
    for (i, e) in truth_bins {
        b.add(2000.0 + (i as f64 + 0.5) * bin_len, e, 1);
    }
    let pulse = PulseShape::from_fwhm_ns(4.0, 3.0).unwrap();
    let w = b.waveform().convolve(&pulse, None).unwrap();
    let ret = detect_returns(&w, 1e-16).unwrap();
    let truth: Vec<Truth> = truth_bins
        .iter()
        .map(|&(i, e)| Truth {
            t_ns: b.t0_ns() + (i as f64 + 0.5) * dt,
            sigma_ns: pulse.sigma_ns(),
            energy: e,
        })
        .collect();
    let (et, ee) = match_returns(&ret, &truth, dt);
    assert!(et < 0.25 && ee < 0.02, "{et} {ee}");
    for r in &ret {
        // Fitted width ≈ √(σ² + Δt²/12) (bin box of the discretised kernel), truncation aside.
        let want = (pulse.sigma_ns().powi(2) + dt * dt / 12.0).sqrt();
        assert!(
            (r.width_ns / want - 1.0).abs() < 0.05,
            "{} vs {want}",
            r.width_ns
        );
    }
    eprintln!("decomposition of convolved impulses: centre {et:.2e} bin, energy {ee:.2e}");
}

/// Poisson photon noise (~6e4 counts in the weakest return): centres < bin/4, energies < 2 %.
#[test]
fn decomposition_with_poisson_noise() {
    let (t0, dt, n) = (6670.0, 1.0, 90);
    let counts_per_joule = 4e13;
    let mut r = rng(99);
    let mut worst = (0.0f64, 0.0f64);
    for truth in truth_sets() {
        let clean = bin_integrated(t0, dt, n, &truth);
        let mut noisy = clean.clone();
        for v in noisy.total.iter_mut() {
            *v = poisson(*v * counts_per_joule, &mut r) as f64 / counts_per_joule;
        }
        noisy.first_order = noisy.total.clone();
        // Floor: 5 Poisson sd at the brightest bin.
        let peak = clean.total.iter().cloned().fold(0.0, f64::max);
        let floor = 5.0 * (peak * counts_per_joule).sqrt() / counts_per_joule;
        let ret = detect_returns(&noisy, floor).unwrap();
        let (et, ee) = match_returns(&ret, &truth, dt);
        assert!(et < 0.25, "centre error {et} bins");
        assert!(ee < 0.02, "energy error {ee}");
        worst = (worst.0.max(et), worst.1.max(ee));
    }
    eprintln!(
        "decomposition with Poisson noise: worst centre error {:.2e} bin, worst energy error {:.2e}",
        worst.0, worst.1
    );
}

// ------------------------------------------------------------------- photon counting (§9.5)

/// Wilson–Hilferty upper quantile of χ²_k at standard-normal level z.
fn chi2_quantile(k: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Exact Poisson draws: sample mean and variance → λ (z-tests at 5 sd, two-sided false-alarm
/// 5.7e-7 each) from λ = 1e-3 to 1e12 across both algorithms (inversion < 10 ≤ PTRS).
#[test]
fn poisson_mean_and_variance() {
    let mut r = rng(2024);
    let n = 100_000;
    for lambda in [1e-3, 0.7, 5.0, 9.99, 10.0, 25.0, 300.0, 1e5, 1e12] {
        let xs: Vec<f64> = (0..n)
            .map(|_| poisson(lambda, &mut r) as f64 - lambda)
            .collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let z_mean = mean / (lambda / n as f64).sqrt();
        let z_var = (var - lambda) / ((lambda + 2.0 * lambda * lambda) / n as f64).sqrt();
        assert!(z_mean.abs() < 5.0, "λ = {lambda}: mean z = {z_mean}");
        assert!(z_var.abs() < 5.0, "λ = {lambda}: variance z = {z_var}");
    }
}

/// Exact distribution: χ² goodness of fit of 200 000 draws against the Poisson pmf (cells with
/// expectation ≥ 20, tails pooled), rejected above the 1 − 1e-6 quantile.
#[test]
fn poisson_pmf_chi_square() {
    let mut r = rng(77);
    let n = 200_000usize;
    for lambda in [3.0, 14.0, 150.0] {
        let mut hist = std::collections::BTreeMap::<u64, usize>::new();
        for _ in 0..n {
            *hist.entry(poisson(lambda, &mut r)).or_default() += 1;
        }
        // pmf by recurrence in log space.
        let kmax = (lambda + 20.0 * lambda.sqrt() + 20.0) as u64;
        let mut pmf = Vec::new();
        let mut lp = -lambda;
        for k in 0..=kmax {
            if k > 0 {
                lp += (lambda / k as f64).ln();
            }
            pmf.push(lp.exp());
        }
        // Cells: contiguous ranges with expectation ≥ 20.
        let mut cells: Vec<(f64, usize)> = Vec::new();
        let (mut e, mut o) = (0.0, 0usize);
        for k in 0..=kmax {
            e += pmf[k as usize] * n as f64;
            o += hist.get(&k).copied().unwrap_or(0);
            if e >= 20.0 {
                cells.push((e, o));
                e = 0.0;
                o = 0;
            }
        }
        let beyond: usize = hist.range(kmax + 1..).map(|(_, c)| *c).sum();
        let last = cells.last_mut().unwrap();
        last.0 += e;
        last.1 += o + beyond;
        let chi2: f64 = cells.iter().map(|(e, o)| (*o as f64 - e).powi(2) / e).sum();
        let dof = (cells.len() - 1) as f64;
        let limit = chi2_quantile(dof, 4.75);
        assert!(
            chi2 < limit,
            "λ = {lambda}: χ² = {chi2} > {limit} ({dof} dof)"
        );
    }
}

/// Zero dead time: mean counts per bin → n_k + n_b (+ dark counts), and the noise labels →
/// n_b + dark; per-bin z-tests at 4.5 sd over 60 bins × 2 (family false-alarm < 1e-3).
#[test]
fn photon_counts_without_dead_time() {
    let det = Detector {
        dead_time_ns: 0.0,
        dark_count_hz: 2e6,
        channels: 3,
        ..Detector::default()
    };
    let (t0, dt, nb) = (1000.0, 0.5, 60);
    let signal: Vec<f64> = (0..nb)
        .map(|i| 3.0 * (-0.5 * ((i as f64 - 30.0) / 4.0).powi(2)).exp())
        .collect();
    let bg = 0.2;
    let dark = det.channels as f64 * det.dark_count_hz * dt * 1e-9;
    let shots = 20_000;
    let mut all = vec![0usize; nb];
    let mut noise = vec![0usize; nb];
    let mut r = rng(5);
    for _ in 0..shots {
        for d in simulate_shot(&signal, bg, t0, dt, &det, &mut r).unwrap() {
            all[d.bin] += 1;
            if d.is_noise {
                noise[d.bin] += 1;
            }
            assert!(
                d.time_ns >= t0 + d.bin as f64 * dt && d.time_ns < t0 + (d.bin + 1) as f64 * dt
            );
            assert!(d.channel < det.channels);
        }
    }
    for k in 0..nb {
        let lam = signal[k] + bg + dark;
        let z = (all[k] as f64 / shots as f64 - lam) / (lam / shots as f64).sqrt();
        assert!(z.abs() < 4.5, "bin {k}: z = {z}");
        let lam_n = bg + dark;
        let zn = (noise[k] as f64 / shots as f64 - lam_n) / (lam_n / shots as f64).sqrt();
        assert!(zn.abs() < 4.5, "bin {k}: noise z = {zn}");
    }
}

/// Constant rate n with non-paralysable dead time τ: the mean count over a gate T follows the
/// renewal result `E N = (T+τ)/μ + (σ²−μ²)/(2μ²)`, μ = τ + 1/n, σ = 1/n, i.e. the rate
/// m = n/(1 + nτ) plus an O(1) start-up term; tested at 5 sd of the renewal variance
/// `T σ²/μ³` (false alarm 5.7e-7), for one channel and for 4 independent channels.
#[test]
fn dead_time_follows_non_paralysable_formula() {
    let (dt, nbins) = (1.0, 2000usize);
    let gate = nbins as f64 * dt;
    for channels in [1u16, 4] {
        let det = Detector {
            dead_time_ns: 2.5,
            dark_count_hz: 0.0,
            channels,
            ..Detector::default()
        };
        let rate_ch = 0.5; // events per ns per channel
        let bg_total = rate_ch * dt * channels as f64;
        let signal = vec![0.0; nbins];
        let shots = 400;
        let mut r = rng(31 + channels as u64);
        let mut total = 0usize;
        for _ in 0..shots {
            let ds = simulate_shot(&signal, bg_total, 0.0, dt, &det, &mut r).unwrap();
            // Within a channel, detections are at least τ apart.
            for ch in 0..channels {
                let ts: Vec<f64> = ds
                    .iter()
                    .filter(|d| d.channel == ch)
                    .map(|d| d.time_ns)
                    .collect();
                assert!(ts.windows(2).all(|w| w[1] - w[0] >= 2.5 - 1e-9));
            }
            total += ds.len();
        }
        let tau = det.dead_time_ns;
        let mu = tau + 1.0 / rate_ch;
        let s2 = 1.0 / (rate_ch * rate_ch);
        let expect_ch = (gate + tau) / mu + (s2 - mu * mu) / (2.0 * mu * mu);
        let var_ch = (gate + tau) * s2 / mu.powi(3);
        let mean = total as f64 / shots as f64;
        let expect = channels as f64 * expect_ch;
        let sd = (channels as f64 * var_ch / shots as f64).sqrt();
        let m_formula = channels as f64 * gate * rate_ch / (1.0 + rate_ch * tau);
        assert!(
            (mean - expect).abs() < 5.0 * sd,
            "{channels} ch: {mean} vs {expect} ± {sd}"
        );
        assert!((expect / m_formula - 1.0).abs() < 2e-3);
        eprintln!(
            "dead time, {channels} channel(s): mean {mean:.2} counts vs renewal {expect:.2} (sd {sd:.2}), n/(1+nτ)·T = {m_formula:.2}"
        );
    }
}

#[test]
fn photon_counting_inputs_and_background() {
    let det = Detector::default();
    // R_sun = η (λ/hc) L Δλ A Ω: Lambertian ρ = 0.3 under E⊥ = 650 W m⁻² µm⁻¹ at θ_s = 30°.
    let l = 0.3 * 650.0 * (30f64.to_radians()).cos() / PI;
    let rate = solar_background_rate(l, 0.03, 0.8, 50e-6, &det, 532.0).unwrap();
    // Ω = 2π(1 − cos α) by its series (the direct form loses 8 digits at 50 µrad).
    let al2 = 50e-6f64 * 50e-6;
    let omega = 2.0 * PI * (al2 / 2.0 - al2 * al2 / 24.0 + al2 * al2 * al2 / 720.0);
    let want = 0.15 * l * 0.03 * 0.8 * omega / photon_energy_j(532.0).unwrap();
    assert!((rate / want - 1.0).abs() < 1e-13, "{rate} vs {want}");
    assert!(solar_background_rate(-1.0, 0.03, 0.8, 1e-4, &det, 532.0).is_err());
    assert!(solar_background_rate(1.0, 0.03, 0.8, f64::NAN, &det, 532.0).is_err());
    let mut r = rng(1);
    assert!(simulate_shot(&[f64::NAN], 0.0, 0.0, 1.0, &det, &mut r).is_err());
    assert!(simulate_shot(&[-1.0], 0.0, 0.0, 1.0, &det, &mut r).is_err());
    assert!(simulate_shot(&[1.0], -0.1, 0.0, 1.0, &det, &mut r).is_err());
    assert!(simulate_shot(&[1.0], 0.0, 0.0, 0.0, &det, &mut r).is_err());
    assert!(simulate_shot(&[1e12], 0.0, 0.0, 1.0, &det, &mut r).is_err());
    assert!(
        simulate_shot(&[], 0.0, 0.0, 1.0, &det, &mut r)
            .unwrap()
            .is_empty()
    );
    // Determinism: the same seed gives the same shot; a closure works as a source.
    let sig = vec![0.5; 100];
    let a = simulate_shot(&sig, 0.1, 0.0, 1.0, &det, &mut rng(3)).unwrap();
    let b = simulate_shot(&sig, 0.1, 0.0, 1.0, &det, &mut rng(3)).unwrap();
    assert_eq!(a, b);
    let mut x = rng(3);
    let mut closure = move || x.next_uniform();
    let c = simulate_shot(&sig, 0.1, 0.0, 1.0, &det, &mut closure).unwrap();
    assert_eq!(a, c);
}

// ---------------------------------------------------------------- footprint sampling (§9.1)

/// Radial CDF of sampled points vs the truncated Gaussian `(1 − e^{−r²/2σ²})/(1 − e^{−R²/2σ²})`:
/// Kolmogorov–Smirnov at 1.95/√N (false alarm ≈ 1e-3), and E[ρ²] = 2σ² without truncation
/// (z < 5).
#[test]
fn footprint_sampling_statistics() {
    let prof = FootprintProfile::dart_default(12.5).unwrap();
    let s = prof.sigma_m();
    let mut r = rng(8);
    let n = 100_000;
    let untrunc = FootprintSampler::new(&prof, f64::INFINITY).unwrap();
    let rho2: Vec<f64> = (0..n)
        .map(|_| {
            let [x, y] = untrunc.sample_footprint_point(r.next_uniform(), r.next_uniform());
            x * x + y * y
        })
        .collect();
    let m = rho2.iter().sum::<f64>() / n as f64;
    // ρ² ~ 2σ² Exp(1): sd 2σ².
    assert!(((m - 2.0 * s * s) / (2.0 * s * s / (n as f64).sqrt())).abs() < 5.0);

    let trunc = FootprintSampler::new(&prof, prof.radius_m()).unwrap();
    assert!((trunc.lost_energy_fraction() - 0.368).abs() < 1e-12);
    let mut radii: Vec<f64> = (0..n)
        .map(|_| {
            let [x, y] = trunc.sample_footprint_point(r.next_uniform(), r.next_uniform());
            (x * x + y * y).sqrt()
        })
        .collect();
    radii.sort_by(f64::total_cmp);
    assert!(*radii.last().unwrap() <= prof.radius_m() * (1.0 + 1e-12));
    let kept = prof.energy_fraction_within(prof.radius_m());
    let d = radii
        .iter()
        .enumerate()
        .map(|(i, &rr)| {
            let f = prof.energy_fraction_within(rr) / kept;
            (f - i as f64 / n as f64)
                .abs()
                .max((f - (i + 1) as f64 / n as f64).abs())
        })
        .fold(0.0, f64::max);
    assert!(d < 1.95 / (n as f64).sqrt(), "KS D = {d}");
}

// ----------------------------------------------------------------------------- LAS 1.4 output

fn sample_points(n_pulses: u64, bands: usize, rgb: bool) -> Vec<LasPoint> {
    let mut r = rng(4);
    let mut pts = Vec::new();
    for pulse in 0..n_pulses {
        let nret = 1 + (r.next_uniform() * 4.0) as u8;
        for k in 1..=nret {
            pts.push(LasPoint {
                x: 651_000.0 + 100.0 * r.next_uniform(),
                y: 4_830_000.0 + 100.0 * r.next_uniform(),
                z: 120.0 + 30.0 * r.next_uniform(),
                intensity: (r.next_uniform() * 65535.0) as u16,
                return_number: k,
                number_of_returns: nret,
                pulse_id: 10_000_000_000 + pulse,
                gps_time: pulse as f64 * 1e-5,
                classification: if k == nret { 2 } else { 5 },
                scanner_channel: (pulse % 4) as u8,
                rgb: rgb.then(|| [pulse as u16, 2 * pulse as u16, 65535]),
                extra: (0..bands)
                    .map(|b| 1e-13 + b as f64 * 0.1 + pulse as f64)
                    .collect(),
            });
        }
    }
    pts
}

fn u16_at(b: &[u8], o: usize) -> u16 {
    u16::from_le_bytes([b[o], b[o + 1]])
}
fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}
fn u64_at(b: &[u8], o: usize) -> u64 {
    u64::from_le_bytes(b[o..o + 8].try_into().unwrap())
}

#[test]
fn las_round_trip_formats_6_and_7() {
    let dir = scratch_dir("las");
    let scale = [0.001, 0.001, 0.0005];
    let offset = [651_000.0, 4_830_000.0, 0.0];
    let names: Vec<String> = ["L_443nm", "L_560nm", "L_665nm", "L_865nm"]
        .map(String::from)
        .to_vec();
    for (fmt, bands, rgb) in [(6u8, 0usize, false), (7, 4, true)] {
        let pts = sample_points(300, bands, rgb);
        let path = dir.join(format!("pc{fmt}.las"));
        write_las(&path, &pts, scale, offset, &names[..bands]).unwrap();

        // Read back with the las crate (0.11 API) and decode the raw extra bytes.
        let mut reader = las::Reader::from_path(&path).unwrap();
        let header = reader.header().clone();
        assert_eq!((header.version().major, header.version().minor), (1, 4));
        assert_eq!(header.point_format().to_u8().unwrap(), fmt);
        assert_eq!(header.number_of_points(), pts.len() as u64);
        let data = reader.read_all().unwrap();
        let back: Vec<las::Point> = data.points().map(|p| p.unwrap()).collect();
        assert_eq!(back.len(), pts.len());
        let mut ids = std::collections::BTreeSet::new();
        for (a, b) in pts.iter().zip(&back) {
            assert!((a.x - b.x).abs() <= 0.5 * scale[0] + 1e-9);
            assert!((a.y - b.y).abs() <= 0.5 * scale[1] + 1e-9);
            assert!((a.z - b.z).abs() <= 0.5 * scale[2] + 1e-9);
            assert_eq!(
                (a.return_number, a.number_of_returns),
                (b.return_number, b.number_of_returns)
            );
            assert_eq!(a.intensity, b.intensity);
            assert_eq!(a.scanner_channel, b.scanner_channel);
            assert_eq!(u8::from(b.classification), a.classification);
            assert_eq!(b.gps_time, Some(a.gps_time));
            assert_eq!(b.color.map(|c| [c.red, c.green, c.blue]), a.rgb);
            assert_eq!(b.extra_bytes.len(), 8 + 8 * bands);
            let id = u64::from_le_bytes(b.extra_bytes[..8].try_into().unwrap());
            assert_eq!(id, a.pulse_id);
            for k in 0..bands {
                let v =
                    f64::from_le_bytes(b.extra_bytes[8 + 8 * k..16 + 8 * k].try_into().unwrap());
                assert_eq!(v.to_bits(), a.extra[k].to_bits());
            }
            ids.insert(id);
        }
        // Pulse IDs consistent: every pulse present once per return, returns 1..=n.
        assert_eq!(ids.len(), 300);
        for id in ids {
            let rs: Vec<&LasPoint> = pts.iter().filter(|p| p.pulse_id == id).collect();
            assert_eq!(rs.len(), rs[0].number_of_returns as usize);
        }

        // The crate's own reader agrees.
        let c = read_las(&path).unwrap();
        assert_eq!((c.version, c.point_format), ((1, 4), fmt));
        assert_eq!(c.extra_names, names[..bands].to_vec());
        assert_eq!(c.points.len(), pts.len());
        for (a, b) in pts.iter().zip(&c.points) {
            assert_eq!((a.pulse_id, &a.extra, a.rgb), (b.pulse_id, &b.extra, b.rgb));
        }

        // Python-free check of the file bytes: header fields and the Extra Bytes VLR as the
        // 192-byte LAS 1.4 struct; extra bytes at the end of each point record.
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[0..4], b"LASF");
        assert_eq!((bytes[24], bytes[25]), (1, 4));
        let header_size = u16_at(&bytes, 94) as usize;
        assert_eq!(header_size, 375);
        let offset_points = u32_at(&bytes, 96) as usize;
        let n_vlrs = u32_at(&bytes, 100);
        assert_eq!(bytes[104], fmt);
        let base_len = if fmt == 6 { 30 } else { 36 };
        let rec_len = u16_at(&bytes, 105) as usize;
        assert_eq!(rec_len, base_len + 8 + 8 * bands);
        assert_eq!(u64_at(&bytes, 247), pts.len() as u64);
        let mut pos = header_size;
        let mut found = false;
        for _ in 0..n_vlrs {
            let user = String::from_utf8_lossy(&bytes[pos + 2..pos + 18])
                .trim_end_matches('\0')
                .to_string();
            let record = u16_at(&bytes, pos + 18);
            let len = u16_at(&bytes, pos + 20) as usize;
            let data = &bytes[pos + 54..pos + 54 + len];
            if user == "LASF_Spec" && record == 4 {
                found = true;
                assert_eq!(len, EXTRA_BYTES_DESCRIPTOR_LEN * (1 + bands));
                for (k, d) in data.chunks_exact(192).enumerate() {
                    assert_eq!(&d[0..2], &[0, 0], "reserved");
                    assert_eq!(d[2], if k == 0 { 7 } else { 10 }, "data_type u64 / f64");
                    assert_eq!(d[3], 0, "options");
                    let name = String::from_utf8_lossy(&d[4..36])
                        .trim_end_matches('\0')
                        .to_string();
                    let want = if k == 0 {
                        PULSE_ID_NAME
                    } else {
                        names[k - 1].as_str()
                    };
                    assert_eq!(name, want);
                    assert!(
                        d[36..160].iter().all(|&b| b == 0),
                        "unused/no_data/min/max/scale/offset"
                    );
                    assert!(d[160] != 0, "description");
                }
            }
            pos += 54 + len;
        }
        assert!(found, "Extra Bytes VLR missing");
        assert!(pos <= offset_points);
        for (i, a) in pts.iter().enumerate() {
            let rec = offset_points + i * rec_len;
            assert_eq!(u64_at(&bytes, rec + base_len), a.pulse_id);
            assert_eq!(bytes[rec + 14] & 0x0f, a.return_number);
            assert_eq!(bytes[rec + 14] >> 4, a.number_of_returns);
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn las_errors_leave_no_file() {
    let dir = scratch_dir("las_err");
    let path = dir.join("bad.las");
    let good = sample_points(3, 1, false);
    let names = vec!["band".to_string()];
    let cases: Vec<(Vec<LasPoint>, &[String])> = vec![
        (
            {
                let mut p = good.clone();
                p[1].return_number = 0;
                p
            },
            &names,
        ),
        (
            {
                let mut p = good.clone();
                p[1].number_of_returns = 16;
                p[1].return_number = 16;
                p
            },
            &names,
        ),
        (
            {
                let mut p = good.clone();
                p[2].x = f64::NAN;
                p
            },
            &names,
        ),
        (
            {
                let mut p = good.clone();
                p[2].z = 1e12;
                p
            },
            &names,
        ),
        (
            {
                let mut p = good.clone();
                p[0].extra.clear();
                p
            },
            &names,
        ),
        (
            {
                let mut p = good.clone();
                p[1].rgb = Some([1, 2, 3]);
                p
            },
            &names,
        ),
        (
            {
                let mut p = good.clone();
                p[1].classification = 12;
                p
            },
            &names,
        ),
        (good.clone(), &[]),
    ];
    for (pts, nm) in cases {
        let err = write_las(&path, &pts, [0.01; 3], [651_000.0, 4_830_000.0, 0.0], nm).unwrap_err();
        assert!(err.contains("bad.las"), "{err}");
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            0,
            "left a file after: {err}"
        );
    }
    assert!(write_las(&path, &good, [0.0, 0.01, 0.01], [0.0; 3], &names).is_err());
    // Empty point list: a valid empty file.
    write_las(&path, &[], [0.01; 3], [0.0; 3], &names).unwrap();
    let c = read_las(&path).unwrap();
    assert!(c.points.is_empty() && c.point_format == 6);
    // Missing folder: error names the file.
    let e = write_las(
        &dir.join("no/such/dir.las"),
        &good,
        [0.01; 3],
        [0.0; 3],
        &names,
    )
    .unwrap_err();
    assert!(e.contains("dir.las"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

// ------------------------------------------------------------------------ waveform products

#[test]
fn waveform_products_round_trip() {
    let dir = scratch_dir("wf");
    let p = example_canopy(GapCorrelation::Independent);
    let (lo, hi) = gate_for(&p);
    let a: AnalyticFirstOrder = analytic_first_order(&p, lo, hi, 1.0).unwrap();
    let conv = a
        .waveform
        .convolve(&PulseShape::from_fwhm_ns(3.0, 3.0).unwrap(), None)
        .unwrap();
    let mut tiny = conv.clone();
    for v in tiny.total.iter_mut().chain(tiny.first_order.iter_mut()) {
        *v *= 1e-4; // ~1e-13 J bins
    }
    tiny.first_order.iter_mut().for_each(|v| *v *= 0.5);
    let items = [
        (7u64, conv.clone()),
        (u64::MAX, tiny.clone()),
        (9, Waveform::zeros(1.0, 1.0, 0)),
    ];
    let refs: Vec<(u64, &Waveform)> = items.iter().map(|(id, w)| (*id, w)).collect();
    let files = write_waveforms(&dir, &refs).unwrap();
    let back = read_waveforms(&dir).unwrap();
    assert_eq!(back.len(), 3);
    for ((id, w), (row, r)) in items.iter().zip(&back) {
        assert_eq!(row.pulse_id, *id);
        assert_eq!(row.n_bins, w.n_bins());
        assert_eq!(row.t0_ns.to_bits(), w.t0_ns.to_bits());
        assert_eq!(row.dt_ns.to_bits(), w.dt_ns.to_bits());
        assert_eq!(row.total_energy_j.to_bits(), w.total_energy_j().to_bits());
        assert_eq!(
            row.first_order_energy_j.to_bits(),
            w.first_order_energy_j().to_bits()
        );
        for (x, y) in w
            .total
            .iter()
            .zip(&r.total)
            .chain(w.first_order.iter().zip(&r.first_order))
        {
            assert!((x - y).abs() <= 6e-8 * x.abs(), "{x} vs {y}");
        }
    }
    let size = std::fs::metadata(&files.data).unwrap().len();
    assert_eq!(size, 8 * (conv.n_bins() + tiny.n_bins()) as u64);
    // Invalid waveform: error, and the previous product is untouched (no partial rewrite).
    let mut bad = conv.clone();
    bad.total[3] = -1.0;
    assert!(write_waveforms(&dir, &[(1, &bad)]).is_err());
    assert_eq!(read_waveforms(&dir).unwrap().len(), 3);

    let svg = waveform_svg(&conv);
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert_eq!(svg.matches("<polyline").count(), 2);
    assert!(svg.contains("time (ns)") && !svg.contains("NaN") && !svg.contains("inf"));
    std::fs::write(dir.join("quicklook.svg"), &svg).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}
