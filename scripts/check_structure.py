#!/usr/bin/env python3
"""Enforce flexopt's code structure: print each violation as `path:line: message`; exit 1 if any.

1. Include arrows.  The module order is the line of docs/architecture.md
       Module order: app → io/case → adjoint → plan → ... → io → core
   (prefix "Module order:", modules separated by "→"; --order "..." overrides it; a missing line
   is a violation).  Modules are folders, include/flexopt/<m>/ and src/<m>/; the pseudo-module
   io/case is include/flexopt/io/case.hpp and src/io/case.cpp, case_*.cpp and case_*.hpp.  A file of module X may
   #include "flexopt/<m>/..." only for m = X or m right of X.  A private header src/<m>/x.hpp
   (#include "x.hpp", relative) may only be included from files in src/<m>/.
2. Function length: clang-tidy's readability-function-size, LineThreshold 120 and nothing else,
   on every TU under src/ with its flags from compile_commands.json, reporting functions in
   headers under include/ and src/ too, each once.  "Lines" as clang-tidy 14 counts them: the
   line number of the body's closing brace minus that of its opening brace, i.e. the body's
   lines after the `{` line (blank and comment lines too) up to and including the `}` line.  The
   signature, template header and constructor initializer list do not count; lambdas count in
   their enclosing function (the check skips lambda call operators); templates are checked as
   written, not per instantiation; bodies without statements are skipped.  121 lines fail.
   Speed (3 s a TU otherwise): the TUs of a module with the same flags are parsed as one unity
   TU (`#include "<each .cpp>"`), file by file if that gives any error (names clashing between
   files); the TU ends with a deliberately missing include, after whose fatal error clang skips
   the end-of-TU template instantiations (2/3 of the time on Eigen-heavy code), which the check
   ignores anyway.  --jobs processes; findings cached per group (key: clang-tidy version,
   settings, flags, and the contents of the files and of the project headers they include).
   The compile database: --build DIR, else `cmake` configured (not built) into <cache>/cmake.
3. File length: a file under src/ or include/ of more than 900 lines fails.
4. Theory citations in src/, include/, tests/, scripts/ (but this script), bench/, CMakeLists.txt
   (.cpp .hpp .h .py .sh .txt .cmake) must name a numbered heading of docs/theory.md (`## 9. T`,
   `### 9.5 T`, `#### ...`: N or N.M after the #s).  Recognized in comments and Python
   docstrings, also across wrapped comment lines:
     * "theory.md" followed by a section: "docs/theory.md section 9.5", "docs/theory.md §9.2",
       "(docs/theory.md, section 4)", "docs/theory.md 9.5", "theory.md sections 5 and 9"; this
       form also in code (string literals), within a line;
     * bare "§N.M", "section N.M", "sections ..." (any case), unless another document is named
       on the match's lines or in the 60 characters before it: another *.md, README,
       CASE_FORMAT, case-format, "et al", arXiv, doi, paper, "Author (1987)".
   Lists and ranges: "6.3 and 7.4", "9.6, 9.7", "9.1-9.5", "6.1–6.2" (both ends); a number
   after ",", "and", "or", "to" or a dash counts if punctuation, another separator or the end
   follows it ("section 9.1, 10 mass parameters" cites 9.1 only).

Exception lists below: each entry needs a reason, and an entry that matches no violation is a
violation itself ("stale"), so that the lists stay honest:
  EXCEPTIONS               "path:function" (check 2, the name clang-tidy prints) or "path" (3)
  INCLUDE_EXCEPTIONS       "path:header as written in the #include" (check 1)
  BROKEN_CITATIONS_ALLOWED "path:section" (check 4)

Options: --root DIR (default: this script's repository), --order "a → b → ...", --build DIR,
--cache DIR (default <build>/check_structure, or <tmp>/flexopt_check_structure_<hash of root>),
--jobs N (2), --clang-tidy PATH.  Exit status: 0 clean, 1 violations, 2 could not run.
"""
import argparse, concurrent.futures as cf, hashlib, json, os, re, shlex, shutil, subprocess, sys
import tempfile, time
from pathlib import Path

LINE_LIMIT, FILE_LIMIT = 120, 900
EXCEPTIONS = {  # "path:function" (function length) or "path" (file length): reason
}
INCLUDE_EXCEPTIONS = {  # "path:included header": reason
}
BROKEN_CITATIONS_ALLOWED = {  # "path:section": reason
}

INCLUDE_RE = re.compile(r'^\s*#\s*include\s*([<"])([^">]+)[">]')


def die(msg):
    print(f"check_structure: {msg}", file=sys.stderr)
    sys.exit(2)


def rel(root, path):
    return Path(os.path.relpath(os.path.realpath(path), root)).as_posix()


def module_of(r):
    """The module of a file (path relative to the root) under include/flexopt/ or src/."""
    parts = r.split("/")
    if r == "include/flexopt/io/case.hpp" or re.fullmatch(r"src/io/case(_\w+)?\.(cpp|hpp)", r):
        return "io/case"
    if parts[0] == "include" and len(parts) > 3 and parts[1] == "flexopt":
        return parts[2]
    return parts[1] if parts[0] == "src" and len(parts) > 2 else None


def lib_files(root):
    return sorted(p for d in ("include", "src") for p in (root / d).rglob("*")
                  if p.is_file() and p.suffix in (".cpp", ".hpp", ".h"))


def includes(root, path):
    """(line, as written, project file) of each #include of a project file."""
    for ln, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
        m = INCLUDE_RE.match(line)
        if m:
            cands = ([path.parent / m.group(2)] if m.group(1) == '"' else []) + [
                root / "include" / m.group(2)]
            target = next((c.resolve() for c in cands if c.is_file()), None)
            if target:
                yield ln, m.group(2), target


# ---- check 1: include arrows ----
def read_order(root, override, out):
    arch = root / "docs/architecture.md"
    text = f"Module order: {override}" if override else arch.is_file() and arch.read_text("utf-8")
    m = re.search(r"^\s*Module order:\s*(.+?)\s*$", text or "", re.M)
    if not m:
        out.append(("docs/architecture.md", 1, "no 'Module order:' line; expected a line like "
                    "'Module order: app → io/case → adjoint → ... → io → core' (left to right, "
                    "separated by '→'; a module may include itself and the modules to its right)"))
        return None
    return [s.strip(" `.") for s in m.group(1).split("→")]


def check_includes(root, order, out, used):
    index = {m: i for i, m in enumerate(order)}
    for path in lib_files(root):
        r = rel(root, path)
        mod = module_of(r)
        if mod not in index:
            out.append((r, 1, f"module '{mod}' is not in the module order {' → '.join(order)}"))
            continue
        for ln, written, target in includes(root, path):
            t = rel(root, target)
            tmod = module_of(t)
            if tmod is None:
                continue
            if t.startswith("src/") and path.parent.resolve() != target.parent:
                msg = f"includes {t}, a private header of src/{tmod}/, from outside src/{tmod}/"
            elif tmod not in index:
                msg = f"includes {t} of module '{tmod}', which is not in the module order"
            elif index[tmod] < index[mod]:
                msg = (f"module {mod} includes {written} of module {tmod}, left of it in the "
                       f"module order (arrows point right: {' → '.join(order)})")
            else:
                continue
            if f"{r}:{written}" in INCLUDE_EXCEPTIONS:
                used["INCLUDE_EXCEPTIONS"].add(f"{r}:{written}")
            else:
                out.append((r, ln, msg))


# ---- check 3: file length ----
def check_file_lengths(root, out, used):
    for path in lib_files(root):
        r, n = rel(root, path), len(path.read_text(encoding="utf-8", errors="replace").splitlines())
        if n > FILE_LIMIT and r in EXCEPTIONS:
            used["EXCEPTIONS"].add(r)
        elif n > FILE_LIMIT:
            out.append((r, n, f"file has {n} lines (limit {FILE_LIMIT})"))


# ---- check 2: function length with clang-tidy ----
STOP = "check_structure_stop_here.h"  # deliberately missing: see the docstring, check 2
TIDY_CONFIG = json.dumps({"Checks": "-*,readability-function-size", "CheckOptions": [
    {"key": "readability-function-size.LineThreshold", "value": str(LINE_LIMIT)},
    {"key": "readability-function-size.StatementThreshold", "value": "4294967295"}]})  # 800 else
WARN_RE = re.compile(r"^(.+?):(\d+):\d+: warning: function '([^']+)' exceeds recommended "
                     r"size/complexity thresholds \[readability-function-size\]")
NOTE_RE = re.compile(r"^.+?:\d+:\d+: note: (\d+) lines including whitespace and comments")
ERROR_RE = re.compile(r"^(.+?):(\d+):\d+: (?:fatal )?error: (.*)$", re.M)


def compile_db(root, args, cache):
    """compile_commands.json from --build, or configured (not built) into <cache>/cmake."""
    if args.build:
        db = Path(args.build) / "compile_commands.json"
        if not db.is_file():
            die(f"no {db} (configure with -DCMAKE_EXPORT_COMPILE_COMMANDS=ON)")
        return db
    db, lists = cache / "cmake/compile_commands.json", [root / "CMakeLists.txt"]
    listed = {e["file"] for e in json.loads(db.read_text())} if db.is_file() else set()
    if (not db.is_file() or any(p.stat().st_mtime > db.stat().st_mtime for p in lists)
            or any(str(p) not in listed for p in (root / "src").glob("*/*.cpp"))):
        p = subprocess.run(["cmake", "-S", str(root), "-B", str(db.parent), "-DBUILD_TESTING=OFF",
                            "-DCMAKE_EXPORT_COMPILE_COMMANDS=ON"], capture_output=True, text=True)
        if p.returncode or not db.is_file():
            die(f"cmake configure failed:\n{p.stdout}{p.stderr}")
    return db


def header_closure(root, path, memo):
    """The project headers a file includes, transitively."""
    if path not in memo:
        memo[path] = set()
        for _, _, t in includes(root, path):
            memo[path] |= {t} | header_closure(root, t, memo)
    return memo[path]


def tu_args(entry, source):
    """The compile command's arguments without the compiler, -c, -o X and the source."""
    argv, out = entry.get("arguments") or shlex.split(entry["command"]), []
    it = iter(argv[1:])
    for a in it:
        if a == "-o":
            next(it, None)
        elif a != "-c" and Path(entry["directory"], a).resolve() != source:
            out.append(a)
    return out


def run_tidy(tidy, wrapper, root, files, directory, flags):
    wrapper.write_text("".join(f'#include "{root / f}"\n' for f in files) + f'#include "{STOP}"\n')
    root_re = re.sub(r"([.^$*+?()\[{}|\\])", r"\\\1", str(root))  # an ERE, as clang-tidy reads it
    t0 = time.time()
    p = subprocess.run([tidy, "--quiet", f"--config={TIDY_CONFIG}", str(wrapper),
                        f"--header-filter=^{root_re}/(include|src)/", "--", *flags],
                       capture_output=True, text=True, cwd=directory)
    found, last = [], None
    for line in p.stdout.splitlines():
        w, n = WARN_RE.match(line), NOTE_RE.match(line)
        if w:
            last = [rel(root, os.path.join(directory, w.group(1))), int(w.group(2)), w.group(3)]
        elif n and last:
            found.append(last + [int(n.group(1))])
            last = None
    errors = [[rel(root, os.path.join(directory, e[1])), int(e[2]), f"clang-tidy: error: {e[3]}"]
              for e in ERROR_RE.finditer(p.stdout) if STOP not in e[0]]
    if not errors and STOP not in p.stdout:
        errors = [[files[0], 1, f"clang-tidy failed ({p.returncode}): {p.stderr.strip()[-300:]}"]]
    return {"found": found, "errors": errors[:5], "seconds": time.time() - t0}


def check_functions(root, args, cache, out, used):
    tidy = args.clang_tidy or shutil.which("clang-tidy") or shutil.which("clang-tidy-14")
    if not tidy:
        die("clang-tidy not found (apt-get install clang-tidy)")
    db, groups = compile_db(root, args, cache), {}
    for e in json.loads(db.read_text()):
        f = Path(e["directory"], e["file"]).resolve()
        if f.is_relative_to(root / "src"):
            r = rel(root, f)
            groups.setdefault((r.split("/")[1], e["directory"], tuple(tu_args(e, f))), []).append(r)
    listed = {r for members in groups.values() for r in members}
    out += [(rel(root, p), 1, f"not in {db}: reconfigure CMake")
            for p in sorted((root / "src").glob("*/*.cpp")) if rel(root, p) not in listed]
    version = subprocess.run([tidy, "--version"], capture_output=True, text=True).stdout
    store, wraps = cache / "tidy_results.json", cache / "wrappers"
    wraps.mkdir(parents=True, exist_ok=True)
    try:
        old = json.loads(store.read_text())
    except (OSError, ValueError):
        old = {}
    memo, results, parts, pending = {}, {}, {}, {}
    with cf.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        def submit(gid, d, flags, files):
            name = gid if len(files) > 1 else f"{gid}-{Path(files[0]).stem}"
            fut = pool.submit(run_tidy, tidy, wraps / f"{name}.cpp", root, files, d, flags)
            pending[fut] = (gid, d, flags, files)
        todo = []
        for (mod, d, flags), members in sorted(groups.items()):
            gid = f"{mod}-{hashlib.sha1(repr((d, flags)).encode()).hexdigest()[:8]}"
            h = hashlib.sha256(repr((version, TIDY_CONFIG, STOP, str(root), d, flags)).encode())
            for f in sorted((root / m).resolve() for m in members):
                for p in [f, *sorted(header_closure(root, f, memo))]:
                    h.update(str(p).encode() + b"\0" + p.read_bytes())
            prev = old.get(gid, {})
            if prev.get("key") == h.hexdigest():
                results[gid] = prev
                continue
            parts[gid] = {"key": h.hexdigest(), "found": [], "errors": [], "seconds": 0.0,
                          "split": prev.get("split", False), "files": len(members)}
            todo.append((-prev.get("seconds", 1e6 * len(members)), gid, d, flags, sorted(members)))
        for _, gid, d, flags, members in sorted(todo):  # longest first
            for files in ([[m] for m in members] if parts[gid]["split"] else [members]):
                submit(gid, d, flags, files)
        while pending:
            done, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
            for fut in done:
                (gid, d, flags, files), res = pending.pop(fut), fut.result()
                part = parts[gid]
                part["seconds"] += res["seconds"]
                if res["errors"] and len(files) > 1:  # clashing names: file by file
                    part["split"] = True
                    for m in files:
                        submit(gid, d, flags, [m])
                else:
                    part["found"] += res["found"]
                    part["errors"] += res["errors"]
    for gid, part in parts.items():
        results[gid] = dict(part, key=None if part["errors"] else part["key"])
    store.with_suffix(".tmp").write_text(json.dumps(results, indent=0))
    os.replace(store.with_suffix(".tmp"), store)
    seen = {}
    for gid, res in sorted(results.items()):
        out += [tuple(e) for e in res["errors"]]
        seen.update({(p, line, name): n for p, line, name, n in res["found"]})
    for (path, line, name), n in sorted(seen.items()):
        if f"{path}:{name}" in EXCEPTIONS:
            used["EXCEPTIONS"].add(f"{path}:{name}")
        else:
            out.append((path, line, f"function '{name}' has {n} lines (limit {LINE_LIMIT}; "
                                    "clang-tidy readability-function-size)"))
    return len(listed), sum(p["files"] for p in parts.values())


# ---- check 4: theory citations ----
NUM = r"\d+(?:\.\d+)*"
SEP = r"(?:,|\band\b|\bor\b|\bto\b|-|–|—)"
SEP_RE = re.compile(rf"\s*{SEP}\s*(?:§\s*)?({NUM})(?=\s*(?:$|[),;:.\]]|{SEP}))", re.I)
ATTACHED_RE = re.compile(rf"(?<![\w-])theory\.md\b[\s,:(]*(?:§§?\s*|sections?\s+)?({NUM})", re.I)
BARE_RE = re.compile(rf"(?:§§?\s*|\bsections?\s+)({NUM})", re.I)
OTHER_DOC_RE = re.compile(r"(?<![\w./-])(?!(?:docs/)?theory\.md)[\w./-]+\.md\b|README|CASE_FORMAT|"
                          r"case-format|\bet al\b|arXiv|\bdoi\b|\bpaper\b|[A-Z][a-z]+ \(\d{4}\)")


def split_comments(text, suffix):
    """Per line: (comment text, code text).  C++: // and /* */; Python: # and triple-quoted
    strings (docstrings); shell and CMake: # at a line start or after a blank."""
    c_like, py = suffix in (".cpp", ".hpp", ".h"), suffix == ".py"
    line_c = "//" if c_like else "#"
    blocks = {"/*": "*/"} if c_like else {'"""': '"""', "'''": "'''"} if py else {}
    quotes = "\"'" if c_like or py or suffix == ".sh" else '"'
    special = re.compile("|".join(map(re.escape, [line_c, *blocks, *quotes])))
    result, end = [], None  # end: the closing delimiter of an open block comment
    for line in text.split("\n"):
        com, code, i = [], [], 0
        while i < len(line):
            if end:
                j = line.find(end, i)
                com.append(line[i:] if j < 0 else line[i:j])
                i, end = (len(line), end) if j < 0 else (j + len(end), None)
                continue
            m = special.search(line, i)
            code.append(line[i:m.start() if m else len(line)])
            if not m:
                break
            i, tok = m.start(), m.group()
            if tok == line_c and (c_like or py or i == 0 or line[i - 1] in " \t"):
                com.append(line[i + len(tok):])
                break
            if tok in blocks:
                end, i = blocks[tok], i + len(tok)
                continue
            j = i + 1
            while tok in quotes and j < len(line) and line[j] != tok:
                j += 2 if line[j] == "\\" else 1
            code.append(line[i:j + 1])
            i = j + 1
        result.append((" ".join(com), "".join(code)))
    return result


def cited(text, m, line):
    """(line, section) for the match's number and the list or range that follows it."""
    nums, pos = [m.group(1)], m.end()
    while (s := SEP_RE.match(text, pos)):
        nums.append(s.group(1))
        pos = s.end()
    return [(line, n) for n in nums]


def citations(path):
    """(line, section) of every theory citation in a file."""
    lines = split_comments(path.read_text(encoding="utf-8", errors="replace"), path.suffix)
    found = [c for ln, (_, code) in enumerate(lines, 1) for m in ATTACHED_RE.finditer(code)
             for c in cited(code, m, ln)]
    ln = 0
    while ln < len(lines):  # comment blocks: consecutive lines with comment text
        text, starts, first = "", [], ln + 1
        while ln < len(lines) and lines[ln][0].strip():
            starts.append(len(text))
            text += re.sub(r"^[\s/*!<#]+", "", lines[ln][0]).rstrip() + " "
            ln += 1
        ln += 1
        line_at = lambda pos: first + sum(1 for s in starts if s <= pos) - 1
        taken = []
        for m in ATTACHED_RE.finditer(text):
            taken.append((m.start(), m.end()))
            found += cited(text, m, line_at(m.start()))
        for m in BARE_RE.finditer(text):
            a = max(0, min(starts[line_at(m.start()) - first], m.start() - 60))
            b = next((s for s in starts if s > m.end()), len(text))
            if not any(x <= m.start() < y for x, y in taken) and not OTHER_DOC_RE.search(text[a:b]):
                found += cited(text, m, line_at(m.start()))
    return found


def theory_sections(root):
    """The numbers of docs/theory.md's headings (code fences skipped)."""
    found, fence = set(), False
    for line in (root / "docs/theory.md").read_text(encoding="utf-8").splitlines():
        fence ^= line.lstrip().startswith("```")
        m = not fence and re.match(rf"#+[ \t]+({NUM})\.?(?=\s|$)", line)
        if m:
            found.add(m.group(1))
    return found


def check_citations(root, out, used):
    if not (root / "docs/theory.md").is_file():
        out.append(("docs/theory.md", 1, "missing: theory citations cannot be checked"))
        return 0
    sections, count = theory_sections(root), 0
    files = [root / "CMakeLists.txt"] + sorted(
        p for d in ("src", "include", "tests", "scripts", "bench") for p in (root / d).rglob("*")
        if p.is_file() and p.suffix in (".cpp", ".hpp", ".h", ".py", ".sh", ".txt", ".cmake"))
    for path in (p for p in files if p.is_file() and rel(root, p) != "scripts/check_structure.py"):
        r = rel(root, path)
        for ln, n in citations(path):
            count += 1
            if n in sections:
                continue
            if f"{r}:{n}" in BROKEN_CITATIONS_ALLOWED:
                used["BROKEN_CITATIONS_ALLOWED"].add(f"{r}:{n}")
            else:
                out.append((r, ln, f"cites docs/theory.md section {n}, which does not exist"))
    return count


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default=str(Path(__file__).resolve().parent.parent),
                    help="repository root (default: %(default)s)")
    ap.add_argument("--order", help='module order "a → b → ..." (default: docs/architecture.md)')
    ap.add_argument("--build", help="build directory whose compile_commands.json to use")
    ap.add_argument("--cache", help="cache directory (cmake configure, clang-tidy findings)")
    ap.add_argument("--jobs", type=int, default=2, help="clang-tidy processes (default 2)")
    ap.add_argument("--clang-tidy", help="clang-tidy executable (default: on the PATH)")
    args = ap.parse_args()
    for key in ("build", "cache"):  # relative to where the script is called from
        if getattr(args, key):
            setattr(args, key, os.path.abspath(getattr(args, key)))
    t0, root = time.time(), Path(os.path.realpath(args.root))
    tag = hashlib.sha1(str(root).encode()).hexdigest()[:10]
    cache = Path(args.cache or (Path(args.build) / "check_structure" if args.build else
                                Path(tempfile.gettempdir()) / f"flexopt_check_structure_{tag}"))
    tables = {"EXCEPTIONS": EXCEPTIONS, "INCLUDE_EXCEPTIONS": INCLUDE_EXCEPTIONS,
              "BROKEN_CITATIONS_ALLOWED": BROKEN_CITATIONS_ALLOWED}
    out, used = [], {name: set() for name in tables}
    order = read_order(root, args.order, out)
    if order:
        check_includes(root, order, out, used)
    check_file_lengths(root, out, used)
    n_cites = check_citations(root, out, used)
    n_tus, n_run = check_functions(root, args, cache, out, used)
    me = Path(__file__).resolve()
    me_lines, me_rel = me.read_text(encoding="utf-8").splitlines(), os.path.relpath(me, root)
    for name, table in tables.items():
        for key, reason in table.items():
            ln = next((i for i, l in enumerate(me_lines, 1) if f'"{key}"' in l), 1)
            if not str(reason).strip():
                out.append((me_rel, ln, f"{name} entry '{key}' gives no reason"))
            if key not in used[name] and (name != "INCLUDE_EXCEPTIONS" or order):
                out.append((me_rel, ln, f"stale {name} entry '{key}': it matches no violation"))
    for path, line, msg in sorted(out):
        print(f"{path}:{line}: {msg}")
    n_used = {k: len(v) for k, v in used.items()}
    print(f"check_structure: {f'FAILED, {len(out)} violations' if out else 'OK'}; exceptions used: "
          f"{sum(n_used.values())} ({n_used['EXCEPTIONS']} functions and files, "
          f"{n_used['INCLUDE_EXCEPTIONS']} includes, {n_used['BROKEN_CITATIONS_ALLOWED']} "
          f"citations); {n_tus} TUs ({n_tus - n_run} cached), {n_cites} theory citations; "
          f"{time.time() - t0:.1f} s")
    return 1 if out else 0


if __name__ == "__main__":
    sys.exit(main())
