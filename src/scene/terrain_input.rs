//! The scene's ground from its description: ESRI ASCII, GeoTIFF (placed through the scene's
//! georeference and cropped to the scene's map extent; issue #37) and raw `f32` raster files,
//! inline rasters and scattered points, turned into a [`Terrain`] (the geometry lives in
//! [`crate::geometry::terrain`]). Errors name the scene file, the raster file and the field.

use crate::geometry::terrain::{Raster, Terrain, TinVertex};
use crate::scene::desc::{RasterDesc, RasterFileDesc, RasterFormat, TopographyDesc};
use crate::scene::error::{Location, SceneError};
use crate::scene::georef::Georeference;
use glam::DVec3;
use spade::{DelaunayTriangulation, Point2, Triangulation};
use std::path::Path;

/// An `Invalid` error located in `path` (a raster file, or the scene), at `line` when known.
pub fn err(
    path: &Path,
    line: Option<usize>,
    field: &str,
    message: impl Into<String>,
) -> SceneError {
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
    if ncols * nrows > MAX_RASTER_NODES as f64 {
        return Err(err(
            path,
            header.get("ncols").map(|v| v.1),
            "ncols/nrows",
            format!("{ncols} × {nrows} nodes are above the limit of {MAX_RASTER_NODES} nodes"),
        ));
    }
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

/// Reads a single-band GeoTIFF that must lie in the scene's map frame: it has a placement
/// (tie point and pixel scale, or a transformation) that is north-up, and its CRS is the
/// scene's (EPSG codes compared; a user-defined CRS is taken as is). Returns the raster and its
/// pixel-corner transform. Errors name the file and the tag at fault.
pub fn read_placed_geotiff(
    path: &Path,
    bytes: &[u8],
    g: &Georeference,
) -> Result<(crate::io::geotiff::GeoRaster, [f64; 6]), SceneError> {
    let r =
        crate::io::geotiff::read_geotiff_band(bytes).map_err(|m| err(path, None, "image", m))?;
    let t = r.transform.ok_or_else(|| {
        err(
            path,
            None,
            "ModelTiepointTag",
            "no georeferencing (ModelTiepointTag + ModelPixelScaleTag, or ModelTransformationTag): \
             give a GeoTIFF with its map placement",
        )
    })?;
    if !(t[2] == 0.0 && t[4] == 0.0 && t[1] > 0.0 && t[5] < 0.0) {
        return Err(err(
            path,
            None,
            "ModelTransformationTag",
            "the raster is rotated or flipped; resample it north-up (e.g. gdalwarp) first",
        ));
    }
    if r.model_type == Some(2) {
        return Err(err(
            path,
            None,
            "GeoKeyDirectoryTag.GTModelTypeGeoKey",
            "the raster is in geographic coordinates (degrees); reproject it to the scene's CRS",
        ));
    }
    let scene_crs = g
        .crs
        .epsg
        .map(|c| format!("EPSG:{c}"))
        .unwrap_or_else(|| g.crs.name.clone());
    match r.projected_crs {
        None => {
            return Err(err(
                path,
                None,
                "GeoKeyDirectoryTag.ProjectedCRSGeoKey",
                format!(
                    "the raster names no projected CRS; it must be in the scene's CRS ({scene_crs})"
                ),
            ));
        }
        Some(crate::io::geotiff::USER_DEFINED) => {}
        Some(c) if g.crs.epsg == Some(c as u32) => {}
        Some(c) => {
            return Err(err(
                path,
                None,
                "GeoKeyDirectoryTag.ProjectedCRSGeoKey",
                format!(
                    "wrong CRS: the raster is in EPSG:{c}, the scene's georeference.crs is \
                     {scene_crs}; reproject the raster (e.g. gdalwarp -t_srs) or fix georeference.crs"
                ),
            ));
        }
    }
    Ok((r, t))
}

/// A DEM GeoTIFF in the scene's map frame: the raster, its transform, its node spacing (E, N; m) and the map
/// coordinates of node (0, 0), the top-left one (pixel centres for PixelIsArea, the transform's
/// points for PixelIsPoint).
struct PlacedDem {
    r: crate::io::geotiff::GeoRaster,
    /// The pixel-corner transform (GDAL order).
    t: [f64; 6],
    spacing: (f64, f64),
    node0: (f64, f64),
}

/// The raster nodes (columns `c_lo..=c_hi`, rows `r_lo..=r_hi`; row 0 at the top) that cover
/// the map box `(e_min, n_min, e_max, n_max)` (m), for a raster of `n` nodes spaced `spacing`
/// from `node0` (the top-left node, map m); an error (`what` names the box) when the raster
/// does not cover it.
fn node_range(
    path: &Path,
    (nx, ny): (usize, usize),
    (dx, dy): (f64, f64),
    (e_node0, n_node0): (f64, f64),
    (e_min, n_min, e_max, n_max): (f64, f64, f64, f64),
    what: &str,
) -> Result<(usize, usize, usize, usize), SceneError> {
    let eps = 1e-9;
    let c_lo = ((e_min - e_node0) / dx + eps).floor();
    let c_hi = ((e_max - e_node0) / dx - eps).ceil();
    let r_lo = ((n_node0 - n_max) / dy + eps).floor();
    let r_hi = ((n_node0 - n_min) / dy - eps).ceil();
    if c_lo < 0.0 || r_lo < 0.0 || c_hi > (nx - 1) as f64 || r_hi > (ny - 1) as f64 {
        return Err(err(
            path,
            None,
            "extent",
            format!(
                "the scene's {what} E [{e_min}, {e_max}], N [{n_min}, {n_max}] m is not inside \
                 the raster's nodes E [{}, {}], N [{}, {}] m; enlarge the raster or move \
                 georeference.origin_map_m",
                e_node0,
                e_node0 + (nx - 1) as f64 * dx,
                n_node0 - (ny - 1) as f64 * dy,
                n_node0
            ),
        ));
    }
    Ok((c_lo as usize, c_hi as usize, r_lo as usize, r_hi as usize))
}

/// The elevation of raster node (`col`, `row`), or an error naming it when it is no-data
/// (`GDAL_NODATA` or not finite); `place` says where it lies (`inside`, `next to` the scene).
fn node_value(
    path: &Path,
    r: &crate::io::geotiff::GeoRaster,
    (col, row): (usize, usize),
    place: &str,
) -> Result<f64, SceneError> {
    let v = r.values[col + r.size.0 * row];
    if is_nodata(r, v) {
        return Err(err(
            path,
            None,
            "GDAL_NODATA",
            format!(
                "pixel (column {col}, row {row}) {place} the scene is no-data ({v}): DEM holes \
                 are not supported; fill them (e.g. gdal_fillnodata) or move the scene"
            ),
        ));
    }
    Ok(v)
}

/// Whether `v` is a no-data value of `r` (its `GDAL_NODATA`, or not finite).
fn is_nodata(r: &crate::io::geotiff::GeoRaster, v: f64) -> bool {
    !v.is_finite() || r.nodata == Some(v)
}

/// [`read_placed_geotiff`] for a DEM: refuses a raster that is no-data everywhere and gives
/// its node placement.
fn read_placed_dem(path: &Path, bytes: &[u8], g: &Georeference) -> Result<PlacedDem, SceneError> {
    let (r, t) = read_placed_geotiff(path, bytes, g)?;
    if r.values
        .iter()
        .all(|&v| !v.is_finite() || r.nodata == Some(v))
    {
        return Err(err(
            path,
            None,
            "GDAL_NODATA",
            "every pixel is no-data: the raster holds no elevation",
        ));
    }
    let (dx, dy) = (t[1], -t[5]);
    let half = if r.pixel_is_point { 0.0 } else { 0.5 };
    Ok(PlacedDem {
        t,
        spacing: (dx, dy),
        node0: (t[0] + half * dx, t[3] - half * dy),
        r,
    })
}

/// Reads a GeoTIFF DEM (OGC GeoTIFF 1.1; [`crate::io::geotiff::read_geotiff_band`]) and crops
/// it to the nodes that cover the scene's map extent, [E₀, E₀ + X] × [N₀, N₀ + Y] for a
/// north-up georeference: pixel values are nodes at pixel centres (PixelIsArea) or at the
/// transform's points (PixelIsPoint). The raster must be north-up, in the scene's CRS (EPSG
/// codes compared; a user-defined CRS is taken as is), cover the extent, and hold no no-data
/// (`GDAL_NODATA`) or non-finite value among the kept nodes. Errors name the raster file and
/// the tag or property at fault.
pub fn read_geotiff_dem(
    path: &Path,
    bytes: &[u8],
    g: &Georeference,
    size: (f64, f64),
) -> Result<Raster, SceneError> {
    let PlacedDem {
        r,
        t,
        spacing: (dx, dy),
        node0: (e_node0, n_node0),
    } = read_placed_dem(path, bytes, g)?;
    let (nx, ny) = r.size;
    let (e0, n0) = g.origin_map_m;
    let (c_lo, c_hi, r_lo, r_hi) = node_range(
        path,
        (nx, ny),
        (dx, dy),
        (e_node0, n_node0),
        (e0, n0, e0 + size.0, n0 + size.1),
        "map extent",
    )?;
    let (mx, my) = (c_hi - c_lo + 1, r_hi - r_lo + 1);
    let mut z = vec![0.0; mx * my];
    for row in r_lo..=r_hi {
        for col in c_lo..=c_hi {
            let v = node_value(path, &r, (col, row), "inside")?;
            z[(col - c_lo) + (r_hi - row) * mx] = v;
        }
    }
    // Lowest-left kept node, written as the ESRI reader does (corner + half a cell − offset).
    let x_ll = t[0] + c_lo as f64 * dx;
    let y_ll = t[3] - (r_hi + 1) as f64 * dy;
    let (x0, y0) = if r.pixel_is_point {
        (t[0] + c_lo as f64 * dx, t[3] - r_hi as f64 * dy)
    } else {
        (x_ll + 0.5 * dx, y_ll + 0.5 * dy)
    };
    Ok(Raster {
        nodes: (mx, my),
        spacing: (dx, dy),
        origin: (x0 - e0, y0 - n0),
        z,
    })
}

/// The nodes of a GeoTIFF DEM under a rotated scene (+x not east), in scene coordinates: every
/// node within a pixel diagonal of the scene rectangle, for a Delaunay TIN (the raster's own
/// lattice, rotated: the surface passes through every node). The raster must cover the
/// scene's map bounding box; no-data nodes are refused near the scene and dropped farther
/// away. Errors as [`read_geotiff_dem`].
pub fn read_geotiff_dem_nodes(
    path: &Path,
    bytes: &[u8],
    g: &Georeference,
    size: (f64, f64),
) -> Result<Vec<TinVertex>, SceneError> {
    let PlacedDem {
        r,
        t: _,
        spacing: (dx, dy),
        node0: (e_node0, n_node0),
    } = read_placed_dem(path, bytes, g)?;
    let (nx, ny) = r.size;
    let (c_lo, c_hi, r_lo, r_hi) = node_range(
        path,
        (nx, ny),
        (dx, dy),
        (e_node0, n_node0),
        g.map_bounds(size),
        "map bounding box",
    )?;
    let margin = dx.hypot(dy);
    let mut verts = Vec::new();
    for row in r_lo..=r_hi {
        for col in c_lo..=c_hi {
            let (x, y) = g.to_scene(e_node0 + col as f64 * dx, n_node0 - row as f64 * dy);
            if x < -margin || y < -margin || x > size.0 + margin || y > size.1 + margin {
                continue;
            }
            let v = node_value(path, &r, (col, row), "next to")?;
            verts.push(TinVertex {
                p: DVec3::new(x, y, v),
            });
        }
    }
    Ok(verts)
}

/// Largest number of nodes of a ground raster (2²⁸: 2 GiB of f64 altitudes), checked before
/// the altitudes are allocated.
pub const MAX_RASTER_NODES: usize = 1 << 28;

/// Builds the terrain of a scene; `base_dir` resolves raster file paths; `field` names the
/// topography in errors.
pub fn build_terrain(
    topo: &TopographyDesc,
    base_dir: &Path,
    scene_file: &Path,
    field: &str,
    size: (f64, f64),
    georef: Option<&Georeference>,
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
                RasterFormat::GeoTiff => {
                    let Some(g) = georef else {
                        return Err(inv(
                            "a GeoTiff DEM is placed through the scene's map coordinates: add a \
                             `georeference` section (CRS and origin_map_m) to the scene"
                                .into(),
                        ));
                    };
                    if *origin_m != (0.0, 0.0) {
                        return Err(inv(
                            "origin_m must be (0, 0) with a GeoTiff DEM (its placement comes from \
                             georeference.origin_map_m)"
                                .into(),
                        ));
                    }
                    let bytes = std::fs::read(&p).map_err(|e| SceneError::Io {
                        path: p.clone(),
                        source: e,
                    })?;
                    if g.north_up() {
                        Terrain::Raster(read_geotiff_dem(&p, &bytes, g, size)?)
                    } else {
                        let verts = read_geotiff_dem_nodes(&p, &bytes, g, size)?;
                        let dt = DelaunayTriangulation::<TinVertex>::bulk_load(verts)
                            .map_err(|e| inv(format!("cannot triangulate the DEM: {e:?}")))?;
                        Terrain::Tin(Box::new(dt))
                    }
                }
                RasterFormat::BinaryF32 { nodes, spacing_m } => {
                    let bytes = std::fs::read(&p).map_err(|e| SceneError::Io {
                        path: p.clone(),
                        source: e,
                    })?;
                    let n = nodes
                        .0
                        .checked_mul(nodes.1)
                        .filter(|&n| n <= MAX_RASTER_NODES)
                        .ok_or_else(|| {
                            err(
                                &p,
                                None,
                                "nodes",
                                format!(
                                    "{} × {} nodes are above the limit of {MAX_RASTER_NODES} nodes",
                                    nodes.0, nodes.1
                                ),
                            )
                        })?;
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
