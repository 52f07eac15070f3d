#!/usr/bin/env bash
# The FFRF reduction adjoint against the reduction (docs/benchmarks.md, "FFRF reduction
# adjoint"): builds and runs bench/ffrf_reduction_adjoint.cpp on FLEXOPT_BENCH_RANKS ranks
# (default 2) with the steel beam of meshes/beam.geo (Tet10) meshed at FLEXOPT_BENCH_SIZES
# (default 0.014 0.006 m: 49,632 and 498,729 DOFs), FLEXOPT_BENCH_MODES fixed-interface modes
# (default 8), a design body with a pseudo-random density per element, in two configurations,
# each its own run (so that each has its own peak memory):
#   a: interfaces clamp and tip, chord frame, no geometric stiffening (6 static + 8 modes);
#   b: interface clamp alone, frame clamped there, centrifugal geometric stiffening (8 modes).
# Prints the reduction's wall time, the adjoint's (exact basis derivative, 1 and 4 responses;
# basis held fixed, 1 response) and their ratios, the conjugate-gradient iterations, the peak
# resident memory of the largest rank and the resident memory the reduction keeps; then the
# kept MUMPS Cholesky factorization as MUMPS reports it (INFOG, from -eps_view: the
# Craig-Bampton eigensolver's factorization, which the static modes, the geometric stiffness'
# load cases and the adjoint reuse). -log_view of every run in $work/log_*.txt; more PETSc
# options in PETSC_OPTIONS; FLEXOPT_BENCH_TIMEOUT (seconds) stops a run that takes longer. The
# last column is the CPU time that other processes used during the run, in cores (from
# /proc/stat; on 2 cores, anything above about 0.2 slows the run down).
#
#   scripts/bench/ffrf_adjoint.sh   # ≈ 6 min on a quiet machine (15 on a busy one), 4.5 GB per rank;
#                                   # results in build/bench/ffrf_adjoint/results.md
#   FLEXOPT_BENCH_SIZES=0.014 scripts/bench/ffrf_adjoint.sh      # the 50k-DOF rows only, ≈ 20 s
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
build="${FLEXOPT_BUILD_DIR:-$root/build}"
bench_build bench_ffrf_reduction_adjoint
driver="$build/bench_ffrf_reduction_adjoint"
bench_init ffrf_adjoint "$driver"
ranks="${FLEXOPT_BENCH_RANKS:-2}"
modes="${FLEXOPT_BENCH_MODES:-8}"
sizes="${FLEXOPT_BENCH_SIZES:-0.014 0.006}"
bench_table "configuration | mesh size [m] | DOFs | elements | basis (static + fixed) | reduction [s] | adjoint, exact, 1 response [s] | / reduction | adjoint, exact, 4 responses [s] | / reduction | adjoint, basis fixed, 1 response [s] | CG iterations (1 / 4 responses) | peak RSS after reduction [MiB] | peak RSS after adjoints [MiB] | kept by the reduction [MiB] | other load [cores]"
factors="$work/factors.md"
{ echo "| configuration | DOFs | entries in the factors (INFOG(29)) | factors [MiB] (8 bytes each) | MUMPS memory allocated, sum of ranks [MB] (INFOG(19)) | of the largest rank [MB] (INFOG(18)) | effectively used, sum [MB] (INFOG(22)) |"
  echo "|---|---|---|---|---|---|---|"; } > "$factors"
# CPU seconds the machine has spent busy since boot (all cores).
busy_seconds() {
  awk -v t="$(getconf CLK_TCK)" 'NR == 1 { print ($2 + $3 + $4 + $7 + $8 + $9) / t }' /proc/stat
}
run_limit=()
[ -z "${FLEXOPT_BENCH_TIMEOUT:-}" ] || run_limit=(timeout "$FLEXOPT_BENCH_TIMEOUT")
for size in $sizes; do
  for config in a b; do
    tag="${size}_$config"
    start=$(date +%s)
    status=0
    busy0=$(busy_seconds)
    TIMEFORMAT="%R %U %S"
    { time "${run_limit[@]}" mpirun -n "$ranks" "$driver" -size "$size" -modes "$modes" -config "$config" \
      -eps_view "ascii:$work/eps_$tag.txt" -log_view ":$work/log_$tag.txt" \
      > "$work/out_$tag.txt" 2> "$work/err_$tag.txt" || status=$?; } 2> "$work/time_$tag.txt"
    other=$(awk -v b0="$busy0" -v b1="$(busy_seconds)" '{ printf "%.2f", (b1 - b0 - $2 - $3) / $1 }' "$work/time_$tag.txt")
    if [ "$status" != 0 ]; then
      # Recorded, not fatal: the 500k rows may run out of memory or time on a shared machine.
      echo "| $config | $size | run failed (exit status $status after $(( $(date +%s) - start )) s, other load $other cores; $work/err_$tag.txt) |" | tee -a "$results"
      tail -n 5 "$work/err_$tag.txt" >&2 || true
      continue
    fi
    grep '^|' "$work/out_$tag.txt" | sed "s/\$/ $other |/" | tee -a "$results"
    dofs=$(sed -n 's/^mesh size [^:]*: \([0-9]*\) DOFs.*/\1/p' "$work/err_$tag.txt")
    awk -v c="$config" -v d="$dofs" '
      function value(line) { sub(/.*: */, "", line); return line }
      /INFOG\(18\) / { g18 = value($0) } /INFOG\(19\) / { g19 = value($0) }
      /INFOG\(22\) / { g22 = value($0) } /INFOG\(29\) / { g29 = value($0) }
      END { printf "| %s | %s | %d | %.0f | %s | %s | %s |\n", c, d, g29, g29 * 8 / 1048576, g19, g18, g22 }' \
      "$work/eps_$tag.txt" >> "$factors"
  done
done
{ echo; cat "$factors"; } | tee -a "$results"
echo "results in $results; -log_view of each run in $work/log_*.txt"
