"""The `longslam` command's argument parser: argparse with manners, for every subcommand.

- A mistyped choice (a subcommand, `--align sse3`) or option (`--methd`) gets difflib's "did you
  mean", and an unknown option is reported as such even when required options are missing too
  (plain argparse says "required: --method, --out" for `--methd keyframe`).
- The options every subcommand takes (`--debug`, `-v`, `--quiet`, `--no-progress`) are added to
  each parser of the tree by `add_common_options`, after the subcommands are built, so a
  subcommand added later gets them without asking.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator
from typing import Any, NoReturn

from longslam.core.suggest import close_names, did_you_mean

# argparse's own test for a token that is a negative number rather than an option.
_NEGATIVE_NUMBER = re.compile(r"^-\d+$|^-\d*\.\d+$")
_REQUIRED = "the following arguments are required"

COMMON_OPTIONS: list[tuple[tuple[str, ...], dict[str, Any]]] = [
    (("--debug",), {"action": "store_true", "help": "show the full traceback of an error"}),
    (
        ("-v", "--verbose"),
        {
            "action": "count",
            "help": "say more: -v where a route's frames come from and what a run uses, -vv debugging detail",
        },
    ),
    (
        ("--quiet",),
        {"action": "store_true", "help": "print only results, warnings and errors: no progress bars, no notes"},
    ),
    (
        ("--no-progress",),
        {"action": "store_true", "help": "draw no progress bars (they are never drawn when stderr is not a terminal)"},
    ),
]


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors suggest the name that was meant (see the module's docstring)."""

    _given: list[str] = []

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        if action.choices is not None and value not in action.choices:
            choices = ", ".join(map(repr, action.choices))
            hint = did_you_mean(value, [str(c) for c in action.choices])
            raise argparse.ArgumentError(action, f"invalid choice: {value!r}{hint}; choose from {choices}")

    def parse_known_args(
        self, args: Any = None, namespace: Any = None
    ) -> tuple[Any, list[str]]:  # Any: the namespace given, or a new one
        # Kept for `error`: argparse checks required options before it reports unknown ones.
        self._given = list(args) if args is not None else []
        return super().parse_known_args(args, namespace)

    def parse_args(self, args: Any = None, namespace: Any = None) -> argparse.Namespace:  # type: ignore[override]
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            leaf = self.leaf(parsed)
            leaf.error(leaf.unrecognized(extras))
        return parsed

    def error(self, message: str) -> NoReturn:
        if message.startswith(_REQUIRED) and not self._has_subcommands():
            unknown = [token for token in self._given if self._unknown_option(token)]
            if unknown:  # the typo is the cause: `--methd` is why --method is missing
                message = self.unrecognized(unknown)
        super().error(message)

    # --- helpers -------------------------------------------------------------------------------
    def leaf(self, parsed: argparse.Namespace) -> "Parser":
        """The (sub)command parser that `parsed` came through."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                chosen = getattr(parsed, action.dest, None) if action.dest != argparse.SUPPRESS else None
                if chosen in action.choices:
                    sub = action.choices[chosen]
                    return sub.leaf(parsed) if isinstance(sub, Parser) else self
        return self

    def unrecognized(self, extras: list[str]) -> str:
        options = [token for token in extras if self._unknown_option(token)]
        if options:  # `--methd keyframe SEQ`: the stray words are the mistyped option's value
            extras = options
        parts = []
        for token in extras:
            name = token.split("=", 1)[0]
            close = close_names(name, self._long_options(), n=1) if name.startswith("-") else []
            parts.append(f"{token} (did you mean {close[0]}?)" if close else token)
        kind = "option" if all(t.startswith("-") for t in extras) else "argument"
        return f"unrecognized {kind}{'s' if len(extras) > 1 else ''}: {', '.join(parts)}"

    def _long_options(self) -> list[str]:
        return [s for s in self._option_string_actions if s.startswith("--")]

    def _unknown_option(self, token: str) -> bool:
        if not token.startswith("-") or token == "-" or token == "--" or _NEGATIVE_NUMBER.match(token):
            return False
        name = token.split("=", 1)[0]
        if name in self._option_string_actions:
            return False
        if self.allow_abbrev and name.startswith("--") and any(s.startswith(name) for s in self._long_options()):
            return False
        return not (len(name) > 2 and name[:2] in self._option_string_actions)  # `-vv`, `-ofile`

    def _has_subcommands(self) -> bool:
        return any(isinstance(a, argparse._SubParsersAction) for a in self._actions)


def subcommand_parsers(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    """Every parser below `parser` (subcommands, and theirs), depth first."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):  # aliases share a parser
                yield sub
                yield from subcommand_parsers(sub)


def add_common_options(parser: argparse.ArgumentParser) -> None:
    """The common options on `parser` and on every subcommand below it. Below the top, their
    default is SUPPRESS, so `longslam --quiet run ...` and `longslam run --quiet ...` both work."""
    for parsers, top in ((iter([parser]), True), (subcommand_parsers(parser), False)):
        for p in parsers:
            for flags, options in COMMON_OPTIONS:
                if any(flag in p._option_string_actions for flag in flags):
                    continue
                below: dict[str, Any] = {} if top else {"default": argparse.SUPPRESS}
                p.add_argument(*flags, **options, **below)
