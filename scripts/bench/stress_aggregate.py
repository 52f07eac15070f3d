#!/usr/bin/python3
"""The stress aggregate's parameter against the gap to the true peak and the iterations needed
(docs/benchmarks.md "Stress-constrained design", issue 43).

Runs `flexopt optimize` on cases/lbracket_stress at a coarser mesh (h = 2 mm, one layer through
the thickness, filter radius 5 mm: the study compares aggregates, not resolutions) on 1 rank,
once per aggregate: p-norm P = 4, 8, 16, 32 and KS k = 10, 20, 40 (relative to the limit), each
without normalization and the p-norm P = 8 with `normalization: adaptive`. Prints per run the
final volume fraction, the aggregate R and the true peak M at the end (R/M: what the constraint
gives away; M/limit: how far below the limit the true peak ends), the iterations run (the stop
rule or the limit) and the seconds.
Usage: scripts/bench/stress_aggregate.py FLEXOPT OUT [ITERATIONS (default 300)]
"""
import json
import os
import re
import shutil
import subprocess
import sys
import time

flexopt, out = sys.argv[1:3]
iterations = sys.argv[3] if len(sys.argv) > 3 else "300"
case = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "cases", "lbracket_stress")
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           FLEXOPT_REPORT="0")
RUNS = [("pnorm P=4", "aggregate: pnorm, p: 4"), ("pnorm P=8", "aggregate: pnorm, p: 8"),
        ("pnorm P=16", "aggregate: pnorm, p: 16"), ("pnorm P=32", "aggregate: pnorm, p: 32"),
        ("ks k=10", "aggregate: ks, ks: 10"), ("ks k=20", "aggregate: ks, ks: 20"),
        ("ks k=40", "aggregate: ks, ks: 40"),
        ("pnorm P=8 adaptive", "aggregate: pnorm, p: 8, normalization: adaptive")]
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
rows = []
for name, aggregate in RUNS:
    d = os.path.join(out, re.sub(r"[^a-z0-9]+", "_", name.lower()))
    os.makedirs(d)
    geo = open(os.path.join(case, "lbracket.geo")).read()
    geo = re.sub(r"^h = [^;]*; t = ([^;]*); layers = [^;]*;", r"h = 2.0e-3; t = \1; layers = 1;", geo,
                 flags=re.M)
    open(os.path.join(d, "lbracket.geo"), "w").write(geo)
    text = open(os.path.join(case, "case.yaml")).read()
    text = re.sub(r"filter: \{type: cone, radius: [^}]*\}", "filter: {type: cone, radius: 0.005}", text)
    text = re.sub(r"\{type: stress, aggregate: [^}]*max: 100.0e6[^}]*\}",
                  "{type: stress, " + aggregate + ", max: 100.0e6, region: design}", text)
    open(os.path.join(d, "case.yaml"), "w").write(text)
    t0 = time.time()
    p = subprocess.run(["mpirun", "-n", "1", flexopt, "optimize", d, "--out", os.path.join(d, "out"),
                        "--max-iterations", iterations], env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True, timeout=7200)
    seconds = time.time() - t0
    if p.returncode != 0:
        print(p.stdout[-3000:])
        sys.exit(f"FAIL: {name}: flexopt exited with {p.returncode}")
    s = json.load(open(os.path.join(d, "out", "summary.json")))
    st = s["problem"]["stress"][0]
    rows.append((name, s["volume_fraction"], st["unscaled_value"] / st["peak"], st["peak"] / 100.0e6,
                 s["iterations"], s["converged"], seconds))
    print(f"{name:20s} volume {rows[-1][1]:.4f}  R/M {rows[-1][2]:.4f}  M/limit {rows[-1][3]:.4f}  "
          f"iterations {rows[-1][4]:4d}{' (converged)' if rows[-1][5] else ''}  {seconds:.0f} s", flush=True)
print("\n| aggregate | volume fraction | R / M (end) | M / limit (end) | iterations | s |")
print("|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r[0]} | {r[1]:.3f} | {r[2]:.3f} | {r[3]:.3f} | {r[4]}{' (converged)' if r[5] else ''} | {r[6]:.0f} |")
