#!/usr/bin/python3
"""check-gradient with a deliberately loose state solve given on the command line (issue 49).

The case (tests/gradient/plate_hole_loose) is run with `-ksp_rtol 1e-4` on the command line, which
check-gradient keeps (the user asked for it on this run). A check whose evaluations carry the
solver's noise must know it:
  - it says so: "solver-limited" in the output, summary.json `solver_limited` true and
    `solver_limits` naming -ksp_rtol, and the noise measured (`noise_measured`);
  - the noise floor it reports lies above the round-off floor for the responses that depend on the
    state (compliance, displacement), i.e. the measurement saw the loose solves;
  - it never reports a wrong gradient: no negative order, the disagreement beyond the
    differences' uncertainty (which includes the measured noise) within 1e-6, the tolerance of the
    exact check.
The same case without the option on the command line (its `solver:` string's -ksp_rtol is left
out) is checked exactly by tests/check_gradient.py (gradient.plate_hole_loose.np*).
Usage: check_gradient_limited.py FLEXOPT CASE OUT RANKS
"""
import json
import os
import subprocess
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

flexopt, case, out, ranks = sys.argv[1:5]
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
p = mpi_job.run(["mpirun", "-n", ranks, flexopt, "check-gradient", case, "--out", out,
                    "-ksp_rtol", "1e-4"], env=env, stdout=subprocess.PIPE,
                   stderr=subprocess.STDOUT, text=True, timeout=600)
print(p.stdout)
if p.returncode != 0:
    sys.exit(f"FAIL: check-gradient exited with {p.returncode}")
s = json.load(open(os.path.join(out, "summary.json")))
checks = []
checks.append(("the output says the check is solver-limited", "solver-limited" in p.stdout))
checks.append(("summary.json: solver_limited", s["solver_limited"] is True))
checks.append(("summary.json: solver_limits names -ksp_rtol",
               any("-ksp_rtol" in l for l in s["solver_limits"])))
checks.append(("summary.json: the noise was measured", s["noise_measured"] is True))
for t in s["taylor"]:
    if t["response"].endswith(("compliance", "displacement")):
        checks.append((f"{t['response']}: measured noise {t['evaluation_noise']:.2e} above the "
                       f"round-off floor {t['round_off_floor']:.2e} / 2",
                       2 * t["evaluation_noise"] > t["round_off_floor"]))
    checks.append((f"{t['response']}: no negative order reported",
                   t["min_order"] is None or t["min_order"] >= 0))
checks.append((f"no wrong gradient: disagreement beyond the uncertainty "
               f"{s['max_rel_err_beyond_uncertainty']:.2e} <= 1e-6",
               s["max_rel_err_beyond_uncertainty"] <= 1e-6 and len(s["fd"]) == 5 * len(s["taylor"])))
failures = 0
for what, ok in checks:
    print(("ok    " if ok else "FAIL  ") + what)
    failures += 0 if ok else 1
sys.exit(1 if failures else 0)
