//! Discretised phase tables over a [`DirectionSet`] (physics.md §2.5, §3.3, §4.2, §5).
//!
//! Stage: Phase. Inputs: the direction set, a material (turbid vegetation LAD + leaf optics,
//! fluid phase function + albedo, or facet reflectance + normal) and optionally the exact sun
//! propagation direction. Output: [`PhaseTable`] — `T[i][j]`, the fraction of power intercepted
//! from incident direction `i` (every tiling direction, then the exact sun direction as an extra
//! last row) that is scattered into outgoing direction `j` (tiling directions, then fictive
//! directions). Each row is renormalised so that its sum over the **tiling** columns equals the
//! single-scattering albedo of that incidence exactly (energy closes by construction); the
//! relative size of that correction is kept per row ([`PhaseTable::renormalisation`]) and measures
//! the discretisation error. Fictive columns hold the pointwise value `T(Ω_i→Ω_v) ΔΩ_v` and are
//! never renormalised (they are not part of the energy budget, physics.md §2.4).
//!
//! Storage: `f32` values (row-major), `f64` per-row targets and sums. The `f64` sum of the stored
//! `f32` values of a row ([`PhaseTable::row_sum`]) differs from the target by ~1e-8 relative; a
//! consumer that needs exact closure should book `absorbed = W_int (1 − row_sum)`.
//!
//! Sector integrals use `s × s` equal-solid-angle sub-samples (physics.md §2.5: ≥ 4×4), refined to
//! `peak_sub_samples²` for sectors near a peak (HG forward lobes, BRDF hotspots, specular lobes).
//! Lambertian facets use exact projected solid angles instead ([`projected_solid_angle`]).

use glam::DVec3;
use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI};

use crate::direction::{Direction, DirectionKind, DirectionSet};
use crate::physics::brdf::{Brdf, BrdfError, LocalGeometry, SpecularLobe, mirror};
use crate::physics::lad::{
    LadError, LeafAngleDistribution, LeafOptics, LeafSpecular, VolscattKernel, gamma_specular,
    specular_albedo, tanh_sinh_pieces, tanh_sinh_pieces_coarse,
};
use crate::physics::phase::{FluidPhase, PhaseError};

/// Resolution of the sector integrations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableParams {
    /// Sub-samples per sector axis (s × s per sector), ≥ 1.
    pub sub_samples: usize,
    /// Sub-samples per axis for sectors near a peak, ≥ `sub_samples`.
    pub peak_sub_samples: usize,
    /// A sector is "near a peak" when its centre is within this angle (degrees) plus its own
    /// radius of the peak direction.
    pub peak_radius_deg: f64,
    /// Inclination bins of non-spherical LADs in the volscatt kernel (≥ 18; 90 is reference).
    pub lad_bins: usize,
}

impl TableParams {
    /// Default: 4×4 sub-samples (physics.md §2.5), 16×16 near peaks within 15°, 36 LAD bins.
    pub fn dart_default() -> Self {
        Self {
            sub_samples: 4,
            peak_sub_samples: 16,
            peak_radius_deg: 15.0,
            lad_bins: 36,
        }
    }

    /// Fast preview: 2×2, 8×8 near peaks, 18 LAD bins.
    pub fn preview() -> Self {
        Self {
            sub_samples: 2,
            peak_sub_samples: 8,
            peak_radius_deg: 15.0,
            lad_bins: 18,
        }
    }

    /// Reference accuracy: 8×8, 32×32 near peaks, 90 LAD bins.
    pub fn reference() -> Self {
        Self {
            sub_samples: 8,
            peak_sub_samples: 32,
            peak_radius_deg: 20.0,
            lad_bins: 90,
        }
    }
}

impl Default for TableParams {
    fn default() -> Self {
        Self::dart_default()
    }
}

/// Bytes used by `n_bands` tables of `n_in` rows × `n_out` columns: `f32` values plus three `f64`
/// per row (target albedo, stored-row sum, renormalisation).
pub fn bytes(n_in: usize, n_out: usize, n_bands: usize) -> usize {
    n_bands * (n_in * n_out * std::mem::size_of::<f32>() + 3 * n_in * std::mem::size_of::<f64>())
}

/// A phase table `T[i][j]` (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseTable {
    n_rows: usize,
    n_cols: usize,
    n_regular: usize,
    has_sun_row: bool,
    values: Vec<f32>,
    albedo: Vec<f64>,
    row_sums: Vec<f64>,
    renorm: Vec<f64>,
}

impl PhaseTable {
    /// Number of rows (tiling directions + 1 if the sun row exists).
    pub fn n_rows(&self) -> usize {
        self.n_rows
    }

    /// Number of columns (tiling + fictive directions).
    pub fn n_cols(&self) -> usize {
        self.n_cols
    }

    /// Number of tiling columns (the renormalised part of each row).
    pub fn n_regular(&self) -> usize {
        self.n_regular
    }

    /// Index of the exact-sun row, if tabulated (always the last row).
    pub fn sun_row(&self) -> Option<usize> {
        self.has_sun_row.then(|| self.n_rows - 1)
    }

    /// Row `i` (all columns).
    pub fn row(&self, i: usize) -> &[f32] {
        &self.values[i * self.n_cols..(i + 1) * self.n_cols]
    }

    /// `T[i][j]`.
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f32 {
        self.values[i * self.n_cols + j]
    }

    /// Target row sum (single-scattering albedo for incidence `i`).
    pub fn albedo(&self, i: usize) -> f64 {
        self.albedo[i]
    }

    /// Exact `f64` sum of the stored `f32` values of row `i` over the tiling columns.
    pub fn row_sum(&self, i: usize) -> f64 {
        self.row_sums[i]
    }

    /// Relative renormalisation of row `i`: `raw_sum/exact − 1`, where `exact` is the exact
    /// integral the sub-sampled row approximates (the albedo before any clipping at 1); 0 for
    /// zero rows. It measures the sector-integration error.
    pub fn renormalisation(&self, i: usize) -> f64 {
        self.renorm[i]
    }

    /// Largest |renormalisation| over rows.
    pub fn max_renormalisation(&self) -> f64 {
        self.renorm.iter().fold(0.0f64, |a, b| a.max(b.abs()))
    }

    /// Largest |row_sum − albedo| over rows (f32 storage error).
    pub fn max_storage_error(&self) -> f64 {
        self.row_sums
            .iter()
            .zip(&self.albedo)
            .fold(0.0f64, |a, (s, t)| a.max((s - t).abs()))
    }

    /// Memory used by this table, bytes.
    pub fn bytes(&self) -> usize {
        bytes(self.n_rows, self.n_cols, 1)
    }

    /// `row_fn(i, raw)` fills row i and returns `(target, exact)`: the row sum to enforce and the
    /// exact value of the integral the raw sum approximates (they differ only when an albedo is
    /// clipped at 1), so that the reported renormalisation measures discretisation error only.
    fn build(
        n_rows: usize,
        n_cols: usize,
        n_regular: usize,
        has_sun_row: bool,
        mut row_fn: impl FnMut(usize, &mut [f64]) -> (f64, f64),
    ) -> Self {
        let mut t = Self {
            n_rows,
            n_cols,
            n_regular,
            has_sun_row,
            values: vec![0.0; n_rows * n_cols],
            albedo: vec![0.0; n_rows],
            row_sums: vec![0.0; n_rows],
            renorm: vec![0.0; n_rows],
        };
        let mut buf = vec![0.0f64; n_cols];
        for i in 0..n_rows {
            buf.iter_mut().for_each(|x| *x = 0.0);
            let (target, exact) = row_fn(i, &mut buf);
            t.store_row(i, &buf, target);
            let raw: f64 = buf[..n_regular].iter().sum();
            t.renorm[i] = if exact > 0.0 && raw > 0.0 {
                raw / exact - 1.0
            } else {
                0.0
            };
        }
        t
    }

    /// Renormalises the tiling part of `raw` to `target` and stores it as f32 (the f32 rounding
    /// residual is pushed into the largest entry).
    fn store_row(&mut self, i: usize, raw: &[f64], target: f64) {
        let nr = self.n_regular;
        let raw_sum: f64 = raw[..nr].iter().sum();
        let (scale, renorm) = if target > 0.0 && raw_sum > 0.0 {
            (target / raw_sum, raw_sum / target - 1.0)
        } else {
            (0.0, 0.0)
        };
        let target = if raw_sum > 0.0 { target } else { 0.0 };
        let row = &mut self.values[i * self.n_cols..(i + 1) * self.n_cols];
        let mut kmax = 0;
        for j in 0..nr {
            row[j] = (raw[j] * scale) as f32;
            if row[j] > row[kmax] {
                kmax = j;
            }
        }
        for j in nr..self.n_cols {
            row[j] = raw[j] as f32;
        }
        let s: f64 = row[..nr].iter().map(|&x| x as f64).sum();
        if nr > 0 && target > 0.0 {
            row[kmax] = (row[kmax] as f64 + (target - s)).max(0.0) as f32;
        }
        self.row_sums[i] = row[..nr].iter().map(|&x| x as f64).sum();
        self.albedo[i] = target;
        self.renorm[i] = renorm;
    }
}

fn incident_dirs(set: &DirectionSet, sun: Option<DVec3>) -> Vec<DVec3> {
    let mut v: Vec<DVec3> = set.tiling().iter().map(|d| d.omega).collect();
    if let Some(s) = sun {
        v.push(s.normalize_or(DVec3::NEG_Z));
    }
    v
}

/// Sub-samples per axis for sector `d` given peak directions.
fn samples_for(d: &Direction, peaks: &[DVec3], p: &TableParams) -> usize {
    if matches!(d.kind, DirectionKind::Fictive { .. }) {
        return 1;
    }
    let radius = (d.solid_angle_sr / PI).sqrt() * 1.5 + p.peak_radius_deg.to_radians();
    let c = radius.min(PI).cos();
    if peaks.iter().any(|pk| pk.dot(d.omega) >= c) {
        p.peak_sub_samples.max(p.sub_samples).max(1)
    } else {
        p.sub_samples.max(1)
    }
}

/// Sub-samples of every column at the base resolution, computed once per table (rows reuse
/// them); peak-refined sectors are re-sampled on demand.
struct ColumnSamples {
    offsets: Vec<usize>,
    samples: Vec<(DVec3, f64)>,
    base: usize,
    scratch: Vec<(DVec3, f64)>,
}

impl ColumnSamples {
    fn new(set: &DirectionSet, s: usize) -> Self {
        let mut offsets = Vec::with_capacity(set.len() + 1);
        let mut samples = Vec::new();
        let mut buf = Vec::new();
        offsets.push(0);
        for d in &set.directions {
            d.sub_samples(s, &mut buf);
            samples.extend_from_slice(&buf);
            offsets.push(samples.len());
        }
        Self {
            offsets,
            samples,
            base: s,
            scratch: Vec::new(),
        }
    }

    /// Samples of column `j` at `s` sub-samples per axis.
    fn get(&mut self, j: usize, d: &Direction, s: usize) -> &[(DVec3, f64)] {
        if s == self.base || matches!(d.kind, DirectionKind::Fictive { .. }) {
            &self.samples[self.offsets[j]..self.offsets[j + 1]]
        } else {
            d.sub_samples(s, &mut self.scratch);
            &self.scratch
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Turbid vegetation
// ---------------------------------------------------------------------------------------------

/// Band-independent unit tables of a turbid vegetation material: Γ is linear in the leaf optics,
/// `T = ρ_L R + τ_L T + factor S`, so one LAD needs only these (memory O(N²) per LAD, not per
/// band). `reflect`/`transmit` rows sum to 1; `specular` rows sum to the G-weighted mean Fresnel
/// reflectance ⟨R_F⟩(Ω_i).
#[derive(Debug, Clone)]
pub struct VegetationTables {
    /// Γ_ρ table (ρ_L = 1, τ_L = 0), rows sum to 1.
    pub reflect: PhaseTable,
    /// Γ_τ table (ρ_L = 0, τ_L = 1), rows sum to 1.
    pub transmit: PhaseTable,
    /// Specular table with factor 1 (present when a specular component was requested).
    pub specular: Option<PhaseTable>,
    /// G(Ω_i) of each row (binned LAD, consistent with the tables).
    pub g: Vec<f64>,
}

impl VegetationTables {
    /// Materialises the table of one band: `ρ R + τ T (+ factor S)`, renormalised to
    /// `ω_i = ρ + τ (+ factor ⟨R_F⟩_i)`. Errors on invalid optics.
    pub fn for_band(&self, optics: &LeafOptics) -> Result<PhaseTable, LadError> {
        optics.validate()?;
        let (r, t) = (optics.reflectance, optics.transmittance);
        let f = optics.specular.map_or(0.0, |s| s.factor);
        let a = &self.reflect;
        let mut out = PhaseTable {
            values: vec![0.0; a.values.len()],
            ..a.clone()
        };
        let mut buf = vec![0.0; a.n_cols];
        for i in 0..a.n_rows {
            let mut target = r * a.albedo[i] + t * self.transmit.albedo[i];
            let mut raw_rel = r * a.albedo[i] * (1.0 + a.renorm[i])
                + t * self.transmit.albedo[i] * (1.0 + self.transmit.renorm[i]);
            for (j, b) in buf.iter_mut().enumerate() {
                *b = r * a.get(i, j) as f64 + t * self.transmit.get(i, j) as f64;
            }
            if let (Some(s), true) = (&self.specular, f > 0.0) {
                target += f * s.albedo[i];
                raw_rel += f * s.albedo[i] * (1.0 + s.renorm[i]);
                for (j, b) in buf.iter_mut().enumerate() {
                    *b += f * s.get(i, j) as f64;
                }
            }
            out.store_row(i, &buf, target);
            out.renorm[i] = if target > 0.0 {
                raw_rel / target - 1.0
            } else {
                0.0
            };
        }
        Ok(out)
    }
}

/// Unit tables of a turbid vegetation LAD (see [`VegetationTables`]); `T_ij = ∫_{ΔΩ_j} Γ dΩ /
/// (π G(Ω_i))` (physics.md §3.3). Spherical LADs use the closed-form Γ; others Verhoef's volscatt
/// with `params.lad_bins` bins; the optional specular table uses [`gamma_specular`] with
/// factor 1 and its exact albedo from [`specular_albedo`].
pub fn vegetation_unit_tables(
    set: &DirectionSet,
    lad: &LeafAngleDistribution,
    specular_index: Option<f64>,
    sun: Option<DVec3>,
    params: &TableParams,
) -> VegetationTables {
    let kernel = VolscattKernel::new(lad, params.lad_bins.max(1), false);
    let inc = incident_dirs(set, sun);
    let dirs = &set.directions;
    let nr = set.n_regular();
    let n_rows = inc.len();
    let g: Vec<f64> = inc
        .iter()
        .map(|o| kernel.g_binned(o.z).max(1e-300))
        .collect();
    let mut trans_rows: Vec<Vec<f64>> = Vec::with_capacity(n_rows);
    let base = params.sub_samples.max(1);
    let mut cols = ColumnSamples::new(set, base);
    let reflect = PhaseTable::build(n_rows, dirs.len(), nr, sun.is_some(), |i, row| {
        let oi = inc[i];
        let mut trow = vec![0.0; dirs.len()];
        let norm = 1.0 / (PI * g[i]);
        if kernel.is_closed_form() {
            for (j, d) in dirs.iter().enumerate() {
                let (mut a, mut b) = (0.0, 0.0);
                for &(o, w) in cols.get(j, d, base) {
                    let (r, t) = kernel.gamma_components(oi, o);
                    a += w * r;
                    b += w * t;
                }
                row[j] = a * norm;
                trow[j] = b * norm;
            }
        } else {
            let vi = kernel.incident(oi);
            let mut cache: HashMap<u64, crate::physics::lad::VolscattPair> = HashMap::new();
            for (j, d) in dirs.iter().enumerate() {
                let (mut a, mut b) = (0.0, 0.0);
                for &(o, w) in cols.get(j, d, base) {
                    let pair = cache.entry(o.z.to_bits()).or_insert_with(|| vi.view(o.z));
                    let (psi, _) = vi.relative_azimuth(o);
                    let (r, t) = pair.eval(psi);
                    a += w * r;
                    b += w * t;
                }
                row[j] = a * norm;
                trow[j] = b * norm;
            }
        }
        trans_rows.push(trow);
        (1.0, 1.0)
    });
    let transmit = PhaseTable::build(n_rows, dirs.len(), nr, sun.is_some(), |i, row| {
        row.copy_from_slice(&trans_rows[i]);
        (1.0, 1.0)
    });
    let specular = specular_index.map(|n_idx| {
        let spec = LeafSpecular {
            refractive_index: n_idx,
            factor: 1.0,
        };
        PhaseTable::build(n_rows, dirs.len(), nr, sun.is_some(), |i, row| {
            let oi = inc[i];
            // Peak: mirror about horizontal leaves (vertical normal).
            let peaks = [DVec3::new(oi.x, oi.y, -oi.z)];
            let norm = 1.0 / (PI * lad.g_function(oi.z).max(1e-300));
            for (j, d) in dirs.iter().enumerate() {
                let smp = cols.get(j, d, samples_for(d, &peaks, params));
                row[j] = smp
                    .iter()
                    .map(|&(o, w)| w * gamma_specular(lad, oi, o, &spec))
                    .sum::<f64>()
                    * norm;
            }
            let a = specular_albedo(lad, oi, &spec, params.lad_bins.max(18) * 2, 360);
            (a, a)
        })
    });
    VegetationTables {
        reflect,
        transmit,
        specular,
        g,
    }
}

/// Table of one band of a turbid vegetation material (LAD + leaf optics), rows summing to the
/// leaf single-scattering albedo (physics.md §2.5, §3.3). See [`vegetation_unit_tables`].
pub fn vegetation_table(
    set: &DirectionSet,
    lad: &LeafAngleDistribution,
    optics: &LeafOptics,
    sun: Option<DVec3>,
    params: &TableParams,
) -> Result<PhaseTable, LadError> {
    optics.validate()?;
    let unit = vegetation_unit_tables(
        set,
        lad,
        optics.specular.map(|s| s.refractive_index),
        sun,
        params,
    );
    unit.for_band(optics)
}

// ---------------------------------------------------------------------------------------------
// Fluids
// ---------------------------------------------------------------------------------------------

/// Table of a fluid: `T_ij = (ω/4π) ∫_{ΔΩ_j} P(Ω_i·Ω) dΩ`, rows renormalised to `ω`
/// (physics.md §2.5, §4.2). Sectors within `peak_radius_deg` of the forward direction (and of
/// the backward direction for two-term HG) use `peak_sub_samples` when the phase function has
/// an HG lobe with |g| ≥ 0.3.
pub fn fluid_table(
    set: &DirectionSet,
    phase: &FluidPhase,
    albedo: f64,
    sun: Option<DVec3>,
    params: &TableParams,
) -> Result<PhaseTable, PhaseError> {
    phase.validate()?;
    if !(albedo.is_finite() && (0.0..=1.0).contains(&albedo)) {
        return Err(PhaseError {
            name: "albedo",
            value: albedo,
            reason: "must be in [0, 1]",
        });
    }
    let inc = incident_dirs(set, sun);
    let dirs = &set.directions;
    let peaked = phase.peakedness() >= 0.3;
    let mut cols = ColumnSamples::new(set, params.sub_samples.max(1));
    Ok(PhaseTable::build(
        inc.len(),
        dirs.len(),
        set.n_regular(),
        sun.is_some(),
        |i, row| {
            let oi = inc[i];
            let peaks: Vec<DVec3> = if peaked { vec![oi, -oi] } else { Vec::new() };
            for (j, d) in dirs.iter().enumerate() {
                let smp = cols.get(j, d, samples_for(d, &peaks, params));
                row[j] = albedo / (4.0 * PI)
                    * smp
                        .iter()
                        .map(|&(o, w)| w * phase.eval(oi.dot(o)))
                        .sum::<f64>();
            }
            (albedo, albedo)
        },
    ))
}

// ---------------------------------------------------------------------------------------------
// Facets
// ---------------------------------------------------------------------------------------------

/// Exact projected solid angle of the part of sector `d` on the front side of a plane of unit
/// normal `normal`: `∫_{ΔΩ} max(0, n·Ω) dΩ` (sr). The azimuth integral is analytic; the μ
/// integral uses tanh–sinh split at every kink (tangent latitudes μ = ±n_h and the plane's
/// crossings of the sector's bounding meridians), accurate to ~1e-13; sectors on one side of
/// the plane (most of them) take the closed form `max(0, n·∫Ω dΩ)` instead. Fictive
/// directions use `max(0, n·Ω_v) ΔΩ_v`.
pub fn projected_solid_angle(d: &Direction, normal: DVec3) -> f64 {
    projected_solid_angle_rule(d, normal, true)
}

/// [`projected_solid_angle`] with the 145-node tanh–sinh rule on every sector (no closed form
/// for one-sided sectors): the check of the 73-node rule and of the closed form.
pub fn projected_solid_angle_fine(d: &Direction, normal: DVec3) -> f64 {
    projected_solid_angle_rule(d, normal, false)
}

fn projected_solid_angle_rule(d: &Direction, normal: DVec3, coarse: bool) -> f64 {
    let n = normal.normalize_or(DVec3::Z);
    if matches!(d.kind, DirectionKind::Fictive { .. }) {
        return n.dot(d.omega).max(0.0) * d.solid_angle_sr;
    }
    let nh = (n.x * n.x + n.y * n.y).sqrt();
    let (pa, pb) = (d.phi_min, d.phi_max);
    if nh < 1e-15 {
        // Horizontal plane: analytic (tiling sectors never straddle the horizon).
        let (a, b) = (d.mu_min, d.mu_max);
        let front = n.z * (a + b) > 0.0;
        return if front {
            (pb - pa) * n.z.abs() * (b * b - a * a).abs() / 2.0
        } else {
            0.0
        };
    }
    let phin = n.y.atan2(n.x);
    if coarse && let Some(v) = one_sided(d, n, nh, phin) {
        return v;
    }
    let mut breaks = vec![nh, -nh];
    for phi in [pa, pb] {
        let c = nh * (phi - phin).cos();
        let r = (n.z * n.z + c * c).sqrt();
        if r > 0.0 {
            breaks.push(c.abs() / r);
            breaks.push(-c.abs() / r);
        }
    }
    breaks.sort_by(f64::total_cmp);
    let ta = pa - phin;
    let dphi = pb - pa;
    let f = |mu: f64, _: f64, _: f64| {
        let a = n.z * mu;
        let b = nh * (1.0 - mu * mu).max(0.0).sqrt();
        azimuth_positive_integral(a, b, ta, dphi)
    };
    if coarse {
        tanh_sinh_pieces_coarse(d.mu_min, d.mu_max, &breaks, f)
    } else {
        tanh_sinh_pieces(d.mu_min, d.mu_max, &breaks, f)
    }
}

/// [`projected_solid_angle`] of a sector that lies on one side of the plane: `n·∫_{ΔΩ} Ω dΩ`
/// in closed form on the front side, 0 on the back side, `None` when the plane cuts the
/// sector. With `S(μ) = ½(μ√(1−μ²) + asin μ)`, `∫Ω dΩ` over μ ∈ [a, b], φ ∈ [φ₁, φ₂] is
/// `((S(b)−S(a))(sin φ₂ − sin φ₁), (S(b)−S(a))(cos φ₁ − cos φ₂), (b²−a²)(φ₂−φ₁)/2)`. The
/// side test takes the extremes of `n·Ω = n_z μ + n_h √(1−μ²) cos(φ−φ_n)` over the sector:
/// at its corners, on its meridians where `μ = ±n_z/√(n_z² + c²)` (c = n_h cos(φ−φ_n)), on
/// its latitude circles at φ = φ_n and φ_n + π, and inside at Ω = ±n.
fn one_sided(d: &Direction, n: DVec3, nh: f64, phin: f64) -> Option<f64> {
    let (a, b) = (d.mu_min, d.mu_max);
    let (pa, pb) = (d.phi_min, d.phi_max);
    let dphi = pb - pa;
    let in_range = |phi: f64| (phi - pa).rem_euclid(2.0 * PI) <= dphi;
    let sq = |mu: f64| (1.0 - mu * mu).max(0.0).sqrt();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut take = |g: f64| {
        lo = lo.min(g);
        hi = hi.max(g);
    };
    for phi in [pa, pb] {
        let c = nh * (phi - phin).cos();
        for mu in [a, b] {
            take(n.z * mu + c * sq(mu));
        }
        let r = (n.z * n.z + c * c).sqrt();
        if r > 0.0 {
            for mu in [n.z / r, -n.z / r] {
                if (a..=b).contains(&mu) {
                    take(n.z * mu + c * sq(mu));
                }
            }
        }
    }
    for (phi, cos) in [(phin, 1.0), (phin + PI, -1.0)] {
        if in_range(phi) {
            for mu in [a, b] {
                take(n.z * mu + cos * nh * sq(mu));
            }
        }
    }
    for (m, g) in [(n, 1.0), (-n, -1.0)] {
        let phi = m.y.atan2(m.x);
        if (a..=b).contains(&m.z) && in_range(phi) {
            take(g);
        }
    }
    if hi <= 0.0 {
        return Some(0.0);
    }
    if lo < 0.0 {
        return None;
    }
    let s = |mu: f64| 0.5 * (mu * sq(mu) + mu.clamp(-1.0, 1.0).asin());
    let sx = s(b) - s(a);
    let v = DVec3::new(
        sx * (pb.sin() - pa.sin()),
        sx * (pa.cos() - pb.cos()),
        0.5 * (b * b - a * a) * dphi,
    );
    Some(n.dot(v).max(0.0))
}

/// `∫_{t_a}^{t_a+Δ} max(0, A + B cos t) dt` for `B ≥ 0`, `Δ ≤ 2π` (closed form).
fn azimuth_positive_integral(a: f64, b: f64, ta: f64, d: f64) -> f64 {
    if a >= b {
        return a * d + b * ((ta + d).sin() - ta.sin());
    }
    if a <= -b {
        return 0.0;
    }
    let alpha = (-a / b).clamp(-1.0, 1.0).acos();
    let t0 = (ta + PI).rem_euclid(2.0 * PI) - PI;
    let t1 = t0 + d;
    let mut s = 0.0;
    for k in -1..=2 {
        let c = 2.0 * PI * k as f64;
        let lo = t0.max(c - alpha);
        let hi = t1.min(c + alpha);
        if hi > lo {
            s += a * (hi - lo) + b * (hi.sin() - lo.sin());
        }
    }
    s
}

/// Lambertian facet redistribution fractions for one facet normal (physics.md §2.5, §5.1).
#[derive(Debug, Clone, PartialEq)]
pub struct FacetFractions {
    /// Fraction of diffusely reflected power going into each direction (front side,
    /// `∫_{ΔΩ_j} max(0, n·Ω) dΩ / π`); tiling part sums to 1 exactly (renormalised).
    pub front: Vec<f64>,
    /// Same for the back side (diffuse transmission, `max(0, −n·Ω)`), sums to 1.
    pub back: Vec<f64>,
    /// `raw_sum − 1` of the front fractions before renormalisation (quadrature error).
    pub renorm_front: f64,
    /// `raw_sum − 1` of the back fractions.
    pub renorm_back: f64,
}

/// Exact Lambertian reflection/transmission fractions into every direction for a facet of unit
/// normal `normal` (multiply by R or T_diff and by `1 − T_dir^{1/μ}`-intercepted power). Sectors
/// straddling the facet plane are split exactly by [`projected_solid_angle`].
pub fn lambertian_facet_fractions(set: &DirectionSet, normal: DVec3) -> FacetFractions {
    let n = normal.normalize_or(DVec3::Z);
    let nr = set.n_regular();
    let mut front: Vec<f64> = set
        .directions
        .iter()
        .map(|d| projected_solid_angle(d, n) / PI)
        .collect();
    let mut back: Vec<f64> = set
        .directions
        .iter()
        .map(|d| projected_solid_angle(d, -n) / PI)
        .collect();
    let fs: f64 = front[..nr].iter().sum();
    let bs: f64 = back[..nr].iter().sum();
    front[..nr].iter_mut().for_each(|x| *x /= fs);
    back[..nr].iter_mut().for_each(|x| *x /= bs);
    FacetFractions {
        front,
        back,
        renorm_front: fs - 1.0,
        renorm_back: bs - 1.0,
    }
}

/// Table of a facet reflectance model for a facet of normal `normal`: row i (incidence Ω_i on the
/// front side, `Ω_i·n < 0`) holds `∫_{ΔΩ_j} BRF(Ω_i→Ω) max(0, n·Ω) dΩ / π`, renormalised to
/// `min(1, ρ_DH(μ_i))` (physics.md §5.2–5.3: RPV/Hapke are not energy-conserving by
/// construction; the directional–hemispherical albedo, computed by fine quadrature, is the
/// facet's scattering fraction). Rows for back-side incidence are zero. Lambertian models use the
/// exact projected fractions times the reflectance.
pub fn brdf_facet_table(
    set: &DirectionSet,
    brdf: &Brdf,
    normal: DVec3,
    sun: Option<DVec3>,
    params: &TableParams,
) -> Result<PhaseTable, BrdfError> {
    brdf.validate()?;
    let n = normal.normalize_or(DVec3::Z);
    let inc = incident_dirs(set, sun);
    let dirs = &set.directions;
    let lamb = if let Brdf::Lambertian { .. } = brdf {
        Some(lambertian_facet_fractions(set, n))
    } else {
        None
    };
    let mut albedo_cache: HashMap<u64, f64> = HashMap::new();
    let mut cols = ColumnSamples::new(set, params.sub_samples.max(1));
    Ok(PhaseTable::build(
        inc.len(),
        dirs.len(),
        set.n_regular(),
        sun.is_some(),
        |i, row| {
            let oi = inc[i];
            let mu_i = -oi.dot(n);
            if mu_i <= 0.0 {
                return (0.0, 0.0);
            }
            if let (Some(f), Brdf::Lambertian { reflectance }) = (&lamb, brdf) {
                for (j, x) in f.front.iter().enumerate() {
                    row[j] = reflectance * x;
                }
                return (*reflectance, *reflectance);
            }
            let exact = *albedo_cache
                .entry(mu_i.to_bits())
                .or_insert_with(|| brdf.albedo_dh(mu_i));
            let peaks = [-oi];
            for (j, d) in dirs.iter().enumerate() {
                let smp = cols.get(j, d, samples_for(d, &peaks, params));
                row[j] = smp
                    .iter()
                    .map(|&(o, w)| {
                        let c = n.dot(o);
                        if c <= 0.0 {
                            return 0.0;
                        }
                        LocalGeometry::from_vectors(n, oi, o)
                            .map_or(0.0, |g| w * brdf.brf_local(&g) * c)
                    })
                    .sum::<f64>()
                    / PI;
            }
            (exact.min(1.0), exact)
        },
    ))
}

/// Distribution of the specular part of a facet's interception (physics.md §5.4 \[rec\]): the
/// fraction `s = lobe.fraction(μ_i)` is spread over the tiling directions whose representative
/// lies within `width_deg` of the mirror direction and on the front side, in proportion to their
/// solid angle (uniform radiance over the lobe); if none qualifies, all goes to the direction
/// containing the mirror direction. Returns `(direction index, fraction)` pairs summing to `s`
/// exactly; empty for back-side incidence. The diffuse part should be scaled by `1 − s`.
pub fn specular_fractions(
    set: &DirectionSet,
    normal: DVec3,
    omega_in: DVec3,
    lobe: &SpecularLobe,
) -> Vec<(usize, f64)> {
    let n = normal.normalize_or(DVec3::Z);
    let oi = omega_in.normalize_or(DVec3::NEG_Z);
    let mu_i = -oi.dot(n);
    if mu_i <= 0.0 {
        return Vec::new();
    }
    let s = lobe.fraction(mu_i);
    if s <= 0.0 {
        return Vec::new();
    }
    let r = mirror(oi, n);
    let c = lobe.width_deg.to_radians().min(FRAC_PI_2).cos();
    let picked: Vec<(usize, f64)> = set
        .tiling()
        .iter()
        .enumerate()
        .filter(|(_, d)| d.omega.dot(r) >= c && d.omega.dot(n) > 0.0)
        .map(|(j, d)| (j, d.solid_angle_sr))
        .collect();
    if picked.is_empty() {
        return vec![(set.find_sector(r), s)];
    }
    let tot: f64 = picked.iter().map(|p| p.1).sum();
    picked.into_iter().map(|(j, w)| (j, s * w / tot)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::lad::Lad;

    #[test]
    fn memory_formula() {
        assert_eq!(bytes(101, 100, 2), 2 * (101 * 100 * 4 + 3 * 101 * 8));
    }

    #[test]
    fn azimuth_integral_matches_brute_force() {
        for &(a, b, ta, d) in &[
            (0.3, 0.5, -2.0, 1.0),
            (-0.2, 0.9, 2.5, 3.0),
            (0.0, 1.0, -3.0, 6.2),
            (0.6, 0.2, 0.3, 0.4),
        ] {
            let n = 200_000;
            let h = d / n as f64;
            let bf: f64 = (0..n)
                .map(|k| (a + b * (ta + (k as f64 + 0.5) * h).cos()).max(0.0) * h)
                .sum();
            assert!((bf - azimuth_positive_integral(a, b, ta, d)).abs() < 1e-9);
        }
    }

    #[test]
    fn spherical_rows_sum_to_albedo() {
        let set = DirectionSet::with_count(50).unwrap();
        let lad = Lad::Spherical.resolve().unwrap();
        let t = vegetation_table(
            &set,
            &lad,
            &LeafOptics::lambertian(0.45, 0.45),
            Some(DVec3::new(0.5, 0.0, -0.866).normalize()),
            &TableParams::preview(),
        )
        .unwrap();
        for i in 0..t.n_rows() {
            assert!((t.row_sum(i) - 0.9).abs() < 1e-6);
        }
        assert!(t.max_renormalisation() < 0.05);
    }
}
