"""Checks of what the command line answers: its exit status, a failure in one line, and shell
completion."""

from __future__ import annotations

import io
import sys

import argcomplete
import pytest

from longslam.cli.main import build_parser, main


def one_line_error(capsys, *needles: str) -> str:
    """The command's stderr was one line, an error naming every needle, and no traceback."""
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "error:" in lines[0], err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def exit_status(argv: list[str]) -> int:
    """main()'s status, also when argparse exits (a usage error)."""
    try:
        return main(argv)
    except SystemExit as exit:
        return exit.code


def complete(monkeypatch, line: str) -> list[str]:
    """What argcomplete answers a shell for `line` (cursor at the end), as its own tests ask it."""
    monkeypatch.setenv("_ARGCOMPLETE", "1")
    monkeypatch.setenv("_ARGCOMPLETE_SHELL", "bash")
    monkeypatch.setenv("COMP_LINE", line)
    monkeypatch.setenv("COMP_POINT", str(len(line)))
    # argcomplete writes debugging to descriptor 9 if it is open: under pytest it may be anything.
    monkeypatch.setattr(argcomplete.finders.CompletionFinder, "_init_debug_stream",
                        lambda self: setattr(argcomplete.io, "debug_stream", io.StringIO()))
    out = io.StringIO()
    with pytest.raises(SystemExit):
        argcomplete.autocomplete(build_parser(), output_stream=out, exit_method=sys.exit)
    return [c.strip() for c in out.getvalue().split("\013")]
