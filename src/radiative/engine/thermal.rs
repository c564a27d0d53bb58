//! Thermal emission as a source of the flux tracking (issue #34; physics.md §7.2; DART 5
//! paper §2–§3): turbid cells, facets and the flat ground emit `ε B(T)` into every tiling
//! direction in iteration 1, with the sun and sky, on their own set of channels (the
//! *thermal* channels, after the sun and sky ones), and what they emit is then intercepted,
//! scattered and absorbed by the normal iterations.
//!
//! * **Turbid cells** emit from their volume: the power of entry e (leaf area density u, m²
//!   m⁻³, cell volume V) into direction j is `ε B G(Ω_j) u V ΔΩ_j` (the emission coefficient
//!   of a leaf medium, `j(Ω) = ε_L u G(Ω) B`, times the volume and the sector's solid angle,
//!   taken as `∫_{ΔΩ_j}|μ|dΩ / |μ_j|`, see [`effective_sr`]),
//!   sent from the cell's two emission points of a uniform source ([`TurbidPair`] about the
//!   cell centre), so the within-cell re-interception is tracked like that of scattered light
//!   and the power leaving the cell is the reciprocal of the interception of a beam from the
//!   same direction (`radiative::emission`, `tests/emission_reciprocity.rs`).
//! * **Facets** emit as Lambertian surfaces of emissivity `1 − R − T_d` per side (both sides
//!   of a two-sided facet, the front of a one-sided one), times `1 − T_dir^{1/|μ|}` for a facet
//!   with direct transmittance (Kirchhoff: the absorptance of a beam along −Ω), with the exact
//!   projected-solid-angle fractions of the scattering, from points spread over the facet.
//! * **The flat ground** column of area a emits `ε B a ∫_{ΔΩ_j} μ dΩ` into each upward
//!   direction, from its sub-cell centres.
//! * **The sky** (an isotropic downwelling radiance, e.g. `B(T_sky)`) is launched like the
//!   solar sky, on the thermal channels.
//!
//! `ε B` is given per element and band ([`ThermalSources`]), so temperatures may vary per
//! element; W m⁻² sr⁻¹ µm⁻¹ (any spectral unit: powers come out per the same unit).

use super::*;

/// The thermal sources of a run: `ε B(T)` per element and band (W m⁻² sr⁻¹ µm⁻¹), index
/// `element · n_bands + band`; an empty list means that kind of element does not emit.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ThermalSources {
    /// Per turbid entry (index of `CellGrid::turbid`): `ε_L B(T)`, ε_L = 1 − ρ_L − τ_L.
    pub turbid: Vec<f64>,
    /// Per facet: `ε B(T)`, ε = 1 − R − T_d (the direct-transmittance factor is applied per
    /// direction by the tracker).
    pub facet: Vec<f64>,
    /// Per flat-ground column `i + n_x j`: `ε B(T)`, ε = 1 − ρ, for a Lambertian ground; for
    /// a ground with a BRDF (`RadiativeInput::ground_brdf`) `B(T)`, the tracker applying the
    /// directional emissivity `1 − ρ_dh(Ω)` (Kirchhoff) from the BRDF tables.
    pub ground: Vec<f64>,
    /// Isotropic downwelling sky radiance per band (empty or zero: none).
    pub sky: Vec<f64>,
}

impl ThermalSources {
    /// Whether the sky radiates.
    pub fn has_sky(&self) -> bool {
        self.sky.iter().any(|&v| v > 0.0)
    }
}

/// An emitting element: a turbid entry, a facet or a flat-ground column (the order in which
/// the launch sends them).
#[derive(Debug, Clone, Copy)]
pub(in crate::radiative) enum ThermalElement {
    Turbid(u32),
    Facet(u32),
    Ground(u32),
}

/// The emitting elements of a run, in a fixed order (turbid entries, facets, ground columns):
/// those with some `ε B > 0`.
pub(in crate::radiative) fn thermal_elements(ctx: &Ctx) -> Vec<ThermalElement> {
    let Some(th) = ctx.inp.thermal else {
        return Vec::new();
    };
    let nb = ctx.nb;
    let emits = |v: &[f64], i: usize| {
        v.get(i * nb..(i + 1) * nb)
            .is_some_and(|s| s.iter().any(|&x| x > 0.0))
    };
    let mut out = Vec::new();
    for (k, e) in ctx.inp.grid.turbid.iter().enumerate() {
        if ctx.tur_mat[e.material as usize] != u32::MAX && e.density > 0.0 && emits(&th.turbid, k) {
            out.push(ThermalElement::Turbid(k as u32));
        }
    }
    for f in 0..ctx.inp.facets.len() {
        if emits(&th.facet, f)
            && matches!(
                ctx.inp.optics[ctx.inp.facets[f].material as usize],
                TrackOptics::Lambert { .. }
            )
        {
            out.push(ThermalElement::Facet(f as u32));
        }
    }
    if ctx.inp.flat_ground.is_some() {
        for c in 0..ctx.inp.spec.n[0] * ctx.inp.spec.n[1] {
            if emits(&th.ground, c) {
                out.push(ThermalElement::Ground(c as u32));
            }
        }
    }
    out
}

/// Scratch of [`thermal_emitter`]: the emission points of a facet or a ground column.
#[derive(Default)]
pub(in crate::radiative) struct ThermalScratch {
    points: Vec<(DVec3, f64)>,
    /// BRDF ground: `1 − ρ_dh` per (upward tiling direction j, band), the directional
    /// emissivity (filled at first use).
    ground_eps: Vec<f64>,
}

/// The power element `el` emits into every tiling direction, `outgoing[j · w + tb + b]` (W per
/// spectral unit; `tb` the first thermal channel), and where its rays start; `fractions` are
/// the facets' Lambertian fractions (front, back) over the tiling directions.
pub(in crate::radiative) fn thermal_emitter<'s>(
    ctx: &Ctx,
    el: ThermalElement,
    fractions: &[(Vec<f32>, Vec<f32>)],
    outgoing: &mut [f64],
    scratch: &'s mut ThermalScratch,
) -> Emitter<'s> {
    let th = ctx.inp.thermal.expect("thermal run");
    let (w, nb, n_dirs, tb) = (ctx.w, ctx.nb, ctx.n_dirs, ctx.thermal_base);
    let spec = ctx.inp.spec;
    let tiling = ctx.inp.dirs.tiling();
    outgoing.iter_mut().for_each(|v| *v = 0.0);
    scratch.points.clear();
    match el {
        ThermalElement::Turbid(k) => {
            let k = k as usize;
            let e = &ctx.inp.grid.turbid[k];
            let tm = ctx.tur_mat[e.material as usize] as usize;
            let vol = spec.cell.x * spec.cell.y * spec.cell.z;
            let eb = &th.turbid[k * nb..(k + 1) * nb];
            let uv = e.density as f64 * vol;
            for j in 0..n_dirs {
                let g = ctx.g_dir[j * ctx.n_tm + tm];
                let f = g * uv * effective_sr(&tiling[j]);
                for b in 0..nb {
                    outgoing[j * w + tb + b] = eb[b] * f;
                }
            }
            let cell = ctx.entry_cell[k] as usize;
            let centre = cell_centre(spec, cell);
            let pair = TurbidPair::new(cell, centre, centre, spec.cell);
            Emitter {
                origin_up: centre,
                origin_dn: centre,
                skip: None,
                normal: None,
                points: &[],
                ground: false,
                pair: Some(match terrain_top(ctx, cell) {
                    Some(z) => pair.above(z),
                    None => pair,
                }),
            }
        }
        ThermalElement::Facet(f) => {
            let fa = &ctx.inp.facets[f as usize];
            let TrackOptics::Lambert { t_dir, .. } = &ctx.inp.optics[fa.material as usize] else {
                unreachable!("thermal_elements keeps Lambertian facets only")
            };
            let cross = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]);
            let area = 0.5 * cross.length();
            let n = cross.normalize_or(DVec3::Z);
            let eb = &th.facet[f as usize * nb..(f as usize + 1) * nb];
            let (fr, bk) = &fractions[f as usize];
            for j in 0..n_dirs {
                let side = if fa.two_sided {
                    fr[j] as f64 + bk[j] as f64
                } else {
                    fr[j] as f64
                };
                if side == 0.0 {
                    continue;
                }
                let mu = n.dot(ctx.omega[j]).abs().max(1e-12);
                for b in 0..nb {
                    let td = t_dir.get(b).copied().unwrap_or(0.0);
                    let open = if td > 0.0 {
                        1.0 - td.powf(1.0 / mu)
                    } else {
                        1.0
                    };
                    outgoing[j * w + tb + b] = eb[b] * area * std::f64::consts::PI * side * open;
                }
            }
            facet_points(
                fa,
                spec.cell.x.min(spec.cell.y) / ctx.sub as f64,
                &mut scratch.points,
            );
            let centroid = (fa.v[0] + fa.v[1] + fa.v[2]) / 3.0;
            Emitter {
                origin_up: centroid,
                origin_dn: centroid,
                skip: Some(f),
                normal: Some(n),
                points: &scratch.points,
                ground: false,
                pair: None,
            }
        }
        ThermalElement::Ground(c) => {
            let c = c as usize;
            let a = spec.cell.x * spec.cell.y;
            let eb = &th.ground[c * nb..(c + 1) * nb];
            if scratch.ground_eps.is_empty() {
                scratch.ground_eps = ground_emissivity(ctx);
            }
            for j in 0..n_dirs {
                if ctx.omega[j].z <= 0.0 {
                    continue;
                }
                for b in 0..nb {
                    outgoing[j * w + tb + b] =
                        eb[b] * scratch.ground_eps[j * nb + b] * a * tiling[j].projected_sr;
                }
            }
            let o = cell_centre(spec, c);
            let d = ground_points_per_side(ctx);
            let share = 1.0 / (d * d) as f64;
            for jy in 0..d {
                for ix in 0..d {
                    let p = DVec3::new(
                        o.x + ((ix as f64 + 0.5) / d as f64 - 0.5) * spec.cell.x,
                        o.y + ((jy as f64 + 0.5) / d as f64 - 0.5) * spec.cell.y,
                        spec.origin.z,
                    );
                    scratch.points.push((p, share));
                }
            }
            Emitter {
                origin_up: DVec3::new(o.x, o.y, spec.origin.z),
                origin_dn: DVec3::new(o.x, o.y, spec.origin.z),
                skip: None,
                normal: None,
                points: &scratch.points,
                ground: true,
                pair: None,
            }
        }
    }
}

/// The solid angle a volume source sends along a tiling direction: `∫_{ΔΩ_j}|μ|dΩ / |μ_j|`,
/// sr. Equal to ΔΩ_j for a sector centred (in μ) on its direction Ω_j; an exact direction's
/// μ-range may be shifted off Ω_j inside its parent tile, and the tracker carries the sector's
/// power along Ω_j, so this is the solid angle for which a deep isothermal medium's exitance
/// through the sector, `B ∫_{ΔΩ_j}|μ|dΩ` per unit area, matches what a surface under it sends
/// (Kirchhoff closure per sector, not only per hemisphere).
fn effective_sr(d: &crate::direction::Direction) -> f64 {
    let mu = d.omega.z.abs();
    if mu > 1e-9 {
        d.projected_sr / mu
    } else {
        d.solid_angle_sr
    }
}

/// The flat ground's directional emissivity per (tiling direction j, band): 1 for a Lambertian
/// ground (its ε is in `ThermalSources::ground`); with a BRDF, Kirchhoff's `1 − ρ_hd(Ω_j)`
/// (physics.md §7.2; = 1 − ρ_dh(Ω_j) by reciprocity) with the hemispherical–directional
/// reflectance the tracker itself applies: an isotropic sky of unit radiance brings
/// `∫_{ΔΩ_i}|μ|dΩ` per unit area from each downward direction i, which the ground scatters into
/// j with its slot row, so `ρ_hd(Ω_j) = Σ_i ∫_{ΔΩ_i}|μ|dΩ · row_{slot(i)}[j] / ∫_{ΔΩ_j}μ dΩ`.
/// With it an isothermal BRDF ground under a sky at its temperature radiates exactly B(T)
/// (the row sums of the incidence containing −Ω_j give ~1 % off with the default preset's
/// slot-averaged rows).
fn ground_emissivity(ctx: &Ctx) -> Vec<f64> {
    let nb = ctx.nb;
    let mut eps = vec![1.0; ctx.n_dirs * nb];
    if ctx.inp.ground_brdf.is_some() {
        let tiling = ctx.inp.dirs.tiling();
        for b in 0..nb {
            let mut r_hd = vec![0.0; ctx.n_dirs];
            for (i, d) in tiling.iter().enumerate() {
                if d.omega.z >= 0.0 {
                    continue;
                }
                let row = ctx.ground_row(b, ctx.inp.sector_of[i] as usize);
                for (r, &x) in r_hd.iter_mut().zip(row) {
                    *r += d.projected_sr * x;
                }
            }
            for (j, d) in tiling.iter().enumerate() {
                if d.omega.z > 0.0 && d.projected_sr > 0.0 {
                    eps[j * nb + b] = (1.0 - r_hd[j] / d.projected_sr).clamp(0.0, 1.0);
                }
            }
        }
    }
    eps
}

/// The highest point of the DEM ground facets over cell `c`'s footprint (each facet's plane at
/// the cell's four corners), m, when the terrain crosses the cell: a turbid cell that the
/// ground cuts holds its leaves above it, so its emission starts there (from below, its rays
/// would leave through the ground). `None` without ground facets in the cell.
fn terrain_top(ctx: &Ctx, c: usize) -> Option<f64> {
    let spec = ctx.inp.spec;
    let [i, j, k] = spec.ijk(c);
    let (lo, hi) = spec.cell_box(i as i64, j as i64, k as i64);
    let mut top: Option<f64> = None;
    for &f in ctx.inp.grid.facets_of(c) {
        let fa = &ctx.inp.facets[f as usize];
        if fa.kind != FacetKind::Ground {
            continue;
        }
        let n = (fa.v[1] - fa.v[0]).cross(fa.v[2] - fa.v[0]);
        if n.z.abs() < 1e-12 {
            continue;
        }
        for (x, y) in [(lo.x, lo.y), (hi.x, lo.y), (lo.x, hi.y), (hi.x, hi.y)] {
            // The plane n·(p − v0) = 0 at (x, y).
            let z = fa.v[0].z - (n.x * (x - fa.v[0].x) + n.y * (y - fa.v[0].y)) / n.z;
            top = Some(top.map_or(z, |t: f64| t.max(z)));
        }
    }
    top.filter(|&z| z > lo.z).map(|z| z.min(hi.z))
}

/// Emission points per side of a flat-ground column: 4 D (D the sub-cell factor), so that the
/// gap fraction each upward direction sees through a facet canopy is sampled finely (on a
/// disc canopy the isothermal closure goes from ±1.1 K with D to ±0.29 K with 4 D; 16 D:
/// ±0.25 K), halved while the scene would hold more than 2²² ground points (large scenes keep
/// D per side, as their scattering does).
fn ground_points_per_side(ctx: &Ctx) -> usize {
    let cols = ctx.inp.spec.n[0] * ctx.inp.spec.n[1];
    let sub = ctx.sub.max(1) as usize;
    let mut d = 4 * sub;
    while d > sub && cols.saturating_mul(d * d) > 1 << 22 {
        d /= 2;
    }
    d.max(sub)
}

/// Emission points spread over a facet: the centroids of its m² congruent sub-triangles (m
/// such that their edges are at most `spacing`, m ≤ 16), equal shares.
fn facet_points(fa: &Facet, spacing: f64, out: &mut Vec<(DVec3, f64)>) {
    let longest = (fa.v[1] - fa.v[0])
        .length()
        .max((fa.v[2] - fa.v[1]).length())
        .max((fa.v[0] - fa.v[2]).length());
    let m = if spacing > 0.0 && longest.is_finite() {
        ((longest / spacing).ceil() as usize).clamp(1, 16)
    } else {
        1
    };
    let share = 1.0 / (m * m) as f64;
    let (a, e1, e2) = (fa.v[0], fa.v[1] - fa.v[0], fa.v[2] - fa.v[0]);
    let at = |u: f64, v: f64| a + e1 * (u / m as f64) + e2 * (v / m as f64);
    for i in 0..m {
        for j in 0..m - i {
            out.push((at(i as f64 + 1.0 / 3.0, j as f64 + 1.0 / 3.0), share));
            if i + j + 1 < m {
                out.push((at(i as f64 + 2.0 / 3.0, j as f64 + 2.0 / 3.0), share));
            }
        }
    }
}

/// The thermal source per band (W per spectral unit): the elements' emission (`outgoing`
/// summed), and the sky's, `L ∫_{ΔΩ}|μ|dΩ` times the launch area `sky_area(Ω)` of each
/// downward direction.
pub(in crate::radiative) fn thermal_source(
    ctx: &Ctx,
    elements: &[ThermalElement],
    fractions: &[(Vec<f32>, Vec<f32>)],
    sky_area: impl Fn(DVec3) -> f64,
) -> (Vec<f64>, Vec<f64>) {
    let (w, nb, tb) = (ctx.w, ctx.nb, ctx.thermal_base);
    let total = elements
        .par_chunks(4096)
        .map(|chunk| {
            let mut outgoing = vec![0.0; ctx.n_dirs * w];
            let mut scratch = ThermalScratch::default();
            let mut t = vec![0.0; nb];
            for &el in chunk {
                thermal_emitter(ctx, el, fractions, &mut outgoing, &mut scratch);
                for o in outgoing.chunks_exact(w) {
                    for b in 0..nb {
                        t[b] += o[tb + b];
                    }
                }
            }
            t
        })
        .collect::<Vec<_>>()
        .into_iter()
        .fold(vec![0.0; nb], |mut acc, t| {
            acc.iter_mut().zip(&t).for_each(|(a, b)| *a += b);
            acc
        });
    let mut sky = vec![0.0; nb];
    if let Some(th) = ctx.inp.thermal.filter(|t| t.has_sky()) {
        for (j, d) in ctx.inp.dirs.tiling().iter().enumerate() {
            if ctx.omega[j].z >= 0.0 {
                continue;
            }
            let a = sky_area(ctx.omega[j]);
            for (b, t) in sky.iter_mut().enumerate() {
                *t += th.sky.get(b).copied().unwrap_or(0.0) * d.projected_sr * a;
            }
        }
    }
    (total, sky)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sub-triangle centroids of `facet_points` average to the centroid and cover the
    /// facet with equal shares.
    #[test]
    fn facet_points_cover_the_triangle() {
        let fa = Facet {
            v: [
                DVec3::ZERO,
                DVec3::new(3.0, 0.0, 0.0),
                DVec3::new(0.0, 2.0, 1.0),
            ],
            material: 0,
            object: 0,
            kind: FacetKind::Mesh,
            two_sided: true,
        };
        for spacing in [10.0, 1.0, 0.37, 1e-9] {
            let mut pts = Vec::new();
            facet_points(&fa, spacing, &mut pts);
            let m = (pts.len() as f64).sqrt().round() as usize;
            assert_eq!(m * m, pts.len());
            let s: f64 = pts.iter().map(|p| p.1).sum();
            assert!((s - 1.0).abs() < 1e-12);
            let c: DVec3 = pts.iter().map(|p| p.0 * p.1).sum();
            let want = (fa.v[0] + fa.v[1] + fa.v[2]) / 3.0;
            assert!((c - want).length() < 1e-12, "{spacing}: {c} vs {want}");
        }
    }
}
