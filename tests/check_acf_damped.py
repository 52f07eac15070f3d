#!/usr/bin/python3
"""Stiffness-proportional damping of an ACF body: the welded bar of tests/dynamics/acf_damped
(gravity from rest, b = 1e-3 s, rho_inf = 1 so that the scheme adds no damping) oscillates in its
first bending mode about its static deflection; the logarithmic decrement of that oscillation
gives the damping ratio, which must equal b w / 2 at the simulated angular frequency w.

Usage: check_acf_damped.py FLEXOPT CASE OUT

Amplitudes are half the distance between successive extrema of the tip's elastic y-displacement
(each located by the parabola through three samples), so the static offset drops out; the
decrement is fitted over the extrema after the first period (the higher modes, damped at
b w_k / 2 with w_2 ~ 6 w_1, are gone by then). Tolerance 2 %: the trapezoidal rule's error in
the decay rate is O((w h)^2) ~ 1e-3, the extrema's location error below 1e-4, and the bar's
static sag (1 % of its length) changes the frequency by less than that.
"""
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import run_flexopt  # noqa: E402

B = 1.0e-3


def extrema(t, v):
    """(time, value) of the interior extrema of v(t), refined by the parabola through three
    samples."""
    import numpy as np
    out = []
    for i in range(1, len(v) - 1):
        if (v[i] - v[i - 1]) * (v[i + 1] - v[i]) < 0:
            a, b, c = np.polyfit(t[i - 1:i + 2] - t[i], v[i - 1:i + 2], 2)
            out.append((t[i] - b / (2 * a), c - b * b / (4 * a)))
    return out


def main():
    import numpy as np
    flexopt, case, out = sys.argv[1:4]
    sys.stdout.write(run_flexopt(["mpirun", "-n", "2", flexopt, "simulate", case, "--out", out]))
    tip = json.load(open(os.path.join(out, "summary.json")))["sensors"]["tip_elastic"]
    t, v = np.array(tip["t"]), np.array(tip["value"])[:, 1]
    ext = extrema(t, v)
    te = np.array([e[0] for e in ext])
    amp = np.array([abs(ext[k + 1][1] - ext[k][1]) / 2 for k in range(len(ext) - 1)])
    tm = 0.5 * (te[1:] + te[:-1])
    period = 2 * np.mean(np.diff(te))
    w = 2 * np.pi / period
    keep = tm > period
    # ln A = ln A0 - zeta w_n t with w_n = w / sqrt(1 - zeta^2).
    slope = np.polyfit(tm[keep], np.log(amp[keep]), 1)[0]
    zeta_target = B * w / 2
    zeta = -slope / w * np.sqrt(1 - zeta_target**2)
    rel = abs(zeta / zeta_target - 1)
    print(f"{keep.sum()} half-cycles, w = {w:.4f} rad/s: damping ratio {zeta:.5f} against "
          f"b w / 2 = {zeta_target:.5f}, relative difference {rel:.2e} (limit 2e-2)")
    sys.exit(0 if rel <= 2e-2 else 1)


if __name__ == "__main__":
    main()
