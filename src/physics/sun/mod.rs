//! Solar position (NREL SPA), scene azimuth conventions, Earth–Sun distance correction and
//! geostationary-satellite view geometry.
//!
//! Pure formulas, no ECS. Inputs: a UTC date-time ([`UtcDateTime`], parsed from
//! `2003-10-17T19:30:30`), an [`Observer`] (latitude, longitude, altitude), ΔT and optional
//! refraction conditions. Outputs: [`SolarPosition`] (zenith, azimuth from north, equation of time,
//! Earth–Sun distance, declination), its conversion to the scene convention ([`SceneAngles`]:
//! DART azimuth, anticlockwise from +x), the irradiance correction 1/r², and [`SatelliteView`]
//! for a geostationary satellite (physics.md §12).
//!
//! Algorithm: Reda I., Andreas A. (2004), Solar position algorithm for solar radiation
//! applications, *Solar Energy* 76:577–589 (NREL/TP-560-34302, rev. 2008) — the full algorithm,
//! with the VSOP87-derived periodic terms of its Table A4.2 and the nutation terms of Table A4.3
//! (transcribed from pvlib's `spa.py`, BSD-3-Clause), ±0.0003° for years −2000 to 6000.
//!
//! # Azimuth conventions (physics.md §1.1, §12.1)
//! * **Compass azimuth** γ: from geographic north, clockwise seen from above (east = 90°). This is
//!   what SPA returns ([`SolarPosition::azimuth_from_north_deg`]).
//! * **Scene (DART) azimuth** φ: anticlockwise from the scene's +x axis seen from above (+y = 90°),
//!   the frame being right-handed with z up. The scene's orientation is the compass bearing β of
//!   its +x axis (`scene_x_bearing_deg`, default 90° = +x points east, +y north). Then
//!   **φ = (β − γ) mod 360°** and γ = (β − φ) mod 360°; with β = 90° this is DART's
//!   φ = (90° − γ) mod 360°. Results lie in [0°, 360°).
//! * Sun and satellite directions are given as *viewing* angles (ground → sun/sensor): zenith
//!   θ ∈ [0°, 180°] and the azimuth of the direction towards the body.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// Default compass bearing of the scene's +x axis, degrees: +x points east, +y north.
pub const DEFAULT_SCENE_X_BEARING_DEG: f64 = 90.0;
/// Standard atmospheric refraction at sunrise/sunset used by SPA to decide whether the sun is up,
/// degrees (Reda & Andreas 2004, §3.14.1).
pub const SPA_ATMOS_REFRACT_DEG: f64 = 0.5667;
/// Apparent solar radius used by SPA's refraction switch, degrees (Reda & Andreas 2004, §3.14.1).
const SUN_RADIUS_DEG: f64 = 0.26667;
/// Altitude of the geostationary orbit above the equator, km (r = 42164.137 km).
pub const GEOSTATIONARY_ALTITUDE_KM: f64 = 35_786.0;
/// WGS-84 equatorial radius, km.
pub const WGS84_A_KM: f64 = 6378.137;
/// WGS-84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// Mean Earth radius for the spherical Earth model, km (physics.md §12.2).
pub const MEAN_EARTH_RADIUS_KM: f64 = 6371.0;

/// Errors of the solar-geometry functions: bad date-times or out-of-domain inputs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SunError {
    /// A date-time string could not be parsed or is not a valid date.
    #[error("invalid UTC date-time `{input}`: {reason}")]
    InvalidTime {
        /// The text given.
        input: String,
        /// What is wrong.
        reason: String,
    },
    /// A numeric input is outside its domain; `field` names it.
    #[error("invalid `{field}` = {value}: {reason}")]
    InvalidInput {
        /// Name of the input (`latitude_deg`, `pressure_hpa`, …).
        field: &'static str,
        /// The value given.
        value: f64,
        /// The accepted domain.
        reason: &'static str,
    },
}

/// A UTC calendar date and time (proleptic Gregorian calendar for validation; SPA's Julian day
/// switches to the Julian calendar before 1582-10-15, as in Reda & Andreas 2004, eq. 4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UtcDateTime {
    /// Year, −2000 to 6000 (SPA's validity range).
    pub year: i32,
    /// Month, 1–12.
    pub month: u32,
    /// Day of the month, 1–28/29/30/31.
    pub day: u32,
    /// Hour, 0–23.
    pub hour: u32,
    /// Minute, 0–59.
    pub minute: u32,
    /// Second, 0 ≤ s < 60 (fractions allowed).
    pub second: f64,
}

fn is_leap_year(year: i32) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

fn days_in_month(year: i32, month: u32) -> u32 {
    match month {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if is_leap_year(year) => 29,
        2 => 28,
        _ => 0,
    }
}

impl UtcDateTime {
    /// A validated date-time (year −2000…6000, real calendar day, 0 ≤ second < 60).
    pub fn new(
        year: i32,
        month: u32,
        day: u32,
        hour: u32,
        minute: u32,
        second: f64,
    ) -> Result<UtcDateTime, SunError> {
        let t = UtcDateTime {
            year,
            month,
            day,
            hour,
            minute,
            second,
        };
        let bad = |reason: String| SunError::InvalidTime {
            input: t.to_string(),
            reason,
        };
        if !(-2000..=6000).contains(&year) {
            return Err(bad(format!(
                "year {year} is outside SPA's range -2000..6000"
            )));
        }
        if !(1..=12).contains(&month) {
            return Err(bad(format!("month {month} is not in 1..12")));
        }
        let dim = days_in_month(year, month);
        if day < 1 || day > dim {
            return Err(bad(format!(
                "day {day} is not in 1..{dim} for {year}-{month:02}"
            )));
        }
        if hour > 23 {
            return Err(bad(format!("hour {hour} is not in 0..23")));
        }
        if minute > 59 {
            return Err(bad(format!("minute {minute} is not in 0..59")));
        }
        if !(second.is_finite() && (0.0..60.0).contains(&second)) {
            return Err(bad(format!("second {second} is not in [0, 60)")));
        }
        Ok(t)
    }

    /// Parses `YYYY-MM-DDTHH:MM[:SS[.fff]][Z]`; a space may replace the `T`. Only UTC is accepted
    /// (a trailing `Z` is allowed, other offsets are rejected).
    pub fn parse(text: &str) -> Result<UtcDateTime, SunError> {
        let input = text.trim();
        let bad = |reason: &str| SunError::InvalidTime {
            input: input.to_string(),
            reason: reason.to_string(),
        };
        let body = input
            .strip_suffix('Z')
            .or_else(|| input.strip_suffix('z'))
            .unwrap_or(input);
        let (date, time) = body.split_once(['T', 't', ' ']).ok_or_else(|| {
            bad("expected `YYYY-MM-DDTHH:MM:SS` (date and time separated by `T` or a space)")
        })?;
        let time = time.trim_start();
        if time.contains('+') || time.contains('-') {
            return Err(bad(
                "time-zone offsets are not accepted: give the time in UTC (optionally with a trailing `Z`)",
            ));
        }
        let d: Vec<&str> = date.split('-').collect();
        if d.len() != 3 || d[0].len() != 4 || d[1].len() != 2 || d[2].len() != 2 {
            return Err(bad("the date must be `YYYY-MM-DD`"));
        }
        let digits = |s: &str, what: &str| -> Result<u32, SunError> {
            if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
                return Err(bad(&format!("{what} `{s}` is not a number")));
            }
            s.parse::<u32>()
                .map_err(|_| bad(&format!("{what} `{s}` is not a number")))
        };
        let year = digits(d[0], "year")? as i32;
        let month = digits(d[1], "month")?;
        let day = digits(d[2], "day")?;
        let t: Vec<&str> = time.split(':').collect();
        if !(t.len() == 2 || t.len() == 3) || t[0].len() != 2 || t[1].len() != 2 {
            return Err(bad("the time must be `HH:MM` or `HH:MM:SS[.fff]`"));
        }
        let hour = digits(t[0], "hour")?;
        let minute = digits(t[1], "minute")?;
        let second = if t.len() == 3 {
            let s = t[2];
            let (int, frac) = s.split_once('.').unwrap_or((s, ""));
            if int.len() != 2 {
                return Err(bad("seconds must have two digits (`SS` or `SS.fff`)"));
            }
            digits(int, "second")?;
            if s.contains('.') {
                digits(frac, "fraction of second")?;
            }
            s.parse::<f64>()
                .map_err(|_| bad(&format!("second `{s}` is not a number")))?
        } else {
            0.0
        };
        UtcDateTime::new(year, month, day, hour, minute, second).map_err(|e| match e {
            SunError::InvalidTime { reason, .. } => SunError::InvalidTime {
                input: input.to_string(),
                reason,
            },
            other => other,
        })
    }

    /// Hours since midnight (fractional).
    pub fn hours(&self) -> f64 {
        self.hour as f64 + self.minute as f64 / 60.0 + self.second / 3600.0
    }

    /// Day of year, 1 on 1 January.
    pub fn day_of_year(&self) -> u32 {
        (1..self.month)
            .map(|m| days_in_month(self.year, m))
            .sum::<u32>()
            + self.day
    }

    /// Julian day (UT) of this instant, Reda & Andreas (2004) eq. 4 (Meeus 1998, eq. 7.1):
    /// JD = INT(365.25 (Y + 4716)) + INT(30.6001 (M + 1)) + D + B − 1524.5, with Y, M shifted for
    /// January/February and the Gregorian correction B = 2 − A + INT(A/4), A = INT(Y/100),
    /// applied from JD 2299160 on (INT truncates towards zero, as in SPA).
    pub fn julian_day(&self) -> f64 {
        let (mut y, mut m) = (self.year as f64, self.month as f64);
        if self.month <= 2 {
            y -= 1.0;
            m += 12.0;
        }
        let d = self.day as f64 + self.hours() / 24.0;
        let mut jd = (365.25 * (y + 4716.0)).trunc() + (30.6001 * (m + 1.0)).trunc() + d - 1524.5;
        if jd > 2_299_160.0 {
            let a = (y / 100.0).trunc();
            jd += 2.0 - a + (a / 4.0).trunc();
        }
        jd
    }
}

impl fmt::Display for UtcDateTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:04}-{:02}-{:02}T{:02}:{:02}:",
            self.year, self.month, self.day, self.hour, self.minute
        )?;
        if self.second.fract() == 0.0 {
            write!(f, "{:02}", self.second as u32)
        } else {
            let s = format!("{:09.6}", self.second);
            write!(f, "{}", s.trim_end_matches('0').trim_end_matches('.'))
        }
    }
}

impl FromStr for UtcDateTime {
    type Err = SunError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        UtcDateTime::parse(s)
    }
}

/// A place on Earth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Observer {
    /// Geodetic latitude, degrees, −90 (south) to 90 (north).
    pub latitude_deg: f64,
    /// Longitude, degrees east of Greenwich, −180 to 180 (west negative).
    pub longitude_deg: f64,
    /// Altitude above the ellipsoid/sea level, m.
    pub altitude_m: f64,
}

impl Observer {
    /// Checks the domain (|lat| ≤ 90°, |lon| ≤ 180°, altitude finite and > −6 500 km).
    pub fn validate(&self) -> Result<(), SunError> {
        let check = |field, value: f64, ok: bool, reason| {
            if ok && value.is_finite() {
                Ok(())
            } else {
                Err(SunError::InvalidInput {
                    field,
                    value,
                    reason,
                })
            }
        };
        check(
            "latitude_deg",
            self.latitude_deg,
            self.latitude_deg.abs() <= 90.0,
            "must be within [-90, 90] degrees",
        )?;
        check(
            "longitude_deg",
            self.longitude_deg,
            self.longitude_deg.abs() <= 180.0,
            "must be within [-180, 180] degrees (east positive)",
        )?;
        check(
            "altitude_m",
            self.altitude_m,
            self.altitude_m > -6_500_000.0,
            "must be a finite altitude above -6500 km",
        )
    }
}

/// Local atmospheric conditions for the refraction correction (Reda & Andreas 2004, §3.14;
/// Bennett-type formula of Meeus 1998, eq. 16.4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Refraction {
    /// Annual mean local pressure, hPa (mbar).
    pub pressure_hpa: f64,
    /// Annual mean local temperature, °C.
    pub temperature_c: f64,
    /// Refraction at sunrise/sunset, degrees; with the solar radius it sets the elevation below
    /// which no refraction is applied (default [`SPA_ATMOS_REFRACT_DEG`]).
    pub atmos_refract_deg: f64,
}

impl Refraction {
    /// Standard atmosphere at sea level: 1013.25 hPa, 15 °C, 0.5667° at the horizon.
    pub fn standard() -> Refraction {
        Refraction {
            pressure_hpa: 1013.25,
            temperature_c: 15.0,
            atmos_refract_deg: SPA_ATMOS_REFRACT_DEG,
        }
    }

    fn validate(&self) -> Result<(), SunError> {
        let err = |field, value, reason| {
            Err(SunError::InvalidInput {
                field,
                value,
                reason,
            })
        };
        if !(self.pressure_hpa.is_finite()
            && self.pressure_hpa > 0.0
            && self.pressure_hpa <= 5000.0)
        {
            return err(
                "pressure_hpa",
                self.pressure_hpa,
                "must be in ]0, 5000] hPa",
            );
        }
        if !(self.temperature_c.is_finite()
            && self.temperature_c > -273.0
            && self.temperature_c <= 6000.0)
        {
            return err(
                "temperature_c",
                self.temperature_c,
                "must be in ]-273, 6000] degC",
            );
        }
        if !(self.atmos_refract_deg.is_finite() && self.atmos_refract_deg.abs() <= 5.0) {
            return err(
                "atmos_refract_deg",
                self.atmos_refract_deg,
                "must be within [-5, 5] degrees",
            );
        }
        Ok(())
    }
}

/// Position of the sun seen from an [`Observer`] (all angles in degrees).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SolarPosition {
    /// Topocentric zenith angle without refraction (geometric).
    pub zenith_deg: f64,
    /// Topocentric zenith angle with refraction (equals `zenith_deg` when refraction is off or the
    /// sun is below −(0.26667° + atmos_refract)).
    pub apparent_zenith_deg: f64,
    /// 90° − `zenith_deg`.
    pub elevation_deg: f64,
    /// 90° − `apparent_zenith_deg`.
    pub apparent_elevation_deg: f64,
    /// Refraction correction applied, degrees (0 when off).
    pub refraction_deg: f64,
    /// Topocentric azimuth from north, clockwise (east = 90°), in [0, 360).
    pub azimuth_from_north_deg: f64,
    /// Equation of time (apparent − mean solar time), minutes.
    pub equation_of_time_min: f64,
    /// Earth–Sun distance, astronomical units.
    pub earth_sun_distance_au: f64,
    /// Geocentric declination of the sun.
    pub declination_deg: f64,
    /// Topocentric declination of the sun.
    pub topocentric_declination_deg: f64,
    /// Geocentric right ascension of the sun, in [0, 360).
    pub right_ascension_deg: f64,
    /// Topocentric local hour angle (westward from the meridian).
    pub hour_angle_deg: f64,
    /// Julian day (UT) of the instant.
    pub julian_day: f64,
}

/// Zenith and azimuth of a direction in the scene convention (DART): zenith from +z, azimuth
/// anticlockwise from +x (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SceneAngles {
    /// Zenith angle of the direction towards the body (ground → body), degrees.
    pub zenith_deg: f64,
    /// Azimuth of that direction, anticlockwise from the scene's +x axis, degrees in [0, 360).
    pub azimuth_deg: f64,
}

/// Converts a compass azimuth γ (from north, clockwise) into the scene azimuth φ (anticlockwise
/// from +x) for a scene whose +x axis has compass bearing β: φ = (β − γ) mod 360°
/// (physics.md §1.1; DART's φ = 90° − γ for β = 90°). Result in [0, 360).
pub fn compass_to_scene_azimuth_deg(azimuth_from_north_deg: f64, scene_x_bearing_deg: f64) -> f64 {
    wrap_360(scene_x_bearing_deg - azimuth_from_north_deg)
}

/// Inverse of [`compass_to_scene_azimuth_deg`]: γ = (β − φ) mod 360°, in [0, 360).
pub fn scene_to_compass_azimuth_deg(scene_azimuth_deg: f64, scene_x_bearing_deg: f64) -> f64 {
    wrap_360(scene_x_bearing_deg - scene_azimuth_deg)
}

fn wrap_360(x: f64) -> f64 {
    let r = x.rem_euclid(360.0);
    // rem_euclid can return 360.0 for tiny negative inputs.
    if r >= 360.0 { 0.0 } else { r }
}

impl SolarPosition {
    /// Sun viewing angles (ground → sun) in the scene convention: the apparent (refracted) zenith
    /// and the scene azimuth for a scene whose +x axis has compass bearing `scene_x_bearing_deg`.
    pub fn scene_angles(&self, scene_x_bearing_deg: f64) -> SceneAngles {
        SceneAngles {
            zenith_deg: self.apparent_zenith_deg,
            azimuth_deg: compass_to_scene_azimuth_deg(
                self.azimuth_from_north_deg,
                scene_x_bearing_deg,
            ),
        }
    }

    /// Factor (1 AU / r)² multiplying a solar irradiance given at 1 AU, see
    /// [`irradiance_distance_factor`].
    pub fn irradiance_factor(&self) -> f64 {
        irradiance_distance_factor(self.earth_sun_distance_au)
    }
}

/// Earth–Sun distance correction of the solar irradiance: E(r) = E(1 AU) · (1/r)², r in AU
/// (inverse-square law; physics.md §1.3). Returns NaN for r ≤ 0.
pub fn irradiance_distance_factor(earth_sun_distance_au: f64) -> f64 {
    if earth_sun_distance_au > 0.0 {
        1.0 / (earth_sun_distance_au * earth_sun_distance_au)
    } else {
        f64::NAN
    }
}

/// Low-accuracy Earth–Sun distance from the day of year, AU:
/// d ≈ 1 − 0.01672 cos(0.9856° (DOY − 4)) (physics.md §1.3; the form DART uses when only a day of
/// year is given). Within 5e-4 AU of SPA (4.0e-4 AU at worst over 2023, at 12:00 UTC).
pub fn earth_sun_distance_approx_au(day_of_year: u32) -> f64 {
    1.0 - 0.01672 * (0.9856_f64 * (day_of_year as f64 - 4.0)).to_radians().cos()
}

/// Estimate of ΔT = TT − UT, seconds, from the polynomial fits of Espenak & Meeus (2006, *Five
/// Millennium Canon of Solar Eclipses*, NASA TP-2006-214141, §2.6; as coded in pvlib
/// `calculate_deltat`). Good to a few seconds for 1900–2025 (e.g. 2024: 73.9 s vs 69.2 s
/// observed); an error of 10 s in ΔT moves the sun by less than 1e-4°.
pub fn delta_t_estimate_s(year: i32, month: u32) -> f64 {
    let y = year as f64 + (month as f64 - 0.5) / 12.0;
    let yr = year;
    if yr < -500 {
        let u = (y - 1820.0) / 100.0;
        -20.0 + 32.0 * u * u
    } else if yr < 500 {
        let u = y / 100.0;
        10583.6 - 1014.41 * u + 33.78311 * u.powi(2) - 5.952053 * u.powi(3) - 0.1798452 * u.powi(4)
            + 0.022174192 * u.powi(5)
            + 0.0090316521 * u.powi(6)
    } else if yr < 1600 {
        let u = (y - 1000.0) / 100.0;
        1574.2 - 556.01 * u + 71.23472 * u.powi(2) + 0.319781 * u.powi(3)
            - 0.8503463 * u.powi(4)
            - 0.005050998 * u.powi(5)
            + 0.0083572073 * u.powi(6)
    } else if yr < 1700 {
        let t = y - 1600.0;
        120.0 - 0.9808 * t - 0.01532 * t * t + t.powi(3) / 7129.0
    } else if yr < 1800 {
        let t = y - 1700.0;
        8.83 + 0.1603 * t - 0.0059285 * t * t + 0.00013336 * t.powi(3) - t.powi(4) / 1_174_000.0
    } else if yr < 1860 {
        let t = y - 1800.0;
        13.72 - 0.332447 * t + 0.0068612 * t * t + 0.0041116 * t.powi(3) - 0.00037436 * t.powi(4)
            + 0.0000121272 * t.powi(5)
            - 0.0000001699 * t.powi(6)
            + 0.000000000875 * t.powi(7)
    } else if yr < 1900 {
        let t = y - 1860.0;
        7.62 + 0.5737 * t - 0.251754 * t * t + 0.01680668 * t.powi(3) - 0.0004473624 * t.powi(4)
            + t.powi(5) / 233_174.0
    } else if yr < 1920 {
        let t = y - 1900.0;
        -2.79 + 1.494119 * t - 0.0598939 * t * t + 0.0061966 * t.powi(3) - 0.000197 * t.powi(4)
    } else if yr < 1941 {
        let t = y - 1920.0;
        21.20 + 0.84493 * t - 0.076100 * t * t + 0.0020936 * t.powi(3)
    } else if yr < 1961 {
        let t = y - 1950.0;
        29.07 + 0.407 * t - t * t / 233.0 + t.powi(3) / 2547.0
    } else if yr < 1986 {
        let t = y - 1975.0;
        45.45 + 1.067 * t - t * t / 260.0 - t.powi(3) / 718.0
    } else if yr < 2005 {
        let t = y - 2000.0;
        63.86 + 0.3345 * t - 0.060374 * t * t
            + 0.0017275 * t.powi(3)
            + 0.000651814 * t.powi(4)
            + 0.00002373599 * t.powi(5)
    } else if yr < 2050 {
        let t = y - 2000.0;
        62.92 + 0.32217 * t + 0.005589 * t * t
    } else if yr < 2150 {
        let u = (y - 1820.0) / 100.0;
        -20.0 + 32.0 * u * u - 0.5628 * (2150.0 - y)
    } else {
        let u = (y - 1820.0) / 100.0;
        -20.0 + 32.0 * u * u
    }
}

/// Σ A cos(B + C x) over a periodic-term table (Reda & Andreas 2004, eq. 9).
fn periodic_sum(table: &[[f64; 3]], x: f64) -> f64 {
    table.iter().map(|r| r[0] * (r[1] + r[2] * x).cos()).sum()
}

/// Polynomial in the Julian ephemeris millennium of per-power periodic sums, divided by 1e8
/// (Reda & Andreas 2004, eqs. 10–11), radians (or AU for R).
fn vsop_series(tables: &[&[[f64; 3]]], jme: f64) -> f64 {
    let mut sum = 0.0;
    let mut power = 1.0;
    for t in tables {
        sum += periodic_sum(t, jme) * power;
        power *= jme;
    }
    sum / 1e8
}

/// Sun position by the NREL Solar Position Algorithm (Reda & Andreas 2004, §3.1–3.15), for a UTC
/// instant, an observer, ΔT = TT − UT in seconds (|ΔT| ≤ 8000 s; see [`delta_t_estimate_s`]) and
/// optional refraction conditions (`None`: apparent = geometric).
///
/// Accuracy ±0.0003° for years −2000…6000 (the reference). At the poles the azimuth is a
/// coordinate singularity: it is the limit along the observer's meridian.
pub fn solar_position(
    time: &UtcDateTime,
    observer: &Observer,
    delta_t_s: f64,
    refraction: Option<&Refraction>,
) -> Result<SolarPosition, SunError> {
    UtcDateTime::new(
        time.year,
        time.month,
        time.day,
        time.hour,
        time.minute,
        time.second,
    )?;
    observer.validate()?;
    if !(delta_t_s.is_finite() && delta_t_s.abs() <= 8000.0) {
        return Err(SunError::InvalidInput {
            field: "delta_t_s",
            value: delta_t_s,
            reason: "must be within [-8000, 8000] s",
        });
    }
    if let Some(r) = refraction {
        r.validate()?;
    }
    use spa_tables::*;
    let lat = observer.latitude_deg;
    let lon = observer.longitude_deg;
    // 3.1 Time scales.
    let jd = time.julian_day();
    let jde = jd + delta_t_s / 86400.0;
    let jc = (jd - 2_451_545.0) / 36525.0;
    let jce = (jde - 2_451_545.0) / 36525.0;
    let jme = jce / 10.0;
    // 3.2 Heliocentric longitude, latitude (degrees) and radius vector (AU).
    let l_deg = wrap_360(vsop_series(&[&L0, &L1, &L2, &L3, &L4, &L5], jme).to_degrees());
    let b_deg = vsop_series(&[&B0, &B1], jme).to_degrees();
    let r_au = vsop_series(&[&R0, &R1, &R2, &R3, &R4], jme);
    // 3.3 Geocentric longitude and latitude.
    let theta = wrap_360(l_deg + 180.0);
    let beta = -b_deg;
    // 3.4 Nutation in longitude and obliquity (degrees).
    let x = [
        297.85036 + 445_267.111_480 * jce - 0.001_914_2 * jce * jce + jce.powi(3) / 189_474.0,
        357.52772 + 35_999.050_340 * jce - 0.000_160_3 * jce * jce - jce.powi(3) / 300_000.0,
        134.96298 + 477_198.867_398 * jce + 0.008_697_2 * jce * jce + jce.powi(3) / 56_250.0,
        93.27191 + 483_202.017_538 * jce - 0.003_682_5 * jce * jce + jce.powi(3) / 327_270.0,
        125.04452 - 1_934.136_261 * jce + 0.002_070_8 * jce * jce + jce.powi(3) / 450_000.0,
    ];
    let mut dpsi = 0.0;
    let mut deps = 0.0;
    for (y, abcd) in NUTATION_Y.iter().zip(NUTATION_ABCD.iter()) {
        let arg = (0..5).map(|k| y[k] * x[k]).sum::<f64>().to_radians();
        dpsi += (abcd[0] + abcd[1] * jce) * arg.sin();
        deps += (abcd[2] + abcd[3] * jce) * arg.cos();
    }
    dpsi /= 36_000_000.0;
    deps /= 36_000_000.0;
    // 3.5 True obliquity of the ecliptic (degrees).
    let u = jme / 10.0;
    let eps0 = 84381.448 - 4680.93 * u - 1.55 * u.powi(2) + 1999.25 * u.powi(3)
        - 51.38 * u.powi(4)
        - 249.67 * u.powi(5)
        - 39.05 * u.powi(6)
        + 7.12 * u.powi(7)
        + 27.87 * u.powi(8)
        + 5.79 * u.powi(9)
        + 2.45 * u.powi(10);
    let eps = eps0 / 3600.0 + deps;
    // 3.6–3.7 Aberration and apparent sun longitude.
    let dtau = -20.4898 / (3600.0 * r_au);
    let lambda = theta + dpsi + dtau;
    // 3.8 Apparent sidereal time at Greenwich.
    let nu0 = wrap_360(
        280.460_618_37 + 360.985_647_366_29 * (jd - 2_451_545.0) + 0.000_387_933 * jc * jc
            - jc.powi(3) / 38_710_000.0,
    );
    let nu = nu0 + dpsi * eps.to_radians().cos();
    // 3.9–3.10 Geocentric right ascension and declination.
    let (lr, er, br) = (lambda.to_radians(), eps.to_radians(), beta.to_radians());
    let alpha = wrap_360(
        (lr.sin() * er.cos() - br.tan() * er.sin())
            .atan2(lr.cos())
            .to_degrees(),
    );
    let delta = (br.sin() * er.cos() + br.cos() * er.sin() * lr.sin())
        .clamp(-1.0, 1.0)
        .asin()
        .to_degrees();
    // 3.11 Observer local hour angle.
    let h = wrap_360(nu + lon - alpha);
    // 3.12 Topocentric right ascension and declination (parallax).
    let xi = (8.794 / (3600.0 * r_au)).to_radians();
    let phi = lat.to_radians();
    let uu = (0.996_647_19 * phi.tan()).atan();
    let xx = uu.cos() + observer.altitude_m / 6_378_140.0 * phi.cos();
    let yy = 0.996_647_19 * uu.sin() + observer.altitude_m / 6_378_140.0 * phi.sin();
    let (hr, dr) = (h.to_radians(), delta.to_radians());
    let dalpha = (-xx * xi.sin() * hr.sin()).atan2(dr.cos() - xx * xi.sin() * hr.cos());
    let delta_prime =
        ((dr.sin() - yy * xi.sin()) * dalpha.cos()).atan2(dr.cos() - xx * xi.sin() * hr.cos());
    // 3.13 Topocentric local hour angle.
    let h_prime = hr - dalpha;
    // 3.14 Topocentric elevation and zenith angles.
    let e0 = (phi.sin() * delta_prime.sin() + phi.cos() * delta_prime.cos() * h_prime.cos())
        .clamp(-1.0, 1.0)
        .asin()
        .to_degrees();
    let refraction_deg = match refraction {
        Some(r) if e0 >= -(SUN_RADIUS_DEG + r.atmos_refract_deg) => {
            (r.pressure_hpa / 1010.0) * (283.0 / (273.0 + r.temperature_c)) * 1.02
                / (60.0 * (e0 + 10.3 / (e0 + 5.11)).to_radians().tan())
        }
        _ => 0.0,
    };
    let e = e0 + refraction_deg;
    // 3.15 Topocentric azimuth (astronomers' from south, then from north).
    let gamma = h_prime
        .sin()
        .atan2(h_prime.cos() * phi.sin() - delta_prime.tan() * phi.cos())
        .to_degrees();
    let azimuth = wrap_360(gamma + 180.0);
    // Equation of time (Reda & Andreas 2004, A.1).
    let m =
        280.466_456_7 + 360_007.698_277_9 * jme + 0.030_320_28 * jme * jme + jme.powi(3) / 49_931.0
            - jme.powi(4) / 15_300.0
            - jme.powi(5) / 2_000_000.0;
    let mut eot = 4.0 * wrap_360(m - 0.005_718_3 - alpha + dpsi * eps.to_radians().cos());
    if eot > 20.0 {
        eot -= 1440.0;
    }
    Ok(SolarPosition {
        zenith_deg: 90.0 - e0,
        apparent_zenith_deg: 90.0 - e,
        elevation_deg: e0,
        apparent_elevation_deg: e,
        refraction_deg,
        azimuth_from_north_deg: azimuth,
        equation_of_time_min: eot,
        earth_sun_distance_au: r_au,
        declination_deg: delta,
        topocentric_declination_deg: delta_prime.to_degrees(),
        right_ascension_deg: alpha,
        hour_angle_deg: h_prime.to_degrees().rem_euclid(360.0),
        julian_day: jd,
    })
}

/// Shape of the Earth for satellite view geometry.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum EarthShape {
    /// A sphere of the given radius (km); the local vertical is radial (physics.md §12.2).
    Sphere {
        /// Radius, km (e.g. [`MEAN_EARTH_RADIUS_KM`]).
        radius_km: f64,
    },
    /// The WGS-84 ellipsoid; latitude is geodetic and the local vertical is the ellipsoid normal.
    Wgs84,
}

/// A geostationary satellite: above the equator at a fixed longitude.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeostationarySatellite {
    /// Sub-satellite longitude, degrees east.
    pub sub_satellite_longitude_deg: f64,
    /// Altitude above the equator (WGS-84 equatorial radius), km (default
    /// [`GEOSTATIONARY_ALTITUDE_KM`]; the DART paper's example uses 36000 km).
    pub altitude_km: f64,
}

impl GeostationarySatellite {
    /// A satellite at the standard geostationary altitude above `sub_satellite_longitude_deg`.
    pub fn new(sub_satellite_longitude_deg: f64) -> GeostationarySatellite {
        GeostationarySatellite {
            sub_satellite_longitude_deg,
            altitude_km: GEOSTATIONARY_ALTITUDE_KM,
        }
    }

    /// Distance from the Earth's centre, km: WGS-84 equatorial radius + altitude.
    pub fn orbit_radius_km(&self) -> f64 {
        WGS84_A_KM + self.altitude_km
    }
}

/// Direction from a ground point to a satellite (viewing angles, ground → sensor).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SatelliteView {
    /// View zenith angle from the local vertical, degrees (> 90° when below the horizon).
    pub zenith_deg: f64,
    /// Azimuth of the direction to the satellite from north, clockwise, degrees in [0, 360).
    pub azimuth_from_north_deg: f64,
    /// Slant range, km.
    pub range_km: f64,
    /// Whether the satellite is above the local horizon.
    pub visible: bool,
}

impl SatelliteView {
    /// View angles in the scene convention for a scene whose +x axis has compass bearing
    /// `scene_x_bearing_deg`.
    pub fn scene_angles(&self, scene_x_bearing_deg: f64) -> SceneAngles {
        SceneAngles {
            zenith_deg: self.zenith_deg,
            azimuth_deg: compass_to_scene_azimuth_deg(
                self.azimuth_from_north_deg,
                scene_x_bearing_deg,
            ),
        }
    }
}

/// View zenith and azimuth of a geostationary satellite from a ground point (physics.md §12.2):
/// P = ground point, S = r_g (cos λ_s, sin λ_s, 0) in Earth-centred coordinates, d = (S − P)/|S − P|,
/// θ_v = arccos(d · up), azimuth = atan2(d · east, d · north), with the local vertical `up`
/// radial (sphere) or the ellipsoid normal (WGS-84, geodetic → ECEF; e.g. Hofmann-Wellenhof et al.
/// 2008, *GNSS*, eq. 2.9).
pub fn geostationary_view(
    observer: &Observer,
    satellite: &GeostationarySatellite,
    earth: EarthShape,
) -> Result<SatelliteView, SunError> {
    observer.validate()?;
    let s_lon = satellite.sub_satellite_longitude_deg;
    if !(s_lon.is_finite() && s_lon.abs() <= 360.0) {
        return Err(SunError::InvalidInput {
            field: "sub_satellite_longitude_deg",
            value: s_lon,
            reason: "must be a finite longitude in degrees east",
        });
    }
    if !(satellite.altitude_km.is_finite() && satellite.altitude_km > 0.0) {
        return Err(SunError::InvalidInput {
            field: "altitude_km",
            value: satellite.altitude_km,
            reason: "the satellite altitude must be positive",
        });
    }
    let (phi, lam) = (
        observer.latitude_deg.to_radians(),
        observer.longitude_deg.to_radians(),
    );
    let h_km = observer.altitude_m / 1000.0;
    let up = [phi.cos() * lam.cos(), phi.cos() * lam.sin(), phi.sin()];
    let p = match earth {
        EarthShape::Sphere { radius_km } => {
            if !(radius_km.is_finite() && radius_km > 0.0) {
                return Err(SunError::InvalidInput {
                    field: "radius_km",
                    value: radius_km,
                    reason: "the Earth radius must be positive",
                });
            }
            let r = radius_km + h_km;
            [r * up[0], r * up[1], r * up[2]]
        }
        EarthShape::Wgs84 => {
            let e2 = WGS84_F * (2.0 - WGS84_F);
            let n = WGS84_A_KM / (1.0 - e2 * phi.sin().powi(2)).sqrt();
            [
                (n + h_km) * phi.cos() * lam.cos(),
                (n + h_km) * phi.cos() * lam.sin(),
                (n * (1.0 - e2) + h_km) * phi.sin(),
            ]
        }
    };
    let rg = satellite.orbit_radius_km();
    let sl = s_lon.to_radians();
    let s = [rg * sl.cos(), rg * sl.sin(), 0.0];
    let v = [s[0] - p[0], s[1] - p[1], s[2] - p[2]];
    let range = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let d = [v[0] / range, v[1] / range, v[2] / range];
    let east = [-lam.sin(), lam.cos(), 0.0];
    let north = [-phi.sin() * lam.cos(), -phi.sin() * lam.sin(), phi.cos()];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cos_z = dot(d, up).clamp(-1.0, 1.0);
    Ok(SatelliteView {
        zenith_deg: cos_z.acos().to_degrees(),
        azimuth_from_north_deg: wrap_360(dot(d, east).atan2(dot(d, north)).to_degrees()),
        range_km: range,
        visible: cos_z > 0.0,
    })
}

/// Periodic terms of SPA: Earth heliocentric longitude L0–L5, latitude B0–B1 and radius R0–R4
/// (Reda & Andreas 2004, Table A4.2; columns A, B, C of A cos(B + C·JME)), and the nutation
/// coefficients (Table A4.3: Y0–Y4 multipliers of X0–X4, and a, b, c, d).
#[rustfmt::skip]
#[allow(clippy::approx_constant)] // 3.14 and 3.142 are SPA table entries, not π
mod spa_tables {
    pub const L0: [[f64; 3]; 64] = [
        [175347046.0, 0.0, 0.0],
        [3341656.0, 4.6692568, 6283.07585],
        [34894.0, 4.6261, 12566.1517],
        [3497.0, 2.7441, 5753.3849],
        [3418.0, 2.8289, 3.5231],
        [3136.0, 3.6277, 77713.7715],
        [2676.0, 4.4181, 7860.4194],
        [2343.0, 6.1352, 3930.2097],
        [1324.0, 0.7425, 11506.7698],
        [1273.0, 2.0371, 529.691],
        [1199.0, 1.1096, 1577.3435],
        [990.0, 5.233, 5884.927],
        [902.0, 2.045, 26.298],
        [857.0, 3.508, 398.149],
        [780.0, 1.179, 5223.694],
        [753.0, 2.533, 5507.553],
        [505.0, 4.583, 18849.228],
        [492.0, 4.205, 775.523],
        [357.0, 2.92, 0.067],
        [317.0, 5.849, 11790.629],
        [284.0, 1.899, 796.298],
        [271.0, 0.315, 10977.079],
        [243.0, 0.345, 5486.778],
        [206.0, 4.806, 2544.314],
        [205.0, 1.869, 5573.143],
        [202.0, 2.458, 6069.777],
        [156.0, 0.833, 213.299],
        [132.0, 3.411, 2942.463],
        [126.0, 1.083, 20.775],
        [115.0, 0.645, 0.98],
        [103.0, 0.636, 4694.003],
        [102.0, 0.976, 15720.839],
        [102.0, 4.267, 7.114],
        [99.0, 6.21, 2146.17],
        [98.0, 0.68, 155.42],
        [86.0, 5.98, 161000.69],
        [85.0, 1.3, 6275.96],
        [85.0, 3.67, 71430.7],
        [80.0, 1.81, 17260.15],
        [79.0, 3.04, 12036.46],
        [75.0, 1.76, 5088.63],
        [74.0, 3.5, 3154.69],
        [74.0, 4.68, 801.82],
        [70.0, 0.83, 9437.76],
        [62.0, 3.98, 8827.39],
        [61.0, 1.82, 7084.9],
        [57.0, 2.78, 6286.6],
        [56.0, 4.39, 14143.5],
        [56.0, 3.47, 6279.55],
        [52.0, 0.19, 12139.55],
        [52.0, 1.33, 1748.02],
        [51.0, 0.28, 5856.48],
        [49.0, 0.49, 1194.45],
        [41.0, 5.37, 8429.24],
        [41.0, 2.4, 19651.05],
        [39.0, 6.17, 10447.39],
        [37.0, 6.04, 10213.29],
        [37.0, 2.57, 1059.38],
        [36.0, 1.71, 2352.87],
        [36.0, 1.78, 6812.77],
        [33.0, 0.59, 17789.85],
        [30.0, 0.44, 83996.85],
        [30.0, 2.74, 1349.87],
        [25.0, 3.16, 4690.48],
    ];
    pub const L1: [[f64; 3]; 34] = [
        [628331966747.0, 0.0, 0.0],
        [206059.0, 2.678235, 6283.07585],
        [4303.0, 2.6351, 12566.1517],
        [425.0, 1.59, 3.523],
        [119.0, 5.796, 26.298],
        [109.0, 2.966, 1577.344],
        [93.0, 2.59, 18849.23],
        [72.0, 1.14, 529.69],
        [68.0, 1.87, 398.15],
        [67.0, 4.41, 5507.55],
        [59.0, 2.89, 5223.69],
        [56.0, 2.17, 155.42],
        [45.0, 0.4, 796.3],
        [36.0, 0.47, 775.52],
        [29.0, 2.65, 7.11],
        [21.0, 5.34, 0.98],
        [19.0, 1.85, 5486.78],
        [19.0, 4.97, 213.3],
        [17.0, 2.99, 6275.96],
        [16.0, 0.03, 2544.31],
        [16.0, 1.43, 2146.17],
        [15.0, 1.21, 10977.08],
        [12.0, 2.83, 1748.02],
        [12.0, 3.26, 5088.63],
        [12.0, 5.27, 1194.45],
        [12.0, 2.08, 4694.0],
        [11.0, 0.77, 553.57],
        [10.0, 1.3, 6286.6],
        [10.0, 4.24, 1349.87],
        [9.0, 2.7, 242.73],
        [9.0, 5.64, 951.72],
        [8.0, 5.3, 2352.87],
        [6.0, 2.65, 9437.76],
        [6.0, 4.67, 4690.48],
    ];
    pub const L2: [[f64; 3]; 20] = [
        [52919.0, 0.0, 0.0],
        [8720.0, 1.0721, 6283.0758],
        [309.0, 0.867, 12566.152],
        [27.0, 0.05, 3.52],
        [16.0, 5.19, 26.3],
        [16.0, 3.68, 155.42],
        [10.0, 0.76, 18849.23],
        [9.0, 2.06, 77713.77],
        [7.0, 0.83, 775.52],
        [5.0, 4.66, 1577.34],
        [4.0, 1.03, 7.11],
        [4.0, 3.44, 5573.14],
        [3.0, 5.14, 796.3],
        [3.0, 6.05, 5507.55],
        [3.0, 1.19, 242.73],
        [3.0, 6.12, 529.69],
        [3.0, 0.31, 398.15],
        [3.0, 2.28, 553.57],
        [2.0, 4.38, 5223.69],
        [2.0, 3.75, 0.98],
    ];
    pub const L3: [[f64; 3]; 7] = [
        [289.0, 5.844, 6283.076],
        [35.0, 0.0, 0.0],
        [17.0, 5.49, 12566.15],
        [3.0, 5.2, 155.42],
        [1.0, 4.72, 3.52],
        [1.0, 5.3, 18849.23],
        [1.0, 5.97, 242.73],
    ];
    pub const L4: [[f64; 3]; 3] = [
        [114.0, 3.142, 0.0],
        [8.0, 4.13, 6283.08],
        [1.0, 3.84, 12566.15],
    ];
    pub const L5: [[f64; 3]; 1] = [
        [1.0, 3.14, 0.0],
    ];
    pub const B0: [[f64; 3]; 5] = [
        [280.0, 3.199, 84334.662],
        [102.0, 5.422, 5507.553],
        [80.0, 3.88, 5223.69],
        [44.0, 3.7, 2352.87],
        [32.0, 4.0, 1577.34],
    ];
    pub const B1: [[f64; 3]; 2] = [
        [9.0, 3.9, 5507.55],
        [6.0, 1.73, 5223.69],
    ];
    pub const R0: [[f64; 3]; 40] = [
        [100013989.0, 0.0, 0.0],
        [1670700.0, 3.0984635, 6283.07585],
        [13956.0, 3.05525, 12566.1517],
        [3084.0, 5.1985, 77713.7715],
        [1628.0, 1.1739, 5753.3849],
        [1576.0, 2.8469, 7860.4194],
        [925.0, 5.453, 11506.77],
        [542.0, 4.564, 3930.21],
        [472.0, 3.661, 5884.927],
        [346.0, 0.964, 5507.553],
        [329.0, 5.9, 5223.694],
        [307.0, 0.299, 5573.143],
        [243.0, 4.273, 11790.629],
        [212.0, 5.847, 1577.344],
        [186.0, 5.022, 10977.079],
        [175.0, 3.012, 18849.228],
        [110.0, 5.055, 5486.778],
        [98.0, 0.89, 6069.78],
        [86.0, 5.69, 15720.84],
        [86.0, 1.27, 161000.69],
        [65.0, 0.27, 17260.15],
        [63.0, 0.92, 529.69],
        [57.0, 2.01, 83996.85],
        [56.0, 5.24, 71430.7],
        [49.0, 3.25, 2544.31],
        [47.0, 2.58, 775.52],
        [45.0, 5.54, 9437.76],
        [43.0, 6.01, 6275.96],
        [39.0, 5.36, 4694.0],
        [38.0, 2.39, 8827.39],
        [37.0, 0.83, 19651.05],
        [37.0, 4.9, 12139.55],
        [36.0, 1.67, 12036.46],
        [35.0, 1.84, 2942.46],
        [33.0, 0.24, 7084.9],
        [32.0, 0.18, 5088.63],
        [32.0, 1.78, 398.15],
        [28.0, 1.21, 6286.6],
        [28.0, 1.9, 6279.55],
        [26.0, 4.59, 10447.39],
    ];
    pub const R1: [[f64; 3]; 10] = [
        [103019.0, 1.10749, 6283.07585],
        [1721.0, 1.0644, 12566.1517],
        [702.0, 3.142, 0.0],
        [32.0, 1.02, 18849.23],
        [31.0, 2.84, 5507.55],
        [25.0, 1.32, 5223.69],
        [18.0, 1.42, 1577.34],
        [10.0, 5.91, 10977.08],
        [9.0, 1.42, 6275.96],
        [9.0, 0.27, 5486.78],
    ];
    pub const R2: [[f64; 3]; 6] = [
        [4359.0, 5.7846, 6283.0758],
        [124.0, 5.579, 12566.152],
        [12.0, 3.14, 0.0],
        [9.0, 3.63, 77713.77],
        [6.0, 1.87, 5573.14],
        [3.0, 5.47, 18849.23],
    ];
    pub const R3: [[f64; 3]; 2] = [
        [145.0, 4.273, 6283.076],
        [7.0, 3.92, 12566.15],
    ];
    pub const R4: [[f64; 3]; 1] = [
        [4.0, 2.56, 6283.08],
    ];
    pub const NUTATION_ABCD: [[f64; 4]; 63] = [
        [-171996.0, -174.2, 92025.0, 8.9],
        [-13187.0, -1.6, 5736.0, -3.1],
        [-2274.0, -0.2, 977.0, -0.5],
        [2062.0, 0.2, -895.0, 0.5],
        [1426.0, -3.4, 54.0, -0.1],
        [712.0, 0.1, -7.0, 0.0],
        [-517.0, 1.2, 224.0, -0.6],
        [-386.0, -0.4, 200.0, 0.0],
        [-301.0, 0.0, 129.0, -0.1],
        [217.0, -0.5, -95.0, 0.3],
        [-158.0, 0.0, 0.0, 0.0],
        [129.0, 0.1, -70.0, 0.0],
        [123.0, 0.0, -53.0, 0.0],
        [63.0, 0.0, 0.0, 0.0],
        [63.0, 0.1, -33.0, 0.0],
        [-59.0, 0.0, 26.0, 0.0],
        [-58.0, -0.1, 32.0, 0.0],
        [-51.0, 0.0, 27.0, 0.0],
        [48.0, 0.0, 0.0, 0.0],
        [46.0, 0.0, -24.0, 0.0],
        [-38.0, 0.0, 16.0, 0.0],
        [-31.0, 0.0, 13.0, 0.0],
        [29.0, 0.0, 0.0, 0.0],
        [29.0, 0.0, -12.0, 0.0],
        [26.0, 0.0, 0.0, 0.0],
        [-22.0, 0.0, 0.0, 0.0],
        [21.0, 0.0, -10.0, 0.0],
        [17.0, -0.1, 0.0, 0.0],
        [16.0, 0.0, -8.0, 0.0],
        [-16.0, 0.1, 7.0, 0.0],
        [-15.0, 0.0, 9.0, 0.0],
        [-13.0, 0.0, 7.0, 0.0],
        [-12.0, 0.0, 6.0, 0.0],
        [11.0, 0.0, 0.0, 0.0],
        [-10.0, 0.0, 5.0, 0.0],
        [-8.0, 0.0, 3.0, 0.0],
        [7.0, 0.0, -3.0, 0.0],
        [-7.0, 0.0, 0.0, 0.0],
        [-7.0, 0.0, 3.0, 0.0],
        [-7.0, 0.0, 3.0, 0.0],
        [6.0, 0.0, 0.0, 0.0],
        [6.0, 0.0, -3.0, 0.0],
        [6.0, 0.0, -3.0, 0.0],
        [-6.0, 0.0, 3.0, 0.0],
        [-6.0, 0.0, 3.0, 0.0],
        [5.0, 0.0, 0.0, 0.0],
        [-5.0, 0.0, 3.0, 0.0],
        [-5.0, 0.0, 3.0, 0.0],
        [-5.0, 0.0, 3.0, 0.0],
        [4.0, 0.0, 0.0, 0.0],
        [4.0, 0.0, 0.0, 0.0],
        [4.0, 0.0, 0.0, 0.0],
        [-4.0, 0.0, 0.0, 0.0],
        [-4.0, 0.0, 0.0, 0.0],
        [-4.0, 0.0, 0.0, 0.0],
        [3.0, 0.0, 0.0, 0.0],
        [-3.0, 0.0, 0.0, 0.0],
        [-3.0, 0.0, 0.0, 0.0],
        [-3.0, 0.0, 0.0, 0.0],
        [-3.0, 0.0, 0.0, 0.0],
        [-3.0, 0.0, 0.0, 0.0],
        [-3.0, 0.0, 0.0, 0.0],
        [-3.0, 0.0, 0.0, 0.0],
    ];
    pub const NUTATION_Y: [[f64; 5]; 63] = [
        [0.0, 0.0, 0.0, 0.0, 1.0],
        [-2.0, 0.0, 0.0, 2.0, 2.0],
        [0.0, 0.0, 0.0, 2.0, 2.0],
        [0.0, 0.0, 0.0, 0.0, 2.0],
        [0.0, 1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0, 0.0],
        [-2.0, 1.0, 0.0, 2.0, 2.0],
        [0.0, 0.0, 0.0, 2.0, 1.0],
        [0.0, 0.0, 1.0, 2.0, 2.0],
        [-2.0, -1.0, 0.0, 2.0, 2.0],
        [-2.0, 0.0, 1.0, 0.0, 0.0],
        [-2.0, 0.0, 0.0, 2.0, 1.0],
        [0.0, 0.0, -1.0, 2.0, 2.0],
        [2.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0, 1.0],
        [2.0, 0.0, -1.0, 2.0, 2.0],
        [0.0, 0.0, -1.0, 0.0, 1.0],
        [0.0, 0.0, 1.0, 2.0, 1.0],
        [-2.0, 0.0, 2.0, 0.0, 0.0],
        [0.0, 0.0, -2.0, 2.0, 1.0],
        [2.0, 0.0, 0.0, 2.0, 2.0],
        [0.0, 0.0, 2.0, 2.0, 2.0],
        [0.0, 0.0, 2.0, 0.0, 0.0],
        [-2.0, 0.0, 1.0, 2.0, 2.0],
        [0.0, 0.0, 0.0, 2.0, 0.0],
        [-2.0, 0.0, 0.0, 2.0, 0.0],
        [0.0, 0.0, -1.0, 2.0, 1.0],
        [0.0, 2.0, 0.0, 0.0, 0.0],
        [2.0, 0.0, -1.0, 0.0, 1.0],
        [-2.0, 2.0, 0.0, 2.0, 2.0],
        [0.0, 1.0, 0.0, 0.0, 1.0],
        [-2.0, 0.0, 1.0, 0.0, 1.0],
        [0.0, -1.0, 0.0, 0.0, 1.0],
        [0.0, 0.0, 2.0, -2.0, 0.0],
        [2.0, 0.0, -1.0, 2.0, 1.0],
        [2.0, 0.0, 1.0, 2.0, 2.0],
        [0.0, 1.0, 0.0, 2.0, 2.0],
        [-2.0, 1.0, 1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0, 2.0, 2.0],
        [2.0, 0.0, 0.0, 2.0, 1.0],
        [2.0, 0.0, 1.0, 0.0, 0.0],
        [-2.0, 0.0, 2.0, 2.0, 2.0],
        [-2.0, 0.0, 1.0, 2.0, 1.0],
        [2.0, 0.0, -2.0, 0.0, 1.0],
        [2.0, 0.0, 0.0, 0.0, 1.0],
        [0.0, -1.0, 1.0, 0.0, 0.0],
        [-2.0, -1.0, 0.0, 2.0, 1.0],
        [-2.0, 0.0, 0.0, 0.0, 1.0],
        [0.0, 0.0, 2.0, 2.0, 1.0],
        [-2.0, 0.0, 2.0, 0.0, 1.0],
        [-2.0, 1.0, 0.0, 2.0, 1.0],
        [0.0, 0.0, 1.0, -2.0, 0.0],
        [-1.0, 0.0, 1.0, 0.0, 0.0],
        [-2.0, 1.0, 0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 2.0, 0.0],
        [0.0, 0.0, -2.0, 2.0, 2.0],
        [-1.0, -1.0, 1.0, 0.0, 0.0],
        [0.0, 1.0, 1.0, 0.0, 0.0],
        [0.0, -1.0, 1.0, 2.0, 2.0],
        [2.0, -1.0, -1.0, 2.0, 2.0],
        [0.0, 0.0, 3.0, 2.0, 2.0],
        [2.0, -1.0, 0.0, 2.0, 2.0],
    ];
}

#[cfg(test)]
mod tests;
