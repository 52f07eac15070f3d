#!/usr/bin/python3
"""Command-line contract of flexopt: help texts, argument errors, option precedence
(program default < case `solver:` < command line), `info` partition figures, --out, and
`info` on the settings a body's model leaves unused."""
import json
import os
import re
import subprocess
import sys
import tempfile
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

FLEXOPT, SOURCE = sys.argv[1], sys.argv[2]
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
CASE = os.path.join(SOURCE, "cases", "cantilever")
failures = []


def run(args, ranks=None):
    cmd = (["mpirun", "-n", str(ranks)] if ranks else []) + [FLEXOPT] + args
    p = mpi_job.run(cmd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=300)
    return p.returncode, p.stdout, p.stderr


def expect(cond, what):
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    if not cond:
        failures.append(what)


rc, out, _ = run(["--help"])
expect(rc == 0 and "usage: flexopt <command> CASE" in out, "flexopt --help prints usage, exit 0")
expect(all(f"flexopt {cmd} cases/" in out for cmd in ("optimize", "plan", "simulate")),
       "the usage's examples run optimize, plan and simulate")
for cmd in ["info", "simulate", "modes", "optimize", "plan", "check-gradient"]:
    rc, out, _ = run([cmd, "--help"])
    expect(rc == 0 and f"usage: flexopt {cmd}" in out, f"flexopt {cmd} --help")
# Under mpirun the texts printed before MPI starts (help, argument errors) come once, from rank 0.
rc, out, _ = run(["--help"], ranks=2)
expect(rc == 0 and out.count("usage: flexopt <command> CASE") == 1, "mpirun -n 2 flexopt --help prints once")
rc, _, err = run(["optimise", CASE], ranks=2)
expect(rc != 0 and err.count("unknown command 'optimise'") == 1,
       "mpirun -n 2: an unknown command is reported once, non-zero exit")
rc, _, err = run(["optimise", CASE])
expect(rc == 2 and "unknown command 'optimise'" in err, "unknown command: exit 2 with a message")
rc, _, err = run(["modes", CASE, "--count", "zero"])
expect(rc == 2 and "--count needs a positive integer" in err, "bad --count: exit 2 with a message")
rc, _, err = run(["simulate", CASE, "--bogus"])
expect(rc == 2 and "unknown option '--bogus'" in err, "unknown --option: exit 2")
rc, _, err = run(["simulate"])
expect(rc == 2 and "missing CASE" in err, "missing case directory: exit 2")

with tempfile.TemporaryDirectory() as tmp:
    # info: partition covers all elements; --out is honoured.
    rc, out, err = run(["info", CASE, "--out", os.path.join(tmp, "info")], ranks=2)
    s = json.load(open(os.path.join(tmp, "info", "summary.json")))
    b = s["bodies"][0]
    expect(rc == 0 and sum(b["elements_per_rank"]) == b["elements"] == s["elements"],
           "info: elements per rank sum to the element count")
    expect(sum(b["nodes_per_rank"]) * 3 == b["dofs"] == s["dofs"] and min(b["elements_per_rank"]) > 0,
           "info: owned nodes per rank sum to the node count; both ranks have elements")
    expect(b["element_type"] == "Tet10" and "rank 1:" in out, "info: element type and per-rank lines printed")
    # The case asks for MUMPS (1 'iteration'); the command line overrides it with CG + GAMG.
    rc, _, _ = run(["simulate", CASE, "--out", os.path.join(tmp, "lu")], ranks=2)
    lu = json.load(open(os.path.join(tmp, "lu", "summary.json")))
    rc2, _, _ = run(["simulate", CASE, "--out", os.path.join(tmp, "cg"), "-ksp_type", "cg", "-pc_type", "gamg",
                     "-ksp_rtol", "1e-10"], ranks=2)
    cg = json.load(open(os.path.join(tmp, "cg", "summary.json")))
    expect(rc == 0 and lu["solver_iterations"] == 1, "case solver string applied (direct solve, 1 iteration)")
    expect(rc2 == 0 and cg["solver_iterations"] > 1, "command-line options override the case's solver string")
    # Same answer from both solvers. The CG error in compliance is quadratic in the residual
    # (1e-20 here); the LU forward error is kappa(K) eps: measured 2.4e-10 on this case
    # (CG converged to rtol 1e-6 ... 1e-12 gives the same 16 digits). Hence 1e-9.
    rel = abs(cg["compliance"] - lu["compliance"]) / lu["compliance"]
    expect(rel < 1e-9, f"CG+GAMG and MUMPS compliance agree ({rel:.2e} < 1e-9)")
    expect(os.path.exists(os.path.join(tmp, "lu", "static.xdmf")) and
           not any(f.endswith(".tmp") for f in os.listdir(os.path.join(tmp, "lu"))),
           "static.xdmf written, no temporary files left")

with tempfile.TemporaryDirectory() as tmp:
    # One word switches a body's model: cases/slider_crank_flexible with the rod's `model: ffrf`
    # changed; info names the rod's settings that the new model does not use.
    src = os.path.join(SOURCE, "cases", "slider_crank_flexible")
    text = open(os.path.join(src, "case.yaml")).read()
    text = re.sub(r"geometry: ../../meshes/", "geometry: " + os.path.join(SOURCE, "meshes") + "/", text)

    def variant(name, replace):
        """A copy of the case with each (old, new) of `replace` applied (old occurs once)."""
        d = os.path.join(tmp, name)
        os.makedirs(d)
        t = text
        for old, new in replace:
            assert t.count(old) == 1, old
            t = t.replace(old, new)
        open(os.path.join(d, "case.yaml"), "w").write(t)
        return d

    expected = {"ffrf": [], "acf": ["reduction.modes"],
                "rigid": ["reduction.modes", "reduction.frame", "initial.elastic_displacement",
                          "initial.elastic_velocity"]}
    for model, unused in expected.items():
        d = variant(model, [("model: ffrf", "model: " + model)])
        rc, out, err = run(["info", d, "--out", os.path.join(d, "out")], ranks=2)
        s = json.load(open(os.path.join(d, "out", "summary.json"))) if rc == 0 else {"bodies": []}
        rod = [b for b in s["bodies"] if b["name"] == "rod"]
        expect(rc == 0 and rod and rod[0]["model"] == model and rod[0]["unused_settings"] == unused,
               f"info, rod model: {model}: unused settings {unused} in summary.json")
        notes = [line.strip() for line in out.splitlines() if "settings not used" in line]
        expect(notes == ([f"body rod (model: {model}): settings not used by this model: "
                          + ", ".join(k + (" (ffrf)" if k == "reduction.modes" else " (ffrf, acf)") for k in unused)]
                         if unused else []),
               f"info, rod model: {model}: the unused settings printed once, under the rod: {notes}")
    # An unused section is still checked: a typo in it is refused, the key named, on every rank.
    d = variant("typo", [("model: ffrf", "model: acf"),
                         ("reduction: {modes: 4, frame: chord}", "reduction: {mode: 4, frame: chord}")])
    rc, out, err = run(["info", d, "--out", os.path.join(d, "out")], ranks=2)
    expect(rc != 0 and "unknown key 'bodies[1].reduction.mode'" in err
           and not os.path.exists(os.path.join(d, "out", "summary.json")),
           "info: a typo in a section the model does not use is refused, the key named")

# A .msh file cut short anywhere is refused with one message, never read as a smaller mesh.
# tests/msh/beam_0.1.msh: meshes/beam.geo at size 0.1, written by Gmsh 4.8 as MSH 4.1.
MSH = os.path.join(SOURCE, "tests", "msh", "beam_0.1.msh")
MSH_CASE = """analysis: static
materials:
  steel: {E: 2.1e11, nu: 0.3, density: 7850}
bodies:
  - {name: beam, geometry: beam.msh, material: steel}
supports:
  - {body: beam, surface: clamp, fix: [x, y, z]}
"""
with open(MSH) as f:
    lines = f.read().splitlines(keepends=True)
sections = {l.strip(): i for i, l in enumerate(lines) if l.startswith("$")}
cuts = {  # name -> number of whole lines kept, then a partial line of `extra` characters
    "in $MeshFormat": (1, 0),
    "in $PhysicalNames": (sections["$PhysicalNames"] + 2, 0),
    "in $Entities": ((sections["$Entities"] + sections["$EndEntities"]) // 2, 5),
    "in $Nodes": ((sections["$Nodes"] + sections["$EndNodes"]) // 2, 0),
    "before $EndNodes": (sections["$EndNodes"], 0),
    "in the $Elements header": (sections["$Elements"] + 1, 4),
    "in the volume elements": ((sections["$Elements"] + 3 * sections["$EndElements"]) // 4, 8),
    "at a line end in the volume elements": (sections["$EndElements"] - 5, 0),
}
# (A file that lacks only its last line, $EndElements, holds the whole mesh, and Gmsh reads it.)
with tempfile.TemporaryDirectory() as tmp:
    def info_on(text, name):
        case = os.path.join(tmp, name)
        os.makedirs(case)
        with open(os.path.join(case, "case.yaml"), "w") as f:
            f.write(MSH_CASE)
        with open(os.path.join(case, "beam.msh"), "w") as f:
            f.write(text)
        out_dir = os.path.join(case, "out")
        p = mpi_job.run(["mpirun", "-n", "2", FLEXOPT, "info", case, "--out", out_dir], env=ENV,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=120)
        errors = [l for l in p.stdout.splitlines() if l.startswith("flexopt: error")]
        return p.returncode, errors, os.path.exists(os.path.join(out_dir, "summary.json"))
    rc, errors, summary = info_on("".join(lines), "whole")
    expect(rc == 0 and not errors and summary, "whole .msh file: read (the control)")
    for k, (name, (keep, extra)) in enumerate(cuts.items()):
        text = "".join(lines[:keep]) + lines[keep][:extra]
        rc, errors, summary = info_on(text, f"cut{k}")
        expect(rc != 0 and len(errors) == 1 and not summary,
               f".msh cut {name} ({len(text)} of {len(''.join(lines))} bytes): one error, no summary"
               + (f" [{errors[0]}]" if errors else ""))

print(f"{len(failures)} failed" if failures else "all CLI checks passed")
sys.exit(1 if failures else 0)
