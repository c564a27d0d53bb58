//! Unit tests of the solar position (NREL SPA) and the sun-related helpers.

use super::*;

fn t(s: &str) -> UtcDateTime {
    UtcDateTime::parse(s).unwrap()
}

#[test]
fn parses_iso_and_space_forms() {
    let a = t("2003-10-17T19:30:30");
    assert_eq!(
        (a.year, a.month, a.day, a.hour, a.minute),
        (2003, 10, 17, 19, 30)
    );
    assert_eq!(a.second, 30.0);
    assert_eq!(t("2003-10-17 19:30:30"), a);
    assert_eq!(t(" 2003-10-17T19:30:30Z "), a);
    assert_eq!(t("2003-10-17T19:30").second, 0.0);
    assert_eq!(t("2024-02-29T00:00:00.25").second, 0.25);
    assert_eq!(a.to_string(), "2003-10-17T19:30:30");
    assert_eq!(
        t("2024-02-29T00:00:00.25").to_string(),
        "2024-02-29T00:00:00.25"
    );
    assert_eq!("2003-10-17T19:30:30".parse::<UtcDateTime>().unwrap(), a);
}

#[test]
fn rejects_bad_date_times_with_reasons() {
    let cases = [
        ("2003-13-01T00:00:00", "month 13"),
        ("2023-02-29T00:00:00", "day 29"),
        ("2003-10-17", "expected"),
        ("2003-10-17T24:00:00", "hour 24"),
        ("2003-10-17T19:60:00", "minute 60"),
        ("2003-10-17T19:30:60", "second 60"),
        ("2003-10-17T19:30:30+02:00", "offsets"),
        ("03-10-17T19:30:30", "YYYY-MM-DD"),
        ("2003-1x-17T19:30:30", "month `1x`"),
        ("2003-10-17T1:30:30", "HH:MM"),
        ("", "expected"),
    ];
    for (input, needle) in cases {
        let e = UtcDateTime::parse(input).unwrap_err().to_string();
        assert!(e.contains(needle), "{input}: {e}");
    }
}

#[test]
fn julian_days_match_meeus_examples() {
    // Meeus (1998), Astronomical Algorithms, ch. 7 examples, and the SPA report (A.5).
    let cases = [
        (
            UtcDateTime::new(2000, 1, 1, 12, 0, 0.0).unwrap(),
            2_451_545.0,
        ),
        (
            UtcDateTime::new(1987, 1, 27, 0, 0, 0.0).unwrap(),
            2_446_822.5,
        ),
        (
            UtcDateTime::new(1988, 6, 19, 12, 0, 0.0).unwrap(),
            2_447_332.0,
        ),
        (
            UtcDateTime::new(1600, 12, 31, 0, 0, 0.0).unwrap(),
            2_305_812.5,
        ),
        (
            UtcDateTime::new(837, 4, 10, 7, 12, 0.0).unwrap(),
            2_026_871.8,
        ),
        (
            UtcDateTime::new(-1001, 8, 17, 21, 36, 0.0).unwrap(),
            1_355_671.4,
        ),
        (t("2003-10-17T19:30:30"), 2_452_930.312_847),
    ];
    for (time, jd) in cases {
        assert!(
            (time.julian_day() - jd).abs() < 1e-6,
            "{time}: {} vs {jd}",
            time.julian_day()
        );
    }
    assert_eq!(t("2024-03-01T00:00:00").day_of_year(), 61);
    assert_eq!(t("2023-12-31T00:00:00").day_of_year(), 365);
}

#[test]
fn scene_azimuth_convention() {
    // +x east (default): north → +y (90°), east → +x (0°), south → 270°, west → 180°.
    for (gamma, phi) in [(0.0, 90.0), (90.0, 0.0), (180.0, 270.0), (270.0, 180.0)] {
        assert!(
            (compass_to_scene_azimuth_deg(gamma, DEFAULT_SCENE_X_BEARING_DEG) - phi).abs() < 1e-12
        );
    }
    // Check against explicit vectors for arbitrary orientations: scene axes in (east, north)
    // are x = (sin β, cos β) and y = z × x = (−cos β, sin β).
    for beta in [0.0, 33.0, 90.0, 200.0, 359.0] {
        for gamma in [0.0, 10.0, 135.0, 194.34, 300.0] {
            let (b, g) = (f64::to_radians(beta), f64::to_radians(gamma));
            let d = [g.sin(), g.cos()];
            let x = [b.sin(), b.cos()];
            let y = [-b.cos(), b.sin()];
            let phi_vec = (d[0] * y[0] + d[1] * y[1])
                .atan2(d[0] * x[0] + d[1] * x[1])
                .to_degrees()
                .rem_euclid(360.0);
            let phi = compass_to_scene_azimuth_deg(gamma, beta);
            let diff = (phi - phi_vec + 540.0).rem_euclid(360.0) - 180.0;
            assert!(
                diff.abs() < 1e-9,
                "beta {beta} gamma {gamma}: {phi} vs {phi_vec}"
            );
            let back = scene_to_compass_azimuth_deg(phi, beta);
            assert!(((back - gamma + 540.0).rem_euclid(360.0) - 180.0).abs() < 1e-9);
            assert!((0.0..360.0).contains(&phi));
        }
    }
    assert_eq!(compass_to_scene_azimuth_deg(90.0 + 1e-17, 90.0), 0.0);
}

#[test]
fn spa_is_finite_and_bounded_everywhere() {
    let refr = Refraction::standard();
    for lat in [-90.0, -66.6, -10.0, 0.0, 45.0, 89.9, 90.0] {
        for lon in [-180.0, -105.0, 0.0, 120.0, 180.0] {
            for hour in [0, 5, 11, 17, 23] {
                let time = UtcDateTime::new(2021, 12, 21, hour, 7, 13.5).unwrap();
                let obs = Observer {
                    latitude_deg: lat,
                    longitude_deg: lon,
                    altitude_m: 100.0,
                };
                let p = solar_position(&time, &obs, 69.0, Some(&refr)).unwrap();
                for v in [
                    p.zenith_deg,
                    p.apparent_zenith_deg,
                    p.azimuth_from_north_deg,
                    p.equation_of_time_min,
                ] {
                    assert!(v.is_finite(), "lat {lat} lon {lon} h {hour}: {p:?}");
                }
                assert!((0.0..=180.0).contains(&p.zenith_deg));
                assert!((0.0..360.0).contains(&p.azimuth_from_north_deg));
                assert!(p.apparent_zenith_deg <= p.zenith_deg);
                assert!(p.refraction_deg >= 0.0 && p.refraction_deg < 0.6);
                // At the December solstice the sun is over the Tropic of Capricorn.
                assert!((p.declination_deg + 23.43).abs() < 0.02);
            }
        }
    }
}

#[test]
fn refraction_switches_off_below_the_horizon_and_is_continuous_above() {
    let refr = Refraction::standard();
    let obs = Observer {
        latitude_deg: 43.6047,
        longitude_deg: 1.4442,
        altitude_m: 146.0,
    };
    let mut prev: Option<SolarPosition> = None;
    // Sunrise in Toulouse, 15 Jan 2024, ≈ 07:30 UTC: step by 10 s.
    for k in 0..360 {
        let s = 7 * 3600 + 10 * 60 + k * 10;
        let time = UtcDateTime::new(2024, 1, 15, s / 3600, s / 60 % 60, (s % 60) as f64).unwrap();
        let p = solar_position(&time, &obs, 69.0, Some(&refr)).unwrap();
        if p.elevation_deg < -(SUN_RADIUS_DEG + SPA_ATMOS_REFRACT_DEG) {
            assert_eq!(p.apparent_zenith_deg, p.zenith_deg);
        } else {
            // Bennett-type refraction: ≈ 0.7° just below the horizon, decreasing with elevation.
            assert!(p.refraction_deg > 0.0 && p.refraction_deg < 0.8, "{p:?}");
            if let Some(prev) = prev {
                assert!(p.refraction_deg < prev.refraction_deg);
                // The apparent elevation rises smoothly (< 0.05° per 10 s near the horizon).
                let rise = p.apparent_elevation_deg - prev.apparent_elevation_deg;
                assert!(rise > 0.0 && rise < 0.05, "{rise}");
            }
            prev = Some(p);
        }
    }
    assert!(prev.is_some_and(|p| p.elevation_deg > 0.5));
    let none = solar_position(&t("2024-01-15T07:30:00"), &obs, 69.0, None).unwrap();
    assert_eq!(none.apparent_zenith_deg, none.zenith_deg);
    assert_eq!(none.refraction_deg, 0.0);
}

#[test]
fn equation_of_time_and_distance_over_a_year() {
    let obs = Observer {
        latitude_deg: 0.0,
        longitude_deg: 0.0,
        altitude_m: 0.0,
    };
    let (mut eot_min, mut eot_max) = (f64::MAX, f64::MIN);
    let (mut r_min, mut r_max) = (f64::MAX, f64::MIN);
    let mut worst_approx: f64 = 0.0;
    for doy in 1..=365u32 {
        // Day-of-year → month/day in 2023 (not a leap year).
        let mut m = 1;
        let mut d = doy;
        while d > days_in_month(2023, m) {
            d -= days_in_month(2023, m);
            m += 1;
        }
        let time = UtcDateTime::new(2023, m, d, 12, 0, 0.0).unwrap();
        assert_eq!(time.day_of_year(), doy);
        let p = solar_position(&time, &obs, 69.0, None).unwrap();
        eot_min = eot_min.min(p.equation_of_time_min);
        eot_max = eot_max.max(p.equation_of_time_min);
        r_min = r_min.min(p.earth_sun_distance_au);
        r_max = r_max.max(p.earth_sun_distance_au);
        worst_approx =
            worst_approx.max((earth_sun_distance_approx_au(doy) - p.earth_sun_distance_au).abs());
    }
    // EoT ranges from about −14.2 min (February) to +16.4 min (November); perihelion and
    // aphelion distances 0.9833 and 1.0167 AU.
    assert!(
        (eot_min + 14.2).abs() < 0.2 && (eot_max - 16.4).abs() < 0.2,
        "{eot_min} {eot_max}"
    );
    assert!(
        (r_min - 0.98329).abs() < 2e-4 && (r_max - 1.01671).abs() < 2e-4,
        "{r_min} {r_max}"
    );
    assert!(worst_approx < 5e-4, "{worst_approx}");
    assert!((irradiance_distance_factor(r_min) - 1.0 / (r_min * r_min)).abs() < 1e-15);
    assert!(irradiance_distance_factor(0.0).is_nan());
}

#[test]
fn delta_t_estimate_is_close_to_observed() {
    // Observed ΔT: 63.83 s on 2000-01-01, 32.18 s on 1960-01-01 (IERS; Espenak & Meeus table).
    assert!((delta_t_estimate_s(2000, 1) - 63.83).abs() < 0.5);
    assert!((delta_t_estimate_s(1960, 1) - 33.1).abs() < 1.0);
    for y in (-1999..=3000).step_by(7) {
        assert!(delta_t_estimate_s(y, 6).is_finite());
    }
}

#[test]
fn bad_inputs_are_errors_naming_the_field() {
    let time = t("2003-10-17T19:30:30");
    let ok = Observer {
        latitude_deg: 39.7,
        longitude_deg: -105.2,
        altitude_m: 1830.0,
    };
    let cases: [(&str, Observer, f64, Refraction); 6] = [
        (
            "latitude_deg",
            Observer {
                latitude_deg: 91.0,
                ..ok
            },
            67.0,
            Refraction::standard(),
        ),
        (
            "longitude_deg",
            Observer {
                longitude_deg: f64::NAN,
                ..ok
            },
            67.0,
            Refraction::standard(),
        ),
        (
            "altitude_m",
            Observer {
                altitude_m: f64::INFINITY,
                ..ok
            },
            67.0,
            Refraction::standard(),
        ),
        ("delta_t_s", ok, 1e5, Refraction::standard()),
        (
            "pressure_hpa",
            ok,
            67.0,
            Refraction {
                pressure_hpa: -1.0,
                ..Refraction::standard()
            },
        ),
        (
            "temperature_c",
            ok,
            67.0,
            Refraction {
                temperature_c: -300.0,
                ..Refraction::standard()
            },
        ),
    ];
    for (field, obs, dt, refr) in cases {
        let e = solar_position(&time, &obs, dt, Some(&refr))
            .unwrap_err()
            .to_string();
        assert!(e.contains(field), "{field}: {e}");
    }
    let bad_time = UtcDateTime {
        month: 2,
        day: 30,
        ..time
    };
    assert!(solar_position(&bad_time, &ok, 67.0, None).is_err());
}

#[test]
fn geostationary_view_checks() {
    // physics.md §12.2 checks (spherical Earth, R = 6371 km, r_g = 42164 km).
    let sphere = EarthShape::Sphere {
        radius_km: MEAN_EARTH_RADIUS_KM,
    };
    let cases = [
        ((45.0, 0.0), 0.0, 51.82, 180.0),
        ((25.5, 30.4), 17.0, 33.36, 208.96),
    ];
    for ((lat, lon), sat_lon, zenith, azimuth) in cases {
        let obs = Observer {
            latitude_deg: lat,
            longitude_deg: lon,
            altitude_m: 0.0,
        };
        let v = geostationary_view(&obs, &GeostationarySatellite::new(sat_lon), sphere).unwrap();
        // The checks are quoted to 0.01°: agree within half a unit of the last digit.
        assert!((v.zenith_deg - zenith).abs() < 0.005, "{v:?}");
        assert!((v.azimuth_from_north_deg - azimuth).abs() < 0.005, "{v:?}");
        assert!(v.visible);
        // WGS-84 differs from the sphere by less than 0.2° (the geodetic/geocentric latitude
        // difference is at most 0.19°).
        let w = geostationary_view(
            &obs,
            &GeostationarySatellite::new(sat_lon),
            EarthShape::Wgs84,
        )
        .unwrap();
        assert!((w.zenith_deg - v.zenith_deg).abs() < 0.2, "{w:?}");
    }
    // Directly below the satellite: at the zenith, range = altitude.
    let obs = Observer {
        latitude_deg: 0.0,
        longitude_deg: -75.0,
        altitude_m: 0.0,
    };
    let v =
        geostationary_view(&obs, &GeostationarySatellite::new(-75.0), EarthShape::Wgs84).unwrap();
    assert!(v.zenith_deg < 1e-9 && (v.range_km - GEOSTATIONARY_ALTITUDE_KM).abs() < 1e-6);
    // The far side of the Earth and the pole: not visible, no NaN.
    for (lat, lon) in [(0.0, 105.0), (90.0, 0.0), (-90.0, 0.0), (81.5, -75.0)] {
        let obs = Observer {
            latitude_deg: lat,
            longitude_deg: lon,
            altitude_m: 0.0,
        };
        let v = geostationary_view(&obs, &GeostationarySatellite::new(-75.0), EarthShape::Wgs84)
            .unwrap();
        assert!(v.zenith_deg.is_finite() && v.azimuth_from_north_deg.is_finite());
        assert!(!v.visible, "{lat} {lon}: {v:?}");
    }
    // Scene angles of the view: a satellite due south is at φ = 270° for +x east.
    let obs = Observer {
        latitude_deg: 45.0,
        longitude_deg: 0.0,
        altitude_m: 0.0,
    };
    let v = geostationary_view(&obs, &GeostationarySatellite::new(0.0), sphere).unwrap();
    assert!((v.scene_angles(90.0).azimuth_deg - 270.0).abs() < 1e-9);
    let bad = GeostationarySatellite {
        altitude_km: -1.0,
        ..GeostationarySatellite::new(0.0)
    };
    assert!(
        geostationary_view(&obs, &bad, sphere)
            .unwrap_err()
            .to_string()
            .contains("altitude_km")
    );
}
