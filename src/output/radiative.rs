//! Passive-solver products (flux tracking or Monte Carlo): `summary.json` (per band albedo,
//! fabs, ftran, energy closure, BRF/HDRF per upward direction, standard errors for Monte Carlo),
//! `brf.csv`, the radiative budget (`budget/cells.csv`, `budget/layers.csv`,
//! `budget/elements.csv`) and the orthographic images (`images/view_*.exr` with one channel per
//! band, PNG quick-looks).

use crate::io::atomic::write_atomic;
use crate::io::exr_out::{ExrLayer, ExrMeta, write_exr_layers_with};
use crate::resources::facets::FacetStore;
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::materials::Materials;
use std::fmt::Write as _;

/// Writes `summary.json`, `brf.csv`, the radiative budget (`budget/`) and the orthographic
/// images (`images/`) of a passive solver's products, and the camera images of `sensors`
/// (`sensors/`), into `dir` (atomic writes); `wants` says which of `brf.csv`, `budget`,
/// `images` and `sensors` to write (`summary.json` always).
#[allow(clippy::too_many_arguments)]
pub fn write_radiative(
    dir: &std::path::Path,
    p: &crate::radiative::products::RadiativeProducts,
    info: &crate::resources::scene::SceneInfo,
    settings: &crate::resources::tracking::RadiativeSettings,
    dirs: &crate::resources::tracking::Directions,
    spec: &GridSpec,
    grid: &CellGrid,
    facets: &FacetStore,
    mats: &Materials,
    memory: Option<&crate::resources::memory::MemoryPlan>,
    sensors: Option<&crate::photon::sensors::SensorProducts>,
    wants: &dyn Fn(&str) -> bool,
) -> Result<(), String> {
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("{}: cannot create output folder: {e}", dir.display()))?;
    if wants("brf.csv") {
        write_brf_csv(dir, p)?;
    }
    // The budget files are solar (per unit incident sun and sky power): none in a `T` run.
    if wants("budget") && p.mode.solar() {
        std::fs::create_dir_all(dir.join("budget"))
            .map_err(|e| format!("{}: cannot create output folder: {e}", dir.display()))?;
        write_budget(dir, p, info, spec, grid, facets, mats)?;
    }
    if wants("images") {
        write_images(dir, p, info, dirs, spec)?;
    }
    if let Some(s) = sensors
        && wants("sensors")
    {
        crate::output::sensors::write_sensors(dir, s)?;
    }
    // Last, so that the measured peak it records covers the other products' writing.
    write_summary(dir, p, info, settings, dirs, memory, sensors)?;
    Ok(())
}

/// `summary.json`: scene, settings (preset, tracking knobs, the instruction set), solver, the
/// walk that ran (kernel, precision, lanes), launch
/// grid, images, iterations and convergence, and per band albedo, fabs, ftran, energy closure
/// and the BRF/HDRF list, and the memory estimate with the measured peak (docs/guide/products.md).
fn write_summary(
    dir: &std::path::Path,
    p: &crate::radiative::products::RadiativeProducts,
    info: &crate::resources::scene::SceneInfo,
    settings: &crate::resources::tracking::RadiativeSettings,
    dirs: &crate::resources::tracking::Directions,
    memory: Option<&crate::resources::memory::MemoryPlan>,
    sensors: Option<&crate::photon::sensors::SensorProducts>,
) -> Result<(), String> {
    let mut summary = serde_json::json!({
        "schema_version": 1,
        "lumenscape_version": env!("CARGO_PKG_VERSION"),
        "scene": info.name,
        "scene_file": info.source.display().to_string(),
        "settings": {
            "preset": format!("{:?}", settings.preset),
            "tracking": settings.tracking,
            "per_direction_stores": settings.per_direction_stores,
            "image_oversampling": settings.image_oversampling,
            // What the walks ran on (products of runs with the same batch lanes are the same
            // bits; 8 and 4 lanes differ in the last bits, 16 (single-precision geometry) from
            // those by ~3e-7, see `TrackingParams::kernel_isa` and `batch_f32`).
            "instruction_set": crate::radiative::engine::instruction_set(settings.tracking.kernel_isa),
            "batch_lanes": if settings.tracking.batch_walk {
                crate::radiative::engine::batch_lanes(
                    settings.tracking.kernel_isa,
                    settings.tracking.batch_f32,
                )
            } else {
                1
            },
            "directions": dirs.set.tiling().len(),
            "sectors": dirs.n_sectors,
            "sun_zenith_deg": info.illumination.sun_zenith_deg,
            "sun_azimuth_deg": info.illumination.sun_azimuth_deg,
        },
        "solver": p.solver,
        // The walk that traced the flux-tracking rays (null for Monte Carlo): products of runs
        // with the same walk are the same bits on any CPU (docs/guide/products.md).
        "walk": p.raw.walk,
        "monte_carlo": p.monte_carlo,
        "launch": p.launch,
        "images": (!p.raw.images.is_empty()).then_some(p.raw.image_grid),
        "iterations": p.iterations,
        "converged": p.converged,
        "extrapolation_ratio": p.extrapolation_ratio,
        "rays": p.rays,
        "cell_crossings": p.crossings,
        "tracking_seconds": p.tracking_seconds,
        "bands": p.bands,
    });
    if let Some(s) = sensors {
        summary["sensors"] =
            s.0.iter()
                .map(crate::output::sensors::summary_entry)
                .collect();
    }
    if p.mode.thermal() {
        // The run mode of a thermal run (`T`, `R+T`; issue #34); absent in solar-only runs.
        summary["mode"] = serde_json::json!(p.mode.name());
    }
    if let Some(m) = memory {
        summary["memory"] = m.record();
    }
    if let Some(t) = &p.toa {
        summary["toa"] = serde_json::to_value(t).map_err(|e| e.to_string())?;
    }
    write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)
            .map_err(|e| e.to_string())?
            .as_bytes(),
    )?;
    Ok(())
}

/// `brf.csv`: one row per band and upward direction (zenith, azimuth, solid angle, kind, BRF,
/// HDRF; Monte Carlo adds the standard errors and the estimator).
fn write_brf_csv(
    dir: &std::path::Path,
    p: &crate::radiative::products::RadiativeProducts,
) -> Result<(), String> {
    // Monte Carlo runs add standard errors and the estimator of each value.
    let mc = p.monte_carlo.is_some();
    let mut csv = String::from("band,zenith_deg,azimuth_deg,solid_angle_sr,kind,brf,hdrf");
    csv.push_str(if mc {
        ",brf_se,hdrf_se,estimator\n"
    } else {
        "\n"
    });
    let opt = |x: Option<f64>| x.map_or(String::new(), |h| format!("{h:.8}"));
    for b in &p.bands {
        for e in &b.brf {
            let _ = write!(
                csv,
                "{},{:.6},{:.6},{:.6e},{},{:.8},{}",
                b.band,
                e.zenith_deg,
                e.azimuth_deg,
                e.solid_angle_sr,
                e.kind,
                e.brf,
                opt(e.hdrf)
            );
            if mc {
                let _ = write!(
                    csv,
                    ",{},{},{}",
                    opt(e.brf_se),
                    opt(e.hdrf_se),
                    e.estimator.unwrap_or("")
                );
            }
            csv.push('\n');
        }
    }
    write_atomic(&dir.join("brf.csv"), csv.as_bytes())?;
    Ok(())
}

/// The radiative budget: `budget/cells.csv` (absorbed and intercepted power per cell and band,
/// per unit incident power on the cell's horizontal area, physics.md §6.7), `budget/layers.csv`
/// (per horizontal layer) and `budget/elements.csv` (per element type and material), both per
/// unit incident power on the scene.
fn write_budget(
    dir: &std::path::Path,
    p: &crate::radiative::products::RadiativeProducts,
    info: &crate::resources::scene::SceneInfo,
    spec: &GridSpec,
    grid: &CellGrid,
    facets: &FacetStore,
    mats: &Materials,
) -> Result<(), String> {
    // Radiative budget per cell: absorbed and intercepted power per band, normalised by the
    // incident power on the cell's horizontal area (physics.md §6.7 [rec]).
    let raw = &p.raw;
    let nb = raw.n_bands;
    let col_area = spec.cell.x * spec.cell.y;
    let scene_area = col_area * (spec.n[0] * spec.n[1]) as f64;
    let src_per_m2: Vec<f64> = (0..nb)
        .map(|b| (raw.source[b] + if raw.has_sky { raw.source[nb + b] } else { 0.0 }) / scene_area)
        .collect();
    let bud = Budget {
        raw,
        info,
        spec,
        grid,
        facets,
        col_area,
        scene_area,
        src_per_m2,
    };
    let (cells, layers) = bud.cells_csv();
    write_atomic(&dir.join("budget/cells.csv"), cells.as_bytes())?;
    let lay = bud.layers_csv(&layers);
    write_atomic(&dir.join("budget/layers.csv"), lay.as_bytes())?;
    let els = bud.elements_csv(mats);
    write_atomic(&dir.join("budget/elements.csv"), els.as_bytes())?;
    Ok(())
}

/// What the steps of [`write_budget`] share: the products, the grid, the cell and scene areas
/// and the incident power per m² per band (sun + sky).
struct Budget<'a> {
    raw: &'a crate::radiative::engine::RadiativeResult,
    info: &'a crate::resources::scene::SceneInfo,
    spec: &'a GridSpec,
    grid: &'a CellGrid,
    facets: &'a FacetStore,
    col_area: f64,
    scene_area: f64,
    src_per_m2: Vec<f64>,
}

impl Budget<'_> {
    /// Element `e`'s power of band `b` in the per-channel array `v`: sun plus sky channel.
    fn band_sum(&self, v: &[f64], e: usize, b: usize) -> f64 {
        let (w, nb) = (self.raw.n_channels, self.raw.n_bands);
        v[e * w + b]
            + if self.raw.has_sky {
                v[e * w + nb + b]
            } else {
                0.0
            }
    }

    /// Step of [`write_budget`]: the share of each facet reference (`grid.facet_ids`) in its
    /// facet's budget — its area inside the cell over the facet's area inside all its cells
    /// (exact clipping; normalised so a facet lying in a cell face is not counted twice).
    fn facet_ref_shares(&self) -> Vec<f64> {
        let (spec, grid, facets) = (self.spec, self.grid, self.facets);
        let mut ref_share = vec![0.0; grid.facet_ids.len()];
        let mut total = vec![0.0; facets.facets.len()];
        for c in 0..spec.n_cells() {
            let [i, j, k] = spec.ijk(c);
            let (lo, hi) = spec.cell_box(i as i64, j as i64, k as i64);
            for r in grid.facet_start[c] as usize..grid.facet_start[c + 1] as usize {
                let f = grid.facet_ids[r] as usize;
                let a = crate::geometry::triangle::polygon_area(
                    &crate::geometry::triangle::clip_to_box(&facets.facets[f].v, lo, hi),
                );
                ref_share[r] = a;
                total[f] += a;
            }
        }
        for r in 0..grid.facet_ids.len() {
            let t = total[grid.facet_ids[r] as usize];
            ref_share[r] = if t > 0.0 { ref_share[r] / t } else { 0.0 };
        }
        ref_share
    }

    /// Step of [`write_budget`]: `budget/cells.csv` (per cell and band, per unit incident power
    /// on the cell's horizontal area) and the per-layer sums (per unit incident power on the
    /// scene).
    fn cells_csv(&self) -> (String, Vec<Vec<[f64; 2]>>) {
        let (raw, info, spec, grid) = (self.raw, self.info, self.spec, self.grid);
        let nb = raw.n_bands;
        let (col_area, scene_area, src_per_m2) = (self.col_area, self.scene_area, &self.src_per_m2);
        let band_sum = |v: &[f64], e: usize, b: usize| self.band_sum(v, e, b);
        let mut cells = String::from("i,j,k,band,fabs,fintercepted\n");
        let mut layers = vec![vec![[0.0f64; 2]; nb]; spec.n[2]];
        // A facet's budget is shared among the cells it crosses in proportion to its area
        // inside each.
        let has_facets = !grid.facet_start.is_empty() && !self.facets.facets.is_empty();
        let ref_share = if has_facets {
            self.facet_ref_shares()
        } else {
            Vec::new()
        };
        for c in 0..spec.n_cells() {
            let [i, j, k] = spec.ijk(c);
            let mut a = vec![0.0; nb];
            let mut x = vec![0.0; nb];
            for e in grid.turbid_start[c] as usize..grid.turbid_start[c + 1] as usize {
                for b in 0..nb {
                    a[b] += band_sum(&raw.absorbed_turbid, e, b);
                    x[b] += band_sum(&raw.intercepted_turbid, e, b);
                }
            }
            if has_facets {
                for r in grid.facet_start[c] as usize..grid.facet_start[c + 1] as usize {
                    let f = grid.facet_ids[r] as usize;
                    for b in 0..nb {
                        a[b] += ref_share[r] * band_sum(&raw.absorbed_facet, f, b);
                        x[b] += ref_share[r] * band_sum(&raw.intercepted_facet, f, b);
                    }
                }
            }
            if k == 0 && !raw.absorbed_ground.is_empty() {
                // The flat ground belongs to the bottom cell of its column.
                let col = i + spec.n[0] * j;
                for b in 0..nb {
                    a[b] += band_sum(&raw.absorbed_ground, col, b);
                    x[b] += band_sum(&raw.intercepted_ground, col, b);
                }
            }
            for b in 0..nb {
                if a[b] != 0.0 || x[b] != 0.0 {
                    let norm = src_per_m2[b] * col_area;
                    let _ = writeln!(
                        cells,
                        "{i},{j},{k},{},{:.8e},{:.8e}",
                        info.bands[b].name,
                        a[b] / norm,
                        x[b] / norm
                    );
                    layers[k][b][0] += a[b] / (src_per_m2[b] * scene_area);
                    layers[k][b][1] += x[b] / (src_per_m2[b] * scene_area);
                }
            }
        }
        (cells, layers)
    }

    /// Step of [`write_budget`]: `budget/layers.csv` from the per-layer sums.
    fn layers_csv(&self, layers: &[Vec<[f64; 2]>]) -> String {
        let (info, spec) = (self.info, self.spec);
        let mut lay = String::from("k,z_bottom_m,z_top_m,band,fabs,fintercepted\n");
        for (k, l) in layers.iter().enumerate() {
            for (b, v) in l.iter().enumerate() {
                let z0 = spec.origin.z + k as f64 * spec.cell.z;
                let _ = writeln!(
                    lay,
                    "{k},{z0:.4},{:.4},{},{:.8e},{:.8e}",
                    z0 + spec.cell.z,
                    info.bands[b].name,
                    v[0],
                    v[1]
                );
            }
        }
        lay
    }

    /// Step of [`write_budget`]: `budget/elements.csv` (per element type and material, per unit
    /// incident power on the scene).
    fn elements_csv(&self, mats: &Materials) -> String {
        let (raw, info, spec, grid, facets) =
            (self.raw, self.info, self.spec, self.grid, self.facets);
        let nb = raw.n_bands;
        let (scene_area, src_per_m2) = (self.scene_area, &self.src_per_m2);
        let band_sum = |v: &[f64], e: usize, b: usize| self.band_sum(v, e, b);
        let mut el: std::collections::BTreeMap<(String, String), Vec<[f64; 2]>> =
            Default::default();
        for (e, t) in grid.turbid.iter().enumerate() {
            let v = el
                .entry(("turbid".into(), mats.list[t.material as usize].name.clone()))
                .or_insert_with(|| vec![[0.0; 2]; nb]);
            for b in 0..nb {
                v[b][0] += band_sum(&raw.absorbed_turbid, e, b);
                v[b][1] += band_sum(&raw.intercepted_turbid, e, b);
            }
        }
        for (fi, f) in facets.facets.iter().enumerate() {
            let v = el
                .entry((
                    format!("{:?}", f.kind).to_lowercase(),
                    mats.list[f.material as usize].name.clone(),
                ))
                .or_insert_with(|| vec![[0.0; 2]; nb]);
            for b in 0..nb {
                v[b][0] += band_sum(&raw.absorbed_facet, fi, b);
                v[b][1] += band_sum(&raw.intercepted_facet, fi, b);
            }
        }
        let n_cols = spec.n[0] * spec.n[1];
        if raw.absorbed_ground.iter().any(|&v| v != 0.0) {
            let v = el
                .entry(("ground".into(), "flat ground".into()))
                .or_insert_with(|| vec![[0.0; 2]; nb]);
            for c in 0..n_cols {
                for b in 0..nb {
                    v[b][0] += band_sum(&raw.absorbed_ground, c, b);
                    v[b][1] += band_sum(&raw.intercepted_ground, c, b);
                }
            }
        }
        let mut els = String::from("element,material,band,fabs,fintercepted\n");
        for ((kind, m), v) in &el {
            for (b, x) in v.iter().enumerate() {
                let norm = src_per_m2[b] * scene_area;
                let _ = writeln!(
                    els,
                    "{kind},{m},{},{:.8e},{:.8e}",
                    info.bands[b].name,
                    x[0] / norm,
                    x[1] / norm
                );
            }
        }
        els
    }
}

/// Orthographic images (DART 5 paper §3.2, §5; physics.md §6.6, §8.1): one multi-channel EXR
/// per exact view direction, `images/view_<zenith>_<azimuth>.exr`, channels `brf.<band>` (and
/// `hdrf.<band>` with sky light), pixels of (Δx/η, Δy/η) (η = `radiative.image_oversampling`;
/// [`crate::radiative::images`]); the BRF of pixel (i, j) is π W_ij / (A_pixel ∫_{ΔΩ}|μ|dΩ E_dir).
/// The image mean equals the direction's BRF. The EXR header carries the pixel size
/// (`pixel_size_x_m`, `pixel_size_y_m`, `pixelAspectRatio`), η (`image_oversampling`), the
/// scene origin and the view direction. A PNG quick-look of the first band (linear grey scale
/// from 0 to the image maximum) goes alongside, and with a scene georeference a GeoTIFF and an
/// ENVI pair of the same values ([`crate::output::geo`]: every `brf` band, then every `hdrf`
/// band, with the band names and wavelengths).
fn write_images(
    dir: &std::path::Path,
    p: &crate::radiative::products::RadiativeProducts,
    info: &crate::resources::scene::SceneInfo,
    dirs: &crate::resources::tracking::Directions,
    spec: &GridSpec,
) -> Result<(), String> {
    let raw = &p.raw;
    let (w, nb) = (raw.n_channels, raw.n_bands);
    let ig = raw.image_grid;
    let (nx, ny) = ig.n;
    let npx = ig.pixels();
    if raw.images.is_empty() {
        return Ok(());
    }
    std::fs::create_dir_all(dir.join("images"))
        .map_err(|e| format!("{}: cannot create images folder: {e}", dir.display()))?;
    let a_px = ig.pixel_m.0 * ig.pixel_m.1;
    let area = spec.n[0] as f64 * spec.cell.x * spec.n[1] as f64 * spec.cell.y;
    let e_dir: Vec<f64> = (0..nb).map(|b| raw.source[b] / area).collect();
    let e_diff: Vec<f64> = (0..nb)
        .map(|b| {
            if raw.has_sky {
                raw.source[nb + b] / area
            } else {
                0.0
            }
        })
        .collect();
    let mut img = 0usize;
    for d in dirs.set.tiling() {
        if !(matches!(d.kind, crate::direction::DirectionKind::Exact { .. }) && d.omega.z > 0.0) {
            continue;
        }
        let mut channels: Vec<(String, Vec<f64>)> = Vec::new();
        let solar = p.mode.solar();
        for b in 0..nb.min(if solar { nb } else { 0 }) {
            let mut brf = vec![0.0; npx];
            let mut hdrf = vec![0.0; npx];
            for px in 0..npx {
                let base = (img * npx + px) * w;
                let sun = raw.images[base + b];
                let sky = if raw.has_sky {
                    raw.images[base + nb + b]
                } else {
                    0.0
                };
                let denom = a_px * d.projected_sr;
                brf[px] = if e_dir[b] > 0.0 {
                    std::f64::consts::PI * sun / (denom * e_dir[b])
                } else {
                    0.0
                };
                hdrf[px] = std::f64::consts::PI * (sun + sky) / (denom * (e_dir[b] + e_diff[b]));
            }
            if b == 0 {
                let name = format!("view_{:05.1}_{:05.1}", d.zenith_deg(), d.azimuth_deg());
                write_png(
                    &dir.join("images").join(format!("{name}.png")),
                    nx,
                    ny,
                    &brf,
                )?;
            }
            channels.push((format!("brf.{:02}_{}", b, info.bands[b].name), brf));
            if raw.has_sky {
                channels.push((format!("hdrf.{:02}_{}", b, info.bands[b].name), hdrf));
            }
        }
        if raw.has_thermal {
            thermal_image_channels(raw, img, d, info, spec, &mut channels)?;
            if !solar {
                let name = format!("view_{:05.1}_{:05.1}", d.zenith_deg(), d.azimuth_deg());
                let bt = &channels[1].1;
                write_png(&dir.join("images").join(format!("{name}.png")), nx, ny, bt)?;
            }
        }
        let name = format!("view_{:05.1}_{:05.1}", d.zenith_deg(), d.azimuth_deg());
        if let Some(g) = &info.georeference {
            let mut bands: Vec<crate::io::geotiff::TiffBand> = Vec::new();
            for kind in ["brf.", "hdrf.", "radiance.", "bt."] {
                for (cname, v) in channels.iter() {
                    if cname.starts_with(kind) {
                        // Channel names are `<kind><band:02>_<name>`.
                        let b: usize = cname[kind.len()..kind.len() + 2].parse().unwrap_or(0);
                        bands.push(crate::io::geotiff::TiffBand {
                            name: cname.clone(),
                            wavelength_nm: Some(info.bands[b].wavelength_nm),
                            values: v,
                        });
                    }
                }
            }
            let grid = crate::output::geo::PixelGrid {
                n: (nx, ny),
                pixel_m: ig.pixel_m,
                origin_m: (spec.origin.x, spec.origin.y),
            };
            crate::output::geo::write_geo_raster(
                &dir.join("images").join(&name),
                &grid,
                &bands,
                g,
            )?;
        }
        write_exr_layers_with(
            &dir.join("images").join(format!("{name}.exr")),
            nx,
            ny,
            &[ExrLayer {
                name: "reflectance".into(),
                channels,
            }],
            &ExrMeta {
                pixel_size_m: Some(ig.pixel_m),
                values: vec![
                    ("image_oversampling".into(), ig.oversampling as f64),
                    ("origin_x_m".into(), spec.origin.x),
                    ("origin_y_m".into(), spec.origin.y),
                    ("view_zenith_deg".into(), d.zenith_deg()),
                    ("view_azimuth_deg".into(), d.azimuth_deg()),
                ],
            },
        )?;
        img += 1;
    }
    Ok(())
}

/// 8-bit grey PNG of `v` (indexed `i + nx·j`, +y up), scaled linearly from 0 to its maximum.
/// Step of [`write_images`] in a `T` or `R+T` run (issue #34): per band the radiance of each
/// pixel (thermal plus, in `R+T`, solar; W m⁻² sr⁻¹ µm⁻¹, over the pixel's area as the
/// summary's radiances: [`crate::radiative::products::radiance_area`]) and its brightness
/// temperature (K), channels `radiance.<band>` and `bt.<band>`.
fn thermal_image_channels(
    raw: &crate::radiative::engine::RadiativeResult,
    img: usize,
    d: &crate::direction::Direction,
    info: &crate::resources::scene::SceneInfo,
    spec: &GridSpec,
    channels: &mut Vec<(String, Vec<f64>)>,
) -> Result<(), String> {
    let (w, nb) = (raw.n_channels, raw.n_bands);
    let ig = raw.image_grid;
    let npx = ig.pixels();
    let (ox, oy) = spec.topography_offset;
    let normal = glam::DVec3::new(-ox / info.size.0, -oy / info.size.1, 1.0).normalize();
    let denom = crate::radiative::products::radiance_area(ig.pixel_m.0 * ig.pixel_m.1, normal, d);
    for b in 0..nb {
        let mut rad = vec![0.0; npx];
        let mut bt = vec![0.0; npx];
        for px in 0..npx {
            let base = (img * npx + px) * w;
            let total: f64 = (0..w)
                .filter(|ch| ch % nb == b)
                .map(|ch| raw.images[base + ch])
                .sum();
            rad[px] = total / denom;
            bt[px] = crate::physics::thermal::band_brightness_temperature(
                &info.band_responses[b],
                rad[px],
            )
            .map_err(|e| format!("band {}: {e}", info.bands[b].name))?;
        }
        channels.push((format!("radiance.{:02}_{}", b, info.bands[b].name), rad));
        channels.push((format!("bt.{:02}_{}", b, info.bands[b].name), bt));
    }
    Ok(())
}

pub(crate) fn write_png(
    path: &std::path::Path,
    nx: usize,
    ny: usize,
    v: &[f64],
) -> Result<(), String> {
    let max = v.iter().cloned().fold(0.0, f64::max).max(1e-300);
    let mut data = vec![0u8; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            data[i + nx * (ny - 1 - j)] =
                (255.0 * (v[i + nx * j] / max).clamp(0.0, 1.0)).round() as u8;
        }
    }
    let mut buf = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut buf, nx as u32, ny as u32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        let mut wr = enc
            .write_header()
            .map_err(|e| format!("{}: {e}", path.display()))?;
        wr.write_image_data(&data)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    write_atomic(path, &buf)
}
