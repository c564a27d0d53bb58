//! The memory estimate of a run, per stage (resource `MemoryPlan`, made by
//! [`crate::memory::estimate`] before anything big is allocated), and the process's resident
//! set read from the system (`VmRSS`, `VmHWM`) to set the baseline and to record the measured
//! peak beside the estimate (`summary.json`, `lidar.json`: [`MemoryPlan::record`]).

use bevy_ecs::prelude::Resource;
use serde::Serialize;

/// Resident memory of the process before any scene-dependent allocation, bytes, where the
/// system does not report the current resident set: the binary's code and data pages, the
/// Rust and C runtimes, the allocator's arenas, the worker threads' stacks and the ECS world
/// (measured on the smallest example scenes, whose heap stays below 3 MiB: 12.2–12.4 MiB
/// peaks, less their modelled terms; docs/performance.md "Memory").
pub const BASELINE_BYTES: u64 = 23 << 19;

/// What the process adds to its resident set after the estimate (`VmRSS` after loading the
/// scene, before planning the grid) besides the stages' own data, bytes, with the flux-tracking
/// solver: the code of the stages still to run (the walks' instruction-set variants are the
/// largest part), the worker threads' stacks and allocator arenas, the libraries' lazy tables
/// (measured on the smallest example scenes; docs/performance.md "Memory").
pub const BASELINE_GROWTH_BYTES: u64 = 2 << 20;

/// [`BASELINE_GROWTH_BYTES`] of runs without the flux tracking (Monte Carlo solver, LiDAR-only
/// scenes): less code is touched (measured on the smallest example scenes).
pub const BASELINE_GROWTH_NO_FLUX_BYTES: u64 = 3 << 19;

/// The process baseline from `rss` (the resident set before planning, [`current_rss_bytes`]):
/// `rss` plus the growth still to come ([`BASELINE_GROWTH_BYTES`], or
/// [`BASELINE_GROWTH_NO_FLUX_BYTES`] when no flux tracking runs), or [`BASELINE_BYTES`] where
/// the system does not report it.
pub fn baseline_bytes(rss: Option<u64>, flux_tracking: bool) -> u64 {
    let growth = if flux_tracking {
        BASELINE_GROWTH_BYTES
    } else {
        BASELINE_GROWTH_NO_FLUX_BYTES
    };
    rss.map_or(BASELINE_BYTES, |b| b + growth)
}

/// One named term of a stage's estimate.
#[derive(Debug, Clone, Serialize)]
pub struct MemoryTerm {
    /// What the term is (see the stage's `memory_terms` documentation).
    pub name: String,
    /// Bytes.
    pub bytes: u64,
}

/// The estimate of one stage: everything resident while it runs.
#[derive(Debug, Clone, Serialize)]
pub struct StageMemory {
    /// Stage: `Maket`, `Radiative` (with Direction and Phase), `Photon`, `LiDAR` or `Output`.
    pub stage: String,
    /// Resident bytes during the stage (the sum of `terms`).
    pub bytes: u64,
    /// The terms, including the baseline and what earlier stages hold.
    pub terms: Vec<MemoryTerm>,
}

/// The memory estimate of a run: per stage and the peak over the stages (resource inserted by
/// `lumenscape run`, written into `summary.json`).
#[derive(Debug, Clone, Serialize, Resource)]
pub struct MemoryPlan {
    /// Process baseline, bytes ([`baseline_bytes`]).
    pub baseline_bytes: u64,
    /// Worker threads the estimate assumes.
    pub threads: usize,
    /// Stages that will run, in order.
    pub stages: Vec<StageMemory>,
    /// Largest stage estimate, bytes.
    pub peak_bytes: u64,
    /// The stage of the peak.
    pub peak_stage: String,
}

impl MemoryPlan {
    /// The first stage whose estimate is above `limit` bytes, if any.
    pub fn over(&self, limit: u64) -> Option<&StageMemory> {
        self.stages.iter().find(|s| s.bytes > limit)
    }

    /// The `memory` record of `summary.json` (and of `lidar.json`): the estimate per stage
    /// and its peak, and the peak resident set measured so far ([`peak_rss_bytes`]; `null`
    /// where the system does not report it).
    pub fn record(&self) -> serde_json::Value {
        serde_json::json!({
            "estimate_peak_bytes": self.peak_bytes,
            "estimate_peak_stage": self.peak_stage,
            "measured_peak_rss_bytes": peak_rss_bytes(),
            "threads": self.threads,
            "baseline_bytes": self.baseline_bytes,
            "stages": self.stages.iter().map(|s| serde_json::json!({
                "stage": s.stage,
                "bytes": s.bytes,
                "terms": s.terms.iter().map(|t| serde_json::json!({
                    "name": t.name,
                    "bytes": t.bytes,
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        })
    }
}

/// The peak resident set of this process so far (`VmHWM` of `/proc/self/status`), bytes;
/// `None` where that file does not exist (other systems than Linux).
pub fn peak_rss_bytes() -> Option<u64> {
    proc_status_kb("VmHWM:")
}

/// The current resident set of this process (`VmRSS` of `/proc/self/status`), bytes; `None`
/// where that file does not exist.
pub fn current_rss_bytes() -> Option<u64> {
    proc_status_kb("VmRSS:")
}

/// A `kB` field of `/proc/self/status`, bytes.
fn proc_status_kb(key: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(key))?;
    let kb: u64 = line
        .trim_start_matches(key)
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024)
}
