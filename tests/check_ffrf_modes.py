#!/usr/bin/python3
"""FFRF without modes is the rigid body; with modes it converges.

Usage: check_ffrf_modes.py FLEXOPT RIGID_LIMIT_CASE PENDULUM_CASE OUT

Runs on 2 ranks:
  * RIGID_LIMIT_CASE (a free tumbling bar whose FFRF frame sits at its centre of mass, no
    modes) as model: ffrf and as model: rigid: the same coordinates and the same discrete
    equations up to the direction of p that the normalization multiplier absorbs, so the tip
    trajectories must agree to round-off: 1e-11 m over 500 steps (Newton stops once an
    increment is below 1e-12 relative, so each run carries ~1e-12 of solver error per step,
    and the mass properties are summed in different orders). With the frame elsewhere (the pendulum's pin) the two runs integrate different
    coordinates and differ by the O(h^2) error of the scheme instead (printed, not checked);
  * variants of PENDULUM_CASE (0.4 s) with modes 1, 2, 4, 8 against 16: the error of the tip's
    elastic y-displacement (max over time) must decrease with every doubling of the modes.
"""
import json
import os
import re
import subprocess
import sys


def run_variant(flexopt, case, out, name, replace):
    text = open(os.path.join(case, "case.yaml")).read()
    text = re.sub(r"geometry: ([./]*)meshes/",
                  lambda m: "geometry: " + os.path.abspath(os.path.join(case, m.group(1), "meshes")) + "/",
                  text)
    text = re.sub(r"time: \{end: [0-9.e-]+", "time: {end: 0.4", text)
    for a, b in replace:
        if a not in text:
            sys.exit(f"'{a}' not in {case}/case.yaml")
        text = text.replace(a, b)
    d = os.path.join(out, name)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "case.yaml"), "w") as f:
        f.write(text)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    cmd = ["mpirun", "-n", "2", flexopt, "simulate", d, "--out", os.path.join(d, "out")]
    print("$ " + " ".join(cmd), flush=True)
    proc = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if proc.returncode != 0:
        sys.stdout.write(proc.stdout)
        sys.exit(f"{name}: flexopt failed")
    return json.load(open(os.path.join(d, "out", "summary.json")))


def main():
    import numpy as np
    flexopt, limit_case, case, out = sys.argv[1:5]
    ok = True

    def tip_difference(a, b):
        return np.max(np.abs(np.array(a["sensors"]["tip"]["value"]) -
                             np.array(b["sensors"]["tip"]["value"])))

    rigid = run_variant(flexopt, limit_case, out, "limit_rigid",
                        [("model: ffrf", "model: rigid"), ("    reduction: {modes: 0}\n", "")])
    ffrf0 = run_variant(flexopt, limit_case, out, "limit_ffrf", [])
    diff = tip_difference(rigid, ffrf0)
    print(f"free bar, frame at the centre of mass: rigid vs ffrf without modes, tip positions "
          f"differ by at most {diff:.3e} m (limit 1e-11)")
    ok &= diff <= 1e-11
    rigid = run_variant(flexopt, case, out, "rigid", [("model: ffrf", "model: rigid"),
                                                      ("    reduction: {modes: 4}\n", "")])
    ffrf0 = run_variant(flexopt, case, out, "ffrf0", [("modes: 4", "modes: 0")])
    print(f"pendulum, frame at the pin: rigid vs ffrf without modes differ by "
          f"{tip_difference(rigid, ffrf0):.3e} m (the scheme's O(h^2) error in other coordinates)")
    runs = {n: run_variant(flexopt, case, out, f"ffrf{n}", [("modes: 4", f"modes: {n}")])
            for n in (1, 2, 4, 8, 16)}
    ref = np.array(runs[16]["sensors"]["tip_elastic"]["value"])[:, 1]
    scale = np.max(np.abs(ref))
    errors = []
    for n in (1, 2, 4, 8):
        v = np.array(runs[n]["sensors"]["tip_elastic"]["value"])[:, 1]
        errors.append(np.max(np.abs(v - ref)) / scale)
        print(f"modes {n:2d}: max error of the tip elastic deflection vs 16 modes {errors[-1]:.3e} "
              f"(relative to its peak {scale:.3e} m)")
    decreasing = all(b < a for a, b in zip(errors, errors[1:]))
    print("errors decrease with every doubling: " + ("yes" if decreasing else "NO"))
    ok &= decreasing
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
