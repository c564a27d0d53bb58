//! ENVI raster products: a band-sequential raw `f32` file (`NAME.dat`) and its text header
//! (`NAME.hdr`) with the map placement (`map info`, `coordinate system string`), the band names
//! and the wavelengths, and a parser of such headers.
//!
//! Format source: "ENVI Header Format" (ENVI documentation, L3Harris Geospatial): keys
//! `samples`, `lines`, `bands`, `header offset`, `file type`, `data type` (4 = 32-bit float),
//! `interleave` (`bsq`), `byte order` (0 = little endian), `map info` = {projection name,
//! reference pixel x, reference pixel y (1-based; (1, 1) is the upper-left corner of the
//! upper-left pixel), easting, northing, pixel size x, pixel size y, [UTM zone, North/South,]
//! datum, `units=Meters`, `rotation=` angle in degrees anticlockwise}, `coordinate system
//! string` (WKT), `band names`, `wavelength units`, `wavelength`. The rotation convention is
//! GDAL's reading of it (`frmts/raw/envidataset.cpp`: rotation = −atan2(−t₂, t₁)).

use crate::io::atomic::{write_atomic, write_atomic_with};
use crate::io::geotiff::{MapPlacement, TiffBand, TiffCrs};
use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::Path;

/// The header text of a band-sequential `f32` raster of `bands` placed by `place`; `wkt` is the
/// CRS's WKT (`coordinate system string`), when known.
pub fn envi_header(
    description: &str,
    nx: usize,
    ny: usize,
    bands: &[TiffBand],
    place: &MapPlacement,
    wkt: Option<&str>,
) -> String {
    let t = &place.transform;
    let px = t[1].hypot(t[4]);
    let py = t[2].hypot(t[5]);
    let rotation = -(-t[2]).atan2(t[1]).to_degrees();
    let (proj, zone) = match &place.crs {
        TiffCrs::Epsg(c @ 32601..=32660) => ("UTM".to_string(), format!(", {}, North", c - 32600)),
        TiffCrs::Epsg(c @ 32701..=32760) => ("UTM".to_string(), format!(", {}, South", c - 32700)),
        TiffCrs::Epsg(c) => (format!("EPSG:{c}"), String::new()),
        TiffCrs::UserDefined { name, .. } => (name.replace([',', '{', '}'], " "), String::new()),
    };
    let datum = if zone.is_empty() { "" } else { ", WGS-84" };
    let rot = if rotation != 0.0 {
        format!(", rotation={rotation}")
    } else {
        String::new()
    };
    let mut h = format!(
        "ENVI\ndescription = {{{}}}\nsamples = {nx}\nlines = {ny}\nbands = {}\nheader offset = 0\nfile type = ENVI Standard\ndata type = 4\ninterleave = bsq\nbyte order = 0\nmap info = {{{proj}, 1, 1, {}, {}, {px}, {py}{zone}{datum}, units=Meters{rot}}}\n",
        description.replace(['{', '}'], " "),
        bands.len(),
        t[0],
        t[3],
    );
    if let Some(w) = wkt {
        h.push_str(&format!("coordinate system string = {{{w}}}\n"));
    }
    let names: Vec<String> = bands
        .iter()
        .map(|b| b.name.replace([',', '{', '}'], "_"))
        .collect();
    h.push_str(&format!("band names = {{{}}}\n", names.join(", ")));
    if bands.iter().all(|b| b.wavelength_nm.is_some()) {
        let w: Vec<String> = bands
            .iter()
            .map(|b| format!("{}", b.wavelength_nm.unwrap_or(0.0)))
            .collect();
        h.push_str(&format!(
            "wavelength units = Nanometers\nwavelength = {{{}}}\n",
            w.join(", ")
        ));
    }
    h
}

/// Writes `base.dat` (band-sequential little-endian `f32`, rows from the top, the same pixel
/// order as the GeoTIFF) and `base.hdr` ([`envi_header`]) atomically. `base` has no extension
/// (dots in its name are kept: `view_000.0_000.0` gives `view_000.0_000.0.hdr`).
pub fn write_envi(
    base: &Path,
    description: &str,
    nx: usize,
    ny: usize,
    bands: &[TiffBand],
    place: &MapPlacement,
    wkt: Option<&str>,
) -> Result<(), String> {
    write_atomic_with(&with_suffix(base, "dat"), |w| {
        for b in bands {
            for r in 0..ny {
                let j = ny - 1 - r;
                for i in 0..nx {
                    w.write_all(&(b.values[i + nx * j] as f32).to_le_bytes())?;
                }
            }
        }
        Ok(())
    })?;
    let h = envi_header(description, nx, ny, bands, place, wkt);
    write_atomic(&with_suffix(base, "hdr"), h.as_bytes())
}

/// `base` with `.ext` appended to its file name.
pub fn with_suffix(base: &Path, ext: &str) -> std::path::PathBuf {
    let mut name = base.file_name().unwrap_or_default().to_os_string();
    name.push(".");
    name.push(ext);
    base.with_file_name(name)
}

/// Parses an ENVI header into its `key = value` entries (keys lower-case, `{…}` values
/// without their braces, spread over lines or not). Errors say what is wrong.
pub fn parse_envi_header(text: &str) -> Result<BTreeMap<String, String>, String> {
    let mut lines = text.lines();
    if lines.next().map(str::trim) != Some("ENVI") {
        return Err("an ENVI header starts with the line `ENVI`".into());
    }
    let mut out = BTreeMap::new();
    let mut pending: Option<(String, String)> = None;
    for l in lines {
        if let Some((k, mut v)) = pending.take() {
            v.push('\n');
            v.push_str(l);
            if l.contains('}') {
                let inner = v.trim().trim_start_matches('{');
                let inner = &inner[..inner.rfind('}').unwrap_or(inner.len())];
                out.insert(k, inner.trim().to_string());
            } else {
                pending = Some((k, v));
            }
            continue;
        }
        let Some((k, v)) = l.split_once('=') else {
            if l.trim().is_empty() {
                continue;
            }
            return Err(format!("line `{l}` is not `key = value`"));
        };
        let (k, v) = (k.trim().to_ascii_lowercase(), v.trim().to_string());
        if v.starts_with('{') && !v.contains('}') {
            pending = Some((k, v));
        } else if let Some(inner) = v.strip_prefix('{') {
            let inner = &inner[..inner.rfind('}').unwrap_or(inner.len())];
            out.insert(k, inner.trim().to_string());
        } else {
            out.insert(k, v);
        }
    }
    if let Some((k, _)) = pending {
        return Err(format!("the value of `{k}` has no closing brace"));
    }
    Ok(out)
}

/// The comma-separated items of a `{…}` header value, trimmed.
pub fn envi_list(value: &str) -> Vec<String> {
    value.split(',').map(|s| s.trim().to_string()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_parses_back() {
        let v = vec![0.0; 6];
        let bands = [
            TiffBand {
                name: "brf.00_red".into(),
                wavelength_nm: Some(670.0),
                values: &v,
            },
            TiffBand {
                name: "brf.01_nir".into(),
                wavelength_nm: Some(860.0),
                values: &v,
            },
        ];
        let place = MapPlacement {
            crs: TiffCrs::Epsg(32631),
            transform: [500_000.0, 0.5, 0.0, 4_800_000.0, 0.0, -0.5],
        };
        let h = envi_header("view", 3, 2, &bands, &place, Some("PROJCS[\"x\"]"));
        let m = parse_envi_header(&h).unwrap();
        assert_eq!(m["samples"], "3");
        assert_eq!(m["bands"], "2");
        assert_eq!(
            envi_list(&m["map info"]),
            [
                "UTM",
                "1",
                "1",
                "500000",
                "4800000",
                "0.5",
                "0.5",
                "31",
                "North",
                "WGS-84",
                "units=Meters"
            ]
        );
        assert_eq!(envi_list(&m["band names"]), ["brf.00_red", "brf.01_nir"]);
        assert_eq!(envi_list(&m["wavelength"]), ["670", "860"]);
        assert!(parse_envi_header("ENVI\nbands = {1,\n").is_err());
        assert!(parse_envi_header("samples = 3").is_err());
    }
}
