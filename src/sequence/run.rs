//! Running a plan's points (or one shard's): each point's products go to their own folder
//! `points/pNNNNNN/` through a staging folder renamed into place when the point has finished,
//! with `point.json` (index, axis values, scene hash, program version) written last inside it.
//! A point whose folder exists is done and is skipped on a re-run, so an interrupted sweep
//! resumes; a killed point leaves only a hidden `.pNNNNNN.partial-PID` folder, removed when
//! its shard runs again.

use super::plan::{Plan, SequenceError, Shard, fnv1a64};
use crate::io::atomic::{StagedDir, write_atomic};
use crate::resources::scene::RunSettings;
use crate::scene::to_ron;
use crate::simulation::Simulation;
use serde_json::json;
use std::path::{Path, PathBuf};

/// What a run of a shard did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SequenceReport {
    /// Points of the shard.
    pub owned: usize,
    /// Points run now.
    pub ran: Vec<usize>,
    /// Points found done (skipped).
    pub skipped: Vec<usize>,
    /// Points that failed, with the message.
    pub failed: Vec<(usize, String)>,
}

/// Folder name of point `i` (`p000042`).
pub fn point_name(i: usize) -> String {
    format!("p{i:06}")
}

/// The folder of point `i` under the sequence folder `out`.
pub fn point_dir(out: &Path, i: usize) -> PathBuf {
    out.join("points").join(point_name(i))
}

/// Version of the program, written with every point.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

impl Plan {
    /// The plan record (`plan.json`): name, axes and their values, zip groups, number of
    /// points, the base scene's hash, the kept products. Shards of one sweep write the same.
    pub fn record(&self) -> serde_json::Value {
        json!({
            "schema_version": 1,
            "name": self.name,
            "sequence_file": self.file.display().to_string(),
            "base_scene": self.src.path.display().to_string(),
            "base_scene_hash": format!("{:016x}", fnv1a64(to_ron(&self.base).as_bytes())),
            "points": self.len(),
            "keep": self.keep,
            "share": self.share,
            "axes": self.axes.iter().map(|a| json!({
                "name": a.name,
                "path": a.path,
                "zip": a.zip,
                "values": a.values,
            })).collect::<Vec<_>>(),
        })
    }

    /// Runs the points of `shard` that are not done into `out` (see the module doc), in index
    /// order, with `settings` (its progress flag drives one bar over the points; the stages
    /// run without theirs). A point that fails is reported and the others go on.
    pub fn run(
        &self,
        out: &Path,
        shard: Shard,
        settings: &RunSettings,
    ) -> Result<SequenceReport, SequenceError> {
        let fail = |message: String| SequenceError {
            at: out.display().to_string(),
            message,
        };
        std::fs::create_dir_all(out.join("points"))
            .map_err(|e| fail(format!("cannot create the folder: {e}")))?;
        let record = self.record();
        let plan_file = out.join("plan.json");
        // The same sweep (axes and base scene) may resume here; another may not.
        if let Ok(old) = std::fs::read_to_string(&plan_file) {
            let old: serde_json::Value = serde_json::from_str(&old).unwrap_or_default();
            let key = |v: &serde_json::Value| {
                (
                    v["axes"].clone(),
                    v["base_scene_hash"].clone(),
                    v["share"].clone(),
                )
            };
            if key(&old) != key(&record) {
                return Err(fail(
                    "holds another sequence's points (plan.json differs in its axes, base scene or `share`): choose a new folder"
                        .into(),
                ));
            }
        } else {
            let text = serde_json::to_string_pretty(&record).expect("json") + "\n";
            write_atomic(&plan_file, text.as_bytes()).map_err(fail)?;
        }
        let merge = self.merges(settings);
        let units = self.units(merge)?;
        let mut rep = SequenceReport::default();
        let mine: Vec<&Vec<usize>> = units
            .iter()
            .enumerate()
            .filter(|(u, _)| shard.owns(*u))
            .map(|(_, p)| p)
            .collect();
        rep.owned = mine.iter().map(|u| u.len()).sum();
        let owned: std::collections::BTreeSet<usize> =
            mine.iter().flat_map(|u| u.iter().copied()).collect();
        remove_stale_staging(&out.join("points"), |i| owned.contains(&i));
        let bar = crate::io::progress::progress_bar(settings.progress, rep.owned as u64, "points");
        let inner = RunSettings {
            progress: false,
            ..settings.clone()
        };
        // Units run side by side (each on the shared thread pool) when that many of the
        // first unit's memory estimate fit under the limit; one after the other otherwise.
        let threads = rayon::current_num_threads().max(1);
        let parallel = threads > 1
            && mine.first().is_some_and(|u| {
                self.unit_estimate(u, &inner)
                    .is_some_and(|b| b.saturating_mul(threads as u64) <= settings.max_memory_bytes)
            });
        let run_one = |unit: &Vec<usize>| -> (Vec<usize>, Vec<usize>, Vec<(usize, String)>) {
            let todo: Vec<usize> = unit
                .iter()
                .copied()
                .filter(|&i| !point_dir(out, i).join("point.json").exists())
                .collect();
            let skipped: Vec<usize> = unit.iter().copied().filter(|i| !todo.contains(i)).collect();
            let res = if todo.is_empty() {
                Ok(())
            } else if unit.len() == 1 {
                self.run_point(unit[0], &point_dir(out, unit[0]), &inner)
            } else {
                self.run_unit(unit, &todo, out, &inner)
            };
            bar.inc(unit.len() as u64);
            match res {
                Ok(()) => (todo, skipped, Vec::new()),
                Err(e) => (
                    Vec::new(),
                    skipped,
                    todo.iter().map(|&i| (i, e.clone())).collect(),
                ),
            }
        };
        let outcomes: Vec<_> = if parallel {
            use rayon::prelude::*;
            mine.par_iter().map(|u| run_one(u)).collect()
        } else {
            mine.iter().map(|u| run_one(u)).collect()
        };
        for (ran, skipped, failed) in outcomes {
            rep.ran.extend(ran);
            rep.skipped.extend(skipped);
            rep.failed.extend(failed);
        }
        bar.finish_and_clear();
        rep.skipped.sort_unstable();
        Ok(rep)
    }

    /// Whether points that differ only in per-band values share runs (see
    /// [`super::merge`]): when the plan allows it (`share`), with flux tracking, when a point
    /// keeps only `summary.json` and `brf.csv` (images, budgets and Maket rasters would mix
    /// the points' bands).
    pub fn merges(&self, settings: &RunSettings) -> bool {
        self.share
            && settings.solver == crate::resources::scene::Solver::FluxTracking
            && self
                .keep
                .iter()
                .all(|k| k == "summary.json" || k == "brf.csv")
    }

    /// The points of `shard` (whole units, see [`Plan::units`]).
    pub fn shard_points(
        &self,
        shard: Shard,
        settings: &RunSettings,
    ) -> Result<Vec<usize>, SequenceError> {
        let units = self.units(self.merges(settings))?;
        let mut v: Vec<usize> = units
            .iter()
            .enumerate()
            .filter(|(u, _)| shard.owns(*u))
            .flat_map(|(_, p)| p.iter().copied())
            .collect();
        v.sort_unstable();
        Ok(v)
    }

    /// The memory estimate (peak over the stages, bytes) of the run of `unit`; `None` when its
    /// scene cannot be planned (the run then reports why).
    fn unit_estimate(&self, unit: &[usize], settings: &RunSettings) -> Option<u64> {
        let desc = if unit.len() == 1 {
            self.point(unit[0]).ok()?.desc
        } else {
            self.merged_scene(unit).ok()?
        };
        let mut sim = Simulation::from_desc(&desc, &self.src, settings.clone()).ok()?;
        sim.memory_plan().ok().map(|m| m.peak_bytes)
    }

    /// Runs the points of `unit` as the bands of one run and writes the products of those in
    /// `todo` (each staged and committed on its own).
    fn run_unit(
        &self,
        unit: &[usize],
        todo: &[usize],
        out: &Path,
        settings: &RunSettings,
    ) -> Result<(), String> {
        let desc = self.merged_scene(unit)?;
        let nb = desc.bands.len() / unit.len();
        let mut sim = self
            .simulation(&desc, settings)
            .map_err(|e| format!("the shared run of points {unit:?}: {e}"))?;
        sim.world
            .insert_resource(crate::resources::scene::ProductSelection(self.keep.clone()));
        let shared = out.join("points").join(format!(
            ".{}.partial-unit-{}",
            point_name(unit[0]),
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&shared);
        let res = (|| -> Result<(), String> {
            sim.run(Some(&shared)).map_err(|e| e.to_string())?;
            let read = |f: &str| std::fs::read_to_string(shared.join(f)).ok();
            let summary = read("summary.json").ok_or("the shared run wrote no summary.json")?;
            let mut summary: serde_json::Value =
                serde_json::from_str(&summary).map_err(|e| e.to_string())?;
            // Each point's copy gets its own bands: the others' are dropped once here.
            let all_bands = summary["bands"].take();
            let brf = read("brf.csv");
            for (k, &i) in unit.iter().enumerate() {
                if !todo.contains(&i) {
                    continue;
                }
                let own: Vec<serde_json::Value> = all_bands
                    .as_array()
                    .map(|b| b.iter().skip(k * nb).take(nb).cloned().collect())
                    .unwrap_or_default();
                summary["bands"] = serde_json::Value::Array(own);
                let (s, csv) = super::merge::split_products(&summary, brf.as_deref(), k, nb, unit)?;
                let p = self.point(i).map_err(|e| e.to_string())?;
                let dir = point_dir(out, i);
                let staged = StagedDir::begin(&dir, false, "--force")?;
                write_atomic(&staged.path().join("summary.json"), s.as_bytes())?;
                if let Some(c) = csv.filter(|_| self.keep.iter().any(|k| k == "brf.csv")) {
                    write_atomic(&staged.path().join("brf.csv"), c.as_bytes())?;
                }
                write_point_json(staged.path(), &p, Some(unit))?;
                staged.commit()?;
            }
            Ok(())
        })();
        let _ = std::fs::remove_dir_all(&shared);
        res
    }

    /// The simulation of `desc` (a point's or a shared run's scene) with its memory plan, refused
    /// when a stage's estimate is above `--max-memory` (as `lumenscape run` does).
    fn simulation(
        &self,
        desc: &crate::scene::desc::SceneDesc,
        settings: &RunSettings,
    ) -> Result<Simulation, String> {
        let mut sim =
            Simulation::from_desc(desc, &self.src, settings.clone()).map_err(|e| e.to_string())?;
        let mem = sim.memory_plan().map_err(|e| e.to_string())?;
        if let Some(s) = mem.over(settings.max_memory_bytes) {
            return Err(format!(
                "the {} stage needs an estimated {} bytes, above the limit of {} bytes (--max-memory)",
                s.stage, s.bytes, settings.max_memory_bytes
            ));
        }
        sim.world.insert_resource(mem);
        Ok(sim)
    }

    /// Runs point `i` into `dir` (staged, committed when complete).
    fn run_point(&self, i: usize, dir: &Path, settings: &RunSettings) -> Result<(), String> {
        let p = self.point(i).map_err(|e| e.to_string())?;
        let mut sim = self.simulation(&p.desc, settings)?;
        // A LiDAR scene's products are what its points are run for: always kept.
        let mut keep = self.keep.clone();
        if p.desc.lidars.as_ref().is_some_and(|l| !l.is_empty())
            && !keep.iter().any(|k| k == "lidar")
        {
            keep.push("lidar".into());
        }
        sim.world
            .insert_resource(crate::resources::scene::ProductSelection(keep.clone()));
        let staged = StagedDir::begin(dir, false, "--force")?;
        sim.run(Some(staged.path())).map_err(|e| e.to_string())?;
        prune(staged.path(), &keep).map_err(|e| format!("{}: {e}", dir.display()))?;
        write_point_json(staged.path(), &p, None)?;
        staged.commit()
    }
}

/// `point.json` (written last into a point's staging folder): index, axis values, scene hash,
/// program version, and the unit it shared a run with.
fn write_point_json(
    dir: &Path,
    p: &super::plan::Point,
    unit: Option<&[usize]>,
) -> Result<(), String> {
    let values: serde_json::Map<String, serde_json::Value> = p.values.iter().cloned().collect();
    let rec = json!({
        "point": p.index,
        "values": values,
        "scene_hash": p.scene_hash,
        "lumenscape_version": VERSION,
        "shared_run_points": unit,
    });
    let text = serde_json::to_string_pretty(&rec).expect("json") + "\n";
    write_atomic(&dir.join("point.json"), text.as_bytes())
}

/// Removes what a point folder should not keep: every top-level entry not named by (or
/// holding) a path of `keep`.
fn prune(dir: &Path, keep: &[String]) -> std::io::Result<()> {
    fn walk(dir: &Path, rel: &str, keep: &[String]) -> std::io::Result<()> {
        for e in std::fs::read_dir(dir)? {
            let e = e?;
            let name = e.file_name().to_string_lossy().into_owned();
            let r = if rel.is_empty() {
                name
            } else {
                format!("{rel}/{name}")
            };
            let kept = keep
                .iter()
                .any(|k| *k == r || k.starts_with(&format!("{r}/")));
            let inside = keep.iter().any(|k| r.starts_with(&format!("{k}/")));
            if inside || kept && keep.contains(&r) {
                continue;
            }
            if kept && e.file_type()?.is_dir() {
                walk(&e.path(), &r, keep)?;
            } else if e.file_type()?.is_dir() {
                std::fs::remove_dir_all(e.path())?;
            } else {
                std::fs::remove_file(e.path())?;
            }
        }
        Ok(())
    }
    walk(dir, "", keep)
}

/// Removes the hidden staging folders (`.pNNNNNN.partial-…`, `.pNNNNNN.old-…`) of the points
/// `owns` accepts: leftovers of a killed run of this shard (other shards' points are left
/// alone: they may be running).
fn remove_stale_staging(points: &Path, owns: impl Fn(usize) -> bool) {
    let Ok(rd) = std::fs::read_dir(points) else {
        return;
    };
    for e in rd.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let idx = name
            .strip_prefix(".p")
            .and_then(|s| s.split_once('.'))
            .filter(|(_, rest)| rest.starts_with("partial-") || rest.starts_with("old-"))
            .and_then(|(n, _)| n.parse::<usize>().ok());
        if let Some(i) = idx
            && owns(i)
        {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}
