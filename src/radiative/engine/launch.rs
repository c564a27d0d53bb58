//! The launch plan (physics.md §6.2, DART 5 paper §3.1): sun and sky launch grids on the
//! top plane (spacing from the facets' outline and the predicted standard error of the
//! direct-sun interception), and the remapping of a facet's wrong-side emission.

use super::*;

/// Sun and sky launch grids on the top plane (see [`launch_plan`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct LaunchPlan {
    /// Sun launch points along x and y.
    pub sun_n: (usize, usize),
    /// Sky launch points along x and y (per downward direction).
    pub sky_n: (usize, usize),
    /// Sun launch spacing (geometric mean of x and y), m.
    pub sun_spacing_m: f64,
    /// Sky launch spacing, m.
    pub sky_spacing_m: f64,
    /// Unshared facet edge length (outline perimeter of all facets), m.
    pub facet_outline_m: f64,
    /// Predicted standard error of the direct-sun interception by facets, as a fraction of the
    /// sun power (0 without facets).
    pub predicted_se: f64,
    /// True when `max_launch_points` capped the spacing above what the target asked for.
    pub capped: bool,
    /// Sub-cell factor D used for facet and ground scattering points (D³ sub-cells per cell,
    /// D² per ground column).
    pub subcells: u32,
    /// Typical facet size `2 A / L` (area over outline, = the radius of a disk leaf) of the
    /// non-ground facets, m (0 without such facets).
    pub facet_size_m: f64,
}

/// Moves the part of an emission row that a facet would send along directions on its wrong
/// side (`ω·n ≤ 0`: a sector straddling the facet plane whose centre lies behind it) to the
/// front-side direction closest to the mirror image `ω − 2(ω·n)n`. Without it that power would
/// start into the facet and, for one-sided ground facets, leave through the grid bottom as
/// "lost" (−2 % albedo on a 17° RPV slope). Only `eligible` directions receive (the regular
/// sectors: an exact view direction's tiny sector must not collect a large sector's power).
/// The row sum is unchanged.
pub fn remap_wrong_side<T>(row: &mut [T], normal: DVec3, omega: &[DVec3], eligible: &[bool])
where
    T: Copy + Default + PartialEq + std::ops::AddAssign,
{
    for j in 0..row.len().min(omega.len()) {
        if row[j] == T::default() || omega[j].dot(normal) > 0.0 {
            continue;
        }
        let m = omega[j] - 2.0 * omega[j].dot(normal) * normal;
        let best = omega
            .iter()
            .enumerate()
            .filter(|(k, o)| o.dot(normal) > 0.0 && eligible.get(*k).copied().unwrap_or(false))
            .max_by(|a, b| a.1.dot(m).total_cmp(&b.1.dot(m)))
            .map(|(k, _)| k);
        if let Some(k) = best
            && k < row.len()
        {
            let v = row[j];
            row[j] = T::default();
            row[k] += v;
        }
    }
}

/// Total length of the facet edges that no other facet shares: the outline of the opaque
/// shapes as the sun sees them (a leaf made of 12 triangles counts its rim, not its spokes; a
/// closed DEM counts only its border). Edges are matched by their exact vertex coordinates, m.
pub fn facet_outline_m<'a>(facets: impl IntoIterator<Item = &'a Facet>) -> f64 {
    // Ordered map: the boundary lengths are summed in key order, the same on every run (a
    // std HashMap's random seed changed the summation order, hence the last bits of the
    // launch spacing, from run to run).
    use std::collections::BTreeMap;
    let key = |a: DVec3| [a.x.to_bits(), a.y.to_bits(), a.z.to_bits()];
    let mut edges: BTreeMap<([u64; 3], [u64; 3]), (u32, f64)> = BTreeMap::new();
    for f in facets {
        for k in 0..3 {
            let (a, b) = (f.v[k], f.v[(k + 1) % 3]);
            let (ka, kb) = (key(a), key(b));
            let e = if ka <= kb { (ka, kb) } else { (kb, ka) };
            let ent = edges.entry(e).or_insert((0, (a - b).length()));
            ent.0 += 1;
        }
    }
    edges
        .values()
        .filter(|(n, _)| *n == 1)
        .map(|(_, l)| l)
        .sum()
}

/// Chooses the sun and sky launch grids on the top plane of a scene of `size` (m) with cells
/// of `cell` (m).
///
/// The power of each launch ray goes whole to the first facet it meets, so a facet's direct
/// interception is estimated by counting lattice points inside its projection. For a convex
/// shape of perimeter `P` under a lattice of spacing `s` with a random offset, the count error
/// has variance ≈ 0.5 · P / (2π s) points (measured by simulation for circles of radius 0.5–8
/// lattice spacings: 0.34–0.53 R; the lattice-point discrepancy of the circle problem grows
/// like R), i.e. an area variance of `P s³ / (4π)`. Summing over independent facet outlines of
/// total length `L` and dividing by the scene area `A` gives the standard error of the directly
/// intercepted fraction: `SE = sqrt(L s³ / (4π)) / A`. The spacing is the largest one with
/// `SE ≤ target`, never above cell/4 (turbid sampling) and never so small that the sun grid
/// exceeds `max_points` (then `capped`). Sky rays average over the downward directions
/// (`n_sky_dirs` independent lattices), so the sky grid may be coarser by `n_sky_dirs^{1/3}` at
/// the same error, again at most cell/4. A scene-given spacing is used as is for both.
///
/// The same reasoning sets the sub-cell factor D of the scattering points (DART 5 paper §3:
/// one scattering point per facet and sub-cell): a facet or ground column scatters from the
/// barycentre of what it intercepted in each of its D³ (ground: D²) sub-cells, so each
/// scattered direction is sampled by one ray per occupied sub-cell. Shadows and gaps have the
/// size of the facets, so D = ceil(cell / r) with r = 2A/L the typical facet size (area over
/// outline of the non-ground facets: a disk leaf's radius), at least the scene's D, at most
/// `max_auto_subcells`, and reduced until columns × D² ≤ `max_launch_points`.
///
/// Checked in tests/radiative_oracles.rs (black-leaf disk canopy against an independent ray
/// cast: 1.3 cm spacing, error within the predicted SE).
pub fn launch_plan(
    size: (f64, f64),
    cell: (f64, f64),
    facets: &[Facet],
    scene_subcells: u32,
    n_sky_dirs: usize,
    params: &TrackingParams,
) -> LaunchPlan {
    let area = size.0 * size.1;
    let outline = if facets.is_empty() {
        0.0
    } else {
        facet_outline_m(facets)
    };
    let objects = facets.iter().filter(|f| f.kind != FacetKind::Ground);
    let obj_area: f64 = objects
        .clone()
        .map(|f| 0.5 * (f.v[1] - f.v[0]).cross(f.v[2] - f.v[0]).length())
        .sum();
    let obj_outline = facet_outline_m(objects);
    let facet_size_m = if obj_outline > 0.0 {
        2.0 * obj_area / obj_outline
    } else {
        0.0
    };
    let grid_of = |s: f64| {
        (
            ((size.0 / s).round() as usize).max(1),
            ((size.1 / s).round() as usize).max(1),
        )
    };
    let spacing_of = |n: (usize, usize)| ((size.0 / n.0 as f64) * (size.1 / n.1 as f64)).sqrt();
    let se_of = |s: f64| (outline * s.powi(3) / (4.0 * std::f64::consts::PI)).sqrt() / area;
    let quarter = cell.0.min(cell.1) / 4.0;
    let mut capped = false;
    let (sun_s, sky_s) = if let Some(s) = params.launch_spacing_m {
        (s, s)
    } else {
        let target = params.launch_target_se.max(1e-12);
        let mut s = if outline > 0.0 {
            (target * target * area * area * 4.0 * std::f64::consts::PI / outline).cbrt()
        } else {
            f64::INFINITY
        }
        .min(quarter);
        let min_s = (area / params.max_launch_points.max(1) as f64).sqrt();
        if s < min_s {
            s = min_s;
            capped = true;
        }
        let sky = (s * (n_sky_dirs.max(1) as f64).cbrt()).min(quarter).max(s);
        (s, sky)
    };
    let sun_n = grid_of(sun_s);
    let sky_n = grid_of(sky_s);
    let sun_spacing_m = spacing_of(sun_n);
    let mut subcells = scene_subcells.max(1);
    if facet_size_m > 0.0 {
        let columns = (size.0 / cell.0).round().max(1.0) * (size.1 / cell.1).round().max(1.0);
        let mut d = ((cell.0.min(cell.1) / facet_size_m).ceil() as u32)
            .min(params.max_auto_subcells.max(1));
        while d > 1 && columns * (d * d) as f64 > params.max_launch_points as f64 {
            d -= 1;
        }
        subcells = subcells.max(d);
    }
    LaunchPlan {
        subcells,
        facet_size_m,
        sun_n,
        sky_n,
        sun_spacing_m,
        sky_spacing_m: spacing_of(sky_n),
        facet_outline_m: outline,
        predicted_se: se_of(sun_spacing_m),
        capped,
    }
}
