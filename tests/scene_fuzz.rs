//! Scene fuzzer (issue #31): structure-aware mutations of every example scene in
//! `assets/scenes`, from a fixed seed, through
//!
//! 1. parsing and validation ([`lumenscape::scene::parse_scene`], [`validate`]),
//! 2. `lumenscape check` (the CLI entry: spawn, Maket plan, plan report, radiative memory
//!    estimate) with a 256 MiB memory cap,
//! 3. a capped run of the valid ones ([`Simulation::run`] without an output folder): 16
//!    directions, the Preview preset, one iteration, at most [`RUN_MAX_CELLS`] cells and
//!    [`RUN_MAX_PULSES`] LiDAR pulses per instrument.
//!
//! Every case must end without a panic (`catch_unwind`), and every error must have a
//! non-empty message. The mutations work on RON tokens, so they keep the scene's structure:
//! a number becomes 0, −1, NaN, ±inf, huge, tiny or a huge integer; a list loses or repeats
//! an element; an enum variant or a keyword becomes another of its family (crown shapes,
//! boundary modes, foliage kinds, footprints, LADs, …); a struct field is dropped; `Some(x)`
//! becomes `None`; a boolean flips. Each case applies one to three mutations to one scene.
//!
//! `cases_in_ci` runs [`CI_CASES`] cases in the normal test run; `many_cases` (ignored) runs
//! [`MANY_CASES`]: `cargo test --release --test scene_fuzz -- --ignored` (a few minutes).
//! A failure prints the seed, the scene and the mutations of each panicking case; rerun one
//! case with `FUZZ_CASE=<index> cargo test --test scene_fuzz -- --ignored one_case`.

use lumenscape::cli::scene_cmds::{CheckArgs, IsaArg, SceneOpts, SolverArg, check};
use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::desc::{Preset, RadiativeDesc, SceneDesc};
use lumenscape::scene::validate::{SceneSource, lidar_pulse_count, validate};
use lumenscape::simulation::Simulation;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

/// Cases of the normal test run.
const CI_CASES: usize = 300;
/// Cases of the ignored long run.
const MANY_CASES: usize = 10_000;
/// Seed of the corpus.
const SEED: u64 = 0x0005_CE7E_0F31;
/// Largest grid (cells) of a capped run.
const RUN_MAX_CELLS: usize = 3_000;
/// Largest LiDAR pulse count of a capped run (per instrument).
const RUN_MAX_PULSES: u64 = 40;
/// Memory cap of `check` and of the capped runs.
const MAX_MEMORY: u64 = 256 << 20;

/// SplitMix64: a tiny seeded generator (no dependency).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[self.below(v.len())]
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Open(u8),
    Close,
    Comma,
    Colon,
    Word,
    Str,
}

#[derive(Debug, Clone, Copy)]
struct Tok {
    start: usize,
    end: usize,
    kind: Kind,
}

/// RON tokens (comments skipped).
fn tokens(s: &str) -> Vec<Tok> {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        let start = i;
        let kind = match c {
            b'/' if b.get(i + 1) == Some(&b'/') => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
                continue;
            }
            b'/' if b.get(i + 1) == Some(&b'*') => {
                i += 2;
                while i + 1 < b.len() && !(b[i] == b'*' && b[i + 1] == b'/') {
                    i += 1;
                }
                i += 2;
                continue;
            }
            b'"' => {
                i += 1;
                while i < b.len() && b[i] != b'"' {
                    if b[i] == b'\\' {
                        i += 1;
                    }
                    i += 1;
                }
                i += 1;
                Kind::Str
            }
            b'(' | b'[' | b'{' => {
                i += 1;
                Kind::Open(c)
            }
            b')' | b']' | b'}' => {
                i += 1;
                Kind::Close
            }
            b',' => {
                i += 1;
                Kind::Comma
            }
            b':' => {
                i += 1;
                Kind::Colon
            }
            c if c.is_ascii_whitespace() => {
                i += 1;
                continue;
            }
            _ => {
                while i < b.len() && !b[i].is_ascii_whitespace() && !b"()[]{},:\"".contains(&b[i]) {
                    i += 1;
                }
                Kind::Word
            }
        };
        out.push(Tok {
            start,
            end: i.min(b.len()),
            kind,
        });
    }
    out
}

fn matching_close(t: &[Tok], open: usize) -> usize {
    let mut depth = 0;
    for (i, x) in t.iter().enumerate().skip(open) {
        match x.kind {
            Kind::Open(_) => depth += 1,
            Kind::Close => {
                depth -= 1;
                if depth == 0 {
                    return i;
                }
            }
            _ => {}
        }
    }
    t.len() - 1
}

/// Byte ranges of the depth-0 elements inside the bracket at token `open` (with the comma
/// that follows each, so that removing one keeps the list well formed).
fn elements(s: &str, t: &[Tok], open: usize) -> Vec<(usize, usize)> {
    let close = matching_close(t, open);
    let mut out = Vec::new();
    let mut depth = 0;
    let mut start = None;
    for k in open + 1..close {
        match t[k].kind {
            Kind::Open(_) => depth += 1,
            Kind::Close => depth -= 1,
            Kind::Comma if depth == 0 => {
                if let Some(a) = start.take() {
                    out.push((a, t[k].end));
                }
                continue;
            }
            _ => {}
        }
        if start.is_none() {
            start = Some(t[k].start);
        }
    }
    if let Some(a) = start {
        out.push((a, t[close].start));
    }
    let _ = s;
    out
}

/// Families of interchangeable words (enum variants, keywords).
const FAMILIES: &[&[&str]] = &[
    &["Ellipsoid", "Cone", "Cylinder", "Trapezoid", "Paraboloid"],
    &["Isolated", "Repetitive", "RepetitiveContinuousTopography"],
    &["Lai", "LeafAreaDensity", "LeafArea"],
    &["Box", "Polygon"],
    &[
        "Spherical",
        "Erectophile",
        "Planophile",
        "Plagiophile",
        "Extremophile",
        "Uniform",
    ],
    &[
        "Lambertian",
        "BiLambertian",
        "Turbid",
        "Rpv",
        "Hapke",
        "ProspectLeaf",
    ],
    &[
        "Ground",
        "Tree",
        "TreeStand",
        "TurbidPlot",
        "Building",
        "Water",
        "Leaves",
        "LeafList",
        "Mesh",
    ],
    &["Flat", "Gable"],
    &["Preview", "Default", "Reference"],
    &["Off", "Faces", "Subfaces", "Blend"],
    &["Airborne", "Terrestrial"],
    &["Single", "List", "Scan"],
    &["true", "false"],
    &["Explicit", "Random"],
    &["EsriAscii", "BinaryF32"],
];

/// Replacement numbers: zero, negative, non-finite, huge, tiny, huge integers.
const NUMBERS: &[&str] = &[
    "0",
    "0.0",
    "-1",
    "-1.0",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e-308",
    "1e300",
    "1e-300",
    "1e6",
    "1e-6",
    "4294967296",
    "18446744073709551615",
    "65536",
    "2",
    "0.5",
    "1e12",
];

fn is_number(w: &str) -> bool {
    w.parse::<f64>().is_ok() || w == "NaN" || w == "inf" || w == "-inf"
}

/// One mutation of `s`; returns the new text and a description.
fn mutate(s: &str, rng: &mut Rng) -> Option<(String, String)> {
    let t = tokens(s);
    let splice = |a: usize, b: usize, with: &str| format!("{}{}{}", &s[..a], with, &s[b..]);
    for _ in 0..20 {
        match rng.below(10) {
            // Numbers (most mutations).
            0..=4 => {
                let nums: Vec<&Tok> = t
                    .iter()
                    .filter(|x| x.kind == Kind::Word && is_number(&s[x.start..x.end]))
                    .collect();
                if nums.is_empty() {
                    continue;
                }
                let x = *rng.pick(&nums);
                let with = *rng.pick(NUMBERS);
                return Some((
                    splice(x.start, x.end, with),
                    format!(
                        "number `{}` at byte {} → {with}",
                        &s[x.start..x.end],
                        x.start
                    ),
                ));
            }
            // Drop or duplicate a list element.
            5 | 6 => {
                let lists: Vec<usize> = (0..t.len())
                    .filter(|&k| t[k].kind == Kind::Open(b'['))
                    .collect();
                if lists.is_empty() {
                    continue;
                }
                let open = *rng.pick(&lists);
                let el = elements(s, &t, open);
                if el.is_empty() {
                    continue;
                }
                let (a, b) = *rng.pick(&el);
                let mut item = s[a..b].to_string();
                if !item.trim_end().ends_with(',') {
                    item.push(',');
                }
                return Some(if rng.below(2) == 0 {
                    (
                        splice(a, b, ""),
                        format!("list element at byte {a} dropped"),
                    )
                } else {
                    (
                        splice(a, a, &item),
                        format!("list element at byte {a} duplicated"),
                    )
                });
            }
            // Swap a variant or keyword within its family.
            7 => {
                let words: Vec<(&Tok, &[&str])> = t
                    .iter()
                    .filter(|x| x.kind == Kind::Word)
                    .filter_map(|x| {
                        let w = &s[x.start..x.end];
                        FAMILIES.iter().find(|f| f.contains(&w)).map(|f| (x, *f))
                    })
                    .collect();
                if words.is_empty() {
                    continue;
                }
                let (x, fam) = *rng.pick(&words);
                let with = *rng.pick(fam);
                return Some((
                    splice(x.start, x.end, with),
                    format!("`{}` at byte {} → {with}", &s[x.start..x.end], x.start),
                ));
            }
            // Drop a struct field `name: value,`.
            8 => {
                let fields: Vec<usize> = (0..t.len().saturating_sub(1))
                    .filter(|&k| t[k].kind == Kind::Word && t[k + 1].kind == Kind::Colon)
                    .collect();
                if fields.is_empty() {
                    continue;
                }
                let k = *rng.pick(&fields);
                // The value ends at the next depth-0 comma or the enclosing close.
                let mut depth = 0;
                let mut end = t.len() - 1;
                for (j, x) in t.iter().enumerate().skip(k + 2) {
                    match x.kind {
                        Kind::Open(_) => depth += 1,
                        Kind::Close if depth == 0 => {
                            end = j;
                            break;
                        }
                        Kind::Close => depth -= 1,
                        Kind::Comma if depth == 0 => {
                            end = j + 1;
                            break;
                        }
                        _ => {}
                    }
                }
                let b = if t[end.min(t.len() - 1)].kind == Kind::Close {
                    t[end].start
                } else {
                    t[end - 1].end
                };
                return Some((
                    splice(t[k].start, b, ""),
                    format!("field `{}` dropped", &s[t[k].start..t[k].end]),
                ));
            }
            // `Some(x)` → `None`.
            _ => {
                let somes: Vec<usize> = (0..t.len().saturating_sub(1))
                    .filter(|&k| {
                        t[k].kind == Kind::Word
                            && &s[t[k].start..t[k].end] == "Some"
                            && t[k + 1].kind == Kind::Open(b'(')
                    })
                    .collect();
                if somes.is_empty() {
                    continue;
                }
                let k = *rng.pick(&somes);
                let close = matching_close(&t, k + 1);
                return Some((
                    splice(t[k].start, t[close].end, "None"),
                    format!("Some(..) at byte {} → None", t[k].start),
                ));
            }
        }
    }
    None
}

struct Scene {
    path: PathBuf,
    text: String,
}

fn scenes() -> Vec<Scene> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "ron"))
        .collect();
    v.sort();
    v.into_iter()
        .map(|path| Scene {
            text: std::fs::read_to_string(&path).unwrap(),
            path,
        })
        .collect()
}

/// A folder mirroring `assets` (scene files are written to `<tmp>/scenes`, and `meshes`,
/// `optics` and `sensors` link to the real folders so that relative paths resolve).
fn work_dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("lumenscape-fuzz-{}", std::process::id()));
    let scenes = d.join("scenes");
    if !scenes.exists() {
        std::fs::create_dir_all(&scenes).unwrap();
        let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
        for sub in ["meshes", "optics", "sensors"] {
            #[cfg(unix)]
            let _ = std::os::unix::fs::symlink(assets.join(sub), d.join(sub));
        }
    }
    scenes
}

/// What a case ended with.
#[derive(Debug, PartialEq)]
enum Outcome {
    SyntaxError,
    Invalid,
    CheckError,
    Checked,
    Ran,
    RunError,
}

fn opts(scene: PathBuf) -> SceneOpts {
    SceneOpts {
        scene,
        max_memory: Some(MAX_MEMORY),
        quiet: true,
        preset: None,
        solver: SolverArg::FluxTracking,
        photons: None,
        mode: None,
        sampler: None,
        box_gamma: None,
        box_budget: None,
        image_oversampling: None,
        isa: IsaArg::Best,
        batch_f64: false,
    }
}

/// Caps a valid scene for a quick run; `None` when it stays too big.
fn capped(mut desc: SceneDesc) -> Option<SceneDesc> {
    if let Some(d) = &mut desc.directions {
        if d.layers.is_none() {
            d.count = d.count.min(16);
        }
        d.exact.truncate(2);
        d.oversample.clear();
    } else {
        desc.directions = Some(lumenscape::direction::DirectionParams::with_count(16));
    }
    let r = desc.radiative.get_or_insert_with(RadiativeDesc::default);
    r.preset = Some(Preset::Preview);
    r.max_iterations = Some(1);
    r.image_oversampling = r.image_oversampling.min(2);
    for l in desc.lidars.iter_mut().flatten() {
        if lidar_pulse_count(l) > RUN_MAX_PULSES {
            return None;
        }
        l.photons_per_pulse = Some(l.photons_per_pulse.unwrap_or(8).min(8));
        l.scattering_photons_per_pulse = l.scattering_photons_per_pulse.map(|n| n.min(8));
        l.max_order = l.max_order.min(3);
        if let Some(pc) = &mut l.photon_counting {
            pc.shots = pc.shots.min(2);
        }
    }
    Some(desc)
}

/// Runs one mutated text through every step; `Err` = a message was empty.
fn run_case(path: &Path, text: &str, name: &str) -> Result<Outcome, String> {
    let desc = match lumenscape::scene::parse_scene(text, path) {
        Ok(d) => d,
        Err(e) => {
            return non_empty(e.to_string(), "parse").map(|_| Outcome::SyntaxError);
        }
    };
    let src = SceneSource {
        path: path.to_path_buf(),
        text: Some(text.to_string()),
    };
    if let Err(e) = validate(&desc, &src) {
        return non_empty(e.to_string(), "validate").map(|_| Outcome::Invalid);
    }
    // `check` through the CLI entry (spawn, plan, plan report, radiative estimate).
    let file = work_dir().join(format!("{name}.ron"));
    std::fs::write(&file, text).unwrap();
    let args = CheckArgs {
        opts: opts(file.clone()),
        json: false,
    };
    let mut out = Vec::new();
    if let Err(e) = check(&args, &mut out) {
        return non_empty(e.message, "check").map(|_| Outcome::CheckError);
    }
    // A capped run.
    let Some(small) = capped(desc) else {
        return Ok(Outcome::Checked);
    };
    let settings = RunSettings {
        max_memory_bytes: MAX_MEMORY,
        progress: false,
        ..RunSettings::default()
    };
    let mut sim = match Simulation::from_desc(&small, &src, settings) {
        Ok(s) => s,
        Err(e) => return non_empty(e.to_string(), "capped load").map(|_| Outcome::RunError),
    };
    if let Err(e) = sim.plan() {
        return non_empty(e.to_string(), "capped plan").map(|_| Outcome::RunError);
    }
    let cells = sim
        .get_resource::<lumenscape::resources::grid::GridSpec>()
        .map_or(usize::MAX, |g| g.n_cells());
    if cells > RUN_MAX_CELLS {
        return Ok(Outcome::Checked);
    }
    let mut sim = Simulation::from_desc(
        &small,
        &src,
        RunSettings {
            max_memory_bytes: MAX_MEMORY,
            progress: false,
            ..RunSettings::default()
        },
    )
    .map_err(|e| format!("capped reload: {e}"))?;
    match sim.run(None) {
        Ok(_) => Ok(Outcome::Ran),
        Err(e) => non_empty(e.to_string(), "run").map(|_| Outcome::RunError),
    }
}

fn non_empty(msg: String, step: &str) -> Result<(), String> {
    // An error message carries more than its prefix (`file: `, `Maket stage: `).
    let body = msg.rsplit(": ").next().unwrap_or("").trim();
    if msg.trim().is_empty() || body.is_empty() {
        Err(format!("{step}: empty error message `{msg}`"))
    } else {
        Ok(())
    }
}

/// Case `i` of the corpus: the scene, the mutated text and the mutations.
fn case(all: &[Scene], i: usize) -> (usize, String, Vec<String>) {
    let mut rng = Rng(SEED ^ (i as u64).wrapping_mul(0x2545_F491_4F6C_DD1D));
    let k = rng.below(all.len());
    let mut text = all[k].text.clone();
    let mut what = Vec::new();
    for _ in 0..1 + rng.below(3) {
        if let Some((t, w)) = mutate(&text, &mut rng) {
            text = t;
            what.push(w);
        }
    }
    (k, text, what)
}

/// Runs cases `range`; panics listing every case that panicked or gave an empty message.
fn fuzz(range: std::ops::Range<usize>) {
    let all = scenes();
    assert!(all.len() >= 10, "example scenes: {}", all.len());
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut failures = Vec::new();
    let mut outcomes = std::collections::BTreeMap::<String, usize>::new();
    for i in range.clone() {
        let (k, text, what) = case(&all, i);
        let name = format!("case{i}");
        let t0 = std::time::Instant::now();
        if std::env::var_os("FUZZ_VERBOSE").is_some() {
            eprintln!("case {i} ({}) {what:?}", all[k].path.display());
        }
        let r = catch_unwind(AssertUnwindSafe(|| run_case(&all[k].path, &text, &name)));
        if std::env::var_os("FUZZ_VERBOSE").is_some() {
            eprintln!(
                "  {:?} in {:.2} s",
                r.as_ref().ok(),
                t0.elapsed().as_secs_f64()
            );
        }
        let tag = match r {
            Ok(Ok(o)) => format!("{o:?}"),
            Ok(Err(m)) => {
                failures.push(format!(
                    "case {i} ({}, {what:?}): {m}",
                    all[k].path.display()
                ));
                "EmptyMessage".into()
            }
            Err(p) => {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                failures.push(format!(
                    "case {i} ({}, {what:?}): PANIC {msg}",
                    all[k].path.display()
                ));
                "Panic".into()
            }
        };
        *outcomes.entry(tag).or_default() += 1;
    }
    std::panic::set_hook(hook);
    eprintln!("fuzz cases {range:?}: {outcomes:?}");
    assert!(
        failures.is_empty(),
        "{} failing cases (seed {SEED:#x}):\n{}",
        failures.len(),
        failures.join("\n")
    );
    // The corpus reaches every step: some cases are refused at each, some run.
    for o in ["SyntaxError", "Invalid", "Ran"] {
        assert!(
            outcomes.contains_key(o),
            "no case ended as {o}: {outcomes:?}"
        );
    }
}

/// The corpus of the normal test run.
#[test]
fn cases_in_ci() {
    fuzz(0..CI_CASES);
}

/// The long corpus: [`MANY_CASES`] cases, run with
/// `cargo test --release --test scene_fuzz -- --ignored many_cases` (a few minutes; ~4 min in
/// the dev profile, where the engines' `debug_assert`s are checked too). Case 9202
/// (`lidar_photon_counting.ron` with `cell_m: (1.0, 1.0, 65536.0)`, a valid scene of 65 km
/// tall cells) tripped the 1e-9 relative `debug_assert` "first-flight return transmittance …
/// vs shadow ray" of `src/photon/engine/peel_off.rs` (1.1e-9 off): the shadow ray's hotspot
/// decorrelation came from a 1-ulp separation of the reversed flight, amplified by 65 km of
/// path over 1 cm leaves; fixed by
/// [`BACKSCATTER_ROUNDING`](lumenscape::radiative::engine::BACKSCATTER_ROUNDING).
#[test]
#[ignore]
fn many_cases() {
    fuzz(0..MANY_CASES);
}

/// Cases of the corpus (`FUZZ_CASE=<index>[,<index>…]`), with the panic message and backtrace
/// shown.
#[test]
#[ignore]
fn one_case() {
    let list = std::env::var("FUZZ_CASE").unwrap_or_else(|_| "0".into());
    let all = scenes();
    for i in list
        .split(',')
        .filter_map(|s| s.trim().parse::<usize>().ok())
    {
        let (k, text, what) = case(&all, i);
        eprintln!("case {i}: {} {what:?}", all[k].path.display());
        let r = run_case(&all[k].path, &text, &format!("case{i}"));
        eprintln!("{r:?}");
        assert!(r.is_ok());
    }
}
