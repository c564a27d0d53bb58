#!/usr/bin/env python3
"""Writes the inputs of assets/scenes/landcover.ron (issue #37): a land-cover classification
GeoTIFF and a DEM GeoTIFF in WGS 84 / UTM zone 31N (EPSG:32631), standard library only.

Usage (from the repository root):  python3 assets/landcover/make_landcover.py

The scene's origin (x = y = 0) lies at E 500000, N 4800000 and spans 40 m × 40 m.

* `classes.tif`: 12 × 12 pixels of 4 m, uint16 class codes, from (E 499998, N 4800042) (2 m
  west and north of the scene, so that the scene's edges cut pixels): 0 bare soil (a track
  across the scene), 1 grass, 2 crop (rows of a field), 3 forest (a seeded pine stand),
  4 water (a pond), 5 buildings (two blocks). GDAL_NODATA 65535 marks a corner outside the
  scene.
* `dem.tif`: 26 × 26 pixels of 2 m, float32 elevations (m), from (E 499994, N 4800046): a
  plane rising 2 % to the north-east and a 2 m hill, PixelIsArea (values at pixel centres).

The files are written by hand (TIFF 6.0 baseline, one uncompressed strip; OGC GeoTIFF 1.1 tags
ModelPixelScaleTag 33550, ModelTiepointTag 33922, GeoKeyDirectoryTag 34735 with
GTModelTypeGeoKey 1024 = 1, GTRasterTypeGeoKey 1025 = 1, ProjectedCRSGeoKey 3072 = 32631;
GDAL_NODATA 42113), so that they come from a writer independent of lumenscape's.
"""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def geotiff(path, nx, ny, values, sample, tie, pixel, epsg, nodata=None):
    """Writes a single-band GeoTIFF; `values` row by row from the top, `sample` 'H' or 'f'."""
    bits, fmt = {"H": (16, 1), "f": (32, 3)}[sample]
    data = struct.pack("<%d%s" % (len(values), sample), *values)
    tags = [
        (256, 4, [nx]), (257, 4, [ny]), (258, 3, [bits]), (259, 3, [1]), (262, 3, [1]),
        (273, 4, [8]), (277, 3, [1]), (278, 4, [ny]), (279, 4, [len(data)]), (284, 3, [1]),
        (339, 3, [fmt]),
        (33550, 12, [pixel, pixel, 0.0]),
        (33922, 12, [0.0, 0.0, 0.0, tie[0], tie[1], 0.0]),
        (34735, 3, [1, 1, 1, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, epsg]),
    ]
    if nodata is not None:
        tags.append((42113, 2, ("%s\0" % nodata).encode()))
    code = {2: "s", 3: "H", 4: "I", 12: "d"}
    out = bytearray(b"II*\0" + struct.pack("<I", 0)) + data
    entries = []
    for tag, typ, val in tags:
        raw = val if typ == 2 else struct.pack("<%d%s" % (len(val), code[typ]), *val)
        count = len(raw) if typ == 2 else len(val)
        if len(raw) <= 4:
            field = raw.ljust(4, b"\0")
        else:
            if len(out) % 2:
                out += b"\0"
            field = struct.pack("<I", len(out))
            out += raw
        entries.append(struct.pack("<HHI", tag, typ, count) + field)
    if len(out) % 2:
        out += b"\0"
    struct.pack_into("<I", out, 4, len(out))
    out += struct.pack("<H", len(entries)) + b"".join(entries) + struct.pack("<I", 0)
    with open(path, "wb") as f:
        f.write(out)


def cls(c, r):
    """Class code of pixel (column c, row r), row 0 at the north."""
    x, y = -2 + 4 * c + 2, 42 - 4 * r - 2  # pixel centre, scene metres
    if c == 11 and r == 11:
        return 65535  # no-data (outside the scene)
    if abs(y - 0.6 * x - 4) < 2.5:
        return 0  # a track
    if (x - 30) ** 2 + (y - 10) ** 2 < 40:
        return 4  # pond
    if 6 <= x <= 14 and 26 <= y <= 34 or 30 <= x <= 34 and 30 <= y <= 38:
        return 5  # buildings
    if x < 16 and y < 20:
        return 3  # forest
    if x >= 20 and y >= 24:
        return 2  # field
    return 1  # grass


def altitude(e, n):
    x, y = e - 500000.0, n - 4800000.0
    z = 100.0 + 0.02 * (x + y) + 2.0 * math.exp(-((x - 12) ** 2 + (y - 30) ** 2) / 60.0)
    return round(z * 256) / 256  # exact in float32 and in text


def main():
    geotiff(os.path.join(HERE, "classes.tif"), 12, 12,
            [cls(c, r) for r in range(12) for c in range(12)], "H",
            (499998.0, 4800042.0), 4.0, 32631, nodata=65535)
    dem = [altitude(499994.0 + 2 * c + 1, 4800046.0 - 2 * r - 1)
           for r in range(26) for c in range(26)]
    geotiff(os.path.join(HERE, "dem.tif"), 26, 26, dem, "f", (499994.0, 4800046.0), 2.0, 32631)


if __name__ == "__main__":
    main()
