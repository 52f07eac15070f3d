#!/usr/bin/python3
"""Responses that cannot move are named before they mislead a design (docs/theory.md section 5,
"Responses that cannot move"): one iteration of `optimize` on cases/first_link as it is (no
warning) and with a constraint on the mean square of the driven crank's end position, which the
rod's densities cannot change (one warning naming constraint1, in the log and in summary.json).
Usage: check_stuck_responses.py FLEXOPT SOURCE OUT
"""
import json
import os
import shutil
import subprocess
import sys

from check_common import expect, failures, finish  # noqa: F401 (also the path to scripts/)
import mpi_job  # noqa: E402
from case_variants import write_variant  # noqa: E402

flexopt, source, out = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(out, ignore_errors=True)
first = os.path.join(source, "cases", "first_link")


def optimize(name, replace):
    case = write_variant(first, os.path.join(out, name + "_case"), replace, optimization=True)
    d = os.path.join(out, name)
    p = mpi_job.run(["mpirun", "-n", "2", flexopt, "optimize", case, "--out", d, "--max-iterations", "1"],
                    env=mpi_job.ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
    if p.returncode != 0:
        print(p.stdout[-3000:])
        sys.exit(f"FAIL: optimize {name} exited with {p.returncode}")
    return p.stdout, json.load(open(os.path.join(d, "summary.json")))


log, s = optimize("as_is", [])
expect("warnings" not in s and "does not depend" not in log, "cases/first_link: no warning")
sensor = "  - {name: mid_elastic, body: rod, point: [0.15, 0, 0], quantity: elastic_displacement}"
bound = "  - {type: volume_fraction, max: 0.5}"
log, s = optimize("driven", [
    (sensor, sensor + "\n  - {name: crank_end, body: crank, point: [0.15, 0, 0], quantity: position}"),
    (bound, bound + "\n  - {type: sensor, sensor: crank_end, component: x, measure: mean_square, max: 1}")])
lines = [ln for ln in log.splitlines() if "warning" in ln and "constraint1" in ln]
print(lines[0] if lines else "no warning")
expect(len(lines) == 1 and "does not depend on the design" in lines[0] and len(s.get("warnings", [])) == 1,
       "the driven crank's position: one warning naming constraint1, in the log and in summary.json")

finish("responses that cannot move are named")
