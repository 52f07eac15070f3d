#!/usr/bin/python3
"""Two runs of the same case on 2 ranks with -fx_deterministic give the same bits
(docs/solvers.md "Reproducibility"):
  - `optimize` of an FFRF design body (cases/slider_crank_topopt, the rod on a 10 mm mesh: each
    evaluation factorizes the rod's stiffness for its Craig-Bampton reduction and its adjoint)
    over 20 iterations: history.csv (every column but the timings), every design of design.h5
    and summary.json's figures;
  - `simulate` of an ACF body (cases/spin_up_beam_acf over its first second: the distributed
    backend factorizes its Newton matrix with MUMPS on every step): motion.h5 and summary.json.
Without the option, MUMPS's parallel factorization on 2 ranks varies from run to run in the last
bits; that is not asserted (it need not show in every pair of runs).
Usage: check_reproducible.py FLEXOPT SOURCE_DIR OUT [ITERATIONS (default 20)]
"""
import csv
import json
import os
import shutil
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_common import case_variants, expect, finish  # noqa: E402

flexopt, source, out = sys.argv[1:4]
cases = os.path.join(source, "cases")
iterations = int(sys.argv[4]) if len(sys.argv) > 4 else 20
shutil.rmtree(out, ignore_errors=True)


def timing(key):
    return "second" in key or key.endswith("_s") or "memory" in key


def figures(tree, path=""):
    """summary.json's numbers and strings by their path, timings and memory left out."""
    if isinstance(tree, dict):
        for k, v in tree.items():
            if not timing(k):
                yield from figures(v, f"{path}.{k}")
    elif isinstance(tree, list):
        for i, v in enumerate(tree):
            yield from figures(v, f"{path}[{i}]")
    else:
        yield path, tree


def summary(d):
    """summary.json's figures, with the run's own directory in paths written as OUT."""
    fs = dict(figures(json.load(open(os.path.join(d, "summary.json")))))
    return {k: v.replace(d, "OUT") if isinstance(v, str) else v for k, v in fs.items()}


def same_summaries(a, b, what):
    fa, fb = summary(a), summary(b)
    differ = sorted(k for k in fa.keys() | fb.keys() if fa.get(k) != fb.get(k))
    expect(not differ, f"{what}: summary.json identical ({len(fa)} figures"
           + (f"; {len(differ)} differ, first {differ[:3]})" if differ else ")"))


def same_datasets(a, b, name, what):
    with h5py.File(os.path.join(a, name), "r") as fa, h5py.File(os.path.join(b, name), "r") as fb:
        names = []
        fa.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
        differ = [n for n in names if n not in fb or not np.array_equal(fa[n][()], fb[n][()])]
        expect(len(names) > 0 and not differ,
               f"{what}: {name} identical ({len(names)} datasets" +
               (f"; {len(differ)} differ, first {differ[:3]})" if differ else ")"))


def history(d):
    with open(os.path.join(d, "history.csv")) as f:
        rows = list(csv.DictReader(f))
    return [{k: v for k, v in row.items() if not k.startswith("seconds")} for row in rows]


def twice(case, command, extra=()):
    runs = []
    for name in ("first", "second"):
        d = os.path.join(case, name)
        case_variants.run_flexopt(["mpirun", "-n", "2", flexopt, command, case, "--out", d,
                                   "-fx_deterministic"] + list(extra))
        runs.append(d)
    return runs


rod = case_variants.write_variant(os.path.join(cases, "slider_crank_topopt"), os.path.join(out, "ffrf"),
                                  [("mesh: {size: 0.005, order: 2}", "mesh: {size: 0.01, order: 2}")],
                                  optimization=True)
a, b = twice(rod, "optimize", ["--max-iterations", str(iterations)])
ha, hb = history(a), history(b)
expect(len(ha) == iterations and ha == hb,
       f"FFRF optimize: history.csv identical over {len(ha)} iterations (timings left out)")
same_datasets(a, b, "design.h5", "FFRF optimize")
same_summaries(a, b, "FFRF optimize")

beam = case_variants.write_variant(os.path.join(cases, "spin_up_beam_acf"), os.path.join(out, "acf"), end=1.0)
a, b = twice(beam, "simulate")
same_datasets(a, b, "motion.h5", "ACF simulate")
same_summaries(a, b, "ACF simulate")
finish("two runs on 2 ranks with -fx_deterministic give the same bits")
