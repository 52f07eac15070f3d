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


def restart_iteration(path):
    """The iteration restart.h5 at `path` holds (0: none yet, being replaced, or unreadable)."""
    import h5py
    try:
        with h5py.File(path, "r") as f:
            return int(f["arrays/meta"][0])
    except (OSError, KeyError):
        return 0
