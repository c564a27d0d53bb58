//! `rami`: the RAMI-3 benchmark scenes (RAdiation transfer Model Intercomparison, phase 3;
//! Widlowski et al. 2007, *J. Geophys. Res.* 112, D09111; ROMC: Widlowski et al. 2008, *Remote
//! Sens. Environ.* 112:1144) from their experiment identifiers, e.g. `HOM13_DIS_PLA_NIR_20`,
//! with the RAMI measurement directions as exact view directions.
//!
//! An identifier is `<SCENE>_<REP>_<LND>_<BAND>_<SZA>`: structure (`HOM01`…`HOM15`: homogeneous
//! layer; `HET01`/`HET02`: floating spheres), representation (`TUR` turbid, `DIS` discrete
//! discs), leaf normal distribution (`ERE`, `PLA`, `UNI`), optics (`RED`, `NIR`, `NR1` = the
//! conservative "purist corner") and the sun zenith angle in degrees.
//!
//! # Parameters and their sources
//!
//! Sources: **(R3)** the RAMI-3 experiment pages (rami-benchmark.jrc.ec.europa.eu, phase RAMI3:
//! `HOM_SOL_DIS`, `HOM_PUR_DIS`, `HET_FLO_SOL_DIS`, `HET_FLO_PUR_TUR`) and the RAMI-1 `HET01`
//! page; **(ROMC)** the ROMC format pages (romc.jrc.ec.europa.eu) and its list of debug
//! experiments; **(S)** a third-party ROMC submission script (a plane-parallel model's
//! `rami romc` script, found by code search) whose tables reproduce the published experiments —
//! used only where the RAMI pages available to us were truncated; **(A)** our assumption.
//!
//! | parameter | value | source |
//! |---|---|---|
//! | HOM LAI / canopy height | HOM01 1 / 1 m, HOM02 2 / 1 m, HOM03 3 / 2 m, HOM05 5 / 1 m, HOM11 1 / 1 m, HOM12 2 / 1 m, HOM13 3 / 2 m, HOM15 5 / 1 m | LAI: (R3) (purist discrete LAI 1, 2, 5; HOM13 LAI 3 from its leaf file, below) and (S); heights: (S) |
//! | HOM disc radius (`DIS`) | 0.1 m | (R3) for HOM13 (planophile, 0.1 m); (S) for the other `DIS` cases |
//! | HOM13 leaf file | 25 × 25 m² section, 59 683 discs (= round(3 · 625 / (π 0.1²))) | (R3) |
//! | turbid leaf size (`TUR`) | 0 (dimensionless scatterers: no hot spot) | (R3) ("gas of dimension-less particles") |
//! | LND `ERE`, `PLA` | erectophile (2/π)(1 − cos 2θ), planophile (2/π)(1 + cos 2θ) | names (R3); the de Wit/Bunnik forms of [`LadDesc`] — RAMI's definition page was not available, **not confirmed** |
//! | LND `UNI` | spherical LAD (`LadDesc::Spherical`) | (R3): RAMI's "uniform (or what is sometimes called a spherical)" distribution, "the probability to be intercepted by a leaf is independent of the direction" |
//! | `RED` optics | leaf r 0.0546, t 0.0149; soil 0.127 (Lambertian) | (S), and the project's DISORT oracle inputs (assets/reference) |
//! | `NIR` optics | leaf r 0.4957, t 0.4409; soil 0.159 | (S), as above |
//! | `NR1` optics | leaf r 0.5, t 0.5; soil 1.0 | (R3) (HET02: "reflectance=0.5, transmittance=0.5 … surface albedo being unity") and (S) |
//! | band wavelengths | red 670 nm, NIR and NR1 865 nm | (A) nominal: RAMI gives optics, not wavelengths; nothing here depends on them |
//! | sun zenith | the last tag, degrees (`00`, `20`, `30`, `50`, `60`) | (ROMC) identifiers, (S) |
//! | sun azimuth | 0° (+x) unless overridden | (A): RAMI stores only SAA − VAA; the HOM cases do not depend on it |
//! | published combinations | see [`PUBLISHED`] | (ROMC) debug-experiment lists |
//! | HET scene | 100 × 100 × 30 m | (R3) |
//! | HET spheres | 15, radius 10 m, LAI 5 per sphere (leaf area / π r²), uniform (spherical) LND | (R3) |
//! | HET01 disc radius | 0.1 m | (R3) (RAMI-1 HET01 page) |
//! | HET02 scatterer size | 0 ("0 or close to 0") | (R3) |
//! | HET sphere coverage | 0.471 (= 15 π 10² / 100²) | (R3) |
//! | HET sphere-centre heights | 11 m … 19 m | minimum 11 m (R3); maximum 19 m (A) (the stored page is truncated there; 19 m keeps every crown below the 30 m scene top) |
//! | HET sphere positions | seeded, uniform, projections disjoint (horizontal distance ≥ 20 m, periodic) | (A): RAMI's position file was not available; disjoint projections reproduce the published coverage 0.471 exactly and keep the spheres non-overlapping |
//! | RAMI views | principal and orthogonal planes, view zenith ±1°, ±3°, …, ±75° | (ROMC) (see [`crate::io::rami_mes`]) |
//!
//! Representations: `TUR` cases use the `turbid-layer` generator (HOM) or turbid ellipsoidal
//! crowns (HET). HOM `DIS` cases draw seeded non-intersecting discs with the `disk-canopy`
//! generator, or read RAMI's own leaf file when one is given. HET01 `DIS` cases read RAMI's
//! one-sphere leaf file (assumed centred on (0, 0, 0), as RAMI-IV/V sphere files are —
//! **not confirmed** for RAMI-3) once per sphere; without it their crowns are turbid with the
//! disc radius as leaf size (RAMI accepts this "statistical description"; 750 000 discs would
//! otherwise be drawn).

use super::disk_canopy::{DiskCanopyParams, disk_canopy, disk_canopy_from_list};
use super::turbid_layer::{TurbidLayerParams, turbid_layer};
use super::*;
use crate::direction::{DirectionParams, ExactDirection};
use crate::io::rami_mes::{Plane, signed_view_zeniths_deg};
use crate::random::{stream, uniform};
use std::f64::consts::PI;
use std::fmt;

/// HOM disc radius, metres ((R3)/(S)).
pub const HOM_DISC_RADIUS_M: f64 = 0.1;
/// Side of the HOM13 leaf-file section, metres ((R3)).
pub const HOM_LEAF_FILE_SIDE_M: f64 = 25.0;
/// HET scene side, metres ((R3)).
pub const HET_SIZE_M: f64 = 100.0;
/// HET scene height, metres ((R3)).
pub const HET_HEIGHT_M: f64 = 30.0;
/// Number of HET spheres ((R3)).
pub const HET_SPHERES: usize = 15;
/// HET sphere radius, metres ((R3)).
pub const HET_SPHERE_RADIUS_M: f64 = 10.0;
/// LAI of one HET sphere: leaf area / (π r²) ((R3)).
pub const HET_SPHERE_LAI: f64 = 5.0;
/// HET01 disc radius, metres ((R3)).
pub const HET01_DISC_RADIUS_M: f64 = 0.1;
/// Lowest HET sphere-centre height, metres ((R3)).
pub const HET_MIN_CENTRE_HEIGHT_M: f64 = 11.0;
/// Highest HET sphere-centre height, metres ((A), see the module table).
pub const HET_MAX_CENTRE_HEIGHT_M: f64 = 19.0;

/// Scene representation (`TUR` / `DIS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Representation {
    /// Turbid medium of dimensionless scatterers.
    Turbid,
    /// Discrete disc-shaped scatterers.
    Discrete,
}

/// Leaf normal distribution (`ERE` / `PLA` / `UNI`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lnd {
    /// Erectophile.
    Erectophile,
    /// Planophile.
    Planophile,
    /// RAMI "uniform" = spherical (isotropic normals).
    Uniform,
}

impl Lnd {
    /// The scene-format LAD (`UNI` is the spherical LAD, see the module table).
    pub fn lad(self) -> LadDesc {
        match self {
            Lnd::Erectophile => LadDesc::Erectophile,
            Lnd::Planophile => LadDesc::Planophile,
            Lnd::Uniform => LadDesc::Spherical,
        }
    }
}

/// Spectral case (`RED` / `NIR` / `NR1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RamiBand {
    /// Red.
    Red,
    /// Near infrared.
    Nir,
    /// Conservative scattering ("purist corner").
    Nr1,
}

impl RamiBand {
    /// Leaf and soil optics of the case (module table).
    pub fn optics(self) -> BandOptics {
        match self {
            RamiBand::Red => BandOptics::red(),
            RamiBand::Nir => BandOptics::nir(),
            RamiBand::Nr1 => BandOptics {
                name: "nr1".into(),
                wavelength_nm: 865.0,
                leaf_r: 0.5,
                leaf_t: 0.5,
                soil_r: 1.0,
            },
        }
    }
}

/// The published RAMI-3 experiments handled here: (scene, representation, LNDs, bands, sun
/// zeniths in degrees), from the ROMC debug-experiment lists.
pub const PUBLISHED: &[(&str, &str, &[&str], &[&str], &[u32])] = &[
    ("HOM01", "TUR", &["ERE", "PLA"], &["NR1"], &[0, 30, 60]),
    ("HOM02", "TUR", &["ERE", "PLA"], &["NR1"], &[0, 30, 60]),
    ("HOM03", "TUR", &["PLA", "UNI"], &["RED", "NIR"], &[20, 50]),
    ("HOM05", "TUR", &["ERE", "PLA"], &["NR1"], &[0, 30, 60]),
    ("HOM03", "DIS", &["ERE"], &["RED", "NIR"], &[20, 50]),
    ("HOM11", "DIS", &["ERE", "PLA"], &["NR1"], &[0, 30, 60]),
    ("HOM12", "DIS", &["ERE", "PLA"], &["NR1"], &[0, 30, 60]),
    ("HOM13", "DIS", &["PLA"], &["RED", "NIR"], &[20, 50]),
    ("HOM15", "DIS", &["ERE", "PLA"], &["NR1"], &[0, 30, 60]),
    ("HET01", "DIS", &["UNI"], &["RED", "NIR", "NR1"], &[20, 50]),
    ("HET02", "TUR", &["UNI"], &["RED", "NIR", "NR1"], &[20, 50]),
];

/// LAI and canopy height (metres) of a HOM structure (module table).
pub fn hom_structure(scene: &str) -> Option<(f64, f64)> {
    Some(match scene {
        "HOM01" | "HOM11" => (1.0, 1.0),
        "HOM02" | "HOM12" => (2.0, 1.0),
        "HOM03" | "HOM13" => (3.0, 2.0),
        "HOM05" | "HOM15" => (5.0, 1.0),
        _ => return None,
    })
}

/// A parsed RAMI-3 experiment identifier.
#[derive(Debug, Clone, PartialEq)]
pub struct RamiCase {
    /// Structure tag (`HOM13`, `HET01`, …).
    pub scene: String,
    /// Turbid or discrete.
    pub representation: Representation,
    /// Leaf normal distribution.
    pub lnd: Lnd,
    /// Spectral case.
    pub band: RamiBand,
    /// Sun zenith (ground→sun), degrees.
    pub sun_zenith_deg: f64,
}

impl RamiCase {
    /// Parses an identifier such as `HOM13_DIS_PLA_NIR_20` (case-insensitive) and checks that it
    /// is one of the [`PUBLISHED`] experiments. Build the struct directly for other
    /// combinations.
    pub fn parse(id: &str) -> Result<RamiCase, String> {
        let up = id.trim().to_ascii_uppercase();
        let t: Vec<&str> = up.split('_').collect();
        let usage = || {
            format!(
                "RAMI case `{id}`: expected SCENE_REP_LND_BAND_SZA, e.g. HOM13_DIS_PLA_NIR_20 (SCENE HOM01…HOM15 or HET01/HET02; REP TUR or DIS; LND ERE, PLA or UNI; BAND RED, NIR or NR1; SZA in degrees)"
            )
        };
        if t.len() != 5 {
            return Err(usage());
        }
        let representation = match t[1] {
            "TUR" => Representation::Turbid,
            "DIS" => Representation::Discrete,
            _ => return Err(usage()),
        };
        let lnd = match t[2] {
            "ERE" => Lnd::Erectophile,
            "PLA" => Lnd::Planophile,
            "UNI" => Lnd::Uniform,
            _ => return Err(usage()),
        };
        let band = match t[3] {
            "RED" => RamiBand::Red,
            "NIR" => RamiBand::Nir,
            "NR1" => RamiBand::Nr1,
            _ => return Err(usage()),
        };
        let sza: u32 = t[4]
            .parse()
            .ok()
            .filter(|_| t[4].len() == 2)
            .ok_or_else(usage)?;
        let published = PUBLISHED.iter().any(|(s, r, l, b, z)| {
            *s == t[0] && *r == t[1] && l.contains(&t[2]) && b.contains(&t[3]) && z.contains(&sza)
        });
        if !published {
            let list: Vec<String> = PUBLISHED
                .iter()
                .map(|(s, r, l, b, z)| {
                    let zs: Vec<String> = z.iter().map(|x| format!("{x:02}")).collect();
                    format!(
                        "{s}_{r}_{{{}}}_{{{}}}_{{{}}}",
                        l.join(","),
                        b.join(","),
                        zs.join(",")
                    )
                })
                .collect();
            return Err(format!(
                "RAMI case `{id}` is not a published RAMI-3 experiment handled here; published: {}",
                list.join(" ")
            ));
        }
        Ok(RamiCase {
            scene: t[0].to_string(),
            representation,
            lnd,
            band,
            sun_zenith_deg: sza as f64,
        })
    }

    /// True for the floating-spheres cases (`HET01`, `HET02`).
    pub fn is_het(&self) -> bool {
        self.scene.starts_with("HET")
    }
}

impl fmt::Display for RamiCase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rep = match self.representation {
            Representation::Turbid => "TUR",
            Representation::Discrete => "DIS",
        };
        let lnd = match self.lnd {
            Lnd::Erectophile => "ERE",
            Lnd::Planophile => "PLA",
            Lnd::Uniform => "UNI",
        };
        let band = match self.band {
            RamiBand::Red => "RED",
            RamiBand::Nir => "NIR",
            RamiBand::Nr1 => "NR1",
        };
        write!(
            f,
            "{}_{rep}_{lnd}_{band}_{:02}",
            self.scene,
            self.sun_zenith_deg.round() as i64
        )
    }
}

impl std::str::FromStr for RamiCase {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        RamiCase::parse(s)
    }
}

/// Generation options (everything not fixed by the RAMI case).
#[derive(Debug, Clone, PartialEq)]
pub struct RamiOptions {
    /// Scene side, metres (HOM only; default: 2 m turbid, 25 m discrete — the side of RAMI's
    /// HOM13 leaf file; HET scenes are always 100 m).
    pub size_m: Option<f64>,
    /// Cell size, metres (default 0.5 m HOM, 1 m HET).
    pub cell_m: Option<f64>,
    /// Seed of the drawn discs (HOM `DIS`) and sphere positions (HET).
    pub seed: u64,
    /// Sun azimuth (ground→sun, anticlockwise from +x), degrees.
    pub sun_azimuth_deg: f64,
    /// A RAMI leaf file (`R Xc Yc Zc Dx Dy Dz` per line) as it should be written into the
    /// scene (absolute, or relative to where the scene is saved): HOM `DIS` — the whole
    /// canopy section, whose side `size_m` must equal (default 25 m, RAMI-3 HOM13's); HET01 —
    /// the leaves of one sphere, centred on (0, 0, 0), instanced in each sphere.
    pub leaves: Option<String>,
}

impl Default for RamiOptions {
    fn default() -> Self {
        Self {
            size_m: None,
            cell_m: None,
            seed: 1,
            sun_azimuth_deg: 0.0,
            leaves: None,
        }
    }
}

/// The RAMI measurement directions: the principal and orthogonal planes at view zenith ±1°,
/// ±3°, …, ±75° ((ROMC); 152 exact upward directions, none at nadir, hence no duplicate), on
/// top of DART's default 100 directions. Principal plane: negative RAMI zenith = sun side
/// (view azimuth = `sun_azimuth_deg`); orthogonal plane: view azimuth = sun azimuth ± 90°
/// (see [`crate::io::rami_mes`]). Labels are `brfpp-75` … `brfop+75`.
pub fn rami_measurement_directions(sun_azimuth_deg: f64) -> DirectionParams {
    let mut exact = Vec::with_capacity(2 * crate::io::rami_mes::VIEWS_PER_PLANE);
    for p in Plane::ALL {
        for vz in signed_view_zeniths_deg() {
            exact.push(ExactDirection {
                zenith_deg: vz.abs(),
                azimuth_deg: p.view_azimuth_deg(vz, sun_azimuth_deg),
                label: Some(format!("{}{vz:+.0}", p.id())),
                solid_angle_sr: None,
            });
        }
    }
    DirectionParams {
        exact,
        ..DirectionParams::default()
    }
}

fn positive(name: &str, x: f64) -> Result<f64, String> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(format!("{name} must be a positive number, got {x}"))
    }
}

/// Builds a HOM case (`HOM01`…`HOM15`): turbid layer or disc canopy over Lambertian soil on a
/// repetitive scene, with the RAMI measurement directions.
pub fn rami_hom(case: &RamiCase, opts: &RamiOptions) -> Result<SceneDesc, String> {
    let (lai, height) = hom_structure(&case.scene)
        .ok_or_else(|| format!("`{}` is not a RAMI HOM structure", case.scene))?;
    if !(case.sun_zenith_deg.is_finite() && (0.0..90.0).contains(&case.sun_zenith_deg)) {
        return Err(format!(
            "sun zenith {}° is outside [0, 90)",
            case.sun_zenith_deg
        ));
    }
    let cell = positive("cell size", opts.cell_m.unwrap_or(0.5))?;
    if opts.leaves.is_some() && case.representation == Representation::Turbid {
        return Err(format!(
            "`{case}` is turbid: a leaf file applies to the discrete (DIS) cases only"
        ));
    }
    let bands = vec![case.band.optics()];
    let mut d = match case.representation {
        Representation::Turbid => {
            let size = positive("scene size", opts.size_m.unwrap_or(2.0))?;
            let mut d = turbid_layer(&TurbidLayerParams {
                lai,
                lad: case.lnd.lad(),
                bands,
                height_m: height,
                cell_m: cell,
                size_m: size,
                sun_zenith_deg: case.sun_zenith_deg,
                sun_azimuth_deg: opts.sun_azimuth_deg,
            });
            // Dimensionless scatterers: no hot spot.
            if let Some(OpticsDesc::Turbid { leaf_size_m, .. }) = d.optics.get_mut("vegetation") {
                *leaf_size_m = 0.0;
            }
            d
        }
        Representation::Discrete => {
            let size = positive("scene size", opts.size_m.unwrap_or(HOM_LEAF_FILE_SIDE_M))?;
            let p = DiskCanopyParams {
                lai,
                disk_radius_m: HOM_DISC_RADIUS_M,
                height_m: height,
                size_m: size,
                cell_m: cell,
                lad: case.lnd.lad(),
                seed: opts.seed,
                bands,
                sun_zenith_deg: case.sun_zenith_deg,
                sun_azimuth_deg: opts.sun_azimuth_deg,
            };
            let mut d = match &opts.leaves {
                Some(path) => disk_canopy_from_list(&p, path),
                None => disk_canopy(&p)?,
            };
            if let Some(OpticsDesc::Turbid { leaf_size_m, .. }) = d.optics.get_mut("vegetation") {
                *leaf_size_m = HOM_DISC_RADIUS_M;
            }
            d
        }
    };
    d.name = format!("RAMI-3 {case}");
    d.seed = opts.seed;
    d.directions = Some(rami_measurement_directions(opts.sun_azimuth_deg));
    Ok(d)
}

/// Seeded HET sphere centres `(x, y, z)`, metres, in the scene frame `[0, 100]²` (RAMI's
/// `[−50, 50]²` shifted by +50 m): [`HET_SPHERES`] spheres whose horizontal projections are
/// disjoint on the periodic scene (distance ≥ 2 r) and whose centres lie between
/// [`HET_MIN_CENTRE_HEIGHT_M`] and [`HET_MAX_CENTRE_HEIGHT_M`]. Random sequential addition,
/// restarted with a new stream when it jams.
pub fn het_sphere_centres(seed: u64) -> Result<Vec<(f64, f64, f64)>, String> {
    let (l, d2) = (HET_SIZE_M, (2.0 * HET_SPHERE_RADIUS_M).powi(2));
    const RESTARTS: u64 = 1000;
    const TRIALS: usize = 20_000;
    for restart in 0..RESTARTS {
        let mut rng = stream(seed, 0x4845_5430, restart);
        let mut c: Vec<(f64, f64, f64)> = Vec::with_capacity(HET_SPHERES);
        let mut jammed = false;
        while c.len() < HET_SPHERES && !jammed {
            jammed = true;
            for _ in 0..TRIALS {
                let (x, y) = (l * uniform(&mut rng), l * uniform(&mut rng));
                let z = HET_MIN_CENTRE_HEIGHT_M
                    + (HET_MAX_CENTRE_HEIGHT_M - HET_MIN_CENTRE_HEIGHT_M) * uniform(&mut rng);
                let free = c.iter().all(|&(a, b, _)| {
                    let dx = (x - a) - l * ((x - a) / l).round();
                    let dy = (y - b) - l * ((y - b) / l).round();
                    dx * dx + dy * dy >= d2
                });
                if free {
                    c.push((x, y, z));
                    jammed = false;
                    break;
                }
            }
        }
        if c.len() == HET_SPHERES {
            return Ok(c);
        }
    }
    Err(format!(
        "could not place {HET_SPHERES} disjoint spheres after {RESTARTS} restarts (seed {seed})"
    ))
}

/// Builds a floating-spheres case (`HET01` discrete, `HET02` turbid): 15 spherical crowns of
/// LAI 5 over Lambertian soil in a 100 × 100 × 30 m repetitive scene, with the RAMI
/// measurement directions. Crowns are turbid unless a HET01 leaf file is given (module docs).
pub fn rami_het01(case: &RamiCase, opts: &RamiOptions) -> Result<SceneDesc, String> {
    let discrete = match (case.scene.as_str(), case.representation) {
        ("HET01", Representation::Discrete) => true,
        ("HET02", Representation::Turbid) => false,
        _ => {
            return Err(format!(
                "`{case}`: the floating-spheres cases are HET01_DIS and HET02_TUR"
            ));
        }
    };
    if !(case.sun_zenith_deg.is_finite() && (0.0..90.0).contains(&case.sun_zenith_deg)) {
        return Err(format!(
            "sun zenith {}° is outside [0, 90)",
            case.sun_zenith_deg
        ));
    }
    if opts.size_m.is_some_and(|s| s != HET_SIZE_M) {
        return Err(format!(
            "the HET scenes are {HET_SIZE_M} m wide: drop --size"
        ));
    }
    if opts.leaves.is_some() && !discrete {
        return Err(format!(
            "`{case}` is turbid: a leaf file applies to HET01_DIS only"
        ));
    }
    let cell = positive("cell size", opts.cell_m.unwrap_or(1.0))?;
    let centres = het_sphere_centres(opts.seed)?;
    let (bands, mut optics) = standard_optics(&[case.band.optics()], case.lnd.lad());
    if let Some(OpticsDesc::Turbid { leaf_size_m, .. }) = optics.get_mut("vegetation") {
        *leaf_size_m = if discrete { HET01_DISC_RADIUS_M } else { 0.0 };
    }
    let r = HET_SPHERE_RADIUS_M;
    let mut objects = vec![flat_ground("soil")];
    for &(x, y, z) in &centres {
        objects.push(match &opts.leaves {
            Some(path) => ObjectDesc::LeafList(LeafListDesc {
                path: path.clone(),
                optics: "leaf".into(),
                sides: 12,
                translation_m: (x, y, z),
                wrap: true,
                as_turbid: false,
            }),
            None => ObjectDesc::Tree(TreeDesc {
                position_m: (x, y),
                trunk: None,
                crown: CrownDesc {
                    shape: CrownShape::Ellipsoid,
                    base_height_m: z - r,
                    height_m: 2.0 * r,
                    radius_x_m: r,
                    radius_y_m: None,
                    top_radius_fraction: None,
                    foliage: FoliageDesc::Lai(HET_SPHERE_LAI),
                    vertical_profile: vec![],
                    radial_profile: vec![],
                    optics: "vegetation".into(),
                },
            }),
        });
    }
    let what = match (&opts.leaves, discrete) {
        (Some(_), _) => "RAMI leaf file in every sphere",
        (None, true) => "turbid crowns with 0.1 m leaf size: statistical description",
        (None, false) => "turbid crowns",
    };
    Ok(SceneDesc {
        version: SCENE_FORMAT_VERSION,
        name: format!("RAMI-3 {case} ({what})"),
        seed: opts.seed,
        grid: GridDesc {
            height_m: Some(HET_HEIGHT_M),
            ..cube_grid(HET_SIZE_M, cell, BoundaryMode::Repetitive)
        },
        bands,
        optics,
        illumination: sun(case.sun_zenith_deg, opts.sun_azimuth_deg),
        objects,
        atmosphere: None,
        sensors: None,
        lidars: None,
        directions: Some(rami_measurement_directions(opts.sun_azimuth_deg)),
        radiative: None,
        passive: None,
        georeference: None,
        thermal: None,
    })
}

/// Builds any handled RAMI case ([`rami_hom`] or [`rami_het01`]).
pub fn rami_scene(case: &RamiCase, opts: &RamiOptions) -> Result<SceneDesc, String> {
    if case.is_het() {
        rami_het01(case, opts)
    } else {
        rami_hom(case, opts)
    }
}

/// Number of discs a HOM `DIS` scene of side `size_m` holds: round(LAI · size² / (π r²)).
pub fn hom_disc_count(lai: f64, size_m: f64) -> usize {
    (lai * size_m * size_m / (PI * HOM_DISC_RADIUS_M * HOM_DISC_RADIUS_M)).round() as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers_round_trip_and_unpublished_ones_are_refused() {
        for (s, r, l, b, z) in PUBLISHED {
            for lnd in *l {
                for band in *b {
                    for sza in *z {
                        let id = format!("{s}_{r}_{lnd}_{band}_{sza:02}");
                        let c = RamiCase::parse(&id).unwrap();
                        assert_eq!(c.to_string(), id);
                        assert_eq!(c.sun_zenith_deg, *sza as f64);
                    }
                }
            }
        }
        assert!(RamiCase::parse("hom13_dis_pla_nir_20").is_ok());
        for bad in [
            "HOM13_DIS_ERE_NIR_20",
            "HOM13_DIS_PLA_NIR_30",
            "HOM13_DIS_PLA_NIR",
            "HOM13_XXX_PLA_NIR_20",
            "HOM13_DIS_PLA_NIR_2",
            "",
        ] {
            assert!(RamiCase::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_hom13_leaf_file_count_follows_from_lai_and_radius() {
        // (R3): 59 683 discs of radius 0.1 m in 25 × 25 m² for LAI 3.
        assert_eq!(hom_disc_count(3.0, HOM_LEAF_FILE_SIDE_M), 59_683);
    }

    #[test]
    fn sphere_centres_are_disjoint_and_in_range() {
        let c = het_sphere_centres(7).unwrap();
        assert_eq!(c.len(), HET_SPHERES);
        assert_eq!(c, het_sphere_centres(7).unwrap());
        for (i, a) in c.iter().enumerate() {
            assert!((HET_MIN_CENTRE_HEIGHT_M..=HET_MAX_CENTRE_HEIGHT_M).contains(&a.2));
            assert!(a.2 + HET_SPHERE_RADIUS_M <= HET_HEIGHT_M);
            for b in &c[..i] {
                let dx = (a.0 - b.0) - HET_SIZE_M * ((a.0 - b.0) / HET_SIZE_M).round();
                let dy = (a.1 - b.1) - HET_SIZE_M * ((a.1 - b.1) / HET_SIZE_M).round();
                assert!(dx.hypot(dy) >= 2.0 * HET_SPHERE_RADIUS_M - 1e-9);
            }
        }
    }
}
