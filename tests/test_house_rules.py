"""House rules that a reader of the tree can check mechanically: no library module over
MAX_MODULE_LINES lines, no function over MAX_FUNCTION_LINES lines, imports one way between the
stage packages (``capture`` <- ``volume`` <- ``render``; the CLI wires them).

The checks are functions of a root folder, so that they run on this tree and on a planted
violation (a temporary package with one of each: each check must report it)."""

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


def sources(root: Path, packages=PACKAGES):
    """(path, parsed module) of every .py file under ``root/PACKAGE`` for each package."""
    for pkg in packages:
        for p in sorted((root / pkg).rglob("*.py")):
            yield p, ast.parse(p.read_text(), filename=str(p))


def long_modules(root: Path, packages=PACKAGES, limit: int = MAX_MODULE_LINES) -> list[str]:
    """'path: N lines' of every module over ``limit`` lines."""
    out = []
    for p, _ in sources(root, packages):
        n = len(p.read_text().splitlines())
        if n > limit:
            out.append(f"{p.relative_to(root)}: {n} lines")
    return out


def long_functions(root: Path, packages=PACKAGES, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """'path:line name: N lines' of every function (methods and nested ones too) over ``limit`` lines."""
    out = []
    for p, tree in sources(root, packages):
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > limit:
                    out.append(f"{p.relative_to(root)}:{node.lineno} {node.name}: {length} lines")
    return out


def wrong_way_imports(root: Path, packages=PACKAGES, forbidden=FORBIDDEN) -> list[str]:
    """'path:line imports NAME' of every import (at any depth, absolute) against ``forbidden``."""
    bad = []
    for p, tree in sources(root, packages):
        pkg = p.relative_to(root).parts[0]
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            bad += [f"{p.relative_to(root)}:{node.lineno} imports {n}" for n in names
                    if n.split(".")[0] in forbidden.get(pkg, ())]
    return bad


def test_modules_and_functions_stay_small():
    mods, fns = long_modules(ROOT), long_functions(ROOT)
    assert not mods, "modules over the limit:\n" + "\n".join(mods)
    assert not fns, "functions over the limit:\n" + "\n".join(fns)


def test_imports_run_one_way():
    bad = wrong_way_imports(ROOT)
    assert not bad, "imports against the stage order:\n" + "\n".join(bad)


def test_the_checks_see_a_planted_violation(tmp_path):
    """A temporary tree with one of each violation (and lawful code beside it): each check reports
    exactly the planted one."""
    cap, vol = tmp_path / "capture", tmp_path / "volume"
    (cap / "deep").mkdir(parents=True)
    vol.mkdir()
    (cap / "__init__.py").write_text('"""ok"""\n')
    (cap / "ok.py").write_text("import numpy\n\n\ndef f():\n    return 1\n")
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))  # def line + 80 = 81 lines
    (cap / "long_function.py").write_text("class A:\n    def method(self):\n        pass\n\n\ndef g():\n" + body)
    (cap / "deep" / "wrong_way.py").write_text("def h():\n    from volume.build import fuse_levels\n    return 1\n")
    (vol / "long_module.py").write_text("from capture import ok\n" + "X = 1\n" * MAX_MODULE_LINES)
    (vol / "fine.py").write_text("import capture.ok\n" + "Y = 1\n" * (MAX_MODULE_LINES - 1))
    pkgs = ("capture", "volume")
    assert long_functions(tmp_path, pkgs) == [f"capture/long_function.py:6 g: {MAX_FUNCTION_LINES + 1} lines"]
    assert long_modules(tmp_path, pkgs) == [f"volume/long_module.py: {MAX_MODULE_LINES + 1} lines"]
    assert wrong_way_imports(tmp_path, pkgs) == ["capture/deep/wrong_way.py:2 imports volume.build"]
