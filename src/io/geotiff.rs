//! GeoTIFF rasters: a writer of multi-band `f32` products with their map georeference and band
//! metadata, and a reader of single-band elevation rasters (DEMs).
//!
//! Format sources: TIFF 6.0 (Adobe 1992: baseline tags, `PlanarConfiguration`, `SampleFormat`);
//! OGC GeoTIFF Standard 1.1 (OGC 19-008r4, 2019): `ModelPixelScaleTag` 33550,
//! `ModelTiepointTag` 33922, `ModelTransformationTag` 34264 (§7.1.2, Annex B), the
//! `GeoKeyDirectoryTag` 34735 with `GeoAsciiParamsTag` 34737 (§7.1.3), and the keys
//! `GTModelTypeGeoKey` 1024, `GTRasterTypeGeoKey` 1025, `GTCitationGeoKey` 1026,
//! `ProjectedCRSGeoKey` 3072, `ProjectedCitationGeoKey` 3073, `ProjLinearUnitsGeoKey` 3076
//! (§7.4); GDAL's private tags `GDAL_METADATA` 42112 (band descriptions and wavelengths as XML)
//! and `GDAL_NODATA` 42113 (the no-data value as text). The TIFF container is written and read
//! by the `tiff` crate (image-rs; pure Rust).

use crate::io::atomic::write_atomic;
use std::io::Cursor;
use std::path::Path;
use tiff::tags::Tag;

/// `GDAL_METADATA` (XML band metadata; GDAL's private tag).
pub const TAG_GDAL_METADATA: u16 = 42112;
/// `GDAL_NODATA` (the no-data value as ASCII text; GDAL's private tag).
pub const TAG_GDAL_NODATA: u16 = 42113;
/// `GTModelTypeGeoKey` (OGC GeoTIFF 1.1 §7.4.1): 1 = projected, 2 = geographic.
pub const KEY_MODEL_TYPE: u16 = 1024;
/// `GTRasterTypeGeoKey` (§7.4.2): 1 = PixelIsArea, 2 = PixelIsPoint.
pub const KEY_RASTER_TYPE: u16 = 1025;
/// `GTCitationGeoKey` (§7.4.3, ASCII).
pub const KEY_CITATION: u16 = 1026;
/// `ProjectedCRSGeoKey` (§7.4.8): an EPSG projected CRS code, 32767 = user-defined.
pub const KEY_PROJECTED_CRS: u16 = 3072;
/// `ProjectedCitationGeoKey` (§7.4.8, ASCII).
pub const KEY_PROJECTED_CITATION: u16 = 3073;
/// `ProjLinearUnitsGeoKey` (§7.4.10): 9001 = metre.
pub const KEY_LINEAR_UNITS: u16 = 3076;
/// The "user-defined" key value (§7.4).
pub const USER_DEFINED: u16 = 32767;

/// The coordinate reference system written into a product.
#[derive(Debug, Clone, PartialEq)]
pub enum TiffCrs {
    /// An EPSG projected CRS code (`ProjectedCRSGeoKey`).
    Epsg(u16),
    /// A user-defined projected CRS in metres: its name (`GTCitationGeoKey`) and WKT
    /// (`ProjectedCitationGeoKey` as `ESRI PE String = <wkt>`, the form GDAL reads back).
    UserDefined {
        /// The CRS name.
        name: String,
        /// The WKT definition.
        wkt: String,
    },
}

/// Where a product's pixels lie on the map: the affine transform of GDAL's convention from
/// pixel corner (column c, row r; row 0 at the top) to map coordinates,
/// `E = t[0] + c·t[1] + r·t[2]`, `N = t[3] + c·t[4] + r·t[5]` (metres).
#[derive(Debug, Clone, PartialEq)]
pub struct MapPlacement {
    /// The CRS.
    pub crs: TiffCrs,
    /// The affine transform.
    pub transform: [f64; 6],
}

impl MapPlacement {
    /// Whether the pixel axes are the map's east and south axes (no rotation), so that a tie
    /// point and a pixel scale describe the placement exactly.
    pub fn north_up(&self) -> bool {
        let t = &self.transform;
        t[2] == 0.0 && t[4] == 0.0 && t[1] > 0.0 && t[5] < 0.0
    }
}

/// One band of a product: its name, centre wavelength (nm) when it is a spectral band, and
/// `nx·ny` values indexed `i + nx·j` with j = 0 the scene's lowest y (written as the last row,
/// so that the image reads as a map).
pub struct TiffBand<'a> {
    /// Band name (`GDAL_METADATA` `DESCRIPTION`).
    pub name: String,
    /// Centre wavelength, nm.
    pub wavelength_nm: Option<f64>,
    /// Values, `i + nx·j`.
    pub values: &'a [f64],
}

/// The bytes of a GeoTIFF of `bands` (`f32`, band-sequential: `PlanarConfiguration` 2, one
/// uncompressed strip per band). North-up placements are written as `ModelPixelScaleTag` +
/// `ModelTiepointTag`, rotated ones as `ModelTransformationTag` (OGC GeoTIFF 1.1 §7.1.2).
pub fn geotiff_bytes(
    nx: usize,
    ny: usize,
    bands: &[TiffBand],
    place: &MapPlacement,
) -> Result<Vec<u8>, String> {
    let e = |e: tiff::TiffError| format!("cannot encode GeoTIFF: {e}");
    if bands.is_empty() || nx == 0 || ny == 0 {
        return Err("cannot encode GeoTIFF: empty image".into());
    }
    let nb = bands.len();
    let mut buf = Cursor::new(Vec::new());
    let mut enc = tiff::encoder::TiffEncoder::new(&mut buf).map_err(e)?;
    let mut dir = enc.image_directory().map_err(e)?;
    let mut offsets = Vec::with_capacity(nb);
    for b in bands {
        let mut rows = vec![0f32; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                rows[i + nx * (ny - 1 - j)] = b.values[i + nx * j] as f32;
            }
        }
        let off = dir.write_data(&rows[..]).map_err(e)?;
        offsets.push(u32::try_from(off).map_err(|_| "GeoTIFF above 4 GiB".to_string())?);
    }
    let bytes = u32::try_from(4 * nx * ny).map_err(|_| "GeoTIFF band above 4 GiB".to_string())?;
    dir.write_tag(Tag::ImageWidth, nx as u32).map_err(e)?;
    dir.write_tag(Tag::ImageLength, ny as u32).map_err(e)?;
    dir.write_tag(Tag::BitsPerSample, &vec![32u16; nb][..])
        .map_err(e)?;
    dir.write_tag(Tag::Compression, 1u16).map_err(e)?;
    dir.write_tag(Tag::PhotometricInterpretation, 1u16)
        .map_err(e)?; // BlackIsZero
    dir.write_tag(Tag::StripOffsets, &offsets[..]).map_err(e)?;
    dir.write_tag(Tag::SamplesPerPixel, nb as u16).map_err(e)?;
    dir.write_tag(Tag::RowsPerStrip, ny as u32).map_err(e)?;
    dir.write_tag(Tag::StripByteCounts, &vec![bytes; nb][..])
        .map_err(e)?;
    dir.write_tag(Tag::PlanarConfiguration, 2u16).map_err(e)?; // separate planes
    if nb > 1 {
        // Unspecified extra samples (TIFF 6.0 §18): the bands are data, not alpha.
        dir.write_tag(Tag::ExtraSamples, &vec![0u16; nb - 1][..])
            .map_err(e)?;
    }
    dir.write_tag(Tag::SampleFormat, &vec![3u16; nb][..])
        .map_err(e)?; // IEEE float
    let t = &place.transform;
    if place.north_up() {
        dir.write_tag(Tag::ModelPixelScaleTag, &[t[1], -t[5], 0.0][..])
            .map_err(e)?;
        dir.write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, t[0], t[3], 0.0][..])
            .map_err(e)?;
    } else {
        // Row-major 4 × 4 (OGC GeoTIFF 1.1 §7.1.2.3): (E, N, Z, 1) = M · (c, r, 0, 1).
        let m = [
            t[1], t[2], 0.0, t[0], t[4], t[5], 0.0, t[3], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ];
        dir.write_tag(Tag::ModelTransformationTag, &m[..])
            .map_err(e)?;
    }
    let (keys, ascii) = geo_keys(&place.crs);
    dir.write_tag(Tag::GeoKeyDirectoryTag, &keys[..])
        .map_err(e)?;
    if !ascii.is_empty() {
        dir.write_tag(Tag::GeoAsciiParamsTag, ascii.as_str())
            .map_err(e)?;
    }
    dir.write_tag(
        Tag::Unknown(TAG_GDAL_METADATA),
        gdal_metadata(bands).as_str(),
    )
    .map_err(e)?;
    dir.finish().map_err(e)?;
    Ok(buf.into_inner())
}

/// Writes [`geotiff_bytes`] to `path` atomically. Errors name the file.
pub fn write_geotiff(
    path: &Path,
    nx: usize,
    ny: usize,
    bands: &[TiffBand],
    place: &MapPlacement,
) -> Result<(), String> {
    let bytes =
        geotiff_bytes(nx, ny, bands, place).map_err(|m| format!("{}: {m}", path.display()))?;
    write_atomic(path, &bytes)
}

/// The GeoKey directory (header `1, 1, 1, count`, then sorted `key, location, count, value`
/// entries; OGC GeoTIFF 1.1 §7.1.3) and the `GeoAsciiParamsTag` text (each string ends with
/// `|`).
fn geo_keys(crs: &TiffCrs) -> (Vec<u16>, String) {
    let mut entries: Vec<[u16; 4]> = vec![[KEY_MODEL_TYPE, 0, 1, 1], [KEY_RASTER_TYPE, 0, 1, 1]];
    let mut ascii = String::new();
    let text = |s: &str, ascii: &mut String| -> [u16; 2] {
        let start = ascii.len() as u16;
        ascii.push_str(&s.replace('|', "/"));
        ascii.push('|');
        [ascii.len() as u16 - start, start]
    };
    match crs {
        TiffCrs::Epsg(code) => entries.push([KEY_PROJECTED_CRS, 0, 1, *code]),
        TiffCrs::UserDefined { name, wkt } => {
            let [n, o] = text(name, &mut ascii);
            entries.push([KEY_CITATION, 34737, n, o]);
            entries.push([KEY_PROJECTED_CRS, 0, 1, USER_DEFINED]);
            let [n, o] = text(&format!("ESRI PE String = {wkt}"), &mut ascii);
            entries.push([KEY_PROJECTED_CITATION, 34737, n, o]);
            entries.push([KEY_LINEAR_UNITS, 0, 1, 9001]);
        }
    }
    entries.sort_by_key(|k| k[0]);
    let mut keys = vec![1, 1, 1, entries.len() as u16];
    keys.extend(entries.iter().flatten());
    (keys, ascii)
}

/// GDAL's band metadata XML: per band (`sample` = band index from 0) its description, its
/// wavelength and units, and its central wavelength in GDAL's `IMAGERY` domain (µm).
fn gdal_metadata(bands: &[TiffBand]) -> String {
    let mut s = String::from("<GDALMetadata>\n");
    for (k, b) in bands.iter().enumerate() {
        s.push_str(&format!(
            "  <Item name=\"DESCRIPTION\" sample=\"{k}\" role=\"description\">{}</Item>\n",
            xml_escape(&b.name)
        ));
        if let Some(w) = b.wavelength_nm {
            s.push_str(&format!(
                "  <Item name=\"wavelength\" sample=\"{k}\">{w}</Item>\n  <Item name=\"wavelength_units\" sample=\"{k}\">nm</Item>\n  <Item name=\"CENTRAL_WAVELENGTH_UM\" sample=\"{k}\" domain=\"IMAGERY\">{}</Item>\n",
                w / 1000.0
            ));
        }
    }
    s.push_str("</GDALMetadata>");
    s
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A single-band raster read from a GeoTIFF, with what it says of its map placement.
#[derive(Debug, Clone, PartialEq)]
pub struct GeoRaster {
    /// Columns and rows.
    pub size: (usize, usize),
    /// Values row by row from the top row, `c + nx·r`, as f64.
    pub values: Vec<f64>,
    /// The pixel-corner transform (see [`MapPlacement::transform`]), from the tie point and
    /// pixel scale or the model transformation; `None` when the file has neither.
    pub transform: Option<[f64; 6]>,
    /// `ProjectedCRSGeoKey`, when present.
    pub projected_crs: Option<u16>,
    /// `GTModelTypeGeoKey`, when present (1 projected, 2 geographic).
    pub model_type: Option<u16>,
    /// `GTRasterTypeGeoKey` = PixelIsPoint: the transform places pixel centres, not corners.
    pub pixel_is_point: bool,
    /// `GDAL_NODATA`, when present.
    pub nodata: Option<f64>,
}

/// Largest number of pixels [`read_geotiff_band`] accepts (2²⁸, as the ESRI reader).
pub const MAX_PIXELS: usize = 1 << 28;

/// Reads the first image of a single-band GeoTIFF (8/16/32/64-bit integers, 32/64-bit floats;
/// strips or tiles; uncompressed, LZW or Deflate). Palette images and multi-band images are
/// refused with a message saying what to do. Errors are plain messages (the caller adds the
/// file and field).
pub fn read_geotiff_band(bytes: &[u8]) -> Result<GeoRaster, String> {
    use tiff::decoder::{Decoder, DecodingResult};
    let e = |e: tiff::TiffError| match e {
        tiff::TiffError::LimitsExceeded => "the raster is larger than the TIFF decoder's limits \
             (256 MiB of samples): crop it to the scene first (e.g. gdal_translate -projwin)"
            .to_string(),
        e => format!(
            "not a readable TIFF ({e}): the file is truncated, damaged or not a TIFF; export it \
             again as a GeoTIFF"
        ),
    };
    let mut dec = Decoder::new(Cursor::new(bytes)).map_err(e)?;
    let (w, h) = dec.dimensions().map_err(e)?;
    let (nx, ny) = (w as usize, h as usize);
    if nx.saturating_mul(ny) > MAX_PIXELS {
        return Err(format!(
            "{nx} × {ny} pixels are above the limit of {MAX_PIXELS} pixels; crop the raster first"
        ));
    }
    let photometric = dec
        .find_tag_unsigned::<u16>(Tag::PhotometricInterpretation)
        .map_err(e)?;
    if photometric == Some(3) {
        return Err(
            "a palette (indexed-colour) TIFF holds colours, not elevations; give the raster of values"
                .into(),
        );
    }
    let spp = dec
        .find_tag_unsigned::<u16>(Tag::SamplesPerPixel)
        .map_err(e)?
        .unwrap_or(1);
    if spp != 1 {
        return Err(format!(
            "the raster has {spp} bands; give a single-band raster (elevation in metres)"
        ));
    }
    let values: Vec<f64> = match dec.read_image().map_err(e)? {
        DecodingResult::U8(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::U32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::U64(v) => v.into_iter().map(|x| x as f64).collect(),
        DecodingResult::I8(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::I16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::I64(v) => v.into_iter().map(|x| x as f64).collect(),
        DecodingResult::F16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F64(v) => v,
    };
    if values.len() != nx * ny {
        return Err(format!(
            "decoded {} values for {nx} × {ny} pixels",
            values.len()
        ));
    }
    let f64s = |dec: &mut Decoder<Cursor<&[u8]>>, t: Tag| -> Result<Option<Vec<f64>>, String> {
        match dec.find_tag(t).map_err(e)? {
            None => Ok(None),
            Some(v) => v.into_f64_vec().map(Some).map_err(e),
        }
    };
    let scale = f64s(&mut dec, Tag::ModelPixelScaleTag)?;
    let tie = f64s(&mut dec, Tag::ModelTiepointTag)?;
    let matrix = f64s(&mut dec, Tag::ModelTransformationTag)?;
    let transform = match (scale, tie, matrix) {
        (_, _, Some(m)) if m.len() >= 8 => Some([m[3], m[0], m[1], m[7], m[4], m[5]]),
        (Some(s), Some(t), _) if s.len() >= 2 && t.len() >= 6 => {
            // Tie point (I, J, K, X, Y, Z): pixel (I, J) lies at map (X, Y).
            Some([
                t[3] - t[0] * s[0],
                s[0],
                0.0,
                t[4] + t[1] * s[1],
                0.0,
                -s[1],
            ])
        }
        _ => None,
    };
    let keys = match dec.find_tag(Tag::GeoKeyDirectoryTag).map_err(e)? {
        Some(v) => v.into_u16_vec().map_err(e)?,
        None => Vec::new(),
    };
    let key = |id: u16| -> Option<u16> {
        keys.get(4..)?
            .chunks_exact(4)
            .find(|k| k[0] == id && k[1] == 0)
            .map(|k| k[3])
    };
    let nodata = match dec.find_tag(Tag::GdalNodata).map_err(e)? {
        Some(v) => {
            let s = v.into_string().map_err(e)?;
            let s = s.trim_matches(|c: char| c.is_whitespace() || c == '\0');
            Some(
                s.parse::<f64>()
                    .map_err(|_| format!("GDAL_NODATA `{s}` is not a number"))?,
            )
        }
        None => None,
    };
    Ok(GeoRaster {
        size: (nx, ny),
        values,
        transform,
        projected_crs: key(KEY_PROJECTED_CRS),
        model_type: key(KEY_MODEL_TYPE),
        pixel_is_point: key(KEY_RASTER_TYPE) == Some(2),
        nodata,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn place(t: [f64; 6]) -> MapPlacement {
        MapPlacement {
            crs: TiffCrs::Epsg(32631),
            transform: t,
        }
    }

    /// A band written as f32 reads back with its tie point, scale, CRS and values; rotated
    /// placements go through the model transformation.
    #[test]
    fn single_band_round_trip() {
        let (nx, ny) = (3, 2);
        let v: Vec<f64> = (0..6).map(|k| k as f64 * 0.5 - 1.0).collect();
        let band = [TiffBand {
            name: "z".into(),
            wavelength_nm: None,
            values: &v,
        }];
        for t in [
            [500_000.0, 2.0, 0.0, 4_800_000.0, 0.0, -3.0],
            [500_000.0, 1.2, 1.6, 4_800_000.0, 1.6, -1.2],
        ] {
            let b = geotiff_bytes(nx, ny, &band, &place(t)).unwrap();
            let r = read_geotiff_band(&b).unwrap();
            assert_eq!(r.size, (nx, ny));
            assert_eq!(r.transform, Some(t));
            assert_eq!(r.projected_crs, Some(32631));
            assert_eq!(r.model_type, Some(1));
            // Top row first: scene row j = 1 is file row 0.
            assert_eq!(r.values, vec![0.5, 1.0, 1.5, -1.0, -0.5, 0.0]);
        }
        // Truncated files are errors, not panics.
        let b = geotiff_bytes(nx, ny, &band, &place([0.0, 1.0, 0.0, 0.0, 0.0, -1.0])).unwrap();
        for cut in [0, 4, 8, 30, b.len() - 10] {
            assert!(read_geotiff_band(&b[..cut]).is_err(), "cut {cut}");
        }
    }

    /// A raster above the decoder's limits (here a 12 000² f32 header without its data) is
    /// refused with a message saying to crop it, before anything is allocated.
    #[test]
    fn oversized_raster_says_crop_it() {
        let mut buf = Cursor::new(Vec::new());
        {
            let mut enc = tiff::encoder::TiffEncoder::new(&mut buf).unwrap();
            let mut dir = enc.image_directory().unwrap();
            for (t, v) in [
                (Tag::ImageWidth, 12_000u32),
                (Tag::ImageLength, 12_000),
                (Tag::StripOffsets, 8),
                (Tag::RowsPerStrip, 12_000),
                (Tag::StripByteCounts, 576_000_000),
            ] {
                dir.write_tag(t, v).unwrap();
            }
            for (t, v) in [
                (Tag::BitsPerSample, 32u16),
                (Tag::Compression, 1),
                (Tag::PhotometricInterpretation, 1),
                (Tag::SamplesPerPixel, 1),
                (Tag::SampleFormat, 3),
            ] {
                dir.write_tag(t, v).unwrap();
            }
            dir.finish().unwrap();
        }
        let m = read_geotiff_band(&buf.into_inner()).unwrap_err();
        assert!(m.contains("crop it"), "{m}");
    }

    /// User-defined CRSs carry their WKT in the ASCII parameters.
    #[test]
    fn user_defined_crs_keys() {
        let (keys, ascii) = geo_keys(&TiffCrs::UserDefined {
            name: "local".into(),
            wkt: "PROJCS[\"local\"]".into(),
        });
        assert_eq!(keys[..4], [1, 1, 1, 6]);
        assert!(ascii.starts_with("local|ESRI PE String = PROJCS"));
        assert!(keys.chunks(4).skip(1).any(|k| k == [3072, 0, 1, 32767]));
    }
}
