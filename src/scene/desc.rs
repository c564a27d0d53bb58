//! Authoring types of the RON scene format (`*Desc`), version 1.
//!
//! These are plain serde types: they are what a user writes and what generators return, never ECS
//! components. Every struct denies unknown fields; units are in field names (`_m`, `_deg`, `_nm`).
//! `spawn` turns a validated [`SceneDesc`] into entities.

use crate::direction::DirectionParams;
use crate::physics::prospect::{ProspectModel, ProspectParams};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

mod atmosphere;
mod lidar;
mod thermal;
pub use atmosphere::*;
pub use lidar::*;
pub use thermal::*;
mod sensor;
pub use sensor::*;

/// The current scene-format version. Files must state it in `version`.
pub const SCENE_FORMAT_VERSION: u32 = 1;

/// A whole scene file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    /// Scene-format version; must equal [`SCENE_FORMAT_VERSION`].
    pub version: u32,
    /// Human-readable name, copied into products.
    #[serde(default)]
    pub name: String,
    /// Seed for every random choice made while building the scene (tree placement, …).
    #[serde(default)]
    pub seed: u64,
    /// Cell grid and boundary mode.
    pub grid: GridDesc,
    /// Spectral bands; every per-band list in `optics` has one value per band.
    pub bands: Vec<BandDesc>,
    /// Library of named optical properties.
    pub optics: BTreeMap<String, OpticsDesc>,
    /// Sun and sky.
    pub illumination: IlluminationDesc,
    /// Scene objects; each becomes one or more entities.
    #[serde(default)]
    pub objects: Vec<ObjectDesc>,
    /// Plane-parallel layered atmosphere over the scene (molecules, aerosols, absorbing gas);
    /// absent: none (the illumination is then at the bottom of the atmosphere).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub atmosphere: Option<AtmosphereDesc>,
    /// Sensors at a finite distance (DART 5 paper §5): frame cameras imaged by the Monte
    /// Carlo solver (`--solver monte-carlo`). Absent: no sensor work.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensors: Option<Vec<SensorDesc>>,
    /// LiDAR instruments (Photon stage, DART 5 paper §4): waveforms, returns as LAS point
    /// clouds, photon counting.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lidars: Option<Vec<LidarDesc>>,
    /// Discrete directions (Direction stage): count, exact view directions, oversampled
    /// regions, fictive directions (refused for now: no product carries them), angular
    /// sectors. Default: 100 directions (DART default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub directions: Option<DirectionParams>,
    /// Radiative-stage settings (preset and individual knobs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radiative: Option<RadiativeDesc>,
    /// Whether the passive solver runs (flux tracking, or the Photon stage's Monte Carlo with
    /// `--solver monte-carlo`) and writes its products (`summary.json`, `brf.csv`, images,
    /// budget). Default (absent): it runs, except in a LiDAR scene whose instruments need no
    /// passive radiance — none has `photon_counting` (solar background) or `fusion: true` —
    /// where it would be wasted work (DART runs its LiDAR mode without a passive run too).
    /// `Some(true)` forces the passive run; `Some(false)` skips it and is refused when an
    /// instrument needs the passive radiance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub passive: Option<bool>,
    /// Where the scene lies on a map (CRS, map coordinates of the scene origin, bearing of
    /// +x). Absent: no geospatial work (no GeoTIFF/ENVI products, no GeoTIFF DEM).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub georeference: Option<GeoreferenceDesc>,
    /// Thermal infrared: the run mode (`R`, `T`, `RT`) and temperatures. Absent: a solar-only
    /// run (no emission work).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal: Option<ThermalDesc>,
}

/// The scene's place on a map: a projected CRS in metres, the map coordinates (easting,
/// northing) of the scene origin (x = y = 0), and the grid bearing of the scene's +x axis.
/// A scene point (x, y) lies at E = E₀ + x·sin β − y·cos β, N = N₀ + x·cos β + y·sin β.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeoreferenceDesc {
    /// The map's coordinate reference system: `Epsg(32631)` or `Wkt("PROJCS[...]")`; a
    /// projected CRS whose unit is the metre.
    pub crs: CrsDesc,
    /// Map coordinates (easting, northing) of the scene origin, metres.
    pub origin_map_m: Xy,
    /// Grid bearing of the scene's +x axis, degrees clockwise from grid north, in [0, 360)
    /// (default 90: +x points east and +y north, as `sun_position.scene_x_bearing_deg`).
    #[serde(default = "default_scene_x_bearing")]
    pub x_axis_bearing_deg: f64,
}

/// A coordinate reference system.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum CrsDesc {
    /// An EPSG code (projected, metres), e.g. 32631 (WGS 84 / UTM zone 31N).
    Epsg(u32),
    /// A WKT definition (`PROJCS[...]` or `PROJCRS[...]`, metres); its EPSG authority code,
    /// when it ends with one, is what the products carry.
    Wkt(String),
}

impl SceneDesc {
    /// Whether the passive solver runs for this scene (see [`SceneDesc::passive`]).
    pub fn runs_passive(&self) -> bool {
        self.passive.unwrap_or_else(|| match &self.lidars {
            Some(l) if !l.is_empty() => l.iter().any(LidarDesc::needs_passive),
            _ => true,
        })
    }
}

/// Accuracy presets of the Radiative stage (direction sampling of the phase tables, stopping
/// thresholds, interception storage).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
pub enum Preset {
    /// Fast look.
    Preview,
    /// DART's documented defaults.
    #[default]
    Default,
    /// Reference accuracy (per-direction interception storage, tight thresholds).
    Reference,
}

/// Radiative-stage settings of a scene; every knob overrides the preset's value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RadiativeDesc {
    /// Preset (default: `Default`); the CLI's `--preset` overrides it.
    pub preset: Option<Preset>,
    /// Maximum number of iterations.
    pub max_iterations: Option<u32>,
    /// Convergence threshold on the relative change of the scene albedo.
    pub albedo_threshold: Option<f64>,
    /// Ray-power threshold relative to the mean source ray.
    pub ray_threshold: Option<f64>,
    /// Spacing of the sun/sky launch points on the top plane, metres.
    pub launch_spacing_m: Option<f64>,
    /// Extrapolate the remaining scattering orders.
    pub extrapolate: Option<bool>,
    /// Store intercepted power per incident direction instead of per angular sector.
    pub per_direction_stores: Option<bool>,
    /// Turbid interception stores per incident cell face or sub-face (DART 5 paper §3.2,
    /// Figure 7): `Off`, `Faces`, `Subfaces` or `Blend` (see [`TurbidSubfaces`]).
    pub turbid_subfaces: Option<TurbidSubfaces>,
    /// With `turbid_subfaces: Faces` or `Subfaces`: rays scattered by a turbid cell are
    /// followed to the cell's exit and merged per (exit face or sub-face, direction) before
    /// being tracked further (DART 5 paper Figure 7c).
    pub turbid_exit_grouping: Option<bool>,
    /// Spatial oversampling factor η of the orthographic images (DART 5 paper §3.2): pixels of
    /// (Δx/η, Δy/η), i.e. η × η pixels per grid column; integer ≥ 1, default 1. Not touched by
    /// presets.
    #[serde(default = "default_image_oversampling")]
    pub image_oversampling: u32,
}

impl Default for RadiativeDesc {
    fn default() -> Self {
        Self {
            preset: None,
            max_iterations: None,
            albedo_threshold: None,
            ray_threshold: None,
            launch_spacing_m: None,
            extrapolate: None,
            per_direction_stores: None,
            turbid_subfaces: None,
            turbid_exit_grouping: None,
            image_oversampling: default_image_oversampling(),
        }
    }
}

/// How a turbid cell stores what it intercepts and where it scatters it from (DART 5 paper,
/// Gastellu-Etchegorry et al. 2015, §3.2 and Figure 7; physics.md §3.6, §6.3, §6.6). DART keeps
/// the intercepted power and the interception points M_int per *incident cell sub-face* s (the
/// sub-face the ray entered through; each face is split in D × D sub-faces, D = the sub-cell
/// factor) and per incident angular sector, and scatters from each sub-face's points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum TurbidSubfaces {
    /// One store per (cell, incidence slot) and one pair of interception points per cell,
    /// averaged over every ray of every direction.
    #[default]
    Off,
    /// Stores and point pairs per incident face (6) plus one for rays that start inside the
    /// cell (scattered from a point in the same cell); each non-empty store scatters from its
    /// own points with its own power.
    Faces,
    /// As `Faces` with each face split in D × D sub-faces (6 D² + 1 stores per cell).
    Subfaces,
    /// One ray pair per (cell, direction j), as `Off`, but from a direction-dependent point:
    /// the barycentre of the interception points of each incidence slot weighted by the power
    /// that slot scatters into j (the finest blend of any face or sub-face partition's points:
    /// blending per (sub-face, slot) points with these weights gives the same point).
    Blend,
}

fn default_image_oversampling() -> u32 {
    1
}

/// What happens to rays leaving the scene through a side (DART 5 paper §3, Fig. 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BoundaryMode {
    /// Infinite repetition of the scene: a ray leaving a side re-enters on the opposite side.
    Repetitive,
    /// Repetition with the ground-altitude offset between opposite sides applied on re-entry.
    RepetitiveContinuousTopography,
    /// Rays leaving a side are lost; objects must lie inside the scene.
    Isolated,
}

/// The cell grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridDesc {
    /// Scene extent along x and y, metres; the scene spans `[0, x] × [0, y]`.
    pub size_m: (f64, f64),
    /// Cell size (dx, dy, dz), metres; non-cubic cells are allowed. The grid holds at most
    /// 2³² − 1 cells (x × y × z).
    pub cell_m: (f64, f64, f64),
    /// Scene height above the lowest ground point, metres; by default the highest object
    /// rounded up to a whole cell (plus one empty cell layer).
    #[serde(default)]
    pub height_m: Option<f64>,
    /// Sub-cell factor D (each cell holds D³ sub-cells for facet scattering points); DART default 2.
    #[serde(default = "default_subcells")]
    pub subcells: u32,
    /// Boundary mode.
    pub boundary: BoundaryMode,
}

fn default_subcells() -> u32 {
    2
}

/// One spectral band and its spectral response S(λ).
///
/// Four forms, told apart by the fields given:
/// * `wavelength_nm` alone (or `fwhm_nm: 0`): monochromatic;
/// * `wavelength_nm` and `fwhm_nm` > 0: Gaussian response centred on `wavelength_nm`
///   (an approximation of a real band, see `physics::spectral::SpectralBand::Gaussian`);
/// * `sensor_band: ("sentinel2a_msi", "B04")`: the measured response of a band of the shipped
///   sensor library (`assets/sensors/`);
/// * `srf_file: "my_band.csv"`: a tabulated response read from a file.
///
/// The response is used by every optical value that depends on wavelength (`ProspectLeaf`
/// leaves: ∫ S X dλ / ∫ S dλ). Plain per-band numbers (`reflectance: [...]`, …) are taken as
/// given, whatever the response.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BandDesc {
    /// Band name, used for image channels and CSV columns.
    pub name: String,
    /// Central wavelength, nanometres. Required for monochromatic and Gaussian bands. For a
    /// `sensor_band` or `srf_file` band it is only the nominal wavelength and may be omitted (0):
    /// the spawn step then uses the response's centroid ∫ λ S dλ / ∫ S dλ.
    #[serde(default)]
    pub wavelength_nm: f64,
    /// Full width at half maximum, nanometres (0 = monochromatic, > 0 = Gaussian). Must be 0
    /// for a `sensor_band` or `srf_file` band.
    #[serde(default)]
    pub fwhm_nm: f64,
    /// A band of the shipped sensor library as `(sensor, band)`. Sensors: `sentinel2a_msi`
    /// (B01–B12, B8A), `landsat8_oli` (B1–B9), `modis_terra` (B1–B7); band names ignore case and
    /// leading zeros (`B4` = `B04`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor_band: Option<(String, String)>,
    /// A tabulated spectral response: CSV file, path relative to the scene file's folder, with
    /// a `wavelength_nm,response` (or `wavelength_um,response`) header, `#` comments allowed,
    /// strictly increasing wavelengths and responses ≥ 0 (any scale; zero outside the table).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub srf_file: Option<String>,
}

/// A named optical property; every list holds one value per band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum OpticsDesc {
    /// Lambertian facet (DART 5 paper §3.1; physics.md §5.1).
    Lambertian {
        /// Hemispherical reflectance per band.
        reflectance: Vec<f64>,
        /// Diffuse (Lambertian) transmittance per band.
        #[serde(default)]
        diffuse_transmittance: Vec<f64>,
        /// Direct transmittance along the normal per band (T_dir; T_dir^(1/|μ|) off-normal).
        #[serde(default)]
        direct_transmittance: Vec<f64>,
    },
    /// Rahman–Pinty–Verstraete reflectance (physics.md §5.2).
    Rpv {
        /// Amplitude ρ0 per band.
        rho0: Vec<f64>,
        /// Minnaert exponent k per band.
        k: Vec<f64>,
        /// Henyey–Greenstein asymmetry Θ per band (Θ < 0: backward scattering).
        theta: Vec<f64>,
        /// Hotspot amplitude ρc per band (default ρ0).
        #[serde(default)]
        rho_c: Option<Vec<f64>>,
    },
    /// Hapke particulate-surface reflectance (physics.md §5.3).
    Hapke {
        /// Single-scattering albedo w per band.
        w: Vec<f64>,
        /// Phase-function asymmetry b per band.
        b: Vec<f64>,
        /// Phase-function back/forward weight c per band.
        c: Vec<f64>,
        /// Macroscopic roughness θ̄, degrees.
        roughness_deg: f64,
        /// Opposition-effect amplitude B0.
        b0: f64,
        /// Opposition-effect width h.
        h: f64,
    },
    /// Bi-Lambertian leaf (physics.md §3.3): reflectance and transmittance per band.
    BiLambertian {
        /// Leaf hemispherical reflectance per band.
        reflectance: Vec<f64>,
        /// Leaf hemispherical transmittance per band.
        transmittance: Vec<f64>,
    },
    /// Bi-Lambertian leaf whose reflectance and transmittance are computed by PROSPECT-5 or
    /// PROSPECT-D (Féret et al. 2008, 2017; physics.md §11) from the leaf's biochemistry, e.g.
    /// `ProspectLeaf(model: D, n: 1.5, cab_ug_cm2: 40, car_ug_cm2: 8, cw_cm: 0.01,
    /// cm_g_cm2: 0.009)`. Usable wherever a `BiLambertian` leaf is.
    ///
    /// The 400–2500 nm, 1 nm spectra are integrated over each band's response:
    /// R_band = ∫ S R dλ / ∫ S dλ (the same for T; the 1 nm spectrum is linearly interpolated,
    /// so a monochromatic band takes the interpolated value at its wavelength). Every band's
    /// response must lie within 400–2500 nm.
    ProspectLeaf {
        /// PROSPECT version: `D` (PROSPECT-D) or `P5` (PROSPECT-5; also written `r#5`).
        model: ProspectModel,
        /// Mesophyll structure parameter N (≥ 1; typically 1–3).
        n: f64,
        /// Chlorophyll a+b content, µg cm⁻².
        cab_ug_cm2: f64,
        /// Carotenoid content, µg cm⁻².
        car_ug_cm2: f64,
        /// Anthocyanin content, µg cm⁻² (default 0; PROSPECT-D only, no effect with `P5`).
        #[serde(default)]
        anth_ug_cm2: f64,
        /// Brown pigment content, arbitrary units (default 0; typically 0–1).
        #[serde(default)]
        cbrown: f64,
        /// Equivalent water thickness, cm (≡ g cm⁻² of water).
        cw_cm: f64,
        /// Dry matter content (leaf mass per area), g cm⁻².
        cm_g_cm2: f64,
    },
    /// Turbid vegetation: leaf optics + leaf angle distribution + leaf size (physics.md §3).
    Turbid {
        /// Name of a `BiLambertian` or `ProspectLeaf` entry of the library.
        leaf: String,
        /// Leaf angle distribution.
        lad: LadDesc,
        /// Leaf dimension for the hotspot, metres (DART `dimFoliar`, default 0.01; 0 = no hotspot).
        #[serde(default = "default_leaf_size")]
        leaf_size_m: f64,
        /// Optional specular leaf-surface reflection (Fresnel with the cuticle's refractive
        /// index × a factor), added to the Lambertian ρ and τ (physics.md §5.4):
        /// `specular: (refractive_index: 1.47, factor: 0.3)`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        specular: Option<crate::physics::lad::LeafSpecular>,
    },
}

fn default_leaf_size() -> f64 {
    0.01
}

impl OpticsDesc {
    /// The PROSPECT version and leaf parameters of a `ProspectLeaf` entry; `None` for the other
    /// kinds.
    pub fn prospect_params(&self) -> Option<(ProspectModel, ProspectParams)> {
        match *self {
            OpticsDesc::ProspectLeaf {
                model,
                n,
                cab_ug_cm2,
                car_ug_cm2,
                anth_ug_cm2,
                cbrown,
                cw_cm,
                cm_g_cm2,
            } => Some((
                model,
                ProspectParams {
                    n,
                    cab_ug_cm2,
                    car_ug_cm2,
                    anth_ug_cm2,
                    cbrown,
                    cw_cm,
                    cm_g_cm2,
                },
            )),
            _ => None,
        }
    }
}

/// Leaf angle distribution of the scene format: the physics type itself (physics.md §3.2),
/// written e.g. `Spherical`, `Ellipsoidal(mean_angle_deg: 57.3)`, `Beta(mu: 2.77, nu: 1.172)`,
/// `Histogram(bins: [...])`.
pub use crate::physics::lad::Lad as LadDesc;

/// Sun and diffuse sky.
///
/// The sun is given in exactly one of two ways (anything else is a validation error):
/// * explicit angles: both `sun_zenith_deg` and `sun_azimuth_deg` (a bare value or `Some(…)`);
/// * `sun_position`: a date, time and place, from which the spawn step computes the angles
///   (NREL SPA) and, unless turned off, the Earth–Sun distance correction of
///   `irradiance_w_m2_um`.
///
/// This is the authoring form only: the spawn step resolves it into
/// `resources::scene::Illumination` (final angles, one value per band), which is what every
/// stage reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IlluminationDesc {
    /// Sun zenith angle of the ground→sun direction, degrees, in [0, 90). Given together with
    /// `sun_azimuth_deg`, and only when `sun_position` is not.
    #[serde(default)]
    pub sun_zenith_deg: Option<f64>,
    /// Sun azimuth of the ground→sun direction, degrees, anticlockwise from +x (DART convention).
    /// Given together with `sun_zenith_deg`, and only when `sun_position` is not.
    #[serde(default)]
    pub sun_azimuth_deg: Option<f64>,
    /// Sun from date, time and place instead of explicit angles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sun_position: Option<SunPositionDesc>,
    /// Diffuse sky fraction SKYL = E_diff / (E_dir + E_diff) per band (default 0).
    #[serde(default)]
    pub skyl: Vec<f64>,
    /// Total bottom-of-atmosphere irradiance on a horizontal plane per band, W m⁻² µm⁻¹
    /// (top of the atmosphere when the scene has an `atmosphere`)
    /// (default 1: products are then relative), for a mean Earth–Sun distance of 1 AU when
    /// `sun_position` applies the distance correction.
    #[serde(default)]
    pub irradiance_w_m2_um: Vec<f64>,
}

/// Sun position from a UTC date-time and a place, computed at spawn by the NREL Solar Position
/// Algorithm (Reda & Andreas 2004, *Solar Energy* 76:577; `physics::sun::solar_position`,
/// ±0.0003°), e.g. `sun_position: (utc: "2003-10-17T19:30:30", latitude_deg: 39.742476,
/// longitude_deg: -105.1786, altitude_m: 1830.14)`; in a georeferenced scene the place and the
/// bearing may be left to the georeference (`sun_position: (utc: "2024-06-21T11:00:00")`).
///
/// The scene sun zenith is the apparent (refracted) topocentric zenith when `refraction` is on,
/// the geometric one otherwise; the scene azimuth is φ = (β − γ) mod 360°, γ the compass
/// azimuth of the sun (from north, clockwise) and β = `scene_x_bearing_deg` (physics.md §1.1,
/// §12.1). A sun at or below the horizon (zenith ≥ 90°) is an error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunPositionDesc {
    /// UTC date-time `YYYY-MM-DDTHH:MM:SS` (a space may replace `T`; fractions of a second and a
    /// trailing `Z` are accepted), year −2000…6000.
    pub utc: String,
    /// Geodetic latitude, degrees north, in [−90, 90]. Default (with `longitude_deg` absent
    /// too): that of the scene centre, from the scene's `georeference` (transverse Mercator
    /// and Lambert conformal conic CRSs; required without a georeference).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latitude_deg: Option<f64>,
    /// Longitude, degrees east of Greenwich, in [−180, 180] (west negative). Default: as
    /// `latitude_deg`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub longitude_deg: Option<f64>,
    /// Altitude of the scene above sea level, metres (default 0).
    #[serde(default)]
    pub altitude_m: f64,
    /// Compass bearing of the scene's +x axis, degrees clockwise from true north (default: from
    /// the scene's `georeference`, its grid bearing plus the meridian convergence at the scene
    /// centre; without a georeference 90: +x points east and +y north, DART's convention).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_x_bearing_deg: Option<f64>,
    /// Apply atmospheric refraction to the zenith angle (default true; Reda & Andreas 2004,
    /// §3.14, with `pressure_hpa` and `temperature_c`).
    #[serde(default = "yes")]
    pub refraction: bool,
    /// Annual mean local pressure for refraction, hPa (default 1013.25, sea level).
    #[serde(default = "default_pressure_hpa")]
    pub pressure_hpa: f64,
    /// Annual mean local temperature for refraction, °C (default 15).
    #[serde(default = "default_temperature_c")]
    pub temperature_c: f64,
    /// ΔT = TT − UT, seconds (default: the Espenak & Meeus 2006 estimate for the date,
    /// `physics::sun::delta_t_estimate_s`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delta_t_s: Option<f64>,
    /// Scale `irradiance_w_m2_um` by (1 AU / d)², d the Earth–Sun distance at `utc`
    /// (inverse-square law; default true). The factor applied is reported in
    /// `resources::scene::SceneInfo::irradiance_distance_factor`.
    #[serde(default = "yes")]
    pub earth_sun_distance_correction: bool,
}

fn default_scene_x_bearing() -> f64 {
    crate::physics::sun::DEFAULT_SCENE_X_BEARING_DEG
}

fn default_pressure_hpa() -> f64 {
    1013.25
}

fn default_temperature_c() -> f64 {
    15.0
}

/// Horizontal placement of one object, metres, in scene coordinates.
pub type Xy = (f64, f64);

/// A scene object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ObjectDesc {
    /// The ground (at most one).
    Ground(GroundDesc),
    /// One tree.
    Tree(TreeDesc),
    /// Several trees from species templates.
    TreeStand(TreeStandDesc),
    /// A turbid plot (grass, crops).
    TurbidPlot(TurbidPlotDesc),
    /// A building made of facets.
    Building(BuildingDesc),
    /// A water body (horizontal polygon of facets).
    Water(WaterDesc),
    /// A mesh imported from glTF or OBJ.
    Mesh(MeshDesc),
    /// Disk leaves listed inline (RAMI HOM-style discrete canopies).
    Leaves(LeavesDesc),
    /// Disk leaves read from a RAMI leaf-list file.
    LeafList(LeafListDesc),
    /// Objects from a land-cover classification GeoTIFF and a class table (needs the scene's
    /// `georeference`).
    LandCover(LandCoverDesc),
}

/// A land-cover map (DART 5 paper §2, "Maket": landscapes from classification maps): a
/// single-band GeoTIFF of integer class codes in the scene's CRS, north-up, covering the
/// scene's map extent, and a table giving what each class becomes. Pixels of one class are
/// merged into rectangles (row runs joined down the rows) and each rectangle becomes one
/// object exactly as if written by hand with a `Box` footprint, clipped to the scene (pixels at
/// the scene edge are clipped, not dropped); in a rotated scene the footprint is the rotated
/// rectangle clipped to the scene (a `Polygon`; `TreeStand` classes need +x east). A cell
/// shared by several classes gets each one's share by exact area. Pixels equal to the raster's
/// `GDAL_NODATA` are left bare.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LandCoverDesc {
    /// Path of the classification GeoTIFF, relative to the scene file's folder.
    pub path: String,
    /// Class code → what it becomes; a code found in the map without an entry is an error.
    pub classes: BTreeMap<u32, LandCoverClass>,
}

/// What the pixels of one land-cover class become.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum LandCoverClass {
    /// Nothing: the scene's ground shows (bare soil, roads).
    Nothing,
    /// Turbid vegetation (grass, crops, a closed canopy as a layer): a `TurbidPlot` per
    /// rectangle.
    TurbidPlot {
        /// Bottom of the vegetation above the local ground, metres.
        #[serde(default)]
        bottom_m: f64,
        /// Top of the vegetation above the local ground, metres.
        top_m: f64,
        /// `Lai` or `LeafAreaDensity` (a `LeafArea` total has no meaning per pixel).
        foliage: FoliageDesc,
        /// Name of a `Turbid` optical property.
        optics: String,
    },
    /// A water surface: a `Water` object per rectangle.
    Water {
        /// Altitude of the surface, metres (default: as `Water`).
        #[serde(default)]
        altitude_m: Option<f64>,
        /// Name of a facet optical property.
        optics: String,
    },
    /// A tree stand: per rectangle a `TreeStand` with seeded random placement (its own stream
    /// per rectangle), the number of trees of each species its density × the rectangle's area
    /// (fractions carried from rectangle to rectangle, so a class gets its density × area to
    /// within one tree). In an isolated scene trunks keep a crown radius from the scene's edges.
    TreeStand {
        /// Species templates (trunk, crown).
        species: Vec<SpeciesDesc>,
        /// Trees per hectare of each species.
        trees_per_ha: Vec<f64>,
        /// Minimum distance between trunks, metres (default 0).
        #[serde(default)]
        min_spacing_m: f64,
    },
    /// Buildings of the footprint height: a flat-roofed `Building` per rectangle.
    Building {
        /// Wall height above the lowest ground point under the rectangle, metres.
        wall_height_m: f64,
        /// Name of a facet optical property for walls.
        wall_optics: String,
        /// Name of a facet optical property for the roof.
        roof_optics: String,
    },
}

/// A RAMI leaf list (`radius x y z nx ny nz` per line, metres; see [`crate::io::leaf_list`]).
/// Disks become regular polygons with the disk's exact area, or turbid cells.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LeafListDesc {
    /// Path relative to the scene file.
    pub path: String,
    /// Name of a leaf optical property (BiLambertian, ProspectLeaf) or a facet property.
    pub optics: String,
    /// Polygon sides per disk (default 12; 3 to 1000).
    #[serde(default = "default_disk_sides")]
    pub sides: u32,
    /// Translation added to every centre, metres (z is above the ground under the leaf).
    #[serde(default)]
    pub translation_m: (f64, f64, f64),
    /// Wrap centres into the scene periodically (x mod X, y mod Y).
    #[serde(default)]
    pub wrap: bool,
    /// Convert the leaves to turbid cells (leaf area per cell kept exactly; the leaves'
    /// inclination histogram becomes the LAD).
    #[serde(default)]
    pub as_turbid: bool,
}

/// Disk-shaped leaves given inline; each disk becomes a regular polygon of facets with the
/// disk's exact area.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LeavesDesc {
    /// Disk radius, metres.
    pub radius_m: f64,
    /// Polygon sides per disk (default 12; 3 to 1000).
    #[serde(default = "default_disk_sides")]
    pub sides: u32,
    /// Name of a facet (usually BiLambertian) optical property.
    pub optics: String,
    /// Both faces interact (default true: leaves).
    #[serde(default = "yes")]
    pub two_sided: bool,
    /// Disks as (x, y, z, normal_x, normal_y, normal_z): centre in metres (z above the ground),
    /// normal (normalised on use).
    pub disks: Vec<(f64, f64, f64, f64, f64, f64)>,
}

fn default_disk_sides() -> u32 {
    12
}

fn yes() -> bool {
    true
}

/// Ground: flat or a digital elevation model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroundDesc {
    /// Name of a facet optical property (Lambertian, RPV or Hapke).
    pub optics: String,
    /// Shape of the ground.
    #[serde(default)]
    pub topography: TopographyDesc,
}

/// Ground shape.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub enum TopographyDesc {
    /// Horizontal plane at z = 0.
    #[default]
    Flat,
    /// Altitudes on a regular raster given inline.
    Raster(RasterDesc),
    /// Altitudes on a regular raster read from a file.
    RasterFile(RasterFileDesc),
    /// Scattered (x, y, z) points, Delaunay-triangulated (spade).
    Points {
        /// Points (x_m, y_m, z_m); their convex hull must cover the scene.
        points_m: Vec<(f64, f64, f64)>,
    },
}

/// Inline raster of altitudes; node (i, j) lies at (origin.x + i·dx, origin.y + j·dy).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RasterDesc {
    /// Number of nodes along x and y (≥ 2 each, at most 2²⁸ nodes in all).
    pub nodes: (usize, usize),
    /// Node spacing along x and y, metres.
    pub spacing_m: (f64, f64),
    /// Position of node (0, 0), metres.
    #[serde(default)]
    pub origin_m: Xy,
    /// Altitudes, metres, row-major with x fastest: value `i + j·nx` is node (i, j).
    pub altitude_m: Vec<f64>,
}

/// Raster file formats.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum RasterFormat {
    /// ESRI ASCII grid (`ncols`, `nrows`, `xllcorner`/`xllcenter`, `cellsize`, optional `nodata_value`).
    /// Rows are stored north (max y) first; node values are taken at cell centres.
    EsriAscii,
    /// A single-band GeoTIFF of elevations, metres (8–64-bit integers or floats; GDAL's
    /// no-data value honoured): placed on the scene through the scene's `georeference` (same
    /// CRS), cropped to the scene's map extent. Pixel values are nodes at pixel centres
    /// (PixelIsArea) or at the tie point (PixelIsPoint). With +x east the nodes form the same
    /// raster ground as an ESRI grid; in a rotated scene they are triangulated (Delaunay) at
    /// their scene positions. `origin_m` must be left at (0, 0).
    GeoTiff,
    /// Raw little-endian f32 values, x fastest then y; dimensions and spacing given in the scene.
    BinaryF32 {
        /// Number of nodes along x and y.
        nodes: (usize, usize),
        /// Node spacing, metres.
        spacing_m: (f64, f64),
    },
}

/// Raster read from a file (path relative to the scene file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RasterFileDesc {
    /// Path, relative to the scene file's folder.
    pub path: String,
    /// File format.
    pub format: RasterFormat,
    /// Position of node (0, 0) in scene coordinates for `BinaryF32`, metres (ESRI files carry
    /// their own origin; this offset is then subtracted from it).
    #[serde(default)]
    pub origin_m: Xy,
}

pub use crate::geometry::crown::CrownShape;

/// Amount of foliage in a crown or plot.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum FoliageDesc {
    /// Mean one-sided leaf area volume density, m² m⁻³ (at most 100).
    LeafAreaDensity(f64),
    /// Leaf area index: leaf area divided by the horizontal projected area of the shape, m² m⁻²
    /// (at most 100).
    Lai(f64),
    /// Total one-sided leaf area, m² (a plot's at most 100 m² m⁻³ over its volume; a crown's at
    /// most LAI 100 over the scene or over its own footprint, whichever is larger).
    LeafArea(f64),
}

/// Tree crown.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CrownDesc {
    /// Shape.
    pub shape: CrownShape,
    /// Height of the crown base above the ground, metres.
    pub base_height_m: f64,
    /// Crown height (base to top), metres.
    pub height_m: f64,
    /// Horizontal semi-axis along x at the widest level, metres.
    pub radius_x_m: f64,
    /// Horizontal semi-axis along y, metres (default: `radius_x_m`).
    #[serde(default)]
    pub radius_y_m: Option<f64>,
    /// For `Trapezoid`: top radius / bottom radius, in [0, 1].
    #[serde(default)]
    pub top_radius_fraction: Option<f64>,
    /// Foliage amount.
    pub foliage: FoliageDesc,
    /// Relative leaf-area-density weights of equal-height layers from base to top (piecewise
    /// constant; default uniform).
    #[serde(default)]
    pub vertical_profile: Vec<f64>,
    /// Relative weights of equal-width rings of relative horizontal radius ρ = d / r(z) from the
    /// axis (ρ = 0) to the crown edge (ρ = 1) (piecewise constant; default uniform).
    #[serde(default)]
    pub radial_profile: Vec<f64>,
    /// Name of a `Turbid` optical property.
    pub optics: String,
}

/// Tree trunk (an n-sided closed prism of facets).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrunkDesc {
    /// Trunk height above the ground, metres.
    pub height_m: f64,
    /// Trunk diameter, metres.
    pub diameter_m: f64,
    /// Number of sides of the prism (default 8; 3 to 1000).
    #[serde(default = "default_trunk_sides")]
    pub sides: u32,
    /// Name of a facet optical property.
    pub optics: String,
}

fn default_trunk_sides() -> u32 {
    8
}

/// One tree: a trunk of facets and a turbid crown.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreeDesc {
    /// Position of the trunk base, metres; z comes from the ground.
    pub position_m: Xy,
    /// Trunk (optional).
    #[serde(default)]
    pub trunk: Option<TrunkDesc>,
    /// Crown.
    pub crown: CrownDesc,
}

/// A species template: a tree without position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeciesDesc {
    /// Species name.
    pub name: String,
    /// Trunk.
    #[serde(default)]
    pub trunk: Option<TrunkDesc>,
    /// Crown.
    pub crown: CrownDesc,
}

/// How trees of a stand are placed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum PlacementDesc {
    /// Explicit positions: (species index, x_m, y_m).
    Explicit(Vec<(usize, f64, f64)>),
    /// Random uniform positions with a minimum spacing, reproducible from the scene seed.
    Random {
        /// Number of trees per species (at most 1 000 000 in all).
        counts: Vec<usize>,
        /// Minimum distance between trunks, metres.
        min_spacing_m: f64,
        /// Area to fill (x_min, y_min, x_max, y_max), metres; default the whole scene.
        #[serde(default)]
        region_m: Option<(f64, f64, f64, f64)>,
        /// A simple polygon to fill instead (vertices in order, metres; with `region_m`, the
        /// trunks lie in both), e.g. a stand's outline.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        polygon_m: Option<Vec<(f64, f64)>>,
    },
}

/// A stand of trees of one or more species.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreeStandDesc {
    /// Species templates.
    pub species: Vec<SpeciesDesc>,
    /// Placement.
    pub placement: PlacementDesc,
}

/// Footprint of a plot or building: an axis-aligned box or a simple polygon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum FootprintDesc {
    /// Axis-aligned rectangle (x_min, y_min, x_max, y_max), metres.
    Box((f64, f64, f64, f64)),
    /// Simple polygon, vertices in order (either orientation), metres.
    Polygon(Vec<Xy>),
}

/// A turbid plot: grass or crop as a turbid layer over a footprint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TurbidPlotDesc {
    /// Footprint.
    pub footprint: FootprintDesc,
    /// Bottom of the vegetation above the local ground, metres.
    #[serde(default)]
    pub bottom_m: f64,
    /// Top of the vegetation above the local ground, metres.
    pub top_m: f64,
    /// Foliage amount (`Lai` = leaf area / footprint area).
    pub foliage: FoliageDesc,
    /// Name of a `Turbid` optical property.
    pub optics: String,
}

/// Roof of a building.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum RoofDesc {
    /// Flat roof at the wall top.
    Flat,
    /// Gable roof over a rectangular (4-vertex) footprint, ridge along the longer side.
    Gable {
        /// Ridge height above the wall top, metres.
        ridge_height_m: f64,
    },
}

/// A building made of facets (walls, roof, floor: a closed shell).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildingDesc {
    /// Footprint polygon.
    pub footprint: FootprintDesc,
    /// Wall height above the lowest ground point under the footprint, metres.
    pub wall_height_m: f64,
    /// Roof.
    pub roof: RoofDesc,
    /// Name of a facet optical property for walls.
    pub wall_optics: String,
    /// Name of a facet optical property for the roof.
    pub roof_optics: String,
}

/// A water body: a horizontal polygon of facets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaterDesc {
    /// Footprint.
    pub footprint: FootprintDesc,
    /// Altitude of the water surface, metres (default: highest ground altitude under the
    /// footprint vertices plus 1 cm).
    #[serde(default)]
    pub altitude_m: Option<f64>,
    /// Name of a facet optical property.
    pub optics: String,
}

/// Optics of one mesh group (material or object name in the file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshGroupOptics {
    /// Group name as written in the file (glTF material / OBJ `usemtl` name).
    pub group: String,
    /// Name of an optical property: a facet property, or a `Turbid` one when `as_turbid`.
    pub optics: String,
    /// Whether both faces of each triangle interact (leaves: true).
    #[serde(default)]
    pub two_sided: bool,
    /// Convert this group's triangles into turbid cells (DART "facet to turbid"): leaf area per
    /// cell is kept exactly and the group's leaf-inclination histogram becomes the LAD.
    #[serde(default)]
    pub as_turbid: bool,
}

/// A mesh imported from a file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshDesc {
    /// Path relative to the scene file (`.gltf`, `.glb`, `.obj`).
    pub path: String,
    /// Convert glTF's y-up axes to the scene's z-up before the transform (default true for glTF).
    #[serde(default)]
    pub y_up: Option<bool>,
    /// Uniform scale applied first.
    #[serde(default = "one")]
    pub scale: f64,
    /// Rotation about z, degrees anticlockwise, applied after the scale.
    #[serde(default)]
    pub rotation_z_deg: f64,
    /// Translation applied last, metres (z relative to the ground under the position).
    #[serde(default)]
    pub translation_m: (f64, f64, f64),
    /// Optics per group; every group of the file must be listed.
    pub groups: Vec<MeshGroupOptics>,
}

fn one() -> f64 {
    1.0
}

/// The footprint of a [`FootprintDesc`] as an anticlockwise polygon (m).
pub fn footprint_polygon(fp: &FootprintDesc) -> Vec<glam::DVec2> {
    use glam::DVec2;
    let mut p: Vec<DVec2> = match fp {
        FootprintDesc::Box((x0, y0, x1, y1)) => vec![
            DVec2::new(*x0, *y0),
            DVec2::new(*x1, *y0),
            DVec2::new(*x1, *y1),
            DVec2::new(*x0, *y1),
        ],
        FootprintDesc::Polygon(v) => v.iter().map(|&(x, y)| DVec2::new(x, y)).collect(),
    };
    if crate::geometry::polygon::signed_area(&p) < 0.0 {
        p.reverse();
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The beam profile's parameter rules: what passes, and the message naming what does not.
    #[test]
    fn beam_profile_check() {
        let table = |points: &[(f64, f64)]| {
            BeamProfile::Tabulated {
                points: points.to_vec(),
            }
            .check()
        };
        assert_eq!(BeamProfile::default().check(), Ok(()));
        assert_eq!(BeamProfile::Uniform.check(), Ok(()));
        assert_eq!(table(&[(0.0, 1.0), (0.8, 1.0), (1.0, 0.0)]), Ok(()));
        assert_eq!(table(&[(0.5, 0.0), (1.0, 2.0)]), Ok(()));
        for s in [0.0, 1.0, -0.5, f64::NAN] {
            let e = BeamProfile::Gaussian { edge_intensity: s }
                .check()
                .unwrap_err();
            assert!(e.contains("edge_intensity") && e.contains("(0, 1)"), "{e}");
        }
        let cases: &[(&[(f64, f64)], &str)] = &[
            (
                &[(0.0, 1.0)],
                "needs at least 2 points (normalised radius, intensity), got 1",
            ),
            (
                &[(0.0, 1.0), (f64::INFINITY, 1.0)],
                "point 1 (inf, 1): normalised radius must be finite",
            ),
            (
                &[(-0.1, 1.0), (1.0, 1.0)],
                "point 0 (-0.1, 1): normalised radius must be >= 0",
            ),
            (
                &[(0.0, 1.0), (0.5, 1.0), (0.5, 1.0)],
                "point 2 (0.5, 1): normalised radii must be strictly increasing",
            ),
            (
                &[(0.0, 1.0), (1.0, -0.5)],
                "point 1 (1, -0.5): relative intensity must be finite and >= 0",
            ),
            (
                &[(0.0, 0.0), (1.0, 0.0)],
                "all intensities are zero (the beam carries no energy)",
            ),
            (
                &[(0.0, 1.0), (1e200, 1.0)],
                "total energy inf is not finite and > 0",
            ),
            (
                &[(0.0, 1.0), (1e-170, 1.0)],
                "total energy 0e0 is not finite and > 0",
            ),
        ];
        for (points, text) in cases {
            let e = table(points).unwrap_err();
            assert!(
                e.starts_with("beam profile table: ") && e.contains(text),
                "{points:?}: {e}"
            );
        }
    }
}
