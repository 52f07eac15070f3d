#!/usr/bin/python3
"""scripts/check_structure.py catches what it is there to catch: in a small tree of its own (the
repository's docs/architecture.md and docs/theory.md, a few planted sources and a compile
database for them), it must
  - fail (exit 1) and name each planted violation: a 130-line function and a 121-line one
    (clang-tidy's count: the body's lines after the `{` line up to the `}` line), an include
    arrow against the module order (core including dynamics), a private header of another
    module, a file of 901 lines and a citation of a section docs/theory.md does not have;
  - pass (exit 0) on the same tree without them, where a 120-line function sits at the limit.
Usage: check_structure_plants.py [WORKDIR]
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

repo = Path(__file__).resolve().parent.parent
script = repo / "scripts" / "check_structure.py"
work = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="plants_"))


def function(name, lines):
    """A function whose body spans `lines` lines by clang-tidy's count."""
    body = "".join(f"  s += {k};\n" for k in range(lines - 3))
    return f"int {name}() {{\n  int s = 0;\n{body}  return s;\n}}\n"


def tree(root, planted):
    shutil.rmtree(root, ignore_errors=True)
    (root / "docs").mkdir(parents=True)
    for doc in ("architecture.md", "theory.md"):
        shutil.copy(repo / "docs" / doc, root / "docs" / doc)
    files = {
        "include/flexopt/core/util.hpp": "#pragma once\nint util();\n",
        "include/flexopt/dynamics/step.hpp": "#pragma once\nint step();\n",
        "src/fem/private.hpp": "#pragma once\nint hidden();\n",
        "src/core/util.cpp": '#include "flexopt/core/util.hpp"\n\n' + function("util", 120) +
                             "// See docs/theory.md section 9.2.\n",
        "src/dynamics/step.cpp": '#include "flexopt/dynamics/step.hpp"\n#include "flexopt/core/util.hpp"\n\n'
                                 "int step() { return util(); }\n",
    }
    if planted:
        files["src/core/util.cpp"] += function("long130", 130) + function("long121", 121)
        files["src/core/arrow.cpp"] = ('#include "flexopt/dynamics/step.hpp"\n\n'
                                       "int arrow() { return step(); }\n")
        files["src/dynamics/peek.cpp"] = '#include "../fem/private.hpp"\n\nint peek() { return 0; }\n'
        files["src/core/big.cpp"] = "".join(f"// line {k}\n" for k in range(901))
        # (split, so that the structure check of this repository does not find it here)
        files["src/dynamics/step.cpp"] += "// The step of docs/theory" ".md section 99.9.\n"
    db = []
    for path, text in files.items():
        (root / path).parent.mkdir(parents=True, exist_ok=True)
        (root / path).write_text(text)
        if path.endswith(".cpp"):
            db.append({"directory": str(root), "file": path,
                       "command": f"c++ -std=c++17 -I{root / 'include'} -c {path} -o {path}.o"})
    (root / "build").mkdir()
    (root / "build" / "compile_commands.json").write_text(json.dumps(db, indent=1))


def run(root):
    p = subprocess.run([sys.executable, str(script), "--root", str(root), "--build", str(root / "build"),
                        "--cache", str(root / "cache")], capture_output=True, text=True)
    print(p.stdout + p.stderr)
    return p.returncode, p.stdout + p.stderr


failures = []
tree(work / "planted", True)
tree(work / "clean", False)
code, text = run(work / "planted")
if code != 1:
    failures.append(f"planted tree: exit {code}, expected 1")
for where, what in [("src/core/util.cpp", "long130"), ("src/core/util.cpp", "long121"),
                    ("src/core/arrow.cpp", "flexopt/dynamics/step.hpp"),
                    ("src/dynamics/peek.cpp", "private.hpp"), ("src/core/big.cpp", "901"),
                    ("src/dynamics/step.cpp", "99.9")]:
    if not any(where in line and what in line for line in text.splitlines()):
        failures.append(f"planted tree: no violation naming {where} and '{what}'")
if any("util.cpp" in line and "'util'" in line for line in text.splitlines()):
    failures.append("the 120-line function 'util' was reported: the limit is 120 lines")
code, text = run(work / "clean")
if code != 0:
    failures.append(f"clean tree: exit {code}, expected 0")
for f in failures:
    print("FAIL:", f)
sys.exit(1 if failures else 0)
