//! A sequence's plan: the axes resolved against the base scene, the points they span (built on
//! demand: a plan of 10⁵ points holds 10⁵ numbers per axis, not 10⁵ scenes) and the shards
//! that split them between processes.
//!
//! A point's scene is the base scene with each axis's field set to the point's value: the base
//! description goes through serde's data model as a JSON tree (`serde_json::Value`), the
//! fields are set there, and the tree is read back into a [`SceneDesc`] and validated like a
//! scene file. A path that does not exist, or a value of another type than the field's, is an
//! error naming the sequence file, the axis's line and the path.

use super::desc::{AxisDesc, SEQUENCE_FORMAT_VERSION, SequenceDesc};
use crate::scene::desc::SceneDesc;
use crate::scene::locate::{Seg, parse_path};
use crate::scene::{SceneSource, load_scene, to_ron, validate::validate};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Most points one sequence may span (a larger plan is almost certainly a mistake in a range's
/// `steps`; split it into several sequences).
pub const MAX_POINTS: usize = 1_000_000;

/// An error in a sequence file or in one of its points, with the place.
#[derive(Debug, thiserror::Error)]
#[error("{at}: {message}")]
pub struct SequenceError {
    /// `file:line:col`, or `file` (and the point) when no line applies.
    pub at: String,
    /// What is wrong.
    pub message: String,
}

/// One axis, resolved.
#[derive(Debug, Clone)]
pub struct Axis {
    /// Column name.
    pub name: String,
    /// The field path as written.
    pub path: String,
    segs: Vec<Seg>,
    /// The values (JSON model of serde).
    pub values: Vec<Value>,
    /// Zip label.
    pub zip: Option<String>,
}

impl Axis {
    /// An axis setting `path` to each of `values` (numbers, strings, lists: anything that
    /// serialises), named `name` in the table.
    pub fn new<T: serde::Serialize>(
        name: &str,
        path: &str,
        values: &[T],
    ) -> Result<Self, SequenceError> {
        let values = values
            .iter()
            .map(serde_json::to_value)
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| SequenceError {
                at: format!("axis `{name}`"),
                message: format!("a value cannot be represented: {e}"),
            })?;
        Ok(Self {
            name: name.to_string(),
            path: path.to_string(),
            segs: parse_path(path),
            values,
            zip: None,
        })
    }

    /// Zips this axis with the other axes of group `label`.
    pub fn zip(mut self, label: &str) -> Self {
        self.zip = Some(label.to_string());
        self
    }
}

/// Which of N disjoint parts of a plan a process runs: point `i` belongs to shard `i mod N`
/// (round robin, so that each shard gets every kind of point and costs stay balanced).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0 ≤ k < n`.
    pub k: usize,
    /// Number of shards, ≥ 1.
    pub n: usize,
}

impl Shard {
    /// The whole plan.
    pub const ALL: Shard = Shard { k: 0, n: 1 };

    /// Parses `K/N` (0-based K).
    pub fn parse(s: &str) -> Result<Self, String> {
        let bad = || format!("shard `{s}`: expected K/N with 0 ≤ K < N (e.g. 0/4)");
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (k, n): (usize, usize) = (
            k.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if n == 0 || k >= n {
            return Err(bad());
        }
        Ok(Self { k, n })
    }

    /// Whether point `i` is this shard's.
    pub fn owns(&self, i: usize) -> bool {
        i % self.n == self.k
    }
}

/// A point of the plan: its index, its axis values and its scene.
#[derive(Debug, Clone)]
pub struct Point {
    /// Index in the plan (row-major over the groups, the last varying fastest).
    pub index: usize,
    /// `(axis name, value)` in axis order.
    pub values: Vec<(String, Value)>,
    /// The point's scene.
    pub desc: SceneDesc,
    /// FNV-1a 64 of the point's scene as RON ([`to_ron`]), hexadecimal: identifies what ran.
    pub scene_hash: String,
}

/// A sequence resolved against its base scene.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Name.
    pub name: String,
    /// The sequence file (`<generated>` for plans built in code).
    pub file: PathBuf,
    /// The sequence text, for line numbers.
    text: Option<String>,
    /// The base scene.
    pub base: SceneDesc,
    /// Where it came from (relative paths in it resolve against its folder).
    pub src: SceneSource,
    /// The axes.
    pub axes: Vec<Axis>,
    /// Products kept per point (relative paths; `summary.json` always).
    pub keep: Vec<String>,
    /// Whether points may share runs ([`crate::sequence::merge`]; default true).
    pub share: bool,
    base_tree: Value,
}

/// FNV-1a, 64 bits (Fowler–Noll–Vo; a stable, dependency-free fingerprint, not a security hash).
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

impl Plan {
    /// A plan over `base` (from `src`) with no axes yet (one point: the base scene).
    pub fn new(base: SceneDesc, src: SceneSource) -> Result<Self, SequenceError> {
        let base_tree = serde_json::to_value(&base).map_err(|e| SequenceError {
            at: src.path.display().to_string(),
            message: format!("the base scene cannot be represented for editing: {e}"),
        })?;
        Ok(Self {
            name: String::new(),
            file: PathBuf::from("<generated>"),
            text: None,
            base,
            src,
            axes: Vec::new(),
            keep: vec!["summary.json".into()],
            share: true,
            base_tree,
        })
    }

    /// Adds an axis (checked with [`Plan::check`]).
    pub fn axis(mut self, a: Axis) -> Self {
        self.axes.push(a);
        self
    }

    /// Reads a sequence file and its base scene, and checks every axis (paths, types, zip
    /// groups, size) and every point's scene before anything runs.
    pub fn load(path: &Path) -> Result<Self, SequenceError> {
        let text = std::fs::read_to_string(path).map_err(|e| SequenceError {
            at: path.display().to_string(),
            message: format!("cannot read file: {e}"),
        })?;
        let desc: SequenceDesc = ron::Options::default()
            .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
            .from_str(&text)
            .map_err(|e| SequenceError {
                at: format!(
                    "{}:{}:{}",
                    path.display(),
                    e.span.start.line,
                    e.span.start.col
                ),
                message: e.code.to_string(),
            })?;
        let at = |field: &str| {
            let lc = crate::scene::locate::locate(&text, field);
            match lc {
                Some((l, c)) => format!("{}:{l}:{c}", path.display()),
                None => path.display().to_string(),
            }
        };
        let err = |field: &str, message: String| SequenceError {
            at: at(field),
            message: format!("field `{field}`: {message}"),
        };
        if desc.version != SEQUENCE_FORMAT_VERSION {
            return Err(err(
                "version",
                format!(
                    "sequence format version {} is not supported (this program reads {SEQUENCE_FORMAT_VERSION})",
                    desc.version
                ),
            ));
        }
        let folder = path.parent().unwrap_or(Path::new(""));
        let base_path = folder.join(&desc.base);
        let (base, src) = load_scene(&base_path).map_err(|e| SequenceError {
            at: at("base"),
            message: format!("the base scene: {e}"),
        })?;
        let mut plan = Self::new(base, src)?;
        plan.name = desc.name.clone();
        plan.file = path.to_path_buf();
        plan.share = desc.share.unwrap_or(true);
        if let Some(k) = &desc.keep {
            for (i, p) in k.iter().enumerate() {
                let q = Path::new(p);
                if p.is_empty()
                    || q.is_absolute()
                    || q.components()
                        .any(|c| !matches!(c, std::path::Component::Normal(_)))
                {
                    return Err(err(
                        &format!("keep[{i}]"),
                        format!("`{p}` is not a plain path inside a point's folder"),
                    ));
                }
            }
            plan.keep = std::iter::once("summary.json".to_string())
                .chain(k.iter().filter(|p| *p != "summary.json").cloned())
                .collect();
        }
        for (i, a) in desc.axes.iter().enumerate() {
            let field = format!("axes[{i}]");
            let values: Vec<Value> = match (&a.values, &a.range) {
                (Some(v), None) => v
                    .iter()
                    .map(serde_json::to_value)
                    .collect::<Result<_, _>>()
                    .map_err(|e| err(&format!("{field}.values"), e.to_string()))?,
                (None, Some(r)) => {
                    if !(r.from.is_finite() && r.to.is_finite()) {
                        return Err(err(
                            &format!("{field}.range"),
                            "`from` and `to` must be finite".into(),
                        ));
                    }
                    if r.steps > MAX_POINTS {
                        return Err(err(
                            &format!("{field}.range.steps"),
                            format!("{} steps: at most {MAX_POINTS}", r.steps),
                        ));
                    }
                    r.values().into_iter().map(Value::from).collect()
                }
                _ => {
                    return Err(err(
                        &field,
                        "give exactly one of `values` and `range`".into(),
                    ));
                }
            };
            let AxisDesc {
                name, path, zip, ..
            } = a;
            plan.axes.push(Axis {
                name: name.clone().unwrap_or_else(|| path.clone()),
                path: path.clone(),
                segs: parse_path(path),
                values,
                zip: zip.clone(),
            });
        }
        plan.text = Some(text);
        plan.check()?;
        Ok(plan)
    }

    /// The place of axis `i`'s field `sub` (`path`, `values`, …) for messages.
    fn axis_at(&self, i: usize, sub: &str) -> String {
        let field = format!("axes[{i}].{sub}");
        match self
            .text
            .as_deref()
            .and_then(|t| crate::scene::locate::locate(t, &field))
        {
            Some((l, c)) => format!("{}:{l}:{c}", self.file.display()),
            None => format!("{} (axis `{}`)", self.file.display(), self.axes[i].name),
        }
    }

    /// The groups: axis indices per group (zip label, or the axis alone), in order of first
    /// appearance.
    fn groups(&self) -> Vec<Vec<usize>> {
        let mut groups: Vec<(Option<&str>, Vec<usize>)> = Vec::new();
        for (i, a) in self.axes.iter().enumerate() {
            match a
                .zip
                .as_deref()
                .and_then(|z| groups.iter_mut().find(|(l, _)| *l == Some(z)))
            {
                Some((_, g)) => g.push(i),
                None => groups.push((a.zip.as_deref(), vec![i])),
            }
        }
        groups.into_iter().map(|(_, g)| g).collect()
    }

    /// Number of points (1 without axes).
    pub fn len(&self) -> usize {
        self.groups()
            .iter()
            .map(|g| self.axes[g[0]].values.len())
            .try_fold(1usize, |a, n| a.checked_mul(n))
            .unwrap_or(usize::MAX)
    }

    /// Whether the plan has no point (an axis without values).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Checks the axes (unique names, non-empty, equal lengths within a zip group, paths and
    /// value types against the base scene) and the size, then builds and validates every point.
    pub fn check(&self) -> Result<(), SequenceError> {
        for (i, a) in self.axes.iter().enumerate() {
            if a.values.is_empty() {
                return Err(SequenceError {
                    at: self.axis_at(i, "path"),
                    message: format!("axis `{}` has no values", a.name),
                });
            }
            if self.axes[..i].iter().any(|b| b.name == a.name) {
                return Err(SequenceError {
                    at: self.axis_at(i, "path"),
                    message: format!("two axes are named `{}` (give `name`)", a.name),
                });
            }
            if a.name == "point" {
                return Err(SequenceError {
                    at: self.axis_at(i, "path"),
                    message: "`point` is the table's index column: name the axis otherwise".into(),
                });
            }
            // Each value alone on the base scene: the path exists and the value has the
            // field's type (serde reads the edited scene back).
            for v in &a.values {
                let mut tree = self.base_tree.clone();
                set_path(&mut tree, &a.segs, v.clone())
                    .and_then(|()| {
                        serde_json::from_value::<SceneDesc>(tree)
                            .map(|_| ())
                            .map_err(|e| format!("value {v}: {e}"))
                    })
                    .map_err(|m| SequenceError {
                        at: self.axis_at(i, "path"),
                        message: format!("axis `{}`, path `{}`: {m}", a.name, a.path),
                    })?;
            }
        }
        for g in self.groups() {
            let n = self.axes[g[0]].values.len();
            if let Some(&j) = g.iter().find(|&&j| self.axes[j].values.len() != n) {
                return Err(SequenceError {
                    at: self.axis_at(j, "zip"),
                    message: format!(
                        "axis `{}` has {} values but axis `{}` of its zip group has {n}",
                        self.axes[j].name,
                        self.axes[j].values.len(),
                        self.axes[g[0]].name
                    ),
                });
            }
        }
        let n = self.len();
        if n > MAX_POINTS {
            return Err(SequenceError {
                at: self.file.display().to_string(),
                message: format!(
                    "the axes span {} points: at most {MAX_POINTS} per sequence (split the sweep)",
                    if n == usize::MAX {
                        "more than 2^64".to_string()
                    } else {
                        n.to_string()
                    }
                ),
            });
        }
        for i in 0..n {
            self.point(i)?;
        }
        Ok(())
    }

    /// The axis values of point `i`.
    pub fn values(&self, i: usize) -> Vec<(String, Value)> {
        let groups = self.groups();
        let mut idx = vec![0usize; self.axes.len()];
        let mut rest = i;
        for g in groups.iter().rev() {
            let n = self.axes[g[0]].values.len().max(1);
            for &j in g {
                idx[j] = rest % n;
            }
            rest /= n;
        }
        self.axes
            .iter()
            .zip(idx)
            .map(|(a, k)| (a.name.clone(), a.values[k].clone()))
            .collect()
    }

    /// Point `i`'s axis values and scene (read back through serde, not validated: see
    /// [`Plan::point`]).
    pub(super) fn scene(
        &self,
        i: usize,
    ) -> Result<(Vec<(String, Value)>, SceneDesc), SequenceError> {
        let values = self.values(i);
        let mut tree = self.base_tree.clone();
        for (a, (_, v)) in self.axes.iter().zip(&values) {
            set_path(&mut tree, &a.segs, v.clone()).map_err(|m| SequenceError {
                at: self.file.display().to_string(),
                message: format!("point {i} ({}): path `{}`: {m}", label(&values), a.path),
            })?;
        }
        let desc: SceneDesc = serde_json::from_value(tree).map_err(|e| SequenceError {
            at: self.file.display().to_string(),
            message: format!("point {i} ({}): {e}", label(&values)),
        })?;
        Ok((values, desc))
    }

    /// Builds and validates point `i`'s scene.
    pub fn point(&self, i: usize) -> Result<Point, SequenceError> {
        let (values, desc) = self.scene(i)?;
        let label = label(&values);
        validate(&desc, &self.src).map_err(|e| SequenceError {
            at: self.file.display().to_string(),
            message: format!("point {i} ({label}): {e}"),
        })?;
        let scene_hash = format!("{:016x}", fnv1a64(to_ron(&desc).as_bytes()));
        Ok(Point {
            index: i,
            values,
            desc,
            scene_hash,
        })
    }
}

/// `name = value, …` of a point, for messages.
fn label(values: &[(String, Value)]) -> String {
    values
        .iter()
        .map(|(n, v)| format!("{n} = {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The kind of a JSON value, for messages.
fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "nothing (None)",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "a list",
        Value::Object(_) => "a structure",
    }
}

/// An enum value in serde's external tagging: `{"Variant": inner}` (capitalised name).
fn variant(v: &mut Value) -> Option<&mut Value> {
    match v {
        Value::Object(m) if m.len() == 1 => {
            let (k, inner) = m.iter_mut().next()?;
            k.starts_with(|c: char| c.is_ascii_uppercase())
                .then_some(inner)
        }
        _ => None,
    }
}

/// Sets the field `segs` of `tree` to `v`. Enum variant layers are passed through when the
/// path does not name them; an absent last field is added (serde then refuses it if the type
/// has no such field); the new value must have the old one's kind (a number for a number …;
/// anything replaces an absent optional value).
fn set_path(tree: &mut Value, segs: &[Seg], v: Value) -> Result<(), String> {
    let mut node = tree;
    let mut at = String::new();
    for (n, seg) in segs.iter().enumerate() {
        let last = n + 1 == segs.len();
        match seg {
            Seg::Field(f) => {
                let has = |x: &Value| x.as_object().is_some_and(|m| m.contains_key(f));
                if !has(node) && variant(node).is_some_and(|inner| has(inner) || inner.is_object())
                {
                    node = variant(node).expect("checked");
                }
                let Value::Object(m) = node else {
                    return Err(format!("`{at}` is {}, not a structure", kind(node)));
                };
                if !m.contains_key(f) {
                    if last {
                        m.insert(f.clone(), Value::Null);
                    } else {
                        let mut keys: Vec<&str> = m.keys().map(String::as_str).collect();
                        keys.sort_unstable();
                        return Err(format!(
                            "no field `{f}` in `{at}` (it has: {})",
                            keys.join(", ")
                        ));
                    }
                }
                node = m.get_mut(f).expect("present");
                at = if at.is_empty() {
                    f.clone()
                } else {
                    format!("{at}.{f}")
                };
            }
            Seg::Index(i) => {
                if !node.is_array() && variant(node).is_some_and(|inner| inner.is_array()) {
                    node = variant(node).expect("checked");
                }
                let Value::Array(list) = node else {
                    return Err(format!("`{at}` is {}, not a list", kind(node)));
                };
                let len = list.len();
                node = list.get_mut(*i).ok_or_else(|| {
                    format!("`{at}` has {len} elements: index {i} is out of range")
                })?;
                at = format!("{at}[{i}]");
            }
        }
    }
    // A newtype enum value (`Lai(3.0)`) set from a plain value sets its inside.
    if !v.is_object()
        && let Some(inner) = variant(node)
        && !inner.is_object()
    {
        node = variant(node).expect("checked");
    }
    let same = match (&*node, &v) {
        (Value::Null, _) => true,
        (a, b) => std::mem::discriminant(a) == std::mem::discriminant(b),
    };
    if !same {
        return Err(format!(
            "`{at}` holds {}; the value {v} is {}",
            kind(node),
            kind(&v)
        ));
    }
    *node = v;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_pass_through_enum_variants_and_check_kinds() {
        let mut t = serde_json::json!({
            "optics": {"leaf": {"ProspectLeaf": {"cab_ug_cm2": 40.0}}},
            "objects": [{"Ground": {}}, {"TurbidPlot": {"foliage": {"Lai": 3.0}, "footprint": {"Box": [0.0, 0.0, 2.0, 2.0]}}}],
            "illumination": {"sun_zenith_deg": 20.0, "skyl": []}
        });
        set_path(&mut t, &parse_path("optics.leaf.cab_ug_cm2"), 10.0.into()).unwrap();
        set_path(&mut t, &parse_path("objects[1].foliage"), 5.0.into()).unwrap();
        set_path(&mut t, &parse_path("objects[1].footprint[2]"), 4.0.into()).unwrap();
        assert_eq!(t["optics"]["leaf"]["ProspectLeaf"]["cab_ug_cm2"], 10.0);
        assert_eq!(t["objects"][1]["TurbidPlot"]["foliage"]["Lai"], 5.0);
        assert_eq!(t["objects"][1]["TurbidPlot"]["footprint"]["Box"][2], 4.0);
        let e = set_path(
            &mut t,
            &parse_path("illumination.sun_zenith_deg"),
            "x".into(),
        );
        assert!(e.unwrap_err().contains("holds a number"));
        let e = set_path(&mut t, &parse_path("objects[7].foliage"), 1.0.into());
        assert!(e.unwrap_err().contains("index 7 is out of range"));
        let e = set_path(&mut t, &parse_path("optic.leaf"), 1.0.into());
        assert!(e.unwrap_err().contains("no field `optic`"));
    }

    #[test]
    fn shards_partition_the_points() {
        for n in 1..8 {
            for i in 0..50 {
                let owners = (0..n).filter(|&k| Shard { k, n }.owns(i)).count();
                assert_eq!(owners, 1);
            }
        }
        assert!(Shard::parse("3/3").is_err());
        assert!(Shard::parse("1/0").is_err());
        assert_eq!(Shard::parse("2/7"), Ok(Shard { k: 2, n: 7 }));
    }

    #[test]
    fn ranges_end_exactly() {
        let r = super::super::desc::RangeDesc {
            from: 0.1,
            to: 0.7,
            steps: 7,
        };
        let v = r.values();
        assert_eq!(v.len(), 7);
        assert_eq!(v[0], 0.1);
        assert_eq!(v[6], 0.7);
    }
}
