# Sourced by the benchmark scripts: the repository root, the MPI environment, and
#   bench_init NAME BINARY   the binary must exist; work=build/bench/NAME (or $FLEXOPT_BENCH_WORK)
#   bench_table "a | b | c"  starts $work/results.md with that header row and its separator
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
source "$root/scripts/env.sh"

bench_init() {
  [ -x "$2" ] || { echo "$2 missing: build first (scripts/build.sh)" >&2; exit 1; }
  work="${FLEXOPT_BENCH_WORK:-$root/build/bench/$1}"
  mkdir -p "$work"
  results="$work/results.md"
}

bench_table() {
  local columns separator
  columns=$(echo "$1" | awk -F'|' '{ print NF }')
  separator=$(printf '|---%.0s' $(seq 1 "$columns"))
  { echo "| $1 |"; echo "$separator|"; } > "$results"
}
