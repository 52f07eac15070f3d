#!/usr/bin/env bash
# Static-solve benchmark of a 3D cantilever (the beam of cases/cantilever, tip shear) at
# ~100k, ~400k and ~1.5M DOFs, Tet10 (unstructured, Gmsh) and Hex8 (structured, transfinite),
# with the default solver (CG + GAMG with the rigid-body near-null space, rtol 1e-8).
# Reports per run: DOFs, mesh (Gmsh + METIS + distribution), assembly, preconditioner set-up,
# Krylov solve, iterations, and peak memory (sum over ranks of the maximum resident set).
# At ~400k DOFs it also runs on 1 rank for the parallel speed-up.
#
#   scripts/bench/static.sh            # full study (about 10 minutes on 2 cores)
#   scripts/bench/static.sh --quick    # the ~100k runs only
# Extra PETSc options can be given in FLEXOPT_BENCH_OPTS. Results: build/bench/static/results.md
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
flexopt="$root/build/flexopt"
bench_init static "$flexopt"
quick=0; [ "${1:-}" = "--quick" ] && quick=1

write_case() { # dir geometry size order
  mkdir -p "$1"
  cat > "$1/case.yaml" <<YAML
analysis: static
materials:
  steel: {E: 2.1e11, nu: 0.3, density: 7850}
bodies:
  - name: beam
    geometry: $2
$( [ -n "$3" ] && echo "    mesh: {size: $3, order: $4}" )
    material: steel
supports:
  - {body: beam, surface: clamp, fix: [x, y, z]}
tractions:
  - {body: beam, surface: tip, value: [0, -1.0e6, 0]}
YAML
}

write_hex_geo() { # file nx ny nz
  cat > "$1" <<GEO
// Structured Hex8 beam 1 x 0.05 x 0.1 m, $2 x $3 x $4 elements.
Point(1) = {0, 0, 0}; Point(2) = {1, 0, 0}; Point(3) = {1, 0.05, 0}; Point(4) = {0, 0.05, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Transfinite Curve{1, 3} = $(( $2 + 1 )); Transfinite Curve{2, 4} = $(( $3 + 1 ));
Transfinite Surface{1}; Recombine Surface{1};
out[] = Extrude {0, 0, 0.1} { Surface{1}; Layers{$4}; Recombine; };
Physical Volume("beam") = {out[1]};
Physical Surface("clamp") = {out[5]};
Physical Surface("tip") = {out[3]};
GEO
}

bench_table "mesh | ranks | DOFs | mesh s | assembly s | PC set-up s | KSP its | KSP s | solve s | peak memory GiB | compliance J"

run() { # label dir ranks [repeats]: the repeat with the fastest solve is reported
  local best="" r
  for r in $(seq 1 "${4:-1}"); do
    local log="$2/run_np$3_$r.log" out="$2/out_np$3_$r"
    mpirun -n "$3" /usr/bin/time -f "rss_kb %M" "$flexopt" simulate "$2" --out "$out" ${FLEXOPT_BENCH_OPTS:-} > "$log" 2>&1 || { cat "$log"; exit 1; }
    awk '/^rss_kb/ {s += $2} END {printf "%.2f", s / 1048576}' "$log" > "$out/memory_gib"
    best=$(/usr/bin/python3 -c "import json,sys; a=sys.argv[1]; b=sys.argv[2]
print(b if not a or json.load(open(b+'/summary.json'))['solve_s'] < json.load(open(a+'/summary.json'))['solve_s'] else a)" "$best" "$out")
  done
  /usr/bin/python3 - "$1" "$3" "$(cat "$best/memory_gib")" "$best/summary.json" "${4:-1}" >> "$results" <<'PY'
import json, sys
label, ranks, mem, path, reps = sys.argv[1:]
s = json.load(open(path)); t = s["timings"]
best = f" (best of {reps})" if int(reps) > 1 else ""
print(f"| {label}{best} | {ranks} | {s['dofs']:,} | {t['mesh_s']:.1f} | {t['assemble_s']:.1f} | {t['pc_setup_s']:.1f} | "
      f"{s['solver_iterations']} | {t['ksp_solve_s']:.1f} | {s['solve_s']:.1f} | {mem} | {s['compliance']:.6f} |")
PY
  tail -n 1 "$results"
}

# Tet10 (Gmsh, unstructured): element sizes for ~100k, ~400k, ~1.5M DOFs.
tet_sizes="0.0103 0.0065 0.00418"; [ $quick = 1 ] && tet_sizes="0.0103"
for s in $tet_sizes; do
  d="$work/tet10_$s"; write_case "$d" "$root/meshes/beam.geo" "$s" 2
  if [ "$s" = "0.0065" ]; then run "Tet10 h=$s" "$d" 2 3; run "Tet10 h=$s" "$d" 1 3; else run "Tet10 h=$s" "$d" 2; fi
done
# Hex8 (structured): nx ny nz for ~100k, ~400k, ~1.5M DOFs.
hex_grids="182x9x18 286x14x29 450x23x45"; [ $quick = 1 ] && hex_grids="182x9x18"
for g in $hex_grids; do
  IFS=x read -r nx ny nz <<< "$g"
  d="$work/hex8_$g"; mkdir -p "$d"; write_hex_geo "$d/beam_hex.geo" "$nx" "$ny" "$nz"
  write_case "$d" beam_hex.geo "" ""
  if [ "$g" = "286x14x29" ]; then run "Hex8 $g" "$d" 2 3; run "Hex8 $g" "$d" 1 3; else run "Hex8 $g" "$d" 2; fi
done
echo
cat "$results"
