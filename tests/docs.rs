//! The documentation against the code (fast: one tiny scene, no heavy runs).
//!
//! (a) every field and variant of the scene-format types (parsed from the source text) appears
//! in `docs/guide/scene-format.md` under its type's heading; (b) every key of a real
//! `summary.json` (flux tracking and Monte Carlo), every `brf.csv` and `budget/*.csv` column and
//! every image file of a run are named in `docs/guide/products.md`; (c) every `physics.md §N.M`
//! cited in `src/`, `systems/` and `tests/` is a heading of `docs/physics.md`; (d) the README is
//! short and free of session history.

mod common;
use common::asset;
use lumenscape::direction::{DirectionParams, ExactDirection};
use lumenscape::resources::scene::{RunSettings, Solver};
use lumenscape::scene::SceneSource;
use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
use lumenscape::simulation::Simulation;
use std::collections::BTreeSet;
use std::path::Path;

fn read(rel: &str) -> String {
    std::fs::read_to_string(asset(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

// ---------------------------------------------------------------------------------------------
// (a) scene format
// ---------------------------------------------------------------------------------------------

/// Serde names of the fields and variants of every `Deserialize` struct or enum in `src`:
/// `(type, [names])`. Struct fields are `pub name: …` lines at one indentation step, enum
/// variants `Name…` lines at one step and variant fields `name: …` lines at two; a
/// `#[serde(rename = "x")]` just above a field or variant replaces its name.
fn serde_items(src: &str) -> Vec<(String, Vec<String>)> {
    let lines: Vec<&str> = src.lines().collect();
    let mut out = Vec::new();
    let mut attrs: Vec<&str> = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let l = lines[i];
        if l.starts_with("#[") {
            attrs.push(l);
        } else if let Some(rest) = l
            .strip_prefix("pub struct ")
            .or_else(|| l.strip_prefix("pub enum "))
        {
            let is_enum = l.starts_with("pub enum");
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let de = attrs.iter().any(|a| a.contains("Deserialize"));
            attrs.clear();
            if !de || !l.trim_end().ends_with('{') {
                i += 1;
                continue;
            }
            let mut names = Vec::new();
            let mut rename: Option<String> = None;
            i += 1;
            while i < lines.len() && !lines[i].starts_with('}') {
                let t = lines[i];
                let ts = t.trim_start();
                let indent = t.len() - ts.len();
                if ts.starts_with("#[serde(") && ts.contains("rename =") {
                    let r = ts.split("rename =").nth(1).unwrap();
                    rename = r.split('"').nth(1).map(String::from);
                } else if ts.starts_with("///") || ts.starts_with("#[") || ts.is_empty() {
                } else {
                    let ident: String = ts
                        .trim_start_matches("pub ")
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    let after = &ts.trim_start_matches("pub ")[ident.len()..];
                    let is_field = after.starts_with(':');
                    let take = if is_enum {
                        (indent == 4 && ident.starts_with(char::is_uppercase))
                            || (indent == 8 && is_field)
                    } else {
                        indent == 4 && ts.starts_with("pub ") && is_field
                    };
                    if take && !ident.is_empty() {
                        names.push(rename.take().unwrap_or(ident));
                    }
                    rename = None;
                }
                i += 1;
            }
            out.push((name, names));
        } else if !l.starts_with("///") {
            attrs.clear();
        }
        i += 1;
    }
    out
}

/// The text of `doc` under the heading `### name…` up to the next `### `.
fn section<'a>(doc: &'a str, name: &str) -> Option<&'a str> {
    let start = doc
        .find(&format!("\n### {name}\n"))
        .or_else(|| doc.find(&format!("\n### {name} (")))?;
    let body = &doc[start + 5..];
    Some(body.find("\n### ").map_or(body, |e| &body[..e]))
}

#[test]
fn every_scene_format_field_is_in_the_reference() {
    let doc = read("docs/guide/scene-format.md");
    // The scene-format types: all of desc.rs and desc/{lidar, atmosphere, sensor, thermal}.rs
    // plus the types they take from other modules.
    let sources: [(&str, &[&str]); 10] = [
        ("src/scene/desc.rs", &[]),
        ("src/scene/desc/lidar.rs", &[]),
        ("src/scene/desc/atmosphere.rs", &[]),
        ("src/physics/phase.rs", &["FluidPhase"]),
        ("src/scene/desc/sensor.rs", &[]),
        ("src/scene/desc/thermal.rs", &[]),
        ("src/geometry/crown.rs", &["CrownShape"]),
        ("src/physics/lad.rs", &["Lad", "LeafSpecular"]),
        ("src/physics/prospect.rs", &["ProspectModel"]),
        (
            "src/direction/mod.rs",
            &["DirectionParams", "ExactDirection", "OversampleRegion"],
        ),
    ];
    let mut missing = Vec::new();
    let mut checked = 0;
    for (file, only) in sources {
        let items = serde_items(&read(file));
        assert!(!items.is_empty(), "{file}: no serde types parsed");
        for (ty, names) in items {
            if !only.is_empty() && !only.contains(&ty.as_str()) {
                continue;
            }
            let Some(sec) = section(&doc, &ty) else {
                missing.push(format!("{file}: type `{ty}` has no `### {ty}` section"));
                continue;
            };
            for n in names {
                checked += 1;
                if !sec.contains(&format!("`{n}`")) {
                    missing.push(format!("{file}: `{ty}::{n}` is not documented"));
                }
            }
        }
    }
    assert!(
        checked > 150,
        "only {checked} fields parsed: the parser broke"
    );
    assert!(
        missing.is_empty(),
        "docs/guide/scene-format.md is out of date (re-run `python3 docs/tools/scene_format.py > \
         docs/guide/scene-format.md`):\n{}",
        missing.join("\n")
    );
}

#[test]
fn the_field_parser_sees_renames_and_variant_fields() {
    let src = "#[derive(Deserialize)]\npub struct A {\n    /// x\n    pub x_m: f64,\n    \
               #[serde(rename = \"why\")]\n    pub y: u32,\n    fn_not: u8,\n}\n\
               #[derive(Serialize, Deserialize)]\npub enum E {\n    Plain,\n    \
               Tuple(f64),\n    Named {\n        inner_deg: f64,\n    },\n}\n\
               #[derive(Debug)]\npub struct NotSerde {\n    pub z: f64,\n}\n";
    assert_eq!(
        serde_items(src),
        vec![
            ("A".to_string(), vec!["x_m".to_string(), "why".to_string()]),
            (
                "E".to_string(),
                vec![
                    "Plain".to_string(),
                    "Tuple".to_string(),
                    "Named".to_string(),
                    "inner_deg".to_string()
                ]
            ),
        ]
    );
}

// ---------------------------------------------------------------------------------------------
// (b) products
// ---------------------------------------------------------------------------------------------

/// Dotted key paths of a JSON value (`bands[].brf[].brf_se`), objects' keys and arrays'
/// elements alike.
fn json_paths(v: &serde_json::Value, prefix: &str, out: &mut BTreeSet<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                out.insert(p.clone());
                json_paths(x, &p, out);
            }
        }
        serde_json::Value::Array(a) => {
            for x in a {
                json_paths(x, &format!("{prefix}[]"), out);
            }
        }
        _ => {}
    }
}

/// Runs a tiny turbid layer (sun + sky, 20 directions and an exact nadir view) to `dir`; with
/// `atmosphere` (RON of the scene's `atmosphere` section) under that atmosphere instead of a
/// sky.
fn tiny_run(dir: &Path, solver: Solver, atmosphere: Option<&str>) {
    let mut desc = turbid_layer(&TurbidLayerParams {
        size_m: 1.0,
        cell_m: 0.5,
        ..Default::default()
    });
    match atmosphere {
        // (As scene files are read: optional fields take a bare value.)
        Some(a) => {
            desc.atmosphere = Some(
                ron::Options::default()
                    .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
                    .from_str(a)
                    .unwrap_or_else(|e| panic!("{e}")),
            )
        }
        None => desc.illumination.skyl = vec![0.2],
    }
    desc.directions = Some(DirectionParams {
        count: 20,
        exact: vec![ExactDirection::new(0.0, 0.0)],
        ..Default::default()
    });
    let settings = RunSettings {
        solver,
        ..Default::default()
    };
    let mut sim = Simulation::from_desc(&desc, &SceneSource::generated(), settings)
        .unwrap_or_else(|e| panic!("{e}"));
    // As `lumenscape run` does: the memory estimate, recorded in summary.json.
    let plan = sim.memory_plan().unwrap_or_else(|e| panic!("{e}"));
    sim.world.insert_resource(plan);
    sim.run(Some(dir)).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn every_product_key_and_column_is_in_the_reference() {
    let doc = read("docs/guide/products.md");
    let root = std::env::temp_dir().join(format!("lumenscape-docs-{}", std::process::id()));
    let mc = Solver::MonteCarlo {
        photons: 4000,
        sampler: lumenscape::photon::engine::SamplerKind::Continuous,
    };
    // (The atmosphere of the scene-format reference's example.)
    let atm = "(molecules: (), aerosols: (tau_reference: 0.2, angstrom_exponent: 1.3, \
               ssa: [0.9], phase: HenyeyGreenstein(g: 0.7)))";
    let runs = [
        ("flux", Solver::FluxTracking, None),
        ("mc", mc, None),
        ("atm", mc, Some(atm)),
    ];
    let mut missing = Vec::new();
    for (name, solver, atmosphere) in runs {
        let dir = root.join(name);
        tiny_run(&dir, solver, atmosphere);
        // summary.json: every key path.
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap())
                .unwrap();
        let mut paths = BTreeSet::new();
        json_paths(&summary, "", &mut paths);
        assert!(paths.len() > 30, "{name}: {} keys", paths.len());
        for p in paths {
            if !doc.contains(&format!("`{p}`")) {
                missing.push(format!("{name}: summary.json key `{p}`"));
            }
        }
        // CSV headers: brf.csv and the budget.
        for csv in [
            "brf.csv",
            "budget/cells.csv",
            "budget/layers.csv",
            "budget/elements.csv",
        ] {
            let text = std::fs::read_to_string(dir.join(csv)).unwrap();
            for col in text.lines().next().unwrap().split(',') {
                if !doc.contains(&format!("`{col}`")) {
                    missing.push(format!("{name}: {csv} column `{col}`"));
                }
            }
        }
        // Maket products and images: every file name pattern.
        for f in ["maket.json", "lai.exr", "dsm.exr", "density.csv"] {
            assert!(dir.join(f).exists(), "{name}: no {f}");
            if !doc.contains(&format!("`{f}`")) {
                missing.push(format!("{name}: file `{f}`"));
            }
        }
        if name == "flux" {
            assert!(dir.join("images/view_000.0_000.0.exr").exists());
            assert!(dir.join("images/view_000.0_000.0.png").exists());
            for f in [
                "images/view_<zenith>_<azimuth>.exr",
                "images/view_<zenith>_<azimuth>.png",
            ] {
                if !doc.contains(&format!("`{f}`")) {
                    missing.push(format!("file `{f}`"));
                }
            }
            let maket: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(dir.join("maket.json")).unwrap())
                    .unwrap();
            let mut mp = BTreeSet::new();
            json_paths(&maket, "", &mut mp);
            for p in mp {
                // Keys under leaf_area / facet_* are material names, not fields.
                let field = p.split('.').next_back().unwrap();
                if p.starts_with("leaf_area.") && p.matches('.').count() == 1 {
                    continue;
                }
                if (p.starts_with("facet_area_m2.") || p.starts_with("facet_count."))
                    && p.matches('.').count() == 1
                {
                    continue;
                }
                if !doc.contains(&format!("`{p}`")) && !doc.contains(&format!("`{field}`")) {
                    missing.push(format!("maket.json key `{p}`"));
                }
            }
        }
    }
    let _ = std::fs::remove_dir_all(&root);
    assert!(
        missing.is_empty(),
        "docs/guide/products.md does not document:\n{}",
        missing.join("\n")
    );
}

// ---------------------------------------------------------------------------------------------
// (c) physics.md citations
// ---------------------------------------------------------------------------------------------

/// Every `§N` / `§N.M` that follows a `physics.md` mention in `text`, in the same citation
/// (`physics.md §3.6, §6.3 and §13`).
fn cited_sections(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (pos, _) in text.match_indices("physics.md") {
        let mut rest = text[pos + "physics.md".len()..].trim_start();
        while let Some(r) = rest.strip_prefix('§') {
            let num: String = r
                .chars()
                .take_while(|c| c.is_ascii_digit() || *c == '.')
                .collect();
            let num = num.trim_end_matches('.').to_string();
            if num.is_empty() {
                break;
            }
            rest = &r[num.len()..];
            out.push(num);
            // Continue over `, §x`, ` and §x` and `–§x`.
            let t = rest
                .trim_start_matches(['.', ','])
                .trim_start()
                .trim_start_matches("and ")
                .trim_start_matches(['–', '-', ',', ' ']);
            if t.starts_with('§') {
                rest = t;
            } else {
                break;
            }
        }
    }
    out
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn every_cited_physics_section_exists() {
    let physics = read("docs/physics.md");
    let headings: BTreeSet<String> = physics
        .lines()
        .filter(|l| l.starts_with("## ") || l.starts_with("### "))
        .filter_map(|l| {
            let num = l.trim_start_matches('#').trim_start().split(' ').next()?;
            let num = num.trim_end_matches('.');
            num.chars()
                .all(|c| c.is_ascii_digit() || c == '.')
                .then(|| num.to_string())
        })
        .collect();
    assert!(headings.contains("0") && headings.contains("9.6") && headings.contains("15"));
    let mut files = Vec::new();
    for d in ["src", "systems", "tests", "benches"] {
        rust_files(&asset(d), &mut files);
    }
    let mut cited = 0;
    let mut missing = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        for s in cited_sections(&text) {
            cited += 1;
            if !headings.contains(&s) {
                missing.push(format!("{}: physics.md §{s}", f.display()));
            }
        }
    }
    assert!(
        cited > 150,
        "only {cited} citations found: the parser broke"
    );
    assert!(
        missing.is_empty(),
        "cited sections missing from docs/physics.md:\n{}",
        missing.join("\n")
    );
}

#[test]
fn the_citation_parser_reads_lists() {
    assert_eq!(
        cited_sections("see physics.md §3.6, §6.3 and §13; physics.md §6.7 [rec]. physics.md §2."),
        ["3.6", "6.3", "13", "6.7", "2"]
    );
    assert!(cited_sections("physics.md is the spec").is_empty());
}

// ---------------------------------------------------------------------------------------------
// (d) README
// ---------------------------------------------------------------------------------------------

#[test]
fn readme_is_short_and_has_no_session_history() {
    let readme = read("README.md");
    let n = readme.lines().count();
    assert!(n <= 200, "README.md has {n} lines (limit 200)");
    assert!(
        !readme.to_lowercase().contains("session"),
        "README.md mentions a session: history goes to CHANGELOG.md"
    );
    for cmd in [
        "cargo run --release -- run assets/scenes/default.ron --out out/default",
        "cargo test",
    ] {
        assert!(readme.contains(cmd), "README.md lost its command `{cmd}`");
    }
    // Every relative link of the README points at a file of the repository (docs/architecture.md
    // is written separately and may not exist yet).
    for part in readme.split("](").skip(1) {
        let target = part.split(')').next().unwrap().split('#').next().unwrap();
        if target.is_empty() || target.contains("://") || target == "docs/architecture.md" {
            continue;
        }
        assert!(
            asset(target).exists(),
            "README.md links to missing `{target}`"
        );
    }
}
