#!/usr/bin/python3
"""Does designing both links pay? cases/fourbar_topopt optimized three ways at the same total
mass bound (docs/benchmarks.md, "Several design bodies"):
  - both: the coupler and the rocker designed at once (the case as it is);
  - coupler: the coupler alone, the rocker solid;
  - rocker: the rocker alone, the coupler solid.
Each runs `flexopt optimize` on 2 ranks (skipped when OUT/<variant>/out/summary.json exists), then
`flexopt simulate --design` of its final design with each link's strain energy and the mass as
responses. Prints a markdown table: design variables, seconds per iteration, the final objective
(the time-averaged strain energy of both links), each link's share, the mass, and each body's
volume fraction; writes OUT/several_bodies.json.
Usage: study_several_bodies.py FLEXOPT OUT [--iterations N]
"""
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = os.path.join(HERE, "..", "cases", "fourbar_topopt", "case.yaml")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           FLEXOPT_REPORT="0", FLEXOPT_PLAN_CHECK="0")


def design_line(text, body):
    return next(line for line in text.splitlines() if line.startswith(f"  - {{body: {body},"))


def variants(text):
    """The case text of each variant: both links, or one with the other solid."""
    meshes = os.path.abspath(os.path.join(HERE, "..", "meshes"))
    text = text.replace("../../meshes", meshes)
    out = {"both": text}
    for alone, other in (("coupler", "rocker"), ("rocker", "coupler")):
        out[alone] = text.replace(design_line(text, other) + "\n", "")
    return out


def measured(text):
    """The variant with each link's strain energy and the mass as responses (bounds unused)."""
    head = text[:text.index("constraints:")]
    return head + ("constraints:\n"
                   "  - {type: strain_energy_integral, body: coupler, max: 100}\n"
                   "  - {type: strain_energy_integral, body: rocker, max: 100}\n"
                   "  - {type: mass, body: [coupler, rocker], max: 100}\n")


def run(cmd, log):
    with open(log, "w") as f:
        p = subprocess.run(cmd, env=ENV, stdout=f, stderr=subprocess.STDOUT)
    if p.returncode != 0:
        sys.exit(f"FAIL: {' '.join(cmd)} exited with {p.returncode} (see {log})")


def main():
    flexopt, out = sys.argv[1], sys.argv[2]
    iterations = sys.argv[sys.argv.index("--iterations") + 1] if "--iterations" in sys.argv else None
    text = open(CASE).read()
    rows = {}
    for name, case_text in variants(text).items():
        d = os.path.join(out, name)
        os.makedirs(d, exist_ok=True)
        with open(os.path.join(d, "case.yaml"), "w") as f:
            f.write(case_text)
        summary = os.path.join(d, "out", "summary.json")
        if not os.path.exists(summary):
            cmd = ["mpirun", "-n", "2", flexopt, "optimize", d, "--out", os.path.join(d, "out")]
            run(cmd + (["--max-iterations", iterations] if iterations else []), d + ".log")
        s = json.load(open(summary))
        m = os.path.join(out, name + "_measure")
        os.makedirs(m, exist_ok=True)
        with open(os.path.join(m, "case.yaml"), "w") as f:
            f.write(measured(case_text))
        run(["mpirun", "-n", "2", flexopt, "simulate", m, "--out", os.path.join(m, "out"),
             "--design", os.path.join(d, "out", "restart.h5")], m + ".log")
        r = json.load(open(os.path.join(m, "out", "summary.json")))["responses"]
        seconds = [sum(x) for x in zip(*s["seconds_split"].values())]
        rows[name] = {
            "design_variables": s["design_variables"],
            "iterations": s["iterations"],
            "seconds_per_iteration": sum(seconds) / len(seconds),
            "objective_first": s["objective"][0],
            "objective_final": s["objective"][-1],
            "coupler_strain_energy": r["constraint0"],
            "rocker_strain_energy": r["constraint1"],
            "mass": r["constraint2"],
            "mass_bound": s["constraint_bounds"][0],
            "volume_fractions": s.get("body_volume_fractions", {}),
            "volume_fraction": s["volume_fraction"],
        }
    json.dump(rows, open(os.path.join(out, "several_bodies.json"), "w"), indent=1)
    both = rows["both"]["objective_final"]
    print("| designed | design variables | s/it | objective (J) | vs both | coupler (J) | "
          "rocker (J) | mass (kg, bound) | volume fractions |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, x in rows.items():
        vf = ", ".join(f"{b} {v:.3f}" for b, v in x["volume_fractions"].items()) or \
            f"{name} {x['volume_fraction']:.3f}"
        print(f"| {name} | {x['design_variables']:,} | {x['seconds_per_iteration']:.2f} | "
              f"{x['objective_final']:.4f} | {x['objective_final'] / both - 1:+.1%} | "
              f"{x['coupler_strain_energy']:.4f} | {x['rocker_strain_energy']:.4f} | "
              f"{x['mass']:.4f} ({x['mass_bound']}) | {vf} |")


if __name__ == "__main__":
    main()
