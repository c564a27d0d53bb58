//! Spectra, sensor spectral response functions (SRFs), band integration and broadband products.
//!
//! Pure formulas, no ECS. Inputs: tabulated spectra ([`Spectrum`], piecewise linear in wavelength)
//! and bands ([`SpectralBand`]: a single wavelength, a Gaussian, a uniform interval or a tabulated
//! SRF). Outputs: band-averaged values, normalised SRFs, broadband averages and band weights.
//!
//! Band value of a spectrum X seen through a response S, optionally weighted by a source spectrum
//! W (e.g. the solar irradiance; Slater 1980, *Remote Sensing: Optics and Optical Systems*, ch. 14;
//! Schott 2007, *Remote Sensing: The Image Chain Approach*, §7.1):
//!
//! `X_band = ∫ S(λ) W(λ) X(λ) dλ / ∫ S(λ) W(λ) dλ`.
//!
//! Integration is exact for the piecewise-linear interpolants: every product is integrated with
//! Simpson's rule on each interval of the union of the factors' wavelength grids, where the
//! product of up to three linear functions is a cubic (Simpson is exact to degree 3). Gaussian
//! responses are sampled at FWHM/40 over ±3 FWHM and interpolated linearly (interpolation error
//! ≤ 4.3e-4 of the peak). Hence a flat spectrum integrates to itself (to rounding) whatever the
//! band, and the values do not depend on how finely the spectrum is sampled beyond its own grid.
//!
//! Shipped data (see `assets/sensors/README.md` and `assets/optics/README.md`):
//! * measured relative SRFs of Sentinel-2A MSI (13 bands), Landsat 8 OLI (9 bands) and Terra MODIS
//!   land bands 1–7, as resampled to 2.5 nm by the Py6S 1.9.2 package ([`SensorId`]);
//! * the ASTM G173-03 solar spectra (extraterrestrial, AM1.5 global tilt, AM1.5 direct+circumsolar)
//!   as shipped by pvlib 0.16.1 ([`solar_spectrum`]).

use std::path::Path;
use std::sync::OnceLock;

use crate::io::csv_text::CsvText;

/// Smallest fraction of a band's response weight that a spectrum must cover for band integration
/// (the missing ≤ 0.1 % is excluded from both numerator and denominator).
pub const MIN_SPECTRAL_COVERAGE: f64 = 0.999;

/// Half-width of the support of a Gaussian response, in units of its FWHM (±3 FWHM = ±7.06 σ; the
/// truncated tails hold 1.7e-12 of the area).
pub const GAUSSIAN_SUPPORT_FWHM: f64 = 3.0;

/// FWHM = 2 √(2 ln 2) σ for a Gaussian.
const FWHM_PER_SIGMA: f64 = 2.354_820_045_030_949_3;

/// Errors of spectra, bands and their files.
#[derive(Debug, thiserror::Error)]
pub enum SpectralError {
    /// A spectrum or band definition is invalid.
    #[error("invalid spectrum or band: {0}")]
    Invalid(String),
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// Underlying I/O error.
        source: std::io::Error,
    },
    /// A file is malformed; `line` is 1-based (0 = the file as a whole).
    #[error("{source_name}{}: {message}", if *line > 0 { format!(":{line}") } else { String::new() })]
    Parse {
        /// File path or name of a compiled-in table.
        source_name: String,
        /// 1-based line number (0 = the file as a whole).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The spectrum does not cover the band's response (or the requested range).
    #[error(
        "spectrum covers {spectrum_lo_nm}-{spectrum_hi_nm} nm, which holds only {coverage_percent:.3}% \
         of the response of {what} (support {band_lo_nm}-{band_hi_nm} nm); at least {required_percent}% is required"
    )]
    OutOfRange {
        /// Description of the band or range.
        what: String,
        /// Lower end of the band support, nm.
        band_lo_nm: f64,
        /// Upper end of the band support, nm.
        band_hi_nm: f64,
        /// Lower end of the spectrum, nm.
        spectrum_lo_nm: f64,
        /// Upper end of the spectrum, nm.
        spectrum_hi_nm: f64,
        /// Covered fraction of the response weight, %.
        coverage_percent: f64,
        /// Required fraction, %.
        required_percent: f64,
    },
}

fn invalid(msg: impl Into<String>) -> SpectralError {
    SpectralError::Invalid(msg.into())
}

/// A tabulated spectrum: values at strictly increasing wavelengths (nm), linearly interpolated in
/// between and undefined outside `[first, last]`. Units of the values are the caller's (a
/// reflectance, W m⁻² nm⁻¹, …).
#[derive(Debug, Clone, PartialEq)]
pub struct Spectrum {
    wavelength_nm: Vec<f64>,
    value: Vec<f64>,
}

impl Spectrum {
    /// A spectrum from samples. Requires equal lengths, at least one sample, finite values and
    /// strictly increasing finite wavelengths.
    pub fn new(wavelength_nm: Vec<f64>, value: Vec<f64>) -> Result<Spectrum, SpectralError> {
        if wavelength_nm.len() != value.len() {
            return Err(invalid(format!(
                "{} wavelengths but {} values",
                wavelength_nm.len(),
                value.len()
            )));
        }
        if wavelength_nm.is_empty() {
            return Err(invalid("a spectrum needs at least one sample"));
        }
        for (i, (&w, &v)) in wavelength_nm.iter().zip(&value).enumerate() {
            if !w.is_finite() || w <= 0.0 {
                return Err(invalid(format!(
                    "wavelength #{i} = {w} nm is not a positive number"
                )));
            }
            if !v.is_finite() {
                return Err(invalid(format!("value #{i} at {w} nm is not finite")));
            }
            if i > 0 && w <= wavelength_nm[i - 1] {
                return Err(invalid(format!(
                    "wavelengths must increase strictly: {} nm then {w} nm",
                    wavelength_nm[i - 1]
                )));
            }
        }
        Ok(Spectrum {
            wavelength_nm,
            value,
        })
    }

    /// A constant spectrum `value` on `[lo_nm, hi_nm]` (two samples).
    pub fn flat(value: f64, lo_nm: f64, hi_nm: f64) -> Result<Spectrum, SpectralError> {
        Spectrum::new(vec![lo_nm, hi_nm], vec![value, value])
    }

    /// Samples a function on `[lo_nm, hi_nm]` with step `step_nm` (the last sample is `hi_nm`).
    pub fn sample(
        lo_nm: f64,
        hi_nm: f64,
        step_nm: f64,
        f: impl Fn(f64) -> f64,
    ) -> Result<Spectrum, SpectralError> {
        if !(lo_nm.is_finite()
            && hi_nm.is_finite()
            && step_nm.is_finite()
            && step_nm > 0.0
            && hi_nm > lo_nm)
        {
            return Err(invalid(format!(
                "cannot sample [{lo_nm}, {hi_nm}] nm with step {step_nm} nm"
            )));
        }
        let n = ((hi_nm - lo_nm) / step_nm).ceil() as usize;
        let mut w: Vec<f64> = (0..n).map(|i| lo_nm + i as f64 * step_nm).collect();
        w.push(hi_nm);
        w.dedup_by(|b, a| *b <= *a);
        let v = w.iter().map(|&x| f(x)).collect();
        Spectrum::new(w, v)
    }

    /// Wavelengths, nm.
    pub fn wavelength_nm(&self) -> &[f64] {
        &self.wavelength_nm
    }

    /// Values at [`Spectrum::wavelength_nm`].
    pub fn values(&self) -> &[f64] {
        &self.value
    }

    /// `(first, last)` wavelength, nm.
    pub fn range_nm(&self) -> (f64, f64) {
        (
            self.wavelength_nm[0],
            self.wavelength_nm[self.wavelength_nm.len() - 1],
        )
    }

    /// Linear interpolation at `wavelength_nm`; `None` outside the tabulated range.
    pub fn value_at(&self, wavelength_nm: f64) -> Option<f64> {
        let (lo, hi) = self.range_nm();
        if !(wavelength_nm >= lo && wavelength_nm <= hi) {
            return None;
        }
        Some(interp_inside(
            &self.wavelength_nm,
            &self.value,
            wavelength_nm,
        ))
    }

    /// ∫ value dλ over `[lo_nm, hi_nm]` ∩ the tabulated range (exact for the linear interpolant),
    /// in value units × nm.
    pub fn integral(&self, lo_nm: f64, hi_nm: f64) -> f64 {
        integrate_product(&[self], lo_nm, hi_nm)
    }

    /// Loads one column of a CSV file: `#` comments, a header naming `wavelength_nm` (or
    /// `wavelength_um`, converted to nm) and `column`, then numeric rows. Errors name file and line.
    pub fn load_csv(path: impl AsRef<Path>, column: &str) -> Result<Spectrum, SpectralError> {
        let path = path.as_ref();
        let text = read_file(path)?;
        Spectrum::parse_csv(&text, column, &path.display().to_string())
    }

    /// Parses one column of CSV text (see [`Spectrum::load_csv`]); `source_name` is used in errors.
    pub fn parse_csv(
        text: &str,
        column: &str,
        source_name: &str,
    ) -> Result<Spectrum, SpectralError> {
        let (w, v) = parse_two_columns(text, column, source_name)?;
        Spectrum::new(w, v).map_err(|e| SpectralError::Parse {
            source_name: source_name.to_string(),
            line: 0,
            message: e.to_string(),
        })
    }
}

/// Linear interpolation of (xs, ys) at x, x inside [xs[0], xs[last]].
fn interp_inside(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    let n = xs.len();
    if n == 1 {
        return ys[0];
    }
    // Index of the first node > x, clamped so that [i-1, i] is a valid interval.
    let i = xs.partition_point(|&w| w <= x).clamp(1, n - 1);
    let (x0, x1) = (xs[i - 1], xs[i]);
    let (y0, y1) = (ys[i - 1], ys[i]);
    let f = (x - x0) / (x1 - x0);
    y0 + f * (y1 - y0)
}

/// ∫ Π factors dλ over [lo, hi] ∩ (intersection of the factors' ranges): Simpson's rule on each
/// interval of the union grid, exact for products of up to three piecewise-linear factors.
fn integrate_product(factors: &[&Spectrum], lo: f64, hi: f64) -> f64 {
    let mut a = lo;
    let mut b = hi;
    for f in factors {
        let (l, h) = f.range_nm();
        a = a.max(l);
        b = b.min(h);
    }
    if b.is_nan() || a.is_nan() || b <= a {
        return 0.0;
    }
    let mut nodes: Vec<f64> = vec![a, b];
    for f in factors {
        nodes.extend(f.wavelength_nm.iter().copied().filter(|&w| w > a && w < b));
    }
    nodes.sort_by(f64::total_cmp);
    nodes.dedup();
    let eval = |x: f64| -> f64 {
        factors
            .iter()
            .map(|f| interp_inside(&f.wavelength_nm, &f.value, x))
            .product()
    };
    let mut sum = 0.0;
    let mut f0 = eval(nodes[0]);
    for w in nodes.windows(2) {
        let (x0, x1) = (w[0], w[1]);
        let fm = eval(0.5 * (x0 + x1));
        let f1 = eval(x1);
        sum += (x1 - x0) / 6.0 * (f0 + 4.0 * fm + f1);
        f0 = f1;
    }
    sum
}

fn read_file(path: &Path) -> Result<String, SpectralError> {
    std::fs::read_to_string(path).map_err(|source| SpectralError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Parses `wavelength_nm|wavelength_um,<column>` CSV (other columns allowed) into two vectors (nm).
fn parse_two_columns(
    text: &str,
    column: &str,
    source_name: &str,
) -> Result<(Vec<f64>, Vec<f64>), SpectralError> {
    let err = |line: usize, message: String| SpectralError::Parse {
        source_name: source_name.to_string(),
        line,
        message,
    };
    let csv =
        CsvText::split(text).ok_or_else(|| err(0, "empty file: no header line".to_string()))?;
    let (header_line, header, names) = (csv.header_line, csv.header, &csv.names);
    let (iw, scale) = if let Some(i) = csv.column("wavelength_nm") {
        (i, 1.0)
    } else if let Some(i) = csv.column("wavelength_um") {
        (i, 1000.0)
    } else {
        return Err(err(
            header_line,
            format!("header `{header}` has no `wavelength_nm` (or `wavelength_um`) column"),
        ));
    };
    let iv = csv.column(column).ok_or_else(|| {
        err(
            header_line,
            format!("header `{header}` has no `{column}` column"),
        )
    })?;
    let mut w = Vec::new();
    let mut v = Vec::new();
    for (line_no, fields) in csv.rows() {
        if let Some(m) = csv.width_error(&fields) {
            return Err(err(line_no, m));
        }
        let parse = |i: usize, name: &str| -> Result<f64, SpectralError> {
            let x: f64 = fields[i]
                .parse()
                .map_err(|_| err(line_no, format!("`{}` is not a number ({name})", fields[i])))?;
            if !x.is_finite() {
                return Err(err(line_no, format!("{name} is not finite")));
            }
            Ok(x)
        };
        let wl = parse(iw, names[iw])? * scale;
        if wl <= 0.0 {
            return Err(err(line_no, format!("wavelength {wl} nm is not positive")));
        }
        if let Some(&prev) = w.last()
            && wl <= prev
        {
            return Err(err(
                line_no,
                format!("wavelength {wl} nm does not increase (previous {prev} nm)"),
            ));
        }
        w.push(wl);
        v.push(parse(iv, column)?);
    }
    if w.is_empty() {
        return Err(err(0, "no data rows".to_string()));
    }
    Ok((w, v))
}

/// A tabulated spectral response function: relative response (dimensionless, ≥ 0, not all zero)
/// at ≥ 2 strictly increasing wavelengths (nm), linear in between and zero outside the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Srf {
    response: Spectrum,
}

impl Srf {
    /// An SRF from samples; errors for fewer than 2 samples, negative/non-finite responses, an
    /// all-zero response or non-increasing wavelengths.
    pub fn new(wavelength_nm: Vec<f64>, response: Vec<f64>) -> Result<Srf, SpectralError> {
        let s = Spectrum::new(wavelength_nm, response)?;
        Srf::from_spectrum(s)
    }

    fn from_spectrum(s: Spectrum) -> Result<Srf, SpectralError> {
        if s.wavelength_nm.len() < 2 {
            return Err(invalid("a tabulated response needs at least 2 samples"));
        }
        if let Some((w, r)) = s
            .wavelength_nm
            .iter()
            .zip(&s.value)
            .find(|(_, r)| **r < 0.0)
        {
            return Err(invalid(format!("negative response {r} at {w} nm")));
        }
        if !s.value.iter().any(|&r| r > 0.0) {
            return Err(invalid("the response is zero everywhere"));
        }
        Ok(Srf { response: s })
    }

    /// Loads a CSV file with a `wavelength_nm,response` header (or `wavelength_um`; `#` comments
    /// allowed). Errors name the file and the line.
    pub fn load_csv(path: impl AsRef<Path>) -> Result<Srf, SpectralError> {
        let path = path.as_ref();
        let text = read_file(path)?;
        Srf::parse_csv(&text, &path.display().to_string())
    }

    /// Parses `wavelength_nm,response` CSV text; `source_name` is used in errors.
    pub fn parse_csv(text: &str, source_name: &str) -> Result<Srf, SpectralError> {
        let (w, v) = parse_two_columns(text, "response", source_name)?;
        Srf::new(w, v).map_err(|e| SpectralError::Parse {
            source_name: source_name.to_string(),
            line: 0,
            message: e.to_string(),
        })
    }

    /// The response as a [`Spectrum`].
    pub fn as_spectrum(&self) -> &Spectrum {
        &self.response
    }

    /// Wavelengths, nm.
    pub fn wavelength_nm(&self) -> &[f64] {
        &self.response.wavelength_nm
    }

    /// Responses at [`Srf::wavelength_nm`].
    pub fn response(&self) -> &[f64] {
        &self.response.value
    }

    /// ∫ S dλ, nm (for a peak-normalised SRF: the equivalent width).
    pub fn integral_nm(&self) -> f64 {
        let (lo, hi) = self.response.range_nm();
        self.response.integral(lo, hi)
    }

    /// This SRF scaled to unit area, ∫ S dλ = 1 nm⁻¹·nm (response in nm⁻¹).
    pub fn normalised_area(&self) -> Srf {
        self.scaled(1.0 / self.integral_nm())
    }

    /// This SRF scaled to a unit maximum.
    pub fn normalised_peak(&self) -> Srf {
        let peak = self.response.value.iter().copied().fold(0.0, f64::max);
        self.scaled(1.0 / peak)
    }

    fn scaled(&self, k: f64) -> Srf {
        Srf {
            response: Spectrum {
                wavelength_nm: self.response.wavelength_nm.clone(),
                value: self.response.value.iter().map(|r| r * k).collect(),
            },
        }
    }
}

/// How a band sees the spectrum.
#[derive(Debug, Clone, PartialEq)]
pub enum SpectralBand {
    /// A single wavelength, nm.
    Monochromatic {
        /// Wavelength, nm.
        wavelength_nm: f64,
    },
    /// Gaussian response exp(−(λ − c)²/(2σ²)), σ = FWHM/(2√(2 ln 2)), truncated at
    /// ±[`GAUSSIAN_SUPPORT_FWHM`]·FWHM. Also the approximation to use for a sensor band known only
    /// by its centre and FWHM (it is not a measured SRF).
    Gaussian {
        /// Centre wavelength, nm.
        center_nm: f64,
        /// Full width at half maximum, nm.
        fwhm_nm: f64,
    },
    /// Uniform response on `[center − width/2, center + width/2]`, as DART's spectral intervals
    /// (mean wavelength and bandwidth).
    Interval {
        /// Centre wavelength, nm.
        center_nm: f64,
        /// Full width, nm.
        width_nm: f64,
    },
    /// A tabulated (e.g. measured) response.
    Tabulated(Srf),
}

impl SpectralBand {
    /// Checks the definition (positive finite wavelengths and widths).
    pub fn validate(&self) -> Result<(), SpectralError> {
        match self {
            SpectralBand::Monochromatic { wavelength_nm } => {
                if !(wavelength_nm.is_finite() && *wavelength_nm > 0.0) {
                    return Err(invalid(format!(
                        "monochromatic band: wavelength_nm = {wavelength_nm} must be positive"
                    )));
                }
            }
            SpectralBand::Gaussian { center_nm, fwhm_nm } => {
                if !(center_nm.is_finite() && fwhm_nm.is_finite() && *fwhm_nm > 0.0) {
                    return Err(invalid(format!(
                        "Gaussian band: center_nm = {center_nm}, fwhm_nm = {fwhm_nm}: both must be finite, fwhm_nm > 0"
                    )));
                }
                if center_nm - GAUSSIAN_SUPPORT_FWHM * fwhm_nm <= 0.0 {
                    return Err(invalid(format!(
                        "Gaussian band: center_nm = {center_nm} is too close to 0 for fwhm_nm = {fwhm_nm}"
                    )));
                }
            }
            SpectralBand::Interval {
                center_nm,
                width_nm,
            } => {
                if !(center_nm.is_finite() && width_nm.is_finite() && *width_nm > 0.0)
                    || center_nm - width_nm / 2.0 <= 0.0
                {
                    return Err(invalid(format!(
                        "interval band: center_nm = {center_nm}, width_nm = {width_nm}: need width_nm > 0 and center_nm > width_nm/2"
                    )));
                }
            }
            SpectralBand::Tabulated(_) => {}
        }
        Ok(())
    }

    /// Short description for messages.
    pub fn describe(&self) -> String {
        match self {
            SpectralBand::Monochromatic { wavelength_nm } => format!("{wavelength_nm} nm"),
            SpectralBand::Gaussian { center_nm, fwhm_nm } => {
                format!("Gaussian band {center_nm} nm (FWHM {fwhm_nm} nm)")
            }
            SpectralBand::Interval {
                center_nm,
                width_nm,
            } => format!("interval band {center_nm} ± {} nm", width_nm / 2.0),
            SpectralBand::Tabulated(s) => {
                let (lo, hi) = s.as_spectrum().range_nm();
                format!("tabulated band {lo}-{hi} nm")
            }
        }
    }

    /// The response as a tabulated SRF (peak 1 for Gaussian and interval bands); `None` for a
    /// monochromatic band. Gaussian responses are sampled with step FWHM/40 over ±3 FWHM
    /// (241 samples; linear-interpolation error ≤ (2.3548/40)²/8 = 4.3e-4 of the peak).
    pub fn to_srf(&self) -> Result<Option<Srf>, SpectralError> {
        self.validate()?;
        Ok(match self {
            SpectralBand::Monochromatic { .. } => None,
            SpectralBand::Gaussian { center_nm, fwhm_nm } => {
                let half = GAUSSIAN_SUPPORT_FWHM * fwhm_nm;
                let step = fwhm_nm / 40.0;
                let sigma = fwhm_nm / FWHM_PER_SIGMA;
                let s = Spectrum::sample(center_nm - half, center_nm + half, step, |x| {
                    (-0.5 * ((x - center_nm) / sigma).powi(2)).exp()
                })?;
                Some(Srf::from_spectrum(s)?)
            }
            SpectralBand::Interval {
                center_nm,
                width_nm,
            } => Some(Srf::new(
                vec![center_nm - width_nm / 2.0, center_nm + width_nm / 2.0],
                vec![1.0, 1.0],
            )?),
            SpectralBand::Tabulated(s) => Some(s.clone()),
        })
    }

    /// Response-weighted mean wavelength ∫ λ S dλ / ∫ S dλ, nm (the wavelength itself for a
    /// monochromatic band).
    pub fn centroid_nm(&self) -> Result<f64, SpectralError> {
        match self.to_srf()? {
            None => match self {
                SpectralBand::Monochromatic { wavelength_nm } => Ok(*wavelength_nm),
                _ => unreachable!("only monochromatic bands have no SRF"),
            },
            Some(srf) => {
                let (lo, hi) = srf.as_spectrum().range_nm();
                let lambda = Spectrum::new(vec![lo, hi], vec![lo, hi])?;
                Ok(integrate_product(&[srf.as_spectrum(), &lambda], lo, hi) / srf.integral_nm())
            }
        }
    }

    /// Band value of `spectrum`: ∫ S X dλ / ∫ S dλ (X interpolated at the wavelength for a
    /// monochromatic band). Errors when the spectrum covers less than [`MIN_SPECTRAL_COVERAGE`]
    /// of the band's response.
    pub fn band_average(&self, spectrum: &Spectrum) -> Result<f64, SpectralError> {
        self.band_average_impl(spectrum, None)
    }

    /// Band value of `spectrum` weighted by a source spectrum `weight` (e.g. the solar spectral
    /// irradiance, [`solar_spectrum`]): ∫ S W X dλ / ∫ S W dλ. This is the band reflectance a
    /// sensor measures for a surface of spectral reflectance X lit by W.
    pub fn band_average_weighted(
        &self,
        spectrum: &Spectrum,
        weight: &Spectrum,
    ) -> Result<f64, SpectralError> {
        self.band_average_impl(spectrum, Some(weight))
    }

    fn band_average_impl(
        &self,
        spectrum: &Spectrum,
        weight: Option<&Spectrum>,
    ) -> Result<f64, SpectralError> {
        let srf = match self.to_srf()? {
            None => {
                let SpectralBand::Monochromatic { wavelength_nm } = self else {
                    unreachable!("only monochromatic bands have no SRF");
                };
                let out = |s: &Spectrum| {
                    let (lo, hi) = s.range_nm();
                    SpectralError::OutOfRange {
                        what: self.describe(),
                        band_lo_nm: *wavelength_nm,
                        band_hi_nm: *wavelength_nm,
                        spectrum_lo_nm: lo,
                        spectrum_hi_nm: hi,
                        coverage_percent: 0.0,
                        required_percent: 100.0,
                    }
                };
                let x = spectrum
                    .value_at(*wavelength_nm)
                    .ok_or_else(|| out(spectrum))?;
                if let Some(w) = weight {
                    w.value_at(*wavelength_nm).ok_or_else(|| out(w))?;
                }
                return Ok(x);
            }
            Some(srf) => srf,
        };
        let s = srf.as_spectrum();
        let (lo, hi) = s.range_nm();
        let total = srf.integral_nm();
        // Coverage of the response weight by the spectrum (and the weighting spectrum).
        for cover in std::iter::once(spectrum).chain(weight) {
            let (clo, chi) = cover.range_nm();
            let covered = s.integral(clo, chi);
            if covered < MIN_SPECTRAL_COVERAGE * total {
                return Err(SpectralError::OutOfRange {
                    what: self.describe(),
                    band_lo_nm: lo,
                    band_hi_nm: hi,
                    spectrum_lo_nm: clo,
                    spectrum_hi_nm: chi,
                    coverage_percent: 100.0 * covered / total,
                    required_percent: 100.0 * MIN_SPECTRAL_COVERAGE,
                });
            }
        }
        let (num, den) = match weight {
            None => (
                integrate_product(&[s, spectrum], lo, hi),
                // Denominator over the same (covered) interval as the numerator.
                integrate_product(&[s, &flat_like(spectrum)], lo, hi),
            ),
            Some(w) => (
                integrate_product(&[s, w, spectrum], lo, hi),
                integrate_product(&[s, w, &flat_like(spectrum)], lo, hi),
            ),
        };
        if den.is_nan() || den <= 0.0 {
            return Err(invalid(format!(
                "{}: the (weighted) response integrates to {den} over the spectrum's range",
                self.describe()
            )));
        }
        Ok(num / den)
    }
}

/// A spectrum equal to 1 on the range of `s` (restricts an integral to that range).
fn flat_like(s: &Spectrum) -> Spectrum {
    let (lo, hi) = s.range_nm();
    Spectrum {
        wavelength_nm: vec![lo, hi.max(lo)],
        value: vec![1.0, 1.0],
    }
}

/// One band of a sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorBand {
    /// Band name as used by the sensor's products (`B04`, `B8A`, …).
    pub name: String,
    /// Relative spectral response (peak ≈ 1 as published).
    pub srf: Srf,
}

impl SensorBand {
    /// The band as a [`SpectralBand::Tabulated`].
    pub fn to_band(&self) -> SpectralBand {
        SpectralBand::Tabulated(self.srf.clone())
    }
}

/// A sensor: a name and its bands' SRFs.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    /// Sensor name.
    pub name: String,
    /// Bands in file order.
    pub bands: Vec<SensorBand>,
}

/// Sensors whose SRFs are shipped in `assets/sensors/` and compiled in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SensorId {
    /// Sentinel-2A MSI, bands B01–B12 and B8A (measured SRFs, ESA; via Py6S 1.9.2, 2.5 nm).
    Sentinel2aMsi,
    /// Landsat 8 OLI, bands B1–B9 (measured SRFs, NASA/USGS; via Py6S 1.9.2, 2.5 nm).
    Landsat8Oli,
    /// Terra MODIS land bands B1–B7 (measured RSRs, NASA; via Py6S 1.9.2, 2.5 nm).
    ModisTerra,
}

impl SensorId {
    /// All shipped sensors.
    pub const ALL: [SensorId; 3] = [
        SensorId::Sentinel2aMsi,
        SensorId::Landsat8Oli,
        SensorId::ModisTerra,
    ];

    /// Display name.
    pub fn name(self) -> &'static str {
        match self {
            SensorId::Sentinel2aMsi => "Sentinel-2A MSI",
            SensorId::Landsat8Oli => "Landsat 8 OLI",
            SensorId::ModisTerra => "Terra MODIS",
        }
    }

    /// File name in `assets/sensors/`.
    pub fn file_name(self) -> &'static str {
        match self {
            SensorId::Sentinel2aMsi => "sentinel2a_msi.csv",
            SensorId::Landsat8Oli => "landsat8_oli.csv",
            SensorId::ModisTerra => "modis_terra.csv",
        }
    }

    fn builtin_text(self) -> &'static str {
        match self {
            SensorId::Sentinel2aMsi => include_str!("../../assets/sensors/sentinel2a_msi.csv"),
            SensorId::Landsat8Oli => include_str!("../../assets/sensors/landsat8_oli.csv"),
            SensorId::ModisTerra => include_str!("../../assets/sensors/modis_terra.csv"),
        }
    }
}

impl Sensor {
    /// A compiled-in sensor (parsed on each call; a few hundred rows).
    pub fn builtin(id: SensorId) -> Sensor {
        Sensor::parse_csv(id.builtin_text(), id.name(), id.file_name())
            .expect("compiled-in sensor tables are valid (checked by tests)")
    }

    /// Loads a sensor file in the long format of `assets/sensors/*.csv`:
    /// `#` comments, header `band,wavelength_nm,response`, rows grouped by band.
    pub fn load_csv(path: impl AsRef<Path>, name: &str) -> Result<Sensor, SpectralError> {
        let path = path.as_ref();
        let text = read_file(path)?;
        Sensor::parse_csv(&text, name, &path.display().to_string())
    }

    /// Parses the long format (see [`Sensor::load_csv`]); `source_name` is used in errors.
    pub fn parse_csv(text: &str, name: &str, source_name: &str) -> Result<Sensor, SpectralError> {
        let err = |line: usize, message: String| SpectralError::Parse {
            source_name: source_name.to_string(),
            line,
            message,
        };
        let csv =
            CsvText::split(text).ok_or_else(|| err(0, "empty file: no header line".to_string()))?;
        if csv.names != ["band", "wavelength_nm", "response"] {
            return Err(err(
                csv.header_line,
                format!(
                    "header must be `band,wavelength_nm,response`, found `{}`",
                    csv.header
                ),
            ));
        }
        let mut groups: Vec<(String, usize, Vec<f64>, Vec<f64>)> = Vec::new();
        for (line_no, f) in csv.rows() {
            if let Some(m) = csv.width_error(&f) {
                return Err(err(line_no, m));
            }
            let num = |s: &str, what: &str| -> Result<f64, SpectralError> {
                s.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| err(line_no, format!("{what} `{s}` is not a finite number")))
            };
            let (w, r) = (num(f[1], "wavelength_nm")?, num(f[2], "response")?);
            match groups.last_mut() {
                Some(g) if g.0 == f[0] => {
                    g.2.push(w);
                    g.3.push(r);
                }
                _ => {
                    if groups.iter().any(|g| g.0 == f[0]) {
                        return Err(err(
                            line_no,
                            format!("rows of band `{}` are not contiguous", f[0]),
                        ));
                    }
                    groups.push((f[0].to_string(), line_no, vec![w], vec![r]));
                }
            }
        }
        if groups.is_empty() {
            return Err(err(0, "no data rows".to_string()));
        }
        let bands = groups
            .into_iter()
            .map(|(band, first_line, w, r)| {
                Srf::new(w, r)
                    .map(|srf| SensorBand {
                        name: band.clone(),
                        srf,
                    })
                    .map_err(|e| err(first_line, format!("band `{band}`: {e}")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Sensor {
            name: name.to_string(),
            bands,
        })
    }

    /// The band called `name`; leading zeros of the band number and letter case are ignored
    /// (`B4`, `b04` and `B04` are the same band).
    pub fn band(&self, name: &str) -> Option<&SensorBand> {
        let key = canonical_band_name(name);
        self.bands
            .iter()
            .find(|b| canonical_band_name(&b.name) == key)
    }
}

fn canonical_band_name(name: &str) -> String {
    let upper = name.trim().to_ascii_uppercase();
    let rest = upper.strip_prefix('B').unwrap_or(&upper);
    let trimmed = rest.trim_start_matches('0');
    format!("B{}", if trimmed.is_empty() { "0" } else { trimmed })
}

/// Which of the ASTM G173-03 reference spectra.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SolarSpectrumKind {
    /// Extraterrestrial spectral irradiance at 1 AU, normal to the beam (top of atmosphere).
    Extraterrestrial,
    /// AM1.5 global irradiance on a 37°-tilted, sun-facing plane (US standard atmosphere).
    GlobalTilt,
    /// AM1.5 direct normal + circumsolar irradiance.
    DirectCircumsolar,
}

/// ASTM G173-03 reference solar spectral irradiance, W m⁻² nm⁻¹, 280–4000 nm (ASTM G173-03,
/// *Standard Tables for Reference Solar Spectral Irradiances*, derived from SMARTS 2.9.2; the
/// extraterrestrial spectrum integrates to 1348 W m⁻² over 280–4000 nm, 1366.1 W m⁻² in total).
/// Compiled in from `assets/optics/solar_astm_g173.csv` (pvlib 0.16.1's copy, BSD-3-Clause).
pub fn solar_spectrum(kind: SolarSpectrumKind) -> &'static Spectrum {
    static SPECTRA: OnceLock<[Spectrum; 3]> = OnceLock::new();
    let all = SPECTRA.get_or_init(|| {
        const TEXT: &str = include_str!("../../assets/optics/solar_astm_g173.csv");
        let name = "builtin solar_astm_g173.csv";
        let col = |c: &str| {
            Spectrum::parse_csv(TEXT, c, name).expect("the compiled-in solar table is valid")
        };
        [
            col("extraterrestrial_w_m2_nm"),
            col("global_tilt_w_m2_nm"),
            col("direct_circumsolar_w_m2_nm"),
        ]
    });
    match kind {
        SolarSpectrumKind::Extraterrestrial => &all[0],
        SolarSpectrumKind::GlobalTilt => &all[1],
        SolarSpectrumKind::DirectCircumsolar => &all[2],
    }
}

/// A broadband wavelength range, nm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BroadbandRange {
    /// Lower limit, nm.
    pub lo_nm: f64,
    /// Upper limit, nm.
    pub hi_nm: f64,
}

impl BroadbandRange {
    /// Photosynthetically active radiation, 400–700 nm (McCree 1972).
    pub const PAR: BroadbandRange = BroadbandRange {
        lo_nm: 400.0,
        hi_nm: 700.0,
    };
    /// The optical domain of PROSPECT and of this simulator's leaf optics, 400–2500 nm
    /// (shortwave albedo of a vegetated scene as simulated here).
    pub const SHORTWAVE_400_2500: BroadbandRange = BroadbandRange {
        lo_nm: 400.0,
        hi_nm: 2500.0,
    };
    /// Shortwave as in the MODIS albedo product, 300–5000 nm. The ASTM table stops at 4000 nm, so
    /// integrals with it cover 300–4000 nm; 4000–5000 nm holds 0.47 % of the 300–5000 nm energy of
    /// a 5778 K blackbody.
    pub const SHORTWAVE_300_5000: BroadbandRange = BroadbandRange {
        lo_nm: 300.0,
        hi_nm: 5000.0,
    };

    fn validate(&self) -> Result<(), SpectralError> {
        if !(self.lo_nm.is_finite()
            && self.hi_nm.is_finite()
            && self.lo_nm > 0.0
            && self.hi_nm > self.lo_nm)
        {
            return Err(invalid(format!(
                "broadband range [{}, {}] nm must satisfy 0 < lo < hi",
                self.lo_nm, self.hi_nm
            )));
        }
        Ok(())
    }
}

/// Broadband average of `spectrum` weighted by `weight` over `range`:
/// ∫ W X dλ / ∫ W dλ, both over `range` ∩ the two spectra's ranges (e.g. the PAR or shortwave
/// albedo of a surface of spectral albedo X under the solar spectrum W). Errors if the spectrum
/// covers less than [`MIN_SPECTRAL_COVERAGE`] of the weight within `range`.
pub fn broadband_average(
    spectrum: &Spectrum,
    weight: &Spectrum,
    range: BroadbandRange,
) -> Result<f64, SpectralError> {
    range.validate()?;
    let band = SpectralBand::Interval {
        center_nm: 0.5 * (range.lo_nm + range.hi_nm),
        width_nm: range.hi_nm - range.lo_nm,
    };
    let total = weight.integral(range.lo_nm, range.hi_nm);
    let (slo, shi) = spectrum.range_nm();
    let covered = weight.integral(range.lo_nm.max(slo), range.hi_nm.min(shi));
    if total.is_nan() || total <= 0.0 || covered < MIN_SPECTRAL_COVERAGE * total {
        let (wlo, whi) = weight.range_nm();
        return Err(SpectralError::OutOfRange {
            what: format!(
                "broadband range {}-{} nm weighted by a spectrum on {wlo}-{whi} nm",
                range.lo_nm, range.hi_nm
            ),
            band_lo_nm: range.lo_nm,
            band_hi_nm: range.hi_nm,
            spectrum_lo_nm: slo,
            spectrum_hi_nm: shi,
            coverage_percent: if total > 0.0 {
                100.0 * covered / total
            } else {
                0.0
            },
            required_percent: 100.0 * MIN_SPECTRAL_COVERAGE,
        });
    }
    let s = band.to_srf()?.expect("an interval band has an SRF");
    let lo = range.lo_nm.max(slo);
    let hi = range.hi_nm.min(shi);
    let num = integrate_product(&[s.as_spectrum(), weight, spectrum], lo, hi);
    let den = integrate_product(&[s.as_spectrum(), weight], lo, hi);
    Ok(num / den)
}

/// Weights to combine band values into a broadband value (narrow-to-broadband conversion).
#[derive(Debug, Clone, PartialEq)]
pub struct BroadbandWeights {
    /// One weight per band, summing to 1.
    pub weights: Vec<f64>,
    /// Σᵢ ∫_range W Sᵢ dλ / ∫_range W dλ with peak-normalised Sᵢ: 1 when the bands tile the range
    /// exactly (contiguous [`SpectralBand::Interval`]s), < 1 with gaps, > 1 with overlaps.
    pub coverage: f64,
}

/// Solar-energy weights of `bands` for a broadband product over `range`:
/// wᵢ ∝ ∫_range W(λ) Sᵢ(λ) dλ with each response peak-normalised, normalised to Σ wᵢ = 1
/// (Liang 2001, *Remote Sens. Environ.* 76:213, for the principle). With contiguous
/// [`SpectralBand::Interval`] bands tiling `range` (DART's spectral intervals), Σ wᵢ Xᵢ is exactly
/// the W-weighted broadband mean of any X that is constant within each band, and a good
/// approximation otherwise. Monochromatic bands have no width and are rejected.
pub fn broadband_weights(
    bands: &[SpectralBand],
    weight: &Spectrum,
    range: BroadbandRange,
) -> Result<BroadbandWeights, SpectralError> {
    range.validate()?;
    if bands.is_empty() {
        return Err(invalid("broadband weights need at least one band"));
    }
    let total = weight.integral(range.lo_nm, range.hi_nm);
    if total.is_nan() || total <= 0.0 {
        return Err(invalid(format!(
            "the weighting spectrum has no energy in {}-{} nm",
            range.lo_nm, range.hi_nm
        )));
    }
    let mut raw = Vec::with_capacity(bands.len());
    for band in bands {
        let srf = band.to_srf()?.ok_or_else(|| {
            invalid(format!(
                "{} has no width: broadband weights need bands with a response (use an interval band)",
                band.describe()
            ))
        })?;
        let srf = srf.normalised_peak();
        raw.push(integrate_product(
            &[srf.as_spectrum(), weight],
            range.lo_nm,
            range.hi_nm,
        ));
    }
    let sum: f64 = raw.iter().sum();
    if sum.is_nan() || sum <= 0.0 {
        return Err(invalid(format!(
            "no band overlaps {}-{} nm where the weighting spectrum is non-zero",
            range.lo_nm, range.hi_nm
        )));
    }
    Ok(BroadbandWeights {
        weights: raw.iter().map(|r| r / sum).collect(),
        coverage: sum / total,
    })
}

/// Photon flux density, µmol m⁻² s⁻¹, of a spectral irradiance in W m⁻² nm⁻¹ over `range`:
/// ∫ E(λ) λ/(h c N_A) dλ (CODATA 2018 exact h, c, N_A). With [`BroadbandRange::PAR`] this is the
/// photosynthetic photon flux density (PPFD).
pub fn photon_flux_umol_m2_s(
    irradiance_w_m2_nm: &Spectrum,
    range: BroadbandRange,
) -> Result<f64, SpectralError> {
    range.validate()?;
    const H: f64 = 6.626_070_15e-34; // J s
    const C: f64 = 299_792_458.0; // m s⁻¹
    const N_A: f64 = 6.022_140_76e23; // mol⁻¹
    let (lo, hi) = (range.lo_nm, range.hi_nm);
    let lambda = Spectrum::new(vec![lo, hi], vec![lo, hi])?;
    // ∫ E λ dλ in W m⁻² nm; photons per joule at λ nm: λ·1e-9/(h c).
    let e_lambda = integrate_product(&[irradiance_w_m2_nm, &lambda], lo, hi);
    Ok(e_lambda * 1e-9 / (H * C) / N_A * 1e6)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gaussian(center_nm: f64, fwhm_nm: f64) -> SpectralBand {
        SpectralBand::Gaussian { center_nm, fwhm_nm }
    }

    #[test]
    fn interpolation_and_integral_are_exact_for_linear_data() {
        let s = Spectrum::new(vec![400.0, 500.0, 700.0], vec![0.0, 1.0, 3.0]).unwrap();
        assert_eq!(s.value_at(450.0), Some(0.5));
        assert_eq!(s.value_at(700.0), Some(3.0));
        assert_eq!(s.value_at(399.0), None);
        // ∫ = 50 + 400 = 450.
        assert!((s.integral(0.0, 1e4) - 450.0).abs() < 1e-12);
        assert!((s.integral(450.0, 500.0) - 0.5 * (0.5 + 1.0) * 50.0).abs() < 1e-12);
    }

    #[test]
    fn flat_spectrum_integrates_to_itself_in_every_band() {
        let flat = Spectrum::flat(0.37, 300.0, 2600.0).unwrap();
        let sun = solar_spectrum(SolarSpectrumKind::Extraterrestrial);
        let mut bands = vec![
            SpectralBand::Monochromatic {
                wavelength_nm: 555.5,
            },
            gaussian(650.0, 30.0),
            gaussian(1000.0, 0.3),
            SpectralBand::Interval {
                center_nm: 865.0,
                width_nm: 20.0,
            },
        ];
        for id in SensorId::ALL {
            bands.extend(Sensor::builtin(id).bands.iter().map(SensorBand::to_band));
        }
        for b in &bands {
            let v = b.band_average(&flat).unwrap();
            assert!((v - 0.37).abs() < 1e-14, "{}: {v}", b.describe());
            let v = b.band_average_weighted(&flat, sun).unwrap();
            assert!((v - 0.37).abs() < 1e-14, "{}: {v}", b.describe());
        }
    }

    #[test]
    fn linear_spectrum_band_average_is_its_value_at_the_centroid() {
        // For X(λ) = a + bλ, ∫ S X / ∫ S = a + b·centroid, for any S.
        let x = Spectrum::new(vec![300.0, 2600.0], vec![0.1, 0.1 + 2300.0 * 2e-4]).unwrap();
        let s2 = Sensor::builtin(SensorId::Sentinel2aMsi);
        for b in s2
            .bands
            .iter()
            .map(SensorBand::to_band)
            .chain([gaussian(700.0, 40.0)])
        {
            let c = b.centroid_nm().unwrap();
            let expect = 0.1 + (c - 300.0) * 2e-4;
            assert!((b.band_average(&x).unwrap() - expect).abs() < 1e-14);
        }
    }

    #[test]
    fn gaussian_band_moments() {
        let b = gaussian(865.0, 21.0);
        assert!((b.centroid_nm().unwrap() - 865.0).abs() < 1e-9);
        let srf = b.to_srf().unwrap().unwrap();
        // Equivalent width of a unit-peak Gaussian: σ √(2π) = FWHM √(π / (4 ln 2)) = 1.0644670 FWHM.
        let expect = 21.0 * (std::f64::consts::PI / (4.0 * 2f64.ln())).sqrt();
        assert!(
            (srf.integral_nm() / expect - 1.0).abs() < 1e-9,
            "{} vs {expect}",
            srf.integral_nm()
        );
        // The response is peak-normalised with value 1/2 at ±FWHM/2 (sample nodes for this band).
        for x in [865.0 - 10.5, 865.0, 865.0 + 10.5] {
            let expect = if x == 865.0 { 1.0 } else { 0.5 };
            assert!((srf.as_spectrum().value_at(x).unwrap() - expect).abs() < 1e-12);
        }
    }

    #[test]
    fn srf_normalisation() {
        for id in SensorId::ALL {
            for band in Sensor::builtin(id).bands {
                let a = band.srf.normalised_area();
                assert!((a.integral_nm() - 1.0).abs() < 1e-12, "{}", band.name);
                let p = band.srf.normalised_peak();
                let peak = p.response().iter().copied().fold(0.0, f64::max);
                assert!((peak - 1.0).abs() < 1e-15);
                // Normalisation does not change band values.
                let x = Spectrum::new(vec![300.0, 2600.0], vec![1.0, 2.0]).unwrap();
                let v0 = band.to_band().band_average(&x).unwrap();
                let v1 = SpectralBand::Tabulated(a).band_average(&x).unwrap();
                assert!((v0 - v1).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn shipped_sensor_bands_are_where_published() {
        // Central wavelengths published by ESA (S2A MSI) and USGS (OLI) are the SRF centroids:
        // they must agree to 0.5 nm. For MODIS, the centroid must lie within the nominal band
        // limits of the MODIS specification.
        let centres: [(SensorId, &str, f64); 5] = [
            (SensorId::Sentinel2aMsi, "B04", 664.6),
            (SensorId::Sentinel2aMsi, "B8A", 864.7),
            (SensorId::Sentinel2aMsi, "B12", 2202.4),
            (SensorId::Landsat8Oli, "B4", 654.6),
            (SensorId::Landsat8Oli, "B5", 864.6),
        ];
        for (id, name, centre) in centres {
            let sensor = Sensor::builtin(id);
            let c = sensor.band(name).unwrap().to_band().centroid_nm().unwrap();
            assert!(
                (c - centre).abs() < 0.5,
                "{} {name}: centroid {c}",
                id.name()
            );
        }
        let modis = Sensor::builtin(SensorId::ModisTerra);
        let limits = [
            ("B1", 620.0, 670.0),
            ("B2", 841.0, 876.0),
            ("B3", 459.0, 479.0),
            ("B4", 545.0, 565.0),
            ("B5", 1230.0, 1250.0),
            ("B6", 1628.0, 1652.0),
            ("B7", 2105.0, 2155.0),
        ];
        for (name, lo, hi) in limits {
            let c = modis.band(name).unwrap().to_band().centroid_nm().unwrap();
            assert!(c > lo && c < hi, "MODIS {name}: centroid {c}");
        }
        assert_eq!(Sensor::builtin(SensorId::Sentinel2aMsi).bands.len(), 13);
        assert_eq!(Sensor::builtin(SensorId::Landsat8Oli).bands.len(), 9);
        assert_eq!(Sensor::builtin(SensorId::ModisTerra).bands.len(), 7);
        let s2 = Sensor::builtin(SensorId::Sentinel2aMsi);
        assert_eq!(s2.band("b4").unwrap().name, "B04");
        assert!(s2.band("B13").is_none());
    }

    #[test]
    fn solar_spectrum_totals() {
        let etr = solar_spectrum(SolarSpectrumKind::Extraterrestrial);
        // ASTM G173-03 ETR: 1366.1 W m⁻² in total, of which 280–4000 nm holds ≈ 1348 W m⁻²
        // (trapezoid sum of the table: 1347.93).
        let total = etr.integral(0.0, 1e5);
        assert!((total - 1347.93).abs() < 0.05, "{total}");
        let par = etr.integral(400.0, 700.0);
        assert!((par - 529.96).abs() < 0.05, "{par}");
        let g = solar_spectrum(SolarSpectrumKind::GlobalTilt).integral(0.0, 1e5);
        assert!((g - 1000.4).abs() < 1.0, "{g}"); // AM1.5G is a 1000 W m⁻² standard
    }

    #[test]
    fn broadband_weights_tile_exactly() {
        let sun = solar_spectrum(SolarSpectrumKind::Extraterrestrial);
        let edges = [400.0, 450.0, 520.0, 600.0, 700.0];
        let bands: Vec<SpectralBand> = edges
            .windows(2)
            .map(|e| SpectralBand::Interval {
                center_nm: 0.5 * (e[0] + e[1]),
                width_nm: e[1] - e[0],
            })
            .collect();
        let w = broadband_weights(&bands, sun, BroadbandRange::PAR).unwrap();
        assert!((w.weights.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        assert!((w.coverage - 1.0).abs() < 1e-12, "{}", w.coverage);
        // Each weight is the band's share of solar energy.
        let total = sun.integral(400.0, 700.0);
        for (wi, e) in w.weights.iter().zip(edges.windows(2)) {
            assert!((wi - sun.integral(e[0], e[1]) / total).abs() < 1e-12);
        }
        // A spectrum flat within each band: Σ wᵢ Xᵢ equals the weighted broadband average, and a
        // flat spectrum gives itself.
        let flat = Spectrum::flat(0.2, 350.0, 800.0).unwrap();
        let bb = broadband_average(&flat, sun, BroadbandRange::PAR).unwrap();
        assert!((bb - 0.2).abs() < 1e-14);
        let combined: f64 = w
            .weights
            .iter()
            .zip(&bands)
            .map(|(wi, b)| wi * b.band_average_weighted(&flat, sun).unwrap())
            .sum();
        assert!((combined - 0.2).abs() < 1e-14);
        // A step spectrum (value k in band k) reproduces the broadband mean (up to the 1e-6 nm ramps).
        let mut wl = Vec::new();
        let mut v = Vec::new();
        for (k, e) in edges.windows(2).enumerate() {
            wl.extend([e[0] + 1e-6, e[1] - 1e-6]);
            v.extend([k as f64, k as f64]);
        }
        let step = Spectrum::new(wl, v).unwrap();
        let direct = broadband_average(
            &step,
            sun,
            BroadbandRange {
                lo_nm: 400.0 + 1e-6,
                hi_nm: 700.0 - 1e-6,
            },
        )
        .unwrap();
        let by_weights: f64 = w
            .weights
            .iter()
            .enumerate()
            .map(|(k, wi)| wi * k as f64)
            .sum();
        assert!(
            (direct - by_weights).abs() < 1e-6,
            "{direct} vs {by_weights}"
        );
    }

    #[test]
    fn photon_flux_of_a_flat_spectrum_is_analytic() {
        // E = 1 W m⁻² nm⁻¹ on 400–700 nm: ∫ λ dλ = (700² − 400²)/2 nm².
        let e = Spectrum::flat(1.0, 400.0, 700.0).unwrap();
        let got = photon_flux_umol_m2_s(&e, BroadbandRange::PAR).unwrap();
        let expect = (700f64.powi(2) - 400f64.powi(2)) / 2.0 * 1e-9
            / (6.626_070_15e-34 * 299_792_458.0)
            / 6.022_140_76e23
            * 1e6;
        assert!((got / expect - 1.0).abs() < 1e-14);
        // ≈ 1381 µmol m⁻² s⁻¹ for 300 W m⁻² of PAR: 4.6 µmol J⁻¹ (McCree 1972's conversion 4.57).
        assert!((got / 300.0 - 4.6).abs() < 0.05, "{}", got / 300.0);
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(Spectrum::new(vec![400.0, 400.0], vec![1.0, 1.0]).is_err());
        assert!(Spectrum::new(vec![400.0], vec![1.0, 2.0]).is_err());
        assert!(Spectrum::new(vec![400.0, 500.0], vec![1.0, f64::NAN]).is_err());
        assert!(Srf::new(vec![400.0, 500.0], vec![0.0, 0.0]).is_err());
        assert!(Srf::new(vec![400.0, 500.0], vec![1.0, -0.1]).is_err());
        assert!(gaussian(500.0, 0.0).validate().is_err());
        assert!(gaussian(f64::NAN, 10.0).validate().is_err());
        // A band outside the spectrum.
        let leaf = Spectrum::flat(0.5, 400.0, 2500.0).unwrap();
        let e = gaussian(405.0, 20.0)
            .band_average(&leaf)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("Gaussian band 405 nm") && e.contains("400-2500 nm"),
            "{e}"
        );
        assert!(
            SpectralBand::Monochromatic {
                wavelength_nm: 350.0
            }
            .band_average(&leaf)
            .is_err()
        );
        // CSV errors name the file and the line.
        let e = Srf::parse_csv("wavelength_nm,response\n400,0.1\n401,abc\n", "my.csv")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("my.csv:3:"), "{e}");
        let e = Srf::parse_csv("# x\nwl,response\n400,0.1\n", "my.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("my.csv:2:") && e.contains("wavelength_nm"),
            "{e}"
        );
        let e = Srf::parse_csv("wavelength_nm,response\n400,0.1\n399,0.2\n", "my.csv")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("my.csv:3:") && e.contains("increase"), "{e}");
        let e = Srf::load_csv("/no/such/srf.csv").unwrap_err().to_string();
        assert!(e.contains("/no/such/srf.csv"), "{e}");
        let ok = Srf::parse_csv("wavelength_um,response\n0.4,0\n0.5,1\n0.6,0\n", "um.csv").unwrap();
        assert_eq!(ok.wavelength_nm(), &[400.0, 500.0, 600.0]);
        let e = Sensor::parse_csv(
            "band,wavelength_nm,response\nB1,400,1\nB2,500,1\nB2,501,1\nB1,402,1\n",
            "x",
            "s.csv",
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("s.csv:5:"), "{e}");
        assert!(
            broadband_weights(
                &[SpectralBand::Monochromatic {
                    wavelength_nm: 500.0
                }],
                &leaf,
                BroadbandRange::PAR
            )
            .is_err()
        );
    }
}
