#!/usr/bin/python3
"""Runs flexopt on a deliberately broken case and checks that it fails cleanly.

The case directory holds case.yaml (and any geometry) plus expect.yaml:
    command: simulate            # flexopt command (default simulate)
    message: "text that must appear in the error output"
Checks: non-zero exit status, the message printed, exactly one 'error' line (one clear message,
not one per rank), no summary.json written, and no hang (timeout).
"""
import argparse
import os
import shutil
import subprocess
import sys

import yaml
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case")
    ap.add_argument("--flexopt", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=120)
    args = ap.parse_args()
    with open(os.path.join(args.case, "expect.yaml")) as f:
        expect = yaml.safe_load(f)
    shutil.rmtree(args.out, ignore_errors=True)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    cmd = ["mpirun", "-n", str(args.ranks), args.flexopt, expect.get("command", "simulate"), args.case,
           "--out", args.out] + [str(a) for a in expect.get("args", [])]
    print("$ " + " ".join(cmd), flush=True)
    try:
        proc = mpi_job.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              timeout=args.timeout)
    except subprocess.TimeoutExpired:
        print(f"FAIL: no exit within {args.timeout} s (a hang)")
        return 1
    print(proc.stdout)
    failures = []
    if proc.returncode == 0:
        failures.append("exit status 0 for a broken case")
    if expect["message"] not in proc.stdout:
        failures.append(f"message not found: {expect['message']!r}")
    errors = [l for l in proc.stdout.splitlines() if l.startswith("flexopt: error")]
    if len(errors) != 1:
        failures.append(f"expected one 'flexopt: error' line, got {len(errors)}")
    if os.path.exists(os.path.join(args.out, "summary.json")):
        failures.append("summary.json was written")
    for f in failures:
        print("FAIL: " + f)
    print("ok" if not failures else f"{len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
