#!/usr/bin/python3
"""Runs every shipped case with a flexopt binary and compares two such runs to 1e-12.

For refactoring under the rule "behaviour does not change": run the cases with the old binary
into A and with the new one into B, then compare every summary.json and optimize's history.csv
of A and B; a second run of the old binary (--noise) shows the code's own run-to-run noise.

  compare_cases.py run --flexopt BIN --out DIR [--ranks 2] [--cases NAME ...]
                       [--iterations 5] [--repeat K]
      For every cases/NAME/case.yaml: `mpirun -n RANKS BIN simulate cases/NAME --out
      DIR/NAME/simulate`, and if it has a `design:` section `mpirun -n RANKS BIN optimize
      cases/NAME --out DIR/NAME/optimize --max-iterations N` (run from the repository root).
      An earlier DIR/NAME/<command>/ is removed first (no stale results).  Each run's command,
      stdout + stderr, exit code and seconds go to DIR/NAME/<command>.log; a failure does not
      stop the others.  A table at the end, also in DIR/runs.json; exit 1 if a run failed.
      --repeat K: the whole set K times into DIR/rep1 ... DIR/repK.
  compare_cases.py compare A B [--rtol 1e-12] [--noise A2] [--json REPORT]
      Every summary.json and history.csv under A or B.  Numbers: |a - b| <= rtol * scale with
      scale = max(|a|, |b|) for a scalar and the largest magnitude of the whole array (both
      sides; nested numeric lists are one array) for an array element; the worst element is
      reported per key path.  history.csv: each numeric column is such an array.  Strings:
      equal after replacing the runs' output roots with <OUT>.  Keys on one side only,
      lengths and types are reported too.  --noise A2 (a second run of A's binary, e.g.
      DIR/rep2 against DIR/rep1): a difference not larger than A/A2's at the same key path is
      "within run-to-run noise".  Exit 0; 1 if a file is on one side only or unreadable.

Ignored keys (from the summary.json writers in src/ and real runs): a key whose name
  - ends with `_s`, seconds (wall_s, solve_s, integration_s, forward_s, adjoint_s, plan_s,
    prerun_s, predicted_cost_s, reduction_s, timings.*_s), but not `_rad_s` (spin_rad_s),
  - contains `seconds` (seconds_split; history.csv's seconds, seconds_<part>), `time_per`,
    `per_second` (steps_per_second), `timing` (the timings block), `memory` (peak_memory_mib,
    peak_memory_total_mib), `elapsed`, the words `wall`, `date`, `version` (not `update`),
    `eta_` / `_eta` (a bare `eta` would be the projection threshold: compared),
  - is `bytes` (motion.bytes, the file on disk) or `checkpoint_bytes` (storage measured);
    motion.estimated_bytes is computed from the frame count and is compared.
history.csv is written with %.17g (objective, constraints, max_change): compared exactly.
"""
import argparse
import csv
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mpi_job  # noqa: E402 (after the path to scripts/)

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
IGNORE_RE = re.compile(r"((?<!_rad)_s$|seconds|(^|_)wall($|_)|time_per|per_second|timing|memory"
                       r"|elapsed|(^|_)(date|version)($|_)|^eta_|_eta$)")
IGNORE_NAMES = {"bytes", "checkpoint_bytes"}
FILES = ("summary.json", "history.csv")


def ignored(name):
    return name in IGNORE_NAMES or bool(IGNORE_RE.search(name))


def list_cases(names):
    root = os.path.join(REPO, "cases")
    found = sorted(d for d in os.listdir(root) if os.path.isfile(os.path.join(root, d, "case.yaml")))
    if not names:
        return found
    wanted = [os.path.basename(os.path.normpath(n)) for n in names]
    unknown = [n for n in wanted if n not in found]
    if unknown:
        sys.exit(f"unknown case(s): {', '.join(unknown)} (cases/: {', '.join(found)})")
    return wanted


def has_design(case):
    path = os.path.join(REPO, "cases", case, "case.yaml")
    try:
        import yaml
        with open(path) as f:
            return "design" in (yaml.safe_load(f) or {})
    except ImportError:
        with open(path) as f:
            return any(re.match(r"design\s*:", line) for line in f)


def run_one(args, case, command, out_root):
    out = os.path.join(out_root, case, command)
    cmd = ["mpirun", "-n", str(args.ranks), args.flexopt, command, f"cases/{case}", "--out", out]
    if command == "optimize":
        cmd += ["--max-iterations", str(args.iterations)]
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_btl_vader_single_copy_mechanism="none")
    if os.path.isdir(out):
        shutil.rmtree(out)  # this script's own earlier output: leave no stale results
    os.makedirs(os.path.join(out_root, case), exist_ok=True)
    log = os.path.join(out_root, case, f"{command}.log")
    print(f"$ {' '.join(cmd)}", end="", flush=True)
    with open(log, "w") as f:
        f.write(f"$ (cd {REPO} && {' '.join(cmd)})\n")
        f.flush()
        start = time.monotonic()
        try:
            rc = mpi_job.run(cmd, cwd=REPO, env=env, stdout=f, stderr=subprocess.STDOUT).returncode
        except OSError as e:  # mpirun not found, ...
            rc = f"error: {e}"
        seconds = time.monotonic() - start
        f.write(f"\n# exit code {rc}, {seconds:.2f} s\n")
    print(f"  -> exit {rc}, {seconds:.1f} s", flush=True)
    return {"case": case, "command": command, "exit_code": rc, "seconds": round(seconds, 3), "log": log}


def cmd_run(args):
    args.flexopt = os.path.abspath(args.flexopt)
    if not os.access(args.flexopt, os.X_OK):
        sys.exit(f"not an executable: {args.flexopt}")
    out = os.path.abspath(args.out)
    cases = list_cases(args.cases)
    roots = [out] if args.repeat == 1 else [os.path.join(out, f"rep{k}") for k in range(1, args.repeat + 1)]
    runs = []
    for root in roots:
        for case in cases:
            for command in ["simulate"] + (["optimize"] if has_design(case) else []):
                runs.append(dict(run_one(args, case, command, root), root=root))
    info_file, earlier = os.path.join(out, "runs.json"), []
    try:  # keep the record of earlier invocations into DIR for other cases
        with open(info_file) as f:
            done = {(r["root"], r["case"], r["command"]) for r in runs}
            earlier = [r for r in json.load(f)["runs"] if (r["root"], r["case"], r["command"]) not in done]
    except (OSError, ValueError, KeyError):
        pass
    with open(info_file, "w") as f:
        with open(args.flexopt, "rb") as b:  # which binary made these results
            sha256 = hashlib.sha256(b.read()).hexdigest()
        json.dump({"flexopt": args.flexopt, "flexopt_sha256": sha256, "ranks": args.ranks, "iterations": args.iterations,
                   "roots": sorted({r["root"] for r in earlier + runs}), "runs": earlier + runs}, f, indent=1)
    print(f"\n{'case':<24} {'command':<9} {'exit':>7} {'seconds':>9}" + ("  rep" if len(roots) > 1 else ""))
    for r in runs:
        rep = f"  {os.path.basename(r['root'])}" if len(roots) > 1 else ""
        print(f"{r['case']:<24} {r['command']:<9} {str(r['exit_code']):>7} {r['seconds']:>9.1f}{rep}")
    failed = [r for r in runs if r["exit_code"] != 0]
    print(f"{len(runs)} runs, {len(failed)} failed")
    return 1 if failed else 0


def is_num(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def flat_numbers(v, at=""):
    """A (nested) list of numbers as one flat list of (index, value); None if not all numbers."""
    out = []
    for i, x in enumerate(v):
        if isinstance(x, list):
            sub = flat_numbers(x, f"{at}[{i}]")
            if sub is None:
                return None
            out.extend(sub)
        elif is_num(x):
            out.append((f"{at}[{i}]", float(x)))
        else:
            return None
    return out


def rel_diff(a, b, scale):
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    if not (math.isfinite(a) and math.isfinite(b)) or scale == 0.0:
        return math.inf
    return abs(a - b) / scale


class Comparison:
    """Walks two decoded files; `entries` maps key path -> {a, b, rel, note} per compared item."""

    def __init__(self, roots):
        self.roots = roots  # output roots replaced by <OUT> in strings
        self.entries = {}

    def norm(self, s):
        for r in self.roots:
            s = s.replace(r, "<OUT>")
        return s

    def add(self, path, a, b, rel, note=""):
        self.entries[path] = {"a": a, "b": b, "rel": rel, "note": note}

    def array(self, path, xa, xb):
        if len(xa) != len(xb):
            return self.add(path, f"{len(xa)} values", f"{len(xb)} values", math.inf, "length differs")
        if not xa:
            return self.add(path, "[]", "[]", 0.0)
        scale = max([abs(x) for _, x in xa + xb if math.isfinite(x)], default=0.0)
        rels = [rel_diff(x, y, scale) for (_, x), (_, y) in zip(xa, xb)]
        at = max(range(len(rels)), key=rels.__getitem__)
        note = f"worst at {xa[at][0]} of {len(xa)} values, scale {scale:.6g}" if len(xa) > 1 else ""
        self.add(path, xa[at][1], xb[at][1], rels[at], note)

    def walk(self, a, b, path):
        if isinstance(a, dict) and isinstance(b, dict):
            for k in sorted(set(a) | set(b), key=str):
                if ignored(str(k)):
                    continue
                p = f"{path}.{k}" if path else str(k)
                if k not in b:
                    self.add(p, "present", "missing", math.inf, "key only in A")
                elif k not in a:
                    self.add(p, "missing", "present", math.inf, "key only in B")
                else:
                    self.walk(a[k], b[k], p)
        elif isinstance(a, list) and isinstance(b, list):
            xa, xb = flat_numbers(a), flat_numbers(b)
            if xa is not None and xb is not None:
                self.array(path, xa, xb)
            elif len(a) != len(b):
                self.add(path, f"{len(a)} items", f"{len(b)} items", math.inf, "length differs")
            else:
                for i, (x, y) in enumerate(zip(a, b)):
                    self.walk(x, y, f"{path}[{i}]")
        elif is_num(a) and is_num(b):
            self.add(path, a, b, rel_diff(float(a), float(b), max(abs(a), abs(b))))
        elif isinstance(a, str) and isinstance(b, str):
            self.add(path, a, b, 0.0 if self.norm(a) == self.norm(b) else math.inf, "string")
        elif type(a) is not type(b):
            self.add(path, repr(a)[:60], repr(b)[:60], math.inf, "type differs")
        else:  # bool, None
            self.add(path, a, b, 0.0 if a == b else math.inf)


def load(path):
    if path.endswith(".json"):
        with open(path) as f:
            return json.load(f)
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    columns = {}
    for j, name in enumerate(rows[0] if rows else []):
        col = [r[j] if j < len(r) else "" for r in rows[1:]]
        try:
            columns[name.strip()] = [float(x) for x in col]  # a numeric column: an array
        except ValueError:
            columns[name.strip()] = col
    return columns


def result_files(root):
    found = set()
    for d, _, files in os.walk(root):
        found.update(os.path.relpath(os.path.join(d, f), root) for f in files if f in FILES)
    return found


def output_roots(root):
    """The root as given, as it is on disk, and as a run recorded it (runs.json)."""
    roots = {os.path.abspath(root), os.path.realpath(root)}
    for info_file in (os.path.join(root, "runs.json"), os.path.join(root, "..", "runs.json")):
        try:  # DIR/runs.json, or DIR/../runs.json for DIR/repK
            with open(info_file) as f:
                roots.update(json.load(f).get("roots", []))
        except (OSError, ValueError, AttributeError):
            pass
    return sorted(roots, key=len, reverse=True)  # longest first


def compare_trees(a_root, b_root):
    """{relative file: Comparison} of every result file under either root, and problems
    (files missing on one side or unreadable)."""
    roots = output_roots(a_root) + output_roots(b_root)
    results, problems = {}, []
    in_a, in_b = result_files(a_root), result_files(b_root)
    for rel in sorted(in_a | in_b):
        if rel not in in_a or rel not in in_b:
            problems.append(f"{rel}: only in {'A' if rel in in_a else 'B'} ({a_root if rel in in_a else b_root})")
            continue
        try:
            a, b = load(os.path.join(a_root, rel)), load(os.path.join(b_root, rel))
        except (OSError, ValueError) as e:
            problems.append(f"{rel}: {e}")
            continue
        results[rel] = Comparison(roots)
        results[rel].walk(a, b, "")
    return results, problems


def cmd_compare(args):
    if any(d and not os.path.isdir(d) for d in (args.a, args.b, args.noise)):
        sys.exit("A, B and --noise must be directories (result trees of `run`)")
    results, problems = compare_trees(args.a, args.b)
    noise = compare_trees(args.a, args.noise)[0] if args.noise else {}
    n = m = k = 0
    report = {"a": args.a, "b": args.b, "noise": args.noise, "rtol": args.rtol, "files": {}, "problems": problems}
    for rel, c in results.items():
        above = []
        for path, e in c.entries.items():
            n += 1
            if e["rel"] <= args.rtol:
                continue
            m += 1
            ne = noise[rel].entries.get(path) if rel in noise else None
            e = dict(e, path=path, noise=ne["rel"] if ne else None,
                     within_noise=bool(ne and e["rel"] <= ne["rel"]))
            k += e["within_noise"]
            above.append(e)
        report["files"][rel] = {"compared": len(c.entries), "above": above}
        print(f"{rel}: {len(c.entries)} keys, {len(above)} above {args.rtol:g}")
        for e in above:
            nz = "" if e["noise"] is None else f"  noise {e['noise']:.3g}" + (
                " (within run-to-run noise)" if e["within_noise"] else "")
            a, b = (f"{v:.17g}" if isinstance(v, float) else v for v in (e["a"], e["b"]))
            print(f"  {e['path']}: A {a}  B {b}  rel {e['rel']:.3g}{nz}"
                  + (f"  [{e['note']}]" if e["note"] and e["note"] != "string" else ""))
    for p in problems:
        print(f"PROBLEM {p}")
    print(f"{n} keys compared, {m} above {args.rtol:g} "
          + (f"({k} within run-to-run noise)" if args.noise else "(no noise run given)"))
    report.update(compared=n, above=m, within_noise=k)
    if args.json:
        def finite(v):  # strict JSON: inf and nan as strings
            if isinstance(v, dict):
                return {key: finite(x) for key, x in v.items()}
            if isinstance(v, list):
                return [finite(x) for x in v]
            return str(v) if isinstance(v, float) and not math.isfinite(v) else v
        with open(args.json, "w") as f:
            json.dump(finite(report), f, indent=1, allow_nan=False)
    return 1 if problems else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    r = sub.add_parser("run", help="run the cases with one binary")
    r.add_argument("--flexopt", required=True)
    r.add_argument("--out", required=True)
    r.add_argument("--ranks", type=int, default=2)
    r.add_argument("--cases", nargs="+", help="case names (default: every cases/*/case.yaml)")
    r.add_argument("--iterations", type=int, default=5, help="optimize --max-iterations")
    r.add_argument("--repeat", type=int, default=1, help="run the set K times into OUT/rep1..repK")
    c = sub.add_parser("compare", help="compare two result trees")
    c.add_argument("a", help="result tree of the reference (old) binary")
    c.add_argument("b", help="result tree to check (new binary)")
    c.add_argument("--rtol", type=float, default=1e-12)
    c.add_argument("--noise", help="a second run of A's binary: A's run-to-run noise")
    c.add_argument("--json", help="write the report to this file")
    args = ap.parse_args()
    return cmd_run(args) if args.what == "run" else cmd_compare(args)


if __name__ == "__main__":
    sys.exit(main())
