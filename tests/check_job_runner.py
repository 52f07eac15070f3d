#!/usr/bin/python3
"""The test helpers' job runner (scripts/mpi_job.py) leaves nothing behind after a timeout.

A 2-rank `flexopt simulate` of a scene that runs for minutes (cases/spin_up_beam_acf) is started
through mpi_job.run with a timeout of a few seconds. Checks: TimeoutExpired is raised, and when
it is, no process is left whose command line names the run's output directory -- neither
mpirun nor either rank. A plain kill of mpirun (what subprocess.run does on its timeout) is
tried first to show that the check can fail: right after it the ranks are still running (Open
MPI 4.1 puts each rank in a process group of its own; they notice the lost mpirun only about a
second later, time enough to write a file that a restarted run then reads).
Usage: check_job_runner.py FLEXOPT SOURCE OUT
"""
import os
import shutil
import subprocess
import sys
import time

from check_common import expect, failures, finish  # noqa: F401 (also the path to scripts/)
import mpi_job  # noqa: E402

flexopt, source, out = sys.argv[1], sys.argv[2], sys.argv[3]
case = os.path.join(source, "cases", "spin_up_beam_acf")
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)


def left_over(tag):
    """The pids of live processes whose command line contains `tag`."""
    pids = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                cmd = f.read().replace(b"\0", b" ").decode(errors="replace")
            with open(f"/proc/{pid}/stat") as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if tag in cmd and state != "Z":
            pids.append(int(pid))
    return pids


def command(name):
    return ["mpirun", "-n", "2", flexopt, "simulate", case, "--out", os.path.join(out, name)]


def wait_for_ranks(tag, count=2, limit=60):
    """Waits until `count` flexopt processes of the run exist (the job has really started)."""
    deadline = time.time() + limit
    while time.time() < deadline:
        ranks = [p for p in left_over(tag) if open(f"/proc/{p}/cmdline", "rb").read().startswith(flexopt.encode())]
        if len(ranks) >= count:
            return True
        time.sleep(0.1)
    return False


# 1. What the runner guards against: a timeout that kills mpirun only.
tag = os.path.join(out, "plain")
p = subprocess.Popen(command("plain"), env=mpi_job.ENV, stdout=subprocess.DEVNULL,
                     stderr=subprocess.DEVNULL, start_new_session=True)
started = wait_for_ranks(tag)
p.kill()  # what subprocess.run does on its timeout
p.wait()
orphans = left_over(tag)
print(f"plain kill of mpirun: ranks started {started}, {len(orphans)} process(es) of the job left right after it")
if not started or not orphans:
    failures.append("the plain kill left no rank running: this check could not fail (Open MPI changed?)")
mpi_job.kill_session(p.pid)

# 2. The runner: a timeout ends the whole job.
tag = os.path.join(out, "runner")
t0 = time.time()
try:
    mpi_job.run(command("runner"), env=mpi_job.ENV, stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL, timeout=8)
    failures.append("the run ended before its timeout (the scene should take minutes)")
except subprocess.TimeoutExpired:
    pass
took = time.time() - t0
left = left_over(tag)
print(f"mpi_job.run with timeout 8 s: returned after {took:.1f} s, {len(left)} process(es) of the job left")
if left:
    failures.append(f"processes of the timed-out job left: {left}")
    for pid in left:
        os.kill(pid, 9)

finish("a timed-out job leaves no process")
