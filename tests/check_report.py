#!/usr/bin/python3
"""`flexopt report` (docs/output.md "Report") on a static optimization and on a dynamic one:
  - optimize writes OUT/report/ at its end (the test runs without FLEXOPT_REPORT=0), and
    `flexopt report OUT` writes it again; every expected file exists;
  - every PNG is a picture: non-empty, and not a single colour (the standard deviation of its
    pixels is above 1 % of the range);
  - index.html names the case and links the XDMF files; opened in headless Chromium it loads
    every picture (the page's own count, data-images-loaded = n/n after the load event);
  - `flexopt report` on a directory without summary.json fails with a message, exit non-zero.
Chromium (Debian's chromium) is needed for the browser check: where it is absent the check is
skipped with a message (scripts/install_deps.sh installs it). ParaView renders on an Xvfb server
of the report's own where there is no display; a run where rendering is impossible writes the plots and says so,
which this test counts as a failure (install_deps.sh installs ParaView and Xvfb).
Usage: check_report.py FLEXOPT SOURCE OUT
"""
import os
import re
import shutil
import subprocess
import sys

import matplotlib.image as mpimg
import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

flexopt, source, out = sys.argv[1:4]
env = {k: v for k, v in os.environ.items() if k != "FLEXOPT_REPORT"}
env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_rmaps_base_oversubscribe="1")
shutil.rmtree(out, ignore_errors=True)
failures = []


def expect(cond, what):
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    if not cond:
        failures.append(what)


def run(args, ranks=2):
    p = mpi_job.run(["mpirun", "-n", str(ranks), flexopt] + args, env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True, timeout=1200)
    print(p.stdout[-3000:], flush=True)
    return p.returncode, p.stdout


def check_png(path):
    if not os.path.isfile(path) or os.path.getsize(path) == 0:
        expect(False, f"{path} exists and is not empty")
        return
    img = mpimg.imread(path)[..., :3].astype(float)
    spread = float(np.std(img)) / max(float(img.max() - img.min()), 1e-12) if img.max() > img.min() else 0.0
    expect(spread > 0.01, f"{os.path.basename(path)}: {img.shape[1]} x {img.shape[0]} pixels, "
                          f"not one colour (std / range {spread:.3f} > 0.01)")


def check_browser(index):
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if not chromium:
        print("skip  the browser check: chromium is not installed (scripts/install_deps.sh installs it)")
        return
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={os.path.join(out, 'chromium-profile')}", "--virtual-time-budget=10000"]
    p = subprocess.run([chromium] + flags + ["--dump-dom", "file://" + index], stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, text=True, timeout=120)
    m = re.search(r'data-images-loaded="(\d+)/(\d+)"', p.stdout)
    expect(bool(m) and m.group(1) == m.group(2) and int(m.group(2)) > 0,
           f"{index} in headless Chromium: pictures loaded {m.group(0) if m else '(no count: the page did not load)'}")
    shot = os.path.join(os.path.dirname(index), "page.png")
    subprocess.run([chromium] + flags + [f"--screenshot={shot}", "--window-size=1200,2400", "file://" + index],
                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=120)
    if os.path.isfile(shot):
        check_png(shot)


def check_report(d, pngs, case):
    rep = os.path.join(d, "report")
    for name in pngs:
        check_png(os.path.join(rep, name))
    index = os.path.join(rep, "index.html")
    text = open(index).read() if os.path.isfile(index) else ""
    expect(case in text and ".xdmf" in text and "not rendered" not in text,
           f"{index}: names {case}, links the XDMF files, every picture rendered")
    check_browser(index)


# A static optimization: history and design.
static = os.path.join(out, "static")
rc, log = run(["optimize", os.path.join(source, "tests", "optimize", "beam"), "--out", static, "--max-iterations", "8"])
expect(rc == 0 and "report:" in log, "optimize (static) exits 0 and writes its report")
check_report(static, ["history.png", "design.png"], "beam")
# `flexopt report OUT` again, on 1 rank.
os.remove(os.path.join(static, "report", "history.png"))
rc, log = run(["report", static], ranks=1)
expect(rc == 0 and os.path.isfile(os.path.join(static, "report", "history.png")),
       "flexopt report OUT writes the report again")
# A dynamic optimization (the slider-crank's rod on a coarse mesh, 3 iterations): history,
# initial and final designs, the final design moving.
dyn = os.path.join(out, "dynamic")
case = os.path.join(out, "slider_crank_topopt")
shutil.copytree(os.path.join(source, "cases", "slider_crank_topopt"), case)
y = open(os.path.join(case, "case.yaml")).read().replace("mesh: {size: 0.005, order: 2}", "mesh: {size: 0.01, order: 2}")
y = y.replace("../../meshes/", os.path.join(source, "meshes") + "/")
open(os.path.join(case, "case.yaml"), "w").write(y)
rc, log = run(["optimize", case, "--out", dyn, "--max-iterations", "3"])
expect(rc == 0 and "report:" in log, "optimize (dynamic) exits 0 and writes its report")
check_report(dyn, ["history.png", "design.png", "motion.png"], "slider_crank_topopt")
# Bad input: no run in the directory.
rc, log = run(["report", os.path.join(out, "nothing")], ranks=1)
expect(rc != 0 and "no summary.json" in log, "flexopt report on a directory without a run: a message, non-zero exit")
sys.exit(1 if failures else 0)
