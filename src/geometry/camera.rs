//! The pinhole (frame) camera model of the sensor stage (DART 5 paper §5, Figure 17, eq. 7;
//! physics.md §8.1): a centre of projection, an orthonormal frame (optical axis, image right,
//! image up), square pixels of angular pitch `pitch = pixel pitch / focal length` on the image
//! plane at unit distance, `nx × ny` pixels.
//!
//! Pixel `(i, j)` (column i from the left, row j from the top) covers the image-plane rectangle
//! `x ∈ [(i − nx/2) pitch, (i + 1 − nx/2) pitch]`, `y ∈ [(ny/2 − j − 1) pitch, (ny/2 − j) pitch]`
//! (unit focal distance, x along `right`, y along `up`); a scene point `q` projects to
//! `x = (q − C)·right / depth`, `y = (q − C)·up / depth` with `depth = (q − C)·axis > 0`.

use glam::DVec3;

/// A pinhole camera (positions in scene coordinates, m).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameCamera {
    /// Centre of projection (the pinhole), m.
    pub position: DVec3,
    /// Optical axis (unit, from the camera toward the scene).
    pub axis: DVec3,
    /// Image right (unit, ⟂ axis).
    pub right: DVec3,
    /// Image up (unit, ⟂ axis and right; `right = axis × up`).
    pub up: DVec3,
    /// Pixel pitch over focal length (the side of a pixel on the unit-distance image plane).
    pub pitch: f64,
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
}

/// The view direction `Ω_v = (sin θ cos φ, sin θ sin φ, cos θ)` (from the scene toward the
/// camera) of a zenith `θ` and azimuth `φ` (anticlockwise from +x), radians.
fn omega(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

impl FrameCamera {
    /// A camera at `position` whose optical axis is `−Ω_v(θ, φ)` (it sits in direction (θ, φ)
    /// from what it looks at; θ from the zenith, φ anticlockwise from +x, radians), image up
    /// `−∂Ω_v/∂θ` (the far side of an oblique view at the top; at θ = 0, the horizontal
    /// direction of azimuth φ + π) turned by `roll` (radians, anticlockwise seen from behind the
    /// camera), `pitch` = pixel pitch / focal length, `nx × ny` pixels.
    pub fn from_angles(
        position: DVec3,
        (theta, phi, roll): (f64, f64, f64),
        pitch: f64,
        (nx, ny): (usize, usize),
    ) -> Self {
        let axis = -omega(theta, phi);
        let up0 = DVec3::new(
            -theta.cos() * phi.cos(),
            -theta.cos() * phi.sin(),
            theta.sin(),
        );
        let right0 = axis.cross(up0);
        let (s, c) = roll.sin_cos();
        // Roll: the camera turns about its axis anticlockwise (seen from behind it) by `roll`:
        // its top goes toward its left (up → −right at a quarter turn).
        let up = up0 * c - right0 * s;
        let right = axis.cross(up);
        Self {
            position,
            axis,
            right,
            up,
            pitch,
            nx,
            ny,
        }
    }

    /// The view zenith and azimuth (radians) of a camera at `position` looking at `target`
    /// (`Ω_v` = unit vector from the target to the camera); a vertical axis gets φ = 3π/2
    /// (image up = +y). `None` when the two points coincide.
    pub fn look_at_angles(position: DVec3, target: DVec3) -> Option<(f64, f64)> {
        let v = position - target;
        let r = v.length();
        if !(r > 0.0) || !r.is_finite() {
            return None;
        }
        let theta = (v.z / r).clamp(-1.0, 1.0).acos();
        let phi = if v.x == 0.0 && v.y == 0.0 {
            1.5 * std::f64::consts::PI
        } else {
            v.y.atan2(v.x)
        };
        Some((theta, phi))
    }

    /// Image-plane coordinates (unit focal distance) of the direction `d` from the pinhole
    /// (any length), `None` when it points behind the image plane.
    #[inline]
    pub fn plane_xy(&self, d: DVec3) -> Option<(f64, f64)> {
        let depth = d.dot(self.axis);
        if !(depth > 0.0) {
            return None;
        }
        Some((d.dot(self.right) / depth, d.dot(self.up) / depth))
    }

    /// The pixel `(column, row)` that the scene point `q` projects into, `None` outside the
    /// image or behind the camera.
    #[inline]
    pub fn pixel_of(&self, q: DVec3) -> Option<(usize, usize)> {
        let (x, y) = self.plane_xy(q - self.position)?;
        let fi = x / self.pitch + self.nx as f64 * 0.5;
        let fj = self.ny as f64 * 0.5 - y / self.pitch;
        if fi >= 0.0 && fj >= 0.0 && fi < self.nx as f64 && fj < self.ny as f64 {
            Some((fi as usize, fj as usize))
        } else {
            None
        }
    }

    /// Image-plane rectangle `[x0, x1] × [y0, y1]` of pixel `(i, j)` (unit focal distance).
    pub fn pixel_rect(&self, i: usize, j: usize) -> (f64, f64, f64, f64) {
        let p = self.pitch;
        let x0 = (i as f64 - self.nx as f64 * 0.5) * p;
        let y1 = (self.ny as f64 * 0.5 - j as f64) * p;
        (x0, x0 + p, y1 - p, y1)
    }

    /// Unit direction from the pinhole through the centre of pixel `(i, j)`.
    pub fn pixel_direction(&self, i: usize, j: usize) -> DVec3 {
        let (x0, x1, y0, y1) = self.pixel_rect(i, j);
        self.direction_of(0.5 * (x0 + x1), 0.5 * (y0 + y1))
    }

    /// Unit direction from the pinhole through the image-plane point `(x, y)`.
    pub fn direction_of(&self, x: f64, y: f64) -> DVec3 {
        (self.axis + self.right * x + self.up * y).normalize()
    }

    /// Solid angle of pixel `(i, j)` seen from the pinhole, sr: exactly
    /// `∫∫ dx dy / (1 + x² + y²)^{3/2}` over its rectangle, from the corner function
    /// `F(x, y) = atan(x y / √(1 + x² + y²))` (solid angle of `[0, x] × [0, y]`).
    pub fn pixel_solid_angle(&self, i: usize, j: usize) -> f64 {
        let (x0, x1, y0, y1) = self.pixel_rect(i, j);
        let f = |x: f64, y: f64| (x * y / (1.0 + x * x + y * y).sqrt()).atan();
        f(x1, y1) - f(x0, y1) - f(x1, y0) + f(x0, y0)
    }

    /// Full field of view across the image width and height, radians.
    pub fn fov(&self) -> (f64, f64) {
        (
            2.0 * (0.5 * self.nx as f64 * self.pitch).atan(),
            2.0 * (0.5 * self.ny as f64 * self.pitch).atan(),
        )
    }

    /// Unit directions through the four image corners (top-left, top-right, bottom-right,
    /// bottom-left).
    pub fn corner_directions(&self) -> [DVec3; 4] {
        let hx = 0.5 * self.nx as f64 * self.pitch;
        let hy = 0.5 * self.ny as f64 * self.pitch;
        [
            self.direction_of(-hx, hy),
            self.direction_of(hx, hy),
            self.direction_of(hx, -hy),
            self.direction_of(-hx, -hy),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn nadir_camera_frame_and_projection() {
        let c = FrameCamera::from_angles(
            DVec3::new(0.0, 0.0, 100.0),
            (0.0, 1.5 * PI, 0.0),
            0.01,
            (10, 8),
        );
        assert!((c.axis - DVec3::NEG_Z).length() < 1e-12);
        assert!((c.up - DVec3::Y).length() < 1e-12);
        assert!((c.right - DVec3::X).length() < 1e-12);
        // A ground point at +x, +y lands right of centre, in the top half.
        assert_eq!(c.pixel_of(DVec3::new(0.5, 0.5, 0.0)), Some((5, 3)));
        assert_eq!(c.pixel_of(DVec3::new(-0.5, -0.5, 0.0)), Some((4, 4)));
        assert_eq!(c.pixel_of(DVec3::new(10.0, 0.0, 0.0)), None);
        assert_eq!(c.pixel_of(DVec3::new(0.0, 0.0, 200.0)), None);
    }

    #[test]
    fn pixel_solid_angles_sum_to_the_image() {
        // Sum over the pixels = solid angle of the whole image rectangle; small pixels
        // approach pitch² cos³ of their off-axis angle.
        let c = FrameCamera::from_angles(DVec3::ZERO, (0.3, 0.2, 0.1), 0.02, (16, 12));
        let s: f64 = (0..12)
            .flat_map(|j| (0..16).map(move |i| (i, j)))
            .map(|(i, j)| c.pixel_solid_angle(i, j))
            .sum();
        let (hx, hy) = (8.0 * 0.02, 6.0 * 0.02);
        let whole = 4.0 * (hx * hy / (1.0f64 + hx * hx + hy * hy).sqrt()).atan();
        assert!((s - whole).abs() < 1e-12 * whole);
        let d = c.pixel_direction(0, 0);
        let cos = d.dot(c.axis);
        let approx = 0.02 * 0.02 * cos.powi(3);
        assert!((c.pixel_solid_angle(0, 0) / approx - 1.0).abs() < 1e-3);
    }

    #[test]
    fn look_at_and_roll() {
        let pos = DVec3::new(0.0, -100.0, 100.0);
        let (t, p) = FrameCamera::look_at_angles(pos, DVec3::ZERO).unwrap();
        assert!((t - PI / 4.0).abs() < 1e-12 && (p + PI / 2.0).abs() < 1e-12);
        let c = FrameCamera::from_angles(pos, (t, p, 0.0), 0.01, (8, 8));
        // The target is at the image centre; up points away from the camera and upward.
        assert!(c.plane_xy(-pos).unwrap().0.abs() < 1e-12);
        assert!(c.up.y > 0.0 && c.up.z > 0.0 && c.right.x > 0.0);
        let r = FrameCamera::from_angles(pos, (t, p, PI / 2.0), 0.01, (8, 8));
        // A quarter turn of the camera anticlockwise (seen from behind): its top goes left.
        assert!((r.up + c.right).length() < 1e-12);
    }
}
