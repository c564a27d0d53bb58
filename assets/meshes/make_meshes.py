#!/usr/bin/env python3
"""Generate the small sample tree meshes used by lumenscape's mesh-import tests.

Run from anywhere:  python3 assets/meshes/make_meshes.py
Pure Python standard library; deterministic (fixed seed, Mersenne Twister `random.Random`,
whose `random()` sequence is stable across Python versions). Rewrites, next to this script:

  small_tree.gltf           glTF 2.0, JSON with one embedded base64 buffer
                            (data:application/octet-stream;base64,...).
  small_tree.glb            the same asset as binary glTF (buffer in the GLB BIN chunk).
  small_tree.obj/.mtl       the same tree as Wavefront OBJ, grouped by `usemtl bark` / `usemtl leaf`.
  small_tree_expected.json  triangle counts, areas, bounding boxes and the trunk's signed volume
                            per format, computed here from exactly the numbers written.

The tree (metres): a trunk, a closed regular 8-sided prism of circumradius 0.15 and height 2.0
(material "bark"), and a crown of 200 small random leaf triangles whose centres lie in an
ellipsoid of horizontal semi-axis 1.5 and vertical semi-axis 1.875 centred 3.5 above the
trunk base (material "leaf").

Coordinate conventions
* glTF is y-up (glTF 2.0 spec, section 3.4): the tree grows along +y. The node hierarchy is
    node 0 "small_tree"  translation (2, 0, -1)            children [1, 2]
    node 1 "trunk"       no transform                       mesh "trunk"
    node 2 "crown"       translation (0, 3.5, 0), scale (1, 1.25, 1)   mesh "crown"
  so an importer must accumulate the parent translation to place the crown; the crown mesh
  itself is a sphere of leaves of radius 1.5 in its local frame, stretched to the ellipsoid
  by node 2's scale.
  Mesh "trunk" has four primitives: the sides as an indexed TRIANGLE_STRIP (u16 indices),
  the top cap as a non-indexed TRIANGLE_FAN, the bottom cap as a TRIANGLE_FAN with u8 indices,
  and the trunk axis as a LINES primitive that a triangle importer must skip (and count).
  Mesh "crown" is one indexed TRIANGLES primitive (u32 indices). Front faces are
  counter-clockwise and the trunk's faces point outward.
* OBJ is z-up (the lumenscape scene frame): the OBJ holds the glTF scene's vertices after the
  node transforms and after the y-up -> z-up rotation (x, y, z) -> (x, -z, y), i.e. +90 deg
  about +x. Its sides are quads and its caps octagons, which an importer triangulates (fan), and
  it has one `l` line (the trunk axis) that a triangle importer skips.

Precision: glTF stores f32 positions, and an OBJ reader may parse into f32, so every vertex is
rounded to f32 *before* it is written and the expected numbers are computed in f64 from those
rounded values (with the node transforms applied in f64). An importer working in f64 should
therefore reproduce the expected numbers to f64 rounding (~1e-15 relative); the tests use
1e-12 relative. The glTF and OBJ numbers differ from each other by the f32 rounding of the
transformed OBJ vertices (~1e-7 relative), which cross-format tests must allow for.
"""

import base64
import json
import math
import os
import random
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
SEED = 20240521

TRUNK_RADIUS = 0.15
TRUNK_HEIGHT = 2.0
N_SIDES = 8
CROWN_RADIUS = 1.5  # local sphere radius of the crown mesh
CROWN_NODE_TRANSLATION = (0.0, 3.5, 0.0)
CROWN_NODE_SCALE = (1.0, 1.25, 1.0)
ROOT_TRANSLATION = (2.0, 0.0, -1.0)
N_LEAVES = 200
LEAF_SIDE = 0.1  # edge length of an (approximately) equilateral leaf triangle


def f32(x):
    """Round a float to the nearest IEEE binary32 value (returned as a Python float)."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def v32(v):
    return tuple(f32(c) for c in v)


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def norm(a):
    return math.sqrt(dot(a, a))


def tri_area(t):
    return 0.5 * norm(cross(sub(t[1], t[0]), sub(t[2], t[0])))


def signed_volume(tris):
    """Divergence theorem: V = 1/6 sum a.(b x c); positive for an outward-facing closed mesh."""
    return sum(dot(a, cross(b, c)) for a, b, c in tris) / 6.0


def bbox(tris):
    pts = [p for t in tris for p in t]
    return (
        [min(p[i] for p in pts) for i in range(3)],
        [max(p[i] for p in pts) for i in range(3)],
    )


# ---------------------------------------------------------------- geometry (glTF local frames)


def trunk_rings():
    """Bottom and top rings (y-up, local frame of node "trunk"), angle increasing from +x to +z."""
    bottom, top = [], []
    for k in range(N_SIDES):
        th = 2.0 * math.pi * k / N_SIDES
        x, z = TRUNK_RADIUS * math.cos(th), TRUNK_RADIUS * math.sin(th)
        bottom.append(v32((x, 0.0, z)))
        top.append(v32((x, TRUNK_HEIGHT, z)))
    return bottom, top


def random_unit(rng):
    while True:
        v = (2 * rng.random() - 1, 2 * rng.random() - 1, 2 * rng.random() - 1)
        n = norm(v)
        if 1e-3 < n <= 1.0:
            return (v[0] / n, v[1] / n, v[2] / n)


def leaves():
    """N_LEAVES triangles (y-up, local frame of node "crown"), centres uniform in a sphere."""
    rng = random.Random(SEED)
    out = []
    while len(out) < N_LEAVES:
        c = (2 * rng.random() - 1, 2 * rng.random() - 1, 2 * rng.random() - 1)
        if dot(c, c) > 1.0:
            continue
        c = tuple(CROWN_RADIUS * x for x in c)
        n = random_unit(rng)
        # orthonormal basis (u, w) of the leaf plane
        helper = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
        u = cross(n, helper)
        u = tuple(x / norm(u) for x in u)
        w = cross(n, u)
        phi = 2.0 * math.pi * rng.random()
        r = LEAF_SIDE / math.sqrt(3.0)  # circumradius of the equilateral triangle
        tri = []
        for k in range(3):
            a = phi + 2.0 * math.pi * k / 3.0
            ca, sa = math.cos(a), math.sin(a)
            tri.append(v32(tuple(c[i] + r * (ca * u[i] + sa * w[i]) for i in range(3))))
        out.append(tuple(tri))
    return out


# ------------------------------------------------- glTF primitive expansion (spec section 3.7.2.1)


def expand(mode, verts):
    """Triangles of a primitive from its vertex sequence (after indexing), glTF conventions."""
    n = len(verts)
    if mode == 4:  # TRIANGLES
        return [(verts[3 * i], verts[3 * i + 1], verts[3 * i + 2]) for i in range(n // 3)]
    if mode == 5:  # TRIANGLE_STRIP: p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}}
        return [(verts[i], verts[i + 1 + i % 2], verts[i + 2 - i % 2]) for i in range(n - 2)]
    if mode == 6:  # TRIANGLE_FAN: p_i = {v_{i+1}, v_{i+2}, v_0}
        return [(verts[i + 1], verts[i + 2], verts[0]) for i in range(n - 2)]
    return []  # points / lines: no triangles


def world_matrix_apply(p, scale, translation):
    """Apply T(translation) * S(scale) in f64 (translation already summed through the hierarchy)."""
    return tuple(scale[i] * p[i] + translation[i] for i in range(3))


def y_up_to_z_up(p):
    """+90 deg about +x: (x, y, z) -> (x, -z, y)."""
    return (p[0], -p[2], p[1])


# ------------------------------------------------------------------------------- build buffers


class BufferBuilder:
    def __init__(self):
        self.data = bytearray()
        self.views = []
        self.accessors = []

    def _align(self):
        while len(self.data) % 4:
            self.data.append(0)

    def add(self, payload, target, accessor):
        self._align()
        offset = len(self.data)
        self.data += payload
        self.views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(payload), "target": target})
        accessor = dict(accessor, bufferView=len(self.views) - 1)
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def positions(self, pts):
        payload = b"".join(struct.pack("<3f", *p) for p in pts)
        lo = [min(p[i] for p in pts) for i in range(3)]
        hi = [max(p[i] for p in pts) for i in range(3)]
        return self.add(payload, 34962, {"componentType": 5126, "count": len(pts), "type": "VEC3", "min": lo, "max": hi})

    def indices(self, idx, component):
        fmt, size = {5121: ("B", 1), 5123: ("H", 2), 5125: ("I", 4)}[component]
        payload = struct.pack("<%d%s" % (len(idx), fmt), *idx)
        return self.add(payload, 34963, {"componentType": component, "count": len(idx), "type": "SCALAR"})


def build():
    bottom, top = trunk_rings()
    leaf_tris = leaves()
    buf = BufferBuilder()

    # trunk sides: 16 ring vertices (bottom 0..7, top 8..15), strip b0 t0 b1 t1 ... b7 t7 b0 t0
    side_pos = bottom + top
    strip = []
    for k in list(range(N_SIDES)) + [0]:
        strip += [k, N_SIDES + k]
    a_side_pos = buf.positions(side_pos)
    a_side_idx = buf.indices(strip, 5123)
    # top cap: normal +y needs angle decreasing (x -> -z), non-indexed fan
    top_fan = [top[0]] + [top[k] for k in range(N_SIDES - 1, 0, -1)]
    a_top_pos = buf.positions(top_fan)
    # bottom cap: normal -y needs angle increasing (x -> +z), u8-indexed fan
    a_bot_pos = buf.positions(bottom)
    a_bot_idx = buf.indices(list(range(N_SIDES)), 5121)
    # trunk axis as LINES (to be skipped by triangle importers)
    axis = [v32((0.0, 0.0, 0.0)), v32((0.0, TRUNK_HEIGHT, 0.0))]
    a_axis_pos = buf.positions(axis)
    # crown leaves: 600 vertices, u32 indices
    leaf_pos = [p for t in leaf_tris for p in t]
    a_leaf_pos = buf.positions(leaf_pos)
    a_leaf_idx = buf.indices(list(range(len(leaf_pos))), 5125)
    while len(buf.data) % 4:
        buf.data.append(0)

    doc = {
        "asset": {"version": "2.0", "generator": "lumenscape assets/meshes/make_meshes.py"},
        "scene": 0,
        "scenes": [{"name": "scene", "nodes": [0]}],
        "nodes": [
            {"name": "small_tree", "translation": list(ROOT_TRANSLATION), "children": [1, 2]},
            {"name": "trunk", "mesh": 0},
            {
                "name": "crown",
                "mesh": 1,
                "translation": list(CROWN_NODE_TRANSLATION),
                "scale": list(CROWN_NODE_SCALE),
            },
        ],
        "materials": [{"name": "bark"}, {"name": "leaf", "doubleSided": True}],
        "meshes": [
            {
                "name": "trunk",
                "primitives": [
                    {"attributes": {"POSITION": a_side_pos}, "indices": a_side_idx, "mode": 5, "material": 0},
                    {"attributes": {"POSITION": a_top_pos}, "mode": 6, "material": 0},
                    {"attributes": {"POSITION": a_bot_pos}, "indices": a_bot_idx, "mode": 6, "material": 0},
                    {"attributes": {"POSITION": a_axis_pos}, "mode": 1},
                ],
            },
            {
                "name": "crown",
                "primitives": [
                    {"attributes": {"POSITION": a_leaf_pos}, "indices": a_leaf_idx, "mode": 4, "material": 1}
                ],
            },
        ],
        "accessors": buf.accessors,
        "bufferViews": buf.views,
        "buffers": [{"byteLength": len(buf.data)}],
    }

    # ---- triangles exactly as an importer must produce them (f64 transforms of f32 data)
    root_t = ROOT_TRANSLATION
    crown_t = tuple(root_t[i] + CROWN_NODE_TRANSLATION[i] for i in range(3))
    one = (1.0, 1.0, 1.0)
    bark_local = (
        expand(5, [side_pos[i] for i in strip])
        + expand(6, top_fan)
        + expand(6, [bottom[i] for i in range(N_SIDES)])
    )
    bark = [tuple(world_matrix_apply(p, one, root_t) for p in t) for t in bark_local]
    leaf = [tuple(world_matrix_apply(p, CROWN_NODE_SCALE, crown_t) for p in t) for t in leaf_tris]
    skipped = 1  # the LINES primitive
    return doc, bytes(buf.data), bark, leaf, skipped, axis


def write_gltf(doc, data):
    d = json.loads(json.dumps(doc))
    d["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode("ascii")
    with open(os.path.join(HERE, "small_tree.gltf"), "w", newline="\n") as f:
        json.dump(d, f, indent=1)
        f.write("\n")


def write_glb(doc, data):
    js = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    js += b" " * ((4 - len(js) % 4) % 4)
    bin_ = data + b"\0" * ((4 - len(data) % 4) % 4)
    total = 12 + 8 + len(js) + 8 + len(bin_)
    out = struct.pack("<4sII", b"glTF", 2, total)
    out += struct.pack("<I4s", len(js), b"JSON") + js
    out += struct.pack("<I4s", len(bin_), b"BIN\0") + bin_
    with open(os.path.join(HERE, "small_tree.glb"), "wb") as f:
        f.write(out)


def write_obj(bark_world_yup, leaf_world_yup, axis_local):
    """OBJ in z-up; returns the triangles an importer must produce (fan triangulation)."""
    # unique vertices, in first-use order, of the world-space (y-up) glTF triangles
    bottom, top = trunk_rings()
    root_t = ROOT_TRANSLATION

    def obj_vertex(p_local, scale, t):
        return v32(y_up_to_z_up(world_matrix_apply(p_local, scale, t)))

    one = (1.0, 1.0, 1.0)
    ring_b = [obj_vertex(p, one, root_t) for p in bottom]
    ring_t = [obj_vertex(p, one, root_t) for p in top]
    axis = [obj_vertex(p, one, root_t) for p in axis_local]
    crown_t = tuple(root_t[i] + CROWN_NODE_TRANSLATION[i] for i in range(3))
    leaf_local = leaves()
    leaf_v = [[obj_vertex(p, CROWN_NODE_SCALE, crown_t) for p in t] for t in leaf_local]

    verts = ring_b + ring_t + axis + [p for t in leaf_v for p in t]
    n = N_SIDES
    lines = [
        "# small_tree.obj: lumenscape sample tree, z-up, metres.",
        "# Generated by assets/meshes/make_meshes.py; do not edit by hand.",
        "mtllib small_tree.mtl",
        "o small_tree",
    ]
    for p in verts:
        lines.append("v %r %r %r" % p)
    bark_faces = []
    # In z-up the angle of the ring now increases from +x towards -y (clockwise seen from
    # above), so an outward side quad is (b_{k+1}, b_k, t_k, t_{k+1}); OBJ indices are 1-based.
    for k in range(n):
        k1 = (k + 1) % n
        bark_faces.append([k1, k, n + k, n + k1])
    # top cap (normal +z): angle decreasing in the y-up frame == counter-clockwise seen from +z
    bark_faces.append([n + k for k in [0] + list(range(n - 1, 0, -1))])
    # bottom cap (normal -z)
    bark_faces.append(list(range(n)))
    lines.append("usemtl bark")
    for f in bark_faces:
        lines.append("f " + " ".join(str(i + 1) for i in f))
    lines.append("# trunk axis: a line element, skipped by triangle importers")
    lines.append("l %d %d" % (2 * n + 1, 2 * n + 2))
    lines.append("usemtl leaf")
    base = 2 * n + 2
    for i in range(len(leaf_v)):
        lines.append("f %d %d %d" % (base + 3 * i + 1, base + 3 * i + 2, base + 3 * i + 3))
    with open(os.path.join(HERE, "small_tree.obj"), "w", newline="\n") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(HERE, "small_tree.mtl"), "w", newline="\n") as f:
        f.write(
            "# small_tree.mtl: generated by assets/meshes/make_meshes.py\n"
            "newmtl bark\nKd 0.35 0.25 0.15\n\n"
            "newmtl leaf\nKd 0.10 0.50 0.10\n"
        )

    def fan(face):
        return [(verts[face[0]], verts[face[i]], verts[face[i + 1]]) for i in range(1, len(face) - 1)]

    bark = [t for f in bark_faces for t in fan(f)]
    leaf = [tuple(t) for t in leaf_v]
    return bark, leaf


def summary(bark, leaf, skipped, coords):
    def group(name, tris):
        lo, hi = bbox(tris)
        return {
            "name": name,
            "triangles": len(tris),
            "area_m2": sum(tri_area(t) for t in tris),
            "bbox_min": lo,
            "bbox_max": hi,
        }

    return {
        "coordinates": coords,
        "skipped_non_triangle_primitives": skipped,
        "groups": [group("bark", bark), group("leaf", leaf)],
        "bark_signed_volume_m3": signed_volume(bark),
    }


def main():
    doc, data, bark, leaf, skipped, axis = build()
    write_gltf(doc, data)
    write_glb(doc, data)
    obj_bark, obj_leaf = write_obj(bark, leaf, axis)
    expected = {
        "about": (
            "Expected import results for small_tree.{gltf,glb,obj}, computed by make_meshes.py in "
            "f64 from the f32-rounded vertices it wrote (glTF: after the node hierarchy, still y-up; "
            "OBJ: z-up). Tolerance for an f64 importer: 1e-12 relative (only f64 rounding differs). "
            "glTF vs OBJ differ by the f32 rounding of the OBJ's transformed vertices (~1e-7)."
        ),
        "tolerance_relative": 1e-12,
        "analytic": {
            "trunk_volume_m3": 2.0 * math.sqrt(2.0) * TRUNK_RADIUS**2 * TRUNK_HEIGHT,
            "trunk_lateral_plus_caps_area_m2": N_SIDES * 2 * TRUNK_RADIUS * math.sin(math.pi / N_SIDES) * TRUNK_HEIGHT
            + 2 * 2.0 * math.sqrt(2.0) * TRUNK_RADIUS**2,
            "crown_centre_gltf": [ROOT_TRANSLATION[i] + CROWN_NODE_TRANSLATION[i] for i in range(3)],
            "crown_semi_axes_gltf": [CROWN_RADIUS * s for s in CROWN_NODE_SCALE],
        },
        "gltf": summary(bark, leaf, skipped, "y-up (glTF), node transforms applied"),
        "obj": summary(obj_bark, obj_leaf, 1, "z-up"),
    }
    with open(os.path.join(HERE, "small_tree_expected.json"), "w", newline="\n") as f:
        json.dump(expected, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
