"""mkdocs hooks: the CLI and parameter references, generated from the code when the site is
built, so they cannot drift from what `longslam --help` and `longslam list --params` print."""

from __future__ import annotations

import argparse
import io
from contextlib import redirect_stdout
from typing import Any

import re

CLI_MARK = "<!-- longslam:cli-reference -->"
# A study report published as a page links each run's files (runs/..., logs/...) in its study
# folder, which the site does not carry: those links are shown as their text.
RUN_FILE_LINK = re.compile(r"\[([^\]]+)\]\(((?:runs|logs)/[^)\s]+)\)")
PARAMS_MARK = "<!-- longslam:parameter-reference -->"
HELP_WIDTH = 100


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _help(parser: argparse.ArgumentParser) -> str:
    import os

    os.environ["COLUMNS"] = str(HELP_WIDTH)  # argparse wraps at the terminal's width
    return parser.format_help().rstrip()


def cli_reference() -> str:
    from longslam.cli.main import build_parser

    parser = build_parser()
    parts = ["## `longslam`", "", "```text", _help(parser), "```", ""]
    for name, sub in _subcommands(parser).items():
        parts += [f"## `longslam {name}`", "", "```text", _help(sub), "```", ""]
        for inner, subsub in _subcommands(sub).items():
            parts += [f"### `longslam {name} {inner}`", "", "```text", _help(subsub), "```", ""]
    return "\n".join(parts)


def parameter_reference() -> str:
    from longslam.cli.listing import list_params
    from longslam.slam.catalog import method_names

    parts = []
    for method in method_names():
        out = io.StringIO()
        with redirect_stdout(out):
            list_params(method)
        parts += [f"## `{method}`", "", "```text", out.getvalue().rstrip(), "```", ""]
    return "\n".join(parts)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    if CLI_MARK in markdown:
        markdown = markdown.replace(CLI_MARK, cli_reference())
    if PARAMS_MARK in markdown:
        markdown = markdown.replace(PARAMS_MARK, parameter_reference())
    return RUN_FILE_LINK.sub(r"\1", markdown)
