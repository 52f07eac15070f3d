#!/usr/bin/env bash
# Install every package flexopt needs from Debian. Idempotent: packages already present are
# left alone and apt-get update only runs when something is missing.
#   scripts/install_deps.sh           # to build and run flexopt (scripts/run_case.sh)
#   scripts/install_deps.sh --tests   # and what the tests need besides (scripts/test.sh)
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config git
  petsc-dev slepc-dev
  libopenmpi-dev openmpi-bin
  libmetis-dev
  libopenblas0-serial # optimized BLAS/LAPACK for MUMPS, ScaLAPACK and LAPACK (replaces the
                      # reference BLAS through Debian's alternatives; 3x faster ACF steps)
  libblas-dev         # the BLAS link library (core/dense_blas.hpp's dgemm; OpenBLAS at run time)
  libhdf5-openmpi-dev
  gmsh libgmsh-dev
  libeigen3-dev
  libgtest-dev libgmock-dev
  libyaml-cpp-dev
  libmuparser-dev
  python3 python3-yaml python3-numpy python3-scipy python3-h5py
  python3-paraview   # tests open the XDMF output with ParaView's own reader
  paraview           # pvbatch: `flexopt report` renders the designs and the motion
  xvfb               # Xvfb: that rendering where there is no display
  python3-matplotlib # `flexopt report`'s plots; scripts/study_ffrf_vs_acf.py
)
if [ "${1:-}" = "--tests" ]; then
  PACKAGES+=(
    chromium # tests/check_report.py opens the report's index.html in headless Chromium
  )
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install_deps: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "install_deps: done"
