//! The flux tracker's batched walk (`RunSettings::batch_walk`): queued rays walked side by side
//! in vector lanes against the same rays walked one by one, both lane counts of the
//! double-precision walk (`batch_f32: false`; 8 with AVX-512 where the CPU has it, 4 with
//! AVX2, `KernelIsa::Avx2`); at the end, the single-precision 16-lane walk (the default on
//! AVX-512) against the double-precision one. Each ray goes through
//! the same operations in both walks, so only the order in which the rays' contributions are
//! summed differs: per turbid entry the intercepted and absorbed power, per direction the
//! escaped power, per ground column the intercepted power and the image pixels agree to
//! 1e-12 relative (sums of the same terms in another order: ~1e-15 seen), the visited and
//! skipped crossing counts and the iteration counts are equal, and energy closes to 1e-12.
//! Cases: a LAI 3 layer with 1, 2 and 4 channels (red; red + NIR; four bands; red + NIR with
//! sky), the hotspot on (first-order sun rays on the one-ray path, the rest batched), sun
//! through cell vertices and along cell edges, grazing sun at 89° (long oblique walks, many
//! periodic wraps), very dense cells (u_f = 50 m²/m³: short walks ended by the power
//! threshold), an isolated scene (side exits lost). On a CPU without AVX2 both runs take the
//! one-ray walk and the comparison holds trivially.

mod common;
use common::no_hotspot;
use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::{BoundaryMode, LadDesc, Preset, SceneDesc};
use lumenscape::scene::generators::BandOptics;
use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
use lumenscape::simulation::Simulation;

/// `desc` with the one-ray walk or the double-precision batched walk (the walks these
/// equality tests compare; the single-precision walk is compared with them at the end).
fn run(desc: &SceneDesc, batch_walk: bool) -> RadiativeProducts {
    run_with(
        desc,
        RunSettings {
            batch_walk,
            batch_f32: false,
            ..Default::default()
        },
    )
}

/// Whether this CPU has `isa` (`"AVX2"`: the batched walk runs; `"AVX-512"`: its 8- and
/// 16-lane forms run); when it has not, prints `skipped: CPU lacks ISA (what)` so that a test
/// that cannot run here says so instead of passing silently (issue #31).
fn cpu_has(isa: &str, what: &str) -> bool {
    let best = lumenscape::radiative::engine::kernel_isa();
    let has = match isa {
        "AVX-512" => best == "AVX-512",
        "AVX2" => best != "baseline",
        other => panic!("unknown instruction set {other}"),
    };
    if !has {
        eprintln!("skipped: CPU lacks {isa} ({what})");
    }
    has
}

/// The walk a run took (`summary.json` key `walk`): kernel, precision and lanes.
fn walk_of(p: &RadiativeProducts) -> (&'static str, &'static str, u32) {
    let w = p.raw.walk.expect("flux tracking records its walk");
    (w.kernel, w.precision, w.lanes)
}

/// The products of `desc` run with `settings` at the preview preset.
fn run_with(desc: &SceneDesc, settings: RunSettings) -> RadiativeProducts {
    let settings = RunSettings {
        preset: Some(Preset::Preview),
        ..settings
    };
    let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), settings)
        .unwrap_or_else(|e| panic!("{e}"));
    sim.run(None).unwrap_or_else(|e| panic!("{e}"));
    sim.resource::<RadiativeProducts>().clone()
}

/// The raw products as bits (escaped, intercepted and absorbed turbid, intercepted ground,
/// images) and the visited crossings.
fn product_bits(p: &RadiativeProducts) -> ([Vec<u64>; 5], u64) {
    let r = &p.raw;
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    (
        [
            bits(&r.escaped),
            bits(&r.intercepted_turbid),
            bits(&r.absorbed_turbid),
            bits(&r.intercepted_ground),
            bits(&r.images),
        ],
        p.crossings,
    )
}

/// Largest |a − b| / max(|a|, |b|) over two equally long product arrays (0 where both are 0).
fn worst_rel(a: &[f64], b: &[f64], what: &str) -> f64 {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            assert!(x.is_finite() && y.is_finite(), "{what}: not finite");
            let m = x.abs().max(y.abs());
            if m == 0.0 { 0.0 } else { (x - y).abs() / m }
        })
        .fold(0.0, f64::max)
}

/// The raw product arrays of two runs side by side, with their names: per turbid entry the
/// intercepted and absorbed power, per direction the escaped power, per ground column the
/// intercepted power, the image pixels.
fn raw_pairs<'a>(
    a: &'a RadiativeProducts,
    b: &'a RadiativeProducts,
) -> [(&'static str, &'a [f64], &'a [f64]); 5] {
    let (ra, rb) = (&a.raw, &b.raw);
    [
        (
            "intercepted turbid",
            &ra.intercepted_turbid,
            &rb.intercepted_turbid,
        ),
        ("absorbed turbid", &ra.absorbed_turbid, &rb.absorbed_turbid),
        ("escaped", &ra.escaped, &rb.escaped),
        (
            "intercepted ground",
            &ra.intercepted_ground,
            &rb.intercepted_ground,
        ),
        ("images", &ra.images, &rb.images),
    ]
}

fn batched_equals_one_by_one(d: &SceneDesc, what: &str) {
    if !cpu_has("AVX2", &format!("{what}: no batched walk to compare")) {
        return;
    }
    let one = run(d, false);
    assert_eq!(
        walk_of(&one),
        ("baseline", "f64", 1),
        "{what}: one-ray walk"
    );
    let batched = run(d, true);
    let (kernel, precision, lanes) = walk_of(&batched);
    assert!(
        kernel != "baseline" && precision == "f64" && lanes > 1,
        "{what}: the batched walk did not run ({kernel}, {precision}, {lanes})"
    );
    same_up_to_summation_order(&batched, &one, what);
    // The 4-lane walk that CPUs without AVX-512 run (where this CPU has AVX-512, the default
    // above ran 8 lanes).
    let avx2 = run_with(
        d,
        RunSettings {
            batch_walk: true,
            batch_f32: false,
            kernel_isa: lumenscape::radiative::engine::KernelIsa::Avx2,
            ..Default::default()
        },
    );
    assert_eq!(walk_of(&avx2), ("avx2", "f64", 4), "{what}: AVX2 walk");
    same_up_to_summation_order(&avx2, &one, &format!("{what}, AVX2 lanes"));
}

/// Two runs that walk the same rays through the same cells and differ only in the order in
/// which the rays' contributions are summed: the same crossings and iterations, every raw
/// product within 1e-12 relative (summation-order rounding over ~1e5 terms is ~1e-14), and
/// energy closing in both.
fn same_up_to_summation_order(a: &RadiativeProducts, b: &RadiativeProducts, what: &str) {
    assert_eq!(a.crossings, b.crossings, "{what}: visited crossings");
    assert_eq!(a.skipped, b.skipped, "{what}: skipped crossings");
    let (ra, rb) = (&a.raw, &b.raw);
    assert_eq!(ra.iterations, rb.iterations, "{what}: iterations");
    assert!(
        ra.intercepted_turbid.iter().any(|&v| v > 0.0),
        "{what}: nothing intercepted"
    );
    for (name, x, y) in raw_pairs(a, b) {
        let r = worst_rel(x, y, &format!("{what}: {name}"));
        assert!(r <= 1e-12, "{what}: {name} differs by {r:e} relative");
    }
    for bd in a.bands.iter().chain(&b.bands) {
        assert!(
            bd.energy_closure <= 1e-12,
            "{what}: closure {:e}",
            bd.energy_closure
        );
    }
}

/// The LAI 3 layer in red + NIR, sun at 30° zenith and 20° azimuth, with sky (SKYL 0.3 and
/// 0.2) and ground: the thread and instruction-set tests' scene.
fn layer_with_sky() -> SceneDesc {
    let mut d = layer(
        3.0,
        vec![BandOptics::red(), BandOptics::nir()],
        0.2,
        30.0,
        20.0,
    );
    d.illumination.skyl = vec![0.3, 0.2];
    d
}

/// Four bands (W = 4): leaf reflectance 0.05–0.4, transmittance 0.8 × it, soil 0.2.
fn four_bands() -> Vec<BandOptics> {
    let band = |name: &str, nm: f64, r: f64| BandOptics {
        name: name.into(),
        wavelength_nm: nm,
        leaf_r: r,
        leaf_t: 0.8 * r,
        soil_r: 0.2,
    };
    vec![
        band("b1", 500.0, 0.05),
        band("b2", 600.0, 0.1),
        band("b3", 700.0, 0.2),
        band("b4", 800.0, 0.4),
    ]
}

/// A 1 m periodic turbid layer, 2 m high, spherical LAD, 36 directions.
fn layer(lai: f64, bands: Vec<BandOptics>, cell: f64, zenith: f64, azimuth: f64) -> SceneDesc {
    let mut d = turbid_layer(&TurbidLayerParams {
        lai,
        lad: LadDesc::Spherical,
        bands,
        height_m: 2.0,
        cell_m: cell,
        size_m: 1.0,
        sun_zenith_deg: zenith,
        sun_azimuth_deg: azimuth,
    });
    no_hotspot(&mut d);
    d.directions.as_mut().expect("directions").count = 36;
    d
}

#[test]
fn batched_walk_matches_the_one_ray_walk_with_1_2_and_4_channels() {
    let red = || vec![BandOptics::red()];
    let two = || vec![BandOptics::red(), BandOptics::nir()];
    batched_equals_one_by_one(&layer(3.0, red(), 0.2, 20.0, 0.0), "LAI 3, red (W = 1)");
    batched_equals_one_by_one(
        &layer(3.0, two(), 0.2, 20.0, 0.0),
        "LAI 3, red + NIR (W = 2)",
    );
    let four = four_bands();
    batched_equals_one_by_one(&layer(3.0, four, 0.2, 20.0, 0.0), "4 bands (W = 4)");
    // Sun and sky channels (W = 2 × 2 bands), without the ground: with it, the later orders of
    // this scene move by up to ~1e-6 per entry under any reordering of the sums (the batched
    // walk with a queue of one ray is bit-identical to the one-ray walk there too, so it is a
    // sensitivity of the engine to the summation order, not of the walk; see the README of
    // 4df2100).
    let mut sky = layer(3.0, two(), 0.2, 20.0, 0.0);
    sky.illumination.skyl = vec![0.3, 0.2];
    sky.objects.remove(0);
    batched_equals_one_by_one(&sky, "LAI 3, red + NIR + sky, no ground (W = 4)");
    // The hotspot on: first-order sun rays take the one-ray path, the others are batched.
    let mut hs = turbid_layer(&TurbidLayerParams {
        lai: 3.0,
        lad: LadDesc::Spherical,
        bands: two(),
        height_m: 2.0,
        cell_m: 0.2,
        size_m: 1.0,
        sun_zenith_deg: 30.0,
        sun_azimuth_deg: 10.0,
    });
    hs.directions.as_mut().expect("directions").count = 36;
    batched_equals_one_by_one(&hs, "LAI 3 with the hotspot");
}

#[test]
fn batched_walk_matches_the_one_ray_walk_on_hard_geometry() {
    for (d, what) in hard_geometry() {
        batched_equals_one_by_one(&d, what);
    }
}

/// The hard-geometry scenes: cubic 0.25 m cells with the sun through cell vertices (azimuth
/// 45°, zenith atan √2) and along cell edges (azimuth 0°, zenith 45°: x and z steps tie); a
/// grazing sun (long oblique walks with many periodic wraps); very dense cells (u_f = 50
/// m²/m³: LAI 25 in 0.5 m), where the power threshold ends most walks after a few cells; an
/// isolated scene (rays leaving through the sides are lost).
fn hard_geometry() -> Vec<(SceneDesc, &'static str)> {
    let two = || vec![BandOptics::red(), BandOptics::nir()];
    let vz = 2f64.sqrt().atan().to_degrees();
    let mut dense = turbid_layer(&TurbidLayerParams {
        lai: 25.0,
        height_m: 0.5,
        cell_m: 0.125,
        size_m: 1.0,
        ..Default::default()
    });
    no_hotspot(&mut dense);
    dense.directions.as_mut().expect("directions").count = 36;
    let mut iso = layer(3.0, two(), 0.25, 40.0, 20.0);
    iso.grid.boundary = BoundaryMode::Isolated;
    vec![
        (layer(3.0, two(), 0.25, vz, 45.0), "sun through vertices"),
        (layer(3.0, two(), 0.25, 45.0, 0.0), "sun along cell edges"),
        (layer(3.0, two(), 0.25, 89.0, 33.0), "sun 89°"),
        (dense, "dense u_f 50"),
        (iso, "isolated layer"),
    ]
}

/// The batched walk's products are bit-identical on 1, 2 and 8 threads (the queues are filled
/// and walked in each chunk's own order), with sky and ground.
#[test]
fn batched_walk_products_are_bit_identical_on_1_2_and_8_threads() {
    if !cpu_has("AVX2", "batched walk on 1, 2 and 8 threads") {
        return;
    }
    let d = layer_with_sky();
    let go = |n| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .expect("thread pool");
        pool.install(|| product_bits(&run(&d, true)))
    };
    let one = go(1);
    assert!(one.1 > 0, "rays walked");
    assert!(go(2) == one, "2 threads differ from 1");
    assert!(go(8) == one, "8 threads differ from 1");
}

/// The walks give the same results on every instruction set this CPU has
/// (`RunSettings::kernel_isa`): on this project's machines (AVX-512) the default runs the
/// batched walk on 8 lanes, and the 4-lane AVX2 and the baseline copies — what other CPUs run —
/// would otherwise go untested. Batched walk: 8 lanes against 4, the same rays through the same
/// cells, products equal up to summation order (the per-ray bits are checked lane by lane in
/// the `dda` and `fastmath` unit tests); one ray at a time: best, AVX2 and baseline, bit for
/// bit (the baseline has no batched walk: it walks one ray at a time, which the tests above
/// compare with the batched walk). A layer with sky and ground, and a small forest (facets, two
/// turbid materials, hotspot, exact views).
#[test]
fn walks_agree_on_every_instruction_set() {
    use lumenscape::radiative::engine::KernelIsa;
    use lumenscape::scene::generators::{forest, rami_directions};
    let products = |d: &SceneDesc, batch_walk: bool, kernel_isa: KernelIsa| {
        let settings = RunSettings {
            batch_walk,
            batch_f32: false,
            kernel_isa,
            ..Default::default()
        };
        run_with(d, settings)
    };
    let run_isa = |d: &SceneDesc, batch_walk: bool, kernel_isa: KernelIsa| {
        product_bits(&products(d, batch_walk, kernel_isa))
    };
    let layer = layer_with_sky();
    let mut trees = forest::forest(&forest::ForestParams {
        size_m: 12.0,
        species: vec![forest::broadleaf(2), forest::conifer(2)],
        ..Default::default()
    });
    trees.directions = Some(rami_directions(225.0));
    // What cannot run on this CPU is reported as skipped, not passed.
    let avx2_here = cpu_has(
        "AVX2",
        "batched walk best vs AVX2; one-ray walk AVX2 vs baseline",
    );
    let avx512_here =
        avx2_here && cpu_has("AVX-512", "batched walk 8 lanes vs 4: the best set is AVX2");
    for (d, what) in [(&layer, "layer"), (&trees, "forest")] {
        if avx512_here {
            let best = products(d, true, KernelIsa::Best);
            assert!(best.crossings > 0, "{what}: rays walked");
            let avx2 = products(d, true, KernelIsa::Avx2);
            same_up_to_summation_order(&best, &avx2, &format!("{what}, batched, best vs AVX2"));
        }
        let one = run_isa(d, false, KernelIsa::Best);
        assert!(one.1 > 0, "{what}: rays walked");
        let caps: &[KernelIsa] = if avx2_here {
            &[KernelIsa::Avx2, KernelIsa::Baseline]
        } else {
            &[]
        };
        for &isa in caps {
            assert!(
                run_isa(d, false, isa) == one,
                "{what}: one ray at a time, {isa:?} differs from the best set"
            );
        }
        let base = run_isa(d, true, KernelIsa::Baseline);
        assert!(base == one, "{what}: the baseline walks one ray at a time");
    }
}

/// The single-precision 16-lane walk (`RunSettings::batch_f32`; AVX-512 CPUs only, elsewhere
/// the setting changes nothing) against the double-precision batched walk on `d`: the same
/// physics with path lengths, fractions and interception points in `f32` (each to ~1e-7
/// relative; powers, bookings and energy closure in `f64`). Tolerances: the band products
/// (albedo, absorbed and transmitted fractions, BRF and HDRF per direction) within 1e-5
/// relative (the f32 e^{−x} is good to ~2e-7, so 1 − e^{−x} to ~1e-6 relative for x ~ 0.1, a
/// cell's optical depth in the 20 m cells below; 0.1 % of the DISORT tolerance), per-entry and per-pixel raw products within 1e-4 relative (a single cell or pixel
/// sums fewer rays, and a ray whose power is at the stopping threshold may stop one crossing
/// earlier or later), the visited crossings within 1e-2 (see below); energy closing to 1e-12 as in the f64
/// walk; no NaN. Measured (the `f32_walk_agrees_*` printouts, 2026-11-27): band products 0.9–2.5e-7
/// on the 0.2–0.25 m layers and the dense cells, 3.4e-6 with 20 m cells; raw ≤ 9.3e-5 (one
/// pixel of the cell-edge case).
fn f32_walk_agrees(d: &SceneDesc, what: &str) {
    let with = |f32w: bool| {
        run_with(
            d,
            RunSettings {
                batch_f32: f32w,
                ..Default::default()
            },
        )
    };
    if !cpu_has("AVX-512", &format!("{what}: the f32 walk does not run")) {
        return;
    }
    let (a, b) = (with(false), with(true));
    assert_eq!(walk_of(&a), ("avx512", "f64", 8), "{what}: f64 walk");
    assert_eq!(walk_of(&b), ("avx512", "f32", 16), "{what}: f32 walk");
    // The f32 walk ran: its products are not the f64 walk's bits.
    assert!(
        product_bits(&a) != product_bits(&b),
        "{what}: f32 walk did not run"
    );
    // Crossings within 1e-2: where a ray passes through cell edges or vertices (the sun
    // cases below), a tie that one precision resolves as one step is two steps (one of zero
    // length, intercepting nothing) in the other.
    let dc = (a.crossings as f64 - b.crossings as f64).abs() / a.crossings as f64;
    eprintln!(
        "{what}: crossings {} (f64) {} (f32)",
        a.crossings, b.crossings
    );
    assert!(
        dc <= 1e-2,
        "{what}: crossings {} vs {}",
        a.crossings,
        b.crossings
    );
    let mut worst_raw = 0f64;
    for (name, x, y) in raw_pairs(&a, &b) {
        let r = worst_rel(x, y, &format!("{what}: {name}"));
        assert!(r <= 1e-4, "{what}: {name} differs by {r:e} relative");
        worst_raw = worst_raw.max(r);
    }
    let mut worst_band = 0f64;
    for (x, y) in a.bands.iter().zip(&b.bands) {
        assert!(
            y.energy_closure <= 1e-12,
            "{what}: closure {:e}",
            y.energy_closure
        );
        let mut v = vec![(x.albedo, y.albedo), (x.fabs, y.fabs), (x.ftran, y.ftran)];
        for (p, q) in x.brf.iter().zip(&y.brf) {
            v.push((p.brf, q.brf));
            if let (Some(p), Some(q)) = (p.hdrf, q.hdrf) {
                v.push((p, q));
            }
        }
        for (p, q) in v {
            assert!(q.is_finite(), "{what}: NaN");
            let r = (p - q).abs() / p.abs().max(q.abs()).max(1e-300);
            worst_band = worst_band.max(r);
        }
    }
    eprintln!("{what}: f32 walk vs f64: band products {worst_band:.2e}, raw {worst_raw:.2e}");
    assert!(
        worst_band <= 1e-5,
        "{what}: band products differ by {worst_band:e}"
    );
}

#[test]
fn f32_walk_agrees_with_the_f64_walk_with_1_2_and_4_channels_and_sky() {
    f32_walk_agrees(
        &layer(3.0, vec![BandOptics::red()], 0.2, 30.0, 20.0),
        "1 channel",
    );
    f32_walk_agrees(&layer_with_sky(), "red + NIR with sky");
    let four = four_bands();
    f32_walk_agrees(&layer(3.0, four, 0.2, 30.0, 20.0), "4 channels");
}

#[test]
fn f32_walk_agrees_with_the_f64_walk_on_hard_geometry() {
    for (d, what) in hard_geometry() {
        f32_walk_agrees(&d, what);
    }
    // A huge scene (cells of 20 m, a 100 m × 100 m tile 200 m high) and a tiny one (1 mm
    // cells): the cell frame keeps f32 relative to the cell, whatever the scene's size.
    let mut huge = turbid_layer(&TurbidLayerParams {
        lai: 3.0,
        height_m: 200.0,
        cell_m: 20.0,
        size_m: 100.0,
        ..Default::default()
    });
    no_hotspot(&mut huge);
    huge.directions.as_mut().expect("directions").count = 36;
    f32_walk_agrees(&huge, "huge cells");
    let mut tiny = turbid_layer(&TurbidLayerParams {
        lai: 3.0,
        height_m: 0.01,
        cell_m: 0.001,
        size_m: 0.005,
        ..Default::default()
    });
    no_hotspot(&mut tiny);
    tiny.directions.as_mut().expect("directions").count = 36;
    f32_walk_agrees(&tiny, "tiny cells");
}

/// The f32 walk's products are bit-identical on 1, 2 and 8 threads.
#[test]
fn f32_walk_products_are_bit_identical_on_1_2_and_8_threads() {
    if !cpu_has("AVX-512", "f32 walk on 1, 2 and 8 threads") {
        return;
    }
    let d = layer_with_sky();
    let go = |n| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .expect("thread pool");
        pool.install(|| {
            product_bits(&run_with(
                &d,
                RunSettings {
                    batch_f32: true,
                    ..Default::default()
                },
            ))
        })
    };
    let one = go(1);
    assert!(one.1 > 0, "rays walked");
    assert!(go(2) == one, "2 threads differ from 1");
    assert!(go(8) == one, "8 threads differ from 1");
}
