#!/usr/bin/python3
"""Frames of the motion output (docs/output.md, "Frames") on variants of cases/pendulum, 2 ranks.

Usage: check_output_frames.py FLEXOPT SRC OUT

1. No `output:` key, 10,000 steps of 0.4 ms (the case's 4 s): motion.xdmf and motion.h5 hold
   201 frames (every 50 steps, fewer than 300), the first at t = 0 and the last at t = 4 s, the same times in the
   XDMF, in /time and as /link/step_K groups of the HDF5 file; energy and sensors keep every
   step (10,001 samples); the progress output names the frame count; the size estimate
   printed and stored in summary.json is within 5 % of the files' size.
2. `output: {interval: T}`: the frames are the steps nearest k T (T = 12.5 steps: round half
   away from zero), plus the last state when no multiple falls on it (T = 0.3 s over 1 s); an
   interval below the step gives every step with a warning; sensors are sampled at the frames.
3. `output: {every: 7}` over 100 steps: 0, 7, ..., 98 and the last state 100.
4. A run whose motion file would exceed 1 GB (300,001 frames of three bodies) warns before it
   starts, with the estimate and the output: key that reduces it (the scene of
   tests/bad_input/newton_diverges stops at t = 0.48 s, so nothing large is written).

Times are compared exactly: flexopt's step times are n h in double precision, as is float(n) * h
here, and the XDMF writes them with %.17g, which reads back to the same double.
"""
import json
import math
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import h5py

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from case_variants import write_variant  # noqa: E402
import mpi_job  # noqa: E402

FLEXOPT, SRC, OUT = sys.argv[1], sys.argv[2], sys.argv[3]
H = 1.0e-3  # time.step of cases/pendulum
H_LONG = 4.0e-4  # 10,000 steps over its 4 s
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
LARGE_STEPS = 300000  # every step a frame: several GB for the three bodies of newton_diverges
# The size estimate's HDF5 header sizes were measured (docs/output.md, "Size"): +0.31 % here,
# for the pendulum's link of 166 nodes: per frame 3,984 bytes of positions, 1,425 of HDF5
# headers, about 600 of XDMF text. 5 % leaves room for another HDF5 version's header sizes; an
# estimate without the headers (-24 %) or the XDMF text (-10 %) fails.
SIZE_TOL = 0.05
failures = []


def expect(cond, what):
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    if not cond:
        failures.append(what)


def variant(name, replace, case="cases/pendulum"):
    """Writes case.yaml of `case` with each (old, new) replaced (old must occur) and absolute
    geometry paths into OUT/name; returns the directory."""
    d = os.path.join(OUT, name)
    shutil.rmtree(d, ignore_errors=True)
    return write_variant(os.path.join(SRC, case), d, replace, optimization=True)


def simulate(d):
    """Runs flexopt simulate on 2 ranks; returns (exit status, output)."""
    cmd = ["mpirun", "-n", "2", FLEXOPT, "simulate", d, "--out", os.path.join(d, "out")]
    print("$ " + " ".join(cmd), flush=True)
    p = mpi_job.run(cmd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                       timeout=600)
    return p.returncode, p.stdout


def run_ok(name, replace):
    """A variant that must run: returns (summary, XDMF frame times, HDF5 /time, output)."""
    d = variant(name, replace)
    rc, log = simulate(d)
    if rc != 0:
        print(log)
        expect(False, f"{name}: flexopt simulate exits with 0 (got {rc})")
        return None
    out = os.path.join(d, "out")
    summary = json.load(open(os.path.join(out, "summary.json")))
    root = ET.parse(os.path.join(out, "motion.xdmf")).getroot()
    xdmf_t = [float(t.get("Value")) for t in root.iter("Time")]
    with h5py.File(os.path.join(out, "motion.h5"), "r") as f:
        h5_t = [float(t) for t in f["/time"][...]]
        groups = sorted(int(k[len("step_"):]) for k in f["/link"].keys() if k.startswith("step_"))
    expect(groups == list(range(len(h5_t))),
           f"{name}: /link holds one step_K group per entry of /time ({len(groups)})")
    expect(xdmf_t == h5_t == summary["motion"]["times"],
           f"{name}: the XDMF, /time and summary.json motion.times agree ({len(xdmf_t)} frames)")
    return summary, xdmf_t, log


def times(steps, h=H):
    return [float(n) * h for n in steps]


def nearest(x):
    """Rounds half away from zero, as std::llround (Python's round() rounds half to even)."""
    return int(math.floor(x + 0.5))


# 1. Default: 10,000 steps, no output: key.
r = run_ok("default", [("step: 1.0e-3,", "step: 4.0e-4,"), ("output: {every: 1}\n", "")])
if r:
    s, t, log = r
    expect(len(t) < 300 and len(t) == 201, f"default: {len(t)} frames < 300 (every 50 steps: 201)")
    expect(t == times(range(0, 10001, 50), H_LONG), "default: frames at steps 0, 50, ..., 10,000")
    expect(t[0] == 0.0 and abs(t[-1] - 4.0) < 1e-12, f"default: first frame t = {t[0]}, last t = {t[-1]}")
    expect(s["motion"]["rule"] == "default" and s["motion"]["every"] == 50 and s["motion"]["frames"] == 201,
           "default: summary.json motion.rule = default, every = 50, frames = 201")
    expect(len(s["sensors"]["tip"]["t"]) == len(s["energy"]) == len(s["output_times"]) == 10001,
           "default: energy and sensors keep every step (10,001 samples)")
    expect("output: motion.xdmf: 201 frames: every 50 steps (the default" in log,
           "default: the progress output names the frame count and the rule")
    est, got = s["motion"]["estimated_bytes"], s["motion"]["bytes"]
    files = sum(os.path.getsize(os.path.join(OUT, "default", "out", f)) for f in ("motion.h5", "motion.xdmf"))
    expect(got == files, f"default: motion.bytes = the files' size ({files} bytes)")
    expect(abs(est - got) <= SIZE_TOL * got,
           f"default: size estimate {est:.0f} bytes within {SIZE_TOL:.0%} of {got} ({(est - got) / got:+.2%})")

# 2. Intervals.
r = run_ok("interval", [("time: {end: 4.0,", "time: {end: 1.0,"),
                        ("output: {every: 1}", "output: {interval: 0.0125}")])
if r:
    s, t, log = r
    steps = [nearest(12.5 * k) for k in range(81)]  # 80 * 12.5 = 1000: the last state
    expect(t == times(steps), f"interval 12.5 steps: frames at round(12.5 k) = {steps[:5]} ... {steps[-1]}")
    expect(s["sensors"]["tip"]["t"] == t == s["output_times"],
           "interval: with output: given, sensors and energy are sampled at the frames")
    expect(s["motion"]["rule"] == "interval" and s["motion"]["interval"] == 0.0125 and "every" not in s["motion"],
           "interval: summary.json motion.rule = interval, interval = 0.0125, no stride")
r = run_ok("interval_whole", [("time: {end: 4.0,", "time: {end: 1.0,"),
                              ("output: {every: 1}", "output: {interval: 0.3}")])
if r:
    s, t, log = r
    expect(t == times([0, 300, 600, 900, 1000]), f"interval 0.3 s over 1 s: frames {t} (the last state added)")
    expect(s["motion"]["every"] == 300, "interval 0.3 s: a stride of 300 steps")
r = run_ok("interval_below_step", [("time: {end: 4.0,", "time: {end: 0.05,"),
                                   ("output: {every: 1}", "output: {interval: 4.0e-4}")])
if r:
    s, t, log = r
    expect(t == times(range(51)), f"interval 0.4 ms < step 1 ms: every step ({len(t)} frames)")
    expect("output: warning: output.interval = 0.0004 s is shorter than time.step = 0.001 s" in log,
           "interval below the step: warning printed")

# 3. every: N.
r = run_ok("every", [("time: {end: 4.0,", "time: {end: 0.1,"), ("output: {every: 1}", "output: {every: 7}")])
if r:
    s, t, log = r
    expect(t == times(list(range(0, 100, 7)) + [100]), f"every 7 over 100 steps: {len(t)} frames, the last at step 100")
    expect(s["sensors"]["tip"]["t"] == t, "every: sensors sampled at the frames")

# 4. The size warning (the scene stops by itself at t = 0.48 s: Newton cannot pass the dead point).
d = variant("large", [("time: {end: 0.6,", f"time: {{end: {LARGE_STEPS / 1000:.1f},"), ("output: {every: 10}", "output: {every: 1}")],
            case="tests/bad_input/newton_diverges")
rc, log = simulate(d)
warning = [l for l in log.splitlines() if l.startswith("output: warning: motion.h5 will take about")]
print("\n".join(warning))
expect(rc != 0 and len(warning) == 1, "large: one warning line before the run (which then stops)")
m = re.search(rf"about ([0-9.]+) GB \({LARGE_STEPS + 1} frames of [0-9.]+ kB\); write fewer frames with output: "
              r"\{every: N\} \(steps\) or output: \{interval: SECONDS\} in case.yaml, e.g. output: "
              r"\{every: ([0-9]+)\} for at most 1.00 GB", warning[0] if warning else "")
expect(m is not None and float(m.group(1)) > 1.0,
       f"large: the warning gives the estimate (> 1 GB, {LARGE_STEPS + 1} frames) and an output: {{every: N}} that fits")
if m:
    # every N of LARGE_STEPS steps writes LARGE_STEPS // N + 1 frames (+1, the last state): that
    # many frames must fit in 1 GB, and with N - 1 they must not (to the 3 digits printed).
    n = int(m.group(2))
    gb = float(m.group(1))
    per_frame = gb / (LARGE_STEPS + 1)
    expect((LARGE_STEPS // n + 2) * per_frame <= 1.005 and (LARGE_STEPS // (n - 1) + 1) * per_frame > 0.99,
           f"large: every {n} steps is the smallest stride under 1 GB (estimate {gb} GB)")

print(f"{len(failures)} failed" if failures else "all output frame checks passed")
sys.exit(1 if failures else 0)
