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
  * variants of PENDULUM_CASE (0.4 s) with modes 2, 4, 8 against 16: the error of the tip's
    elastic y-displacement (max over time) must decrease with every doubling of the modes.
    (The bar's modes come in pairs, bending in y and z at the same frequency, and which of a
    pair comes first is arbitrary: odd counts are not comparable.)
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import run_variant  # noqa: E402


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
    pendulum = "    reduction: {modes: 8, geometric_stiffening: true}\n"
    rigid = run_variant(flexopt, case, out, "rigid", end=0.4,
                        replace=[("model: ffrf", "model: rigid"), (pendulum, "")])
    ffrf0 = run_variant(flexopt, case, out, "ffrf0", end=0.4,
                        replace=[("modes: 8, geometric_stiffening: true", "modes: 0")])
    print(f"pendulum, frame at the pin: rigid vs ffrf without modes differ by "
          f"{tip_difference(rigid, ffrf0):.3e} m (the scheme's O(h^2) error in other coordinates)")
    runs = {n: run_variant(flexopt, case, out, f"ffrf{n}", end=0.4,
                           replace=[("modes: 8", f"modes: {n}")])
            for n in (2, 4, 8, 16)}
    ref = np.array(runs[16]["sensors"]["tip_elastic"]["value"])[:, 1]
    scale = np.max(np.abs(ref))
    errors = []
    for n in (2, 4, 8):
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
