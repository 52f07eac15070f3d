#!/usr/bin/python3
"""The design ladder of issue 47 on cases/slider_crank_topopt (the rod of a slider-crank at
150 rad/s, the time average of its strain energy with half of its design region): each rung
designs the same rod with the same design field (region, filter, projection, MMA) and is timed;
every design is then evaluated in the same dynamic model (the case's FFRF rod, `flexopt simulate
--design`), so the rungs compare by the objective they were all meant to reduce.

Rungs (--rungs, comma-separated; default all but `static`):
  static      the single-instant static design of scripts/study_dynamic_vs_static.py: its
              study.json (--static-study FILE; docs/figures/study_dynamic_vs_static.json holds
              a run's) gives the design's wall time and its objective in the same FFRF model
  esl12       equivalent static loads, 12 instants (`optimizer: {method: esl}`, theory 14)
  esl48       the same with 48 instants
  fixed       FFRF with the basis held fixed in the gradient (`adjoint: {basis: fixed}`)
  exact       FFRF with the exact derivative of its reduction (the case as it is)

With --acf every rung's design (of OUT/ladder.json: this run's and the earlier ones') is also
evaluated with the rod `model: acf`, the geometrically nonlinear model on the same mesh.
ESL runs at most --outer outer iterations of the case's max_iterations static iterations.
Writes OUT/ladder.json (rungs measured before in OUT kept), and with --figure a PNG (objective
against wall time per rung).

usage: study_design_ladder.py --flexopt BUILD/flexopt --out DIR [--ranks 2] [--rungs ...]
       [--outer 4] [--static-study study.json] [--figure docs/figures/study_design_ladder.png]
       [--plot-only] [--acf]
"""
import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from case_variants import write_variant  # noqa: E402
from study_run import run_flexopt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CASE = os.path.join(ROOT, "cases", "slider_crank_topopt")
OPTIMIZER = "optimizer: {max_iterations: 100, move_limit: 0.2, tolerance: 1.0e-3}"

p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
p.add_argument("--flexopt", required=True)
p.add_argument("--out", required=True)
p.add_argument("--ranks", type=int, default=2)
p.add_argument("--rungs", default="esl12,esl48,fixed,exact")
p.add_argument("--outer", type=int, default=4)
p.add_argument("--static-study", default=None)
p.add_argument("--figure", default=None)
p.add_argument("--plot-only", action="store_true", help="the figure of OUT/ladder.json, nothing run")
p.add_argument("--acf", action="store_true", help="also evaluate every rung's design with the rod model: acf")
args = p.parse_args()
flexopt, out = os.path.abspath(args.flexopt), os.path.abspath(args.out)
os.makedirs(out, exist_ok=True)


def variant(name):
    """The case for rung `name` (its optimization sections kept) in OUT/NAME."""
    if name.startswith("esl"):
        esl = f"method: esl, instants: {int(name[3:])}, outer_iterations: {args.outer}, "
        replace = [(OPTIMIZER, OPTIMIZER.replace("{", "{" + esl, 1))]
    elif name == "fixed":
        replace = [(OPTIMIZER, OPTIMIZER + "\nadjoint: {basis: fixed}")]
    else:
        replace = []
    return write_variant(CASE, os.path.join(out, name), replace, optimization=True)


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
        case = write_variant(CASE, os.path.join(out, "acf_model"), [("model: ffrf", "model: acf")],
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
    if name.startswith("esl"):
        rung.update({k: summary[k] for k in ("outer_iterations", "inner_iterations", "dynamic_objective",
                                             "static_objective", "max_change", "converged")})
    elif "iterations" in summary:
        rung["iterations"] = summary["iterations"]
    ladder[name] = rung
    print(f"{name:7s} objective {objective:.6g} J  volume fraction {volume:.5f}  wall {wall:.1f} s", flush=True)
    json.dump(ladder, open(os.path.join(out, "ladder.json"), "w"), indent=1)

# Every rung's design in the ACF model (--acf): the objective of the finest model.
for name, r in ladder.items() if args.acf else []:
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
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, r in ladder.items():
        ax.plot(r["wall_s"], r["objective"], "o")
        ax.annotate(name, (r["wall_s"], r["objective"]), textcoords="offset points", xytext=(5, 5))
    ax.set_xscale("log")
    ax.set_xlabel("design wall time [s] (2 ranks)")
    ax.set_ylabel("mean strain energy of the design [J] (FFRF rod)")
    ax.set_title("slider-crank rod: the design ladder")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.figure, dpi=120)
    print("wrote " + args.figure)
