#!/usr/bin/env bash
# Product identity of two builds, for refactors that must not change any result.
#
#   bash benches/identity.sh BIN_A BIN_B [SCENES_DIR]
#
# BIN_A and BIN_B are two `lumenscape` executables (copy `target/release/lumenscape` aside
# between builds). Both run every scene of SCENES_DIR (default assets/scenes, read by both from
# the same copy) and the extra settings below (Monte Carlo, the reference preset, the
# double-precision walk, the AVX2 cap with image oversampling, a Maket run); then every product
# file is compared byte for byte, except the run times, rates, paths and version in
# summary.json / lidar.json. Prints "identical" and exits 0, or lists what differs and exits 1.
# About 30 s on 2 cores.
set -uo pipefail
[ $# -ge 2 ] || { echo "usage: bash benches/identity.sh BIN_A BIN_B [SCENES_DIR]" >&2; exit 2; }
A=$(realpath "$1"); B=$(realpath "$2")
SCENES=$(realpath "${3:-$(dirname "$0")/../assets/scenes}")
WORK=$(mktemp -d); trap 'rm -rf "$WORK"' EXIT
# The scenes' relative paths (meshes, rasters) resolve against their own folder.
cp -r "$SCENES" "$WORK/scenes"

run_all() { # BIN OUT
  local bin=$1 out=$2 s n
  mkdir -p "$out"
  for s in "$WORK"/scenes/*.ron; do
    n=$(basename "$s" .ron)
    "$bin" run "$s" --out "$out/$n" --quiet > /dev/null 2>&1 && echo "$n 0" >> "$out/rc.txt" || echo "$n $?" >> "$out/rc.txt"
  done
  local t="$WORK/scenes/turbid_layer.ron"
  "$bin" run "$t" --out "$out/mc_turbid" --quiet --solver monte-carlo --photons 200000 > /dev/null 2>&1; echo "mc $?" >> "$out/rc.txt"
  "$bin" run "$t" --out "$out/ref_turbid" --quiet --preset reference > /dev/null 2>&1; echo "ref $?" >> "$out/rc.txt"
  "$bin" run "$t" --out "$out/avx2_turbid" --quiet --isa avx2 --image-oversampling 2 > /dev/null 2>&1; echo "avx2 $?" >> "$out/rc.txt"
  "$bin" run "$WORK/scenes/forest_dem.ron" --out "$out/f64_forest" --quiet --batch-f64 > /dev/null 2>&1; echo "f64 $?" >> "$out/rc.txt"
  "$bin" run "$WORK/scenes/disk_canopy.ron" --out "$out/mc_disk" --quiet --solver monte-carlo --photons 100000 --sampler alias > /dev/null 2>&1; echo "mcdisk $?" >> "$out/rc.txt"
  "$bin" run "$WORK/scenes/default.ron" --out "$out/mc_default" --quiet --solver monte-carlo --photons 100000 > /dev/null 2>&1; echo "mcdef $?" >> "$out/rc.txt"
  "$bin" maket "$WORK/scenes/urban.ron" --out "$out/maket_urban" --quiet > /dev/null 2>&1; echo "maket $?" >> "$out/rc.txt"
}

run_all "$A" "$WORK/a"
run_all "$B" "$WORK/b"
status=0
diff -r -q -x summary.json -x lidar.json "$WORK/a" "$WORK/b" || status=1
strip() { grep -v '_seconds"\|"seconds"\|_per_second\|"wall\|"version"' "$1" | sed "s#$2#X#g"; }
while IFS= read -r f; do
  if ! diff <(strip "$WORK/a/$f" "$WORK/a") <(strip "$WORK/b/$f" "$WORK/b") > /dev/null; then
    echo "differs: $f"
    status=1
  fi
done < <(cd "$WORK/a" && find . -name summary.json -o -name lidar.json)
if [ $status -eq 0 ]; then echo "identical"; fi
exit $status
