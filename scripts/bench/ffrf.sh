#!/usr/bin/env bash
# FFRF benchmark (docs/benchmarks.md):
#  1. reduction time against body DOFs: the spin-up beam (cases/spin_up_beam) meshed at
#     FLEXOPT_BENCH_SIZES (default 0.1 0.05 0.025 0.0143 m; 13k to 506k DOFs: the 10k,
#     ~100k and >= 500k points of the issue), 10 fixed-interface modes, no geometric
#     stiffening, on 2 ranks, one time step; the body's reduction_s in summary.json (assembly,
#     Craig-Bampton with SLEPc, M-orthonormal basis, invariants) and the run's wall_s (also
#     Gmsh meshing on rank 0 and partitioning);
#  2. steps per second of cases/slider_crank_flexible (0.1 s = 10,000 steps, no output) on one rank with
#     4, 10 and 20 fixed-interface modes (10, 16, 26 elastic coordinates);
#  3. the same with 10 modes and the rod meshed at FLEXOPT_BENCH_ROD_SIZES (default 0.004
#     0.003 0.002 m): the step cost does not depend on the body's mesh.
#
#   scripts/bench/ffrf.sh            # results in build/bench/ffrf/results.md
#   FLEXOPT_BIN=... FLEXOPT_BENCH_WORK=DIR FLEXOPT_BENCH_SIZES= scripts/bench/ffrf.sh
#                                    # another binary and directory, the slider-crank only
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
flexopt="${FLEXOPT_BIN:-$root/build/flexopt}"
bench_init ffrf "$flexopt"
FLEXOPT_BENCH_SIZES="${FLEXOPT_BENCH_SIZES-0.1 0.05 0.025 0.0143}" \
FLEXOPT_BENCH_ROD_SIZES="${FLEXOPT_BENCH_ROD_SIZES:-0.004 0.003 0.002}" /usr/bin/python3 - "$flexopt" "$root" "$work" <<'PY' | tee "$work/results.md"
import json, os, sys
flexopt, root, work = sys.argv[1:4]
sys.path.insert(0, os.path.join(root, "scripts"))
from case_variants import run_variant

print("| mesh size [m] | body DOFs | elements | elastic coordinates | reduction [s] | run wall [s] |")
print("|---|---|---|---|---|---|")
for size in os.environ["FLEXOPT_BENCH_SIZES"].split():
    name = f"reduce_{size}"
    run_variant(flexopt, os.path.join(root, "cases", "spin_up_beam"), work, name,
                [("size: 0.1,", f"size: {size},"),
                 ("modes: 8, geometric_stiffening: true", "modes: 10, geometric_stiffening: false"),
                 ("end: 12.0", "end: 2.0e-3")], ranks=2)
    s = json.load(open(os.path.join(work, name, "out", "summary.json")))
    b = s["bodies"][0]
    print(f"| {size} | {b['dofs']} | {b['elements']} | {b['elastic_coordinates']} | "
          f"{b['reduction_s']:.2f} | {s['wall_s']:.1f} |", flush=True)

print()
print("| slider-crank | elastic coordinates | coordinates + multipliers | Newton iterations / step | factorizations / step | steps/s | µs/step |")
print("|---|---|---|---|---|---|---|")
crank = os.path.join(root, "cases", "slider_crank_flexible")


def run_crank(name, modes, size="0.004"):
    """The slider-crank for 0.1 s without output, `modes` fixed-interface modes, the rod
    meshed at `size`; returns the summary and the rod's entry."""
    s = run_variant(flexopt, crank, work, name,
                    [("modes: 4, frame: chord}", f"modes: {modes}, frame: chord}}"), ("every: 10}", "every: 100000}"),
                     ("mesh: {size: 0.004, order: 2}", f"mesh: {{size: {size}, order: 2}}")],
                    ranks=1, end=0.1)
    return s, [b for b in s["bodies"] if b["name"] == "rod"][0]


for modes in (4, 10, 20):
    s, rod = run_crank(f"crank_{modes}", modes)
    print(f"| {modes} fixed-interface modes | {rod['elastic_coordinates']} | "
          f"{s['coordinates']} + {s['constraint_rows']} | "
          f"{s['newton_iterations_total'] / s['steps']:.2f} | "
          f"{s['newton_factorizations_total'] / s['steps']:.3f} | {s['steps_per_second']:.0f} | "
          f"{1e6 / s['steps_per_second']:.1f} |", flush=True)

print()
print("| slider-crank, 10 fixed-interface modes: rod mesh size [m] | rod DOFs | elastic coordinates | Newton iterations / step | factorizations / step | steps/s | µs/step |")
print("|---|---|---|---|---|---|---|")
for size in os.environ["FLEXOPT_BENCH_ROD_SIZES"].split():
    s, rod = run_crank(f"crank_mesh_{size}", 10, size)
    print(f"| {size} | {rod['dofs']} | {rod['elastic_coordinates']} | "
          f"{s['newton_iterations_total'] / s['steps']:.2f} | "
          f"{s['newton_factorizations_total'] / s['steps']:.3f} | {s['steps_per_second']:.0f} | "
          f"{1e6 / s['steps_per_second']:.1f} |", flush=True)
PY
