"""The scenes where a method fails (issue 22), shared by tests/check_stability.py and
scripts/study_stability.py: case dicts (scripts/case_variants.case_dict) of cases/ variants."""
import os

from case_variants import case_dict

CASES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "cases")


def soft_pendulum():
    """cases/flexible_pendulum with E = 1e8 Pa (100 times softer), a 0.05 m Tet10 mesh, 1 s at
    1 ms: elastic rotations of 0.26 rad. The bar as the case has it (stiffened FFRF, 8 modes)."""
    c = case_dict(os.path.join(CASES, "flexible_pendulum"))
    c["materials"]["soft"]["E"] = 1.0e8
    c["time"] = {"end": 1.0, "step": 1.0e-3, "rho_inf": 0.9}
    c["bodies"][0]["mesh"] = {"size": 0.05, "order": 2}
    return c


def as_acf(body):
    """Makes a body dict of a case an ACF body (its reduction dropped)."""
    body["model"] = "acf"
    body.pop("reduction", None)


def kane_ffrf(modes, stiffening):
    """cases/kane_beam over 10 s with the beam as FFRF."""
    c = case_dict(os.path.join(CASES, "kane_beam"))
    c["time"]["end"] = 10.0
    c["bodies"][0]["model"] = "ffrf"
    c["bodies"][0]["reduction"] = {"modes": modes, "geometric_stiffening": stiffening}
    return c


def acf_slider_crank(step, rho_inf, steps=10):
    """cases/slider_crank_flexible with the rod as ACF on an 8 mm Tet10 mesh, `steps` steps."""
    c = case_dict(os.path.join(CASES, "slider_crank_flexible"))
    as_acf(c["bodies"][1])
    c["bodies"][1]["mesh"] = {"size": 0.008, "order": 2}
    c["time"] = {"end": steps * step, "step": step, "rho_inf": rho_inf}
    return c
