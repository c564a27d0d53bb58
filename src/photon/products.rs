//! Products of the Photon stage: the Radiative stage's products (BRF/HDRF per direction and
//! band, albedo, fabs, ftran, budget) computed from Monte Carlo tallies, with standard errors
//! from the spread of the batch estimates (design.md §5; physics.md §1.4).
//!
//! Every product is a linear functional `F` of the tallies, so its standard error is
//! `SE(F) = √(B/(B−1) Σ_k (F(S_k) − F̄)²)` over the `B` batch summaries `S_k` (each batch holds
//! 1/B of the photons, with weights normalised to the whole run).

use super::engine::{PhotonParams, PhotonResult, sum_standard_error};
use crate::direction::DirectionSet;
use crate::radiative::engine::RadiativeResult;
use crate::radiative::products::RadiativeProducts;
use std::f64::consts::PI;

/// The run description is a field of the products ([`RadiativeProducts::monte_carlo`]).
pub use crate::radiative::products::MonteCarloInfo;

/// SE of a linear functional of the batch summaries.
fn se_of(batches: &[Vec<f64>], f: impl Fn(&[f64]) -> f64) -> f64 {
    let vals: Vec<Vec<f64>> = batches.iter().map(|s| vec![f(s)]).collect();
    sum_standard_error(&vals, 0)
}

/// Builds the products. `view_dir[v]` is the tiling index of view `v` (the engine's peel-off
/// views, in order); `ground_facet[f]` marks DEM facets. Under an atmosphere (`column_tau`: its
/// optical depth per band) `e_dir` is the irradiance at the top of the atmosphere: the per-band
/// products are then those of the bottom of the atmosphere (normalised by the downward
/// irradiance the Monte Carlo found there) and [`RadiativeProducts::toa`] holds the TOA ones.
#[allow(clippy::too_many_arguments)]
pub fn photon_products(
    mut res: PhotonResult,
    params: &PhotonParams,
    dirs: &DirectionSet,
    view_dir: &[usize],
    band_names: &[String],
    area: f64,
    e_dir: &[f64],
    e_diff: &[f64],
    ground_facet: &[bool],
    seconds: f64,
    column_tau: Option<&[f64]>,
) -> RadiativeProducts {
    let nb = res.n_bands;
    let w = res.n_channels;
    let has_sky = res.has_sky;
    let sm = res.summary.clone();
    let batches = res.batch_summaries.clone();
    // Under an atmosphere the scene's source is what came down through its top.
    let toa_source = res.source.clone();
    let e_toa = e_dir.to_vec();
    let e_boa: Vec<f64>;
    let e_dir = if column_tau.is_some() {
        for ch in 0..w {
            res.source[ch] = batches.iter().map(|s| s[sm.boa_down(ch)]).sum();
        }
        e_boa = (0..nb).map(|b| res.source[b] / area).collect();
        &e_boa[..]
    } else {
        e_dir
    };
    let raw = RadiativeResult {
        n_channels: w,
        n_bands: nb,
        has_sky,
        has_thermal: false,
        thermal_sky_source: Vec::new(),
        source: res.source.clone(),
        escaped: res.escaped.clone(),
        images: Vec::new(),
        image_grid: Default::default(),
        launch: Default::default(),
        escaped_per_iteration: Vec::new(),
        absorbed_turbid: res.absorbed_turbid.clone(),
        intercepted_turbid: res.intercepted_turbid.clone(),
        absorbed_facet: res.absorbed_facet.clone(),
        intercepted_facet: res.intercepted_facet.clone(),
        absorbed_ground: res.absorbed_ground.clone(),
        intercepted_ground: res.intercepted_ground.clone(),
        lost: res.lost.clone(),
        // The roulette balance (expectation 0) stands where flux tracking books its
        // unscattered remainder, so the closure identity holds exactly.
        remaining: res.roulette.clone(),
        iterations: 0,
        q: vec![0.0; w],
        converged: true,
        rays: res.photons,
        crossings: res.crossings,
        skipped: res.skipped,
        kernel_seconds: 0.0,
        walk: None,
    };
    let mut p = RadiativeProducts::new(
        raw,
        dirs,
        band_names,
        area,
        e_dir,
        e_diff,
        ground_facet,
        seconds,
    );
    let tiling = dirs.tiling();
    let src = |b: usize| res.source[b] + if has_sky { res.source[nb + b] } else { 0.0 };
    let both = |s: &[f64], idx: &dyn Fn(usize) -> usize, b: usize| {
        s[idx(b)] + if has_sky { s[idx(nb + b)] } else { 0.0 }
    };
    for b in 0..nb {
        let bp = &mut p.bands[b];
        let sb = src(b);
        bp.albedo_se = Some(se_of(&batches, |s| both(s, &|c| sm.escaped(c), b)) / sb);
        bp.fabs_se = Some(se_of(&batches, |s| both(s, &|c| sm.absorbed(c), b)) / sb);
        bp.fabs_ground_se = Some(se_of(&batches, |s| both(s, &|c| sm.absorbed_ground(c), b)) / sb);
        bp.ftran_se = Some(se_of(&batches, |s| both(s, &|c| sm.ground(c), b)) / sb);
        let mut entry = 0;
        for (j, d) in tiling.iter().enumerate() {
            if d.omega.z <= 0.0 {
                continue;
            }
            let e = &mut bp.brf[entry];
            entry += 1;
            let view = view_dir.iter().position(|&x| x == j);
            let (sun_f, tot_f): (f64, f64);
            match view {
                Some(v) => {
                    // Peel-off: BRF = π I_v / (A μ_v E), I_v in W sr⁻¹.
                    let mu = d.omega.z;
                    sun_f = PI / (area * mu * e_dir[b]);
                    tot_f = PI / (area * mu * (e_dir[b] + e_diff[b]));
                    let i_sun = res.peel[v * w + b];
                    let i_sky = if has_sky {
                        res.peel[v * w + nb + b]
                    } else {
                        0.0
                    };
                    e.brf = i_sun * sun_f;
                    if has_sky {
                        e.hdrf = Some((i_sun + i_sky) * tot_f);
                    }
                    e.brf_se = Some(se_of(&batches, |s| s[sm.view(v, b)]) * sun_f);
                    if has_sky {
                        e.hdrf_se = Some(
                            se_of(&batches, |s| s[sm.view(v, b)] + s[sm.view(v, nb + b)]) * tot_f,
                        );
                    }
                    e.estimator = Some("peel-off");
                    let comp = |c: usize| {
                        batches
                            .iter()
                            .map(|s| s[sm.view_component(v, c, b)])
                            .sum::<f64>()
                            * sun_f
                    };
                    e.brf_co_sgl = Some(comp(0));
                    e.brf_uc_sgl = Some(comp(1));
                    e.brf_mlt = Some(comp(2));
                    let cse = |c: usize| se_of(&batches, |s| s[sm.view_component(v, c, b)]) * sun_f;
                    e.brf_components_se = Some([cse(0), cse(1), cse(2)]);
                }
                None => {
                    let denom = area * d.projected_sr;
                    sun_f = PI / (denom * e_dir[b]);
                    tot_f = PI / (denom * (e_dir[b] + e_diff[b]));
                    e.brf_se = Some(se_of(&batches, |s| s[sm.dir(j, b)]) * sun_f);
                    if has_sky {
                        e.hdrf_se = Some(
                            se_of(&batches, |s| s[sm.dir(j, b)] + s[sm.dir(j, nb + b)]) * tot_f,
                        );
                    }
                    e.estimator = Some("escape");
                }
            }
        }
    }
    if let Some(tau) = column_tau {
        let views: Vec<(f64, f64, f64)> = view_dir
            .iter()
            .map(|&j| {
                let d = &tiling[j];
                (d.zenith_deg(), d.azimuth_deg(), d.omega.z)
            })
            .collect();
        p.toa = Some(toa_products(
            &res,
            &toa_source,
            &e_toa,
            area,
            tau,
            &views,
            band_names,
        ));
    }
    let threads = rayon::current_num_threads().max(1) as f64;
    p.solver = "monte-carlo";
    p.launch = None;
    p.iterations = 0;
    p.monte_carlo = Some(MonteCarloInfo {
        photons: res.photons,
        batches: params.batches,
        seed: params.seed,
        sampler: params.sampler.name(),
        events: res.events,
        photons_per_second_per_core: res.photons as f64 / (seconds.max(1e-9) * threads),
        roulette_balance: (0..nb)
            .map(|b| (res.roulette[b] + if has_sky { res.roulette[nb + b] } else { 0.0 }) / src(b))
            .collect(),
        lost: (0..nb)
            .map(|b| (res.lost[b] + if has_sky { res.lost[nb + b] } else { 0.0 }) / src(b))
            .collect(),
    });
    p
}

/// The TOA products per band of a run under an atmosphere (radiative::toa): TOA albedo and
/// reflectance factors `π I_v / (A μ_v E⊥_TOA)` (I_v the peel-off intensity reaching the TOA,
/// W sr⁻¹; A the scene area) with standard errors, absorption per layer and in the scene, BOA
/// irradiance and the energy closure. `source` is the TOA input per channel, `e_toa` the TOA
/// irradiance per band, `views` (zenith °, azimuth °, μ) the peel-off views in order.
fn toa_products(
    res: &PhotonResult,
    source: &[f64],
    e_toa: &[f64],
    area: f64,
    tau: &[f64],
    views: &[(f64, f64, f64)],
    band_names: &[String],
) -> Vec<crate::radiative::toa::ToaBand> {
    use crate::radiative::toa::{ToaBand, ToaBrf};
    let sm = &res.summary;
    let batches = &res.batch_summaries;
    let tot = |i: usize| batches.iter().map(|s| s[i]).sum::<f64>();
    (0..res.n_bands)
        .map(|b| {
            let input = source[b];
            let esc = tot(sm.toa_escaped(b));
            let layers: Vec<f64> = (0..sm.atm_layers)
                .map(|l| tot(sm.atm_absorbed(l, b)))
                .collect();
            let atm_abs: f64 = layers.iter().sum();
            let scene_abs = tot(sm.absorbed(b)) + tot(sm.absorbed_ground(b));
            let lost = tot(sm.atm_lost(b)) + res.lost[b];
            let balance = tot(sm.atm_balance(b)) + res.roulette[b];
            let closure = (1.0 - (esc + atm_abs + scene_abs + lost + balance) / input).abs();
            let brf = views
                .iter()
                .enumerate()
                .map(|(v, &(zen, az, mu))| {
                    let f = PI / (area * mu * e_toa[b]);
                    let brf = tot(sm.toa_view(v, b)) * f;
                    ToaBrf {
                        zenith_deg: zen,
                        azimuth_deg: az,
                        brf,
                        brf_se: se_of(batches, |s| s[sm.toa_view(v, b)]) * f,
                        radiance_w_m2_sr_um: brf * e_toa[b] / PI,
                        boa_sky: tot(sm.boa_sky(v, b)) * f,
                        boa_sky_se: se_of(batches, |s| s[sm.boa_sky(v, b)]) * f,
                    }
                })
                .collect();
            ToaBand {
                band: band_names.get(b).cloned().unwrap_or_default(),
                albedo: esc / input,
                albedo_se: se_of(batches, |s| s[sm.toa_escaped(b)]) / input,
                fabs_atmosphere: atm_abs / input,
                fabs_layers: layers.iter().map(|x| x / input).collect(),
                fabs_scene: scene_abs / input,
                flost: lost / input,
                energy_closure: closure,
                boa_irradiance_w_m2_um: tot(sm.boa_down(b)) / area,
                boa_direct_irradiance_w_m2_um: tot(sm.boa_direct(b)) / area,
                optical_depth: tau[b],
                brf,
            }
        })
        .collect()
}

/// The products of a Monte Carlo thermal run (`T` mode, issue #34; channels `[sun (zero),
/// thermal]`): the flux tracking's thermal products ([`RadiativeProducts::with_thermal`]:
/// radiance and brightness temperature per upward direction, thermal budget), with the
/// radiance of every view direction from the peel-off tallies, `L_v = I_v / (A μ_v)` (I_v in
/// W sr⁻¹ per spectral unit, A the scene area), the escape-counting sector mean
/// `W_j / (A ∫_{ΔΩ_j} μ dΩ)` elsewhere, and their standard errors from the batches.
/// `responses`: the bands' spectral responses (brightness temperatures).
#[allow(clippy::too_many_arguments)]
pub fn thermal_photon_products(
    res: PhotonResult,
    params: &PhotonParams,
    dirs: &DirectionSet,
    view_dir: &[usize],
    band_names: &[String],
    responses: &[crate::physics::spectral::SpectralBand],
    area: f64,
    ground_facet: &[bool],
    seconds: f64,
) -> RadiativeProducts {
    let nb = res.n_bands;
    let w = res.n_channels;
    let zeros = vec![0.0; nb];
    let peel = res.peel.clone();
    let batches = res.batch_summaries.clone();
    let sm = res.summary.clone();
    let (roulette, lost, source) = (res.roulette.clone(), res.lost.clone(), res.source.clone());
    let sky = res.thermal_sky_source.clone();
    let mut p = photon_products(
        res,
        params,
        dirs,
        view_dir,
        band_names,
        area,
        &zeros,
        &zeros,
        ground_facet,
        seconds,
        None,
    );
    p.raw.has_thermal = true;
    p.raw.thermal_sky_source = sky;
    let mut p = p.with_thermal(
        crate::scene::desc::RunMode::T,
        dirs,
        responses,
        area,
        glam::DVec3::Z,
    );
    let tiling = dirs.tiling();
    for b in 0..nb {
        let ch = nb + b;
        let bp = &mut p.bands[b];
        // No reflectance in a T run (its solar fractions are NaN, null in JSON).
        bp.albedo_se = None;
        bp.fabs_se = None;
        bp.fabs_ground_se = None;
        bp.ftran_se = None;
        if let Some(t) = bp.thermal.as_mut() {
            t.exitance_se_w_m2_um = Some(se_of(&batches, |s| s[sm.escaped(ch)]) / area);
        }
        let mut entry = 0;
        for (j, d) in tiling.iter().enumerate() {
            if d.omega.z <= 0.0 {
                continue;
            }
            let Some(e) = bp.radiance.get_mut(entry) else {
                break;
            };
            entry += 1;
            match view_dir.iter().position(|&x| x == j) {
                Some(v) => {
                    let f = 1.0 / (area * d.omega.z);
                    e.radiance_w_m2_sr_um = peel[v * w + ch] * f;
                    e.radiance_se_w_m2_sr_um = Some(se_of(&batches, |s| s[sm.view(v, ch)]) * f);
                    e.brightness_temperature_k = responses.get(b).map_or(0.0, |r| {
                        crate::physics::thermal::band_brightness_temperature(
                            r,
                            e.radiance_w_m2_sr_um,
                        )
                        .unwrap_or(0.0)
                    });
                }
                None => {
                    let f = 1.0 / (area * d.projected_sr);
                    e.radiance_se_w_m2_sr_um = Some(se_of(&batches, |s| s[sm.dir(j, ch)]) * f);
                }
            }
        }
    }
    if let Some(mc) = p.monte_carlo.as_mut() {
        mc.roulette_balance = (0..nb).map(|b| roulette[nb + b] / source[nb + b]).collect();
        mc.lost = (0..nb).map(|b| lost[nb + b] / source[nb + b]).collect();
    }
    p
}

/// The products of a Monte Carlo `R+T` run (issue #34): the solar run's products (`solar`,
/// [`photon_products`]) joined with the thermal run's (`thermal`, [`thermal_photon_products`];
/// independent photon streams), like the flux tracking's
/// ([`RadiativeResult::with_thermal_of`]): per upward direction the total radiance is the
/// thermal one plus the solar one, `HDRF (E_dir + E_diff)/π` (`BRF E_dir/π` without a sky),
/// their standard errors added in quadrature; the thermal budget is the thermal run's.
pub fn join_thermal_products(
    solar: RadiativeProducts,
    thermal: RadiativeProducts,
    e_dir: &[f64],
    e_diff: &[f64],
    responses: &[crate::physics::spectral::SpectralBand],
) -> RadiativeProducts {
    let mut p = solar;
    let raw = std::mem::take(&mut p.raw);
    p.raw = raw.with_thermal_of(thermal.raw.clone());
    p.mode = crate::scene::desc::RunMode::RT;
    for (b, tb) in thermal.bands.iter().enumerate() {
        let e_tot = e_dir[b] + e_diff.get(b).copied().unwrap_or(0.0);
        let radiance = tb
            .radiance
            .iter()
            .zip(&p.bands[b].brf)
            .map(|(t, r)| {
                let (sol, sol_se) = match r.hdrf {
                    Some(h) => (h * e_tot / PI, r.hdrf_se.unwrap_or(0.0) * e_tot / PI),
                    None => (
                        r.brf * e_dir[b] / PI,
                        r.brf_se.unwrap_or(0.0) * e_dir[b] / PI,
                    ),
                };
                let th = t.radiance_w_m2_sr_um;
                let total = th + sol;
                let se = t.radiance_se_w_m2_sr_um.unwrap_or(0.0).hypot(sol_se);
                let mut e = t.clone();
                e.radiance_w_m2_sr_um = total;
                e.radiance_se_w_m2_sr_um = Some(se);
                e.thermal_radiance_w_m2_sr_um = Some(th);
                e.solar_radiance_w_m2_sr_um = Some(sol);
                e.brightness_temperature_k = responses.get(b).map_or(0.0, |r| {
                    crate::physics::thermal::band_brightness_temperature(r, total).unwrap_or(0.0)
                });
                e
            })
            .collect();
        p.bands[b].radiance = radiance;
        p.bands[b].thermal = tb.thermal.clone();
    }
    if let (Some(a), Some(t)) = (p.monte_carlo.as_mut(), thermal.monte_carlo.as_ref()) {
        a.photons += t.photons;
        a.events += t.events;
    }
    p.tracking_seconds += thermal.tracking_seconds;
    p
}
