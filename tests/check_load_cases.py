#!/usr/bin/python3
"""Static load cases (issue 45), facts that hold for any correct implementation:
  - Compliance is a quadratic form in the load, C(f) = f.K^-1 f, so C(f1) + C(f2) =
    C((f1 + f2)/sqrt 2) + C((f1 - f2)/sqrt 2) for every design: an optimization of the summed
    compliance over load cases {f1, f2} and one over {(f1 + f2)/sqrt 2, (f1 - f2)/sqrt 2} are the
    same problem, and their objective histories agree to TOL relative (the two differ by the
    rounding of the loads' sums only);
  - the case's two load cases are mirror images of each other about the plate's mid-height, on a
    mirror-symmetric mesh, so the summed design stays symmetric and the two load cases'
    compliances agree to TOL relative (summary.json problem.scenario_responses);
  - `flexopt simulate CASE --design restart.h5` solves every load case at that design, writes
    static.NAME.xdmf for each, and its compliances are those of the responses it reports.
Usage: check_load_cases.py FLEXOPT CASE OUT N TOL
"""
import json
import math
import os
import re
import shutil
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

flexopt, case, out, n, tol = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), float(sys.argv[5])
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
failures = []


def run(args, ranks=2):
    return mpi_job.flexopt(flexopt, args, ranks)


def rel(a, b):
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


# The rotated load cases: (f1 + f2)/sqrt 2 and (f1 - f2)/sqrt 2 from the case's lower (f1, on
# corner_bottom) and upper (f2, on corner_top) load cases.
text = open(os.path.join(case, "case.yaml")).read()
loads = dict(re.findall(r"curve: (corner_\w+), value: \[0, (-?[0-9.]+), 0\]", text))
f1, f2 = float(loads["corner_bottom"]), float(loads["corner_top"])
s = 1 / math.sqrt(2)
rotated_cases = (
    "load_cases:\n"
    "  - name: sum\n"
    f"    line_loads: [{{body: plate, curve: corner_bottom, value: [0, {s * f1!r}, 0]}},\n"
    f"                 {{body: plate, curve: corner_top, value: [0, {s * f2!r}, 0]}}]\n"
    "  - name: difference\n"
    f"    line_loads: [{{body: plate, curve: corner_bottom, value: [0, {s * f1!r}, 0]}},\n"
    f"                 {{body: plate, curve: corner_top, value: [0, {-s * f2!r}, 0]}}]\n")
start, end = text.index("load_cases:\n"), text.index("design:\n")
rotated = os.path.join(out, "rotated")
os.makedirs(rotated)
geometry = os.path.abspath(os.path.join(case, "square_slab.geo"))
open(os.path.join(rotated, "case.yaml"), "w").write(
    (text[:start] + rotated_cases + text[end:]).replace("square_slab.geo", geometry))

histories = {}
for name, d in (("case", case), ("rotated", rotated)):
    o = os.path.join(out, name + "_out")
    run(["optimize", d, "--out", o, "--max-iterations", str(n)])
    histories[name] = json.load(open(os.path.join(o, "summary.json")))
a, b = histories["case"], histories["rotated"]
worst = max(rel(x, y) for x, y in zip(a["objective"], b["objective"]))
print(f"summed compliance, {{f1, f2}} against {{(f1 +- f2)/sqrt 2}}: {len(a['objective'])} "
      f"iterations, largest relative difference {worst:.2e} (tolerance {tol:g})")
if len(a["objective"]) != n or len(b["objective"]) != n or worst > tol:
    failures.append(f"the rotated load cases' history differs by {worst:.2e} (> {tol:g}) or "
                    f"has another length ({len(a['objective'])}, {len(b['objective'])}, {n})")

per = a["problem"]["scenario_responses"]
lower, upper = per["lower"]["objective:compliance"], per["upper"]["objective:compliance"]
print(f"mirror symmetry: lower {lower!r}, upper {upper!r}, relative difference {rel(lower, upper):.2e}")
if rel(lower, upper) > tol:
    failures.append(f"the mirror-image load cases' compliances differ by {rel(lower, upper):.2e}")

d = os.path.join(out, "simulate")
run(["simulate", case, "--out", d, "--design", os.path.join(out, "case_out", "restart.h5")])
sim = json.load(open(os.path.join(d, "summary.json")))
total = 0.0
for name in ("lower", "upper"):
    one = sim["load_cases"][name]
    total += one["compliance"]
    if not os.path.exists(os.path.join(d, f"static.{name}.xdmf")):
        failures.append(f"{d}: no static.{name}.xdmf")
    if rel(one["compliance"], one["responses"]["objective"]) > 1e-10:
        failures.append(f"load case {name}: compliance {one['compliance']!r} is not the objective "
                        f"{one['responses']['objective']!r} it reports")
print(f"simulate --design: compliances {sim['load_cases']['lower']['compliance']!r}, "
      f"{sim['load_cases']['upper']['compliance']!r} (sum {total!r})")
if rel(sim["load_cases"]["lower"]["compliance"], sim["load_cases"]["upper"]["compliance"]) > tol:
    failures.append("simulate --design: the mirror-image load cases' compliances differ")

if failures:
    sys.exit("FAIL:\n  " + "\n  ".join(failures))
print("OK")
