#!/usr/bin/python3
"""Where FFRF fails and ACF does not: cases/kane_beam (the spin-up beam at w_s = 6 rad/s, above
its first bending frequency 3.80 rad/s; Kane, Ryan & Banerjee 1987) run three ways on 2 ranks:

  - ACF (the case as it is): bounded, minimum tip deflection -0.5744 m at t = 6.76 s within 5 %
    (shared/REFERENCES.md: a converged beam model with centrifugal stiffening), and a residual
    oscillation after T_s = 15 s of a few mm (below 1 cm);
  - FFRF without geometric stiffening: the spurious divergence, |tip deflection| > 1 m before
    T_s (the centrifugal softening -theta'^2 rho A L makes the bending stiffness negative);
  - FFRF with geometric stiffening: close to ACF (minimum within 2 % of ACF's, the two
    formulations' discretization difference being -0.6 % and +0.1 % of the reference).

usage: check_kane_beam.py --flexopt BIN --out DIR"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import check_arguments, finish, run_variant  # noqa: E402

CASE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "cases", "kane_beam")
REFERENCE, T_REFERENCE = -0.5744, 6.76


def tip(summary):
    s = summary["sensors"]["tip_elastic"]
    return s["t"], [v[1] for v in s["value"]]


def minimum(t, y, t_max):
    i = min((k for k in range(len(t)) if t[k] <= t_max), key=lambda k: y[k])
    return y[i], t[i]


def main():
    a = check_arguments()
    failures = []
    ffrf = "model: ffrf\n    reduction: {modes: 8, geometric_stiffening: %s}"
    acf_t, acf_y = tip(run_variant(a.flexopt, CASE, a.out, "acf", []))
    lin_t, lin_y = tip(run_variant(a.flexopt, CASE, a.out, "ffrf_linear",
                                   [("model: acf", ffrf % "false")], end=15.0))
    stf_t, stf_y = tip(run_variant(a.flexopt, CASE, a.out, "ffrf_stiffened",
                                   [("model: acf", ffrf % "true")]))
    m_acf, tm_acf = minimum(acf_t, acf_y, 15.0)
    m_stf, tm_stf = minimum(stf_t, stf_y, 15.0)
    residual = max(abs(y) for t, y in zip(acf_t, acf_y) if t >= 15.0)
    peak_lin = max(abs(y) for t, y in zip(lin_t, lin_y) if t <= 15.0)
    print(f"ACF:             minimum {m_acf:.5f} m at t = {tm_acf:.2f} s "
          f"({100 * (m_acf / REFERENCE - 1):+.2f} % against {REFERENCE} m at {T_REFERENCE} s); "
          f"after T_s max |v| = {1e3 * residual:.2f} mm")
    print(f"FFRF linear:     max |v| before T_s = {peak_lin:.3g} m")
    print(f"FFRF stiffened:  minimum {m_stf:.5f} m at t = {tm_stf:.2f} s "
          f"({100 * (m_stf / m_acf - 1):+.2f} % against ACF)")
    if not abs(m_acf / REFERENCE - 1) <= 0.05 or not abs(tm_acf - T_REFERENCE) <= 0.3:
        failures.append("ACF minimum not within 5 % / 0.3 s of the reference")
    if not residual < 0.01:
        failures.append("ACF residual oscillation after T_s not below 1 cm")
    if not peak_lin > 1.0:
        failures.append("linear FFRF did not show its divergence (|v| > 1 m before T_s)")
    if not abs(m_stf / m_acf - 1) <= 0.02:
        failures.append("stiffened FFRF not within 2 % of ACF")
    finish(failures)


if __name__ == "__main__":
    main()
