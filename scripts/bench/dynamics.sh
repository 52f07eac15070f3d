#!/usr/bin/env bash
# Rigid-mechanism benchmark (docs/benchmarks.md): integration speed in steps per second on one
# rank for the rigid slider-crank (3 bodies) and for chains of N pendulum links (N = 2, 8, 32),
# from summary.json's integration_s (the time-stepping loop, output included: every 100th step).
#
#   scripts/bench/dynamics.sh            # results in build/bench/dynamics/results.md
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
flexopt="${FLEXOPT_BIN:-$root/build/flexopt}"
bench_init dynamics "$flexopt"
bench_table "scene | bodies | coordinates + multipliers | steps | Newton iterations / step | factorizations / step | steps/s | µs/step"

report() { # name dir
  /usr/bin/python3 - "$1" "$2" >> "$results" <<'PY'
import json, sys
name, d = sys.argv[1], sys.argv[2]
s = json.load(open(d + "/out/summary.json"))
log = open(d + "/log.txt").read()
import re
m = re.search(r"mechanism: (\d+) bodies, (\d+) coordinates, (\d+) constraint rows enforced", log)
nb, n, m_ = (int(x) for x in m.groups())
steps = s["steps"]
print(f"| {name} | {nb} | {n} + {m_} | {steps} | {s['newton_iterations_total'] / steps:.2f} | "
      f"{s['newton_factorizations_total'] / steps:.3f} | {s['steps_per_second']:.0f} | {1e6 / s['steps_per_second']:.1f} |")
PY
  tail -n 1 "$results"
}

# Slider-crank: the case itself, 2 s of motion (20,000 steps), output every 100 steps.
d="$work/slider_crank"; mkdir -p "$d"
sed -e "s#../../meshes#$root/meshes#" -e "s/time: {end: 0.4/time: {end: 2.0/" -e "s/every: 10}/every: 100}/" \
    "$root/cases/slider_crank_rigid/case.yaml" > "$d/case.yaml"
"$flexopt" simulate "$d" --out "$d/out" > "$d/log.txt" 2>&1
report "slider-crank (rigid)" "$d"

# Chains of N links of 1 m hanging from the ground, released horizontally: 2000 steps.
for N in 2 8 32; do
  d="$work/chain_$N"; mkdir -p "$d"
  {
    echo "analysis: dynamic"
    echo "materials: {steel: {E: 2.1e11, nu: 0.3, density: 7850}}"
    echo "bodies:"
    for ((i = 0; i < N; i++)); do
      echo "  - {name: l$i, model: rigid, geometry: $root/meshes/link.geo, mesh: {size: 0.1, order: 1}, material: steel, interfaces: [end_a, end_b], initial: {position: [$i, 0, 0]}}"
    done
    echo "ground: {interfaces: {pivot: [0, 0, 0]}}"
    echo "joints:"
    echo "  - {name: j0, type: revolute, a: ground, a_interface: pivot, b: l0, b_interface: end_a, axis: [0, 0, 1]}"
    for ((i = 1; i < N; i++)); do
      echo "  - {name: j$i, type: revolute, a: l$((i - 1)), a_interface: end_b, b: l$i, b_interface: end_a, axis: [0, 0, 1]}"
    done
    echo "loads: {gravity: [0, -9.81, 0]}"
    echo "time: {end: 0.5, step: 2.5e-4, rho_inf: 0.8}"
    echo "output: {every: 100}"
  } > "$d/case.yaml"
  "$flexopt" simulate "$d" --out "$d/out" > "$d/log.txt" 2>&1 || { tail -5 "$d/log.txt"; exit 1; }
  report "chain of $N links" "$d"
done
cat "$results"
