#!/usr/bin/env python3
"""Joint reaction sensors against Newton's second law (tests/dynamics/slider_crank_reactions).

The rigid slider-crank runs one revolution; its sensors give the slider's and the rod's centre
of mass positions and the forces of the wrist pin on the slider and of the crank pin on the rod.
With accelerations a from second differences of the positions over the output steps:

  slider, along the frictionless guide:  F_wrist,x = m_s a_s,x
  rod:                                   F_crank_pin - F_wrist + m_r g = m_r a_G

(the wrist pin pushes the rod with -F_wrist). Both hold to the difference between the
integrator's acceleration and the second difference of positions, O(h^2): measured 7e-6 of the
largest inertial force at h = 0.1 ms; the check allows 1e-4. The multipliers of the index-3
generalized-alpha scheme start with an oscillation that decays as rho_inf^n (Arnold & Bruls
2007; measured 2.5 N, 4e-3 of the rod's force, at step 7): the first 100 steps (0.8^100 = 2e-10)
are left out. The out-of-plane components vanish (planar motion): below 1e-6 N.

(With a flexible rod the second differences do not resolve the rod-slider axial mode, 2.5 kHz
at a 0.1 ms step, so this check is for rigid scenes.)

usage: check_reactions.py FLEXOPT SCENE OUT [--ranks N]
"""
import argparse, json, os, shutil, sys

import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

p = argparse.ArgumentParser()
p.add_argument("flexopt")
p.add_argument("scene")
p.add_argument("out")
p.add_argument("--ranks", type=int, default=1)
a = p.parse_args()

os.makedirs(a.out, exist_ok=True)
cmd = ["mpirun", "-n", str(a.ranks), a.flexopt, "simulate", a.scene, "--out", os.path.join(a.out, "run")]
print(" ".join(cmd), flush=True)
mpi_job.run(cmd, check=True)
s = json.load(open(os.path.join(a.out, "run", "summary.json")))["sensors"]

def series(name):
    return np.array(s[name]["value"], dtype=float)

t = np.array(s["slider"]["t"])
h = t[1] - t[0]
assert np.allclose(np.diff(t), h, rtol=1e-9), "output every step expected"
rho, g = 7850.0, np.array([0, -9.81, 0])
m_s = 0.1 * 0.06 * 0.06 * rho
m_r = 0.5 * 0.04 * 0.04 * rho

SKIP = 100  # the multipliers' start-up oscillation (see above)

def accel(x):  # at the output steps SKIP .. N-2
    return ((x[2:] - 2 * x[1:-1] + x[:-2]) / h**2)[SKIP - 1:]

def mid(x):
    return x[SKIP:-1]

ok = True
def check(name, lhs, rhs, tol):
    global ok
    scale = np.abs(rhs).max()
    err = np.abs(lhs - rhs).max() / scale
    good = err <= tol
    ok &= good
    print(f"{name}: max |lhs - rhs| / max |rhs| = {err:.3e} (allowed {tol:g}; max |rhs| {scale:.4g} N)"
          f" {'ok' if good else 'FAILED'}")

wrist = series("wrist")
a_s = accel(series("slider"))
check("slider: F_wrist,x = m_s a_x", mid(wrist)[:, 0], m_s * a_s[:, 0], 1e-4)
z = np.abs(wrist[:, 2]).max()
print(f"wrist pin out-of-plane force {z:.3e} N (allowed 1e-6)")
ok &= z <= 1e-6
crank = series("crank_pin")
a_g = accel(series("rod_center"))
lhs = mid(crank) - mid(wrist) + m_r * g
for k, axis in enumerate("xy"):
    check(f"rod: F_crank_pin,{axis} - F_wrist,{axis} + m_r g_{axis} = m_r a_G,{axis}",
          lhs[:, k], m_r * a_g[:, k], 1e-4)
sys.exit(0 if ok else 1)
