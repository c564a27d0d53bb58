//! `lumenscape generate KIND [flags] > scene.ron`: the programmatic generators on the command
//! line; the scene is printed as RON on stdout.

use super::scene_cmds::CliError;
use crate::scene::desc::LadDesc;
use crate::scene::generators::{BandOptics, disk_canopy, forest, rami, turbid_layer, urban};
use std::io::Write;

/// Parses a LAD name: spherical, uniform, planophile, erectophile, plagiophile, extremophile,
/// ellipsoidal:MEAN_DEG, beta:MU,NU.
pub fn parse_lad(s: &str) -> Result<LadDesc, String> {
    let l = s.to_ascii_lowercase();
    Ok(match l.as_str() {
        "spherical" => LadDesc::Spherical,
        "uniform" => LadDesc::Uniform,
        "planophile" => LadDesc::Planophile,
        "erectophile" => LadDesc::Erectophile,
        "plagiophile" => LadDesc::Plagiophile,
        "extremophile" => LadDesc::Extremophile,
        _ => {
            if let Some(v) = l.strip_prefix("ellipsoidal:") {
                LadDesc::Ellipsoidal {
                    mean_angle_deg: v.parse().map_err(|_| format!("bad mean angle in `{s}`"))?,
                }
            } else if let Some(v) = l.strip_prefix("beta:") {
                let (a, b) = v
                    .split_once(',')
                    .ok_or_else(|| format!("`{s}`: expected beta:MU,NU"))?;
                LadDesc::Beta {
                    mu: a.parse().map_err(|_| format!("bad μ in `{s}`"))?,
                    nu: b.parse().map_err(|_| format!("bad ν in `{s}`"))?,
                }
            } else {
                return Err(format!(
                    "unknown LAD `{s}` (spherical, uniform, planophile, erectophile, plagiophile, extremophile, ellipsoidal:MEAN_DEG, beta:MU,NU)"
                ));
            }
        }
    })
}

/// Optics and sun flags shared by the vegetation generators.
#[derive(clap::Args, Debug, Clone)]
pub struct OpticsFlags {
    /// Leaf reflectance (single band named `red`; ignored when --band is given).
    #[arg(long, default_value_t = 0.0546)]
    pub leaf_r: f64,
    /// Leaf transmittance.
    #[arg(long, default_value_t = 0.0149)]
    pub leaf_t: f64,
    /// Soil reflectance.
    #[arg(long, default_value_t = 0.127)]
    pub soil_r: f64,
    /// A band `NAME[@NM]:leaf_r,leaf_t,soil_r` (repeat for several bands).
    #[arg(long = "band")]
    pub bands: Vec<String>,
    /// Sun zenith angle (ground→sun), degrees.
    #[arg(long, default_value_t = 20.0)]
    pub sun_zenith: f64,
    /// Sun azimuth (ground→sun, anticlockwise from +x), degrees.
    #[arg(long, default_value_t = 0.0)]
    pub sun_azimuth: f64,
    /// Run mode written into the scene's `thermal` section: `r`, `t` (emission only) or `rt`
    /// (both); with `t`/`rt` the temperatures below are required.
    #[arg(long, value_enum)]
    pub mode: Option<super::scene_cmds::ModeArg>,
    /// Leaf (turbid and leaf optics) temperature, K.
    #[arg(long)]
    pub leaf_temperature_k: Option<f64>,
    /// Soil (and every other Lambertian surface) temperature, K.
    #[arg(long)]
    pub soil_temperature_k: Option<f64>,
    /// Brightness temperature of an isotropic sky, K (absent: a cold sky).
    #[arg(long)]
    pub sky_temperature_k: Option<f64>,
    #[command(flatten)]
    /// An atmosphere over the scene.
    pub atmosphere: AtmosphereFlags,
}

/// Atmosphere flags of the vegetation generators: any of them puts an `atmosphere` over the
/// scene (then run it with `--solver monte-carlo`; the irradiance is at the TOA).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct AtmosphereFlags {
    /// Rayleigh optical depth of the column, the same in every band (pure Rayleigh phase,
    /// depolarisation 0, as DISORT-type oracles use).
    #[arg(long, conflicts_with = "rayleigh")]
    pub rayleigh_tau: Option<f64>,
    /// Rayleigh optical depth of Bodhaine et al. (1999) at each band's wavelength, air's
    /// depolarisation 0.0279.
    #[arg(long)]
    pub rayleigh: bool,
    /// Aerosol extinction optical depth of the column, the same in every band.
    #[arg(long)]
    pub aerosol_tau: Option<f64>,
    /// Aerosol single-scattering albedo (with --aerosol-tau).
    #[arg(long, default_value_t = 0.9, requires = "aerosol_tau")]
    pub aerosol_ssa: f64,
    /// Aerosol Henyey–Greenstein asymmetry g (with --aerosol-tau).
    #[arg(long, default_value_t = 0.7, requires = "aerosol_tau")]
    pub aerosol_g: f64,
}

impl AtmosphereFlags {
    /// The `atmosphere` section these flags describe for `nb` bands (`None`: no flag given).
    fn desc(&self, nb: usize) -> Option<crate::scene::desc::AtmosphereDesc> {
        use crate::physics::phase::{AIR_DEPOLARIZATION, FluidPhase};
        use crate::scene::desc::{AerosolsDesc, AtmosphereDesc, MoleculesDesc};
        let molecules = match (self.rayleigh_tau, self.rayleigh) {
            (Some(t), _) => Some(MoleculesDesc {
                tau: Some(vec![t; nb]),
                pressure_hpa: 1013.25,
                depolarization: 0.0,
                scale_height_km: 8.4,
            }),
            (None, true) => Some(MoleculesDesc {
                tau: None,
                pressure_hpa: 1013.25,
                depolarization: AIR_DEPOLARIZATION,
                scale_height_km: 8.4,
            }),
            (None, false) => None,
        };
        let aerosols = self.aerosol_tau.map(|t| AerosolsDesc {
            tau: Some(vec![t; nb]),
            tau_reference: None,
            reference_wavelength_nm: 550.0,
            angstrom_exponent: 0.0,
            ssa: vec![self.aerosol_ssa; nb],
            phase: FluidPhase::HenyeyGreenstein { g: self.aerosol_g },
            scale_height_km: 1.0,
        });
        (molecules.is_some() || aerosols.is_some()).then_some(AtmosphereDesc {
            toa_altitude_km: 100.0,
            layer_altitudes_km: None,
            molecules,
            aerosols,
            gas: None,
        })
    }
}

impl OpticsFlags {
    /// The `thermal` section of `--mode` and the temperatures (scene keys: turbid and leaf
    /// optics take the leaf temperature, Lambertian ones the soil's); `None` without
    /// `--mode`. Temperatures without `--mode` are refused (they would be silently unused).
    fn thermal(
        &self,
        optics: &std::collections::BTreeMap<String, crate::scene::desc::OpticsDesc>,
    ) -> Result<Option<crate::scene::desc::ThermalDesc>, String> {
        use crate::scene::desc::{OpticsDesc, RunMode, ThermalDesc};
        let Some(m) = self.mode else {
            if self.leaf_temperature_k.is_some()
                || self.soil_temperature_k.is_some()
                || self.sky_temperature_k.is_some()
            {
                return Err("temperatures need --mode t or rt".into());
            }
            return Ok(None);
        };
        let mode = match m {
            super::scene_cmds::ModeArg::R => RunMode::R,
            super::scene_cmds::ModeArg::T => RunMode::T,
            super::scene_cmds::ModeArg::Rt => RunMode::RT,
        };
        let mut temperatures_k = std::collections::BTreeMap::new();
        for (k, o) in optics {
            let (t, flag) = match o {
                OpticsDesc::Lambertian { .. } => (self.soil_temperature_k, "--soil-temperature-k"),
                _ => (self.leaf_temperature_k, "--leaf-temperature-k"),
            };
            match t {
                Some(t) => {
                    temperatures_k.insert(k.clone(), t);
                }
                None if mode.thermal() => {
                    return Err(format!("--mode {}: {flag} is required", mode.name()));
                }
                None => {}
            }
        }
        Ok(Some(ThermalDesc {
            mode,
            temperatures_k,
            sunlit_temperatures_k: Default::default(),
            default_temperature_k: None,
            sky_temperature_k: self.sky_temperature_k,
        }))
    }

    fn bands(&self) -> Result<Vec<BandOptics>, String> {
        if self.bands.is_empty() {
            Ok(vec![BandOptics {
                name: "red".into(),
                wavelength_nm: 670.0,
                leaf_r: self.leaf_r,
                leaf_t: self.leaf_t,
                soil_r: self.soil_r,
            }])
        } else {
            self.bands.iter().map(|b| BandOptics::parse(b)).collect()
        }
    }
}

/// Generator kinds.
#[derive(clap::Subcommand, Debug)]
pub enum Kind {
    /// Horizontally homogeneous turbid canopy on a periodic scene.
    TurbidLayer {
        /// Leaf area index.
        #[arg(long, default_value_t = 3.0)]
        lai: f64,
        /// Leaf angle distribution.
        #[arg(long, default_value = "spherical", value_parser = parse_lad)]
        lad: LadDesc,
        /// Canopy height, metres.
        #[arg(long, default_value_t = 2.0)]
        height: f64,
        /// Cell size, metres.
        #[arg(long, default_value_t = 0.5)]
        cell_size: f64,
        /// Scene side, metres.
        #[arg(long, default_value_t = 2.0)]
        size: f64,
        /// Leaf size of every turbid material, metres (DART `dimFoliar`, the hotspot's leaf
        /// dimension); 0 = no hotspot, the pure turbid medium that DISORT-type oracles solve.
        #[arg(long)]
        leaf_size: Option<f64>,
        #[command(flatten)]
        /// Optics and sun.
        optics: OpticsFlags,
    },
    /// RAMI HOM-style canopy of random non-intersecting disk leaves.
    DiskCanopy {
        /// Leaf area index.
        #[arg(long, default_value_t = 1.0)]
        lai: f64,
        /// Disk radius, metres.
        #[arg(long, default_value_t = 0.05)]
        disk_radius: f64,
        /// Canopy height, metres.
        #[arg(long, default_value_t = 1.0)]
        height: f64,
        /// Scene side, metres.
        #[arg(long, default_value_t = 2.0)]
        size: f64,
        /// Cell size, metres.
        #[arg(long, default_value_t = 0.5)]
        cell_size: f64,
        /// Leaf angle distribution.
        #[arg(long, default_value = "spherical", value_parser = parse_lad)]
        lad: LadDesc,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Use the leaves of this RAMI leaf list (radius x y z nx ny nz per line) instead of
        /// drawing them; the scene refers to the file by its absolute path.
        #[arg(long)]
        leaves: Option<std::path::PathBuf>,
        #[command(flatten)]
        /// Optics and sun.
        optics: OpticsFlags,
    },
    /// A seeded stand of broadleaf and conifer trees on flat ground or a slope.
    Forest {
        /// Scene side, metres.
        #[arg(long, default_value_t = 40.0)]
        size: f64,
        /// Cell size, metres.
        #[arg(long, default_value_t = 1.0)]
        cell_size: f64,
        /// Number of broadleaf trees.
        #[arg(long, default_value_t = 12)]
        broadleaf: usize,
        /// Number of conifers.
        #[arg(long, default_value_t = 12)]
        conifer: usize,
        /// Minimum trunk spacing, metres.
        #[arg(long, default_value_t = 3.0)]
        min_spacing: f64,
        /// Ground slope along +x, degrees.
        #[arg(long, default_value_t = 0.0)]
        slope: f64,
        /// Crown size jitter (fraction).
        #[arg(long, default_value_t = 0.0)]
        jitter: f64,
        /// Random seed.
        #[arg(long, default_value_t = 7)]
        seed: u64,
        /// Sun zenith, degrees.
        #[arg(long, default_value_t = 30.0)]
        sun_zenith: f64,
        /// Sun azimuth, degrees.
        #[arg(long, default_value_t = 225.0)]
        sun_azimuth: f64,
        /// Leaf size of every turbid material, metres (DART `dimFoliar`, the hotspot's leaf
        /// dimension); 0 = no hotspot, the pure turbid medium that DISORT-type oracles solve.
        #[arg(long)]
        leaf_size: Option<f64>,
    },
    /// A RAMI-3 benchmark case from its experiment identifier (HOM turbid/discrete layers,
    /// HET01/HET02 floating spheres), with the RAMI measurement directions as exact views.
    Rami {
        /// Experiment identifier, e.g. HOM13_DIS_PLA_NIR_20 or HET01_DIS_UNI_RED_20.
        #[arg(long)]
        case: String,
        /// Scene side, metres (HOM only; default 2 m turbid, 25 m discrete).
        #[arg(long)]
        size: Option<f64>,
        /// Cell size, metres (default 0.5 m HOM, 1 m HET).
        #[arg(long)]
        cell_size: Option<f64>,
        /// Random seed (drawn discs, sphere positions).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Sun azimuth (ground→sun, anticlockwise from +x), degrees.
        #[arg(long, default_value_t = 0.0)]
        sun_azimuth: f64,
        /// RAMI leaf file (R Xc Yc Zc Dx Dy Dz per line): the whole canopy for HOM discrete
        /// cases, one sphere's leaves for HET01; the scene refers to it by its absolute path.
        #[arg(long)]
        leaves: Option<std::path::PathBuf>,
    },
    /// A block of buildings with streets and street trees.
    Urban {
        /// Buildings per side.
        #[arg(long, default_value_t = 3)]
        blocks: usize,
        /// Building side, metres.
        #[arg(long, default_value_t = 12.0)]
        building: f64,
        /// Street width, metres.
        #[arg(long, default_value_t = 8.0)]
        street: f64,
        /// Cell size, metres.
        #[arg(long, default_value_t = 1.0)]
        cell_size: f64,
        /// Random seed.
        #[arg(long, default_value_t = 3)]
        seed: u64,
        /// Leaf size of every turbid material, metres (DART `dimFoliar`, the hotspot's leaf
        /// dimension); 0 = no hotspot, the pure turbid medium that DISORT-type oracles solve.
        #[arg(long)]
        leaf_size: Option<f64>,
    },
}

/// `generate` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// What to generate.
    #[command(subcommand)]
    pub kind: Kind,
}

/// Runs `generate`: prints the scene as RON.
pub fn run(args: &Args, out: &mut dyn Write) -> Result<(), CliError> {
    let leaf_size = match &args.kind {
        Kind::TurbidLayer { leaf_size, .. }
        | Kind::Forest { leaf_size, .. }
        | Kind::Urban { leaf_size, .. } => *leaf_size,
        _ => None,
    };
    if let Some(x) = leaf_size
        && !(x.is_finite() && x >= 0.0)
    {
        return Err(format!("--leaf-size: {x} is not a length ≥ 0 m").into());
    }
    let mut desc = generate_scene(&args.kind)?;
    if let Kind::TurbidLayer { optics, .. } | Kind::DiskCanopy { optics, .. } = &args.kind {
        desc.atmosphere = optics.atmosphere.desc(desc.bands.len());
    }
    if let Some(x) = leaf_size {
        for o in desc.optics.values_mut() {
            if let crate::scene::desc::OpticsDesc::Turbid { leaf_size_m, .. } = o {
                *leaf_size_m = x;
            }
        }
    }
    if let Kind::TurbidLayer { optics, .. } | Kind::DiskCanopy { optics, .. } = &args.kind {
        desc.thermal = optics.thermal(&desc.optics)?;
    }
    // Refuse to print a scene that would not load.
    crate::scene::validate::validate(&desc, &crate::scene::SceneSource::generated())?;
    out.write_all(crate::scene::to_ron(&desc).as_bytes())?;
    writeln!(out)?;
    Ok(())
}

/// Step of [`run`]: the scene of the generator `kind` with its arguments (before the
/// `--leaf-size` override).
fn generate_scene(kind: &Kind) -> Result<crate::scene::desc::SceneDesc, CliError> {
    Ok(match kind {
        Kind::TurbidLayer {
            lai,
            lad,
            height,
            cell_size,
            size,
            optics,
            ..
        } => turbid_layer::turbid_layer(&turbid_layer::TurbidLayerParams {
            lai: *lai,
            lad: lad.clone(),
            bands: optics.bands()?,
            height_m: *height,
            cell_m: *cell_size,
            size_m: *size,
            sun_zenith_deg: optics.sun_zenith,
            sun_azimuth_deg: optics.sun_azimuth,
        }),
        Kind::DiskCanopy {
            lai,
            disk_radius,
            height,
            size,
            cell_size,
            lad,
            seed,
            leaves,
            optics,
        } => {
            let params = disk_canopy::DiskCanopyParams {
                lai: *lai,
                disk_radius_m: *disk_radius,
                height_m: *height,
                size_m: *size,
                cell_m: *cell_size,
                lad: lad.clone(),
                seed: *seed,
                bands: optics.bands()?,
                sun_zenith_deg: optics.sun_zenith,
                sun_azimuth_deg: optics.sun_azimuth,
            };
            match leaves {
                Some(path) => {
                    let abs = checked_leaf_list(path)?;
                    disk_canopy::disk_canopy_from_list(&params, &abs.to_string_lossy())
                }
                None => disk_canopy::disk_canopy(&params)?,
            }
        }
        Kind::Forest {
            size,
            cell_size,
            broadleaf,
            conifer,
            min_spacing,
            slope,
            jitter,
            seed,
            sun_zenith,
            sun_azimuth,
            ..
        } => forest::forest(&forest::ForestParams {
            size_m: *size,
            cell_m: *cell_size,
            species: vec![forest::broadleaf(*broadleaf), forest::conifer(*conifer)],
            min_spacing_m: *min_spacing,
            slope_deg: *slope,
            seed: *seed,
            size_jitter: *jitter,
            sun_zenith_deg: *sun_zenith,
            sun_azimuth_deg: *sun_azimuth,
            ..Default::default()
        }),
        Kind::Rami {
            case,
            size,
            cell_size,
            seed,
            sun_azimuth,
            leaves,
        } => {
            let case = rami::RamiCase::parse(case)?;
            let leaves = match leaves {
                Some(path) => Some(checked_leaf_list(path)?.to_string_lossy().into_owned()),
                None => None,
            };
            rami::rami_scene(
                &case,
                &rami::RamiOptions {
                    size_m: *size,
                    cell_m: *cell_size,
                    seed: *seed,
                    sun_azimuth_deg: *sun_azimuth,
                    leaves,
                },
            )?
        }
        Kind::Urban {
            blocks,
            building,
            street,
            cell_size,
            seed,
            ..
        } => urban::urban(&urban::UrbanParams {
            blocks: *blocks,
            building_m: *building,
            street_m: *street,
            cell_m: *cell_size,
            seed: *seed,
            ..Default::default()
        }),
    })
}

/// Step of [`generate_scene`]: the canonical path of a `--leaves` list, checked now (read and
/// parsed) so a broken file fails here rather than at run time.
fn checked_leaf_list(path: &std::path::Path) -> Result<std::path::PathBuf, CliError> {
    let abs = std::fs::canonicalize(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let text = std::fs::read_to_string(&abs).map_err(|e| format!("{}: {e}", abs.display()))?;
    crate::io::leaf_list::parse_leaf_list(&text, &abs)?;
    Ok(abs)
}
