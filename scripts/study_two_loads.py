#!/usr/bin/python3
"""What do two load cases change against one? cases/cantilever_two_loads optimized three ways
(docs/benchmarks.md, "Scenarios", static load cases):
  - two load cases: the case as it is (the sum of the two compliances);
  - two load cases, KS max: combine: max over the two (ks 50);
  - one load case: both forces at once, as one load (what a user gets who lists both forces
    under one set of loads).
Each runs `flexopt optimize` on 2 ranks (skipped when OUT/<variant>/out/summary.json exists);
every final design is then solved under each force alone by `flexopt simulate --design` of the
case. Prints a markdown table (each design's compliance in each load case, their sum, iterations
and seconds per iteration), writes OUT/two_loads.json and, with matplotlib, OUT/two_loads.png
(the filtered densities).
Usage: study_two_loads.py FLEXOPT OUT [--iterations N]
"""
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = os.path.join(HERE, "..", "cases", "cantilever_two_loads")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           FLEXOPT_REPORT="0", FLEXOPT_PLAN_CHECK="0")
LOADS = ("lower", "upper")


def variants(text, iterations):
    geometry = os.path.abspath(os.path.join(CASE, "square_slab.geo"))
    text = text.replace("square_slab.geo", geometry).replace(
        "max_iterations: 20", f"max_iterations: {iterations}")
    start, end = text.index("load_cases:\n"), text.index("design:\n")
    one = ("line_loads:\n"
           "  - {body: plate, curve: corner_bottom, value: [0, -60, 0]}\n"
           "  - {body: plate, curve: corner_top, value: [0, 60, 0]}\n")
    return {
        "two load cases (sum)": text,
        "two load cases (KS max)": text.replace(
            "objective: {type: compliance}", "objective: {type: compliance, combine: max, ks: 50}"),
        "one load case (both forces)": text[:start] + one + text[end:],
    }


def run(cmd, log):
    with open(log, "w") as f:
        p = subprocess.run(cmd, env=ENV, stdout=f, stderr=subprocess.STDOUT)
    if p.returncode != 0:
        sys.exit(f"FAIL: {' '.join(cmd)} exited with {p.returncode} (see {log})")


def slug(name):
    return "".join(c if c.isalnum() else "_" for c in name).strip("_")


def optimize(flexopt, out, name, text):
    d = os.path.join(out, slug(name))
    os.makedirs(d, exist_ok=True)
    open(os.path.join(d, "case.yaml"), "w").write(text)
    summary = os.path.join(d, "out", "summary.json")
    if not os.path.exists(summary):
        run(["mpirun", "-n", "2", flexopt, "optimize", d, "--out", os.path.join(d, "out")],
            os.path.join(d, "optimize.log"))
    return json.load(open(summary))


def evaluate(flexopt, out, name):
    """The final design of variant `name` under each force alone: {load case: compliance}."""
    d = os.path.join(out, slug(name), "eval")
    summary = os.path.join(d, "summary.json")
    if not os.path.exists(summary):
        run(["mpirun", "-n", "2", flexopt, "simulate", CASE, "--out", d, "--design",
             os.path.join(out, slug(name), "out", "restart.h5")],
            os.path.join(out, slug(name), "eval.log"))
    s = json.load(open(summary))
    return {k: s["load_cases"][k]["compliance"] for k in LOADS}


def densities(out, name):
    """(x, y, filtered density) of the elements of the last frame of design.h5."""
    import h5py
    import numpy as np
    with h5py.File(os.path.join(out, slug(name), "out", "design.h5"), "r") as f:
        xyz = f["/mesh/geometry"][()]
        cells = f["/mesh/topology"][()]
        last = max(int(k.split("_")[1]) for k in f.keys() if k.startswith("step_"))
        rho = f[f"/step_{last}/filtered_density"][()]
    centre = xyz[cells].mean(axis=1)
    return centre[:, 0], centre[:, 1], np.asarray(rho)


def figure(out, rows):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, len(rows), figsize=(3.2 * len(rows), 3.4))
        for ax, name in zip(axes, rows):
            x, y, rho = densities(out, name)
            ax.tricontourf(x, y, rho, levels=[0, 0.25, 0.5, 0.75, 1.0], cmap="Greys")
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(name, fontsize=9)
        fig.tight_layout()
        fig.savefig(os.path.join(out, "two_loads.png"), dpi=120)
    except (ImportError, KeyError) as e:
        print(f"(no figure: {e})")


def main():
    flexopt, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    iterations = sys.argv[sys.argv.index("--iterations") + 1] if "--iterations" in sys.argv else "200"
    os.makedirs(out, exist_ok=True)
    rows = {}
    for name, text in variants(open(os.path.join(CASE, "case.yaml")).read(), iterations).items():
        s = optimize(flexopt, out, name, text)
        rows[name] = {"iterations": s["iterations"],
                      "seconds_per_iteration": s["wall_s"] / max(1, s["iterations"]),
                      "own_objective": s["objective"][-1],
                      "compliance": evaluate(flexopt, out, name)}
    print("| design | C, lower force alone | C, upper force alone | sum | iterations | s/it |")
    print("|---|---|---|---|---|---|")
    for name, r in rows.items():
        c = r["compliance"]
        print(f"| {name} | {c['lower']:.5g} | {c['upper']:.5g} | {c['lower'] + c['upper']:.5g} | "
              f"{r['iterations']} | {r['seconds_per_iteration']:.2f} |")
    json.dump(rows, open(os.path.join(out, "two_loads.json"), "w"), indent=2)
    figure(out, rows)


if __name__ == "__main__":
    main()
