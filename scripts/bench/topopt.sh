#!/usr/bin/env bash
# Topology-optimization benchmark: time per optimization iteration of cases/cantilever_topopt
# (the Aage et al. 2015 cantilever, Hex8 box 2 x 1 x 1) at ~100k and ~1M DOFs on 2 ranks,
# split into assembly, state solve, adjoint solves, filter, sensitivities, MMA (PETSc log
# events of -log_view), and peak memory. Each size runs a few iterations (the per-iteration
# cost is nearly constant; the first iteration includes set-up).
#
#   scripts/bench/topopt.sh              # 48x24x24 (~92k DOFs), 64x32x32 (212k DOFs, the
#                                        # reference code's default size), 104x52x52 (~1.2M)
#   scripts/bench/topopt.sh --quick      # the ~92k size only
# Environment: FLEXOPT_BENCH_GRIDS="64x32x32", FLEXOPT_BENCH_ITERATIONS=30 (default 4),
# FLEXOPT_BENCH_OPTIONS="-ksp_rtol 1e-5" (appended PETSc options).
# Results: build/bench/topopt/results.md
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
flexopt="$root/build/flexopt"
bench_init topopt "$flexopt"
grids="${FLEXOPT_BENCH_GRIDS:-48x24x24 64x32x32 104x52x52}"; [ "${1:-}" = "--quick" ] && grids="48x24x24"
iterations="${FLEXOPT_BENCH_ITERATIONS:-4}"
results="$work/results.md"
echo "| grid | DOFs | iterations | s/iteration | assembly | state solve | adjoint | filter | sensitivities | MMA | peak memory GiB |" > "$results"
echo "|---|---|---|---|---|---|---|---|---|---|---|" >> "$results"
for g in $grids; do
  IFS=x read -r nx ny nz <<< "$g"
  d="$work/$g"
  # The reference code's problem at this size (common.sh); the case's tolerance rtol 1e-10.
  cantilever_case "$d" "$nx" "$ny" "$nz" "$iterations" "-ksp_rtol 1e-10"
  mpirun -n 2 /usr/bin/time -f "rss_kb %M" "$flexopt" optimize "$d" --out "$d/out" -log_view ${FLEXOPT_BENCH_OPTIONS:-} > "$d/log.txt" 2>&1 || { tail -30 "$d/log.txt"; exit 1; }
  /usr/bin/python3 - "$g" "$d" "$iterations" >> "$results" <<'PY'
import json, re, sys
g, d, its = sys.argv[1], sys.argv[2], int(sys.argv[3])
log = open(d + "/log.txt").read()
s = json.load(open(d + "/out/summary.json"))
def event(name):
    m = re.search(r"^" + re.escape(name) + r"\s+(\d+)\s+\S+\s+(\S+)", log, re.M)
    return float(m.group(2)) if m else 0.0
mem = sum(int(x) for x in re.findall(r"^rss_kb (\d+)", log, re.M)) / 1048576
per = lambda v: f"{v / its:.2f}"
times = [event(n) for n in ("FxAssembleMatrix", "FxStateSolve", "FxAdjointSolve", "FxFilterSolve", "FxSensitivities", "MMA update")]
total = event("FxTopologyEvaluate") + times[5]
print(f"| {g} | {s['dofs']:,} | {its} | {total / its:.2f} | " + " | ".join(per(t) for t in times) + f" | {mem:.2f} |")
PY
  tail -n 1 "$results"
done
cat "$results"
