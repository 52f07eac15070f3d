#!/usr/bin/env bash
# ACF step cost (docs/benchmarks.md, "ACF steps: where the time goes"): `flexopt simulate` with
# -log_view on
#   - bench/acf_link: a 0.6 m steel link, co-rotated Tet4, 756 DOFs, hinged to the ground and
#     swinging under gravity, 1,000 steps of 1 ms;
#   - cases/kane_beam (3.2k DOFs, Tet10) cut to its first FLEXOPT_BENCH_KANE_END seconds (default
#     0.5: 250 steps of 2 ms);
#   - cases/slider_crank_start with an ACF rod (10k DOFs), its first 5 ms (100 steps);
# on FLEXOPT_BENCH_RANKS ranks (default "1 2"). Prints steps/s, Newton iterations and
# factorizations per step and the time per step split into element loops, assembly,
# factorization, solves and the rest (scripts/bench/step_breakdown.py). PETSc options (e.g.
# "-mech_pc_factor_mat_solver_type mumps") go in PETSC_OPTIONS.
#
#   scripts/bench/acf_link.sh       # ≈ 3 min; results in build/bench/acf_link/results.md
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
flexopt="${FLEXOPT_BIN:-$root/build/flexopt}"
bench_init acf_link "$flexopt"
breakdown="$root/scripts/bench/step_breakdown.py"
# kane_beam shortened: a copy of the case with its mesh path made absolute.
kane="$work/kane_beam"
mkdir -p "$kane"
sed -e "s|end: 20.0|end: ${FLEXOPT_BENCH_KANE_END:-0.5}|" \
    -e "s|geometry: ../../meshes/|geometry: $root/meshes/|" \
    -e "s|output: {every: 10}|output: {every: 50}|" "$root/cases/kane_beam/case.yaml" > "$kane/case.yaml"
first=1
# The slider-crank of issue 18 (cases/slider_crank_start) with the rod as an ACF body (Tet10 at
# 4 mm: 10k DOFs), cut to its first FLEXOPT_BENCH_CRANK_END seconds (default 0.005: 100 steps of
# 50 us); FLEXOPT_BENCH_CRANK=0 leaves it out.
crank="$work/slider_crank_acf"
mkdir -p "$crank"
sed -e "s|end: 0.1,|end: ${FLEXOPT_BENCH_CRANK_END:-0.005},|" \
    -e "s|geometry: ../../meshes/|geometry: $root/meshes/|" \
    -e "s|model: ffrf|model: acf|" "$root/cases/slider_crank_start/case.yaml" > "$crank/case.yaml"
scenes=("$root/bench/acf_link" "$kane")
[ "${FLEXOPT_BENCH_CRANK:-1}" = 0 ] || scenes+=("$crank")
for scene in "${scenes[@]}"; do
  name=$(basename "$scene")
  for ranks in ${FLEXOPT_BENCH_RANKS:-1 2}; do
    out="$work/out_${name}_np$ranks"
    mpirun -n "$ranks" "$flexopt" simulate "$scene" --out "$out" -log_view ":$out.log" \
      > "$out.txt" 2>&1 || { cat "$out.txt"; exit 1; }
    if [ $first = 1 ]; then
      python3 "$breakdown" "$out.log" "$out/summary.json" --label "$name" --header | tee "$results"
      first=0
    else
      python3 "$breakdown" "$out.log" "$out/summary.json" --label "$name" | tee -a "$results"
    fi
  done
done
echo "times in ms per step; results in $results"
