#!/usr/bin/python3
"""A rank that dies ends the job (issue 42): kill -9 of one flexopt process of a 2-rank run.

  - `simulate` of cases/spin_up_beam_acf (a 1-minute run): rank 1 killed 4 s into the time
    integration;
  - `optimize` of cases/slider_crank_topopt on a 10 mm rod mesh: rank 0 killed once restart.h5
    holds iteration 1.
Checks, each: the job ends within 30 s of the kill, with a non-zero exit and Open MPI's message
naming the lost rank ("process rank N ... exited on signal 9"); no process of the job is left;
no summary.json is written (nothing that looks like a finished run); for optimize, restart.h5 is
intact (its iteration readable); the killed simulate's motion.h5.tmp is removed, and named, by the
next run in that output directory.
Usage: check_rank_death.py FLEXOPT SOURCE OUT
"""
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import h5py

from check_common import expect, failures, finish, restart_iteration  # noqa: F401 (also the path to scripts/)
import mpi_job  # noqa: E402
from case_variants import write_variant  # noqa: E402

flexopt, source, out = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)


def ranks(job):
    """{MPI rank: pid} of the job's flexopt processes."""
    found = {}
    for pid in mpi_job.session_members(job.pid):
        try:
            argv = open(f"/proc/{pid}/cmdline", "rb").read().split(b"\0")
            env = open(f"/proc/{pid}/environ", "rb").read().split(b"\0")
        except OSError:
            continue
        if argv and argv[0].decode(errors="replace") == flexopt:
            for e in env:
                if e.startswith(b"OMPI_COMM_WORLD_RANK="):
                    found[int(e.split(b"=")[1])] = pid
    return found



def kill_one(name, command, case, rank, ready, *args):
    d = os.path.join(out, name)
    job = mpi_job.start(["mpirun", "-n", "2", flexopt, command, case, "--out", d, *args], env=mpi_job.ENV,
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.time() + 600
    while time.time() < deadline and job.poll() is None and not (len(ranks(job)) == 2 and ready(d)):
        time.sleep(0.05)
    pids = ranks(job)
    if job.poll() is not None or rank not in pids:
        failures.append(f"{name}: the run ended or never started before the kill")
        mpi_job.kill_session(job.pid)
        return d
    os.kill(pids[rank], signal.SIGKILL)
    t0 = time.time()
    try:
        text, _ = job.communicate(timeout=30)
        ended = True
    except subprocess.TimeoutExpired:
        ended = False
        mpi_job.kill_session(job.pid)
        text, _ = job.communicate()
    took = time.time() - t0
    left = mpi_job.session_members(job.pid)
    named = re.search(rf"process rank {rank} .*exited on signal 9", text) is not None
    print(f"{name}: rank {rank} killed; the job ended after {took:.1f} s, exit {job.returncode}, "
          f"{len(left)} process(es) left")
    expect(ended and job.returncode != 0, f"{name}: the job ends within 30 s with a non-zero exit")
    expect(named, f"{name}: the message names the lost rank {rank}")
    expect(not left, f"{name}: no process of the job is left")
    expect(not os.path.exists(os.path.join(d, "summary.json")), f"{name}: no summary.json")
    return d


started = {}


def integrating_for(seconds):
    def ready(d):
        if not os.path.exists(os.path.join(d, "motion.h5.tmp")):
            return False
        started.setdefault(d, time.time())
        return time.time() - started[d] > seconds
    return ready


spin = os.path.join(source, "cases", "spin_up_beam_acf")
d = kill_one("simulate", "simulate", spin, 1, integrating_for(4))
# The killed run's incomplete motion.h5.tmp: the next run in that directory removes and names it.
had = os.path.exists(os.path.join(d, "motion.h5.tmp"))
p = mpi_job.run(["mpirun", "-n", "2", flexopt, "info", spin, "--out", d], env=mpi_job.ENV, stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT, text=True, timeout=120)
expect(had and p.returncode == 0 and "removed motion.h5.tmp" in p.stdout and
       not os.path.exists(os.path.join(d, "motion.h5.tmp")),
       "the next run in that directory removes the stale motion.h5.tmp and says so")
rod = write_variant(os.path.join(source, "cases", "slider_crank_topopt"), os.path.join(out, "rod_case"),
                    [("mesh: {size: 0.005, order: 2}", "mesh: {size: 0.01, order: 2}")], optimization=True)
d = kill_one("optimize", "optimize", rod, 0, lambda d: restart_iteration(os.path.join(d, "restart.h5")) >= 1)
expect(restart_iteration(os.path.join(d, "restart.h5")) >= 1, "optimize: restart.h5 is intact after the kill")

finish("a lost rank ends the job")
