"""The layout rule of the render package (docs/design.md "The render package"):

- ``render/`` itself keeps only what every method shares (at most ``MAX_TOP_MODULES`` modules);
- one folder per method or pass, holding its GL owner ``gl.py``, its numpy twin ``reference.py``,
  its shaders in ``shaders/`` and a package docstring saying what is where;
- every registered method's folder has both, its spec ``spec.py`` (render.methods.MethodSpec: the
  registry line points at it, and it names the folder's ``gl.py`` class), and a test file in the
  mirrored ``tests/render/<folder>/``;
- no two modules under ``render/`` share a basename, apart from the per-folder names of the rule;
- shader file names are unique in the package (the loader finds them by name, render.gl.shader_path);
- the benchmarks import render names that are public (no leading underscore).
"""

from __future__ import annotations

import ast
import importlib
from collections import defaultdict
from pathlib import Path

from render.gl import RENDER_DIR, shader_index, shader_path
from render.methods import METHODS, method_spec

REPO = Path(__file__).resolve().parents[2]
#: Most modules (``__init__.py`` included) directly in ``render/``.
MAX_TOP_MODULES = 10
#: Module names a folder of the rule may repeat.
PER_FOLDER_NAMES = {"__init__.py", "gl.py", "reference.py", "config.py", "spec.py"}
#: The passes that follow a method, each a folder of the rule like the methods.
PASS_FOLDERS = ("composite", "relight")


def _modules(root: Path) -> list[Path]:
    return [p for p in root.rglob("*.py") if "__pycache__" not in p.parts]


def _method_folder(name: str) -> Path:
    module = METHODS[name].split(":")[0]
    return REPO / Path(*module.split(".")).parent


def test_top_level_holds_only_the_shared_core():
    top = sorted(p.name for p in RENDER_DIR.glob("*.py"))
    assert len(top) <= MAX_TOP_MODULES, f"render/ holds {len(top)} modules: {top}"


def test_no_two_modules_share_a_basename():
    seen = defaultdict(list)
    for p in _modules(RENDER_DIR):
        if p.name not in PER_FOLDER_NAMES:
            seen[p.name].append(p.relative_to(REPO).as_posix())
    clashes = {k: v for k, v in seen.items() if len(v) > 1}
    assert not clashes, f"modules with the same basename under render/: {clashes}"


def test_every_method_and_pass_folder_has_owner_twin_docstring_and_tests():
    folders = {_method_folder(n) for n in METHODS} | {RENDER_DIR / f for f in PASS_FOLDERS}
    assert len(folders) >= 6
    for folder in sorted(folders):
        rel = folder.relative_to(REPO)
        assert (folder / "gl.py").is_file(), f"{rel}: no GL module gl.py"
        assert (folder / "reference.py").is_file(), f"{rel}: no numpy twin reference.py"
        doc = ast.get_docstring(ast.parse((folder / "__init__.py").read_text()))
        assert doc and "gl.py" in doc and "reference.py" in doc, f"{rel}/__init__.py must say what is where"
        tests = REPO / "tests" / rel
        assert sorted(tests.glob("test_*.py")), f"no tests in {tests.relative_to(REPO)} for {rel}"


def test_registered_specs_live_in_their_folders_and_name_its_gl_class():
    for name, target in METHODS.items():
        module = target.split(":")[0]
        assert module.endswith(".spec"), f"{name}: registered from {module}, not a folder's spec module"
        spec = method_spec(name)
        owner, cls = spec.renderer.split(":")
        folder_gl = module.rsplit(".", 1)[0] + ".gl"
        assert owner == folder_gl, f"{name}: its renderer {spec.renderer} is not in its folder's gl.py"
        assert hasattr(importlib.import_module(owner), cls)
        assert spec.renderer_class().name == name


def test_shader_names_are_unique_and_each_program_finds_its_shader():
    index = shader_index()  # raises on a name used twice
    shared = {p.name for p in (RENDER_DIR / "shaders").glob("*.glsl")}
    assert not shared & set(index), f"shared shaders also in a folder: {shared & set(index)}"
    for name in list(index) + sorted(shared):
        assert shader_path(name).is_file()
    # every folder's shaders sit beside the code that uses them: a folder's shader is named in that folder
    for name, path in index.items():
        folder = path.parent.parent
        used = any(name in p.read_text() for p in folder.rglob("*.py")) or any(
            f'"{name}"' in p.read_text() for p in RENDER_DIR.rglob("*.glsl"))
        assert used, f"{path.relative_to(REPO)} is used by no module of {folder.relative_to(REPO)} nor included"


def test_benchmarks_import_public_render_names_only():
    for p in sorted((REPO / "furrow" / "bench").glob("*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("render"):
                private = [a.name for a in node.names if a.name.startswith("_")]
                assert not private, f"{p.relative_to(REPO)} imports private {private} from {node.module}"
