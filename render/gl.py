"""Headless OpenGL: one explicit moderngl context, and the shader loader.

The context is always passed explicitly (no global context).  On machines without a GPU
this is Mesa's llvmpipe through EGL (docs/pitfalls.md).  Shaders live in
``render/shaders/*.glsl`` and may ``#include "other.glsl"`` (resolved relative to that
folder, each file at most once, recursion detected).  Constants a shader shares with its numpy
twin are injected as ``#define``s from Python: by the program's owner (``defines=``, e.g.
``render.microfacet.shader_defines``) or, for an include used by several owners, wherever the
file is expanded (:data:`TWIN_CONSTANTS`).
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator
from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
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


def load_shader(name: str, defines: dict[str, object] | None = None) -> str:
    """Source of ``render/shaders/NAME`` with ``#include`` resolved and ``defines`` injected
    after the ``#version`` line (or at the top if none)."""
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
    path = SHADER_DIR / name
    if not path.is_file():
        where = f" (included from {stack[-1]})" if stack else ""
        raise FileNotFoundError(f"shader {path} not found{where}")
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
    """Build a program from shader file names in ``render/shaders``."""
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
