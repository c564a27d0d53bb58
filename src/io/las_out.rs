//! LAS 1.4 point clouds of LiDAR returns (ASPRS LAS Specification 1.4 R15, 2019) through the
//! `las` crate: discrete returns, photon-counting detections and the fusion product (returns
//! with the co-registered image's spectral radiance attached per band).
//!
//! * Point data record format **6** (no colour) or **7** (RGB), chosen from the points: all of
//!   them must carry `rgb` or none.
//! * **Pulse ID**: LAS 1.4 has no pulse-ID field, so every point carries an extra-bytes
//!   dimension `pulse_id` (u64), declared in an Extra Bytes VLR (user "LASF_Spec", record 4) so
//!   that laspy and PDAL expose it by name. `gps_time` holds the pulse emission time (s from the
//!   start of the scan, GPS-week-time flag), and the return number/number of returns fields are
//!   the LAS ones.
//! * Per-band values (e.g. spectral radiance W m⁻² sr⁻¹ µm⁻¹ of the fused image) follow as one
//!   f64 extra-bytes dimension per band, named by the caller.
//!
//! Extra bytes of one point record: `pulse_id` u64 LE, then one f64 LE per band, in the order of
//! the descriptors. Each descriptor is the 192-byte LAS 1.4 `EXTRA_BYTES` struct (see
//! [`extra_bytes_descriptor`]). Points are converted and written one by one to a temporary file
//! renamed into place at the end ([`write_las_stream`]): memory does not grow with the cloud,
//! and after an error no partial file is left.

use std::path::Path;

/// Name of the extra-bytes dimension carrying the pulse identifier.
pub const PULSE_ID_NAME: &str = "pulse_id";
/// LAS user id of the Extra Bytes VLR.
pub const EXTRA_BYTES_USER_ID: &str = "LASF_Spec";
/// LAS record id of the Extra Bytes VLR.
pub const EXTRA_BYTES_RECORD_ID: u16 = 4;
/// Size of one extra-bytes descriptor (LAS 1.4 R15 Table 24).
pub const EXTRA_BYTES_DESCRIPTOR_LEN: usize = 192;
/// Extra-bytes data type code of u64 (LAS 1.4 R15 Table 25).
pub const EXTRA_BYTES_TYPE_U64: u8 = 7;
/// Extra-bytes data type code of f64 (LAS 1.4 R15 Table 25).
pub const EXTRA_BYTES_TYPE_F64: u8 = 10;

/// One point of a LiDAR point cloud.
#[derive(Debug, Clone, PartialEq)]
pub struct LasPoint {
    /// Coordinates (m, scene/projected frame).
    pub x: f64,
    /// See `x`.
    pub y: f64,
    /// See `x`.
    pub z: f64,
    /// Return intensity (sensor-specific scaling, e.g. return energy normalised to u16).
    pub intensity: u16,
    /// Return number within its pulse, 1..=15.
    pub return_number: u8,
    /// Number of returns of the pulse, `return_number..=15`.
    pub number_of_returns: u8,
    /// Pulse identifier (stored in the `pulse_id` extra-bytes dimension).
    pub pulse_id: u64,
    /// Pulse emission time (s).
    pub gps_time: f64,
    /// ASPRS class (LAS 1.4 Table 17: 0 never classified, 1 unclassified, 2 ground, 3–5
    /// vegetation, 6 building, 7 low noise, 18 high noise...; 12 is rejected: in PDRF 6+
    /// overlap is a flag).
    pub classification: u8,
    /// Scanner channel 0..=3 (photon-counting detector channel).
    pub scanner_channel: u8,
    /// 16-bit colour; `Some` on every point → PDRF 7, `None` on every point → PDRF 6.
    pub rgb: Option<[u16; 3]>,
    /// One value per extra band (same length as `extra_names` of [`write_las`]).
    pub extra: Vec<f64>,
}

/// A LAS file read back by [`read_las`].
#[derive(Debug, Clone, PartialEq)]
pub struct LasContents {
    /// LAS version (major, minor).
    pub version: (u8, u8),
    /// Point data record format.
    pub point_format: u8,
    /// Names of the f64 band dimensions (after `pulse_id`).
    pub extra_names: Vec<String>,
    /// The points, `extra` filled from the band dimensions.
    pub points: Vec<LasPoint>,
}

/// The 192-byte LAS 1.4 extra-bytes descriptor (R15 Table 24): `reserved[2]`, `data_type` (u8),
/// `options` (u8, 0: no no_data/min/max/scale/offset), `name[32]`, `unused[4]`, `no_data[24]`,
/// `min[24]`, `max[24]`, `scale[24]`, `offset[24]`, `description[32]`. Names and descriptions
/// are NUL-padded ASCII of at most 32 bytes.
pub fn extra_bytes_descriptor(
    data_type: u8,
    name: &str,
    description: &str,
) -> Result<[u8; EXTRA_BYTES_DESCRIPTOR_LEN], String> {
    check_las_name(name)?;
    if !description.is_ascii() || description.len() > 32 {
        return Err(format!(
            "extra-bytes description {description:?} must be ASCII of at most 32 bytes"
        ));
    }
    let mut d = [0u8; EXTRA_BYTES_DESCRIPTOR_LEN];
    d[2] = data_type;
    d[3] = 0;
    d[4..4 + name.len()].copy_from_slice(name.as_bytes());
    d[160..160 + description.len()].copy_from_slice(description.as_bytes());
    Ok(d)
}

fn check_las_name(name: &str) -> Result<(), String> {
    if name.is_empty() || !name.is_ascii() || name.len() > 32 || name.contains('\0') {
        return Err(format!(
            "extra-bytes name {name:?} must be 1 to 32 ASCII bytes without NUL"
        ));
    }
    Ok(())
}

/// Payload of the Extra Bytes VLR for `pulse_id` + the named f64 bands.
pub fn extra_bytes_vlr_payload(extra_names: &[String]) -> Result<Vec<u8>, String> {
    let mut data = Vec::with_capacity(EXTRA_BYTES_DESCRIPTOR_LEN * (1 + extra_names.len()));
    data.extend_from_slice(&extra_bytes_descriptor(
        EXTRA_BYTES_TYPE_U64,
        PULSE_ID_NAME,
        "pulse identifier (lumenscape)",
    )?);
    for (i, name) in extra_names.iter().enumerate() {
        if name == PULSE_ID_NAME || extra_names[..i].contains(name) {
            return Err(format!(
                "extra-bytes name {name:?} is duplicated or reserved"
            ));
        }
        data.extend_from_slice(&extra_bytes_descriptor(
            EXTRA_BYTES_TYPE_F64,
            name,
            "band value (lumenscape)",
        )?);
    }
    Ok(data)
}

/// Writes `points` to `path` as LAS 1.4, PDRF 7 if the points carry RGB, else PDRF 6.
///
/// * `scale`, `offset`: per-axis coordinate transform (stored integer = round((x − offset)/
///   scale)); scales must be finite and > 0, every coordinate must fit in i32 after it;
/// * `extra_names`: names of the f64 band dimensions; each point's `extra` must have this length.
///
/// Errors name the file (and the point); after an error no file is left ([`write_las_stream`]).
/// An empty point list writes a valid empty file.
pub fn write_las(
    path: &Path,
    points: &[LasPoint],
    scale: [f64; 3],
    offset: [f64; 3],
    extra_names: &[String],
) -> Result<(), String> {
    let with_rgb = points.first().is_some_and(|p| p.rgb.is_some());
    write_las_stream(
        path,
        with_rgb,
        points.iter().cloned().map(Ok),
        scale,
        offset,
        extra_names,
    )
    .map(|_| ())
}

/// [`write_las`] from a stream of points, PDRF 7 if `with_rgb` (every point must then carry
/// RGB) else 6; returns the number of points written. Each point is converted and written as
/// it comes (memory independent of the number of points) to a temporary file in the same
/// folder, renamed to `path` at the end; an invalid point, an error of the stream or an I/O
/// error removes the temporary file: no partial product is left.
pub fn write_las_stream(
    path: &Path,
    with_rgb: bool,
    points: impl IntoIterator<Item = Result<LasPoint, String>>,
    scale: [f64; 3],
    offset: [f64; 3],
    extra_names: &[String],
) -> Result<u64, String> {
    let fail = |msg: String| format!("{}: {msg}", path.display());
    let header = las_header(with_rgb, scale, offset, extra_names).map_err(fail)?;
    let transforms = *header.transforms();
    let tmp = crate::io::atomic::tmp_path(path);
    let res = (|| -> Result<u64, String> {
        let file = std::fs::File::create(&tmp).map_err(|e| format!("cannot write: {e}"))?;
        let mut writer = las::Writer::new(std::io::BufWriter::new(file), header)
            .map_err(|e| format!("cannot write: {e}"))?;
        let mut n = 0u64;
        for (i, p) in points.into_iter().enumerate() {
            let p = to_las_point(&p?, i, with_rgb, extra_names.len(), &transforms)?;
            writer
                .write_point(p)
                .map_err(|e| format!("cannot write: {e}"))?;
            n += 1;
        }
        let file = writer
            .into_inner()
            .map_err(|e| format!("cannot write: {e}"))?
            .into_inner()
            .map_err(|e| format!("cannot write: {}", e.error()))?;
        file.sync_all()
            .and_then(|_| std::fs::rename(&tmp, path))
            .map_err(|e| format!("cannot write: {e}"))?;
        Ok(n)
    })();
    res.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        fail(e)
    })
}

/// The LAS 1.4 header of [`write_las`]: PDRF 6 or 7, the transforms, the Extra Bytes VLR
/// (`pulse_id` + one f64 per band).
fn las_header(
    with_rgb: bool,
    scale: [f64; 3],
    offset: [f64; 3],
    extra_names: &[String],
) -> Result<las::Header, String> {
    for (axis, s, o) in [
        ("x", scale[0], offset[0]),
        ("y", scale[1], offset[1]),
        ("z", scale[2], offset[2]),
    ] {
        if !(s.is_finite() && s > 0.0 && o.is_finite()) {
            return Err(format!(
                "{axis} scale {s} / offset {o}: scale must be finite > 0, offset finite"
            ));
        }
    }
    let vlr_data = extra_bytes_vlr_payload(extra_names)?;
    let n_extra = 8 + 8 * extra_names.len();

    let mut builder = las::Builder::from((1, 4));
    builder.point_format =
        las::point::Format::new(if with_rgb { 7 } else { 6 }).map_err(|e| e.to_string())?;
    builder.point_format.extra_bytes = u16::try_from(n_extra).map_err(|_| {
        format!(
            "{} extra bands are too many for a LAS record",
            extra_names.len()
        )
    })?;
    builder.system_identifier = "lumenscape simulation".into();
    builder.generating_software = format!("lumenscape {}", env!("CARGO_PKG_VERSION"));
    builder.transforms = las::Vector {
        x: las::Transform {
            scale: scale[0],
            offset: offset[0],
        },
        y: las::Transform {
            scale: scale[1],
            offset: offset[1],
        },
        z: las::Transform {
            scale: scale[2],
            offset: offset[2],
        },
    };
    builder.vlrs.push(las::Vlr {
        user_id: EXTRA_BYTES_USER_ID.into(),
        record_id: EXTRA_BYTES_RECORD_ID,
        description: "Extra Bytes Record".into(),
        data: vlr_data,
    });
    builder.into_header().map_err(|e| e.to_string())
}

fn to_las_point(
    p: &LasPoint,
    i: usize,
    with_rgb: bool,
    n_bands: usize,
    transforms: &las::Vector<las::Transform>,
) -> Result<las::Point, String> {
    let err = |m: String| format!("point {i} (pulse {}): {m}", p.pulse_id);
    for (axis, v, t) in [
        ("x", p.x, transforms.x),
        ("y", p.y, transforms.y),
        ("z", p.z, transforms.z),
    ] {
        if !v.is_finite() {
            return Err(err(format!("{axis} = {v} is not finite")));
        }
        t.inverse(v)
            .map_err(|_| err(format!("{axis} = {v} does not fit in i32 with {t}")))?;
    }
    if !(1..=15).contains(&p.return_number)
        || !(p.return_number..=15).contains(&p.number_of_returns)
    {
        return Err(err(format!(
            "return {} of {}: need 1 <= return_number <= number_of_returns <= 15",
            p.return_number, p.number_of_returns
        )));
    }
    if !p.gps_time.is_finite() {
        return Err(err(format!("gps_time = {} is not finite", p.gps_time)));
    }
    if p.scanner_channel > 3 {
        return Err(err(format!("scanner_channel {} > 3", p.scanner_channel)));
    }
    let classification = las::point::Classification::new(p.classification)
        .map_err(|e| err(format!("classification {}: {e}", p.classification)))?;
    if p.rgb.is_some() != with_rgb {
        return Err(err(
            "all points must carry rgb (PDRF 7) or none (PDRF 6)".to_string()
        ));
    }
    if p.extra.len() != n_bands {
        return Err(err(format!(
            "{} extra values, expected {n_bands}",
            p.extra.len()
        )));
    }
    let mut extra_bytes = Vec::with_capacity(8 + 8 * n_bands);
    extra_bytes.extend_from_slice(&p.pulse_id.to_le_bytes());
    for v in &p.extra {
        extra_bytes.extend_from_slice(&v.to_le_bytes());
    }
    Ok(las::Point {
        x: p.x,
        y: p.y,
        z: p.z,
        intensity: p.intensity,
        return_number: p.return_number,
        number_of_returns: p.number_of_returns,
        classification,
        scanner_channel: p.scanner_channel,
        gps_time: Some(p.gps_time),
        color: p.rgb.map(|[r, g, b]| las::Color::new(r, g, b)),
        extra_bytes,
        ..Default::default()
    })
}

/// Reads a file written by [`write_las`] with the `las` reader: finds `pulse_id` and the f64
/// band dimensions in the Extra Bytes VLR and decodes them from each record's extra bytes.
pub fn read_las(path: &Path) -> Result<LasContents, String> {
    let fail = |m: String| format!("{}: {m}", path.display());
    let mut reader = las::Reader::from_path(path).map_err(|e| fail(e.to_string()))?;
    let header = reader.header().clone();
    let vlr = header
        .vlrs()
        .iter()
        .find(|v| v.user_id == EXTRA_BYTES_USER_ID && v.record_id == EXTRA_BYTES_RECORD_ID)
        .ok_or_else(|| fail("no Extra Bytes VLR".into()))?;
    if vlr.data.len() % EXTRA_BYTES_DESCRIPTOR_LEN != 0 || vlr.data.is_empty() {
        return Err(fail(format!("Extra Bytes VLR of {} bytes", vlr.data.len())));
    }
    let mut names = Vec::new();
    for (k, d) in vlr
        .data
        .chunks_exact(EXTRA_BYTES_DESCRIPTOR_LEN)
        .enumerate()
    {
        let name_end = d[4..36].iter().position(|&b| b == 0).unwrap_or(32);
        let name = String::from_utf8_lossy(&d[4..4 + name_end]).into_owned();
        let expected = if k == 0 {
            EXTRA_BYTES_TYPE_U64
        } else {
            EXTRA_BYTES_TYPE_F64
        };
        if d[2] != expected || (k == 0 && name != PULSE_ID_NAME) {
            return Err(fail(format!(
                "extra-bytes descriptor {k} ({name}, type {}) is not a lumenscape layout",
                d[2]
            )));
        }
        if k > 0 {
            names.push(name);
        }
    }
    let n_extra = 8 + 8 * names.len();
    let version = header.version();
    let format = header
        .point_format()
        .to_u8()
        .map_err(|e| fail(e.to_string()))?;
    let data = reader.read_all().map_err(|e| fail(e.to_string()))?;
    let mut points = Vec::with_capacity(data.len());
    for (i, p) in data.points().enumerate() {
        let p = p.map_err(|e| fail(format!("point {i}: {e}")))?;
        if p.extra_bytes.len() != n_extra {
            return Err(fail(format!(
                "point {i} has {} extra bytes, expected {n_extra}",
                p.extra_bytes.len()
            )));
        }
        let eb = &p.extra_bytes;
        let pulse_id = u64::from_le_bytes(eb[0..8].try_into().expect("8 bytes"));
        let extra = eb[8..]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        points.push(LasPoint {
            x: p.x,
            y: p.y,
            z: p.z,
            intensity: p.intensity,
            return_number: p.return_number,
            number_of_returns: p.number_of_returns,
            pulse_id,
            gps_time: p.gps_time.unwrap_or(f64::NAN),
            classification: u8::from(p.classification),
            scanner_channel: p.scanner_channel,
            rgb: p.color.map(|c| [c.red, c.green, c.blue]),
            extra,
        });
    }
    Ok(LasContents {
        version: (version.major, version.minor),
        point_format: format,
        extra_names: names,
        points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn descriptor_layout() {
        let d = extra_bytes_descriptor(EXTRA_BYTES_TYPE_F64, "band_550nm", "radiance").unwrap();
        assert_eq!(d.len(), 192);
        assert_eq!(&d[0..2], &[0, 0]);
        assert_eq!(d[2], 10);
        assert_eq!(&d[4..14], b"band_550nm");
        assert!(d[14..36].iter().all(|&b| b == 0));
        assert_eq!(&d[160..168], b"radiance");
        assert!(extra_bytes_descriptor(10, "", "x").is_err());
        assert!(extra_bytes_descriptor(10, &"a".repeat(33), "x").is_err());
        assert!(extra_bytes_descriptor(10, "é", "x").is_err());
        assert!(extra_bytes_vlr_payload(&["pulse_id".into()]).is_err());
        assert!(extra_bytes_vlr_payload(&["a".into(), "a".into()]).is_err());
        assert_eq!(
            extra_bytes_vlr_payload(&["a".into(), "b".into()])
                .unwrap()
                .len(),
            3 * 192
        );
    }
}
