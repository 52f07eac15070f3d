#!/usr/bin/env bash
# The dynamic adjoint against its forward run (docs/benchmarks.md, "Dynamic adjoint"):
# `flexopt simulate --gradient` on the rigid slider-crank with a design rod
# (tests/gradient/rigid_slider_crank, here with FLEXOPT_BENCH_ADJOINT_STEPS steps, default
# 2,000), each forward run solved as the case says (kept Newton matrices, time.newton_reuse
# 0.1) and by Newton's method proper (newton_reuse 0), with every state stored and with 32
# binomial checkpoints (in memory and on disk). Prints forward_s, adjoint_s, their ratio, the
# recomputed steps and (forward + adjoint) / forward, and the memory of the stored states.
# Each line is the median of FLEXOPT_BENCH_REPEAT runs (default 3), measured in one run of
# this script (the machine is shared: compare ratios, not seconds across days).
#
# Then the ACF design link (FLEXOPT_BENCH_ACF=0 leaves it out) at about 1k and 10k DOFs, its
# forward run with kept Newton matrices and by Newton's method proper.
#
#   scripts/bench/adjoint.sh     # ~ 2 min; results in build/bench/adjoint/results.md
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
flexopt="${FLEXOPT_BIN:-$root/build/flexopt}"
bench_init adjoint "$flexopt"
steps="${FLEXOPT_BENCH_ADJOINT_STEPS:-2000}"
repeat="${FLEXOPT_BENCH_REPEAT:-3}"
ranks="${FLEXOPT_BENCH_RANKS:-1}"
bench_table "Newton | checkpoints | storage | steps | forward_s | adjoint_s | adjoint / forward | recomputed steps | (forward + adjoint) / forward | stored states [kB] | peak memory [MiB]"
for reuse in 0.1 0; do
  for variant in all:memory 32:memory 32:disk; do
    checkpoints=${variant%%:*}
    storage=${variant##*:}
    scene="$work/slider_crank_${reuse}_${checkpoints}_${storage}"
    mkdir -p "$scene"
    end=$(python3 -c "print($steps * 1e-4)")
    sed -e "s|geometry: ../../../meshes/|geometry: $root/meshes/|" \
        -e "s|time: {end: 0.2, step: 1.0e-3, rho_inf: 0.8}|time: {end: $end, step: 1.0e-4, rho_inf: 0.8, newton_reuse: $reuse}|" \
        "$root/tests/gradient/rigid_slider_crank/case.yaml" > "$scene/case.yaml"
    echo "output: {every: $steps}" >> "$scene/case.yaml"
    echo "adjoint: {checkpoints: $checkpoints, storage: $storage}" >> "$scene/case.yaml"
    rows=()
    for r in $(seq 1 "$repeat"); do
      mpirun -n "$ranks" "$flexopt" simulate "$scene" --gradient --out "$scene/out" > "$scene/log" 2>&1 ||
        { cat "$scene/log"; exit 1; }
      rows+=("$(python3 - "$scene/out/summary.json" <<'EOF'
import json, sys
s = json.load(open(sys.argv[1]))
a = s["adjoint"]
f, b = a["forward_s"], a["adjoint_s"]
print(f"{f:.4f} {b:.4f} {b / f:.3f} {a['recomputed_steps']} {(f + b) / f:.3f} {a['checkpoint_bytes'] / 1e3:.1f} {a['steps']} {s['peak_memory_mib']:.0f}")
EOF
)")
    done
    median=$(printf '%s\n' "${rows[@]}" | sort -t' ' -k3,3n | sed -n "$(( (repeat + 1) / 2 ))p")
    read -r f b ratio rec total kb n peak <<< "$median"
    newton=$([ "$reuse" = 0 ] && echo "proper" || echo "kept ($reuse)")
    echo "| $newton | $checkpoints | $storage | $n | $f | $b | $ratio | $rec | $total | $kb | $peak |" | tee -a "$results"
  done
done
# ACF design body (tests/gradient/acf_pendulum: a soft hinged link, 50 steps of 2 ms) at about
# 1k and 10k DOFs (Tet4 at 2.5 cm and 1 cm), every state kept, the forward run with the case's
# kept Newton matrices and by Newton's method proper.
if [ "${FLEXOPT_BENCH_ACF:-1}" != 0 ]; then
  { echo; echo "| ACF link | Newton | DOFs | steps | forward_s | adjoint_s | adjoint / forward | forward factorizations | adjoint factorizations | stored states [MB] | peak memory [MiB] |"
    echo "|---|---|---|---|---|---|---|---|---|---|---|"; } >> "$results"
  for size in 0.025 0.01; do
    for reuse in 0.1 0; do
      scene="$work/acf_pendulum_${size}_$reuse"
      mkdir -p "$scene"
      sed -e "s|geometry: ../../../meshes/|geometry: $root/meshes/|" \
          -e "s|mesh: {size: 0.05, order: 1}|mesh: {size: $size, order: 1}|" \
          -e "s|rho_inf: 0.8}|rho_inf: 0.8, newton_reuse: $reuse}|" \
          "$root/tests/gradient/acf_pendulum/case.yaml" > "$scene/case.yaml"
      echo "output: {every: 50}" >> "$scene/case.yaml"
      mpirun -n "$ranks" "$flexopt" simulate "$scene" --gradient --out "$scene/out" > "$scene/log" 2>&1 ||
        { cat "$scene/log"; exit 1; }
      python3 - "$scene/out/summary.json" "$size" "$reuse" <<'EOF2' | tee -a "$results"
import json, sys
s = json.load(open(sys.argv[1]))
a = s["adjoint"]
dofs = sum(b.get("dofs", 0) for b in s["bodies"])
f, b = a["forward_s"], a["adjoint_s"]
newton = "proper" if float(sys.argv[3]) == 0 else f"kept ({sys.argv[3]})"
print(f"| {sys.argv[2]} m Tet4 | {newton} | {dofs} | {a['steps']} | {f:.3f} | {b:.3f} | {b / f:.2f} | {s['newton_factorizations_total']} | {a['adjoint_factorizations']} | {a['checkpoint_bytes'] / 1e6:.1f} | {s['peak_memory_mib']:.0f} |")
EOF2
    done
  done
fi
echo "wrote $results"
