#!/usr/bin/env bash
# Configure and build flexopt in build/ (Release). Used by run_case.sh and test.sh.
#   scripts/build.sh            # everything: flexopt and the test programs (scripts/test.sh)
#   scripts/build.sh flexopt    # the program alone (scripts/run_case.sh: a first run builds
#                               # only what it runs)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${FLEXOPT_BUILD_DIR:-$root/build}"
mkdir -p "$build"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE="${CMAKE_BUILD_TYPE:-Release}" > "$build/configure.log" 2>&1 || {
  cat "$build/configure.log"; echo "build.sh: CMake configuration failed" >&2; exit 1; }
cmake --build "$build" -j "$(nproc)" ${1:+--target "$1"}
