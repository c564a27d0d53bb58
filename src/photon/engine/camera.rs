//! Peel-off to frame cameras (next-event estimation to a finite point; DART 5 paper §5 eq. 5
//! and Figure 17, Ray-Carlo eqs. 1–2 of the local estimate; physics.md §8.1): from every
//! scattering event, toward the pinhole of each camera, into the pixel the event projects to.
//!
//! An event of weight `w_b` (W) whose radiant intensity per unit weight toward the pinhole is
//! `f_b(u)` (sr⁻¹) at distance `r` (m) with transmittance `T_b` (traced through the grid:
//! turbid cells, facets, fluids, ground, repetitive sides) puts the irradiance
//! `w_b f_b T_b / r²` on the pinhole from inside the pixel's solid angle `Ω_pix` (sr); its
//! contribution to the pixel's mean radiance is `w_b f_b T_b / (r² Ω_pix)` (W m⁻² sr⁻¹). Over
//! the events of a Lambertian ground of reflectance ρ under the horizontal irradiance E, the
//! sum is `E ρ/π` in every pixel (`Σ dA cos θ / r² = Ω_pix` over the pixel's footprint).
//!
//! Repetitive scenes are infinite: the event stands for all its periodic copies, and every copy
//! inside the camera's view (within the scene's height range) is peeled off, each with its
//! own ray (traced from the wrapped event, which the periodic walk makes the same). When the
//! view holds more than [`MAX_COPIES`] candidate copies, the nine nearest the camera are peeled
//! off and a systematic sample of that many of the others with weight n/[`MAX_COPIES`]
//! (unbiased; the cost per event stays bounded).

use super::context::{Ctx, PerMaterial, Photon};
use super::tally::BatchOut;
use crate::geometry::camera::FrameCamera;
use crate::photon::small::Small;
use crate::scene::desc::BoundaryMode;
use glam::DVec3;

/// A camera as the tracker sees it: the model, its pixel solid angles, where its pixels start
/// in the batch tally and the range of periodic copies it can see.
#[derive(Debug, Clone)]
pub(crate) struct CameraPeel {
    /// The pinhole model.
    pub(crate) cam: FrameCamera,
    /// Solid angle of every pixel `(i, j)` at `i + nx·j`, sr.
    pub(crate) solid: Vec<f64>,
    /// Index of the camera's first pixel value in [`BatchOut::cams`] (pixel-major, then
    /// channel).
    pub(crate) base: usize,
    /// Box `[x0, y0, x1, y1]` (m) holding every point of the scene's height range the camera
    /// sees (repetitive scenes; `None`: only the event itself, isolated scenes).
    pub(crate) footprint: Option<[f64; 4]>,
}

/// Most periodic copies of one event peeled off toward one camera: beyond, the nine nearest
/// the camera and a systematic sample of this many (weighted by the ratio) keep the cost per
/// event bounded.
pub(crate) const MAX_COPIES: u64 = 16;

/// A uniform number in [0, 1) from the event's position and order (SplitMix64 of their bits):
/// the start of the systematic copy sample, reproducible whatever the thread count and drawn
/// from no photon stream (so the other products do not change with a camera).
fn event_uniform(p: DVec3, order: u32) -> f64 {
    let mut z = p.x.to_bits()
        ^ p.y.to_bits().rotate_left(21)
        ^ p.z.to_bits().rotate_left(42)
        ^ (order as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Horizontal reach (m) of a view that meets the horizon: at least 1 km, or ten times the
/// camera's height above the bottom of the scene.
fn horizon_reach(height: f64) -> f64 {
    (10.0 * height.abs()).max(1000.0)
}

impl CameraPeel {
    /// The tracker's view of `cam` with its first value at `base`; `z_range` the scene's
    /// heights (bottom, top), `repetitive` whether copies exist.
    pub(crate) fn new(cam: &FrameCamera, base: usize, z_range: (f64, f64), rep: bool) -> Self {
        let solid = (0..cam.ny)
            .flat_map(|j| (0..cam.nx).map(move |i| (i, j)))
            .map(|(i, j)| cam.pixel_solid_angle(i, j))
            .collect();
        let footprint = rep.then(|| {
            let c = cam.position;
            let corners = cam.corner_directions();
            // A view holding both rising and falling directions holds horizontal ones, which
            // meet the height range arbitrarily far away: clipped at the horizon reach.
            let down = corners.iter().all(|d| d.z < 0.0);
            let up = corners.iter().all(|d| d.z > 0.0);
            if !(down || up) {
                let r = horizon_reach(c.z - z_range.0);
                return [c.x - r, c.y - r, c.x + r, c.y + r];
            }
            // Otherwise the view inside the height range is the convex hull of the corner
            // rays' points on its two planes ahead of the camera, and of the camera itself
            // when it is inside the range (empty: the camera looks away from the scene).
            let (mut x0, mut y0, mut x1, mut y1) = if (z_range.0..=z_range.1).contains(&c.z) {
                (c.x, c.y, c.x, c.y)
            } else {
                (
                    f64::INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::NEG_INFINITY,
                )
            };
            for d in corners {
                for z in [z_range.0, z_range.1] {
                    let t = (z - c.z) / d.z;
                    if t >= 0.0 {
                        let q = c + d * t;
                        x0 = x0.min(q.x);
                        x1 = x1.max(q.x);
                        y0 = y0.min(q.y);
                        y1 = y1.max(q.y);
                    }
                }
            }
            [x0, y0, x1, y1]
        });
        Self {
            cam: cam.clone(),
            solid,
            base,
            footprint,
        }
    }
}

/// The tracker's cameras of `cams`, with their tally offsets, and the tally length (pixels ×
/// `w` channels in all).
pub(crate) fn camera_peels(ctx: &Ctx, cams: &[FrameCamera], w: usize) -> (Vec<CameraPeel>, usize) {
    let spec = ctx.inp.spec;
    let rep = spec.boundary != BoundaryMode::Isolated;
    let mut base = 0;
    let peels = cams
        .iter()
        .map(|c| {
            let p = CameraPeel::new(c, base, (spec.origin.z, spec.top()), rep);
            base += c.nx * c.ny * w;
            p
        })
        .collect();
    (peels, base)
}

impl Ctx<'_> {
    /// Peel-off from the event at the wrapped point `p` to every camera: per periodic copy in
    /// the camera's view, the pixel it projects into, the intensity factors `f(usize::MAX, u,
    /// ·)` toward the pinhole (sr⁻¹), the transmittance along the ray to it (the hotspot
    /// terms of a first-order sun photon, physics.md §3.5, as for the views), and
    /// `w_b f_b T_b / (r² Ω_pix)` added to the pixel (module documentation).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn peel_cameras(
        &self,
        ph: &Photon,
        p: DVec3,
        skip: Option<u32>,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
        f: &mut dyn FnMut(usize, DVec3, &mut [f64]) -> bool,
    ) {
        let spec = self.inp.spec;
        let (lx, ly) = self.size;
        let (ox, oy) = spec.topography_offset;
        for cp in self.cameras.iter() {
            let ((x0, nx), (y0, ny)) = match cp.footprint {
                Some([x0, _, x1, _]) if !(x0 <= x1) => continue,
                Some([x0, y0, x1, y1]) => {
                    let range = |lo: f64, hi: f64, at: f64, len: f64| {
                        let a = ((lo - at) / len).ceil() as i64;
                        let b = ((hi - at) / len).floor() as i64;
                        (a, (b - a + 1).max(0) as u64)
                    };
                    (range(x0, x1, p.x, lx), range(y0, y1, p.y, ly))
                }
                None => ((0, 1), (0, 1)),
            };
            let n = nx * ny;
            let mut peel = |kx: i64, ky: i64, weight: f64| {
                let (sx, sy) = (kx as f64, ky as f64);
                let q = p + DVec3::new(sx * lx, sy * ly, sx * ox + sy * oy);
                self.peel_copy(cp, ph, (p, q, weight), skip, out, scratch, tr, f);
            };
            if n <= MAX_COPIES {
                for idx in 0..n {
                    peel(x0 + (idx % nx) as i64, y0 + (idx / nx) as i64, 1.0);
                }
                continue;
            }
            // Too many: every copy within one tile of the one under the camera (the nearest,
            // whose pixels have the smallest footprints), then a systematic sample of
            // MAX_COPIES over all of them, the near ones skipped (each far copy kept with
            // probability MAX_COPIES/n and weighted n/MAX_COPIES: unbiased), its start from a
            // hash of the event (no draw from the photon's stream).
            let cx = ((cp.cam.position.x - p.x) / lx).round() as i64;
            let cy = ((cp.cam.position.y - p.y) / ly).round() as i64;
            let near = |kx: i64, ky: i64| (kx - cx).abs() <= 1 && (ky - cy).abs() <= 1;
            let inside = |kx: i64, ky: i64| {
                (x0..x0 + nx as i64).contains(&kx) && (y0..y0 + ny as i64).contains(&ky)
            };
            for ky in cy - 1..=cy + 1 {
                for kx in cx - 1..=cx + 1 {
                    if inside(kx, ky) {
                        peel(kx, ky, 1.0);
                    }
                }
            }
            let step = n as f64 / MAX_COPIES as f64;
            let start = event_uniform(p, ph.order) * step;
            for c in 0..MAX_COPIES {
                let idx = ((start + c as f64 * step) as u64).min(n - 1);
                let (kx, ky) = (x0 + (idx % nx) as i64, y0 + (idx / nx) as i64);
                if !near(kx, ky) {
                    peel(kx, ky, step);
                }
            }
        }
    }

    /// [`Ctx::peel_cameras`] for one copy `q` of the event at `p` (wrapped), its contribution
    /// weighted by `weight` (the inverse of its sampling probability).
    #[allow(clippy::too_many_arguments)]
    fn peel_copy(
        &self,
        cp: &CameraPeel,
        ph: &Photon,
        (p, q, weight): (DVec3, DVec3, f64),
        skip: Option<u32>,
        out: &mut BatchOut,
        scratch: &mut [f64],
        tr: &mut [f64],
        f: &mut dyn FnMut(usize, DVec3, &mut [f64]) -> bool,
    ) {
        let Some((i, j)) = cp.cam.pixel_of(q) else {
            return;
        };
        let v = cp.cam.position - q;
        let r = v.length();
        if !(r > 0.0) {
            return;
        }
        let u = v / r;
        if !f(usize::MAX, u, scratch) {
            return;
        }
        let g: PerMaterial<f64> = Small::from_fn(self.tur_ids.len(), |tm| self.g_of(tm, u.z));
        let first_sun = ph.order == 0 && ph.off == 0 && self.hs_leaf.iter().any(|&l| l > 0.0);
        let hs: PerMaterial<[f64; 2]> = if first_sun {
            Small::from_fn(self.tur_ids.len(), |tm| {
                crate::radiative::engine::hotspot_terms(
                    self.inp.sun,
                    u,
                    self.g_sun[tm],
                    g[tm],
                    self.hs_leaf[tm],
                )
            })
        } else {
            Small::from_elem([0.0; 2], 0)
        };
        // Isolated scenes: nothing outside the box, so the ray is done when it leaves through
        // a side (the walk would count that as blocked).
        let reach = if self.inp.spec.boundary == BoundaryMode::Isolated {
            r.min(self.side_exit(p, u) * (1.0 - 1e-12))
        } else {
            r
        };
        self.transmittance(p, u, reach, &g, &hs, skip, tr);
        if tr.iter().all(|&t| t < 1e-30) {
            return;
        }
        let k = weight / (r * r * cp.solid[i + cp.cam.nx * j]);
        let at = cp.base + (i + cp.cam.nx * j) * self.w + ph.off;
        for b in 0..self.nb {
            out.cams[at + b] += ph.w[b] * scratch[b] * tr[b] * k;
        }
    }

    /// Distance (m) from `p` along the unit `u` to the vertical sides of the scene box
    /// (infinite for a vertical `u`).
    fn side_exit(&self, p: DVec3, u: DVec3) -> f64 {
        let spec = self.inp.spec;
        let size = [self.size.0, self.size.1];
        let mut t = f64::INFINITY;
        for a in 0..2 {
            if u[a] > 0.0 {
                t = t.min((spec.origin[a] + size[a] - p[a]) / u[a]);
            } else if u[a] < 0.0 {
                t = t.min((spec.origin[a] - p[a]) / u[a]);
            }
        }
        t.max(0.0)
    }
}
