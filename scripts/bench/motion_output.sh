#!/usr/bin/env bash
# The motion output's cost per step (docs/output.md, "Cost"): builds and runs
# bench/motion_output.cpp on FLEXOPT_BENCH_RANKS ranks (default 2): 3 bodies x 1000 nodes for
# FLEXOPT_MOTION_STEPS steps (default 200) and 1 body x 100 000 nodes for
# FLEXOPT_MOTION_BIG_STEPS steps (default 20), positions and a displacement field each step.
# Prints the mesh write, the mean time per step (first and last tenth), MB per step and the close.
#
#   scripts/bench/motion_output.sh    # ≈ 10 s; the files and the printout in build/bench/motion_output
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
build="${FLEXOPT_BUILD_DIR:-$root/build}"
bench_build bench_motion_output
driver="$build/bench_motion_output"
bench_init motion_output "$driver"
mpirun -n "${FLEXOPT_BENCH_RANKS:-2}" "$driver" -out "$work" \
  -steps "${FLEXOPT_MOTION_STEPS:-200}" -big_steps "${FLEXOPT_MOTION_BIG_STEPS:-20}" | tee "$work/out.txt"
