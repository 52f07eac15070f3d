#!/usr/bin/python3
"""Restart of `flexopt optimize` gives the iterates of an uninterrupted run:
  - a run stopped after 5 iterations (--max-iterations 5) and continued with --restart to N on
    the same number of ranks R: bit for bit (the state is restored exactly: the design, MMA's
    history and asymptotes, the objective scale and the continuation stage);
  - the same stopped run continued on the other rank count (1 for R = 2, 2 for R = 1): to 1e-8
    relative (parallel sums round differently; measured 7e-12 on the static beam);
  - a run killed with SIGKILL (mpirun and every rank: the whole session) once restart.h5 holds iteration 3 or
    later, then continued with --restart: bit for bit (restart.h5 is replaced atomically after
    every iteration, so a kill at any moment leaves the last complete one);
  - after each resume on R ranks, design.xdmf holds every frame of the uninterrupted run's, from
    iteration 0, with the same densities bit for bit (the frames before the restart point
    carried over from the stopped run's design.h5 or the killed run's design.h5.tmp), and the
    killed run's design.h5.tmp is gone;
  - --restart without a restart file fails with a clear message.
Usage: check_restart.py FLEXOPT CASE OUT [N (default 12) [R (default 2)]] [--replace OLD NEW]...
                        [--option OPTION]...
With --replace, the runs use a copy of CASE (in OUT/case) with each OLD text of case.yaml replaced
by NEW (a coarser mesh: the restart does not depend on the resolution, and a coarse mesh makes
each iteration cheaper).
With --option, every run gets OPTION on its command line.
Bit for bit needs an evaluation that is itself repeatable on R ranks: MUMPS's parallel
factorization is not (docs/solvers.md "Reproducibility"), so a case whose evaluation factorizes
with MUMPS on 2 ranks (an FFRF design body's reduction) is checked with --option
-fx_deterministic.
"""
import json
import os
import shutil
import subprocess
import sys
import time

import re

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import write_variant  # noqa: E402
from check_common import restart_iteration  # noqa: E402
import mpi_job  # noqa: E402

args, replace, options = sys.argv[1:], [], []
while "--replace" in args:
    i = args.index("--replace")
    replace.append((args[i + 1], args[i + 2]))
    del args[i:i + 3]
while "--option" in args:
    i = args.index("--option")
    options.append(args[i + 1])
    del args[i:i + 2]
flexopt, case, out = args[:3]
N = int(args[3]) if len(args) > 3 else 12
R = int(args[4]) if len(args) > 4 else 2
other = 1 if R == 2 else 2
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
shutil.rmtree(out, ignore_errors=True)
if replace:
    case = write_variant(case, os.path.join(out, "case"), replace, optimization=True)


def command(ranks, d, *args):
    return (["mpirun", "-n", str(ranks), flexopt, "optimize", case, "--out", os.path.join(out, d)] + list(args)
            + options)


def run(ranks, d, *args, ok=True):
    p = mpi_job.run(command(ranks, d, *args), env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True, timeout=1200)
    print(p.stdout[-2000:])
    if ok and p.returncode != 0:
        sys.exit(f"FAIL: optimize {args} exited with {p.returncode}")
    return p


def summary(d):
    return json.load(open(os.path.join(out, d, "summary.json")))


failures = []


def compare(a, b, tol, what):
    values_a = a["objective"] + [v for row in a["constraints"] for v in row]
    values_b = b["objective"] + [v for row in b["constraints"] for v in row]
    if len(values_a) != len(values_b) or a["iterations"] != b["iterations"]:
        diff = float("inf")
    else:
        diff = max(abs(x - y) / abs(x) for x, y in zip(values_a, values_b))
    ok = diff <= tol
    shown = "identical" if tol == 0 else f"<= {tol:g}"
    print(("ok    " if ok else "FAIL  ") + f"{what}: max relative difference {diff:.2e} ({shown})")
    if not ok:
        failures.append(what)


def same_designs(d, what):
    """design.xdmf's frame times and design.h5's densities of run `d` against the straight run's."""
    def times(run_dir):
        return re.findall(r'<Time Value="([^"]+)"', open(os.path.join(out, run_dir, "design.xdmf")).read())
    ta, tb = times("straight"), times(d)
    same = ta == tb
    with h5py.File(os.path.join(out, "straight", "design.h5"), "r") as fa, \
            h5py.File(os.path.join(out, d, "design.h5"), "r") as fb:
        for k in range(len(ta) if same else 0):
            for name in fa[f"step_{k}"]:
                same = same and np.array_equal(fa[f"step_{k}/{name}"][()], fb[f"step_{k}/{name}"][()])
    stale = os.path.exists(os.path.join(out, d, "design.h5.tmp"))
    ok = same and not stale
    print(("ok    " if ok else "FAIL  ") + f"{what}: design.xdmf's {len(tb)} frames (iterations {tb[0]} to {tb[-1]}) "
          f"{'equal' if same else 'differ from'} the uninterrupted run's {len(ta)}"
          + (", design.h5.tmp left behind" if stale else ""))
    if not ok:
        failures.append(what + ": design history")


run(R, "straight", "--max-iterations", str(N))
run(R, "split", "--max-iterations", "5")
shutil.copytree(os.path.join(out, "split"), os.path.join(out, "split_other"))
run(R, "split", "--max-iterations", str(N), "--restart")
run(other, "split_other", "--max-iterations", str(N), "--restart")
compare(summary("straight"), summary("split"), 0.0, f"stopped at 5, restarted on {R} rank(s) to {N}")
same_designs("split", "stopped at 5, restarted")
compare(summary("straight"), summary("split_other"), 1e-8,
        f"stopped at 5 on {R} rank(s), restarted on {other} rank(s)")

# kill -9 in the middle of an iteration (as soon as the third restart point is there), then
# --restart.
killed = os.path.join(out, "killed")
os.makedirs(killed)
p = mpi_job.start(command(R, "killed", "--max-iterations", str(N)), env=env, stdout=subprocess.DEVNULL,
                  stderr=subprocess.DEVNULL)
deadline = time.time() + 1200
while restart_iteration(os.path.join(killed, "restart.h5")) < 3 and p.poll() is None and time.time() < deadline:
    time.sleep(0.005)
mpi_job.kill_session(p.pid)  # mpirun and every rank (mpi_job.py says why)
p.wait()
done = restart_iteration(os.path.join(killed, "restart.h5"))
print(f"killed the run with SIGKILL after restart point {done}")
if done >= N:
    failures.append("the run ended before it could be killed")
run(R, "killed", "--max-iterations", str(N), "--restart")
compare(summary("straight"), summary("killed"), 0.0, f"killed after iteration {done}, restarted on {R} rank(s)")
same_designs("killed", "killed, restarted")

p = run(2, "none", "--restart", ok=False)
ok = p.returncode != 0 and "restart file not found" in p.stdout
print(("ok    " if ok else "FAIL  ") + "--restart without a restart file: clear error, non-zero exit")
if not ok:
    failures.append("missing restart file")
sys.exit(1 if failures else 0)
