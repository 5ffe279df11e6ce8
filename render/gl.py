"""Headless OpenGL: one explicit moderngl context, and the shader loader.

The context is always passed explicitly (no global context).  On machines without a GPU
this is Mesa's llvmpipe through EGL (docs/pitfalls.md).

Shaders live beside the code that draws with them: ``render/<folder>/shaders/*.glsl`` for a
method or pass (``render/gather/shaders/``, ``render/microfacet/shaders/``, ...) and
``render/shaders/*.glsl`` for what several folders share (the environment-shading formulas,
the anti-aliasing resolve, the framebuffer row flip).  One rule finds a shader, whether a
program names it or another shader ``#include``s it: **by its file name, which is unique in the
render package** -- first in ``render/shaders/``, then in every ``render/**/shaders/`` folder
(:func:`shader_path`; two files of one name are an error).  Each file is included at most once
and recursion is detected.  Constants a shader shares with its numpy
twin are injected as ``#define``s from Python: by the program's owner (``defines=``, e.g.
``render.microfacet.gl.shader_defines``) or, for an include used by several owners, wherever the
file is expanded (:data:`TWIN_CONSTANTS`).
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator
from pathlib import Path

#: The render package; every ``shaders/`` folder below it holds shaders (docs/design.md, the layout rule).
RENDER_DIR = Path(__file__).resolve().parent
#: The shaders shared by several folders (looked up first).
SHADER_DIR = RENDER_DIR / "shaders"
#: OpenGL version required: 4.3 core (geometry shaders, texture arrays, SSBOs).
GL_REQUIRE = 430
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')


def _sg_constants() -> dict:
    from render.shading import sg

    return {"SG_COS_LAMBDA": f"{sg.COS_LOBE_LAMBDA:.9e}", "SG_COS_MU": f"{sg.COS_LOBE_MU:.9e}",
            "SG_PRODUCT_AXIS_EPS": f"{sg.PRODUCT_AXIS_EPS:.9e}"}


#: Shader file -> the #defines of its numpy twin's constants, put in front of the file's text
#: wherever it is expanded (so every program including it gets them).
TWIN_CONSTANTS = {"shading_sg.glsl": _sg_constants}

_NO_GL_HELP = (
    "could not create a headless OpenGL {req} context through EGL ({err}). "
    "furrow renders with Mesa's llvmpipe when there is no GPU: install the Debian packages "
    "with `apt-get install --no-install-recommends libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri libgbm1` "
    "(or run `make setup` as root)."
)


class GLUnavailable(RuntimeError):
    """No OpenGL context could be created; the message says how to fix it."""


def create_context(require: int = GL_REQUIRE):
    """Create a standalone moderngl context (EGL). The caller owns it (``ctx.release()``)."""
    try:
        import moderngl
    except ImportError as e:  # pragma: no cover - dependency missing
        raise GLUnavailable(_NO_GL_HELP.format(req=require, err=e)) from e
    try:
        return moderngl.create_standalone_context(backend="egl", require=require)
    except Exception as e:  # glcontext raises plain Exceptions
        raise GLUnavailable(_NO_GL_HELP.format(req=require, err=e)) from e


@contextlib.contextmanager
def gl_context(require: int = GL_REQUIRE) -> Iterator:
    """``with gl_context() as ctx:`` a headless context, released on exit."""
    ctx = create_context(require)
    try:
        yield ctx
    finally:
        ctx.release()


def shader_index(root: Path = RENDER_DIR) -> dict[str, Path]:
    """File name -> path of every shader in a ``shaders/`` folder below ``root`` (except the shared
    ``render/shaders/``, which :func:`shader_path` looks in first); a name used twice is an error."""
    index: dict[str, Path] = {}
    for path in sorted(root.glob("**/shaders/*.glsl")):
        if path.parent == SHADER_DIR:
            continue
        if path.name in index:
            raise ValueError(f"shader name {path.name} is used twice: {index[path.name]} and {path} "
                             "(shader file names are unique in the render package)")
        index[path.name] = path
    return index


def shader_path(name: str) -> Path:
    """Where the shader ``name`` (a file name) lives: ``render/shaders/NAME`` if there, else the one
    ``render/**/shaders/NAME``; FileNotFoundError when neither exists."""
    shared = SHADER_DIR / name
    if shared.is_file():
        return shared
    global _INDEX
    if _INDEX is None:
        _INDEX = shader_index()
    if name not in _INDEX:
        raise FileNotFoundError(f"shader {name} not found in {SHADER_DIR} or any render/**/shaders/ folder")
    return _INDEX[name]


_INDEX: dict[str, Path] | None = None


def load_shader(name: str, defines: dict[str, object] | None = None) -> str:
    """Source of the shader file ``NAME`` (found by :func:`shader_path`) with ``#include`` resolved and
    ``defines`` injected after the ``#version`` line (or at the top if none)."""
    text = _expand(name, seen=set(), stack=())
    if defines:
        block = "".join(f"#define {k} {v}\n" for k, v in defines.items())
        lines = text.splitlines(keepends=True)
        if lines and lines[0].lstrip().startswith("#version"):
            text = lines[0] + block + "".join(lines[1:])
        else:
            text = block + text
    return text


def _expand(name: str, seen: set[str], stack: tuple[str, ...]) -> str:
    if name in stack:
        raise ValueError(f"shader #include cycle: {' -> '.join(stack + (name,))}")
    try:
        path = shader_path(name)
    except FileNotFoundError as e:
        where = f" (included from {stack[-1]})" if stack else ""
        raise FileNotFoundError(f"{e}{where}") from None
    if name in seen:
        return ""
    seen.add(name)
    out = []
    for line in path.read_text().splitlines():
        m = _INCLUDE.match(line)
        if m:
            out.append(_expand(m.group(1), seen, stack + (name,)))
        else:
            out.append(line)
    if name in TWIN_CONSTANTS:  # after a #version line, if the file has one
        at = 1 if out and out[0].lstrip().startswith("#version") else 0
        out[at:at] = [f"#define {k} {v}" for k, v in TWIN_CONSTANTS[name]().items()]
    return "\n".join(out) + "\n"


def program(ctx, vertex: str, fragment: str | None = None, geometry: str | None = None,
            defines: dict[str, object] | None = None, **kw):
    """Build a program from shader file names (found by :func:`shader_path`)."""
    src = {"vertex_shader": load_shader(vertex, defines)}
    if fragment:
        src["fragment_shader"] = load_shader(fragment, defines)
    if geometry:
        src["geometry_shader"] = load_shader(geometry, defines)
    return ctx.program(**src, **kw)


def set_uniform(prog, name: str, value) -> None:
    """Set a uniform's value if the program has it (the compiler drops unused ones)."""
    if name in prog:
        prog[name].value = value
