#!/usr/bin/python3
"""The motion output of a flexible (FFRF) body, read back with ParaView's own XDMF readers.

Usage: paraview_motion_ffrf.py FLEXOPT SRC OUT PVPYTHON   (system Python)
Runs a short variant of cases/flexible_pendulum on 2 ranks (scripts/case_variants.py: 30 ms
instead of 1 s, mesh size 0.02 instead of 0.01 so the reduction takes a few seconds, and two
sensors at the tip corner (1, 0.01, 0.01), a vertex of the box and so a mesh node: its world
position and its elastic displacement). Then runs itself under pvpython (`--check OUT`), which
opens OUT/ffrf/out/motion.xdmf with each of ParaView's .xdmf readers (the three of
tests/paraview_motion.py) and checks against the run's summary.json:

1. the time steps are the frame times (summary.json motion.times), there is one block (the bar), its points are stored in
   double precision and it carries the 3-component point field `elastic_displacement`, zero at
   t = 0 (the bar starts undeformed);
2. at the last step, the corner node's coordinates equal the `corner` position sensor;
3. its `elastic_displacement` equals the `corner_elastic` sensor (body-frame axes) and is not
   small: the bar bends as it starts to fall;
4. every node j is where the floating frame puts it: |x_j - r| = |X_j - o + u_j| (a rotation
   keeps lengths), with X_j the node's position at t = 0, o the frame origin in mesh
   coordinates (summary.json) and r the frame origin's world position, held at the pivot
   (0, 0, 0) by the revolute joint.

Tolerances. motion.h5 stores float64 (docs/output.md), the XDMF says Precision="8" and the
readers keep doubles (checked), so the file adds no error. The sensor and the node value are
the same expression r + A (X - o + Psi zeta) evaluated in a different order: the sensor's basis
comes from interpolating at the point (shape functions at a node are 1 and 0 up to the
round-off of the affine inverse map, ~1e-14), so both agree to a few ulps of 1 m (2.2e-16 m
each). 1e-12 m is used for positions and the field (measured: 0, the values are bit for bit
the same). Check 4 adds the joint's constraint violation (summary.json, ~1e-16 m) to it
(measured: 2.2e-16 m). The times are compared exactly: the XDMF file writes them with %.17g,
which reads back to the same double.
"""
import json
import math
import os
import shutil
import subprocess
import sys

CORNER = (1.0, 0.01, 0.01)  # tip corner of meshes/bar.geo (L = 1, b = 0.02): a mesh vertex
END = 0.03                  # s: 300 steps of 1e-4 s, output every 10 steps = 31 output steps
TOL = 1e-12                 # m, positions and elastic displacement (float64 round-off, above)
# The corner's elastic displacement at t = END is 6.5e-4 m, almost all along y: gravity and the
# inertia of the starting swing load the bar unevenly along its length, so it bends relative to
# its frame clamped at the pin (at the tip centre, mesh size 0.01 gives the same to 0.05 %).
# Requiring 1e-4 m leaves a factor 6 of margin and is 8 orders of magnitude above round-off, so
# an output in which the deformation is lost (zero field, undeformed positions) cannot pass.
MIN_ELASTIC = 1e-4          # m
PIVOT = (0.0, 0.0, 0.0)     # ground interface of the hinge in cases/flexible_pendulum


def run(flexopt, src, out, pvpython):
    sys.path.insert(0, os.path.join(src, "scripts"))
    from case_variants import run_variant
    shutil.rmtree(os.path.join(out, "ffrf"), ignore_errors=True)
    point = "[" + ", ".join(repr(c) for c in CORNER) + "]"
    sensors = (f"  - {{name: corner, body: bar, point: {point}, quantity: position}}\n"
               f"  - {{name: corner_elastic, body: bar, point: {point}, quantity: elastic_displacement}}\n"
               "  - {name: angle")
    run_variant(flexopt, os.path.join(src, "cases", "flexible_pendulum"), out, "ffrf",
                [("size: 0.01", "size: 0.02"), ("  - {name: angle", sensors)], end=END)
    check = [pvpython, "--force-offscreen-rendering", os.path.abspath(__file__), "--check",
             os.path.join(out, "ffrf", "out")]
    print("$ " + " ".join(check), flush=True)
    sys.exit(subprocess.run(check).returncode)


# ---------------------------------------------------------------------------------------------
# pvpython part


failures = []


def expect(cond, what):
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    if not cond:
        failures.append(what)


def leaves(data):
    """Every leaf dataset of a multiblock/multipiece tree, in order."""
    if data is None:
        return []
    if data.IsA("vtkMultiBlockDataSet"):
        return [x for i in range(data.GetNumberOfBlocks()) for x in leaves(data.GetBlock(i))]
    if data.IsA("vtkMultiPieceDataSet"):
        return [x for i in range(data.GetNumberOfPieces()) for x in leaves(data.GetPiece(i))]
    return [data]


def norm(v):
    return math.sqrt(sum(c * c for c in v))


def dist(a, b):
    return norm([x - y for x, y in zip(a, b)])


def check_reader(label, reader, summary):
    from paraview import servermanager
    times = summary["motion"]["times"]
    sensors = summary["sensors"]
    body = summary["bodies"][0]
    nodes = body["dofs"] // 3
    reader.UpdatePipelineInformation()
    steps = list(reader.TimestepValues)
    expect(len(steps) == len(times) >= 5 and all(a == b for a, b in zip(steps, times)),
           f"{label}: {len(steps)} time steps, {steps[0]} ... {steps[-1]} s = the frame times of summary.json")

    def grid_at(t):
        reader.UpdatePipeline(t)
        blocks = leaves(servermanager.Fetch(reader))
        expect(len(blocks) == 1, f"{label}, t = {t}: {len(blocks)} block (the bar)")
        if not blocks:
            return [], None
        grid = blocks[0]
        u = grid.GetPointData().GetArray("elastic_displacement")
        expect(u is not None and u.GetNumberOfComponents() == 3 and u.GetNumberOfTuples() == nodes,
               f"{label}, t = {t}: point field 'elastic_displacement' (3 components, {nodes} nodes)")
        points_type = grid.GetPoints().GetData().GetDataTypeAsString()
        expect(grid.GetNumberOfPoints() == nodes and points_type == "double",
               f"{label}, t = {t}: {grid.GetNumberOfPoints()} points, stored as {points_type}")
        x = [grid.GetPoint(i) for i in range(grid.GetNumberOfPoints())]
        if u is None:
            return x, None
        return x, [u.GetTuple3(i) for i in range(u.GetNumberOfTuples())]

    X, u0 = grid_at(times[0])
    if u0 is None or len(X) != nodes:
        return
    expect(max(abs(c) for v in u0 for c in v) == 0.0, f"{label}, t = 0: elastic_displacement is zero")
    i = min(range(len(X)), key=lambda j: dist(X[j], CORNER))
    expect(dist(X[i], CORNER) <= TOL, f"{label}: node {i} at {X[i]} is the sensor point {CORNER} "
                                      f"({dist(X[i], CORNER):.1e} m)")

    t = times[-1]
    x, u = grid_at(t)
    if u is None or len(x) != nodes:
        return
    pos = sensors["corner"]["value"][-1]
    el = sensors["corner_elastic"]["value"][-1]
    dx = max(abs(a - b) for a, b in zip(x[i], pos))
    du = max(abs(a - b) for a, b in zip(u[i], el))
    expect(dx <= TOL, f"{label}, t = {t}: corner node at {x[i]} = sensor 'corner' {pos} "
                      f"(max difference {dx:.1e} m, limit {TOL:g})")
    expect(du <= TOL, f"{label}, t = {t}: elastic_displacement {u[i]} = sensor 'corner_elastic' {el} "
                      f"(max difference {du:.1e} m, limit {TOL:g})")
    size = norm(u[i])
    expect(size >= MIN_ELASTIC, f"{label}, t = {t}: |elastic_displacement| at the corner = {size:.3e} m "
                                f"(at least {MIN_ELASTIC:g})")

    o = body["frame_origin"]
    tol = TOL + summary["constraint_violation_max"]
    err = max(abs(dist(x[j], PIVOT) - norm([X[j][k] - o[k] + u[j][k] for k in range(3)]))
              for j in range(nodes))
    expect(err <= tol, f"{label}, t = {t}: every node at |x - r| = |X - o + u| "
                       f"(max difference {err:.1e} m, limit {tol:.1e})")


def check(out):
    from paraview.simple import Delete, XDMFReader, Xdmf3ReaderS, Xdmf3ReaderT
    summary = json.load(open(os.path.join(out, "summary.json")))
    xdmf = os.path.join(out, "motion.xdmf")
    for label, make in [("Xdmf3ReaderT", lambda: Xdmf3ReaderT(FileName=[xdmf])),
                        ("XDMFReader", lambda: XDMFReader(FileNames=[xdmf])),
                        ("Xdmf3ReaderS", lambda: Xdmf3ReaderS(FileName=[xdmf]))]:
        reader = make()
        check_reader(label, reader, summary)
        Delete(reader)
    print(f"{len(failures)} failed" if failures else "ParaView reads the flexible body's motion")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    if sys.argv[1] == "--check":
        check(sys.argv[2])
    else:
        run(*sys.argv[1:5])
