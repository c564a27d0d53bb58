#!/usr/bin/env python3
"""Generates docs/guide/scene-format.md from the scene-format types' source and doc comments.

Usage (from the repository root):  python3 docs/tools/scene_format.py > docs/guide/scene-format.md

The types are the serde types a scene file is read into (`src/scene/desc.rs`, `desc/lidar.rs`, `desc/thermal.rs`, `desc/atmosphere.rs`, `desc/sensor.rs` and the types it
uses from other modules). `tests/docs.rs` parses the same sources independently and fails when a
field or variant is missing from the generated file, so re-run this script after changing them.
"""
import re
import sys

# (file, [types in the order they are documented]) — the order follows a scene file.
SOURCES = [
    ("src/scene/desc.rs", [
        "SceneDesc", "GridDesc", "BoundaryMode", "BandDesc", "OpticsDesc", "IlluminationDesc",
        "SunPositionDesc", "GeoreferenceDesc", "CrsDesc", "ObjectDesc", "GroundDesc", "TopographyDesc", "RasterDesc",
        "RasterFileDesc", "RasterFormat", "TreeDesc", "TreeStandDesc", "SpeciesDesc",
        "PlacementDesc", "TrunkDesc", "CrownDesc", "FoliageDesc", "TurbidPlotDesc",
        "FootprintDesc", "BuildingDesc", "RoofDesc", "WaterDesc", "MeshDesc", "MeshGroupOptics",
        "LeavesDesc", "LeafListDesc", "LandCoverDesc", "LandCoverClass", "RadiativeDesc", "Preset", "TurbidSubfaces",
    ]),
    ("src/scene/desc/lidar.rs", [
        "LidarDesc", "LidarPlatform", "PulsePattern", "PhotonCountingDesc", "LidarSampler",
        "LidarEstimator",
    ]),
    ("src/scene/desc/atmosphere.rs", ["AtmosphereDesc", "MoleculesDesc", "AerosolsDesc", "GasDesc"]),
    ("src/physics/phase.rs", ["FluidPhase"]),
    ("src/scene/desc/thermal.rs", ["ThermalDesc", "RunMode"]),
    ("src/scene/desc/sensor.rs", [
        "SensorDesc", "InstrumentDesc", "FrameCameraDesc", "AttitudeDesc",
    ]),
    ("src/geometry/crown.rs", ["CrownShape"]),
    ("src/physics/lad.rs", ["Lad", "LeafSpecular"]),
    ("src/physics/prospect.rs", ["ProspectModel"]),
    ("src/direction/mod.rs", ["DirectionParams", "ExactDirection", "OversampleRegion"]),
    ("src/scene/desc/lidar.rs", ["BeamProfile", "ReturnsMethod"]),
]

# Defaults that are not a literal in a `default = "fn"` function.
CONST_DEFAULTS = {
    "default_scene_x_bearing": "90 (x points east)",
    "default_beam_edge_intensity": "0.368",
    "default_depolarization": "0.0279",
    "yes": "true",
    "one": "1.0",
}
STRUCT_DEFAULTS = {  # fields of structs with `#[serde(default)]` on the struct
    ("DirectionParams", "count"): "100",
    ("DirectionParams", "cos_weighted"): "false",
    ("DirectionParams", "layers"): "None (automatic)",
    ("DirectionParams", "exact"): "[]",
    ("DirectionParams", "oversample"): "[]",
    ("DirectionParams", "fictive"): "[]",
    ("DirectionParams", "exact_solid_angle_sr"): "0.001",
    ("DirectionParams", "sectors"): "10",
}
UNITS = [  # field-name suffix → unit
    ("_ug_cm2", "µg cm⁻²"), ("_g_cm2", "g cm⁻²"), ("_w_m2_um", "W m⁻² µm⁻¹"), ("_m2", "m²"),
    ("_mrad", "mrad"), ("_km", "km"), ("_deg", "°"), ("_nm", "nm"), ("_ns", "ns"), ("_sr", "sr"), ("_hz", "Hz"),
    ("_hpa", "hPa"), ("_k", "K"), ("_j", "J"), ("_cm", "cm"), ("_mm", "mm"), ("_um", "µm"), ("temperature_c", "°C"), ("_s", "s"), ("_m", "m"),
]


def unit_of(name):
    for suf, u in UNITS:
        if name.endswith(suf):
            return u
    return "–"


def default_of(ty, attrs, fns, struct_default, owner, name):
    if (owner, name) in STRUCT_DEFAULTS:
        return STRUCT_DEFAULTS[(owner, name)]
    m = re.search(r'default\s*=\s*"(\w+)"', attrs)
    if m:
        f = m.group(1)
        if f in CONST_DEFAULTS:
            return CONST_DEFAULTS[f]
        return fns.get(f, f + "()")
    if re.search(r"\bdefault\b", attrs) or struct_default:
        if ty.startswith("Option<"):
            return "None"
        if ty.startswith("Vec<") or ty.startswith("BTreeMap"):
            return "[]"
        if ty == "bool":
            return "false"
        if ty in ("f64", "u32", "u64", "usize"):
            return "0"
        if ty == "String":
            return '""'
        if ty.startswith("(") or ty == "Xy":
            return "(0, …)"
        return "see the type"
    return "**required**"


def parse(path):
    """Returns {type: (doc, kind, struct_default, items)}; items are
    (variant_or_None, field_or_None, type, attrs, doc) for structs' fields and enums' variants
    and variant fields."""
    lines = open(path, encoding="utf-8").read().split("\n")
    fns = {}
    for i, l in enumerate(lines):
        m = re.match(r"(?:pub(?:\(crate\))? )?fn (\w+)\(\) -> \w+ \{", l)
        if m and i + 1 < len(lines):
            body = lines[i + 1].strip()
            if re.fullmatch(r"[-0-9.e_]+|true|false", body):
                fns[m.group(1)] = body
    types = {}
    doc, attrs = [], []
    i = 0
    while i < len(lines):
        l = lines[i]
        s = l.strip()
        if s.startswith("///") and not l.startswith(" "):
            doc.append(s[3:].strip())
        elif s.startswith("#[") and not l.startswith(" "):
            attrs.append(s)
        else:
            m = re.match(r"pub (struct|enum) (\w+)\s*\{", l)
            if m and any("Deserialize" in a for a in attrs):
                kind, name = m.groups()
                struct_default = any(re.search(r"serde\([^)]*\bdefault\b", a) for a in attrs)
                items, j = [], i + 1
                fdoc, fattrs, variant = [], [], None
                while not lines[j].startswith("}"):
                    t = lines[j]
                    ts = t.strip()
                    ind = len(t) - len(t.lstrip())
                    if ts.startswith("///"):
                        fdoc.append(ts[3:].strip())
                    elif ts.startswith("#["):
                        fattrs.append(ts)
                    elif kind == "struct" and ind == 4:
                        fm = re.match(r"pub (\w+): (.+),$", ts)
                        if fm:
                            items.append((None, fm.group(1), fm.group(2), " ".join(fattrs), " ".join(fdoc)))
                        fdoc, fattrs = [], []
                    elif kind == "enum" and ind == 4:
                        vm = re.match(r"([A-Z]\w*)\s*(\{|\((.*)\),|,)?$", ts)
                        if vm:
                            variant = vm.group(1)
                            payload = vm.group(3) if vm.group(2) and vm.group(2).startswith("(") else ("{…}" if vm.group(2) == "{" else "")
                            items.append((variant, None, payload, " ".join(fattrs), " ".join(fdoc)))
                        fdoc, fattrs = [], []
                    elif kind == "enum" and ind == 8:
                        fm = re.match(r"(\w+): (.+),$", ts)
                        if fm:
                            items.append((variant, fm.group(1), fm.group(2), " ".join(fattrs), " ".join(fdoc)))
                        fdoc, fattrs = [], []
                    j += 1
                types[name] = (" ".join(doc), kind, struct_default, items, fns)
                i = j
            doc, attrs = [], []
        i += 1
    return types


def cell(s):
    s = re.sub(r"\[`([^`]+)`\](?!\()", r"`\1`", s)  # rustdoc intra-doc links
    s = re.sub(r"\[`([^`]+)`\]\((?:crate|super|self)::[\w:]+\)", r"`\1`", s)  # with a path
    return s.replace("|", "\\|").replace("\n", " ")


def short_type(t):
    t = t.replace("crate::direction::", "").replace("crate::lidar::pulse::", "")
    t = t.replace("crate::lidar::returns::", "").replace("crate::physics::lad::", "")
    t = t.replace("serde::de::IgnoredAny", "(anything)")
    return t


def main():
    out = sys.stdout
    out.write(HEADER)
    for path, names in SOURCES:
        types = parse(path)
        for name in names:
            if name not in types:
                sys.exit(f"{path}: type {name} not found")
            doc, kind, sd, items, fns = types[name]
            alias = {"Lad": " (`lad` of a `Turbid` optics entry; `LadDesc` in desc.rs)"}.get(name, "")
            out.write(f"\n### {name}{alias}\n\n{cell(doc)}\n\n")
            if kind == "struct":
                out.write("| field | type | unit | default | meaning |\n|---|---|---|---|---|\n")
                for _, f, ty, at, d in items:
                    serde_name = re.search(r'rename\s*=\s*"(\w+)"', at)
                    f = serde_name.group(1) if serde_name else f
                    out.write(f"| `{f}` | `{cell(short_type(ty))}` | {unit_of(f)} | "
                              f"{cell(default_of(ty, at, fns, sd, name, f))} | {cell(d)} |\n")
            else:
                out.write("| variant / field | type | unit | default | meaning |\n|---|---|---|---|---|\n")
                for v, f, ty, at, d in items:
                    if f is None:
                        ren = re.search(r'rename\s*=\s*"(\w+)"', at)
                        shown = f"`{ren.group(1)}` (or `{v}`)" if ren else f"`{v}`"
                        dflt = "default variant" if "#[default]" in at else ""
                        tyc = f"`{cell(short_type(ty))}`" if ty else "–"
                        out.write(f"| {shown} | {tyc} | | {dflt} | {cell(d)} |\n")
                    else:
                        out.write(f"| ↳ `{f}` | `{cell(short_type(ty))}` | {unit_of(f)} | "
                                  f"{cell(default_of(ty, at, fns, False, name, f))} | {cell(d)} |\n")
    out.write(FOOTER)


HEADER = """# Scene format reference (RON, version 1)

<!-- Generated by `python3 docs/tools/scene_format.py > docs/guide/scene-format.md` from the doc
comments of the scene-format types; `cargo test --test docs` checks that every field and variant
of those types appears here. Edit the doc comments in the code, not this file. -->

A scene is one [RON](https://github.com/ron-rs/ron) file read into `SceneDesc`
(`src/scene/desc.rs`). Conventions:

* **Units are SI and in the field name**: `_m` metres, `_deg` degrees, `_nm` nanometres,
  `_m2` m², `_sr` steradians, `_ns` nanoseconds, `_j` joules; reflectances, transmittances and
  albedos are dimensionless in [0, 1]. Per-band lists have one value per entry of `bands`, in
  order.
* **Angles**: zenith from +z (up); azimuth anticlockwise from +x (DART's convention). The sun's
  angles are those of the ground→sun direction; a view direction is the ground→sensor
  direction. Directions in `directions` are *propagation* directions (zenith < 90° goes up).
* **Space**: the scene spans `[0, X] × [0, Y]` with z up; relative paths (meshes, rasters, leaf
  lists, SRF files) are resolved from the scene file's folder.
* **Strictness**: every struct denies unknown fields; a misspelt field is an error with file,
  line, column and field. Optional fields (`Option<…>`) take a bare value or `Some(…)`; a field
  whose default is **required** must be present. Enum values are written by variant name:
  `Spherical`, `Lai(3.0)`, `Gable(ridge_height_m: 2.5)`.
* **Validation** (`src/scene/validate.rs`, run by `lumenscape check` and before every run): one
  value per band in every per-band list; reflectance + transmittance ≤ 1; optics names refer to
  entries of `optics` of the right kind (a crown or plot needs a `Turbid` entry, a facet a
  surface entry, a `Turbid` entry a `BiLambertian` or `ProspectLeaf` leaf); band names unique
  and non-empty; positive sizes; the scene size a whole number of cells; `subcells` in 1..=16;
  RPV and Hapke parameters in their ranges (e.g. `k` in [0, 10], Hapke `roughness_deg` in
  [0, 60]); simple (non-self-crossing) polygons; objects inside the scene for `Isolated`
  boundaries; sun given either by both
  angles or by `sun_position`; `image_oversampling` in 1..=64 with at most 2²⁶ pixels per image;
  an `atmosphere` needs a
  `Repetitive` grid, `skyl` 0 or absent, no `lidars`, `--solver monte-carlo` (flux tracking
  through it is not implemented yet), per-band lists of one value per band, optical depths in
  [0, 100], strictly increasing layer altitudes below the TOA and at least one constituent;
  sensor cameras above the ground (z > 0) with a field of view of at most 170° and at most 2²⁴
  pixels. Limits
  that refuse absurd values before any allocation: at most 2³² − 1 grid cells; `Lai` and
  `LeafAreaDensity` at most 100 (and the density a `LeafArea` implies); trunk and disk polygons
  of 3 to 1000 sides; at most 10⁶ trees per random stand; ground rasters of at most 2²⁸ nodes;
  exact (view) directions with zenith in [0, 90]; airborne LiDAR aim points within 100 scene
  sizes; at most 10⁷ pulses per LiDAR; an `optics` name defined twice is an error (RON would
  keep the last). Each error names the file, line, column and field.

Example: `assets/scenes/default.ron` uses every object kind; the other files of
`assets/scenes/` are one example per feature.

## Types
"""

FOOTER = """
## Defaults not written in the types

* `radiative` knobs left `None` take the preset's value (`Preview`, `Default`, `Reference`;
  `--preset` on the command line overrides the scene's preset). The values in use are written
  to `summary.json` under `settings.tracking`.
* `directions` absent: 100 regular directions, 10 angular sectors, no exact view direction, so
  no `images/`. Add `exact: [(zenith_deg: 0.0, azimuth_deg: 0.0, label: Some("nadir"))]` for a
  nadir BRF in `brf.csv` (kind `exact`) and a nadir image.
* `atmosphere` absent: no atmosphere work at all; the illumination is at the bottom of the
  atmosphere. Present, e.g. `atmosphere: (molecules: (), aerosols: (tau_reference: 0.2,
  angstrom_exponent: 1.3, ssa: [0.9], phase: HenyeyGreenstein(g: 0.7)))`: the irradiance is at
  the top of the atmosphere, Rayleigh optical depths follow Bodhaine et al. (1999) at each band's
  wavelength, and `summary.json` gains a `toa` block (docs/guide/products.md).
* `LidarDesc::photons_per_pulse` absent: 48 beam rays for a pulse whose first order the column
  quadrature scores, 72 otherwise (`DEFAULT_LIDAR_PHOTONS`, `DEFAULT_LIDAR_PHOTONS_PER_RAY`).
"""

if __name__ == "__main__":
    main()
