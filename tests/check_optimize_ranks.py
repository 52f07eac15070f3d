#!/usr/bin/python3
"""The first N iterates of `flexopt optimize` on 1 and 2 ranks agree: the objective and every
constraint of each iteration to TOL relative. A design problem's evaluation differs between rank
counts only by the rounding of parallel sums (and, with an FFRF design body, of the reduction's
eigensolution, about eps lambda_max / lambda_1, docs/theory.md section 10 "Accuracy"); MMA carries
the differences from one iterate to the next.
Usage: check_optimize_ranks.py FLEXOPT CASE OUT N TOL
"""
import json
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

flexopt, case, out, n, tol = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), float(sys.argv[5])
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
shutil.rmtree(out, ignore_errors=True)
runs = {}
for ranks in (1, 2):
    d = os.path.join(out, f"np{ranks}")
    p = mpi_job.run(["mpirun", "-n", str(ranks), flexopt, "optimize", case, "--out", d, "--max-iterations", str(n)],
                       env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=1800)
    print(p.stdout[-3000:])
    if p.returncode != 0:
        sys.exit(f"FAIL: optimize on {ranks} rank(s) exited with {p.returncode}")
    runs[ranks] = json.load(open(os.path.join(d, "summary.json")))
a, b = runs[1], runs[2]
worst, where = 0.0, ""
for k in range(n):
    pairs = [("objective", a["objective"][k], b["objective"][k])]
    pairs += [(f"constraint {i}", x, y) for i, (x, y) in enumerate(zip(a["constraints"][k], b["constraints"][k]))]
    for name, x, y in pairs:
        d = abs(x - y) / max(abs(x), 1e-300)
        print(f"iteration {k + 1:3d} {name:14s} 1 rank {x:.15e}  2 ranks {y:.15e}  rel {d:.2e}")
        if d > worst:
            worst, where = d, f"iteration {k + 1}, {name}"
ok = a["iterations"] == b["iterations"] == n and worst <= tol
# The final motion shows the whole mechanism after thresholding physical_density at 0.5: every
# body carries the field, 1 in each cell of a body that is not the design body.
import h5py  # noqa: E402
with h5py.File(os.path.join(out, "np2", "motion_final.h5"), "r") as f:
    bodies = [k for k in f.keys() if isinstance(f[k], h5py.Group) and "reference_geometry" in f[k]]
    fields = {k: f[k]["physical_density"][...] for k in bodies if "physical_density" in f[k]}
solid = [k for k, v in fields.items() if v.size and (v == 1.0).all()]
designed = [k for k, v in fields.items() if v.size and not (v == 1.0).all()]
dens_ok = len(fields) == len(bodies) >= 2 and len(designed) == 1 and len(solid) == len(bodies) - 1
print(("ok    " if dens_ok else "FAIL  ") + f"motion_final.h5: physical_density on {sorted(fields)} of the bodies "
      f"{sorted(bodies)}; solid (1 everywhere): {sorted(solid)}, designed: {designed}")
ok = ok and dens_ok
print(("ok    " if ok else "FAIL  ") + f"first {n} iterates on 1 and 2 ranks: max relative difference {worst:.2e} "
      f"({where}) <= {tol:g}")
sys.exit(0 if ok else 1)
