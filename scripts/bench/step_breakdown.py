#!/usr/bin/python3
"""Per-step breakdown of a `flexopt simulate` run of a scene with ACF bodies from its -log_view
file (stage "Time steps") and its summary.json (docs/benchmarks.md, scripts/bench/acf_link.sh).

usage: step_breakdown.py LOG_VIEW SUMMARY_JSON [--label TEXT] [--header]

Prints one Markdown table row, the times in ms per step (the largest rank's, as -log_view's
"Max" column):
  element loops   FxCorotForce + FxCorotTangent: the co-rotated element kernels with their
                  VecSetValues/MatSetValues (tangent loops: one per factorization);
  assembly        FxNewtonMatrix + FxNewtonRhs less the element loops: zeroing, the assembly
                  passes, the constraints' rows (ties, joints), M acc, the scaling;
  factorization   PCSetUp (the numeric LU; the symbolic one once);
  solves          MatSolve (the triangular solves; KSPSolve's own overhead counts as other);
  other           the rest of the stage: the predictor, the updates, the run loop's monitor
                  and output.
"""
import argparse
import json
import re
import sys

COLUMNS = ["ranks", "steps", "steps/s", "Newton iterations / step", "factorizations / step",
           "ms / step", "element loops", "of which tangent loops", "assembly", "factorization",
           "solves", "other"]


def stage_events(path, stage):
    """{event: (count, max time [s])} of the stage, and the stage's total time [s]."""
    events, total, inside = {}, None, False
    for line in open(path):
        m = re.match(r"\s*\d+:\s+(.+?):\s+([0-9.e+-]+)\s", line)
        if m and m.group(1) == stage and total is None:
            total = float(m.group(2))
        if line.startswith("--- Event Stage"):
            inside = line.split(":", 1)[1].strip() == stage
            continue
        if inside:
            f = line.split()
            if len(f) > 4 and re.match(r"^\d+$", f[1]):
                events[f[0]] = (int(f[1]), float(f[3]))
    if total is None:
        sys.exit(f"{path}: no stage '{stage}' in the -log_view output")
    return events, total


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log")
    ap.add_argument("summary")
    ap.add_argument("--label", default="")
    ap.add_argument("--header", action="store_true")
    a = ap.parse_args()
    s = json.load(open(a.summary))
    ev, total = stage_events(a.log, "Time steps")
    t = lambda name: ev.get(name, (0, 0.0))[1]
    steps = s["steps"]
    elements = t("FxCorotForce") + t("FxCorotTangent")
    assembly = t("FxNewtonMatrix") + t("FxNewtonRhs") - elements
    factor, solve = t("PCSetUp"), t("MatSolve")
    other = total - elements - assembly - factor - solve
    ms = lambda x: f"{1e3 * x / steps:.3f}"
    row = [str(s["ranks"]) if "ranks" in s else "", str(steps),
           f"{s['steps_per_second']:.0f}", f"{s['newton_iterations_total'] / steps:.2f}",
           f"{s['newton_factorizations_total'] / steps:.2f}", ms(total), ms(elements),
           ms(t("FxCorotTangent")), ms(assembly), ms(factor), ms(solve), ms(other)]
    cols = COLUMNS
    if a.label:
        cols, row = ["run"] + cols, [a.label] + row
    if a.header:
        print("| " + " | ".join(cols) + " |")
        print("|" + "---|" * len(cols))
    print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
