#!/usr/bin/env bash
# FFRF benchmark (docs/benchmarks.md):
#  1. reduction time against body DOFs: the spin-up beam (cases/spin_up_beam) meshed at
#     FLEXOPT_BENCH_SIZES (default 0.1 0.05 0.025 0.015 m; 13k to ~550k DOFs), 10
#     fixed-interface modes, no geometric stiffening, on 2 ranks, one time step; the body's
#     reduction_s in summary.json (assembly, Craig-Bampton with SLEPc, M-orthonormal basis,
#     invariants);
#  2. steps per second of cases/slider_crank_flexible (0.02 s, no output) on one rank with
#     4, 10 and 20 fixed-interface modes (10, 16, 26 elastic coordinates).
#
#   scripts/bench/ffrf.sh            # results in build/bench/ffrf/results.md
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
source "$root/scripts/env.sh"
flexopt="${FLEXOPT_BIN:-$root/build/flexopt}"
[ -x "$flexopt" ] || { echo "build flexopt first (scripts/build.sh)" >&2; exit 1; }
work="$root/build/bench/ffrf"
mkdir -p "$work"
FLEXOPT_BENCH_SIZES="${FLEXOPT_BENCH_SIZES:-0.1 0.05 0.025 0.015}" /usr/bin/python3 - "$flexopt" "$root" "$work" <<'PY' | tee "$work/results.md"
import json, os, sys
flexopt, root, work = sys.argv[1:4]
sys.path.insert(0, os.path.join(root, "scripts"))
from case_variants import run_variant

print("| mesh size [m] | body DOFs | elements | elastic coordinates | reduction [s] |")
print("|---|---|---|---|---|")
for size in os.environ["FLEXOPT_BENCH_SIZES"].split():
    name = f"reduce_{size}"
    run_variant(flexopt, os.path.join(root, "cases", "spin_up_beam"), work, name,
                [("size: 0.1,", f"size: {size},"),
                 ("modes: 8, geometric_stiffening: true", "modes: 10, geometric_stiffening: false"),
                 ("end: 12.0", "end: 2.0e-3")], ranks=2)
    b = json.load(open(os.path.join(work, name, "out", "summary.json")))["bodies"][0]
    print(f"| {size} | {b['dofs']} | {b['elements']} | {b['elastic_coordinates']} | "
          f"{b['reduction_s']:.2f} |", flush=True)

print()
print("| slider-crank | elastic coordinates | coordinates + multipliers | Newton iterations / step | steps/s | µs/step |")
print("|---|---|---|---|---|---|")
for modes in (4, 10, 20):
    s = run_variant(flexopt, os.path.join(root, "cases", "slider_crank_flexible"), work,
                    f"crank_{modes}", [("modes: 4}", f"modes: {modes}}}"),
                                       ("every: 10}", "every: 100000}")], ranks=1, end=0.02)
    rod = [b for b in s["bodies"] if b["name"] == "rod"][0]
    print(f"| {modes} fixed-interface modes | {rod['elastic_coordinates']} | "
          f"{s['coordinates']} + {s['constraint_rows']} | "
          f"{s['newton_iterations_total'] / s['steps']:.2f} | {s['steps_per_second']:.0f} | "
          f"{1e6 / s['steps_per_second']:.1f} |", flush=True)
PY
