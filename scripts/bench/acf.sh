#!/usr/bin/env bash
# ACF benchmark (docs/benchmarks.md): one free ACF body (the steel beam of meshes/beam.geo,
# Tet10, thrown spinning under gravity) integrated by the distributed backend with steps of
# 1 ms, meshed at FLEXOPT_BENCH_ACF_SIZES (default 0.05 0.025 0.015 0.0107 m: 2.8k to 104k
# DOFs; 0.0063 m gives 500k DOFs, 12 GB and minutes per step), on 1 and 2 ranks: Newton
# iterations and factorizations per step, wall time per step and per iteration, the largest
# resident memory of a rank. A driver of the library runs it (bench/acf_free_body.cpp, built
# with flexopt); PETSc options (e.g. an iterative solver for the Newton systems,
# "-mech_ksp_type cg -mech_pc_type bjacobi -mech_sub_pc_type icc -mech_ksp_rtol 1e-10") go in
# PETSC_OPTIONS.
#
#   scripts/bench/acf.sh            # results in build/bench/acf/results.md
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
[ -n "${FLEXOPT_BENCH_ACF_BIN:-}" ] || bench_build bench_acf_free_body
driver="${FLEXOPT_BENCH_ACF_BIN:-${FLEXOPT_BUILD_DIR:-$root/build}/bench_acf_free_body}"
bench_init acf "$driver"
bench_table "mesh size [m] | DOFs | ranks | steps | Newton iterations / step | factorizations / step | ms / step | ms / iteration | peak resident memory per rank [MiB]"
for size in ${FLEXOPT_BENCH_ACF_SIZES:-0.05 0.025 0.015 0.0107}; do
  # Fewer steps for the larger meshes (one factorization per step dominates).
  steps=$(awk -v h="$size" 'BEGIN { print (h >= 0.05 ? 20 : (h >= 0.015 ? 5 : (h >= 0.01 ? 3 : 1))) }')
  for ranks in 1 2; do
    mpirun -n "$ranks" "$driver" "$size" "$steps" | tee -a "$results"
  done
done
echo "results in $results"
