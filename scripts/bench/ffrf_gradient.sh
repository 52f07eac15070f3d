#!/usr/bin/env bash
# The whole gradient of an FFRF design body against the forward run it differentiates
# (docs/benchmarks.md, "FFRF design gradient against the forward run"): the steel beam of
# meshes/beam.geo (Tet10, meshed at FLEXOPT_BENCH_SIZES, default 0.014 0.006 m: 49,632 and
# 498,729 DOFs) as a pendulum falling from horizontal about a revolute joint at its clamp face,
# FFRF with FLEXOPT_BENCH_MODES fixed-interface modes (default 8), frame clamped there, the
# whole beam a design region at density 0.8, FLEXOPT_BENCH_STEPS steps of 1 ms (default 500).
# `flexopt simulate CASE --gradient` on FLEXOPT_BENCH_RANKS ranks (default 2), with 1 response
# (the tip's elastic y, mean square) and with 4 (also its KS maximum, the tip's final y and the
# strain energy integral). From summary.json: the reduction, the forward integration, the
# dynamic adjoint and the reduction adjoint, and
#   forward run = reduction + integration,   gradient = all four,   ratio = gradient / forward,
# the issue's target being a ratio <= 3; then the peak resident memory of the largest rank.
#
#   scripts/bench/ffrf_gradient.sh                               # ≈ 10 min, 4.5 GB per rank
#   FLEXOPT_BENCH_SIZES=0.014 scripts/bench/ffrf_gradient.sh     # the 50k-DOF rows, ≈ 1 min
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
build="${FLEXOPT_BUILD_DIR:-$root/build}"
bench_init ffrf_gradient "$build/flexopt"
ranks="${FLEXOPT_BENCH_RANKS:-2}"
modes="${FLEXOPT_BENCH_MODES:-8}"
steps="${FLEXOPT_BENCH_STEPS:-500}"
sizes="${FLEXOPT_BENCH_SIZES:-0.014 0.006}"
bench_table "mesh size [m] | DOFs | responses | reduction [s] | integration [s] | dynamic adjoint [s] | reduction adjoint [s] | forward run [s] | gradient [s] | gradient / forward | peak RSS [MiB]"
end=$(awk -v n="$steps" 'BEGIN { printf "%.6g", n * 1e-3 }')
for size in $sizes; do
  for responses in 1 4; do
    dir="$work/beam_${size}_$responses"
    rm -rf "$dir"
    mkdir -p "$dir"
    radius=$(awk -v s="$size" 'BEGIN { printf "%.6g", 2.5 * s }')
    constraints=""
    if [ "$responses" = 4 ]; then
      constraints="constraints:
  - {type: sensor, sensor: tip_elastic, component: y, measure: ks_max, ks: 1000, max: 1}
  - {type: sensor, sensor: tip, component: y, measure: final, max: 0}
  - {type: strain_energy_integral, body: beam, max: 1}"
    fi
    cat > "$dir/case.yaml" <<CASE
analysis: dynamic
materials:
  steel: {E: 2.1e11, nu: 0.3, density: 7850}
bodies:
  - name: beam
    model: ffrf
    geometry: $root/meshes/beam.geo
    mesh: {size: $size, order: 2}
    material: steel
    interfaces: [clamp]
    reduction: {modes: $modes}
ground: {interfaces: {pivot: [0, 0.025, 0.05]}}
joints:
  - {name: hinge, type: revolute, a: ground, a_interface: pivot, b: beam, b_interface: clamp, axis: [0, 0, 1]}
loads:
  gravity: [0, -9.81, 0]
time: {end: $end, step: 1.0e-3, rho_inf: 0.9}
sensors:
  - {name: tip_elastic, body: beam, point: [1.0, 0.025, 0.05], quantity: elastic_displacement}
  - {name: tip, body: beam, point: [1.0, 0.025, 0.05], quantity: position}
output: {every: 100000}
design: {body: beam, region: beam, initial: 0.8, filter: {type: cone, radius: $radius}}
objective: {type: sensor, sensor: tip_elastic, component: y, measure: mean_square}
$constraints
CASE
    mpirun -n "$ranks" "$build/flexopt" simulate "$dir" --gradient --out "$dir/out" > "$dir/log.txt" 2>&1 ||
      { echo "| $size | run failed: $dir/log.txt |" | tee -a "$results"; tail -n 5 "$dir/log.txt" >&2; continue; }
    python3 - "$dir/out/summary.json" "$dir/log.txt" "$size" "$responses" <<'PY' | tee -a "$results"
import json, re, sys
s = json.load(open(sys.argv[1]))
a = s["adjoint"]
red, fwd, adj, radj = (float(a[k]) for k in ("reduction_s", "forward_s", "adjoint_s", "reduction_adjoint_s"))
nodes = re.search(r"Tet10 elements, (\d+) nodes", open(sys.argv[2]).read())
dofs = 3 * int(nodes.group(1)) if nodes else ""
forward = red + fwd
grad = forward + adj + radj
print(f"| {sys.argv[3]} | {dofs} | {sys.argv[4]} | {red:.2f} | {fwd:.2f} | {adj:.2f} | {radj:.2f} | "
      f"{forward:.2f} | {grad:.2f} | {grad / forward:.2f} | {s.get('peak_memory_mib', '')} |")
PY
  done
done
echo "results in $results"
