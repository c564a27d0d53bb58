//! Products of the sensor stage from the Monte Carlo camera tallies (DART 5 paper §5;
//! physics.md §8.1): per camera and recorded band the pixel radiance `L` (W m⁻² sr⁻¹ per unit
//! of the band's irradiance), the reflectance factor `π L / E` with `E` the horizontal
//! irradiance (sun, plus sky when the scene has one; without sky `E = E_sun cos θ_s` and the
//! factor is the camera's BRF), their per-pixel standard errors from the spread of the batch
//! estimates, and the image means with theirs.

use super::engine::PhotonResult;
use crate::geometry::camera::FrameCamera;
use bevy_ecs::prelude::Resource;
use std::f64::consts::PI;

/// One camera's image.
#[derive(Debug, Clone)]
pub struct SensorImage {
    /// Sensor name.
    pub name: String,
    /// The pinhole model.
    pub camera: FrameCamera,
    /// Names of the recorded bands.
    pub band_names: Vec<String>,
    /// Horizontal irradiance per recorded band (sun + sky), W m⁻² (per band unit).
    pub irradiance: Vec<f64>,
    /// Pixel radiance `[band][i + nx·j]`, W m⁻² sr⁻¹ (per band unit).
    pub radiance: Vec<Vec<f64>>,
    /// Standard error of `radiance`.
    pub radiance_se: Vec<Vec<f64>>,
    /// Image-mean radiance per band and its standard error.
    pub mean_radiance: Vec<(f64, f64)>,
}

impl SensorImage {
    /// Reflectance factor `π L / E` of recorded band `k` (per pixel).
    pub fn reflectance(&self, k: usize) -> Vec<f64> {
        let f = PI / self.irradiance[k];
        self.radiance[k].iter().map(|l| l * f).collect()
    }
    /// Standard error of [`SensorImage::reflectance`].
    pub fn reflectance_se(&self, k: usize) -> Vec<f64> {
        let f = PI / self.irradiance[k];
        self.radiance_se[k].iter().map(|l| l * f).collect()
    }
    /// Image-mean reflectance factor of recorded band `k` and its standard error.
    pub fn mean_reflectance(&self, k: usize) -> (f64, f64) {
        let f = PI / self.irradiance[k];
        (self.mean_radiance[k].0 * f, self.mean_radiance[k].1 * f)
    }
}

/// The camera images of a Monte Carlo run (inserted by the Photon stage when the scene has
/// sensors).
#[derive(Debug, Clone, Default, Resource)]
pub struct SensorProducts(pub Vec<SensorImage>);

/// A camera of the run: its name, the scene bands it records (indices) and its model, in the
/// order of the engine input's cameras.
pub struct CameraSpec {
    /// Sensor name.
    pub name: String,
    /// Recorded scene bands.
    pub bands: Vec<usize>,
    /// The pinhole model.
    pub camera: FrameCamera,
}

/// Standard error of a sum over `nbat` batches from the sum `s` and the sum of squares `sq`
/// of the batch values: `√(B/(B−1) (Σ S_k² − (Σ S_k)²/B))`.
fn se_from(s: f64, sq: f64, nbat: usize) -> f64 {
    if nbat < 2 {
        return f64::NAN;
    }
    let b = nbat as f64;
    (b / (b - 1.0) * (sq - s * s / b).max(0.0)).sqrt()
}

/// The images of `cams` (the engine input's cameras, in order) from the run's tallies;
/// `band_names`, `e_dir` and `e_diff` are the scene's (horizontal irradiances per band).
pub fn sensor_products(
    res: &PhotonResult,
    cams: &[CameraSpec],
    band_names: &[String],
    e_dir: &[f64],
    e_diff: &[f64],
) -> SensorProducts {
    let nb = res.n_bands;
    let w = res.n_channels;
    let nbat = res.batch_summaries.len();
    let mut base = 0;
    let mut out = Vec::with_capacity(cams.len());
    for (c, spec) in cams.iter().enumerate() {
        let n = spec.camera.nx * spec.camera.ny;
        let total = |px: usize, b: usize| {
            let v = &res.camera[base + px * w..base + (px + 1) * w];
            v[b] + if res.has_sky { v[nb + b] } else { 0.0 }
        };
        let sq0 = base / w * nb;
        let mut img = SensorImage {
            name: spec.name.clone(),
            camera: spec.camera.clone(),
            band_names: spec.bands.iter().map(|&b| band_names[b].clone()).collect(),
            irradiance: spec.bands.iter().map(|&b| e_dir[b] + e_diff[b]).collect(),
            radiance: Vec::new(),
            radiance_se: Vec::new(),
            mean_radiance: Vec::new(),
        };
        for &b in &spec.bands {
            let l: Vec<f64> = (0..n).map(|px| total(px, b)).collect();
            let se: Vec<f64> = (0..n)
                .map(|px| se_from(l[px], res.camera_sq[sq0 + px * nb + b], nbat))
                .collect();
            let mean = l.iter().sum::<f64>() / n as f64;
            let mse = se_from(mean, res.camera_mean_sq[c * nb + b], nbat);
            img.radiance.push(l);
            img.radiance_se.push(se);
            img.mean_radiance.push((mean, mse));
        }
        base += n * w;
        out.push(img);
    }
    SensorProducts(out)
}
