//! Validation of the scene's objects (part of [`super::validate`]): the ground and its
//! topography, trees and stands with their placement, turbid plots, buildings, water, leaves
//! and meshes; every error names the object's field path (`objects[i]...`).

use super::*;

/// The objects section of [`validate`].
impl V<'_> {
    /// The objects, in order (at most one Ground).
    pub(super) fn objects(&self) -> R {
        let mut ground_seen = false;
        for (i, o) in self.desc.objects.iter().enumerate() {
            let f = format!("objects[{i}]");
            match o {
                ObjectDesc::Ground(gd) => {
                    if ground_seen {
                        return Err(self.src.invalid(f, "a scene has at most one Ground"));
                    }
                    ground_seen = true;
                    self.ground(&f, gd)?;
                }
                ObjectDesc::Tree(t) => self.tree(&f, t)?,
                ObjectDesc::TreeStand(s) => self.tree_stand(&f, s)?,
                ObjectDesc::TurbidPlot(p) => self.turbid_plot(&f, p)?,
                ObjectDesc::Building(b) => self.building(&f, b)?,
                ObjectDesc::Water(w) => self.water(&f, w)?,
                ObjectDesc::LeafList(l) => self.leaf_list(&f, l)?,
                ObjectDesc::Leaves(l) => self.leaves(&f, l)?,
                ObjectDesc::Mesh(m) => self.mesh(&f, m)?,
                ObjectDesc::LandCover(l) => self.land_cover(&f, l)?,
            }
        }
        Ok(())
    }

    /// A land-cover map: a georeference to place it, and every class template valid as the
    /// object it becomes (checked on a 1 m square at the scene origin).
    fn land_cover(&self, f: &str, l: &LandCoverDesc) -> R {
        if self.desc.georeference.is_none() {
            return Err(self.src.invalid(
                f,
                "a LandCover map is placed through the scene's map coordinates: add a \
                 `georeference` section (CRS and origin_map_m) to the scene",
            ));
        }
        if l.path.trim().is_empty() {
            return Err(self.src.invalid(format!("{f}.path"), "must name a GeoTIFF"));
        }
        let (sx, sy) = self.desc.grid.size_m;
        let square = (0.0, 0.0, sx.min(1.0), sy.min(1.0));
        for (k, class) in &l.classes {
            let fk = format!("{f}.classes[{k}]");
            if let LandCoverClass::TurbidPlot {
                foliage: FoliageDesc::LeafArea(_),
                ..
            } = class
            {
                return Err(self.src.invalid(
                    format!("{fk}.foliage"),
                    "a LeafArea total has no meaning per pixel: give Lai or LeafAreaDensity",
                ));
            }
            if let LandCoverClass::TreeStand {
                species,
                trees_per_ha,
                min_spacing_m,
            } = class
            {
                if species.is_empty() {
                    return Err(self.src.invalid(
                        format!("{fk}.species"),
                        "a stand needs at least one species",
                    ));
                }
                for (s, sp) in species.iter().enumerate() {
                    self.crown(&format!("{fk}.species[{s}].crown"), &sp.crown)?;
                    if let Some(tr) = &sp.trunk {
                        self.trunk(&format!("{fk}.species[{s}].trunk"), tr)?;
                    }
                }
                if trees_per_ha.len() != species.len() {
                    return Err(self.src.invalid(
                        format!("{fk}.trees_per_ha"),
                        format!(
                            "needs one density per species ({}), got {}",
                            species.len(),
                            trees_per_ha.len()
                        ),
                    ));
                }
                for (s, &d) in trees_per_ha.iter().enumerate() {
                    self.in_range(&format!("{fk}.trees_per_ha[{s}]"), d, 0.0, 1e5)?;
                }
                self.non_negative(&format!("{fk}.min_spacing_m"), *min_spacing_m)?;
                continue;
            }
            match crate::scene::landcover::class_object(class, FootprintDesc::Box(square)) {
                Some(ObjectDesc::TurbidPlot(p)) => self.turbid_plot(&fk, &p)?,
                Some(ObjectDesc::Water(w)) => self.water(&fk, &w)?,
                Some(ObjectDesc::Building(b)) => self.building(&fk, &b)?,
                _ => {}
            }
        }
        Ok(())
    }

    /// The Ground: its optics and topography.
    fn ground(&self, f: &str, gd: &GroundDesc) -> R {
        let src = self.src;
        self.optics_ref(&format!("{f}.optics"), &gd.optics, OpticsRole::Facet)?;
        match &gd.topography {
            TopographyDesc::Flat => {}
            TopographyDesc::Raster(r) => self.raster(f, r)?,
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
                        self.finite(&format!("{f}.topography.points_m[{k}]"), x)?;
                    }
                }
            }
        }
        Ok(())
    }

    /// An inline raster topography: node counts, spacing and altitudes.
    fn raster(&self, f: &str, r: &RasterDesc) -> R {
        let src = self.src;
        let tf = format!("{f}.topography");
        if r.nodes.0 < 2 || r.nodes.1 < 2 {
            return Err(src.invalid(format!("{tf}.nodes"), "a raster needs at least 2 × 2 nodes"));
        }
        self.positive(&format!("{tf}.spacing_m"), r.spacing_m.0)?;
        self.positive(&format!("{tf}.spacing_m"), r.spacing_m.1)?;
        let max = crate::scene::terrain_input::MAX_RASTER_NODES;
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
            self.finite(&format!("{tf}.altitude_m[{k}]"), *z)?;
        }
        Ok(())
    }

    /// One tree: crown, trunk, extent.
    fn tree(&self, f: &str, t: &TreeDesc) -> R {
        self.crown(&format!("{f}.crown"), &t.crown)?;
        if let Some(tr) = &t.trunk {
            self.trunk(&format!("{f}.trunk"), tr)?;
        }
        self.tree_extent(
            &format!("{f}.position_m"),
            t.position_m.0,
            t.position_m.1,
            &t.crown,
        )?;
        Ok(())
    }

    /// A tree stand: its species, then the placement.
    fn tree_stand(&self, f: &str, s: &TreeStandDesc) -> R {
        let src = self.src;
        if s.species.is_empty() {
            return Err(src.invalid(format!("{f}.species"), "a stand needs at least one species"));
        }
        for (k, sp) in s.species.iter().enumerate() {
            self.crown(&format!("{f}.species[{k}].crown"), &sp.crown)?;
            if let Some(tr) = &sp.trunk {
                self.trunk(&format!("{f}.species[{k}].trunk"), tr)?;
            }
        }
        self.placement(f, s)?;
        Ok(())
    }

    /// A stand's placement: explicit positions, or random counts in a region.
    fn placement(&self, f: &str, s: &TreeStandDesc) -> R {
        let (desc, src) = (self.desc, self.src);
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
                    self.tree_extent(&pf, *x, *y, &spd.crown)?;
                }
            }
            PlacementDesc::Random {
                counts,
                min_spacing_m,
                region_m,
                polygon_m,
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
                self.non_negative(&format!("{pf}.min_spacing_m"), *min_spacing_m)?;
                let r = s
                    .species
                    .iter()
                    .map(|sp| sp.crown.radius_x_m.max(sp.crown.radius_y_m.unwrap_or(0.0)))
                    .fold(0.0, f64::max);
                if let Some(p) = polygon_m {
                    self.footprint(
                        &format!("{pf}.polygon_m"),
                        &FootprintDesc::Polygon(p.clone()),
                    )?;
                }
                if let Some((x0, y0, x1, y1)) = region_m {
                    self.footprint(
                        &format!("{pf}.region_m"),
                        &FootprintDesc::Box((*x0, *y0, *x1, *y1)),
                    )?;
                    self.inside(&format!("{pf}.region_m"), x0 - r, y0 - r, x1 + r, y1 + r)?;
                } else if let Some(p) = polygon_m
                    && desc.grid.boundary == BoundaryMode::Isolated
                {
                    let (x0, y0, x1, y1) = p.iter().fold(
                        (f64::MAX, f64::MAX, f64::MIN, f64::MIN),
                        |(a, b, c, d), &(x, y)| (a.min(x), b.min(y), c.max(x), d.max(y)),
                    );
                    self.inside(&format!("{pf}.polygon_m"), x0 - r, y0 - r, x1 + r, y1 + r)?;
                } else if desc.grid.boundary == BoundaryMode::Isolated {
                    return Err(src.invalid(
                        format!("{pf}.region_m"),
                        "random placement in an isolated scene needs a `region_m` (or `polygon_m`) that keeps crowns inside the scene",
                    ));
                }
            }
        }
        Ok(())
    }

    /// A turbid plot: footprint, layer, foliage (and its implied density), optics.
    fn turbid_plot(&self, f: &str, p: &TurbidPlotDesc) -> R {
        let src = self.src;
        self.footprint(&format!("{f}.footprint"), &p.footprint)?;
        self.non_negative(&format!("{f}.bottom_m"), p.bottom_m)?;
        self.positive(&format!("{f}.top_m"), p.top_m)?;
        if p.top_m <= p.bottom_m {
            return Err(src.invalid(
                format!("{f}.top_m"),
                format!("top ({}) must be above bottom ({})", p.top_m, p.bottom_m),
            ));
        }
        self.foliage(&format!("{f}.foliage"), &p.foliage)?;
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
            self.implied_density(&format!("{f}.foliage"), &p.foliage, a, volume)?;
        }
        self.optics_ref(&format!("{f}.optics"), &p.optics, OpticsRole::Turbid)?;
        let (a, b, c, d) = footprint_bounds(&p.footprint);
        self.inside(&format!("{f}.footprint"), a, b, c, d)?;
        Ok(())
    }

    /// A building: footprint, heights, roof, optics.
    fn building(&self, f: &str, b: &BuildingDesc) -> R {
        let src = self.src;
        self.footprint(&format!("{f}.footprint"), &b.footprint)?;
        self.positive(&format!("{f}.wall_height_m"), b.wall_height_m)?;
        if let RoofDesc::Gable { ridge_height_m } = b.roof {
            self.positive(&format!("{f}.roof.ridge_height_m"), ridge_height_m)?;
            if let FootprintDesc::Polygon(p) = &b.footprint
                && !polygon::is_rectangle(p)
            {
                return Err(src.invalid(
                    format!("{f}.roof"),
                    "a Gable roof needs a rectangular footprint (a Box or a 4-vertex rectangle)",
                ));
            }
        }
        self.optics_ref(
            &format!("{f}.wall_optics"),
            &b.wall_optics,
            OpticsRole::Facet,
        )?;
        self.optics_ref(
            &format!("{f}.roof_optics"),
            &b.roof_optics,
            OpticsRole::Facet,
        )?;
        let (a, bb, c, d) = footprint_bounds(&b.footprint);
        self.inside(&format!("{f}.footprint"), a, bb, c, d)?;
        Ok(())
    }

    /// A water body: footprint, altitude, optics.
    fn water(&self, f: &str, w: &WaterDesc) -> R {
        self.footprint(&format!("{f}.footprint"), &w.footprint)?;
        if let Some(z) = w.altitude_m {
            self.finite(&format!("{f}.altitude_m"), z)?;
        }
        self.optics_ref(&format!("{f}.optics"), &w.optics, OpticsRole::Facet)?;
        let (a, b, c, d) = footprint_bounds(&w.footprint);
        self.inside(&format!("{f}.footprint"), a, b, c, d)?;
        Ok(())
    }

    /// A RAMI leaf-list file: optics, sides, translation.
    fn leaf_list(&self, f: &str, l: &LeafListDesc) -> R {
        let src = self.src;
        let role = if l.as_turbid {
            OpticsRole::Leaf
        } else {
            OpticsRole::Facet
        };
        self.optics_ref(&format!("{f}.optics"), &l.optics, role)?;
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
            self.finite(&format!("{f}.translation_m"), x)?;
        }
        Ok(())
    }

    /// Inline disk leaves: radius, sides, optics, each disk.
    fn leaves(&self, f: &str, l: &LeavesDesc) -> R {
        let src = self.src;
        self.positive(&format!("{f}.radius_m"), l.radius_m)?;
        if !(3..=MAX_POLYGON_SIDES).contains(&l.sides) {
            return Err(src.invalid(
                format!("{f}.sides"),
                format!(
                    "a disk polygon needs 3 to {MAX_POLYGON_SIDES} sides, got {}",
                    l.sides
                ),
            ));
        }
        self.optics_ref(&format!("{f}.optics"), &l.optics, OpticsRole::Facet)?;
        for (k, d) in l.disks.iter().enumerate() {
            let df = format!("{f}.disks[{k}]");
            for x in [d.0, d.1, d.2, d.3, d.4, d.5] {
                self.finite(&df, x)?;
            }
            if (d.3 * d.3 + d.4 * d.4 + d.5 * d.5).sqrt() < 1e-9 {
                return Err(src.invalid(df, "disk normal has zero length"));
            }
            self.inside(
                &df,
                d.0 - l.radius_m,
                d.1 - l.radius_m,
                d.0 + l.radius_m,
                d.1 + l.radius_m,
            )?;
        }
        Ok(())
    }

    /// A mesh: scale, placement, its groups' optics.
    fn mesh(&self, f: &str, m: &MeshDesc) -> R {
        let src = self.src;
        self.positive(&format!("{f}.scale"), m.scale)?;
        self.finite(&format!("{f}.rotation_z_deg"), m.rotation_z_deg)?;
        for x in [m.translation_m.0, m.translation_m.1, m.translation_m.2] {
            self.finite(&format!("{f}.translation_m"), x)?;
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
            self.optics_ref(&format!("{f}.groups[{k}].optics"), &gr.optics, role)?;
        }
        Ok(())
    }
}
