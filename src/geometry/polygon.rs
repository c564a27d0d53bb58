//! 2D polygon helpers: area, simplicity, clipping against axis-aligned rectangles (exact
//! Sutherland–Hodgman, Sutherland & Hodgman 1974) and constrained Delaunay triangulation of a
//! simple polygon with spade.

use glam::DVec2;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// Signed area (shoelace formula), m²; positive for anticlockwise vertex order.
pub fn signed_area(p: &[DVec2]) -> f64 {
    let n = p.len();
    let mut a = 0.0;
    for i in 0..n {
        let (u, v) = (p[i], p[(i + 1) % n]);
        a += u.x * v.y - v.x * u.y;
    }
    0.5 * a
}

fn orient(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    (b - a).perp_dot(c - a)
}

fn segments_cross(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let d1 = orient(c, d, a);
    let d2 = orient(c, d, b);
    let d3 = orient(a, b, c);
    let d4 = orient(a, b, d);
    ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
}

/// First pair of non-adjacent edges that properly cross, if any (O(n²)).
pub fn self_intersection(p: &[DVec2]) -> Option<(usize, usize)> {
    let n = p.len();
    for i in 0..n {
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue;
            }
            if segments_cross(p[i], p[(i + 1) % n], p[j], p[(j + 1) % n]) {
                return Some((i, j));
            }
        }
    }
    None
}

/// True if the 4 vertices form a rectangle (any orientation) to 1e-9 relative.
pub fn is_rectangle(p: &[(f64, f64)]) -> bool {
    if p.len() != 4 {
        return false;
    }
    let v: Vec<DVec2> = p.iter().map(|&(x, y)| DVec2::new(x, y)).collect();
    let scale = (v[2] - v[0]).length().max(1e-300);
    (0..4).all(|i| {
        let a = v[(i + 1) % 4] - v[i];
        let b = v[(i + 2) % 4] - v[(i + 1) % 4];
        a.dot(b).abs() <= 1e-9 * scale * scale
    })
}

/// Clips a polygon to the rectangle `[x0, x1] × [y0, y1]` (Sutherland–Hodgman). The result may
/// contain degenerate edges for concave input but its area is exact.
pub fn clip_to_rect(poly: &[DVec2], x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
    let mut out: Vec<DVec2> = poly.to_vec();
    let planes: [(usize, f64, bool); 4] =
        [(0, x0, true), (0, x1, false), (1, y0, true), (1, y1, false)];
    for (axis, c, keep_greater) in planes {
        if out.is_empty() {
            break;
        }
        let input = std::mem::take(&mut out);
        let inside = |p: DVec2| {
            let v = if axis == 0 { p.x } else { p.y };
            if keep_greater { v >= c } else { v <= c }
        };
        let n = input.len();
        for i in 0..n {
            let cur = input[i];
            let prev = input[(i + n - 1) % n];
            let (ci, pi) = (inside(cur), inside(prev));
            if ci != pi {
                let (a, b) = if axis == 0 {
                    (prev.x, cur.x)
                } else {
                    (prev.y, cur.y)
                };
                let t = (c - a) / (b - a);
                let mut q = prev + (cur - prev) * t;
                if axis == 0 {
                    q.x = c;
                } else {
                    q.y = c;
                }
                out.push(q);
            }
            if ci {
                out.push(cur);
            }
        }
    }
    out
}

/// Area of the intersection of a polygon with a rectangle, m².
pub fn rect_overlap_area(poly: &[DVec2], x0: f64, y0: f64, x1: f64, y1: f64) -> f64 {
    signed_area(&clip_to_rect(poly, x0, y0, x1, y1)).abs()
}

/// Point-in-polygon by the even–odd rule.
pub fn contains(poly: &[DVec2], q: DVec2) -> bool {
    let n = poly.len();
    let mut inside = false;
    let mut j = n - 1;
    for i in 0..n {
        let (a, b) = (poly[i], poly[j]);
        if (a.y > q.y) != (b.y > q.y) && q.x < (b.x - a.x) * (q.y - a.y) / (b.y - a.y) + a.x {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// Triangulates a simple polygon (constrained Delaunay, spade); triangles are anticlockwise.
/// Returns `None` if spade rejects the input (e.g. duplicate vertices).
pub fn triangulate(poly: &[DVec2]) -> Option<Vec<[DVec2; 3]>> {
    let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::new();
    let mut handles = Vec::with_capacity(poly.len());
    for p in poly {
        handles.push(cdt.insert(Point2::new(p.x, p.y)).ok()?);
    }
    for i in 0..handles.len() {
        let (a, b) = (handles[i], handles[(i + 1) % handles.len()]);
        if a != b && cdt.can_add_constraint(a, b) {
            cdt.add_constraint(a, b);
        }
    }
    let mut tris = Vec::new();
    for face in cdt.inner_faces() {
        let [a, b, c] = face.vertices().map(|v| {
            let p = v.position();
            DVec2::new(p.x, p.y)
        });
        let centroid = (a + b + c) / 3.0;
        if contains(poly, centroid) {
            let t = if orient(a, b, c) >= 0.0 {
                [a, b, c]
            } else {
                [a, c, b]
            };
            tris.push(t);
        }
    }
    Some(tris)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn l_shape_area_and_clip() {
        let l = [
            DVec2::new(0.0, 0.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(2.0, 1.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(1.0, 2.0),
            DVec2::new(0.0, 2.0),
        ];
        assert!((signed_area(&l) - 3.0).abs() < 1e-12);
        assert!((rect_overlap_area(&l, 0.5, 0.5, 1.5, 1.5) - 0.75).abs() < 1e-12);
        let tris = triangulate(&l).unwrap();
        let a: f64 = tris.iter().map(|t| signed_area(t)).sum();
        assert!((a - 3.0).abs() < 1e-12);
        assert!(self_intersection(&l).is_none());
        let bow = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.0, 1.0),
        ];
        assert!(self_intersection(&bow).is_some());
    }
}
