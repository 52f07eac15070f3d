#!/usr/bin/python3
"""Regression check of a case directory against its reference.yaml.

Runs flexopt on the case (2 MPI ranks by default) for every run that reference.yaml lists,
reads the run's summary.json and compares each check:

    source: "where the reference values come from"
    runs:                                   # or a single run: command/args/checks at top level
      - command: simulate                   # flexopt command
        args: [--count, "6"]                # optional extra arguments
        checks:
          - {path: sensors.tip.value[1], value: -7.634e-3, rel_tol: 0.02, source: "..."}
          - {path: compliance, value: 37.9, abs_tol: 0.5}
          - {path: frequencies_hz[0:6], max_abs: 0.2}      # every selected |value| <= max_abs
          - {path: "objective[-1]", ratio_to: "objective[0]", max: 0.7}   # value / other <= max
          # time series (a sensor's t/value, or a list against output_times):
          - {path: sensors.tip, component: 1, period: 1.9339, between: [0, 2], rel_tol: 1.0e-4}
          - {path: sensors.s, component: 0, formula: "0.2*np.cos(t)", max_abs_err: 1.0e-8}
          - {path: energy, max_relative_change: 1.0e-6}
          - {path: sensors.tip, component: 1, minimum: -0.40, rel_tol: 0.05, at: 7.0, time_tol: 0.5}
          - {path: sensors.tip, component: 1, max_abs_over: [0, 15], max: 1.0}   # bounded
          # distance of a position sensor from the line through two others, signed by the
          # normal n: ((b - a) x (m - a)) . n / |b - a|, at the sample nearest `at`
          - {path: sensors.mid, chord: [end_a, end_b], normal: [0, 0, 1], at: 0.1, value: 1.9e-4, rel_tol: 0.1}

Usage: check_case.py CASE_DIR [--flexopt build/flexopt] [--ranks 2] [--out DIR] [--reference FILE]
Exit status 0 if every check passes.
"""
import argparse
import json
import os
import re
import subprocess
import sys

import yaml
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mpi_job  # noqa: E402 (after the path to scripts/)


def select(summary, path):
    """Returns the value at a dotted path with [i] (negative: from the end) or [a:b] indices."""
    value = summary
    for part in path.split("."):
        m = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_:]*)((?:\[-?[0-9:]+\])*)", part)
        if not m:
            raise KeyError(f"bad path component '{part}'")
        value = value[m.group(1)]
        for idx in re.findall(r"\[(-?[0-9:]+)\]", m.group(2)):
            if ":" in idx:
                a, b = idx.split(":")
                value = value[int(a) if a else None:int(b) if b else None]
            else:
                value = value[int(idx)]
    return value


def series(summary, check):
    """The time series a check names: times t and values (component `component` of vector
    values, if given) of `path`, a sensor (with t and value) or a plain list (times from
    output_times)."""
    import numpy as np
    got = select(summary, check["path"])
    if isinstance(got, dict):
        t, v = got["t"], got["value"]
    else:
        t, v = summary["output_times"], got
    v = np.array(v, dtype=float)
    if "component" in check:
        v = v[:, int(check["component"])]
    return np.array(t, dtype=float), v


def maxima_period(t, v, first, second):
    """Time between interior maxima number `first` and `second` (0-based) of v(t), each located
    by the parabola through the three samples around it, or None."""
    import numpy as np
    peaks = []
    for i in range(1, len(v) - 1):
        if v[i] >= v[i - 1] and v[i] > v[i + 1]:
            a, b, _ = np.polyfit(t[i - 1:i + 2] - t[i], v[i - 1:i + 2], 2)
            peaks.append(t[i] - b / (2 * a))
        if len(peaks) > second:
            return peaks[second] - peaks[first]
    return None


def check_derived(summary, check):
    """Checks on time series: `formula` (numpy expression in t, or statements setting `value`;
    every sample within max_abs_err), `period` (time between the maxima `between: [i, j]`,
    default the first two, against period/rel_tol; choose a component whose maxima are
    quadratic, not flat) and
    `max_relative_change` (max |v - v[0]| / |v[0]| <= the given bound)."""
    import numpy as np
    path = check["path"]
    try:
        t, v = series(summary, check)
    except (KeyError, IndexError, TypeError) as e:
        return False, f"{path}: not in summary.json ({e})"
    label = path + (f"[{check['component']}]" if "component" in check else "")
    if "formula" in check:
        ns = {"np": np, "t": t, "pi": np.pi}
        if "value =" in check["formula"]:  # statements that set `value`
            exec(check["formula"], ns)
            expected = ns["value"]
        else:
            expected = eval(check["formula"], ns)
        err = float(np.max(np.abs(v - expected)))
        shown = check["formula"] if len(check["formula"]) < 60 else check.get("name", "formula")
        return err <= check["max_abs_err"], (f"{label}: max |value - ({shown})| "
                                             f"{err:.3g} <= {check['max_abs_err']:.3g} over {len(t)} samples")
    if "chord" in check:
        a, b = (np.array(select(summary, "sensors." + n)["value"], dtype=float) for n in check["chord"])
        d = b - a
        off = np.cross(d, v - a) @ np.array(check["normal"], dtype=float) / np.linalg.norm(d, axis=1)
        k = int(np.argmin(np.abs(t - check["at"])))
        if abs(t[k] - check["at"]) > 1e-9 * max(1.0, abs(check["at"])):
            return False, f"{label}: no sample at t = {check['at']}"
        ref = check["value"]
        rel = abs(off[k] - ref) / abs(ref)
        return rel <= check["rel_tol"], (f"{label}: distance from the chord {'-'.join(check['chord'])} at "
                                         f"t = {t[k]:.6g}: {off[k]:.6g} vs {ref:.6g}, rel err {rel:.3g} <= {check['rel_tol']:.3g}")
    if "minimum" in check or "maximum" in check:
        kind = "minimum" if "minimum" in check else "maximum"
        k = int(np.argmin(v) if kind == "minimum" else np.argmax(v))
        ref = check[kind]
        rel = abs(v[k] - ref) / abs(ref)
        ok = rel <= check["rel_tol"]
        msg = f"{label}: {kind} {v[k]:.6g} at t = {t[k]:.4g} vs {ref:.6g}, rel err {rel:.3g} <= {check['rel_tol']:.3g}"
        if "at" in check:
            dt = abs(t[k] - check["at"])
            ok = ok and dt <= check["time_tol"]
            msg += f"; time {t[k]:.4g} vs {check['at']:.4g}, |dt| {dt:.3g} <= {check['time_tol']:.3g}"
        return ok, msg
    if "max_abs_over" in check:
        t0, t1 = check["max_abs_over"]
        window = np.abs(v[(t >= t0) & (t <= t1)])
        if window.size == 0:
            return False, f"{label}: no samples in [{t0}, {t1}]"
        worst = float(np.max(window))
        if "max" in check:
            return worst <= check["max"], f"{label}: max |value| over [{t0}, {t1}] {worst:.6g} <= {check['max']:.6g}"
        return worst >= check["min"], f"{label}: max |value| over [{t0}, {t1}] {worst:.6g} >= {check['min']:.6g}"
    if "period" in check:
        i, j = check.get("between", [0, 1])
        T = maxima_period(t, v, i, j)
        if T is None:
            return False, f"{label}: fewer than two maxima, no period"
        rel = abs(T - check["period"]) / abs(check["period"])
        return rel <= check["rel_tol"], f"{label}: period {T:.10g} vs {check['period']:.10g}, rel err {rel:.3g} <= {check['rel_tol']:.3g}"
    bound = check["max_relative_change"]
    change = float(np.max(np.abs(v - v[0])) / abs(v[0]))
    return change <= bound, f"{label}: max |v - v0| / |v0| {change:.3g} <= {bound:.3g}"


def check_one(summary, check):
    if any(k in check for k in ("formula", "period", "max_relative_change", "minimum", "maximum",
                                "max_abs_over", "chord")):
        return check_derived(summary, check)
    path = check["path"]
    try:
        got = select(summary, path)
    except (KeyError, IndexError, TypeError) as e:
        return False, f"{path}: not in summary.json ({e})"
    values = got if isinstance(got, list) else [got]
    if "ratio_to" in check:
        other = select(summary, check["ratio_to"])
        ratio = got / other
        if "max" in check:
            return ratio <= check["max"], f"{path} / {check['ratio_to']} = {got:.6g} / {other:.6g} = {ratio:.4g} <= {check['max']:.4g}"
        return ratio >= check["min"], f"{path} / {check['ratio_to']} = {got:.6g} / {other:.6g} = {ratio:.4g} >= {check['min']:.4g}"
    if "count" in check:
        n = len(got) if isinstance(got, list) else -1
        return n == check["count"], f"{path}: {n} entries, expected {check['count']}"
    if "max_abs" in check:
        worst = max(abs(v) for v in values)
        ok = worst <= check["max_abs"]
        return ok, f"{path}: max |value| {worst:.6g} <= {check['max_abs']:.6g}"
    ref = check["value"]
    if isinstance(got, list):
        return False, f"{path}: selects a list; compare single values"
    err = abs(got - ref)
    if "rel_tol" in check:
        rel = err / abs(ref) if ref != 0 else float("inf")
        return rel <= check["rel_tol"], f"{path}: {got:.10g} vs {ref:.10g}, rel err {rel:.3g} <= {check['rel_tol']:.3g}"
    if "abs_tol" in check:
        return err <= check["abs_tol"], f"{path}: {got:.10g} vs {ref:.10g}, abs err {err:.3g} <= {check['abs_tol']:.3g}"
    return False, f"{path}: check needs rel_tol, abs_tol or max_abs"


def verify_xdmf(path):
    """Checks that every HDF5 dataset an XDMF file names exists with the stated dimensions,
    and that topology indices address existing nodes: what ParaView needs to open it."""
    import xml.etree.ElementTree as ET
    import h5py
    problems = []
    base = os.path.dirname(path)
    root = ET.parse(path).getroot()
    grids = root.findall(".//Grid[@GridType='Uniform']")
    if not grids:
        problems.append("no grids")
    for item in root.iter("DataItem"):
        fname, dset = item.text.strip().split(":", 1)
        dims = tuple(int(d) for d in item.get("Dimensions").split())
        with h5py.File(os.path.join(base, fname), "r") as h5:
            if dset not in h5:
                problems.append(f"{dset} missing in {fname}")
                continue
            if h5[dset].shape != dims:
                problems.append(f"{dset}: shape {h5[dset].shape} but XDMF says {dims}")
    with h5py.File(os.path.join(base, os.path.basename(path)[:-5] + ".h5"), "r") as h5:
        topo, geom = h5["/mesh/topology"][...], h5["/mesh/geometry"][...]
        if topo.min() < 0 or topo.max() >= geom.shape[0]:
            problems.append("topology addresses nodes outside the geometry")
    return problems


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("case")
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--flexopt", default=os.path.join(here, "..", "build", "flexopt"))
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--out", default=None, help="output directory (default: CASE/out)")
    ap.add_argument("--reference", default=None,
                    help="reference file (default: CASE/reference.yaml)")
    args = ap.parse_args()

    with open(args.reference or os.path.join(args.case, "reference.yaml")) as f:
        ref = yaml.safe_load(f)
    runs = ref.get("runs") or [{"command": ref["command"], "args": ref.get("args", []), "checks": ref["checks"]}]
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    failures = 0
    print(f"case {args.case}: reference from {ref.get('source', '(no source given)')}")
    for i, run in enumerate(runs):
        out = args.out or os.path.join(args.case, "out")
        out = os.path.join(out, f"check_{i}")
        cmd = ["mpirun", "-n", str(args.ranks), args.flexopt, run["command"], args.case, "--out", out]
        cmd += [str(a) for a in run.get("args", [])]
        print("$ " + " ".join(cmd), flush=True)
        proc = mpi_job.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        sys.stdout.write(proc.stdout)
        if proc.returncode != 0:
            print(f"FAIL: flexopt exited with {proc.returncode}")
            failures += 1
            continue
        with open(os.path.join(out, "summary.json")) as f:
            summary = json.load(f)
        if "output" in summary:
            problems = verify_xdmf(summary["output"])
            print(("ok    " if not problems else "FAIL  ") + f"{summary['output']}: XDMF/HDF5 consistent"
                  + ("" if not problems else ": " + "; ".join(problems)))
            failures += len(problems)
        for check in run["checks"]:
            ok, text = check_one(summary, check)
            print(("ok    " if ok else "FAIL  ") + text)
            failures += 0 if ok else 1
    print(f"{args.case}: {'all checks passed' if failures == 0 else str(failures) + ' check(s) failed'}")
    return 0 if failures == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
