//! Maket benchmark (harness = false): a 1 km × 1 km stand of 10,000 trees (two species) on 1 m
//! cells, built by the seeded `forest` generator. Prints wall time per phase, cells, leaf-area
//! conservation error and memory (estimate, held, and the process's peak resident set).
//!
//! `cargo bench --bench maket` (add `-- --small` for a 200 m, 400-tree run).

use lumenscape::resources::grid::CellGrid;
use lumenscape::resources::maket_report::MaketReport;
use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::SceneSource;
use lumenscape::scene::generators::forest::{ForestParams, broadleaf, conifer, forest};
use lumenscape::simulation::{Simulation, Stage};
use std::time::Instant;

mod common;
use common::peak_rss_mib;

fn main() {
    let small = std::env::args().any(|a| a == "--small");
    let (size, n) = if small { (200.0, 200) } else { (1000.0, 5000) };
    let params = ForestParams {
        size_m: size,
        cell_m: 1.0,
        species: vec![broadleaf(n), conifer(n)],
        min_spacing_m: 4.0,
        seed: 11,
        ..Default::default()
    };
    let desc = forest(&params);
    let t0 = Instant::now();
    let mut sim = Simulation::from_desc(&desc, &SceneSource::generated(), RunSettings::default())
        .expect("scene");
    let t_spawn = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    sim.run_stage(Stage::Maket).expect("maket");
    let t_maket = t1.elapsed().as_secs_f64();
    let r = sim.resource::<MaketReport>().clone();
    let g = sim.resource::<CellGrid>();
    let mut worst = 0.0f64;
    for la in r.leaf_area.values() {
        worst =
            worst.max((la.rasterised_m2.unwrap_or(0.0) - la.analytic_m2).abs() / la.analytic_m2);
    }
    println!(
        "maket bench: {size} m x {size} m, {} trees, cells {:?} ({} cells), threads {}",
        2 * n,
        r.cells,
        r.n_cells,
        rayon::current_num_threads()
    );
    println!("  spawn (placement)        {t_spawn:8.3} s");
    println!("  maket stage              {t_maket:8.3} s");
    println!("  turbid entries           {:>10}", g.turbid.len());
    println!(
        "  cells with vegetation    {:>10}",
        r.turbid_cells.unwrap_or(0)
    );
    println!(
        "  facets                   {:>10}",
        r.facet_count.values().sum::<u64>()
    );
    println!("  worst leaf-area error    {worst:10.2e} (relative)");
    println!(
        "  memory estimate (peak)   {:8.1} MiB",
        r.memory.peak_bytes as f64 / 1048576.0
    );
    println!(
        "  memory held after Maket  {:8.1} MiB",
        r.memory_used_bytes.unwrap_or(0) as f64 / 1048576.0
    );
    println!("  process peak RSS         {:8.1} MiB", peak_rss_mib());
}
