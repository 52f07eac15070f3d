#!/usr/bin/env bash
# Seconds per iteration of the dynamic topology optimization of cases/slider_crank_topopt at
# large design-variable counts (docs/benchmarks.md, "Dynamic topology optimization"): the case
# as it stands (FFRF rod, 8 fixed-interface modes, one crank revolution of 2,094 steps of 20 µs)
# with the rod meshed at each FLEXOPT_BENCH_MESHES entry SIZE:ORDER (default 0.0016:1, Tet4 of
# 1.6 mm: about 116,000 design elements), the filter radius kept at 8 mm, and
# FLEXOPT_BENCH_ITERATIONS MMA iterations (default 4) on FLEXOPT_BENCH_RANKS ranks (default 2).
# From history.csv and summary.json: the mean seconds per iteration over iterations 2 ... N
# (iteration 1 reuses the reduction made while the scene was built) split into reduction,
# forward run, adjoint sweep, reduction adjoint and update; the peak resident memory of the
# largest rank and the memory per design variable (the ranks' peaks summed, divided by the
# design variables). The issue's target: <= 60 s per iteration at >= 100,000 design elements.
#
# FLEXOPT_BENCH_FILTER replaces the case's filter (default: the case's cone filter of R = 8 mm),
# e.g. the Helmholtz filter of the same smoothing, r = R / (2 sqrt 3), where the cone's weights
# would not fit (the 1,000,000-variable rod: about 43,000 neighbours per element).
#
#   scripts/bench/dynamic_topopt.sh                                  # ≈ 5 min
#   FLEXOPT_BENCH_MESHES="0.005:2 0.0016:1" scripts/bench/dynamic_topopt.sh
#   FLEXOPT_BENCH_MESHES="0.00075:1" FLEXOPT_BENCH_ITERATIONS=3 \
#     FLEXOPT_BENCH_FILTER="{radius: 0.0023094}" scripts/bench/dynamic_topopt.sh   # ≈ 20 min, 1.04M variables
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
build="${FLEXOPT_BUILD_DIR:-$root/build}"
bench_init dynamic_topopt "$build/flexopt"
ranks="${FLEXOPT_BENCH_RANKS:-2}"
iterations="${FLEXOPT_BENCH_ITERATIONS:-4}"
meshes="${FLEXOPT_BENCH_MESHES:-0.0016:1}"
filter="${FLEXOPT_BENCH_FILTER:-{type: cone, radius: 0.008}}"
bench_table "mesh | elements | design variables | DOFs | s / iteration | reduction | forward | adjoint | reduction adjoint | update | peak RSS, largest rank [MiB] | memory per design variable [kB]"
for mesh in $meshes; do
  size="${mesh%%:*}"
  order="${mesh##*:}"
  dir="$work/rod_${size}_$order"
  rm -rf "$dir"
  mkdir -p "$dir"
  # The case with the rod's mesh replaced, absolute geometry paths and no motion frames to speak
  # of (output.every also thins design.xdmf).
  sed -e "s|\.\./\.\./meshes|$root/meshes|" \
      -e "s|mesh: {size: 0.005, order: 2}|mesh: {size: $size, order: $order}|" \
      -e "s|output: {every: 10}|output: {every: 100000}|" \
      -e "s|filter: {type: cone, radius: 0.008}|filter: $filter|" \
      "$root/cases/slider_crank_topopt/case.yaml" > "$dir/case.yaml"
  grep -q "size: $size, order: $order" "$dir/case.yaml" || { echo "the rod's mesh line was not found" >&2; exit 1; }
  grep -qF "filter: $filter" "$dir/case.yaml" || { echo "the rod's filter line was not found" >&2; exit 1; }
  mpirun -n "$ranks" "$build/flexopt" optimize "$dir" --max-iterations "$iterations" --out "$dir/out" \
    > "$dir/log.txt" 2>&1 || { echo "| $mesh | run failed: $dir/log.txt |" | tee -a "$results"; tail -n 5 "$dir/log.txt" >&2; continue; }
  python3 - "$dir" "$mesh" "$ranks" <<'PY' | tee -a "$results"
import csv, json, re, sys
d, mesh, ranks = sys.argv[1], sys.argv[2], int(sys.argv[3])
s = json.load(open(f"{d}/out/summary.json"))
rows = list(csv.DictReader(open(f"{d}/out/history.csv")))[1:]  # iterations 2 ... N
mean = lambda key: sum(float(r[key]) for r in rows) / len(rows)
log = open(f"{d}/log.txt").read()
m = re.search(r"body rod: meshed in [0-9.]+ s: (\d+) (Tet\d+) elements, (\d+) nodes", log)
elements, kind, nodes = int(m.group(1)), m.group(2), int(m.group(3))
peak = float(s.get("peak_memory_mib", float("nan")))
total = float(s.get("peak_memory_total_mib", peak * ranks))
per_var = total * 1024 / s["design_variables"]
print(f"| {mesh} ({kind}) | {elements} | {s['design_variables']} | {3 * nodes} | {mean('seconds'):.2f} | "
      f"{mean('seconds_reduction'):.2f} | {mean('seconds_forward'):.2f} | {mean('seconds_adjoint'):.2f} | "
      f"{mean('seconds_reduction_adjoint'):.2f} | {mean('seconds_update'):.2f} | {peak:.0f} | {per_var:.1f} |")
PY
done
echo "results: $results"
