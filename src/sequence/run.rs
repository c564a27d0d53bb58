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
            let key = |v: &serde_json::Value| (v["axes"].clone(), v["base_scene_hash"].clone());
            if key(&old) != key(&record) {
                return Err(fail(
                    "holds another sequence's points (plan.json differs in its axes or base scene): choose a new folder"
                        .into(),
                ));
            }
        } else {
            let text = serde_json::to_string_pretty(&record).expect("json") + "\n";
            write_atomic(&plan_file, text.as_bytes()).map_err(fail)?;
        }
        let n = self.len();
        let mut rep = SequenceReport::default();
        let mine: Vec<usize> = (0..n).filter(|&i| shard.owns(i)).collect();
        rep.owned = mine.len();
        remove_stale_staging(&out.join("points"), shard);
        let bar = crate::io::progress::progress_bar(settings.progress, mine.len() as u64, "points");
        let inner = RunSettings {
            progress: false,
            ..settings.clone()
        };
        for i in mine {
            let dir = point_dir(out, i);
            if dir.join("point.json").exists() {
                rep.skipped.push(i);
                bar.inc(1);
                continue;
            }
            match self.run_point(i, &dir, &inner) {
                Ok(()) => rep.ran.push(i),
                Err(e) => rep.failed.push((i, e)),
            }
            bar.inc(1);
        }
        bar.finish_and_clear();
        Ok(rep)
    }

    /// Runs point `i` into `dir` (staged, committed when complete).
    fn run_point(&self, i: usize, dir: &Path, settings: &RunSettings) -> Result<(), String> {
        let p = self.point(i).map_err(|e| e.to_string())?;
        let mut sim = Simulation::from_desc(&p.desc, &self.src, settings.clone())
            .map_err(|e| e.to_string())?;
        let mem = sim.memory_plan().map_err(|e| e.to_string())?;
        if let Some(s) = mem.over(settings.max_memory_bytes) {
            return Err(format!(
                "the {} stage needs an estimated {} bytes, above the limit of {} bytes (--max-memory)",
                s.stage, s.bytes, settings.max_memory_bytes
            ));
        }
        sim.world.insert_resource(mem);
        sim.world
            .insert_resource(crate::resources::scene::ProductSelection(self.keep.clone()));
        let staged = StagedDir::begin(dir, false, "--force")?;
        sim.run(Some(staged.path())).map_err(|e| e.to_string())?;
        prune(staged.path(), &self.keep).map_err(|e| format!("{}: {e}", dir.display()))?;
        let values: serde_json::Map<String, serde_json::Value> = p.values.into_iter().collect();
        let rec = json!({
            "point": i,
            "values": values,
            "scene_hash": p.scene_hash,
            "lumenscape_version": VERSION,
        });
        let text = serde_json::to_string_pretty(&rec).expect("json") + "\n";
        write_atomic(&staged.path().join("point.json"), text.as_bytes())?;
        staged.commit()
    }
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

/// Removes the hidden staging folders (`.pNNNNNN.partial-PID`, `.pNNNNNN.old-PID`) of points
/// that `shard` owns: leftovers of a killed run of this shard (other shards' points are left
/// alone: they may be running).
fn remove_stale_staging(points: &Path, shard: Shard) {
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
            && shard.owns(i)
        {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}
