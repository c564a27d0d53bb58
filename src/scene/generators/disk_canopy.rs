//! `disk-canopy`: a RAMI HOM-style discrete canopy of randomly placed, non-intersecting disk
//! leaves over Lambertian soil on a repetitive scene (RAMI-3 HOM "DIS" family; Pinty et al.
//! 2004). Leaf normals follow the requested LAD (inclination by inverse-CDF sampling of f(θ),
//! azimuth uniform); disk centres are uniform in the canopy volume; a candidate disk that
//! intersects an already placed disk (exact 3D disk–disk test, periodic) is moved to a new
//! random position with the same orientation, so the accepted normals are independent draws
//! from the LAD.

use super::*;
use crate::random::{stream, uniform};
use glam::DVec3;
use std::f64::consts::{FRAC_PI_2, PI};

/// Parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct DiskCanopyParams {
    /// Leaf area index, m² m⁻².
    pub lai: f64,
    /// Disk radius, metres.
    pub disk_radius_m: f64,
    /// Canopy height, metres.
    pub height_m: f64,
    /// Scene side, metres.
    pub size_m: f64,
    /// Cell size, metres.
    pub cell_m: f64,
    /// Leaf angle distribution.
    pub lad: LadDesc,
    /// Random seed.
    pub seed: u64,
    /// Bands.
    pub bands: Vec<BandOptics>,
    /// Sun zenith, degrees.
    pub sun_zenith_deg: f64,
    /// Sun azimuth, degrees.
    pub sun_azimuth_deg: f64,
}

impl Default for DiskCanopyParams {
    fn default() -> Self {
        Self {
            lai: 1.0,
            disk_radius_m: 0.05,
            height_m: 1.0,
            size_m: 2.0,
            cell_m: 0.5,
            lad: LadDesc::Spherical,
            seed: 1,
            bands: vec![BandOptics::red()],
            sun_zenith_deg: 20.0,
            sun_azimuth_deg: 0.0,
        }
    }
}

/// Tabulated inverse CDF of the inclination (4096 bins, linear within a bin).
fn inclination_table(lad: &LadDesc) -> Result<Vec<f64>, String> {
    const N: usize = 4096;
    let dist = crate::physics::lad::LeafAngleDistribution::new(lad).map_err(|e| e.to_string())?;
    let inclination_pdf = |_: &LadDesc, t: f64| -> Result<f64, String> { Ok(dist.pdf(t)) };
    let mut cdf = vec![0.0; N + 1];
    for i in 0..N {
        let (a, b) = (
            FRAC_PI_2 * i as f64 / N as f64,
            FRAC_PI_2 * (i + 1) as f64 / N as f64,
        );
        // Simpson on each bin.
        let f = (inclination_pdf(lad, a)?
            + 4.0 * inclination_pdf(lad, 0.5 * (a + b))?
            + inclination_pdf(lad, b)?)
            * (b - a)
            / 6.0;
        cdf[i + 1] = cdf[i] + f.max(0.0);
    }
    let total = cdf[N];
    Ok(cdf.iter().map(|c| c / total).collect())
}

fn sample_inclination(cdf: &[f64], u: f64) -> f64 {
    let n = cdf.len() - 1;
    let k = cdf.partition_point(|&c| c <= u).clamp(1, n);
    let (c0, c1) = (cdf[k - 1], cdf[k]);
    let frac = if c1 > c0 { (u - c0) / (c1 - c0) } else { 0.5 };
    FRAC_PI_2 * ((k - 1) as f64 + frac) / n as f64
}

/// Exact test: do two disks of radius r (centres c, unit normals n) intersect?
pub fn disks_intersect(c1: DVec3, n1: DVec3, c2: DVec3, n2: DVec3, r: f64) -> bool {
    let d = c2 - c1;
    if d.length_squared() > 4.0 * r * r {
        return false;
    }
    let u = n1.cross(n2);
    let s2 = u.length_squared();
    if s2 < 1e-18 {
        // Parallel planes: intersect only if coplanar and overlapping.
        return n1.dot(d).abs() < 1e-12 * r && d.length() < 2.0 * r;
    }
    let (h1, h2) = (n1.dot(c1), n2.dot(c2));
    let k = n1.dot(n2);
    let p = ((h1 - h2 * k) * n1 + (h2 - h1 * k) * n2) / (1.0 - k * k);
    let u = u / s2.sqrt();
    let chord = |c: DVec3| -> Option<(f64, f64)> {
        let t = (c - p).dot(u);
        let dist2 = (c - p - t * u).length_squared();
        (dist2 <= r * r).then(|| {
            let h = (r * r - dist2).sqrt();
            (t - h, t + h)
        })
    };
    match (chord(c1), chord(c2)) {
        (Some((a0, a1)), Some((b0, b1))) => a0 <= b1 && b0 <= a1,
        _ => false,
    }
}

/// Draws the disks: (x, y, z, nx, ny, nz).
pub fn draw_disks(p: &DiskCanopyParams) -> Result<Vec<(f64, f64, f64, f64, f64, f64)>, String> {
    let r = p.disk_radius_m;
    let n = (p.lai * p.size_m * p.size_m / (PI * r * r)).round() as usize;
    let cdf = inclination_table(&p.lad)?;
    let mut rng = stream(p.seed, 2, 0);
    let g = ((p.size_m / (2.0 * r)).floor() as usize).clamp(1, 2048);
    let gz = ((p.height_m / (2.0 * r)).floor() as usize).clamp(1, 2048);
    let (cw, ch) = (p.size_m / g as f64, p.height_m / gz as f64);
    let mut buckets: Vec<Vec<(DVec3, DVec3)>> = vec![Vec::new(); g * g * gz];
    let mut out = Vec::with_capacity(n);
    let max_attempts = 200 * n.max(1);
    let mut attempts = 0;
    // The orientation of the next disk, kept until a position accepts it: redrawing it on
    // rejection would favour the orientations that intersect least (flat disks) and bias the
    // leaf angle distribution away from the requested one.
    let mut pending: Option<(f64, DVec3)> = None;
    while out.len() < n {
        attempts += 1;
        if attempts > max_attempts {
            return Err(format!(
                "placed only {} of {n} non-intersecting disks after {max_attempts} attempts: LAI {} is too dense for disks of radius {r} m in {} m of height",
                out.len(),
                p.lai,
                p.height_m
            ));
        }
        let (theta, nrm) = *pending.get_or_insert_with(|| {
            let theta = sample_inclination(&cdf, uniform(&mut rng));
            let phi = 2.0 * PI * uniform(&mut rng);
            (
                theta,
                DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ),
            )
        });
        let half = r * theta.sin();
        if p.height_m <= 2.0 * half {
            // This inclination cannot fit in the canopy height at all: draw another.
            pending = None;
            continue;
        }
        let c = DVec3::new(
            p.size_m * uniform(&mut rng),
            p.size_m * uniform(&mut rng),
            half + (p.height_m - 2.0 * half) * uniform(&mut rng),
        );
        let (bi, bj, bk) = (
            ((c.x / cw) as usize).min(g - 1),
            ((c.y / cw) as usize).min(g - 1),
            ((c.z / ch) as usize).min(gz - 1),
        );
        let mut ok = true;
        'scan: for dk in -1i64..=1 {
            let kk = bk as i64 + dk;
            if kk < 0 || kk >= gz as i64 {
                continue;
            }
            for dj in -1i64..=1 {
                for di in -1i64..=1 {
                    let ii = (bi as i64 + di).rem_euclid(g as i64) as usize;
                    let jj = (bj as i64 + dj).rem_euclid(g as i64) as usize;
                    for &(oc, on) in &buckets[ii + g * (jj + g * kk as usize)] {
                        // Periodic image of the other disk nearest to this one.
                        let mut d = oc - c;
                        d.x -= p.size_m * (d.x / p.size_m).round();
                        d.y -= p.size_m * (d.y / p.size_m).round();
                        if disks_intersect(c, nrm, c + d, on, r) {
                            ok = false;
                            break 'scan;
                        }
                    }
                }
            }
        }
        if ok {
            buckets[bi + g * (bj + g * bk)].push((c, nrm));
            out.push((c.x, c.y, c.z, nrm.x, nrm.y, nrm.z));
            pending = None;
        }
    }
    let _ = ch;
    Ok(out)
}

/// The same scene with the leaves of a RAMI leaf-list file (`path` as written into the scene:
/// absolute, or relative to where the scene will be saved) instead of drawn ones.
pub fn disk_canopy_from_list(p: &DiskCanopyParams, path: &str) -> SceneDesc {
    let mut d = disk_canopy(&DiskCanopyParams {
        lai: 0.0,
        ..p.clone()
    })
    .expect("no disks to draw");
    d.name = format!("disk canopy from {path}");
    d.objects.retain(|o| !matches!(o, ObjectDesc::Leaves(_)));
    d.objects.push(ObjectDesc::LeafList(LeafListDesc {
        path: path.to_string(),
        optics: "leaf".into(),
        sides: 12,
        translation_m: (0.0, 0.0, 0.0),
        wrap: true,
        as_turbid: false,
    }));
    d
}

/// Builds the scene.
pub fn disk_canopy(p: &DiskCanopyParams) -> Result<SceneDesc, String> {
    let disks = draw_disks(p)?;
    let (bands, optics) = standard_optics(&p.bands, p.lad.clone());
    Ok(SceneDesc {
        version: SCENE_FORMAT_VERSION,
        name: format!("disk canopy LAI {} r {} m", p.lai, p.disk_radius_m),
        seed: p.seed,
        grid: cube_grid(p.size_m, p.cell_m, BoundaryMode::Repetitive),
        bands,
        optics,
        illumination: sun(p.sun_zenith_deg, p.sun_azimuth_deg),
        objects: vec![
            flat_ground("soil"),
            ObjectDesc::Leaves(LeavesDesc {
                radius_m: p.disk_radius_m,
                sides: 12,
                optics: "leaf".into(),
                two_sided: true,
                disks,
            }),
        ],
        atmosphere: None,
        sensors: None,
        lidars: None,
        directions: Some(rami_directions(p.sun_azimuth_deg)),
        radiative: None,
        passive: None,
        georeference: None,
        thermal: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn disk_intersection_cases() {
        let z = DVec3::Z;
        let x = DVec3::X;
        // Crossing perpendicular disks.
        assert!(disks_intersect(
            DVec3::ZERO,
            z,
            DVec3::new(0.0, 0.0, 0.05),
            x,
            0.1
        ));
        // Perpendicular but too far sideways.
        assert!(!disks_intersect(
            DVec3::ZERO,
            z,
            DVec3::new(0.15, 0.0, 0.05),
            x,
            0.1
        ));
        // Parallel stacked.
        assert!(!disks_intersect(
            DVec3::ZERO,
            z,
            DVec3::new(0.0, 0.0, 0.01),
            z,
            0.1
        ));
        // Coplanar overlapping.
        assert!(disks_intersect(
            DVec3::ZERO,
            z,
            DVec3::new(0.1, 0.0, 0.0),
            z,
            0.1
        ));
    }
}
