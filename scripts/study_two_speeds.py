#!/usr/bin/python3
"""What does designing for two speeds give up, and gain? cases/slider_crank_two_speeds optimized
three ways (docs/benchmarks.md, "Scenarios"):
  - slow: the rod designed for 100 rad/s alone (the case with the fast scenario left out);
  - fast: designed for 150 rad/s alone (the slow scenario left out);
  - both: the case as it is (the KS maximum of the two speeds' strain energies);
  - both_normalized: the two speeds weighted by the inverse of their strain energy at the first
    design (combine: weighted), so that each counts by its relative change.
Each runs `flexopt optimize` on 2 ranks (skipped when OUT/<variant>/out/summary.json exists); then
every final design is evaluated at both speeds by `flexopt simulate --design` of the whole case.
Prints a markdown table (each design's strain energy at each speed, relative to the design for
that speed alone, and the seconds per iteration), writes OUT/two_speeds.json and, with
matplotlib, OUT/two_speeds.png.
Usage: study_two_speeds.py FLEXOPT OUT [--iterations N]
"""
import json
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = os.path.join(HERE, "..", "cases", "slider_crank_two_speeds", "case.yaml")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           FLEXOPT_REPORT="0", FLEXOPT_PLAN_CHECK="0")
SPEEDS = ("slow", "fast")


def scenario_block(text, name):
    """The lines of scenario `name` in the case text (its first line to the next scenario)."""
    lines = text.splitlines(keepends=True)
    start = next(i for i, l in enumerate(lines) if re.match(rf"  - (\{{)?name: {name}\b", l))
    end = start + 1
    while end < len(lines) and lines[end].startswith("    "):
        end += 1
    return "".join(lines[start:end])


def variants(text, initial=None):
    meshes = os.path.abspath(os.path.join(HERE, "..", "meshes"))
    text = text.replace("../../meshes", meshes)
    out = {"both": text}
    for alone, other in (("slow", "fast"), ("fast", "slow")):
        out[alone] = text.replace(scenario_block(text, other), "")
    if initial:
        weights = f"[{1.0 / initial['slow']:.6g}, {1.0 / initial['fast']:.6g}]"
        out["both_normalized"] = text.replace(
            "combine: max, ks: 20", f"combine: weighted, weights: {weights}")
    return out


def run(cmd, log):
    with open(log, "w") as f:
        p = subprocess.run(cmd, env=ENV, stdout=f, stderr=subprocess.STDOUT)
    if p.returncode != 0:
        sys.exit(f"FAIL: {' '.join(cmd)} exited with {p.returncode} (see {log})")


def optimize(flexopt, out, name, text, iterations):
    d = os.path.join(out, name)
    os.makedirs(d, exist_ok=True)
    case = os.path.join(d, "case.yaml")
    open(case, "w").write(text)
    summary = os.path.join(d, "out", "summary.json")
    if not os.path.exists(summary):
        extra = ["--max-iterations", iterations] if iterations else []
        run(["mpirun", "-n", "2", flexopt, "optimize", d, "--out", os.path.join(d, "out")] + extra,
            os.path.join(d, "optimize.log"))
    return json.load(open(summary))


def evaluate(flexopt, out, name, both_case):
    """The final design of variant `name` at both speeds: {speed: strain energy}."""
    d = os.path.join(out, name, "eval")
    summary = os.path.join(d, "summary.json")
    if not os.path.exists(summary):
        run(["mpirun", "-n", "2", flexopt, "simulate", both_case, "--out", d, "--design",
             os.path.join(out, name, "out", "restart.h5")], os.path.join(out, name, "eval.log"))
    s = json.load(open(summary))
    return {k: s["scenarios"][k]["responses"]["objective"] for k in SPEEDS}


def print_table(names, headers, initial, rows):
    """Markdown: each design's value in each condition, relative to the design for it alone."""
    best = {k: rows[k]["energy"][k] for k in names}
    print("| design for | " + " | ".join(f"{h} [J] | vs its own design's" for h in headers) + " | s/it |")
    print("|---" * (2 * len(names) + 2) + "|")
    for name, r in [("initial", {"energy": initial})] + list(rows.items()):
        cells = " | ".join(f"{r['energy'][k]:.5g} | {r['energy'][k] / best[k] - 1:+.1%}" for k in names)
        seconds = f"{r['seconds_per_iteration']:.2f}" if "seconds_per_iteration" in r else ""
        print(f"| {name} | {cells} | {seconds} |")


def main():
    flexopt, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    iterations = sys.argv[sys.argv.index("--iterations") + 1] if "--iterations" in sys.argv else None
    os.makedirs(out, exist_ok=True)
    text = open(CASE).read()
    base = variants(text)
    both_dir = os.path.join(out, "both")
    rows = {}
    for name in ("slow", "fast", "both"):
        s = optimize(flexopt, out, name, base[name], iterations)
        rows[name] = {"seconds_per_iteration": s["wall_s"] / max(1, s["iterations"]),
                      "iterations": s["iterations"]}
    # The two speeds' strain energies at the first design.
    h0 = os.path.join(out, "initial")
    if not os.path.exists(os.path.join(h0, "summary.json")):
        run(["mpirun", "-n", "2", flexopt, "simulate", both_dir,
             "--out", h0], os.path.join(out, "initial.log"))
    s0 = json.load(open(os.path.join(h0, "summary.json")))
    initial = {k: s0["scenarios"][k]["responses"]["objective"] for k in SPEEDS}
    name = "both_normalized"
    s = optimize(flexopt, out, name, variants(text, initial)[name], iterations)
    rows[name] = {"seconds_per_iteration": s["wall_s"] / max(1, s["iterations"]),
                  "iterations": s["iterations"]}
    for name in rows:
        rows[name]["energy"] = evaluate(flexopt, out, name, both_dir)
    print_table(SPEEDS, ("at 100 rad/s", "at 150 rad/s"), initial, rows)
    json.dump({"initial": initial, "designs": rows}, open(os.path.join(out, "two_speeds.json"), "w"),
              indent=2)
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(6, 4))
    names = ["initial"] + list(rows)
    for i, speed in enumerate(SPEEDS):
        vals = [initial[speed]] + [rows[n]["energy"][speed] for n in rows]
        ax.bar([j + 0.4 * i for j in range(len(names))], vals, width=0.4,
               label=f"at {'100' if speed == 'slow' else '150'} rad/s")
    ax.set_xticks([j + 0.2 for j in range(len(names))])
    ax.set_xticklabels(["initial", "for 100", "for 150", "both\n(KS max)", "both\n(normalized)"])
    ax.set_ylabel("time-averaged rod strain energy [J]")
    ax.set_yscale("log")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(out, "two_speeds.png"), dpi=120)


if __name__ == "__main__":
    main()
