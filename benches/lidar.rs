//! LiDAR speed (harness = false): `cargo bench --bench lidar` (`-- --quick`: fewer pulses).
//!
//! 1. ALS on the 40 m forest (24 trees, 1 m cells): pulses per second per core at 1000
//!    photons per pulse, multiple scattering (orders ≤ 100), nadir, 0.3 m footprints.
//! 2. A multi-pulse scan of the urban scene: 250 000 pulses (500 × 500 grid, 0.12 m spacing)
//!    at 100 photons per pulse (`--quick`: 10 000 pulses), wall time, pulses/s/core, peak RSS.
//!
//! The passive solver is reduced to a 64-photon Monte Carlo run so the timings are the LiDAR's.

use lumenscape::photon::engine::SamplerKind;
use lumenscape::resources::lidar::LidarProducts;
use lumenscape::resources::scene::{RunSettings, Solver};
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::{LidarDesc, LidarPlatform, PulsePattern, SceneDesc};
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
    }
}

fn run(mut d: SceneDesc, l: LidarDesc) -> (f64, usize) {
    d.lidars = Some(vec![l]);
    let mut sim = Simulation::from_desc(
        &d,
        &SceneSource::generated(),
        RunSettings {
            solver: Solver::MonteCarlo {
                photons: 64,
                sampler: SamplerKind::Continuous,
            },
            ..Default::default()
        },
    )
    .unwrap();
    sim.run(None).unwrap();
    let r = &sim.resource::<LidarProducts>().0[0];
    (r.seconds, r.pulses.len())
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let threads = rayon::current_num_threads() as f64;
    let f = forest::forest(&forest::ForestParams {
        size_m: 40.0,
        ..Default::default()
    });
    let n = if quick { 200 } else { 2000 };
    let side = (n as f64).sqrt().ceil() as u32;
    let (secs, pulses) = run(
        f,
        lidar(
            PulsePattern::Scan {
                start: (1.0, 1.0),
                end: (39.0, 1.0),
                lines: side,
                line_spacing_m: 38.0 / side as f64,
                pulse_spacing_m: 38.0 / (side - 1) as f64,
            },
            1000,
        ),
    );
    println!(
        "ALS forest 40 m, {pulses} pulses × 1000 photons (multiple scattering): {secs:.2} s, {:.0} pulses/s/core, {:.2e} photons/s/core, peak RSS {:.0} MiB",
        pulses as f64 / secs / threads,
        pulses as f64 * 1000.0 / secs / threads,
        peak_rss_mib()
    );
    let u = urban::urban(&urban::UrbanParams::default());
    let m = if quick { 100 } else { 500 };
    let (secs, pulses) = run(
        u,
        lidar(
            PulsePattern::Scan {
                start: (0.0, 0.0),
                end: (59.9, 0.0),
                lines: m,
                line_spacing_m: 59.9 / m as f64,
                pulse_spacing_m: 59.9 / (m - 1) as f64,
            },
            100,
        ),
    );
    println!(
        "urban scan, {pulses} pulses × 100 photons: {secs:.1} s, {:.0} pulses/s/core, peak RSS {:.0} MiB",
        pulses as f64 / secs / threads,
        peak_rss_mib()
    );
}
