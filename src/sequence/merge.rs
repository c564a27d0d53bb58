//! Points that differ only in per-band values — the optics lists, `ProspectLeaf` parameters
//! (resolved to per-band values first), the sky fraction and irradiance per band — run as the
//! bands of one flux-tracking run: DART's remark that one N-band run is far cheaper than N
//! one-band runs (DART 5 paper §2), since the geometry (Maket grid, directions, phase tables,
//! the rays' paths) is the same for every band.
//!
//! The units (points run together) depend on the whole plan only, not on which points are done
//! or on the shard, so that a point's products are the same however the sweep was split,
//! interrupted and resumed. A unit holds at most [`MAX_BANDS`] bands.
//!
//! What differs from a point run on its own: the tracker stops a ray when its power summed over
//! the channels falls below the threshold and stops iterating when the albedo summed over the
//! channels has converged (`radiative::engine::iterate`), so the bands of other points change
//! where those stops fall: the products agree with a standalone run within the tracking's own
//! tolerance, not bit for bit (tests/sequence.rs states the bound).

use super::plan::{Plan, SequenceError};
use crate::resources::materials::prospect_leaf_bands;
use crate::scene::SceneSource;
use crate::scene::desc::SceneDesc;
use crate::scene::resolve::band_responses;
use serde_json::Value;
use std::collections::BTreeMap;

/// Most bands of one shared run (memory of the stores grows with the channels).
pub const MAX_BANDS: usize = 128;

/// The scene as a JSON tree with every `ProspectLeaf` replaced by the `BiLambertian` values
/// PROSPECT gives in the scene's bands (the numbers the Maket's materials would compute).
fn band_form(desc: &SceneDesc, src: &SceneSource) -> Result<Value, String> {
    let mut tree = serde_json::to_value(desc).map_err(|e| e.to_string())?;
    if desc.optics.values().any(|o| o.prospect_params().is_some()) {
        let responses = band_responses(desc, src).map_err(|e| e.to_string())?;
        let names: Vec<String> = desc.bands.iter().map(|b| b.name.clone()).collect();
        for (name, o) in &desc.optics {
            if let Some((model, params)) = o.prospect_params() {
                let (r, t) = prospect_leaf_bands(model, &params, &responses, &names)?;
                tree["optics"][name] = serde_json::json!({
                    "BiLambertian": {"reflectance": r, "transmittance": t}
                });
            }
        }
    }
    Ok(tree)
}

/// Visits every list of numbers under `v` (depth first, in key order).
fn number_lists<'a>(v: &'a mut Value, f: &mut dyn FnMut(&'a mut Vec<Value>)) {
    match v {
        Value::Array(a) => {
            if !a.is_empty() && a.iter().all(Value::is_number) {
                f(a)
            } else {
                a.iter_mut().for_each(|x| number_lists(x, f))
            }
        }
        Value::Object(m) => m.values_mut().for_each(|x| number_lists(x, f)),
        _ => {}
    }
}

/// The per-band lists of a band-form tree: every list of numbers in `optics`, and the sky
/// fraction and irradiance lists.
fn band_lists(tree: &mut Value) -> Vec<&mut Vec<Value>> {
    let mut out = Vec::new();
    let (optics, illum) = match tree {
        Value::Object(m) => {
            let mut o = None;
            let mut i = None;
            for (k, v) in m.iter_mut() {
                match k.as_str() {
                    "optics" => o = Some(v),
                    "illumination" => i = Some(v),
                    _ => {}
                }
            }
            (o, i)
        }
        _ => (None, None),
    };
    if let Some(o) = optics {
        number_lists(o, &mut |a| out.push(a));
    }
    if let Some(Value::Object(m)) = illum {
        for (k, v) in m.iter_mut() {
            if let ("skyl" | "irradiance_w_m2_um", Value::Array(a)) = (k.as_str(), v)
                && !a.is_empty()
            {
                out.push(a);
            }
        }
    }
    out
}

/// The merge key of a band-form tree: the tree with every per-band list replaced by its length
/// (`None` when a list's length is not the band count: such a scene runs alone).
/// A `ProspectLeaf`'s parameters count as per-band values (they become the band lists of a
/// `BiLambertian` in [`band_form`]), so its numbers are left out of the key too.
fn key(tree: &Value, nb: usize) -> Option<String> {
    let mut t = tree.clone();
    let mut ok = true;
    if let Some(Value::Object(optics)) = t.get_mut("optics") {
        for o in optics.values_mut() {
            if let Some(Value::Object(p)) = o.get_mut("ProspectLeaf") {
                for v in p.values_mut().filter(|v| v.is_number()) {
                    *v = Value::Null;
                }
            }
        }
    }
    for a in band_lists(&mut t) {
        ok &= a.len() == nb;
        *a = vec![Value::from(a.len())];
    }
    ok.then(|| t.to_string())
}

impl Plan {
    /// The run units: groups of points that share one run (see the module doc) when `merge`,
    /// else one point each; in order of their first point.
    pub fn units(&self, merge: bool) -> Result<Vec<Vec<usize>>, SequenceError> {
        let n = self.len();
        if !merge {
            return Ok((0..n).map(|i| vec![i]).collect());
        }
        let mut groups: Vec<Vec<usize>> = Vec::new();
        let mut by_key: BTreeMap<String, usize> = BTreeMap::new();
        for i in 0..n {
            // The scene read back through serde (its canonical tree), unvalidated: `check`
            // validated every point.
            let (_, desc) = self.scene(i)?;
            let nb = desc.bands.len();
            let k = if desc.lidars.as_ref().is_some_and(|l| !l.is_empty()) || nb == 0 {
                None
            } else {
                let tree = serde_json::to_value(&desc).map_err(|e| SequenceError {
                    at: self.file.display().to_string(),
                    message: format!("point {i}: {e}"),
                })?;
                key(&tree, nb)
            };
            let cap = (MAX_BANDS / nb.max(1)).max(1);
            match k.as_ref().and_then(|k| by_key.get(k)) {
                Some(&g) if groups[g].len() < cap => groups[g].push(i),
                _ => {
                    if let Some(k) = k {
                        by_key.insert(k, groups.len());
                    }
                    groups.push(vec![i]);
                }
            }
        }
        Ok(groups)
    }

    /// The scene that runs the points of `unit` as the bands of one run: the first point's
    /// scene with the bands of every point (`NAME~k` for the unit's k-th point) and every
    /// per-band list the concatenation of the points' lists.
    pub(super) fn merged_scene(&self, unit: &[usize]) -> Result<SceneDesc, String> {
        let mut trees = Vec::with_capacity(unit.len());
        for &i in unit {
            // The merged scene is validated below as a whole.
            let (_, desc) = self.scene(i).map_err(|e| e.to_string())?;
            trees.push(band_form(&desc, &self.src)?);
        }
        let mut merged = trees[0].clone();
        let bands: Vec<Value> = trees
            .iter()
            .enumerate()
            .flat_map(|(k, t)| {
                t["bands"]
                    .as_array()
                    .cloned()
                    .unwrap_or_default()
                    .into_iter()
                    .map(move |mut b| {
                        let name = b["name"].as_str().unwrap_or("").to_string();
                        b["name"] = Value::from(format!("{name}~{k}"));
                        b
                    })
            })
            .collect();
        merged["bands"] = Value::Array(bands);
        let mut rest: Vec<Vec<Vec<Value>>> = trees[1..]
            .iter_mut()
            .map(|t| band_lists(t).into_iter().map(|a| a.clone()).collect())
            .collect();
        for (l, a) in band_lists(&mut merged).into_iter().enumerate() {
            for r in &mut rest {
                a.append(&mut r[l]);
            }
        }
        let desc: SceneDesc = serde_json::from_value(merged).map_err(|e| e.to_string())?;
        crate::scene::validate::validate(&desc, &self.src).map_err(|e| e.to_string())?;
        Ok(desc)
    }
}

/// The products of the unit's `k`-th point (`nb` bands) from the shared run's `summary.json`
/// (parsed) and `brf.csv` text: its bands, with their own names; `points` is the unit.
pub(super) fn split_products(
    summary: &Value,
    brf_csv: Option<&str>,
    k: usize,
    nb: usize,
    points: &[usize],
) -> Result<(String, Option<String>), String> {
    let mut s = summary.clone();
    let suffix = format!("~{k}");
    let own = |name: &str| name.strip_suffix(&suffix).map(str::to_string);
    let bands: Vec<Value> = s["bands"]
        .as_array()
        .ok_or("summary.json without bands")?
        .iter()
        .filter_map(|b| {
            let name = own(b["band"].as_str()?)?;
            let mut b = b.clone();
            b["band"] = Value::from(name);
            Some(b)
        })
        .collect();
    if bands.len() != nb {
        return Err(format!(
            "the shared run's summary has {} bands for point {k} of its unit, not {nb}",
            bands.len()
        ));
    }
    s["bands"] = Value::Array(bands);
    s["shared_run"] = serde_json::json!({
        "points": points,
        "bands": nb * points.len(),
        "note": "run as bands of one flux-tracking run with these points (docs/guide/sequences.md)",
    });
    let csv = brf_csv.map(|text| {
        let mut out = String::new();
        for (n, line) in text.lines().enumerate() {
            if n == 0 {
                out += line;
                out.push('\n');
                continue;
            }
            if let Some((band, rest)) = line.split_once(',')
                && let Some(name) = own(band)
            {
                out += &format!("{name},{rest}\n");
            }
        }
        out
    });
    Ok((
        serde_json::to_string_pretty(&s).map_err(|e| e.to_string())?,
        csv,
    ))
}
