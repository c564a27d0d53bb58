//! Ground: flat plane or digital elevation model (DEM).
//!
//! Rasters become two triangles per raster cell directly (a regular grid's Delaunay
//! triangulation is degenerate: co-circular quads); scattered points are Delaunay-triangulated
//! with spade (DART 5 paper §2: "DEMs … imported … as a triangulated irregular network").
//! Triangles are clipped to the scene extent `[0, X] × [0, Y]`. Heights at raster nodes equal the
//! raster values exactly.

use glam::{DVec2, DVec3};
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

/// A point of a TIN carrying its altitude.
#[derive(Debug, Clone, Copy)]
pub struct TinVertex {
    /// x, y, z (metres).
    pub p: DVec3,
}

impl HasPosition for TinVertex {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        Point2::new(self.p.x, self.p.y)
    }
}

/// A regular raster of node altitudes.
#[derive(Debug, Clone, PartialEq)]
pub struct Raster {
    /// Nodes along x and y.
    pub nodes: (usize, usize),
    /// Spacing, metres.
    pub spacing: (f64, f64),
    /// Node (0, 0), metres.
    pub origin: (f64, f64),
    /// Altitudes, x fastest.
    pub z: Vec<f64>,
}

impl Raster {
    fn node(&self, i: usize, j: usize) -> DVec3 {
        DVec3::new(
            self.origin.0 + i as f64 * self.spacing.0,
            self.origin.1 + j as f64 * self.spacing.1,
            self.z[i + j * self.nodes.0],
        )
    }

    /// Altitude at (x, y) on the raster's triangulation (diagonal from node (i,j) to (i+1,j+1)).
    pub fn height(&self, x: f64, y: f64) -> f64 {
        let fx = ((x - self.origin.0) / self.spacing.0).clamp(0.0, (self.nodes.0 - 1) as f64);
        let fy = ((y - self.origin.1) / self.spacing.1).clamp(0.0, (self.nodes.1 - 1) as f64);
        let i = (fx.floor() as usize).min(self.nodes.0 - 2);
        let j = (fy.floor() as usize).min(self.nodes.1 - 2);
        let (u, v) = (fx - i as f64, fy - j as f64);
        let z00 = self.z[i + j * self.nodes.0];
        let z10 = self.z[i + 1 + j * self.nodes.0];
        let z01 = self.z[i + (j + 1) * self.nodes.0];
        let z11 = self.z[i + 1 + (j + 1) * self.nodes.0];
        if u >= v {
            z00 + u * (z10 - z00) + v * (z11 - z10)
        } else {
            z00 + v * (z01 - z00) + u * (z11 - z01)
        }
    }

    fn triangles(&self) -> Vec<[DVec3; 3]> {
        let mut t = Vec::with_capacity(2 * (self.nodes.0 - 1) * (self.nodes.1 - 1));
        for j in 0..self.nodes.1 - 1 {
            for i in 0..self.nodes.0 - 1 {
                let (a, b, c, d) = (
                    self.node(i, j),
                    self.node(i + 1, j),
                    self.node(i + 1, j + 1),
                    self.node(i, j + 1),
                );
                t.push([a, b, c]);
                t.push([a, c, d]);
            }
        }
        t
    }
}

/// The ground of a scene.
#[derive(Debug, Clone)]
pub enum Terrain {
    /// Horizontal plane at altitude z (metres).
    Flat(f64),
    /// Raster DEM.
    Raster(Raster),
    /// Triangulated irregular network.
    Tin(Box<DelaunayTriangulation<TinVertex>>),
}

impl Terrain {
    /// Altitude of the ground at (x, y), metres.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        match self {
            Terrain::Flat(z) => *z,
            Terrain::Raster(r) => r.height(x, y),
            Terrain::Tin(dt) => {
                use spade::FloatTriangulation;
                dt.barycentric()
                    .interpolate(|v| v.data().p.z, Point2::new(x, y))
                    .unwrap_or_else(|| nearest_z(dt, x, y))
            }
        }
    }

    /// Ground triangles clipped to `[0, sx] × [0, sy]` (empty for a flat ground, which the
    /// tracker handles as an exact plane).
    pub fn triangles(&self, sx: f64, sy: f64) -> Vec<[DVec3; 3]> {
        let raw = match self {
            Terrain::Flat(_) => return Vec::new(),
            Terrain::Raster(r) => r.triangles(),
            Terrain::Tin(dt) => dt
                .inner_faces()
                .map(|f| f.vertices().map(|v| v.data().p))
                .map(|[a, b, c]| {
                    if (b - a).cross(c - a).z >= 0.0 {
                        [a, b, c]
                    } else {
                        [a, c, b]
                    }
                })
                .collect(),
        };
        let mut out = Vec::with_capacity(raw.len());
        for t in raw {
            clip_triangle_xy(&t, sx, sy, &mut out);
        }
        out
    }

    /// Altitude offsets (along x, along y) between opposite scene edges, metres: the mean of
    /// `h(X, y) − h(0, y)` over y and of `h(x, Y) − h(x, 0)` over x. Used by the
    /// `RepetitiveContinuousTopography` boundary (DART 5 paper Fig. 4).
    pub fn edge_offsets(&self, sx: f64, sy: f64) -> (f64, f64) {
        const N: usize = 64;
        let mut ox = 0.0;
        let mut oy = 0.0;
        for k in 0..N {
            let t = (k as f64 + 0.5) / N as f64;
            ox += self.height(sx, t * sy) - self.height(0.0, t * sy);
            oy += self.height(t * sx, sy) - self.height(t * sx, 0.0);
        }
        (ox / N as f64, oy / N as f64)
    }
}

fn nearest_z(dt: &DelaunayTriangulation<TinVertex>, x: f64, y: f64) -> f64 {
    dt.vertices()
        .map(|v| v.data().p)
        .min_by(|a, b| {
            let da = (a.x - x).powi(2) + (a.y - y).powi(2);
            let db = (b.x - x).powi(2) + (b.y - y).powi(2);
            da.total_cmp(&db)
        })
        .map_or(0.0, |p| p.z)
}

/// Clips a triangle's xy projection to the scene rectangle, lifting new vertices onto its plane,
/// and fan-triangulates the result.
fn clip_triangle_xy(t: &[DVec3; 3], sx: f64, sy: f64, out: &mut Vec<[DVec3; 3]>) {
    let lo = t
        .iter()
        .fold(DVec2::splat(f64::INFINITY), |m, v| m.min(v.truncate()));
    let hi = t
        .iter()
        .fold(DVec2::splat(f64::NEG_INFINITY), |m, v| m.max(v.truncate()));
    if lo.x >= 0.0 && lo.y >= 0.0 && hi.x <= sx && hi.y <= sy {
        out.push(*t);
        return;
    }
    if hi.x <= 0.0 || hi.y <= 0.0 || lo.x >= sx || lo.y >= sy {
        return;
    }
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    if n.z.abs() < 1e-300 {
        return;
    }
    let z_at = |p: DVec2| t[0].z - (n.x * (p.x - t[0].x) + n.y * (p.y - t[0].y)) / n.z;
    let poly2: Vec<DVec2> = t.iter().map(|v| v.truncate()).collect();
    let clipped = crate::geometry::polygon::clip_to_rect(&poly2, 0.0, 0.0, sx, sy);
    if clipped.len() < 3 {
        return;
    }
    let p3: Vec<DVec3> = clipped.iter().map(|p| p.extend(z_at(*p))).collect();
    for i in 1..p3.len() - 1 {
        let tri = [p3[0], p3[i], p3[i + 1]];
        if !crate::geometry::triangle::is_degenerate(&tri) {
            out.push(tri);
        }
    }
}
