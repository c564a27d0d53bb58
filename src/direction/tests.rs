//! Unit tests of the direction tiling (exact 4π partition, exact directions, lookup).

use super::*;

#[test]
fn azimuth_box_span_and_the_empty_range() {
    assert_eq!(azimuth_span_deg(0.0, 360.0), 360.0);
    assert_eq!(azimuth_span_deg(350.0, 10.0), 20.0);
    assert_eq!(azimuth_span_deg(10.0, 350.0), 340.0);
    let region = |lo: f64, hi: f64| DirectionParams {
        count: 100,
        oversample: vec![OversampleRegion::Box {
            zenith_min_deg: 10.0,
            zenith_max_deg: 40.0,
            azimuth_min_deg: lo,
            azimuth_max_deg: hi,
            solid_angle_sr: 0.01,
        }],
        ..DirectionParams::default()
    };
    // A whole turn is a valid box and oversamples every azimuth.
    let set = DirectionSet::new(&region(0.0, 360.0)).expect("0..360 is valid");
    assert!(
        set.tiling()
            .iter()
            .any(|d| d.kind == DirectionKind::Oversampled)
    );
    // Equal bounds: an empty range, rejected with the field named (it used to pass and
    // oversample nothing while the direction-count bound counted a whole turn).
    let e = DirectionSet::new(&region(90.0, 90.0)).expect_err("empty azimuth range");
    let m = e.to_string();
    assert!(m.contains("azimuth_max_deg") && m.contains("empty"), "{m}");
}

#[test]
fn default_set_identities() {
    let s = DirectionSet::with_count(100).unwrap();
    assert_eq!(s.n_regular(), 100);
    assert!((s.total_solid_angle() - 4.0 * PI).abs() < 1e-12);
    for (o, p) in s.hemisphere_sums() {
        assert!((o - TAU).abs() < 1e-12 && (p - PI).abs() < 1e-12);
    }
    let (a, b) = s.aspect_ratio_range();
    assert!(a > 0.5 && b < 2.0, "{a} {b}");
    for (i, d) in s.tiling().iter().enumerate() {
        assert_eq!(s.find_sector(d.omega), i);
    }
    assert!(s.n_sectors() == 10);
}

#[test]
fn ron_roundtrip_of_params() {
    let txt = "(count: 50, exact: [(zenith_deg: 30, azimuth_deg: 0, label: Some(\"hotspot\"))], oversample: [Cone(zenith_deg: 30, azimuth_deg: 0, half_angle_deg: 10, solid_angle_sr: 0.002)])";
    let p: DirectionParams = ron::from_str(txt).unwrap();
    assert_eq!(p.count, 50);
    assert_eq!(p.sectors, 10);
    assert!(ron::from_str::<DirectionParams>("(cont: 50)").is_err());
}
