//! Direction and Phase stages: direction generation and phase tabulation for N = 100, 400, 1000
//! directions (spherical and planophile leaves, an aerosol fluid, an RPV ground). Prints the
//! table memory.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use lumenscape::direction::{DirectionParams, DirectionSet, ExactDirection};
use lumenscape::phase::{TableParams, brdf_facet_table, bytes, fluid_table, vegetation_table};
use lumenscape::physics::brdf::Brdf;
use lumenscape::physics::lad::{Lad, LeafOptics};
use lumenscape::physics::phase::FluidPhase;
use std::hint::black_box;

fn params(n: usize) -> DirectionParams {
    DirectionParams {
        count: n,
        exact: vec![
            ExactDirection::new(30.0, 225.0),
            ExactDirection::new(0.0, 0.0),
        ],
        ..DirectionParams::default()
    }
}

fn bench(c: &mut Criterion) {
    let sun = Some(-glam::DVec3::new(0.5f64.sqrt() * 0.5, 0.5f64.sqrt() * 0.5, 0.866).normalize());
    let tp = TableParams::dart_default();
    let mut g = c.benchmark_group("direction_phase");
    g.sample_size(10);
    for n in [100usize, 400, 1000] {
        let p = params(n);
        g.bench_function(format!("directions/{n}"), |b| {
            b.iter(|| DirectionSet::new(black_box(&p)).unwrap())
        });
        let set = DirectionSet::new(&p).unwrap();
        let (rows, cols) = (set.n_regular() + 1, set.len());
        println!(
            "N={n}: {} directions, one table {rows}x{cols} = {:.2} MB per band (f32 + 3 f64/row); 10 bands: {:.1} MB",
            set.len(),
            bytes(rows, cols, 1) as f64 / 1e6,
            bytes(rows, cols, 10) as f64 / 1e6
        );
        let sph = Lad::Spherical.resolve().unwrap();
        let pla = Lad::Planophile.resolve().unwrap();
        let optics = LeafOptics::lambertian(0.45, 0.4);
        g.bench_function(format!("vegetation_spherical/{n}"), |b| {
            b.iter(|| vegetation_table(&set, &sph, &optics, sun, &tp).unwrap())
        });
        g.bench_function(format!("vegetation_planophile/{n}"), |b| {
            b.iter(|| vegetation_table(&set, &pla, &optics, sun, &tp).unwrap())
        });
        let aer = FluidPhase::dart_aerosol_default();
        g.bench_function(format!("fluid_tthg/{n}"), |b| {
            b.iter(|| fluid_table(&set, &aer, 0.947, sun, &tp).unwrap())
        });
        let rpv = Brdf::Rpv {
            rho0: 0.25,
            k: 0.6,
            theta: -0.2,
            rho_c: Some(0.5),
        };
        g.bench_function(format!("rpv_ground/{n}"), |b| {
            b.iter(|| brdf_facet_table(&set, &rpv, DVec3::Z, sun, &tp).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
