//! Triangles: Möller–Trumbore ray–triangle intersection, exact triangle–box overlap (separating-axis test, Akenine-Möller 2001), clipping of
//! a triangle to a box (Sutherland–Hodgman in 3D) for the area a facet puts in each cell, and
//! degeneracy checks.

use glam::DVec3;

/// Triangle area, m².
pub fn area(t: &[DVec3; 3]) -> f64 {
    0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length()
}

/// Unit normal (right-hand rule), or zero for a degenerate triangle.
pub fn normal(t: &[DVec3; 3]) -> DVec3 {
    (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero()
}

/// True if the triangle has non-finite vertices or an area below `1e-12 × (longest edge)²`
/// (a sliver that no ray can hit reliably).
pub fn is_degenerate(t: &[DVec3; 3]) -> bool {
    if !t.iter().all(|v| v.is_finite()) {
        return true;
    }
    let l = (t[1] - t[0])
        .length_squared()
        .max((t[2] - t[1]).length_squared())
        .max((t[0] - t[2]).length_squared());
    l == 0.0 || 2.0 * area(t) <= 1e-12 * l
}

/// Möller–Trumbore ray–triangle intersection (Möller & Trumbore 1997), both faces; distance or
/// `None`.
#[inline]
pub fn intersect(v: &[DVec3; 3], o: DVec3, d: DVec3) -> Option<f64> {
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - v[0];
    let u = s.dot(p) * inv;
    if !(-1e-12..=1.0 + 1e-12).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let vv = d.dot(q) * inv;
    if vv < -1e-12 || u + vv > 1.0 + 1e-12 {
        return None;
    }
    Some(e2.dot(q) * inv)
}

/// Exact overlap test of a triangle and the closed box `[lo, hi]` (touching counts as overlap,
/// so a facet lying in a cell face belongs to both cells that share it).
pub fn overlaps_box(t: &[DVec3; 3], lo: DVec3, hi: DVec3) -> bool {
    let c = 0.5 * (lo + hi);
    let h = 0.5 * (hi - lo);
    let v = [t[0] - c, t[1] - c, t[2] - c];
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    // 1. Box face normals.
    for a in 0..3 {
        let mn = v[0][a].min(v[1][a]).min(v[2][a]);
        let mx = v[0][a].max(v[1][a]).max(v[2][a]);
        if mn > h[a] || mx < -h[a] {
            return false;
        }
    }
    // 2. Triangle normal.
    let n = e[0].cross(e[1]);
    let r = h.x * n.x.abs() + h.y * n.y.abs() + h.z * n.z.abs();
    let d = n.dot(v[0]);
    if d.abs() > r {
        return false;
    }
    // 3. Edge × box axes.
    let axes = [DVec3::X, DVec3::Y, DVec3::Z];
    for ei in e {
        for ax in axes {
            let a = ei.cross(ax);
            if a.length_squared() < 1e-300 {
                continue;
            }
            let p = [a.dot(v[0]), a.dot(v[1]), a.dot(v[2])];
            let mn = p[0].min(p[1]).min(p[2]);
            let mx = p[0].max(p[1]).max(p[2]);
            let r = h.x * a.x.abs() + h.y * a.y.abs() + h.z * a.z.abs();
            if mn > r || mx < -r {
                return false;
            }
        }
    }
    true
}

/// Polygon of the triangle clipped to the box `[lo, hi]` (may be empty).
pub fn clip_to_box(t: &[DVec3; 3], lo: DVec3, hi: DVec3) -> Vec<DVec3> {
    let mut poly: Vec<DVec3> = t.to_vec();
    for axis in 0..3 {
        for (bound, keep_greater) in [(lo[axis], true), (hi[axis], false)] {
            if poly.is_empty() {
                return poly;
            }
            let input = std::mem::take(&mut poly);
            let n = input.len();
            let inside = |p: DVec3| {
                if keep_greater {
                    p[axis] >= bound
                } else {
                    p[axis] <= bound
                }
            };
            for i in 0..n {
                let cur = input[i];
                let prev = input[(i + n - 1) % n];
                let (ci, pi) = (inside(cur), inside(prev));
                if ci != pi {
                    let t = (bound - prev[axis]) / (cur[axis] - prev[axis]);
                    let mut q = prev + (cur - prev) * t;
                    q[axis] = bound;
                    poly.push(q);
                }
                if ci {
                    poly.push(cur);
                }
            }
        }
    }
    poly
}

/// Area of a planar 3D polygon, m².
pub fn polygon_area(p: &[DVec3]) -> f64 {
    if p.len() < 3 {
        return 0.0;
    }
    let mut s = DVec3::ZERO;
    for i in 1..p.len() - 1 {
        s += (p[i] - p[0]).cross(p[i + 1] - p[0]);
    }
    0.5 * s.length()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn face_lying_triangle_touches_both_cells() {
        let t = [
            DVec3::new(0.1, 0.1, 1.0),
            DVec3::new(0.9, 0.1, 1.0),
            DVec3::new(0.1, 0.9, 1.0),
        ];
        assert!(overlaps_box(&t, DVec3::ZERO, DVec3::ONE));
        assert!(overlaps_box(
            &t,
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 1.0, 2.0)
        ));
        assert!(!overlaps_box(
            &t,
            DVec3::new(0.0, 0.0, 1.1),
            DVec3::new(1.0, 1.0, 2.0)
        ));
        // Diagonal triangle missing a corner box.
        let d = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ];
        assert!(!overlaps_box(
            &d,
            DVec3::new(1.5, 1.5, -0.5),
            DVec3::new(2.5, 2.5, 0.5)
        ));
        assert!(overlaps_box(
            &d,
            DVec3::new(0.9, 0.9, -0.5),
            DVec3::new(1.9, 1.9, 0.5)
        ));
    }

    #[test]
    fn clipped_areas_partition_the_triangle() {
        let t = [
            DVec3::new(0.13, 0.2, 0.3),
            DVec3::new(2.7, 0.4, 1.9),
            DVec3::new(0.5, 2.9, 2.2),
        ];
        let mut s = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    let lo = DVec3::new(i as f64, j as f64, k as f64);
                    s += polygon_area(&clip_to_box(&t, lo, lo + DVec3::ONE));
                }
            }
        }
        assert!(
            (s - area(&t)).abs() < 1e-12 * area(&t),
            "{s} vs {}",
            area(&t)
        );
    }
}
