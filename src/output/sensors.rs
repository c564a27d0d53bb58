//! Sensor-stage products (DART 5 paper §5; docs/guide/products.md): per camera
//! `sensors/<name>.exr` (radiance, reflectance factor and their standard errors, one channel
//! per recorded band), a PNG quick-look of the first band's reflectance factor and a JSON
//! sidecar with the camera model, the per-pixel view geometry summarised and the per-band
//! image means; [`summary_entry`] is the camera's record in `summary.json`.

use crate::geometry::camera::FrameCamera;
use crate::io::atomic::write_atomic;
use crate::io::exr_out::{ExrLayer, ExrMeta, write_exr_layers_with};
use crate::photon::sensors::{SensorImage, SensorProducts};
use serde_json::json;

/// Writes every camera's products into `dir/sensors/`.
pub fn write_sensors(dir: &std::path::Path, p: &SensorProducts) -> Result<(), String> {
    let out = dir.join("sensors");
    std::fs::create_dir_all(&out)
        .map_err(|e| format!("{}: cannot create sensors folder: {e}", out.display()))?;
    for img in &p.0 {
        write_image(&out, img)?;
    }
    Ok(())
}

/// Top row first (pixel row j = 0 at the top) into the writer's map order (+y up).
fn map_order(v: &[f64], nx: usize, ny: usize) -> Vec<f64> {
    let mut o = vec![0.0; v.len()];
    for j in 0..ny {
        o[nx * (ny - 1 - j)..nx * (ny - j)].copy_from_slice(&v[nx * j..nx * (j + 1)]);
    }
    o
}

/// One camera's EXR, PNG quick-look and JSON sidecar.
fn write_image(out: &std::path::Path, img: &SensorImage) -> Result<(), String> {
    let cam = &img.camera;
    let (nx, ny) = (cam.nx, cam.ny);
    let mut layers: Vec<ExrLayer> = ["radiance", "radiance_se", "reflectance", "reflectance_se"]
        .iter()
        .map(|n| ExrLayer {
            name: n.to_string(),
            channels: Vec::new(),
        })
        .collect();
    for (k, b) in img.band_names.iter().enumerate() {
        let ch = format!("{k:02}_{b}");
        let vals = [
            img.radiance[k].clone(),
            img.radiance_se[k].clone(),
            img.reflectance(k),
            img.reflectance_se(k),
        ];
        for (l, v) in layers.iter_mut().zip(vals) {
            l.channels.push((ch.clone(), map_order(&v, nx, ny)));
        }
    }
    let (fx, fy) = cam.fov();
    let meta = ExrMeta {
        pixel_size_m: None,
        values: vec![
            ("camera_x_m".into(), cam.position.x),
            ("camera_y_m".into(), cam.position.y),
            ("camera_z_m".into(), cam.position.z),
            ("fov_x_deg".into(), fx.to_degrees()),
            ("fov_y_deg".into(), fy.to_degrees()),
        ],
    };
    write_exr_layers_with(
        &out.join(format!("{}.exr", img.name)),
        nx,
        ny,
        &layers,
        &meta,
    )?;
    if !img.band_names.is_empty() {
        crate::output::radiative::write_png(
            &out.join(format!("{}.png", img.name)),
            nx,
            ny,
            &map_order(&img.reflectance(0), nx, ny),
        )?;
    }
    let mut side = json!({
        "name": img.name,
        "kind": "frame-camera",
        "camera": camera_json(cam),
        "view_geometry": view_geometry(cam),
        "bands": bands_json(img),
    });
    side["files"] = json!({
        "exr": format!("{}.exr", img.name),
        "png": format!("{}.png", img.name),
    });
    write_atomic(
        &out.join(format!("{}.json", img.name)),
        serde_json::to_string_pretty(&side)
            .map_err(|e| e.to_string())?
            .as_bytes(),
    )
}

/// The camera model: pinhole position, frame, pixel pitch over focal length, fields of view.
fn camera_json(cam: &FrameCamera) -> serde_json::Value {
    let v = |d: glam::DVec3| [d.x, d.y, d.z];
    let (fx, fy) = cam.fov();
    let n = cam.nx * cam.ny;
    let (mut smin, mut smax) = (f64::INFINITY, 0.0f64);
    for px in 0..n {
        let s = cam.pixel_solid_angle(px % cam.nx, px / cam.nx);
        smin = smin.min(s);
        smax = smax.max(s);
    }
    json!({
        "model": "pinhole",
        "position_m": v(cam.position),
        "axis": v(cam.axis),
        "right": v(cam.right),
        "up": v(cam.up),
        "pixels": [cam.nx, cam.ny],
        "pitch_over_focal": cam.pitch,
        "fov_deg": [fx.to_degrees(), fy.to_degrees()],
        "pixel_solid_angle_sr": {"min": smin, "max": smax},
        "pixel_order": "row-major from the top-left pixel (column i, row j: index i + nx·j)",
    })
}

/// Summary of the per-pixel view geometry: view zenith and azimuth of every pixel's centre
/// (the direction from the scene toward the camera, azimuth anticlockwise from +x) and its
/// range to the plane z = 0 (pixels looking above the horizon have none).
fn view_geometry(cam: &FrameCamera) -> serde_json::Value {
    let (mut zmin, mut zmax, mut zsum) = (f64::INFINITY, f64::NEG_INFINITY, 0.0);
    let (mut rmin, mut rmax) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut reach = 0usize;
    let n = cam.nx * cam.ny;
    let angles = |d: glam::DVec3| {
        let o = -d;
        (
            o.z.clamp(-1.0, 1.0).acos().to_degrees(),
            o.y.atan2(o.x).to_degrees().rem_euclid(360.0),
        )
    };
    for px in 0..n {
        let d = cam.pixel_direction(px % cam.nx, px / cam.nx);
        let (z, _) = angles(d);
        zmin = zmin.min(z);
        zmax = zmax.max(z);
        zsum += z;
        if d.z < 0.0 {
            let r = -cam.position.z / d.z;
            rmin = rmin.min(r);
            rmax = rmax.max(r);
            reach += 1;
        }
    }
    let (cz, ca) = angles(cam.axis);
    json!({
        "view_zenith_deg": {"min": zmin, "max": zmax, "mean": zsum / n as f64},
        "axis_view_zenith_deg": cz,
        "axis_view_azimuth_deg": ca,
        "range_to_z0_m": (reach > 0).then(|| json!({"min": rmin, "max": rmax})),
        "pixels_reaching_z0": reach,
    })
}

/// Per recorded band: the horizontal irradiance, the image-mean radiance and reflectance
/// factor with their standard errors.
fn bands_json(img: &SensorImage) -> Vec<serde_json::Value> {
    img.band_names
        .iter()
        .enumerate()
        .map(|(k, b)| {
            let (l, lse) = img.mean_radiance[k];
            let (rf, rfse) = img.mean_reflectance(k);
            json!({
                "band": b,
                "irradiance": img.irradiance[k],
                "mean_radiance": l,
                "mean_radiance_se": lse,
                "mean_reflectance_factor": rf,
                "mean_reflectance_factor_se": rfse,
            })
        })
        .collect()
}

/// The camera's record in `summary.json`: name, kind, pixels, products and per-band means.
pub fn summary_entry(img: &SensorImage) -> serde_json::Value {
    json!({
        "name": img.name,
        "kind": "frame-camera",
        "pixels": [img.camera.nx, img.camera.ny],
        "exr": format!("sensors/{}.exr", img.name),
        "sidecar": format!("sensors/{}.json", img.name),
        "bands": bands_json(img),
    })
}
