//! Facet shapes built by Maket: tree trunks (n-sided prisms), building shells (walls, floor,
//! flat or gable roof), water polygons and leaf disks. Every closed shape is a closed shell with
//! outward normals (right-hand winding).

use super::polygon::{signed_area, triangulate};
use glam::{DVec2, DVec3};
use std::f64::consts::PI;

/// A closed n-sided prism approximating a trunk of diameter `d` (vertices on the circle of
/// radius d/2), from `base` up `height` metres: n side quads, a bottom and a top cap.
pub fn trunk_prism(base: DVec3, height: f64, d: f64, sides: u32) -> Vec<[DVec3; 3]> {
    let n = sides.max(3) as usize;
    let r = 0.5 * d;
    let ring: Vec<DVec3> = (0..n)
        .map(|k| {
            let a = 2.0 * PI * k as f64 / n as f64;
            base + DVec3::new(r * a.cos(), r * a.sin(), 0.0)
        })
        .collect();
    let up = DVec3::Z * height;
    let mut t = Vec::with_capacity(4 * n);
    for k in 0..n {
        let (a, b) = (ring[k], ring[(k + 1) % n]);
        t.push([a, b, b + up]);
        t.push([a, b + up, a + up]);
        // Caps as fans around the axis.
        t.push([base, b, a]);
        t.push([base + up, a + up, b + up]);
    }
    t
}

/// Roof of a building shell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Roof {
    /// Flat roof at the wall top.
    Flat,
    /// Gable roof with the ridge `ridge` metres above the wall top, along the longer side.
    Gable(f64),
}

/// Facets of a building: (walls, roof) triangle lists; the floor is included with the walls.
/// `poly` must be a simple polygon; it is used anticlockwise.
pub fn building_shell(
    poly: &[DVec2],
    base_z: f64,
    wall_h: f64,
    roof: Roof,
) -> Option<(Vec<[DVec3; 3]>, Vec<[DVec3; 3]>)> {
    let mut p = poly.to_vec();
    if signed_area(&p) < 0.0 {
        p.reverse();
    }
    let top = base_z + wall_h;
    let n = p.len();
    let mut walls = Vec::new();
    for k in 0..n {
        let (a, b) = (p[k], p[(k + 1) % n]);
        let (a0, b0) = (a.extend(base_z), b.extend(base_z));
        let (a1, b1) = (a.extend(top), b.extend(top));
        walls.push([a0, b0, b1]);
        walls.push([a0, b1, a1]);
    }
    let tris = triangulate(&p)?;
    // Floor faces down.
    for [a, b, c] in &tris {
        walls.push([a.extend(base_z), c.extend(base_z), b.extend(base_z)]);
    }
    let mut roof_t = Vec::new();
    match roof {
        Roof::Flat => {
            for [a, b, c] in &tris {
                roof_t.push([a.extend(top), b.extend(top), c.extend(top)]);
            }
        }
        Roof::Gable(ridge) => {
            if n != 4 {
                return None;
            }
            // Start at the vertex whose outgoing edge is the longer one.
            let s = if (p[1] - p[0]).length() >= (p[2] - p[1]).length() {
                0
            } else {
                1
            };
            let q: Vec<DVec3> = (0..4).map(|k| p[(s + k) % 4].extend(top)).collect();
            // Edges q0→q1 and q2→q3 are long; ridge joins the midpoints of the short edges.
            let r0 = 0.5 * (q[3] + q[0]) + DVec3::Z * ridge;
            let r1 = 0.5 * (q[1] + q[2]) + DVec3::Z * ridge;
            roof_t.push([q[0], q[1], r1]);
            roof_t.push([q[0], r1, r0]);
            roof_t.push([q[2], q[3], r0]);
            roof_t.push([q[2], r0, r1]);
            roof_t.push([q[1], q[2], r1]);
            roof_t.push([q[3], q[0], r0]);
        }
    }
    Some((walls, roof_t))
}

/// An upward-facing horizontal polygon at altitude z (water bodies).
pub fn horizontal_polygon(poly: &[DVec2], z: f64) -> Option<Vec<[DVec3; 3]>> {
    let tris = triangulate(poly)?;
    Some(
        tris.iter()
            .map(|[a, b, c]| [a.extend(z), b.extend(z), c.extend(z)])
            .collect(),
    )
}

/// A regular n-gon (fan of n triangles) with exactly the area of the disk of radius `r`
/// (circumradius `r √(2π / (n sin(2π/n)))`), centred at `c` with unit normal `normal`.
pub fn disk_polygon(c: DVec3, normal: DVec3, r: f64, n: u32) -> Vec<[DVec3; 3]> {
    let n = n.max(3) as usize;
    let nrm = normal.normalize();
    let (u, v) = nrm.any_orthonormal_pair();
    let rr = r * (2.0 * PI / (n as f64 * (2.0 * PI / n as f64).sin())).sqrt();
    let pts: Vec<DVec3> = (0..n)
        .map(|k| {
            let a = 2.0 * PI * k as f64 / n as f64;
            c + rr * (a.cos() * u + a.sin() * v)
        })
        .collect();
    (0..n)
        .map(|k| {
            let t = [c, pts[k], pts[(k + 1) % n]];
            if (t[1] - t[0]).cross(t[2] - t[0]).dot(nrm) >= 0.0 {
                t
            } else {
                [c, pts[(k + 1) % n], pts[k]]
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle::area;

    #[test]
    fn disk_area_exact() {
        let t = disk_polygon(DVec3::ZERO, DVec3::new(0.3, 0.2, 0.9), 0.1, 12);
        let a: f64 = t.iter().map(area).sum();
        assert!((a - PI * 0.01).abs() < 1e-14);
    }
}
