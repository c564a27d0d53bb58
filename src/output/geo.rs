//! Georeferenced copies of the image products (issue #37): beside each EXR raster, a GeoTIFF
//! (`NAME.tif`: one `f32` band per channel, the scene's CRS, pixel size and tie point or model
//! transformation, band names and wavelengths in `GDAL_METADATA`; OGC GeoTIFF 1.1) and an ENVI
//! pair (`NAME.dat` band-sequential `f32` + `NAME.hdr` with `map info`, `coordinate system
//! string`, `band names`, `wavelength`; ENVI Header Format). Written only for scenes with a
//! `georeference`; every file atomically ([`crate::io::atomic`]).

use crate::io::envi::{with_suffix, write_envi};
use crate::io::geotiff::{TiffBand, write_geotiff};
use crate::scene::georef::Georeference;
use std::path::Path;

/// A product raster's pixel grid in scene coordinates: `n` pixels of `pixel_m`, the pixel
/// (0, 0) (lowest x, lowest y) with its lower-left corner at `origin_m`.
#[derive(Debug, Clone, Copy)]
pub struct PixelGrid {
    /// Pixels along x and y.
    pub n: (usize, usize),
    /// Pixel size along x and y, m.
    pub pixel_m: (f64, f64),
    /// Lower-left corner of the raster, scene metres.
    pub origin_m: (f64, f64),
}

/// Writes `stem.tif`, `stem.dat` and `stem.hdr` for `bands` (values indexed `i + nx·j`, j = 0
/// at the lowest y, as the EXR writer takes them). `stem` has no extension.
pub fn write_geo_raster(
    stem: &Path,
    grid: &PixelGrid,
    bands: &[TiffBand],
    geo: &Georeference,
) -> Result<(), String> {
    let (nx, ny) = grid.n;
    let (px, py) = grid.pixel_m;
    let y_top = grid.origin_m.1 + ny as f64 * py;
    let place = geo.placement(grid.origin_m.0, y_top, px, py);
    write_geotiff(&with_suffix(stem, "tif"), nx, ny, bands, &place)?;
    let description = stem
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    write_envi(
        stem,
        &format!("lumenscape {description}"),
        nx,
        ny,
        bands,
        &place,
        Some(&geo.crs.wkt),
    )
}
