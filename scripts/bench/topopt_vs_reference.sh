#!/usr/bin/env bash
# Static topology optimization side by side with the published PETSc code of Aage, Andreassen &
# Lazarov (2015), TopOpt_in_PETSc: the same cantilever (Hex8 box 2 x 1 x 1, volume fraction
# 0.12, penalty 3, cone filter of 2.56 elements, Krylov rtol 1e-5), the same grid, 2 ranks each,
# run in alternating pairs on this machine; prints the time ratio per pair and per iteration and
# the Krylov iterations of every state solve, and the time to the same answer (flexopt until it
# reaches the reference's iteration-20 compliance, against the reference's 20 iterations).
#
# The reference is built outside this repository (docs/benchmarks.md "Side by side with the
# reference code" says how) and its executable named by the environment:
#   FLEXOPT_TOPOPT_REFERENCE=/path/to/TopOpt_in_PETSc/topopt scripts/bench/topopt_vs_reference.sh
# Environment (defaults): FLEXOPT_BENCH_GRID=64x32x32 (elements; each divisible by 2^(levels-1)),
# FLEXOPT_BENCH_ITERATIONS=50, FLEXOPT_BENCH_PAIRS=2, FLEXOPT_BENCH_OPTIONS="" (more PETSc options
# for flexopt), FLEXOPT_REFERENCE_OPTIONS="" (more options for the reference, e.g. -nlvls 3 where
# a grid side is not divisible by 8).
# Times: the reference's own per-iteration clock ("It.: k ... time: t", design update to design
# update, without its file output); flexopt's history.csv seconds (the same span; its design
# output is switched off here). Results: build/bench/topopt_vs_reference/results.md and
# results.json.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
flexopt="$root/build/flexopt"
bench_init topopt_vs_reference "$flexopt"
reference="${FLEXOPT_TOPOPT_REFERENCE:-}"
if [ -z "$reference" ] || [ ! -x "$reference" ]; then
  echo "topopt_vs_reference: set FLEXOPT_TOPOPT_REFERENCE to the reference code's executable" >&2
  echo "  (got '${reference}'); docs/benchmarks.md says how to fetch and build it outside" >&2
  echo "  this repository against Debian's PETSc." >&2
  exit 2
fi
grid="${FLEXOPT_BENCH_GRID:-64x32x32}"
iterations="${FLEXOPT_BENCH_ITERATIONS:-50}"
pairs="${FLEXOPT_BENCH_PAIRS:-2}"
IFS=x read -r nx ny nz <<< "$grid"
# The reference's filter radius is in length units: 2.56 elements of the 1-long side.
rmin=$(python3 -c "print(2.56/$ny)")

d="$work/$grid"; mkdir -p "$d"
cantilever_case "$d/case" "$nx" "$ny" "$nz" "$iterations" "-ksp_rtol 1e-5"

run_reference() { # $1: run directory
  rm -rf "$1"; mkdir -p "$1"
  (cd "$1" && mpirun -n 2 "$reference" -nx $((nx + 1)) -ny $((ny + 1)) -nz $((nz + 1)) \
     -rmin "$rmin" -maxItr "$iterations" ${FLEXOPT_REFERENCE_OPTIONS:-} > log.txt 2>&1) \
    || { tail -20 "$1/log.txt"; echo "topopt_vs_reference: the reference run failed ($1/log.txt)" >&2; exit 1; }
  rm -f "$1"/output_* "$1"/Restart* # its VTK and restart files (tens of MB each)
}
run_flexopt() { # $1: run directory
  rm -rf "$1"
  mpirun -n 2 "$flexopt" optimize "$d/case" --out "$1" ${FLEXOPT_BENCH_OPTIONS:-} > "$d/$(basename "$1").log" 2>&1 \
    || { tail -20 "$d/$(basename "$1").log"; echo "topopt_vs_reference: the flexopt run failed" >&2; exit 1; }
}

for p in $(seq 1 "$pairs"); do
  # Alternate which runs first: a slow spell of the machine then hits both sides.
  if [ $((p % 2)) -eq 1 ]; then
    run_reference "$d/reference$p"; run_flexopt "$d/flexopt$p"
  else
    run_flexopt "$d/flexopt$p"; run_reference "$d/reference$p"
  fi
  echo "pair $p of $pairs done"
done

/usr/bin/python3 - "$d" "$grid" "$iterations" "$pairs" "$results" "$work/results.json" <<'PY'
import csv, json, re, sys
d, grid, its, pairs, out_md, out_json = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5], sys.argv[6]

def reference(p):
    log = open(f"{d}/reference{p}/log.txt").read()
    t = [float(x) for x in re.findall(r"^It\.: *\d+,.*time: *(\S+)", log, re.M)]
    f = [float(x) for x in re.findall(r"^It\.: *\d+, True fx: *(\S+),", log, re.M)]
    k = [int(x) for x in re.findall(r"^State solver: *iter: *(\d+)", log, re.M)]
    return t, f, k

def flexopt(p):
    rows = list(csv.DictReader(open(f"{d}/flexopt{p}/history.csv")))
    s = json.load(open(f"{d}/flexopt{p}/summary.json"))
    return ([float(r["seconds"]) for r in rows], [float(r["objective"]) for r in rows],
            [int(k) for k in s["problem"]["krylov_iterations"]], s)

runs = []
for p in range(1, pairs + 1):
    rt, rf, rk = reference(p)
    ft, ff, fk, s = flexopt(p)
    n = min(len(rt), len(ft), its)
    if n < its:
        sys.exit(f"topopt_vs_reference: pair {p}: reference {len(rt)}, flexopt {len(ft)} iterations of {its}")
    runs.append(dict(ref_t=rt[:n], ref_f=rf[:n], ref_k=rk[:n], fx_t=ft[:n], fx_f=ff[:n], fx_k=fk[:n]))
dofs = 3 * (int(grid.split("x")[0]) + 1) * (int(grid.split("x")[1]) + 1) * (int(grid.split("x")[2]) + 1)
mean = lambda v: sum(v) / len(v)
lines = [f"Grid {grid} ({dofs:,} DOFs), 2 ranks each, {its} iterations, {pairs} alternating pairs.", "",
         "| pair | reference s/it | flexopt s/it | flexopt / reference | reference Krylov its (1st → last) | flexopt Krylov its (1st → last) |",
         "|---|---|---|---|---|---|"]
for p, r in enumerate(runs, 1):
    lines.append(f"| {p} | {mean(r['ref_t']):.2f} | {mean(r['fx_t']):.2f} | {mean(r['fx_t']) / mean(r['ref_t']):.2f} | "
                 f"{r['ref_k'][0]} → {r['ref_k'][-1]} | {r['fx_k'][0]} → {r['fx_k'][-1]} |")
rt = [mean([r["ref_t"][k] for r in runs]) for k in range(its)]
ft = [mean([r["fx_t"][k] for r in runs]) for k in range(its)]
lines += ["", f"Mean over the pairs: reference {mean(rt):.2f} s/it, flexopt {mean(ft):.2f} s/it, "
              f"**flexopt / reference {mean(ft) / mean(rt):.2f}**.", "",
          "| iteration | reference s | flexopt s | ratio | reference Krylov its | flexopt Krylov its | reference objective | flexopt objective |",
          "|---|---|---|---|---|---|---|---|"]
for k in range(its):
    lines.append(f"| {k + 1} | {rt[k]:.2f} | {ft[k]:.2f} | {ft[k] / rt[k]:.2f} | {runs[0]['ref_k'][k]} | {runs[0]['fx_k'][k]} | "
                 f"{runs[0]['ref_f'][k]:.6g} | {runs[0]['fx_f'][k]:.6g} |")
# Time to the same answer: flexopt's time until its compliance first reaches the reference's at
# iteration N (20, or the last run if fewer), against the reference's time for its N iterations.
target_it = min(20, its)
to_answer = []
for p, r in enumerate(runs, 1):
    target = r["ref_f"][target_it - 1]
    k = next((i + 1 for i, f in enumerate(r["fx_f"]) if f <= target), None)
    if k is None:
        lines.append(f"Pair {p}: flexopt does not reach the reference's iteration-{target_it} compliance "
                     f"{target:.6g} within {its} iterations.")
        continue
    ratio = sum(r["fx_t"][:k]) / sum(r["ref_t"][:target_it])
    to_answer.append(ratio)
    lines.append(f"Pair {p}: the reference's iteration-{target_it} compliance {target:.6g} reached by flexopt at "
                 f"iteration {k}: time to the same answer **{ratio:.3f}** of the reference's.")
open(out_md, "w").write("\n".join(lines) + "\n")
json.dump(dict(grid=grid, dofs=dofs, iterations=its, runs=runs, ratio=mean(ft) / mean(rt),
               time_to_answer=to_answer), open(out_json, "w"), indent=1)
print("\n".join(lines))
PY
