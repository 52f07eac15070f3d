#!/usr/bin/env bash
# The 2-rank speed-up of the ACF benchmark (docs/benchmarks.md), measured as this virtual
# machine allows: PAIRS back-to-back pairs of a 1-rank and a 2-rank run of
# bench_acf_free_body at one mesh size, each pair giving a ratio of the times per step. Prints
# every pair, the median of the ratios and the ratio of the best times (noise on a shared host
# only ever adds time, so the best of several runs is the closest to the machine's own speed).
#
#   scripts/bench/acf_speedup.sh [SIZE [PAIRS [STEPS]]]     # default 0.0107 m (104k DOFs), 5, 3
#
# PETSc options (e.g. "-mech_pc_type cholesky -mech_pc_factor_mat_solver_type mumps") go in
# PETSC_OPTIONS; results in build/bench/acf_speedup/results.md.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
[ -n "${FLEXOPT_BENCH_ACF_BIN:-}" ] || bench_build bench_acf_free_body
driver="${FLEXOPT_BENCH_ACF_BIN:-${FLEXOPT_BUILD_DIR:-$root/build}/bench_acf_free_body}"
bench_init acf_speedup "$driver"
size="${1:-0.0107}"
pairs="${2:-5}"
steps="${3:-3}"
bench_table "pair | ms / step, 1 rank | ms / step, 2 ranks | speed-up"
times1=()
times2=()
for pair in $(seq 1 "$pairs"); do
  row1=$(mpirun -n 1 "$driver" "$size" "$steps" | tail -n 1)
  row2=$(mpirun -n 2 "$driver" "$size" "$steps" | tail -n 1)
  # Column 8 of the driver's row is the wall time per step in ms.
  t1=$(echo "$row1" | awk -F'|' '{ gsub(/ /, "", $8); print $8 }')
  t2=$(echo "$row2" | awk -F'|' '{ gsub(/ /, "", $8); print $8 }')
  times1+=("$t1")
  times2+=("$t2")
  awk -v p="$pair" -v a="$t1" -v b="$t2" 'BEGIN { printf "| %d | %.1f | %.1f | %.2f |\n", p, a, b, a / b }' |
    tee -a "$results"
done
printf '%s\n' "${times1[@]}" > "$work/times1"
printf '%s\n' "${times2[@]}" > "$work/times2"
paste "$work/times1" "$work/times2" | awk -v size="$size" '
  { t1[NR] = $1; t2[NR] = $2; r[NR] = $1 / $2 }
  END {
    n = NR
    for (i = 1; i <= n; ++i) for (j = i + 1; j <= n; ++j) if (r[j] < r[i]) { x = r[i]; r[i] = r[j]; r[j] = x }
    median = (n % 2) ? r[(n + 1) / 2] : 0.5 * (r[n / 2] + r[n / 2 + 1])
    b1 = t1[1]; b2 = t2[1]
    for (i = 2; i <= n; ++i) { if (t1[i] < b1) b1 = t1[i]; if (t2[i] < b2) b2 = t2[i] }
    printf "\nmesh size %s m, %d pairs: speed-up median %.2f (range %.2f-%.2f); best times %.1f / %.1f ms = %.2f\n",
      size, n, median, r[1], r[n], b1, b2, b1 / b2
  }' | tee -a "$results"
echo "results in $results"
