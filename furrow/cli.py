"""``furrow <command>``: the command line. Wires the stages together; holds no algorithms.

Each command lives in ``furrow/cmd_<name>.py`` and defines ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args, console) -> int``, and its --help text as ``DESCRIPTION``
or, when part of it is made from the registries (the methods' entries), ``description()``.  Only the commands whose
module is present are listed.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from furrow.console import console, fail

#: Command names in the order ``--help`` lists them.
COMMANDS = ["synth", "register", "check", "model", "render", "eval", "view", "export", "batch", "bench"]


def _load(name: str):
    try:
        return importlib.import_module(f"furrow.cmd_{name}")
    except ModuleNotFoundError as e:
        if e.name == f"furrow.cmd_{name}":
            return None
        raise


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="furrow",
        description="Capture-to-render for fur and plants: scans -> signed distance pyramid -> "
        "view-dependent microfacet billboards with environment shading.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Run `furrow COMMAND --help` for the options of one command.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        mod = _load(name)
        if mod is None:
            continue
        desc = mod.description() if hasattr(mod, "description") else getattr(mod, "DESCRIPTION", mod.HELP)
        p = sub.add_parser(name, help=mod.HELP, description=desc, formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        p.set_defaults(_module=mod)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    try:
        return int(args._module.run(args, console) or 0)
    except KeyboardInterrupt:
        fail("interrupted")
        return 130
    except Exception as e:  # one-line reason, non-zero exit; --debug shows the traceback
        if "--debug" in (argv if argv is not None else sys.argv):
            raise
        fail(f"{type(e).__name__}: {e}")
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
