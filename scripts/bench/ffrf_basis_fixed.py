#!/usr/bin/python3
"""`adjoint: {basis: fixed}` against `exact` (docs/theory.md section 10, docs/benchmarks.md).

For each case (a directory with an FFRF design body), runs `flexopt simulate CASE --gradient`
twice on 2 ranks, with `adjoint: {basis: exact}` and with `adjoint: {basis: fixed}` appended to
case.yaml, and prints per response the relative error of the fixed-basis gradient,
|g_fixed - g_exact| / |g_exact|, and the angle between the two (2-norms over the design
elements, gradient.h5), with the wall time of each gradient (summary.json adjoint_s and
reduction_adjoint_s).
Usage: scripts/bench/ffrf_basis_fixed.py FLEXOPT OUT CASE [CASE ...]
"""
import json
import math
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

flexopt, out = sys.argv[1:3]
cases = sys.argv[3:]
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)


def run(case, basis):
    d = os.path.join(out, os.path.basename(case.rstrip("/")) + "_" + basis)
    os.makedirs(d)
    text = open(os.path.join(case, "case.yaml")).read()
    text = text.replace("../../../meshes/", os.path.abspath(os.path.join(case, "../../../meshes")) + "/")
    text = text.replace("../../meshes/", os.path.abspath(os.path.join(case, "../../meshes")) + "/")
    text += f"\nadjoint: {{basis: {basis}}}\n"
    open(os.path.join(d, "case.yaml"), "w").write(text)
    p = subprocess.run(["mpirun", "-n", "2", flexopt, "simulate", d, "--gradient", "--out",
                        os.path.join(d, "out")], env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True, timeout=3600)
    if p.returncode != 0:
        print(p.stdout[-3000:])
        sys.exit(f"simulate --gradient ({case}, {basis}) exited with {p.returncode}")
    s = json.load(open(os.path.join(d, "out", "summary.json")))
    grads = {}
    with h5py.File(os.path.join(d, "out", "gradient.h5"), "r") as f:
        for name in f["step_0"]:
            grads[name] = f["step_0/" + name][()]
    return s, grads


print("| case | response | rel. error of fixed | angle [deg] | adjoint s (exact / fixed) | "
      "reduction adjoint s (exact / fixed) |")
print("|---|---|---|---|---|---|")
for case in cases:
    se, ge = run(case, "exact")
    sf, gf = run(case, "fixed")
    for name in sorted(ge):
        a, b = ge[name], gf[name]
        na = np.linalg.norm(a)
        if na == 0:
            continue
        rel = np.linalg.norm(b - a) / na
        cosine = float(np.dot(a, b) / (na * np.linalg.norm(b))) if np.linalg.norm(b) > 0 else 0.0
        angle = math.degrees(math.acos(max(-1.0, min(1.0, cosine))))
        print(f"| {os.path.basename(case.rstrip('/'))} | {name.replace('gradient_', '')} | "
              f"{rel:.3g} | {angle:.3g} | {se['adjoint']['adjoint_s']:.3f} / "
              f"{sf['adjoint']['adjoint_s']:.3f} | {se['adjoint']['reduction_adjoint_s']:.3f} / "
              f"{sf['adjoint']['reduction_adjoint_s']:.3f} |")
