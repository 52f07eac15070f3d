"""What the fault tests (tests/check_*.py of CTest label `faults`) share: the path to scripts/
(mpi_job, case_variants), one line per check, and the exit status.

    from check_common import expect, finish
    expect(rc != 0, "refused")       # prints "ok    refused" or "FAIL  refused"
    finish("what passed")            # exit 1 naming every failed check, else print and return
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))

failures = []


def expect(cond, what):
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    if not cond:
        failures.append(what)
    return cond


def finish(passed):
    if failures:
        print("FAIL: " + "; ".join(failures))
        sys.exit(1)
    print("ok: " + passed)
