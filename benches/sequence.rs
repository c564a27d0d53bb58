//! Sequence benchmark (harness = false, issue #36): a 1 000-point look-up table on the turbid
//! layer of `assets/sequences/prospect_layer.ron` — 10 chlorophyll contents (PROSPECT-D, an
//! optics-only axis) × 10 LAI × 10 sun zeniths, default preset — run three ways:
//!
//! 1. `lumenscape sequence` in-process with shared runs (points that differ only in per-band
//!    values run as the bands of one run);
//! 2. the same with `share: false` (each point its own run, bit for bit its standalone run);
//! 3. a sample of points as separate `lumenscape run` processes (what a shell loop does),
//!    products written as by default.
//!
//! Prints wall time per point and the speed-up against (3), and the worst relative difference
//! of every albedo, fabs, ftran and BRF of (1) against (2) (the error that sharing costs).
//!
//! `cargo bench --bench sequence` (add `-- --points 120` for a 4 × 5 × 6 run; `--processes N`
//! sets the sample of separate processes, default 40).

use lumenscape::resources::scene::RunSettings;
use lumenscape::sequence::lut::gather;
use lumenscape::sequence::plan::{Axis, Plan, Shard};
use std::path::{Path, PathBuf};
use std::time::Instant;

mod common;

fn arg(name: &str, default: usize) -> usize {
    let a: Vec<String> = std::env::args().collect();
    a.iter()
        .position(|x| x == name)
        .and_then(|i| a.get(i + 1)?.parse().ok())
        .unwrap_or(default)
}

fn plan(base: &Path, n: (usize, usize, usize), share: bool) -> Plan {
    let (desc, src) = lumenscape::scene::load_scene(base).expect("base scene");
    let lin = |a: f64, b: f64, k: usize| -> Vec<f64> {
        (0..k)
            .map(|i| a + (b - a) * i as f64 / (k.max(2) - 1) as f64)
            .collect()
    };
    let mut p = Plan::new(desc, src)
        .expect("plan")
        .axis(Axis::new("lai", "objects[1].foliage", &lin(0.5, 6.0, n.0)).unwrap())
        .axis(Axis::new("sza", "illumination.sun_zenith_deg", &lin(0.0, 60.0, n.1)).unwrap())
        .axis(Axis::new("cab", "optics.leaf.cab_ug_cm2", &lin(10.0, 80.0, n.2)).unwrap());
    p.share = share;
    p.check().expect("valid plan");
    p
}

fn table(path: &Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let base = root.join("assets/sequences/prospect_layer.ron");
    let n = match arg("--points", 1000) {
        120 => (4, 5, 6),
        _ => (10, 10, 10),
    };
    let total = n.0 * n.1 * n.2;
    let work = std::env::temp_dir().join(format!("lumenscape-bench-seq-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&work);
    let settings = RunSettings::default();
    let mut rows = Vec::new();
    let mut tables = Vec::new();
    for share in [true, false] {
        let p = plan(&base, n, share);
        let out = work.join(if share { "shared" } else { "alone" });
        let t0 = Instant::now();
        let rep = p.run(&out, Shard::ALL, &settings).expect("run");
        let wall = t0.elapsed().as_secs_f64();
        assert!(rep.failed.is_empty(), "{:?}", rep.failed);
        gather(&out, &out.join("lut.csv")).expect("gather");
        tables.push(table(&out.join("lut.csv")));
        let units = p.units(p.merges(&settings)).unwrap().len();
        rows.push((
            if share {
                "sequence, shared runs"
            } else {
                "sequence, share: false"
            },
            total,
            units,
            wall,
        ));
    }
    // Separate processes on a sample of the points' scenes.
    let sample = arg("--processes", 40).min(total);
    let p = plan(&base, n, false);
    let exe = root.join("target/release/lumenscape");
    let mut proc_wall = f64::NAN;
    if exe.exists() {
        let dir = work.join("processes");
        std::fs::create_dir_all(&dir).unwrap();
        let scenes: Vec<PathBuf> = (0..sample)
            .map(|k| {
                let i = k * total / sample;
                // Next to the base scene's folder is not needed: the example has no file paths.
                let f = dir.join(format!("p{i}.ron"));
                std::fs::write(&f, lumenscape::scene::to_ron(&p.point(i).unwrap().desc)).unwrap();
                f
            })
            .collect();
        let t0 = Instant::now();
        for (k, s) in scenes.iter().enumerate() {
            let st = std::process::Command::new(&exe)
                .args(["run", "-q"])
                .arg(s)
                .arg("--out")
                .arg(dir.join(format!("out{k}")))
                .stdout(std::process::Stdio::null())
                .status()
                .unwrap();
            assert!(st.success());
        }
        proc_wall = t0.elapsed().as_secs_f64();
        rows.push((
            "separate `lumenscape run` processes",
            sample,
            sample,
            proc_wall,
        ));
    } else {
        eprintln!(
            "(no target/release/lumenscape: run `cargo build --release` for the process row)"
        );
    }
    let per_proc = proc_wall / sample as f64;
    println!("| mode | points | runs | wall s | ms per point | speed-up vs processes |");
    println!("|---|---|---|---|---|---|");
    for (mode, pts, runs, wall) in &rows {
        let per = wall / *pts as f64;
        println!(
            "| {mode} | {pts} | {runs} | {wall:.2} | {:.2} | {:.1} |",
            per * 1e3,
            per_proc / per
        );
    }
    // The error sharing costs: (1) against (2), every numeric product column.
    let (a, b) = (&tables[0], &tables[1]);
    assert_eq!(a.len(), b.len());
    let head = &a[0];
    let mut worst: Vec<(String, f64)> = Vec::new();
    for name in ["albedo", "fabs", "fabs_ground", "ftran", "view_brf"] {
        let c = head.iter().position(|h| h == name).expect("column");
        let w = a[1..]
            .iter()
            .zip(&b[1..])
            .map(|(x, y)| {
                let (x, y): (f64, f64) = (x[c].parse().unwrap(), y[c].parse().unwrap());
                if y == 0.0 {
                    0.0
                } else {
                    (x - y).abs() / y.abs()
                }
            })
            .fold(0.0, f64::max);
        worst.push((name.to_string(), w));
    }
    let w: Vec<String> = worst.iter().map(|(n, w)| format!("{n} {w:.2e}")).collect();
    println!(
        "shared vs share: false, worst relative difference: {}",
        w.join(", ")
    );
    println!("peak RSS {:.0} MiB", common::peak_rss_mib());
    let _ = std::fs::remove_dir_all(&work);
}
