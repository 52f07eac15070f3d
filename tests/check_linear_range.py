#!/usr/bin/python3
"""The FFRF model's linear range (issue 42; docs/theory.md section 7.7): cases/flexible_pendulum
for 0.3 s, as it is (E = 1e10: its largest elastic displacement a fraction of a percent of the
1 m bar) and with E = 2e7 (500 times softer: about a third of the bar). Checks: summary.json's
elastic_displacement_max gives the bar's largest nodal elastic displacement over the frames; the
soft run ends with one warning naming the body, in the log and in summary.json `warnings`; the
stiff one has none and stays below 5 % of the bar's size.
Usage: check_linear_range.py FLEXOPT SOURCE OUT
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
pendulum = os.path.join(source, "cases", "flexible_pendulum")


def simulate(name, replace):
    case = write_variant(pendulum, os.path.join(out, name + "_case"),
                         [("end: 1.0, step: 1.0e-4", "end: 0.3, step: 1.0e-4")] + replace)
    d = os.path.join(out, name)
    p = mpi_job.run(["mpirun", "-n", "2", flexopt, "simulate", case, "--out", d], env=mpi_job.ENV,
                    stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
    if p.returncode != 0:
        print(p.stdout[-3000:])
        sys.exit(f"FAIL: simulate {name} exited with {p.returncode}")
    return p.stdout, json.load(open(os.path.join(d, "summary.json")))


log, s = simulate("stiff", [])
largest = s["elastic_displacement_max"]["bar"]
print(f"stiff bar (E 1e10): largest elastic displacement {largest:.3g} m")
expect(0 < largest < 0.05 and "warnings" not in s and "linear FFRF model" not in log,
       "the stiff bar stays in the linear range, no warning")
log, s = simulate("soft", [("E: 1.0e10", "E: 2.0e7")])
largest = s["elastic_displacement_max"]["bar"]
lines = [ln for ln in log.splitlines() if "beyond the linear FFRF model's range" in ln]
print(f"soft bar (E 2e7): largest elastic displacement {largest:.3g} m; " + (lines[0] if lines else "no warning"))
expect(largest > 0.05 and len(lines) == 1 and "'bar'" in lines[0] and len(s.get("warnings", [])) == 1,
       "the soft bar: one warning naming the body, in the log and in summary.json")

finish("the linear FFRF range is watched")
