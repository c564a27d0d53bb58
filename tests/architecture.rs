//! Layout rule (design.md §2): only `src/simulation.rs` (and the `#[path]` declaration in
//! `lib.rs`) refer to the stage systems; everything else goes through the simulation, the
//! resources and the pure modules, so stages can be rescheduled without touching callers.
//! And the photon engine never imports the LiDAR modules (LiDAR builds on photon).

use std::path::Path;

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn only_simulation_rs_imports_the_systems() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for d in ["src", "tests", "benches"] {
        rust_files(&root.join(d), &mut files);
    }
    let mut offenders = Vec::new();
    for f in files {
        let rel = f.strip_prefix(root).unwrap().to_string_lossy().to_string();
        if rel == "src/simulation.rs" || rel == "src/lib.rs" || rel == "tests/architecture.rs" {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap();
        if text.contains("crate::systems") || text.contains("lumenscape::systems") {
            offenders.push(rel);
        }
    }
    assert!(
        offenders.is_empty(),
        "these files import the stage systems directly: {offenders:?}"
    );
}

/// The photon engine is the passive Monte Carlo engine plus the shared photon-walk primitives;
/// the LiDAR pulse tracking builds on it (`lidar::tracking`), never the reverse.
#[test]
fn photon_does_not_import_lidar() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files(&root.join("src/photon"), &mut files);
    let offenders: Vec<String> = files
        .iter()
        .filter(|f| std::fs::read_to_string(f).unwrap().contains("crate::lidar"))
        .map(|f| f.strip_prefix(root).unwrap().to_string_lossy().to_string())
        .collect();
    assert!(
        offenders.is_empty(),
        "these photon files import the LiDAR modules: {offenders:?}"
    );
}
