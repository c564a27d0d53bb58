//! PROSPECT-5 and PROSPECT-D leaf optical model: hemispherical leaf reflectance and
//! transmittance, 400–2500 nm at 1 nm, from the leaf's biochemistry and structure.
//!
//! Pure formulas, no ECS. Inputs: [`ProspectParams`] (N, Cab, Car, Anth, Cbrown, Cw, Cm) and the
//! published specific absorption coefficients and refractive index ([`ProspectData`], shipped in
//! `assets/optics/prospect_spectra.csv` and compiled in). Output: a [`LeafSpectrum`].
//!
//! The model is the generalised plate model (physics.md §11):
//! * Jacquemoud S., Baret F. (1990), PROSPECT: a model of leaf optical properties spectra,
//!   *Remote Sens. Environ.* 34:75–91 — the N-layer leaf;
//! * Féret J.-B. et al. (2008), PROSPECT-4 and 5: advances in the leaf optical properties model
//!   separating photosynthetic pigments, *Remote Sens. Environ.* 112:3030–3043 — PROSPECT-5;
//! * Féret J.-B., Gitelson A.A., Noble S.D., Jacquemoud S. (2017), PROSPECT-D: towards modeling
//!   leaf optical properties through a complete lifecycle, *Remote Sens. Environ.* 193:204–215;
//! * Allen W.A., Gausman H.W., Richardson A.J., Thomas J.R. (1969), Interaction of isotropic light
//!   with a compact plant leaf, *J. Opt. Soc. Am.* 59:1376 — the compact plate;
//! * Stokes G.G. (1862), On the intensity of the light reflected from or transmitted through a pile
//!   of plates, *Proc. R. Soc. Lond.* 11:545 — the pile of N − 1 plates;
//! * Stern F. (1964), Transmission of isotropic radiation across an interface between two
//!   dielectrics, *Appl. Opt.* 3:111; Allen W.A. (1973), *J. Opt. Soc. Am.* 63:664 — `t_av`.
//!
//! The implementation follows the reference code distributed with the model (as re-implemented by
//! the `prosail` Python package 2.0.5, `prospect_d.py`), with the top surface illuminated within a
//! cone of half-angle α = 40°, and is tested against that package's output to 1e-4.

use std::fmt;
use std::path::Path;
use std::str::FromStr;
use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use crate::io::csv_text::CsvText;
use crate::physics::spectral::{SpectralError, Spectrum};

/// First wavelength of the published PROSPECT tables, nm.
pub const PROSPECT_WAVELENGTH_MIN_NM: f64 = 400.0;
/// Last wavelength of the published PROSPECT tables, nm.
pub const PROSPECT_WAVELENGTH_MAX_NM: f64 = 2500.0;
/// Number of wavelengths of the published PROSPECT tables (400–2500 nm at 1 nm).
pub const PROSPECT_WAVELENGTH_COUNT: usize = 2101;
/// Default half-angle α (degrees) of the illumination cone on the leaf's top surface, as in the
/// PROSPECT reference code and `prosail` (Féret et al. 2008, §2).
pub const PROSPECT_DEFAULT_ALPHA_DEG: f64 = 40.0;

/// The spectral data table compiled into the library (same file as `assets/optics/prospect_spectra.csv`).
const BUILTIN_PROSPECT_CSV: &str = include_str!("../../assets/optics/prospect_spectra.csv");

/// Errors of the PROSPECT model: invalid parameters or an unreadable data table.
#[derive(Debug, thiserror::Error)]
pub enum ProspectError {
    /// A leaf parameter is out of its domain; `field` names it.
    #[error("invalid PROSPECT parameter `{field}` = {value}: {reason}")]
    InvalidParameter {
        /// Name of the offending field (`n`, `cab_ug_cm2`, …).
        field: &'static str,
        /// The value given.
        value: f64,
        /// Why it is rejected.
        reason: &'static str,
    },
    /// The spectral data table could not be read.
    #[error("cannot read PROSPECT data file {path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// Underlying I/O error.
        source: std::io::Error,
    },
    /// The spectral data table is malformed; `line` is 1-based (0 when the whole file is at fault).
    #[error("{source_name}:{line}: {message}")]
    Data {
        /// File path or name of the compiled-in table.
        source_name: String,
        /// 1-based line number (0 = the file as a whole).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Conversion of the result to a [`Spectrum`] failed (cannot happen for valid data).
    #[error(transparent)]
    Spectral(#[from] SpectralError),
}

/// PROSPECT version.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ProspectModel {
    /// PROSPECT-5 (Féret et al. 2008): chlorophylls and carotenoids separated, no anthocyanins.
    #[serde(rename = "5", alias = "P5", alias = "prospect-5")]
    P5,
    /// PROSPECT-D (Féret et al. 2017): adds anthocyanins, recalibrated coefficients.
    #[serde(rename = "D", alias = "PD", alias = "prospect-d")]
    D,
}

impl fmt::Display for ProspectModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ProspectModel::P5 => "5",
            ProspectModel::D => "D",
        })
    }
}

impl FromStr for ProspectModel {
    type Err = String;

    /// Accepts `5`, `P5`, `PROSPECT-5`, `D`, `PD`, `PROSPECT-D` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_uppercase().as_str() {
            "5" | "P5" | "PROSPECT-5" | "PROSPECT5" => Ok(ProspectModel::P5),
            "D" | "PD" | "PROSPECT-D" | "PROSPECTD" => Ok(ProspectModel::D),
            other => Err(format!(
                "unknown PROSPECT model `{other}`: expected `5` (PROSPECT-5) or `D` (PROSPECT-D)"
            )),
        }
    }
}

/// Leaf parameters of PROSPECT (physics.md §11; units in the field names).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProspectParams {
    /// Mesophyll structure parameter N (number of elementary layers, ≥ 1; typically 1–3).
    pub n: f64,
    /// Chlorophyll a+b content Cab, µg cm⁻².
    pub cab_ug_cm2: f64,
    /// Carotenoid content Car, µg cm⁻².
    pub car_ug_cm2: f64,
    /// Anthocyanin content Anth, µg cm⁻² (PROSPECT-D only; PROSPECT-5 has no anthocyanin
    /// absorption, so the value has no effect there).
    #[serde(default)]
    pub anth_ug_cm2: f64,
    /// Brown pigment content Cbrown, arbitrary units (typically 0–1).
    #[serde(default)]
    pub cbrown: f64,
    /// Equivalent water thickness Cw, cm (≡ g cm⁻² of water).
    pub cw_cm: f64,
    /// Dry matter content Cm (leaf mass per area), g cm⁻².
    pub cm_g_cm2: f64,
}

impl ProspectParams {
    /// A green leaf often used to exercise PROSPECT (physics.md §11, the `prosail` example):
    /// N = 2.1, Cab = 60, Car = 10, Anth = 0, Cbrown = 0.1, Cw = 0.013 cm, Cm = 0.016 g cm⁻².
    pub fn typical_green_leaf() -> Self {
        ProspectParams {
            n: 2.1,
            cab_ug_cm2: 60.0,
            car_ug_cm2: 10.0,
            anth_ug_cm2: 0.0,
            cbrown: 0.1,
            cw_cm: 0.013,
            cm_g_cm2: 0.016,
        }
    }

    /// Checks every field: all finite, N ≥ 1, contents ≥ 0. The error names the field.
    pub fn validate(&self) -> Result<(), ProspectError> {
        let fields: [(&'static str, f64); 7] = [
            ("n", self.n),
            ("cab_ug_cm2", self.cab_ug_cm2),
            ("car_ug_cm2", self.car_ug_cm2),
            ("anth_ug_cm2", self.anth_ug_cm2),
            ("cbrown", self.cbrown),
            ("cw_cm", self.cw_cm),
            ("cm_g_cm2", self.cm_g_cm2),
        ];
        for (field, value) in fields {
            if !value.is_finite() {
                return Err(ProspectError::InvalidParameter {
                    field,
                    value,
                    reason: "must be a finite number",
                });
            }
            if value < 0.0 {
                return Err(ProspectError::InvalidParameter {
                    field,
                    value,
                    reason: "must be non-negative",
                });
            }
        }
        if self.n < 1.0 {
            return Err(ProspectError::InvalidParameter {
                field: "n",
                value: self.n,
                reason: "the leaf structure parameter N must be >= 1 (one compact layer at least)",
            });
        }
        Ok(())
    }
}

/// Refractive index and specific absorption coefficients of one PROSPECT version, one value per
/// wavelength of [`ProspectData::wavelength_nm`].
#[derive(Debug, Clone, PartialEq)]
pub struct ProspectCoefficients {
    /// Refractive index of the leaf material n(λ), dimensionless (> 1).
    pub refractive_index: Vec<f64>,
    /// Specific absorption coefficient of chlorophyll a+b, cm² µg⁻¹.
    pub k_cab: Vec<f64>,
    /// Specific absorption coefficient of carotenoids, cm² µg⁻¹.
    pub k_car: Vec<f64>,
    /// Specific absorption coefficient of anthocyanins, cm² µg⁻¹ (all zero for PROSPECT-5).
    pub k_anth: Vec<f64>,
    /// Specific absorption coefficient of brown pigments, per unit Cbrown (arbitrary units).
    pub k_brown: Vec<f64>,
    /// Specific absorption coefficient of water, cm⁻¹.
    pub k_cw: Vec<f64>,
    /// Specific absorption coefficient of dry matter, cm² g⁻¹.
    pub k_cm: Vec<f64>,
}

/// The PROSPECT-5 and PROSPECT-D spectral data on a common wavelength grid.
///
/// Source of the shipped table: PyPI package `prosail` 2.0.5 (files `prospect5_spectra.txt` and
/// `prospect_d_spectra.txt`, the latter being the authors' `dataSpec_PDB.m` of 16 Jan 2017); see
/// `assets/optics/README.md` for provenance and licence.
#[derive(Debug, Clone, PartialEq)]
pub struct ProspectData {
    /// Wavelengths, nm, strictly increasing (400–2500 at 1 nm for the shipped table).
    pub wavelength_nm: Vec<f64>,
    /// PROSPECT-5 coefficients (Féret et al. 2008).
    pub prospect5: ProspectCoefficients,
    /// PROSPECT-D coefficients (Féret et al. 2017).
    pub prospect_d: ProspectCoefficients,
}

/// Column names of the data table, in the order the loader stores them.
const COLUMNS: [&str; 14] = [
    "wavelength_nm",
    "p5_n",
    "p5_k_cab_cm2_per_ug",
    "p5_k_car_cm2_per_ug",
    "p5_k_brown",
    "p5_k_cw_per_cm",
    "p5_k_cm_cm2_per_g",
    "pd_n",
    "pd_k_cab_cm2_per_ug",
    "pd_k_car_cm2_per_ug",
    "pd_k_anth_cm2_per_ug",
    "pd_k_brown",
    "pd_k_cw_per_cm",
    "pd_k_cm_cm2_per_g",
];

impl ProspectData {
    /// The compiled-in table (`assets/optics/prospect_spectra.csv`), parsed once.
    pub fn builtin() -> &'static ProspectData {
        static DATA: OnceLock<ProspectData> = OnceLock::new();
        DATA.get_or_init(|| {
            ProspectData::parse(BUILTIN_PROSPECT_CSV, "builtin prospect_spectra.csv")
                .expect("the compiled-in PROSPECT table is valid (checked by tests)")
        })
    }

    /// Loads a table in the format of `assets/optics/prospect_spectra.csv` from `path`.
    pub fn load(path: impl AsRef<Path>) -> Result<ProspectData, ProspectError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| ProspectError::Io {
            path: path.display().to_string(),
            source,
        })?;
        ProspectData::parse(&text, &path.display().to_string())
    }

    /// Parses a table: `#` comment lines, then a header naming the 14 columns of
    /// `assets/optics/prospect_spectra.csv` (any order), then one row per wavelength.
    /// `source_name` is used in error messages.
    pub fn parse(text: &str, source_name: &str) -> Result<ProspectData, ProspectError> {
        let err = |line: usize, message: String| ProspectError::Data {
            source_name: source_name.to_string(),
            line,
            message,
        };
        let csv =
            CsvText::split(text).ok_or_else(|| err(0, "empty file: no header line".to_string()))?;
        let mut index = [0usize; 14];
        for (k, col) in COLUMNS.iter().enumerate() {
            index[k] = csv.column(col).ok_or_else(|| {
                err(
                    csv.header_line,
                    format!(
                        "header lacks column `{col}` (expected: {})",
                        COLUMNS.join(",")
                    ),
                )
            })?;
        }
        let mut cols: Vec<Vec<f64>> = vec![Vec::new(); 14];
        for (line_no, fields) in csv.rows() {
            if let Some(m) = csv.width_error(&fields) {
                return Err(err(line_no, m));
            }
            for (k, col) in COLUMNS.iter().enumerate() {
                let raw = fields[index[k]];
                let v: f64 = raw.parse().map_err(|_| {
                    err(line_no, format!("column `{col}`: `{raw}` is not a number"))
                })?;
                if !v.is_finite() {
                    return Err(err(line_no, format!("column `{col}`: value is not finite")));
                }
                if k > 0 && v < 0.0 {
                    return Err(err(line_no, format!("column `{col}`: negative value {v}")));
                }
                if (*col == "p5_n" || *col == "pd_n") && v <= 1.0 {
                    return Err(err(
                        line_no,
                        format!("column `{col}`: refractive index {v} must be > 1"),
                    ));
                }
                if k == 0
                    && let Some(&prev) = cols[0].last()
                    && v <= prev
                {
                    return Err(err(
                        line_no,
                        format!("wavelength {v} nm does not increase (previous {prev} nm)"),
                    ));
                }
                cols[k].push(v);
            }
        }
        if cols[0].is_empty() {
            return Err(err(0, "no data rows".to_string()));
        }
        let mut it = cols.into_iter();
        let mut next = || it.next().unwrap_or_default();
        let wavelength_nm = next();
        let (p5_n, p5_cab, p5_car, p5_brown, p5_cw, p5_cm) =
            (next(), next(), next(), next(), next(), next());
        let (pd_n, pd_cab, pd_car, pd_anth, pd_brown, pd_cw, pd_cm) =
            (next(), next(), next(), next(), next(), next(), next());
        let zeros = vec![0.0; wavelength_nm.len()];
        Ok(ProspectData {
            wavelength_nm,
            prospect5: ProspectCoefficients {
                refractive_index: p5_n,
                k_cab: p5_cab,
                k_car: p5_car,
                k_anth: zeros,
                k_brown: p5_brown,
                k_cw: p5_cw,
                k_cm: p5_cm,
            },
            prospect_d: ProspectCoefficients {
                refractive_index: pd_n,
                k_cab: pd_cab,
                k_car: pd_car,
                k_anth: pd_anth,
                k_brown: pd_brown,
                k_cw: pd_cw,
                k_cm: pd_cm,
            },
        })
    }

    /// The coefficients of one PROSPECT version.
    pub fn coefficients(&self, model: ProspectModel) -> &ProspectCoefficients {
        match model {
            ProspectModel::P5 => &self.prospect5,
            ProspectModel::D => &self.prospect_d,
        }
    }
}

/// Leaf directional–hemispherical reflectance and transmittance spectra (dimensionless, per unit
/// incident flux on the leaf's top surface).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LeafSpectrum {
    /// Wavelengths, nm.
    pub wavelength_nm: Vec<f64>,
    /// Leaf reflectance R(λ).
    pub reflectance: Vec<f64>,
    /// Leaf transmittance T(λ).
    pub transmittance: Vec<f64>,
}

impl LeafSpectrum {
    /// Leaf absorptance A(λ) = 1 − R − T.
    pub fn absorptance(&self) -> Vec<f64> {
        self.reflectance
            .iter()
            .zip(&self.transmittance)
            .map(|(r, t)| 1.0 - r - t)
            .collect()
    }

    /// The reflectance as a [`Spectrum`] (for band integration with `physics::spectral`).
    pub fn reflectance_spectrum(&self) -> Result<Spectrum, ProspectError> {
        Ok(Spectrum::new(
            self.wavelength_nm.clone(),
            self.reflectance.clone(),
        )?)
    }

    /// The transmittance as a [`Spectrum`] (for band integration with `physics::spectral`).
    pub fn transmittance_spectrum(&self) -> Result<Spectrum, ProspectError> {
        Ok(Spectrum::new(
            self.wavelength_nm.clone(),
            self.transmittance.clone(),
        )?)
    }
}

/// Exponential integral E1(x) = ∫ₓ^∞ e^{−t}/t dt for x > 0 (Abramowitz & Stegun 5.1.1).
///
/// Series A&S 5.1.11 for x ≤ 1, Lentz's continued fraction (A&S 5.1.22; Press et al.,
/// *Numerical Recipes* §6.3) for x > 1; relative accuracy ~1e-15. Returns +∞ at 0 and NaN for
/// x < 0 or NaN (E1 is real only for x > 0).
pub fn exp_integral_e1(x: f64) -> f64 {
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return f64::INFINITY;
    }
    if x <= 1.0 {
        e1_series(x)
    } else {
        e1_scaled_continued_fraction(x) * (-x).exp()
    }
}

/// Euler–Mascheroni constant γ.
const EULER_GAMMA: f64 = 0.577_215_664_901_532_9;

/// E1 by its power series (A&S 5.1.11): E1(x) = −γ − ln x − Σ_{k≥1} (−x)^k / (k·k!), 0 < x ≤ 1.
fn e1_series(x: f64) -> f64 {
    let mut sum = 0.0;
    let mut term = 1.0; // (−x)^k / k!
    for k in 1..200 {
        term *= -x / k as f64;
        let contribution = term / k as f64;
        sum += contribution;
        if contribution.abs() < 1e-17 * sum.abs().max(1e-300) {
            break;
        }
    }
    -EULER_GAMMA - x.ln() - sum
}

/// e^x E1(x) for x > 1 by the continued fraction E1(x) = e^{−x} / (x + 1 − 1²/(x + 3 − 2²/(x + 5 − …)))
/// (A&S 5.1.22), evaluated with the modified Lentz method.
fn e1_scaled_continued_fraction(x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let mut b = x + 1.0;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..1000 {
        let an = -((i * i) as f64);
        b += 2.0;
        d = 1.0 / (an * d + b);
        c = b + an / c;
        let delta = c * d;
        h *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    h
}

/// Transmissivity τ(K) of an elementary absorbing layer for isotropic incident light
/// (Allen et al. 1969; Jacquemoud & Baret 1990, eq. 2): τ = (1 − K) e^{−K} + K² E1(K),
/// K = total absorption coefficient of the layer (dimensionless, ≥ 0). τ(0) = 1; τ → 0 for large K.
pub fn layer_transmissivity(k: f64) -> f64 {
    if k.is_nan() {
        return f64::NAN;
    }
    if k <= 0.0 {
        return 1.0;
    }
    if k >= 700.0 {
        // τ < e^{−700} · (2/K): below the smallest normal f64 times 1e-4, i.e. zero here.
        return 0.0;
    }
    if k <= 1.0 {
        (1.0 - k) * (-k).exp() + k * k * e1_series(k)
    } else {
        (-k).exp() * ((1.0 - k) + k * k * e1_scaled_continued_fraction(k))
    }
}

/// Average transmissivity of a plane dielectric interface for isotropic light incident within a
/// cone of half-angle `alpha_deg` (degrees, 0 < α ≤ 90) from a medium of index 1 onto a medium of
/// relative refractive index `n` (> 1): Stern (1964), Allen (1973); physics.md §11 step 3.
pub fn tav(alpha_deg: f64, n: f64) -> f64 {
    let n2 = n * n;
    let np = n2 + 1.0;
    let nm = n2 - 1.0;
    let a = (n + 1.0) * (n + 1.0) / 2.0;
    let k = -(n2 - 1.0) * (n2 - 1.0) / 4.0;
    let sa = alpha_deg.to_radians().sin();
    let b2 = sa * sa - np / 2.0;
    let b1 = if alpha_deg == 90.0 {
        0.0
    } else {
        (b2 * b2 + k).sqrt()
    };
    let b = b1 - b2;
    let b3 = b * b * b;
    let a3 = a * a * a;
    let ts = (k * k / (6.0 * b3) + k / b - b / 2.0) - (k * k / (6.0 * a3) + k / a - a / 2.0);
    let tp1 = -2.0 * n2 * (b - a) / (np * np);
    let tp2 = -2.0 * n2 * np * (b / a).ln() / (nm * nm);
    let tp3 = n2 * (1.0 / b - 1.0 / a) / 2.0;
    let tp4 = 16.0
        * n2
        * n2
        * (n2 * n2 + 1.0)
        * ((2.0 * np * b - nm * nm) / (2.0 * np * a - nm * nm)).ln()
        / (np * np * np * nm * nm);
    let tp5 =
        16.0 * n2 * n2 * n2 * (1.0 / (2.0 * np * b - nm * nm) - 1.0 / (2.0 * np * a - nm * nm))
            / (np * np * np);
    let tp = tp1 + tp2 + tp3 + tp4 + tp5;
    (ts + tp) / (2.0 * sa * sa)
}

/// Reflectance and transmittance of a pile of `layers` (= N − 1 ≥ 0, real) identical plates of
/// reflectance `r` and transmittance `t` (Stokes 1862; physics.md §11 step 5), returned as
/// `(R_sub, T_sub)`.
///
/// Written with s⁻¹ = b^{−(N−1)} ≤ 1 instead of s = b^{N−1}, which is algebraically identical but
/// cannot overflow for nearly opaque plates. The non-absorbing limit r + t → 1 uses the exact
/// conservative formula T = t / (t + (1 − t)(N − 1)); an opaque plate (t = 0) gives (r, 0) for
/// a non-empty pile.
pub fn stokes_pile(r: f64, t: f64, layers: f64) -> (f64, f64) {
    if layers <= 0.0 {
        return (0.0, 1.0);
    }
    if t <= 0.0 {
        return (r, 0.0);
    }
    // Conservative plates: the general formula is 0/0 there (Δ → 0, a, b → 1).
    if 1.0 - r - t <= 1e-12 {
        let t_sub = t / (t + (1.0 - t) * layers);
        return (1.0 - t_sub, t_sub);
    }
    let delta = ((1.0 + r + t) * (1.0 + r - t) * (1.0 - r + t) * (1.0 - r - t))
        .max(0.0)
        .sqrt();
    let a = (1.0 + r * r - t * t + delta) / (2.0 * r);
    let b = (1.0 - r * r + t * t + delta) / (2.0 * t);
    let s_inv = (-layers * b.ln()).exp();
    let s_inv2 = s_inv * s_inv;
    let denom = a * a - s_inv2;
    let r_sub = a * (1.0 - s_inv2) / denom;
    let t_sub = s_inv * (a * a - 1.0) / denom;
    (r_sub, t_sub)
}

/// Leaf reflectance and transmittance at one wavelength from the total absorption coefficient of
/// the leaf `k_total` = Σ Cᵢ kᵢ (before division by N), the refractive index `n`, the structure
/// parameter `n_layers` = N and the top-surface cone half-angle `alpha_deg`
/// (Jacquemoud & Baret 1990; physics.md §11 steps 1–6). Returns `(R, T)`.
pub fn leaf_reflectance_transmittance(
    k_total: f64,
    n: f64,
    n_layers: f64,
    alpha_deg: f64,
) -> (f64, f64) {
    let tau = layer_transmissivity(k_total / n_layers);
    // Interfaces (Allen et al. 1969).
    let t_alpha = tav(alpha_deg, n);
    let r_alpha = 1.0 - t_alpha;
    let t12 = tav(90.0, n);
    let r12 = 1.0 - t12;
    let t21 = t12 / (n * n);
    let r21 = 1.0 - t21;
    let denom = 1.0 - r21 * r21 * tau * tau;
    // Top compact layer, illuminated within the cone α.
    let ta = t_alpha * tau * t21 / denom;
    let ra = r_alpha + r21 * tau * ta;
    // Inner compact layer, isotropic illumination.
    let t = t12 * tau * t21 / denom;
    let r = r12 + r21 * tau * t;
    if t <= 0.0 {
        return (ra, 0.0);
    }
    let (r_sub, t_sub) = stokes_pile(r, t, n_layers - 1.0);
    let d = 1.0 - r_sub * r;
    let tran = ta * t_sub / d;
    let refl = ra + ta * r_sub * t / d;
    (refl, tran)
}

/// PROSPECT leaf spectrum with the standard top-surface cone α = 40°
/// ([`PROSPECT_DEFAULT_ALPHA_DEG`]). See [`prospect_with_alpha`].
pub fn prospect(
    model: ProspectModel,
    params: &ProspectParams,
    data: &ProspectData,
) -> Result<LeafSpectrum, ProspectError> {
    prospect_with_alpha(model, params, data, PROSPECT_DEFAULT_ALPHA_DEG)
}

/// PROSPECT-5 or PROSPECT-D leaf reflectance and transmittance on the data's wavelength grid
/// (Jacquemoud & Baret 1990; Féret et al. 2008, 2017; physics.md §11):
/// K(λ) = (Cab k_ab + Car k_car + Anth k_anth + Cbrown k_brown + Cw k_w + Cm k_m)/N, one compact
/// top plate illuminated within a cone of half-angle `alpha_deg` (degrees, 0 < α ≤ 90) plus a
/// Stokes pile of N − 1 plates. For PROSPECT-5, `anth_ug_cm2` has no effect (no anthocyanin term).
///
/// Errors: invalid parameters (the message names the field) or α out of range.
pub fn prospect_with_alpha(
    model: ProspectModel,
    params: &ProspectParams,
    data: &ProspectData,
    alpha_deg: f64,
) -> Result<LeafSpectrum, ProspectError> {
    params.validate()?;
    if !(alpha_deg.is_finite() && alpha_deg > 0.0 && alpha_deg <= 90.0) {
        return Err(ProspectError::InvalidParameter {
            field: "alpha_deg",
            value: alpha_deg,
            reason: "the illumination cone half-angle must be in ]0, 90] degrees",
        });
    }
    let c = data.coefficients(model);
    let anth = match model {
        ProspectModel::P5 => 0.0,
        ProspectModel::D => params.anth_ug_cm2,
    };
    let count = data.wavelength_nm.len();
    let mut reflectance = Vec::with_capacity(count);
    let mut transmittance = Vec::with_capacity(count);
    for i in 0..count {
        let k_total = params.cab_ug_cm2 * c.k_cab[i]
            + params.car_ug_cm2 * c.k_car[i]
            + anth * c.k_anth[i]
            + params.cbrown * c.k_brown[i]
            + params.cw_cm * c.k_cw[i]
            + params.cm_g_cm2 * c.k_cm[i];
        let (r, t) =
            leaf_reflectance_transmittance(k_total, c.refractive_index[i], params.n, alpha_deg);
        reflectance.push(r);
        transmittance.push(t);
    }
    Ok(LeafSpectrum {
        wavelength_nm: data.wavelength_nm.clone(),
        reflectance,
        transmittance,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_table_has_the_published_grid() {
        let d = ProspectData::builtin();
        assert_eq!(d.wavelength_nm.len(), PROSPECT_WAVELENGTH_COUNT);
        assert_eq!(d.wavelength_nm[0], PROSPECT_WAVELENGTH_MIN_NM);
        assert_eq!(*d.wavelength_nm.last().unwrap(), PROSPECT_WAVELENGTH_MAX_NM);
        for w in d.wavelength_nm.windows(2) {
            assert_eq!(w[1] - w[0], 1.0);
        }
        assert!(d.prospect5.k_anth.iter().all(|&k| k == 0.0));
        assert!(d.prospect_d.k_anth.iter().any(|&k| k > 0.0));
    }

    #[test]
    fn e1_matches_tabulated_values() {
        // Abramowitz & Stegun Table 5.1: E1(0.5) = 0.5597735948, E1(1) = 0.2193839344,
        // E1(2) = 0.04890051071, e^5 E1(5) = 0.1704221762 (x e^x E1(x) = 0.8521108814 at x = 5).
        assert!((exp_integral_e1(0.5) - 0.559_773_594_8).abs() < 1e-10);
        assert!((exp_integral_e1(1.0) - 0.219_383_934_4).abs() < 1e-10);
        assert!((exp_integral_e1(2.0) - 0.048_900_510_71).abs() < 1e-11);
        assert!((5.0 * 5f64.exp() * exp_integral_e1(5.0) - 0.852_110_881_4).abs() < 1e-9);
        // Continuity across the series / continued-fraction switch at x = 1.
        let below = e1_series(1.0);
        let above = e1_scaled_continued_fraction(1.0) * (-1f64).exp();
        assert!((below - above).abs() < 1e-14);
    }

    #[test]
    fn layer_transmissivity_limits() {
        assert_eq!(layer_transmissivity(0.0), 1.0);
        // τ(K) = 1 − K(γ + ln K + ...) ... tends to 1 continuously.
        assert!((layer_transmissivity(1e-12) - 1.0).abs() < 1e-9);
        assert_eq!(layer_transmissivity(1e6), 0.0);
        let mut prev = 1.0;
        for i in 1..2000 {
            let k = i as f64 * 0.01;
            let tau = layer_transmissivity(k);
            assert!(tau.is_finite() && tau > 0.0 && tau < prev, "K = {k}");
            prev = tau;
        }
        // Continuity across K = 1.
        let l = (1.0 - 1.0) * (-1f64).exp() + exp_integral_e1(1.0);
        assert!((layer_transmissivity(1.0) - l).abs() < 1e-15);
        assert!((layer_transmissivity(1.0 + 1e-12) - l).abs() < 1e-11);
    }

    #[test]
    fn tav_is_one_for_matched_index_and_decreases_with_contrast() {
        // n → 1: no interface, transmissivity → 1 (b → a). Use n slightly above 1.
        assert!((tav(90.0, 1.0001) - 1.0).abs() < 1e-3);
        assert!(tav(90.0, 1.5) < tav(90.0, 1.3));
        // Hemispherical (α = 90°) transmissivity for n = 1.5: 1 − 0.0918 (Stern 1964;
        // Allen 1973: diffuse reflectance of glass ≈ 0.092).
        assert!((tav(90.0, 1.5) - 0.9082).abs() < 1e-3, "{}", tav(90.0, 1.5));
        for alpha in [1.0, 10.0, 40.0, 59.0, 89.0, 90.0] {
            let t = tav(alpha, 1.45);
            assert!(t.is_finite() && t > 0.0 && t < 1.0, "alpha {alpha}: {t}");
        }
        // Continuity at 90°.
        assert!((tav(89.999_999, 1.45) - tav(90.0, 1.45)).abs() < 1e-6);
    }

    #[test]
    fn stokes_pile_identities() {
        // An empty pile is transparent; one layer is the layer itself.
        assert_eq!(stokes_pile(0.3, 0.5, 0.0), (0.0, 1.0));
        let (r1, t1) = stokes_pile(0.3, 0.5, 1.0);
        assert!((r1 - 0.3).abs() < 1e-12 && (t1 - 0.5).abs() < 1e-12);
        // Two layers by adding: R2 = r + t² r / (1 − r²), T2 = t² / (1 − r²).
        let (r, t) = (0.3, 0.5);
        let (r2, t2) = stokes_pile(r, t, 2.0);
        assert!((r2 - (r + t * t * r / (1.0 - r * r))).abs() < 1e-12);
        assert!((t2 - t * t / (1.0 - r * r)).abs() < 1e-12);
        // Conservative plates conserve energy; the near-conservative branch is continuous with it.
        let (rc, tc) = stokes_pile(0.2, 0.8, 3.0);
        assert!((rc + tc - 1.0).abs() < 1e-15);
        let (rn, tn) = stokes_pile(0.2, 0.8 - 1e-9, 3.0);
        assert!((rn - rc).abs() < 1e-6 && (tn - tc).abs() < 1e-6);
        // Nearly opaque plates: no overflow, no NaN.
        let (ro, to) = stokes_pile(0.1, 1e-200, 50.0);
        assert!(ro.is_finite() && to.is_finite() && to >= 0.0);
    }

    #[test]
    fn non_absorbing_leaf_conserves_energy() {
        let d = ProspectData::builtin();
        for model in [ProspectModel::P5, ProspectModel::D] {
            for n in [1.0, 1.5, 2.7] {
                let p = ProspectParams {
                    n,
                    cab_ug_cm2: 0.0,
                    car_ug_cm2: 0.0,
                    anth_ug_cm2: 0.0,
                    cbrown: 0.0,
                    cw_cm: 0.0,
                    cm_g_cm2: 0.0,
                };
                let s = prospect(model, &p, d).unwrap();
                for (r, t) in s.reflectance.iter().zip(&s.transmittance) {
                    assert!(
                        (r + t - 1.0).abs() < 1e-12,
                        "{model} N={n}: R+T = {}",
                        r + t
                    );
                }
            }
        }
    }

    #[test]
    fn leaf_is_physical_and_opaque_limit_is_finite() {
        let d = ProspectData::builtin();
        let mut p = ProspectParams::typical_green_leaf();
        for model in [ProspectModel::P5, ProspectModel::D] {
            let s = prospect(model, &p, d).unwrap();
            for ((r, t), a) in s
                .reflectance
                .iter()
                .zip(&s.transmittance)
                .zip(s.absorptance())
            {
                assert!(*r > 0.0 && *r < 1.0 && *t >= 0.0 && *t < 1.0 && a > 0.0);
            }
        }
        // Extremely absorbing leaf: R tends to the top-surface specular reflectance, T to 0.
        p.cab_ug_cm2 = 1e9;
        p.cw_cm = 1e6;
        p.cm_g_cm2 = 1e6;
        p.n = 3.0;
        let s = prospect(ProspectModel::D, &p, d).unwrap();
        for (i, (r, t)) in s.reflectance.iter().zip(&s.transmittance).enumerate() {
            let n = d.prospect_d.refractive_index[i];
            assert!(r.is_finite() && t.is_finite(), "NaN at {i}");
            assert!(*t < 1e-12);
            assert!((r - (1.0 - tav(40.0, n))).abs() < 1e-9);
        }
    }

    #[test]
    fn invalid_parameters_name_the_field() {
        let d = ProspectData::builtin();
        let good = ProspectParams::typical_green_leaf();
        let cases: [(&str, ProspectParams); 4] = [
            ("n", ProspectParams { n: 0.5, ..good }),
            (
                "cab_ug_cm2",
                ProspectParams {
                    cab_ug_cm2: -1.0,
                    ..good
                },
            ),
            (
                "cw_cm",
                ProspectParams {
                    cw_cm: f64::NAN,
                    ..good
                },
            ),
            (
                "anth_ug_cm2",
                ProspectParams {
                    anth_ug_cm2: f64::INFINITY,
                    ..good
                },
            ),
        ];
        for (field, p) in cases {
            let e = prospect(ProspectModel::D, &p, d).unwrap_err();
            assert!(e.to_string().contains(field), "{e}");
        }
        let e = prospect_with_alpha(ProspectModel::D, &good, d, 0.0).unwrap_err();
        assert!(e.to_string().contains("alpha_deg"));
    }

    #[test]
    fn malformed_tables_report_line() {
        let header = COLUMNS.join(",");
        let row = "400,1.5,0,0,0,0,0,1.5,0,0,0,0,0,0";
        let ok = format!("# c\n{header}\n{row}\n");
        assert!(ProspectData::parse(&ok, "t.csv").is_ok());
        let bad = format!("# c\n{header}\n{row}\n401,1.5,x,0,0,0,0,1.5,0,0,0,0,0,0\n");
        let e = ProspectData::parse(&bad, "t.csv").unwrap_err().to_string();
        assert!(e.starts_with("t.csv:4:") && e.contains("p5_k_cab"), "{e}");
        let e = ProspectData::parse("wavelength_nm,p5_n\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.csv:1:") && e.contains("lacks column"), "{e}");
        let e = ProspectData::load("/nonexistent/prospect.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/prospect.csv"), "{e}");
        let back = format!("{header}\n{row}\n{row}\n");
        let e = ProspectData::parse(&back, "t.csv").unwrap_err().to_string();
        assert!(
            e.contains("t.csv:3:") && e.contains("does not increase"),
            "{e}"
        );
    }

    #[test]
    fn model_names_parse() {
        assert_eq!("5".parse::<ProspectModel>().unwrap(), ProspectModel::P5);
        assert_eq!("d".parse::<ProspectModel>().unwrap(), ProspectModel::D);
        assert_eq!(
            "PROSPECT-D".parse::<ProspectModel>().unwrap(),
            ProspectModel::D
        );
        assert!("4".parse::<ProspectModel>().is_err());
    }
}
