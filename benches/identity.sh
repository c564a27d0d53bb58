#!/usr/bin/env bash
# Product identity of two builds, for refactors that must not change any result.
#
#   bash benches/identity.sh BIN_A BIN_B [ASSETS_DIR]
#
# BIN_A and BIN_B are two `lumenscape` executables (copy `target/release/lumenscape` aside
# between builds). Both run every scene of ASSETS_DIR/scenes (default: this repository's
# assets, copied once so that both read the same files and the scenes' relative mesh paths
# resolve) and the extra settings below (Monte Carlo, the reference preset, the
# double-precision walk, the AVX2 cap with image oversampling, a Maket run); then every product
# file is compared byte for byte, except the run times, rates, paths and version in
# summary.json / lidar.json and their `memory` record (the estimate's baseline and the measured
# peak depend on the process). Prints "identical" and exits 0, or lists what differs (or which run
# failed: a run that fails with both binaries is not an identity) and exits 1.
# About 30 s on 2 cores.
set -uo pipefail
[ $# -ge 2 ] || { echo "usage: bash benches/identity.sh BIN_A BIN_B [ASSETS_DIR]" >&2; exit 2; }
A=$(realpath "$1"); B=$(realpath "$2")
ASSETS=$(realpath "${3:-$(dirname "$0")/../assets}")
WORK=$(mktemp -d); trap 'rm -rf "$WORK"' EXIT
cp -r "$ASSETS" "$WORK/assets"

run_all() { # BIN OUT
  local bin=$1 out=$2 s n
  mkdir -p "$out"
  for s in "$WORK"/assets/scenes/*.ron; do
    n=$(basename "$s" .ron)
    "$bin" run "$s" --out "$out/$n" --quiet > /dev/null 2>&1 && echo "$n 0" >> "$out/rc.txt" || echo "$n $?" >> "$out/rc.txt"
  done
  local t="$WORK/assets/scenes/turbid_layer.ron"
  "$bin" run "$t" --out "$out/mc_turbid" --quiet --solver monte-carlo --photons 200000 > /dev/null 2>&1; echo "mc $?" >> "$out/rc.txt"
  "$bin" run "$t" --out "$out/ref_turbid" --quiet --preset reference > /dev/null 2>&1; echo "ref $?" >> "$out/rc.txt"
  "$bin" run "$t" --out "$out/avx2_turbid" --quiet --isa avx2 --image-oversampling 2 > /dev/null 2>&1; echo "avx2 $?" >> "$out/rc.txt"
  "$bin" run "$WORK/assets/scenes/forest_dem.ron" --out "$out/f64_forest" --quiet --batch-f64 > /dev/null 2>&1; echo "f64 $?" >> "$out/rc.txt"
  "$bin" run "$WORK/assets/scenes/disk_canopy.ron" --out "$out/mc_disk" --quiet --solver monte-carlo --photons 100000 --sampler alias > /dev/null 2>&1; echo "mcdisk $?" >> "$out/rc.txt"
  "$bin" run "$WORK/assets/scenes/default.ron" --out "$out/mc_default" --quiet --solver monte-carlo --photons 100000 > /dev/null 2>&1; echo "mcdef $?" >> "$out/rc.txt"
  "$bin" maket "$WORK/assets/scenes/urban.ron" --out "$out/maket_urban" --quiet > /dev/null 2>&1; echo "maket $?" >> "$out/rc.txt"
}

run_all "$A" "$WORK/run-a"
run_all "$B" "$WORK/run-b"
status=0
if grep -v ' 0$' "$WORK/run-a/rc.txt"; then
  echo "runs above failed with BIN_A (exit codes)"
  status=1
fi
diff -r -q -x summary.json -x lidar.json "$WORK/run-a" "$WORK/run-b" || status=1
strip() { sed '/^  "memory": {/,/^  }/d' "$1" | grep -v '_seconds"\|"seconds"\|_per_second\|"wall\|"version"' | sed "s#$2#X#g"; }
while IFS= read -r f; do
  if ! diff <(strip "$WORK/run-a/$f" "$WORK/run-a") <(strip "$WORK/run-b/$f" "$WORK/run-b") > /dev/null; then
    echo "differs: $f"
    status=1
  fi
done < <(cd "$WORK/run-a" && find . -name summary.json -o -name lidar.json)
if [ $status -eq 0 ]; then echo "identical"; fi
exit $status
