//! `lumenscape sequence SEQ.ron --out DIR` (a parameter sweep, optionally one shard of it) and
//! `lumenscape gather DIR` (every finished point into one look-up table); see
//! [`crate::sequence`] and docs/guide/sequences.md.

use super::scene_cmds::{CliError, SceneOpts, SolverArg, human_bytes};
use crate::sequence::plan::{Plan, Shard};
use std::io::Write;
use std::path::PathBuf;

/// `sequence`: expand, plan and run a sweep.
#[derive(clap::Args, Debug)]
pub struct SequenceArgs {
    /// Sequence file (RON).
    pub sequence: PathBuf,
    /// Sequence folder: `plan.json` and `points/pNNNNNN/` per point. Points already there are
    /// skipped, so running again resumes an interrupted sweep.
    #[arg(long)]
    pub out: PathBuf,
    /// Run the K-th of N disjoint parts (0 ≤ K < N; point i belongs to part i mod N). Without
    /// it the part comes from a Slurm job array (`SLURM_ARRAY_TASK_ID` − `SLURM_ARRAY_TASK_MIN`
    /// of `SLURM_ARRAY_TASK_COUNT`) or a Kubernetes Indexed Job (`JOB_COMPLETION_INDEX` of
    /// `--shard-count`), else the whole plan runs.
    #[arg(long)]
    pub shard: Option<String>,
    /// Number of parts when the index comes from `JOB_COMPLETION_INDEX` (Kubernetes).
    #[arg(long)]
    pub shard_count: Option<usize>,
    /// Print the plan (axes, points, this shard's share, what is done, the memory estimate of
    /// the first point) and run nothing.
    #[arg(long)]
    pub dry_run: bool,
    /// Accuracy preset of the Radiative stage for every point.
    #[arg(long, value_enum)]
    pub preset: Option<crate::scene::desc::Preset>,
    /// Passive solver of every point.
    #[arg(long, value_enum, default_value = "flux-tracking")]
    pub solver: SolverArg,
    /// Photons per point for the Monte Carlo solver [default: 1000000].
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub photons: Option<u64>,
    /// Refuse points whose memory estimate is above this (e.g. 4G, 50%).
    #[arg(long, value_parser = super::scene_cmds::parse_memory)]
    pub max_memory: Option<u64>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `gather`: one table from every finished point of a sequence folder.
#[derive(clap::Args, Debug)]
pub struct GatherArgs {
    /// Sequence folder (the `--out` of `lumenscape sequence`; every shard's points).
    pub dir: PathBuf,
    /// Table to write (CSV; the same table as Parquet beside it, extension `.parquet`)
    /// [default: DIR/lut.csv].
    #[arg(long)]
    pub table: Option<PathBuf>,
}

/// The shard to run: `--shard K/N`, else a Slurm array task, else a Kubernetes Indexed Job
/// (count from `--shard-count`), else the whole plan. `env` reads an environment variable.
pub fn resolve_shard(
    flag: Option<&str>,
    count: Option<usize>,
    env: impl Fn(&str) -> Option<String>,
) -> Result<Shard, String> {
    if let Some(s) = flag {
        return Shard::parse(s);
    }
    let num = |name: &str| -> Result<Option<usize>, String> {
        env(name)
            .map(|v| {
                v.trim()
                    .parse::<usize>()
                    .map_err(|_| format!("{name}={v}: not a non-negative integer"))
            })
            .transpose()
    };
    if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
        let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
        let n = count.or(num("SLURM_ARRAY_TASK_COUNT")?).ok_or(
            "SLURM_ARRAY_TASK_ID is set but not SLURM_ARRAY_TASK_COUNT: give --shard-count",
        )?;
        let k = id
            .checked_sub(min)
            .ok_or("SLURM_ARRAY_TASK_ID is below SLURM_ARRAY_TASK_MIN")?;
        return Shard::parse(&format!("{k}/{n}")).map_err(|e| format!("Slurm array: {e}"));
    }
    if let Some(k) = num("JOB_COMPLETION_INDEX")? {
        let n = count.ok_or(
            "JOB_COMPLETION_INDEX is set (Kubernetes Indexed Job): give --shard-count with the Job's completions",
        )?;
        return Shard::parse(&format!("{k}/{n}")).map_err(|e| format!("Indexed Job: {e}"));
    }
    if count.is_some() {
        return Err("--shard-count needs JOB_COMPLETION_INDEX or SLURM_ARRAY_TASK_ID".into());
    }
    Ok(Shard::ALL)
}

/// Runs `sequence`.
pub fn run(args: &SequenceArgs, out: &mut dyn Write) -> Result<(), CliError> {
    let t0 = std::time::Instant::now();
    let usage = |message: String| CliError { message, code: 2 };
    let shard = resolve_shard(args.shard.as_deref(), args.shard_count, |k| {
        std::env::var(k).ok()
    })
    .map_err(usage)?;
    let opts = SceneOpts {
        scene: args.sequence.clone(),
        max_memory: args.max_memory,
        quiet: args.quiet,
        preset: args.preset,
        solver: args.solver,
        photons: args.photons,
        mode: None,
        sampler: None,
        box_gamma: None,
        box_budget: None,
        image_oversampling: None,
        isa: super::scene_cmds::IsaArg::Best,
        batch_f64: false,
    };
    opts.check_flags()?;
    let settings = opts.settings();
    let plan = Plan::load(&args.sequence).map_err(|e| CliError {
        message: e.to_string(),
        code: 1,
    })?;
    let n = plan.len();
    let points = plan.shard_points(shard, &settings).map_err(|e| CliError {
        message: e.to_string(),
        code: 1,
    })?;
    let mine = points.len();
    if args.dry_run {
        writeln!(
            out,
            "sequence `{}` on {}: {n} points",
            plan.name,
            plan.src.path.display()
        )?;
        for a in &plan.axes {
            let vals: Vec<String> = a.values.iter().map(|v| v.to_string()).collect();
            writeln!(
                out,
                "  axis `{}` ({}){}: {} values: {}",
                a.name,
                a.path,
                a.zip
                    .as_deref()
                    .map(|z| format!(", zip `{z}`"))
                    .unwrap_or_default(),
                vals.len(),
                vals.join(", ")
            )?;
        }
        let done = points
            .iter()
            .filter(|&&i| {
                crate::sequence::run::point_dir(&args.out, i)
                    .join("point.json")
                    .exists()
            })
            .count();
        let units = plan
            .units(plan.merges(&settings))
            .map_err(|e| CliError {
                message: e.to_string(),
                code: 1,
            })?
            .len();
        writeln!(
            out,
            "runs: {units} (points that differ only in per-band values share one run as its bands)"
        )?;
        writeln!(
            out,
            "shard {}/{}: {mine} points, {done} already done in {}",
            shard.k,
            shard.n,
            args.out.display()
        )?;
        let first = plan.point(0).map_err(|e| CliError {
            message: e.to_string(),
            code: 1,
        })?;
        let mut sim =
            crate::simulation::Simulation::from_desc(&first.desc, &plan.src, settings.clone())?;
        let mem = sim.memory_plan()?;
        writeln!(
            out,
            "memory estimate of point 0: {} (peak stage {})",
            human_bytes(mem.peak_bytes),
            mem.peak_stage
        )?;
        writeln!(out, "kept per point: {}", plan.keep.join(", "))?;
        return Ok(());
    }
    let rep = plan
        .run(&args.out, shard, &settings)
        .map_err(|e| CliError {
            message: e.to_string(),
            code: 1,
        })?;
    writeln!(
        out,
        "shard {}/{} of `{}`: {} points run, {} already done, {} failed, in {:.2} s; products in {}/points",
        shard.k,
        shard.n,
        args.sequence.display(),
        rep.ran.len(),
        rep.skipped.len(),
        rep.failed.len(),
        t0.elapsed().as_secs_f64(),
        args.out.display()
    )?;
    if !rep.failed.is_empty() {
        let lines: Vec<String> = rep
            .failed
            .iter()
            .map(|(i, m)| format!("  point {i}: {m}"))
            .collect();
        return Err(CliError {
            message: format!(
                "{} points failed (the others are done; run again to retry these):\n{}",
                rep.failed.len(),
                lines.join("\n")
            ),
            code: 1,
        });
    }
    Ok(())
}

/// Runs `gather`.
pub fn gather(args: &GatherArgs, out: &mut dyn Write) -> Result<(), CliError> {
    let table = args
        .table
        .clone()
        .unwrap_or_else(|| args.dir.join("lut.csv"));
    let rep = crate::sequence::lut::gather(&args.dir, &table)
        .map_err(|message| CliError { message, code: 1 })?;
    writeln!(
        out,
        "{} and {}: {} rows from {} of {} points",
        table.display(),
        table.with_extension("parquet").display(),
        rep.rows,
        rep.finished,
        rep.points
    )?;
    if !rep.no_passive.is_empty() {
        writeln!(
            out,
            "{} finished points have no passive products (LiDAR-only scenes; their LiDAR products are in points/*/lidar/) and are not in the table",
            rep.no_passive.len()
        )?;
    }
    if !rep.missing.is_empty() {
        let shown: Vec<String> = rep.missing.iter().take(20).map(|i| i.to_string()).collect();
        writeln!(
            out,
            "missing (not finished): {} points: {}{}",
            rep.missing.len(),
            shown.join(", "),
            if rep.missing.len() > 20 { ", …" } else { "" }
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env_of<'a>(pairs: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            pairs
                .iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn shards_come_from_the_flag_slurm_or_kubernetes() {
        assert_eq!(resolve_shard(None, None, env_of(&[])), Ok(Shard::ALL));
        assert_eq!(
            resolve_shard(Some("1/3"), None, env_of(&[("SLURM_ARRAY_TASK_ID", "2")])),
            Ok(Shard { k: 1, n: 3 })
        );
        let slurm = [
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
        ];
        assert_eq!(
            resolve_shard(None, None, env_of(&slurm)),
            Ok(Shard { k: 4, n: 8 })
        );
        let k8s = [("JOB_COMPLETION_INDEX", "6")];
        assert_eq!(
            resolve_shard(None, Some(7), env_of(&k8s)),
            Ok(Shard { k: 6, n: 7 })
        );
        assert!(resolve_shard(None, None, env_of(&k8s)).is_err());
        assert!(resolve_shard(None, Some(6), env_of(&k8s)).is_err());
        assert!(resolve_shard(Some("x"), None, env_of(&[])).is_err());
        assert!(resolve_shard(None, None, env_of(&[("SLURM_ARRAY_TASK_ID", "1")])).is_err());
    }
}
