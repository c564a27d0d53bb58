//! Maket products: `maket.json` (the `MaketReport`), `lai.exr` (leaf area index per column, one
//! channel per turbid material plus `total`), `dsm.exr` (digital surface model: highest object
//! point per column, metres), `density.csv` (non-empty turbid cells: i, j, k, material,
//! density_m2_m3); with a scene georeference also `lai.tif`/`dsm.tif` and their ENVI pairs
//! ([`crate::output::geo`]).

use crate::io::atomic::write_atomic;
use crate::io::exr_out::{ExrLayer, write_exr_layers};
use crate::resources::facets::FacetStore;
use crate::resources::grid::{CellGrid, GridSpec};
use crate::resources::maket_report::MaketReport;
use crate::resources::materials::Materials;
use std::fmt::Write as _;

/// Leaf area index map per turbid material (m² m⁻²), indexed `i + nx·j`.
pub fn lai_maps(spec: &GridSpec, grid: &CellGrid, n_materials: usize) -> Vec<Vec<f64>> {
    let (nx, ny) = (spec.n[0], spec.n[1]);
    let mut maps = vec![vec![0.0; nx * ny]; n_materials];
    for c in 0..spec.n_cells() {
        let col = c % (nx * ny);
        for e in grid.turbid_of(c) {
            maps[e.material as usize][col] += e.density as f64 * spec.cell.z;
        }
    }
    maps
}

/// Digital surface model: highest point of any facet or non-empty turbid cell per column
/// (metres, absolute altitude); the grid bottom where a column is empty.
pub fn dsm(spec: &GridSpec, grid: &CellGrid, facets: &FacetStore) -> Vec<f64> {
    let (nx, ny) = (spec.n[0], spec.n[1]);
    let mut h = vec![spec.origin.z; nx * ny];
    for c in 0..spec.n_cells() {
        let [i, j, k] = spec.ijk(c);
        let col = i + nx * j;
        if !grid.turbid_of(c).is_empty() {
            h[col] = h[col].max(spec.origin.z + (k + 1) as f64 * spec.cell.z);
        }
        if !grid.facet_start.is_empty() {
            let (lo, hi) = spec.cell_box(i as i64, j as i64, k as i64);
            for &f in grid.facets_of(c) {
                // Highest point of the facet inside this column.
                let poly =
                    crate::geometry::triangle::clip_to_box(&facets.facets[f as usize].v, lo, hi);
                for v in poly {
                    h[col] = h[col].max(v.z);
                }
            }
        }
    }
    h
}

/// Writes `maket.json`, `lai.exr`, `dsm.exr` and `density.csv` into `dir` (atomic writes), and
/// with a georeference `lai.tif`, `lai.dat`, `lai.hdr`, `dsm.tif`, `dsm.dat`, `dsm.hdr`.
#[allow(clippy::too_many_arguments)]
pub fn write_maket(
    dir: &std::path::Path,
    spec: &GridSpec,
    grid: &CellGrid,
    facets: &FacetStore,
    mats: &Materials,
    report: &MaketReport,
    georef: Option<&crate::scene::georef::Georeference>,
) -> Result<(), String> {
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("{}: cannot create output folder: {e}", dir.display()))?;
    let json = serde_json::to_string_pretty(report).map_err(|e| e.to_string())?;
    write_atomic(&dir.join("maket.json"), json.as_bytes())?;
    let (nx, ny) = (spec.n[0], spec.n[1]);
    let maps = lai_maps(spec, grid, mats.list.len());
    let mut channels = Vec::new();
    let mut total = vec![0.0; nx * ny];
    for (m, map) in maps.iter().enumerate() {
        if mats.list[m].is_turbid() {
            for (t, v) in total.iter_mut().zip(map) {
                *t += v;
            }
            channels.push((format!("lai.{}", mats.list[m].name), map.clone()));
        }
    }
    channels.push(("lai.total".to_string(), total));
    let pixels = crate::output::geo::PixelGrid {
        n: (nx, ny),
        pixel_m: (spec.cell.x, spec.cell.y),
        origin_m: (spec.origin.x, spec.origin.y),
    };
    let geo_raster = |stem: &str, channels: &[(String, Vec<f64>)]| -> Result<(), String> {
        let Some(g) = georef else { return Ok(()) };
        let bands: Vec<crate::io::geotiff::TiffBand> = channels
            .iter()
            .map(|(name, v)| crate::io::geotiff::TiffBand {
                name: name.clone(),
                wavelength_nm: None,
                values: v,
            })
            .collect();
        crate::output::geo::write_geo_raster(&dir.join(stem), &pixels, &bands, g)
    };
    geo_raster("lai", &channels)?;
    write_exr_layers(
        &dir.join("lai.exr"),
        nx,
        ny,
        &[ExrLayer {
            name: "lai".into(),
            channels,
        }],
    )?;
    let d = vec![("dsm.altitude_m".to_string(), dsm(spec, grid, facets))];
    geo_raster("dsm", &d)?;
    write_exr_layers(
        &dir.join("dsm.exr"),
        nx,
        ny,
        &[ExrLayer {
            name: "dsm".into(),
            channels: d,
        }],
    )?;
    let mut csv = String::from("i,j,k,material,density_m2_m3\n");
    for c in 0..spec.n_cells() {
        let [i, j, k] = spec.ijk(c);
        for e in grid.turbid_of(c) {
            let _ = writeln!(
                csv,
                "{i},{j},{k},{},{}",
                mats.list[e.material as usize].name, e.density
            );
        }
    }
    write_atomic(&dir.join("density.csv"), csv.as_bytes())?;
    Ok(())
}
