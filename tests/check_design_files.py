#!/usr/bin/python3
"""Files that carry a design are checked before use (issue 42; docs/output.md "Restart").

On tests/optimize/beam (2 ranks): a run's restart.h5 carries the design's fingerprint (body,
region, element count, a hash of the design elements' tags and centroids) and `--restart` from
it continues. Each of these is refused with one located message and a non-zero exit, before any
computation:
  - the restart.h5 of the same case on another mesh (mesh.size 0.03: another element count);
  - the restart.h5 of the same mesh moved by 1 mm (the same count and tags, other positions);
  - a restart.h5 whose x holds a NaN, or a 1.5, at one element (named by its Gmsh tag);
  - `check-gradient --design` of a file from another mesh.
A file without a fingerprint (written by an earlier flexopt) is used with a warning. design.h5
carries the fingerprint too: `--restart` beside another design's design.h5 resumes without its
frames, with one warning saying why.
Usage: check_design_files.py FLEXOPT SOURCE OUT
"""
import os
import re
import shutil
import subprocess
import sys

import h5py
import numpy as np

from check_common import expect, failures, finish  # noqa: F401 (also the path to scripts/)
import mpi_job  # noqa: E402
from case_variants import write_variant  # noqa: E402

flexopt, source, out = sys.argv[1], sys.argv[2], sys.argv[3]
beam = os.path.join(source, "tests", "optimize", "beam")
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)


def flexopt_run(command, case, d, *args):
    cmd = ["mpirun", "-n", "2", flexopt, command, case, "--out", os.path.join(out, d), *args]
    p = mpi_job.run(cmd, env=mpi_job.ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                    timeout=600)
    return p.returncode, p.stdout


def refused(rc, text, pattern, what):
    errors = [ln for ln in text.splitlines() if "error" in ln.lower()]
    ok = rc != 0 and len(errors) == 1 and re.search(pattern, errors[0]) is not None
    expect(ok, f"{what}: refused with one message matching '{pattern}'")
    if not ok:
        print(text[-3000:])


def copy_restart(src, d):
    os.makedirs(os.path.join(out, d), exist_ok=True)
    path = os.path.join(out, d, "restart.h5")
    shutil.copy(os.path.join(out, src, "restart.h5"), path)
    return path


# A run of 3 iterations, and its restart to 4.
rc, text = flexopt_run("optimize", beam, "run", "--max-iterations", "3")
expect(rc == 0, "optimize, 3 iterations")
with h5py.File(os.path.join(out, "run", "restart.h5"), "r") as f:
    labels = {k: (v.decode() if isinstance(v, bytes) else str(v)) for k, v in f.attrs.items()}
    tags = f["tags"][...]
print("fingerprint: " + ", ".join(f"{k} {v}" for k, v in sorted(labels.items())))
expect(labels.get("design_body") == "beam" and labels.get("design_region") == "beam" and
       labels.get("design_elements") == str(len(tags)) and len(labels.get("design_positions", "")) == 16,
       "restart.h5 carries the fingerprint (body, region, element count, positions hash)")
shutil.copytree(os.path.join(out, "run"), os.path.join(out, "continued"))
rc, text = flexopt_run("optimize", beam, "continued", "--max-iterations", "4", "--restart")
expect(rc == 0 and "restarting from" in text, "--restart from it continues")

# Another mesh of the same case.
coarse = write_variant(beam, os.path.join(out, "coarse_case"), [("size: 0.025", "size: 0.03")],
                       optimization=True)
copy_restart("run", "coarse")
rc, text = flexopt_run("optimize", coarse, "coarse", "--max-iterations", "4", "--restart")
refused(rc, text, r"written for another design: design_elements '\d+' in the file, '\d+' in this case",
        "--restart on another mesh")

# The same mesh moved by 1 mm: the same element count and tags.
geo = os.path.join(out, "moved.geo")
with open(geo, "w") as f:
    f.write(f'Include "{os.path.join(source, "meshes", "beam.geo")}";\n'
            "Translate {0, 0.001, 0} { Volume{:}; }\n")
moved = write_variant(beam, os.path.join(out, "moved_case"), [],
                      optimization=True)
moved_yaml = open(os.path.join(moved, "case.yaml")).read()
moved_yaml = re.sub(r"geometry: \S*beam\.geo", f"geometry: {geo}", moved_yaml)
open(os.path.join(moved, "case.yaml"), "w").write(moved_yaml)
copy_restart("run", "moved")
rc, text = flexopt_run("optimize", moved, "moved", "--max-iterations", "4", "--restart")
refused(rc, text, r"tags or positions differ", "--restart on the mesh moved by 1 mm (same count and tags)")

# Densities that are not densities.
for name, value in (("nan", np.nan), ("above_one", 1.5)):
    path = copy_restart("run", name)
    with h5py.File(path, "r+") as f:
        x = f["fields/x"][...]
        x[7] = value
        f["fields/x"][...] = x
        tag = int(f["tags"][7])
    rc, text = flexopt_run("optimize", beam, name, "--max-iterations", "4", "--restart")
    refused(rc, text, rf"field 'x': element {tag} has {'nan' if name == 'nan' else '1.5'}, not a density",
            f"--restart from a file with x = {value} at element {tag}")

# design.h5 carries the fingerprint too: --restart carries frames over only from this design's
# file. The run's restart.h5 beside the coarse mesh's design.h5: the run resumes, warning that
# design.xdmf lacks the earlier frames because that file belongs to another design.
rc, text = flexopt_run("optimize", coarse, "coarse_run", "--max-iterations", "3")
with h5py.File(os.path.join(out, "coarse_run", "design.h5"), "r") as f:
    design_labels = {k: (v.decode() if isinstance(v, bytes) else str(v)) for k, v in f.attrs.items()}
expect(rc == 0 and design_labels.get("design_body") == "beam" and "design_positions" in design_labels,
       "design.h5 carries the fingerprint")
foreign = copy_restart("run", "foreign_design")
shutil.copy(os.path.join(out, "coarse_run", "design.h5"), os.path.join(out, "foreign_design", "design.h5"))
rc, text = flexopt_run("optimize", beam, "foreign_design", "--max-iterations", "4", "--restart")
warned = [ln for ln in text.splitlines() if "warning" in ln and "design.xdmf lacks" in ln]
print(warned[0] if warned else text[-2000:])
expect(rc == 0 and len(warned) == 1 and "written for another design" in warned[0],
       "--restart beside another design's design.h5: runs, its frames not carried, one warning saying why")

# --design of a file from another mesh.
rc, text = flexopt_run("check-gradient", coarse, "design_other",
                       "--design", os.path.join(out, "run", "restart.h5"))
refused(rc, text, r"written for another design", "check-gradient --design of another mesh's file")

# A file without a fingerprint: used, with a warning.
path = copy_restart("run", "old")
with h5py.File(path, "r+") as f:
    for k in list(f.attrs.keys()):
        del f.attrs[k]
rc, text = flexopt_run("optimize", beam, "old", "--max-iterations", "4", "--restart")
expect(rc == 0 and "carries no design fingerprint" in text, "a file without a fingerprint: used with a warning")

finish("design files are checked before use")
