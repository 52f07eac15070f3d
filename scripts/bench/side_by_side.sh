#!/usr/bin/env bash
# Two builds side by side on the benchmarks of the time integration and the adjoint (issue 40:
# "not slower beyond the noise"): scripts/bench/ffrf.sh (the FFRF slider-crank's steps per second
# at 4, 10, 20 modes; FLEXOPT_BENCH_SIZES empty: no reduction sweep), acf_link.sh (ACF steps),
# adjoint.sh (forward and backward sweeps) and dynamic_topopt.sh (s per design iteration), each
# run alternately with the base build and this one, FLEXOPT_SIDE_ROUNDS times (default 2), in
# one run of this script (the machine is shared: compare the rounds' ratios, not seconds across
# days). The tables of every run go to build/bench/side_by_side/<bench>_<build>_<round>/results.md
# and are printed one after the other.
#
#   FLEXOPT_BASE_BUILD=/path/to/base/build scripts/bench/side_by_side.sh     # ≈ 40 min
#   FLEXOPT_SIDE_BENCHES="adjoint acf_link" ...                              # a subset
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
base="${FLEXOPT_BASE_BUILD:?set FLEXOPT_BASE_BUILD to the base build directory (with flexopt)}"
this="${FLEXOPT_BUILD_DIR:-$root/build}"
[ -x "$base/flexopt" ] || { echo "$base/flexopt missing" >&2; exit 1; }
[ -x "$this/flexopt" ] || { echo "$this/flexopt missing: build first (scripts/build.sh)" >&2; exit 1; }
out="$root/build/bench/side_by_side"
mkdir -p "$out"
rounds="${FLEXOPT_SIDE_ROUNDS:-2}"
for round in $(seq 1 "$rounds"); do
  for bench in ${FLEXOPT_SIDE_BENCHES:-ffrf acf_link adjoint dynamic_topopt}; do
    for build in base this; do
      dir=$([ "$build" = base ] && echo "$base" || echo "$this")
      work="$out/${bench}_${build}_${round}"
      echo "== $bench, $build build ($dir), round $round"
      FLEXOPT_BIN="$dir/flexopt" FLEXOPT_BUILD_DIR="$dir" FLEXOPT_BENCH_WORK="$work" \
        FLEXOPT_BENCH_SIZES="${FLEXOPT_BENCH_SIZES-}" FLEXOPT_BENCH_ROD_SIZES="${FLEXOPT_BENCH_ROD_SIZES:-0.004}" \
        FLEXOPT_BENCH_RANKS="${FLEXOPT_BENCH_RANKS_OVERRIDE:-}" \
        "$root/scripts/bench/$bench.sh" > "$work.log" 2>&1 || { tail -n 20 "$work.log"; exit 1; }
      cat "$work/results.md"
    done
  done
done
