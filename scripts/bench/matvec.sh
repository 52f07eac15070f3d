#!/usr/bin/env bash
# The matrix-free Hex8 candidate of issue 23 (docs/solvers.md, "Candidates"): builds and runs
# bench/hex8_matvec.cpp on FLEXOPT_BENCH_RANKS ranks (default 2) for the cantilever lattices
# FLEXOPT_BENCH_GRIDS (default 64x32x32 104x52x52: 212,355 and 884,835 DOFs), each the box of
# scripts/bench/common.sh's cantilever_case. Prints per grid the assembled MatMult's mean time,
# the matrix-free product's (one 24 x 24 unit element matrix times rho_e^3 per element, ghost
# exchange included), their ratio and the results' difference, over FLEXOPT_BENCH_REPEAT
# products (default 50).
#
#   scripts/bench/matvec.sh    # ≈ 2 min; results in build/bench/matvec/results.md
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
build="${FLEXOPT_BUILD_DIR:-$root/build}"
bench_build bench_hex8_matvec
driver="$build/bench_hex8_matvec"
bench_init matvec "$driver"
ranks="${FLEXOPT_BENCH_RANKS:-2}"
repeat="${FLEXOPT_BENCH_REPEAT:-50}"
bench_table "grid | DOFs | matrix entries | matrix [MiB] | assembled MatMult [ms] | matrix-free [ms] | matrix-free / MatMult | max rel. difference"
for grid in ${FLEXOPT_BENCH_GRIDS:-64x32x32 104x52x52}; do
  IFS=x read -r nx ny nz <<< "$grid"
  cantilever_case "$work/case_$grid" "$nx" "$ny" "$nz" 1 ""
  out="$work/out_$grid.txt"
  mpirun -n "$ranks" "$driver" -geo "$work/case_$grid/box.geo" -repeat "$repeat" > "$out"
  cat "$out"
  awk -v g="$grid" '
    /^DOFs/ { d = $2; n = $6; m = $8 } /^assembled/ { a = $3 } /^matrix-free/ { f = $3; r = $5; sub(/[(]/, "", r) }
    /^difference/ { x = $2 }
    END { printf "| %s | %s | %s | %s | %s | %s | %s | %s |\n", g, d, n, m, a, f, r, x }' "$out" >> "$results"
done
cat "$results"
