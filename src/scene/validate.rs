//! Validation of a parsed [`SceneDesc`]: every number a physical quantity must satisfy, every
//! reference between sections, and the extent rules of isolated scenes. Errors name the file,
//! the line/column (found with [`super::locate`]) and the field.

use super::desc::*;
use super::error::{Location, SceneError};
use super::locate::locate;
use crate::geometry::polygon;
use crate::physics::prospect::ProspectError;
use std::path::{Path, PathBuf};

mod atmosphere;
mod lidar;
mod objects;
mod sensor;
mod thermal;
pub use sensor::MAX_SENSOR_PIXELS;

/// The text a scene came from, to turn field paths into line numbers.
#[derive(Debug, Clone)]
pub struct SceneSource {
    /// The file (or `<generated>`).
    pub path: PathBuf,
    /// Its text, when the scene was read from a file.
    pub text: Option<String>,
}

impl SceneSource {
    /// A scene built in memory (generators, tests).
    pub fn generated() -> Self {
        Self {
            path: PathBuf::from("<generated>"),
            text: None,
        }
    }

    /// Folder that relative paths in the scene are resolved against.
    pub fn base_dir(&self) -> PathBuf {
        match self.text {
            Some(_) => self
                .path
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default(),
            None => PathBuf::from("."),
        }
    }

    /// Location of a field path.
    pub fn at(&self, field: &str) -> Location {
        Location {
            file: self.path.clone(),
            line_col: self.text.as_deref().and_then(|t| locate(t, field)),
        }
    }

    /// An `Invalid` error for `field`.
    pub fn invalid(&self, field: impl Into<String>, message: impl Into<String>) -> SceneError {
        let field = field.into();
        SceneError::Invalid {
            at: self.at(&field),
            field,
            message: message.into(),
        }
    }
}

/// A number for a message: as written for ordinary magnitudes, in scientific notation for
/// huge or tiny ones (`1e300`, not three hundred digits).
pub fn num(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-6..1e9).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// Kind of optical property expected where a name is referenced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OpticsRole {
    /// A facet: Lambertian, RPV, Hapke (or a bi-Lambertian leaf used as facet).
    Facet,
    /// Turbid vegetation.
    Turbid,
    /// A bi-Lambertian leaf.
    Leaf,
}

struct V<'a> {
    src: &'a SceneSource,
    nb: usize,
    desc: &'a SceneDesc,
}

type R = Result<(), SceneError>;

impl V<'_> {
    fn finite(&self, f: &str, x: f64) -> R {
        if x.is_finite() {
            Ok(())
        } else {
            Err(self
                .src
                .invalid(f, format!("must be a finite number, got {}", num(x))))
        }
    }
    fn positive(&self, f: &str, x: f64) -> R {
        self.finite(f, x)?;
        if x > 0.0 {
            Ok(())
        } else {
            Err(self.src.invalid(f, format!("must be > 0, got {}", num(x))))
        }
    }
    fn non_negative(&self, f: &str, x: f64) -> R {
        self.finite(f, x)?;
        if x >= 0.0 {
            Ok(())
        } else {
            Err(self.src.invalid(f, format!("must be >= 0, got {}", num(x))))
        }
    }
    fn in_range(&self, f: &str, x: f64, lo: f64, hi: f64) -> R {
        self.finite(f, x)?;
        if (lo..=hi).contains(&x) {
            Ok(())
        } else {
            Err(self
                .src
                .invalid(f, format!("must lie in [{lo}, {hi}], got {}", num(x))))
        }
    }
    /// A per-band list: exactly one value per band (empty allowed when `optional`).
    fn bands(&self, f: &str, v: &[f64], lo: f64, hi: f64, optional: bool) -> R {
        if v.is_empty() && optional {
            return Ok(());
        }
        if v.len() != self.nb {
            return Err(self.src.invalid(
                f,
                format!(
                    "needs one value per band ({} bands), got {}",
                    self.nb,
                    v.len()
                ),
            ));
        }
        for (i, &x) in v.iter().enumerate() {
            self.in_range(&format!("{f}[{i}]"), x, lo, hi)?;
        }
        Ok(())
    }

    fn optics_ref(&self, f: &str, name: &str, role: OpticsRole) -> R {
        let Some(o) = self.desc.optics.get(name) else {
            let known: Vec<&str> = self.desc.optics.keys().map(String::as_str).collect();
            return Err(self.src.invalid(
                f,
                format!(
                    "unknown optical property `{name}` (defined: {})",
                    known.join(", ")
                ),
            ));
        };
        let ok = match role {
            OpticsRole::Facet => matches!(
                o,
                OpticsDesc::Lambertian { .. }
                    | OpticsDesc::Rpv { .. }
                    | OpticsDesc::Hapke { .. }
                    | OpticsDesc::BiLambertian { .. }
                    | OpticsDesc::ProspectLeaf { .. }
            ),
            OpticsRole::Turbid => matches!(o, OpticsDesc::Turbid { .. }),
            OpticsRole::Leaf => matches!(
                o,
                OpticsDesc::BiLambertian { .. } | OpticsDesc::ProspectLeaf { .. }
            ),
        };
        if ok {
            Ok(())
        } else {
            let want = match role {
                OpticsRole::Facet => {
                    "a facet property (Lambertian, Rpv, Hapke, BiLambertian or ProspectLeaf)"
                }
                OpticsRole::Turbid => "a Turbid property",
                OpticsRole::Leaf => "a leaf property (BiLambertian or ProspectLeaf)",
            };
            Err(self.src.invalid(f, format!("`{name}` is not {want}")))
        }
    }

    fn foliage(&self, f: &str, fo: &FoliageDesc) -> R {
        let (name, x) = match fo {
            FoliageDesc::LeafAreaDensity(x) => ("LeafAreaDensity", *x),
            FoliageDesc::Lai(x) => ("Lai", *x),
            FoliageDesc::LeafArea(x) => ("LeafArea", *x),
        };
        self.non_negative(&format!("{f}.{name}"), x).map_err(|_| {
            self.src.invalid(
                f,
                format!("{name} must be a finite number >= 0, got {}", num(x)),
            )
        })?;
        let (max, unit) = match fo {
            FoliageDesc::Lai(_) => (MAX_LAI, "m²/m²"),
            FoliageDesc::LeafAreaDensity(_) => (MAX_LEAF_AREA_DENSITY, "m²/m³"),
            FoliageDesc::LeafArea(_) => (f64::MAX, "m²"),
        };
        if x > max {
            return Err(self.src.invalid(
                f,
                format!(
                    "{name}({}) is outside the accepted range [0, {max}] {unit} (denser foliage is optically opaque at any cell size)",
                    num(x)
                ),
            ));
        }
        Ok(())
    }

    /// The mean leaf area density `leaf_area` m² makes over `volume` m³ must not exceed
    /// [`MAX_LEAF_AREA_DENSITY`].
    fn implied_density(&self, f: &str, fo: &FoliageDesc, leaf_area: f64, volume: f64) -> R {
        let u = leaf_area / volume;
        if !(u <= MAX_LEAF_AREA_DENSITY) {
            let given = match fo {
                FoliageDesc::LeafAreaDensity(x) => format!("LeafAreaDensity({})", num(*x)),
                FoliageDesc::Lai(x) => format!("Lai({})", num(*x)),
                FoliageDesc::LeafArea(x) => format!("LeafArea({})", num(*x)),
            };
            return Err(self.src.invalid(
                f,
                format!(
                    "{given} puts a mean leaf area density of {u:.3e} m²/m³ in a volume of {volume:.3e} m³, outside the accepted range [0, {MAX_LEAF_AREA_DENSITY}] m²/m³"
                ),
            ));
        }
        Ok(())
    }

    fn weights(&self, f: &str, w: &[f64]) -> R {
        if w.is_empty() {
            return Ok(());
        }
        for (i, &x) in w.iter().enumerate() {
            self.non_negative(&format!("{f}[{i}]"), x)?;
        }
        if w.iter().sum::<f64>() <= 0.0 {
            return Err(self.src.invalid(f, "weights must not all be zero"));
        }
        Ok(())
    }

    fn footprint(&self, f: &str, fp: &FootprintDesc) -> R {
        match fp {
            FootprintDesc::Box((x0, y0, x1, y1)) => {
                for (k, v) in [x0, y0, x1, y1].iter().enumerate() {
                    self.finite(&format!("{f}.Box[{k}]"), **v)?;
                }
                if !(x1 > x0 && y1 > y0) {
                    return Err(self.src.invalid(
                        f,
                        format!("box needs x_min < x_max and y_min < y_max, got ({x0}, {y0}, {x1}, {y1})"),
                    ));
                }
            }
            FootprintDesc::Polygon(pts) => {
                if pts.len() < 3 {
                    return Err(self.src.invalid(f, "a polygon needs at least 3 vertices"));
                }
                for (i, p) in pts.iter().enumerate() {
                    self.finite(&format!("{f}.Polygon[{i}]"), p.0)?;
                    self.finite(&format!("{f}.Polygon[{i}]"), p.1)?;
                }
                let poly: Vec<glam::DVec2> =
                    pts.iter().map(|p| glam::DVec2::new(p.0, p.1)).collect();
                if polygon::signed_area(&poly).abs() <= 1e-12 {
                    return Err(self.src.invalid(f, "polygon has zero area"));
                }
                if let Some((a, b)) = polygon::self_intersection(&poly) {
                    return Err(self
                        .src
                        .invalid(f, format!("polygon is not simple: edges {a} and {b} cross")));
                }
            }
        }
        Ok(())
    }

    /// Isolated scenes: the footprint must lie inside [0, X] × [0, Y].
    fn inside(&self, f: &str, xmin: f64, ymin: f64, xmax: f64, ymax: f64) -> R {
        if self.desc.grid.boundary != BoundaryMode::Isolated {
            return Ok(());
        }
        let (sx, sy) = self.desc.grid.size_m;
        let eps = 1e-9 * sx.max(sy);
        if xmin < -eps || ymin < -eps || xmax > sx + eps || ymax > sy + eps {
            return Err(self.src.invalid(
                f,
                format!(
                    "object spans x [{xmin:.3}, {xmax:.3}] m, y [{ymin:.3}, {ymax:.3}] m, outside the isolated scene [0, {sx}] × [0, {sy}] m"
                ),
            ));
        }
        Ok(())
    }

    fn crown(&self, f: &str, c: &CrownDesc) -> R {
        self.non_negative(&format!("{f}.base_height_m"), c.base_height_m)?;
        self.positive(&format!("{f}.height_m"), c.height_m)?;
        self.positive(&format!("{f}.radius_x_m"), c.radius_x_m)?;
        if let Some(ry) = c.radius_y_m {
            self.positive(&format!("{f}.radius_y_m"), ry)?;
        }
        match (c.shape, c.top_radius_fraction) {
            (CrownShape::Trapezoid, Some(t)) => {
                self.in_range(&format!("{f}.top_radius_fraction"), t, 0.0, 1.0)?
            }
            (CrownShape::Trapezoid, None) => {
                return Err(self.src.invalid(
                    format!("{f}.shape"),
                    "a Trapezoid crown needs `top_radius_fraction`",
                ));
            }
            (_, Some(_)) => {
                return Err(self.src.invalid(
                    format!("{f}.top_radius_fraction"),
                    "only a Trapezoid crown takes `top_radius_fraction`",
                ));
            }
            _ => {}
        }
        self.foliage(&format!("{f}.foliage"), &c.foliage)?;
        if let FoliageDesc::LeafArea(a) = c.foliage {
            // A crown holds at most LAI 100 over the scene's ground (or over its own
            // footprint when that is larger): tiny crowns may be dense (the Maket conserves
            // their area), but not beyond what the scene could carry.
            let (sx, sy) = self.desc.grid.size_m;
            let rx = c.radius_x_m;
            let footprint = std::f64::consts::PI * rx * c.radius_y_m.unwrap_or(rx);
            let max = MAX_LAI * (sx * sy).max(footprint);
            if !(a <= max) {
                return Err(self.src.invalid(
                    format!("{f}.foliage"),
                    format!(
                        "LeafArea({}) is outside the accepted range [0, {max:.4e}] m² (LAI {MAX_LAI} over the {sx} × {sy} m scene)",
                        num(a)
                    ),
                ));
            }
        }
        self.weights(&format!("{f}.vertical_profile"), &c.vertical_profile)?;
        self.weights(&format!("{f}.radial_profile"), &c.radial_profile)?;
        self.optics_ref(&format!("{f}.optics"), &c.optics, OpticsRole::Turbid)
    }

    fn trunk(&self, f: &str, t: &TrunkDesc) -> R {
        self.positive(&format!("{f}.height_m"), t.height_m)?;
        self.positive(&format!("{f}.diameter_m"), t.diameter_m)?;
        if !(3..=MAX_POLYGON_SIDES).contains(&t.sides) {
            return Err(self.src.invalid(
                format!("{f}.sides"),
                format!(
                    "a trunk needs 3 to {MAX_POLYGON_SIDES} sides, got {}",
                    t.sides
                ),
            ));
        }
        self.optics_ref(&format!("{f}.optics"), &t.optics, OpticsRole::Facet)
    }

    fn tree_extent(&self, f: &str, x: f64, y: f64, c: &CrownDesc) -> R {
        self.finite(&format!("{f}.position_m"), x)?;
        self.finite(&format!("{f}.position_m"), y)?;
        let rx = c.radius_x_m;
        let ry = c.radius_y_m.unwrap_or(rx);
        self.inside(f, x - rx, y - ry, x + rx, y + ry)
    }
}

fn footprint_bounds(fp: &FootprintDesc) -> (f64, f64, f64, f64) {
    match fp {
        FootprintDesc::Box(b) => *b,
        FootprintDesc::Polygon(p) => p.iter().fold(
            (
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ),
            |(a, b, c, d), &(x, y)| (a.min(x), b.min(y), c.max(x), d.max(y)),
        ),
    }
}

/// Checks a scene; returns the first error found (the sections in this order: format,
/// directions, radiative settings, LiDARs, sensors, grid, images, bands, optics, georeference,
/// illumination, thermal, objects).
pub fn validate(desc: &SceneDesc, src: &SceneSource) -> Result<(), SceneError> {
    let v = V {
        src,
        nb: desc.bands.len(),
        desc,
    };
    v.header()?;
    v.directions()?;
    v.radiative()?;
    v.lidars()?;
    v.sensors()?;
    v.grid()?;
    v.images()?;
    v.spectral_bands()?;
    v.optics()?;
    v.georeference()?;
    v.illumination()?;
    v.atmosphere()?;
    v.thermal()?;
    v.objects()
}

/// The sections of [`validate`], one method each.
impl V<'_> {
    /// The georeference: a known projected CRS in metres, a finite origin, a bearing in
    /// [0, 360) (`scene::georef`).
    fn georeference(&self) -> R {
        match &self.desc.georeference {
            Some(g) => crate::scene::georef::Georeference::from_desc(g)
                .map(|_| ())
                .map_err(|(f, m)| self.src.invalid(format!("georeference.{f}"), m)),
            None => Ok(()),
        }
    }

    /// The format version.
    fn header(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        if desc.version != SCENE_FORMAT_VERSION {
            return Err(src.invalid(
                "version",
                format!(
                    "scene format version {} is not known (this lumenscape reads version {SCENE_FORMAT_VERSION})",
                    desc.version
                ),
            ));
        }
        Ok(())
    }

    /// The direction set parameters and the exact (view) directions.
    fn directions(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        if let Some(dp) = &desc.directions
            && let Err(e) = crate::direction::DirectionSet::new(dp)
        {
            return Err(src.invalid(format!("directions.{}", e.field), e.reason));
        }
        // Fictive directions (DART: radiance along them, outside the 4π tiling) are built and
        // tabulated by the Direction and Phase stages, but no solver computes radiance along
        // them: flux tracking traces, intercepts and re-scatters along the tiling directions only
        // (a fictive one would need its own attenuation-only walk from every scattering element,
        // G values, slot-averaged phase/BRDF columns and Lambertian fractions along it, and the
        // hotspot terms), and Monte Carlo peels off toward the exact directions. Accepting them
        // would drop them from every product without a word (issue #31).
        if let Some(d) = &desc.directions
            && !d.fictive.is_empty()
        {
            return Err(SceneError::NotSupported {
                at: src.at("directions.fictive"),
                field: "directions.fictive".into(),
                message: format!(
                    "{} fictive direction(s) listed, but no solver computes radiance along fictive directions: list them under `directions.exact` instead (an exact direction's sector has the requested vector, bit for bit, and its BRF and image are written), or leave `fictive: []`",
                    d.fictive.len()
                ),
            });
        }
        // Exact directions of a scene are view directions (ground→sensor): the BRF table and the
        // orthographic images only hold upward ones, so a downward one would vanish from every
        // product without a word.
        for (i, e) in desc
            .directions
            .iter()
            .flat_map(|d| d.exact.iter())
            .enumerate()
        {
            if !(0.0..=90.0).contains(&e.zenith_deg) {
                return Err(src.invalid(
                    format!("directions.exact[{i}].zenith_deg"),
                    format!(
                        "a view direction's zenith (ground→sensor) must lie in [0, 90]°, got {}: a direction below the horizon appears in no product",
                        e.zenith_deg
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The flux-tracking settings (`radiative`).
    fn radiative(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        if let Some(r) = &desc.radiative {
            if let Some(x) = r.albedo_threshold {
                self.positive("radiative.albedo_threshold", x)?;
            }
            if let Some(x) = r.ray_threshold {
                self.non_negative("radiative.ray_threshold", x)?;
            }
            if let Some(x) = r.launch_spacing_m {
                self.positive("radiative.launch_spacing_m", x)?;
            }
            if r.image_oversampling == 0 || r.image_oversampling > MAX_IMAGE_OVERSAMPLING {
                return Err(src.invalid(
                    "radiative.image_oversampling",
                    format!(
                        "must be an integer in 1..={MAX_IMAGE_OVERSAMPLING} (pixels per cell along x and y), got {}",
                        r.image_oversampling
                    ),
                ));
            }
            if r.turbid_exit_grouping == Some(true)
                && matches!(
                    r.turbid_subfaces,
                    Some(
                        crate::scene::desc::TurbidSubfaces::Off
                            | crate::scene::desc::TurbidSubfaces::Blend
                    )
                )
            {
                return Err(src.invalid(
                    "radiative.turbid_exit_grouping",
                    "groups the rays of incident-face stores: needs turbid_subfaces: Some(Faces) or Some(Subfaces)",
                ));
            }
            if r.max_iterations == Some(0) {
                return Err(src.invalid(
                    "radiative.max_iterations",
                    "at least one iteration is needed",
                ));
            }
        }
        Ok(())
    }

    /// Every LiDAR, and the passive radiance the LiDARs need.
    fn lidars(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        for (i, l) in desc.lidars.iter().flatten().enumerate() {
            self.lidar(i, l)?;
            if desc.passive == Some(false) && l.needs_passive() {
                let why = if l.fusion {
                    "its fusion product (`fusion: true`)"
                } else {
                    "its photon-counting solar background"
                };
                return Err(src.invalid(
                    "passive",
                    format!(
                        "is false, but lidar `{}` needs the passive radiance for {why}",
                        l.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The grid: sizes, whole cell counts, the cell-count limit, sub-cells.
    fn grid(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        let g = &desc.grid;
        self.positive("grid.size_m", g.size_m.0)?;
        self.positive("grid.size_m", g.size_m.1)?;
        self.positive("grid.cell_m", g.cell_m.0)?;
        self.positive("grid.cell_m", g.cell_m.1)?;
        self.positive("grid.cell_m", g.cell_m.2)?;
        for (s, c, axis) in [(g.size_m.0, g.cell_m.0, "x"), (g.size_m.1, g.cell_m.1, "y")] {
            let n = s / c;
            if (n - n.round()).abs() > 1e-6 * n.max(1.0) || n.round() < 1.0 {
                return Err(src.invalid(
                    "grid.cell_m",
                    format!(
                        "scene size along {axis} ({s} m) must be a whole number of cells of {c} m"
                    ),
                ));
            }
        }
        if let Some(h) = g.height_m {
            self.positive("grid.height_m", h)?;
        }
        // Cell counts, in floating point before any integer cast: `size_m: (2.0, 1e308)` would
        // otherwise saturate `as usize` and overflow every product of the counts downstream.
        let columns = (g.size_m.0 / g.cell_m.0).round() * (g.size_m.1 / g.cell_m.1).round();
        if columns > MAX_GRID_CELLS as f64 {
            return Err(src.invalid(
                "grid.size_m",
                format!(
                    "{} × {} m in cells of {} × {} m make {columns:.3e} grid columns, above the limit of {MAX_GRID_CELLS} cells: use larger cells or a smaller scene",
                    num(g.size_m.0),
                    num(g.size_m.1),
                    num(g.cell_m.0),
                    num(g.cell_m.1)
                ),
            ));
        }
        if let Some(h) = g.height_m {
            let cells = columns * (h / g.cell_m.2).ceil().max(1.0);
            if cells > MAX_GRID_CELLS as f64 {
                return Err(src.invalid(
                    "grid.height_m",
                    format!(
                        "a height of {} m in cells of {} m makes a grid of {cells:.3e} cells, above the limit of {MAX_GRID_CELLS}: use larger cells or a lower scene",
                        num(h),
                        num(g.cell_m.2)
                    ),
                ));
            }
        }
        if g.subcells == 0 || g.subcells > 16 {
            return Err(src.invalid(
                "grid.subcells",
                format!("must be in 1..=16, got {}", g.subcells),
            ));
        }
        Ok(())
    }

    /// Orthographic images: columns × η² pixels each.
    fn images(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        let g = &desc.grid;
        if let Some(r) = &desc.radiative {
            let columns = (g.size_m.0 / g.cell_m.0).round() * (g.size_m.1 / g.cell_m.1).round();
            let pixels = columns * (r.image_oversampling as f64).powi(2);
            if pixels > MAX_IMAGE_PIXELS as f64 {
                return Err(src.invalid(
                        "radiative.image_oversampling",
                        format!(
                            "{} × {} pixels per grid column make images of {pixels:.3e} pixels (limit {MAX_IMAGE_PIXELS})",
                            r.image_oversampling, r.image_oversampling
                        ),
                    ));
            }
        }
        Ok(())
    }

    /// The spectral bands: names, widths and responses.
    fn spectral_bands(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        if desc.bands.is_empty() {
            return Err(src.invalid("bands", "at least one band is needed"));
        }
        for (i, b) in desc.bands.iter().enumerate() {
            if b.name.trim().is_empty() {
                return Err(src.invalid(format!("bands[{i}].name"), "band name is empty"));
            }
            if desc.bands[..i].iter().any(|o| o.name == b.name) {
                return Err(src.invalid(
                    format!("bands[{i}].name"),
                    format!("duplicate band name `{}`", b.name),
                ));
            }
            self.non_negative(&format!("bands[{i}].fwhm_nm"), b.fwhm_nm)?;
            // Response form, shipped sensor and band names (SRF files are read at spawn).
            super::resolve::check_band(b)
                .map_err(|(sub, m)| src.invalid(format!("bands[{i}].{sub}"), m))?;
        }
        Ok(())
    }

    /// The optical properties: duplicated names (found in the text: a RON map keeps the
    /// last of two equal keys), then each entry.
    fn optics(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        if let Some(text) = src.text.as_deref()
            && let Some((key, first, second)) = super::locate::duplicate_key(text, "optics")
        {
            return Err(SceneError::Invalid {
                at: Location {
                    file: src.path.clone(),
                    line_col: Some(second),
                },
                field: format!("optics[\"{key}\"]"),
                message: format!(
                    "`{key}` is defined twice (line {} and line {}); the later definition would silently replace the earlier: rename or remove one",
                    first.0, second.0
                ),
            });
        }
        for (name, o) in &desc.optics {
            let f = format!("optics[\"{name}\"]");
            self.optic(&f, o)?;
        }
        Ok(())
    }

    /// One optical property `o` at the field path `f`.
    fn optic(&self, f: &str, o: &OpticsDesc) -> R {
        let (desc, src) = (self.desc, self.src);
        match o {
            OpticsDesc::Lambertian {
                reflectance,
                diffuse_transmittance,
                direct_transmittance,
            } => {
                self.bands(&format!("{f}.reflectance"), reflectance, 0.0, 1.0, false)?;
                self.bands(
                    &format!("{f}.diffuse_transmittance"),
                    diffuse_transmittance,
                    0.0,
                    1.0,
                    true,
                )?;
                self.bands(
                    &format!("{f}.direct_transmittance"),
                    direct_transmittance,
                    0.0,
                    1.0,
                    true,
                )?;
                for b in 0..self.nb {
                    let r = reflectance[b];
                    let t = diffuse_transmittance.get(b).copied().unwrap_or(0.0);
                    if r + t > 1.0 + 1e-12 {
                        return Err(src.invalid(
                            format!("{f}.reflectance[{b}]"),
                            format!(
                                "reflectance + diffuse transmittance = {} > 1 in band `{}`",
                                r + t,
                                desc.bands[b].name
                            ),
                        ));
                    }
                }
            }
            OpticsDesc::BiLambertian {
                reflectance,
                transmittance,
            } => {
                self.bands(&format!("{f}.reflectance"), reflectance, 0.0, 1.0, false)?;
                self.bands(
                    &format!("{f}.transmittance"),
                    transmittance,
                    0.0,
                    1.0,
                    false,
                )?;
                for b in 0..self.nb {
                    if reflectance[b] + transmittance[b] > 1.0 + 1e-12 {
                        return Err(src.invalid(
                            format!("{f}.reflectance[{b}]"),
                            format!(
                                "leaf reflectance + transmittance = {} > 1 in band `{}`",
                                reflectance[b] + transmittance[b],
                                desc.bands[b].name
                            ),
                        ));
                    }
                }
            }
            OpticsDesc::ProspectLeaf { .. } => {
                let (_, params) = o.prospect_params().expect("a ProspectLeaf entry");
                params.validate().map_err(|e| match e {
                    ProspectError::InvalidParameter {
                        field,
                        value,
                        reason,
                    } => src.invalid(format!("{f}.{field}"), format!("{reason}, got {value}")),
                    other => src.invalid(f, other.to_string()),
                })?;
            }
            OpticsDesc::Rpv {
                rho0,
                k,
                theta,
                rho_c,
            } => {
                self.bands(&format!("{f}.rho0"), rho0, 0.0, f64::MAX, false)?;
                self.bands(&format!("{f}.k"), k, 0.0, 10.0, false)?;
                self.bands(&format!("{f}.theta"), theta, -0.999, 0.999, false)?;
                if let Some(rc) = rho_c {
                    self.bands(&format!("{f}.rho_c"), rc, 0.0, f64::MAX, false)?;
                }
            }
            OpticsDesc::Hapke {
                w,
                b,
                c,
                roughness_deg,
                b0,
                h,
            } => {
                self.bands(&format!("{f}.w"), w, 0.0, 1.0, false)?;
                self.bands(&format!("{f}.b"), b, 0.0, 0.999, false)?;
                self.bands(&format!("{f}.c"), c, 0.0, 1.0, false)?;
                self.in_range(&format!("{f}.roughness_deg"), *roughness_deg, 0.0, 60.0)?;
                self.non_negative(&format!("{f}.b0"), *b0)?;
                self.positive(&format!("{f}.h"), *h)?;
            }
            OpticsDesc::Turbid {
                leaf,
                lad,
                leaf_size_m,
                specular,
            } => self.turbid_optics(f, leaf, lad, *leaf_size_m, specular.as_ref())?,
        }
        Ok(())
    }

    /// A turbid vegetation property: its leaf, leaf size, specular term and LAD.
    fn turbid_optics(
        &self,
        f: &str,
        leaf: &str,
        lad: &LadDesc,
        leaf_size_m: f64,
        specular: Option<&crate::physics::lad::LeafSpecular>,
    ) -> R {
        let (desc, src) = (self.desc, self.src);
        self.optics_ref(&format!("{f}.leaf"), leaf, OpticsRole::Leaf)?;
        self.non_negative(&format!("{f}.leaf_size_m"), leaf_size_m)?;
        if let Some(s) = specular {
            // ρ + τ + factor ≤ 1 per band, refractive index in (1, 5].
            let mut check = crate::physics::lad::LeafOptics::lambertian(0.0, 0.0);
            check.specular = Some(*s);
            if let Some(OpticsDesc::BiLambertian {
                reflectance,
                transmittance,
            }) = desc.optics.get(leaf)
            {
                for b in 0..reflectance.len().min(transmittance.len()) {
                    check.reflectance = reflectance[b];
                    check.transmittance = transmittance[b];
                    if let Err(e) = check.validate() {
                        return Err(src.invalid(
                            format!("{f}.specular"),
                            format!(
                                "band `{}`: {e}",
                                desc.bands.get(b).map_or("?", |x| x.name.as_str())
                            ),
                        ));
                    }
                }
            } else if let Err(e) = check.validate() {
                return Err(src.invalid(format!("{f}.specular"), e.to_string()));
            }
        }
        // The physics type validates itself (parameter ranges, normalisable pdf).
        if let Err(e) = crate::physics::lad::LeafAngleDistribution::new(lad) {
            return Err(src.invalid(format!("{f}.lad"), e.to_string()));
        }
        Ok(())
    }

    /// The sun (explicit angles or date and place, exactly one of the two), the sky
    /// fraction and the irradiance.
    fn illumination(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        let il = &desc.illumination;
        match (&il.sun_position, il.sun_zenith_deg, il.sun_azimuth_deg) {
            (Some(p), None, None) => {
                super::resolve::sun_from_position(p, desc.georeference.as_ref(), desc.grid.size_m)
                    .map_err(|(sub, m)| {
                        src.invalid(format!("illumination.sun_position.{sub}"), m)
                    })?;
            }
            (Some(_), _, _) => {
                return Err(src.invalid(
                    "illumination.sun_position",
                    "give the sun either by `sun_zenith_deg` and `sun_azimuth_deg` or by `sun_position`, not both",
                ));
            }
            (None, Some(zenith), Some(azimuth)) => {
                self.finite("illumination.sun_zenith_deg", zenith)?;
                if !(0.0..90.0).contains(&zenith) {
                    return Err(src.invalid(
                        "illumination.sun_zenith_deg",
                        format!("sun zenith (ground→sun) must lie in [0°, 90°), got {zenith}"),
                    ));
                }
                self.finite("illumination.sun_azimuth_deg", azimuth)?;
            }
            (None, None, None) => {
                return Err(src.invalid(
                    "illumination",
                    "the sun is missing: give `sun_zenith_deg` and `sun_azimuth_deg`, or `sun_position`",
                ));
            }
            (None, Some(_), None) => {
                return Err(src.invalid(
                    "illumination.sun_azimuth_deg",
                    "`sun_zenith_deg` is given without `sun_azimuth_deg`: give both",
                ));
            }
            (None, None, Some(_)) => {
                return Err(src.invalid(
                    "illumination.sun_zenith_deg",
                    "`sun_azimuth_deg` is given without `sun_zenith_deg`: give both",
                ));
            }
        }
        self.bands("illumination.skyl", &il.skyl, 0.0, 1.0, true)?;
        if !il.irradiance_w_m2_um.is_empty() {
            self.bands(
                "illumination.irradiance_w_m2_um",
                &il.irradiance_w_m2_um,
                0.0,
                f64::MAX,
                false,
            )?;
        }
        Ok(())
    }
}

/// Largest number of grid cells (x × y × z): the Maket build buffers store cell indices as
/// `u32`, so a larger grid cannot be built (it would also need ≥ 32 GiB for the cell index
/// alone). Checked on the scene's counts (`grid.size_m` / `grid.cell_m` / `grid.height_m`)
/// by [`validate`] and on the planned grid (height from the objects) by the Maket plan.
pub const MAX_GRID_CELLS: u64 = u32::MAX as u64;

/// Largest leaf area index accepted (`Lai`, m² of leaf per m² of ground). The densest
/// natural canopies measured reach LAI ≈ 15–20, and beyond ~20 a canopy is optically opaque
/// (e^(−0.5 · 20) ≈ 5e-5 of the sun reaches the ground); 100 leaves room for synthetic tests
/// and refuses typos such as `1e6`.
pub const MAX_LAI: f64 = 100.0;

/// Largest (mean) leaf area density accepted (`LeafAreaDensity`, and the mean density a
/// `LeafArea` or `Lai` implies over its volume), m²/m³. Measured densities of the densest
/// foliage (crops, hedges, conifer shoots) stay below ~10–50 m²/m³; at 100 m²/m³ the
/// extinction length 1/(G u) is 2 cm, so anything denser is indistinguishable from an opaque
/// volume at any usable cell size.
pub const MAX_LEAF_AREA_DENSITY: f64 = 100.0;

/// Most sides of a trunk prism or of a disk polygon: a 1000-gon's area is within 7e-6 of its
/// circle's (and each side is a facet per disk, allocated before the Maket plan).
pub const MAX_POLYGON_SIDES: u32 = 1000;

/// Largest number of trees of a randomly placed stand (the placement tries up to 1000 times
/// per tree; a million crowns is far beyond what the Maket grid of a scene can hold usefully).
pub const MAX_STAND_TREES: usize = 1_000_000;

/// Pulses per instrument above which a scene is refused (memory for waveforms).
pub const MAX_LIDAR_PULSES: u64 = 10_000_000;

/// Largest image oversampling factor η (`radiative.image_oversampling`): η² pixels per grid
/// column and per image.
pub const MAX_IMAGE_OVERSAMPLING: u32 = 64;

/// Largest number of pixels of one orthographic image (columns × η²): 2²⁶, 0.5 GiB per
/// channel at 8 bytes a pixel.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 26;

/// Number of pulses a LiDAR description asks for.
pub fn lidar_pulse_count(l: &crate::scene::desc::LidarDesc) -> u64 {
    use crate::scene::desc::{LidarPlatform, PulsePattern};
    let steps = |(a, b, s): (f64, f64, f64)| -> u64 {
        if s > 0.0 && b >= a {
            (((b - a) / s + 1e-9).floor() as u64).saturating_add(1)
        } else {
            0
        }
    };
    match &l.platform {
        LidarPlatform::Airborne { pulses, .. } => match pulses {
            PulsePattern::Single(_) => 1,
            PulsePattern::List(v) => v.len() as u64,
            PulsePattern::Scan {
                start,
                end,
                lines,
                pulse_spacing_m,
                ..
            } => {
                let len = ((end.0 - start.0).powi(2) + (end.1 - start.1).powi(2)).sqrt();
                if *pulse_spacing_m > 0.0 {
                    (*lines as u64).saturating_mul(
                        ((len / pulse_spacing_m + 1e-9).floor() as u64).saturating_add(1),
                    )
                } else {
                    0
                }
            }
        },
        LidarPlatform::Terrestrial {
            zenith_deg,
            azimuth_deg,
            ..
        } => steps(*zenith_deg).saturating_mul(steps(*azimuth_deg)),
    }
}
