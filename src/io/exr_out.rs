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
    image
        .write()
        .to_file(&tmp)
        .map_err(|e| format!("{}: cannot write EXR: {e}", path.display()))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("{}: cannot write: {e}", path.display())
    })?;
    let _ = write_atomic;
    Ok(())
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
    /// header), whatever order the compression threads finish in; values read back.
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
        let mut first = None;
        for k in 0..6 {
            let p = dir.join(format!("img{k}.exr"));
            write_exr_layers(&p, nx, ny, &layers).unwrap();
            let bytes = std::fs::read(&p).unwrap();
            match &first {
                None => first = Some(bytes),
                Some(f) => assert!(f == &bytes, "write {k} differs"),
            }
        }
        let meta = exr::meta::MetaData::read_from_file(dir.join("img0.exr"), false).unwrap();
        assert_eq!(meta.headers[0].line_order, LineOrder::Increasing);
        let (rx, ry, ch) = read_exr_channels(&dir.join("img0.exr")).unwrap();
        assert_eq!((rx, ry), (nx, ny));
        let a = &ch.iter().find(|c| c.0 == "brf.a").unwrap().1;
        assert!(a.iter().zip(vals(0.37)).all(|(x, y)| *x == y as f32));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
