#!/usr/bin/python3
"""The speed-accuracy map of issue 22: sensor error against wall time for every body model on
four scenes of cases/, with `model: auto`'s choice marked.

Usage: scripts/study_speed_accuracy.py [--flexopt build/flexopt] [--out build/study_speed_accuracy]
                                       [--scenes kane_beam,...] [--quick] [--figure PNG]
       scripts/study_speed_accuracy.py --replot       # table and figure from OUT/results.json

Scenes (SCENES below; each one body whose model the study varies, the other bodies as the case
has them), each with a fine reference and one observable y(t):

  flexible_pendulum      the bar's tip deflection in the pin frame (sensor tip_elastic, y) over
                         0.5 s; reference: the geometrically exact beam of
                         scripts/reference/flexible_pendulum.csv (docs/reference-flexible-pendulum.md);
  slider_crank_flexible  the rod's mid-point distance from its chord, q1(t) (position sensors
                         end_a, end_b, mid); reference: the rod as an ACF body on a 4 mm Tet10
                         mesh (the 3D solid with no small-deformation assumption) at the case's
                         step; ACF at 24, 16 and 8 mm;
  kane_beam              the beam's tip deflection in the hub frame over 10 s (6 rad/s, above
                         the first bending frequency); reference: ACF on a 0.1 m mesh;
  spin_up_beam           the same at 4 rad/s over 10 s; reference: the geometrically exact beam
                         of scripts/reference/spin_up_beam_omega4.csv.

Runs per scene, each `flexopt simulate` on 2 ranks at every time step of the scene's `steps`
and every value of its `rho_inf`: the body rigid; FFRF from the scene's FFRF mesh with 2, 4, 8,
16 and 40 fixed-interface modes (and the number `auto` picks), linear and with geometric
stiffening (in the frame clamped at the first interface: the slider-crank rod's chord frame does not
combine with stiffening); ACF at three mesh sizes. Then `flexopt plan --auto` at the scene's first step and
ρ∞ (the pick, its reasons, its predicted cost) and `simulate` with the body's model `auto` (the
pick's point on the chart, its cost including the plan's).

Error of a run: max over the reference's samples t in [0, end] of |y(t) - y_ref(t)| divided by
max |y_ref| (the run interpolated linearly onto the reference's times). A run that fails (the
Newton iteration diverges, say) is recorded with flexopt's error line and drawn at the top of
its chart. Costs: the wall time measured around mpirun (MPI start-up, meshing, reduction,
integration, output), summary.json's `integration_s` and `wall_s`; "other load" is the CPU time
other processes used during the run, in cores (from /proc/stat): runs with >= 0.5 core of other
load are drawn with open markers.

Every finished run is kept in OUT/SCENE/RUN/row.json and not run again (delete the directory to
redo it, or --retime 0.5 to run again those timed with half a core or more of other load);
OUT/results.json and OUT/results.csv gather them. --quick: a smoke run of the script
(end times cut to a tenth, one step, one ρ∞, FFRF 2 and 8 modes, the coarsest ACF mesh).
"""
import argparse
import csv
import json
import os
import re
import resource
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from case_variants import case_dict, chord_deflection, write_case  # noqa: E402
from study_run import ENV  # noqa: E402
import mpi_job  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LOADED = 0.5  # other load [cores] from which a run counts as timed on a busy machine
# A run still going after STALL_AFTER seconds whose progress line shows more than STALL_ITERATIONS
# Newton iterations per step on average is stopped and recorded as failed (Newton stalls: ~90
# per step on the ACF slider-crank at rho_inf = 1, against 5-7 for a run that is only slow).
STALL_AFTER, STALL_ITERATIONS, HARD_LIMIT = 240, 30, 1200
MODES = [2, 4, 8, 16, 40]

# body: the body whose model varies; ffrf_mesh: the mesh FFRF reduces from ({size, order});
# acf_meshes: three mesh sizes (order 2); steps, rho_inf: the time grids (the first of each is the
# one the plan and auto run at); reference: a CSV column or a run {model, mesh, step}.
SCENES = {
    "flexible_pendulum": dict(
        body="bar", end=0.5, observable=("sensor", "tip_elastic", 1),
        ffrf_mesh=0.01, acf_meshes=[0.05, 0.03, 0.02], steps=[1e-4, 4e-4], rho_inf=[0.9, 1.0],
        reference=dict(csv="scripts/reference/flexible_pendulum.csv", t="t_s", y="v_transverse_m",
                       what="geometrically exact beam (512 elements, dt 2.5e-5 s)")),
    "slider_crank_flexible": dict(
        body="rod", end=0.1, observable=("chord", ("end_a", "end_b", "mid")),
        ffrf_mesh=0.004, acf_meshes=[0.024, 0.016, 0.008], steps=[1e-5, 2e-5],
        rho_inf=[0.8, 1.0],
        reference=dict(model="acf", mesh=0.004, step=1e-5, rho_inf=0.8,
                       what="ACF rod, 4 mm Tet10 mesh, dt 1e-5 s")),
    "kane_beam": dict(
        body="beam", end=10.0, observable=("sensor", "tip_elastic", 1),
        ffrf_mesh=0.2, acf_meshes=[0.4, 0.3, 0.2], steps=[2e-3, 4e-3], rho_inf=[0.9, 1.0],
        reference=dict(model="acf", mesh=0.1, step=2e-3, rho_inf=0.9,
                       what="ACF beam, 0.1 m Tet10 mesh (12.9k DOFs), dt 2e-3 s")),
    "spin_up_beam": dict(
        body="beam", end=10.0, observable=("sensor", "tip_elastic", 1),
        ffrf_mesh=0.1, acf_meshes=[0.4, 0.3, 0.2], steps=[2e-3, 4e-3], rho_inf=[0.9, 1.0],
        reference=dict(csv="scripts/reference/spin_up_beam_omega4.csv", t="t_s",
                       y="tip_deflection_m", what="geometrically exact beam (80 elements)")),
}


def busy_seconds():
    """CPU seconds the machine has spent busy since boot (all cores, /proc/stat)."""
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    return (sum(v[:8]) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")


def children_seconds():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def variant(scene, name, model, mesh=None, modes=None, stiff=None, step=None, rho=None, end=None):
    """The case of SCENE as a simulate-only case dict with the scene body's model (rigid, ffrf,
    acf or auto), mesh size, reduction and the time grid set."""
    c = case_dict(os.path.join(ROOT, "cases", scene))
    b = next(b for b in c["bodies"] if b["name"] == SCENES[scene]["body"])
    b["model"] = model
    if mesh is not None:
        b["mesh"] = dict(b.get("mesh", {}), size=mesh, order=2)
    if model == "ffrf":
        b["reduction"] = dict(b.get("reduction", {}), modes=modes, geometric_stiffening=stiff)
        if stiff and b["reduction"].get("frame") == "chord":
            # The centrifugal preload is that of the body clamped at its first interface: a
            # stiffened body takes the clamped frame (slider_crank_flexible's rod).
            del b["reduction"]["frame"]
    elif model != "auto":
        b.pop("reduction", None)
    if model == "rigid":
        # A rigid body carries no elastic fields (slider_crank_flexible starts its rod deformed).
        init = b.get("initial", {})
        for k in ("elastic_displacement", "elastic_velocity"):
            init.pop(k, None)
    c["time"] = dict(c["time"], end=end, step=step, rho_inf=rho)
    return c


def observe(scene, summary):
    """(t, y) of the scene's observable in a run's summary."""
    kind = SCENES[scene]["observable"]
    if kind[0] == "sensor":
        s = summary["sensors"][kind[1]]
        y = [np.nan if v is None or v[kind[2]] is None else v[kind[2]] for v in s["value"]]
        return np.array(s["t"], float), np.array(y, float)
    ends = kind[1]
    t = summary["sensors"][ends[2]]["t"]
    return np.array(t, float), np.array(chord_deflection(summary, ends[:2], ends[2]), float)


def run(args, scene, name, c, command="simulate"):
    """Runs `flexopt COMMAND` on case dict C in OUT/SCENE/NAME (or returns the kept row) and
    returns the row: costs, and t, y of the observable (or the failure)."""
    d = os.path.join(args.out, scene, name)
    kept = os.path.join(d, "row.json")
    if os.path.exists(kept):
        row = json.load(open(kept))
        if args.retime is None or row["other_load_cores"] < args.retime or row["failed"]:
            return row
    write_case(c, d)
    out = os.path.join(d, "out")
    cmd = ["mpirun", "-n", "2", args.flexopt, command, d, "--out", out]
    if command == "plan":
        cmd.append("--auto")
    print(f"[{time.strftime('%H:%M:%S')}] {scene}/{name}: " + " ".join(cmd[3:5]), flush=True)
    b0, c0, t0 = busy_seconds(), children_seconds(), time.monotonic()
    log = os.path.join(d, "log.txt")
    stalled = None
    with open(log, "w") as f:
        proc = mpi_job.start(cmd, stdout=f, stderr=subprocess.STDOUT, env=ENV)
        while True:
            try:
                proc.wait(timeout=5)
                break
            except subprocess.TimeoutExpired:
                pass
            waited = time.monotonic() - t0
            if waited < STALL_AFTER:
                continue
            lines = [l for l in open(log) if "Newton" in l and "/step" in l]
            per_step = float(re.search(r"Newton ([0-9.]+)/step", lines[-1]).group(1)) if lines else 0
            if per_step > STALL_ITERATIONS or waited > HARD_LIMIT:
                stalled = lines[-1].strip() if lines else "no progress line"
                mpi_job.kill_session(proc.pid, grace=10)  # mpirun and every rank
                proc.wait()
        rc = None if stalled else proc.returncode
    wall = time.monotonic() - t0
    other = max(0.0, busy_seconds() - b0 - (children_seconds() - c0)) / wall
    row = {"scene": scene, "name": name, "measured_wall_s": wall, "other_load_cores": other,
           "time": c["time"]}
    if rc is None:
        row.update(failed=True, error=f"stopped after {wall:.0f} s: {stalled}")
        print(f"    {row['error']}", flush=True)
    elif rc != 0:
        errs = [l.strip() for l in open(os.path.join(d, "log.txt")) if "error" in l.lower()]
        row.update(failed=True, error=errs[0] if errs else f"exit {rc}")
        print(f"    failed: {row['error']}", flush=True)
    else:
        s = json.load(open(os.path.join(out, "summary.json")))
        row.update(failed=False, flexopt_wall_s=s.get("wall_s"), integration_s=s.get("integration_s"),
                   newton_iterations=s.get("newton_iterations_total"))
        if command == "plan":
            row["plan"] = s["plan"]
            row["plan_s"] = s.get("plan_s")
        else:
            t, y = observe(scene, s)
            row.update(t=t.tolist(), y=[None if not np.isfinite(v) else float(v) for v in y])
            row["dofs"] = next(b.get("dofs") for b in s["bodies"] if b["name"] == SCENES[scene]["body"])
            if "plan" in s:
                row["plan"] = s["plan"]
        print(f"    {wall:.1f} s (other load {other:.2f} cores)", flush=True)
    with open(kept, "w") as f:
        json.dump(row, f)
    return row


def reference(args, scene):
    """(t, y, description) of the scene's reference, cut to [0, end]."""
    sc = SCENES[scene]
    ref = sc["reference"]
    end = sc["end"] / (10 if args.quick else 1)
    if "csv" in ref:
        data = np.genfromtxt(os.path.join(ROOT, ref["csv"]), delimiter=",", names=True)
        t, y = data[ref["t"]], data[ref["y"]]
        row = {"scene": scene, "name": "reference", "what": ref["what"], "failed": False}
    else:
        model = ref["model"] if not args.quick else "acf"
        mesh = ref["mesh"] if not args.quick else sc["acf_meshes"][-1]
        c = variant(scene, "reference", model, mesh=mesh, step=ref["step"], rho=ref["rho_inf"], end=end)
        row = dict(run(args, scene, "reference", c), what=ref["what"])
        if row["failed"]:
            sys.exit(f"the reference of {scene} failed: {row['error']}")
        t, y = np.array(row["t"]), np.array(row["y"], float)
    keep = t <= end * (1 + 1e-9)
    return t[keep], y[keep], row


def error(row, t_ref, y_ref):
    """Adds max_t |y - y_ref| / max |y_ref| to a run's row (None where it failed or is not
    finite over the reference's time span)."""
    if row["failed"]:
        row["max_error"] = None
        return
    t, y = np.array(row["t"]), np.array([np.nan if v is None else v for v in row["y"]], float)
    if not np.all(np.isfinite(y)) or t[-1] < t_ref[-1] * (1 - 1e-9):
        row["max_error"] = None
        return
    row["max_error"] = float(np.max(np.abs(np.interp(t_ref, t, y) - y_ref)) / np.max(np.abs(y_ref)))


def runs_of(args, scene):
    """The scene's runs as (name, model, mesh, modes, stiffening, step, rho)."""
    sc = SCENES[scene]
    steps, rhos = sc["steps"], sc["rho_inf"]
    modes, meshes = MODES, sc["acf_meshes"]
    if args.quick:
        steps, rhos, modes, meshes = steps[:1], rhos[:1], [2, 8], meshes[:1]
    out = []
    for h in steps:
        for rho in rhos:
            tag = f"h{h:g}_r{rho:g}"
            out.append((f"rigid_{tag}", "rigid", None, None, None, h, rho))
            for stiff in (False, True):
                for n in modes:
                    out.append((f"ffrf{'s' if stiff else 'l'}{n}_{tag}", "ffrf", sc["ffrf_mesh"], n,
                                stiff, h, rho))
            for m in meshes:
                out.append((f"acf{m:g}_{tag}", "acf", m, None, None, h, rho))
    return out


def study_scene(args, scene):
    sc = SCENES[scene]
    end = sc["end"] / (10 if args.quick else 1)
    t_ref, y_ref, ref = reference(args, scene)
    rows = []
    # The plan and auto's run, at the scene's first step and rho_inf.
    h0, r0 = sc["steps"][0], sc["rho_inf"][0]
    c = variant(scene, "auto", "auto", step=h0, rho=r0, end=end)
    plan = run(args, scene, "plan", c, command="plan")
    pick = None
    if not plan["failed"]:
        pick = next(p for p in plan["plan"] if p["body"] == sc["body"])
    auto = run(args, scene, "auto", c)
    auto.update(model="auto", step=h0, rho_inf=r0, pick=pick, plan_s=plan.get("plan_s"))
    rows.append(auto)
    planned = list(runs_of(args, scene))
    if pick and pick["model"] == "ffrf" and pick["modes"] not in MODES:
        stiff = bool(pick["geometric_stiffening"])
        planned.append((f"ffrf{'s' if stiff else 'l'}{pick['modes']}_h{h0:g}_r{r0:g}", "ffrf",
                        sc["ffrf_mesh"], pick["modes"], stiff, h0, r0))
    for name, model, mesh, modes, stiff, h, rho in planned:
        row = run(args, scene, name, variant(scene, name, model, mesh, modes, stiff, h, rho, end))
        row.update(model=model, mesh=mesh, modes=modes, stiffening=stiff, step=h, rho_inf=rho)
        rows.append(row)
    for row in rows:
        error(row, t_ref, y_ref)
    # Which run auto's pick is (its model at the first step and rho_inf).
    if pick:
        for row in rows:
            same = (row.get("model") == pick["model"] and row["step"] == h0 and row["rho_inf"] == r0
                    and (pick["model"] != "ffrf" or (row["modes"] == pick["modes"] and
                                                     row["stiffening"] == bool(pick["geometric_stiffening"]))))
            if same and row["model"] != "acf":
                row["is_pick"] = True
    ref_row = {k: v for k, v in ref.items() if k not in ("t", "y")}
    return {"scene": scene, "end": end, "reference": ref_row, "accuracy": 1e-2, "rows": rows,
            "scale": float(np.max(np.abs(y_ref)))}


def label(r):
    if r["model"] == "auto":
        p = r.get("pick") or {}
        return "auto → " + describe(p.get("model"), p.get("modes"), p.get("geometric_stiffening"))
    return describe(r["model"], r.get("modes"), r.get("stiffening"), r.get("mesh"))


def describe(model, modes=None, stiff=None, mesh=None):
    if model == "ffrf":
        return f"FFRF {'stiffened' if stiff else 'linear'} {modes} modes"
    if model == "acf":
        return f"ACF h = {mesh:g} m" if mesh else "ACF"
    return str(model)


def fmt(v, spec):
    return "—" if v is None else format(v, spec)


def table(result):
    lines = [f"**{result['scene']}** (reference: {result['reference']['what']}; "
             f"max |y_ref| = {result['scale']:.4g})", "",
             "| run | dt [s] | ρ∞ | DOFs | error | measured wall [s] | integration [s] | other load |",
             "|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        err = (f"failed: {r['error']}" if r["failed"] else
               fmt(r.get("max_error"), ".2e") if r.get("max_error") is not None else "not finite")
        mark = " **(auto's pick)**" if r.get("is_pick") else ""
        lines.append(f"| {label(r)}{mark} | {r['step']:g} | {r['rho_inf']:g} | {fmt(r.get('dofs'), ',')} | "
                     f"{err} | {r['measured_wall_s']:.1f} | {fmt(r.get('integration_s'), '.2f')} | "
                     f"{r['other_load_cores']:.2f} |")
    return "\n".join(lines)


# The plan's ACF cost model (docs/theory.md section 12.4, src/plan/plan.cpp).
ACF_ITERATIONS_PER_STEP, ACF_SECONDS_PER_DOF_ITERATION = 4.2, 2.2e-6


def cost_table(results, out):
    """The plan's predicted costs against the measured ones: every ACF run (steps x 4.2 Newton
    iterations x DOFs x 2.2 us / 2 ranks against integration_s, and the measured iterations per
    step and seconds per DOF and iteration) and auto's pick (predicted_cost_s against the run's
    integration_s)."""
    lines = ["| scene | run | DOFs | steps | Newton it./step | predicted [s] | integration [s] | "
             "measured / predicted | µs per DOF and iteration (rank-seconds) | other load |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for res in results:
        for r in res["rows"]:
            if r["failed"] or r.get("integration_s") is None:
                continue
            it = r.get("newton_iterations")
            if it is None:  # rows kept from before the field was recorded
                try:
                    it = json.load(open(os.path.join(out, res["scene"], r["name"], "out", "summary.json")))[
                        "newton_iterations_total"]
                except (OSError, KeyError):
                    it = None
            steps = round(r["time"]["end"] / r["time"]["step"])
            if r["model"] == "acf":
                pred = steps * ACF_ITERATIONS_PER_STEP * r["dofs"] * ACF_SECONDS_PER_DOF_ITERATION / 2
            elif r["model"] == "auto" and r.get("pick"):
                pred = r["pick"]["predicted_cost_s"]
            else:
                continue
            per = 2 * r["integration_s"] / (it * r["dofs"]) * 1e6 if it and r.get("dofs") else None
            lines.append(f"| {res['scene']} | {label(r)}, dt {r['step']:g}, ρ∞ {r['rho_inf']:g} | "
                         f"{fmt(r.get('dofs'), ',')} | {steps:,} | {fmt(it / steps if it else None, '.2f')} | "
                         f"{pred:.3g} | {r['integration_s']:.3g} | {r['integration_s'] / pred:.2f} | "
                         f"{fmt(per, '.2f')} | {r['other_load_cores']:.2f} |")
    return "\n".join(lines)


def figure(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(results)
    cols = 2 if n > 1 else 1
    fig, axes = plt.subplots((n + 1) // 2, cols, figsize=(7 * cols, 5.2 * ((n + 1) // 2)), squeeze=False)
    families = [("rigid", "k", "s"), ("ffrf_linear", "C1", "v"), ("ffrf_stiff", "C0", "o"), ("acf", "C3", "D")]
    for ax, res in zip(axes.flat, results):
        rows = [r for r in res["rows"] if r["model"] != "auto"]
        # A run in the reference's own configuration (auto's ACF pick on the slider-crank) has
        # an error at round-off: drawn at the bottom edge, labelled.
        errs = [r["max_error"] for r in res["rows"] if r.get("max_error") and r["max_error"] > 1e-9]
        top = min(10.0, 3 * max(errs)) if errs else 1.0
        bottom = min(errs) / 3 if errs else 1e-4
        for r in res["rows"]:
            if r.get("max_error") is not None and r["max_error"] <= 1e-9:
                r["max_error"] = bottom * 1.2
                r["at_reference"] = True
        grids = sorted({(r["step"], r["rho_inf"]) for r in rows})
        styles = ["-", "--", ":", "-."]
        for fam, color, marker in families:
            for gi, (h, rho) in enumerate(grids):
                pts = [r for r in rows if (r["step"], r["rho_inf"]) == (h, rho) and
                       (fam == r["model"] or (r["model"] == "ffrf" and fam == ("ffrf_stiff" if r["stiffening"] else "ffrf_linear")))]
                pts.sort(key=lambda r: (-(r.get("mesh") or 0), r.get("modes") or 0))
                if not pts:
                    continue
                ok = [r for r in pts if r.get("max_error") is not None]
                ax.plot([r["measured_wall_s"] for r in ok], [min(r["max_error"], top) for r in ok], color=color,
                        linestyle=styles[gi % 4], linewidth=0.8, marker=marker, markersize=4,
                        markerfacecolor=color if gi % 2 == 0 else "none")
                for r in pts:
                    if r.get("max_error") is None:
                        ax.plot(r["measured_wall_s"], top, marker="x", color=color, markersize=7)
                if fam.startswith("ffrf") and gi == 0:
                    for r in ok:
                        ax.annotate(str(r["modes"]), (r["measured_wall_s"], r["max_error"]), fontsize=6,
                                    color=color, textcoords="offset points", xytext=(3, 2))
                if fam == "acf" and gi == 0:
                    for r in ok:
                        ax.annotate(f"{r['mesh']:g} m", (r["measured_wall_s"], r["max_error"]), fontsize=6,
                                    color=color, textcoords="offset points", xytext=(3, 2))
        for gi, (h, rho) in enumerate(grids):
            ax.plot([], [], color="grey", linestyle=styles[gi % 4], marker="o",
                    markerfacecolor="grey" if gi % 2 == 0 else "none", label=f"dt = {h:g} s, ρ∞ = {rho:g}")
        for fam, color, marker in families:
            ax.plot([], [], color=color, marker=marker, linestyle="none",
                    label={"rigid": "rigid", "ffrf_linear": "FFRF linear (modes)",
                           "ffrf_stiff": "FFRF stiffened (modes)", "acf": "ACF (mesh size)"}[fam])
        for r in res["rows"]:
            if r["model"] == "auto" and r.get("max_error") is not None:
                ax.plot(r["measured_wall_s"], r["max_error"], marker="*", markersize=16, color="gold",
                        markeredgecolor="k", linestyle="none", label=label(r) + " (incl. plan)")
                if r.get("at_reference"):
                    ax.annotate("the reference's configuration\n(error at round-off)",
                                (r["measured_wall_s"], r["max_error"]), fontsize=7, ha="right",
                                textcoords="offset points", xytext=(-8, 6))
            if r.get("other_load_cores", 0) >= LOADED and r.get("max_error") is not None:
                ax.plot(r["measured_wall_s"], min(r["max_error"], top), marker="o", markersize=10,
                        markerfacecolor="none", markeredgecolor="grey", linestyle="none")
            if r.get("is_pick") and r.get("max_error") is not None:
                ax.plot(r["measured_wall_s"], r["max_error"], marker="o", markersize=13, markerfacecolor="none",
                        markeredgecolor="gold", markeredgewidth=2, linestyle="none")
        ax.axhline(res["accuracy"], color="g", linewidth=1, linestyle="-.", label=f"accuracy {res['accuracy']:g}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(bottom, top * 1.5)
        ax.set_xlabel("wall time of the run, measured around mpirun, 2 ranks [s]")
        ax.set_ylabel("max |y − y_ref| / max |y_ref|")
        ax.set_title(f"{res['scene']}: reference {res['reference']['what']}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, loc="best")
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.suptitle("Speed against accuracy (x at the top: the run failed or diverged; "
                 "open markers: second ρ∞; ★ auto incl. its plan, ○ the pick's own run;\n"
                 "grey ○: timed with other load ≥ 0.5 cores, its wall time too long)", fontsize=10)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"figure: {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--flexopt", default=os.path.join(ROOT, "build", "flexopt"))
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "study_speed_accuracy"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "speed_accuracy.png"))
    ap.add_argument("--results", default=os.path.join(ROOT, "docs", "data", "speed_accuracy.json"),
                    help="a copy of the results kept with the figure (committed: --replot falls back to "
                         "it when OUT holds none)")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--replot", action="store_true")
    ap.add_argument("--retime", type=float, default=None, metavar="CORES",
                    help="run again every kept run timed with at least CORES of other load")
    a = ap.parse_args()
    a.flexopt = os.path.abspath(a.flexopt)
    results_path = os.path.join(a.out, "results.json")
    scenes = [s for s in a.scenes.split(",") if s]
    for s in scenes:
        if s not in SCENES:
            sys.exit(f"unknown scene '{s}' (one of {', '.join(SCENES)})")
    if a.replot:
        if not os.path.exists(results_path) and os.path.exists(a.results):
            results_path = a.results
        results = json.load(open(results_path))["scenes"]
    else:
        os.makedirs(a.out, exist_ok=True)
        start = time.monotonic()
        results = [study_scene(a, s) for s in scenes]
        doc = {"scenes": results, "quick": a.quick, "flexopt": a.flexopt,
               "study_wall_s": time.monotonic() - start}
        with open(results_path, "w") as f:
            json.dump(doc, f)
        if not a.quick and len(scenes) == len(SCENES):
            # The kept copy without the runs' time series (t, y: in OUT's rows), which neither
            # the tables nor the figure read.
            kept = dict(doc, scenes=[dict(res, rows=[{k: v for k, v in r.items() if k not in ("t", "y")}
                                                     for r in res["rows"]]) for res in results])
            os.makedirs(os.path.dirname(a.results), exist_ok=True)
            with open(a.results, "w") as f:
                json.dump(kept, f, indent=0)
        with open(os.path.join(a.out, "results.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["scene", "run", "model", "mesh", "modes", "stiffening", "step", "rho_inf", "dofs",
                        "max_error", "failed", "measured_wall_s", "integration_s", "other_load_cores"])
            for res in results:
                for r in res["rows"]:
                    w.writerow([res["scene"], r["name"], r["model"], r.get("mesh"), r.get("modes"),
                                r.get("stiffening"), r["step"], r["rho_inf"], r.get("dofs"), r.get("max_error"),
                                r["failed"], r["measured_wall_s"], r.get("integration_s"), r["other_load_cores"]])
    for res in results:
        print(table(res) + "\n")
    print(cost_table(results, a.out) + "\n")
    figure(results, a.figure)


if __name__ == "__main__":
    main()
