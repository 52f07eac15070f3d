#!/usr/bin/python3
"""The design ladder of issue 47 on a dynamic case whose objective is the time average of its
FFRF design body's strain energy (--case; default cases/slider_crank_topopt, the rod of a
slider-crank at 150 rad/s; cases/heavy_arm_topopt, a slow arm with a 5 kg payload under gravity):
each rung designs the same body with the same design field (region, filter, projection, MMA) and
is timed; every design is then evaluated in the same dynamic model (the case's FFRF body,
`flexopt simulate --design`), so the rungs compare by the objective they were all meant to reduce.

Rungs (--rungs, comma-separated; default all but `static`):
  static      the single-instant static design of scripts/study_dynamic_vs_static.py: its
              study.json (--static-study FILE; docs/figures/study_dynamic_vs_static.json holds
              a run's) gives the design's wall time and its objective in the same FFRF model
  esl12       equivalent static loads, 12 instants (`optimizer: {method: esl}`, theory 14)
  esl48       the same with 48 instants
  fixed       FFRF with the basis held fixed in the gradient (`adjoint: {basis: fixed}`)
  exact       FFRF with the exact derivative of its reduction (the case as it is)
  exactM      the same with M MMA iterations (exact160: as many as ESL's 4 outer iterations of 40)
  acf         the design body `model: acf` (every `model: ffrf` of the case made ACF: in both
              scenes that is the design body alone; co-rotated elements on the same mesh, the
              geometrically nonlinear model) in the design loop: the finest rung
  peak        a single-instant static design computed by flexopt itself: the instant of esl48's
              first loads (OUT/esl48/out/esl/loads_00.csv) with the largest moment about the
              clamped interface (--arm: the other interface's position in the body's axes), the
              case run up to it and `method: esl, instants: 1, outer_iterations: 1`

With --acf every rung's design (of OUT/ladder.json: this run's, and earlier ones not evaluated
there yet) is also evaluated with the design body `model: acf`, the geometrically nonlinear
model on the same mesh.
ESL runs at most --outer outer iterations of the case's max_iterations static iterations.
Writes OUT/ladder.json (rungs measured before in OUT kept), and with --figure a PNG (objective
against wall time per rung).

usage: study_design_ladder.py --flexopt BUILD/flexopt --out DIR [--case DIR] [--ranks 2] [--rungs ...]
       [--outer 4] [--static-study study.json] [--figure docs/figures/study_design_ladder.png]
       [--plot-only] [--acf] [--arm 0.3,0,0]
"""
import argparse
import csv
import functools
import json
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from case_variants import write_variant  # noqa: E402
from study_run import run_flexopt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
p.add_argument("--flexopt", required=True)
p.add_argument("--out", required=True)
p.add_argument("--case", default=os.path.join(ROOT, "cases", "slider_crank_topopt"))
p.add_argument("--arm", default="0.3,0,0", help="peak rung: the second interface in the body's axes [m]")
p.add_argument("--ranks", type=int, default=2)
p.add_argument("--rungs", default="esl12,esl48,fixed,exact")
p.add_argument("--outer", type=int, default=4)
p.add_argument("--static-study", default=None)
p.add_argument("--figure", default=None)
p.add_argument("--plot-only", action="store_true", help="the figure of OUT/ladder.json, nothing run")
p.add_argument("--acf", action="store_true", help="also evaluate every rung's design with the design body model: acf")
args = p.parse_args()
flexopt, out = os.path.abspath(args.flexopt), os.path.abspath(args.out)
CASE = os.path.abspath(args.case)
os.makedirs(out, exist_ok=True)
# The case's optimizer and time lines (one line each, `optimizer: {...}`, `time: {...}`): the
# rungs edit them.
CASE_LINES = open(os.path.join(CASE, "case.yaml")).read().split("\n")
OPTIMIZER = next(line for line in CASE_LINES if line.startswith("optimizer: {"))
TIME = next(line for line in CASE_LINES if line.startswith("time: {"))
# The ACF model of the case: every FFRF body (in both scenes the design body alone) made ACF.
TO_ACF = [("model: ffrf", "model: acf")]


def variant(name):
    """The case for rung `name` (its optimization sections kept) in OUT/NAME."""
    if name.startswith("esl"):
        esl = f"method: esl, instants: {int(name[3:])}, outer_iterations: {args.outer}, "
        replace = [(OPTIMIZER, OPTIMIZER.replace("{", "{" + esl, 1))]
    elif name == "fixed":
        replace = [(OPTIMIZER, OPTIMIZER + "\nadjoint: {basis: fixed}")]
    elif re.fullmatch(r"exact\d+", name):
        replace = [(OPTIMIZER, re.sub(r"max_iterations: \d+", f"max_iterations: {name[5:]}", OPTIMIZER))]
    elif name == "acf":
        replace = TO_ACF
    elif name == "peak":
        end = peak_time()
        replace = [(OPTIMIZER, OPTIMIZER.replace("{", "{method: esl, instants: 1, outer_iterations: 1, ", 1)),
                   (TIME, re.sub(r"end: [^,}]*", f"end: {end!r}", TIME))]
    else:
        replace = []
    return write_variant(CASE, os.path.join(out, name), replace, optimization=True)


@functools.lru_cache(maxsize=None)
def peak_time():
    """The time of esl48's first-iteration instant with the largest moment about the clamped
    interface from the other interfaces' loads: |M + r x F| (r = --arm)."""
    loads = os.path.join(out, "esl48", "out", "esl", "loads_00.csv")
    if not os.path.exists(loads):
        sys.exit(f"the peak rung needs {loads}: run the esl48 rung first")
    r = [float(v) for v in args.arm.split(",")]
    moment = {}
    for row in csv.DictReader(open(loads)):
        f = [float(row[k]) for k in ("fx", "fy", "fz")]
        m = [float(row[k]) + c for k, c in zip(("mx", "my", "mz"),
                                               (r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2],
                                                r[0] * f[1] - r[1] * f[0]))]
        t = float(row["time"])
        moment[t] = max(moment.get(t, 0.0), math.sqrt(sum(c * c for c in m)))
    t = max(moment, key=moment.get)
    print(f"peak: the instant t = {t:.6g} s, moment {moment[t]:.4g} N m about the clamped interface", flush=True)
    return t


def design_run(name):
    """Optimizes rung `name`; returns (its restart.h5, wall time [s], its own summary)."""
    d = variant(name)
    wall = run_flexopt(flexopt, args.ranks, ["optimize", d, "--out", os.path.join(d, "out")],
                       os.path.join(out, name + ".log"))
    return os.path.join(d, "out", "restart.h5"), wall, json.load(open(os.path.join(d, "out", "summary.json")))


def static_rung():
    """The single-instant static rung from scripts/study_dynamic_vs_static.py's study.json."""
    if not args.static_study:
        sys.exit("the static rung needs --static-study FILE (scripts/study_dynamic_vs_static.py's study.json)")
    s = json.load(open(args.static_study))
    e = s["evaluation"]["static"]
    return {"wall_s": s["static_optimize_s"], "objective": e["objective"], "volume_fraction": e["volume_fraction"],
            "from": args.static_study}


def evaluate(name, design, acf=False):
    """The design's objective and volume fraction in the case's FFRF model, or (acf) with the rod
    `model: acf` (co-rotated elements on the same mesh: the geometrically nonlinear model)."""
    tag = ("acf_" if acf else "") + name
    d = os.path.join(out, "eval_" + tag)
    case = CASE
    if acf:
        case = write_variant(CASE, os.path.join(out, "acf_model"), TO_ACF,
                             optimization=True)
    run_flexopt(flexopt, args.ranks, ["simulate", case, "--out", d, "--design", design],
                os.path.join(out, f"eval_{tag}.log"))
    e = json.load(open(os.path.join(d, "summary.json")))
    return e["responses"]["objective"], e["responses"]["constraint0"]


# Rungs measured before in OUT are kept (a rung run again replaces its entry).
saved = os.path.join(out, "ladder.json")
ladder = json.load(open(saved)) if os.path.exists(saved) else {}
for name in [] if args.plot_only else args.rungs.split(","):
    if name == "static":
        ladder[name] = static_rung()
        json.dump(ladder, open(os.path.join(out, "ladder.json"), "w"), indent=1)
        continue
    design, wall, summary = design_run(name)
    objective, volume = evaluate(name, design)
    rung = {"wall_s": wall, "objective": objective, "volume_fraction": volume, "design": design}
    if name == "peak":
        rung["time"] = peak_time()
    elif name.startswith("esl"):
        rung.update({k: summary[k] for k in ("outer_iterations", "inner_iterations", "dynamic_objective",
                                             "static_objective", "max_change", "converged")})
    elif "iterations" in summary:
        rung["iterations"] = summary["iterations"]
    ladder[name] = rung
    print(f"{name:7s} objective {objective:.6g} J  volume fraction {volume:.5f}  wall {wall:.1f} s", flush=True)
    json.dump(ladder, open(os.path.join(out, "ladder.json"), "w"), indent=1)

# Every rung's design in the ACF model (--acf): the objective of the finest model.
# A rung evaluated there before and not run again keeps its figure.
ran = [] if args.plot_only else args.rungs.split(",")
for name, r in ladder.items() if args.acf else []:
    if "objective_acf" in r and name not in ran:
        continue
    design = r.get("design") or (os.path.join(os.path.dirname(os.path.abspath(args.static_study)), "static",
                                              "out", "restart.h5") if name == "static" else None)
    if design and os.path.exists(design):
        r["objective_acf"], _ = evaluate(name, design, acf=True)
        print(f"{name:7s} objective in the ACF model {r['objective_acf']:.6g} J", flush=True)
        json.dump(ladder, open(saved, "w"), indent=1)

if args.figure:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for k, (name, r) in enumerate(ladder.items()):
        colour = f"C{k}"
        ax.plot(r["wall_s"], r["objective"], "o", color=colour)
        if "objective_acf" in r:
            ax.plot(r["wall_s"], r["objective_acf"], "s", mfc="none", color=colour)
            ax.plot([r["wall_s"]] * 2, [r["objective"], r["objective_acf"]], ":", color=colour, lw=0.8)
        ax.annotate(name, (r["wall_s"], r["objective"]), textcoords="offset points",
                    xytext=(5, 5 if k % 2 == 0 else -12))
    ax.plot([], [], "ko", label="evaluated in the FFRF model")
    if any("objective_acf" in r for r in ladder.values()):
        ax.plot([], [], "ks", mfc="none", label="evaluated in the ACF model")
    ax.legend(fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel(f"design wall time [s] ({args.ranks} rank(s))")
    ax.set_ylabel("mean strain energy of the design [J]")
    ax.set_title(os.path.basename(CASE) + ": the design ladder")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.figure, dpi=120)
    print("wrote " + args.figure)
