//! Ground: flat plane or digital elevation model (DEM).
//!
//! Rasters become two triangles per raster cell directly (a regular grid's Delaunay
//! triangulation is degenerate: co-circular quads); scattered points are Delaunay-triangulated
//! with spade (DART 5 paper §2: "DEMs … imported … as a triangulated irregular network").
//! Triangles are clipped to the scene extent `[0, X] × [0, Y]`. Heights at raster nodes equal the
//! raster values exactly.

use crate::scene::desc::{RasterDesc, RasterFileDesc, RasterFormat, TopographyDesc};
use crate::scene::error::{Location, SceneError};
use glam::{DVec2, DVec3};
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};
use std::path::Path;

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

fn err(path: &Path, line: Option<usize>, field: &str, message: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        at: Location {
            file: path.to_path_buf(),
            line_col: line.map(|l| (l, 1)),
        },
        field: field.into(),
        message: message.into(),
    }
}

/// Reads an ESRI ASCII grid; node values are taken at cell centres.
pub fn read_esri_ascii(path: &Path, text: &str, offset: (f64, f64)) -> Result<Raster, SceneError> {
    let mut header = std::collections::HashMap::new();
    let mut lines = text.lines().enumerate().peekable();
    while let Some((_, l)) = lines.peek() {
        let mut it = l.split_whitespace();
        let Some(key) = it.next() else {
            lines.next();
            continue;
        };
        if key.chars().next().is_some_and(|c| c.is_ascii_alphabetic()) {
            let (ln, l) = lines.next().unwrap_or((0, ""));
            let mut it = l.split_whitespace();
            let key = it.next().unwrap_or("").to_ascii_lowercase();
            let val: f64 = it.next().and_then(|v| v.parse().ok()).ok_or_else(|| {
                err(
                    path,
                    Some(ln + 1),
                    &key,
                    "header value is missing or not a number",
                )
            })?;
            header.insert(key, (val, ln + 1));
        } else {
            break;
        }
    }
    let get = |k: &str| header.get(k).map(|v| v.0);
    let ncols = get("ncols").ok_or_else(|| err(path, None, "ncols", "missing header entry"))?;
    let nrows = get("nrows").ok_or_else(|| err(path, None, "nrows", "missing header entry"))?;
    let cs = get("cellsize").ok_or_else(|| err(path, None, "cellsize", "missing header entry"))?;
    if ncols < 2.0 || nrows < 2.0 || ncols.fract() != 0.0 || nrows.fract() != 0.0 {
        return Err(err(path, None, "ncols/nrows", "need whole numbers >= 2"));
    }
    if !(cs > 0.0 && cs.is_finite()) {
        return Err(err(
            path,
            header.get("cellsize").map(|v| v.1),
            "cellsize",
            format!("must be > 0, got {cs}"),
        ));
    }
    let (x0, y0) = match (
        get("xllcorner"),
        get("yllcorner"),
        get("xllcenter"),
        get("yllcenter"),
    ) {
        (Some(x), Some(y), _, _) => (x + 0.5 * cs, y + 0.5 * cs),
        (_, _, Some(x), Some(y)) => (x, y),
        _ => {
            return Err(err(
                path,
                None,
                "xllcorner",
                "missing xllcorner/yllcorner (or xllcenter/yllcenter)",
            ));
        }
    };
    let nodata = get("nodata_value");
    let (nx, ny) = (ncols as usize, nrows as usize);
    let mut z = vec![0.0; nx * ny];
    let mut count = 0usize;
    for (ln, l) in lines {
        for tok in l.split_whitespace() {
            let v: f64 = tok.parse().map_err(|_| {
                err(
                    path,
                    Some(ln + 1),
                    "values",
                    format!("`{tok}` is not a number"),
                )
            })?;
            if !v.is_finite() || nodata == Some(v) {
                return Err(err(
                    path,
                    Some(ln + 1),
                    "values",
                    "no-data or non-finite altitude: DEM holes are not supported",
                ));
            }
            if count >= nx * ny {
                return Err(err(
                    path,
                    Some(ln + 1),
                    "values",
                    format!("more than ncols × nrows = {} values", nx * ny),
                ));
            }
            let (col, row) = (count % nx, count / nx);
            z[col + (ny - 1 - row) * nx] = v;
            count += 1;
        }
    }
    if count != nx * ny {
        return Err(err(
            path,
            None,
            "values",
            format!("expected {} values, found {count}", nx * ny),
        ));
    }
    Ok(Raster {
        nodes: (nx, ny),
        spacing: (cs, cs),
        origin: (x0 - offset.0, y0 - offset.1),
        z,
    })
}

/// Builds the terrain of a scene; `base_dir` resolves raster file paths; `field` names the
/// topography in errors.
pub fn build_terrain(
    topo: &TopographyDesc,
    base_dir: &Path,
    scene_file: &Path,
    field: &str,
    size: (f64, f64),
) -> Result<Terrain, SceneError> {
    let inv = |m: String| SceneError::Invalid {
        at: Location {
            file: scene_file.to_path_buf(),
            line_col: None,
        },
        field: field.to_string(),
        message: m,
    };
    let terrain = match topo {
        TopographyDesc::Flat => Terrain::Flat(0.0),
        TopographyDesc::Raster(RasterDesc {
            nodes,
            spacing_m,
            origin_m,
            altitude_m,
        }) => Terrain::Raster(Raster {
            nodes: *nodes,
            spacing: *spacing_m,
            origin: *origin_m,
            z: altitude_m.clone(),
        }),
        TopographyDesc::RasterFile(RasterFileDesc {
            path,
            format,
            origin_m,
        }) => {
            let p = base_dir.join(path);
            match format {
                RasterFormat::EsriAscii => {
                    let text = std::fs::read_to_string(&p).map_err(|e| SceneError::Io {
                        path: p.clone(),
                        source: e,
                    })?;
                    Terrain::Raster(read_esri_ascii(&p, &text, *origin_m)?)
                }
                RasterFormat::BinaryF32 { nodes, spacing_m } => {
                    let bytes = std::fs::read(&p).map_err(|e| SceneError::Io {
                        path: p.clone(),
                        source: e,
                    })?;
                    let n = nodes.0 * nodes.1;
                    if nodes.0 < 2 || nodes.1 < 2 || bytes.len() != 4 * n {
                        return Err(err(
                            &p,
                            None,
                            "nodes",
                            format!(
                                "expected {} × {} f32 values = {} bytes, file has {}",
                                nodes.0,
                                nodes.1,
                                4 * n,
                                bytes.len()
                            ),
                        ));
                    }
                    let z: Vec<f64> = bytes
                        .chunks_exact(4)
                        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64)
                        .collect();
                    if let Some(k) = z.iter().position(|v| !v.is_finite()) {
                        return Err(err(&p, None, "values", format!("value {k} is not finite")));
                    }
                    Terrain::Raster(Raster {
                        nodes: *nodes,
                        spacing: *spacing_m,
                        origin: *origin_m,
                        z,
                    })
                }
            }
        }
        TopographyDesc::Points { points_m } => {
            let verts: Vec<TinVertex> = points_m
                .iter()
                .map(|&(x, y, z)| TinVertex {
                    p: DVec3::new(x, y, z),
                })
                .collect();
            let dt = DelaunayTriangulation::<TinVertex>::bulk_load(verts)
                .map_err(|e| inv(format!("cannot triangulate the points: {e:?}")))?;
            if dt.num_inner_faces() == 0 {
                return Err(inv("points are collinear: no triangle".into()));
            }
            Terrain::Tin(Box::new(dt))
        }
    };
    // The DEM must cover the scene.
    match &terrain {
        Terrain::Raster(r) => {
            let x1 = r.origin.0 + (r.nodes.0 - 1) as f64 * r.spacing.0;
            let y1 = r.origin.1 + (r.nodes.1 - 1) as f64 * r.spacing.1;
            let eps = 1e-9 * size.0.max(size.1);
            if r.origin.0 > eps || r.origin.1 > eps || x1 < size.0 - eps || y1 < size.1 - eps {
                return Err(inv(format!(
                    "raster covers x [{:.3}, {x1:.3}], y [{:.3}, {y1:.3}] m but the scene is [0, {}] × [0, {}] m",
                    r.origin.0, r.origin.1, size.0, size.1
                )));
            }
        }
        Terrain::Tin(dt) => {
            use spade::FloatTriangulation;
            for (x, y) in [(0.0, 0.0), (size.0, 0.0), (0.0, size.1), (size.0, size.1)] {
                if dt
                    .barycentric()
                    .interpolate(|v| v.data().p.z, Point2::new(x, y))
                    .is_none()
                {
                    return Err(inv(format!(
                        "the points' convex hull does not cover the scene corner ({x}, {y})"
                    )));
                }
            }
        }
        Terrain::Flat(_) => {}
    }
    Ok(terrain)
}
