"""Opens flexopt's XDMF output with ParaView's own XDMF reader (run with pvpython).

Usage: pvpython paraview_open.py OUT_DIR BASENAME
Checks against OUT_DIR/summary.json: the number of points (DOFs / 3) and cells (elements),
the VTK cell type of the element type, the arrays, and the time steps (one per mode for
modes.xdmf, whose mode shapes are scaled to a largest component of 1).
"""
import json
import os
import sys

from paraview import servermanager
from paraview.simple import Xdmf3ReaderS, UpdatePipeline

out, base = sys.argv[1], sys.argv[2]
summary = json.load(open(os.path.join(out, "summary.json")))
vtk_type = {"Tet4": 10, "Tet10": 24, "Hex8": 12}[summary["element_type"]]
reader = Xdmf3ReaderS(FileName=[os.path.join(out, base + ".xdmf")])
reader.UpdatePipeline()
failures = []


def expect(cond, what):
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    if not cond:
        failures.append(what)


def block(data):
    return data.GetBlock(0) if data.IsA("vtkMultiBlockDataSet") else data


times = list(reader.TimestepValues) if reader.TimestepValues else [0.0]
reader.UpdatePipeline(times[0])
grid = block(servermanager.Fetch(reader))
expect(grid.GetNumberOfPoints() * 3 == summary["dofs"], f"points: {grid.GetNumberOfPoints()} = DOFs / 3")
expect(grid.GetNumberOfCells() == summary["elements"], f"cells: {grid.GetNumberOfCells()} = elements")
types = {grid.GetCellType(i) for i in range(grid.GetNumberOfCells())}
expect(types == {vtk_type}, f"cell types {types} = {{{vtk_type}}} ({summary['element_type']})")
if base == "static":
    u = grid.GetPointData().GetArray("displacement")
    expect(u is not None and u.GetNumberOfComponents() == 3, "point array 'displacement' (3 components)")
    mags = [sum(c * c for c in u.GetTuple3(i)) ** 0.5 for i in range(u.GetNumberOfTuples())]
    expect(abs(max(mags) - summary["max_displacement"]) <= 1e-12 * summary["max_displacement"],
           "max |displacement| equals summary max_displacement")
    for name in ["von_mises", "rank"]:
        expect(grid.GetCellData().GetArray(name) is not None, f"cell array '{name}'")
    ranks = grid.GetCellData().GetArray("rank").GetRange()
    expect(ranks == (0.0, summary["ranks"] - 1.0), f"rank field spans 0 .. {summary['ranks'] - 1}")
else:
    n = len(summary["frequencies_hz"])
    expect(times == [float(k + 1) for k in range(n)], f"{n} time steps, one per mode")
    for t in times:
        reader.UpdatePipeline(t)
        g = block(servermanager.Fetch(reader))
        a = g.GetPointData().GetArray("mode_shape")
        lo, hi = min(a.GetRange(k)[0] for k in range(3)), max(a.GetRange(k)[1] for k in range(3))
        expect(abs(max(abs(lo), abs(hi)) - 1.0) < 1e-12 and hi >= abs(lo), f"mode {int(t)}: largest component +1")
print(f"{len(failures)} failed" if failures else "ParaView reads the output")
sys.exit(1 if failures else 0)
