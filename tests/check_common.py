"""What check scripts share: the path to scripts/ (mpi_job, case_variants), one line per check,
the exit status (case_variants.finish), and the iteration a restart.h5 holds.

    from check_common import expect, finish
    expect(rc != 0, "refused")       # prints "ok    refused" or "FAIL  refused"
    finish("what passed")            # exit 1 naming every failed check, else print and return
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import case_variants  # noqa: E402
from case_variants import restart_iteration  # noqa: E402,F401 (the checks' import of it)

failures = []


def expect(cond, what):
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    if not cond:
        failures.append(what)
    return cond


def finish(passed):
    """Exits 1 naming every failed check, or prints `passed` and exits 0."""
    if not failures:
        print("ok: " + passed)
    case_variants.finish(failures)
