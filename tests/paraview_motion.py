"""Plays flexopt's motion output (motion.xdmf + motion.h5) with ParaView's readers (run with pvpython).

Usage: pvpython paraview_motion.py OUT_DIR
OUT_DIR holds motion.xdmf, motion.h5 and expected.json, written by the MPI test
MotionOutput.RigidMotionOfThreeBodiesReadsBackExactly with FLEXOPT_MOTION_OUT=OUT_DIR: the step
times and, per body, its name, point and cell counts, XDMF topology type and rigid motion
x(t) = pivot + R(axis, omega t) (X - pivot) + velocity t, where X is the position at the first
step (t = 0). Every reader ParaView offers for .xdmf is checked: the time steps, one block per
body (named after the body where the reader keeps names), the counts and cell types, and every
body's point coordinates at the last step against the rigid motion of its first-step points.
"""
import json
import math
import os
import sys

from paraview import servermanager
from paraview.simple import Delete, XDMFReader, Xdmf3ReaderS, Xdmf3ReaderT

out = sys.argv[1]
expected = json.load(open(os.path.join(out, "expected.json")))
xdmf = os.path.join(out, "motion.xdmf")
times = expected["times"]
bodies = expected["bodies"]
vtk_type = {"Tetrahedron": 10, "Tetrahedron_10": 24, "Hexahedron": 12}
failures = []


def expect(cond, what):
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    if not cond:
        failures.append(what)


def leaves(data, name=None):
    """(name, dataset) of every leaf in order; the name of the nearest named ancestor block."""
    if data is None:
        return []
    if data.IsA("vtkMultiBlockDataSet") or data.IsA("vtkMultiPieceDataSet"):
        piece = data.IsA("vtkMultiPieceDataSet")
        n = data.GetNumberOfPieces() if piece else data.GetNumberOfBlocks()
        result = []
        for i in range(n):
            child_name = name
            if data.HasMetaData(i) and data.GetMetaData(i).Has(data.NAME()):
                child_name = data.GetMetaData(i).Get(data.NAME())
            result += leaves(data.GetPiece(i) if piece else data.GetBlock(i), child_name)
        return result
    return [(name, data)]


def rigid(motion, p, t):
    c, s = math.cos(motion["omega"] * t), math.sin(motion["omega"] * t)
    a = motion["axis"]
    i, j = (a + 1) % 3, (a + 2) % 3
    d = [p[k] - motion["pivot"][k] for k in range(3)]
    x = list(d)
    x[i] = c * d[i] - s * d[j]
    x[j] = s * d[i] + c * d[j]
    return [x[k] + motion["pivot"][k] + motion["velocity"][k] * t for k in range(3)]


def check(label, reader, names_kept):
    reader.UpdatePipelineInformation()
    steps = list(reader.TimestepValues)
    expect(len(steps) == len(times) and all(abs(a - b) <= 1e-15 for a, b in zip(steps, times)),
           f"{label}: {len(steps)} time steps at {steps}")
    first_points = []
    for k, t in enumerate([times[0], times[-1]]):
        reader.UpdatePipeline(t)
        blocks = leaves(servermanager.Fetch(reader))
        expect(len(blocks) == len(bodies), f"{label}, t = {t}: {len(blocks)} blocks = {len(bodies)} bodies")
        if len(blocks) != len(bodies):
            return
        for (name, grid), body in zip(blocks, bodies):
            if names_kept:
                # The readers make block names unique over the whole file: "arm" at the
                # first step, "arm[K]" at step K.
                K = times.index(t)
                expect(name in (body["name"], f"{body['name']}[{K}]"),
                       f"{label}, t = {t}: block '{name}' is body '{body['name']}'")
            n, c = grid.GetNumberOfPoints(), grid.GetNumberOfCells()
            expect(n == body["points"] and c == body["cells"],
                   f"{label}, t = {t}, {body['name']}: {n} points, {c} cells")
            types = {grid.GetCellType(i) for i in range(c)}
            expect(types == {vtk_type[body["topology_type"]]},
                   f"{label}, t = {t}, {body['name']}: cell types {types} ({body['topology_type']})")
            points = [grid.GetPoint(i) for i in range(n)]
            if k == 0:
                first_points.append(points)
                continue
            X = first_points[len(first_points) - len(bodies) + bodies.index(body)]
            err = max(abs(a - b) for p, P in zip(points, X) for a, b in zip(p, rigid(body, P, t)))
            expect(err <= 1e-12, f"{label}, t = {t}, {body['name']}: positions follow the rigid motion "
                                 f"(max error {err:.1e})")
            u = grid.GetPointData().GetArray("displacement")
            if body["name"] == bodies[0]["name"]:
                expect(u is not None and u.GetNumberOfComponents() == 3,
                       f"{label}, t = {t}, {body['name']}: point array 'displacement'")
            expect(grid.GetCellData().GetArray("rank") is not None,
                   f"{label}, t = {t}, {body['name']}: cell array 'rank'")


for label, make, names_kept in [
    ("Xdmf3ReaderT", lambda: Xdmf3ReaderT(FileName=[xdmf]), True),
    ("XDMFReader", lambda: XDMFReader(FileNames=[xdmf]), True),
    ("Xdmf3ReaderS", lambda: Xdmf3ReaderS(FileName=[xdmf]), False),
]:
    reader = make()
    check(label, reader, names_kept)
    Delete(reader)

print(f"{len(failures)} failed" if failures else "ParaView plays the motion")
sys.exit(1 if failures else 0)
