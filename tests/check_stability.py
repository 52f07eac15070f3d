#!/usr/bin/python3
"""Where a method fails, and that `flexopt plan` says so (issue 22's stability map; the figures
are drawn by scripts/study_stability.py, docs/benchmarks.md "Where each method fails").

  large_rotation  FFRF at large elastic rotation against ACF. cases/flexible_pendulum with the
                  bar 100 times softer (E = 1e8 Pa: first frequency 0.62 Hz, the tip swings
                  0.2 m off the pin frame's axis, elastic rotations of 0.26 rad), 1 s at 1 ms.
                  plan --auto picks ACF (rotation^2 > accuracy); the plan of the scene as given
                  with FFRF (stiffened, 8 modes) warns of FFRF's small-deformation assumption;
                  and the two runs differ: FFRF's deepest tip deflection is more than 50 % off
                  ACF's (measured -0.86 m against -0.20 m: the linear strain of the floating frame
                  stretches the bar as it bends, and the bar's own weight then bends it further).
  linear_spin     Linear FFRF above the first bending frequency: cases/kane_beam (6 rad/s against
                  3.8 rad/s) with the beam as linear FFRF, 4 modes, over 10 s. The plan warns
                  "linear FFRF will diverge"; the run does: its tip deflection exceeds ten times
                  the stiffened run's largest (measured 69.5 m against 0.57 m).
  acf_rho1        ACF at rho_inf = 1 with a step that does not resolve the mesh's highest
                  frequencies: cases/slider_crank_flexible with the rod as ACF (8 mm Tet10 mesh:
                  its highest frequency is bounded by 3.6 MHz, h w_max = 2,260 at h = 0.1 ms),
                  10 steps of 0.1 ms. The plan warns at rho_inf = 1 (not at 0.8); Newton needs
                  more than four times the iterations per step at rho_inf = 1 than at 0.8
                  (measured 92 against 14: the first step's 65, from the published initial
                  elastic velocities, then ~9 per step while rho_inf = 0.8 damps what that start
                  excites; at 1 nothing does, and every step takes 85-107).

usage: check_stability.py --flexopt BIN --out DIR --part large_rotation|linear_spin|acf_rho1
"""
import argparse
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import finish, write_case  # noqa: E402
from stability_scenes import acf_slider_crank, as_acf, kane_ffrf, soft_pendulum  # noqa: E402
from study_run import ENV  # noqa: E402
import mpi_job  # noqa: E402

from check_common import expect as check, failures  # noqa: E402


def flexopt(a, command, d, *extra):
    out = os.path.join(d, "out_" + command)
    cmd = ["mpirun", "-n", "2", a.flexopt, command, d, "--out", out] + list(extra)
    print("$ " + " ".join(cmd), flush=True)
    r = mpi_job.run(cmd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    print(r.stdout[-3000:])
    if r.returncode != 0:
        sys.exit(f"FAIL: {' '.join(cmd)} exits {r.returncode}")
    return json.load(open(os.path.join(out, "summary.json")))


def body_plan(summary, body):
    return next(p for p in summary["plan"] if p["body"] == body)


def tip_y(summary):
    return [v[1] for v in summary["sensors"]["tip_elastic"]["value"]]


def large_rotation(a):
    c = soft_pendulum()
    bar = c["bodies"][0]
    given = write_case(c, os.path.join(a.out, "soft_pendulum_ffrf"))
    p = body_plan(flexopt(a, "plan", given, "--auto"), "bar")
    rot = p["estimates"]["rotation_rad"]
    check(p["recommended"] == "acf",
          f"soft pendulum: plan --auto picks {p['recommended']} (acf expected; elastic rotation "
          f"{rot:.3g} rad, rotation^2 {rot * rot:.3g} > 0.01)")
    p = body_plan(flexopt(a, "plan", given), "bar")
    check(any("small-deformation" in w for w in p["warnings"]),
          f"soft pendulum given as FFRF: the plan warns of the small-deformation assumption "
          f"({p['warnings']})")
    ffrf = min(tip_y(flexopt(a, "simulate", given)))
    as_acf(bar)
    acf = min(tip_y(flexopt(a, "simulate", write_case(c, os.path.join(a.out, "soft_pendulum_acf")))))
    check(abs(ffrf - acf) > 0.5 * abs(acf),
          f"soft pendulum: FFRF's deepest tip deflection {ffrf:.4g} m is more than 50 % off "
          f"ACF's {acf:.4g} m ({100 * (ffrf / acf - 1):+.0f} %)")


def linear_spin(a):
    c = kane_ffrf(4, False)
    beam = c["bodies"][0]
    linear = write_case(c, os.path.join(a.out, "kane_linear"))
    p = body_plan(flexopt(a, "plan", linear), "beam")
    check(any("will diverge" in w for w in p["warnings"]),
          f"kane_beam as linear FFRF: the plan warns that it diverges ({p['warnings']})")
    y_linear = max(abs(v) for v in tip_y(flexopt(a, "simulate", linear)))
    beam["reduction"]["geometric_stiffening"] = True
    stiff = write_case(c, os.path.join(a.out, "kane_stiffened"))
    y_stiff = max(abs(v) for v in tip_y(flexopt(a, "simulate", stiff)))
    check(y_linear > 10 * y_stiff,
          f"kane_beam: linear FFRF's largest tip deflection {y_linear:.3g} m is more than ten "
          f"times the stiffened run's {y_stiff:.3g} m (it diverges)")


def acf_rho1(a):
    per_step = {}
    for rho in (1.0, 0.8):
        c = acf_slider_crank(1.0e-4, rho)
        d = write_case(c, os.path.join(a.out, f"slider_crank_acf_rho{rho:g}"))
        p = body_plan(flexopt(a, "plan", d), "rod")
        warned = any("not damped" in w for w in p["warnings"])
        check(warned == (rho == 1.0),
              f"ACF slider-crank at rho_inf = {rho:g}: the plan {'warns' if warned else 'does not warn'} "
              f"of the undamped highest frequency ({p['estimates'].get('highest_frequency_hz', 0):.3g} Hz)")
        s = flexopt(a, "simulate", d)
        per_step[rho] = s["newton_iterations_total"] / 10
    check(per_step[1.0] > 4 * per_step[0.8],
          f"ACF slider-crank: {per_step[1.0]:.1f} Newton iterations per step at rho_inf = 1 against "
          f"{per_step[0.8]:.1f} at 0.8 (more than 4 times: Newton stalls on the undamped modes)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--flexopt", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--part", required=True, choices=["large_rotation", "linear_spin", "acf_rho1"])
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    {"large_rotation": large_rotation, "linear_spin": linear_spin, "acf_rho1": acf_rho1}[a.part](a)
    finish(failures)


if __name__ == "__main__":
    main()
