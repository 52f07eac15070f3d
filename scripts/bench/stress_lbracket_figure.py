#!/usr/bin/python3
"""docs/figures/lbracket_stress.png: the stress-constrained and the compliance design of
cases/lbracket_stress (docs/benchmarks.md "Stress-constrained design"), each coloured by its
elements' von Mises stress (design.h5's `von_mises`, physical density >= 0.5), in the plane of
the plate (first layer of elements).
Usage: scripts/bench/stress_lbracket_figure.py STRESS_OUT COMPLIANCE_OUT FIGURE [LIMIT (1e8)]
"""
import json
import os
import sys

import h5py
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

stress_out, compliance_out, figure = sys.argv[1:4]
limit = float(sys.argv[4]) if len(sys.argv) > 4 else 1e8
fig, axes = plt.subplots(1, 2, figsize=(11, 5), constrained_layout=True)
for ax, out, title in ((axes[0], stress_out, "volume under a 100 MPa stress limit"),
                       (axes[1], compliance_out, "compliance at the same volume")):
    with h5py.File(os.path.join(out, "design.h5"), "r") as f:
        steps = sorted((k for k in f if k.startswith("step_")), key=lambda s: int(s[5:]))
        last = f[steps[-1]]
        X, T = f["mesh/geometry"][:], f["mesh/topology"][:]
        rho, vm = last["physical_density"][:], last["von_mises"][:]
    c = X[T].mean(axis=1)
    layer = (c[:, 2] <= c[:, 2].min() + 1e-9) & (rho >= 0.5)
    s = json.load(open(os.path.join(out, "summary.json")))
    st = s["problem"]["stress"][-1]
    sc = ax.scatter(1e3 * c[layer, 0], 1e3 * c[layer, 1], c=vm[layer] / 1e6, s=5, marker="s", cmap="jet",
                    vmin=0, vmax=max(1.8 * limit, st["peak"]) / 1e6)
    ax.set_aspect("equal")
    ax.set_xlim(0, 100)
    ax.set_ylim(0, 100)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(f"{title}\nvolume {s['volume_fraction']:.3f}, peak {st['peak'] / 1e6:.0f} MPa")
fig.colorbar(sc, ax=axes, label="von Mises stress [MPa]")
fig.savefig(figure, dpi=90)
print("wrote", figure)
