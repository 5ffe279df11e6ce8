"""The command line: --help lists working commands; failures exit non-zero with one line."""

from __future__ import annotations

import subprocess
import sys

import pytest

from furrow.cli import COMMANDS, build_parser, main


def test_help_lists_every_present_command(capsys):
    parser = build_parser()
    text = parser.format_help()
    present = [c for c in COMMANDS if c in parser._subparsers._group_actions[0].choices]
    assert {"synth", "model", "render", "eval", "register", "bench"} <= set(present)
    for c in present:
        assert c in text


@pytest.mark.parametrize("cmd", ["synth", "model", "render", "eval", "register", "bench"])
def test_each_command_help(cmd, capsys):
    with pytest.raises(SystemExit) as e:
        main([cmd, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "usage: furrow " + cmd in out


def test_failure_is_one_line_and_nonzero(tmp_path):
    r = subprocess.run([sys.executable, "-m", "furrow", "model", str(tmp_path / "missing"), "-o", str(tmp_path / "m")],
                       capture_output=True, text=True)
    assert r.returncode != 0
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    errors = [ln for ln in lines if "error:" in ln]
    assert len(errors) == 1 and errors[0] == lines[-1] and "missing" in errors[0], r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "m").exists()


def test_no_command_prints_help(capsys):
    assert main([]) == 2
    assert "COMMAND" in capsys.readouterr().out
