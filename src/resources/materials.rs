//! The optical-property library of a scene, resolved to indices (resource `Materials`).

use crate::scene::desc::{LadDesc, OpticsDesc};
use bevy_ecs::prelude::Resource;

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

impl Material {
    /// True for turbid vegetation.
    pub fn is_turbid(&self) -> bool {
        matches!(self.kind, MaterialKind::Turbid { .. })
    }
}

/// All materials of a scene.
#[derive(Debug, Clone, Default, Resource)]
pub struct Materials {
    /// Materials; the index is the [`MaterialId`].
    pub list: Vec<Material>,
}

impl Materials {
    /// Builds the library from a validated scene (`nb` bands). Names are unique (BTreeMap keys).
    pub fn from_desc(optics: &std::collections::BTreeMap<String, OpticsDesc>, nb: usize) -> Self {
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
                OpticsDesc::BiLambertian {
                    reflectance,
                    transmittance,
                } => MaterialKind::Leaf {
                    reflectance: reflectance.clone(),
                    transmittance: transmittance.clone(),
                },
                OpticsDesc::Turbid {
                    leaf,
                    lad,
                    leaf_size_m,
                } => {
                    let (r, t) = match optics.get(leaf) {
                        Some(OpticsDesc::BiLambertian {
                            reflectance,
                            transmittance,
                        }) => (reflectance.clone(), transmittance.clone()),
                        _ => (vec![0.0; nb], vec![0.0; nb]),
                    };
                    MaterialKind::Turbid {
                        reflectance: r,
                        transmittance: t,
                        lad: lad.clone(),
                        leaf_size_m: *leaf_size_m,
                    }
                }
            };
            list.push(Material {
                name: name.clone(),
                kind,
            });
        }
        Self { list }
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
