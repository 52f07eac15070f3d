#!/usr/bin/env bash
# Set up (Debian packages), build, and run the test suite with CTest.
#   scripts/test.sh          # unit, 2-rank MPI, regression and bad-input tests (two at a time:
#                            # ctest -j 2, a test with 2 ranks alone; tests/CMakeLists.txt)
#   scripts/test.sh --long   # also the long studies (CTest label "long")
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
long=0
for a in "$@"; do
  case "$a" in
    --long) long=1 ;;
    *) echo "usage: scripts/test.sh [--long]" >&2; exit 2 ;;
  esac
done
"$root/scripts/install_deps.sh" --tests
"$root/scripts/build.sh"
source "$root/scripts/env.sh"
cd "${FLEXOPT_BUILD_DIR:-$root/build}"
if [ "$long" = 1 ]; then
  ctest --output-on-failure --timeout 3600 -j 2
else
  ctest --output-on-failure --timeout 900 -LE long -j 2
fi
