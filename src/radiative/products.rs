//! Products of the Radiative stage (resource `RadiativeProducts`): reflectance factors per
//! direction and band, albedo, absorbed and transmitted fractions, energy closure
//! (physics.md §1.4, §6.7; design.md §5).

use super::engine::RadiativeResult;
use crate::direction::DirectionSet;
use bevy_ecs::prelude::Resource;
use serde::Serialize;
use std::f64::consts::PI;

/// One reflectance factor.
#[derive(Debug, Clone, Serialize)]
pub struct BrfEntry {
    /// View zenith (ground→sensor), degrees.
    pub zenith_deg: f64,
    /// View azimuth, degrees anticlockwise from +x.
    pub azimuth_deg: f64,
    /// Solid angle of the direction's sector, sr.
    pub solid_angle_sr: f64,
    /// Kind of direction (`regular`, `exact`, `oversampled`).
    pub kind: &'static str,
    /// Bidirectional reflectance factor under direct sun only: π L / (E_dir cos θs·…),
    /// i.e. π W_j / (A ∫_{ΔΩ_j}|μ|dΩ E_dir,horizontal).
    pub brf: f64,
    /// Hemispherical–directional reflectance factor under sun + sky (present with sky light).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hdrf: Option<f64>,
    /// Standard error of `brf` (Monte Carlo solver only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brf_se: Option<f64>,
    /// Standard error of `hdrf` (Monte Carlo solver with sky light only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hdrf_se: Option<f64>,
    /// RAMI components of `brf` (Monte Carlo peel-off directions): single scattering by the
    /// vegetation and other non-ground elements (`brf_co_sgl`), single scattering by the ground
    /// of uncollided light (`brf_uc_sgl`), multiple scattering (`brf_mlt`); they sum to `brf`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brf_co_sgl: Option<f64>,
    /// See `brf_co_sgl`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brf_uc_sgl: Option<f64>,
    /// See `brf_co_sgl`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brf_mlt: Option<f64>,
    /// Standard errors of (`brf_co_sgl`, `brf_uc_sgl`, `brf_mlt`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brf_components_se: Option<[f64; 3]>,
    /// How the value was estimated: `escape` (flux leaving the sector; sector mean) or `peel-off`
    /// (Monte Carlo local estimate in the exact direction); absent for the flux-tracking solver.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimator: Option<&'static str>,
}

/// Products of one band.
#[derive(Debug, Clone, Serialize)]
pub struct BandProducts {
    /// Band name.
    pub band: String,
    /// Scene albedo: exitance / incident irradiance (sun + sky).
    pub albedo: f64,
    /// Fraction absorbed by vegetation and facets other than the ground.
    pub fabs: f64,
    /// Fraction absorbed by the ground.
    pub fabs_ground: f64,
    /// Fraction intercepted by the ground (all orders): transmitted through the canopy.
    pub ftran: f64,
    /// Fraction booked as lost (thresholds, isolated sides, crossings).
    pub flost: f64,
    /// |1 − (absorbed + escaped + lost + remaining) / source|.
    pub energy_closure: f64,
    /// Standard error of `albedo` (Monte Carlo solver only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub albedo_se: Option<f64>,
    /// Standard error of `fabs` (Monte Carlo solver only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fabs_se: Option<f64>,
    /// Standard error of `fabs_ground` (Monte Carlo solver only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fabs_ground_se: Option<f64>,
    /// Standard error of `ftran` (Monte Carlo solver only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ftran_se: Option<f64>,
    /// Reflectance factors for every upward direction (empty in a `T` run).
    pub brf: Vec<BrfEntry>,
    /// Radiance and brightness temperature for every upward direction (`T` and `R+T` runs;
    /// issue #34).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub radiance: Vec<RadianceEntry>,
    /// The thermal channels' budget (`T` and `R+T` runs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub thermal: Option<ThermalBudget>,
}

/// Radiance leaving the scene top along one upward direction (`T` and `R+T` runs):
/// `L = W_j / (A ∫_{ΔΩ_j} μ dΩ)` with W_j the power escaping into the direction's sector
/// (on continuous topography, relative to the mean terrain plane; `NaN`, null in JSON, for
/// a direction behind it).
#[derive(Debug, Clone, Serialize)]
pub struct RadianceEntry {
    /// View zenith (ground→sensor), degrees.
    pub zenith_deg: f64,
    /// View azimuth, degrees anticlockwise from +x.
    pub azimuth_deg: f64,
    /// Solid angle of the direction's sector, sr.
    pub solid_angle_sr: f64,
    /// Kind of direction (`regular`, `exact`, `oversampled`).
    pub kind: &'static str,
    /// Radiance a sensor sees (thermal emission and the reflected thermal sky, plus in `R+T`
    /// the reflected sun and sky), W m⁻² sr⁻¹ µm⁻¹.
    pub radiance_w_m2_sr_um: f64,
    /// The band's brightness temperature of `radiance_w_m2_sr_um` (the T whose band-averaged
    /// Planck radiance it is), K; 0 for no radiance.
    pub brightness_temperature_k: f64,
    /// `R+T`: the thermal part (emission and reflected thermal sky).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub thermal_radiance_w_m2_sr_um: Option<f64>,
    /// `R+T`: the solar part (reflected sun and sky).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solar_radiance_w_m2_sr_um: Option<f64>,
    /// Monte Carlo: the standard error of `radiance_w_m2_sr_um` (spread of the batch
    /// estimates), W m⁻² sr⁻¹ µm⁻¹.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radiance_se_w_m2_sr_um: Option<f64>,
}

/// The thermal channels' budget of one band, per unit horizontal scene area, W m⁻² µm⁻¹.
#[derive(Debug, Clone, Serialize)]
pub struct ThermalBudget {
    /// Power emitted by the scene's elements (vegetation, facets, ground).
    pub emitted_w_m2_um: f64,
    /// Downwelling thermal sky irradiance.
    pub sky_w_m2_um: f64,
    /// Thermal exitance through the top (emitted and reflected sky that escaped).
    pub exitance_w_m2_um: f64,
    /// Absorbed by vegetation and non-ground facets (of all elements' emission and the sky).
    pub absorbed_w_m2_um: f64,
    /// Absorbed by the ground.
    pub absorbed_ground_w_m2_um: f64,
    /// Booked as lost (thresholds, isolated sides).
    pub lost_w_m2_um: f64,
    /// |1 − (absorbed + escaped + lost + remaining) / (emitted + sky)|.
    pub energy_closure: f64,
    /// Monte Carlo: the standard error of `exitance_w_m2_um` (spread of the batch estimates).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exitance_se_w_m2_um: Option<f64>,
}

/// The Radiative stage's products.
#[derive(Debug, Clone, Serialize, Resource)]
pub struct RadiativeProducts {
    /// Per band.
    pub bands: Vec<BandProducts>,
    /// Iterations run.
    pub iterations: u32,
    /// Whether the convergence threshold was met.
    pub converged: bool,
    /// Geometric ratio of the last two iterations per band (sun channel).
    pub extrapolation_ratio: Vec<f64>,
    /// Rays traced.
    pub rays: u64,
    /// Cell crossings the walks visited (read the cell's contents).
    pub crossings: u64,
    /// Empty cells jumped over by empty-space skipping (not in `crossings`).
    pub skipped: u64,
    /// Wall time of the tracking, seconds.
    pub tracking_seconds: f64,
    /// Solver: `flux-tracking` (Radiative stage) or `monte-carlo` (Photon stage).
    pub solver: &'static str,
    /// Run mode (issue #34); `summary.json` records it as `mode` for `T` and `R+T` runs.
    #[serde(skip)]
    pub mode: crate::scene::desc::RunMode,
    /// Sun and sky launch grids (flux tracking only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub launch: Option<crate::radiative::engine::LaunchPlan>,
    /// Monte Carlo run description (Photon stage only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub monte_carlo: Option<MonteCarloInfo>,
    /// Top-of-atmosphere products per band (scenes with an atmosphere only; the per-band
    /// products above are then those of the bottom of the atmosphere).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub toa: Option<Vec<crate::radiative::toa::ToaBand>>,
    /// Raw engine result (not serialised).
    #[serde(skip)]
    pub raw: RadiativeResult,
    /// Whether each facet belongs to a DEM ground (not serialised).
    #[serde(skip)]
    pub ground_facet: Vec<bool>,
}

/// The `A ∫_{ΔΩ_j} μ dΩ` (m² sr) that turns the power escaping into sector j into a radiance:
/// on a continuous-topography scene the mean terrain plane of normal n̄ (the scene's
/// horizontal area A is A/n̄_z of it) replaces the horizontal plane, `(A/n̄_z)(n̄·Ω_j)
/// ∫_{ΔΩ_j}|μ|dΩ/μ_j`, so that an isothermal black slope has radiance B(T) in every
/// direction (the power is carried along Ω_j); `NaN` behind the mean plane.
pub fn radiance_area(area: f64, n: glam::DVec3, d: &crate::direction::Direction) -> f64 {
    if n == glam::DVec3::Z {
        return area * d.projected_sr;
    }
    let c = n.dot(d.omega);
    if c > 1e-9 && d.omega.z > 0.0 {
        area / n.z * c * d.projected_sr / d.omega.z
    } else {
        f64::NAN
    }
}

/// Description of a Monte Carlo run (in summary.json).
#[derive(Debug, Clone, Serialize)]
pub struct MonteCarloInfo {
    /// Photons traced (sun + sky).
    pub photons: u64,
    /// Batches (standard errors come from their spread).
    pub batches: u32,
    /// Seed.
    pub seed: u64,
    /// Direction sampler (`continuous`, `alias`, `box`).
    pub sampler: &'static str,
    /// Scattering events.
    pub events: u64,
    /// Photons per second per core (wall time × threads).
    pub photons_per_second_per_core: f64,
    /// Russian-roulette balance relative to the source, per band (expectation 0).
    pub roulette_balance: Vec<f64>,
    /// Fraction of the source lost per band (isolated sides, caps).
    pub lost: Vec<f64>,
}

impl RadiativeProducts {
    /// Builds the products; `area` is the scene's horizontal area (m²), `e_dir`/`e_diff` the
    /// horizontal irradiances per band.
    /// `ground_facet[f]` marks the facets of a DEM ground: their absorption counts as ground
    /// absorption and their interception as transmission (`ftran`).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        raw: RadiativeResult,
        dirs: &DirectionSet,
        band_names: &[String],
        area: f64,
        e_dir: &[f64],
        e_diff: &[f64],
        ground_facet: &[bool],
        seconds: f64,
    ) -> Self {
        let nb = raw.n_bands;
        let w = raw.n_channels;
        let tiling = dirs.tiling();
        // The solar channels (sun, sky); the thermal ones, after them, are in `thermal`.
        let solar_w = if raw.has_thermal { w - nb } else { w };
        let sum_ch = |v: &[f64], b: usize| -> f64 {
            let mut s = 0.0;
            for (i, x) in v.iter().enumerate() {
                let ch = i % w;
                if ch % nb == b && ch < solar_w {
                    s += x;
                }
            }
            s
        };
        let mut bands = Vec::new();
        for b in 0..nb {
            let src = raw.source[b] + if raw.has_sky { raw.source[nb + b] } else { 0.0 };
            let esc = sum_ch(&raw.escaped, b);
            let facet_part = |v: &[f64], ground: bool| -> f64 {
                let mut s = 0.0;
                for (f, &g) in ground_facet.iter().enumerate() {
                    if g == ground {
                        s += v[f * w + b] + if raw.has_sky { v[f * w + nb + b] } else { 0.0 };
                    }
                }
                s
            };
            let abs_v = sum_ch(&raw.absorbed_turbid, b) + facet_part(&raw.absorbed_facet, false);
            let abs_g = sum_ch(&raw.absorbed_ground, b) + facet_part(&raw.absorbed_facet, true);
            let lost = sum_ch(&raw.lost, b);
            let rem = sum_ch(&raw.remaining, b);
            let tran =
                sum_ch(&raw.intercepted_ground, b) + facet_part(&raw.intercepted_facet, true);
            let closure = if src > 0.0 {
                (1.0 - (abs_v + abs_g + esc + lost + rem) / src).abs()
            } else {
                0.0
            };
            let mut brf = Vec::new();
            for (j, d) in tiling.iter().enumerate() {
                if d.omega.z <= 0.0 {
                    continue;
                }
                let sun = raw.escaped[j * w + b];
                let sky = if raw.has_sky {
                    raw.escaped[j * w + nb + b]
                } else {
                    0.0
                };
                let denom = area * d.projected_sr;
                let brf_v = if e_dir[b] > 0.0 {
                    PI * sun / (denom * e_dir[b])
                } else {
                    f64::NAN
                };
                let hdrf = raw
                    .has_sky
                    .then(|| PI * (sun + sky) / (denom * (e_dir[b] + e_diff[b])));
                brf.push(BrfEntry {
                    zenith_deg: d.zenith_deg(),
                    azimuth_deg: d.azimuth_deg(),
                    solid_angle_sr: d.solid_angle_sr,
                    kind: d.kind.name(),
                    brf: brf_v,
                    hdrf,
                    brf_se: None,
                    hdrf_se: None,
                    brf_co_sgl: None,
                    brf_uc_sgl: None,
                    brf_mlt: None,
                    brf_components_se: None,
                    estimator: None,
                });
            }
            bands.push(BandProducts {
                band: band_names.get(b).cloned().unwrap_or_default(),
                albedo: esc / src,
                fabs: abs_v / src,
                fabs_ground: abs_g / src,
                ftran: tran / src,
                flost: lost / src,
                energy_closure: closure,
                albedo_se: None,
                fabs_se: None,
                fabs_ground_se: None,
                ftran_se: None,
                brf,
                radiance: Vec::new(),
                thermal: None,
            });
        }
        Self {
            bands,
            iterations: raw.iterations,
            converged: raw.converged,
            extrapolation_ratio: raw.q.iter().take(nb).copied().collect(),
            rays: raw.rays,
            crossings: raw.crossings,
            skipped: raw.skipped,
            tracking_seconds: seconds,
            solver: "flux-tracking",
            mode: crate::scene::desc::RunMode::R,
            launch: Some(raw.launch),
            monte_carlo: None,
            toa: None,
            raw,
            ground_facet: ground_facet.to_vec(),
        }
    }

    /// Adds the thermal products of a `T` or `R+T` run (issue #34): per band the radiance and
    /// brightness temperature of every upward direction (`responses`: the bands' spectral
    /// responses) and the thermal budget; a `T` run has no reflectance factors (its solar
    /// fractions are `NaN`, null in JSON).
    pub fn with_thermal(
        mut self,
        mode: crate::scene::desc::RunMode,
        dirs: &DirectionSet,
        responses: &[crate::physics::spectral::SpectralBand],
        area: f64,
        mean_normal: glam::DVec3,
    ) -> Self {
        self.mode = mode;
        let raw = &self.raw;
        if !raw.has_thermal {
            return self;
        }
        let (nb, w) = (raw.n_bands, raw.n_channels);
        let tb = w - nb;
        let tiling = dirs.tiling();
        for b in 0..nb {
            let sum = |v: &[f64]| -> f64 { v.iter().skip(tb + b).step_by(w).sum() };
            let src = raw.source[tb + b];
            let sky = raw.thermal_sky_source.get(b).copied().unwrap_or(0.0);
            let esc = sum(&raw.escaped);
            let ground: f64 = sum(&raw.absorbed_ground);
            let ground_facets: f64 = (0..raw.absorbed_facet.len() / w)
                .filter(|&f| self.ground_facet.get(f).copied().unwrap_or(false))
                .map(|f| raw.absorbed_facet[f * w + tb + b])
                .sum();
            let abs_all = sum(&raw.absorbed_turbid) + sum(&raw.absorbed_facet);
            let lost = raw.lost[tb + b];
            let rem = raw.remaining[tb + b];
            let closure = if src > 0.0 {
                (1.0 - (abs_all + ground + esc + lost + rem) / src).abs()
            } else {
                0.0
            };
            let mut radiance = Vec::new();
            for (j, d) in tiling.iter().enumerate() {
                if d.omega.z <= 0.0 {
                    continue;
                }
                let denom = radiance_area(area, mean_normal, d);
                let thermal = raw.escaped[j * w + tb + b] / denom;
                let solar: f64 = (0..tb)
                    .filter(|ch| ch % nb == b)
                    .map(|ch| raw.escaped[j * w + ch])
                    .sum::<f64>()
                    / denom;
                let total = thermal + solar;
                let bt = responses.get(b).map_or(0.0, |r| {
                    crate::physics::thermal::band_brightness_temperature(r, total).unwrap_or(0.0)
                });
                radiance.push(RadianceEntry {
                    zenith_deg: d.zenith_deg(),
                    azimuth_deg: d.azimuth_deg(),
                    solid_angle_sr: d.solid_angle_sr,
                    kind: d.kind.name(),
                    radiance_w_m2_sr_um: total,
                    brightness_temperature_k: bt,
                    thermal_radiance_w_m2_sr_um: (mode.solar()).then_some(thermal),
                    solar_radiance_w_m2_sr_um: (mode.solar()).then_some(solar),
                    radiance_se_w_m2_sr_um: None,
                });
            }
            let band = &mut self.bands[b];
            band.radiance = radiance;
            band.thermal = Some(ThermalBudget {
                emitted_w_m2_um: (src - sky) / area,
                sky_w_m2_um: sky / area,
                exitance_w_m2_um: esc / area,
                absorbed_w_m2_um: (abs_all - ground_facets) / area,
                absorbed_ground_w_m2_um: (ground + ground_facets) / area,
                lost_w_m2_um: lost / area,
                energy_closure: closure,
                exitance_se_w_m2_um: None,
            });
            if !mode.solar() {
                band.brf.clear();
            }
        }
        self
    }

    /// The BRF entry of band `b` closest to a view direction (zenith, azimuth in degrees).
    pub fn brf_at(&self, b: usize, zenith_deg: f64, azimuth_deg: f64) -> Option<&BrfEntry> {
        let target = crate::direction::direction_from_deg(zenith_deg, azimuth_deg);
        self.bands.get(b)?.brf.iter().max_by(|x, y| {
            let dx = crate::direction::direction_from_deg(x.zenith_deg, x.azimuth_deg).dot(target);
            let dy = crate::direction::direction_from_deg(y.zenith_deg, y.azimuth_deg).dot(target);
            dx.total_cmp(&dy)
        })
    }
}
