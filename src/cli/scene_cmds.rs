//! `lumenscape check | maket | run SCENE`.

use crate::io::atomic::StagedDir;
use crate::resources::maket_report::MaketReport;
use crate::resources::scene::{RunSettings, default_max_memory};
use crate::simulation::{Simulation, Stage};
use std::io::Write;
use std::path::{Path, PathBuf};

/// A command failure: message for stderr and process exit code.
#[derive(Debug)]
pub struct CliError {
    /// Message.
    pub message: String,
    /// Exit code (non-zero).
    pub code: i32,
}

impl<E: std::fmt::Display> From<E> for CliError {
    fn from(e: E) -> Self {
        Self {
            message: e.to_string(),
            code: 1,
        }
    }
}

/// Parses a memory size: `123` (bytes), `512K`, `300M`, `4G`, `1.5G`, or `50%` of RAM.
pub fn parse_memory(s: &str) -> Result<u64, String> {
    let s = s.trim();
    let err = || format!("cannot read memory size `{s}` (use e.g. 4G, 500M or 50%)");
    if let Some(p) = s.strip_suffix('%') {
        let f: f64 = p.parse().map_err(|_| err())?;
        if !(f > 0.0 && f <= 100.0) {
            return Err(err());
        }
        return Ok((default_max_memory() as f64 / 0.75 * f / 100.0) as u64);
    }
    let (num, mult) = match s.chars().last() {
        Some('K' | 'k') => (&s[..s.len() - 1], 1u64 << 10),
        Some('M' | 'm') => (&s[..s.len() - 1], 1 << 20),
        Some('G' | 'g') => (&s[..s.len() - 1], 1 << 30),
        Some('T' | 't') => (&s[..s.len() - 1], 1 << 40),
        _ => (s, 1),
    };
    let v: f64 = num.parse().map_err(|_| err())?;
    if !(v > 0.0 && v.is_finite()) {
        return Err(err());
    }
    Ok((v * mult as f64) as u64)
}

/// Options shared by the scene commands.
#[derive(clap::Args, Debug, Clone)]
pub struct SceneOpts {
    /// Scene file (RON).
    pub scene: PathBuf,
    /// Refuse scenes where any stage's memory estimate (Maket, flux tracking, Monte Carlo,
    /// LiDAR, output; `check` prints them) is above this (e.g. 4G, 500M, 50%), before anything
    /// is allocated. Default: 75% of the machine's RAM.
    #[arg(long, value_parser = parse_memory)]
    pub max_memory: Option<u64>,
    /// No progress bars.
    #[arg(long, short)]
    pub quiet: bool,
    /// Accuracy preset of the Radiative stage (overrides the scene's `radiative.preset`).
    #[arg(long, value_enum)]
    pub preset: Option<crate::scene::desc::Preset>,
    /// Passive solver: DART flux tracking (Radiative stage) or forward Monte Carlo (Photon
    /// stage, products with standard errors).
    #[arg(long, value_enum, default_value = "flux-tracking")]
    pub solver: SolverArg,
    /// Run mode (overrides the scene's `thermal.mode`): `r` reflected sunlight, `t` thermal
    /// emission, `rt` both; `t` and `rt` need the scene's `thermal` section (temperatures).
    #[arg(long, value_enum)]
    pub mode: Option<ModeArg>,
    /// Photons for the Monte Carlo solver (sun + sky) [default: 1000000]; only with
    /// `--solver monte-carlo`.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub photons: Option<u64>,
    /// Scattering-direction sampler of the Monte Carlo solver: exact continuous phase
    /// functions (unbiased reference) or DART's Ray-Carlo over the discrete directions with
    /// alias tables or the Box method [default: continuous]; only with `--solver monte-carlo`.
    #[arg(long, value_enum)]
    pub sampler: Option<SamplerArg>,
    /// Box method: largest max/min probability ratio inside a class (> 1) [default: 2];
    /// only with `--sampler box`.
    #[arg(long)]
    pub box_gamma: Option<f64>,
    /// Box method: boxes per incident direction (memory budget) [default: 4096]; only with
    /// `--sampler box`.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub box_budget: Option<u64>,
    /// Oversampling factor η of the orthographic images: pixels of Δx/η × Δy/η (overrides
    /// the scene's `radiative.image_oversampling`; 1..=64, and at most 2^26 pixels per image).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=crate::scene::validate::MAX_IMAGE_OVERSAMPLING as i64))]
    pub image_oversampling: Option<u32>,
    /// Most capable instruction set of the flux-tracking walks. `best`: AVX-512 where the CPU
    /// has it (the batched walk on 16 lanes in single-precision geometry, or 8 with
    /// `--batch-f64`), else AVX2 (4 lanes); `avx2`: 4 lanes on every x86-64 CPU with AVX2, so
    /// that AVX-512 and AVX2-only machines give the same bits (8 and 4 lanes sum the rays'
    /// contributions in different orders: ~1e-15 relative; 16 single-precision lanes differ
    /// from both by ~3e-7); `baseline`: one ray at a time.
    #[arg(long, value_enum, default_value = "best")]
    pub isa: IsaArg,
    /// The batched walk in double precision (8 lanes on AVX-512) instead of the default
    /// single-precision geometry on 16 lanes: products equal to the one-ray walk's to rounding
    /// (~1e-15) and to AVX2 machines' within ~1e-15, for ~0.7× the speed. (The default's
    /// products are within ~3e-7 relative of these.)
    #[arg(long)]
    pub batch_f64: bool,
}

/// `--isa` values.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum IsaArg {
    /// The best the CPU has.
    Best,
    /// At most AVX2 + FMA.
    Avx2,
    /// Baseline x86-64.
    Baseline,
}

/// `--mode` values.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeArg {
    /// Reflected sunlight and sky light only.
    R,
    /// Thermal emission only.
    T,
    /// Both (R+T).
    Rt,
}

/// `--solver` values.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverArg {
    /// DART discrete-ordinate flux tracking.
    FluxTracking,
    /// Forward Monte Carlo photon tracking.
    MonteCarlo,
}

/// `--sampler` values.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum SamplerArg {
    /// Exact continuous phase functions.
    Continuous,
    /// Discrete directions, Walker/Vose alias tables.
    Alias,
    /// Discrete directions, DART Box method.
    Box,
}

impl SceneOpts {
    /// The run settings these options give.
    pub(crate) fn settings(&self) -> RunSettings {
        use crate::photon::engine::SamplerKind;
        let sampler = match self.sampler.unwrap_or(SamplerArg::Continuous) {
            SamplerArg::Continuous => SamplerKind::Continuous,
            SamplerArg::Alias => SamplerKind::Alias,
            SamplerArg::Box => SamplerKind::Box {
                gamma: self.box_gamma.unwrap_or(2.0),
                max_boxes: self.box_budget.unwrap_or(4096) as usize,
            },
        };
        RunSettings {
            max_memory_bytes: self.max_memory.unwrap_or_else(default_max_memory),
            progress: !self.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr()),
            preset: self.preset,
            solver: match self.solver {
                SolverArg::FluxTracking => crate::resources::scene::Solver::FluxTracking,
                SolverArg::MonteCarlo => crate::resources::scene::Solver::MonteCarlo {
                    photons: self.photons.unwrap_or(1_000_000),
                    sampler,
                },
            },
            image_oversampling: self.image_oversampling,
            skip_empty: true,
            batch_walk: true,
            kernel_isa: match self.isa {
                IsaArg::Best => crate::radiative::engine::KernelIsa::Best,
                IsaArg::Avx2 => crate::radiative::engine::KernelIsa::Avx2,
                IsaArg::Baseline => crate::radiative::engine::KernelIsa::Baseline,
            },
            batch_f32: !self.batch_f64,
            chunk_rays: crate::radiative::engine::CHUNK_RAYS,
            lidar_chunk_pulses: crate::lidar::simulate::DEFAULT_CHUNK_PULSES,
            lidar_first_order_columns: true,
            lidar_far_roulette: Default::default(),
        }
    }

    /// Refuses Monte Carlo flags that the chosen solver or sampler would ignore, and a Box
    /// ratio that is not > 1 (exit 2, like clap's own usage errors).
    pub(crate) fn check_flags(&self) -> Result<(), CliError> {
        let usage = |message: String| CliError { message, code: 2 };
        if self.solver == SolverArg::FluxTracking {
            for (flag, given) in [
                ("--photons", self.photons.is_some()),
                ("--sampler", self.sampler.is_some()),
                ("--box-gamma", self.box_gamma.is_some()),
                ("--box-budget", self.box_budget.is_some()),
            ] {
                if given {
                    return Err(usage(format!(
                        "{flag} is an option of the Monte Carlo solver and would be ignored by the flux-tracking solver: add `--solver monte-carlo` or remove {flag}"
                    )));
                }
            }
        }
        if self.sampler != Some(SamplerArg::Box) {
            for (flag, given) in [
                ("--box-gamma", self.box_gamma.is_some()),
                ("--box-budget", self.box_budget.is_some()),
            ] {
                if given {
                    return Err(usage(format!(
                        "{flag} is an option of the Box sampler and would be ignored: add `--sampler box` or remove {flag}"
                    )));
                }
            }
        }
        if let Some(g) = self.box_gamma
            && !(g.is_finite() && g > 1.0)
        {
            return Err(usage(format!(
                "--box-gamma {g}: the Box method's max/min probability ratio must be a finite number > 1"
            )));
        }
        Ok(())
    }

    /// Loads, validates and spawns the scene with these settings; an `--image-oversampling`
    /// that would make images above the pixel limit for this scene's grid is refused here
    /// (exit 1), before any work.
    fn load(&self) -> Result<Simulation, CliError> {
        self.check_flags()?;
        let (mut desc, src) = crate::scene::load_scene(&self.scene)?;
        if let Some(m) = self.mode {
            use crate::scene::desc::RunMode;
            let mode = match m {
                ModeArg::R => RunMode::R,
                ModeArg::T => RunMode::T,
                ModeArg::Rt => RunMode::RT,
            };
            match desc.thermal.as_mut() {
                Some(t) => t.mode = mode,
                None if mode.thermal() => {
                    return Err(CliError {
                        message: format!(
                            "--mode {}: {} has no `thermal` section (the temperatures of its elements)",
                            mode.name(),
                            self.scene.display()
                        ),
                        code: 1,
                    });
                }
                None => {}
            }
            // The mode decides which temperatures are needed.
            crate::scene::validate::validate(&desc, &src)?;
        }
        if let Some(eta) = self.image_oversampling {
            let g = &desc.grid;
            let columns = (g.size_m.0 / g.cell_m.0).round() * (g.size_m.1 / g.cell_m.1).round();
            let pixels = columns * (eta as f64).powi(2);
            let limit = crate::scene::validate::MAX_IMAGE_PIXELS;
            if pixels > limit as f64 {
                return Err(CliError {
                    message: format!(
                        "--image-oversampling {eta}: {eta} × {eta} pixels per grid column of {} make images of {pixels:.3e} pixels (limit {limit})",
                        self.scene.display()
                    ),
                    code: 1,
                });
            }
        }
        Ok(Simulation::from_desc(&desc, &src, self.settings())?)
    }
}

/// `check`: validate a scene and print its summary (leaf and facet areas, cell counts, memory
/// estimate) without allocating the grid.
#[derive(clap::Args, Debug)]
pub struct CheckArgs {
    #[command(flatten)]
    /// Scene and settings.
    pub opts: SceneOpts,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

pub(crate) fn human_bytes(b: u64) -> String {
    let b = b as f64;
    if b >= (1u64 << 30) as f64 {
        format!("{:.2} GiB", b / (1u64 << 30) as f64)
    } else if b >= (1u64 << 20) as f64 {
        format!("{:.1} MiB", b / (1u64 << 20) as f64)
    } else {
        format!("{:.1} KiB", b / 1024.0)
    }
}

/// Prints a report as text.
pub fn print_report(r: &MaketReport, out: &mut dyn Write) -> std::io::Result<()> {
    writeln!(
        out,
        "grid: {} × {} × {} cells of {} × {} × {} m ({} cells), z from {:.3} to {:.3} m",
        r.cells[0],
        r.cells[1],
        r.cells[2],
        r.cell_m[0],
        r.cell_m[1],
        r.cell_m[2],
        r.n_cells,
        r.z_range_m[0],
        r.z_range_m[1]
    )?;
    if r.topography_offset_m != (0.0, 0.0) {
        writeln!(
            out,
            "continuous topography offsets: {:.4} m along x, {:.4} m along y",
            r.topography_offset_m.0, r.topography_offset_m.1
        )?;
    }
    for (m, la) in &r.leaf_area {
        match la.rasterised_m2 {
            Some(x) => writeln!(
                out,
                "leaf area `{m}`: {:.6} m² (analytic {:.6} m², relative difference {:.2e})",
                x,
                la.analytic_m2,
                (x - la.analytic_m2) / la.analytic_m2.max(1e-300)
            )?,
            None => writeln!(out, "leaf area `{m}`: {:.6} m²", la.analytic_m2)?,
        }
    }
    for (m, a) in &r.facet_area_m2 {
        writeln!(
            out,
            "facets `{m}`: {} triangles, {:.4} m²",
            r.facet_count.get(m).copied().unwrap_or(0),
            a
        )?;
    }
    if let Some(t) = r.turbid_cells {
        writeln!(out, "cells with vegetation: {t}")?;
    }
    if let Some(f) = r.facet_cells {
        writeln!(out, "cells with facets: {f}")?;
    }
    writeln!(
        out,
        "Maket grid memory estimate (build peak, without the process baseline): {} (limit {})",
        human_bytes(r.memory.peak_bytes),
        human_bytes(r.memory.limit_bytes)
    )?;
    if let Some(u) = r.memory_used_bytes {
        writeln!(out, "memory held after Maket: {}", human_bytes(u))?;
    }
    for w in &r.warnings {
        writeln!(out, "warning: {w}")?;
    }
    Ok(())
}

/// Prints the memory estimate per stage (the terms of each) and the peak.
pub fn print_memory(
    m: &crate::resources::memory::MemoryPlan,
    limit: u64,
    out: &mut dyn Write,
) -> std::io::Result<()> {
    writeln!(
        out,
        "memory estimate per stage ({} worker threads):",
        m.threads
    )?;
    for s in &m.stages {
        let terms: Vec<String> = s
            .terms
            .iter()
            .filter(|t| t.bytes > 0)
            .map(|t| format!("{} {}", t.name, human_bytes(t.bytes)))
            .collect();
        writeln!(
            out,
            "  {:<9} {:>10}  ({})",
            s.stage,
            human_bytes(s.bytes),
            terms.join(", ")
        )?;
    }
    writeln!(
        out,
        "memory estimate (peak, all stages): {} in the {} stage (limit {})",
        human_bytes(m.peak_bytes),
        m.peak_stage,
        human_bytes(limit)
    )
}

/// The refusal of a run whose stage `s` is estimated above `limit` bytes (`--max-memory`).
fn over_limit_error(
    scene: &Path,
    s: &crate::resources::memory::StageMemory,
    limit: u64,
) -> CliError {
    CliError {
        message: format!(
            "{}: the {} stage needs an estimated {} ({} bytes), above the limit of {} (--max-memory): use larger cells, fewer directions or a smaller scene, or raise --max-memory",
            scene.display(),
            s.stage,
            human_bytes(s.bytes),
            s.bytes,
            human_bytes(limit)
        ),
        code: 1,
    }
}

/// Runs `check`: the plan report, the memory estimate per stage; exit 1 when the scene is
/// invalid or a stage's estimate is above `--max-memory`.
pub fn check(args: &CheckArgs, out: &mut dyn Write) -> Result<(), CliError> {
    let mut sim = args.opts.load()?;
    let rss = crate::resources::memory::current_rss_bytes();
    let planned = sim.plan();
    if !sim
        .world
        .contains_resource::<crate::resources::maket_report::MemoryEstimate>()
    {
        planned?;
        return Err(CliError {
            message: "planning produced no grid".into(),
            code: 1,
        });
    }
    let report = sim.plan_report().expect("planning inserted its resources");
    let mem = crate::memory::estimate(&sim.world, &report, rss);
    let limit = report.memory.limit_bytes;
    if args.json {
        let mut v = serde_json::to_value(&report)?;
        v["memory_plan"] = serde_json::to_value(&mem)?;
        v["radiative_memory_estimate_bytes"] = mem
            .stages
            .iter()
            .find(|s| s.stage == "Radiative")
            .map_or(0, |s| s.bytes)
            .into();
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(out, "{}: scene is valid", args.opts.scene.display())?;
        print_report(&report, out)?;
        print_memory(&mem, limit, out)?;
    }
    planned?;
    if let Some(s) = mem.over(limit) {
        return Err(over_limit_error(&args.opts.scene, s, limit));
    }
    Ok(())
}

/// `maket`: run the Maket stage and write its products.
#[derive(clap::Args, Debug)]
pub struct MaketArgs {
    #[command(flatten)]
    /// Scene and settings.
    pub opts: SceneOpts,
    /// Output folder (created; an earlier run's products there are replaced as a whole; a
    /// folder holding other files is refused unless `--force`).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the contents of a non-empty output folder that holds other files.
    #[arg(long)]
    pub force: bool,
}

/// Runs `maket`.
pub fn maket(args: &MaketArgs, out: &mut dyn Write) -> Result<(), CliError> {
    let mut sim = args.opts.load()?;
    let staged = StagedDir::begin(&args.out, args.force, "--force")?;
    sim.world
        .insert_resource(crate::resources::scene::OutputDir(
            staged.path().to_path_buf(),
        ));
    sim.run_stage(Stage::Maket)?;
    sim.run_stage(Stage::Output)?;
    staged.commit()?;
    print_report(sim.resource::<MaketReport>(), out)?;
    writeln!(out, "products written to {}", args.out.display())?;
    Ok(())
}

/// `run`: every stage that exists so far, products into `--out`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    #[command(flatten)]
    /// Scene and settings.
    pub opts: SceneOpts,
    /// Output folder (created; an earlier run's products there are replaced as a whole; a
    /// folder holding other files is refused unless `--force`). The products are written into
    /// a hidden staging folder beside it and moved into place when the run has finished, so a
    /// failed or killed run never leaves a complete-looking folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the contents of a non-empty output folder that holds other files.
    #[arg(long)]
    pub force: bool,
}

/// Runs `run`.
pub fn run(args: &RunArgs, out: &mut dyn Write) -> Result<(), CliError> {
    let t0 = std::time::Instant::now();
    let mut sim = args.opts.load()?;
    // The memory estimate of every stage, before the output folder and anything big exist.
    let mem = sim.memory_plan()?;
    let limit = sim
        .resource::<crate::resources::scene::RunSettings>()
        .max_memory_bytes;
    if let Some(s) = mem.over(limit) {
        return Err(over_limit_error(&args.opts.scene, s, limit));
    }
    sim.world.insert_resource(mem);
    let staged = StagedDir::begin(&args.out, args.force, "--force")?;
    let ran = sim.run(Some(staged.path()))?;
    let written: Vec<String> = product_files(staged.path()).into_keys().collect();
    staged.commit()?;
    print_report(sim.resource::<MaketReport>(), out)?;
    let skipped: Vec<String> = Stage::ALL
        .iter()
        .filter(|s| !s.implemented())
        .map(|s| format!("{s:?}"))
        .collect();
    writeln!(
        out,
        "stages run: {:?}; not implemented yet: {}",
        ran,
        skipped.join(", ")
    )?;
    if sim
        .get_resource::<crate::resources::scene::SkipPassive>()
        .is_some()
    {
        writeln!(
            out,
            "passive solver: not run (LiDAR-only scene: no instrument has `fusion: true` or \
             `photon_counting`; set `passive: Some(true)` for the passive products)"
        )?;
    }
    writeln!(
        out,
        "products written to {} in {:.2} s: {}",
        args.out.display(),
        t0.elapsed().as_secs_f64(),
        product_list(&written)
    )?;
    Ok(())
}

/// Every file under `dir` (relative paths with `/`, sorted) and its modification time; the
/// hidden temporary files of atomic writes are left out. An absent folder has none.
fn product_files(dir: &Path) -> std::collections::BTreeMap<String, std::time::SystemTime> {
    fn walk(
        root: &Path,
        d: &Path,
        acc: &mut std::collections::BTreeMap<String, std::time::SystemTime>,
    ) {
        let Ok(entries) = std::fs::read_dir(d) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            if e.file_name().to_string_lossy().starts_with('.') {
                continue;
            }
            let Ok(meta) = e.metadata() else { continue };
            if meta.is_dir() {
                walk(root, &p, acc);
            } else if let (Ok(rel), Ok(t)) = (p.strip_prefix(root), meta.modified()) {
                let rel: Vec<String> = rel
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect();
                acc.insert(rel.join("/"), t);
            }
        }
    }
    let mut acc = Default::default();
    walk(dir, dir, &mut acc);
    acc
}

/// A short list of written products (relative paths): the files of the output folder itself by
/// name, each sub-folder as `folder/ (N files: …)` with its file names when there are at most
/// four, else its count per extension (`images/ (6 files: 3 .exr, 3 .png)`).
pub fn product_list(paths: &[String]) -> String {
    use std::collections::BTreeMap;
    if paths.is_empty() {
        return "no files".into();
    }
    let mut top = Vec::new();
    let mut dirs: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for p in paths {
        match p.rsplit_once('/') {
            Some((d, f)) => dirs.entry(d).or_default().push(f),
            None => top.push(p.as_str()),
        }
    }
    let mut parts: Vec<String> = top.iter().map(|s| s.to_string()).collect();
    for (d, files) in dirs {
        let what = if files.len() <= 4 {
            files.join(", ")
        } else {
            let mut ext: BTreeMap<&str, usize> = BTreeMap::new();
            for f in &files {
                *ext.entry(f.rsplit_once('.').map_or("", |(_, e)| e))
                    .or_default() += 1;
            }
            ext.iter()
                .map(|(e, n)| format!("{n} .{e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let n = files.len();
        let s = if n == 1 { "" } else { "s" };
        parts.push(format!("{d}/ ({n} file{s}: {what})"));
    }
    parts.join(", ")
}

/// Resolves a path relative to the current folder (for messages).
pub fn display(p: &Path) -> String {
    p.display().to_string()
}

#[cfg(test)]
mod tests {
    use super::product_list;

    #[test]
    fn product_list_names_files_and_counts_folders() {
        let paths: Vec<String> = [
            "brf.csv",
            "budget/cells.csv",
            "budget/layers.csv",
            "images/view_000.0_000.0.exr",
            "images/view_000.0_000.0.png",
            "images/view_030.0_000.0.exr",
            "images/view_030.0_000.0.png",
            "images/view_030.0_090.0.exr",
            "summary.json",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        assert_eq!(
            product_list(&paths),
            "brf.csv, summary.json, budget/ (2 files: cells.csv, layers.csv), \
             images/ (5 files: 3 .exr, 2 .png)"
        );
        assert_eq!(product_list(&[]), "no files");
    }
}
