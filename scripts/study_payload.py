#!/usr/bin/python3
"""Scenarios that change the shape of the loads: the rod of cases/slider_crank_two_speeds at 150
rad/s with the 0.5 kg slider (scenario light) and with a 4 kg slider (scenario heavy: the slider's
density times 8), designed for each alone and for both (KS maximum), every design evaluated in both
scenarios (docs/benchmarks.md, "Scenarios"). The same runs and table as
scripts/study_two_speeds.py. Usage: study_payload.py FLEXOPT OUT [--iterations N]
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import study_two_speeds as st  # noqa: E402

SCENARIOS = ('''scenarios:
  - name: light
  - name: heavy
    bodies: {slider: {density: 11111.2}}
''')


def main():
    flexopt, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    iterations = sys.argv[sys.argv.index("--iterations") + 1] if "--iterations" in sys.argv else None
    os.makedirs(out, exist_ok=True)
    text = open(st.CASE).read()
    start = text.index("scenarios:")
    end = text.index("design:")
    text = text[:start] + SCENARIOS + text[end:]
    meshes = os.path.abspath(os.path.join(st.HERE, "..", "meshes"))
    text = text.replace("../../meshes", meshes)
    variants = {"both": text}
    variants["light"] = text.replace("    bodies: {slider: {density: 11111.2}}\n", "").replace(
        "  - name: heavy\n", "")
    variants["heavy"] = text.replace("  - name: light\n", "")
    rows = {}
    for name in ("light", "heavy", "both"):
        s = st.optimize(flexopt, out, name, variants[name], iterations)
        rows[name] = {"seconds_per_iteration": s["wall_s"] / max(1, s["iterations"])}
    both_dir = os.path.join(out, "both")
    h0 = os.path.join(out, "initial")
    if not os.path.exists(os.path.join(h0, "summary.json")):
        st.run(["mpirun", "-n", "2", flexopt, "simulate", both_dir, "--out", h0],
               os.path.join(out, "initial.log"))
    s0 = json.load(open(os.path.join(h0, "summary.json")))
    names = ("light", "heavy")
    initial = {k: s0["scenarios"][k]["responses"]["objective"] for k in names}
    for name in rows:
        d = os.path.join(out, name, "eval")
        if not os.path.exists(os.path.join(d, "summary.json")):
            st.run(["mpirun", "-n", "2", flexopt, "simulate", both_dir, "--out", d, "--design",
                    os.path.join(out, name, "out", "restart.h5")], os.path.join(out, name, "eval.log"))
        s = json.load(open(os.path.join(d, "summary.json")))
        rows[name]["energy"] = {k: s["scenarios"][k]["responses"]["objective"] for k in names}
    st.print_table(names, ("light slider", "heavy slider"), initial, rows)
    json.dump({"initial": initial, "designs": rows}, open(os.path.join(out, "payload.json"), "w"),
              indent=2)


if __name__ == "__main__":
    main()
