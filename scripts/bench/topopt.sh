#!/usr/bin/env bash
# Topology-optimization benchmark: time per optimization iteration of cases/cantilever_topopt
# (the Aage et al. 2015 cantilever, Hex8 box 2 x 1 x 1) at ~100k and ~1M DOFs on 2 ranks,
# split into assembly, state solve, adjoint solves, filter, sensitivities, MMA (PETSc log
# events of -log_view), and peak memory. Each size runs a few iterations (the per-iteration
# cost is nearly constant; the first iteration includes set-up).
#
#   scripts/bench/topopt.sh              # 48x24x24 (~92k DOFs) and 104x52x52 (~1.2M DOFs)
#   scripts/bench/topopt.sh --quick      # the ~92k size only
# Results: build/bench/topopt/results.md
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
source "$root/scripts/env.sh"
flexopt="$root/build/flexopt"
[ -x "$flexopt" ] || { echo "build flexopt first (scripts/build.sh)" >&2; exit 1; }
work="$root/build/bench/topopt"
mkdir -p "$work"
grids="48x24x24 104x52x52"; [ "${1:-}" = "--quick" ] && grids="48x24x24"
iterations="${FLEXOPT_BENCH_ITERATIONS:-4}"
results="$work/results.md"
echo "| grid | DOFs | iterations | s/iteration | assembly | state solve | adjoint | filter | sensitivities | MMA | peak memory GiB |" > "$results"
echo "|---|---|---|---|---|---|---|---|---|---|---|" >> "$results"
for g in $grids; do
  IFS=x read -r nx ny nz <<< "$g"
  d="$work/$g"; mkdir -p "$d"
  sed -e "s/^nx = 32; ny = 16; nz = 16;.*/nx = $nx; ny = $ny; nz = $nz;/" "$root/meshes/box_2x1x1_hex.geo" > "$d/box.geo"
  # Same problem; the load keeps 0.001 per node (q = 0.001 ny N/m) as in the reference code.
  sed -e "s#../../meshes/box_2x1x1_hex.geo#box.geo#" -e "s#value: \[0, 0, -0.016\]#value: [0, 0, -$(python3 -c "print(0.001*$ny)")]#" \
      -e "s/radius: 0.046188/radius: $(python3 -c "print(0.046188*16/$ny)")/" "$root/cases/cantilever_topopt/case.yaml" > "$d/case.yaml"
  mpirun -n 2 /usr/bin/time -f "rss_kb %M" "$flexopt" optimize "$d" --out "$d/out" --max-iterations "$iterations" -log_view > "$d/log.txt" 2>&1 || { tail -30 "$d/log.txt"; exit 1; }
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
