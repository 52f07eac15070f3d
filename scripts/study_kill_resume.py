#!/usr/bin/python3
"""kill -9 at random moments of `flexopt optimize` on the shipped topology cases, each run resumed
with --restart and compared bit for bit with an uninterrupted run (docs/testing.md, "Faults
tried").

For each case as shipped (with the iteration limit below; the static ones also with
-fx_warm_start 0), on 2 ranks with -fx_deterministic (docs/solvers.md
"Reproducibility"):
  1. an uninterrupted run of N iterations, timed (T);
  2. KILLS runs, each killed with SIGKILL (mpirun and every rank) at a moment drawn uniformly
     from [0.05 T, 0.95 T] (seeded), then resumed in the same directory: with --restart when
     restart.h5 is there, else from the start, as a user would;
  3. the resumed run against the uninterrupted one: the objective and constraints of every
     iteration, design.xdmf's frame times and every density of design.h5, all identical; no
     `.tmp` or `design.interrupted.h5` left.
Prints one markdown row per kill and exits 1 if any comparison fails.

Usage: study_kill_resume.py FLEXOPT SOURCE_DIR OUT [--cases NAME,...] [--seed S]
"""
import json
import os
import random
import re
import shutil
import subprocess
import sys
import time

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import case_variants  # noqa: E402
import mpi_job  # noqa: E402
from case_variants import restart_iteration  # noqa: E402

# name, replacements of case.yaml, iterations, kills, options besides -fx_deterministic
CASES = [
    ("cantilever_topopt", [], 20, 3, []),
    ("cantilever_topopt", [], 20, 1, ["-fx_warm_start", "0"]),
    ("bridge_topopt", [], 20, 3, []),
    ("bridge_topopt", [], 20, 1, ["-fx_warm_start", "0"]),
    ("first_link", [], 10, 2, []),
    ("slider_crank_topopt", [], 8, 2, []),
    ("manipulator_topopt", [], 6, 2, []),
    ("spin_link_topopt", [], 6, 2, []),
]


def optimize(flexopt, case, d, n, options, restart=False):
    return (["mpirun", "-n", "2", flexopt, "optimize", case, "--out", d, "--max-iterations", str(n),
             "-fx_deterministic"] + options + (["--restart"] if restart else []))


def run(cmd):
    p = mpi_job.run(cmd, env=mpi_job.ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                    timeout=3600)
    if p.returncode != 0:
        sys.stdout.write(p.stdout[-3000:])
        sys.exit(f"failed (exit {p.returncode}): {' '.join(cmd)}")
    return p.stdout


def figures(d):
    s = json.load(open(os.path.join(d, "summary.json")))
    return s["iterations"], s["objective"], s["constraints"]


def relative_difference(a, b):
    """The largest relative difference of the objective and constraint values of two runs."""
    if a[0] != b[0]:
        return float("inf")
    va = a[1] + [v for row in a[2] for v in row]
    vb = b[1] + [v for row in b[2] for v in row]
    return max(abs(x - y) / max(abs(y), 1e-300) for x, y in zip(va, vb))


def frames(d):
    times = re.findall(r'<Time Value="([^"]+)"', open(os.path.join(d, "design.xdmf")).read())
    with h5py.File(os.path.join(d, "design.h5"), "r") as f:
        data = [{name: f[f"step_{k}/{name}"][()] for name in f[f"step_{k}"]} for k in range(len(times))]
    return times, data


def same_frames(a, b):
    (ta, da), (tb, db) = a, b
    return ta == tb and all(x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)
                            for x, y in zip(da, db))


def main():
    args = sys.argv[1:]
    seed, names = 20261128, None
    if "--seed" in args:
        i = args.index("--seed")
        seed = int(args[i + 1])
        del args[i:i + 2]
    if "--cases" in args:
        i = args.index("--cases")
        names = args[i + 1].split(",")
        del args[i:i + 2]
    flexopt, source, out = args[:3]
    rng = random.Random(seed)
    shutil.rmtree(out, ignore_errors=True)
    rows, bad = [], 0
    print("| case | iterations | uninterrupted [s] | killed at [s] | restart point | files left by the kill | resumed | objective and constraints | design.xdmf frames |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, replace, n, kills, options in CASES:
        if names and name not in names:
            continue
        case = os.path.join(source, "cases", name)
        if replace:
            case = case_variants.write_variant(case, os.path.join(out, name, "case"), replace, optimization=True)
        tag = name + "".join(options).replace("-fx_", "_")
        straight = os.path.join(out, tag, "straight")
        t0 = time.time()
        run(optimize(flexopt, case, straight, n, options))
        total = time.time() - t0
        reference = figures(straight), frames(straight)
        for k in range(kills):
            d = os.path.join(out, tag, f"killed{k}")
            at = rng.uniform(0.05, 0.95) * total
            p = mpi_job.start(optimize(flexopt, case, d, n, options), env=mpi_job.ENV, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
            time.sleep(at)
            mpi_job.kill_session(p.pid)
            p.wait()
            point = restart_iteration(os.path.join(d, "restart.h5"))
            left = sorted(f for f in os.listdir(d) if f.endswith(".tmp")) if os.path.isdir(d) else []
            log = run(optimize(flexopt, case, d, n, options, restart=point > 0))
            carried = re.search(r"iterations 0 to \S+ \((\d+) frames\) carried over from (\S+)", log)
            resumed = (f"--restart, {carried.group(1)} frame{'' if carried.group(1) == '1' else 's'} from {carried.group(2)}" if carried
                       else "--restart" if point > 0 else "from the start")
            got = figures(d)
            same = got == reference[0]
            diff = relative_difference(got, reference[0])
            same_design = same_frames(frames(d), reference[1])
            stale = [f for f in os.listdir(d) if f.endswith(".tmp") or f == "design.interrupted.h5"]
            ok = same and same_design and not stale
            bad += 0 if ok else 1
            row = (f"| {name}{' ' + ' '.join(options) if options else ''} | {n} | {total:.1f} | {at:.1f} | {point} | {', '.join(left) or 'none'} | {resumed} | "
                   f"{'identical' if same else f'differ by {diff:.1e}'} | "
                   f"{'identical' if same_design else 'DIFFER'}{', stale ' + ', '.join(stale) if stale else ''} |")
            print(row, flush=True)
            rows.append(row)
    print(f"{len(rows)} kills, {len(rows) - bad} resumed bit for bit")
    sys.exit(1 if bad or not rows else 0)


main()
