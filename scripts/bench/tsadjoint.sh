#!/usr/bin/env bash
# PETSc TSAdjoint side by side with flexopt's dynamic adjoint (docs/benchmarks.md, "Dynamic
# adjoint", "Against PETSc TSAdjoint"): builds scripts/bench/tsadjoint/ts_adjoint_bench.cpp
# against the installed PETSc (pkg-config petsc) and times TSSolve (forward) and TSAdjointSolve
# (backward sweep) for Crank-Nicolson (TSCN, fixed step) on a mass-spring lattice with nonlinear
# springs, one stiffness parameter per spring, cost u_y(tip, T) + int mean |u|^2 dt:
#   dense  10-mass chain, 40 unknowns, MATSEQDENSE + LU, 2,000 steps of 1 ms
#   sparse 16 x 16 lattice, 1,024 unknowns, AIJ + PETSc's LU, 500 steps of 10 ms
#   sparse 50 x 50 lattice, 10,000 unknowns, AIJ + PETSc's LU, 50 steps of 10 ms
# each with the forward run by Newton's method proper (PETSc's default SNES: a Jacobian and an LU
# per iteration), with the Jacobian kept for the whole run (-snes_lag_jacobian -2
# -snes_lag_jacobian_persists) and renewed every 10 Newton iterations across steps
# (-snes_lag_jacobian 10 -snes_lag_jacobian_persists); the trajectory in memory
# (-ts_trajectory_type memory) and with the default (basic: one file per step on disk). The
# backward sweep always uses exact Jacobians (the program resets the lag before it). Prints
# forward_s, adjoint_s, their ratio, Newton iterations, Jacobian evaluations, LU factorizations
# and residual evaluations of both phases, each line the median (by ratio) of
# FLEXOPT_BENCH_REPEAT runs (default 3) on 1 rank; then a finite-difference check of the
# gradient in 3 stiffnesses (central differences, relative error).
#
#   scripts/bench/tsadjoint.sh     # ~ 3 min; results in build/bench/tsadjoint/results.md
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
build="$root/build/bench/tsadjoint"
bin="$build/ts_adjoint_bench"
mkdir -p "$build"
pkg-config --exists petsc || { echo "PETSc not found by pkg-config (package petsc)" >&2; exit 1; }
# shellcheck disable=SC2046
mpicxx -std=c++17 -O2 -Wall $(pkg-config --cflags petsc) "$root/scripts/bench/tsadjoint/ts_adjoint_bench.cpp" \
  -o "$bin" $(pkg-config --libs petsc)
bench_init tsadjoint "$bin"
repeat="${FLEXOPT_BENCH_REPEAT:-3}"
cd "$work"  # the basic trajectory writes its files (SA-data/) here

declare -A case_args=(
  [dense]="-dense -nx 10 -ny 1 -k 1e4 -steps 2000 -dt 1e-3"
  [sparse_1k]="-nx 16 -ny 16 -k 1e3 -steps 500 -dt 1e-2"
  [sparse_10k]="-nx 50 -ny 50 -k 1e3 -steps 50 -dt 1e-2")
declare -A newton_args=(
  [proper]=""
  [kept]="-snes_lag_jacobian -2 -snes_lag_jacobian_persists"
  [lag10]="-snes_lag_jacobian 10 -snes_lag_jacobian_persists")
declare -A newton_label=([proper]="proper" [kept]="kept (lag -2)" [lag10]="lag 10")
declare -A traj_args=([memory]="-ts_trajectory_type memory" [default]="")

# the program's "key=value ..." line as the fields of a table row, the ratio first
row() {
  python3 - "$1" <<'PY'
import sys
r = dict(kv.split("=", 1) for kv in sys.argv[1].split() if "=" in kv)
f, b, n = float(r["forward_s"]), float(r["adjoint_s"]), int(r["steps"])
print(f"{b / f:.3f} {r['unknowns']} {r['params']} {n} {r['trajectory']} {f:.4f} {b:.4f}",
      f"{int(r['newton_fwd']) / n:.2f} {r['J_fwd']}/{r['J_adj']} {r['lu_fwd']}/{r['lu_adj']}",
      f"{r['F_fwd']}/{r['F_adj']}")
PY
}

bench_table "case | Newton (forward) | trajectory | unknowns | parameters | steps | forward_s | adjoint_s | adjoint / forward | Newton its / step | Jacobians fwd / adj | LU fwd / adj | residuals fwd / adj"
cat "$results"
for c in dense sparse_1k sparse_10k; do
  for newton in proper kept lag10; do
    for traj in memory default; do
      rows=()
      for r in $(seq 1 "$repeat"); do
        # shellcheck disable=SC2086
        out=$(mpirun -n 1 "$bin" ${case_args[$c]} ${newton_args[$newton]} ${traj_args[$traj]} 2>&1) ||
          { echo "$out"; exit 1; }
        rows+=("$(row "$(echo "$out" | grep '^unknowns=')")")
      done
      median=$(printf '%s\n' "${rows[@]}" | sort -t' ' -k1,1n | sed -n "$(( (repeat + 1) / 2 ))p")
      read -r ratio n np steps tj f b its jac lu res <<< "$median"
      echo "| $c | ${newton_label[$newton]} | $tj | $n | $np | $steps | $f | $b | $ratio | $its | $jac | $lu | $res |" | tee -a "$results"
    done
  done
done

{ echo; echo "| gradient check | Newton (forward) | parameter | adjoint | central difference | relative error |"
  echo "|---|---|---|---|---|---|"; } | tee -a "$results"
for check in dense:proper dense:kept dense:lag10 sparse_1k:proper sparse_1k:kept; do
  c=${check%%:*}
  newton=${check##*:}
  # shellcheck disable=SC2086
  out=$(mpirun -n 1 "$bin" ${case_args[$c]} ${newton_args[$newton]} -ts_trajectory_type memory -fd_check 2>&1) ||
    { echo "$out"; exit 1; }
  python3 - "$c" "${newton_label[$newton]}" "$out" <<'PY' | tee -a "$results"
import sys
for line in sys.argv[3].splitlines():
    if line.startswith("fd_check"):
        r = dict(kv.split("=", 1) for kv in line.split()[1:])
        print(f"| {sys.argv[1]} | {sys.argv[2]} | k_{r['param']} | {r['adjoint']} | {r['fd']} | {r['rel_err']} |")
PY
done
echo "wrote $results"
