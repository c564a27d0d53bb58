//! GeoTIFF fixtures for the geospatial tests, written with the `tiff` crate's own image encoder
//! (not lumenscape's writer): single-band DEMs of several sample types and compressions, with
//! a tie point, a pixel scale, GeoKeys (OGC GeoTIFF 1.1 §7) and optionally `GDAL_NODATA`.
#![allow(dead_code)]

use std::io::Cursor;
use tiff::encoder::{Compression, TiffEncoder, colortype};
use tiff::tags::Tag;

/// What a DEM fixture holds: `nx × ny` pixels (row 0 at the top), top-left corner at `tie`
/// (E, N), square pixels of `pixel_m`, in `epsg` (None: no GeoKeys, no tie point).
#[derive(Clone, Debug)]
pub struct Dem {
    pub nx: usize,
    pub ny: usize,
    pub values: Vec<f64>,
    pub tie: (f64, f64),
    pub pixel_m: f64,
    pub epsg: Option<u16>,
    pub nodata: Option<f64>,
    /// 2 = PixelIsPoint, 1 = PixelIsArea.
    pub raster_type: u16,
}

/// Sample type and compression of a fixture.
#[derive(Clone, Copy, Debug)]
pub enum Sample {
    F32,
    F64,
    I16,
    U16,
}

fn geo_tags<
    W: std::io::Write + std::io::Seek,
    C: colortype::ColorType,
    K: tiff::encoder::TiffKind,
>(
    img: &mut tiff::encoder::ImageEncoder<'_, W, C, K>,
    d: &Dem,
) {
    let e = img.encoder();
    if let Some(code) = d.epsg {
        e.write_tag(Tag::ModelPixelScaleTag, &[d.pixel_m, d.pixel_m, 0.0][..])
            .unwrap();
        e.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, d.tie.0, d.tie.1, 0.0][..],
        )
        .unwrap();
        let keys: [u16; 16] = [
            1,
            1,
            1,
            3,
            1024,
            0,
            1,
            1,
            1025,
            0,
            1,
            d.raster_type,
            3072,
            0,
            1,
            code,
        ];
        e.write_tag(Tag::GeoKeyDirectoryTag, &keys[..]).unwrap();
    }
    if let Some(n) = d.nodata {
        e.write_tag(Tag::GdalNodata, format!("{n}").as_str())
            .unwrap();
    }
}

/// The bytes of `d` as a GeoTIFF of sample type `s` with `compression`.
pub fn dem_tiff(d: &Dem, s: Sample, compression: Compression) -> Vec<u8> {
    let mut buf = Cursor::new(Vec::new());
    {
        let mut enc = TiffEncoder::new(&mut buf)
            .unwrap()
            .with_compression(compression);
        let (w, h) = (d.nx as u32, d.ny as u32);
        macro_rules! write {
            ($ct:ty, $conv:expr) => {{
                let data: Vec<_> = d.values.iter().map($conv).collect();
                let mut img = enc.new_image::<$ct>(w, h).unwrap();
                img.rows_per_strip(3).unwrap();
                geo_tags(&mut img, d);
                img.write_data(&data).unwrap();
            }};
        }
        match s {
            Sample::F32 => write!(colortype::Gray32Float, |&v| v as f32),
            Sample::F64 => write!(colortype::Gray64Float, |&v| v),
            Sample::I16 => write!(colortype::GrayI16, |&v| v as i16),
            Sample::U16 => write!(colortype::Gray16, |&v| v as u16),
        }
    }
    buf.into_inner()
}

/// An 8-bit RGB image (three bands) with GeoKeys: not a DEM.
pub fn rgb_tiff() -> Vec<u8> {
    let mut buf = Cursor::new(Vec::new());
    {
        let mut enc = TiffEncoder::new(&mut buf).unwrap();
        enc.write_image::<colortype::RGB8>(2, 2, &[0u8; 12])
            .unwrap();
    }
    buf.into_inner()
}

/// A 16-bit palette (indexed-colour) TIFF: `PhotometricInterpretation` 3 with a colour map.
pub fn palette_tiff() -> Vec<u8> {
    let mut buf = Cursor::new(Vec::new());
    {
        let mut enc = TiffEncoder::new(&mut buf).unwrap();
        let mut dir = enc.image_directory().unwrap();
        let data = [0u16, 1, 2, 3];
        let off = dir.write_data(&data[..]).unwrap() as u32;
        dir.write_tag(Tag::ImageWidth, 2u32).unwrap();
        dir.write_tag(Tag::ImageLength, 2u32).unwrap();
        dir.write_tag(Tag::BitsPerSample, 16u16).unwrap();
        dir.write_tag(Tag::Compression, 1u16).unwrap();
        dir.write_tag(Tag::PhotometricInterpretation, 3u16).unwrap();
        dir.write_tag(Tag::StripOffsets, off).unwrap();
        dir.write_tag(Tag::SamplesPerPixel, 1u16).unwrap();
        dir.write_tag(Tag::RowsPerStrip, 2u32).unwrap();
        dir.write_tag(Tag::StripByteCounts, 8u32).unwrap();
        dir.write_tag(Tag::ColorMap, &vec![0u16; 3 * 65536][..])
            .unwrap();
        dir.finish().unwrap();
    }
    buf.into_inner()
}

/// A 20 × 20 m scene's DEM in EPSG:32631 around the origin (500000, 4800000): 16 × 14 pixels
/// of 2 m from (499990, 4800010) (top-left) — the scene's map extent with 5 m margins — holding
/// a plane plus a cone, in multiples of 1/64 m (exact in f32 and in decimal text).
pub fn scene_dem() -> Dem {
    let (nx, ny, px) = (16, 14, 2.0);
    let tie = (499_990.0, 4_800_026.0);
    let mut values = Vec::new();
    for r in 0..ny {
        for c in 0..nx {
            let e = tie.0 + (c as f64 + 0.5) * px;
            let n = tie.1 - (r as f64 + 0.5) * px;
            let (x, y) = (e - 500_010.0, n - 4_800_010.0);
            let z = 3.0 + 0.1 * x - 0.05 * y + (4.0 - 0.3 * x.hypot(y)).max(0.0);
            values.push((z * 64.0).round() / 64.0);
        }
    }
    Dem {
        nx,
        ny,
        values,
        tie,
        pixel_m: px,
        epsg: Some(32631),
        nodata: None,
        raster_type: 1,
    }
}

/// The pixels of columns `c0..=c1` and rows `r0..=r1` of `d`, as a DEM of their own.
pub fn crop(d: &Dem, c0: usize, c1: usize, r0: usize, r1: usize) -> Dem {
    let mut values = Vec::new();
    for r in r0..=r1 {
        for c in c0..=c1 {
            values.push(d.values[c + d.nx * r]);
        }
    }
    Dem {
        nx: c1 - c0 + 1,
        ny: r1 - r0 + 1,
        values,
        tie: (
            d.tie.0 + c0 as f64 * d.pixel_m,
            d.tie.1 - r0 as f64 * d.pixel_m,
        ),
        ..d.clone()
    }
}

/// A DEM as an ESRI ASCII grid of the same nodes (cell centres).
pub fn esri_ascii(d: &Dem) -> String {
    let mut s = format!(
        "ncols {}\nnrows {}\nxllcorner {}\nyllcorner {}\ncellsize {}\nnodata_value -9999\n",
        d.nx,
        d.ny,
        d.tie.0,
        d.tie.1 - d.ny as f64 * d.pixel_m,
        d.pixel_m
    );
    for r in 0..d.ny {
        let row: Vec<String> = (0..d.nx)
            .map(|c| format!("{}", d.values[c + d.nx * r]))
            .collect();
        s.push_str(&row.join(" "));
        s.push('\n');
    }
    s
}

/// Writes `text` (and `files`) into a fresh folder `lumenscape-<suite>-<pid>/<name>` and runs
/// `cmd` (`run` or `maket`) on it; returns the output folder (asserts success).
pub fn run_scene(
    suite: &str,
    name: &str,
    cmd: &str,
    text: &str,
    files: &[(&str, &[u8])],
) -> std::path::PathBuf {
    let dir = std::env::temp_dir()
        .join(format!("lumenscape-{suite}-{}", std::process::id()))
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("scene.ron");
    std::fs::write(&scene, text).unwrap();
    for (n, b) in files {
        std::fs::write(dir.join(n), b).unwrap();
    }
    let out = dir.join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_lumenscape"))
        .args([
            cmd,
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    out
}
