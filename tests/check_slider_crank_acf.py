#!/usr/bin/python3
"""cases/slider_crank_flexible with the rod as an ACF body (absolute nodal coordinates,
co-rotated Tet10 on a 16 mm mesh at a 20 us step; in the speed-accuracy map, against the beam
model: q1(0.1) +0.21 %, amplitude +0.08 %, x3 -2.2e-6 in 76 s, where 8 mm at 10 us gives +0.21 %,
+0.12 %, -2.4e-6 in 236 s and 24 mm misses q1 by 1.0 %) against the FFRF run of the same scene (the case as it is: chord frame,
4 modes), the published reference (Simeon 1996, shared/REFERENCES.md) and a geometrically exact
beam model of the rod (scripts/reference/slider_crank_beam.py).

1. The published scene (crank at 150 rad/s, the published initial values):
   - slider x3(0.1) within 1e-5 of the published value (a tenth of the rod's axial stretch);
   - the rod's mid-point deflection from the chord q1 within 1 % of the beam model, at
     t = 0.1 s and in amplitude (max |q1| over [0, 0.1 s]). The beam model (64 co-rotational
     Euler-Bernoulli elements, converged to 2e-4) carries the effect of the rod's axial force
     (up to ~700 N against the Euler load 7.5 kN) on its bending, P-delta, which the published
     model and FFRF (linear elasticity in the chord frame) leave out: they differ from the beam
     and from ACF by ~10 % of the amplitude. That difference is asserted (> 5 %): where the
     linear models fail, show it.
2. Small loads (crank at 50 rad/s from the undeformed rigid motion, 1/9 of the inertial loads):
   ACF and FFRF agree to 3 % of the amplitude over the first 0.05 s (the P-delta share falls
   as the square of the speed; the remaining modelling difference is ~0.2 %).

usage: check_slider_crank_acf.py --flexopt BIN --out DIR"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import check_arguments, chord_deflection, finish, run_variant  # noqa: E402

CASE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "cases",
                    "slider_crank_flexible")
X3_REF = 0.1697373326718410  # published x3(0.1)
# scripts/reference/slider_crank_beam.py (64 elements, step 4.1e-7 s): q1(0.1), max |q1|.
Q1_BEAM, AMP_BEAM = 2.32441e-4, 1.56120e-3
# The rod's reduction: stays in the case; an acf rod leaves it unused.
# Every run at 20 us, so that ACF and FFRF are compared sample by sample.
STEP = [("time: {end: 0.1, step: 1.0e-5,", "time: {end: 0.1, step: 2.0e-5,")]
# The small-load runs over 0.05 s (2.5 rad of the crank's turn at 50 rad/s).
SLOW_END = 0.05
ACF = [("model: ffrf", "model: acf"),
       ("mesh: {size: 0.004, order: 2}", "mesh: {size: 0.016, order: 2}")] + STEP


def slow_scene(w):
    """Replacements for the crank at w rad/s from the rigid motion at rest in the chord frame (no
    initial elastic fields): crank pin velocity 0.15 w, rod turning at -w / 2, slider at 0.45 m."""
    text = open(os.path.join(CASE, "case.yaml")).read()
    fields = text[text.index("      elastic_displacement:"):text.index("  - name: slider")]
    return [("initial: {angular_velocity: [0, 0, 150]}", f"initial: {{angular_velocity: [0, 0, {w}]}}"),
            ("velocity: [0, 22.5, 0]", f"velocity: [0, {0.15 * w}, 0]"),
            ("angular_velocity: [0, 0, -74.9957670]", f"angular_velocity: [0, 0, {-0.5 * w}]"),
            (fields, ""),
            ("initial: {position: [0.450016933, 0, 0], velocity: [-2.68938672e-6, 0, 0]}",
             "initial: {position: [0.45, 0, 0]}"),
            ('value: "150*t"', f'value: "{w}*t"')]


def difference(a, b):
    """max |a - b| / max |b| over the common samples (the runs' samples at the same times)."""
    if len(a) != len(b):
        sys.exit(f"FAIL: the runs have {len(a)} and {len(b)} samples: not at the same times")
    return max(abs(x - y) for x, y in zip(a, b)) / max(abs(y) for y in b)


def main():
    a = check_arguments()
    failures = []

    acf = run_variant(a.flexopt, CASE, a.out, "acf", ACF)
    ffrf = run_variant(a.flexopt, CASE, a.out, "ffrf", STEP)
    x3 = acf["sensors"]["end_b"]["value"][-1][0]
    q_acf, q_ffrf = chord_deflection(acf), chord_deflection(ffrf)
    amp = max(abs(q) for q in q_acf)
    pdelta = difference(q_ffrf, q_acf)
    print(f"150 rad/s, t = 0.1 s: slider x3 ACF {x3:.10f}, published {X3_REF:.10f} "
          f"({x3 / X3_REF - 1:+.1e})")
    print(f"  mid-point deflection q1(0.1): ACF {q_acf[-1]:.6e} m, beam {Q1_BEAM:.6e} m "
          f"({100 * (q_acf[-1] / Q1_BEAM - 1):+.2f} %), FFRF {q_ffrf[-1]:.6e} m")
    print(f"  amplitude max |q1|: ACF {amp:.6e} m, beam {AMP_BEAM:.6e} m "
          f"({100 * (amp / AMP_BEAM - 1):+.2f} %), FFRF {max(abs(q) for q in q_ffrf):.6e} m")
    print(f"  FFRF against ACF over the history: {100 * pdelta:.2f} % of the amplitude (P-delta)")
    print(f"  ACF: {acf['integration_s']:.1f} s, {acf['newton_factorizations_total']} "
          f"factorizations; FFRF: {ffrf['integration_s']:.1f} s")
    if not abs(x3 / X3_REF - 1) <= 1e-5:
        failures.append("ACF slider position not within 1e-5 of the published value")
    if not abs(q_acf[-1] / Q1_BEAM - 1) <= 0.01:
        failures.append("ACF q1(0.1) not within 1 % of the beam model")
    if not abs(amp / AMP_BEAM - 1) <= 0.01:
        failures.append("ACF amplitude not within 1 % of the beam model")
    if not pdelta > 0.05:
        failures.append("FFRF (linear) and ACF differ by less than 5 %: the P-delta effect is missing")

    w = 50
    acf = run_variant(a.flexopt, CASE, a.out, f"acf_{w}", slow_scene(w) + ACF, end=SLOW_END)
    ffrf = run_variant(a.flexopt, CASE, a.out, f"ffrf_{w}", slow_scene(w) + STEP, end=SLOW_END)
    small = difference(chord_deflection(acf), chord_deflection(ffrf))
    print(f"{w} rad/s: ACF against FFRF over the history: {100 * small:.2f} % of the amplitude "
          f"(P-delta scaled by ({w}/150)^2: {100 * pdelta * (w / 150) ** 2:.2f} %)")
    if not small <= 0.03:
        failures.append(f"ACF and FFRF differ by more than 3 % at {w} rad/s")
    finish(failures)


if __name__ == "__main__":
    main()
