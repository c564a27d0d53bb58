//! Photon: the Monte Carlo optics of every material ([`PhotonOptics`]): leaf-normal samplers,
//! Γ kernels and G(μ) tables of turbid materials (built once per LAD and shared through
//! [`LadCache`]), the discrete-direction rows of DART Ray-Carlo, Lambertian and RPV/Hapke
//! facet models (physics.md §3.3, §6).

use crate::photon::engine::{DiscreteRows, PhotonOptics, SamplerKind};
use crate::photon::sampling::{BrdfSampler, LeafSampler};
use crate::physics::lad::{GTable, LeafAngleDistribution, VolscattKernel};
use crate::radiative::engine::TrackOptics;
use crate::resources::materials::{MaterialKind, Materials};
use crate::resources::tracking::OpticsTables;
use crate::scene::desc::LadDesc;
use std::sync::Arc;

/// Inclination bins of the Γ kernel used for peel-off values of non-spherical LADs (the
/// spherical LAD uses its closed form); the binning error is O(n⁻²) (physics.md §3.3).
pub const PEEL_LAD_BINS: usize = 180;
/// Intervals of the G(μ) table (interpolation error ≈ 1e-8 for the classical LADs).
pub const G_TABLE_INTERVALS: usize = 4096;

/// The LAD-derived part of a turbid material's photon optics (leaf-normal sampler, Γ kernel,
/// G table), by far the costly part of [`build_photon_optics`]: the G table alone is
/// [`G_TABLE_INTERVALS`]` + 1` tanh–sinh quadratures (≈320 M instructions for a non-spherical
/// LAD). Built once per LAD and run, and shared by the passive Monte Carlo solver and every
/// LiDAR instrument of the Photon stage (keyed by the LAD itself, so materials with the same
/// LAD share one entry).
#[derive(Default)]
pub struct LadCache(Vec<(LadDesc, Arc<LadOptics>)>);

/// One entry of [`LadCache`].
#[derive(Debug)]
pub struct LadOptics {
    sampler: LeafSampler,
    kernel: VolscattKernel,
    g: GTable,
}

impl LadCache {
    /// The optics of `lad`, built on first use.
    fn get(&mut self, lad: &LadDesc) -> Result<Arc<LadOptics>, String> {
        if let Some((_, o)) = self.0.iter().find(|(l, _)| l == lad) {
            return Ok(o.clone());
        }
        let d = LeafAngleDistribution::new(lad).map_err(|e| e.to_string())?;
        let o = Arc::new(LadOptics {
            sampler: LeafSampler::new(&d).map_err(|e| e.to_string())?,
            kernel: VolscattKernel::new(&d, PEEL_LAD_BINS, false),
            g: GTable::new(&d, G_TABLE_INTERVALS),
        });
        self.0.push((lad.clone(), o.clone()));
        Ok(o)
    }
}

/// Photon-tracker optics of every material (`used[id]`: turbid materials a component uses);
/// the LAD-derived parts come from (and go into) `cache`.
pub fn build_photon_optics(
    mats: &Materials,
    used: &[bool],
    tables: Option<&OpticsTables>,
    sampler: SamplerKind,
    nb: usize,
    cache: &mut LadCache,
) -> Result<Vec<PhotonOptics>, String> {
    let mut optics = Vec::with_capacity(mats.list.len());
    for (id, m) in mats.list.iter().enumerate() {
        let o = match &m.kind {
            MaterialKind::Turbid {
                reflectance,
                transmittance,
                lad,
                specular,
                leaf_size_m,
            } if used[id] => {
                if specular.is_some() {
                    return Err(format!(
                        "material `{}`: specular leaves are not supported by the Monte Carlo solver yet (use the flux-tracking solver)",
                        m.name
                    ));
                }
                let lo = cache
                    .get(lad)
                    .map_err(|e| format!("material `{}`: {e}", m.name))?;
                let discrete = if sampler.is_discrete() {
                    let Some(TrackOptics::Turbid { tables, .. }) =
                        tables.and_then(|t| t.optics.get(id))
                    else {
                        return Err(format!(
                            "material `{}`: discrete Monte Carlo needs the Phase tables",
                            m.name
                        ));
                    };
                    match DiscreteRows::new(tables.clone(), sampler) {
                        Ok(r) => Some(r),
                        Err(e) => {
                            return Err(format!("material `{}`: {e}", m.name));
                        }
                    }
                } else {
                    None
                };
                PhotonOptics::Turbid {
                    sampler: lo.sampler.clone(),
                    kernel: lo.kernel.clone(),
                    g: lo.g.clone(),
                    rho: reflectance.clone(),
                    tau: transmittance.clone(),
                    discrete,
                    leaf_size_m: *leaf_size_m,
                }
            }
            MaterialKind::Lambertian { .. } | MaterialKind::Leaf { .. } => {
                let (r, t, t_dir) = m.kind.lambert_parts().expect("Lambertian kind");
                PhotonOptics::Lambert { r, t, t_dir }
            }
            k @ (MaterialKind::Rpv(_) | MaterialKind::Hapke(_)) => {
                let models = k.brdf_models(nb).expect("RPV/Hapke");
                // The sampler follows band 0's BRDF; other bands are reweighted (unbiased:
                // RPV and Hapke BRFs are positive wherever band 0's is).
                match BrdfSampler::new(&models[0], Default::default()) {
                    Ok(sampler) => PhotonOptics::Brdf { models, sampler },
                    Err(e) => {
                        return Err(format!("material `{}`: {e}", m.name));
                    }
                }
            }
            _ => PhotonOptics::Unused,
        };
        optics.push(o);
    }
    Ok(optics)
}
