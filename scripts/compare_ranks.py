#!/usr/bin/python3
"""Runs a flexopt command on 1 and on 2 MPI ranks and compares summary.json figures.

Usage: compare_ranks.py CASE COMMAND --keys K [K ...] [--rel-tol 1e-9] [-- extra flexopt args]
A key is a dotted path into summary.json (lists compared element-wise). Each value must agree
to rel-tol relative to the largest magnitude in that key (so that near-zero entries of a
vector are held to the vector's scale). Exit 0 if all agree.
"""
import argparse
import json
import os
import subprocess
import sys

from check_case import select
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mpi_job  # noqa: E402 (after the path to scripts/)


def run(flexopt, ranks, case, command, out, extra):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    cmd = ["mpirun", "-n", str(ranks), flexopt, command, case, "--out", out] + extra
    print("$ " + " ".join(cmd), flush=True)
    proc = mpi_job.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    sys.stdout.write(proc.stdout)
    if proc.returncode != 0:
        sys.exit(f"flexopt failed on {ranks} rank(s) (exit {proc.returncode})")
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def flatten(v):
    """Nested lists (e.g. a sensor's vector per output step) as one flat list."""
    if not isinstance(v, list):
        return [v]
    out = []
    for x in v:
        out.extend(flatten(x))
    return out


def main():
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1:]
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("case")
    ap.add_argument("command")
    ap.add_argument("--keys", nargs="+", required=True)
    ap.add_argument("--rel-tol", type=float, default=1e-9)
    ap.add_argument("--flexopt", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build", "flexopt"))
    ap.add_argument("--out", default="/tmp/flexopt_compare_ranks")
    args = ap.parse_args(argv)
    one = run(args.flexopt, 1, args.case, args.command, os.path.join(args.out, "np1"), extra)
    two = run(args.flexopt, 2, args.case, args.command, os.path.join(args.out, "np2"), extra)
    failures = 0
    for key in args.keys:
        a, b = select(one, key), select(two, key)
        a, b = flatten(a), flatten(b)
        if len(a) != len(b):
            print(f"FAIL  {key}: {len(a)} values on 1 rank, {len(b)} on 2")
            failures += 1
            continue
        scale = max(abs(x) for x in a) or 1.0
        worst = max(abs(x - y) for x, y in zip(a, b)) / scale
        ok = worst <= args.rel_tol
        failures += 0 if ok else 1
        print(f"{'ok   ' if ok else 'FAIL '} {key}: 1 vs 2 ranks, max relative difference {worst:.3g} <= {args.rel_tol:g}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
