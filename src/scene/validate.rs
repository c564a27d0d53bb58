//! Validation of a parsed [`SceneDesc`]: every number a physical quantity must satisfy, every
//! reference between sections, and the extent rules of isolated scenes. Errors name the file,
//! the line/column (found with [`super::locate`]) and the field.

use super::desc::*;
use super::error::{Location, SceneError};
use super::locate::locate;
use crate::geometry::polygon;
use crate::physics::prospect::ProspectError;
use std::path::{Path, PathBuf};

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

/// Checks a scene; returns the first error found.
pub fn validate(desc: &SceneDesc, src: &SceneSource) -> Result<(), SceneError> {
    let v = V {
        src,
        nb: desc.bands.len(),
        desc,
    };
    if desc.version != SCENE_FORMAT_VERSION {
        return Err(src.invalid(
            "version",
            format!(
                "scene format version {} is not known (this lumenscape reads version {SCENE_FORMAT_VERSION})",
                desc.version
            ),
        ));
    }
    for (field, present, issue) in [
        (
            "atmosphere",
            desc.atmosphere.is_some(),
            "the atmosphere module is planned",
        ),
        (
            "sensors",
            desc.sensors.is_some(),
            "sensors arrive with the Radiative/Sensor stages",
        ),
    ] {
        if present {
            return Err(SceneError::NotSupported {
                at: src.at(field),
                field: field.into(),
                message: issue.into(),
            });
        }
    }
    if let Some(dp) = &desc.directions
        && let Err(e) = crate::direction::DirectionSet::new(dp)
    {
        return Err(src.invalid(format!("directions.{}", e.field), e.reason));
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
    if let Some(r) = &desc.radiative {
        if let Some(x) = r.albedo_threshold {
            v.positive("radiative.albedo_threshold", x)?;
        }
        if let Some(x) = r.ray_threshold {
            v.non_negative("radiative.ray_threshold", x)?;
        }
        if let Some(x) = r.launch_spacing_m {
            v.positive("radiative.launch_spacing_m", x)?;
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
    for (i, l) in desc.lidars.iter().flatten().enumerate() {
        validate_lidar(&v, desc, src, i, l)?;
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
    // Grid.
    let g = &desc.grid;
    v.positive("grid.size_m", g.size_m.0)?;
    v.positive("grid.size_m", g.size_m.1)?;
    v.positive("grid.cell_m", g.cell_m.0)?;
    v.positive("grid.cell_m", g.cell_m.1)?;
    v.positive("grid.cell_m", g.cell_m.2)?;
    for (s, c, axis) in [(g.size_m.0, g.cell_m.0, "x"), (g.size_m.1, g.cell_m.1, "y")] {
        let n = s / c;
        if (n - n.round()).abs() > 1e-6 * n.max(1.0) || n.round() < 1.0 {
            return Err(src.invalid(
                "grid.cell_m",
                format!("scene size along {axis} ({s} m) must be a whole number of cells of {c} m"),
            ));
        }
    }
    if let Some(h) = g.height_m {
        v.positive("grid.height_m", h)?;
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
    // Orthographic images: columns × η² pixels each.
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
    // Bands.
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
        v.non_negative(&format!("bands[{i}].fwhm_nm"), b.fwhm_nm)?;
        // Response form, shipped sensor and band names (SRF files are read at spawn).
        super::resolve::check_band(b)
            .map_err(|(sub, m)| src.invalid(format!("bands[{i}].{sub}"), m))?;
    }
    // Optics. A RON map keeps the last of two equal keys: find duplicates in the text.
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
        match o {
            OpticsDesc::Lambertian {
                reflectance,
                diffuse_transmittance,
                direct_transmittance,
            } => {
                v.bands(&format!("{f}.reflectance"), reflectance, 0.0, 1.0, false)?;
                v.bands(
                    &format!("{f}.diffuse_transmittance"),
                    diffuse_transmittance,
                    0.0,
                    1.0,
                    true,
                )?;
                v.bands(
                    &format!("{f}.direct_transmittance"),
                    direct_transmittance,
                    0.0,
                    1.0,
                    true,
                )?;
                for b in 0..v.nb {
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
                v.bands(&format!("{f}.reflectance"), reflectance, 0.0, 1.0, false)?;
                v.bands(
                    &format!("{f}.transmittance"),
                    transmittance,
                    0.0,
                    1.0,
                    false,
                )?;
                for b in 0..v.nb {
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
                    other => src.invalid(f.clone(), other.to_string()),
                })?;
            }
            OpticsDesc::Rpv {
                rho0,
                k,
                theta,
                rho_c,
            } => {
                v.bands(&format!("{f}.rho0"), rho0, 0.0, f64::MAX, false)?;
                v.bands(&format!("{f}.k"), k, 0.0, 10.0, false)?;
                v.bands(&format!("{f}.theta"), theta, -0.999, 0.999, false)?;
                if let Some(rc) = rho_c {
                    v.bands(&format!("{f}.rho_c"), rc, 0.0, f64::MAX, false)?;
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
                v.bands(&format!("{f}.w"), w, 0.0, 1.0, false)?;
                v.bands(&format!("{f}.b"), b, 0.0, 0.999, false)?;
                v.bands(&format!("{f}.c"), c, 0.0, 1.0, false)?;
                v.in_range(&format!("{f}.roughness_deg"), *roughness_deg, 0.0, 60.0)?;
                v.non_negative(&format!("{f}.b0"), *b0)?;
                v.positive(&format!("{f}.h"), *h)?;
            }
            OpticsDesc::Turbid {
                leaf,
                lad,
                leaf_size_m,
                specular,
            } => {
                v.optics_ref(&format!("{f}.leaf"), leaf, OpticsRole::Leaf)?;
                v.non_negative(&format!("{f}.leaf_size_m"), *leaf_size_m)?;
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
            }
        }
    }
    // Illumination: the sun by explicit angles or by date and place, exactly one of the two.
    let il = &desc.illumination;
    match (&il.sun_position, il.sun_zenith_deg, il.sun_azimuth_deg) {
        (Some(p), None, None) => {
            super::resolve::sun_from_position(p)
                .map_err(|(sub, m)| src.invalid(format!("illumination.sun_position.{sub}"), m))?;
        }
        (Some(_), _, _) => {
            return Err(src.invalid(
                "illumination.sun_position",
                "give the sun either by `sun_zenith_deg` and `sun_azimuth_deg` or by `sun_position`, not both",
            ));
        }
        (None, Some(zenith), Some(azimuth)) => {
            v.finite("illumination.sun_zenith_deg", zenith)?;
            if !(0.0..90.0).contains(&zenith) {
                return Err(src.invalid(
                    "illumination.sun_zenith_deg",
                    format!("sun zenith (ground→sun) must lie in [0°, 90°), got {zenith}"),
                ));
            }
            v.finite("illumination.sun_azimuth_deg", azimuth)?;
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
    v.bands("illumination.skyl", &il.skyl, 0.0, 1.0, true)?;
    if !il.irradiance_w_m2_um.is_empty() {
        v.bands(
            "illumination.irradiance_w_m2_um",
            &il.irradiance_w_m2_um,
            0.0,
            f64::MAX,
            false,
        )?;
    }
    // Objects.
    let mut ground_seen = false;
    for (i, o) in desc.objects.iter().enumerate() {
        let f = format!("objects[{i}]");
        match o {
            ObjectDesc::Ground(gd) => {
                if ground_seen {
                    return Err(src.invalid(f, "a scene has at most one Ground"));
                }
                ground_seen = true;
                v.optics_ref(&format!("{f}.optics"), &gd.optics, OpticsRole::Facet)?;
                match &gd.topography {
                    TopographyDesc::Flat => {}
                    TopographyDesc::Raster(r) => {
                        let tf = format!("{f}.topography");
                        if r.nodes.0 < 2 || r.nodes.1 < 2 {
                            return Err(src.invalid(
                                format!("{tf}.nodes"),
                                "a raster needs at least 2 × 2 nodes",
                            ));
                        }
                        v.positive(&format!("{tf}.spacing_m"), r.spacing_m.0)?;
                        v.positive(&format!("{tf}.spacing_m"), r.spacing_m.1)?;
                        let max = super::terrain_input::MAX_RASTER_NODES;
                        if r.nodes.0.checked_mul(r.nodes.1).is_none_or(|n| n > max) {
                            return Err(src.invalid(
                                format!("{tf}.nodes"),
                                format!(
                                    "{} × {} nodes are above the limit of {max} nodes",
                                    r.nodes.0, r.nodes.1
                                ),
                            ));
                        }
                        if r.altitude_m.len() != r.nodes.0 * r.nodes.1 {
                            return Err(src.invalid(
                                format!("{tf}.altitude_m"),
                                format!(
                                    "expected {} × {} = {} altitudes, got {}",
                                    r.nodes.0,
                                    r.nodes.1,
                                    r.nodes.0 * r.nodes.1,
                                    r.altitude_m.len()
                                ),
                            ));
                        }
                        for (k, z) in r.altitude_m.iter().enumerate() {
                            v.finite(&format!("{tf}.altitude_m[{k}]"), *z)?;
                        }
                    }
                    TopographyDesc::RasterFile(_) => {}
                    TopographyDesc::Points { points_m } => {
                        if points_m.len() < 3 {
                            return Err(src.invalid(
                                format!("{f}.topography.points_m"),
                                "at least 3 points are needed",
                            ));
                        }
                        for (k, p) in points_m.iter().enumerate() {
                            for x in [p.0, p.1, p.2] {
                                v.finite(&format!("{f}.topography.points_m[{k}]"), x)?;
                            }
                        }
                    }
                }
            }
            ObjectDesc::Tree(t) => {
                v.crown(&format!("{f}.crown"), &t.crown)?;
                if let Some(tr) = &t.trunk {
                    v.trunk(&format!("{f}.trunk"), tr)?;
                }
                v.tree_extent(
                    &format!("{f}.position_m"),
                    t.position_m.0,
                    t.position_m.1,
                    &t.crown,
                )?;
            }
            ObjectDesc::TreeStand(s) => {
                if s.species.is_empty() {
                    return Err(
                        src.invalid(format!("{f}.species"), "a stand needs at least one species")
                    );
                }
                for (k, sp) in s.species.iter().enumerate() {
                    v.crown(&format!("{f}.species[{k}].crown"), &sp.crown)?;
                    if let Some(tr) = &sp.trunk {
                        v.trunk(&format!("{f}.species[{k}].trunk"), tr)?;
                    }
                }
                match &s.placement {
                    PlacementDesc::Explicit(list) => {
                        for (k, (sp, x, y)) in list.iter().enumerate() {
                            let pf = format!("{f}.placement.Explicit[{k}]");
                            let Some(spd) = s.species.get(*sp) else {
                                return Err(src.invalid(
                                    pf,
                                    format!(
                                        "species index {sp} out of range (stand has {})",
                                        s.species.len()
                                    ),
                                ));
                            };
                            v.tree_extent(&pf, *x, *y, &spd.crown)?;
                        }
                    }
                    PlacementDesc::Random {
                        counts,
                        min_spacing_m,
                        region_m,
                    } => {
                        let pf = format!("{f}.placement");
                        if counts.len() != s.species.len() {
                            return Err(src.invalid(
                                format!("{pf}.counts"),
                                format!(
                                    "needs one count per species ({}), got {}",
                                    s.species.len(),
                                    counts.len()
                                ),
                            ));
                        }
                        let total = counts.iter().try_fold(0usize, |a, &n| a.checked_add(n));
                        if total.is_none_or(|t| t > MAX_STAND_TREES) {
                            return Err(src.invalid(
                                format!("{pf}.counts"),
                                format!(
                                    "asks for {} trees (allowed: at most {MAX_STAND_TREES} per stand)",
                                    total.map_or("more than 2^64".to_string(), |t| t.to_string())
                                ),
                            ));
                        }
                        v.non_negative(&format!("{pf}.min_spacing_m"), *min_spacing_m)?;
                        if let Some((x0, y0, x1, y1)) = region_m {
                            v.footprint(
                                &format!("{pf}.region_m"),
                                &FootprintDesc::Box((*x0, *y0, *x1, *y1)),
                            )?;
                            let r = s
                                .species
                                .iter()
                                .map(|sp| {
                                    sp.crown.radius_x_m.max(sp.crown.radius_y_m.unwrap_or(0.0))
                                })
                                .fold(0.0, f64::max);
                            v.inside(&format!("{pf}.region_m"), x0 - r, y0 - r, x1 + r, y1 + r)?;
                        } else if desc.grid.boundary == BoundaryMode::Isolated {
                            return Err(src.invalid(
                                format!("{pf}.region_m"),
                                "random placement in an isolated scene needs a `region_m` that keeps crowns inside the scene",
                            ));
                        }
                    }
                }
            }
            ObjectDesc::TurbidPlot(p) => {
                v.footprint(&format!("{f}.footprint"), &p.footprint)?;
                v.non_negative(&format!("{f}.bottom_m"), p.bottom_m)?;
                v.positive(&format!("{f}.top_m"), p.top_m)?;
                if p.top_m <= p.bottom_m {
                    return Err(src.invalid(
                        format!("{f}.top_m"),
                        format!("top ({}) must be above bottom ({})", p.top_m, p.bottom_m),
                    ));
                }
                v.foliage(&format!("{f}.foliage"), &p.foliage)?;
                if let FoliageDesc::LeafArea(a) = p.foliage {
                    let (x0, y0, x1, y1) = footprint_bounds(&p.footprint);
                    let poly: Vec<glam::DVec2> = match &p.footprint {
                        FootprintDesc::Box(_) => vec![
                            glam::DVec2::new(x0, y0),
                            glam::DVec2::new(x1, y0),
                            glam::DVec2::new(x1, y1),
                            glam::DVec2::new(x0, y1),
                        ],
                        FootprintDesc::Polygon(pts) => {
                            pts.iter().map(|q| glam::DVec2::new(q.0, q.1)).collect()
                        }
                    };
                    let volume = polygon::signed_area(&poly).abs() * (p.top_m - p.bottom_m);
                    v.implied_density(&format!("{f}.foliage"), &p.foliage, a, volume)?;
                }
                v.optics_ref(&format!("{f}.optics"), &p.optics, OpticsRole::Turbid)?;
                let (a, b, c, d) = footprint_bounds(&p.footprint);
                v.inside(&format!("{f}.footprint"), a, b, c, d)?;
            }
            ObjectDesc::Building(b) => {
                v.footprint(&format!("{f}.footprint"), &b.footprint)?;
                v.positive(&format!("{f}.wall_height_m"), b.wall_height_m)?;
                if let RoofDesc::Gable { ridge_height_m } = b.roof {
                    v.positive(&format!("{f}.roof.ridge_height_m"), ridge_height_m)?;
                    if let FootprintDesc::Polygon(p) = &b.footprint
                        && !polygon::is_rectangle(p)
                    {
                        return Err(src.invalid(
                            format!("{f}.roof"),
                            "a Gable roof needs a rectangular footprint (a Box or a 4-vertex rectangle)",
                        ));
                    }
                }
                v.optics_ref(
                    &format!("{f}.wall_optics"),
                    &b.wall_optics,
                    OpticsRole::Facet,
                )?;
                v.optics_ref(
                    &format!("{f}.roof_optics"),
                    &b.roof_optics,
                    OpticsRole::Facet,
                )?;
                let (a, bb, c, d) = footprint_bounds(&b.footprint);
                v.inside(&format!("{f}.footprint"), a, bb, c, d)?;
            }
            ObjectDesc::Water(w) => {
                v.footprint(&format!("{f}.footprint"), &w.footprint)?;
                if let Some(z) = w.altitude_m {
                    v.finite(&format!("{f}.altitude_m"), z)?;
                }
                v.optics_ref(&format!("{f}.optics"), &w.optics, OpticsRole::Facet)?;
                let (a, b, c, d) = footprint_bounds(&w.footprint);
                v.inside(&format!("{f}.footprint"), a, b, c, d)?;
            }
            ObjectDesc::LeafList(l) => {
                let role = if l.as_turbid {
                    OpticsRole::Leaf
                } else {
                    OpticsRole::Facet
                };
                v.optics_ref(&format!("{f}.optics"), &l.optics, role)?;
                if !(3..=MAX_POLYGON_SIDES).contains(&l.sides) {
                    return Err(src.invalid(
                        format!("{f}.sides"),
                        format!(
                            "a disk polygon needs 3 to {MAX_POLYGON_SIDES} sides, got {}",
                            l.sides
                        ),
                    ));
                }
                for x in [l.translation_m.0, l.translation_m.1, l.translation_m.2] {
                    v.finite(&format!("{f}.translation_m"), x)?;
                }
            }
            ObjectDesc::Leaves(l) => {
                v.positive(&format!("{f}.radius_m"), l.radius_m)?;
                if !(3..=MAX_POLYGON_SIDES).contains(&l.sides) {
                    return Err(src.invalid(
                        format!("{f}.sides"),
                        format!(
                            "a disk polygon needs 3 to {MAX_POLYGON_SIDES} sides, got {}",
                            l.sides
                        ),
                    ));
                }
                v.optics_ref(&format!("{f}.optics"), &l.optics, OpticsRole::Facet)?;
                for (k, d) in l.disks.iter().enumerate() {
                    let df = format!("{f}.disks[{k}]");
                    for x in [d.0, d.1, d.2, d.3, d.4, d.5] {
                        v.finite(&df, x)?;
                    }
                    if (d.3 * d.3 + d.4 * d.4 + d.5 * d.5).sqrt() < 1e-9 {
                        return Err(src.invalid(df, "disk normal has zero length"));
                    }
                    v.inside(
                        &df,
                        d.0 - l.radius_m,
                        d.1 - l.radius_m,
                        d.0 + l.radius_m,
                        d.1 + l.radius_m,
                    )?;
                }
            }
            ObjectDesc::Mesh(m) => {
                v.positive(&format!("{f}.scale"), m.scale)?;
                v.finite(&format!("{f}.rotation_z_deg"), m.rotation_z_deg)?;
                for x in [m.translation_m.0, m.translation_m.1, m.translation_m.2] {
                    v.finite(&format!("{f}.translation_m"), x)?;
                }
                if m.groups.is_empty() {
                    return Err(src.invalid(
                        format!("{f}.groups"),
                        "list the optics of at least one mesh group",
                    ));
                }
                for (k, gr) in m.groups.iter().enumerate() {
                    let role = if gr.as_turbid {
                        OpticsRole::Leaf
                    } else {
                        OpticsRole::Facet
                    };
                    v.optics_ref(&format!("{f}.groups[{k}].optics"), &gr.optics, role)?;
                }
            }
        }
    }
    Ok(())
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

fn validate_lidar(
    v: &V,
    desc: &SceneDesc,
    src: &SceneSource,
    i: usize,
    l: &crate::scene::desc::LidarDesc,
) -> R {
    use crate::scene::desc::{LidarPlatform, PulsePattern};
    let f = |x: &str| format!("lidars[{i}].{x}");
    if l.name.trim().is_empty() || l.name.contains(['/', '\\']) {
        return Err(src.invalid(f("name"), "needs a name usable as a folder name"));
    }
    if desc
        .lidars
        .iter()
        .flatten()
        .take(i)
        .any(|o| o.name == l.name)
    {
        return Err(src.invalid(f("name"), format!("`{}` is used twice", l.name)));
    }
    if !desc.bands.iter().any(|b| b.name == l.band) {
        return Err(src.invalid(f("band"), format!("no band named `{}` in `bands`", l.band)));
    }
    match (l.footprint_radius_m, l.divergence_mrad) {
        (Some(r), None) => v.positive(&f("footprint_radius_m"), r)?,
        (None, Some(d)) => v.in_range(&f("divergence_mrad"), d, 1e-9, 1000.0)?,
        _ => {
            return Err(src.invalid(
                f("footprint_radius_m"),
                "give exactly one of footprint_radius_m and divergence_mrad",
            ));
        }
    }
    v.in_range(&f("edge_intensity"), l.edge_intensity, 1e-6, 0.999)?;
    if let Some(beam) = &l.beam {
        if l.edge_intensity != crate::scene::desc::default_edge_intensity() {
            return Err(src.invalid(
                f("edge_intensity"),
                "with a `beam` profile, give the edge intensity inside it (`Gaussian(edge_intensity: ..)`)",
            ));
        }
        if let crate::lidar::pulse::BeamProfile::Gaussian { edge_intensity } = beam {
            v.in_range(&f("beam.edge_intensity"), *edge_intensity, 1e-6, 0.999)?;
        }
        if let Err(e) = beam.validate() {
            return Err(src.invalid(f("beam"), e.to_string()));
        }
    }
    if let Some(r) = l.fov_radius_m {
        v.positive(&f("fov_radius_m"), r)?;
    }
    v.positive(&f("pulse_energy_j"), l.pulse_energy_j)?;
    v.positive(&f("pulse_fwhm_ns"), l.pulse_fwhm_ns)?;
    v.positive(&f("aperture_m2"), l.aperture_m2)?;
    v.in_range(&f("bin_ns"), l.bin_ns, 1e-3, 1e3)?;
    v.non_negative(&f("gate_margin_m"), l.gate_margin_m)?;
    if l.photons_per_pulse == Some(0) {
        return Err(src.invalid(f("photons_per_pulse"), "must be at least 1"));
    }
    if l.max_order == 0 {
        return Err(src.invalid(f("max_order"), "must be at least 1"));
    }
    if let Some(n) = l.scattering_photons_per_pulse
        && (n == 0
            || n > l
                .photons_per_pulse
                .unwrap_or(crate::scene::desc::DEFAULT_LIDAR_PHOTONS))
    {
        return Err(src.invalid(
            f("scattering_photons_per_pulse"),
            "must be between 1 and photons_per_pulse (every order ≥ 2 needs photons)",
        ));
    }
    match &l.platform {
        LidarPlatform::Airborne {
            altitude_m,
            view_zenith_deg,
            view_azimuth_deg,
            pulses,
        } => {
            v.positive(&f("platform.altitude_m"), *altitude_m)?;
            v.in_range(&f("platform.view_zenith_deg"), *view_zenith_deg, 0.0, 80.0)?;
            v.finite(&f("platform.view_azimuth_deg"), *view_azimuth_deg)?;
            // Aim points within 100 scene sizes of the scene: farther, a pulse misses every
            // object of an isolated scene, and coordinates that large lose the precision the
            // first-flight geometry needs (1e12 m: 1e-4 m steps).
            let (sx, sy) = desc.grid.size_m;
            let aim = |p: (f64, f64)| -> R {
                v.finite(&f("platform.pulses"), p.0)?;
                v.finite(&f("platform.pulses"), p.1)?;
                if !(-100.0 * sx..=101.0 * sx).contains(&p.0)
                    || !(-100.0 * sy..=101.0 * sy).contains(&p.1)
                {
                    return Err(src.invalid(
                        f("platform.pulses"),
                        format!(
                            "aim point ({}, {}) m lies more than 100 scene sizes away from the scene [0, {sx}] × [0, {sy}] m",
                            num(p.0),
                            num(p.1)
                        ),
                    ));
                }
                Ok(())
            };
            match pulses {
                PulsePattern::Single(p) => aim(*p)?,
                PulsePattern::List(ps) => {
                    if ps.is_empty() {
                        return Err(src.invalid(f("platform.pulses"), "the pulse list is empty"));
                    }
                    for p in ps {
                        aim(*p)?;
                    }
                }
                PulsePattern::Scan {
                    start,
                    end,
                    lines,
                    line_spacing_m,
                    pulse_spacing_m,
                } => {
                    aim(*start)?;
                    aim(*end)?;
                    if *lines == 0 {
                        return Err(src.invalid(f("platform.pulses.lines"), "must be at least 1"));
                    }
                    v.non_negative(&f("platform.pulses.line_spacing_m"), *line_spacing_m)?;
                    v.positive(&f("platform.pulses.pulse_spacing_m"), *pulse_spacing_m)?;
                }
            }
        }
        LidarPlatform::Terrestrial {
            position_m,
            zenith_deg,
            azimuth_deg,
        } => {
            let (sx, sy) = desc.grid.size_m;
            if !(position_m.0 >= 0.0
                && position_m.0 <= sx
                && position_m.1 >= 0.0
                && position_m.1 <= sy)
            {
                return Err(src.invalid(
                    f("platform.position_m"),
                    format!(
                        "a terrestrial scanner must stand inside the scene [0, {sx}] × [0, {sy}]"
                    ),
                ));
            }
            v.finite(&f("platform.position_m"), position_m.2)?;
            for (name, (a, b, s)) in [("zenith_deg", zenith_deg), ("azimuth_deg", azimuth_deg)] {
                let fld = f(&format!("platform.{name}"));
                v.finite(&fld, *a)?;
                v.finite(&fld, *b)?;
                v.positive(&fld, *s)?;
                if b < a {
                    return Err(src.invalid(fld, "needs (first, last, step) with last ≥ first"));
                }
            }
            if zenith_deg.0 < 0.0 || zenith_deg.1 > 180.0 {
                return Err(src.invalid(f("platform.zenith_deg"), "zenith angles lie in [0, 180]"));
            }
        }
    }
    let n = lidar_pulse_count(l);
    if n == 0 || n > MAX_LIDAR_PULSES {
        return Err(src.invalid(
            f("platform"),
            format!("asks for {n} pulses (allowed: 1 to {MAX_LIDAR_PULSES})"),
        ));
    }
    if let Some(pc) = &l.photon_counting {
        v.in_range(
            &f("photon_counting.quantum_efficiency"),
            pc.quantum_efficiency,
            0.0,
            1.0,
        )?;
        v.non_negative(&f("photon_counting.dead_time_ns"), pc.dead_time_ns)?;
        v.non_negative(&f("photon_counting.dark_count_hz"), pc.dark_count_hz)?;
        v.positive(
            &f("photon_counting.filter_bandwidth_nm"),
            pc.filter_bandwidth_nm,
        )?;
        v.positive(&f("photon_counting.wavelength_nm"), pc.wavelength_nm)?;
        if pc.shots == 0 {
            return Err(src.invalid(f("photon_counting.shots"), "must be at least 1"));
        }
    }
    Ok(())
}
