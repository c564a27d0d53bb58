#!/usr/bin/env bash
# A/B comparison of two builds of the radiative bench that cancels the host's speed drift:
# each pair runs build A and build B at the same time, one thread each, pinned to different
# cores (swapped at every pair), and the ratio B/A of their kernel rates (Mcross/s/core) is
# taken within the pair. Prints the medians of A, B and B/A over N pairs.
#
#   benches/ab_pairs.sh N ROW BIN_A BIN_B [EXTRA_ARGS...]
#
# ROW is a `--row` of `cargo bench --bench radiative` ("Default 100 0.2", "forest Default",
# ...); BIN_A / BIN_B are bench executables (`target/release/deps/radiative-*`, copied aside
# between builds; each reads its oracle tables from the checkout it was built in, so keep that
# checkout); EXTRA_ARGS go to both (e.g. `--avx2`). Needs 2 idle cores and `taskset`.
# On the 2-core CI-class VM, back-to-back runs of one build drift by ±5 % from run to run;
# the median paired ratio of a build against itself came out 0.9996 and 0.9999 (6 pairs each;
# single pairs within 0.94–1.06), so 8–10 pairs resolve a 2 % change.
set -euo pipefail
if [ $# -lt 4 ]; then
    sed -n 2,15p "$0"
    exit 2
fi
n=$1 row=$2 bin_a=$3 bin_b=$4
shift 4
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# The kernel rate of a bench output: column 7 of a turbid-layer row, `(kernel X)` of a forest
# or sparse row.
kernel() {
    local last
    last=$(tail -1 "$1")
    if [[ $last == *"(kernel "* ]]; then
        sed -E 's/.*\(kernel ([0-9.]+)\).*/\1/' <<<"$last"
    else
        awk '{print $7}' <<<"$last"
    fi
}
median() {
    printf '%s\n' "$@" | sort -g | awk '{v[NR] = $1} END {
        printf "%.4f (min %.4f, max %.4f)\n", v[int((NR + 1) / 2)], v[1], v[NR] }'
}
ka=() kb=() ratio=()
for i in $(seq "$n"); do
    ca=$((i % 2)) cb=$(((i + 1) % 2))
    RAYON_NUM_THREADS=1 taskset -c "$ca" "$bin_a" --row "$row" "$@" >"$tmp/a" 2>"$tmp/a.err" &
    pa=$!
    RAYON_NUM_THREADS=1 taskset -c "$cb" "$bin_b" --row "$row" "$@" >"$tmp/b" 2>"$tmp/b.err" &
    pb=$!
    # A bench binary reads its oracle tables from the checkout it was built in.
    for run in "a $pa $bin_a" "b $pb $bin_b"; do
        read -r tag pid bin <<<"$run"
        if ! wait "$pid"; then
            echo "ab_pairs: $bin failed:" >&2
            tail -8 "$tmp/$tag.err" >&2
            exit 1
        fi
    done
    a=$(kernel "$tmp/a") b=$(kernel "$tmp/b")
    ka+=("$a") kb+=("$b")
    ratio+=("$(awk -v a="$a" -v b="$b" 'BEGIN {print b / a}')")
done
echo "A kernel Mcross/s: $(median "${ka[@]}")"
echo "B kernel Mcross/s: $(median "${kb[@]}")"
echo "B/A:               $(median "${ratio[@]}")"
