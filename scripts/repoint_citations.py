#!/usr/bin/env python3
"""Re-point citations of the pages outside the repository to the project's own ``docs/``.

The code used to cite ``../shared/METHODS.md`` / ``METHODS §N``, ``../shared/DESIGN.md`` /
``DESIGN.md`` and ``shared/PITFALLS.md`` / ``PITFALLS``, and the benchmarks as ``bench/NAME.py``;
a reader of the repository alone cannot follow those.  This rewrites them to
``docs/methods.md §N`` (same section numbers), ``docs/design.md``, ``docs/pitfalls.md`` and
``furrow/bench/NAME.py`` in the tracked ``*.py``, ``*.glsl``, ``*.sh``, ``*.toml``, ``Makefile``
and ``README.md`` files.

    python3 scripts/repoint_citations.py            # dry run: print what would change
    python3 scripts/repoint_citations.py --write    # rewrite the files in place

Idempotent: a second run changes nothing.  ``tests/test_docs.py`` checks the result.
"""

from __future__ import annotations

import argparse
import fnmatch
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

#: Files whose citations are re-pointed (and checked by tests/test_docs.py).
PATTERNS = ("*.py", "*.glsl", "*.sh", "*.toml", "Makefile", "README.md")
#: Files that spell the old citations on purpose (this script and its test).
SELF = ("scripts/repoint_citations.py", "tests/test_docs.py")
#: Folders never scanned when git is not available.
SKIP_DIRS = {".git", ".venv", "out", "build", "__pycache__", ".pytest_cache", ".hypothesis"}

_SHARED = r"(?:(?:\.\./)?shared/)?"
#: (pattern, replacement), applied in order.  Every replacement is lower case or prefixed, so
#: no pattern matches its own output (idempotence).
RULES = (
    (re.compile(_SHARED + r"METHODS\.md"), "docs/methods.md"),
    (re.compile(r"\bMETHODS(?= ?§)"), "docs/methods.md"),
    (re.compile(_SHARED + r"DESIGN\.md"), "docs/design.md"),
    (re.compile(r"\bDESIGN\b(?!\.md)"), "docs/design.md"),
    (re.compile(_SHARED + r"PITFALLS\.md"), "docs/pitfalls.md"),
    (re.compile(r"\bPITFALLS\b(?!\.md)"), "docs/pitfalls.md"),
    (re.compile(r"(?<![\w/.])bench/(\w+)\.py"), r"furrow/bench/\1.py"),
)


def rewrite(text: str) -> str:
    """The text with every old citation re-pointed (pure function of the text)."""
    for pattern, repl in RULES:
        text = pattern.sub(repl, text)
    return text


def source_files(repo: Path = REPO) -> list[Path]:
    """Tracked files matching PATTERNS (every such file below ``repo`` when git is unavailable),
    without SELF, as paths relative to ``repo``."""
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=repo, capture_output=True, check=True).stdout
        names = [n for n in out.decode().split("\0") if n]
    except (OSError, subprocess.CalledProcessError):
        names = []
        for root, dirs, files in os.walk(repo):
            dirs[:] = [d for d in dirs if d not in SKIP_DIRS]
            names += [os.path.relpath(os.path.join(root, f), repo) for f in files]
    keep = [n for n in names if any(fnmatch.fnmatch(Path(n).name, p) for p in PATTERNS) and n not in SELF]
    return sorted(Path(n) for n in keep if (repo / n).is_file())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--write", action="store_true", help="rewrite the files (default: dry run)")
    ap.add_argument("--repo", type=Path, default=REPO, help="repository root (default: this script's)")
    args = ap.parse_args(argv)
    files = lines = 0
    for rel in source_files(args.repo):
        path = args.repo / rel
        old = path.read_text(encoding="utf-8")
        new = rewrite(old)
        if new == old:
            continue
        files += 1
        for i, (a, b) in enumerate(zip(old.splitlines(), new.splitlines()), 1):
            if a != b:
                lines += 1
                print(f"{rel}:{i}:\n  - {a.strip()}\n  + {b.strip()}")
        if args.write:
            tmp = path.with_name(f".{path.name}.repoint-tmp")
            tmp.write_text(new, encoding="utf-8")
            shutil.copymode(path, tmp)
            os.replace(tmp, path)
    verb = "rewrote" if args.write else "would rewrite"
    print(f"{verb} {lines} lines in {files} files" + ("" if args.write else " (dry run; --write to apply)"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
