//! The flux tracker's chunk scheduler (`radiative::engine::stream`): each pass is cut into
//! chunks of emitters whose outputs are merged in chunk order as they finish, holding only the
//! chunks in flight. Scenes of up to 16 chunks of `chunk_rays` nominal rays keep 16 chunks (the
//! asset scenes: their products are the same bytes as before the scheduler, checked with
//! `benches/identity.sh`); larger ones get more, smaller chunks. Here `chunk_rays` is set so low
//! that small scenes run in hundreds of chunks per pass, the regime of a 1 km² scene, with far
//! more chunks than the scheduler lets run ahead of the merge:
//! - the products are bit-identical on 1, 2 and 8 threads (the merge order is the chunk order,
//!   whatever thread finishes first);
//! - they equal the 16-chunk products up to summation order (1e-12 relative; the same rays
//!   through the same cells, per-chunk sums cut at other places), with the same crossing
//!   counts, and energy closes to 1e-12 (absorbed + escaped + lost + remaining = source).
//!
//! Scenes: a turbid layer with sky light (batched walk, ground, images) and a small forest
//! (facets, two turbid materials, hotspot, one-ray walk).

use lumenscape::radiative::products::RadiativeProducts;
use lumenscape::resources::scene::RunSettings;
use lumenscape::scene::SceneSource;
use lumenscape::scene::desc::{Preset, SceneDesc};
use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
use lumenscape::scene::generators::{forest, rami_directions};
use lumenscape::simulation::Simulation;

/// Small enough that every pass of the scenes below runs in hundreds of chunks.
const TINY_CHUNK_RAYS: usize = 400;

fn scenes() -> Vec<(SceneDesc, &'static str)> {
    let mut layer = turbid_layer(&TurbidLayerParams {
        lai: 3.0,
        cell_m: 0.25,
        size_m: 2.0,
        ..Default::default()
    });
    layer.illumination.skyl = vec![0.2];
    layer.directions.as_mut().expect("directions").count = 40;
    let mut trees = forest::forest(&forest::ForestParams {
        size_m: 12.0,
        species: vec![forest::broadleaf(2), forest::conifer(2)],
        ..Default::default()
    });
    trees.directions = Some(rami_directions(225.0));
    vec![(layer, "turbid layer with sky"), (trees, "small forest")]
}

fn run(desc: &SceneDesc, chunk_rays: usize, threads: usize) -> RadiativeProducts {
    let settings = RunSettings {
        preset: Some(Preset::Preview),
        chunk_rays,
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    pool.install(|| {
        let mut sim = Simulation::from_desc(desc, &SceneSource::generated(), settings)
            .unwrap_or_else(|e| panic!("{e}"));
        sim.run(None).unwrap_or_else(|e| panic!("{e}"));
        sim.resource::<RadiativeProducts>().clone()
    })
}

/// Every raw product array, in a fixed order.
fn arrays(p: &RadiativeProducts) -> Vec<(&'static str, &[f64])> {
    let r = &p.raw;
    vec![
        ("escaped", &r.escaped),
        ("intercepted turbid", &r.intercepted_turbid),
        ("absorbed turbid", &r.absorbed_turbid),
        ("intercepted facet", &r.intercepted_facet),
        ("absorbed facet", &r.absorbed_facet),
        ("intercepted ground", &r.intercepted_ground),
        ("absorbed ground", &r.absorbed_ground),
        ("images", &r.images),
    ]
}

fn bits(p: &RadiativeProducts) -> Vec<Vec<u64>> {
    arrays(p)
        .iter()
        .map(|(_, v)| v.iter().map(|x| x.to_bits()).collect())
        .collect()
}

#[test]
fn many_chunks_are_bit_identical_on_1_2_and_8_threads() {
    for (d, what) in scenes() {
        let one = run(&d, TINY_CHUNK_RAYS, 1);
        assert!(one.rays > 0, "{what}: rays walked");
        let b1 = bits(&one);
        for n in [2, 8] {
            assert!(
                bits(&run(&d, TINY_CHUNK_RAYS, n)) == b1,
                "{what}: {n} threads differ from 1"
            );
        }
    }
}

#[test]
fn many_chunks_change_only_the_summation_order() {
    for (d, what) in scenes() {
        let few = run(&d, lumenscape::radiative::engine::CHUNK_RAYS, 2);
        let many = run(&d, TINY_CHUNK_RAYS, 2);
        assert_eq!(few.crossings, many.crossings, "{what}: crossings");
        assert_eq!(few.rays, many.rays, "{what}: rays");
        assert_eq!(few.iterations, many.iterations, "{what}: iterations");
        for ((name, a), (_, b)) in arrays(&few).into_iter().zip(arrays(&many)) {
            assert_eq!(a.len(), b.len(), "{what}: {name} length");
            for (k, (x, y)) in a.iter().zip(b).enumerate() {
                let scale = x.abs().max(y.abs());
                assert!(
                    (x - y).abs() <= 1e-12 * scale,
                    "{what}: {name}[{k}] {x} (16 chunks) vs {y} (many chunks)"
                );
            }
        }
        for p in [&few, &many] {
            for b in &p.bands {
                assert!(
                    b.energy_closure.abs() < 1e-12,
                    "{what}: energy closure {}",
                    b.energy_closure
                );
            }
        }
    }
}
