#!/usr/bin/python3
"""Runs cases/slider_crank_start (the flexible slider-crank as a user writes it first) to its
end for every combination of the rod's joints (spherical, revolute about z), the rod's model
(ffrf, acf), the step h and rho_inf, and tabulates what each run did: whether it reached
t = 0.1 s, Newton iterations and factorizations per step, the largest step halving, the
constraint violation, the mid-chord deflection of the rod at 0.1 s and its amplitude, the
integration time. The case README quotes the table.

usage: study_slider_crank_start.py --flexopt BIN --out DIR [--models ffrf acf]
       [--steps 5e-5 1e-5] [--rho 0.8 0.9 1.0] [--joints spherical revolute] [--end 0.1]"""
import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
from case_variants import chord_deflection, run_variant  # noqa: E402
from check_slider_crank_start import CASE, MODELS, REVOLUTE  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--flexopt", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--models", nargs="+", default=["ffrf", "acf"])
    ap.add_argument("--steps", nargs="+", type=float, default=[5e-5, 1e-5])
    ap.add_argument("--rho", nargs="+", type=float, default=[0.8, 0.9, 1.0])
    ap.add_argument("--joints", nargs="+", default=["spherical", "revolute"])
    ap.add_argument("--end", type=float, default=0.1)
    a = ap.parse_args()
    rows = []
    results = os.path.join(a.out, "results.json")
    if os.path.exists(results):
        rows = json.load(open(results))
    done = {(r["joint"], r["model"], r["h"], r["rho_inf"]) for r in rows}
    for joint in a.joints:
        for model in a.models:
            for h in a.steps:
                for rho in a.rho:
                    if (joint, model, h, rho) in done:
                        continue
                    repl = ([] if joint == "spherical" else REVOLUTE) + MODELS[model] + [
                        ("time: {end: 0.1, step: 5.0e-5, rho_inf: 0.9}",
                         f"time: {{end: {a.end}, step: {h}, rho_inf: {rho}}}")]
                    name = f"{joint}_{model}_h{h:g}_rho{rho:g}"
                    try:
                        s = run_variant(a.flexopt, CASE, a.out, name, repl)
                    except SystemExit as e:  # the run failed: record its message
                        log = os.path.join(a.out, name, "failure.txt")
                        with open(log, "w") as f:
                            f.write(str(e))
                        rows.append({"joint": joint, "model": model, "h": h, "rho_inf": rho,
                                     "failed": str(e)[:400]})
                        json.dump(rows, open(results, "w"), indent=1)
                        print(json.dumps(rows[-1]), flush=True)
                        continue
                    q = chord_deflection(s)
                    steps = s["steps"]
                    row = {"joint": joint, "model": model, "h": h, "rho_inf": rho,
                           "t_end": s["output_times"][-1],
                           "newton_per_step": s["newton_iterations_total"] / steps,
                           "newton_max": s["newton_iterations_max"],
                           "factorizations_per_step": s["newton_factorizations_total"] / steps,
                           "halvings_max": s["step_halvings_max"],
                           "violation": s["constraint_violation_max"],
                           "q1_end": q[-1], "q1_amplitude": max(abs(v) for v in q),
                           "integration_s": s["integration_s"]}
                    rows.append(row)
                    json.dump(rows, open(results, "w"), indent=1)
                    print(json.dumps(row), flush=True)
    print("| joints | rod | h | rho_inf | t reached | Newton/step (max) | factorizations/step "
          "| halvings | violation | q1(end) [m] | max abs q1 [m] | integration [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "failed" in r:
            print(f"| {r['joint']} | {r['model']} | {r['h']:g} | {r['rho_inf']:g} | failed | | | | | "
                  f"| | |")
            continue
        print(f"| {r['joint']} | {r['model']} | {r['h']:g} | {r['rho_inf']:g} | {r['t_end']:g} | "
              f"{r['newton_per_step']:.2f} ({r['newton_max']}) | "
              f"{r['factorizations_per_step']:.3f} | {r['halvings_max']} | {r['violation']:.1e} | "
              f"{r['q1_end']:.4e} | {r['q1_amplitude']:.4e} | {r['integration_s']:.1f} |")


if __name__ == "__main__":
    main()
