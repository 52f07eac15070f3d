#!/usr/bin/python3
"""The element von Mises stress of a spinning bar against 1D theory, for an ACF and an FFRF body:
the bar of tests/dynamics/spinning_stress/{acf,ffrf} (L = 1 m, rho = 2700 kg/m^3) turning
steadily at omega = 20 rad/s about z through its clamped end carries the uniaxial centrifugal
stress rho omega^2 (L^2 - x^2) / 2, so von Mises = sigma_xx.

Usage: check_spinning_stress.py FLEXOPT CASES OUT

From the motion file's last frame (motion.h5 /bar/step_K/von_mises, the element centroids from
the reference mesh) on the elements with centroid 0.1 < x < 0.9 (the clamped end's and the free
end's 3D effects left out):
  - ACF (the co-rotated stress, docs/theory.md 8.3): within 2e-3 of rho omega^2 L^2 / 2
    (measured 2.6e-4: the Tet10 centroid stress of the cubic displacement and the residual
    vibration);
  - FFRF (the stress shapes of a 40-mode basis, 10.3): within 4e-2 (measured 3.2e-2: the
    basis's truncation; the error falls with the modes, 10 % at 20 and 5.9 % at 30);
  - the first frame (at rest) is free of stress, and summary.json's von_mises_max is the
    largest value of the frames.
"""
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import run_flexopt  # noqa: E402

RHO, OMEGA, L = 2700.0, 20.0, 1.0
LIMITS = {"acf": 2e-3, "ffrf": 4e-2}


def check(flexopt, case, out, limit):
    import h5py
    import numpy as np
    sys.stdout.write(run_flexopt(["mpirun", "-n", "2", flexopt, "simulate", case, "--out", out]))
    ok = True
    with h5py.File(os.path.join(out, "motion.h5"), "r") as f:
        X = f["bar/reference_geometry"][:]
        cells = f["bar/topology"][:]
        steps = sorted((k for k in f["bar"] if k.startswith("step_")), key=lambda k: int(k[5:]))
        frames = [f["bar/" + k + "/von_mises"][:] for k in steps]
    xc = X[cells[:, :4]].mean(axis=1)[:, 0]  # the corner nodes' mean: the centroid
    exact = RHO * OMEGA**2 * (L**2 - xc**2) / 2
    scale = RHO * OMEGA**2 * L**2 / 2
    mid = (xc > 0.1) & (xc < 0.9)
    err = np.abs(frames[-1][mid] - exact[mid]).max() / scale
    name = os.path.basename(case.rstrip("/"))
    print(f"{name}: {mid.sum()} elements, largest difference from rho omega^2 (L^2 - x^2) / 2: "
          f"{err:.3e} of {scale:.4g} Pa (limit {limit:g})")
    ok &= err <= limit
    at_rest = np.abs(frames[0]).max()
    print(f"{name}: largest stress of the first frame (at rest) {at_rest:.3e} Pa")
    ok &= at_rest <= 1e-9 * scale
    summary = json.load(open(os.path.join(out, "summary.json")))
    largest = max(v.max() for v in frames)
    reported = summary["von_mises_max"]["bar"]
    print(f"{name}: von_mises_max {reported:.6g} Pa, the frames' largest {largest:.6g} Pa")
    ok &= abs(reported - largest) <= 1e-12 * largest
    return ok


def main():
    flexopt, cases, out = sys.argv[1:4]
    ok = True
    for model, limit in LIMITS.items():
        ok &= check(flexopt, os.path.join(cases, model), os.path.join(out, model), limit)
    print("PASS" if ok else "FAIL")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
