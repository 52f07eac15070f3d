#!/usr/bin/env bash
# ACF benchmark (docs/benchmarks.md): one free ACF body (the steel beam of meshes/beam.geo,
# Tet10, thrown spinning under gravity) integrated by the distributed backend with steps of
# 1 ms, meshed at FLEXOPT_BENCH_ACF_SIZES (default 0.05 0.025 0.015 0.0113 m: 2.8k to 86k
# DOFs), on 1 and 2 ranks: Newton iterations and factorizations per step, wall time per step
# and per iteration, the largest memory of a rank. ACF bodies are not reachable through a
# case yet (joints on ACF interfaces come first), so a driver of the library runs them
# (bench/acf_free_body.cpp, built with flexopt).
#
#   scripts/bench/acf.sh            # results in build/bench/acf/results.md
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
driver="${FLEXOPT_BENCH_ACF_BIN:-$root/build/bench_acf_free_body}"
bench_init acf "$driver"
bench_table "mesh size [m] | DOFs | ranks | steps | Newton iterations / step | factorizations / step | ms / step | ms / iteration | max memory per rank [MiB]"
for size in ${FLEXOPT_BENCH_ACF_SIZES:-0.05 0.025 0.015 0.0113}; do
  # Fewer steps for the larger meshes (one factorization per step dominates).
  steps=$(awk -v h="$size" 'BEGIN { print (h >= 0.05 ? 20 : (h >= 0.015 ? 5 : 3)) }')
  for ranks in 1 2; do
    mpirun -n "$ranks" "$driver" "$size" "$steps" | tee -a "$results"
  done
done
echo "results in $results"
