#!/usr/bin/python3
"""docs/figures/slider_crank_stress.png: the stress-constrained rod of cases/slider_crank_stress
and the strain-energy rod at the same mass (docs/benchmarks.md "Stress-constrained design"):
each final design's physical density seen from +z (every element's centroid, darker where
denser), with its mass and the true peak of its von Mises stress over the revolution
(summary.json problem.stress).
Usage: scripts/bench/stress_rod_figure.py STRESS_OUT STRAIN_ENERGY_OUT FIGURE
"""
import json
import os
import sys

import h5py
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

stress_out, energy_out, figure = sys.argv[1:4]
fig, axes = plt.subplots(2, 1, figsize=(10, 4.6), constrained_layout=True)
for ax, out, title in ((axes[0], stress_out, "least mass, stress <= 60 MPa"),
                       (axes[1], energy_out, "least strain energy at the same mass")):
    with h5py.File(os.path.join(out, "design.h5"), "r") as f:
        steps = sorted((k for k in f if k.startswith("step_")), key=lambda s: int(s[5:]))
        X, T = f["mesh/geometry"][:], f["mesh/topology"][:]
        rho = f[steps[-1]]["physical_density"][:]
    c = X[T].mean(axis=1)
    order = c[:, 2].argsort()  # the densest through the thickness drawn last
    s = json.load(open(os.path.join(out, "summary.json")))
    st = s["problem"]["stress"][-1]
    ax.scatter(1e3 * c[order, 0], 1e3 * c[order, 1], c=rho[order], s=2, cmap="gray_r", vmin=0, vmax=1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(f"{title}: peak von Mises {st['peak'] / 1e6:.1f} MPa at t = {1e3 * st['peak_time']:.2f} ms")
fig.savefig(figure, dpi=90)
print("wrote", figure)
