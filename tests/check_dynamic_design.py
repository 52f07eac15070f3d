#!/usr/bin/python3
"""`flexopt simulate` on a dynamic case with a design section (tests/gradient/rigid_pendulum):
  - at design.initial: summary.json `responses` holds every response; the sensor response
    `final` equals the last sample of the same sensor in `sensors` bit for bit (the same
    forward run); the mass and volume fraction are those of the initial density 0.5;
  - --design FILE (a restart.h5 holding x = 0.7 everywhere): mass and volume fraction scale to
    0.7, and the kinematic responses equal those at 0.5 to 1e-9 relative (a uniform density
    scaling of a pendulum under gravity changes no motion; the forward runs differ only by
    Newton's tolerance);
  - --gradient: gradient.xdmf + .h5 with one cell array per response, forward_s and adjoint_s;
  - `optimize` (the static problem's MMA loop on the dynamic problem) lowers the objective
    within the constraints;
  - --gradient on a case without a design section (a static one) is refused.
Usage: check_dynamic_design.py FLEXOPT SOURCE_DIR OUT RANKS
"""
import json
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

flexopt, source, out, ranks = sys.argv[1:5]
case = os.path.join(source, "tests", "gradient", "rigid_pendulum")
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
failures = 0


def check(ok, what):
    global failures
    print(("ok    " if ok else "FAIL  ") + what)
    failures += 0 if ok else 1


def run(name, *args):
    d = os.path.join(out, name)
    p = mpi_job.run(["mpirun", "-n", ranks, flexopt, "simulate", case, "--out", d, *args], env=env,
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
    print(p.stdout[-3000:])
    if p.returncode != 0:
        sys.exit(f"FAIL: simulate {' '.join(args)} exited with {p.returncode}")
    return json.load(open(os.path.join(d, "summary.json"))), d


s, _ = run("initial")
r = s["responses"]
check(set(r) == {"objective", "constraint0", "constraint1", "constraint2", "constraint3",
                 "constraint4"}, f"responses: {sorted(r)}")
check(r["constraint0"] == s["sensors"]["tip"]["value"][-1][1],
      f"final tip y {r['constraint0']!r} is the last sensor sample {s['sensors']['tip']['value'][-1][1]!r}")
solid = 7850 * 1.0 * 0.05 * 0.05
check(abs(r["constraint4"] - 0.5 * solid) <= 1e-12 * solid, f"mass {r['constraint4']} = 0.5 x {solid}")
check(abs(r["constraint3"] - 0.5) <= 1e-14, f"volume fraction {r['constraint3']}")

# A restart file of a run with x = 0.7 (keyed by element tag: a superset of the mesh's tags).
tags = np.arange(1, 200001, dtype=np.uint64)
restart = os.path.join(out, "restart.h5")
with h5py.File(restart, "w") as f:
    f["tags"] = tags
    f["fields/x"] = np.full(tags.shape, 0.7)
    f["arrays/meta"] = np.array([3.0, 1.0, 5.0, 0.0, 1.0])
s7, _ = run("design07", "--design", restart)
r7 = s7["responses"]
check(abs(r7["constraint4"] - 0.7 * solid) <= 1e-12 * solid, f"--design: mass {r7['constraint4']} = 0.7 x {solid}")
check(abs(r7["constraint3"] - 0.7) <= 1e-14, f"--design: volume fraction {r7['constraint3']}")
for k in ("objective", "constraint0", "constraint1", "constraint2"):
    check(abs(r7[k] - r[k]) <= 1e-9 * max(abs(r[k]), 1e-3),
          f"--design: {k} {r7[k]!r} unchanged by the uniform scaling ({r[k]!r})")

sg, dg = run("gradient", "--gradient")
a = sg["adjoint"]
check(a["forward_s"] > 0 and a["adjoint_s"] > 0 and a["checkpoints"] == "all",
      f"--gradient: forward {a['forward_s']:.4f} s, adjoint {a['adjoint_s']:.4f} s, checkpoints {a['checkpoints']}")
with h5py.File(os.path.join(dg, "gradient.h5"), "r") as f:
    names = sorted(k for k in f["step_0"])
    check(names == ["gradient_constraint0", "gradient_constraint1", "gradient_constraint2",
                    "gradient_constraint3", "gradient_constraint4", "gradient_objective"],
          f"gradient.h5 arrays {names}")
    g = np.array(f["step_0/gradient_constraint4"])
    check(np.all(g > 0), "d mass / d density > 0 on every element")

# `optimize` runs the same MMA loop on the dynamic problem: 8 iterations lower the tracking
# error and keep every constraint.
od = os.path.join(out, "optimize")
p = mpi_job.run(["mpirun", "-n", ranks, flexopt, "optimize", case, "--out", od, "--max-iterations",
                    "8"], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                   timeout=600)
print(p.stdout[-2500:])
check(p.returncode == 0, "optimize on the dynamic case runs")
if p.returncode == 0:
    so = json.load(open(os.path.join(od, "summary.json")))
    obj, cons = so["objective"], so["constraints"]
    check(min(obj[1:]) < 0.9 * obj[0], f"optimize: objective {obj[0]:.6g} -> best {min(obj[1:]):.6g}")
    bounds = [0, 1, 1, 0.5, 10]
    check(all(c <= b + 1e-9 for c, b in zip(cons[-1], bounds)),
          f"optimize: last constraints {cons[-1]} within {bounds}")
    check(os.path.exists(os.path.join(od, "restart.h5")), "optimize: restart.h5 written")
cantilever = os.path.join(source, "cases", "cantilever")
p = mpi_job.run(["mpirun", "-n", ranks, flexopt, "simulate", cantilever, "--out",
                    os.path.join(out, "static"), "--gradient"], env=env, stdout=subprocess.PIPE,
                   stderr=subprocess.STDOUT, text=True, timeout=600)
check(p.returncode != 0 and "--gradient applies to `flexopt simulate` of a dynamic case" in p.stdout,
      "--gradient on a static case is refused")
sys.exit(1 if failures else 0)
