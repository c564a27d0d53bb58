//! RAMI / ROMC measurement files (`.mes`): writer, reader, the RAMI view geometry, and the
//! conversion of a finished run (`DIR/summary.json`) into the RAMI-3 measurements `brfpp`,
//! `brfop` (and their `_co_sgl`, `_uc_sgl`, `_mlt` parts), `brf1`, `fabs` and `ftran`.
//!
//! # Sources
//! * ROMC "file naming and formatting conventions"
//!   (romc.jrc.ec.europa.eu/_www/ROMC_Home_Formats.php): files are named
//!   `<MES>_<MOD>-<EXP>.mes` (e.g. `brf1_raytran-HET01_DIS_UNI_NIR_50.mes`); `<MOD>` is the model
//!   name registered with the ROMC (case-insensitive alphanumeric, at most 10 characters);
//!   `<EXP>` is the experiment identifier `A_B_C_D_E`; the permissible `<MES>` are `fabs`,
//!   `brfop`, `brfop_co_sgl`, `brfop_mlt`, `brfop_uc_sgl`, `brfpp`, `brfpp_co_sgl`, `brfpp_mlt`,
//!   `brfpp_uc_sgl`, `brf1` (spectral albedo, i.e. the directional–hemispherical reflectance,
//!   DHR), `ftran` (total transmission to the soil level, direct + diffuse) and `gonio` (not
//!   produced here).
//! * ROMC measurement page for RAMI-3 `brfpp` (…/data/MEAS/FORWARD/DEBUG/RAMI3/brfpp.php): BRFs
//!   every 2° of view zenith from −75° to 75°; header line `# rows`, `# columns in file`,
//!   `ratio of filtered rays` (−1.000000 when not available); body lines `SZA [rad]`,
//!   `VZA [rad]`, `SAA − VAA [rad]`, `BRF`, `std. dev. BRF` (−1.000000 when not available); for
//!   `brf1` the VZA and SAA − VAA columns are −1.000000. Reals are written with 6 decimals.
//!   The single- and multiple-scattering parts use the format of their plane (RAMI pages
//!   `brfpp_uc_sgl`, `brfop_mlt`, …).
//! * ROMC measurement page for RAMI-3 `fabs` (…/RAMI3/fabs.php): one real, the *percentage* of
//!   the radiation entering the canopy that the foliage absorbs (example `78.654321`).
//!
//! # Geometry (as read from the published example files)
//! 2° steps over −75…75° without 0 give 76 views: ±1°, ±3°, …, ±75° (so there is no nadir view
//! and no duplicate at nadir). Rows run from −75° to −1° then from 1° to 75°, and the VZA column
//! holds |VZA|; the sign is carried by the SAA − VAA column:
//! * principal plane: negative VZA = viewer on the sun side (SAA − VAA = 0, the hot spot is in
//!   the first half of the published example), positive = forward (SAA − VAA = π);
//! * orthogonal plane: negative VZA ↔ SAA − VAA = −π/2 (as in the published `brfop` examples),
//!   positive ↔ +π/2.
//!
//! In this crate's angles (azimuth anticlockwise from +x, view azimuth = sun azimuth on the sun
//! side) the view azimuth is therefore VAA = SAA − (SAA − VAA).
//!
//! # Not confirmed by the material available
//! * The second half of the published examples (positive VZA) was not in the stored pages: π
//!   and +π/2 are inferred (the rows' count, 76, and the third-party readers agree).
//! * Whether RAMI azimuths turn clockwise or anticlockwise: the orthogonal-plane sides
//!   (VAA = SAA ± 90°) may be mirrored with respect to RAMI's. This matters only for scenes
//!   without mirror symmetry about the principal plane (not the HOM cases; HET01 only through
//!   its sphere positions).
//! * The `ftran` file format: written like `fabs` (one real, percentage), as third-party ROMC
//!   submission scripts do; the ROMC `ftran` page itself was not available.
//! * `std. dev. BRF`: we write the Monte Carlo standard error of the estimate (−1 for flux
//!   tracking); the ratio of filtered rays is always −1 (not applicable).

use serde::{Deserialize, Deserializer, Serialize};
use std::f64::consts::{FRAC_PI_2, PI};

/// Number of views per plane: ±1°, ±3°, …, ±75°.
pub const VIEWS_PER_PLANE: usize = 76;

/// Angular tolerance, degrees, when matching a run's exact directions to the RAMI views.
pub const MATCH_TOLERANCE_DEG: f64 = 1e-3;

/// The RAMI signed view zeniths, degrees, in file order: −75, −73, …, −1, 1, 3, …, 75.
pub fn signed_view_zeniths_deg() -> Vec<f64> {
    let neg = (0..38).map(|k| -(75.0 - 2.0 * k as f64));
    let pos = (0..38).map(|k| 1.0 + 2.0 * k as f64);
    neg.chain(pos).collect()
}

/// A RAMI measurement plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Plane {
    /// Principal plane (contains the sun): `brfpp*`.
    Principal,
    /// Orthogonal (cross) plane, perpendicular to the principal plane: `brfop*`.
    Orthogonal,
}

impl Plane {
    /// Both planes, in the order the files are written.
    pub const ALL: [Plane; 2] = [Plane::Principal, Plane::Orthogonal];

    /// `SAA − VAA`, radians, of the view at signed zenith `signed_vza_deg` (column 3 of the
    /// file; see the module documentation for the sign convention).
    pub fn relative_azimuth_rad(self, signed_vza_deg: f64) -> f64 {
        match (self, signed_vza_deg < 0.0) {
            (Plane::Principal, true) => 0.0,
            (Plane::Principal, false) => PI,
            (Plane::Orthogonal, true) => -FRAC_PI_2,
            (Plane::Orthogonal, false) => FRAC_PI_2,
        }
    }

    /// View azimuth in the scene convention (anticlockwise from +x, view on the sun side has
    /// the sun's azimuth), degrees in `[0, 360)`: VAA = SAA − (SAA − VAA).
    pub fn view_azimuth_deg(self, signed_vza_deg: f64, sun_azimuth_deg: f64) -> f64 {
        let v = (sun_azimuth_deg - self.relative_azimuth_rad(signed_vza_deg).to_degrees())
            .rem_euclid(360.0);
        // rem_euclid may return 360 for tiny negative inputs.
        if v >= 360.0 { 0.0 } else { v }
    }

    /// The measurement identifier of the total BRF in this plane (`brfpp` or `brfop`).
    pub fn id(self) -> &'static str {
        match self {
            Plane::Principal => "brfpp",
            Plane::Orthogonal => "brfop",
        }
    }
}

/// Part of a BRF (RAMI: total, single scattering by the canopy, single scattering by the soil of
/// uncollided light, multiple scattering).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Component {
    /// Total BRF.
    Total,
    /// `_co_sgl`: single-scattered radiation collided by the leaves.
    CoSgl,
    /// `_uc_sgl`: single-scattered radiation collided by the soil (uncollided by the canopy).
    UcSgl,
    /// `_mlt`: two or more scattering events.
    Mlt,
}

impl Component {
    /// All parts, in the order the files are written.
    pub const ALL: [Component; 4] = [
        Component::Total,
        Component::CoSgl,
        Component::UcSgl,
        Component::Mlt,
    ];

    fn suffix(self) -> &'static str {
        match self {
            Component::Total => "",
            Component::CoSgl => "_co_sgl",
            Component::UcSgl => "_uc_sgl",
            Component::Mlt => "_mlt",
        }
    }
}

/// A ROMC measurement identifier (`<MES>`) produced here.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Measurement {
    /// A BRF in a plane (`brfpp`, `brfpp_co_sgl`, …, `brfop_mlt`).
    Brf(Plane, Component),
    /// Spectral albedo (DHR).
    Brf1,
    /// Absorption by the foliage, percent.
    Fabs,
    /// Total transmission to the soil level, percent.
    Ftran,
}

impl Measurement {
    /// Every measurement, in the order the files are written.
    pub fn all() -> Vec<Measurement> {
        let mut v = Vec::new();
        for p in Plane::ALL {
            for c in Component::ALL {
                v.push(Measurement::Brf(p, c));
            }
        }
        v.extend([Measurement::Brf1, Measurement::Fabs, Measurement::Ftran]);
        v
    }

    /// The identifier, e.g. `brfpp_co_sgl`.
    pub fn id(self) -> String {
        match self {
            Measurement::Brf(p, c) => format!("{}{}", p.id(), c.suffix()),
            Measurement::Brf1 => "brf1".into(),
            Measurement::Fabs => "fabs".into(),
            Measurement::Ftran => "ftran".into(),
        }
    }

    /// Parses an identifier.
    pub fn from_id(s: &str) -> Option<Measurement> {
        Measurement::all().into_iter().find(|m| m.id() == s)
    }

    /// True for the files holding a BRF table (`brfpp*`, `brfop*`, `brf1`).
    pub fn is_brf_table(self) -> bool {
        matches!(self, Measurement::Brf(..) | Measurement::Brf1)
    }
}

/// A malformed `.mes` file or name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}line {line}: {message}", .file.as_ref().map(|f| format!("{f}: ")).unwrap_or_default())]
pub struct MesError {
    /// File name, when known.
    pub file: Option<String>,
    /// 1-based line number (0: the file name itself).
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

fn merr(line: usize, message: impl Into<String>) -> MesError {
    MesError {
        file: None,
        line,
        message: message.into(),
    }
}

/// Checks a ROMC model name: 1–10 ASCII letters or digits.
pub fn validate_model_name(model: &str) -> Result<(), String> {
    if model.is_empty() || model.len() > 10 || !model.chars().all(|c| c.is_ascii_alphanumeric()) {
        Err(format!(
            "model name `{model}`: the ROMC wants 1 to 10 letters or digits (the name registered with the ROMC)"
        ))
    } else {
        Ok(())
    }
}

/// Checks an experiment identifier: five non-empty ASCII alphanumeric tags separated by `_`
/// (e.g. `HOM13_DIS_PLA_NIR_20`).
pub fn validate_experiment(exp: &str) -> Result<(), String> {
    let parts: Vec<&str> = exp.split('_').collect();
    if parts.len() != 5
        || parts
            .iter()
            .any(|p| p.is_empty() || !p.chars().all(|c| c.is_ascii_alphanumeric()))
    {
        Err(format!(
            "experiment `{exp}`: expected five letter/digit tags separated by `_`, e.g. HOM13_DIS_PLA_NIR_20"
        ))
    } else {
        Ok(())
    }
}

/// The ROMC file name `<MES>_<MOD>-<EXP>.mes`.
pub fn file_name(m: Measurement, model: &str, experiment: &str) -> String {
    format!("{}_{model}-{experiment}.mes", m.id())
}

/// Splits a ROMC file name into measurement, model and experiment.
pub fn parse_file_name(name: &str) -> Result<(Measurement, String, String), MesError> {
    let bad = |msg: String| MesError {
        file: Some(name.to_string()),
        line: 0,
        message: msg,
    };
    let stem = name
        .strip_suffix(".mes")
        .ok_or_else(|| bad("the name must end in `.mes`".into()))?;
    let (head, exp) = stem
        .split_once('-')
        .ok_or_else(|| bad("expected <MES>_<MOD>-<EXP>.mes".into()))?;
    let (mes, model) = head
        .rsplit_once('_')
        .ok_or_else(|| bad("expected <MES>_<MOD>-<EXP>.mes".into()))?;
    let m = Measurement::from_id(mes).ok_or_else(|| bad(format!("unknown measurement `{mes}`")))?;
    validate_model_name(model).map_err(bad)?;
    validate_experiment(exp).map_err(bad)?;
    Ok((m, model.to_string(), exp.to_string()))
}

/// One body line of a BRF file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BrfRow {
    /// Sun zenith angle, radians.
    pub sza_rad: f64,
    /// |view zenith|, radians (−1 for `brf1`).
    pub vza_rad: f64,
    /// Sun azimuth − view azimuth, radians (−1 for `brf1`).
    pub rel_azimuth_rad: f64,
    /// Bidirectional reflectance factor (or the DHR for `brf1`).
    pub brf: f64,
    /// Standard deviation of the BRF estimate (−1 if not available).
    pub std_dev: f64,
}

/// A BRF file: header and rows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BrfTable {
    /// Ratio of filtered rays (−1 if not available).
    pub ratio_filtered_rays: f64,
    /// Body lines.
    pub rows: Vec<BrfRow>,
}

/// `%.6f` without a negative zero.
fn f6(x: f64) -> String {
    let s = format!("{x:.6}");
    if s == "-0.000000" {
        "0.000000".into()
    } else {
        s
    }
}

/// Writes a BRF table (header `rows columns ratio`, then one tab-separated line per row).
pub fn write_brf_table(t: &BrfTable) -> String {
    let mut s = format!("{}\t5\t{}\n", t.rows.len(), f6(t.ratio_filtered_rays));
    for r in &t.rows {
        s.push_str(&format!(
            "{}\t{}\t{}\t{}\t{}\n",
            f6(r.sza_rad),
            f6(r.vza_rad),
            f6(r.rel_azimuth_rad),
            f6(r.brf),
            f6(r.std_dev)
        ));
    }
    s
}

fn numbers(line: &str, lineno: usize) -> Result<Vec<f64>, MesError> {
    line.split_whitespace()
        .map(|w| {
            w.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| merr(lineno, format!("`{w}` is not a finite number")))
        })
        .collect()
}

/// Non-blank lines with their 1-based numbers.
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
}

/// Parses a BRF table; errors name the line.
pub fn parse_brf_table(text: &str) -> Result<BrfTable, MesError> {
    let mut lines = content_lines(text);
    let (hl, header) = lines.next().ok_or_else(|| merr(1, "empty file"))?;
    let h: Vec<&str> = header.split_whitespace().collect();
    if h.len() != 3 {
        return Err(merr(
            hl,
            format!("header: expected `rows columns ratio`, found `{header}`"),
        ));
    }
    let n: usize = h[0].parse().map_err(|_| {
        merr(
            hl,
            format!("header: row count `{}` is not an integer", h[0]),
        )
    })?;
    let cols: usize = h[1].parse().map_err(|_| {
        merr(
            hl,
            format!("header: column count `{}` is not an integer", h[1]),
        )
    })?;
    if cols != 5 {
        return Err(merr(hl, format!("header: {cols} columns, expected 5")));
    }
    let ratio = numbers(h[2], hl)?[0];
    let mut rows = Vec::with_capacity(n);
    let mut last = hl;
    for (ln, l) in lines {
        last = ln;
        let v = numbers(l, ln)?;
        if v.len() != cols {
            return Err(merr(ln, format!("{} values, expected {cols}", v.len())));
        }
        rows.push(BrfRow {
            sza_rad: v[0],
            vza_rad: v[1],
            rel_azimuth_rad: v[2],
            brf: v[3],
            std_dev: v[4],
        });
        if rows.len() > n {
            return Err(merr(ln, format!("more rows than the {n} of the header")));
        }
    }
    if rows.len() != n {
        return Err(merr(
            last,
            format!("{} rows, the header announces {n}", rows.len()),
        ));
    }
    Ok(BrfTable {
        ratio_filtered_rays: ratio,
        rows,
    })
}

/// Writes a percentage file (`fabs`, `ftran`): one real with 6 decimals.
pub fn write_percent(percent: f64) -> String {
    format!("{}\n", f6(percent))
}

/// Parses a percentage file (one real; a second value, a standard deviation as in RAMI-IV
/// files, is accepted and ignored).
pub fn parse_percent(text: &str) -> Result<f64, MesError> {
    let mut lines = content_lines(text);
    let (ln, l) = lines.next().ok_or_else(|| merr(1, "empty file"))?;
    let v = numbers(l, ln)?;
    if v.is_empty() || v.len() > 2 {
        return Err(merr(ln, format!("expected one value, found {}", v.len())));
    }
    if let Some((ln2, _)) = lines.next() {
        return Err(merr(ln2, "unexpected extra line"));
    }
    Ok(v[0])
}

/// The content of a parsed `.mes` file.
#[derive(Debug, Clone, PartialEq)]
pub enum MesContent {
    /// A BRF table (`brfpp*`, `brfop*`, `brf1`).
    Brf(BrfTable),
    /// A percentage (`fabs`, `ftran`).
    Percent(f64),
}

/// Parses a `.mes` file given its ROMC name (which selects the format).
pub fn parse_mes(name: &str, text: &str) -> Result<(Measurement, MesContent), MesError> {
    let (m, _, _) = parse_file_name(name)?;
    let with_file = |mut e: MesError| {
        e.file = Some(name.to_string());
        e
    };
    let c = if m.is_brf_table() {
        MesContent::Brf(parse_brf_table(text).map_err(with_file)?)
    } else {
        MesContent::Percent(parse_percent(text).map_err(with_file)?)
    };
    Ok((m, c))
}

// ---------------------------------------------------------------------------------------------
// Conversion of a run's summary.json.

fn nan_if_null<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// The parts of a run's `summary.json` read here (unknown fields are ignored; JSON `null`,
/// which is how serde_json writes NaN, reads as NaN).
#[derive(Debug, Clone, Deserialize)]
pub struct RunSummary {
    /// `flux-tracking` or `monte-carlo`.
    pub solver: String,
    /// Run settings (sun angles).
    pub settings: RunSettingsSummary,
    /// Per-band products.
    pub bands: Vec<RunBand>,
}

/// Sun angles of a run.
#[derive(Debug, Clone, Deserialize)]
pub struct RunSettingsSummary {
    /// Sun zenith (ground→sun), degrees.
    #[serde(deserialize_with = "nan_if_null")]
    pub sun_zenith_deg: f64,
    /// Sun azimuth (ground→sun, anticlockwise from +x), degrees.
    #[serde(deserialize_with = "nan_if_null")]
    pub sun_azimuth_deg: f64,
}

/// Products of one band of a run.
#[derive(Debug, Clone, Deserialize)]
pub struct RunBand {
    /// Band name.
    pub band: String,
    /// Scene albedo.
    #[serde(deserialize_with = "nan_if_null")]
    pub albedo: f64,
    /// Fraction absorbed by the vegetation.
    #[serde(deserialize_with = "nan_if_null")]
    pub fabs: f64,
    /// Fraction reaching the ground.
    #[serde(deserialize_with = "nan_if_null")]
    pub ftran: f64,
    /// Standard error of `albedo` (Monte Carlo).
    #[serde(default)]
    pub albedo_se: Option<f64>,
    /// Standard error of `fabs` (Monte Carlo).
    #[serde(default)]
    pub fabs_se: Option<f64>,
    /// Standard error of `ftran` (Monte Carlo).
    #[serde(default)]
    pub ftran_se: Option<f64>,
    /// Reflectance factors of the upward directions.
    pub brf: Vec<RunBrf>,
}

/// One reflectance factor of a run.
#[derive(Debug, Clone, Deserialize)]
pub struct RunBrf {
    /// View zenith, degrees.
    pub zenith_deg: f64,
    /// View azimuth, degrees (anticlockwise from +x).
    pub azimuth_deg: f64,
    /// Direction kind (`regular`, `exact`, `oversampled`).
    pub kind: String,
    /// BRF under direct sun.
    #[serde(deserialize_with = "nan_if_null")]
    pub brf: f64,
    /// HDRF (present only with sky light).
    #[serde(default)]
    pub hdrf: Option<f64>,
    /// Standard error of `brf` (Monte Carlo).
    #[serde(default)]
    pub brf_se: Option<f64>,
    /// Single scattering by the canopy (Monte Carlo peel-off).
    #[serde(default)]
    pub brf_co_sgl: Option<f64>,
    /// Single scattering by the soil of uncollided light.
    #[serde(default)]
    pub brf_uc_sgl: Option<f64>,
    /// Multiple scattering.
    #[serde(default)]
    pub brf_mlt: Option<f64>,
    /// Standard errors of the three parts (Monte Carlo).
    #[serde(default)]
    pub brf_components_se: Option<[f64; 3]>,
    /// `peel-off`, `escape` or absent (flux tracking).
    #[serde(default)]
    pub estimator: Option<String>,
}

/// One RAMI view of a plane with its values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaneView {
    /// Signed RAMI view zenith, degrees (principal plane: negative = sun side).
    pub view_zenith_deg: f64,
    /// View azimuth in the scene convention, degrees.
    pub view_azimuth_deg: f64,
    /// Total BRF.
    pub brf: f64,
    /// Standard error of `brf` (Monte Carlo).
    pub brf_se: Option<f64>,
    /// Single scattering by the canopy (`_co_sgl`).
    pub co_sgl: Option<f64>,
    /// Single scattering by the soil (`_uc_sgl`).
    pub uc_sgl: Option<f64>,
    /// Multiple scattering (`_mlt`).
    pub mlt: Option<f64>,
    /// Standard errors of (`co_sgl`, `uc_sgl`, `mlt`) (Monte Carlo).
    #[serde(default)]
    pub components_se: Option<[f64; 3]>,
    /// How the value was estimated (`peel-off` in Monte Carlo, absent for flux tracking).
    pub estimator: Option<String>,
}

impl PlaneView {
    /// The value of a part (`None` when the solver does not separate it).
    pub fn component(&self, c: Component) -> Option<f64> {
        match c {
            Component::Total => Some(self.brf),
            Component::CoSgl => self.co_sgl,
            Component::UcSgl => self.uc_sgl,
            Component::Mlt => self.mlt,
        }
    }
}

/// The RAMI measurements of one experiment (written to `measurements.json` and as `.mes`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RamiMeasurements {
    /// Experiment identifier, e.g. `HOM13_DIS_PLA_NIR_20`.
    pub experiment: String,
    /// ROMC model name.
    pub model: String,
    /// Band of the run the values come from.
    pub band: String,
    /// Solver of the run.
    pub solver: String,
    /// Sun zenith, degrees.
    pub sun_zenith_deg: f64,
    /// Sun azimuth (scene convention), degrees.
    pub sun_azimuth_deg: f64,
    /// Principal-plane views in file order.
    pub brfpp: Vec<PlaneView>,
    /// Orthogonal-plane views in file order.
    pub brfop: Vec<PlaneView>,
    /// Spectral albedo (DHR) under direct sun: the run's `albedo`.
    pub brf1: f64,
    /// Standard error of `brf1`.
    pub brf1_se: Option<f64>,
    /// Fraction absorbed by the foliage (0–1; the file holds the percentage).
    pub fabs: f64,
    /// Standard error of `fabs`.
    pub fabs_se: Option<f64>,
    /// Fraction transmitted to the soil level, direct + diffuse (0–1; the file holds the
    /// percentage).
    pub ftran: f64,
    /// Standard error of `ftran`.
    pub ftran_se: Option<f64>,
}

impl RamiMeasurements {
    /// Views of a plane.
    pub fn plane(&self, p: Plane) -> &[PlaneView] {
        match p {
            Plane::Principal => &self.brfpp,
            Plane::Orthogonal => &self.brfop,
        }
    }

    /// True when every view carries the single/multiple-scattering parts.
    pub fn has_components(&self) -> bool {
        self.brfpp
            .iter()
            .chain(&self.brfop)
            .all(|v| v.co_sgl.is_some() && v.uc_sgl.is_some() && v.mlt.is_some())
    }

    /// The measurements available from this run (the `_co_sgl`/`_uc_sgl`/`_mlt` parts only
    /// when the solver separates them).
    pub fn available(&self) -> Vec<Measurement> {
        let comps = self.has_components();
        Measurement::all()
            .into_iter()
            .filter(|m| match m {
                Measurement::Brf(_, Component::Total) => true,
                Measurement::Brf(..) => comps,
                _ => true,
            })
            .collect()
    }

    /// The BRF table of a plane measurement (or `brf1`); `None` for a part the run lacks or for
    /// `fabs`/`ftran`.
    pub fn brf_table(&self, m: Measurement) -> Option<BrfTable> {
        let sza = self.sun_zenith_deg.to_radians();
        let rows = match m {
            Measurement::Brf(p, c) => self
                .plane(p)
                .iter()
                .map(|v| {
                    Some(BrfRow {
                        sza_rad: sza,
                        vza_rad: v.view_zenith_deg.abs().to_radians(),
                        rel_azimuth_rad: p.relative_azimuth_rad(v.view_zenith_deg),
                        brf: v.component(c)?,
                        std_dev: match c {
                            Component::Total => v.brf_se,
                            Component::CoSgl => v.components_se.map(|s| s[0]),
                            Component::UcSgl => v.components_se.map(|s| s[1]),
                            Component::Mlt => v.components_se.map(|s| s[2]),
                        }
                        .unwrap_or(-1.0),
                    })
                })
                .collect::<Option<Vec<_>>>()?,
            Measurement::Brf1 => vec![BrfRow {
                sza_rad: sza,
                vza_rad: -1.0,
                rel_azimuth_rad: -1.0,
                brf: self.brf1,
                std_dev: self.brf1_se.unwrap_or(-1.0),
            }],
            _ => return None,
        };
        Some(BrfTable {
            ratio_filtered_rays: -1.0,
            rows,
        })
    }

    /// Every available `.mes` file as `(file name, content)`.
    pub fn mes_files(&self) -> Vec<(String, String)> {
        self.available()
            .into_iter()
            .filter_map(|m| {
                let text = match m {
                    Measurement::Fabs => write_percent(100.0 * self.fabs),
                    Measurement::Ftran => write_percent(100.0 * self.ftran),
                    _ => write_brf_table(&self.brf_table(m)?),
                };
                Some((file_name(m, &self.model, &self.experiment), text))
            })
            .collect()
    }
}

fn unit(zenith_deg: f64, azimuth_deg: f64) -> [f64; 3] {
    let (st, ct) = zenith_deg.to_radians().sin_cos();
    let (sp, cp) = azimuth_deg.to_radians().sin_cos();
    [st * cp, st * sp, ct]
}

fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    // atan2(|a×b|, a·b): accurate for small angles.
    let c = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let s = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    s.atan2(d).to_degrees()
}

/// Extracts the RAMI measurements of `experiment` from a run's summary.
///
/// `band`: the band to use (by name); `None` picks the only band, or the band whose name
/// equals the experiment's spectral tag (4th tag, case-insensitive: `RED` → `red`).
/// Every RAMI view must be an exact direction of the run (within [`MATCH_TOLERANCE_DEG`]);
/// `brf1` is the run's albedo, which is the DHR because RAMI illumination is direct only — a
/// run with sky light is refused.
pub fn measurements_from_run(
    run: &RunSummary,
    band: Option<&str>,
    experiment: &str,
    model: &str,
) -> Result<RamiMeasurements, String> {
    validate_experiment(experiment)?;
    validate_model_name(model)?;
    let names: Vec<&str> = run.bands.iter().map(|b| b.band.as_str()).collect();
    let b = match band {
        Some(n) => run
            .bands
            .iter()
            .find(|b| b.band == n)
            .ok_or_else(|| format!("no band `{n}` in the run (bands: {})", names.join(", ")))?,
        None if run.bands.len() == 1 => &run.bands[0],
        None => {
            let tag = experiment
                .split('_')
                .nth(3)
                .unwrap_or("")
                .to_ascii_lowercase();
            run.bands
                .iter()
                .find(|b| b.band.to_ascii_lowercase() == tag)
                .ok_or_else(|| {
                    format!(
                        "the run has several bands ({}) and none is named after the experiment's band tag `{tag}`: choose one with --band",
                        names.join(", ")
                    )
                })?
        }
    };
    let (sza, saa) = (run.settings.sun_zenith_deg, run.settings.sun_azimuth_deg);
    if !(sza.is_finite() && saa.is_finite()) {
        return Err("the run's summary has no sun angles".into());
    }
    if b.brf.iter().any(|e| e.hdrf.is_some()) {
        return Err(
            "the run has sky light (HDRF present): RAMI measurements are defined under direct illumination only (set skyl to 0)"
                .into(),
        );
    }
    let finite = |name: &str, x: f64| {
        if x.is_finite() {
            Ok(x)
        } else {
            Err(format!("band `{}`: {name} is not a finite number", b.band))
        }
    };
    let mut planes = Vec::new();
    for p in Plane::ALL {
        let mut views = Vec::with_capacity(VIEWS_PER_PLANE);
        for vz in signed_view_zeniths_deg() {
            let az = p.view_azimuth_deg(vz, saa);
            let target = unit(vz.abs(), az);
            let e = b
                .brf
                .iter()
                .filter(|e| e.kind == "exact")
                .map(|e| (angle_deg(unit(e.zenith_deg, e.azimuth_deg), target), e))
                .filter(|(d, _)| *d <= MATCH_TOLERANCE_DEG)
                .min_by(|x, y| x.0.total_cmp(&y.0))
                .map(|(_, e)| e)
                .ok_or_else(|| {
                    format!(
                        "{}: the run has no exact view direction at zenith {:.0}°, azimuth {az:.3}° (RAMI view {vz:+.0}°); generate the scene with `lumenscape generate rami` (or request the RAMI measurement directions as exact directions)",
                        p.id(),
                        vz.abs()
                    )
                })?;
            let what = format!("{} at {vz:+.0}°", p.id());
            views.push(PlaneView {
                view_zenith_deg: vz,
                view_azimuth_deg: az,
                brf: finite(&what, e.brf)?,
                brf_se: e.brf_se,
                co_sgl: e.brf_co_sgl,
                uc_sgl: e.brf_uc_sgl,
                mlt: e.brf_mlt,
                components_se: e.brf_components_se,
                estimator: e.estimator.clone(),
            });
        }
        planes.push(views);
    }
    let brfop = planes.pop().unwrap_or_default();
    let brfpp = planes.pop().unwrap_or_default();
    Ok(RamiMeasurements {
        experiment: experiment.to_string(),
        model: model.to_string(),
        band: b.band.clone(),
        solver: run.solver.clone(),
        sun_zenith_deg: sza,
        sun_azimuth_deg: saa,
        brfpp,
        brfop,
        brf1: finite("albedo", b.albedo)?,
        brf1_se: b.albedo_se,
        fabs: finite("fabs", b.fabs)?,
        fabs_se: b.fabs_se,
        ftran: finite("ftran", b.ftran)?,
        ftran_se: b.ftran_se,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seventy_six_views_without_nadir_or_duplicates() {
        let v = signed_view_zeniths_deg();
        assert_eq!(v.len(), VIEWS_PER_PLANE);
        assert_eq!((v[0], v[37], v[38], v[75]), (-75.0, -1.0, 1.0, 75.0));
        assert!(v.windows(2).all(|w| w[1] > w[0]));
        assert!(v.iter().all(|z| *z != 0.0 && (z.abs() - 1.0) % 2.0 == 0.0));
    }

    #[test]
    fn view_azimuths_follow_the_published_examples() {
        // Sun side of the principal plane = the sun's azimuth; forward = +180°; orthogonal
        // plane: negative VZA at SAA + 90° (SAA − VAA = −π/2).
        let p = Plane::Principal;
        assert_eq!(p.view_azimuth_deg(-20.0, 30.0), 30.0);
        assert_eq!(p.view_azimuth_deg(20.0, 30.0), 210.0);
        let o = Plane::Orthogonal;
        assert!((o.view_azimuth_deg(-5.0, 30.0) - 120.0).abs() < 1e-12);
        assert!((o.view_azimuth_deg(5.0, 30.0) - 300.0).abs() < 1e-12);
        assert_eq!(o.relative_azimuth_rad(-5.0), -FRAC_PI_2);
        assert!(p.view_azimuth_deg(-1.0, 0.0) < 360.0);
    }

    #[test]
    fn names_round_trip() {
        for m in Measurement::all() {
            let n = file_name(m, "lumen1", "HOM13_DIS_PLA_NIR_20");
            let (m2, model, exp) = parse_file_name(&n).unwrap();
            assert_eq!(
                (m2, model.as_str(), exp.as_str()),
                (m, "lumen1", "HOM13_DIS_PLA_NIR_20")
            );
        }
        assert_eq!(
            file_name(Measurement::Brf1, "raytran", "HET01_DIS_UNI_NIR_50"),
            "brf1_raytran-HET01_DIS_UNI_NIR_50.mes"
        );
        assert!(parse_file_name("brfxx_m-HOM13_DIS_PLA_NIR_20.mes").is_err());
        assert!(parse_file_name("brfpp_toolongname1-HOM13_DIS_PLA_NIR_20.mes").is_err());
        assert!(validate_model_name("a-b").is_err());
        assert!(validate_experiment("HOM13_DIS_PLA_NIR").is_err());
    }

    #[test]
    fn parser_reports_line_numbers() {
        let e = parse_brf_table("2 5 -1\n0.1 0.2 0.0 0.3 -1\n0.1 x 0.0 0.3 -1\n").unwrap_err();
        assert_eq!(e.line, 3, "{e}");
        let e = parse_brf_table("3 5 -1\n0.1 0.2 0.0 0.3 -1\n").unwrap_err();
        assert!(e.message.contains("header announces 3"), "{e}");
        let e = parse_brf_table("1 4 -1\n0.1 0.2 0.0 0.3\n").unwrap_err();
        assert_eq!(e.line, 1);
        let e = parse_brf_table("1 5 -1\n0.1 0.2 0.0 0.3 -1 7\n").unwrap_err();
        assert_eq!(e.line, 2);
        assert!(parse_brf_table("").is_err());
        assert!(parse_percent("12.5\n3\n").is_err());
        assert!(parse_percent("nan\n").is_err());
        assert_eq!(parse_percent("78.654321\n").unwrap(), 78.654321);
        assert_eq!(parse_percent("0.123456\t-1.000000\n").unwrap(), 0.123456);
    }

    #[test]
    fn table_writer_matches_the_published_layout() {
        let t = BrfTable {
            ratio_filtered_rays: -1.0,
            rows: vec![BrfRow {
                sza_rad: 20f64.to_radians(),
                vza_rad: 75f64.to_radians(),
                rel_azimuth_rad: -0.0,
                brf: 0.0318550,
                std_dev: -1.0,
            }],
        };
        assert_eq!(
            write_brf_table(&t),
            "1\t5\t-1.000000\n0.349066\t1.308997\t0.000000\t0.031855\t-1.000000\n"
        );
    }

    /// A synthetic run: every RAMI view as an exact direction, plus a regular one.
    fn synthetic_run(components: bool) -> RunSummary {
        let mut brf = vec![serde_json::json!({"zenith_deg": 40.0, "azimuth_deg": 10.0,
            "kind": "regular", "brf": 0.5})];
        for p in Plane::ALL {
            for vz in signed_view_zeniths_deg() {
                let az = p.view_azimuth_deg(vz, 33.0);
                let v = 0.2 + 0.001 * vz + if p == Plane::Orthogonal { 0.05 } else { 0.0 };
                let mut e = serde_json::json!({"zenith_deg": vz.abs(), "azimuth_deg": az,
                    "kind": "exact", "brf": v, "brf_se": 1e-3, "estimator": "peel-off"});
                if components {
                    e["brf_co_sgl"] = (0.5 * v).into();
                    e["brf_uc_sgl"] = (0.2 * v).into();
                    e["brf_mlt"] = (0.3 * v).into();
                }
                brf.push(e);
            }
        }
        serde_json::from_value(serde_json::json!({
            "solver": "monte-carlo", "schema_version": 1,
            "settings": {"sun_zenith_deg": 20.0, "sun_azimuth_deg": 33.0, "preset": "Default"},
            "bands": [{"band": "nir", "albedo": 0.31, "fabs": 0.42, "ftran": 0.27,
                       "albedo_se": 1e-4, "fabs_se": 2e-4, "ftran_se": 3e-4, "flost": 0.0,
                       "brf": brf}]
        }))
        .unwrap()
    }

    #[test]
    fn measurements_round_trip_through_mes_files() {
        for comps in [true, false] {
            let run = synthetic_run(comps);
            let m = measurements_from_run(&run, None, "HOM13_DIS_PLA_NIR_20", "lumen").unwrap();
            let files = m.mes_files();
            assert_eq!(files.len(), if comps { 11 } else { 5 });
            for (name, text) in &files {
                let (meas, content) = parse_mes(name, text).unwrap();
                match (meas, content) {
                    (Measurement::Fabs, MesContent::Percent(x)) => {
                        assert!((x - 42.0).abs() < 1e-6)
                    }
                    (Measurement::Ftran, MesContent::Percent(x)) => {
                        assert!((x - 27.0).abs() < 1e-6)
                    }
                    (Measurement::Brf1, MesContent::Brf(t)) => {
                        assert_eq!(t.rows.len(), 1);
                        assert!((t.rows[0].brf - 0.31).abs() < 1e-6);
                        assert_eq!((t.rows[0].vza_rad, t.rows[0].rel_azimuth_rad), (-1.0, -1.0));
                    }
                    (Measurement::Brf(p, c), MesContent::Brf(t)) => {
                        assert_eq!(t.rows.len(), VIEWS_PER_PLANE);
                        for (r, v) in t.rows.iter().zip(m.plane(p)) {
                            assert!((r.brf - v.component(c).unwrap()).abs() <= 5e-7);
                            assert!((r.sza_rad - 20f64.to_radians()).abs() <= 5e-7);
                            assert!(
                                (r.vza_rad - v.view_zenith_deg.abs().to_radians()).abs() <= 5e-7
                            );
                            // Re-derive the view azimuth from the file's SAA − VAA.
                            let az = (33.0 - r.rel_azimuth_rad.to_degrees()).rem_euclid(360.0);
                            let d = (az - v.view_azimuth_deg).rem_euclid(360.0);
                            assert!(d.min(360.0 - d) < 1e-4);
                        }
                    }
                    other => panic!("{name}: unexpected {other:?}"),
                }
                // Writing what was read gives the same bytes.
                if let Ok(t) = parse_brf_table(text)
                    && meas.is_brf_table()
                {
                    assert_eq!(&write_brf_table(&t), text);
                }
            }
            // measurements.json round trip (serde_json parses floats to within 1 ulp).
            let back: RamiMeasurements =
                serde_json::from_str(&serde_json::to_string(&m).unwrap()).unwrap();
            assert_eq!((back.brfpp.len(), back.brfop.len()), (76, 76));
            for (a, b) in back
                .brfpp
                .iter()
                .chain(&back.brfop)
                .zip(m.brfpp.iter().chain(&m.brfop))
            {
                assert!((a.brf - b.brf).abs() <= 1e-15 && a.view_zenith_deg == b.view_zenith_deg);
                assert_eq!(a.co_sgl.is_some(), b.co_sgl.is_some());
            }
            assert!((back.fabs - m.fabs).abs() <= 1e-15 && back.experiment == m.experiment);
        }
    }

    #[test]
    fn missing_views_and_sky_light_are_refused() {
        let mut run = synthetic_run(true);
        run.bands[0].brf.retain(|e| e.zenith_deg != 73.0);
        let e = measurements_from_run(&run, None, "HOM13_DIS_PLA_NIR_20", "m").unwrap_err();
        assert!(e.contains("zenith 73"), "{e}");
        let mut run = synthetic_run(true);
        run.bands[0].brf[3].hdrf = Some(0.2);
        assert!(measurements_from_run(&run, None, "HOM13_DIS_PLA_NIR_20", "m").is_err());
        let run = synthetic_run(true);
        assert!(measurements_from_run(&run, Some("red"), "HOM13_DIS_PLA_NIR_20", "m").is_err());
        let mut run = synthetic_run(true);
        run.bands[0].brf[5].brf = f64::NAN;
        assert!(measurements_from_run(&run, None, "HOM13_DIS_PLA_NIR_20", "m").is_err());
    }
}
