# Sourced by the benchmark scripts: the repository root, the MPI environment, and
#   bench_build TARGET       configures build/ if needed and builds that target alone
#   bench_init NAME BINARY   the binary must exist; work=build/bench/NAME (or $FLEXOPT_BENCH_WORK)
#   bench_table "a | b | c"  starts $work/results.md with that header row and its separator
#   cantilever_case DIR NX NY NZ ITERATIONS "SOLVER"
#                            writes DIR/case.yaml and DIR/box.geo: cases/cantilever_topopt on an
#                            NX x NY x NZ Hex8 grid, the reference code's problem at that size (load
#                            0.001 per node of the load edge, cone filter radius 2.56 elements),
#                            ITERATIONS iterations with no stop on the design change, no design
#                            output, the PETSc options SOLVER
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
source "$root/scripts/env.sh"

bench_build() { # the log in build/TARGET_build.log
  local build="${FLEXOPT_BUILD_DIR:-$root/build}"
  [ -f "$build/CMakeCache.txt" ] || cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release > /dev/null
  cmake --build "$build" --target "$1" -j "$(nproc)" > "$build/$1_build.log" 2>&1 ||
    { tail -n 30 "$build/$1_build.log"; echo "build of $1 failed" >&2; exit 1; }
}

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

cantilever_case() {
  local dir="$1" nx="$2" ny="$3" nz="$4" iterations="$5" solver="$6"
  mkdir -p "$dir"
  sed -e "s/^nx = 32; ny = 16; nz = 16;.*/nx = $nx; ny = $ny; nz = $nz;/" "$root/meshes/box_2x1x1_hex.geo" > "$dir/box.geo"
  sed -e "s#../../meshes/box_2x1x1_hex.geo#box.geo#" \
      -e "s#value: \[0, 0, -0.016\]#value: [0, 0, -$(python3 -c "print(0.001*$ny)")]#" \
      -e "s/type: cone, radius: 0.16/type: cone, radius: $(python3 -c "print(2.56/$ny)")/" \
      -e "s/^optimizer: .*/optimizer: {max_iterations: $iterations, move_limit: 0.2, tolerance: 0}/" \
      -e "s/^output: .*/output: {every: 1000000}/" \
      -e "s/^solver: .*/solver: \"$solver\"/" "$root/cases/cantilever_topopt/case.yaml" > "$dir/case.yaml"
  grep -q "max_iterations: $iterations," "$dir/case.yaml" && grep -q "box.geo" "$dir/case.yaml" \
    || { echo "cantilever_case: cases/cantilever_topopt/case.yaml no longer has the lines it edits" >&2; exit 1; }
}
