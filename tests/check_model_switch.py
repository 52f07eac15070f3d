#!/usr/bin/python3
"""One word switches a body's model: cases/slider_crank_flexible, whose rod carries the settings
of FFRF (reduction: chord frame, 4 modes) and the initial elastic fields, run for a short time
with only the rod's `model: ffrf` changed to `rigid` and to `acf` (2 ranks each).

Checks, per model:
- the run succeeds and reports the rod as that model;
- it names the settings the model does not use, on rank 0 ("note: body rod (model: acf):
  settings not used by this model: reduction.modes (ffrf)") and in summary.json
  (bodies[].unused_settings): rigid leaves the reduction (its modes and frame) and both elastic
  fields unused, acf the modes (it measures its elastic displacement in the reduction's frame,
  docs/theory.md 8.4), ffrf nothing;
- unused means unused: the rigid run with the FFRF settings deleted from case.yaml gives the
  same sensor values to round-off (1e-12 m; the two runs do the same arithmetic);
- the models move the slider as their rods allow: at TIME_END the rigid rod's slider trails the
  FFRF rod's by the axial stretch at t = 0 that the rigid rod lacks (the case's
  elastic_displacement at the wrist pin, 1.693e-5 m; within 10 %, as the axial force changes
  it), and FFRF and ACF, which start from the same stretched rod, agree to 1e-6 m (6 % of the
  stretch; their bending, up to 2e-4 m at the mid-point over the published run, barely moves
  the wrist pin this early);
- rho_inf = 1 is warned about once with the FFRF rod and not with the rigid one.

usage: check_model_switch.py --flexopt BIN --out DIR"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import check_arguments, finish, run_variant  # noqa: E402

CASE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "cases",
                    "slider_crank_flexible")
TIME_END = 1.0e-4  # 10 steps of 1e-5 s: the ACF rod (10k DOFs) takes a few seconds
STRETCH = 1.69327969e-5  # the case's elastic_displacement x-component at the wrist pin (x = 0.3)
UNUSED = {"ffrf": [], "acf": ["reduction.modes"],
          "rigid": ["reduction.modes", "reduction.frame", "initial.elastic_displacement",
                    "initial.elastic_velocity"]}
NOTE = {"acf": "note: body rod (model: acf): settings not used by this model: reduction.modes (ffrf)",
        "rigid": "note: body rod (model: rigid): settings not used by this model: reduction.modes (ffrf), "
                 "reduction.frame (ffrf, acf), initial.elastic_displacement (ffrf, acf), "
                 "initial.elastic_velocity (ffrf, acf)"}


def rod(summary):
    return next(b for b in summary["bodies"] if b["name"] == "rod")


def max_sensor_difference(a, b):
    """Largest |a - b| over every sensor, sample and component."""
    return max(abs(x - y) for name in a["sensors"]
               for va, vb in zip(a["sensors"][name]["value"], b["sensors"][name]["value"])
               for x, y in zip(va, vb))


def main():
    a = check_arguments()
    failures = []

    def expect(cond, what):
        print(("ok    " if cond else "FAIL  ") + what, flush=True)
        if not cond:
            failures.append(what)

    runs = {}
    for model in ["ffrf", "acf", "rigid"]:
        replace = [("model: ffrf", "model: " + model)] if model != "ffrf" else []
        runs[model], log = run_variant(a.flexopt, CASE, a.out, model, replace, end=TIME_END,
                                       output=True)
        r = rod(runs[model])
        expect(r["model"] == model, f"{model}: the rod runs as {r['model']}")
        expect(r["unused_settings"] == UNUSED[model],
               f"{model}: unused settings {r['unused_settings']} (expected {UNUSED[model]})")
        notes = [line for line in log.splitlines() if line.startswith("note: body rod")]
        expect(notes == ([NOTE[model]] if model in NOTE else []),
               f"{model}: the note on unused settings printed once: {notes}")

    # The rigid rod with the FFRF settings deleted instead of left unused.
    text = open(os.path.join(CASE, "case.yaml")).read()
    fields = text[text.index("      elastic_displacement:"):text.index("  - name: slider")]
    bare, _ = run_variant(a.flexopt, CASE, a.out, "rigid_bare",
                          [("model: ffrf", "model: rigid"),
                           ("    reduction: {modes: 4, frame: chord}\n", ""), (fields, "")],
                          end=TIME_END, output=True)
    diff = max_sensor_difference(runs["rigid"], bare)
    expect(diff <= 1e-12, f"rigid with unused FFRF settings = rigid without them ({diff:.1e} m)")

    x3 = {m: s["sensors"]["end_b"]["value"][-1][0] for m, s in runs.items()}
    print("slider x at t = %g s: " % TIME_END + ", ".join(f"{m} {x:.9f}" for m, x in x3.items()))
    lag = x3["ffrf"] - x3["rigid"]
    expect(abs(lag / STRETCH - 1) < 0.1,
           f"the rigid rod's slider trails FFRF's by the stretch: {lag:.4e} m ({STRETCH:.4e} m, 10 %)")
    gap = abs(x3["acf"] - x3["ffrf"])
    expect(gap < 1e-6, f"FFRF and ACF sliders agree: {gap:.1e} m < 1e-6 m")

    # rho_inf = 1 with a flexible body gets a warning (docs/theory.md 6.4), a rigid rod none.
    for model in ["ffrf", "rigid"]:
        replace = [("rho_inf: 0.8", "rho_inf: 1.0")] + (
            [("model: ffrf", "model: " + model)] if model != "ffrf" else [])
        _, log = run_variant(a.flexopt, CASE, a.out, model + "_rho1", replace, end=2e-5,
                             output=True)
        warned = [line for line in log.splitlines() if line.startswith("time: warning: rho_inf = 1")]
        expect(len(warned) == (1 if model == "ffrf" else 0),
               f"{model}, rho_inf = 1: {len(warned)} warning(s) on the undamped scheme")
    finish(failures)


if __name__ == "__main__":
    main()
