"""Runs MPI jobs for the tests and scripts so that a timeout leaves nothing behind.

`run` is subprocess.run for a command that starts an MPI job (`mpirun -n N flexopt ...`, or
flexopt alone): the job gets a session of its own, and on a timeout, an exception or an
interrupt every process of that session is killed -- mpirun and all its ranks -- before the
error goes on. Killing mpirun alone is not enough: Open MPI 4.1 puts each rank in a process
group of its own, so the ranks of a killed mpirun go on running until they notice (about a
second here: time enough to write a file that a restarted run then reads), but they stay in
mpirun's session. tests/check_job_runner.py (CTest faults.job_timeout) checks both.

    import mpi_job
    p = mpi_job.run(["mpirun", "-n", "2", flexopt, "simulate", case], env=mpi_job.ENV,
                    stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
"""
import os
import signal
import subprocess
import time

# What mpirun needs here: running as root in containers, 2 ranks on fewer cores.
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")


def session_members(sid):
    """The live processes of session `sid` (zombies left out)."""
    members = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":  # stat field 6: the session id
            members.append(int(pid))
    return members


def kill_session(sid, grace=0.0):
    """Ends every process of session `sid`: SIGTERM first when `grace` > 0 (seconds to leave),
    then SIGKILL until none is left."""
    if grace > 0:
        for pid in session_members(sid):
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        deadline = time.time() + grace
        while session_members(sid) and time.time() < deadline:
            time.sleep(0.05)
    while True:
        members = session_members(sid)
        if not members:
            return
        for pid in members:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        time.sleep(0.05)


def start(cmd, **kwargs):
    """subprocess.Popen in a session of its own (kill_session(p.pid) ends the whole job)."""
    return subprocess.Popen(cmd, start_new_session=True, **kwargs)


def run(cmd, *, timeout=None, input=None, check=False, capture_output=False, **kwargs):
    """subprocess.run with the job in a session of its own, killed whole on a timeout (then
    subprocess.TimeoutExpired is raised as subprocess.run raises it) or on any exception."""
    if capture_output:
        kwargs["stdout"] = kwargs["stderr"] = subprocess.PIPE
    if input is not None:
        kwargs["stdin"] = subprocess.PIPE
    p = start(cmd, **kwargs)
    try:
        out, err = p.communicate(input, timeout=timeout)
    except subprocess.TimeoutExpired:
        kill_session(p.pid)
        out, err = p.communicate()
        raise subprocess.TimeoutExpired(cmd, timeout, output=out, stderr=err) from None
    except BaseException:
        kill_session(p.pid)
        p.wait()
        raise
    if check and p.returncode:
        raise subprocess.CalledProcessError(p.returncode, cmd, out, err)
    return subprocess.CompletedProcess(cmd, p.returncode, out, err)


def flexopt(binary, args, ranks, timeout=1800, tail=2500):
    """`mpirun -n RANKS BINARY ARGS` with ENV and no report or plan check (the tests' runs):
    prints the last `tail` characters of its output and returns the output; exits the calling
    script naming the command if the run fails."""
    env = dict(ENV, FLEXOPT_REPORT="0", FLEXOPT_PLAN_CHECK="0")
    p = run(["mpirun", "-n", str(ranks), binary] + list(args), env=env, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True, timeout=timeout)
    print(p.stdout[-tail:])
    if p.returncode != 0:
        raise SystemExit(f"FAIL: {' '.join(args)} on {ranks} rank(s) exited with {p.returncode}")
    return p.stdout
