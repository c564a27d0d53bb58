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

/// Rows written per Parquet row group (and CSV flush): memory stays bounded by one batch, not
/// by the table (a 10 000-point sweep has ~10⁶ rows).
const BATCH_ROWS: usize = 1 << 16;

/// The table's columns: names and whether each holds only numbers (and nulls).
struct Layout {
    axes: Vec<String>,
    band_cols: Vec<String>,
    view_cols: Vec<String>,
    names: Vec<String>,
    numeric: Vec<bool>,
}

impl Layout {
    /// The rows of one point: `[point, axes…, band, band scalars…, view fields…, hash, version]`.
    fn rows(&self, i: usize, p: &Value, s: &Value) -> Vec<Vec<Value>> {
        let mut rows = Vec::new();
        let mut head = vec![Value::from(i)];
        head.extend(self.axes.iter().map(|a| p["values"][a].clone()));
        for b in s["bands"].as_array().into_iter().flatten() {
            let mut band = head.clone();
            band.push(b["band"].clone());
            band.extend(self.band_cols.iter().map(|c| b[c].clone()));
            for e in b["brf"].as_array().into_iter().flatten() {
                let mut row = band.clone();
                row.extend(self.view_cols.iter().map(|c| e[c].clone()));
                row.push(p["scene_hash"].clone());
                row.push(p["lumenscape_version"].clone());
                rows.push(row);
            }
        }
        rows
    }
}

/// Gathers the sequence folder `dir` into `table` (CSV) and the same table as Parquet next to
/// it (`table` with the extension `.parquet`), in point order. Two passes over the points'
/// files: the columns (the union over every point, sorted, so independent of which shard
/// wrote what) and their types, then the rows, written in batches of 65 536 (`BATCH_ROWS`). Fails on a
/// folder without `plan.json` or on a finished point whose files cannot be read; unfinished
/// points are reported.
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
    let mut done = Vec::new();
    for i in 0..n {
        let pd = point_dir(dir, i);
        if !pd.join("point.json").exists() {
            rep.missing.push(i);
        } else if !pd.join("summary.json").exists() {
            // A LiDAR-only point: no passive products (its LiDAR products are in its folder).
            rep.no_passive.push(i);
        } else {
            done.push(i);
        }
    }
    rep.finished = done.len() + rep.no_passive.len();
    let read = |i: usize| -> Result<(Value, Value), String> {
        let pd = point_dir(dir, i);
        Ok((
            read_json(&pd.join("point.json"))?,
            read_json(&pd.join("summary.json"))?,
        ))
    };
    // Pass 1: the columns and which of them hold text.
    let (mut band_cols, mut view_cols) = (BTreeSet::new(), BTreeSet::new());
    let mut text_cols: BTreeSet<String> = BTreeSet::new();
    let is_text = |v: &Value| !(v.is_number() || v.is_null());
    for &i in &done {
        let (p, s) = read(i)?;
        for a in &axes {
            if is_text(&p["values"][a]) {
                text_cols.insert(a.clone());
            }
        }
        for b in s["bands"].as_array().into_iter().flatten() {
            for (k, v) in scalars(b, &["band"]) {
                band_cols.insert(k.clone());
                if is_text(v) {
                    text_cols.insert(k.clone());
                }
            }
            for e in b["brf"].as_array().into_iter().flatten() {
                for (k, v) in scalars(e, &[]) {
                    view_cols.insert(k.clone());
                    if is_text(v) {
                        text_cols.insert(format!("view_{k}"));
                    }
                }
            }
        }
    }
    let mut names: Vec<String> = vec!["point".into()];
    names.extend(axes.iter().cloned());
    names.push("band".into());
    names.extend(band_cols.iter().cloned());
    names.extend(view_cols.iter().map(|c| format!("view_{c}")));
    names.extend(["scene_hash".to_string(), "lumenscape_version".to_string()]);
    let fixed_text = ["band", "scene_hash", "lumenscape_version"];
    let numeric = names
        .iter()
        .enumerate()
        .map(|(c, n)| c == 0 || !(text_cols.contains(n) || fixed_text.contains(&n.as_str())))
        .collect();
    let layout = Layout {
        axes,
        band_cols: band_cols.into_iter().collect(),
        view_cols: view_cols.into_iter().collect(),
        names,
        numeric,
    };
    // Pass 2: the rows, as CSV and as Parquet row groups.
    let pq_path = table.with_extension("parquet");
    let pq_tmp = crate::io::atomic::tmp_path(&pq_path);
    let pq_file = std::fs::File::create(&pq_tmp)
        .map_err(|e| format!("{}: cannot write: {e}", pq_path.display()))?;
    let mut pq = ParquetTable::new(pq_file, &layout)?;
    let mut rows_out = 0usize;
    let res = crate::io::atomic::write_atomic_with(table, |w| {
        use std::io::Write;
        let io = |e: String| std::io::Error::other(e);
        let head: Vec<String> = layout
            .names
            .iter()
            .map(|n| cell(&Value::from(n.as_str())))
            .collect();
        writeln!(w, "{}", head.join(","))?;
        let mut batch: Vec<Vec<Value>> = Vec::new();
        for &i in &done {
            let (p, s) = read(i).map_err(io)?;
            for r in layout.rows(i, &p, &s) {
                let line: Vec<String> = r.iter().map(cell).collect();
                writeln!(w, "{}", line.join(","))?;
                batch.push(r);
            }
            if batch.len() >= BATCH_ROWS {
                rows_out += batch.len();
                pq.write(&batch).map_err(io)?;
                batch.clear();
            }
        }
        rows_out += batch.len();
        if !batch.is_empty() || rows_out == 0 {
            pq.write(&batch).map_err(io)?;
        }
        Ok(())
    });
    let finish = res.and_then(|()| {
        pq.close()?;
        std::fs::rename(&pq_tmp, &pq_path)
            .map_err(|e| format!("{}: cannot write: {e}", pq_path.display()))
    });
    if let Err(e) = finish {
        let _ = std::fs::remove_file(&pq_tmp);
        return Err(e);
    }
    rep.rows = rows_out;
    Ok(rep)
}

/// The table as a Parquet file (Apache Parquet, uncompressed, a row group per batch): a column
/// of JSON numbers is `DOUBLE` (`point`: `INT64`), any other column UTF-8 text (strings as they
/// are, other values as JSON); missing values are nulls. Readable by pandas, polars, DuckDB and
/// Arrow.
struct ParquetTable {
    writer: parquet::file::writer::SerializedFileWriter<std::io::BufWriter<std::fs::File>>,
    numeric: Vec<bool>,
}

impl ParquetTable {
    fn new(file: std::fs::File, layout: &Layout) -> Result<Self, String> {
        use parquet::file::properties::WriterProperties;
        use std::sync::Arc;
        let field = |c: usize| -> String {
            // Parquet schema names: the column name with characters outside [A-Za-z0-9_] as `_`.
            let n: String = layout.names[c]
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
            } else if layout.numeric[c] {
                format!("optional double {n};")
            } else {
                format!("optional binary {n} (UTF8);")
            }
        };
        let schema = format!(
            "message lut {{ {} }}",
            (0..layout.names.len())
                .map(field)
                .collect::<Vec<_>>()
                .join(" ")
        );
        let schema = Arc::new(
            parquet::schema::parser::parse_message_type(&schema).map_err(|e| e.to_string())?,
        );
        let props = Arc::new(WriterProperties::builder().build());
        let writer = parquet::file::writer::SerializedFileWriter::new(
            std::io::BufWriter::new(file),
            schema,
            props,
        )
        .map_err(|e| e.to_string())?;
        Ok(Self {
            writer,
            numeric: layout.numeric.clone(),
        })
    }

    /// Writes `rows` as one row group.
    fn write(&mut self, rows: &[Vec<Value>]) -> Result<(), String> {
        use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int64Type};
        let mut rg = self.writer.next_row_group().map_err(|e| e.to_string())?;
        let mut c = 0;
        while let Some(mut col) = rg.next_column().map_err(|e| e.to_string())? {
            let defs: Vec<i16> = rows.iter().map(|r| i16::from(!r[c].is_null())).collect();
            if c == 0 {
                let v: Vec<i64> = rows.iter().map(|r| r[0].as_i64().unwrap_or(0)).collect();
                col.typed::<Int64Type>().write_batch(&v, None, None)
            } else if self.numeric[c] {
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
        Ok(())
    }

    /// Writes the footer and flushes the file to disk.
    fn close(self) -> Result<(), String> {
        let w = self.writer.into_inner().map_err(|e| e.to_string())?;
        let f = w.into_inner().map_err(|e| e.to_string())?;
        f.sync_all().map_err(|e| e.to_string())
    }
}
