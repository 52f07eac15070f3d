#!/usr/bin/python3
"""Scenarios run concurrently give what they give one after another (issue 45):
  - `flexopt optimize CASE --max-iterations N` on 2 ranks in 2 groups (the default split), on 2
    ranks in 1 group (--scenario-groups 1: the scenarios one after another on both ranks) and on
    4 ranks in as many groups as the case has scenarios (at most 4): the objective and every
    constraint of every iteration agree to TOL relative (a condition's evaluation differs between
    splits only by the rounding of parallel sums; MMA carries the differences on);
  - summary.json names the split (scenario_groups, and per scenario its group and ranks), each
    scenario's response values (scenario_responses) and each scenario's motions, and the motion
    files motion_initial.NAME.xdmf and motion_final.NAME.xdmf exist for every scenario;
  - `flexopt simulate CASE` writes motion.NAME.xdmf and summary.json scenarios.NAME for each.
Usage: check_scenarios.py FLEXOPT CASE OUT N TOL
"""
import json
import os
import shutil
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

flexopt, case, out, n, tol = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), float(sys.argv[5])
shutil.rmtree(out, ignore_errors=True)
failures = []


def run(args, ranks):
    return mpi_job.flexopt(flexopt, args, ranks)


runs = {}
for ranks, groups in ((2, 0), (2, 1), (4, 0)):
    d = os.path.join(out, f"np{ranks}_groups{groups}")
    extra = ["--scenario-groups", str(groups)] if groups else []
    run(["optimize", case, "--out", d, "--max-iterations", str(n)] + extra, ranks)
    s = json.load(open(os.path.join(d, "summary.json")))
    runs[(ranks, groups)] = s
    names = list(s["problem"]["scenarios"].keys())
    expected_groups = min(ranks, len(names)) if groups == 0 else groups
    if s["problem"]["scenario_groups"] != expected_groups:
        failures.append(f"{d}: {s['problem']['scenario_groups']} groups, expected {expected_groups}")
    ranks_seen = sorted(r for sp in s["problem"]["scenario_split"] for r in sp["ranks"])
    if not set(ranks_seen) == set(range(ranks)):
        failures.append(f"{d}: the split's ranks {ranks_seen} are not 0..{ranks - 1}")
    for name in names:
        if name not in s["problem"]["scenario_responses"]:
            failures.append(f"{d}: no scenario_responses for '{name}'")
        if name not in s.get("scenario_motions", {}):
            failures.append(f"{d}: no scenario_motions for '{name}'")
        for which in ("initial", "final"):
            f = os.path.join(d, f"motion_{which}.{name}.xdmf")
            if not os.path.exists(f):
                failures.append(f"missing {f}")

base = runs[(2, 0)]
for key, s in runs.items():
    if key == (2, 0):
        continue
    worst = 0.0
    if s["iterations"] != base["iterations"]:
        failures.append(f"{key}: {s['iterations']} iterations against {base['iterations']}")
    for k in range(min(s["iterations"], base["iterations"])):
        pairs = [(base["objective"][k], s["objective"][k])]
        pairs += list(zip(base["constraints"][k], s["constraints"][k]))
        for x, y in pairs:
            worst = max(worst, abs(x - y) / max(abs(x), 1e-300))
    print(f"ranks {key[0]}, groups {key[1] or 'default'}: largest relative difference to 2 ranks in "
          f"2 groups {worst:.2e} (tolerance {tol:g})")
    if not worst <= tol:
        failures.append(f"ranks {key[0]} groups {key[1]}: relative difference {worst:.2e} > {tol:g}")

d = os.path.join(out, "simulate")
run(["simulate", case, "--out", d], 2)
s = json.load(open(os.path.join(d, "summary.json")))
for name in runs[(2, 0)]["problem"]["scenarios"]:
    if not os.path.exists(os.path.join(d, f"motion.{name}.xdmf")):
        failures.append(f"simulate: missing motion.{name}.xdmf")
    if "responses" not in s.get("scenarios", {}).get(name, {}):
        failures.append(f"simulate: summary.json has no scenarios.{name}.responses")

for f in failures:
    print("FAIL:", f)
sys.exit(1 if failures else 0)
