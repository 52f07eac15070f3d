#!/usr/bin/env python3
"""The plan's kineto-elastodynamic (KED) estimate against the FFRF simulation it stands for
(docs/theory.md section 12.1).

The spin-up beam (cases/spin_up_beam) made stiffer, so that it spins well below its first
bending frequency, run two ways:

  - `flexopt plan`: the beam held rigid in the spin-up, the linear elastic response of its
    Craig-Bampton model (40 fixed-interface modes) to that forcing, one-way coupled;
  - `flexopt simulate` with the beam as linear FFRF (8 modes), which also has the terms KED
    leaves out: the centrifugal softening -Omega^2 of the bending stiffness (the effective
    stiffness w1^2 - Omega^2), Coriolis coupling and the feedback of the elastic motion.

Their largest tip deflection differs by the left-out terms, of relative size r = (Omega/w1)^2
(the softening amplifies the quasi-static deflection by 1 / (1 - r)). For E x 100 and E x 400
(r = 0.010 and 0.0025) the check is: the relative difference is at most 2 r, and it falls by
at least 2.5 from the first to the second (4 expected: the difference is O(r)).

usage: check_ked.py FLEXOPT CASES OUT [--ranks N]
"""
import argparse, json, os, re, shutil, sys

import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

p = argparse.ArgumentParser()
p.add_argument("flexopt")
p.add_argument("cases")
p.add_argument("out")
p.add_argument("--ranks", type=int, default=2)
a = p.parse_args()
os.makedirs(a.out, exist_ok=True)
meshes = os.path.join(os.path.abspath(a.cases), "..", "meshes")

ok = True
def check(cond, what):
    global ok
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    ok = ok and cond

def run(args):
    cmd = ["mpirun", "-n", str(a.ranks), a.flexopt] + args
    print("$ " + " ".join(cmd), flush=True)
    r = mpi_job.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        print(r.stdout[-3000:], r.stderr[-3000:])
        sys.exit(1)
    return r.stdout

base = open(os.path.join(a.cases, "spin_up_beam", "case.yaml")).read()
base = base.replace("geometry: ../../meshes/", "geometry: " + meshes + "/")
base = base[:base.index("# The beam as a design body")]  # no design: the beam as it is
E0 = 4.6666666666666667e9
results = []
for factor in (100, 400):
    d = os.path.join(a.out, f"E{factor}")
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    text = re.sub(r"beam: \{E: [0-9.eE+]+", f"beam: {{E: {E0 * factor:.17g}", base, count=1)
    assert f"E: {E0 * factor:.17g}" in text, "the case's modulus was not found"
    text = text.replace("geometric_stiffening: true", "geometric_stiffening: false")
    open(os.path.join(d, "case.yaml"), "w").write(text)
    run(["plan", d, "--out", os.path.join(d, "plan")])
    plan = json.load(open(os.path.join(d, "plan", "summary.json")))["plan"][0]
    est = plan["estimates"]
    ked = est["sensor_deflection_m"]["tip_elastic"]
    w1 = 2 * np.pi * est["first_frequency_hz"]
    r = (est["spin_rad_s"] / w1) ** 2
    run(["simulate", d, "--out", os.path.join(d, "sim")])
    s = json.load(open(os.path.join(d, "sim", "summary.json")))["sensors"]["tip_elastic"]
    ffrf = float(np.max(np.linalg.norm(np.array(s["value"], dtype=float), axis=1)))
    diff = abs(ked - ffrf) / ffrf
    print(f"E x {factor}: KED {ked:.6e} m, FFRF {ffrf:.6e} m, relative difference {diff:.3e}, "
          f"(Omega/w1)^2 = {r:.3e}")
    check(diff <= 2 * r, f"E x {factor}: |KED - FFRF| / FFRF = {diff:.2e} <= 2 (Omega/w1)^2 = {2 * r:.2e}")
    results.append(diff)
check(results[0] / results[1] >= 2.5,
      f"the difference falls by {results[0] / results[1]:.2f} (>= 2.5; O((Omega/w1)^2) gives 4)")
print("KED against FFRF: " + ("PASSED" if ok else "FAILED"))
sys.exit(0 if ok else 1)
