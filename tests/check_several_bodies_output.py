#!/usr/bin/python3
"""The output of several design bodies (docs/output.md "Design frames", issue 44):
`simulate --gradient` on tests/gradient/two_pendulums (an FFRF Tet10 bar and an ACF Tet4 link,
both designed) writes gradient.xdmf as one grid:
  - an XDMF Mixed topology (two element types): one type code per cell (6 Tet4, 38 Tet10) and its
    nodes, the list as long as the cells' codes and nodes, every node index inside the geometry;
  - the link in its placement (initial position z = 2 m), the bar at z = 0: each body where the
    scene puts it;
  - as many cells as the two meshes, and a gradient on each body's cells.
Usage: check_several_bodies_output.py FLEXOPT SOURCE OUT RANKS
"""
import os
import subprocess
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402

flexopt, source, out, ranks = sys.argv[1:5]
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           FLEXOPT_REPORT="0", OMPI_MCA_rmaps_base_oversubscribe="1")
case = os.path.join(source, "tests", "gradient", "two_pendulums")
p = mpi_job.run(["mpirun", "-n", ranks, flexopt, "simulate", case, "--out", out, "--gradient"],
                env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
print(p.stdout[-2000:])
if p.returncode != 0:
    sys.exit(f"FAIL: simulate --gradient exited with {p.returncode}")
failures = 0


def check(ok, what):
    global failures
    print(("ok    " if ok else "FAIL  ") + what)
    failures += 0 if ok else 1


xdmf = open(os.path.join(out, "gradient.xdmf")).read()
check('TopologyType="Mixed"' in xdmf, "gradient.xdmf: a Mixed topology (Tet10 bar, Tet4 link)")
with h5py.File(os.path.join(out, "gradient.h5"), "r") as f:
    topo = f["mesh/topology"][()]
    geom = f["mesh/geometry"][()]
    grad = f["step_0/gradient_objective"][()]
nodes = {6: 4, 38: 10}
cells, k, types, bad = [], 0, {6: 0, 38: 0}, 0
while k < len(topo):
    code = int(topo[k])
    if code not in nodes:
        bad += 1
        break
    conn = topo[k + 1:k + 1 + nodes[code]]
    bad += int(np.any(conn < 0) or np.any(conn >= len(geom)))
    cells.append((code, conn))
    types[code] += 1
    k += 1 + nodes[code]
check(bad == 0 and k == len(topo), f"the list is {len(topo)} entries of type codes and nodes, "
      f"every node inside the {len(geom)} nodes")
check(len(cells) == len(grad), f"{len(cells)} cells, one gradient value each ({len(grad)})")
check(types[6] > 0 and types[38] > 0, f"Tet4 cells {types[6]} (the link), Tet10 {types[38]} (the bar)")
z = {code: [] for code in nodes}
for (code, conn), g in zip(cells, grad):
    z[code].append(geom[conn, 2].mean())
check(abs(np.mean(z[6]) - 2.0) < 0.05, f"the link placed at z = 2 m (mean {np.mean(z[6]):.4f})")
check(abs(np.mean(z[38])) < 0.05, f"the bar at z = 0 (mean {np.mean(z[38]):.4f})")
on = {code: int(np.count_nonzero([g for (c, _), g in zip(cells, grad) if c == code]))
      for code in nodes}
check(on[6] > 0 and on[38] > 0, f"a gradient on both bodies' cells ({on[38]} bar, {on[6]} link)")
sys.exit(1 if failures else 0)
