#!/usr/bin/python3
"""Every YAML example of docs/case-format.md and README.md is a case that flexopt accepts, so that
documented examples cannot rot: `flexopt info` (which reads and checks case.yaml and meshes the
bodies) exits 0 on each.

A block is one of:
  - a whole case (it has `analysis:`): run as it is, beside the repository's meshes/;
  - a fragment whose first line names the case it belongs to, `# in cases/NAME` (or any case
    directory of the repository): merged into that case's case.yaml, mappings key by key, lists
    of named items (bodies, joints, sensors, ...) item by item by `name` (drivers by `joint`: an
    item of the fragment replaces the case's item of that name, or is added), other lists
    replaced; `# in cases/NAME, body BODY` for a fragment of one body (indented in
    the page), `# in cases/NAME, bodies` for items of the bodies list;
  - `# reference.yaml`: not a case (checked to be YAML only).
The merged case is written to OUT/<file>_<line>/case.yaml with its geometry paths made absolute.
Usage: check_doc_examples.py FLEXOPT SOURCE OUT
"""
import copy
import os
import re
import shutil
import subprocess
import sys
import textwrap

import yaml
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import mpi_job  # noqa: E402 (after the path to scripts/)

flexopt, source, out = sys.argv[1:4]
env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
shutil.rmtree(out, ignore_errors=True)
failures = []
KEYS = ("name", "joint")


def merge(base, frag):
    if isinstance(base, dict) and isinstance(frag, dict):
        for k, v in frag.items():
            base[k] = merge(base[k], v) if k in base else v
        return base
    if isinstance(base, list) and isinstance(frag, list) and frag and all(isinstance(x, dict) for x in frag):
        key = next((k for k in KEYS if all(k in x for x in frag)), None)
        if key:
            for item in frag:
                same = [i for i, b in enumerate(base) if isinstance(b, dict) and b.get(key) == item[key]]
                if same:
                    base[same[0]] = copy.deepcopy(item)  # a named item is defined whole
                else:
                    base.append(copy.deepcopy(item))
            return base
    return copy.deepcopy(frag)


def absolute_geometry(case, case_dir):
    for b in case.get("bodies", []):
        g = b.get("geometry")
        if isinstance(g, str) and not os.path.isabs(g):
            b["geometry"] = os.path.normpath(os.path.join(case_dir, g))


def blocks(path):
    text = open(path).read()
    for m in re.finditer(r"```yaml\n(.*?)```", text, re.S):
        yield text[:m.start()].count("\n") + 2, m.group(1)


def build(block, doc):
    """(case dict, case directory for relative paths) or None for a reference.yaml block."""
    first = block.lstrip().split("\n", 1)[0].strip()
    body = textwrap.dedent(block)
    if first.startswith("# reference.yaml"):
        yaml.safe_load(body)
        return None
    m = re.match(r"#\s*in\s+(\S+?)(?:,\s*(bodies|body\s+(\S+)))?\s*$", first)
    frag = yaml.safe_load(body)
    if not m:
        if not (isinstance(frag, dict) and "analysis" in frag):
            raise ValueError("neither a whole case (analysis:) nor a fragment naming its case "
                             "(first line '# in cases/NAME')")
        return frag, os.path.join(source, "cases", "doc_example")
    case_dir = os.path.join(source, m.group(1))
    case = yaml.safe_load(open(os.path.join(case_dir, "case.yaml")))
    if m.group(3):
        target = [b for b in case["bodies"] if b["name"] == m.group(3)]
        if not target:
            raise ValueError(f"{m.group(1)} has no body {m.group(3)}")
        merge(target[0], frag)
    elif m.group(2) == "bodies":
        merge(case["bodies"], frag)
    else:
        merge(case, frag)
    return case, case_dir


for doc in ("docs/case-format.md", "README.md"):
    for line, block in blocks(os.path.join(source, doc)):
        what = f"{doc}:{line}"
        try:
            built = build(block, doc)
        except (ValueError, yaml.YAMLError, OSError, KeyError) as e:
            failures.append(what)
            print(f"FAIL  {what}: {e}")
            continue
        if built is None:
            print(f"ok    {what}: reference.yaml, valid YAML")
            continue
        case, case_dir = built
        absolute_geometry(case, case_dir)
        d = os.path.join(out, f"{os.path.basename(doc).split('.')[0]}_{line}")
        os.makedirs(d)
        yaml.safe_dump(case, open(os.path.join(d, "case.yaml"), "w"), sort_keys=False)
        p = mpi_job.run(["mpirun", "-n", "1", flexopt, "info", d, "--out", os.path.join(d, "out")], env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
        ok = p.returncode == 0
        print(("ok    " if ok else "FAIL  ") + f"{what}: flexopt info exits {p.returncode}")
        if not ok:
            print(textwrap.indent(p.stdout[-1500:], "      "))
            failures.append(what)
print(f"{len(failures)} example(s) failed" + (": " + ", ".join(failures) if failures else ""))
sys.exit(1 if failures else 0)
