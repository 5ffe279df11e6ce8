"""House rules that a reader of the tree can check mechanically: no library module over
MAX_MODULE_LINES lines, no function over MAX_FUNCTION_LINES lines, imports one way between the
stage packages (``capture`` <- ``volume`` <- ``render``; the CLI wires them)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The house style's limits (README "House style"): a module ~500 lines, a function ~80.
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 80
#: Library packages held to the limits (tests are not: a table of cases may run long).
PACKAGES = ("capture", "volume", "render", "datasets_synthetic", "furrow")
#: What each stage package must not import.
FORBIDDEN = {"capture": ("volume", "render", "datasets_synthetic", "furrow"),
             "volume": ("render", "datasets_synthetic", "furrow"),
             "render": ("datasets_synthetic", "furrow")}


def _sources():
    for pkg in PACKAGES:
        for p in sorted((ROOT / pkg).rglob("*.py")):
            yield p, ast.parse(p.read_text(), filename=str(p))


def test_modules_and_functions_stay_small():
    long_modules, long_functions = [], []
    for p, tree in _sources():
        n = len(p.read_text().splitlines())
        if n > MAX_MODULE_LINES:
            long_modules.append(f"{p.relative_to(ROOT)}: {n} lines")
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    long_functions.append(f"{p.relative_to(ROOT)}:{node.lineno} {node.name}: {length} lines")
    assert not long_modules, "modules over the limit:\n" + "\n".join(long_modules)
    assert not long_functions, "functions over the limit:\n" + "\n".join(long_functions)


def test_imports_run_one_way():
    bad = []
    for p, tree in _sources():
        pkg = p.relative_to(ROOT).parts[0]
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            bad += [f"{p.relative_to(ROOT)}:{node.lineno} imports {n}" for n in names
                    if n.split(".")[0] in FORBIDDEN.get(pkg, ())]
    assert not bad, "imports against the stage order:\n" + "\n".join(bad)


def test_the_checks_see_a_violation(tmp_path):
    """The size walk is not vacuous: a synthetic 81-line function is found."""
    body = "def f():\n" + "    x = 1\n" * 80
    tree = ast.parse(body)
    fn = next(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef))
    assert fn.end_lineno - fn.lineno + 1 > MAX_FUNCTION_LINES
