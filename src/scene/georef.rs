//! The scene's georeference (issue #37): its CRS resolved (an EPSG code looked up in the EPSG
//! table of the `crs-definitions` crate, or a WKT definition), the map placement of scene
//! points, and the pixel-to-map transform of a product raster (OGC GeoTIFF 1.1 §7.1.2; GDAL's
//! six-coefficient convention), and the geodetic latitude, longitude and true bearing of +x of
//! a scene point for the sun position (transverse Mercator grids, `physics::geodesy`). Scene
//! coordinates are metres with +x at the grid bearing β (clockwise from grid north) and +y 90°
//! anticlockwise from +x: a point (x, y) lies at E = E₀ + x·sin β − y·cos β,
//! N = N₀ + x·cos β + y·sin β.

use crate::io::geotiff::{MapPlacement, TiffCrs};
use crate::physics::geodesy::{LambertConformal, MapProjection, TransverseMercator};
use crate::scene::desc::{CrsDesc, GeoreferenceDesc};

/// A resolved projected CRS in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct MapCrs {
    /// The EPSG code, when known (given, or the WKT's authority code).
    pub epsg: Option<u32>,
    /// Its name (the WKT's first quoted string).
    pub name: String,
    /// Its WKT definition.
    pub wkt: String,
    /// Its PROJ string, when known (EPSG codes).
    pub proj4: Option<String>,
}

/// Why a CRS is not accepted (the message for the `georeference.crs` field).
pub fn resolve_crs(c: &CrsDesc) -> Result<MapCrs, String> {
    match c {
        CrsDesc::Epsg(code) => {
            let def = u16::try_from(*code)
                .ok()
                .and_then(crs_definitions::from_code)
                .ok_or_else(|| {
                    format!("EPSG:{code} is not a known EPSG CRS code (see epsg.io for the code of your map)")
                })?;
            let proj = def.proj4;
            if proj.contains("+proj=longlat") || proj.contains("+proj=geocent") {
                return Err(format!(
                    "EPSG:{code} is a geographic CRS (degrees); give a projected CRS in metres, \
                     e.g. the UTM zone of the scene (EPSG:326zz north, 327zz south)"
                ));
            }
            if !proj.contains("+units=m ") && !proj.ends_with("+units=m") {
                return Err(format!(
                    "EPSG:{code} is not in metres ({proj}); give a projected CRS in metres"
                ));
            }
            Ok(MapCrs {
                epsg: Some(*code),
                name: wkt_name(def.wkt),
                wkt: def.wkt.to_string(),
                proj4: Some(proj.to_string()),
            })
        }
        CrsDesc::Wkt(w) => {
            let t = w.trim();
            if !(t.starts_with("PROJCS[") || t.starts_with("PROJCRS[")) {
                return Err(
                    "the WKT must define a projected CRS (start with `PROJCS[` or `PROJCRS[`)"
                        .into(),
                );
            }
            let u = t.to_ascii_lowercase().replace(' ', "");
            if !(u.contains("unit[\"metre\"") || u.contains("unit[\"meter\"")) {
                return Err("the WKT's unit must be the metre (`UNIT[\"metre\",1]`)".into());
            }
            let epsg = wkt_epsg(t);
            Ok(MapCrs {
                epsg,
                name: wkt_name(t),
                wkt: t.to_string(),
                proj4: epsg
                    .and_then(|c| u16::try_from(c).ok())
                    .and_then(crs_definitions::from_code)
                    .map(|d| d.proj4.to_string()),
            })
        }
    }
}

/// The first quoted string of a WKT (the CRS name).
fn wkt_name(w: &str) -> String {
    w.split('"').nth(1).unwrap_or("unnamed").to_string()
}

/// The EPSG code of a WKT's outermost authority (`AUTHORITY["EPSG","32631"]` of WKT 1 or
/// `ID["EPSG",32631]` of WKT 2: the last one in the text, and only when it closes the CRS,
/// not when it belongs to an inner element).
fn wkt_epsg(w: &str) -> Option<u32> {
    let compact: String = w.chars().filter(|c| !c.is_whitespace()).collect();
    let (a, b) = (
        compact.rfind("AUTHORITY[\"EPSG\","),
        compact.rfind("ID[\"EPSG\","),
    );
    let start = match (a, b) {
        (Some(a), Some(b)) => a.max(b),
        (a, b) => a.or(b)?,
    };
    let rest = &compact[start..];
    if &rest[rest.find(']')? + 1..] != "]" {
        return None;
    }
    let rest = &rest[rest.find(',')? + 1..];
    let digits: String = rest
        .trim_start_matches('"')
        .chars()
        .take_while(char::is_ascii_digit)
        .collect();
    digits.parse().ok()
}

/// The scene's resolved georeference.
#[derive(Debug, Clone, PartialEq)]
pub struct Georeference {
    /// The map CRS.
    pub crs: MapCrs,
    /// Map coordinates (E₀, N₀) of the scene origin, m.
    pub origin_map_m: (f64, f64),
    /// Grid bearing β of +x, degrees clockwise from grid north.
    pub x_axis_bearing_deg: f64,
}

/// (sin, cos) of an angle in degrees, exact at multiples of 90°.
fn sin_cos_deg(deg: f64) -> (f64, f64) {
    let r = deg.rem_euclid(360.0);
    match r {
        0.0 => (0.0, 1.0),
        90.0 => (1.0, 0.0),
        180.0 => (0.0, -1.0),
        270.0 => (-1.0, 0.0),
        _ => r.to_radians().sin_cos(),
    }
}

/// The map projection of a PROJ string — transverse Mercator (`+proj=utm +zone=Z [+south]`
/// or `+proj=tmerc +lat_0 +lon_0 +k +x_0 +y_0`) or Lambert conformal conic (`+proj=lcc
/// +lat_0 +lon_0 +lat_1 [+lat_2] [+k_0] +x_0 +y_0`), ellipsoid from `+ellps` or `+datum` — or
/// why not.
pub fn map_projection(proj4: &str) -> Result<MapProjection, String> {
    let param = |k: &str| -> Option<&str> {
        proj4
            .split_whitespace()
            .find_map(|t| t.strip_prefix('+')?.strip_prefix(k)?.strip_prefix('='))
    };
    let num = |k: &str, default: f64| -> Result<f64, String> {
        param(k).map_or(Ok(default), |v| {
            v.parse()
                .map_err(|_| format!("`+{k}={v}` is not a number in `{proj4}`"))
        })
    };
    let ellipsoid = match param("ellps").or(match param("datum") {
        Some("WGS84") => Some("WGS84"),
        Some("NAD83") => Some("GRS80"),
        Some("NAD27") => Some("clrk66"),
        _ => None,
    }) {
        Some("WGS84") => (6_378_137.0, 298.257_223_563),
        Some("GRS80") => (6_378_137.0, 298.257_222_101),
        Some("intl") => (6_378_388.0, 297.0),
        Some("bessel") => (6_377_397.155, 299.152_812_8),
        Some("clrk66") => (6_378_206.4, 294.978_698_2),
        Some("airy") => (6_377_563.396, 299.324_964_6),
        other => {
            return Err(format!(
                "the ellipsoid {} of `{proj4}` is not one lumenscape knows (WGS84, GRS80, intl, \
                 bessel, clrk66, airy)",
                other.unwrap_or("(none)")
            ));
        }
    };
    match param("proj") {
        Some("utm") => {
            let zone = num("zone", f64::NAN)?;
            if !(1.0..=60.0).contains(&zone) || zone.fract() != 0.0 {
                return Err(format!("no UTM zone in `{proj4}`"));
            }
            let south = proj4.split_whitespace().any(|t| t == "+south");
            Ok(MapProjection::TransverseMercator(TransverseMercator::utm(
                zone as u32,
                south,
                ellipsoid,
            )))
        }
        Some("tmerc") => Ok(MapProjection::TransverseMercator(TransverseMercator {
            a_m: ellipsoid.0,
            f: 1.0 / ellipsoid.1,
            lon0_deg: num("lon_0", 0.0)?,
            lat0_deg: num("lat_0", 0.0)?,
            k0: num("k", num("k_0", 1.0)?)?,
            false_easting_m: num("x_0", 0.0)?,
            false_northing_m: num("y_0", 0.0)?,
        })),
        Some("lcc") => {
            let lat1 = num("lat_1", f64::NAN)?;
            if !lat1.is_finite() || lat1 == 0.0 {
                return Err(format!("no standard parallel (+lat_1, not 0) in `{proj4}`"));
            }
            Ok(MapProjection::LambertConformal(LambertConformal {
                a_m: ellipsoid.0,
                f: 1.0 / ellipsoid.1,
                lat0_deg: num("lat_0", lat1)?,
                lon0_deg: num("lon_0", 0.0)?,
                lat1_deg: lat1,
                lat2_deg: num("lat_2", lat1)?,
                k0: num("k_0", num("k", 1.0)?)?,
                false_easting_m: num("x_0", 0.0)?,
                false_northing_m: num("y_0", 0.0)?,
            }))
        }
        _ => Err(format!(
            "latitude and longitude are derived for transverse Mercator (UTM and others) and \
             Lambert conformal conic grids only, not `{proj4}`: give latitude_deg and \
             longitude_deg in sun_position"
        )),
    }
}

impl Georeference {
    /// Geodetic latitude and longitude (degrees) of the scene point (x, y), and the true bearing
    /// (degrees clockwise from true north) of the scene's +x axis there (the grid bearing plus
    /// the meridian convergence; [`crate::physics::geodesy`]). An error says why the CRS does
    /// not allow it.
    pub fn geographic(&self, x: f64, y: f64) -> Result<(f64, f64, f64), String> {
        let proj4 = self.crs.proj4.as_deref().ok_or_else(|| {
            format!(
                "the CRS `{}` has no EPSG code, so latitude and longitude cannot be derived",
                self.crs.name
            )
        })?;
        let tm = map_projection(proj4)?;
        let (e, n) = self.to_map(x, y);
        let (lat, lon) = tm.inverse(e, n);
        Ok((lat, lon, tm.true_bearing_deg(e, n, self.x_axis_bearing_deg)))
    }

    /// Resolves a validated description; the error names the field (`crs`, `origin_map_m`,
    /// `x_axis_bearing_deg`) and says why.
    pub fn from_desc(d: &GeoreferenceDesc) -> Result<Self, (&'static str, String)> {
        let crs = resolve_crs(&d.crs).map_err(|m| ("crs", m))?;
        let (e, n) = d.origin_map_m;
        if !(e.is_finite() && n.is_finite()) {
            return Err(("origin_map_m", format!("must be finite, got ({e}, {n})")));
        }
        let b = d.x_axis_bearing_deg;
        if !(0.0..360.0).contains(&b) {
            return Err((
                "x_axis_bearing_deg",
                format!("must be in [0, 360) degrees, got {b}"),
            ));
        }
        Ok(Self {
            crs,
            origin_map_m: d.origin_map_m,
            x_axis_bearing_deg: b,
        })
    }

    /// Whether +x points to grid east (β = 90°): products are north-up.
    pub fn north_up(&self) -> bool {
        self.x_axis_bearing_deg == 90.0
    }

    /// Map coordinates (E, N) of the scene point (x, y), m.
    pub fn to_map(&self, x: f64, y: f64) -> (f64, f64) {
        let (s, c) = sin_cos_deg(self.x_axis_bearing_deg);
        let (e0, n0) = self.origin_map_m;
        (e0 + x * s - y * c, n0 + x * c + y * s)
    }

    /// Scene coordinates (x, y) of the map point (E, N), m (the inverse of [`Self::to_map`]).
    pub fn to_scene(&self, e: f64, n: f64) -> (f64, f64) {
        let (s, c) = sin_cos_deg(self.x_axis_bearing_deg);
        let (de, dn) = (e - self.origin_map_m.0, n - self.origin_map_m.1);
        (de * s + dn * c, -de * c + dn * s)
    }

    /// The map bounding box (E_min, N_min, E_max, N_max) of the scene rectangle [0, X] × [0, Y].
    pub fn map_bounds(&self, size: (f64, f64)) -> (f64, f64, f64, f64) {
        let corners =
            [(0.0, 0.0), (size.0, 0.0), (0.0, size.1), size].map(|(x, y)| self.to_map(x, y));
        corners.iter().fold(
            (
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ),
            |b, &(e, n)| (b.0.min(e), b.1.min(n), b.2.max(e), b.3.max(n)),
        )
    }

    /// The CRS as a product carries it: its EPSG code when it has one that fits a GeoKey, else
    /// user-defined with its WKT.
    pub fn tiff_crs(&self) -> TiffCrs {
        match self.crs.epsg.and_then(|c| u16::try_from(c).ok()) {
            Some(c) if c < crate::io::geotiff::USER_DEFINED => TiffCrs::Epsg(c),
            _ => TiffCrs::UserDefined {
                name: self.crs.name.clone(),
                wkt: self.crs.wkt.clone(),
            },
        }
    }

    /// The map placement of a raster of pixels (px, py) m whose top-left pixel corner is the
    /// scene point (x_left, y_top); rows run towards −y.
    pub fn placement(&self, x_left: f64, y_top: f64, px: f64, py: f64) -> MapPlacement {
        let (s, c) = sin_cos_deg(self.x_axis_bearing_deg);
        let (e, n) = self.to_map(x_left, y_top);
        // Column step = px along +x = px·(sin β, cos β); row step = py along −y =
        // py·(cos β, −sin β).
        MapPlacement {
            crs: self.tiff_crs(),
            transform: [e, px * s, py * c, n, px * c, -py * s],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crs_resolution() {
        let utm = resolve_crs(&CrsDesc::Epsg(32631)).unwrap();
        assert_eq!(utm.epsg, Some(32631));
        assert!(utm.name.contains("UTM zone 31N"), "{}", utm.name);
        assert!(
            resolve_crs(&CrsDesc::Epsg(4326))
                .unwrap_err()
                .contains("geographic")
        );
        assert!(
            resolve_crs(&CrsDesc::Epsg(1))
                .unwrap_err()
                .contains("not a known")
        );
        let w = resolve_crs(&CrsDesc::Wkt(utm.wkt.clone())).unwrap();
        assert_eq!(w.epsg, Some(32631));
        let local =
            "PROJCS[\"local\",GEOGCS[\"g\",AUTHORITY[\"EPSG\",\"4326\"]],UNIT[\"metre\",1]]";
        // The only authority is the GEOGCS's: the projected CRS has no EPSG code.
        let l = resolve_crs(&CrsDesc::Wkt(local.into())).unwrap();
        assert_eq!((l.name.as_str(), l.epsg), ("local", None));
        assert!(resolve_crs(&CrsDesc::Wkt("GEOGCS[\"x\"]".into())).is_err());
    }

    /// β = 90°: +x east, +y north; β = 0°: +x north, +y west. The placement maps pixel
    /// corners to the map images of the scene points.
    #[test]
    fn map_placement() {
        let mut g = Georeference {
            crs: resolve_crs(&CrsDesc::Epsg(32631)).unwrap(),
            origin_map_m: (500_000.0, 4_800_000.0),
            x_axis_bearing_deg: 90.0,
        };
        assert_eq!(g.to_map(10.0, 20.0), (500_010.0, 4_800_020.0));
        let p = g.placement(0.0, 40.0, 0.5, 0.5);
        assert_eq!(p.transform, [500_000.0, 0.5, 0.0, 4_800_040.0, 0.0, -0.5]);
        assert!(p.north_up());
        g.x_axis_bearing_deg = 0.0;
        assert_eq!(g.to_map(10.0, 20.0), (499_980.0, 4_800_010.0));
        assert_eq!(g.to_scene(499_980.0, 4_800_010.0), (10.0, 20.0));
        g.x_axis_bearing_deg = 33.0;
        let (x, y) = g.to_scene(g.to_map(3.0, -7.0).0, g.to_map(3.0, -7.0).1);
        assert!((x - 3.0).abs() < 1e-9 && (y + 7.0).abs() < 1e-9);
        for b in [0.0, 30.0, 135.0, 250.0] {
            g.x_axis_bearing_deg = b;
            let t = g.placement(3.0, 40.0, 0.5, 0.25).transform;
            // Pixel corner (c, r) = scene (3 + 0.5 c, 40 − 0.25 r).
            let (c, r) = (7.0, 11.0);
            let (e, n) = g.to_map(3.0 + 0.5 * c, 40.0 - 0.25 * r);
            assert!((t[0] + c * t[1] + r * t[2] - e).abs() < 1e-9);
            assert!((t[3] + c * t[4] + r * t[5] - n).abs() < 1e-9);
        }
    }
}
