#!/usr/bin/python3
"""The adjoint gradient of a dynamic response against a closed-form sensitivity
(tests/dynamics/pendulum_sensitivity, docs/testing.md "Dynamic adjoint").

A rigid link hinged at the origin about z under gravity g (-y), released from rest at
phi0 = -pi/2 + theta0. With the element densities rho_e (linear mass, identity filter), its first
moments about the pivot in body axes are A_x = sum_e rho_e a_x,e, A_y = sum_e rho_e a_y,e
(a_e = c int_e (X, Y), c the material density) and its inertia about the axis
J = sum_e rho_e j_e (j_e = c int_e (X^2 + Y^2)); the integrals are exact on a Tet4.

1. The motion about a fixed axis depends on the densities only through (A_x, A_y, J), for the
   discrete solution as for the exact one. So the adjoint gradient of the tip's x at t = T must
   be g_e = c_x a_x,e + c_y a_y,e + c_J j_e to round-off: a least-squares fit leaves a residual
   <= 1e-8 of |g| (an adjoint that is wrong anywhere — a wrong inertia term, a wrong first
   moment, a missing initial-state term — leaves a residual or wrong coefficients).
2. The coefficients are dx(T)/dA_x, dx(T)/dA_y, dx(T)/dJ of the generalized-alpha solution;
   they converge at second order in h to those of the small-angle oscillator
   psi'' = -w^2 psi, w^2 = g A / J (psi = phi + beta + pi/2, beta = atan2(A_y, A_x),
   A = |(A_x, A_y)|), where x(T) = sin(psi(T) - beta) ~ (theta0 + beta) cos(w T) - beta, which at
   A_y = 0 gives
     dx/dA_x = -theta0 T sin(w T) g / (2 w J),   dx/dJ = theta0 T sin(w T) w / (2 J),
     dx/dA_y = (cos(w T) - 1) / A_x.
   theta0 = 1e-3 puts the small-angle model's own error (relative theta0^2 / 16 in w) near
   1e-7, below the h-error. Asserted: every coefficient within 1e-3 (relative) of the closed
   form at h = 2 ms, and halving h to 1 ms divides the largest difference at least 3-fold
   (order > 1.58; the expected order is 2). The response x(T) itself likewise within 1e-3.
Usage: check_pendulum_sensitivity.py FLEXOPT SOURCE_DIR OUT RANKS
"""
import json
import math
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

flexopt, source, out, ranks = sys.argv[1:5]
case_dir = os.path.join(source, "tests", "dynamics", "pendulum_sensitivity")
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
failures = 0
g, density, theta0, T = 9.81, 7850.0, 1.0e-3, 1.0


def check(ok, what):
    global failures
    print(("ok    " if ok else "FAIL  ") + what)
    failures += 0 if ok else 1


def run(h):
    d = os.path.join(out, f"h{h:g}")
    os.makedirs(d)
    text = open(os.path.join(case_dir, "case.yaml")).read()
    text = text.replace("../../../meshes/", os.path.join(source, "meshes") + "/")
    text = text.replace("step: 2.0e-3", f"step: {h!r}")
    open(os.path.join(d, "case.yaml"), "w").write(text)
    p = mpi_job.run(["mpirun", "-n", ranks, flexopt, "simulate", d, "--gradient", "--out",
                        os.path.join(d, "out")], env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True, timeout=600)
    print(p.stdout[-1500:])
    if p.returncode != 0:
        sys.exit(f"FAIL: simulate --gradient at h = {h} exited with {p.returncode}")
    s = json.load(open(os.path.join(d, "out", "summary.json")))
    with h5py.File(os.path.join(d, "out", "gradient.h5"), "r") as f:
        X = f["mesh/geometry"][()]
        tets = f["mesh/topology"][()]
        grad = f["step_0/gradient_objective"][()]
    return s["responses"]["objective"], X, tets, grad


def element_integrals(X, tets):
    """a_x,e, a_y,e and j_e of every element (exact for a Tet4)."""
    P = X[tets]                                      # (ne, 4, 3)
    V = np.abs(np.einsum("ei,ei->e", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]),
                         P[:, 3] - P[:, 0])) / 6
    first = density * V[:, None] * P.mean(axis=1)    # c int X over each element
    second = density * V[:, None] / 20 * ((P**2).sum(axis=1) + P.sum(axis=1)**2)
    return np.column_stack([first[:, 0], first[:, 1], second[:, 0] + second[:, 1]])


errors = []
for h in (2e-3, 1e-3):
    value, X, tets, grad = run(h)
    G = element_integrals(X, tets)
    Ax, Ay, J = 0.5 * G.sum(axis=0)
    check(abs(Ay) <= 1e-12 * Ax, f"the link's first moment A_y = {Ay:.2e} vanishes (symmetric)")
    w = math.sqrt(g * Ax / J)
    s, c = math.sin(w * T), math.cos(w * T)
    exact = np.array([-theta0 * T * s * g / (2 * w * J), (c - 1) / Ax, theta0 * T * s * w / (2 * J)])
    x = theta0 * c
    coef, *_ = np.linalg.lstsq(G, grad, rcond=None)
    residual = np.linalg.norm(grad - G @ coef) / np.linalg.norm(grad)
    err = np.abs(coef / exact - 1)
    verr = abs(value / x - 1)
    print(f"h = {h:g}: w = {w:.9f} rad/s; coefficients (dx/dA_x, dx/dA_y, dx/dJ) adjoint "
          f"{coef} closed form {exact}; relative differences {err}; fit residual {residual:.2e}; "
          f"x(T) = {value:.9e} (closed form {x:.9e}, {verr:.2e})")
    check(residual <= 1e-8, f"h = {h:g}: the gradient is a combination of a_x, a_y, j "
                            f"(residual {residual:.2e} <= 1e-8)")
    check(err.max() <= 1e-3, f"h = {h:g}: coefficients within 1e-3 of the closed form "
                             f"(max {err.max():.2e})")
    check(verr <= 1e-3, f"h = {h:g}: x(T) within 1e-3 of the closed form ({verr:.2e})")
    errors.append(err.max())
ratio = errors[0] / errors[1]
check(ratio >= 3, f"halving h divides the largest coefficient difference by {ratio:.2f} "
                  "(>= 3; order 2: 4)")
sys.exit(1 if failures else 0)
