//! Geospatial landscapes (issue #37), stage-level through the built binary:
//!
//! * the GeoTIFF products read back by an independent reader (the `tiff` crate's decoder, tags
//!   and strips read directly) hold the EXR's pixel values bit for bit, the scene's tie point,
//!   pixel scale (or model transformation for a rotated scene) and EPSG code, and the band
//!   names and wavelengths; the ENVI header parses to the same placement and bands and its raw
//!   file holds the same values;
//! * a scene without a georeference writes no geospatial file;
//! * a DEM given as a GeoTIFF (f32 LZW, f64 Deflate, i16, u16; written by the `tiff` crate's
//!   own image encoder) gives products byte-identical to the same DEM given as ESRI ASCII, and
//!   an analytic plane + cone as an f64 GeoTIFF gives the DSM of the same surface given inline
//!   to 1e-6 m;
//! * a `sun_position` without a place takes the latitude, longitude and true bearing of +x of
//!   the scene centre from the georeference (PROJ's values).

#[path = "common/geo.rs"]
mod geo;
use geo::{Dem, Sample, crop, dem_tiff, esri_ascii, scene_dem};
use lumenscape::io::envi::{envi_list, parse_envi_header};
use lumenscape::io::exr_out::read_exr_channels;
use std::path::{Path, PathBuf};
use tiff::decoder::{Decoder, DecodingResult};
use tiff::encoder::Compression;
use tiff::tags::Tag;

const GEO: &str = "(crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0))";

/// A 20 m × 20 m two-band scene with sky light, a tree and a grass plot, two exact views and
/// images of 1 m pixels (2 m cells, η = 2).
fn scene(georeference: &str, topography: &str) -> String {
    format!(
        r#"(
    version: 1,
    {georeference}
    grid: (size_m: (20.0, 20.0), cell_m: (2.0, 2.0, 1.0), boundary: Isolated),
    bands: [(name: "red", wavelength_nm: 670.0), (name: "nir", wavelength_nm: 865.0)],
    optics: {{
        "leaf": BiLambertian(reflectance: [0.05, 0.45], transmittance: [0.02, 0.4]),
        "veg": Turbid(leaf: "leaf", lad: Spherical),
        "soil": Lambertian(reflectance: [0.1, 0.25]),
    }},
    illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 20.0, skyl: [0.1, 0.1]),
    directions: (count: 40, exact: [(zenith_deg: 0.0, azimuth_deg: 0.0), (zenith_deg: 30.0, azimuth_deg: 90.0)]),
    radiative: (preset: Preview, image_oversampling: 2),
    objects: [
        Ground((optics: "soil", topography: {topography})),
        Tree((position_m: (12.0, 11.0),
              crown: (shape: Ellipsoid, base_height_m: 2.0, height_m: 4.0, radius_x_m: 3.0,
                      foliage: Lai(2.0), optics: "veg"))),
        TurbidPlot((footprint: Box((1.0, 1.0, 7.0, 6.0)), bottom_m: 0.0, top_m: 1.0,
                    foliage: Lai(1.5), optics: "veg")),
    ],
)
"#
    )
}

/// Writes `text` (and `files`) into a fresh folder and runs `cmd` (`run` or `maket`) on it;
/// returns the output folder.
fn run(name: &str, cmd: &str, text: &str, files: &[(&str, &[u8])]) -> PathBuf {
    geo::run_scene("geo", name, cmd, text, files)
}

/// What the independent reader finds in a product GeoTIFF.
struct Tif {
    size: (usize, usize),
    bands: Vec<Vec<f32>>,
    names: Vec<String>,
    wavelengths: Vec<f64>,
    scale: Option<Vec<f64>>,
    tie: Option<Vec<f64>>,
    matrix: Option<Vec<f64>>,
    keys: Vec<u16>,
}

fn read_tif(p: &Path) -> Tif {
    let bytes = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let mut d = Decoder::new(std::io::Cursor::new(bytes)).unwrap();
    let (w, h) = d.dimensions().unwrap();
    let nb = d.get_tag_u32(Tag::SamplesPerPixel).unwrap() as usize;
    assert_eq!(d.get_tag_u32(Tag::PlanarConfiguration).unwrap(), 2);
    assert_eq!(d.get_tag_u16_vec(Tag::SampleFormat).unwrap(), vec![3; nb]);
    assert_eq!(d.get_tag_u16_vec(Tag::BitsPerSample).unwrap(), vec![32; nb]);
    let mut bands = Vec::new();
    for k in 0..nb {
        match d.read_chunk(k as u32).unwrap() {
            DecodingResult::F32(v) => bands.push(v),
            _ => panic!("{}: band {k} is not f32", p.display()),
        }
    }
    let f64s = |d: &mut Decoder<_>, t| {
        d.find_tag(t)
            .unwrap()
            .map(|v: tiff::decoder::ifd::Value| v.into_f64_vec().unwrap())
    };
    let scale = f64s(&mut d, Tag::ModelPixelScaleTag);
    let tie = f64s(&mut d, Tag::ModelTiepointTag);
    let matrix = f64s(&mut d, Tag::ModelTransformationTag);
    let keys = d.get_tag_u16_vec(Tag::GeoKeyDirectoryTag).unwrap();
    let xml = d.get_tag_ascii_string(Tag::Unknown(42112)).unwrap();
    let item = |name: &str, k: usize| -> Option<String> {
        let open = format!("<Item name=\"{name}\" sample=\"{k}\"");
        let at = xml.find(&open)?;
        let rest = &xml[at..];
        let v = &rest[rest.find('>')? + 1..];
        Some(v[..v.find('<')?].to_string())
    };
    let names = (0..nb)
        .map(|k| item("DESCRIPTION", k).expect("band description"))
        .collect();
    let wavelengths = (0..nb)
        .filter_map(|k| item("wavelength", k).map(|s| s.parse().unwrap()))
        .collect();
    Tif {
        size: (w as usize, h as usize),
        bands,
        names,
        wavelengths,
        scale,
        tie,
        matrix,
        keys,
    }
}

/// The GeoKey (location 0) `id`, if present.
fn key(keys: &[u16], id: u16) -> Option<u16> {
    keys[4..]
        .chunks(4)
        .find(|k| k[0] == id && k[1] == 0)
        .map(|k| k[3])
}

/// Checks one product stem (`images/view_…`, `lai`, `dsm`): the GeoTIFF and the ENVI pair
/// against the EXR, and their placement against the georeference (origin (500000, 4800000),
/// 20 m scene, north-up), pixels of `px` m; `spectral`: the bands carry wavelengths.
fn check_product(out: &Path, stem: &str, px: f64, spectral: bool) {
    let (nx, ny, exr) = read_exr_channels(&out.join(format!("{stem}.exr"))).unwrap();
    let t = read_tif(&out.join(format!("{stem}.tif")));
    assert_eq!(t.size, (nx, ny), "{stem}: size");
    assert_eq!(t.bands.len(), exr.len(), "{stem}: one band per EXR channel");
    for (name, band) in t.names.iter().zip(&t.bands) {
        let (_, v) = exr
            .iter()
            .find(|(n, _)| n == name || n.ends_with(&format!(".{name}")))
            .unwrap_or_else(|| panic!("{stem}: band `{name}` is no EXR channel"));
        for r in 0..ny {
            for c in 0..nx {
                let (a, b) = (band[c + nx * r], v[c + nx * (ny - 1 - r)]);
                assert!(
                    a.to_bits() == b.to_bits(),
                    "{stem} `{name}` pixel ({c}, {r}): {a} ≠ EXR {b}"
                );
            }
        }
    }
    // Placement: top-left corner = map of the scene point (0, 20); pixel scale = pixel size.
    assert_eq!(t.scale, Some(vec![px, px, 0.0]), "{stem}: pixel scale");
    assert_eq!(
        t.tie,
        Some(vec![0.0, 0.0, 0.0, 500_000.0, 4_800_020.0, 0.0]),
        "{stem}: tie point"
    );
    assert!(
        t.matrix.is_none(),
        "{stem}: north-up needs no transformation"
    );
    assert_eq!(
        key(&t.keys, 3072),
        Some(32631),
        "{stem}: ProjectedCRSGeoKey"
    );
    assert_eq!(key(&t.keys, 1024), Some(1), "{stem}: GTModelTypeGeoKey");
    assert_eq!(key(&t.keys, 1025), Some(1), "{stem}: GTRasterTypeGeoKey");
    if spectral {
        let want: Vec<f64> = t
            .names
            .iter()
            .map(|n| if n.contains("_red") { 670.0 } else { 865.0 })
            .collect();
        assert_eq!(t.wavelengths, want, "{stem}: wavelengths");
    } else {
        assert!(t.wavelengths.is_empty(), "{stem}: no wavelengths");
    }
    // ENVI: the header parses back to the same grid, placement and bands; the raw file holds
    // the GeoTIFF's values, band after band.
    let h = parse_envi_header(&std::fs::read_to_string(out.join(format!("{stem}.hdr"))).unwrap())
        .unwrap();
    assert_eq!(h["samples"], nx.to_string());
    assert_eq!(h["lines"], ny.to_string());
    assert_eq!(h["bands"], t.bands.len().to_string());
    assert_eq!(
        (&*h["data type"], &*h["interleave"], &*h["byte order"]),
        ("4", "bsq", "0")
    );
    let p = format!("{px}");
    assert_eq!(
        envi_list(&h["map info"]),
        [
            "UTM",
            "1",
            "1",
            "500000",
            "4800020",
            &p,
            &p,
            "31",
            "North",
            "WGS-84",
            "units=Meters"
        ],
        "{stem}: map info"
    );
    assert!(h["coordinate system string"].contains("UTM zone 31N"));
    assert_eq!(envi_list(&h["band names"]), t.names, "{stem}: band names");
    if spectral {
        let w: Vec<f64> = envi_list(&h["wavelength"])
            .iter()
            .map(|s| s.parse().unwrap())
            .collect();
        assert_eq!(w, t.wavelengths);
    }
    let raw = std::fs::read(out.join(format!("{stem}.dat"))).unwrap();
    let vals: Vec<f32> = raw
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(vals, t.bands.concat(), "{stem}: ENVI raw values");
}

/// The DSM channel of `out` and its largest difference from `reference`'s, m.
fn dsm_difference(out: &Path, reference: &Path) -> (Vec<(String, Vec<f32>)>, f32) {
    let (_, _, a) = read_exr_channels(&out.join("dsm.exr")).unwrap();
    let (_, _, b) = read_exr_channels(&reference.join("dsm.exr")).unwrap();
    let worst = a[0]
        .1
        .iter()
        .zip(&b[0].1)
        .map(|(x, y)| (x - y).abs())
        .fold(0f32, f32::max);
    (a, worst)
}

#[test]
fn geotiff_and_envi_products_equal_the_exr_and_carry_the_georeference() {
    let out = run(
        "products",
        "run",
        &scene(&format!("georeference: {GEO},"), "Flat"),
        &[],
    );
    check_product(&out, "images/view_000.0_000.0", 1.0, true);
    check_product(&out, "images/view_030.0_090.0", 1.0, true);
    check_product(&out, "lai", 2.0, false);
    check_product(&out, "dsm", 2.0, false);
    // Sky light: every brf band, then every hdrf band.
    let t = read_tif(&out.join("images/view_000.0_000.0.tif"));
    assert_eq!(
        t.names,
        ["brf.00_red", "brf.01_nir", "hdrf.00_red", "hdrf.01_nir"]
    );
}

/// A rotated scene (+x at bearing 30°) is placed by a model transformation whose pixel corners
/// are the map images of the scene's corners; ENVI gets the rotation 90° − 30° = 60°.
#[test]
fn rotated_scene_is_placed_by_the_model_transformation() {
    let geo = "(crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0), x_axis_bearing_deg: 30.0)";
    let out = run(
        "rotated",
        "maket",
        &scene(&format!("georeference: {geo},"), "Flat"),
        &[],
    );
    let t = read_tif(&out.join("dsm.tif"));
    assert!(t.scale.is_none() && t.tie.is_none());
    let m = t.matrix.expect("ModelTransformationTag");
    let (nx, ny) = (t.size.0 as f64, t.size.1 as f64);
    let map = |c: f64, r: f64| (m[0] * c + m[1] * r + m[3], m[4] * c + m[5] * r + m[7]);
    let (s, co) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
    for ((c, r), (x, y)) in [
        ((0.0, ny), (0.0, 0.0)),
        ((nx, ny), (20.0, 0.0)),
        ((0.0, 0.0), (0.0, 20.0)),
        ((nx, 0.0), (20.0, 20.0)),
    ] {
        let (e, n) = map(c, r);
        let (we, wn) = (500_000.0 + x * s - y * co, 4_800_000.0 + x * co + y * s);
        assert!(
            (e - we).abs() < 1e-6 && (n - wn).abs() < 1e-6,
            "corner ({c}, {r}): ({e}, {n}) against ({we}, {wn})"
        );
    }
    let h = parse_envi_header(&std::fs::read_to_string(out.join("dsm.hdr")).unwrap()).unwrap();
    let rot = envi_list(&h["map info"]).pop().unwrap();
    let deg: f64 = rot.strip_prefix("rotation=").unwrap().parse().unwrap();
    assert!((deg - 60.0).abs() < 1e-9, "{rot}");
}

/// Without a georeference no geospatial file is written.
#[test]
fn no_georeference_no_geospatial_file() {
    let out = run("plain", "run", &scene("", "Flat"), &[]);
    let mut files = Vec::new();
    for d in [out.clone(), out.join("images")] {
        for e in std::fs::read_dir(d).unwrap() {
            files.push(e.unwrap().file_name().to_string_lossy().into_owned());
        }
    }
    assert!(files.iter().any(|f| f.ends_with(".exr")));
    assert!(
        !files
            .iter()
            .any(|f| f.ends_with(".tif") || f.ends_with(".hdr") || f.ends_with(".dat")),
        "{files:?}"
    );
}

/// Every product file under `out` (relative path, bytes), except the ones that record timings
/// or memory (`summary.json`, `maket.json`).
fn products(out: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    for d in [
        PathBuf::new(),
        PathBuf::from("images"),
        PathBuf::from("budget"),
    ] {
        let Ok(rd) = std::fs::read_dir(out.join(&d)) else {
            continue;
        };
        for e in rd {
            let p = e.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            if p.is_file() && name != "summary.json" && name != "maket.json" {
                v.push((
                    d.join(&name).display().to_string(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    v.sort();
    v
}

fn assert_same_files(a: &Path, b: &Path, what: &str) {
    let (pa, pb) = (products(a), products(b));
    let names = |p: &[(String, Vec<u8>)]| p.iter().map(|x| x.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(&pa), names(&pb), "{what}: file lists");
    assert!(pa.len() >= 8, "{what}: {:?}", names(&pa));
    for ((n, x), (_, y)) in pa.iter().zip(&pb) {
        assert!(x == y, "{what}: {n} differs");
    }
}

const ESRI: &str =
    r#"RasterFile((path: "dem.asc", format: EsriAscii, origin_m: (500000.0, 4800000.0)))"#;
const GEOTIFF: &str = r#"RasterFile((path: "dem.tif", format: GeoTiff))"#;

/// The nodes of [`scene_dem`] the scene's map extent needs: columns 4..=15, rows 2..=13.
fn needed(d: &Dem) -> Dem {
    crop(d, 4, 15, 2, 13)
}

#[test]
fn dem_geotiff_gives_the_products_of_the_same_esri_ascii_dem() {
    let geo = format!("georeference: {GEO},");
    let dem = scene_dem();
    let asc = esri_ascii(&needed(&dem));
    let reference = run(
        "dem_esri",
        "run",
        &scene(&geo, ESRI),
        &[("dem.asc", asc.as_bytes())],
    );
    for (name, s, comp) in [
        ("dem_f32_lzw", Sample::F32, Compression::Lzw),
        (
            "dem_f64_deflate",
            Sample::F64,
            Compression::Deflate(Default::default()),
        ),
    ] {
        let tif = dem_tiff(&dem, s, comp);
        let out = run(name, "run", &scene(&geo, GEOTIFF), &[("dem.tif", &tif)]);
        assert_same_files(&reference, &out, name);
    }
    // The whole raster as ESRI ASCII (nodes beyond the scene too) gives the same products as
    // well: the crop keeps every node a facet inside the scene uses.
    let whole = run(
        "dem_esri_whole",
        "maket",
        &scene(&geo, ESRI),
        &[("dem.asc", esri_ascii(&dem).as_bytes())],
    );
    let cropped = run(
        "dem_tif_maket",
        "maket",
        &scene(&geo, GEOTIFF),
        &[(
            "dem.tif",
            &dem_tiff(&dem, Sample::F32, Compression::Uncompressed),
        )],
    );
    for f in ["dsm.exr", "lai.exr", "density.csv"] {
        assert!(
            std::fs::read(whole.join(f)).unwrap() == std::fs::read(cropped.join(f)).unwrap(),
            "{f}: whole ESRI raster against the cropped GeoTIFF"
        );
    }
    // Integer sample types: i16 and u16 rasters of whole metres against the same ESRI grid;
    // a no-data value outside the scene's extent is harmless.
    let mut int = dem.clone();
    for v in &mut int.values {
        *v = v.round() + 100.0;
    }
    int.values[0] = -9999.0;
    int.nodata = Some(-9999.0);
    let asc = esri_ascii(&needed(&int));
    let reference = run(
        "int_esri",
        "maket",
        &scene(&geo, ESRI),
        &[("dem.asc", asc.as_bytes())],
    );
    let mut unsigned = int.clone();
    unsigned.values[0] = 0.0;
    unsigned.nodata = Some(0.0);
    for (name, d, s) in [
        ("int_i16", &int, Sample::I16),
        ("int_u16", &unsigned, Sample::U16),
    ] {
        let tif = dem_tiff(d, s, Compression::Uncompressed);
        let out = run(name, "maket", &scene(&geo, GEOTIFF), &[("dem.tif", &tif)]);
        for f in ["dsm.exr", "lai.exr", "density.csv", "dsm.tif"] {
            assert!(
                std::fs::read(reference.join(f)).unwrap() == std::fs::read(out.join(f)).unwrap(),
                "{name}: {f} differs from the ESRI ASCII run"
            );
        }
    }
}

/// An analytic plane + cone stored as an f64 GeoTIFF (PixelIsPoint: values at the tie-point
/// lattice) gives the DSM of the same surface given inline to 1e-6 m.
#[test]
fn dem_geotiff_of_an_analytic_surface_gives_the_analytic_ground() {
    let surface = |x: f64, y: f64| {
        3.0 + 0.1 * x - 0.05 * y + (4.0 - 0.3 * (x - 10.0).hypot(y - 9.0)).max(0.0)
    };
    // Nodes every 2 m from scene (−2, −2) to (22, 22): 13 × 13.
    let n = 13;
    let mut values = Vec::new();
    for r in 0..n {
        for c in 0..n {
            values.push(surface(-2.0 + 2.0 * c as f64, 22.0 - 2.0 * r as f64));
        }
    }
    let dem = Dem {
        nx: n,
        ny: n,
        values,
        tie: (499_998.0, 4_800_022.0),
        pixel_m: 2.0,
        epsg: Some(32631),
        nodata: None,
        raster_type: 2,
    };
    let tif = dem_tiff(&dem, Sample::F64, Compression::Uncompressed);
    let geo = format!("georeference: {GEO},");
    let out = run(
        "analytic_tif",
        "maket",
        &scene(&geo, GEOTIFF),
        &[("dem.tif", &tif)],
    );
    let mut alt = Vec::new();
    for j in 0..n {
        for i in 0..n {
            alt.push(format!(
                "{:?}",
                surface(-2.0 + 2.0 * i as f64, -2.0 + 2.0 * j as f64)
            ));
        }
    }
    let inline = format!(
        "Raster((nodes: ({n}, {n}), spacing_m: (2.0, 2.0), origin_m: (-2.0, -2.0), altitude_m: [{}]))",
        alt.join(", ")
    );
    let reference = run("analytic_inline", "maket", &scene(&geo, &inline), &[]);
    let (_, worst) = dsm_difference(&out, &reference);
    assert!(worst <= 1e-6, "DSM differs by {worst} m");
    // The ground facets themselves: the same leaf-free ground area and the same density file.
    assert_eq!(
        std::fs::read(out.join("density.csv")).unwrap(),
        std::fs::read(reference.join("density.csv")).unwrap()
    );
}

/// The sun from a date alone in a georeferenced scene: the latitude and longitude of the scene
/// centre and the true bearing of +x (grid bearing + meridian convergence) come from the
/// georeference; the angles equal those of the same date with the place and bearing that PROJ
/// gives for that point (GDAL 3.6 `gdaltransform`, EPSG:32631 → EPSG:4326).
#[test]
fn the_sun_position_takes_its_place_from_the_georeference() {
    use lumenscape::scene::{SceneSource, parse_scene, resolve};
    let resolve = |text: &str| {
        let d = parse_scene(text, Path::new("<test>")).unwrap();
        let src = SceneSource {
            path: "<test>".into(),
            text: Some(text.to_string()),
        };
        lumenscape::scene::validate::validate(&d, &src).unwrap_or_else(|e| panic!("{e}"));
        resolve::illumination(&d, &src).unwrap_or_else(|e| panic!("{e}"))
    };
    // The sun of a scene placed by `geo` (centre at latitude `lat`, longitude `lon` by PROJ,
    // grid north `gamma` east of true north there) equals the sun of the same scene given
    // that place and the true bearing of +x (90° + γ) by hand.
    let check = |geo: &str, lat: f64, lon: f64, gamma: f64| {
        let by_map = scene(geo, "Flat").replace(
            "illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 20.0,",
            "illumination: (sun_position: (utc: \"2024-06-21T09:30:00\"),",
        );
        let by_hand = scene("", "Flat").replace(
            "illumination: (sun_zenith_deg: 30.0, sun_azimuth_deg: 20.0,",
            &format!(
                "illumination: (sun_position: (utc: \"2024-06-21T09:30:00\", latitude_deg: {lat}, longitude_deg: {lon}, scene_x_bearing_deg: {}),",
                90.0 + gamma
            ),
        );
        let (m, h) = (resolve(&by_map), resolve(&by_hand));
        let (zm, am) = (
            m.illumination.sun_zenith_deg,
            m.illumination.sun_azimuth_deg,
        );
        let (zh, ah) = (
            h.illumination.sun_zenith_deg,
            h.illumination.sun_azimuth_deg,
        );
        assert!(gamma > 1.0, "convergence {gamma}°");
        assert!(
            (zm - zh).abs() < 1e-6 && (am - ah).abs() < 1e-5,
            "{geo}: ({zm}, {am}) against ({zh}, {ah})"
        );
    };
    // UTM 31N, scene centre at (650000, 4800000): 150 km east of the central meridian.
    // PROJ: the centre at (43.3378837055532 N, 4.85045491139206 E); 10 m grid north at
    // (43.3379737040746, 4.85045764532076).
    let (lat, lon) = (43.3378837055532f64, 4.85045491139206f64);
    let (a, f) = (6_378_137.0f64, 1.0 / 298.257_223_563f64);
    let e2 = f * (2.0 - f);
    let w = (1.0 - e2 * lat.to_radians().sin().powi(2)).sqrt();
    let dn = (43.3379737040746f64 - lat).to_radians() * a * (1.0 - e2) / w.powi(3);
    let de = (4.85045764532076f64 - lon).to_radians() * a / w * lat.to_radians().cos();
    check(
        "georeference: (crs: Epsg(32631), origin_map_m: (649990.0, 4799990.0)),",
        lat,
        lon,
        de.atan2(dn).to_degrees(),
    );
    // Lambert-93 (EPSG:2154, Lambert conformal conic), centre at PROJ's grid point of 45° N,
    // 5° E, (857581.8993196681, 6435414.747835401); PROJ's meridian convergence there
    // 1.4512155301030194° (pyproj 3.7.2, PROJ 9.5.1).
    check(
        "georeference: (crs: Epsg(2154), origin_map_m: (857571.8993196681, 6435404.747835401)),",
        45.0,
        5.0,
        1.4512155301030194,
    );
}

/// Under a rotated scene (+x at bearing 60°) a GeoTIFF DEM becomes a TIN through its nodes in
/// scene coordinates: a plane in the map gives the Maket the same ground as the same plane
/// given inline in scene coordinates (any triangulation of a plane is the plane), to 1e-6 m.
#[test]
fn rotated_scene_dem_is_the_same_plane() {
    let geo = "georeference: (crs: Epsg(32631), origin_map_m: (500000.0, 4800000.0), x_axis_bearing_deg: 60.0),";
    let plane = |e: f64, n: f64| 100.0 + 0.03 * (e - 500_000.0) - 0.02 * (n - 4_800_000.0);
    // 2 m pixels from (499980, 4800032): nodes E 499981…500019, N 4800031…4799981.
    let (nx, ny) = (20, 26);
    let tie = (499_980.0, 4_800_032.0);
    let mut values = Vec::new();
    for r in 0..ny {
        for c in 0..nx {
            values.push(plane(
                tie.0 + 1.0 + 2.0 * c as f64,
                tie.1 - 1.0 - 2.0 * r as f64,
            ));
        }
    }
    let dem = Dem {
        nx,
        ny,
        values,
        tie,
        pixel_m: 2.0,
        epsg: Some(32631),
        nodata: None,
        raster_type: 1,
    };
    let tif = dem_tiff(&dem, Sample::F64, Compression::Uncompressed);
    let out = run(
        "rotated_dem",
        "maket",
        &scene(geo, GEOTIFF),
        &[("dem.tif", &tif)],
    );
    // The same plane in scene coordinates: E − E0 = x sin β − y cos β, N − N0 = x cos β + y sin β.
    let (s, c) = 60f64.to_radians().sin_cos();
    let n = 13;
    let mut alt = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (-2.0 + 2.0 * i as f64, -2.0 + 2.0 * j as f64);
            alt.push(format!(
                "{:?}",
                plane(500_000.0 + x * s - y * c, 4_800_000.0 + x * c + y * s)
            ));
        }
    }
    let inline = format!(
        "Raster((nodes: ({n}, {n}), spacing_m: (2.0, 2.0), origin_m: (-2.0, -2.0), altitude_m: [{}]))",
        alt.join(", ")
    );
    let reference = run("rotated_inline", "maket", &scene(geo, &inline), &[]);
    let (a, worst) = dsm_difference(&out, &reference);
    // f32 in the EXR: 2 ulp at 100 m.
    assert!(worst <= 1.6e-5, "DSM differs by {worst} m");
    // The plane's slope shows: the DSM is not flat.
    let (lo, hi) = a[0]
        .1
        .iter()
        .fold((f32::MAX, f32::MIN), |m, &v| (m.0.min(v), m.1.max(v)));
    assert!(hi - lo > 0.5, "DSM range {lo}..{hi}");
}
