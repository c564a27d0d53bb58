//! RAMI leaf lists (RAMI-3/4 "discrete" scenes): one disk leaf per line,
//! `radius x_center y_center z_center normal_x normal_y normal_z` (metres), separated by white
//! space or commas; `#` starts a comment; blank lines are allowed.

use glam::DVec3;
use std::path::Path;

/// One disk leaf.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiskLeaf {
    /// Radius, metres.
    pub radius: f64,
    /// Centre, metres.
    pub center: DVec3,
    /// Unit normal.
    pub normal: DVec3,
}

/// A parsed leaf list.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LeafList {
    /// Leaves in file order.
    pub leaves: Vec<DiskLeaf>,
    /// Lines whose normal was not of unit length (normalised; warn the user).
    pub renormalised: usize,
}

impl LeafList {
    /// Total one-sided leaf area Σ π r², m².
    pub fn leaf_area(&self) -> f64 {
        self.leaves
            .iter()
            .map(|l| std::f64::consts::PI * l.radius * l.radius)
            .sum()
    }
}

/// Parses a leaf list; errors name the file and the 1-based line.
pub fn parse_leaf_list(text: &str, path: &Path) -> Result<LeafList, String> {
    let mut out = LeafList::default();
    for (n, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let at = || format!("{}:{}", path.display(), n + 1);
        let vals: Vec<f64> = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse::<f64>()
                    .map_err(|_| format!("{}: `{t}` is not a number", at()))
            })
            .collect::<Result<_, _>>()?;
        if vals.len() != 7 {
            return Err(format!(
                "{}: expected 7 values (radius x y z nx ny nz), found {}",
                at(),
                vals.len()
            ));
        }
        if vals.iter().any(|v| !v.is_finite()) {
            return Err(format!("{}: non-finite value", at()));
        }
        if vals[0] <= 0.0 {
            return Err(format!(
                "{}: leaf radius must be > 0, got {}",
                at(),
                vals[0]
            ));
        }
        let normal = DVec3::new(vals[4], vals[5], vals[6]);
        let len = normal.length();
        if len < 1e-12 {
            return Err(format!("{}: leaf normal has zero length", at()));
        }
        if (len - 1.0).abs() > 1e-6 {
            out.renormalised += 1;
        }
        out.leaves.push(DiskLeaf {
            radius: vals[0],
            center: DVec3::new(vals[1], vals[2], vals[3]),
            normal: normal / len,
        });
    }
    if out.leaves.is_empty() {
        return Err(format!("{}: the leaf list holds no leaf", path.display()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_comments_commas_and_reports_lines() {
        let p = Path::new("leaves.txt");
        let l = parse_leaf_list(
            "# RAMI\n0.1 1 2 3 0 0 1\n\n0.05, 1, 2, 3.5, 0, 2, 0  # tilted\n",
            p,
        )
        .unwrap();
        assert_eq!(l.leaves.len(), 2);
        assert_eq!(l.renormalised, 1);
        assert!((l.leaves[1].normal - DVec3::Y).length() < 1e-15);
        assert!((l.leaf_area() - std::f64::consts::PI * (0.01 + 0.0025)).abs() < 1e-15);
        let e = parse_leaf_list("0.1 1 2 3 0 0 1\n0.1 1 2 x 0 0 1\n", p).unwrap_err();
        assert!(e.starts_with("leaves.txt:2:"), "{e}");
        assert!(
            parse_leaf_list("0 1 2 3 0 0 1\n", p)
                .unwrap_err()
                .contains("radius")
        );
        assert!(
            parse_leaf_list("0.1 1 2 3 0 0\n", p)
                .unwrap_err()
                .contains("7 values")
        );
    }
}
