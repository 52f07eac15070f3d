#!/usr/bin/python3
"""Plots the densities of plate-like designs seen along z: per cell of a regular x-y grid, the
mean physical density of the elements whose centroids fall in it (the average through the
thickness). One panel per design, stacked.

Usage: plot_design.py OUT.png DESIGN.h5[:STEP][=TITLE] [DESIGN.h5[:STEP][=TITLE] ...] [--cell 0.004]
STEP is the index of the saved iteration in design.h5 (default: the last one).
"""
import argparse
import re

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def load(spec):
    title = None
    if "=" in spec:
        spec, title = spec.split("=", 1)
    step = None
    m = re.match(r"(.*\.h5):(\d+)$", spec)
    if m:
        spec, step = m.group(1), int(m.group(2))
    with h5py.File(spec, "r") as f:
        steps = sorted(int(k[5:]) for k in f if k.startswith("step_"))
        k = steps[-1] if step is None else step
        xyz = f["mesh/geometry"][...]
        top = f["mesh/topology"][...]
        rho = f[f"step_{k}/physical_density"][...]
    corners = 4 if top.shape[1] in (4, 10) else 8  # Tet4/Tet10 or Hex8: the corner nodes first
    centroid = xyz[top[:, :corners]].mean(axis=1)
    return centroid, rho, title or f"{spec} (saved step {k})"


def image(centroid, rho, cell):
    x0, y0 = centroid[:, 0].min(), centroid[:, 1].min()
    i = np.floor((centroid[:, 0] - x0) / cell).astype(int)
    j = np.floor((centroid[:, 1] - y0) / cell).astype(int)
    total = np.zeros((j.max() + 1, i.max() + 1))
    count = np.zeros_like(total)
    np.add.at(total, (j, i), rho)
    np.add.at(count, (j, i), 1)
    img = np.full_like(total, np.nan)
    img[count > 0] = total[count > 0] / count[count > 0]
    extent = [x0, x0 + cell * (i.max() + 1), y0, y0 + cell * (j.max() + 1)]
    return img, extent


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("designs", nargs="+")
    ap.add_argument("--cell", type=float, default=0.004, help="grid cell [m] (a few element sizes: every cell holds centroids)")
    a = ap.parse_args()
    fig, axes = plt.subplots(len(a.designs), 1, figsize=(9, 1.6 * len(a.designs) + 0.4), squeeze=False)
    for ax, spec in zip(axes[:, 0], a.designs):
        c, rho, title = load(spec)
        img, extent = image(c, rho, a.cell)
        ax.imshow(img, origin="lower", extent=extent, cmap="gray_r", vmin=0, vmax=1, interpolation="nearest")
        ax.set_title(title, fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    fig.savefig(a.out, dpi=130)


if __name__ == "__main__":
    main()
