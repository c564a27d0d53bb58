//! LiDAR speed (harness = false): `cargo bench --bench lidar` (`-- --quick`: fewer pulses).
//!
//! Options (after `--`): `--quick`; `--pulses N` (pulses of every forest row and of the urban
//! scan, rounded up to a square grid); `--row NAME` (run one row only: `continuous-gauss`,
//! `discrete-gauss`, `discrete-peak`, `continuous-peak` or `urban`; repeatable);
//! `--no-skip` (empty-space skipping off: every cell visited, for comparisons);
//! `--digest` (print an FNV-1a hash of every product of each row — raw and convolved
//! waveforms, gate losses, returns — to prove bit-identity across code changes); `--dump FILE`
//! (write those products as text, one pulse per line, rows one after another);
//! `--fit-study FILE` (re-run the Gaussian decomposition with the pipeline's settings on every
//! stored waveform, padded with 64 empty bins on each side, and print the fits' counters: share
//! of fits stopped by the iteration cap, iterations and model evaluations per fit, decomposition
//! CPU time per waveform; write one line per waveform — row, pulse, final residual sum of
//! squares (J²), returns, fits, capped fits, evaluations — to FILE, to compare fitters on the
//! same waveforms).
//!
//! 1. ALS on the 40 m forest (24 trees, 1 m cells): pulses per second per core at 1000
//!    photons per pulse, multiple scattering (orders ≤ 100), nadir, 0.3 m footprints, for the
//!    continuous and discrete (Ray-Carlo) samplers and both returns methods, with the mean
//!    waveform energy and return count per pulse next to each speed.
//! 2. A multi-pulse scan of the urban scene: 250 000 pulses (500 × 500 grid, 0.12 m spacing)
//!    at 100 photons per pulse (`--quick`: 10 000 pulses), wall time, pulses/s/core, peak RSS.
//!
//! The passive solver is reduced to a 64-photon Monte Carlo run so the timings are the LiDAR's.

use lumenscape::lidar::returns::ReturnsMethod;
use lumenscape::photon::engine::SamplerKind;
use lumenscape::resources::lidar::{LidarProducts, LidarRun};
use lumenscape::resources::scene::{RunSettings, Solver};
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::{LidarDesc, LidarPlatform, LidarSampler, PulsePattern, SceneDesc};
use lumenscape::scene::generators::{forest, urban};
use lumenscape::simulation::Simulation;

mod common;
use common::peak_rss_mib;

fn lidar(pulses: PulsePattern, photons: u32) -> LidarDesc {
    LidarDesc {
        name: "bench".into(),
        band: "nir".into(),
        platform: LidarPlatform::Airborne {
            altitude_m: 1000.0,
            view_zenith_deg: 0.0,
            view_azimuth_deg: 0.0,
            pulses,
        },
        footprint_radius_m: Some(0.3),
        divergence_mrad: None,
        edge_intensity: 0.368,
        fov_radius_m: None,
        pulse_energy_j: 1.0,
        pulse_fwhm_ns: 3.0,
        aperture_m2: 0.1,
        bin_ns: 1.0,
        photons_per_pulse: photons,
        max_order: 100,
        gate_margin_m: 10.0,
        photon_counting: None,
        beam: None,
        returns: ReturnsMethod::GaussianDecomposition,
        sampler: LidarSampler::Discrete,
    }
}

/// Command-line options (see the module doc).
#[derive(Default)]
struct Options {
    quick: bool,
    pulses: Option<usize>,
    rows: Vec<String>,
    digest: bool,
    dump: Option<std::fs::File>,
    fit_study: Option<std::fs::File>,
    /// `--no-skip`: empty-space skipping off (every cell visited), for comparisons.
    no_skip: bool,
}

impl Options {
    fn parse() -> Self {
        let mut o = Options::default();
        let mut args = std::env::args().skip(1);
        while let Some(a) = args.next() {
            match a.as_str() {
                "--quick" => o.quick = true,
                "--digest" => o.digest = true,
                "--no-skip" => o.no_skip = true,
                "--pulses" => {
                    o.pulses = Some(
                        args.next()
                            .and_then(|v| v.parse().ok())
                            .expect("--pulses N (a positive integer)"),
                    )
                }
                "--row" => o.rows.push(args.next().expect("--row NAME")),
                "--dump" => {
                    let f = args.next().expect("--dump FILE");
                    o.dump = Some(std::fs::File::create(&f).expect("--dump: cannot create file"));
                }
                "--fit-study" => {
                    let f = args.next().expect("--fit-study FILE");
                    o.fit_study =
                        Some(std::fs::File::create(&f).expect("--fit-study: cannot create file"));
                }
                _ => {} // `--bench` and the like, passed by cargo
            }
        }
        o
    }

    fn wants(&self, row: &str) -> bool {
        self.rows.is_empty() || self.rows.iter().any(|r| r == row)
    }
}

/// FNV-1a (64 bit) over the products of one run, and the optional text dump.
fn digest(r: &LidarRun, name: &str, dump: Option<&mut std::fs::File>) -> u64 {
    use std::io::Write;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |x: u64| {
        for b in x.to_le_bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    let mut text = String::new();
    for p in &r.pulses {
        eat(p.id);
        text += &format!("{name} pulse {}", p.id);
        for w in [&p.raw, &p.waveform] {
            eat(w.t0_ns.to_bits());
            eat(w.total.len() as u64);
            w.total.iter().for_each(|v| eat(v.to_bits()));
            w.first_order.iter().for_each(|v| eat(v.to_bits()));
            text += &format!(
                " | t0 {:e} n {} E {:e} E1 {:e}",
                w.t0_ns,
                w.total.len(),
                w.total.iter().sum::<f64>(),
                w.first_order.iter().sum::<f64>()
            );
        }
        eat(p.out_of_gate_j.to_bits());
        eat(p.missed_j.to_bits());
        text += &format!(" | gate {:e} missed {:e} |", p.out_of_gate_j, p.missed_j);
        for x in &p.returns {
            for v in [x.time_ns, x.amplitude_j_per_bin, x.width_ns, x.energy_j] {
                eat(v.to_bits());
            }
            text += &format!(
                " ({:.6e} {:.6e} {:.6e} {:.6e})",
                x.time_ns, x.amplitude_j_per_bin, x.width_ns, x.energy_j
            );
        }
        text.push('\n');
    }
    if let Some(f) = dump {
        f.write_all(text.as_bytes()).expect("--dump: write failed");
    }
    h
}

fn run(mut d: SceneDesc, l: LidarDesc, name: &str, opt: &mut Options) -> Outcome {
    d.lidars = Some(vec![l]);
    let mut sim = Simulation::from_desc(
        &d,
        &SceneSource::generated(),
        RunSettings {
            solver: Solver::MonteCarlo {
                photons: 64,
                sampler: SamplerKind::Continuous,
            },
            skip_empty: !opt.no_skip,
            ..Default::default()
        },
    )
    .unwrap();
    sim.run(None).unwrap();
    let r = &sim.resource::<LidarProducts>().0[0];
    if opt.digest || opt.dump.is_some() {
        let h = digest(r, name, opt.dump.as_mut());
        if opt.digest {
            println!("digest {name}: {h:016x}");
        }
    }
    if let Some(f) = opt.fit_study.as_mut() {
        fit_study(r, name, f);
    }
    let n = r.pulses.len().max(1) as f64;
    let energy = r
        .pulses
        .iter()
        .map(|p| p.waveform.total.iter().sum::<f64>())
        .sum::<f64>()
        / n;
    let returns = r.pulses.iter().map(|p| p.returns.len()).sum::<usize>() as f64 / n;
    Outcome {
        seconds: r.seconds,
        pulses: r.pulses.len(),
        energy,
        returns,
    }
}

/// `--fit-study`: the decomposition's counters on the run's stored waveforms (see the module
/// doc).
fn fit_study(r: &LidarRun, name: &str, f: &mut std::fs::File) {
    use lumenscape::lidar::returns::{FitStats, detect_returns_stats};
    use std::io::Write;
    let settings = lumenscape::lidar::simulate::pipeline_decomposition_settings();
    let mut sum = FitStats::default();
    let mut text = String::new();
    let mut secs = 0.0;
    let mut waveforms = 0;
    for p in &r.pulses {
        let w = &p.waveform;
        let peak = w.total.iter().cloned().fold(0.0, f64::max);
        if peak <= 0.0 {
            continue;
        }
        let w = w.padded_to(w.t0_ns - 64.0 * w.dt_ns, w.total.len() + 128);
        let t0 = std::time::Instant::now();
        let (ret, st) = detect_returns_stats(&w, 1e-3 * peak, &settings).expect("fit");
        secs += t0.elapsed().as_secs_f64();
        waveforms += 1;
        sum.fits += st.fits;
        sum.capped += st.capped;
        sum.iterations += st.iterations;
        sum.evaluations += st.evaluations;
        sum.chi2_pairs.extend_from_slice(&st.chi2_pairs);
        text += &format!(
            "{name} {} {:e} {} {} {} {}\n",
            p.id,
            st.rss_j2,
            ret.len(),
            st.fits,
            st.capped,
            st.evaluations
        );
    }
    f.write_all(text.as_bytes())
        .expect("--fit-study: write failed");
    // Per fit, new vs legacy final χ² from the same start.
    let mut rel: Vec<f64> = sum
        .chi2_pairs
        .iter()
        .map(|&(old, new)| if old > 0.0 { (new - old) / old } else { 0.0 })
        .collect();
    rel.sort_by(f64::total_cmp);
    let count = |f: &dyn Fn(f64) -> bool| rel.iter().filter(|&&r| f(r)).count();
    let q = |p: f64| {
        rel.get(((rel.len().max(1) - 1) as f64 * p) as usize)
            .copied()
    };
    println!(
        "fit study {name}: final chi2 of each fit vs the legacy fitter from the same start: lower by > 1e-9 relative in {}, within 1e-9 in {}, higher by > 1e-9 in {} (> 1e-6: {}) of {}; quantiles 0/1/50/99/100 %: {:?} {:?} {:?} {:?} {:?}",
        count(&|r| r < -1e-9),
        count(&|r| r.abs() <= 1e-9),
        count(&|r| r > 1e-9),
        count(&|r| r > 1e-6),
        rel.len(),
        q(0.0),
        q(0.01),
        q(0.5),
        q(0.99),
        q(1.0)
    );
    let fits = sum.fits.max(1) as f64;
    println!(
        "fit study {name}: {waveforms} waveforms, {} fits, {:.1} % capped at {} iterations, {:.1} iterations and {:.1} evaluations per fit, {:.0} µs per waveform",
        sum.fits,
        100.0 * sum.capped as f64 / fits,
        settings.max_iterations,
        sum.iterations as f64 / fits,
        sum.evaluations as f64 / fits,
        1e6 * secs / waveforms.max(1) as f64
    );
}

/// One LiDAR run: stage wall time, pulses, mean waveform energy per pulse (J) and mean number
/// of discrete returns per pulse.
struct Outcome {
    seconds: f64,
    pulses: usize,
    energy: f64,
    returns: f64,
}

fn main() {
    let mut opt = Options::parse();
    let quick = opt.quick;
    let threads = rayon::current_num_threads() as f64;
    let f = forest::forest(&forest::ForestParams {
        size_m: 40.0,
        ..Default::default()
    });
    let n = opt.pulses.unwrap_or(if quick { 200 } else { 2000 });
    let side = ((n as f64).sqrt().ceil() as u32).max(2);
    println!(
        "ALS forest 40 m, 1000 photons/pulse, multiple scattering (100 orders), {threads} threads"
    );
    println!(
        "{:>10} {:>22} {:>7} {:>8} {:>13} {:>15} {:>13} {:>9}",
        "sampler",
        "returns",
        "pulses",
        "wall_s",
        "pulses/s/core",
        "photons/s/core",
        "mean_E_J",
        "returns"
    );
    for (name, sampler, method) in [
        (
            "continuous-gauss",
            LidarSampler::Continuous,
            ReturnsMethod::GaussianDecomposition,
        ),
        (
            "discrete-gauss",
            LidarSampler::Discrete,
            ReturnsMethod::GaussianDecomposition,
        ),
        (
            "discrete-peak",
            LidarSampler::Discrete,
            ReturnsMethod::PeakDetection,
        ),
        (
            "continuous-peak",
            LidarSampler::Continuous,
            ReturnsMethod::PeakDetection,
        ),
    ] {
        if !opt.wants(name) {
            continue;
        }
        let mut l = lidar(
            PulsePattern::Scan {
                start: (1.0, 1.0),
                end: (39.0, 1.0),
                lines: side,
                line_spacing_m: 38.0 / side as f64,
                pulse_spacing_m: 38.0 / (side - 1) as f64,
            },
            1000,
        );
        l.sampler = sampler;
        l.returns = method;
        let o = run(f.clone(), l, name, &mut opt);
        println!(
            "{:>10} {:>22} {:>7} {:>8.2} {:>13.0} {:>15.2e} {:>13.4e} {:>9.2}",
            format!("{sampler:?}"),
            format!("{method:?}"),
            o.pulses,
            o.seconds,
            o.pulses as f64 / o.seconds / threads,
            o.pulses as f64 * 1000.0 / o.seconds / threads,
            o.energy,
            o.returns
        );
    }
    println!("peak RSS {:.0} MiB", peak_rss_mib());
    if !opt.wants("urban") {
        return;
    }
    let u = urban::urban(&urban::UrbanParams::default());
    let m = match opt.pulses {
        Some(p) => ((p as f64).sqrt().ceil() as u32).max(2),
        None if quick => 100,
        None => 500,
    };
    let mut l = lidar(
        PulsePattern::Scan {
            start: (0.0, 0.0),
            end: (59.9, 0.0),
            lines: m,
            line_spacing_m: 59.9 / m as f64,
            pulse_spacing_m: 59.9 / (m - 1) as f64,
        },
        100,
    );
    l.returns = ReturnsMethod::PeakDetection;
    let o = run(u, l, "urban", &mut opt);
    let (secs, pulses) = (o.seconds, o.pulses);
    println!(
        "urban scan, {pulses} pulses × 100 photons, peak-detection returns: {secs:.1} s, {:.0} pulses/s/core, peak RSS {:.0} MiB",
        pulses as f64 / secs / threads,
        peak_rss_mib()
    );
}
