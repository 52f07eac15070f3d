#!/usr/bin/python3
"""The qp-relaxation's exponent q against the design it leads to (docs/theory.md 5.1 "Which q",
docs/benchmarks.md "Stress-constrained design").

Runs cases/lbracket_stress (as it is: initial 0.5, projection, adaptive p-norm) on 2 ranks once
per q in QS (`design.interpolation.stress_exponent`), and prints per run the final volume
fraction, the true peak over the limit, the grey share (design elements with physical density
in (0.1, 0.9)) and the mean volume over the last 50 iterations with its range (the adaptive
normalization keeps moving it).
Usage: scripts/bench/stress_relaxation.py FLEXOPT OUT [Q ...] (default 0.5 1.5 2.0 2.5)
"""
import csv
import json
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

flexopt, out = sys.argv[1:3]
qs = [float(q) for q in sys.argv[3:]] or [0.5, 1.5, 2.0, 2.5]
case = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "cases", "lbracket_stress")
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", FLEXOPT_REPORT="0")
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
rows = []
for q in qs:
    d = os.path.join(out, f"q_{q:g}")
    os.makedirs(d)
    shutil.copy(os.path.join(case, "lbracket.geo"), d)
    text = open(os.path.join(case, "case.yaml")).read()
    text = text.replace("  filter: {type: cone, radius: 0.0025}",
                        f"  filter: {{type: cone, radius: 0.0025}}\n  interpolation: {{stress_exponent: {q}}}")
    open(os.path.join(d, "case.yaml"), "w").write(text)
    subprocess.run(["mpirun", "-n", "2", flexopt, "optimize", d, "--out", os.path.join(d, "out")], env=env,
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    s = json.load(open(os.path.join(d, "out", "summary.json")))
    with h5py.File(os.path.join(d, "out", "design.h5"), "r") as f:
        last = max((k for k in f if k.startswith("step_")), key=lambda k: int(k[5:]))
        rho = f[last]["physical_density"][:]
    design = rho < 1.0  # the pad stays at 1 exactly
    grey = float(np.mean((rho[design] > 0.1) & (rho[design] < 0.9)))
    vols = [float(r["objective"]) for r in csv.DictReader(open(os.path.join(d, "out", "history.csv")))][-50:]
    rows.append((q, s["volume_fraction"], s["problem"]["stress"][0]["peak_over_max"], grey,
                 sum(vols) / len(vols), min(vols), max(vols)))
    print(f"q {q:g}: volume {rows[-1][1]:.3f}, peak/limit {rows[-1][2]:.3f}, grey {grey:.3f}, last 50: "
          f"{rows[-1][4]:.3f} ({rows[-1][5]:.3f} ... {rows[-1][6]:.3f})", flush=True)
print("\n| q | volume fraction | peak / limit | grey share | volume, last 50 iterations |")
print("|---|---|---|---|---|")
for r in rows:
    print(f"| {r[0]:g} | {r[1]:.3f} | {r[2]:.3f} | {r[3]:.3f} | {r[4]:.3f} ({r[5]:.3f} … {r[6]:.3f}) |")
