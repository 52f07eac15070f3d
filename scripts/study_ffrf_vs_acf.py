#!/usr/bin/python3
"""Speed against accuracy of FFRF and ACF bodies on cases/kane_beam (the 10 m beam spun up to
6 rad/s, above its first bending frequency; minimum tip deflection about -0.57 m at 6.8 s).

Usage: scripts/study_ffrf_vs_acf.py [--flexopt build/flexopt] [--out build/study_ffrf_vs_acf]
                                    [--figure docs/figures/ffrf_vs_acf.png] [--end 10] [--quick]
       scripts/study_ffrf_vs_acf.py --replot      # table and figure again from OUT/results.json

Method. Every run is the case with time.end = END (default 10 s, past the minimum) on 2 ranks,
written by scripts/case_variants.py into OUT/NAME:

  - reference: ACF at mesh size 0.1 m (12.9k DOFs; ~15 min);
  - ACF at mesh sizes 0.4 and 0.2 m (the case's);
  - FFRF with centrifugal geometric stiffening and 2, 4, 8, 16, 40 fixed-interface modes,
    reduced from the case's 0.2 m mesh and from the reference's 0.1 m mesh (the FFRF result
    depends on the mesh it is reduced from: at 0.1 m the comparison with the reference isolates
    the modal truncation and the formulation);
  - linear FFRF (no stiffening), 4 modes, which diverges (plotted only if inside the axes).

The observable is y_tip(t), the y component of the sensor tip_elastic (the tip's elastic
displacement in the hub frame). Errors against the reference: the largest difference over the
run, max_t |y_tip(t) - y_ref(t)| / max_t |y_ref| (on the reference's sample times, each run
interpolated onto them), and the error of the minimum tip deflection min y_tip against min y_ref.
Costs: `integration_s` of summary.json (the time-stepping loop), `wall_s` of summary.json
(flexopt from start to end: meshing, partitioning, reduction, integration, output) and the wall
time measured here around `mpirun` (also MPI start-up). "other load" is the CPU time that
processes other than the run used during it, in cores (from /proc/stat), so that timings taken
on a busy machine can be told apart.

Writes OUT/results.json and OUT/results.csv (one row per run), prints a markdown table and draws
the log-log figure of the error against the measured wall time (left) and against the
integration time (right). --quick (a smoke run of a few minutes): the 0.2 m ACF run as the
reference, ACF 0.4 m and FFRF with 2 and 8 modes on the 0.2 m mesh only; add --end 2 for
seconds.
"""
import argparse
import csv
import hashlib
import json
import os
import resource
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from case_variants import run_variant  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CASE = os.path.join(ROOT, "cases", "kane_beam")
FFRF = "model: ffrf\n    reduction: {modes: %d, geometric_stiffening: %s}"
COLUMNS = ["name", "model", "mesh_m", "dofs", "modes", "stiffening", "max_error", "min_tip_m",
           "t_min_s", "min_error", "integration_s", "flexopt_wall_s", "measured_wall_s",
           "other_load_cores"]
LOADED = 0.5  # other load [cores] from which a run's times count as taken on a busy machine


def plan(quick):
    """The runs as (name, model, mesh size, modes, stiffening); the first is the reference."""
    if quick:
        return ([("acf_h0.2", "acf", 0.2, None, None), ("acf_h0.4", "acf", 0.4, None, None)]
                + [(f"ffrf_m{n}_h0.2", "ffrf", 0.2, n, True) for n in (2, 8)])
    runs = [("acf_h0.1", "acf", 0.1, None, None)]
    runs += [(f"acf_h{h}", "acf", h, None, None) for h in (0.4, 0.2)]
    runs += [(f"ffrf_m{n}_h{h}", "ffrf", h, n, True) for h in (0.2, 0.1) for n in (2, 4, 8, 16, 40)]
    runs.append(("ffrf_linear_m4_h0.2", "ffrf", 0.2, 4, False))
    return runs


def busy_seconds():
    """CPU seconds the whole machine has spent busy since boot (all cores, /proc/stat)."""
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    return (sum(v[:8]) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")


def children_seconds():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()[:16]


def run(args, name, model, mesh, modes, stiff):
    """Runs one variant (waiting for the binary while it is being rebuilt) and returns its tip
    deflection, its summary and the measured wall time and other machine load."""
    replace = [] if mesh == 0.2 else [("mesh: {size: 0.2,", f"mesh: {{size: {mesh},")]
    if model == "ffrf":
        replace.append(("model: acf", FFRF % (modes, "true" if stiff else "false")))
    for attempt in range(10):
        while not os.access(args.flexopt, os.X_OK):
            print(f"{args.flexopt} missing (being rebuilt?): waiting 60 s", flush=True)
            time.sleep(60)
        sha = digest(args.flexopt)
        b0, c0, t0 = busy_seconds(), children_seconds(), time.monotonic()
        try:
            s = run_variant(args.flexopt, CASE, args.out, name, replace, ranks=2, end=args.end)
            break
        except SystemExit:
            if os.access(args.flexopt, os.X_OK) or attempt == 9:
                raise
            print(f"{args.flexopt} disappeared during the run: retrying in 60 s", flush=True)
            time.sleep(60)
    wall = time.monotonic() - t0
    other = max(0.0, busy_seconds() - b0 - (children_seconds() - c0)) / wall
    tip = s["sensors"]["tip_elastic"]
    y = np.array([np.nan if v is None or v[1] is None else v[1] for v in tip["value"]], dtype=float)
    body = s["bodies"][0]
    row = {"name": name, "model": model, "mesh_m": mesh, "dofs": body["dofs"], "modes": modes,
           "stiffening": stiff, "integration_s": s["integration_s"], "flexopt_wall_s": s["wall_s"],
           "measured_wall_s": wall, "other_load_cores": other, "binary_sha256": sha}
    print(f"  {name}: {wall:.1f} s, other load {other:.2f} cores", flush=True)
    return np.array(tip["t"], dtype=float), y, row


def errors(t, y, t_ref, y_ref, row):
    """Adds the two errors against the reference to the row (None where the run is not finite)."""
    i = int(np.argmin(y_ref))
    scale = np.max(np.abs(y_ref))
    with np.errstate(invalid="ignore", over="ignore"):
        d = np.abs(np.interp(t_ref, t, y) - y_ref)
    finite = bool(np.all(np.isfinite(y)))
    k = int(np.nanargmin(y)) if finite else None
    row.update(max_error=float(d.max() / scale) if finite else None,
               min_tip_m=float(y[k]) if finite else None, t_min_s=float(t[k]) if finite else None,
               min_error=float(y[k] / y_ref[i] - 1) if finite else None,
               max_abs_tip_m=float(np.nanmax(np.abs(y))))


def fmt(v, spec):
    return "—" if v is None else format(v, spec)


def table(rows):
    lines = ["| run | DOFs | max error | min tip [m] | at t [s] | min error | integration [s] | "
             "flexopt wall [s] | measured wall [s] | other load [cores] |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["model"] == "acf":
            what = f"ACF, h = {r['mesh_m']} m" + (" (reference)" if r.get("reference") else "")
        else:
            what = (f"FFRF {'stiffened' if r['stiffening'] else 'linear'}, {r['modes']} modes, "
                    f"h = {r['mesh_m']} m")
        err = ("0 (ref.)" if r.get("reference") else
               fmt(r["max_error"], ".2e") if r["max_error"] is not None
               else f"diverges (max \\|y\\| = {r['max_abs_tip_m']:.3g} m)")
        minerr = "—" if r.get("reference") or r["min_error"] is None else f"{100 * r['min_error']:+.2f} %"
        lines.append(f"| {what} | {r['dofs']:,} | {err} | {fmt(r['min_tip_m'], '.5f')} | "
                     f"{fmt(r['t_min_s'], '.2f')} | {minerr} | {r['integration_s']:.2f} | "
                     f"{r['flexopt_wall_s']:.2f} | {r['measured_wall_s']:.1f} | "
                     f"{r['other_load_cores']:.2f} |")
    return "\n".join(lines)


def figure(rows, path, end):
    """Log-log error against cost, measured wall time (left) and integration time (right); runs
    during which other processes used at least LOADED cores are drawn with open markers."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import ticker

    ref = next(r for r in rows if r.get("reference"))
    runs = [r for r in rows if not r.get("reference")]
    stiff = [r for r in runs if r["model"] == "acf" or r["stiffening"]]
    top = 3 * max(r["max_error"] for r in stiff)
    bottom = min(r["max_error"] for r in stiff) / 3
    linear = [r for r in runs if r not in stiff]
    hidden = [r for r in linear if r["max_error"] is None or not bottom <= r["max_error"] <= top]
    series = [("ACF", "s", "C3", [r for r in stiff if r["model"] == "acf"],
               lambda r: f"{r['mesh_m']} m\n{r['dofs']:,} DOFs")]
    for h, marker, color in ((0.2, "o", "C0"), (0.1, "^", "C2")):
        series.append((f"FFRF stiffened, modes from the {h} m mesh", marker, color,
                       [r for r in stiff if r["model"] == "ffrf" and r["mesh_m"] == h],
                       lambda r: str(r["modes"])))
    series.append(("FFRF linear", "x", "k", [r for r in linear if r not in hidden],
                   lambda r: f"linear, {r['modes']}"))
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.4), sharey=True)
    for ax, key, xlabel in ((axes[0], "measured_wall_s", "wall time of the run, measured around mpirun [s]"),
                            (axes[1], "integration_s", "integration time (summary.json integration_s) [s]")):
        for label, marker, color, pts, text in series:
            if not pts:
                continue
            # In the order of refinement (mesh size down, modes up), not of cost.
            pts = sorted(pts, key=lambda r: (-r["mesh_m"], r["modes"] or 0))
            ax.plot([r[key] for r in pts], [r["max_error"] for r in pts], color=color, linewidth=1,
                    linestyle="-" if label != "FFRF linear" else "none")
            for r in pts:
                loaded = r["other_load_cores"] >= LOADED
                ax.plot(r[key], r["max_error"], marker=marker, color=color, linestyle="none",
                        markerfacecolor="none" if loaded else color)
                ax.annotate(text(r), (r[key], r["max_error"]), textcoords="offset points",
                            xytext=(6, 4), fontsize=8, color=color)
            ax.plot([], [], marker=marker, color=color, label=label)
        ax.axvline(ref[key], color="C3", linestyle=":", linewidth=1)
        ax.annotate(f"reference: ACF {ref['mesh_m']} m,\n{ref['dofs']:,} DOFs", (ref[key], bottom),
                    textcoords="offset points", xytext=(-4, 4), ha="right", fontsize=8, color="C3")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_major_locator(ticker.LogLocator(subs=(1, 2, 5)))
        ax.xaxis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(ticker.NullFormatter())
        ax.set_ylim(bottom, top)
        ax.set_xlim(right=ref[key] * 2)
        ax.set_xlabel(xlabel)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel(r"max$_t$ |y$_{tip}$ − y$_{ref}$| / max$_t$ |y$_{ref}$|")
    axes[0].legend(loc="upper right", fontsize=8)
    notes = [f"open markers: other jobs used ≥ {LOADED} core during the run"]
    notes += [f"linear FFRF, {r['modes']} modes: |y_tip| up to {r['max_abs_tip_m']:.3g} m (diverges), "
              "not shown" for r in hidden]
    fig.suptitle(f"cases/kane_beam, t ∈ [0, {end:g}] s, 2 ranks: tip deflection error against "
                 f"the reference, against cost\n" + "; ".join(notes), fontsize=10)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"figure: {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--flexopt", default=os.path.join(ROOT, "build", "flexopt"))
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "study_ffrf_vs_acf"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "ffrf_vs_acf.png"))
    ap.add_argument("--end", type=float, default=10.0, help="time.end of every run [s]")
    ap.add_argument("--quick", action="store_true", help="smoke run: 0.2 m reference, 4 runs")
    ap.add_argument("--replot", action="store_true", help="table and figure from OUT/results.json")
    a = ap.parse_args()
    a.flexopt = os.path.abspath(a.flexopt)
    results = os.path.join(a.out, "results.json")
    if a.replot:
        with open(results) as f:
            saved = json.load(f)
        print(table(saved["rows"]))
        figure(saved["rows"], a.figure, saved["end"])
        return
    os.makedirs(a.out, exist_ok=True)
    start, load0 = time.monotonic(), os.getloadavg()
    runs = [run(a, *p) for p in plan(a.quick)]
    t_ref, y_ref, ref = runs[0]
    ref["reference"] = True
    for t, y, row in runs:
        errors(t, y, t_ref, y_ref, row)
    rows = [row for _, _, row in runs]
    total = time.monotonic() - start
    saved = {"case": "cases/kane_beam", "end": a.end, "ranks": 2, "quick": a.quick,
             "flexopt": a.flexopt, "study_wall_s": total, "loadavg_start": load0,
             "loadavg_end": os.getloadavg(), "rows": rows}
    with open(results, "w") as f:
        json.dump(saved, f, indent=1)
    with open(os.path.join(a.out, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    print(table(rows))
    print(f"study: {total / 60:.1f} min; load average {load0[0]:.2f} at the start, "
          f"{saved['loadavg_end'][0]:.2f} at the end; results in {a.out}")
    if len({r["binary_sha256"] for r in rows}) > 1:
        print("WARNING: the flexopt binary changed during the study (binary_sha256 in results.json)")
    figure(rows, a.figure, a.end)


if __name__ == "__main__":
    main()
