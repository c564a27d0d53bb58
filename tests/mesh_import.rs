//! Mesh import (glTF, GLB, OBJ) against the sample tree written by
//! `assets/meshes/make_meshes.py`, whose expected counts, areas, bounding boxes and trunk
//! volume are in `assets/meshes/small_tree_expected.json`, plus error handling on bad files.
//!
//! Tolerances: the script rounds every vertex to f32 before writing it and computes the
//! expected numbers in f64 from those rounded values, so an f64 importer matches them up to
//! f64 rounding: 1e-12 relative (observed ~1e-16). Comparisons between formats (glTF → z-up
//! vs OBJ) carry the f32 rounding of the OBJ's transformed vertices: 1e-6 relative.

use std::path::{Path, PathBuf};

use base64::Engine;
use glam::{DMat4, DVec3};
use lumenscape::io::mesh::{
    DegenerateReport, ImportedMesh, MeshError, gltf_y_up_to_z_up, load_mesh,
};
use serde_json::Value;

/// Expected-vs-loaded tolerance (relative), see the module doc.
const SAME_DATA_REL_TOL: f64 = 1e-12;
/// glTF-vs-OBJ tolerance (relative): f32 rounding of the OBJ's world-space vertices.
const CROSS_FORMAT_REL_TOL: f64 = 1e-6;

fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/meshes")
        .join(name)
}

fn expected() -> Value {
    let text = std::fs::read_to_string(asset("small_tree_expected.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn vec3(v: &Value) -> DVec3 {
    let a = v.as_array().unwrap();
    DVec3::new(
        a[0].as_f64().unwrap(),
        a[1].as_f64().unwrap(),
        a[2].as_f64().unwrap(),
    )
}

/// A fresh, unique scratch directory under the system temp dir.
fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "lumenscape_mesh_import_{}_{}",
        std::process::id(),
        tag
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn rel_err(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

fn signed_volume(tris: &[[DVec3; 3]]) -> f64 {
    tris.iter().map(|t| t[0].dot(t[1].cross(t[2]))).sum::<f64>() / 6.0
}

/// Compares a loaded mesh with one format's section of the expected JSON; returns the worst
/// relative errors (area, bbox, volume) for reporting.
fn check_against_expected(mesh: &ImportedMesh, exp: &Value, label: &str) -> [f64; 3] {
    let groups = exp["groups"].as_array().unwrap();
    assert_eq!(mesh.groups.len(), groups.len(), "{label}: group count");
    assert_eq!(
        mesh.skipped_non_triangle as u64,
        exp["skipped_non_triangle_primitives"].as_u64().unwrap(),
        "{label}: skipped primitives"
    );
    let (lo, hi) = mesh.bounding_box().unwrap();
    let scale = (hi - lo).length();
    let mut worst = [0.0f64; 3];
    for g in groups {
        let name = g["name"].as_str().unwrap();
        let got = mesh
            .group(name)
            .unwrap_or_else(|| panic!("{label}: no group {name}"));
        assert_eq!(
            got.triangles.len() as u64,
            g["triangles"].as_u64().unwrap(),
            "{label}/{name}: triangle count"
        );
        let e = rel_err(got.area(), g["area_m2"].as_f64().unwrap());
        worst[0] = worst[0].max(e);
        assert!(e <= SAME_DATA_REL_TOL, "{label}/{name}: area rel err {e:e}");
        let (blo, bhi) = got.bounding_box().unwrap();
        let eb = (blo - vec3(&g["bbox_min"]))
            .abs()
            .max((bhi - vec3(&g["bbox_max"])).abs())
            .max_element()
            / scale;
        worst[1] = worst[1].max(eb);
        assert!(eb <= SAME_DATA_REL_TOL, "{label}/{name}: bbox err {eb:e}");
    }
    let v = signed_volume(&mesh.group("bark").unwrap().triangles);
    let ev = rel_err(v, exp["bark_signed_volume_m3"].as_f64().unwrap());
    worst[2] = ev;
    assert!(
        ev <= SAME_DATA_REL_TOL,
        "{label}: bark volume rel err {ev:e}"
    );
    println!(
        "{label}: worst rel err area {:.1e}, bbox {:.1e}, volume {:.1e}",
        worst[0], worst[1], worst[2]
    );
    worst
}

#[test]
fn gltf_matches_expected_counts_and_areas() {
    let mesh = load_mesh(&asset("small_tree.gltf")).unwrap();
    check_against_expected(&mesh, &expected()["gltf"], "gltf");
    let names: Vec<_> = mesh.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(names, ["bark", "leaf"], "groups in file order, by material");
}

#[test]
fn glb_matches_expected_and_equals_gltf() {
    let glb = load_mesh(&asset("small_tree.glb")).unwrap();
    check_against_expected(&glb, &expected()["gltf"], "glb");
    let gltf = load_mesh(&asset("small_tree.gltf")).unwrap();
    assert_eq!(glb.groups, gltf.groups, "same content, bit for bit");
}

#[test]
fn obj_matches_expected_counts_and_areas() {
    let mesh = load_mesh(&asset("small_tree.obj")).unwrap();
    check_against_expected(&mesh, &expected()["obj"], "obj");
    assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
}

#[test]
fn trunk_is_closed_outward_and_has_the_prism_volume() {
    // Strip/fan winding: a closed, outward-facing prism has positive signed volume equal
    // to its volume 2√2 r² h (regular octagon of circumradius r); f32 radius → 1e-6.
    let analytic = expected()["analytic"]["trunk_volume_m3"].as_f64().unwrap();
    for (file, up) in [
        ("small_tree.gltf", DMat4::IDENTITY),
        ("small_tree.glb", DMat4::IDENTITY),
        ("small_tree.obj", DMat4::IDENTITY),
        ("small_tree.gltf", gltf_y_up_to_z_up()),
    ] {
        let mut mesh = load_mesh(&asset(file)).unwrap();
        mesh.transform(up);
        let v = signed_volume(&mesh.group("bark").unwrap().triangles);
        let e = rel_err(v, analytic);
        assert!(
            e < 1e-6,
            "{file}: trunk volume {v} vs {analytic} (rel {e:e})"
        );
    }
}

#[test]
fn gltf_hierarchy_places_the_crown() {
    // Node "small_tree" translates by (2, 0, −1); its child "crown" by (0, 3.5, 0) with
    // scale (1, 1.25, 1); leaf centres lie in a local sphere of radius 1.5 and leaf vertices
    // within 0.1/√3 of their centre. Undo the composed transform and check every vertex.
    let exp = expected();
    let centre = vec3(&exp["analytic"]["crown_centre_gltf"]);
    let semi = vec3(&exp["analytic"]["crown_semi_axes_gltf"]);
    assert_eq!(centre, DVec3::new(2.0, 3.5, -1.0));
    let mesh = load_mesh(&asset("small_tree.gltf")).unwrap();
    let leaf = mesh.group("leaf").unwrap();
    let scale = semi / 1.5;
    let reach = 1.5 + 0.1 / 3f64.sqrt() + 1e-6;
    for p in leaf.triangles.iter().flatten() {
        let local = (*p - centre) / scale;
        assert!(local.length() <= reach, "leaf vertex {p} outside the crown");
    }
    // The crown fills its ellipsoid: the bbox spans most of each axis around the centre.
    let (lo, hi) = leaf.bounding_box().unwrap();
    for k in 0..3 {
        assert!(lo[k] < centre[k] - 0.8 * semi[k] && hi[k] > centre[k] + 0.8 * semi[k]);
    }
    // The trunk only gets the root translation: base at y = 0 around (2, ·, −1).
    let (tlo, thi) = mesh.group("bark").unwrap().bounding_box().unwrap();
    assert!(
        ((tlo + thi) / 2.0 - DVec3::new(2.0, 1.0, -1.0))
            .abs()
            .max_element()
            < 1e-7
    );
    assert_eq!((tlo.y, thi.y), (0.0, 2.0));
}

#[test]
fn gltf_converted_to_z_up_agrees_with_obj() {
    let mut gltf = load_mesh(&asset("small_tree.gltf")).unwrap();
    gltf.transform(gltf_y_up_to_z_up());
    let obj = load_mesh(&asset("small_tree.obj")).unwrap();
    let (lo, hi) = obj.bounding_box().unwrap();
    let scale = (hi - lo).length();
    let mut worst_area = 0.0f64;
    let mut worst_pos = 0.0f64;
    for name in ["bark", "leaf"] {
        let (a, b) = (gltf.group(name).unwrap(), obj.group(name).unwrap());
        assert_eq!(a.triangles.len(), b.triangles.len());
        worst_area = worst_area.max(rel_err(a.area(), b.area()));
        let (alo, ahi) = a.bounding_box().unwrap();
        let (blo, bhi) = b.bounding_box().unwrap();
        worst_pos = worst_pos.max((alo - blo).abs().max((ahi - bhi).abs()).max_element() / scale);
    }
    // Leaves are written in the same order by both files: compare vertex by vertex.
    let (a, b) = (gltf.group("leaf").unwrap(), obj.group("leaf").unwrap());
    for (ta, tb) in a.triangles.iter().zip(&b.triangles) {
        for k in 0..3 {
            worst_pos = worst_pos.max((ta[k] - tb[k]).abs().max_element() / scale);
        }
    }
    println!("gltf→z-up vs obj: worst rel area {worst_area:.1e}, worst position {worst_pos:.1e}");
    assert!(worst_area < CROSS_FORMAT_REL_TOL, "{worst_area:e}");
    assert!(worst_pos < CROSS_FORMAT_REL_TOL, "{worst_pos:e}");
}

/// The sample glTF's JSON and its decoded embedded buffer.
fn sample_gltf_parts() -> (Value, Vec<u8>) {
    let text = std::fs::read_to_string(asset("small_tree.gltf")).unwrap();
    let doc: Value = serde_json::from_str(&text).unwrap();
    let uri = doc["buffers"][0]["uri"].as_str().unwrap();
    let b64 = uri.split_once(',').unwrap().1;
    let data = base64::engine::general_purpose::STANDARD
        .decode(b64)
        .unwrap();
    (doc, data)
}

#[test]
fn external_bin_buffer_relative_to_the_gltf() {
    let dir = temp_dir("external_bin");
    let (mut doc, data) = sample_gltf_parts();
    std::fs::create_dir_all(dir.join("sub dir")).unwrap();
    std::fs::write(dir.join("sub dir/tree data.bin"), &data).unwrap();
    doc["buffers"][0]["uri"] = "sub%20dir/tree%20data.bin".into();
    let path = dir.join("tree.gltf");
    std::fs::write(&path, serde_json::to_string(&doc).unwrap()).unwrap();
    let external = load_mesh(&path).unwrap();
    let embedded = load_mesh(&asset("small_tree.gltf")).unwrap();
    assert_eq!(external.groups, embedded.groups);

    // Missing and short .bin files are bad buffers, naming the glTF and the .bin.
    std::fs::remove_file(dir.join("sub dir/tree data.bin")).unwrap();
    let e = load_mesh(&path).unwrap_err();
    assert!(matches!(e, MeshError::BadBuffer { .. }), "{e}");
    assert!(
        e.to_string().contains("tree.gltf") && e.to_string().contains("tree data.bin"),
        "{e}"
    );
    std::fs::write(dir.join("sub dir/tree data.bin"), &data[..data.len() / 2]).unwrap();
    let e = load_mesh(&path).unwrap_err();
    assert!(matches!(e, MeshError::BadBuffer { .. }), "{e}");
    println!("{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_gltf_buffers_and_layouts_are_errors() {
    let dir = temp_dir("bad_buffers");
    let (doc, data) = sample_gltf_parts();
    let b64 = |d: &[u8]| {
        format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(d)
        )
    };
    type Edit = Box<dyn Fn(&mut Value)>;
    let cases: Vec<(&str, Edit)> = vec![
        (
            "truncated_data_uri",
            Box::new(move |d| d["buffers"][0]["uri"] = b64(&data[..100]).into()),
        ),
        (
            "invalid_base64",
            Box::new(|d| {
                d["buffers"][0]["uri"] = "data:application/octet-stream;base64,@@@@".into()
            }),
        ),
        (
            "remote_uri",
            Box::new(|d| d["buffers"][0]["uri"] = "https://example.invalid/x.bin".into()),
        ),
        (
            "view_past_buffer",
            Box::new(|d| d["bufferViews"][0]["byteLength"] = 100_000.into()),
        ),
        (
            "accessor_past_view",
            Box::new(|d| d["accessors"][0]["count"] = 1000.into()),
        ),
        (
            "accessor_count_zero",
            Box::new(|d| d["accessors"][0]["count"] = 0.into()),
        ),
        (
            "positions_not_float",
            Box::new(|d| d["accessors"][0]["componentType"] = 5123.into()),
        ),
        (
            "float_indices",
            Box::new(|d| d["accessors"][1]["componentType"] = 5126.into()),
        ),
        (
            "small_stride",
            Box::new(|d| d["bufferViews"][0]["byteStride"] = 4.into()),
        ),
        (
            "index_out_of_range",
            Box::new(|d| d["accessors"][0]["count"] = 4.into()),
        ),
    ];
    for (tag, edit) in cases {
        let mut d = doc.clone();
        edit(&mut d);
        let path = dir.join(format!("{tag}.gltf"));
        std::fs::write(&path, serde_json::to_string(&d).unwrap()).unwrap();
        match load_mesh(&path) {
            Err(e @ (MeshError::BadBuffer { .. } | MeshError::Parse { .. })) => {
                assert!(e.to_string().contains(&format!("{tag}.gltf")), "{e}");
                println!("{tag}: {e}");
            }
            other => panic!("{tag}: expected a buffer/parse error, got {other:?}"),
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mirrored_node_keeps_outward_trunk() {
    // A node with negative determinant must reverse the winding (glTF 2.0 §3.7.4).
    let dir = temp_dir("mirror");
    let (mut doc, _) = sample_gltf_parts();
    doc["nodes"][0]["scale"] = serde_json::json!([-1.0, 1.0, 1.0]);
    let path = dir.join("mirrored.gltf");
    std::fs::write(&path, serde_json::to_string(&doc).unwrap()).unwrap();
    let mesh = load_mesh(&path).unwrap();
    let v = signed_volume(&mesh.group("bark").unwrap().triangles);
    let exp = expected()["gltf"]["bark_signed_volume_m3"]
        .as_f64()
        .unwrap();
    assert!(rel_err(v, exp) < SAME_DATA_REL_TOL, "{v} vs {exp}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn hierarchy_cycles_and_shared_children_are_errors() {
    let dir = temp_dir("cycle");
    let (doc, _) = sample_gltf_parts();
    for (tag, children) in [("cycle", [0u64]), ("shared", [2u64])] {
        let mut d = doc.clone();
        d["nodes"][1]["children"] = serde_json::json!(children);
        let path = dir.join(format!("{tag}.gltf"));
        std::fs::write(&path, serde_json::to_string(&d).unwrap()).unwrap();
        let e = load_mesh(&path).unwrap_err();
        assert!(matches!(e, MeshError::Parse { .. }), "{tag}: {e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn missing_file_is_not_found() {
    let dir = temp_dir("missing");
    let path = dir.join("no_such_tree.obj");
    let e = load_mesh(&path).unwrap_err();
    assert!(matches!(e, MeshError::NotFound { .. }), "{e}");
    assert!(e.to_string().contains("no_such_tree.obj"), "{e}");
    assert_eq!(e.path(), path);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unsupported_extension_names_the_file() {
    let dir = temp_dir("ext");
    for name in ["tree.ply", "tree", "tree.obj.bak"] {
        let path = dir.join(name);
        std::fs::write(&path, "v 0 0 0\n").unwrap();
        let e = load_mesh(&path).unwrap_err();
        assert!(matches!(e, MeshError::UnsupportedExtension { .. }), "{e}");
        assert!(e.to_string().contains(name), "{e}");
    }
    // Extensions are case-insensitive.
    std::fs::copy(asset("small_tree.glb"), dir.join("TREE.GLB")).unwrap();
    assert_eq!(
        load_mesh(&dir.join("TREE.GLB")).unwrap().triangle_count(),
        228
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn garbage_and_truncated_files_are_errors_not_panics() {
    let dir = temp_dir("garbage");
    // Deterministic pseudo-random bytes (64-bit LCG, Knuth's MMIX constants).
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let noise: Vec<u8> = (0..4096)
        .map(|_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 56) as u8
        })
        .collect();
    for ext in ["gltf", "glb", "obj"] {
        let path = dir.join(format!("noise.{ext}"));
        std::fs::write(&path, &noise).unwrap();
        let e = load_mesh(&path).unwrap_err();
        assert!(matches!(e, MeshError::Parse { .. }), "{ext}: {e}");
        assert!(e.to_string().contains("noise."), "{e}");
    }
    // Every truncation of the GLB and of the glTF JSON is an error, never a panic.
    let glb = std::fs::read(asset("small_tree.glb")).unwrap();
    let gltf = std::fs::read(asset("small_tree.gltf")).unwrap();
    for (bytes, name) in [(&glb, "cut.glb"), (&gltf, "cut.gltf")] {
        let path = dir.join(name);
        let step = (bytes.len() / 97).max(1);
        for len in (0..bytes.len()).step_by(step) {
            std::fs::write(&path, &bytes[..len]).unwrap();
            assert!(load_mesh(&path).is_err(), "{name} cut at {len} loaded");
        }
    }
    // A GLB whose header lies about its length.
    let mut lying = glb.clone();
    lying[8..12].copy_from_slice(&3u32.to_le_bytes());
    std::fs::write(dir.join("lying.glb"), &lying).unwrap();
    assert!(matches!(
        load_mesh(&dir.join("lying.glb")),
        Err(MeshError::Parse { .. })
    ));
    // Text that is not an OBJ at all parses to nothing.
    std::fs::write(dir.join("prose.obj"), "Dear reader,\nthis is not a mesh.\n").unwrap();
    assert!(matches!(
        load_mesh(&dir.join("prose.obj")),
        Err(MeshError::Empty { .. })
    ));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn obj_parse_error_reports_the_line() {
    let dir = temp_dir("obj_line");
    let path = dir.join("broken.obj");
    std::fs::write(&path, "# broken\nv 0 0 0\nv 1 0 0\nv 0 one 0\nf 1 2 3\n").unwrap();
    let e = load_mesh(&path).unwrap_err();
    assert!(matches!(e, MeshError::Parse { line: Some(4), .. }), "{e}");
    assert!(e.to_string().contains("broken.obj:4:"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn empty_meshes_are_errors() {
    let dir = temp_dir("empty");
    let obj = dir.join("points_only.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\np 1 2 3\n").unwrap();
    let e = load_mesh(&obj).unwrap_err();
    assert!(matches!(e, MeshError::Empty { .. }), "{e}");
    assert!(e.to_string().contains("points_only.obj"), "{e}");

    let gltf = dir.join("no_meshes.gltf");
    std::fs::write(
        &gltf,
        r#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[]}],"scene":0}"#,
    )
    .unwrap();
    let e = load_mesh(&gltf).unwrap_err();
    assert!(matches!(e, MeshError::Empty { .. }), "{e}");

    // Only the LINES primitive of the sample: empty, and the message says what was skipped.
    let (mut doc, _) = sample_gltf_parts();
    doc["meshes"][0]["primitives"] = serde_json::json!([doc["meshes"][0]["primitives"][3]]);
    doc["nodes"][0]["children"] = serde_json::json!([1]);
    let lines = dir.join("lines_only.gltf");
    std::fs::write(&lines, serde_json::to_string(&doc).unwrap()).unwrap();
    let e = load_mesh(&lines).unwrap_err();
    assert!(matches!(e, MeshError::Empty { .. }), "{e}");
    assert!(e.to_string().contains("1 non-triangle"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn degenerate_triangles_are_kept_by_the_loader_and_counted_by_clean() {
    let dir = temp_dir("degenerate");
    let path = dir.join("degenerate.obj");
    std::fs::write(
        &path,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 2 0\nv nan 0 0\nv 1 1 0\n\
         g plate\nf 1 2 3\nf 2 4 3\n\
         g bad\nf 1 2 2\nf 1 6 4\nf 5 2 3\n",
    )
    .unwrap();
    let mut mesh = load_mesh(&path).unwrap();
    assert_eq!(
        mesh.triangle_count(),
        5,
        "loader keeps degenerate triangles"
    );
    let report = mesh.clean_triangles();
    assert_eq!(
        report,
        DegenerateReport {
            removed_degenerate: 2,
            removed_non_finite: 1
        }
    );
    assert_eq!(mesh.triangle_count(), 2);
    assert_eq!(mesh.group("plate").unwrap().triangles.len(), 2);
    assert!(mesh.group("bad").unwrap().triangles.is_empty());
    assert!((mesh.total_area() - 2.0).abs() < 1e-15);
    // The clean sample tree has nothing to remove.
    let mut tree = load_mesh(&asset("small_tree.gltf")).unwrap();
    assert_eq!(tree.clean_triangles(), DegenerateReport::default());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn obj_without_its_mtl_groups_by_object_name() {
    let dir = temp_dir("no_mtl");
    let path = dir.join("small_tree.obj");
    std::fs::copy(asset("small_tree.obj"), &path).unwrap();
    let mesh = load_mesh(&path).unwrap();
    let names: Vec<_> = mesh.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(names, ["small_tree"]);
    assert_eq!(mesh.triangle_count(), 228);
    assert!(
        mesh.warnings.iter().any(|w| w.contains("small_tree.mtl")),
        "{:?}",
        mesh.warnings
    );
    // Only `newmtl` names are read from the .mtl: a terse `Kd 0.3` (which makes tobj's own
    // MTL parser panic) is fine, and the groups follow the materials.
    std::fs::write(
        dir.join("small_tree.mtl"),
        "newmtl bark\nKd 0.3\n\nnewmtl leaf\n",
    )
    .unwrap();
    let mesh = load_mesh(&path).unwrap();
    let names: Vec<_> = mesh.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(names, ["bark", "leaf"]);
    // A malformed .mtl is an error naming the .mtl and its line.
    std::fs::write(
        dir.join("small_tree.mtl"),
        "newmtl bark\nKd 0.3 0.2 0.1\nnewmtl  \n",
    )
    .unwrap();
    let e = load_mesh(&path).unwrap_err();
    println!("{e}");
    assert!(
        matches!(&e, MeshError::Parse { path, line: Some(3), .. } if path.ends_with("small_tree.mtl")),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn rotation_and_uniform_scale_scale_area_by_its_square() {
    let mut mesh = load_mesh(&asset("small_tree.obj")).unwrap();
    let area = mesh.total_area();
    mesh.transform(DMat4::from_scale(DVec3::splat(3.0)) * DMat4::from_rotation_z(0.7));
    assert!(rel_err(mesh.total_area(), 9.0 * area) < 1e-12);
}
