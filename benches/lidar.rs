//! LiDAR speed (harness = false): `cargo bench --bench lidar` (`-- --quick`: fewer pulses).
//!
//! Options (after `--`): `--quick`; `--pulses N` (pulses of every forest row and of the urban
//! scan, rounded up to a square grid); `--row NAME` (run one row only: `legacy-peak`,
//! `continuous-gauss`, `discrete-gauss`, `discrete-peak`, `continuous-peak` or `urban`;
//! repeatable); `--estimator legacy|stratified|expected`, `--photons N`, `--scattering N` (estimator,
//! beam rays and rays continued into multiple scattering of the forest rows, e.g. under
//! callgrind; the estimator also of the urban scan); `--no-skip` (empty-space skipping off:
//! every cell visited, for comparisons); `--no-far-roulette` (the expected-value estimator's
//! far-photon roulette off; `--far-roulette-m M`: its scale ρ₀ = M metres instead of the
//! scene's); `--no-columns` (its column quadrature of the first order off);
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
//! `--row returns` (only when asked for): the two returns methods' time per waveform on
//! synthetic and Monte-Carlo-like waveforms (see `returns_methods`).
//!
//! `--error` runs the speed-against-error study instead of the speed rows (see
//! `error_study`): `--setting EST:PHOTONS[:SCATTERING]` (repeatable; PHOTONS `auto`: the per-pulse default
//! of `photons_per_pulse`; default `legacy:1000`, `stratified:600` and `expected:auto`), `--reps R` realizations per setting (default 4), `--ref-photons N`
//! (reference photons per pulse, default 1e5), `--ref-cache FILE` (reuse the reference),
//! `--error-urban` (the study's 8 × 8 pulse centres over the 60 m urban scene instead of the
//! 40 m forest).
//!
//! 1. ALS on the 40 m forest (24 trees, 1 m cells): pulses per second per core at the default
//!    photons per pulse (`DEFAULT_LIDAR_PHOTONS`, `ExpectedValue` estimator; row `legacy-peak`: 1000 photons of the
//!    `Legacy` estimator, an earlier default at the same waveform error), multiple scattering
//!    (orders ≤ 100), nadir, 0.3 m footprints, for the continuous and discrete (Ray-Carlo)
//!    samplers and both returns methods, with the mean waveform energy and return count per
//!    pulse next to each speed.
//! 2. A multi-pulse scan of the urban scene: 250 000 pulses (500 × 500 grid, 0.12 m spacing)
//!    at 100 photons per pulse (`--quick`: 10 000 pulses), wall time, pulses/s/core, peak RSS.
//!
//! The bench scenes are LiDAR-only, so no passive solver runs (`SceneDesc::runs_passive`); the
//! 64-photon Monte Carlo solver setting only matters if a scene asks for the passive run.

use lumenscape::lidar::returns::{ReturnsMethod, detect_returns_method};
use lumenscape::lidar::run::{LidarProducts, LidarRun};
use lumenscape::lidar::waveform::Waveform;
use lumenscape::photon::engine::SamplerKind;
use lumenscape::resources::scene::{RunSettings, SceneInfo, Solver};
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::{
    DEFAULT_LIDAR_PHOTONS, LidarDesc, LidarEstimator, LidarSampler, PulsePattern, SceneDesc,
};
use lumenscape::scene::generators::{forest, urban};
use lumenscape::simulation::Simulation;
use std::time::Instant;

mod common;
use common::peak_rss_mib;
#[path = "../tests/common/mod.rs"]
mod fixtures;
#[path = "../tests/fixtures/returns_waveforms.rs"]
mod returns_waveforms;
use returns_waveforms::{forest_waveform, gaussian_waveform, peak, settings};

/// The bench instrument: the tests' airborne LiDAR (`tests/common`) at 1 000 m in band `nir`
/// with 3 ns pulses.
fn lidar(pulses: PulsePattern, photons: Option<u32>) -> LidarDesc {
    LidarDesc {
        band: "nir".into(),
        pulse_fwhm_ns: 3.0,
        photons_per_pulse: photons,
        ..fixtures::lidar("bench", 1000.0, pulses, 1)
    }
}

/// The next argument parsed as a `T`; panics with `what` (the option's usage) if it is missing
/// or does not parse (a bench's command line).
fn parsed<T: std::str::FromStr>(args: &mut impl Iterator<Item = String>, what: &str) -> T {
    args.next()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{what}"))
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
    /// `--estimator legacy|stratified|expected` for the forest speed rows (default: the scene default).
    estimator: Option<LidarEstimator>,
    /// `--photons N`: beam rays per pulse of the forest speed rows (default 1000).
    photons: Option<u32>,
    /// `--scattering N`: rays per pulse continued into multiple scattering (stratified).
    scattering: Option<u32>,
    /// `--error`: the speed-against-error study (see the module doc).
    error: bool,
    /// `--ref-photons N`: photons per pulse of the error study's reference (default 100 000).
    ref_photons: u32,
    /// `--ref-cache FILE`: read the reference from FILE if it exists, else write it there.
    ref_cache: Option<String>,
    /// `--setting EST:PHOTONS[:SCATTERING]` (repeatable): the error study's settings
    /// (PHOTONS `auto`, `None` here: the per-pulse default of `photons_per_pulse`).
    settings: Vec<(LidarEstimator, Option<u32>, Option<u32>)>,
    /// `--reps R`: independent realizations of each setting in the error study (default 4).
    reps: usize,
    /// `--out DIR`: the urban scan writes its products into DIR (streaming its waveforms, as
    /// `lumenscape run --out` does), so the peak RSS is that of a real run.
    out: Option<std::path::PathBuf>,
    /// `--no-stream`: every pulse in one chunk (no streaming with `--out`), for comparisons.
    no_stream: bool,
    /// `--no-far-roulette`: the expected-value estimator's far-photon roulette off.
    no_far_roulette: bool,
    /// `--no-columns`: the expected-value estimator's column quadrature of the first order off.
    no_columns: bool,
    /// `--far-roulette-m M`: the far-photon roulette's distance scale ρ₀ instead of the scene's.
    far_roulette_m: Option<f64>,
    /// `--error-urban`: the error study on the urban scene (60 m) instead of the forest.
    error_urban: bool,
}

impl Options {
    fn parse() -> Self {
        let mut o = Options {
            ref_photons: 100_000,
            reps: 4,
            out: None,
            no_stream: false,
            no_far_roulette: false,
            ..Default::default()
        };
        let mut args = std::env::args().skip(1);
        while let Some(a) = args.next() {
            match a.as_str() {
                "--quick" => o.quick = true,
                "--digest" => o.digest = true,
                "--no-skip" => o.no_skip = true,
                "--no-stream" => o.no_stream = true,
                "--no-far-roulette" => o.no_far_roulette = true,
                "--far-roulette-m" => {
                    o.far_roulette_m = Some(parsed(&mut args, "--far-roulette-m METRES"))
                }
                "--no-columns" => o.no_columns = true,
                "--error-urban" => o.error_urban = true,
                "--out" => {
                    o.out = Some(args.next().expect("--out DIR").into());
                }
                "--pulses" => o.pulses = Some(parsed(&mut args, "--pulses N (a positive integer)")),
                "--row" => o.rows.push(args.next().expect("--row NAME")),
                "--estimator" => {
                    o.estimator = Some(parse_estimator(&args.next().expect("--estimator NAME")))
                }
                "--photons" => o.photons = Some(parsed(&mut args, "--photons N")),
                "--scattering" => o.scattering = Some(parsed(&mut args, "--scattering N")),
                "--error" => o.error = true,
                "--ref-photons" => o.ref_photons = parsed(&mut args, "--ref-photons N"),
                "--reps" => o.reps = args.next().and_then(|v| v.parse().ok()).expect("--reps R"),
                "--ref-cache" => o.ref_cache = Some(args.next().expect("--ref-cache FILE")),
                "--setting" => {
                    let v = args.next().expect("--setting EST:PHOTONS[:SCATTERING]");
                    let f: Vec<&str> = v.split(':').collect();
                    let n = |i: usize| -> Option<u32> {
                        f.get(i).map(|x| x.parse().expect("--setting: a count"))
                    };
                    let photons = match f.get(1) {
                        Some(&"auto") => None,
                        _ => Some(n(1).expect("--setting EST:PHOTONS")),
                    };
                    o.settings.push((parse_estimator(f[0]), photons, n(2)));
                }
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
        if self.error && self.rows.is_empty() {
            return false;
        }
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

/// Runs the scene with one LiDAR (its products in the `LidarProducts` resource).
fn simulate(
    d: SceneDesc,
    l: LidarDesc,
    opt: &Options,
    out: Option<&std::path::Path>,
) -> Simulation {
    simulate_seeded(d, l, opt, out, None)
}

/// [`simulate`] with the LiDAR's random seed replaced by `seed` when given (the scene itself,
/// tree placement included, is still built from the description's seed: same forest).
fn simulate_seeded(
    mut d: SceneDesc,
    l: LidarDesc,
    opt: &Options,
    out: Option<&std::path::Path>,
    seed: Option<u64>,
) -> Simulation {
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
            lidar_first_order_columns: !opt.no_columns,
            lidar_far_roulette: match (opt.no_far_roulette, opt.far_roulette_m) {
                (true, _) => lumenscape::lidar::simulate::FarRoulette::Off,
                (false, Some(m)) => lumenscape::lidar::simulate::FarRoulette::ScaleM(m),
                (false, None) => lumenscape::lidar::simulate::FarRoulette::Auto,
            },
            lidar_chunk_pulses: if opt.no_stream {
                usize::MAX
            } else {
                lumenscape::lidar::simulate::DEFAULT_CHUNK_PULSES
            },
            ..Default::default()
        },
    )
    .unwrap();
    if let Some(seed) = seed {
        sim.world.resource_mut::<SceneInfo>().seed = seed;
    }
    sim.run(out).unwrap();
    sim
}

/// Runs the scene with one LiDAR and returns its products.
fn run_products(d: SceneDesc, l: LidarDesc, opt: &Options) -> LidarRun {
    run_products_seeded(d, l, opt, None)
}

/// [`run_products`] with the LiDAR's random seed replaced by `seed` when given.
fn run_products_seeded(d: SceneDesc, l: LidarDesc, opt: &Options, seed: Option<u64>) -> LidarRun {
    simulate_seeded(d, l, opt, None, seed)
        .resource::<LidarProducts>()
        .0[0]
        .clone()
}

/// SplitMix64's output function (Steele, Lea & Flood 2014): a bijection of 64-bit words whose
/// outputs for consecutive inputs are statistically independent.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn run(d: SceneDesc, l: LidarDesc, name: &str, opt: &mut Options) -> Outcome {
    run_into(d, l, name, opt, None)
}

/// [`run`], writing the products into `out` when given (a scan longer than one chunk then
/// streams its waveforms to disk while it runs).
fn run_into(
    d: SceneDesc,
    l: LidarDesc,
    name: &str,
    opt: &mut Options,
    out: Option<&std::path::Path>,
) -> Outcome {
    let t0 = std::time::Instant::now();
    let sim = simulate(d, l, opt, out);
    let wall = t0.elapsed().as_secs_f64();
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
    // Every pulse (a streamed run keeps only the quick-looks' pulses in memory).
    let n = r.pulse_count().max(1) as f64;
    let (mut energy, mut returns) = (0.0, 0.0);
    for p in r.pulse_entries().expect("pulse entries") {
        let p = p.expect("pulse entry");
        energy += p.received_j / n;
        returns += p.returns.len() as f64 / n;
    }
    Outcome {
        seconds: r.seconds,
        wall,
        pulses: r.pulse_count(),
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
    /// LiDAR stage time, s.
    seconds: f64,
    /// The whole simulation (stages and product writing), s.
    wall: f64,
    pulses: usize,
    energy: f64,
    returns: f64,
}

fn main() {
    let mut opt = Options::parse();
    if opt.rows.iter().any(|r| r == "returns") {
        returns_methods();
        if opt.rows.len() == 1 {
            return;
        }
    }
    let quick = opt.quick;
    let threads = rayon::current_num_threads() as f64;
    let f = forest::forest(&forest::ForestParams {
        size_m: 40.0,
        ..Default::default()
    });
    let n = opt.pulses.unwrap_or(if quick { 200 } else { 2000 });
    let side = ((n as f64).sqrt().ceil() as u32).max(2);
    println!(
        "ALS forest 40 m, multiple scattering (100 orders), {threads} threads; photons/pulse: {} (expected-value estimator, the default) or 1000 (legacy row)",
        opt.photons.unwrap_or(DEFAULT_LIDAR_PHOTONS)
    );
    println!(
        "{:>16} {:>10} {:>22} {:>7} {:>8} {:>13} {:>15} {:>13} {:>9}",
        "row",
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
            "legacy-peak",
            LidarSampler::Discrete,
            ReturnsMethod::PeakDetection,
        ),
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
            opt.photons,
        );
        l.sampler = sampler;
        l.returns = method;
        if name == "legacy-peak" {
            // The estimator and photon count before 2026-11-26.
            l.estimator = LidarEstimator::Legacy;
            l.photons_per_pulse = Some(1000);
        }
        if let Some(e) = opt.estimator {
            l.estimator = e;
        }
        l.scattering_photons_per_pulse = opt.scattering.or(l.scattering_photons_per_pulse);
        // Nominal (with the default count, pulses without the column quadrature have 72).
        let photons = l.photons_per_pulse.unwrap_or(DEFAULT_LIDAR_PHOTONS) as f64;
        let o = run(f.clone(), l, name, &mut opt);
        println!(
            "{:>16} {:>10} {:>22} {:>7} {:>8.2} {:>13.0} {:>15.2e} {:>13.4e} {:>9.2}",
            name,
            format!("{sampler:?}"),
            format!("{method:?}"),
            o.pulses,
            o.seconds,
            o.pulses as f64 / o.seconds / threads,
            o.pulses as f64 * photons / o.seconds / threads,
            o.energy,
            o.returns
        );
    }
    println!("peak RSS {:.0} MiB", peak_rss_mib());
    if opt.error {
        if opt.error_urban {
            error_study(
                &urban::urban(&urban::UrbanParams::default()),
                60.0,
                &mut opt,
            );
        } else {
            error_study(&f, 40.0, &mut opt);
        }
    }
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
        Some(100),
    );
    l.returns = ReturnsMethod::PeakDetection;
    if let Some(e) = opt.estimator {
        l.estimator = e;
    }
    let out = opt.out.clone();
    let o = run_into(u, l, "urban", &mut opt, out.as_deref());
    let (secs, pulses) = (o.seconds, o.pulses);
    println!(
        "urban scan, {pulses} pulses × 100 photons, peak-detection returns: {secs:.1} s, {:.0} pulses/s/core, peak RSS {:.0} MiB{}",
        pulses as f64 / secs / threads,
        peak_rss_mib(),
        match &out {
            Some(d) => format!(
                "; products written to {} (waveforms {}), whole run {:.1} s",
                d.display(),
                if opt.no_stream {
                    "kept in memory"
                } else {
                    "streamed"
                },
                o.wall
            ),
            None => String::new(),
        }
    );
}

fn parse_estimator(v: &str) -> LidarEstimator {
    match v {
        "legacy" => LidarEstimator::Legacy,
        "stratified" => LidarEstimator::Stratified,
        "expected" => LidarEstimator::ExpectedValue,
        _ => panic!("estimator `{v}`: legacy, stratified or expected"),
    }
}

/// Waveforms (raw, convolved) of every pulse of a run, in pulse order.
fn waveforms_of(r: &LidarRun) -> Vec<(Waveform, Waveform)> {
    let mut v: Vec<_> = r
        .pulses
        .iter()
        .map(|p| (p.id, p.raw.clone(), p.waveform.clone()))
        .collect();
    v.sort_by_key(|x| x.0);
    v.into_iter().map(|(_, a, b)| (a, b)).collect()
}

fn write_waveform(text: &mut String, w: &Waveform) {
    *text += &format!("{:e} {:e} {}", w.t0_ns, w.dt_ns, w.total.len());
    for v in w.total.iter().chain(&w.first_order) {
        *text += &format!(" {v:e}");
    }
    text.push('\n');
}

fn read_waveform(line: &str) -> Waveform {
    let mut it = line
        .split_whitespace()
        .map(|x| x.parse::<f64>().expect("cache"));
    let t0 = it.next().expect("cache");
    let dt = it.next().expect("cache");
    let n = it.next().expect("cache") as usize;
    let v: Vec<f64> = it.collect();
    assert_eq!(v.len(), 2 * n, "cache: bins");
    Waveform {
        t0_ns: t0,
        dt_ns: dt,
        total: v[..n].to_vec(),
        first_order: v[n..].to_vec(),
    }
}

/// Relative L2 distance `‖a − r‖/‖r‖` over a common time axis, for the total, the first
/// order and the rest (multiple scattering), and the relative energy error of the total.
fn waveform_errors(a: &Waveform, r: &Waveform) -> [f64; 4] {
    let dt = r.dt_ns;
    let t0 = a.t0_ns.min(r.t0_ns);
    let t1 = (a.t0_ns + a.total.len() as f64 * dt).max(r.t0_ns + r.total.len() as f64 * dt);
    let n = ((t1 - t0) / dt).round() as usize + 1;
    let (a, r) = (a.padded_to(t0, n), r.padded_to(t0, n));
    let l2 = |x: &dyn Fn(&Waveform, usize) -> f64| {
        let (mut d, mut s) = (0.0, 0.0);
        for k in 0..n {
            let (u, v) = (x(&a, k), x(&r, k));
            d += (u - v) * (u - v);
            s += v * v;
        }
        if s > 0.0 { (d / s).sqrt() } else { 0.0 }
    };
    let ea: f64 = a.total.iter().sum();
    let er: f64 = r.total.iter().sum();
    [
        l2(&|w, k| w.total[k]),
        l2(&|w, k| w.first_order[k]),
        l2(&|w, k| w.total[k] - w.first_order[k]),
        if er > 0.0 { (ea / er - 1.0).abs() } else { 0.0 },
    ]
}

/// `--error`: speed against waveform error on 64 forest ALS pulses (8 × 8 grid over the 40 m
/// forest, the speed rows' instrument, discrete sampler, peak detection). Reference: the
/// `Legacy` estimator at `--ref-photons` photons per pulse (default 1e5), with the pulses listed
/// in reverse order; each realization of a setting draws from its own LiDAR seed (SplitMix64 of
/// the scene seed and the realization index; the scene is built from the scene seed), so the
/// realizations are independent of each other and of the reference. Per pulse: relative L2
/// error of the convolved waveform (the product) and of the raw one, total, first order and
/// multiple scattering (total − first), and the relative error of the pulse energy; the table
/// gives their means over the pulses.
/// The reference's own noise adds (N_set/N_ref) of each setting's error variance (1 % at
/// 1000 vs 1e5 photons: +0.5 % on the error).
fn error_study(f: &SceneDesc, size_m: f64, opt: &mut Options) {
    let side = 8usize;
    let centres: Vec<(f64, f64)> = (0..side * side)
        .map(|k| {
            let (i, j) = (k % side, k / side);
            (
                1.0 + (size_m - 2.0) * i as f64 / (side - 1) as f64,
                1.0 + (size_m - 2.0) * j as f64 / (side - 1) as f64,
            )
        })
        .collect();
    let desc = |est: LidarEstimator,
                photons: Option<u32>,
                scattering: Option<u32>,
                list: Vec<(f64, f64)>| {
        let mut l = lidar(PulsePattern::List(list), photons);
        l.returns = ReturnsMethod::PeakDetection;
        l.estimator = est;
        l.scattering_photons_per_pulse = scattering;
        l
    };
    let cached = opt
        .ref_cache
        .as_ref()
        .and_then(|p| std::fs::read_to_string(p).ok());
    let reference: Vec<(Waveform, Waveform)> = match cached {
        Some(text) => {
            let lines: Vec<&str> = text.lines().collect();
            assert_eq!(lines.len(), 2 * centres.len(), "--ref-cache: pulses");
            lines
                .chunks(2)
                .map(|c| (read_waveform(c[0]), read_waveform(c[1])))
                .collect()
        }
        None => {
            let mut rev = centres.clone();
            rev.reverse();
            let l = desc(LidarEstimator::Legacy, Some(opt.ref_photons), None, rev);
            let t = std::time::Instant::now();
            let r = run_products(f.clone(), l, opt);
            let mut w = waveforms_of(&r);
            w.reverse();
            println!(
                "reference: {} pulses × {} photons (legacy), {:.1} s",
                w.len(),
                opt.ref_photons,
                t.elapsed().as_secs_f64()
            );
            if let Some(p) = &opt.ref_cache {
                let mut text = String::new();
                for (a, b) in &w {
                    write_waveform(&mut text, a);
                    write_waveform(&mut text, b);
                }
                std::fs::write(p, text).expect("--ref-cache: write");
            }
            w
        }
    };
    let settings = if opt.settings.is_empty() {
        vec![
            (LidarEstimator::Legacy, Some(1000), None),
            (LidarEstimator::Stratified, Some(600), None),
            (LidarEstimator::ExpectedValue, None, None),
        ]
    } else {
        opt.settings.clone()
    };
    let threads = rayon::current_num_threads() as f64;
    let reps = opt.reps.max(1);
    println!(
        "error study: 64 forest pulses × {reps} realizations; mean over pulses of the relative L2 error of the convolved (raw) waveform: total, first order, multiple scattering; mean |energy error|"
    );
    println!(
        "pulses/s/core at 1 %: the speed scaled to a total error of 1 % by error ∝ 1/√cost, (1 %/error)² × pulses/s/core (wall time: noisy on a loaded host; callgrind instruction counts in docs/performance.md)"
    );
    println!(
        "{:>13} {:>7} {:>7} {:>8} {:>13} {:>16} {:>16} {:>16} {:>8} {:>10}",
        "estimator",
        "photons",
        "scatter",
        "wall_s",
        "pulses/s/core",
        "total",
        "first",
        "multiple",
        "energy",
        "at 1 %"
    );
    for (est, photons, scattering) in settings {
        let mut conv = [0.0; 4];
        let mut raw = [0.0; 4];
        let (mut seconds, mut pulses) = (0.0, 0);
        let mut per_rep = Vec::new();
        for k in 0..reps {
            // Realization k: the LiDAR's random streams come from its own seed, SplitMix64 of
            // (scene seed, k), so every realization is independent of the others and of the
            // reference (scene seed, pulses reversed); the forest itself is the same.
            let seed = splitmix64(f.seed ^ splitmix64(k as u64 + 1));
            let l = desc(est, photons, scattering, centres.clone());
            let r = run_products_seeded(f.clone(), l, opt, Some(seed));
            seconds += r.seconds;
            pulses += r.pulses.len();
            let w = waveforms_of(&r);
            let mut e_rep = 0.0;
            for ((wr, wc), (rr, rc)) in w.iter().zip(&reference) {
                let ec = waveform_errors(wc, rc);
                let er = waveform_errors(wr, rr);
                for k in 0..4 {
                    conv[k] += ec[k] / (w.len() * reps) as f64;
                    raw[k] += er[k] / (w.len() * reps) as f64;
                }
                e_rep += ec[0] / w.len() as f64;
            }
            per_rep.push(format!("{:.2}", 100.0 * e_rep));
        }
        let r = Outcome {
            seconds,
            wall: seconds,
            pulses,
            energy: 0.0,
            returns: 0.0,
        };
        let rate = r.pulses as f64 / r.seconds / threads;
        println!(
            "{:>13} {:>7} {:>7} {:>8.2} {:>13.0} {:>7.2} % ({:>4.1}) {:>7.2} % ({:>4.1}) {:>7.2} % ({:>4.1}) {:>6.2} % {:>10.0}",
            format!("{est:?}"),
            photons.map_or("auto".to_string(), |n| n.to_string()),
            scattering.map_or("all".to_string(), |s| s.to_string()),
            r.seconds,
            rate,
            100.0 * conv[0],
            100.0 * raw[0],
            100.0 * conv[1],
            100.0 * raw[1],
            100.0 * conv[2],
            100.0 * raw[2],
            100.0 * conv[3],
            rate / (100.0 * conv[0]).powi(2)
        );
        println!("    total error per realization (%): {}", per_rep.join(" "));
    }
}

/// µs per waveform for both methods with the pipeline's settings and floor (1e-3 × peak).
fn returns_methods() {
    let n = 100;
    let sets: Vec<(&str, Vec<Waveform>)> = vec![
        (
            "3-6 Gaussians, 400 bins, clean",
            (0..n).map(|s| gaussian_waveform(s, false)).collect(),
        ),
        (
            "3-6 Gaussians, 400 bins, Poisson 1e5",
            (0..n).map(|s| gaussian_waveform(s, true)).collect(),
        ),
        (
            "MC forest, 1000 packets, pulse σ = 2 bins",
            (0..n).map(|s| forest_waveform(s, 1000, 2.0)).collect(),
        ),
        (
            "MC forest, 1000 packets, pulse FWHM 3 ns",
            (0..n)
                .map(|s| forest_waveform(s, 1000, 3.0 / 2.3548))
                .collect(),
        ),
    ];
    for (name, ws) in &sets {
        for method in [
            ReturnsMethod::PeakDetection,
            ReturnsMethod::GaussianDecomposition,
        ] {
            let reps = if method == ReturnsMethod::PeakDetection {
                200
            } else {
                1
            };
            let mut count = 0;
            let t = Instant::now();
            for _ in 0..reps {
                for w in ws {
                    count += detect_returns_method(w, 1e-3 * peak(w), method, &settings())
                        .unwrap()
                        .len();
                }
            }
            let per = (reps * ws.len()) as f64;
            eprintln!(
                "{name} ({} bins): {method:?} {:.2} µs/waveform, {:.2} returns/waveform",
                ws[0].n_bins(),
                t.elapsed().as_secs_f64() * 1e6 / per,
                count as f64 / per
            );
        }
    }
}
