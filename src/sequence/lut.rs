//! `gather`: every finished point of a sequence folder (of every shard) into one look-up table,
//! one row per point × band × upward direction, in point order.
//!
//! Columns: `point`, the axes (their values), `band`, the band's scalar products from
//! `summary.json` (`albedo`, `fabs`, `fabs_ground`, `ftran`, … and their `_se` with Monte
//! Carlo), the direction's fields prefixed `view_` (`view_kind`, `view_zenith_deg`,
//! `view_azimuth_deg`, `view_solid_angle_sr`, `view_brf`, …), then `scene_hash` and
//! `lumenscape_version`. Only products are read (no timings), so the table is the same byte
//! for byte however the points were split between shards and processes.

use super::run::point_dir;
use crate::io::atomic::write_atomic;
use serde_json::Value;
use std::collections::BTreeSet;
use std::path::Path;

/// What `gather` found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GatherReport {
    /// Points in the plan.
    pub points: usize,
    /// Points found finished (in the table).
    pub finished: usize,
    /// Points not finished (not in the table).
    pub missing: Vec<usize>,
    /// Rows written.
    pub rows: usize,
}

fn read_json(path: &Path) -> Result<Value, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// A value as CSV text: numbers as JSON writes them (shortest round trip), strings quoted when
/// needed, other values as JSON.
fn cell(v: &Value) -> String {
    match v {
        Value::Null => String::new(),
        Value::String(s) => {
            if s.contains([',', '"', '\n']) {
                format!("\"{}\"", s.replace('"', "\"\""))
            } else {
                s.clone()
            }
        }
        Value::Number(_) | Value::Bool(_) => v.to_string(),
        _ => {
            let s = v.to_string();
            format!("\"{}\"", s.replace('"', "\"\""))
        }
    }
}

/// Scalar fields of an object (numbers, strings, booleans), other than `skip`.
fn scalars<'a>(o: &'a Value, skip: &'a [&str]) -> impl Iterator<Item = (&'a String, &'a Value)> {
    o.as_object()
        .into_iter()
        .flat_map(|m| m.iter())
        .filter(move |(k, v)| {
            !skip.contains(&k.as_str())
                && matches!(v, Value::Number(_) | Value::String(_) | Value::Bool(_))
        })
}

/// Gathers the sequence folder `dir` into `table` (CSV). Fails on a folder without `plan.json`
/// or on a finished point whose files cannot be read; unfinished points are reported.
pub fn gather(dir: &Path, table: &Path) -> Result<GatherReport, String> {
    let plan = read_json(&dir.join("plan.json")).map_err(|e| {
        format!(
            "{e} (is {} a sequence folder? `lumenscape sequence` writes plan.json)",
            dir.display()
        )
    })?;
    let n = plan["points"].as_u64().ok_or("plan.json: no `points`")? as usize;
    let axes: Vec<String> = plan["axes"]
        .as_array()
        .ok_or("plan.json: no `axes`")?
        .iter()
        .map(|a| a["name"].as_str().unwrap_or("").to_string())
        .collect();
    let mut rep = GatherReport {
        points: n,
        ..Default::default()
    };
    let mut points = Vec::new();
    for i in 0..n {
        let pd = point_dir(dir, i);
        if !pd.join("point.json").exists() {
            rep.missing.push(i);
            continue;
        }
        points.push((
            i,
            read_json(&pd.join("point.json"))?,
            read_json(&pd.join("summary.json"))?,
        ));
    }
    rep.finished = points.len();
    // Columns: the union over every row, sorted (independent of which shard wrote what).
    let (mut band_cols, mut view_cols) = (BTreeSet::new(), BTreeSet::new());
    for (_, _, s) in &points {
        for b in s["bands"].as_array().into_iter().flatten() {
            band_cols.extend(scalars(b, &["band"]).map(|(k, _)| k.clone()));
            for e in b["brf"].as_array().into_iter().flatten() {
                view_cols.extend(scalars(e, &[]).map(|(k, _)| k.clone()));
            }
        }
    }
    let mut csv = String::from("point");
    for a in &axes {
        csv += &format!(",{}", cell(&Value::from(a.as_str())));
    }
    csv += ",band";
    for c in &band_cols {
        csv += &format!(",{c}");
    }
    for c in &view_cols {
        csv += &format!(",view_{c}");
    }
    csv += ",scene_hash,lumenscape_version\n";
    for (i, p, s) in &points {
        let mut head = i.to_string();
        for a in &axes {
            head += &format!(",{}", cell(&p["values"][a]));
        }
        let tail = format!(
            ",{},{}\n",
            cell(&p["scene_hash"]),
            cell(&p["lumenscape_version"])
        );
        for b in s["bands"].as_array().into_iter().flatten() {
            let mut band = format!("{head},{}", cell(&b["band"]));
            for c in &band_cols {
                band += &format!(",{}", cell(&b[c]));
            }
            for e in b["brf"].as_array().into_iter().flatten() {
                csv += &band;
                for c in &view_cols {
                    csv += &format!(",{}", cell(&e[c]));
                }
                csv += &tail;
                rep.rows += 1;
            }
        }
    }
    write_atomic(table, csv.as_bytes())?;
    Ok(rep)
}
