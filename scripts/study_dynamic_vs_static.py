#!/usr/bin/python3
"""Study 1 of issue 21: the slider-crank rod designed for its dynamics against the rod designed
for an equivalent static load case, both evaluated in the dynamic scene.

  1. dynamic design: `flexopt optimize cases/slider_crank_topopt` (time-averaged strain energy of
     the FFRF rod over one revolution at 150 rad/s, volume fraction <= 0.5);
  2. the rigid mechanism: the same scene with the rod `model: rigid` and the start design's
     densities (its mass and inertia follow them), two revolutions, with sensors for the rod's
     angle, the position of its pin A and the wrist pin's reaction; accelerations by central
     differences over the output steps of the second revolution (the first holds the index-3
     multipliers' start-up oscillation);
  3. the equivalent static load case at every one of N instants of that revolution, in the rod's
     own axes: pin A clamped (the crank pin), the wrist pin's force on the rod as a total force on
     pin B, and the rod's d'Alembert body force (loads.inertia: the acceleration of pin A, the
     rod's spin and angular acceleration; scaled by the design's mass interpolation). The rod's
     compliance at the start design under each; the instant with the largest is "the peak";
  4. static design: compliance under the peak instant's loads at the same volume fraction, with
     the dynamic case's design field (region, filter, projection, optimizer);
  5. both final designs, and the uniform start, in the dynamic scene
     (`flexopt simulate cases/slider_crank_topopt --design .../restart.h5`): the dynamic
     objective, the volume fraction, and the rod's elastic mid-span deflection over the
     revolution.

Writes OUT/study.json, and with --figure a PNG (the ESL sweep, the mid-span deflection of the
three designs, the two designs). docs/benchmarks.md "Dynamic against static design" holds the
figures of a run; its study.json is docs/figures/study_dynamic_vs_static.json.

usage: study_dynamic_vs_static.py --flexopt BUILD/flexopt --out DIR [--ranks 2]
       [--iterations 100] [--instants 24] [--figure docs/figures/study_dynamic_vs_static.png]
"""
import argparse
import csv
import json
import math
import os
import sys

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from study_run import run_flexopt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CASE = os.path.join(ROOT, "cases", "slider_crank_topopt")

p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
p.add_argument("--flexopt", required=True)
p.add_argument("--out", required=True)
p.add_argument("--ranks", type=int, default=2)
p.add_argument("--iterations", type=int, default=None, help="optimizer iterations (default: the case's)")
p.add_argument("--instants", type=int, default=24, help="ESL candidate instants over one revolution")
p.add_argument("--figure", default=None)
args = p.parse_args()
flexopt = os.path.abspath(args.flexopt)
out = os.path.abspath(args.out)
os.makedirs(out, exist_ok=True)


def run(cmd_args, log):
    return run_flexopt(flexopt, args.ranks, cmd_args, log)


def absolute_paths(case):
    for b in case["bodies"]:
        b["geometry"] = os.path.normpath(os.path.join(CASE, b["geometry"]))
    return case


def write_case(case, directory):
    os.makedirs(directory, exist_ok=True)
    with open(os.path.join(directory, "case.yaml"), "w") as f:
        f.write("# written by scripts/study_dynamic_vs_static.py\n")
        yaml.safe_dump(case, f, default_flow_style=None, sort_keys=False, width=100)
    return directory


base = absolute_paths(yaml.safe_load(open(os.path.join(CASE, "case.yaml"))))
rod = next(b for b in base["bodies"] if b["name"] == "rod")
steel = base["materials"][rod["material"]]
opt_args = [] if args.iterations is None else ["--max-iterations", str(args.iterations)]
report = {"case": "cases/slider_crank_topopt", "ranks": args.ranks}

# 1. The dynamic design.
dyn_dir = os.path.join(out, "dynamic")
report["dynamic_optimize_s"] = run(["optimize", CASE, "--out", dyn_dir] + opt_args,
                                   os.path.join(out, "dynamic.log"))

# 2. The rigid mechanism with the start design's densities.
rigid = absolute_paths(yaml.safe_load(open(os.path.join(CASE, "case.yaml"))))
for b in rigid["bodies"]:
    if b["name"] == "rod":
        b["model"] = "rigid"
        for k in ("reduction", "damping"):
            b.pop(k, None)
period = 2 * math.pi / 150.0
step = float(base["time"]["step"])
every = 4
rigid["time"]["end"] = 2 * period
rigid["sensors"] = [
    {"name": "rod_angle", "body": "rod", "point": [0, 0, 0], "quantity": "rotation_angle"},
    {"name": "pin_a", "body": "rod", "point": [0, 0, 0], "quantity": "position"},
    {"name": "wrist", "joint": "wrist_pin"},  # the wrist pin's force on the slider
]
rigid["objective"] = {"type": "mass", "body": "rod"}
rigid["constraints"] = [{"type": "volume_fraction", "max": 0.5}]
rigid["output"] = {"every": every}
run(["simulate", write_case(rigid, os.path.join(out, "rigid")), "--out", os.path.join(out, "rigid", "out")],
    os.path.join(out, "rigid.log"))
s = json.load(open(os.path.join(out, "rigid", "out", "summary.json")))
report["rod_mass_start_kg"] = s["responses"]["objective"]
t = np.array(s["sensors"]["pin_a"]["t"])
phi = np.array(s["sensors"]["rod_angle"]["value"])[:, 2]
pa = np.array(s["sensors"]["pin_a"]["value"])
f_rod = -np.array(s["sensors"]["wrist"]["value"])  # the wrist pin's force on the rod
dt = every * step
if len(t) > 2 and not math.isclose(t[-1] - t[-2], dt, rel_tol=1e-6):  # the final step's frame
    t, phi, pa, f_rod = t[:-1], phi[:-1], pa[:-1], f_rod[:-1]
assert np.allclose(np.diff(t), dt, rtol=1e-6), "rigid run: evenly spaced outputs expected"
k = np.arange(1, len(t) - 1)
omega = (phi[k + 1] - phi[k - 1]) / (2 * dt)
alpha = (phi[k + 1] - 2 * phi[k] + phi[k - 1]) / dt**2
acc = (pa[k + 1] - 2 * pa[k] + pa[k - 1]) / dt**2
crank = (150.0 * t[k]) % (2 * math.pi)
second = t[k] >= period - 0.5 * dt


def body_axes(v, angle):  # world vector -> the rod's axes (rotated by angle about z)
    c, s_ = math.cos(angle), math.sin(angle)
    return [c * v[0] + s_ * v[1], -s_ * v[0] + c * v[1], v[2]]


# 3. The equivalent static load cases.
def static_case(i):
    j = k[i]
    return {
        "analysis": "static",
        "materials": {"steel": steel},
        "bodies": [{"name": "rod", "geometry": rod["geometry"], "mesh": rod["mesh"], "material": "steel"}],
        "supports": [{"body": "rod", "surface": "pin_a", "fix": ["x", "y", "z"]}],
        "tractions": [{"body": "rod", "surface": "pin_b", "force": [float(v) for v in body_axes(f_rod[j], phi[j])]}],
        "loads": {"inertia": {"point": [0.0, 0.0, 0.0],
                              "acceleration": [float(v) for v in body_axes(acc[i], phi[j])],
                              "angular_velocity": [0.0, 0.0, float(omega[i])],
                              "angular_acceleration": [0.0, 0.0, float(alpha[i])]}},
        "design": base["design"],
        "objective": {"type": "compliance"},
        "constraints": [{"type": "volume_fraction", "max": 0.5}],
        "optimizer": base["optimizer"],
        "output": {"every": 10},
        "solver": "-ksp_type preonly -pc_type lu -pc_factor_mat_solver_type mumps",
    }


candidates = np.flatnonzero(second)
picks = candidates[np.linspace(0, len(candidates) - 1, args.instants, endpoint=False).round().astype(int)]
sweep = []
for n, i in enumerate(picks):
    d = write_case(static_case(i), os.path.join(out, "esl", f"instant_{n:02d}"))
    run(["optimize", d, "--out", os.path.join(d, "out"), "--max-iterations", "1"], os.path.join(d, "log"))
    with open(os.path.join(d, "out", "history.csv")) as f:
        c0 = float(next(csv.DictReader(f))["objective"])
    sweep.append({"t": float(t[k[i]]), "crank_deg": math.degrees(crank[i]), "compliance": c0,
                  "pin_b_force_body": body_axes(f_rod[k[i]], phi[k[i]]),
                  "acceleration_pin_a_body": body_axes(acc[i], phi[k[i]]),
                  "omega": float(omega[i]), "alpha": float(alpha[i])})
    print(f"ESL at crank {sweep[-1]['crank_deg']:6.1f} deg: compliance {c0:.6g} J", flush=True)
peak = max(range(len(sweep)), key=lambda n: sweep[n]["compliance"])
report["esl_sweep"] = sweep
report["esl_peak"] = sweep[peak]
print(f"peak: crank {sweep[peak]['crank_deg']:.1f} deg", flush=True)

# 4. The static design.
static_dir = write_case(static_case(picks[peak]), os.path.join(out, "static"))
report["static_optimize_s"] = run(["optimize", static_dir, "--out", os.path.join(static_dir, "out")] + opt_args,
                                  os.path.join(out, "static.log"))
sj = json.load(open(os.path.join(static_dir, "out", "summary.json")))
report["static_compliance"] = {"start": sj["objective"][0], "final": sj["objective"][-1]}


# 5. All designs in the dynamic scene.
def evaluate(name, design):
    d = os.path.join(out, "eval_" + name)
    extra = [] if design is None else ["--design", design]
    run(["simulate", CASE, "--out", d] + extra, os.path.join(out, f"eval_{name}.log"))
    e = json.load(open(os.path.join(d, "summary.json")))
    mid = np.array(e["sensors"]["mid_elastic"]["value"])[:, 1]
    return {"objective": e["responses"]["objective"], "volume_fraction": e["responses"]["constraint0"],
            "mid_elastic_y_max_abs": float(np.abs(mid).max()),
            "t": e["sensors"]["mid_elastic"]["t"], "mid_elastic_y": mid.tolist()}


designs = {"uniform": None, "static": os.path.join(static_dir, "out", "restart.h5"),
           "dynamic": os.path.join(dyn_dir, "restart.h5")}
report["evaluation"] = {name: evaluate(name, f) for name, f in designs.items()}
ev = report["evaluation"]
for name in designs:
    print(f"{name:8s} dynamic objective {ev[name]['objective']:.6g} J  volume fraction "
          f"{ev[name]['volume_fraction']:.5f}  max |mid-span elastic y| {ev[name]['mid_elastic_y_max_abs']:.4g} m")
report["static_over_dynamic"] = ev["static"]["objective"] / ev["dynamic"]["objective"]
print(f"the static design's dynamic objective is {report['static_over_dynamic']:.3f} x the dynamic design's")
with open(os.path.join(out, "study.json"), "w") as f:
    json.dump(report, f, indent=1)
print(f"wrote {os.path.join(out, 'study.json')}")

if args.figure:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sys.path.insert(0, os.path.join(ROOT, "scripts"))
    import plot_design

    fig = plt.figure(figsize=(11, 8))
    ax = fig.add_subplot(2, 2, 1)
    ax.plot([s_["crank_deg"] for s_ in sweep], [s_["compliance"] for s_ in sweep], "o-")
    ax.plot([sweep[peak]["crank_deg"]], [sweep[peak]["compliance"]], "r*", ms=14, label="peak: the static load case")
    ax.set_xlabel("crank angle [deg]")
    ax.set_ylabel("compliance at the start design [J]")
    ax.set_title("equivalent static loads of the rigid mechanism")
    ax.legend()
    ax = fig.add_subplot(2, 2, 2)
    for name in designs:
        e = ev[name]
        ax.plot(np.degrees(150.0 * np.array(e["t"])), 1e6 * np.array(e["mid_elastic_y"]),
                label=f"{name}: mean strain energy {e['objective']:.4g} J")
    ax.set_xlabel("crank angle [deg]")
    ax.set_ylabel("rod mid-span elastic deflection y [um]")
    ax.set_title("in the dynamic scene (FFRF, 150 rad/s)")
    ax.legend(fontsize=8)
    for n, (name, title) in enumerate([("static", "static design"), ("dynamic", "dynamic design")]):
        h5 = os.path.join(static_dir, "out", "design.h5") if name == "static" else os.path.join(dyn_dir, "design.h5")
        centroid, rho, _ = plot_design.load(h5)
        img, extent = plot_design.image(centroid, rho, 0.004)
        ax = fig.add_subplot(4, 1, 3 + n)
        ax.imshow(img, origin="lower", extent=extent, cmap="gray_r", vmin=0, vmax=1, aspect="equal")
        ax.set_title(f"{title}: dynamic objective {ev[name]['objective']:.4g} J")
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(args.figure, dpi=110)
    print(f"wrote {args.figure}")
