#!/usr/bin/python3
"""Runs `flexopt check-gradient` on a case and asserts the adjoint gradients are right:
  - Taylor test: for every response that is not linear in the design, the observed order of
    the remainder |R(x + h d) - R(x) - h g.d| is >= MIN_ORDER (1.9 unless given) between all steps above the noise
    floor (2 exactly for a correct gradient; 1 for a wrong one); a linear response (volume
    fraction) has all remainders at round-off;
  - central differences (fourth order, step 1e-2) on 5 design elements agree with the adjoint
    gradient to FD_TOL (default 1e-6, the issue's requirement). The difference quotients carry
    the round-off of the response evaluation divided by the step and the entry. That round-off
    is set by the cancellation in the strain energy (eps |u|^T |K| |u| / u^T K u, docs/theory.md
    section 5): about 1e-14 relative on the compact block cases (measured FD errors <= 3.3e-9,
    1 and 2 ranks), about 1e-10 on the slender beam (length / depth 10, large rigid-like
    displacements: 1e-9 ... 1.5e-5 measured), which is therefore checked at 2e-5.
  - every reported order is non-negative (an order is taken only above the evaluations' noise
    floor, check-gradient's own measurement: it must never print a negative one);
  - `--raw`: FD_TOL bounds the whole disagreement, not only its part beyond the differences'
    uncertainty (the static cases with default solvers, issue 49: the check solves to round-off,
    so nothing of the disagreement is the solver's);
  - the evaluations were not solver-limited (summary.json `solver_limited`).
Usage: check_gradient.py FLEXOPT CASE OUT RANKS [FD_TOL [MIN_ORDER[@H] [DESIGN]]]  (MIN_ORDER default
1.9; @H: over the pairs of steps from H down only, for a design whose sharp projection makes the
largest step pre-asymptotic, and with the smaller remainder of a pair above the noise floor
rather than 10 times it (the FFRF floor, 1e-8, is the noisiest case's, and a pair below 10 times
it can still be clean: the orders are then 2.000 +- 0.001, measured); DESIGN: a run's
restart.h5, checked at its design instead of the initial one). `--fd-step H` anywhere: passed to
check-gradient (one step pair h, h/2 instead of the problem's own search over halvings)
"""
import json
import os
import subprocess
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

args = sys.argv[1:]
fd_step = []
if "--fd-step" in args:
    k = args.index("--fd-step")
    fd_step = args[k:k + 2]
    del args[k:k + 2]
raw = "--raw" in args
if raw:
    args.remove("--raw")
sys.argv[1:] = args
flexopt, case, out, ranks = sys.argv[1:5]
FD_TOL = float(sys.argv[5]) if len(sys.argv) > 5 else 1e-6
order_arg = sys.argv[6] if len(sys.argv) > 6 else "1.9"
MIN_ORDER = float(order_arg.split("@")[0])
FROM_STEP = float(order_arg.split("@")[1]) if "@" in order_arg else float("inf")
design = ["--design", sys.argv[7]] if len(sys.argv) > 7 else []
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
p = mpi_job.run(["mpirun", "-n", ranks, flexopt, "check-gradient", case, "--out", out] + design + fd_step, env=env,
                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
print(p.stdout)
if p.returncode != 0:
    sys.exit(f"FAIL: check-gradient exited with {p.returncode}")
s = json.load(open(os.path.join(out, "summary.json")))
failures = 0
for t in s["taylor"]:
    floors = t.get("noise_floors", [t["noise_floor"]] * len(t["steps"]))
    if t["linear"]:
        ok = all(r <= f for r, f in zip(t["remainders"], floors))
        print(("ok    " if ok else "FAIL  ") + f"{t['response']}: linear, remainders at round-off")
    elif t["min_order"] is None:
        ok = False
        print(f"FAIL  {t['response']}: no Taylor remainders above the noise floor: order not measured")
        failures += 1
        continue
    else:
        # The pairs (h_k, h_k+1) from FROM_STEP down whose smaller remainder is above the noise
        # floor.
        orders = [o for k, o in enumerate(t["orders"])
                  if t["steps"][k] <= FROM_STEP and t["remainders"][k + 1] > floors[k + 1]]
        if FROM_STEP == float("inf"):
            orders = [t["min_order"]]
        least = min(orders) if orders else float("nan")
        ok = bool(orders) and least >= MIN_ORDER
        span = "" if FROM_STEP == float("inf") else f" (steps from {FROM_STEP:g} down)"
        print(("ok    " if ok else "FAIL  ") + f"{t['response']}: Taylor order {least:.3f} >= {MIN_ORDER:g}{span}")
    failures += 0 if ok else 1
    if t["min_order"] is not None and t["min_order"] < 0:
        print(f"FAIL  {t['response']}: negative order {t['min_order']:.3f} reported above the noise floor")
        failures += 1
if s.get("solver_limited"):
    print(f"FAIL  the check was solver-limited: {s.get('solver_limits')}")
    failures += 1
if raw:
    ok = s["max_rel_err"] <= FD_TOL
    print(("ok    " if ok else "FAIL  ") + f"finite differences: max relative error {s['max_rel_err']:.2e} <= {FD_TOL:g} (raw)")
    failures += 0 if ok else 1
# The part of each disagreement beyond the extrapolated difference's own uncertainty (its gap to
# the next extrapolation: the responses' noise over the step) counts against the adjoint.
# 5 design elements, or with several design bodies 3 of each (check-gradient's sample): at least
# 5 rows per response.
ok = s["max_rel_err_beyond_uncertainty"] <= FD_TOL and len(s["fd"]) >= 5 * len(s["taylor"])
print(("ok    " if ok else "FAIL  ") + f"finite differences: max relative error {s['max_rel_err']:.2e}, "
      f"beyond the differences' uncertainty {s['max_rel_err_beyond_uncertainty']:.2e} <= {FD_TOL:g}")
failures += 0 if ok else 1
sys.exit(1 if failures else 0)
