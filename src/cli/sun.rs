//! `lumenscape sun`: solar position (NREL SPA) for a UTC date-time and a place, in compass and
//! scene (DART) conventions, as JSON or CSV; optionally the view geometry of a geostationary
//! satellite.
//!
//! Output fields: `zenith_deg`, `apparent_zenith_deg`, `azimuth_from_north_deg` (clockwise from
//! north), `azimuth_deg` (scene convention: anticlockwise from +x, +x having compass bearing
//! `scene_x_bearing_deg`), elevations, refraction, equation of time, Earth–Sun distance and the
//! irradiance factor 1/r², declination; with `--geo-lon-deg`, `geo_view_zenith_deg`,
//! `geo_view_azimuth_from_north_deg`, `geo_view_azimuth_deg`, `geo_visible`.

use serde::Serialize;

use crate::physics::sun::{
    DEFAULT_SCENE_X_BEARING_DEG, EarthShape, GEOSTATIONARY_ALTITUDE_KM, GeostationarySatellite,
    Observer, Refraction, SPA_ATMOS_REFRACT_DEG, UtcDateTime, compass_to_scene_azimuth_deg,
    delta_t_estimate_s, geostationary_view, solar_position,
};

/// Output format of `lumenscape sun`.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// One JSON object.
    Json,
    /// A header line and one row.
    Csv,
}

/// Arguments of `lumenscape sun`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// UTC date-time, `YYYY-MM-DDTHH:MM:SS` (a space may replace `T`; fractions of a second and a
    /// trailing `Z` are accepted).
    #[arg(long)]
    pub utc: String,
    /// Latitude, degrees north (−90…90).
    #[arg(long, allow_negative_numbers = true)]
    pub lat: f64,
    /// Longitude, degrees east (−180…180; west negative).
    #[arg(long, allow_negative_numbers = true)]
    pub lon: f64,
    /// Altitude above sea level, m.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub altitude_m: f64,
    /// Local pressure for refraction, hPa.
    #[arg(long, default_value_t = 1013.25)]
    pub pressure_hpa: f64,
    /// Local temperature for refraction, °C.
    #[arg(long, default_value_t = 15.0, allow_negative_numbers = true)]
    pub temperature_c: f64,
    /// ΔT = TT − UT, seconds (default: Espenak & Meeus 2006 estimate for the date).
    #[arg(long, allow_negative_numbers = true)]
    pub delta_t_s: Option<f64>,
    /// Do not apply atmospheric refraction (apparent zenith = geometric zenith).
    #[arg(long)]
    pub no_refraction: bool,
    /// Compass bearing of the scene's +x axis, degrees (90 = +x east, +y north).
    #[arg(long, default_value_t = DEFAULT_SCENE_X_BEARING_DEG, allow_negative_numbers = true)]
    pub scene_x_bearing_deg: f64,
    /// Also report the view direction of a geostationary satellite at this sub-satellite
    /// longitude, degrees east (WGS-84 Earth).
    #[arg(long, allow_negative_numbers = true)]
    pub geo_lon_deg: Option<f64>,
    /// Altitude of the geostationary satellite above the equator, km.
    #[arg(long, default_value_t = GEOSTATIONARY_ALTITUDE_KM)]
    pub geo_altitude_km: f64,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Json)]
    pub format: Format,
}

/// One output record.
#[derive(Debug, Serialize)]
struct Report {
    utc: String,
    latitude_deg: f64,
    longitude_deg: f64,
    altitude_m: f64,
    delta_t_s: f64,
    refraction: bool,
    zenith_deg: f64,
    apparent_zenith_deg: f64,
    elevation_deg: f64,
    apparent_elevation_deg: f64,
    refraction_deg: f64,
    azimuth_from_north_deg: f64,
    azimuth_deg: f64,
    scene_x_bearing_deg: f64,
    equation_of_time_min: f64,
    earth_sun_distance_au: f64,
    irradiance_factor: f64,
    declination_deg: f64,
    julian_day: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    geo_view_zenith_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    geo_view_azimuth_from_north_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    geo_view_azimuth_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    geo_visible: Option<bool>,
}

/// Runs the subcommand, writing one JSON object or a CSV header and row to `out`.
/// Errors are user-facing messages naming the offending option.
pub fn run(args: &Args, out: &mut dyn std::io::Write) -> Result<(), String> {
    let time = UtcDateTime::parse(&args.utc).map_err(|e| format!("--utc: {e}"))?;
    let observer = Observer {
        latitude_deg: args.lat,
        longitude_deg: args.lon,
        altitude_m: args.altitude_m,
    };
    if !(args.scene_x_bearing_deg.is_finite()) {
        return Err(format!(
            "--scene-x-bearing-deg: {} is not a finite angle",
            args.scene_x_bearing_deg
        ));
    }
    let delta_t_s = args
        .delta_t_s
        .unwrap_or_else(|| delta_t_estimate_s(time.year, time.month));
    let refraction = Refraction {
        pressure_hpa: args.pressure_hpa,
        temperature_c: args.temperature_c,
        atmos_refract_deg: SPA_ATMOS_REFRACT_DEG,
    };
    let p = solar_position(
        &time,
        &observer,
        delta_t_s,
        (!args.no_refraction).then_some(&refraction),
    )
    .map_err(|e| option_names(&e.to_string()))?;
    let geo = match args.geo_lon_deg {
        Some(lon) => {
            let sat = GeostationarySatellite {
                sub_satellite_longitude_deg: lon,
                altitude_km: args.geo_altitude_km,
            };
            Some(
                geostationary_view(&observer, &sat, EarthShape::Wgs84)
                    .map_err(|e| option_names(&e.to_string()))?,
            )
        }
        None => None,
    };
    let report = Report {
        utc: time.to_string(),
        latitude_deg: args.lat,
        longitude_deg: args.lon,
        altitude_m: args.altitude_m,
        delta_t_s,
        refraction: !args.no_refraction,
        zenith_deg: p.zenith_deg,
        apparent_zenith_deg: p.apparent_zenith_deg,
        elevation_deg: p.elevation_deg,
        apparent_elevation_deg: p.apparent_elevation_deg,
        refraction_deg: p.refraction_deg,
        azimuth_from_north_deg: p.azimuth_from_north_deg,
        azimuth_deg: p.scene_angles(args.scene_x_bearing_deg).azimuth_deg,
        scene_x_bearing_deg: args.scene_x_bearing_deg,
        equation_of_time_min: p.equation_of_time_min,
        earth_sun_distance_au: p.earth_sun_distance_au,
        irradiance_factor: p.irradiance_factor(),
        declination_deg: p.declination_deg,
        julian_day: p.julian_day,
        geo_view_zenith_deg: geo.map(|g| g.zenith_deg),
        geo_view_azimuth_from_north_deg: geo.map(|g| g.azimuth_from_north_deg),
        geo_view_azimuth_deg: geo.map(|g| {
            compass_to_scene_azimuth_deg(g.azimuth_from_north_deg, args.scene_x_bearing_deg)
        }),
        geo_visible: geo.map(|g| g.visible),
    };
    let io = |e: std::io::Error| format!("cannot write output: {e}");
    match args.format {
        Format::Json => {
            let text = serde_json::to_string_pretty(&report)
                .map_err(|e| format!("cannot encode JSON: {e}"))?;
            writeln!(out, "{text}").map_err(io)?;
        }
        Format::Csv => {
            let value = serde_json::to_value(&report).map_err(|e| format!("cannot encode: {e}"))?;
            let obj = value
                .as_object()
                .ok_or("internal error: report is not an object")?;
            let keys: Vec<&str> = obj.keys().map(String::as_str).collect();
            let cells: Vec<String> = obj
                .values()
                .map(|v| match v {
                    serde_json::Value::String(s) => s.clone(),
                    other => other.to_string(),
                })
                .collect();
            writeln!(out, "{}", keys.join(",")).map_err(io)?;
            writeln!(out, "{}", cells.join(",")).map_err(io)?;
        }
    }
    Ok(())
}

/// Rewrites library field names into the command-line option names in a message.
fn option_names(message: &str) -> String {
    let mut m = message.to_string();
    for (field, option) in [
        ("`latitude_deg`", "`--lat`"),
        ("`longitude_deg`", "`--lon`"),
        ("`altitude_m`", "`--altitude-m`"),
        ("`delta_t_s`", "`--delta-t-s`"),
        ("`pressure_hpa`", "`--pressure-hpa`"),
        ("`temperature_c`", "`--temperature-c`"),
        ("`sub_satellite_longitude_deg`", "`--geo-lon-deg`"),
        ("`altitude_km`", "`--geo-altitude-km`"),
    ] {
        m = m.replace(field, option);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    fn run_with(argv: &[&str]) -> Result<String, String> {
        let cli = Cli::try_parse_from(std::iter::once("sun").chain(argv.iter().copied()))
            .map_err(|e| e.to_string())?;
        let mut out = Vec::new();
        run(&cli.args, &mut out)?;
        Ok(String::from_utf8(out).unwrap())
    }

    const SPA: [&str; 14] = [
        "--utc",
        "2003-10-17T19:30:30",
        "--lat",
        "39.742476",
        "--lon",
        "-105.1786",
        "--altitude-m",
        "1830.14",
        "--pressure-hpa",
        "820",
        "--temperature-c",
        "11",
        "--delta-t-s",
        "67",
    ];

    #[test]
    fn json_reports_the_spa_example() {
        let text = run_with(&SPA).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        // Reda & Andreas (2004) example: topocentric zenith 50.11162°, azimuth 194.34024°.
        assert!((v["apparent_zenith_deg"].as_f64().unwrap() - 50.11162).abs() < 1e-5);
        assert!((v["azimuth_from_north_deg"].as_f64().unwrap() - 194.34024).abs() < 1e-5);
        // Scene azimuth with +x east: 90 − 194.34024 + 360.
        assert!((v["azimuth_deg"].as_f64().unwrap() - 255.65976).abs() < 1e-5);
        assert!(v["zenith_deg"].as_f64().is_some());
        assert!(v.get("geo_view_zenith_deg").is_none());
    }

    #[test]
    fn csv_and_options() {
        let mut argv: Vec<&str> = SPA.to_vec();
        argv.extend([
            "--format",
            "csv",
            "--no-refraction",
            "--scene-x-bearing-deg",
            "0",
            "--geo-lon-deg",
            "-75",
        ]);
        let text = run_with(&argv).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 2);
        let keys: Vec<&str> = lines[0].split(',').collect();
        let vals: Vec<&str> = lines[1].split(',').collect();
        assert_eq!(keys.len(), vals.len());
        let get = |k: &str| vals[keys.iter().position(|x| *x == k).unwrap()];
        assert_eq!(get("apparent_zenith_deg"), get("zenith_deg"));
        assert_eq!(get("refraction"), "false");
        // +x north: φ = 0 − γ.
        let gamma: f64 = get("azimuth_from_north_deg").parse().unwrap();
        let phi: f64 = get("azimuth_deg").parse().unwrap();
        assert!((phi - (360.0 - gamma)).abs() < 1e-9);
        assert_eq!(get("geo_visible"), "true");
        // Default ΔT is the estimate.
        let text = run_with(&["--utc", "2003-10-17 19:30:30", "--lat", "0", "--lon", "0"]).unwrap();
        assert!(text.contains("\"delta_t_s\": 64."), "{text}");
    }

    #[test]
    fn errors_name_the_option() {
        let e =
            run_with(&["--utc", "2003-10-32T00:00:00", "--lat", "0", "--lon", "0"]).unwrap_err();
        assert!(e.starts_with("--utc:") && e.contains("day 32"), "{e}");
        let e =
            run_with(&["--utc", "2003-10-17T00:00:00", "--lat", "95", "--lon", "0"]).unwrap_err();
        assert!(e.contains("`--lat`"), "{e}");
        let e = run_with(&[
            "--utc",
            "2003-10-17T00:00:00",
            "--lat",
            "0",
            "--lon",
            "0",
            "--pressure-hpa",
            "0",
        ])
        .unwrap_err();
        assert!(e.contains("`--pressure-hpa`"), "{e}");
        let e = run_with(&[
            "--utc",
            "2003-10-17T00:00:00",
            "--lat",
            "0",
            "--lon",
            "0",
            "--format",
            "xml",
        ])
        .unwrap_err();
        assert!(e.contains("xml"), "{e}");
    }
}
