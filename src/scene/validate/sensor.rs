//! Validation of the scene's sensors (part of [`super::validate`]): names, recorded bands,
//! camera position (above the ground), attitude and optics; every error names the field path
//! (`sensors[i]...`).

use super::*;

/// Largest pixel count of one camera image (16.8 Mpixel).
pub const MAX_SENSOR_PIXELS: u64 = 1 << 24;

/// The sensor sections of [`validate`].
impl V<'_> {
    /// Every sensor: a usable unique name, known bands, the instrument.
    pub(super) fn sensors(&self) -> R {
        let (desc, src) = (self.desc, self.src);
        let list = desc.sensors.as_deref().unwrap_or(&[]);
        for (i, s) in list.iter().enumerate() {
            let f = |x: &str| format!("sensors[{i}].{x}");
            if s.name.is_empty()
                || !s
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
            {
                return Err(src.invalid(
                    f("name"),
                    format!(
                        "`{}` is not usable as a file name (letters, digits, `-` and `_`)",
                        s.name
                    ),
                ));
            }
            if list[..i].iter().any(|o| o.name == s.name) {
                return Err(src.invalid(f("name"), format!("`{}` is used twice", s.name)));
            }
            for (k, b) in s.bands.iter().enumerate() {
                if !desc.bands.iter().any(|x| &x.name == b) {
                    return Err(src.invalid(
                        format!("sensors[{i}].bands[{k}]"),
                        format!("no band named `{b}` in `bands`"),
                    ));
                }
                if s.bands[..k].contains(b) {
                    return Err(src.invalid(
                        format!("sensors[{i}].bands[{k}]"),
                        format!("band `{b}` is listed twice"),
                    ));
                }
            }
            match &s.instrument {
                InstrumentDesc::FrameCamera(c) => self.frame_camera(i, c)?,
            }
        }
        Ok(())
    }

    /// Frame camera `i`: position above the ground, attitude, pixels and optics.
    fn frame_camera(&self, i: usize, c: &FrameCameraDesc) -> R {
        let src = self.src;
        let f = |x: &str| format!("sensors[{i}].instrument.{x}");
        let (x, y, z) = c.position_m;
        for v in [x, y, z] {
            self.finite(&f("position_m"), v)?;
        }
        if z <= 0.0 {
            return Err(src.invalid(
                f("position_m"),
                format!(
                    "the camera is at z = {} m, at or below the ground (z = 0): it must be above it",
                    num(z)
                ),
            ));
        }
        match &c.attitude {
            AttitudeDesc::LookAt { target_m, roll_deg } => {
                for v in [target_m.0, target_m.1, target_m.2] {
                    self.finite(&f("attitude.target_m"), v)?;
                }
                self.in_range(&f("attitude.roll_deg"), *roll_deg, -360.0, 360.0)?;
                if *target_m == c.position_m {
                    return Err(src.invalid(
                        f("attitude.target_m"),
                        "is the camera position: the camera needs a direction to look in",
                    ));
                }
            }
            AttitudeDesc::Angles {
                zenith_deg,
                azimuth_deg,
                roll_deg,
            } => {
                self.in_range(&f("attitude.zenith_deg"), *zenith_deg, 0.0, 180.0)?;
                self.in_range(&f("attitude.azimuth_deg"), *azimuth_deg, -360.0, 360.0)?;
                self.in_range(&f("attitude.roll_deg"), *roll_deg, -360.0, 360.0)?;
            }
        }
        let (nx, ny) = c.pixels;
        let n = nx as u64 * ny as u64;
        if nx == 0 || ny == 0 || n > MAX_SENSOR_PIXELS {
            return Err(src.invalid(
                f("pixels"),
                format!("{nx} × {ny} pixels (allowed: 1 to {MAX_SENSOR_PIXELS} in all)"),
            ));
        }
        match (c.fov_deg, c.focal_length_mm, c.pixel_pitch_um) {
            (Some(fov), None, None) => self.in_range(&f("fov_deg"), fov, 1e-6, 170.0)?,
            (None, Some(fl), Some(p)) => {
                self.positive(&f("focal_length_mm"), fl)?;
                self.positive(&f("pixel_pitch_um"), p)?;
            }
            _ => {
                return Err(src.invalid(
                    f("fov_deg"),
                    "give either fov_deg, or focal_length_mm with pixel_pitch_um",
                ));
            }
        }
        let model = c
            .model()
            .ok_or_else(|| src.invalid(f("attitude"), "is degenerate"))?;
        let (fx, fy) = model.fov();
        let most = 170f64.to_radians();
        if !(fx <= most && fy <= most) {
            return Err(src.invalid(
                f("pixels"),
                format!(
                    "give a field of view of {:.1}° × {:.1}°: at most 170° across either side",
                    fx.to_degrees(),
                    fy.to_degrees()
                ),
            ));
        }
        Ok(())
    }
}
