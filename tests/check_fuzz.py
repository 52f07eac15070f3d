#!/usr/bin/python3
"""Seeded fuzzing of what flexopt reads (issue 42): mutants of four case.yaml files (a rigid, an
FFRF, an ACF and a design case: tests/gradient/rigid_pendulum, ffrf_pendulum, acf_pendulum and
tests/optimize/beam), of a Gmsh .msh file and of a restart.h5, each run with a time limit.

case.yaml mutants (a line deleted, duplicated or truncated, a number replaced by an extreme or
non-numeric value, a key renamed, a value swapped for another line's, bytes flipped) go through
`flexopt info` on 1 rank and one in four through `flexopt simulate` on 2 ranks with the time
cut to a few steps (`check-gradient`-free: design cases simulate their design); .msh mutants
(bytes flipped, or the file cut) through `info` of a case that reads that mesh; restart.h5
mutants (bytes flipped in its data and its headers) through `optimize --restart`.
Each run must:
  - end by itself within the limit (no hang) and not by a signal (no crash: exit 0 or 1);
  - on a refusal (exit 1): print exactly one error line, naming a file ("case.yaml", ".msh",
    "restart.h5") and, for case.yaml, a LINE:COL where the mutated text has one, and leave no
    summary.json (nothing that looks like a finished run);
  - on success (exit 0): print no error line and write summary.json.
Mutants are made in order from the seed (the same mutants every run); the case.yaml and .msh
ones run four at a time (each `info` is half a second of MPI, Gmsh and PETSc start-up, most of
it waiting: four keep 2 cores busy); the runs stop being started when the time budget is spent
(default 170 s).
Usage: check_fuzz.py FLEXOPT SOURCE OUT [--seed S] [--cases N] [--msh N] [--restarts N]
                     [--budget SECONDS] [--workers N]
"""
import argparse
import os
import random
import re
import shutil
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor

from check_common import expect, finish
import mpi_job  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("flexopt")
ap.add_argument("source")
ap.add_argument("out")
ap.add_argument("--seed", type=int, default=20261128)
ap.add_argument("--cases", type=int, default=60, help="mutants per case.yaml")
ap.add_argument("--msh", type=int, default=40, help=".msh mutants")
ap.add_argument("--restarts", type=int, default=20, help="restart.h5 mutants")
ap.add_argument("--budget", type=float, default=170.0, help="seconds for all mutants")
ap.add_argument("--workers", type=int, default=4, help="case.yaml and .msh mutants run at a time")
a = ap.parse_args()
rng = random.Random(a.seed)
shutil.rmtree(a.out, ignore_errors=True)
os.makedirs(a.out)
t_start = time.time()
counts = {"runs": 0, "accepted": 0, "refused": 0}
bad = []

EXTREMES = ["0", "-1", "1e308", "-1e308", "nan", ".inf", "1e-320", "abc", "[]", "{}", "~", "''", "3.5.1",
            "99999999999999999999", "[1, 2]", "\"t*\"", "2e-3,", "&x", "*x"]


def mutate_yaml(text):
    lines = text.split("\n")
    kind = rng.randrange(7)
    k = rng.randrange(len(lines))
    if kind == 0:
        del lines[k]
    elif kind == 1:
        lines.insert(k, lines[k])
    elif kind == 2:
        lines[k] = lines[k][:rng.randrange(len(lines[k]) + 1)]
    elif kind == 3:
        numbers = [(i, m) for i, ln in enumerate(lines) for m in re.finditer(r"-?\d+(\.\d+)?(e-?\d+)?", ln)]
        if numbers:
            i, m = rng.choice(numbers)
            lines[i] = lines[i][:m.start()] + rng.choice(EXTREMES) + lines[i][m.end():]
    elif kind == 4:
        keys = [(i, m) for i, ln in enumerate(lines) for m in re.finditer(r"([a-z_]+):", ln)]
        if keys:
            i, m = rng.choice(keys)
            lines[i] = lines[i][:m.start()] + m.group(1)[:-1] + "x:" + lines[i][m.end():]
    elif kind == 5:
        j = rng.randrange(len(lines))
        lines[k], lines[j] = lines[j], lines[k]
    else:
        b = bytearray("\n".join(lines).encode())
        for _ in range(rng.randint(1, 4)):
            b[rng.randrange(len(b))] = rng.choice(b":{}[],-#&*!|>'\"%@` \t\n0123456789")
        return b.decode(errors="replace")
    return "\n".join(lines)


def run(name, cmd, case_file, out, timeout):
    """One run under the rules above; returns (exit code, output)."""
    counts["runs"] += 1
    try:
        p = mpi_job.run(cmd + ["--out", out], env=dict(mpi_job.ENV, FLEXOPT_REPORT="0", FLEXOPT_PLAN_CHECK="0"),
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, errors="replace",
                        timeout=timeout)
    except subprocess.TimeoutExpired:
        bad.append(f"{name}: no end within {timeout} s (a hang)")
        return None, ""
    errors = [ln for ln in p.stdout.splitlines() if re.search(r"\berror\b", ln, re.IGNORECASE)
              and "warning" not in ln]
    summary = os.path.exists(os.path.join(out, "summary.json"))
    if p.returncode not in (0, 1):
        bad.append(f"{name}: exit {p.returncode} (a crash or a signal): {p.stdout[-400:]!r}")
    elif p.returncode == 1:
        counts["refused"] += 1
        if len(errors) != 1:
            bad.append(f"{name}: refused with {len(errors)} error lines: {errors[:3]}")
        elif summary:
            bad.append(f"{name}: refused but wrote summary.json")
        elif case_file and not any(s in errors[0] for s in (case_file, ".msh", ".geo", "restart.h5")):
            bad.append(f"{name}: the refusal names no file: {errors[0]}")
    else:
        counts["accepted"] += 1
        if errors or not summary:
            bad.append(f"{name}: exit 0 with {len(errors)} error lines, summary.json {summary}")
    return p.returncode, p.stdout


def short_time(text):
    """The case with time.end cut to 3 steps of its own step (a simulate of a few steps)."""
    return re.sub(r"time: \{end: [^,]+, step: ([^,}]+)", lambda m: f"time: {{end: {3 * float(m.group(1))!r}, step: {m.group(1)}",
                  text, count=1)


def fuzz_cases():
    """The case.yaml mutants, made in order from the seed, then run two at a time (the info runs
    take one rank each)."""
    bases = ["tests/gradient/rigid_pendulum", "tests/gradient/ffrf_pendulum", "tests/gradient/acf_pendulum",
             "tests/optimize/beam"]
    jobs = []
    for base in bases:
        src = os.path.join(a.source, base)
        text = open(os.path.join(src, "case.yaml")).read()
        text = re.sub(r"geometry: ([./]*)meshes/", "geometry: " + os.path.join(a.source, "meshes") + "/", text)
        for n in range(a.cases):
            d = os.path.join(a.out, f"{os.path.basename(base)}_{n}")
            os.makedirs(d)
            simulate = n % 4 == 0 and "analysis: dynamic" in text
            mutant = mutate_yaml(short_time(text) if simulate else text)
            with open(os.path.join(d, "case.yaml"), "w") as f:
                f.write(mutant)
            cmd = ["mpirun", "-n", "2" if simulate else "1", a.flexopt, "simulate" if simulate else "info", d]
            jobs.append((f"{base} mutant {n} ({'simulate' if simulate else 'info'})", cmd, os.path.join(d, "out")))

    def one(job):
        if time.time() - t_start <= a.budget * 0.7:
            run(job[0], job[1], "case.yaml", job[2], 60)

    with ThreadPoolExecutor(max_workers=a.workers) as pool:
        list(pool.map(one, jobs))


def mutate_bytes(data, cut=False):
    b = bytearray(data)
    if cut:
        return bytes(b[:rng.randrange(1, len(b))])
    for _ in range(rng.randint(1, 16)):
        b[rng.randrange(len(b))] = rng.randrange(256)
    return bytes(b)


def fuzz_msh(count):
    """The .msh mutants, made in order from the seed, then run a.workers at a time."""
    mesh = os.path.join(a.out, "bar.msh")
    gm = subprocess.run(["gmsh", "-3", "-format", "msh4", os.path.join(a.source, "meshes", "bar.geo"), "-o", mesh],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=120)
    if gm.returncode != 0 or not os.path.exists(mesh):
        bad.append("gmsh could not write the .msh to mutate: " + gm.stdout[-300:])
        return
    data = open(mesh, "rb").read()
    jobs = []
    for n in range(count):
        d = os.path.join(a.out, f"msh_{n}")
        os.makedirs(d)
        with open(os.path.join(d, "bar.msh"), "wb") as f:
            f.write(mutate_bytes(data, cut=n % 3 == 0))
        with open(os.path.join(d, "case.yaml"), "w") as f:
            f.write("analysis: static\nmaterials:\n  steel: {E: 2.1e11, nu: 0.3, density: 7850}\n"
                    "bodies:\n  - {name: bar, geometry: bar.msh, material: steel}\n")
        jobs.append((f"msh mutant {n}", ["mpirun", "-n", "1", a.flexopt, "info", d], os.path.join(d, "out")))

    def one(job):
        if time.time() - t_start <= a.budget * 0.85:
            run(job[0], job[1], "case.yaml", job[2], 60)

    with ThreadPoolExecutor(max_workers=a.workers) as pool:
        list(pool.map(one, jobs))


def fuzz_restart(count):
    beam = os.path.join(a.source, "tests", "optimize", "beam")
    base = os.path.join(a.out, "restart_base")
    p = mpi_job.run(["mpirun", "-n", "2", a.flexopt, "optimize", beam, "--out", base, "--max-iterations", "2"],
                    env=dict(mpi_job.ENV, FLEXOPT_REPORT="0"), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                    text=True, timeout=300)
    if p.returncode != 0:
        bad.append("the run that writes the restart.h5 to mutate failed")
        return
    data = open(os.path.join(base, "restart.h5"), "rb").read()
    for n in range(count):
        if time.time() - t_start > a.budget:
            return
        d = os.path.join(a.out, f"restart_{n}")
        os.makedirs(d)
        b = bytearray(data)
        # Flip bytes in the headers (the first 4 kB) or anywhere.
        span = 4096 if n % 2 == 0 else len(b)
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(min(span, len(b)))] = rng.randrange(256)
        with open(os.path.join(d, "restart.h5"), "wb") as f:
            f.write(bytes(b))
        run(f"restart.h5 mutant {n}", ["mpirun", "-n", "2", a.flexopt, "optimize", beam, "--restart",
                                       "--max-iterations", "3"], "restart.h5", d, 120)


fuzz_cases()
fuzz_msh(a.msh)
fuzz_restart(a.restarts)
took = time.time() - t_start
print(f"fuzz: seed {a.seed}: {counts['runs']} runs in {took:.0f} s, {counts['accepted']} accepted, "
      f"{counts['refused']} refused cleanly, {len(bad)} bad")
for b in bad[:20]:
    print("  " + b)
# At least 50 runs within the budget (all 300 on 2 idle cores, four at a time; fewer beside other tests).
expect(counts["runs"] >= min(50, a.cases * 4 + a.msh + a.restarts) and not bad, f"{counts['runs']} mutants: no crash, no hang, one located message per refusal")
finish("fuzzed inputs are refused cleanly or accepted")
