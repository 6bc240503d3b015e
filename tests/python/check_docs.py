#!/usr/bin/env python3
"""Runs the code blocks of the user documentation, so that what the docs say runs as written.

    python3 tests/python/check_docs.py [FILE.md ...]      (default: README.md, docs/*.md,
                                                           bench/README.md, scenes/README.md)

Environment: ``ZEROSET``, the zeroset binary the commands call (default ``target/release/zeroset``,
else ``target/debug/zeroset``). ``python3`` blocks run with this interpreter; they need the
``zeroset`` package installed (``pip install ./python``).

What runs, each block in a scratch directory that looks like the checkout (``scenes/`` copied,
the rest linked; one per document, so a block may use the files an earlier block of the same
document wrote):

- fenced ``sh`` / ``bash`` blocks, as one ``bash -eo pipefail`` script, with ``zeroset`` on the
  ``PATH`` (the binary above), ``python3`` the interpreter running this script, and ``cargo run --release --`` read as ``zeroset`` (the same
  command, without a build);
- ``console`` blocks: the lines that start with ``$ `` (the rest is output, not compared);
- ``python`` blocks, each saved as a script and run (so ``if __name__ == "__main__":`` guards
  work); matplotlib draws off screen (``MPLBACKEND=Agg``);
- ``ron`` blocks that are a whole scene (they start with ``Scene(``): rendered at 16×16.

Markers, an HTML comment on the line just before the fence:

- ``<!-- not-run: REASON -->``: the block is skipped and listed with its reason (whole test
  suites, installs, benchmarks that take minutes, peers that CI does not install);
- ``<!-- needs: MODULE ... -->``: a ``sh`` block that needs those Python modules; the block is
  skipped, with the reason, where one does not import (``python`` blocks are checked for their
  own imports the same way).

Other blocks (``rust``, ``text``, ``toml``, RON fragments) are not run. Each document's relative
links must point at files that exist (one check a document). Prints one line a block
and, last, ``N passed, M failed``; exits 1 if any failed.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
TIMEOUT_S = 90
FENCE = re.compile(r"^(\s*)```([A-Za-z0-9_+-]*)\s*$")
MARKER = re.compile(r"^\s*<!--\s*(not-run|needs)\s*:\s*(.*?)\s*-->\s*$")


def default_files() -> list[Path]:
    files = [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))
    files += [p for p in (REPO / "bench" / "README.md", REPO / "scenes" / "README.md") if p.exists()]
    return files


def blocks(path: Path):
    """(line number, language, code, marker kind, marker text) of each fenced block."""
    lines = path.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, lang = m.group(1), m.group(2).lower()
        start = i
        body = []
        i += 1
        while i < len(lines) and lines[i].strip() != "```":
            line = lines[i]
            body.append(line[len(indent):] if line.startswith(indent) else line)
            i += 1
        i += 1
        prev = start - 1
        while prev >= 0 and not lines[prev].strip():
            prev -= 1
        marker = MARKER.match(lines[prev]) if prev >= 0 else None
        kind, text = (marker.group(1), marker.group(2)) if marker else (None, "")
        yield start + 1, lang, "\n".join(body) + "\n", kind, text


def broken_links(path: Path) -> list[str]:
    """Relative link targets (`[text](target)`, images included) that do not exist."""
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    broken = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue
        if not (path.parent / target.split("#")[0]).exists():
            broken.append(target)
    return broken


def missing_modules(names) -> list[str]:
    return [n for n in names if importlib.util.find_spec(n) is None]


def python_imports(code: str) -> list[str]:
    found = []
    for line in code.splitlines():
        m = re.match(r"^\s*(?:import|from)\s+([A-Za-z_][A-Za-z0-9_]*)", line)
        if m and m.group(1) not in found:
            found.append(m.group(1))
    return [n for n in found if n not in sys.builtin_module_names and n != "__future__"]


def zeroset_binary() -> Path:
    if os.environ.get("ZEROSET"):
        return Path(os.environ["ZEROSET"]).resolve()
    for profile in ("release", "debug"):
        candidate = REPO / os.environ.get("CARGO_TARGET_DIR", "target") / profile / "zeroset"
        if candidate.exists():
            return candidate.resolve()
    sys.exit("check_docs: no zeroset binary: set ZEROSET or build one (cargo build --release)")


def workspace(root: Path) -> Path:
    """A scratch directory that looks like the checkout: `scenes/` copied (blocks may write
    beside the scenes), every other top-level entry but `target/` and `.git` linked."""
    work = Path(tempfile.mkdtemp(prefix="docs-", dir=root))
    shutil.copytree(REPO / "scenes", work / "scenes")
    for entry in REPO.iterdir():
        if entry.name not in ("scenes", "target", ".git", "out", "bench-results"):
            (work / entry.name).symlink_to(entry)
    return work


def run(cmd, cwd: Path, env: dict) -> tuple[bool, str]:
    try:
        p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return False, f"timed out after {TIMEOUT_S} s"
    tail = (p.stdout + p.stderr).strip().splitlines()[-8:]
    return p.returncode == 0, f"exit {p.returncode}\n    " + "\n    ".join(tail)


def main() -> int:
    files = [Path(a).resolve() for a in sys.argv[1:]] or default_files()
    binary = zeroset_binary()
    root = Path(tempfile.mkdtemp(prefix="check-docs-"))
    shims = root / "bin"
    shims.mkdir()
    (shims / "zeroset").symlink_to(binary)
    for name in ("python3", "python"):  # sh blocks' Python is this one, with its packages
        (shims / name).write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
        (shims / name).chmod(0o755)
    env = dict(os.environ, PATH=f"{shims}{os.pathsep}{os.environ.get('PATH', '')}", MPLBACKEND="Agg")
    passed = failed = skipped = 0
    try:
        for path in files:
            work = workspace(root)
            name = path.relative_to(REPO) if path.is_relative_to(REPO) else path
            broken = broken_links(path)
            if broken:
                failed += 1
                print(f"FAIL {name}: links to missing files: {', '.join(broken)}")
            else:
                passed += 1
                print(f"ok   {name} (links)")
            for number, (line, lang, code, kind, text) in enumerate(blocks(path)):
                where = f"{name}:{line} ({lang})"
                script = None
                if lang in ("sh", "bash", "shell"):
                    script = code
                elif lang == "console":
                    script = "\n".join(l[2:] for l in code.splitlines() if l.startswith("$ ")) + "\n"
                elif lang in ("python", "py"):
                    pass
                elif lang == "ron" and re.match(r"^\s*(//[^\n]*\n\s*)*Scene\s*\(", code):
                    pass
                else:
                    continue
                if kind == "not-run":
                    skipped += 1
                    print(f"skip {where}: {text}")
                    continue
                needs = text.split() if kind == "needs" else []
                if lang in ("python", "py"):
                    needs += python_imports(code)
                absent = missing_modules(needs)
                if absent:
                    skipped += 1
                    print(f"skip {where}: Python module(s) not installed: {', '.join(absent)}")
                    continue
                if script is not None:
                    script = re.sub(r"\bcargo run --release --(?=\s)", "zeroset", script)
                    ok, detail = run(["bash", "-eo", "pipefail", "-c", script], work, env)
                elif lang in ("python", "py"):
                    file = work / f"_block_{number}.py"
                    file.write_text(code, encoding="utf-8")
                    ok, detail = run([sys.executable, file.name], work, env)
                else:
                    file = work / "scenes" / f"_block_{number}.ron"
                    file.write_text(code, encoding="utf-8")
                    ok, detail = run([str(binary), "render", str(file), "-o", str(work / "_ron_out"),
                                      "--width", "16", "--height", "16", "--no-previews"], work, env)
                if ok:
                    passed += 1
                    print(f"ok   {where}")
                else:
                    failed += 1
                    print(f"FAIL {where}: {detail}")
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print(f"{skipped} skipped")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
