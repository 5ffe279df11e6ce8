"""The command-line side of the rendering methods, made from their specs (render.methods): the
flags of the shared options (RenderOptions: --supersample) and of each method's own options
(--tolerance, --refine, ...), the methods' part of the help, and the RenderOptions of the flags
given.  ``furrow render`` and ``furrow eval`` take them the same way; a method registered in
render.methods.METHODS brings its flags and its help line here without an edit."""

from __future__ import annotations

import argparse
import textwrap

from render.methods import RenderOptions, method_spec, method_specs, option_fields

#: Column of the summaries in the methods' help, and the width they wrap to.
HELP_INDENT = 15
HELP_WIDTH = 100


def _dest(method: str | None, name: str) -> str:
    """argparse dest of an option flag (unique: a method's flag never collides with a command's)."""
    return f"option:{method or ''}:{name}"


def flagged_options() -> list[tuple[str | None, object, object]]:
    """(method or None for a shared option, dataclasses.Field, OptionInfo) of every option with a
    flag: the shared ones (RenderOptions), then each method's in registry order."""
    out = [(None, f, info) for f, info in option_fields(RenderOptions) if info.flag]
    for spec in method_specs():
        out += [(spec.name, f, info) for f, info in option_fields(spec.options) if info.flag]
    seen: dict[str, str] = {}
    for method, _, info in out:
        owner = method or "every method"
        if info.flag in seen:
            raise ValueError(f"flag {info.flag} is declared by {seen[info.flag]} and by {owner}: a flag names one "
                             "option")
        seen[info.flag] = owner
    return out


def _help(method: str | None, f, info) -> str:
    who = "" if method is None else f"{method}: "
    default = "" if f.default is None or info.type is bool else f" (default {f.default:g})" \
        if isinstance(f.default, float) else f" (default {f.default})"
    return f"{who}{info.help}{default}".replace("%", "%%")


def add_option_arguments(p: argparse.ArgumentParser) -> None:
    """Add the flag of every option (shared, then each method's) to ``p`` in one group; a flag not
    given stays None (the option's default)."""
    g = p.add_argument_group("rendering options (each method's spec, render/NAME/spec.py; a flag the "
                             "method does not read is an error)")
    for method, f, info in flagged_options():
        kw = {"dest": _dest(method, f.name), "default": None, "help": _help(method, f, info)}
        if info.type is bool:
            kw.update(action="store_const", const=True)
        else:
            kw.update(type=info.type, choices=info.choices, metavar=info.metavar)
        g.add_argument(info.flag, **kw)


def given_options(args) -> list[tuple[str | None, str, str, object]]:
    """(method or None, field, flag, value) of every option flag given on the command line."""
    out = []
    for method, f, info in flagged_options():
        value = getattr(args, _dest(method, f.name), None)
        if value is not None:
            out.append((method, f.name, info.flag, value))
    return out


def render_options(args, methods, what: str | None = None) -> RenderOptions:
    """The RenderOptions of the option flags given, for drawing with ``methods`` (names); a flag
    that none of them reads is an error (``what`` names them in it: "--method NAME" by default)."""
    methods = list(methods)
    what = what or f"--method {', '.join(methods)}"
    shared, own = {}, {}
    for method, name, flag, value in given_options(args):
        reads = any(method_spec(m).reads(name) for m in methods) if method is None else method in methods
        if not reads:
            raise ValueError(f"{flag} does not apply to {what}")
        if method is None:
            shared[name] = value
        else:
            own.setdefault(method, {})[name] = value
    opts = RenderOptions(**shared)
    for method, values in own.items():
        opts = opts.changed_for(method, **values)
    return opts


def _supports(spec) -> str:
    """What a method supports, in one clause of its help entry."""
    flags = [info.flag for _, info in option_fields(spec.options) if info.flag]
    parts = ["S x S samples per pixel (--supersample)" if spec.supersample else "one sample per pixel",
             f"alpha: {spec.alpha}"]
    if flags:
        parts.append("options " + ", ".join(flags))
    if spec.debug_outputs:
        parts.append("debug views " + ", ".join(spec.debug_outputs))
    if not spec.evaluate:
        parts.append("not evaluated")
    return "; ".join(parts)


def methods_help(default: str | None = None, methods=None) -> str:
    """The methods' entries of a --help text: name, summary and what each supports (its spec)."""
    lines = []
    for spec in method_specs():
        if methods is not None and spec.name not in methods:
            continue
        text = ("(default) " if spec.name == default else "") + f"{spec.summary} [{_supports(spec)}]"
        body = textwrap.wrap(text, HELP_WIDTH - HELP_INDENT)
        lines.append(f"  {spec.name:<{HELP_INDENT - 3}} {body[0]}")
        lines += [" " * HELP_INDENT + b for b in body[1:]]
    return "\n".join(lines)
