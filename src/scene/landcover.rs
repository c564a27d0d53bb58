//! Land-cover import (issue #37; DART 5 paper §2, "Maket": landscapes from classification
//! maps): a classification GeoTIFF in the scene's map frame and the scene's class table become
//! ordinary objects (turbid plots, water bodies, buildings) with `Box` footprints, exactly as if
//! written by hand. Pixels of one class are merged into rectangles (maximal runs along a row,
//! joined with identical runs of the following rows), clipped to the scene; in a rotated scene
//! (+x not east) each rectangle is the rotated polygon clipped to the scene
//! (Sutherland–Hodgman, `geometry::polygon`).

use crate::geometry::polygon::{clip_to_rect, signed_area};
use crate::scene::desc::{
    BuildingDesc, FootprintDesc, LandCoverClass, LandCoverDesc, ObjectDesc, PlacementDesc,
    RoofDesc, TreeStandDesc, TurbidPlotDesc, WaterDesc,
};
use crate::scene::error::{Location, SceneError};
use crate::scene::georef::Georeference;
use crate::scene::terrain_input::{err, read_placed_geotiff};
use glam::DVec2;
use std::path::Path;

/// The object a class becomes over `footprint` (a `Box` for north-up scenes, the clipped
/// rotated rectangle otherwise; metres); `None` for `Nothing`. A `TreeStand` gets one tree per species here; [`expand_land_cover`] sets the
/// counts from the densities.
pub fn class_object(class: &LandCoverClass, footprint: FootprintDesc) -> Option<ObjectDesc> {
    let region = match &footprint {
        FootprintDesc::Box(r) => *r,
        FootprintDesc::Polygon(p) => p.iter().fold(
            (
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ),
            |b, &(x, y)| (b.0.min(x), b.1.min(y), b.2.max(x), b.3.max(y)),
        ),
    };
    match class {
        LandCoverClass::Nothing => None,
        LandCoverClass::TurbidPlot {
            bottom_m,
            top_m,
            foliage,
            optics,
        } => Some(ObjectDesc::TurbidPlot(TurbidPlotDesc {
            footprint,
            bottom_m: *bottom_m,
            top_m: *top_m,
            foliage: *foliage,
            optics: optics.clone(),
        })),
        LandCoverClass::Water { altitude_m, optics } => Some(ObjectDesc::Water(WaterDesc {
            footprint,
            altitude_m: *altitude_m,
            optics: optics.clone(),
        })),
        LandCoverClass::TreeStand {
            species,
            min_spacing_m,
            ..
        } => Some(ObjectDesc::TreeStand(TreeStandDesc {
            species: species.clone(),
            placement: PlacementDesc::Random {
                counts: vec![1; species.len()],
                min_spacing_m: *min_spacing_m,
                region_m: Some(region),
                polygon_m: match &footprint {
                    FootprintDesc::Polygon(p) => Some(p.clone()),
                    FootprintDesc::Box(_) => None,
                },
            },
        })),
        LandCoverClass::Building {
            wall_height_m,
            wall_optics,
            roof_optics,
        } => Some(ObjectDesc::Building(BuildingDesc {
            footprint,
            wall_height_m: *wall_height_m,
            roof: RoofDesc::Flat,
            wall_optics: wall_optics.clone(),
            roof_optics: roof_optics.clone(),
        })),
    }
}

/// Rectangles `(class, c0, c1, r0, r1)` (inclusive pixel ranges) covering every cell of the
/// `nx × ny` class grid `cls` (`c + nx·r`; `None` = no-data) that holds a class: maximal runs
/// along each row, each joined with the identical run (same columns, same class) of the rows
/// below. Ordered by first row, then first column.
pub fn merge_rectangles(
    nx: usize,
    ny: usize,
    cls: &[Option<u32>],
) -> Vec<(u32, usize, usize, usize, usize)> {
    let mut done = Vec::new();
    // Open rectangles: (class, c0, c1, r0).
    let mut open: Vec<(u32, usize, usize, usize)> = Vec::new();
    for r in 0..=ny {
        let mut runs = Vec::new();
        if r < ny {
            let mut c = 0;
            while c < nx {
                let k = cls[c + nx * r];
                let start = c;
                while c < nx && cls[c + nx * r] == k {
                    c += 1;
                }
                if let Some(k) = k {
                    runs.push((k, start, c - 1));
                }
            }
        }
        let mut next = Vec::new();
        for o in open.drain(..) {
            if let Some(p) = runs
                .iter()
                .position(|&(k, a, b)| (k, a, b) == (o.0, o.1, o.2))
            {
                runs.remove(p);
                next.push(o);
            } else {
                done.push((o.0, o.1, o.2, o.3, r - 1));
            }
        }
        for (k, a, b) in runs {
            next.push((k, a, b, r));
        }
        open = next;
    }
    done.sort_by_key(|&(_, c0, _, r0, _)| (r0, c0));
    done
}

/// The objects of a land-cover map over a scene of `size` (m) placed by `g` (`isolated`: the
/// scene's boundary is isolated, trees keep their crowns inside). `field` is the object's path
/// (`objects[i]`) for errors in the scene; errors in the raster name the raster file and the
/// tag at fault.
pub fn expand_land_cover(
    l: &LandCoverDesc,
    base_dir: &Path,
    scene_file: &Path,
    field: &str,
    g: Option<&Georeference>,
    size: (f64, f64),
    isolated: bool,
) -> Result<Vec<ObjectDesc>, SceneError> {
    let inv = |f: &str, m: String| SceneError::Invalid {
        at: Location {
            file: scene_file.to_path_buf(),
            line_col: None,
        },
        field: format!("{field}{f}"),
        message: m,
    };
    let Some(g) = g else {
        return Err(inv(
            "",
            "a LandCover map is placed through the scene's map coordinates: add a \
             `georeference` section (CRS and origin_map_m) to the scene"
                .into(),
        ));
    };
    let p = base_dir.join(&l.path);
    let bytes = std::fs::read(&p).map_err(|e| SceneError::Io {
        path: p.clone(),
        source: e,
    })?;
    let (r, t) = read_placed_geotiff(&p, &bytes, g)?;
    let (nx, ny) = r.size;
    let (dx, dy) = (t[1], -t[5]);
    let (e0, n0) = g.origin_map_m;
    let eps = 1e-9;
    // Pixels overlapping the scene's map bounding box (its extent when north-up).
    let (e_min, n_min, e_max, n_max) = g.map_bounds(size);
    let c_lo = ((e_min - t[0]) / dx + eps).floor();
    let c_hi = ((e_max - t[0]) / dx - eps).ceil() - 1.0;
    let r_lo = ((t[3] - n_max) / dy + eps).floor();
    let r_hi = ((t[3] - n_min) / dy - eps).ceil() - 1.0;
    // The scene polygon of the pixel block [c0, c1] × [r0, r1] clipped to the scene (rotated
    // scenes).
    let scene_poly = |c0: usize, c1: usize, r0: usize, r1: usize| -> Vec<DVec2> {
        let (el, er) = (t[0] + c0 as f64 * dx, t[0] + (c1 + 1) as f64 * dx);
        let (nt, nb) = (t[3] - r0 as f64 * dy, t[3] - (r1 + 1) as f64 * dy);
        let poly: Vec<DVec2> = [(el, nb), (er, nb), (er, nt), (el, nt)]
            .iter()
            .map(|&(e, n)| {
                let (x, y) = g.to_scene(e, n);
                DVec2::new(x, y)
            })
            .collect();
        let mut clipped = clip_to_rect(&poly, 0.0, 0.0, size.0, size.1);
        clipped.dedup_by(|a, b| a.distance(*b) < 1e-9);
        if clipped.len() > 1 && clipped[0].distance(clipped[clipped.len() - 1]) < 1e-9 {
            clipped.pop();
        }
        clipped
    };
    let min_area = 1e-9 * dx * dy;
    if c_lo < 0.0 || r_lo < 0.0 || c_hi > (nx - 1) as f64 || r_hi > (ny - 1) as f64 {
        return Err(err(
            &p,
            None,
            "extent",
            format!(
                "the scene's map extent E [{e_min}, {e_max}], N [{n_min}, {n_max}] m is not inside \
                 the map's pixels E [{}, {}], N [{}, {}] m; enlarge the map or move \
                 georeference.origin_map_m",
                t[0],
                t[0] + nx as f64 * dx,
                t[3] - ny as f64 * dy,
                t[3]
            ),
        ));
    }
    let (c_lo, c_hi, r_lo, r_hi) = (c_lo as usize, c_hi as usize, r_lo as usize, r_hi as usize);
    let (wx, wy) = (c_hi - c_lo + 1, r_hi - r_lo + 1);
    let mut cls = vec![None; wx * wy];
    for row in r_lo..=r_hi {
        for col in c_lo..=c_hi {
            let v = r.values[col + nx * row];
            if r.nodata == Some(v) {
                continue;
            }
            if !g.north_up() && signed_area(&scene_poly(col, col, row, row)).abs() <= min_area {
                continue; // in the bounding box, not in the rotated scene
            }
            if !(v >= 0.0 && v <= u32::MAX as f64 && v.fract() == 0.0) {
                return Err(err(
                    &p,
                    None,
                    "image",
                    format!(
                        "pixel (column {col}, row {row}) holds {v}, not a class code (a whole \
                         number ≥ 0); give the classification raster"
                    ),
                ));
            }
            let k = v as u32;
            if !l.classes.contains_key(&k) {
                return Err(inv(
                    ".classes",
                    format!(
                        "class {k} of {} (pixel column {col}, row {row}) has no entry; add `{k}: \
                         Nothing` (bare ground) or the object it becomes",
                        p.display()
                    ),
                ));
            }
            cls[(col - c_lo) + wx * (row - r_lo)] = Some(k);
        }
    }
    let mut out = Vec::new();
    // Tree counts not yet placed, per class and species (fractions carried over).
    let mut carry: std::collections::BTreeMap<u32, Vec<f64>> = Default::default();
    let mut trees = 0usize;
    for (k, a, b, ra, rb) in merge_rectangles(wx, wy, &cls) {
        let (c0, c1, r0, r1) = (a + c_lo, b + c_lo, ra + r_lo, rb + r_lo);
        let class = &l.classes[&k];
        let footprint = if g.north_up() {
            let x0 = (t[0] + c0 as f64 * dx - e0).max(0.0);
            let x1 = (t[0] + (c1 + 1) as f64 * dx - e0).min(size.0);
            let y1 = (t[3] - r0 as f64 * dy - n0).min(size.1);
            let y0 = (t[3] - (r1 + 1) as f64 * dy - n0).max(0.0);
            if !(x1 > x0 && y1 > y0) {
                continue;
            }
            FootprintDesc::Box((x0, y0, x1, y1))
        } else {
            let poly = scene_poly(c0, c1, r0, r1);
            if poly.len() < 3 || signed_area(&poly).abs() <= min_area {
                continue;
            }
            FootprintDesc::Polygon(poly.iter().map(|v| (v.x, v.y)).collect())
        };
        // The rectangle's area (trees owed) and bounding box (the isolated inset below).
        let (area_m2, (x0, y0, x1, y1)) = match &footprint {
            FootprintDesc::Box(b) => ((b.2 - b.0) * (b.3 - b.1), *b),
            FootprintDesc::Polygon(p) => {
                let v: Vec<DVec2> = p.iter().map(|&(x, y)| DVec2::new(x, y)).collect();
                let bb = p.iter().fold(
                    (f64::MAX, f64::MAX, f64::MIN, f64::MIN),
                    |(a, b, c, d), &(x, y)| (a.min(x), b.min(y), c.max(x), d.max(y)),
                );
                (signed_area(&v).abs(), bb)
            }
        };
        let Some(mut o) = class_object(class, footprint) else {
            continue;
        };
        if let (
            LandCoverClass::TreeStand {
                species,
                trees_per_ha,
                ..
            },
            ObjectDesc::TreeStand(TreeStandDesc {
                placement:
                    PlacementDesc::Random {
                        counts, region_m, ..
                    },
                ..
            }),
        ) = (class, &mut o)
        {
            let area_ha = area_m2 / 1e4;
            let owed = carry.entry(k).or_insert_with(|| vec![0.0; species.len()]);
            for (s, n) in counts.iter_mut().enumerate() {
                owed[s] += trees_per_ha[s] * area_ha;
                *n = owed[s].floor().max(0.0) as usize;
                owed[s] -= *n as f64;
            }
            if isolated {
                let r = species
                    .iter()
                    .map(|sp| sp.crown.radius_x_m.max(sp.crown.radius_y_m.unwrap_or(0.0)))
                    .fold(0.0, f64::max);
                let (ix0, iy0) = (x0.max(r), y0.max(r));
                let (ix1, iy1) = (x1.min(size.0 - r), y1.min(size.1 - r));
                if !(ix1 > ix0 && iy1 > iy0) {
                    // No room for a trunk here: the trees go to the class's next rectangle.
                    for (s, n) in counts.iter().enumerate() {
                        owed[s] += *n as f64;
                    }
                    continue;
                }
                *region_m = Some((ix0, iy0, ix1, iy1));
            }
            trees += counts.iter().sum::<usize>();
            if trees > crate::scene::validate::MAX_STAND_TREES {
                return Err(inv(
                    &format!(".classes[{k}].trees_per_ha"),
                    format!(
                        "the map asks for more than {} trees: lower the densities or the scene size",
                        crate::scene::validate::MAX_STAND_TREES
                    ),
                ));
            }
            if counts.iter().all(|&n| n == 0) {
                continue;
            }
        }
        out.push(o);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every classed cell is in exactly one rectangle of its class; a uniform map is one
    /// rectangle.
    #[test]
    fn rectangles_cover_each_cell_once() {
        let (nx, ny) = (7, 5);
        let cls: Vec<Option<u32>> = (0..nx * ny)
            .map(|k| match (k % nx, k / nx) {
                (0, _) => None,
                (c, r) if c < 4 && r < 3 => Some(1),
                (c, _) if c % 2 == 0 => Some(2),
                _ => Some(3),
            })
            .collect();
        let rects = merge_rectangles(nx, ny, &cls);
        let mut seen = vec![0; nx * ny];
        for &(k, c0, c1, r0, r1) in &rects {
            for r in r0..=r1 {
                for c in c0..=c1 {
                    assert_eq!(cls[c + nx * r], Some(k));
                    seen[c + nx * r] += 1;
                }
            }
        }
        for (i, n) in seen.iter().enumerate() {
            assert_eq!(*n, usize::from(cls[i].is_some()), "cell {i}");
        }
        assert_eq!(
            merge_rectangles(3, 4, &[Some(5); 12]),
            vec![(5, 0, 2, 0, 3)]
        );
    }
}
