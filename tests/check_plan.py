#!/usr/bin/env python3
"""`flexopt plan --auto` picks on the case suite (issue 22; docs/theory.md section 12).

Every body of the scene is estimated as if its model were auto, at the case's accuracy (1e-2):

  slider_crank_rigid     every link rigid (steel links at 5 rev/s deflect by micrometres)
  slider_crank_flexible  the rod flexible: its elastic_displacement sensor needs it; ACF at 1e-2
                         (its axial force changes its bending stiffness by ~5-10 %), FFRF at 0.2;
                         ACF also with the case's responses on that sensor (issue 48)
  spin_up_beam           the beam FFRF with geometric stiffening (spun to 4 rad/s, above its
                         first bending frequency of 3.8 rad/s), never linear FFRF
  kane_beam              the beam ACF or FFRF with geometric stiffening (6 rad/s), never linear

and, without --auto, the user's own choice is kept and questioned:

  spin_up_beam with `geometric_stiffening: false` runs linear FFRF as given, with the warning
  that linear FFRF diverges at this spin rate.

Then `simulate` of the rigid slider-crank with every `model:` removed (auto) runs the plan
first, records it in summary.json, and moves exactly as the case with `model: rigid`. Last,
the joints' stress stiffening estimate against Euler's load on the slider-crank held at rest with
an axial force on the slider, and `optimize` with an auto design body (and its --restart).

usage: check_plan.py FLEXOPT CASES OUT [--ranks N]
"""
import argparse, json, os, re, shutil, sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import case_dict, write_case  # noqa: E402
import yaml  # noqa: E402
import mpi_job  # noqa: E402

p = argparse.ArgumentParser()
p.add_argument("flexopt")
p.add_argument("cases")
p.add_argument("out")
p.add_argument("--ranks", type=int, default=2)
a = p.parse_args()
os.makedirs(a.out, exist_ok=True)

ok = True
def check(cond, what):
    global ok
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    ok = ok and cond

def plan(case_dir, name, auto=True):
    out = os.path.join(a.out, name)
    cmd = ["mpirun", "-n", str(a.ranks), a.flexopt, "plan", case_dir, "--out", out]
    if auto:
        cmd.append("--auto")
    print("$ " + " ".join(cmd), flush=True)
    r = mpi_job.run(cmd, capture_output=True, text=True)
    print(r.stdout[-4000:])
    if r.returncode != 0:
        print(r.stderr[-4000:])
        check(False, f"{name}: flexopt plan exits 0")
        return {}
    s = json.load(open(os.path.join(out, "summary.json")))
    return {b["body"]: b for b in s["plan"]}

def case(name):
    return os.path.join(a.cases, name)

# 1. The rigid slider-crank: every body rigid.
bodies = plan(case("slider_crank_rigid"), "slider_crank_rigid")
for body, b in bodies.items():
    check(b["recommended"] == "rigid",
          f"slider_crank_rigid: {body} -> {b['recommended']} (rigid error "
          f"{b.get('estimates', {}).get('rigid_error', 0):.2e})")

# 2. The flexible slider-crank: the crank and slider rigid; the rod flexible, and ACF at the
#    case's accuracy (1e-2): the rod's axial force (up to ~390 N in the rigid motion against its
#    Euler load of 7.49 kN) changes its bending stiffness by ~5-10 %, which linear FFRF leaves out
#    (tests/check_slider_crank_acf.py: FFRF and ACF differ by ~10 % of the deflection; the plan
#    estimates 8.4 %, the speed-accuracy map measures 9.3-9.5 %). At accuracy 0.2 the same
#    estimates accept FFRF (within half the budget). The case as it is (its design section's
#    objective on the rod's elastic_displacement sensor) gets ACF as well: an ACF body measures
#    it in the frame FFRF's basis holds (docs/theory.md section 8.4; before issue 48 the plan
#    kept FFRF there with a warning). A design body keeps the case's mesh.
c = case_dict(case("slider_crank_flexible"))  # without design, objective, constraints
bodies = plan(write_case(c, os.path.join(a.out, "slider_crank_flexible_simulate")), "slider_crank_flexible_simulate")
if bodies:
    e = bodies["rod"]["estimates"]
    check(bodies["rod"]["recommended"] == "acf" and 0.01 < e["stress_stiffening"] < 0.15
          and e["stress_error"] > 0.005,
          f"slider_crank_flexible: rod -> {bodies['rod']['recommended']} (the loads' stress "
          f"stiffening {e['stress_stiffening']:.3g} in (0.01, 0.15), {e['stress_error']:.3g} of "
          f"the sensor > 0.005)")
    # ACF's mesh (docs/theory.md section 12.3): coarser than the case's 4 mm where the coarse
    # mesh's frequencies change the KED deflection by at most accuracy / 4 (the speed-accuracy map:
    # ACF at 16 mm is 0.12 % off the 4 mm run, at 24 mm 0.74 %).
    size = bodies["rod"].get("mesh_size", 0)
    check(0.004 < size <= 0.016 and e.get("acf_dofs", 0) < e["dofs"] / 2,
          f"slider_crank_flexible: the rod's ACF mesh {size} m (the case's 0.004 m; in (0.004, 0.016]), "
          f"{e.get('acf_dofs')} DOFs against {e['dofs']}")
    for body in ("crank", "slider"):
        check(bodies[body]["recommended"] == "rigid", f"slider_crank_flexible: {body} -> {bodies[body]['recommended']}")
c["accuracy"] = 0.2
bodies = plan(write_case(c, os.path.join(a.out, "slider_crank_flexible_0.2")), "slider_crank_flexible_0.2")
if bodies:
    check(bodies["rod"]["recommended"] == "ffrf" and bodies["rod"]["modes"] >= 1,
          f"slider_crank_flexible at accuracy 0.2: rod -> {bodies['rod']['recommended']}, "
          f"{bodies['rod']['modes']} modes")
bodies = plan(case("slider_crank_flexible"), "slider_crank_flexible")
if bodies:
    b = bodies["rod"]
    check(b["recommended"] == "acf" and not b["warnings"] and not b.get("mesh_size"),
          f"slider_crank_flexible with its design responses on the rod's elastic displacement: "
          f"rod -> {b['recommended']} on the case's mesh, no warning ({b['warnings']})")

stiffened = {}
# 3. The spin-up beam: FFRF with geometric stiffening.
bodies = stiffened["spin_up_beam"] = plan(case("spin_up_beam"), "spin_up_beam")
if bodies:
    b = bodies["beam"]
    e = b["estimates"]
    check(e["spin_rad_s"] > 2 * 3.14159 * e["first_frequency_hz"],
          f"spin_up_beam: spin {e['spin_rad_s']:.3f} rad/s above the first frequency "
          f"{2 * 3.14159 * e['first_frequency_hz']:.3f} rad/s")
    check(b["recommended"] == "ffrf" and b["geometric_stiffening"],
          f"spin_up_beam: beam -> {b['recommended']}, stiffening {b['geometric_stiffening']}")

# 3b. Without --auto the case's own model runs and the plan reports what runs: the spin-up
#     beam's `model: ffrf` with `reduction: {modes: 8, geometric_stiffening: true}`, whatever
#     the estimates recommend (recommended_modes).
bodies = plan(case("spin_up_beam"), "spin_up_beam_given", auto=False)
if bodies:
    b = bodies["beam"]
    check(b["given"] == "ffrf" and b["model"] == "ffrf" and b["modes"] == 8 and b["geometric_stiffening"]
          and b["recommended_modes"] >= 1,
          f"spin_up_beam as given: {b['model']}, {b['modes']} modes (the case's 8), stiffening "
          f"{b['geometric_stiffening']}; recommended {b['recommended_modes']} modes")

# 3c. simulate repeats the plan's word on a given model that the estimates disagree with: the
#     flexible slider-crank's rod, given ffrf, is warned that the loads' stress calls for ACF
#     (the same warning as `flexopt plan`), after the run's results.
env = {k: v for k, v in os.environ.items() if k != "FLEXOPT_PLAN_CHECK"}
env["FLEXOPT_REPORT"] = "0"
r = mpi_job.run(["mpirun", "-n", str(a.ranks), a.flexopt, "simulate", case("slider_crank_flexible"), "--out",
                    os.path.join(a.out, "simulate_given")], capture_output=True, text=True, env=env)
warned = [ln for ln in r.stdout.splitlines() if ln.startswith("plan: body rod: warning:")]
check(r.returncode == 0 and warned and "acf" in warned[0] and
      r.stdout.index(warned[0]) > r.stdout.index("summary.json"),
      f"simulate of slider_crank_flexible (rod given ffrf) repeats the plan's warning after its results: {warned[:1]}")

# 4. The Kane beam: ACF or stiffened FFRF, never linear FFRF.
bodies = stiffened["kane_beam"] = plan(case("kane_beam"), "kane_beam")
if bodies:
    b = bodies["beam"]
    check(b["recommended"] == "acf" or (b["recommended"] == "ffrf" and b["geometric_stiffening"]),
          f"kane_beam: beam -> {b['recommended']}, stiffening {b['geometric_stiffening']}")

# 4b. The flexible pendulum (the scene, without its design responses): ACF. Gravity's and the
#    tangential inertia's axial stress (about 1 % of the bar's bending stiffness; the centrifugal
#    part is what stiffened FFRF takes in) drifts the phase of the bar's vibration, rung by its
#    release undeformed under gravity, by several per cent of the tip deflection over the second
#    (every FFRF of the speed-accuracy map misses 1 %, docs/benchmarks.md). On the spin-up and
#    Kane beams, whose stress is the centrifugal one, the same estimate leaves stiffened FFRF
#    (checked above) with far less than half the budget.
c = case_dict(case("flexible_pendulum"))
bodies = plan(write_case(c, os.path.join(a.out, "flexible_pendulum_simulate")), "flexible_pendulum_simulate")
if bodies:
    b = bodies["bar"]
    e = b["estimates"]
    check(b["recommended"] == "acf" and 0.003 < e["stress_stiffening"] < 0.03 and e["stress_error"] > 0.005,
          f"flexible_pendulum: bar -> {b['recommended']} (the loads' stress stiffening "
          f"{e['stress_stiffening']:.3g} in (0.003, 0.03), {e['stress_error']:.3g} of the sensor > 0.005)")
for name, bodies in stiffened.items():
    if bodies:
        e = bodies["beam"]["estimates"]
        check(e["stress_error"] < 0.005 * 0.1,
              f"{name}: stiffened FFRF leaves {e['stress_error']:.2g} of the sensor to the loads' "
              f"other stress (< a tenth of half the budget)")

# 4c. The scene a user writes first: an aluminium bar on a pin with no `mesh:` key (the .geo's own
#     sizes, order 1: 73 Tet4, one across the 2 cm section). Linear tetrahedra lock in bending:
#     the plan warns that the first frequency is far above the same mesh at order 2 (measured
#     89.05 against 16.73 Hz; the Euler-Bernoulli beam 16.45 Hz), and is silent at order 2.
first = {"analysis": "dynamic", "materials": {"alu": {"E": 7.0e10, "nu": 0.33, "density": 2700}},
         "bodies": [{"name": "bar", "model": "auto", "material": "alu", "interfaces": ["pin"],
                     "geometry": os.path.abspath(os.path.join(a.cases, "..", "meshes", "bar.geo"))}],
         "ground": {"interfaces": {"pivot": [0, 0, 0]}},
         "joints": [{"name": "hinge", "type": "revolute", "a": "ground", "a_interface": "pivot", "b": "bar",
                     "b_interface": "pin", "axis": [0, 0, 1]}],
         "loads": {"gravity": [0, -9.81, 0]}, "time": {"end": 1.0, "step": 1.0e-3},
         "sensors": [{"name": "tip_bend", "body": "bar", "point": [1.0, 0, 0], "quantity": "elastic_displacement"}]}
for order in (1, 2):
    if order == 2:
        first["bodies"][0]["mesh"] = {"order": 2}
    bodies = plan(write_case(first, os.path.join(a.out, f"first_bar_order{order}")), f"first_bar_order{order}", auto=False)
    if bodies:
        warned = [w for w in bodies["bar"]["warnings"] if "lock in bending" in w]
        check(bool(warned) == (order == 1),
              f"a first bar at order {order}: {'warned' if warned else 'no warning'} of Tet4 locking "
              f"({warned[0][:120] if warned else ''})")

# 5. A user's linear FFRF on the spin-up beam is kept, with the divergence warning.
lin = os.path.join(a.out, "spin_up_beam_linear")
shutil.rmtree(lin, ignore_errors=True)
shutil.copytree(case("spin_up_beam"), lin, ignore=shutil.ignore_patterns("out"))
text = open(os.path.join(lin, "case.yaml")).read()
text = text.replace("geometry: ../../meshes/", "geometry: " + os.path.join(os.path.abspath(a.cases), "..", "meshes") + "/")
text = text.replace("geometric_stiffening: true", "geometric_stiffening: false")
open(os.path.join(lin, "case.yaml"), "w").write(text)
bodies = plan(lin, "spin_up_beam_linear_plan", auto=False)
if bodies:
    b = bodies["beam"]
    check(b["model"] == "ffrf", f"spin_up_beam linear: the given model runs ({b['model']})")
    check(any("linear FFRF will diverge" in w for w in b["warnings"]),
          "spin_up_beam linear: warns that linear FFRF diverges at this spin rate")

# 6. `simulate` of the rigid slider-crank with every model left to auto: the plan runs first,
#    summary.json records it, and the motion is the rigid case's to round-off.
auto = os.path.join(a.out, "slider_crank_auto")
shutil.rmtree(auto, ignore_errors=True)
shutil.copytree(case("slider_crank_rigid"), auto, ignore=shutil.ignore_patterns("out"))
text = open(os.path.join(auto, "case.yaml")).read()
text = text.replace("geometry: ../../meshes/", "geometry: " + os.path.join(os.path.abspath(a.cases), "..", "meshes") + "/")
text = re.sub(r"\n *model: rigid", "", text)
open(os.path.join(auto, "case.yaml"), "w").write(text)
runs = {}
for name, d in (("given", case("slider_crank_rigid")), ("auto", auto)):
    out = os.path.join(a.out, "simulate_" + name)
    cmd = ["mpirun", "-n", str(a.ranks), a.flexopt, "simulate", d, "--out", out]
    print("$ " + " ".join(cmd), flush=True)
    r = mpi_job.run(cmd, capture_output=True, text=True)
    check(r.returncode == 0, f"simulate ({name}) exits 0")
    if r.returncode == 0:
        runs[name] = (json.load(open(os.path.join(out, "summary.json"))), r.stdout)
if len(runs) == 2:
    s_auto, log = runs["auto"]
    check("plan" in s_auto and all(b["model"] == "rigid" and b["given"] == "auto" for b in s_auto["plan"]),
          "simulate (auto): summary.json plan has every body auto -> rigid")
    check("plan: body crank (auto): rigid" in log, "simulate (auto): prints the plan first")
    worst = 0.0
    for name, sensor in runs["given"][0]["sensors"].items():
        for u, v in zip(sensor["value"], s_auto["sensors"][name]["value"]):
            worst = max(worst, max(abs(x - y) for x, y in zip(u, v)))
    check(worst < 1e-12, f"simulate (auto) equals the rigid case: max sensor difference {worst:.1e} < 1e-12")

# 7. The joints' stress stiffening against Euler: the slider-crank held at rest (crank driven at
#    angle 0, rod along x) with F = 500 N pushing the slider against the rod: the rod carries
#    P = F, and the estimate is P / P_E, P_E = pi^2 E I / L^2 = 7486.6 N for the 0.3 m, 8 x 8 mm
#    steel rod pinned at both ends (what the chord frame's basis is). Within 2 %: the Tet10
#    mesh's bending (its first frequency is 0.11 % below the beam's) and the stress where the
#    pin forces enter through the rigid interfaces (8 mm of 300 mm at each end); measured +0.9 %.
#    The crank and the slider, whose sensors do not move, are measured by their nodes: rigid.
c = case_dict(case("slider_crank_flexible"))
for b in c["bodies"]:
    for k in ("velocity", "angular_velocity", "elastic_displacement", "elastic_velocity"):
        b.get("initial", {}).pop(k, None)
c["bodies"][2]["initial"] = {"position": [0.45, 0, 0]}
c["drivers"] = [{"joint": "main", "value": "0"}]
c["time"] = {"end": 0.01, "step": 1.0e-4, "rho_inf": 0.8}
for F in (500.0, -500.0):
    c["loads"] = {"forces": [{"body": "slider", "interface": "pin", "value": [-F, 0, 0]}]}
    name = f"slider_crank_axial_{F:+.0f}"
    bodies = plan(write_case(c, os.path.join(a.out, name)), name)
    if bodies:
        mu, euler = bodies["rod"]["estimates"]["stress_stiffening"], abs(F) / 7486.6
        check(abs(mu / euler - 1) < 0.02,
              f"{name}: the loads' stress stiffening {mu:.5f} against P / P_E = {euler:.5f} "
              f"({100 * (mu / euler - 1):+.2f} %, within 2 %)")
        check(bodies["crank"]["recommended"] == "rigid" and bodies["slider"]["recommended"] == "rigid",
              f"{name}: crank -> {bodies['crank']['recommended']}, slider -> {bodies['slider']['recommended']}")

# 8. `optimize` with an auto design body (cases/spin_link_topopt, the link's model removed, 2
#    iterations): the plan runs first, summary.json records it, and the optimization runs on the
#    planned model. (check-gradient with an auto body: the ctest gradient.ffrf_pendulum_auto.)
#    At the case's accuracy (1e-2) the plan picks ACF for the link (its payload's centrifugal pull
#    stiffens it by 0.57, 0.02 of its elastic sensor: ACF, whose run of the case takes minutes);
#    at accuracy 0.1 the same estimates accept stiffened FFRF, which runs 2 iterations in seconds.
text = open(os.path.join(case("spin_link_topopt"), "case.yaml")).read()
c = yaml.safe_load(text.replace("    model: ffrf\n", "    model: auto\n", 1))
for b in c["bodies"]:
    b["geometry"] = os.path.abspath(os.path.join(case("spin_link_topopt"), b["geometry"]))
c["optimizer"]["max_iterations"] = 2
c["accuracy"] = 0.1
d = write_case(c, os.path.join(a.out, "optimize_auto"))

def optimize(*extra):
    """`flexopt optimize` of d: the completed process and its summary.json (None if it failed)."""
    cmd = ["mpirun", "-n", str(a.ranks), a.flexopt, "optimize", d, "--out", os.path.join(d, "out"), *extra]
    print("$ " + " ".join(cmd), flush=True)
    r = mpi_job.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        print(r.stdout[-3000:] + r.stderr[-2000:])
        return r, None
    return r, json.load(open(os.path.join(d, "out", "summary.json")))

r, s = optimize()
check(s is not None, "optimize with an auto design body exits 0")
if s is not None:
    p = s.get("plan", [{}])[0]
    check(p.get("given") == "auto" and p.get("model") == "ffrf" and "plan: body link (auto): ffrf" in r.stdout,
          f"optimize (auto): the plan printed first and recorded ({p.get('model')}, {p.get('modes')} modes)")
    check(os.path.exists(os.path.join(d, "out", "design.xdmf")), "optimize (auto): design.xdmf written")
    # --restart plans again (the plan depends on the case, not on the design: a design body is
    # planned with its solid material) and continues on the same model.
    r2, s2 = optimize("--max-iterations", "3", "--restart")
    check(s2 is not None, "optimize --restart with an auto design body exits 0")
    if s2 is not None:
        p2 = s2.get("plan", [{}])[0]
        same = all(p2.get(k) == p.get(k) for k in ("model", "modes", "geometric_stiffening", "mesh_size"))
        n, n2 = len(s.get("objective", [])), len(s2.get("objective", []))
        check(same and "plan: body link (auto)" in r2.stdout and n2 > n and s2["objective"][:n] == s["objective"],
              f"optimize --restart (auto): planned again, the same pick ({p2.get('model')}, {p2.get('modes')} "
              f"modes), the history continued bit for bit ({n} -> {n2} values)")

print("plan picks: " + ("PASSED" if ok else "FAILED"))
sys.exit(0 if ok else 1)
