//! The floor plan's rules (docs/architecture.md), checked on the source text so that a change that
//! breaks them fails here with the file and the line, not in a reviewer's head:
//! - the top-level modules form layers, and a module imports only from the layers below it (so
//!   there is no import circle), and a type's inherent methods are written in the module that
//!   defines it (so no call reaches a higher layer unseen);
//! - each DART stage has its engine in `src/<stage>/` with no ECS machinery, and its glue in
//!   `systems/<stage>.rs`, which exports the stage's system set; only `src/simulation.rs`
//!   imports `systems`;
//! - every source file opens with a `//!` doc; files stay under ~1 500 lines (the few larger ones
//!   are listed below with the reason); only the command line reads environment variables.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The top-level modules of the crate, lowest layer first. A module may import (`crate::x`)
/// only modules that come before it here.
const LAYERS: &[&str] = &[
    "random",     // seeded streams
    "io",         // file formats (CSV text, meshes, EXR, LAS, atomic writes)
    "physics",    // pure formulas: LAD/G/Γ, phase functions, BRDFs, PROSPECT, SRFs, sun
    "geometry",   // shapes, crowns, terrain, triangles, polygons, quadrature
    "direction",  // Direction engine: the discrete directions
    "phase",      // Phase engine: phase tables over the directions
    "scene",      // RON scene format: authoring types, validation, generators, raster input
    "resources",  // data shared between stages (grid, facets, materials, settings)
    "components", // plain data on entities
    "maket",      // Maket engine: objects → cell grid
    "radiative",  // Radiative engine: flux tracking
    "photon",     // Photon engine: Monte Carlo
    "lidar",      // LiDAR engine (on top of the photon walk)
    "memory",     // the memory estimate per stage, from the engines' terms
    "output",     // product writers
    "systems",    // ECS glue, one file per stage
    "simulation", // the World and the stage loop
    "sequence",   // parameter sweeps over simulations, look-up tables
    "cli",        // the command line
];

/// Engine folders: plain functions over data, no ECS machinery.
const ENGINES: &[&str] = &[
    "random",
    "io",
    "physics",
    "geometry",
    "direction",
    "phase",
    "scene",
    "maket",
    "radiative",
    "photon",
    "lidar",
    "output",
];

/// Files allowed above the size limit, with the reason. An entry that no longer exists or has
/// come under the limit fails the test, so the list only shrinks.
const LARGE_FILES: &[(&str, &str)] = &[];

const MAX_LINES: usize = 1500;

/// Upward imports that remain (module, imported module), each to be removed by moving a type
/// down a layer (issue #30). An entry that no longer occurs fails the test, so the list only
/// shrinks. The engines' parameter and product types moved down (`TrackingParams`/`KernelIsa`/
/// `TrackOptics` to `resources::tracking`, `SamplerKind`/`FarRoulette`/`DEFAULT_CHUNK_PULSES` to
/// `resources::scene`, `MonteCarloInfo` to `radiative::products`, `BeamProfile`/`ReturnsMethod`
/// to `scene::desc`) and the LiDAR results up (`LidarRun`, `LidarProducts`, … to `lidar::run`);
/// what remains: `src/scene/validate.rs` still names `crate::lidar::pulse::BeamProfile` (the
/// type is `crate::scene::desc::BeamProfile` now; that file was not changed with the move).
const KNOWN_UPWARD: &[(&str, &str)] = &[];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Every source file of the crate with its top-level module (`systems` for `systems/`).
fn sources() -> Vec<(String, PathBuf, String)> {
    let mut files = Vec::new();
    rust_files(&root().join("src"), &mut files);
    rust_files(&root().join("systems"), &mut files);
    files
        .into_iter()
        .filter_map(|p| {
            let rel = p.strip_prefix(root()).unwrap().to_path_buf();
            let parts: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            let module = if parts[0] == "systems" {
                "systems".to_string()
            } else if parts[1] == "lib.rs" || parts[1] == "bin" {
                return None;
            } else {
                parts[1].trim_end_matches(".rs").to_string()
            };
            let text = std::fs::read_to_string(&p).unwrap();
            Some((module, rel, text))
        })
        .collect()
}

/// The code lines of a file (1-based line numbers): comments stripped, unit-test modules left out.
fn code_lines(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let lines: Vec<&str> = text.lines().collect();
    for (i, line) in lines.iter().enumerate() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            // `#[cfg(test)] mod tests;` (a file of its own) is skipped, an inline module ends
            // the code.
            let next = lines.get(i + 1).map_or("", |l| l.trim());
            if next.starts_with("mod ") && next.ends_with(';') {
                continue;
            }
            break;
        }
        let code = line.split("//").next().unwrap_or("");
        out.push((i + 1, code.to_string()));
    }
    out
}

/// `crate::m` references of each code line.
fn crate_refs(line: &str) -> Vec<String> {
    let mut refs = Vec::new();
    let mut rest = line;
    while let Some(k) = rest.find("crate::") {
        let tail = &rest[k + "crate::".len()..];
        let name: String = tail
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let before = rest[..k].chars().last();
        if !before.is_some_and(|c| c.is_alphanumeric() || c == '_') && !name.is_empty() {
            refs.push(name);
        }
        rest = tail;
    }
    refs
}

#[test]
fn every_module_has_a_layer() {
    let known: BTreeSet<&str> = LAYERS.iter().copied().collect();
    let missing: BTreeSet<String> = sources()
        .into_iter()
        .map(|(m, _, _)| m)
        .filter(|m| !known.contains(m.as_str()))
        .collect();
    assert!(
        missing.is_empty(),
        "modules without a place in tests/architecture.rs LAYERS: {missing:?}"
    );
}

#[test]
fn modules_import_only_from_lower_layers() {
    let rank: BTreeMap<&str, usize> = LAYERS.iter().enumerate().map(|(i, m)| (*m, i)).collect();
    let mut bad = Vec::new();
    let mut seen_known = BTreeSet::new();
    for (module, path, text) in sources() {
        let Some(&own) = rank.get(module.as_str()) else {
            continue;
        };
        for (line, code) in code_lines(&text) {
            for target in crate_refs(&code) {
                if target == module {
                    continue;
                }
                if let Some(&t) = rank.get(target.as_str())
                    && t > own
                {
                    if KNOWN_UPWARD.contains(&(module.as_str(), target.as_str())) {
                        seen_known.insert((module.clone(), target.clone()));
                        continue;
                    }
                    bad.push(format!(
                        "{}:{line}: `{module}` imports `{target}` (a higher layer)",
                        path.display()
                    ));
                }
            }
        }
    }
    for (m, t) in KNOWN_UPWARD {
        if !seen_known.contains(&(m.to_string(), t.to_string())) {
            bad.push(format!(
                "{m} → {t} no longer occurs: take it off KNOWN_UPWARD"
            ));
        }
    }
    assert!(bad.is_empty(), "upward imports:\n{}", bad.join("\n"));
}

#[test]
fn the_module_graph_has_no_cycle() {
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let names: BTreeSet<String> = sources().into_iter().map(|(m, _, _)| m).collect();
    for (module, _, text) in sources() {
        for (_, code) in code_lines(&text) {
            for t in crate_refs(&code) {
                if KNOWN_UPWARD.contains(&(module.as_str(), t.as_str())) {
                    continue;
                }
                if t != module && names.contains(&t) {
                    graph.entry(module.clone()).or_default().insert(t);
                }
            }
        }
    }
    // Depth-first search with colours; report one cycle.
    fn visit(
        n: &str,
        g: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(n.to_string(), 1);
        stack.push(n.to_string());
        for m in g.get(n).into_iter().flatten() {
            match state.get(m.as_str()).copied().unwrap_or(0) {
                1 => {
                    let k = stack.iter().position(|s| s == m).unwrap();
                    let mut c = stack[k..].to_vec();
                    c.push(m.clone());
                    return Some(c);
                }
                0 => {
                    if let Some(c) = visit(m, g, state, stack) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(n.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for n in &names {
        if state.get(n.as_str()).copied().unwrap_or(0) == 0 {
            let cycle = visit(n, &graph, &mut state, &mut Vec::new());
            assert!(
                cycle.is_none(),
                "import circle: {}",
                cycle.unwrap().join(" → ")
            );
        }
    }
}

#[test]
fn engines_hold_no_ecs_machinery() {
    // A `Resource`/`Component` derive on a data type is allowed; systems, queries, commands,
    // worlds and schedules belong in systems/ and simulation.rs.
    const FORBIDDEN: &[&str] = &[
        "Query<",
        "Res<",
        "ResMut<",
        "Commands",
        "World",
        "Schedule",
        "SystemSet",
        "bevy_ecs::system",
        "bevy_ecs::world",
        "run_if",
    ];
    let mut bad = Vec::new();
    for (module, path, text) in sources() {
        if !ENGINES.contains(&module.as_str()) {
            continue;
        }
        for (line, code) in code_lines(&text) {
            for f in FORBIDDEN {
                if code.contains(f) {
                    bad.push(format!("{}:{line}: `{f}`", path.display()));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "ECS machinery in engine code:\n{}",
        bad.join("\n")
    );
}

#[test]
fn each_stage_has_an_engine_folder_and_a_systems_file() {
    for stage in [
        "direction",
        "phase",
        "maket",
        "radiative",
        "photon",
        "lidar",
    ] {
        let engine = root().join("src").join(stage).join("mod.rs");
        assert!(engine.exists(), "missing engine {}", engine.display());
        let glue = root().join("systems").join(format!("{stage}.rs"));
        assert!(glue.exists(), "missing glue {}", glue.display());
    }
    // Every stage's glue exports its system set and the function the stage loop calls.
    for stage in [
        "direction",
        "phase",
        "maket",
        "radiative",
        "photon",
        "output",
    ] {
        let path = root().join("systems").join(format!("{stage}.rs"));
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains("pub fn add_systems(s: &mut Schedule)"),
            "{} exports no add_systems",
            path.display()
        );
        assert!(
            text.contains("#[derive(SystemSet"),
            "{} exports no system set",
            path.display()
        );
    }
}

#[test]
fn only_the_simulation_imports_systems() {
    let mut bad = Vec::new();
    for (module, path, text) in sources() {
        if module == "systems" || module == "simulation" {
            continue;
        }
        for (line, code) in code_lines(&text) {
            if crate_refs(&code).iter().any(|r| r == "systems") {
                bad.push(format!("{}:{line}", path.display()));
            }
        }
    }
    // Tests, benches and users go through the simulation too.
    let mut files = Vec::new();
    rust_files(&root().join("tests"), &mut files);
    rust_files(&root().join("benches"), &mut files);
    for f in files {
        if f.ends_with("tests/architecture.rs") {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap();
        if text.contains("lumenscape::systems") {
            bad.push(f.strip_prefix(root()).unwrap().display().to_string());
        }
    }
    assert!(bad.is_empty(), "imports of systems:\n{}", bad.join("\n"));
}

#[test]
fn every_source_file_opens_with_its_doc() {
    let bad: Vec<String> = sources()
        .into_iter()
        .filter(|(_, _, text)| !text.trim_start().starts_with("//!"))
        .map(|(_, p, _)| p.display().to_string())
        .collect();
    assert!(bad.is_empty(), "files without a `//!` opening doc: {bad:?}");
}

#[test]
fn files_stay_under_the_size_limit() {
    let mut bad = Vec::new();
    let sizes: BTreeMap<String, usize> = sources()
        .into_iter()
        .map(|(_, p, t)| (p.display().to_string(), t.lines().count()))
        .collect();
    for (p, n) in &sizes {
        if *n > MAX_LINES && !LARGE_FILES.iter().any(|(f, _)| f == p) {
            bad.push(format!("{p}: {n} lines"));
        }
    }
    for (f, _) in LARGE_FILES {
        match sizes.get(*f) {
            None => bad.push(format!("{f}: listed in LARGE_FILES but gone")),
            Some(&n) if n <= MAX_LINES => {
                bad.push(format!("{f}: {n} lines, take it off LARGE_FILES"))
            }
            _ => {}
        }
    }
    assert!(
        bad.is_empty(),
        "over {MAX_LINES} lines:\n{}",
        bad.join("\n")
    );
}

#[test]
fn only_the_command_line_reads_the_environment() {
    let mut bad = Vec::new();
    for (module, path, text) in sources() {
        if module == "cli" {
            continue;
        }
        for (line, code) in code_lines(&text) {
            if code.contains("env::var") {
                bad.push(format!("{}:{line}", path.display()));
            }
        }
    }
    assert!(bad.is_empty(), "environment reads:\n{}", bad.join("\n"));
}

/// The name a type definition line defines (`pub(crate) struct Name<..>`, `enum Name {`), if any.
fn defined_type(code: &str) -> Option<String> {
    let t = code.trim_start();
    let t = if let Some(r) = t.strip_prefix("pub") {
        // `pub`, `pub(crate)`, `pub(in path)`.
        let r = r.trim_start();
        match r.strip_prefix('(') {
            Some(r) => r.split_once(')')?.1.trim_start(),
            None => r,
        }
    } else {
        t
    };
    let rest = ["struct ", "enum ", "union "]
        .iter()
        .find_map(|k| t.strip_prefix(k))?;
    let name: String = rest
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    (!name.is_empty()).then_some(name)
}

/// The type of an inherent `impl` line (`impl<..> path::Name<..> {`), if it is one (trait
/// impls, `impl .. for ..`, are not).
fn inherent_impl_type(code: &str) -> Option<String> {
    let t = code.trim_start().strip_prefix("impl")?;
    if code.contains(" for ") || !code.trim_end().ends_with('{') {
        return None;
    }
    let mut rest = t;
    if rest.starts_with('<') {
        let mut depth = 0;
        let end = rest.char_indices().find_map(|(i, c)| {
            match c {
                '<' => depth += 1,
                '>' => depth -= 1,
                _ => {}
            }
            (depth == 0).then_some(i)
        })?;
        rest = &rest[end + 1..];
    } else if !rest.starts_with(' ') {
        return None;
    }
    let path: String = rest
        .trim_start()
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
        .collect();
    let name = path.rsplit("::").next()?.to_string();
    (!name.is_empty()).then_some(name)
}

/// Methods of a type are written in the module that defines it: an inherent `impl` of a type
/// of another module (e.g. a `scene` type given methods in `lidar`) lets the defining module
/// call code of a higher layer with no `crate::` path that the import rule would see.
#[test]
fn inherent_impls_live_with_their_type() {
    let srcs = sources();
    let mut defined: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (module, _, text) in &srcs {
        for (_, code) in code_lines(text) {
            if let Some(name) = defined_type(&code) {
                defined.entry(name).or_default().insert(module.clone());
            }
        }
    }
    let mut bad = Vec::new();
    for (module, path, text) in &srcs {
        for (line, code) in code_lines(text) {
            let Some(name) = inherent_impl_type(&code) else {
                continue;
            };
            if let Some(owners) = defined.get(&name)
                && !owners.contains(module)
            {
                bad.push(format!(
                    "{}:{line}: `{module}` adds methods to `{name}` of `{}`",
                    path.display(),
                    owners.iter().cloned().collect::<Vec<_>>().join("`, `")
                ));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "inherent impls away from their type:\n{}",
        bad.join("\n")
    );
}
