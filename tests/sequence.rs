//! Sequences and look-up tables (issue #36), through the built binary as a user (or a cluster
//! scheduler) runs them: the example sequence's plan, sharded runs gathered into one table
//! byte for byte, resuming after a SIGKILL, a point equal to the same scene run on its own,
//! and bad sequence files refused with the file, line and axis before anything runs.

use lumenscape::sequence::plan::{Axis, Plan, Shard};
use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lumenscape"))
}

/// `lumenscape sequence -q SEQ --out OUT`.
fn sequence(seq: &Path, out: &Path) -> Command {
    let mut c = bin();
    c.args(["sequence", "-q"]).arg(seq).arg("--out").arg(out);
    c
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lumenscape-seq-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A sequence over the turbid-layer example scene, written into `dir`: LAI × leaf reflectance
/// × zipped sun zenith and azimuth (`lai.len() · 2 · sun.len()` points), preview preset.
fn write_sequence(dir: &Path, lai: &[f64], sun: &[(f64, f64)]) -> PathBuf {
    write_sequence_with(dir, lai, sun, "Preview", "")
}

/// [`write_sequence`] with a preset and extra top-level fields (`keep: [...]`).
fn write_sequence_with(
    dir: &Path,
    lai: &[f64],
    sun: &[(f64, f64)],
    preset: &str,
    extra: &str,
) -> PathBuf {
    let base = root().join("assets/scenes/turbid_layer.ron");
    let list = |v: Vec<String>| v.join(", ");
    let text = format!(
        r#"(
    version: 1,
    name: "test sweep",
    base: "{}",
    axes: [
        (name: "lai", path: "objects[1].foliage", values: [{}]),
        (name: "leaf_r", path: "optics.leaf.reflectance[0]", values: [0.05, 0.08]),
        (name: "sza", path: "illumination.sun_zenith_deg", values: [{}], zip: "sun"),
        (name: "saa", path: "illumination.sun_azimuth_deg", values: [{}], zip: "sun"),
        (name: "preset", path: "radiative", values: [(preset: "{preset}")]),
    ],
    {extra}
)
"#,
        base.display(),
        list(lai.iter().map(|v| format!("{v:?}")).collect()),
        list(sun.iter().map(|s| format!("{:?}", s.0)).collect()),
        list(sun.iter().map(|s| format!("{:?}", s.1)).collect()),
    );
    let p = dir.join("seq.ron");
    std::fs::write(&p, text).unwrap();
    p
}

fn run_ok(cmd: &mut Command) -> String {
    let o = cmd.output().unwrap();
    assert!(
        o.status.success(),
        "{:?} failed: {}{}",
        cmd,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn the_example_sequence_spans_its_grid_and_sets_each_field() {
    let plan = Plan::load(&root().join("assets/sequences/lai_cab_sun.ron")).unwrap();
    assert_eq!(plan.len(), 6 * 8 * 4);
    // Row-major, the last axis fastest: point 1 changes the sun, point 4 the chlorophyll.
    let p = plan.point(4 + 1).unwrap();
    let v: Vec<String> = p.values.iter().map(|(n, v)| format!("{n}={v}")).collect();
    assert_eq!(v, ["lai=0.5", "cab_ug_cm2=20.0", "sun_zenith_deg=20.0"]);
    let text = lumenscape::scene::to_ron(&p.desc);
    assert!(text.contains("foliage: Lai(0.5)"), "{text}");
    assert!(text.contains("cab_ug_cm2: 20.0"), "{text}");
    assert!(text.contains("sun_zenith_deg: Some(20.0)"), "{text}");
    // The range's last value is exact, and every other field is the base scene's.
    let last = plan.point(plan.len() - 1).unwrap();
    assert_eq!(last.values[1].1, serde_json::json!(80.0));
    let mut base = plan.base.clone();
    base.illumination.sun_zenith_deg = Some(60.0);
    assert_ne!(base, last.desc);
}

/// Sharded runs (1, 3 and 7 separate processes) gather into the same table, byte for byte,
/// and every point's values are in it.
#[test]
fn sharded_runs_gather_into_the_same_table() {
    let dir = tmp("shards");
    let seq = write_sequence(&dir, &[1.0, 3.0], &[(0.0, 0.0), (40.0, 90.0)]);
    let mut tables = Vec::new();
    let mut parquets = Vec::new();
    for n in [1usize, 3, 7] {
        let out = dir.join(format!("out{n}"));
        for k in 0..n {
            run_ok(sequence(&seq, &out).args(["--shard", &format!("{k}/{n}")]));
        }
        let msg = run_ok(bin().arg("gather").arg(&out));
        assert!(msg.contains("from 8 of 8 points"), "{msg}");
        tables.push(std::fs::read(out.join("lut.csv")).unwrap());
        parquets.push(std::fs::read(out.join("lut.parquet")).unwrap());
    }
    assert_eq!(tables[0], tables[1]);
    assert_eq!(tables[0], tables[2]);
    assert_eq!(parquets[0], parquets[1]);
    assert_eq!(parquets[0], parquets[2]);
    parquet_equals_csv(&dir.join("out1/lut.parquet"), &dir.join("out1/lut.csv"));
    let text = String::from_utf8(tables[0].clone()).unwrap();
    let header = text.lines().next().unwrap();
    assert!(
        header.starts_with("point,lai,leaf_r,sza,saa,preset,band,albedo"),
        "{header}"
    );
    // 8 points × 1 band × (100 regular + 21 exact upward directions... whatever the set has):
    // every point has the same number of rows.
    let per_point: Vec<usize> = (0..8)
        .map(|i| {
            text.lines()
                .filter(|l| l.starts_with(&format!("{i},")))
                .count()
        })
        .collect();
    assert!(
        per_point.iter().all(|&c| c == per_point[0] && c > 20),
        "{per_point:?}"
    );
    // A gather of a partial folder reports what is missing.
    let part = dir.join("part");
    run_ok(sequence(&seq, &part).args(["--shard", "1/3"]));
    let msg = run_ok(bin().arg("gather").arg(&part));
    // Points that differ only in the leaf reflectance share a run (units {0, 2}, {1, 3},
    // {4, 6}, {5, 7}); shards take whole units (unit u to shard u mod N): shard 1 of 3 has {1, 3}.
    assert!(
        msg.contains("from 2 of 8 points")
            && msg.contains("missing (not finished): 6 points: 0, 2, 4, 5, 6, 7"),
        "{msg}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The Parquet table read back with the `parquet` crate's record reader holds the CSV's rows:
/// the same column names, numbers equal to the CSV's text (shortest round trip), strings equal.
fn parquet_equals_csv(pq: &Path, csv: &Path) {
    use parquet::file::reader::{FileReader, SerializedFileReader};
    use parquet::record::Field;
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let reader = SerializedFileReader::new(std::fs::File::open(pq).unwrap()).unwrap();
    let mut n = 0;
    for (row, line) in reader.get_row_iter(None).unwrap().zip(lines) {
        let row = row.unwrap();
        let cells: Vec<&str> = line.split(',').collect();
        let fields: Vec<(&String, &Field)> = row.get_column_iter().collect();
        assert_eq!(fields.len(), header.len());
        for ((name, f), (h, c)) in fields.iter().zip(header.iter().zip(&cells)) {
            assert_eq!(name.as_str(), *h);
            match f {
                Field::Long(v) => assert_eq!(v.to_string(), *c),
                Field::Double(v) => assert_eq!(*v, c.parse::<f64>().unwrap(), "{h}"),
                Field::Str(v) => {
                    // CSV quotes a cell holding `"` (the values are free of commas here).
                    let unq = match c.strip_prefix('"').and_then(|c| c.strip_suffix('"')) {
                        Some(q) => q.replace("\"\"", "\""),
                        None => c.to_string(),
                    };
                    assert_eq!(*v, unq, "{h}")
                }
                Field::Null => assert!(c.is_empty(), "{h}: null for `{c}`"),
                other => panic!("{h}: unexpected {other:?}"),
            }
        }
        n += 1;
    }
    assert_eq!(n, text.lines().count() - 1);
}

/// The products of point 1 of `out` and of its scene run on its own with `lumenscape run`
/// (the `bands` record of each summary.json).
fn point_and_alone(dir: &Path, seq: &Path, out: &Path) -> (serde_json::Value, serde_json::Value) {
    let plan = Plan::load(seq).unwrap();
    let p = plan.point(1).unwrap();
    let scene = dir.join("point1.ron");
    std::fs::write(&scene, lumenscape::scene::to_ron(&p.desc)).unwrap();
    let alone = dir.join("alone");
    let _ = std::fs::remove_dir_all(&alone);
    run_ok(
        bin()
            .args(["run", "-q"])
            .arg(&scene)
            .arg("--out")
            .arg(&alone),
    );
    let bands = |f: &Path| -> serde_json::Value {
        serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(f).unwrap()).unwrap()
            ["bands"]
            .clone()
    };
    (
        bands(&out.join("points/p000001/summary.json")),
        bands(&alone.join("summary.json")),
    )
}

/// A point that runs on its own (here: it keeps its images, so it shares no run) gives the
/// products of its scene run with `lumenscape run`, bit for bit (same code, same settings).
#[test]
fn a_point_run_alone_equals_its_scene_run_bit_for_bit() {
    let dir = tmp("alone");
    let keep = "keep: [\"images\", \"brf.csv\"],";
    let seq = write_sequence_with(&dir, &[3.0], &[(40.0, 90.0)], "Preview", keep);
    let out = dir.join("out");
    run_ok(&mut sequence(&seq, &out));
    let (a, b) = point_and_alone(&dir, &seq, &out);
    assert_eq!(a, b);
    assert_eq!(
        std::fs::read(out.join("points/p000001/brf.csv")).unwrap(),
        std::fs::read(dir.join("alone/brf.csv")).unwrap()
    );
    let mut names: Vec<String> = std::fs::read_dir(out.join("points/p000001"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["brf.csv", "images", "point.json", "summary.json"]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Points that differ only in per-band values (here the leaf reflectance) run as the bands
/// of one run. The tracker's stops (a ray's power summed over the channels against the ray
/// threshold, convergence of the albedo summed over the channels) then fall differently than
/// in a one-point run, so the products agree within the preset's albedo threshold (1e-3
/// relative for the default preset; measured on the LAI × Cab × sun example: ≤ 2.1e-3 on
/// ftran, ≤ 1.6e-3 on the BRFs, ≤ 4e-4 on the albedo), asserted here within 3× that
/// threshold on every band scalar and BRF.
#[test]
fn points_sharing_a_run_agree_with_their_standalone_runs() {
    let dir = tmp("shared");
    let seq = write_sequence_with(&dir, &[3.0], &[(40.0, 90.0)], "Default", "");
    let out = dir.join("out");
    let msg = run_ok(&mut sequence(&seq, &out));
    assert!(msg.contains("2 points run"), "{msg}");
    let point: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("points/p000001/point.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(point["shared_run_points"], serde_json::json!([0, 1]));
    let (a, b) = point_and_alone(&dir, &seq, &out);
    let (a, b) = (&a[0], &b[0]);
    let tol = 3e-3;
    let mut worst: f64 = 0.0;
    for k in ["albedo", "fabs", "fabs_ground", "ftran"] {
        let (x, y) = (a[k].as_f64().unwrap(), b[k].as_f64().unwrap());
        worst = worst.max((x - y).abs() / y.abs());
    }
    let (ba, bb) = (a["brf"].as_array().unwrap(), b["brf"].as_array().unwrap());
    assert_eq!(ba.len(), bb.len());
    for (x, y) in ba.iter().zip(bb) {
        assert_eq!(x["zenith_deg"], y["zenith_deg"]);
        let (x, y) = (x["brf"].as_f64().unwrap(), y["brf"].as_f64().unwrap());
        worst = worst.max((x - y).abs() / y.abs());
    }
    eprintln!("shared run vs standalone: worst relative difference {worst:.3e}");
    assert!(
        worst <= tol,
        "worst relative difference {worst:.2e} > {tol:.0e}"
    );
    // Not the same bits (else the sharing would be untested here).
    assert_ne!(a, b);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A sweep killed (SIGKILL) mid-way resumes: the points done before the kill are skipped, no
/// partial folder is taken as done, none is run twice, and the table equals an uninterrupted
/// run's.
#[test]
fn a_killed_sweep_resumes_without_losing_or_repeating_points() {
    let dir = tmp("kill");
    let lai: Vec<f64> = (1..=6).map(|i| i as f64).collect();
    let seq = write_sequence(&dir, &lai, &[(0.0, 0.0), (20.0, 30.0), (40.0, 90.0)]);
    let n = 6 * 2 * 3;
    let out = dir.join("out");
    let mut child = sequence(&seq, &out).spawn().unwrap();
    let done = |o: &Path| {
        (0..n)
            .filter(|&i| o.join(format!("points/p{i:06}/point.json")).exists())
            .count()
    };
    let t0 = std::time::Instant::now();
    while done(&out) < 3 && t0.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap(); // SIGKILL on Unix
    child.wait().unwrap();
    let before = done(&out);
    assert!(
        (3..n).contains(&before),
        "the sweep should have been killed mid-way ({before} of {n} points done)"
    );
    // Every visible point folder is complete.
    for e in std::fs::read_dir(out.join("points")).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        if !name.starts_with('.') {
            assert!(e.path().join("point.json").exists(), "{name} is incomplete");
            assert!(
                e.path().join("summary.json").exists(),
                "{name} is incomplete"
            );
        }
    }
    let msg = run_ok(&mut sequence(&seq, &out));
    let expect = format!("{} points run, {before} already done, 0 failed", n - before);
    assert!(msg.contains(&expect), "{msg} (expected `{expect}`)");
    // No staging leftovers, and the same table as an uninterrupted sweep.
    let hidden: Vec<_> = std::fs::read_dir(out.join("points"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with('.')
        })
        .collect();
    assert!(hidden.is_empty(), "{hidden:?}");
    let clean = dir.join("clean");
    run_ok(&mut sequence(&seq, &clean));
    run_ok(bin().arg("gather").arg(&out));
    run_ok(bin().arg("gather").arg(&clean));
    assert_eq!(
        std::fs::read(out.join("lut.csv")).unwrap(),
        std::fs::read(clean.join("lut.csv")).unwrap()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Bad sequence files: each refused before anything runs, with the sequence file and the line
/// (or the point) in the message, a non-zero exit that is not a panic, and no output folder.
#[test]
fn bad_sequence_files_are_refused_with_the_place() {
    let dir = tmp("bad");
    let base = root().join("assets/scenes/turbid_layer.ron");
    let good = format!(
        "(\n    version: 1,\n    base: \"{}\",\n    axes: [\n        (name: \"lai\", path: \"objects[1].foliage\", values: [1.0, 2.0]),\n    ],\n)\n",
        base.display()
    );
    let cases: &[(&str, &str, &str, &str)] = &[
        // (what, replace, with, needle in the message)
        (
            "unknown path",
            "objects[1].foliage",
            "objects[1].folage",
            "seq.ron:5:",
        ),
        (
            "unknown top field",
            "objects[1].foliage",
            "optic.leaf",
            "no field `optic`",
        ),
        (
            "index out of range",
            "objects[1].foliage",
            "objects[9].foliage",
            "index 9 is out of range",
        ),
        (
            "type mismatch",
            "values: [1.0, 2.0]",
            "values: [\"dense\"]",
            "holds a number",
        ),
        (
            "empty axis",
            "values: [1.0, 2.0]",
            "values: []",
            "has no values",
        ),
        (
            "values and range",
            "values: [1.0, 2.0]",
            "values: [1.0], range: (from: 1.0, to: 2.0, steps: 2)",
            "exactly one of",
        ),
        (
            "1e9 points",
            "values: [1.0, 2.0]",
            "range: (from: 1.0, to: 2.0, steps: 1000000000)",
            "seq.ron:5:",
        ),
        (
            "huge grid",
            "values: [1.0, 2.0]),",
            "range: (from: 1.0, to: 2.0, steps: 1000)), (name: \"r\", path: \"optics.leaf.reflectance[0]\", range: (from: 0.01, to: 0.1, steps: 1001)),",
            "1001000 points",
        ),
        (
            "invalid point",
            "values: [1.0, 2.0]",
            "values: [1.0, -2.0]",
            "point 1 (lai = -2.0)",
        ),
        (
            "unknown scene field",
            "objects[1].foliage",
            "illumination.sun_zenit_deg",
            "unknown field `sun_zenit_deg`",
        ),
        (
            "zip lengths",
            "values: [1.0, 2.0]),",
            "values: [1.0, 2.0], zip: \"a\"), (name: \"r\", path: \"optics.leaf.reflectance[0]\", values: [0.1], zip: \"a\"),",
            "zip group",
        ),
        (
            "duplicate names",
            "values: [1.0, 2.0]),",
            "values: [1.0, 2.0]), (name: \"lai\", path: \"optics.leaf.reflectance[0]\", values: [0.1]),",
            "two axes are named `lai`",
        ),
        ("version", "version: 1", "version: 7", "seq.ron:2:"),
        (
            "missing base",
            "turbid_layer.ron",
            "no_such_scene.ron",
            "no_such_scene.ron",
        ),
        ("unknown sequence field", "axes:", "axis:", "seq.ron:4:"),
        ("bad keep", "axes:", "keep: [\"../x\"], axes:", "keep[0]"),
    ];
    for (what, from, to, needle) in cases {
        assert!(
            good.contains(from),
            "{what}: `{from}` not in the base sequence"
        );
        let text = good.replacen(from, to, 1);
        let seq = dir.join("seq.ron");
        std::fs::write(&seq, &text).unwrap();
        let out = dir.join("out");
        let o = sequence(&seq, &out).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        let code = o.status.code().unwrap_or(-1);
        assert!(code != 0 && code != 101, "{what}: exit {code}: {err}");
        assert!(!err.contains("panicked"), "{what}: {err}");
        assert!(err.contains(needle), "{what}: `{needle}` not in: {err}");
        assert!(!out.exists(), "{what}: an output folder was written");
    }
    // And from code: a path that does not exist is an error naming the axis.
    let (desc, src) = lumenscape::scene::load_scene(&base).unwrap();
    let e = Plan::new(desc, src)
        .unwrap()
        .axis(Axis::new("x", "grid.nope.deeper", &[1.0]).unwrap())
        .check()
        .unwrap_err();
    assert!(e.to_string().contains("no field `nope`"), "{e}");
    assert_eq!(Shard::parse("0/1"), Ok(Shard::ALL));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A folder holding another sweep's points is refused (its plan differs).
#[test]
fn another_sweeps_folder_is_refused() {
    let dir = tmp("other");
    let seq = write_sequence(&dir, &[1.0], &[(0.0, 0.0)]);
    let out = dir.join("out");
    run_ok(&mut sequence(&seq, &out));
    let seq2 = write_sequence(&dir, &[2.0], &[(0.0, 0.0)]);
    let o = sequence(&seq2, &out).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("another sequence"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Monte Carlo sweeps run each point on its own (seeded: bit for bit its standalone run), and
/// LiDAR-only scenes keep their LiDAR products; `gather` says they have no passive rows.
#[test]
fn monte_carlo_and_lidar_points_run_alone() {
    let dir = tmp("mc-lidar");
    let seq = write_sequence(&dir, &[3.0], &[(40.0, 90.0)]);
    let out = dir.join("mc");
    let mc = ["--solver", "monte-carlo", "--photons", "20000"];
    run_ok(sequence(&seq, &out).args(mc));
    let plan = Plan::load(&seq).unwrap();
    let scene = dir.join("point1.ron");
    std::fs::write(
        &scene,
        lumenscape::scene::to_ron(&plan.point(1).unwrap().desc),
    )
    .unwrap();
    let alone = dir.join("alone");
    run_ok(
        bin()
            .args(["run", "-q"])
            .arg(&scene)
            .arg("--out")
            .arg(&alone)
            .args(mc),
    );
    let bands = |f: &Path| -> serde_json::Value {
        serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(f).unwrap()).unwrap()
            ["bands"]
            .clone()
    };
    assert_eq!(
        bands(&out.join("points/p000001/summary.json")),
        bands(&alone.join("summary.json"))
    );
    let point: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("points/p000001/point.json")).unwrap(),
    )
    .unwrap();
    assert!(point["shared_run_points"].is_null());
    // A LiDAR-only base scene.
    let lidar = dir.join("lidar.ron");
    std::fs::write(
        &lidar,
        format!(
            "(version: 1, base: \"{}\", axes: [(name: \"r\", path: \"optics.leaf.reflectance[0]\", values: [0.3, 0.4])])",
            root().join("assets/scenes/lidar_als.ron").display()
        ),
    )
    .unwrap();
    let lo = dir.join("lidar-out");
    run_ok(&mut sequence(&lidar, &lo));
    for i in 0..2 {
        assert!(
            lo.join(format!("points/p{i:06}/lidar/als/returns.las"))
                .exists()
        );
    }
    let msg = run_ok(bin().arg("gather").arg(&lo));
    assert!(
        msg.contains("0 rows from 2 of 2 points")
            && msg.contains("2 finished points have no passive products"),
        "{msg}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The example sequence on a small grid (its first two values per axis), from code: 8 points
/// in 2 shared runs, every point's table rows present, energy closed in every point and band.
#[test]
fn the_example_sequence_runs_on_a_small_grid() {
    let dir = tmp("example");
    let mut plan = Plan::load(&root().join("assets/sequences/lai_cab_sun.ron")).unwrap();
    for a in &mut plan.axes {
        a.values.truncate(2);
    }
    plan.check().unwrap();
    assert_eq!(plan.len(), 8);
    let settings = lumenscape::resources::scene::RunSettings {
        preset: Some(lumenscape::scene::desc::Preset::Preview),
        progress: false,
        ..Default::default()
    };
    assert_eq!(plan.units(plan.merges(&settings)).unwrap().len(), 4);
    let out = dir.join("out");
    let rep = plan.run(&out, Shard::ALL, &settings).unwrap();
    assert_eq!(
        (rep.ran.len(), rep.failed.len()),
        (8, 0),
        "{:?}",
        rep.failed
    );
    let g = lumenscape::sequence::lut::gather(&out, &out.join("lut.csv")).unwrap();
    assert_eq!((g.finished, g.missing.len()), (8, 0));
    for i in 0..8 {
        let s: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join(format!("points/p{i:06}/summary.json"))).unwrap(),
        )
        .unwrap();
        let bands = s["bands"].as_array().unwrap();
        assert_eq!(bands.len(), 2);
        for b in bands {
            // Energy closes: absorbed (canopy + soil) + escaped + lost = input, per band.
            let closure = b["energy_closure"].as_f64().unwrap();
            assert!(
                closure.abs() < 1e-9,
                "point {i} band {}: {closure}",
                b["band"]
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
