//! Authoring types of the sensors (`sensors` in a scene; DART 5 paper §5, Figure 17;
//! physics.md §8): named instruments at a finite distance, each with the bands it records.
//! Re-exported by [`crate::scene::desc`].

use super::*;
use crate::geometry::camera::FrameCamera;
use glam::DVec3;

/// A sensor: a named instrument that records an image of the scene from a finite distance.
/// Its products go to `DIR/sensors/<name>.exr` and `DIR/sensors/<name>.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorDesc {
    /// Name (file names of its products; letters, digits, `-` and `_`).
    pub name: String,
    /// Names of the scene bands recorded (default: all bands).
    #[serde(default)]
    pub bands: Vec<String>,
    /// The instrument: `FrameCamera(..)`.
    pub instrument: InstrumentDesc,
}

/// The kind of instrument of a [`SensorDesc`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum InstrumentDesc {
    /// A frame camera (pinhole projection, DART 5 paper §5 eq. 7): every pixel records the
    /// mean radiance over its solid angle seen from the pinhole.
    FrameCamera(FrameCameraDesc),
}

/// A frame (pinhole) camera: position, attitude and optics. Pixel (0, 0) is the top-left
/// corner of the image; pixels are square.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameCameraDesc {
    /// Position of the pinhole in scene coordinates (x, y, z), m: above the ground.
    pub position_m: (f64, f64, f64),
    /// Where the camera looks: `LookAt(target_m: (x, y, z))` or
    /// `Angles(zenith_deg: .., azimuth_deg: .., roll_deg: ..)`.
    pub attitude: AttitudeDesc,
    /// Pixel count (columns, rows).
    pub pixels: (u32, u32),
    /// Full field of view across the image width (columns), degrees in (0, 170]; give
    /// either this or `focal_length_mm` with `pixel_pitch_um`.
    #[serde(default)]
    pub fov_deg: Option<f64>,
    /// Focal length, mm (with `pixel_pitch_um`, instead of `fov_deg`).
    #[serde(default)]
    pub focal_length_mm: Option<f64>,
    /// Pixel pitch on the detector, µm (with `focal_length_mm`).
    #[serde(default)]
    pub pixel_pitch_um: Option<f64>,
}

/// Attitude of a camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum AttitudeDesc {
    /// The optical axis goes through `target_m` (scene coordinates, m); image up is the far
    /// side of an oblique view (a vertical axis: +y), turned by `roll_deg` (default 0).
    LookAt {
        /// The point at the image centre, m.
        target_m: (f64, f64, f64),
        /// Rotation of the camera about its axis, anticlockwise seen from behind it, degrees.
        #[serde(default)]
        roll_deg: f64,
    },
    /// Three rotation angles: the camera sits in the view direction (zenith, azimuth) from
    /// what it looks at (optical axis `−Ω(θ, φ)`, θ in [0, 180] from the zenith, φ
    /// anticlockwise from +x as every azimuth of the scene), image up the far side (at θ = 0,
    /// toward azimuth φ + 180°), then turned about its axis by `roll_deg`.
    Angles {
        /// View zenith angle θ of the camera seen from its target, degrees.
        zenith_deg: f64,
        /// View azimuth φ, degrees (anticlockwise from +x).
        azimuth_deg: f64,
        /// Rotation of the camera about its axis, anticlockwise seen from behind it, degrees.
        #[serde(default)]
        roll_deg: f64,
    },
}

impl FrameCameraDesc {
    /// The pinhole model of this camera ([`FrameCamera`]); `None` when the attitude is
    /// degenerate (a look-at target at the camera) or the optics are missing (validation
    /// refuses both).
    pub fn model(&self) -> Option<FrameCamera> {
        let (x, y, z) = self.position_m;
        let pos = DVec3::new(x, y, z);
        let (theta, phi, roll) = match &self.attitude {
            AttitudeDesc::LookAt { target_m, roll_deg } => {
                let t = DVec3::new(target_m.0, target_m.1, target_m.2);
                let (th, ph) = FrameCamera::look_at_angles(pos, t)?;
                (th, ph, roll_deg.to_radians())
            }
            AttitudeDesc::Angles {
                zenith_deg,
                azimuth_deg,
                roll_deg,
            } => (
                zenith_deg.to_radians(),
                azimuth_deg.to_radians(),
                roll_deg.to_radians(),
            ),
        };
        let nx = self.pixels.0 as usize;
        let pitch = match (self.fov_deg, self.focal_length_mm, self.pixel_pitch_um) {
            (Some(fov), None, None) => 2.0 * (0.5 * fov.to_radians()).tan() / nx as f64,
            (None, Some(f), Some(p)) => p * 1e-3 / f,
            _ => return None,
        };
        Some(FrameCamera::from_angles(
            pos,
            (theta, phi, roll),
            pitch,
            (nx, self.pixels.1 as usize),
        ))
    }
}
