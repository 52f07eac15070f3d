"""What the study scripts share: one flexopt command on N ranks, its output to a log file, a
clear exit if it fails, and its wall time (scripts/study_*.py)."""
import os
import subprocess
import sys
import time
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mpi_job  # noqa: E402 (after the path to scripts/)

ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")


def run_flexopt(flexopt, ranks, cmd_args, log):
    """Runs `mpirun -n RANKS FLEXOPT CMD_ARGS...` with its output in LOG; exits the study with
    the log's name if it fails; returns the wall time [s]."""
    cmd = ["mpirun", "-n", str(ranks), flexopt] + list(cmd_args)
    print("$ " + " ".join(cmd), flush=True)
    t0 = time.time()
    with open(log, "w") as f:
        r = mpi_job.run(cmd, stdout=f, stderr=subprocess.STDOUT, env=ENV)
    if r.returncode != 0:
        sys.exit(f"study: failed ({r.returncode}); see {log}")
    return time.time() - t0
