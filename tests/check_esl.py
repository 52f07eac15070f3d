#!/usr/bin/python3
"""Equivalent static loads (`optimizer: {method: esl}`, issue 47, docs/theory.md section 14).

compare (on a quasi-static scene, tests/optimize/esl_slow_crank: the rod's first mode about 100
times the crank's frequency):
  - ESL's fixed point matches the dynamic design: the final design's dynamic objective (the mean
    strain energy, measured by a dynamic run) within TOL of the full dynamic design's (`method:
    mma` on the same case and iteration budget);
  - the static problem is the quasi-static limit of the dynamic one: at the final design, ESL's
    static objective sum_k (1/N) 1/2 C_k is the dynamic mean strain energy within TOL;
  - ESL stops on its design change (optimizer.tolerance) within its outer iterations, feasible;
  - each outer iteration's loads are written: esl/loads_JJ.xdmf with N time steps of the nodal
    body force, esl/loads_JJ.csv with N rows per loaded interface.
restart (a smaller variant on R ranks, with -fx_deterministic; bit for bit needs runs that repeat
bit for bit, which the static load cases' parallel MUMPS factorization (the case's solver:) does not
on 2 ranks: docs/solvers.md "Reproducibility"; ctest runs it on 1 rank):
  - a run killed with SIGKILL in the middle of its second outer iteration's static design
    (once esl/outer_01/restart.h5 holds iteration 2), continued with --restart, gives the
    uninterrupted run's history.csv (every outer iteration's dynamic and static objectives,
    inner iterations and design change, the timings aside) and its final design bit for bit;
  - --restart without any restart file fails with a clear message;
  - (with a projection whose beta rises within the first static design) the second outer
    iteration's dynamic objective is that of `simulate --design` of the first static design's
    restart.h5: the simulated design is the one the static design ended with, at its stage.
Usage: check_esl.py FLEXOPT CASE OUT compare TOL
       check_esl.py FLEXOPT CASE OUT restart [R (default 2)]
"""
import csv
import json
import os
import re
import shutil
import subprocess
import sys
import time

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import restart_iteration, write_variant  # noqa: E402
import mpi_job  # noqa: E402

flexopt, case, out, mode = sys.argv[1:5]
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
failures = []


def check(ok, text):
    print(("ok    " if ok else "FAIL  ") + text)
    if not ok:
        failures.append(text)


def rel(a, b):
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def esl_variant(name, esl_keys, extra=()):
    """CASE with `method: esl` and ESL_KEYS added to its optimizer: line (and EXTRA replacements)."""
    return write_variant(case, os.path.join(out, name),
                         [("optimizer: {", "optimizer: {" + esl_keys + ", ")] + list(extra), optimization=True)


def history(d):
    """history.csv's rows without the timing columns."""
    with open(os.path.join(d, "out", "history.csv")) as f:
        return [{k: v for k, v in row.items() if not k.startswith("seconds")} for row in csv.DictReader(f)]


def compare_mode(tol):
    dynamic = write_variant(case, os.path.join(out, "dynamic"), optimization=True)
    mpi_job.flexopt(flexopt, ["optimize", dynamic, "--out", os.path.join(dynamic, "out")], 2)
    dyn = json.load(open(os.path.join(dynamic, "out", "summary.json")))
    n = 12
    esl = esl_variant("esl", f"method: esl, instants: {n}, outer_iterations: 4")
    mpi_job.flexopt(flexopt, ["optimize", esl, "--out", os.path.join(esl, "out")], 2)
    s = json.load(open(os.path.join(esl, "out", "summary.json")))
    j_dyn, j_esl = dyn["objective"][-1], s["final_dynamic_objective"]
    check(rel(j_esl, j_dyn) <= tol, f"ESL's design: dynamic objective {j_esl:.6e} against the dynamic "
          f"design's {j_dyn:.6e} ({100 * (j_esl / j_dyn - 1):+.2f} %, tolerance {100 * tol:g} %)")
    rows = history(esl)
    static = float(rows[-2]["static_objective"])
    check(rel(static, j_esl) <= tol, f"quasi-static limit: static objective {static:.6e} against the "
          f"dynamic mean strain energy {j_esl:.6e} ({100 * (static / j_esl - 1):+.2f} %)")
    check(s["converged"] and s["outer_iterations"] <= 4,
          f"stopped on the design change after {s['outer_iterations']} outer iterations (changes "
          + ", ".join(f"{c:.2e}" for c in s["max_change"]) + ")")
    volume = s["final_dynamic_constraints"][0]
    check(volume <= 0.5 * (1 + 1e-3), f"volume fraction {volume:.6f} <= 0.5")
    for j in range(s["outer_iterations"]):
        xdmf = open(os.path.join(esl, "out", "esl", f"loads_{j:02d}.xdmf")).read()
        steps = len(re.findall(r"<Time Value=", xdmf))
        with open(os.path.join(esl, "out", "esl", f"loads_{j:02d}.csv")) as f:
            loads = list(csv.DictReader(f))
        interfaces = {r["interface"] for r in loads}
        check(steps == n and len(loads) == n * len(interfaces) and interfaces == {"pin_b"},
              f"outer iteration {j}: loads_{j:02d}.xdmf has {steps} instants, loads_{j:02d}.csv "
              f"{len(loads)} rows on {sorted(interfaces)}")


def restart_mode(ranks):
    keys = "method: esl, instants: 4, outer_iterations: 2, inner_iterations: 6"
    # A projection whose beta rises within the first static design: the second outer iteration
    # simulates the design at the stage that static design ended at.
    projection = [("filter: {type: cone, radius: 0.02}",
                   "filter: {type: cone, radius: 0.02}\n  projection: {beta: [1, 4], every: 3}")]
    opts = ["-fx_deterministic"]
    straight, killed = esl_variant("straight", keys, projection), esl_variant("killed", keys, projection)
    mpi_job.flexopt(flexopt, ["optimize", straight, "--out", os.path.join(straight, "out")] + opts, ranks)
    # History row 1 is the dynamic run of outer iteration 0's design: what `simulate --design` of
    # that static design's restart.h5 (its design and projection stage) computes.
    check_design = os.path.join(out, "outer_00_design")
    mpi_job.flexopt(flexopt, ["simulate", straight, "--out", check_design, "--design",
                              os.path.join(straight, "out", "esl", "outer_00", "restart.h5")] + opts, ranks)
    simulated = json.load(open(os.path.join(check_design, "summary.json")))["responses"]["objective"]
    row1 = float(history(straight)[1]["dynamic_objective"])
    check(rel(row1, simulated) <= 1e-9, f"outer iteration 1 simulates outer 0's design at its stage: "
          f"{row1:.10e} against simulate --design {simulated:.10e}")
    env = dict(mpi_job.ENV, FLEXOPT_REPORT="0", FLEXOPT_PLAN_CHECK="0")
    p = mpi_job.start(["mpirun", "-n", str(ranks), flexopt, "optimize", killed, "--out", os.path.join(killed, "out")]
                      + opts, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    inner = os.path.join(killed, "out", "esl", "outer_01", "restart.h5")
    deadline = time.time() + 900
    while restart_iteration(inner) < 2 and p.poll() is None and time.time() < deadline:
        time.sleep(0.005)
    mpi_job.kill_session(p.pid)  # mpirun and every rank (mpi_job.py says why)
    p.wait()
    done = restart_iteration(inner)
    print(f"killed the run with SIGKILL in outer iteration 1 after its static iteration {done}")
    check(0 < done < 6, f"the run was killed in the middle of outer iteration 1 (static iteration {done} of 6)")
    mpi_job.flexopt(flexopt, ["optimize", killed, "--out", os.path.join(killed, "out"), "--restart"] + opts,
                    ranks)
    ha, hb = history(straight), history(killed)
    check(ha == hb, f"history.csv: the restarted run's {len(hb)} rows equal the uninterrupted run's {len(ha)}")
    with h5py.File(os.path.join(straight, "out", "restart.h5"), "r") as fa, \
            h5py.File(os.path.join(killed, "out", "restart.h5"), "r") as fb:
        def by_tag(f):
            order = np.argsort(f["tags"][()])
            return f["tags"][()][order], f["fields/x"][()][order]
        (ta, xa), (tb, xb) = by_tag(fa), by_tag(fb)
        same = np.array_equal(ta, tb) and np.array_equal(xa, xb)
    check(same, "the final design equals the uninterrupted run's bit for bit")
    none = esl_variant("none", keys)
    r = mpi_job.run(["mpirun", "-n", "2", flexopt, "optimize", none, "--out", os.path.join(none, "out"), "--restart"],
                    env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    check(r.returncode != 0 and "restart file not found" in r.stdout,
          "--restart without a restart file: clear error, non-zero exit")


if mode == "compare":
    compare_mode(float(sys.argv[5]))
elif mode == "restart":
    restart_mode(int(sys.argv[5]) if len(sys.argv) > 5 else 2)
else:
    sys.exit(f"unknown mode {mode}")
for f in failures:
    print("FAIL: " + f)
sys.exit(1 if failures else 0)
