//! Thermal sources of a scene (issue #34; physics.md §7): `ε B(T)` per turbid entry, facet
//! and flat-ground column and band from the materials' optics (Kirchhoff emissivities) and the
//! run's temperatures — fixed per optics key or following illumination (each element's
//! directly lit fraction from a launch-only sun pass) — for
//! [`ThermalSources`].

use crate::radiative::engine::{RadiativeInput, RadiativeResult, ThermalSources, TrackOptics};
use crate::resources::facets::{FacetKind, FacetStore};
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::materials::{MaterialId, MaterialKind, Materials};
use crate::resources::scene::{SceneInfo, ThermalRun};
use std::collections::HashMap;

/// `ε B(T)` per turbid entry, facet and flat-ground column and band
/// (physics.md §7.1–7.2): B the band-averaged Planck radiance at the temperature of the
/// element's optics key (a material derived from a key, `key@objects[i]`, takes the key's),
/// ε Kirchhoff's `1 − ρ_L − τ_L` (turbid leaves), `1 − R − T_d` (Lambertian facets) or
/// `1 − ρ` (Lambertian ground); the thermal sky `B(T_sky)`. What lies in contact inside a
/// building does not emit (its rays would start in the ground or pass through the one-sided
/// shell from inside): floors (one-sided wall facets facing down), DEM facets whose centroid is
/// under a footprint, and a flat-ground column's share covered by footprints.
pub fn thermal_sources(
    run: &ThermalRun,
    info: &SceneInfo,
    mats: &Materials,
    (grid, facets, spec): (&CellGrid, &FacetStore, &GridSpec),
    flat_ground: Option<MaterialId>,
    footprints: &[Vec<glam::DVec2>],
    lit: Option<&SunlitFractions>,
) -> Result<ThermalSources, String> {
    let nb = info.bands.len();
    let planck = |t: f64| -> Result<Vec<f64>, String> {
        info.band_responses
            .iter()
            .map(|r| {
                crate::physics::thermal::band_planck(r, t)
                    .map_err(|e| format!("{}: thermal: {e}", info.source.display()))
            })
            .collect()
    };
    // ε B per material and band (`None`: the material does not emit).
    let mut per_mat: Vec<Option<Vec<f64>>> = Vec::with_capacity(mats.list.len());
    let mut eps_mat: Vec<Option<Vec<f64>>> = Vec::with_capacity(mats.list.len());
    for m in &mats.list {
        let key = m.name.split('@').next().unwrap_or(&m.name);
        let eps: Option<Vec<f64>> = match &m.kind {
            MaterialKind::Turbid {
                reflectance,
                transmittance,
                ..
            }
            | MaterialKind::Leaf {
                reflectance,
                transmittance,
            } => Some(
                (0..nb)
                    .map(|b| 1.0 - reflectance[b] - transmittance.get(b).copied().unwrap_or(0.0))
                    .collect(),
            ),
            MaterialKind::Lambertian {
                reflectance,
                diffuse_transmittance,
                ..
            } => Some(
                (0..nb)
                    .map(|b| {
                        1.0 - reflectance[b] - diffuse_transmittance.get(b).copied().unwrap_or(0.0)
                    })
                    .collect(),
            ),
            // A flat ground with a BRDF: B(T), the tracker applies 1 − ρ_dh(Ω) per direction
            // (validation refuses BRDF facets in thermal runs).
            MaterialKind::Rpv(_) | MaterialKind::Hapke(_) => Some(vec![1.0; nb]),
        };
        eps_mat.push(eps.clone());
        per_mat.push(match (eps, run.desc.temperature_of(key)) {
            (Some(eps), Some(t)) => {
                let b = planck(t)?;
                Some((0..nb).map(|i| eps[i].max(0.0) * b[i]).collect())
            }
            _ => None,
        });
    }
    let need = |id: MaterialId| -> Result<&Vec<f64>, String> {
        per_mat[id as usize].as_ref().ok_or_else(|| {
            let m = &mats.list[id as usize];
            format!(
                "{}: thermal.temperatures_k: no temperature for optics `{}` (mode {}), which an emitting element is made of",
                info.source.display(),
                m.name.split('@').next().unwrap_or(&m.name),
                run.mode.name()
            )
        })
    };
    let mut out = ThermalSources::default();
    out.turbid.reserve(grid.turbid.len() * nb);
    // ε B at an element's own temperature when its key's temperature follows illumination
    // (`sunlit_temperatures_k`), else its material's (`per_mat`).
    let mut at_f = LitPlanck::new(run, info, mats, &eps_mat);
    for (k, e) in grid.turbid.iter().enumerate() {
        match lit.and_then(|l| at_f.get(e.material, l.turbid[k])) {
            Some(v) => out.turbid.extend_from_slice(&v?),
            None => out.turbid.extend_from_slice(need(e.material)?),
        }
    }
    let under_building = |q: glam::DVec2| {
        footprints
            .iter()
            .any(|p| crate::geometry::polygon::contains(p, q))
    };
    out.facet.reserve(facets.facets.len() * nb);
    for f in &facets.facets {
        let n = (f.v[1] - f.v[0])
            .cross(f.v[2] - f.v[0])
            .normalize_or(glam::DVec3::Z);
        let c = (f.v[0] + f.v[1] + f.v[2]) / 3.0;
        let buried = match f.kind {
            FacetKind::Wall => !f.two_sided && n.z < -0.99,
            FacetKind::Ground => under_building(c.truncate()),
            _ => false,
        };
        if buried {
            out.facet.extend(std::iter::repeat_n(0.0, nb));
        } else {
            let i = out.facet.len() / nb.max(1);
            match lit.and_then(|l| at_f.get(f.material, l.facet[i])) {
                Some(v) => out.facet.extend_from_slice(&v?),
                None => out.facet.extend_from_slice(need(f.material)?),
            }
        }
    }
    if let Some(g) = flat_ground {
        let eb = need(g)?;
        let (dx, dy) = (spec.cell.x, spec.cell.y);
        for c in 0..spec.n[0] * spec.n[1] {
            let (i, j) = ((c % spec.n[0]) as f64, (c / spec.n[0]) as f64);
            let (x0, y0) = (spec.origin.x + i * dx, spec.origin.y + j * dy);
            let covered: f64 = footprints
                .iter()
                .map(|p| crate::geometry::polygon::rect_overlap_area(p, x0, y0, x0 + dx, y0 + dy))
                .sum::<f64>()
                / (dx * dy);
            let open = (1.0 - covered).clamp(0.0, 1.0);
            match lit.and_then(|l| at_f.get(g, l.ground[c])) {
                Some(v) => out.ground.extend(v?.iter().map(|v| v * open)),
                None => out.ground.extend(eb.iter().map(|v| v * open)),
            }
        }
    }
    if let Some(t) = run.desc.sky_temperature_k {
        out.sky = planck(t)?;
    }
    Ok(out)
}

/// The directly lit fraction of every element (for `sunlit_temperatures_k`), from a
/// launch-only pass of the sun (no sky, no scattering): per turbid entry the direct power it
/// intercepted over `E⊥ G(Ω_s) u V` (the mean transmittance of the direct beam over its
/// leaves), per facet over `E⊥ A |n·Ω_s| (1 − T_dir^{1/|μ|})` (its lit area share), per
/// flat-ground column over `E_h a`; clamped to [0, 1].
pub struct SunlitFractions {
    /// Per turbid entry.
    pub turbid: Vec<f64>,
    /// Per facet.
    pub facet: Vec<f64>,
    /// Per flat-ground column.
    pub ground: Vec<f64>,
}

/// [`SunlitFractions`] of the launch-only (sun, no sky, one pass) result `r` of `inp`.
pub fn sunlit_fractions(inp: &RadiativeInput, r: &RadiativeResult) -> SunlitFractions {
    let w = r.n_channels;
    // The first band the sun lights (the fractions are geometric: any band gives them).
    let b = inp.e_dir.iter().position(|&e| e > 0.0);
    let mu_s = (-inp.sun.z).max(1e-12);
    let spec = inp.spec;
    let frac = |x: f64, full: f64| {
        if full > 0.0 {
            (x / full).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let Some(b) = b else {
        return SunlitFractions {
            turbid: vec![0.0; inp.grid.turbid.len()],
            facet: vec![0.0; inp.facets.len()],
            ground: vec![0.0; spec.n[0] * spec.n[1]],
        };
    };
    let e_perp = inp.e_dir[b] / mu_s;
    let vol = spec.cell.x * spec.cell.y * spec.cell.z;
    let turbid = inp
        .grid
        .turbid
        .iter()
        .enumerate()
        .map(|(k, e)| {
            let g = match &inp.optics[e.material as usize] {
                TrackOptics::Turbid { g, .. } => g.last().copied().unwrap_or(0.5),
                _ => 0.0,
            };
            frac(
                r.intercepted_turbid[k * w + b],
                e_perp * g * e.density as f64 * vol,
            )
        })
        .collect();
    let facet = inp
        .facets
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let n2 = (f.v[1] - f.v[0]).cross(f.v[2] - f.v[0]);
            let mu = n2.normalize_or(glam::DVec3::Z).dot(inp.sun).abs();
            let open = match &inp.optics[f.material as usize] {
                TrackOptics::Lambert { t_dir, .. } => {
                    let t = t_dir.get(b).copied().unwrap_or(0.0);
                    if t > 0.0 {
                        1.0 - t.powf(1.0 / mu.max(1e-12))
                    } else {
                        1.0
                    }
                }
                _ => 1.0,
            };
            frac(
                r.intercepted_facet[i * w + b],
                e_perp * 0.5 * n2.length() * mu * open,
            )
        })
        .collect();
    let a = spec.cell.x * spec.cell.y;
    let ground = (0..spec.n[0] * spec.n[1])
        .map(|c| frac(r.intercepted_ground[c * w + b], inp.e_dir[b] * a))
        .collect();
    SunlitFractions {
        turbid,
        facet,
        ground,
    }
}

/// `ε B(T(f))` per band for materials whose key's temperature follows illumination, cached
/// per (material, f to 1e-4).
struct LitPlanck<'a> {
    run: &'a ThermalRun,
    info: &'a SceneInfo,
    mats: &'a Materials,
    eps: &'a [Option<Vec<f64>>],
    cache: HashMap<(u32, u32), Vec<f64>>,
}

impl<'a> LitPlanck<'a> {
    fn new(
        run: &'a ThermalRun,
        info: &'a SceneInfo,
        mats: &'a Materials,
        eps: &'a [Option<Vec<f64>>],
    ) -> Self {
        LitPlanck {
            run,
            info,
            mats,
            eps,
            cache: HashMap::new(),
        }
    }

    /// `ε B` of material `m` lit over fraction `f`; `Ok(None)` when its key's temperature does
    /// not follow illumination.
    fn get(&mut self, m: u32, f: f64) -> Option<Result<Vec<f64>, String>> {
        let mat = &self.mats.list[m as usize];
        let key = mat.name.split('@').next().unwrap_or(&mat.name);
        if !self.run.desc.sunlit_temperatures_k.contains_key(key) {
            return None;
        }
        let eps = self.eps[m as usize].as_ref()?;
        let q = (f.clamp(0.0, 1.0) * 1e4).round() as u32;
        if let Some(v) = self.cache.get(&(m, q)) {
            return Some(Ok(v.clone()));
        }
        let t = self.run.desc.temperature_at(key, q as f64 * 1e-4)?;
        let v: Result<Vec<f64>, String> = self
            .info
            .band_responses
            .iter()
            .zip(eps)
            .map(|(r, e)| {
                crate::physics::thermal::band_planck(r, t)
                    .map(|b| e.max(0.0) * b)
                    .map_err(|e| format!("{}: thermal: {e}", self.info.source.display()))
            })
            .collect();
        if let Ok(v) = &v {
            self.cache.insert((m, q), v.clone());
        }
        Some(v)
    }
}
