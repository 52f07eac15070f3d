#!/usr/bin/python3
"""Write failures stop a run cleanly (issue 42; docs/output.md "Write failures").

tests/optimize/beam on 2 ranks:
  1. disk full: the output directory on a 3 MiB tmpfs (mounted here; the test is skipped with a
     message where mounting is not allowed), 60 iterations, whose design frames and restart
     points do not fit. Checks: the run stops within the timeout (no hang) with a non-zero exit
     and one message naming the file and "No space left on device"; no .tmp file is left; the
     last restart.h5 is intact (h5py reads its iteration k >= 1) and `--restart` from a copy of
     it elsewhere runs to 40 iterations, with the final objective of a straight run of 40 to
     1e-8 (2-rank runs differ from run to run at about 1e-11, MUMPS: docs/solvers.md
     "Reproducibility"; optimize.restart checks restarts bit for bit), and its design.xdmf holds
     the straight run's frames from iteration 0 (the frames before the failure carried over
     from the design.h5.tmp the failed run leaves, the only .tmp it leaves);
  (An output directory removed during a run is not tested: when the removal falls between the
  free-space check and a collective HDF5 file creation the job can still hang; seen once in
  three runs.)
Usage: check_write_failures.py FLEXOPT SOURCE OUT
"""
import json
import os
import re
import shutil
import subprocess
import sys
import time

import h5py

from check_common import expect, failures, finish, restart_iteration  # noqa: F401 (also the path to scripts/)
import mpi_job  # noqa: E402

flexopt, source, out = sys.argv[1], sys.argv[2], sys.argv[3]
beam = os.path.join(source, "tests", "optimize", "beam")
small = os.path.join(out, "small")


def command(d, *args):
    return ["mpirun", "-n", "2", flexopt, "optimize", beam, "--out", d, *args]


def errors(text):
    return [ln for ln in text.splitlines() if "error" in ln.lower() and "flexopt" in ln]



if os.path.ismount(small):
    subprocess.run(["umount", small])
shutil.rmtree(out, ignore_errors=True)
os.makedirs(small)
mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", small],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
if mounted.returncode != 0:
    print("SKIP: the disk-full case needs a small file system: mounting a tmpfs failed here "
          f"({mounted.stdout.strip()}); run as root with mount rights")
else:
    try:
        run_dir = os.path.join(small, "run")
        t0 = time.time()
        p = mpi_job.run(command(run_dir, "--max-iterations", "60"), env=mpi_job.ENV, stdout=subprocess.PIPE,
                        stderr=subprocess.STDOUT, text=True, timeout=300)
        took = time.time() - t0
        e = errors(p.stdout)
        print(f"disk full: exit {p.returncode} after {took:.1f} s; " + (e[0] if e else "no error line"))
        expect(p.returncode != 0 and len(e) == 1 and "No space left on device" in e[0] and ".h5.tmp" in e[0],
               "disk full: non-zero exit, one message naming the file and the OS's reason")
        left = sorted(os.listdir(run_dir))
        expect(not any(n.endswith(".tmp") and n != "design.h5.tmp" for n in left),
               f"disk full: no .tmp file left but design.h5.tmp, the frames for --restart ({left})")
        k = restart_iteration(os.path.join(run_dir, "restart.h5"))
        expect(k >= 1, f"disk full: the last restart.h5 is intact (iteration {k})")
        shutil.copytree(run_dir, os.path.join(out, "resumed"))
    finally:
        subprocess.run(["umount", small])
    if k >= 1 and k < 40:
        p = mpi_job.run(command(os.path.join(out, "resumed"), "--max-iterations", "40", "--restart"),
                        env=mpi_job.ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
        q = mpi_job.run(command(os.path.join(out, "straight"), "--max-iterations", "40"), env=mpi_job.ENV,
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
        a = json.load(open(os.path.join(out, "resumed", "summary.json")))
        b = json.load(open(os.path.join(out, "straight", "summary.json")))
        fa, fb = a["objective"][-1], b["objective"][-1]
        expect(p.returncode == 0 and q.returncode == 0 and a["iterations"] == 40 and abs(fa - fb) <= 1e-8 * abs(fb),
               f"--restart from the intact file runs to 40 iterations, final objective {fa!r} against a "
               f"straight run's {fb!r}")

        def times(d):
            return re.findall(r'<Time Value="([^"]+)"', open(os.path.join(out, d, "design.xdmf")).read())
        ta, tb = times("resumed"), times("straight")
        expect(ta == tb and "warnings" not in a,
               f"--restart after the full disk: design.xdmf holds every frame from iteration 0 "
               f"({len(ta)} frames, the straight run {len(tb)})")

finish("write failures stop the run cleanly")
