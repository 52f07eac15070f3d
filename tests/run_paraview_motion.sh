#!/usr/bin/env bash
# Writes the motion output of three rigidly moving bodies on 2 ranks (the MPI test
# MotionOutput.RigidMotionOfThreeBodiesReadsBackExactly) and plays it in ParaView.
set -euo pipefail
mpi_tests="$1"; src="$2"; out="$3"
rm -rf "$out"
mkdir -p "$out"
FLEXOPT_MOTION_OUT="$out" mpirun -n 2 -x FLEXOPT_MOTION_OUT "$mpi_tests" \
  --gtest_filter=MotionOutput.RigidMotionOfThreeBodiesReadsBackExactly
pvpython --force-offscreen-rendering "$src/tests/paraview_motion.py" "$out"
