#!/usr/bin/python3
"""Runs variants of a case directory: copies case.yaml with text replacements (geometry paths
made absolute) into OUT/NAME and runs flexopt there. Shared by the FFRF checks and studies."""
import json
import os
import re
import subprocess
import sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mpi_job  # noqa: E402 (after the path to scripts/)


def run_flexopt(cmd):
    """Runs a command line (mpirun ... flexopt ...) as root-capable MPI job; exits with its
    output on failure."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    print("$ " + " ".join(cmd), flush=True)
    proc = mpi_job.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if proc.returncode != 0:
        sys.stdout.write(proc.stdout)
        errors = [line for line in proc.stdout.splitlines() if line.startswith("flexopt: error")]
        sys.exit(f"failed (exit {proc.returncode}): {' '.join(cmd)}" +
                 ("\n" + errors[0] if errors else ""))
    return proc.stdout


def without_optimization(text):
    """case.yaml text without its top-level design, objective and constraints entries (each key
    line and the indented or list lines under it)."""
    out, skipping = [], False
    for line in text.split("\n"):
        if re.match(r"(design|objective|constraints):", line):
            skipping = True
            continue
        if skipping and (line.startswith(" ") or line.startswith("-")):
            continue
        skipping = False
        out.append(line)
    return "\n".join(out)


def case_dict(case):
    """CASE's case.yaml as a dict for `simulate` or `plan` variants: the optimization sections
    (design, objective, constraints) left out and the geometry paths made absolute."""
    import yaml
    c = yaml.safe_load(open(os.path.join(case, "case.yaml")))
    for key in ("design", "objective", "constraints"):
        c.pop(key, None)
    for b in c["bodies"]:
        b["geometry"] = os.path.abspath(os.path.join(case, b["geometry"]))
    return c


def write_case(c, d):
    """Writes case dict C as D/case.yaml; returns D."""
    import yaml
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "case.yaml"), "w") as f:
        yaml.safe_dump(c, f, default_flow_style=None, sort_keys=False, width=1000)
    return d


def case_text(case, replace=(), end=None, optimization=False):
    """CASE's case.yaml text with the geometry paths made absolute, each (old, new) of `replace`
    applied (old must occur), then time.end set to `end` if given, and without the optimization
    sections unless `optimization`."""
    text = open(os.path.join(case, "case.yaml")).read()
    if not optimization:
        text = without_optimization(text)
    text = re.sub(r"geometry: ([./]*)meshes/",
                  lambda m: "geometry: " + os.path.abspath(os.path.join(case, m.group(1), "meshes")) + "/",
                  text)
    for a, b in replace:
        if a not in text:
            sys.exit(f"'{a}' not in {case}/case.yaml")
        text = text.replace(a, b)
    if end is not None:
        text, n = re.subn(r"time: \{end: [0-9.e+-]+", f"time: {{end: {end}", text)
        if n != 1:
            sys.exit(f"{case}/case.yaml: no 'time: {{end: ...' line to set the end time in")
    return text


def write_variant(case, d, replace=(), end=None, optimization=False):
    """Writes case_text(CASE, ...) as D/case.yaml (D created); returns D."""
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "case.yaml"), "w") as f:
        f.write(case_text(case, replace, end, optimization))
    return d


def run_variant(flexopt, case, out, name, replace, ranks=2, end=None, output=False):
    """Runs `flexopt simulate` on CASE's case.yaml with each (old, new) of `replace` applied
    (old must occur) and then, if given, time.end set to `end`; returns the summary, or with
    `output` the pair (summary, the run's printed output). A variant simulates the scene: the
    case's optimization sections (design, objective, constraints) are left out, so that a
    variant may change what they rely on (the design body's model, say)."""
    d = write_variant(case, os.path.join(out, name), replace, end)
    log = run_flexopt(["mpirun", "-n", str(ranks), flexopt, "simulate", d, "--out", os.path.join(d, "out")])
    summary = json.load(open(os.path.join(d, "out", "summary.json")))
    return (summary, log) if output else summary


def chord_deflection(summary, ends=("end_a", "end_b"), mid="mid"):
    """Per sample, the signed distance of the position sensor `mid` from the line through the
    position sensors `ends` in the x-y plane: ((b - a) x (m - a))_z / |b - a|, negated (a rod's
    mid-point deflection from its chord, positive to the right of a -> b)."""
    s = summary["sensors"]
    out = []
    for a, b, m in zip(*(s[n]["value"] for n in (ends[0], ends[1], mid))):
        dx, dy = b[0] - a[0], b[1] - a[1]
        out.append(-((m[0] - a[0]) * dy - (m[1] - a[1]) * dx) / (dx * dx + dy * dy) ** 0.5)
    return out


def check_arguments():
    """The command line of the check scripts that run case variants: --flexopt BIN --out DIR."""
    import argparse
    ap = argparse.ArgumentParser()
    ap.add_argument("--flexopt", required=True)
    ap.add_argument("--out", required=True)
    return ap.parse_args()


def finish(failures):
    """Prints each failure and exits with 1 if there is any, else 0."""
    for f in failures:
        print("FAIL: " + f)
    sys.exit(1 if failures else 0)


def restart_iteration(path):
    """The iteration restart.h5 at `path` holds (0: none yet, being replaced, or unreadable)."""
    import h5py
    try:
        with h5py.File(path, "r") as f:
            return int(f["arrays/meta"][0])
    except (OSError, KeyError):
        return 0
