#!/usr/bin/python3
"""Memory bounds before the run (issue 42): the states a dynamic optimization keeps for its
backward sweep are measured (the first one stored) and counted before the forward run; above
80 % of the memory a node reports they are refused with the adjoint.checkpoints that fits.
cases/first_link with a Helmholtz filter in place of its cone filter and a ten times smaller
time step (20,944 states of about 3 kB per node: 61 MB), one iteration, with the node's
available memory given as 60 MB (FLEXOPT_MEMORY_AVAILABLE stands in for MemAvailable; the rod's
MUMPS factorization, estimated at 44 MB, fits):
  - `checkpoints: all` (the default): refused, one message naming adjoint.checkpoints and an N;
  - that N written into the case: the iteration runs;
  - `storage: disk`: the iteration runs (nothing is kept in memory).
The cone filter's weights likewise, before they are computed: cases/cantilever_topopt (8192
elements, R = 2.56 h: about 70 weights per element, each pair stored once, 3.5 MB on a node) with
3 MB available is refused naming design.filter and type: helmholtz.
MUMPS's factorization in the FFRF reduction, estimated by its analysis: printed in every run
above; cases/slider_crank_topopt (36,255 unknowns, 135 MB) with 100 MB available is refused
before its first factorization, naming the FFRF reduction and mesh.size; the ACF Newton matrix
of cases/spin_up_beam_acf (79 MB) with 50 MB available likewise.
Usage: check_memory_bounds.py FLEXOPT SOURCE OUT
"""
import os
import re
import shutil
import subprocess
import sys

from check_common import expect, failures, finish  # noqa: F401 (also the path to scripts/)
import mpi_job  # noqa: E402
from case_variants import write_variant  # noqa: E402

flexopt, source, out = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(out, ignore_errors=True)
first = os.path.join(source, "cases", "first_link")
env = dict(mpi_job.ENV, FLEXOPT_MEMORY_AVAILABLE=str(60_000_000))


def optimize(name, adjoint=None):
    # The Helmholtz filter (the case's cone filter has its own bound, checked below).
    extra = [("filter: {type: cone, radius: 0.015}", "filter: {radius: 0.0043}"), ("step: 2.0e-5", "step: 2.0e-6")]
    extra += [("optimizer: {", f"adjoint: {adjoint}\noptimizer: {{")] if adjoint else []
    case = write_variant(first, os.path.join(out, name + "_case"), extra, optimization=True)
    p = mpi_job.run(["mpirun", "-n", "2", flexopt, "optimize", case, "--out", os.path.join(out, name),
                     "--max-iterations", "1"], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                    text=True, timeout=600)
    return p.returncode, p.stdout


rc, log = optimize("all")
errors = [ln for ln in log.splitlines() if "error" in ln]
m = re.search(r"adjoint: \{checkpoints: (\d+)\}", errors[0]) if len(errors) == 1 else None
print(errors[0] if errors else "no error")
expect(rc != 0 and m is not None and "adjoint.checkpoints" in errors[0],
       "checkpoints: all above the memory: refused with one message and the N that fits")
if m:
    rc, log = optimize("suggested", "{checkpoints: %s}" % m.group(1))
    line = [ln for ln in log.splitlines() if ln.startswith("adjoint:")]
    print(line[0] if line else "")
    expect(rc == 0, f"checkpoints: {m.group(1)} (the suggestion): the iteration runs")
    expect("memory: the FFRF reduction: MUMPS's analysis estimates" in log,
           "the FFRF reduction's factorization estimate printed")
rc, log = optimize("disk", "{storage: disk}")
expect(rc == 0, "storage: disk: the iteration runs")

def refused(command, case, name, memory, words, what):
    """`command` (optimize: one iteration) of `case` with `memory` bytes available: refused with
    one error line holding every one of `words`, and no summary.json."""
    extra = ["--max-iterations", "1"] if command == "optimize" else []
    p = mpi_job.run(["mpirun", "-n", "2", flexopt, command, case, "--out", os.path.join(out, name)] + extra,
                    env=dict(mpi_job.ENV, FLEXOPT_MEMORY_AVAILABLE=str(memory)), stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT, text=True, timeout=600)
    errors = [ln for ln in p.stdout.splitlines() if "error" in ln]
    print(errors[0] if errors else "no error")
    expect(p.returncode != 0 and len(errors) == 1 and all(w in errors[0] for w in words)
           and not os.path.exists(os.path.join(out, name, "summary.json")), what)


refused("optimize", os.path.join(source, "cases", "cantilever_topopt"), "cone", 3_000_000,
        ["design.filter", "helmholtz"], "a cone filter above the memory: refused before its weights, naming design.filter")
refused("optimize", os.path.join(source, "cases", "slider_crank_topopt"), "mumps", 100_000_000,
        ["the FFRF reduction", "mesh.size"],
        "a MUMPS factorization above the memory: refused before it starts, naming the FFRF reduction and mesh.size")
acf = write_variant(os.path.join(source, "cases", "spin_up_beam_acf"), os.path.join(out, "acf_case"), end=0.1)
refused("simulate", acf, "acf", 50_000_000, ["ACF scene's Newton matrix"],
        "an ACF scene's MUMPS factorization above the memory: refused before it starts")

finish("the adjoint's states, the cone filter and MUMPS's factors are bounded before the run")
