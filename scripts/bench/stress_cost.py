#!/usr/bin/python3
"""What a stress constraint adds to a static design iteration (issue 43's 25 % target;
docs/benchmarks.md "Stress-constrained design"), measured side by side in one run.

Runs `flexopt optimize` on a case (default cases/lbracket_stress/compliance: compliance under a
volume bound, with a stress constraint that never binds) for ITERATIONS iterations on 2 ranks,
with its stress constraints and with them removed, alternating ROUNDS times, and prints the mean
seconds per iteration (iterations 2 onward: the first sets up the solvers) with its split
(history.csv seconds_<part>) and the ratio. `--solver S` replaces the case's solver: line (e.g.
--solver "-ksp_rtol 1e-8" for CG + GAMG); `--add C` appends the constraint C (a YAML flow map)
to the case's constraints for the run with stress (e.g. on cases/slider_crank_topopt:
--add "{type: stress, body: rod, max: 1.0e12}").
Usage: scripts/bench/stress_cost.py FLEXOPT OUT [--case DIR] [--iterations N (20)] [--rounds R (2)]
                                    [--solver OPTIONS] [--add CONSTRAINT]
"""
import argparse
import csv
import os
import re
import shutil
import subprocess

ap = argparse.ArgumentParser()
ap.add_argument("flexopt")
ap.add_argument("out")
root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
ap.add_argument("--case", default=os.path.join(root, "cases", "lbracket_stress", "compliance"))
ap.add_argument("--iterations", default="20")
ap.add_argument("--rounds", type=int, default=2)
ap.add_argument("--solver")
ap.add_argument("--add")
args = ap.parse_args()
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", FLEXOPT_REPORT="0")
shutil.rmtree(args.out, ignore_errors=True)
os.makedirs(args.out)
case = os.path.abspath(args.case)
text = open(os.path.join(case, "case.yaml")).read()
text = re.sub(r"geometry: ([^,}\s]+\.geo)",
              lambda m: "geometry: " + os.path.normpath(os.path.join(case, m.group(1))), text)
if args.add:
    text = re.sub(r"^constraints:\n", "constraints:\n  - " + args.add + "\n", text, count=1, flags=re.M)
if args.solver:
    text = re.sub(r"^solver:.*$", "", text, flags=re.M) + f'\nsolver: "{args.solver}"\n'
variants = {"with stress": text,
            "without stress": re.sub(r"^\s*- \{type: stress[^\n]*\n", "", text, flags=re.M)}
assert variants["with stress"] != variants["without stress"], "the case has no stress constraint"
times = {k: [] for k in variants}
for r in range(args.rounds):
    for name, t in variants.items():
        d = os.path.join(args.out, f"{name.replace(' ', '_')}_{r}")
        os.makedirs(d)
        open(os.path.join(d, "case.yaml"), "w").write(t)
        subprocess.run(["mpirun", "-n", "2", args.flexopt, "optimize", d, "--out", os.path.join(d, "out"),
                        "--max-iterations", args.iterations], env=env, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
        rows = list(csv.DictReader(open(os.path.join(d, "out", "history.csv"))))[1:]
        parts = ["seconds"] + [c for c in rows[0] if c.startswith("seconds_")]
        times[name] += [[float(x[c]) for c in parts] for x in rows]
mean = {k: [sum(col) / len(col) for col in zip(*v)] for k, v in times.items()}
for k, m in mean.items():
    split = ", ".join(f"{p[8:]} {x:.3f}" for p, x in zip(parts[1:], m[1:]))
    print(f"{k:16s} {m[0]:.3f} s/it ({split})")
print(f"ratio with / without: {mean['with stress'][0] / mean['without stress'][0]:.3f}")
