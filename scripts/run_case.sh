#!/usr/bin/env bash
# Set up (Debian packages), build, and run a case on 2 MPI ranks.
#   scripts/run_case.sh cases/first_link optimize     # a link designed inside a running mechanism
#   scripts/run_case.sh cases/cantilever              # flexopt simulate
#   scripts/run_case.sh cases/beam_modes modes --count 6
# Extra arguments after the command go to flexopt (including PETSc options).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ $# -lt 1 ]; then
  echo "usage: scripts/run_case.sh CASE_DIR [command] [flexopt/PETSc options]" >&2
  exit 2
fi
case_dir="$1"; shift
command="${1:-simulate}"; [ $# -gt 0 ] && shift
[ -f "$case_dir/case.yaml" ] || { echo "run_case.sh: no case.yaml in '$case_dir'" >&2; exit 2; }
"$root/scripts/install_deps.sh"
"$root/scripts/build.sh" flexopt
source "$root/scripts/env.sh"
ranks="${FLEXOPT_RANKS:-2}"
echo "run_case.sh: mpirun -n $ranks build/flexopt $command $case_dir $*"
mpirun -n "$ranks" "$root/build/flexopt" "$command" "$case_dir" "$@"
out="$case_dir/out"
prev=""
for a in "$@"; do
  [ "$prev" = "--out" ] && out="$a"
  prev="$a"
done
echo "run_case.sh: results in $out/ (open the .xdmf files in ParaView; figures in $out/summary.json)"
if [ -f "$out/report/index.html" ]; then
  echo "run_case.sh: pictures in $out/report/ (open $out/report/index.html in a browser)"
fi
