//! Multi-channel OpenEXR output (f32 samples). Channel names are `layer.channel`; exr sorts
//! channels by name. Image row r holds scene row j = ny − 1 − r, so the image reads as a map
//! (+x right, +y up).

use crate::io::atomic::{tmp_path, write_atomic};
use exr::prelude::*;
use std::path::Path;

/// One named layer of channels; each channel holds `nx·ny` values indexed `i + nx·j`.
pub struct ExrLayer {
    /// Layer name.
    pub name: String,
    /// (channel name, values).
    pub channels: Vec<(String, Vec<f64>)>,
}

/// Header metadata of an EXR file.
#[derive(Debug, Clone, Default)]
pub struct ExrMeta {
    /// Pixel size (x, y), m: written as the attributes `pixel_size_x_m` and `pixel_size_y_m`
    /// (f64) and as the standard `pixelAspectRatio` (y / x).
    pub pixel_size_m: Option<(f64, f64)>,
    /// Other named numbers, written as f64 attributes.
    pub values: Vec<(String, f64)>,
}

/// Writes the layers into one EXR file atomically.
pub fn write_exr_layers(
    path: &Path,
    nx: usize,
    ny: usize,
    layers: &[ExrLayer],
) -> std::result::Result<(), String> {
    write_exr_layers_with(path, nx, ny, layers, &ExrMeta::default())
}

/// [`write_exr_layers`] with header metadata.
pub fn write_exr_layers_with(
    path: &Path,
    nx: usize,
    ny: usize,
    layers: &[ExrLayer],
    meta: &ExrMeta,
) -> std::result::Result<(), String> {
    let mut list = Vec::new();
    for l in layers {
        let chans: Vec<AnyChannel<FlatSamples>> = l
            .channels
            .iter()
            .map(|(name, v)| {
                let mut flipped = vec![0f32; nx * ny];
                for j in 0..ny {
                    for i in 0..nx {
                        flipped[i + nx * (ny - 1 - j)] = v[i + nx * j] as f32;
                    }
                }
                AnyChannel::new(name.as_str(), FlatSamples::F32(flipped))
            })
            .collect();
        let layer = Layer::new(
            (nx, ny),
            LayerAttributes::named(l.name.as_str()),
            // RLE in 64×64 tiles as `FAST_LOSSLESS`, but the tiles in increasing order: with
            // `Unspecified` the crate writes them as its threads finish compressing, and the
            // same image gave different bytes from run to run.
            Encoding {
                line_order: LineOrder::Increasing,
                ..Encoding::FAST_LOSSLESS
            },
            AnyChannels::sort(chans.into()),
        );
        list.push(layer);
    }
    let mut attributes = ImageAttributes::new(IntegerBounds::from_dimensions((nx, ny)));
    let mut values = meta.values.clone();
    if let Some((px, py)) = meta.pixel_size_m {
        attributes.pixel_aspect = (py / px) as f32;
        values.push(("pixel_size_x_m".into(), px));
        values.push(("pixel_size_y_m".into(), py));
    }
    for (name, v) in values {
        let key = Text::new_or_none(name.as_str())
            .ok_or_else(|| format!("{}: bad EXR attribute name `{name}`", path.display()))?;
        attributes.other.insert(key, AttributeValue::F64(v));
    }
    let image = Image::from_layers(attributes, list);
    let tmp = tmp_path(path);
    let res = (|| -> std::result::Result<(), String> {
        image
            .write()
            .to_file(&tmp)
            .map_err(|e| format!("cannot write EXR: {e}"))?;
        // exr keeps the custom attributes in a std HashMap (randomly seeded): put every
        // header's attributes in name order so that the same image gives the same bytes.
        let mut bytes = std::fs::read(&tmp).map_err(|e| format!("cannot write: {e}"))?;
        sort_header_attributes(&mut bytes)?;
        std::fs::write(&tmp, &bytes).map_err(|e| format!("cannot write: {e}"))?;
        std::fs::rename(&tmp, path).map_err(|e| format!("cannot write: {e}"))
    })();
    res.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("{}: {e}", path.display())
    })?;
    let _ = write_atomic;
    Ok(())
}

/// Sorts the attributes of every header of an OpenEXR file image by name, in place. Each
/// attribute is `name\0 type\0 size:i32 value[size]`; a header ends with a null byte, and a
/// multi-part file's header list with an empty header (OpenEXR file layout, "Header"). The
/// headers keep their lengths, so the offset tables after them stay valid.
fn sort_header_attributes(bytes: &mut [u8]) -> std::result::Result<(), String> {
    let bad = |what: &str| format!("cannot reorder the EXR header: {what}");
    if bytes.len() < 8 || bytes[0..4] != [0x76, 0x2f, 0x31, 0x01] {
        return Err(bad("no OpenEXR magic number"));
    }
    let multipart = bytes[5] & 0x10 != 0; // flag bit 12 of the version field
    let cstr_end = |b: &[u8], from: usize| -> std::result::Result<usize, String> {
        b.get(from..)
            .and_then(|r| r.iter().position(|&c| c == 0))
            .map(|k| from + k + 1)
            .ok_or_else(|| bad("unterminated name"))
    };
    let mut pos = 8;
    loop {
        let start = pos;
        let mut attrs: Vec<(Vec<u8>, std::ops::Range<usize>)> = Vec::new();
        loop {
            match bytes.get(pos) {
                None => return Err(bad("truncated header")),
                Some(0) => break,
                Some(_) => {}
            }
            let a = pos;
            let name_end = cstr_end(bytes, pos)?;
            let type_end = cstr_end(bytes, name_end)?;
            let size = bytes
                .get(type_end..type_end + 4)
                .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .filter(|&n| n >= 0)
                .ok_or_else(|| bad("attribute size"))?;
            pos = type_end + 4 + size as usize;
            if pos > bytes.len() {
                return Err(bad("attribute past the end"));
            }
            attrs.push((bytes[a..name_end].to_vec(), a..pos));
        }
        let end = pos; // the header's terminating null byte
        attrs.sort_by(|x, y| x.0.cmp(&y.0));
        let sorted: Vec<u8> = attrs
            .iter()
            .flat_map(|(_, r)| bytes[r.clone()].to_vec())
            .collect();
        bytes[start..end].copy_from_slice(&sorted);
        pos = end + 1;
        if !multipart || bytes.get(pos) == Some(&0) {
            return Ok(());
        }
    }
}

/// Reads the f64 attributes of an EXR file's header (see [`ExrMeta`]), plus
/// `pixelAspectRatio`.
pub fn read_exr_values(path: &Path) -> std::result::Result<Vec<(String, f64)>, String> {
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = Vec::new();
    if let Some(h) = meta.headers.first() {
        out.push((
            "pixelAspectRatio".to_string(),
            h.shared_attributes.pixel_aspect as f64,
        ));
        for (k, v) in h
            .shared_attributes
            .other
            .iter()
            .chain(&h.own_attributes.other)
        {
            if let AttributeValue::F64(x) = v {
                out.push((k.to_string(), *x));
            }
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

/// Reads every channel of an EXR file as (name, values indexed `i + nx·j`), plus (nx, ny).
pub fn read_exr_channels(
    path: &Path,
) -> std::result::Result<(usize, usize, Vec<(String, Vec<f32>)>), String> {
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = Vec::new();
    let mut size = (0, 0);
    for layer in &img.layer_data {
        let (nx, ny) = (layer.size.0, layer.size.1);
        size = (nx, ny);
        for ch in &layer.channel_data.list {
            let vals: Vec<f32> = ch.sample_data.values_as_f32().collect();
            let mut v = vec![0f32; nx * ny];
            for j in 0..ny {
                for i in 0..nx {
                    v[i + nx * j] = vals[i + nx * (ny - 1 - j)];
                }
            }
            let lname = layer.attributes.layer_name.as_ref().map(|t| t.to_string());
            let cname = ch.name.to_string();
            let full = match lname {
                Some(l) if !cname.starts_with(&format!("{l}.")) => format!("{l}.{cname}"),
                _ => cname,
            };
            out.push((full, v));
        }
    }
    Ok((size.0, size.1, out))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same image gives the same bytes (tiles in increasing order, declared so in the
    /// header, whatever order the compression threads finish in; attributes in name order);
    /// values and attributes read back.
    #[test]
    fn the_same_image_gives_the_same_bytes() {
        let dir = std::env::temp_dir().join(format!("lumenscape-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // 5 × 4 tiles of 64 × 64, varied values (RLE blocks of different sizes).
        let (nx, ny) = (300, 250);
        let vals = |s: f64| -> Vec<f64> {
            (0..nx * ny)
                .map(|k| ((k as f64 * s).sin() * 1e3).round() / 1e3)
                .collect()
        };
        let layers = [ExrLayer {
            name: "brf".into(),
            channels: vec![("a".into(), vals(0.37)), ("b".into(), vals(1.1))],
        }];
        // Custom attributes (kept by exr in a randomly seeded HashMap).
        let meta = ExrMeta {
            pixel_size_m: Some((0.5, 0.25)),
            values: (0..8)
                .map(|k| (format!("value_{k}"), k as f64 * 1.5))
                .collect(),
        };
        // Six writes of `layers` as `name{k}.exr` give the same bytes.
        let same_bytes = |name: &str, layers: &[ExrLayer]| {
            let mut first = None;
            for k in 0..6 {
                let p = dir.join(format!("{name}{k}.exr"));
                write_exr_layers_with(&p, nx, ny, layers, &meta).unwrap();
                let bytes = std::fs::read(&p).unwrap();
                match &first {
                    None => first = Some(bytes),
                    Some(f) => assert!(f == &bytes, "{name}: write {k} differs"),
                }
            }
        };
        same_bytes("img", &layers);
        // Two layers: a multi-part file, one header per part.
        let two = [
            ExrLayer {
                name: "absorbed".into(),
                channels: vec![("red".into(), vals(0.2))],
            },
            ExrLayer {
                name: "scattered".into(),
                channels: vec![("red".into(), vals(0.9)), ("nir".into(), vals(0.4))],
            },
        ];
        same_bytes("two", &two);
        let (_, _, ch) = read_exr_channels(&dir.join("two0.exr")).unwrap();
        let nir = &ch.iter().find(|c| c.0 == "scattered.nir").unwrap().1;
        assert!(nir.iter().zip(vals(0.4)).all(|(x, y)| *x == y as f32));
        let meta = exr::meta::MetaData::read_from_file(dir.join("img0.exr"), false).unwrap();
        assert_eq!(meta.headers[0].line_order, LineOrder::Increasing);
        let (rx, ry, ch) = read_exr_channels(&dir.join("img0.exr")).unwrap();
        assert_eq!((rx, ry), (nx, ny));
        let a = &ch.iter().find(|c| c.0 == "brf.a").unwrap().1;
        assert!(a.iter().zip(vals(0.37)).all(|(x, y)| *x == y as f32));
        let v = read_exr_values(&dir.join("img0.exr")).unwrap();
        assert_eq!(v.len(), 1 + 2 + 8, "{v:?}");
        assert!(v.contains(&("value_7".to_string(), 10.5)));
        assert!(v.contains(&("pixel_size_y_m".to_string(), 0.25)));
        // A corrupt image is an error, not a panic.
        for cut in [0, 7, 20, 60] {
            let mut b = std::fs::read(dir.join("img0.exr")).unwrap()[..cut].to_vec();
            assert!(sort_header_attributes(&mut b).is_err(), "cut {cut}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
