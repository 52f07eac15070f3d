#!/usr/bin/python3
"""Where each method fails (issue 22): one panel per failure, the data of tests/check_stability.py
and of the unit test GeneralizedAlpha.ScaledNewtonMatrixStaysConditionedAsTheStepShrinks.

Usage: scripts/study_stability.py [--flexopt build/flexopt] [--unit-tests build/tests/unit_tests]
                                  [--out build/study_stability] [--figure docs/figures/stability.png]
       scripts/study_stability.py --replot      # the figure again from OUT/stability.json

Panels (2 ranks; about 5 minutes):
  1. linear FFRF above the first bending frequency: cases/kane_beam's tip deflection, FFRF with 4
     modes, linear and stiffened, over 10 s (the spin passes w1 = 3.8 rad/s at t = 8.5 s);
  2. FFRF at large elastic rotation: cases/flexible_pendulum with E = 1e8 Pa (the plan's elastic
     rotation 0.26 rad), the tip deflection of stiffened FFRF (8 modes) and of ACF (0.05 m mesh),
     1 s at 1 ms;
  3. ACF at rho_inf = 1: the ACF slider-crank rod (8 mm Tet10), mean Newton iterations per step
     over the first 10 steps against the step, at rho_inf = 0.8 and 1;
  4. the index-3 scheme as h -> 0: the condition number of the step's Newton matrix, unscaled and
     scaled (section 6.4), on a moving double pendulum (the unit test's table).
"""
import argparse
import json
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from case_variants import write_case  # noqa: E402
from stability_scenes import acf_slider_crank, as_acf, kane_ffrf, soft_pendulum  # noqa: E402
from study_run import run_flexopt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def simulate(a, c, name):
    d = write_case(c, os.path.join(a.out, name))
    run_flexopt(a.flexopt, 2, ["simulate", d, "--out", os.path.join(d, "out")], os.path.join(d, "log.txt"))
    return json.load(open(os.path.join(d, "out", "summary.json")))


def tip(s):
    t = s["sensors"]["tip_elastic"]["t"]
    return t, [v[1] for v in s["sensors"]["tip_elastic"]["value"]]


def linear_spin(a):
    return {("stiffened" if stiff else "linear"):
            tip(simulate(a, kane_ffrf(4, stiff), f"kane_{'stiff' if stiff else 'linear'}"))
            for stiff in (False, True)}


def large_rotation(a):
    c = soft_pendulum()
    out = {"ffrf": tip(simulate(a, c, "soft_pendulum_ffrf"))}
    as_acf(c["bodies"][0])
    out["acf"] = tip(simulate(a, c, "soft_pendulum_acf"))
    return out


def acf_rho1(a):
    out = {}
    for rho in (0.8, 1.0):
        rows = []
        for h in (1.25e-5, 2.5e-5, 5e-5, 1e-4):
            s = simulate(a, acf_slider_crank(h, rho), f"slider_crank_acf_h{h:g}_rho{rho:g}")
            rows.append((h, s["newton_iterations_total"] / 10, s["integration_s"]))
        out[str(rho)] = rows
    return out


def index3(a):
    r = subprocess.run([a.unit_tests, "--gtest_filter=GeneralizedAlpha.ScaledNewtonMatrixStaysConditionedAsTheStepShrinks"],
                       capture_output=True, text=True)
    rows = [tuple(float(x) for x in m) for m in
            re.findall(r"index3 h= (\S+) scaled= (\S+) unscaled= (\S+)", r.stdout)]
    if not rows:
        sys.exit("study_stability: the unit test printed no table:\n" + r.stdout[-2000:])
    return rows


def figure(data, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(13, 9))
    p = ax[0, 0]
    for k, color in (("linear", "C1"), ("stiffened", "C0")):
        t, y = data["linear_spin"][k]
        p.plot(t, y, color=color, label=f"FFRF {k}, 4 modes")
    p.axvline(8.5, color="grey", linestyle=":", linewidth=1)
    p.annotate("spin passes w1", (8.5, 0), fontsize=8, color="grey", xytext=(4, 10), textcoords="offset points")
    p.set_ylim(-3, 1)
    p.set_xlabel("t [s]")
    p.set_ylabel("tip deflection y in the hub frame [m]")
    p.set_title("1. kane_beam (6 rad/s): linear FFRF above the first bending frequency diverges", fontsize=9)
    p.legend(fontsize=8)
    p = ax[0, 1]
    for k, color, label in (("ffrf", "C0", "FFRF stiffened, 8 modes"), ("acf", "C3", "ACF, 0.05 m Tet10")):
        t, y = data["large_rotation"][k]
        p.plot(t, y, color=color, label=label)
    p.set_xlabel("t [s]")
    p.set_ylabel("tip deflection y in the pin frame [m]")
    p.set_title("2. flexible_pendulum with E = 1e8 Pa: FFRF at elastic rotations of 0.26 rad", fontsize=9)
    p.legend(fontsize=8)
    p = ax[1, 0]
    for rho, color in (("0.8", "C0"), ("1.0", "C3")):
        rows = data["acf_rho1"][rho]
        p.plot([r[0] for r in rows], [r[1] for r in rows], marker="o", color=color, label=f"ρ∞ = {rho}")
    p.set_xscale("log")
    p.set_yscale("log")
    p.set_xlabel("time step h [s]")
    p.set_ylabel("Newton iterations per step (first 10 steps)")
    p.set_title("3. ACF slider-crank rod (8 mm Tet10, highest frequency < 3.6 MHz): ρ∞ = 1", fontsize=9)
    p.legend(fontsize=8)
    p.grid(True, which="both", alpha=0.3)
    p = ax[1, 1]
    rows = data["index3"]
    p.plot([r[0] for r in rows], [r[2] for r in rows], marker="s", color="C1", label="unscaled [β′M + γ′C + K, Jᵀ; J, 0]")
    p.plot([r[0] for r in rows], [r[1] for r in rows], marker="o", color="C0", label="scaled (section 6.4)")
    p.axhline(1 / 2.2e-16, color="grey", linestyle=":", linewidth=1)
    p.annotate("1 / machine ε", (rows[-1][0], 1 / 2.2e-16), fontsize=8, color="grey", xytext=(2, 4), textcoords="offset points")
    p.set_xscale("log")
    p.set_yscale("log")
    p.invert_xaxis()
    p.set_xlabel("time step h [s]")
    p.set_ylabel("condition number of the Newton matrix (2-norm)")
    p.set_title("4. index-3 generalized-α as h → 0: double pendulum", fontsize=9)
    p.legend(fontsize=8)
    p.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"figure: {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--flexopt", default=os.path.join(ROOT, "build", "flexopt"))
    ap.add_argument("--unit-tests", default=os.path.join(ROOT, "build", "tests", "unit_tests"))
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "study_stability"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "stability.png"))
    ap.add_argument("--replot", action="store_true")
    a = ap.parse_args()
    a.flexopt = os.path.abspath(a.flexopt)
    path = os.path.join(a.out, "stability.json")
    if a.replot:
        data = json.load(open(path))
    else:
        os.makedirs(a.out, exist_ok=True)
        data = {"index3": index3(a), "linear_spin": linear_spin(a), "large_rotation": large_rotation(a),
                "acf_rho1": acf_rho1(a)}
        json.dump(data, open(path, "w"))
    for rho, rows in data["acf_rho1"].items():
        for h, it, s in rows:
            print(f"ACF slider-crank rho_inf {rho}: h = {h:g} s: {it:.1f} Newton iterations per step, {s:.1f} s")
    for h, sc, un in data["index3"]:
        print(f"index-3 h = {h:g}: scaled {sc:.3g}, unscaled {un:.3g}")
    figure(data, a.figure)


if __name__ == "__main__":
    main()
