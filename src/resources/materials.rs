//! The optical-property library of a scene, resolved to indices (resource `Materials`).
//!
//! Resolution turns every entry into per-band values: numbers are copied as given, and
//! `ProspectLeaf` leaves are computed by PROSPECT (400–2500 nm at 1 nm) and integrated over each
//! band's spectral response.

use crate::physics::prospect::{ProspectData, ProspectModel, ProspectParams, prospect};
use crate::physics::spectral::SpectralBand;
use crate::scene::desc::{BandDesc, LadDesc, OpticsDesc};
use bevy_ecs::prelude::Resource;
use std::collections::BTreeMap;

/// Index of a material in [`Materials::list`].
pub type MaterialId = u32;

/// One resolved optical property. Per-band vectors have one value per scene band.
#[derive(Debug, Clone, PartialEq)]
pub enum MaterialKind {
    /// Lambertian facet: reflectance, diffuse transmittance, direct transmittance.
    Lambertian {
        /// Reflectance per band.
        reflectance: Vec<f64>,
        /// Diffuse transmittance per band.
        diffuse_transmittance: Vec<f64>,
        /// Direct transmittance (normal incidence) per band.
        direct_transmittance: Vec<f64>,
    },
    /// RPV facet (the desc is kept as written).
    Rpv(OpticsDesc),
    /// Hapke facet (the desc is kept as written).
    Hapke(OpticsDesc),
    /// Bi-Lambertian leaf (used as a two-sided facet or by turbid materials).
    Leaf {
        /// Reflectance per band.
        reflectance: Vec<f64>,
        /// Transmittance per band.
        transmittance: Vec<f64>,
    },
    /// Turbid vegetation.
    Turbid {
        /// Leaf reflectance per band.
        reflectance: Vec<f64>,
        /// Leaf transmittance per band.
        transmittance: Vec<f64>,
        /// Leaf angle distribution.
        lad: LadDesc,
        /// Leaf size for the hotspot, metres.
        leaf_size_m: f64,
        /// Specular leaf-surface component.
        specular: Option<crate::physics::lad::LeafSpecular>,
    },
}

/// A named material.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Name in the scene library (derived materials get a suffix).
    pub name: String,
    /// Properties.
    pub kind: MaterialKind,
}

impl MaterialKind {
    /// Lambertian facet model `(R, T_d, T_dir at normal incidence)` per band of a Lambertian
    /// property or a bi-Lambertian leaf (R = ρ_L, T_d = τ_L, no direct transmission;
    /// physics.md §5.1), `None` for other kinds.
    pub fn lambert_parts(&self) -> Option<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        match self {
            MaterialKind::Lambertian {
                reflectance,
                diffuse_transmittance,
                direct_transmittance,
            } => Some((
                reflectance.clone(),
                diffuse_transmittance.clone(),
                direct_transmittance.clone(),
            )),
            MaterialKind::Leaf {
                reflectance,
                transmittance,
            } => Some((
                reflectance.clone(),
                transmittance.clone(),
                vec![0.0; reflectance.len()],
            )),
            _ => None,
        }
    }

    /// Per-band BRDF models of an RPV/Hapke material (physics.md §5.2–5.3), `None` for other
    /// kinds.
    pub fn brdf_models(&self, nb: usize) -> Option<Vec<crate::physics::brdf::Brdf>> {
        use crate::physics::brdf::Brdf;
        use crate::scene::desc::OpticsDesc;
        match self {
            MaterialKind::Rpv(OpticsDesc::Rpv {
                rho0,
                k,
                theta,
                rho_c,
            }) => Some(
                (0..nb)
                    .map(|b| Brdf::Rpv {
                        rho0: rho0[b],
                        k: k[b],
                        theta: theta[b],
                        rho_c: rho_c.as_ref().map(|r| r[b]),
                    })
                    .collect(),
            ),
            MaterialKind::Hapke(OpticsDesc::Hapke {
                w,
                b,
                c,
                roughness_deg,
                b0,
                h,
            }) => Some(
                (0..nb)
                    .map(|k| Brdf::Hapke {
                        w: w[k],
                        b: b[k],
                        c: c[k],
                        theta_bar_deg: *roughness_deg,
                        b0: *b0,
                        h: *h,
                    })
                    .collect(),
            ),
            _ => None,
        }
    }
}

impl Material {
    /// True for turbid vegetation.
    pub fn is_turbid(&self) -> bool {
        matches!(self.kind, MaterialKind::Turbid { .. })
    }
}

/// An optical property that cannot be resolved to per-band values, e.g. a `ProspectLeaf` seen
/// by a band whose response reaches outside PROSPECT's 400–2500 nm.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("field `{field}`: {message}")]
pub struct MaterialError {
    /// Field path in the scene (`optics["leaf"]`).
    pub field: String,
    /// Why.
    pub message: String,
}

/// Leaf reflectance and transmittance per band from PROSPECT (Jacquemoud & Baret 1990; Féret et
/// al. 2008, 2017; `physics::prospect`): the 1 nm spectra R(λ), T(λ) over 400–2500 nm,
/// averaged over each band's response S as ∫ S R dλ / ∫ S dλ (exact for the linear
/// interpolants, `SpectralBand::band_average`; a monochromatic band takes the interpolated value
/// at its wavelength). Returns `(reflectance, transmittance)`, one value per band; errors are
/// messages (invalid parameters, or a band outside 400–2500 nm, named by `band_names`).
pub fn prospect_leaf_bands(
    model: ProspectModel,
    params: &ProspectParams,
    bands: &[SpectralBand],
    band_names: &[String],
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let leaf = prospect(model, params, ProspectData::builtin()).map_err(|e| e.to_string())?;
    let r = leaf.reflectance_spectrum().map_err(|e| e.to_string())?;
    let t = leaf.transmittance_spectrum().map_err(|e| e.to_string())?;
    let mut out = (
        Vec::with_capacity(bands.len()),
        Vec::with_capacity(bands.len()),
    );
    for (b, band) in bands.iter().enumerate() {
        let name = band_names.get(b).map_or("?", String::as_str);
        let avg = |s| {
            band.band_average(s).map_err(|e| {
                format!("PROSPECT (400–2500 nm) cannot be evaluated in band `{name}`: {e}")
            })
        };
        out.0.push(avg(&r)?);
        out.1.push(avg(&t)?);
    }
    Ok(out)
}

/// All materials of a scene.
#[derive(Debug, Clone, Default, Resource)]
pub struct Materials {
    /// Materials; the index is the [`MaterialId`].
    pub list: Vec<Material>,
}

impl Materials {
    /// Builds the library from a validated scene: `bands` as written and their spectral
    /// responses (`responses[b]` for `bands[b]`, used by `ProspectLeaf` leaves). Names are
    /// unique (BTreeMap keys). Errors name the optics entry (PROSPECT outside a band).
    pub fn from_desc(
        optics: &BTreeMap<String, OpticsDesc>,
        bands: &[BandDesc],
        responses: &[SpectralBand],
    ) -> Result<Self, MaterialError> {
        let nb = bands.len();
        let names: Vec<String> = bands.iter().map(|b| b.name.clone()).collect();
        // Per-band leaf values of every leaf entry (Turbid entries refer to them by name).
        let mut leaves: BTreeMap<&str, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
        for (name, o) in optics {
            match o {
                OpticsDesc::BiLambertian {
                    reflectance,
                    transmittance,
                } => {
                    leaves.insert(name, (reflectance.clone(), transmittance.clone()));
                }
                OpticsDesc::ProspectLeaf { .. } => {
                    let (model, params) = o.prospect_params().expect("a ProspectLeaf entry");
                    let rt = prospect_leaf_bands(model, &params, responses, &names).map_err(
                        |message| MaterialError {
                            field: format!("optics[\"{name}\"]"),
                            message,
                        },
                    )?;
                    leaves.insert(name, rt);
                }
                _ => {}
            }
        }
        let pad = |v: &Vec<f64>| {
            if v.is_empty() {
                vec![0.0; nb]
            } else {
                v.clone()
            }
        };
        let mut list = Vec::new();
        for (name, o) in optics {
            let kind = match o {
                OpticsDesc::Lambertian {
                    reflectance,
                    diffuse_transmittance,
                    direct_transmittance,
                } => MaterialKind::Lambertian {
                    reflectance: reflectance.clone(),
                    diffuse_transmittance: pad(diffuse_transmittance),
                    direct_transmittance: pad(direct_transmittance),
                },
                OpticsDesc::Rpv { .. } => MaterialKind::Rpv(o.clone()),
                OpticsDesc::Hapke { .. } => MaterialKind::Hapke(o.clone()),
                OpticsDesc::BiLambertian { .. } | OpticsDesc::ProspectLeaf { .. } => {
                    let (r, t) = leaves[name.as_str()].clone();
                    MaterialKind::Leaf {
                        reflectance: r,
                        transmittance: t,
                    }
                }
                OpticsDesc::Turbid {
                    leaf,
                    lad,
                    leaf_size_m,
                    specular,
                } => {
                    let (r, t) = leaves
                        .get(leaf.as_str())
                        .cloned()
                        .unwrap_or_else(|| (vec![0.0; nb], vec![0.0; nb]));
                    MaterialKind::Turbid {
                        reflectance: r,
                        transmittance: t,
                        lad: lad.clone(),
                        leaf_size_m: *leaf_size_m,
                        specular: *specular,
                    }
                }
            };
            list.push(Material {
                name: name.clone(),
                kind,
            });
        }
        Ok(Self { list })
    }

    /// Id of a named material (names were validated, so a miss is a programming error upstream).
    pub fn id(&self, name: &str) -> Option<MaterialId> {
        self.list
            .iter()
            .position(|m| m.name == name)
            .map(|i| i as MaterialId)
    }

    /// Adds a material and returns its id.
    pub fn push(&mut self, m: Material) -> MaterialId {
        self.list.push(m);
        (self.list.len() - 1) as MaterialId
    }
}
