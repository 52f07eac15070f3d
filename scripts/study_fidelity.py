#!/usr/bin/python3
"""Study 2 of issue 21: fidelity against cost. The rod of cases/slider_crank_topopt optimized
with models of different fidelity, every final design evaluated with one fine model.

Variants (each `flexopt optimize` of the case with one setting changed):
  ffrf4, ffrf8, ffrf16   FFRF rod with 4, 8 (the case) and 16 modes, exact basis;
  ffrf8_fixed            8 modes, `adjoint: {basis: fixed}` (the basis of the start design kept,
                         its change with the design ignored in the gradient);
  acf_coarse             ACF rod on the case's mesh with linear elements (Tet4: the same
                         elements and design variables as the Tet10 mesh, a coarser field)
                         and a step of --acf-step (default 1e-4 s: 10 steps per period of the
                         rod's first bending mode; the case's 2e-5 s resolves FFRF's modes to
                         50 steps per period).

The fine model: the ACF rod on the case's Tet10 mesh (`flexopt simulate --design`), the one
with no modal truncation and no small-deformation assumption. For each variant the study
records the optimization's wall time and iterations, its own final objective, and the fine
model's objective of its final design ("the true objective"); and the fine model's objective of
the uniform start. Writes OUT/study.json and, with --figure, the chart of true objective
against wall time. docs/benchmarks.md "Fidelity against cost" holds a run's figures.

usage: study_fidelity.py --flexopt BUILD/flexopt --out DIR [--ranks 2] [--iterations 100]
       [--acf-iterations N] [--acf-step H] [--variants ffrf4,ffrf8,...] [--figure PNG]
A run appends to OUT/study.json: variants run separately (--variants acf_coarse) join the
ones already there, and the uniform start's fine evaluation is made once. The recorded run is
docs/figures/study_fidelity.json (copy it to OUT/study.json to add a variant to it).
"""
import argparse
import json
import os
import sys

import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from study_run import run_flexopt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CASE = os.path.join(ROOT, "cases", "slider_crank_topopt")
VARIANTS = ["ffrf4", "ffrf8", "ffrf16", "ffrf8_fixed", "acf_coarse"]

p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
p.add_argument("--flexopt", required=True)
p.add_argument("--out", required=True)
p.add_argument("--ranks", type=int, default=2)
p.add_argument("--iterations", type=int, default=None, help="optimizer iterations (default: the case's)")
p.add_argument("--acf-iterations", type=int, default=None, help="iterations of acf_coarse (default: --iterations)")
p.add_argument("--acf-step", type=float, default=1e-4, help="time step of acf_coarse [s]")
p.add_argument("--variants", default=",".join(VARIANTS))
p.add_argument("--figure", default=None)
p.add_argument("--plot-only", action="store_true", help="only draw --figure from OUT/study.json")
args = p.parse_args()
flexopt = os.path.abspath(args.flexopt)
out = os.path.abspath(args.out)
os.makedirs(out, exist_ok=True)
variants = [] if args.plot_only else [v for v in args.variants.split(",") if v]
for v in variants:
    if v not in VARIANTS:
        sys.exit(f"study: unknown variant '{v}' (known: {', '.join(VARIANTS)})")


def run(cmd_args, log):
    return run_flexopt(flexopt, args.ranks, cmd_args, log)


def case_variant(name):
    c = yaml.safe_load(open(os.path.join(CASE, "case.yaml")))
    for b in c["bodies"]:
        b["geometry"] = os.path.normpath(os.path.join(CASE, b["geometry"]))
    rod = next(b for b in c["bodies"] if b["name"] == "rod")
    if name.startswith("ffrf"):
        rod["reduction"]["modes"] = int(name[4:].split("_")[0])
        if name.endswith("_fixed"):
            c["adjoint"] = {"basis": "fixed"}
    elif name in ("acf_coarse", "acf_fine"):
        rod["model"] = "acf"
        rod.pop("reduction", None)
        rod["mesh"] = dict(rod["mesh"], order=1 if name == "acf_coarse" else 2)
        if name == "acf_coarse":
            c["time"]["step"] = args.acf_step
    d = os.path.join(out, "case_" + name)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "case.yaml"), "w") as f:
        f.write(f"# written by scripts/study_fidelity.py: cases/slider_crank_topopt, variant {name}\n")
        yaml.safe_dump(c, f, default_flow_style=None, sort_keys=False, width=100)
    return d


fine = case_variant("acf_fine")
study_json = os.path.join(out, "study.json")
report = json.load(open(study_json)) if os.path.exists(study_json) else {
    "case": "cases/slider_crank_topopt", "ranks": args.ranks, "fine_model": "ACF, Tet10 (the case's mesh)",
    "variants": {}}
if "uniform_true_objective" not in report and not args.plot_only:
    t = run(["simulate", fine, "--out", os.path.join(out, "fine_uniform")], os.path.join(out, "fine_uniform.log"))
    report["uniform_true_objective"] = json.load(open(os.path.join(out, "fine_uniform", "summary.json")))["responses"]["objective"]
    report["fine_evaluation_s"] = t
if "uniform_true_objective" in report:
    print(f"uniform start: fine ACF objective {report['uniform_true_objective']:.6g} J", flush=True)
for name in variants:
    d = case_variant(name)
    its = args.acf_iterations if name == "acf_coarse" and args.acf_iterations else args.iterations
    extra = [] if its is None else ["--max-iterations", str(its)]
    run_dir = os.path.join(out, "run_" + name)
    wall = run(["optimize", d, "--out", run_dir] + extra, os.path.join(out, f"run_{name}.log"))
    s = json.load(open(os.path.join(run_dir, "summary.json")))
    ev = os.path.join(out, "fine_" + name)
    run(["simulate", fine, "--out", ev, "--design", os.path.join(run_dir, "restart.h5")],
        os.path.join(out, f"fine_{name}.log"))
    e = json.load(open(os.path.join(ev, "summary.json")))
    r = {"wall_s": wall, "seconds_per_iteration": wall / max(s["iterations"], 1), "iterations": s["iterations"], "own_objective": s["objective"][-1],
         "own_start_objective": s["objective"][0],
         "true_objective": e["responses"]["objective"], "true_volume_fraction": e["responses"]["constraint0"]}
    report["variants"][name] = r
    print(f"{name:12s} {wall:7.0f} s  own objective {r['own_objective']:.6g} J  fine ACF objective "
          f"{r['true_objective']:.6g} J  volume fraction {r['true_volume_fraction']:.5f}", flush=True)
    with open(study_json, "w") as f:
        json.dump(report, f, indent=1)
if variants:
    print(f"wrote {study_json}")

LABELS = {"ffrf4": "FFRF 4 modes", "ffrf8": "FFRF 8", "ffrf16": "FFRF 16",
          "ffrf8_fixed": "FFRF 8,\nbasis fixed", "acf_coarse": "ACF Tet4"}
LEFT = {"ffrf8_fixed"}  # labelled left of the marker (FFRF 4 and 8 sit to its right)

if args.figure:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5))
    for n, (name, r) in enumerate(report["variants"].items()):
        c = f"C{n}"
        ax.plot(r["wall_s"], r["true_objective"], "o", ms=9, color=c)
        ax.plot(r["wall_s"], r["own_objective"], "o", ms=9, mfc="none", color=c)
        ax.plot([r["wall_s"]] * 2, [r["own_objective"], r["true_objective"]], "-", color=c, lw=1)
        # Labelled at the open marker: those spread out more than the true values do.
        ax.annotate(f"{LABELS.get(name, name)}\n({r['iterations']} it.)",
                    (r["wall_s"], r["own_objective"]), textcoords="offset points",
                    xytext=(-7 if name in LEFT else 7, -4), fontsize=9, va="top",
                    ha="right" if name in LEFT else "left")
    ax.plot([], [], "ko", label="true: the final design in the fine ACF model")
    ax.plot([], [], "ko", mfc="none", label="the optimizing model's own value")
    ax.set_xscale("log")
    ax.set_xlabel("optimization wall time [s] (2 ranks)")
    ax.set_ylabel("mean strain energy over a revolution [J]")
    ax.set_title("slider-crank rod: model fidelity against cost\n(uniform start, fine ACF: "
                 f"{report['uniform_true_objective']:.4g} J)", fontsize=11)
    walls = [r["wall_s"] for r in report["variants"].values()]
    ax.set_xlim(min(walls) / 1.9, max(walls) * 3)
    ax.legend(fontsize=9, loc="upper center")
    fig.tight_layout()
    fig.savefig(args.figure, dpi=120)
    print(f"wrote {args.figure}")
