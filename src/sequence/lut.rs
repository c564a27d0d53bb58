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
    /// Points found finished (those with passive products are in the table).
    pub finished: usize,
    /// Finished points without passive products (LiDAR-only scenes; not in the table).
    pub no_passive: Vec<usize>,
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

/// Gathers the sequence folder `dir` into `table` (CSV) and the same table as Parquet next to
/// it (`table` with the extension `.parquet`). Fails on a folder without `plan.json` or on a
/// finished point whose files cannot be read; unfinished points are reported.
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
        if !pd.join("summary.json").exists() {
            // A LiDAR-only point: no passive products (its LiDAR products are in its folder).
            rep.no_passive.push(i);
            continue;
        }
        points.push((
            i,
            read_json(&pd.join("point.json"))?,
            read_json(&pd.join("summary.json"))?,
        ));
    }
    rep.finished = points.len() + rep.no_passive.len();
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
    // The rows as JSON values under their column names, written as CSV and as Parquet.
    let mut names: Vec<String> = vec!["point".into()];
    names.extend(axes.iter().cloned());
    names.push("band".into());
    names.extend(band_cols.iter().cloned());
    names.extend(view_cols.iter().map(|c| format!("view_{c}")));
    names.extend(["scene_hash".to_string(), "lumenscape_version".to_string()]);
    let mut rows: Vec<Vec<Value>> = Vec::new();
    for (i, p, s) in &points {
        let mut head = vec![Value::from(*i)];
        head.extend(axes.iter().map(|a| p["values"][a].clone()));
        for b in s["bands"].as_array().into_iter().flatten() {
            let mut band = head.clone();
            band.push(b["band"].clone());
            band.extend(band_cols.iter().map(|c| b[c].clone()));
            for e in b["brf"].as_array().into_iter().flatten() {
                let mut row = band.clone();
                row.extend(view_cols.iter().map(|c| e[c].clone()));
                row.push(p["scene_hash"].clone());
                row.push(p["lumenscape_version"].clone());
                rows.push(row);
            }
        }
    }
    rep.rows = rows.len();
    let mut csv = names
        .iter()
        .map(|n| cell(&Value::from(n.as_str())))
        .collect::<Vec<_>>()
        .join(",");
    csv.push('\n');
    for r in &rows {
        csv += &r.iter().map(cell).collect::<Vec<_>>().join(",");
        csv.push('\n');
    }
    let parquet = parquet_table(&names, &rows).map_err(|e| format!("Parquet table: {e}"))?;
    write_atomic(&table.with_extension("parquet"), &parquet)?;
    write_atomic(table, csv.as_bytes())?;
    Ok(rep)
}

/// The table as a Parquet file (Apache Parquet format 2, one row group, uncompressed): a
/// column of JSON numbers is `DOUBLE` (`point`: `INT64`), any other column UTF-8 text (strings
/// as they are, other values as JSON); missing values are nulls. Readable by pandas, polars,
/// DuckDB and Arrow.
pub fn parquet_table(names: &[String], rows: &[Vec<Value>]) -> Result<Vec<u8>, String> {
    use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int64Type};
    use parquet::file::properties::WriterProperties;
    use parquet::file::writer::SerializedFileWriter;
    use std::sync::Arc;
    let numeric: Vec<bool> = (0..names.len())
        .map(|c| rows.iter().all(|r| r[c].is_number() || r[c].is_null()))
        .collect();
    let field = |c: usize| -> String {
        // Parquet schema names: the column name with characters outside [A-Za-z0-9_] as `_`.
        let n: String = names[c]
            .chars()
            .map(|ch| {
                if ch.is_ascii_alphanumeric() || ch == '_' {
                    ch
                } else {
                    '_'
                }
            })
            .collect();
        if c == 0 {
            format!("required int64 {n};")
        } else if numeric[c] {
            format!("optional double {n};")
        } else {
            format!("optional binary {n} (UTF8);")
        }
    };
    let schema = format!(
        "message lut {{ {} }}",
        (0..names.len()).map(field).collect::<Vec<_>>().join(" ")
    );
    let schema =
        Arc::new(parquet::schema::parser::parse_message_type(&schema).map_err(|e| e.to_string())?);
    let props = Arc::new(WriterProperties::builder().build());
    let mut buf = Vec::new();
    let mut w = SerializedFileWriter::new(&mut buf, schema, props).map_err(|e| e.to_string())?;
    let mut rg = w.next_row_group().map_err(|e| e.to_string())?;
    let mut c = 0;
    while let Some(mut col) = rg.next_column().map_err(|e| e.to_string())? {
        let defs: Vec<i16> = rows.iter().map(|r| i16::from(!r[c].is_null())).collect();
        if c == 0 {
            let v: Vec<i64> = rows.iter().map(|r| r[0].as_i64().unwrap_or(0)).collect();
            col.typed::<Int64Type>().write_batch(&v, None, None)
        } else if numeric[c] {
            let v: Vec<f64> = rows.iter().filter_map(|r| r[c].as_f64()).collect();
            col.typed::<DoubleType>().write_batch(&v, Some(&defs), None)
        } else {
            let v: Vec<ByteArray> = rows
                .iter()
                .filter(|r| !r[c].is_null())
                .map(|r| match &r[c] {
                    Value::String(s) => ByteArray::from(s.as_str()),
                    other => ByteArray::from(other.to_string().as_str()),
                })
                .collect();
            col.typed::<ByteArrayType>()
                .write_batch(&v, Some(&defs), None)
        }
        .map_err(|e| e.to_string())?;
        col.close().map_err(|e| e.to_string())?;
        c += 1;
    }
    rg.close().map_err(|e| e.to_string())?;
    w.close().map_err(|e| e.to_string())?;
    Ok(buf)
}
