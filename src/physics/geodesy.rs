//! Geodesy for placing a georeferenced scene on the Earth (issue #37): the inverse transverse
//! Mercator projection (UTM and other transverse Mercator grids with their origin latitude on
//! the equator) by Krüger's series to order n⁶ as given by Karney (2011), and the true bearing of
//! a map direction.
//!
//! Karney, C. F. F. (2011), "Transverse Mercator with an accuracy of a few nanometers",
//! *J. Geodesy* 85:475–485: eq. (14) (rectifying radius A), eq. (36) (the β coefficients of the
//! inverse series, here to n⁶), eqs. (11)–(12) (ξ′, η′ → τ′, λ) and eqs. (19)–(21) (Newton's
//! method for τ = tan φ from τ′). Accurate to well under 1 mm within a UTM zone (Karney 2011,
//! §4).

/// A transverse Mercator grid: ellipsoid (semi-major axis `a_m`, flattening `f`), central
/// meridian `lon0_deg`, scale on it `k0`, false easting and northing (m). The origin latitude is
/// the equator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransverseMercator {
    /// Semi-major axis, m.
    pub a_m: f64,
    /// Flattening.
    pub f: f64,
    /// Central meridian, degrees east.
    pub lon0_deg: f64,
    /// Scale factor on the central meridian.
    pub k0: f64,
    /// False easting, m.
    pub false_easting_m: f64,
    /// False northing, m.
    pub false_northing_m: f64,
}

/// WGS 84 ellipsoid (a, 1/f).
pub const WGS84: (f64, f64) = (6_378_137.0, 298.257_223_563);

impl TransverseMercator {
    /// The UTM zone `zone` (1..=60) of the northern (`south` false) or southern hemisphere on the
    /// ellipsoid (a, 1/f).
    pub fn utm(zone: u32, south: bool, ellipsoid: (f64, f64)) -> Self {
        Self {
            a_m: ellipsoid.0,
            f: 1.0 / ellipsoid.1,
            lon0_deg: 6.0 * zone as f64 - 183.0,
            k0: 0.9996,
            false_easting_m: 500_000.0,
            false_northing_m: if south { 10_000_000.0 } else { 0.0 },
        }
    }

    /// Geodetic latitude and longitude (degrees) of the grid point (easting, northing), m.
    pub fn inverse(&self, easting_m: f64, northing_m: f64) -> (f64, f64) {
        let n = self.f / (2.0 - self.f);
        let (n2, n3) = (n * n, n * n * n);
        let (n4, n5, n6) = (n2 * n2, n2 * n3, n3 * n3);
        // Karney (2011) eq. (14).
        let a_rect = self.a_m / (1.0 + n) * (1.0 + n2 / 4.0 + n4 / 64.0 + n6 / 256.0);
        // Karney (2011) eq. (36), β_1..β_6.
        let beta = [
            n / 2.0 - 2.0 * n2 / 3.0 + 37.0 * n3 / 96.0 - n4 / 360.0 - 81.0 * n5 / 512.0
                + 96199.0 * n6 / 604800.0,
            n2 / 48.0 + n3 / 15.0 - 437.0 * n4 / 1440.0 + 46.0 * n5 / 105.0
                - 1118711.0 * n6 / 3870720.0,
            17.0 * n3 / 480.0 - 37.0 * n4 / 840.0 - 209.0 * n5 / 4480.0 + 5569.0 * n6 / 90720.0,
            4397.0 * n4 / 161280.0 - 11.0 * n5 / 504.0 - 830251.0 * n6 / 7257600.0,
            4583.0 * n5 / 161280.0 - 108847.0 * n6 / 3991680.0,
            20648693.0 * n6 / 638668800.0,
        ];
        let xi = (northing_m - self.false_northing_m) / (self.k0 * a_rect);
        let eta = (easting_m - self.false_easting_m) / (self.k0 * a_rect);
        let (mut xi1, mut eta1) = (xi, eta);
        for (j, b) in beta.iter().enumerate() {
            let k = 2.0 * (j + 1) as f64;
            xi1 -= b * (k * xi).sin() * (k * eta).cosh();
            eta1 -= b * (k * xi).cos() * (k * eta).sinh();
        }
        let tau1 = xi1.sin() / (eta1.sinh().powi(2) + xi1.cos().powi(2)).sqrt();
        let lon = self.lon0_deg + eta1.sinh().atan2(xi1.cos()).to_degrees();
        // τ from τ′: Karney (2011) eqs. (19)–(21).
        let e2 = self.f * (2.0 - self.f);
        let e = e2.sqrt();
        let tau_prime = |tau: f64| {
            let sigma = (e * (e * tau / (1.0 + tau * tau).sqrt()).atanh()).sinh();
            tau * (1.0 + sigma * sigma).sqrt() - sigma * (1.0 + tau * tau).sqrt()
        };
        let mut tau = tau1;
        for _ in 0..8 {
            let tp = tau_prime(tau);
            let d = (tau1 - tp) * (1.0 + (1.0 - e2) * tau * tau)
                / ((1.0 - e2) * (1.0 + tp * tp).sqrt() * (1.0 + tau * tau).sqrt());
            tau += d;
            if d.abs() < 1e-15 * tau.abs().max(1.0) {
                break;
            }
        }
        (tau.atan().to_degrees(), lon)
    }

    /// True bearing (degrees clockwise from true north, in [0, 360)) at the grid point
    /// (easting, northing) of the grid direction of grid bearing `grid_bearing_deg`: the
    /// direction of a 1 m grid step, its latitude and longitude differences scaled by the
    /// meridional and prime-vertical radii of curvature (the step is small enough for the
    /// local flat approximation: error below 1e-6°).
    pub fn true_bearing_deg(&self, easting_m: f64, northing_m: f64, grid_bearing_deg: f64) -> f64 {
        let (s, c) = grid_bearing_deg.to_radians().sin_cos();
        let (lat0, lon0) = self.inverse(easting_m, northing_m);
        let (lat1, lon1) = self.inverse(easting_m + s, northing_m + c);
        let e2 = self.f * (2.0 - self.f);
        let phi = lat0.to_radians();
        let w = (1.0 - e2 * phi.sin().powi(2)).sqrt();
        let m = self.a_m * (1.0 - e2) / (w * w * w);
        let nu = self.a_m / w;
        let d_north = (lat1 - lat0).to_radians() * m;
        let d_east = (lon1 - lon0).to_radians() * nu * phi.cos();
        d_east.atan2(d_north).to_degrees().rem_euclid(360.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against PROJ (GDAL 3.6 `gdaltransform -s_srs EPSG:326zz/327zz -t_srs EPSG:4326`).
    #[test]
    fn utm_inverse_matches_proj() {
        let cases = [
            (31, false, 500_000.0, 4_800_000.0, 43.3528553921544, 3.0),
            (
                31,
                false,
                700_000.0,
                5_500_000.0,
                49.6194171918883,
                5.76905774721387,
            ),
            (
                31,
                false,
                300_000.0,
                1_000_000.0,
                9.04204706640632,
                1.18047749123267,
            ),
            (
                31,
                false,
                650_000.0,
                4_800_000.0,
                43.3378837055532,
                4.85045491139206,
            ),
            (
                33,
                true,
                400_000.0,
                6_000_000.0,
                -36.1395604498603,
                13.8885219677738,
            ),
        ];
        for (zone, south, e, n, lat, lon) in cases {
            let (la, lo) = TransverseMercator::utm(zone, south, WGS84).inverse(e, n);
            // 1e-9° ≈ 0.1 mm.
            assert!(
                (la - lat).abs() < 1e-9 && (lo - lon).abs() < 1e-9,
                "({e}, {n}): ({la}, {lo})"
            );
        }
    }

    /// Grid north is true north on the central meridian; 150 km east of it at 43° N it points
    /// east of true north by the convergence that PROJ's coordinates give (1 m steps).
    #[test]
    fn convergence() {
        let tm = TransverseMercator::utm(31, false, WGS84);
        assert!(
            tm.true_bearing_deg(500_000.0, 4_800_000.0, 0.0)
                .min(360.0 - tm.true_bearing_deg(500_000.0, 4_800_000.0, 0.0))
                < 1e-9
        );
        // PROJ: (650000, 4800000) → (43.3378837055532, 4.85045491139206); (650000, 4800010) →
        // (43.3379737040746, 4.85045764532076).
        let phi = 43.3378837055532f64.to_radians();
        let (a, f) = (WGS84.0, 1.0 / WGS84.1);
        let e2 = f * (2.0 - f);
        let w = (1.0 - e2 * phi.sin().powi(2)).sqrt();
        let dn = (43.3379737040746f64 - 43.3378837055532).to_radians() * a * (1.0 - e2) / w.powi(3);
        let de = (4.85045764532076f64 - 4.85045491139206).to_radians() * a / w * phi.cos();
        let want = de.atan2(dn).to_degrees();
        let got = tm.true_bearing_deg(650_000.0, 4_800_000.0, 0.0);
        assert!(
            want > 1.0 && (got - want).abs() < 1e-5,
            "{got} against {want}"
        );
        // A grid direction turns with it.
        let east = tm.true_bearing_deg(650_000.0, 4_800_000.0, 90.0);
        assert!((east - (90.0 + got)).abs() < 1e-5, "{east}");
    }
}
