"""Renders the pictures of `flexopt report` with ParaView (run with pvbatch; scripts/report.py
calls it, under Xvfb where no display exists).

Usage: pvbatch report_render.py JOBS.json
JOBS.json: a list of jobs, each a dict with
  xdmf     the file to read (design.xdmf, motion.xdmf, motion_final.xdmf, ...)
  png      the picture to write (one per view or instant: png with {k} replaced by its index)
  views    ["iso", "top", "front"]: one picture per view of one time step (`time`: "first" or
           "last"), or
  times    a list of simulated times: one picture per time, all seen from one camera that
           frames the union of the bodies' extents at those times
  threshold  a cell field (physical_density): keep the cells where it is >= 0.5; a body
           without it is kept whole
  color    a point vector field (elastic_displacement): colour by its magnitude, one colour
           range over all pictures of the job; absent from a body: that body is grey
  size     [width, height] in pixels (default [640, 480])
Each picture is checked to exist after SaveScreenshot; a job that fails is reported on stderr
and the others still run. Exit status 0 if every job rendered, 1 otherwise.
"""
import json
import math
import os
import sys

from paraview.simple import (ColorBy, Delete, GetActiveViewOrCreate, GetColorTransferFunction, GetScalarBar,
                             Hide, Render, SaveScreenshot, Show, Threshold, Xdmf3ReaderS,
                             XDMFReader)


def open_xdmf(path):
    """ParaView's XDMF (2) reader: it makes each body a block of its own, so that a point field
    of some bodies only (elastic_displacement) colours those and leaves the others grey; the
    XDMF3 readers make the bodies pieces of one block, which ParaView then draws uncoloured."""
    try:
        return XDMFReader(FileNames=[path])
    except Exception:  # noqa: BLE001 (a ParaView without it)
        return Xdmf3ReaderS(FileName=[path])


def cell_arrays(src):
    return [a.Name for a in src.CellData]


def point_arrays(src):
    return [a.Name for a in src.PointData]


def pipeline(src, job):
    """The reader, thresholded on job['threshold'] where the field exists."""
    field = job.get("threshold")
    if field and field in cell_arrays(src):
        t = Threshold(Input=src)
        t.Scalars = ["CELLS", field]
        # ParaView 5.10+: LowerThreshold/UpperThreshold; older: ThresholdRange.
        if hasattr(t, "LowerThreshold"):
            t.LowerThreshold, t.UpperThreshold = 0.5, 1e30
        else:
            t.ThresholdRange = [0.5, 1e30]
        return t
    return src


def bounds_union(b, c):
    if b is None:
        return list(c)
    return [min(b[0], c[0]), max(b[1], c[1]), min(b[2], c[2]), max(b[3], c[3]), min(b[4], c[4]),
            max(b[5], c[5])]


def place_camera(view, bounds, direction, up):
    """Looks at the box `bounds` along `direction`, framing it."""
    cx, cy, cz = (bounds[0] + bounds[1]) / 2, (bounds[2] + bounds[3]) / 2, (bounds[4] + bounds[5]) / 2
    r = 0.5 * math.sqrt((bounds[1] - bounds[0]) ** 2 + (bounds[3] - bounds[2]) ** 2 +
                        (bounds[5] - bounds[4]) ** 2) or 1.0
    n = math.sqrt(sum(d * d for d in direction))
    d = [x / n for x in direction]
    view.CameraFocalPoint = [cx, cy, cz]
    view.CameraPosition = [cx - 4 * r * d[0], cy - 4 * r * d[1], cz - 4 * r * d[2]]
    view.CameraViewUp = up
    view.CameraParallelProjection = 1
    view.CameraParallelScale = 1.05 * r


VIEWS = {  # direction of sight, view-up
    "iso": ([-1, -1, -1], [0, 1, 0]),
    "top": ([0, 0, -1], [0, 1, 0]),   # looking down z: the x-y plane
    "front": ([0, 1, 0], [0, 0, 1]),  # looking along y: the x-z plane
}


def style(view, display, src, job, lut_range):
    field = job.get("color")
    if field and field in point_arrays(src):
        ColorBy(display, ("POINTS", field, "Magnitude"))
        lut = GetColorTransferFunction(field)
        lut.ApplyPreset("Viridis (matplotlib)", True)
        if lut_range:
            lut.RescaleTransferFunction(lut_range[0], lut_range[1])
        display.SetScalarBarVisibility(view, True)
        bar = GetScalarBar(lut, view)
        bar.Title = field + " [m]"
        bar.ComponentTitle = "magnitude"
        bar.TitleColor = bar.LabelColor = [0, 0, 0]
    else:
        ColorBy(display, None)
        display.DiffuseColor = [0.72, 0.74, 0.78]
        display.AmbientColor = [0.72, 0.74, 0.78]


def magnitude_range(src, field):
    info = src.PointData.GetArray(field) if field in point_arrays(src) else None
    if info is None:
        return None
    return info.GetRange(-1)


def white_view(job):
    """The render view at the job's size on a white background."""
    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = job.get("size", [640, 480])
    view.OrientationAxesVisibility = 1
    view.Background = [1, 1, 1]
    if hasattr(view, "UseColorPaletteForBackground"):
        view.UseColorPaletteForBackground = 0
    return view


def snapshot(view, job, k, bounds, direction, up):
    """Picture k of the job: the camera on `bounds` along `direction`."""
    place_camera(view, bounds, direction, up)
    Render(view)
    png = job["png"].format(k=k)
    SaveScreenshot(png, view, ImageResolution=job.get("size", [640, 480]))
    return png


def render_views(job):
    src = open_xdmf(job["xdmf"])
    times = list(src.TimestepValues) if hasattr(src.TimestepValues, "__len__") else [src.TimestepValues]
    t = times[0] if job.get("time") == "first" else times[-1]
    shown = pipeline(src, job)
    shown.UpdatePipeline(t)
    view = white_view(job)
    view.ViewTime = t
    display = Show(shown, view)
    style(view, display, shown, job, magnitude_range(shown, job.get("color", "")))
    bounds = shown.GetDataInformation().GetBounds()
    written = [snapshot(view, job, k, bounds, *VIEWS[name]) for k, name in enumerate(job["views"])]
    Hide(shown, view)
    Delete(shown)
    return written


def render_times(job):
    src = open_xdmf(job["xdmf"])
    shown = pipeline(src, job)
    view = white_view(job)
    bounds, lo, hi = None, math.inf, -math.inf
    field = job.get("color", "")
    for t in job["times"]:
        shown.UpdatePipeline(t)
        bounds = bounds_union(bounds, shown.GetDataInformation().GetBounds())
        r = magnitude_range(shown, field)
        if r:
            lo, hi = min(lo, r[0]), max(hi, r[1])
    display = Show(shown, view)
    style(view, display, shown, job, (lo, hi) if hi >= lo else None)
    written = []
    for k, t in enumerate(job["times"]):
        view.ViewTime = t
        written.append(snapshot(view, job, k, bounds, *VIEWS[job.get("view", "top")]))
    Hide(shown, view)
    Delete(shown)
    return written


def main():
    jobs = json.load(open(sys.argv[1]))
    status = 0
    for job in jobs:
        try:
            written = render_views(job) if "views" in job else render_times(job)
            missing = [p for p in written if not os.path.isfile(p)]
            if missing:
                raise RuntimeError("not written: " + ", ".join(missing))
            print("rendered " + ", ".join(written), flush=True)
        except Exception as e:  # noqa: BLE001 (one failed job must not stop the others)
            print(f"report_render: {job.get('xdmf')}: {e}", file=sys.stderr, flush=True)
            status = 1
    # Leave without ParaView's teardown: under Xvfb its GLX context's destruction can raise an X
    # error (GLXBadContext) after every picture is written, which would turn a success into a
    # failure.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


main()
